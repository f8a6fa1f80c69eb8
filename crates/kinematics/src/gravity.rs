//! Gravity torques about the joint axes from the URDF inertials (lumped per joint, see
//! [`RobotModel::inertials`]).
//!
//! For joint `i` with unit axis `z_i` through the point `o_i` (both in the base frame, at posture
//! `q`), and the lumped masses `m_k` with centres `c_k` (base frame) carried by joints `k ≥ i`:
//!
//! `τ_i = z_i · Σ_{k≥i} (c_k − o_i) × (m_k·g)`, N·m,
//!
//! the torque gravity exerts about the joint axis (positive in the joint's positive sense). It equals
//! `−∂V/∂q_i` with the potential energy `V = −Σ_k m_k·g·c_k`. `g` is the gravity acceleration in the
//! robot's base frame, m/s² (floor mount: `(0, 0, −9.81)`).

use nalgebra::{Matrix3, Vector3};

use crate::error::KinematicsError;
use crate::fk::apply_step;
use crate::model::RobotModel;

/// Joints handled on the stack (no allocation) by the internal hot paths; longer chains allocate.
pub(crate) const STACK_DOF: usize = 16;

/// Per-joint quantities of the gravity sums, base frame.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct GravityEntry {
    /// Joint axis, unit.
    pub(crate) z: Vector3<f64>,
    /// A point on the axis (the joint frame origin), m.
    pub(crate) o: Vector3<f64>,
    /// Lumped mass carried by this joint times its centre of mass, kg·m.
    pub(crate) mc: Vector3<f64>,
    /// Lumped mass, kg.
    pub(crate) m: f64,
}

/// Checks that the gravity vector is finite.
pub(crate) fn check_gravity(g_base: &Vector3<f64>) -> Result<(), KinematicsError> {
    if g_base.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(KinematicsError::InvalidInput(format!(
            "gravity vector {:?} m/s² is not finite; give the gravity acceleration in the robot's \
             base frame, e.g. (0, 0, -9.81) for a floor mount",
            g_base.as_slice()
        )))
    }
}

/// Fills `entries[i]` (len = dof) for the NOMINAL model at `q`. No checks.
pub(crate) fn gravity_entries(model: &RobotModel, q: &[f64], entries: &mut [GravityEntry]) {
    let mut r = Matrix3::identity();
    let mut t = Vector3::zeros();
    for (((step, &qi), inertial), e) in model
        .steps
        .iter()
        .zip(q)
        .zip(model.inertials())
        .zip(entries.iter_mut())
    {
        apply_step(&mut r, &mut t, step, qi);
        let c = t + r * inertial.com;
        *e = GravityEntry {
            z: r * step.axis.into_inner(),
            o: t,
            mc: inertial.mass * c,
            m: inertial.mass,
        };
    }
}

/// `τ_i` from the entries (backward accumulation of the carried mass moments). No checks.
pub(crate) fn torques_from_entries(
    entries: &[GravityEntry],
    g_base: &Vector3<f64>,
    out: &mut [f64],
) {
    let mut s = Vector3::zeros();
    let mut m = 0.0;
    for (e, tau) in entries.iter().zip(out.iter_mut()).rev() {
        s += e.mc;
        m += e.m;
        // Σ_{k≥i} m_k (c_k − o_i) = S_i − M_i·o_i.
        *tau = e.z.dot(&(s - m * e.o).cross(g_base));
    }
}

/// Gravity torques of the nominal model at `q` into `out` (len = dof), without checks and, for
/// `dof ≤ 16`, without allocation.
pub(crate) fn gravity_torques_into(
    model: &RobotModel,
    q: &[f64],
    g_base: &Vector3<f64>,
    out: &mut [f64],
) {
    let n = model.dof();
    if n <= STACK_DOF {
        let mut buf = [GravityEntry::default(); STACK_DOF];
        gravity_entries(model, q, &mut buf[..n]);
        torques_from_entries(&buf[..n], g_base, out);
    } else {
        let mut buf = vec![GravityEntry::default(); n];
        gravity_entries(model, q, &mut buf);
        torques_from_entries(&buf, g_base, out);
    }
}

/// Gravity torques about every joint axis, N·m, in chain order.
///
/// `τ_i = z_i · Σ_{k≥i} (c_k − o_i) × (m_k·g_base)`: the torque gravity exerts about joint `i`'s
/// axis from all the mass it carries (the lumped URDF inertials, [`RobotModel::inertials`]), with
/// the axis `z_i`, axis point `o_i` and centres of mass `c_k` in the base frame at posture `q`
/// (rad). `g_base` is the gravity acceleration in the base frame, m/s² (floor mount:
/// `(0, 0, −9.81)`; a ceiling mount: `(0, 0, +9.81)`). A model without inertials gives zeros.
///
/// Equals `−∂V/∂q_i` with `V = −Σ_k m_k·g_base·c_k`.
///
/// Errors: a bad `q` (see [`RobotModel::check_q`]) or a non-finite `g_base`.
///
/// # Examples
/// ```
/// # use kinematics::{gravity_torques, RobotModel};
/// # use nalgebra::Vector3;
/// let urdf = r#"<robot name="pendulum">
///   <link name="base"/>
///   <link name="arm"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
///     <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
///     <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
/// </robot>"#;
/// let model = RobotModel::from_urdf_str(urdf, "arm").unwrap();
/// let tau = gravity_torques(&model, &[0.0], &Vector3::new(0.0, 0.0, -9.81)).unwrap();
/// // 2 kg at 0.5 m along x, gravity along −z, axis +y: τ = ((0.5,0,0) × (0,0,−19.62))·ŷ = +9.81 N·m.
/// assert!((tau[0] - 9.81).abs() < 1e-12);
/// ```
pub fn gravity_torques(
    model: &RobotModel,
    q: &[f64],
    g_base: &Vector3<f64>,
) -> Result<Vec<f64>, KinematicsError> {
    model.check_q(q)?;
    check_gravity(g_base)?;
    let mut tau = vec![0.0; model.dof()];
    gravity_torques_into(model, q, g_base, &mut tau);
    Ok(tau)
}

/// `∂τ/∂q`, the dof×dof gravity-torque Jacobian, N·m/rad, row `k` = joint torque `k`, column `i`
/// = joint angle `i`, at posture `q` (rad). Symmetric (it is minus the Hessian of the potential
/// energy).
///
/// With `W_k = Σ_{m≥k} m_m (c_m − o_k)` (base frame): for `i < k`,
/// `∂τ_k/∂q_i = (z_i × z_k)·(W_k × g) + z_k·((z_i × W_k) × g)`; for `i ≥ k`,
/// `∂τ_k/∂q_i = z_k·((z_i × W_i) × g)`.
///
/// Errors: as [`gravity_torques`].
pub fn gravity_torque_jacobian(
    model: &RobotModel,
    q: &[f64],
    g_base: &Vector3<f64>,
) -> Result<nalgebra::DMatrix<f64>, KinematicsError> {
    model.check_q(q)?;
    check_gravity(g_base)?;
    let n = model.dof();
    let mut entries = vec![GravityEntry::default(); n];
    gravity_entries(model, q, &mut entries);
    Ok(gravity_jacobian_from_entries(&entries, g_base))
}

/// See [`gravity_torque_jacobian`]. No checks.
pub(crate) fn gravity_jacobian_from_entries(
    entries: &[GravityEntry],
    g_base: &Vector3<f64>,
) -> nalgebra::DMatrix<f64> {
    let n = entries.len();
    // W_k = S_k − M_k o_k.
    let mut w = vec![Vector3::zeros(); n];
    let mut s = Vector3::zeros();
    let mut m = 0.0;
    for (e, wk) in entries.iter().zip(w.iter_mut()).rev() {
        s += e.mc;
        m += e.m;
        *wk = s - m * e.o;
    }
    let mut jac = nalgebra::DMatrix::zeros(n, n);
    for k in 0..n {
        let zk = entries[k].z;
        for i in 0..n {
            let zi = entries[i].z;
            jac[(k, i)] = if i < k {
                zi.cross(&zk).dot(&w[k].cross(g_base)) + zk.dot(&zi.cross(&w[k]).cross(g_base))
            } else {
                zk.dot(&zi.cross(&w[i]).cross(g_base))
            };
        }
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_fixtures::{HP20, PLANAR, VA1400};
    use proptest::prelude::*;

    const G_FLOOR: [f64; 3] = [0.0, 0.0, -9.81];

    fn model(xml: &str) -> RobotModel {
        RobotModel::from_urdf_str(xml, "tool0").expect("test URDF loads")
    }

    fn potential(model: &RobotModel, q: &[f64], g: &Vector3<f64>) -> f64 {
        let mut e = vec![GravityEntry::default(); model.dof()];
        gravity_entries(model, q, &mut e);
        -e.iter().map(|e| e.mc.dot(g)).sum::<f64>()
    }

    /// Hand computation for the planar arm, with x forward and gravity −z, axis +y:
    /// a mass m at horizontal distance d (x) from the axis gives τ = m·9.81·d about +y
    /// ((d,0,h) × (0,0,−m g) = (0, m g d, 0)).
    #[test]
    fn planar_arm_matches_hand_computation() {
        let m = model(PLANAR);
        let g = Vector3::from(G_FLOOR);
        // Straight arm: l1 COM at x=0.5 (2 kg), l2 COM at x=1.25 (1 kg), tool0 at x=1.5 (3 kg).
        let tau = gravity_torques(&m, &[0.0, 0.0], &g).unwrap();
        let tau1 = 9.81 * (2.0 * 0.5 + 1.0 * 1.25 + 3.0 * 1.5);
        let tau2 = 9.81 * (1.0 * 0.25 + 3.0 * 0.5);
        assert!((tau[0] - tau1).abs() < 1e-12, "{} vs {}", tau[0], tau1);
        assert!((tau[1] - tau2).abs() < 1e-12, "{} vs {}", tau[1], tau2);
        // Joint 2 at +90° about +y turns link 2 to point down (−z): no lever for joint 2, joint 1
        // keeps only l1 plus the (now vertical) rest at x = 1.
        let tau = gravity_torques(&m, &[0.0, std::f64::consts::FRAC_PI_2], &g).unwrap();
        let tau1 = 9.81 * (2.0 * 0.5 + 4.0 * 1.0);
        assert!((tau[0] - tau1).abs() < 1e-12, "{} vs {}", tau[0], tau1);
        assert!(tau[1].abs() < 1e-12, "{}", tau[1]);
    }

    #[test]
    fn zero_gravity_gives_zero_torque_and_bad_inputs_are_errors() {
        let m = model(VA1400);
        let q = vec![0.1; m.dof()];
        let tau = gravity_torques(&m, &q, &Vector3::zeros()).unwrap();
        assert!(tau.iter().all(|&t| t == 0.0));
        assert!(gravity_torques(&m, &q[..3], &Vector3::from(G_FLOOR)).is_err());
        let err = gravity_torques(&m, &q, &Vector3::new(0.0, f64::NAN, 0.0)).unwrap_err();
        assert!(err.to_string().contains("gravity"), "{err}");
    }

    fn q_strategy(n: usize) -> impl Strategy<Value = Vec<f64>> {
        // Inside every joint's limits on both robots (the tightest are about ±1.48 rad).
        proptest::collection::vec(-1.4f64..1.4, n)
    }

    fn g_strategy() -> impl Strategy<Value = Vector3<f64>> {
        (-10.0f64..10.0, -10.0f64..10.0, -10.0f64..10.0).prop_map(|(x, y, z)| Vector3::new(x, y, z))
    }

    // Central differences of V with step H = 1e-6 rad: truncation error ~ H²·|V'''| ≈ 1e-12·(mass
    // moment ≈ 1e3 N·m) = 1e-9, round-off ~ eps·|V|/H ≈ 2e-16·1e4/1e-6 = 2e-6 N·m. Torques are up to
    // ~1e3 N·m, so an absolute tolerance of 1e-5 N·m is tight.
    const H: f64 = 1e-6;
    const TOL_TAU: f64 = 1e-5;
    // Central differences of τ (second derivatives of V): round-off ~ eps·|τ|/H ≈ 2e-16·1e3/1e-6 =
    // 2e-7 N·m/rad; tolerance 1e-5 N·m/rad.
    const TOL_DTAU: f64 = 1e-5;

    fn check_against_potential(m: &RobotModel, q: &[f64], g: &Vector3<f64>) {
        let tau = gravity_torques(m, q, g).unwrap();
        for i in 0..m.dof() {
            let mut qp = q.to_vec();
            let mut qm = q.to_vec();
            qp[i] += H;
            qm[i] -= H;
            let fd = -(potential(m, &qp, g) - potential(m, &qm, g)) / (2.0 * H);
            assert!(
                (tau[i] - fd).abs() < TOL_TAU,
                "joint {i}: analytic {} vs fd {}",
                tau[i],
                fd
            );
        }
        let jac = gravity_torque_jacobian(m, q, g).unwrap();
        for i in 0..m.dof() {
            let mut qp = q.to_vec();
            let mut qm = q.to_vec();
            qp[i] += H;
            qm[i] -= H;
            let tp = gravity_torques(m, &qp, g).unwrap();
            let tm = gravity_torques(m, &qm, g).unwrap();
            for k in 0..m.dof() {
                let fd = (tp[k] - tm[k]) / (2.0 * H);
                assert!(
                    (jac[(k, i)] - fd).abs() < TOL_DTAU,
                    "dτ{k}/dq{i}: analytic {} vs fd {}",
                    jac[(k, i)],
                    fd
                );
            }
        }
        // Minus a Hessian: symmetric.
        assert!((&jac - jac.transpose()).amax() < 1e-9);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn torque_is_minus_gradient_of_potential_va1400(q in q_strategy(7), g in g_strategy()) {
            check_against_potential(&model(VA1400), &q, &g);
        }

        #[test]
        fn torque_is_minus_gradient_of_potential_hp20(q in q_strategy(6), g in g_strategy()) {
            check_against_potential(&model(HP20), &q, &g);
        }

        #[test]
        fn torque_is_minus_gradient_of_potential_planar(q in q_strategy(2), g in g_strategy()) {
            check_against_potential(&model(PLANAR), &q, &g);
        }
    }
}

//! Gravity torques about the joint axes (and forces along prismatic axes) from the URDF
//! inertials (lumped per joint, see [`RobotModel::inertials`]), one per chain joint
//! ([`RobotModel::chain_joints`], coupled joints included).
//!
//! For joint `i` with unit axis `z_i` through the point `o_i` (both in the base frame, at posture
//! `q`), and the lumped masses `m_k` with centres `c_k` (base frame) carried by joints `k ≥ i`:
//!
//! - revolute or continuous: `τ_i = z_i · Σ_{k≥i} (c_k − o_i) × (m_k·g)`, N·m, the torque gravity
//!   exerts about the joint axis;
//! - prismatic: `f_i = z_i · Σ_{k≥i} m_k·g`, N, the force gravity exerts along the axis (what the
//!   joint's drive holds; a compliance of the axis, m/N, deflects it by `compliance·f_i`),
//!
//! both positive in the joint's positive sense. Each equals `−∂V/∂q_i` with the potential energy
//! `V = −Σ_k m_k·g·c_k`, `q_i` the chain joint's value (rad or m). `g` is the gravity acceleration
//! in the robot's base frame, m/s² (floor mount: `(0, 0, −9.81)`).

use nalgebra::{Matrix3, Vector3};

use crate::error::KinematicsError;
use crate::fk::apply_step;
pub(crate) use crate::model::STACK_DOF;
use crate::model::{RobotModel, PRISMATIC};

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
    /// A prismatic joint (a force along `z`, not a torque about it).
    pub(crate) prismatic: bool,
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

/// Fills `entries[k]` (len = chain joints) for the NOMINAL model at the independent joint vector
/// `q`. No checks.
pub(crate) fn gravity_entries(model: &RobotModel, q: &[f64], entries: &mut [GravityEntry]) {
    if model.prismatic {
        gravity_entries_k::<true>(model, q, entries);
    } else {
        gravity_entries_k::<false>(model, q, entries);
    }
}

/// [`gravity_entries`] for a chain that may (or, `false`, does not) hold prismatic joints.
#[inline(always)]
fn gravity_entries_k<const MAY_BE_PRISMATIC: bool>(
    model: &RobotModel,
    q: &[f64],
    entries: &mut [GravityEntry],
) {
    let mut r = Matrix3::identity();
    let mut t = Vector3::zeros();
    let mut buf = Vec::new();
    for (((step, &qi), inertial), e) in model
        .steps
        .iter()
        .zip(model.chain_q(q, &mut buf))
        .zip(model.inertials())
        .zip(entries.iter_mut())
    {
        apply_step::<MAY_BE_PRISMATIC>(&mut r, &mut t, step, qi);
        let c = t + r * inertial.com;
        *e = GravityEntry {
            z: r * step.axis.into_inner(),
            o: t,
            mc: inertial.mass * c,
            m: inertial.mass,
            prismatic: MAY_BE_PRISMATIC && step.axis_kind == PRISMATIC,
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
        *tau = if e.prismatic {
            // The carried weight along the axis.
            m * e.z.dot(g_base)
        } else {
            // Σ_{k≥i} m_k (c_k − o_i) = S_i − M_i·o_i.
            e.z.dot(&(s - m * e.o).cross(g_base))
        };
    }
}

/// Gravity torques of the nominal model at `q` into `out` (len = chain joints), without checks
/// and, for chains of up to 16 joints without coupled joints, without allocation.
pub(crate) fn gravity_torques_into(
    model: &RobotModel,
    q: &[f64],
    g_base: &Vector3<f64>,
    out: &mut [f64],
) {
    let n = model.chain_joints().len();
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

/// Gravity torques about every joint axis, N·m (forces along the axis, N, for prismatic
/// joints), one per chain joint ([`RobotModel::chain_joints`], coupled joints included; `dof`
/// values for a chain without coupled joints), in chain order.
///
/// `τ_i = z_i · Σ_{k≥i} (c_k − o_i) × (m_k·g_base)`: the torque gravity exerts about joint `i`'s
/// axis from all the mass it carries (the lumped URDF inertials, [`RobotModel::inertials`]), with
/// the axis `z_i`, axis point `o_i` and centres of mass `c_k` in the base frame at posture `q`
/// (the independent joints, rad or m); for a prismatic joint `f_i = z_i · Σ_{k≥i} m_k·g_base`.
/// `g_base` is the gravity acceleration in the base frame, m/s² (floor mount: `(0, 0, −9.81)`; a
/// ceiling mount: `(0, 0, +9.81)`). A model without inertials gives zeros.
///
/// Equals `−∂V/∂q_i` with `V = −Σ_k m_k·g_base·c_k` and `q_i` the chain joint's value (the
/// generalised force on the independent joints is `Aᵀτ`, `A` the
/// [`RobotModel::coupling_matrix`]).
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
    let mut tau = vec![0.0; model.chain_joints().len()];
    gravity_torques_into(model, q, g_base, &mut tau);
    Ok(tau)
}

/// `∂τ/∂q`, the gravity-torque Jacobian, (chain joints)×dof: row `k` = chain joint `k`'s torque
/// (N·m) or force (N), column `i` = independent joint `i` (per rad, or per m for a prismatic
/// joint), at posture `q`. Without coupled joints it is dof×dof and symmetric (minus the
/// Hessian of the potential energy); with them it is the chain Jacobian below times the
/// [`RobotModel::coupling_matrix`].
///
/// Chain Jacobian, with `W_k = Σ_{m≥k} m_m (c_m − o_k)` and `M_k = Σ_{m≥k} m_m` (base frame),
/// `i` rotary: for `i < k`, `∂τ_k/∂q_i = (z_i × z_k)·(W_k × g) + z_k·((z_i × W_k) × g)`; for
/// `i ≥ k`, `∂τ_k/∂q_i = z_k·((z_i × W_i) × g)`. `i` prismatic (it translates everything it
/// carries by `z_i`): 0 for `i < k` (`W_k` is unchanged), `z_k·((M_i z_i) × g)` for `i > k`.
/// A prismatic `k`'s force `f_k = M_k z_k·g` changes only with the direction `z_k`:
/// `∂f_k/∂q_i = M_k (z_i × z_k)·g` for a rotary `i < k`, 0 otherwise.
///
/// Errors: as [`gravity_torques`].
pub fn gravity_torque_jacobian(
    model: &RobotModel,
    q: &[f64],
    g_base: &Vector3<f64>,
) -> Result<nalgebra::DMatrix<f64>, KinematicsError> {
    model.check_q(q)?;
    check_gravity(g_base)?;
    let n = model.chain_joints().len();
    let mut entries = vec![GravityEntry::default(); n];
    gravity_entries(model, q, &mut entries);
    let chain = gravity_jacobian_from_entries(&entries, g_base);
    Ok(if model.has_coupled_joints() {
        chain * model.coupling_matrix()
    } else {
        chain
    })
}

/// The chain Jacobian of [`gravity_torque_jacobian`] (chain joints × chain joints). No checks.
pub(crate) fn gravity_jacobian_from_entries(
    entries: &[GravityEntry],
    g_base: &Vector3<f64>,
) -> nalgebra::DMatrix<f64> {
    let n = entries.len();
    // W_k = S_k − M_k o_k, and the carried masses M_k.
    let mut w = vec![Vector3::zeros(); n];
    let mut carried = vec![0.0; n];
    let mut s = Vector3::zeros();
    let mut m = 0.0;
    for ((e, wk), mk) in entries
        .iter()
        .zip(w.iter_mut())
        .zip(carried.iter_mut())
        .rev()
    {
        s += e.mc;
        m += e.m;
        *wk = s - m * e.o;
        *mk = m;
    }
    let mut jac = nalgebra::DMatrix::zeros(n, n);
    for k in 0..n {
        let zk = entries[k].z;
        for i in 0..n {
            let zi = entries[i].z;
            jac[(k, i)] = match (entries[k].prismatic, entries[i].prismatic) {
                (false, false) if i < k => {
                    zi.cross(&zk).dot(&w[k].cross(g_base)) + zk.dot(&zi.cross(&w[k]).cross(g_base))
                }
                (false, false) => zk.dot(&zi.cross(&w[i]).cross(g_base)),
                (false, true) if i > k => zk.dot(&(carried[i] * zi).cross(g_base)),
                (false, true) => 0.0,
                (true, false) if i < k => carried[k] * zi.cross(&zk).dot(g_base),
                (true, _) => 0.0,
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
        let mut e = vec![GravityEntry::default(); model.chain_joints().len()];
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

    /// The generalised forces on the independent joints, `Aᵀτ` (`A` the coupling matrix), are
    /// `−∂V/∂q` (central differences in `q`), the chain torques are those of the same chain with
    /// every joint independent at the chain values, and `∂τ/∂q` matches central differences of
    /// `τ` in `q`: on the rail-mounted hp20 (a prismatic joint carrying everything), the mixed
    /// chain (an oblique rail, a lift in the middle, a mimic) with and without a one-to-many
    /// coupling, and the mimic torso. Step H and tolerances as above (rail masses ~420 kg at up to
    /// ~6 m: |V| ≲ 3e4 J, so round-off eps·|V|/H ≈ 7e-6 N·m; TOL_TAU 1e-5 still holds it, with
    /// TOL_COUPLED_TAU 3e-5 for the sums Aᵀτ).
    fn check_mixed_chain(m: &RobotModel, independent: &RobotModel, seed: u64) {
        use crate::test_fixtures::random_q;
        use rand::SeedableRng;
        const TOL_COUPLED_TAU: f64 = 3e-5;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let q = random_q(m, &mut rng);
        let g = Vector3::new(0.3, -0.5, -9.8);
        let tau = gravity_torques(m, &q, &g).unwrap();
        assert_eq!(tau.len(), m.chain_joints().len());
        let generalised =
            m.coupling_matrix().transpose() * nalgebra::DVector::from_vec(tau.clone());
        for i in 0..m.dof() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[i] += H;
            qm[i] -= H;
            let fd = -(potential(m, &qp, &g) - potential(m, &qm, &g)) / (2.0 * H);
            assert!(
                (generalised[i] - fd).abs() < TOL_COUPLED_TAU,
                "{} joint {i}: analytic {} vs fd {fd}",
                m.name(),
                generalised[i]
            );
        }
        let chain_q = m.chain_values(&q).unwrap();
        let tau_independent = gravity_torques(independent, &chain_q, &g).unwrap();
        for (a, b) in tau.iter().zip(&tau_independent) {
            assert!(
                (a - b).abs() < 1e-9,
                "{}: {tau:?} vs {tau_independent:?}",
                m.name()
            );
        }
        let jac = gravity_torque_jacobian(m, &q, &g).unwrap();
        assert_eq!(jac.shape(), (m.chain_joints().len(), m.dof()));
        for i in 0..m.dof() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[i] += H;
            qm[i] -= H;
            let tp = gravity_torques(m, &qp, &g).unwrap();
            let tm = gravity_torques(m, &qm, &g).unwrap();
            for k in 0..m.chain_joints().len() {
                let fd = (tp[k] - tm[k]) / (2.0 * H);
                assert!(
                    (jac[(k, i)] - fd).abs() < TOL_DTAU,
                    "{} dτ{k}/dq{i}: analytic {} vs fd {fd}",
                    m.name(),
                    jac[(k, i)]
                );
            }
        }
        if !m.has_coupled_joints() {
            assert!((&jac - jac.transpose()).amax() < 1e-9);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(16))]
        #[test]
        fn prismatic_and_coupled_chains_match_their_potential(seed in any::<u64>()) {
            use crate::test_fixtures::{mixed_coupled, MIMIC_TORSO, MIXED, RAIL_6R};
            let rail = model(RAIL_6R);
            check_mixed_chain(&rail, &rail, seed);
            let no_mimic = model(&MIXED.replace(r#"<mimic joint="j2" multiplier="-1" offset="0.1"/>"#, ""));
            check_mixed_chain(&model(MIXED), &no_mimic, seed);
            check_mixed_chain(&mixed_coupled(), &no_mimic, seed);
            let torso_free = model(&MIMIC_TORSO.replace(
                r#"<mimic joint="torso_pitch_1" multiplier="-1" offset="0.05"/>"#, ""));
            check_mixed_chain(&model(MIMIC_TORSO), &torso_free, seed);
        }
    }

    /// Hand computation: a 2 kg slider on a vertical lift feels −2·9.81 N along +z whatever its
    /// height, and a joint turning the lift by 90° (axis now horizontal) makes it 0; the rotary
    /// joint under it feels the slider's moment.
    #[test]
    fn a_lift_carries_its_weight_as_a_force() {
        let xml = r#"<robot name="lift">
          <link name="base"/><link name="post"/>
          <link name="slider"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
            <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
          <joint name="tilt" type="revolute"><parent link="base"/><child link="post"/>
            <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
          <joint name="lift" type="prismatic"><parent link="post"/><child link="slider"/>
            <axis xyz="0 0 1"/><limit lower="0" upper="1" effort="100" velocity="1"/></joint>
        </robot>"#;
        let m = RobotModel::from_urdf_str(xml, "slider").unwrap();
        let g = Vector3::from(G_FLOOR);
        let tau = gravity_torques(&m, &[0.0, 0.7], &g).unwrap();
        assert!((tau[1] + 2.0 * 9.81).abs() < 1e-12, "{tau:?}");
        // (0.5, 0, 0.7) × (0, 0, −19.62) about +y: +0.5·19.62 N·m.
        assert!((tau[0] - 0.5 * 2.0 * 9.81).abs() < 1e-12, "{tau:?}");
        let tau = gravity_torques(&m, &[std::f64::consts::FRAC_PI_2, 0.7], &g).unwrap();
        assert!(tau[1].abs() < 1e-12, "{tau:?}");
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

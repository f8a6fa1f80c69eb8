//! Geometric and tip-position Jacobians, analytic. Lengths in metres, angles in radians.
//!
//! Column of a chain joint k with axis `w_k` (base axes) through `o_k`: `[w_k × (p − o_k); w_k]`
//! for a revolute or continuous joint, `[w_k; 0]` for a prismatic one. The Jacobian with respect
//! to the independent joints `q` is, by the chain rule, the chain columns times the coupling
//! matrix ([`RobotModel::coupling_matrix`]): column i = Σ_k (∂q_k/∂q_i)·column_k.

use nalgebra::{Matrix3, Matrix3xX, Matrix6xX, Vector3};

use crate::error::KinematicsError;
use crate::fk::{check_tip, joint_frames};
use crate::model::{RobotModel, Step, PRISMATIC};

/// Axes in which a geometric Jacobian is expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JacobianFrame {
    /// Base-frame axes, reference point at the tip (pinocchio `LOCAL_WORLD_ALIGNED`).
    Base,
    /// Tip-frame axes (= flange axes), reference point at the tip (pinocchio `LOCAL`).
    Tip,
}

/// The columns `(v, ω)` of chain joint `step` with frame `(r, t)` (after its motion, base) for
/// the tip at `p_tip`: `(w × (p − t), w)` for a rotary joint, `(w, 0)` for a prismatic one,
/// `w = r·axis`. `MAY_BE_PRISMATIC = false` (a chain without prismatic joints) skips the test.
#[inline(always)]
pub(crate) fn joint_columns<const MAY_BE_PRISMATIC: bool>(
    step: &Step,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    p_tip: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let w = r * step.axis.into_inner();
    if MAY_BE_PRISMATIC && step.axis_kind == PRISMATIC {
        (w, Vector3::zeros())
    } else {
        (w.cross(&(p_tip - t)), w)
    }
}

/// Fills `jac` (6×dof, rows [v; ω], base axes, reference point at the tip) and returns the
/// flange rotation (base axes) and the tip position (m, base). No checks. `frames` is scratch.
pub(crate) fn jacobian_base_into(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
    frames: &mut Vec<(Matrix3<f64>, Vector3<f64>)>,
    jac: &mut Matrix6xX<f64>,
) -> (Matrix3<f64>, Vector3<f64>) {
    let (r_flange, t_flange) = joint_frames(model, q, frames);
    let p_tip = t_flange + r_flange * flange_from_tip;
    if model.has_coupled_joints() {
        jac.fill(0.0);
        for (k, ((r, t), step)) in frames.iter().zip(&model.steps).enumerate() {
            let (v, w) = joint_columns::<true>(step, r, t, &p_tip);
            // Chain rule: chain joint k moves with every independent joint it depends on.
            model.for_each_dependence(k, |i, c| {
                let mut col = jac.fixed_view_mut::<6, 1>(0, i);
                col.fixed_rows_mut::<3>(0).axpy(c, &v, 1.0);
                col.fixed_rows_mut::<3>(3).axpy(c, &w, 1.0);
            });
        }
    } else if model.prismatic {
        fill_columns::<true>(model, frames, &p_tip, jac);
    } else {
        fill_columns::<false>(model, frames, &p_tip, jac);
    }
    (r_flange, p_tip)
}

/// The columns of a chain without coupled joints (column k = chain joint k) that may (or,
/// `false`, does not) hold prismatic joints.
#[inline(always)]
fn fill_columns<const MAY_BE_PRISMATIC: bool>(
    model: &RobotModel,
    frames: &[(Matrix3<f64>, Vector3<f64>)],
    p_tip: &Vector3<f64>,
    jac: &mut Matrix6xX<f64>,
) {
    for (k, ((r, t), step)) in frames.iter().zip(&model.steps).enumerate() {
        let (v, w) = joint_columns::<MAY_BE_PRISMATIC>(step, r, t, p_tip);
        jac.fixed_view_mut::<3, 1>(0, k).copy_from(&v);
        jac.fixed_view_mut::<3, 1>(3, k).copy_from(&w);
    }
}

/// Geometric Jacobian of the tip, 6×dof, rows `[v; ω]`, in `frame` axes with the reference point
/// at the tip, with respect to the independent joints `q` ([`RobotModel::joints`]): a revolute
/// column in m/rad and rad/rad, a prismatic one in m/m and rad/m (its ω rows are zero unless it
/// drives a coupled revolute joint). Coupled joints enter by the chain rule.
///
/// Errors: bad `q` (see [`RobotModel::check_q`]) or a non-finite tip offset.
pub fn geometric_jacobian(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
    frame: JacobianFrame,
) -> Result<Matrix6xX<f64>, KinematicsError> {
    model.check_q(q)?;
    check_tip(flange_from_tip)?;
    let mut frames = Vec::with_capacity(model.dof());
    let mut jac = Matrix6xX::zeros(model.dof());
    let (r_base_tip, _) = jacobian_base_into(model, q, flange_from_tip, &mut frames, &mut jac);
    if frame == JacobianFrame::Tip {
        let m = r_base_tip.transpose();
        for mut col in jac.column_iter_mut() {
            let v = m * col.fixed_rows::<3>(0);
            let w = m * col.fixed_rows::<3>(3);
            col.fixed_rows_mut::<3>(0).copy_from(&v);
            col.fixed_rows_mut::<3>(3).copy_from(&w);
        }
    }
    Ok(jac)
}

/// `∂p_base_tip/∂q`, 3×dof, base axes, m/rad (m/m for a prismatic joint).
///
/// Errors: as [`geometric_jacobian`].
pub fn tip_position_jacobian(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
) -> Result<Matrix3xX<f64>, KinematicsError> {
    let j = geometric_jacobian(model, q, flange_from_tip, JacobianFrame::Base)?;
    Ok(j.fixed_rows::<3>(0).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fk::{base_from_tip, base_from_tip_unchecked};
    use crate::test_fixtures::{mixed_coupled, model, random_q, robots, MIXED, RAIL_6R};
    use proptest::prelude::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// Central-difference step (rad or m) and tolerance per column (m/rad, rad/rad, m/m, rad/m):
    /// truncation h²/6·|p'''| ≲ 2e-11 with lever arms under 3 m (a coupled joint moving at up to
    /// 2 rad/m scales it by 2³ on its prismatic driver: ≲ 2e-10), round-off ≈ eps·|p|/h ≈ 1e-10
    /// with positions up to 5 m; 1e-9 leaves a margin of ~3× over their sum.
    const FD_STEP: f64 = 1e-5;
    const FD_TOL: f64 = 1e-9;

    /// Every column of the base, tip and position Jacobians against central differences of the
    /// FK in the independent joints, on every test chain (this replaced the hp20/va1400-only
    /// check of `tests/kinematics.rs`, same step and tolerance): revolute only, a rail under an arm, a
    /// prismatic joint on an oblique axis and one in the middle, a URDF mimic, a one-to-many
    /// coupling driven by a prismatic joint (chain rule), a coupled torso.
    fn fd_check(m: &RobotModel, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let q = random_q(m, &mut rng);
        let tip = Vector3::new(0.01, -0.02, 0.15);
        let jb = geometric_jacobian(m, &q, &tip, JacobianFrame::Base).unwrap();
        let jt = geometric_jacobian(m, &q, &tip, JacobianFrame::Tip).unwrap();
        let jp = tip_position_jacobian(m, &q, &tip).unwrap();
        let t0 = base_from_tip(m, &q, &tip).unwrap();
        assert_eq!(jb.ncols(), m.dof());
        for k in 0..m.dof() {
            let (mut qp, mut qm) = (q.clone(), q.clone());
            qp[k] += FD_STEP;
            qm[k] -= FD_STEP;
            let tp = base_from_tip_unchecked(m, &qp, &tip);
            let tm = base_from_tip_unchecked(m, &qm, &tip);
            let v = (tp.translation.vector - tm.translation.vector) / (2.0 * FD_STEP);
            // ω from the rotation difference: R(q+h)·R(q−h)ᵀ ≈ exp(2h[ω]×).
            let w = (tp.rotation * tm.rotation.inverse()).scaled_axis() / (2.0 * FD_STEP);
            let col = jb.column(k);
            let at = format!("{} column {k} at {q:?}", m.name());
            assert!((col.fixed_rows::<3>(0) - v).norm() < FD_TOL, "v {at}");
            assert!((col.fixed_rows::<3>(3) - w).norm() < FD_TOL, "ω {at}");
            assert!((jp.column(k) - v).norm() < FD_TOL, "{at}");
            let r_inv = t0.rotation.inverse();
            assert!((jt.column(k).fixed_rows::<3>(0) - r_inv * v).norm() < FD_TOL);
            assert!((jt.column(k).fixed_rows::<3>(3) - r_inv * w).norm() < FD_TOL);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn jacobians_match_central_differences_on_every_chain(seed in any::<u64>()) {
            for m in robots() {
                fd_check(&m, seed);
            }
        }
    }

    /// A prismatic column is the axis in base axes with no rotation; the rail's is the floor's x
    /// axis turned 0.2 rad about z, whatever the arm does.
    #[test]
    fn prismatic_columns_are_the_axis_and_no_rotation() {
        let m = model(RAIL_6R);
        let q = [1.3, 0.4, -0.3, 0.2, 1.0, -0.5, 2.0];
        let j = geometric_jacobian(&m, &q, &Vector3::zeros(), JacobianFrame::Base).unwrap();
        let (s, c) = 0.2f64.sin_cos();
        assert!((j.fixed_view::<3, 1>(0, 0) - Vector3::new(c, s, 0.0)).norm() < 1e-15);
        assert_eq!(j.fixed_view::<3, 1>(3, 0), Vector3::zeros());
        // In the mixed chain the lift (q index 3) only turns anything through the coupled j4.
        let plain = model(MIXED);
        let coupled = mixed_coupled();
        let q = [0.2, 0.3, -0.4, 0.1];
        let jp = geometric_jacobian(
            &plain,
            &[0.2, 0.3, -0.4, 0.1, 0.7],
            &Vector3::zeros(),
            JacobianFrame::Base,
        )
        .unwrap();
        let jc = geometric_jacobian(&coupled, &q, &Vector3::zeros(), JacobianFrame::Base).unwrap();
        assert_eq!(jp.fixed_view::<3, 1>(3, 3), Vector3::zeros());
        assert!(jc.fixed_view::<3, 1>(3, 3).norm() > 0.1);
    }
}

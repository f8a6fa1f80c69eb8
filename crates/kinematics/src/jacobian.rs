//! Geometric and tip-position Jacobians, analytic. Lengths in metres, angles in radians.

use nalgebra::{Matrix3, Matrix3xX, Matrix6xX, Vector3};

use crate::error::KinematicsError;
use crate::fk::{check_tip, joint_frames};
use crate::model::RobotModel;

/// Axes in which a geometric Jacobian is expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JacobianFrame {
    /// Base-frame axes, reference point at the tip (pinocchio `LOCAL_WORLD_ALIGNED`).
    Base,
    /// Tip-frame axes (= flange axes), reference point at the tip (pinocchio `LOCAL`).
    Tip,
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
    for (k, ((r, t), step)) in frames.iter().zip(&model.steps).enumerate() {
        let w = r * step.axis.into_inner();
        let v = w.cross(&(p_tip - t));
        jac.fixed_view_mut::<3, 1>(0, k).copy_from(&v);
        jac.fixed_view_mut::<3, 1>(3, k).copy_from(&w);
    }
    (r_flange, p_tip)
}

/// Geometric Jacobian of the tip, 6×dof, rows `[v; ω]` (m/rad and rad/rad), in `frame` axes with the
/// reference point at the tip.
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

/// `∂p_base_tip/∂q`, 3×dof, base axes, m/rad.
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

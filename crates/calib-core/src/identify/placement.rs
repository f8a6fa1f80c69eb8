//! The placement rotation: the turn between the fitted `b1_from_b2` and a reference placement.

use super::fit::IdentFit;
use crate::stats::t_two_sided_p;
use nalgebra::{Isometry3, Matrix3, Vector3};

/// Rotation of the fitted `b1_from_b2` against a reference placement (e.g. the cell's stated
/// `b1_from_b2`), expressed as a rotation of robot 2's base: `R_fit = R_ref · exp([a]ₓ)`, `a` in
/// b2 axes (rad). If the reference is the true placement of the nominal bases, a turn of robot
/// 2's true base by `a` (the kinematic-error model's `MountRpy`) gives exactly this `a`; a turn of
/// robot 1's base by `a1` gives `a = −R_refᵀ·a1` (the two are indistinguishable from handclasp
/// data).
#[derive(Debug, Clone)]
pub struct PlacementRotation {
    /// `a`, b2 axes, rad.
    pub a_b2: Vector3<f64>,
    /// Standard errors of `a`'s components, rad (fit covariance plus `reference_sd_rad²`).
    pub std_error: Vector3<f64>,
    /// Two-sided t-test p-values of each component (dof of the fit).
    pub p_value: Vector3<f64>,
    /// The same rotation as a turn of robot 1's base, b1 axes, rad: `a1 = −R_ref·a`.
    pub a1_b1: Vector3<f64>,
    /// Translation of the fit minus the reference, b1 axes, m.
    pub dt_b1: Vector3<f64>,
    /// Standard errors of `dt_b1`, m.
    pub dt_std_error: Vector3<f64>,
    /// Residual degrees of freedom of the fit (for t quantiles).
    pub dof: usize,
}

/// Compares `fit.b1_from_b2` with `reference` (see [`PlacementRotation`]). `reference_sd_rad` is
/// the uncertainty of the reference's angles (e.g. the rounding of a file's degrees), added in
/// quadrature to each component's standard error.
pub fn placement_rotation(
    fit: &IdentFit,
    reference: &Isometry3<f64>,
    reference_sd_rad: f64,
) -> PlacementRotation {
    let r_fit = fit.b1_from_b2.rotation.to_rotation_matrix();
    let r_ref = reference.rotation.to_rotation_matrix();
    let a_b2 = (r_ref.inverse() * r_fit).scaled_axis();
    // Left perturbation of the fit, R_fit ← exp(φ)·R_fit: δa ≈ R_fitᵀ·δφ (a small).
    let rt = r_fit.matrix().transpose();
    let sigma_phi = fit.covariance.fixed_view::<3, 3>(3, 3).into_owned();
    let cov_a = rt * sigma_phi * rt.transpose();
    let std_error = Vector3::from_fn(|i, _| {
        (cov_a[(i, i)].max(0.0) + reference_sd_rad * reference_sd_rad).sqrt()
    });
    let p_value = Vector3::from_fn(|i, _| {
        if std_error[i] > 0.0 {
            t_two_sided_p(a_b2[i] / std_error[i], fit.dof)
        } else {
            1.0
        }
    });
    // Translation: X ← (ρ, exp φ)·X moves the translation by ρ + φ×t: δt = ρ − [t]ₓφ.
    let t = fit.b1_from_b2.translation.vector;
    let mut jt = nalgebra::Matrix3x6::zeros();
    jt.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&Matrix3::identity());
    jt.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-t.cross_matrix()));
    let sigma_x = fit.covariance.fixed_view::<6, 6>(0, 0).into_owned();
    let cov_t = jt * sigma_x * jt.transpose();
    PlacementRotation {
        a_b2,
        std_error,
        p_value,
        a1_b1: -(r_ref * a_b2),
        dt_b1: t - reference.translation.vector,
        dt_std_error: Vector3::from_fn(|i, _| cov_t[(i, i)].max(0.0).sqrt()),
        dof: fit.dof,
    }
}

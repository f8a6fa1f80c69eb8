//! Registration of `b1_from_b2` from handclasp point pairs: the paper's methods and better ones.
//!
//! All fits take points in metres (`p_b1` in robot 1's base frame, `p_b2` in robot 2's) and return
//! `b1_from_b2` with `p_b1 ≈ b1_from_b2 · p_b2`.
//!
//! | method | cost minimised | points |
//! |---|---|---|
//! | `generic` ([`generic_4point`]) | exact affine `H = A·B⁻¹`, nearest rotation of its 3×3 block, eq (12) | 4 (n > 4: affine least squares), not coplanar |
//! | `generic-affine` | as `generic` but H's own translation column | same |
//! | `paper` ([`paper_constrained`]) | `H`'s block projected onto the mounts' rotation family (eqs 11, 30, 16–21), eq (12) | same |
//! | `lsq` ([`rigid_lsq`]) | `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` over all rotations (Arun/Umeyama/Horn, no scale) | ≥ 3, not collinear |
//! | `constrained` ([`constrained_lsq`]) | the same cost, with R restricted to the mounts' family inside the fit | ≥ 3, not collinear |
//!
//! # Mount families
//! A [`Mount`] gives a base's orientation relative to a level frame (z up, against gravity):
//! `level_from_base = L`, with `L = I` (floor), `Rx(180°)` (ceiling), `Rx(rx)·Ry(ry)` (tilt).
//! With both mounts known, `R = L1ᵀ·Rz(γ)·L2`: one free angle, the yaw about gravity.
//! [`Mount::Wall`] is the paper's wall family: only "this base's z axis is horizontal" is known,
//! which leaves two free angles, `Rz(β)·Ry(−90°)·Rz(α)` in the level frame.
//! In every case the best member maximises `tr(Rᵀ·M)` (M = the affine block for `paper`, the
//! cross-covariance for `constrained`), which is the same as minimising `‖R − M‖_F`:
//! - yaw family: closed form `γ = atan2(M'₁₀ − M'₀₁, M'₀₀ + M'₁₁)` with `M' = L1·M·L2ᵀ`
//!   (this is eq 11 for floor–floor and eq 30 for floor–ceiling);
//! - wall family: for a fixed β the best α is closed form, which leaves a 1-D maximisation of
//!   `f(β) = ‖Kᵀu(β) + b‖ + aᵀu(β)`, solved globally by sampling then Newton.

// File order (each file uses only files before it): mount, method, rotation, family, checks,
// four_point, lsq, fast.
mod checks;
mod family;
mod fast;
mod four_point;
mod lsq;
mod method;
mod mount;
mod rotation;
#[cfg(test)]
mod tests;

pub use checks::{spread_singular_values, COLLINEAR_REL, COPLANAR_REL};
pub(crate) use family::family_axes;
pub use family::{project_rotation_family, wall_family_angles, wall_rotation};
pub(crate) use fast::rigid_fit_fast_indexed;
pub use fast::{
    affine_lsq_fast, constrained_fast, fit_fast, generic_fast, paper_fast, rigid_fit_fast,
};
pub use four_point::{generic_4point, paper_constrained};
pub(crate) use lsq::fill_fit_jacobian;
#[cfg(test)]
use lsq::fit_jtj;
pub use lsq::{constrained_lsq, rigid_lsq, ConstrainedOptions};
pub(crate) use method::{build_uncertainty, residuals};
pub use method::{Fit, Method, Uncertainty};
pub use mount::{Mount, MountPair};
pub use rotation::{nearest_rotation, rotation_maximizing_trace};

use crate::error::CalibError;
use crate::points::PointPairs;

/// Runs `method` on `pairs` (the mounts are used by `paper` and `constrained` only; for the
/// others [`fit_unconstrained`] needs no mounts).
pub fn fit(pairs: &PointPairs, method: Method, mounts: &MountPair) -> Result<Fit, CalibError> {
    match method {
        Method::Generic => generic_4point(pairs, false),
        Method::GenericAffine => generic_4point(pairs, true),
        Method::Paper => paper_constrained(pairs, mounts),
        Method::Lsq => rigid_lsq(pairs, None),
        Method::Constrained => constrained_lsq(pairs, mounts, &ConstrainedOptions::default()),
    }
}

/// Runs a `method` that does not use the installation (`generic`, `generic-affine`, `lsq`: see
/// [`Method::uses_mounts`]) on `pairs`, without a [`MountPair`] to invent.
///
/// Errors: [`CalibError::InvalidOption`] for `paper` and `constrained` (they need the mounts:
/// call [`fit`]); otherwise those of the method ([`generic_4point`], [`rigid_lsq`]).
///
/// # Examples
/// ```
/// use calib_core::{fit_unconstrained, Method, PointPairs};
/// use calib_core::nalgebra::{Isometry3, Point3, Vector3};
///
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.5, 0.0, 0.1), Vector3::new(0.1, 0.0, 3.0));
/// let p_b2 = vec![
///     Point3::new(0.8, 0.1, 0.2), Point3::new(0.2, 0.9, 0.3),
///     Point3::new(0.5, 0.5, 1.1), Point3::new(0.9, 0.7, 0.6),
/// ];
/// let p_b1: Vec<_> = p_b2.iter().map(|p| b1_from_b2 * p).collect();
/// let pairs = PointPairs::new(p_b1, p_b2).unwrap();
/// let fit = fit_unconstrained(&pairs, Method::Lsq).unwrap();
/// assert!((fit.b1_from_b2.translation.vector - b1_from_b2.translation.vector).norm() < 1e-9);
/// assert!(fit_unconstrained(&pairs, Method::Constrained).is_err());
/// ```
pub fn fit_unconstrained(pairs: &PointPairs, method: Method) -> Result<Fit, CalibError> {
    match method {
        Method::Generic => generic_4point(pairs, false),
        Method::GenericAffine => generic_4point(pairs, true),
        Method::Lsq => rigid_lsq(pairs, None),
        Method::Paper | Method::Constrained => Err(CalibError::InvalidOption {
            name: "method".into(),
            value: method.name().into(),
            message: format!(
                "`{}` fits within the installation's rotation family and needs both mounts: call \
                 calib_core::fit(pairs, method, &mounts) (or use generic, generic-affine or lsq)",
                method.name()
            ),
        }),
    }
}

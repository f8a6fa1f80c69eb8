//! The placement rotation's posterior for the model a controller uses.
//!
//! A fit may keep unknowns the data do not determine: a joint offset of robot 2's first joint
//! turns robot 2 about its base axis exactly as the placement's yaw does, and a fit that keeps
//! it (a diagnosis's family, at its widened prior) leaves the split between the two to the
//! prior. The placement's *marginal* posterior then carries that prior: it answers "where is
//! robot 2's physical base frame", which the session cannot tell. A controller gets the
//! exported model, whose joint zeros it keeps: what it uses is the placement *conditional* on
//! those undetermined unknowns held at their exported values, the figure a calibration that
//! holds them at nominal (`calibrate --cell`'s base-parameter reduction) reports.
//!
//! [`placement_rotation_posterior`] finds the undetermined unknowns of a fit with the base-
//! parameter reduction's own test ([`reduce_layout`] on the fit's layout, linearised at its
//! estimate) and conditions the placement's rotation block on them (the Schur complement of
//! the posterior covariance), keeping the marginal block too.

use nalgebra::{DMatrix, Matrix3};

use super::reduce::reduce_layout;
use super::{CellFit, CellFitError, CellParam, CellProblem, ReductionEntry};
use kinematics::Axis;

/// Relative singular-value cutoff of the pseudo-inverse of the held unknowns' covariance block
/// when it is not positive definite (a direction neither data nor prior determine): below
/// this fraction of the largest singular value a direction is treated as absent. Round-off
/// level for f64 covariances of prior-σ-sized unknowns.
pub const CONDITIONING_RCOND: f64 = 1e-12;

/// The placement rotation's posterior covariance (rad², robot 1's base axes; left
/// perturbation of `b1_from_b2`), conditional and marginal.
#[derive(Debug, Clone)]
pub struct PlacementRotationPosterior {
    /// Conditional on the unknowns in `held` at their fitted values: what a controller that
    /// keeps the exported joint zeros uses. Equals `marginal` when `held` is empty.
    pub conditional: Matrix3<f64>,
    /// Every fitted unknown free (the prior of the undetermined ones included).
    pub marginal: Matrix3<f64>,
    /// The fit's unknowns the data do not determine (the base-parameter reduction's test on
    /// the fit's layout), with why; empty when the data determine every one.
    pub held: Vec<ReductionEntry>,
}

impl PlacementRotationPosterior {
    /// One line for people: which figure the conditional one is, naming what it is conditional
    /// on, e.g. "conditional on 2 directions the data do not determine, held at the exported
    /// values: robot 2 joint_offset joint 1, …".
    pub fn basis(&self) -> String {
        if self.held.is_empty() {
            "the data determine every fitted unknown: the posterior of the placement's rotation \
             (conditional and marginal are the same)"
                .into()
        } else {
            format!(
                "conditional on {} direction{} the data do not determine, held at the exported \
                 values (the joint zeros a controller keeps): {}",
                self.held.len(),
                if self.held.len() == 1 { "" } else { "s" },
                self.held
                    .iter()
                    .map(|e| e.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        }
    }
}

/// The posterior of `fit`'s placement rotation (a fit of `problem`): see the module
/// documentation. `None` when the fit's layout does not hold the placement's rotation.
///
/// Errors: the linearisation at the fit's estimate fails (as [`reduce_layout`]).
pub fn placement_rotation_posterior(
    problem: &CellProblem,
    fit: &CellFit,
) -> Result<Option<PlacementRotationPosterior>, CellFitError> {
    let Some(rot) = Axis::ALL
        .into_iter()
        .map(|axis| fit.layout.column(&CellParam::PlacementRotation { axis }))
        .collect::<Option<Vec<usize>>>()
    else {
        return Ok(None);
    };
    let cov = &fit.covariance;
    let marginal = Matrix3::from_fn(|a, b| cov[(rot[a], rot[b])]);
    let penalised = (0..fit.layout.len()).any(|j| fit.layout.prior_sigma(j) > 0.0);
    let held: Vec<ReductionEntry> = if penalised {
        reduce_layout(problem, &fit.layout, &fit.estimate, &fit.active)?
            .dropped
            .into_iter()
            .filter(|e| fit.layout.column(&e.param).is_some())
            .collect()
    } else {
        Vec::new()
    };
    let u: Vec<usize> = held
        .iter()
        .filter_map(|e| fit.layout.column(&e.param))
        .collect();
    let conditional = if u.is_empty() {
        marginal
    } else {
        let s_uu = DMatrix::from_fn(u.len(), u.len(), |a, b| cov[(u[a], u[b])]);
        let s_ru = DMatrix::from_fn(3, u.len(), |a, b| cov[(rot[a], u[b])]);
        // Σ_rr − Σ_ru·Σ_uu⁻¹·Σ_ur: Cholesky, else the pseudo-inverse.
        let x = match s_uu.clone().cholesky() {
            Some(c) => c.solve(&s_ru.transpose()),
            None => {
                let svd = s_uu.svd(true, true);
                let smax = svd.singular_values.max();
                svd.solve(&s_ru.transpose(), CONDITIONING_RCOND * smax)
                    .unwrap_or_else(|_| DMatrix::zeros(u.len(), 3))
            }
        };
        let reduction = &s_ru * x;
        let c = marginal - Matrix3::from_fn(|a, b| reduction[(a, b)]);
        (c + c.transpose()) * 0.5
    };
    Ok(Some(PlacementRotationPosterior {
        conditional,
        marginal,
        held,
    }))
}

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
                 values (as a controller keeps them, e.g. its joint zeros): {}",
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::Robot;
    use crate::whole_cell::fixtures::{sim_cell, Cell};
    use crate::whole_cell::{
        fit_cell_with, initial_estimate, reduce, ParamLayout, SolveOptions, Tolerance,
    };
    use kinematics::ErrorParam;

    /// Largest difference between the two fits' exported placements for them to be the same
    /// model: 1 µm and 1 µrad (the export's own read-back tolerance).
    const SAME_MODEL_M: f64 = 1e-6;
    const SAME_MODEL_RAD: f64 = 1e-6;
    /// Relative agreement of the two fits' conditional rotation rms: the conditional of the fit
    /// that keeps the undetermined offsets is, to first order, the covariance of the fit that
    /// holds them (the same information without those columns); what is left is the two
    /// linearisation points' difference, well under 1 %.
    const SAME_MODEL_ROTATION_RTOL: f64 = 1e-2;
    /// The marginal of the fit that keeps them must carry their prior: at least this many times
    /// the conditional (robot 2's joint-1 offset at a 0.5° tolerance against a placement yaw
    /// the data fix to hundredths of a degree).
    const MARGINAL_CARRIES_PRIOR: f64 = 3.0;

    /// The same coincident session fitted twice with joint offsets only: as `calibrate --cell`
    /// does (base-parameter reduction: the offsets confounded with the placement or moving no
    /// tip held at nominal) and as a diagnosis does (every offset of the family kept at its
    /// widened prior). The exported models are the same; the conditional rotation figures agree;
    /// the diagnosis-style marginal carries the prior of robot 2's joint-1 offset (the figure
    /// the diagnose page showed before, 15× `calibrate --cell`'s on the README's mixed session).
    #[test]
    fn conditional_rotation_is_the_same_for_the_same_exported_model() {
        let tol = Tolerance {
            joint_offset_rad: 10.0 * Tolerance::default().joint_offset_rad,
            origin_xyz_m: 0.0,
            origin_rpy_rad: 0.0,
            tip_m: 0.0,
            ..Tolerance::none()
        };
        let sc = sim_cell(Cell::Wall, tol, false, 23);
        let mut p = sc.problem();
        p.observations = sc.coincident(40, 3e-4, 0.7, 123);
        let active: Vec<usize> = (0..p.observations.len()).collect();
        let init = initial_estimate(&p, None, &active).unwrap();
        let opts = SolveOptions::default();
        let red = reduce(&p, &init, &active).unwrap();
        let held_by_reduce = red.dropped.len();
        let reduced = fit_cell_with(&p, red.layout, &active, Some(&init), &opts).unwrap();
        let kept =
            fit_cell_with(&p, ParamLayout::new(&p, &[]), &active, Some(&init), &opts).unwrap();

        // The same exported model: placement and every joint offset.
        let d = reduced.estimate.b1_from_b2.inverse() * kept.estimate.b1_from_b2;
        assert!(d.translation.vector.norm() < SAME_MODEL_M, "{d}");
        assert!(d.rotation.angle() < SAME_MODEL_RAD, "{d}");
        for r in [Robot::One, Robot::Two] {
            for j in 0..6 {
                let e = ErrorParam::JointOffset { joint: j };
                let (a, b) = (
                    reduced.estimate.robot(r).errors.get(e),
                    kept.estimate.robot(r).errors.get(e),
                );
                assert!(
                    (a - b).abs() < SAME_MODEL_RAD,
                    "{r:?} joint {j}: {a} vs {b}"
                );
            }
        }

        let of_reduced = placement_rotation_posterior(&p, &reduced).unwrap().unwrap();
        let of_kept = placement_rotation_posterior(&p, &kept).unwrap().unwrap();
        // The reduced fit holds nothing more; the kept one conditions on what reduce held.
        assert!(of_reduced.held.is_empty(), "{:?}", of_reduced.held);
        assert_eq!(of_reduced.conditional, of_reduced.marginal);
        assert_eq!(of_kept.held.len(), held_by_reduce, "{:?}", of_kept.held);
        assert!(
            of_kept
                .held
                .iter()
                .any(|e| e.name == "robot 2 joint_offset joint 1"),
            "{}",
            of_kept.basis()
        );
        let rms = |c: &Matrix3<f64>| c.trace().sqrt();
        let (want, got) = (rms(&of_reduced.conditional), rms(&of_kept.conditional));
        assert!(
            (got - want).abs() <= SAME_MODEL_ROTATION_RTOL * want,
            "conditional rotation rms {got:.3e} rad vs calibrate-style {want:.3e} rad"
        );
        let marginal = rms(&of_kept.marginal);
        assert!(
            marginal >= MARGINAL_CARRIES_PRIOR * want,
            "marginal {marginal:.3e} rad vs conditional {want:.3e} rad"
        );
    }

    /// A placement-only fit has nothing to condition on.
    #[test]
    fn placement_only_fit_is_its_own_conditional() {
        let sc = sim_cell(Cell::Floor, Tolerance::none(), false, 5);
        let mut p = sc.problem();
        p.observations = sc.coincident(12, 3e-4, 0.7, 6);
        let active: Vec<usize> = (0..p.observations.len()).collect();
        let fit = fit_cell_with(
            &p,
            ParamLayout::new(&p, &[]),
            &active,
            None,
            &SolveOptions::default(),
        )
        .unwrap();
        let post = placement_rotation_posterior(&p, &fit).unwrap().unwrap();
        assert!(post.held.is_empty());
        assert_eq!(post.conditional, post.marginal);
        assert!(post
            .basis()
            .starts_with("the data determine every fitted unknown"));
    }
}

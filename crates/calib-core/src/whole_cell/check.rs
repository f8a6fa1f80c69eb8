//! The result check run after every whole-cell fit: what the fit says against what the user
//! stated. No I/O; SI units inside, mm and degrees in the report.
//!
//! 1. [`robust_noise_scale`]: the residuals' robust noise scale against the stated σ (the
//!    median of each block's whitened χ² over the median of `χ²_dim`, corrected for the
//!    degrees of freedom the fit used, the hat matrix's trace). Far above 1: the model misfits
//!    (or σ is understated); far below: σ is overstated.
//! 2. [`placement_distance`]: the fitted `b1_from_b2` against the cell's stated placement
//!    (its translation in mm, its rotation angle in degrees), judged against the cell's stated
//!    σ times [`CheckThresholds::placement_k_sigma`], or the default
//!    [`CheckThresholds::default_placement_mm`] / [`CheckThresholds::default_placement_deg`]
//!    when the cell states none.
//! 3. [`layout_shape`]: robot 1's tool points of the two-robot rows (coincident, contact, face
//!    contact), their spread's singular values: nearly collinear (second over first below
//!    [`CheckThresholds::collinear_ratio`]) or coplanar (third over first below
//!    [`CheckThresholds::coplanar_ratio`]).
//!
//! When a check is off, `mistakes.rs` tries the likely data mistakes and `cli-support` frames
//! the outcome (refusal or `warning:`).

use nalgebra::{Isometry3, Matrix3, Vector3};
use serde::Serialize;
use statrs::distribution::{ChiSquared, ContinuousCDF};

use super::solve::{assemble, CellFit};
use super::{CellFitError, CellProblem, ObservationKind};

/// The thresholds of the result check; every default is documented on its field (and in the
/// guide's "when the tool warns" page).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckThresholds {
    /// Robust noise scale above this: a warning (model misfit or σ understated). Default 3: a
    /// correct session's scale stays within ±30 % of 1 for the kinematic model; the placement
    /// model, whose residuals also carry the robots' unmodelled kinematic error, reaches ~2.5 on
    /// the shipped cells with tolerance-sized errors.
    pub noise_high: f64,
    /// Robust noise scale above this with no likely mistake explaining it: a refusal (the
    /// model contradicts the data). Default 30 (the mistakes of issue 21 gave 100–2,300).
    pub noise_refuse: f64,
    /// Robust noise scale below this: a warning (σ overstated: the prior and the blunder screen
    /// then trust the data too little). Default 0.3.
    pub noise_low: f64,
    /// The placement's allowed distance from the cell's stated one, in the cell's stated σ
    /// (`[b1_from_b2] sigma_mm`, `sigma_deg`). Default 5.
    pub placement_k_sigma: f64,
    /// The allowed translation distance when the cell states no σ, mm. Default 50 (a tape
    /// measure's first guess of a base is good to a few cm).
    pub default_placement_mm: f64,
    /// The allowed rotation distance when the cell states no σ, degrees. Default 5.
    pub default_placement_deg: f64,
    /// Second over first singular value of the tool points' spread below this: nearly
    /// collinear. Default 0.05.
    pub collinear_ratio: f64,
    /// Third over first below this: nearly coplanar. Default 0.005 (sim-cell's `planar`
    /// layout, ±1 % thick, stays above).
    pub coplanar_ratio: f64,
    /// A mistake explains a high noise scale when it lowers the scale by this factor.
    /// Default 3.
    pub mistake_gain: f64,
}

impl Default for CheckThresholds {
    fn default() -> Self {
        Self {
            noise_high: 3.0,
            noise_refuse: 30.0,
            noise_low: 0.3,
            placement_k_sigma: 5.0,
            default_placement_mm: 50.0,
            default_placement_deg: 5.0,
            collinear_ratio: 0.05,
            coplanar_ratio: 0.005,
            mistake_gain: 3.0,
        }
    }
}

/// The robust noise scale of `fit` over **every** observation of `problem` (rejected ones
/// included, so that a screen cannot hide a misfit), relative to the stated noise:
/// `sqrt(median_i(t_i/m_dim) · N/(N − p))`, `t_i` the block's whitened χ², `m_dim` the median of
/// `χ²_dim`, `N` the residual rows and `p` the degrees of freedom the fit used (the trace of
/// its hat matrix over the active rows, the layout's width at most; `cov_scale²` divides the
/// covariance back to the stated noise, as `calibrate_cell` scales a placement-only fit's).
/// A blunder moves the median by one rank only.
///
/// # Errors
/// The residuals cannot be evaluated (a model failure at a row).
pub fn robust_noise_scale(
    problem: &CellProblem,
    fit: &CellFit,
    cov_scale: f64,
) -> Result<f64, CellFitError> {
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let sys = assemble(problem, &fit.layout, &fit.estimate, &all, None, false)?;
    let mut ratios = Vec::with_capacity(all.len());
    let mut rows = 0usize;
    for (b, &i) in all.iter().enumerate() {
        let dim = problem.observations[i].kind.rows();
        rows += dim;
        let t = sys.r.rows(sys.block_start[b], dim).norm_squared();
        ratios.push(t / chi2_median(dim));
    }
    if ratios.is_empty() {
        return Ok(1.0);
    }
    ratios.sort_by(f64::total_cmp);
    let mid = ratios.len() / 2;
    let median = if ratios.len() % 2 == 1 {
        ratios[mid]
    } else {
        0.5 * (ratios[mid - 1] + ratios[mid])
    };
    let p = hat_trace(problem, fit, cov_scale)?.min(fit.layout.len() as f64);
    let dof = (rows as f64 - p).max(1.0);
    Ok((median * rows as f64 / dof).sqrt())
}

/// Median of `χ²_dim`.
fn chi2_median(dim: usize) -> f64 {
    ChiSquared::new(dim as f64)
        .map(|d| d.inverse_cdf(0.5))
        .unwrap_or(dim as f64)
}

/// `trace(J·Σ·Jᵀ)/cov_scale²` over the fit's active data rows: the degrees of freedom the fit
/// spent.
fn hat_trace(problem: &CellProblem, fit: &CellFit, cov_scale: f64) -> Result<f64, CellFitError> {
    if fit.layout.is_empty() || fit.active.is_empty() {
        return Ok(0.0);
    }
    let sys = assemble(problem, &fit.layout, &fit.estimate, &fit.active, None, true)?;
    let j = sys.j.rows(0, sys.data_rows);
    let h = j * &fit.covariance * j.transpose();
    let s2 = (cov_scale * cov_scale).max(f64::MIN_POSITIVE);
    Ok(h.trace() / s2)
}

/// How far a fitted placement lies from a stated one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlacementDistance {
    /// Translation distance `‖t(fitted·stated⁻¹)‖`, mm.
    pub translation_mm: f64,
    /// Rotation angle of `fitted·stated⁻¹`, degrees.
    pub rotation_deg: f64,
}

/// [`PlacementDistance`] of `fitted` from `stated` (both `b1_from_b2`).
pub fn placement_distance(fitted: &Isometry3<f64>, stated: &Isometry3<f64>) -> PlacementDistance {
    let delta = fitted * stated.inverse();
    PlacementDistance {
        translation_mm: delta.translation.vector.norm() * 1e3,
        rotation_deg: delta.rotation.angle().to_degrees(),
    }
}

/// The shape of a set of tool points: their spread's singular values, largest first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LayoutShape {
    /// How many points.
    pub points: usize,
    /// The rms spread along the three principal axes, mm, largest first.
    pub spread_mm: [f64; 3],
}

impl LayoutShape {
    /// Second over first principal spread (0 for a line).
    pub fn line_ratio(&self) -> f64 {
        ratio(self.spread_mm[1], self.spread_mm[0])
    }

    /// Third over first principal spread (0 for a plane).
    pub fn plane_ratio(&self) -> f64 {
        ratio(self.spread_mm[2], self.spread_mm[0])
    }
}

fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        0.0
    }
}

/// Robot 1's nominal tool points (b1, at the reported joints) of the two-robot rows of
/// `problem` (coincident, contact, face contact), and their [`LayoutShape`]; `None` with
/// fewer than 3 such rows or a model failure.
pub fn layout_shape(problem: &CellProblem) -> Option<LayoutShape> {
    let mut points: Vec<Vector3<f64>> = Vec::new();
    for o in &problem.observations {
        let (q1, tool1) = match &o.kind {
            ObservationKind::Coincident { q1, tool1, .. }
            | ObservationKind::Contact { q1, tool1, .. }
            | ObservationKind::FaceContact { q1, tool1, .. } => (q1, *tool1),
            _ => continue,
        };
        let tool = problem.robot1.tools.get(tool1)?;
        let f = kinematics::base_from_tip(&problem.robot1.model, q1, &tool.flange_from_tip).ok()?;
        points.push(f.translation.vector);
    }
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    let mut cov = Matrix3::zeros();
    for p in &points {
        let d = p - mean;
        cov += d * d.transpose();
    }
    cov /= n;
    let mut ev: Vec<f64> = cov
        .symmetric_eigenvalues()
        .iter()
        .map(|v| v.max(0.0).sqrt() * 1e3)
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    Some(LayoutShape {
        points: points.len(),
        spread_mm: [ev[0], ev[1], ev[2]],
    })
}

/// Both robots' nominal tool points (each in its own base, at the reported joints) of the
/// coincident rows of `problem`, as point pairs with the rows' source rows: the points problem
/// a placement-only fit of those rows solves (for [`crate::masked_blunders`]). `None` with
/// fewer than 3 such rows or a model failure.
pub fn coincident_pairs(problem: &CellProblem) -> Option<crate::PointPairs> {
    let (mut p_b1, mut p_b2, mut rows) = (Vec::new(), Vec::new(), Vec::new());
    for o in &problem.observations {
        let ObservationKind::Coincident {
            q1,
            q2,
            tool1,
            tool2,
            ..
        } = &o.kind
        else {
            continue;
        };
        let t1 = problem.robot1.tools.get(*tool1)?;
        let t2 = problem.robot2.tools.get(*tool2)?;
        let a = kinematics::base_from_tip(&problem.robot1.model, q1, &t1.flange_from_tip).ok()?;
        let b = kinematics::base_from_tip(&problem.robot2.model, q2, &t2.flange_from_tip).ok()?;
        p_b1.push(nalgebra::Point3::from(a.translation.vector));
        p_b2.push(nalgebra::Point3::from(b.translation.vector));
        rows.push(o.row);
    }
    (rows.len() >= 3).then_some(crate::PointPairs { p_b1, p_b2, rows })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    /// The distance of a placement from itself is 0; a 10 mm shift and a 90° turn read as such.
    #[test]
    fn placement_distance_reads_mm_and_degrees() {
        let a = Isometry3::from_parts(
            Translation3::new(1.0, 0.2, 0.3),
            UnitQuaternion::from_euler_angles(0.1, 0.2, 0.3),
        );
        let d0 = placement_distance(&a, &a);
        assert!(d0.translation_mm < 1e-9 && d0.rotation_deg < 1e-9);
        let shifted = Isometry3::translation(0.01, 0.0, 0.0) * a;
        assert!((placement_distance(&shifted, &a).translation_mm - 10.0).abs() < 1e-9);
        let turned = Isometry3::rotation(Vector3::z() * std::f64::consts::FRAC_PI_2) * a;
        assert!((placement_distance(&turned, &a).rotation_deg - 90.0).abs() < 1e-9);
    }

    /// The line and plane ratios: a line has both 0, a square's plane ratio is 0.
    #[test]
    fn shape_ratios() {
        let line = LayoutShape {
            points: 4,
            spread_mm: [100.0, 0.0, 0.0],
        };
        assert_eq!(line.line_ratio(), 0.0);
        let square = LayoutShape {
            points: 4,
            spread_mm: [100.0, 100.0, 0.0],
        };
        assert_eq!(square.line_ratio(), 1.0);
        assert_eq!(square.plane_ratio(), 0.0);
    }
}

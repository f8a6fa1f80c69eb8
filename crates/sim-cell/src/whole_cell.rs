//! The whole-cell calibration problem of a [`Cell`] and a measured [`Session`]
//! ([`calib_core::whole_cell`]): the cell's two nominal robots with their tips as the only tools,
//! gravity from the mounts, the noise of each handclasp from the cell's `[noise]`, the prior from
//! `[robotN.tolerance]`, and one coincident observation per session row.
//!
//! Noise of a handclasp (b1 axes): the operator's alignment error (σ per b1 axis,
//! `noise.alignment_mm`) plus both robots' repeatability (`noise.repeatability_mm`, isotropic, so
//! robot 2's rotates into b1 unchanged): `Σ = diag(σ_align²) + 2·σ_rep²·I`. The encoder
//! quantisation (`noise.encoder_resolution_deg`, a uniform error of variance step²/12 per joint,
//! ≈ 0.01 mm at the tip for 0.001° on a 1.5 m arm) is left out.

use calib_core::whole_cell::{
    CellEstimate, CellProblem, CellRobot as WholeCellRobot, ConfigPair, Noise3, Observation,
    ObservationKind, RobotCorrection, Tolerance, Tool,
};
use nalgebra::{Matrix3, Vector3};

use crate::cell::{Cell, CellRobot};
use crate::session::Session;

/// Which unknowns the whole-cell fit estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FitModel {
    /// `b1_from_b2` only: both robots held at their nominal models (every tolerance 0), a
    /// weighted least-squares placement from the same session.
    Placement,
    /// `b1_from_b2` with every kinematic parameter the robots' tolerances select (MAP).
    Kinematic,
}

/// Name of the one tool of each robot: the cell's tip (`robotN.tip_mm`).
pub const TIP_TOOL: &str = "tip";

fn robot(r: &CellRobot, model: FitModel) -> WholeCellRobot {
    WholeCellRobot {
        model: r.model.clone(),
        tools: vec![Tool {
            name: TIP_TOOL.into(),
            flange_from_tip: r.flange_from_tip,
        }],
        g_base: r.g_base,
        tolerance: match model {
            FitModel::Placement => Tolerance::none(),
            FitModel::Kinematic => r.tolerance,
        },
    }
}

/// Covariance of one handclasp's residual `p1_b1 − b1_from_b2·p2_b2`, m², b1 axes (see the module
/// documentation). A cell with no noise at all gets 1 µm per axis, so the fit stays defined.
pub fn handclasp_covariance(cell: &Cell) -> Matrix3<f64> {
    let a = cell.noise.alignment_m;
    let rep2 = 2.0 * cell.noise.repeatability_m.powi(2);
    let floor = 1e-6f64.powi(2);
    Matrix3::from_diagonal(&Vector3::new(
        (a.x * a.x + rep2).max(floor),
        (a.y * a.y + rep2).max(floor),
        (a.z * a.z + rep2).max(floor),
    ))
}

/// The whole-cell problem of `cell` and `session`: one coincident observation per session row
/// (row = the CSV's `point` label), tool 0 of each robot = the cell's tip. `model` selects the
/// unknowns ([`FitModel`]). The session must have been read for this cell (its joint vectors have
/// the cell's joint counts; [`Session::read_csv`] checks that); [`CellProblem::check`] reports
/// anything else by row.
pub fn cell_problem(cell: &Cell, session: &Session, model: FitModel) -> CellProblem {
    let cov_m2 = handclasp_covariance(cell);
    let isotropic = cov_m2[(0, 0)] == cov_m2[(1, 1)] && cov_m2[(1, 1)] == cov_m2[(2, 2)];
    let noise = if isotropic {
        Noise3::Isotropic {
            sigma_m: cov_m2[(0, 0)].sqrt(),
        }
    } else {
        Noise3::Covariance { cov_m2 }
    };
    CellProblem {
        robot1: robot(&cell.robot1, model),
        robot2: robot(&cell.robot2, model),
        observations: session
            .points
            .iter()
            .map(|p| Observation {
                row: p.point,
                kind: ObservationKind::Coincident {
                    q1: p.q1.clone(),
                    q2: p.q2.clone(),
                    tool1: 0,
                    tool2: 0,
                    noise,
                },
            })
            .collect(),
        trackers: Vec::new(),
        planes: Vec::new(),
        contacts: Vec::new(),
    }
}

/// Every configuration pair `(q1_i, q2_j)` of the session's rows (`n²` pairs, row-major in `i`):
/// the session's own workspace, over which the calibration's cooperative accuracy is predicted.
pub fn session_config_pairs(session: &Session) -> Vec<ConfigPair> {
    let mut pairs = Vec::with_capacity(session.points.len().pow(2));
    for a in &session.points {
        for b in &session.points {
            pairs.push(ConfigPair {
                q1: a.q1.clone(),
                q2: b.q2.clone(),
                tool1: 0,
                tool2: 0,
            });
        }
    }
    pairs
}

/// The cell's truth as an estimate of `problem` (built by [`cell_problem`] from this cell): the
/// cell's `b1_from_b2` and each robot's true kinematic errors (`[robotN.errors]`, the tip error
/// as tool 0's), for [`calib_core::whole_cell::measure_cooperative_error`] in studies and tests.
pub fn truth_estimate(cell: &Cell, problem: &CellProblem) -> CellEstimate {
    let mut est = CellEstimate::nominal(problem, cell.b1_from_b2);
    let correction = |r: &CellRobot| {
        let mut errors = r.errors.clone();
        let tip = errors.tip;
        errors.tip = Vector3::zeros();
        RobotCorrection {
            errors,
            tool_tip_m: vec![tip],
        }
    };
    est.robot1 = correction(&cell.robot1);
    est.robot2 = correction(&cell.robot2);
    est
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{generate_session, trial_rng, Layout, SessionSpec};
    use calib_core::whole_cell::{calibrate_cell, ScreenOptions, SolveOptions};

    /// Recovery tolerance of b1_from_b2 from a noise-free, error-free session: the solver's
    /// convergence (cost tolerance 1e-10 relative) and the 6-decimal joints leave ≪ 1 µm.
    const PLACEMENT_TOL_M: f64 = 1e-5;

    #[test]
    fn problem_has_one_row_per_point_and_the_cells_prior() {
        let cell = Cell::default_floor_floor();
        let session = generate_session(
            &cell,
            &SessionSpec::new(8, Layout::Tetrahedron, 1.0),
            &mut trial_rng(3, 0),
        )
        .unwrap();
        let p = cell_problem(&cell, &session, FitModel::Kinematic);
        p.check().unwrap();
        assert_eq!(p.observations.len(), 8);
        assert_eq!(p.observations[4].row, session.points[4].point);
        assert_eq!(p.robot2.tolerance, cell.robot2.tolerance);
        let p0 = cell_problem(&cell, &session, FitModel::Placement);
        assert!(p0.robot1.fitted_params().is_empty());
        assert_eq!(session_config_pairs(&session).len(), 64);
        // σ² = 0.3² + 2·0.03² mm² per axis for the shipped floor–floor cell.
        let c = handclasp_covariance(&cell);
        assert!((c[(0, 0)] - (0.3e-3f64.powi(2) + 2.0 * 0.03e-3f64.powi(2))).abs() < 1e-15);
    }

    #[test]
    fn noise_free_placement_fit_recovers_the_cell() {
        let mut cell = Cell::default_floor_floor();
        cell.noise.alignment_m = Vector3::zeros();
        cell.noise.repeatability_m = 0.0;
        cell.noise.encoder_resolution_rad = 0.0;
        let session = generate_session(
            &cell,
            &SessionSpec::new(8, Layout::Tetrahedron, 1.0),
            &mut trial_rng(5, 0),
        )
        .unwrap();
        let p = cell_problem(&cell, &session, FitModel::Placement);
        let cal = calibrate_cell(&p, &SolveOptions::default(), &ScreenOptions::default()).unwrap();
        let x = cal.fit.estimate.b1_from_b2;
        assert!(
            (x.translation.vector - cell.b1_from_b2.translation.vector).amax() < PLACEMENT_TOL_M
        );
        assert!(x.rotation.angle_to(&cell.b1_from_b2.rotation) < PLACEMENT_TOL_M);
        let truth = truth_estimate(&cell, &p);
        assert_eq!(truth.b1_from_b2, cell.b1_from_b2);
    }
}

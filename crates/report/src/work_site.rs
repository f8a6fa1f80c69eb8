//! The verdict at the work site: the calibration's predicted cooperative accuracy where the
//! robots will work, against what the user accepts.
//!
//! 1. [`read_work_points`]: the work site, tool positions in base 1 (mm in the file, m inside).
//! 2. [`predict_work_site`]: each point becomes a meeting pair `(q1, q2)` where both robots'
//!    tips meet head-on (`sim_cell::generate_session` on the cell's nominal robots with the
//!    fitted `b1_from_b2`, no noise: the generator `handclasp plan` uses for its candidates),
//!    and calib-core's [`predict_error`] (the one definition `calibrate --cell` and `plan` use)
//!    gives the rms, its parts and the p95 (with its interval) of the error of the cooperative
//!    vector over those pairs; the placement's
//!    rotation error comes from its 3×3 posterior block ([`summarise_covariances`]),
//!    conditional on the fit's unknowns the data do not determine (the joint zeros a
//!    controller keeps: calib-core's [`placement_rotation_posterior`], the one definition both
//!    commands use), with the marginal block's figures beside it.
//! 3. [`workspace_map`]: the same prediction over the whole workspace
//!    ([`calib_core::whole_cell::workspace_pairs`], the poses `calibrate --cell` reports), with
//!    each pose's meeting point, for the page's map.
//! 4. [`Acceptance::verdict`]: PASS when the upper end of each predicted p95's interval is
//!    within the accepted error, and every work point was predicted.

use std::path::Path;

use calib_core::stats::trial_rng;
use calib_core::whole_cell::{
    placement_rotation_posterior, predict_error, summarise_covariances, workspace_pairs,
    CellCalibration, CellFit, CellProblem, ConfigPair, ObservationKind, PairSet,
    PredictedErrorReport, PredictionSplit, WORKSPACE_POSES, WORKSPACE_SEED,
};
use handclasp_cell::Cell;
use kinematics::base_from_tip;
use nalgebra::{Matrix3, Point3};
use serde::{Deserialize, Serialize};
use sim_cell::plan::nominal_cell;
use sim_cell::{generate_session, Layout, SessionSpec};

use crate::ReportError;

/// One row of the work-points CSV: a tool position in base 1, mm.
#[derive(Debug, Deserialize)]
struct WorkPointRow {
    x_mm: f64,
    y_mm: f64,
    z_mm: f64,
}

/// Reads a work-points CSV (header `x_mm,y_mm,z_mm`, one tool position in base 1 per row, mm)
/// into points in m, base 1.
///
/// Errors: the file cannot be read, a column is missing, a value is not a finite number (the
/// error names the 1-based data row), or the file has no row.
pub fn read_work_points(path: &Path) -> Result<Vec<Point3<f64>>, ReportError> {
    let err = |message: String| ReportError::WorkPoints {
        path: path.to_path_buf(),
        message,
    };
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_path(path)
        .map_err(|e| err(format!("cannot read it ({e})")))?;
    let mut points = Vec::new();
    for (i, row) in reader.deserialize::<WorkPointRow>().enumerate() {
        let row = row.map_err(|e| {
            err(format!(
                "data row {}: {e} (the header is x_mm,y_mm,z_mm: tool positions in base 1, mm)",
                i + 1
            ))
        })?;
        let p = [row.x_mm, row.y_mm, row.z_mm];
        if !p.iter().all(|v| v.is_finite()) {
            return Err(err(format!(
                "data row {}: x_mm, y_mm and z_mm must be finite numbers",
                i + 1
            )));
        }
        points.push(Point3::new(p[0], p[1], p[2]) * 1e-3);
    }
    if points.is_empty() {
        return Err(err(
            "no work point: give one row x_mm,y_mm,z_mm per tool position in base 1".into(),
        ));
    }
    Ok(points)
}

/// What the user accepts at the work site; `None` where nothing is stated.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Acceptance {
    /// Largest accepted rotation error of `b1_from_b2` (the p95), degrees.
    pub accept_deg: Option<f64>,
    /// Largest accepted cooperative position error (the p95), mm.
    pub accept_mm: Option<f64>,
}

impl Acceptance {
    /// An acceptance, checked: each stated threshold positive and finite.
    ///
    /// Errors: a threshold that is zero, negative or not finite.
    pub fn new(accept_mm: Option<f64>, accept_deg: Option<f64>) -> Result<Self, ReportError> {
        for (name, v) in [("mm", accept_mm), ("deg", accept_deg)] {
            if let Some(value) = v {
                if !(value.is_finite() && value > 0.0) {
                    return Err(ReportError::Acceptance { name, value });
                }
            }
        }
        Ok(Acceptance {
            accept_deg,
            accept_mm,
        })
    }

    /// The verdict on `w` (whose own acceptance fields are ignored) and why, one sentence per
    /// check: PASS when every stated threshold holds at the upper end of its p95's interval and
    /// every work point was predicted; FAIL otherwise; [`Verdict::NoAcceptance`] when nothing is
    /// stated.
    pub fn verdict(&self, w: &WorkSiteReport) -> (Verdict, String) {
        if self.accept_mm.is_none() && self.accept_deg.is_none() {
            return (
                Verdict::NoAcceptance,
                "no acceptance stated: give the largest error the job accepts (mm, and degrees \
                 for the placement's rotation) to get PASS or FAIL"
                    .into(),
            );
        }
        let mut pass = true;
        let mut why = Vec::new();
        if let Some(a) = self.accept_mm {
            let [lo, hi] = w.predicted_p95_ci_mm;
            if hi <= a {
                why.push(format!(
                    "the predicted p95 position error {:.3} mm (95 % interval {lo:.3}–{hi:.3}) is within the accepted {a:.3} mm",
                    w.predicted_p95_mm
                ));
            } else {
                pass = false;
                let how = if w.predicted_p95_mm > a {
                    "exceeds"
                } else {
                    "is not shown to be within (its interval reaches above)"
                };
                why.push(format!(
                    "the predicted p95 position error {:.3} mm (95 % interval {lo:.3}–{hi:.3}) {how} the accepted {a:.3} mm",
                    w.predicted_p95_mm
                ));
            }
        }
        if let Some(a) = self.accept_deg {
            match &w.placement_rotation {
                Some(r) => {
                    let [lo, hi] = r.p95_ci_deg;
                    let ok = hi <= a;
                    pass &= ok;
                    let basis = if r.conditional_on.is_empty() {
                        ""
                    } else {
                        " (with the exported joint zeros)"
                    };
                    why.push(format!(
                        "the placement's predicted p95 rotation error{basis} {:.4}° (95 % interval {lo:.4}–{hi:.4}) {} the accepted {a:.4}°",
                        r.p95_deg,
                        if ok { "is within" } else if r.p95_deg > a { "exceeds" } else { "is not shown to be within" }
                    ));
                }
                None if w.one_robot => {
                    pass = false;
                    why.push(
                        "a one-robot cell has no placement, so no rotation error is predicted \
                         (--accept-deg checks b1_from_b2's; the tool's orientation is not \
                         predicted): drop --accept-deg"
                            .into(),
                    );
                }
                None => {
                    pass = false;
                    why.push(
                        "the placement's rotation was not fitted, so its error is not predicted"
                            .into(),
                    );
                }
            }
        }
        if !w.unreachable.is_empty() {
            pass = false;
            why.push(format!(
                "{} work point(s) are not predicted: {} (rows {})",
                w.unreachable.len(),
                if w.one_robot {
                    "robot 1 does not reach them head-on"
                } else {
                    "both robots do not reach them head-on"
                },
                w.unreachable
                    .iter()
                    .map(|u| u.row.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        let verdict = if pass { Verdict::Pass } else { Verdict::Fail };
        (verdict, why.join("; "))
    }
}

/// PASS, FAIL, or no acceptance stated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Every stated threshold holds at the work site.
    Pass,
    /// A stated threshold does not hold, or a work point was not predicted.
    Fail,
    /// Nothing was accepted or refused: no threshold was stated.
    NoAcceptance,
}

impl Verdict {
    /// `PASS`, `FAIL` or `NO ACCEPTANCE STATED`: the page's headline.
    pub fn headline(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::NoAcceptance => "NO ACCEPTANCE STATED",
        }
    }
}

/// One work point and its own prediction.
#[derive(Debug, Clone, Serialize)]
pub struct WorkPointReport {
    /// The tool position in base 1, mm.
    pub p_b1_mm: [f64; 3],
    /// Predicted rms of the cooperative error there, mm.
    pub predicted_rms_mm: f64,
    /// 1-based row of the work-points file (1 for the teach centre).
    pub row: usize,
}

/// A work point that was not predicted.
#[derive(Debug, Clone, Serialize)]
pub struct UnreachableReport {
    /// The tool position in base 1, mm.
    pub p_b1_mm: [f64; 3],
    /// 1-based row of the work-points file.
    pub row: usize,
    /// Why (which robot, what would work).
    pub why: String,
}

/// The predicted rotation error of `b1_from_b2` (the norm of its rotation-vector error), deg:
/// conditional on the fit's unknowns the data do not determine (the figure a controller that
/// keeps the exported joint zeros uses; see [`placement_rotation_posterior`]), with the marginal
/// figures beside it.
#[derive(Debug, Clone, Serialize)]
pub struct RotationPredictionReport {
    /// Which figure this is, in words: conditional on which undetermined directions, or the
    /// plain posterior when the data determine every fitted unknown.
    pub basis: String,
    /// The fitted unknowns the data do not determine (readable names), held at their exported
    /// values for the figures; empty when there are none.
    pub conditional_on: Vec<String>,
    /// The marginal figures (every fitted unknown free, the prior of the undetermined ones
    /// included): the physical base frame's uncertainty, which the session cannot tell.
    pub marginal: RotationFigures,
    /// Distribution-free 95 % interval of the p95 from the seeded draws, degrees.
    pub p95_ci_deg: [f64; 2],
    /// Predicted 95th percentile, degrees.
    pub p95_deg: f64,
    /// Predicted rms, degrees.
    pub rms_deg: f64,
}

/// rms and p95 (with its interval) of a rotation error, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RotationFigures {
    /// Distribution-free 95 % interval of the p95 from the seeded draws, degrees.
    pub p95_ci_deg: [f64; 2],
    /// Predicted 95th percentile, degrees.
    pub p95_deg: f64,
    /// Predicted rms, degrees.
    pub rms_deg: f64,
}

impl RotationFigures {
    /// The figures of a rotation-vector error with covariance `c` (rad²), the p95 from draws
    /// seeded by `seed` ([`summarise_covariances`]).
    fn of(c: Matrix3<f64>, seed: u64) -> Self {
        let r = summarise_covariances(&[c], seed);
        RotationFigures {
            p95_ci_deg: r.predicted_p95_ci_m.map(f64::to_degrees),
            p95_deg: r.predicted_p95_m.to_degrees(),
            rms_deg: r.predicted_rms_m.to_degrees(),
        }
    }
}

/// The verdict at the work site: the predicted cooperative accuracy there (mm), the
/// placement's rotation error (degrees), what the user accepts, and PASS or FAIL with why.
/// On a one-robot cell ([`WorkSiteReport::one_robot`]) the position figures are robot 1's
/// absolute accuracy: the error of its tool's position in its base frame (the frame the
/// measuring device's registration puts it in), and there is no placement.
/// Fields in alphabetical order (the JSON key order of every report).
#[derive(Debug, Clone, Serialize)]
pub struct WorkSiteReport {
    /// What the user accepts.
    pub acceptance: Acceptance,
    /// A one-robot cell (JSON `"one_robot": true`, absent for two robots): the predicted
    /// errors are of robot 1's tool position in its base frame (its absolute accuracy), not of
    /// the vector between two tools, and there is no placement rotation.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub one_robot: bool,
    /// The prediction at the work points in parts (data-determined, prior-asserted, model
    /// error) with its 95 % bound, mm.
    pub parts_mm: PredictedErrorReport,
    /// The predicted rotation error of `b1_from_b2`; `None` when the fit did not estimate it,
    /// and on a one-robot cell (no placement).
    pub placement_rotation: Option<RotationPredictionReport>,
    /// The predicted points.
    pub points: Vec<WorkPointReport>,
    /// Distribution-free 95 % interval of the p95 from the seeded draws, mm.
    pub predicted_p95_ci_mm: [f64; 2],
    /// Predicted 95th percentile of the cooperative position error over the points (one-robot
    /// cell: of robot 1's tool position in its base frame), mm.
    pub predicted_p95_mm: f64,
    /// Predicted rms of the cooperative position error over the points (one-robot cell: of
    /// robot 1's tool position in its base frame), mm.
    pub predicted_rms_mm: f64,
    /// Seed of the p95 draws.
    pub seed: u64,
    /// Where the points come from (a file, or the cell's teach centre).
    pub source: String,
    /// Work points both robots do not reach head-on (one-robot cell: robot 1 does not reach
    /// head-on), not predicted.
    pub unreachable: Vec<UnreachableReport>,
    /// PASS, FAIL or no acceptance stated.
    pub verdict: Verdict,
    /// Why, one clause per check.
    pub why: String,
}

impl WorkSiteReport {
    /// What the position figures are, for a sentence: `cooperative accuracy` (two robots), or
    /// `absolute accuracy of robot 1's tool (its position in robot 1's base frame)` (a
    /// one-robot cell).
    pub fn accuracy_name(&self) -> &'static str {
        if self.one_robot {
            "absolute accuracy of robot 1's tool (its position in robot 1's base frame)"
        } else {
            "cooperative accuracy"
        }
    }
}

/// The meeting pairs with their 0-based work-point index, and the points that failed with why.
type PlacedPoints = (Vec<(usize, ConfigPair)>, Vec<(usize, String)>);

/// The work site's meeting pairs: each point (m, b1) placed as a noise-free head-on handclasp
/// on `cell`'s nominal robots with the placement `b1_from_b2` (the fit's). Returns the pairs
/// with their 0-based point index, and the points that failed with why.
fn work_site_pairs(
    cell: &Cell,
    b1_from_b2: nalgebra::Isometry3<f64>,
    points_b1: &[Point3<f64>],
    seed: u64,
) -> PlacedPoints {
    let mut nominal = nominal_cell(cell);
    nominal.b1_from_b2 = b1_from_b2;
    let mut pairs = Vec::new();
    let mut failed = Vec::new();
    for (i, p) in points_b1.iter().enumerate() {
        let spec = SessionSpec {
            points_b1: Some(vec![*p]),
            ..SessionSpec::new(1, Layout::Random, 1.0)
        };
        // The placement is noise-free; the generator's draws only pick among approach
        // directions, seeded per point so any point can be replayed alone.
        let mut rng = trial_rng(seed, i as u64);
        match generate_session(&nominal, &spec, &mut rng) {
            Ok(s) => match s.points.into_iter().next() {
                Some(pt) => pairs.push((
                    i,
                    ConfigPair {
                        q1: pt.q1,
                        q2: pt.q2,
                        tool1: 0,
                        tool2: 0,
                    },
                )),
                None => failed.push((i, "no handclasp placed".into())),
            },
            // The generator numbers the one point it was given 1; say "the work point".
            Err(e) => failed.push((
                i,
                e.to_string()
                    .replacen("teach point 1 ", "the work point ", 1),
            )),
        }
    }
    (pairs, failed)
}

/// The predicted rotation error of the placement of `fit` (of `problem`): conditional on the
/// fit's undetermined unknowns, with the marginal beside it; `None` when the layout does not fit
/// the placement's rotation.
///
/// Errors: the linearisation at the fit's estimate fails.
pub fn placement_rotation_report(
    problem: &CellProblem,
    fit: &CellFit,
    seed: u64,
) -> Result<Option<RotationPredictionReport>, ReportError> {
    let Some(post) = placement_rotation_posterior(problem, fit).map_err(ReportError::Prediction)?
    else {
        return Ok(None);
    };
    let conditional = RotationFigures::of(post.conditional, seed);
    Ok(Some(RotationPredictionReport {
        basis: post.basis(),
        conditional_on: post.held.iter().map(|e| e.name.clone()).collect(),
        marginal: RotationFigures::of(post.marginal, seed),
        p95_ci_deg: conditional.p95_ci_deg,
        p95_deg: conditional.p95_deg,
        rms_deg: conditional.rms_deg,
    }))
}

/// The verdict at the work site `points_b1` (m, base 1; described by `source`) of the
/// calibration `cal` of `problem` (built from `cell`): see the module documentation. `seed`
/// seeds the p95 draws and the head-on placement of each point.
///
/// Errors: no point reachable by both robots head-on, or a prediction the models reject.
pub fn predict_work_site(
    cell: &Cell,
    problem: &CellProblem,
    cal: &CellCalibration,
    points_b1: &[Point3<f64>],
    source: &str,
    acceptance: Acceptance,
    seed: u64,
) -> Result<WorkSiteReport, ReportError> {
    predict_work_site_of_fit(
        cell,
        problem,
        &cal.fit,
        cal.noise_scale,
        points_b1,
        source,
        acceptance,
        seed,
    )
}

/// [`predict_work_site`] for a fit of `problem` that is not a [`CellCalibration`] (one model
/// of a diagnosis: the model `diagnose --export` writes), through
/// [`PredictionSplit::of_fit`] with `noise_scale` (1 when the problem's σ are already the
/// ones to trust).
///
/// Errors: as [`predict_work_site`].
#[allow(clippy::too_many_arguments)]
pub fn predict_work_site_of_fit(
    cell: &Cell,
    problem: &CellProblem,
    fit: &CellFit,
    noise_scale: f64,
    points_b1: &[Point3<f64>],
    source: &str,
    acceptance: Acceptance,
    seed: u64,
) -> Result<WorkSiteReport, ReportError> {
    let (pairs, failed) = work_site_pairs(cell, fit.estimate.b1_from_b2, points_b1, seed);
    if pairs.is_empty() {
        return Err(ReportError::NoReachableWorkPoint {
            points: points_b1.len(),
            first: failed.first().map(|f| f.1.clone()).unwrap_or_default(),
        });
    }
    let config: Vec<ConfigPair> = pairs.iter().map(|(_, p)| p.clone()).collect();
    let split =
        PredictionSplit::of_fit(problem, fit, noise_scale).map_err(ReportError::Prediction)?;
    let prediction = predict_with(problem, fit, &split, &config, PairSet::WorkPoints, seed)?;
    let mm = |p: &Point3<f64>| [p.x * 1e3, p.y * 1e3, p.z * 1e3];
    let points = pairs
        .iter()
        .zip(&prediction.per_pair_rms_m)
        .map(|((i, _), rms)| WorkPointReport {
            p_b1_mm: mm(&points_b1[*i]),
            predicted_rms_mm: rms * 1e3,
            row: i + 1,
        })
        .collect();
    let unreachable = failed
        .into_iter()
        .map(|(i, why)| UnreachableReport {
            p_b1_mm: mm(&points_b1[i]),
            row: i + 1,
            why,
        })
        .collect();
    // A one-robot cell's placement is its stand-in's, held at the identity: no rotation to
    // predict.
    let placement_rotation = if cell.one_robot {
        None
    } else {
        placement_rotation_report(problem, fit, seed)?
    };
    let mut report = WorkSiteReport {
        acceptance,
        one_robot: cell.one_robot,
        parts_mm: PredictedErrorReport::from(&prediction),
        placement_rotation,
        points,
        predicted_p95_ci_mm: prediction.p95_ci_m.map(|v| v * 1e3),
        predicted_p95_mm: prediction.p95_m * 1e3,
        predicted_rms_mm: prediction.rms_m * 1e3,
        seed,
        source: source.to_string(),
        unreachable,
        verdict: Verdict::NoAcceptance,
        why: String::new(),
    };
    let (verdict, why) = acceptance.verdict(&report);
    report.verdict = verdict;
    report.why = why;
    Ok(report)
}

/// The predicted error of `cal` over `pairs` of `pair_set` (calib-core's one definition,
/// [`predict_error`], with the calibration's split).
fn predict_over(
    problem: &CellProblem,
    cal: &CellCalibration,
    pairs: &[ConfigPair],
    pair_set: PairSet,
    seed: u64,
) -> Result<calib_core::whole_cell::PredictedError, ReportError> {
    let split = PredictionSplit::of_calibration(problem, cal).map_err(ReportError::Prediction)?;
    predict_with(problem, &cal.fit, &split, pairs, pair_set, seed)
}

/// The predicted error of `fit` over `pairs` with its `split` ([`predict_error`]).
fn predict_with(
    problem: &CellProblem,
    fit: &CellFit,
    split: &PredictionSplit,
    pairs: &[ConfigPair],
    pair_set: PairSet,
    seed: u64,
) -> Result<calib_core::whole_cell::PredictedError, ReportError> {
    predict_error(
        problem,
        &fit.layout,
        &fit.estimate,
        split,
        pairs,
        pair_set,
        seed,
    )
    .map_err(ReportError::Prediction)
}

/// The predicted error over the whole workspace, pose by pose, for the page's map.
#[derive(Debug, Clone)]
pub struct WorkspaceMap {
    /// Each pose's meeting point (robot 1's nominal tip in base 1), mm.
    pub points_mm: Vec<[f64; 3]>,
    /// Each pose's predicted cooperative rms, mm.
    pub rms_mm: Vec<f64>,
    /// The session's meeting points (robot 1's tip of each coincident or contact row), mm.
    pub session_mm: Vec<[f64; 3]>,
    /// The prediction over all of them (the JSON's `workspace_accuracy_mm`).
    pub report: PredictedErrorReport,
}

/// The predicted error of `cal` over the whole workspace of `problem`
/// ([`workspace_pairs`] at the fitted placement, [`WORKSPACE_POSES`] poses, seed
/// [`WORKSPACE_SEED`]: the poses `calibrate --cell` reports), pose by pose; `seed` seeds the
/// p95's draws.
///
/// Errors: no workspace pose is reachable, or the models reject a pose.
pub fn workspace_map(
    problem: &CellProblem,
    cal: &CellCalibration,
    seed: u64,
) -> Result<WorkspaceMap, ReportError> {
    let poses = workspace_pairs(
        problem,
        &cal.fit.estimate.b1_from_b2,
        WORKSPACE_POSES,
        WORKSPACE_SEED,
    );
    let pairs: Vec<ConfigPair> = poses.iter().map(|p| p.pair.clone()).collect();
    let prediction = predict_over(problem, cal, &pairs, PairSet::Workspace, seed)?;
    let mm = |p: &Point3<f64>| [p.x * 1e3, p.y * 1e3, p.z * 1e3];
    let r1 = &problem.robot1;
    let session_mm = problem
        .observations
        .iter()
        .filter_map(|o| match &o.kind {
            ObservationKind::Coincident { q1, tool1, .. }
            | ObservationKind::Contact { q1, tool1, .. } => {
                let tool = r1.tools.get(*tool1)?;
                base_from_tip(&r1.model, q1, &tool.flange_from_tip)
                    .ok()
                    .map(|t| mm(&Point3::from(t.translation.vector)))
            }
            _ => None,
        })
        .collect();
    Ok(WorkspaceMap {
        points_mm: poses.iter().map(|p| mm(&p.p_b1)).collect(),
        rms_mm: prediction.per_pair_rms_m.iter().map(|v| v * 1e3).collect(),
        session_mm,
        report: PredictedErrorReport::from(&prediction),
    })
}

/// The work site's points and where they come from: `file`'s points (m, base 1, as
/// [`read_work_points`] read them) or, without a file, the cell's `[teach]` centre.
pub fn work_site_points(
    cell: &Cell,
    file: Option<(&Path, &[Point3<f64>])>,
) -> (Vec<Point3<f64>>, String) {
    match file {
        Some((path, points)) => (
            points.to_vec(),
            format!("{} points of {}", points.len(), path.display()),
        ),
        None => {
            let c = cell.centre_b1 * 1e3;
            (
                vec![cell.centre_b1],
                format!(
                    "the cell's teach centre ({:.1}, {:.1}, {:.1}) mm in base 1",
                    c.x, c.y, c.z
                ),
            )
        }
    }
}

/// Which model of a whole-cell diagnosis a verdict at the work site is for.
#[derive(Debug, Clone, Serialize)]
pub struct VerdictModel {
    /// In words: which model, what it holds, what the prediction assumes.
    pub description: String,
    /// The named families in it (besides the placement and the session's nuisances), in
    /// selection order.
    pub families: Vec<String>,
    /// `do_no_harm` (what `diagnose --export` writes) or `full` (every named family: what
    /// `diagnose --export --force` writes).
    pub model: &'static str,
    /// The named families it leaves out (the do-no-harm rule's withheld ones; empty for
    /// `full`).
    pub withheld: Vec<String>,
}

/// The verdict at the work site `points_b1` (m, base 1; described by `source`) of the model a
/// whole-cell diagnosis `report` of a session on `cell` exports: the do-no-harm rule's
/// ([`diagnose::CellDiagnoseReport::export_model`]), or the full model when `full` (what
/// `--export --force` writes). Predicted by [`predict_work_site_of_fit`] from that model's fit
/// on the rows used, with the diagnosis's prior (the tolerances × its prior widening) and each
/// kind's σ scaled to its noise level; families the model does not hold are at nominal, and
/// their tolerances are not in the prediction.
///
/// Errors: as [`predict_work_site`].
pub fn diagnosis_work_site(
    cell: &Cell,
    report: &diagnose::CellDiagnoseReport,
    full: bool,
    points_b1: &[Point3<f64>],
    source: &str,
    acceptance: Acceptance,
    seed: u64,
) -> Result<(WorkSiteReport, VerdictModel), ReportError> {
    let all: Vec<String> = report
        .effects
        .iter()
        .map(|e| e.family.name.clone())
        .collect();
    let (model, families, withheld, fitted) = if full || !report.do_no_harm.withholds() {
        ("full", all, Vec::new(), &report.full_model)
    } else {
        (
            "do_no_harm",
            report.do_no_harm.exported_families.clone(),
            report
                .do_no_harm
                .withheld
                .iter()
                .map(|w| w.family.clone())
                .collect(),
            &report.export_model,
        )
    };
    let holds = if families.is_empty() {
        "the placement only (both robots nominal)".to_string()
    } else {
        format!("the placement and {}", families.join(", "))
    };
    let which = if model == "do_no_harm" {
        format!(
            "the model `diagnose --export` writes, the do-no-harm rule's: {holds}; withheld: {} \
             (`--export --force` writes them)",
            withheld.join(", ")
        )
    } else if report.do_no_harm.withholds() {
        format!(
            "the full model `diagnose --export --force` writes: {holds}, the families the \
             do-no-harm rule withholds included"
        )
    } else {
        format!(
            "the model `diagnose --export` writes (the do-no-harm rule withholds nothing): {holds}"
        )
    };
    let description = format!(
        "{which}. Predicted from its fit on the {} rows used, with the diagnosis's prior (the \
         cell's tolerances × {}) and each kind's σ scaled to its noise level; the families it \
         does not hold are at nominal, and their tolerances are not in the prediction",
        report.rows_used, report.prior_widening
    );
    let w = predict_work_site_of_fit(
        cell,
        &fitted.problem,
        &fitted.fit,
        1.0,
        points_b1,
        source,
        acceptance,
        seed,
    )?;
    Ok((
        w,
        VerdictModel {
            description,
            families,
            model,
            withheld,
        },
    ))
}

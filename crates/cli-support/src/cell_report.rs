//! The whole-cell calibration's report, as `handclasp calibrate --cell CELL --session SESSION`
//! and the Python package's `calibrate_cell` give it ([`calibrate_session`]): the fit
//! (`calib_core::whole_cell::calibrate_cell`) of the session's problem
//! (`handclasp_cell::cell_problem`), framed by the session.
//!
//! 1. [`calibrate_session`] builds the problem (`cell_problem`) and fits it (`calibrate_cell`,
//!    starting from the cell's `b1_from_b2` when there are too few coincident rows);
//! 2. it predicts the cooperative accuracy over the session's meeting pairs
//!    (`predict_cooperative_accuracy`, seed [`P95_SEED`]);
//! 3. [`CellReport::new`] frames the calibration's report by the session; [`render_text`] prints it.
//!
//! Predicted cooperative accuracy: the posterior error of the predicted vector from tip 2 to tip
//! 1 (b1), over **the session's meeting pairs `(q1_i, q2_i)`** of its coincident and contact rows
//! (rejected rows included: their joint vectors are still the session's workspace), rms exact,
//! p95 from a seeded draw (seed [`P95_SEED`]).
//!
//! Output units: mm and degrees (ZYZ, `R = Rz(φ)·Ry(θ)·Rz(ψ)`); parameters in their unit (`deg`,
//! `mm`, `ratio`, `deg/kNm`).

use std::fmt::Write as _;

use calib_core::whole_cell::{
    calibrate_cell_with, format_scale, predict_error, session_coverage, widen_prior,
    workspace_pairs, CalibrationReport, CellCalibration, CellFitError, CellProblem, ConfigPair,
    CoverageReport, DropReason, ErrorFamily, FittedPlacementReport, GroupsReport, Kind,
    NuisanceReport, PairSet, ParameterReport, PlacementSigmaReport, PredictedErrorReport,
    PredictionSplit, PriorScaleReport, RejectedRowReport, ScaleMethod, ScreenOptions, SolveOptions,
    UnidentifiableReport, WORKSPACE_POSES, WORKSPACE_SEED,
};
use calib_core::{PoseForms, StopReason};
use handclasp_cell::problem::{cell_problem, session_meeting_pairs, FitModel};
use handclasp_cell::{Cell, Session};
use serde::Serialize;

use crate::result_check::{
    check_result, misfit_outcome, screen_outcome, ResultCheckReport, ScreenMode, ScreenReport,
};

/// Seed of the predicted p95's Monte Carlo draw.
pub const P95_SEED: u64 = 1;

/// Seed of the coverage report's reach samples
/// (`calib_core::whole_cell::session_coverage`).
pub const COVERAGE_SEED: u64 = 1;

/// How many of the largest kinematic corrections the text report lists.
const TEXT_LARGEST: usize = 10;

/// How many partners of a merged parameter the text report names (largest coefficients first).
const MERGE_PARTNERS_SHOWN: usize = 3;

/// The whole-cell model; serialised as its [`CellModel::name`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CellModel {
    /// b1_from_b2 and every identifiable kinematic parameter of both robots (MAP).
    Kinematic,
    /// b1_from_b2 only, both robots nominal.
    Placement,
    /// [`CellModel::Kinematic`] plus each robot's lumped gravity compliance (compliance × mass
    /// moment, no masses needed).
    #[serde(rename = "kinematic+compliance")]
    KinematicCompliance,
}

impl CellModel {
    /// The problem's model.
    pub fn fit_model(self) -> FitModel {
        match self {
            CellModel::Kinematic => FitModel::Kinematic,
            CellModel::Placement => FitModel::Placement,
            CellModel::KinematicCompliance => FitModel::KinematicCompliance,
        }
    }

    /// `kinematic`, `placement` or `kinematic+compliance`.
    pub fn name(self) -> &'static str {
        match self {
            CellModel::Kinematic => "kinematic",
            CellModel::Placement => "placement",
            CellModel::KinematicCompliance => "kinematic+compliance",
        }
    }

    /// From [`CellModel::name`]; `None` for any other text.
    pub fn from_name(name: &str) -> Option<CellModel> {
        match name {
            "kinematic" => Some(CellModel::Kinematic),
            "placement" => Some(CellModel::Placement),
            "kinematic+compliance" => Some(CellModel::KinematicCompliance),
            _ => None,
        }
    }
}

/// Why [`calibrate_session`] failed; the caller names the files.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CellCalibrationError {
    /// The session fails the input checks every command shares
    /// ([`handclasp_cell::check_session_inputs`]: no rows, radians, metres, duplicates).
    #[error(transparent)]
    Session(#[from] handclasp_cell::SessionCheckError),
    /// The fit failed (the problem is invalid, or the solver met a non-finite value).
    #[error(transparent)]
    Fit(CellFitError),
    /// The cooperative-accuracy prediction failed.
    #[error("predicting the cooperative accuracy over the session's meeting pairs")]
    Prediction(#[source] CellFitError),
    /// The coverage report (joint ranges and reach) failed.
    #[error("the session's coverage of the robots' joint ranges and reach")]
    Coverage(#[source] CellFitError),
    /// `kinematic+compliance` on a shared-trunk cell with one-robot rows (tracker, plane) that
    /// do not give the other arm's joints: the other arm's weight loads the trunk, so its
    /// posture is needed at every row ([`Session::other_arm_q`]).
    #[error(
        "--model kinematic+compliance on a shared-trunk cell (robot 2 shares {shared_joints} joints \
         with robot 1): the other arm's weight loads the trunk, so every tracker or plane row needs \
         the other arm's joints, but {} row(s) leave them empty (points {}); fill the other \
         robot's joint columns of those rows ({columns}) with the other arm's posture at that \
         moment (its trunk columns equal to the row's), or use --model kinematic",
        points.len(),
        crate::cell_report::list_points(points)
    )]
    OtherArmJointsMissing {
        /// Robot 2's joints shared with robot 1.
        shared_joints: usize,
        /// The point numbers of the one-robot rows without the other arm's joints.
        points: Vec<usize>,
        /// The columns to fill, e.g. `r2_q1_deg … r2_q10_deg` (both robots' when rows of both
        /// lack them).
        columns: String,
    },
}

/// Up to 8 point numbers, then "…" and the count left.
fn list_points(points: &[usize]) -> String {
    let shown: Vec<String> = points.iter().take(8).map(usize::to_string).collect();
    if points.len() > 8 {
        format!("{}, … ({} more)", shown.join(", "), points.len() - 8)
    } else {
        shown.join(", ")
    }
}

/// On a shared-trunk cell fitted with `kinematic+compliance`, the one-robot rows of `session`
/// without the other arm's joints, refused with the columns to fill; `Ok` otherwise.
fn check_other_arm_joints(
    cell: &Cell,
    session: &Session,
    model: CellModel,
) -> Result<(), CellCalibrationError> {
    if model != CellModel::KinematicCompliance || cell.shared_joints == 0 {
        return Ok(());
    }
    let mut points = Vec::new();
    let mut robots = Vec::new();
    for o in &session.observations {
        if let Some((robot, _, _)) = o.kind.single() {
            if !session.other_arm_q.contains_key(&o.point) {
                points.push(o.point);
                if !robots.contains(&robot.other()) {
                    robots.push(robot.other());
                }
            }
        }
    }
    if points.is_empty() {
        return Ok(());
    }
    robots.sort_by_key(|r| r.number());
    let columns = robots
        .iter()
        .map(|&r| {
            let c = cell.robot(r);
            let kinds: Vec<bool> = c
                .model
                .joints()
                .iter()
                .map(|j| j.kind.is_prismatic())
                .collect();
            let n = r.number();
            format!(
                "`{}` … `{}` on robot {}'s rows",
                handclasp_cell::joint_column(n, 1, kinds.first().copied().unwrap_or(false)),
                handclasp_cell::joint_column(
                    n,
                    kinds.len(),
                    kinds.last().copied().unwrap_or(false)
                ),
                r.other().number()
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    Err(CellCalibrationError::OtherArmJointsMissing {
        shared_joints: cell.shared_joints,
        points,
        columns,
    })
}

/// A whole-cell calibration: its report, the problem and the fit it came from (for the export).
#[derive(Debug)]
pub struct SessionCalibration {
    /// The report (the CLI's JSON).
    pub report: CellReport,
    /// The problem fitted.
    pub problem: CellProblem,
    /// The calibration (`calibration.fit.estimate` is what an export writes).
    pub calibration: CellCalibration,
}

/// Calibrates `session` of `cell` with `model`: the MAP fit with blunder screening, and the
/// predicted cooperative accuracy over the session's meeting pairs (none without coincident or
/// contact rows). The session first passes the input checks every command shares
/// ([`handclasp_cell::check_session_inputs`]), so a header-only session is refused, not fitted.
pub fn calibrate_session(
    cell: &Cell,
    session: &Session,
    model: CellModel,
) -> Result<SessionCalibration, CellCalibrationError> {
    calibrate_session_with(cell, session, model, ScreenMode::Auto, None)
}

/// [`calibrate_session`] with the blunder screen's mode (`--screen`) and the prior scale fixed
/// at `tolerance_scale` (`calibrate --cell --tolerance-scale X`: every tolerance × X, 1e-3 …
/// 100; `None`: the evidence's choice): the fit at the stated tolerances, the result check
/// ([`crate::result_check`]) on it, and only when the check does not refuse it, the widening
/// the evidence asks for (or the caller's scale above 1); the report's
/// [`CellReport::result_check`] is the check of the fit returned (with the stated fit's
/// findings when the tolerances were widened).
pub fn calibrate_session_with(
    cell: &Cell,
    session: &Session,
    model: CellModel,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
) -> Result<SessionCalibration, CellCalibrationError> {
    calibrate_session_withholding(cell, session, model, screen, tolerance_scale, &[])
}

/// [`calibrate_session_with`] with the error families `withheld` left nominal: their
/// tolerances zeroed in the problem ([`ErrorFamily::withhold_from`]) before anything is fitted,
/// so the whole calibration (screen, result check, prior-scale choice, predictions) is a refit
/// without them (the do-no-harm export's model, [`crate::do_no_harm`]).
pub fn calibrate_session_withholding(
    cell: &Cell,
    session: &Session,
    model: CellModel,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
    withheld: &[ErrorFamily],
) -> Result<SessionCalibration, CellCalibrationError> {
    let (problem, cal, check) =
        checked_calibration(cell, session, model, screen, tolerance_scale, withheld)?;
    let pairs = session_meeting_pairs(session);
    let (cooperative, workspace) = if pairs.is_empty() {
        (None, None)
    } else {
        let split = PredictionSplit::of_calibration(&problem, &cal)
            .map_err(CellCalibrationError::Prediction)?;
        let meeting = predict_over(&problem, &cal, &split, &pairs, PairSet::MeetingPairs)
            .map_err(CellCalibrationError::Prediction)?;
        let poses = workspace_pairs(
            &problem,
            &cal.fit.estimate.b1_from_b2,
            WORKSPACE_POSES,
            WORKSPACE_SEED,
        );
        let over: Vec<ConfigPair> = poses.into_iter().map(|p| p.pair).collect();
        let workspace = if over.is_empty() {
            None
        } else {
            Some(
                predict_over(&problem, &cal, &split, &over, PairSet::Workspace)
                    .map_err(CellCalibrationError::Prediction)?,
            )
        };
        (Some(meeting), workspace)
    };
    let coverage = CoverageReport::from(
        &session_coverage(&problem, COVERAGE_SEED).map_err(CellCalibrationError::Coverage)?,
    );
    let rows_by_kind =
        (!session.is_handclasp_only()).then(|| RowsByKind::from_counts(session.kind_counts()));
    let mut report = CellReport::new(
        cal.report(&problem),
        model,
        session.len(),
        rows_by_kind,
        cooperative,
        coverage,
    );
    report.workspace_accuracy_mm = workspace;
    report.one_robot = cell.one_robot;
    report.shared_trunk = cell.shared_joints > 0;
    keep_cell_robots(cell, &mut report.coverage);
    report.result_check = Some(check);
    Ok(SessionCalibration {
        report,
        problem,
        calibration: cal,
    })
}

/// The result check of [`calibrate_session_with`]'s calibration (its report's
/// [`CellReport::result_check`], bit for bit), without what the report adds to the fit (the
/// predicted accuracy over the meeting pairs and the workspace, the coverage): what a command
/// that only needs the check before its own work (`diagnose`'s pre-check) asks for.
///
/// # Errors
/// As [`calibrate_session_with`]'s input checks and fit.
pub fn session_result_check(
    cell: &Cell,
    session: &Session,
    model: CellModel,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
) -> Result<ResultCheckReport, CellCalibrationError> {
    checked_calibration(cell, session, model, screen, tolerance_scale, &[]).map(|c| c.2)
}

/// The problem of [`calibrate_session_withholding`] (the session's input checks passed, the
/// families `withheld` zeroed), its calibration and that calibration's result check
/// ([`fit_and_check`]): the part of a calibration the report and the pre-check share.
fn checked_calibration(
    cell: &Cell,
    session: &Session,
    model: CellModel,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
    withheld: &[ErrorFamily],
) -> Result<(CellProblem, CellCalibration, ResultCheckReport), CellCalibrationError> {
    handclasp_cell::check_session_inputs(session)?;
    check_other_arm_joints(cell, session, model)?;
    let mut problem = cell_problem(cell, session, model.fit_model());
    for f in withheld {
        f.withhold_from(&mut problem);
    }
    let solve = solve_options(cell, session);
    // A placement fit's screen judges the rows it keeps against the stated noise plus the
    // robots' tolerances (their own error is in every row).
    let toleranced = (model.fit_model() == FitModel::Placement)
        .then(|| cell_problem(cell, session, FitModel::Kinematic));
    let (cal, check) = fit_and_check(
        cell,
        session,
        &problem,
        &solve,
        screen,
        tolerance_scale,
        toleranced.as_ref(),
    )?;
    Ok((problem, cal, check))
}

/// The fit and its result check: the fit at the stated tolerances ([`fit_with_screen`], or the
/// caller's scale when it is 1 or less), checked; then, only when that check found no likely
/// mistake and did not refuse, the widening (`calib_core::whole_cell::widen_prior`, or the
/// caller's scale above 1) with the screen in the same mode, checked again. A wrong model looks
/// to the evidence like robots further off than stated, and a widened prior lets the kinematic
/// terms absorb it, so the check must see the fit before any widening. The check returned is
/// the final fit's, with the stated fit's findings it does not repeat (said as such).
fn fit_and_check(
    cell: &Cell,
    session: &Session,
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: ScreenMode,
    tolerance_scale: Option<f64>,
    toleranced: Option<&CellProblem>,
) -> Result<(CellCalibration, ResultCheckReport), CellCalibrationError> {
    let fit_err = CellCalibrationError::Fit;
    let stated_scale = tolerance_scale.filter(|&x| x <= 1.0);
    let (stated, screen_report, stated_options) = fit_with_screen(
        problem,
        screen,
        &|o| calibrate_cell_with(problem, solve, o, stated_scale),
        toleranced,
    )
    .map_err(fit_err)?;
    let check = check_result(cell, session, problem, &stated, screen_report).map_err(fit_err)?;
    if check.refused() || check.likely_mistake.is_some() || stated_scale.is_some() {
        return Ok((stated, check));
    }
    // The widened fit at screen options `o`: from the stated fit when it was made at `o`.
    let widen = |o: &ScreenOptions| -> Result<Option<CellCalibration>, CellFitError> {
        if let Some(x) = tolerance_scale {
            return calibrate_cell_with(problem, solve, o, Some(x)).map(Some);
        }
        if *o == stated_options {
            widen_prior(problem, &stated, solve, o)
        } else {
            let at_o = calibrate_cell_with(problem, solve, o, None)?;
            widen_prior(problem, &at_o, solve, o)
        }
    };
    // Would the evidence widen at all? (Cheap: no refit unless it does.)
    let Some(first) = widen(&stated_options).map_err(fit_err)? else {
        return Ok((stated, check));
    };
    let (wide, wide_screen, _) = fit_with_screen(
        problem,
        screen,
        &|o| {
            if *o == stated_options {
                Ok(first.clone())
            } else {
                widen(o).map(|w| w.unwrap_or_else(|| first.clone()))
            }
        },
        toleranced,
    )
    .map_err(fit_err)?;
    let mut wide_check =
        check_result(cell, session, problem, &wide, wide_screen).map_err(fit_err)?;
    wide_check.add_stated_findings(&check);
    Ok((wide, wide_check))
}

/// The screened fit in `mode` ([`ScreenMode`]), each fit made by `fit` with the screen options
/// it is given: `strict` rejects as the screen says, `off` rejects nothing, `auto` refits
/// without rejection when the rejected rows are a model misfit ([`screen_outcome`]). Also gives
/// the screen options of the fit returned.
fn fit_with_screen(
    problem: &CellProblem,
    mode: ScreenMode,
    fit: &dyn Fn(&ScreenOptions) -> Result<CellCalibration, CellFitError>,
    toleranced: Option<&CellProblem>,
) -> Result<(CellCalibration, ScreenReport, ScreenOptions), CellFitError> {
    let keep_all = ScreenOptions {
        reject: false,
        ..ScreenOptions::default()
    };
    let options = match mode {
        ScreenMode::Off => keep_all.clone(),
        ScreenMode::Auto | ScreenMode::Strict => ScreenOptions::default(),
    };
    let cal = match fit(&options) {
        // The screen would leave too few rows: when most rows disagree with the model, the
        // model is wrong; auto keeps them all and reports the misfit.
        // A session too small for its unknowns (nothing rejected) is refused, as `plan`
        // refuses such a design.
        Err(CellFitError::TooFewRows { rejected_rows, .. })
            if mode == ScreenMode::Auto && !rejected_rows.is_empty() =>
        {
            let cal = fit(&keep_all)?;
            let screen = misfit_outcome(problem, &cal, &rejected_rows, mode, toleranced)?;
            return Ok((cal, screen, keep_all));
        }
        other => other?,
    };
    let screen = screen_outcome(problem, &cal, mode, toleranced)?;
    if screen.rows_kept {
        return Ok((fit(&keep_all)?, screen, keep_all));
    }
    Ok((cal, screen, options))
}

/// The predicted error of calibration `cal` of `problem` over `pairs` (of `pair_set`), in mm
/// ([`predict_error`] with the calibration's split, seed [`P95_SEED`]): the one definition
/// `calibrate --cell`, `plan` and the report page share.
///
/// # Errors
/// A pair the models reject.
pub fn predict_over(
    problem: &CellProblem,
    cal: &CellCalibration,
    split: &PredictionSplit,
    pairs: &[ConfigPair],
    pair_set: PairSet,
) -> Result<PredictedErrorReport, CellFitError> {
    let p = predict_error(
        problem,
        &cal.fit.layout,
        &cal.fit.estimate,
        split,
        pairs,
        pair_set,
        P95_SEED,
    )?;
    Ok(PredictedErrorReport::from(&p))
}

/// The coverage report of `session` of `cell` (seed [`COVERAGE_SEED`]): each joint's covered
/// range against its limits and the tool points' region against the sampled reach, as
/// `calibrate --cell` and `diagnose` report it. Its [`CoverageReport::warnings`] are the caller's
/// to print.
///
/// # Errors
/// The problem cannot be evaluated (a non-finite tool point).
pub fn session_coverage_report(
    cell: &Cell,
    session: &Session,
) -> Result<CoverageReport, CellFitError> {
    let problem = cell_problem(cell, session, FitModel::Placement);
    let mut report = CoverageReport::from(&session_coverage(&problem, COVERAGE_SEED)?);
    keep_cell_robots(cell, &mut report);
    Ok(report)
}

/// Drops a one-robot cell's stand-in robot 2 from `report` (a two-robot cell's is kept).
fn keep_cell_robots(cell: &Cell, report: &mut CoverageReport) {
    report.robots.retain(|c| cell.robots().contains(&c.robot));
}

/// Fewer coincident rows than this: the fit starts from the cell's `b1_from_b2` (a rigid start
/// needs 3 points not on a line).
pub(crate) const MIN_COINCIDENT_FOR_START: usize = 3;

/// The solver settings of a calibration of `session` on `cell` (and of its do-no-harm check's
/// fits): the fit starts from the cell's own `b1_from_b2` when the session has fewer than
/// [`MIN_COINCIDENT_FOR_START`] coincident rows (contact, tracker and plane rows alone give no
/// rigid starting placement) or the cell has a shared trunk (the placement is the trunk's, the
/// identity its prior holds: a rigid registration of the nominal tips would start it a few mm
/// and mrad away, and the reduction, linearised there, read the trunk's parameters, which move
/// both hands alike, as motions of `b1_from_b2`). Otherwise from a rigid registration.
pub(crate) fn solve_options(cell: &Cell, session: &Session) -> SolveOptions {
    let mut solve = SolveOptions::default();
    if session.points.len() < MIN_COINCIDENT_FOR_START || cell.shared_joints > 0 {
        solve.initial_b1_from_b2 = Some(cell.b1_from_b2);
    }
    solve
}

/// The predicted cooperative accuracy over the session's meeting pairs (or the workspace), mm:
/// calib-core's [`PredictedErrorReport`].
pub type CooperativeAccuracyReport = PredictedErrorReport;

/// A session's rows by observation kind, in [`Kind::ALL`]'s order inside; serialised as an
/// object keyed by [`Kind::name`] in alphabetical order (the JSON key order of every report).
#[derive(Debug, Clone, Copy)]
pub struct RowsByKind([usize; Kind::ALL.len()]);

impl RowsByKind {
    /// From [`handclasp_cell::Session::kind_counts`] (one count per [`Kind::ALL`] entry).
    pub fn from_counts(counts: [usize; Kind::ALL.len()]) -> Self {
        RowsByKind(counts)
    }

    /// The rows of `kind`.
    pub fn get(&self, kind: Kind) -> usize {
        Kind::ALL
            .iter()
            .position(|k| *k == kind)
            .map_or(0, |i| self.0[i])
    }
}

impl Serialize for RowsByKind {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let sorted: std::collections::BTreeMap<&str, usize> =
            Kind::ALL.iter().map(|k| (k.name(), self.get(*k))).collect();
        sorted.serialize(serializer)
    }
}

/// What `calibrate --cell` prints: the calibration's report ([`CalibrationReport`], whose
/// fields these are, see there) framed by the session (`model`, `rows`, `rows_by_kind`,
/// `cooperative_accuracy_mm`). `--json` serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this
/// report was before it had types).
#[derive(Debug, Clone, Serialize)]
pub struct CellReport {
    /// The fitted `b1_from_b2` (mm, ZYZ deg) with its posterior σ per axis.
    pub b1_from_b2: FittedPlacementReport,
    /// `None` (JSON null) for a session without coincident or contact rows.
    pub cooperative_accuracy_mm: Option<CooperativeAccuracyReport>,
    /// The session's joint ranges and tool-point region against the limits and the reach
    /// (its [`CoverageReport::warnings`] are the caller's to print).
    pub coverage: CoverageReport,
    /// The data χ² at the solution (residuals in their σ).
    pub data_chi2: f64,
    /// Parameter directions the data determine (not the prior).
    pub data_determined_directions: usize,
    /// Only for a session with rows other than plain handclasps (with `rows_by_kind`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub groups: Option<GroupsReport>,
    /// Solver iterations.
    pub iterations: usize,
    /// The model fitted.
    pub model: CellModel,
    /// A one-robot cell (`[robot1]` only): `b1_from_b2` is the stand-in identity, not printed,
    /// the coverage holds robot 1 alone, and the accuracy figures (the work site's, the
    /// workspace's) are robot 1's absolute accuracy: its tool's position error in its base frame
    /// (there is no cooperative accuracy). Omitted from the JSON when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub one_robot: bool,
    /// A shared-trunk cell (`[robot2] shares`): `b1_from_b2` is the identity its prior holds
    /// (the arms' one base), so no parameter is "absorbed by b1_from_b2". Omitted from the JSON
    /// when false.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub shared_trunk: bool,
    /// The blunder screen's noise scale (residuals' variance factor).
    pub noise_scale: f64,
    /// The session's nuisance parameters (tracker frames, scales, planes, contact distances).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub nuisance_parameters: Vec<NuisanceReport>,
    /// The fitted kinematic parameters with their σ and prior σ, in their units.
    pub parameters: Vec<ParameterReport>,
    /// Parameter directions the prior decides.
    pub prior_dominated_directions: usize,
    /// The prior scale chosen by the evidence.
    pub prior_scale: PriorScaleReport,
    /// Rows rejected as blunders.
    pub rejected_points: Vec<RejectedRowReport>,
    /// Residual rows of the final fit.
    pub residual_rows: usize,
    /// The result check ([`crate::result_check`]): the fit against what was stated, the likely
    /// mistakes tried, what the screen did. `None` only for a report built without a session
    /// check ([`CellReport::new`]); [`calibrate_session`] always sets it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub result_check: Option<ResultCheckReport>,
    /// The session's rows of all kinds.
    pub rows: usize,
    /// Only for a session with rows other than plain handclasps (with `groups`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rows_by_kind: Option<RowsByKind>,
    /// The session's rows used (not rejected).
    pub rows_used: usize,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// Parameters the session cannot determine, and why.
    pub unidentifiable: Vec<UnidentifiableReport>,
    /// The predicted cooperative accuracy over the whole common workspace
    /// ([`calib_core::whole_cell::workspace_pairs`], [`WORKSPACE_POSES`] poses, seed
    /// [`WORKSPACE_SEED`]); `None` without meeting pairs or when no workspace pose is reachable.
    /// A one-robot cell's is robot 1's absolute accuracy (its stand-in robot 2 is exact).
    pub workspace_accuracy_mm: Option<CooperativeAccuracyReport>,
}

impl CellReport {
    /// The calibration's report `cal` framed by the session: its `model`, its number of `rows`,
    /// its rows by kind (`Some` for a session with rows other than plain handclasps, which then
    /// also shows the nuisance groups) and the predicted cooperative accuracy.
    pub fn new(
        cal: CalibrationReport,
        model: CellModel,
        rows: usize,
        rows_by_kind: Option<RowsByKind>,
        cooperative_accuracy_mm: Option<CooperativeAccuracyReport>,
        coverage: CoverageReport,
    ) -> Self {
        let CalibrationReport {
            b1_from_b2,
            data_chi2,
            data_determined_directions,
            groups,
            iterations,
            noise_scale,
            nuisance_parameters,
            parameters,
            prior_dominated_directions,
            prior_scale,
            rejected_points,
            residual_rows,
            rows_used,
            stopped,
            unidentifiable,
        } = cal;
        CellReport {
            b1_from_b2,
            cooperative_accuracy_mm,
            coverage,
            data_chi2,
            data_determined_directions,
            groups: rows_by_kind.is_some().then_some(groups),
            iterations,
            model,
            one_robot: false,
            shared_trunk: false,
            noise_scale,
            nuisance_parameters,
            parameters,
            prior_dominated_directions,
            prior_scale,
            rejected_points,
            residual_rows,
            result_check: None,
            rows,
            rows_by_kind,
            rows_used,
            stopped,
            unidentifiable,
            workspace_accuracy_mm: None,
        }
    }
}

/// A group name as the text report quotes it: a JSON string.
fn quoted(name: &str) -> String {
    serde_json::to_string(name).unwrap_or_else(|_| format!("\"{name}\""))
}

/// The text report (mm, degrees).
pub fn render_text(r: &CellReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &CellReport) -> std::fmt::Result {
    writeln!(
        s,
        "== whole-cell calibration, model {} ({} of {} rows used)",
        r.model.name(),
        r.rows_used,
        r.rows
    )?;
    let b = &r.b1_from_b2;
    let xyz = b.xyz_mm;
    // Near θ = 0° or 180° φ and ψ alone mean nothing: a tilt below the printed resolution, or
    // for a placement held by a rotation prior below its posterior σ, is printed as a pure yaw
    // (the JSON keeps the exact angles). A freely fitted placement's tilt is printed unless it
    // is below the resolution: its σ may be large, and a tilt within it is still the estimate.
    let tilt_sigma_deg = b
        .sigma
        .iter()
        .filter(|p| p.name.ends_with("rotation x") || p.name.ends_with("rotation y"))
        .filter(|p| p.prior_sigma.is_some())
        .map(|p| p.sigma)
        .fold(f64::INFINITY, f64::min);
    let band_deg = if tilt_sigma_deg.is_finite() {
        tilt_sigma_deg.max(PRINTED_TILT_DEG)
    } else {
        PRINTED_TILT_DEG
    };
    let pose = PoseForms {
        quaternion_wxyz: b.quaternion_wxyz,
        rotation: b.rotation,
        xyz_mm: b.xyz_mm,
        zyz_deg: b.zyz_deg,
    };
    let (zyz, note) = printed_zyz(&pose, band_deg);
    if r.one_robot {
        writeln!(s, "one-robot cell: no placement (robot 1's own base frame)")?;
    } else {
        writeln!(
            s,
            "b1_from_b2:  x {:.3} mm  y {:.3} mm  z {:.3} mm   φ {:.4}°  θ {:.4}°  ψ {:.4}°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ)){note}",
            xyz[0], xyz[1], xyz[2], zyz[0], zyz[1], zyz[2]
        )?;
        writeln!(s, "{}", placement_sigma_line(&b.sigma, r.noise_scale))?;
    }
    let params = &r.parameters;
    if params.is_empty() {
        writeln!(s, "kinematic parameters: none fitted (both robots nominal)")?;
    } else {
        let mut ranked: Vec<&ParameterReport> = params.iter().collect();
        let size = |p: &ParameterReport| (p.value / p.prior_sigma).abs();
        ranked.sort_by(|a, b| size(b).total_cmp(&size(a)));
        writeln!(
            s,
            "kinematic parameters: {} fitted; the {} largest corrections (in prior σ):",
            params.len(),
            TEXT_LARGEST.min(params.len())
        )?;
        for p in ranked.iter().take(TEXT_LARGEST) {
            let unit = p.unit.name();
            writeln!(
                s,
                "  {:<40} {:>+10.4} {unit:<4} ± {:.4} {unit:<4} (prior σ {:.4}; {:.1} σ)",
                p.name,
                p.value,
                p.sigma,
                p.prior_sigma,
                size(p)
            )?;
        }
    }
    if !r.unidentifiable.is_empty() {
        writeln!(
            s,
            "not identifiable from this session ({}; held at nominal, their prior kept in the prediction):",
            r.unidentifiable.len()
        )?;
        for d in &r.unidentifiable {
            writeln!(s, "  {}", dropped_line(d, r.one_robot, r.shared_trunk))?;
        }
    }
    if r.rejected_points.is_empty() {
        writeln!(
            s,
            "blunders: none (no row's studentised residual above the Bonferroni limit)"
        )?;
    } else {
        writeln!(
            s,
            "blunders: rejected and refitted without them; re-record these rows:"
        )?;
        for b in &r.rejected_points {
            writeln!(
                s,
                "  row {:>4}: {:.1} σ (residual {:.3} mm)",
                b.row, b.size_sigma, b.residual_mm
            )?;
        }
    }
    if r.model == CellModel::Placement {
        writeln!(
            s,
            "note: the placement model takes both robots' nominal kinematics as exact; its blunder screen and \
             predicted accuracy allow for their errors only as extra noise, from the residuals' variance \
             factor (use --model kinematic to fit them)"
        )?;
    }
    if let (Some(g), Some(k)) = (&r.groups, &r.rows_by_kind) {
        writeln!(
            s,
            "rows by kind: {} coincident, {} contact, {} tracker, {} plane",
            k.get(Kind::Coincident),
            k.get(Kind::Contact),
            k.get(Kind::Tracker),
            k.get(Kind::Plane)
        )?;
        for c in &g.contact {
            writeln!(
                s,
                "  contact group {}: distance {:.3} mm ({})",
                quoted(&c.group),
                c.distance_mm,
                if c.fitted { "fitted" } else { "given" }
            )?;
        }
        for p in &g.plane {
            writeln!(
                s,
                "  plane group {}: normal ({:.5}, {:.5}, {:.5}), offset {:.3} mm (base of robot {})",
                quoted(&p.group),
                p.normal[0],
                p.normal[1],
                p.normal[2],
                p.offset_mm,
                p.anchor_robot.number()
            )?;
        }
        for t in &g.tracker {
            let a = &t.anchor_from_tracker;
            let xyz = a.xyz_mm;
            let (zyz, note) = printed_zyz(a, PRINTED_TILT_DEG);
            let q = a.quaternion_wxyz;
            writeln!(
                s,
                "  tracker group {}: origin ({:.3}, {:.3}, {:.3}) mm, rotation φ {:.4}°  θ {:.4}°  ψ {:.4}° (ZYZ){note}, quaternion (w, x, y, z) ({:.6}, {:.6}, {:.6}, {:.6}), in the base of robot {}",
                quoted(&t.group),
                xyz[0],
                xyz[1],
                xyz[2],
                zyz[0],
                zyz[1],
                zyz[2],
                q[0],
                q[1],
                q[2],
                q[3],
                t.anchor_robot.number()
            )?;
        }
    }
    match &r.cooperative_accuracy_mm {
        None if r.one_robot => writeln!(
            s,
            "predicted cooperative accuracy: not applicable (a one-robot cell: no second robot; \
             --work-points or --accept-mm give robot 1's absolute accuracy at the work site)"
        )?,
        None => writeln!(
            s,
            "predicted cooperative accuracy: none (no coincident or contact row: no meeting pair)"
        )?,
        Some(c) => {
            writeln!(
                s,
                "predicted cooperative accuracy (tip 2 → tip 1 in b1, over the {} meeting pairs (q1_i, q2_i) of this session's coincident and contact rows): rms {:.3} mm, p95 {:.3} mm",
                c.pairs, c.predicted_rms, c.predicted_p95
            )?;
            writeln!(s, "  {}", c.parts_line())?;
        }
    }
    if let Some(w) = r.workspace_accuracy_mm.as_ref().filter(|_| r.one_robot) {
        writeln!(
            s,
            "predicted absolute accuracy of robot 1's tool (its position in robot 1's base frame) over the whole workspace ({} seeded reachable poses within its joint limits): rms {:.3} mm, p95 {:.3} mm",
            w.pairs, w.predicted_rms, w.predicted_p95
        )?;
        writeln!(s, "  {}", w.parts_line())?;
    } else if let Some(w) = &r.workspace_accuracy_mm {
        writeln!(
            s,
            "predicted cooperative accuracy over the whole workspace ({} seeded reachable handclasps: robot 1 within its joint limits, robot 2 meeting it head-on): rms {:.3} mm, p95 {:.3} mm",
            w.pairs, w.predicted_rms, w.predicted_p95
        )?;
        writeln!(s, "  {}", w.parts_line())?;
    }
    if let Some(c) = &r.cooperative_accuracy_mm {
        if !params.is_empty() && r.prior_scale.chosen < 1.0 && c.prior_part_rms > c.data_part_rms {
            writeln!(
                s,
                "  why the prior part: the evidence chose prior scale {}, so the kinematic corrections are held within {} × their tolerances; the prediction keeps of the tolerances what the evidence does not reject (the reference prior: the stated tolerances where the data cannot tell), the error the data cannot rule out; `plan` predicts at scale 1 (the data correct what they see): its 'placement-only limit' line is this case",
                format_scale(r.prior_scale.chosen),
                format_scale(r.prior_scale.chosen)
            )?;
        }
    }
    for line in r.coverage.text_lines() {
        writeln!(s, "{line}")?;
    }
    if params.is_empty() {
        writeln!(
            s,
            "prior scale: none (no kinematic parameter fitted); blunder-screen noise scale {:.3}{}",
            r.noise_scale,
            noise_scale_note(r.noise_scale)
        )?;
    } else {
        writeln!(
            s,
            "{} (prior σ = scale × tolerance/√3; scales 1e-3 … 100, 1e-3 = placement-only limit); blunder-screen noise scale {:.3}{}",
            prior_scale_phrase(&r.prior_scale),
            r.noise_scale,
            noise_scale_note(r.noise_scale)
        )?;
        writeln!(s, "  why: {}", r.prior_scale.why)?;
    }
    writeln!(
        s,
        "solver: {} after {} iterations (data χ² {:.1} over {} residual rows)",
        r.stopped.name(),
        r.iterations,
        r.data_chi2,
        r.residual_rows
    )
}

/// The first part of the text report's prior-scale line: how the scales were set and their
/// values (one for every family, or each family's).
fn prior_scale_phrase(p: &PriorScaleReport) -> String {
    let families = || {
        p.families
            .iter()
            .map(|f| format!("{} ×{}", f.family, format_scale(f.scale)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    match p.method {
        ScaleMethod::EvidencePerFamily => {
            format!(
                "prior scales chosen by the evidence, per family: {}",
                families()
            )
        }
        ScaleMethod::Fixed => format!(
            "prior scale fixed by --tolerance-scale: {} for every family",
            format_scale(p.chosen)
        ),
        _ => format!(
            "prior scale chosen by the evidence: {} for every family",
            format_scale(p.chosen)
        ),
    }
}

/// The lines for fitted corrections beyond their stated tolerances by more than
/// `TOLERANCE_WARNING_SIGMAS` posterior σ, one per parameter, each with its prefix for the
/// caller to print: `warning: ` when the evidence widened the parameter's family (the family's
/// stated tolerances are wrong: the integrator should correct them), `note: ` when the fit kept
/// them (one parameter beyond its band, which the evidence did not find enough to reject the
/// family's tolerances; a correct session of the shipped examples shows one, and a warning
/// there would teach integrators to ignore warnings).
pub fn tolerance_warnings(r: &CellReport) -> Vec<String> {
    r.parameters
        .iter()
        .filter_map(|p| {
            let level = if p.prior_scale > 1.0 {
                "warning"
            } else {
                "note"
            };
            p.tolerance_warning().map(|w| format!("{level}: {w}"))
        })
        .collect()
}

/// The placement's posterior σ per axis, each with its prior σ (`free` without a prior); with a
/// noise scale above 1, which σ this is (the data's stated σ times the scale, a prior's as
/// stated).
fn placement_sigma_line(sigma: &[PlacementSigmaReport], noise_scale: f64) -> String {
    let parts: Vec<String> = sigma
        .iter()
        .map(|p| {
            let unit = p.unit.name();
            let prior = match p.prior_sigma {
                Some(s) => format!("prior {s:.4} {unit}"),
                None => "prior: free".to_string(),
            };
            format!(
                "{} ± {:.4} {unit} ({prior})",
                p.name.trim_start_matches("b1_from_b2 "),
                p.sigma,
            )
        })
        .collect();
    let which = if noise_scale > 1.0 {
        format!(
            " (as fitted, with the data's stated σ × the noise scale {noise_scale:.3} and the prior σ as stated)"
        )
    } else {
        String::new()
    };
    format!("b1_from_b2 posterior σ{which}: {}", parts.join(", "))
}

/// Half the text's angle resolution (4 decimals of a degree): a tilt below it prints as 0.
pub const PRINTED_TILT_DEG: f64 = 5e-5;

/// The ZYZ angles (deg) a text report prints for `pose`: a tilt within `band_deg` of θ = 0°
/// or 180° as a pure yaw ([`PoseForms::zyz_deg_within`]), with a note naming the tilt dropped
/// when it would have shown at the printed resolution; otherwise its exact `zyz_deg`. Used by
/// every text report that prints a pose's ZYZ angles (the whole-cell and points reports).
pub fn printed_zyz(pose: &PoseForms, band_deg: f64) -> ([f64; 3], String) {
    let theta = pose.zyz_deg[1];
    let tilt_deg = theta.abs().min((180.0 - theta.abs()).abs());
    if tilt_deg >= band_deg {
        return (pose.zyz_deg, String::new());
    }
    let z = pose.zyz_deg_within(band_deg);
    let note = if tilt_deg >= PRINTED_TILT_DEG {
        format!(
            " [θ {theta:.4}° is within its σ of {:.0}°, where φ and ψ alone are undefined: printed as the pure yaw φ + ψ; the JSON has the exact angles]",
            z[1]
        )
    } else {
        String::new()
    };
    (z, note)
}

/// What a noise scale above 1 means (empty at 1).
fn noise_scale_note(noise_scale: f64) -> &'static str {
    if noise_scale > 1.0 {
        " (the residuals are this many times the stated σ, √(χ²/dof) of the placement model: its \
         blunder screen, its posterior σ and its predicted accuracy take the data's σ times it)"
    } else {
        ""
    }
}

/// One readable line per dropped parameter: why, and for a merge its largest partners
/// (`one_robot`: a one-robot cell, which has no placement; `shared_trunk`: a shared-trunk cell,
/// whose placement is held at the identity).
fn dropped_line(d: &UnidentifiableReport, one_robot: bool, shared_trunk: bool) -> String {
    let name = &d.name;
    match d.reason {
        DropReason::Merged => {
            let mut into: Vec<(&str, f64)> = d
                .merged_into
                .iter()
                .flatten()
                .map(|m| (m.parameter.as_str(), m.coefficient))
                .collect();
            into.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            let shown: Vec<String> = into
                .iter()
                .take(MERGE_PARTNERS_SHOWN)
                .map(|(n, c)| format!("{c:+.3}·{n}"))
                .collect();
            let more = into.len().saturating_sub(MERGE_PARTNERS_SHOWN);
            let more = if more > 0 {
                format!(" and {more} smaller")
            } else {
                String::new()
            };
            format!(
                "{name}: merged into {}{more} (coefficients in prior σ)",
                shown.join(", ")
            )
        }
        DropReason::ConfoundedWithPlacement if one_robot => {
            format!("{name}: absorbed by the robot's base frame (the tracker/plane unknowns)")
        }
        DropReason::ConfoundedWithPlacement if shared_trunk => format!(
            "{name}: moves robot 2's tips against robot 1's as b1_from_b2 would, which the shared trunk holds"
        ),
        DropReason::ConfoundedWithPlacement => format!("{name}: absorbed by b1_from_b2"),
        DropReason::NoEffect => format!("{name}: moves no observed tip"),
        DropReason::MovesBothHandsAlike => format!(
            "{name}: the shared trunk's, moves both hands alike (the rows see only where they meet)"
        ),
        DropReason::PriorDecided => {
            format!("{name}: barely seen by the data, the prior decides it")
        }
        _ => d.why.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::whole_cell::{
        ContactGroupReport, FamilyScaleReport, LogEvidenceReport, MergePartner, ParamIdentity,
        PlaneGroupReport, ReportUnit, TrackerGroupReport,
    };
    use calib_core::Robot;
    use std::f64::consts::FRAC_1_SQRT_2;

    fn sigma(name: &str, unit: ReportUnit, prior: Option<f64>) -> PlacementSigmaReport {
        PlacementSigmaReport {
            name: format!("b1_from_b2 {name}"),
            prior_sigma: prior,
            sigma: 0.25,
            unit,
        }
    }

    fn dropped(
        name: &str,
        reason: DropReason,
        into: Option<Vec<(&str, f64)>>,
    ) -> UnidentifiableReport {
        UnidentifiableReport {
            identity: None,
            independent_fraction: 0.0,
            merged_into: into.map(|v| {
                v.into_iter()
                    .map(|(p, c)| MergePartner {
                        coefficient: c,
                        parameter: p.into(),
                    })
                    .collect()
            }),
            name: name.into(),
            reason,
            why: format!("{name} is confounded with the nuisances"),
        }
    }

    /// A kinematic fit of a mixed session with one blunder, every section of the text filled.
    fn mixed_report() -> CellReport {
        let parameter = |name: &str, value: f64, prior_sigma: f64| ParameterReport {
            identity: ParamIdentity {
                axis: None,
                joint: Some(2),
                link: None,
                kind: "joint_offset",
                robot: Robot::One,
            },
            name: name.into(),
            prior_scale: 1.0,
            prior_sigma,
            sigma: 0.01,
            tolerance: prior_sigma * 3f64.sqrt(),
            unit: ReportUnit::Deg,
            value,
        };
        CellReport {
            b1_from_b2: FittedPlacementReport {
                quaternion_wxyz: [1.0, 0.0, 0.0, 0.0],
                rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                sigma: vec![
                    sigma("translation x", ReportUnit::Mm, Some(2.0)),
                    sigma("rotation z", ReportUnit::Deg, None),
                ],
                xyz_mm: [1303.25, -102.5, 1386.125],
                zyz_deg: [180.0, 89.874, -179.997],
            },
            cooperative_accuracy_mm: Some(CooperativeAccuracyReport {
                data_part_rms: 0.9,
                held_out_ratio: Some(1.04),
                held_out_p_value: Some(0.31),
                held_out_regions: Some(5),
                model_error_rms: 0.0,
                model_error_source: "held_out_residuals",
                pair_set: PairSet::MeetingPairs.describe(),
                pair_set_kind: PairSet::MeetingPairs,
                pairs: 14,
                predicted_p95: 2.75,
                predicted_rms: 1.5,
                prior_part_rms: 1.2,
                rms_bound95: 2.0,
            }),
            coverage: CoverageReport {
                reach_samples: 4000,
                robots: vec![],
                seed: 1,
            },
            data_chi2: 62.46,
            data_determined_directions: 3,
            groups: Some(GroupsReport {
                contact: vec![ContactGroupReport {
                    distance_mm: 100.0214,
                    fitted: true,
                    group: "pins \"a\"".into(),
                }],
                plane: vec![PlaneGroupReport {
                    anchor_robot: Robot::Two,
                    group: "table".into(),
                    normal: [0.0, 0.6, -0.8],
                    offset_mm: -971.3256,
                }],
                tracker: vec![TrackerGroupReport {
                    // A turn of 90° about z, a tilt of 2e-5° (below the printed resolution).
                    anchor_from_tracker: PoseForms {
                        quaternion_wxyz: [FRAC_1_SQRT_2, 0.0, 0.0, FRAC_1_SQRT_2],
                        rotation: [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                        xyz_mm: [-1226.9961, 1146.2934, 1295.3159],
                        zyz_deg: [30.0, 2e-5, 60.0],
                    },
                    anchor_robot: Robot::One,
                    group: "leica".into(),
                }],
            }),
            iterations: 4,
            model: CellModel::Kinematic,
            one_robot: false,
            shared_trunk: false,
            noise_scale: 1.0,
            nuisance_parameters: vec![],
            parameters: vec![
                parameter("robot 1 joint_offset joint 2", 0.001, 0.01),
                parameter("robot 1 joint_offset joint 3", -0.02, 0.01),
            ],
            prior_dominated_directions: 1,
            prior_scale: PriorScaleReport {
                chosen: 0.0625,
                families: vec![FamilyScaleReport {
                    family: "joint_offset".into(),
                    parameters: 2,
                    scale: 0.0625,
                }],
                family_log_evidence: None,
                log_evidence: vec![LogEvidenceReport {
                    log_evidence: -3.5,
                    scale: 0.0625,
                }],
                method: ScaleMethod::EvidenceCommon,
                why: "common scale 0.0625 has the largest log evidence (-3.5)".into(),
            },
            rejected_points: vec![RejectedRowReport {
                residual_mm: 7.1234,
                row: 6,
                size_sigma: 21.04,
            }],
            residual_rows: 80,
            result_check: None,
            workspace_accuracy_mm: None,
            rows: 41,
            rows_by_kind: Some(RowsByKind::from_counts([7, 8, 13, 13, 0])),
            rows_used: 40,
            stopped: StopReason::Converged,
            unidentifiable: vec![
                dropped(
                    "robot 1 origin_xyz joint 2 z",
                    DropReason::Merged,
                    Some(vec![("a", 0.1), ("b", -0.9), ("c", 0.5), ("d", 0.05)]),
                ),
                dropped(
                    "robot 2 joint_offset joint 1",
                    DropReason::ConfoundedWithPlacement,
                    None,
                ),
                dropped("robot 1 joint_offset joint 7", DropReason::NoEffect, None),
                dropped("robot 1 tool `tip` tip x", DropReason::PriorDecided, None),
                dropped(
                    "robot 1 origin_xyz joint 1 x",
                    DropReason::ConfoundedWithNuisance,
                    None,
                ),
            ],
        }
    }

    /// Every line of the text comes from a typed field: the figures as they were set, the
    /// corrections ranked by size in prior σ, merges with their three largest partners, the
    /// groups quoted as JSON strings.
    #[test]
    fn text_of_a_mixed_kinematic_fit() {
        let text = render_text(&mixed_report());
        let expected = [
            "== whole-cell calibration, model kinematic (40 of 41 rows used)",
            "b1_from_b2:  x 1303.250 mm  y -102.500 mm  z 1386.125 mm   φ 180.0000°  θ 89.8740°  ψ -179.9970°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
            "b1_from_b2 posterior σ: translation x ± 0.2500 mm (prior 2.0000 mm), rotation z ± 0.2500 deg (prior: free)",
            "kinematic parameters: 2 fitted; the 2 largest corrections (in prior σ):",
            "  robot 1 joint_offset joint 3                -0.0200 deg  ± 0.0100 deg  (prior σ 0.0100; 2.0 σ)",
            "  robot 1 joint_offset joint 2                +0.0010 deg  ± 0.0100 deg  (prior σ 0.0100; 0.1 σ)",
            "not identifiable from this session (5; held at nominal, their prior kept in the prediction):",
            "  robot 1 origin_xyz joint 2 z: merged into -0.900·b, +0.500·c, +0.100·a and 1 smaller (coefficients in prior σ)",
            "  robot 2 joint_offset joint 1: absorbed by b1_from_b2",
            "  robot 1 joint_offset joint 7: moves no observed tip",
            "  robot 1 tool `tip` tip x: barely seen by the data, the prior decides it",
            "  robot 1 origin_xyz joint 1 x is confounded with the nuisances",
            "blunders: rejected and refitted without them; re-record these rows:",
            "  row    6: 21.0 σ (residual 7.123 mm)",
            "rows by kind: 7 coincident, 8 contact, 13 tracker, 13 plane",
            "  contact group \"pins \\\"a\\\"\": distance 100.021 mm (fitted)",
            "  plane group \"table\": normal (0.00000, 0.60000, -0.80000), offset -971.326 mm (base of robot 2)",
            "  tracker group \"leica\": origin (-1226.996, 1146.293, 1295.316) mm, rotation φ 0.0000°  θ 0.0000°  ψ 90.0000° (ZYZ), quaternion (w, x, y, z) (0.707107, 0.000000, 0.000000, 0.707107), in the base of robot 1",
            "predicted cooperative accuracy (tip 2 → tip 1 in b1, over the 14 meeting pairs (q1_i, q2_i) of this session's coincident and contact rows): rms 1.500 mm, p95 2.750 mm",
            "  of which: data-determined 0.900 mm, prior-asserted 1.200 mm (the tolerances of the terms the data do not determine: right only if the robots are that far off), model error none (held-out residuals of 5 joint-space regions 1.04× what the fit predicts, p 0.31: not significantly above); 95 % bound of the rms 2.000 mm",
            "  why the prior part: the evidence chose prior scale 0.0625, so the kinematic corrections are held within 0.0625 × their tolerances; the prediction keeps of the tolerances what the evidence does not reject (the reference prior: the stated tolerances where the data cannot tell), the error the data cannot rule out; `plan` predicts at scale 1 (the data correct what they see): its 'placement-only limit' line is this case",
            "coverage (the session against the joint limits and the reach sampled at 4000 joint vectors within them; a calibration is extrapolated outside it):",
            "prior scale chosen by the evidence: 0.0625 for every family (prior σ = scale × tolerance/√3; scales 1e-3 … 100, 1e-3 = placement-only limit); blunder-screen noise scale 1.000",
            "  why: common scale 0.0625 has the largest log evidence (-3.5)",
            "solver: converged after 4 iterations (data χ² 62.5 over 80 residual rows)",
        ];
        assert_eq!(text.lines().collect::<Vec<_>>(), expected);
    }

    /// A placement fit of plain handclasps without meeting pairs: no parameters, the placement
    /// note, no groups, and "none" for the accuracy and the prior scale; the JSON then has no
    /// `groups`, `rows_by_kind` or `nuisance_parameters` and a null accuracy.
    #[test]
    fn text_and_json_of_a_placement_fit_without_groups() {
        let mut r = mixed_report();
        r.model = CellModel::Placement;
        r.parameters.clear();
        r.unidentifiable.clear();
        r.rejected_points.clear();
        r.groups = None;
        r.rows_by_kind = None;
        r.cooperative_accuracy_mm = None;
        let text = render_text(&r);
        for line in [
            "== whole-cell calibration, model placement (40 of 41 rows used)",
            "kinematic parameters: none fitted (both robots nominal)",
            "blunders: none (no row's studentised residual above the Bonferroni limit)",
            "predicted cooperative accuracy: none (no coincident or contact row: no meeting pair)",
            "prior scale: none (no kinematic parameter fitted); blunder-screen noise scale 1.000",
        ] {
            assert!(
                text.lines().any(|l| l == line),
                "{line:?} missing in\n{text}"
            );
        }
        assert!(text.contains("(use --model kinematic to fit them)"));
        assert!(!text.contains("not identifiable") && !text.contains("rows by kind"));
        let json = serde_json::to_string(&r).unwrap();
        for absent in ["\"groups\"", "\"rows_by_kind\"", "\"nuisance_parameters\""] {
            assert!(!json.contains(absent), "{absent} in {json}");
        }
        assert!(json.contains("\"cooperative_accuracy_mm\":null"));
        assert!(json.contains("\"model\":\"placement\""));
    }

    /// A placement near the identity held by a prior (σ 0.001°) with a tilt of 0.0008°: the
    /// text prints the pure yaw φ + ψ and names the dropped tilt, the JSON keeps the exact
    /// angles; without the prior the tilt is printed; a noise scale above 1 says which σ is
    /// printed and what the scale is.
    #[test]
    fn near_identity_prints_canonical_angles_and_the_noise_scale_is_explained() {
        let mut r = mixed_report();
        let pose = calib_core::PoseMmDeg {
            xyz_mm: [0.0; 3],
            zyz_deg: [48.3, 0.0008, -48.2],
        };
        let forms = PoseForms::from_isometry(&pose.to_isometry());
        r.b1_from_b2.rotation = forms.rotation;
        r.b1_from_b2.quaternion_wxyz = forms.quaternion_wxyz;
        r.b1_from_b2.xyz_mm = forms.xyz_mm;
        r.b1_from_b2.zyz_deg = forms.zyz_deg;
        r.b1_from_b2.sigma = vec![
            sigma("rotation x", ReportUnit::Deg, Some(0.001)),
            sigma("rotation y", ReportUnit::Deg, Some(0.001)),
        ];
        r.b1_from_b2.sigma.iter_mut().for_each(|p| p.sigma = 0.001);
        r.noise_scale = 2.5;
        let text = render_text(&r);
        let line = text.lines().nth(1).unwrap();
        assert!(
            line.contains("φ 0.0000°  θ 0.0000°  ψ 0.1000°")
                && line.contains("[θ 0.0008° is within its σ of 0°"),
            "{line}"
        );
        assert!(
            (forms.zyz_deg[0] - 48.3).abs() < 1e-6,
            "{:?}",
            forms.zyz_deg
        );
        let mut free = r.clone();
        free.b1_from_b2
            .sigma
            .iter_mut()
            .for_each(|p| p.prior_sigma = None);
        let free_text = render_text(&free);
        let line = free_text.lines().nth(1).unwrap();
        assert!(
            line.contains("φ 48.3000°  θ 0.0008°  ψ -48.2000°") && !line.contains('['),
            "{line}"
        );
        assert!(text.contains("posterior σ (as fitted, with the data's stated σ × the noise scale 2.500 and the prior σ as stated)"));
        assert!(text.contains(
            "blunder-screen noise scale 2.500 (the residuals are this many times the stated σ"
        ));
    }

    /// The JSON's keys stand in alphabetical order at every level (the order of the
    /// `serde_json::Value`, a BTreeMap, that this report was before it had types).
    #[test]
    fn json_keys_in_value_order() {
        let json = serde_json::to_string(&mixed_report()).unwrap();
        let value: serde_json::Value = serde_json::from_str(&json).unwrap();
        assert_eq!(
            json,
            serde_json::to_string(&value).unwrap(),
            "keys out of alphabetical order"
        );
    }

    /// `diagnose`'s pre-check computes only the result check: it must be the check
    /// `calibrate_session_with` reports, bit for bit, for each model and screen mode (the docs'
    /// example session on its cell; a session the check refuses is covered by
    /// `tests/e2e/result_check.rs`).
    #[test]
    fn session_result_check_is_the_calibrations_check() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let cell = Cell::from_toml_file(&root.join("cells/floor-wall.toml")).expect("cell");
        let session =
            Session::read_csv(&root.join("docs/examples/session.csv"), &cell).expect("session");
        for model in [CellModel::Placement, CellModel::Kinematic] {
            for screen in [ScreenMode::Auto, ScreenMode::Off] {
                let full = calibrate_session_with(&cell, &session, model, screen, None)
                    .expect("calibration");
                let check =
                    session_result_check(&cell, &session, model, screen, None).expect("check");
                assert_eq!(
                    serde_json::to_string(&check).expect("json"),
                    serde_json::to_string(&full.report.result_check).expect("json"),
                    "{model:?} {screen:?}"
                );
            }
        }
    }
}

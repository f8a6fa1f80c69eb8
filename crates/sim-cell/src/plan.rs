//! Session planning: choose `n` handclasp poses, from `k` seeded reachable candidates, that
//! minimise the predicted cooperative error of the whole-cell calibration (A-optimal) or maximise
//! its information volume (D-optimal), with the cell's `[robotN.tolerance]` as the prior and its
//! `[noise]` as the noise ([`calib_core::whole_cell::greedy_design`]).
//!
//! # Candidates
//! [`reachable_handclasps`] is the one generator of candidate handclasps, shared with the
//! robot-mode sweep's held-out pairs and planned layout (`sweep::robot`): meeting points drawn
//! one after another, uniformly in a cube of side `spread_m` around the teach centre, each
//! simulated as `sim-cell session` places a handclasp ([`generate_session`] with that one
//! explicit point) on the cell's **nominal** robots with no noise ([`nominal_cell`]): both robots
//! reach it head-on, from the first approach direction of the session generator's list that both
//! reach within their joint limits. Points the robot pair does not reach are skipped; at most
//! [`ATTEMPTS_PER_CANDIDATE`]`·k` points are drawn. The plan's candidates come from the
//! generator [`trial_rng`]`(seed, `[`CANDIDATE_STREAM`]`)`. The tip is not checked for
//! collision with its own links (not modelled).
//!
//! # Prediction
//! The cooperative error is predicted over [`EVAL_POSES`] further reachable handclasp poses
//! `(q1_i, q2_i)` (generator [`trial_rng`]`(seed, `[`EVAL_STREAM`]`)`: held out from the
//! candidates, spread over the same cube), linearised at the nominal cell. These pairs meet, so
//! the error of the predicted vector is invariant to anything confounded with the base frames
//! (a base rotation turns a vector of length ~0). Cross pairs `(q1_i, q2_j)` would not be: their
//! vectors are up to ~1.5 m long, and the base rotations that no handclasp can observe (e.g. robot 1's joint-1
//! offset against the placement's yaw) turn them by the prior's 0.05°, ~0.8 mm whatever the
//! session. The plan is compared with
//! [`PlanSpec::random_draws`] random picks of `n` of the same candidates (seeded); the report
//! gives their mean.

use calib_core::whole_cell::{
    design_prediction, design_split, greedy_design, predict_error, workspace_pairs, CellEstimate,
    CellFitError, ConfigPair, DesignCriterion, DesignPrediction, PairSet, ParamLayout,
    PredictedError, ScreenOptions, PRIOR_SCALES, WORKSPACE_POSES, WORKSPACE_SEED,
};
use kinematics::{ErrorParam, KinematicErrors};
use nalgebra::{Point3, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::error::SimError;
use crate::simulate::{generate_session, SessionSpec};
use crate::trial_rng;
use crate::Layout;
use handclasp_cell::cell::{Cell, CellRobot};
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::{Session, SessionPoint};

/// Draws per wanted candidate before giving up (`k` candidates: at most `4·k` points tried).
pub const ATTEMPTS_PER_CANDIDATE: usize = 4;
/// Held-out reachable handclasp poses `(q1_i, q2_i)` over which the cooperative error is predicted.
pub const EVAL_POSES: usize = 200;
/// Default number of random picks the plan is compared with.
pub const DEFAULT_RANDOM_DRAWS: usize = 20;
/// Seed of the placement draws behind the predicted `e_tran`/`e_rot`.
const PREDICTION_SEED: u64 = 7;
/// Points drawn between two progress reports.
const BATCH: usize = 32;
/// Stream of `seed` that draws the candidates.
pub const CANDIDATE_STREAM: u64 = 0;
/// Stream of `seed` that draws the held-out evaluation poses.
pub const EVAL_STREAM: u64 = 1;
/// Stream offset of the random picks, far from the candidate and evaluation streams.
const RANDOM_STREAM: u64 = 1 << 40;

/// What to plan.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanSpec {
    /// Poses to choose (≥ 1).
    pub n: usize,
    /// Reachable candidates to choose from (≥ `n`).
    pub candidates: usize,
    /// A (cooperative accuracy) or D (information volume).
    pub criterion: DesignCriterion,
    /// Seed of the candidates, the evaluation poses and the random picks.
    pub seed: u64,
    /// Side of the candidates' cube, m.
    pub spread_m: f64,
    /// Centre of the cube, m, b1 (`None`: the cell's teach centre).
    pub centre_b1: Option<Point3<f64>>,
    /// Random picks of `n` candidates the plan is compared with (≥ 1).
    pub random_draws: usize,
}

impl PlanSpec {
    /// `n` of `candidates` for `criterion`, seed 1, a 1 m cube around the cell's teach centre,
    /// [`DEFAULT_RANDOM_DRAWS`] random picks.
    pub fn new(n: usize, candidates: usize, criterion: DesignCriterion) -> Self {
        PlanSpec {
            n,
            candidates,
            criterion,
            seed: 1,
            spread_m: 1.0,
            centre_b1: None,
            random_draws: DEFAULT_RANDOM_DRAWS,
        }
    }
}

/// A planned session.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The chosen poses in the order chosen, numbered 1..n: joints (rad) and nominal tips (m).
    pub session: Session,
    /// Index of each chosen pose among the candidates.
    pub chosen: Vec<usize>,
    /// The reachable candidates (poses numbered by candidate index + 1).
    pub candidates: Vec<SessionPoint>,
    /// Points drawn to find them.
    pub attempts: usize,
    /// The held-out evaluation pairs of the prediction.
    pub eval_pairs: Vec<ConfigPair>,
    /// The plan's prediction.
    pub predicted: DesignPrediction,
    /// Mean over the random picks of each field of their predictions.
    pub random_mean: DesignPrediction,
    /// Each random pick's prediction.
    pub random: Vec<DesignPrediction>,
    /// The plan's predicted error in parts (the one definition `calibrate --cell` uses:
    /// [`calib_core::whole_cell::predict_error`]).
    pub parts: PlanParts,
}

/// The plan's predicted error in parts, over its held-out pairs and the whole workspace, at
/// the tolerances (prior scale 1, as the design assumes) and at the placement-only limit.
#[derive(Debug, Clone)]
pub struct PlanParts {
    /// Over the held-out evaluation pairs, prior scale 1: its rms is
    /// [`DesignPrediction::cooperative_rms_m`].
    pub held_out: PredictedError,
    /// Over the same pairs at the smallest prior scale `calibrate --cell`'s evidence may choose
    /// ([`PRIOR_SCALES`]' last, the placement-only limit): the kinematic corrections held at
    /// nominal, their tolerances left in the prediction.
    pub placement_only_limit: PredictedError,
    /// Over the whole workspace ([`workspace_pairs`], [`WORKSPACE_POSES`] poses, seed
    /// [`WORKSPACE_SEED`]: the poses `calibrate --cell` predicts over), prior scale 1; `None`
    /// when none is reachable.
    pub workspace: Option<PredictedError>,
}

/// The cell with nominal robots (no `[robotN.errors]`) and no noise: where candidates are
/// placed (the plan's and the robot-mode sweep's setup, as an operator would plan).
pub fn nominal_cell(cell: &Cell) -> Cell {
    let mut c = cell.clone();
    for r in [&mut c.robot1, &mut c.robot2] {
        r.errors = KinematicErrors::zero_for(&r.model);
    }
    c.noise.alignment_m = Vector3::zeros();
    c.noise.repeatability_m = 0.0;
    c.noise.encoder_resolution_rad = 0.0;
    c
}

/// Up to `count` handclasps both robots of `cell` reach head-on, drawn from `rng` one after
/// another: each meeting point uniform in the cube of side `spread_m` (m) around `centre_b1`
/// (m, b1), placed by [`generate_session`] with that one point (the same generator continues
/// into it); unreachable points are skipped, and at most `max_draws` are drawn.
/// `progress(found, drawn)` every 32 draws and at the end. Returns the handclasps
/// (numbered 1..) and the draws used. Pass a [`nominal_cell`] for noise-free nominal poses.
///
/// This is the one candidate generator of `handclasp plan` ([`plan_session`]) and of the
/// robot-mode sweep (held-out pairs, planned layout). It draws sequentially, so its output
/// depends on `rng` alone, never on the thread count.
pub fn reachable_handclasps(
    cell: &Cell,
    centre_b1: &Point3<f64>,
    spread_m: f64,
    count: usize,
    max_draws: usize,
    rng: &mut ChaCha8Rng,
    progress: &mut dyn FnMut(usize, usize),
) -> (Vec<SessionPoint>, usize) {
    let mut out = Vec::with_capacity(count);
    let mut drawn = 0;
    while out.len() < count && drawn < max_draws {
        let offset = Vector3::from_fn(|_, _| rng.random_range(-0.5..0.5)) * spread_m;
        let spec = SessionSpec {
            n: 1,
            layout: Layout::Random,
            spread_m,
            centre_b1: None,
            points_b1: Some(vec![centre_b1 + offset]),
        };
        drawn += 1;
        if let Ok(s) = generate_session(cell, &spec, rng) {
            if let Some(mut p) = s.points.into_iter().next() {
                p.point = out.len() + 1;
                out.push(p);
            }
        }
        if drawn % BATCH == 0 {
            progress(out.len(), drawn);
        }
    }
    progress(out.len(), drawn);
    (out, drawn)
}

fn plan_error(e: CellFitError) -> SimError {
    SimError::InvalidInput(format!("planning: {e}"))
}

/// Plans a session on `cell` (see the module documentation); `progress(found, drawn)` reports
/// the candidate search (the long part for large `k`).
///
/// Errors: a one-robot cell (it has no handclasp poses), `n` = 0, `n` > `k`, no random draws, a
/// non-positive spread; fewer than `n`
/// reachable candidates (naming how many were found and what to change); a cell none of whose
/// drawn points both robots reach.
pub fn plan_session(
    cell: &Cell,
    spec: &PlanSpec,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Plan, SimError> {
    if cell.one_robot {
        return Err(SimError::InvalidInput(
            "the cell has only [robot1]: a plan chooses handclasp poses that both robots reach, \
             so a one-robot cell has none; simulate its tracker or plane session with \
             `sim-cell session --kind tracker` (or plane) instead"
                .into(),
        ));
    }
    if spec.n == 0 {
        return Err(SimError::InvalidSetting {
            field: "n",
            message: "is 0: plan at least 1 pose (40 is a good session)".into(),
        });
    }
    if spec.n > spec.candidates {
        return Err(SimError::InvalidSetting {
            field: "n",
            message: format!(
                "{} is more than the {} candidates: give at least as many candidates as poses (e.g. {})",
                spec.n,
                spec.candidates,
                5 * spec.n
            ),
        });
    }
    if spec.random_draws == 0 {
        return Err(SimError::InvalidSetting {
            field: "random_draws",
            message: "is 0: compare with at least 1 random pick".into(),
        });
    }
    if !(spec.spread_m.is_finite() && spec.spread_m > 0.0) {
        return Err(SimError::InvalidSetting {
            field: "spread_m",
            message: format!("{} m must be a positive length (e.g. 1 m)", spec.spread_m),
        });
    }
    let centre = spec.centre_b1.unwrap_or(cell.centre_b1);
    let max_attempts = ATTEMPTS_PER_CANDIDATE * spec.candidates;
    let nominal = nominal_cell(cell);
    let (candidates, attempts) = reachable_handclasps(
        &nominal,
        &centre,
        spec.spread_m,
        spec.candidates,
        max_attempts,
        &mut trial_rng(spec.seed, CANDIDATE_STREAM),
        progress,
    );
    let c_mm = centre * 1e3;
    let hint = format!(
        "reduce the spread ({:.0} mm) or move the centre ({:.0}, {:.0}, {:.0}) mm into the common workspace",
        spec.spread_m * 1e3,
        c_mm.x,
        c_mm.y,
        c_mm.z
    );
    if candidates.is_empty() {
        return Err(SimError::Unreachable {
            point: 1,
            p_b1_mm: [c_mm.x, c_mm.y, c_mm.z],
            message: format!(
                "none of {attempts} points drawn in the {:.0} mm cube around the centre is reached head-on by both robots; {hint}",
                spec.spread_m * 1e3
            ),
        });
    }
    if candidates.len() < spec.n {
        return Err(SimError::InvalidInput(format!(
            "only {} of {attempts} drawn points are reached by both robots, fewer than the {} poses asked; \
             {hint}, or plan fewer poses",
            candidates.len(),
            spec.n
        )));
    }
    // Held-out evaluation poses: a generator of their own.
    let (eval, _) = reachable_handclasps(
        &nominal,
        &centre,
        spec.spread_m,
        EVAL_POSES,
        ATTEMPTS_PER_CANDIDATE * EVAL_POSES,
        &mut trial_rng(spec.seed, EVAL_STREAM),
        &mut |_, _| {},
    );
    if eval.is_empty() {
        return Err(SimError::InvalidInput(format!(
            "no evaluation pose is reached by both robots; {hint}"
        )));
    }
    let eval_pairs: Vec<ConfigPair> = eval
        .iter()
        .map(|p| ConfigPair {
            q1: p.q1.clone(),
            q2: p.q2.clone(),
            tool1: 0,
            tool2: 0,
        })
        .collect();
    let problem = cell_problem(
        cell,
        &Session::from_points(candidates.clone()),
        FitModel::Kinematic,
    );
    problem.check().map_err(plan_error)?;
    let layout = ParamLayout::new(&problem, &[]);
    refuse_unfittable(&problem, &layout, spec.n)?;
    let at = CellEstimate::nominal(&problem, cell.b1_from_b2);
    let obs = &problem.observations;
    let design = greedy_design(
        &problem,
        &layout,
        &at,
        obs,
        &eval_pairs,
        spec.n,
        spec.criterion,
    )
    .map_err(plan_error)?;
    let predict = |chosen: &[usize]| {
        design_prediction(
            &problem,
            &layout,
            &at,
            obs,
            chosen,
            &eval_pairs,
            PREDICTION_SEED,
        )
        .map_err(plan_error)
    };
    let predicted = predict(&design.chosen)?;
    let random = (0..spec.random_draws)
        .map(|d| {
            let mut rng = trial_rng(spec.seed, RANDOM_STREAM + d as u64);
            let pick = rand::seq::index::sample(&mut rng, candidates.len(), spec.n).into_vec();
            predict(&pick)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mean = |f: &dyn Fn(&DesignPrediction) -> f64| {
        random.iter().map(f).sum::<f64>() / random.len() as f64
    };
    let random_mean = DesignPrediction {
        cooperative_rms_m: mean(&|p| p.cooperative_rms_m),
        e_tran_m: mean(&|p| p.e_tran_m),
        e_rot_rad: mean(&|p| p.e_rot_rad),
        log_det_info: mean(&|p| p.log_det_info),
    };
    let parts = plan_parts(&problem, &layout, &at, &design.chosen, &eval_pairs, cell)?;
    let points = design
        .chosen
        .iter()
        .enumerate()
        .map(|(k, &c)| SessionPoint {
            point: k + 1,
            ..candidates[c].clone()
        })
        .collect();
    Ok(Plan {
        session: Session::from_points(points),
        chosen: design.chosen,
        candidates,
        attempts,
        eval_pairs,
        predicted,
        random_mean,
        random,
        parts,
    })
}

/// Refuses a plan of `n` handclasps that `calibrate --cell` would refuse to fit, with its
/// words ([`CellFitError::TooFewRows`]): fewer residual rows (3 a handclasp) than the
/// unpenalised unknowns plus the blunder screen's redundancy ([`ScreenOptions::min_redundancy`]).
fn refuse_unfittable(
    problem: &calib_core::whole_cell::CellProblem,
    layout: &ParamLayout,
    n: usize,
) -> Result<(), SimError> {
    let unpenalised = (0..layout.len())
        .filter(|&j| layout.prior_sigma(j) == 0.0)
        .count();
    let needed = unpenalised + ScreenOptions::default().min_redundancy;
    let per_row = problem.observations.first().map_or(3, |o| o.kind.rows());
    let remaining = n * per_row;
    if remaining < needed {
        let why = CellFitError::TooFewRows {
            remaining,
            needed,
            rejected_rows: Vec::new(),
        };
        return Err(SimError::InvalidInput(format!(
            "a session of {n} handclasps cannot be calibrated, so no accuracy is predicted: \
             calibrate --cell would refuse it: {why} (plan at least {} poses)",
            needed.div_ceil(per_row)
        )));
    }
    Ok(())
}

/// The plan's predicted error in parts ([`PlanParts`]).
fn plan_parts(
    problem: &calib_core::whole_cell::CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    chosen: &[usize],
    eval_pairs: &[ConfigPair],
    cell: &Cell,
) -> Result<PlanParts, SimError> {
    let obs = &problem.observations;
    let at_scale = |scale: f64, pairs: &[ConfigPair], set: PairSet| {
        let split = design_split(problem, layout, at, obs, chosen, scale).map_err(plan_error)?;
        predict_error(problem, layout, at, &split, pairs, set, PREDICTION_SEED).map_err(plan_error)
    };
    let limit = PRIOR_SCALES[PRIOR_SCALES.len() - 1];
    let workspace: Vec<ConfigPair> =
        workspace_pairs(problem, &cell.b1_from_b2, WORKSPACE_POSES, WORKSPACE_SEED)
            .into_iter()
            .map(|p| p.pair)
            .collect();
    Ok(PlanParts {
        held_out: at_scale(1.0, eval_pairs, PairSet::HeldOutHandclasps)?,
        placement_only_limit: at_scale(limit, eval_pairs, PairSet::HeldOutHandclasps)?,
        workspace: if workspace.is_empty() {
            None
        } else {
            Some(at_scale(1.0, &workspace, PairSet::Workspace)?)
        },
    })
}

/// Draws every parameter `robot`'s tolerance selects from `U(±tol)`, in the catalogue order of
/// [`calib_core::whole_cell::CellRobot::fitted_params`], then the tip (x, y, z) from
/// `U(±tip_mm)`; parameters the tolerance does not select keep their value. `tol` is the
/// tolerance's half-width (`[robotN.tolerance]`: the prior σ is `tol/√3`). The one tolerance
/// draw of the planning studies ([`draw_errors_from_tolerance`]) and of the robot-mode sweep's
/// `--kinematic-errors tolerance` (`sweep::KinematicErrorDraw::Tolerance`).
pub fn draw_kinematic_errors(robot: &mut CellRobot, rng: &mut impl Rng) {
    let wc = calib_core::whole_cell::CellRobot {
        model: robot.model.clone(),
        tools: Vec::new(),
        g_base: robot.g_base,
        tolerance: robot.tolerance,
        shared_joints: 0,
    };
    let t = robot.tolerance;
    for p in wc.fitted_params() {
        let prismatic = p
            .joint()
            .is_some_and(|j| robot.model.chain_joints()[j].kind.is_prismatic());
        let tol = match p {
            // A prismatic joint's offset is a length, its band the origin tolerance.
            _ if prismatic => wc.prior_sigma(p) * 3f64.sqrt(),
            ErrorParam::JointOffset { .. } => t.joint_offset_rad,
            ErrorParam::OriginXyz { .. } => t.origin_xyz_m,
            ErrorParam::OriginRpy { .. } => t.origin_rpy_rad,
            ErrorParam::JointScale { .. } => t.joint_scale.unwrap_or(0.0),
            ErrorParam::Compliance { .. } => t.compliance_rad_per_nm.unwrap_or(0.0),
            // The half-width behind the prior σ = tol/√3 of any other kind.
            _ => t.prior_sigma(p) * 3f64.sqrt(),
        };
        robot.errors.set(p, rng.random_range(-tol..=tol));
    }
    let tip = robot.tolerance.tip_m;
    if tip > 0.0 {
        robot.errors.tip = Vector3::from_fn(|_, _| rng.random_range(-tip..=tip));
    }
}

/// Replaces `truth`'s kinematic errors by a draw from its tolerances: both robots' errors are
/// zeroed, then each robot (1, then 2) is drawn by [`draw_kinematic_errors`] from `rng`; on a
/// shared-trunk cell robot 2's trunk then carries robot 1's draw ([`share_trunk_errors`]: one
/// set of trunk errors, as the cell file and the fit have it). For studies of planned sessions.
pub fn draw_errors_from_tolerance(truth: &mut Cell, rng: &mut impl Rng) {
    for r in [&mut truth.robot1, &mut truth.robot2] {
        r.errors = KinematicErrors::zero_for(&r.model);
        draw_kinematic_errors(r, rng);
    }
    share_trunk_errors(truth);
}

/// On a shared-trunk cell ([`Cell::shared_joints`] > 0), sets robot 2's errors at the shared
/// chain joints to robot 1's: the trunk has one set of errors, as the cell reader makes them
/// (`[robot2.errors]` at a shared joint is 0 or robot 1's) and the whole-cell fit has them (one
/// column per trunk parameter). Robot 2's own lumped coefficients of its arm links on the trunk
/// joints ([`kinematics::trunk::is_branch_param`]: its arm's weight on the trunk) stay its own.
/// Does nothing on other cells. The draws that fill each robot alone
/// ([`draw_kinematic_errors`]) call it after both robots are drawn, so the random stream, and
/// every other drawn value, is that of the draw without sharing.
pub fn share_trunk_errors(cell: &mut Cell) {
    let k = cell.shared_joints;
    if k == 0 {
        return;
    }
    let model = &cell.robot2.model;
    let trunk: Vec<ErrorParam> = kinematics::all_params_for(model)
        .into_iter()
        .chain(kinematics::lumped_params(model))
        .filter(|p| p.joint().is_some_and(|j| j < k) && !kinematics::trunk::is_branch_param(p, k))
        .collect();
    for p in trunk {
        let v = cell.robot1.errors.get(p);
        if cell.robot2.errors.get(p) != v {
            cell.robot2.errors.set(p, v);
        }
    }
}

pub mod report;

#[cfg(test)]
mod tests;

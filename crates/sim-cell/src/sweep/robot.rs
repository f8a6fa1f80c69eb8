//! Robot-mode trials: a simulated session on a cell whose robots may carry kinematic errors drawn
//! per trial from their tolerances, every method fitted on it, and each fit scored by
//! `e_tran`/`e_rot` and by its **cooperative accuracy** (issue 11): over held-out configuration
//! pairs `(q1_k, q2_k)` in the common workspace, the error of the calibrated models' prediction
//! of the vector from tip 2 to tip 1 in base 1, `v = f1(q1) − b1_from_b2·f2(q2)`
//! ([`calib_core::whole_cell::measure_cooperative_error`]). A point-registration method's models
//! are the nominal ones with its fitted `b1_from_b2`; the whole-cell fits carry their own
//! kinematic corrections.
//!
//! What does not change between the trials of a grid cell is made once, before the trials, from
//! generators of its own ([`setup_rng`], independent of every trial's): the [`EVAL_PAIRS`]
//! held-out pairs and, for the planned layout, the plan. Both are made on the NOMINAL cell
//! (no errors, no noise), as an operator would: the plan is the greedy A-optimal choice
//! ([`greedy_design`], cooperative criterion over the held-out pairs, the grid cell's σ) of
//! the grid cell's point count among [`PLAN_CANDIDATES`] reachable handclasps drawn uniformly
//! in the spread cube around the cell's centre. The same cube holds the held-out pairs. Both
//! are drawn, in that order from the setup generator, by `handclasp plan`'s candidate generator
//! ([`crate::plan::reachable_handclasps`] on [`crate::plan::nominal_cell`]).

use calib_core::whole_cell::{
    calibrate_cell, greedy_design, measure_cooperative_error, predict_cooperative_accuracy,
    CellEstimate, CellFitError, CellProblem, ConfigPair, DesignCriterion, ParamLayout,
    ScreenOptions, SolveOptions,
};
use calib_core::{fit_fast, Method, MountPair, TrialErrors};
use nalgebra::{Isometry3, Point3, Vector3};
use rand_chacha::ChaCha8Rng;

use super::config::{GridCell, KinematicErrorDraw, SweepConfig, SweepLayout, SweepMethod};
use super::run::{Cooperative, Failure, Outcome, TrialOutcome};
use crate::error::SimError;
use crate::layout::Layout;
pub use crate::plan::draw_kinematic_errors;
use crate::plan::{nominal_cell, reachable_handclasps};
use crate::simulate::{generate_session, SessionSpec};
use crate::trial_rng;
use handclasp_cell::cell::Cell;
use handclasp_cell::problem::{cell_problem, truth_estimate, FitModel};
use handclasp_cell::{Session, SessionPoint};

/// Held-out configuration pairs per grid cell for the cooperative columns.
pub const EVAL_PAIRS: usize = 200;
/// Candidate handclasps of the planned layout per grid cell.
pub const PLAN_CANDIDATES: usize = 300;
/// Draws per wanted point before a grid cell's spread cube is declared unreachable.
const DRAWS_PER_POINT: usize = 20;

/// The generator of grid cell `cell_index`'s setup (held-out pairs, plan): stream
/// `u64::MAX − cell_index` of the master seed, far above every trial's index.
pub fn setup_rng(seed: u64, cell_index: usize) -> ChaCha8Rng {
    trial_rng(seed, u64::MAX - cell_index as u64)
}

/// What the trials of one robot-mode grid cell share.
#[derive(Debug, Clone)]
pub struct RobotSetup {
    /// Held-out configuration pairs (rad) of the cooperative columns.
    pub eval_pairs: Vec<ConfigPair>,
    /// The planned teach points (robot 1's nominal tip targets, m, b1) for the planned layout.
    pub planned_b1: Option<Vec<Point3<f64>>>,
}

/// `count` handclasps both nominal robots of `nominal` reach, drawn by the plan's generator
/// ([`reachable_handclasps`]) around the cell's centre; an error naming `what` when fewer than
/// `count` of `DRAWS_PER_POINT·count` draws are reachable.
fn reachable_or_error(
    nominal: &Cell,
    spread_m: f64,
    count: usize,
    what: &str,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<SessionPoint>, SimError> {
    let max_draws = DRAWS_PER_POINT * count;
    let (out, _) = reachable_handclasps(
        nominal,
        &nominal.centre_b1,
        spread_m,
        count,
        max_draws,
        rng,
        &mut |_, _| {},
    );
    if out.len() < count {
        let c = nominal.centre_b1 * 1e3;
        return Err(SimError::InvalidInput(format!(
            "{what}: only {} of {max_draws} draws in the {:.0} mm cube around ({:.0}, {:.0}, {:.0}) mm are \
             reachable by both robots ({count} needed); reduce the spread",
            out.len(),
            spread_m * 1e3,
            c.x,
            c.y,
            c.z
        )));
    }
    Ok(out)
}

fn design_error(e: CellFitError) -> SimError {
    SimError::InvalidInput(format!("planned layout: {e}"))
}

/// The setup of one robot-mode grid cell (see the module documentation), from `rng` alone.
pub fn robot_setup(
    config: &SweepConfig,
    grid_cell: &GridCell,
    cell: &Cell,
    rng: &mut ChaCha8Rng,
) -> Result<RobotSetup, SimError> {
    let nominal = nominal_cell(cell);
    let spread_m = config.spread_m[grid_cell.spread];
    let eval_pairs: Vec<ConfigPair> =
        reachable_or_error(&nominal, spread_m, EVAL_PAIRS, "held-out pairs", rng)?
            .into_iter()
            .map(|p| ConfigPair {
                q1: p.q1,
                q2: p.q2,
                tool1: 0,
                tool2: 0,
            })
            .collect();
    let planned_b1 = if config.layout == SweepLayout::Planned {
        let n = config.n_points[grid_cell.n];
        let candidates = Session::from_points(reachable_or_error(
            &nominal,
            spread_m,
            PLAN_CANDIDATES,
            "plan candidates",
            rng,
        )?);
        let mut noisy = nominal.clone();
        noisy.noise = cell.noise;
        noisy.noise.alignment_m = Vector3::repeat(config.noise_mm[grid_cell.noise] * 1e-3);
        let problem = cell_problem(&noisy, &candidates, FitModel::Kinematic);
        let layout = ParamLayout::new(&problem, &[]);
        let at = CellEstimate::nominal(&problem, cell.b1_from_b2);
        let design = greedy_design(
            &problem,
            &layout,
            &at,
            &problem.observations,
            &eval_pairs,
            n,
            DesignCriterion::CooperativeA,
        )
        .map_err(design_error)?;
        Some(
            design
                .chosen
                .iter()
                .map(|&i| candidates.points[i].p_b1)
                .collect(),
        )
    } else {
        None
    };
    Ok(RobotSetup {
        eval_pairs,
        planned_b1,
    })
}

/// Indices of the 4 points whose tetrahedron has the largest volume: exhaustive up to
/// [`SPREAD4_EXHAUSTIVE`] points, else greedy (the farthest pair, then the point farthest from
/// its line, then from their plane). `None` for fewer than 4 points.
pub fn most_spread_four(points: &[Point3<f64>]) -> Option<[usize; 4]> {
    let n = points.len();
    if n < 4 {
        return None;
    }
    let volume = |a: usize, b: usize, c: usize, d: usize| {
        let (pa, pb, pc, pd) = (points[a], points[b], points[c], points[d]);
        (pb - pa).cross(&(pc - pa)).dot(&(pd - pa)).abs()
    };
    if n <= SPREAD4_EXHAUSTIVE {
        let mut best = ([0, 1, 2, 3], -1.0);
        for a in 0..n {
            for b in a + 1..n {
                for c in b + 1..n {
                    for d in c + 1..n {
                        let v = volume(a, b, c, d);
                        if v > best.1 {
                            best = ([a, b, c, d], v);
                        }
                    }
                }
            }
        }
        return Some(best.0);
    }
    let argmax =
        |f: &dyn Fn(usize) -> f64| (0..n).max_by(|&i, &j| f(i).total_cmp(&f(j))).unwrap_or(0);
    let a = argmax(&|i| (points[i] - points[0]).norm());
    let b = argmax(&|i| (points[i] - points[a]).norm());
    let c = argmax(&|i| {
        (points[b] - points[a])
            .cross(&(points[i] - points[a]))
            .norm()
    });
    let d = argmax(&|i| volume(a, b, c, i));
    Some([a, b, c, d])
}

/// Largest point count for which [`most_spread_four`] tries every quadruple.
pub const SPREAD4_EXHAUSTIVE: usize = 64;

/// The cooperative error of the nominal models with placement `b1_from_b2` against the truth.
fn nominal_models_cooperative(
    problem: &CellProblem,
    truth: &CellEstimate,
    b1_from_b2: Isometry3<f64>,
    pairs: &[ConfigPair],
) -> Option<Cooperative> {
    let est = CellEstimate::nominal(problem, b1_from_b2);
    let e = measure_cooperative_error(problem, &est, truth, pairs).ok()?;
    Some(Cooperative {
        rms_m: e.rms_m,
        p95_m: e.p95_m,
        predicted_rms_m: None,
    })
}

/// A whole-cell fit of `model` on the session: `b1_from_b2` and the cooperative error of its
/// models, with the fit's predicted rms over the same pairs
/// ([`calib_core::whole_cell::predict_cooperative_accuracy`], the model-error term included).
fn whole_cell_outcome(
    cell: &Cell,
    session: &Session,
    model: FitModel,
    truth: &CellEstimate,
    pairs: &[ConfigPair],
) -> Outcome {
    let problem = cell_problem(cell, session, model);
    let cal = calibrate_cell(
        &problem,
        &SolveOptions::default(),
        &ScreenOptions::default(),
    )
    .map_err(|_| Failure::FitFailed)?;
    let fit = &cal.fit;
    let measured = measure_cooperative_error(&problem, &fit.estimate, truth, pairs)
        .map_err(|_| Failure::FitFailed)?;
    // Only the rms is used (exact); the p95 draw's seed does not matter.
    let predicted =
        predict_cooperative_accuracy(&problem, fit, pairs, 0).map_err(|_| Failure::FitFailed)?;
    Ok(TrialOutcome {
        errors: TrialErrors::between(&cell.b1_from_b2, &fit.estimate.b1_from_b2),
        cooperative: Some(Cooperative {
            rms_m: measured.rms_m,
            p95_m: measured.p95_m,
            predicted_rms_m: Some(predicted.predicted_rms_m),
        }),
    })
}

/// One robot-mode trial: the true errors (if drawn), a simulated session on `cell` (σ from the
/// grid), every method fitted on it, errors against the cell's true `b1_from_b2` and the
/// cooperative accuracy against the true robots. One outcome per method is pushed to `out`.
pub(super) fn robot_trial(
    config: &SweepConfig,
    grid_cell: &GridCell,
    cell: &Cell,
    setup: &RobotSetup,
    rng: &mut ChaCha8Rng,
    out: &mut Vec<Outcome>,
) {
    let mut cell = cell.clone();
    cell.noise.alignment_m = Vector3::repeat(config.noise_mm[grid_cell.noise] / 1000.0);
    if config.kinematic_errors == KinematicErrorDraw::Tolerance {
        draw_kinematic_errors(&mut cell.robot1, rng);
        draw_kinematic_errors(&mut cell.robot2, rng);
        crate::plan::share_trunk_errors(&mut cell);
    }
    let n = config.n_points[grid_cell.n];
    let spread_m = config.spread_m[grid_cell.spread];
    let spec = match config.layout {
        SweepLayout::Points(layout) => SessionSpec::new(n, layout, spread_m),
        SweepLayout::Planned => SessionSpec {
            points_b1: setup.planned_b1.clone(),
            ..SessionSpec::new(n, Layout::Random, spread_m)
        },
    };
    let session = match generate_session(&cell, &spec, rng) {
        Ok(s) => s,
        Err(_) => {
            out.extend(config.methods.iter().map(|_| Err(Failure::Unreachable)));
            return;
        }
    };
    let (p1, p2) = session.tips();
    let mounts: MountPair = config.mounts[grid_cell.mounts];
    let scoring = cell_problem(&cell, &session, FitModel::Kinematic);
    let truth = truth_estimate(&cell, &scoring);
    let pairs = &setup.eval_pairs;
    let registration = |x: Option<Isometry3<f64>>| -> Outcome {
        let x = x.ok_or(Failure::FitFailed)?;
        Ok(TrialOutcome {
            errors: TrialErrors::between(&cell.b1_from_b2, &x),
            cooperative: nominal_models_cooperative(&scoring, &truth, x, pairs),
        })
    };
    for &method in &config.methods {
        out.push(match method {
            SweepMethod::Registration(m) => registration(fit_fast(m, &mounts, &p1, &p2)),
            SweepMethod::PaperSpread4 => registration(most_spread_four(&p1).and_then(|idx| {
                let a = idx.map(|i| p1[i]);
                let b = idx.map(|i| p2[i]);
                fit_fast(Method::Paper, &mounts, &a, &b)
            })),
            SweepMethod::Placement => {
                whole_cell_outcome(&cell, &session, FitModel::Placement, &truth, pairs)
            }
            SweepMethod::Kinematic => {
                whole_cell_outcome(&cell, &session, FitModel::Kinematic, &truth, pairs)
            }
        });
    }
}

//! `handclasp plan --cell CELL --n N [--candidates K] [--criterion a|d] [--seed S] --out plan.csv
//! [--json]`: chooses the N handclasp poses (of K seeded candidates both robots reach within
//! their joint limits) that minimise the predicted cooperative error of the whole-cell
//! calibration (A) or maximise its information volume (D), with the cell's tolerances as the prior
//! and its noise (`sim_cell::plan`, maths in `calib_core::whole_cell::design`).
//!
//! `plan.csv` is a session CSV (point, r1_q*_deg, r2_q*_deg, nominal r1_/r2_ tip columns in mm):
//! the operator teaches from it and `Session::read_csv` reads it. The report compares the plan's
//! prediction with the mean over `--random-draws` random picks of N of the same candidates.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use calib_core::whole_cell::{DesignCriterion, DesignPredictionReport, PredictedErrorReport};
use handclasp_cell::Cell;
use nalgebra::Point3;
use serde::Serialize;

use crate::progress::Progress;
use sim_cell::plan::{plan_session, Plan, PlanSpec, DEFAULT_RANDOM_DRAWS, EVAL_POSES};

/// `--criterion`; serialised as `"a"` or `"d"`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum CriterionArg {
    /// A-optimal: smallest predicted cooperative error (tip 2 → tip 1 in b1) of the whole-cell fit.
    A,
    /// D-optimal: largest information volume (smallest posterior parameter volume).
    D,
}

/// Arguments of `handclasp plan`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cell TOML (robots' URDFs and tips in mm, b1_from_b2, `[noise]` σ in mm,
    /// `[robotN.tolerance]` as the prior, `[teach]` centre).
    #[arg(long)]
    pub cell: PathBuf,
    /// Poses to plan.
    #[arg(long, default_value_t = 40)]
    pub n: usize,
    /// Reachable candidate poses to choose from (seeded). More candidates plan better and take
    /// longer (400: about 1.3 s of CPU in a release build).
    #[arg(long, default_value_t = 400)]
    pub candidates: usize,
    /// a: smallest predicted cooperative error; d: largest information volume.
    #[arg(long, value_enum, default_value = "a")]
    pub criterion: CriterionArg,
    /// Seed of the candidates, the evaluation poses and the random comparison.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Side of the cube the candidate meeting points are drawn in, mm.
    #[arg(long, default_value_t = 1000.0)]
    pub spread_mm: f64,
    /// Centre of that cube in base 1, mm, as X,Y,Z (negative values allowed; default: the
    /// cell's `[teach]` centre).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_name = "X,Y,Z"
    )]
    pub centre_mm: Option<Vec<f64>>,
    /// Random picks of N candidates the plan is compared with (the report gives their mean).
    #[arg(long, default_value_t = DEFAULT_RANDOM_DRAWS)]
    pub random_draws: usize,
    /// Where to write the plan (a session CSV: point, r1_q*_deg, r2_q*_deg, nominal tips in mm).
    #[arg(long)]
    pub out: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs `handclasp plan`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let centre_b1 = match &args.centre_mm {
        None => None,
        Some(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => {
            Some(Point3::new(v[0], v[1], v[2]) * 1e-3)
        }
        Some(v) => bail!(
            "--centre-mm takes three finite numbers X,Y,Z in mm (e.g. 475,-50,995); got {v:?}"
        ),
    };
    let cell = Cell::from_toml_file(&args.cell)?;
    let spec = PlanSpec {
        n: args.n,
        candidates: args.candidates,
        criterion: match args.criterion {
            CriterionArg::A => DesignCriterion::CooperativeA,
            CriterionArg::D => DesignCriterion::D,
        },
        seed: args.seed,
        spread_m: args.spread_mm * 1e-3,
        centre_b1,
        random_draws: args.random_draws,
    };
    // Progress on stderr only when it is a terminal (scripts and captures see the report alone).
    let tty = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let wanted = args.candidates;
    let mut design: Option<Progress> = None;
    let plan = plan_session(&cell, &spec, &mut |found, drawn| {
        if tty {
            eprint!("\rcandidates: {found}/{wanted} reachable of {drawn} drawn");
            if found == wanted && design.is_none() {
                // The greedy design and the random picks' predictions come next.
                eprintln!();
                design = Some(Progress::new(
                    true,
                    format!("choosing {} poses of {wanted} candidates", args.n),
                ));
            }
        }
    });
    match &design {
        Some(p) => p.finish(),
        None if tty => eprintln!(),
        None => {}
    }
    let plan = plan.with_context(|| format!("planning on {}", args.cell.display()))?;
    // The input checks every command runs on a session: the plan is one (a planner defect
    // otherwise; never written).
    handclasp_cell::check_session_inputs(&plan.session).map_err(|source| {
        handclasp_cell::FormatError::SessionCheck {
            path: args.out.clone(),
            source,
        }
    })?;
    // The degeneracy check calibrate --cell runs on a session, in its words.
    let planned = handclasp_cell::problem::cell_problem(
        &cell,
        &plan.session,
        handclasp_cell::problem::FitModel::Kinematic,
    );
    for w in cli_support::result_check::layout_warnings(&planned) {
        eprintln!("warning: {w}");
    }
    plan.session
        .write_csv(&args.out, &cell)
        .with_context(|| format!("--out {}", args.out.display()))?;
    let report = PlanReport::new(&args, &cell, &plan);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

/// What `handclasp plan` prints: the command's inputs (cell, output file, flags), the plan's
/// poses and its prediction beside the random picks'. `--json` serialises it; [`render_text`]
/// reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this
/// report was before it had types).
#[derive(Debug, Clone, Serialize)]
struct PlanReport {
    /// The candidates asked for, found reachable, and the points drawn to find them.
    candidates: CandidateCounts,
    /// `--cell`.
    cell: String,
    /// The candidates' cube centre in b1, mm (`--centre-mm` or the cell's `[teach]` centre).
    centre_mm: [f64; 3],
    /// How much lower the plan's predicted cooperative rms is than the random picks' mean, %.
    cooperative_gain_over_random_percent: f64,
    /// `--criterion`.
    criterion: CriterionArg,
    /// What the evaluation pairs are.
    evaluation_pair_set: String,
    /// Number of held-out evaluation pairs.
    evaluation_pairs: usize,
    /// `--n`.
    n: usize,
    /// `--out`.
    out: String,
    /// The chosen poses, in the order chosen.
    poses: Vec<PlannedPose>,
    /// The plan's prediction and the random picks' mean.
    predicted: Predicted,
    /// The plan's predicted error in parts, over its held-out pairs and the whole workspace.
    predicted_error_mm: PlanPredictedError,
    /// Random picks compared with.
    random_draws: usize,
    /// `--seed`.
    seed: u64,
    /// `--spread-mm`.
    spread_mm: f64,
    /// Always false: the tip is not checked for collision with its own robot's links.
    tip_collision_checked: bool,
}

/// Candidate counts of a plan.
#[derive(Debug, Clone, Serialize)]
struct CandidateCounts {
    asked: usize,
    drawn: usize,
    reachable: usize,
}

/// The plan's prediction and the mean of the random picks'.
#[derive(Debug, Clone, Serialize)]
struct Predicted {
    plan: DesignPredictionReport,
    random: DesignPredictionReport,
}

/// The plan's predicted error in parts ([`sim_cell::plan::PlanParts`]), mm.
#[derive(Debug, Clone, Serialize)]
struct PlanPredictedError {
    /// Over the held-out pairs at the tolerances (prior scale 1, as the design assumes).
    held_out: PredictedErrorReport,
    /// Over the same pairs at the placement-only limit (prior scale 0.001).
    placement_only_limit: PredictedErrorReport,
    /// Over the whole workspace (the poses `calibrate --cell` predicts over), prior scale 1.
    workspace: Option<PredictedErrorReport>,
}

/// One chosen pose: joints (deg) and nominal tips (mm, each in its robot's base).
#[derive(Debug, Clone, Serialize)]
struct PlannedPose {
    /// Its candidate number (1-based).
    candidate: usize,
    /// Its point number in the plan.
    point: usize,
    r1_q_deg: Vec<f64>,
    r1_tip_mm: [f64; 3],
    r2_q_deg: Vec<f64>,
    r2_tip_mm: [f64; 3],
}

impl PlanReport {
    fn new(args: &Args, cell: &Cell, plan: &Plan) -> Self {
        let deg = |q: &[f64]| q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>();
        let poses = plan
            .session
            .points
            .iter()
            .zip(&plan.chosen)
            .map(|(p, &c)| PlannedPose {
                candidate: c + 1,
                point: p.point,
                r1_q_deg: deg(&p.q1),
                r1_tip_mm: [p.p_b1.x * 1e3, p.p_b1.y * 1e3, p.p_b1.z * 1e3],
                r2_q_deg: deg(&p.q2),
                r2_tip_mm: [p.p_b2.x * 1e3, p.p_b2.y * 1e3, p.p_b2.z * 1e3],
            })
            .collect();
        let gain = 1.0 - plan.predicted.cooperative_rms_m / plan.random_mean.cooperative_rms_m;
        PlanReport {
            candidates: CandidateCounts {
                asked: args.candidates,
                drawn: plan.attempts,
                reachable: plan.candidates.len(),
            },
            cell: args.cell.display().to_string(),
            centre_mm: plan_centre(args, cell),
            cooperative_gain_over_random_percent: gain * 100.0,
            criterion: args.criterion,
            evaluation_pair_set: format!(
                "{EVAL_POSES} held-out reachable handclasp poses (q1_i, q2_i) in the same cube"
            ),
            evaluation_pairs: plan.eval_pairs.len(),
            n: args.n,
            out: args.out.display().to_string(),
            poses,
            predicted: Predicted {
                plan: DesignPredictionReport::from(&plan.predicted),
                random: DesignPredictionReport::from(&plan.random_mean),
            },
            predicted_error_mm: PlanPredictedError {
                held_out: PredictedErrorReport::from(&plan.parts.held_out),
                placement_only_limit: PredictedErrorReport::from(&plan.parts.placement_only_limit),
                workspace: plan
                    .parts
                    .workspace
                    .as_ref()
                    .map(PredictedErrorReport::from),
            },
            random_draws: plan.random.len(),
            seed: args.seed,
            spread_mm: args.spread_mm,
            tip_collision_checked: false,
        }
    }
}

fn plan_centre(args: &Args, cell: &Cell) -> [f64; 3] {
    match &args.centre_mm {
        Some(v) if v.len() == 3 => [v[0], v[1], v[2]],
        _ => {
            let c = cell.centre_b1 * 1e3;
            [c.x, c.y, c.z]
        }
    }
}

/// Numbers with `decimals` decimals, separated by spaces.
fn list(v: &[f64], decimals: usize) -> String {
    v.iter()
        .map(|x| format!("{x:.decimals$}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The text report (mm, degrees).
fn render_text(r: &PlanReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &PlanReport) -> std::fmt::Result {
    let (criterion, goal) = match r.criterion {
        CriterionArg::A => ("a", "smallest predicted cooperative error"),
        CriterionArg::D => ("d", "largest information volume"),
    };
    writeln!(
        s,
        "== session plan: {} poses, criterion {criterion} ({goal}), from {} reachable candidates ({} drawn, seed {})",
        r.n, r.candidates.reachable, r.candidates.drawn, r.seed
    )?;
    writeln!(
        s,
        "{:>5} {:>9}  {:<58} {:<50} meeting point in b1, mm",
        "point", "candidate", "robot 1 joints, deg", "robot 2 joints, deg",
    )?;
    for p in &r.poses {
        writeln!(
            s,
            "{:>5} {:>9}  {:<58} {:<50} {}",
            p.point,
            p.candidate,
            list(&p.r1_q_deg, 2),
            list(&p.r2_q_deg, 2),
            list(&p.r1_tip_mm, 1)
        )?;
    }
    writeln!(
        s,
        "predicted after a whole-cell calibration (prior from the cell's tolerances, the cell's noise), \
         cooperative error over the {} held-out configuration pairs:",
        r.evaluation_pairs
    )?;
    let random = format!(
        "random (mean of {} picks of the same candidates)",
        r.random_draws
    );
    for (name, p) in [
        ("plan", &r.predicted.plan),
        (random.as_str(), &r.predicted.random),
    ] {
        writeln!(
            s,
            "  {name:<50} cooperative rms {:.3} mm   e_tran {:.3} mm   e_rot {:.4}°",
            p.cooperative_rms_mm, p.e_tran_mm, p.e_rot_deg
        )?;
    }
    writeln!(
        s,
        "  the plan's cooperative rms is {:.0} % below the random picks' mean",
        r.cooperative_gain_over_random_percent
    )?;
    let p = &r.predicted_error_mm;
    writeln!(s, "  plan, {}", p.held_out.parts_line())?;
    if let Some(w) = &p.workspace {
        writeln!(
            s,
            "  plan over the whole workspace ({} seeded reachable handclasps: robot 1 within its joint limits, robot 2 meeting it head-on; the poses calibrate --cell predicts over): rms {:.3} mm, p95 {:.3} mm",
            w.pairs, w.predicted_rms, w.predicted_p95
        )?;
        writeln!(s, "    {}", w.parts_line())?;
    }
    let l = &p.placement_only_limit;
    writeln!(
        s,
        "  plan at the placement-only limit (prior scale 0.001: the kinematic corrections held at nominal, as calibrate --cell's evidence chooses when the robots look closer to nominal than their tolerances or the data are few or noisy): rms {:.3} mm over the held-out pairs, of which prior-asserted {:.3} mm",
        l.predicted_rms, l.prior_part_rms
    )?;
    writeln!(
        s,
        "  (calibrate --cell predicts with the same definition over its session's own meeting pairs and the whole workspace, at the prior scale its evidence chooses: near the figures at scale 1 above when it chooses 1, near the placement-only limit when it chooses 0.001)"
    )?;
    writeln!(
        s,
        "  (e_tran/e_rot of b1_from_b2 carry the kinematic errors no handclasp can tell from the placement, \
         held by the prior; the cooperative error does not)"
    )?;
    writeln!(
        s,
        "note: the tip is not checked for collision with its own robot's links"
    )?;
    writeln!(s, "wrote {}", r.out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prediction(rms_mm: f64) -> DesignPredictionReport {
        DesignPredictionReport {
            cooperative_rms_mm: rms_mm,
            e_rot_deg: 0.01234,
            e_tran_mm: 0.25,
            log_det_information: 12.5,
        }
    }

    fn parts(rms: f64, set: PairSet) -> PredictedErrorReport {
        PredictedErrorReport {
            data_part_rms: 0.3,
            held_out_ratio: None,
            held_out_p_value: None,
            held_out_regions: None,
            model_error_rms: 0.0,
            model_error_source: "assumed_none",
            pair_set: set.describe(),
            pair_set_kind: set,
            pairs: 200,
            predicted_p95: 2.0 * rms,
            predicted_rms: rms,
            prior_part_rms: 0.4,
            rms_bound95: 1.2 * rms,
        }
    }

    fn report() -> PlanReport {
        PlanReport {
            candidates: CandidateCounts {
                asked: 400,
                drawn: 1234,
                reachable: 400,
            },
            cell: "cells/floor-wall.toml".into(),
            centre_mm: [475.0, -50.0, 995.0],
            cooperative_gain_over_random_percent: 41.6,
            criterion: CriterionArg::A,
            evaluation_pair_set: "200 held-out …".into(),
            evaluation_pairs: 200,
            n: 1,
            out: "plan.csv".into(),
            poses: vec![PlannedPose {
                candidate: 17,
                point: 1,
                r1_q_deg: vec![10.0, -20.555, 0.0],
                r1_tip_mm: [475.04, -50.0, 995.0],
                r2_q_deg: vec![1.0, 2.0],
                r2_tip_mm: [0.0; 3],
            }],
            predicted: Predicted {
                plan: prediction(0.5),
                random: prediction(0.85),
            },
            predicted_error_mm: PlanPredictedError {
                held_out: parts(0.5, PairSet::HeldOutHandclasps),
                placement_only_limit: parts(1.5, PairSet::HeldOutHandclasps),
                workspace: Some(parts(0.75, PairSet::Workspace)),
            },
            random_draws: 20,
            seed: 1,
            spread_mm: 1000.0,
            tip_collision_checked: false,
        }
    }

    use calib_core::whole_cell::PairSet;

    #[test]
    fn text_of_a_plan() {
        let text = render_text(&report());
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "== session plan: 1 poses, criterion a (smallest predicted cooperative error), from 400 reachable candidates (1234 drawn, seed 1)"
        );
        assert_eq!(
            lines[2],
            format!(
                "{:>5} {:>9}  {:<58} {:<50} 475.0 -50.0 995.0",
                1, 17, "10.00 -20.55 0.00", "1.00 2.00"
            )
        );
        for line in [
            "  plan                                               cooperative rms 0.500 mm   e_tran 0.250 mm   e_rot 0.0123°",
            "  random (mean of 20 picks of the same candidates)   cooperative rms 0.850 mm   e_tran 0.250 mm   e_rot 0.0123°",
            "  the plan's cooperative rms is 42 % below the random picks' mean",
            "  plan, of which: data-determined 0.300 mm, prior-asserted 0.400 mm (the tolerances of the terms the data do not determine: right only if the robots are that far off), model error none assumed; 95 % bound of the rms 0.600 mm",
            "  plan at the placement-only limit (prior scale 0.001: the kinematic corrections held at nominal, as calibrate --cell's evidence chooses when the robots look closer to nominal than their tolerances or the data are few or noisy): rms 1.500 mm over the held-out pairs, of which prior-asserted 0.400 mm",
            "wrote plan.csv",
        ] {
            assert!(lines.contains(&line), "{line:?} missing in\n{text}");
        }
        let mut d = report();
        d.criterion = CriterionArg::D;
        assert!(render_text(&d).contains("criterion d (largest information volume)"));
    }

    /// The JSON's keys in the order of the `serde_json::Value` it was, the criterion as a letter.
    #[test]
    fn json_keys_in_value_order() {
        let json = crate::test_support::json_in_value_order(&report());
        assert!(
            json.contains(r#""criterion":"a""#)
                && json.contains(r#""tip_collision_checked":false"#)
        );
    }
}

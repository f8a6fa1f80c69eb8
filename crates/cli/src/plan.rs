//! `handclasp plan --cell CELL --n N [--candidates K] [--criterion a|d] [--seed S] --out plan.csv
//! [--json]`: chooses the N handclasp poses (of K seeded candidates both robots reach within
//! their joint limits) that minimise the predicted cooperative error of the whole-cell
//! calibration (A) or maximise its information volume (D), with the cell's tolerances as the prior
//! and its noise (`sim_cell::plan`, maths in `calib_core::whole_cell::design`).
//!
//! `plan.csv` is a session CSV (point, r1_q*_deg, r2_q*_deg, nominal r1_/r2_ tip columns in mm):
//! the operator teaches from it and `Session::read_csv` reads it. The report compares the plan's
//! prediction with the mean over `--random-draws` random picks of N of the same candidates.

use std::path::PathBuf;

use anyhow::{bail, Context};
use calib_core::whole_cell::{DesignCriterion, DesignPrediction};
use handclasp_cell::Cell;
use nalgebra::Point3;
use serde_json::{json, Value};
use sim_cell::plan::{plan_session, Plan, PlanSpec, DEFAULT_RANDOM_DRAWS, EVAL_POSES};

/// `--criterion`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
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
    let plan = plan_session(&cell, &spec, &mut |found, drawn| {
        if tty {
            eprint!("\rcandidates: {found}/{wanted} reachable of {drawn} drawn");
        }
    });
    if tty {
        eprintln!();
    }
    let plan = plan.with_context(|| format!("planning on {}", args.cell.display()))?;
    plan.session
        .write_csv(&args.out, &cell)
        .with_context(|| format!("--out {}", args.out.display()))?;
    let out = report(&args, &cell, &plan);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print_text(&out);
    }
    Ok(())
}

fn prediction(p: &DesignPrediction) -> Value {
    json!({
        "cooperative_rms_mm": p.cooperative_rms_m * 1e3,
        "e_tran_mm": p.e_tran_m * 1e3,
        "e_rot_deg": p.e_rot_rad.to_degrees(),
        "log_det_information": p.log_det_info,
    })
}

/// The JSON report (mm, degrees).
fn report(args: &Args, cell: &Cell, plan: &Plan) -> Value {
    let deg = |q: &[f64]| q.iter().map(|v| v.to_degrees()).collect::<Vec<_>>();
    let poses: Vec<Value> = plan
        .session
        .points
        .iter()
        .zip(&plan.chosen)
        .map(|(p, &c)| {
            json!({
                "point": p.point,
                "candidate": c + 1,
                "r1_q_deg": deg(&p.q1),
                "r2_q_deg": deg(&p.q2),
                "r1_tip_mm": [p.p_b1.x * 1e3, p.p_b1.y * 1e3, p.p_b1.z * 1e3],
                "r2_tip_mm": [p.p_b2.x * 1e3, p.p_b2.y * 1e3, p.p_b2.z * 1e3],
            })
        })
        .collect();
    let centre = plan_centre(args, cell);
    let gain = 1.0 - plan.predicted.cooperative_rms_m / plan.random_mean.cooperative_rms_m;
    json!({
        "cell": args.cell.display().to_string(),
        "out": args.out.display().to_string(),
        "n": args.n,
        "criterion": match args.criterion { CriterionArg::A => "a", CriterionArg::D => "d" },
        "seed": args.seed,
        "spread_mm": args.spread_mm,
        "centre_mm": centre,
        "candidates": {
            "asked": args.candidates,
            "reachable": plan.candidates.len(),
            "drawn": plan.attempts,
        },
        "evaluation_pairs": plan.eval_pairs.len(),
        "evaluation_pair_set": format!(
            "{EVAL_POSES} held-out reachable handclasp poses (q1_i, q2_i) in the same cube"
        ),
        "random_draws": plan.random.len(),
        "predicted": {
            "plan": prediction(&plan.predicted),
            "random": prediction(&plan.random_mean),
        },
        "cooperative_gain_over_random_percent": gain * 100.0,
        "tip_collision_checked": false,
        "poses": poses,
    })
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

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn list(v: &Value, decimals: usize) -> String {
    v.as_array()
        .map(|a| {
            a.iter()
                .map(|x| format!("{:.*}", decimals, num(x)))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_default()
}

fn print_text(v: &Value) {
    let c = &v["candidates"];
    println!(
        "== session plan: {} poses, criterion {} ({}), from {} reachable candidates ({} drawn, seed {})",
        v["n"],
        v["criterion"].as_str().unwrap_or("?"),
        if v["criterion"] == "a" {
            "smallest predicted cooperative error"
        } else {
            "largest information volume"
        },
        c["reachable"],
        c["drawn"],
        v["seed"]
    );
    println!(
        "{:>5} {:>9}  {:<58} {:<50} meeting point in b1, mm",
        "point", "candidate", "robot 1 joints, deg", "robot 2 joints, deg",
    );
    for p in v["poses"].as_array().cloned().unwrap_or_default() {
        println!(
            "{:>5} {:>9}  {:<58} {:<50} {}",
            p["point"].as_u64().unwrap_or(0),
            p["candidate"].as_u64().unwrap_or(0),
            list(&p["r1_q_deg"], 2),
            list(&p["r2_q_deg"], 2),
            list(&p["r1_tip_mm"], 1)
        );
    }
    let pr = &v["predicted"];
    println!(
        "predicted after a whole-cell calibration (prior from the cell's tolerances, the cell's noise), \
         cooperative error over the {} held-out configuration pairs:",
        v["evaluation_pairs"]
    );
    for (name, k) in [
        ("plan", "plan"),
        (
            &format!(
                "random (mean of {} picks of the same candidates)",
                v["random_draws"]
            ),
            "random",
        ),
    ] {
        println!(
            "  {name:<50} cooperative rms {:.3} mm   e_tran {:.3} mm   e_rot {:.4}°",
            num(&pr[k]["cooperative_rms_mm"]),
            num(&pr[k]["e_tran_mm"]),
            num(&pr[k]["e_rot_deg"])
        );
    }
    println!(
        "  the plan's cooperative rms is {:.0} % below the random picks' mean",
        num(&v["cooperative_gain_over_random_percent"])
    );
    println!(
        "  (e_tran/e_rot of b1_from_b2 carry the kinematic errors no handclasp can tell from the placement, \
         held by the prior; the cooperative error does not)"
    );
    println!("note: the tip is not checked for collision with its own robot's links");
    println!("wrote {}", v["out"].as_str().unwrap_or("?"));
}

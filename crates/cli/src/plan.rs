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
use handclasp_cell::Cell;
use nalgebra::Point3;

use crate::progress::Progress;
use sim_cell::plan::report::{render_text, Criterion, PlanInputs, PlanReport};
use sim_cell::plan::{plan_session, PlanSpec, DEFAULT_RANDOM_DRAWS};

/// `--criterion` (the report's [`Criterion`]).
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CriterionArg {
    /// A-optimal: smallest predicted cooperative error (tip 2 → tip 1 in b1) of the whole-cell fit.
    A,
    /// D-optimal: largest information volume (smallest posterior parameter volume).
    D,
}

impl CriterionArg {
    /// The report's criterion.
    fn criterion(self) -> Criterion {
        match self {
            CriterionArg::A => Criterion::A,
            CriterionArg::D => Criterion::D,
        }
    }
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
        criterion: args.criterion.criterion().design(),
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
    let cell_name = args.cell.display().to_string();
    let out = args.out.display().to_string();
    let report = PlanReport::new(
        &PlanInputs {
            cell: &cell_name,
            out: &out,
            n: args.n,
            candidates: args.candidates,
            criterion: args.criterion.criterion(),
            seed: args.seed,
            spread_mm: args.spread_mm,
            centre_mm: args
                .centre_mm
                .as_ref()
                .filter(|v| v.len() == 3)
                .map(|v| [v[0], v[1], v[2]]),
        },
        &cell,
        &plan,
    );
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

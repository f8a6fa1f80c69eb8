//! `sim-cell`: simulated handclasp sessions and Monte Carlo sweeps.
//!
//! `sim-cell session` writes a simulated session CSV for a cell; `sim-cell sweep` runs a Monte Carlo
//! study (geometry-only or robot mode) and writes trials.csv, summary.csv and SVG plots;
//! `sim-cell paper` sets the simulation beside the paper's Table 1.

use anyhow::{bail, Context, Result};
use calib_core::whole_cell::Kind;
use calib_core::MountPair;
use clap::{Parser, Subcommand, ValueEnum};
use handclasp_cell::Cell;
use handclasp_cell::Session;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use sim_cell::layout::Layout;
use sim_cell::sweep::{self, KinematicErrorDraw, Mode, SweepConfig, SweepLayout, SweepMethod};
use sim_cell::{
    generate_kind_session, read_points_b1_csv, teach_from_plan, trial_rng, KindSpec, SessionSpec,
    SimError, SimKind,
};
use std::io::{BufWriter, IsTerminal, Write};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Parser)]
#[command(name = "sim-cell", version, about = "Simulated dual-robot handclasp cell: sessions and Monte Carlo sweeps", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate one handclasp session on a cell and write it as CSV (valid `handclasp calibrate` input).
    Session(SessionArgs),
    /// Monte Carlo study over noise × spread × points × mounts × methods.
    Sweep(SweepArgs),
    /// The simulation beside the paper's Table 1: the noise level that best explains the published
    /// errors per method and mount, where simulation and measurements agree and where they do not
    /// (the same study as `handclasp paper diagnose`).
    Paper(PaperArgs),
    /// The prior-scale benchmark (issue 20): the whole-cell fit's evidence-chosen prior scales
    /// against a MAP fit that knows the true prior (the oracle), the stated tolerances held
    /// (scale 1) and the placement-only fit, by held-out cooperative rms; prints a table.
    Oracle(OracleArgs),
}

#[derive(clap::Args)]
struct OracleArgs {
    /// Cell TOMLs (their robots, placement, teach centre and noise; the tolerances are set
    /// from --joint-deg and --origin-mm). Default: cells/floor-floor, floor-wall and
    /// floor-ceiling.toml.
    #[arg(long = "cell", value_name = "CELL.toml")]
    cells: Vec<PathBuf>,
    /// Seeds (sessions) per cell.
    #[arg(long, default_value_t = 20)]
    seeds: usize,
    /// Master seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Handclasps per session.
    #[arg(long, default_value_t = 40)]
    points: usize,
    /// Alignment σ per axis, mm.
    #[arg(long, default_value_t = 0.3)]
    noise_mm: f64,
    /// Side of the teach cube around the cell's teach centre, mm.
    #[arg(long, default_value_t = 700.0)]
    spread_mm: f64,
    /// Stated joint-offset tolerance, degrees.
    #[arg(long, default_value_t = 0.05)]
    joint_deg: f64,
    /// Stated origin-xyz and tip tolerance, mm.
    #[arg(long, default_value_t = 0.5)]
    origin_mm: f64,
    /// The truth is drawn from U(±F·tolerance): 1 = the stated tolerances are right, 10 = the
    /// robots are 10× further off than stated.
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    truth_factor: f64,
    /// Also print one line per trial.
    #[arg(long)]
    trials: bool,
}

#[derive(clap::Args)]
struct PaperArgs {
    /// Print one JSON object instead of the text report.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    study: sim_cell::paper::StudyOptions,
}

#[derive(Clone, Copy, ValueEnum)]
enum LayoutArg {
    /// Paper's advice: regular tetrahedron (edge = spread), extra points inside.
    Tetrahedron,
    /// Uniform in a cube of side = spread.
    Random,
    /// Near-planar: horizontal square of side = spread, ±1 % thick.
    Planar,
    /// Two small clusters spread apart.
    Clustered,
}

impl From<LayoutArg> for Layout {
    fn from(l: LayoutArg) -> Layout {
        match l {
            LayoutArg::Tetrahedron => Layout::Tetrahedron,
            LayoutArg::Random => Layout::Random,
            LayoutArg::Planar => Layout::Planar,
            LayoutArg::Clustered => Layout::Clustered,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum SweepLayoutArg {
    /// Paper's advice: regular tetrahedron (edge = spread), extra points inside.
    Tetrahedron,
    /// Uniform in a cube of side = spread.
    Random,
    /// Near-planar: horizontal square of side = spread, ±1 % thick.
    Planar,
    /// Two small clusters spread apart.
    Clustered,
    /// Robot mode: the greedy A-optimal plan (cooperative accuracy) of N points from 300 seeded
    /// reachable candidates in the spread cube, made once per grid cell on the nominal cell.
    Planned,
}

impl From<SweepLayoutArg> for SweepLayout {
    fn from(l: SweepLayoutArg) -> SweepLayout {
        match l {
            SweepLayoutArg::Tetrahedron => Layout::Tetrahedron.into(),
            SweepLayoutArg::Random => Layout::Random.into(),
            SweepLayoutArg::Planar => Layout::Planar.into(),
            SweepLayoutArg::Clustered => Layout::Clustered.into(),
            SweepLayoutArg::Planned => SweepLayout::Planned,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum KinematicErrorsArg {
    /// The cell files' `[robotN.errors]` as written (zero when absent), the same every trial.
    None,
    /// Per trial, every parameter of `[robotN.tolerance]` drawn from U(±tolerance), both robots,
    /// seeded per trial.
    Tolerance,
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    /// Points and noise only (fast).
    Geometry,
    /// Full sessions: IK, reach limits, encoder quantisation, repeatability.
    Robot,
}

#[derive(clap::Args)]
struct SessionArgs {
    /// Cell TOML (default: the paper's floor-wall cell, built in).
    #[arg(long)]
    cell: Option<PathBuf>,
    /// Number of teach points.
    #[arg(long, default_value_t = 6)]
    n: usize,
    /// Teach-point layout.
    #[arg(long, value_enum, default_value = "tetrahedron")]
    layout: LayoutArg,
    /// Layout size, mm (tetrahedron edge, cube/square side, cluster distance).
    #[arg(long, default_value_t = 1000.0)]
    spread_mm: f64,
    /// Centre of the layout in base 1, mm, as X,Y,Z, e.g. `--centre-mm 475,-50,995` (negative
    /// values allowed; default: the cell's teach centre).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_xyz_mm, value_name = "X,Y,Z")]
    centre_mm: Option<[f64; 3]>,
    /// Override the cell's alignment σ, mm per axis.
    #[arg(long)]
    noise_mm: Option<f64>,
    /// Seed of the session's random generator.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output CSV (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Observation kind of the rows: coincident handclasps (the default, today's files), contacts
    /// at a distance, tracker measurements, plane touches, or all of them in turn (mixed).
    #[arg(long, value_enum, default_value = "coincident")]
    kind: KindArg,
    /// Teach points from a CSV with columns x_mm,y_mm,z_mm (robot 1's tip in base 1, mm, one per
    /// row) instead of --n/--layout/--spread-mm.
    #[arg(long, value_name = "FILE", conflicts_with = "plan")]
    points_csv: Option<PathBuf>,
    /// Teach poses from a plan (a session CSV of this cell, e.g. `handclasp plan --out plan.csv`):
    /// its robot 1 tips are the teach points and its joint angles seed the robots' poses; the
    /// reported joints and tips are regenerated with the cell's errors and noise.
    #[arg(long, value_name = "PLAN.csv")]
    plan: Option<PathBuf>,
    /// Contact kind: true distance between the two tips, mm.
    #[arg(long, default_value_t = 100.0)]
    contact_distance_mm: f64,
    /// Contact kind: σ of the distance, mm.
    #[arg(long, default_value_t = 0.2)]
    contact_sigma_mm: f64,
    /// Contact kind: write the distance into the rows (known) instead of leaving `distance_mm`
    /// empty (fitted per group).
    #[arg(long)]
    contact_known: bool,
    /// Face-contact kind: largest slide of the two faces on each other, mm, per tangent axis
    /// (uniform in ±this; 0 puts the tips on the normal line). The distance, its σ and
    /// --contact-known are the contact kind's.
    #[arg(long, default_value_t = 5.0)]
    face_slide_mm: f64,
    /// Face-contact kind: largest tilt of the touching faces' normal from the approach direction
    /// (robot 1's flange z), degrees (uniform in 0…this, any azimuth; 0: every face normal along
    /// the flange z, which leaves the tool-frame sideways offsets unobserved).
    #[arg(long, default_value_t = 20.0)]
    face_tilt_deg: f64,
    /// Tracker kind: σ per axis of a tracker measurement, mm.
    #[arg(long, default_value_t = 0.05)]
    tracker_sigma_mm: f64,
    /// Tracker kind: the tool the tracker sees (`tip` or a name of the cell's [robotN.tools]).
    #[arg(long, default_value = "tip")]
    tracker_tool: String,
    /// Plane kind: σ of a touch (distance of the tip from the plane), mm.
    #[arg(long, default_value_t = 0.1)]
    plane_sigma_mm: f64,
}

#[derive(Clone, Copy, ValueEnum)]
enum KindArg {
    /// Coincident handclasps (the two tips meet).
    Coincident,
    /// The two tips a distance apart (--contact-distance-mm), fitted or known.
    Contact,
    /// Two flat faces flush: the tips a distance apart along the face normal, the faces slid
    /// (--face-slide-mm); rows of kind `face_contact`.
    #[value(name = "face_contact", alias = "face-contact")]
    FaceContact,
    /// One robot's tool measured by a tracker in an unknown frame (robots alternate).
    Tracker,
    /// One robot's tip touches an unknown plane (robots alternate).
    Plane,
    /// Coincident, contact, tracker (robot 1), plane (robot 1), tracker (robot 2), plane (robot 2), in turn.
    Mixed,
}

#[derive(clap::Args)]
struct SweepArgs {
    /// geometry (points + noise, fast) or robot (full sessions on the paper cells).
    #[arg(long, value_enum, default_value = "geometry")]
    mode: ModeArg,
    /// Mount pairs: floor-floor, floor-wall, floor-ceiling (comma-separated).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "floor-floor,floor-wall,floor-ceiling"
    )]
    mounts: Vec<String>,
    /// Alignment σ per axis, mm (comma-separated grid).
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,3")]
    noise_mm: Vec<f64>,
    /// Layout spreads, mm (comma-separated grid).
    #[arg(long, value_delimiter = ',', default_value = "250,500,1000,1500")]
    spread_mm: Vec<f64>,
    /// Numbers of teach points (comma-separated grid).
    #[arg(long, value_delimiter = ',', default_value = "4,6,8,12")]
    points: Vec<usize>,
    /// Methods (comma-separated): generic, generic-affine, paper, lsq, constrained on every
    /// point; robot mode also: paper-spread4 (the paper's method on the 4 most spread points),
    /// placement (whole-cell placement-only fit), kinematic (whole-cell MAP fit of the placement
    /// and both robots' kinematic parameters).
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "generic,generic-affine,paper,lsq,constrained"
    )]
    methods: Vec<String>,
    /// Teach-point layout (planned: robot mode only).
    #[arg(long, value_enum, default_value = "tetrahedron")]
    layout: SweepLayoutArg,
    /// Robot mode: the robots' true kinematic errors (tolerance: drawn per trial from
    /// [robotN.tolerance]).
    #[arg(long, value_enum, default_value = "none")]
    kinematic_errors: KinematicErrorsArg,
    /// Trials per grid cell (default: 200 in geometry mode, 5 in robot mode).
    #[arg(long)]
    trials: Option<usize>,
    /// Master seed; trial k uses trial_rng(seed, k).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Output directory for trials.csv, summary.csv and the SVG plots.
    #[arg(long, default_value = "out/sweep")]
    out: PathBuf,
    /// Robot mode: simulate on these cell files instead of the built-in paper cells (comma-separated;
    /// their mounts replace --mounts).
    #[arg(long, value_delimiter = ',')]
    cell: Vec<PathBuf>,
}

fn main() -> ExitCode {
    cli_support::exit_quietly_on_broken_pipe();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", cli_support::error_chain_text(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Session(a) => session(a),
        Command::Sweep(a) => sweep_cmd(a),
        Command::Paper(a) => paper_cmd(a),
        Command::Oracle(a) => oracle_cmd(a),
    }
}

fn oracle_cmd(a: OracleArgs) -> Result<()> {
    let o = sim_cell::oracle::OracleOptions {
        seeds: a.seeds,
        seed: a.seed,
        points: a.points,
        noise_mm: a.noise_mm,
        spread_mm: a.spread_mm,
        joint_deg: a.joint_deg,
        origin_mm: a.origin_mm,
        truth_factor: a.truth_factor,
    };
    let cells = if a.cells.is_empty() {
        ["floor-floor", "floor-wall", "floor-ceiling"]
            .iter()
            .map(|n| PathBuf::from(format!("cells/{n}.toml")))
            .collect()
    } else {
        a.cells
    };
    let mut results = Vec::new();
    for path in &cells {
        let cell = Cell::from_toml_file(path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let r = sim_cell::oracle::run_cell(&name, &cell, &o)
            .with_context(|| format!("sim-cell oracle --cell {}", path.display()))?;
        if a.trials {
            for t in &r.trials {
                println!(
                    "{name} trial {}: evidence {:.3} mm, oracle {:.3} mm (ratio {:.3}), held {:.3} mm, placement {:.3} mm; scales {}",
                    t.trial,
                    t.evidence_m * 1e3,
                    t.oracle_m * 1e3,
                    t.evidence_m / t.oracle_m,
                    t.held_m * 1e3,
                    t.placement_m * 1e3,
                    t.scales
                );
            }
        }
        results.push(r);
    }
    print!("{}", sim_cell::oracle::render_table(&results, &o));
    Ok(())
}

fn paper_cmd(a: PaperArgs) -> Result<()> {
    let d = sim_cell::paper::run_paper_diagnosis(&a.study).context("sim-cell paper")?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&d)?);
    } else {
        print!("{}", sim_cell::paper::diagnosis_text(&d));
    }
    Ok(())
}

fn session(a: SessionArgs) -> Result<()> {
    let mut cell = match &a.cell {
        Some(p) => Cell::from_toml_file(p)?,
        None => Cell::default_floor_wall(),
    };
    if let Some(s) = a.noise_mm {
        if !(s.is_finite() && s >= 0.0) {
            bail!("--noise-mm {s} must be a finite σ ≥ 0 in mm");
        }
        cell.noise.alignment_m = nalgebra::Vector3::repeat(s * 1e-3);
    }
    let mut spec = SessionSpec::new(a.n, a.layout.into(), a.spread_mm * 1e-3);
    if let Some(c) = &a.centre_mm {
        spec.centre_b1 = Some(nalgebra::Point3::new(c[0], c[1], c[2]) * 1e-3);
    }
    if let Some(p) = &a.points_csv {
        spec.points_b1 = Some(read_points_b1_csv(p).context("--points-csv")?);
    }
    let plan = match &a.plan {
        Some(p) => {
            let plan = Session::read_csv(p, &cell).context("--plan")?;
            Some(teach_from_plan(&plan).with_context(|| format!("--plan {}", p.display()))?)
        }
        None => None,
    };
    let kinds = KindSpec {
        kind: match a.kind {
            KindArg::Coincident => SimKind::Coincident,
            KindArg::Contact => SimKind::Contact,
            KindArg::FaceContact => SimKind::FaceContact,
            KindArg::Tracker => SimKind::Tracker,
            KindArg::Plane => SimKind::Plane,
            KindArg::Mixed => SimKind::Mixed,
        },
        contact_distance_m: a.contact_distance_mm * 1e-3,
        contact_sigma_m: a.contact_sigma_mm * 1e-3,
        contact_known: a.contact_known,
        face_slide_m: a.face_slide_mm * 1e-3,
        face_tilt_max_rad: a.face_tilt_deg.to_radians(),
        tracker_sigma_m: a.tracker_sigma_mm * 1e-3,
        tracker_tool: a.tracker_tool.clone(),
        plane_sigma_m: a.plane_sigma_mm * 1e-3,
        ..KindSpec::default()
    };
    let (session, truth) = generate_kind_session(
        &cell,
        &spec,
        &kinds,
        plan.as_deref(),
        &mut trial_rng(a.seed, 0),
    )
    .map_err(|e| match e {
        // The library says what to change; the binary names the flags that change it.
        SimError::Unreachable { .. } if spec.points_b1.is_none() && plan.is_none() => {
            anyhow::anyhow!("{e} (the spread is --spread-mm, the centre --centre-mm)")
        }
        other => other.into(),
    })?;
    if !matches!(a.kind, KindArg::Coincident) {
        // Every kind's count; a kind after the first four only when present, so that the message
        // of a session without it is as before that kind.
        let rows: Vec<String> = Kind::ALL
            .iter()
            .zip(session.kind_counts())
            .enumerate()
            .filter(|&(k, (_, n))| k < 4 || n > 0)
            .map(|(_, (kind, n))| format!("{n} {}", kind.name()))
            .collect();
        let t = truth.tracker_from_b1.inverse().translation.vector * 1e3;
        let (n, d) = truth.plane_b1;
        eprintln!(
            "rows: {}; truth: contact distance {:.3} mm, \
             tracker origin in b1 ({:.1}, {:.1}, {:.1}) mm, plane normal (b1) ({:.4}, {:.4}, {:.4}) offset {:.3} mm",
            rows.join(", "),
            truth.contact_distance_m * 1e3,
            t.x,
            t.y,
            t.z,
            n.x,
            n.y,
            n.z,
            d * 1e3
        );
    }
    match &a.out {
        Some(p) => {
            session.write_csv(p, &cell)?;
            eprintln!("wrote {} points to {}", session.len(), p.display());
        }
        None => print!("{}", session.csv_text(&cell)),
    }
    Ok(())
}

/// A library error with a setting's field name replaced by the flag that sets it
/// (`trials must be at least 1` → `--trials must be at least 1`).
fn with_flag_names(e: SimError) -> anyhow::Error {
    match e {
        SimError::InvalidSetting { field, message } => {
            let flag = match field {
                "trials" => "--trials",
                "mounts" => "--mounts",
                "noise_mm" => "--noise-mm",
                "spread_m" => "--spread-mm",
                "n_points" => "--points",
                "methods" => "--methods",
                other => other,
            };
            anyhow::anyhow!("{flag} {message}")
        }
        other => other.into(),
    }
}

fn sweep_cmd(a: SweepArgs) -> Result<()> {
    let mode = match a.mode {
        ModeArg::Geometry => Mode::Geometry,
        ModeArg::Robot => Mode::Robot,
    };
    let mounts = a
        .mounts
        .iter()
        .map(|m| MountPair::parse_paper(m))
        .collect::<Result<Vec<_>, _>>()?;
    let methods = a
        .methods
        .iter()
        .map(|m| {
            SweepMethod::from_name(m).with_context(|| {
                format!("--methods: unknown method `{m}`; use generic, generic-affine, paper, lsq, constrained, or in robot mode paper-spread4, placement, kinematic")
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let config = SweepConfig {
        mode,
        mounts,
        noise_mm: a.noise_mm.clone(),
        spread_m: a.spread_mm.iter().map(|s| s * 1e-3).collect(),
        n_points: a.points.clone(),
        methods,
        layout: a.layout.into(),
        kinematic_errors: match a.kinematic_errors {
            KinematicErrorsArg::None => KinematicErrorDraw::None,
            KinematicErrorsArg::Tolerance => KinematicErrorDraw::Tolerance,
        },
        trials: a.trials.unwrap_or(match mode {
            Mode::Geometry => 200,
            Mode::Robot => 5,
        }),
        seed: a.seed,
    };
    config.validate().map_err(with_flag_names)?;
    let mut config = config;
    let cells: Vec<Cell> = if mode == Mode::Robot {
        if a.cell.is_empty() {
            config
                .mounts
                .iter()
                .map(|m| {
                    Cell::shipped(*m)
                        .context("robot mode without --cell knows the paper's three cells only")
                })
                .collect::<Result<_>>()?
        } else {
            // The cells define the mount axis (their own mounts, in the order given).
            let cells: Vec<Cell> = a
                .cell
                .iter()
                .map(|p| Cell::from_toml_file(p).map_err(anyhow::Error::from))
                .collect::<Result<_>>()?;
            config.mounts = cells.iter().map(Cell::mounts).collect();
            cells
        }
    } else {
        if !a.cell.is_empty() {
            bail!("--cell is for --mode robot (geometry mode uses the paper's placements)");
        }
        vec![]
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .context("cannot start the worker threads")?;
    let total = config.total_trials() as u64;
    let pb = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::stderr());
    if !std::io::stderr().is_terminal() {
        pb.set_draw_target(ProgressDrawTarget::hidden());
    }
    pb.set_style(
        ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} trials ({per_sec}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    eprintln!(
        "sweep: {} mode, {} grid cells × {} trials × {} methods, {} threads, seed {}",
        mode.name(),
        config.grid().len(),
        config.trials,
        config.methods.len(),
        pool.current_num_threads(),
        config.seed
    );
    let t0 = Instant::now();
    let cpu0 = process_cpu_seconds();
    let result = pool
        .install(|| sweep::run_sweep(&config, &cells, &|n| pb.inc(n)))
        .map_err(with_flag_names)?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let cpu = process_cpu_seconds().zip(cpu0).map(|(a, b)| a - b);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    let trials_path = a.out.join("trials.csv");
    let f = std::fs::File::create(&trials_path)
        .with_context(|| format!("cannot write {}", trials_path.display()))?;
    let mut w = BufWriter::new(f);
    sweep::write_trials_csv(&result, &mut w)?;
    w.flush()?;
    let summary_path = a.out.join("summary.csv");
    let mut w = BufWriter::new(
        std::fs::File::create(&summary_path)
            .with_context(|| format!("cannot write {}", summary_path.display()))?,
    );
    sweep::write_summary_csv(&sweep::summarize_cells(&result), &mut w)?;
    w.flush()?;
    let plots = sim_cell::plot::write_sweep_plots(&result, &a.out)?;
    let pooled = sweep::summarize_pooled(&result);
    let per_cpu = cpu
        .filter(|c| *c > 0.0)
        .map(|c| format!(", {:.0} per CPU-second", total as f64 / c))
        .unwrap_or_default();
    // Timed: run_sweep only (draw, fit and metrics of every trial × method, into memory);
    // writing the CSV files and plots below is not.
    println!(
        "{} trials in {:.2} s ({:.0} trials/s{per_cpu}; simulation only, files not timed). Pooled over noise, spread and points; median and p95 with 95 % CI:",
        total,
        secs,
        total as f64 / secs.max(1e-9)
    );
    print!("{}", sweep::render_table(&pooled));
    println!("wrote {}", trials_path.display());
    println!("wrote {} (per grid cell)", summary_path.display());
    for p in plots {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// Parses `X,Y,Z` (mm, any of them negative) for `--centre-mm`; the message says what was given and
/// the expected form.
fn parse_xyz_mm(text: &str) -> Result<[f64; 3], String> {
    let form = "expected three numbers in mm separated by commas, e.g. 475,-50,995";
    let values: Vec<&str> = text.split(',').map(str::trim).collect();
    if values.len() != 3 {
        return Err(format!("`{text}` has {} value(s); {form}", values.len()));
    }
    let mut xyz = [0.0; 3];
    for (v, s) in xyz.iter_mut().zip(&values) {
        *v = s
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("`{s}` is not a finite number; {form}"))?;
    }
    Ok(xyz)
}

/// User + system CPU time of this process, s (Linux `/proc/self/stat`, 100 Hz ticks); None elsewhere.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // After the command: state is field 3, utime 14, stime 15 (1-based over the whole line).
    let utime: f64 = f.get(11)?.parse().ok()?;
    let stime: f64 = f.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

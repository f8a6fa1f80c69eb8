//! `handclasp diagnose`: what the nominal models get wrong in a measured session.
//!
//! Thin glue over the `diagnose` crate: reads the cell and the session, runs the diagnosis,
//! prints text or JSON, optionally exports corrected URDFs and a calibrated cell. A session with
//! contact, tracker or plane rows gets the whole-cell diagnosis
//! (`diagnose::diagnose_cell_session`, exported by `diagnose::export_cell_diagnosis`).

use std::path::PathBuf;

use anyhow::Context;
use cli_support::result_check::ScreenMode;
use diagnose::DiagnoseOptions;
use handclasp_cell::Cell;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use report::{
    diagnosis_work_site, read_work_points, work_site_points, Acceptance, CellDiagnosisWithSite,
};

/// Arguments of `handclasp diagnose`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The cell TOML (robots' URDFs, tip offsets in mm, mounts, b1_from_b2, noise σ in mm).
    #[arg(long)]
    pub cell: PathBuf,
    /// The session CSV (point, r1_q*_deg, r2_q*_deg, r1_x_mm … r2_z_mm).
    #[arg(long)]
    pub session: PathBuf,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Write the corrected model into this folder (created if missing; refused if it is not
    /// empty, unless --overwrite): robot1_corrected.urdf, robot2_corrected.urdf, cell_corrected.toml
    /// (load it with fk/calibrate/diagnose --cell) and effects.json; a session with contact,
    /// tracker or plane rows also gets report.json and report.txt. Session nuisances (tracker
    /// frames, scales, drifts, planes, contact distances) are not cell properties and stay in
    /// the report.
    #[arg(long)]
    pub export: Option<PathBuf>,
    /// With --export: write into a folder that is not empty, overwriting files of the same names
    /// (other files are left as they are). (--force no longer overwrites.)
    #[arg(long, requires = "export")]
    pub overwrite: bool,
    /// Diagnose a session the result check refuses (a likely data mistake explains the
    /// placement fit: rows shifted, joints swapped, radians, another cell…); its findings then
    /// print as `warning: kept by --force: …`. Whole-cell sessions: with --export, also write
    /// the full model, families the do-no-harm rule withholds included. To write --export into
    /// a non-empty folder, use --overwrite.
    #[arg(long)]
    pub force: bool,
    /// Truth of the b1_from_b2 translation (e.g. from a CMM), mm: x,y,z. Needs --truth-zyz-deg.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub truth_xyz_mm: Option<Vec<f64>>,
    /// Truth of the b1_from_b2 rotation, ZYZ degrees (R = Rz·Ry·Rz). Needs --truth-xyz-mm.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub truth_zyz_deg: Option<Vec<f64>>,
    /// Seed of the Monte Carlo simulations.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Monte Carlo trials for the predicted residual distributions (at least 20).
    #[arg(long, default_value_t = 400)]
    pub trials: usize,
    /// Sessions with contact, tracker or plane rows (whole-cell diagnosis): every tolerance of
    /// the cell is multiplied by this to form the prior of the candidate families (the
    /// diagnosis looks for errors beyond the stated tolerances).
    #[arg(long, default_value_t = 10.0)]
    pub prior_widening: f64,
    /// Also list (on stderr) each URDF's joints and links outside the base-to-flange chain,
    /// which are ignored.
    #[arg(long)]
    pub verbose: bool,
    /// Sessions with contact, tracker or plane rows: the most selection steps (families named);
    /// the report says when the selection stopped here while still accepting families.
    #[arg(long, default_value_t = 8)]
    pub max_steps: usize,
    /// Sessions with contact, tracker or plane rows: how the held-out folds are made. groups
    /// (default): the session's own groups (tracker files, planes, contact groups) and blocks of
    /// coincident rows; regions: clusters of the rows' joint vectors (seeded k-means++, at least
    /// 12 rows each), so the choice and the do-no-harm rule measure extrapolation to postures
    /// the fit did not see (a session too small for 3 regions falls back to groups, and the
    /// report says so).
    #[arg(long, value_enum, default_value = "groups")]
    pub cv_folds: CvFoldsArg,
    /// The blunder screen. auto: reject blunders, but keep every row and report a model misfit
    /// when the rejected rows are more than a few percent or cluster in joint space or time;
    /// strict: reject whatever the screen rejects; off: no screen (sessions with contact,
    /// tracker or plane rows; the result check before the diagnosis uses it too).
    #[arg(long, value_enum, default_value = "auto")]
    pub screen: crate::calibrate_cell::ScreenArg,
    /// Write a self-contained HTML page here (sessions with contact, tracker or plane rows:
    /// the verdict at the work site first; the named causes with their gain, before and after,
    /// held out; the rejected families; plots), to open in a browser.
    #[arg(long, value_name = "FILE.html")]
    pub report: Option<PathBuf>,
    /// Sessions with contact, tracker or plane rows: the work site, a CSV of tool positions in
    /// base 1 (header x_mm,y_mm,z_mm) where the robots will work together; the verdict
    /// predicts the accuracy of the model --export writes there (default: the cell's `[teach]`
    /// centre).
    #[arg(long, value_name = "FILE.csv")]
    pub work_points: Option<PathBuf>,
    /// Sessions with contact, tracker or plane rows: the largest cooperative position error the
    /// job accepts at the work site, mm (PASS when the predicted p95's 95 % interval lies below
    /// it), for the model --export writes.
    #[arg(long, value_name = "MM")]
    pub accept_mm: Option<f64>,
    /// Sessions with contact, tracker or plane rows: the largest rotation error of b1_from_b2
    /// the job accepts, degrees (PASS when the predicted p95's 95 % interval lies below it).
    #[arg(long, value_name = "DEG")]
    pub accept_deg: Option<f64>,
}

impl Args {
    /// Whether the verdict at the work site is asked for (`--report`, `--work-points`,
    /// `--accept-mm` or `--accept-deg`).
    fn wants_work_site(&self) -> bool {
        self.report.is_some()
            || self.work_points.is_some()
            || self.accept_mm.is_some()
            || self.accept_deg.is_some()
    }
}

/// The verdict options, read and checked before the diagnosis runs: the acceptance and the
/// work points (m, base 1) of `--work-points`.
struct WorkSiteInputs {
    acceptance: Acceptance,
    points: Option<Vec<nalgebra::Point3<f64>>>,
}

impl WorkSiteInputs {
    fn read(args: &Args) -> anyhow::Result<Self> {
        let acceptance = Acceptance::new(args.accept_mm, args.accept_deg)
            .context("--accept-mm / --accept-deg")?;
        let points = args
            .work_points
            .as_ref()
            .map(|path| read_work_points(path).context("--work-points"))
            .transpose()?;
        Ok(WorkSiteInputs { acceptance, points })
    }
}

/// Sessions of at least this many points print progress on stderr even when it is not a
/// terminal (a 500-point session with errors takes about 20 s on a loaded 2-core machine).
const PROGRESS_MIN_POINTS: usize = 500;

/// Sessions of at least this many rows print progress of the whole-cell diagnosis on stderr
/// even when it is not a terminal (the CTU tracker files take minutes).
const PROGRESS_MIN_ROWS_WHOLE_CELL: usize = 100;

/// The coverage report of `session` (read as handclasp-cell's `Session` for `cell`), its
/// `warning:` lines printed on stderr.
fn coverage(
    cell: &Cell,
    session: &handclasp_cell::Session,
) -> anyhow::Result<calib_core::whole_cell::CoverageReport> {
    let c = cli_support::cell_report::session_coverage_report(cell, session)
        .context("the session's coverage of the robots' joint ranges and reach")?;
    for w in c.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(c)
}

/// The result check of `calibrate --cell --model placement` on the session
/// ([`cli_support::result_check`]), before the diagnosis. A likely data mistake that explains
/// the fit refuses the diagnosis (it would otherwise name effects that the mistake made)
/// unless `args.force`; with `--json` the refusal's object (key `result_check`) is printed on
/// stdout first. A misfit no mistake explains is what the diagnosis is for: its findings are
/// `warning:` lines. A check that cannot run says so and the diagnosis goes on (it reports its
/// own failure).
fn result_precheck(
    args: &Args,
    cell: &Cell,
    session: &handclasp_cell::Session,
) -> anyhow::Result<()> {
    act_on_result_precheck(args, precheck_result(args, cell, session))
}

/// The result check [`result_precheck`] acts on (computed only: nothing is printed).
fn precheck_result(
    args: &Args,
    cell: &Cell,
    session: &handclasp_cell::Session,
) -> Result<
    cli_support::result_check::ResultCheckReport,
    cli_support::cell_report::CellCalibrationError,
> {
    cli_support::cell_report::session_result_check(
        cell,
        session,
        cli_support::cell_report::CellModel::Placement,
        args.screen.mode(),
        None,
    )
}

/// What [`result_precheck`] does with the check [`precheck_result`] computed: refuse, warn, or
/// note that it could not run.
fn act_on_result_precheck(
    args: &Args,
    check: Result<
        cli_support::result_check::ResultCheckReport,
        cli_support::cell_report::CellCalibrationError,
    >,
) -> anyhow::Result<()> {
    match check {
        Ok(r) => {
            let r = &r;
            if r.likely_mistake.is_some() && !args.force {
                let reason = format!(
                    "result check (placement fit): the session contradicts what the cell \
                     states: {}",
                    r.messages.join("; ")
                );
                if args.json {
                    let mut refusal =
                        cli_support::result_check::Refusal::new("diagnose", reason.clone());
                    refusal.result_check = Some(r);
                    crate::json_out::print_pretty(&refusal)?;
                }
                anyhow::bail!("{reason}");
            }
            let kept = if r.likely_mistake.is_some() {
                "kept by --force: "
            } else {
                ""
            };
            for m in &r.messages {
                eprintln!("warning: {kept}result check (placement fit): {m}");
            }
        }
        Err(e) => eprintln!(
            "note: the result check (placement fit) could not run: {}",
            cli_support::error_chain_text(&e)
        ),
    }
    Ok(())
}

/// The whole-cell diagnosis of a session with contact, tracker or plane rows.
fn run_whole_cell(
    args: &Args,
    cell: &Cell,
    session: &handclasp_cell::Session,
    truth: bool,
    site: &WorkSiteInputs,
) -> anyhow::Result<()> {
    if truth {
        anyhow::bail!(
            "{}: --truth-* applies to coincident-only sessions; this session has contact, \
             tracker or plane rows (whole-cell diagnosis): drop --truth-xyz-mm and --truth-zyz-deg",
            args.session.display()
        );
    }
    if args.max_steps == 0 {
        anyhow::bail!("--max-steps 0 selects nothing: give at least 1 (default 8)");
    }
    let screen = args.screen.mode();
    let options = diagnose::CellDiagnoseOptions {
        folds: args.cv_folds.design(),
        prior_widening: args.prior_widening,
        max_steps: args.max_steps,
        screen_blunders: screen != ScreenMode::Off,
        keep_misfit: screen == ScreenMode::Auto,
        ..diagnose::CellDiagnoseOptions::default()
    };
    let show = std::io::IsTerminal::is_terminal(&std::io::stderr())
        || session.len() >= PROGRESS_MIN_ROWS_WHOLE_CELL;
    let start = std::time::Instant::now();
    let mut report = diagnose::diagnose_cell_session(cell, session, &options, &|line| {
        if show {
            eprintln!("[{:6.1} s] {line}", start.elapsed().as_secs_f64());
        }
    })
    .with_context(|| format!("diagnosing {}", args.session.display()))?;
    report.coverage = Some(coverage(cell, session)?);
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    for n in &report.notes {
        eprintln!("note: {n}");
    }
    if let Some(dir) = &args.export {
        let files = crate::export_dir::locked(dir, args.overwrite, "--export", || {
            Ok(diagnose::export_cell_diagnosis_with(
                cell, &report, dir, args.force,
            )?)
        })
        .context("--export")?;
        if report.do_no_harm.withholds() {
            if args.force {
                eprintln!(
                    "warning: kept by --force: {} wrote the full model, families the do-no-harm \
                     rule withholds included",
                    dir.display()
                );
            } else {
                eprintln!(
                    "note: {} holds the placement{} only; withheld: {}",
                    dir.display(),
                    if report.do_no_harm.exported_families.is_empty() {
                        String::new()
                    } else {
                        format!(" and {}", report.do_no_harm.exported_families.join(", "))
                    },
                    report
                        .do_no_harm
                        .withheld
                        .iter()
                        .map(|w| w.family.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
        if !args.json {
            for f in &files {
                println!("wrote {}", f.display());
            }
        }
    }
    let verdict = if args.wants_work_site() {
        let file = args.work_points.as_deref().zip(site.points.as_deref());
        let (points, source) = work_site_points(cell, file);
        let (w, model) = diagnosis_work_site(
            cell,
            &report,
            args.force,
            &points,
            &source,
            site.acceptance,
            cli_support::cell_report::P95_SEED,
        )
        .context("the verdict at the work site")?;
        crate::report_page::warn_unreachable(&w);
        Some((w, model))
    } else {
        None
    };
    let json = serde_json::to_string(&CellDiagnosisWithSite {
        report: &report,
        work_site: verdict.as_ref().map(|v| &v.0),
        work_site_model: verdict.as_ref().map(|v| &v.1),
    })?;
    let mut text = diagnose::render_cell_text(&report);
    if let Some((w, model)) = &verdict {
        text.push_str(&format!(
            "work site: the verdict is for {}\n",
            model.description
        ));
        text.push_str(&report::work_site_text(w));
    }
    print_and_write_page(args, &json, &text, |cell, session, json, invocation| {
        report::cell_diagnosis_page(
            &report,
            verdict.as_ref().map(|(w, m)| (w, m)),
            cell,
            session,
            json,
            invocation,
        )
    })
}

/// Runs `handclasp diagnose`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let truth = match (&args.truth_xyz_mm, &args.truth_zyz_deg) {
        (Some(t), Some(z)) if t.len() == 3 && z.len() == 3 => {
            if !t.iter().chain(z).all(|v| v.is_finite()) {
                anyhow::bail!("--truth-xyz-mm and --truth-zyz-deg must be finite numbers");
            }
            let rot = kinematics::rotation_from_zyz([
                z[0].to_radians(),
                z[1].to_radians(),
                z[2].to_radians(),
            ]);
            Some(Isometry3::from_parts(
                Translation3::from(Vector3::new(t[0], t[1], t[2]) / 1000.0),
                UnitQuaternion::from_rotation_matrix(&rot),
            ))
        }
        (None, None) => None,
        _ => anyhow::bail!(
            "give both --truth-xyz-mm x,y,z (mm) and --truth-zyz-deg a,b,c (degrees), 3 numbers each, or neither"
        ),
    };
    if args.trials < 20 {
        anyhow::bail!(
            "--trials {} is too few for a residual distribution: use at least 20 (default 400)",
            args.trials
        );
    }
    if let Some(dir) = &args.export {
        crate::export_dir::check_export_folder_overwrite(dir, args.overwrite, args.force)?;
    }
    let site = WorkSiteInputs::read(&args)?;
    let cell = Cell::from_toml_file(&args.cell)?;
    if args.verbose {
        crate::fk::print_cell_branches(&cell);
    }
    let cell_session = handclasp_cell::Session::read_csv(&args.session, &cell).ok();
    if let Some(session) = &cell_session {
        if !session.is_handclasp_only() {
            result_precheck(&args, &cell, session)?;
            handclasp_cell::check_session_inputs(session).map_err(|source| {
                handclasp_cell::FormatError::SessionCheck {
                    path: args.session.clone(),
                    source,
                }
            })?;
            // Contact, tracker or plane rows (or other tools): the whole-cell diagnosis.
            return run_whole_cell(&args, &cell, session, truth.is_some(), &site);
        }
    }
    let site_args =
        args.work_points.is_some() || args.accept_mm.is_some() || args.accept_deg.is_some();
    let options = DiagnoseOptions {
        seed: args.seed,
        trials: args.trials,
        truth,
        ..DiagnoseOptions::default()
    };
    let loaded = diagnose::load_session(&args.session, &cell);
    let start = std::time::Instant::now();
    // The result check (a placement fit) and the diagnosis's first phase (the session's check
    // and blunder screen, a kinematic fit) are independent and each mostly serial: they run side
    // by side, and what each finds is acted on in the order they used to run (the check first).
    let (check, screened) = std::thread::scope(|scope| {
        let screen = scope.spawn(|| match &loaded {
            Ok(session) if !site_args => Some(diagnose::screen_session(&cell, session, &options)),
            _ => None,
        });
        let check = cell_session
            .as_ref()
            .map(|s| precheck_result(&args, &cell, s));
        let screened = screen
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (check, screened)
    });
    if let Some(check) = check {
        act_on_result_precheck(&args, check)?;
    }
    if site_args {
        anyhow::bail!(
            "{}: --work-points, --accept-mm and --accept-deg need a session with contact, \
             tracker or plane rows (the whole-cell diagnosis, whose exported model has a \
             posterior to predict from); this session has coincident rows only: drop them, or \
             get the verdict from `handclasp calibrate --cell … --report FILE.html` with them",
            args.session.display()
        );
    }
    let session = loaded.context("--session")?;
    // Progress on stderr when it is a terminal, or when the session is large enough to take
    // more than a few seconds (PROGRESS_MIN_POINTS); small sessions in scripts and captures see
    // the report alone (a size rule, not a clock: the output does not depend on machine load).
    let show = std::io::IsTerminal::is_terminal(&std::io::stderr())
        || session.points.len() >= PROGRESS_MIN_POINTS;
    let mut report = screened
        .unwrap_or_else(|| diagnose::screen_session(&cell, &session, &options))
        .and_then(|screened| {
            diagnose::diagnose_screened_session_with_progress(
                &cell,
                screened,
                &options,
                &mut |line| {
                    if show {
                        eprintln!("[{:6.1} s] {line}", start.elapsed().as_secs_f64());
                    }
                },
            )
        })
        .with_context(|| format!("diagnosing {}", args.session.display()))?;
    // The coverage needs the session in handclasp-cell's form (read above; the diagnosis's own
    // reader also takes sessions that one refuses, which then go without it).
    if let Some(s) = &cell_session {
        report.coverage = Some(coverage(&cell, s)?);
    }
    if let Some(dir) = &args.export {
        let calibrated = report.b1_from_b2.to_isometry();
        let files = crate::export_dir::locked(dir, args.overwrite, "--export", || {
            Ok(diagnose::export_corrected(
                &cell,
                &report,
                &calibrated,
                dir,
            )?)
        })
        .context("--export")?;
        if !args.json {
            for f in &files {
                println!("wrote {}", f.display());
            }
        }
    }
    let json = serde_json::to_string(&report)?;
    print_and_write_page(
        &args,
        &json,
        &diagnose::render_text(&report),
        |cell, session, json, invocation| {
            report::coincident_diagnosis_page(&report, cell, session, json, invocation)
        },
    )
}

/// Writes the page with --report (`page(cell, session, json, invocation)`), then prints the
/// report: `json` with --json, else `text` and the page's path.
fn print_and_write_page(
    args: &Args,
    json: &str,
    text: &str,
    page: impl FnOnce(&str, &str, &str, &report::Invocation) -> String,
) -> anyhow::Result<()> {
    if let Some(path) = &args.report {
        let html = page(
            &args.cell.display().to_string(),
            &args.session.display().to_string(),
            json,
            &crate::report_page::invocation(),
        );
        crate::report_page::write(path, &html)?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{text}");
        if let Some(path) = &args.report {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// `--cv-folds`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CvFoldsArg {
    /// Regions of joint space (k-means++ on the joint vectors).
    Regions,
    /// The session's groups and coincident blocks.
    Groups,
}

impl CvFoldsArg {
    fn design(self) -> diagnose::FoldDesign {
        match self {
            CvFoldsArg::Regions => diagnose::FoldDesign::JointRegions,
            CvFoldsArg::Groups => diagnose::FoldDesign::Groups,
        }
    }
}

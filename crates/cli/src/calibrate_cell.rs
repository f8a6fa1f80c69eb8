//! `handclasp calibrate --cell CELL --session SESSION --model kinematic|placement|kinematic+compliance [--export DIR]
//! [--tolerance-scale X] [--json]`: the whole-cell calibration (`calib_core::whole_cell`) of a measured session.
//!
//! `kinematic` fits `b1_from_b2` jointly with every identifiable kinematic parameter of both
//! robots (joint offsets, joint origin xyz/rpy, tip offsets), a maximum a posteriori fit with the
//! prior from the cell's `[robotN.tolerance]`; what the session cannot separate is dropped or
//! merged and reported. `placement` fits `b1_from_b2` alone (both robots nominal) from the same
//! session. Both screen the rows for blunders and refit without them.
//!
//! Predicted cooperative accuracy: the posterior error of the predicted vector from tip 2 to tip
//! 1 (b1), over **the session's meeting pairs `(q1_i, q2_i)`** of its coincident and contact rows
//! (rejected rows included: their joint vectors are still the session's workspace), rms exact,
//! p95 from a seeded draw (seed [`cli_support::cell_report::P95_SEED`]).
//! The fit and its report are [`cli_support::cell_report`]'s, shared with the Python package.
//!
//! The placement's uncertainty: JSON `b1_from_b2.sigma`, one entry per translation axis (mm) and
//! rotation-vector axis (deg, of the left perturbation `b1_from_b2 ← R(φ)·b1_from_b2`), each with
//! its `sigma` (posterior) and `prior_sigma` (the cell's `[b1_from_b2] sigma_mm`/`sigma_deg`;
//! `null` when that half is fitted freely); the text report prints the same on one line.
//!
//! Output units: mm and degrees (ZYZ, `R = Rz(φ)·Ry(θ)·Rz(ψ)`); parameters in their unit (`deg`,
//! `mm`, `ratio`, `deg/kNm`).

use std::path::PathBuf;

use anyhow::{bail, Context};
use cli_support::cell_report::{
    calibrate_session_with, render_text, tolerance_warnings, CellCalibrationError, CellModel,
    CellReport,
};
use cli_support::result_check::ScreenMode;
use handclasp_cell::{export_calibrated_cell, Cell, Session, CALIBRATE_EXPORT_NAMES};
use report::{
    calibration_page_of_fit, predict_work_site, read_work_points, work_site_points, Acceptance,
    CalibrationPageInputs, CalibrationWithSite, MeetingPairsAccuracy,
};
use serde::Serialize;

use cli_support::cell_report::P95_SEED;

use crate::progress::{shown, Progress};

/// The whole-cell path's own arguments of `handclasp calibrate` (`--json` and `--force` are the
/// command's, [`crate::calibrate::Args`]).
#[derive(clap::Args, Debug)]
pub struct CellArgs {
    /// Whole-cell calibration: the cell TOML (robots, tips, noise, [robotN.tolerance]).
    #[arg(long, requires = "session", conflicts_with_all = ["mounts", "mount1", "mount2", "method", "tilt_sigma_deg"])]
    pub cell: Option<PathBuf>,
    /// With --cell: the session CSV (point, r1_q*_deg, r2_q*_deg, r1_x_mm … r2_z_mm).
    #[arg(long, requires = "cell")]
    pub session: Option<PathBuf>,
    /// With --cell: kinematic (b1_from_b2 and every identifiable kinematic parameter of both
    /// robots, MAP with the cell's tolerances), placement (b1_from_b2 only) or
    /// kinematic+compliance (kinematic plus gravity compliance as lumped coefficients, joint
    /// compliance × mass moment: no URDF masses needed; exported to [robotN.errors]).
    #[arg(long, requires = "cell", value_enum, default_value = "kinematic")]
    pub model: ModelArg,
    /// With --cell: write DIR/cell.toml, DIR/robot1.urdf and DIR/robot2.urdf (the calibrated cell).
    /// DIR must be new or empty, unless --overwrite (files of the same names are overwritten).
    /// The export is re-predicted on the session's rows before it is reported.
    #[arg(long, requires = "cell")]
    pub export: Option<PathBuf>,
    /// With --cell --export: write into a folder that is not empty, overwriting files of the
    /// same names (--force keeps a refused fit; it no longer overwrites).
    #[arg(long, requires = "export")]
    pub overwrite: bool,
    /// With --cell: the blunder screen. auto: reject blunders, but keep every row and report a
    /// model misfit when more than 5 % of the rows (at least 3) would go or the rejected rows
    /// cluster in joint space or time; strict: reject whatever the screen rejects; off: no
    /// screen.
    #[arg(long, requires = "cell", value_enum, default_value = "auto")]
    pub screen: ScreenArg,
    /// With --cell: also list (on stderr) each URDF's joints and links outside the
    /// base-to-flange chain, which are ignored.
    #[arg(long, requires = "cell", display_order = 103)]
    pub verbose: bool,
    /// With --cell: write a self-contained HTML page here (the verdict at the work site first,
    /// then the placement, the parameters and the plots), to open in a browser.
    #[arg(long, requires = "cell", value_name = "FILE.html")]
    pub report: Option<PathBuf>,
    /// With --cell: the work site, a CSV of tool positions in base 1 (header x_mm,y_mm,z_mm)
    /// where the robots will work together; the verdict predicts the accuracy there
    /// (default: the cell's `[teach]` centre).
    #[arg(long, requires = "cell", value_name = "FILE.csv")]
    pub work_points: Option<PathBuf>,
    /// With --cell: the largest cooperative position error the job accepts at the work site, mm
    /// (PASS when the predicted p95's 95 % interval lies below it).
    #[arg(long, requires = "cell", value_name = "MM")]
    pub accept_mm: Option<f64>,
    /// With --cell: the largest rotation error of b1_from_b2 the job accepts, degrees (PASS
    /// when the predicted p95's 95 % interval lies below it).
    #[arg(long, requires = "cell", value_name = "DEG")]
    pub accept_deg: Option<f64>,
    /// With --cell: fix the prior scale instead of letting the session's evidence choose it:
    /// every [robotN.tolerance] × X (0.001 = the placement-only limit … 100). Default: the
    /// evidence chooses (one scale, or one per family of parameters) from 0.001 to 100.
    #[arg(long, requires = "cell", value_name = "X")]
    pub tolerance_scale: Option<f64>,
}

/// `--model`; the report names it as [`CellModel::name`] does.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelArg {
    /// b1_from_b2 and every identifiable kinematic parameter of both robots (MAP).
    Kinematic,
    /// b1_from_b2 only, both robots nominal.
    Placement,
    /// kinematic, plus each robot's gravity compliance as lumped coefficients (joint
    /// compliance × mass moment: no URDF masses needed), each within ±0.5°.
    #[value(name = "kinematic+compliance")]
    #[serde(rename = "kinematic+compliance")]
    KinematicCompliance,
}

/// `--screen`; the report names it as [`ScreenMode::name`] does.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScreenArg {
    /// Reject blunders unless the rejections are a model misfit (then keep the rows, warn).
    Auto,
    /// No screen: every row is fitted.
    Off,
    /// Reject every row the screen rejects (misfit or not).
    Strict,
}

impl ScreenArg {
    /// The mode.
    pub fn mode(self) -> ScreenMode {
        match self {
            ScreenArg::Auto => ScreenMode::Auto,
            ScreenArg::Off => ScreenMode::Off,
            ScreenArg::Strict => ScreenMode::Strict,
        }
    }
}

impl ModelArg {
    fn cell_model(self) -> CellModel {
        match self {
            ModelArg::Kinematic => CellModel::Kinematic,
            ModelArg::Placement => CellModel::Placement,
            ModelArg::KinematicCompliance => CellModel::KinematicCompliance,
        }
    }
}

/// The kinds of the non-zero `[robotN.errors]` terms of each robot of `cell` (catalogue order,
/// e.g. `["joint_offset", "compliance"]`), for robots that have any: the whole-cell fit starts
/// from the URDFs and tips and does not use them.
fn unused_error_terms(cell: &Cell) -> Vec<(calib_core::Robot, Vec<&'static str>)> {
    [calib_core::Robot::One, calib_core::Robot::Two]
        .into_iter()
        .filter_map(|robot| {
            let errors = &cell.robot(robot).errors;
            let mut kinds: Vec<&'static str> = Vec::new();
            for p in kinematics::all_params(errors.dof()) {
                if errors.get(p) != 0.0 && !kinds.contains(&p.kind_name()) {
                    kinds.push(p.kind_name());
                }
            }
            if errors
                .lumped_compliance
                .iter()
                .flatten()
                .any(|c| c.norm() > 0.0)
            {
                kinds.push("lumped_compliance");
            }
            (!kinds.is_empty()).then_some((robot, kinds))
        })
        .collect()
}

/// Runs the whole-cell calibration (`args.cell` is `Some`); `json` and `force` are the command's
/// `--json` and `--force`.
pub fn run(args: CellArgs, json: bool, force: bool) -> anyhow::Result<()> {
    let (Some(cell_path), Some(session_path)) = (&args.cell, &args.session) else {
        bail!("--cell CELL needs --session SESSION (the session CSV of that cell)");
    };
    if let Some(dir) = &args.export {
        crate::export_dir::check_export_folder_overwrite(dir, args.overwrite, force)?;
    }
    let acceptance =
        Acceptance::new(args.accept_mm, args.accept_deg).context("--accept-mm / --accept-deg")?;
    let work_points = args
        .work_points
        .as_ref()
        .map(|path| read_work_points(path).context("--work-points"))
        .transpose()?;
    let cell = Cell::from_toml_file(cell_path)?;
    if cell.one_robot && args.accept_deg.is_some() {
        bail!(
            "--accept-deg: {} is a one-robot cell, which has no placement between two robots, so \
             no placement rotation is fitted or predicted for --accept-deg to judge; drop the \
             flag and judge the robot's absolute accuracy with --accept-mm (with --work-points \
             for the sites that matter)",
            cell_path.display()
        );
    }
    if args.verbose {
        crate::fk::print_cell_branches(&cell);
    }
    for (robot, kinds) in unused_error_terms(&cell) {
        eprintln!(
            "note: {}: [robot{}.errors] holds {} terms, which calibrate --cell does not use: it \
             fits from the URDFs and tips, within [robot{}.tolerance] (a simulated cell's errors \
             are its hidden truth; an exported cell's are an earlier calibration's, which fk --cell \
             applies). --export writes this fit's terms in their place.",
            cell_path.display(),
            robot.number(),
            kinds.join(", "),
            robot.number(),
        );
    }
    let progress = Progress::new(shown(json), "reading the session");
    let session = Session::read_csv(session_path, &cell)?;
    progress.phase(format!(
        "calibrating on {} rows (start, reduction, blunder screen, prior scale, prediction)",
        session.len()
    ));
    let calibrated = calibrate_session_with(
        &cell,
        &session,
        args.model.cell_model(),
        args.screen.mode(),
        args.tolerance_scale,
    )
    .map_err(|e| {
        let context = match &e {
            CellCalibrationError::Prediction(_) => String::new(),
            _ => format!(
                "calibrating {} with cell {}",
                session_path.display(),
                cell_path.display()
            ),
        };
        let e = anyhow::Error::from(e);
        if context.is_empty() {
            e
        } else {
            e.context(context)
        }
    })?;
    let do_no_harm = match &args.export {
        Some(_) => {
            progress.phase("do no harm: the model against nominal, region by region held out");
            cli_support::do_no_harm::check(
                &cell,
                &session,
                &calibrated,
                args.model.cell_model(),
                args.screen.mode(),
                args.tolerance_scale,
                force,
            )
            .context("the do-no-harm check before --export")?
        }
        None => None,
    };
    progress.finish();
    let (do_no_harm, safe) = match do_no_harm {
        Some((r, safe)) => (Some(r), safe),
        None => (None, None),
    };
    if let Some(r) = &do_no_harm {
        for line in cli_support::do_no_harm::messages(r, args.model.cell_model(), "--force") {
            eprintln!("{line}");
        }
    }
    let report = calibrated.report;
    for w in report.coverage.warnings() {
        eprintln!("warning: {w}");
    }
    if let Some(check) = &report.result_check {
        crate::result_check::refuse_or_warn(check, force, json, "calibrate --cell")?;
    }
    for line in tolerance_warnings(&report) {
        eprintln!("{line}");
    }
    let cal = calibrated.calibration;
    let problem = calibrated.problem;
    let wants_work_site = args.report.is_some()
        || work_points.is_some()
        || args.accept_mm.is_some()
        || args.accept_deg.is_some();
    let mut report: CellReportWithSite = CalibrationWithSite {
        report,
        work_site: None,
        do_no_harm,
    };
    // The verdict and the page describe the model the export writes: the do-no-harm rule's
    // refit without the withheld families (placement only when all are), not the full fit.
    let safe_model = report
        .do_no_harm
        .as_ref()
        .filter(|r| r.withholds())
        .map(|r| exported_model_name(r, args.model.cell_model()));
    let exported = match (&safe, &safe_model) {
        (Some(s), Some(name)) => Exported {
            problem: &s.problem,
            cal: &s.calibration,
            report: &s.report,
            model: name.clone(),
        },
        _ => Exported {
            problem: &problem,
            cal: &cal,
            report: &report.report,
            model: args.model.cell_model().name().to_string(),
        },
    };
    if safe.is_some() && wants_work_site {
        eprintln!(
            "note: do no harm: the verdict at the work site{} is for the exported model ({}), \
             not for the full {} fit",
            if args.report.is_some() {
                " and the --report page"
            } else {
                ""
            },
            exported.model,
            args.model.cell_model().name()
        );
    }
    if wants_work_site {
        let file = args.work_points.as_deref().zip(work_points.as_deref());
        let (points, source) = work_site_points(&cell, file);
        let w = predict_work_site(
            &cell,
            exported.problem,
            exported.cal,
            &points,
            &source,
            acceptance,
            P95_SEED,
        )
        .context("the verdict at the work site")?;
        crate::report_page::warn_unreachable(&w);
        report.work_site = Some(w);
    }
    if let Some(path) = &args.report {
        write_report_page(path, &args, &cell, &exported, &report)?;
    }
    let written = match &args.export {
        Some(dir) => crate::export_dir::locked(dir, args.overwrite, "--export", || {
            // The safe model when the do-no-harm rule withholds the kinematics.
            let (problem, cal) = match &safe {
                Some(s) => (&s.problem, &s.calibration),
                None => (&problem, &cal),
            };
            if let Some((_, note)) =
                handclasp_cell::cell::refitted_robot2_mount(&cell, &cal.fit.estimate.b1_from_b2)
            {
                eprintln!("warning: {note}");
            }
            let written =
                export_calibrated_cell(&cell, &cal.fit.estimate, dir, &CALIBRATE_EXPORT_NAMES)?;
            crate::result_check::check_export(dir, &session, problem, cal, force, json)?;
            Ok(written)
        })
        .with_context(|| format!("--export {}", dir.display()))?,
        None => Vec::new(),
    };
    if json {
        crate::json_out::print_pretty(&report)?;
    } else {
        print!("{}", text(&report));
        for f in &written {
            println!("wrote {}", f.display());
        }
        if let Some(path) = &args.report {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Writes the HTML page of `calibrate --cell … --report FILE` ([`calibration_page_of_fit`], the
/// function Python's `CellResult.report` calls): the same `report` as `--json` (embedded as
/// JSON) and the page of the exported model's fit.
fn write_report_page(
    path: &std::path::Path,
    args: &CellArgs,
    cell: &Cell,
    exported: &Exported<'_>,
    report: &CellReportWithSite,
) -> anyhow::Result<()> {
    let Some(work_site) = &report.work_site else {
        bail!("internal: the report page needs the work-site verdict");
    };
    let json = serde_json::to_string_pretty(report)?;
    let display = |p: &Option<PathBuf>| {
        p.as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_default()
    };
    let invocation = crate::report_page::invocation();
    let html = calibration_page_of_fit(
        cell,
        exported.problem,
        exported.cal,
        &CalibrationPageInputs {
            cell: &display(&args.cell),
            session: &display(&args.session),
            model: &exported.model,
            rows: exported.report.rows,
            meeting_pairs: exported.report.cooperative_accuracy_mm.as_ref().map(|c| {
                MeetingPairsAccuracy {
                    pairs: c.pairs,
                    rms_mm: c.predicted_rms,
                    p95_mm: c.predicted_p95,
                }
            }),
            work_site,
            json: &json,
            invocation: &invocation,
        },
        P95_SEED,
    )
    .context("--report: the rows' residuals")?;
    crate::report_page::write(path, &html)
}

/// The calibration `--export` writes (the fit, or the do-no-harm rule's safe model), which the
/// verdict at the work site and the `--report` page describe.
struct Exported<'a> {
    problem: &'a calib_core::whole_cell::CellProblem,
    cal: &'a calib_core::whole_cell::CellCalibration,
    /// Its report (rows, the prediction over the meeting pairs).
    report: &'a CellReport,
    /// Its model's name (`kinematic`, `kinematic+compliance`, `placement`, or the model less
    /// the families the do-no-harm rule withholds: [`exported_model_name`]).
    model: String,
}

/// The name of the model the do-no-harm rule exports: `placement` when it withholds every
/// family, else `kinematic without robot 1 joint offsets, …`.
fn exported_model_name(r: &cli_support::do_no_harm::DoNoHarmReport, model: CellModel) -> String {
    if r.kept.is_empty() {
        return CellModel::Placement.name().to_string();
    }
    let withheld: Vec<&str> = r.withheld.iter().map(|w| w.family.as_str()).collect();
    format!("{} without {}", model.name(), withheld.join(", "))
}

/// `calibrate --cell`'s report ([`CellReport`]) with the verdict at the work site when
/// `--report`, `--work-points`, `--accept-mm` or `--accept-deg` asks for it, and the
/// do-no-harm rule's verdict with `--export` ([`CalibrationWithSite`], shared with Python).
type CellReportWithSite = CalibrationWithSite<CellReport, cli_support::do_no_harm::DoNoHarmReport>;

/// The text report of `r`: [`render_text`] and, when asked for, the verdict at the work site and
/// the do-no-harm rule's verdict.
fn text(r: &CellReportWithSite) -> String {
    let mut s = render_text(&r.report);
    if let Some(w) = &r.work_site {
        s.push_str(&report::work_site_text(w));
    }
    if let Some(d) = &r.do_no_harm {
        s.push_str(&cli_support::do_no_harm::text(d));
    }
    s
}

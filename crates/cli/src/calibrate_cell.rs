//! `handclasp calibrate --cell CELL --session SESSION --model kinematic|placement [--export DIR]
//! [--json]`: the whole-cell calibration (`calib_core::whole_cell`) of a measured session.
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
use cli_support::cell_report::{calibrate_session, render_text, CellCalibrationError, CellModel};
use handclasp_cell::{export_calibrated_cell, Cell, Session, CALIBRATE_EXPORT_NAMES};
use serde::Serialize;

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
    /// robots, MAP with the cell's tolerances) or placement (b1_from_b2 only).
    #[arg(long, requires = "cell", value_enum, default_value = "kinematic")]
    pub model: ModelArg,
    /// With --cell: write DIR/cell.toml, DIR/robot1.urdf and DIR/robot2.urdf (the calibrated cell).
    /// DIR must be new or empty, unless --force (files of the same names are overwritten).
    #[arg(long, requires = "cell")]
    pub export: Option<PathBuf>,
    /// With --cell: also list (on stderr) each URDF's joints and links outside the
    /// base-to-flange chain, which are ignored.
    #[arg(long, requires = "cell", display_order = 103)]
    pub verbose: bool,
}

/// `--model`; the report names it as [`CellModel::name`] does.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelArg {
    /// b1_from_b2 and every identifiable kinematic parameter of both robots (MAP).
    Kinematic,
    /// b1_from_b2 only, both robots nominal.
    Placement,
}

impl ModelArg {
    fn cell_model(self) -> CellModel {
        match self {
            ModelArg::Kinematic => CellModel::Kinematic,
            ModelArg::Placement => CellModel::Placement,
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
        crate::export_dir::check_export_folder(dir, force)?;
    }
    let cell = Cell::from_toml_file(cell_path)?;
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
    let session = Session::read_csv(session_path, &cell)?;
    let calibrated = calibrate_session(&cell, &session, args.model.cell_model()).map_err(|e| {
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
    let report = calibrated.report;
    for w in report.coverage.warnings() {
        eprintln!("warning: {w}");
    }
    let cal = calibrated.calibration;
    let written = match &args.export {
        Some(dir) => export_calibrated_cell(&cell, &cal.fit.estimate, dir, &CALIBRATE_EXPORT_NAMES)
            .with_context(|| format!("--export {}", dir.display()))?,
        None => Vec::new(),
    };
    if json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
        for f in &written {
            println!("wrote {}", f.display());
        }
    }
    Ok(())
}

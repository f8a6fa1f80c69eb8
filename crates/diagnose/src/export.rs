//! Export of the extended model: corrected URDFs (joint origins and offsets patched into the
//! URDF text by [`kinematics::patch_urdf_text`], everything else kept byte for byte), a cell TOML
//! with the calibrated `b1_from_b2`, and the effects as JSON. Every file is written to a
//! temporary file in the target folder, read back and checked (a URDF's FK against the corrected
//! model, the cell and the JSON by loading them), and only then renamed into place.
//!
//! Two diagnoses export: the coincident one ([`export_corrected`]) and the whole-cell one
//! ([`export_cell_diagnosis`]), with the same file names (`robot1_corrected.urdf`,
//! `robot2_corrected.urdf`, `cell_corrected.toml`, `effects.json`; the whole-cell export adds
//! the report as `report.json` and `report.txt`).

use std::path::{Path, PathBuf};

use calib_core::Robot;
use handclasp_cell::{export_calibrated_cell, ExportNames};
use handclasp_cell::{Cell, CellRobot};
use kinematics::{KinematicErrors, RobotModel};
use nalgebra::Isometry3;

use crate::catalogue::effects_to_errors;
use crate::cell_report::{render_cell_text, CellDiagnoseReport};
use crate::report::DiagnoseReport;
use crate::DiagnoseError;

/// The files of the whole-cell export ([`export_cell_diagnosis`]): the coincident export's
/// names, and the header of the cell file.
pub const CELL_DIAGNOSIS_EXPORT_NAMES: ExportNames<'static> = ExportNames {
    cell: "cell_corrected.toml",
    robot1_urdf: "robot1_corrected.urdf",
    robot2_urdf: "robot2_corrected.urdf",
    header: "# Written by `handclasp diagnose --export` (whole-cell diagnosis): the named families' fitted\n\
             # values. robot1_corrected.urdf / robot2_corrected.urdf: joint offsets, origin positions and\n\
             # angles; tip_mm and [robotN.tools]: fitted tool tips; [robotN.errors]: compliance and\n\
             # joint-periodic terms, which a URDF cannot hold; [b1_from_b2]: fitted when the session\n\
             # determines it, else the input cell's. Tracker frames, scales and drifts, planes and contact\n\
             # distances are properties of the session, not of the cell: they are in report.json only.\n",
};

/// Writes the whole-cell diagnosis `report` of a session on `cell` to `dir` (created if
/// missing; files of the same names are overwritten):
/// - `robot1_corrected.urdf`, `robot2_corrected.urdf` and `cell_corrected.toml`: the cell with
///   the named families' fitted values ([`handclasp_cell::export_calibrated_cell`]: joint offsets and
///   origin errors patched into the URDFs and verified; the fitted tip of tool 0 as `tip_mm`
///   and of every other tool in `[robotN.tools]`; compliance and joint-periodic terms as
///   `[robotN.errors]`); `b1_from_b2` is the fitted placement when the session determines it
///   ([`CellDiagnoseReport::placement_fitted`]), else `cell`'s; the cell's placement σ, noise,
///   tolerances and mounts are kept. The unnamed families are zero, so the file is loaded by
///   `handclasp fk --cell`, `calibrate --cell` and `diagnose` like any cell;
/// - `effects.json` (the named effects), `report.json` (the whole report) and `report.txt`
///   ([`render_cell_text`]).
///
/// The session's nuisances (tracker frames, scales and drifts, planes, contact distances) are
/// not written into the cell: they belong to the recording, not to the robots. The input cell's
/// `[robotN.errors]` are not carried over either: the diagnosis fits from the URDFs and tips and
/// ignores them (as `calibrate --cell` does), so the written `[robotN.errors]` hold the named
/// compliance and joint-periodic terms only.
///
/// Returns the files written, in that order. Errors: an estimate of the wrong shape for `cell`
/// (a report of another cell), a URDF that cannot be read or corrected, a file that cannot be
/// written or does not read back.
pub fn export_cell_diagnosis(
    cell: &Cell,
    report: &CellDiagnoseReport,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::ExportFolder {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut estimate = report.final_estimate.clone();
    if !report.placement_fitted {
        estimate.b1_from_b2 = cell.b1_from_b2;
    }
    // Tools after tool 0 (`[robotN.tools]`): their fitted tips go into the cell's tool table;
    // `export_calibrated_cell` writes tool 0's as `tip_mm`.
    let mut with_tools = cell.clone();
    for (setup, correction) in [
        (&mut with_tools.robot1, &estimate.robot1),
        (&mut with_tools.robot2, &estimate.robot2),
    ] {
        if correction.tool_tip_m.len() != setup.tools.len() + 1 {
            return Err(DiagnoseError::Export {
                path: setup.urdf_path.clone(),
                message: format!(
                    "the diagnosis has {} tools for this robot, the cell {} (tip_mm and [robotN.tools]): export with the cell that was diagnosed",
                    correction.tool_tip_m.len(),
                    setup.tools.len() + 1
                ),
            });
        }
        for (tool, tip_error) in setup.tools.iter_mut().zip(&correction.tool_tip_m[1..]) {
            tool.flange_from_tip += tip_error;
        }
    }
    let mut written =
        export_calibrated_cell(&with_tools, &estimate, dir, &CELL_DIAGNOSIS_EXPORT_NAMES)?;
    let effects_path = dir.join("effects.json");
    write_json_checked(&effects_path, &report.effects)?;
    written.push(effects_path);
    let report_path = dir.join("report.json");
    write_json_checked(&report_path, report)?;
    written.push(report_path);
    let text_path = dir.join("report.txt");
    let text = render_cell_text(report);
    write_checked(&text_path, &text, |back, tmp| {
        if back == text {
            Ok(())
        } else {
            Err(DiagnoseError::Export {
                path: tmp.to_path_buf(),
                message: "the written report reads back different".into(),
            })
        }
    })?;
    written.push(text_path);
    Ok(written)
}

/// Writes `text` to a temporary file beside `path` (in the same folder, so that the rename is
/// atomic), reads it back, runs `check` on what was read, and only if that passes renames it to
/// `path`: nothing unchecked is ever written under the final name. On a failed check the
/// temporary file is removed and the check's error returned.
/// Writes `value` as pretty JSON to `path` through [`write_checked`], which reads it back as JSON.
fn write_json_checked<T: serde::Serialize + ?Sized>(
    path: &Path,
    value: &T,
) -> Result<(), DiagnoseError> {
    let text = serde_json::to_string_pretty(value).map_err(|source| DiagnoseError::Json {
        path: path.to_path_buf(),
        source,
    })?;
    write_checked(path, &text, |back, tmp| {
        serde_json::from_str::<serde_json::Value>(back)
            .map(|_| ())
            .map_err(|source| DiagnoseError::Json {
                path: tmp.to_path_buf(),
                source,
            })
    })
}

fn write_checked<T>(
    path: &Path,
    text: &str,
    check: impl FnOnce(&str, &Path) -> Result<T, DiagnoseError>,
) -> Result<T, DiagnoseError> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.partial"));
    std::fs::write(&tmp, text).map_err(|e| DiagnoseError::io(&tmp, e))?;
    let checked = std::fs::read_to_string(&tmp)
        .map_err(|e| DiagnoseError::io(&tmp, e))
        .and_then(|back| check(&back, &tmp));
    match checked {
        Ok(value) => {
            std::fs::rename(&tmp, path).map_err(|e| DiagnoseError::io(path, e))?;
            Ok(value)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Writes `setup`'s URDF corrected by the URDF-expressible part of `errors` (joint origin xyz and
/// rpy errors, joint offsets: [`kinematics::split_for_urdf`]; SI units) to `path`, patched into
/// the source text by [`kinematics::patch_urdf_text`] (everything else kept byte for byte). The
/// file is read back from a temporary file and verified ([`kinematics::verify_patched_urdf`]: its
/// FK equals the nominal model with those errors) before it is renamed to `path`. Returns the
/// corrected model, loaded from the written text.
///
/// Errors: the source URDF cannot be read or patched, the written file cannot be read back or
/// fails the verification, or the file system refuses the write or the rename.
pub fn write_corrected_urdf(
    setup: &CellRobot,
    errors: &KinematicErrors,
    path: &Path,
) -> Result<RobotModel, DiagnoseError> {
    let xml = std::fs::read_to_string(&setup.urdf_path)
        .map_err(|e| DiagnoseError::io(&setup.urdf_path, e))?;
    let (urdf_errors, _) = kinematics::split_for_urdf(errors);
    let corrected =
        kinematics::patch_urdf_text(&xml, &setup.model, &urdf_errors).map_err(|source| {
            DiagnoseError::UrdfPatch {
                path: setup.urdf_path.clone(),
                source,
            }
        })?;
    write_checked(path, &corrected, |back, tmp| {
        let patch_error = |source| DiagnoseError::UrdfPatch {
            path: tmp.to_path_buf(),
            source,
        };
        kinematics::verify_patched_urdf(back, &setup.model, &urdf_errors).map_err(patch_error)?;
        RobotModel::from_urdf_str(back, &setup.tool_link)
            .map_err(|e| patch_error(kinematics::UrdfPatchError::Reload(Box::new(e))))
    })
}

/// Writes the extended model to `dir`: `robot1_corrected.urdf`, `robot2_corrected.urdf` (joint
/// origins and offsets, see [`write_corrected_urdf`]), `cell_corrected.toml` (the calibrated
/// `b1_from_b2`, corrected tip offsets, URDF paths to the corrected files, and the joint-scale and
/// compliance errors, which URDF cannot express, as `[robotN.errors]`) and `effects.json`.
/// Returns the files written.
pub fn export_corrected(
    cell: &Cell,
    report: &DiagnoseReport,
    b1_from_b2: &Isometry3<f64>,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir).map_err(|source| DiagnoseError::ExportFolder {
        path: dir.to_path_buf(),
        source,
    })?;
    let (e1, e2) = effects_to_errors(cell, &report.effects);
    let mut written = Vec::new();
    let mut out = cell.clone();
    out.base_dir = dir.to_path_buf();
    out.b1_from_b2 = *b1_from_b2;
    for (robot, errors) in [(Robot::One, &e1), (Robot::Two, &e2)] {
        let setup = cell.robot(robot);
        let file = format!("robot{}_corrected.urdf", robot.number());
        let path = dir.join(&file);
        let model = write_corrected_urdf(setup, errors, &path)?;
        written.push(path.clone());
        let r = match robot {
            Robot::One => &mut out.robot1,
            Robot::Two => &mut out.robot2,
        };
        r.model = model;
        r.urdf = file;
        r.urdf_path = path;
        r.flange_from_tip = setup.flange_from_tip + errors.tip;
        let mut rest = KinematicErrors::zero(setup.model.dof());
        rest.joint_scale = errors.joint_scale.clone();
        rest.compliance = errors.compliance.clone();
        r.errors = rest;
    }
    // Robot 2's gravity follows the calibrated placement.
    out.robot2.g_base = out.b1_from_b2.rotation.inverse() * out.robot1.g_base;
    let cell_path = dir.join("cell_corrected.toml");
    let text = format!(
        "# Written by `handclasp diagnose --export`: the extended model (corrected URDFs, tip offsets,\n# calibrated b1_from_b2; joint scale and compliance as [robotN.errors]).\n{}",
        out.to_toml_string()
    );
    write_checked(&cell_path, &text, |back, tmp| {
        let reloaded = Cell::from_toml_str(back, dir).map_err(|e| DiagnoseError::Export {
            path: tmp.to_path_buf(),
            message: format!("the written cell does not load: {e}"),
        })?;
        // The TOML keeps 10 decimals of mm and degrees: the placement reloads to 1e-9 (m, rad).
        let moved = (reloaded.b1_from_b2.translation.vector - out.b1_from_b2.translation.vector)
            .amax()
            .max(
                reloaded
                    .b1_from_b2
                    .rotation
                    .angle_to(&out.b1_from_b2.rotation),
            );
        if moved > 1e-9 {
            return Err(DiagnoseError::Export {
                path: tmp.to_path_buf(),
                message: format!("the written cell's b1_from_b2 reloads {moved:e} (m or rad) off"),
            });
        }
        Ok(())
    })?;
    written.push(cell_path);
    let eff_path = dir.join("effects.json");
    write_json_checked(&eff_path, &report.effects)?;
    written.push(eff_path);
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;
    use kinematics::{Axis, ErrorParam};
    use nalgebra::Vector3;
    use rand::Rng;

    /// The patched text carries 9 decimals (1 nm, 1 nrad): FK agreement to 1e-8 m.
    const URDF_DIGITS_TOL_M: f64 = 1e-8;

    /// The FK of `corrected` equals the nominal model with `e` at 20 random postures.
    fn assert_matches_error_model(robot: &CellRobot, e: &KinematicErrors, corrected: &RobotModel) {
        let mut rng = calib_core::stats::trial_rng(3, 0);
        for _ in 0..20 {
            let q: Vec<f64> = robot
                .model
                .joints()
                .iter()
                .map(|j| rng.random_range(j.lower.max(-2.0)..j.upper.min(2.0)))
                .collect();
            let want = kinematics::true_base_from_tip(
                &robot.model,
                e,
                &q,
                &robot.flange_from_tip,
                &robot.g_base,
            )
            .expect("fk");
            let got = kinematics::base_from_tip(corrected, &q, &robot.flange_from_tip).expect("fk");
            let d = (want.translation.vector - got.translation.vector).norm();
            assert!(d < URDF_DIGITS_TOL_M, "{}: {d} m", robot.model.name());
        }
    }

    /// The corrected URDF (offsets folded into origin rpy, lengths added to origin xyz), as
    /// written and re-loaded, gives the same tips as the nominal URDF with the error model, at
    /// random postures; no temporary file is left behind.
    #[test]
    fn corrected_urdf_matches_the_error_model() {
        let cell = Cell::default_floor_floor();
        let dir = tempfile::tempdir().expect("tempdir");
        for (k_robot, robot) in [&cell.robot1, &cell.robot2].into_iter().enumerate() {
            let dof = robot.model.dof();
            let mut e = KinematicErrors::zero(dof);
            for k in 0..dof {
                e.set(
                    ErrorParam::JointOffset { joint: k },
                    1e-3 * (k as f64 + 1.0),
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::X,
                    },
                    -2e-4 * k as f64,
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::Z,
                    },
                    3e-4,
                );
            }
            let path = dir.path().join(format!("robot{}.urdf", k_robot + 1));
            let corrected = write_corrected_urdf(robot, &e, &path).expect("corrected");
            let text = std::fs::read_to_string(&path).expect("written");
            assert!(text.contains("<calibration rising="));
            let reloaded = RobotModel::from_urdf_str(&text, &robot.tool_link).expect("loads");
            assert_matches_error_model(robot, &e, &corrected);
            assert_matches_error_model(robot, &e, &reloaded);
        }
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .expect("dir")
            .map(|f| f.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        assert_eq!(names, ["robot1.urdf", "robot2.urdf"]);
    }

    /// Regression: the old text patcher corrected the first `<joint name=…>` it found, which in
    /// kinematics' fixture transmission_first.urdf is the `<joint>` inside a `<transmission>`
    /// before the real joint, and left the real joint wrong. The export corrects the chain's
    /// joint and keeps the transmission byte for byte.
    #[test]
    fn export_from_a_urdf_with_a_transmission_first_corrects_the_chain_joint() {
        let fixture = std::path::PathBuf::from(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../kinematics/tests/fixtures/transmission_first.urdf"
        ));
        let xml = std::fs::read_to_string(&fixture).expect("fixture");
        let cell = Cell::default_floor_wall();
        let mut robot = cell.robot2.clone();
        robot.model = RobotModel::from_urdf_str(&xml, &robot.tool_link).expect("fixture loads");
        robot.urdf_path = fixture;
        let mut e = KinematicErrors::zero(robot.model.dof());
        e.origin_xyz[0] = Vector3::new(0.0, 0.0, 0.0115);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("robot2_corrected.urdf");
        let corrected = write_corrected_urdf(&robot, &e, &path).expect("exported");
        let text = std::fs::read_to_string(&path).expect("written");
        let transmission = |t: &str| {
            let a = t.find("<transmission").expect("transmission");
            let b = t.find("</transmission>").expect("end");
            t[a..b].to_string()
        };
        assert_eq!(transmission(&text), transmission(&xml));
        let changed: Vec<&str> = xml
            .lines()
            .zip(text.lines())
            .filter(|(a, b)| a != b)
            .map(|(_, b)| b)
            .collect();
        assert_eq!(
            changed,
            [r#"    <origin xyz="0.000000000 0.000000000 0.516500000" rpy="0 0 0"/>"#]
        );
        let joint_1 = text.find(r#"<joint name="joint_1_s""#).expect("joint_1_s");
        let origin = text.find("0.516500000").expect("corrected origin");
        assert!(origin > joint_1 && origin > text.find("</transmission>").unwrap());
        assert_matches_error_model(&robot, &e, &corrected);
    }
}

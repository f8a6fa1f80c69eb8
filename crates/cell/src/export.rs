//! Writing a calibrated cell: corrected URDFs (the URDF-expressible corrections — joint offsets,
//! origin xyz/rpy) and a cell TOML (the fitted `b1_from_b2`, corrected tips, and in
//! `[robotN.errors]` what a URDF cannot hold: joint scale, compliance). Used by
//! `handclasp calibrate --cell --export` and the `ctu-motoman` study (studies/ctu-motoman).
//!
//! # The placement's σ in the exported cell
//! `[b1_from_b2] sigma_mm / sigma_deg` is the input cell's, unchanged, centred on the fitted
//! placement; a cell without it is written without it. Never the posterior σ:
//! - **A known placement** (two arms on one base): the σ states a mechanical fact, which the
//!   calibration does not change; the fit stays well within it (the CTU self-contact fit moves
//!   the placement by 2e-6 mm against σ 0.01 mm), so the re-centred prior says the same thing.
//! - **A placement fitted from the session** (two robots calibrated by handclasp, no σ in the
//!   cell): the exported cell is written without a σ. Its next use is a new calibration, whose
//!   job includes finding out whether a robot moved; a prior at this fit's posterior σ (tens of
//!   µm from 40 handclasps) would pin the placement to the old fit and hide the move. The
//!   kinematic corrections are treated the same way: the corrected URDFs carry the fit, and the
//!   next calibration's prior is again the cell's `[robotN.tolerance]`, not a posterior.
//! - **Both** (a σ in the cell and a session that determines the placement): the posterior σ
//!   is at most the prior σ, so the kept prior σ is a conservative statement about the fitted
//!   placement and keeps what the cell's author declared.

use std::path::{Path, PathBuf};

use calib_core::whole_cell::CellEstimate;
use calib_core::Robot;
use kinematics::{
    patch_urdf_text, split_for_urdf, verify_patched_urdf, KinematicErrors, RobotModel,
};

use crate::cell::{refitted_robot2_mount, Cell, CellRobot};
use crate::error::FormatError;

/// The files [`export_calibrated_cell`] writes, relative to its output folder, and the comment
/// put at the top of the cell file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ExportNames<'a> {
    /// The cell file, e.g. `cell.toml`.
    pub cell: &'a str,
    /// Robot 1's corrected URDF, e.g. `robot1.urdf`.
    pub robot1_urdf: &'a str,
    /// Robot 2's corrected URDF, e.g. `robot2.urdf`.
    pub robot2_urdf: &'a str,
    /// Comment lines (each starting with `#`, ending with a newline) written before the TOML.
    pub header: &'a str,
}

/// The names `handclasp calibrate --cell --export DIR` uses: `robot1.urdf`, `robot2.urdf`,
/// `cell.toml`.
pub const CALIBRATE_EXPORT_NAMES: ExportNames<'static> = ExportNames {
    cell: "cell.toml",
    robot1_urdf: "robot1.urdf",
    robot2_urdf: "robot2.urdf",
    header: "# Written by `handclasp calibrate --cell --export`: the calibrated cell (fitted b1_from_b2,\n\
             # corrected URDFs robot1.urdf / robot2.urdf and tip offsets; [robotN.errors] holds only what a\n\
             # URDF cannot express). [b1_from_b2] sigma_mm/sigma_deg, if any, is the input cell's prior,\n\
             # now centred on the fitted placement. A session recorded with the old models has their tip\n\
             # columns, which these models reject (record a new session, or use the old cell for it).\n",
};

/// Writes the calibrated `cell` into `dir` (created if missing): each robot's URDF corrected by
/// the URDF-expressible part of `estimate`'s corrections ([`split_for_urdf`]), and the cell file
/// with `estimate.b1_from_b2`, the tips corrected by tool 0's tip error (tool 0 = the cell's tip,
/// as [`crate::problem::cell_problem`] builds it) and each named tool (`[robotN.tools]`, tools
/// 1.. in the cell's order) by its own, the rest of each robot's errors (joint
/// scale, compliance) as `[robotN.errors]`, robot 2's gravity rotated by the fitted placement, and
/// the cell's placement σ (if any) unchanged, now centred on the fitted placement (see the
/// module documentation for why). Robot 2's mount is the cell's unless the fitted placement
/// puts robot 2's gravity more than [`crate::cell::MOUNT_TOLERANCE_DEG`] from it: then the
/// mount that placement implies, with a comment line in the file saying so
/// ([`refitted_robot2_mount`]; callers warn with its note), so a fitted calibration is always
/// exportable. The placement's angles are written by
/// [`calib_core::zyz_canonical`] (a tilt below 1e-8 rad is written as a pure yaw).
/// Each URDF is written to a temporary file, re-loaded, verified against the fitted model
/// ([`verify_patched_urdf`], flange within [`kinematics::PATCH_TOLERANCE_M`]) and renamed into
/// place; the cell file is written the same way and re-loaded. Returns the files written (the two
/// URDFs, or robot 1's alone for a one-robot cell, then the cell).
///
/// Exactness: without compliance the exported cell reproduces the estimate's tips to
/// [`kinematics::PATCH_TOLERANCE_M`]. With compliance AND geometry corrections on the same robot
/// it does not, exactly: the fit evaluates the gravity torques with the nominal model, the
/// exported cell with the corrected URDF, so the tips differ by about `compliance × δτ` (δτ the
/// torque change the geometry correction causes; ~1 µm for 1e-6 rad/(N·m) and 1 mrad). Robot 2's
/// gravity in the written file comes from its mount, not from `cell`'s (possibly tilted) robot 2
/// gravity the fit used, which moves a compliant robot 2 by `compliance × δτ` too (~2e-9 m for
/// 1e-6 rad/(N·m) and a 1.2e-5 rad tilt).
///
/// Errors: `estimate` of the wrong shape for `cell` (joint counts, no tool 0), a URDF that cannot
/// be read or corrected ([`FormatError::Cell`] naming the robot and file), any file that cannot be
/// written ([`FormatError::Io`]), a written cell that does not load.
pub fn export_calibrated_cell(
    cell: &Cell,
    estimate: &CellEstimate,
    dir: &Path,
    names: &ExportNames<'_>,
) -> Result<Vec<PathBuf>, FormatError> {
    std::fs::create_dir_all(dir).map_err(|e| FormatError::io(dir, e))?;
    let mut out = cell.clone();
    out.base_dir = dir.to_path_buf();
    out.b1_from_b2 = estimate.b1_from_b2;
    let mut written = Vec::new();
    // A one-robot cell writes robot 1's URDF only (its robot 2 is a stand-in, not written).
    for &robot in cell.robots() {
        let setup = cell.robot(robot);
        let correction = estimate.robot(robot);
        let bad = |message: String| FormatError::Cell {
            path: setup.urdf_path.clone(),
            message: format!("{robot}: {message}"),
        };
        let Some(tip_error) = correction.tool_tip_m.first() else {
            return Err(bad(
                "the estimate has no tool 0 (the cell's tip); build it from this cell's problem"
                    .into(),
            ));
        };
        let file = match robot {
            Robot::One => names.robot1_urdf,
            Robot::Two => names.robot2_urdf,
        };
        let path = dir.join(file);
        let model = write_corrected_urdf(robot, setup, &correction.errors, &path)?;
        written.push(path.clone());
        let r = if robot == Robot::One {
            &mut out.robot1
        } else {
            &mut out.robot2
        };
        r.model = model;
        r.urdf = file.to_string();
        r.urdf_path = path;
        r.flange_from_tip = setup.flange_from_tip + tip_error;
        // The named tools ([robotN.tools], tools 1.. of the problem) carry their fitted tip
        // errors too.
        for (tool, error) in r.tools.iter_mut().zip(correction.tool_tip_m.iter().skip(1)) {
            tool.flange_from_tip += error;
        }
        // What a URDF cannot hold (scale, compliance; tips are in tip_mm, mounts are never fitted).
        r.errors = split_for_urdf(&correction.errors).1;
    }
    // Robot 2's gravity follows the calibrated placement; its declared mount too when the
    // placement moved it out of the mount's tolerance (the written cell must load).
    out.robot2.g_base = out.b1_from_b2.rotation.inverse() * out.robot1.g_base;
    let mut header = names.header.to_string();
    if let Some((mount, note)) = refitted_robot2_mount(cell, &estimate.b1_from_b2) {
        out.robot2.mount = mount;
        header.push_str(&format!("# {note}\n"));
    }
    let cell_path = dir.join(names.cell);
    let text = format!("{header}{}", out.to_toml_string());
    crate::output::write_atomically(&cell_path, text.as_bytes())?;
    Cell::from_toml_file(&cell_path)?;
    written.push(cell_path);
    Ok(written)
}

/// Writes `setup`'s URDF corrected by the URDF-expressible part of `errors` ([`split_for_urdf`]:
/// joint offsets, joint origin xyz and rpy; SI) to `path`: patched into the source text by
/// [`patch_urdf_text`] (every other byte kept), written to a temporary file beside `path`
/// (`path` with the extension `urdf.tmp`), read back, verified against the corrected model
/// ([`verify_patched_urdf`]) and re-loaded, and only then renamed to `path`; on a failure the
/// temporary file is removed. Returns the corrected model as loaded from the written file.
///
/// Errors ([`FormatError::Cell`] naming the source URDF and `robot`, or [`FormatError::Io`]):
/// the source URDF cannot be read or patched, the written text fails the verification or does
/// not load, the file system refuses the write or the rename.
pub(crate) fn write_corrected_urdf(
    robot: Robot,
    setup: &CellRobot,
    errors: &KinematicErrors,
    path: &Path,
) -> Result<RobotModel, FormatError> {
    let bad = |message: String| FormatError::Cell {
        path: setup.urdf_path.clone(),
        message: format!("{robot}: {message}"),
    };
    let (urdf_part, _) = split_for_urdf(errors);
    let xml =
        kinematics::input::read_input_text(&setup.urdf_path, "URDF").map_err(FormatError::input)?;
    let patched = patch_urdf_text(&xml, &setup.model, &urdf_part)
        .map_err(|e| bad(format!("cannot write the corrected URDF: {e}")))?;
    let tmp = path.with_extension("urdf.tmp");
    std::fs::write(&tmp, &patched).map_err(|e| FormatError::io(&tmp, e))?;
    let checked = (|| {
        let reread = std::fs::read_to_string(&tmp).map_err(|e| FormatError::io(&tmp, e))?;
        verify_patched_urdf(&reread, &setup.model, &urdf_part)
            .map_err(|e| bad(format!("verifying {}: {e}", tmp.display())))?;
        // The couplings the cell declares (not in the URDF) hold for the corrected URDF too.
        let model = RobotModel::from_urdf_file(&tmp, &setup.tool_link)
            .and_then(|m| m.with_couplings(setup.model.added_couplings()))
            .map_err(|e| bad(format!("re-loading {}: {e}", tmp.display())))?;
        std::fs::rename(&tmp, path).map_err(|e| FormatError::io(path, e))?;
        Ok(model)
    })();
    if checked.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    checked
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::coincident_session;
    use crate::problem::{cell_problem, FitModel};
    use kinematics::true_base_from_tip;
    use kinematics::{Axis, ErrorParam};
    use nalgebra::{Isometry3, Vector3};
    use rand::Rng;

    /// Exported model vs fitted model: the URDF patch's own tolerance
    /// (kinematics::PATCH_TOLERANCE_M); the cell TOML keeps 10 decimals of mm (1e-13 m).
    const TOL_M: f64 = 1e-9;
    /// The cell TOML keeps 10 decimals of deg/kNm: 1e-10 deg/kNm = 1.7e-15 rad/(N·m).
    const COMPLIANCE_TOL: f64 = 2e-15;

    fn floor_floor() -> Cell {
        Cell::from_toml_file(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/floor-floor.toml"),
        )
        .unwrap()
    }

    #[test]
    fn exported_cell_reproduces_the_estimate_with_the_given_names() {
        let cell = floor_floor();
        let session = coincident_session(&cell, 4);
        let problem = cell_problem(&cell, &session, FitModel::Kinematic);
        let mut est = CellEstimate::nominal(
            &problem,
            Isometry3::new(
                Vector3::new(0.01, -0.02, 0.003),
                Vector3::new(0.0, 0.0, 0.01),
            ),
        );
        // Geometry on robot 2, compliance on robot 1 alone: exact (see the function's doc).
        est.robot2.errors.joint_offset[1] = 2e-3;
        est.robot2.errors.origin_xyz[2].x = 4e-4;
        est.robot2.errors.origin_rpy[3].z = -1e-3;
        est.robot2.tool_tip_m[0] = Vector3::new(1e-3, 0.0, -2e-3);
        est.robot1.errors.compliance[1] = 1e-6;
        let dir = tempfile::tempdir().unwrap();
        let names = ExportNames {
            cell: "calibrated.toml",
            robot1_urdf: "a.urdf",
            robot2_urdf: "b.urdf",
            header: "# a test header\n",
        };
        let written = export_calibrated_cell(&cell, &est, dir.path(), &names).unwrap();
        assert_eq!(
            written,
            vec![
                dir.path().join("a.urdf"),
                dir.path().join("b.urdf"),
                dir.path().join("calibrated.toml")
            ]
        );
        let text = std::fs::read_to_string(dir.path().join("calibrated.toml")).unwrap();
        assert!(text.starts_with("# a test header\n"));
        let out = Cell::from_toml_file(&dir.path().join("calibrated.toml")).unwrap();
        assert!(
            (out.b1_from_b2.translation.vector - est.b1_from_b2.translation.vector).norm() < TOL_M
        );
        // The compliance, which a URDF cannot hold, is in [robot2.errors]; the rest in the URDFs.
        assert!((out.robot1.errors.compliance[1] - 1e-6).abs() < COMPLIANCE_TOL);
        assert_eq!(out.robot2.errors.joint_offset[1], 0.0);
        for (setup, fitted, tip_err, exported) in [
            (
                &cell.robot1,
                &est.robot1.errors,
                est.robot1.tool_tip_m[0],
                &out.robot1,
            ),
            (
                &cell.robot2,
                &est.robot2.errors,
                est.robot2.tool_tip_m[0],
                &out.robot2,
            ),
        ] {
            for p in &session.points {
                let q = if std::ptr::eq(setup, &cell.robot1) {
                    &p.q1
                } else {
                    &p.q2
                };
                let want = true_base_from_tip(
                    &setup.model,
                    fitted,
                    q,
                    &(setup.flange_from_tip + tip_err),
                    &setup.g_base,
                )
                .unwrap();
                let got = true_base_from_tip(
                    &exported.model,
                    &exported.errors,
                    q,
                    &exported.flange_from_tip,
                    &exported.g_base,
                )
                .unwrap();
                let d = (want.translation.vector - got.translation.vector).norm();
                assert!(d < TOL_M, "{}: {d} m", exported.urdf);
            }
        }
    }

    /// Rotation angle of `q`, rad, accurate near 0 (`UnitQuaternion::angle` takes an `acos`,
    /// which loses ~1e-8 rad there).
    fn angle_rad(q: &nalgebra::UnitQuaternion<f64>) -> f64 {
        2.0 * q.vector().norm().atan2(q.scalar().abs())
    }

    /// A seeded 4-point floor–floor session and its kinematic problem.
    fn floor_floor_problem(cell: &Cell) -> calib_core::whole_cell::CellProblem {
        let session = coincident_session(cell, 4);
        cell_problem(cell, &session, FitModel::Kinematic)
    }

    #[test]
    fn the_placement_sigma_is_kept_centred_on_the_fit_and_absent_stays_absent() {
        use crate::PlacementSigma;
        let plain = floor_floor();
        let mut known = plain.clone();
        let sigma = PlacementSigma {
            sigma_m: 2e-5,
            sigma_rad: 3e-5,
        };
        known.b1_from_b2_sigma = Some(sigma);
        for (cell, want) in [(&plain, None), (&known, Some(sigma))] {
            let problem = floor_floor_problem(cell);
            let fitted = Isometry3::new(
                Vector3::new(0.04, 1.47, 0.05),
                Vector3::new(1e-3, -2e-3, -0.77),
            );
            let est = CellEstimate::nominal(&problem, fitted);
            let dir = tempfile::tempdir().unwrap();
            export_calibrated_cell(cell, &est, dir.path(), &CALIBRATE_EXPORT_NAMES).unwrap();
            let out = Cell::from_toml_file(&dir.path().join("cell.toml")).unwrap();
            let got = out.b1_from_b2_sigma;
            match (got, want) {
                (None, None) => {}
                (Some(g), Some(w)) => {
                    // The TOML keeps 10 decimals of mm and deg.
                    assert!((g.sigma_m - w.sigma_m).abs() < 1e-13, "{g:?}");
                    assert!((g.sigma_rad - w.sigma_rad).abs() < 2e-12, "{g:?}");
                }
                _ => panic!("placement σ written as {got:?}, want {want:?}"),
            }
            // The prior's centre is the fitted placement.
            let d = out.b1_from_b2.inverse() * fitted;
            assert!(d.translation.vector.norm() < TOL_M);
            assert!(angle_rad(&d.rotation) < 1e-9);
        }
    }

    #[test]
    fn a_near_identity_placement_is_written_with_phi_zero_and_reads_back() {
        let cell = floor_floor();
        let problem = floor_floor_problem(&cell);
        // The CTU study's case: a placement held at the identity, left 2e-9 rad from it by the
        // fit, which eq 32 reads as φ ≈ 1.34°, ψ ≈ −1.34°.
        let fitted = Isometry3::from_parts(
            nalgebra::Translation3::new(1e-9, 0.0, -2e-9),
            calib_core::rotation_from_zyz([1.34f64.to_radians(), 2e-9, (-1.335f64).to_radians()])
                .into(),
        );
        let est = CellEstimate::nominal(&problem, fitted);
        let dir = tempfile::tempdir().unwrap();
        export_calibrated_cell(&cell, &est, dir.path(), &CALIBRATE_EXPORT_NAMES).unwrap();
        let text = std::fs::read_to_string(dir.path().join("cell.toml")).unwrap();
        assert!(
            text.contains("zyz_deg = [0.0, 0.0, 0.005]"),
            "canonical angles: {text}"
        );
        let out = Cell::from_toml_file(&dir.path().join("cell.toml")).unwrap();
        // Same rotation within the dropped tilt (calib_core::ZYZ_CANONICAL_TILT_RAD) and the
        // file's 10 decimals of degrees.
        let angle = angle_rad(&(out.b1_from_b2.rotation.inverse() * fitted.rotation));
        assert!(angle < calib_core::ZYZ_CANONICAL_TILT_RAD, "{angle}");
        // Written again, the read-back cell gives the same text (a fixed point).
        let again = tempfile::tempdir().unwrap();
        let est2 = CellEstimate::nominal(&problem, out.b1_from_b2);
        export_calibrated_cell(&cell, &est2, again.path(), &CALIBRATE_EXPORT_NAMES).unwrap();
        let text2 = std::fs::read_to_string(again.path().join("cell.toml")).unwrap();
        let zyz_line = |t: &str| {
            t.lines()
                .find(|l| l.starts_with("zyz_deg"))
                .map(str::to_string)
        };
        assert_eq!(zyz_line(&text), zyz_line(&text2));
    }

    #[test]
    fn an_estimate_without_the_tip_tool_is_refused_naming_the_robot() {
        let cell = floor_floor();
        let session = coincident_session(&cell, 4);
        let problem = cell_problem(&cell, &session, FitModel::Kinematic);
        let mut est = CellEstimate::nominal(&problem, cell.b1_from_b2);
        est.robot1.tool_tip_m.clear();
        let dir = tempfile::tempdir().unwrap();
        let e = export_calibrated_cell(&cell, &est, dir.path(), &CALIBRATE_EXPORT_NAMES)
            .unwrap_err()
            .to_string();
        assert!(e.contains("robot 1") && e.contains("tool 0"), "{e}");
    }

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
            let which = [Robot::One, Robot::Two][k_robot];
            let corrected = write_corrected_urdf(which, robot, &e, &path).expect("corrected");
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
        let mut e = KinematicErrors::zero_for(&robot.model);
        e.origin_xyz[0] = Vector3::new(0.0, 0.0, 0.0115);
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("robot2_corrected.urdf");
        let corrected = write_corrected_urdf(Robot::Two, &robot, &e, &path).expect("exported");
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

    /// A write that fails after the temporary file exists (here the rename, onto a folder of the
    /// URDF's name) removes the temporary file and names the path.
    #[test]
    fn a_failed_urdf_write_leaves_no_temporary_file() {
        let cell = Cell::default_floor_floor();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("robot1.urdf");
        std::fs::create_dir(&path).unwrap();
        std::fs::write(path.join("keep"), "").unwrap();
        let errors = KinematicErrors::zero_for(&cell.robot1.model);
        let e = write_corrected_urdf(Robot::One, &cell.robot1, &errors, &path).unwrap_err();
        assert!(matches!(e, FormatError::Io { .. }), "{e}");
        assert!(e.to_string().contains("robot1.urdf"), "{e}");
        assert!(!dir.path().join("robot1.urdf.tmp").exists());
    }

    /// A fitted placement that tilts a wall-mounted robot 2 by more than the mount tolerance
    /// (as harm36 found: a sag-tracker session of `tests/e2e/do_no_harm.rs`'s benchmark, seed
    /// 4, `--model placement --force`, 3.2° from the cell's placement): the export used to
    /// fail re-loading its own cell ("`robot2.mount` = \"wall\" is impossible"). It writes the
    /// mount the fitted placement implies, says so in the file, and keeps the fitted placement.
    #[test]
    fn a_fitted_placement_off_the_declared_mount_is_exported_with_the_mount_it_implies() {
        let cell = Cell::from_toml_file(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/floor-wall.toml"),
        )
        .unwrap();
        let session = coincident_session(&cell, 4);
        let problem = cell_problem(&cell, &session, FitModel::Placement);
        // Robot 2's base tipped 3.2° about an axis of its xy plane: its up direction leaves
        // the wall's horizontal by about that much.
        // (about b1's horizontal axis normal to robot 2's z axis, which the wall holds level).
        let z2_b1 = cell.b1_from_b2.rotation * Vector3::z();
        let tip = Isometry3::rotation(Vector3::z().cross(&z2_b1).normalize() * 3.2f64.to_radians());
        let fitted = Isometry3::from_parts(
            (cell.b1_from_b2.translation.vector + Vector3::new(0.07, 0.0, 0.0)).into(),
            tip.rotation * cell.b1_from_b2.rotation,
        );
        let up_b2 = -(fitted.rotation.inverse() * cell.robot1.g_base) / crate::cell::G;
        let off = crate::cell::mount_mismatch_deg(&cell.robot2.mount, &up_b2);
        assert!(off > crate::cell::MOUNT_TOLERANCE_DEG, "{off}");
        let est = CellEstimate::nominal(&problem, fitted);
        let dir = tempfile::tempdir().unwrap();
        export_calibrated_cell(&cell, &est, dir.path(), &CALIBRATE_EXPORT_NAMES).unwrap();
        let text = std::fs::read_to_string(dir.path().join("cell.toml")).unwrap();
        assert!(text.contains("from its declared mount"), "{text}");
        let out = Cell::from_toml_file(&dir.path().join("cell.toml")).unwrap();
        assert!((out.b1_from_b2.translation.vector - fitted.translation.vector).norm() < TOL_M);
        assert!(out.b1_from_b2.rotation.angle_to(&fitted.rotation) < 1e-9);
        assert!(matches!(out.robot2.mount, calib_core::Mount::Tilt { .. }));
        // The written mount agrees with the placement (what the loader checks).
        assert!(crate::cell::mount_mismatch_deg(&out.robot2.mount, &up_b2) < 1e-6);
        // Within the tolerance the declared mount is kept.
        let near = Isometry3::from_parts(
            cell.b1_from_b2.translation,
            Isometry3::rotation(tip.rotation.scaled_axis() * 0.25).rotation
                * cell.b1_from_b2.rotation,
        );
        let est = CellEstimate::nominal(&problem, near);
        let dir = tempfile::tempdir().unwrap();
        export_calibrated_cell(&cell, &est, dir.path(), &CALIBRATE_EXPORT_NAMES).unwrap();
        let out = Cell::from_toml_file(&dir.path().join("cell.toml")).unwrap();
        assert_eq!(out.robot2.mount, cell.robot2.mount);
    }
}

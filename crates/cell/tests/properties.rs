//! Property test (issue 10, "Fuzzing and properties"): a cell TOML round-trips through
//! `Cell::to_toml_string` → `Cell::from_toml_str`. The fixed-input versions are the unit tests in
//! `src/cell/tests.rs`; this one draws the cell.

use std::path::{Path, PathBuf};

use handclasp_cell::Cell;
use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

/// Lengths (m) and angles (rad) after a TOML round trip: the writer rounds to 1e-10 mm and 1e-10°
/// (5e-14 m, 9e-13 rad), plus the ZYZ extraction's round-off.
const ROUND_TRIP_TOL: f64 = 1e-12;
/// `joint_scale` is written unitless, rounded to 1e-10.
const SCALE_ROUND_TRIP_TOL: f64 = 1e-10;
/// Rotation of `b1_from_b2` after the ZYZ round trip, rad.
const ROTATION_ROUND_TRIP_TOL_RAD: f64 = 1e-11;

fn cells_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells")
}

const CELLS: [&str; 4] = ["floor-wall", "floor-floor", "floor-ceiling", "ctu-motoman"];

/// Random contents of the fields a cell file writes (robot 2's mount stays consistent with the
/// placement: the drawn rotation turns about b1's z axis, which robot 1's floor mount keeps level).
#[derive(Debug, Clone)]
struct Draw {
    cell: usize,
    t_mm: [f64; 3],
    yaw: f64,
    tips_mm: [[f64; 3]; 2],
    /// Per robot and joint: offset, scale, origin xyz, origin rpy, compliance, each maybe zero.
    joint_errors: Vec<[f64; 9]>,
    tip_mount_errors: [[f64; 9]; 2],
    alignment_mm: [f64; 3],
    isotropic: bool,
    repeatability_mm: f64,
    encoder_deg: f64,
    centre_mm: [f64; 3],
    tolerance: Option<[f64; 4]>,
}

fn small() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), -1.0..1.0f64]
}

fn draw() -> impl Strategy<Value = Draw> {
    (
        (
            0..CELLS.len(),
            proptest::array::uniform3(-3000.0..3000.0f64),
            -std::f64::consts::PI..std::f64::consts::PI,
            proptest::array::uniform2(proptest::array::uniform3(-300.0..300.0f64)),
        ),
        (
            proptest::collection::vec(proptest::array::uniform9(small()), 14),
            proptest::array::uniform2(proptest::array::uniform9(small())),
        ),
        (
            proptest::array::uniform3(0.0..2.0f64),
            any::<bool>(),
            0.0..0.1f64,
            prop_oneof![Just(0.0), 0.0..0.01f64],
            proptest::array::uniform3(-2000.0..2000.0f64),
            proptest::option::of(proptest::array::uniform4(1e-4..1.0f64)),
        ),
    )
        .prop_map(
            |(
                (cell, t_mm, yaw, tips_mm),
                (joint_errors, tip_mount_errors),
                (alignment_mm, isotropic, repeatability_mm, encoder_deg, centre_mm, tolerance),
            )| Draw {
                cell,
                t_mm,
                yaw,
                tips_mm,
                joint_errors,
                tip_mount_errors,
                alignment_mm,
                isotropic,
                repeatability_mm,
                encoder_deg,
                centre_mm,
                tolerance,
            },
        )
}

fn drawn_cell(d: &Draw) -> Cell {
    let mut cell = Cell::from_toml_file(&cells_dir().join(format!("{}.toml", CELLS[d.cell])))
        .expect("shipped cell");
    let yaw = UnitQuaternion::from_rotation_matrix(&Rotation3::from_axis_angle(
        &Vector3::z_axis(),
        d.yaw,
    ));
    cell.b1_from_b2 = Isometry3::from_parts(
        Translation3::from(Vector3::from(d.t_mm) * 1e-3),
        yaw * cell.b1_from_b2.rotation,
    );
    let mut joint_draws = d.joint_errors.iter();
    for (r, robot) in [&mut cell.robot1, &mut cell.robot2].into_iter().enumerate() {
        robot.flange_from_tip = Vector3::from(d.tips_mm[r]) * 1e-3;
        let e = &mut robot.errors;
        for k in 0..e.dof() {
            let v = joint_draws.next().copied().unwrap_or([0.0; 9]);
            e.joint_offset[k] = v[0] * 1e-3;
            e.joint_scale[k] = v[1] * 1e-4;
            e.origin_xyz[k] = Vector3::new(v[2], v[3], v[4]) * 1e-3;
            e.origin_rpy[k] = Vector3::new(v[5], v[6], v[7]) * 1e-3;
            e.compliance[k] = v[8].abs() * 1e-6;
        }
        let v = d.tip_mount_errors[r];
        e.tip = Vector3::new(v[0], v[1], v[2]) * 1e-3;
        e.mount_xyz = Vector3::new(v[3], v[4], v[5]) * 1e-3;
        e.mount_rpy = Vector3::new(v[6], v[7], v[8]) * 1e-3;
        if let Some(t) = d.tolerance {
            robot.tolerance.joint_offset_rad = t[0] * 1e-3;
            robot.tolerance.origin_xyz_m = t[1] * 1e-3;
            robot.tolerance.origin_rpy_rad = t[2] * 1e-3;
            robot.tolerance.tip_m = t[3] * 1e-3;
        }
    }
    cell.noise.alignment_m = if d.isotropic {
        Vector3::repeat(d.alignment_mm[0])
    } else {
        Vector3::from(d.alignment_mm)
    } * 1e-3;
    cell.noise.repeatability_m = d.repeatability_mm * 1e-3;
    cell.noise.encoder_resolution_rad = d.encoder_deg.to_radians();
    cell.centre_b1 = Point3::from(Vector3::from(d.centre_mm) * 1e-3);
    cell
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

fn close3(a: &Vector3<f64>, b: &Vector3<f64>, tol: f64) -> bool {
    (a - b).amax() <= tol
}

fn check_equal(a: &Cell, b: &Cell) -> Result<(), TestCaseError> {
    let ta = a.b1_from_b2.translation.vector;
    prop_assert!(close3(
        &ta,
        &b.b1_from_b2.translation.vector,
        ROUND_TRIP_TOL
    ));
    prop_assert!(
        a.b1_from_b2.rotation.angle_to(&b.b1_from_b2.rotation) <= ROTATION_ROUND_TRIP_TOL_RAD
    );
    for (r, s) in [(&a.robot1, &b.robot1), (&a.robot2, &b.robot2)] {
        prop_assert_eq!(&r.urdf, &s.urdf);
        prop_assert_eq!(&r.tool_link, &s.tool_link);
        prop_assert_eq!(r.mount, s.mount);
        prop_assert!(close3(
            &r.flange_from_tip,
            &s.flange_from_tip,
            ROUND_TRIP_TOL
        ));
        let (e, f) = (&r.errors, &s.errors);
        prop_assert_eq!(e.dof(), f.dof());
        for k in 0..e.dof() {
            prop_assert!(close(e.joint_offset[k], f.joint_offset[k], ROUND_TRIP_TOL));
            prop_assert!(close(
                e.joint_scale[k],
                f.joint_scale[k],
                SCALE_ROUND_TRIP_TOL
            ));
            prop_assert!(close3(&e.origin_xyz[k], &f.origin_xyz[k], ROUND_TRIP_TOL));
            prop_assert!(close3(&e.origin_rpy[k], &f.origin_rpy[k], ROUND_TRIP_TOL));
            prop_assert!(close(e.compliance[k], f.compliance[k], ROUND_TRIP_TOL));
        }
        prop_assert!(close3(&e.tip, &f.tip, ROUND_TRIP_TOL));
        prop_assert!(close3(&e.mount_xyz, &f.mount_xyz, ROUND_TRIP_TOL));
        prop_assert!(close3(&e.mount_rpy, &f.mount_rpy, ROUND_TRIP_TOL));
        let (t, u) = (&r.tolerance, &s.tolerance);
        prop_assert!(close(
            t.joint_offset_rad,
            u.joint_offset_rad,
            ROUND_TRIP_TOL
        ));
        prop_assert!(close(t.origin_xyz_m, u.origin_xyz_m, ROUND_TRIP_TOL));
        prop_assert!(close(t.origin_rpy_rad, u.origin_rpy_rad, ROUND_TRIP_TOL));
        prop_assert!(close(t.tip_m, u.tip_m, ROUND_TRIP_TOL));
    }
    prop_assert!(close3(
        &a.noise.alignment_m,
        &b.noise.alignment_m,
        ROUND_TRIP_TOL
    ));
    prop_assert!(close(
        a.noise.repeatability_m,
        b.noise.repeatability_m,
        ROUND_TRIP_TOL
    ));
    prop_assert!(close(
        a.noise.encoder_resolution_rad,
        b.noise.encoder_resolution_rad,
        ROUND_TRIP_TOL
    ));
    prop_assert!(close3(
        &a.centre_b1.coords,
        &b.centre_b1.coords,
        ROUND_TRIP_TOL
    ));
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// A shipped cell with drawn placement (yaw about gravity, any translation), tips, kinematic
    /// errors of every kind, noise, teach centre and tolerances: written and read back it is the
    /// same cell, and reading its text a second time gives the same derived gravity.
    #[test]
    fn cell_toml_round_trips(d in draw()) {
        let cell = drawn_cell(&d);
        let text = cell.to_toml_string();
        let back = Cell::from_toml_str(&text, &cell.base_dir)
            .map_err(|e| TestCaseError::fail(format!("{e}\n{text}")))?;
        check_equal(&cell, &back)?;
        let again = Cell::from_toml_str(&back.to_toml_string(), &cell.base_dir).unwrap();
        check_equal(&back, &again)?;
        for (r, s) in [(&back.robot1, &again.robot1), (&back.robot2, &again.robot2)] {
            prop_assert!(close3(&r.g_base, &s.g_base, 1e-9));
        }
    }
}

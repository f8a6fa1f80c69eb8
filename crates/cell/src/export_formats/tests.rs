use super::*;
use kinematics::rotation_from_zyx;
use std::f64::consts::FRAC_PI_2;

/// What a file written to its decimals (1 nm, 1e-9°, 1e-12) reads back to: round-off of the
/// printed digits, 1e-9 m and 1e-9 rad with margin.
const FILE_ROUND_OFF: f64 = 1e-9;

fn shipped_cells() -> Vec<(&'static str, Cell)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    ["floor-wall", "floor-floor", "floor-ceiling", "ctu-motoman"]
        .into_iter()
        .map(|name| {
            let cell = Cell::from_toml_file(&dir.join(format!("{name}.toml"))).unwrap();
            (name, cell)
        })
        .collect()
}

fn placement(xyz_m: [f64; 3], zyx: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(xyz_m)),
        UnitQuaternion::from_rotation_matrix(&rotation_from_zyx(zyx)),
    )
}

#[test]
fn conventions_on_a_known_placement() {
    // Robot 2 1.5 m along x, turned 90° about z, then tilted 30° about its y: KUKA A = 90,
    // B = 30, C = 0; Fanuc/Yaskawa list the same angles the other way round.
    let p = placement([1.5, -0.2, 0.3], [FRAC_PI_2, 30f64.to_radians(), 0.0]);
    let f = PlacementFormats::new(&p, &ControllerFormat::ALL);
    let k = f.kuka.unwrap();
    assert!((k.x_mm - 1500.0).abs() < 1e-9 && (k.y_mm + 200.0).abs() < 1e-9);
    assert!((k.a_deg - 90.0).abs() < 1e-9 && (k.b_deg - 30.0).abs() < 1e-9 && k.c_deg.abs() < 1e-9);
    let fa = f.fanuc.unwrap();
    assert_eq!((fa.w_deg, fa.p_deg, fa.r_deg), (k.c_deg, k.b_deg, k.a_deg));
    let y = f.yaskawa.unwrap();
    assert_eq!((y.rx_deg, y.ry_deg, y.rz_deg), (k.c_deg, k.b_deg, k.a_deg));
    // Quaternion of Rz(90°)·Ry(30°) = (cos45, 0, 0, sin45)·(cos15, 0, sin15, 0).
    let (c45, s45, c15, s15) = (
        45f64.to_radians().cos(),
        45f64.to_radians().sin(),
        15f64.to_radians().cos(),
        15f64.to_radians().sin(),
    );
    let want = [c45 * c15, -s45 * s15, c45 * s15, s45 * c15];
    let a = f.abb.unwrap();
    let r = f.ros2.unwrap();
    for (got, w) in [a.q1, a.q2, a.q3, a.q4].iter().zip(want) {
        assert!((got - w).abs() < 1e-15, "{a:?} vs {want:?}");
    }
    assert_eq!([r.qw, r.qx, r.qy, r.qz], [a.q1, a.q2, a.q3, a.q4]);
    assert_eq!((a.x_m, r.z_m), (1.5, 0.3));
}

#[test]
fn every_format_reads_back_its_own_numbers() {
    let header = Header { source: "test" };
    let cases = [
        placement([0.0; 3], [0.0; 3]),
        placement([1.2, -3.4, 0.5], [0.3, -0.7, 2.9]),
        // Gimbal lock (wall mount) both ways, and a half-turn (ceiling).
        placement([2.0, 0.1, 1.0], [1.0, FRAC_PI_2, -0.4]),
        placement([2.0, 0.1, 1.0], [-2.0, -FRAC_PI_2, 0.4]),
        placement([0.0, 0.0, 3.0], [0.2, 0.0, std::f64::consts::PI]),
        placement([1e-7, 0.0, 0.0], [1e-12, -1e-12, 1e-15]),
    ];
    for p in cases {
        let f = PlacementFormats::new(&p, &ControllerFormat::ALL);
        let reads = [
            abb::parse(&abb::render(&f.abb.unwrap(), &header)),
            kuka::parse(&kuka::render(&f.kuka.unwrap(), &header)),
            fanuc::parse(&fanuc::render(&f.fanuc.unwrap(), &header)),
            yaskawa::parse(&yaskawa::render(&f.yaskawa.unwrap(), &header)),
            ros2::parse_xacro(&ros2::render_xacro(&p, &header)),
            ros2::parse_launch(&ros2::render_launch(&f.ros2.unwrap(), "a", "b", &header)),
        ];
        for (k, read) in reads.into_iter().enumerate() {
            let d = Deviation::between(&p, &read.unwrap());
            assert!(
                d.translation_m < FILE_ROUND_OFF && d.rotation_rad < FILE_ROUND_OFF,
                "format {k}: {} m {} rad",
                d.translation_m,
                d.rotation_rad
            );
        }
    }
}

#[test]
fn parse_errors_name_what_is_wrong() {
    assert!(abb::parse("ROBOT:\n -name \"ROB_1\" -base_frame_pos_x 1\n")
        .unwrap_err()
        .contains("ROB_2"));
    assert!(abb::parse("-name \"ROB_2\" -base_frame_orient_u0 2\n")
        .unwrap_err()
        .contains("unit quaternion"));
    assert!(kuka::parse("FRAME $ROBROOT={X 1,Y 2,Z 3,A 0,B 0}\n")
        .unwrap_err()
        .contains("C missing"));
    assert!(fanuc::parse("X: 1\nY: 2\nZ: 3\nW: 0\nP: nan\nR: 0\n")
        .unwrap_err()
        .contains("P"));
    assert!(yaskawa::parse("X: 1\nY: 2\nZ: 3\nRx: 0\nRy: 0\n")
        .unwrap_err()
        .contains("Rz"));
    assert_eq!(
        ControllerFormat::from_name(" ROS2"),
        Some(ControllerFormat::Ros2)
    );
    assert_eq!(ControllerFormat::from_name("staubli"), None);
}

#[test]
fn exports_the_shipped_cells_and_reads_them_back() {
    for (name, cell) in shipped_cells() {
        let dir = tempfile::tempdir().unwrap();
        let out = export_placement(&cell, name, dir.path(), &ControllerFormat::ALL).unwrap();
        let expected: Vec<&str> = ControllerFormat::ALL
            .iter()
            .flat_map(|f| f.files().iter().copied())
            .collect();
        let mut names: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        let mut want: Vec<String> = expected.iter().map(|s| s.to_string()).collect();
        want.sort();
        assert_eq!(names, want, "{name}: no .tmp left, every file there");
        assert_eq!(out.files.len(), expected.len());
        for f in &out.files {
            // The files hold 1 nm / 1e-12 digits; the URDF's numbers are Rust's shortest
            // round-trip form, its chains compared through FK.
            assert!(
                f.translation_error_m < FILE_ROUND_OFF && f.rotation_error_rad < FILE_ROUND_OFF,
                "{name} {}: {} m {} rad",
                f.path.display(),
                f.translation_error_m,
                f.rotation_error_rad
            );
        }
        let text = std::fs::read_to_string(dir.path().join(kuka::FILE)).unwrap();
        assert!(
            text.starts_with("; handclasp export: robot 2's base frame"),
            "{text}"
        );
        assert!(text.contains("R = Rz(A)*Ry(B)*Rx(C)"));
        // The simulated cells carry true errors, which the URDF does not: said, not hidden.
        let has_errors = !cell.robot1.errors.is_zero() || !cell.robot2.errors.is_zero();
        assert_eq!(
            !out.warnings.is_empty(),
            has_errors,
            "{name}: {:?}",
            out.warnings
        );
    }
}

#[test]
fn subset_of_formats_writes_only_those() {
    let (_, cell) = shipped_cells().remove(0);
    let dir = tempfile::tempdir().unwrap();
    let out = export_placement(&cell, "x", dir.path(), &[ControllerFormat::Fanuc]).unwrap();
    assert!(out.formats.fanuc.is_some() && out.formats.abb.is_none());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let json = serde_json::to_value(out.formats).unwrap();
    assert_eq!(
        json.as_object().unwrap().keys().collect::<Vec<_>>(),
        ["fanuc"]
    );
}

/// A robot URDF rooted at its own `world` link (the world rule) with a second child of `world`:
/// the cell URDF drops that world link, attaches the base to the cell's world and moves the
/// other child to the base with the composed origin.
#[test]
fn cell_urdf_handles_a_robot_with_its_own_world_link() {
    let dir = tempfile::tempdir().unwrap();
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../robots");
    let hp20 = std::fs::read_to_string(robots.join("hp20.urdf")).unwrap();
    let with_world = hp20.replacen(
        "<link name=\"base_link\">",
        "<link name=\"world\"/>\n  <link name=\"table\"/>\n  \
         <joint name=\"world_joint\" type=\"fixed\"><origin xyz=\"0.1 0.2 0.3\" rpy=\"0 0 0.5\"/>\
         <parent link=\"world\"/><child link=\"base_link\"/></joint>\n  \
         <joint name=\"table_joint\" type=\"fixed\"><origin xyz=\"1 0 0\" rpy=\"0 0 0\"/>\
         <parent link=\"world\"/><child link=\"table\"/></joint>\n  <link name=\"base_link\">",
        1,
    );
    std::fs::write(dir.path().join("hp20w.urdf"), with_world).unwrap();
    std::fs::copy(robots.join("va1400.urdf"), dir.path().join("va1400.urdf")).unwrap();
    let shipped = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/floor-floor.toml"),
    )
    .unwrap();
    let text = shipped
        .replace("../robots/hp20.urdf", "hp20w.urdf")
        .replace("../robots/va1400.urdf", "va1400.urdf");
    let cell = Cell::from_toml_str(&text, dir.path()).unwrap();
    assert!(
        cell.robot2.model.root_from_base().is_some()
            || cell.robot1.model.root_from_base().is_some()
    );
    let out_dir = dir.path().join("out");
    let out = export_placement(&cell, "t", &out_dir, &[ControllerFormat::Ros2]).unwrap();
    assert_eq!(out.files.len(), 3);
    let urdf = std::fs::read_to_string(out_dir.join(ros2::URDF_FILE)).unwrap();
    let robot = urdf_rs::read_from_string(&urdf).unwrap();
    let which = if cell.robot1.model.root_from_base().is_some() {
        "robot1_"
    } else {
        "robot2_"
    };
    assert!(!robot
        .links
        .iter()
        .any(|l| l.name == format!("{which}world")));
    let table = robot
        .joints
        .iter()
        .find(|j| j.name == format!("{which}table_joint"))
        .unwrap();
    assert_eq!(table.parent.link, format!("{which}base_link"));
    // base_from_table = (world_from_base)⁻¹ · world_from_table.
    let world_from_base =
        kinematics::origin_isometry(&Vector3::new(0.1, 0.2, 0.3), &Vector3::new(0.0, 0.0, 0.5));
    let want = world_from_base.inverse() * Isometry3::translation(1.0, 0.0, 0.0);
    let got = kinematics::origin_isometry(
        &Vector3::from(table.origin.xyz.0),
        &Vector3::from(table.origin.rpy.0),
    );
    let d = Deviation::between(&want, &got);
    assert!(d.translation_m < 1e-15 && d.rotation_rad < 1e-15);
}

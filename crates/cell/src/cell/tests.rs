use super::*;

/// Round-off of mm/degree text conversions, m and rad.
const ROUND_TRIP_TOL: f64 = 1e-12;

fn assert_cells_equal(a: &Cell, b: &Cell) {
    assert!(
        (a.b1_from_b2.translation.vector - b.b1_from_b2.translation.vector).amax() < ROUND_TRIP_TOL
    );
    assert!(a.b1_from_b2.rotation.angle_to(&b.b1_from_b2.rotation) < 1e-9);
    for (r, s) in [(&a.robot1, &b.robot1), (&a.robot2, &b.robot2)] {
        assert_eq!(r.urdf, s.urdf);
        assert_eq!(r.mount, s.mount);
        assert!((r.flange_from_tip - s.flange_from_tip).amax() < ROUND_TRIP_TOL);
        assert!((r.g_base - s.g_base).amax() < 1e-9);
        let (e, f) = (&r.errors, &s.errors);
        for (x, y) in e.joint_offset.iter().zip(&f.joint_offset) {
            assert!((x - y).abs() < ROUND_TRIP_TOL);
        }
        for (x, y) in e.compliance.iter().zip(&f.compliance) {
            assert!((x - y).abs() < ROUND_TRIP_TOL);
        }
        for (x, y) in e
            .periodic_sin
            .iter()
            .chain(&e.periodic_cos)
            .zip(f.periodic_sin.iter().chain(&f.periodic_cos))
        {
            assert!((x - y).abs() < ROUND_TRIP_TOL);
        }
        for (x, y) in e.origin_xyz.iter().zip(&f.origin_xyz) {
            assert!((x - y).amax() < ROUND_TRIP_TOL);
        }
        assert!((e.mount_rpy - f.mount_rpy).amax() < ROUND_TRIP_TOL);
        assert_eq!(e.joint_scale, f.joint_scale);
    }
    assert!((a.noise.alignment_m - b.noise.alignment_m).amax() < ROUND_TRIP_TOL);
    assert!((a.noise.repeatability_m - b.noise.repeatability_m).abs() < ROUND_TRIP_TOL);
    assert!(
        (a.noise.encoder_resolution_rad - b.noise.encoder_resolution_rad).abs() < ROUND_TRIP_TOL
    );
    assert!((a.centre_b1 - b.centre_b1).amax() < ROUND_TRIP_TOL);
}

#[test]
fn shipped_cells_parse_and_round_trip() {
    for cell in [
        Cell::default_floor_floor(),
        Cell::default_floor_wall(),
        Cell::default_floor_ceiling(),
    ] {
        let text = cell.to_toml_string();
        let back = Cell::from_toml_str(&text, &cell.base_dir).unwrap();
        assert_cells_equal(&cell, &back);
    }
}

/// `[robotN.tools]`: parsed in mm, looked up by name (`tip` = index 0), written back; the
/// reserved name and a tip written in metres are refused with the key named.
#[test]
fn tools_table_parses_round_trips_and_names_errors() {
    let text = FLOOR_WALL_TOML.to_string()
        + "\n[robot1.tools]\nreflector = [41.79, -16.69, 245.0]\nprobe = [0, 0, 80]\n";
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    let cell = Cell::from_toml_str(&text, &dir).unwrap();
    let r = &cell.robot1;
    assert_eq!(r.tool_names(), ["tip", "probe", "reflector"]);
    assert_eq!(r.tool_index("reflector"), Some(2));
    assert_eq!(r.tool_index("tip"), Some(0));
    assert_eq!(r.tool_index("laser"), None);
    let reflector = r.flange_from_tool(2).unwrap();
    assert!((reflector - Vector3::new(0.04179, -0.01669, 0.245)).amax() < ROUND_TRIP_TOL);
    assert!(cell.robot2.tools.is_empty());
    let back = Cell::from_toml_str(&cell.to_toml_string(), &dir).unwrap();
    assert_eq!(back.robot1.tools, cell.robot1.tools);
    for (bad, want) in [
        ("tip = [0, 0, 10]", "robot1.tools.tip"),
        ("reflector = [0, 0, 0.245]", "robot1.tools.reflector"),
    ] {
        let text = FLOOR_WALL_TOML.to_string() + "\n[robot1.tools]\n" + bad + "\n";
        let e = Cell::from_toml_str(&text, &dir).unwrap_err().to_string();
        assert!(e.contains(want), "{e}");
    }
}

#[test]
fn errors_and_anisotropic_noise_round_trip() {
    let text = FLOOR_WALL_TOML.to_string()
        + r#"
[robot2.errors]
joint_offset_deg = [0.01, -0.02, 0.0, 0.0, 0.03, 0.0]
joint_scale = [0.0, 1e-4, 0.0, 0.0, 0.0, 0.0]
origin_xyz_mm = [[0.1, 0, 0], [0, 0, 0], [0, -0.2, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]]
mount_rpy_deg = [0.01, 0.0, 0.02]
compliance_deg_per_knm = [0.0, 0.05, 0.05, 0.0, 0.0, 0.0]
periodic_sin_deg = [0.0, 0.0, 0.01, 0.0, 0.0, 0.0]
periodic_cos_deg = [0.0, 0.0, -0.02, 0.0, 0.0, 0.0]
"#;
    let text = text.replace("alignment_mm = 0.3", "alignment_mm = [0.3, 0.5, 0.2]");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    let cell = Cell::from_toml_str(&text, &dir).unwrap();
    assert!((cell.robot2.errors.joint_offset[1] - (-0.02f64).to_radians()).abs() < 1e-15);
    assert!((cell.robot2.errors.compliance[1] - 0.05f64.to_radians() / 1000.0).abs() < 1e-18);
    assert!((cell.robot2.errors.periodic_sin[2] - 0.01f64.to_radians()).abs() < 1e-15);
    assert!((cell.robot2.errors.periodic_cos[2] - (-0.02f64).to_radians()).abs() < 1e-15);
    assert!(cell.to_toml_string().contains("periodic_cos_deg"));
    assert!((cell.noise.alignment_m.y - 0.5e-3).abs() < 1e-15);
    let back = Cell::from_toml_str(&cell.to_toml_string(), &dir).unwrap();
    assert_cells_equal(&cell, &back);
}

#[test]
fn gravity_of_robot2_follows_the_placement() {
    let ff = Cell::default_floor_floor();
    assert!((ff.robot1.g_base - Vector3::new(0.0, 0.0, -G)).norm() < 1e-12);
    assert!(ff.robot2.g_base.z < -0.9999 * G);
    let fc = Cell::default_floor_ceiling();
    assert!(fc.robot2.g_base.z > 0.9999 * G);
    let fw = Cell::default_floor_wall();
    assert!(fw.robot2.g_base.z.abs() < 0.01 * G);
    assert!((fw.robot2.g_base.norm() - G).abs() < 1e-9);
}

/// `tip_mm = [0, 0, 0.15]` (metres written as mm): refused with the unit and the fix named; a
/// zero tip (the flange) and a 1 mm tip still load.
#[test]
fn tip_mm_of_0_15() {
    let text = FLOOR_WALL_TOML.replacen("tip_mm = [0.0, 0.0, 150.0]", "tip_mm = [0, 0, 0.15]", 1);
    assert_ne!(text, FLOOR_WALL_TOML);
    let e = err_text(&text);
    assert!(
        e.contains("robot1.tip_mm")
            && e.contains("0.15 mm long")
            && e.contains("metres")
            && e.contains("[0.0, 0.0, 150.0]"),
        "{e}"
    );
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    for ok in ["tip_mm = [0, 0, 0]", "tip_mm = [0, 0, 1.0]"] {
        let text = FLOOR_WALL_TOML.replacen("tip_mm = [0.0, 0.0, 150.0]", ok, 1);
        Cell::from_toml_str(&text, &dir).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
}

fn err_text(text: &str) -> String {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    Cell::from_toml_str(text, &dir).unwrap_err().to_string()
}

#[test]
fn unknown_key_is_named() {
    let e = err_text(&FLOOR_WALL_TOML.replace("tip_mm", "tip_mmm"));
    assert!(e.contains("tip_mmm") && e.contains("tip_mm"), "{e}");
    let e = err_text(
        &(FLOOR_WALL_TOML.to_string() + "\n[robot2.errors]\njoint_ofset_deg = [0,0,0,0,0,0]\n"),
    );
    assert!(
        e.contains("joint_ofset_deg") && e.contains("joint_offset_deg"),
        "{e}"
    );
}

#[test]
fn missing_urdf_is_named() {
    let e = err_text(&FLOOR_WALL_TOML.replace("../robots/hp20.urdf", "../robots/nope.urdf"));
    assert!(e.contains("robot2.urdf") && e.contains("nope.urdf"), "{e}");
}

#[test]
fn impossible_mount_is_named_with_the_fix() {
    let e = err_text(&FLOOR_WALL_TOML.replace("mount = \"wall\"", "mount = \"ceiling\""));
    assert!(e.contains("robot2.mount") && e.contains("\"wall\""), "{e}");
    let e = err_text(&FLOOR_WALL_TOML.replace("mount = \"floor\"", "mount = \"wall\""));
    assert!(e.contains("robot1.mount"), "{e}");
    let e = err_text(&FLOOR_WALL_TOML.replace("mount = \"wall\"", "mount = \"roof\""));
    assert!(e.contains("robot2.mount") && e.contains("ceiling"), "{e}");
}

#[test]
fn wrong_error_length_is_named() {
    let e = err_text(
        &(FLOOR_WALL_TOML.to_string() + "\n[robot1.errors]\njoint_offset_deg = [0.0, 0.1]\n"),
    );
    assert!(
        e.contains("robot1.errors.joint_offset_deg") && e.contains("7 joints"),
        "{e}"
    );
}

mod tolerance_tests {
    use super::*;

    fn err_text(text: &str) -> String {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
        Cell::from_toml_str(text, &dir).unwrap_err().to_string()
    }

    /// Round-off of the mm/degree → SI → mm/degree round trip of a tolerance (tidy_floats keeps
    /// 10 decimals of mm/deg: 1e-13 m, 1e-12 rad).
    const TOLERANCE_TOL: f64 = 1e-12;

    #[test]
    fn tolerance_table_is_optional_parsed_and_round_trips() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
        let plain = Cell::from_toml_str(FLOOR_FLOOR_TOML, &dir).unwrap();
        assert_eq!(plain.robot1.tolerance, Tolerance::default());
        assert_eq!(plain.robot2.tolerance, Tolerance::default());
        let text = FLOOR_FLOOR_TOML.to_string()
            + "\n[robot2.tolerance]\njoint_offset_deg = 0.1\norigin_mm = 0.2\ntip_mm = 0\n";
        let cell = Cell::from_toml_str(&text, &dir).unwrap();
        let t = cell.robot2.tolerance;
        assert!((t.joint_offset_rad - 0.1f64.to_radians()).abs() < TOLERANCE_TOL);
        assert!((t.origin_xyz_m - 0.2e-3).abs() < TOLERANCE_TOL);
        assert_eq!(t.origin_rpy_rad, Tolerance::default().origin_rpy_rad);
        assert_eq!(t.tip_m, 0.0);
        assert_eq!(cell.robot1.tolerance, Tolerance::default());
        let back = Cell::from_toml_str(&cell.to_toml_string(), &dir).unwrap();
        let b = back.robot2.tolerance;
        assert!((b.joint_offset_rad - t.joint_offset_rad).abs() < TOLERANCE_TOL);
        assert!((b.origin_xyz_m - t.origin_xyz_m).abs() < TOLERANCE_TOL);
        assert!((b.origin_rpy_rad - t.origin_rpy_rad).abs() < TOLERANCE_TOL);
        assert_eq!(b.tip_m, 0.0);
        // The default is not written: a cell without the table round-trips without one.
        assert!(!plain.to_toml_string().contains("tolerance"));
    }

    #[test]
    fn bad_tolerance_key_or_value_is_named() {
        let bad_key = FLOOR_FLOOR_TOML.to_string() + "\n[robot1.tolerance]\noffset_deg = 0.1\n";
        let e = err_text(&bad_key);
        assert!(e.contains("offset_deg"), "{e}");
        for valid in [
            "joint_offset_deg",
            "origin_mm",
            "origin_deg",
            "tip_mm",
            "joint_scale",
            "periodic_deg",
        ] {
            assert!(e.contains(valid), "{e}");
        }
        let negative = FLOOR_FLOOR_TOML.to_string() + "\n[robot2.tolerance]\norigin_mm = -1.0\n";
        let e = err_text(&negative);
        assert!(e.contains("robot2.tolerance.origin_mm"), "{e}");
        let negative = FLOOR_FLOOR_TOML.to_string() + "\n[robot1.tolerance]\njoint_scale = -0.01\n";
        let e = err_text(&negative);
        assert!(e.contains("robot1.tolerance.joint_scale"), "{e}");
    }

    /// The optional families: `joint_scale` (a ratio) and `periodic_deg` are fitted when given
    /// and > 0, not fitted (`None`) when absent or 0, and round-trip through the cell text.
    #[test]
    fn joint_scale_and_periodic_tolerances_parse_and_round_trip() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
        let text = FLOOR_FLOOR_TOML.to_string()
            + "\n[robot1.tolerance]\njoint_scale = 0.002\nperiodic_deg = 0.03\n\
               [robot2.tolerance]\njoint_scale = 0\n";
        let cell = Cell::from_toml_str(&text, &dir).unwrap();
        let t = cell.robot1.tolerance;
        assert_eq!(t.joint_scale, Some(0.002));
        assert!((t.periodic_rad.unwrap() - 0.03f64.to_radians()).abs() < TOLERANCE_TOL);
        assert_eq!(t.joint_offset_rad, Tolerance::default().joint_offset_rad);
        assert_eq!(cell.robot2.tolerance, Tolerance::default());
        let back = Cell::from_toml_str(&cell.to_toml_string(), &dir).unwrap();
        let b = back.robot1.tolerance;
        assert!((b.joint_scale.unwrap() - 0.002).abs() < TOLERANCE_TOL);
        assert!((b.periodic_rad.unwrap() - t.periodic_rad.unwrap()).abs() < TOLERANCE_TOL);
        assert_eq!(back.robot2.tolerance, Tolerance::default());
    }

    /// `FLOOR_FLOOR_TOML` with `lines` added to its `[b1_from_b2]` table.
    fn with_placement_sigma(lines: &str) -> String {
        FLOOR_FLOOR_TOML.replacen("[b1_from_b2]", &format!("[b1_from_b2]\n{lines}"), 1)
    }

    #[test]
    fn placement_sigma_is_optional_parsed_and_round_trips() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
        let plain = Cell::from_toml_str(FLOOR_FLOOR_TOML, &dir).unwrap();
        assert_eq!(plain.b1_from_b2_sigma, None);
        assert!(!plain.to_toml_string().contains("sigma_mm"));
        let text = with_placement_sigma("sigma_mm = 0.01\nsigma_deg = 0.002");
        let cell = Cell::from_toml_str(&text, &dir).unwrap();
        let s = cell.b1_from_b2_sigma.unwrap();
        assert!((s.sigma_m - 0.01e-3).abs() < TOLERANCE_TOL);
        assert!((s.sigma_rad - 0.002f64.to_radians()).abs() < TOLERANCE_TOL);
        let back = Cell::from_toml_str(&cell.to_toml_string(), &dir).unwrap();
        assert!(back.b1_from_b2.rotation.angle_to(&cell.b1_from_b2.rotation) < TOLERANCE_TOL);
        let b = back.b1_from_b2_sigma.unwrap();
        assert!((b.sigma_m - s.sigma_m).abs() < TOLERANCE_TOL);
        assert!((b.sigma_rad - s.sigma_rad).abs() < TOLERANCE_TOL);
        // The shipped CTU cell states its placement.
        let ctu = Cell::from_toml_file(&dir.join("ctu-motoman.toml")).unwrap();
        assert!(ctu.b1_from_b2_sigma.is_some());
    }

    #[test]
    fn bad_placement_sigma_is_named() {
        let e = err_text(&with_placement_sigma("sigma_mm = -0.01\nsigma_deg = 0.001"));
        assert!(e.contains("b1_from_b2.sigma_mm"), "{e}");
        let e = err_text(&with_placement_sigma("sigma_mm = 0.01\nsigma_deg = nan"));
        assert!(e.contains("b1_from_b2.sigma_deg"), "{e}");
        let e = err_text(&with_placement_sigma("sigma_mm = 0.01"));
        assert!(e.contains("sigma_deg") && e.contains("both"), "{e}");
        let e = err_text(&with_placement_sigma("sigma_m = 0.01"));
        assert!(
            e.contains("sigma_m") && e.contains("sigma_mm, sigma_deg"),
            "{e}"
        );
    }
}

/// The rail fixture: the hp20 on a 4 m track, a prismatic first joint.
const RAIL: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../kinematics/tests/fixtures/rail_6r.urdf"
);

/// A one-robot cell on the rail, with `extra` appended (its errors, tolerance, …).
fn rail_cell(extra: &str) -> Result<Cell, FormatError> {
    Cell::from_toml_str(
        &format!("[robot1]\nurdf = \"{RAIL}\"\nmount = \"floor\"\ntip_mm = [0, 0, 150]\n{extra}"),
        Path::new("."),
    )
}

/// A robot with a prismatic joint loads (issue 22; before, it was refused until the files
/// described prismatic values): its offset is written in `joint_offset_mm` (mm), a rotary
/// joint's in `joint_offset_deg`, and both round-trip through the TOML.
#[test]
fn prismatic_offsets_round_trip_in_millimetres() {
    let cell = rail_cell(
        "[robot1.errors]\njoint_offset_deg = [0, 0.02, 0, 0, 0, 0, -0.01]\njoint_offset_mm = [1.5, 0, 0, 0, 0, 0, 0]\n",
    )
    .unwrap();
    assert!(cell.robot1.model.joints()[0].kind.is_prismatic());
    assert!((cell.robot1.errors.joint_offset[0] - 1.5e-3).abs() < ROUND_TRIP_TOL);
    assert!((cell.robot1.errors.joint_offset[1] - 0.02f64.to_radians()).abs() < ROUND_TRIP_TOL);
    let text = cell.to_toml_string();
    assert!(text.contains("joint_offset_mm = [1.5, 0.0"), "{text}");
    assert!(text.contains("joint_offset_deg = [0.0, 0.02"), "{text}");
    let back = Cell::from_toml_str(&text, Path::new(".")).unwrap();
    assert_cells_equal(&cell, &back);
}

/// Each per-joint array has one unit: an angle given at a prismatic joint, or a length at a
/// rotary one, is refused naming the joint and the key to use.
#[test]
fn a_value_in_the_wrong_units_array_is_refused_by_joint() {
    let e = rail_cell("[robot1.errors]\njoint_offset_deg = [0.5, 0, 0, 0, 0, 0, 0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("joint rail") && e.contains("joint_offset_mm"),
        "{e}"
    );
    let e = rail_cell("[robot1.errors]\njoint_offset_mm = [0, 2, 0, 0, 0, 0, 0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("entry 2") && e.contains("joint_offset_deg"),
        "{e}"
    );
    let e = rail_cell("[robot1.errors]\ncompliance_deg_per_knm = [1, 0, 0, 0, 0, 0, 0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("compliance_deg_per_knm") && e.contains("prismatic"),
        "{e}"
    );
}

const HUMANOID: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/humanoid.urdf");

/// The humanoid's right arm with `extra` appended (e.g. `[[robot1.couplings]]`).
fn humanoid_cell(extra: &str) -> Result<Cell, crate::FormatError> {
    Cell::from_toml_str(
        &format!(
            "[robot1]\nurdf = \"{HUMANOID}\"\ntool_link = \"right_tool0\"\nmount = \"floor\"\ntip_mm = [0, 0, 50]\n{extra}"
        ),
        Path::new("."),
    )
}

const TORSO_4: &str = "[[robot1.couplings]]\njoint = \"torso_4\"\nterms = [{ joint = \"torso_1\", c = -1.0 }, { joint = \"torso_2\", c = -1.0 }]\noffset_deg = 0.5\n";

/// A URDF `<mimic>` is accepted: the coupled joint takes no session column, its errors one
/// entry (chain order).
#[test]
fn a_mimic_joint_is_accepted_in_a_cell() {
    let mimic = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../kinematics/tests/fixtures/mimic_on_chain.urdf"
    );
    let cell = Cell::from_toml_str(
        &format!("[robot1]\nurdf = \"{mimic}\"\nmount = \"floor\"\ntip_mm = [0, 0, 150]\n[robot1.errors]\njoint_offset_deg = [0, 0, 0.1]\n"),
        Path::new("."),
    )
    .unwrap();
    assert_eq!(cell.robot1.model.dof(), 2);
    assert_eq!(cell.robot1.errors.joint_offset.len(), 3);
    assert!((cell.robot1.errors.joint_offset[2] - 0.1f64.to_radians()).abs() < 1e-15);
    // The URDF's mimic is not written into the cell (the URDF keeps it).
    assert!(!cell.to_toml_string().contains("couplings"));
}

/// A cell's `[[robotN.couplings]]`: `q_k = Σ c_i·q_i + c_0` in degrees, one session column fewer,
/// `[robotN.errors]` over every chain joint, written back as declared.
#[test]
fn declared_coupling_parses_and_round_trips() {
    let cell = humanoid_cell(&format!(
        "{TORSO_4}[robot1.errors]\njoint_offset_deg = [0, 0, 0, 0.08, 0, 0, 0, 0, 0, 0, 0]\n"
    ))
    .unwrap();
    let m = &cell.robot1.model;
    assert_eq!((m.dof(), m.chain_joints().len()), (10, 11));
    let chain = m
        .chain_values(&[0.1, 0.2, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
        .unwrap();
    assert!((chain[3] - (-0.3 + 0.5f64.to_radians())).abs() < 1e-15);
    assert!((cell.robot1.errors.joint_offset[3] - 0.08f64.to_radians()).abs() < 1e-15);
    let text = cell.to_toml_string();
    assert!(text.contains("torso_4"), "{text}");
    let back = Cell::from_toml_str(&text, Path::new(".")).unwrap();
    assert_eq!(back.robot1.model.couplings(), m.couplings());
    assert_cells_equal(&cell, &back);
    // Errors sized for the independent joints only are refused, saying coupled joints count.
    let e = humanoid_cell(&format!(
        "{TORSO_4}[robot1.errors]\njoint_scale = [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("11 joints") && e.contains("coupled joints included"),
        "{e}"
    );
}

/// Malformed couplings are refused naming the entry, the joint and the fix: an unknown joint, a
/// loop, a joint coupled twice, no terms, an offset in the wrong unit.
#[test]
fn malformed_couplings_are_refused_by_name() {
    let c = |joint: &str, terms: &str| {
        format!("[[robot1.couplings]]\njoint = \"{joint}\"\nterms = [{terms}]\n")
    };
    let cases = [
        (
            c("torso_4", "{ joint = \"torso_9\", c = 1.0 }"),
            vec!["torso_9", "not a moving joint"],
        ),
        (
            c("torso_9", "{ joint = \"torso_1\", c = 1.0 }"),
            vec!["torso_9", "not a moving joint"],
        ),
        (
            c("torso_4", "{ joint = \"torso_2\", c = 1.0 }")
                + &c("torso_2", "{ joint = \"torso_4\", c = 1.0 }"),
            vec!["loop", "torso_2", "torso_4"],
        ),
        (
            c("torso_4", "{ joint = \"torso_2\", c = 1.0 }")
                + &c("torso_4", "{ joint = \"torso_1\", c = 1.0 }"),
            vec!["coupled twice"],
        ),
        (c("torso_4", ""), vec!["entry 1", "no terms"]),
        (
            c("torso_4", "{ joint = \"torso_2\", c = 1.0 }") + "offset_mm = 1.0\n",
            vec!["rotary", "offset_deg"],
        ),
        (
            c("torso_4", "{ joint = \"torso_2\", k = 1.0 }"),
            vec!["unknown field", "k"],
        ),
    ];
    for (extra, want) in cases {
        let e = humanoid_cell(&extra).unwrap_err().to_string();
        for w in want {
            assert!(e.contains(w), "{extra}: `{w}` not in: {e}");
        }
    }
}

/// A cell with `[robot1]` only is a one-robot cell: robot 2 is a stand-in held at nominal, the
/// placement the identity under a tight prior, and the TOML written back has no `[robot2]` or
/// `[b1_from_b2]`.
#[test]
fn one_robot_cell_parses_and_round_trips_without_robot2() {
    let cell = rail_cell("[robot1.tools]\nreflector = [0, 60, 80]\n").unwrap();
    assert!(cell.one_robot && !cell.has_robot2());
    assert_eq!(cell.robots(), &[Robot::One]);
    assert_eq!(cell.robot2.tolerance, Tolerance::none());
    assert!(cell.robot2.tools.is_empty());
    assert_eq!(cell.b1_from_b2, Isometry3::identity());
    assert_eq!(cell.b1_from_b2_sigma, Some(ONE_ROBOT_PLACEMENT_SIGMA));
    let text = cell.to_toml_string();
    assert!(
        !text.contains("robot2") && !text.contains("b1_from_b2"),
        "{text}"
    );
    let back = Cell::from_toml_str(&text, Path::new(".")).unwrap();
    assert!(back.one_robot);
    assert_cells_equal(&cell, &back);
    // Two-robot cells are unchanged.
    assert!(Cell::default_floor_wall().has_robot2());
}

/// Half a cell is refused saying which half is missing.
#[test]
fn placement_without_robot2_and_robot2_without_placement_are_refused() {
    let e = rail_cell("[b1_from_b2]\nxyz_mm = [0, 0, 0]\nzyz_deg = [0, 0, 0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("without `[robot2]`") && e.contains("one-robot cell"),
        "{e}"
    );
    let e = rail_cell(&format!(
        "[robot2]\nurdf = \"{RAIL}\"\nmount = \"floor\"\ntip_mm = [0, 0, 150]\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("without `[b1_from_b2]`"), "{e}");
}

/// The shipped shared-trunk cell with its `[robot2]` table's `shares` line replaced by `shares`
/// and `extra` appended.
fn trunk_cell(shares: &str, extra: &str) -> Result<Cell, crate::FormatError> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/humanoid-trunk.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let line = text
        .lines()
        .find(|l| l.starts_with("shares ="))
        .expect("a shares line");
    Cell::from_toml_str(
        &format!("{}{extra}", text.replace(line, shares)),
        path.parent().unwrap(),
    )
}

/// `[robot2] shares`: by joint count or branch link; robot 2's trunk errors become robot 1's,
/// the placement is the identity held tight, and the cell round-trips without `[b1_from_b2]`.
#[test]
fn shared_trunk_parses_and_round_trips() {
    let by_link = trunk_cell("shares = { robot = 1, link = \"chest\" }", "").unwrap();
    let by_count = trunk_cell("shares = { robot = 1, joints = 4 }", "").unwrap();
    assert_eq!((by_link.shared_joints, by_count.shared_joints), (4, 4));
    assert_eq!(by_link.shared_independent_joints(), 3);
    assert_eq!(by_link.b1_from_b2, Isometry3::identity());
    assert_eq!(by_link.b1_from_b2_sigma, Some(SHARED_TRUNK_PLACEMENT_SIGMA));
    let (e1, e2) = (&by_link.robot1.errors, &by_link.robot2.errors);
    assert_eq!(e1.joint_offset[..4], e2.joint_offset[..4]);
    assert_eq!(e1.origin_xyz[..4], e2.origin_xyz[..4]);
    assert_ne!(e1.joint_offset[5], e2.joint_offset[5]);
    let text = by_link.to_toml_string();
    assert!(
        !text.contains("b1_from_b2") && text.contains("joints = 4"),
        "{text}"
    );
    let back = Cell::from_toml_str(&text, &by_link.base_dir).unwrap();
    assert_eq!(back.shared_joints, 4);
    assert_cells_equal(&by_link, &back);
}

/// A shared trunk that is not one is refused naming what differs and the fix.
#[test]
fn malformed_shared_trunks_are_refused_by_name() {
    let placement = "[b1_from_b2]\nxyz_mm = [0, 0, 0]\nzyz_deg = [0, 0, 0]\n";
    let cases: [(&str, &str, &[&str]); 5] = [
        (
            "shares = { robot = 1, joints = 4 }",
            placement,
            &["[b1_from_b2]", "trunk", "remove"],
        ),
        (
            "shares = { robot = 1, link = \"spine\" }",
            "",
            &["spine", "chest"],
        ),
        ("shares = { robot = 1, joints = 11 }", "", &["1 to 10"]),
        ("shares = { robot = 2, joints = 4 }", "", &["robot = 1"]),
        (
            "shares = { robot = 1, joints = 6 }",
            "",
            &[
                "shared joint 5",
                "right_shoulder_pitch",
                "left_shoulder_pitch",
            ],
        ),
    ];
    for (shares, extra, want) in cases {
        let e = trunk_cell(shares, extra).unwrap_err().to_string();
        for w in want {
            assert!(e.contains(w), "{shares}: `{w}` not in: {e}");
        }
    }
    // Coupling a shared joint in only one arm.
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/humanoid-trunk.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let r2 = text.find("[[robot2.couplings]]").unwrap();
    let end = text[r2..].find("offset_deg = 0.0\n").unwrap() + r2 + "offset_deg = 0.0\n".len();
    let e = Cell::from_toml_str(
        &format!("{}{}", &text[..r2], &text[end..]),
        path.parent().unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("torso_4") && e.contains("in robot 1's chain and not in robot 2's"),
        "{e}"
    );
    // Robot 2's own (different) error at a shared joint.
    let e = Cell::from_toml_str(
        &text.replace(
            "joint_offset_deg = [0.0, 0.0, 0.0, 0.0, 0.0, -0.03",
            "joint_offset_deg = [0.1, 0.0, 0.0, 0.0, 0.0, -0.03",
        ),
        path.parent().unwrap(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("torso_1") && e.contains("differs from robot 1's"),
        "{e}"
    );
}

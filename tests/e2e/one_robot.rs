//! One-robot cells (a file with `[robot1]` only) and prismatic joints through the files (issue
//! 22, items 6 and 0): a robot on a linear track measured by a tracker, simulated, calibrated,
//! exported and scored on held-out poses as a new user would run it; the commands' refusals of
//! what needs two robots; and FIGAROH's TIAGo (a prismatic torso) when its data are present.

use std::path::{Path, PathBuf};

use handclasp_cell::{Cell, Session};
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::support::{
    handclasp, shared_data_or_skip, shipped_cell, stderr_of_failure, stdout_json, workspace,
    write_session_csv,
};

/// The true errors of the simulated rail robot: the rail's zero 1.5 mm off (a prismatic offset,
/// written in mm), joint offsets of a few hundredths of a degree and origins off by tenths of a
/// millimetre: within a few times the cell's default tolerances (0.05°, 0.5 mm).
const RAIL_TRUTH_ERRORS: &str = "
[robot1.errors]
joint_offset_deg = [0.0, 0.03, -0.04, 0.02, 0.0, 0.03, -0.02]
joint_offset_mm = [1.5, 0, 0, 0, 0, 0, 0]
origin_xyz_mm = [[0.2, -0.3, 0.1], [0, 0.3, 0], [0.2, 0, -0.3], [0, 0, 0.2], [0.3, 0, 0], [0, -0.2, 0], [0.1, 0, 0]]
";

/// The tracker's σ per axis in the simulation, m (sim-cell's default, a laser tracker).
const TRACKER_SIGMA_M: f64 = 0.05e-3;

/// The shipped one-robot cell `cells/rail-tracker.toml` (the nominal robot).
fn rail_cell_path() -> PathBuf {
    shipped_cell("rail-tracker")
}

/// The rail cell with [`RAIL_TRUTH_ERRORS`]: the simulation's truth.
fn rail_truth() -> Cell {
    let text = std::fs::read_to_string(rail_cell_path()).expect("rail cell");
    Cell::from_toml_str(&format!("{text}{RAIL_TRUTH_ERRORS}"), &workspace("cells")).expect("truth")
}

/// `n` tracker rows of the reflector of `truth`'s robot at random poses about the teach centre
/// (a cube of 1.2 m), seeded; each session has its own tracker frame.
fn tracker_session(truth: &Cell, n: usize, seed: u64) -> Session {
    let spec = SessionSpec::new(n, Layout::Random, 1.2);
    let kinds = KindSpec {
        kind: SimKind::Tracker,
        tracker_tool: "reflector".into(),
        tracker_sigma_m: TRACKER_SIGMA_M,
        ..KindSpec::default()
    };
    generate_kind_session(truth, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .expect("the rail robot reaches its teach points")
        .0
}

/// A training session of 60 rows and a held-out one of 40 of `truth`'s robot (seeds `seed` and
/// `seed + 1`), written as `train.csv` and `held.csv` in `dir` for the `nominal` cell.
fn train_and_held(dir: &Path, truth: &Cell, nominal: &Cell, seed: u64) -> (PathBuf, PathBuf) {
    let write = |name: &str, n: usize, s: u64| {
        write_session_csv(dir, name, &tracker_session(truth, n, s), nominal)
    };
    (
        write("train.csv", 60, seed),
        write("held.csv", 40, seed + 1),
    )
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

/// Recovery on a simulated robot with a linear axis: a 60-row tracker session of the rail robot
/// (its rail 1.5 mm off, its arm off by tenths of a mm and hundredths of a degree) calibrated as
/// a one-robot cell, exported (robot 1's URDF and a cell with no `[robot2]`), then scored by
/// `handclasp validate` on 40 new poses with their own tracker frame: the calibrated cell's
/// held-out rms is near the tracker's own noise, the nominal's is not.
#[test]
fn rail_robot_one_robot_cell_is_calibrated_to_its_noise_on_new_poses() {
    let dir = tempfile::tempdir().unwrap();
    let truth = rail_truth();
    let nominal = Cell::from_toml_file(&rail_cell_path()).expect("rail cell loads");
    assert!(nominal.one_robot && truth.robot1.model.joints()[0].kind.is_prismatic());
    let (train, held) = train_and_held(dir.path(), &truth, &nominal, 21);
    let header = std::fs::read_to_string(&train).unwrap();
    let header = header.lines().next().unwrap();
    assert!(header.starts_with("point,r1_q1_mm,r1_q2_deg"), "{header}");
    assert!(!header.contains("r2_"), "{header}");

    let cal = dir.path().join("cal");
    let out = handclasp(&[
        "calibrate",
        "--cell",
        &arg(&rail_cell_path()),
        "--session",
        &arg(&train),
        "--export",
        &arg(&cal),
        "--json",
    ]);
    let report = stdout_json(&out);
    assert_eq!(report["one_robot"], true);
    let robots: Vec<u64> = report["coverage"]["robots"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["robot"].as_u64().unwrap())
        .collect();
    assert_eq!(robots, [1], "the coverage of a one-robot cell is robot 1's");
    let text = handclasp(&[
        "calibrate",
        "--cell",
        &arg(&rail_cell_path()),
        "--session",
        &arg(&train),
    ]);
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("one-robot cell: no placement"), "{text}");
    // Worded for one robot: what a tracker cannot tell from the robot's base is confounded with
    // the tracker frame, never with a placement the cell does not have.
    assert!(
        text.contains("confounded with the tracker/plane unknowns") && !text.contains("b1_from_b2"),
        "{text}"
    );
    // --accept-deg judges a placement rotation, which a one-robot cell has not: refused up
    // front, saying why and what to use.
    let e = stderr_of_failure(&[
        "calibrate",
        "--cell",
        &arg(&rail_cell_path()),
        "--session",
        &arg(&train),
        "--accept-mm",
        "1",
        "--accept-deg",
        "0.1",
    ]);
    assert!(
        e.contains("--accept-deg")
            && e.contains("one-robot cell")
            && e.contains("no placement")
            && e.contains("--accept-mm"),
        "{e}"
    );
    assert!(
        !text.contains("b1_from_b2:") && !text.contains("robot 2 ("),
        "{text}"
    );
    assert!(cal.join("robot1.urdf").is_file() && !cal.join("robot2.urdf").exists());
    let exported = std::fs::read_to_string(cal.join("cell.toml")).unwrap();
    // (The file's header comment names the keys of two-robot cells; no table is written.)
    assert!(
        !exported
            .lines()
            .any(|l| l.starts_with("[robot2") || l.starts_with("[b1_from_b2]")),
        "{exported}"
    );

    let (calibrated, nominal_rms) =
        crate::support::validate_rms_mm(&cal.join("cell.toml"), &held, &rail_cell_path());
    // The tracker's own 3-D rms is σ·√3 = 0.087 mm; the held-out score adds the tracker frame
    // refitted on half the rows and the fit's own error at new poses. Twice the noise is a
    // calibration that recovered the robot; the nominal robot (1.5 mm on the rail, which the
    // tracker frame absorbs, and the arm's errors, which it cannot) is several times that.
    let noise_3d_mm = TRACKER_SIGMA_M * 3f64.sqrt() * 1e3;
    eprintln!(
        "rail robot, 40 held-out tracker rows: calibrated rms {calibrated:.3} mm, nominal {nominal_rms:.3} mm (noise {noise_3d_mm:.3} mm)"
    );
    assert!(
        calibrated < 2.0 * noise_3d_mm,
        "calibrated held-out rms {calibrated:.3} mm vs noise {noise_3d_mm:.3} mm"
    );
    assert!(
        nominal_rms > 3.0 * calibrated,
        "nominal {nominal_rms:.3} mm vs calibrated {calibrated:.3} mm"
    );
}

/// The rail reading's scale in the simulation's truth (0.2 %: 2 mm per metre of travel).
const RAIL_TRUE_SCALE: f64 = 0.002;

/// How far the fitted scale may sit from the truth, in posterior σ.
const SCALE_RECOVERY_SIGMAS: f64 = 3.0;

/// An encoder scale as a fitted family (`[robotN.tolerance] joint_scale`): the rail robot with a
/// 0.2 % rail scale on top of [`RAIL_TRUTH_ERRORS`], calibrated from 60 tracker rows with and
/// without the `joint_scale` tolerance. With it, the rail's fitted scale is within 3 posterior σ
/// of the truth and determined by the data, it is exported as `[robot1.errors] joint_scale`, and
/// the exported cell scores 40 new poses near the tracker's noise; without it, the same fit
/// cannot reach the noise.
#[test]
fn rail_scale_is_fitted_exported_and_applied_when_its_tolerance_is_given() {
    let dir = tempfile::tempdir().unwrap();
    let scale_line = format!("joint_scale = [{RAIL_TRUE_SCALE}, 0, 0, 0, 0, 0, 0]\n");
    let text = std::fs::read_to_string(rail_cell_path()).expect("rail cell");
    let truth = Cell::from_toml_str(
        &format!("{text}{RAIL_TRUTH_ERRORS}{scale_line}"),
        &workspace("cells"),
    )
    .expect("truth");
    let nominal = Cell::from_toml_file(&rail_cell_path()).expect("rail cell loads");
    let (train, held) = train_and_held(dir.path(), &truth, &nominal, 31);
    // The nominal cell with the scale family fitted (its URDF named absolutely: the file moves).
    let urdf = workspace("crates/kinematics/tests/fixtures/rail_6r.urdf");
    let with_scale = dir.path().join("rail-scale.toml");
    let scaled_text = text.replace(
        "../crates/kinematics/tests/fixtures/rail_6r.urdf",
        &arg(&urdf),
    ) + "\n[robot1.tolerance]\njoint_scale = 0.005\n";
    std::fs::write(&with_scale, scaled_text).unwrap();
    let calibrate = |cell: &Path, name: &str| {
        let cal = dir.path().join(name);
        let report = stdout_json(&handclasp(&[
            "calibrate",
            "--cell",
            &arg(cell),
            "--session",
            &arg(&train),
            "--export",
            &arg(&cal),
            "--json",
        ]));
        let v = stdout_json(&handclasp(&[
            "validate",
            "--cell",
            &arg(&cal.join("cell.toml")),
            "--session",
            &arg(&held),
            "--json",
        ]));
        (
            report,
            cal,
            v["all"]["calibrated"]["rms_mm"].as_f64().unwrap(),
        )
    };
    let (report, cal, scaled_rms) = calibrate(&with_scale, "cal-scale");
    let (_, _, plain_rms) = calibrate(&rail_cell_path(), "cal-plain");
    let rail_scale = report["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "robot 1 joint_scale joint 1")
        .expect("the rail's scale is fitted");
    let (value, sigma) = (
        rail_scale["value"].as_f64().unwrap(),
        rail_scale["sigma"].as_f64().unwrap(),
    );
    assert!(
        (value - RAIL_TRUE_SCALE).abs() < SCALE_RECOVERY_SIGMAS * sigma,
        "fitted rail scale {value:.6} ± {sigma:.6}, truth {RAIL_TRUE_SCALE}"
    );
    assert!(
        sigma < 0.1 * RAIL_TRUE_SCALE,
        "σ {sigma} is not determined by the data"
    );
    let exported = Cell::from_toml_file(&cal.join("cell.toml")).expect("exported cell loads");
    // The file keeps 10 decimals.
    assert!(
        (exported.robot1.errors.joint_scale[0] - value).abs() < 1e-9,
        "exported {} vs fitted {value}",
        exported.robot1.errors.joint_scale[0]
    );
    let noise_3d_mm = TRACKER_SIGMA_M * 3f64.sqrt() * 1e3;
    eprintln!(
        "rail scale {value:.6} ± {sigma:.6} (truth {RAIL_TRUE_SCALE}); 40 held-out rows: with the \
         scale family {scaled_rms:.3} mm, without {plain_rms:.3} mm (noise {noise_3d_mm:.3} mm)"
    );
    assert!(
        scaled_rms < 2.0 * noise_3d_mm,
        "with the scale family: {scaled_rms:.3} mm vs noise {noise_3d_mm:.3} mm"
    );
    assert!(
        plain_rms > 2.0 * noise_3d_mm,
        "without the scale family: {plain_rms:.3} mm vs noise {noise_3d_mm:.3} mm"
    );
}

/// What needs two robots is refused by name on a one-robot cell: simulating handclasps,
/// planning handclasp poses, `fk --robot 2`, and a session without a `kind` column.
#[test]
fn one_robot_cell_refuses_what_needs_two_robots() {
    let dir = tempfile::tempdir().unwrap();
    let cell = Cell::from_toml_file(&rail_cell_path()).unwrap();
    let spec = SessionSpec::new(5, Layout::Random, 1.0);
    for kind in [SimKind::Coincident, SimKind::Contact, SimKind::Mixed] {
        let kinds = KindSpec {
            kind,
            ..KindSpec::default()
        };
        let e = generate_kind_session(&cell, &spec, &kinds, None, &mut trial_rng(1, 0))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("only [robot1]") && e.contains("--kind tracker"),
            "{e}"
        );
    }
    let cell_arg = arg(&rail_cell_path());
    let e = stderr_of_failure(&[
        "plan",
        "--cell",
        &cell_arg,
        "--n",
        "10",
        "--out",
        &arg(&dir.path().join("plan.csv")),
    ]);
    assert!(
        e.contains("only [robot1]") && e.contains("sim-cell session --kind tracker"),
        "{e}"
    );
    let e = stderr_of_failure(&[
        "fk",
        "--cell",
        &cell_arg,
        "--robot",
        "2",
        "--q-deg",
        "1000,0,0,0,0,0,0",
    ]);
    assert!(
        e.contains("one-robot cell") && e.contains("--robot 1"),
        "{e}"
    );
    // fk --cell --robot 1 takes the rail's value in mm: 1000 mm along the rail moves the flange
    // 1 m along the rail's axis (turned 0.2 rad about z).
    let at = |rail_mm: &str| {
        let v = stdout_json(&handclasp(&[
            "fk",
            "--cell",
            &cell_arg,
            "--robot",
            "1",
            "--q-deg",
            &format!("{rail_mm},0,0,0,0,0,0"),
            "--json",
        ]));
        crate::support::floats(&v["xyz_mm"])
    };
    let (a, b) = (at("0"), at("1000"));
    let moved = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    // The fixture's rail: axis x of a frame turned 0.2 rad about z. Round-off of the printed
    // pose is far below this 1 µm tolerance.
    let want = [1000.0 * 0.2f64.cos(), 1000.0 * 0.2f64.sin(), 0.0];
    for (m, w) in moved.iter().zip(want) {
        assert!((m - w).abs() < 1e-3, "moved {moved:?}, want {want:?}");
    }
    let handclasps = dir.path().join("handclasps.csv");
    std::fs::write(
        &handclasps,
        "point,r1_q1_mm,r1_q2_deg,r1_q3_deg,r1_q4_deg,r1_q5_deg,r1_q6_deg,r1_q7_deg,r1_x_mm,r1_y_mm,r1_z_mm\n1,1000,0,30,0,0,0,0,1,2,3\n",
    )
    .unwrap();
    let e = stderr_of_failure(&[
        "calibrate",
        "--cell",
        &cell_arg,
        "--session",
        &arg(&handclasps),
    ]);
    assert!(e.contains("only [robot1]") && e.contains("kind"), "{e}");
}

/// FIGAROH's TIAGo data (`../shared/data/figaroh-tiago/`, read in place): the URDF as shipped
/// (a prismatic torso lift), the training file's marker 1 imported with
/// `tools/figaroh-tiago/map_bl.toml` (one mocap frame), calibrated as the one-robot cell
/// `tools/figaroh-tiago/tiago.toml` (its tolerances, the torso's encoder scale among them, and
/// the rows fitted chosen by `tools/figaroh-tiago/cv.py` on the training file alone), and the validation file's marker 1 scored with the training
/// registration (`validate --nuisance fixed`). The kinematic fit must beat a registration-only
/// fit (placement model: the mocap frame and the four marker positions) on the held-out file.
#[test]
fn tiago_prismatic_torso_is_calibrated_as_a_one_robot_cell() {
    let Some(data) = shared_data_or_skip(
        "FIGAROH_TIAGO_DATA",
        "figaroh-tiago",
        "tiago_48_schunk.urdf",
        "FIGAROH's TIAGo data",
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // The repository's cell names the URDF relative to the main checkout; point it at the data
    // folder found.
    let template = std::fs::read_to_string(workspace("tools/figaroh-tiago/tiago.toml")).unwrap();
    let urdf = data.join("tiago_48_schunk.urdf");
    let text = template.replace(
        "../../../shared/data/figaroh-tiago/tiago_48_schunk.urdf",
        &arg(&urdf),
    );
    assert_ne!(text, template, "the cell names the shipped URDF");
    let cell = dir.path().join("tiago.toml");
    std::fs::write(&cell, text).unwrap();
    let import = |map: &str, file: &str, out: &Path| {
        let o = handclasp(&[
            "import",
            "--cell",
            &arg(&cell),
            "--map",
            &arg(&workspace(&format!("tools/figaroh-tiago/{map}"))),
            "--input",
            &arg(&data.join(file)),
            "--out",
            &arg(out),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let train = dir.path().join("train.csv");
    let held = dir.path().join("validation-bl.csv");
    // Marker 1's rows are fitted, as the protocol (tools/figaroh-tiago/protocol.py) fits them.
    import(
        "map_bl.toml",
        "qualisys_2021-11-30_static_postures.csv",
        &train,
    );
    import(
        "map_bl.toml",
        "qualisys_2021-11-26_static_postures.csv",
        &held,
    );
    // The registration-only comparator (FIGAROH's first row: the mocap frame and the marker
    // positions): the same cell with every kinematic tolerance 0, i.e. held at nominal.
    let registration_cell = dir.path().join("registration.toml");
    // (Every kinematic tolerance key of the cell dropped, then each family given as 0.)
    let registration_text: String = std::fs::read_to_string(&cell)
        .unwrap()
        .lines()
        .filter(|l| {
            !matches!(
                l.split(" = ").next(),
                Some("joint_offset_deg" | "origin_mm" | "origin_deg" | "joint_scale")
            )
        })
        .map(|l| match l {
            "[robot1.tolerance]" => format!(
                "{l}\njoint_offset_deg = 0.0\norigin_mm = 0.0\norigin_deg = 0.0\njoint_scale = 0.0\n"
            ),
            _ => format!("{l}\n"),
        })
        .collect();
    assert!(
        registration_text.contains("origin_mm = 0.0"),
        "{registration_text}"
    );
    std::fs::write(&registration_cell, registration_text).unwrap();
    let score = |cell: &Path, name: &str| {
        let cal = dir.path().join(name);
        let o = handclasp(&[
            "calibrate",
            "--cell",
            &arg(cell),
            "--session",
            &arg(&train),
            "--force",
            "--export",
            &arg(&cal),
        ]);
        assert!(
            cal.join("cell.toml").is_file(),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let v = stdout_json(&handclasp(&[
            "validate",
            "--cell",
            &arg(&cal.join("cell.toml")),
            "--session",
            &arg(&held),
            "--nuisance",
            "fixed",
            "--calibration-session",
            &arg(&train),
            "--json",
        ]));
        let all = &v["all"]["calibrated"];
        let (rms, whitened) = (
            all["rms_mm"].as_f64().unwrap(),
            all["whitened_rms"].as_f64().unwrap(),
        );
        // The published metric is the 3-D rms of point 1 in mm: `rms_mm` is ‖r‖'s rms, and the
        // whitened rms is per axis (map_bl.toml's σ is 1 mm), so they differ by √3 exactly.
        assert!(
            (rms - 3f64.sqrt() * whitened * MAP_SIGMA_MM).abs() < METRIC_REL * rms,
            "rms_mm {rms} is not the 3-D rms of the whitened per-axis {whitened}"
        );
        rms
    };
    // map_bl.toml's placeholder σ of every tracker row, mm.
    const MAP_SIGMA_MM: f64 = 1.0;
    // Relative round-off allowed between the two printed forms of the same rms.
    const METRIC_REL: f64 = 1e-9;
    let kinematic = score(&cell, "kinematic");
    let registration = score(&registration_cell, "registration");
    eprintln!(
        "TIAGo validation file, marker 1: kinematic {kinematic:.3} mm, registration only {registration:.3} mm"
    );
    assert!(
        kinematic < registration,
        "kinematic {kinematic:.3} mm vs registration only {registration:.3} mm"
    );
}

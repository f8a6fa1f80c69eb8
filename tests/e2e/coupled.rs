//! Coupled joints in cells (issue 22, item 2): the simulated humanoid of `cells/humanoid.toml`,
//! whose fourth torso joint follows the first two (`q4 = −(q1 + q2)`, declared in
//! `[[robotN.couplings]]`), simulated, calibrated, exported and scored on held-out poses as a new
//! user would run it.

use std::path::{Path, PathBuf};

use handclasp_cell::{Cell, Session};
use sim_cell::{generate_kind_session, trial_rng, KindSpec, Layout, SessionSpec, SimKind};

use crate::support::{handclasp, shipped_cell, stderr_of_failure, stdout_json, write_session_csv};

/// The camera's σ per axis in the simulation, m.
const TRACKER_SIGMA_M: f64 = 0.1e-3;

fn humanoid() -> PathBuf {
    shipped_cell("humanoid")
}

/// `n` tracker rows of both hands (robots alternate) at random poses about the teach centre (a
/// cube of 0.4 m), seeded; each session has its own tracker frame.
fn tracker_session(truth: &Cell, n: usize, seed: u64) -> Session {
    let spec = SessionSpec::new(n, Layout::Random, 0.4);
    let kinds = KindSpec {
        kind: SimKind::Tracker,
        tracker_sigma_m: TRACKER_SIGMA_M,
        ..KindSpec::default()
    };
    generate_kind_session(truth, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .expect("the humanoid's hands reach their teach points")
        .0
}

fn arg(p: &Path) -> String {
    p.display().to_string()
}

/// `handclasp validate` of the calibrated cell in `cal` on the `held` session against `nominal`:
/// the held-out rms is within twice the camera's 3-D noise (σ·√3; the score adds the tracker
/// frame refitted on half the rows and the fit's error at new poses), and the nominal cell's is
/// more than twice the calibrated one's. Prints both.
fn assert_held_out_near_noise(cal: &Path, held: &Path, nominal: &Path, what: &str) {
    assert_cell_held_out_near_noise(&cal.join("cell.toml"), held, nominal, what);
}

/// [`assert_held_out_near_noise`] of the calibrated cell file `cell` (any export's).
fn assert_cell_held_out_near_noise(cell: &Path, held: &Path, nominal: &Path, what: &str) {
    let (calibrated, nominal_rms) = crate::support::validate_rms_mm(cell, held, nominal);
    let noise_3d_mm = TRACKER_SIGMA_M * 3f64.sqrt() * 1e3;
    eprintln!(
        "humanoid ({what}), held-out rows: calibrated rms {calibrated:.3} mm, nominal {nominal_rms:.3} mm (noise {noise_3d_mm:.3} mm)"
    );
    assert!(
        calibrated < 2.0 * noise_3d_mm,
        "{what}: calibrated held-out rms {calibrated:.3} mm vs noise {noise_3d_mm:.3} mm"
    );
    assert!(
        nominal_rms > 2.0 * calibrated,
        "{what}: nominal {nominal_rms:.3} mm vs calibrated {calibrated:.3} mm"
    );
}

/// Recovery with a coupled joint: 80 tracker rows of the humanoid's hands (its errors, torso_4's
/// own offset and origin included, are the cell's `[robotN.errors]`), calibrated with
/// `calibrate --cell`, exported (the corrected URDFs and a cell that keeps the couplings), then
/// scored by `validate` on 40 new poses: the calibrated cell's held-out rms is near the camera's
/// noise, the nominal's is not. `fk --cell` on the export takes the 10 independent joints and
/// refuses 11 naming the coupled joint.
#[test]
fn coupled_torso_joint_is_calibrated_to_its_noise_on_new_poses() {
    let dir = tempfile::tempdir().unwrap();
    let truth = Cell::from_toml_file(&humanoid()).expect("humanoid cell");
    let (m1, m2) = (&truth.robot1.model, &truth.robot2.model);
    assert_eq!((m1.dof(), m1.chain_joints().len()), (10, 11));
    assert_eq!((m2.dof(), m2.chain_joints().len()), (10, 11));
    assert!(
        truth.robot1.errors.joint_offset[3] != 0.0,
        "torso_4 has its own offset"
    );
    let train = write_session_csv(
        dir.path(),
        "train.csv",
        &tracker_session(&truth, 80, 31),
        &truth,
    );
    let held = write_session_csv(
        dir.path(),
        "held.csv",
        &tracker_session(&truth, 40, 32),
        &truth,
    );
    let header = std::fs::read_to_string(&train).unwrap();
    let header = header.lines().next().unwrap();
    assert!(
        header.contains("r1_q10_deg") && !header.contains("r1_q11"),
        "{header}"
    );

    let cal = dir.path().join("cal");
    let report = stdout_json(&handclasp(&[
        "calibrate",
        "--cell",
        &arg(&humanoid()),
        "--session",
        &arg(&train),
        "--export",
        &arg(&cal),
        "--json",
    ]));
    assert!(report["b1_from_b2"].is_object(), "{report}");
    let exported = std::fs::read_to_string(cal.join("cell.toml")).unwrap();
    assert!(
        exported.contains("[[robot1.couplings]]") && exported.contains("[[robot2.couplings]]"),
        "{exported}"
    );
    let back = Cell::from_toml_file(&cal.join("cell.toml")).expect("the export loads");
    assert_eq!(back.robot1.model.couplings(), m1.couplings());

    assert_held_out_near_noise(&cal, &held, &humanoid(), "coupled torso_4");

    let cell = arg(&cal.join("cell.toml"));
    let fk = |q: &str| {
        [
            "fk", "--cell", &cell, "--robot", "2", "--q-deg", q, "--json",
        ]
        .map(String::from)
    };
    let ok = handclasp(&fk("10,5,20,-30,10,0,-60,0,20,0"));
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let e = stderr_of_failure(&fk("10,5,20,0,-30,10,0,-60,0,20,0"));
    assert!(e.contains("torso_4"), "{e}");
}

fn humanoid_trunk() -> PathBuf {
    shipped_cell("humanoid-trunk")
}

/// True if `text` names a parameter of robot 2 at chain joint 1 … 4 (the shared trunk's): each
/// name `robot 2 <kind> joint N[ axis]` is read up to its own end (a `:`, `,`, `(` or the line's
/// end), so a robot 1 joint named after it on the same line (a merge list:
/// `-1.000·robot 2 origin_xyz joint 6 y, +1.000·robot 1 origin_xyz joint 4 y`) is not taken
/// for robot 2's.
fn names_robot2_trunk_parameter(text: &str) -> bool {
    text.lines().any(|l| {
        l.match_indices("robot 2 ").any(|(at, _)| {
            let name = l[at..].split([':', ',', '(']).next().unwrap_or("");
            (1..=4).any(|j| {
                let key = format!(" joint {j}");
                name.split_once(&key).is_some_and(|(_, tail)| {
                    tail.chars().next().is_none_or(|c| !c.is_ascii_digit())
                })
            })
        })
    })
}

/// `handclasp calibrate --cell cells/humanoid-trunk.toml --session {train} --export {cal}`,
/// which must succeed; its standard output.
fn calibrate_trunk_export(train: &Path, cal: &Path) -> String {
    let out = handclasp(&[
        "calibrate",
        "--cell",
        &arg(&humanoid_trunk()),
        "--session",
        &arg(train),
        "--export",
        &arg(cal),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Recovery with a shared trunk (`[robot2] shares = { robot = 1, link = "chest" }`, a coupled
/// torso_4 in it): the trunk's parameters are fitted once (robot 1's; no robot 2 parameter at
/// the 4 trunk joints, no free placement), the export re-loads as a shared-trunk cell, the
/// held-out rms is near the camera's noise; a session the fit cannot use is refused by name.
#[test]
fn shared_trunk_is_fitted_once_and_calibrated_to_its_noise() {
    let dir = tempfile::tempdir().unwrap();
    let truth = Cell::from_toml_file(&humanoid_trunk()).expect("humanoid-trunk cell");
    assert_eq!(
        (truth.shared_joints, truth.shared_independent_joints()),
        (4, 3)
    );
    let train = write_session_csv(
        dir.path(),
        "train.csv",
        &tracker_session(&truth, 80, 41),
        &truth,
    );
    let held = write_session_csv(
        dir.path(),
        "held.csv",
        &tracker_session(&truth, 40, 42),
        &truth,
    );
    let cal = dir.path().join("cal");
    let text = calibrate_trunk_export(&train, &cal);
    assert!(text.contains("robot 1 origin_xyz joint 4"), "{text}");
    assert!(!names_robot2_trunk_parameter(&text), "{text}");
    let back = Cell::from_toml_file(&cal.join("cell.toml")).expect("the export loads");
    assert_eq!(back.shared_joints, 4);
    assert_held_out_near_noise(&cal, &held, &humanoid_trunk(), "shared trunk");

    // Refused by name: lumped compliance on tracker rows that do not give the other arm's joints (its weight
    // loads the trunk), naming the columns to fill.
    let cell = arg(&humanoid_trunk());
    let mut bare = tracker_session(&truth, 10, 43);
    assert_eq!(
        bare.other_arm_q.len(),
        10,
        "the simulator gives the other arm"
    );
    bare.other_arm_q.clear();
    let bare = write_session_csv(dir.path(), "bare.csv", &bare, &truth);
    let e = stderr_of_failure(&[
        "calibrate",
        "--cell",
        &cell,
        "--session",
        &arg(&bare),
        "--model",
        "kinematic+compliance",
    ]);
    assert!(
        e.contains("shared-trunk")
            && e.contains("`r2_q1_deg` … `r2_q10_deg` on robot 1's rows")
            && e.contains("`r1_q1_deg` … `r1_q10_deg` on robot 2's rows")
            && e.contains("--model kinematic"),
        "{e}"
    );
    // A two-robot row whose trunk columns disagree.
    let csv = std::fs::read_to_string(&train).unwrap();
    let header = csv.lines().next().unwrap();
    let row: Vec<String> = header
        .split(',')
        .map(|c| match c {
            "point" => "1".into(),
            "kind" => "coincident".into(),
            "r2_q1_deg" => "5.0".into(),
            c if c.contains("_q") => "0.0".into(),
            _ => String::new(),
        })
        .collect();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, format!("{header}\n{}\n", row.join(","))).unwrap();
    let e = stderr_of_failure(&["calibrate", "--cell", &cell, "--session", &arg(&bad)]);
    assert!(
        e.contains("r1_q1_deg") && e.contains("r2_q1_deg") && e.contains("shared"),
        "{e}"
    );
}

/// The plan of a shared-trunk cell's handclasps: meeting points in a cube of this side (m) in
/// front of the humanoid's chest ([`TRUNK_PLAN_CENTRE_MM`]), where both hands meet head-on.
const TRUNK_PLAN_SPREAD_MM: f64 = 300.0;
/// Centre of that cube, mm, b1 (the pelvis): 350 mm in front, 1450 mm up (the shoulders are at
/// 1750 mm with the trunk upright; the cell's `[teach]` centre, 1100 mm up, is for tracker rows).
const TRUNK_PLAN_CENTRE_MM: [f64; 3] = [350.0, 0.0, 1450.0];
/// Largest ratio, either way, between one calibration's measured held-out cooperative rms and
/// the plan's prediction (the expected rms over truths drawn from the tolerances): one truth
/// draw and one noise draw scatter about the expectation, by less than this.
const PREDICTION_RATIO: f64 = 2.0;

/// `handclasp plan` on a shared-trunk cell, end to end as a user runs it (issue 22): plan 40
/// handclasps of the humanoid's two hands (each candidate's trunk drawn once, both arms solved
/// with it held), simulate the plan on a truth whose errors are drawn from the cell's
/// tolerances (seed 71; both arms agree on the trunk at every row, `sim-cell session --plan`),
/// `calibrate --cell` it, and score the export with `validate` on 40 new noise-free handclasps
/// (seed 72): there the calibrated rms is the cooperative error itself, which lands within
/// [`PREDICTION_RATIO`] of the plan's predicted cooperative rms, and the nominal's is more
/// than twice it.
#[test]
fn plan_on_a_shared_trunk_predicts_the_calibration_it_plans() {
    let dir = tempfile::tempdir().unwrap();
    let cell = humanoid_trunk();
    let nominal = Cell::from_toml_file(&cell).expect("humanoid-trunk cell");
    let plan_csv = dir.path().join("plan.csv");
    let c = TRUNK_PLAN_CENTRE_MM;
    let centre = format!("{},{},{}", c[0], c[1], c[2]);
    let spread = TRUNK_PLAN_SPREAD_MM.to_string();
    let v = stdout_json(&handclasp(&[
        "plan",
        "--cell",
        &arg(&cell),
        "--n",
        "40",
        "--candidates",
        "120",
        "--spread-mm",
        &spread,
        "--centre-mm",
        &centre,
        "--out",
        &arg(&plan_csv),
        "--json",
    ]));
    let predicted = v["predicted"]["plan"]["cooperative_rms_mm"]
        .as_f64()
        .expect("a predicted cooperative rms");
    let plan = Session::read_csv(&plan_csv, &nominal).expect("the plan reads back");
    assert_eq!(plan.points.len(), 40);
    let k = nominal.shared_independent_joints();
    for p in &plan.points {
        assert_eq!(
            p.q1[..k],
            p.q2[..k],
            "planned pose {} disagrees on the trunk",
            p.point
        );
    }

    // The truth: errors drawn from the tolerances the plan assumes, the trunk's once.
    let mut truth = nominal.clone();
    let mut rng = trial_rng(71, 0);
    sim_cell::plan::draw_errors_from_tolerance(&mut truth, &mut rng);
    let trunk_params = calib_core::whole_cell::CellRobot {
        model: truth.robot1.model.clone(),
        tools: Vec::new(),
        g_base: truth.robot1.g_base,
        tolerance: truth.robot1.tolerance,
        shared_joints: 0,
    }
    .fitted_params()
    .into_iter()
    .filter(|p| p.joint().is_some_and(|j| j < truth.shared_joints));
    for p in trunk_params {
        let v = truth.robot1.errors.get(p);
        truth.robot2.errors.set(p, v);
    }
    let teach = sim_cell::teach_from_plan(&plan).expect("a plan of handclasps");
    let kinds = KindSpec::default();
    let spec = SessionSpec::new(teach.len(), Layout::Random, 0.3);
    let (train, _) = generate_kind_session(&truth, &spec, &kinds, Some(&teach), &mut rng)
        .expect("the plan's poses are reached");
    for (a, b) in train.points.iter().zip(&plan.points) {
        assert_eq!(
            a.q1[..k],
            a.q2[..k],
            "simulated pose {} disagrees on the trunk",
            a.point
        );
        assert!(
            a.q1[..k]
                .iter()
                .zip(&b.q1[..k])
                .all(|(x, y)| (x - y).abs() < 1e-3),
            "pose {} left the planned trunk",
            a.point
        );
    }
    let train = write_session_csv(dir.path(), "train.csv", &train, &nominal);
    let cal = dir.path().join("cal");
    let out = handclasp(&[
        "calibrate",
        "--cell",
        &arg(&cell),
        "--session",
        &arg(&train),
        "--export",
        &arg(&cal),
    ]);
    crate::support::assert_success(&out);
    // The placement is the trunk's, held at the identity: nothing is "absorbed by b1_from_b2"
    // (the fit used to start at a free registration, where the trunk's origin shifts read as
    // placement motions); the trunk's origin shifts, which move both hands alike, say so.
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(!text.contains("absorbed by b1_from_b2"), "{text}");
    assert!(
        text.contains("robot 1 origin_xyz joint 1 x: the shared trunk's, moves both hands alike"),
        "{text}"
    );

    // New handclasps, noise-free: the residual of a row is the cooperative error there.
    let mut exact = truth.clone();
    exact.noise.alignment_m = nalgebra::Vector3::zeros();
    exact.noise.repeatability_m = 0.0;
    exact.noise.encoder_resolution_rad = 0.0;
    let mut spec = SessionSpec::new(40, Layout::Random, TRUNK_PLAN_SPREAD_MM * 1e-3);
    spec.centre_b1 = Some(nalgebra::Point3::new(c[0], c[1], c[2]) * 1e-3);
    let held = sim_cell::generate_session(&exact, &spec, &mut trial_rng(72, 0))
        .expect("new handclasps are reached");
    let held = write_session_csv(dir.path(), "held.csv", &held, &nominal);
    let (measured, nominal_rms) =
        crate::support::validate_rms_mm(&cal.join("cell.toml"), &held, &cell);
    eprintln!(
        "shared-trunk plan: predicted cooperative rms {predicted:.3} mm, measured on 40 new \
         handclasps {measured:.3} mm (nominal {nominal_rms:.3} mm)"
    );
    assert!(
        measured < PREDICTION_RATIO * predicted && predicted < PREDICTION_RATIO * measured,
        "measured {measured:.3} mm vs predicted {predicted:.3} mm"
    );
    assert!(
        nominal_rms > 2.0 * measured,
        "nominal {nominal_rms:.3} mm vs calibrated {measured:.3} mm"
    );
}

/// The truth's joint compliance on every joint of both arms (the trunk's once), deg/(kN·m):
/// 2.0 ≈ 35 µrad/(N·m), a sag of a millimetre or two at the hands from the URDF's masses.
const TRUNK_COMPLIANCE_DEG_PER_KNM: f64 = 2.0;

/// `cells/humanoid-trunk.toml` with its URDF at `urdf` and, when `compliance` is given, that
/// compliance (deg/(kN·m)) on all 11 chain joints of both arms' `[robotN.errors]`.
fn humanoid_trunk_text(urdf: &Path, compliance: Option<f64>) -> String {
    let mut text = std::fs::read_to_string(humanoid_trunk())
        .unwrap()
        .replace("../robots/humanoid.urdf", &arg(urdf));
    if let Some(c) = compliance {
        let list = format!(
            "compliance_deg_per_knm = [{}]\n",
            vec![c.to_string(); 11].join(", ")
        );
        for r in ["[robot1.errors]\n", "[robot2.errors]\n"] {
            text = text.replace(r, &format!("{r}{list}"));
        }
    }
    text
}

/// Gravity compliance on a shared trunk from the CLI (issue 22): the truth's humanoid sags by
/// [`TRUNK_COMPLIANCE_DEG_PER_KNM`] × the gravity torques of the URDF's masses, both arms
/// loading the torso (the simulator draws the other arm's posture at every tracker row and
/// writes it in the other robot's joint columns); the fit's cell names the same humanoid with
/// every `<inertial>` removed. `calibrate --cell --model kinematic+compliance` (160 rows,
/// seed 51) beats `--model kinematic` on 60 held-out rows (seed 52) by a third at least and
/// lands within twice the camera's 3-D noise; its export holds `lumped_compliance_deg`, which
/// `validate` applies (the other arm's load included, from the held-out rows' columns).
#[test]
fn shared_trunk_compliance_is_fitted_from_the_cli_without_masses() {
    let dir = tempfile::tempdir().unwrap();
    let urdf = crate::support::workspace("robots/humanoid.urdf");
    let truth_path = dir.path().join("truth.toml");
    std::fs::write(
        &truth_path,
        humanoid_trunk_text(&urdf, Some(TRUNK_COMPLIANCE_DEG_PER_KNM)),
    )
    .unwrap();
    let truth = Cell::from_toml_file(&truth_path).expect("the truth loads");
    let massless = crate::support::strip_inertials(&std::fs::read_to_string(&urdf).unwrap());
    let massless_urdf = dir.path().join("humanoid-massless.urdf");
    std::fs::write(&massless_urdf, massless).unwrap();
    let fit_cell = dir.path().join("fit.toml");
    std::fs::write(&fit_cell, humanoid_trunk_text(&massless_urdf, None)).unwrap();
    let train = write_session_csv(
        dir.path(),
        "train.csv",
        &tracker_session(&truth, 160, 51),
        &truth,
    );
    let held = write_session_csv(
        dir.path(),
        "held.csv",
        &tracker_session(&truth, 60, 52),
        &truth,
    );
    let mut rms = Vec::new();
    for model in ["kinematic", "kinematic+compliance"] {
        let cal = dir.path().join(model);
        let out = handclasp(&[
            "calibrate",
            "--cell",
            &arg(&fit_cell),
            "--session",
            &arg(&train),
            "--model",
            model,
            "--export",
            &arg(&cal),
        ]);
        assert!(
            out.status.success(),
            "{model}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        rms.push(crate::support::validate_rms_mm(&cal.join("cell.toml"), &held, &fit_cell).0);
    }
    let exported =
        std::fs::read_to_string(dir.path().join("kinematic+compliance/cell.toml")).unwrap();
    assert!(exported.contains("lumped_compliance_deg"), "{exported}");
    let noise_3d_mm = TRACKER_SIGMA_M * 3f64.sqrt() * 1e3;
    eprintln!(
        "humanoid trunk compliance, held-out rms: kinematic {:.3} mm, kinematic+compliance {:.3} mm (noise {noise_3d_mm:.3} mm)",
        rms[0], rms[1]
    );
    assert!(rms[1] < 2.0 / 3.0 * rms[0], "{rms:?}");
    assert!(rms[1] < 2.0 * noise_3d_mm, "{rms:?}");
}

/// `cells/humanoid-trunk.toml` without its `[robotN.errors]` (a nominal humanoid) and with the
/// single error line `line` (e.g. `joint_offset_deg = […]`) under `[robot{robot}.errors]`.
fn humanoid_trunk_with_one_error(robot: u8, line: &str) -> String {
    let urdf = crate::support::workspace("robots/humanoid.urdf");
    let nominal: String = humanoid_trunk_text(&urdf, None)
        .lines()
        .filter(|l| !l.starts_with("joint_offset_deg") && !l.starts_with("origin_xyz_mm"))
        .map(|l| format!("{l}\n"))
        .collect();
    let header = format!("[robot{robot}.errors]\n");
    nominal.replace(&header, &format!("{header}{line}\n"))
}

/// The names of every parameter of the named effects of a `diagnose --json` report.
fn effect_parameter_names(report: &serde_json::Value) -> Vec<String> {
    report["effects"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|e| e["parameters"].as_array().unwrap().iter())
        .map(|p| p["name"].as_str().unwrap().to_string())
        .collect()
}

/// A robot parameter of chain joint 1 … 4 (the shared trunk's) in `names`: a trunk parameter
/// named as one robot's copy.
fn robot_copy_of_trunk_parameter(names: &[String]) -> Option<&String> {
    names
        .iter()
        .find(|n| names_robot2_trunk_parameter(&n.replace("robot 1 ", "robot 2 ")))
}

/// The truth's hidden offset, deg (≈ 5.2 mrad: ~50 times the fitted value's σ here).
const HIDDEN_OFFSET_DEG: f64 = 0.3;

/// `handclasp diagnose --cell nominal --session session --json` and the `extra` arguments: the
/// report.
fn diagnose_json(nominal: &Path, session: &Path, extra: &[&str]) -> serde_json::Value {
    let (nominal, session) = (arg(nominal), arg(session));
    let mut args = vec![
        "diagnose",
        "--cell",
        &nominal,
        "--session",
        &session,
        "--json",
    ];
    args.extend_from_slice(extra);
    stdout_json(&handclasp(&args))
}

/// Writes `{what}.toml`, the shared-trunk humanoid with one hidden offset of
/// [`HIDDEN_OFFSET_DEG`] on chain joint `joint` (0-based) of robot `robot`'s chain, and loads it.
fn write_hidden_offset_truth(dir: &Path, what: &str, robot: u8, joint: usize) -> Cell {
    let hidden_deg = HIDDEN_OFFSET_DEG.to_string();
    let mut offsets = ["0.0"; 11];
    offsets[joint] = &hidden_deg;
    let line = format!("joint_offset_deg = [{}]", offsets.join(", "));
    let truth_path = dir.join(format!("{what}.toml"));
    std::fs::write(&truth_path, humanoid_trunk_with_one_error(robot, &line)).unwrap();
    Cell::from_toml_file(&truth_path).expect("the truth loads")
}

/// `diagnose` on a shared-trunk cell (issue 22): the trunk's parameters are one set (the
/// candidates "trunk joint offsets", … beside each arm's own), so a hidden error of the trunk is
/// named once, as the trunk's, and one of an arm on that arm; the export is a shared-trunk cell
/// whose held-out rms is near the camera's noise. Two truths, each with one hidden offset of
/// [`HIDDEN_OFFSET_DEG`] on the nominal humanoid: torso_4 (trunk chain joint 4; torso_1–3's
/// offsets are exact aliases of what a tracker sees: torso_1's turns the whole body about the
/// pelvis (the tracker frame), torso_2's equals a trunk joint-2 origin shift plus that,
/// torso_3's equals torso_4's origin angle about z) and robot 2's chain joint 7 (its third arm
/// joint). 80 tracker rows (seeds 61/63) to diagnose, 40 new poses (62/64) to score the export.
#[test]
fn diagnose_names_a_trunk_error_once_and_an_arm_error_on_its_arm() {
    let dir = tempfile::tempdir().unwrap();
    let nominal = dir.path().join("nominal.toml");
    std::fs::write(&nominal, humanoid_trunk_with_one_error(1, "")).unwrap();
    let cases = [
        ("trunk", 1, 3, 61, "trunk joint_offset joint 4"),
        ("arm", 2, 6, 63, "robot 2 joint_offset joint 7"),
    ];
    for (what, robot, joint, seed, hidden) in cases {
        let truth = write_hidden_offset_truth(dir.path(), what, robot, joint);
        assert_eq!(truth.shared_joints, 4);
        let train = write_session_csv(
            dir.path(),
            &format!("{what}-train.csv"),
            &tracker_session(&truth, 80, seed),
            &truth,
        );
        let held = write_session_csv(
            dir.path(),
            &format!("{what}-held.csv"),
            &tracker_session(&truth, 40, seed + 1),
            &truth,
        );
        let export = dir.path().join(format!("{what}-export"));
        let report = diagnose_json(&nominal, &train, &["--export", &arg(&export)]);
        let names = effect_parameter_names(&report);
        eprintln!("{what}: named {names:?}");
        assert_eq!(
            robot_copy_of_trunk_parameter(&names),
            None,
            "{what}: {names:?}"
        );
        // The hidden offset is named, in the right family, at its value within 3 σ.
        let effects = report["effects"].as_array().unwrap();
        let found = effects
            .iter()
            .flat_map(|e| {
                let p = e["parameters"].as_array().unwrap();
                p.iter().map(move |p| (e, p))
            })
            .find(|(_, p)| p["name"] == hidden);
        let (effect, p) = found.unwrap_or_else(|| panic!("{what}: {hidden} not named: {report}"));
        let trunk = effect["family"]["trunk"].as_bool() == Some(true);
        assert_eq!(trunk, what == "trunk", "{what}: {effect}");
        let (value, sigma) = (
            p["value_mrad"].as_f64().unwrap(),
            p["sigma_mrad"].as_f64().unwrap(),
        );
        let truth_mrad = HIDDEN_OFFSET_DEG.to_radians() * 1e3;
        assert!(
            (value - truth_mrad).abs() <= 3.0 * sigma,
            "{what}: {hidden} {value:.3} ± {sigma:.3} mrad vs truth {truth_mrad:.3}"
        );
        // No trunk family when the error is on an arm: the trunk is named only when it is wrong.
        if what == "arm" {
            assert!(
                effects.iter().all(|e| e["family"]["trunk"].is_null()),
                "{report}"
            );
        }
        let back =
            Cell::from_toml_file(&export.join("cell_corrected.toml")).expect("the export loads");
        assert_eq!(back.shared_joints, 4, "the export is a shared-trunk cell");
        assert_cell_held_out_near_noise(
            &export.join("cell_corrected.toml"),
            &held,
            &nominal,
            &format!("diagnose, {what} offset"),
        );
    }
}

/// The seed of the 80-row arm-offset session (the arm truth of
/// `diagnose_names_a_trunk_error_once_and_an_arm_error_on_its_arm`) on which the held-out rule
/// alone (gain ≥ 1 %, t ≥ 3, no level) named "robot 2 joint compliance" at step 2 (held-out χ²
/// 321.3 → 302.3, t = 9.1 over the tracker file's 4 blocks), a family the truth lacks
/// (trunk22c, stop 35; one of 5 extra families in seeds 61–110). The nested F test at the
/// selection's 5 % per-step level (stop 36) names only the offset.
const EXTRA_FAMILY_SEED: u64 = 61;

#[test]
fn diagnose_names_only_the_arm_offset_on_the_session_that_once_gained_compliance() {
    let dir = tempfile::tempdir().unwrap();
    let nominal = dir.path().join("nominal.toml");
    std::fs::write(&nominal, humanoid_trunk_with_one_error(1, "")).unwrap();
    let truth = write_hidden_offset_truth(dir.path(), "arm", 2, 6);
    let train = write_session_csv(
        dir.path(),
        "arm-train.csv",
        &tracker_session(&truth, 80, EXTRA_FAMILY_SEED),
        &truth,
    );
    let report = diagnose_json(&nominal, &train, &[]);
    let families: Vec<&str> = report["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["family"]["name"].as_str().unwrap())
        .collect();
    eprintln!(
        "seed {EXTRA_FAMILY_SEED}: named {families:?}, step 1 gain {} t {}",
        report["effects"][0]["gain"]["relative_gain"], report["effects"][0]["gain"]["gain_t"]
    );
    assert_eq!(families, ["robot 2 joint offsets"], "{report}");
    // The compliance is still tried at the stopping step, and rejected.
    let rejected: Vec<&str> = report["rejected_families"]
        .as_array()
        .map(|r| {
            r.iter()
                .filter_map(|f| f["family"]["name"].as_str())
                .collect()
        })
        .unwrap_or_default();
    assert!(rejected.contains(&"robot 2 joint compliance"), "{report}");
}

/// The trunk's three independent joints (torso_1 … torso_3, rad) at every row of
/// [`still_trunk_session`]: one posture, not upright, held for the whole session.
const STILL_TRUNK_RAD: [f64; 3] = [0.1, -0.05, 0.2];

/// `n` tracker rows of the humanoid's hands (robots alternate) with the trunk held still at
/// [`STILL_TRUNK_RAD`] and each arm's 7 joints uniform in the middle 80 % of their limits: the
/// truth's tool point (its `[robotN.errors]`, no repeatability) measured in a tracker frame 2 m
/// away with the camera's σ ([`TRACKER_SIGMA_M`]) per axis, seeded. Built here because the
/// simulator's inverse kinematics moves the trunk to reach its teach points.
fn still_trunk_session(truth: &Cell, n: usize, seed: u64) -> Session {
    use handclasp_cell::session::{SessionKind, SessionObservation};
    use nalgebra::{Isometry3, Point3, Vector3};
    let mut rng = SplitMix(seed);
    let tracker_from_b1 =
        Isometry3::new(Vector3::new(2.0, 0.3, -1.0), Vector3::new(0.1, -0.2, 2.5));
    let mut session = Session::default();
    for i in 0..n {
        let robot = if i % 2 == 0 {
            calib_core::Robot::One
        } else {
            calib_core::Robot::Two
        };
        let c = truth.robot(robot);
        let q: Vec<f64> = c
            .model
            .joints()
            .iter()
            .enumerate()
            .map(|(k, j)| match STILL_TRUNK_RAD.get(k) {
                Some(&v) => v,
                None => {
                    let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
                    lo + (0.1 + 0.8 * rng.uniform()) * (hi - lo)
                }
            })
            .collect();
        let tip =
            kinematics::true_base_from_tip(&c.model, &c.errors, &q, &c.flange_from_tip, &c.g_base)
                .expect("the truth's tip");
        let b1_from_b = match robot {
            calib_core::Robot::One => Isometry3::identity(),
            calib_core::Robot::Two => truth.b1_from_b2,
        };
        let p_b1 = b1_from_b * Point3::from(tip.translation.vector);
        let e = Vector3::from_fn(|_, _| TRACKER_SIGMA_M * rng.normal());
        session.observations.push(SessionObservation {
            point: i + 1,
            kind: SessionKind::Tracker {
                robot,
                q,
                tool: 0,
                group: "camera".into(),
                p_tracker: tracker_from_b1 * p_b1 + e,
                sigma_m: TRACKER_SIGMA_M,
            },
        });
    }
    session
}

/// `cells/humanoid-trunk.toml`'s truth with an error at robot 2's shoulder (chain joint 5, the
/// left arm's first joint after the trunk): [`SHOULDER_OFFSET_DEG`] on its zero and
/// [`SHOULDER_ORIGIN_MM`] on its origin.
fn shoulder_error_truth() -> String {
    let urdf = crate::support::workspace("robots/humanoid.urdf");
    let text = humanoid_trunk_text(&urdf, None);
    let (head, robot2) = text.split_at(text.find("[robot2]").expect("a [robot2] table"));
    let [x, y, z] = SHOULDER_ORIGIN_MM;
    let robot2 = robot2
        .replacen(
            "joint_offset_deg = [0.0, 0.0, 0.0, 0.0, 0.0,",
            &format!("joint_offset_deg = [0.0, 0.0, 0.0, 0.0, {SHOULDER_OFFSET_DEG},"),
            1,
        )
        .replacen(
            "origin_xyz_mm = [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0],",
            &format!(
                "origin_xyz_mm = [[0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0], [{x}, {y}, {z}],"
            ),
            1,
        );
    assert!(
        robot2.contains(&format!("{SHOULDER_OFFSET_DEG}, -0.03"))
            && robot2.contains(&format!("[{x}, {y}, {z}]")),
        "the shipped cell's robot 2 errors changed: {robot2}"
    );
    format!("{head}{robot2}")
}

/// The truth's error on robot 2's shoulder zero, deg (a few tenths of a millimetre at the hand).
const SHOULDER_OFFSET_DEG: f64 = 0.05;
/// The truth's error on robot 2's shoulder origin, mm.
const SHOULDER_ORIGIN_MM: [f64; 3] = [0.4, -0.3, 0.3];

/// Issue 22 (stop 35's prediction): on a shared trunk held still across the rows, each arm's
/// shoulder moves its hand as a move of `b1_from_b2` would, and the reduction, which read the
/// placement the trunk holds at the identity as a free registration, dropped robot 2's shoulder
/// parameters ("moves robot 2's tips against robot 1's as a move of b1_from_b2 would") although
/// the trunk holds the placement and the tracker sees each hand. Now the placement prior's rows
/// count: nothing is held for the placement, the shoulders are fitted, and on 40 new poses (the
/// trunk still) the calibrated cell is within twice the camera's 3-D noise where the nominal
/// is not. The truth has an error at robot 2's shoulder ([`shoulder_error_truth`]). (The
/// trunk's own parameters, which move both hands alike with the trunk still, stay dropped: the
/// tracker frame absorbs them.) Frozen from stop 36 (main `9bb437a` on this session): 9 robot 2
/// shoulder parameters (joint 5, two of joint 6) held at 0 "as b1_from_b2 would", held-out rms 0.563 mm (nominal 0.935,
/// noise 0.173); with the prior rows 0.179 mm.
#[test]
fn a_shared_trunk_held_still_keeps_the_shoulders() {
    let dir = tempfile::tempdir().unwrap();
    let truth_path = dir.path().join("truth.toml");
    std::fs::write(&truth_path, shoulder_error_truth()).unwrap();
    let truth = Cell::from_toml_file(&truth_path).expect("the truth cell");
    let train = write_session_csv(
        dir.path(),
        "train.csv",
        &still_trunk_session(&truth, 120, 91),
        &truth,
    );
    let held = write_session_csv(
        dir.path(),
        "held.csv",
        &still_trunk_session(&truth, 40, 92),
        &truth,
    );
    let cal = dir.path().join("cal");
    let text = calibrate_trunk_export(&train, &cal);
    eprintln!("{text}");
    assert!(
        !text.contains("as a move of b1_from_b2 would"),
        "nothing is held for the placement the trunk holds: {text}"
    );
    assert_held_out_near_noise(&cal, &held, &humanoid_trunk(), "shared trunk held still");
}

/// A seeded generator for [`still_trunk_session`] (SplitMix64; the e2e tests do not depend on
/// `rand`).
struct SplitMix(u64);

impl SplitMix {
    /// Uniform in [0, 1).
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u = 1.0 - self.uniform();
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

//! End-to-end tests for `handclasp calibrate --cell CELL --session SESSION`: the whole-cell
//! calibration on a floor–floor cell whose robots carry realistic kinematic errors on every joint
//! (offsets U(±0.05°), origins U(±0.5 mm) per axis, seeded), sessions simulated by sim-cell as
//! `sim-cell session` does (`generate_session` + `write_csv`).

use std::path::{Path, PathBuf};

use calib_core::Robot;
use handclasp_cell::Cell;
use handclasp_cell::Session;
use kinematics::{base_from_tip, true_base_from_tip, KinematicErrors, PATCH_TOLERANCE_M};
use nalgebra::{Point3, Vector3};
use serde_json::Value;

use crate::support::{
    assert_success, cell_session_args, handclasp, random_session, shipped_cell, stdout_json,
    workspace, write_session_csv,
};

/// splitmix64: the seeded draws of the true errors (the test needs no `rand` dependency).
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    /// U(±half_width).
    fn uniform(&mut self, half_width: f64) -> f64 {
        (2.0 * self.next_f64() - 1.0) * half_width
    }
}

/// Joint counts of the shipped robots: VA1400 (7 joints) and HP20 (6).
const DOF: [usize; 2] = [7, 6];
/// Tolerance-sized true errors: offsets U(±0.05°), origins U(±0.5 mm) per axis.
const OFFSET_DEG: f64 = 0.05;
const ORIGIN_MM: f64 = 0.5;

/// The shipped floor–floor cell with seeded true errors on every joint of both robots, written to
/// `dir/cell.toml` (URDF paths absolute to the workspace's robots/).
pub(crate) fn write_cell(dir: &Path, seed: u64) -> PathBuf {
    let robots = workspace("robots/");
    let mut text = std::fs::read_to_string(shipped_cell("floor-floor"))
        .unwrap()
        .replace("../robots/", &format!("{}/", robots.display()));
    let mut rng = SplitMix(seed);
    for (r, dof) in DOF.iter().enumerate() {
        let offsets: Vec<String> = (0..*dof)
            .map(|_| format!("{:.6}", rng.uniform(OFFSET_DEG)))
            .collect();
        let origins: Vec<String> = (0..*dof)
            .map(|_| {
                let v: Vec<String> = (0..3)
                    .map(|_| format!("{:.6}", rng.uniform(ORIGIN_MM)))
                    .collect();
                format!("[{}]", v.join(", "))
            })
            .collect();
        text += &format!(
            "\n[robot{}.errors]\njoint_offset_deg = [{}]\norigin_xyz_mm = [{}]\n",
            r + 1,
            offsets.join(", "),
            origins.join(", ")
        );
    }
    let path = dir.join("cell.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn calibrate_json(cell: &Path, session: &Path, model: &str, export: Option<&Path>) -> Value {
    let mut args = cell_session_args("calibrate", cell, session, &["--model", model, "--json"]);
    if let Some(dir) = export {
        args.push("--export".into());
        args.push(dir.display().to_string());
    }
    stdout_json(&handclasp(&args))
}

/// Tip of robot `r` of `cell` at reported joints `q` in its base frame, with the cell's errors.
pub(crate) fn tip(cell: &Cell, r: Robot, q: &[f64]) -> Vector3<f64> {
    let rb = cell.robot(r);
    true_base_from_tip(&rb.model, &rb.errors, q, &rb.flange_from_tip, &rb.g_base)
        .unwrap()
        .translation
        .vector
}

/// The cooperative vector `v = p1_b1 − b1_from_b2·p2_b2` (m) of `cell` at a configuration pair.
fn cooperative(cell: &Cell, q1: &[f64], q2: &[f64]) -> Vector3<f64> {
    tip(cell, Robot::One, q1) - (cell.b1_from_b2 * Point3::from(tip(cell, Robot::Two, q2))).coords
}

/// rms over every pair `(q1_i, q2_j)` of `held_out` of ‖v_calibrated − v_true‖, mm.
pub(crate) fn cooperative_rms_mm(calibrated: &Cell, truth: &Cell, held_out: &Session) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    for a in &held_out.points {
        for b in &held_out.points {
            let e = cooperative(calibrated, &a.q1, &b.q2) - cooperative(truth, &a.q1, &b.q2);
            sum += e.norm_squared();
            n += 1;
        }
    }
    (sum / n as f64).sqrt() * 1e3
}

/// The fitted kinematic errors of robot `r` from the JSON `parameters` (tip error in `tip`).
fn fitted_errors(v: &Value, r: u64, dof: usize) -> KinematicErrors {
    let mut e = KinematicErrors::zero(dof);
    for p in v["parameters"].as_array().unwrap() {
        if p["robot"].as_u64() != Some(r) {
            continue;
        }
        let value = p["value"].as_f64().unwrap();
        let si = match p["unit"].as_str().unwrap() {
            "deg" => value.to_radians(),
            "mm" => value * 1e-3,
            u => panic!("unexpected unit {u}"),
        };
        let joint = p["joint"].as_u64().map(|j| j as usize - 1);
        let axis = match p["axis"].as_str() {
            Some("x") => 0,
            Some("y") => 1,
            Some("z") => 2,
            _ => usize::MAX,
        };
        match p["kind"].as_str().unwrap() {
            "joint_offset" => e.joint_offset[joint.unwrap()] = si,
            "origin_xyz" => e.origin_xyz[joint.unwrap()][axis] = si,
            "origin_rpy" => e.origin_rpy[joint.unwrap()][axis] = si,
            "tip" => e.tip[axis] = si,
            k => panic!("unexpected parameter kind {k}"),
        }
    }
    e
}

#[test]
fn kinematic_model_beats_placement_and_exports_verified_urdfs() {
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_cell(dir.path(), 11);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let s = random_session(&truth, 30, 3);
    let session_path = write_session_csv(dir.path(), "session.csv", &s, &truth);
    let held_out = random_session(&truth, 20, 1003);

    let out_k = dir.path().join("kinematic");
    let out_p = dir.path().join("placement");
    let k = calibrate_json(&cell_path, &session_path, "kinematic", Some(&out_k));
    let p = calibrate_json(&cell_path, &session_path, "placement", Some(&out_p));

    // The JSON has the documented keys.
    for v in [&k, &p] {
        for key in ["xyz_mm", "zyz_deg", "rotation"] {
            assert!(v["b1_from_b2"][key].is_array(), "b1_from_b2.{key} in {v}");
        }
        for key in ["parameters", "unidentifiable", "rejected_points"] {
            assert!(v[key].is_array(), "{key}");
        }
        for key in ["predicted_rms", "predicted_p95"] {
            assert!(v["cooperative_accuracy_mm"][key].as_f64().unwrap() > 0.0);
        }
        assert!(v["stopped"].is_string());
    }
    assert!(p["parameters"].as_array().unwrap().is_empty());
    let kp = k["parameters"].as_array().unwrap();
    assert!(!kp.is_empty());
    for q in kp {
        for key in ["robot", "name", "value", "unit", "sigma"] {
            assert!(!q[key].is_null(), "parameter key {key}: {q}");
        }
    }
    for d in k["unidentifiable"].as_array().unwrap() {
        assert!(d["why"].as_str().is_some_and(|w| !w.is_empty()), "{d}");
    }

    // The exported cells load (URDF paths resolve inside the folder).
    let cal_k = Cell::from_toml_file(&out_k.join("cell.toml")).unwrap();
    let cal_p = Cell::from_toml_file(&out_p.join("cell.toml")).unwrap();
    for r in [Robot::One, Robot::Two] {
        assert_eq!(
            cal_k.robot(r).urdf_path,
            out_k.join(format!("robot{}.urdf", r.number()))
        );
        assert!(cal_k.robot(r).urdf_path.is_file());
    }
    // A second export into the now non-empty folder is refused before the fit (it would mix two
    // models' files)…
    let mut again = cell_session_args("calibrate", &cell_path, &session_path, &["--json"]);
    again.extend(["--export".to_string(), out_k.display().to_string()]);
    let refused = handclasp(&again);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains("the folder is not empty") && err.contains("--overwrite"),
        "{err}"
    );
    // …--force alone keeps a refused fit, it does not overwrite (issue 21: one flag, one
    // meaning), and says which flag does…
    let mut forced_only = again.clone();
    forced_only.push("--force".into());
    let refused = handclasp(&forced_only);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains("no longer overwrites an export (add --overwrite)"),
        "{err}"
    );
    // …and --overwrite overwrites the files of the same names with the same calibration.
    let before = std::fs::read_to_string(out_k.join("cell.toml")).unwrap();
    again.push("--overwrite".into());
    let forced = handclasp(&again);
    let forced_err = String::from_utf8_lossy(&forced.stderr);
    assert!(forced.status.success(), "{forced_err}");
    assert_eq!(
        std::fs::read_to_string(out_k.join("cell.toml")).unwrap(),
        before
    );
    // The input cell's [robotN.errors] (this simulation's truth) are named as not used.
    for r in [1, 2] {
        assert!(
            forced_err.contains(&format!(
                "[robot{r}.errors] holds joint_offset, origin_xyz terms, which calibrate --cell does not use"
            )),
            "{forced_err}"
        );
    }

    // `handclasp diagnose` takes the exported cell (with a session recorded on it: the old
    // session's tip columns are the old models' and fail its consistency check by design).
    let s2 = random_session(&cal_k, 12, 9);
    let s2_path = write_session_csv(dir.path(), "session_on_calibrated.csv", &s2, &cal_k);
    let out = handclasp(&cell_session_args(
        "diagnose",
        &out_k.join("cell.toml"),
        &s2_path,
        &["--trials", "20", "--json"],
    ));
    assert_success(&out);
    // The exported cell keeps nothing in [robotN.errors] here, so calibrating with it notes nothing.
    let recal = handclasp(&cell_session_args(
        "calibrate",
        &out_k.join("cell.toml"),
        &s2_path,
        &["--json"],
    ));
    let recal_err = String::from_utf8_lossy(&recal.stderr);
    assert!(recal.status.success(), "{recal_err}");
    assert!(!recal_err.contains("does not use"), "{recal_err}");

    // Cooperative accuracy against the truth, over 400 held-out configuration pairs.
    let rms_k = cooperative_rms_mm(&cal_k, &truth, &held_out);
    let rms_p = cooperative_rms_mm(&cal_p, &truth, &held_out);
    eprintln!(
        "cooperative rms over {} held-out pairs: kinematic {rms_k:.3} mm (predicted {:.3}), placement {rms_p:.3} mm (predicted {:.3})",
        held_out.points.len().pow(2),
        k["cooperative_accuracy_mm"]["predicted_rms"],
        p["cooperative_accuracy_mm"]["predicted_rms"],
    );
    assert!(
        rms_k < rms_p,
        "kinematic {rms_k:.3} mm should beat placement {rms_p:.3} mm"
    );

    // The exported URDFs (+ the exported tips) reproduce the fitted model's tips to 1e-9 m.
    for (r, dof) in [(Robot::One, DOF[0]), (Robot::Two, DOF[1])] {
        let nominal = truth.robot(r);
        let fitted = fitted_errors(&k, u64::from(r.number()), dof);
        let exported = cal_k.robot(r);
        assert!(exported.errors.is_zero(), "nothing beside the URDF and tip");
        let mut worst = 0.0f64;
        for pt in s.points.iter().chain(&held_out.points) {
            let q = if r == Robot::One { &pt.q1 } else { &pt.q2 };
            let want = true_base_from_tip(
                &nominal.model,
                &fitted,
                q,
                &nominal.flange_from_tip,
                &nominal.g_base,
            )
            .unwrap();
            let got = base_from_tip(&exported.model, q, &exported.flange_from_tip).unwrap();
            worst = worst.max((want.translation.vector - got.translation.vector).norm());
        }
        assert!(
            worst <= PATCH_TOLERANCE_M,
            "{r}: exported tip off the fitted model by {worst:e} m"
        );
    }
}

/// Moves robot 2's reported joint 1 of session row `i` so that its tip moves by `mm`, and the
/// reported tip with it (the controller believes it): a blunder of that size in b1.
fn add_blunder(cell: &Cell, s: &mut Session, i: usize, mm: f64) {
    let rb = &cell.robot2;
    let p = &mut s.points[i];
    let at = |q: &[f64]| {
        base_from_tip(&rb.model, q, &rb.flange_from_tip)
            .unwrap()
            .translation
            .vector
    };
    let step = 1e-3;
    let mut q = p.q2.clone();
    q[0] += step;
    let rate_m_per_rad = (at(&q) - at(&p.q2)).norm() / step;
    p.q2[0] += mm * 1e-3 / rate_m_per_rad;
    p.p_b2 = Point3::from(at(&p.q2));
}

#[test]
fn three_blunders_are_named_in_json_and_text() {
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_cell(dir.path(), 12);
    let truth = Cell::from_toml_file(&cell_path).unwrap();
    let mut s = random_session(&truth, 30, 5);
    let bad = [(4usize, 5.0), (11, 7.5), (19, 10.0)];
    for (i, mm) in bad {
        add_blunder(&truth, &mut s, i, mm);
    }
    let session_path = write_session_csv(dir.path(), "session.csv", &s, &truth);
    let v = calibrate_json(&cell_path, &session_path, "kinematic", None);
    let mut rows: Vec<u64> = v["rejected_points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["row"].as_u64().unwrap())
        .collect();
    rows.sort_unstable();
    let want: Vec<u64> = bad.iter().map(|(i, _)| s.points[*i].point as u64).collect();
    assert_eq!(rows, want, "{}", v["rejected_points"]);
    for r in v["rejected_points"].as_array().unwrap() {
        assert!(r["size_sigma"].as_f64().unwrap() > 5.0, "{r}");
    }
    let out = handclasp(&cell_session_args(
        "calibrate",
        &cell_path,
        &session_path,
        &[],
    ));
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for row in &want {
        assert!(text.contains(&format!("row {row:>4}:")), "{text}");
    }
}

/// The placement's prior σ is reported beside its posterior σ (JSON `b1_from_b2.sigma[].prior_sigma`,
/// mm and deg; `null` without a prior) and in the text report.
#[test]
fn placement_prior_sigma_is_reported_beside_the_posterior() {
    let dir = tempfile::tempdir().unwrap();
    let free_path = write_cell(dir.path(), 14);
    let truth = Cell::from_toml_file(&free_path).unwrap();
    let s = random_session(&truth, 12, 6);
    let session_path = write_session_csv(dir.path(), "session.csv", &s, &truth);
    let text = std::fs::read_to_string(&free_path).unwrap();
    assert!(text.contains("[b1_from_b2]"));
    let known_path = dir.path().join("known.toml");
    std::fs::write(
        &known_path,
        text.replacen(
            "[b1_from_b2]",
            "[b1_from_b2]\nsigma_mm = 0.5\nsigma_deg = 0.05\n",
            1,
        ),
    )
    .unwrap();
    for (cell, prior) in [(&free_path, None), (&known_path, Some([0.5, 0.05]))] {
        let v = calibrate_json(cell, &session_path, "placement", None);
        let sigma = v["b1_from_b2"]["sigma"].as_array().unwrap();
        assert_eq!(sigma.len(), 6, "{sigma:?}");
        for (k, e) in sigma.iter().enumerate() {
            let posterior = e["sigma"].as_f64().unwrap();
            assert!(posterior > 0.0, "{e}");
            assert_eq!(e["unit"], if k < 3 { "mm" } else { "deg" }, "{e}");
            match prior {
                None => assert!(e["prior_sigma"].is_null(), "{e}"),
                Some(p) => {
                    let want = p[usize::from(k >= 3)];
                    let got = e["prior_sigma"].as_f64().unwrap();
                    // The cell's value through mm → m → mm (or deg → rad → deg): round-off.
                    // (No posterior ≤ prior check: the placement model scales its covariance by
                    // the residuals' variance factor, which the robots' errors push above 1.)
                    assert!((got - want).abs() < 1e-12 * want, "{e}");
                }
            }
        }
        let out = handclasp(&cell_session_args(
            "calibrate",
            cell,
            &session_path,
            &["--model", "placement"],
        ));
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        let line = text
            .lines()
            .find(|l| l.starts_with("b1_from_b2 posterior σ"))
            .unwrap_or_else(|| panic!("no placement σ line in {text}"));
        match prior {
            None => assert_eq!(line.matches("prior: free").count(), 6, "{line}"),
            Some(_) => {
                assert_eq!(line.matches("(prior 0.5000 mm)").count(), 3, "{line}");
                assert_eq!(line.matches("(prior 0.0500 deg)").count(), 3, "{line}");
            }
        }
    }
}

#[test]
fn cell_mode_errors_name_the_fix() {
    // --cell without --session, and points mixed with --cell, are refused by the argument parser.
    let out = handclasp(&["calibrate", "--cell", "x.toml"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--session"));
    let out = handclasp(&[
        "calibrate",
        "p.csv",
        "--cell",
        "x.toml",
        "--session",
        "s.csv",
    ]);
    assert!(!out.status.success());
    // A session of another cell names the file and the column.
    let dir = tempfile::tempdir().unwrap();
    let cell_path = write_cell(dir.path(), 13);
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, "point,r1_x_mm\n1,0\n").unwrap();
    let out = handclasp(&cell_session_args("calibrate", &cell_path, &bad, &[]));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.csv") && err.contains("r1_q1_deg"),
        "{err}"
    );
}

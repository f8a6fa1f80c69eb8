//! End-to-end tests for `handclasp plan`: the plan is a session CSV that `Session::read_csv` reads
//! for the same cell (what `sim-cell session --plan` consumes), its poses are within both robots'
//! joint limits, and the JSON carries the documented keys.

use handclasp_cell::Cell;
use handclasp_cell::Session;

use crate::support::{handclasp, shipped_cell, stdout_json};

/// `handclasp plan` followed by `args`.
fn plan(args: &[&str]) -> std::process::Output {
    handclasp(&[&["plan"][..], args].concat())
}

#[test]
fn plan_json_keys_and_csv_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let cell = shipped_cell("floor-ceiling");
    let o = plan(&[
        "--cell",
        cell.to_str().unwrap(),
        "--n",
        "6",
        "--candidates",
        "24",
        "--spread-mm",
        "800",
        "--random-draws",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    let v = stdout_json(&o);
    for who in ["plan", "random"] {
        for key in ["cooperative_rms_mm", "e_tran_mm", "e_rot_deg"] {
            let x = v["predicted"][who][key].as_f64();
            assert!(
                x.is_some_and(|x| x.is_finite() && x > 0.0),
                "{who}.{key}: {v}"
            );
        }
    }
    assert!(
        v["predicted"]["plan"]["cooperative_rms_mm"].as_f64()
            < v["predicted"]["random"]["cooperative_rms_mm"].as_f64()
    );
    assert_eq!(v["random_draws"], 5);
    // The prediction in parts, with the same definition as calibrate --cell: at scale 1 its
    // total is the design's figure; the placement-only limit leaves more to the prior.
    let parts = &v["predicted_error_mm"];
    let held = &parts["held_out"];
    assert_eq!(held["pair_set_kind"], "held_out_handclasps", "{v}");
    let rms = held["predicted_rms"].as_f64().unwrap();
    let design = v["predicted"]["plan"]["cooperative_rms_mm"]
        .as_f64()
        .unwrap();
    // The same posterior through two products: round-off only.
    assert!((rms - design).abs() <= 1e-9 * design, "{rms} vs {design}");
    let limit = &parts["placement_only_limit"];
    assert!(
        limit["prior_part_rms"].as_f64().unwrap() > held["prior_part_rms"].as_f64().unwrap(),
        "{v}"
    );
    assert_eq!(parts["workspace"]["pair_set_kind"], "workspace", "{v}");
    assert_eq!(v["poses"].as_array().unwrap().len(), 6);
    let c = Cell::from_toml_file(&cell).unwrap();
    let s = Session::read_csv(&out, &c).expect("plan.csv is a session CSV of its cell");
    assert_eq!(s.points.len(), 6);
    for p in &s.points {
        c.robot1.model.check_q(&p.q1).unwrap();
        c.robot2.model.check_q(&p.q2).unwrap();
    }
}

#[test]
fn plan_errors_say_what_to_change() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let cell = shipped_cell("floor-floor");
    let o = plan(&[
        "--cell",
        cell.to_str().unwrap(),
        "--n",
        "30",
        "--candidates",
        "10",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("more than the 10 candidates"), "{e}");
    let o = plan(&[
        "--cell",
        cell.to_str().unwrap(),
        "--n",
        "4",
        "--candidates",
        "8",
        "--centre-mm",
        "20000,-20000,0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("outside the common workspace") && e.contains("move the centre"),
        "{e}"
    );
    assert!(!out.exists(), "no plan written on error");
}

/// A plan that calibrate --cell would refuse (3 handclasps: 9 residual rows for 6 placement
/// unknowns and the screen's 6 of redundancy) is refused with calibrate --cell's words, no
/// accuracy predicted and no plan written; calibrate --cell refuses such a session alike.
#[test]
fn plan_refuses_a_session_calibrate_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("plan.csv");
    let cell_path = shipped_cell("floor-wall");
    let o = plan(&[
        "--cell",
        cell_path.to_str().unwrap(),
        "--n",
        "3",
        "--candidates",
        "12",
        "--random-draws",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    let words = "the session gives only 9 residual rows, but the fit needs at least 12";
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains(words) && e.contains("no accuracy is predicted"),
        "{e}"
    );
    assert!(!out.exists(), "no plan written");
    let cell = Cell::from_toml_file(&cell_path).unwrap();
    let session = crate::support::random_session(&cell, 3, 1);
    let csv = crate::support::write_session_csv(dir.path(), "s3.csv", &session, &cell);
    let e = crate::support::stderr_of_failure(&crate::support::cell_session_args(
        "calibrate",
        &cell_path,
        &csv,
        &[],
    ));
    assert!(e.contains(words), "{e}");
}

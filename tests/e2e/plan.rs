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

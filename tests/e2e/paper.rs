//! End-to-end tests for the paper commands.

use crate::support::{handclasp, json_ok};

#[test]
fn paper_table1_json_reproduces_published_values() {
    let v = json_ok(&["paper", "table1", "--json"]);
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 15);
    for r in rows {
        for k in ["1", "2"] {
            let e_tran = r[format!("e_tran{k}_mm")].as_f64().unwrap();
            let e_rot = r[format!("e_rot{k}_deg")].as_f64().unwrap();
            let pt = r[format!("published_e_tran{k}_mm")].as_f64().unwrap();
            let pr = r[format!("published_e_rot{k}_deg")].as_f64().unwrap();
            // The table's rounding tolerance (±0.2 mm, ±0.01°).
            assert!((e_tran - pt).abs() <= 0.2 + 1e-9, "{r}");
            assert!((e_rot - pr).abs() <= 0.01 + 1e-9, "{r}");
            assert!(r[format!("geodesic{k}_deg")].as_f64().unwrap() > 0.0);
        }
    }
    assert_eq!(rows[0]["mounts"], "floor-floor");
    assert_eq!(rows[14]["mounts"], "floor-wall");
    assert!(
        !rows[3]["notes"].as_array().unwrap().is_empty(),
        "experiment 4's e_tran1 is inconsistent"
    );
}

#[test]
fn paper_table1_text_mentions_inconsistencies() {
    let out = handclasp(&["paper", "table1"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("agree with the published ones"), "{text}");
    assert!(text.contains("experiment 4: e_tran1"), "{text}");
}

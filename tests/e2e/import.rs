//! `handclasp import` on the CTU dual-arm Motoman dataset (`/work/shared/data/ctu-motoman/`, or
//! `$CTU_MOTOMAN_DATA`) with the shipped maps (`tools/ctu-motoman/maps/`), and
//! `calibrate --cell cells/ctu-motoman.toml --model kinematic` on the imported self-contact
//! session. Skipped, with the reason printed, when the data folder is absent.

use crate::support::{
    cell_session_args, ctu_data_or_skip, ctu_import, floats, handclasp, shipped_cell, stdout_json,
};

#[test]
fn ctu_maps_import_and_self_contact_calibrates() {
    let Some(data) = ctu_data_or_skip() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // Tracker maps: rows without a tracker value are skipped and counted (README: 212 of 216
    // right-arm grid poses and 208 of 216 left-arm ones have one).
    let tr = dir.path().join("tracker_right.csv");
    let text = ctu_import(
        &data,
        "tracker_right.toml",
        &["leica_right_hand_6x6x6_dataset.csv"],
        &tr,
    );
    assert!(text.contains("212 tracker row(s), 4 skipped"), "{text}");
    let tl = dir.path().join("tracker_left.csv");
    let text = ctu_import(
        &data,
        "tracker_left.toml",
        &["leica_left_hand_6x6x6_dataset.csv"],
        &tl,
    );
    assert!(text.contains("208 tracker row(s), 8 skipped"), "{text}");
    let pl = dir.path().join("plane.csv");
    let text = ctu_import(
        &data,
        "plane_right.toml",
        &[
            "no_leica_wall_table1_5x5_dataset.csv",
            "no_leica_lower_table1_5x5_dataset.csv",
        ],
        &pl,
    );
    assert!(text.contains("wrote 184 rows"), "{text}");
    let body = std::fs::read_to_string(&pl).unwrap();
    assert!(body.contains(",plane,1,no_leica_wall_table1_5x5_dataset,"));
    // The maps keep the source file's pose number (`source_id = "pose"`): the last column, the
    // file's `pose` column (1, 2, … in each file).
    let header = body.lines().find(|l| !l.starts_with('#')).unwrap();
    assert!(header.ends_with(",source_id"), "{header}");
    let last_ids: Vec<&str> = body
        .lines()
        .filter(|l| l.contains(",plane,1,no_leica_lower_table1_5x5_dataset,"))
        .map(|l| l.rsplit(',').next().unwrap())
        .collect();
    let want: Vec<String> = (1..=last_ids.len()).map(|k| k.to_string()).collect();
    assert!(last_ids.len() > 1 && last_ids == want, "{last_ids:?}");
    // Self-contact (two 16-pose tracker-session files: the test stays quick in a debug build;
    // the 502 no-tracker poses import the same way).
    let sc = dir.path().join("self.csv");
    let text = ctu_import(
        &data,
        "self_contact.toml",
        &[
            "leica_self_lower1_4x4_dataset.csv",
            "leica_self_upper1_4x4_dataset.csv",
        ],
        &sc,
    );
    assert!(text.contains("wrote 32 rows"), "{text}");
    let v = stdout_json(&handclasp(&cell_session_args(
        "calibrate",
        &shipped_cell("ctu-motoman"),
        &sc,
        &["--model", "kinematic", "--json"],
    )));
    assert_eq!(v["rows_by_kind"]["contact"], 32);
    assert_eq!(v["groups"]["contact"].as_array().map(Vec::len), Some(2));
    // The cell's `[b1_from_b2]` prior (σ 0.01 mm, 0.001°: both arms on one base) holds the
    // placement: contacts alone moved it ~3 m and hit the iteration cap without it.
    assert_eq!(v["stopped"], "converged", "{}", v["stopped"]);
    let b = &v["b1_from_b2"];
    for (k, s) in b["sigma"].as_array().unwrap().iter().enumerate() {
        let sigma = s["sigma"].as_f64().unwrap();
        let prior = if k < 3 { 0.01 } else { 0.001 };
        assert!(
            sigma <= prior * PRIOR_SIGMA_SLACK,
            "{}: posterior σ {sigma} above the prior {prior}",
            s["name"]
        );
    }
    for (k, x) in b["xyz_mm"].as_array().unwrap().iter().enumerate() {
        let x = x.as_f64().unwrap();
        assert!(x.abs() < 0.01, "b1_from_b2 xyz_mm[{k}] = {x} mm, σ 0.01 mm");
    }
    let q: Vec<f64> = floats(&b["quaternion_wxyz"]);
    let angle_rad = 2.0
        * (q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            .sqrt()
            .atan2(q[0].abs());
    assert!(
        angle_rad.to_degrees() < 0.001,
        "b1_from_b2 rotated by {}°, σ 0.001°",
        angle_rad.to_degrees()
    );
}

/// Round-off allowance on the reported posterior σ against the prior σ.
const PRIOR_SIGMA_SLACK: f64 = 1.0 + 1e-6;

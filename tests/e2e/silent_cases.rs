//! End-to-end tests of the silent cases left by issue 21's result check: 30 % blunders and
//! nearly collinear points in points mode and in `calibrate --cell --model placement`, the
//! `--json` refusal object (`calibrate --cell`, `diagnose`, `calibrate POINTS.csv`), and
//! `diagnose`'s `--force` / `--overwrite` split. Every case ends in a refusal or a `warning:`
//! that names the problem; the healthy counterparts stay quiet.

use std::path::{Path, PathBuf};
use std::process::Output;

use handclasp_cell::{Cell, Session};
use nalgebra::{Point3, Vector3};
use serde_json::Value;

use crate::result_check::{truth, with_reported_tips, workdir};
use crate::support::{
    cell_session_args, handclasp, random_session, shipped_cell, write_session_csv,
};

/// The bad rows of the 30 % blunder sessions (0-based; 6 of 20).
const BAD: [usize; 6] = [1, 4, 7, 11, 15, 18];

/// A 20-point session simulated on the example truth (seeded), written with the shipped
/// floor-wall cell's tips, after `edit`.
fn points_session(dir: &Path, name: &str, seed: u64, edit: impl Fn(&mut Session)) -> PathBuf {
    let mut s = random_session(&truth(), 20, seed);
    let cell = Cell::from_toml_file(&shipped_cell("floor-wall")).unwrap();
    s = with_reported_tips(&s, &cell);
    edit(&mut s);
    write_session_csv(dir, name, &s, &cell)
}

/// Robot 2's point of each of [`BAD`] moved by 12–37 mm (a bad handclasp: the tips did not
/// meet), in fixed directions.
fn blunders(s: &mut Session) {
    for (k, &i) in BAD.iter().enumerate() {
        let dir = Vector3::new(1.0, -2.0 + k as f64, 0.5 * k as f64 - 1.0).normalize();
        s.points[i].p_b2 += dir * (0.012 + 0.005 * k as f64);
    }
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// 30 % blunders in points mode mask one another in the leave-one-out test: a `warning:`
/// names all of them (lsq and constrained with the mounts), the JSON flags them; the same
/// session without them is quiet.
#[test]
fn points_thirty_percent_blunders_are_named() {
    let dir = workdir();
    let bad = points_session(dir.path(), "bad.csv", 31, blunders);
    let good = points_session(dir.path(), "good.csv", 31, |_| {});
    // Rows are file lines (the header is line 1).
    let rows: Vec<u64> = BAD.iter().map(|&i| i as u64 + 2).collect();
    for mounts in [&[][..], &["--mounts", "floor-wall"][..]] {
        let mut args = vec!["calibrate", bad.to_str().unwrap(), "--json"];
        args.extend_from_slice(mounts);
        let out = handclasp(&args);
        let err = stderr(&out);
        assert!(out.status.success(), "{err}");
        assert!(
            err.contains(
                "warning: 6 of 20 rows (30 %) disagree with the rigid fit of the other 14"
            ) && err.contains("mask one another")
                && err.contains(&format!("{rows:?}")),
            "{mounts:?}: {err}"
        );
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        let flagged: Vec<u64> = json["outliers"]["flagged_rows"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap())
            .collect();
        assert_eq!(flagged, rows, "{mounts:?}");
        let mut args = vec!["calibrate", good.to_str().unwrap()];
        args.extend_from_slice(mounts);
        let out = handclasp(&args);
        assert!(
            out.status.success() && !stderr(&out).contains("warning:"),
            "{}",
            stderr(&out)
        );
    }
}

/// Points nearly on a line (1 m long, ±2 mm across): a `warning:` says so with the fit's
/// rotation uncertainty; the random layout is quiet (tested above).
#[test]
fn points_nearly_collinear_warn() {
    let dir = workdir();
    let cell = truth();
    let path = dir.path().join("line.csv");
    let mut text = String::from("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n");
    for i in 0..20 {
        let t = i as f64 / 19.0 - 0.5;
        // Deterministic sideways offsets of ±2 mm, a line ratio of ~0.003.
        let side = 0.002 * ((i * 7 % 5) as f64 / 2.0 - 1.0);
        let p_b1 = Point3::new(0.475 + 0.8 * t, -0.05 + 0.6 * t + side, 0.995 - side);
        let p_b2 = cell.b1_from_b2.inverse() * p_b1;
        text.push_str(&format!(
            "{},{},{},{},{},{}\n",
            p_b1.x * 1e3,
            p_b1.y * 1e3,
            p_b1.z * 1e3,
            p_b2.x * 1e3,
            p_b2.y * 1e3,
            p_b2.z * 1e3
        ));
    }
    std::fs::write(&path, text).unwrap();
    let out = handclasp(&["calibrate", path.to_str().unwrap()]);
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: the 20 points are nearly collinear")
            && err.contains("the rotation about their line is poorly determined"),
        "{err}"
    );
}

/// `calibrate --cell --model placement` with 30 % blunders (12 of 40 rows, robot 2's joints
/// 1–3 off by 1.5–3°): the blunder screen, its scale inflated by them, rejects few; the result
/// check names the rest as blunders that mask one another. A correct session stays quiet
/// (`result_check::a_correct_session_is_quiet`).
#[test]
fn placement_thirty_percent_blunders_are_named() {
    let dir = workdir();
    let mut s = random_session(&truth(), 40, 33);
    for (k, i) in (0..40)
        .step_by(10)
        .flat_map(|b| [b + 1, b + 4, b + 8])
        .enumerate()
    {
        s.points[i].q2[k % 3] += (1.5 + 0.125 * k as f64).to_radians();
    }
    let reported = shipped_cell("floor-wall");
    let cell = Cell::from_toml_file(&reported).unwrap();
    let csv = write_session_csv(
        dir.path(),
        "blunders.csv",
        &with_reported_tips(&s, &cell),
        &cell,
    );
    let out = handclasp(&cell_session_args(
        "calibrate",
        &reported,
        &csv,
        &["--model", "placement", "--json"],
    ));
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.lines()
            .any(|l| l.starts_with("warning:") && l.contains("blunders that mask one another")),
        "{err}"
    );
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let check = &json["result_check"];
    assert_eq!(check["status"], "warning");
    let masked = check["checks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == "masked_blunders")
        .expect("the masked_blunders check");
    assert!(masked["value"].as_f64().unwrap() >= 4.0, "{masked}");
}

/// `--json` on a refusal prints the refusal object on stdout (status, reason, check values),
/// exit non-zero, for `calibrate --cell`, `diagnose` and `calibrate POINTS.csv`.
#[test]
fn refusals_print_their_json() {
    let dir = workdir();
    let ceiling = Cell::from_toml_file(&shipped_cell("floor-ceiling")).unwrap();
    let s = random_session(&ceiling, 20, 16);
    let cell = Cell::from_toml_file(&shipped_cell("floor-wall")).unwrap();
    let csv = write_session_csv(
        dir.path(),
        "ceiling.csv",
        &with_reported_tips(&s, &cell),
        &cell,
    );
    for (command, extra) in [
        ("calibrate", &["--model", "placement"][..]),
        ("diagnose", &["--trials", "20"][..]),
    ] {
        let mut rest = vec!["--json"];
        rest.extend_from_slice(extra);
        let out = handclasp(&cell_session_args(
            command,
            &shipped_cell("floor-wall"),
            &csv,
            &rest,
        ));
        let err = stderr(&out);
        assert!(!out.status.success(), "{command}: {err}");
        let refusal: Value = serde_json::from_slice(&out.stdout).expect("refusal JSON");
        assert_eq!(refusal["status"], "refused", "{command}");
        let reason = refusal["reason"].as_str().unwrap();
        assert!(
            reason.contains("another cell, floor-ceiling.toml"),
            "{reason}"
        );
        assert!(
            err.contains(&format!("error: {reason}")),
            "{command}: {err}"
        );
        let checks = refusal["result_check"]["checks"].as_array().unwrap();
        assert!(checks
            .iter()
            .any(|c| c["name"] == "placement_rotation_deg" && c["value"].as_f64().unwrap() > 80.0));
    }
    // Points mode: robot 2's rows shifted by one.
    let shifted = points_session(dir.path(), "shifted.csv", 32, |s| {
        let p2: Vec<_> = s.points.iter().map(|p| p.p_b2).collect();
        for (i, p) in s.points.iter_mut().enumerate() {
            p.p_b2 = p2[(i + 1) % p2.len()];
        }
    });
    let out = handclasp(&["calibrate", shifted.to_str().unwrap(), "--json"]);
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    let refusal: Value = serde_json::from_slice(&out.stdout).expect("refusal JSON");
    assert_eq!(refusal["status"], "refused");
    assert_eq!(refusal["command"], "calibrate");
    let m = &refusal["misfit"];
    assert!(m["median_residual_mm"].as_f64().unwrap() > m["limit_mm"].as_f64().unwrap());
    assert_eq!(m["points"], 20);
    assert!(err.contains(&format!("error: {}", refusal["reason"].as_str().unwrap())));
}

/// `diagnose --force` no longer overwrites an export folder: with a non-empty folder it is
/// refused naming `--overwrite`, which writes into it.
#[test]
fn diagnose_overwrite_is_not_force() {
    let dir = workdir();
    let csv = points_session(dir.path(), "ok.csv", 34, |_| {});
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    std::fs::write(out_dir.join("old.txt"), "x").unwrap();
    let export = out_dir.to_str().unwrap();
    let cell = shipped_cell("floor-wall");
    let old = handclasp(&cell_session_args(
        "diagnose",
        &cell,
        &csv,
        &["--trials", "20", "--export", export, "--force"],
    ));
    let err = stderr(&old);
    assert!(!old.status.success(), "{err}");
    assert!(
        err.contains(
            "--force keeps a refused result; it no longer overwrites an export (add --overwrite)"
        ),
        "{err}"
    );
    let new = handclasp(&cell_session_args(
        "diagnose",
        &cell,
        &csv,
        &["--trials", "20", "--export", export, "--overwrite"],
    ));
    assert!(new.status.success(), "{}", stderr(&new));
    assert!(out_dir.join("cell_corrected.toml").exists());
}

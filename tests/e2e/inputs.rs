//! End-to-end tests for the inputs a new user brings (issue 10): files saved with `;` or tabs or a
//! BOM, output piped into `head`, duplicated session rows. Each test is named after its input.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Stdio;

use handclasp_cell::Cell;

use crate::support::{handclasp_command, random_session, shipped_cell};

/// `n` exact rigid point pairs (b1_from_b2 = Rz(30°), (1500, 200, 50) mm) as a points CSV with
/// `sep` between fields, on a spiral so that no two points are duplicates.
fn points_text(n: usize, sep: &str) -> String {
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let mut text = [
        "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
    ]
    .join(sep)
        + "\n";
    for i in 0..n {
        let a = i as f64 * 0.37;
        let r = 300.0 + 500.0 * (i as f64 / n as f64);
        let p2 = [
            r * a.cos(),
            r * a.sin(),
            200.0 + 800.0 * ((i * 7) % 11) as f64 / 11.0,
        ];
        let p1 = [
            c * p2[0] - s * p2[1] + 1500.0,
            s * p2[0] + c * p2[1] + 200.0,
            p2[2] + 50.0,
        ];
        let row: Vec<String> = p1.iter().chain(&p2).map(|v| format!("{v:.6}")).collect();
        text += &(row.join(sep) + "\n");
    }
    text
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::File::create(&path)
        .unwrap()
        .write_all(text.as_bytes())
        .unwrap();
    path
}

/// `calibrate` on a points file saved by a spreadsheet in a European locale (`;`), copied from a
/// table (tabs), and with a BOM: the same fit as the comma file.
#[test]
fn semicolon_separated_points_calibrate() {
    let dir = tempfile::tempdir().unwrap();
    let json = |path: &Path| {
        let out = handclasp_command()
            .arg("calibrate")
            .arg(path)
            .args(["--method", "lsq", "--json"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["b1_from_b2"].clone()
    };
    let want = json(&write(dir.path(), "comma.csv", &points_text(8, ",")));
    for (name, text) in [
        ("semicolon.csv", points_text(8, ";")),
        ("tab.csv", points_text(8, "\t")),
        ("bom.csv", format!("\u{feff}{}", points_text(8, ";"))),
    ] {
        assert_eq!(json(&write(dir.path(), name, &text)), want, "{name}");
    }
}

/// `handclasp calibrate … | head`: stdout closed early ends quietly with exit 0, not a
/// broken-pipe panic (exit 101). The text report lists every row (~1500 lines, far beyond a pipe's
/// buffer), so the write fails whenever the reader closes.
#[test]
fn calibrate_piped_into_head() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "many.csv", &points_text(1500, ","));
    let mut child = handclasp_command()
        .arg("calibrate")
        .arg(&path)
        .args(["--method", "lsq"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    let mut first = [0u8; 64];
    std::io::Read::read_exact(&mut stdout, &mut first).unwrap();
    drop(stdout);
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("panicked"), "{err}");
}

/// A session of the shipped floor–floor cell written with `sep` and a BOM.
fn session_text(sep: &str, bom: bool) -> String {
    let cell = Cell::from_toml_file(&cell_path()).unwrap();
    let s = random_session(&cell, 12, 4);
    let text = s
        .to_csv_string(cell.robot1.model.dof(), cell.robot2.model.dof())
        .replace(',', sep);
    if bom {
        format!("\u{feff}{text}")
    } else {
        text
    }
}

fn cell_path() -> PathBuf {
    shipped_cell("floor-floor")
}

/// `diagnose` on a session saved with a BOM and `;` or tabs: the pre-checks and the reader pass
/// (the BOM used to reach the pre-check with an invisible character in the message).
#[test]
fn bom_semicolon_session_diagnose() {
    let dir = tempfile::tempdir().unwrap();
    for (name, sep) in [("semicolon.csv", ";"), ("tab.csv", "\t")] {
        let path = write(dir.path(), name, &session_text(sep, true));
        let out = handclasp_command()
            .args(["diagnose", "--cell"])
            .arg(cell_path())
            .arg("--session")
            .arg(&path)
            .args(["--json", "--trials", "20"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{name}: {err}");
        assert!(!err.contains('\u{feff}'), "{name}: {err}");
    }
}

/// `ik --xyz-mm 1.2,0,0.9` (metres): refused, not "reachable", with the unit and the ×1000 fix.
#[test]
fn ik_xyz_mm_in_metres() {
    let robot = concat!(env!("CARGO_MANIFEST_DIR"), "/../../robots/hp20.urdf");
    let out = handclasp_command()
        .args(["ik", "--robot", robot, "--xyz-mm", "1.2,0,0.9"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("look like metres") && err.contains("--xyz-mm 1200,0,900"),
        "{err}"
    );
}

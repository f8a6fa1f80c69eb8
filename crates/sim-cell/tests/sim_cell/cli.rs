//! The `sim-cell` binary as a user runs it.

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_sim-cell"))
}

#[test]
fn small_sweep_finishes_and_writes_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["sweep", "--seed", "7", "--trials", "20", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("median") && stdout.contains("wrote"),
        "{stdout}"
    );
    let trials = std::fs::read_to_string(dir.path().join("trials.csv")).unwrap();
    // 3 mounts × 4 noise × 4 spread × 4 n × 20 trials × 5 methods + header.
    assert_eq!(trials.lines().count(), 3 * 4 * 4 * 4 * 20 * 5 + 1);
    for f in [
        "summary.csv",
        "spread_floor-wall.svg",
        "noise_floor-ceiling.svg",
    ] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    let svg = std::fs::read_to_string(dir.path().join("spread_floor-floor.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("constrained"));
    // Same seed, one thread: byte-identical trials.csv.
    let dir1 = tempfile::tempdir().unwrap();
    let out = bin()
        .args([
            "sweep",
            "--seed",
            "7",
            "--trials",
            "20",
            "--threads",
            "1",
            "--out",
        ])
        .arg(dir1.path())
        .output()
        .unwrap();
    assert!(out.status.success());
    assert_eq!(
        trials,
        std::fs::read_to_string(dir1.path().join("trials.csv")).unwrap()
    );
}

#[test]
fn session_command_writes_a_session() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.csv");
    let cell = concat!(env!("CARGO_MANIFEST_DIR"), "/../../cells/floor-floor.toml");
    let out = bin()
        .args([
            "session",
            "--cell",
            cell,
            "--n",
            "5",
            "--layout",
            "random",
            "--spread-mm",
            "800",
            "--seed",
            "3",
            "--out",
        ])
        .arg(&path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text.lines().count(), 6);
    assert!(text.starts_with("point,r1_q1_deg,"));
}

#[test]
fn bad_cell_error_names_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../cells/floor-wall.toml"
    ))
    .unwrap()
    .replace("repeatability_mm", "repeatibility_mm");
    std::fs::write(&path, text).unwrap();
    let out = bin()
        .args(["session", "--cell"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("repeatibility_mm") && err.contains("repeatability_mm"),
        "{err}"
    );
}

/// The library says "reduce the spread"; the binary names the flags that set it.
#[test]
fn unreachable_layout_names_the_flags() {
    let out = bin()
        .args(["session", "--n", "4", "--spread-mm", "6000", "--seed", "1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("reduce the spread") && err.contains("--spread-mm"),
        "{err}"
    );
}

#[test]
fn bad_grid_axis_is_an_error_not_a_panic() {
    let out = bin()
        .args(["sweep", "--spread-mm=-5", "--trials", "1"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("spread") && !err.contains("panicked"), "{err}");
}

#[test]
fn paper_command_sets_the_simulation_beside_table1() {
    // Small and seeded: the σ fit and the side-by-side table must be there, and the same seed
    // must give the same JSON.
    let run = || {
        let out = bin()
            .args(["paper", "--trials", "300", "--bootstrap", "0", "--json"])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    let a = run();
    assert_eq!(a, run(), "same seed, different report");
    let v: serde_json::Value = serde_json::from_slice(&a).unwrap();
    let text = v.to_string();
    assert!(
        text.contains("sigma") && text.contains("floor-wall"),
        "{text:.400}"
    );
}

/// `--centre-mm 475,-50,995`, the documented form, with a negative coordinate (and a negative
/// first one); a wrong count says what was given and the expected form.
#[test]
fn centre_mm_with_negative_values() {
    for centre in ["475,-50,995", "-300,200,995"] {
        let out = bin()
            .args([
                "session",
                "--n",
                "4",
                "--spread-mm",
                "300",
                "--centre-mm",
                centre,
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{centre}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 5);
    }
    let out = bin()
        .args(["session", "--centre-mm", "475,-50"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("`475,-50` has 2 value(s)") && err.contains("e.g. 475,-50,995"),
        "{err}"
    );
}

/// `sim-cell session … | head`: stdout closed early ends quietly with exit 0, not a broken-pipe
/// panic (exit 101). The output (600 rows, ~130 kB) is far beyond a pipe's buffer, so the write fails
/// whenever the reader closes.
#[test]
fn session_piped_into_head() {
    let mut child = bin()
        .args([
            "session",
            "--n",
            "300",
            "--layout",
            "random",
            "--spread-mm",
            "600",
        ])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
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

/// `sim-cell session --kind mixed` writes every kind; `--points-csv` and `--plan` take the teach
/// points from a file (a plan's joints seed the poses: the regenerated session's joints stay
/// within a degree of the plan's on a cell without errors), and errors name the file and line.
#[test]
fn session_kinds_points_csv_and_plan() {
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let out = bin().arg("session").args(args).output().unwrap();
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (ok, csv, err) = run(&[
        "--kind",
        "mixed",
        "--n",
        "12",
        "--layout",
        "random",
        "--spread-mm",
        "600",
    ]);
    assert!(ok, "{err}");
    assert!(
        err.contains("rows: 2 coincident, 2 contact, 4 tracker, 4 plane"),
        "{err}"
    );
    assert!(csv.lines().next().unwrap().contains(",kind,robot,group,"));
    assert_eq!(csv.lines().count(), 13);

    let points = dir.path().join("points.csv");
    std::fs::write(
        &points,
        "x_mm,y_mm,z_mm\n400,-100,900\n600,100,1000\n500,0,1100\n",
    )
    .unwrap();
    let plan = dir.path().join("plan.csv");
    let (ok, _, err) = run(&[
        "--points-csv",
        points.to_str().unwrap(),
        "--noise-mm",
        "0",
        "--out",
        plan.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let plan_text = std::fs::read_to_string(&plan).unwrap();
    assert_eq!(plan_text.lines().count(), 4);
    let (ok, regenerated, err) = run(&["--plan", plan.to_str().unwrap(), "--seed", "5"]);
    assert!(ok, "{err}");
    assert!(!regenerated.contains("kind"));
    for (a, b) in plan_text.lines().zip(regenerated.lines()).skip(1) {
        let fa: Vec<f64> = a.split(',').map(|x| x.parse().unwrap()).collect();
        let fb: Vec<f64> = b.split(',').map(|x| x.parse().unwrap()).collect();
        // Joint columns 1..=13 (7 + 6 joints of the floor–wall cell): the planned pose.
        for k in 1..=13 {
            assert!(
                (fa[k] - fb[k]).abs() < 1.0,
                "column {k}: {} vs {}",
                fa[k],
                fb[k]
            );
        }
    }
    std::fs::write(&points, "x_mm,y_mm,z_mm\n400,-100,abc\n").unwrap();
    let (ok, _, err) = run(&["--points-csv", points.to_str().unwrap()]);
    assert!(!ok && err.contains("line 2, column `z_mm`"), "{err}");
}

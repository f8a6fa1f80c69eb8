//! `handclasp import` of whole poses (several robots per input row, array-valued cells, the
//! source id) and its refusals, on a generated source file of the shipped floor–floor cell (7 and
//! 6 joints); and the canonical angles of a placement held at the identity by a prior
//! (`calibrate --cell` on imported contact rows).

use std::path::{Path, PathBuf};

use crate::support::{
    floats, handclasp, json_ok, shipped_cell, stderr_of_failure, stdout_json, workspace,
};

/// A source file of `n` poses: `pose` ids, robot 1's 7 joints as one numpy-style array column
/// `q1` (deg), robot 2's 6 joints in `l1..l6` (deg) and a 2-D `markers` column (mm, pandas
/// style) with one marker per hand.
fn source_csv(dir: &Path, n: usize) -> PathBuf {
    let mut text = String::from("pose,q1,l1,l2,l3,l4,l5,l6,markers\n");
    for k in 0..n {
        let a = k as f64;
        let q1: Vec<String> = (0..7)
            .map(|j| format!("{:.3}", 5.0 + 3.0 * a - 2.0 * j as f64))
            .collect();
        let q2: Vec<String> = (0..6)
            .map(|j| format!("{:.3}", -4.0 + 2.5 * a + j as f64))
            .collect();
        text += &format!(
            "id-{k},\"[{}]\",{},\"[[{}, 20.5, 30], [40, 50, {}]]\"\n",
            q1.join(" "),
            q2.join(","),
            100.0 + a,
            60.0 - a
        );
    }
    let path = dir.join("poses.csv");
    std::fs::write(&path, text).unwrap();
    path
}

/// Both hands of each pose into one tracker group: a map with a [[rows]] entry per robot.
const BOTH_HANDS: &str = r#"kind = "tracker"
group = "camera"
sigma_mm = 1.0
source_id = "pose"
[joints]
unit = "deg"
robot1 = "q1"
robot2 = ["l1", "l2", "l3", "l4", "l5", "l6"]
[[rows]]
robot = 1
[rows.tracker]
columns = "markers[0]"
unit = "mm"
[[rows]]
robot = 2
[rows.tracker]
columns = ["markers[1][0]", "markers[1][1]", "markers[1][2]"]
unit = "mm"
"#;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn import_args(map: &Path, input: &Path, out: &Path) -> Vec<String> {
    [
        "import",
        "--cell",
        shipped_cell("floor-floor").to_str().unwrap(),
        "--map",
        map.to_str().unwrap(),
        "--input",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]
    .map(String::from)
    .to_vec()
}

/// One map with both robots per row: one session with both, each pose's two rows numbered in
/// order, the array cells indexed, the source id kept in the `source_id` column.
#[test]
fn both_robots_per_row_array_cells_and_source_ids() {
    let dir = tempfile::tempdir().unwrap();
    let input = source_csv(dir.path(), 3);
    let map = write(dir.path(), "both.toml", BOTH_HANDS);
    let out = dir.path().join("session.csv");
    let mut args = import_args(&map, &input, &out);
    args.push("--json".into());
    let v = json_ok(&args);
    assert_eq!(
        (v["rows"].as_u64(), v["kind"].as_str()),
        (Some(6), Some("tracker"))
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    let seen: Vec<(&str, &str, &str, &str, &str)> = rows
        .iter()
        .map(|r| {
            (
                r[col("point")],
                r[col("robot")],
                r[col("group")],
                r[col("tracker_x_mm")],
                r[col("source_id")],
            )
        })
        .collect();
    assert_eq!(
        seen,
        [
            ("1", "1", "camera", "100.000000", "id-0"),
            ("2", "2", "camera", "40.000000", "id-0"),
            ("3", "1", "camera", "101.000000", "id-1"),
            ("4", "2", "camera", "40.000000", "id-1"),
            ("5", "1", "camera", "102.000000", "id-2"),
            ("6", "2", "camera", "40.000000", "id-2"),
        ]
    );
    // q1[6] of pose 2 (5 + 3·2 − 2·6 = −1°) and robot 2's l6 of pose 1 (−4 + 2.5 + 5 = 3.5°).
    assert_eq!(rows[4][col("r1_q7_deg")], "-1.000000");
    assert_eq!(rows[3][col("r2_q6_deg")], "3.500000");
    assert_eq!(rows[3][col("r1_q1_deg")], "");
    assert_eq!(rows[4][col("tracker_z_mm")], "30.000000");
}

/// An array column named without an element is refused naming the column and the fix; a
/// `robot2` joint list in a `robot = 1` map, and an unknown key, are refused naming the key.
#[test]
fn array_columns_unindexed_and_ignored_keys_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let input = source_csv(dir.path(), 2);
    let out = dir.path().join("s.csv");
    let unindexed = BOTH_HANDS.replace(
        "columns = \"markers[0]\"",
        "columns = [\"markers\", \"l1\", \"l2\"]",
    );
    let map = write(dir.path(), "unindexed.toml", &unindexed);
    let e = stderr_of_failure(&import_args(&map, &input, &out));
    assert!(
        e.contains("line 2, column `markers` holds an array (`[[100, 20.5, 30], [40, 50, 60]]`): name one element in the map, e.g. `markers[0]`"),
        "{e}"
    );
    let robot2_ignored = r#"kind = "tracker"
robot = 1
group = "camera"
sigma_mm = 1.0
[joints]
unit = "deg"
robot1 = "q1"
robot2 = ["l1", "l2", "l3", "l4", "l5", "l6"]
[tracker]
columns = "markers[0]"
unit = "mm"
"#;
    let map = write(dir.path(), "robot2.toml", robot2_ignored);
    let e = stderr_of_failure(&import_args(&map, &input, &out));
    assert!(
        e.contains("[joints] robot2 is given but no row uses robot 2's joints")
            && e.contains("remove it, or add a [[rows]] entry with robot = 2"),
        "{e}"
    );
    let map = write(
        dir.path(),
        "typo.toml",
        &BOTH_HANDS.replace("source_id = \"pose\"", "source_ids = \"pose\""),
    );
    let e = stderr_of_failure(&import_args(&map, &input, &out));
    assert!(e.contains("unknown key `source_ids` at the top"), "{e}");
    assert!(!out.exists(), "no session is written on a refusal");
}

/// A placement held at the identity by a prior (σ 0.01 mm, 0.001°) and fitted from contact rows
/// (made-up poses: residuals of tens of mm) whose residuals are above their stated σ (100 mm:
/// noise scale 1.5): the fit leaves a tilt of ~3e-6°, where eq 32 reads φ ≈ −ψ ≈ 172°; the
/// text prints the angles as a pure yaw, the JSON has the quaternion and the exact angles, and
/// the posterior σ stays within the prior (the noise scale does not inflate it).
#[test]
fn identity_placement_prints_canonical_angles() {
    let dir = tempfile::tempdir().unwrap();
    let input = source_csv(dir.path(), 24);
    let cell_text = std::fs::read_to_string(shipped_cell("floor-floor"))
        .unwrap()
        .replace("../robots/", &format!("{}/", workspace("robots").display()))
        .replace(
            "xyz_mm = [37.9, 1476.5, 54.5]\nzyz_deg = [-0.001, 0.001, -44.5]",
            "xyz_mm = [0.0, 0.0, 0.0]\nzyz_deg = [0.0, 0.0, 0.0]\nsigma_mm = 0.01\nsigma_deg = 0.001",
        );
    assert!(
        cell_text.contains("sigma_deg = 0.001"),
        "the cell's placement was replaced"
    );
    let cell = write(dir.path(), "one-base.toml", &cell_text);
    let map = write(
        dir.path(),
        "contact.toml",
        "kind = \"contact\"\ngroup = \"touch\"\nsigma_mm = 100\nsource_id = \"pose\"\n[joints]\nunit = \"deg\"\n\
         robot1 = \"q1\"\nrobot2 = [\"l1\", \"l2\", \"l3\", \"l4\", \"l5\", \"l6\"]\n",
    );
    let session = dir.path().join("contact.csv");
    let mut args = import_args(&map, &input, &session);
    args[2] = cell.to_str().unwrap().into();
    json_ok(&[args, vec!["--json".into()]].concat());
    let calibrate = |json: bool| {
        let mut a: Vec<String> = [
            "calibrate",
            "--cell",
            cell.to_str().unwrap(),
            "--session",
            session.to_str().unwrap(),
            "--model",
            "placement",
        ]
        .map(String::from)
        .to_vec();
        if json {
            a.push("--json".into());
        }
        handclasp(&a)
    };
    let v = stdout_json(&calibrate(true));
    let b = &v["b1_from_b2"];
    let q = floats(&b["quaternion_wxyz"]);
    assert_eq!(q.len(), 4);
    let angle_deg = 2.0
        * (q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
            .sqrt()
            .atan2(q[0].abs());
    assert!(
        angle_deg.to_degrees() < PRIOR_DEG * 10.0,
        "rotated {}°",
        angle_deg.to_degrees()
    );
    assert!(
        v["noise_scale"].as_f64().unwrap() > 1.0,
        "the contacts disagree with σ 100 mm"
    );
    // The case: a tilt that is not exactly 0, with φ and ψ far from 0 in the JSON's exact angles.
    let zyz = floats(&b["zyz_deg"]);
    assert!(zyz[1] > 0.0 && zyz[0].abs() > 1.0, "{zyz:?}");
    for s in b["sigma"].as_array().unwrap() {
        let (sigma, prior) = (
            s["sigma"].as_f64().unwrap(),
            s["prior_sigma"].as_f64().unwrap(),
        );
        assert!(
            sigma <= prior * PRIOR_SIGMA_SLACK,
            "{}: σ {sigma} above the prior {prior}",
            s["name"]
        );
    }
    let out = calibrate(false);
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("b1_from_b2: "))
        .unwrap();
    let angles: Vec<f64> = ["φ ", "θ ", "ψ "]
        .iter()
        .map(|k| {
            let at = line.find(k).unwrap() + k.len();
            line[at..]
                .split('°')
                .next()
                .unwrap()
                .trim()
                .parse()
                .unwrap()
        })
        .collect();
    assert_eq!((angles[0], angles[1]), (0.0, 0.0), "{line}");
    assert!(angles[2].abs() < PRIOR_DEG * 10.0, "{line}");
    assert!(text.contains("noise scale"), "{text}");
}

/// The cell's placement prior on rotation, degrees.
const PRIOR_DEG: f64 = 0.001;

/// Round-off allowance on the reported posterior σ against the prior σ.
const PRIOR_SIGMA_SLACK: f64 = 1.0 + 1e-6;

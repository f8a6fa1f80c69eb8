//! The mapping file's checks and the conversion of input rows: one row per input row (the
//! shipped maps' shape), several rows per input row (`[[rows]]`), array-valued cells, source
//! ids, and the keys a map would ignore.

use super::*;
use crate::fixtures::{joints, tool_point};

/// The shipped floor–wall cell with a `reflector` tool on robot 2.
fn cell() -> Cell {
    let mut cell = Cell::default_floor_wall();
    cell.robot2.tools.push(calib_core::whole_cell::Tool {
        name: "reflector".into(),
        flange_from_tip: nalgebra::Vector3::new(0.04, 0.0, 0.2),
    });
    cell
}

fn map(text: &str) -> Result<ImportMap, FormatError> {
    ImportMap::from_toml_str(text, Path::new("m.toml"), &cell())
}

const JOINTS1: &str = "robot1 = [\"a1\", \"a2\", \"a3\", \"a4\", \"a5\", \"a6\", \"a7\"]";
const JOINTS2: &str = "robot2 = [\"b1\", \"b2\", \"b3\", \"b4\", \"b5\", \"b6\"]";

/// Every error names the map file and the key, and says what would work.
#[test]
fn map_errors_name_the_key_and_the_fix() {
    let e = map("kind = \"laser\"\n[joints]\nunit = \"deg\"\n")
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "m.toml: kind = \"laser\" is not an observation kind; use one of coincident, contact, tracker, plane, face_contact"
    );
    let e = map("kind = \"face_contact\"\n[joints]\nunit = \"deg\"\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cannot be imported yet") && e.contains("n1_x"),
        "{e}"
    );
    let tracker = format!("kind = \"tracker\"\nrobot = 2\ngroup = \"g\"\nsigma_mm = 0.1\n[joints]\nunit = \"rad\"\n{JOINTS2}\n");
    let e = map(&tracker).unwrap_err().to_string();
    assert!(e.contains("a tracker map needs [tracker] columns"), "{e}");
    let e = map(&tracker.replace("robot = 2", "robot = 2\ntool = \"laser\""))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("`tool` = \"laser\"") && e.contains("tip, reflector"),
        "{e}"
    );
    let e = map(&format!(
        "kind = \"contact\"\ngroup = \"c\"\nsigma_mm = 0.1\n[joints]\nunit = \"deg\"\n{JOINTS1}\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("a contact map needs [joints] robot2"), "{e}");
    let e = map("kind = \"coincident\"\nunit = \"deg\"\n[joints]\nunit = \"deg\"\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("unknown key `unit` at the top")
            && e.contains("goes in [joints]")
            && e.contains("(keys: kind"),
        "{e}"
    );
}

/// A tracker map: joints in rad, positions in m with a σ column; a row without a tracker
/// value is skipped and counted, a `{stem}` group is the file's stem, point numbers go on
/// from the session's rows, and the session reads back through the CSV.
#[test]
fn tracker_rows_are_converted_and_empty_ones_skipped() {
    let cell = cell();
    let m = map(&format!(
        "kind = \"tracker\"\nrobot = 2\ntool = \"reflector\"\ngroup = \"{{stem}}\"\n\
         [joints]\nunit = \"rad\"\n{JOINTS2}\n\
         [tracker]\ncolumns = [\"x\", \"y\", \"z\"]\nunit = \"m\"\nsigma_column = \"s\"\n"
    ))
    .unwrap();
    assert_eq!(m.kind(), Kind::Tracker);
    let q: Vec<Vec<f64>> = (0..3).map(|k| joints(&cell.robot2, k)).collect();
    let mut text = String::from("b1,b2,b3,b4,b5,b6,x,y,z,s\n");
    for (k, q) in q.iter().enumerate() {
        let joints: Vec<String> = q.iter().map(|v| format!("{v:.12}")).collect();
        let xyz = if k == 1 {
            ",,".to_string()
        } else {
            format!("1.5,{k}.25,-0.5")
        };
        text += &format!("{},{xyz},0.000006\n", joints.join(","));
    }
    let mut session = Session::default();
    session.observations.push(SessionObservation {
        point: 1,
        kind: SessionKind::Plane {
            robot: Robot::One,
            q: joints(&cell.robot1, 0),
            tool: 0,
            group: "table".into(),
            sigma_m: 1e-4,
        },
    });
    let count = m
        .read_rows(&text, Path::new("dir/leica_right.csv"), &cell, &mut session)
        .unwrap();
    assert_eq!(
        count,
        ImportCount {
            rows: 2,
            skipped: 1
        }
    );
    let SessionObservation { point, kind } = &session.observations[2];
    assert_eq!(*point, 3);
    let SessionKind::Tracker {
        robot,
        q: q_read,
        tool,
        group,
        p_tracker,
        sigma_m,
    } = kind
    else {
        panic!("a tracker row: {kind:?}");
    };
    assert_eq!(
        (*robot, *tool, group.as_str()),
        (Robot::Two, 1, "leica_right")
    );
    assert!((p_tracker - Point3::new(1.5, 2.25, -0.5)).amax() < 1e-15);
    assert!((sigma_m - 6e-6).abs() < 1e-18);
    assert!(q_read.iter().zip(&q[2]).all(|(a, b)| (a - b).abs() < 1e-11));
    let back = Session::parse_csv(&session.csv_text(&cell), Path::new("s.csv"), &cell).unwrap();
    assert_eq!(back.kind_counts(), [0, 0, 2, 1, 0]);
    // A joint angle that is not a number is named by line and column.
    let bad = text.replacen(&format!("{:.12}", q[0][0]), "abc", 1);
    let e = m
        .read_rows(&bad, Path::new("in.csv"), &cell, &mut Session::default())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "in.csv: line 2, column `b1`: `abc` is not a number");
}

/// A coincident map: joints in degrees, the tips computed by the nominal models with the
/// row's tools; default tools give handclasp points.
#[test]
fn coincident_rows_get_their_tips_from_the_nominal_models() {
    let cell = cell();
    let m = map(&format!(
        "kind = \"coincident\"\n[joints]\nunit = \"deg\"\n{JOINTS1}\n{JOINTS2}\n"
    ))
    .unwrap();
    let (q1, q2) = (joints(&cell.robot1, 4), joints(&cell.robot2, 5));
    let deg = |q: &[f64]| -> Vec<String> { q.iter().map(|v| v.to_degrees().to_string()).collect() };
    let text = format!(
        "a1,a2,a3,a4,a5,a6,a7,b1,b2,b3,b4,b5,b6\n{},{}\n",
        deg(&q1).join(","),
        deg(&q2).join(",")
    );
    let mut session = Session::default();
    let count = m
        .read_rows(&text, Path::new("c.csv"), &cell, &mut session)
        .unwrap();
    assert_eq!(
        count,
        ImportCount {
            rows: 1,
            skipped: 0
        }
    );
    let p = &session.points[0];
    assert!((p.p_b1 - tool_point(&cell.robot1, &p.q1, 0)).norm() < 1e-12);
    assert!((p.p_b2 - tool_point(&cell.robot2, &p.q2, 0)).norm() < 1e-12);
    assert!((p.q1[3] - q1[3]).abs() < 1e-12);
}

/// A map of both robots per input row: one tracker group, robot 1's joints as an array column
/// (`q1`, numpy text), robot 2's marker an element pair of a 2-D array column; one session row
/// per robot and input row, numbered in order, each keeping the input row's source id.
#[test]
fn rows_of_both_robots_from_one_input_row_with_arrays_and_source_ids() {
    let cell = cell();
    let m = map(&format!(
        "kind = \"tracker\"\ngroup = \"cam\"\nsigma_mm = 0.5\nsource_id = \"pose\"\n\
         [joints]\nunit = \"rad\"\nrobot1 = \"q1\"\n{JOINTS2}\n\
         [tracker]\ncolumns = \"markers[0]\"\nunit = \"mm\"\n\
         [[rows]]\nrobot = 1\n\
         [[rows]]\nrobot = 2\ntool = \"reflector\"\n\
         [rows.tracker]\ncolumns = [\"markers[1][0]\", \"markers[1][1]\", \"markers[1][2]\"]\nunit = \"mm\"\n"
    ))
    .unwrap();
    assert_eq!(
        (m.kinds(), m.rows_per_input_row()),
        (vec![Kind::Tracker], 2)
    );
    let mut text = String::from("pose,q1,b1,b2,b3,b4,b5,b6,markers\n");
    for k in 0..2 {
        let (q1, q2) = (joints(&cell.robot1, k), joints(&cell.robot2, k));
        let q1: Vec<String> = q1.iter().map(|v| format!("{v:.12}")).collect();
        let q2: Vec<String> = q2.iter().map(|v| format!("{v:.12}")).collect();
        text += &format!(
            "p{k},\"[{}]\",{},\"[[1 2 {k}]\n [4 5 6]]\"\n",
            q1.join(" "),
            q2.join(",")
        );
    }
    let mut session = Session::default();
    let count = m
        .read_rows(&text, Path::new("in.csv"), &cell, &mut session)
        .unwrap();
    assert_eq!(
        count,
        ImportCount {
            rows: 4,
            skipped: 0
        }
    );
    let robots: Vec<(usize, Robot, Point3<f64>)> = session
        .observations
        .iter()
        .map(|o| match &o.kind {
            SessionKind::Tracker {
                robot,
                p_tracker,
                group,
                ..
            } => {
                assert_eq!(group, "cam");
                (o.point, *robot, *p_tracker)
            }
            k => panic!("a tracker row: {k:?}"),
        })
        .collect();
    assert_eq!(
        robots.iter().map(|r| (r.0, r.1)).collect::<Vec<_>>(),
        [
            (1, Robot::One),
            (2, Robot::Two),
            (3, Robot::One),
            (4, Robot::Two)
        ]
    );
    assert!((robots[2].2 - Point3::new(1e-3, 2e-3, 1e-3)).norm() < 1e-15);
    assert!((robots[3].2 - Point3::new(4e-3, 5e-3, 6e-3)).norm() < 1e-15);
    let SessionKind::Tracker { q, .. } = &session.observations[2].kind else {
        unreachable!()
    };
    assert!(q
        .iter()
        .zip(joints(&cell.robot1, 1))
        .all(|(a, b)| (a - b).abs() < 1e-11));
    let ids: Vec<(usize, &str)> = session
        .source_ids
        .iter()
        .map(|(k, v)| (*k, v.as_str()))
        .collect();
    assert_eq!(ids, [(1, "p0"), (2, "p0"), (3, "p1"), (4, "p1")]);
    // Unindexed, the array column is refused by name.
    let e = ImportMap::from_toml_str(
        &format!(
            "kind = \"tracker\"\nrobot = 2\ngroup = \"cam\"\nsigma_mm = 0.5\n[joints]\nunit = \"rad\"\n{JOINTS2}\n\
             [tracker]\ncolumns = [\"markers\", \"b1\", \"b2\"]\nunit = \"mm\"\n"
        ),
        Path::new("m.toml"),
        &cell,
    )
    .unwrap()
    .read_rows(&text, Path::new("in.csv"), &cell, &mut Session::default())
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("in.csv: line 2, column `markers` holds an array"),
        "{e}"
    );
}

/// Keys the map would not use are refused, naming the key and the fix: a joint list of a robot
/// no row uses, a top-level key every [[rows]] entry overrides, an unknown key in an entry, a
/// misplaced key.
#[test]
fn keys_a_map_would_ignore_are_refused() {
    let tracker = "kind = \"tracker\"\nrobot = 1\ngroup = \"g\"\nsigma_mm = 0.1\n[tracker]\ncolumns = [\"x\", \"y\", \"z\"]\nunit = \"mm\"\n";
    let e = map(&format!(
        "{tracker}[joints]\nunit = \"rad\"\n{JOINTS1}\n{JOINTS2}\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("m.toml: [joints] robot2 is given but no row uses robot 2's joints")
            && e.contains("add a [[rows]] entry with robot = 2"),
        "{e}"
    );
    let e = map(&format!(
        "{tracker}[joints]\nunit = \"rad\"\n{JOINTS1}\n[[rows]]\nrobot = 1\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("`robot` at the top is overridden by every [[rows]] entry"),
        "{e}"
    );
    let e = map(&format!(
        "{tracker}[joints]\nunit = \"rad\"\n{JOINTS1}\n[[rows]]\ntool = \"tip\"\nrobto = 2\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(e.contains("unknown key `robto` at [[rows]] entry 1"), "{e}");
    let e = map(&format!(
        "robot2 = [\"b1\"]\n{tracker}[joints]\nunit = \"rad\"\n{JOINTS1}\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("unknown key `robot2` at the top") && e.contains("[joints] robot2"),
        "{e}"
    );
    // A wrong joint count names the key and both counts.
    let e = map(&format!(
        "{tracker}[joints]\nunit = \"rad\"\nrobot1 = [\"a\"]\n"
    ))
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("[joints] robot1 names 1 column(s) but needs 7"),
        "{e}"
    );
}

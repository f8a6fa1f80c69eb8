//! The session CSV: round trips (handclasp-only, mixed, face contacts), the reader's tolerance
//! of spreadsheet files (separators, BOM, CRLF, quotes, reordered and extra columns), and errors
//! that name the line, the column and the fix. Sessions come from [`crate::fixtures`] (nominal FK;
//! the simulated sessions' round trips are sim-cell's tests).

use std::path::Path;

use nalgebra::Vector3;

use crate::fixtures::{coincident_session, face_session, mixed_session};
use crate::problem::{cell_problem, FitModel};
use crate::{Cell, Session, SessionKind};

/// CSV round trip: 6 decimals of degrees / mm (half a unit in the last place), deg and mm.
const CSV_TOL: f64 = 5.1e-7;

/// The floor–floor cell with a reflector tool on each robot (the tracker rows measure it).
fn cell_both_reflectors() -> Cell {
    let mut cell = Cell::default_floor_floor();
    cell.robot1.tools.push(calib_core::whole_cell::Tool {
        name: "reflector".into(),
        flange_from_tip: Vector3::new(0.04, -0.02, 0.2),
    });
    cell.robot2.tools.push(calib_core::whole_cell::Tool {
        name: "reflector".into(),
        flange_from_tip: Vector3::new(0.05, 0.0, 0.25),
    });
    cell
}

/// A session saved by a spreadsheet in a European locale (`;`) or copied from a table (tabs),
/// with or without a BOM, reads like the comma file; the message for an unknown separator
/// shows the header it found.
#[test]
fn semicolon_separated_session() {
    let cell = Cell::default_floor_wall();
    let session = coincident_session(&cell, 5);
    let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
    let text = session.to_csv_string(d1, d2);
    let p = Path::new("session.csv");
    let want = Session::parse_csv(&text, p, &cell).unwrap();
    for sep in [";", "\t"] {
        let variant = text.replace(',', sep);
        assert_eq!(
            Session::parse_csv(&variant, p, &cell).unwrap(),
            want,
            "{sep:?}"
        );
        let bom = format!("\u{feff}{variant}");
        assert_eq!(
            Session::parse_csv(&bom, p, &cell).unwrap(),
            want,
            "BOM {sep:?}"
        );
    }
    let e = Session::parse_csv(&text.replace(',', "|"), p, &cell)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no column `point`")
            && e.contains("point|r1_q1_deg")
            && e.contains("semicolons or tabs"),
        "{e}"
    );
}

#[test]
fn session_csv_round_trips_and_is_calibrate_input() {
    let cell = Cell::default_floor_ceiling();
    let session = coincident_session(&cell, 7);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.csv");
    session.write_csv(&path, &cell).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let header = text.lines().next().unwrap();
    let mut want = String::from("point");
    for k in 1..=7 {
        want += &format!(",r1_q{k}_deg");
    }
    for k in 1..=6 {
        want += &format!(",r2_q{k}_deg");
    }
    want += ",r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm";
    assert_eq!(header, want);
    let back = Session::read_csv(&path, &cell).unwrap();
    assert_eq!(back.points.len(), 7);
    for (a, b) in session.points.iter().zip(&back.points) {
        assert_eq!(a.point, b.point);
        for (x, y) in a.q1.iter().chain(&a.q2).zip(b.q1.iter().chain(&b.q2)) {
            assert!((x.to_degrees() - y.to_degrees()).abs() < CSV_TOL);
        }
        assert!(
            (a.p_b1 - b.p_b1).amax() * 1e3 < CSV_TOL && (a.p_b2 - b.p_b2).amax() * 1e3 < CSV_TOL
        );
    }
    // Write → read → write is byte-identical.
    assert_eq!(back.to_csv_string(7, 6), text);
    // calib-core reads it as it stands.
    let pairs = calib_core::read_points_csv(&path).unwrap();
    assert_eq!(pairs.len(), 7);
    assert!((pairs.p_b1[3] - session.points[3].p_b1).amax() < 1e-9);
}

#[test]
fn bad_session_csv_names_line_and_column() {
    let cell = Cell::default_floor_wall();
    let session = coincident_session(&cell, 4);
    let text = session.to_csv_string(7, 6);
    let p = Path::new("bad.csv");
    let e = Session::parse_csv(&text.replace("r2_q3_deg", "r2_q3_rad"), p, &cell)
        .unwrap_err()
        .to_string();
    assert!(e.contains("r2_q3_rad") && e.contains("r2_q3_deg"), "{e}");
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let mut fields: Vec<&str> = lines[2].split(',').collect();
    fields[3] = "abc";
    let bad_row = fields.join(",");
    let mut t2 = lines.clone();
    t2[2] = bad_row;
    let e = Session::parse_csv(&(t2.join("\n") + "\n"), p, &cell)
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3") && e.contains("r1_q3_deg"), "{e}");
    // Tip columns in metres instead of mm: caught by the FK consistency check.
    let mut fields: Vec<String> = lines[1].split(',').map(String::from).collect();
    let n = fields.len();
    for f in &mut fields[n - 6..] {
        *f = format!("{:.6}", f.parse::<f64>().unwrap() / 1000.0);
    }
    let mut t3 = lines.clone();
    t3[1] = fields.join(",");
    let e = Session::parse_csv(&(t3.join("\n") + "\n"), p, &cell)
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 2") && e.contains("mm"), "{e}");
}

/// The session reader follows calib-core's points reader: columns found by header name in any
/// order, a UTF-8 BOM, CRLF line ends, quoted fields and extra columns are all read to the same
/// session as the file as written.
#[test]
fn session_csv_reader_accepts_reordered_columns_bom_crlf_and_extra_columns() {
    let cell = Cell::default_floor_wall();
    let session = coincident_session(&cell, 5);
    let p = Path::new("variant.csv");
    let text = session.to_csv_string(cell.robot1.model.dof(), cell.robot2.model.dof());
    let want = Session::parse_csv(&text, p, &cell).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .map(|l| l.split(',').collect::<Vec<_>>())
        .collect();
    let join = |rows: &[Vec<String>], end: &str| {
        rows.iter()
            .map(|r| r.join(","))
            .collect::<Vec<_>>()
            .join(end)
            + end
    };
    let owned = |f: &dyn Fn(usize, &Vec<&str>) -> Vec<String>| -> Vec<Vec<String>> {
        rows.iter().enumerate().map(|(i, r)| f(i, r)).collect()
    };
    let reordered = owned(&|_, r| r.iter().rev().map(|s| s.to_string()).collect());
    let extra = owned(&|i, r| {
        let mut v: Vec<String> = r.iter().map(|s| s.to_string()).collect();
        v.insert(
            3,
            if i == 0 {
                "operator".into()
            } else {
                format!("\"Lee, J{i}\"")
            },
        );
        v
    });
    let quoted = owned(&|_, r| r.iter().map(|s| format!("\"{s}\"")).collect());
    let plain = owned(&|_, r| r.iter().map(|s| s.to_string()).collect());
    let variants = [
        ("reordered", join(&reordered, "\n")),
        ("bom", format!("\u{feff}{}", join(&plain, "\n"))),
        ("crlf", join(&plain, "\r\n")),
        ("extra column", join(&extra, "\n")),
        ("quoted", join(&quoted, "\n")),
    ];
    for (name, variant) in variants {
        let got = Session::parse_csv(&variant, p, &cell).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(got, want, "{name}");
    }
    // A missing column is named, with the columns this cell needs.
    let missing = owned(&|_, r| r[1..].iter().map(|s| s.to_string()).collect());
    let e = Session::parse_csv(&join(&missing, "\n"), p, &cell)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 1") && e.contains("`point`") && e.contains("any order"),
        "{e}"
    );
}

/// A file without a `kind` column reads as before, and a handclasp-only session is written in
/// today's columns, byte for byte.
#[test]
fn session_without_kind_is_unchanged() {
    let cell = Cell::default_floor_wall();
    let s = coincident_session(&cell, 7);
    let old = s.to_csv_string(7, 6);
    assert_eq!(s.csv_text(&cell), old);
    assert!(!old.contains("kind"));
    let back = Session::parse_csv(&old, Path::new("s.csv"), &cell).unwrap();
    assert!(back.is_handclasp_only());
    assert_eq!(back.points.len(), 7);
    assert_eq!(back.csv_text(&cell), old);
    // The same rows with an all-empty or all-"coincident" kind column read identically.
    let with_kind: String = old
        .lines()
        .enumerate()
        .map(|(i, l)| {
            format!(
                "{l},{}\n",
                if i == 0 {
                    "kind"
                } else if i % 2 == 0 {
                    "coincident"
                } else {
                    ""
                }
            )
        })
        .collect();
    let back2 = Session::parse_csv(&with_kind, Path::new("s.csv"), &cell).unwrap();
    assert_eq!(back2, back);
    // And the whole-cell problem is the same.
    let a = cell_problem(&cell, &s, FitModel::Kinematic);
    let b = cell_problem(&cell, &back2, FitModel::Kinematic);
    assert_eq!(a.observations.len(), b.observations.len());
    assert!(a.trackers.is_empty() && a.planes.is_empty() && a.contacts.is_empty());
}

/// Every error names the line, the column and the fix.
#[test]
fn kind_errors_name_row_column_and_fix() {
    let cell = cell_both_reflectors();
    let s = mixed_session(&cell, 12);
    let text = s.csv_text(&cell);
    let lines: Vec<&str> = text.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    // Line 4 of the file (data row 3) is a tracker row of robot 1.
    let edit_all = |line: usize, columns: &[&str], value: &str| -> String {
        let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        let mut f: Vec<String> = out[line - 1].split(',').map(String::from).collect();
        for column in columns {
            f[col(column)] = value.into();
        }
        out[line - 1] = f.join(",");
        out.join("\n") + "\n"
    };
    let edit = |line: usize, column: &str, value: &str| edit_all(line, &[column], value);
    let err = |t: String| {
        Session::parse_csv(&t, Path::new("m.csv"), &cell)
            .unwrap_err()
            .to_string()
    };
    assert!(lines[3].contains(",tracker,1,"), "{}", lines[3]);
    let e = err(edit(4, "kind", "laser"));
    assert!(
        e.contains("line 4, column `kind`") && e.contains("coincident, contact, tracker, plane"),
        "{e}"
    );
    let e = err(edit(4, "sigma_mm", ""));
    assert!(e.contains("line 4, column `sigma_mm` is empty"), "{e}");
    let e = err(edit_all(
        4,
        &[
            "r2_q1_deg",
            "r2_q2_deg",
            "r2_q3_deg",
            "r2_q4_deg",
            "r2_q5_deg",
            "r2_q6_deg",
        ],
        "10",
    ));
    assert!(
        e.contains("line 4")
            && e.contains("joints given for robot 2")
            && e.contains("leave the other robot's joint cells empty"),
        "{e}"
    );
    let e = err(edit(4, "tool", "probe"));
    assert!(
        e.contains("line 4, column `tool`")
            && e.contains("tip, reflector")
            && e.contains("[robot1.tools]"),
        "{e}"
    );
    let e = err(edit(4, "tracker_y_mm", ""));
    assert!(e.contains("line 4, column `tracker_y_mm` is empty"), "{e}");
    let e = err(edit(4, "distance_mm", "100"));
    assert!(
        e.contains("line 4, column `distance_mm`") && e.contains("leave it empty"),
        "{e}"
    );
    let e = err(edit(4, "robot", "3"));
    assert!(e.contains("line 4, column `robot`: `3`"), "{e}");
    // Line 2 is a coincident row: its tips are required and FK-checked.
    let e = err(edit(2, "r1_x_mm", ""));
    assert!(e.contains("line 2, column `r1_x_mm` is empty"), "{e}");
    // Line 3 is a contact row: a second distance for its group must agree.
    let e = err(edit(3, "group", ""));
    assert!(e.contains("line 3, column `group` is empty"), "{e}");
}

/// A normal that is not unit is normalised on reading; a zero, non-finite or missing component
/// is an error naming the line, the column and the fix; a sphere-contact row must leave the
/// normal columns empty.
#[test]
fn face_normal_errors_name_line_column_and_fix() {
    let cell = Cell::default_floor_floor();
    let s = face_session(&cell, 4);
    let text = s.csv_text(&cell);
    let lines: Vec<&str> = text.lines().collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let edit = |line: usize, values: &[(&str, &str)]| -> String {
        let mut out: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        let mut f: Vec<String> = out[line - 1].split(',').map(String::from).collect();
        for (column, value) in values {
            f[col(column)] = value.to_string();
        }
        out[line - 1] = f.join(",");
        out.join("\n") + "\n"
    };
    let parse = |t: String| Session::parse_csv(&t, Path::new("f.csv"), &cell);
    let err = |t: String| parse(t).unwrap_err().to_string();
    let scaled = parse(edit(2, &[("n1_x", "0"), ("n1_y", "0"), ("n1_z", "2.5")])).unwrap();
    let SessionKind::FaceContact { n1_tip, .. } = &scaled.observations[0].kind else {
        panic!("a face contact");
    };
    assert_eq!(n1_tip.into_inner(), Vector3::z());
    let e = err(edit(2, &[("n2_x", "0"), ("n2_y", "0"), ("n2_z", "0")]));
    assert!(
        e.contains("line 2, columns `n2_x, n2_y, n2_z`")
            && e.contains("is zero")
            && e.contains("outward normal"),
        "{e}"
    );
    let e = err(edit(3, &[("n1_y", "NaN")]));
    assert!(
        e.contains("line 3, column `n1_y`: `NaN` is not a finite number"),
        "{e}"
    );
    let e = err(edit(3, &[("n2_z", "")]));
    assert!(
        e.contains("line 3, column `n2_z` is empty") && e.contains("outward face normal"),
        "{e}"
    );
    let e = err(edit(4, &[("kind", "contact")]));
    assert!(
        e.contains("line 4, column `n1_x`") && e.contains("does not use it"),
        "{e}"
    );
}

/// A session of every kind (tools by name, both robots' one-robot rows) and a face-contact
/// session, written and read back, give the same rows to the file's decimals (6 for degrees and
/// millimetres, 9 for the unitless normals), and writing them again gives the same text; the
/// extra columns follow the standard ones, the face-normal columns only when a face contact is
/// present.
#[test]
fn mixed_and_face_sessions_round_trip_through_the_csv() {
    let cell = cell_both_reflectors();
    let mixed = mixed_session(&cell, 24);
    assert_eq!(mixed.kind_counts(), [4, 4, 8, 8, 0]);
    let faces = face_session(&cell, 5);
    assert_eq!(faces.kind_counts(), [0, 0, 0, 0, 5]);
    for (s, tail) in [
        (&mixed, ",kind,robot,group,tool1,tool2,tool,distance_mm,sigma_mm,tracker_x_mm,tracker_y_mm,tracker_z_mm"),
        (&faces, ",tracker_z_mm,n1_x,n1_y,n1_z,n2_x,n2_y,n2_z"),
    ] {
        let text = s.csv_text(&cell);
        let header = text.lines().next().unwrap();
        assert!(header.ends_with(tail), "{header}");
        let back = Session::parse_csv(&text, Path::new("kinds.csv"), &cell).unwrap();
        assert_eq!(back.kind_counts(), s.kind_counts());
        assert_eq!(back.csv_text(&cell), text);
        for (a, b) in s.observations.iter().zip(&back.observations) {
            assert_eq!((a.point, a.kind.name()), (b.point, b.kind.name()));
            match (&a.kind, &b.kind) {
                (
                    SessionKind::Tracker {
                        robot,
                        q,
                        tool,
                        p_tracker,
                        ..
                    },
                    SessionKind::Tracker {
                        robot: r2,
                        q: q2,
                        tool: t2,
                        p_tracker: p2,
                        ..
                    },
                ) => {
                    assert_eq!((robot, tool), (r2, t2));
                    assert_eq!(*tool, 1, "the reflector");
                    assert!((p_tracker - p2).amax() * 1e3 < CSV_TOL);
                    let dq = q.iter().zip(q2).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
                    assert!(dq.to_degrees() < CSV_TOL);
                }
                (
                    SessionKind::FaceContact {
                        n1_tip,
                        n2_tip,
                        group,
                        distance_m,
                        ..
                    },
                    SessionKind::FaceContact {
                        n1_tip: m1,
                        n2_tip: m2,
                        group: g2,
                        distance_m: d2,
                        ..
                    },
                ) => {
                    assert!((n1_tip.into_inner() - m1.into_inner()).amax() < 1e-8);
                    assert!((n2_tip.into_inner() - m2.into_inner()).amax() < 1e-8);
                    assert_eq!((group, distance_m), (g2, d2));
                }
                _ => {}
            }
        }
    }
}

/// The kind names and each column's owners, derived from `Kind` and `kind_columns`, are the
/// tables they replaced (`KIND_NAMES` and `FIELD_KINDS` as written out before), in the same
/// order: the reader's messages name them in these words.
#[test]
fn kind_names_and_column_owners_are_the_former_tables() {
    assert_eq!(
        super::KIND_NAMES,
        ["coincident", "contact", "tracker", "plane", "face_contact"]
    );
    let former: [(&str, &[&str]); 16] = [
        ("robot", &["tracker", "plane"]),
        ("group", &["contact", "face_contact", "tracker", "plane"]),
        ("tool1", &["coincident", "contact", "face_contact"]),
        ("tool2", &["coincident", "contact", "face_contact"]),
        ("tool", &["tracker", "plane"]),
        ("distance_mm", &["contact", "face_contact"]),
        ("sigma_mm", &["contact", "face_contact", "tracker", "plane"]),
        ("tracker_x_mm", &["tracker"]),
        ("tracker_y_mm", &["tracker"]),
        ("tracker_z_mm", &["tracker"]),
        ("n1_x", &["face_contact"]),
        ("n1_y", &["face_contact"]),
        ("n1_z", &["face_contact"]),
        ("n2_x", &["face_contact"]),
        ("n2_y", &["face_contact"]),
        ("n2_z", &["face_contact"]),
    ];
    let columns: Vec<&str> = former.iter().map(|(c, _)| *c).collect();
    assert_eq!(columns, super::EXTRA_COLUMNS[1..]);
    for (column, kinds) in former {
        assert_eq!(super::kinds::kinds_using(column), kinds, "{column}");
    }
}

/// The optional `source_id` column: written last when a row has an id (quoted where CSV needs
/// it), read back by point number into `source_ids` (an empty cell: no id), absent from files
/// without ids, whose text is unchanged.
#[test]
fn source_ids_round_trip_and_older_files_read_as_before() {
    let cell = Cell::default_floor_wall();
    let mut s = coincident_session(&cell, 3);
    let plain = s.csv_text(&cell);
    assert!(!plain.contains(crate::session::SOURCE_ID_COLUMN));
    s.source_ids.insert(1, "pose 17".into());
    s.source_ids.insert(3, "a,b".into());
    let text = s.csv_text(&cell);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].ends_with(",source_id"), "{}", lines[0]);
    assert!(
        lines[1].ends_with(",pose 17") && lines[2].ends_with(',') && lines[3].ends_with(",\"a,b\"")
    );
    let back = Session::parse_csv(&text, Path::new("s.csv"), &cell).unwrap();
    assert_eq!(back.source_ids, s.source_ids);
    assert_eq!(back.len(), 3);
    // A mixed session carries it after the kind columns.
    let mut m = mixed_session(&cell_both_reflectors(), 4);
    let first = m.rows()[0].point();
    m.source_ids.insert(first, "id-0".into());
    let back = Session::parse_csv(
        &m.csv_text(&cell_both_reflectors()),
        Path::new("m.csv"),
        &cell_both_reflectors(),
    )
    .unwrap();
    assert_eq!(back.source_ids, m.source_ids);
    assert_eq!(back.kind_counts(), m.kind_counts());
}

/// A one-robot cell on the rail (a prismatic first joint) with a reflector tool.
fn rail_cell() -> Cell {
    let rail = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../kinematics/tests/fixtures/rail_6r.urdf"
    );
    Cell::from_toml_str(
        &format!(
            "[robot1]\nurdf = \"{rail}\"\nmount = \"floor\"\ntip_mm = [0, 0, 150]\n[robot1.tools]\nreflector = [0, 60, 80]\n"
        ),
        Path::new("."),
    )
    .unwrap()
}

/// A one-robot session of a robot with a prismatic joint: the header has robot 1's columns only,
/// the prismatic joint's named `r1_q1_mm` and written in millimetres (metres inside), and the
/// session reads back to the same values.
#[test]
fn one_robot_prismatic_session_round_trips_in_millimetres() {
    let cell = rail_cell();
    let q = vec![1.2345, 0.1, -0.2, 0.3, 0.0, 0.4, -0.5];
    let session = Session {
        observations: vec![crate::SessionObservation {
            point: 1,
            kind: SessionKind::Tracker {
                robot: calib_core::Robot::One,
                q: q.clone(),
                tool: 1,
                group: "tracker".into(),
                p_tracker: nalgebra::Point3::new(1.0, 2.0, 3.0),
                sigma_m: 5e-5,
            },
        }],
        ..Session::default()
    };
    let text = session.csv_text(&cell);
    let header = text.lines().next().unwrap();
    assert!(header.starts_with("point,r1_q1_mm,r1_q2_deg,"), "{header}");
    assert!(!header.contains("r2_"), "{header}");
    assert!(text.contains(",1234.500000,"), "{text}");
    let back = Session::parse_csv(&text, Path::new("s.csv"), &cell).unwrap();
    let (robot, q_back, tool) = back.observations[0].kind.single().unwrap();
    assert_eq!((robot, tool), (calib_core::Robot::One, 1));
    // 6 decimals of mm (the rail) and of degrees.
    assert!((q_back[0] - q[0]).abs() < CSV_TOL * 1e-3);
    for (a, b) in q_back[1..].iter().zip(&q[1..]) {
        assert!((a - b).abs() < CSV_TOL.to_radians());
    }
    assert_eq!(Session::csv_header_for(&cell)[1], "r1_q1_mm");
}

/// A one-robot cell refuses, by line and column, rows that need two robots and rows of robot 2.
#[test]
fn one_robot_cell_refuses_two_robot_rows() {
    let cell = rail_cell();
    let joints = "1000,0,30,0,0,0,0";
    let head = "point,r1_q1_mm,r1_q2_deg,r1_q3_deg,r1_q4_deg,r1_q5_deg,r1_q6_deg,r1_q7_deg,r1_x_mm,r1_y_mm,r1_z_mm,kind,robot,group,tool,sigma_mm,tracker_x_mm,tracker_y_mm,tracker_z_mm";
    let p = Path::new("s.csv");
    let e = Session::parse_csv(
        &format!("{head}\n1,{joints},,,,tracker,2,t,reflector,0.05,1,2,3\n"),
        p,
        &cell,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("line 2") && e.contains("only [robot1]"), "{e}");
    let e = Session::parse_csv(
        &format!("{head}\n1,{joints},,,,coincident,,,,,,,\n"),
        p,
        &cell,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("needs two robots") && e.contains("tracker and plane"),
        "{e}"
    );
    let e = Session::parse_csv(
        "point,r1_q1_mm,r1_q2_deg,r1_q3_deg,r1_q4_deg,r1_q5_deg,r1_q6_deg,r1_q7_deg,r1_x_mm,r1_y_mm,r1_z_mm\n1,1000,0,30,0,0,0,0,1,2,3\n",
        p,
        &cell,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("`kind` column"), "{e}");
    // The same tracker row for robot 1 reads.
    Session::parse_csv(
        &format!("{head}\n1,{joints},,,,tracker,1,t,reflector,0.05,1,2,3\n"),
        p,
        &cell,
    )
    .unwrap();
}

/// The shipped shared-trunk humanoid (`cells/humanoid-trunk.toml`).
fn humanoid_trunk() -> Cell {
    Cell::from_toml_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/humanoid-trunk.toml"),
    )
    .unwrap()
}

/// On a shared-trunk cell, a tracker or plane row of one arm carries the other arm's posture in
/// the other robot's joint columns: written, read back to the file's 6 decimals, and given to
/// the whole-cell problem with the trunk's values the row's own; a row without them reads as
/// before (none given). A trunk column that disagrees with the row's is refused naming both
/// columns; the same columns on a cell without a shared trunk are refused naming the fix.
#[test]
fn other_arm_joints_on_a_shared_trunk_round_trip_and_are_checked() {
    let cell = humanoid_trunk();
    let trunk = cell.shared_independent_joints();
    let q1: Vec<f64> = (0..10).map(|j| 0.05 * j as f64 - 0.2).collect();
    let mut q2: Vec<f64> = (0..10).map(|j| 0.3 - 0.04 * j as f64).collect();
    q2[..trunk].copy_from_slice(&q1[..trunk]);
    let tracker = |robot, q: &Vec<f64>| SessionKind::Tracker {
        robot,
        q: q.clone(),
        tool: 0,
        group: "camera".into(),
        p_tracker: nalgebra::Point3::new(1.0, 2.0, 3.0),
        sigma_m: 1e-4,
    };
    let mut session = Session {
        observations: vec![
            crate::SessionObservation {
                point: 1,
                kind: tracker(calib_core::Robot::One, &q1),
            },
            crate::SessionObservation {
                point: 2,
                kind: tracker(calib_core::Robot::Two, &q2),
            },
            crate::SessionObservation {
                point: 3,
                kind: SessionKind::Plane {
                    robot: calib_core::Robot::One,
                    q: q1.clone(),
                    tool: 0,
                    group: "table".into(),
                    sigma_m: 1e-4,
                },
            },
        ],
        ..Session::default()
    };
    session.other_arm_q.insert(1, q2.clone());
    session.other_arm_q.insert(2, q1.clone());
    let text = session.csv_text(&cell);
    let back = Session::parse_csv(&text, Path::new("s.csv"), &cell).unwrap();
    assert_eq!(back.other_arm_q.len(), 2, "{text}");
    for (point, want) in [(1, &q2), (2, &q1)] {
        for (a, b) in back.other_arm_q[&point].iter().zip(want) {
            assert!((a - b).abs() < CSV_TOL.to_radians(), "point {point}");
        }
    }
    let problem = cell_problem(&cell, &back, FitModel::KinematicCompliance);
    assert_eq!(problem.other_arm_q.len(), 2);
    let (_, q_row, _) = back.observations[0].kind.single().unwrap();
    assert_eq!(problem.other_arm_q[&1][..trunk], q_row[..trunk]);
    problem.check().unwrap();

    // Robot 2's trunk column on robot 1's row disagrees with the row's.
    let line = text.lines().nth(1).unwrap();
    let cols: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let k = cols.iter().position(|c| *c == "r2_q2_deg").unwrap();
    let mut cells: Vec<String> = line.split(',').map(str::to_string).collect();
    cells[k] = "7.5".into();
    let bad = text.replace(line, &cells.join(","));
    let e = Session::parse_csv(&bad, Path::new("s.csv"), &cell)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 2") && e.contains("`r1_q2_deg`") && e.contains("`r2_q2_deg` = 7.500000"),
        "{e}"
    );
    // The same columns on a cell without a shared trunk.
    let mut plain = cell.clone();
    plain.shared_joints = 0;
    let e = Session::parse_csv(&text, Path::new("s.csv"), &plain)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("line 2")
            && e.contains("joints given for robot 2")
            && e.contains("shared-trunk"),
        "{e}"
    );
}

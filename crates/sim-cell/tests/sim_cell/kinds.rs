//! Sessions of every observation kind: the CSV `kind` column round trip, its error messages,
//! backward compatibility of files without it, and a seeded mixed session calibrated by the
//! whole-cell fit against the truth.

use std::path::Path;

use calib_core::whole_cell::{
    calibrate_cell, measure_cooperative_error, predict_cooperative_accuracy, ScreenOptions,
    SolveOptions,
};
use handclasp_cell::Cell;
use kinematics::Axis;
use nalgebra::Vector3;
use sim_cell::whole_cell::{cell_problem, session_config_pairs, truth_estimate, FitModel};
use sim_cell::{
    generate_kind_session, generate_session, trial_rng, KindSpec, Layout, Session, SessionKind,
    SessionSpec, SimKind,
};

/// The floor–floor cell with a reflector tool on robot 1 and seeded small kinematic errors
/// (joint offsets ±0.05°, a few origins ±0.5 mm), the truth of the mixed-session tests.
fn cell_with_errors() -> Cell {
    let mut cell = Cell::default_floor_floor();
    cell.robot1.tools.push(calib_core::whole_cell::Tool {
        name: "reflector".into(),
        flange_from_tip: Vector3::new(0.04, -0.02, 0.2),
    });
    let offsets1 = [0.03, -0.04, 0.02, 0.05, -0.01, 0.03, 0.0];
    let offsets2 = [-0.02, 0.04, -0.05, 0.01, 0.03, -0.03];
    for (e, o) in cell.robot1.errors.joint_offset.iter_mut().zip(offsets1) {
        *e = f64::to_radians(o);
    }
    for (e, o) in cell.robot2.errors.joint_offset.iter_mut().zip(offsets2) {
        *e = f64::to_radians(o);
    }
    cell.robot1.errors.origin_xyz[2] = Vector3::new(0.3e-3, -0.2e-3, 0.4e-3);
    cell.robot2.errors.origin_xyz[3] = Vector3::new(-0.4e-3, 0.1e-3, 0.3e-3);
    cell
}

fn mixed(cell: &Cell, n: usize, seed: u64) -> Session {
    let spec = SessionSpec::new(n, Layout::Random, 0.7);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        tracker_tool: "reflector".into(),
        ..KindSpec::default()
    };
    generate_kind_session(cell, &spec, &kinds, None, &mut trial_rng(seed, 0))
        .map(|(s, _)| s)
        .unwrap_or_else(|e| panic!("{e}"))
}

fn cell_both_reflectors() -> Cell {
    let mut cell = cell_with_errors();
    cell.robot2.tools.push(calib_core::whole_cell::Tool {
        name: "reflector".into(),
        flange_from_tip: Vector3::new(0.05, 0.0, 0.25),
    });
    cell
}

/// A simulated mixed session written and read back gives the same rows (to the file's 6
/// decimals), and writing it again gives the same text.
#[test]
fn mixed_session_round_trips_through_the_csv() {
    let cell = cell_both_reflectors();
    let s = mixed(&cell, 24, 11);
    let counts = s.kind_counts();
    assert_eq!(counts, [4, 4, 8, 8, 0], "{counts:?}");
    let text = s.csv_text(&cell);
    assert!(text.lines().next().unwrap().ends_with(",kind,robot,group,tool1,tool2,tool,distance_mm,sigma_mm,tracker_x_mm,tracker_y_mm,tracker_z_mm"));
    let back = Session::parse_csv(&text, Path::new("mixed.csv"), &cell).unwrap();
    assert_eq!(back.kind_counts(), counts);
    assert_eq!(back.csv_text(&cell), text);
    // Six decimals of degrees and millimetres: within 1e-6 deg / 1e-6 mm of the simulation.
    for (a, b) in s.observations.iter().zip(&back.observations) {
        assert_eq!(a.point, b.point);
        assert_eq!(a.kind.name(), b.kind.name());
        if let (
            SessionKind::Tracker {
                p_tracker: p,
                tool,
                robot,
                ..
            },
            SessionKind::Tracker {
                p_tracker: q,
                tool: t2,
                robot: r2,
                ..
            },
        ) = (&a.kind, &b.kind)
        {
            assert!((p - q).amax() < 1e-9, "{p} {q}");
            assert_eq!((tool, robot), (t2, r2));
            assert_eq!(*tool, 1, "the reflector");
        }
    }
}

/// A file without a `kind` column reads as before, and a handclasp-only session is written in
/// today's columns, byte for byte.
#[test]
fn session_without_kind_is_unchanged() {
    let cell = Cell::default_floor_wall();
    let spec = SessionSpec::new(7, Layout::Tetrahedron, 0.9);
    let s = generate_session(&cell, &spec, &mut trial_rng(4, 0)).unwrap();
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
    let s = mixed(&cell, 12, 5);
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

/// Tolerance of the placement check: the fit's posterior σ per axis times this.
const SIGMA_FACTOR: f64 = 4.0;

/// A seeded mixed session (6 kinds in turn, 48 rows) calibrated with `--model kinematic`
/// recovers b1_from_b2 within 4 posterior σ per axis, every nuisance near its truth, and its
/// measured cooperative error is within a factor 2 of the prediction.
#[test]
fn calibrating_a_mixed_session_recovers_the_truth() {
    let cell = cell_both_reflectors();
    let spec = SessionSpec::new(48, Layout::Random, 0.7);
    let kinds = KindSpec {
        kind: SimKind::Mixed,
        tracker_tool: "reflector".into(),
        ..KindSpec::default()
    };
    let (s, truth) =
        generate_kind_session(&cell, &spec, &kinds, None, &mut trial_rng(21, 0)).unwrap();
    let text = s.csv_text(&cell);
    let s = Session::parse_csv(&text, Path::new("mixed.csv"), &cell).unwrap();
    let problem = cell_problem(&cell, &s, FitModel::Kinematic);
    assert_eq!(
        (
            problem.trackers.len(),
            problem.planes.len(),
            problem.contacts.len()
        ),
        (1, 1, 1)
    );
    let cal = calibrate_cell(
        &problem,
        &SolveOptions::default(),
        &ScreenOptions::default(),
    )
    .unwrap();
    let est = &cal.fit.estimate;
    let params = cal.fit.parameters(&problem);
    for axis in Axis::ALL {
        let k = axis as usize;
        let p = params
            .iter()
            .find(|p| p.param == calib_core::whole_cell::CellParam::PlacementTranslation { axis })
            .unwrap();
        let e = est.b1_from_b2.translation.vector[k] - cell.b1_from_b2.translation.vector[k];
        assert!(
            e.abs() < SIGMA_FACTOR * p.posterior_sigma,
            "{axis}: {e} m vs σ {}",
            p.posterior_sigma
        );
    }
    // Nuisances: contact distance within 4 σ_c/√n of 100 mm (8 rows, σ 0.2 mm → 0.3 mm), the
    // tracker frame within 0.5 mm at the teach centre, the plane normal within 0.1°.
    assert!((est.contact_distance_m[0] - truth.contact_distance_m).abs() < 0.3e-3);
    // The tracker frame where it is used: the image of the teach centre (its origin, 2–3 m
    // away, carries the lever arm of the frame's rotation σ).
    let c = cell.centre_b1;
    let t_err = (est.tracker_from_anchor[0] * c - truth.tracker_from_b1 * c).norm();
    assert!(
        t_err < 0.5e-3,
        "tracker frame off by {t_err} m at the teach centre"
    );
    assert!(est.planes[0].normal_anchor.angle(&truth.plane_b1.0) < 0.1f64.to_radians());
    let pairs = session_config_pairs(&s);
    let predicted = predict_cooperative_accuracy(&problem, &cal.fit, &pairs, 1).unwrap();
    let measured =
        measure_cooperative_error(&problem, est, &truth_estimate(&cell, &problem), &pairs).unwrap();
    let ratio = measured.rms_m / predicted.predicted_rms_m;
    assert!(
        (0.5..2.0).contains(&ratio),
        "measured {} vs predicted {} m",
        measured.rms_m,
        predicted.predicted_rms_m
    );
}

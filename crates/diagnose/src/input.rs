//! Input checks: a session CSV read for a cell, with pre-checks that name the usual unit
//! mistakes (radians under `*_deg`, metres under `*_mm`), and a session checked against its cell
//! (joint counts, limits, tips against FK, enough points).

use std::path::Path;

use calib_core::identify;
use handclasp_cell::Cell;
use handclasp_cell::Session;
use nalgebra::Vector3;

use crate::DiagnoseError;

/// Largest distance (m) between a session's reported tip and FK of its joint columns with the
/// cell's tip offset: 0.2 mm covers the rounding of a file and the encoder resolution.
pub const FK_TOLERANCE_M: f64 = 2e-4;

/// Checks a session against the cell: joint counts, duplicate points (the rule of
/// [`calib_core::PointPairs::check_duplicates`]), units (radians under `*_deg`, metres under
/// `*_mm`), joint limits, the reported tips against FK of the joint columns with the cell's tip
/// offsets, and that there are enough points to identify anything. `path` is named in messages.
pub fn check_session(cell: &Cell, s: &Session, path: &Path) -> Result<(), DiagnoseError> {
    let serr = |message: String| DiagnoseError::Session {
        path: path.to_path_buf(),
        message,
    };
    let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
    for p in &s.points {
        if p.q1.len() != d1 || p.q2.len() != d2 {
            return Err(serr(format!(
                "point {}: {} joint value(s) for robot 1 and {} for robot 2, but the cell's URDFs have {d1} ({}) and {d2} ({}): \
                 use the session recorded with this cell, or the cell of this session",
                p.point,
                p.q1.len(),
                p.q2.len(),
                cell.robot1.model.name(),
                cell.robot2.model.name()
            )));
        }
    }
    // The input checks every command shares (no rows, radians, metres, duplicates), with the
    // same words as calibrate --cell and import.
    handclasp_cell::check_session_inputs(s).map_err(|source| {
        handclasp_cell::FormatError::SessionCheck {
            path: path.to_path_buf(),
            source,
        }
    })?;
    let n = s.points.len();
    let needed = identify::min_points(1);
    if n < needed {
        return Err(serr(format!(
            "{n} handclasp point(s): too few to identify anything; fitting b1_from_b2 (6 unknowns) and one error \
             parameter with a meaningful test needs at least {needed} points, and the full catalogue 20–60 \
             (40 recommended)"
        )));
    }
    for p in &s.points {
        for (r, setup, q, tip) in [
            (1, &cell.robot1, &p.q1, &p.p_b1),
            (2, &cell.robot2, &p.q2, &p.p_b2),
        ] {
            let row = p.point;
            setup
                .model
                .check_q(q)
                .map_err(|e| serr(format!("point {row}, robot {r}: {e}")))?;
            let fk = kinematics::base_from_tip(&setup.model, q, &setup.flange_from_tip)
                .map_err(|e| serr(format!("point {row}, robot {r}: {e}")))?;
            let d = (fk.translation.vector - tip.coords).norm();
            if d > FK_TOLERANCE_M {
                return Err(serr(format!(
                    "point {row}: robot {r}'s tip columns differ by {:.3} mm from FK of its joint columns with \
                     the cell's tip offset ({} mm): wrong cell, wrong tip_mm, or tips not in mm / not in the robot's base frame",
                    d * 1000.0,
                    fmt3(&(setup.flange_from_tip * 1000.0))
                )));
            }
        }
    }
    Ok(())
}

/// `[x, y, z]` with 3 decimals, for messages.
fn fmt3(v: &Vector3<f64>) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
}

/// Reads a session CSV for `cell` with sim-cell's reader, after a unit pre-check that names the
/// likely mistake (radians under `*_deg`, metres under `*_mm`), then [`check_session`] on its
/// coincident handclasps at the cell's tips (`Session::points`). Rows of other kinds or tools
/// stay in `Session::observations`, which the engine does not use; a session with too few
/// coincident rows is refused, naming `handclasp calibrate --cell`.
///
/// Errors: the file cannot be read ([`DiagnoseError::Io`]); sim-cell rejects it
/// ([`DiagnoseError::Format`], or [`DiagnoseError::SessionUnits`] when a unit mistake explains
/// it); the units or the session do not fit the cell ([`DiagnoseError::Session`]).
pub fn load_session(path: &Path, cell: &Cell) -> Result<Session, DiagnoseError> {
    let text = kinematics::input::read_input_text(path, "session CSV").map_err(|e| match e {
        kinematics::input::InputError::Io { source, .. } => DiagnoseError::io(path, source),
        other => handclasp_cell::FormatError::InputFile(other).into(),
    })?;
    let serr = |message: String| DiagnoseError::Session {
        path: path.to_path_buf(),
        message,
    };
    // Before sim-cell's reader, whose FK check would refuse a unit slip without naming it; the
    // words are the shared checks' (handclasp_cell::check_session_inputs).
    let (max_deg, max_mm, rows) = unit_ranges(&text);
    let unit_error =
        if rows > 0 && max_deg > 0.0 && max_deg <= handclasp_cell::session::RADIANS_LIMIT_DEG {
            Some(handclasp_cell::SessionCheckError::RadiansAsDegrees { max_deg })
        } else if rows > 0 && max_mm > 0.0 && max_mm < handclasp_cell::session::METRES_LIMIT_MM {
            Some(handclasp_cell::SessionCheckError::MetresAsMillimetres { max_mm })
        } else {
            None
        };
    if let Some(source) = unit_error {
        return Err(handclasp_cell::FormatError::SessionCheck {
            path: path.to_path_buf(),
            source,
        }
        .into());
    }
    let session = match Session::parse_csv(&text, path, cell) {
        Ok(s) => s,
        Err(e) => {
            return Err(match unit_hint(&text, cell) {
                Some(hint) => DiagnoseError::SessionUnits { hint, source: e },
                None => e.into(),
            })
        }
    };
    if !session.is_handclasp_only() && session.points.len() < identify::min_points(1) {
        return Err(serr(format!(
            "{} coincident handclasp row(s) at the cell's tips and {} row(s) of other kinds or tools: this engine explains \
             coincident handclasps only and needs at least {}; diagnose this session with \
             `diagnose_cell_session` (what `handclasp diagnose` runs on it) or calibrate it with \
             `handclasp calibrate --cell CELL --session SESSION --model kinematic`",
            session.points.len(),
            session.observations.len(),
            identify::min_points(1)
        )));
    }
    check_session(cell, &session, path)?;
    Ok(session)
}

/// The largest |value| under the robots' `r1_*_deg`/`r2_*_deg` and `r1_*_mm`/`r2_*_mm` columns
/// (unparsable fields skipped), and the number of data rows. Text that is no CSV gives zeros (sim-cell's reader says why).
fn unit_ranges(text: &str) -> (f64, f64, usize) {
    let mut reader = calib_core::csv_reader(text);
    let Ok(names) = reader.headers().cloned() else {
        return (0.0, 0.0, 0);
    };
    let (mut max_deg, mut max_mm, mut rows) = (0.0f64, 0.0f64, 0usize);
    for record in reader.records() {
        let Ok(record) = record else {
            continue;
        };
        rows += 1;
        for (name, v) in names.iter().zip(record.iter()) {
            let Ok(v) = v.parse::<f64>() else {
                continue;
            };
            // Only the robots' own columns (r1_…, r2_…): a mixed session's sigma_mm,
            // distance_mm and tracker_*_mm are not tip coordinates.
            let robot_column = name.starts_with("r1_") || name.starts_with("r2_");
            if !robot_column {
                continue;
            }
            if name.ends_with("_deg") {
                max_deg = max_deg.max(v.abs());
            } else if name.ends_with("_mm") {
                max_mm = max_mm.max(v.abs());
            }
        }
    }
    (max_deg, max_mm, rows)
}

/// When a session's tips do not match FK of its joints, tries the usual unit mistakes on its
/// first rows (angles in radians under `*_deg`, a prismatic joint's travel in metres under its
/// `*_mm` column, tips in metres under `*_mm`) and says which one makes every tried row
/// consistent (within 1 mm), if any. The joint columns are named as the session reader wants
/// them ([`handclasp_cell::joint_column`]: `rN_qK_deg`, `rN_qK_mm` for a prismatic joint).
fn unit_hint(text: &str, cell: &Cell) -> Option<String> {
    let mut reader = calib_core::csv_reader(text);
    let names: Vec<String> = reader.headers().ok()?.iter().map(str::to_string).collect();
    let col = |n: &str| names.iter().position(|h| h == n);
    // Each robot's joint columns with whether the joint is prismatic.
    let q_cols = |r: u8, model: &kinematics::RobotModel| -> Option<Vec<(usize, bool)>> {
        model
            .joints()
            .iter()
            .enumerate()
            .map(|(k, j)| {
                let prismatic = j.kind.is_prismatic();
                col(&handclasp_cell::joint_column(r, k + 1, prismatic)).map(|c| (c, prismatic))
            })
            .collect()
    };
    let (c1, c2) = (
        q_cols(1, &cell.robot1.model)?,
        q_cols(2, &cell.robot2.model)?,
    );
    let has_prismatic = c1.iter().chain(&c2).any(|&(_, p)| p);
    let t_cols: Vec<usize> = [
        "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
    ]
    .iter()
    .map(|n| col(n))
    .collect::<Option<_>>()?;
    let rows: Vec<Vec<f64>> = reader
        .records()
        .take(5)
        .filter_map(Result::ok)
        .map(|record| {
            record
                .iter()
                .map(|v| v.parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    // Every row consistent when the file's angles are multiplied by `angle_scale`, its prismatic
    // joints' values by `travel_scale` and its tips by `length_scale` (each to SI).
    let consistent = |angle_scale: f64, travel_scale: f64, length_scale: f64| {
        rows.iter().all(|v| {
            let get = |c: &[(usize, bool)]| {
                c.iter()
                    .map(|&(i, prismatic)| {
                        let scale = if prismatic { travel_scale } else { angle_scale };
                        v.get(i).copied().unwrap_or(f64::NAN) * scale
                    })
                    .collect::<Vec<f64>>()
            };
            let (q1, q2) = (get(&c1), get(&c2));
            let t: Vec<f64> = t_cols
                .iter()
                .map(|&i| v.get(i).copied().unwrap_or(f64::NAN) * length_scale)
                .collect();
            if !q1.iter().chain(&q2).chain(&t).all(|x| x.is_finite()) {
                return false;
            }
            let f1 = kinematics::base_from_tip_unchecked(
                &cell.robot1.model,
                &q1,
                &cell.robot1.flange_from_tip,
            );
            let f2 = kinematics::base_from_tip_unchecked(
                &cell.robot2.model,
                &q2,
                &cell.robot2.flange_from_tip,
            );
            (f1.translation.vector - Vector3::new(t[0], t[1], t[2])).norm() < 1e-3
                && (f2.translation.vector - Vector3::new(t[3], t[4], t[5])).norm() < 1e-3
        })
    };
    let deg = std::f64::consts::PI / 180.0;
    // The file's units: degrees and millimetres (a prismatic joint's travel in mm too).
    let (mm, m) = (1e-3, 1.0);
    if consistent(1.0, mm, mm) {
        Some("the joint columns are consistent with the tips if read as RADIANS: the columns are *_deg, so convert the angles to degrees".into())
    } else if consistent(deg, mm, m) {
        Some("the tip columns are consistent with the joints if read as METRES: the columns are *_mm, so convert the tips to millimetres".into())
    } else if consistent(1.0, mm, m) {
        Some("the session is consistent if its angles are radians and its tips metres: the columns are *_deg and *_mm, so convert both".into())
    } else if has_prismatic && consistent(deg, m, mm) {
        // The other mixes (the travel in metres with radians or metre tips) are caught before,
        // by the range checks of `load_session`, every such column being small.
        Some("the prismatic joints' columns (rN_qK_mm) are consistent with the tips if read as METRES: \
              a prismatic joint's column is millimetres, so convert the travel to millimetres".into())
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session of other kinds only is refused naming `calibrate --cell`; a mixed one with
    /// enough coincident rows is read, its other rows kept aside in `observations`.
    #[test]
    fn mixed_sessions_keep_the_coincident_rows_or_name_calibrate_cell() {
        let cell = Cell::default_floor_floor();
        let dir = tempfile::tempdir().unwrap();
        for (kind, n, ok) in [
            (sim_cell::SimKind::Contact, 12, false),
            (sim_cell::SimKind::Mixed, 60, true),
        ] {
            let spec = sim_cell::SessionSpec::new(n, sim_cell::Layout::Random, 0.7);
            let kinds = sim_cell::KindSpec {
                kind,
                ..sim_cell::KindSpec::default()
            };
            let (s, _) = sim_cell::generate_kind_session(
                &cell,
                &spec,
                &kinds,
                None,
                &mut sim_cell::trial_rng(9, 0),
            )
            .unwrap();
            let path = dir.path().join("mixed.csv");
            s.write_csv(&path, &cell).unwrap();
            match load_session(&path, &cell) {
                Ok(back) => {
                    assert!(ok);
                    assert_eq!(back.points.len(), 10);
                    assert_eq!(back.observations.len(), 50);
                }
                Err(e) => {
                    let text = e.to_string();
                    assert!(!ok, "{text}");
                    assert!(
                        text.contains("0 coincident") && text.contains("calibrate --cell"),
                        "{text}"
                    );
                }
            }
        }
    }

    /// The unit pre-check reads the text as CSV: trimmed and quoted fields, blank lines and
    /// non-numeric fields are handled, and only the robots' `r1_`/`r2_` `*_deg` / `*_mm` columns count.
    #[test]
    fn unit_ranges_read_csv_fields() {
        let text = "point, r1_q1_deg ,r1_x_mm,note,sigma_mm\n1, -2.5 ,\"1200.0\",a,0.1\n\n2,1.0,-7,\"x,y\",5000\n";
        let (max_deg, max_mm, rows) = unit_ranges(text);
        assert_eq!((max_deg, max_mm, rows), (2.5, 1200.0, 2));
        assert_eq!(unit_ranges(""), (0.0, 0.0, 0));
    }

    /// Joint angles written in radians under `*_deg` are caught before sim-cell's reader, and
    /// the message names the file and the fix.
    #[test]
    fn radians_under_deg_columns_are_named() {
        let cell = Cell::default_floor_wall();
        let spec = sim_cell::SessionSpec::new(12, sim_cell::Layout::Random, 0.8);
        let session =
            sim_cell::generate_session(&cell, &spec, &mut sim_cell::trial_rng(5, 0)).unwrap();
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let text = session.to_csv_string(d1, d2);
        let mut lines = text.lines();
        let header = lines.next().unwrap();
        let mut bad = format!("{header}\n");
        for line in lines {
            let fields: Vec<String> = line
                .split(',')
                .enumerate()
                .map(|(i, f)| match f.parse::<f64>() {
                    Ok(v) if (1..=d1 + d2).contains(&i) => format!("{}", v.to_radians()),
                    _ => f.to_string(),
                })
                .collect();
            bad += &(fields.join(",") + "\n");
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("radians.csv");
        std::fs::write(&path, bad).unwrap();
        let err = load_session(&path, &cell).unwrap_err();
        let text = err.to_string();
        // The shared session check's typed error (handclasp_cell::check_session_inputs's words).
        assert!(
            matches!(
                err,
                DiagnoseError::Format(handclasp_cell::FormatError::SessionCheck {
                    source: handclasp_cell::SessionCheckError::RadiansAsDegrees { .. },
                    ..
                })
            ),
            "{text}"
        );
        assert!(
            text.contains("radians") && text.contains("radians.csv"),
            "{text}"
        );
        std::fs::write(&path, session.to_csv_string(d1, d2)).unwrap();
        load_session(&path, &cell).expect("the session as written reads back");
    }

    /// A handclasp cell whose robot 1 rides a 4 m linear track (a prismatic first joint, the
    /// rail fixture of `cells/rail-tracker.toml`) facing the hp20.
    fn rail_cell() -> Cell {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let text = r#"
            [robot1]
            urdf = "crates/kinematics/tests/fixtures/rail_6r.urdf"
            mount = "floor"
            tip_mm = [0.0, 0.0, 120.0]
            [robot2]
            urdf = "robots/hp20.urdf"
            mount = "floor"
            tip_mm = [0.0, 0.0, 120.0]
            [b1_from_b2]
            xyz_mm = [1800.0, 1500.0, 0.0]
            zyz_deg = [-90.0, 0.0, 0.0]
            [teach]
            centre_mm = [1800.0, 750.0, 700.0]
        "#;
        Cell::from_toml_str(text, &root).expect("the rail cell loads")
    }

    /// A prismatic joint's travel written in metres under its `rN_qK_mm` column (alone, or with
    /// the tips in metres too): the refusal names the prismatic columns and the conversion
    /// (the hint used to know `*_deg` joint columns only and said nothing on such a cell).
    #[test]
    fn metres_under_a_prismatic_joint_column_are_named() {
        let cell = rail_cell();
        assert!(cell.robot1.model.joints()[0].kind.is_prismatic());
        let spec = sim_cell::SessionSpec::new(8, sim_cell::Layout::Random, 0.6);
        let session =
            sim_cell::generate_session(&cell, &spec, &mut sim_cell::trial_rng(5, 0)).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rail.csv");
        session.write_csv(&path, &cell).unwrap();
        load_session(&path, &cell).expect("the session as written reads back");
        let text = std::fs::read_to_string(&path).unwrap();
        // Each data row with the columns named in `scaled` multiplied by their factor.
        let rewrite = |scaled: &[(&str, f64)]| -> String {
            let mut lines = text.lines();
            let header = lines.next().unwrap();
            let names: Vec<&str> = header.split(',').collect();
            let mut out = format!("{header}\n");
            for line in lines {
                let fields: Vec<String> = line
                    .split(',')
                    .zip(&names)
                    .map(|(f, name)| {
                        match (scaled.iter().find(|(n, _)| n == name), f.parse::<f64>()) {
                            (Some((_, k)), Ok(v)) => format!("{}", v * k),
                            _ => f.to_string(),
                        }
                    })
                    .collect();
                out += &(fields.join(",") + "\n");
            }
            out
        };
        std::fs::write(&path, rewrite(&[("r1_q1_mm", 1e-3)])).unwrap();
        let e = load_session(&path, &cell).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, DiagnoseError::SessionUnits { .. }), "{msg}");
        assert!(
            msg.contains("rN_qK_mm") && msg.contains("read as METRES"),
            "{msg}"
        );
        // The travel in millimetres and the tips in metres: the tips are named, not the travel.
        let tips: Vec<(&str, f64)> = [
            "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
        ]
        .iter()
        .map(|&n| (n, 1e-3))
        .collect();
        std::fs::write(&path, rewrite(&tips)).unwrap();
        let msg = load_session(&path, &cell).unwrap_err().to_string();
        assert!(
            msg.contains("tip columns") && !msg.contains("rN_qK_mm"),
            "{msg}"
        );
    }

    /// A session saved with `;` or tabs and a UTF-8 BOM passes the unit pre-checks and reads
    /// like the comma file (the BOM used to reach the pre-check's header names).
    #[test]
    fn semicolon_separated_session_with_bom() {
        let cell = Cell::default_floor_wall();
        let spec = sim_cell::SessionSpec::new(12, sim_cell::Layout::Random, 0.8);
        let session =
            sim_cell::generate_session(&cell, &spec, &mut sim_cell::trial_rng(5, 0)).unwrap();
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let text = session.to_csv_string(d1, d2);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.csv");
        std::fs::write(&path, &text).unwrap();
        let want = load_session(&path, &cell).unwrap();
        for sep in [",", ";", "\t"] {
            let variant = format!("\u{feff}{}", text.replace(',', sep));
            std::fs::write(&path, &variant).unwrap();
            let got = load_session(&path, &cell).unwrap_or_else(|e| panic!("{sep:?}: {e}"));
            assert_eq!(got, want, "{sep:?}");
            assert_eq!(unit_ranges(&variant), unit_ranges(&text), "{sep:?}");
        }
    }

    /// A session with every row duplicated (calibrate refuses it): refused, naming the points.
    #[test]
    fn every_row_duplicated_session() {
        let cell = Cell::default_floor_wall();
        let spec = sim_cell::SessionSpec::new(12, sim_cell::Layout::Random, 0.8);
        let session =
            sim_cell::generate_session(&cell, &spec, &mut sim_cell::trial_rng(5, 0)).unwrap();
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let text = session.to_csv_string(d1, d2);
        let rows: Vec<&str> = text.lines().skip(1).collect();
        let doubled = format!("{text}{}\n", rows.join("\n"));
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("doubled.csv");
        std::fs::write(&path, doubled).unwrap();
        let e = load_session(&path, &cell).unwrap_err().to_string();
        assert!(
            e.contains("data rows 1 and 13 (`point` 1 and 1)")
                && e.contains("duplicate")
                && e.contains("delete one"),
            "{e}"
        );
    }
}

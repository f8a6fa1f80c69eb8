//! Writing a session CSV: the standard columns, and for a mixed session the extra columns of
//! every kind (the face-normal columns only when a `face_contact` row is present).

use calib_core::Robot;
use nalgebra::Point3;

use super::{Session, SessionKind, SessionRow, EXTRA_COLUMNS, FACE_COLUMNS};
use crate::cell::Cell;

impl Session {
    /// The CSV text (see the module docs) for joint counts `dof1`, `dof2`: today's columns for a
    /// handclasp-only session, plus [`EXTRA_COLUMNS`] when it has rows of other kinds. Without
    /// the cell, a tool other than the tip is written by its index (`#1`, …), which
    /// [`Session::parse_csv`] refuses: write such sessions with [`Session::csv_text`].
    pub fn to_csv_string(&self, dof1: usize, dof2: usize) -> String {
        self.write_text(dof1, dof2, &|_, k| {
            if k == 0 {
                crate::cell::TIP_TOOL.to_string()
            } else {
                format!("#{k}")
            }
        })
    }

    /// The CSV text for `cell` (tools by their names in the cell); see
    /// [`Session::to_csv_string`].
    pub fn csv_text(&self, cell: &Cell) -> String {
        self.write_text(cell.robot1.model.dof(), cell.robot2.model.dof(), &|r, k| {
            cell.robot(r)
                .tool_name(k)
                .map_or_else(|| format!("#{k}"), str::to_string)
        })
    }

    fn write_text(
        &self,
        dof1: usize,
        dof2: usize,
        tool_name: &dyn Fn(Robot, usize) -> String,
    ) -> String {
        let mixed = !self.is_handclasp_only();
        let faces = self
            .observations
            .iter()
            .any(|o| matches!(o.kind, SessionKind::FaceContact { .. }));
        // Without a face contact the face columns are left out (files as before they existed).
        let n_extra = EXTRA_COLUMNS.len() - if faces { 0 } else { FACE_COLUMNS.len() };
        let mut out = csv::Writer::from_writer(Vec::new());
        let mut header = Session::csv_header(dof1, dof2);
        if mixed {
            header.extend(EXTRA_COLUMNS[..n_extra].iter().map(|c| c.to_string()));
        }
        // Writing to memory cannot fail, and every field is plain ASCII.
        let _ = out.write_record(&header);
        let deg = |q: &[f64]| {
            q.iter()
                .map(|x| format!("{:.6}", x.to_degrees()))
                .collect::<Vec<_>>()
        };
        let mm3 = |p: &Point3<f64>| {
            (0..3)
                .map(|a| format!("{:.6}", p[a] * 1e3))
                .collect::<Vec<_>>()
        };
        let mm = |x: f64| format!("{:.6}", x * 1e3);
        for row in self.rows() {
            let mut record = vec![row.point().to_string()];
            let mut extra = vec![String::new(); n_extra];
            let mut set = |name: &str, v: String| {
                if let Some(k) = EXTRA_COLUMNS.iter().position(|c| *c == name) {
                    extra[k] = v;
                }
            };
            let (q1, q2, t1, t2): (Vec<String>, Vec<String>, Vec<String>, Vec<String>) = match row {
                SessionRow::Point(p) => {
                    set("kind", "coincident".into());
                    (deg(&p.q1), deg(&p.q2), mm3(&p.p_b1), mm3(&p.p_b2))
                }
                SessionRow::Observation(o) => {
                    set("kind", o.kind.name().into());
                    let blank = |n: usize| vec![String::new(); n];
                    // Joint columns of a row that involves one robot; the other's stay empty.
                    let one_robot = |robot: Robot, q: &[f64]| {
                        if robot == Robot::One {
                            (deg(q), blank(dof2), blank(3), blank(3))
                        } else {
                            (blank(dof1), deg(q), blank(3), blank(3))
                        }
                    };
                    match &o.kind {
                        SessionKind::Coincident {
                            q1,
                            q2,
                            tool1,
                            tool2,
                            p_b1,
                            p_b2,
                        } => {
                            set("tool1", tool_name(Robot::One, *tool1));
                            set("tool2", tool_name(Robot::Two, *tool2));
                            (deg(q1), deg(q2), mm3(p_b1), mm3(p_b2))
                        }
                        SessionKind::Contact {
                            q1,
                            q2,
                            tool1,
                            tool2,
                            group,
                            distance_m,
                            sigma_m,
                        }
                        | SessionKind::FaceContact {
                            q1,
                            q2,
                            tool1,
                            tool2,
                            group,
                            distance_m,
                            sigma_m,
                            ..
                        } => {
                            set("tool1", tool_name(Robot::One, *tool1));
                            set("tool2", tool_name(Robot::Two, *tool2));
                            set("group", group.clone());
                            set("distance_mm", distance_m.map(mm).unwrap_or_default());
                            set("sigma_mm", mm(*sigma_m));
                            if let SessionKind::FaceContact { n1_tip, n2_tip, .. } = &o.kind {
                                let normals = n1_tip.iter().chain(n2_tip.iter());
                                for (c, v) in FACE_COLUMNS.iter().zip(normals) {
                                    // `+ 0.0` writes −0 as 0.
                                    set(c, format!("{:.9}", v + 0.0));
                                }
                            }
                            (deg(q1), deg(q2), blank(3), blank(3))
                        }
                        SessionKind::Tracker {
                            robot,
                            q,
                            tool,
                            group,
                            p_tracker,
                            sigma_m,
                        } => {
                            set("robot", robot.number().to_string());
                            set("tool", tool_name(*robot, *tool));
                            set("group", group.clone());
                            set("sigma_mm", mm(*sigma_m));
                            for (a, c) in ["tracker_x_mm", "tracker_y_mm", "tracker_z_mm"]
                                .iter()
                                .enumerate()
                            {
                                set(c, mm(p_tracker[a]));
                            }
                            one_robot(*robot, q)
                        }
                        SessionKind::Plane {
                            robot,
                            q,
                            tool,
                            group,
                            sigma_m,
                        } => {
                            set("robot", robot.number().to_string());
                            set("tool", tool_name(*robot, *tool));
                            set("group", group.clone());
                            set("sigma_mm", mm(*sigma_m));
                            one_robot(*robot, q)
                        }
                    }
                }
            };
            record.extend(q1);
            record.extend(q2);
            record.extend(t1);
            record.extend(t2);
            if mixed {
                record.extend(extra);
            }
            let _ = out.write_record(&record);
        }
        let bytes = out.into_inner().unwrap_or_default();
        String::from_utf8(bytes).unwrap_or_default()
    }
}

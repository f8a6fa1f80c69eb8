//! Writing a session CSV: the standard columns, and for a mixed session the extra columns of
//! every kind (a column added with a later kind, such as the face normals, only when a row of
//! that kind is present). Each kind fills its own columns (`kinds.rs`).

use calib_core::whole_cell::Kind;
use calib_core::Robot;
use nalgebra::Point3;

use super::kinds::{kind_columns, ALWAYS_WRITTEN, EXTRA_COLUMNS};
use super::{header_of, joint_kinds, joint_to_file, Session, SessionRow, SOURCE_ID_COLUMN};
use crate::cell::Cell;

impl Session {
    /// The CSV text (see the module docs) for joint counts `dof1`, `dof2`: today's columns for a
    /// handclasp-only session, plus [`EXTRA_COLUMNS`] when it has rows of other kinds. Without
    /// the cell, a tool other than the tip is written by its index (`#1`, …), which
    /// [`Session::parse_csv`] refuses: write such sessions with [`Session::csv_text`]. The
    /// [`SOURCE_ID_COLUMN`] comes last, when [`Session::source_ids`] is not empty. A one-robot
    /// row with [`Session::other_arm_q`] fills the other robot's joint columns with them.
    pub fn to_csv_string(&self, dof1: usize, dof2: usize) -> String {
        self.write_text([vec![false; dof1], vec![false; dof2]], &|_, k| {
            if k == 0 {
                crate::cell::TIP_TOOL.to_string()
            } else {
                format!("#{k}")
            }
        })
    }

    /// The CSV text for `cell` (tools by their names in the cell; a prismatic joint's column in
    /// mm, [`Session::csv_header_for`]); see [`Session::to_csv_string`].
    pub fn csv_text(&self, cell: &Cell) -> String {
        self.write_text(joint_kinds(cell), &|r, k| {
            cell.robot(r)
                .tool_name(k)
                .map_or_else(|| format!("#{k}"), str::to_string)
        })
    }

    fn write_text(
        &self,
        prismatic: [Vec<bool>; 2],
        tool_name: &dyn Fn(Robot, usize) -> String,
    ) -> String {
        let mixed = !self.is_handclasp_only();
        // The extra columns written: the first ALWAYS_WRITTEN, and a later one (such as the face
        // normals) only when a row uses it, so that files without its kind are as before it.
        let columns: Vec<&'static str> = EXTRA_COLUMNS
            .iter()
            .enumerate()
            .filter(|(k, c)| {
                *k < ALWAYS_WRITTEN
                    || self
                        .observations
                        .iter()
                        .any(|o| kind_columns(o.kind.kind()).contains(c))
            })
            .map(|(_, c)| *c)
            .collect();
        let mut out = csv::Writer::from_writer(Vec::new());
        let mut header = header_of(&prismatic);
        let two_robots = !prismatic[1].is_empty();
        if mixed {
            header.extend(columns.iter().map(|c| c.to_string()));
        }
        // The source ids, last, only when a row has one (older files are written as before).
        let with_ids = !self.source_ids.is_empty();
        if with_ids {
            header.push(SOURCE_ID_COLUMN.to_string());
        }
        // Writing to memory cannot fail, and every field is plain ASCII.
        let _ = out.write_record(&header);
        for row in self.rows() {
            let mut w = RowWriter {
                columns: &columns,
                extra: vec![String::new(); columns.len()],
                tool_name,
                prismatic: &prismatic,
                q1: vec![String::new(); prismatic[0].len()],
                q2: vec![String::new(); prismatic[1].len()],
                tips: [vec![String::new(); 3], vec![String::new(); 3]],
            };
            match row {
                SessionRow::Point(p) => {
                    w.set("kind", Kind::Coincident.name().into());
                    w.joints(Robot::One, &p.q1);
                    w.joints(Robot::Two, &p.q2);
                    w.tips(&p.p_b1, &p.p_b2);
                }
                SessionRow::Observation(o) => {
                    w.set("kind", o.kind.name().into());
                    o.kind.write(&mut w);
                    // The other arm's posture on a shared trunk: the other robot's columns.
                    if let (Some((robot, _, _)), Some(q)) =
                        (o.kind.single(), self.other_arm_q.get(&o.point))
                    {
                        w.joints(robot.other(), q);
                    }
                }
            }
            let mut record = vec![row.point().to_string()];
            record.extend(w.q1);
            record.extend(w.q2);
            let [t1, t2] = w.tips;
            record.extend(t1);
            if two_robots {
                record.extend(t2);
            }
            if mixed {
                record.extend(w.extra);
            }
            if with_ids {
                record.push(
                    self.source_ids
                        .get(&row.point())
                        .cloned()
                        .unwrap_or_default(),
                );
            }
            let _ = out.write_record(&record);
        }
        let bytes = out.into_inner().unwrap_or_default();
        String::from_utf8(bytes).unwrap_or_default()
    }
}

/// One data row being written: the standard columns (joints in degrees or mm, tips in mm, 6
/// decimals; empty until set) and the extra columns the session writes.
pub(super) struct RowWriter<'a> {
    columns: &'a [&'static str],
    extra: Vec<String>,
    tool_name: &'a dyn Fn(Robot, usize) -> String,
    /// Per robot, whether each joint is prismatic (written in mm, not degrees).
    prismatic: &'a [Vec<bool>; 2],
    q1: Vec<String>,
    q2: Vec<String>,
    tips: [Vec<String>; 2],
}

impl RowWriter<'_> {
    /// `x` m as mm with 6 decimals.
    pub(super) fn mm(x: f64) -> String {
        format!("{:.6}", x * 1e3)
    }

    /// Sets extra column `name` (a column the session does not write is ignored).
    pub(super) fn set(&mut self, name: &str, value: String) {
        if let Some(k) = self.columns.iter().position(|c| *c == name) {
            self.extra[k] = value;
        }
    }

    /// Robot `r`'s joint columns from `q`, rad (m for a prismatic joint).
    fn joints(&mut self, r: Robot, q: &[f64]) {
        let kinds = &self.prismatic[usize::from(r.number() - 1)];
        let deg = q
            .iter()
            .enumerate()
            .map(|(j, x)| {
                let prismatic = kinds.get(j).copied().unwrap_or(false);
                format!("{:.6}", joint_to_file(*x, prismatic))
            })
            .collect();
        match r {
            Robot::One => self.q1 = deg,
            Robot::Two => self.q2 = deg,
        }
    }

    /// Both robots' joints and tools (`tool1`, `tool2`) of a two-robot row.
    pub(super) fn pair(&mut self, q1: &[f64], q2: &[f64], tool1: usize, tool2: usize) {
        self.set("tool1", (self.tool_name)(Robot::One, tool1));
        self.set("tool2", (self.tool_name)(Robot::Two, tool2));
        self.joints(Robot::One, q1);
        self.joints(Robot::Two, q2);
    }

    /// The robot (`robot`), its tool (`tool`) and its joints of a one-robot row; the other
    /// robot's joints stay empty unless [`Session::other_arm_q`] gives them.
    pub(super) fn single(&mut self, robot: Robot, q: &[f64], tool: usize) {
        self.set("robot", robot.number().to_string());
        self.set("tool", (self.tool_name)(robot, tool));
        self.joints(robot, q);
    }

    /// Both robots' reported tips, m, each robot's base.
    pub(super) fn tips(&mut self, p_b1: &Point3<f64>, p_b2: &Point3<f64>) {
        let mm3 = |p: &Point3<f64>| (0..3).map(|a| Self::mm(p[a])).collect();
        self.tips = [mm3(p_b1), mm3(p_b2)];
    }

    /// A contact's group, distance (empty when fitted) and σ, m.
    pub(super) fn contact(&mut self, group: &str, distance_m: Option<f64>, sigma_m: f64) {
        self.set("group", group.to_string());
        self.set("distance_mm", distance_m.map(Self::mm).unwrap_or_default());
        self.set("sigma_mm", Self::mm(sigma_m));
    }
}

//! Handclasp sessions: what the two controllers report at each teach point (joint angles and
//! nominal-model tip positions), and rows of the other observation kinds (contact, face contact,
//! tracker, plane), read from and written to CSV.
//!
//! CSV: header `point,r1_q1_deg,…,r1_qN_deg,r2_q1_deg,…,r2_qM_deg,r1_x_mm,r1_y_mm,r1_z_mm,
//! r2_x_mm,r2_y_mm,r2_z_mm` (N, M = the models' joint counts, URDF chain order), one row per point,
//! degrees and millimetres with 6 decimals; tips in each robot's own base frame. It is valid input
//! to `handclasp calibrate` (calib-core's reader ignores the joint columns).
//!
//! Mixed sessions add the columns [`EXTRA_COLUMNS`] (`kind`, `robot`, `group`, `tool1`, `tool2`,
//! `tool`, `distance_mm`, `sigma_mm`, `tracker_x_mm`, `tracker_y_mm`, `tracker_z_mm`, and, when
//! a `face_contact` row is present, [`FACE_COLUMNS`] `n1_x,n1_y,n1_z,n2_x,n2_y,n2_z`); a file
//! without a `kind` column is all coincident handclasps, read exactly as before. Which kind uses
//! which column is [`kind_columns`]; `docs/formats.md` has the table and an example.
//!
//! An optional `source_id` column ([`SOURCE_ID_COLUMN`], after every other column) carries
//! each row's id in the source it was imported from ([`Session::source_ids`], by point number;
//! `handclasp import` fills it from the map's `source_id` key); a file without it reads as before,
//! and readers that do not know it ignore it like any extra column.
//!
//! On a shared-trunk cell (`[robot2] shares`) a one-robot row (tracker, plane) may also fill the
//! other robot's joint columns: the other arm's posture at that row ([`Session::other_arm_q`]),
//! which loads the trunk; its trunk columns must equal the row's. On any other cell they stay
//! empty.
//!
//! One job: the session CSV. This file holds the row types; `kinds.rs` each observation kind's
//! row ([`SessionKind`]: its columns, reader, writer and whole-cell observation), `read.rs` the
//! reader (header, the columns the kinds share, errors by line and column), `write.rs` the
//! writer. Sessions are simulated by sim-cell.

use std::collections::BTreeMap;
use std::path::Path;

use calib_core::whole_cell::Kind;
use calib_core::PointPairs;
use nalgebra::Point3;

use crate::cell::Cell;
use crate::error::FormatError;

mod checks;
mod kinds;
mod read;
mod write;

pub use checks::{check_session_inputs, SessionCheckError, METRES_LIMIT_MM, RADIANS_LIMIT_DEG};
pub use kinds::{
    kind_columns, FaceNormals, SessionKind, ToolPair, ALWAYS_WRITTEN, EXTRA_COLUMNS, FACE_COLUMNS,
    KIND_NAMES,
};
pub use read::TIP_CONSISTENCY_MM;

/// The optional column holding each row's id in its source (a pose id of the data set a row was
/// imported from); written last, only when some row has one.
pub const SOURCE_ID_COLUMN: &str = "source_id";

/// One teach point as the controllers report it.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionPoint {
    /// Point number (1-based label, the CSV `point` column).
    pub point: usize,
    /// Robot 1's reported joint angles, rad, URDF chain order.
    pub q1: Vec<f64>,
    /// Robot 2's reported joint angles, rad.
    pub q2: Vec<f64>,
    /// Robot 1's tip by its nominal model, m, base 1.
    pub p_b1: Point3<f64>,
    /// Robot 2's tip by its nominal model, m, base 2.
    pub p_b2: Point3<f64>,
}

/// One row of another kind than a default-tool coincident handclasp.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionObservation {
    /// Point number (the CSV `point` column).
    pub point: usize,
    /// What was observed.
    pub kind: SessionKind,
}

/// A session: coincident handclasps at both robots' tips (`points`, what every reader of
/// handclasp sessions uses) and rows of the other kinds (`observations`, used by the whole-cell
/// calibration).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Session {
    /// The coincident handclasps at the default tips, in file order.
    pub points: Vec<SessionPoint>,
    /// Every other row (other kinds, or other tools), in file order.
    pub observations: Vec<SessionObservation>,
    /// Each row's id in the source it came from, by point number (the [`SOURCE_ID_COLUMN`]);
    /// rows without one are absent. Empty for sessions that were not imported.
    pub source_ids: BTreeMap<usize, String>,
    /// A shared-trunk cell (`[robot2] shares`): the other arm's joints (rad, m for a prismatic
    /// joint; its independent joints, chain order, the trunk's equal to the row's) of each
    /// one-robot row (tracker, plane) that gives them, by point number. In the file they are the
    /// other robot's joint columns of that row (`r2_q*_deg` on a `robot = 1` row, `r1_q*_deg` on
    /// a `robot = 2` row): the other arm's weight loads the trunk, so a
    /// `kinematic+compliance` fit needs its posture. Empty on any other cell.
    pub other_arm_q: BTreeMap<usize, Vec<f64>>,
}

/// One row of a session, in file order ([`Session::rows`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SessionRow<'a> {
    /// A coincident handclasp at the default tips.
    Point(&'a SessionPoint),
    /// A row of another kind.
    Observation(&'a SessionObservation),
}

impl SessionRow<'_> {
    /// The row's point number.
    pub fn point(&self) -> usize {
        match self {
            SessionRow::Point(p) => p.point,
            SessionRow::Observation(o) => o.point,
        }
    }
}

impl Session {
    /// A session of coincident handclasps only.
    pub fn from_points(points: Vec<SessionPoint>) -> Self {
        Session {
            points,
            observations: Vec::new(),
            source_ids: BTreeMap::new(),
            other_arm_q: BTreeMap::new(),
        }
    }

    /// True when every row is a coincident handclasp at the default tips (the session every
    /// points-based tool, such as `diagnose`, reads in full).
    pub fn is_handclasp_only(&self) -> bool {
        self.observations.is_empty()
    }

    /// Number of rows of all kinds.
    pub fn len(&self) -> usize {
        self.points.len() + self.observations.len()
    }

    /// True when there is no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every row, merged by point number (a stable merge of `points` and `observations`, so a
    /// file whose point numbers increase is given back in file order).
    pub fn rows(&self) -> Vec<SessionRow<'_>> {
        let mut out = Vec::with_capacity(self.len());
        let (mut i, mut j) = (0, 0);
        while i < self.points.len() || j < self.observations.len() {
            let take_point = match (self.points.get(i), self.observations.get(j)) {
                (Some(p), Some(o)) => p.point <= o.point,
                (Some(_), None) => true,
                _ => false,
            };
            if take_point {
                out.push(SessionRow::Point(&self.points[i]));
                i += 1;
            } else {
                out.push(SessionRow::Observation(&self.observations[j]));
                j += 1;
            }
        }
        out
    }

    /// Count of rows per kind, in [`Kind::ALL`] order (the names [`KIND_NAMES`]).
    pub fn kind_counts(&self) -> [usize; Kind::ALL.len()] {
        let mut n = [0; Kind::ALL.len()];
        let kinds = std::iter::repeat_n(Kind::Coincident, self.points.len())
            .chain(self.observations.iter().map(|o| o.kind.kind()));
        for kind in kinds {
            if let Some(k) = Kind::ALL.iter().position(|k| *k == kind) {
                n[k] += 1;
            }
        }
        n
    }

    /// The nominal tips `(p_b1, p_b2)`, m.
    pub fn tips(&self) -> (Vec<Point3<f64>>, Vec<Point3<f64>>) {
        (
            self.points.iter().map(|p| p.p_b1).collect(),
            self.points.iter().map(|p| p.p_b2).collect(),
        )
    }

    /// The tips as calib-core point pairs (rows = point numbers).
    pub fn to_point_pairs(&self) -> PointPairs {
        let (p_b1, p_b2) = self.tips();
        PointPairs {
            p_b1,
            p_b2,
            rows: self.points.iter().map(|p| p.point).collect(),
        }
    }

    /// The CSV columns (see the module docs) for joint counts `dof1`, `dof2` of two robots whose
    /// joints are all rotary (`rK_qJ_deg`). [`Session::csv_header_for`] names a cell's columns.
    pub fn csv_header(dof1: usize, dof2: usize) -> Vec<String> {
        header_of(&[vec![false; dof1], vec![false; dof2]])
    }

    /// The CSV columns for `cell`'s robots: a prismatic joint's column is `rK_qJ_mm`
    /// (millimetres), a rotary one's `rK_qJ_deg`; a one-robot cell ([`Cell::has_robot2`] false)
    /// has no `r2_*` columns.
    pub fn csv_header_for(cell: &Cell) -> Vec<String> {
        header_of(&joint_kinds(cell))
    }

    /// Writes the session CSV for `cell`'s robots ([`Session::csv_text`]).
    pub fn write_csv(&self, path: &Path, cell: &Cell) -> Result<(), FormatError> {
        crate::output::write_atomically(path, self.csv_text(cell).as_bytes())
    }

    /// Reads a session CSV for `cell` (see [`Session::parse_csv`]).
    pub fn read_csv(path: &Path, cell: &Cell) -> Result<Session, FormatError> {
        let text =
            kinematics::input::read_input_text(path, "session CSV").map_err(FormatError::input)?;
        Session::parse_csv(&text, path, cell)
    }
}

#[cfg(test)]
mod tests;

/// Per robot of `cell` that the session describes, whether each joint is prismatic (its column
/// in mm) or rotary (degrees), chain order: two entries, the second empty for a one-robot cell.
pub(crate) fn joint_kinds(cell: &Cell) -> [Vec<bool>; 2] {
    let kinds = |r: &crate::cell::CellRobot| -> Vec<bool> {
        r.model
            .joints()
            .iter()
            .map(|j| j.kind.is_prismatic())
            .collect()
    };
    let two = if cell.has_robot2() {
        kinds(&cell.robot2)
    } else {
        Vec::new()
    };
    [kinds(&cell.robot1), two]
}

/// The joint column of joint `k` (1-based) of robot `robot` (1 or 2): `rR_qK_mm` for a
/// prismatic joint, `rR_qK_deg` otherwise.
pub fn joint_column(robot: u8, k: usize, prismatic: bool) -> String {
    format!("r{robot}_q{k}_{}", if prismatic { "mm" } else { "deg" })
}

/// A joint value in its file unit (degrees, mm for a prismatic joint) from SI (rad, m).
pub(crate) fn joint_to_file(q: f64, prismatic: bool) -> f64 {
    if prismatic {
        q * 1e3
    } else {
        q.to_degrees()
    }
}

/// A joint value in SI (rad, m) from its file unit (degrees, mm for a prismatic joint).
pub(crate) fn joint_from_file(v: f64, prismatic: bool) -> f64 {
    if prismatic {
        v * 1e-3
    } else {
        v.to_radians()
    }
}

/// The standard columns for the joint kinds `kinds` ([`joint_kinds`]): robot 2's tip columns
/// only when it has joints.
fn header_of(kinds: &[Vec<bool>; 2]) -> Vec<String> {
    let mut header = vec!["point".to_string()];
    for (r, k) in [(1u8, &kinds[0]), (2, &kinds[1])] {
        for (j, &p) in k.iter().enumerate() {
            header.push(joint_column(r, j + 1, p));
        }
    }
    header.extend(["r1_x_mm", "r1_y_mm", "r1_z_mm"].map(String::from));
    if !kinds[1].is_empty() {
        header.extend(["r2_x_mm", "r2_y_mm", "r2_z_mm"].map(String::from));
    }
    header
}

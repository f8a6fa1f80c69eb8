//! Reading a session CSV: the header by column name, then each row: its `point`, its `kind`
//! (empty or absent = coincident), the columns its kind leaves empty, its joint and tip columns,
//! and the fields of its kind (`kinds.rs`). Errors name the line and the column and say what
//! would work.

use std::collections::BTreeMap;
use std::path::Path;

use calib_core::whole_cell::Kind;
use calib_core::Robot;
use kinematics::base_from_tip;
use kinematics::input::cap_echo;
use nalgebra::{Point3, Unit, Vector3};

use super::kinds::{kind_columns, kinds_using, read_row, ReadRow, EXTRA_COLUMNS, KIND_NAMES};
use super::{
    joint_from_file, joint_kinds, Session, SessionObservation, SessionPoint, SOURCE_ID_COLUMN,
};
use crate::cell::Cell;
use crate::error::FormatError;

/// Largest allowed mismatch between a session row's tip columns and FK of its joint columns, mm.
pub const TIP_CONSISTENCY_MM: f64 = 0.01;

/// A row's joint and tip columns as read (SI), before its kind says which it needs.
pub(super) struct RowValues {
    /// Robot 1's joints, rad; `None` if its joint cells are empty.
    pub(super) q1: Option<Vec<f64>>,
    /// Robot 2's joints, rad; `None` if its joint cells are empty.
    pub(super) q2: Option<Vec<f64>>,
    /// Each robot's reported tip, m, its base; `None` if its tip cells are empty.
    pub(super) tips: [Option<Point3<f64>>; 2],
}

/// A two-robot row's joints (rad), tools and tips (m), as [`RowReader::pair`] reads them.
pub(super) struct Pair {
    pub(super) q1: Vec<f64>,
    pub(super) q2: Vec<f64>,
    pub(super) tool1: usize,
    pub(super) tool2: usize,
    pub(super) tips: [Option<Point3<f64>>; 2],
}

/// A one-robot row as [`RowReader::single`] reads it: the robot, its joints (rad), its tool and
/// the other arm's joints (rad; shared-trunk cells only, `None` when not given).
pub(super) type SingleRow = (Robot, Vec<f64>, usize, Option<Vec<f64>>);

/// The distance of each contact group read so far: `(group, distance m, first line)`.
#[derive(Default)]
pub(super) struct ContactDistances(Vec<(String, Option<f64>, u64)>);

impl Session {
    /// Parses session CSV text with the rules of calib-core's points reader
    /// ([`calib_core::parse_points_csv`]): a UTF-8 BOM and CRLF line ends are accepted, fields may be
    /// quoted and separated by commas, semicolons or tabs (detected from the header line,
    /// [`calib_core::csv_delimiter`]), columns are found by header name in any order and extra columns are ignored, blank
    /// lines are skipped. Every joint column of `cell`'s joint counts must be in the header.
    ///
    /// Without a `kind` column every row is a coincident handclasp: every value finite, and each
    /// row's tip columns must match FK of its joint columns with the cell's nominal models and tip
    /// offsets within [`TIP_CONSISTENCY_MM`] (catches a wrong cell, tip or unit). With a `kind`
    /// column each row is one of [`KIND_NAMES`] (empty = `coincident`) and carries the fields of
    /// [`super::SessionKind`] (`docs/formats.md` has the table): fields a kind does not use must be empty,
    /// tip columns are required on coincident rows and FK-checked wherever given, tools are named
    /// from the cell (`tip` or `[robotN.tools]`), and the rows of one contact group agree on
    /// `distance_mm`. An optional [`SOURCE_ID_COLUMN`] fills [`Session::source_ids`] (an empty
    /// cell: no id). Errors name the line and column and say what would work.
    pub fn parse_csv(text: &str, path: &Path, cell: &Cell) -> Result<Session, FormatError> {
        let err = |message: String| FormatError::Session {
            path: path.to_path_buf(),
            message,
        };
        let kinds = joint_kinds(cell);
        let (d1, d2) = (kinds[0].len(), kinds[1].len());
        let want = Session::csv_header_for(cell);
        let mut reader = calib_core::csv_reader(text);
        let headers = reader
            .headers()
            .map_err(|e| err(format!("line 1: the header is not valid CSV: {e}")))?
            .clone();
        if headers.iter().all(str::is_empty) {
            return Err(err("the file is empty; expected a header line".into()));
        }
        let col = |name: &str| headers.iter().position(|h| h == name);
        let has_kind = col("kind").is_some();
        // Without a `kind` column, today's rule: every column of `want` is required. With one,
        // the tip columns are needed only by coincident rows (checked per row).
        let required = if has_kind { 1 + d1 + d2 } else { want.len() };
        let mut idx: Vec<Option<usize>> = Vec::with_capacity(want.len());
        for (k, name) in want.iter().enumerate() {
            let found = col(name);
            if found.is_none() && k < required {
                let known: Vec<&str> = want
                    .iter()
                    .map(String::as_str)
                    .chain(EXTRA_COLUMNS)
                    .chain([SOURCE_ID_COLUMN])
                    .collect();
                let unused: Vec<String> = headers
                    .iter()
                    .filter(|h| !known.contains(h))
                    .map(|h| format!("`{h}`"))
                    .collect();
                let unused = if unused.is_empty() {
                    String::new()
                } else if headers.len() == 1 {
                    format!(
                        " (the header reads as the single column {}: separate the fields by commas, semicolons or tabs)",
                        cap_echo(&unused.join(", "))
                    )
                } else {
                    format!(" (columns not used: {})", cap_echo(&unused.join(", ")))
                };
                let robots = if cell.has_robot2() {
                    format!(
                        "{} with {d1} joints, {} with {d2}",
                        cell.robot1.model.name(),
                        cell.robot2.model.name()
                    )
                } else {
                    format!("one robot, {} with {d1} joints", cell.robot1.model.name())
                };
                return Err(err(format!(
                    "line 1: the header has no column `{name}`{unused}, which this cell ({robots}) needs; \
                     the header must hold these columns (any order, extra columns ignored; joints in degrees, \
                     a prismatic joint's `_mm` column in millimetres): {}",
                    want[..required].join(","),
                )));
            }
            idx.push(found);
        }
        let extra: Vec<Option<usize>> = EXTRA_COLUMNS.iter().map(|c| col(c)).collect();
        let source_col = col(SOURCE_ID_COLUMN);
        let mut source_ids = BTreeMap::new();
        let mut points = Vec::new();
        let mut observations = Vec::new();
        let mut contacts = ContactDistances::default();
        let mut other_arm_q = BTreeMap::new();
        for record in reader.records() {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                err(format!("line {line}: not valid CSV: {e}"))
            })?;
            let line_no = record.position().map_or(0, |p| p.line());
            if record.iter().all(str::is_empty) {
                continue;
            }
            if record.len() != headers.len() {
                return Err(err(format!(
                    "line {line_no}: {} values but the header has {} columns",
                    record.len(),
                    headers.len()
                )));
            }
            let row = RowReader {
                record: &record,
                line_no,
                want: &want,
                idx: &idx,
                extra: &extra,
                path,
            };
            let point: usize = row.cell(0).parse().map_err(|_| {
                err(format!(
                    "line {line_no}, column `point`: `{}` is not a point number (1, 2, …)",
                    cap_echo(row.cell(0))
                ))
            })?;
            if let Some(id) = source_col
                .and_then(|i| record.get(i))
                .filter(|s| !s.is_empty())
            {
                source_ids.insert(point, id.to_string());
            }
            if !has_kind {
                if !cell.has_robot2() {
                    return Err(err(format!(
                        "line {line_no}: a session without a `kind` column is all coincident handclasps, which need two robots; \
                         this cell has only [robot1]: add a `kind` column with tracker or plane rows"
                    )));
                }
                let mut v = Vec::with_capacity(want.len() - 1);
                for k in 1..want.len() {
                    v.push(row.number(k)?);
                }
                let si = |vals: &[f64], k: &[bool]| -> Vec<f64> {
                    vals.iter()
                        .zip(k)
                        .map(|(x, &p)| joint_from_file(*x, p))
                        .collect()
                };
                let q1 = si(&v[..d1], &kinds[0]);
                let q2 = si(&v[d1..d1 + d2], &kinds[1]);
                let t = &v[d1 + d2..];
                let p_b1 = Point3::new(t[0], t[1], t[2]) * 1e-3;
                let p_b2 = Point3::new(t[3], t[4], t[5]) * 1e-3;
                check_tip(cell, Robot::One, 0, &q1, &p_b1, line_no, path)?;
                check_tip(cell, Robot::Two, 0, &q2, &p_b2, line_no, path)?;
                points.push(SessionPoint {
                    point,
                    q1,
                    q2,
                    p_b1,
                    p_b2,
                });
                continue;
            }
            let kind_text = row
                .extra("kind")
                .unwrap_or("coincident")
                .to_ascii_lowercase();
            let Some(kind) = Kind::from_name(&kind_text) else {
                return Err(err(format!(
                    "line {line_no}, column `kind`: `{}` is not an observation kind; use one of {} (empty = coincident)",
                    cap_echo(&kind_text),
                    KIND_NAMES.join(", ")
                )));
            };
            row.only_fields_of(kind)?;
            let values = RowValues {
                q1: row.joints(cell, Robot::One)?,
                q2: row.joints(cell, Robot::Two)?,
                tips: [row.tip(Robot::One, d1, d2)?, row.tip(Robot::Two, d1, d2)?],
            };
            match read_row(kind, &row, values, cell, point, &mut contacts)? {
                ReadRow::Point(p) => points.push(p),
                ReadRow::Observation(kind, q_other) => {
                    if let Some(q) = q_other {
                        other_arm_q.insert(point, q);
                    }
                    observations.push(SessionObservation { point, kind });
                }
            }
        }
        Ok(Session {
            points,
            observations,
            source_ids,
            other_arm_q,
        })
    }
}

/// The robot that is not `r`.
/// Largest difference between the two robots' columns of a shared joint on one row, in the
/// file's unit (degrees or mm): half the last written decimal (files carry 6 decimals).
const SHARED_JOINT_TOL: f64 = 1e-6;

fn other(r: Robot) -> Robot {
    match r {
        Robot::One => Robot::Two,
        Robot::Two => Robot::One,
    }
}

fn fmt_opt_mm(d: Option<f64>) -> String {
    d.map_or("empty (fitted)".into(), |d| format!("{} mm", d * 1e3))
}

/// Checks a tip column triple against nominal FK of the row's joints with tool `tool`.
fn check_tip(
    cell: &Cell,
    r: Robot,
    tool: usize,
    q: &[f64],
    p: &Point3<f64>,
    line_no: u64,
    path: &Path,
) -> Result<(), FormatError> {
    let err = |message: String| FormatError::Session {
        path: path.to_path_buf(),
        message,
    };
    let robot = cell.robot(r);
    let flange_from_tool = robot
        .flange_from_tool(tool)
        .unwrap_or(robot.flange_from_tip);
    let n = r.number();
    let fk = base_from_tip(&robot.model, q, &flange_from_tool)
        .map_err(|e| err(format!("line {line_no}: robot {n}'s joint columns: {e}")))?;
    let d_mm = (fk.translation.vector - p.coords).norm() * 1e3;
    if d_mm > TIP_CONSISTENCY_MM {
        let what = if tool == 0 {
            "tip_mm".to_string()
        } else {
            format!("tool `{}`", robot.tool_name(tool).unwrap_or("?"))
        };
        return Err(err(format!(
            "line {line_no}: robot {n}'s tip columns are {d_mm:.3} mm from the nominal FK of its joint columns \
             ({what} = {:?}); check the cell (URDF, tip_mm) and that angles are in degrees and lengths in mm",
            (flange_from_tool * 1e3).as_slice()
        )));
    }
    Ok(())
}

/// One data row of a session CSV being parsed.
pub(super) struct RowReader<'a> {
    record: &'a csv::StringRecord,
    line_no: u64,
    want: &'a [String],
    idx: &'a [Option<usize>],
    extra: &'a [Option<usize>],
    path: &'a Path,
}

impl RowReader<'_> {
    pub(super) fn err(&self, message: String) -> FormatError {
        FormatError::Session {
            path: self.path.to_path_buf(),
            message: format!("line {}, {message}", self.line_no),
        }
    }

    pub(super) fn missing(&self, column: &str, why: &str) -> FormatError {
        self.err(format!("column `{column}` is empty: {why}"))
    }

    /// The value of standard column `k` ("" when the column is absent).
    fn cell(&self, k: usize) -> &str {
        self.idx[k].and_then(|i| self.record.get(i)).unwrap_or("")
    }

    /// Standard column `k` as a finite number.
    fn number(&self, k: usize) -> Result<f64, FormatError> {
        let c = self.cell(k);
        c.parse()
            .ok()
            .filter(|x: &f64| x.is_finite())
            .ok_or_else(|| {
                self.err(format!(
                    "column `{}`: `{}` is not a finite number",
                    self.want[k],
                    cap_echo(c)
                ))
            })
    }

    /// Extra column `name`, `None` when absent or empty.
    fn extra(&self, name: &str) -> Option<&str> {
        let k = EXTRA_COLUMNS.iter().position(|c| *c == name)?;
        self.extra[k]
            .and_then(|i| self.record.get(i))
            .filter(|s| !s.is_empty())
    }

    pub(super) fn optional_number(&self, name: &str) -> Result<Option<f64>, FormatError> {
        match self.extra(name) {
            None => Ok(None),
            Some(c) => c
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .map(Some)
                .ok_or_else(|| {
                    self.err(format!(
                        "column `{name}`: `{}` is not a finite number",
                        cap_echo(c)
                    ))
                }),
        }
    }

    /// Robot `r`'s face normal of a `face_contact` row (columns `n{r}_x`, `n{r}_y`, `n{r}_z`,
    /// its tip frame, unitless), normalised. Errors: a missing or non-finite component, or a
    /// zero vector.
    pub(super) fn normal(&self, r: u8) -> Result<Unit<Vector3<f64>>, FormatError> {
        let mut n = Vector3::zeros();
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let name = format!("n{r}_{axis}");
            n[a] = self.optional_number(&name)?.ok_or_else(|| {
                self.missing(
                    &name,
                    &format!(
                        "a face_contact row needs robot {r}'s outward face normal in its tip frame \
                         (n{r}_x, n{r}_y, n{r}_z, unitless, normalised on reading)"
                    ),
                )
            })?;
        }
        Unit::try_new(n, 1e-12).ok_or_else(|| {
            self.err(format!(
                "columns `n{r}_x, n{r}_y, n{r}_z`: the face normal ({}, {}, {}) is zero; give the \
                 outward normal of robot {r}'s touching face in its tip frame, e.g. 0,0,1",
                n.x, n.y, n.z
            ))
        })
    }

    pub(super) fn required_text(&self, name: &str, why: &str) -> Result<String, FormatError> {
        self.extra(name)
            .map(str::to_string)
            .ok_or_else(|| self.missing(name, why))
    }

    pub(super) fn sigma(&self) -> Result<f64, FormatError> {
        let s = self.optional_number("sigma_mm")?.ok_or_else(|| {
            self.missing(
                "sigma_mm",
                "give the measurement's standard deviation in mm (a contact's distance, a plane's normal offset, a tracker's per-axis σ)",
            )
        })?;
        if s > 0.0 {
            Ok(s * 1e-3)
        } else {
            Err(self.err(format!("column `sigma_mm`: {s} must be > 0 (mm), e.g. 0.1")))
        }
    }

    fn robot(&self) -> Result<Robot, FormatError> {
        match self.extra("robot") {
            Some("1") => Ok(Robot::One),
            Some("2") => Ok(Robot::Two),
            Some(c) => Err(self.err(format!(
                "column `robot`: `{c}` is not a robot; write 1 or 2 (the robot whose tool is measured)"
            ))),
            None => Err(self.missing("robot", "write 1 or 2 (the robot whose tool is measured)")),
        }
    }

    /// The joint angles of robot `r` (rad): `None` if all its joint cells are empty.
    fn joints(&self, cell: &Cell, r: Robot) -> Result<Option<Vec<f64>>, FormatError> {
        let kinds = joint_kinds(cell);
        let (d1, d2) = (kinds[0].len(), kinds[1].len());
        let (range, kinds) = match r {
            Robot::One => (1..1 + d1, &kinds[0]),
            Robot::Two => (1 + d1..1 + d1 + d2, &kinds[1]),
        };
        if range.clone().all(|k| self.cell(k).is_empty()) {
            return Ok(None);
        }
        let mut q = Vec::with_capacity(range.len());
        for (j, k) in range.enumerate() {
            if self.cell(k).is_empty() {
                return Err(self.missing(
                    &self.want[k],
                    &format!("give all of {r}'s joint values (degrees, mm for a prismatic joint) or none"),
                ));
            }
            q.push(joint_from_file(self.number(k)?, kinds[j]));
        }
        Ok(Some(q))
    }

    /// The reported tip of robot `r` (m): `None` if its three tip cells are empty.
    fn tip(&self, r: Robot, d1: usize, d2: usize) -> Result<Option<Point3<f64>>, FormatError> {
        let k0 = 1 + d1 + d2 + 3 * usize::from(r.number() - 1);
        // A one-robot cell's session has no robot 2 tip columns.
        if k0 + 3 > self.want.len() || (k0..k0 + 3).all(|k| self.cell(k).is_empty()) {
            return Ok(None);
        }
        let mut p = [0.0; 3];
        for (a, k) in (k0..k0 + 3).enumerate() {
            if self.cell(k).is_empty() {
                return Err(
                    self.missing(&self.want[k], "give all three tip coordinates (mm) or none")
                );
            }
            p[a] = self.number(k)? * 1e-3;
        }
        Ok(Some(Point3::from(p)))
    }

    /// The tool named in column `name` (index into the cell robot's tools; empty = `tip`).
    fn tool(&self, cell: &Cell, r: Robot, name: &str) -> Result<usize, FormatError> {
        let Some(t) = self.extra(name) else {
            return Ok(0);
        };
        let robot = cell.robot(r);
        robot.tool_index(t).ok_or_else(|| {
            self.err(format!(
                "column `{name}`: {r} has no tool `{t}`; its tools are {} (add `{t} = [x, y, z]` in mm to [robot{}.tools] of the cell)",
                robot.tool_names().join(", "),
                r.number()
            ))
        })
    }

    /// Fails when a column the row's kind does not use holds a value.
    fn only_fields_of(&self, kind: Kind) -> Result<(), FormatError> {
        let used = kind_columns(kind);
        for name in &EXTRA_COLUMNS[1..] {
            if !used.contains(name) {
                if let Some(v) = self.extra(name) {
                    return Err(self.err(format!(
                        "column `{name}` = `{}`: a {} row does not use it (it belongs to {} rows); leave it empty",
                        cap_echo(v),
                        kind.name(),
                        kinds_using(name).join("/")
                    )));
                }
            }
        }
        Ok(())
    }

    /// Fails unless robot 1's and robot 2's columns of every shared trunk joint agree within
    /// [`SHARED_JOINT_TOL`] (one trunk has one posture); `why` says what the row gives.
    fn same_trunk(
        &self,
        cell: &Cell,
        q1: &[f64],
        q2: &[f64],
        why: &str,
    ) -> Result<(), FormatError> {
        let shared_q = cell.shared_independent_joints();
        let [kinds1, _] = super::joint_kinds(cell);
        for k in 0..shared_q.min(q1.len()).min(q2.len()) {
            let unit = if kinds1[k] { 1e3 } else { 1f64.to_degrees() };
            if ((q1[k] - q2[k]) * unit).abs() > SHARED_JOINT_TOL {
                let (c1, c2) = (
                    super::joint_column(1, k + 1, kinds1[k]),
                    super::joint_column(2, k + 1, kinds1[k]),
                );
                return Err(self.err(format!(
                    "columns `{c1}` = {:.6} and `{c2}` = {:.6}: joint {} is shared by the two robots \
                     (the cell's `robot2.shares`), and {why}; write the same value in both columns",
                    q1[k] * unit,
                    q2[k] * unit,
                    k + 1
                )));
            }
        }
        Ok(())
    }

    /// Both robots' joints (required), tools (`tool1`, `tool2`; empty = `tip`) and tips
    /// (optional, FK-checked) of a two-robot row of `kind`.
    pub(super) fn pair(&self, cell: &Cell, kind: Kind, v: RowValues) -> Result<Pair, FormatError> {
        if !cell.has_robot2() {
            return Err(self.err(format!(
                "column `kind`: a {} row needs two robots, but this cell has only [robot1]; \
                 a one-robot cell takes tracker and plane rows (`robot` = 1)",
                kind.name()
            )));
        }
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let needs = format!(
            "a {} row needs both robots' joint angles (degrees)",
            kind.name()
        );
        let (q1, q2) = match (v.q1, v.q2) {
            (Some(a), Some(b)) => (a, b),
            (None, _) => return Err(self.missing(&format!("r1_q1_deg … r1_q{d1}_deg"), &needs)),
            (_, None) => return Err(self.missing(&format!("r2_q1_deg … r2_q{d2}_deg"), &needs)),
        };
        self.same_trunk(cell, &q1, &q2, "a row with both robots gives it one value")?;
        let tool1 = self.tool(cell, Robot::One, "tool1")?;
        let tool2 = self.tool(cell, Robot::Two, "tool2")?;
        for (r, q, tool, tip) in [
            (Robot::One, &q1, tool1, &v.tips[0]),
            (Robot::Two, &q2, tool2, &v.tips[1]),
        ] {
            if let Some(p) = tip {
                check_tip(cell, r, tool, q, p, self.line_no, self.path)?;
            }
        }
        Ok(Pair {
            q1,
            q2,
            tool1,
            tool2,
            tips: v.tips,
        })
    }

    /// The robot (`robot`), its joints (required), its tool (`tool`; empty = `tip`) and, on a
    /// shared-trunk cell, the other arm's joints if given, of a one-robot row of `kind`. The
    /// other robot's tip must be empty, and so must its joints unless the cell has a shared
    /// trunk (then they are the other arm's posture, its trunk columns equal to the row's). The
    /// row's tip, if given, is FK-checked.
    pub(super) fn single(
        &self,
        cell: &Cell,
        kind: Kind,
        v: RowValues,
    ) -> Result<SingleRow, FormatError> {
        let kind = kind.name();
        let robot = self.robot()?;
        if robot == Robot::Two && !cell.has_robot2() {
            return Err(self.err(format!(
                "column `robot`: this {kind} row is for robot 2, but this cell has only [robot1]; write 1"
            )));
        }
        let (q, q_other) = match robot {
            Robot::One => (v.q1, v.q2),
            Robot::Two => (v.q2, v.q1),
        };
        let other_robot = other(robot);
        if q_other.is_some() && cell.shared_joints == 0 {
            return Err(self.err(format!(
                "columns `r{}_q*_deg`: joints given for {other_robot}, but this {kind} row is for {robot} (column `robot`); \
                 leave the other robot's joint cells empty or set `robot` to {} (the other arm's \
                 joints belong on a one-robot row only on a shared-trunk cell, `robot2.shares`)",
                other_robot.number(),
                other_robot.number()
            )));
        }
        let slot = usize::from(other_robot.number() - 1);
        if v.tips[slot].is_some() {
            return Err(self.err(format!(
                "columns `r{n}_x_mm, r{n}_y_mm, r{n}_z_mm`: a tip given for {other_robot}, but this {kind} row is for {robot}; leave them empty",
                n = other_robot.number()
            )));
        }
        let n = robot.number();
        let q = q.ok_or_else(|| {
            self.missing(
                &format!("r{n}_q1_deg …"),
                &format!("a {kind} row for {robot} needs its joint angles (degrees)"),
            )
        })?;
        if let Some(q_other) = &q_other {
            let (q1, q2) = match robot {
                Robot::One => (&q, q_other),
                Robot::Two => (q_other, &q),
            };
            self.same_trunk(
                cell,
                q1,
                q2,
                &format!("a {kind} row of {robot} on a shared trunk gives the other arm's posture"),
            )?;
        }
        let tool = self.tool(cell, robot, "tool")?;
        if let Some(p) = &v.tips[usize::from(n - 1)] {
            check_tip(cell, robot, tool, &q, p, self.line_no, self.path)?;
        }
        Ok((robot, q, tool, q_other))
    }

    /// A contact or face-contact row's group (required), distance (`distance_mm`, optional,
    /// ≥ 0, the same on every row of the group) and σ (`sigma_mm`, required).
    pub(super) fn contact(
        &self,
        contacts: &mut ContactDistances,
    ) -> Result<(String, Option<f64>, f64), FormatError> {
        let line_no = self.line_no;
        let group = self.required_text(
            "group",
            "name the contact group (rows of one group share one distance), e.g. contact",
        )?;
        let distance_m = self.optional_number("distance_mm")?.map(|d| d * 1e-3);
        if let Some(d) = distance_m {
            if d < 0.0 {
                return Err(self.err(format!("column `distance_mm`: {} is negative; give the distance between the two tool points in mm (≥ 0), or leave it empty to fit it", d * 1e3)));
            }
        }
        match contacts.0.iter().find(|(g, _, _)| *g == group) {
            Some((_, d, first)) if *d != distance_m => {
                return Err(self.err(format!(
                    "column `distance_mm`: contact group `{group}` has distance {} here but {} on line {first}; \
                     give every row of a group the same distance_mm (or leave all empty to fit it)",
                    fmt_opt_mm(distance_m),
                    fmt_opt_mm(*d)
                )));
            }
            Some(_) => {}
            None => contacts.0.push((group.clone(), distance_m, line_no)),
        }
        let sigma_m = self.sigma()?;
        Ok((group, distance_m, sigma_m))
    }
}

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
//! which column is [`FIELD_KINDS`]; sim-cell's README has the table and an example.
//!
//! One job: the session CSV. This file holds the row types, the schema and the reader with its
//! row/column errors; `write.rs` the writer. Sessions are simulated by sim-cell.

use std::path::Path;

use calib_core::{PointPairs, Robot};
use kinematics::base_from_tip;
use nalgebra::{Point3, Unit, Vector3};

use crate::cell::Cell;
use crate::error::FormatError;

mod write;

/// Largest allowed mismatch between a session row's tip columns and FK of its joint columns, mm.
pub const TIP_CONSISTENCY_MM: f64 = 0.01;

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

/// The observation kinds of the `kind` column, in the order documented.
pub const KIND_NAMES: [&str; 5] = ["coincident", "contact", "tracker", "plane", "face_contact"];

/// The face normals of a `face_contact` row: robot 1's outward face normal in its tip frame
/// (`n1_*`), robot 2's in its tip frame (`n2_*`); unitless, normalised on reading. Written
/// only when the session has a `face_contact` row (the last six of [`EXTRA_COLUMNS`]).
pub const FACE_COLUMNS: [&str; 6] = ["n1_x", "n1_y", "n1_z", "n2_x", "n2_y", "n2_z"];

/// The columns of a mixed session after the standard ones ([`Session::csv_header`]), in the
/// order they are written ([`FACE_COLUMNS`] only when a `face_contact` row is present).
pub const EXTRA_COLUMNS: [&str; 17] = [
    "kind",
    "robot",
    "group",
    "tool1",
    "tool2",
    "tool",
    "distance_mm",
    "sigma_mm",
    "tracker_x_mm",
    "tracker_y_mm",
    "tracker_z_mm",
    "n1_x",
    "n1_y",
    "n1_z",
    "n2_x",
    "n2_y",
    "n2_z",
];

/// Which kinds use each optional column (any other kind must leave it empty).
pub const FIELD_KINDS: [(&str, &[&str]); 16] = [
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

/// A session row that is not a coincident handclasp at both robots' default tips. Tools are
/// indices into the cell robot's tools ([`handclasp_cell::CellRobot::tool_index`]: 0 = `tip_mm`).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum SessionKind {
    /// A coincident handclasp with at least one non-default tool.
    Coincident {
        /// Robot 1's reported joints, rad.
        q1: Vec<f64>,
        /// Robot 2's reported joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Robot 1's tool point by its nominal model, m, base 1.
        p_b1: Point3<f64>,
        /// Robot 2's tool point by its nominal model, m, base 2.
        p_b2: Point3<f64>,
    },
    /// The two tool points are a distance apart (e.g. two spheres touching).
    Contact {
        /// Robot 1's reported joints, rad.
        q1: Vec<f64>,
        /// Robot 2's reported joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Contact group: its rows share one distance.
        group: String,
        /// The distance, m; `None`: fitted (one unknown per group).
        distance_m: Option<f64>,
        /// σ of the distance, m.
        sigma_m: f64,
    },
    /// Two flat faces touching flush: the two tool points are a distance apart ALONG the faces'
    /// normal (the faces may slide on each other; see
    /// [`calib_core::whole_cell::ObservationKind::FaceContact`]).
    FaceContact {
        /// Robot 1's reported joints, rad.
        q1: Vec<f64>,
        /// Robot 2's reported joints, rad.
        q2: Vec<f64>,
        /// Robot 1's tool.
        tool1: usize,
        /// Robot 2's tool.
        tool2: usize,
        /// Robot 1's outward face normal, its tip frame (unit).
        n1_tip: Unit<Vector3<f64>>,
        /// Robot 2's outward face normal, its tip frame (unit).
        n2_tip: Unit<Vector3<f64>>,
        /// Contact group: its rows share one distance (one namespace with `Contact` groups).
        group: String,
        /// The distance along the normal, m (the two faces' distances from their tool points
        /// summed); `None`: fitted (one unknown per group).
        distance_m: Option<f64>,
        /// σ of the distance, m.
        sigma_m: f64,
    },
    /// One robot's tool point measured by an external device (a laser tracker) in the unknown
    /// frame of its group.
    Tracker {
        /// The robot measured.
        robot: Robot,
        /// Its reported joints, rad.
        q: Vec<f64>,
        /// Its tool (e.g. the reflector).
        tool: usize,
        /// Tracker group: one unknown tracker frame per group.
        group: String,
        /// The measured position, m, tracker frame.
        p_tracker: Point3<f64>,
        /// σ per axis of the measured position, m.
        sigma_m: f64,
    },
    /// One robot's tool point touches a plane of unknown position.
    Plane {
        /// The robot touching.
        robot: Robot,
        /// Its reported joints, rad.
        q: Vec<f64>,
        /// Its tool.
        tool: usize,
        /// Plane group: one unknown plane per group.
        group: String,
        /// σ of the point's distance from the plane, m.
        sigma_m: f64,
    },
}

impl SessionKind {
    /// The `kind` column's value (one of [`KIND_NAMES`]).
    pub fn name(&self) -> &'static str {
        match self {
            SessionKind::Coincident { .. } => "coincident",
            SessionKind::Contact { .. } => "contact",
            SessionKind::FaceContact { .. } => "face_contact",
            SessionKind::Tracker { .. } => "tracker",
            SessionKind::Plane { .. } => "plane",
        }
    }
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

    /// Count of rows per kind, in [`KIND_NAMES`] order.
    pub fn kind_counts(&self) -> [usize; 5] {
        let mut n = [self.points.len(), 0, 0, 0, 0];
        for o in &self.observations {
            let k = KIND_NAMES
                .iter()
                .position(|k| *k == o.kind.name())
                .unwrap_or(0);
            n[k] += 1;
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

    /// The CSV columns (see the module docs) for joint counts `dof1`, `dof2`.
    pub fn csv_header(dof1: usize, dof2: usize) -> Vec<String> {
        let mut header = vec!["point".to_string()];
        for (r, d) in [(1, dof1), (2, dof2)] {
            for k in 1..=d {
                header.push(format!("r{r}_q{k}_deg"));
            }
        }
        header.extend(
            [
                "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
            ]
            .map(String::from),
        );
        header
    }

    /// Writes the session CSV for `cell`'s robots ([`Session::csv_text`]).
    pub fn write_csv(&self, path: &Path, cell: &Cell) -> Result<(), FormatError> {
        std::fs::write(path, self.csv_text(cell)).map_err(|e| FormatError::io(path, e))
    }

    /// Reads a session CSV for `cell` (see [`Session::parse_csv`]).
    pub fn read_csv(path: &Path, cell: &Cell) -> Result<Session, FormatError> {
        let text = std::fs::read_to_string(path).map_err(|e| FormatError::io(path, e))?;
        Session::parse_csv(&text, path, cell)
    }

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
    /// [`SessionKind`] (the crate README's table): fields a kind does not use must be empty,
    /// tip columns are required on coincident rows and FK-checked wherever given, tools are named
    /// from the cell (`tip` or `[robotN.tools]`), and the rows of one contact group agree on
    /// `distance_mm`. Errors name the line and column and say what would work.
    pub fn parse_csv(text: &str, path: &Path, cell: &Cell) -> Result<Session, FormatError> {
        let err = |message: String| FormatError::Session {
            path: path.to_path_buf(),
            message,
        };
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let want = Session::csv_header(d1, d2);
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
                        unused.join(", ")
                    )
                } else {
                    format!(" (columns not used: {})", unused.join(", "))
                };
                return Err(err(format!(
                    "line 1: the header has no column `{name}`{unused}, which this cell ({} with {d1} joints, {} with {d2}) needs; \
                     the header must hold these columns (any order, extra columns ignored): {}",
                    cell.robot1.model.name(),
                    cell.robot2.model.name(),
                    want[..required].join(","),
                )));
            }
            idx.push(found);
        }
        let extra: Vec<Option<usize>> = EXTRA_COLUMNS.iter().map(|c| col(c)).collect();
        let mut points = Vec::new();
        let mut observations = Vec::new();
        let mut contact_distance: Vec<(String, Option<f64>, u64)> = Vec::new();
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
                    row.cell(0)
                ))
            })?;
            if !has_kind {
                let mut v = Vec::with_capacity(want.len() - 1);
                for k in 1..want.len() {
                    v.push(row.number(k)?);
                }
                let q1: Vec<f64> = v[..d1].iter().map(|x| x.to_radians()).collect();
                let q2: Vec<f64> = v[d1..d1 + d2].iter().map(|x| x.to_radians()).collect();
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
            let Some(&kind) = KIND_NAMES.iter().find(|k| **k == kind_text) else {
                return Err(err(format!(
                    "line {line_no}, column `kind`: `{kind_text}` is not an observation kind; use one of {} (empty = coincident)",
                    KIND_NAMES.join(", ")
                )));
            };
            row.only_fields_of(kind)?;
            let q1 = row.joints(cell, Robot::One)?;
            let q2 = row.joints(cell, Robot::Two)?;
            let tips = [row.tip(Robot::One, d1, d2)?, row.tip(Robot::Two, d1, d2)?];
            let both = |q1: Option<Vec<f64>>, q2: Option<Vec<f64>>| match (q1, q2) {
                (Some(a), Some(b)) => Ok((a, b)),
                (None, _) => Err(row.missing(
                    &format!("r1_q1_deg … r1_q{d1}_deg"),
                    &format!("a {kind} row needs both robots' joint angles (degrees)"),
                )),
                (_, None) => Err(row.missing(
                    &format!("r2_q1_deg … r2_q{d2}_deg"),
                    &format!("a {kind} row needs both robots' joint angles (degrees)"),
                )),
            };
            match kind {
                "coincident" | "contact" | "face_contact" => {
                    let (q1, q2) = both(q1, q2)?;
                    let tool1 = row.tool(cell, Robot::One, "tool1")?;
                    let tool2 = row.tool(cell, Robot::Two, "tool2")?;
                    for (r, q, tool, tip) in [
                        (Robot::One, &q1, tool1, &tips[0]),
                        (Robot::Two, &q2, tool2, &tips[1]),
                    ] {
                        if let Some(p) = tip {
                            check_tip(cell, r, tool, q, p, line_no, path)?;
                        }
                    }
                    if kind == "contact" || kind == "face_contact" {
                        let group = row.required_text("group", "name the contact group (rows of one group share one distance), e.g. contact")?;
                        let distance_m = row.optional_number("distance_mm")?.map(|d| d * 1e-3);
                        if let Some(d) = distance_m {
                            if d < 0.0 {
                                return Err(err(format!("line {line_no}, column `distance_mm`: {} is negative; give the distance between the two tool points in mm (≥ 0), or leave it empty to fit it", d * 1e3)));
                            }
                        }
                        match contact_distance.iter().find(|(g, _, _)| *g == group) {
                            Some((_, d, first)) if *d != distance_m => {
                                return Err(err(format!(
                                    "line {line_no}, column `distance_mm`: contact group `{group}` has distance {} here but {} on line {first}; \
                                     give every row of a group the same distance_mm (or leave all empty to fit it)",
                                    fmt_opt_mm(distance_m),
                                    fmt_opt_mm(*d)
                                )));
                            }
                            Some(_) => {}
                            None => contact_distance.push((group.clone(), distance_m, line_no)),
                        }
                        let sigma_m = row.sigma()?;
                        let kind = if kind == "contact" {
                            SessionKind::Contact {
                                q1,
                                q2,
                                tool1,
                                tool2,
                                group,
                                distance_m,
                                sigma_m,
                            }
                        } else {
                            SessionKind::FaceContact {
                                q1,
                                q2,
                                tool1,
                                tool2,
                                n1_tip: row.normal(1)?,
                                n2_tip: row.normal(2)?,
                                group,
                                distance_m,
                                sigma_m,
                            }
                        };
                        observations.push(SessionObservation { point, kind });
                    } else {
                        let [Some(p_b1), Some(p_b2)] = tips else {
                            let r = if tips[0].is_none() { 1 } else { 2 };
                            return Err(row.missing(
                                &format!("r{r}_x_mm, r{r}_y_mm, r{r}_z_mm"),
                                "a coincident row needs both robots' reported tips (mm, each robot's base)",
                            ));
                        };
                        if tool1 == 0 && tool2 == 0 {
                            points.push(SessionPoint {
                                point,
                                q1,
                                q2,
                                p_b1,
                                p_b2,
                            });
                        } else {
                            observations.push(SessionObservation {
                                point,
                                kind: SessionKind::Coincident {
                                    q1,
                                    q2,
                                    tool1,
                                    tool2,
                                    p_b1,
                                    p_b2,
                                },
                            });
                        }
                    }
                }
                _ => {
                    let robot = row.robot()?;
                    let (q, other_given) = match robot {
                        Robot::One => (q1, q2.is_some()),
                        Robot::Two => (q2, q1.is_some()),
                    };
                    let other_robot = other(robot);
                    if other_given {
                        return Err(err(format!(
                            "line {line_no}, columns `r{}_q*_deg`: joints given for {other_robot}, but this {kind} row is for {robot} (column `robot`); \
                             leave the other robot's joint cells empty or set `robot` to {}",
                            other_robot.number(),
                            other_robot.number()
                        )));
                    }
                    let slot = usize::from(other_robot.number() - 1);
                    if tips[slot].is_some() {
                        return Err(err(format!(
                            "line {line_no}, columns `r{n}_x_mm, r{n}_y_mm, r{n}_z_mm`: a tip given for {other_robot}, but this {kind} row is for {robot}; leave them empty",
                            n = other_robot.number()
                        )));
                    }
                    let n = robot.number();
                    let q = q.ok_or_else(|| {
                        row.missing(
                            &format!("r{n}_q1_deg …"),
                            &format!("a {kind} row for {robot} needs its joint angles (degrees)"),
                        )
                    })?;
                    let tool = row.tool(cell, robot, "tool")?;
                    if let Some(p) = &tips[usize::from(n - 1)] {
                        check_tip(cell, robot, tool, &q, p, line_no, path)?;
                    }
                    let what = if kind == "tracker" {
                        "name the tracker frame (one unknown frame per group), e.g. the file it came from"
                    } else {
                        "name the plane (one unknown plane per group), e.g. table"
                    };
                    let group = row.required_text("group", what)?;
                    let sigma_m = row.sigma()?;
                    let kind = if kind == "tracker" {
                        let mut p = [0.0; 3];
                        for (a, c) in ["tracker_x_mm", "tracker_y_mm", "tracker_z_mm"]
                            .iter()
                            .enumerate()
                        {
                            p[a] = row.optional_number(c)?.ok_or_else(|| {
                                row.missing(
                                    c,
                                    "a tracker row needs the measured position (mm, tracker frame)",
                                )
                            })? * 1e-3;
                        }
                        SessionKind::Tracker {
                            robot,
                            q,
                            tool,
                            group,
                            p_tracker: Point3::from(p),
                            sigma_m,
                        }
                    } else {
                        SessionKind::Plane {
                            robot,
                            q,
                            tool,
                            group,
                            sigma_m,
                        }
                    };
                    observations.push(SessionObservation { point, kind });
                }
            }
        }
        Ok(Session {
            points,
            observations,
        })
    }
}

/// The robot that is not `r`.
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
struct RowReader<'a> {
    record: &'a csv::StringRecord,
    line_no: u64,
    want: &'a [String],
    idx: &'a [Option<usize>],
    extra: &'a [Option<usize>],
    path: &'a Path,
}

impl RowReader<'_> {
    fn err(&self, message: String) -> FormatError {
        FormatError::Session {
            path: self.path.to_path_buf(),
            message: format!("line {}, {message}", self.line_no),
        }
    }

    fn missing(&self, column: &str, why: &str) -> FormatError {
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
                    "column `{}`: `{c}` is not a finite number",
                    self.want[k]
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

    fn optional_number(&self, name: &str) -> Result<Option<f64>, FormatError> {
        match self.extra(name) {
            None => Ok(None),
            Some(c) => c
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .map(Some)
                .ok_or_else(|| self.err(format!("column `{name}`: `{c}` is not a finite number"))),
        }
    }

    /// Robot `r`'s face normal of a `face_contact` row (columns `n{r}_x`, `n{r}_y`, `n{r}_z`,
    /// its tip frame, unitless), normalised. Errors: a missing or non-finite component, or a
    /// zero vector.
    fn normal(&self, r: u8) -> Result<Unit<Vector3<f64>>, FormatError> {
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

    fn required_text(&self, name: &str, why: &str) -> Result<String, FormatError> {
        self.extra(name)
            .map(str::to_string)
            .ok_or_else(|| self.missing(name, why))
    }

    fn sigma(&self) -> Result<f64, FormatError> {
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
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let range = match r {
            Robot::One => 1..1 + d1,
            Robot::Two => 1 + d1..1 + d1 + d2,
        };
        if range.clone().all(|k| self.cell(k).is_empty()) {
            return Ok(None);
        }
        let mut q = Vec::with_capacity(range.len());
        for k in range {
            if self.cell(k).is_empty() {
                return Err(self.missing(
                    &self.want[k],
                    &format!("give all of {r}'s joint angles (degrees) or none"),
                ));
            }
            q.push(self.number(k)?.to_radians());
        }
        Ok(Some(q))
    }

    /// The reported tip of robot `r` (m): `None` if its three tip cells are empty.
    fn tip(&self, r: Robot, d1: usize, d2: usize) -> Result<Option<Point3<f64>>, FormatError> {
        let k0 = 1 + d1 + d2 + 3 * usize::from(r.number() - 1);
        if (k0..k0 + 3).all(|k| self.cell(k).is_empty()) {
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
    fn only_fields_of(&self, kind: &str) -> Result<(), FormatError> {
        for (name, kinds) in FIELD_KINDS {
            if !kinds.contains(&kind) {
                if let Some(v) = self.extra(name) {
                    return Err(self.err(format!(
                        "column `{name}` = `{v}`: a {kind} row does not use it (it belongs to {} rows); leave it empty",
                        kinds.join("/")
                    )));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;

//! The session rows of each observation kind: [`SessionKind`] (one arm per
//! [`calib_core::whole_cell::Kind`]), the extra columns each kind fills, how a row of each kind is
//! read and written, and the whole-cell observation it becomes. Everything a kind owns in the
//! session CSV is in this file; `read.rs` and `write.rs` hold what the kinds share (the header,
//! the joint, tip and tool columns, the line and column of an error), `problem.rs` the nuisance
//! groups.
//!
//! A new kind: an arm of [`Kind`] and of [`calib_core::whole_cell::ObservationKind`] with its
//! residual (calib-core), an arm of [`SessionKind`], its columns ([`EXTRA_COLUMNS`],
//! `columns`) and its arms of the matches below (the compiler lists them).

use calib_core::whole_cell::{Kind, Noise3, ObservationKind};
use calib_core::Robot;
use nalgebra::{Point3, Unit, Vector3};

use super::read::{ContactDistances, RowReader, RowValues};
use super::write::RowWriter;
use super::SessionPoint;
use crate::cell::Cell;
use crate::error::FormatError;

/// The `kind` column's values, in [`Kind::ALL`] order (the order messages list them in).
pub const KIND_NAMES: [&str; Kind::ALL.len()] = {
    let mut names = [""; Kind::ALL.len()];
    let mut k = 0;
    while k < names.len() {
        names[k] = Kind::ALL[k].name();
        k += 1;
    }
    names
};

/// The face normals of a `face_contact` row: robot 1's outward face normal in its tip frame
/// (`n1_*`), robot 2's in its tip frame (`n2_*`); unitless, normalised on reading. Written
/// only when the session has a `face_contact` row (the last six of [`EXTRA_COLUMNS`]).
pub const FACE_COLUMNS: [&str; 6] = ["n1_x", "n1_y", "n1_z", "n2_x", "n2_y", "n2_z"];

/// The columns of a mixed session after the standard ones ([`super::Session::csv_header`]), in
/// the order they are written: `kind`, then every kind's columns ([`kind_columns`]). The first
/// [`ALWAYS_WRITTEN`] are written in every mixed session; a later one (a column added with a later
/// kind, such as [`FACE_COLUMNS`]) only when a row uses it, so that the files of sessions without
/// that kind stay as they were.
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

/// How many of [`EXTRA_COLUMNS`] every mixed session writes (`kind` … `tracker_z_mm`).
pub const ALWAYS_WRITTEN: usize = 11;

/// The extra columns a row of `kind` fills ([`EXTRA_COLUMNS`] order, `kind` itself aside); a
/// row must leave every other one empty.
pub fn kind_columns(kind: Kind) -> &'static [&'static str] {
    match kind {
        Kind::Coincident => &["tool1", "tool2"],
        Kind::Contact => &["group", "tool1", "tool2", "distance_mm", "sigma_mm"],
        Kind::FaceContact => &[
            "group",
            "tool1",
            "tool2",
            "distance_mm",
            "sigma_mm",
            "n1_x",
            "n1_y",
            "n1_z",
            "n2_x",
            "n2_y",
            "n2_z",
        ],
        Kind::Tracker => &[
            "robot",
            "group",
            "tool",
            "sigma_mm",
            "tracker_x_mm",
            "tracker_y_mm",
            "tracker_z_mm",
        ],
        Kind::Plane => &["robot", "group", "tool", "sigma_mm"],
    }
}

/// The kinds whose rows fill `column`, for messages: the two-robot kinds first, then the
/// one-robot kinds, each in [`Kind::ALL`] order.
pub(super) fn kinds_using(column: &str) -> Vec<&'static str> {
    let uses = |k: &Kind| kind_columns(*k).contains(&column);
    let two = Kind::ALL.into_iter().filter(|k| k.two_robot() && uses(k));
    let one = Kind::ALL.into_iter().filter(|k| !k.two_robot() && uses(k));
    two.chain(one).map(Kind::name).collect()
}

/// A session row that is not a coincident handclasp at both robots' default tips. Tools are
/// indices into the cell robot's tools ([`crate::CellRobot::tool_index`]: 0 = `tip_mm`).
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
    /// normal (the faces may slide on each other; see [`ObservationKind::FaceContact`]).
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

/// A two-robot row's joints and tools: `(q1, q2, tool1, tool2)`, rad.
pub type ToolPair<'a> = (&'a [f64], &'a [f64], usize, usize);

/// A face contact's outward normals `(n1_tip, n2_tip)`, each in its robot's tip frame.
pub type FaceNormals = (Unit<Vector3<f64>>, Unit<Vector3<f64>>);

impl SessionKind {
    /// The row's kind.
    pub fn kind(&self) -> Kind {
        match self {
            SessionKind::Coincident { .. } => Kind::Coincident,
            SessionKind::Contact { .. } => Kind::Contact,
            SessionKind::FaceContact { .. } => Kind::FaceContact,
            SessionKind::Tracker { .. } => Kind::Tracker,
            SessionKind::Plane { .. } => Kind::Plane,
        }
    }

    /// The `kind` column's value (one of [`KIND_NAMES`]).
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// Both robots' joints and tools of a two-robot row ([`Kind::two_robot`]); `None` for a
    /// one-robot row.
    pub fn pair(&self) -> Option<ToolPair<'_>> {
        match self {
            SessionKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                ..
            }
            | SessionKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                ..
            }
            | SessionKind::FaceContact {
                q1,
                q2,
                tool1,
                tool2,
                ..
            } => Some((q1, q2, *tool1, *tool2)),
            SessionKind::Tracker { .. } | SessionKind::Plane { .. } => None,
        }
    }

    /// The robot, joints (rad) and tool of a one-robot row; `None` for a two-robot row.
    pub fn single(&self) -> Option<(Robot, &[f64], usize)> {
        match self {
            SessionKind::Tracker { robot, q, tool, .. }
            | SessionKind::Plane { robot, q, tool, .. } => Some((*robot, q, *tool)),
            SessionKind::Coincident { .. }
            | SessionKind::Contact { .. }
            | SessionKind::FaceContact { .. } => None,
        }
    }

    /// The name of the row's nuisance group (its kind is [`Kind::group`]); `None` for a
    /// coincident row.
    pub fn group(&self) -> Option<&str> {
        match self {
            SessionKind::Coincident { .. } => None,
            SessionKind::Contact { group, .. }
            | SessionKind::FaceContact { group, .. }
            | SessionKind::Tracker { group, .. }
            | SessionKind::Plane { group, .. } => Some(group),
        }
    }

    /// The given distance of a contact or face-contact row, m; `None` when it is fitted, or for
    /// another kind.
    pub fn distance_m(&self) -> Option<f64> {
        match self {
            SessionKind::Contact { distance_m, .. }
            | SessionKind::FaceContact { distance_m, .. } => *distance_m,
            SessionKind::Coincident { .. }
            | SessionKind::Tracker { .. }
            | SessionKind::Plane { .. } => None,
        }
    }

    /// A face contact's outward normals `(n1_tip, n2_tip)`, each in its robot's tip frame;
    /// `None` for another kind.
    pub fn face_normals(&self) -> Option<FaceNormals> {
        match self {
            SessionKind::FaceContact { n1_tip, n2_tip, .. } => Some((*n1_tip, *n2_tip)),
            SessionKind::Coincident { .. }
            | SessionKind::Contact { .. }
            | SessionKind::Tracker { .. }
            | SessionKind::Plane { .. } => None,
        }
    }

    /// The whole-cell observation of this row: `noise` is the cell's handclasp noise (coincident
    /// rows; the other kinds carry their row's σ), `group` the index of its nuisance group in the
    /// problem's list of that kind (ignored by a coincident row).
    pub(crate) fn observation(&self, noise: Noise3, group: usize) -> ObservationKind {
        match self.clone() {
            SessionKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                ..
            } => ObservationKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                noise,
            },
            SessionKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                sigma_m,
                ..
            } => ObservationKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                group,
                sigma_m,
            },
            SessionKind::FaceContact {
                q1,
                q2,
                tool1,
                tool2,
                n1_tip,
                n2_tip,
                sigma_m,
                ..
            } => ObservationKind::FaceContact {
                q1,
                q2,
                tool1,
                tool2,
                n1_tip,
                n2_tip,
                group,
                sigma_m,
            },
            SessionKind::Tracker {
                robot,
                q,
                tool,
                p_tracker,
                sigma_m,
                ..
            } => ObservationKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                noise: Noise3::Isotropic { sigma_m },
            },
            SessionKind::Plane {
                robot,
                q,
                tool,
                sigma_m,
                ..
            } => ObservationKind::Plane {
                robot,
                q,
                tool,
                group,
                sigma_m,
            },
        }
    }

    /// Fills the row's columns: its joints, tools and tips, and its own extra columns.
    pub(super) fn write(&self, w: &mut RowWriter<'_>) {
        match self {
            SessionKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                p_b1,
                p_b2,
            } => {
                w.pair(q1, q2, *tool1, *tool2);
                w.tips(p_b1, p_b2);
            }
            SessionKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                group,
                distance_m,
                sigma_m,
            } => {
                w.pair(q1, q2, *tool1, *tool2);
                w.contact(group, *distance_m, *sigma_m);
            }
            SessionKind::FaceContact {
                q1,
                q2,
                tool1,
                tool2,
                n1_tip,
                n2_tip,
                group,
                distance_m,
                sigma_m,
            } => {
                w.pair(q1, q2, *tool1, *tool2);
                w.contact(group, *distance_m, *sigma_m);
                for (c, v) in FACE_COLUMNS.iter().zip(n1_tip.iter().chain(n2_tip.iter())) {
                    // `+ 0.0` writes −0 as 0.
                    w.set(c, format!("{:.9}", v + 0.0));
                }
            }
            SessionKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                sigma_m,
            } => {
                w.single(*robot, q, *tool);
                w.set("group", group.clone());
                w.set("sigma_mm", RowWriter::mm(*sigma_m));
                for (a, c) in ["tracker_x_mm", "tracker_y_mm", "tracker_z_mm"]
                    .iter()
                    .enumerate()
                {
                    w.set(c, RowWriter::mm(p_tracker[a]));
                }
            }
            SessionKind::Plane {
                robot,
                q,
                tool,
                group,
                sigma_m,
            } => {
                w.single(*robot, q, *tool);
                w.set("group", group.clone());
                w.set("sigma_mm", RowWriter::mm(*sigma_m));
            }
        }
    }
}

/// A data row as read: a coincident handclasp at the default tips, or a row of another kind.
pub(super) enum ReadRow {
    /// A coincident handclasp at both robots' default tips.
    Point(SessionPoint),
    /// Any other row, with the other arm's joints of a one-robot row on a shared trunk (rad).
    Observation(SessionKind, Option<Vec<f64>>),
}

/// Reads the fields of a row of `kind` numbered `point` (its joint and tip columns in `values`,
/// every column its kind does not use already checked empty). `contacts` holds the distance of
/// each contact group read so far.
pub(super) fn read_row(
    kind: Kind,
    row: &RowReader<'_>,
    values: RowValues,
    cell: &Cell,
    point: usize,
    contacts: &mut ContactDistances,
) -> Result<ReadRow, FormatError> {
    Ok(match kind {
        Kind::Coincident => {
            let p = row.pair(cell, kind, values)?;
            let [Some(p_b1), Some(p_b2)] = p.tips else {
                let r = if p.tips[0].is_none() { 1 } else { 2 };
                return Err(row.missing(
                    &format!("r{r}_x_mm, r{r}_y_mm, r{r}_z_mm"),
                    "a coincident row needs both robots' reported tips (mm, each robot's base)",
                ));
            };
            if p.tool1 == 0 && p.tool2 == 0 {
                ReadRow::Point(SessionPoint {
                    point,
                    q1: p.q1,
                    q2: p.q2,
                    p_b1,
                    p_b2,
                })
            } else {
                ReadRow::Observation(
                    SessionKind::Coincident {
                        q1: p.q1,
                        q2: p.q2,
                        tool1: p.tool1,
                        tool2: p.tool2,
                        p_b1,
                        p_b2,
                    },
                    None,
                )
            }
        }
        Kind::Contact | Kind::FaceContact => {
            let p = row.pair(cell, kind, values)?;
            let (group, distance_m, sigma_m) = row.contact(contacts)?;
            ReadRow::Observation(
                if kind == Kind::Contact {
                    SessionKind::Contact {
                        q1: p.q1,
                        q2: p.q2,
                        tool1: p.tool1,
                        tool2: p.tool2,
                        group,
                        distance_m,
                        sigma_m,
                    }
                } else {
                    SessionKind::FaceContact {
                        q1: p.q1,
                        q2: p.q2,
                        tool1: p.tool1,
                        tool2: p.tool2,
                        n1_tip: row.normal(1)?,
                        n2_tip: row.normal(2)?,
                        group,
                        distance_m,
                        sigma_m,
                    }
                },
                None,
            )
        }
        Kind::Tracker => {
            let (robot, q, tool, q_other) = row.single(cell, kind, values)?;
            let group = row.required_text(
                "group",
                "name the tracker frame (one unknown frame per group), e.g. the file it came from",
            )?;
            let sigma_m = row.sigma()?;
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
            ReadRow::Observation(
                SessionKind::Tracker {
                    robot,
                    q,
                    tool,
                    group,
                    p_tracker: Point3::from(p),
                    sigma_m,
                },
                q_other,
            )
        }
        Kind::Plane => {
            let (robot, q, tool, q_other) = row.single(cell, kind, values)?;
            let group = row.required_text(
                "group",
                "name the plane (one unknown plane per group), e.g. table",
            )?;
            let sigma_m = row.sigma()?;
            ReadRow::Observation(
                SessionKind::Plane {
                    robot,
                    q,
                    tool,
                    group,
                    sigma_m,
                },
                q_other,
            )
        }
    })
}

//! The import mapping file: how a controller's or a dataset's CSV becomes session rows of a cell
//! (`handclasp import`). [`ImportMap::from_toml_str`] reads and checks a mapping against the
//! cell; [`ImportMap::read_rows`] converts one input file's text and appends its rows to a
//! [`Session`].
//!
//! The mapping file (TOML; documented with examples in docs/formats.md, § The import mapping
//! file):
//! ```toml
//! kind = "contact"            # coincident | contact | tracker | plane
//! robot = 1                   # tracker and plane: the robot whose tool is measured / touches
//! group = "{stem}"            # contact/tracker/plane group; "{stem}" = the input file's stem
//! tool = "reflector"          # tracker/plane tool (default "tip"); tool1/tool2 for two-robot kinds
//! sigma_mm = 1.3              # σ of every row, mm (or [tracker] sigma_column)
//! distance_mm = 116           # contact: known distance; absent = fitted per group
//! source_id = "pose"          # optional: a source column kept as the session's source_id
//! [joints]
//! unit = "rad"                # rad | deg
//! robot1 = ["r_s_rad", "r_l_rad", "r_u_rad", "r_r_rad", "r_b_rad", "r_t_rad"]
//! robot2 = "q_left"           # one column holding an array: its elements in chain order
//! [tracker]                   # tracker kind only
//! columns = ["leica_x_m", "leica_y_m", "leica_z_m"]   # or "markers[0]", an array column
//! unit = "m"                  # m | mm (also the unit of sigma_column)
//! sigma_column = "leica_unc_m"
//! [[rows]]                    # optional: several session rows per input row, each the keys
//! robot = 1                   # above (kind, robot, group, tool…, [rows.tracker]) over the
//! [[rows]]                    # top-level ones
//! robot = 2
//! ```
//! A column name may index an array-valued cell (`q[3]`, `markers[0][1]`; numpy's `[0.1 0.2]`
//! and pandas' `[0.1, 0.2]` are read), see docs/formats.md.
//!
//! Rows: a tracker row with an empty or NaN tracker value is skipped (and counted); an empty or
//! NaN joint angle is an error naming the file, line and column. The coincident kind's tip
//! columns are the nominal FK of the joints with the row's tools. Point numbers continue the
//! session's (1, 2, … over every output row of all inputs in order). A kind that has no mapping
//! yet (a face contact: a map has no normal columns) is refused by name, and so is a key the
//! map would not use (a joint list of a robot no row measures, a top-level key every `[[rows]]`
//! entry overrides, an unknown key).
//!
//! Errors are [`FormatError::Map`] (the mapping file, with the key and the fix) and
//! [`FormatError::Input`] (an input file, with the line and column).

use std::path::Path;

use calib_core::whole_cell::Kind;
use calib_core::Robot;
use kinematics::base_from_tip;
use nalgebra::Point3;
use serde::Deserialize;

use crate::cell::Cell;
use crate::error::FormatError;
use crate::session::{Session, SessionKind, SessionObservation, SessionPoint, KIND_NAMES};

mod columns;
#[cfg(test)]
mod tests;

use columns::{ColumnList, ColumnRef, LocatedColumn};

/// The keys of one output row: at the top of the map (every row's defaults) or in one
/// `[[rows]]` entry (over the top-level ones).
#[derive(Debug, Clone, Default, Deserialize)]
struct RowKeys {
    kind: Option<String>,
    robot: Option<u8>,
    group: Option<String>,
    tool: Option<String>,
    tool1: Option<String>,
    tool2: Option<String>,
    sigma_mm: Option<f64>,
    distance_mm: Option<f64>,
    tracker: Option<TrackerMap>,
}

/// [`RowKeys`]' names, in the order messages list them.
const ROW_KEYS: [&str; 9] = [
    "kind",
    "robot",
    "group",
    "tool",
    "tool1",
    "tool2",
    "sigma_mm",
    "distance_mm",
    "tracker",
];

/// The top-level keys that are not a row's.
const MAP_KEYS: [&str; 3] = ["joints", "source_id", "rows"];

impl RowKeys {
    /// Which keys are set, in [`ROW_KEYS`] order.
    fn set(&self) -> [bool; ROW_KEYS.len()] {
        [
            self.kind.is_some(),
            self.robot.is_some(),
            self.group.is_some(),
            self.tool.is_some(),
            self.tool1.is_some(),
            self.tool2.is_some(),
            self.sigma_mm.is_some(),
            self.distance_mm.is_some(),
            self.tracker.is_some(),
        ]
    }

    /// These keys over the `defaults`.
    fn over(&self, defaults: &RowKeys) -> RowKeys {
        RowKeys {
            kind: self.kind.clone().or_else(|| defaults.kind.clone()),
            robot: self.robot.or(defaults.robot),
            group: self.group.clone().or_else(|| defaults.group.clone()),
            tool: self.tool.clone().or_else(|| defaults.tool.clone()),
            tool1: self.tool1.clone().or_else(|| defaults.tool1.clone()),
            tool2: self.tool2.clone().or_else(|| defaults.tool2.clone()),
            sigma_mm: self.sigma_mm.or(defaults.sigma_mm),
            distance_mm: self.distance_mm.or(defaults.distance_mm),
            tracker: self.tracker.clone().or_else(|| defaults.tracker.clone()),
        }
    }
}

/// The mapping file as written (its unknown keys are refused before it is read as this).
#[derive(Debug, Deserialize)]
struct MapFile {
    #[serde(flatten)]
    defaults: RowKeys,
    joints: JointsMap,
    source_id: Option<String>,
    #[serde(default)]
    rows: Vec<RowKeys>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointsMap {
    unit: String,
    /// The unit of a prismatic joint's column: `m` or `mm` (default `mm`).
    #[serde(default)]
    prismatic_unit: Option<String>,
    #[serde(default)]
    robot1: Option<ColumnList>,
    #[serde(default)]
    robot2: Option<ColumnList>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackerMap {
    columns: ColumnList,
    unit: String,
    #[serde(default)]
    sigma_column: Option<String>,
}

/// The kinds a map can make (a two-robot kind is a contact or a coincident handclasp, a
/// one-robot kind a tracker or a plane row); another kind is refused by name when the map is
/// read, until its fields have columns in the map.
const IMPORTED_KINDS: [Kind; 4] = [Kind::Coincident, Kind::Contact, Kind::Tracker, Kind::Plane];

/// The tracker columns of a row: the three position columns, m per file unit, the σ column.
#[derive(Debug, Clone)]
struct TrackerColumns {
    xyz: [ColumnRef; 3],
    m_per_unit: f64,
    sigma: Option<ColumnRef>,
}

/// One output row per input row, checked against the cell.
#[derive(Debug, Clone)]
struct RowSpec {
    kind: Kind,
    robot: Robot,
    group: String,
    tools: [usize; 2],
    sigma_m: Option<f64>,
    distance_m: Option<f64>,
    tracker: Option<TrackerColumns>,
}

impl RowSpec {
    /// The robots whose joints the row uses.
    fn robots(&self) -> Vec<Robot> {
        if self.kind.two_robot() {
            vec![Robot::One, Robot::Two]
        } else {
            vec![self.robot]
        }
    }
}

/// A mapping file checked against a cell: which rows it makes of each input row and from which
/// columns.
#[derive(Debug, Clone)]
pub struct ImportMap {
    rows: Vec<RowSpec>,
    deg_per_unit: f64,
    /// Metres per file unit of a prismatic joint's column (`[joints] prismatic_unit`).
    m_per_prismatic_unit: f64,
    /// Per robot, whether each joint is prismatic (chain order).
    prismatic: [Vec<bool>; 2],
    joints: [Option<Vec<ColumnRef>>; 2],
    source_id: Option<String>,
}

/// What one input file gave: the rows appended and the tracker rows skipped for want of a
/// tracker value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImportCount {
    /// Rows appended to the session.
    pub rows: usize,
    /// Tracker rows skipped (an empty or NaN tracker value or σ).
    pub skipped: usize,
}

/// The keys a map may hold, for messages.
const KEYS_HELP: &str = "keys: kind, robot, group, tool, tool1, tool2, sigma_mm, distance_mm, \
    source_id, [joints] unit, prismatic_unit, robot1, robot2, [tracker] columns, unit, sigma_column, [[rows]] \
    (each with the row keys kind … distance_mm and [rows.tracker])";

/// Refuses a key of `table` that is neither a row key nor (`top`) a map key, naming it (`at`
/// is where: `the top` or `[[rows]] entry k`) and the fix.
fn unknown_keys(table: &toml::Table, top: bool, at: &str) -> Result<(), String> {
    for key in table.keys() {
        let known = ROW_KEYS.contains(&key.as_str()) || (top && MAP_KEYS.contains(&key.as_str()));
        if known {
            continue;
        }
        let hint = match key.as_str() {
            "robot1" | "robot2" => {
                format!(" (a robot's joint columns go in [joints]: `[joints] {key} = [...]`)")
            }
            "unit" => " (the joints' unit goes in [joints], the tracker's in [tracker])".into(),
            "columns" | "sigma_column" => format!(" (`{key}` goes in [tracker])"),
            "joints" | "source_id" | "rows" => " (it belongs at the top of the map)".into(),
            _ => String::new(),
        };
        return Err(format!(
            "unknown key `{key}` at {at}{hint}; it would be ignored: remove or move it ({KEYS_HELP})"
        ));
    }
    Ok(())
}

/// A TOML error's message with the map line it is on.
fn toml_message(e: &toml::de::Error, text: &str) -> String {
    // A span over the whole text (an error of a flattened key) names no line.
    let line = e
        .span()
        .filter(|s| s.len() < text.trim_end().len())
        .map(|s| {
            let n = text[..s.start.min(text.len())].matches('\n').count() + 1;
            let content = text.lines().nth(n - 1).unwrap_or("").trim();
            format!(" (line {n}: `{content}`)")
        });
    format!(
        "{}{} ({KEYS_HELP})",
        e.message().trim_end(),
        line.unwrap_or_default()
    )
}

impl ImportMap {
    /// Reads the mapping file text `text` (named `path` in messages) and checks it against
    /// `cell`: the keys (an unknown key, or one the map would not use, is refused), and for
    /// each output row (the top-level keys, or each `[[rows]]` entry over them) the kind, the
    /// robot, the tools (by name in the cell), σ, the contact distance, the group and the
    /// tracker columns, each where its kind needs it and nowhere else; the joint columns (one
    /// per joint of each robot a row uses, and none of a robot no row uses) and their unit.
    ///
    /// Errors: [`FormatError::Map`] naming the key (and the `[[rows]]` entry) and what would
    /// work.
    pub fn from_toml_str(text: &str, path: &Path, cell: &Cell) -> Result<ImportMap, FormatError> {
        let at = |message: String| FormatError::Map {
            path: path.to_path_buf(),
            message,
        };
        let table: toml::Table = toml::from_str(text).map_err(|e| at(toml_message(&e, text)))?;
        unknown_keys(&table, true, "the top").map_err(at)?;
        if let Some(rows) = table.get("rows").and_then(toml::Value::as_array) {
            for (k, row) in rows.iter().enumerate() {
                if let Some(t) = row.as_table() {
                    unknown_keys(t, false, &format!("[[rows]] entry {}", k + 1)).map_err(at)?;
                }
            }
        }
        let map: MapFile = toml::from_str(text).map_err(|e| at(toml_message(&e, text)))?;
        // Top-level keys every [[rows]] entry overrides would be ignored.
        if !map.rows.is_empty() {
            let top = map.defaults.set();
            for (k, name) in ROW_KEYS.iter().enumerate() {
                if top[k] && map.rows.iter().all(|r| r.set()[k]) {
                    return Err(at(format!(
                        "`{name}` at the top is overridden by every [[rows]] entry, so it would be \
                         ignored: remove it from the top (or from the entries that should take it)"
                    )));
                }
            }
        }
        let merged: Vec<(String, RowKeys)> = if map.rows.is_empty() {
            vec![(String::new(), map.defaults.clone())]
        } else {
            map.rows
                .iter()
                .enumerate()
                .map(|(k, r)| (format!("[[rows]] entry {}: ", k + 1), r.over(&map.defaults)))
                .collect()
        };
        let rows: Vec<RowSpec> = merged
            .iter()
            .map(|(prefix, keys)| row_spec(keys, cell).map_err(|m| at(format!("{prefix}{m}"))))
            .collect::<Result<_, _>>()?;
        let deg_per_unit = match map.joints.unit.as_str() {
            "rad" => 1f64.to_degrees(),
            "deg" => 1.0,
            u => {
                return Err(at(format!(
                    "[joints] unit = \"{u}\": write \"rad\" or \"deg\""
                )))
            }
        };
        let m_per_prismatic_unit = match map.joints.prismatic_unit.as_deref().unwrap_or("mm") {
            "m" => 1.0,
            "mm" => 1e-3,
            u => {
                return Err(at(format!(
                    "[joints] prismatic_unit = \"{u}\": write \"m\" or \"mm\" (the unit of a prismatic joint's column)"
                )))
            }
        };
        let prismatic = crate::session::joint_kinds(cell);
        let dofs = [cell.robot1.model.dof(), cell.robot2.model.dof()];
        let lists = [&map.joints.robot1, &map.joints.robot2];
        let mut joints: [Option<Vec<ColumnRef>>; 2] = [None, None];
        for r in [Robot::One, Robot::Two] {
            let k = usize::from(r.number() - 1);
            let n = r.number();
            let users: Vec<&RowSpec> = rows.iter().filter(|s| s.robots().contains(&r)).collect();
            match (lists[k], users.first()) {
                (None, Some(s)) => {
                    return Err(at(format!(
                        "a {} map needs [joints] robot{n} = [the source columns of {r}'s {} joints, chain order] \
                         (or robot{n} = \"q\", one column holding them as an array)",
                        s.kind.name(),
                        dofs[k]
                    )))
                }
                (Some(_), None) => {
                    let measured: Vec<String> = rows
                        .iter()
                        .map(|s| match s.kind.two_robot() {
                            true => format!("a {} row of both robots", s.kind.name()),
                            false => format!("a {} row of {}", s.kind.name(), s.robot),
                        })
                        .collect();
                    return Err(at(format!(
                        "[joints] robot{n} is given but no row uses {r}'s joints (the map makes {}), so it \
                         would be ignored: remove it, or add a [[rows]] entry with robot = {n}",
                        measured.join(", ")
                    )));
                }
                (Some(list), Some(_)) => {
                    let key = format!("[joints] robot{n}");
                    let what = format!(
                        "one per joint of {r} of the cell ({}), chain order",
                        cell.robot(r).model.name()
                    );
                    joints[k] = Some(list.expand(dofs[k], &key, &what).map_err(at)?);
                }
                (None, None) => {}
            }
        }
        Ok(ImportMap {
            rows,
            deg_per_unit,
            m_per_prismatic_unit,
            prismatic,
            joints,
            source_id: map.source_id,
        })
    }

    /// The kind of the map's first output row (of its only one without `[[rows]]`).
    pub fn kind(&self) -> Kind {
        self.rows.first().map_or(Kind::Coincident, |r| r.kind)
    }

    /// The kinds the map makes, each once, in the order of its rows.
    pub fn kinds(&self) -> Vec<Kind> {
        let mut out: Vec<Kind> = Vec::new();
        for r in &self.rows {
            if !out.contains(&r.kind) {
                out.push(r.kind);
            }
        }
        out
    }

    /// Session rows the map makes of each input row (1 without `[[rows]]`).
    pub fn rows_per_input_row(&self) -> usize {
        self.rows.len()
    }

    /// Converts the text `text` of the input file `input` (named in messages; its stem is the
    /// group of a `"{stem}"` map) and appends its rows to `session`: for each input row, one
    /// session row per row of the map, each numbered on from the session's row count, each
    /// with the input row's `source_id` (when the map names that column and the cell is not
    /// empty). The text is read as calib-core's CSV reader reads (separator from the header, a
    /// BOM, CRLF and quotes accepted), its columns found by the names in the map (an indexed
    /// name, `q[3]`, reads that element of the array its cell holds).
    ///
    /// Errors: [`FormatError::Input`] naming the line and column: a column of the map missing
    /// from the header, a joint angle that is not a finite number, a cell holding an array
    /// where the map names no element (or an element it does not have), a non-positive tracker
    /// σ, a joint vector the cell's model refuses (coincident rows, whose tips are computed).
    pub fn read_rows(
        &self,
        text: &str,
        input: &Path,
        cell: &Cell,
        session: &mut Session,
    ) -> Result<ImportCount, FormatError> {
        let mut reader = calib_core::csv_reader(text);
        let at = |message: String| FormatError::Input {
            path: input.to_path_buf(),
            message,
        };
        let headers = reader
            .headers()
            .map_err(|e| at(format!("line 1: the header is not valid CSV: {e}")))?
            .clone();
        let locate = |c: &ColumnRef| c.locate(&headers).map_err(&at);
        let joint_cols: Vec<Option<Vec<LocatedColumn>>> = self
            .joints
            .iter()
            .map(|cols| {
                cols.as_ref()
                    .map(|cols| cols.iter().map(locate).collect::<Result<Vec<_>, _>>())
                    .transpose()
            })
            .collect::<Result<_, _>>()?;
        let tracker_cols: Vec<Option<([LocatedColumn; 3], Option<LocatedColumn>)>> = self
            .rows
            .iter()
            .map(|s| {
                s.tracker
                    .as_ref()
                    .map(|t| -> Result<_, FormatError> {
                        let [x, y, z] = &t.xyz;
                        Ok((
                            [locate(x)?, locate(y)?, locate(z)?],
                            t.sigma.as_ref().map(locate).transpose()?,
                        ))
                    })
                    .transpose()
            })
            .collect::<Result<_, _>>()?;
        let source_col = match &self.source_id {
            Some(name) => Some(headers.iter().position(|h| h == name).ok_or_else(|| {
                at(format!(
                    "line 1: no column `{name}` (the map's source_id); the header has: {}",
                    kinematics::input::cap_echo(&headers.iter().collect::<Vec<_>>().join(","))
                ))
            })?),
            None => None,
        };
        let stem = input
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut count = ImportCount {
            rows: 0,
            skipped: 0,
        };
        for record in reader.records() {
            let record = record.map_err(|e| at(format!("not valid CSV: {e}")))?;
            let line = record.position().map_or(0, |p| p.line());
            if record.iter().all(str::is_empty) {
                continue;
            }
            let number = |c: &LocatedColumn| {
                c.value(&record)
                    .map_err(|m| at(format!("line {line}, {m}")))
            };
            let mut q: [Option<Vec<f64>>; 2] = [None, None];
            for (k, cols) in joint_cols.iter().enumerate() {
                if let Some(cols) = cols {
                    let mut v = Vec::with_capacity(cols.len());
                    for c in cols {
                        let x = number(c)?.ok_or_else(|| {
                            at(format!(
                                "line {line}, column `{}`: `{}` is not a finite joint angle",
                                self.joints[k]
                                    .as_ref()
                                    .map_or("", |j| j[v.len()].written.as_str()),
                                kinematics::input::cap_echo(record.get(c.position()).unwrap_or(""))
                            ))
                        })?;
                        let prismatic = self.prismatic[k].get(v.len()).copied().unwrap_or(false);
                        v.push(if prismatic {
                            x * self.m_per_prismatic_unit
                        } else {
                            (x * self.deg_per_unit).to_radians()
                        });
                    }
                    q[k] = Some(v);
                }
            }
            let source_id = source_col
                .and_then(|i| record.get(i))
                .map(str::trim)
                .filter(|s| !s.is_empty());
            for (spec, tracker) in self.rows.iter().zip(&tracker_cols) {
                let point = session.len() + 1;
                let joints = |r: Robot| -> Result<Vec<f64>, FormatError> {
                    q[usize::from(r.number() - 1)].clone().ok_or_else(|| {
                        at("internal: the map checks every robot's joint columns".into())
                    })
                };
                let group = spec.group.replace("{stem}", &stem);
                let kind = match spec.kind {
                    Kind::Contact => SessionKind::Contact {
                        q1: joints(Robot::One)?,
                        q2: joints(Robot::Two)?,
                        tool1: spec.tools[0],
                        tool2: spec.tools[1],
                        group,
                        distance_m: spec.distance_m,
                        sigma_m: spec.sigma_m.unwrap_or_default(),
                    },
                    Kind::Coincident => {
                        let (q1, q2) = (joints(Robot::One)?, joints(Robot::Two)?);
                        let tip = |r: Robot, q: &[f64], tool: usize| {
                            let c = cell.robot(r);
                            let t = c.flange_from_tool(tool).unwrap_or(c.flange_from_tip);
                            base_from_tip(&c.model, q, &t)
                                .map(|f| Point3::from(f.translation.vector))
                                .map_err(|e| at(format!("line {line}: {r}'s joints: {e}")))
                        };
                        let p_b1 = tip(Robot::One, &q1, spec.tools[0])?;
                        let p_b2 = tip(Robot::Two, &q2, spec.tools[1])?;
                        if spec.tools == [0, 0] {
                            session.points.push(SessionPoint {
                                point,
                                q1,
                                q2,
                                p_b1,
                                p_b2,
                            });
                            keep_source_id(session, point, source_id);
                            count.rows += 1;
                            continue;
                        }
                        SessionKind::Coincident {
                            q1,
                            q2,
                            tool1: spec.tools[0],
                            tool2: spec.tools[1],
                            p_b1,
                            p_b2,
                        }
                    }
                    Kind::Tracker => {
                        let (Some((cols, sigma_col)), Some(t)) = (tracker, &spec.tracker) else {
                            return Err(at("internal: a tracker row has its columns".into()));
                        };
                        let mut p = [0.0; 3];
                        let mut missing = false;
                        for (a, c) in cols.iter().enumerate() {
                            match number(c)? {
                                Some(x) => p[a] = x * t.m_per_unit,
                                None => missing = true,
                            }
                        }
                        let sigma = match sigma_col {
                            Some(c) => number(c)?.map(|s| s * t.m_per_unit),
                            None => spec.sigma_m,
                        };
                        let Some(sigma_m) = sigma.filter(|_| !missing) else {
                            count.skipped += 1;
                            continue;
                        };
                        if sigma_m <= 0.0 {
                            return Err(at(format!(
                                "line {line}: the tracker σ {sigma_m} m must be > 0"
                            )));
                        }
                        SessionKind::Tracker {
                            robot: spec.robot,
                            q: joints(spec.robot)?,
                            tool: spec.tools[0],
                            group,
                            p_tracker: Point3::from(p),
                            sigma_m,
                        }
                    }
                    _ => SessionKind::Plane {
                        robot: spec.robot,
                        q: joints(spec.robot)?,
                        tool: spec.tools[0],
                        group,
                        sigma_m: spec.sigma_m.unwrap_or_default(),
                    },
                };
                session
                    .observations
                    .push(SessionObservation { point, kind });
                keep_source_id(session, point, source_id);
                count.rows += 1;
            }
        }
        Ok(count)
    }
}

/// Records row `point`'s source id, if it has one.
fn keep_source_id(session: &mut Session, point: usize, id: Option<&str>) {
    if let Some(id) = id {
        session.source_ids.insert(point, id.to_string());
    }
}

/// Checks one output row's keys (the top-level keys, or a `[[rows]]` entry over them) against
/// `cell`. Errors: what is wrong, naming the key, and the fix.
fn row_spec(keys: &RowKeys, cell: &Cell) -> Result<RowSpec, String> {
    let Some(kind_name) = &keys.kind else {
        return Err(format!(
            "no `kind`: give kind = one of {} (at the top, or in each [[rows]] entry)",
            KIND_NAMES[..4].join(", ")
        ));
    };
    let kind = Kind::from_name(kind_name).ok_or_else(|| {
        format!(
            "kind = \"{kind_name}\" is not an observation kind; use one of {}",
            KIND_NAMES.join(", ")
        )
    })?;
    if kind == Kind::FaceContact {
        return Err(
            "kind = \"face_contact\" cannot be imported yet: a map has no face-normal columns \
             (n1_x … n2_z); import the rows as `contact` and add the kind and the normals, or \
             write the session with handclasp_cell::Session"
                .into(),
        );
    }
    if !IMPORTED_KINDS.contains(&kind) {
        return Err(format!(
            "kind = \"{}\" cannot be imported yet: a map has no columns for its fields; write \
             the session with handclasp_cell::Session",
            kind.name()
        ));
    }
    let name = kind.name();
    let two_robot = kind.two_robot();
    let robot = match (two_robot, keys.robot) {
        (true, None) => Robot::One,
        (true, Some(_)) => {
            return Err(format!(
                "`robot` is for tracker and plane rows; a {name} row uses both robots: remove it"
            ))
        }
        (false, Some(n)) => {
            Robot::from_number(n).ok_or_else(|| format!("robot = {n}: write 1 or 2"))?
        }
        (false, None) => {
            return Err(format!(
                "a {name} map needs `robot = 1` or `robot = 2` (the robot whose tool is measured)"
            ))
        }
    };
    let tool_of = |r: Robot, key: &str, tool: &Option<String>| -> Result<usize, String> {
        match tool {
            None => Ok(0),
            Some(t) => cell.robot(r).tool_index(t).ok_or_else(|| {
                format!(
                    "`{key}` = \"{t}\": {r} of the cell has no such tool; its tools are {} \
                     (add `{t} = [x, y, z]` in mm to [robot{}.tools] of the cell)",
                    cell.robot(r).tool_names().join(", "),
                    r.number()
                )
            }),
        }
    };
    let tools = if two_robot {
        if keys.tool.is_some() {
            return Err(format!(
                "`tool` is for tracker and plane rows; a {name} row names tool1 and tool2"
            ));
        }
        [
            tool_of(Robot::One, "tool1", &keys.tool1)?,
            tool_of(Robot::Two, "tool2", &keys.tool2)?,
        ]
    } else {
        if keys.tool1.is_some() || keys.tool2.is_some() {
            return Err(format!(
                "`tool1`/`tool2` are for coincident and contact rows; a {name} row names `tool`"
            ));
        }
        let t = tool_of(robot, "tool", &keys.tool)?;
        [t, t]
    };
    let sigma_m = match keys.sigma_mm {
        Some(s) if !(s.is_finite() && s > 0.0) => {
            return Err(format!("sigma_mm = {s}: give a σ > 0 in mm"))
        }
        s => s.map(|s| s * 1e-3),
    };
    let tracker = match (&keys.tracker, kind) {
        (Some(t), Kind::Tracker) => {
            let m_per_unit = match t.unit.as_str() {
                "m" => 1.0,
                "mm" => 1e-3,
                u => return Err(format!("[tracker] unit = \"{u}\": write \"m\" or \"mm\"")),
            };
            if t.sigma_column.is_some() && sigma_m.is_some() {
                return Err(
                    "give either sigma_mm (one σ for every row) or [tracker] sigma_column (σ per row), not both".into(),
                );
            }
            let xyz = t
                .columns
                .expand(3, "[tracker] columns", "x, y, z in the tracker frame")?;
            let sigma = t
                .sigma_column
                .as_deref()
                .map(|c| ColumnRef::parse(c, "[tracker] sigma_column"))
                .transpose()?;
            Some(TrackerColumns {
                xyz: [xyz[0].clone(), xyz[1].clone(), xyz[2].clone()],
                m_per_unit,
                sigma,
            })
        }
        (None, Kind::Tracker) => {
            return Err(
                "a tracker map needs [tracker] columns = [x, y, z] (or one array column) and unit = \"m\" | \"mm\""
                    .into(),
            )
        }
        (Some(_), _) => return Err(format!("[tracker] is for tracker rows, not {name}")),
        (None, _) => None,
    };
    if kind != Kind::Coincident
        && sigma_m.is_none()
        && tracker.as_ref().is_none_or(|t| t.sigma.is_none())
    {
        return Err(format!(
            "a {name} map needs sigma_mm (the σ of each row, mm){}",
            if kind == Kind::Tracker {
                " or [tracker] sigma_column"
            } else {
                ""
            }
        ));
    }
    if kind == Kind::Coincident && sigma_m.is_some() {
        return Err("coincident rows take the cell's [noise]; remove sigma_mm".into());
    }
    let distance_m = match (keys.distance_mm, kind) {
        (Some(d), Kind::Contact) if d.is_finite() && d >= 0.0 => Some(d * 1e-3),
        (Some(d), Kind::Contact) => {
            return Err(format!("distance_mm = {d}: give a distance ≥ 0 in mm"))
        }
        (Some(_), _) => return Err(format!("distance_mm is for contact rows, not {name}")),
        (None, _) => None,
    };
    let group = match (&keys.group, kind) {
        (Some(g), Kind::Coincident) => {
            return Err(format!(
                "group = \"{g}\": coincident rows have no group; remove it"
            ))
        }
        (Some(g), _) => g.clone(),
        (None, Kind::Coincident) => String::new(),
        (None, _) => {
            return Err(format!(
                "a {name} map needs group = \"NAME\" (or \"{{stem}}\": one group per input file)"
            ))
        }
    };
    Ok(RowSpec {
        kind,
        robot,
        group,
        tools,
        sigma_m,
        distance_m,
        tracker,
    })
}

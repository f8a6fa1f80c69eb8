//! The import mapping file: how a controller's or a dataset's CSV becomes session rows of a cell
//! (`handclasp import`). [`ImportMap::from_toml_str`] reads and checks a mapping against the
//! cell; [`ImportMap::read_rows`] converts one input file's text and appends its rows to a
//! [`Session`].
//!
//! The mapping file (TOML; documented with an example in docs/formats.md, § The import mapping file):
//! ```toml
//! kind = "contact"            # coincident | contact | tracker | plane
//! robot = 1                   # tracker and plane: the robot whose tool is measured / touches
//! group = "{stem}"            # contact/tracker/plane group; "{stem}" = the input file's stem
//! tool = "reflector"          # tracker/plane tool (default "tip"); tool1/tool2 for two-robot kinds
//! sigma_mm = 1.3              # σ of every row, mm (or [tracker] sigma_column)
//! distance_mm = 116           # contact: known distance; absent = fitted per group
//! [joints]
//! unit = "rad"                # rad | deg
//! robot1 = ["r_s_rad", "r_l_rad", "r_u_rad", "r_r_rad", "r_b_rad", "r_t_rad"]
//! robot2 = ["l_s_rad", "l_l_rad", "l_u_rad", "l_r_rad", "l_b_rad", "l_t_rad"]
//! [tracker]                   # tracker kind only
//! columns = ["leica_x_m", "leica_y_m", "leica_z_m"]
//! unit = "m"                  # m | mm (also the unit of sigma_column)
//! sigma_column = "leica_unc_m"
//! ```
//! Rows: a tracker row with an empty or NaN tracker value is skipped (and counted); an empty or
//! NaN joint angle is an error naming the file, line and column. The coincident kind's tip
//! columns are the nominal FK of the joints with the row's tools. Point numbers continue the
//! session's (1, 2, … over all inputs in order). A kind that has no mapping yet (a face contact:
//! a map has no normal columns) is refused by name.
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

/// The mapping file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MapFile {
    kind: String,
    #[serde(default)]
    robot: Option<u8>,
    #[serde(default)]
    group: Option<String>,
    #[serde(default)]
    tool: Option<String>,
    #[serde(default)]
    tool1: Option<String>,
    #[serde(default)]
    tool2: Option<String>,
    #[serde(default)]
    sigma_mm: Option<f64>,
    #[serde(default)]
    distance_mm: Option<f64>,
    joints: JointsMap,
    #[serde(default)]
    tracker: Option<TrackerMap>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct JointsMap {
    unit: String,
    #[serde(default)]
    robot1: Option<Vec<String>>,
    #[serde(default)]
    robot2: Option<Vec<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrackerMap {
    columns: [String; 3],
    unit: String,
    #[serde(default)]
    sigma_column: Option<String>,
}

/// The kinds a map can make (a two-robot kind is a contact or a coincident handclasp, a
/// one-robot kind a tracker or a plane row); another kind is refused by name when the map is
/// read, until its fields have columns in the map.
const IMPORTED_KINDS: [Kind; 4] = [Kind::Coincident, Kind::Contact, Kind::Tracker, Kind::Plane];

/// The tracker columns of a map: the three position columns, m per file unit, the σ column.
type TrackerColumns = ([String; 3], f64, Option<String>);

/// A mapping file checked against a cell: which kind of row it makes and from which columns.
#[derive(Debug, Clone)]
pub struct ImportMap {
    kind: Kind,
    robot: Robot,
    group: String,
    tools: [usize; 2],
    sigma_m: Option<f64>,
    distance_m: Option<f64>,
    deg_per_unit: f64,
    joints: [Option<Vec<String>>; 2],
    tracker: Option<TrackerColumns>,
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

impl ImportMap {
    /// Reads the mapping file text `text` (named `path` in messages) and checks it against
    /// `cell`: the kind, the robot, the tools (by name in the cell), the joint columns (one per
    /// joint of each robot the kind uses), the units, σ, the contact distance, the group and the
    /// tracker columns, each where its kind needs it and nowhere else.
    ///
    /// Errors: [`FormatError::Map`] naming the key and what would work.
    pub fn from_toml_str(text: &str, path: &Path, cell: &Cell) -> Result<ImportMap, FormatError> {
        let at = |message: String| FormatError::Map {
            path: path.to_path_buf(),
            message,
        };
        let map: MapFile = toml::from_str(text).map_err(|e| {
            at(format!(
                "{} (keys: kind, robot, group, tool, tool1, tool2, sigma_mm, distance_mm, \
                 [joints] unit, robot1, robot2, [tracker] columns, unit, sigma_column)",
                e.message().trim_end()
            ))
        })?;
        let kind = Kind::from_name(&map.kind).ok_or_else(|| {
            at(format!(
                "kind = \"{}\" is not an observation kind; use one of {}",
                map.kind,
                KIND_NAMES.join(", ")
            ))
        })?;
        if kind == Kind::FaceContact {
            return Err(at(
                "kind = \"face_contact\" cannot be imported yet: a map has no face-normal columns \
                 (n1_x … n2_z); import the rows as `contact` and add the kind and the normals, or \
                 write the session with handclasp_cell::Session"
                    .into(),
            ));
        }
        if !IMPORTED_KINDS.contains(&kind) {
            return Err(at(format!(
                "kind = \"{}\" cannot be imported yet: a map has no columns for its fields; write \
                 the session with handclasp_cell::Session",
                kind.name()
            )));
        }
        let name = kind.name();
        let two_robot = kind.two_robot();
        let robot = match (two_robot, map.robot) {
            (true, None) => Robot::One,
            (true, Some(_)) => {
                return Err(at(format!(
                "`robot` is for tracker and plane maps; a {name} row uses both robots: remove it"
            )))
            }
            (false, Some(n)) => {
                Robot::from_number(n).ok_or_else(|| at(format!("robot = {n}: write 1 or 2")))?
            }
            (false, None) => {
                return Err(at(format!(
                "a {name} map needs `robot = 1` or `robot = 2` (the robot whose tool is measured)"
            )))
            }
        };
        let tool_of = |r: Robot, key: &str, tool: &Option<String>| -> Result<usize, FormatError> {
            match tool {
                None => Ok(0),
                Some(t) => cell.robot(r).tool_index(t).ok_or_else(|| {
                    at(format!(
                        "`{key}` = \"{t}\": {r} of the cell has no such tool; its tools are {} \
                         (add `{t} = [x, y, z]` in mm to [robot{}.tools] of the cell)",
                        cell.robot(r).tool_names().join(", "),
                        r.number()
                    ))
                }),
            }
        };
        let tools = if two_robot {
            if map.tool.is_some() {
                return Err(at(format!(
                    "`tool` is for tracker and plane maps; a {name} map names tool1 and tool2"
                )));
            }
            [
                tool_of(Robot::One, "tool1", &map.tool1)?,
                tool_of(Robot::Two, "tool2", &map.tool2)?,
            ]
        } else {
            if map.tool1.is_some() || map.tool2.is_some() {
                return Err(at(format!(
                    "`tool1`/`tool2` are for coincident and contact maps; a {name} map names `tool`"
                )));
            }
            let t = tool_of(robot, "tool", &map.tool)?;
            [t, t]
        };
        let deg_per_unit = match map.joints.unit.as_str() {
            "rad" => 1f64.to_degrees(),
            "deg" => 1.0,
            u => {
                return Err(at(format!(
                    "[joints] unit = \"{u}\": write \"rad\" or \"deg\""
                )))
            }
        };
        let dofs = [cell.robot1.model.dof(), cell.robot2.model.dof()];
        let needed: Vec<Robot> = if two_robot {
            vec![Robot::One, Robot::Two]
        } else {
            vec![robot]
        };
        let joints = [map.joints.robot1.clone(), map.joints.robot2.clone()];
        for r in needed {
            let k = usize::from(r.number() - 1);
            match &joints[k] {
                None => {
                    return Err(at(format!(
                        "a {name} map needs [joints] robot{} = [the source columns of {r}'s {} joints, chain order]",
                        r.number(),
                        dofs[k]
                    )))
                }
                Some(c) if c.len() != dofs[k] => {
                    return Err(at(format!(
                        "[joints] robot{} names {} column(s) but {r} of the cell ({}) has {} joints",
                        r.number(),
                        c.len(),
                        cell.robot(r).model.name(),
                        dofs[k]
                    )))
                }
                Some(_) => {}
            }
        }
        let sigma_m = match map.sigma_mm {
            Some(s) if !(s.is_finite() && s > 0.0) => {
                return Err(at(format!("sigma_mm = {s}: give a σ > 0 in mm")))
            }
            s => s.map(|s| s * 1e-3),
        };
        let tracker = match (&map.tracker, kind) {
            (Some(t), Kind::Tracker) => {
                let m_per_unit = match t.unit.as_str() {
                    "m" => 1.0,
                    "mm" => 1e-3,
                    u => {
                        return Err(at(format!(
                            "[tracker] unit = \"{u}\": write \"m\" or \"mm\""
                        )))
                    }
                };
                if t.sigma_column.is_some() && sigma_m.is_some() {
                    return Err(at(
                        "give either sigma_mm (one σ for every row) or [tracker] sigma_column (σ per row), not both".into(),
                    ));
                }
                Some((t.columns.clone(), m_per_unit, t.sigma_column.clone()))
            }
            (None, Kind::Tracker) => {
                return Err(at(
                    "a tracker map needs [tracker] columns = [x, y, z] and unit = \"m\" | \"mm\""
                        .into(),
                ))
            }
            (Some(_), _) => return Err(at(format!("[tracker] is for tracker maps, not {name}"))),
            (None, _) => None,
        };
        if kind != Kind::Coincident
            && sigma_m.is_none()
            && tracker.as_ref().is_none_or(|t| t.2.is_none())
        {
            return Err(at(format!(
                "a {name} map needs sigma_mm (the σ of each row, mm){}",
                if kind == Kind::Tracker {
                    " or [tracker] sigma_column"
                } else {
                    ""
                }
            )));
        }
        if kind == Kind::Coincident && sigma_m.is_some() {
            return Err(at(
                "coincident rows take the cell's [noise]; remove sigma_mm".into(),
            ));
        }
        let distance_m = match (map.distance_mm, kind) {
            (Some(d), Kind::Contact) if d.is_finite() && d >= 0.0 => Some(d * 1e-3),
            (Some(d), Kind::Contact) => {
                return Err(at(format!("distance_mm = {d}: give a distance ≥ 0 in mm")))
            }
            (Some(_), _) => return Err(at(format!("distance_mm is for contact maps, not {name}"))),
            (None, _) => None,
        };
        let group = match (&map.group, kind) {
            (Some(g), Kind::Coincident) => {
                return Err(at(format!(
                    "group = \"{g}\": coincident rows have no group; remove it"
                )))
            }
            (Some(g), _) => g.clone(),
            (None, Kind::Coincident) => String::new(),
            (None, _) => {
                return Err(at(format!(
                "a {name} map needs group = \"NAME\" (or \"{{stem}}\": one group per input file)"
            )))
            }
        };
        Ok(ImportMap {
            kind,
            robot,
            group,
            tools,
            sigma_m,
            distance_m,
            deg_per_unit,
            joints,
            tracker,
        })
    }

    /// The kind of row the map makes.
    pub fn kind(&self) -> Kind {
        self.kind
    }

    /// Converts the text `text` of the input file `input` (named in messages; its stem is the
    /// group of a `"{stem}"` map) and appends its rows to `session`, numbered on from the
    /// session's row count. The text is read as calib-core's CSV reader reads (separator from the
    /// header, a BOM, CRLF and quotes accepted), its columns found by the names in the map.
    ///
    /// Errors: [`FormatError::Input`] naming the line and column: a column of the map missing
    /// from the header, a joint angle that is not a finite number, a non-positive tracker σ, a
    /// joint vector the cell's model refuses (coincident rows, whose tips are computed).
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
        let col = |name: &str| {
            headers.iter().position(|h| h == name).ok_or_else(|| {
                at(format!(
                    "line 1: no column `{name}` (named in the map); the header has: {}",
                    kinematics::input::cap_echo(&headers.iter().collect::<Vec<_>>().join(","))
                ))
            })
        };
        let mut joint_cols: [Option<Vec<(usize, &str)>>; 2] = [None, None];
        for (k, names) in self.joints.iter().enumerate() {
            let r = Robot::from_number(k as u8 + 1).unwrap_or(Robot::One);
            let used = self.kind.two_robot() || r == self.robot;
            if let (true, Some(names)) = (used, names) {
                joint_cols[k] = Some(
                    names
                        .iter()
                        .map(|n| col(n).map(|i| (i, n.as_str())))
                        .collect::<Result<_, _>>()?,
                );
            }
        }
        let tracker_cols = match &self.tracker {
            Some((c, _, s)) => Some((
                [col(&c[0])?, col(&c[1])?, col(&c[2])?],
                s.as_deref().map(col).transpose()?,
            )),
            None => None,
        };
        let group = self.group.replace(
            "{stem}",
            &input
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
        );
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
            let value = |i: usize| -> Option<f64> {
                record
                    .get(i)
                    .and_then(|c| c.parse::<f64>().ok())
                    .filter(|x| x.is_finite())
            };
            let mut q: [Option<Vec<f64>>; 2] = [None, None];
            for k in 0..2 {
                if let Some(cols) = &joint_cols[k] {
                    let mut v = Vec::with_capacity(cols.len());
                    for (i, name) in cols {
                        let x = value(*i).ok_or_else(|| {
                            at(format!(
                                "line {line}, column `{name}`: `{}` is not a finite joint angle",
                                kinematics::input::cap_echo(record.get(*i).unwrap_or(""))
                            ))
                        })?;
                        v.push((x * self.deg_per_unit).to_radians());
                    }
                    q[k] = Some(v);
                }
            }
            let point = session.len() + 1;
            let [q1, q2] = q;
            // The map's checks give every robot the kind uses its joint columns; a kind not in
            // IMPORTED_KINDS never gets here.
            let kind = if self.kind.two_robot() {
                let (Some(q1), Some(q2)) = (q1, q2) else {
                    return Err(at(
                        "internal: both robots' joints are checked by the map".into()
                    ));
                };
                if self.kind == Kind::Contact {
                    SessionKind::Contact {
                        q1,
                        q2,
                        tool1: self.tools[0],
                        tool2: self.tools[1],
                        group: group.clone(),
                        distance_m: self.distance_m,
                        sigma_m: self.sigma_m.unwrap_or_default(),
                    }
                } else {
                    let tip =
                        |r: Robot, q: &[f64], tool: usize| -> Result<Point3<f64>, FormatError> {
                            let c = cell.robot(r);
                            let t = c.flange_from_tool(tool).unwrap_or(c.flange_from_tip);
                            let f = base_from_tip(&c.model, q, &t)
                                .map_err(|e| at(format!("line {line}: {r}'s joints: {e}")))?;
                            Ok(Point3::from(f.translation.vector))
                        };
                    let p_b1 = tip(Robot::One, &q1, self.tools[0])?;
                    let p_b2 = tip(Robot::Two, &q2, self.tools[1])?;
                    if self.tools == [0, 0] {
                        session.points.push(SessionPoint {
                            point,
                            q1,
                            q2,
                            p_b1,
                            p_b2,
                        });
                        count.rows += 1;
                        continue;
                    }
                    SessionKind::Coincident {
                        q1,
                        q2,
                        tool1: self.tools[0],
                        tool2: self.tools[1],
                        p_b1,
                        p_b2,
                    }
                }
            } else {
                let q = if self.robot == Robot::One { q1 } else { q2 };
                let Some(q) = q else {
                    return Err(at(
                        "internal: the measured robot's joints are checked by the map".into(),
                    ));
                };
                if let (Some((cols, sigma_col)), Some((_, m_per_unit, _))) =
                    (&tracker_cols, &self.tracker)
                {
                    let p: Vec<Option<f64>> = cols.iter().map(|&i| value(i)).collect();
                    let sigma = match sigma_col {
                        Some(i) => value(*i).map(|s| s * m_per_unit),
                        None => self.sigma_m,
                    };
                    let (Some(x), Some(y), Some(z), Some(sigma_m)) = (p[0], p[1], p[2], sigma)
                    else {
                        count.skipped += 1;
                        continue;
                    };
                    if sigma_m <= 0.0 {
                        return Err(at(format!(
                            "line {line}: the tracker σ {sigma_m} m must be > 0"
                        )));
                    }
                    SessionKind::Tracker {
                        robot: self.robot,
                        q,
                        tool: self.tools[0],
                        group: group.clone(),
                        p_tracker: Point3::new(x, y, z) * *m_per_unit,
                        sigma_m,
                    }
                } else {
                    SessionKind::Plane {
                        robot: self.robot,
                        q,
                        tool: self.tools[0],
                        group: group.clone(),
                        sigma_m: self.sigma_m.unwrap_or_default(),
                    }
                }
            };
            session
                .observations
                .push(SessionObservation { point, kind });
            count.rows += 1;
        }
        Ok(count)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{joints, tool_point};

    /// The shipped floor–wall cell with a `reflector` tool on robot 2.
    fn cell() -> Cell {
        let mut cell = Cell::default_floor_wall();
        cell.robot2.tools.push(calib_core::whole_cell::Tool {
            name: "reflector".into(),
            flange_from_tip: nalgebra::Vector3::new(0.04, 0.0, 0.2),
        });
        cell
    }

    fn map(text: &str) -> Result<ImportMap, FormatError> {
        ImportMap::from_toml_str(text, Path::new("m.toml"), &cell())
    }

    const JOINTS1: &str = "robot1 = [\"a1\", \"a2\", \"a3\", \"a4\", \"a5\", \"a6\", \"a7\"]";
    const JOINTS2: &str = "robot2 = [\"b1\", \"b2\", \"b3\", \"b4\", \"b5\", \"b6\"]";

    /// Every error names the map file and the key, and says what would work.
    #[test]
    fn map_errors_name_the_key_and_the_fix() {
        let e = map("kind = \"laser\"\n[joints]\nunit = \"deg\"\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "m.toml: kind = \"laser\" is not an observation kind; use one of coincident, contact, tracker, plane, face_contact"
        );
        let e = map("kind = \"face_contact\"\n[joints]\nunit = \"deg\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cannot be imported yet") && e.contains("n1_x"),
            "{e}"
        );
        let tracker = format!("kind = \"tracker\"\nrobot = 2\ngroup = \"g\"\nsigma_mm = 0.1\n[joints]\nunit = \"rad\"\n{JOINTS2}\n");
        let e = map(&tracker).unwrap_err().to_string();
        assert!(e.contains("a tracker map needs [tracker] columns"), "{e}");
        let e = map(&tracker.replace("robot = 2", "robot = 2\ntool = \"laser\""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("`tool` = \"laser\"") && e.contains("tip, reflector"),
            "{e}"
        );
        let e = map(&format!("kind = \"contact\"\ngroup = \"c\"\nsigma_mm = 0.1\n[joints]\nunit = \"deg\"\n{JOINTS1}\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("a contact map needs [joints] robot2"), "{e}");
        let e = map("kind = \"coincident\"\nunit = \"deg\"\n[joints]\nunit = \"deg\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("unknown field `unit`") && e.contains("(keys: kind"),
            "{e}"
        );
    }

    /// A tracker map: joints in rad, positions in m with a σ column; a row without a tracker
    /// value is skipped and counted, a `{stem}` group is the file's stem, point numbers go on
    /// from the session's rows, and the session reads back through the CSV.
    #[test]
    fn tracker_rows_are_converted_and_empty_ones_skipped() {
        let cell = cell();
        let m = map(&format!(
            "kind = \"tracker\"\nrobot = 2\ntool = \"reflector\"\ngroup = \"{{stem}}\"\n\
             [joints]\nunit = \"rad\"\n{JOINTS2}\n\
             [tracker]\ncolumns = [\"x\", \"y\", \"z\"]\nunit = \"m\"\nsigma_column = \"s\"\n"
        ))
        .unwrap();
        assert_eq!(m.kind(), Kind::Tracker);
        let q: Vec<Vec<f64>> = (0..3).map(|k| joints(&cell.robot2, k)).collect();
        let mut text = String::from("b1,b2,b3,b4,b5,b6,x,y,z,s\n");
        for (k, q) in q.iter().enumerate() {
            let joints: Vec<String> = q.iter().map(|v| format!("{v:.12}")).collect();
            let xyz = if k == 1 {
                ",,".to_string()
            } else {
                format!("1.5,{k}.25,-0.5")
            };
            text += &format!("{},{xyz},0.000006\n", joints.join(","));
        }
        let mut session = Session::default();
        session.observations.push(SessionObservation {
            point: 1,
            kind: SessionKind::Plane {
                robot: Robot::One,
                q: joints(&cell.robot1, 0),
                tool: 0,
                group: "table".into(),
                sigma_m: 1e-4,
            },
        });
        let count = m
            .read_rows(&text, Path::new("dir/leica_right.csv"), &cell, &mut session)
            .unwrap();
        assert_eq!(
            count,
            ImportCount {
                rows: 2,
                skipped: 1
            }
        );
        let SessionObservation { point, kind } = &session.observations[2];
        assert_eq!(*point, 3);
        let SessionKind::Tracker {
            robot,
            q: q_read,
            tool,
            group,
            p_tracker,
            sigma_m,
        } = kind
        else {
            panic!("a tracker row: {kind:?}");
        };
        assert_eq!(
            (*robot, *tool, group.as_str()),
            (Robot::Two, 1, "leica_right")
        );
        assert!((p_tracker - Point3::new(1.5, 2.25, -0.5)).amax() < 1e-15);
        assert!((sigma_m - 6e-6).abs() < 1e-18);
        assert!(q_read.iter().zip(&q[2]).all(|(a, b)| (a - b).abs() < 1e-11));
        let back = Session::parse_csv(&session.csv_text(&cell), Path::new("s.csv"), &cell).unwrap();
        assert_eq!(back.kind_counts(), [0, 0, 2, 1, 0]);
        // A joint angle that is not a number is named by line and column.
        let bad = text.replacen(&format!("{:.12}", q[0][0]), "abc", 1);
        let e = m
            .read_rows(&bad, Path::new("in.csv"), &cell, &mut Session::default())
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "in.csv: line 2, column `b1`: `abc` is not a finite joint angle"
        );
    }

    /// A coincident map: joints in degrees, the tips computed by the nominal models with the
    /// row's tools; default tools give handclasp points.
    #[test]
    fn coincident_rows_get_their_tips_from_the_nominal_models() {
        let cell = cell();
        let m = map(&format!(
            "kind = \"coincident\"\n[joints]\nunit = \"deg\"\n{JOINTS1}\n{JOINTS2}\n"
        ))
        .unwrap();
        let (q1, q2) = (joints(&cell.robot1, 4), joints(&cell.robot2, 5));
        let deg =
            |q: &[f64]| -> Vec<String> { q.iter().map(|v| v.to_degrees().to_string()).collect() };
        let text = format!(
            "a1,a2,a3,a4,a5,a6,a7,b1,b2,b3,b4,b5,b6\n{},{}\n",
            deg(&q1).join(","),
            deg(&q2).join(",")
        );
        let mut session = Session::default();
        let count = m
            .read_rows(&text, Path::new("c.csv"), &cell, &mut session)
            .unwrap();
        assert_eq!(
            count,
            ImportCount {
                rows: 1,
                skipped: 0
            }
        );
        let p = &session.points[0];
        assert!((p.p_b1 - tool_point(&cell.robot1, &p.q1, 0)).norm() < 1e-12);
        assert!((p.p_b2 - tool_point(&cell.robot2, &p.q2, 0)).norm() < 1e-12);
        assert!((p.q1[3] - q1[3]).abs() < 1e-12);
    }
}

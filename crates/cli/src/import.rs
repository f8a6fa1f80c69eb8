//! `handclasp import --cell CELL --map MAP.toml --input FILE.csv [--input …] --out SESSION.csv
//! [--json]`: converts a controller's or a dataset's CSV into a session CSV of `CELL`
//! (`sim_cell::Session`), as the mapping file says.
//!
//! The mapping file (TOML; documented with an example in the main README):
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
//! columns are the nominal FK of the joints with the row's tools. Point numbers run 1, 2, … over
//! all inputs in order. The session is written with the cell's tool names and read back through
//! `Session::parse_csv` before the command succeeds.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use calib_core::Robot;
use kinematics::base_from_tip;
use nalgebra::Point3;
use serde::Deserialize;
use sim_cell::{Cell, Session, SessionKind, SessionObservation, SessionPoint};

/// Arguments of `handclasp import`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Cell TOML: its robots' joint counts and tools (`tip`, `[robotN.tools]`) check the mapping,
    /// and its nominal models give the coincident kind's tip columns.
    #[arg(long)]
    pub cell: PathBuf,
    /// Mapping file (TOML): which source columns are each robot's joints and in which unit, the
    /// kind, robot, group, tool, σ and tracker columns (see the README).
    #[arg(long)]
    pub map: PathBuf,
    /// Source CSV file(s); repeat the flag for several (rows are numbered over all of them).
    #[arg(long, required = true)]
    pub input: Vec<PathBuf>,
    /// Session CSV to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Print one JSON summary instead of the text lines.
    #[arg(long)]
    pub json: bool,
}

/// The mapping file.
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

/// What one input gave (JSON `input`, `rows`, `skipped`).
#[derive(Debug, serde::Serialize)]
struct FileCount {
    /// The input file.
    #[serde(rename = "input")]
    path: PathBuf,
    /// Rows imported from it.
    rows: usize,
    /// Rows skipped (no tracker value: empty or NaN).
    skipped: usize,
}

/// What `handclasp import` prints: each input's counts, the kind, the session written and its
/// rows. `--json` serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this report
/// was before it had types).
#[derive(Debug, serde::Serialize)]
struct ImportReport {
    /// Each input, in order.
    files: Vec<FileCount>,
    /// The observation kind imported (the mapping's `kind`).
    kind: &'static str,
    /// The session CSV written (`--out`).
    out: PathBuf,
    /// Rows in the written session.
    rows: usize,
}

/// The text report.
fn render_text(r: &ImportReport) -> String {
    let mut s = String::new();
    for c in &r.files {
        let skipped = if c.skipped > 0 {
            format!(", {} skipped (no tracker value: empty or NaN)", c.skipped)
        } else {
            String::new()
        };
        s += &format!(
            "{}: {} {} row(s){skipped}\n",
            c.path.display(),
            c.rows,
            r.kind
        );
    }
    s += &format!("wrote {} rows to {}\n", r.rows, r.out.display());
    s
}

/// Runs `handclasp import`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cell = Cell::from_toml_file(&args.cell)?;
    let text = std::fs::read_to_string(&args.map)
        .with_context(|| format!("--map {}", args.map.display()))?;
    let map: MapFile = toml::from_str(&text).map_err(|e| {
        anyhow::anyhow!(
            "--map {}: {} (keys: kind, robot, group, tool, tool1, tool2, sigma_mm, distance_mm, \
             [joints] unit, robot1, robot2, [tracker] columns, unit, sigma_column)",
            args.map.display(),
            e.message().trim_end()
        )
    })?;
    let plan = Plan::new(&map, &cell, &args.map)?;
    let mut session = Session::default();
    let mut counts = Vec::new();
    for input in &args.input {
        counts.push(plan.read(input, &cell, &mut session)?);
    }
    if session.is_empty() {
        bail!("no row imported from {} file(s)", args.input.len());
    }
    session.write_csv(&args.out, &cell)?;
    // The written file must read back as a session of this cell (tips, tools, groups).
    Session::read_csv(&args.out, &cell).context("reading back the written session")?;
    let report = ImportReport {
        files: counts,
        kind: plan.kind,
        out: args.out.clone(),
        rows: session.len(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

/// The validated mapping.
struct Plan {
    kind: &'static str,
    robot: Robot,
    group: String,
    tools: [usize; 2],
    sigma_m: Option<f64>,
    distance_m: Option<f64>,
    deg_per_unit: f64,
    joints: [Option<Vec<String>>; 2],
    tracker: Option<([String; 3], f64, Option<String>)>,
}

impl Plan {
    fn new(map: &MapFile, cell: &Cell, path: &Path) -> anyhow::Result<Plan> {
        let at = |msg: String| anyhow::anyhow!("--map {}: {msg}", path.display());
        let kind = sim_cell::session::KIND_NAMES
            .into_iter()
            .find(|k| *k == map.kind)
            .ok_or_else(|| {
                at(format!(
                    "kind = \"{}\" is not an observation kind; use one of {}",
                    map.kind,
                    sim_cell::session::KIND_NAMES.join(", ")
                ))
            })?;
        if kind == "face_contact" {
            return Err(at(
                "kind = \"face_contact\" cannot be imported yet: a map has no face-normal columns \
                 (n1_x … n2_z); import the rows as `contact` and add the kind and the normals, or \
                 write the session with sim_cell::Session"
                    .into(),
            ));
        }
        let two_robot = matches!(kind, "coincident" | "contact");
        let robot = match (two_robot, map.robot) {
            (true, None) => Robot::One,
            (true, Some(_)) => {
                return Err(at(format!(
                "`robot` is for tracker and plane maps; a {kind} row uses both robots: remove it"
            )))
            }
            (false, Some(n)) => {
                Robot::from_number(n).ok_or_else(|| at(format!("robot = {n}: write 1 or 2")))?
            }
            (false, None) => {
                return Err(at(format!(
                "a {kind} map needs `robot = 1` or `robot = 2` (the robot whose tool is measured)"
            )))
            }
        };
        let tool_of = |r: Robot, key: &str, name: &Option<String>| -> anyhow::Result<usize> {
            match name {
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
                    "`tool` is for tracker and plane maps; a {kind} map names tool1 and tool2"
                )));
            }
            [
                tool_of(Robot::One, "tool1", &map.tool1)?,
                tool_of(Robot::Two, "tool2", &map.tool2)?,
            ]
        } else {
            if map.tool1.is_some() || map.tool2.is_some() {
                return Err(at(format!(
                    "`tool1`/`tool2` are for coincident and contact maps; a {kind} map names `tool`"
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
                        "a {kind} map needs [joints] robot{} = [the source columns of {r}'s {} joints, chain order]",
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
            (Some(t), "tracker") => {
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
            (None, "tracker") => {
                return Err(at(
                    "a tracker map needs [tracker] columns = [x, y, z] and unit = \"m\" | \"mm\""
                        .into(),
                ))
            }
            (Some(_), _) => return Err(at(format!("[tracker] is for tracker maps, not {kind}"))),
            (None, _) => None,
        };
        if kind != "coincident"
            && sigma_m.is_none()
            && tracker.as_ref().is_none_or(|t| t.2.is_none())
        {
            return Err(at(format!(
                "a {kind} map needs sigma_mm (the σ of each row, mm){}",
                if kind == "tracker" {
                    " or [tracker] sigma_column"
                } else {
                    ""
                }
            )));
        }
        if kind == "coincident" && sigma_m.is_some() {
            return Err(at(
                "coincident rows take the cell's [noise]; remove sigma_mm".into(),
            ));
        }
        let distance_m = match (map.distance_mm, kind) {
            (Some(d), "contact") if d.is_finite() && d >= 0.0 => Some(d * 1e-3),
            (Some(d), "contact") => {
                return Err(at(format!("distance_mm = {d}: give a distance ≥ 0 in mm")))
            }
            (Some(_), _) => return Err(at(format!("distance_mm is for contact maps, not {kind}"))),
            (None, _) => None,
        };
        let group = match (&map.group, kind) {
            (Some(g), "coincident") => {
                return Err(at(format!(
                    "group = \"{g}\": coincident rows have no group; remove it"
                )))
            }
            (Some(g), _) => g.clone(),
            (None, "coincident") => String::new(),
            (None, _) => {
                return Err(at(format!(
                "a {kind} map needs group = \"NAME\" (or \"{{stem}}\": one group per input file)"
            )))
            }
        };
        Ok(Plan {
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

    /// Reads one input file and appends its rows.
    fn read(&self, input: &Path, cell: &Cell, session: &mut Session) -> anyhow::Result<FileCount> {
        let text = std::fs::read_to_string(input)
            .with_context(|| format!("--input {}", input.display()))?;
        let mut reader = calib_core::csv_reader(&text);
        let at = |msg: String| anyhow::anyhow!("--input {}: {msg}", input.display());
        let headers = reader
            .headers()
            .map_err(|e| at(format!("line 1: the header is not valid CSV: {e}")))?
            .clone();
        let col = |name: &str| {
            headers.iter().position(|h| h == name).ok_or_else(|| {
                at(format!(
                    "line 1: no column `{name}` (named in the map); the header has: {}",
                    headers.iter().collect::<Vec<_>>().join(",")
                ))
            })
        };
        let mut joint_cols: [Option<Vec<(usize, &str)>>; 2] = [None, None];
        for (k, names) in self.joints.iter().enumerate() {
            let r = Robot::from_number(k as u8 + 1).unwrap_or(Robot::One);
            let used = matches!(self.kind, "coincident" | "contact") || r == self.robot;
            if let (true, Some(names)) = (used, names) {
                joint_cols[k] = Some(
                    names
                        .iter()
                        .map(|n| col(n).map(|i| (i, n.as_str())))
                        .collect::<anyhow::Result<_>>()?,
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
        let (mut rows, mut skipped) = (0, 0);
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
                                record.get(*i).unwrap_or("")
                            ))
                        })?;
                        v.push((x * self.deg_per_unit).to_radians());
                    }
                    q[k] = Some(v);
                }
            }
            let point = session.len() + 1;
            let [q1, q2] = q;
            let kind = match self.kind {
                "coincident" | "contact" => {
                    let (Some(q1), Some(q2)) = (q1, q2) else {
                        bail!("internal: both robots' joints are checked by the map");
                    };
                    if self.kind == "contact" {
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
                            |r: Robot, q: &[f64], tool: usize| -> anyhow::Result<Point3<f64>> {
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
                            rows += 1;
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
                }
                _ => {
                    let q = if self.robot == Robot::One { q1 } else { q2 };
                    let Some(q) = q else {
                        bail!("internal: the measured robot's joints are checked by the map");
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
                            skipped += 1;
                            continue;
                        };
                        if sigma_m <= 0.0 {
                            bail!(at(format!(
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
                }
            };
            session
                .observations
                .push(SessionObservation { point, kind });
            rows += 1;
        }
        Ok(FileCount {
            path: input.to_path_buf(),
            rows,
            skipped,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_and_json_of_an_import() {
        let r = ImportReport {
            files: vec![
                FileCount {
                    path: "a.csv".into(),
                    rows: 212,
                    skipped: 4,
                },
                FileCount {
                    path: "b.csv".into(),
                    rows: 10,
                    skipped: 0,
                },
            ],
            kind: "tracker",
            out: "s.csv".into(),
            rows: 222,
        };
        assert_eq!(
            render_text(&r),
            "a.csv: 212 tracker row(s), 4 skipped (no tracker value: empty or NaN)\n\
             b.csv: 10 tracker row(s)\n\
             wrote 222 rows to s.csv\n"
        );
        assert_eq!(
            serde_json::to_string(&r).unwrap(),
            r#"{"files":[{"input":"a.csv","rows":212,"skipped":4},{"input":"b.csv","rows":10,"skipped":0}],"kind":"tracker","out":"s.csv","rows":222}"#
        );
    }
}

//! The `handclasp diagnose` engine: what the nominal models get wrong in a measured session.
//!
//! Steps (issue #5): (1) baseline fit of `b1_from_b2` with the nominal models, the residual RMS the
//! cell's stated noise predicts at these very joint configurations (seeded Monte Carlo), a χ² test
//! and the residual structure (correlations with joints, position and reach); (2) the catalogue
//! of candidate error parameters with identifiability per family; (3) forward selection
//! (`calib_core::identify::forward_select`); (4) the gain; (5) export of corrected URDFs and cell.
//!
//! The maths lives in `calib_core::identify`; this module wires it to the kinematic error model
//! (`kinematics::true_base_from_tip`, `kinematics::tip_error_jacobian`) and to files. Inside, SI
//! units; the report speaks mm and degrees (field names carry the unit).

use std::path::{Path, PathBuf};

use calib_core::identify::{
    self, IdentStatus, IdentifyError, Robot, SelectionOptions, TipEval, TipModel,
};
use kinematics::{Axis, ErrorParam, KinematicErrors, RobotModel};
use nalgebra::{Isometry3, Matrix3xX, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// Errors of the diagnosis: bad files or inputs. Each names the file/row/field and the fix.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The cell file is invalid.
    #[error("cell file {path}: {message}")]
    Cell {
        /// The file.
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// The session file is invalid.
    #[error("session file {path}: {message}")]
    Session {
        /// The file.
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// A simulated session could not be generated.
    #[error("simulation: {0}")]
    Simulation(String),
    /// The identification failed on the input.
    #[error("identification: {0}")]
    Identify(#[from] IdentifyError),
}

/// One robot of the cell, as the diagnosis needs it.
#[derive(Debug, Clone)]
pub struct RobotSetup {
    /// The nominal model.
    pub model: RobotModel,
    /// URDF file it was read from.
    pub urdf_path: PathBuf,
    /// Nominal tip offset in the tool0 frame, m.
    pub flange_from_tip: Vector3<f64>,
    /// Gravity in the robot's base frame, m/s² (floor: (0, 0, −9.81)).
    pub g_base: Vector3<f64>,
}

/// The cell as the diagnosis reads it (a lenient reader of the sim-cell TOML: unknown keys are
/// ignored here, since sim-cell's own reader validates them).
#[derive(Debug, Clone)]
pub struct DiagnoseCell {
    /// The cell file.
    pub path: PathBuf,
    /// Robot 1.
    pub robot1: RobotSetup,
    /// Robot 2.
    pub robot2: RobotSetup,
    /// Nominal `b1_from_b2` from the file (m, rad).
    pub b1_from_b2: Isometry3<f64>,
    /// σ of the tips' alignment error per axis, m (`[noise] alignment_mm`).
    pub sigma_alignment_m: f64,
}

const G: f64 = 9.81;

fn cell_err(path: &Path, message: impl Into<String>) -> DiagnoseError {
    DiagnoseError::Cell {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

fn vec3(path: &Path, v: Option<&toml::Value>, key: &str) -> Result<Vector3<f64>, DiagnoseError> {
    let arr = v.and_then(|v| v.as_array()).ok_or_else(|| {
        cell_err(
            path,
            format!("`{key}` is missing or not an array of 3 numbers"),
        )
    })?;
    let nums: Vec<f64> = arr
        .iter()
        .filter_map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
        .collect();
    if nums.len() != 3 || arr.len() != 3 {
        return Err(cell_err(
            path,
            format!("`{key}` must be an array of 3 numbers"),
        ));
    }
    Ok(Vector3::new(nums[0], nums[1], nums[2]))
}

pub use kinematics::{rotation_from_zyz, zyz_from_rotation};

fn gravity_for_mount(
    path: &Path,
    key: &str,
    mount: Option<&toml::Value>,
) -> Result<Vector3<f64>, DiagnoseError> {
    let down = Vector3::new(0.0, 0.0, -G);
    match mount {
        None => Ok(down),
        Some(toml::Value::String(s)) => match s.as_str() {
            "floor" => Ok(down),
            "ceiling" => Ok(-down),
            // Wall: base z horizontal; the roll is not given, take base x pointing down (the
            // usual wall mount). Compliance about horizontal axes depends on it.
            "wall" => Ok(Vector3::new(-G, 0.0, 0.0)),
            other => Err(cell_err(
                path,
                format!("`{key}.mount` = \"{other}\" is unknown: use floor, ceiling, wall or {{ tilt_deg = [rx, ry] }}"),
            )),
        },
        Some(toml::Value::Table(t)) => {
            let tilt = t.get("tilt_deg").and_then(|v| v.as_array()).ok_or_else(|| {
                cell_err(path, format!("`{key}.mount` table needs tilt_deg = [rx, ry] (degrees)"))
            })?;
            let a: Vec<f64> = tilt
                .iter()
                .filter_map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .collect();
            if a.len() != 2 {
                return Err(cell_err(path, format!("`{key}.mount.tilt_deg` must be [rx, ry] in degrees")));
            }
            let level_from_base = Rotation3::from_axis_angle(&Vector3::x_axis(), a[0].to_radians())
                * Rotation3::from_axis_angle(&Vector3::y_axis(), a[1].to_radians());
            Ok(level_from_base.inverse() * down)
        }
        Some(_) => Err(cell_err(path, format!("`{key}.mount` must be a string or a tilt table"))),
    }
}

/// Reads the cell TOML (lengths mm, angles degrees, paths relative to the file).
pub fn load_cell(path: &Path) -> Result<DiagnoseCell, DiagnoseError> {
    let text = std::fs::read_to_string(path).map_err(|e| DiagnoseError::Io {
        path: path.to_path_buf(),
        message: format!("cannot read the cell file: {e}"),
    })?;
    let value: toml::Value = text
        .parse()
        .map_err(|e| cell_err(path, format!("not valid TOML: {e}")))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let robot = |key: &str| -> Result<RobotSetup, DiagnoseError> {
        let t = value
            .get(key)
            .ok_or_else(|| cell_err(path, format!("missing table [{key}]")))?;
        let urdf = t.get("urdf").and_then(|v| v.as_str()).ok_or_else(|| {
            cell_err(
                path,
                format!("`{key}.urdf` is missing (path of the URDF, relative to the cell file)"),
            )
        })?;
        let urdf_path = dir.join(urdf);
        let model = RobotModel::from_urdf_file(&urdf_path, "tool0")
            .map_err(|e| cell_err(path, format!("`{key}.urdf` = {}: {e}", urdf_path.display())))?;
        let tip_mm = vec3(path, t.get("tip_mm"), &format!("{key}.tip_mm"))?;
        Ok(RobotSetup {
            model,
            urdf_path,
            flange_from_tip: tip_mm / 1000.0,
            g_base: gravity_for_mount(path, key, t.get("mount"))?,
        })
    };
    let robot1 = robot("robot1")?;
    let robot2 = robot("robot2")?;
    let b = value.get("b1_from_b2");
    let xyz = vec3(path, b.and_then(|b| b.get("xyz_mm")), "b1_from_b2.xyz_mm")? / 1000.0;
    let zyz = vec3(path, b.and_then(|b| b.get("zyz_deg")), "b1_from_b2.zyz_deg")?;
    let rot = rotation_from_zyz([
        zyz[0].to_radians(),
        zyz[1].to_radians(),
        zyz[2].to_radians(),
    ]);
    // σ per axis; an anisotropic [σx, σy, σz] is summarised by its RMS. Missing: 0.3 mm (the
    // sim-cell default), stated in the report.
    let sigma_value = value.get("noise").and_then(|n| n.get("alignment_mm"));
    let num = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
    let sigma_mm = match sigma_value {
        None => 0.3,
        Some(toml::Value::Array(a)) => {
            let v: Vec<f64> = a.iter().filter_map(num).collect();
            if v.is_empty() || v.len() != a.len() {
                return Err(cell_err(
                    path,
                    "`noise.alignment_mm` must be a number or an array of numbers (mm)",
                ));
            }
            (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
        }
        Some(v) => {
            num(v).ok_or_else(|| cell_err(path, "`noise.alignment_mm` must be a number (mm)"))?
        }
    };
    if !(sigma_mm > 0.0 && sigma_mm.is_finite()) {
        return Err(cell_err(
            path,
            format!("`noise.alignment_mm` = {sigma_mm}: must be a positive σ in mm"),
        ));
    }
    Ok(DiagnoseCell {
        path: path.to_path_buf(),
        robot1,
        robot2,
        b1_from_b2: Isometry3::from_parts(
            Translation3::from(xyz),
            UnitQuaternion::from_rotation_matrix(&rot),
        ),
        sigma_alignment_m: sigma_mm / 1000.0,
    })
}

/// A handclasp session (joint angles rad, nominal tips m).
#[derive(Debug, Clone)]
pub struct HandclaspSession {
    /// Robot 1's reported joints per point, rad.
    pub q1: Vec<Vec<f64>>,
    /// Robot 2's reported joints per point, rad.
    pub q2: Vec<Vec<f64>>,
    /// Robot 1's reported tips in b1, m.
    pub p1_b1: Vec<Point3<f64>>,
    /// Robot 2's reported tips in b2, m.
    pub p2_b2: Vec<Point3<f64>>,
    /// 1-based data rows (for messages).
    pub rows: Vec<usize>,
}

/// Reads a session CSV (`r1_q1_deg…, r2_q1_deg…, r1_x_mm…r2_z_mm`) and checks it against the
/// cell: joint counts, units (radians written as degrees, metres as millimetres) and the nominal
/// tip columns against FK of the joint columns with the cell's tip offsets.
pub fn load_session(path: &Path, cell: &DiagnoseCell) -> Result<HandclaspSession, DiagnoseError> {
    let serr = |message: String| DiagnoseError::Session {
        path: path.to_path_buf(),
        message,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| DiagnoseError::Io {
            path: path.to_path_buf(),
            message: format!("cannot read the session: {e}"),
        })?;
    let headers = rdr
        .headers()
        .map_err(|e| serr(format!("bad header: {e}")))?
        .clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let count = |r: u8| {
        (1..=20)
            .take_while(|k| col(&format!("r{r}_q{k}_deg")).is_some())
            .count()
    };
    let (n1, n2) = (count(1), count(2));
    let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
    if n1 != d1 || n2 != d2 {
        return Err(serr(format!(
            "the session has {n1} joint column(s) for robot 1 and {n2} for robot 2 (r1_q1_deg…, r2_q1_deg…), \
             but the cell's URDFs have {d1} and {d2} joints: use the session recorded with this cell, or the cell of this session"
        )));
    }
    let tip_cols: Vec<usize> = [
        "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
    ]
    .iter()
    .map(|c| col(c).ok_or_else(|| serr(format!("missing column `{c}` (tip positions in mm)"))))
    .collect::<Result<_, _>>()?;
    let mut s = HandclaspSession {
        q1: vec![],
        q2: vec![],
        p1_b1: vec![],
        p2_b2: vec![],
        rows: vec![],
    };
    for (i, rec) in rdr.records().enumerate() {
        let row = i + 1;
        let rec = rec.map_err(|e| serr(format!("data row {row}: {e}")))?;
        let num = |c: usize, name: &str| -> Result<f64, DiagnoseError> {
            let v: f64 = rec.get(c).unwrap_or("").parse().map_err(|_| {
                serr(format!(
                    "data row {row}, column `{name}`: `{}` is not a number",
                    rec.get(c).unwrap_or("")
                ))
            })?;
            if !v.is_finite() {
                return Err(serr(format!("data row {row}, column `{name}`: not finite")));
            }
            Ok(v)
        };
        let q = |r: u8, d: usize| -> Result<Vec<f64>, DiagnoseError> {
            (1..=d)
                .map(|k| {
                    let name = format!("r{r}_q{k}_deg");
                    num(col(&name).unwrap_or(0), &name).map(f64::to_radians)
                })
                .collect()
        };
        s.q1.push(q(1, d1)?);
        s.q2.push(q(2, d2)?);
        let t: Vec<f64> = tip_cols
            .iter()
            .map(|&c| num(c, &headers[c]).map(|v| v / 1000.0))
            .collect::<Result<_, _>>()?;
        s.p1_b1.push(Point3::new(t[0], t[1], t[2]));
        s.p2_b2.push(Point3::new(t[3], t[4], t[5]));
        s.rows.push(row);
    }
    let n = s.rows.len();
    let needed = identify::min_points(1);
    if n < needed {
        return Err(serr(format!(
            "{n} handclasp point(s): too few to identify anything; fitting b1_from_b2 and one error \
             parameter with a meaningful test needs at least {needed} points (40 recommended)"
        )));
    }
    // Units: joint columns that are all within ±π "degrees" are almost surely radians.
    let max_q =
        s.q1.iter()
            .chain(&s.q2)
            .flatten()
            .fold(0.0f64, |a, v| a.max(v.abs()));
    if max_q.to_degrees() <= std::f64::consts::PI + 1e-9 {
        return Err(serr(format!(
            "every joint angle is within ±{:.3} — these look like radians, but the columns are *_deg: convert them to degrees",
            max_q.to_degrees()
        )));
    }
    let max_p = s
        .p1_b1
        .iter()
        .chain(&s.p2_b2)
        .fold(0.0f64, |a, p| a.max(p.coords.amax()));
    if max_p < 0.01 {
        return Err(serr(format!(
            "every tip coordinate is below {:.4} mm — these look like metres, but the columns are *_mm: convert them to millimetres",
            max_p * 1000.0
        )));
    }
    // Cross-check the reported nominal tips with FK (0.2 mm allows for the rounding of the file).
    const FK_TOL_M: f64 = 2e-4;
    for (r, setup, qs, ps) in [
        (1, &cell.robot1, &s.q1, &s.p1_b1),
        (2, &cell.robot2, &s.q2, &s.p2_b2),
    ] {
        for (k, (q, p)) in qs.iter().zip(ps.iter()).enumerate() {
            setup
                .model
                .check_q(q)
                .map_err(|e| serr(format!("data row {}, robot {r}: {e}", s.rows[k])))?;
            let fk = kinematics::base_from_tip(&setup.model, q, &setup.flange_from_tip)
                .map_err(|e| serr(format!("data row {}, robot {r}: {e}", s.rows[k])))?;
            let d = (fk.translation.vector - p.coords).norm();
            if d > FK_TOL_M {
                return Err(serr(format!(
                    "data row {}: robot {r}'s tip columns differ by {:.3} mm from FK of its joint columns with \
                     the cell's tip offset ({} mm): wrong cell, wrong tip_mm, or tips not in mm / not in the robot's base frame",
                    s.rows[k],
                    d * 1000.0,
                    fmt3(&(setup.flange_from_tip * 1000.0))
                )));
            }
        }
    }
    Ok(s)
}

fn fmt3(v: &Vector3<f64>) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
}

/// Kind of a candidate effect (the six kinds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// A joint's zero offset.
    JointOffset,
    /// A joint origin's translation along x, y or z (parent frame).
    LinkLength,
    /// The tip offset error, tool0 frame.
    TipOffset,
    /// A base tilt about its x or y axis.
    MountTilt,
    /// A joint's deflection under gravity.
    Compliance,
    /// A joint's gear-ratio error.
    JointScale,
}

impl EffectKind {
    /// The kind's name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Self::JointOffset => "joint_offset",
            Self::LinkLength => "link_length",
            Self::TipOffset => "tip_offset",
            Self::MountTilt => "mount_tilt",
            Self::Compliance => "compliance",
            Self::JointScale => "joint_scale",
        }
    }
    /// Output unit.
    pub fn unit(self) -> &'static str {
        match self {
            Self::JointOffset | Self::MountTilt => "deg",
            Self::LinkLength | Self::TipOffset => "mm",
            Self::JointScale => "ratio",
            Self::Compliance => "deg/(kN·m)",
        }
    }
    /// Factor from SI (rad, m, ratio, rad/(N·m)) to the output unit.
    pub fn to_output(self) -> f64 {
        match self {
            Self::JointOffset | Self::MountTilt => 180.0 / std::f64::consts::PI,
            Self::LinkLength | Self::TipOffset => 1000.0,
            Self::JointScale => 1.0,
            Self::Compliance => 180.0 / std::f64::consts::PI * 1000.0,
        }
    }
}

/// One candidate of the catalogue.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    /// Kind.
    pub kind: EffectKind,
    /// Robot, 1 or 2.
    pub robot: u8,
    /// 0-based joint, where it applies.
    pub joint: Option<usize>,
    /// Axis, where it applies.
    pub axis: Option<Axis>,
    /// The kinematic-error parameter.
    pub param: ErrorParam,
}

impl Candidate {
    /// Readable name, e.g. `robot 2 joint_offset joint 3` or `robot 1 link_length joint 2 x`.
    pub fn label(&self) -> String {
        let mut s = format!("robot {} {}", self.robot, self.kind.name());
        if let Some(j) = self.joint {
            s += &format!(" joint {}", j + 1);
        }
        if let Some(a) = self.axis {
            s += &format!(" {}", axis_name(a));
        }
        s
    }
}

fn axis_name(a: Axis) -> &'static str {
    match a {
        Axis::X => "x",
        Axis::Y => "y",
        Axis::Z => "z",
    }
}

/// The full catalogue for two robots with `dof1`, `dof2` joints.
pub fn catalogue(dof1: usize, dof2: usize) -> Vec<Candidate> {
    let mut c = Vec::new();
    for (robot, dof) in [(1u8, dof1), (2u8, dof2)] {
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::JointOffset,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::JointOffset { joint: j },
            });
        }
        for j in 0..dof {
            for a in [Axis::X, Axis::Y, Axis::Z] {
                c.push(Candidate {
                    kind: EffectKind::LinkLength,
                    robot,
                    joint: Some(j),
                    axis: Some(a),
                    param: ErrorParam::OriginXyz { joint: j, axis: a },
                });
            }
        }
        for a in [Axis::X, Axis::Y, Axis::Z] {
            c.push(Candidate {
                kind: EffectKind::TipOffset,
                robot,
                joint: None,
                axis: Some(a),
                param: ErrorParam::Tip { axis: a },
            });
        }
        for a in [Axis::X, Axis::Y] {
            c.push(Candidate {
                kind: EffectKind::MountTilt,
                robot,
                joint: None,
                axis: Some(a),
                param: ErrorParam::MountRpy { axis: a },
            });
        }
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::Compliance,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::Compliance { joint: j },
            });
        }
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::JointScale,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::JointScale { joint: j },
            });
        }
    }
    c
}

/// The identification problem of a session: tips from the kinematic-error model.
pub struct SessionModel<'a> {
    cell: &'a DiagnoseCell,
    q1: &'a [Vec<f64>],
    q2: &'a [Vec<f64>],
    candidates: &'a [Candidate],
}

impl<'a> SessionModel<'a> {
    /// Wraps a cell, joint vectors (rad) and a catalogue.
    pub fn new(
        cell: &'a DiagnoseCell,
        q1: &'a [Vec<f64>],
        q2: &'a [Vec<f64>],
        candidates: &'a [Candidate],
    ) -> Self {
        Self {
            cell,
            q1,
            q2,
            candidates,
        }
    }

    /// The two robots' error sets for parameters `params = values`.
    pub fn errors(&self, params: &[usize], values: &[f64]) -> (KinematicErrors, KinematicErrors) {
        let mut e1 = KinematicErrors::zero(self.cell.robot1.model.dof());
        let mut e2 = KinematicErrors::zero(self.cell.robot2.model.dof());
        for (&p, &v) in params.iter().zip(values) {
            let c = &self.candidates[p];
            if c.robot == 1 {
                e1.set(c.param, v);
            } else {
                e2.set(c.param, v);
            }
        }
        (e1, e2)
    }
}

impl TipModel for SessionModel<'_> {
    fn n_points(&self) -> usize {
        self.q1.len()
    }
    fn n_params(&self) -> usize {
        self.candidates.len()
    }
    fn param_robot(&self, j: usize) -> Robot {
        if self.candidates[j].robot == 1 {
            Robot::One
        } else {
            Robot::Two
        }
    }
    fn param_scale(&self, j: usize) -> f64 {
        match self.candidates[j].kind {
            // 1 mrad, 1 mm, 1e-3, and 1e-6 rad/(N·m) (≈ 0.06 deg/(kN·m)).
            EffectKind::Compliance => 1e-6,
            _ => 1e-3,
        }
    }
    fn eval(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<TipEval, IdentifyError> {
        let (e1, e2) = self.errors(params, values);
        let merr = |e: kinematics::KinematicsError| IdentifyError::Model {
            point,
            message: e.to_string(),
        };
        let (r1, r2) = (&self.cell.robot1, &self.cell.robot2);
        let p1 = kinematics::true_base_from_tip(
            &r1.model,
            &e1,
            &self.q1[point],
            &r1.flange_from_tip,
            &r1.g_base,
        )
        .map_err(merr)?;
        let p2 = kinematics::true_base_from_tip(
            &r2.model,
            &e2,
            &self.q2[point],
            &r2.flange_from_tip,
            &r2.g_base,
        )
        .map_err(merr)?;
        let mut jacobian = Matrix3xX::zeros(jacobian_params.len());
        if !jacobian_params.is_empty() {
            for (robot, setup, errors, q) in [
                (1u8, r1, &e1, &self.q1[point]),
                (2u8, r2, &e2, &self.q2[point]),
            ] {
                let cols: Vec<usize> = (0..jacobian_params.len())
                    .filter(|&c| self.candidates[jacobian_params[c]].robot == robot)
                    .collect();
                if cols.is_empty() {
                    continue;
                }
                let eps: Vec<ErrorParam> = cols
                    .iter()
                    .map(|&c| self.candidates[jacobian_params[c]].param)
                    .collect();
                let j = kinematics::tip_error_jacobian(
                    &setup.model,
                    errors,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                    &eps,
                )
                .map_err(merr)?;
                for (k, &c) in cols.iter().enumerate() {
                    jacobian.set_column(c, &j.column(k));
                }
            }
        }
        Ok(TipEval {
            p1_b1: Point3::from(p1.translation.vector),
            p2_b2: Point3::from(p2.translation.vector),
            jacobian,
        })
    }
}

/// Options of the diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Seed of the Monte Carlo simulations (default 1).
    pub seed: u64,
    /// Monte Carlo trials for the predicted residual distributions (default 400).
    pub trials: usize,
    /// Selection settings (α = 0.05 family-wise per step, 10 folds).
    pub selection: SelectionOptions,
    /// Truth of `b1_from_b2` (e.g. from a CMM), for e_tran/e_rot before and after.
    pub truth: Option<Isometry3<f64>>,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            trials: 400,
            selection: SelectionOptions::default(),
            truth: None,
        }
    }
}

/// `b1_from_b2` in file units.
#[derive(Debug, Clone, Serialize)]
pub struct PoseReport {
    /// Translation, mm.
    pub xyz_mm: [f64; 3],
    /// ZYZ angles, degrees, `R = Rz(φ)·Ry(θ)·Rz(ψ)`.
    pub zyz_deg: [f64; 3],
}

impl PoseReport {
    /// From an isometry; the ZYZ branch nearest `reference` (rad), e.g. the cell's nominal angles.
    pub fn from_isometry(x: &Isometry3<f64>, reference: [f64; 3]) -> Self {
        let t = x.translation.vector * 1000.0;
        let z = kinematics::zyz_nearest(&x.rotation.to_rotation_matrix(), reference);
        Self {
            xyz_mm: [t.x, t.y, t.z],
            zyz_deg: [z[0].to_degrees(), z[1].to_degrees(), z[2].to_degrees()],
        }
    }
}

/// One named effect.
#[derive(Debug, Clone, Serialize)]
pub struct EffectReport {
    /// Kind.
    pub kind: EffectKind,
    /// Robot, 1 or 2.
    pub robot: u8,
    /// 1-based joint, or null.
    pub joint: Option<usize>,
    /// "x" | "y" | "z", or null.
    pub axis: Option<&'static str>,
    /// Estimate, true minus nominal, in `unit`.
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
    /// 95% interval (t quantile), in `unit`.
    pub ci95: [f64; 2],
    /// Candidates the data cannot tell apart from this one (labels), including itself.
    pub confounded_with: Vec<String>,
    /// F-test p-value at its selection step.
    pub p_value: f64,
}

/// A significant correlation of the residuals.
#[derive(Debug, Clone, Serialize)]
pub struct CorrelationReport {
    /// Residual component: "x", "y", "z" (b1 axes) or "norm".
    pub residual: String,
    /// Against what: "r1_q3", "r2_q1", "x", "y", "z" (robot 1 tip in b1), "reach1", "reach2".
    pub against: String,
    /// Pearson r.
    pub r: f64,
    /// Bonferroni-adjusted p-value.
    pub p_adjusted: f64,
}

/// The smallest effect of one candidate this session can detect (80% power, first step).
#[derive(Debug, Clone, Serialize)]
pub struct DetectableReport {
    /// Candidate label, e.g. `robot 2 joint_offset joint 3`.
    pub label: String,
    /// Smallest detectable |value|, in `unit` (cell σ).
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
}

/// Identifiability of one family.
#[derive(Debug, Clone, Serialize)]
pub struct FamilyReport {
    /// Robot.
    pub robot: u8,
    /// Kind.
    pub kind: EffectKind,
    /// Candidates in the family.
    pub size: usize,
    /// Rank after projecting out the base frames.
    pub rank: usize,
    /// Condition number of the unit-scaled projected columns (null when rank-deficient).
    pub condition: Option<f64>,
    /// Singular values (dimensionless, unit-scaled columns).
    pub singular_values: Vec<f64>,
    /// Members confounded with a base frame (absorbed by `b1_from_b2`).
    pub confounded_with_base: Vec<String>,
    /// Members that do not move the tip at these configurations.
    pub no_effect: Vec<String>,
}

/// The diagnosis report (`--json` prints it).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnoseReport {
    /// Named effects.
    pub effects: Vec<EffectReport>,
    /// Residual RMS (3-D per point) of the nominal fit, mm.
    pub rms_before_mm: f64,
    /// Residual RMS of the extended model, mm.
    pub rms_after_mm: f64,
    /// K-fold held-out residual RMS, nominal model, mm.
    pub heldout_rms_before_mm: f64,
    /// K-fold held-out residual RMS, extended model, mm.
    pub heldout_rms_after_mm: f64,
    /// Calibrated `b1_from_b2` (extended model).
    pub b1_from_b2: PoseReport,
    /// `b1_from_b2` of the nominal fit.
    pub b1_from_b2_before: PoseReport,
    /// Points.
    pub n_points: usize,
    /// The cell's alignment σ, mm.
    pub sigma_cell_mm: f64,
    /// σ estimated from the nominal fit, mm.
    pub sigma_hat_before_mm: f64,
    /// σ estimated from the extended fit, mm.
    pub sigma_hat_after_mm: f64,
    /// Predicted RMS under the cell's noise (MC median), mm.
    pub predicted_rms_mm: f64,
    /// MC 5–95% band of the predicted RMS, mm.
    pub predicted_rms_band_mm: [f64; 2],
    /// Fraction of MC trials whose RMS is below the measured one.
    pub measured_rms_percentile: f64,
    /// χ² test of RSS/σ² with 3n−6 dof: upper-tail p-value.
    pub chi2_p_value: f64,
    /// Significant residual correlations (Bonferroni 5%).
    pub correlations: Vec<CorrelationReport>,
    /// Identifiability per family.
    pub families: Vec<FamilyReport>,
    /// Smallest detectable |value| per identifiable candidate under this session's design and
    /// the cell's σ.
    pub min_detectable: Vec<DetectableReport>,
    /// Groups of mutually confounded candidates (labels).
    pub confounded_groups: Vec<Vec<String>>,
    /// Predicted 1-σ translation error of `b1_from_b2`, before / after, mm.
    pub predicted_e_tran_mm: [f64; 2],
    /// Predicted 1-σ rotation error, before / after, degrees.
    pub predicted_e_rot_deg: [f64; 2],
    /// e_tran against the truth, before / after, mm (when truth given).
    pub truth_e_tran_mm: Option<[f64; 2]>,
    /// Geodesic rotation error against the truth, before / after, degrees (when truth given).
    pub truth_e_rot_deg: Option<[f64; 2]>,
    /// Re-simulation with the extended model: MC median of the nominal-fit RMS it predicts, mm
    /// (to compare with `rms_before_mm`), and the measured RMS's percentile in it.
    pub resimulated_rms_before_mm: f64,
    /// Percentile of the measured nominal RMS in the re-simulated distribution.
    pub resimulated_percentile: f64,
    /// Selection steps in words.
    pub steps: Vec<String>,
    /// Whether the final LM fit converged.
    pub converged: bool,
}

/// Seeded generator of Monte Carlo trial `index` (independent of thread count).
pub fn trial_rng(seed: u64, index: u64) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// MC distribution of the rigid-fit residual RMS (m) for data `p1 = x·p2 + d + ε`, `ε ~ N(0, σ²I)`.
fn simulate_rms(
    p2: &[Point3<f64>],
    x: &Isometry3<f64>,
    d: &[Vector3<f64>],
    sigma: f64,
    seed: u64,
    trials: usize,
) -> Vec<f64> {
    let normal = Normal::new(0.0, sigma).expect("sigma checked positive");
    let mut out: Vec<f64> = (0..trials)
        .map(|t| {
            let mut rng = trial_rng(seed, t as u64);
            let p1: Vec<Point3<f64>> = p2
                .iter()
                .zip(d)
                .map(|(p, di)| {
                    x * p
                        + di
                        + Vector3::new(
                            normal.sample(&mut rng),
                            normal.sample(&mut rng),
                            normal.sample(&mut rng),
                        )
                })
                .collect();
            let fit = identify::kabsch(&p1, p2).unwrap_or(*x);
            let rss: f64 = p1
                .iter()
                .zip(p2)
                .map(|(a, b)| (a - fit * b).norm_squared())
                .sum();
            (rss / p2.len() as f64).sqrt()
        })
        .collect();
    out.sort_by(f64::total_cmp);
    out
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn percentile(sorted: &[f64], v: f64) -> f64 {
    sorted.iter().filter(|&&s| s < v).count() as f64 / sorted.len().max(1) as f64
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

fn correlations(session: &HandclaspSession, residuals: &[Vector3<f64>]) -> Vec<CorrelationReport> {
    let n = residuals.len();
    let mut targets: Vec<(String, Vec<f64>)> = Vec::new();
    for (r, qs) in [(1, &session.q1), (2, &session.q2)] {
        for k in 0..qs.first().map_or(0, |q| q.len()) {
            targets.push((
                format!("r{r}_q{}", k + 1),
                qs.iter().map(|q| q[k]).collect(),
            ));
        }
    }
    for (a, name) in ["x", "y", "z"].iter().enumerate() {
        targets.push((
            name.to_string(),
            session.p1_b1.iter().map(|p| p[a]).collect(),
        ));
    }
    targets.push((
        "reach1".into(),
        session.p1_b1.iter().map(|p| p.coords.norm()).collect(),
    ));
    targets.push((
        "reach2".into(),
        session.p2_b2.iter().map(|p| p.coords.norm()).collect(),
    ));
    let comps: Vec<(String, Vec<f64>)> = vec![
        ("x".into(), residuals.iter().map(|r| r.x).collect()),
        ("y".into(), residuals.iter().map(|r| r.y).collect()),
        ("z".into(), residuals.iter().map(|r| r.z).collect()),
        ("norm".into(), residuals.iter().map(|r| r.norm()).collect()),
    ];
    let tests = (targets.len() * comps.len()) as f64;
    let mut out = Vec::new();
    for (cn, cv) in &comps {
        for (tn, tv) in &targets {
            let r = pearson(cv, tv);
            let stat = r * ((n as f64 - 2.0) / (1.0 - r * r).max(1e-300)).sqrt();
            let p = identify::t_two_sided_p(stat, n.saturating_sub(2));
            let p_adj = (p * tests).min(1.0);
            if p_adj < 0.05 {
                out.push(CorrelationReport {
                    residual: cn.clone(),
                    against: tn.clone(),
                    r,
                    p_adjusted: p_adj,
                });
            }
        }
    }
    out
}

/// Runs the full diagnosis of a session.
pub fn diagnose(
    cell: &DiagnoseCell,
    session: &HandclaspSession,
    options: &DiagnoseOptions,
) -> Result<DiagnoseReport, DiagnoseError> {
    let cands = catalogue(cell.robot1.model.dof(), cell.robot2.model.dof());
    let model = SessionModel::new(cell, &session.q1, &session.q2, &cands);
    let all: Vec<usize> = (0..cands.len()).collect();
    let sel = identify::forward_select(&model, &all, &options.selection)?;
    let base = &sel.baseline;
    let fit = &sel.fit;
    let n = session.rows.len();
    let sigma = cell.sigma_alignment_m;
    let reference = zyz_from_rotation(&cell.b1_from_b2.rotation.to_rotation_matrix());
    // 1. Baseline against the cell's noise.
    let p2_nom: Vec<Point3<f64>> = (0..n)
        .map(|i| model.eval(i, &[], &[], &[]).map(|e| e.p2_b2))
        .collect::<Result<_, _>>()?;
    let zeros = vec![Vector3::zeros(); n];
    let mc = simulate_rms(
        &p2_nom,
        &base.b1_from_b2,
        &zeros,
        sigma,
        options.seed,
        options.trials,
    );
    let chi2_p = identify::chi2_sf(base.rss / (sigma * sigma), base.dof);
    // 4. Re-simulation with the extended model: the deterministic discrepancy the nominal fit sees.
    let mut d = Vec::with_capacity(n);
    for i in 0..n {
        let nom = model.eval(i, &[], &[], &[])?;
        let ext = model.eval(i, &fit.params, &fit.values, &[])?;
        d.push((nom.p1_b1 - ext.p1_b1) - fit.b1_from_b2.rotation * (nom.p2_b2 - ext.p2_b2));
    }
    let remc = simulate_rms(
        &p2_nom,
        &fit.b1_from_b2,
        &d,
        sigma,
        options.seed ^ 0x5eed,
        options.trials,
    );
    // Effects.
    let step_of = |p: usize| sel.steps.iter().find(|s| s.param == p && s.accepted);
    let effects = fit
        .params
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let c = &cands[p];
            let f = c.kind.to_output();
            let (lo, hi) = fit.interval(k, 0.95);
            EffectReport {
                kind: c.kind,
                robot: c.robot,
                joint: c.joint.map(|j| j + 1),
                axis: c.axis.map(axis_name),
                value: fit.values[k] * f,
                unit: c.kind.unit(),
                ci95: [lo * f, hi * f],
                confounded_with: sel
                    .groups
                    .get(k)
                    .map(|g| g.iter().map(|&m| cands[m].label()).collect())
                    .unwrap_or_default(),
                p_value: step_of(p).map_or(f64::NAN, |s| s.p_value),
            }
        })
        .collect();
    // Families.
    let id = &sel.identifiability;
    let mut families = Vec::new();
    for robot in [1u8, 2] {
        for kind in [
            EffectKind::JointOffset,
            EffectKind::LinkLength,
            EffectKind::TipOffset,
            EffectKind::MountTilt,
            EffectKind::Compliance,
            EffectKind::JointScale,
        ] {
            let members: Vec<usize> = (0..cands.len())
                .filter(|&m| cands[m].robot == robot && cands[m].kind == kind)
                .collect();
            let fam = id.family(&members);
            let with = |st: IdentStatus| {
                members
                    .iter()
                    .filter(|&&m| id.params[m].status == st)
                    .map(|&m| cands[m].label())
                    .collect()
            };
            families.push(FamilyReport {
                robot,
                kind,
                size: fam.size,
                rank: fam.rank,
                condition: fam.condition.is_finite().then_some(fam.condition),
                singular_values: fam.singular_values,
                confounded_with_base: with(IdentStatus::ConfoundedWithBase),
                no_effect: with(IdentStatus::NoEffect),
            });
        }
    }
    let (truth_e_tran_mm, truth_e_rot_deg) = match &options.truth {
        Some(t) => {
            let et =
                |x: &Isometry3<f64>| (x.translation.vector - t.translation.vector).norm() * 1000.0;
            let er = |x: &Isometry3<f64>| x.rotation.angle_to(&t.rotation).to_degrees();
            (
                Some([et(&base.b1_from_b2), et(&fit.b1_from_b2)]),
                Some([er(&base.b1_from_b2), er(&fit.b1_from_b2)]),
            )
        }
        None => (None, None),
    };
    let steps = sel
        .steps
        .iter()
        .map(|s| {
            format!(
                "{}: {} (F = {:.2}, p = {:.2e} vs α/m = {:.2e} over {} screened; held-out RMS {:.4} → {:.4} mm; BIC {:.1} → {:.1})",
                cands[s.param].label(),
                if s.accepted { "accepted" } else { "rejected" },
                s.f_stat, s.p_value, s.threshold, s.screened,
                s.heldout_rms_before * 1000.0, s.heldout_rms_after * 1000.0, s.bic_before, s.bic_after
            )
        })
        .collect();
    Ok(DiagnoseReport {
        effects,
        rms_before_mm: base.rms() * 1000.0,
        rms_after_mm: fit.rms() * 1000.0,
        heldout_rms_before_mm: sel.heldout_rms_before * 1000.0,
        heldout_rms_after_mm: sel.heldout_rms_after * 1000.0,
        b1_from_b2: PoseReport::from_isometry(&fit.b1_from_b2, reference),
        b1_from_b2_before: PoseReport::from_isometry(&base.b1_from_b2, reference),
        n_points: n,
        sigma_cell_mm: sigma * 1000.0,
        sigma_hat_before_mm: base.sigma_hat * 1000.0,
        sigma_hat_after_mm: fit.sigma_hat * 1000.0,
        predicted_rms_mm: quantile(&mc, 0.5) * 1000.0,
        predicted_rms_band_mm: [quantile(&mc, 0.05) * 1000.0, quantile(&mc, 0.95) * 1000.0],
        measured_rms_percentile: percentile(&mc, base.rms()),
        chi2_p_value: chi2_p,
        correlations: correlations(session, &base.residuals),
        families,
        min_detectable: identify::min_detectable(id, options.selection.alpha, sigma)
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(m, v)| DetectableReport {
                label: cands[m].label(),
                value: v * cands[m].kind.to_output(),
                unit: cands[m].kind.unit(),
            })
            .collect(),
        confounded_groups: id
            .groups
            .iter()
            .map(|g| g.iter().map(|&m| cands[m].label()).collect())
            .collect(),
        predicted_e_tran_mm: [
            base.predicted_translation_error() * 1000.0,
            fit.predicted_translation_error() * 1000.0,
        ],
        predicted_e_rot_deg: [
            base.predicted_rotation_error().to_degrees(),
            fit.predicted_rotation_error().to_degrees(),
        ],
        truth_e_tran_mm,
        truth_e_rot_deg,
        resimulated_rms_before_mm: quantile(&remc, 0.5) * 1000.0,
        resimulated_percentile: percentile(&remc, base.rms()),
        steps,
        converged: fit.converged,
    })
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> DiagnoseError {
    DiagnoseError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Applies the report's `link_length` and `joint_offset` effects of `robot` to a URDF's text:
/// adds the value to the joint's `<origin xyz>` component and writes the offset as
/// `<calibration rising="rad"/>` (true angle = reported angle + rising). Other elements are kept
/// byte for byte.
pub fn correct_urdf_text(
    xml: &str,
    model: &RobotModel,
    robot: u8,
    effects: &[EffectReport],
) -> Result<String, String> {
    let mut out = xml.to_string();
    for e in effects.iter().filter(|e| e.robot == robot) {
        let Some(joint) = e.joint else { continue };
        let name = &model
            .joints()
            .get(joint - 1)
            .ok_or_else(|| format!("joint {joint} is not in the model"))?
            .name;
        let open = out
            .find(&format!("name=\"{name}\""))
            .and_then(|i| out[..i].rfind("<joint").map(|s| (s, i)))
            .ok_or_else(|| format!("joint `{name}` not found in the URDF text"))?
            .0;
        let close = out[open..]
            .find("</joint>")
            .map(|i| open + i)
            .ok_or_else(|| format!("joint `{name}` has no </joint>"))?;
        match e.kind {
            EffectKind::LinkLength => {
                let block = &out[open..close];
                let origin = block
                    .find("<origin")
                    .ok_or_else(|| format!("joint `{name}` has no <origin>"))?;
                let xyz_at = block[origin..]
                    .find("xyz=\"")
                    .map(|i| open + origin + i + 5);
                let add = e.value / 1000.0;
                let a = match e.axis {
                    Some("x") => 0,
                    Some("y") => 1,
                    _ => 2,
                };
                match xyz_at {
                    Some(start) => {
                        let end = start + out[start..].find('"').ok_or("unterminated xyz")?;
                        let mut v: Vec<f64> = out[start..end]
                            .split_whitespace()
                            .map(|t| {
                                t.parse::<f64>()
                                    .map_err(|_| format!("joint `{name}`: bad xyz `{t}`"))
                            })
                            .collect::<Result<_, _>>()?;
                        if v.len() != 3 {
                            return Err(format!("joint `{name}`: xyz needs 3 numbers"));
                        }
                        v[a] += add;
                        out.replace_range(start..end, &format!("{} {} {}", v[0], v[1], v[2]));
                    }
                    None => {
                        let mut v = [0.0; 3];
                        v[a] = add;
                        let at = open + origin + "<origin".len();
                        out.insert_str(at, &format!(" xyz=\"{} {} {}\"", v[0], v[1], v[2]));
                    }
                }
            }
            EffectKind::JointOffset => {
                let rad = e.value.to_radians();
                out.insert_str(close, &format!("  <calibration rising=\"{rad}\"/>\n  "));
            }
            _ => {}
        }
    }
    Ok(out)
}

/// Writes the extended model to `dir`: `robot1_corrected.urdf`, `robot2_corrected.urdf` (joint
/// origins and `<calibration rising>` offsets), `cell_corrected.toml` (calibrated `b1_from_b2`,
/// corrected tip offsets, URDF paths to the corrected files) and `effects.json` (every effect,
/// including compliance and joint scale, which URDF cannot express). Returns the files written.
pub fn export_corrected(
    cell: &DiagnoseCell,
    report: &DiagnoseReport,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| io_err(dir, format!("cannot create the export folder: {e}")))?;
    let mut written = Vec::new();
    let text = std::fs::read_to_string(&cell.path).map_err(|e| io_err(&cell.path, e))?;
    let mut value: toml::Value = text
        .parse()
        .map_err(|e| cell_err(&cell.path, format!("not valid TOML: {e}")))?;
    for (robot, setup, key) in [(1u8, &cell.robot1, "robot1"), (2u8, &cell.robot2, "robot2")] {
        let xml =
            std::fs::read_to_string(&setup.urdf_path).map_err(|e| io_err(&setup.urdf_path, e))?;
        let corrected = correct_urdf_text(&xml, &setup.model, robot, &report.effects)
            .map_err(|m| io_err(&setup.urdf_path, m))?;
        let file = format!("robot{robot}_corrected.urdf");
        let path = dir.join(&file);
        std::fs::write(&path, corrected).map_err(|e| io_err(&path, e))?;
        written.push(path);
        let mut tip = setup.flange_from_tip * 1000.0;
        for e in report
            .effects
            .iter()
            .filter(|e| e.robot == robot && e.kind == EffectKind::TipOffset)
        {
            let a = match e.axis {
                Some("x") => 0,
                Some("y") => 1,
                _ => 2,
            };
            tip[a] += e.value;
        }
        if let Some(t) = value.get_mut(key).and_then(|t| t.as_table_mut()) {
            t.insert("urdf".into(), toml::Value::String(file));
            t.insert(
                "tip_mm".into(),
                toml::Value::Array(tip.iter().map(|v| toml::Value::Float(*v)).collect()),
            );
        }
    }
    if let Some(root) = value.as_table_mut() {
        let mut b = toml::map::Map::new();
        let arr =
            |v: [f64; 3]| toml::Value::Array(v.iter().map(|x| toml::Value::Float(*x)).collect());
        b.insert("xyz_mm".into(), arr(report.b1_from_b2.xyz_mm));
        b.insert("zyz_deg".into(), arr(report.b1_from_b2.zyz_deg));
        root.insert("b1_from_b2".into(), toml::Value::Table(b));
    }
    let cell_path = dir.join("cell_corrected.toml");
    let cell_text = toml::to_string(&value).map_err(|e| io_err(&cell_path, e))?;
    std::fs::write(&cell_path, cell_text).map_err(|e| io_err(&cell_path, e))?;
    written.push(cell_path);
    let eff_path = dir.join("effects.json");
    let eff = serde_json::to_string_pretty(&report.effects).map_err(|e| io_err(&eff_path, e))?;
    std::fs::write(&eff_path, eff).map_err(|e| io_err(&eff_path, e))?;
    written.push(eff_path);
    Ok(written)
}

/// Readable text of a report.
pub fn render_text(r: &DiagnoseReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "handclasp diagnose: {} points, cell σ = {:.3} mm",
        r.n_points, r.sigma_cell_mm
    );
    let _ = writeln!(s, "\n1. Baseline (nominal models)");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} mm; predicted under the cell's noise {:.3} mm (5–95%: {:.3}–{:.3}); measured at MC percentile {:.1}%",
        r.rms_before_mm, r.predicted_rms_mm, r.predicted_rms_band_mm[0], r.predicted_rms_band_mm[1], 100.0 * r.measured_rms_percentile
    );
    let _ = writeln!(
        s,
        "   χ² test of RSS/σ²: p = {:.3e} ({}); σ̂ = {:.3} mm per axis",
        r.chi2_p_value,
        if r.chi2_p_value < 0.05 {
            "the nominal model does NOT explain the data"
        } else {
            "consistent with noise"
        },
        r.sigma_hat_before_mm
    );
    if r.correlations.is_empty() {
        let _ = writeln!(s, "   no significant residual correlation (Bonferroni 5%)");
    }
    for c in &r.correlations {
        let _ = writeln!(
            s,
            "   residual {} correlates with {}: r = {:+.2} (adjusted p = {:.1e})",
            c.residual, c.against, c.r, c.p_adjusted
        );
    }
    let _ = writeln!(
        s,
        "\n2. Identifiability from these handclasps (rank / size, condition)"
    );
    for f in &r.families {
        let cond = f.condition.map_or("∞".to_string(), |c| format!("{c:.1}"));
        let _ = write!(
            s,
            "   robot {} {:<13} rank {}/{} cond {}",
            f.robot,
            f.kind.name(),
            f.rank,
            f.size,
            cond
        );
        if !f.confounded_with_base.is_empty() {
            let _ = write!(
                s,
                "; confounded with the base frame: {}",
                f.confounded_with_base.join(", ")
            );
        }
        if !f.no_effect.is_empty() {
            let _ = write!(s, "; no effect here: {}", f.no_effect.join(", "));
        }
        let _ = writeln!(s);
    }
    for g in &r.confounded_groups {
        let _ = writeln!(s, "   indistinguishable: {}", g.join(" ≡ "));
    }
    let _ = writeln!(s, "\n3. Model selection");
    for st in &r.steps {
        let _ = writeln!(s, "   {st}");
    }
    if r.effects.is_empty() {
        let _ = writeln!(s, "   no significant effect: noise alone explains the data");
    }
    for e in &r.effects {
        let _ = writeln!(
            s,
            "   {} robot {}{}{}: {:+.4} {} (95%: {:+.4} … {:+.4}){}",
            e.kind.name(),
            e.robot,
            e.joint.map_or(String::new(), |j| format!(" joint {j}")),
            e.axis.map_or(String::new(), |a| format!(" axis {a}")),
            e.value,
            e.unit,
            e.ci95[0],
            e.ci95[1],
            if e.confounded_with.len() > 1 {
                format!(" [or any of: {}]", e.confounded_with.join(", "))
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s, "\n4. Gain");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} → {:.3} mm; held-out (K-fold) {:.3} → {:.3} mm",
        r.rms_before_mm, r.rms_after_mm, r.heldout_rms_before_mm, r.heldout_rms_after_mm
    );
    let _ = writeln!(
        s,
        "   predicted b1_from_b2 accuracy: {:.3} → {:.3} mm, {:.4} → {:.4} deg (1σ)",
        r.predicted_e_tran_mm[0],
        r.predicted_e_tran_mm[1],
        r.predicted_e_rot_deg[0],
        r.predicted_e_rot_deg[1]
    );
    if let (Some(t), Some(a)) = (r.truth_e_tran_mm, r.truth_e_rot_deg) {
        let _ = writeln!(
            s,
            "   against the truth: e_tran {:.3} → {:.3} mm, rotation {:.4} → {:.4} deg",
            t[0], t[1], a[0], a[1]
        );
    }
    let _ = writeln!(
        s,
        "   re-simulated with the extended model: nominal-fit RMS {:.3} mm predicted vs {:.3} measured (percentile {:.1}%)",
        r.resimulated_rms_before_mm, r.rms_before_mm, 100.0 * r.resimulated_percentile
    );
    let _ = writeln!(
        s,
        "   b1_from_b2: xyz {:.3?} mm, zyz {:.4?} deg",
        r.b1_from_b2.xyz_mm, r.b1_from_b2.zyz_deg
    );
    s
}

/// Solves the reported joints that put the TRUE robot's tip (nominal base frame) at `p_base`:
/// nominal IK, then Newton steps on the true model with the nominal position Jacobian.
fn solve_true(
    setup: &RobotSetup,
    errors: &KinematicErrors,
    p_base: &Point3<f64>,
) -> Option<Vec<f64>> {
    let opts = kinematics::IkOptions::default();
    let sol =
        kinematics::ik_tip_position(&setup.model, p_base, &setup.flange_from_tip, &opts).ok()?;
    if !sol.reachable() {
        return None;
    }
    let mut q = sol.q;
    for _ in 0..30 {
        let tip = kinematics::true_base_from_tip(
            &setup.model,
            errors,
            &q,
            &setup.flange_from_tip,
            &setup.g_base,
        )
        .ok()?;
        let e = p_base.coords - tip.translation.vector;
        if e.norm() < 1e-11 {
            return setup.model.check_q(&q).ok().map(|_| q);
        }
        let j = kinematics::tip_position_jacobian(&setup.model, &q, &setup.flange_from_tip).ok()?;
        let dq = j.svd(true, true).solve(&e, 1e-12).ok()?;
        for (qi, d) in q.iter_mut().zip(dq.iter()) {
            *qi += d;
        }
    }
    None
}

/// Simulates a session at `n` random teach points around the midpoint of the two bases (a box
/// of ±`half_size_m`), with hidden kinematic errors `errors1`, `errors2`, the cell's `b1_from_b2`
/// as the truth and the cell's alignment noise: robot 1's true tip is put on the point, robot 2's
/// true tip on the point plus noise; the controllers report the joints and the nominal tips.
/// Seeded (point attempt `k` draws from `trial_rng(seed, k)`). For tests and benches.
pub fn simulate_session(
    cell: &DiagnoseCell,
    errors1: &KinematicErrors,
    errors2: &KinematicErrors,
    n: usize,
    half_size_m: f64,
    seed: u64,
) -> Result<HandclaspSession, DiagnoseError> {
    use rand::Rng;
    let normal = Normal::new(0.0, cell.sigma_alignment_m)
        .map_err(|e| DiagnoseError::Simulation(e.to_string()))?;
    let centre = cell.b1_from_b2.translation.vector / 2.0;
    let b2_from_b1 = cell.b1_from_b2.inverse();
    let mut s = HandclaspSession {
        q1: vec![],
        q2: vec![],
        p1_b1: vec![],
        p2_b2: vec![],
        rows: vec![],
    };
    let mut attempt = 0u64;
    while s.rows.len() < n {
        if attempt > 100 * n as u64 + 100 {
            return Err(DiagnoseError::Simulation(format!(
                "only {} of {n} teach points reachable by both robots around {} mm; check the cell's b1_from_b2",
                s.rows.len(),
                fmt3(&(centre * 1000.0))
            )));
        }
        let mut rng = trial_rng(seed, attempt);
        attempt += 1;
        let p = Point3::from(
            centre
                + Vector3::new(
                    rng.random_range(-half_size_m..half_size_m),
                    rng.random_range(-half_size_m..half_size_m),
                    rng.random_range(-half_size_m..half_size_m),
                ),
        );
        let Some(q1) = solve_true(&cell.robot1, errors1, &p) else {
            continue;
        };
        let eps = Vector3::new(
            normal.sample(&mut rng),
            normal.sample(&mut rng),
            normal.sample(&mut rng),
        );
        let p2 = b2_from_b1 * (p + eps);
        let Some(q2) = solve_true(&cell.robot2, errors2, &p2) else {
            continue;
        };
        let t1 = kinematics::base_from_tip(&cell.robot1.model, &q1, &cell.robot1.flange_from_tip)
            .map_err(|e| DiagnoseError::Simulation(e.to_string()))?;
        let t2 = kinematics::base_from_tip(&cell.robot2.model, &q2, &cell.robot2.flange_from_tip)
            .map_err(|e| DiagnoseError::Simulation(e.to_string()))?;
        s.q1.push(q1);
        s.q2.push(q2);
        s.p1_b1.push(Point3::from(t1.translation.vector));
        s.p2_b2.push(Point3::from(t2.translation.vector));
        s.rows.push(s.rows.len() + 1);
    }
    Ok(s)
}

/// Writes a session CSV in the sim-cell format (`point, r1_q*_deg, r2_q*_deg, r1_x_mm … r2_z_mm`,
/// degrees and mm with 6 decimals).
pub fn write_session_csv(path: &Path, session: &HandclaspSession) -> Result<(), DiagnoseError> {
    use std::fmt::Write;
    let d1 = session.q1.first().map_or(0, |q| q.len());
    let d2 = session.q2.first().map_or(0, |q| q.len());
    let mut s = String::from("point");
    for (r, d) in [(1, d1), (2, d2)] {
        for k in 1..=d {
            let _ = write!(s, ",r{r}_q{k}_deg");
        }
    }
    s += ",r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n";
    for i in 0..session.q1.len() {
        let _ = write!(s, "{}", i + 1);
        for q in session.q1[i].iter().chain(&session.q2[i]) {
            let _ = write!(s, ",{:.6}", q.to_degrees());
        }
        for p in [&session.p1_b1[i], &session.p2_b2[i]] {
            for a in 0..3 {
                let _ = write!(s, ",{:.6}", p[a] * 1000.0);
            }
        }
        s += "\n";
    }
    std::fs::write(path, s).map_err(|e| io_err(path, e))
}

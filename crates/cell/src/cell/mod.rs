//! A cell: two robots (or one: a file with `[robot1]` only, [`Cell::one_robot`]), their mounts, tip offsets and tools, kinematic errors (a
//! simulation's hidden truth, or what an earlier calibration left beside the URDFs), the
//! placement `b1_from_b2` and the noise of a handclasp session. Read from TOML (mm, degrees,
//! paths relative to the file); every key is documented in `docs/formats.md`.
//!
//! One job: turning a cell file into a checked [`Cell`] and back. The TOML schema, the checks that
//! make a cell physically possible (robot 2's declared mount against the gravity direction implied
//! by `b1_from_b2`, robot 1 not on a wall) and the writer all serve that job; its tests are in
//! `tests.rs`.

use crate::error::FormatError;
use calib_core::whole_cell::{Tolerance, Tool};
use calib_core::{zyz_canonical, Mount, MountPair, PoseMmDeg, Robot};
use kinematics::{JointCoupling, KinematicErrors, RobotModel};
use nalgebra::{Isometry3, Point3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Standard gravity, m/s².
pub const G: f64 = 9.81;
/// Largest angle (deg) between robot 2's declared mount and the gravity direction implied by
/// `b1_from_b2` before the cell is rejected as an impossible mount.
pub const MOUNT_TOLERANCE_DEG: f64 = 2.0;
/// Default `[noise] alignment_mm` when the key is absent, mm.
pub const DEFAULT_ALIGNMENT_MM: f64 = 0.3;

/// The default cell (floor–wall), as shipped in `cells/floor-wall.toml`.
pub const FLOOR_WALL_TOML: &str = include_str!("../../../../cells/floor-wall.toml");
/// The floor–floor cell, as shipped in `cells/floor-floor.toml`.
pub const FLOOR_FLOOR_TOML: &str = include_str!("../../../../cells/floor-floor.toml");
/// The floor–ceiling cell, as shipped in `cells/floor-ceiling.toml`.
pub const FLOOR_CEILING_TOML: &str = include_str!("../../../../cells/floor-ceiling.toml");
/// The embedded URDFs (path as written in the shipped cells, text).
const EMBEDDED_URDFS: [(&str, &str); 2] = [
    (
        "../robots/va1400.urdf",
        include_str!("../../../../robots/va1400.urdf"),
    ),
    (
        "../robots/hp20.urdf",
        include_str!("../../../../robots/hp20.urdf"),
    ),
];

/// Name of each robot's default tool, the cell's `tip_mm` (tool index 0; extra tools follow).
pub const TIP_TOOL: &str = "tip";

/// One robot of a cell.
#[derive(Debug, Clone)]
pub struct CellRobot {
    /// The nominal model (what the controller believes).
    pub model: RobotModel,
    /// The `urdf` value as written in the cell file (relative to the file's directory).
    pub urdf: String,
    /// The resolved URDF path.
    pub urdf_path: PathBuf,
    /// The URDF link of the flange (`tool_link`, default `tool0`).
    pub tool_link: String,
    /// Nominal tip offset, m, flange (`tool0`) frame: the default tool, named [`TIP_TOOL`].
    pub flange_from_tip: Vector3<f64>,
    /// Extra named tools (`[robotN.tools] name = [x, y, z]`, mm in the file, m here, flange
    /// frame), e.g. a tracker reflector, in name order; never named [`TIP_TOOL`]. Session rows
    /// pick one by name (`tool1`, `tool2`, `tool` columns).
    pub tools: Vec<Tool>,
    /// The mount.
    pub mount: Mount,
    /// Gravity in this robot's nominal base frame, m/s² (robot 1: from its mount; robot 2:
    /// `R(b1_from_b2)ᵀ·g_b1`).
    pub g_base: Vector3<f64>,
    /// The robot's true kinematic errors (zero = the nominal robot).
    pub errors: KinematicErrors,
    /// Manufacturing tolerances, the prior of a whole-cell calibration (`[robotN.tolerance]`;
    /// default [`Tolerance::default`]: 0.05° joint offsets and origin rpy, 0.5 mm origin xyz and
    /// tip; half-widths of a uniform band, see [`Tolerance`]).
    pub tolerance: Tolerance,
}

impl CellRobot {
    /// Index of the tool named `name`: 0 for [`TIP_TOOL`] (`tip_mm`), `k` for `tools[k − 1]`;
    /// `None` if the robot has no such tool.
    pub fn tool_index(&self, name: &str) -> Option<usize> {
        if name == TIP_TOOL {
            return Some(0);
        }
        self.tools
            .iter()
            .position(|t| t.name == name)
            .map(|k| k + 1)
    }

    /// Name of tool `index` ([`CellRobot::tool_index`]'s numbering); `None` out of range.
    pub fn tool_name(&self, index: usize) -> Option<&str> {
        match index {
            0 => Some(TIP_TOOL),
            k => self.tools.get(k - 1).map(|t| t.name.as_str()),
        }
    }

    /// Nominal offset of tool `index` in the flange frame, m; `None` out of range.
    pub fn flange_from_tool(&self, index: usize) -> Option<Vector3<f64>> {
        match index {
            0 => Some(self.flange_from_tip),
            k => self.tools.get(k - 1).map(|t| t.flange_from_tip),
        }
    }

    /// Every tool's name, index order (`tip` first), for messages.
    pub fn tool_names(&self) -> Vec<&str> {
        std::iter::once(TIP_TOOL)
            .chain(self.tools.iter().map(|t| t.name.as_str()))
            .collect()
    }
}

/// The noise of a handclasp session: what the simulator draws, and what the whole-cell fit weighs
/// coincident rows by ([`crate::problem::handclasp_covariance`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// σ of the operator's tip-alignment error per b1 axis, m.
    pub alignment_m: Vector3<f64>,
    /// σ of each robot's repeatability per axis, m (unseen by the encoders).
    pub repeatability_m: f64,
    /// Encoder resolution, rad (reported joints are multiples of it; 0 = exact).
    pub encoder_resolution_rad: f64,
}

/// A cell (see the module docs). Build with [`Cell::from_toml_file`], [`Cell::from_toml_str`] or
/// the paper's cells [`Cell::default_floor_wall`], [`Cell::default_floor_floor`],
/// [`Cell::default_floor_ceiling`] ([`Cell::shipped`] by mount pair).
#[derive(Debug, Clone)]
pub struct Cell {
    /// Directory the relative paths are resolved against.
    pub base_dir: PathBuf,
    /// Robot 1 (defines the b1 frame).
    pub robot1: CellRobot,
    /// Robot 2.
    pub robot2: CellRobot,
    /// Placement of base 2 in base 1, m, rad (a simulation's truth, or the placement as known or
    /// calibrated).
    pub b1_from_b2: Isometry3<f64>,
    /// How well `b1_from_b2` is known (`[b1_from_b2] sigma_mm, sigma_deg`): `Some` puts a prior
    /// around it in the whole-cell fit (e.g. two arms on one base); `None`: the placement is
    /// fitted freely.
    pub b1_from_b2_sigma: Option<PlacementSigma>,
    /// Session noise.
    pub noise: Noise,
    /// Centre of the teach points, m, b1 frame (`[teach] centre_mm`; default: the midpoint of the
    /// two shoulders, i.e. of joint 2's origins at q = 0).
    pub centre_b1: Point3<f64>,
    /// True for a one-robot cell (a file with `[robot1]` only): then `robot2` is a stand-in
    /// that no observation may use (robot 1's model with [`Tolerance::none`], no tools but the
    /// tip), `b1_from_b2` the identity held by [`ONE_ROBOT_PLACEMENT_SIGMA`], and the files, the
    /// reports and the export leave robot 2 and the placement out ([`Cell::has_robot2`]).
    pub one_robot: bool,
    /// A shared trunk (`[robot2] shares = { robot = 1, joints = k }`): robot 2's first `k` chain
    /// joints are robot 1's (one set of parameters, fitted once; robot 2's errors at them are
    /// robot 1's), the placement is the identity held by [`SHARED_TRUNK_PLACEMENT_SIGMA`] (both
    /// chains start at the common base) and a row with both robots has equal shared joint
    /// values. 0 otherwise.
    pub shared_joints: usize,
}

/// The prior σ holding a shared-trunk cell's placement at the identity: both arms' chains start
/// at the common base, so `b1_from_b2` is known (1 µm, 1 µrad; as [`ONE_ROBOT_PLACEMENT_SIGMA`]).
pub const SHARED_TRUNK_PLACEMENT_SIGMA: PlacementSigma = ONE_ROBOT_PLACEMENT_SIGMA;

/// The prior σ holding a one-robot cell's stand-in placement at the identity (no observation
/// reaches it): 1 µm and 1 µrad per component, far below any measurement, far above round-off.
pub const ONE_ROBOT_PLACEMENT_SIGMA: PlacementSigma = PlacementSigma {
    sigma_m: 1e-6,
    sigma_rad: 1e-6,
};

/// The stated uncertainty of a cell's `b1_from_b2` (per component, SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacementSigma {
    /// σ of each translation component, m (≥ 0; 0 leaves the translation free).
    pub sigma_m: f64,
    /// σ of each rotation-vector component, rad (≥ 0; 0 leaves the rotation free).
    pub sigma_rad: f64,
}

// ---- file format -------------------------------------------------------------------------

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CellFile {
    robot1: RobotFile,
    /// Absent in a one-robot cell (then `b1_from_b2` is absent too).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    robot2: Option<RobotFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    b1_from_b2: Option<PlacementFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    noise: Option<NoiseFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    teach: Option<TeachFile>,
}

/// `[b1_from_b2]`: the placement (mm, ZYZ degrees) and, optionally, how well it is known.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlacementFile {
    xyz_mm: [f64; 3],
    zyz_deg: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    sigma_deg: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    urdf: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tool_link: Option<String>,
    mount: toml::Value,
    tip_mm: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tools: Option<std::collections::BTreeMap<String, [f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    errors: Option<ErrorsFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tolerance: Option<ToleranceFile>,
    /// `[[robotN.couplings]]`: joints whose value follows others' (`q_k = Σ c_i·q_i + c_0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    couplings: Option<Vec<CouplingFile>>,
    /// `[robot2] shares = { robot = 1, joints = k }` (or `link = "chest"`): a shared trunk.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    shares: Option<SharesFile>,
}

/// `shares = { robot = 1, joints = k }` or `{ robot = 1, link = "name" }`: robot 2's first `k`
/// chain joints (those up to and including the joint whose child is `link`) are robot 1's.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SharesFile {
    robot: u8,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joints: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    link: Option<String>,
}

/// `[[robotN.couplings]]`: `joint` follows `Σ c·q[term.joint] + offset`, in file units (degrees
/// for a rotary joint, mm for a prismatic one; `c` in the coupled joint's unit per the driving
/// joint's).
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CouplingFile {
    joint: String,
    terms: Vec<CouplingTermFile>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    offset_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    offset_mm: Option<f64>,
}

/// One term `{ joint = "name", c = coefficient }` of a [`CouplingFile`].
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CouplingTermFile {
    joint: String,
    c: f64,
}

/// `[robotN.tolerance]`: half-widths of uniform bands (mm, degrees); absent keys take
/// [`Tolerance::default`]; 0 holds that kind of parameter at nominal.
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ToleranceFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_offset_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    origin_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    origin_deg: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tip_mm: Option<f64>,
    /// Encoder scale of every chain joint, a ratio (revolute: gear ratio; prismatic: the
    /// reading's scale); absent or 0: not fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_scale: Option<f64>,
    /// Each once-per-turn amplitude (sin and cos) of every rotary chain joint, degrees; absent
    /// or 0: not fitted.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    periodic_deg: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NoiseFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    alignment_mm: Option<toml::Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    repeatability_mm: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    encoder_resolution_deg: Option<f64>,
}

#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TeachFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    centre_mm: Option<[f64; 3]>,
}

#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ErrorsFile {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_offset_deg: Option<Vec<f64>>,
    /// Prismatic joints' zero offsets, mm (one entry per joint; 0 at rotary joints).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_offset_mm: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    joint_scale: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    origin_xyz_mm: Option<Vec<[f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    origin_rpy_deg: Option<Vec<[f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    tip_mm: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mount_xyz_mm: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    mount_rpy_deg: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    compliance_deg_per_knm: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    periodic_sin_deg: Option<Vec<f64>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    periodic_cos_deg: Option<Vec<f64>>,
    /// Lumped gravity compliance, deg: per chain joint, one `[x, y, z]` per link it carries
    /// (`kinematics::KinematicErrors::lumped_compliance`); an empty list is all zero.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    lumped_compliance_deg: Option<Vec<Vec<[f64; 3]>>>,
}

// ---- parsing -----------------------------------------------------------------------------

/// A message-to-error closure naming the cell file (for parsers in other files).
fn ctx_err<'a>(ctx: &'a Ctx<'a>) -> impl Fn(String) -> FormatError + 'a {
    move |m| ctx.err(m)
}

struct Ctx<'a> {
    path: &'a Path,
}

impl Ctx<'_> {
    fn err(&self, message: impl Into<String>) -> FormatError {
        FormatError::Cell {
            path: self.path.to_path_buf(),
            message: message.into(),
        }
    }
}

/// A measuring tip shorter than this (mm, from the flange) is almost surely written in metres:
/// real handclasp tips are tens to hundreds of millimetres long. A zero tip (the flange itself)
/// is allowed.
pub const MIN_TIP_MM: f64 = 1.0;

/// `{key}.tip_mm` as finite numbers, refusing a nonzero tip shorter than [`MIN_TIP_MM`] with the
/// unit named.
fn tip3(ctx: &Ctx, key: &str, v: [f64; 3]) -> Result<Vector3<f64>, FormatError> {
    let tip = finite3(ctx, key, v)?;
    let length_mm = tip.norm();
    if length_mm > 0.0 && length_mm < MIN_TIP_MM {
        return Err(ctx.err(format!(
            "`{key}` = {v:?} is a tip {length_mm} mm long: a measuring tip shorter than {MIN_TIP_MM} mm is almost surely \
             written in metres; tip_mm is in millimetres, so multiply by 1000 ({:?}), or write [0, 0, 0] for the flange itself",
            v.map(|x| x * 1000.0)
        )));
    }
    Ok(tip)
}

fn finite3(ctx: &Ctx, key: &str, v: [f64; 3]) -> Result<Vector3<f64>, FormatError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(Vector3::from(v))
    } else {
        Err(ctx.err(format!("`{key}` = {v:?} must hold 3 finite numbers")))
    }
}

fn parse_mount(ctx: &Ctx, key: &str, v: &toml::Value) -> Result<Mount, FormatError> {
    let what = "use \"floor\", \"ceiling\", \"wall\" or { tilt_deg = [rx, ry] } (degrees)";
    match v {
        toml::Value::String(s) => match s.trim().to_ascii_lowercase().as_str() {
            "floor" => Ok(Mount::Floor),
            "ceiling" => Ok(Mount::Ceiling),
            "wall" => Ok(Mount::Wall),
            other => Err(ctx.err(format!("`{key}` = \"{other}\" is not a mount: {what}"))),
        },
        toml::Value::Table(t) => {
            if let Some(k) = t.keys().find(|k| k.as_str() != "tilt_deg") {
                return Err(ctx.err(format!(
                    "`{key}.{k}` is not a key of a tilt mount: only tilt_deg = [rx, ry] (degrees)"
                )));
            }
            let a = t
                .get("tilt_deg")
                .and_then(|v| v.as_array())
                .ok_or_else(|| {
                    ctx.err(format!("`{key}` table needs tilt_deg = [rx, ry] (degrees)"))
                })?;
            let nums: Vec<f64> = a
                .iter()
                .filter_map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                .collect();
            if nums.len() != 2
                || a.len() != 2
                || nums.iter().any(|x| !x.is_finite() || x.abs() > 360.0)
            {
                return Err(ctx.err(format!(
                    "`{key}.tilt_deg` must be [rx, ry]: two finite angles in degrees within ±360"
                )));
            }
            Ok(Mount::Tilt {
                rx: nums[0].to_radians(),
                ry: nums[1].to_radians(),
            })
        }
        _ => Err(ctx.err(format!("`{key}` has the wrong type: {what}"))),
    }
}

fn mount_value(m: &Mount) -> toml::Value {
    match m {
        Mount::Tilt { rx, ry } => {
            let mut t = toml::map::Map::new();
            t.insert(
                "tilt_deg".into(),
                toml::Value::Array(vec![
                    toml::Value::Float(rx.to_degrees()),
                    toml::Value::Float(ry.to_degrees()),
                ]),
            );
            toml::Value::Table(t)
        }
        other => toml::Value::String(other.to_string()),
    }
}

/// The angle, degrees, between `mount`'s gravity direction and `up_base` (unit "up" in the
/// base frame): for a wall (roll unknown), the angle of `up_base` out of the base's xy plane;
/// otherwise the angle between the mount's up direction and `up_base`. A cell whose robot 2
/// is more than [`MOUNT_TOLERANCE_DEG`] off its `b1_from_b2` is rejected.
pub fn mount_mismatch_deg(mount: &Mount, up_base: &Vector3<f64>) -> f64 {
    match mount.level_from_base() {
        None => up_base.z.abs().min(1.0).asin().to_degrees(),
        Some(level_from_base) => {
            let expected: Vector3<f64> = level_from_base.inverse() * Vector3::z();
            expected.angle(up_base).to_degrees()
        }
    }
}

/// The mount whose gravity direction is `up_base` (unit "up" in the base frame): floor,
/// ceiling or wall when within [`MOUNT_TOLERANCE_DEG`] of one, else the tilt that gives it
/// exactly.
pub fn mount_of_up(up_base: &Vector3<f64>) -> Mount {
    let tol = MOUNT_TOLERANCE_DEG.to_radians();
    if up_base.z > tol.cos() {
        Mount::Floor
    } else if up_base.z < -tol.cos() {
        Mount::Ceiling
    } else if up_base.z.abs() < tol.sin() {
        Mount::Wall
    } else {
        // level_from_base = Rx(rx)·Ry(ry) ⇒ up_base = (−cos rx·sin ry, sin rx, cos rx·cos ry).
        Mount::Tilt {
            rx: up_base.y.clamp(-1.0, 1.0).asin(),
            ry: (-up_base.x).atan2(up_base.z),
        }
    }
}

/// When `b1_from_b2` (a fitted placement) puts robot 2's gravity direction more than
/// [`MOUNT_TOLERANCE_DEG`] from its declared mount in `cell`: the mount that placement
/// implies ([`mount_of_up`]) and a sentence saying so (the angle, both mounts, the likely
/// causes). `None` when they agree, and for a one-robot cell.
pub fn refitted_robot2_mount(cell: &Cell, b1_from_b2: &Isometry3<f64>) -> Option<(Mount, String)> {
    if !cell.has_robot2() {
        return None;
    }
    let up_b2 = -(b1_from_b2.rotation.inverse() * cell.robot1.g_base) / G;
    let off_deg = mount_mismatch_deg(&cell.robot2.mount, &up_b2);
    if off_deg <= MOUNT_TOLERANCE_DEG {
        return None;
    }
    let implied = mount_of_up(&up_b2);
    let note = format!(
        "the fitted b1_from_b2 puts robot 2's up direction {off_deg:.2}° from its declared \
         mount = {} (a cell file allows {MOUNT_TOLERANCE_DEG}°): the exported cell's robot 2 \
         mount is {}, as the fitted placement implies (gravity follows the placement either \
         way); check the mount, or whether errors the model lacks (e.g. gravity sag) pulled the \
         placement",
        mount_value(&cell.robot2.mount),
        mount_value(&implied)
    );
    Some((implied, note))
}

/// The mount whose gravity direction matches `up_base` (unit "up" in the base frame), as text.
fn mount_suggestion(up_base: &Vector3<f64>) -> String {
    let tol = MOUNT_TOLERANCE_DEG.to_radians();
    if up_base.z > tol.cos() {
        "\"floor\"".into()
    } else if up_base.z < -tol.cos() {
        "\"ceiling\"".into()
    } else if up_base.z.abs() < tol.sin() {
        "\"wall\"".into()
    } else {
        // level_from_base = Rx(rx)·Ry(ry) ⇒ up_base = (−cos rx·sin ry, sin rx, cos rx·cos ry).
        let rx = up_base.y.clamp(-1.0, 1.0).asin();
        let ry = (-up_base.x).atan2(up_base.z);
        format!(
            "{{ tilt_deg = [{:.3}, {:.3}] }}",
            rx.to_degrees(),
            ry.to_degrees()
        )
    }
}

fn build_errors(
    ctx: &Ctx,
    key: &str,
    model: &RobotModel,
    e: &ErrorsFile,
) -> Result<KinematicErrors, FormatError> {
    // One entry per chain joint, coupled joints included (their own offsets and compliance).
    let dof = model.chain_joints().len();
    let mut out = KinematicErrors::zero(dof);
    let coupled_note = if model.has_coupled_joints() {
        " (coupled joints included: every moving joint of the chain)"
    } else {
        ""
    };
    let len_err = |field: &str, len: usize| {
        ctx.err(format!(
            "`{key}.errors.{field}` has {len} entries but {} has {dof} joints{coupled_note}: give one per joint, in URDF chain order",
            model.name()
        ))
    };
    let per_joint =
        |field: &str, v: &Option<Vec<f64>>, scale: f64| -> Result<Option<Vec<f64>>, FormatError> {
            match v {
                None => Ok(None),
                Some(v) if v.len() != dof => Err(len_err(field, v.len())),
                Some(v) if v.iter().any(|x| !x.is_finite()) => {
                    Err(ctx.err(format!("`{key}.errors.{field}` must hold finite numbers")))
                }
                Some(v) => Ok(Some(v.iter().map(|x| x * scale).collect())),
            }
        };
    let per_joint3 = |field: &str,
                      v: &Option<Vec<[f64; 3]>>,
                      scale: f64|
     -> Result<Option<Vec<Vector3<f64>>>, FormatError> {
        match v {
            None => Ok(None),
            Some(v) if v.len() != dof => Err(len_err(field, v.len())),
            Some(v) => v
                .iter()
                .map(|a| finite3(ctx, &format!("{key}.errors.{field}"), *a).map(|x| x * scale))
                .collect::<Result<Vec<_>, _>>()
                .map(Some),
        }
    };
    let d2r = 1f64.to_radians();
    // Per-joint angle fields hold 0 at a prismatic joint, `joint_offset_mm` 0 at a rotary one:
    // each array has one unit.
    let prismatic: Vec<bool> = model
        .chain_joints()
        .iter()
        .map(|j| j.kind.is_prismatic())
        .collect();
    let kind_only = |field: &str, v: &Option<Vec<f64>>, want_prismatic: bool| {
        let bad = v
            .iter()
            .flatten()
            .zip(&prismatic)
            .position(|(x, &p)| *x != 0.0 && p != want_prismatic);
        match bad {
            None => Ok(()),
            Some(j) => Err(ctx.err(format!(
                "`{key}.errors.{field}` entry {} (joint {}) is {}, but that joint is {}: {}",
                j + 1,
                model.chain_joints()[j].name,
                v.as_ref().map_or(0.0, |v| v[j]),
                model.chain_joints()[j].kind.urdf_name(),
                if want_prismatic {
                    "joint_offset_mm holds prismatic joints' offsets only; give a rotary joint's in joint_offset_deg (0 here)"
                } else {
                    "a prismatic joint's zero offset is a length: give it in joint_offset_mm (0 here); compliance, periodic terms are for rotary joints"
                }
            ))),
        }
    };
    kind_only("joint_offset_deg", &e.joint_offset_deg, false)?;
    kind_only("compliance_deg_per_knm", &e.compliance_deg_per_knm, false)?;
    kind_only("joint_offset_mm", &e.joint_offset_mm, true)?;
    if let Some(v) = per_joint("joint_offset_deg", &e.joint_offset_deg, d2r)? {
        out.joint_offset = v;
    }
    if let Some(v) = per_joint("joint_offset_mm", &e.joint_offset_mm, 1e-3)? {
        for (j, x) in v.into_iter().enumerate() {
            if prismatic[j] {
                out.joint_offset[j] = x;
            }
        }
    }
    if let Some(v) = per_joint("joint_scale", &e.joint_scale, 1.0)? {
        out.joint_scale = v;
    }
    // deg/(kN·m) → rad/(N·m)
    if let Some(v) = per_joint(
        "compliance_deg_per_knm",
        &e.compliance_deg_per_knm,
        d2r / 1000.0,
    )? {
        out.compliance = v;
    }
    if let Some(v) = per_joint("periodic_sin_deg", &e.periodic_sin_deg, d2r)? {
        out.periodic_sin = v;
    }
    if let Some(v) = per_joint("periodic_cos_deg", &e.periodic_cos_deg, d2r)? {
        out.periodic_cos = v;
    }
    if let Some(v) = &e.lumped_compliance_deg {
        out.lumped_compliance = crate::lumped_file::parse_lumped(ctx_err(ctx), key, model, v)?;
    }
    if let Some(v) = per_joint3("origin_xyz_mm", &e.origin_xyz_mm, 1e-3)? {
        out.origin_xyz = v;
    }
    if let Some(v) = per_joint3("origin_rpy_deg", &e.origin_rpy_deg, d2r)? {
        out.origin_rpy = v;
    }
    if let Some(v) = e.tip_mm {
        out.tip = finite3(ctx, &format!("{key}.errors.tip_mm"), v)? * 1e-3;
    }
    if let Some(v) = e.mount_xyz_mm {
        out.mount_xyz = finite3(ctx, &format!("{key}.errors.mount_xyz_mm"), v)? * 1e-3;
    }
    if let Some(v) = e.mount_rpy_deg {
        out.mount_rpy = finite3(ctx, &format!("{key}.errors.mount_rpy_deg"), v)? * d2r;
    }
    Ok(out)
}

fn build_tolerance(ctx: &Ctx, key: &str, t: &ToleranceFile) -> Result<Tolerance, FormatError> {
    let d = Tolerance::default();
    let field = |name: &str, v: Option<f64>, default_si: f64, to_si: f64| {
        match v {
        None => Ok(default_si),
        Some(v) if v.is_finite() && v >= 0.0 => Ok(v * to_si),
        Some(v) => Err(ctx.err(format!(
            "`{key}.tolerance.{name}` = {v}: give a finite half-width ≥ 0 (0 holds these parameters at nominal)"
        ))),
    }
    };
    let d2r = 1f64.to_radians();
    Ok(Tolerance {
        joint_offset_rad: field(
            "joint_offset_deg",
            t.joint_offset_deg,
            d.joint_offset_rad,
            d2r,
        )?,
        origin_xyz_m: field("origin_mm", t.origin_mm, d.origin_xyz_m, 1e-3)?,
        origin_rpy_rad: field("origin_deg", t.origin_deg, d.origin_rpy_rad, d2r)?,
        tip_m: field("tip_mm", t.tip_mm, d.tip_m, 1e-3)?,
        // Optional families: 0 (like absent) is "not fitted".
        joint_scale: Some(field("joint_scale", t.joint_scale, 0.0, 1.0)?).filter(|v| *v > 0.0),
        periodic_rad: Some(field("periodic_deg", t.periodic_deg, 0.0, d2r)?).filter(|v| *v > 0.0),
        ..d
    })
}

/// The `[robotN.tolerance]` table of `t`, or `None` when it is the default (so cells without
/// one round-trip unchanged).
fn tolerance_file(t: &Tolerance) -> Option<ToleranceFile> {
    if *t == Tolerance::default() {
        return None;
    }
    Some(ToleranceFile {
        joint_offset_deg: Some(t.joint_offset_rad.to_degrees()),
        origin_mm: Some(t.origin_xyz_m * 1e3),
        origin_deg: Some(t.origin_rpy_rad.to_degrees()),
        tip_mm: Some(t.tip_m * 1e3),
        joint_scale: t.joint_scale.filter(|v| *v > 0.0),
        periodic_deg: t.periodic_rad.filter(|v| *v > 0.0).map(f64::to_degrees),
    })
}

fn errors_file(model: &RobotModel, e: &KinematicErrors) -> Option<ErrorsFile> {
    if e.is_zero() {
        return None;
    }
    // A prismatic joint's offset (m) goes to `joint_offset_mm`, a rotary one's to `_deg`.
    let (mut rotary_offset, mut prismatic_offset) =
        (e.joint_offset.clone(), e.joint_offset.clone());
    for (j, joint) in model
        .chain_joints()
        .iter()
        .enumerate()
        .take(e.joint_offset.len())
    {
        if joint.kind.is_prismatic() {
            rotary_offset[j] = 0.0;
        } else {
            prismatic_offset[j] = 0.0;
        }
    }
    let nz = |v: &[f64]| v.iter().any(|x| *x != 0.0);
    let nz3 = |v: &[Vector3<f64>]| v.iter().any(|x| x.iter().any(|c| *c != 0.0));
    let a3 = |v: &Vector3<f64>, s: f64| [v.x * s, v.y * s, v.z * s];
    let r2d = 1f64.to_degrees();
    Some(ErrorsFile {
        joint_offset_deg: nz(&rotary_offset)
            .then(|| rotary_offset.iter().map(|x| x * r2d).collect()),
        joint_offset_mm: nz(&prismatic_offset)
            .then(|| prismatic_offset.iter().map(|x| x * 1e3).collect()),
        joint_scale: nz(&e.joint_scale).then(|| e.joint_scale.clone()),
        origin_xyz_mm: nz3(&e.origin_xyz)
            .then(|| e.origin_xyz.iter().map(|v| a3(v, 1e3)).collect()),
        origin_rpy_deg: nz3(&e.origin_rpy)
            .then(|| e.origin_rpy.iter().map(|v| a3(v, r2d)).collect()),
        tip_mm: nz(e.tip.as_slice()).then(|| a3(&e.tip, 1e3)),
        mount_xyz_mm: nz(e.mount_xyz.as_slice()).then(|| a3(&e.mount_xyz, 1e3)),
        mount_rpy_deg: nz(e.mount_rpy.as_slice()).then(|| a3(&e.mount_rpy, r2d)),
        compliance_deg_per_knm: nz(&e.compliance)
            .then(|| e.compliance.iter().map(|x| x * r2d * 1000.0).collect()),
        periodic_sin_deg: nz(&e.periodic_sin)
            .then(|| e.periodic_sin.iter().map(|x| x * r2d).collect()),
        periodic_cos_deg: nz(&e.periodic_cos)
            .then(|| e.periodic_cos.iter().map(|x| x * r2d).collect()),
        lumped_compliance_deg: crate::lumped_file::write_lumped(&e.lumped_compliance),
    })
}

/// Shoulder (joint 2's origin at q = 0) of a model, m, its base frame.
fn shoulder(model: &RobotModel) -> Point3<f64> {
    // At q = 0 the joint rotations are identities: compose the fixed parts only.
    let t = model
        .chain_joints()
        .iter()
        .take(2)
        .fold(Isometry3::identity(), |t, j| {
            t * j.fixed_prefix * kinematics::origin_isometry(&j.origin_xyz, &j.origin_rpy)
        });
    Point3::from(t.translation.vector)
}

impl Cell {
    /// Reads a cell TOML file (paths in it relative to the file's directory).
    pub fn from_toml_file(path: &Path) -> Result<Cell, FormatError> {
        let text = kinematics::input::read_input_text(path, "cell TOML").map_err(|e| match e {
            kinematics::input::InputError::Io { source, .. } => FormatError::Cell {
                path: path.to_path_buf(),
                message: format!("cannot read the cell file: {source}"),
            },
            other => FormatError::InputFile(other),
        })?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        parse(&text, &dir, path, false)
    }

    /// Parses cell TOML text; relative URDF paths are resolved against `base_dir`.
    pub fn from_toml_str(text: &str, base_dir: &Path) -> Result<Cell, FormatError> {
        parse(text, base_dir, Path::new("<string>"), false)
    }

    /// The paper's floor–wall cell (the default; `cells/floor-wall.toml`, URDFs embedded).
    pub fn default_floor_wall() -> Cell {
        embedded(FLOOR_WALL_TOML)
    }

    /// The paper's floor–floor cell (`cells/floor-floor.toml`, URDFs embedded).
    pub fn default_floor_floor() -> Cell {
        embedded(FLOOR_FLOOR_TOML)
    }

    /// The paper's floor–ceiling cell (`cells/floor-ceiling.toml`, URDFs embedded).
    pub fn default_floor_ceiling() -> Cell {
        embedded(FLOOR_CEILING_TOML)
    }

    /// The shipped cell of the paper's mount pair `m` (floor–floor, floor–wall or
    /// floor–ceiling), or `None` for other mounts.
    pub fn shipped(m: MountPair) -> Option<Cell> {
        if m == MountPair::floor_floor() {
            Some(Cell::default_floor_floor())
        } else if m == MountPair::floor_wall() {
            Some(Cell::default_floor_wall())
        } else if m == MountPair::floor_ceiling() {
            Some(Cell::default_floor_ceiling())
        } else {
            None
        }
    }

    /// The mounts of both robots.
    pub fn mounts(&self) -> MountPair {
        MountPair {
            robot1: self.robot1.mount,
            robot2: self.robot2.mount,
        }
    }

    /// The cell as TOML (mm, degrees); URDF paths as written (relative to [`Cell::base_dir`]).
    /// Zero errors are omitted. [`Cell::from_toml_str`] of it with the same `base_dir` gives this
    /// cell back (to round-off).
    pub fn to_toml_string(&self) -> String {
        let robot = |r: &CellRobot| RobotFile {
            urdf: r.urdf.clone(),
            tool_link: (r.tool_link != "tool0").then(|| r.tool_link.clone()),
            mount: mount_value(&r.mount),
            tip_mm: [
                r.flange_from_tip.x * 1e3,
                r.flange_from_tip.y * 1e3,
                r.flange_from_tip.z * 1e3,
            ],
            tools: (!r.tools.is_empty()).then(|| {
                r.tools
                    .iter()
                    .map(|t| {
                        let v = t.flange_from_tip * 1e3;
                        (t.name.clone(), [v.x, v.y, v.z])
                    })
                    .collect()
            }),
            errors: errors_file(&r.model, &r.errors),
            tolerance: tolerance_file(&r.tolerance),
            couplings: couplings_file(&r.model),
            shares: None,
        };
        let zyz = zyz_canonical(&self.b1_from_b2.rotation.to_rotation_matrix());
        let t = self.b1_from_b2.translation.vector * 1e3;
        let a = self.noise.alignment_m * 1e3;
        let two = self.has_robot2();
        let file = CellFile {
            robot1: robot(&self.robot1),
            robot2: two.then(|| {
                let mut r2 = robot(&self.robot2);
                r2.shares = (self.shared_joints > 0).then_some(SharesFile {
                    robot: 1,
                    joints: Some(self.shared_joints),
                    link: None,
                });
                r2
            }),
            b1_from_b2: (two && self.shared_joints == 0).then(|| PlacementFile {
                xyz_mm: [t.x, t.y, t.z],
                zyz_deg: zyz.map(f64::to_degrees),
                sigma_mm: self.b1_from_b2_sigma.map(|s| s.sigma_m * 1e3),
                sigma_deg: self.b1_from_b2_sigma.map(|s| s.sigma_rad.to_degrees()),
            }),
            noise: Some(NoiseFile {
                alignment_mm: Some(if a.x == a.y && a.y == a.z {
                    toml::Value::Float(a.x)
                } else {
                    toml::Value::Array(vec![a.x.into(), a.y.into(), a.z.into()])
                }),
                repeatability_mm: Some(self.noise.repeatability_m * 1e3),
                encoder_resolution_deg: Some(self.noise.encoder_resolution_rad.to_degrees()),
            }),
            teach: Some(TeachFile {
                centre_mm: Some([
                    self.centre_b1.x * 1e3,
                    self.centre_b1.y * 1e3,
                    self.centre_b1.z * 1e3,
                ]),
            }),
        };
        let mut value = match toml::Value::try_from(&file) {
            Ok(v) => v,
            Err(e) => return format!("# cannot serialise the cell: {e}\n"),
        };
        tidy_floats(&mut value);
        toml::to_string(&value).unwrap_or_else(|e| format!("# cannot serialise the cell: {e}\n"))
    }

    /// False for a one-robot cell ([`Cell::one_robot`]): robot 2 is then a stand-in that no
    /// row may use.
    pub fn has_robot2(&self) -> bool {
        !self.one_robot
    }

    /// The number of independent joints (session columns) among the shared trunk's joints
    /// ([`Cell::shared_joints`] chain joints; coupled trunk joints take no column): the first
    /// that many joint columns of robot 1 and robot 2 are the same joints. 0 without a shared
    /// trunk.
    pub fn shared_independent_joints(&self) -> usize {
        self.robot1
            .model
            .chain_joints()
            .iter()
            .take(self.shared_joints)
            .filter(|j| !j.is_coupled())
            .count()
    }

    /// The robots a session of this cell may use: robot 1, and robot 2 unless the cell has one
    /// robot.
    pub fn robots(&self) -> &'static [Robot] {
        if self.one_robot {
            &[Robot::One]
        } else {
            &[Robot::One, Robot::Two]
        }
    }

    /// The cell's robot `which` (robot 1 or robot 2).
    pub fn robot(&self, which: Robot) -> &CellRobot {
        match which {
            Robot::One => &self.robot1,
            Robot::Two => &self.robot2,
        }
    }
}

/// Rounds every float to 10 decimals (mm, degrees: far below any tolerance) so that unit
/// conversions print as written (0.03, not 0.030000000000000002).
fn tidy_floats(v: &mut toml::Value) {
    match v {
        toml::Value::Float(x) => {
            let r = (*x * 1e10).round() / 1e10;
            if r.is_finite() {
                *x = if r == 0.0 { 0.0 } else { r };
            }
        }
        toml::Value::Array(a) => a.iter_mut().for_each(tidy_floats),
        toml::Value::Table(t) => t.iter_mut().for_each(|(_, v)| tidy_floats(v)),
        _ => {}
    }
}

fn embedded(text: &str) -> Cell {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells");
    // The shipped cells are tested to parse; an error here is a build defect, reported loudly.
    parse(text, &dir, Path::new("<embedded cell>"), true)
        .unwrap_or_else(|e| panic!("embedded cell does not parse: {e}"))
}

fn load_model(
    ctx: &Ctx,
    key: &str,
    urdf: &str,
    path: &Path,
    tool_link: &str,
    embedded: bool,
) -> Result<RobotModel, FormatError> {
    if embedded {
        if let Some((_, xml)) = EMBEDDED_URDFS.iter().find(|(p, _)| *p == urdf) {
            return RobotModel::from_urdf_str(xml, tool_link)
                .map_err(|e| ctx.err(format!("`{key}.urdf` (embedded {urdf}): {e}")));
        }
    }
    if !path.is_file() {
        return Err(ctx.err(format!(
            "`{key}.urdf` = \"{urdf}\": no such file {} (paths are relative to the cell file's directory; e.g. \"../robots/va1400.urdf\" from cells/)",
            path.display()
        )));
    }
    RobotModel::from_urdf_file(path, tool_link)
        .map_err(|e| ctx.err(format!("`{key}.urdf` = \"{urdf}\": {e}")))
}

/// SI units per file unit of a chain joint's value: rad per degree for a rotary joint, m per mm
/// for a prismatic one (1 for a name the chain does not hold; the model's check names it).
fn joint_file_unit(model: &RobotModel, name: &str) -> f64 {
    match model.chain_joints().iter().find(|j| j.name == name) {
        Some(j) if j.kind.is_prismatic() => 1e-3,
        _ => 1f64.to_radians(),
    }
}

/// `model` with the cell's `[[{key}.couplings]]` declared on it (file units converted to SI).
/// Errors name the entry, the joint and the fix: an unknown joint, a loop, a joint coupled
/// twice (also by a URDF `<mimic>`), an offset in the other unit.
fn apply_couplings(
    ctx: &Ctx,
    key: &str,
    model: RobotModel,
    couplings: &[CouplingFile],
) -> Result<RobotModel, FormatError> {
    let mut declared = Vec::with_capacity(couplings.len());
    for (k, c) in couplings.iter().enumerate() {
        let at = format!("`{key}.couplings` entry {} (joint `{}`)", k + 1, c.joint);
        if c.terms.is_empty() {
            return Err(ctx.err(format!(
                "{at}: no terms; give terms = [{{ joint = \"name\", c = coefficient }}, …]"
            )));
        }
        let unit_k = joint_file_unit(&model, &c.joint);
        let prismatic = unit_k == 1e-3;
        let offset = match (c.offset_deg, c.offset_mm) {
            (Some(_), Some(_)) => {
                return Err(ctx.err(format!(
                    "{at}: both offset_deg and offset_mm; give one (offset_deg for a rotary joint, offset_mm for a prismatic one)"
                )))
            }
            (Some(_), None) if prismatic => {
                return Err(ctx.err(format!(
                    "{at}: the joint is prismatic: give its offset in offset_mm, not offset_deg"
                )))
            }
            (None, Some(_)) if !prismatic => {
                return Err(ctx.err(format!(
                    "{at}: the joint is rotary: give its offset in offset_deg, not offset_mm"
                )))
            }
            (a, b) => a.or(b).unwrap_or(0.0) * unit_k,
        };
        declared.push(JointCoupling {
            joint: c.joint.clone(),
            terms: c
                .terms
                .iter()
                .map(|t| {
                    (
                        t.joint.clone(),
                        t.c * unit_k / joint_file_unit(&model, &t.joint),
                    )
                })
                .collect(),
            offset,
        });
    }
    model
        .with_couplings(&declared)
        .map_err(|e| ctx.err(format!("`{key}.couplings`: {e}")))
}

/// The couplings declared in the cell (not the URDF's `<mimic>`s), in file units.
fn couplings_file(model: &RobotModel) -> Option<Vec<CouplingFile>> {
    let added = model.added_couplings();
    (!added.is_empty()).then(|| {
        added
            .iter()
            .map(|c| {
                let unit_k = joint_file_unit(model, &c.joint);
                let offset = c.offset / unit_k;
                let prismatic = unit_k == 1e-3;
                CouplingFile {
                    joint: c.joint.clone(),
                    terms: c
                        .terms
                        .iter()
                        .map(|(name, x)| CouplingTermFile {
                            joint: name.clone(),
                            c: x * joint_file_unit(model, name) / unit_k,
                        })
                        .collect(),
                    offset_deg: (!prismatic).then_some(offset),
                    offset_mm: prismatic.then_some(offset),
                }
            })
            .collect()
    })
}

fn parse(text: &str, base_dir: &Path, path: &Path, embedded: bool) -> Result<Cell, FormatError> {
    let ctx = Ctx { path };
    let file: CellFile = toml::from_str(text).map_err(|e| {
        let at = e
            .span()
            .map(|r| format!("line {}: ", text[..r.start.min(text.len())].lines().count().max(1)))
            .unwrap_or_default();
        ctx.err(format!(
            "{at}{} (keys: [robot1], [robot2] (absent in a one-robot cell) with urdf, mount, tip_mm, tool_link, [robotN.tools] name = [x, y, z], [robotN.errors], [robotN.tolerance] joint_offset_deg, origin_mm, origin_deg, tip_mm, joint_scale, periodic_deg, [[robotN.couplings]] joint, terms = [{{ joint, c }}], offset_deg | offset_mm; [b1_from_b2] xyz_mm, zyz_deg, sigma_mm, sigma_deg (with [robot2] only); [noise] alignment_mm, repeatability_mm, encoder_resolution_deg; [teach] centre_mm)",
            e.message().trim_end()
        ))
    })?;
    let robot = |key: &str, r: &RobotFile| -> Result<CellRobot, FormatError> {
        let tool_link = r.tool_link.clone().unwrap_or_else(|| "tool0".into());
        let urdf_path = base_dir.join(&r.urdf);
        let mut model = load_model(&ctx, key, &r.urdf, &urdf_path, &tool_link, embedded)?;
        if let Some(c) = &r.couplings {
            model = apply_couplings(&ctx, key, model, c)?;
        }
        let errors = match &r.errors {
            Some(e) => build_errors(&ctx, key, &model, e)?,
            None => KinematicErrors::zero_for(&model),
        };
        let tolerance = match &r.tolerance {
            Some(t) => build_tolerance(&ctx, key, t)?,
            None => Tolerance::default(),
        };
        let mut tools = Vec::new();
        for (name, v) in r.tools.iter().flatten() {
            if name == TIP_TOOL || name.is_empty() || name.contains([',', ';', '\t', '"']) {
                return Err(ctx.err(format!(
                    "`{key}.tools.{name}`: a tool name must be non-empty, not `{TIP_TOOL}` (the name of tip_mm) \
                     and free of commas, semicolons, tabs and quotes; rename it (e.g. reflector)"
                )));
            }
            tools.push(Tool {
                name: name.clone(),
                flange_from_tip: tip3(&ctx, &format!("{key}.tools.{name}"), *v)? * 1e-3,
            });
        }
        Ok(CellRobot {
            mount: parse_mount(&ctx, &format!("{key}.mount"), &r.mount)?,
            tools,
            flange_from_tip: tip3(&ctx, &format!("{key}.tip_mm"), r.tip_mm)? * 1e-3,
            model,
            urdf: r.urdf.clone(),
            urdf_path,
            tool_link,
            g_base: Vector3::zeros(),
            errors,
            tolerance,
        })
    };
    if file.robot1.shares.is_some() {
        return Err(ctx.err(
            "`robot1.shares`: robot 1 defines the trunk; say `shares = { robot = 1, joints = k }` \
             in [robot2]",
        ));
    }
    let mut robot1 = robot("robot1", &file.robot1)?;
    let (placement, mut robot2, one_robot) = match (&file.robot2, &file.b1_from_b2) {
        (Some(r2), _) if r2.shares.is_some() => {
            if file.b1_from_b2.is_some() {
                return Err(ctx.err(
                        "`[b1_from_b2]` in a shared-trunk cell (`robot2.shares`): the placement between \
                         the arms is the trunk, not a free b1_from_b2; remove [b1_from_b2] (both \
                         arms' URDF chains start at the common base)",
                    ));
            }
            (&ONE_ROBOT_PLACEMENT, robot("robot2", r2)?, false)
        }
        (Some(r2), Some(placement)) => (placement, robot("robot2", r2)?, false),
        (None, None) => {
            // A one-robot cell: robot 2 is a stand-in nothing observes, held at nominal.
            let mut stand_in = robot1.clone();
            stand_in.tools.clear();
            stand_in.errors = KinematicErrors::zero_for(&stand_in.model);
            stand_in.tolerance = Tolerance::none();
            (&ONE_ROBOT_PLACEMENT, stand_in, true)
        }
        (None, Some(_)) => {
            return Err(ctx.err(
                "`[b1_from_b2]` without `[robot2]`: a one-robot cell has no placement; remove \
                 [b1_from_b2], or add [robot2] (urdf, mount, tip_mm) for a two-robot cell",
            ))
        }
        (Some(_), None) => {
            return Err(ctx.err(
                "`[robot2]` without `[b1_from_b2]`: a two-robot cell needs robot 2's placement \
                 (xyz_mm, zyz_deg); add [b1_from_b2], or remove [robot2] for a one-robot cell",
            ))
        }
    };
    let shared_joints = match file.robot2.as_ref().and_then(|r| r.shares.as_ref()) {
        Some(shares) => shared_trunk(&ctx, shares, &robot1, &mut robot2)?,
        None => 0,
    };
    finite3(&ctx, "b1_from_b2.xyz_mm", placement.xyz_mm)?;
    finite3(&ctx, "b1_from_b2.zyz_deg", placement.zyz_deg)?;
    let b1_from_b2 = PoseMmDeg {
        xyz_mm: placement.xyz_mm,
        zyz_deg: placement.zyz_deg,
    }
    .to_isometry();
    let b1_from_b2_sigma = match (placement.sigma_mm, placement.sigma_deg) {
        (None, None) => None,
        (Some(mm), Some(deg)) => {
            for (key, v) in [("sigma_mm", mm), ("sigma_deg", deg)] {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(ctx.err(format!(
                        "`b1_from_b2.{key}` = {v} must be a finite σ ≥ 0 (0 leaves that part free)"
                    )));
                }
            }
            Some(PlacementSigma {
                sigma_m: mm * 1e-3,
                sigma_rad: deg.to_radians(),
            })
        }
        _ => {
            return Err(ctx.err(
                "`[b1_from_b2]` gives only one of sigma_mm and sigma_deg; give both (a known placement) or neither (fitted freely)",
            ))
        }
    };

    // Gravity: robot 1's mount fixes the level frame; robot 2's follows from the placement.
    let level_from_b1 = robot1.mount.level_from_base().ok_or_else(|| {
        ctx.err(
            "`robot1.mount` = \"wall\": robot 1 defines the level frame, so its roll must be known; \
             use \"floor\", \"ceiling\" or { tilt_deg = [rx, ry] } (a wall with known roll is tilt_deg = [±90, ry])",
        )
    })?;
    let g_level = Vector3::new(0.0, 0.0, -G);
    robot1.g_base = level_from_b1.inverse() * g_level;
    robot2.g_base = b1_from_b2.rotation.inverse() * robot1.g_base;
    let up_b2 = -robot2.g_base / G;
    if mount_mismatch_deg(&robot2.mount, &up_b2) > MOUNT_TOLERANCE_DEG {
        return Err(ctx.err(format!(
            "`robot2.mount` = {} is impossible with [b1_from_b2] zyz_deg = {:?}: that placement puts robot 2's \
             up direction at ({:.3}, {:.3}, {:.3}) in its base frame; use mount = {} or change zyz_deg",
            mount_value(&robot2.mount),
            placement.zyz_deg,
            up_b2.x,
            up_b2.y,
            up_b2.z,
            mount_suggestion(&up_b2)
        )));
    }

    let noise = match &file.noise {
        None => Noise {
            alignment_m: Vector3::repeat(DEFAULT_ALIGNMENT_MM * 1e-3),
            repeatability_m: 0.0,
            encoder_resolution_rad: 0.0,
        },
        Some(n) => {
            let nonneg = |key: &str, v: f64| {
                if v.is_finite() && v >= 0.0 {
                    Ok(v)
                } else {
                    Err(ctx.err(format!("`noise.{key}` = {v} must be a finite σ ≥ 0")))
                }
            };
            let num = |v: &toml::Value| v.as_float().or_else(|| v.as_integer().map(|i| i as f64));
            let alignment_mm = match &n.alignment_mm {
                None => Vector3::repeat(DEFAULT_ALIGNMENT_MM),
                Some(toml::Value::Array(a)) => {
                    let v: Vec<f64> = a.iter().filter_map(num).collect();
                    if v.len() != 3 || a.len() != 3 {
                        return Err(ctx.err(
                            "`noise.alignment_mm` must be one σ (mm, isotropic) or [σx, σy, σz] (mm, b1 axes)",
                        ));
                    }
                    Vector3::new(
                        nonneg("alignment_mm", v[0])?,
                        nonneg("alignment_mm", v[1])?,
                        nonneg("alignment_mm", v[2])?,
                    )
                }
                Some(v) => Vector3::repeat(nonneg(
                    "alignment_mm",
                    num(v).ok_or_else(|| {
                        ctx.err("`noise.alignment_mm` must be one σ (mm) or [σx, σy, σz] (mm)")
                    })?,
                )?),
            };
            Noise {
                alignment_m: alignment_mm * 1e-3,
                repeatability_m: nonneg("repeatability_mm", n.repeatability_mm.unwrap_or(0.0))?
                    * 1e-3,
                encoder_resolution_rad: nonneg(
                    "encoder_resolution_deg",
                    n.encoder_resolution_deg.unwrap_or(0.0),
                )?
                .to_radians(),
            }
        }
    };
    let centre_b1 = match file.teach.as_ref().and_then(|t| t.centre_mm) {
        Some(c) => Point3::from(finite3(&ctx, "teach.centre_mm", c)? * 1e-3),
        None => {
            let s1 = shoulder(&robot1.model);
            let s2 = b1_from_b2 * shoulder(&robot2.model);
            Point3::from((s1.coords + s2.coords) / 2.0)
        }
    };
    Ok(Cell {
        base_dir: base_dir.to_path_buf(),
        robot1,
        robot2,
        b1_from_b2,
        b1_from_b2_sigma,
        noise,
        centre_b1,
        one_robot,
        shared_joints,
    })
}

/// The number of shared chain joints of `robot2.shares`, checked: robot 1's trunk, the same
/// joints at the start of both chains (names, kinds, origins, axes, limits, couplings over
/// shared joints only), the same mount; robot 2's errors at the shared joints (compliance
/// included: one joint, loaded by both arms) must be 0 or robot 1's, and become robot 1's.
fn shared_trunk(
    ctx: &Ctx,
    shares: &SharesFile,
    robot1: &CellRobot,
    robot2: &mut CellRobot,
) -> Result<usize, FormatError> {
    if shares.robot != 1 {
        return Err(ctx.err(format!(
            "`robot2.shares.robot` = {}: robot 2 can share robot 1's joints only; give robot = 1",
            shares.robot
        )));
    }
    let (c1, c2) = (robot1.model.chain_joints(), robot2.model.chain_joints());
    let k = match (&shares.joints, &shares.link) {
        (Some(k), None) => *k,
        (None, Some(link)) => match c1.iter().position(|j| j.child_link == *link) {
            Some(i) => i + 1,
            None => {
                return Err(ctx.err(format!(
                    "`robot2.shares.link` = \"{link}\" is not the child link of a moving joint on \
                     robot 1's chain ({}); name the link where the arms branch, or give joints = k",
                    c1.iter().map(|j| j.child_link.as_str()).collect::<Vec<_>>().join(", ")
                )))
            }
        },
        _ => {
            return Err(ctx.err(
                "`robot2.shares` needs one of joints = k (the first k chain joints) or link = \"name\" \
                 (the branch link), not both",
            ))
        }
    };
    if k == 0 || k >= c1.len() || k >= c2.len() {
        return Err(ctx.err(format!(
            "`robot2.shares.joints` = {k}: give 1 to {} (each arm keeps at least one joint of its own; \
             robot 1 has {} chain joints, robot 2 {})",
            c1.len().min(c2.len()).saturating_sub(1),
            c1.len(),
            c2.len()
        )));
    }
    for j in 0..k {
        let (a, b) = (&c1[j], &c2[j]);
        let what = if a.name != b.name {
            Some(format!("robot 1's is `{}`, robot 2's `{}`", a.name, b.name))
        } else if a.is_coupled() != b.is_coupled() || a.coupling != b.coupling {
            Some(format!(
                "it is coupled {}: declare the same [[robotN.couplings]] (or <mimic>) in both robots",
                if a.is_coupled() && !b.is_coupled() {
                    "in robot 1's chain and not in robot 2's"
                } else if b.is_coupled() && !a.is_coupled() {
                    "in robot 2's chain and not in robot 1's"
                } else {
                    "differently in the two robots"
                }
            ))
        } else if a != b {
            Some("its kind, origin, axis or limits differ between the two URDFs".into())
        } else {
            None
        };
        if let Some(what) = what {
            return Err(ctx.err(format!(
                "`robot2.shares`: shared joint {} (`{}`) is not the same joint in both robots: \
                 {what}; the first {k} chain joints must be the trunk in both chains",
                j + 1,
                a.name
            )));
        }
        if let Some(c) = &a.coupling {
            let shared_q = c1[..k].iter().filter(|j| !j.is_coupled()).count();
            if c.terms.iter().any(|&(i, _)| i >= shared_q) {
                return Err(ctx.err(format!(
                    "`robot2.shares`: shared joint `{}` follows a joint of robot 1's arm; a \
                     shared joint may follow shared joints only",
                    a.name
                )));
            }
        }
    }
    if robot1.mount != robot2.mount {
        return Err(ctx.err(format!(
            "`robot2.mount` = {} differs from robot 1's {}: in a shared-trunk cell both chains \
             start at the common base; give both the same mount",
            mount_value(&robot2.mount),
            mount_value(&robot1.mount)
        )));
    }
    let (e1, e2) = (&robot1.errors, &mut robot2.errors);
    #[allow(clippy::needless_range_loop)] // j indexes both robots' errors and robot 1's chain
    for j in 0..k {
        let pairs = [
            ("joint_offset", e1.joint_offset[j], &mut e2.joint_offset[j]),
            ("joint_scale", e1.joint_scale[j], &mut e2.joint_scale[j]),
            ("periodic_sin", e1.periodic_sin[j], &mut e2.periodic_sin[j]),
            ("periodic_cos", e1.periodic_cos[j], &mut e2.periodic_cos[j]),
            (
                "compliance_deg_per_knm",
                e1.compliance[j],
                &mut e2.compliance[j],
            ),
        ];
        for (field, v1, v2) in pairs {
            if *v2 != 0.0 && (*v2 - v1).abs() > 1e-12 * v1.abs().max(1e-9) {
                return Err(ctx.err(format!(
                    "`robot2.errors.{field}` at shared joint `{}` differs from robot 1's: a shared \
                     joint has one set of errors; give it in [robot1.errors] (0 or the same value here)",
                    c1[j].name
                )));
            }
            *v2 = v1;
        }
        for (field, v1, v2) in [
            ("origin_xyz_mm", e1.origin_xyz[j], &mut e2.origin_xyz[j]),
            ("origin_rpy_deg", e1.origin_rpy[j], &mut e2.origin_rpy[j]),
        ] {
            if *v2 != Vector3::zeros() && (*v2 - v1).norm() > 1e-12 * v1.norm().max(1e-9) {
                return Err(ctx.err(format!(
                    "`robot2.errors.{field}` at shared joint `{}` differs from robot 1's: a shared \
                     joint has one set of errors; give it in [robot1.errors] (0 or the same value here)",
                    c1[j].name
                )));
            }
            *v2 = v1;
        }
    }
    if e1.mount_xyz != e2.mount_xyz || e1.mount_rpy != e2.mount_rpy {
        return Err(ctx.err(
            "`[robotN.errors] mount_xyz_mm / mount_rpy_deg` differ between the robots of a \
             shared-trunk cell: they share one base; give the same mount errors (or none)",
        ));
    }
    Ok(k)
}

/// The `[b1_from_b2]` a one-robot cell stands in with: the identity, held by
/// [`ONE_ROBOT_PLACEMENT_SIGMA`].
const ONE_ROBOT_PLACEMENT: PlacementFile = PlacementFile {
    xyz_mm: [0.0; 3],
    zyz_deg: [0.0; 3],
    sigma_mm: Some(ONE_ROBOT_PLACEMENT_SIGMA.sigma_m * 1e3),
    sigma_deg: Some(1e-6 * 180.0 / std::f64::consts::PI),
};

/// Rotation of the level frame relative to base 1 (for callers that need it): `level_from_b1`.
pub fn level_from_b1(cell: &Cell) -> Option<Rotation3<f64>> {
    cell.robot1.mount.level_from_base()
}

#[cfg(test)]
mod tests;

//! The placement `b1_from_b2` (robot 2's base frame in robot 1's base frame) in each controller's
//! and ROS 2's own convention and file, written atomically and read back before it counts.
//! Used by `handclasp export`.
//!
//! 1. [`PlacementFormats::new`] converts the placement into each target's numbers (pure; the
//!    angle maths is [`kinematics::cardan`]): [`AbbBaseFrame`], [`KukaFrame`], [`FanucFrame`],
//!    [`YaskawaFrame`], [`Ros2Transform`]. Each has `placement()`, the inverse conversion.
//! 2. Each target's module renders its file(s) and parses them back: [`abb`], [`kuka`],
//!    [`fanuc`], [`yaskawa`], [`ros2`] (a cell URDF, xacro properties, a launch file). The module
//!    documentation of each cites the vendor's documentation for its convention.
//! 3. [`export_placement`] writes each file under a temporary name, parses what it wrote, checks
//!    it against the placement ([`READ_BACK_TOL_M`], [`READ_BACK_TOL_RAD`]; the cell URDF is
//!    loaded with [`kinematics::RobotModel`] and both chains compared) and only then renames it
//!    into place.
//!
//! The world of every target is robot 1's base: robot 1 keeps the identity placement and robot
//! 2's base is `b1_from_b2`. Files carry mm and degrees where the controller does (KUKA, Fanuc,
//! Yaskawa), metres and a quaternion where it does (ABB MOC.cfg, ROS), each named in the file's
//! opening comment.

pub mod abb;
pub mod fanuc;
pub mod kuka;
pub mod ros2;
pub mod yaskawa;

use std::path::{Path, PathBuf};

use calib_core::Robot;
use kinematics::{
    quaternion_wxyz, rotation_from_quaternion_wxyz, rotation_from_zyx, zyx_from_rotation,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::cell::Cell;
use crate::error::FormatError;

/// Largest translation difference, m, between a file read back and the placement (1 µm).
pub const READ_BACK_TOL_M: f64 = 1e-6;
/// Largest rotation difference, rad, between a file read back and the placement (1 µrad).
pub const READ_BACK_TOL_RAD: f64 = 1e-6;

/// Decimals of millimetres in the files (1 nm), far below [`READ_BACK_TOL_M`].
const MM_DECIMALS: usize = 6;
/// Decimals of metres in the files (1 nm).
const M_DECIMALS: usize = 9;
/// Decimals of degrees in the files (1e-9° = 1.7e-11 rad).
const DEG_DECIMALS: usize = 9;
/// Decimals of quaternion components and radians in the files (1e-12).
const UNIT_DECIMALS: usize = 12;

/// An export target.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum ControllerFormat {
    /// ABB MultiMove: the ROB_2 base frame of MOC.cfg ([`abb`]).
    Abb,
    /// KUKA: `$ROBROOT` / `BASE_DATA` frame ([`kuka`]).
    Kuka,
    /// Fanuc: a user frame of robot 1 ([`fanuc`]).
    Fanuc,
    /// Yaskawa Motoman: a user frame of robot 1 ([`yaskawa`]).
    Yaskawa,
    /// ROS 2: cell URDF, xacro properties, static transform launch file ([`ros2`]).
    Ros2,
}

impl ControllerFormat {
    /// Every target, in the order files and reports list them.
    pub const ALL: [ControllerFormat; 5] = [
        ControllerFormat::Abb,
        ControllerFormat::Kuka,
        ControllerFormat::Fanuc,
        ControllerFormat::Yaskawa,
        ControllerFormat::Ros2,
    ];

    /// The name on the command line and in JSON (`abb`, `kuka`, `fanuc`, `yaskawa`, `ros2`).
    pub fn name(self) -> &'static str {
        match self {
            ControllerFormat::Abb => "abb",
            ControllerFormat::Kuka => "kuka",
            ControllerFormat::Fanuc => "fanuc",
            ControllerFormat::Yaskawa => "yaskawa",
            ControllerFormat::Ros2 => "ros2",
        }
    }

    /// The target named `name` (case-insensitive), `None` for an unknown name.
    pub fn from_name(name: &str) -> Option<ControllerFormat> {
        Self::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name.trim()))
    }

    /// The files this target writes, relative to the export folder.
    pub fn files(self) -> &'static [&'static str] {
        match self {
            ControllerFormat::Abb => &[abb::FILE],
            ControllerFormat::Kuka => &[kuka::FILE],
            ControllerFormat::Fanuc => &[fanuc::FILE],
            ControllerFormat::Yaskawa => &[yaskawa::FILE],
            ControllerFormat::Ros2 => &[ros2::URDF_FILE, ros2::XACRO_FILE, ros2::LAUNCH_FILE],
        }
    }
}

/// ABB base frame: position in metres, orientation `q1..q4 = w, x, y, z` with `q1 ≥ 0`
/// (see [`abb`] for the sources).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct AbbBaseFrame {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
    /// z, m.
    pub z_m: f64,
    /// Quaternion scalar part `w` (≥ 0).
    pub q1: f64,
    /// Quaternion `x`.
    pub q2: f64,
    /// Quaternion `y`.
    pub q3: f64,
    /// Quaternion `z`.
    pub q4: f64,
}

/// KUKA frame: X, Y, Z in mm, A, B, C in degrees, `R = Rz(A)·Ry(B)·Rx(C)` (see [`kuka`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KukaFrame {
    /// X, mm.
    pub x_mm: f64,
    /// Y, mm.
    pub y_mm: f64,
    /// Z, mm.
    pub z_mm: f64,
    /// A (about z), degrees.
    pub a_deg: f64,
    /// B (about y'), degrees, in [−90, 90].
    pub b_deg: f64,
    /// C (about x''), degrees; 0 at B = ±90° (the canonical choice of [`kinematics::cardan`]).
    pub c_deg: f64,
}

/// Fanuc frame: X, Y, Z in mm, W, P, R in degrees about the fixed x, y, z axes,
/// `R = Rz(R)·Ry(P)·Rx(W)` (see [`fanuc`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FanucFrame {
    /// X, mm.
    pub x_mm: f64,
    /// Y, mm.
    pub y_mm: f64,
    /// Z, mm.
    pub z_mm: f64,
    /// W (about fixed x, applied first), degrees; 0 at P = ±90°.
    pub w_deg: f64,
    /// P (about fixed y), degrees, in [−90, 90].
    pub p_deg: f64,
    /// R (about fixed z, applied last), degrees.
    pub r_deg: f64,
}

/// Yaskawa frame: X, Y, Z in mm, Rx, Ry, Rz in degrees about the fixed x, y, z axes,
/// `R = Rz(Rz)·Ry(Ry)·Rx(Rx)` (see [`yaskawa`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct YaskawaFrame {
    /// X, mm.
    pub x_mm: f64,
    /// Y, mm.
    pub y_mm: f64,
    /// Z, mm.
    pub z_mm: f64,
    /// Rx (about fixed x, applied first), degrees; 0 at Ry = ±90°.
    pub rx_deg: f64,
    /// Ry (about fixed y), degrees, in [−90, 90].
    pub ry_deg: f64,
    /// Rz (about fixed z, applied last), degrees.
    pub rz_deg: f64,
}

/// ROS 2 transform (`geometry_msgs/Transform`, tf2): translation in metres, unit quaternion listed
/// `x, y, z, w` with `w ≥ 0` (see [`ros2`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Ros2Transform {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
    /// z, m.
    pub z_m: f64,
    /// Quaternion `x`.
    pub qx: f64,
    /// Quaternion `y`.
    pub qy: f64,
    /// Quaternion `z`.
    pub qz: f64,
    /// Quaternion scalar part `w` (≥ 0).
    pub qw: f64,
}

/// Translation in mm and Z-Y-X angles `[a, b, c]` in degrees of `b1_from_b2`.
fn mm_and_zyx_deg(b1_from_b2: &Isometry3<f64>) -> ([f64; 3], [f64; 3]) {
    let t = b1_from_b2.translation.vector * 1e3;
    let zyx = zyx_from_rotation(&b1_from_b2.rotation.to_rotation_matrix());
    ([t.x, t.y, t.z], zyx.map(f64::to_degrees))
}

/// The isometry of a translation in mm and Z-Y-X angles `[a, b, c]` in degrees.
fn from_mm_and_zyx_deg(xyz_mm: [f64; 3], zyx_deg: [f64; 3]) -> Isometry3<f64> {
    let r = rotation_from_zyx(zyx_deg.map(f64::to_radians));
    Isometry3::from_parts(
        Translation3::from(Vector3::from(xyz_mm) * 1e-3),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// The isometry of a translation in m and a quaternion `[w, x, y, z]`; `None` if the quaternion's
/// norm is not within 1e-9 of 1 (a file's quaternion is written to 12 decimals).
fn from_m_and_wxyz(xyz_m: [f64; 3], wxyz: [f64; 4]) -> Option<Isometry3<f64>> {
    let norm = wxyz.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > 1e-9 {
        return None;
    }
    let r = rotation_from_quaternion_wxyz(wxyz)?;
    Some(Isometry3::from_parts(
        Translation3::from(Vector3::from(xyz_m)),
        UnitQuaternion::from_rotation_matrix(&r),
    ))
}

impl AbbBaseFrame {
    /// The ABB numbers of `b1_from_b2`.
    pub fn from_placement(b1_from_b2: &Isometry3<f64>) -> Self {
        let t = b1_from_b2.translation.vector;
        let [q1, q2, q3, q4] = quaternion_wxyz(&b1_from_b2.rotation.to_rotation_matrix());
        AbbBaseFrame {
            x_m: t.x,
            y_m: t.y,
            z_m: t.z,
            q1,
            q2,
            q3,
            q4,
        }
    }

    /// The placement these numbers stand for; `None` if the quaternion is not unit (±1e-9).
    pub fn placement(&self) -> Option<Isometry3<f64>> {
        from_m_and_wxyz(
            [self.x_m, self.y_m, self.z_m],
            [self.q1, self.q2, self.q3, self.q4],
        )
    }
}

impl KukaFrame {
    /// The frame of its six numbers in the file's order: X, Y, Z (mm), A, B, C (deg).
    pub fn from_listed([x_mm, y_mm, z_mm, a_deg, b_deg, c_deg]: [f64; 6]) -> Self {
        KukaFrame {
            x_mm,
            y_mm,
            z_mm,
            a_deg,
            b_deg,
            c_deg,
        }
    }

    /// The KUKA numbers of `b1_from_b2`.
    pub fn from_placement(b1_from_b2: &Isometry3<f64>) -> Self {
        let ([x, y, z], [a, b, c]) = mm_and_zyx_deg(b1_from_b2);
        Self::from_listed([x, y, z, a, b, c])
    }

    /// The placement these numbers stand for.
    pub fn placement(&self) -> Isometry3<f64> {
        from_mm_and_zyx_deg(
            [self.x_mm, self.y_mm, self.z_mm],
            [self.a_deg, self.b_deg, self.c_deg],
        )
    }
}

impl FanucFrame {
    /// The frame of its six numbers in the file's order: X, Y, Z (mm), W, P, R (deg).
    pub fn from_listed([x_mm, y_mm, z_mm, w_deg, p_deg, r_deg]: [f64; 6]) -> Self {
        FanucFrame {
            x_mm,
            y_mm,
            z_mm,
            w_deg,
            p_deg,
            r_deg,
        }
    }

    /// The Fanuc numbers of `b1_from_b2`.
    pub fn from_placement(b1_from_b2: &Isometry3<f64>) -> Self {
        let ([x, y, z], [r, p, w]) = mm_and_zyx_deg(b1_from_b2);
        Self::from_listed([x, y, z, w, p, r])
    }

    /// The placement these numbers stand for.
    pub fn placement(&self) -> Isometry3<f64> {
        from_mm_and_zyx_deg(
            [self.x_mm, self.y_mm, self.z_mm],
            [self.r_deg, self.p_deg, self.w_deg],
        )
    }
}

impl YaskawaFrame {
    /// The frame of its six numbers in the file's order: X, Y, Z (mm), Rx, Ry, Rz (deg).
    pub fn from_listed([x_mm, y_mm, z_mm, rx_deg, ry_deg, rz_deg]: [f64; 6]) -> Self {
        YaskawaFrame {
            x_mm,
            y_mm,
            z_mm,
            rx_deg,
            ry_deg,
            rz_deg,
        }
    }

    /// The Yaskawa numbers of `b1_from_b2`.
    pub fn from_placement(b1_from_b2: &Isometry3<f64>) -> Self {
        let ([x, y, z], [rz, ry, rx]) = mm_and_zyx_deg(b1_from_b2);
        Self::from_listed([x, y, z, rx, ry, rz])
    }

    /// The placement these numbers stand for.
    pub fn placement(&self) -> Isometry3<f64> {
        from_mm_and_zyx_deg(
            [self.x_mm, self.y_mm, self.z_mm],
            [self.rz_deg, self.ry_deg, self.rx_deg],
        )
    }
}

impl Ros2Transform {
    /// The ROS 2 numbers of `b1_from_b2`.
    pub fn from_placement(b1_from_b2: &Isometry3<f64>) -> Self {
        let t = b1_from_b2.translation.vector;
        let [qw, qx, qy, qz] = quaternion_wxyz(&b1_from_b2.rotation.to_rotation_matrix());
        Ros2Transform {
            x_m: t.x,
            y_m: t.y,
            z_m: t.z,
            qx,
            qy,
            qz,
            qw,
        }
    }

    /// The placement these numbers stand for; `None` if the quaternion is not unit (±1e-9).
    pub fn placement(&self) -> Option<Isometry3<f64>> {
        from_m_and_wxyz(
            [self.x_m, self.y_m, self.z_m],
            [self.qw, self.qx, self.qy, self.qz],
        )
    }
}

/// The placement in the conventions asked for (`None` for the others), as JSON writes it:
/// `{"abb": {...}, "kuka": {...}, ...}`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlacementFormats {
    /// ABB.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub abb: Option<AbbBaseFrame>,
    /// KUKA.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kuka: Option<KukaFrame>,
    /// Fanuc.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fanuc: Option<FanucFrame>,
    /// Yaskawa.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub yaskawa: Option<YaskawaFrame>,
    /// ROS 2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ros2: Option<Ros2Transform>,
}

impl PlacementFormats {
    /// `b1_from_b2` in each of `formats`.
    pub fn new(b1_from_b2: &Isometry3<f64>, formats: &[ControllerFormat]) -> Self {
        let has = |f| formats.contains(&f);
        PlacementFormats {
            abb: has(ControllerFormat::Abb).then(|| AbbBaseFrame::from_placement(b1_from_b2)),
            kuka: has(ControllerFormat::Kuka).then(|| KukaFrame::from_placement(b1_from_b2)),
            fanuc: has(ControllerFormat::Fanuc).then(|| FanucFrame::from_placement(b1_from_b2)),
            yaskawa: has(ControllerFormat::Yaskawa)
                .then(|| YaskawaFrame::from_placement(b1_from_b2)),
            ros2: has(ControllerFormat::Ros2).then(|| Ros2Transform::from_placement(b1_from_b2)),
        }
    }
}

/// One file [`export_placement`] wrote, with what reading it back measured.
#[derive(Debug, Clone, PartialEq)]
pub struct WrittenFile {
    /// The file.
    pub path: PathBuf,
    /// The target it belongs to.
    pub format: ControllerFormat,
    /// Largest translation difference between the file read back and the placement, m (for the
    /// cell URDF also between its chains and the cell's models).
    pub translation_error_m: f64,
    /// Largest rotation difference, rad (same comparisons).
    pub rotation_error_rad: f64,
}

/// What [`export_placement`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacementExport {
    /// The numbers, per target asked for.
    pub formats: PlacementFormats,
    /// The files, in target order.
    pub files: Vec<WrittenFile>,
    /// Things the files cannot carry, one sentence each (the CLI prints them as `warning:`).
    pub warnings: Vec<String>,
}

/// What a written file reads back as: the largest translation (m) and rotation (rad) differences
/// to what it should hold.
pub(crate) struct Deviation {
    pub(crate) translation_m: f64,
    pub(crate) rotation_rad: f64,
}

impl Deviation {
    pub(crate) fn between(expected: &Isometry3<f64>, read: &Isometry3<f64>) -> Deviation {
        Deviation {
            translation_m: (read.translation.vector - expected.translation.vector).norm(),
            rotation_rad: expected.rotation.angle_to(&read.rotation),
        }
    }

    pub(crate) fn max(self, other: Deviation) -> Deviation {
        Deviation {
            translation_m: self.translation_m.max(other.translation_m),
            rotation_rad: self.rotation_rad.max(other.rotation_rad),
        }
    }
}

/// Writes `b1_from_b2` of `cell` in each of `formats` into `dir` (created if missing; files of
/// the same names are replaced: the caller decides whether `dir` may hold files, see the CLI's
/// `--force`). `source` names the cell in each file's opening comment.
///
/// Each file is written under `NAME.tmp`, read back and parsed by its target's parser, compared
/// with the placement (≤ [`READ_BACK_TOL_M`], ≤ [`READ_BACK_TOL_RAD`]; the cell URDF: both chains
/// loaded by [`kinematics::RobotModel`] and compared with the cell's models, see [`ros2`]) and
/// only then renamed to `NAME`. On any failure the temporary file is removed and nothing of that
/// file is left in place.
///
/// Errors: a one-robot cell ([`FormatError::Cell`]: it has no `b1_from_b2`; its calibrated robot
/// is the corrected URDF `calibrate --cell --export` writes); a file that cannot be written
/// ([`FormatError::Io`]); a robot URDF the cell URDF cannot be built from ([`FormatError::Cell`]); a file that does not read back to the placement
/// ([`FormatError::Export`]: a defect of this crate, never expected).
pub fn export_placement(
    cell: &Cell,
    source: &str,
    dir: &Path,
    formats: &[ControllerFormat],
) -> Result<PlacementExport, FormatError> {
    if cell.one_robot {
        return Err(FormatError::Cell {
            path: PathBuf::from(source),
            message: "a one-robot cell (no [robot2]) has no b1_from_b2 (robot 2's base in robot \
                      1's) to export: its calibrated robot is the corrected URDF that \
                      `calibrate --cell … --export DIR` writes (DIR/robot1.urdf); export a \
                      two-robot cell"
                .into(),
        });
    }
    std::fs::create_dir_all(dir).map_err(|e| FormatError::io(dir, e))?;
    let b1_from_b2 = cell.b1_from_b2;
    let values = PlacementFormats::new(&b1_from_b2, formats);
    let mut files = Vec::new();
    let mut warnings = Vec::new();
    let header = Header { source };
    for format in ControllerFormat::ALL {
        if !formats.contains(&format) {
            continue;
        }
        let mut put =
            |name: &str, text: String, check: &dyn Fn(&str) -> Result<Deviation, String>| {
                write_checked(&dir.join(name), format, &text, check).map(|f| files.push(f))
            };
        let placement_check = |read: Result<Isometry3<f64>, String>| {
            read.map(|p| Deviation::between(&b1_from_b2, &p))
        };
        match format {
            ControllerFormat::Abb => {
                let v = values.abb.expect("asked for");
                put(abb::FILE, abb::render(&v, &header), &|t| {
                    placement_check(abb::parse(t))
                })?;
            }
            ControllerFormat::Kuka => {
                let v = values.kuka.expect("asked for");
                put(kuka::FILE, kuka::render(&v, &header), &|t| {
                    placement_check(kuka::parse(t))
                })?;
            }
            ControllerFormat::Fanuc => {
                let v = values.fanuc.expect("asked for");
                put(fanuc::FILE, fanuc::render(&v, &header), &|t| {
                    placement_check(fanuc::parse(t))
                })?;
            }
            ControllerFormat::Yaskawa => {
                let v = values.yaskawa.expect("asked for");
                put(yaskawa::FILE, yaskawa::render(&v, &header), &|t| {
                    placement_check(yaskawa::parse(t))
                })?;
            }
            ControllerFormat::Ros2 => {
                let v = values.ros2.expect("asked for");
                let urdf = ros2::cell_urdf(cell, &header)?;
                put(ros2::URDF_FILE, urdf, &|t| ros2::check_cell_urdf(t, cell))?;
                put(
                    ros2::XACRO_FILE,
                    ros2::render_xacro(&b1_from_b2, &header),
                    &|t| placement_check(ros2::parse_xacro(t)),
                )?;
                let (parent, child) = (
                    ros2::base_frame(cell, Robot::One),
                    ros2::base_frame(cell, Robot::Two),
                );
                put(
                    ros2::LAUNCH_FILE,
                    ros2::render_launch(&v, &parent, &child, &header),
                    &|t| placement_check(ros2::parse_launch(t)),
                )?;
                warnings.extend(ros2::unexpressed_errors(cell));
            }
        }
    }
    Ok(PlacementExport {
        formats: values,
        files,
        warnings,
    })
}

/// What every file's opening comment says besides its convention.
pub(crate) struct Header<'a> {
    /// The cell, as the user named it.
    pub(crate) source: &'a str,
}

impl Header<'_> {
    /// The common opening lines, each prefixed by `comment` (e.g. `"# "`).
    pub(crate) fn lines(&self, comment: &str, convention: &[&str]) -> String {
        let mut s = format!(
            "{comment}handclasp export: robot 2's base frame in robot 1's base frame (b1_from_b2), from the cell\n\
             {comment}{}\n",
            self.source
        );
        for line in convention {
            s.push_str(comment);
            s.push_str(line);
            s.push('\n');
        }
        s
    }
}

/// `x` with `decimals` decimals, never `-0.000…`.
pub(crate) fn fixed(x: f64, decimals: usize) -> String {
    let s = format!("{x:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_string()
    } else {
        s
    }
}

/// Millimetres as files write them.
pub(crate) fn mm(x: f64) -> String {
    fixed(x, MM_DECIMALS)
}

/// Metres as files write them.
pub(crate) fn metres(x: f64) -> String {
    fixed(x, M_DECIMALS)
}

/// Degrees as files write them.
pub(crate) fn deg(x: f64) -> String {
    fixed(x, DEG_DECIMALS)
}

/// Quaternion components and radians as files write them.
pub(crate) fn unit(x: f64) -> String {
    fixed(x, UNIT_DECIMALS)
}

/// A finite number from a file's text; the error names `what`.
pub(crate) fn number(text: &str, what: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{what}: `{}` is not a finite number", text.trim())),
    }
}

/// A pendant listing: one `KEY: value unit` line per entry, keys padded to one width.
pub(crate) fn listing(rows: &[(&str, String, &str)]) -> String {
    let width = rows.iter().map(|(k, _, _)| k.len()).max().unwrap_or(0);
    rows.iter()
        .map(|(k, v, u)| format!("{k:<width$}: {v:>20} {u}\n"))
        .collect()
}

/// The values of `keys` (in that order) from a listing written by [`listing`]; lines starting
/// with `comment` are skipped, keys match case-sensitively (`R` and `Rx` differ).
pub(crate) fn parse_listing<const N: usize>(
    text: &str,
    comment: &str,
    keys: [&str; N],
) -> Result<[f64; N], String> {
    let mut values = [None; N];
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with(comment) {
            continue;
        }
        let Some((key, rest)) = line.split_once(':') else {
            continue;
        };
        if let Some(k) = keys.iter().position(|k| *k == key.trim()) {
            let value = rest.split_whitespace().next().unwrap_or("");
            values[k] = Some(number(value, keys[k])?);
        }
    }
    let mut out = [0.0; N];
    for (k, v) in values.iter().enumerate() {
        out[k] = v.ok_or_else(|| format!("no `{}:` line", keys[k]))?;
    }
    Ok(out)
}

/// Writes `text` to `path` through `path.tmp`, checks it with `check` against the tolerances and
/// renames it into place.
fn write_checked(
    path: &Path,
    format: ControllerFormat,
    text: &str,
    check: &dyn Fn(&str) -> Result<Deviation, String>,
) -> Result<WrittenFile, FormatError> {
    let mut tmp_name = path.as_os_str().to_owned();
    tmp_name.push(".tmp");
    let tmp = PathBuf::from(tmp_name);
    let fail = |message: String| {
        let _ = std::fs::remove_file(&tmp);
        FormatError::Export {
            path: path.to_path_buf(),
            message,
        }
    };
    std::fs::write(&tmp, text).map_err(|e| FormatError::io(&tmp, e))?;
    let reread = std::fs::read_to_string(&tmp).map_err(|e| FormatError::io(&tmp, e))?;
    let dev = check(&reread).map_err(|m| fail(format!("reading the file back: {m}")))?;
    if !(dev.translation_m <= READ_BACK_TOL_M && dev.rotation_rad <= READ_BACK_TOL_RAD) {
        return Err(fail(format!(
            "reads back {:.3e} m / {:.3e} rad away from the placement (allowed {READ_BACK_TOL_M:e} m, \
             {READ_BACK_TOL_RAD:e} rad); not written",
            dev.translation_m, dev.rotation_rad
        )));
    }
    std::fs::rename(&tmp, path).map_err(|e| FormatError::io(path, e))?;
    Ok(WrittenFile {
        path: path.to_path_buf(),
        format,
        translation_error_m: dev.translation_m,
        rotation_error_rad: dev.rotation_rad,
    })
}

/// Robot 1 and robot 2 with their placement in the cell's world (robot 1's base).
pub(crate) fn robots_in_world(cell: &Cell) -> [(Robot, Isometry3<f64>); 2] {
    [
        (Robot::One, Isometry3::identity()),
        (Robot::Two, cell.b1_from_b2),
    ]
}

#[cfg(test)]
mod tests;

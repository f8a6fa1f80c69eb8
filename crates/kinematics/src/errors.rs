//! The kinematic-error model: the one source of truth for simulating a "true" robot that differs
//! from its nominal URDF, and for identifying those differences.
//!
//! For a reported (controller) joint vector `q_rep` (rad) the TRUE robot is the nominal chain with:
//! - joint angles `q_true_i = q_rep_i·(1 + joint_scale_i) + joint_offset_i + compliance_i·τ_i(q_rep)`,
//!   `τ` the gravity torques of the NOMINAL model at the commanded posture `q_rep`
//!   ([`gravity_torques`](crate::gravity_torques), N·m);
//! - joint `k`'s URDF origin `xyz + origin_xyz_k` (m, parent link frame) and `rpy + origin_rpy_k`
//!   (rad, `Rz(yaw)·Ry(pitch)·Rx(roll)`);
//! - the tip offset `flange_from_tip + tip` (m, flange = `tool0` axes);
//! - the true base at `nominal_base_from_base = (mount_xyz, Rz·Ry·Rx(mount_rpy))` in the NOMINAL
//!   base frame.
//!
//! [`true_base_from_tip`] gives the true tip pose in the nominal base frame and
//! [`tip_error_jacobian`] its exact analytic derivatives with respect to any [`ErrorParam`], at any
//! error values (not only at zero).

use std::fmt;

use nalgebra::{Isometry3, Matrix3, Matrix3xX, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::KinematicsError;
use crate::fk::{
    apply_step, base_from_tip_unchecked, check_tip, isometry, sin_cos, tip_isometry,
    to_flange_nalgebra,
};
use crate::gravity::{
    check_gravity, gravity_entries, gravity_jacobian_from_entries, gravity_torques_into,
    GravityEntry, STACK_DOF,
};
use crate::model::{origin_isometry, RobotModel, Step};

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
}

impl Axis {
    /// The three axes in order x, y, z.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The unit vector along the axis.
    pub fn unit(self) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        v[self.index()] = 1.0;
        v
    }

    /// `"x"`, `"y"` or `"z"`.
    pub fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }

    /// 0, 1 or 2 (the component index).
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Deviations of a real robot from its nominal URDF model (see the module documentation for how
/// each one enters the kinematics). Per-joint vectors have one entry per actuated joint, in chain
/// order (0-based). [`KinematicErrors::zero`] is the nominal robot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KinematicErrors {
    /// Joint zero offsets, rad: added to the scaled reported angle.
    pub joint_offset: Vec<f64>,
    /// Joint scale (gear-ratio) errors, ratio: `q_true = q_rep·(1 + scale) + …`.
    pub joint_scale: Vec<f64>,
    /// Added to joint k's URDF `<origin xyz>`, m, in the joint's parent link frame.
    pub origin_xyz: Vec<Vector3<f64>>,
    /// Added to joint k's URDF `<origin rpy>` (roll, pitch, yaw), rad.
    pub origin_rpy: Vec<Vector3<f64>>,
    /// Added to the tip offset `flange_from_tip`, m, flange (`tool0`) axes.
    pub tip: Vector3<f64>,
    /// Origin of the true base in the nominal base frame, m.
    pub mount_xyz: Vector3<f64>,
    /// Orientation of the true base in the nominal base frame, (roll, pitch, yaw) rad,
    /// `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    pub mount_rpy: Vector3<f64>,
    /// Joint compliance, rad/(N·m): the joint deflects by `compliance_i·τ_i` under the gravity
    /// torque `τ_i` of the nominal model at the reported posture.
    pub compliance: Vec<f64>,
}

impl KinematicErrors {
    /// No errors (the nominal robot) for a chain of `dof` actuated joints.
    pub fn zero(dof: usize) -> Self {
        Self {
            joint_offset: vec![0.0; dof],
            joint_scale: vec![0.0; dof],
            origin_xyz: vec![Vector3::zeros(); dof],
            origin_rpy: vec![Vector3::zeros(); dof],
            tip: Vector3::zeros(),
            mount_xyz: Vector3::zeros(),
            mount_rpy: Vector3::zeros(),
            compliance: vec![0.0; dof],
        }
    }

    /// Number of joints (the length of `joint_offset`).
    pub fn dof(&self) -> usize {
        self.joint_offset.len()
    }

    /// True if every value is exactly zero (the nominal robot).
    pub fn is_zero(&self) -> bool {
        let z = |v: &[f64]| v.iter().all(|&x| x == 0.0);
        let z3 = |v: &[Vector3<f64>]| v.iter().all(|x| x.iter().all(|&c| c == 0.0));
        z(&self.joint_offset)
            && z(&self.joint_scale)
            && z3(&self.origin_xyz)
            && z3(&self.origin_rpy)
            && z(self.tip.as_slice())
            && z(self.mount_xyz.as_slice())
            && z(self.mount_rpy.as_slice())
            && z(&self.compliance)
    }

    /// Checks the errors against a model: every per-joint vector has `model.dof()` entries and all
    /// values are finite. Errors name the field and the (1-based) joint.
    pub fn check(&self, model: &RobotModel) -> Result<(), KinematicsError> {
        let n = model.dof();
        let lens = [
            ("joint_offset", self.joint_offset.len()),
            ("joint_scale", self.joint_scale.len()),
            ("origin_xyz", self.origin_xyz.len()),
            ("origin_rpy", self.origin_rpy.len()),
            ("compliance", self.compliance.len()),
        ];
        for (field, len) in lens {
            if len != n {
                return Err(KinematicsError::InvalidInput(format!(
                    "kinematic errors: `{field}` has {len} entries but {} has {n} joints; give one \
                     value per joint (KinematicErrors::zero({n}) has the right shape)",
                    model.name()
                )));
            }
        }
        let bad = |field: &str, joint: Option<usize>, v: f64| {
            let at = joint.map_or(String::new(), |j| {
                format!(" of joint {} ({})", j + 1, model.joints()[j].name)
            });
            KinematicsError::InvalidInput(format!(
                "kinematic errors: `{field}`{at} is {v}, not a finite number; give finite values"
            ))
        };
        for j in 0..n {
            for (field, v) in [
                ("joint_offset", self.joint_offset[j]),
                ("joint_scale", self.joint_scale[j]),
                ("compliance", self.compliance[j]),
            ] {
                if !v.is_finite() {
                    return Err(bad(field, Some(j), v));
                }
            }
            for (field, v) in [
                ("origin_xyz", &self.origin_xyz[j]),
                ("origin_rpy", &self.origin_rpy[j]),
            ] {
                if let Some(&x) = v.iter().find(|x| !x.is_finite()) {
                    return Err(bad(field, Some(j), x));
                }
            }
        }
        for (field, v) in [
            ("tip", &self.tip),
            ("mount_xyz", &self.mount_xyz),
            ("mount_rpy", &self.mount_rpy),
        ] {
            if let Some(&x) = v.iter().find(|x| !x.is_finite()) {
                return Err(bad(field, None, x));
            }
        }
        Ok(())
    }

    /// The value of one parameter, in its SI unit ([`ErrorParam::unit_si`]).
    ///
    /// Panics if the parameter's joint index is `≥ self.dof()` (a programming error, like slice
    /// indexing); use [`KinematicErrors::try_get`] for indices that come from input.
    pub fn get(&self, p: ErrorParam) -> f64 {
        match p {
            ErrorParam::JointOffset { joint } => self.joint_offset[joint],
            ErrorParam::JointScale { joint } => self.joint_scale[joint],
            ErrorParam::OriginXyz { joint, axis } => self.origin_xyz[joint][axis.index()],
            ErrorParam::OriginRpy { joint, axis } => self.origin_rpy[joint][axis.index()],
            ErrorParam::Tip { axis } => self.tip[axis.index()],
            ErrorParam::MountXyz { axis } => self.mount_xyz[axis.index()],
            ErrorParam::MountRpy { axis } => self.mount_rpy[axis.index()],
            ErrorParam::Compliance { joint } => self.compliance[joint],
        }
    }

    /// Sets one parameter to `v`, in its SI unit ([`ErrorParam::unit_si`]).
    ///
    /// Panics if the parameter's joint index is `≥ self.dof()`; see [`KinematicErrors::try_set`].
    pub fn set(&mut self, p: ErrorParam, v: f64) {
        *self.slot(p) = v;
    }

    /// [`KinematicErrors::get`] with the joint index checked: `None` if it is out of range.
    pub fn try_get(&self, p: ErrorParam) -> Option<f64> {
        match p.joint() {
            Some(j) if j >= self.dof() => None,
            _ => Some(self.get(p)),
        }
    }

    /// [`KinematicErrors::set`] with the joint index checked.
    ///
    /// Errors: the joint index is `≥ self.dof()`.
    pub fn try_set(&mut self, p: ErrorParam, v: f64) -> Result<(), KinematicsError> {
        p.check_dof(self.dof())?;
        self.set(p, v);
        Ok(())
    }

    /// Adds `v` to one parameter (panics like [`KinematicErrors::set`]).
    pub fn add(&mut self, p: ErrorParam, v: f64) {
        *self.slot(p) += v;
    }

    fn slot(&mut self, p: ErrorParam) -> &mut f64 {
        match p {
            ErrorParam::JointOffset { joint } => &mut self.joint_offset[joint],
            ErrorParam::JointScale { joint } => &mut self.joint_scale[joint],
            ErrorParam::OriginXyz { joint, axis } => &mut self.origin_xyz[joint][axis.index()],
            ErrorParam::OriginRpy { joint, axis } => &mut self.origin_rpy[joint][axis.index()],
            ErrorParam::Tip { axis } => &mut self.tip[axis.index()],
            ErrorParam::MountXyz { axis } => &mut self.mount_xyz[axis.index()],
            ErrorParam::MountRpy { axis } => &mut self.mount_rpy[axis.index()],
            ErrorParam::Compliance { joint } => &mut self.compliance[joint],
        }
    }

    /// The transform `nominal_base_from_base` of the mount error:
    /// `(mount_xyz, Rz·Ry·Rx(mount_rpy))`.
    pub fn nominal_base_from_base(&self) -> Isometry3<f64> {
        origin_isometry(&self.mount_xyz, &self.mount_rpy)
    }
}

/// One scalar parameter of [`KinematicErrors`]. Joint indices are 0-based (displayed 1-based).
///
/// Serialized as `{"kind": "origin_xyz", "joint": 1, "axis": "x"}`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ErrorParam {
    /// `joint_offset[joint]`, rad.
    JointOffset {
        /// 0-based joint index.
        joint: usize,
    },
    /// `joint_scale[joint]`, ratio.
    JointScale {
        /// 0-based joint index.
        joint: usize,
    },
    /// `origin_xyz[joint][axis]`, m.
    OriginXyz {
        /// 0-based joint index.
        joint: usize,
        /// Component (parent link frame).
        axis: Axis,
    },
    /// `origin_rpy[joint][axis]`, rad: `X` = roll, `Y` = pitch, `Z` = yaw.
    OriginRpy {
        /// 0-based joint index.
        joint: usize,
        /// `X` = roll, `Y` = pitch, `Z` = yaw.
        axis: Axis,
    },
    /// `tip[axis]`, m (flange axes).
    Tip {
        /// Component (flange frame).
        axis: Axis,
    },
    /// `mount_xyz[axis]`, m (nominal base axes).
    MountXyz {
        /// Component (nominal base frame).
        axis: Axis,
    },
    /// `mount_rpy[axis]`, rad: `X` = roll, `Y` = pitch, `Z` = yaw.
    MountRpy {
        /// `X` = roll, `Y` = pitch, `Z` = yaw.
        axis: Axis,
    },
    /// `compliance[joint]`, rad/(N·m).
    Compliance {
        /// 0-based joint index.
        joint: usize,
    },
}

impl ErrorParam {
    /// The field name: `"joint_offset"`, `"joint_scale"`, `"origin_xyz"`, `"origin_rpy"`, `"tip"`,
    /// `"mount_xyz"`, `"mount_rpy"` or `"compliance"`.
    pub fn kind_name(self) -> &'static str {
        match self {
            ErrorParam::JointOffset { .. } => "joint_offset",
            ErrorParam::JointScale { .. } => "joint_scale",
            ErrorParam::OriginXyz { .. } => "origin_xyz",
            ErrorParam::OriginRpy { .. } => "origin_rpy",
            ErrorParam::Tip { .. } => "tip",
            ErrorParam::MountXyz { .. } => "mount_xyz",
            ErrorParam::MountRpy { .. } => "mount_rpy",
            ErrorParam::Compliance { .. } => "compliance",
        }
    }

    /// The SI unit of the value: `"rad"`, `"ratio"`, `"m"` or `"rad/(N·m)"`.
    pub fn unit_si(self) -> &'static str {
        match self {
            ErrorParam::JointOffset { .. }
            | ErrorParam::OriginRpy { .. }
            | ErrorParam::MountRpy { .. } => "rad",
            ErrorParam::JointScale { .. } => "ratio",
            ErrorParam::OriginXyz { .. } | ErrorParam::Tip { .. } | ErrorParam::MountXyz { .. } => {
                "m"
            }
            ErrorParam::Compliance { .. } => "rad/(N·m)",
        }
    }

    /// The 0-based joint index, for per-joint parameters.
    pub fn joint(self) -> Option<usize> {
        match self {
            ErrorParam::JointOffset { joint }
            | ErrorParam::JointScale { joint }
            | ErrorParam::OriginXyz { joint, .. }
            | ErrorParam::OriginRpy { joint, .. }
            | ErrorParam::Compliance { joint } => Some(joint),
            ErrorParam::Tip { .. } | ErrorParam::MountXyz { .. } | ErrorParam::MountRpy { .. } => {
                None
            }
        }
    }

    /// The axis, for vector parameters.
    pub fn axis(self) -> Option<Axis> {
        match self {
            ErrorParam::OriginXyz { axis, .. }
            | ErrorParam::OriginRpy { axis, .. }
            | ErrorParam::Tip { axis }
            | ErrorParam::MountXyz { axis }
            | ErrorParam::MountRpy { axis } => Some(axis),
            _ => None,
        }
    }

    /// Checks the joint index against a chain of `dof` joints.
    ///
    /// Errors: the joint index is `≥ dof`.
    pub fn check_dof(self, dof: usize) -> Result<(), KinematicsError> {
        match self.joint() {
            Some(j) if j >= dof => Err(KinematicsError::InvalidInput(format!(
                "error parameter {self} refers to joint {} but the robot has {dof} joints; use a \
                 joint number from 1 to {dof} (0-based index below {dof} in code)",
                j + 1
            ))),
            _ => Ok(()),
        }
    }
}

impl fmt::Display for ErrorParam {
    /// `joint_offset joint 3`, `origin_xyz joint 2 x`, `tip z`, … (joints 1-based).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.kind_name())?;
        if let Some(j) = self.joint() {
            write!(f, " joint {}", j + 1)?;
        }
        if let Some(a) = self.axis() {
            write!(f, " {a}")?;
        }
        Ok(())
    }
}

/// The whole catalogue of parameters for a chain of `dof` joints, in a fixed order: per joint
/// (offset, scale, origin xyz x/y/z, origin rpy x/y/z, compliance), then tip x/y/z, mount xyz
/// x/y/z, mount rpy x/y/z. `9·dof + 9` entries.
pub fn all_params(dof: usize) -> Vec<ErrorParam> {
    let mut v = Vec::with_capacity(9 * dof + 9);
    for joint in 0..dof {
        v.push(ErrorParam::JointOffset { joint });
        v.push(ErrorParam::JointScale { joint });
        v.extend(Axis::ALL.map(|axis| ErrorParam::OriginXyz { joint, axis }));
        v.extend(Axis::ALL.map(|axis| ErrorParam::OriginRpy { joint, axis }));
        v.push(ErrorParam::Compliance { joint });
    }
    v.extend(Axis::ALL.map(|axis| ErrorParam::Tip { axis }));
    v.extend(Axis::ALL.map(|axis| ErrorParam::MountXyz { axis }));
    v.extend(Axis::ALL.map(|axis| ErrorParam::MountRpy { axis }));
    v
}

/// Per-joint frame data of the true chain, nominal base frame.
#[derive(Debug, Clone, Copy)]
struct TrueJointFrame {
    /// Rotation `nominal_base_from_parent` (the joint's URDF parent link frame).
    parent_rotation: Matrix3<f64>,
    /// Derivative axes of the origin rotation at the true rpy, indexed by [`Axis::index`] (roll,
    /// pitch, yaw); see [`rpy_derivative_axes`].
    rpy_axes: [Vector3<f64>; 3],
    /// Origin of the joint frame, m.
    o: Vector3<f64>,
    /// Joint axis, unit.
    z: Vector3<f64>,
}

impl Default for TrueJointFrame {
    fn default() -> Self {
        Self {
            parent_rotation: Matrix3::identity(),
            rpy_axes: [Vector3::zeros(); 3],
            o: Vector3::zeros(),
            z: Vector3::zeros(),
        }
    }
}

fn all_zero(v: &[f64]) -> bool {
    v.iter().all(|&x| x == 0.0)
}

/// Checks all the inputs of the public entry points.
fn check_inputs(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
) -> Result<(), KinematicsError> {
    model.check_q(q_rep)?;
    check_tip(flange_from_tip)?;
    check_gravity(g_base)?;
    errors.check(model)
}

/// The true joint angles into `q_true` (len = dof), with the nominal gravity torques into `tau`
/// (zeros if no compliance is set). No checks.
fn true_joint_angles(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
    tau: &mut [f64],
    q_true: &mut [f64],
) {
    if all_zero(&errors.compliance) {
        tau.iter_mut().for_each(|t| *t = 0.0);
    } else {
        gravity_torques_into(model, q_rep, g_base, tau);
    }
    for i in 0..q_rep.len() {
        q_true[i] = q_rep[i] * (1.0 + errors.joint_scale[i])
            + errors.joint_offset[i]
            + errors.compliance[i] * tau[i];
    }
}

/// The true chain at the true joint angles: `nominal_base_from_flange` as (rotation matrix,
/// translation in m), filling `frames` (if given, len = dof). No checks, no allocation.
///
/// Joints without origin error go through the nominal FK step ([`apply_step`]) unchanged; a joint
/// with an origin error goes through the same step with its origin replaced by
/// `fixed_prefix · Origin(xyz + Δxyz, rpy + Δrpy)`.
fn true_chain(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_true: &[f64],
    mut frames: Option<&mut [TrueJointFrame]>,
) -> (Matrix3<f64>, Vector3<f64>) {
    let mount_zero = all_zero(errors.mount_xyz.as_slice()) && all_zero(errors.mount_rpy.as_slice());
    let (mut r, mut t) = if mount_zero {
        (Matrix3::identity(), Vector3::zeros())
    } else {
        (matrix_from_rpy(&errors.mount_rpy), errors.mount_xyz)
    };
    for (k, ((step, joint), &qk)) in model
        .steps
        .iter()
        .zip(model.joints())
        .zip(q_true)
        .enumerate()
    {
        let dxyz = &errors.origin_xyz[k];
        let drpy = &errors.origin_rpy[k];
        let origin_zero = all_zero(dxyz.as_slice()) && all_zero(drpy.as_slice());
        let prefix_r = || {
            if joint.fixed_prefix.rotation.w == 1.0 {
                Matrix3::identity()
            } else {
                *joint.fixed_prefix.rotation.to_rotation_matrix().matrix()
            }
        };
        let parent_rotation = frames.as_ref().map(|_| r * prefix_r());
        if origin_zero {
            // The nominal step, so that zero errors reproduce the nominal FK.
            apply_step(&mut r, &mut t, step, qk);
        } else {
            let fp = &joint.fixed_prefix;
            let fp_r = prefix_r();
            let origin_r = if all_zero(drpy.as_slice()) {
                step.origin.r
            } else {
                fp_r * matrix_from_rpy(&(joint.origin_rpy + drpy))
            };
            let perturbed = Step::new(
                step.axis,
                origin_r,
                fp.translation.vector + fp_r * (joint.origin_xyz + dxyz),
            );
            apply_step(&mut r, &mut t, &perturbed, qk);
        }
        if let (Some(f), Some(parent_rotation)) = (frames.as_deref_mut(), parent_rotation) {
            f[k] = TrueJointFrame {
                parent_rotation,
                rpy_axes: rpy_derivative_axes(&parent_rotation, &(joint.origin_rpy + drpy)),
                o: t,
                z: r * step.axis.into_inner(),
            };
        }
    }
    to_flange_nalgebra(model, &mut r, &mut t);
    (r, t)
}

/// `Rz(yaw)·Ry(pitch)·Rx(roll)` as a matrix, written out (no products of rotations). Agrees with
/// [`rotation_from_rpy`](crate::rotation_from_rpy) to round-off (tested).
fn matrix_from_rpy(rpy: &Vector3<f64>) -> Matrix3<f64> {
    let (sr, cr) = sin_cos(rpy.x);
    let (sp, cp) = sin_cos(rpy.y);
    let (sy, cy) = sin_cos(rpy.z);
    Matrix3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// Runs `f` with two scratch slices of length `dof` (on the stack for `dof ≤ 16`).
fn with_scratch<R>(dof: usize, f: impl FnOnce(&mut [f64], &mut [f64]) -> R) -> R {
    if dof <= STACK_DOF {
        let mut a = [0.0; STACK_DOF];
        let mut b = [0.0; STACK_DOF];
        f(&mut a[..dof], &mut b[..dof])
    } else {
        let mut a = vec![0.0; dof];
        let mut b = vec![0.0; dof];
        f(&mut a, &mut b)
    }
}

/// `true_base_from_flange` without checks (allocation-free for `dof ≤ 16`); see
/// [`true_base_from_flange`]. Panics only if the lengths do not match the model.
pub fn true_base_from_flange_unchecked(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
) -> Isometry3<f64> {
    let (r, t) = true_flange_rt(model, errors, q_rep, g_base);
    isometry(&r, &t)
}

/// The true flange as (rotation matrix, translation), no checks, no allocation for `dof ≤ 16`.
fn true_flange_rt(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
) -> (Matrix3<f64>, Vector3<f64>) {
    with_scratch(model.dof(), |tau, q_true| {
        true_joint_angles(model, errors, q_rep, g_base, tau, q_true);
        true_chain(model, errors, q_true, None)
    })
}

/// Flange pose of the TRUE robot (nominal model + `errors`) in the NOMINAL base frame, at the
/// reported joint angles `q_rep` (rad); `g_base` is the gravity acceleration in the nominal base
/// frame, m/s², used for the compliance deflection. The tip error is not applied (see
/// [`true_base_from_tip`]).
///
/// Errors: a bad `q_rep` ([`RobotModel::check_q`]; the true angles are not limit-checked), a
/// non-finite `g_base`, or `errors` of the wrong shape or non-finite ([`KinematicErrors::check`]).
pub fn true_base_from_flange(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
) -> Result<Isometry3<f64>, KinematicsError> {
    check_inputs(model, errors, q_rep, &Vector3::zeros(), g_base)?;
    Ok(true_base_from_flange_unchecked(
        model, errors, q_rep, g_base,
    ))
}

/// `true_base_from_tip` without checks (allocation-free for `dof ≤ 16`); see
/// [`true_base_from_tip`]. Panics only if the lengths do not match the model.
pub fn true_base_from_tip_unchecked(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
) -> Isometry3<f64> {
    if errors.is_zero() {
        // Exactly the nominal FK (the general path agrees to round-off; tested).
        return base_from_tip_unchecked(model, q_rep, flange_from_tip);
    }
    true_tip_general(model, errors, q_rep, flange_from_tip, g_base)
}

/// The general path of [`true_base_from_tip_unchecked`] (no zero-error shortcut).
fn true_tip_general(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
) -> Isometry3<f64> {
    let (r, t) = true_flange_rt(model, errors, q_rep, g_base);
    tip_isometry(&r, &t, &(flange_from_tip + errors.tip))
}

/// Tip pose of the TRUE robot in the NOMINAL base frame at the reported joint angles `q_rep` (rad):
/// the nominal chain with `errors` applied as described in the module documentation, tip offset
/// `flange_from_tip + errors.tip` (m, flange axes), orientation the flange's. `g_base` is the gravity
/// acceleration in the nominal base frame, m/s² (used only through `errors.compliance`).
///
/// With [`KinematicErrors::zero`] it equals [`base_from_tip`](crate::base_from_tip) exactly.
/// Allocation-free for chains of up to 16 joints.
///
/// Errors: a bad `q_rep` ([`RobotModel::check_q`]; the true angles are not limit-checked), a
/// non-finite tip offset or `g_base`, or `errors` of the wrong shape or non-finite
/// ([`KinematicErrors::check`]).
///
/// # Examples
/// ```
/// # use kinematics::{true_base_from_tip, base_from_tip, ErrorParam, KinematicErrors, RobotModel};
/// # use nalgebra::Vector3;
/// let urdf = r#"<robot name="arm">
///   <link name="base"/><link name="tool0"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="tool0"/>
///     <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
/// </robot>"#;
/// let model = RobotModel::from_urdf_str(urdf, "tool0").unwrap();
/// let tip = Vector3::new(1.0, 0.0, 0.0);
/// let g = Vector3::new(0.0, 0.0, -9.81);
/// let mut errors = KinematicErrors::zero(1);
/// errors.set(ErrorParam::JointOffset { joint: 0 }, std::f64::consts::FRAC_PI_2);
/// let true_tip = true_base_from_tip(&model, &errors, &[0.0], &tip, &g).unwrap();
/// // The true joint sits 90° further: the tip at (1,0,0.5) nominally is really at (0,1,0.5).
/// assert!((true_tip.translation.vector - Vector3::new(0.0, 1.0, 0.5)).norm() < 1e-12);
/// ```
pub fn true_base_from_tip(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
) -> Result<Isometry3<f64>, KinematicsError> {
    check_inputs(model, errors, q_rep, flange_from_tip, g_base)?;
    Ok(true_base_from_tip_unchecked(
        model,
        errors,
        q_rep,
        flange_from_tip,
        g_base,
    ))
}

/// Axes `a` (in base) of the derivatives of `R_parent·Rz(yaw)·Ry(pitch)·Rx(roll)` with respect to
/// roll, pitch and yaw, in that order: `∂(R·v)/∂angle = a × (R·v)` exactly, with
/// `a_roll = R_parent·Rz·Ry·e_x = R_parent·(cy·cp, sy·cp, −sp)`,
/// `a_pitch = R_parent·Rz·e_y = R_parent·(−sy, cy, 0)`, `a_yaw = R_parent·e_z`.
fn rpy_derivative_axes(parent_rotation: &Matrix3<f64>, rpy: &Vector3<f64>) -> [Vector3<f64>; 3] {
    let (sp, cp) = sin_cos(rpy.y);
    let (sy, cy) = sin_cos(rpy.z);
    [
        parent_rotation * Vector3::new(cy * cp, sy * cp, -sp),
        parent_rotation * Vector3::new(-sy, cy, 0.0),
        parent_rotation * Vector3::z(),
    ]
}

/// `∂p_tip/∂param`, m per parameter unit, 3 × `params.len()`, nominal base axes: the exact analytic
/// derivative of the position of [`true_base_from_tip`] with respect to each listed parameter, at
/// the given `errors` (not only at zero).
///
/// Columns, with `p` the true tip, `o_k`, `z_k` joint k's true origin and axis, `R_P` the rotation
/// of its parent link frame (all in the nominal base frame):
/// - joint offset: `z_k × (p − o_k)`; scale: that × `q_rep_k`; compliance: that × `τ_k(q_rep)`;
/// - origin xyz: `R_P·e_axis`; origin rpy: `a × (p − o_k)` with `a = R_P·e_z` (yaw),
///   `R_P·Rz(yaw)·e_y` (pitch), `R_P·Rz(yaw)·Ry(pitch)·e_x` (roll) at the true rpy;
/// - tip: `R_flange·e_axis`; mount xyz: `e_axis`; mount rpy: `a × (p − mount_xyz)` with the same
///   axes as the origin rpy, `R_P = I`.
///
/// Errors: as [`true_base_from_tip`], plus a parameter whose joint index is `≥ model.dof()`.
pub fn tip_error_jacobian(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> Result<Matrix3xX<f64>, KinematicsError> {
    check_inputs(model, errors, q_rep, flange_from_tip, g_base)?;
    let n = model.dof();
    for p in params {
        p.check_dof(n)?;
    }
    let mut jac = Matrix3xX::zeros(params.len());
    with_chain_scratch(n, |tau, q_true, frames| {
        // Compliance columns need τ even when no compliance is set.
        if params
            .iter()
            .any(|p| matches!(p, ErrorParam::Compliance { .. }))
            || !all_zero(&errors.compliance)
        {
            gravity_torques_into(model, q_rep, g_base, tau);
        }
        for i in 0..n {
            q_true[i] = q_rep[i] * (1.0 + errors.joint_scale[i])
                + errors.joint_offset[i]
                + errors.compliance[i] * tau[i];
        }
        let (flange_r, flange_t) = true_chain(model, errors, q_true, Some(frames));
        let p = flange_t + flange_r * (flange_from_tip + errors.tip);
        fill_error_columns(errors, q_rep, tau, frames, &flange_r, &p, params, &mut jac);
    });
    Ok(jac)
}

/// The columns of [`tip_error_jacobian`] from the true chain's frames, tip `p` and flange rotation.
#[allow(clippy::too_many_arguments)]
fn fill_error_columns(
    errors: &KinematicErrors,
    q_rep: &[f64],
    tau: &[f64],
    frames: &[TrueJointFrame],
    flange_r: &Matrix3<f64>,
    p: &Vector3<f64>,
    params: &[ErrorParam],
    jac: &mut Matrix3xX<f64>,
) {
    let p = *p;
    let mount_axes = rpy_derivative_axes(&Matrix3::identity(), &errors.mount_rpy);
    for (c, param) in params.iter().enumerate() {
        let joint_col = |k: usize| frames[k].z.cross(&(p - frames[k].o));
        let col = match *param {
            ErrorParam::JointOffset { joint } => joint_col(joint),
            ErrorParam::JointScale { joint } => joint_col(joint) * q_rep[joint],
            ErrorParam::Compliance { joint } => joint_col(joint) * tau[joint],
            ErrorParam::OriginXyz { joint, axis } => frames[joint].parent_rotation * axis.unit(),
            ErrorParam::OriginRpy { joint, axis } => {
                let f = &frames[joint];
                f.rpy_axes[axis.index()].cross(&(p - f.o))
            }
            ErrorParam::Tip { axis } => flange_r * axis.unit(),
            ErrorParam::MountXyz { axis } => axis.unit(),
            ErrorParam::MountRpy { axis } => {
                mount_axes[axis.index()].cross(&(p - errors.mount_xyz))
            }
        };
        jac.set_column(c, &col);
    }
}

/// Runs `f` with scratch `tau`, `q_true` (len = dof) and `frames` (on the stack for `dof ≤ 16`).
fn with_chain_scratch<R>(
    dof: usize,
    f: impl FnOnce(&mut [f64], &mut [f64], &mut [TrueJointFrame]) -> R,
) -> R {
    if dof <= STACK_DOF {
        let mut frames = [TrueJointFrame::default(); STACK_DOF];
        with_scratch(dof, |tau, q_true| f(tau, q_true, &mut frames[..dof]))
    } else {
        let mut frames = vec![TrueJointFrame::default(); dof];
        with_scratch(dof, |tau, q_true| f(tau, q_true, &mut frames))
    }
}

/// `∂p_tip/∂q_rep` of the TRUE robot, 3×dof, m/rad, nominal base axes, at the reported angles
/// `q_rep`: column `i` is `(1 + scale_i)·J_i + Σ_k J_k·compliance_k·∂τ_k/∂q_i`, with `J` the tip
/// position Jacobian of the true chain with respect to the true angles and `∂τ/∂q` the nominal
/// gravity-torque Jacobian ([`gravity_torque_jacobian`](crate::gravity_torque_jacobian)).
///
/// Errors: as [`true_base_from_tip`].
pub fn tip_joint_jacobian_true(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
) -> Result<Matrix3xX<f64>, KinematicsError> {
    check_inputs(model, errors, q_rep, flange_from_tip, g_base)?;
    let n = model.dof();
    let mut tau = vec![0.0; n];
    let mut q_true = vec![0.0; n];
    true_joint_angles(model, errors, q_rep, g_base, &mut tau, &mut q_true);
    let mut frames = vec![TrueJointFrame::default(); n];
    let (flange_r, flange_t) = true_chain(model, errors, &q_true, Some(&mut frames));
    let p = flange_t + flange_r * (flange_from_tip + errors.tip);
    // ∂p/∂q_true.
    let mut j_true = Matrix3xX::zeros(n);
    for (k, f) in frames.iter().enumerate() {
        j_true.set_column(k, &f.z.cross(&(p - f.o)));
    }
    let mut jac = Matrix3xX::zeros(n);
    for i in 0..n {
        jac.set_column(i, &(j_true.column(i) * (1.0 + errors.joint_scale[i])));
    }
    if !all_zero(&errors.compliance) {
        let mut entries = vec![GravityEntry::default(); n];
        gravity_entries(model, q_rep, &mut entries);
        let dtau = gravity_jacobian_from_entries(&entries, g_base);
        for i in 0..n {
            let mut col = jac.column(i).into_owned();
            for k in 0..n {
                col += j_true.column(k) * (errors.compliance[k] * dtau[(k, i)]);
            }
            jac.set_column(i, &col);
        }
    }
    Ok(jac)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fk::base_from_tip;
    use nalgebra::{Rotation3, Translation3, UnitQuaternion};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    const VA1400: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../robots/va1400.urdf"
    ));
    const HP20: &str = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../robots/hp20.urdf"
    ));

    /// A 4-joint test arm that exercises what the shipped URDFs do not: non-zero origin rpy, a
    /// fixed joint between two actuated joints, an oblique axis, a fixed joint before the first
    /// actuated joint and a rotated tool0. `origins[k]` = (xyz, rpy) of actuated joint k.
    fn oblique_urdf(origins: &[(Vector3<f64>, Vector3<f64>); 4]) -> String {
        let o = |k: usize| {
            let (x, r) = &origins[k];
            format!(
                r#"<origin xyz="{:e} {:e} {:e}" rpy="{:e} {:e} {:e}"/>"#,
                x.x, x.y, x.z, r.x, r.y, r.z
            )
        };
        let link = |name: &str, com: &str, mass: f64| {
            format!(
                r#"<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>
                <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>"#
            )
        };
        let lim = r#"<limit lower="-3" upper="3" effort="100" velocity="1"/>"#;
        format!(
            r#"<robot name="oblique">
            <link name="world"/>
            {}{}{}{}{}{}
            <link name="tool0"/>
            <joint name="world-base" type="fixed"><parent link="world"/><child link="base"/>
              <origin xyz="0.1 -0.05 0.2" rpy="0.05 -0.1 0.3"/></joint>
            <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>{}<axis xyz="0 0 1"/>{lim}</joint>
            <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>{}<axis xyz="0 1 0"/>{lim}</joint>
            <joint name="l2-l2b" type="fixed"><parent link="l2"/><child link="l2b"/>
              <origin xyz="0.3 0.02 0.1" rpy="0.2 0.1 -0.4"/></joint>
            <joint name="j3" type="revolute"><parent link="l2b"/><child link="l3"/>{}<axis xyz="0.3 -0.5 0.8"/>{lim}</joint>
            <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>{}<axis xyz="-1 0 0"/></joint>
            <joint name="l4-tool0" type="fixed"><parent link="l4"/><child link="tool0"/>
              <origin xyz="0.05 0 0.01" rpy="0 1.5707963267948966 0.2"/></joint>
            </robot>"#,
            link("base", "0 0 0.1", 20.0),
            link("l1", "0.05 0 0.2", 15.0),
            link("l2", "0.2 0 0.05", 10.0),
            link("l2b", "0.1 0.01 0", 4.0),
            link("l3", "0 0.1 0.3", 6.0),
            link("l4", "0.04 0 0", 2.0),
            o(0),
            o(1),
            o(2),
            o(3),
        )
    }

    fn oblique_origins() -> [(Vector3<f64>, Vector3<f64>); 4] {
        [
            (Vector3::new(0.0, 0.0, 0.4), Vector3::new(0.0, 0.0, 0.0)),
            (Vector3::new(0.15, 0.0, 0.1), Vector3::new(0.3, -0.2, 0.1)),
            (Vector3::new(0.0, 0.05, 0.5), Vector3::new(-0.1, 0.25, 0.5)),
            (Vector3::new(0.6, 0.0, 0.0), Vector3::new(1.2, 0.0, -0.3)),
        ]
    }

    fn model(xml: &str) -> RobotModel {
        RobotModel::from_urdf_str(xml, "tool0").expect("test URDF loads")
    }

    fn robots() -> Vec<RobotModel> {
        vec![
            model(VA1400),
            model(HP20),
            model(&oblique_urdf(&oblique_origins())),
        ]
    }

    const G_FLOOR: Vector3<f64> = Vector3::new(0.0, 0.0, -9.81);

    fn random_q(model: &RobotModel, rng: &mut ChaCha8Rng) -> Vec<f64> {
        model
            .joints()
            .iter()
            .map(|j| {
                let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
                rng.random_range(lo + 0.05 * (hi - lo)..hi - 0.05 * (hi - lo))
            })
            .collect()
    }

    fn random_vec(rng: &mut ChaCha8Rng, s: f64) -> Vector3<f64> {
        Vector3::new(
            rng.random_range(-s..s),
            rng.random_range(-s..s),
            rng.random_range(-s..s),
        )
    }

    /// Random errors of realistic-to-large size. The angles are large (up to 0.3–0.5 rad) on
    /// purpose: the Jacobian must be exact, not a small-angle approximation.
    fn random_errors(dof: usize, rng: &mut ChaCha8Rng) -> KinematicErrors {
        let mut e = KinematicErrors::zero(dof);
        for j in 0..dof {
            e.joint_offset[j] = rng.random_range(-0.05..0.05);
            e.joint_scale[j] = rng.random_range(-0.01..0.01);
            e.origin_xyz[j] = random_vec(rng, 0.01);
            e.origin_rpy[j] = random_vec(rng, 0.3);
            e.compliance[j] = rng.random_range(-2e-5..2e-5);
        }
        e.tip = random_vec(rng, 0.05);
        e.mount_xyz = random_vec(rng, 0.5);
        e.mount_rpy = random_vec(rng, 0.5);
        // Zero about a third of the parameters (all of a joint's origin rpy, say), so that the
        // mixed paths (nominal step for some joints, perturbed for others; xyz-only origin
        // errors) are exercised too.
        for p in all_params(dof) {
            if rng.random_range(0..3) == 0 {
                e.set(p, 0.0);
            }
        }
        for j in 0..dof {
            match rng.random_range(0..4) {
                0 => e.origin_rpy[j] = Vector3::zeros(),
                1 => e.origin_xyz[j] = Vector3::zeros(),
                _ => {}
            }
        }
        e
    }

    fn random_tip(rng: &mut ChaCha8Rng) -> Vector3<f64> {
        Vector3::new(
            rng.random_range(-0.05..0.05),
            rng.random_range(-0.05..0.05),
            rng.random_range(0.0..0.3),
        )
    }

    fn random_g(rng: &mut ChaCha8Rng) -> Vector3<f64> {
        // Any direction: floor, wall and ceiling mounts and everything between.
        let v = random_vec(rng, 1.0);
        9.81 * v / v.norm().max(1e-3)
    }

    /// Central-difference step in the parameter's own unit. A step of 1e-6 moves the tip by
    /// ~1e-6 m for the metre and radian parameters. A compliance is multiplied by torques of up to
    /// ~5e3 N·m (HP20), so its step is 1e-6 / 5e3 ≈ 2e-10 rad/(N·m) for the same tip motion.
    fn fd_step(p: ErrorParam) -> f64 {
        match p {
            ErrorParam::Compliance { .. } => 2e-10,
            _ => 1e-6,
        }
    }

    /// Tolerance of a central difference with a tip motion of ~1e-6 m per step: truncation
    /// ~h²·|p'''| ≲ 1e-12·few m, round-off ~eps·|p|/h ≈ 2.2e-16·3 m/1e-6 ≈ 7e-10 m per unit step.
    /// So |analytic − fd|·h ≤ 1e-14 m + 1e-8 relative: compare the tip motions `column·h`.
    const FD_TOL_M: f64 = 1e-14;
    const FD_TOL_REL: f64 = 1e-7;

    fn check_param_jacobian(model: &RobotModel, seed: u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let q = random_q(model, &mut rng);
        let errors = random_errors(model.dof(), &mut rng);
        let tip = random_tip(&mut rng);
        let g = random_g(&mut rng);
        let params = all_params(model.dof());
        let jac = tip_error_jacobian(model, &errors, &q, &tip, &g, &params).unwrap();
        for (c, &p) in params.iter().enumerate() {
            let h = fd_step(p);
            let mut ep = errors.clone();
            let mut em = errors.clone();
            ep.add(p, h);
            em.add(p, -h);
            let tp = true_base_from_tip(model, &ep, &q, &tip, &g)
                .unwrap()
                .translation
                .vector;
            let tm = true_base_from_tip(model, &em, &q, &tip, &g)
                .unwrap()
                .translation
                .vector;
            // Tip motion over the central step, m.
            let fd_motion = (tp - tm) / 2.0;
            let an_motion = jac.column(c) * h;
            let diff = (fd_motion - an_motion).norm();
            assert!(
                diff <= FD_TOL_M + FD_TOL_REL * an_motion.norm().max(1e-9),
                "{} seed {seed} {p}: analytic {:?} vs fd {:?} (per unit), |Δ|·h = {diff:e} m",
                model.name(),
                jac.column(c).as_slice(),
                (fd_motion / h).as_slice(),
            );
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        #[test]
        fn error_jacobian_matches_central_differences(seed in any::<u64>()) {
            for m in robots() {
                check_param_jacobian(&m, seed);
            }
        }

        #[test]
        fn zero_errors_reproduce_nominal_fk_exactly(seed in any::<u64>()) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for m in robots() {
                let q = random_q(&m, &mut rng);
                let tip = random_tip(&mut rng);
                let g = random_g(&mut rng);
                let nominal = base_from_tip(&m, &q, &tip).unwrap();
                let zero = KinematicErrors::zero(m.dof());
                let t = true_base_from_tip(&m, &zero, &q, &tip, &g).unwrap();
                prop_assert_eq!(t, nominal);
                // The general path (no zero shortcut) agrees to round-off.
                let general = true_tip_general(&m, &zero, &q, &tip, &g);
                prop_assert!((general.translation.vector - nominal.translation.vector).norm() < EXACT_TOL);
                prop_assert!(general.rotation.angle_to(&nominal.rotation) < EXACT_TOL);
                // And the flange agrees as well.
                let flange = true_base_from_flange(&m, &zero, &q, &g).unwrap();
                let nominal_flange = crate::base_from_flange(&m, &q).unwrap();
                prop_assert!((flange.translation.vector - nominal_flange.translation.vector).norm() < EXACT_TOL);
                prop_assert!(flange.rotation.angle_to(&nominal_flange.rotation) < EXACT_TOL);
            }
        }

        #[test]
        fn joint_jacobian_true_matches_central_differences(seed in any::<u64>()) {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            for m in robots() {
                let q = random_q(&m, &mut rng);
                let errors = random_errors(m.dof(), &mut rng);
                let tip = random_tip(&mut rng);
                let g = random_g(&mut rng);
                let jac = tip_joint_jacobian_true(&m, &errors, &q, &tip, &g).unwrap();
                // Step 1e-6 rad, tolerance as for the parameter Jacobian (tip motions ~1e-6 m).
                let h = 1e-6;
                for i in 0..m.dof() {
                    let mut qp = q.clone();
                    let mut qm = q.clone();
                    qp[i] += h;
                    qm[i] -= h;
                    let tp = true_base_from_tip(&m, &errors, &qp, &tip, &g).unwrap().translation.vector;
                    let tm = true_base_from_tip(&m, &errors, &qm, &tip, &g).unwrap().translation.vector;
                    let fd_motion = (tp - tm) / 2.0;
                    let an_motion = jac.column(i) * h;
                    let diff = (fd_motion - an_motion).norm();
                    prop_assert!(
                        diff <= FD_TOL_M + FD_TOL_REL * an_motion.norm().max(1e-9),
                        "{} joint {}: |Δ|·h = {:e} m", m.name(), i + 1, diff
                    );
                }
            }
        }
    }

    /// Exact-arithmetic comparisons of metre-scale poses (a few ulps).
    const EXACT_TOL: f64 = 1e-12;

    fn assert_pose_eq(a: &Isometry3<f64>, b: &Isometry3<f64>, what: &str) {
        let dt = (a.translation.vector - b.translation.vector).norm();
        let dr = a.rotation.angle_to(&b.rotation);
        assert!(
            dt < EXACT_TOL && dr < EXACT_TOL,
            "{what}: Δt = {dt:e} m, Δr = {dr:e} rad"
        );
    }

    /// The semantics of each error kind, against independent constructions: a URDF with the
    /// modified origins, nominal FK at modified angles, the mount composed in front.
    #[test]
    fn each_error_kind_means_what_the_contract_says() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let origins = oblique_origins();
        let m = model(&oblique_urdf(&origins));
        let n = m.dof();
        let q = random_q(&m, &mut rng);
        let tip = random_tip(&mut rng);
        let g = random_g(&mut rng);
        let e = random_errors(n, &mut rng);

        // Origins: a URDF with xyz + origin_xyz, rpy + origin_rpy.
        let mut only = KinematicErrors::zero(n);
        only.origin_xyz.clone_from(&e.origin_xyz);
        only.origin_rpy.clone_from(&e.origin_rpy);
        let mut modified = origins;
        for (k, o) in modified.iter_mut().enumerate() {
            o.0 += e.origin_xyz[k];
            o.1 += e.origin_rpy[k];
        }
        let m_mod = model(&oblique_urdf(&modified));
        assert_pose_eq(
            &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
            &base_from_tip(&m_mod, &q, &tip).unwrap(),
            "origin errors",
        );

        // Joint offset, scale and compliance: nominal FK at q_true.
        let mut only = KinematicErrors::zero(n);
        only.joint_offset.clone_from(&e.joint_offset);
        only.joint_scale.clone_from(&e.joint_scale);
        only.compliance.clone_from(&e.compliance);
        let tau = crate::gravity_torques(&m, &q, &g).unwrap();
        let q_true: Vec<f64> = (0..n)
            .map(|i| q[i] * (1.0 + e.joint_scale[i]) + e.joint_offset[i] + e.compliance[i] * tau[i])
            .collect();
        assert!(
            tau.iter().any(|t| t.abs() > 1.0),
            "the test arm must feel gravity: {tau:?}"
        );
        assert_pose_eq(
            &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
            &base_from_tip(&m, &q_true, &tip).unwrap(),
            "joint errors",
        );

        // Tip: added to flange_from_tip in flange axes.
        let mut only = KinematicErrors::zero(n);
        only.tip = e.tip;
        assert_pose_eq(
            &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
            &base_from_tip(&m, &q, &(tip + e.tip)).unwrap(),
            "tip error",
        );

        // Mount: nominal_base_from_base in front, R = Rz·Ry·Rx.
        let mut only = KinematicErrors::zero(n);
        only.mount_xyz = e.mount_xyz;
        only.mount_rpy = e.mount_rpy;
        let r = Rotation3::from_axis_angle(&Vector3::z_axis(), e.mount_rpy.z)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), e.mount_rpy.y)
            * Rotation3::from_axis_angle(&Vector3::x_axis(), e.mount_rpy.x);
        let nominal_base_from_base = Isometry3::from_parts(
            Translation3::from(e.mount_xyz),
            UnitQuaternion::from_rotation_matrix(&r),
        );
        assert_pose_eq(
            &true_base_from_tip(&m, &only, &q, &tip, &g).unwrap(),
            &(nominal_base_from_base * base_from_tip(&m, &q, &tip).unwrap()),
            "mount error",
        );

        // All together, and true_base_from_flange consistent with the tip.
        let flange = true_base_from_flange(&m, &e, &q, &g).unwrap();
        let t = true_base_from_tip(&m, &e, &q, &tip, &g).unwrap();
        assert_pose_eq(
            &t,
            &Isometry3::from_parts(
                Translation3::from((flange * nalgebra::Point3::from(tip + e.tip)).coords),
                flange.rotation,
            ),
            "flange vs tip",
        );
    }

    #[test]
    fn matrix_from_rpy_matches_rotation_from_rpy() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        // Random angles plus tiny angles and exact ±90°/180° (gimbal lock of the pitch).
        let mut cases: Vec<Vector3<f64>> = (0..200).map(|_| random_vec(&mut rng, 4.0)).collect();
        let fpi = std::f64::consts::PI;
        cases.extend([
            Vector3::new(1e-12, -1e-12, 1e-12),
            Vector3::new(0.3, fpi / 2.0, -0.2),
            Vector3::new(0.3, -fpi / 2.0, -0.2),
            Vector3::new(fpi, 0.0, fpi),
        ]);
        for rpy in cases {
            let a = matrix_from_rpy(&rpy);
            let b = crate::rotation_from_rpy(&rpy);
            assert!((a - b.matrix()).amax() < EXACT_TOL, "{rpy:?}");
        }
    }

    #[test]
    fn gravity_direction_only_matters_through_compliance() {
        let m = model(HP20);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let q = random_q(&m, &mut rng);
        let tip = random_tip(&mut rng);
        let mut e = random_errors(m.dof(), &mut rng);
        e.compliance.iter_mut().for_each(|c| *c = 0.0);
        let a = true_base_from_tip(&m, &e, &q, &tip, &G_FLOOR).unwrap();
        let b = true_base_from_tip(&m, &e, &q, &tip, &(-G_FLOOR)).unwrap();
        assert_eq!(a, b);
        e.compliance[1] = 1e-5;
        let c = true_base_from_tip(&m, &e, &q, &tip, &(-G_FLOOR)).unwrap();
        assert!((a.translation.vector - c.translation.vector).norm() > 1e-4);
    }

    #[test]
    fn catalogue_get_set_and_display() {
        let dof = 6;
        let params = all_params(dof);
        assert_eq!(params.len(), 9 * dof + 9);
        let mut sorted = params.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), params.len(), "catalogue has duplicates");
        // Every parameter addresses its own slot.
        let mut e = KinematicErrors::zero(dof);
        for (i, &p) in params.iter().enumerate() {
            e.set(p, i as f64 + 1.0);
        }
        for (i, &p) in params.iter().enumerate() {
            assert_eq!(e.get(p), i as f64 + 1.0, "{p}");
        }
        assert!(!e.is_zero());
        assert!(KinematicErrors::zero(dof).is_zero());
        assert_eq!(
            ErrorParam::OriginXyz {
                joint: 1,
                axis: Axis::X
            }
            .to_string(),
            "origin_xyz joint 2 x"
        );
        assert_eq!(ErrorParam::Tip { axis: Axis::Z }.to_string(), "tip z");
        assert_eq!(ErrorParam::Compliance { joint: 0 }.unit_si(), "rad/(N·m)");
        assert_eq!(ErrorParam::JointScale { joint: 0 }.unit_si(), "ratio");
        assert_eq!(ErrorParam::MountRpy { axis: Axis::Y }.unit_si(), "rad");
        assert_eq!(ErrorParam::MountXyz { axis: Axis::Y }.unit_si(), "m");
        assert_eq!(Axis::Y.unit(), Vector3::y());
        assert_eq!(Axis::Z.name(), "z");
        // Out-of-range joints are errors, not panics, on the checked paths.
        assert!(e.try_get(ErrorParam::JointOffset { joint: dof }).is_none());
        assert!(e
            .try_set(ErrorParam::Compliance { joint: dof }, 1.0)
            .is_err());
    }

    #[test]
    fn axis_deserializes_from_lowercase_names() {
        use serde::de::{value::StrDeserializer, IntoDeserializer};
        for a in Axis::ALL {
            let d: StrDeserializer<'_, serde::de::value::Error> = a.name().into_deserializer();
            assert_eq!(Axis::deserialize(d).unwrap(), a);
        }
        let d: StrDeserializer<'_, serde::de::value::Error> = "X".into_deserializer();
        assert!(
            Axis::deserialize(d).is_err(),
            "upper case is not an axis name"
        );
    }

    #[test]
    fn bad_inputs_are_named_errors() {
        let m = model(VA1400);
        let q = vec![0.1; m.dof()];
        let tip = Vector3::new(0.0, 0.0, 0.1);
        let short = KinematicErrors::zero(m.dof() - 1);
        let err = true_base_from_tip(&m, &short, &q, &tip, &G_FLOOR).unwrap_err();
        assert!(err.to_string().contains("joint_offset"), "{err}");
        let mut nan = KinematicErrors::zero(m.dof());
        nan.origin_rpy[2].y = f64::NAN;
        let err = true_base_from_tip(&m, &nan, &q, &tip, &G_FLOOR).unwrap_err();
        assert!(
            err.to_string().contains("origin_rpy") && err.to_string().contains("joint 3"),
            "{err}"
        );
        let zero = KinematicErrors::zero(m.dof());
        let err = tip_error_jacobian(
            &m,
            &zero,
            &q,
            &tip,
            &G_FLOOR,
            &[ErrorParam::JointOffset { joint: 7 }],
        )
        .unwrap_err();
        assert!(err.to_string().contains("joint 8"), "{err}");
        assert!(true_base_from_tip(&m, &zero, &q[..3], &tip, &G_FLOOR).is_err());
        assert!(
            true_base_from_tip(&m, &zero, &q, &Vector3::new(f64::NAN, 0.0, 0.0), &G_FLOOR).is_err()
        );
        assert!(
            true_base_from_tip(&m, &zero, &q, &tip, &Vector3::new(0.0, 0.0, f64::INFINITY))
                .is_err()
        );
    }
}

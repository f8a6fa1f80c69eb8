//! The kinematic-error model: the one source of truth for simulating a "true" robot that differs
//! from its nominal URDF, and for identifying those differences.
//!
//! For a reported (controller) joint vector `q_rep` (rad) the TRUE robot is the nominal chain with:
//! - joint angles `q_true_i = q_rep_i·(1 + joint_scale_i) + joint_offset_i +
//!   compliance_i·τ_i(q_rep) + periodic_sin_i·sin(q_rep_i) + periodic_cos_i·cos(q_rep_i)`, `τ` the gravity torques of
//!   the NOMINAL model at the commanded posture `q_rep` ([`gravity_torques`](crate::gravity_torques),
//!   N·m); the last two terms are the first harmonic of a joint-angle-periodic error (e.g. an
//!   encoder or gear eccentricity: one period per joint revolution), in rad;
//! - joint `k`'s URDF origin `xyz + origin_xyz_k` (m, parent link frame) and `rpy + origin_rpy_k`
//!   (rad, `Rz(yaw)·Ry(pitch)·Rx(roll)`);
//! - the tip offset `flange_from_tip + tip` (m, flange = `tool0` axes);
//! - the true base at `nominal_base_from_base = (mount_xyz, Rz·Ry·Rx(mount_rpy))` in the NOMINAL
//!   base frame.
//!
//! [`true_base_from_tip`](crate::true_base_from_tip) gives the true tip pose in the nominal base frame and
//! [`tip_error_jacobian`](crate::tip_error_jacobian) its exact analytic derivatives with respect to any [`ErrorParam`], at any
//! error values (not only at zero).
//!
//! Every per-joint term is per chain joint ([`RobotModel::chain_joints`]), coupled joints
//! included, in that joint's unit:
//! - a **prismatic** joint's `q` is a travel in m: its offset is a length (m, the zero of the
//!   linear encoder), its scale an encoder scale (ratio), its compliance in m/N (it deflects by
//!   `compliance_i·f_i` under the gravity force `f_i` along its axis, N), and it has no periodic
//!   terms (`sin(q)` of a length has no meaning: a non-zero value is refused by
//!   [`KinematicErrors::check`]);
//! - a **coupled** joint's reported value is its coupling evaluated at the reported independent
//!   joints (`Σ c_i·q_rep_i + c_0`), and its own offset, scale, compliance and periodic terms apply
//!   to that value like any joint's: its value comes from the others, its errors are its own.
//!
//! This file holds the parameters ([`KinematicErrors`], [`ErrorParam`], [`all_params`],
//! [`all_params_for`]); the true chain and its Jacobians are in `true_fk.rs`.

use std::fmt;

use nalgebra::{Isometry3, Vector3};
use serde::{Deserialize, Serialize};

use crate::axis::Axis;
use crate::error::KinematicsError;
use crate::model::{origin_isometry, RobotModel};

/// Deviations of a real robot from its nominal URDF model (see the module documentation for how
/// each one enters the kinematics). Per-joint vectors have one entry per chain joint
/// ([`RobotModel::chain_joints`]: the moving joints, coupled ones included; `dof` of them without
/// coupled joints), in chain order (0-based). [`KinematicErrors::zero`] is the nominal robot.
/// Per-joint units are those of a rotary joint unless a prismatic joint's are named.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KinematicErrors {
    /// Joint zero offsets, rad (m for a prismatic joint): added to the scaled reported value.
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
    /// Joint compliance, rad/(N·m) (m/N for a prismatic joint): the joint deflects by
    /// `compliance_i·τ_i` under the
    /// gravity torque (force) `τ_i` of the nominal model at the reported posture.
    pub compliance: Vec<f64>,
    /// First-harmonic periodic joint error, sine part, rad: adds `periodic_sin_i·sin(q_rep_i)`
    /// to joint i's true angle (rotary joints only: zero for a prismatic joint). Omitted from the
    /// serialised form when all zero.
    #[serde(default, skip_serializing_if = "all_zero")]
    pub periodic_sin: Vec<f64>,
    /// First-harmonic periodic joint error, cosine part, rad: adds `periodic_cos_i·cos(q_rep_i)`
    /// to joint i's true angle (at `q_rep_i = 0` it acts like a joint offset). Omitted from the
    /// serialised form when all zero.
    #[serde(default, skip_serializing_if = "all_zero")]
    pub periodic_cos: Vec<f64>,
    /// Lumped gravity compliance (compliance × mass moment, no masses needed; see
    /// [`crate::lumped`]): `lumped_compliance[j][i − j]`, rad, a vector in link `i`'s frame for
    /// each rotary chain joint `j` and each chain link `i ≥ j` it carries. Joint `j` deflects by
    /// `Σ_{i≥j} lumped_compliance[j][i−j] · R_iᵀ·(g/g₀ × z_j)` at the reported posture
    /// ([`crate::lumped_deflections`]). Empty (the default, omitted when serialised) is none;
    /// else one inner vector per chain joint with `n − j` entries.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lumped_compliance: Vec<Vec<Vector3<f64>>>,
}

/// True if every entry is exactly zero (serde's skip test of the periodic terms).
fn all_zero(v: &[f64]) -> bool {
    v.iter().all(|&x| x == 0.0)
}

impl KinematicErrors {
    /// No errors (the nominal robot) for a chain of `dof` moving joints (coupled ones included:
    /// `model.chain_joints().len()`; see [`KinematicErrors::zero_for`]).
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
            periodic_sin: vec![0.0; dof],
            periodic_cos: vec![0.0; dof],
            lumped_compliance: Vec::new(),
        }
    }

    /// No errors for `model`: one entry per chain joint ([`RobotModel::chain_joints`]).
    pub fn zero_for(model: &RobotModel) -> Self {
        Self::zero(model.chain_joints().len())
    }

    /// Number of joints (the length of `joint_offset`: the chain joints, coupled ones included).
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
            && z(&self.periodic_sin)
            && z(&self.periodic_cos)
            && self
                .lumped_compliance
                .iter()
                .flatten()
                .all(|c| c.iter().all(|&x| x == 0.0))
    }

    /// Checks the errors against a model: every per-joint vector has one entry per chain joint
    /// (`model.chain_joints().len()`, which is `model.dof()` without coupled joints), all values
    /// are finite, and a prismatic joint has no periodic term. Errors name the field and the
    /// (1-based) joint. (Deserialised errors without the periodic fields have them empty: set them
    /// to `vec![0.0; dof]`.)
    pub fn check(&self, model: &RobotModel) -> Result<(), KinematicsError> {
        let n = model.chain_joints().len();
        // Formed only for a message: this check runs at every evaluation of the fits.
        let joints_text = || {
            if model.has_coupled_joints() {
                format!(
                    "{n} chain joints ({} independent, the coupled ones included)",
                    model.dof()
                )
            } else {
                format!("{n} joints")
            }
        };
        let lens = [
            ("joint_offset", self.joint_offset.len()),
            ("joint_scale", self.joint_scale.len()),
            ("origin_xyz", self.origin_xyz.len()),
            ("origin_rpy", self.origin_rpy.len()),
            ("compliance", self.compliance.len()),
            ("periodic_sin", self.periodic_sin.len()),
            ("periodic_cos", self.periodic_cos.len()),
        ];
        for (field, len) in lens {
            if len != n {
                return Err(KinematicsError::InvalidInput(format!(
                    "kinematic errors: `{field}` has {len} entries but {} has {}; give \
                     one value per joint (KinematicErrors::zero({n}) has the right shape)",
                    model.name(),
                    joints_text()
                )));
            }
        }
        let bad = |field: &str, joint: Option<usize>, v: f64| {
            let at = joint.map_or(String::new(), |j| {
                format!(" of joint {} ({})", j + 1, model.chain_joints()[j].name)
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
                ("periodic_sin", self.periodic_sin[j]),
                ("periodic_cos", self.periodic_cos[j]),
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
            let joint = &model.chain_joints()[j];
            if joint.kind.is_prismatic() {
                for (field, v) in [
                    ("periodic_sin", self.periodic_sin[j]),
                    ("periodic_cos", self.periodic_cos[j]),
                ] {
                    if v != 0.0 {
                        return Err(KinematicsError::InvalidInput(format!(
                            "kinematic errors: `{field}` of joint {} ({}) is {v}, but the joint \
                             is prismatic: a periodic term is a once-per-turn error of a rotary \
                             joint (sin and cos of a length in metres mean nothing); set it to 0",
                            j + 1,
                            joint.name
                        )));
                    }
                }
            }
        }
        crate::lumped::check_lumped(model, &self.lumped_compliance)?;
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
            ErrorParam::PeriodicSin { joint } => self.periodic_sin[joint],
            ErrorParam::PeriodicCos { joint } => self.periodic_cos[joint],
            ErrorParam::LumpedCompliance { joint, link, axis } => self
                .lumped_compliance
                .get(joint)
                .and_then(|row| row.get(link.wrapping_sub(joint)))
                .map_or(0.0, |c| c[axis.index()]),
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
            ErrorParam::PeriodicSin { joint } => &mut self.periodic_sin[joint],
            ErrorParam::PeriodicCos { joint } => &mut self.periodic_cos[joint],
            ErrorParam::LumpedCompliance { joint, link, axis } => {
                if self.lumped_compliance.is_empty() {
                    self.lumped_compliance = crate::lumped::lumped_zero(self.dof());
                }
                &mut self.lumped_compliance[joint][link - joint][axis.index()]
            }
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
    /// `joint_offset[joint]`, rad (m for a prismatic joint).
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
    /// `compliance[joint]`, rad/(N·m) (m/N for a prismatic joint).
    Compliance {
        /// 0-based joint index.
        joint: usize,
    },
    /// `periodic_sin[joint]`, rad (amplitude of the `sin(q_rep)` term of the true angle).
    PeriodicSin {
        /// 0-based joint index.
        joint: usize,
    },
    /// `periodic_cos[joint]`, rad (amplitude of the `cos(q_rep)` term of the true angle).
    PeriodicCos {
        /// 0-based joint index.
        joint: usize,
    },
    /// `lumped_compliance[joint][link − joint][axis]`, rad: the lumped gravity compliance of
    /// rotary chain joint `joint` from the mass carried at and beyond chain link `link ≥ joint`,
    /// component `axis` of link `link`'s frame ([`crate::lumped`]).
    LumpedCompliance {
        /// 0-based index of the deflecting (rotary) chain joint.
        joint: usize,
        /// 0-based index of the carried chain link (the child link of chain joint `link`).
        link: usize,
        /// Component, in that link's frame.
        axis: Axis,
    },
}

impl ErrorParam {
    /// The field name: `"joint_offset"`, `"joint_scale"`, `"origin_xyz"`, `"origin_rpy"`, `"tip"`,
    /// `"mount_xyz"`, `"mount_rpy"`, `"compliance"`, `"periodic_sin"` or `"periodic_cos"`.
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
            ErrorParam::PeriodicSin { .. } => "periodic_sin",
            ErrorParam::PeriodicCos { .. } => "periodic_cos",
            ErrorParam::LumpedCompliance { .. } => "lumped_compliance",
        }
    }

    /// The SI unit of the value for a rotary joint: `"rad"`, `"ratio"`, `"m"` or `"rad/(N·m)"`
    /// (for a parameter of a given model's joint, [`ErrorParam::unit_si_in`]).
    pub fn unit_si(self) -> &'static str {
        match self {
            ErrorParam::JointOffset { .. }
            | ErrorParam::OriginRpy { .. }
            | ErrorParam::MountRpy { .. }
            | ErrorParam::PeriodicSin { .. }
            | ErrorParam::PeriodicCos { .. }
            | ErrorParam::LumpedCompliance { .. } => "rad",
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
            | ErrorParam::Compliance { joint }
            | ErrorParam::PeriodicSin { joint }
            | ErrorParam::PeriodicCos { joint }
            | ErrorParam::LumpedCompliance { joint, .. } => Some(joint),
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
            | ErrorParam::MountRpy { axis }
            | ErrorParam::LumpedCompliance { axis, .. } => Some(axis),
            _ => None,
        }
    }

    /// The SI unit of the value in `model`: [`ErrorParam::unit_si`], except for a prismatic
    /// joint's offset (`"m"`) and compliance (`"m/N"`). A joint index outside the chain gives
    /// [`ErrorParam::unit_si`].
    pub fn unit_si_in(self, model: &RobotModel) -> &'static str {
        let prismatic = self
            .joint()
            .and_then(|j| model.chain_joints().get(j))
            .is_some_and(|j| j.kind.is_prismatic());
        match self {
            ErrorParam::JointOffset { .. } if prismatic => "m",
            ErrorParam::Compliance { .. } if prismatic => "m/N",
            _ => self.unit_si(),
        }
    }

    /// Checks the parameter against `model`: the joint index is a chain joint's
    /// (`< model.chain_joints().len()`), and a periodic parameter is not a prismatic joint's.
    ///
    /// Errors: either is violated (the message names the joint and the fix).
    pub fn check_model(self, model: &RobotModel) -> Result<(), KinematicsError> {
        self.check_dof(model.chain_joints().len())?;
        if let ErrorParam::LumpedCompliance { joint, link, axis } = self {
            crate::lumped::check_lumped_param(model, joint, link, axis)?;
        }
        if let ErrorParam::PeriodicSin { joint } | ErrorParam::PeriodicCos { joint } = self {
            let j = &model.chain_joints()[joint];
            if j.kind.is_prismatic() {
                return Err(KinematicsError::InvalidInput(format!(
                    "error parameter {self}: joint {} ({}) is prismatic, and a periodic term is a \
                     once-per-turn error of a rotary joint; leave it out (all_params_for lists \
                     the parameters of a model)",
                    joint + 1,
                    j.name
                )));
            }
        }
        Ok(())
    }

    /// Checks the joint index against a chain of `dof` joints.
    ///
    /// Errors: the joint index is `≥ dof`.
    pub fn check_dof(self, dof: usize) -> Result<(), KinematicsError> {
        if let ErrorParam::LumpedCompliance { joint, link, .. } = self {
            if link < joint || link >= dof {
                return Err(KinematicsError::InvalidInput(format!(
                    "error parameter {self}: link {} is not a link joint {} carries in a chain \
                     of {dof} joints; give a link from {} to {dof}",
                    link + 1,
                    joint + 1,
                    joint + 1
                )));
            }
        }
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
        if let ErrorParam::LumpedCompliance { link, .. } = self {
            write!(f, " link {}", link + 1)?;
        }
        if let Some(a) = self.axis() {
            write!(f, " {a}")?;
        }
        Ok(())
    }
}

/// The whole catalogue of parameters for a chain of `dof` rotary joints, in a fixed order: per
/// joint (offset, scale, origin xyz x/y/z, origin rpy x/y/z, compliance, periodic sin, periodic
/// cos), then tip x/y/z, mount xyz x/y/z, mount rpy x/y/z. `11·dof + 9` entries. For a model with
/// prismatic joints use [`all_params_for`].
pub fn all_params(dof: usize) -> Vec<ErrorParam> {
    let mut v = Vec::with_capacity(11 * dof + 9);
    for joint in 0..dof {
        v.push(ErrorParam::JointOffset { joint });
        v.push(ErrorParam::JointScale { joint });
        v.extend(Axis::ALL.map(|axis| ErrorParam::OriginXyz { joint, axis }));
        v.extend(Axis::ALL.map(|axis| ErrorParam::OriginRpy { joint, axis }));
        v.push(ErrorParam::Compliance { joint });
        v.push(ErrorParam::PeriodicSin { joint });
        v.push(ErrorParam::PeriodicCos { joint });
    }
    v.extend(Axis::ALL.map(|axis| ErrorParam::Tip { axis }));
    v.extend(Axis::ALL.map(|axis| ErrorParam::MountXyz { axis }));
    v.extend(Axis::ALL.map(|axis| ErrorParam::MountRpy { axis }));
    v
}

/// The catalogue of [`all_params`] for `model`'s chain joints
/// (`model.chain_joints().len()`), without the periodic parameters of prismatic joints, which
/// have none: the parameters [`crate::tip_error_jacobian`] accepts for it.
pub fn all_params_for(model: &RobotModel) -> Vec<ErrorParam> {
    let chain = model.chain_joints();
    all_params(chain.len())
        .into_iter()
        .filter(|p| match *p {
            ErrorParam::PeriodicSin { joint } | ErrorParam::PeriodicCos { joint } => {
                !chain[joint].kind.is_prismatic()
            }
            _ => true,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_get_set_and_display() {
        let dof = 6;
        let params = all_params(dof);
        assert_eq!(params.len(), 11 * dof + 9);
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
        assert_eq!(ErrorParam::PeriodicSin { joint: 0 }.unit_si(), "rad");
        assert_eq!(
            ErrorParam::PeriodicCos { joint: 2 }.to_string(),
            "periodic_cos joint 3"
        );
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
}

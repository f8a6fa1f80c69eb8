//! The TRUE robot of the kinematic-error model (see `error_model.rs` for the parameters and how
//! each one enters): its flange and tip poses in the NOMINAL base frame ([`true_base_from_flange`],
//! [`true_base_from_tip`]) and their exact analytic derivatives with respect to the error
//! parameters ([`tip_error_jacobian`]) and the reported joint values ([`tip_joint_jacobian_true`]).
//!
//! The errors have one entry per chain joint ([`RobotModel::chain_joints`]); `q_rep` holds the
//! independent joints, and a coupled joint's reported value is its coupling evaluated at `q_rep`
//! (its own offset, scale and compliance then apply to that value).

use nalgebra::{Isometry3, Matrix3, Matrix3xX, Vector3};

use crate::error::KinematicsError;
use crate::error_model::{ErrorParam, KinematicErrors};
use crate::fk::{
    apply_step, base_from_tip_unchecked, check_tip, isometry, sin_cos, tip_isometry,
    to_flange_nalgebra,
};
use crate::gravity::{
    check_gravity, gravity_entries, gravity_jacobian_from_entries, gravity_torques_into,
    GravityEntry, STACK_DOF,
};
use crate::model::{rotation_from_rpy, RobotModel, Step, PRISMATIC};

/// Per-joint frame data of the true chain, nominal base frame.
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrueJointFrame {
    /// Rotation `nominal_base_from_parent` (the joint's URDF parent link frame).
    parent_rotation: Matrix3<f64>,
    /// The joint origin's true rpy (nominal + error), rad: [`rpy_derivative_axes`] of it and
    /// `parent_rotation` gives the origin-rpy Jacobian axes (computed only for the origin-rpy
    /// columns asked for).
    rpy: Vector3<f64>,
    /// Origin of the joint frame before the joint's motion, m (for a rotary joint the same as
    /// after it): the pivot of an origin-rpy error and the point on a rotary axis.
    o: Vector3<f64>,
    /// Joint axis, unit.
    z: Vector3<f64>,
    /// A prismatic joint: `∂p/∂q_true` is `z`, not `z × (p − o)`.
    prismatic: bool,
}

impl TrueJointFrame {
    /// `∂p/∂q_true` of this joint for the tip at `p`: `z × (p − o)` (rotary, per rad) or `z`
    /// (prismatic, per m).
    #[inline]
    pub(crate) fn joint_column(&self, p: &Vector3<f64>) -> Vector3<f64> {
        if self.prismatic {
            self.z
        } else {
            self.z.cross(&(p - self.o))
        }
    }
}

impl Default for TrueJointFrame {
    fn default() -> Self {
        Self {
            parent_rotation: Matrix3::identity(),
            rpy: Vector3::zeros(),
            o: Vector3::zeros(),
            z: Vector3::zeros(),
            prismatic: false,
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

/// The true joint values into `q_true` (len = chain joints), with the nominal gravity torques
/// into `tau` (zeros if no compliance is set and `need_tau` is false), from the reported
/// independent values `q_rep`. Returns the chain's reported values (`q_rep` itself without
/// coupled joints, else computed into `buf`). No checks.
fn true_joint_angles<'a>(
    model: &RobotModel,
    errors: &KinematicErrors,
    (q_rep, buf): (&'a [f64], &'a mut Vec<f64>),
    g_base: &Vector3<f64>,
    need_tau: bool,
    tau: &mut [f64],
    q_true: &mut [f64],
) -> &'a [f64] {
    if need_tau || !all_zero(&errors.compliance) {
        gravity_torques_into(model, q_rep, g_base, tau);
    } else {
        tau.iter_mut().for_each(|t| *t = 0.0);
    }
    if !errors.lumped_compliance.is_empty() {
        // Before the chain values borrow `buf`: the lumped walk forms its own.
        let mut lumped = vec![0.0; q_true.len()];
        crate::lumped::add_lumped_deflections(
            model,
            &errors.lumped_compliance,
            q_rep,
            g_base,
            &mut lumped,
        );
        let q_rep_chain = model.chain_q(q_rep, buf);
        true_angles_of_chain(errors, q_rep_chain, tau, q_true);
        for (q, d) in q_true.iter_mut().zip(lumped) {
            *q += d;
        }
        return q_rep_chain;
    }
    let q_rep_chain = model.chain_q(q_rep, buf);
    true_angles_of_chain(errors, q_rep_chain, tau, q_true);
    q_rep_chain
}

/// The per-joint part of [`true_joint_angles`]: `q_true` from the chain's reported values and
/// the torques.
fn true_angles_of_chain(errors: &KinematicErrors, q_rep: &[f64], tau: &[f64], q_true: &mut [f64]) {
    for i in 0..q_rep.len() {
        q_true[i] = q_rep[i] * (1.0 + errors.joint_scale[i])
            + errors.joint_offset[i]
            + errors.compliance[i] * tau[i];
    }
    // Skipped when zero, so that errors without the periodic terms give bit-identical angles.
    if !(all_zero(&errors.periodic_sin) && all_zero(&errors.periodic_cos)) {
        for i in 0..q_rep.len() {
            let (s, c) = sin_cos(q_rep[i]);
            q_true[i] += errors.periodic_sin[i] * s + errors.periodic_cos[i] * c;
        }
    }
}

/// `∂q_true_i/∂q_rep_i` of chain joint i (the chain rule factor apart from compliance), at the
/// chain's reported values: `1 + joint_scale_i + periodic_sin_i·cos(q_rep_i) −
/// periodic_cos_i·sin(q_rep_i)`.
fn joint_rate(errors: &KinematicErrors, q_rep: &[f64], i: usize) -> f64 {
    let (s, c) = sin_cos(q_rep[i]);
    1.0 + errors.joint_scale[i] + errors.periodic_sin[i] * c - errors.periodic_cos[i] * s
}

/// The true chain at the true joint values: `nominal_base_from_flange` as (rotation matrix,
/// translation in m), filling `frames` (if given, len = chain joints). No checks, no allocation.
///
/// Joints without origin error go through the nominal FK step ([`apply_step`]) unchanged; a joint
/// with an origin error goes through the same step with its origin replaced by
/// `fixed_prefix · Origin(xyz + Δxyz, rpy + Δrpy)`.
fn true_chain(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_true: &[f64],
    frames: Option<&mut [TrueJointFrame]>,
    prep: Option<&ChainPrep>,
) -> (Matrix3<f64>, Vector3<f64>) {
    if model.prismatic {
        true_chain_k::<true>(model, errors, q_true, frames, prep)
    } else {
        true_chain_k::<false>(model, errors, q_true, frames, prep)
    }
}

/// What [`true_chain`] and [`fill_error_columns`] compute from the errors alone, formed once for
/// many joint vectors ([`PreparedTip`]): the same expressions, so the same values, as they
/// compute at each call without it.
#[derive(Debug, Clone)]
struct ChainPrep {
    /// The mount rotation, `None` when the mount has no error.
    mount_r: Option<Matrix3<f64>>,
    /// Per chain joint: its step with the origin error applied (`None`: no origin error, the
    /// nominal step).
    steps: Vec<Option<Step>>,
    /// Per chain joint: the origin-rpy derivative axes of roll and pitch in the parent link's
    /// frame ([`rpy_local_axes`] at the true rpy).
    rpy_local: Vec<[Vector3<f64>; 2]>,
    /// The mount-rpy derivative axes ([`rpy_derivative_axes`] with `R_P = I`).
    mount_axes: [Vector3<f64>; 3],
}

impl ChainPrep {
    /// The prepared chain of `model` with `errors` (checked by the caller).
    fn new(model: &RobotModel, errors: &KinematicErrors) -> Self {
        let mount_zero =
            all_zero(errors.mount_xyz.as_slice()) && all_zero(errors.mount_rpy.as_slice());
        let steps = model
            .steps
            .iter()
            .zip(model.chain_joints())
            .enumerate()
            .map(|(k, (step, joint))| {
                let dxyz = &errors.origin_xyz[k];
                let drpy = &errors.origin_rpy[k];
                let origin_zero = all_zero(dxyz.as_slice()) && all_zero(drpy.as_slice());
                (!origin_zero).then(|| perturbed_step(step, joint, dxyz, drpy))
            })
            .collect();
        let rpy_local = model
            .chain_joints()
            .iter()
            .enumerate()
            .map(|(k, joint)| rpy_local_axes(&(joint.origin_rpy + errors.origin_rpy[k])))
            .collect();
        ChainPrep {
            mount_r: (!mount_zero).then(|| *rotation_from_rpy(&errors.mount_rpy).matrix()),
            steps,
            rpy_local,
            mount_axes: rpy_derivative_axes(&Matrix3::identity(), &errors.mount_rpy),
        }
    }
}

/// The rotation of a joint's fixed prefix (the identity exactly when it has none).
#[inline(always)]
fn prefix_rotation(joint: &crate::model::Joint) -> Matrix3<f64> {
    if joint.fixed_prefix.rotation.w == 1.0 {
        Matrix3::identity()
    } else {
        *joint.fixed_prefix.rotation.to_rotation_matrix().matrix()
    }
}

/// A joint's FK step with its origin replaced by `fixed_prefix · Origin(xyz + dxyz, rpy + drpy)`.
#[inline(always)]
fn perturbed_step(
    step: &Step,
    joint: &crate::model::Joint,
    dxyz: &Vector3<f64>,
    drpy: &Vector3<f64>,
) -> Step {
    let fp = &joint.fixed_prefix;
    let fp_r = prefix_rotation(joint);
    let origin_r = if all_zero(drpy.as_slice()) {
        step.origin.r
    } else {
        fp_r * rotation_from_rpy(&(joint.origin_rpy + drpy)).matrix()
    };
    Step::new(
        step.axis,
        origin_r,
        fp.translation.vector + fp_r * (joint.origin_xyz + dxyz),
        step.axis_kind == PRISMATIC,
    )
}

/// [`true_chain`] for a chain that may (or, `false`, does not) hold prismatic joints.
#[inline(always)]
fn true_chain_k<const MAY_BE_PRISMATIC: bool>(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_true: &[f64],
    mut frames: Option<&mut [TrueJointFrame]>,
    prep: Option<&ChainPrep>,
) -> (Matrix3<f64>, Vector3<f64>) {
    let mount_zero = all_zero(errors.mount_xyz.as_slice()) && all_zero(errors.mount_rpy.as_slice());
    let (mut r, mut t) = if mount_zero {
        (Matrix3::identity(), Vector3::zeros())
    } else {
        (
            match prep.and_then(|p| p.mount_r) {
                Some(mount_r) => mount_r,
                None => *rotation_from_rpy(&errors.mount_rpy).matrix(),
            },
            errors.mount_xyz,
        )
    };
    for (k, ((step, joint), &qk)) in model
        .steps
        .iter()
        .zip(model.chain_joints())
        .zip(q_true)
        .enumerate()
    {
        let dxyz = &errors.origin_xyz[k];
        let drpy = &errors.origin_rpy[k];
        let origin_zero = all_zero(dxyz.as_slice()) && all_zero(drpy.as_slice());
        let parent_rotation = frames.as_ref().map(|_| r * prefix_rotation(joint));
        if origin_zero {
            // The nominal step, so that zero errors reproduce the nominal FK.
            apply_step::<MAY_BE_PRISMATIC>(&mut r, &mut t, step, qk);
        } else {
            match prep.and_then(|p| p.steps[k].as_ref()) {
                Some(perturbed) => apply_step::<MAY_BE_PRISMATIC>(&mut r, &mut t, perturbed, qk),
                None => {
                    let perturbed = perturbed_step(step, joint, dxyz, drpy);
                    apply_step::<MAY_BE_PRISMATIC>(&mut r, &mut t, &perturbed, qk);
                }
            }
        }
        if let (Some(f), Some(parent_rotation)) = (frames.as_deref_mut(), parent_rotation) {
            let z = r * step.axis.into_inner();
            let prismatic = MAY_BE_PRISMATIC && step.axis_kind == PRISMATIC;
            f[k] = TrueJointFrame {
                parent_rotation,
                rpy: joint.origin_rpy + drpy,
                // A prismatic joint's frame moved by z·q along its axis; its origin is before.
                o: if prismatic { t - z * qk } else { t },
                z,
                prismatic,
            };
        }
    }
    to_flange_nalgebra(model, &mut r, &mut t);
    (r, t)
}

/// Runs `f` with two scratch slices of length `dof` (on the stack for `dof ≤ 16`; `dof` here
/// is the number of chain joints).
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

/// `true_base_from_flange` without checks (allocation-free for `dof ≤ 16` without coupled joints); see
/// [`true_base_from_flange`]. Panics only if the lengths do not match the model.
pub fn true_base_from_flange_unchecked(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
) -> Isometry3<f64> {
    let (r, t) = true_flange_rt(model, errors, q_rep, g_base, None);
    isometry(&r, &t)
}

/// The true flange as (rotation matrix, translation), no checks, no allocation for `dof ≤ 16`.
fn true_flange_rt(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    g_base: &Vector3<f64>,
    prep: Option<&ChainPrep>,
) -> (Matrix3<f64>, Vector3<f64>) {
    with_scratch(model.chain_joints().len(), |tau, q_true| {
        let mut buf = Vec::new();
        true_joint_angles(model, errors, (q_rep, &mut buf), g_base, false, tau, q_true);
        true_chain(model, errors, q_true, None, prep)
    })
}

/// Flange pose of the TRUE robot (nominal model + `errors`) in the NOMINAL base frame, at the
/// reported independent joint values `q_rep` (rad, or m for a prismatic joint); `g_base` is the gravity acceleration in the nominal base
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

/// `true_base_from_tip` without checks (allocation-free for `dof ≤ 16` without coupled joints); see
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
    true_tip_general(model, errors, q_rep, flange_from_tip, g_base, None)
}

/// The general path of [`true_base_from_tip_unchecked`] (no zero-error shortcut).
fn true_tip_general(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    prep: Option<&ChainPrep>,
) -> Isometry3<f64> {
    let (r, t) = true_flange_rt(model, errors, q_rep, g_base, prep);
    tip_isometry(&r, &t, &(flange_from_tip + errors.tip))
}

/// Tip pose of the TRUE robot in the NOMINAL base frame at the reported independent joint values
/// `q_rep` (rad, or m for a prismatic joint):
/// the nominal chain with `errors` applied as described in the module documentation, tip offset
/// `flange_from_tip + errors.tip` (m, flange axes), orientation the flange's. `g_base` is the gravity
/// acceleration in the nominal base frame, m/s² (used only through `errors.compliance`).
///
/// With [`KinematicErrors::zero`] it equals [`base_from_tip`](crate::base_from_tip) exactly.
/// Allocation-free for chains of up to 16 joints without coupled joints (a coupled chain computes
/// its chain values into a vector).
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
    let [roll, pitch] = rpy_local_axes(rpy);
    [
        parent_rotation * roll,
        parent_rotation * pitch,
        parent_rotation * Vector3::z(),
    ]
}

/// The roll and pitch axes of [`rpy_derivative_axes`] before `R_parent`:
/// `(cy·cp, sy·cp, −sp)` and `(−sy, cy, 0)`.
#[inline(always)]
fn rpy_local_axes(rpy: &Vector3<f64>) -> [Vector3<f64>; 2] {
    let (sp, cp) = sin_cos(rpy.y);
    let (sy, cy) = sin_cos(rpy.z);
    [
        Vector3::new(cy * cp, sy * cp, -sp),
        Vector3::new(-sy, cy, 0.0),
    ]
}

/// `∂p_tip/∂param`, m per parameter unit, 3 × `params.len()`, nominal base axes: the exact analytic
/// derivative of the position of [`true_base_from_tip`] with respect to each listed parameter, at
/// the given `errors` (not only at zero).
///
/// Columns, with `p` the true tip, `o_k`, `z_k` joint k's true origin and axis, `R_P` the rotation
/// of its parent link frame (all in the nominal base frame), `q_rep_k` chain joint k's reported
/// value (a coupled joint's from its coupling):
/// - joint offset: `z_k × (p − o_k)` (m/rad) for a rotary joint, `z_k` (m/m) for a prismatic one;
///   scale: that × `q_rep_k`; compliance: that × `τ_k(q_rep)` (N·m, or the force in N along a
///   prismatic axis); periodic sin / cos (rotary joints only): that × `sin(q_rep_k)` /
///   `cos(q_rep_k)`;
/// - origin xyz: `R_P·e_axis`; origin rpy: `a × (p − o_k)` with `a = R_P·e_z` (yaw),
///   `R_P·Rz(yaw)·e_y` (pitch), `R_P·Rz(yaw)·Ry(pitch)·e_x` (roll) at the true rpy;
/// - tip: `R_flange·e_axis`; mount xyz: `e_axis`; mount rpy: `a × (p − mount_xyz)` with the same
///   axes as the origin rpy, `R_P = I`.
///
/// Errors: as [`true_base_from_tip`], plus a parameter whose joint index is not a chain joint's
/// or a periodic parameter of a prismatic joint ([`ErrorParam::check_model`]).
pub fn tip_error_jacobian(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> Result<Matrix3xX<f64>, KinematicsError> {
    model.check_q(q_rep)?;
    check_tip_inputs(model, errors, flange_from_tip, g_base, params)?;
    Ok(tip_error_jacobian_unchecked(
        model,
        errors,
        q_rep,
        flange_from_tip,
        g_base,
        params,
    ))
}

/// [`tip_error_jacobian`] without checks: the caller has run [`check_tip_inputs`] on these
/// `errors`, tip, gravity and `params`, and [`RobotModel::check_q`] on `q_rep` (the same columns,
/// bit for bit, as the checked call; for a caller that evaluates many joint vectors at the same
/// errors and checks them once). Panics only if the lengths do not match the model.
pub fn tip_error_jacobian_unchecked(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> Matrix3xX<f64> {
    let mut jac = Matrix3xX::zeros(params.len());
    error_jacobian_walk(
        model,
        errors,
        q_rep,
        flange_from_tip,
        g_base,
        params,
        &mut jac,
        None,
    );
    jac
}

/// One walk of the true chain filling `jac` with the columns of [`tip_error_jacobian`]; returns
/// the flange (rotation, translation). No checks.
#[allow(clippy::too_many_arguments)]
fn error_jacobian_walk(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
    jac: &mut Matrix3xX<f64>,
    prep: Option<&ChainPrep>,
) -> (Matrix3<f64>, Vector3<f64>) {
    with_chain_scratch(model.chain_joints().len(), |tau, q_true, frames| {
        // Compliance columns need τ even when no compliance is set.
        let need_tau = params
            .iter()
            .any(|p| matches!(p, ErrorParam::Compliance { .. }));
        let mut buf = Vec::new();
        let q_rep_chain = true_joint_angles(
            model,
            errors,
            (q_rep, &mut buf),
            g_base,
            need_tau,
            tau,
            q_true,
        );
        let (flange_r, flange_t) = true_chain(model, errors, q_true, Some(frames), prep);
        let p = flange_t + flange_r * (flange_from_tip + errors.tip);
        fill_error_columns(
            errors,
            q_rep_chain,
            tau,
            frames,
            &flange_r,
            &p,
            params,
            jac,
            prep,
        );
        crate::lumped::fill_lumped_columns(model, q_rep, g_base, frames, &p, params, jac);
        (flange_r, flange_t)
    })
}

/// [`true_base_from_tip`] and [`tip_error_jacobian`] at the same inputs from one walk of the
/// true chain (the whole-cell fit wants both at every observation): the same two values, bit for
/// bit, as the two calls, for a little more than the price of the Jacobian alone.
///
/// Two cases still walk the chain twice, so that the pose stays the one
/// [`true_base_from_tip`] gives: `errors` all zero (the pose is the nominal FK's), and
/// compliance columns asked for while every compliance is zero (the Jacobian's true angles
/// then add `0·τ`, whose sign of zero may differ from the pose's).
///
/// Errors: as [`tip_error_jacobian`].
pub fn true_tip_with_error_jacobian(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> Result<(Isometry3<f64>, Matrix3xX<f64>), KinematicsError> {
    model.check_q(q_rep)?;
    check_tip_inputs(model, errors, flange_from_tip, g_base, params)?;
    Ok(true_tip_with_error_jacobian_unchecked(
        model,
        errors,
        q_rep,
        flange_from_tip,
        g_base,
        params,
    ))
}

/// The checks of [`true_tip_with_error_jacobian`] (and of [`true_base_from_tip`] and
/// [`tip_error_jacobian`]) that do not depend on the joint values, in their order after
/// [`RobotModel::check_q`]: a non-finite tip offset or `g_base`, `errors` of the wrong shape or
/// non-finite ([`KinematicErrors::check`]), then each of `params`
/// ([`ErrorParam::check_model`]). A caller that evaluates many joint vectors at the same errors
/// builds a [`PreparedTip`] (which runs this once), or runs this once, then
/// [`RobotModel::check_q`] and the `_unchecked` functions per vector.
pub fn check_tip_inputs(
    model: &RobotModel,
    errors: &KinematicErrors,
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> Result<(), KinematicsError> {
    check_tip(flange_from_tip)?;
    check_gravity(g_base)?;
    errors.check(model)?;
    for p in params {
        p.check_model(model)?;
    }
    Ok(())
}

/// [`true_tip_with_error_jacobian`] without checks: the caller has run [`check_tip_inputs`] on
/// these `errors`, tip, gravity and `params`, and [`RobotModel::check_q`] on `q_rep` (the same
/// values, bit for bit, as the checked call). Panics only if the lengths do not match the model.
/// [`PreparedTip`] is the safe form for many joint vectors at the same inputs (checked once,
/// then only the joint values; no panic) and is faster (the errors' chain prepared once).
pub fn true_tip_with_error_jacobian_unchecked(
    model: &RobotModel,
    errors: &KinematicErrors,
    q_rep: &[f64],
    flange_from_tip: &Vector3<f64>,
    g_base: &Vector3<f64>,
    params: &[ErrorParam],
) -> (Isometry3<f64>, Matrix3xX<f64>) {
    let need_tau = params
        .iter()
        .any(|p| matches!(p, ErrorParam::Compliance { .. }));
    let two_walks = errors.is_zero() || (need_tau && all_zero(&errors.compliance));
    let inputs = (model, errors, flange_from_tip, g_base, params);
    tip_with_error_jacobian_walks(inputs, q_rep, two_walks, None)
}

/// The body of [`true_tip_with_error_jacobian_unchecked`], with its choice of one or two walks
/// (`two_walks`) and the errors' prepared chain if any.
fn tip_with_error_jacobian_walks(
    (model, errors, flange_from_tip, g_base, params): TipInputs<'_>,
    q_rep: &[f64],
    two_walks: bool,
    prep: Option<&ChainPrep>,
) -> (Isometry3<f64>, Matrix3xX<f64>) {
    let mut jac = Matrix3xX::zeros(params.len());
    let walk = |jac: &mut Matrix3xX<f64>| {
        error_jacobian_walk(
            model,
            errors,
            q_rep,
            flange_from_tip,
            g_base,
            params,
            jac,
            prep,
        )
    };
    if two_walks {
        let pose = if errors.is_zero() {
            base_from_tip_unchecked(model, q_rep, flange_from_tip)
        } else {
            true_tip_general(model, errors, q_rep, flange_from_tip, g_base, prep)
        };
        walk(&mut jac);
        return (pose, jac);
    }
    let (flange_r, flange_t) = walk(&mut jac);
    // The pose as `true_tip_general` forms it from the same flange.
    let pose = tip_isometry(&flange_r, &flange_t, &(flange_from_tip + errors.tip));
    (pose, jac)
}

/// A robot model, its errors, the tip offset, gravity and the Jacobian's parameters.
type TipInputs<'a> = (
    &'a RobotModel,
    &'a KinematicErrors,
    &'a Vector3<f64>,
    &'a Vector3<f64>,
    &'a [ErrorParam],
);

/// The inputs of [`true_tip_with_error_jacobian`] that do not depend on the joint values,
/// checked once ([`check_tip_inputs`]) and prepared for evaluating many joint vectors: each
/// joint's origin error applied to its step and the rotation-error axes formed once, not at
/// every joint vector. Its methods give the same values, bit for bit, as the checked functions
/// at the same inputs, and check only the joint values; a value of this type cannot be built
/// from unchecked inputs, so its methods cannot panic on a length mismatch.
///
/// # Examples
/// ```
/// # use kinematics::{true_tip_with_error_jacobian, ErrorParam, KinematicErrors, PreparedTip, RobotModel};
/// # use nalgebra::Vector3;
/// let urdf = r#"<robot name="arm">
///   <link name="base"/><link name="tool0"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="tool0"/>
///     <origin xyz="0 0 0.5"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
/// </robot>"#;
/// let model = RobotModel::from_urdf_str(urdf, "tool0").unwrap();
/// let (tip, g) = (Vector3::new(1.0, 0.0, 0.0), Vector3::new(0.0, 0.0, -9.81));
/// let mut errors = KinematicErrors::zero(1);
/// errors.set(ErrorParam::JointOffset { joint: 0 }, 0.01);
/// let params = [ErrorParam::JointOffset { joint: 0 }];
/// let prepared = PreparedTip::new(&model, &errors, &tip, &g, &params).unwrap();
/// for q in [0.0, 0.5, 1.0] {
///     let once = prepared.tip_with_error_jacobian(&[q]).unwrap();
///     assert_eq!(once, true_tip_with_error_jacobian(&model, &errors, &[q], &tip, &g, &params).unwrap());
/// }
/// assert!(prepared.tip_with_error_jacobian(&[0.0, 1.0]).is_err()); // a wrong length is an error
/// ```
#[derive(Debug, Clone)]
pub struct PreparedTip<'m> {
    model: &'m RobotModel,
    errors: KinematicErrors,
    flange_from_tip: Vector3<f64>,
    g_base: Vector3<f64>,
    params: Vec<ErrorParam>,
    /// Whether [`true_tip_with_error_jacobian_unchecked`] walks the chain twice at these inputs.
    two_walks: bool,
    chain: ChainPrep,
}

impl<'m> PreparedTip<'m> {
    /// Checks the inputs ([`check_tip_inputs`]: its errors, in its order) and prepares them.
    pub fn new(
        model: &'m RobotModel,
        errors: &KinematicErrors,
        flange_from_tip: &Vector3<f64>,
        g_base: &Vector3<f64>,
        params: &[ErrorParam],
    ) -> Result<Self, KinematicsError> {
        check_tip_inputs(model, errors, flange_from_tip, g_base, params)?;
        let need_tau = params
            .iter()
            .any(|p| matches!(p, ErrorParam::Compliance { .. }));
        Ok(PreparedTip {
            model,
            errors: errors.clone(),
            flange_from_tip: *flange_from_tip,
            g_base: *g_base,
            params: params.to_vec(),
            two_walks: errors.is_zero() || (need_tau && all_zero(&errors.compliance)),
            chain: ChainPrep::new(model, errors),
        })
    }

    /// The errors it was prepared with.
    pub fn errors(&self) -> &KinematicErrors {
        &self.errors
    }

    /// [`true_tip_with_error_jacobian`] at `q_rep` (the same values).
    ///
    /// Errors: a bad `q_rep` ([`RobotModel::check_q`]).
    pub fn tip_with_error_jacobian(
        &self,
        q_rep: &[f64],
    ) -> Result<(Isometry3<f64>, Matrix3xX<f64>), KinematicsError> {
        self.model.check_q(q_rep)?;
        let inputs = (
            self.model,
            &self.errors,
            &self.flange_from_tip,
            &self.g_base,
            self.params.as_slice(),
        );
        Ok(tip_with_error_jacobian_walks(
            inputs,
            q_rep,
            self.two_walks,
            Some(&self.chain),
        ))
    }

    /// [`true_base_from_tip`] at `q_rep` (the same value).
    ///
    /// Errors: a bad `q_rep` ([`RobotModel::check_q`]).
    pub fn tip(&self, q_rep: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
        self.model.check_q(q_rep)?;
        let (model, t) = (self.model, &self.flange_from_tip);
        Ok(if self.errors.is_zero() {
            base_from_tip_unchecked(model, q_rep, t)
        } else {
            true_tip_general(
                model,
                &self.errors,
                q_rep,
                t,
                &self.g_base,
                Some(&self.chain),
            )
        })
    }
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
    prep: Option<&ChainPrep>,
) {
    let p = *p;
    let mount_axes = match prep {
        Some(prep) => prep.mount_axes,
        None => rpy_derivative_axes(&Matrix3::identity(), &errors.mount_rpy),
    };
    // The last joint's origin-rpy axes: a joint's three rpy columns are usually asked for
    // together, and the axes (two sines and cosines) are the same for all three.
    let mut rpy_axes: Option<(usize, [Vector3<f64>; 3])> = None;
    for (c, param) in params.iter().enumerate() {
        let joint_col = |k: usize| frames[k].joint_column(&p);
        let col = match *param {
            ErrorParam::JointOffset { joint } => joint_col(joint),
            ErrorParam::JointScale { joint } => joint_col(joint) * q_rep[joint],
            ErrorParam::Compliance { joint } => joint_col(joint) * tau[joint],
            ErrorParam::PeriodicSin { joint } => joint_col(joint) * sin_cos(q_rep[joint]).0,
            ErrorParam::PeriodicCos { joint } => joint_col(joint) * sin_cos(q_rep[joint]).1,
            ErrorParam::OriginXyz { joint, axis } => frames[joint].parent_rotation * axis.unit(),
            ErrorParam::OriginRpy { joint, axis } => {
                let f = &frames[joint];
                let axes = match rpy_axes {
                    Some((j, axes)) if j == joint => axes,
                    _ => {
                        let axes = match prep {
                            Some(prep) => {
                                let [roll, pitch] = prep.rpy_local[joint];
                                let r_p = &f.parent_rotation;
                                [r_p * roll, r_p * pitch, r_p * Vector3::z()]
                            }
                            None => rpy_derivative_axes(&f.parent_rotation, &f.rpy),
                        };
                        rpy_axes = Some((joint, axes));
                        axes
                    }
                };
                axes[axis.index()].cross(&(p - f.o))
            }
            ErrorParam::Tip { axis } => flange_r * axis.unit(),
            ErrorParam::MountXyz { axis } => axis.unit(),
            ErrorParam::MountRpy { axis } => {
                mount_axes[axis.index()].cross(&(p - errors.mount_xyz))
            }
            // Filled by `lumped::fill_lumped_columns` (it needs the nominal link frames).
            ErrorParam::LumpedCompliance { .. } => continue,
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

/// `∂p_tip/∂q_rep` of the TRUE robot, 3×dof, m/rad (m/m for a prismatic joint), nominal base
/// axes, at the reported independent values `q_rep`: without coupled joints column `i` is
/// `(1 + scale_i + sin_i·cos q_i − cos_i·sin q_i)·J_i + Σ_k J_k·compliance_k·∂τ_k/∂q_i`
/// (`sin_i`, `cos_i` the periodic amplitudes), with `J` the tip position Jacobian of the true
/// chain with respect to the true values and `∂τ/∂q` the nominal gravity-torque Jacobian
/// ([`gravity_torque_jacobian`](crate::gravity_torque_jacobian)). With coupled joints the first
/// term is summed over the chain joints k times `∂q_k/∂q_i` (the coupling coefficients).
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
    let n = model.chain_joints().len();
    let mut tau = vec![0.0; n];
    let mut q_true = vec![0.0; n];
    let mut buf = Vec::new();
    let q_rep_chain = true_joint_angles(
        model,
        errors,
        (q_rep, &mut buf),
        g_base,
        false,
        &mut tau,
        &mut q_true,
    );
    let mut frames = vec![TrueJointFrame::default(); n];
    let (flange_r, flange_t) = true_chain(model, errors, &q_true, Some(&mut frames), None);
    let p = flange_t + flange_r * (flange_from_tip + errors.tip);
    // ∂p/∂q_true, per chain joint.
    let mut j_true = Matrix3xX::zeros(n);
    for (k, f) in frames.iter().enumerate() {
        j_true.set_column(k, &f.joint_column(&p));
    }
    // ∂p/∂q_rep through each chain joint's own rate, then the couplings (chain rule).
    let mut jac = Matrix3xX::zeros(model.dof());
    for k in 0..n {
        let col = j_true.column(k) * joint_rate(errors, q_rep_chain, k);
        if model.has_coupled_joints() {
            model.for_each_dependence(k, |i, c| {
                let sum = jac.column(i) + col * c;
                jac.set_column(i, &sum);
            });
        } else {
            jac.set_column(k, &col);
        }
    }
    if !all_zero(&errors.compliance) {
        let mut entries = vec![GravityEntry::default(); n];
        gravity_entries(model, q_rep, &mut entries);
        let mut dtau = gravity_jacobian_from_entries(&entries, g_base);
        if model.has_coupled_joints() {
            dtau *= model.coupling_matrix();
        }
        for i in 0..model.dof() {
            let mut col = jac.column(i).into_owned();
            for k in 0..n {
                col += j_true.column(k) * (errors.compliance[k] * dtau[(k, i)]);
            }
            jac.set_column(i, &col);
        }
    }
    if !errors.lumped_compliance.is_empty() {
        let nominal = crate::lumped::NominalFrames::at(model, q_rep);
        let mut d = nominal.deflection_jacobian(model, &errors.lumped_compliance, g_base);
        if model.has_coupled_joints() {
            d *= model.coupling_matrix();
        }
        jac += &j_true * d;
    }
    Ok(jac)
}

#[cfg(test)]
mod tests;

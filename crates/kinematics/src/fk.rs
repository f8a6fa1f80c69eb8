//! Forward kinematics: `base_from_flange(q)` and `base_from_tip(q)`.
//! Lengths in metres, angles in radians; `base` is the URDF root link. `q` holds the independent
//! joints (rad, or m for a prismatic joint); the coupled joints' values are computed from it.
//!
//! `base_from_flange = Π_k [prev_from_joint_k · Motion_k(q_k)] · last_from_flange` over the chain
//! joints, `Motion_k` the rotation `Rot(axis_k, q_k)` of a revolute or continuous joint or the
//! translation `Trans(axis_k·q_k)` of a prismatic one, evaluated
//! on (rotation columns, translation) arrays: the fixed transforms are classified when the model
//! is built (identity rotations and zero translation components are skipped, a rotation about
//! ±x/±y/±z mixes two columns), and the sines and cosines of all joints are computed up front,
//! two per SIMD register, by a branch-free fdlibm kernel (≤ 1 ulp). The rotation is converted to
//! a quaternion once at the end, without data-dependent branches. The hot path allocates
//! nothing and has no branch that depends on the joint values.

use nalgebra::{
    ArrayStorage, Isometry3, Matrix3, Quaternion, Rotation3, Translation3, UnitQuaternion, Vector3,
};

use crate::error::KinematicsError;
use crate::model::{FixedTransform, RobotModel, Step, FAST_PRISMATIC, PRISMATIC, STACK_DOF};

/// Largest |x| handled by [`sin_cos_kernel`]; beyond (and for NaN, ±∞) `f64::sin_cos` is used.
const SIN_COS_KERNEL_MAX: f64 = 1e5;

/// `(sin x, cos x)` for the FK hot path: [`sin_cos_kernel`] for |x| ≤ 1e5, `f64::sin_cos`
/// beyond (and for NaN and ±∞).
#[inline(always)]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    if x.abs() <= SIN_COS_KERNEL_MAX {
        sin_cos_kernel(x)
    } else {
        x.sin_cos()
    }
}

/// [`sin_cos`] of the first `n` entries of `x` into `(s, c)`, two at a time: each pair is
/// straight-line code on two-element arrays, which the compiler evaluates in the two lanes of
/// an SSE2 register. Same results, bit for bit, as calling [`sin_cos`] on each entry.
#[inline(always)]
fn sin_cos_batch(
    x: &[f64; MAX_BATCH],
    n: usize,
    s: &mut [f64; MAX_BATCH],
    c: &mut [f64; MAX_BATCH],
) {
    let pairs = n.div_ceil(2);
    for ((xp, sp), cp) in x
        .chunks_exact(2)
        .zip(s.chunks_exact_mut(2))
        .zip(c.chunks_exact_mut(2))
        .take(pairs)
    {
        for j in 0..2 {
            (sp[j], cp[j]) = sin_cos_kernel(xp[j]);
        }
    }
    if !x[..n].iter().all(|v| v.abs() <= SIN_COS_KERNEL_MAX) {
        for i in 0..n {
            (s[i], c[i]) = sin_cos(x[i]);
        }
    }
}

/// `(sin x, cos x)` for |x| ≤ 1e5, branch-free: musl/fdlibm's `__rem_pio2` medium case
/// (x = n·π/2 + y₀ + y₁ with π/2 to 33 + 33 + 53 bits, i.e. its "2nd round, good to 118 bits",
/// done always) and its `__sin`/`__cos` kernels with the tail y₁, then the quadrant. Error
/// against 60-digit values: ≤ 0.77 ulp of the result over random |x| ≤ 1e5 and ≤ 0.61 ulp at the
/// doubles nearest n·π/2, |n| ≤ 63 662 (`benches/sin_cos_ulp.py`, an exact replica in Python
/// floats), so the relative accuracy also holds next to the zeros of sin and cos; a table of
/// such points is checked in the tests.
// The constants are fdlibm's published decimal values (each rounds to the intended double).
#[allow(clippy::excessive_precision)]
#[inline(always)]
fn sin_cos_kernel(x: f64) -> (f64, f64) {
    // π/2 = PIO2_1 + PIO2_2 + PIO2_2T (33 + 33 + 53 bits; n·PIO2_1 and n·PIO2_2 are exact).
    const PIO2_1: f64 = 1.570_796_326_734_125_614_17;
    const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
    const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
    // Round to nearest without a libm call: adding 1.5·2⁵² leaves no fraction bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    let big = x * std::f64::consts::FRAC_2_PI + ROUND;
    // The low bits of `big` are the quadrant n (two's complement, |n| < 2⁵¹).
    let quadrant = big.to_bits();
    let n = big - ROUND;
    let t = x - n * PIO2_1;
    let w = n * PIO2_2;
    let r = t - w;
    let w = n * PIO2_2T - ((t - r) - w);
    let y0 = r - w;
    let y1 = (r - y0) - w;
    // fdlibm __kernel_sin / __kernel_cos coefficients and evaluation order (musl's).
    const S1: f64 = -1.666_666_666_666_663_243_48e-1;
    const S2: f64 = 8.333_333_333_322_489_461_24e-3;
    const S3: f64 = -1.984_126_982_985_794_931_34e-4;
    const S4: f64 = 2.755_731_370_707_006_767_89e-6;
    const S5: f64 = -2.505_076_025_340_686_341_95e-8;
    const S6: f64 = 1.589_690_995_211_550_102_21e-10;
    const C1: f64 = 4.166_666_666_666_660_190_37e-2;
    const C2: f64 = -1.388_888_888_887_410_957_49e-3;
    const C3: f64 = 2.480_158_728_947_672_941_78e-5;
    const C4: f64 = -2.755_731_435_139_066_330_35e-7;
    const C5: f64 = 2.087_572_321_298_174_827_90e-9;
    const C6: f64 = -1.135_964_755_778_819_482_65e-11;
    let z = y0 * y0;
    let z2 = z * z;
    let sr = S2 + z * (S3 + z * S4) + z * z2 * (S5 + z * S6);
    let v = z * y0;
    let sin_r = y0 - ((z * (0.5 * y1 - v * sr) - y1) - v * S1);
    let cr = z * (C1 + z * (C2 + z * C3)) + z2 * z2 * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    let cos_r = w + (((1.0 - w) - hz) + (z * cr - y0 * y1));
    // Quadrant 0: (s, c), 1: (c, −s), 2: (−s, −c), 3: (−c, s), selected without branches (the
    // quadrant of a random joint angle is unpredictable): swap when n is odd, negate the sine
    // when bit 1 of n is set and the cosine when bit 1 of n + 1 is.
    let swap = 0u64.wrapping_sub(quadrant & 1);
    let (sb, cb) = (sin_r.to_bits(), cos_r.to_bits());
    let a = (sb & !swap) | (cb & swap);
    let b = (cb & !swap) | (sb & swap);
    (
        f64::from_bits(a ^ ((quadrant & 2) << 62)),
        f64::from_bits(b ^ ((quadrant.wrapping_add(1) & 2) << 62)),
    )
}

/// A 3×3 matrix as its columns, `cols[j][i]` = row i of column j (nalgebra's storage order), and
/// the translation as an array: the FK hot path works on these, written out component by
/// component so that the compiler keeps the pose in registers and skips nothing but exact zeros.
pub(crate) type Cols = [[f64; 3]; 3];

/// `t ← t + m · v`, summed `m₀·v₀ + m₁·v₁ + m₂·v₂` per row.
#[inline(always)]
fn add_mul_vec(t: &mut [f64; 3], m: &Cols, v: &[f64; 3]) {
    for i in 0..3 {
        t[i] += m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2];
    }
}

/// `a · b`, each entry summed `a_i0·b_0j + a_i1·b_1j + a_i2·b_2j`.
#[inline(always)]
fn mul_mat(a: &Cols, b: &Cols) -> Cols {
    let mut out = [[0.0; 3]; 3];
    for (o, bj) in out.iter_mut().zip(b) {
        for (i, oi) in o.iter_mut().enumerate() {
            *oi = a[0][i] * bj[0] + a[1][i] * bj[1] + a[2][i] * bj[2];
        }
    }
    out
}

/// `(r, t) ← (r, t) · f`: the translation as classified (a single non-zero component moves
/// along one column; terms that are exactly zero are skipped), then the rotation (nothing for
/// the identity; with `AXIS_MIX`, a column mix for a rotation about a coordinate axis, which
/// gives the numbers of the full product in 18 instead of 45 flops, but as one more branch
/// target per step costs more than it saves in the per-joint loop).
#[inline(always)]
fn apply_fixed<const AXIS_MIX: bool>(r: &mut Cols, t: &mut [f64; 3], f: &FixedTransform) {
    let o = &f.t;
    match f.t_kind {
        0 => add_col(t, &r[0], o.x),
        1 => add_col(t, &r[1], o.y),
        2 => add_col(t, &r[2], o.z),
        3 => {}
        _ => add_mul_vec(t, r, &[o.x, o.y, o.z]),
    }
    let (s, c) = f.r_sc;
    match f.r_kind {
        3 => {}
        0 if AXIS_MIX => mix_columns::<1, 2>(r, s, c),
        1 if AXIS_MIX => mix_columns::<2, 0>(r, s, c),
        2 if AXIS_MIX => mix_columns::<0, 1>(r, s, c),
        _ => *r = mul_mat(r, &f.r.data.0),
    }
}

#[inline(always)]
fn add_col(t: &mut [f64; 3], col: &[f64; 3], a: f64) {
    for i in 0..3 {
        t[i] += col[i] * a;
    }
}

/// Applies joint step `step` at value `q` (rad, or m for a prismatic joint) to the running pose
/// `(r, t)` = base_from_prev: `(r, t) ← (r, t) · prev_from_joint · Rot(axis, q)` (or
/// `· Trans(axis·q)` for a prismatic joint). Rotations about ±x/±y/±z mix two columns of `r`
/// (12 flops); an identity origin rotation is skipped. Allocation-free.
///
/// `MAY_BE_PRISMATIC = false` (a chain without prismatic joints, `RobotModel::prismatic`) leaves
/// the prismatic test out, so the rotary chains' loops compile to the code they had before
/// prismatic joints existed (measured: 1023 instructions per checked hp20 FK call, IK and
/// Jacobians likewise).
#[inline(always)]
pub(crate) fn apply_step<const MAY_BE_PRISMATIC: bool>(
    r: &mut Matrix3<f64>,
    t: &mut Vector3<f64>,
    step: &Step,
    q: f64,
) {
    let mut rc = r.data.0;
    let mut tc = [t.x, t.y, t.z];
    if MAY_BE_PRISMATIC && step.axis_kind == PRISMATIC {
        prismatic_step(&mut rc, &mut tc, step, q);
    } else {
        let sc = if step.axis_kind < 3 {
            sin_cos(q * step.axis_sign)
        } else {
            (0.0, 1.0)
        };
        rotary_step_sc(&mut rc, &mut tc, step, q, sc);
    }
    *r = Matrix3::from_data(ArrayStorage(rc));
    *t = Vector3::from(tc);
}

/// [`apply_step`] on columns, with `sc = sin_cos(q · axis_sign)` already computed (ignored for a
/// general axis, which uses `q`, and for a prismatic joint).
#[inline(always)]
fn apply_step_sc(r: &mut Cols, t: &mut [f64; 3], step: &Step, q: f64, sc: (f64, f64)) {
    if step.axis_kind == PRISMATIC {
        prismatic_step(r, t, step, q);
    } else {
        rotary_step_sc(r, t, step, q, sc);
    }
}

/// [`apply_step_sc`] of a revolute or continuous joint.
#[inline(always)]
fn rotary_step_sc(r: &mut Cols, t: &mut [f64; 3], step: &Step, q: f64, sc: (f64, f64)) {
    apply_fixed::<false>(r, t, &step.origin);
    let (s, c) = sc;
    // R·Rot(axis, q) mixes the column pair (x: 1,2), (y: 2,0), (z: 0,1):
    // c_i ← c·c_i + s·c_j, c_j ← c·c_j − s·c_i.
    match step.axis_kind {
        0 => mix_columns::<1, 2>(r, s, c),
        1 => mix_columns::<2, 0>(r, s, c),
        2 => mix_columns::<0, 1>(r, s, c),
        _ => {
            let rot = Rotation3::from_axis_angle(&step.axis, q);
            *r = mul_mat(r, &rot.matrix().data.0);
        }
    }
}

/// [`apply_step_sc`] of a prismatic joint at travel `q`, m: the origin, then
/// `t ← t + R·(axis·q)`, the travel along the axis in the joint frame's axes.
#[inline(always)]
fn prismatic_step(r: &mut Cols, t: &mut [f64; 3], step: &Step, q: f64) {
    apply_fixed::<false>(r, t, &step.origin);
    let a = step.axis.into_inner() * q;
    add_mul_vec(t, r, &[a.x, a.y, a.z]);
}

/// A joint step with the origin translation along axis `T` only, no origin rotation, and the
/// joint axis mixing columns `I`, `J` (see [`Step::fast_kind`]).
#[inline(always)]
fn fast_step<const T: usize, const I: usize, const J: usize>(
    r: &mut Cols,
    t: &mut [f64; 3],
    step: &Step,
    (s, c): (f64, f64),
) {
    add_col(t, &r[T], step.origin.t[T]);
    mix_columns::<I, J>(r, s, c);
}

#[inline(always)]
fn mix_columns<const I: usize, const J: usize>(r: &mut Cols, s: f64, c: f64) {
    let (a, b) = (r[I], r[J]);
    for k in 0..3 {
        r[I][k] = a[k] * c + b[k] * s;
        r[J][k] = b[k] * c - a[k] * s;
    }
}

/// `(r, t) ← (r, t) · last_from_flange`: the fixed joints after the last actuated one.
#[inline(always)]
fn to_flange(model: &RobotModel, r: &mut Cols, t: &mut [f64; 3]) {
    apply_fixed::<true>(r, t, &model.flange);
}

/// [`to_flange`] on nalgebra types (for the chains that keep per-joint frames).
#[inline]
pub(crate) fn to_flange_nalgebra(model: &RobotModel, r: &mut Matrix3<f64>, t: &mut Vector3<f64>) {
    let mut rc = r.data.0;
    let mut tc = [t.x, t.y, t.z];
    to_flange(model, &mut rc, &mut tc);
    *r = Matrix3::from_data(ArrayStorage(rc));
    *t = Vector3::from(tc);
}

/// Most joints handled with the sines and cosines computed up front (independent, so the CPU
/// overlaps them); longer chains fall back to one at a time.
const MAX_BATCH: usize = 8;

/// `base_from_flange(q)` as (rotation columns, translation in m), no checks, for the independent
/// joint vector `q`. Allocation-free for chains of up to 16 joints. Joints missing from a short
/// `q` stay at their zero pose.
#[inline(always)]
fn flange_cols(model: &RobotModel, q: &[f64]) -> (Cols, [f64; 3]) {
    if model.sources.is_some() {
        return flange_cols_coupled(model, q);
    }
    flange_cols_chain(model, q)
}

/// [`flange_cols`] of a chain with coupled joints: the chain values first.
#[cold]
#[inline(never)]
fn flange_cols_coupled(model: &RobotModel, q: &[f64]) -> (Cols, [f64; 3]) {
    let n = model.chain_joints().len();
    if n <= STACK_DOF {
        let mut buf = [0.0; STACK_DOF];
        model.chain_values_into(q, &mut buf[..n]);
        flange_cols_chain(model, &buf[..n])
    } else {
        let mut buf = Vec::new();
        flange_cols_chain(model, model.chain_q(q, &mut buf))
    }
}

/// `base_from_flange` as (rotation columns, translation in m) for the chain values `q` (one per
/// chain joint), no checks. Allocation-free. Joints missing from a short `q` stay at their zero
/// pose.
#[inline(always)]
fn flange_cols_chain(model: &RobotModel, q: &[f64]) -> (Cols, [f64; 3]) {
    let mut r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut t = [0.0; 3];
    if model.steps.len() <= MAX_BATCH && q.len() >= model.steps.len() {
        let mut x = [0.0; MAX_BATCH];
        for ((xk, step), &qk) in x.iter_mut().zip(&model.steps).zip(q) {
            *xk = qk * step.axis_sign;
        }
        let (mut s, mut c) = ([0.0; MAX_BATCH], [0.0; MAX_BATCH]);
        sin_cos_batch(&x, model.steps.len(), &mut s, &mut c);
        for (k, (step, &qk)) in model.steps.iter().zip(q).enumerate() {
            let sc = (s[k], c[k]);
            // One dispatch for the usual joint: a single-component origin translation, no
            // origin rotation, a coordinate axis (same operations as `apply_step_sc`).
            match step.fast_kind {
                0 => fast_step::<0, 1, 2>(&mut r, &mut t, step, sc),
                1 => fast_step::<0, 2, 0>(&mut r, &mut t, step, sc),
                2 => fast_step::<0, 0, 1>(&mut r, &mut t, step, sc),
                3 => fast_step::<1, 1, 2>(&mut r, &mut t, step, sc),
                4 => fast_step::<1, 2, 0>(&mut r, &mut t, step, sc),
                5 => fast_step::<1, 0, 1>(&mut r, &mut t, step, sc),
                6 => fast_step::<2, 1, 2>(&mut r, &mut t, step, sc),
                7 => fast_step::<2, 2, 0>(&mut r, &mut t, step, sc),
                8 => fast_step::<2, 0, 1>(&mut r, &mut t, step, sc),
                FAST_PRISMATIC => prismatic_step(&mut r, &mut t, step, qk),
                _ => rotary_step_sc(&mut r, &mut t, step, qk, sc),
            }
        }
    } else {
        for (k, step) in model.steps.iter().enumerate() {
            let qk = q.get(k).copied().unwrap_or(0.0);
            let sc = if step.axis_kind < 3 {
                sin_cos(qk * step.axis_sign)
            } else {
                (0.0, 1.0)
            };
            apply_step_sc(&mut r, &mut t, step, qk, sc);
        }
    }
    to_flange(model, &mut r, &mut t);
    (r, t)
}

/// `UnitQuaternion::from_rotation_matrix(r)` bit for bit (same case choice, same expressions),
/// without its data-dependent branches: the case (trace > 0, else the largest diagonal entry) is
/// an index into tables of the four candidate numerators.
#[inline]
pub(crate) fn quaternion_from_cols(r: &Cols) -> UnitQuaternion<f64> {
    let [[m00, m10, m20], [m01, m11, m21], [m02, m12, m22]] = *r;
    let tr = m00 + m11 + m22;
    // nalgebra's order of tests: tr > 0; m00 > m11 && m00 > m22; m11 > m22; else.
    let not0 = 1 - usize::from(tr > 0.0);
    let not1 = 1 - usize::from((m00 > m11) & (m00 > m22));
    let not2 = 1 - usize::from(m11 > m22);
    let case = not0 * (1 + not1 * (1 + not2));
    let radicand = [
        tr + 1.0,
        1.0 + m00 - m11 - m22,
        1.0 + m11 - m00 - m22,
        1.0 + m22 - m00 - m11,
    ][case];
    let (a, b, c) = (m21 - m12, m02 - m20, m10 - m01);
    let (d, e, f) = (m01 + m10, m02 + m20, m12 + m21);
    // Numerators (w, i, j, k) of each case; the case's own component is 0.25·denom instead.
    let numerators = [
        [0.0, a, b, c],
        [a, 0.0, d, e],
        [b, d, 0.0, f],
        [c, e, f, 0.0],
    ][case];
    let denom = radicand.sqrt() * 2.0;
    let mut wijk = numerators.map(|x| x / denom);
    wijk[case] = 0.25 * denom;
    UnitQuaternion::new_unchecked(Quaternion::new(wijk[0], wijk[1], wijk[2], wijk[3]))
}

/// (rotation matrix, translation in m) to an isometry; the quaternion as nalgebra's
/// `from_rotation_matrix` computes it (see [`quaternion_from_cols`]).
#[inline]
pub(crate) fn isometry(r: &Matrix3<f64>, t: &Vector3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(Translation3::from(*t), quaternion_from_cols(&r.data.0))
}

/// The tip pose for the flange pose `(r, t)`: `(r, t + r · flange_from_tip)` as an isometry.
#[inline]
pub(crate) fn tip_isometry(
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    flange_from_tip: &Vector3<f64>,
) -> Isometry3<f64> {
    let mut p = [t.x, t.y, t.z];
    add_mul_vec(
        &mut p,
        &r.data.0,
        &[flange_from_tip.x, flange_from_tip.y, flange_from_tip.z],
    );
    Isometry3::from_parts(
        Translation3::from(Vector3::from(p)),
        quaternion_from_cols(&r.data.0),
    )
}

/// `base_from_flange(q)` without any check of `q` (caller guarantees `q.len() == dof`, finite).
/// Allocation-free; used by IK and benches. If `q` is shorter than `dof` the missing joints are
/// left at their zero pose; never panics.
#[inline]
pub fn base_from_flange_unchecked(model: &RobotModel, q: &[f64]) -> Isometry3<f64> {
    let (r, t) = flange_cols(model, q);
    Isometry3::from_parts(
        Translation3::from(Vector3::from(t)),
        quaternion_from_cols(&r),
    )
}

/// Pose of the flange (tool link) in the base frame at the independent joint values `q` (rad, or
/// m for a prismatic joint; [`RobotModel::joints`]).
///
/// Errors: `q` of the wrong length, non-finite, in degrees (revolute) or millimetres (prismatic),
/// or outside the joint limits.
pub fn base_from_flange(model: &RobotModel, q: &[f64]) -> Result<Isometry3<f64>, KinematicsError> {
    model.check_q(q)?;
    Ok(base_from_flange_unchecked(model, q))
}

/// `base_from_tip` without checks; see [`base_from_flange_unchecked`].
#[inline]
pub fn base_from_tip_unchecked(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
) -> Isometry3<f64> {
    let (r, mut t) = flange_cols(model, q);
    add_mul_vec(
        &mut t,
        &r,
        &[flange_from_tip.x, flange_from_tip.y, flange_from_tip.z],
    );
    Isometry3::from_parts(
        Translation3::from(Vector3::from(t)),
        quaternion_from_cols(&r),
    )
}

/// Pose of the tip in the base frame: the flange pose moved by `flange_from_tip` (m, flange axes);
/// the tip's orientation is the flange's.
///
/// Errors: as [`base_from_flange`], plus a non-finite tip offset.
pub fn base_from_tip(
    model: &RobotModel,
    q: &[f64],
    flange_from_tip: &Vector3<f64>,
) -> Result<Isometry3<f64>, KinematicsError> {
    model.check_q(q)?;
    check_tip(flange_from_tip)?;
    Ok(base_from_tip_unchecked(model, q, flange_from_tip))
}

pub(crate) fn check_tip(flange_from_tip: &Vector3<f64>) -> Result<(), KinematicsError> {
    if flange_from_tip.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(KinematicsError::InvalidInput(format!(
            "tip offset {:?} m is not finite; give a finite flange_from_tip",
            flange_from_tip.as_slice()
        )))
    }
}

/// Poses `base_from_joint_k` (after joint k's motion) for every chain joint, as (rotation
/// matrix, translation in m), and the flange's, at the independent joint vector `q`. Used by the
/// Jacobians and IK. No checks.
pub(crate) fn joint_frames(
    model: &RobotModel,
    q: &[f64],
    out: &mut Vec<(Matrix3<f64>, Vector3<f64>)>,
) -> (Matrix3<f64>, Vector3<f64>) {
    if model.prismatic {
        joint_frames_k::<true>(model, q, out)
    } else {
        joint_frames_k::<false>(model, q, out)
    }
}

/// [`joint_frames`] for a chain that may (or, `false`, does not) hold prismatic joints.
#[inline(always)]
fn joint_frames_k<const MAY_BE_PRISMATIC: bool>(
    model: &RobotModel,
    q: &[f64],
    out: &mut Vec<(Matrix3<f64>, Vector3<f64>)>,
) -> (Matrix3<f64>, Vector3<f64>) {
    out.clear();
    let mut r = Matrix3::identity();
    let mut t = Vector3::zeros();
    let mut buf = Vec::new();
    for (step, &qi) in model.steps.iter().zip(model.chain_q(q, &mut buf)) {
        apply_step::<MAY_BE_PRISMATIC>(&mut r, &mut t, step, qi);
        out.push((r, t));
    }
    to_flange_nalgebra(model, &mut r, &mut t);
    (r, t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Unit};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn robot(name: &str) -> RobotModel {
        let p = format!("{}/../../robots/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
        RobotModel::from_urdf_file(std::path::Path::new(&p), "tool0").unwrap()
    }

    /// Distance in ulps of `b` (0 if equal).
    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            0.0
        } else {
            (a - b).abs() / (b.abs() * f64::EPSILON).max(f64::MIN_POSITIVE)
        }
    }

    #[test]
    fn fast_sin_cos_matches_libm() {
        // Tolerance 2 ulp of 1 (4.4e-16): both are within ~1 ulp of the true value.
        const TOL: f64 = 4.5e-16;
        let mut x = -50.0;
        while x < 50.0 {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            assert!(
                (s - s0).abs() < TOL && (c - c0).abs() < TOL,
                "x = {x}: {s} {c} vs {s0} {c0}"
            );
            x += 0.000_123_7;
        }
        // Exact quadrant points, tiny angles and the fallback.
        for x in [
            0.0,
            -0.0,
            1e-300,
            -1e-12,
            std::f64::consts::PI,
            -std::f64::consts::FRAC_PI_2,
            1e6,
            -3e7,
        ] {
            let (s, c) = sin_cos(x);
            let (s0, c0) = x.sin_cos();
            assert!((s - s0).abs() < TOL && (c - c0).abs() < TOL, "x = {x}");
        }
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert!(sin_cos(-0.0).0.is_sign_negative());
        assert!(sin_cos(f64::NAN).0.is_nan());
        assert!(sin_cos(f64::INFINITY).1.is_nan());
    }

    /// Relative accuracy, also next to the zeros of sin and cos (the doubles nearest n·π/2,
    /// where a two-part π/2 loses all relative accuracy): within 1 ulp of the correctly rounded
    /// value (the 25-digit reference parsed to the nearest double). Reference values from
    /// mpmath at 50 digits; x printed with Python's round-trip `repr`.
    #[test]
    // The table starts with the doubles nearest ±n·π/2 on purpose.
    #[allow(clippy::approx_constant)]
    fn fast_sin_cos_is_within_one_ulp_of_a_50_digit_reference() {
        let table: &[(f64, &str, &str)] = &[
            (1.5707963267948966, "1.0", "6.12323399573676588613033e-17"),
            (-1.5707963267948966, "-1.0", "6.12323399573676588613033e-17"),
            (3.141592653589793, "1.224646799147353177226066e-16", "-1.0"),
            (
                -3.141592653589793,
                "-1.224646799147353177226066e-16",
                "-1.0",
            ),
            (4.71238898038469, "-1.0", "-1.836970198721029765839099e-16"),
            (-4.71238898038469, "1.0", "-1.836970198721029765839099e-16"),
            (6.283185307179586, "-2.449293598294706354452132e-16", "1.0"),
            (-6.283185307179586, "2.449293598294706354452132e-16", "1.0"),
            (7.853981633974483, "1.0", "3.061616997868382943065165e-16"),
            (-7.853981633974483, "-1.0", "3.061616997868382943065165e-16"),
            (9.42477796076938, "3.673940397442059531678198e-16", "-1.0"),
            (-9.42477796076938, "-3.673940397442059531678198e-16", "-1.0"),
            (
                10.995574287564276,
                "-1.0",
                "-4.286263797015736120291231e-16",
            ),
            (
                -10.995574287564276,
                "1.0",
                "-4.286263797015736120291231e-16",
            ),
            (12.566370614359172, "-4.898587196589412708904264e-16", "1.0"),
            (-12.566370614359172, "4.898587196589412708904264e-16", "1.0"),
            (99998.46496008991, "1.0", "-1.25336247215584771725812e-13"),
            (-99998.46496008991, "-1.0", "-1.25336247215584771725812e-13"),
            (
                -2.466341292335727,
                "-6.250935364626471603150761e-1",
                "-7.805498514974051323053332e-1",
            ),
            (
                -4.888111565056973,
                "9.846004739673989157794187e-1",
                "1.748196403816613791398618e-1",
            ),
            (
                2.113082622557952,
                "8.565309737642613443798266e-1",
                "-5.160956219369102965923264e-1",
            ),
            (
                -5.985891986654401,
                "2.929333376453104695216605e-1",
                "9.56132867176930871615062e-1",
            ),
            (
                0.5023480602936488,
                "4.814848318499875584242377e-1",
                "8.76454423628741351586637e-1",
            ),
            (
                -1.8803551632238023,
                "-9.524680579646943149497067e-1",
                "-3.046384718924445211562287e-1",
            ),
            (
                -6.188015053154105,
                "9.502665359077457798467715e-2",
                "9.954747285126523637581638e-1",
            ),
            (
                0.10410026465188338,
                "1.039123464155223480646705e-1",
                "9.94586458917685285324656e-1",
            ),
            (1e-300, "1.000000000000000025059092e-300", "1.0"),
            (
                -1e-09,
                "-1.000000000000000062114925e-9",
                "9.999999999999999995e-1",
            ),
            (
                0.7853981633974483,
                "7.07106781186547502751943e-1",
                "7.071067811865475460497458e-1",
            ),
            (
                3.1416,
                "-7.346410206643587091859822e-6",
                "-9.999999999730151285374974e-1",
            ),
            (
                6.2832,
                "1.469282041289069031344545e-5",
                "9.999999998920605141514459e-1",
            ),
            (
                -2.4435,
                "-6.427576972998622876923476e-1",
                "-7.660695415964392745943761e-1",
            ),
            (
                3.4907,
                "-3.420591365268410189193965e-1",
                "-9.396784275051289780144258e-1",
            ),
            (
                -2.328793193956046,
                "-7.262145567714284040050227e-1",
                "-6.874681211032827168677095e-1",
            ),
            (
                0.8170041191731459,
                "7.290986982248414400806462e-1",
                "6.844085682155371683369266e-1",
            ),
            (
                55621.1808790791,
                "6.571660355082458697997672e-1",
                "-7.53745846936734324464414e-1",
            ),
            (-91553.86390724055, "-1.0", "2.260440600708131933410092e-16"),
        ];
        for &(x, s_ref, c_ref) in table {
            let (s_ref, c_ref): (f64, f64) = (s_ref.parse().unwrap(), c_ref.parse().unwrap());
            let (s, c) = sin_cos(x);
            assert!(
                ulps(s, s_ref) <= 1.0,
                "sin({x:?}) = {s:e}, reference {s_ref:e}"
            );
            assert!(
                ulps(c, c_ref) <= 1.0,
                "cos({x:?}) = {c:e}, reference {c_ref:e}"
            );
        }
    }

    #[test]
    fn batched_sin_cos_matches_scalar_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for n in 0..=MAX_BATCH {
            for _ in 0..200 {
                let mut x = [0.0; MAX_BATCH];
                for v in &mut x[..n] {
                    *v = rng.random_range(-20.0..20.0);
                }
                // Now and then a value for the libm fallback.
                if n > 0 && rng.random_bool(0.1) {
                    x[rng.random_range(0..n)] = [2e5, f64::NAN, -1e9][rng.random_range(0..3)];
                }
                let (mut s, mut c) = ([0.0; MAX_BATCH], [0.0; MAX_BATCH]);
                sin_cos_batch(&x, n, &mut s, &mut c);
                for i in 0..n {
                    let (s0, c0) = sin_cos(x[i]);
                    assert!(s[i].to_bits() == s0.to_bits() || (s0.is_nan() && s[i].is_nan()));
                    assert!(c[i].to_bits() == c0.to_bits() || (c0.is_nan() && c[i].is_nan()));
                }
            }
        }
    }

    /// The branch-free conversion is nalgebra's `from_rotation_matrix`, bit for bit, in all
    /// four cases, at ties between diagonal entries, at exactly 180° and at tiny angles.
    #[test]
    fn quaternion_from_cols_is_nalgebras_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut rotations: Vec<Rotation3<f64>> = (0..20_000)
            .map(|_| {
                let axis = Unit::new_normalize(Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ));
                Rotation3::from_axis_angle(&axis, rng.random_range(-4.0..4.0))
            })
            .collect();
        let pi = std::f64::consts::PI;
        for axis in [Vector3::x_axis(), Vector3::y_axis(), Vector3::z_axis()] {
            for angle in [
                0.0,
                1e-300,
                1e-12,
                -1e-12,
                pi,
                -pi,
                pi / 2.0,
                2.0 * pi / 3.0,
            ] {
                rotations.push(Rotation3::from_axis_angle(&axis, angle));
            }
        }
        // Exactly 180° with equal diagonal entries (ties in the case choice).
        let d = Unit::new_normalize(Vector3::new(1.0, 1.0, 0.0));
        rotations.push(Rotation3::from_axis_angle(&d, pi));
        let d = Unit::new_normalize(Vector3::new(1.0, 1.0, 1.0));
        rotations.push(Rotation3::from_axis_angle(&d, pi));
        rotations.push(Rotation3::from_matrix_unchecked(Matrix3::new(
            -1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0,
        )));
        rotations.push(Rotation3::from_matrix_unchecked(Matrix3::new(
            0.0, 0.0, 1.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0,
        )));
        for rot in &rotations {
            let ours = quaternion_from_cols(&rot.matrix().data.0);
            let theirs = UnitQuaternion::from_rotation_matrix(rot);
            let (a, b) = (ours.coords, theirs.coords);
            for k in 0..4 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "{rot:?}: {a:?} vs {b:?}");
            }
        }
    }

    /// The hot path against the plain product of nalgebra isometries (URDF origins, axis-angle
    /// rotations with libm's sin and cos), for both shipped arms over their whole joint ranges.
    /// The two differ by round-off only: ≈ 1 ulp per sine/cosine and per product, over ≤ 8
    /// factors, so 4e-15 on rotation entries (≤ 1) and 4e-15 m per metre of reach on the tip.
    #[test]
    fn fk_agrees_with_the_isometry_product_to_round_off() {
        const TOL: f64 = 4e-15;
        let tip = Vector3::new(0.01, -0.02, 0.15);
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let mut worst: (f64, f64) = (0.0, 0.0);
        for name in ["hp20", "va1400"] {
            let m = robot(name);
            for _ in 0..5_000 {
                let q: Vec<f64> = m
                    .joints()
                    .iter()
                    .map(|j| rng.random_range(j.lower..=j.upper))
                    .collect();
                let mut reference = Isometry3::identity();
                for (j, &qi) in m.joints().iter().zip(&q) {
                    reference = reference
                        * j.fixed_prefix
                        * crate::model::origin_isometry(&j.origin_xyz, &j.origin_rpy)
                        * UnitQuaternion::from_axis_angle(&j.axis, qi);
                }
                reference *= m.last_from_flange();
                let p_ref = reference * Point3::from(tip);
                let ours = base_from_tip(&m, &q, &tip).unwrap();
                let dr = (ours.rotation.to_rotation_matrix().matrix()
                    - reference.rotation.to_rotation_matrix().matrix())
                .amax();
                let dp =
                    (ours.translation.vector - p_ref.coords).amax() / (1.0 + p_ref.coords.norm());
                worst = (worst.0.max(dr), worst.1.max(dp));
            }
        }
        assert!(worst.0 < TOL && worst.1 < TOL, "worst {worst:?}");
    }

    /// Chains with prismatic joints (a rail; an oblique rail and a lift in the middle) and
    /// coupled joints against the plain product of nalgebra isometries at the chain values
    /// (`Trans(axis·q)` for a prismatic joint), through the batched loop and, with a short `q`,
    /// the one-at-a-time loop (missing joints at 0). Round-off as above, with lever arms up to
    /// 6 m: 1e-14.
    #[test]
    fn prismatic_and_coupled_fk_agree_with_the_isometry_product() {
        use crate::test_fixtures::{mixed_coupled, model, random_q, MIMIC_TORSO, MIXED, RAIL_6R};
        use nalgebra::Translation3;
        const TOL: f64 = 1e-14;
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for m in [
            model(RAIL_6R),
            model(MIXED),
            mixed_coupled(),
            model(MIMIC_TORSO),
        ] {
            let reference = |q: &[f64]| {
                let q_chain = m.chain_values(q).unwrap();
                let mut f = Isometry3::identity();
                for (j, &v) in m.chain_joints().iter().zip(&q_chain) {
                    let motion = if j.kind.is_prismatic() {
                        Isometry3::from_parts(
                            Translation3::from(j.axis.into_inner() * v),
                            UnitQuaternion::identity(),
                        )
                    } else {
                        Isometry3::from_parts(
                            Translation3::identity(),
                            UnitQuaternion::from_axis_angle(&j.axis, v),
                        )
                    };
                    f = f
                        * j.fixed_prefix
                        * crate::model::origin_isometry(&j.origin_xyz, &j.origin_rpy)
                        * motion;
                }
                f * m.last_from_flange()
            };
            for _ in 0..200 {
                let q = random_q(&m, &mut rng);
                let want = reference(&q);
                let got = base_from_flange(&m, &q).unwrap();
                let dp = (got.translation.vector - want.translation.vector).amax();
                assert!(
                    dp < TOL && got.rotation.angle_to(&want.rotation) < TOL,
                    "{}",
                    m.name()
                );
                // Short q: the one-at-a-time loop, the missing joints at 0.
                let mut padded = q[..2].to_vec();
                padded.resize(q.len(), 0.0);
                let short = base_from_flange_unchecked(&m, &q[..2]);
                let full = base_from_flange_unchecked(&m, &padded);
                assert!((short.translation.vector - full.translation.vector).amax() < TOL);
                assert!(short.rotation.angle_to(&full.rotation) < TOL);
            }
        }
    }

    /// The shipped arms take the short paths of the hot loop (pins the performance figures in
    /// BENCHMARKS.md): coordinate axes, no origin rotations and single-component origins (the
    /// one-dispatch `fast_step`), and a flange rotation (rpy = (0, π/2, 0)) recognised as a
    /// rotation about y.
    #[test]
    fn shipped_arms_take_the_short_paths() {
        for name in ["hp20", "va1400"] {
            let m = robot(name);
            for step in &m.steps {
                assert!(step.fast_kind < 9, "{name}: {step:?}");
            }
            assert_eq!((m.flange.r_kind, m.flange.t_kind), (1, 3), "{name}");
        }
    }

    /// The one-pass `check_q` accepts exactly what the per-joint checks accept.
    #[test]
    fn fast_check_q_agrees_with_the_detailed_check() {
        let m = robot("hp20");
        let j0 = &m.joints()[0];
        let edge = j0.upper + 1e-9;
        for v in [
            0.0,
            j0.lower,
            j0.upper,
            edge,
            edge + 1e-12,
            -edge,
            7.0,
            90.0,
            f64::NAN,
            f64::INFINITY,
        ] {
            let mut q = vec![0.1; 6];
            q[0] = v;
            let fast = m.check_q(&q);
            let slow = m.check_q_error(&q);
            assert_eq!(fast.is_ok(), slow.is_ok(), "q0 = {v}");
            assert_eq!(format!("{fast:?}"), format!("{slow:?}"));
        }
        assert!(m.check_q(&[0.0; 5]).is_err());
        assert!(m.check_q(&[0.0; 7]).is_err());
    }
}

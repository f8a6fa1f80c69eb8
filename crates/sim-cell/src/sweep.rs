//! Monte Carlo sweeps over noise × spread × number of points × mounts × methods.
//!
//! Two modes:
//! - **geometry**: teach points from a [`Layout`] around the cell's centre, robot 2's reading
//!   perturbed by the operator's alignment error, fitted by calib-core's allocation-free kernels
//!   ([`calib_core::generic_fast`], [`calib_core::paper_fast`], [`calib_core::rigid_fit_fast`],
//!   [`calib_core::constrained_fast`]); no robots, millions of trials per second.
//! - **robot**: each trial simulates a full session on a [`Cell`] ([`crate::session::generate_session`]:
//!   IK of both true robots, reach limits, encoder quantisation, repeatability, nominal-model tips).
//!
//! Trial `k` (global index over grid cells × trials) draws only from [`trial_rng`]`(seed, k)` and every
//! method is fitted on that trial's points (common random numbers), so results are identical for
//! any thread count. Grid cells are ordered mounts, noise, spread, n (n fastest).

use crate::cell::Cell;
use crate::error::SimError;
use crate::layout::{teach_points_into, Layout};
use crate::placement::{mounts_label, paper_placement};
use crate::session::{generate_session, SessionSpec};
use crate::trial_rng;
use calib_core::stats::{quantile_ci, sorted_finite, QuantileCi};
use calib_core::ZYZ_SINGULAR_BAND_RAD;
use calib_core::{
    constrained_fast, e_rot, e_tran, generic_fast, geodesic_angle, paper_fast,
    project_rotation_family, rigid_fit_fast, rotation_maximizing_trace, wrap_angle,
    zyz_from_rotation, Method, MountPair,
};
use indicatif::ProgressBar;
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use std::io::Write;

/// Largest point count of a geometry-mode trial.
pub const MAX_GEOMETRY_POINTS: usize = 256;
/// Trials per parallel work item (also the progress-bar step).
const CHUNK: usize = 2048;

/// Errors of one estimate against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrialErrors {
    /// eq (34): largest per-axis translation error, m.
    pub e_tran: f64,
    /// eq (33): largest ZYZ angle error (branch-matched, wrapped; at the floor–floor /
    /// floor–ceiling singularity max(tilt, |yaw error|), see [`calib_core::e_rot_zyz`]), rad.
    pub e_rot: f64,
    /// Geodesic angle between the true and estimated rotations, rad.
    pub geodesic: f64,
    /// Signed translation error `T_est − T_true`, m, b1 axes.
    pub translation_error: Vector3<f64>,
    /// Rotation error as a rotation vector of `R_est·R_trueᵀ`, rad, b1 axes.
    pub rotation_error: Vector3<f64>,
}

impl TrialErrors {
    /// Errors of `est` against `truth` (both `b1_from_b2`), with calib-core's metrics.
    pub fn between(truth: &Isometry3<f64>, est: &Isometry3<f64>) -> Self {
        TrialErrors {
            e_tran: e_tran(truth, est),
            e_rot: e_rot(truth, est),
            geodesic: geodesic_angle(truth, est),
            translation_error: est.translation.vector - truth.translation.vector,
            rotation_error: (est.rotation * truth.rotation.inverse()).scaled_axis(),
        }
    }

    /// As [`TrialErrors::between`] with the truth's eq 33 reading precomputed
    /// ([`ErotTruth::new`] of its eq 32 angles), allocation-free (e_rot by [`ErotTruth::e_rot`];
    /// the geodesic angle and rotation vector from one quaternion `atan2`); equal to it to
    /// round-off (tested).
    pub fn between_fast(
        truth: &Isometry3<f64>,
        erot_truth: &ErotTruth,
        est: &Isometry3<f64>,
    ) -> Self {
        let dt = est.translation.vector - truth.translation.vector;
        let dq = (est.rotation * truth.rotation.inverse()).into_inner();
        let (w, v) = if dq.w < 0.0 {
            (-dq.w, -dq.imag())
        } else {
            (dq.w, dq.imag())
        };
        let n = v.norm();
        let angle = 2.0 * n.atan2(w);
        TrialErrors {
            e_tran: dt.amax(),
            e_rot: erot_truth.e_rot(&est.rotation.to_rotation_matrix()),
            geodesic: angle,
            translation_error: dt,
            rotation_error: if n > 0.0 { v * (angle / n) } else { v * 2.0 },
        }
    }
}

/// The true rotation as [`e_rot_fast`] reads estimates against it (eq 33), precomputed once per
/// grid cell: the true ZYZ angles and, when they lie within [`ZYZ_SINGULAR_BAND_RAD`] of θ = 0 or
/// 180°, the true z axis and yaw (see [`calib_core::e_rot_zyz`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErotTruth {
    /// True ZYZ angles `[φ, θ, ψ]`, rad, as given.
    zyz: [f64; 3],
    /// The same wrapped to (−π, π], for the regular reading.
    zyz_wrapped: [f64; 3],
    /// At the singularity: the reading's constants.
    singular: Option<SingularTruth>,
}

/// A true rotation at the ZYZ singularity, as eq 33 reads estimates against it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SingularTruth {
    /// θ near 0 (yaw `φ + ψ`) rather than near π (yaw `φ − ψ`).
    near_zero: bool,
    /// The true z axis (third column), b1.
    a: Vector3<f64>,
    /// `(cos, sin)` of the true yaw.
    yaw: (f64, f64),
}

impl ErotTruth {
    /// From the true ZYZ angles (rad, eq 32 or published).
    pub fn new(zyz_true: [f64; 3]) -> Self {
        let [phi, theta, psi] = zyz_true;
        let (st, ct) = theta.sin_cos();
        let singular = (st.abs() < ZYZ_SINGULAR_BAND_RAD.sin()).then(|| {
            let near_zero = ct > 0.0;
            let (sp, cp) = phi.sin_cos();
            let yaw = if near_zero { phi + psi } else { phi - psi };
            let (sy, cy) = yaw.sin_cos();
            SingularTruth {
                near_zero,
                a: Vector3::new(cp * st, sp * st, ct),
                yaw: (cy, sy),
            }
        });
        ErotTruth {
            zyz: zyz_true,
            zyz_wrapped: zyz_true.map(wrap_angle),
            singular,
        }
    }

    /// The true ZYZ angles, rad.
    pub fn zyz(&self) -> [f64; 3] {
        self.zyz
    }

    /// eq (33) of `r_est` against this truth, rad: [`e_rot_fast`].
    pub fn e_rot(&self, r_est: &Rotation3<f64>) -> f64 {
        let Some(t) = &self.singular else {
            return e_rot_regular(self.zyz_wrapped, r_est);
        };
        let m = r_est.matrix();
        // tilt = ∠(a_true, a_est) = atan2(|a_true × a_est|, a_true·a_est), accurate at any angle.
        let a = m.column(2);
        let (tilt_x, tilt_y) = (t.a.dot(&a), t.a.cross(&a).norm());
        // The estimate's yaw as a (cos, sin) pair scaled by 1 ± cos θ_est ≥ 0 (zero only for an
        // estimate flipped upside down, whose tilt is then 180° anyway):
        // R₀₀ + R₁₁ = (1 + cos θ)·cos(φ + ψ), R₁₀ − R₀₁ = (1 + cos θ)·sin(φ + ψ);
        // R₁₁ − R₀₀ = (1 − cos θ)·cos(φ − ψ), −(R₁₀ + R₀₁) = (1 − cos θ)·sin(φ − ψ).
        let (c, s) = if t.near_zero {
            (m[(0, 0)] + m[(1, 1)], m[(1, 0)] - m[(0, 1)])
        } else {
            (m[(1, 1)] - m[(0, 0)], -(m[(1, 0)] + m[(0, 1)]))
        };
        // An estimate exactly upside down has no yaw: read it as 0 like calib-core's atan2(0, 0).
        let (c, s) = if c == 0.0 && s == 0.0 {
            (1.0, 0.0)
        } else {
            (c, s)
        };
        // |wrap(yaw_est − yaw_true)| = atan2(yaw_y, yaw_x), the angle between the yaw directions.
        let (ct, st) = t.yaw;
        let (yaw_x, yaw_y) = (c * ct + s * st, (s * ct - c * st).abs());
        // Both angles are atan2(y, x) with y ≥ 0, in [0, π]: the larger one's vector lies
        // counter-clockwise of the other's (positive cross product), so only it is evaluated. On a
        // tie (parallel or opposite vectors, or NaN) both are, and the larger is returned.
        let ccw = yaw_x * tilt_y - yaw_y * tilt_x;
        if ccw > 0.0 {
            tilt_y.atan2(tilt_x)
        } else if ccw < 0.0 {
            yaw_y.atan2(yaw_x)
        } else {
            tilt_y.atan2(tilt_x).max(yaw_y.atan2(yaw_x))
        }
    }
}

/// eq (33) against true ZYZ angles `zyz_true` (rad), allocation-free; the same value as
/// [`calib_core::e_rot_zyz`] (tested), rad. At a true θ within [`ZYZ_SINGULAR_BAND_RAD`] of 0 or
/// 180°: `max(tilt of the z axis, |yaw error|)`; elsewhere the smallest, over the exact ZYZ
/// readings of `r_est` that [`calib_core::zyz_nearest`] chooses among, of the largest wrapped angle
/// difference. For many estimates against one truth, build the [`ErotTruth`] once.
pub fn e_rot_fast(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
    ErotTruth::new(zyz_true).e_rot(r_est)
}

/// eq (33) on the nearest exact branch (both regular branches and, at `|sin θ_est| < 1e-9`, the
/// reference-anchored singular readings of [`calib_core::zyz_nearest`]), rad. `zyz_true` must be
/// wrapped to (−π, π] ([`ErotTruth::new`] does it), so that every difference below lies in
/// (−2π, 2π) and [`wrap_difference`] applies.
fn e_rot_regular(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
    use std::f64::consts::PI;
    let [phi, theta, psi] = zyz_from_rotation(r_est);
    let diff = |a: [f64; 3]| -> f64 {
        let mut d: f64 = 0.0;
        for i in 0..3 {
            d = d.max(wrap_difference(a[i] - zyz_true[i]).abs());
        }
        d
    };
    // φ, ψ ∈ (−π, π] and θ ∈ [0, π] (eq 32), so φ + π, ψ + π ∈ (0, 2π].
    let mut best = diff([phi, theta, psi]).min(diff([
        wrap_difference(phi + PI),
        -theta,
        wrap_difference(psi + PI),
    ]));
    // |sin θ| < 1e-9 needs θ within 1e-6 of 0 or π: test that first and skip the sine otherwise.
    if !(1e-6..=PI - 1e-6).contains(&theta) && theta.sin().abs() < 1e-9 {
        let phi_n = zyz_true[0];
        let psi_n = if theta.cos() > 0.0 {
            phi + psi - phi_n
        } else {
            phi_n - (phi - psi)
        };
        for th in [theta, -theta] {
            best = best.min(diff([phi_n, th, wrap_difference(psi_n)]));
        }
    }
    best
}

/// [`wrap_angle`] for `x ∈ (−3π, 3π)` (sums and differences of angles in (−π, π]): one exact
/// add or subtract of 2π (exact by Sterbenz's lemma for `π ≤ |x| ≤ 4π`), no `fmod`. Equal to
/// [`wrap_angle`] up to its own round-off (it keeps tiny negative angles that `wrap_angle` rounds
/// to 0). Outside that range, or NaN, it defers to [`wrap_angle`].
#[inline]
fn wrap_difference(x: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if x > PI {
        if x < 3.0 * PI {
            x - TAU
        } else {
            wrap_angle(x)
        }
    } else if x <= -PI {
        if x > -3.0 * PI {
            x + TAU
        } else {
            wrap_angle(x)
        }
    } else {
        x // (−π, π], and NaN
    }
}

/// One geometry-mode trial's setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeometrySpec {
    /// The mounts (used by the `paper` and `constrained` methods).
    pub mounts: MountPair,
    /// The true `b1_from_b2` (m, rad).
    pub b1_from_b2: Isometry3<f64>,
    /// Teach-point layout.
    pub layout: Layout,
    /// Number of teach points (1..=[`MAX_GEOMETRY_POINTS`]).
    pub n: usize,
    /// Layout size, m (see [`crate::layout`]).
    pub spread_m: f64,
    /// Centre of the teach points, m, b1 frame.
    pub centre_b1: Point3<f64>,
    /// σ of the operator's alignment error per b1 axis, m (≥ 0).
    pub sigma_m: Vector3<f64>,
}

impl GeometrySpec {
    /// The spec for one of the paper's cells (true placement and centre from
    /// [`crate::placement`]), isotropic noise `sigma_m`. `None` for mounts the paper did not use.
    pub fn paper(
        mounts: &MountPair,
        layout: Layout,
        n: usize,
        spread_m: f64,
        sigma_m: f64,
    ) -> Option<Self> {
        let p = paper_placement(mounts)?;
        Some(GeometrySpec {
            mounts: *mounts,
            b1_from_b2: p.b1_from_b2(),
            layout,
            n,
            spread_m,
            centre_b1: p.centre_b1(),
            sigma_m: Vector3::repeat(sigma_m),
        })
    }

    /// The true rotation's ZYZ angles (eq 32, rad), as e_rot compares against.
    pub fn zyz_true(&self) -> [f64; 3] {
        zyz_from_rotation(&self.b1_from_b2.rotation.to_rotation_matrix())
    }

    /// The truth's eq 33 reading ([`ErotTruth::new`] of [`GeometrySpec::zyz_true`]).
    pub fn erot_truth(&self) -> ErotTruth {
        ErotTruth::new(self.zyz_true())
    }

    /// Checks the spec: point count, finite non-negative spread and σ.
    pub fn validate(&self) -> Result<(), SimError> {
        if self.n == 0 || self.n > MAX_GEOMETRY_POINTS {
            return Err(SimError::InvalidInput(format!(
                "number of points {} is out of range: use 1..={MAX_GEOMETRY_POINTS} (4 or more for every method)",
                self.n
            )));
        }
        if !(self.spread_m.is_finite() && self.spread_m > 0.0) {
            return Err(SimError::InvalidInput(format!(
                "spread {} m must be a positive length (e.g. 1.0 m)",
                self.spread_m
            )));
        }
        if !self.sigma_m.iter().all(|s| s.is_finite() && *s >= 0.0) {
            return Err(SimError::InvalidInput(format!(
                "alignment σ {:?} m must be finite and ≥ 0",
                self.sigma_m.as_slice()
            )));
        }
        if !self.centre_b1.iter().all(|c| c.is_finite()) {
            return Err(SimError::InvalidInput("centre must be finite".into()));
        }
        Ok(())
    }
}

/// Draws one trial's points: `p_b1` the teach points (the true position of robot 1's tip) and
/// `p_b2 = b2_from_b1·(p_b1 + ε)` with `ε ~ N(0, diag(σ²))` the alignment error (b1 axes).
/// The slices' length is the point count (must be equal). Allocation-free.
pub fn draw_geometry(
    spec: &GeometrySpec,
    rng: &mut impl Rng,
    p_b1: &mut [Point3<f64>],
    p_b2: &mut [Point3<f64>],
) {
    teach_points_into(spec.layout, spec.spread_m, &spec.centre_b1, rng, p_b1);
    let b2_from_b1 = spec.b1_from_b2.inverse();
    for (a, b) in p_b1.iter().zip(p_b2.iter_mut()) {
        let eps = Vector3::new(
            spec.sigma_m.x * rng.sample::<f64, _>(StandardNormal),
            spec.sigma_m.y * rng.sample::<f64, _>(StandardNormal),
            spec.sigma_m.z * rng.sample::<f64, _>(StandardNormal),
        );
        *b = b2_from_b1 * (a + eps);
    }
}

/// Centred affine least squares `p1 ≈ M·p2 + t` (n ≥ 4, allocation-free): `(M, t)`.
fn affine_lsq_fast(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let n = p_b1.len() as f64;
    let c1 = p_b1.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let c2 = p_b2.iter().fold(Vector3::zeros(), |a, p| a + p.coords) / n;
    let mut s12 = Matrix3::zeros();
    let mut s22 = Matrix3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        let d1 = a.coords - c1;
        let d2 = b.coords - c2;
        s12 += d1 * d2.transpose();
        s22 += d2 * d2.transpose();
    }
    let m = s12 * s22.try_inverse()?;
    m.iter().all(|v| v.is_finite()).then(|| (m, c1 - m * c2))
}

/// eq (12) translation for rotation `q`.
fn eq12(p_b1: &[Point3<f64>], p_b2: &[Point3<f64>], q: &UnitQuaternion<f64>) -> Vector3<f64> {
    p_b1.iter().zip(p_b2).fold(Vector3::zeros(), |acc, (a, b)| {
        acc + (a.coords - q * b.coords)
    }) / p_b1.len() as f64
}

/// Fits `b1_from_b2` by `method` without allocation: calib-core's fast kernels for 4 points (and for
/// `lsq`/`constrained` at any n); for the 4-point methods with n > 4, the affine least-squares `H`
/// (as [`calib_core::generic_4point`] does) then the same rotation step. `None` when the method
/// needs more points, the points are degenerate for it, or the mounts are unsupported.
pub fn fit_fast(
    method: Method,
    mounts: &MountPair,
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
) -> Option<Isometry3<f64>> {
    let n = p_b1.len();
    if n != p_b2.len() || n < method.min_points() {
        return None;
    }
    match method {
        Method::Lsq => rigid_fit_fast(p_b1, p_b2),
        Method::Constrained => constrained_fast(p_b1, p_b2, mounts),
        Method::Generic | Method::GenericAffine | Method::Paper if n == 4 => {
            let a: &[Point3<f64>; 4] = p_b1.try_into().ok()?;
            let b: &[Point3<f64>; 4] = p_b2.try_into().ok()?;
            match method {
                Method::Paper => paper_fast(a, b, mounts),
                m => generic_fast(a, b, m == Method::GenericAffine),
            }
        }
        Method::Generic | Method::GenericAffine | Method::Paper => {
            let (m, t_h) = affine_lsq_fast(p_b1, p_b2)?;
            let q = if method == Method::Paper {
                UnitQuaternion::from_rotation_matrix(&project_rotation_family(&m, mounts).ok()?)
            } else {
                rotation_maximizing_trace(&m)?
            };
            let t = if method == Method::GenericAffine {
                t_h
            } else {
                eq12(p_b1, p_b2, &q)
            };
            Some(Isometry3::from_parts(Translation3::from(t), q))
        }
    }
}

/// One geometry-mode trial of one method: draws the points ([`draw_geometry`]) and fits them.
/// `Ok(None)` when the fit fails (degenerate points for the method); errors for an invalid spec.
///
/// # Examples
/// ```
/// use sim_cell::{layout::Layout, sweep::{geometry_trial, GeometrySpec}, trial_rng};
/// use calib_core::{Method, MountPair};
/// let spec = GeometrySpec::paper(&MountPair::floor_floor(), Layout::Tetrahedron, 4, 1.0, 0.5e-3).unwrap();
/// let e = geometry_trial(&spec, Method::Paper, &mut trial_rng(7, 0)).unwrap().unwrap();
/// assert!(e.e_tran < 5e-3); // m
/// ```
pub fn geometry_trial(
    spec: &GeometrySpec,
    method: Method,
    rng: &mut impl Rng,
) -> Result<Option<TrialErrors>, SimError> {
    spec.validate()?;
    const SMALL: usize = 16;
    if spec.n <= SMALL {
        let mut buf1 = [Point3::origin(); SMALL];
        let mut buf2 = [Point3::origin(); SMALL];
        Ok(geometry_trial_into(
            spec,
            &spec.erot_truth(),
            method,
            rng,
            &mut buf1[..spec.n],
            &mut buf2[..spec.n],
        ))
    } else {
        let mut buf1 = vec![Point3::origin(); spec.n];
        let mut buf2 = vec![Point3::origin(); spec.n];
        Ok(geometry_trial_into(
            spec,
            &spec.erot_truth(),
            method,
            rng,
            &mut buf1,
            &mut buf2,
        ))
    }
}

/// [`geometry_trial`] without validation, drawing into caller buffers (their length is the
/// point count; the spec's `n` is not used), with the truth's eq 33 reading precomputed
/// ([`GeometrySpec::erot_truth`]): allocation-free, for hot loops of a validated spec.
/// `None` when the fit fails.
pub fn geometry_trial_into(
    spec: &GeometrySpec,
    erot_truth: &ErotTruth,
    method: Method,
    rng: &mut impl Rng,
    p_b1: &mut [Point3<f64>],
    p_b2: &mut [Point3<f64>],
) -> Option<TrialErrors> {
    draw_geometry(spec, rng, p_b1, p_b2);
    fit_fast(method, &spec.mounts, p_b1, p_b2)
        .map(|est| TrialErrors::between_fast(&spec.b1_from_b2, erot_truth, &est))
}

/// [`trial_rng`] for many trials of one seed: the seed is expanded into the ChaCha key once, and
/// each trial's generator is a copy of the fresh keyed generator with its stream set, the same
/// state as `trial_rng(seed, index)` (tested).
#[derive(Debug, Clone)]
pub struct TrialRngs {
    base: ChaCha8Rng,
}

impl TrialRngs {
    /// The generators of master `seed`.
    pub fn new(seed: u64) -> Self {
        TrialRngs {
            base: trial_rng(seed, 0),
        }
    }

    /// The generator of trial `index`, equal to `trial_rng(seed, index)`.
    #[inline]
    pub fn get(&self, index: u64) -> ChaCha8Rng {
        let mut rng = self.base.clone();
        rng.set_stream(index);
        rng
    }
}

/// Why a trial gave no estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    /// The method could not fit these points (degenerate geometry, too few points).
    FitFailed,
    /// Robot mode: no layout draw was reachable by both robots.
    Unreachable,
}

impl Failure {
    /// Name in the CSV `status` column.
    pub fn name(self) -> &'static str {
        match self {
            Failure::FitFailed => "fit-failed",
            Failure::Unreachable => "unreachable",
        }
    }
}

/// A trial's result for one method.
pub type Outcome = Result<TrialErrors, Failure>;

/// Simulation mode of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Points and noise only (fast).
    Geometry,
    /// Full sessions on robot cells (IK, reach, joint-level noise).
    Robot,
}

impl Mode {
    /// `geometry` or `robot`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Geometry => "geometry",
            Mode::Robot => "robot",
        }
    }
}

/// A sweep's grid and settings. Noise is the operator's isotropic alignment σ per axis.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepConfig {
    /// Simulation mode.
    pub mode: Mode,
    /// Mount pairs (geometry mode: the paper's cells only, see [`crate::placement`]).
    pub mounts: Vec<MountPair>,
    /// Alignment σ per axis, mm.
    pub noise_mm: Vec<f64>,
    /// Layout spreads, m.
    pub spread_m: Vec<f64>,
    /// Point counts.
    pub n_points: Vec<usize>,
    /// Methods fitted on every trial.
    pub methods: Vec<Method>,
    /// Teach-point layout.
    pub layout: Layout,
    /// Trials per grid cell.
    pub trials: usize,
    /// Master seed.
    pub seed: u64,
}

impl Default for SweepConfig {
    /// The default study: the paper's three cells, noise 0.5/1/2/3 mm, spread 0.25/0.5/1/1.5 m,
    /// 4/6/8/12 points, every method, tetrahedron layout, 200 trials per cell, seed 1, geometry mode.
    fn default() -> Self {
        SweepConfig {
            mode: Mode::Geometry,
            mounts: vec![
                MountPair::floor_floor(),
                MountPair::floor_wall(),
                MountPair::floor_ceiling(),
            ],
            noise_mm: vec![0.5, 1.0, 2.0, 3.0],
            spread_m: vec![0.25, 0.5, 1.0, 1.5],
            n_points: vec![4, 6, 8, 12],
            methods: Method::ALL.to_vec(),
            layout: Layout::Tetrahedron,
            trials: 200,
            seed: 1,
        }
    }
}

/// One grid cell: indices into the config's axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridCell {
    /// Index into `mounts`.
    pub mounts: usize,
    /// Index into `noise_mm`.
    pub noise: usize,
    /// Index into `spread_m`.
    pub spread: usize,
    /// Index into `n_points`.
    pub n: usize,
}

impl SweepConfig {
    /// Checks every axis: non-empty, finite, in range; names the axis and what would work.
    pub fn validate(&self) -> Result<(), SimError> {
        let empty = |name: &str| {
            SimError::InvalidInput(format!("the {name} axis is empty: give at least one value"))
        };
        if self.mounts.is_empty() {
            return Err(empty("mounts"));
        }
        if self.noise_mm.is_empty() {
            return Err(empty("noise"));
        }
        if self.spread_m.is_empty() {
            return Err(empty("spread"));
        }
        if self.n_points.is_empty() {
            return Err(empty("points"));
        }
        if self.methods.is_empty() {
            return Err(empty("methods"));
        }
        if self.trials == 0 {
            return Err(SimError::InvalidInput("--trials must be at least 1".into()));
        }
        if let Some(v) = self
            .noise_mm
            .iter()
            .find(|v| !(v.is_finite() && **v >= 0.0))
        {
            return Err(SimError::InvalidInput(format!(
                "noise {v} mm must be finite and ≥ 0 (e.g. 0.5,1,2,3)"
            )));
        }
        if let Some(v) = self.spread_m.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            return Err(SimError::InvalidInput(format!(
                "spread {} mm must be a positive length (e.g. 250,500,1000,1500)",
                v * 1000.0
            )));
        }
        if let Some(n) = self
            .n_points
            .iter()
            .find(|n| **n < 3 || **n > MAX_GEOMETRY_POINTS)
        {
            return Err(SimError::InvalidInput(format!(
                "{n} points is out of range: use 3..={MAX_GEOMETRY_POINTS} (the 4-point methods need ≥ 4)"
            )));
        }
        if self.mode == Mode::Geometry {
            if let Some(m) = self.mounts.iter().find(|m| paper_placement(m).is_none()) {
                return Err(SimError::InvalidInput(format!(
                    "geometry mode knows the paper's cells only (floor-floor, floor-wall, floor-ceiling), not {}",
                    mounts_label(m)
                )));
            }
        }
        Ok(())
    }

    /// The grid cells in sweep order (mounts, noise, spread, n; n fastest).
    pub fn grid(&self) -> Vec<GridCell> {
        let mut out = Vec::new();
        for mounts in 0..self.mounts.len() {
            for noise in 0..self.noise_mm.len() {
                for spread in 0..self.spread_m.len() {
                    for n in 0..self.n_points.len() {
                        out.push(GridCell {
                            mounts,
                            noise,
                            spread,
                            n,
                        });
                    }
                }
            }
        }
        out
    }

    /// Total number of trials (grid cells × trials per cell).
    pub fn total_trials(&self) -> usize {
        self.mounts.len()
            * self.noise_mm.len()
            * self.spread_m.len()
            * self.n_points.len()
            * self.trials
    }
}

/// A finished sweep: outcome `[trial · methods.len() + method]` for every global trial index.
#[derive(Debug, Clone)]
pub struct SweepResult {
    /// The configuration it ran.
    pub config: SweepConfig,
    /// The grid cells (index = cell number).
    pub grid: Vec<GridCell>,
    /// Outcomes, trial-major, methods in `config.methods` order.
    pub outcomes: Vec<Outcome>,
}

impl SweepResult {
    /// Outcome of global trial `trial` for method index `m`.
    pub fn outcome(&self, trial: usize, m: usize) -> &Outcome {
        &self.outcomes[trial * self.config.methods.len() + m]
    }
}

/// Runs the sweep in parallel on the current rayon pool. Robot mode needs one [`Cell`] per mount
/// pair of the config (same order; their alignment σ is replaced by the noise axis);
/// geometry mode ignores `cells`. `progress` is advanced by trials.
pub fn run_sweep(
    config: &SweepConfig,
    cells: &[Cell],
    progress: &ProgressBar,
) -> Result<SweepResult, SimError> {
    config.validate()?;
    if config.mode == Mode::Robot && cells.len() != config.mounts.len() {
        return Err(SimError::InvalidInput(format!(
            "robot mode needs one cell per mount pair: {} cells for {} mount pairs",
            cells.len(),
            config.mounts.len()
        )));
    }
    if config.mode == Mode::Robot {
        if let Some((c, m)) = cells
            .iter()
            .zip(&config.mounts)
            .find(|(c, m)| c.mounts() != **m)
        {
            return Err(SimError::InvalidInput(format!(
                "robot mode: a cell has mounts {} but its grid entry is {}; give the cells in the order of --mounts",
                mounts_label(&c.mounts()),
                mounts_label(m)
            )));
        }
    }
    let grid = config.grid();
    let total = config.total_trials();
    let n_methods = config.methods.len();
    let specs: Vec<(GeometrySpec, ErotTruth)> = grid
        .iter()
        .map(|g| {
            let spec = geometry_spec(config, g);
            (spec, spec.erot_truth())
        })
        .collect();
    let rngs = TrialRngs::new(config.seed);
    // One item per trial × method, written in place into `outcomes` by rayon (no serial
    // pre-fill of the output); a worker runs a trial's methods when it meets the trial's first
    // item it is given (a trial split between two workers is run by both, identically).
    let mut outcomes: Vec<Outcome> = Vec::new();
    (0..total * n_methods)
        .into_par_iter()
        .with_min_len(CHUNK * n_methods)
        .map_init(
            || Worker::new(progress),
            |w, item| {
                let trial = item / n_methods;
                if w.trial != Some(trial) {
                    w.trial = Some(trial);
                    w.outcomes.clear();
                    let cell_index = trial / config.trials;
                    let mut rng = rngs.get(trial as u64);
                    match config.mode {
                        Mode::Geometry => {
                            let (spec, erot_truth) = &specs[cell_index];
                            let (p1, p2) = (&mut w.buf1[..spec.n], &mut w.buf2[..spec.n]);
                            draw_geometry(spec, &mut rng, p1, p2);
                            w.outcomes.extend(config.methods.iter().map(|&method| {
                                fit_fast(method, &spec.mounts, p1, p2)
                                    .map(|est| {
                                        TrialErrors::between_fast(
                                            &spec.b1_from_b2,
                                            erot_truth,
                                            &est,
                                        )
                                    })
                                    .ok_or(Failure::FitFailed)
                            }));
                        }
                        Mode::Robot => {
                            let cell = &grid[cell_index];
                            robot_trial(
                                config,
                                cell,
                                &cells[cell.mounts],
                                &mut rng,
                                &mut w.outcomes,
                            );
                        }
                    }
                }
                let m = item % n_methods;
                if m == 0 {
                    w.count_trial();
                }
                w.outcomes[m]
            },
        )
        .collect_into_vec(&mut outcomes);
    Ok(SweepResult {
        config: config.clone(),
        grid,
        outcomes,
    })
}

/// Per-worker state of [`run_sweep`]: point buffers, the trial in hand and its outcomes (one per
/// method), and progress not yet reported (reported every [`CHUNK`] trials and when dropped).
struct Worker<'a> {
    buf1: Vec<Point3<f64>>,
    buf2: Vec<Point3<f64>>,
    trial: Option<usize>,
    outcomes: Vec<Outcome>,
    progress: &'a ProgressBar,
    pending: u64,
}

impl<'a> Worker<'a> {
    fn new(progress: &'a ProgressBar) -> Self {
        Worker {
            buf1: vec![Point3::origin(); MAX_GEOMETRY_POINTS],
            buf2: vec![Point3::origin(); MAX_GEOMETRY_POINTS],
            trial: None,
            outcomes: Vec::new(),
            progress,
            pending: 0,
        }
    }

    fn count_trial(&mut self) {
        self.pending += 1;
        if self.pending == CHUNK as u64 {
            self.progress.inc(self.pending);
            self.pending = 0;
        }
    }
}

impl Drop for Worker<'_> {
    fn drop(&mut self) {
        self.progress.inc(self.pending);
    }
}

/// The geometry spec of a grid cell.
fn geometry_spec(config: &SweepConfig, cell: &GridCell) -> GeometrySpec {
    let mounts = &config.mounts[cell.mounts];
    let p = paper_placement(mounts).unwrap_or(crate::placement::FLOOR_FLOOR);
    GeometrySpec {
        mounts: *mounts,
        b1_from_b2: p.b1_from_b2(),
        layout: config.layout,
        n: config.n_points[cell.n],
        spread_m: config.spread_m[cell.spread],
        centre_b1: p.centre_b1(),
        sigma_m: Vector3::repeat(config.noise_mm[cell.noise] / 1000.0),
    }
}

/// One robot-mode trial: a simulated session on `cell` (σ from the grid), every method fitted on
/// the controllers' nominal tips, errors against the cell's true `b1_from_b2`.
fn robot_trial(
    config: &SweepConfig,
    grid_cell: &GridCell,
    cell: &Cell,
    rng: &mut rand_chacha::ChaCha8Rng,
    out: &mut Vec<Outcome>,
) {
    let mut cell = cell.clone();
    cell.noise.alignment_m = Vector3::repeat(config.noise_mm[grid_cell.noise] / 1000.0);
    let spec = SessionSpec {
        n: config.n_points[grid_cell.n],
        layout: config.layout,
        spread_m: config.spread_m[grid_cell.spread],
        centre_b1: None,
        points_b1: None,
    };
    match generate_session(&cell, &spec, rng) {
        Ok(session) => {
            let (p1, p2) = session.tips();
            for &method in &config.methods {
                out.push(
                    fit_fast(method, &config.mounts[grid_cell.mounts], &p1, &p2)
                        .map(|est| TrialErrors::between(&cell.b1_from_b2, &est))
                        .ok_or(Failure::FitFailed),
                );
            }
        }
        Err(_) => out.extend(config.methods.iter().map(|_| Err(Failure::Unreachable))),
    }
}

/// Writes every trial × method as CSV: `seed,trial,cell,trial_in_cell,mode,mounts,layout,method,
/// noise_mm,spread_mm,n,status,e_tran_mm,e_rot_deg,geodesic_deg,dx_mm,dy_mm,dz_mm` (errors empty
/// when the status is not `ok`; `trial` is the index given to [`trial_rng`]). Deterministic text.
pub fn write_trials_csv(result: &SweepResult, w: &mut impl Write) -> std::io::Result<()> {
    let c = &result.config;
    writeln!(
        w,
        "seed,trial,cell,trial_in_cell,mode,mounts,layout,method,noise_mm,spread_mm,n,status,e_tran_mm,e_rot_deg,geodesic_deg,dx_mm,dy_mm,dz_mm"
    )?;
    let labels: Vec<String> = c.mounts.iter().map(mounts_label).collect();
    for trial in 0..c.total_trials() {
        let cell_idx = trial / c.trials;
        let cell = result.grid[cell_idx];
        for (m, method) in c.methods.iter().enumerate() {
            write!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},",
                c.seed,
                trial,
                cell_idx,
                trial % c.trials,
                c.mode.name(),
                labels[cell.mounts],
                c.layout.name(),
                method.name(),
                c.noise_mm[cell.noise],
                c.spread_m[cell.spread] * 1000.0,
                c.n_points[cell.n],
            )?;
            match result.outcome(trial, m) {
                Ok(e) => writeln!(
                    w,
                    "ok,{:.6},{:.7},{:.7},{:.6},{:.6},{:.6}",
                    e.e_tran * 1e3,
                    e.e_rot.to_degrees(),
                    e.geodesic.to_degrees(),
                    e.translation_error.x * 1e3,
                    e.translation_error.y * 1e3,
                    e.translation_error.z * 1e3
                )?,
                Err(f) => writeln!(w, "{},,,,,,", f.name())?,
            }
        }
    }
    Ok(())
}

/// Statistics of one method over a group of trials.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// Mount pair label.
    pub mounts: String,
    /// Method.
    pub method: Method,
    /// Noise σ, mm (None when pooled over the noise axis).
    pub noise_mm: Option<f64>,
    /// Spread, m (None when pooled).
    pub spread_m: Option<f64>,
    /// Point count (None when pooled).
    pub n: Option<usize>,
    /// Trials in the group.
    pub trials: usize,
    /// Trials without an estimate.
    pub failed: usize,
    /// Median e_tran, mm, with 95 % CI.
    pub e_tran_mm_median: QuantileCi,
    /// 95th percentile e_tran, mm, with 95 % CI.
    pub e_tran_mm_p95: QuantileCi,
    /// Median e_rot, degrees, with 95 % CI.
    pub e_rot_deg_median: QuantileCi,
    /// 95th percentile e_rot, degrees, with 95 % CI.
    pub e_rot_deg_p95: QuantileCi,
    /// Median geodesic error, degrees, with 95 % CI.
    pub geodesic_deg_median: QuantileCi,
    /// 95th percentile geodesic error, degrees, with 95 % CI.
    pub geodesic_deg_p95: QuantileCi,
}

fn summary_row(
    result: &SweepResult,
    mounts: usize,
    m: usize,
    key: (Option<f64>, Option<f64>, Option<usize>),
    trials: impl Iterator<Item = usize>,
) -> SummaryRow {
    let mut count = 0;
    let mut failed = 0;
    let (mut et, mut er, mut eg) = (Vec::new(), Vec::new(), Vec::new());
    for t in trials {
        count += 1;
        match result.outcome(t, m) {
            Ok(e) => {
                et.push(e.e_tran * 1e3);
                er.push(e.e_rot.to_degrees());
                eg.push(e.geodesic.to_degrees());
            }
            Err(_) => failed += 1,
        }
    }
    let (et, er, eg) = (sorted_finite(et), sorted_finite(er), sorted_finite(eg));
    SummaryRow {
        mounts: mounts_label(&result.config.mounts[mounts]),
        method: result.config.methods[m],
        noise_mm: key.0,
        spread_m: key.1,
        n: key.2,
        trials: count,
        failed,
        e_tran_mm_median: quantile_ci(&et, 0.5),
        e_tran_mm_p95: quantile_ci(&et, 0.95),
        e_rot_deg_median: quantile_ci(&er, 0.5),
        e_rot_deg_p95: quantile_ci(&er, 0.95),
        geodesic_deg_median: quantile_ci(&eg, 0.5),
        geodesic_deg_p95: quantile_ci(&eg, 0.95),
    }
}

/// One row per grid cell × method.
pub fn summarize_cells(result: &SweepResult) -> Vec<SummaryRow> {
    let c = &result.config;
    let mut rows = Vec::new();
    for (ci, cell) in result.grid.iter().enumerate() {
        for m in 0..c.methods.len() {
            let key = (
                Some(c.noise_mm[cell.noise]),
                Some(c.spread_m[cell.spread]),
                Some(c.n_points[cell.n]),
            );
            rows.push(summary_row(
                result,
                cell.mounts,
                m,
                key,
                ci * c.trials..(ci + 1) * c.trials,
            ));
        }
    }
    rows
}

/// One row per mount pair × method, pooled over the noise, spread and point-count axes.
pub fn summarize_pooled(result: &SweepResult) -> Vec<SummaryRow> {
    let c = &result.config;
    let mut rows = Vec::new();
    for mi in 0..c.mounts.len() {
        for m in 0..c.methods.len() {
            let trials = result
                .grid
                .iter()
                .enumerate()
                .filter(|(_, g)| g.mounts == mi)
                .flat_map(|(ci, _)| ci * c.trials..(ci + 1) * c.trials);
            rows.push(summary_row(result, mi, m, (None, None, None), trials));
        }
    }
    rows
}

fn ci_text(q: &QuantileCi, decimals: usize) -> String {
    format!(
        "{:.d$} [{:.d$}, {:.d$}]",
        q.value,
        q.lower,
        q.upper,
        d = decimals
    )
}

/// The terminal table: mounts, method, trials, failures, then median and p95 of e_tran (mm),
/// e_rot (deg, eq 33, read the paper's way at the floor–floor / floor–ceiling singularity, see
/// [`calib_core::e_rot_zyz`]) and the geodesic angle (deg), each `value [95 % CI]`.
pub fn render_table(rows: &[SummaryRow]) -> String {
    let header = [
        "mounts".to_string(),
        "method".into(),
        "trials".into(),
        "failed".into(),
        "e_tran median mm".into(),
        "e_tran p95 mm".into(),
        "e_rot median deg".into(),
        "e_rot p95 deg".into(),
        "geodesic median deg".into(),
        "geodesic p95 deg".into(),
    ];
    let body: Vec<[String; 10]> = rows
        .iter()
        .map(|r| {
            [
                r.mounts.clone(),
                r.method.name().into(),
                r.trials.to_string(),
                r.failed.to_string(),
                ci_text(&r.e_tran_mm_median, 3),
                ci_text(&r.e_tran_mm_p95, 3),
                ci_text(&r.e_rot_deg_median, 4),
                ci_text(&r.e_rot_deg_p95, 4),
                ci_text(&r.geodesic_deg_median, 4),
                ci_text(&r.geodesic_deg_p95, 4),
            ]
        })
        .collect();
    let mut widths = header.clone().map(|h| h.chars().count());
    for r in &body {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: &[String; 10]| {
        let mut s = String::new();
        for (i, (c, w)) in cells.iter().zip(&widths).enumerate() {
            if i > 0 {
                s.push_str("  ");
            }
            if i < 2 {
                s.push_str(&format!("{c:<w$}"));
            } else {
                s.push_str(&format!("{c:>w$}"));
            }
        }
        s.trim_end().to_string() + "\n"
    };
    let mut s = line(&header);
    s.push_str(&"-".repeat(widths.iter().sum::<usize>() + 2 * (widths.len() - 1)));
    s.push('\n');
    for r in &body {
        s.push_str(&line(r));
    }
    s
}

/// Writes summary rows as CSV (`mounts,method,noise_mm,spread_mm,n,trials,failed`, then for each
/// statistic `_value,_lo,_hi`; pooled axes are empty).
pub fn write_summary_csv(rows: &[SummaryRow], w: &mut impl Write) -> std::io::Result<()> {
    let stats = [
        "e_tran_mm_median",
        "e_tran_mm_p95",
        "e_rot_deg_median",
        "e_rot_deg_p95",
        "geodesic_deg_median",
        "geodesic_deg_p95",
    ];
    write!(w, "mounts,method,noise_mm,spread_mm,n,trials,failed")?;
    for s in stats {
        write!(w, ",{s},{s}_lo,{s}_hi")?;
    }
    writeln!(w)?;
    let opt = |v: Option<String>| v.unwrap_or_default();
    for r in rows {
        write!(
            w,
            "{},{},{},{},{},{},{}",
            r.mounts,
            r.method.name(),
            opt(r.noise_mm.map(|v| v.to_string())),
            opt(r.spread_m.map(|v| (v * 1000.0).to_string())),
            opt(r.n.map(|v| v.to_string())),
            r.trials,
            r.failed
        )?;
        for q in [
            &r.e_tran_mm_median,
            &r.e_tran_mm_p95,
            &r.e_rot_deg_median,
            &r.e_rot_deg_p95,
            &r.geodesic_deg_median,
            &r.geodesic_deg_p95,
        ] {
            write!(w, ",{:.7},{:.7},{:.7}", q.value, q.lower, q.upper)?;
        }
        writeln!(w)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::placement::PAPER;
    use calib_core::{fit, rotation_from_zyz, PointPairs};
    use nalgebra::Rotation3;

    /// Fast and slow paths compute the same maths: agreement to round-off (m, rad).
    const SAME_MATHS_TOL: f64 = 1e-9;
    /// Exact data: recovery to round-off (m, rad).
    const EXACT_TOL: f64 = 1e-9;

    fn small_config() -> SweepConfig {
        SweepConfig {
            mode: Mode::Geometry,
            mounts: PAPER.iter().map(|p| p.mounts).collect(),
            noise_mm: vec![0.5, 3.0],
            spread_m: vec![0.25, 1.5],
            n_points: vec![4, 12],
            methods: Method::ALL.to_vec(),
            layout: Layout::Tetrahedron,
            trials: 30,
            seed: 7,
        }
    }

    #[test]
    fn e_rot_fast_matches_calib_core_including_singular_angles() {
        let mut rng = trial_rng(3, 0);
        let mut truths: Vec<[f64; 3]> = PAPER
            .iter()
            .map(|p| zyz_from_rotation(&p.b1_from_b2().rotation.to_rotation_matrix()))
            .collect();
        use std::f64::consts::PI;
        // Exactly at θ = 0 and 180°, tiny angles either side, the band's edges (1°) and a regular
        // truth next to them.
        let band = ZYZ_SINGULAR_BAND_RAD;
        truths.extend([
            [0.0, 0.0, 0.0],
            [0.3, 0.0, -0.7],
            [0.3, 1e-12, -0.7],
            [0.3, -1e-9, 2.9],
            [0.0, PI, 0.0],
            [0.3, PI, -0.7],
            [-3.0, PI - 1e-12, 3.1],
            [1.0, -PI + 1e-9, 0.2],
            [0.2, 0.999 * band, -1.0],
            [0.2, PI - 0.999 * band, -1.0],
            [0.2, 1.001 * band, -1.0],
            [0.2, PI - 1.001 * band, -1.0],
        ]);
        for zyz_true in truths {
            let r_true = rotation_from_zyz(zyz_true);
            let truth = ErotTruth::new(zyz_true);
            assert_eq!(truth.zyz(), zyz_true);
            for k in 0..300 {
                // Perturbations from 1e-12 rad (singular branch) to 1 rad, and exactly 0.
                let scale = if k == 299 { 0.0 } else { 10f64.powi(-(k % 13)) };
                let v = Vector3::new(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                ) * scale;
                let r_est = Rotation3::new(v) * r_true;
                let a = e_rot_fast(zyz_true, &r_est);
                let b = calib_core::e_rot_zyz(zyz_true, &r_est);
                assert!(
                    (a - b).abs() < SAME_MATHS_TOL,
                    "{zyz_true:?} {v:?}: {a} vs {b}"
                );
                assert_eq!(a, truth.e_rot(&r_est));
            }
            // A half turn about z (yaw error exactly 180°) and about x (estimate upside down).
            for axis in [Vector3::z_axis(), Vector3::x_axis()] {
                let r_est = Rotation3::from_axis_angle(&axis, PI) * r_true;
                let (a, b) = (
                    e_rot_fast(zyz_true, &r_est),
                    calib_core::e_rot_zyz(zyz_true, &r_est),
                );
                assert!(
                    (a - b).abs() < SAME_MATHS_TOL,
                    "{zyz_true:?} {axis:?}: {a} vs {b}"
                );
            }
        }
    }

    #[test]
    fn fit_fast_matches_calib_core_slow_paths() {
        for placement in PAPER {
            for n in [4, 7] {
                let spec =
                    GeometrySpec::paper(&placement.mounts, Layout::Random, n, 1.0, 1e-3).unwrap();
                let mut p1 = vec![Point3::origin(); n];
                let mut p2 = vec![Point3::origin(); n];
                draw_geometry(&spec, &mut trial_rng(11, n as u64), &mut p1, &mut p2);
                let pairs = PointPairs::new(p1.clone(), p2.clone()).unwrap();
                for method in Method::ALL {
                    let fast = fit_fast(method, &spec.mounts, &p1, &p2).unwrap();
                    let slow = fit(&pairs, method, &spec.mounts).unwrap().b1_from_b2;
                    assert!(
                        (fast.translation.vector - slow.translation.vector).amax() < SAME_MATHS_TOL
                            && fast.rotation.angle_to(&slow.rotation) < SAME_MATHS_TOL,
                        "{} n={n} {}",
                        placement.label(),
                        method.name()
                    );
                    let e = TrialErrors::between(&spec.b1_from_b2, &fast);
                    let zyz = zyz_from_rotation(&spec.b1_from_b2.rotation.to_rotation_matrix());
                    let f =
                        TrialErrors::between_fast(&spec.b1_from_b2, &ErotTruth::new(zyz), &fast);
                    assert!((e.e_tran - f.e_tran).abs() < SAME_MATHS_TOL);
                    assert!((e.e_rot - f.e_rot).abs() < SAME_MATHS_TOL);
                    assert!((e.geodesic - f.geodesic).abs() < SAME_MATHS_TOL);
                }
            }
        }
    }

    #[test]
    fn zero_noise_recovers_the_truth_up_to_the_mount_family_deviation() {
        for placement in PAPER {
            // How far Table 1's true rotation is from the mounts' family (it is a measurement).
            let truth = placement.b1_from_b2();
            let projected = project_rotation_family(
                &truth.rotation.to_rotation_matrix().into_inner(),
                &placement.mounts,
            )
            .unwrap();
            let family_dev = truth.rotation.to_rotation_matrix().angle_to(&projected);
            for method in Method::ALL {
                for n in [4, 9] {
                    let spec =
                        GeometrySpec::paper(&placement.mounts, Layout::Tetrahedron, n, 1.0, 0.0)
                            .unwrap();
                    let e = geometry_trial(&spec, method, &mut trial_rng(1, n as u64))
                        .unwrap()
                        .unwrap();
                    let constrained = matches!(method, Method::Paper | Method::Constrained);
                    // A constrained estimate lies in the family, so it is at least `family_dev` from the
                    // truth; the least-squares member differs from the nearest one only to second
                    // order, hence the 5 % margin.
                    let allowed = if constrained {
                        1.05 * family_dev + EXACT_TOL
                    } else {
                        EXACT_TOL
                    };
                    assert!(
                        e.geodesic <= allowed,
                        "{} {} n={n}: {e:?}",
                        placement.label(),
                        method.name()
                    );
                    if !constrained {
                        assert!(e.e_tran < EXACT_TOL);
                    }
                }
            }
        }
    }

    #[test]
    fn invalid_specs_are_errors_not_panics() {
        let mut spec =
            GeometrySpec::paper(&MountPair::floor_floor(), Layout::Random, 4, 1.0, 1e-3).unwrap();
        spec.n = MAX_GEOMETRY_POINTS + 1;
        assert!(geometry_trial(&spec, Method::Lsq, &mut trial_rng(1, 1)).is_err());
        spec.n = 4;
        spec.spread_m = f64::NAN;
        assert!(geometry_trial(&spec, Method::Lsq, &mut trial_rng(1, 1)).is_err());
        let mut c = small_config();
        c.noise_mm = vec![];
        assert!(c.validate().unwrap_err().to_string().contains("noise"));
        let mut c = small_config();
        c.mounts = vec![MountPair {
            robot1: calib_core::Mount::Floor,
            robot2: calib_core::Mount::Tilt { rx: 0.1, ry: 0.0 },
        }];
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("paper's cells"));
        // Too few points for a method is a failed fit, not a panic.
        let spec3 =
            GeometrySpec::paper(&MountPair::floor_floor(), Layout::Random, 3, 1.0, 1e-3).unwrap();
        assert_eq!(
            geometry_trial(&spec3, Method::Generic, &mut trial_rng(1, 1)).unwrap(),
            None
        );
    }

    fn csv_with_threads(config: &SweepConfig, threads: usize) -> Vec<u8> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let progress = ProgressBar::hidden();
        let result = pool.install(|| run_sweep(config, &[], &progress)).unwrap();
        // Every trial is counted once, even when a trial is split between two workers.
        assert_eq!(progress.position(), config.total_trials() as u64);
        let mut out = Vec::new();
        write_trials_csv(&result, &mut out).unwrap();
        write_summary_csv(&summarize_cells(&result), &mut out).unwrap();
        out
    }

    #[test]
    fn same_seed_gives_byte_identical_csv_with_one_and_two_threads() {
        let mut config = small_config();
        // More trials than one work chunk so that two threads really split the work.
        config.trials = 2 * CHUNK / config.grid().len() + 7;
        let a = csv_with_threads(&config, 1);
        let b = csv_with_threads(&config, 2);
        assert_eq!(a, b);
        config.seed = 8;
        assert_ne!(a, csv_with_threads(&config, 2));
    }

    #[test]
    fn wrap_difference_equals_wrap_angle() {
        use std::f64::consts::{PI, TAU};
        assert_eq!(wrap_difference(PI), PI);
        assert_eq!(wrap_difference(-PI), PI);
        assert_eq!(wrap_difference(TAU), 0.0);
        assert_eq!(wrap_difference(-1e-300), -1e-300); // wrap_angle rounds this to 0
        assert!(wrap_difference(f64::NAN).is_nan());
        let mut x: f64 = -12.0;
        while x < 12.0 {
            for y in [x, x + 4e-15, x - 4e-15] {
                let (a, b) = (wrap_difference(y), wrap_angle(y));
                assert!(a > -PI && a <= PI, "{y} -> {a}");
                // wrap_angle's own round-off: one ulp of 2π.
                assert!((a - b).abs() <= 1e-15, "{y}: {a} vs {b}");
            }
            x += PI / 64.0;
        }
    }

    #[test]
    fn trial_rngs_equal_trial_rng() {
        for seed in [0, 1, 7, u64::MAX] {
            let rngs = TrialRngs::new(seed);
            for index in [0, 1, 2, 63, 64, 1 << 20, u64::MAX] {
                let (mut a, mut b) = (rngs.get(index), trial_rng(seed, index));
                for _ in 0..100 {
                    assert_eq!(a.random::<u64>(), b.random::<u64>());
                }
            }
        }
    }

    #[test]
    fn trial_k_replays_alone() {
        let config = small_config();
        let result = run_sweep(&config, &[], &ProgressBar::hidden()).unwrap();
        let k = 3 * config.trials + 5; // grid cell 3
        let g = result.grid[k / config.trials];
        let spec = GeometrySpec::paper(
            &config.mounts[g.mounts],
            config.layout,
            config.n_points[g.n],
            config.spread_m[g.spread],
            config.noise_mm[g.noise] / 1000.0,
        )
        .unwrap();
        for (m, method) in config.methods.iter().enumerate() {
            let alone =
                geometry_trial(&spec, *method, &mut trial_rng(config.seed, k as u64)).unwrap();
            assert_eq!(alone.ok_or(Failure::FitFailed), *result.outcome(k, m));
        }
    }

    /// Median of a statistic over a grid cell's rows.
    fn median_of(
        rows: &[SummaryRow],
        mounts: &str,
        method: Method,
        noise: f64,
        spread: f64,
        n: usize,
    ) -> (f64, f64) {
        let r = rows
            .iter()
            .find(|r| {
                r.mounts == mounts
                    && r.method == method
                    && r.noise_mm == Some(noise)
                    && r.spread_m == Some(spread)
                    && r.n == Some(n)
            })
            .unwrap();
        (r.e_tran_mm_median.value, r.geodesic_deg_median.value)
    }

    #[test]
    fn small_sweep_shows_the_expected_trends() {
        let mut config = small_config();
        config.trials = 300;
        config.mounts = vec![MountPair::floor_floor(), MountPair::floor_ceiling()];
        config.methods = vec![
            Method::Generic,
            Method::Paper,
            Method::Lsq,
            Method::Constrained,
        ];
        let rows = summarize_cells(&run_sweep(&config, &[], &ProgressBar::hidden()).unwrap());
        for mounts in ["floor-floor", "floor-ceiling"] {
            for &method in &config.methods {
                // Error falls with spread (n = 4, σ = 1 mm... here 0.5 and 3 mm).
                for noise in [0.5, 3.0] {
                    let small = median_of(&rows, mounts, method, noise, 0.25, 4);
                    let large = median_of(&rows, mounts, method, noise, 1.5, 4);
                    assert!(
                        large.0 < small.0 && large.1 < small.1,
                        "{mounts} {method:?} spread: {small:?} -> {large:?}"
                    );
                }
                // Error falls with the point count.
                let few = median_of(&rows, mounts, method, 3.0, 1.5, 4);
                let many = median_of(&rows, mounts, method, 3.0, 1.5, 12);
                assert!(
                    many.0 < few.0 && many.1 < few.1,
                    "{mounts} {method:?} points: {few:?} -> {many:?}"
                );
                // Error rises with noise.
                let quiet = median_of(&rows, mounts, method, 0.5, 1.5, 12);
                let loud = median_of(&rows, mounts, method, 3.0, 1.5, 12);
                assert!(
                    loud.0 > quiet.0 && loud.1 > quiet.1,
                    "{mounts} {method:?} noise: {quiet:?} -> {loud:?}"
                );
            }
        }
    }

    #[test]
    fn table_and_summary_csv_render() {
        let result = run_sweep(&small_config(), &[], &ProgressBar::hidden()).unwrap();
        let t = render_table(&summarize_pooled(&result));
        assert!(t.contains("floor-wall") && t.contains("generic-affine") && t.contains('['));
        let mut out = Vec::new();
        write_summary_csv(&summarize_cells(&result), &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert_eq!(text.lines().count(), 1 + result.grid.len() * 5);
    }

    proptest::proptest! {
        /// The allocation-free metrics equal calib-core's for any truth and estimate
        /// (tolerance: round-off, rad and m).
        #[test]
        fn fast_metrics_equal_calib_core(
            phi in -3.2f64..3.2, theta in 0.0f64..std::f64::consts::PI, psi in -3.2f64..3.2,
            ex in -0.5f64..0.5, ey in -0.5f64..0.5, ez in -0.5f64..0.5, scale_exp in 0i32..12,
            tx in -2.0f64..2.0,
        ) {
            let truth = Isometry3::from_parts(
                Translation3::new(tx, 0.3, -0.2),
                UnitQuaternion::from_rotation_matrix(&rotation_from_zyz([phi, theta, psi])),
            );
            let d = Vector3::new(ex, ey, ez) * 10f64.powi(-scale_exp);
            let est = Isometry3::from_parts(
                Translation3::new(tx + ex * 1e-3, 0.3, -0.2),
                UnitQuaternion::new(d) * truth.rotation,
            );
            let a = TrialErrors::between(&truth, &est);
            let b = TrialErrors::between_fast(&truth, &ErotTruth::new(zyz_from_rotation(&truth.rotation.to_rotation_matrix())), &est);
            proptest::prop_assert!((a.e_tran - b.e_tran).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.e_rot - b.e_rot).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.geodesic - b.geodesic).abs() < SAME_MATHS_TOL);
            proptest::prop_assert!((a.rotation_error - b.rotation_error).amax() < SAME_MATHS_TOL);
        }
    }
}

//! Geometry-mode trials and the allocation-free kernels they use: the teach points and noise of a
//! trial ([`GeometrySpec`], [`draw_geometry`]), every method's fast fit ([`fit_fast`]) and the
//! metrics of an estimate ([`TrialErrors`], [`ErotTruth`], [`e_rot_fast`]).

use calib_core::ZYZ_SINGULAR_BAND_RAD;
use calib_core::{
    constrained_fast, e_rot, e_tran, generic_fast, geodesic_angle, paper_fast,
    project_rotation_family, rigid_fit_fast, rotation_maximizing_trace, wrap_angle,
    zyz_from_rotation, Method, MountPair,
};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

use super::MAX_GEOMETRY_POINTS;
use crate::error::SimError;
use crate::layout::{teach_points_into, Layout};
use crate::placement::paper_placement;

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
pub(super) struct SingularTruth {
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
pub(super) fn e_rot_regular(zyz_true: [f64; 3], r_est: &Rotation3<f64>) -> f64 {
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
pub(super) fn wrap_difference(x: f64) -> f64 {
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
pub(super) fn affine_lsq_fast(
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
pub(super) fn eq12(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    q: &UnitQuaternion<f64>,
) -> Vector3<f64> {
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

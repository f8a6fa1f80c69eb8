//! Bad-handclasp detection by leave-one-out residuals.

use crate::error::CalibError;
use crate::points::PointPairs;
use crate::registration::{
    family_axes, fit, nearest_rotation, project_rotation_family, spread_singular_values, Fit,
    Method, MountPair,
};
use nalgebra::{DMatrix, Matrix3, Matrix4, Matrix4x3, Vector3, Vector4};

/// A point is flagged when its leave-one-out residual exceeds this multiple of the residual scale of
/// the fit without it (an externally studentised residual) …
pub const OUTLIER_FACTOR: f64 = 5.0;
/// … and also exceeds this absolute floor, m (so that noise-free data flags nothing).
pub const OUTLIER_MIN_M: f64 = 1e-3;
/// Up to this many points [`leave_one_out`] refits exactly once per point (cost O(n²), a few ms
/// here); above it, `lsq` and `constrained` use the linearised deletion formulas (cost O(n)).
pub const EXACT_LOO_MAX_POINTS: usize = 200;

/// Leave-one-out residuals of every point, and the points flagged as bad handclasps.
/// Serialises (serde) with the fields' SI units.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct OutlierReport {
    /// Source rows, one per point.
    pub rows: Vec<usize>,
    /// `‖p1ᵢ − X₋ᵢ·p2ᵢ‖` with `X₋ᵢ` fitted without point i, m.
    pub loo_residuals_m: Vec<f64>,
    /// Per point, the threshold used, m: `max(OUTLIER_FACTOR·s₋ᵢ, OUTLIER_MIN_M)` with
    /// `s₋ᵢ = √(3·RSS₋ᵢ/(3(n−1) − 6))` the per-point residual scale of the fit without point i.
    pub thresholds_m: Vec<f64>,
    /// Per point: flagged as a bad handclasp.
    pub flagged: Vec<bool>,
}

impl OutlierReport {
    /// Source rows of the flagged points.
    pub fn flagged_rows(&self) -> Vec<usize> {
        self.rows
            .iter()
            .zip(&self.flagged)
            .filter(|(_, f)| **f)
            .map(|(r, _)| *r)
            .collect()
    }
}

/// Fits `method` once per point with that point left out and measures how far the left-out point
/// falls from that fit (its leave-one-out residual). A point is flagged when this exceeds
/// `max(OUTLIER_FACTOR × s₋ᵢ, OUTLIER_MIN_M)`, `s₋ᵢ` being the residual scale of the fit without it
/// (a bad point inflates the others' leave-one-out residuals, but also the scale they are judged
/// against, while its own fit-without-it is clean). Needs one point more than the method needs
/// (`TooFewPoints` otherwise); with 4–5 points read a flag as "look at this row", not as proof.
///
/// Cost: exact refits up to [`EXACT_LOO_MAX_POINTS`] points; above, `lsq` and `constrained` take
/// the linearised formulas of [`leave_one_out_linearised`] (linear in n, equal to the refits to
/// second order in the point's influence, tested), and the 4-point methods (`generic`,
/// `generic-affine`, `paper`) the downdated sums of [`leave_one_out_four_point`] (linear in n,
/// equal to the refits to round-off, tested).
pub fn leave_one_out(
    pairs: &PointPairs,
    method: Method,
    mounts: &MountPair,
) -> Result<OutlierReport, CalibError> {
    let n = pairs.len();
    if n < method.min_points() + 1 {
        return Err(CalibError::TooFewPoints {
            method: format!("leave-one-out with {}", method.name()),
            needed: method.min_points() + 1,
            got: n,
        });
    }
    if n > EXACT_LOO_MAX_POINTS && matches!(method, Method::Lsq | Method::Constrained) {
        let full = fit(pairs, method, mounts)?;
        return leave_one_out_linearised(pairs, &full, mounts);
    }
    if n > EXACT_LOO_MAX_POINTS {
        // The 4-point methods: the full fit first, so that its errors (degenerate points, wall
        // mounts for `paper`) come out as they would from the refits.
        fit(pairs, method, mounts)?;
        return leave_one_out_four_point(pairs, method, mounts);
    }
    let mut loo = Vec::with_capacity(n);
    let mut thresholds_m = Vec::with_capacity(n);
    for i in 0..n {
        let sub = pairs.without(i);
        let f = fit(&sub, method, mounts)?;
        loo.push((pairs.p_b1[i] - f.b1_from_b2 * pairs.p_b2[i]).norm());
        let rss: f64 = f.residuals.iter().map(|r| r.norm_squared()).sum();
        let dof = (3 * (n - 1)).saturating_sub(6).max(1) as f64;
        let scale = (3.0 * rss / dof).sqrt();
        thresholds_m.push((OUTLIER_FACTOR * scale).max(OUTLIER_MIN_M));
    }
    let flagged = loo.iter().zip(&thresholds_m).map(|(r, t)| r > t).collect();
    Ok(OutlierReport {
        rows: (0..n).map(|i| pairs.row(i)).collect(),
        loo_residuals_m: loo,
        thresholds_m,
        flagged,
    })
}

/// [`leave_one_out`] for `full`, the fit `fit(pairs, full.method, mounts)` already made: the same
/// report, without fitting every point again (above [`EXACT_LOO_MAX_POINTS`] points, `lsq` and
/// `constrained` linearise `full` itself, where [`leave_one_out`] refits it first; a full fit's
/// residuals are 24 bytes a point). Below that, or for the 4-point methods, it is
/// [`leave_one_out`]. Errors: those of [`leave_one_out`].
pub fn leave_one_out_of_fit(
    pairs: &PointPairs,
    full: &Fit,
    mounts: &MountPair,
) -> Result<OutlierReport, CalibError> {
    if pairs.len() > EXACT_LOO_MAX_POINTS
        && matches!(full.method, Method::Lsq | Method::Constrained)
    {
        return leave_one_out_linearised(pairs, full, mounts);
    }
    leave_one_out(pairs, full.method, mounts)
}

/// Leave-one-out residuals of a least-squares fit (`lsq` or `constrained`) without refitting, in
/// O(n): the deletion formulas of linear least squares applied to the fit linearised at its optimum.
///
/// With `eᵢ = p1ᵢ − X̂·p2ᵢ` (m), `Jᵢ` the 3×k Jacobian of `eᵢ` with respect to the fit's free
/// rotation angles (rad, left perturbation about the family's axes in b1) and `δt` (m), and
/// `A = Σ JᵢᵀJᵢ`, the one-step Gauss–Newton fit without point i moves by
/// `(A − JᵢᵀJᵢ)⁻¹Jᵢᵀeᵢ`, so (Sherman–Morrison–Woodbury, `Hᵢ = Jᵢ·A⁻¹·Jᵢᵀ`, 3×3):
/// - leave-one-out residual `eᵢ₋ = (I − Hᵢ)⁻¹·eᵢ`,
/// - residual sum of squares without i `RSS₋ᵢ = RSS − eᵢᵀ·(I − Hᵢ)⁻¹·eᵢ`.
///
/// Exact for a linear model; here the neglected terms are second order in the fit's change
/// (relative size ~ ‖eᵢ‖/(n·spread)). Thresholds and flags as in [`leave_one_out`].
/// Errors: a point with no leverage left (`I − Hᵢ` singular: the fit without it is undetermined)
/// gives `TooFewPoints`; the mount errors of the fit.
pub fn leave_one_out_linearised(
    pairs: &PointPairs,
    full: &Fit,
    mounts: &MountPair,
) -> Result<OutlierReport, CalibError> {
    let n = pairs.len();
    let r = full.b1_from_b2.rotation.to_rotation_matrix();
    let axes: Vec<Vector3<f64>> = match full.method {
        Method::Constrained => family_axes(mounts, &r)?,
        _ => vec![Vector3::x(), Vector3::y(), Vector3::z()],
    };
    let k = axes.len() + 3;
    let jac = |i: usize| {
        let y = full.b1_from_b2 * pairs.p_b2[i];
        let mut j = nalgebra::OMatrix::<f64, nalgebra::U3, nalgebra::Dyn>::zeros(k);
        for (c, a) in axes.iter().enumerate() {
            j.set_column(c, &y.coords.cross(a));
        }
        for d in 0..3 {
            j[(d, axes.len() + d)] = -1.0;
        }
        j
    };
    let mut a = DMatrix::<f64>::zeros(k, k);
    for i in 0..n {
        let j = jac(i);
        a += j.transpose() * &j;
    }
    let too_few = || CalibError::TooFewPoints {
        method: format!("leave-one-out with {}", full.method.name()),
        needed: full.method.min_points() + 1,
        got: n,
    };
    let a_inv = a.try_inverse().ok_or_else(too_few)?;
    let rss: f64 = full.residuals.iter().map(|e| e.norm_squared()).sum();
    let dof = (3 * (n - 1)).saturating_sub(6).max(1) as f64;
    let mut loo = Vec::with_capacity(n);
    let mut thresholds_m = Vec::with_capacity(n);
    for (i, e) in full.residuals.iter().enumerate() {
        let j = jac(i);
        let h_dyn = &j * &a_inv * j.transpose();
        let h = Matrix3::from_fn(|r, c| h_dyn[(r, c)]);
        let m_inv = (Matrix3::identity() - h)
            .try_inverse()
            .ok_or_else(too_few)?;
        let e_loo = m_inv * e;
        loo.push(e_loo.norm());
        let rss_without = (rss - e.dot(&e_loo)).max(0.0);
        let scale = (3.0 * rss_without / dof).sqrt();
        thresholds_m.push((OUTLIER_FACTOR * scale).max(OUTLIER_MIN_M));
    }
    let flagged = loo.iter().zip(&thresholds_m).map(|(r, t)| r > t).collect();
    Ok(OutlierReport {
        rows: (0..n).map(|i| pairs.row(i)).collect(),
        loo_residuals_m: loo,
        thresholds_m,
        flagged,
    })
}

/// Leave-one-out of the 4-point methods (`generic`, `generic-affine`, `paper`) in O(n), equal to
/// the refits of [`leave_one_out`] to round-off: every quantity a refit without point i needs is
/// a sum over the points, so it is the full sum minus point i's term.
///
/// In coordinates centred on the full centroids (`a = p1 − c1`, `b = p2 − c2`; residuals do not
/// change), with `x = [b; 1]`: the affine fit without i is `H₋ᵢ = (G − xᵢxᵢᵀ)⁻¹(C − xᵢaᵢᵀ)`
/// (`G = Σ xxᵀ`, `C = Σ xaᵀ`, 4×4 and 4×3), its rotation the nearest rotation of (or, for `paper`,
/// the mounts' family member nearest to) the 3×3 block, its translation H's column (moved back
/// to the original origin for `generic-affine`) or eq (12) from the downdated centroids. The residual sum of squares
/// without i follows from `Σ‖a‖²`, `Σ‖b‖²`, `Σ a·bᵀ`, `Σ a`, `Σ b` (R orthogonal):
/// `RSS₋ᵢ = Σ‖a‖² + Σ‖b‖² + m‖t‖² − 2·tr(Rᵀ·Σ a·bᵀ) − 2·tᵀΣa + 2·tᵀR·Σb` over the m = n − 1
/// other points. Thresholds and flags as in [`leave_one_out`].
///
/// Errors: `TooFewPoints` below 5 points or for `lsq`/`constrained` (use
/// [`leave_one_out_linearised`]); `Coplanar` when the points without i are coplanar; the mount
/// errors of `paper`; `NumericalFailure` when an affine solve overflows.
pub fn leave_one_out_four_point(
    pairs: &PointPairs,
    method: Method,
    mounts: &MountPair,
) -> Result<OutlierReport, CalibError> {
    let n = pairs.len();
    if n < 5 || matches!(method, Method::Lsq | Method::Constrained) {
        return Err(CalibError::TooFewPoints {
            method: format!("four-point leave-one-out with {}", method.name()),
            needed: 5,
            got: n,
        });
    }
    let centroid = |p: &[nalgebra::Point3<f64>]| {
        p.iter().fold(Vector3::zeros(), |s, q| s + q.coords) / n as f64
    };
    let (c1, c2) = (centroid(&pairs.p_b1), centroid(&pairs.p_b2));
    let a: Vec<Vector3<f64>> = pairs.p_b1.iter().map(|p| p.coords - c1).collect();
    let b: Vec<Vector3<f64>> = pairs.p_b2.iter().map(|p| p.coords - c2).collect();
    let x = |i: usize| Vector4::new(b[i].x, b[i].y, b[i].z, 1.0);
    let mut g = Matrix4::zeros();
    let mut c = Matrix4x3::zeros();
    let (mut s_a, mut s_b) = (Vector3::zeros(), Vector3::zeros());
    let mut s_ab = Matrix3::zeros();
    let (mut q_a, mut q_b) = (0.0, 0.0);
    for i in 0..n {
        let xi = x(i);
        g += xi * xi.transpose();
        c += xi * a[i].transpose();
        s_a += a[i];
        s_b += b[i];
        s_ab += a[i] * b[i].transpose();
        q_a += a[i].norm_squared();
        q_b += b[i].norm_squared();
    }
    let m = (n - 1) as f64;
    let dof = (3 * (n - 1)).saturating_sub(6).max(1) as f64;
    let mut loo = Vec::with_capacity(n);
    let mut thresholds_m = Vec::with_capacity(n);
    for i in 0..n {
        let xi = x(i);
        let g_i = g - xi * xi.transpose();
        let Some(g_inv) = g_i.try_inverse() else {
            let (rows, p_b2): (Vec<usize>, Vec<_>) = (0..n)
                .filter(|&j| j != i)
                .map(|j| (pairs.row(j), pairs.p_b2[j]))
                .unzip();
            return Err(CalibError::Coplanar {
                rows,
                robot: 2,
                singular_values_mm: spread_singular_values(&p_b2).map(|s| s * 1e3),
            });
        };
        let h = g_inv * (c - xi * a[i].transpose());
        if !h.iter().all(|v| v.is_finite()) {
            return Err(CalibError::NumericalFailure {
                method: method.name().into(),
                message: format!(
                    "leave-one-out without row {}: the affine solve overflowed",
                    pairs.row(i)
                ),
            });
        }
        let block = Matrix3::from_fn(|r, col| h[(col, r)]);
        let r = match method {
            Method::Paper => project_rotation_family(&block, mounts)?.into_inner(),
            _ => nearest_rotation(&block).into_inner(),
        };
        let (sa, sb) = (s_a - a[i], s_b - b[i]);
        let t = match method {
            // H's column in the original coordinates is `t_H + c1 − M·c2`, so in the centred
            // ones the translation paired with R is `t_H − (M − R)·c2` (generic-affine is not
            // invariant to the origin).
            Method::GenericAffine => {
                Vector3::new(h[(3, 0)], h[(3, 1)], h[(3, 2)]) - (block - r) * c2
            }
            _ => sa / m - r * (sb / m),
        };
        let e = a[i] - r * b[i] - t;
        loo.push(e.norm());
        let sab = s_ab - a[i] * b[i].transpose();
        let rss = q_a - a[i].norm_squared() + q_b - b[i].norm_squared() + m * t.norm_squared()
            - 2.0 * (r.transpose() * sab).trace()
            - 2.0 * t.dot(&sa)
            + 2.0 * t.dot(&(r * sb));
        let scale = (3.0 * rss.max(0.0) / dof).sqrt();
        thresholds_m.push((OUTLIER_FACTOR * scale).max(OUTLIER_MIN_M));
    }
    let flagged = loo.iter().zip(&thresholds_m).map(|(r, t)| r > t).collect();
    Ok(OutlierReport {
        rows: (0..n).map(|i| pairs.row(i)).collect(),
        loo_residuals_m: loo,
        thresholds_m,
        flagged,
    })
}

/// Default expected alignment noise of a handclasp, m: the median residual norm a valid session
/// stays below (recorded handclasps agree to about 0.1–1 mm; a few mm allows for worn tips and
/// uncalibrated kinematics). The CLI's `--expected-noise-mm` overrides it.
pub const DEFAULT_EXPECTED_NOISE_M: f64 = 5e-3;

/// One-sided false-alarm rate of [`misfit_threshold_m`]: a healthy session is refused about once
/// in 1000.
pub const MISFIT_FALSE_ALARM: f64 = 1e-3;

/// The largest median residual norm (m) a fit of `n_points` handclasps by `method` reaches at
/// alignment noise `sigma_m` per axis, but for a chance of [`MISFIT_FALSE_ALARM`]: the bound the
/// points-mode plausibility check compares [`median_residual_m`] with.
///
/// Derivation: with isotropic Gaussian noise σ per axis on each residual, |r|²/σ² is χ² with 3
/// degrees of freedom, shrunk on average by the fit's parameters to (3n − p)/(3n) of it (p = 6 for
/// a rigid fit, 12 for `generic-affine`, 4 for `constrained`: the mounts fix two rotations). The
/// sample median of n such norms sits at the χ²₃ quantile `P = ½ + z·½/√n` with probability
/// `1 − α` (the normal approximation of the median's rank, z = Φ⁻¹(1 − α)), so the bound is
/// `σ·√(χ²₃⁻¹(P))·√((3n − p)/(3n))`. At σ = 4.4 mm (the paper's noise) and 20 points the median
/// is ~6.4 mm and the bound 9.6 mm; a shifted row, swapped axes or a unit slip moves the
/// residuals by the layout's spread (hundreds of mm). NaN for a σ that is not finite and > 0.
pub fn misfit_threshold_m(n_points: usize, method: Method, sigma_m: f64) -> f64 {
    if !(sigma_m.is_finite() && sigma_m > 0.0) {
        return f64::NAN;
    }
    let n = n_points.max(1) as f64;
    let params = match method {
        Method::GenericAffine => 12.0,
        Method::Constrained => 4.0,
        Method::Generic | Method::Paper | Method::Lsq => 6.0,
    };
    let z = crate::stats::normal_quantile(1.0 - MISFIT_FALSE_ALARM);
    let p = (0.5 + z * 0.5 / n.sqrt()).min(1.0 - MISFIT_FALSE_ALARM);
    let chi2 = statrs::distribution::ChiSquared::new(3.0)
        .map(|d| statrs::distribution::ContinuousCDF::inverse_cdf(&d, p))
        .unwrap_or(f64::NAN);
    let shrink = ((3.0 * n - params).max(1.0) / (3.0 * n)).sqrt();
    sigma_m * chi2.sqrt() * shrink
}

/// Median of the residual norms of a fit, m (robust to a few bad handclasps, which
/// [`leave_one_out`] finds; a gross data mistake moves every residual).
pub fn median_residual_m(fit: &Fit) -> f64 {
    let mut v: Vec<f64> = fit.residuals.iter().map(|r| r.norm()).collect();
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// A data mistake that can make a fit's residuals far larger than the alignment noise.
///
/// Serialises (serde) as `{"kind": "rows-shifted", "robot2_offset": 1}` etc.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
#[non_exhaustive]
pub enum MisfitCause {
    /// Rows out of order: robot 1's row i belongs with robot 2's row `i + robot2_offset`.
    RowsShifted {
        /// Offset of robot 2's rows (±1, ±2 or ±3).
        robot2_offset: isize,
    },
    /// Two coordinate columns of one robot swapped.
    AxesSwapped {
        /// 1 or 2.
        robot: u8,
        /// The swapped axes (0 = x, 1 = y, 2 = z).
        axes: (usize, usize),
    },
    /// One coordinate column of one robot has the wrong sign.
    AxisFlipped {
        /// 1 or 2.
        robot: u8,
        /// The flipped axis (0 = x, 1 = y, 2 = z).
        axis: usize,
    },
    /// One robot's coordinates are in the wrong unit: multiplying them by `factor` fits.
    Units {
        /// 1 or 2.
        robot: u8,
        /// 1000 (the file has metres) or 0.001.
        factor: f64,
    },
    /// Robot 1's and robot 2's columns swapped (visible only with mounts, where the two differ).
    RobotOrder,
}

impl std::fmt::Display for MisfitCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        const AXIS: [&str; 3] = ["x", "y", "z"];
        match *self {
            MisfitCause::RowsShifted { robot2_offset } => write!(
                f,
                "rows out of order: robot 1's row i matches robot 2's row i{robot2_offset:+}"
            ),
            MisfitCause::AxesSwapped { robot, axes } => write!(
                f,
                "swapped axes: robot {robot}'s {} and {} columns are swapped",
                AXIS[axes.0], AXIS[axes.1]
            ),
            MisfitCause::AxisFlipped { robot, axis } => {
                write!(
                    f,
                    "wrong sign: robot {robot}'s {} column is negated",
                    AXIS[axis]
                )
            }
            MisfitCause::Units { robot, factor } => write!(
                f,
                "wrong units: robot {robot}'s coordinates fit when multiplied by {factor}"
            ),
            MisfitCause::RobotOrder => write!(
                f,
                "wrong robot order: the r1_* and r2_* columns are swapped (or the mounts are)"
            ),
        }
    }
}

/// The data mistakes that explain a misfit: each candidate of [`MisfitCause`] (robot 2's rows
/// shifted by ±1..3; each robot's axis pairs swapped and single axes negated; each robot ×1000 and
/// ×0.001; the robots swapped) is applied to `pairs`, `method` refitted, and the candidate kept
/// when its median residual norm ([`median_residual_m`]) is at most `expected_noise_m`. Returns
/// the kept causes with their median residual, m, best first; empty when none explains the data.
/// Causes with (nearly) equal medians cannot be told apart by the data: for a free rotation every
/// reflection of one robot (any swap or negation of its axes) fits equally well, and robot 2 ×1000
/// is robot 1 ×0.001 (residuals are compared in robot 1's original units).
/// Cost: 19 refits.
pub fn explain_misfit(
    pairs: &PointPairs,
    method: Method,
    mounts: &MountPair,
    expected_noise_m: f64,
) -> Vec<(MisfitCause, f64)> {
    let n = pairs.len();
    let mut candidates: Vec<(MisfitCause, PointPairs)> = Vec::new();
    for k in [-3isize, -2, -1, 1, 2, 3] {
        let (i0, i1) = (
            0.max(-k) as usize,
            (n as isize).min(n as isize - k).max(0) as usize,
        );
        if i1 <= i0 {
            continue;
        }
        let idx: Vec<usize> = (i0..i1).collect();
        candidates.push((
            MisfitCause::RowsShifted { robot2_offset: k },
            PointPairs {
                p_b1: idx.iter().map(|&i| pairs.p_b1[i]).collect(),
                p_b2: idx
                    .iter()
                    .map(|&i| pairs.p_b2[(i as isize + k) as usize])
                    .collect(),
                rows: idx.iter().map(|&i| pairs.row(i)).collect(),
            },
        ));
    }
    let map_robot = |robot: u8, g: &dyn Fn(&Vector3<f64>) -> Vector3<f64>| {
        let mut p = pairs.clone();
        let pts = if robot == 1 { &mut p.p_b1 } else { &mut p.p_b2 };
        for q in pts.iter_mut() {
            q.coords = g(&q.coords);
        }
        p
    };
    for robot in [1u8, 2] {
        for axes in [(0usize, 1usize), (0, 2), (1, 2)] {
            let p = map_robot(robot, &|v| {
                let mut w = *v;
                w.swap_rows(axes.0, axes.1);
                w
            });
            candidates.push((MisfitCause::AxesSwapped { robot, axes }, p));
        }
        for axis in 0..3 {
            let p = map_robot(robot, &|v| {
                let mut w = *v;
                w[axis] = -w[axis];
                w
            });
            candidates.push((MisfitCause::AxisFlipped { robot, axis }, p));
        }
        for factor in [1000.0, 1e-3] {
            candidates.push((
                MisfitCause::Units { robot, factor },
                map_robot(robot, &|v| v * factor),
            ));
        }
    }
    candidates.push((
        MisfitCause::RobotOrder,
        PointPairs {
            p_b1: pairs.p_b2.clone(),
            p_b2: pairs.p_b1.clone(),
            rows: pairs.rows.clone(),
        },
    ));
    let mut kept: Vec<(MisfitCause, f64)> = candidates
        .into_iter()
        .filter_map(|(cause, p)| {
            let f = fit(&p, method, mounts).ok()?;
            // Residuals are in robot 1's coordinates: undo a rescaling of robot 1 before comparing.
            let med = match cause {
                MisfitCause::Units { robot: 1, factor } => median_residual_m(&f) / factor,
                _ => median_residual_m(&f),
            };
            (med <= expected_noise_m).then_some((cause, med))
        })
        .collect();
    kept.sort_by(|a, b| a.1.total_cmp(&b.1));
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Point3, Vector3};

    #[test]
    fn bad_handclasp_is_flagged_by_row() {
        let truth = Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        );
        let p_b2: Vec<Point3<f64>> = (0..8)
            .map(|i| {
                let a = i as f64 * 0.8;
                Point3::new(0.9 * a.cos(), 0.9 * a.sin(), 0.2 + 0.12 * i as f64)
            })
            .collect();
        // Small deterministic "noise" (±0.2 mm) and one 15 mm bad handclasp at index 5.
        let mut p_b1: Vec<Point3<f64>> = p_b2
            .iter()
            .enumerate()
            .map(|(i, p)| truth * p + Vector3::new(0.2e-3 * ((i % 3) as f64 - 1.0), 0.0, 0.1e-3))
            .collect();
        p_b1[5].y += 0.015;
        let mut pairs = PointPairs::new(p_b1, p_b2).unwrap();
        pairs.rows = (10..18).collect();
        for method in [Method::Lsq, Method::Constrained] {
            let rep = leave_one_out(&pairs, method, &MountPair::floor_floor()).unwrap();
            assert_eq!(rep.flagged_rows(), vec![15], "{rep:?}");
        }
        // Clean data: nothing flagged.
        let mut clean = pairs.clone();
        clean.p_b1[5].y -= 0.015;
        let rep = leave_one_out(&clean, Method::Lsq, &MountPair::floor_floor()).unwrap();
        assert!(rep.flagged_rows().is_empty());
        // Too few points.
        let few = PointPairs::new(pairs.p_b1[..3].to_vec(), pairs.p_b2[..3].to_vec()).unwrap();
        assert!(leave_one_out(&few, Method::Lsq, &MountPair::floor_floor()).is_err());
    }

    /// A fast leave-one-out equals the exact one: every left-out residual and threshold within
    /// `tol` m, and the same flagged points.
    fn assert_same_loo(fast: &OutlierReport, exact: &OutlierReport, tol: f64, what: &str) {
        for i in 0..exact.loo_residuals_m.len() {
            let d = (fast.loo_residuals_m[i] - exact.loo_residuals_m[i]).abs();
            let dt = (fast.thresholds_m[i] - exact.thresholds_m[i]).abs();
            assert!(d < tol && dt < tol, "{what} point {i}: {d} {dt}");
        }
        assert_eq!(
            fast.loo_residuals_m.len(),
            exact.loo_residuals_m.len(),
            "{what}"
        );
        assert_eq!(fast.flagged, exact.flagged, "{what}");
    }

    /// `n` points scattered over a 1.6 × 1.6 × 1.2 m box in b2 (the leave-one-out tests' data).
    fn loo_scattered_points(rng: &mut impl rand::Rng, n: usize) -> Vec<Point3<f64>> {
        (0..n)
            .map(|_| {
                Point3::new(
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                    rng.random_range(0.0..1.2),
                )
            })
            .collect()
    }

    /// `p_b2` mapped into b1 by a fixed placement that fits `mounts` (a wall rotation for a wall
    /// robot 2, a yaw otherwise), plus `noise` per axis, m.
    fn loo_noisy_images(
        mounts: &MountPair,
        p_b2: &[Point3<f64>],
        noise: &rand_distr::Normal<f64>,
        rng: &mut impl rand::Rng,
    ) -> Vec<Point3<f64>> {
        use rand_distr::Distribution;
        let truth = match mounts.robot2 {
            crate::Mount::Wall => Isometry3::from_parts(
                nalgebra::Translation3::new(0.3, 1.4, 0.6),
                nalgebra::UnitQuaternion::from_rotation_matrix(
                    &crate::registration::wall_rotation(0.4, -0.9),
                ),
            ),
            _ => Isometry3::new(
                Vector3::new(0.04, 1.48, 0.05),
                Vector3::new(0.0, 0.0, -0.78),
            ),
        };
        p_b2.iter()
            .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(rng)))
            .collect()
    }

    /// The linearised leave-one-out equals the exact refits on moderate data: 60 points over about
    /// 1.6 m, 0.5 mm noise and one 20 mm bad handclasp, for `lsq` and `constrained` (floor–floor,
    /// floor–wall). The neglected terms are second order in the fit's change when a point is left
    /// out (measured ≤ 7e-8 m here); `LINEARISED_LOO_TOL` allows 1 µm, a thousandth
    /// of the report's 1e-3 mm print precision. The flags agree exactly.
    #[test]
    fn linearised_leave_one_out_matches_refits() {
        use rand::SeedableRng;
        use rand_distr::Normal;
        const LINEARISED_LOO_TOL: f64 = 1e-6;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(10);
        let noise = Normal::new(0.0, 0.5e-3).unwrap();
        let p_b2 = loo_scattered_points(&mut rng, 60);
        for mounts in [MountPair::floor_floor(), MountPair::floor_wall()] {
            let mut p_b1 = loo_noisy_images(&mounts, &p_b2, &noise, &mut rng);
            p_b1[17].x += 0.02;
            let pairs = PointPairs::new(p_b1, p_b2.clone()).unwrap();
            for method in [Method::Lsq, Method::Constrained] {
                let full = fit(&pairs, method, &mounts).unwrap();
                let fast = leave_one_out_linearised(&pairs, &full, &mounts).unwrap();
                let exact = leave_one_out(&pairs, method, &mounts).unwrap();
                assert_same_loo(
                    &fast,
                    &exact,
                    LINEARISED_LOO_TOL,
                    &format!("{mounts} {}", method.name()),
                );
                assert_eq!(exact.flagged_rows(), vec![18], "{mounts} {}", method.name());
            }
        }
    }

    /// The O(n) leave-one-out of the 4-point methods equals the refits (60 noisy points with a
    /// 20 mm blunder, floor–floor and floor–wall): the same sums, so only round-off differs
    /// (metre-scale coordinates, residuals of 1e-3 m: 1e-10 m is far above it, far below noise).
    #[test]
    fn four_point_leave_one_out_matches_refits() {
        use rand::SeedableRng;
        use rand_distr::Normal;
        const FOUR_POINT_LOO_TOL: f64 = 1e-10;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let noise = Normal::new(0.0, 0.5e-3).unwrap();
        let p_b2 = loo_scattered_points(&mut rng, 60);
        for mounts in [MountPair::floor_floor(), MountPair::floor_wall()] {
            let mut p_b1 = loo_noisy_images(&mounts, &p_b2, &noise, &mut rng);
            p_b1[23].y -= 0.02;
            let pairs = PointPairs::new(p_b1, p_b2.clone()).unwrap();
            for method in [Method::Generic, Method::GenericAffine, Method::Paper] {
                let fast = leave_one_out_four_point(&pairs, method, &mounts).unwrap();
                let exact = leave_one_out(&pairs, method, &mounts).unwrap();
                assert_same_loo(
                    &fast,
                    &exact,
                    FOUR_POINT_LOO_TOL,
                    &format!("{mounts} {}", method.name()),
                );
                assert_eq!(exact.flagged_rows(), vec![24], "{mounts} {}", method.name());
            }
            assert!(leave_one_out_four_point(&pairs, Method::Lsq, &mounts).is_err());
        }
    }

    /// [`leave_one_out_of_fit`] is [`leave_one_out`] given the full fit: identical reports (`==`)
    /// for every method, below [`EXACT_LOO_MAX_POINTS`] (60 points: refits) and above it (260:
    /// the linearised and four-point formulas), floor–floor and floor–wall, one 20 mm blunder.
    #[test]
    fn leave_one_out_of_the_fit_is_leave_one_out() {
        use rand::SeedableRng;
        use rand_distr::Normal;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(14);
        let noise = Normal::new(0.0, 0.5e-3).unwrap();
        for n in [60, EXACT_LOO_MAX_POINTS + 60] {
            let p_b2 = loo_scattered_points(&mut rng, n);
            for mounts in [MountPair::floor_floor(), MountPair::floor_wall()] {
                let mut p_b1 = loo_noisy_images(&mounts, &p_b2, &noise, &mut rng);
                p_b1[7].z += 0.02;
                let pairs = PointPairs::new(p_b1, p_b2.clone()).unwrap();
                for method in Method::ALL {
                    let what = format!("{n} points, {mounts} {}", method.name());
                    let Ok(full) = fit(&pairs, method, &mounts) else {
                        // A method the mounts refuse: leave-one-out refuses it too.
                        assert!(leave_one_out(&pairs, method, &mounts).is_err(), "{what}");
                        continue;
                    };
                    let given = leave_one_out_of_fit(&pairs, &full, &mounts).unwrap();
                    let refit = leave_one_out(&pairs, method, &mounts).unwrap();
                    assert_eq!(given, refit, "{what}");
                    assert_eq!(given.flagged_rows(), vec![8], "{what}");
                }
            }
        }
    }

    /// Gross data mistakes (issue 10: pairs shifted by one row, x/y swapped for one robot, robot 2
    /// in metres) give median residuals of hundreds of mm, and [`explain_misfit`] names the cause
    /// as the best explanation (its refit brings the median back to the 0.3 mm noise level).
    #[test]
    fn explain_misfit_names_shifted_rows_swapped_axes_and_units() {
        use rand::{Rng, SeedableRng};
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.3e-3).unwrap();
        let truth = Isometry3::new(
            Vector3::new(0.04, 1.48, 0.05),
            Vector3::new(0.0, 0.0, -0.78),
        );
        let p_b2: Vec<Point3<f64>> = (0..20)
            .map(|_| {
                Point3::new(
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                    rng.random_range(0.0..1.2),
                )
            })
            .collect();
        let p_b1: Vec<Point3<f64>> = p_b2
            .iter()
            .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng)))
            .collect();
        let mounts = MountPair::floor_floor();
        let good = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
        for method in [Method::Lsq, Method::Constrained] {
            assert!(median_residual_m(&fit(&good, method, &mounts).unwrap()) < 1e-3);
        }
        let mut shifted_b2 = p_b2.clone();
        shifted_b2.rotate_right(1); // robot 2's row i+1 holds the point of robot 1's row i
        let mut swapped_b2 = p_b2.clone();
        for p in &mut swapped_b2 {
            p.coords.swap_rows(0, 1);
        }
        let metres_b2: Vec<Point3<f64>> = p_b2.iter().map(|p| p * 1e-3).collect();
        let cases = [
            (shifted_b2, MisfitCause::RowsShifted { robot2_offset: 1 }),
            (
                swapped_b2,
                MisfitCause::AxesSwapped {
                    robot: 2,
                    axes: (0, 1),
                },
            ),
            (
                metres_b2,
                MisfitCause::Units {
                    robot: 2,
                    factor: 1000.0,
                },
            ),
        ];
        for (bad_b2, cause) in cases {
            let bad = PointPairs::new(p_b1.clone(), bad_b2).unwrap();
            for method in [Method::Lsq, Method::Constrained] {
                let f = fit(&bad, method, &mounts).unwrap();
                assert!(
                    median_residual_m(&f) > 0.05,
                    "{cause}: {}",
                    median_residual_m(&f)
                );
                let found = explain_misfit(&bad, method, &mounts, DEFAULT_EXPECTED_NOISE_M);
                // Reflections of either robot are equivalent for a free rotation (lsq): the cause
                // must be among the explanations tied (within 1 %) with the best, at noise level.
                let best = found.first().map_or(f64::INFINITY, |c| c.1);
                assert!(best < 1e-3, "{found:?}");
                assert!(
                    found.iter().any(|c| c.0 == cause && c.1 <= best * 1.01),
                    "{cause}: {found:?}"
                );
                // Robot 2 ×1000 is robot 1 ×0.001 (tied); a row shift has no twin.
                if matches!(cause, MisfitCause::RowsShifted { .. }) {
                    assert_eq!(found[0].0, cause, "{found:?}");
                }
            }
        }
    }
}

#[cfg(test)]
mod misfit_threshold_tests {
    use super::*;

    /// The bound against a seeded simulation of its own definition: the median of n residual
    /// norms of χ₃·σ·shrink exceeds it in about [`MISFIT_FALSE_ALARM`] of the draws (here: at
    /// most 5× that in 4000 draws), and the paper's noise (σ 4.4 mm, 20 points, lsq) stays below
    /// the default bound.
    #[test]
    fn bound_holds_its_false_alarm_rate() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, StandardNormal};
        const DRAWS: usize = 4000;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for n in [6usize, 20, 100] {
            let sigma = 1e-3;
            let limit = misfit_threshold_m(n, Method::Lsq, sigma);
            let shrink = ((3.0 * n as f64 - 6.0) / (3.0 * n as f64)).sqrt();
            let mut over = 0;
            for _ in 0..DRAWS {
                let mut norms: Vec<f64> = (0..n)
                    .map(|_| {
                        let v: [f64; 3] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
                        sigma * shrink * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
                    })
                    .collect();
                norms.sort_by(f64::total_cmp);
                let median = if n % 2 == 1 {
                    norms[n / 2]
                } else {
                    0.5 * (norms[n / 2 - 1] + norms[n / 2])
                };
                over += usize::from(median > limit);
            }
            let rate = over as f64 / DRAWS as f64;
            assert!(rate <= 5.0 * MISFIT_FALSE_ALARM, "n {n}: {rate}");
        }
        let paper = misfit_threshold_m(20, Method::Lsq, 4.4e-3);
        assert!((paper - 9.6e-3).abs() < 0.2e-3, "{paper}");
        assert!(misfit_threshold_m(20, Method::Lsq, DEFAULT_EXPECTED_NOISE_M) > 6.8e-3);
        assert!(misfit_threshold_m(20, Method::Lsq, f64::NAN).is_nan());
    }
}

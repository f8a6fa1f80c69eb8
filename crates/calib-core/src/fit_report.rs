//! The report of a points calibration ([`fit`] or [`constrained_soft`] on [`PointPairs`], with
//! [`leave_one_out`] and [`mount_check`]): typed structs in file units (mm, degrees) that
//! serialise to JSON and that a text renderer reads (`handclasp calibrate POINTS.csv` prints
//! them). Lengths are rounded to 1e-6 mm and the placement's angles to 1e-9°, the figures the
//! text prints from.
//!
//! The fields of every struct stand in alphabetical order: serde writes them in declaration
//! order, and this is the key order of the JSON the command printed before it had types.
//!
//! [`fit`]: crate::fit
//! [`constrained_soft`]: crate::constrained_soft
//! [`leave_one_out`]: crate::leave_one_out
//! [`mount_check`]: crate::mount_check

use serde::Serialize;

use crate::{
    leave_one_out, Fit, Method, MountCheck, MountPair, PointPairs, PoseForms, SoftFit,
    MOUNT_CHECK_ALPHA,
};

/// A length in m as report millimetres, rounded to 1e-6 mm.
fn report_mm(v_m: f64) -> f64 {
    (v_m * 1e3 * 1e6).round() / 1e6
}

/// An angle in rad as report degrees, rounded to 1e-9°.
fn report_deg(v_rad: f64) -> f64 {
    (v_rad.to_degrees() * 1e9).round() / 1e9
}

/// One points fit, its checks and its predicted uncertainty (mm, degrees).
#[derive(Debug, Clone, Serialize)]
pub struct FitReport {
    /// The fitted `b1_from_b2` (`p_b1 = b1_from_b2·p_b2`); `xyz_mm` rounded to 1e-6 mm and
    /// `zyz_deg` to 1e-9°.
    pub b1_from_b2: PoseForms,
    /// The fit's conditioning figure (≥ 1, larger is worse; [`Fit::condition`]).
    pub condition: f64,
    /// The method; serialised as its [`Method::name`].
    pub method: Method,
    /// The mounts' F-test against the points, for the methods that impose the mounts (absent
    /// from the JSON when not run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mount_check: Option<MountCheckReport>,
    /// The mounts as given (e.g. `floor-wall`), `None` when none were given.
    pub mounts: Option<String>,
    /// Leave-one-out outlier flags; `None` when the method leaves no point to spare.
    pub outliers: Option<OutliersReport>,
    /// Number of point pairs.
    pub points: usize,
    /// `|p_b1 − b1_from_b2·p_b2|` per point, mm.
    pub residual_norms_mm: Vec<f64>,
    /// RMS of the residual norms, mm (agreement between points, not an accuracy).
    pub residual_rms_mm: f64,
    /// `p_b1 − b1_from_b2·p_b2` per point, b1 axes, mm.
    pub residuals_mm: Vec<[f64; 3]>,
    /// The source row of each point (1-based file rows, as [`PointPairs::row`]).
    pub rows: Vec<usize>,
    /// The soft mount's estimate, for `constrained` with a tilt prior (absent from the JSON
    /// otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub soft_mount: Option<SoftMountReport>,
    /// Predicted uncertainty from the residuals and the Jacobian; `None` for the 4-point methods.
    pub uncertainty: Option<UncertaintyReport>,
}

impl FitReport {
    /// The report of `f` on `pairs`, with leave-one-out outlier flags (run here, with `mounts`
    /// or floor–floor when none are given). `mount_check` and `soft_mount` are left `None`.
    pub fn new(pairs: &PointPairs, f: &Fit, mounts: Option<&MountPair>) -> Self {
        let x = &f.b1_from_b2;
        let mut b1_from_b2 = PoseForms::from_isometry(x);
        b1_from_b2.xyz_mm = b1_from_b2.xyz_mm.map(|v| (v * 1e6).round() / 1e6);
        b1_from_b2.zyz_deg = b1_from_b2.zyz_deg.map(|v| (v * 1e9).round() / 1e9);
        let uncertainty = f.uncertainty.as_ref().map(|u| UncertaintyReport {
            covariance: [0, 1, 2, 3, 4, 5]
                .map(|i| [0, 1, 2, 3, 4, 5].map(|j| u.covariance[(i, j)])),
            covariance_order: COVARIANCE_ORDER,
            dof: u.dof,
            e_rot_1sigma_deg: report_deg(u.e_rot_1sigma_rad),
            e_tran_1sigma_mm: report_mm(u.e_tran_1sigma_m),
            sigma_point_mm: report_mm(u.sigma_point_m),
            tre_rms_mm_at_points: pairs
                .p_b2
                .iter()
                .map(|p| report_mm(u.tre_rms_m(x, p)))
                .collect(),
        });
        // Leave-one-out needs one point more than the method; the 4-point methods with 4 points
        // have none.
        let outliers = leave_one_out(pairs, f.method, mounts.unwrap_or(&MountPair::floor_floor()))
            .ok()
            .map(|rep| OutliersReport {
                flagged_rows: rep.flagged_rows(),
                loo_residuals_mm: rep.loo_residuals_m.iter().map(|v| report_mm(*v)).collect(),
                thresholds_mm: rep.thresholds_m.iter().map(|v| report_mm(*v)).collect(),
            });
        FitReport {
            b1_from_b2,
            condition: f.condition,
            method: f.method,
            mount_check: None,
            mounts: mounts.map(|m| m.to_string()),
            outliers,
            points: pairs.len(),
            residual_norms_mm: f.residuals.iter().map(|v| report_mm(v.norm())).collect(),
            residual_rms_mm: report_mm(f.residual_rms_m()),
            residuals_mm: f
                .residuals
                .iter()
                .map(|v| [report_mm(v.x), report_mm(v.y), report_mm(v.z)])
                .collect(),
            rows: (0..pairs.len()).map(|i| pairs.row(i)).collect(),
            soft_mount: None,
            uncertainty,
        }
    }
}

/// [`UncertaintyReport::covariance_order`].
const COVARIANCE_ORDER: &str = "[dθx, dθy, dθz (rad, b1 axes), dtx, dty, dtz (m)]";

/// A points fit's predicted uncertainty ([`crate::Uncertainty`]), mm and degrees.
#[derive(Debug, Clone, Serialize)]
pub struct UncertaintyReport {
    /// 6×6 covariance of `[δθ (rad, b1 axes); δt (m)]`, SI (row-major).
    pub covariance: [[f64; 6]; 6],
    /// The order and units of `covariance`'s rows.
    pub covariance_order: &'static str,
    /// Degrees of freedom of the residual (3n − k).
    pub dof: usize,
    /// Predicted 1σ rotation error, degrees.
    pub e_rot_1sigma_deg: f64,
    /// Predicted 1σ of e_tran, mm.
    pub e_tran_1sigma_mm: f64,
    /// Per-coordinate point noise σ estimated from the residuals, mm.
    pub sigma_point_mm: f64,
    /// Predicted error (target registration error, RMS) at each handclasp point, mm.
    pub tre_rms_mm_at_points: Vec<f64>,
}

/// Leave-one-out outlier flags ([`crate::OutlierReport`]), mm.
#[derive(Debug, Clone, Serialize)]
pub struct OutliersReport {
    /// Source rows of the points flagged as bad handclasps.
    pub flagged_rows: Vec<usize>,
    /// Per point, its residual against the fit without it, mm.
    pub loo_residuals_mm: Vec<f64>,
    /// Per point, the limit that residual is held to, mm.
    pub thresholds_mm: Vec<f64>,
}

/// The mounts' F-test against the points ([`MountCheck`]), mm and degrees.
#[derive(Debug, Clone, Serialize)]
pub struct MountCheckReport {
    /// The test's level ([`MOUNT_CHECK_ALPHA`]).
    pub alpha: f64,
    /// `p_value ≥ alpha`: the points do not contradict the mounts.
    pub consistent: bool,
    /// Rotation degrees of freedom the mounts remove.
    pub constraints: usize,
    /// Residual degrees of freedom of the free fit, `3n − 6`.
    pub dof: usize,
    /// The F statistic.
    pub f_statistic: f64,
    /// Its upper tail probability.
    pub p_value: f64,
    /// RMS residual per point of the installation-constrained fit, mm.
    pub rms_constrained_mm: f64,
    /// RMS residual per point of the free rigid fit, mm.
    pub rms_free_mm: f64,
    /// Angle between the constrained and the free fit's rotations, degrees (not rounded).
    pub rotation_gap_deg: f64,
}

impl MountCheckReport {
    /// The report of `c` over `points` point pairs.
    pub fn new(c: &MountCheck, points: usize) -> Self {
        MountCheckReport {
            alpha: MOUNT_CHECK_ALPHA,
            consistent: c.consistent(),
            constraints: c.constraints,
            dof: c.dof_free,
            f_statistic: c.f_statistic,
            p_value: c.p_value,
            rms_constrained_mm: report_mm((c.rss_constrained_m2 / points as f64).sqrt()),
            rms_free_mm: report_mm((c.rss_free_m2 / points as f64).sqrt()),
            rotation_gap_deg: c.rotation_gap_rad.to_degrees(),
        }
    }
}

/// The soft mount's estimate ([`SoftFit`]) and its priors, mm and degrees (not rounded).
#[derive(Debug, Clone, Serialize)]
pub struct SoftMountReport {
    /// The per-coordinate point noise σ the fit assumed, mm.
    pub point_sigma_mm: f64,
    /// Magnitude of the estimated relative tilt, degrees.
    pub tilt_estimate_deg: f64,
    /// The tilt prior's σ, degrees.
    pub tilt_sigma_deg: f64,
    /// The estimated relative tilt vector, b1 axes, degrees.
    pub tilt_vector_deg_b1: [f64; 3],
}

impl SoftMountReport {
    /// The report of `soft`, fitted with tilt prior σ `tilt_sigma_rad` (rad) and point noise
    /// `point_sigma_m` (m).
    pub fn new(soft: &SoftFit, tilt_sigma_rad: f64, point_sigma_m: f64) -> Self {
        SoftMountReport {
            point_sigma_mm: point_sigma_m * 1e3,
            tilt_estimate_deg: soft.tilt_angle_rad.to_degrees(),
            tilt_sigma_deg: tilt_sigma_rad.to_degrees(),
            tilt_vector_deg_b1: [
                soft.tilt_rad.x.to_degrees(),
                soft.tilt_rad.y.to_degrees(),
                soft.tilt_rad.z.to_degrees(),
            ],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit;
    use nalgebra::{Isometry3, Point3, Vector3};

    /// Eight noisy points of a known placement: the report's rows, units and rounding, and a JSON
    /// whose keys come out in the order above (alphabetical, as `serde_json::Value` sorts them).
    #[test]
    fn report_of_an_lsq_fit_in_mm_with_sorted_keys() {
        let b1_from_b2 = Isometry3::new(Vector3::new(1.2, -0.1, 0.3), Vector3::new(0.0, 0.0, 0.5));
        let p_b2: Vec<Point3<f64>> = (0..8)
            .map(|i| {
                let t = i as f64;
                Point3::new(0.3 * t.cos(), 0.4 * (1.3 * t).sin(), 0.1 * t)
            })
            .collect();
        // Residuals of ~0.1 mm, alternating in sign.
        let p_b1 = p_b2
            .iter()
            .enumerate()
            .map(|(i, p)| b1_from_b2 * p + Vector3::repeat(if i % 2 == 0 { 1e-4 } else { -1e-4 }))
            .collect();
        let pairs = PointPairs::new(p_b1, p_b2.clone()).unwrap();
        let f = fit(&pairs, Method::Lsq, &MountPair::floor_floor()).unwrap();
        let r = FitReport::new(&pairs, &f, None);
        assert_eq!(r.points, 8);
        assert_eq!(r.rows.len(), 8);
        assert_eq!(r.residuals_mm.len(), 8);
        assert!(r.mounts.is_none() && r.mount_check.is_none() && r.soft_mount.is_none());
        // mm, rounded to 1e-6 mm: the placement's 1200 mm translation comes out within the noise.
        assert!((r.b1_from_b2.xyz_mm[0] - 1200.0).abs() < 0.5);
        assert_eq!(
            r.b1_from_b2.xyz_mm[0],
            (r.b1_from_b2.xyz_mm[0] * 1e6).round() / 1e6
        );
        let u = r.uncertainty.as_ref().expect("lsq has an uncertainty");
        assert_eq!(u.tre_rms_mm_at_points.len(), 8);
        assert!(r.outliers.is_some());
        let text = serde_json::to_string(&r).unwrap();
        let sorted = serde_json::to_string(&serde_json::to_value(&r).unwrap()).unwrap();
        assert_eq!(text, sorted, "fields out of alphabetical order");
        assert!(text.contains(r#""method":"lsq""#), "{text}");
        assert!(!text.contains("mount_check") && !text.contains("soft_mount"));
    }
}

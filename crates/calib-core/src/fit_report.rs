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

use nalgebra::{Isometry3, Point3, Vector3};

use crate::{
    leave_one_out, Fit, Method, MountCheck, MountPair, OutlierReport, PointPairs, PoseForms,
    SoftFit, Uncertainty, MOUNT_CHECK_ALPHA,
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
    ///
    /// Holds every per-point array in memory (64 bytes a point); [`StreamedFitReport`] writes
    /// them from the fit when serialised instead.
    pub fn new(pairs: &PointPairs, f: &Fit, mounts: Option<&MountPair>) -> Self {
        // Leave-one-out needs one point more than the method; the 4-point methods with 4 points
        // have none.
        let outliers =
            leave_one_out(pairs, f.method, mounts.unwrap_or(&MountPair::floor_floor())).ok();
        StreamedFitReport::new(pairs, f.clone(), mounts, outliers).into_report()
    }
}

/// A points fit's report whose per-point arrays are written from the fit as the JSON is
/// serialised, instead of being held as [`FitReport`]'s vectors: the same JSON, byte for byte, as
/// the [`FitReport`] of [`StreamedFitReport::into_report`], in 40 bytes a point fewer (at 1e6
/// points, 64 MB of report arrays are never built; `handclasp calibrate POINTS.csv --json`
/// prints this).
///
/// It borrows the points (their rows and robot 2's points, for the predicted error at each
/// point) and keeps the fit's residuals and the leave-one-out figures, SI units.
#[derive(Debug, Clone)]
pub struct StreamedFitReport<'a> {
    /// The report without its per-point arrays: `residual_norms_mm`, `residuals_mm`, `rows`,
    /// `outliers.loo_residuals_mm`, `outliers.thresholds_mm` and
    /// `uncertainty.tre_rms_mm_at_points` are empty (serialising this struct writes them);
    /// every other field as [`FitReport::new`] fills it, and may be changed (a flagged row, the
    /// mount check, the soft mount).
    pub report: FitReport,
    /// The points fitted.
    pairs: &'a PointPairs,
    /// The fit's residuals `p_b1 − b1_from_b2·p_b2`, m, b1 axes.
    residuals_m: Vec<Vector3<f64>>,
    /// The fitted `b1_from_b2`, unrounded.
    b1_from_b2: Isometry3<f64>,
    /// The fit's uncertainty (for the predicted error at each point).
    uncertainty: Option<Uncertainty>,
    /// Leave-one-out residual and threshold per point, m (empty without leave-one-out).
    loo_residuals_m: Vec<f64>,
    /// See `loo_residuals_m`.
    thresholds_m: Vec<f64>,
}

impl<'a> StreamedFitReport<'a> {
    /// The report of `f` on `pairs` with the leave-one-out report `outliers` of `f`'s method
    /// ([`leave_one_out`] with `mounts` or floor–floor, or [`crate::leave_one_out_of_fit`];
    /// `None` when it does not apply). `mounts` is the mounts as given (`None`: none given).
    /// `mount_check` and `soft_mount` are left `None`. Takes the fit's residuals.
    pub fn new(
        pairs: &'a PointPairs,
        f: Fit,
        mounts: Option<&MountPair>,
        outliers: Option<OutlierReport>,
    ) -> Self {
        let x = f.b1_from_b2;
        let mut b1_from_b2 = PoseForms::from_isometry(&x);
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
            tre_rms_mm_at_points: Vec::new(),
        });
        let (outliers, loo_residuals_m, thresholds_m) = match outliers {
            Some(rep) => (
                Some(OutliersReport {
                    flagged_rows: rep.flagged_rows(),
                    loo_residuals_mm: Vec::new(),
                    thresholds_mm: Vec::new(),
                }),
                rep.loo_residuals_m,
                rep.thresholds_m,
            ),
            None => (None, Vec::new(), Vec::new()),
        };
        let report = FitReport {
            b1_from_b2,
            condition: f.condition,
            method: f.method,
            mount_check: None,
            mounts: mounts.map(|m| m.to_string()),
            outliers,
            points: pairs.len(),
            residual_norms_mm: Vec::new(),
            residual_rms_mm: report_mm(f.residual_rms_m()),
            residuals_mm: Vec::new(),
            rows: Vec::new(),
            soft_mount: None,
            uncertainty,
        };
        StreamedFitReport {
            report,
            pairs,
            residuals_m: f.residuals,
            b1_from_b2: x,
            uncertainty: f.uncertainty,
            loo_residuals_m,
            thresholds_m,
        }
    }

    /// The fitted `b1_from_b2` (`p_b1 = b1_from_b2·p_b2`), SI units, unrounded.
    pub fn b1_from_b2(&self) -> &Isometry3<f64> {
        &self.b1_from_b2
    }

    /// The [`FitReport`] with its per-point arrays filled (the fit's residuals and the
    /// leave-one-out vectors become the report's in place).
    pub fn into_report(self) -> FitReport {
        let mut report = self.report;
        report.residual_norms_mm = self.residuals_m.iter().map(norm_mm).collect();
        report.residuals_mm = self.residuals_m.into_iter().map(|v| xyz_mm(&v)).collect();
        report.rows = (0..self.pairs.len()).map(|i| self.pairs.row(i)).collect();
        if let Some(o) = report.outliers.as_mut() {
            o.loo_residuals_mm = self.loo_residuals_m.into_iter().map(report_mm).collect();
            o.thresholds_mm = self.thresholds_m.into_iter().map(report_mm).collect();
        }
        if let (Some(r), Some(u)) = (report.uncertainty.as_mut(), self.uncertainty.as_ref()) {
            let x = &self.b1_from_b2;
            r.tre_rms_mm_at_points = self.pairs.p_b2.iter().map(|p| tre_mm(u, x, p)).collect();
        }
        report
    }
}

/// A residual's norm as report mm.
fn norm_mm(v: &Vector3<f64>) -> f64 {
    report_mm(v.norm())
}

/// A residual's coordinates as report mm.
fn xyz_mm(v: &Vector3<f64>) -> [f64; 3] {
    [report_mm(v.x), report_mm(v.y), report_mm(v.z)]
}

/// The predicted error at `p_b2` as report mm.
fn tre_mm(u: &Uncertainty, x: &Isometry3<f64>, p_b2: &Point3<f64>) -> f64 {
    report_mm(u.tre_rms_m(x, p_b2))
}

/// Lengths in m as a sequence of report mm.
fn mm_seq(v: &[f64]) -> Seq<impl ExactSizeIterator<Item = f64> + Clone + '_> {
    Seq(v.iter().map(|v| report_mm(*v)))
}

/// A sequence serialised from an iterator (cloned to be walked), as a `Vec` of its items is.
struct Seq<I>(I);

impl<I> Serialize for Seq<I>
where
    I: Iterator + ExactSizeIterator + Clone,
    I::Item: Serialize,
{
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let items = self.0.clone();
        let mut seq = s.serialize_seq(Some(items.len()))?;
        for item in items {
            seq.serialize_element(&item)?;
        }
        seq.end()
    }
}

/// [`FitReport`]'s serialised form with its per-point arrays as sequences: the same names, order
/// and skips.
#[derive(Serialize)]
struct FitReportJson<'r, Outliers, Norms, Residuals, Rows, Uncertainty> {
    b1_from_b2: &'r PoseForms,
    condition: f64,
    method: Method,
    #[serde(skip_serializing_if = "Option::is_none")]
    mount_check: Option<&'r MountCheckReport>,
    mounts: &'r Option<String>,
    outliers: Option<Outliers>,
    points: usize,
    residual_norms_mm: Norms,
    residual_rms_mm: f64,
    residuals_mm: Residuals,
    rows: Rows,
    #[serde(skip_serializing_if = "Option::is_none")]
    soft_mount: Option<&'r SoftMountReport>,
    uncertainty: Option<Uncertainty>,
}

/// [`OutliersReport`]'s serialised form with its per-point arrays as sequences.
#[derive(Serialize)]
struct OutliersJson<'r, Column> {
    flagged_rows: &'r [usize],
    loo_residuals_mm: Column,
    thresholds_mm: Column,
}

/// [`UncertaintyReport`]'s serialised form with its per-point array as a sequence.
#[derive(Serialize)]
struct UncertaintyJson<'r, Column> {
    covariance: &'r [[f64; 6]; 6],
    covariance_order: &'static str,
    dof: usize,
    e_rot_1sigma_deg: f64,
    e_tran_1sigma_mm: f64,
    sigma_point_mm: f64,
    tre_rms_mm_at_points: Column,
}

impl Serialize for StreamedFitReport<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let r = &self.report;
        let pairs = self.pairs;
        let x = &self.b1_from_b2;
        // The predicted error at each point, from the fit's uncertainty (none without it).
        let u = self.uncertainty.as_ref();
        let tre_points = if u.is_some() { pairs.len() } else { 0 };
        FitReportJson {
            b1_from_b2: &r.b1_from_b2,
            condition: r.condition,
            method: r.method,
            mount_check: r.mount_check.as_ref(),
            mounts: &r.mounts,
            outliers: r.outliers.as_ref().map(|o| OutliersJson {
                flagged_rows: &o.flagged_rows,
                loo_residuals_mm: mm_seq(&self.loo_residuals_m),
                thresholds_mm: mm_seq(&self.thresholds_m),
            }),
            points: r.points,
            residual_norms_mm: Seq(self.residuals_m.iter().map(norm_mm)),
            residual_rms_mm: r.residual_rms_mm,
            residuals_mm: Seq(self.residuals_m.iter().map(xyz_mm)),
            rows: Seq((0..pairs.len()).map(|i| pairs.row(i))),
            soft_mount: r.soft_mount.as_ref(),
            uncertainty: r.uncertainty.as_ref().map(|ur| UncertaintyJson {
                covariance: &ur.covariance,
                covariance_order: ur.covariance_order,
                dof: ur.dof,
                e_rot_1sigma_deg: ur.e_rot_1sigma_deg,
                e_tran_1sigma_mm: ur.e_tran_1sigma_mm,
                sigma_point_mm: ur.sigma_point_mm,
                tre_rms_mm_at_points: Seq(pairs
                    .p_b2
                    .iter()
                    .take(tre_points)
                    .map(move |p| u.map_or(f64::NAN, |u| tre_mm(u, x, p)))),
            }),
        }
        .serialize(s)
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

    /// The streamed report's JSON is the owned report's, byte for byte (pretty and compact):
    /// every method, with and without leave-one-out (4 points: none; 12: refits; 260: the
    /// linearised and four-point formulas), mounts given or not, a mount check and a soft mount
    /// set, a flagged row added; and [`FitReport::new`] is the owned report.
    #[test]
    fn streamed_report_serialises_as_the_owned_report() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(25);
        let truth = Isometry3::new(Vector3::new(1.2, -0.1, 0.3), Vector3::new(0.0, 0.0, 0.5));
        let same = |streamed: &StreamedFitReport, what: &str| {
            let owned = streamed.clone().into_report();
            assert_eq!(
                serde_json::to_string_pretty(streamed).unwrap(),
                serde_json::to_string_pretty(&owned).unwrap(),
                "{what}"
            );
            assert_eq!(
                serde_json::to_string(streamed).unwrap(),
                serde_json::to_string(&owned).unwrap(),
                "{what}"
            );
            owned
        };
        let mut runs = 0;
        for n in [4, 12, crate::EXACT_LOO_MAX_POINTS + 60] {
            let p_b2: Vec<Point3<f64>> = (0..n)
                .map(|_| {
                    Point3::new(
                        rng.random_range(-0.8..0.8),
                        rng.random_range(-0.8..0.8),
                        rng.random_range(0.0..1.2),
                    )
                })
                .collect();
            let p_b1 = p_b2
                .iter()
                .map(|p| truth * p + Vector3::from_fn(|_, _| rng.random_range(-3e-4..3e-4)))
                .collect();
            let mut pairs = PointPairs::new(p_b1, p_b2).unwrap();
            pairs.rows = (0..n).map(|i| 2 * i + 3).collect();
            for given in [None, Some(MountPair::floor_floor())] {
                let mounts = given.unwrap_or_else(MountPair::floor_floor);
                for method in Method::ALL {
                    let what = format!("{n} points, {} {given:?}", method.name());
                    let Ok(f) = fit(&pairs, method, &mounts) else {
                        continue;
                    };
                    let outliers = leave_one_out(&pairs, method, &mounts).ok();
                    assert_eq!(outliers.is_some(), n > method.min_points(), "{what}");
                    let mut streamed =
                        StreamedFitReport::new(&pairs, f.clone(), given.as_ref(), outliers);
                    let owned = same(&streamed, &what);
                    assert_eq!(owned.rows.len(), n, "{what}");
                    assert_eq!(
                        serde_json::to_string(&owned).unwrap(),
                        serde_json::to_string(&FitReport::new(&pairs, &f, given.as_ref())).unwrap(),
                        "{what}"
                    );
                    // The fields a caller sets afterwards.
                    if let Some(o) = streamed.report.outliers.as_mut() {
                        o.flagged_rows.push(pairs.row(1));
                    }
                    if let Ok(c) = crate::mount_check(&pairs, &mounts) {
                        streamed.report.mount_check = Some(MountCheckReport::new(&c, n));
                    }
                    if let Ok(soft) = crate::constrained_soft(&pairs, &mounts, 0.01, 3e-4) {
                        streamed.report.soft_mount = Some(SoftMountReport::new(&soft, 0.01, 3e-4));
                    }
                    let owned = same(&streamed, &format!("{what}, fields set"));
                    if n > 4 {
                        assert!(owned.mount_check.is_some() && owned.soft_mount.is_some());
                    }
                    runs += 1;
                }
            }
        }
        // Every method fits these points at every size (the 4-point methods with 4 points too).
        assert_eq!(runs, 3 * 2 * Method::ALL.len());
    }
}

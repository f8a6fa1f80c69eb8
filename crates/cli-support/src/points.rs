//! A points fit's report, as `handclasp calibrate POINTS.csv` and the Python package's
//! `calibrate_points` give it: the fit ([`calib_core::fit`], or the soft-mount variant of
//! `constrained`), the plausibility check of its residuals against the expected alignment noise,
//! and the mounts' F-test for the methods that impose them.
//!
//! 1. [`points_report`] fits the method (`constrained_soft` when a soft mount is asked for);
//! 2. `plausible` refuses residuals far beyond the alignment noise, naming the likely data
//!    mistake ([`calib_core::explain_misfit`]) and the worst rows (or only warns when forced);
//! 3. the methods that impose the mounts get [`calib_core::mount_check`]'s F-test.

use calib_core::nalgebra::Isometry3;
use calib_core::{
    constrained_soft, explain_misfit, fit, leave_one_out, leave_one_out_of_fit, median_residual_m,
    misfit_threshold_m, mount_check, CalibError, Fit, FitReport, Method, MountCheckReport,
    MountPair, PointPairs, SoftMountReport, StreamedFitReport,
};

/// How a points fit runs ([`points_report`]).
#[derive(Debug, Clone)]
pub struct PointsOptions {
    /// The method.
    pub method: Method,
    /// The installation's mounts as given (`None`: none given; the fit then uses floor-floor
    /// where a method needs some, and the report says "none given").
    pub mounts: Option<MountPair>,
    /// Soft mount for `constrained`: (prior σ of the mount tilt, rad; point noise σ per
    /// coordinate, m). Ignored by the other methods.
    pub soft: Option<(f64, f64)>,
    /// Expected handclasp alignment noise σ per axis, m: a fit whose median residual norm exceeds
    /// [`calib_core::misfit_threshold_m`] at this σ fails.
    pub expected_noise_m: f64,
    /// Keep an implausible fit (the check's text is returned as a warning instead).
    pub force: bool,
}

/// The names a misfit message gives the two ways out, as the caller spells them
/// (`--expected-noise-mm` and `--force` on the command line).
#[derive(Debug, Clone, Copy)]
pub struct MisfitHints {
    /// The option that sets the expected alignment noise.
    pub noise: &'static str,
    /// The option that keeps the fit anyway.
    pub force: &'static str,
}

/// The command line's names ([`MisfitHints`]).
pub const CLI_HINTS: MisfitHints = MisfitHints {
    noise: "--expected-noise-mm",
    force: "--force",
};

/// Why a points fit failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PointsError {
    /// The method cannot fit these points (too few, collinear, …).
    #[error(transparent)]
    Fit(#[from] CalibError),
    /// The residuals are far beyond the alignment noise: the message names the likely data
    /// mistake and the worst rows; the values behind it are in [`PointsMisfit`].
    #[error("{}", .0.message)]
    Misfit(Box<PointsMisfit>),
}

/// The values behind a refused points fit ([`PointsError::Misfit`]; JSON `misfit` of a
/// refusal, mm): the median residual against its bound, the likely causes tried that explain
/// it, the worst rows.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PointsMisfit {
    /// The expected alignment noise σ per axis, mm (`--expected-noise-mm`).
    pub expected_noise_mm: f64,
    /// Each cause whose correction brings the median below the bound, with the median it gives,
    /// mm, best first ([`calib_core::explain_misfit`]); empty when none does.
    pub likely_causes: Vec<MisfitCauseReport>,
    /// The bound of the median ([`calib_core::misfit_threshold_m`]), mm.
    pub limit_mm: f64,
    /// The median residual norm, mm.
    pub median_residual_mm: f64,
    /// The full message (what the command prints after `error:`).
    pub message: String,
    /// The method.
    pub method: Method,
    /// Number of points.
    pub points: usize,
    /// The residual RMS, mm.
    pub residual_rms_mm: f64,
    /// The worst rows (source row, residual norm in mm), largest first.
    pub worst_rows: Vec<(usize, f64)>,
}

/// A likely cause of a points misfit and the median residual with it corrected, mm.
#[derive(Debug, Clone, serde::Serialize)]
pub struct MisfitCauseReport {
    /// The cause ([`calib_core::MisfitCause`], tagged by `kind`).
    pub cause: calib_core::MisfitCause,
    /// In words.
    pub description: String,
    /// The median residual norm with it corrected, mm.
    pub median_residual_mm: f64,
}

/// A points fit's report and the warnings to show beside it (a misfit kept by `force`).
#[derive(Debug, Clone)]
pub struct PointsFit {
    /// The report (the CLI's JSON).
    pub report: FitReport,
    /// The fitted `b1_from_b2` (`p_b1 = b1_from_b2·p_b2`), SI units, unrounded (the report's
    /// pose forms are rounded for printing). The residuals are the report's.
    pub b1_from_b2: Isometry3<f64>,
    /// Warnings for stderr, each starting `WARNING (method, kept by …)`.
    pub warnings: Vec<String>,
}

/// [`PointsFit`] whose per-point arrays are written from the fit when the report is serialised
/// ([`StreamedFitReport`]: the same JSON, 40 bytes a point less memory); it borrows the points.
#[derive(Debug, Clone)]
pub struct StreamedPointsFit<'a> {
    /// The report (the CLI's JSON); [`StreamedFitReport::b1_from_b2`] is the fit, unrounded.
    pub report: StreamedFitReport<'a>,
    /// Warnings for stderr, each starting `WARNING (method, kept by …)`.
    pub warnings: Vec<String>,
}

/// Fits one method (the soft-mount variant for `constrained` when asked) and builds its report.
/// The methods that impose the mounts also get the mounts' F-test against the points.
///
/// Errors: [`PointsError::Fit`] when the method does not apply; [`PointsError::Misfit`] when the
/// median residual norm exceeds `options.expected_noise_m` and `options.force` is off.
pub fn points_report(
    pairs: &PointPairs,
    options: &PointsOptions,
    hints: MisfitHints,
) -> Result<PointsFit, PointsError> {
    let fitted = points_report_streamed(pairs, options, hints)?;
    Ok(PointsFit {
        b1_from_b2: *fitted.report.b1_from_b2(),
        report: fitted.report.into_report(),
        warnings: fitted.warnings,
    })
}

/// [`points_report`] whose report writes its per-point arrays from the fit when serialised
/// (`handclasp calibrate POINTS.csv --json` prints it: at 1e6 points the report's 64 MB of
/// per-point arrays are never held). Errors: those of [`points_report`].
pub fn points_report_streamed<'a>(
    pairs: &'a PointPairs,
    options: &PointsOptions,
    hints: MisfitHints,
) -> Result<StreamedPointsFit<'a>, PointsError> {
    let method = options.method;
    let mounts = options.mounts.unwrap_or_else(MountPair::floor_floor);
    let mut warnings = Vec::new();
    // Before the fit and its report: the robust fit's working vectors (~28 MB at 1e6 rows) are
    // freed before the fit's and the leave-one-out's vectors exist, which lowers the command's
    // peak memory.
    let masked = calib_core::masked_blunders(pairs);
    let (f, soft_mount, outliers) =
        if let (Method::Constrained, Some((tilt_sigma, point_sigma))) = (method, options.soft) {
            let soft = constrained_soft(pairs, &mounts, tilt_sigma, point_sigma)?;
            warnings.extend(plausible(pairs, &soft.fit, &mounts, options, hints)?);
            let soft_mount = SoftMountReport::new(&soft, tilt_sigma, point_sigma);
            // Leave-one-out of the method's plain fit (not the soft one), as `FitReport::new`.
            let outliers = leave_one_out(pairs, soft.fit.method, &mounts).ok();
            (soft.fit, Some(soft_mount), outliers)
        } else {
            let f = fit(pairs, method, &mounts)?;
            warnings.extend(plausible(pairs, &f, &mounts, options, hints)?);
            // `f` is the fit leave-one-out would start from: it is not fitted again.
            let outliers = leave_one_out_of_fit(pairs, &f, &mounts).ok();
            (f, None, outliers)
        };
    warnings.extend(layout_warning(pairs, &f));
    let fit_method = f.method;
    let mut report = StreamedFitReport::new(pairs, f, options.mounts.as_ref(), outliers);
    report.report.soft_mount = soft_mount;
    let b1_from_b2 = *report.b1_from_b2();
    warnings.extend(masked.and_then(|m| {
        masked_warning(
            pairs,
            fit_method,
            &b1_from_b2,
            &mounts,
            m,
            &mut report.report,
        )
    }));
    if matches!(method, Method::Paper | Method::Constrained) && options.mounts.is_some() {
        // Fewer than 3 usable points already failed the fit above; anything else is reported.
        if let Ok(c) = mount_check(pairs, &mounts) {
            report.report.mount_check = Some(MountCheckReport::new(&c, pairs.len()));
        }
    }
    Ok(StreamedPointsFit { report, warnings })
}

/// The methods `calibrate --method all` fits, in this order: every method when the mounts are
/// given, else those that need none (generic, generic-affine, lsq).
pub fn all_methods(mounts_given: bool) -> Vec<Method> {
    if mounts_given {
        vec![
            Method::Generic,
            Method::GenericAffine,
            Method::Paper,
            Method::Lsq,
            Method::Constrained,
        ]
    } else {
        vec![Method::Generic, Method::GenericAffine, Method::Lsq]
    }
}

/// `calibrate --method all`'s report: each method's report, or why it does not apply, by method
/// name (a map: the JSON lists the methods in alphabetical order).
#[derive(Debug, Default, serde::Serialize)]
pub struct AllMethods {
    /// Each method's outcome, by [`Method::name`].
    pub methods: std::collections::BTreeMap<&'static str, MethodOutcome>,
}

impl AllMethods {
    /// Records `method`'s outcome: its report, or the text of why it does not apply
    /// ([`crate::error_chain_text`]: a misfit's message, or the fit's error).
    pub fn insert(&mut self, method: Method, outcome: Result<FitReport, PointsError>) {
        let outcome = match outcome {
            Ok(r) => MethodOutcome::Fit(Box::new(r)),
            Err(e) => MethodOutcome::NotApplicable {
                error: crate::error_chain_text(&e),
                method,
            },
        };
        self.methods.insert(method.name(), outcome);
    }
}

/// One method's outcome under `--method all`.
#[derive(Debug, serde::Serialize)]
#[serde(untagged)]
pub enum MethodOutcome {
    /// The fit's report.
    Fit(Box<FitReport>),
    /// The method does not apply to these points (JSON `{"error": …, "method": …}`).
    NotApplicable {
        /// Why, as the error's text.
        error: String,
        /// The method.
        method: Method,
    },
}

/// A `warning:` when the points are nearly collinear (second over first principal spread of
/// robot 1's points below the result check's
/// [`calib_core::whole_cell::CheckThresholds::collinear_ratio`], 5 %: the rotation about their
/// line is then poorly determined; the registration refuses exact lines, below
/// [`calib_core::COLLINEAR_REL`]), or, for the 4-point methods, nearly coplanar (third over
/// first below [`calib_core::whole_cell::CheckThresholds::coplanar_ratio`]).
fn layout_warning(pairs: &PointPairs, f: &Fit) -> Option<String> {
    let th = calib_core::whole_cell::CheckThresholds::default();
    let sv = calib_core::spread_singular_values(&pairs.p_b1);
    let ratio = |a: f64| if sv[0] > 0.0 { a / sv[0] } else { 0.0 };
    let spread = format!(
        "principal spread {:.1}, {:.1}, {:.1} mm",
        sv[0] * 1e3,
        sv[1] * 1e3,
        sv[2] * 1e3
    );
    let rotation = f
        .uncertainty
        .as_ref()
        .map(|u| {
            format!(
                "; the fit's predicted rotation error is {:.3}° (1σ)",
                u.e_rot_1sigma_rad.to_degrees()
            )
        })
        .unwrap_or_default();
    if ratio(sv[1]) < th.collinear_ratio {
        return Some(format!(
            "warning: the {} points are nearly collinear ({spread}; second over first {:.4}, \
             below {}): the rotation about their line is poorly determined{rotation}; add points \
             off that line",
            pairs.len(),
            ratio(sv[1]),
            th.collinear_ratio
        ));
    }
    if f.method.min_points() == 4 && ratio(sv[2]) < th.coplanar_ratio {
        return Some(format!(
            "warning: the {} points are nearly coplanar ({spread}; third over first {:.4}, below \
             {}): method {} fits an affine map, which a plane leaves poorly determined; add \
             points off that plane, or use lsq",
            pairs.len(),
            ratio(sv[2]),
            th.coplanar_ratio,
            f.method.name()
        ));
    }
    None
}

/// Blunders that mask one another in the leave-one-out test (`m`, from
/// [`calib_core::masked_blunders`]): the rows that disagree with the rigid fit of the majority but
/// that leave-one-out did not flag are added to `report`'s flagged rows, and a `warning:` names
/// them with how far the fit moves without them (the fit printed still uses every row).
fn masked_warning(
    pairs: &PointPairs,
    method: Method,
    b1_from_b2: &Isometry3<f64>,
    mounts: &MountPair,
    m: calib_core::MaskedBlunders,
    report: &mut FitReport,
) -> Option<String> {
    let outliers = report.outliers.as_mut()?;
    // Sorted lookups: with many flagged rows at 1e6 rows, `contains` would be quadratic.
    let mut already = outliers.flagged_rows.clone();
    already.sort_unstable();
    let masked: Vec<usize> = m
        .flagged
        .iter()
        .map(|&i| pairs.row(i))
        .filter(|r| already.binary_search(r).is_err())
        .collect();
    if masked.is_empty() {
        return None;
    }
    outliers.flagged_rows.extend(&masked);
    outliers.flagged_rows.sort_unstable();
    let bad: Vec<f64> = m.flagged.iter().map(|&i| m.residuals_m[i] * 1e3).collect();
    let (lo, hi) = bad
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    let keep: Vec<usize> = (0..pairs.len())
        .filter(|i| m.flagged.binary_search(i).is_err()) // ascending
        .collect();
    let clean = PointPairs {
        p_b1: keep.iter().map(|&i| pairs.p_b1[i]).collect(),
        p_b2: keep.iter().map(|&i| pairs.p_b2[i]).collect(),
        rows: keep.iter().map(|&i| pairs.row(i)).collect(),
    };
    let moved = match fit(&clean, method, mounts) {
        Ok(c) => {
            let d = c.b1_from_b2 * b1_from_b2.inverse();
            format!(
                "without them the {} fit moves by {} mm / {:.3}°",
                method.name(),
                mm_text(d.translation.vector.norm() * 1e3),
                d.rotation.angle().to_degrees()
            )
        }
        Err(e) => format!("without them the {} fit fails ({e})", method.name()),
    };
    let rows: Vec<usize> = m.flagged.iter().map(|&i| pairs.row(i)).collect();
    Some(format!(
        "warning: {} of {} rows ({:.0} %) disagree with the rigid fit of the other {} by {}–{} \
         mm (limit {} mm, {} × their residual scale) and mask one another in the leave-one-out \
         test: bad handclasps at rows {rows:?}; {moved}; the fit printed uses every row: \
         re-record them, or remove them and re-run",
        rows.len(),
        pairs.len(),
        100.0 * rows.len() as f64 / pairs.len() as f64,
        pairs.len() - rows.len(),
        mm_text(lo),
        mm_text(hi),
        mm_text(m.limit_m * 1e3),
        calib_core::OUTLIER_FACTOR,
    ))
}

/// Rows listed as the worst in a misfit error.
const WORST_ROWS: usize = 5;

/// Fails when the fit's median residual norm exceeds the expected alignment noise: such residuals
/// come from a data mistake, not from noise. The error names each mistake whose correction, refitted,
/// brings the median back below the noise ([`calib_core::explain_misfit`]; ties cannot be told apart
/// and are listed together), and the worst rows. With `force` it returns the text as a warning. For
/// the methods that impose mounts it fails only when the free rigid fit is implausible too (otherwise
/// the mounts are wrong, and the mount check says so).
fn plausible(
    pairs: &PointPairs,
    f: &Fit,
    mounts: &MountPair,
    options: &PointsOptions,
    hints: MisfitHints,
) -> Result<Option<String>, PointsError> {
    let median = median_residual_m(f);
    // The bound from the data and the method at the stated noise (σ per axis).
    let limit = misfit_threshold_m(pairs.len(), f.method, options.expected_noise_m);
    if median <= limit {
        return Ok(None);
    }
    // With imposed mounts: if the free rigid fit agrees with the noise, the points are fine and
    // the mounts are wrong: the gate still runs and says so on stderr (the mount check's
    // WARNING in the report gives the advice), the fit with the mounts asked for is kept.
    if matches!(f.method, Method::Paper | Method::Constrained) {
        if let Ok(free) = fit(pairs, Method::Lsq, mounts) {
            let free_median = median_residual_m(&free);
            if free_median <= misfit_threshold_m(pairs.len(), Method::Lsq, options.expected_noise_m)
            {
                return Ok(Some(format!(
                    "warning: {}: median |r| {} mm is beyond the noise bound {} mm ({noise} {} mm, {} points), \
                     but a free rigid fit reaches {} mm: the points are consistent and the mounts are not; check the mounts \
                     (the mount check below says how far off they are)",
                    f.method.name(),
                    mm_text(median * 1e3),
                    mm_text(limit * 1e3),
                    mm_text(options.expected_noise_m * 1e3),
                    pairs.len(),
                    mm_text(free_median * 1e3),
                    noise = hints.noise,
                )));
            }
        }
    }
    let mut worst: Vec<(usize, f64)> = f
        .residuals
        .iter()
        .enumerate()
        .map(|(i, r)| (pairs.row(i), r.norm()))
        .collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    let worst_txt = worst
        .iter()
        .take(WORST_ROWS)
        .map(|(row, r)| format!("row {row} ({} mm)", mm_text(r * 1e3)))
        .collect::<Vec<_>>()
        .join(", ");
    let found = explain_misfit(pairs, f.method, mounts, limit);
    let cause = match found.first() {
        Some(&(_, best)) => {
            // Equal medians (to 1 %) are the same correction seen differently (e.g. any reflection
            // of one robot's axes under a free rotation): list them together.
            let tied: Vec<String> = found
                .iter()
                .filter(|c| c.1 <= best * 1.01 + 1e-12)
                .map(|c| c.0.to_string())
                .collect();
            format!(
                "likely cause (refitting with it corrected gives median {:.3} mm): {}",
                best * 1e3,
                tied.join("; or ")
            )
        }
        None => "none of the checked causes explains it (rows shifted by ±1–3, one robot's axes swapped or negated, one robot ×1000 or ×0.001, robots swapped); check the recording and the mounts".into(),
    };
    let msg = format!(
        "the residuals are far beyond the alignment noise: median |r| {} mm > {} mm (the {:.1} % bound of the median of {} points at {noise} {} mm per axis), residual RMS {} mm; {cause}; worst rows: {worst_txt}. Fix the file, or raise {noise}, or give {force} to keep this fit",
        mm_text(median * 1e3),
        mm_text(limit * 1e3),
        100.0 * (1.0 - calib_core::MISFIT_FALSE_ALARM),
        pairs.len(),
        mm_text(options.expected_noise_m * 1e3),
        mm_text(f.residual_rms_m() * 1e3),
        noise = hints.noise,
        force = hints.force,
    );
    if options.force {
        return Ok(Some(format!(
            "WARNING ({}, kept by {}): {msg}",
            f.method.name(),
            hints.force
        )));
    }
    Err(PointsError::Misfit(Box::new(PointsMisfit {
        expected_noise_mm: options.expected_noise_m * 1e3,
        likely_causes: found
            .iter()
            .map(|&(cause, med)| MisfitCauseReport {
                cause,
                description: cause.to_string(),
                median_residual_mm: med * 1e3,
            })
            .collect(),
        limit_mm: limit * 1e3,
        median_residual_mm: median * 1e3,
        message: msg,
        method: f.method,
        points: pairs.len(),
        residual_rms_mm: f.residual_rms_m() * 1e3,
        worst_rows: worst
            .iter()
            .take(WORST_ROWS)
            .map(|&(row, r)| (row, r * 1e3))
            .collect(),
    })))
}

/// A length in mm for a message: 3 decimals, scientific notation from 1e6 mm.
pub fn mm_text(v_mm: f64) -> String {
    if v_mm.abs() < 1e6 {
        format!("{v_mm:.3}")
    } else {
        format!("{v_mm:.3e}")
    }
}

//! The result check of a whole-cell fit (`calibrate --cell`, both models, the Python package's
//! `calibrate_cell`; `diagnose` runs its [`ScreenMode`] rule), run after the fit by
//! [`crate::cell_report::calibrate_session_with`]. Its thresholds and why are in
//! `docs/guide/warnings.md`.
//!
//! 1. [`screen_outcome`]: with `--screen auto`, the rows the blunder screen rejected are
//!    classified (`calib_core::whole_cell::classify_rejections`); a model misfit keeps every row
//!    (the caller refits without rejection) and says so.
//! 2. [`check_result`]: the robust noise scale against the stated σ, the fitted `b1_from_b2`
//!    against the cell's (its stated σ, or a default, named), the layout's shape;
//! 3. when the noise scale is high or the placement far, the likely mistakes
//!    (`calib_core::whole_cell::candidate_mistakes`) and the other cells in the cell's folder
//!    ([`sibling_cells`]) are tried placement-only, each reported with its noise scale and
//!    placement distance; one that explains the contradiction is the likely mistake;
//! 4. the status: `refused` (a likely mistake, or a noise scale above the refusal limit),
//!    `warning`, or `ok`, with one message per finding (the CLI prints them after `warning:`,
//!    or refuses with them unless `--force`).

use std::path::Path;

use calib_core::whole_cell::{
    candidate_mistakes, classify_rejections, coincident_pairs, fitted_rows_noise_scale,
    layout_shape, placement_distance, robust_noise_scale, robust_noise_scale_with_tolerances,
    try_problem, CellCalibration, CellFitError, CellProblem, CheckThresholds, LayoutShape,
    PlacementDistance, RejectionPattern, Trial, MISFIT_SHARE_ALONE, REST_FITS_SCALE,
};
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::{Cell, Session};
use serde::Serialize;

/// How the blunder screen treats rows that disagree with the fit (`--screen`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum ScreenMode {
    /// Reject blunders, unless the rejections are a model misfit (more than a few percent of
    /// the rows, or clustered in joint space or time): then keep every row and say so.
    #[default]
    Auto,
    /// No screen: every row is fitted.
    Off,
    /// Reject every row above the screen's limit, misfit or not (the behaviour before the
    /// result check).
    Strict,
}

impl ScreenMode {
    /// `auto`, `off` or `strict`.
    pub fn name(self) -> &'static str {
        match self {
            ScreenMode::Auto => "auto",
            ScreenMode::Off => "off",
            ScreenMode::Strict => "strict",
        }
    }

    /// From [`ScreenMode::name`]; `None` for any other text.
    pub fn from_name(name: &str) -> Option<ScreenMode> {
        [ScreenMode::Auto, ScreenMode::Off, ScreenMode::Strict]
            .into_iter()
            .find(|m| m.name() == name)
    }
}

/// What the screen did (JSON `result_check.screen`).
#[derive(Debug, Clone, Serialize)]
pub struct ScreenReport {
    /// The mode.
    pub mode: ScreenMode,
    /// The rejections classified (`None` when the screen rejected nothing or is off).
    pub pattern: Option<RejectionPattern>,
    /// True when every row was kept because the rejections were a model misfit.
    pub rows_kept: bool,
}

/// The screen's outcome after a fit in `mode`: with `auto` and rows rejected, their
/// classification, judged with the robust noise scale of the rows kept (for a placement-only
/// fit, against the stated noise plus the robots' tolerances of `toleranced`, the session's
/// problem with them: `FitModel::Kinematic`'s). The caller refits without rejection when
/// `rows_kept`.
///
/// # Errors
/// The residuals cannot be evaluated.
pub fn screen_outcome(
    problem: &CellProblem,
    cal: &CellCalibration,
    mode: ScreenMode,
    toleranced: Option<&CellProblem>,
) -> Result<ScreenReport, CellFitError> {
    if mode == ScreenMode::Off || cal.rejected.is_empty() {
        return Ok(ScreenReport {
            mode,
            pattern: None,
            rows_kept: false,
        });
    }
    let rejected: Vec<usize> = problem
        .observations
        .iter()
        .enumerate()
        .filter(|(_, o)| cal.rejected.iter().any(|r| r.row == o.row))
        .map(|(i, _)| i)
        .collect();
    let pattern = classify_with_noise(problem, cal, &rejected, toleranced)?;
    let rows_kept = mode == ScreenMode::Auto && pattern.misfit;
    Ok(ScreenReport {
        mode,
        pattern: Some(pattern),
        rows_kept,
    })
}

/// The screen's outcome when rejecting the source rows `rejected_rows` would leave too few
/// rows to fit (`CellFitError::TooFewRows`): a model misfit by definition, every row kept
/// (`cal` is the fit on all of them).
///
/// # Errors
/// The residuals cannot be evaluated.
pub fn misfit_outcome(
    problem: &CellProblem,
    cal: &CellCalibration,
    rejected_rows: &[usize],
    mode: ScreenMode,
    toleranced: Option<&CellProblem>,
) -> Result<ScreenReport, CellFitError> {
    let rejected: Vec<usize> = problem
        .observations
        .iter()
        .enumerate()
        .filter(|(_, o)| rejected_rows.contains(&o.row))
        .map(|(i, _)| i)
        .collect();
    let mut pattern = classify_with_noise(problem, cal, &rejected, toleranced)?;
    pattern.misfit = true;
    Ok(ScreenReport {
        mode,
        pattern: Some(pattern),
        rows_kept: true,
    })
}

/// [`classify_rejections`] with the robust noise scale of the rows `cal` kept (against the
/// stated noise plus the robots' tolerances of `toleranced` for a placement-only fit) and the
/// check's [`CheckThresholds::noise_high`].
fn classify_with_noise(
    problem: &CellProblem,
    cal: &CellCalibration,
    rejected: &[usize],
    toleranced: Option<&CellProblem>,
) -> Result<RejectionPattern, CellFitError> {
    let placement_only = cal.fit.layout.prior_sqrt_info.nrows() == 0;
    let rest = fitted_rows_noise_scale(problem, &cal.fit, toleranced.filter(|_| placement_only))?;
    classify_rejections(
        problem,
        &cal.fit,
        rejected,
        Some(rest),
        CheckThresholds::default().noise_high,
    )
}

/// One check: its value against its limits (JSON `result_check.checks[]`).
#[derive(Debug, Clone, Serialize)]
pub struct CheckItem {
    /// What the value means and where the limits come from.
    pub detail: String,
    /// `noise_scale`, `placement_translation_mm`, `placement_rotation_deg`, `layout_line_ratio`
    /// or `layout_plane_ratio`.
    pub name: &'static str,
    /// `ok`, `high`, `low`, `far` or `degenerate`.
    pub status: &'static str,
    /// The limits: `[low, high, refusal]` for the noise scale, `[allowed]` for the placement,
    /// `[limit]` for the layout ratios.
    pub thresholds: Vec<f64>,
    /// The value.
    pub value: f64,
}

/// A mistake tried (JSON `result_check.mistakes_tried[]`, `likely_mistake`).
#[derive(Debug, Clone, Serialize)]
pub struct MistakeTrialReport {
    /// True when it explains the contradiction.
    pub explains: bool,
    /// The mistake, in words.
    pub mistake: String,
    /// The robust noise scale with the mistake undone (placement-only fit).
    pub noise_scale: f64,
    /// Its placement's rotation from the cell's stated one (or, for another cell, from that
    /// cell's), degrees.
    pub placement_deg: f64,
    /// Its placement's distance from the stated one, mm.
    pub placement_mm: f64,
}

/// The result check (JSON `result_check`).
#[derive(Debug, Clone, Serialize)]
pub struct ResultCheckReport {
    /// Each check with its value and limits.
    pub checks: Vec<CheckItem>,
    /// The mistake that explains the contradiction, if one does.
    pub likely_mistake: Option<MistakeTrialReport>,
    /// One line per finding (the CLI prints each after `warning:`, or refuses with them).
    pub messages: Vec<String>,
    /// The placement-only fit as given (the baseline the mistakes are compared with), then
    /// every mistake tried (empty when every check passed).
    pub mistakes_tried: Vec<MistakeTrialReport>,
    /// What the blunder screen did.
    pub screen: ScreenReport,
    /// `ok`, `warning` or `refused`.
    pub status: &'static str,
}

impl ResultCheckReport {
    /// True when the result contradicts what was stated and a caller should refuse it
    /// (unless forced).
    pub fn refused(&self) -> bool {
        self.status == STATUS_REFUSED
    }

    /// Adds the findings of `stated`, the check of the fit at the stated tolerances, that this
    /// check (of the fit at widened tolerances) does not repeat, each said as such: a widened
    /// prior can absorb what the stated fit showed (σ understated, a model misfit), and the user
    /// must still hear it. The status becomes `warning` when a finding was added (`refused`
    /// stays).
    pub fn add_stated_findings(&mut self, stated: &ResultCheckReport) {
        for m in &stated.messages {
            if !self.messages.contains(m) {
                self.messages.push(format!(
                    "at the stated tolerances, before the evidence widened them: {m}"
                ));
            }
        }
        if !self.messages.is_empty() && self.status == "ok" {
            self.status = "warning";
        }
    }

    /// The text of a refusal (what `calibrate --cell` prints after `error:`): its messages,
    /// joined.
    pub fn refusal_reason(&self) -> String {
        format!(
            "the result contradicts what the cell states: {}",
            self.messages.join("; ")
        )
    }
}

const STATUS_REFUSED: &str = "refused";

/// The placement allowance: `(mm, deg, where it comes from)`.
fn allowance(cell: &Cell, th: &CheckThresholds) -> (f64, f64, String) {
    match cell.b1_from_b2_sigma {
        Some(s) if s.sigma_m > 0.0 && s.sigma_rad > 0.0 => (
            th.placement_k_sigma * s.sigma_m * 1e3,
            th.placement_k_sigma * s.sigma_rad.to_degrees(),
            format!(
                "{} × the cell's [b1_from_b2] sigma_mm/sigma_deg",
                th.placement_k_sigma
            ),
        ),
        _ => (
            th.default_placement_mm,
            th.default_placement_deg,
            "the default: the cell states no [b1_from_b2] sigma_mm/sigma_deg".into(),
        ),
    }
}

fn within(d: &PlacementDistance, mm: f64, deg: f64) -> bool {
    d.translation_mm <= mm && d.rotation_deg <= deg
}

/// The other cell files in `cell`'s folder (its `base_dir`) that read as cells with the same
/// joint counts, without the cell itself (same URDFs and placement): `(file name, cell)`, in
/// file-name order. Unreadable files are skipped.
pub fn sibling_cells(cell: &Cell) -> Vec<(String, Cell)> {
    let Ok(entries) = std::fs::read_dir(&cell.base_dir) else {
        return Vec::new();
    };
    let mut paths: Vec<std::path::PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    paths
        .into_iter()
        .filter_map(|p| {
            let other = Cell::from_toml_file(&p).ok()?;
            let same_robots = other.robot1.model.dof() == cell.robot1.model.dof()
                && other.robot2.model.dof() == cell.robot2.model.dof();
            let d = placement_distance(&other.b1_from_b2, &cell.b1_from_b2);
            let itself = d.translation_mm < 1e-3
                && d.rotation_deg < 1e-6
                && other.robot1.urdf_path == cell.robot1.urdf_path
                && other.robot2.urdf_path == cell.robot2.urdf_path;
            (same_robots && !itself).then(|| (file_name(&p), other))
        })
        .collect()
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The layout's line and plane ratios `(name, value, limit, warning when below the limit)`:
/// the degeneracy check `calibrate --cell` runs on its fit and `plan` on its design.
fn layout_ratios(
    shape: &LayoutShape,
    th: &CheckThresholds,
) -> [(&'static str, f64, f64, Option<String>); 2] {
    let item = |name: &'static str, value: f64, limit: f64, what: &str, off: &str| {
        let message = (value < limit).then(|| {
            format!(
                "robot 1's tool points of the {} two-robot rows are {what} (principal spread \
                 {:.1}, {:.1}, {:.1} mm; {name} {value:.4} below {limit}): add rows off that {off}",
                shape.points, shape.spread_mm[0], shape.spread_mm[1], shape.spread_mm[2],
            )
        });
        (name, value, limit, message)
    };
    [
        item(
            "layout_line_ratio",
            shape.line_ratio(),
            th.collinear_ratio,
            "nearly collinear: the rotation about their line is poorly determined",
            "line",
        ),
        item(
            "layout_plane_ratio",
            shape.plane_ratio(),
            th.coplanar_ratio,
            "nearly coplanar: a kinematic fit cannot separate the errors that move the tips out \
             of that plane",
            "plane",
        ),
    ]
}

/// The degenerate-layout warnings of `problem`'s two-robot rows (nearly collinear or coplanar
/// tool points), worded as `calibrate --cell`'s result check words them; empty when the layout
/// is sound or has too few points to judge.
pub fn layout_warnings(problem: &CellProblem) -> Vec<String> {
    let th = CheckThresholds::default();
    layout_shape(problem)
        .map(|shape| {
            layout_ratios(&shape, &th)
                .into_iter()
                .filter_map(|(_, _, _, m)| m)
                .collect()
        })
        .unwrap_or_default()
}

/// The result check of `cal`, the fit of `problem` (built from `cell` and `session`), after
/// the screen `screen` (module documentation, steps 2–4).
///
/// # Errors
/// The fit's residuals cannot be evaluated.
pub fn check_result(
    cell: &Cell,
    session: &Session,
    problem: &CellProblem,
    cal: &CellCalibration,
    screen: ScreenReport,
) -> Result<ResultCheckReport, CellFitError> {
    let th = CheckThresholds::default();
    let noise = robust_noise_scale(problem, &cal.fit)?;
    // A placement fit's residuals carry the nominal robots' own error: the refusal judges them
    // against the stated noise plus the variance the robots' tolerances allow.
    let noise_tol = if cal.fit.layout.prior_sqrt_info.nrows() == 0 {
        let toleranced = cell_problem(cell, session, FitModel::Kinematic);
        Some(robust_noise_scale_with_tolerances(
            problem,
            &cal.fit,
            &toleranced,
        )?)
    } else {
        None
    };
    let judged = noise_tol.unwrap_or(noise);
    let dist = placement_distance(&cal.fit.estimate.b1_from_b2, &cell.b1_from_b2);
    let (allow_mm, allow_deg, allow_source) = allowance(cell, &th);
    let mut checks = Vec::new();
    let noise_status = if noise > th.noise_high {
        "high"
    } else if noise < th.noise_low {
        "low"
    } else {
        "ok"
    };
    checks.push(CheckItem {
        detail: "robust noise scale of the residuals (median of each row's χ² over its median \
                 under the stated noise, every row): far above 1, the model misfits or σ is \
                 understated; far below, σ is overstated"
            .into(),
        name: "noise_scale",
        status: noise_status,
        thresholds: vec![th.noise_low, th.noise_high, th.noise_refuse],
        value: noise,
    });
    if let Some(value) = noise_tol {
        checks.push(CheckItem {
            detail: "robust noise scale of a placement fit's residuals against the stated noise \
                     plus the variance the robots' tolerances put in each row (the nominal \
                     robots' own error): what a refusal judges"
                .into(),
            name: "noise_scale_with_tolerances",
            status: if value > th.noise_refuse {
                "high"
            } else {
                "ok"
            },
            thresholds: vec![th.noise_refuse],
            value,
        });
    }
    let placement_far = !within(&dist, allow_mm, allow_deg);
    for (name, value, allowed) in [
        ("placement_translation_mm", dist.translation_mm, allow_mm),
        ("placement_rotation_deg", dist.rotation_deg, allow_deg),
    ] {
        checks.push(CheckItem {
            detail: format!(
                "the fitted b1_from_b2 against the cell's stated one; allowed: {allow_source}"
            ),
            name,
            status: if value > allowed { "far" } else { "ok" },
            thresholds: vec![allowed],
            value,
        });
    }
    let shape = layout_shape(problem);
    let mut degenerate = Vec::new();
    if let Some(shape) = &shape {
        for (name, value, limit, message) in layout_ratios(shape, &th) {
            let bad = message.is_some();
            degenerate.extend(message);
            checks.push(CheckItem {
                detail: "second (line) or third (plane) over the first principal spread of \
                         robot 1's tool points of the two-robot rows"
                    .into(),
                name,
                status: if bad { "degenerate" } else { "ok" },
                thresholds: vec![limit],
                value,
            });
        }
    }
    let masked = masked_blunders_check(problem, cal);
    if let Some((item, _)) = &masked {
        checks.push(item.clone());
    }
    let noise_high = noise > th.noise_high;
    let mut tried = Vec::new();
    let mut likely: Option<MistakeTrialReport> = None;
    if noise_high || placement_far {
        if let Ok(base) = try_problem(problem, &cell.b1_from_b2) {
            let bd = base.distance(&cell.b1_from_b2);
            tried.push(trial_report("none (the data as given)", &base, &bd, false));
            let explains = |t: &Trial, d: &PlacementDistance, mm: f64, deg: f64| {
                let ok_here = within(d, mm, deg);
                if noise_high {
                    t.noise_scale * th.mistake_gain <= base.noise_scale
                        && (ok_here || !placement_far)
                } else {
                    ok_here && t.noise_scale <= (1.5 * base.noise_scale).max(th.noise_high)
                }
            };
            for m in candidate_mistakes(problem) {
                let Some(p) = m.apply(problem) else { continue };
                let Ok(t) = try_problem(&p, &cell.b1_from_b2) else {
                    continue;
                };
                let d = t.distance(&cell.b1_from_b2);
                let e = explains(&t, &d, allow_mm, allow_deg);
                tried.push(trial_report(&m.describe(), &t, &d, e));
            }
            for (name, other) in sibling_cells(cell) {
                let p = cell_problem(&other, session, FitModel::Placement);
                let Ok(t) = try_problem(&p, &other.b1_from_b2) else {
                    continue;
                };
                let d = t.distance(&other.b1_from_b2);
                let (mm, deg, _) = allowance(&other, &th);
                let e = explains(&t, &d, mm, deg);
                let what = format!("the session recorded in another cell, {name} (its robots, mounts and placement)");
                tried.push(trial_report(&what, &t, &d, e));
            }
            likely = tried
                .iter()
                .filter(|t| t.explains)
                .min_by(|a, b| {
                    a.noise_scale
                        .total_cmp(&b.noise_scale)
                        .then(a.placement_mm.total_cmp(&b.placement_mm))
                })
                .cloned();
        }
    }
    let mut messages = Vec::new();
    let mut refused = false;
    let now = format!(
        "now {noise:.2} and {:.1} mm / {:.2}°",
        dist.translation_mm, dist.rotation_deg
    );
    let tried_count = tried.len().saturating_sub(1);
    if let Some(m) = &likely {
        refused = true;
        messages.push(format!(
            "likely mistake: {}: undone, the noise scale would be {:.2} and the placement {:.1} mm \
             / {:.2}° from the stated one ({now}); correct it and re-run (--force keeps this fit)",
            m.mistake, m.noise_scale, m.placement_mm, m.placement_deg
        ));
    } else if judged > th.noise_refuse {
        refused = true;
        messages.push(format!(
            "model misfit: the residuals are {noise:.1}× the stated noise{} (refused above {}), \
             and none of {tried_count} likely mistakes tried (rows shifted, robots or joints \
             swapped, a joint's sign, radians, tips, the other cells beside this one) explains \
             it: check the robots' URDFs and tips; `handclasp diagnose` names what the model \
             misses (--force keeps this fit)",
            with_tolerances(noise_tol),
            th.noise_refuse
        ));
    } else {
        if noise_high && noise_tol.is_some_and(|t| t <= th.noise_high) {
            messages.push(format!(
                "the residuals are {noise:.1}× the stated noise (warning above {}){}: within what \
                 the robots' tolerances allow, so this is the nominal robots' own error, larger \
                 than the session's noise; the placement model leaves it in every row \
                 (`--model kinematic` fits it); none of {tried_count} likely mistakes explains it",
                th.noise_high,
                with_tolerances(noise_tol),
            ));
        } else if noise_high {
            messages.push(format!(
                "the residuals are {noise:.1}× the stated noise{} (warning above {}): the model \
                 misfits or the cell's [noise] is understated; none of {tried_count} likely \
                 mistakes explains it; `handclasp diagnose` names what the model misses",
                with_tolerances(noise_tol),
                th.noise_high
            ));
        }
        if placement_far {
            messages.push(format!(
                "the fitted b1_from_b2 is {:.1} mm / {:.2}° from the cell's (allowed {allow_mm:.1} \
                 mm / {allow_deg:.2}°, {allow_source}); none of {tried_count} likely mistakes \
                 explains it: check the cell's placement, mounts and tips",
                dist.translation_mm, dist.rotation_deg
            ));
        }
    }
    if let Some((_, Some(m))) = &masked {
        if !refused {
            messages.push(m.clone());
        }
    }
    if noise < th.noise_low {
        messages.push(format!(
            "the residuals are {noise:.2}× the stated noise (warning below {}): the cell's \
             [noise] looks overstated, so the kinematic prior and the blunder screen trust the \
             data too little; state the session's real noise",
            th.noise_low
        ));
    }
    messages.extend(degenerate);
    if let Some(p) = screen
        .pattern
        .as_ref()
        .filter(|p| !p.misfit && p.share > MISFIT_SHARE_ALONE)
    {
        let rows: Vec<usize> = cal.rejected.iter().map(|r| r.row).collect();
        messages.push(format!(
            "{} of {} rows ({:.0} %) rejected as blunders: the rows left fit at the stated noise \
             (robust noise scale {:.2}, at most {REST_FITS_SCALE}), so these rows disagree with \
             any model, not the model with them: rows {rows:?}; re-record them, or remove them \
             and re-run",
            p.rejected_rows,
            p.rows,
            100.0 * p.share,
            p.rest_noise_scale.unwrap_or(f64::NAN),
        ));
    }
    if let Some(p) = screen.pattern.as_ref().filter(|p| p.misfit) {
        messages.push(if screen.rows_kept {
            format!(
                "model misfit, not blunders: {}; every row kept (--screen auto); `handclasp \
                 diagnose` names what the model misses (--screen strict rejects them)",
                p.describe()
            )
        } else {
            format!(
                "the rejected rows look like a model misfit, not blunders: {}; rejected anyway \
                 (--screen strict); `handclasp diagnose` names what the model misses",
                p.describe()
            )
        });
    }
    let status = if refused {
        STATUS_REFUSED
    } else if messages.is_empty() {
        "ok"
    } else {
        "warning"
    };
    Ok(ResultCheckReport {
        checks,
        likely_mistake: likely,
        messages,
        mistakes_tried: tried,
        screen,
        status,
    })
}

/// Blunders that mask one another in a placement-only fit: the coincident rows that disagree
/// with the rigid fit of the majority of them ([`calib_core::masked_blunders`] on the nominal
/// tips, [`coincident_pairs`]) and that the blunder screen kept (its noise scale, √(χ²/dof),
/// is inflated by them). The check item (`masked_blunders`: how many such rows) and, when
/// there are any, the message. `None` for a kinematic fit (nominal tips are not its model: a
/// kinematic error would look like blunders) or fewer than 6 coincident rows.
fn masked_blunders_check(
    problem: &CellProblem,
    cal: &CellCalibration,
) -> Option<(CheckItem, Option<String>)> {
    if cal.fit.layout.prior_sqrt_info.nrows() != 0 {
        return None;
    }
    let pairs = coincident_pairs(problem)?;
    let m = calib_core::masked_blunders(&pairs)?;
    let rows: Vec<usize> = m.flagged.iter().map(|&i| pairs.row(i)).collect();
    let kept: Vec<usize> = rows
        .iter()
        .copied()
        .filter(|r| !cal.rejected.iter().any(|x| x.row == *r))
        .collect();
    let item = CheckItem {
        detail: format!(
            "coincident rows farther from the rigid fit of the majority (nominal robots) than \
             {} × its residual scale that the blunder screen kept: blunders that mask one \
             another",
            calib_core::OUTLIER_FACTOR
        ),
        name: "masked_blunders",
        status: if kept.is_empty() { "ok" } else { "high" },
        thresholds: vec![0.0],
        value: kept.len() as f64,
    };
    if kept.is_empty() {
        return Some((item, None));
    }
    let far: Vec<f64> = m.flagged.iter().map(|&i| m.residuals_m[i] * 1e3).collect();
    let (lo, hi) = far
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    let moved = placement_distance(&m.b1_from_b2, &cal.fit.estimate.b1_from_b2);
    let message = format!(
        "{} of {} coincident rows ({:.0} %) disagree with the rigid fit of the other {} by \
         {lo:.1}–{hi:.1} mm (limit {:.1} mm, {} × their residual scale): blunders that mask one \
         another, of which the blunder screen rejected {}: rows {rows:?}; the majority's fit is \
         {:.1} mm / {:.2}° from this one; re-record them, or remove them and re-run",
        rows.len(),
        pairs.len(),
        100.0 * rows.len() as f64 / pairs.len() as f64,
        pairs.len() - rows.len(),
        m.limit_m * 1e3,
        calib_core::OUTLIER_FACTOR,
        rows.len() - kept.len(),
        moved.translation_mm,
        moved.rotation_deg,
    );
    Some((item, Some(message)))
}

/// The words for a placement fit's noise scale with the robots' tolerances (empty without
/// one).
fn with_tolerances(noise_tol: Option<f64>) -> String {
    noise_tol.map_or_else(String::new, |t| {
        format!(" ({t:.2}× the stated noise plus what the robots' tolerances allow)")
    })
}

fn trial_report(
    what: &str,
    t: &Trial,
    d: &PlacementDistance,
    explains: bool,
) -> MistakeTrialReport {
    MistakeTrialReport {
        explains,
        mistake: what.to_string(),
        noise_scale: t.noise_scale,
        placement_deg: d.rotation_deg,
        placement_mm: d.translation_mm,
    }
}

/// The largest difference allowed between a row's residual re-predicted from an exported cell
/// and the fit's own, mm: the URDF patch's tolerance (`kinematics::PATCH_TOLERANCE_M`) and the
/// cell file's rounding are far below it; a fitted quantity the export lost is far above it
/// (a named tool moved by millimetres).
pub const EXPORT_REPREDICTION_TOL_MM: f64 = 0.01;

/// The largest difference, mm, between each training row's residual re-predicted from
/// `exported` (the cell an export wrote, read back; its `[robotN.errors]` applied, the fit's
/// nuisances — tracker frames, planes, contact distances — carried over, as they are not cell
/// properties) and the residual of the fit `cal` of `problem`, with the row of the largest.
///
/// # Errors
/// A residual cannot be evaluated, or the exported cell's estimate does not fit the session
/// (joint counts, tools).
pub fn reprediction_difference(
    exported: &Cell,
    session: &Session,
    problem: &CellProblem,
    cal: &CellCalibration,
) -> Result<(f64, usize), CellFitError> {
    use calib_core::whole_cell::{CellEstimate, Evaluator, ParamLayout};
    use calib_core::Robot;
    let p = cell_problem(exported, session, FitModel::Placement);
    let mut est = CellEstimate::nominal(&p, exported.b1_from_b2);
    for robot in Robot::BOTH {
        let errors = exported.robot(robot).errors.clone();
        match robot {
            Robot::One => est.robot1.errors = errors,
            Robot::Two => est.robot2.errors = errors,
        }
    }
    let fitted = &cal.fit.estimate;
    est.tracker_from_anchor = fitted.tracker_from_anchor.clone();
    est.tracker_scale = fitted.tracker_scale.clone();
    est.tracker_drift_m = fitted.tracker_drift_m.clone();
    est.planes = fitted.planes.clone();
    est.contact_distance_m = fitted.contact_distance_m.clone();
    est.check(&p)?;
    let layout_exported = ParamLayout::new(&p, &[]);
    let ev_exported = Evaluator::new(&p, &layout_exported);
    let ev_fit = Evaluator::new(problem, &cal.fit.layout);
    let mut worst = (0.0f64, 0usize);
    for (a, b) in problem.observations.iter().zip(&p.observations) {
        let ra = ev_fit.linearise(a, fitted, false)?.residual;
        let rb = ev_exported.linearise(b, &est, false)?.residual;
        let d = (ra - rb).norm() * 1e3;
        if d > worst.0 {
            worst = (d, a.row);
        }
    }
    Ok(worst)
}

/// The JSON a command prints on stdout with `--json` when it refuses a result (exit code still
/// non-zero), so that a script can read why: `status` `"refused"`, the `reason` (the text the
/// command prints after `error:`), and the check values behind it, under the key of the check
/// that refused (`result_check` for `calibrate --cell` and `diagnose`, `misfit` for
/// `calibrate POINTS.csv`, `export_reprediction` for a refused export).
#[derive(Debug, Clone, Serialize)]
pub struct Refusal<'a> {
    /// The command that refused (`calibrate --cell`, `diagnose`, `calibrate`).
    pub command: &'static str,
    /// The refused export's re-prediction ([`ExportReprediction`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub export_reprediction: Option<ExportReprediction>,
    /// The points fit's plausibility check ([`crate::points::PointsMisfit`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub misfit: Option<&'a crate::points::PointsMisfit>,
    /// Why, in words (the error message).
    pub reason: String,
    /// The whole-cell result check ([`ResultCheckReport`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub result_check: Option<&'a ResultCheckReport>,
    /// Always `"refused"` (as [`ResultCheckReport::status`] names it).
    pub status: &'static str,
}

impl<'a> Refusal<'a> {
    /// A refusal by `command` for `reason`, with no check values yet.
    pub fn new(command: &'static str, reason: String) -> Self {
        Refusal {
            command,
            export_reprediction: None,
            misfit: None,
            reason,
            result_check: None,
            status: STATUS_REFUSED,
        }
    }
}

/// A refused export's re-prediction check (JSON `export_reprediction` of a [`Refusal`]).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ExportReprediction {
    /// The allowed difference, mm ([`EXPORT_REPREDICTION_TOL_MM`]).
    pub limit_mm: f64,
    /// The session row of the largest difference.
    pub row: usize,
    /// The largest difference between the exported cell's re-prediction and the fit, mm.
    pub worst_mm: f64,
}

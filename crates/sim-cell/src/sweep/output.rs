//! A sweep's outputs: the per-trial CSV, the summary rows (median and 95th percentile with 95 %
//! confidence intervals), the terminal table and the summary CSV.

use calib_core::stats::{quantile_ci, sorted_finite, QuantileCi};
use std::io::Write;

use super::config::{Mode, SweepMethod};
use super::run::SweepResult;
use crate::placement::mounts_label;

/// Writes every trial × method as CSV: `seed,trial,cell,trial_in_cell,mode,mounts,layout,method,
/// noise_mm,spread_mm,n,status,e_tran_mm,e_rot_deg,geodesic_deg,dx_mm,dy_mm,dz_mm` (errors empty
/// when the status is not `ok`; `trial` is the index given to [`crate::trial_rng`]), and in
/// robot mode `ROBOT_TRIALS_COLUMNS` after them: `kinematic_errors`, the cooperative rms and
/// p95 over the held-out pairs, mm, and the fit's predicted rms, mm (whole-cell methods; empty
/// otherwise). Fields are quoted where CSV needs it (a tilted mount's label holds a comma).
/// Deterministic text.
pub fn write_trials_csv(result: &SweepResult, w: &mut impl Write) -> std::io::Result<()> {
    let c = &result.config;
    let robot = c.mode == Mode::Robot;
    let header = trials_header(c.mode);
    let mut out = csv::Writer::from_writer(w);
    out.write_record(&header)?;
    let labels: Vec<String> = c.mounts.iter().map(mounts_label).collect();
    let mut record: Vec<String> = Vec::with_capacity(header.len());
    for trial in 0..c.total_trials() {
        let cell_idx = trial / c.trials;
        let cell = result.grid[cell_idx];
        for (m, method) in c.methods.iter().enumerate() {
            record.clear();
            record.extend([
                c.seed.to_string(),
                trial.to_string(),
                cell_idx.to_string(),
                (trial % c.trials).to_string(),
                c.mode.name().to_string(),
                labels[cell.mounts].clone(),
                c.layout.name().to_string(),
                method.name().to_string(),
                c.noise_mm[cell.noise].to_string(),
                (c.spread_m[cell.spread] * 1000.0).to_string(),
                c.n_points[cell.n].to_string(),
            ]);
            match result.outcome(trial, m) {
                Ok(o) => {
                    let e = &o.errors;
                    record.extend([
                        "ok".to_string(),
                        format!("{:.6}", e.e_tran * 1e3),
                        format!("{:.7}", e.e_rot.to_degrees()),
                        format!("{:.7}", e.geodesic.to_degrees()),
                        format!("{:.6}", e.translation_error.x * 1e3),
                        format!("{:.6}", e.translation_error.y * 1e3),
                        format!("{:.6}", e.translation_error.z * 1e3),
                    ]);
                    if robot {
                        record.push(c.kinematic_errors.name().to_string());
                        let mm =
                            |v: Option<f64>| v.map_or(String::new(), |v| format!("{:.6}", v * 1e3));
                        let co = o.cooperative;
                        record.extend([
                            mm(co.map(|co| co.rms_m)),
                            mm(co.map(|co| co.p95_m)),
                            mm(co.and_then(|co| co.predicted_rms_m)),
                        ]);
                    }
                }
                Err(f) => {
                    record.push(f.name().to_string());
                    record.resize(TRIALS_HEADER.len(), String::new());
                    if robot {
                        record.push(c.kinematic_errors.name().to_string());
                        record.resize(header.len(), String::new());
                    }
                }
            }
            out.write_record(&record)?;
        }
    }
    out.flush()
}

/// The columns of `trials.csv`.
pub const TRIALS_HEADER: [&str; 18] = [
    "seed",
    "trial",
    "cell",
    "trial_in_cell",
    "mode",
    "mounts",
    "layout",
    "method",
    "noise_mm",
    "spread_mm",
    "n",
    "status",
    "e_tran_mm",
    "e_rot_deg",
    "geodesic_deg",
    "dx_mm",
    "dy_mm",
    "dz_mm",
];

/// The columns robot mode adds to `trials.csv` after [`TRIALS_HEADER`].
pub const ROBOT_TRIALS_COLUMNS: [&str; 4] = [
    "kinematic_errors",
    "cooperative_rms_mm",
    "cooperative_p95_mm",
    "predicted_cooperative_rms_mm",
];

/// The columns of `trials.csv` in `mode` ([`TRIALS_HEADER`], plus [`ROBOT_TRIALS_COLUMNS`] in
/// robot mode).
pub fn trials_header(mode: Mode) -> Vec<&'static str> {
    let mut h = TRIALS_HEADER.to_vec();
    if mode == Mode::Robot {
        h.extend(ROBOT_TRIALS_COLUMNS);
    }
    h
}

/// Statistics of one method over a group of trials.
#[derive(Debug, Clone, PartialEq)]
pub struct SummaryRow {
    /// Mount pair label.
    pub mounts: String,
    /// Method.
    pub method: SweepMethod,
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
    /// Robot mode: median over trials of the cooperative rms, mm, with 95 % CI (`None` in
    /// geometry mode).
    pub cooperative_rms_mm_median: Option<QuantileCi>,
    /// Robot mode: median over trials of the cooperative p95, mm, with 95 % CI.
    pub cooperative_p95_mm_median: Option<QuantileCi>,
    /// Robot mode: median over trials of the predicted cooperative rms, mm, with 95 % CI (NaN
    /// for methods that predict nothing).
    pub predicted_cooperative_rms_mm_median: Option<QuantileCi>,
}

pub(super) fn summary_row(
    result: &SweepResult,
    mounts: usize,
    m: usize,
    key: (Option<f64>, Option<f64>, Option<usize>),
    trials: impl Iterator<Item = usize>,
) -> SummaryRow {
    let mut count = 0;
    let mut failed = 0;
    let (mut et, mut er, mut eg) = (Vec::new(), Vec::new(), Vec::new());
    let (mut cr, mut cp, mut pr) = (Vec::new(), Vec::new(), Vec::new());
    for t in trials {
        count += 1;
        match result.outcome(t, m) {
            Ok(o) => {
                let e = &o.errors;
                et.push(e.e_tran * 1e3);
                er.push(e.e_rot.to_degrees());
                eg.push(e.geodesic.to_degrees());
                if let Some(c) = o.cooperative {
                    cr.push(c.rms_m * 1e3);
                    cp.push(c.p95_m * 1e3);
                    if let Some(p) = c.predicted_rms_m {
                        pr.push(p * 1e3);
                    }
                }
            }
            Err(_) => failed += 1,
        }
    }
    let (et, er, eg) = (sorted_finite(et), sorted_finite(er), sorted_finite(eg));
    let robot = result.config.mode == Mode::Robot;
    let coop = |v: Vec<f64>| robot.then(|| quantile_ci(&sorted_finite(v), 0.5));
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
        cooperative_rms_mm_median: coop(cr),
        cooperative_p95_mm_median: coop(cp),
        predicted_cooperative_rms_mm_median: coop(pr),
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

pub(super) fn ci_text(q: &QuantileCi, decimals: usize) -> String {
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
/// [`calib_core::e_rot_zyz`]) and the geodesic angle (deg), each `value [95 % CI]`; rows of a
/// robot-mode sweep add the medians of the cooperative rms and the predicted rms (mm).
pub fn render_table(rows: &[SummaryRow]) -> String {
    let robot = rows
        .first()
        .is_some_and(|r| r.cooperative_rms_mm_median.is_some());
    let mut header: Vec<String> = [
        "mounts",
        "method",
        "trials",
        "failed",
        "e_tran median mm",
        "e_tran p95 mm",
        "e_rot median deg",
        "e_rot p95 deg",
        "geodesic median deg",
        "geodesic p95 deg",
    ]
    .map(String::from)
    .to_vec();
    if robot {
        header.extend(["coop rms median mm".into(), "predicted median mm".into()]);
    }
    let body: Vec<Vec<String>> = rows
        .iter()
        .map(|r| {
            let mut cells = vec![
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
            ];
            if robot {
                for q in [
                    &r.cooperative_rms_mm_median,
                    &r.predicted_cooperative_rms_mm_median,
                ] {
                    cells.push(q.as_ref().map_or(String::new(), |q| {
                        if q.value.is_nan() {
                            "-".into()
                        } else {
                            ci_text(q, 3)
                        }
                    }));
                }
            }
            cells
        })
        .collect();
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in &body {
        for (w, c) in widths.iter_mut().zip(r) {
            *w = (*w).max(c.chars().count());
        }
    }
    let line = |cells: &[String]| {
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
/// statistic `_value,_lo,_hi`; pooled axes are empty). Rows with cooperative statistics (robot
/// mode) add `ROBOT_SUMMARY_STATS` after the others.
pub fn write_summary_csv(rows: &[SummaryRow], w: &mut impl Write) -> std::io::Result<()> {
    let robot = rows
        .first()
        .is_some_and(|r| r.cooperative_rms_mm_median.is_some());
    let mut out = csv::Writer::from_writer(w);
    let mut header = summary_header();
    if robot {
        for s in ROBOT_SUMMARY_STATS {
            header.extend([s.to_string(), format!("{s}_lo"), format!("{s}_hi")]);
        }
    }
    out.write_record(header)?;
    let opt = |v: Option<String>| v.unwrap_or_default();
    for r in rows {
        let mut record = vec![
            r.mounts.clone(),
            r.method.name().to_string(),
            opt(r.noise_mm.map(|v| v.to_string())),
            opt(r.spread_m.map(|v| (v * 1000.0).to_string())),
            opt(r.n.map(|v| v.to_string())),
            r.trials.to_string(),
            r.failed.to_string(),
        ];
        for q in [
            &r.e_tran_mm_median,
            &r.e_tran_mm_p95,
            &r.e_rot_deg_median,
            &r.e_rot_deg_p95,
            &r.geodesic_deg_median,
            &r.geodesic_deg_p95,
        ] {
            record.extend([
                format!("{:.7}", q.value),
                format!("{:.7}", q.lower),
                format!("{:.7}", q.upper),
            ]);
        }
        if robot {
            for q in [
                &r.cooperative_rms_mm_median,
                &r.cooperative_p95_mm_median,
                &r.predicted_cooperative_rms_mm_median,
            ] {
                let q = q.unwrap_or(QuantileCi {
                    value: f64::NAN,
                    lower: f64::NAN,
                    upper: f64::NAN,
                });
                record.extend([
                    format!("{:.7}", q.value),
                    format!("{:.7}", q.lower),
                    format!("{:.7}", q.upper),
                ]);
            }
        }
        out.write_record(&record)?;
    }
    out.flush()
}

/// The statistics robot mode adds to `summary.csv` (each `<statistic>,_lo,_hi`): medians over
/// the trials of the cooperative rms and p95 and of the predicted cooperative rms, mm.
pub const ROBOT_SUMMARY_STATS: [&str; 3] = [
    "cooperative_rms_mm_median",
    "cooperative_p95_mm_median",
    "predicted_cooperative_rms_mm_median",
];

/// The columns of `summary.csv`: `mounts,method,noise_mm,spread_mm,n,trials,failed`, then
/// `<statistic>,<statistic>_lo,<statistic>_hi` for each statistic.
pub fn summary_header() -> Vec<String> {
    let stats = [
        "e_tran_mm_median",
        "e_tran_mm_p95",
        "e_rot_deg_median",
        "e_rot_deg_p95",
        "geodesic_deg_median",
        "geodesic_deg_p95",
    ];
    let mut header: Vec<String> = [
        "mounts",
        "method",
        "noise_mm",
        "spread_mm",
        "n",
        "trials",
        "failed",
    ]
    .map(String::from)
    .to_vec();
    for s in stats {
        header.extend([s.to_string(), format!("{s}_lo"), format!("{s}_hi")]);
    }
    header
}

//! The σ fit and the simulated band.
//!
//! For a set of (cell, method) groups sharing one σ, the log-likelihood of the published
//! `(e_tran, e_rot)` pairs is a Gaussian kernel density estimate of the simulated
//! `(ln e_tran, ln e_rot)` (full-covariance bandwidth, Scott's factor `n^(−1/3)` on the covariance),
//! with the Jacobian `1/(e_tran·e_rot)`. σ̂ maximises it (grid in ln σ, then golden section); the 95 %
//! The tests built on it are in `study.rs`.

use calib_core::stats::{maximize_log_1d, quantile, Maximize1dOptions};
use serde::Serialize;

use super::experiments::PaperMethod;
use super::simulate::CellSim;
use super::{BAND, SIGMA_RANGE_MM};

/// Log-likelihood of observed `(e_tran, e_rot)` pairs under simulated ones: Gaussian KDE on the logs
/// (full covariance bandwidth `n^(−1/3)·Cov`), with the Jacobian of the log transform.
pub(super) fn kde_loglik(sim: &[(f64, f64)], obs: &[(f64, f64)]) -> f64 {
    let u: Vec<[f64; 2]> = sim
        .iter()
        .filter(|(a, b)| *a > 0.0 && *b > 0.0)
        .map(|(a, b)| [a.ln(), b.ln()])
        .collect();
    let n = u.len() as f64;
    if u.len() < 10 {
        return f64::NEG_INFINITY;
    }
    let mean = u.iter().fold([0.0, 0.0], |m, x| [m[0] + x[0], m[1] + x[1]]);
    let mean = [mean[0] / n, mean[1] / n];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for x in &u {
        let (dx, dy) = (x[0] - mean[0], x[1] - mean[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let f = n.powf(-1.0 / 3.0) / (n - 1.0);
    let (hxx, hxy, hyy) = (sxx * f, sxy * f, syy * f);
    let det = (hxx * hyy - hxy * hxy).max(1e-300);
    let (ixx, ixy, iyy) = (hyy / det, -hxy / det, hxx / det);
    let log_norm = -(2.0 * std::f64::consts::PI).ln() - 0.5 * det.ln() - n.ln();
    let mut total = 0.0;
    for &(et, er) in obs {
        if et <= 0.0 || er <= 0.0 {
            return f64::NEG_INFINITY;
        }
        let o = [et.ln(), er.ln()];
        let mut max_e = f64::NEG_INFINITY;
        let exps: Vec<f64> = u
            .iter()
            .map(|x| {
                let (dx, dy) = (o[0] - x[0], o[1] - x[1]);
                let e = -0.5 * (ixx * dx * dx + 2.0 * ixy * dx * dy + iyy * dy * dy);
                max_e = max_e.max(e);
                e
            })
            .collect();
        let s: f64 = exps.iter().map(|e| (e - max_e).exp()).sum();
        total += log_norm + max_e + s.ln() - o[0] - o[1];
    }
    total
}

/// A group of published pairs sharing σ: a cell's simulation, a method and the observations.
pub(super) struct Group<'a> {
    pub(super) sim: &'a CellSim,
    pub(super) method: PaperMethod,
    pub(super) obs: Vec<(f64, f64)>,
}

pub(super) fn group_loglik(groups: &[Group<'_>], sigma_mm: f64) -> f64 {
    groups
        .iter()
        .map(|g| kde_loglik(&g.sim.errors_at(g.method, sigma_mm), &g.obs))
        .sum()
}

/// A maximum-likelihood σ with its profile-likelihood 95 % interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SigmaFit {
    /// σ̂, mm.
    pub sigma_mm: f64,
    /// 95 % profile-likelihood interval, mm (an end at [`SIGMA_RANGE_MM`] means unbounded there).
    pub ci95_mm: [f64; 2],
    /// Maximised log-likelihood (density of e_tran in mm and e_rot in degrees).
    pub loglik: f64,
    /// Number of published pairs used.
    pub n: usize,
}

pub(super) fn fit_sigma(groups: &[Group<'_>]) -> SigmaFit {
    fit_sigma_opt(groups, true)
}

/// As [`fit_sigma`]; without the interval (NaN) when `with_ci` is false (bootstrap replicates).
pub(super) fn fit_sigma_opt(groups: &[Group<'_>], with_ci: bool) -> SigmaFit {
    let f = |s: f64| group_loglik(groups, s);
    // A fine grid when the interval is wanted; a coarse one is enough to bracket the maximum.
    let options = if with_ci {
        Maximize1dOptions::default()
    } else {
        Maximize1dOptions {
            grid_steps: 20,
            golden_iterations: 25,
            profile_interval: false,
            ..Maximize1dOptions::default()
        }
    };
    let m = maximize_log_1d(&f, SIGMA_RANGE_MM[0], SIGMA_RANGE_MM[1], &options);
    let (sigma_mm, loglik, ci95_mm) = (m.argmax, m.max, m.ci95);
    SigmaFit {
        sigma_mm,
        ci95_mm,
        loglik,
        n: groups.iter().map(|g| g.obs.len()).sum(),
    }
}

/// A simulated distribution summarised: 5 %, 50 % and 95 % quantiles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Band {
    /// 5 % quantile.
    pub p05: f64,
    /// Median.
    pub p50: f64,
    /// 95 % quantile.
    pub p95: f64,
}

impl Band {
    pub(super) fn of(values: impl IntoIterator<Item = f64>) -> Band {
        let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        Band {
            p05: quantile(&v, BAND[0]),
            p50: quantile(&v, 0.5),
            p95: quantile(&v, BAND[1]),
        }
    }

    /// Whether `x` lies outside the 5–95 % band.
    pub fn outside(&self, x: f64) -> bool {
        x < self.p05 || x > self.p95
    }
}

//! Fitting a candidate model to the signed errors: generalised least squares for the mean, closed
//! form for σ², 1-D searches for the noise shape, profile intervals, AIC and held-out likelihood.

use calib_core::stats::{chi2_sf, maximize_log_1d, Maximize1dOptions, CHI2_1_95};
use nalgebra::{DMatrix, DVector, Vector6};
use rayon::prelude::*;
use serde::Serialize;

use super::candidates::{Candidate, Obs, ParamName};
use super::experiments::PaperCell;
use super::{ANISOTROPY_RANGE, SPREAD_BASE, SPREAD_GRID_M};

/// A model: a set of candidates on top of the isotropic baseline.
#[derive(Debug, Clone)]
pub(super) struct ModelFit {
    pub(super) beta: Vec<f64>,
    pub(super) beta_se: Vec<f64>,
    pub(super) names: Vec<ParamName>,
    pub(super) sigma2: [f64; 3],
    pub(super) shape: Shape,
    pub(super) loglik: f64,
    pub(super) n_params: usize,
}

/// Gaussian log-density of each observation under a fitted model.
pub(super) fn obs_loglik(o: &Obs, mean: &DVector<f64>, sigma2: f64, shape: Shape) -> f64 {
    let d = o.y.len();
    let cov = shape_cov(o, shape) * sigma2;
    let Some(ch) = cov.cholesky() else {
        return f64::NEG_INFINITY;
    };
    let r = &o.y - mean;
    let sol = ch.solve(&r);
    let logdet: f64 = 2.0 * ch.l().diagonal().iter().map(|x| x.ln()).sum::<f64>();
    -0.5 * (d as f64 * (2.0 * std::f64::consts::PI).ln() + logdet + r.dot(&sol))
}

pub(super) fn design(cands: &[Candidate], o: &Obs) -> (DMatrix<f64>, Vec<ParamName>) {
    let dims = o.cell.observed_dims();
    let mut cols: Vec<&Vector6<f64>> = Vec::new();
    let mut names = Vec::new();
    for &c in cands {
        let pc = &o.columns[c.index()];
        names.extend(pc.names.iter().cloned());
        cols.extend(pc.cols.iter());
    }
    let j = DMatrix::from_fn(dims.len(), cols.len(), |i, k| cols[k][dims[i]]);
    (j, names)
}

/// Covariance shape of the signed error per σ² (mm², mrad²): anisotropy `k`, per-experiment
/// contact offset `rho` (τ/σ) and layout index `g` into [`SPREAD_GRID_M`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Shape {
    pub(super) k: f64,
    pub(super) rho: f64,
    pub(super) g: usize,
}

impl Shape {
    const BASE: Shape = Shape {
        k: 1.0,
        rho: 0.0,
        g: SPREAD_BASE,
    };
}

/// `Σp + k²·Σa + ρ²·I_translation` of one observation.
pub(super) fn shape_cov(o: &Obs, shape: Shape) -> DMatrix<f64> {
    let (cov_perp, cov_along) = &o.covs[shape.g];
    let mut cov = cov_perp + cov_along * (shape.k * shape.k);
    // The first three observed components are the translation (mm) in every cell.
    for i in 0..3 {
        cov[(i, i)] += shape.rho * shape.rho;
    }
    cov
}

pub(super) fn fit_fixed_k(cands: &[Candidate], data: &[&Obs], shape: Shape) -> Option<ModelFit> {
    let per_cell = cands.contains(&Candidate::SigmaPerCell);
    let designs: Vec<(DMatrix<f64>, DMatrix<f64>)> = data
        .iter()
        .map(|o| {
            let cov = shape_cov(o, shape);
            let inv = cov
                .clone()
                .try_inverse()
                .unwrap_or_else(|| DMatrix::zeros(cov.nrows(), cov.ncols()));
            (design(cands, o).0, inv)
        })
        .collect();
    let names = data.first().map(|o| design(cands, o).1).unwrap_or_default();
    let p = names.len();
    // Drop parameters no observation informs (e.g. a cell absent from `data`).
    let informed: Vec<bool> = (0..p)
        .map(|c| designs.iter().any(|(j, _)| j.column(c).amax() > 0.0))
        .collect();
    let mut sigma2 = [1.0; 3];
    let mut beta = DVector::zeros(p);
    let mut cov_beta = DMatrix::zeros(p, p);
    for _ in 0..200 {
        if p > 0 {
            let mut a = DMatrix::zeros(p, p);
            let mut b = DVector::zeros(p);
            for ((j, w), o) in designs.iter().zip(data) {
                let s2 = sigma2[o.cell.index()];
                let jt_w = j.transpose() * w / s2;
                a += &jt_w * j;
                b += &jt_w * &o.y;
            }
            for (c, inf) in informed.iter().enumerate() {
                if !inf {
                    a[(c, c)] = 1.0;
                }
            }
            let ch = a.cholesky()?;
            beta = ch.solve(&b);
            cov_beta = ch.inverse();
        }
        let mut q = [0.0; 3];
        let mut n = [0.0; 3];
        for ((j, w), o) in designs.iter().zip(data) {
            let r = &o.y - j * &beta;
            let ci = o.cell.index();
            q[ci] += r.dot(&(w * &r));
            n[ci] += r.len() as f64;
        }
        let old = sigma2;
        if per_cell {
            for c in 0..3 {
                sigma2[c] = if n[c] > 0.0 {
                    (q[c] / n[c]).max(1e-12)
                } else {
                    1.0
                };
            }
        } else {
            let s = (q.iter().sum::<f64>() / n.iter().sum::<f64>()).max(1e-12);
            sigma2 = [s; 3];
        }
        let change = (0..3)
            .map(|c| (sigma2[c] / old[c] - 1.0).abs())
            .fold(0.0, f64::max);
        if change < 1e-12 || (!per_cell && p == 0) {
            break;
        }
    }
    let loglik = designs
        .iter()
        .zip(data)
        .map(|((j, _), o)| obs_loglik(o, &(j * &beta), sigma2[o.cell.index()], shape))
        .sum();
    let cells_present = PaperCell::ALL
        .iter()
        .filter(|c| data.iter().any(|o| o.cell == **c))
        .count();
    let n_params = informed.iter().filter(|x| **x).count()
        + if per_cell { cells_present } else { 1 }
        + cands.contains(&Candidate::AnisotropicNoise) as usize
        + cands.contains(&Candidate::LayoutSpread) as usize
        + cands.contains(&Candidate::ContactOffsetPerExperiment) as usize;
    Some(ModelFit {
        beta: beta.iter().copied().collect(),
        beta_se: (0..p).map(|i| cov_beta[(i, i)].max(0.0).sqrt()).collect(),
        names,
        sigma2,
        shape,
        loglik,
        n_params,
    })
}

pub(super) fn fit_model(cands: &[Candidate], data: &[&Obs]) -> Option<ModelFit> {
    if cands.contains(&Candidate::LayoutSpread) {
        (0..SPREAD_GRID_M.len())
            .filter_map(|g| fit_model_at(cands, data, g))
            .max_by(|a, b| a.loglik.total_cmp(&b.loglik))
    } else {
        fit_model_at(cands, data, SPREAD_BASE)
    }
}

/// The 1-D searches of the noise-shape parameters: a 16-interval grid in `ln x`, then 30
/// golden-section steps; no interval.
pub(super) const SHAPE_SEARCH: Maximize1dOptions = Maximize1dOptions {
    grid_steps: 16,
    golden_iterations: 30,
    profile_interval: false,
    bisection_iterations: 0,
};

/// Range of ρ = τ/σ searched by the per-experiment contact offset (0 is tried too).
pub(super) const RHO_RANGE: [f64; 2] = [0.05, 20.0];

/// [`fit_model`] at the tetrahedron edge `SPREAD_GRID_M[g]`: the noise-shape parameters (k, ρ)
/// by 1-D searches, alternated when both are present.
pub(super) fn fit_model_at(cands: &[Candidate], data: &[&Obs], g: usize) -> Option<ModelFit> {
    let aniso = cands.contains(&Candidate::AnisotropicNoise);
    let offset = cands.contains(&Candidate::ContactOffsetPerExperiment);
    let mut shape = Shape { g, ..Shape::BASE };
    let ll = |sh: Shape| {
        fit_fixed_k(cands, data, sh)
            .map(|m| m.loglik)
            .unwrap_or(f64::NEG_INFINITY)
    };
    let rounds = if aniso && offset { 3 } else { 1 };
    for _ in 0..rounds {
        if offset {
            let r = maximize_log_1d(
                &|rho| ll(Shape { rho, ..shape }),
                RHO_RANGE[0],
                RHO_RANGE[1],
                &SHAPE_SEARCH,
            )
            .argmax;
            shape.rho = if ll(Shape { rho: r, ..shape }) >= ll(Shape { rho: 0.0, ..shape }) {
                r
            } else {
                0.0
            };
        }
        if aniso {
            shape.k = maximize_log_1d(
                &|k| ll(Shape { k, ..shape }),
                ANISOTROPY_RANGE[0],
                ANISOTROPY_RANGE[1],
                &SHAPE_SEARCH,
            )
            .argmax;
        }
    }
    fit_fixed_k(cands, data, shape)
}

pub(super) fn mean_of(cands: &[Candidate], o: &Obs, beta: &[f64]) -> DVector<f64> {
    let (j, _) = design(cands, o);
    if beta.is_empty() {
        return DVector::zeros(o.y.len());
    }
    j * DVector::from_column_slice(beta)
}

/// Leave-one-experiment-out held-out log-likelihood (sum over experiments).
pub(super) fn heldout(cands: &[Candidate], data: &[Obs]) -> f64 {
    (0..data.len())
        .into_par_iter()
        .map(|i| {
            let train: Vec<&Obs> = data
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, o)| o)
                .collect();
            match fit_model(cands, &train) {
                Some(m) => {
                    let o = &data[i];
                    obs_loglik(
                        o,
                        &mean_of(cands, o, &m.beta),
                        m.sigma2[o.cell.index()],
                        m.shape,
                    )
                }
                None => f64::NEG_INFINITY,
            }
        })
        .collect::<Vec<f64>>()
        .into_iter()
        .sum() // sequential: the same sum whatever the thread count
}

/// A fitted parameter of a candidate model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamEstimate {
    /// Name (`candidate.parameter[cell]`).
    pub name: String,
    /// Value in `unit`.
    pub value: f64,
    /// Unit (`mm`, `deg`, `ratio`).
    pub unit: String,
    /// 95 % interval (Wald, from the GLS covariance; anisotropy: profile likelihood).
    pub ci95: [f64; 2],
}

/// A candidate (or a selected combination) fitted to the 15 signed errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateResult {
    /// Candidate names (one, or the selected combination).
    pub candidates: Vec<String>,
    /// What it models.
    pub description: String,
    /// Fitted parameters (besides σ).
    pub params: Vec<ParamEstimate>,
    /// Fitted σ per cell `[floor-floor, floor-ceiling, floor-wall]`, mm (equal unless per cell).
    pub sigma_mm: [f64; 3],
    /// Number of parameters including σ.
    pub n_params: usize,
    /// Maximised log-likelihood.
    pub loglik: f64,
    /// AIC = 2·n_params − 2·loglik.
    pub aic: f64,
    /// Likelihood-ratio statistic against the baseline (isotropic σ only).
    pub lr_statistic: f64,
    /// Its degrees of freedom.
    pub lr_df: usize,
    /// Its p-value (χ²).
    pub lr_p_value: f64,
    /// Leave-one-experiment-out held-out log-likelihood (sum over the experiments).
    pub heldout_loglik: f64,
    /// Held-out gain over the baseline (positive = better prediction).
    pub heldout_gain: f64,
}

pub(super) fn candidate_result(
    cands: &[Candidate],
    data: &[Obs],
    base: Option<(&ModelFit, f64)>,
) -> Option<(CandidateResult, ModelFit)> {
    let refs: Vec<&Obs> = data.iter().collect();
    let m = fit_model(cands, &refs)?;
    let held = heldout(cands, data);
    let (lr, df, p, gain) = match base {
        Some((b, bh)) => {
            let lr = (2.0 * (m.loglik - b.loglik)).max(0.0);
            let df = m.n_params.saturating_sub(b.n_params);
            (
                lr,
                df,
                if df == 0 { 1.0 } else { chi2_sf(lr, df) },
                held - bh,
            )
        }
        None => (0.0, 0, 1.0, 0.0),
    };
    let mut params: Vec<ParamEstimate> = m
        .names
        .iter()
        .zip(m.beta.iter().zip(&m.beta_se))
        .filter(|(_, (_, se))| **se > 0.0)
        .map(|(n, (b, se))| ParamEstimate {
            name: n.name.clone(),
            value: b * n.scale,
            unit: n.unit.to_string(),
            ci95: [(b - 1.96 * se) * n.scale, (b + 1.96 * se) * n.scale],
        })
        .collect();
    if cands.contains(&Candidate::AnisotropicNoise) {
        // Profile interval of k.
        let f = |lk: f64| {
            fit_fixed_k(
                cands,
                &refs,
                Shape {
                    k: lk.exp(),
                    ..m.shape
                },
            )
            .map(|x| x.loglik)
            .unwrap_or(f64::NEG_INFINITY)
        };
        let target = m.loglik - 0.5 * CHI2_1_95;
        let cross = |outer: f64| -> f64 {
            let inner = m.shape.k.ln();
            if f(outer) >= target {
                return outer.exp();
            }
            let (mut i, mut o) = (inner, outer);
            for _ in 0..30 {
                let mid = 0.5 * (i + o);
                if f(mid) >= target {
                    i = mid;
                } else {
                    o = mid;
                }
            }
            (0.5 * (i + o)).exp()
        };
        params.push(ParamEstimate {
            name: "anisotropic_noise.k".into(),
            value: m.shape.k,
            unit: "ratio".into(),
            ci95: [
                cross(ANISOTROPY_RANGE[0].ln()),
                cross(ANISOTROPY_RANGE[1].ln()),
            ],
        });
    }
    if cands.contains(&Candidate::ContactOffsetPerExperiment) {
        // τ = ρ·σ; its interval from the profile of ρ (σ re-fitted at each ρ).
        let f = |rho: f64| {
            fit_fixed_k(cands, &refs, Shape { rho, ..m.shape })
                .map(|x| (x.loglik, x.sigma2[0].sqrt()))
        };
        let target = m.loglik - 0.5 * CHI2_1_95;
        let tau = |rho: f64| f(rho).map(|x| rho * x.1).unwrap_or(f64::NAN);
        let above = |rho: f64| f(rho).map(|x| x.0 >= target).unwrap_or(false);
        let cross = |outer: f64| -> f64 {
            if above(outer) {
                return tau(outer);
            }
            let (mut i, mut o) = (m.shape.rho, outer);
            for _ in 0..30 {
                let mid = 0.5 * (i + o);
                if above(mid) {
                    i = mid;
                } else {
                    o = mid;
                }
            }
            tau(0.5 * (i + o))
        };
        params.push(ParamEstimate {
            name: "contact_offset_per_experiment.tau".into(),
            value: tau(m.shape.rho),
            unit: "mm".into(),
            ci95: [cross(0.0), cross(RHO_RANGE[1])],
        });
    }
    if cands.contains(&Candidate::LayoutSpread) {
        // Profile over the grid: the edges whose best log-likelihood is within χ²(1)/2 of the top.
        let prof: Vec<f64> = (0..SPREAD_GRID_M.len())
            .map(|g| {
                fit_model_at(cands, &refs, g)
                    .map(|x| x.loglik)
                    .unwrap_or(f64::NEG_INFINITY)
            })
            .collect();
        let inside: Vec<f64> = SPREAD_GRID_M
            .iter()
            .zip(&prof)
            .filter(|(_, l)| **l >= m.loglik - 0.5 * CHI2_1_95)
            .map(|(e, _)| *e)
            .collect();
        params.push(ParamEstimate {
            name: "layout_spread.edge".into(),
            value: SPREAD_GRID_M[m.shape.g],
            unit: "m".into(),
            ci95: [
                inside.first().copied().unwrap_or(f64::NAN),
                inside.last().copied().unwrap_or(f64::NAN),
            ],
        });
    }
    let res = CandidateResult {
        candidates: cands.iter().map(|c| c.name().to_string()).collect(),
        description: cands
            .iter()
            .map(|c| c.description())
            .collect::<Vec<_>>()
            .join(" + "),
        params,
        sigma_mm: m.sigma2.map(f64::sqrt),
        n_params: m.n_params,
        loglik: m.loglik,
        aic: 2.0 * m.n_params as f64 - 2.0 * m.loglik,
        lr_statistic: lr,
        lr_df: df,
        lr_p_value: p,
        heldout_loglik: held,
        heldout_gain: gain,
    };
    Some((res, m))
}

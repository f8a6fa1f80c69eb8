//! The simulated protocol (geometry mode).
//! For each of the paper's cells (floor–floor, floor–ceiling, floor–wall) the true `b1_from_b2` is
//! Table 1's CMM truth. One simulated experiment teaches 4 handclasp points in a regular
//! tetrahedron of edge [`PAPER_SPREAD_M`] (the paper's "≥ 1 m apart, P4 off the P1–P3 plane"),
//! horizontal base triangle, random yaw, centred on the cell's teach-point centre
//! ([`crate::placement`]). The operator's tip-alignment error is a 3-vector per point, N(0, σ²·I)
//! (isotropic) by default, added to robot 1's reported point (only the relative position of the two
//! tips matters). Both of the table's methods are run on the same points: the generic 4-point method
//! (Ĥ1, `calib_core::generic_fast`, translation by eq 12) and the paper's constrained method (Ĥ2,
//! `calib_core::paper_fast`).
//!
//! # Linear scaling
//! At millimetre noise over a metre the estimators are linear in the noise to about 1e-3 relative,
//! so every error component of a trial is `bias + σ·slope`: `bias` is the noise-free error (zero for
//! the generic method; for the constrained method it is the part of the truth outside the mount
//! family, e.g. the floor–wall truth's θ = 89.874° against the family's 90°), `slope` the error at
//! σ = 1 mm minus the bias, with the same random numbers. One simulation at σ = 1 mm therefore gives
//! the error distribution at every σ (common random numbers, so the likelihood is smooth in σ); the
//! claim is checked per trial against direct simulation in the tests.

use calib_core::{generic_fast, paper_fast};
use nalgebra::{Isometry3, Matrix6, Point3, Rotation3, Vector3, Vector6};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::Serialize;

use super::experiments::{
    components, metrics, paper_errors, ErrorComponents, Experiment, PaperCell, PaperMethod,
};
use super::{MM_PER_M, PAPER_POINTS, PAPER_SPREAD_M, SPREAD_BASE, SPREAD_GRID_M};
use crate::layout::{teach_points_into, Layout};
use crate::trial_rng;

/// Effects planted in a synthetic experiment (true robot minus nominal model, as the simulator
/// injects them); all zero and `anisotropy = 1` is the isotropic noise-only protocol.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlantedEffects {
    /// Sum of the two tips' length errors along their tool axes, mm (true tip longer than nominal
    /// when positive).
    pub tip_mm: f64,
    /// Robot 1's joint-1 offset, degrees (true angle = reported + value).
    pub r1_joint1_deg: f64,
    /// Robot 2's joint-1 offset, degrees (true angle = reported + value).
    pub r2_joint1_deg: f64,
    /// σ along the approach axis divided by σ across it (1 = isotropic).
    pub anisotropy: f64,
    /// Standard deviation of a contact offset common to an experiment's points, random between
    /// experiments, mm per axis (0 = none).
    pub contact_offset_sd_mm: f64,
}

impl Default for PlantedEffects {
    fn default() -> Self {
        PlantedEffects {
            tip_mm: 0.0,
            r1_joint1_deg: 0.0,
            r2_joint1_deg: 0.0,
            anisotropy: 1.0,
            contact_offset_sd_mm: 0.0,
        }
    }
}

/// A cell's simulation context.
#[derive(Debug, Clone)]
pub(super) struct CellContext {
    pub(super) cell: PaperCell,
    pub(super) truth: Isometry3<f64>,
    pub(super) centre: Point3<f64>,
    /// Approach axis of robot 1's tip at the handclasp, b1 (unit vector from base 1 toward base 2:
    /// the tips meet head-on along the line between the bases).
    pub(super) approach: Vector3<f64>,
}

impl CellContext {
    pub(super) fn new(cell: PaperCell, truth: Isometry3<f64>) -> CellContext {
        let t = truth.translation.vector;
        CellContext {
            cell,
            truth,
            centre: cell.placement().centre_b1(),
            approach: t.normalize(),
        }
    }
}

/// One simulated handclasp experiment: true points (b1, b2) and the noise draws (unit normal).
pub(super) struct Draw {
    pub(super) p_b1: [Point3<f64>; PAPER_POINTS],
    pub(super) p_b2: [Point3<f64>; PAPER_POINTS],
    pub(super) noise: [Vector3<f64>; PAPER_POINTS],
    /// Unit-normal draw of the experiment's common contact offset.
    pub(super) offset: Vector3<f64>,
}

pub(super) fn draw(ctx: &CellContext, spread_m: f64, rng: &mut impl Rng) -> Draw {
    let mut p_b1 = [Point3::origin(); PAPER_POINTS];
    teach_points_into(Layout::Tetrahedron, spread_m, &ctx.centre, rng, &mut p_b1);
    let b2_from_b1 = ctx.truth.inverse();
    let p_b2 = p_b1.map(|p| b2_from_b1 * p);
    let mut noise = [Vector3::zeros(); PAPER_POINTS];
    for n in &mut noise {
        *n = Vector3::new(
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
            rng.sample(StandardNormal),
        );
    }
    let offset = Vector3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    );
    Draw {
        p_b1,
        p_b2,
        noise,
        offset,
    }
}

/// The reported points of a draw with noise `σ_across·(n_perp + k·n_along)` (mm) and planted effects.
pub(super) fn reported(
    ctx: &CellContext,
    d: &Draw,
    sigma_mm: f64,
    along_only: Option<bool>,
    plant: &PlantedEffects,
) -> ([Point3<f64>; PAPER_POINTS], [Point3<f64>; PAPER_POINTS]) {
    let a = ctx.approach;
    let r1 = Rotation3::from_axis_angle(&Vector3::z_axis(), -plant.r1_joint1_deg.to_radians());
    let r2 = Rotation3::from_axis_angle(&Vector3::z_axis(), -plant.r2_joint1_deg.to_radians());
    let mut p1 = d.p_b1;
    let mut p2 = d.p_b2;
    for i in 0..PAPER_POINTS {
        let n = d.noise[i];
        let along = a * a.dot(&n);
        let perp = n - along;
        let e = match along_only {
            None => perp + along * plant.anisotropy,
            Some(true) => along,
            Some(false) => perp,
        };
        let contact = d.p_b1[i].coords - a * (plant.tip_mm / MM_PER_M)
            + d.offset * (plant.contact_offset_sd_mm / MM_PER_M)
            + e * (sigma_mm / MM_PER_M);
        p1[i] = Point3::from(r1 * contact);
        p2[i] = r2 * d.p_b2[i];
    }
    (p1, p2)
}

pub(super) fn fit_both(
    ctx: &CellContext,
    p1: &[Point3<f64>; PAPER_POINTS],
    p2: &[Point3<f64>; PAPER_POINTS],
) -> Option<[Isometry3<f64>; 2]> {
    Some([
        generic_fast(p1, p2, false)?,
        paper_fast(p1, p2, &ctx.cell.mounts())?,
    ])
}

/// One simulated experiment at `sigma_mm` with planted effects: `[generic, constrained]` estimates.
/// `None` only if the 4 points are degenerate (never for the tetrahedron).
pub(super) fn simulate_experiment(
    ctx: &CellContext,
    sigma_mm: f64,
    plant: &PlantedEffects,
    rng: &mut impl Rng,
) -> Option<[Isometry3<f64>; 2]> {
    let d = draw(ctx, PAPER_SPREAD_M, rng);
    let (p1, p2) = reported(ctx, &d, sigma_mm, None, plant);
    fit_both(ctx, &p1, &p2)
}

/// Synthetic Table 1: `per_cell` experiments per cell (numbered in Table 1's order), simulated with
/// the paper's protocol at `sigma_mm` with `plant`, truths from `truths` (`[floor-floor,
/// floor-ceiling, floor-wall]`, e.g. Table 1's) — for tests of the fit and the selection. Trial `k`
/// draws from `trial_rng(seed, k)`.
pub fn synthetic_experiments(
    seed: u64,
    per_cell: usize,
    sigma_mm: f64,
    plant: &PlantedEffects,
    truths: &[Isometry3<f64>; 3],
) -> Vec<Experiment> {
    let mut out = Vec::new();
    let mut k = 0u64;
    for cell in PaperCell::ALL {
        let ctx = CellContext::new(cell, truths[cell.index()]);
        let mut made = 0;
        while made < per_cell {
            let mut rng = trial_rng(seed, k);
            k += 1;
            let Some(est) = simulate_experiment(&ctx, sigma_mm, plant, &mut rng) else {
                continue;
            };
            let (t1, r1) = paper_errors(cell, &ctx.truth, &est[0]);
            let (t2, r2) = paper_errors(cell, &ctx.truth, &est[1]);
            made += 1;
            out.push(Experiment {
                number: out.len() as u32 + 1,
                cell,
                b1_from_b2_true: ctx.truth,
                estimate: est,
                e_tran_mm: [t1, t2],
                e_rot_deg: [r1, r2],
            });
        }
    }
    out
}

/// Simulated error components of one cell at σ = 1 mm (linear representation, see the module doc).
#[derive(Debug, Clone)]
pub(super) struct CellSim {
    pub(super) ctx: CellContext,
    /// Noise-free error components per method, per trial.
    pub(super) bias: [Vec<ErrorComponents>; 2],
    /// Error components per mm of σ, per method, per trial.
    pub(super) slope: [Vec<ErrorComponents>; 2],
    /// Covariance of the generic signed error at σ = 1 mm from the noise across the approach axis.
    pub(super) cov_perp: Matrix6<f64>,
    /// Same from the noise along the approach axis.
    pub(super) cov_along: Matrix6<f64>,
    /// `(cov_perp, cov_along)` for each tetrahedron edge of [`SPREAD_GRID_M`].
    pub(super) spread_covs: Vec<(Matrix6<f64>, Matrix6<f64>)>,
}

/// Covariances (across, along the approach axis) of the generic signed error at σ = 1 mm for a
/// tetrahedron of edge `spread_m`.
pub(super) fn generic_covariances(
    ctx: &CellContext,
    seed: u64,
    trials: usize,
    spread_m: f64,
    stream: u64,
) -> (Matrix6<f64>, Matrix6<f64>) {
    let none = PlantedEffects::default();
    let outs: Vec<Option<(ErrorComponents, ErrorComponents)>> = (0..trials)
        .into_par_iter()
        .map(|t| {
            let mut rng = trial_rng(seed, stream + t as u64);
            let d = draw(ctx, spread_m, &mut rng);
            let comp = |sigma: f64, part: Option<bool>| -> Option<ErrorComponents> {
                let (p1, p2) = reported(ctx, &d, sigma, part, &none);
                let est = generic_fast(&p1, &p2, false)?;
                Some(components(ctx.cell, &ctx.truth, &est))
            };
            let c0 = comp(0.0, None)?;
            Some((
                comp(1.0, Some(false))?.minus(&c0),
                comp(1.0, Some(true))?.minus(&c0),
            ))
        })
        .collect();
    let (p, a): (Vec<ErrorComponents>, Vec<ErrorComponents>) = outs.into_iter().flatten().unzip();
    (cov6(&p), cov6(&a))
}

/// Sample covariance of the signed errors `(Δ mm, ω mrad)`.
pub(super) fn cov6(samples: &[ErrorComponents]) -> Matrix6<f64> {
    let n = samples.len().max(2) as f64;
    let mut mean = Vector6::zeros();
    for s in samples {
        mean += s.signed();
    }
    mean /= n;
    let mut c = Matrix6::zeros();
    for s in samples {
        let v = s.signed() - mean;
        c += v * v.transpose();
    }
    c / (n - 1.0)
}

/// One trial's error components at σ = 1 mm (the linear representation).
struct TrialComponents {
    /// Noise-free errors, `[generic, constrained]`.
    bias: [ErrorComponents; 2],
    /// Errors per mm of σ, `[generic, constrained]`.
    slope: [ErrorComponents; 2],
    /// Generic error per mm of σ from the noise across the approach axis.
    perp: ErrorComponents,
    /// Same from the noise along it.
    along: ErrorComponents,
}

impl CellSim {
    pub(super) fn build(ctx: CellContext, seed: u64, trials: usize) -> CellSim {
        let stream = (ctx.cell.index() as u64 + 1) << 40;
        let none = PlantedEffects::default();
        let outs: Vec<Option<TrialComponents>> = (0..trials)
            .into_par_iter()
            .map(|t| {
                let mut rng = trial_rng(seed, stream + t as u64);
                let d = draw(&ctx, PAPER_SPREAD_M, &mut rng);
                let comp = |sigma: f64, part: Option<bool>| -> Option<[ErrorComponents; 2]> {
                    let (p1, p2) = reported(&ctx, &d, sigma, part, &none);
                    let est = fit_both(&ctx, &p1, &p2)?;
                    Some(est.map(|e| components(ctx.cell, &ctx.truth, &e)))
                };
                let c0 = comp(0.0, None)?;
                let c1 = comp(1.0, None)?;
                let cp = comp(1.0, Some(false))?;
                let ca = comp(1.0, Some(true))?;
                Some(TrialComponents {
                    bias: c0,
                    slope: [c1[0].minus(&c0[0]), c1[1].minus(&c0[1])],
                    perp: cp[0].minus(&c0[0]),
                    along: ca[0].minus(&c0[0]),
                })
            })
            .collect();
        let mut bias = [Vec::new(), Vec::new()];
        let mut slope = [Vec::new(), Vec::new()];
        let mut perp = Vec::new();
        let mut along = Vec::new();
        for o in outs.into_iter().flatten() {
            for m in 0..2 {
                bias[m].push(o.bias[m]);
                slope[m].push(o.slope[m]);
            }
            perp.push(o.perp);
            along.push(o.along);
        }
        let (cov_perp, cov_along) = (cov6(&perp), cov6(&along));
        let spread_covs = SPREAD_GRID_M
            .iter()
            .enumerate()
            .map(|(g, &edge)| {
                if g == SPREAD_BASE {
                    (cov_perp, cov_along)
                } else {
                    generic_covariances(&ctx, seed, trials, edge, stream + ((g as u64 + 1) << 32))
                }
            })
            .collect();
        CellSim {
            ctx,
            bias,
            slope,
            cov_perp,
            cov_along,
            spread_covs,
        }
    }

    /// Simulated `(e_tran mm, e_rot deg)` of every trial at `sigma_mm`.
    pub(super) fn errors_at(&self, method: PaperMethod, sigma_mm: f64) -> Vec<(f64, f64)> {
        let m = method.index();
        self.bias[m]
            .iter()
            .zip(&self.slope[m])
            .map(|(b, s)| {
                let c = b.plus_scaled(s, sigma_mm);
                metrics(self.ctx.cell, &c)
            })
            .collect()
    }
}

pub(super) fn build_sims(truths: &[Isometry3<f64>; 3], seed: u64, trials: usize) -> Vec<CellSim> {
    PaperCell::ALL
        .iter()
        .map(|&c| CellSim::build(CellContext::new(c, truths[c.index()]), seed, trials))
        .collect()
}

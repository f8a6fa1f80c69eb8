//! The simulation beside the paper's Table 1 (Gan et al. 2014), and the diagnosis of what it gets
//! wrong (`handclasp paper diagnose`).
//!
//! # The simulated protocol (geometry mode)
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
//!
//! # Metrics as the paper reads them
//! `e_tran` is eq 34 (∞-norm, mm). `e_rot` (degrees): for the floor–wall cell, eq 33 on ZYZ angles
//! read on the branch nearest the truth; for the floor–floor and floor–ceiling cells (θ ≈ 0° or
//! 180°, the ZYZ singularity) the paper prints φ = 0 and a signed θ, i.e. it reports
//! `max(tilt, |yaw error|)` (tilt: angle between the estimated and true base-2 z axes), which is what
//! is simulated. The published `calib1` angles of those two cells therefore lose the tilt's
//! direction, so the signed analysis uses only their yaw (rotation about b1's z axis).
//!
//! # The σ fit (study)
//! For a set of (cell, method) groups sharing one σ, the log-likelihood of the published
//! `(e_tran, e_rot)` pairs is a Gaussian kernel density estimate of the simulated
//! `(ln e_tran, ln e_rot)` (full-covariance bandwidth, Scott's factor `n^(−1/3)` on the covariance),
//! with the Jacobian `1/(e_tran·e_rot)`. σ̂ maximises it (grid in ln σ, then golden section); the 95 %
//! interval is the profile-likelihood set `2·(ℓ̂ − ℓ(σ)) ≤ 3.84`. A likelihood-ratio test compares
//! one σ for all cells with one σ per cell (per method; χ² with 2 degrees of freedom). Whether both
//! methods share σ is tested by parametric bootstrap of `ln(σ̂_constrained/σ̂_generic)` (the two
//! methods use the same points, so their likelihoods are not independent and cannot be added).
//!
//! # The diagnosis (signed errors)
//! The signed error of the generic estimate is `y = (T_est − T_true [mm], log(R_est·R_trueᵀ) [mrad])`
//! in b1 axes (all six components for floor–wall; translation and yaw for the other two cells). The
//! baseline model is `y ~ N(0, σ²·Σ_cell)` with `Σ_cell` the simulated covariance at σ = 1 mm.
//! Candidate extended models ([`Candidate`]) add a mean `J·β` (exact, layout-independent effects of
//! a physical cause on the estimate: a tip length error along the approach axis, a contact bias per
//! cell, robot 1's or robot 2's joint-1 offset) and/or change the covariance (anisotropic alignment
//! noise, one σ per cell, a wider or narrower layout on [`SPREAD_GRID_M`], a contact offset constant
//! within an experiment). A mount tilt is not a free candidate: the CMM truth already carries it
//! (floor–wall θ = 89.874°), and the simulated constrained method inherits it. Each is fitted by maximum likelihood (generalised least squares for β, closed
//! form for σ², golden section for the anisotropy), and scored by the likelihood ratio against the
//! baseline, AIC, and leave-one-experiment-out held-out log-likelihood (refit on the other 14
//! experiments — 4 of the held-out one's cell — and score the held-out one). Forward selection
//! accepts a candidate when its likelihood-ratio p-value is below 0.05 / (number of candidates
//! tried) and its AIC is below the current model's, choosing among those the best held-out score
//! (which must beat the current model's); it stops when none qualifies.

use crate::layout::{teach_points_into, Layout};
use crate::placement::{Placement, FLOOR_CEILING, FLOOR_FLOOR, FLOOR_WALL};
use crate::trial_rng;
use calib_core::paper::{table1, Table1Row};
use calib_core::stats::{chi2_sf, maximize_log_1d, quantile, Maximize1dOptions, CHI2_1_95};
use calib_core::{
    generic_fast, paper_fast, wrap_angle, zyz_from_rotation, zyz_nearest, CalibError, MountPair,
};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix6, Point3, Rotation3, Vector3, Vector6};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;

/// Handclasp points per experiment in the paper.
pub const PAPER_POINTS: usize = 4;
/// Edge of the simulated teach-point tetrahedron, m (the paper: points ≥ 1 m apart).
pub const PAPER_SPREAD_M: f64 = 1.0;
/// Default Monte Carlo trials per cell.
pub const DEFAULT_TRIALS: usize = 2000;
/// Default parametric-bootstrap replicates of the methods-share-σ test.
pub const DEFAULT_BOOTSTRAP: usize = 40;
/// Default seed.
pub const DEFAULT_SEED: u64 = 2014;
/// Fewest trials accepted (the kernel density and the 5–95 % band need a few hundred).
pub const MIN_TRIALS: usize = 200;
/// Significance level of the tests and of the selection (before Bonferroni).
pub const ALPHA: f64 = 0.05;
/// Search range of σ, mm (the fit reports when an interval end reaches it).
pub const SIGMA_RANGE_MM: [f64; 2] = [0.05, 50.0];
/// Search range of the anisotropy factor (σ along the approach axis / σ across it).
pub const ANISOTROPY_RANGE: [f64; 2] = [0.1, 10.0];
/// Tetrahedron edges tried by the `layout_spread` candidate, m (the paper asks for ≥ 1 m; the
/// baseline uses [`PAPER_SPREAD_M`], index [`SPREAD_BASE`]).
pub const SPREAD_GRID_M: [f64; 6] = [0.8, 1.0, 1.25, 1.5, 1.75, 2.0];
/// Index of [`PAPER_SPREAD_M`] in [`SPREAD_GRID_M`].
pub const SPREAD_BASE: usize = 1;
/// Lower and upper quantile of the simulated band.
pub const BAND: [f64; 2] = [0.05, 0.95];

const MM_PER_M: f64 = 1000.0;
const MRAD_PER_RAD: f64 = 1000.0;

/// Errors of the paper study.
#[derive(Debug, thiserror::Error)]
pub enum PaperError {
    /// Table 1 could not be read.
    #[error("paper Table 1: {0}")]
    Table(#[from] CalibError),
    /// An option is out of range; the message says what would work.
    #[error("paper study option {option}: {message}")]
    Option {
        /// The option's name.
        option: &'static str,
        /// What is wrong and what would work.
        message: String,
    },
    /// The experiments given are not usable; the message says why.
    #[error("paper experiments: {0}")]
    Experiments(String),
}

/// One of the paper's three cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PaperCell {
    /// Both robots on the floor (experiments 1–5).
    FloorFloor,
    /// Robot 2 hanging from the ceiling (experiments 6–10).
    FloorCeiling,
    /// Robot 2 on a wall (experiments 11–15).
    FloorWall,
}

impl PaperCell {
    /// The cells in Table 1's order.
    pub const ALL: [PaperCell; 3] = [
        PaperCell::FloorFloor,
        PaperCell::FloorCeiling,
        PaperCell::FloorWall,
    ];

    /// Table 1's label (`floor-floor`, `floor-ceiling`, `floor-wall`).
    pub fn label(self) -> &'static str {
        match self {
            PaperCell::FloorFloor => "floor-floor",
            PaperCell::FloorCeiling => "floor-ceiling",
            PaperCell::FloorWall => "floor-wall",
        }
    }

    /// Parses Table 1's label.
    pub fn from_label(text: &str) -> Option<PaperCell> {
        PaperCell::ALL
            .into_iter()
            .find(|c| c.label() == text.trim())
    }

    /// The cell's mounts, truth and teach-point centre ([`crate::placement`]).
    pub fn placement(self) -> Placement {
        match self {
            PaperCell::FloorFloor => FLOOR_FLOOR,
            PaperCell::FloorCeiling => FLOOR_CEILING,
            PaperCell::FloorWall => FLOOR_WALL,
        }
    }

    /// The mount pair.
    pub fn mounts(self) -> MountPair {
        self.placement().mounts
    }

    fn index(self) -> usize {
        match self {
            PaperCell::FloorFloor => 0,
            PaperCell::FloorCeiling => 1,
            PaperCell::FloorWall => 2,
        }
    }

    /// Signed-error components observable from the published estimates: indices into
    /// `(Δx, Δy, Δz [mm], ωx, ωy, ωz [mrad])`. Floor–floor and floor–ceiling: translation and yaw.
    pub fn observed_dims(self) -> &'static [usize] {
        match self {
            PaperCell::FloorWall => &[0, 1, 2, 3, 4, 5],
            _ => &[0, 1, 2, 5],
        }
    }
}

/// The two methods of Table 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PaperMethod {
    /// The generic 4-point method (calib1, Ĥ1).
    Generic,
    /// The paper's installation-constrained method (calib2, Ĥ2).
    Constrained,
}

impl PaperMethod {
    /// Both methods.
    pub const ALL: [PaperMethod; 2] = [PaperMethod::Generic, PaperMethod::Constrained];

    /// `generic` or `constrained`.
    pub fn name(self) -> &'static str {
        match self {
            PaperMethod::Generic => "generic",
            PaperMethod::Constrained => "constrained",
        }
    }

    fn index(self) -> usize {
        match self {
            PaperMethod::Generic => 0,
            PaperMethod::Constrained => 1,
        }
    }
}

/// One experiment: the truth and the two estimates (published or simulated), and their errors.
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Experiment number (Table 1: 1..=15).
    pub number: u32,
    /// The cell.
    pub cell: PaperCell,
    /// True `b1_from_b2` (m, rad).
    pub b1_from_b2_true: Isometry3<f64>,
    /// Estimates of `b1_from_b2`: `[generic, constrained]`.
    pub estimate: [Isometry3<f64>; 2],
    /// e_tran of `[generic, constrained]`, mm (eq 34).
    pub e_tran_mm: [f64; 2],
    /// e_rot of `[generic, constrained]`, degrees (as the paper reads it, see the module doc).
    pub e_rot_deg: [f64; 2],
}

impl Experiment {
    /// From a Table 1 row (published e_tran/e_rot kept as printed). `None` for an unknown cell label.
    pub fn from_table_row(row: &Table1Row) -> Option<Experiment> {
        Some(Experiment {
            number: row.experiment,
            cell: PaperCell::from_label(&row.mounts)?,
            b1_from_b2_true: row.truth.isometry(),
            estimate: [row.calib1.isometry(), row.calib2.isometry()],
            e_tran_mm: [row.e_tran1_mm, row.e_tran2_mm],
            e_rot_deg: [row.e_rot1_deg, row.e_rot2_deg],
        })
    }

    /// Signed error of the generic estimate, `(Δx, Δy, Δz [mm], ωx, ωy, ωz [mrad])`, b1 axes:
    /// `T_est − T_true` and `log(R_est·R_trueᵀ)`.
    pub fn signed_generic(&self) -> [f64; 6] {
        let c = components(self.cell, &self.b1_from_b2_true, &self.estimate[0]);
        [c[0], c[1], c[2], c[3], c[4], c[5]]
    }
}

/// Table 1 as [`Experiment`]s.
pub fn table1_experiments() -> Result<Vec<Experiment>, PaperError> {
    table1()?
        .iter()
        .map(|r| {
            Experiment::from_table_row(r).ok_or_else(|| {
                PaperError::Experiments(format!(
                    "experiment {}: unknown mounts `{}` (expected floor-floor, floor-ceiling or floor-wall)",
                    r.experiment, r.mounts
                ))
            })
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Error components and metrics
// ---------------------------------------------------------------------------------------------

/// Error components of `est` against `truth`: `[Δx, Δy, Δz (mm), ωx, ωy, ωz (mrad, b1 axes),
/// Δφ, Δθ, Δψ (degrees, ZYZ read on the branch nearest the truth, wrapped)]`.
fn components(cell: PaperCell, truth: &Isometry3<f64>, est: &Isometry3<f64>) -> [f64; 9] {
    let dt = (est.translation.vector - truth.translation.vector) * MM_PER_M;
    let w = (est.rotation * truth.rotation.inverse()).scaled_axis() * MRAD_PER_RAD;
    let mut out = [dt.x, dt.y, dt.z, w.x, w.y, w.z, 0.0, 0.0, 0.0];
    if cell == PaperCell::FloorWall {
        let r_true = truth.rotation.to_rotation_matrix();
        let zt = zyz_from_rotation(&r_true);
        let ze = zyz_nearest(&est.rotation.to_rotation_matrix(), zt);
        for k in 0..3 {
            out[6 + k] = wrap_angle(ze[k] - zt[k]).to_degrees();
        }
    }
    out
}

/// `(e_tran mm, e_rot deg)` from error components (see the module doc for the paper's reading).
fn metrics(cell: PaperCell, c: &[f64; 9]) -> (f64, f64) {
    let e_tran = c[0].abs().max(c[1].abs()).max(c[2].abs());
    let e_rot = match cell {
        PaperCell::FloorWall => c[6].abs().max(c[7].abs()).max(c[8].abs()),
        _ => {
            let tilt = c[3].hypot(c[4]);
            tilt.max(c[5].abs()) / MRAD_PER_RAD * 180.0 / std::f64::consts::PI
        }
    };
    (e_tran, e_rot)
}

/// `(e_tran mm, e_rot deg)` of an estimate as the paper reads them.
pub fn paper_errors(cell: PaperCell, truth: &Isometry3<f64>, est: &Isometry3<f64>) -> (f64, f64) {
    metrics(cell, &components(cell, truth, est))
}

// ---------------------------------------------------------------------------------------------
// Simulation
// ---------------------------------------------------------------------------------------------

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
struct CellContext {
    cell: PaperCell,
    truth: Isometry3<f64>,
    centre: Point3<f64>,
    /// Approach axis of robot 1's tip at the handclasp, b1 (unit vector from base 1 toward base 2:
    /// the tips meet head-on along the line between the bases).
    approach: Vector3<f64>,
}

impl CellContext {
    fn new(cell: PaperCell, truth: Isometry3<f64>) -> CellContext {
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
struct Draw {
    p_b1: [Point3<f64>; PAPER_POINTS],
    p_b2: [Point3<f64>; PAPER_POINTS],
    noise: [Vector3<f64>; PAPER_POINTS],
    /// Unit-normal draw of the experiment's common contact offset.
    offset: Vector3<f64>,
}

fn draw(ctx: &CellContext, spread_m: f64, rng: &mut impl Rng) -> Draw {
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
fn reported(
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

fn fit_both(
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
fn simulate_experiment(
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

/// The truths of Table 1, `[floor-floor, floor-ceiling, floor-wall]`.
pub fn table1_truths() -> Result<[Isometry3<f64>; 3], PaperError> {
    truths_of(&table1_experiments()?)
}

fn truths_of(exps: &[Experiment]) -> Result<[Isometry3<f64>; 3], PaperError> {
    let mut out = [Isometry3::identity(); 3];
    for cell in PaperCell::ALL {
        let n = exps.iter().filter(|e| e.cell == cell).count();
        if n < 2 {
            return Err(PaperError::Experiments(format!(
                "cell {} has {n} experiment(s); at least 2 per cell are needed (Table 1 has 5)",
                cell.label()
            )));
        }
        out[cell.index()] = exps
            .iter()
            .find(|e| e.cell == cell)
            .map(|e| e.b1_from_b2_true)
            .unwrap_or_else(Isometry3::identity);
    }
    Ok(out)
}

/// Simulated error components of one cell at σ = 1 mm (linear representation, see the module doc).
#[derive(Debug, Clone)]
struct CellSim {
    ctx: CellContext,
    /// Noise-free error components per method, per trial.
    bias: [Vec<[f64; 9]>; 2],
    /// Error components per mm of σ, per method, per trial.
    slope: [Vec<[f64; 9]>; 2],
    /// Covariance of the generic signed error at σ = 1 mm from the noise across the approach axis.
    cov_perp: Matrix6<f64>,
    /// Same from the noise along the approach axis.
    cov_along: Matrix6<f64>,
    /// `(cov_perp, cov_along)` for each tetrahedron edge of [`SPREAD_GRID_M`].
    spread_covs: Vec<(Matrix6<f64>, Matrix6<f64>)>,
}

/// Covariances (across, along the approach axis) of the generic signed error at σ = 1 mm for a
/// tetrahedron of edge `spread_m`.
fn generic_covariances(
    ctx: &CellContext,
    seed: u64,
    trials: usize,
    spread_m: f64,
    stream: u64,
) -> (Matrix6<f64>, Matrix6<f64>) {
    let none = PlantedEffects::default();
    let outs: Vec<Option<([f64; 9], [f64; 9])>> = (0..trials)
        .into_par_iter()
        .map(|t| {
            let mut rng = trial_rng(seed, stream + t as u64);
            let d = draw(ctx, spread_m, &mut rng);
            let comp = |sigma: f64, part: Option<bool>| -> Option<[f64; 9]> {
                let (p1, p2) = reported(ctx, &d, sigma, part, &none);
                let est = generic_fast(&p1, &p2, false)?;
                Some(components(ctx.cell, &ctx.truth, &est))
            };
            let c0 = comp(0.0, None)?;
            Some((
                sub9(&comp(1.0, Some(false))?, &c0),
                sub9(&comp(1.0, Some(true))?, &c0),
            ))
        })
        .collect();
    let (p, a): (Vec<[f64; 9]>, Vec<[f64; 9]>) = outs.into_iter().flatten().unzip();
    (cov6(&p), cov6(&a))
}

fn sub9(a: &[f64; 9], b: &[f64; 9]) -> [f64; 9] {
    std::array::from_fn(|k| a[k] - b[k])
}

fn cov6(samples: &[[f64; 9]]) -> Matrix6<f64> {
    let n = samples.len().max(2) as f64;
    let mut mean = Vector6::zeros();
    for s in samples {
        mean += Vector6::from_fn(|k, _| s[k]);
    }
    mean /= n;
    let mut c = Matrix6::zeros();
    for s in samples {
        let v = Vector6::from_fn(|k, _| s[k]) - mean;
        c += v * v.transpose();
    }
    c / (n - 1.0)
}

impl CellSim {
    fn build(ctx: CellContext, seed: u64, trials: usize) -> CellSim {
        let stream = (ctx.cell.index() as u64 + 1) << 40;
        let none = PlantedEffects::default();
        type Out = ([[f64; 9]; 2], [[f64; 9]; 2], [f64; 9], [f64; 9]);
        let outs: Vec<Option<Out>> = (0..trials)
            .into_par_iter()
            .map(|t| {
                let mut rng = trial_rng(seed, stream + t as u64);
                let d = draw(&ctx, PAPER_SPREAD_M, &mut rng);
                let comp = |sigma: f64, part: Option<bool>| -> Option<[[f64; 9]; 2]> {
                    let (p1, p2) = reported(&ctx, &d, sigma, part, &none);
                    let est = fit_both(&ctx, &p1, &p2)?;
                    Some(est.map(|e| components(ctx.cell, &ctx.truth, &e)))
                };
                let c0 = comp(0.0, None)?;
                let c1 = comp(1.0, None)?;
                let cp = comp(1.0, Some(false))?;
                let ca = comp(1.0, Some(true))?;
                Some((
                    c0,
                    [sub9(&c1[0], &c0[0]), sub9(&c1[1], &c0[1])],
                    sub9(&cp[0], &c0[0]),
                    sub9(&ca[0], &c0[0]),
                ))
            })
            .collect();
        let mut bias = [Vec::new(), Vec::new()];
        let mut slope = [Vec::new(), Vec::new()];
        let mut perp = Vec::new();
        let mut along = Vec::new();
        for (b, s, p, a) in outs.into_iter().flatten() {
            for m in 0..2 {
                bias[m].push(b[m]);
                slope[m].push(s[m]);
            }
            perp.push(p);
            along.push(a);
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
    fn errors_at(&self, method: PaperMethod, sigma_mm: f64) -> Vec<(f64, f64)> {
        let m = method.index();
        self.bias[m]
            .iter()
            .zip(&self.slope[m])
            .map(|(b, s)| {
                let c: [f64; 9] = std::array::from_fn(|k| b[k] + sigma_mm * s[k]);
                metrics(self.ctx.cell, &c)
            })
            .collect()
    }
}

fn build_sims(truths: &[Isometry3<f64>; 3], seed: u64, trials: usize) -> Vec<CellSim> {
    PaperCell::ALL
        .iter()
        .map(|&c| CellSim::build(CellContext::new(c, truths[c.index()]), seed, trials))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Kernel density likelihood and the σ fit
// ---------------------------------------------------------------------------------------------

/// Log-likelihood of observed `(e_tran, e_rot)` pairs under simulated ones: Gaussian KDE on the logs
/// (full covariance bandwidth `n^(−1/3)·Cov`), with the Jacobian of the log transform.
fn kde_loglik(sim: &[(f64, f64)], obs: &[(f64, f64)]) -> f64 {
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
struct Group<'a> {
    sim: &'a CellSim,
    method: PaperMethod,
    obs: Vec<(f64, f64)>,
}

fn group_loglik(groups: &[Group<'_>], sigma_mm: f64) -> f64 {
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

fn fit_sigma(groups: &[Group<'_>]) -> SigmaFit {
    fit_sigma_opt(groups, true)
}

/// As [`fit_sigma`]; without the interval (NaN) when `with_ci` is false (bootstrap replicates).
fn fit_sigma_opt(groups: &[Group<'_>], with_ci: bool) -> SigmaFit {
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

// ---------------------------------------------------------------------------------------------
// Statistics helpers
// ---------------------------------------------------------------------------------------------

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
    fn of(values: impl IntoIterator<Item = f64>) -> Band {
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

// ---------------------------------------------------------------------------------------------
// The study (item 1)
// ---------------------------------------------------------------------------------------------

/// Options of the paper study and diagnosis (also the command-line flags of
/// `handclasp paper diagnose` and `sim-cell paper`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, clap::Args)]
pub struct StudyOptions {
    /// Seed of every Monte Carlo draw (same seed, same report; trial `k` of a cell uses
    /// `trial_rng(seed, …)`).
    #[arg(long, default_value_t = DEFAULT_SEED)]
    pub seed: u64,
    /// Simulated experiments per cell (at least 200, `MIN_TRIALS`).
    #[arg(long, default_value_t = DEFAULT_TRIALS)]
    pub trials: usize,
    /// Parametric-bootstrap replicates for the "both methods share σ" test (0 skips it).
    #[arg(long, default_value_t = DEFAULT_BOOTSTRAP)]
    pub bootstrap: usize,
}

impl Default for StudyOptions {
    fn default() -> Self {
        StudyOptions {
            seed: DEFAULT_SEED,
            trials: DEFAULT_TRIALS,
            bootstrap: DEFAULT_BOOTSTRAP,
        }
    }
}

impl StudyOptions {
    /// Checks the options.
    pub fn validate(&self) -> Result<(), PaperError> {
        if self.trials < MIN_TRIALS {
            return Err(PaperError::Option {
                option: "trials",
                message: format!(
                    "{} trials per cell are too few for the kernel density and the 5–95 % band; use at least {MIN_TRIALS} (default {DEFAULT_TRIALS})",
                    self.trials
                ),
            });
        }
        if self.trials > 1_000_000 {
            return Err(PaperError::Option {
                option: "trials",
                message: format!(
                    "{} trials per cell would take very long; use at most 1000000",
                    self.trials
                ),
            });
        }
        if self.bootstrap > 10_000 {
            return Err(PaperError::Option {
                option: "bootstrap",
                message: format!(
                    "{} replicates would take very long; use at most 10000",
                    self.bootstrap
                ),
            });
        }
        Ok(())
    }
}

/// σ̂ of one cell and method.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CellSigma {
    /// The cell.
    pub cell: PaperCell,
    /// The method.
    pub method: PaperMethod,
    /// The fit on this cell's 5 published pairs.
    pub fit: SigmaFit,
}

/// Likelihood-ratio test of one σ for all cells against one σ per cell, for one method.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CommonSigmaTest {
    /// The method.
    pub method: PaperMethod,
    /// σ̂ shared by the three cells.
    pub common: SigmaFit,
    /// Sum of the per-cell maximised log-likelihoods.
    pub loglik_per_cell: f64,
    /// `2·(ℓ_per_cell − ℓ_common)`.
    pub statistic: f64,
    /// Degrees of freedom (2).
    pub df: usize,
    /// p-value (χ²).
    pub p_value: f64,
}

/// Parametric-bootstrap test that both methods share σ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MethodsShareSigma {
    /// `ln(σ̂_constrained / σ̂_generic)` on the published table.
    pub log_ratio: f64,
    /// Its 5–95 % band under the isotropic model at the generic σ̂ (bootstrap).
    pub band: Band,
    /// Two-sided bootstrap p-value.
    pub p_value: f64,
    /// Replicates used.
    pub replicates: usize,
}

/// One published experiment and method beside the simulation at the method's common σ̂.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StudyRow {
    /// Experiment number.
    pub experiment: u32,
    /// The cell.
    pub cell: PaperCell,
    /// The method.
    pub method: PaperMethod,
    /// Published e_tran, mm.
    pub e_tran_mm: f64,
    /// Published e_rot, degrees.
    pub e_rot_deg: f64,
    /// Simulated e_tran at σ̂ (the method's common σ), mm.
    pub sim_e_tran_mm: Band,
    /// Simulated e_rot at σ̂, degrees.
    pub sim_e_rot_deg: Band,
    /// The published e_tran lies outside the 5–95 % band.
    pub e_tran_outside: bool,
    /// The published e_rot lies outside the 5–95 % band.
    pub e_rot_outside: bool,
}

/// The simulation beside Table 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperStudy {
    /// Options used.
    pub options: StudyOptions,
    /// σ̂ per cell and method.
    pub per_cell: Vec<CellSigma>,
    /// One σ per method for all cells, with the test against one per cell.
    pub common: Vec<CommonSigmaTest>,
    /// Whether both methods share σ (absent when `bootstrap = 0`).
    pub methods_share_sigma: Option<MethodsShareSigma>,
    /// Published vs simulated, per experiment and method.
    pub rows: Vec<StudyRow>,
    /// Number of published values outside their 5–95 % band (of `2·rows.len()`); about 10 % are
    /// expected by chance.
    pub outside_band: usize,
    /// What 5 experiments per cell can and cannot show.
    pub notes: Vec<String>,
}

fn groups_for<'a>(
    sims: &'a [CellSim],
    exps: &[Experiment],
    method: PaperMethod,
    cells: &[PaperCell],
) -> Vec<Group<'a>> {
    cells
        .iter()
        .map(|&c| Group {
            sim: &sims[c.index()],
            method,
            obs: exps
                .iter()
                .filter(|e| e.cell == c)
                .map(|e| (e.e_tran_mm[method.index()], e.e_rot_deg[method.index()]))
                .collect(),
        })
        .collect()
}

/// Runs the study on Table 1.
///
/// # Examples
/// ```no_run
/// let study = sim_cell::paper::run_paper_study(&sim_cell::paper::StudyOptions::default()).unwrap();
/// println!("{}", sim_cell::paper::render_text(&study));
/// ```
pub fn run_paper_study(opts: &StudyOptions) -> Result<PaperStudy, PaperError> {
    study_experiments(&table1_experiments()?, opts)
}

/// Runs the study on any set of experiments (Table 1 or synthetic), ≥ 2 per cell.
pub fn study_experiments(
    exps: &[Experiment],
    opts: &StudyOptions,
) -> Result<PaperStudy, PaperError> {
    opts.validate()?;
    let truths = truths_of(exps)?;
    let sims = build_sims(&truths, opts.seed, opts.trials);
    Ok(study_with(exps, opts, &sims, &truths))
}

fn study_with(
    exps: &[Experiment],
    opts: &StudyOptions,
    sims: &[CellSim],
    truths: &[Isometry3<f64>; 3],
) -> PaperStudy {
    let mut per_cell = Vec::new();
    let mut common = Vec::new();
    let mut rows = Vec::new();
    let mut common_sigma = [0.0; 2];
    for method in PaperMethod::ALL {
        let mut ll_cells = 0.0;
        for cell in PaperCell::ALL {
            let fit = fit_sigma(&groups_for(sims, exps, method, &[cell]));
            ll_cells += fit.loglik;
            per_cell.push(CellSigma { cell, method, fit });
        }
        let fit = fit_sigma(&groups_for(sims, exps, method, &PaperCell::ALL));
        common_sigma[method.index()] = fit.sigma_mm;
        let statistic = (2.0 * (ll_cells - fit.loglik)).max(0.0);
        common.push(CommonSigmaTest {
            method,
            common: fit,
            loglik_per_cell: ll_cells,
            statistic,
            df: 2,
            p_value: chi2_sf(statistic, 2),
        });
        for cell in PaperCell::ALL {
            let sim = sims[cell.index()].errors_at(method, fit.sigma_mm);
            let bt = Band::of(sim.iter().map(|x| x.0));
            let br = Band::of(sim.iter().map(|x| x.1));
            for e in exps.iter().filter(|e| e.cell == cell) {
                let (t, r) = (e.e_tran_mm[method.index()], e.e_rot_deg[method.index()]);
                rows.push(StudyRow {
                    experiment: e.number,
                    cell,
                    method,
                    e_tran_mm: t,
                    e_rot_deg: r,
                    sim_e_tran_mm: bt,
                    sim_e_rot_deg: br,
                    e_tran_outside: bt.outside(t),
                    e_rot_outside: br.outside(r),
                });
            }
        }
    }
    rows.sort_by_key(|r| (r.experiment, r.method.index()));
    let methods_share_sigma = (opts.bootstrap > 0).then(|| {
        let observed = (common_sigma[1] / common_sigma[0]).ln();
        let per_cell_n: usize = PaperCell::ALL
            .iter()
            .map(|&c| exps.iter().filter(|e| e.cell == c).count())
            .max()
            .unwrap_or(5);
        let ratios: Vec<f64> = (0..opts.bootstrap)
            .into_par_iter()
            .map(|b| {
                let syn = synthetic_experiments(
                    opts.seed
                        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                        .wrapping_add(b as u64 + 1),
                    per_cell_n,
                    common_sigma[0],
                    &PlantedEffects::default(),
                    truths,
                );
                let s1 = fit_sigma_opt(
                    &groups_for(sims, &syn, PaperMethod::Generic, &PaperCell::ALL),
                    false,
                );
                let s2 = fit_sigma_opt(
                    &groups_for(sims, &syn, PaperMethod::Constrained, &PaperCell::ALL),
                    false,
                );
                (s2.sigma_mm / s1.sigma_mm).ln()
            })
            .collect();
        let band = Band::of(ratios.iter().copied());
        let below = ratios.iter().filter(|&&r| r <= observed).count() as f64;
        let above = ratios.iter().filter(|&&r| r >= observed).count() as f64;
        let n = ratios.len() as f64;
        let p_value = (2.0 * ((below + 1.0) / (n + 1.0)).min((above + 1.0) / (n + 1.0))).min(1.0);
        MethodsShareSigma {
            log_ratio: observed,
            band,
            p_value,
            replicates: ratios.len(),
        }
    });
    let outside_band = rows
        .iter()
        .map(|r| r.e_tran_outside as usize + r.e_rot_outside as usize)
        .sum();
    let notes = vec![
        "Each cell has only 5 experiments: a per-cell σ̂ has a wide interval (see ci95), and a per-cell σ ratio below about 2 cannot be told from chance.".to_string(),
        "The layout (a 1 m regular tetrahedron around the cell's teach-point centre) and the isotropic alignment noise are assumptions: the paper publishes no raw points.".to_string(),
        "The constrained method's errors include the part of the CMM truth outside its mount family (floor-wall: θ = 89.874° vs 90°, a 0.126° floor under e_rot2); the simulation keeps it.".to_string(),
        format!("About {:.0} % of published values fall outside a correct model's 5–95 % band by chance.", 100.0 * (1.0 - (BAND[1] - BAND[0]))),
    ];
    PaperStudy {
        options: *opts,
        per_cell,
        common,
        methods_share_sigma,
        rows,
        outside_band,
        notes,
    }
}

/// Readable text of the study.
pub fn render_text(study: &PaperStudy) -> String {
    let mut s = String::new();
    let o = &study.options;
    let _ = writeln!(
        s,
        "The simulation beside the paper's Table 1 (geometry mode: 4 points, 1 m tetrahedron, isotropic alignment noise; seed {}, {} trials per cell)",
        o.seed, o.trials
    );
    let _ = writeln!(s, "\nσ̂ of the tip-alignment noise (maximum likelihood of the published e_tran/e_rot; 95 % profile interval), mm:");
    let _ = writeln!(
        s,
        "{:<14} {:>24} {:>24}",
        "cell", "generic (calib1)", "constrained (calib2)"
    );
    let fmt = |f: &SigmaFit| {
        format!(
            "{:.2} [{:.2}, {:.2}]",
            f.sigma_mm, f.ci95_mm[0], f.ci95_mm[1]
        )
    };
    for cell in PaperCell::ALL {
        let get = |m: PaperMethod| {
            study
                .per_cell
                .iter()
                .find(|c| c.cell == cell && c.method == m)
                .map(|c| fmt(&c.fit))
                .unwrap_or_default()
        };
        let _ = writeln!(
            s,
            "{:<14} {:>24} {:>24}",
            cell.label(),
            get(PaperMethod::Generic),
            get(PaperMethod::Constrained)
        );
    }
    for t in &study.common {
        let _ = writeln!(
            s,
            "{:<14} one σ for all cells: {} ; vs one per cell: LR = {:.2} (df {}), p = {:.3} → {}",
            t.method.name(),
            fmt(&t.common),
            t.statistic,
            t.df,
            t.p_value,
            if t.p_value < ALPHA {
                "the cells need different σ"
            } else {
                "one σ explains all cells"
            }
        );
    }
    if let Some(m) = &study.methods_share_sigma {
        let _ = writeln!(
            s,
            "both methods share σ? ln(σ̂_constrained/σ̂_generic) = {:.3}, expected band [{:.3}, {:.3}] under one σ ({} bootstrap replicates), p = {:.3} → {}",
            m.log_ratio,
            m.band.p05,
            m.band.p95,
            m.replicates,
            m.p_value,
            if m.p_value < ALPHA { "no: the methods' errors do not fit one noise level" } else { "consistent with one σ" }
        );
    }
    let _ = writeln!(s, "\nPublished vs simulated at the method's common σ̂ (median [5 %, 95 %]); * = outside the band:");
    let _ = writeln!(
        s,
        "{:>3} {:<14} {:<12} {:>7} {:>24} {:>8} {:>26}",
        "exp", "cell", "method", "e_tran", "sim e_tran mm", "e_rot", "sim e_rot °"
    );
    for r in &study.rows {
        let _ = writeln!(
            s,
            "{:>3} {:<14} {:<12} {:>6.1}{} {:>8.2} [{:>5.2}, {:>5.2}] {:>7.3}{} {:>8.3} [{:>6.3}, {:>6.3}]",
            r.experiment,
            r.cell.label(),
            r.method.name(),
            r.e_tran_mm,
            if r.e_tran_outside { '*' } else { ' ' },
            r.sim_e_tran_mm.p50,
            r.sim_e_tran_mm.p05,
            r.sim_e_tran_mm.p95,
            r.e_rot_deg,
            if r.e_rot_outside { '*' } else { ' ' },
            r.sim_e_rot_deg.p50,
            r.sim_e_rot_deg.p05,
            r.sim_e_rot_deg.p95,
        );
    }
    let _ = writeln!(
        s,
        "{} of {} published values lie outside their band ({:.0} expected by chance).",
        study.outside_band,
        2 * study.rows.len(),
        0.1 * 2.0 * study.rows.len() as f64
    );
    for n in &study.notes {
        let _ = writeln!(s, "note: {n}");
    }
    s
}

// ---------------------------------------------------------------------------------------------
// The diagnosis (item 2): signed errors, candidate causes, selection
// ---------------------------------------------------------------------------------------------

/// A candidate extension of the isotropic-noise model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Candidate {
    /// A tip length error (sum of both tips, mm) along the approach axis: a handclasp cannot see it
    /// in either robot, it shifts every estimate by `−d·a` (a: unit vector from base 1 to base 2).
    /// One parameter for all cells (the same pins were used).
    TipOffset,
    /// A constant contact bias per cell (3 translations per cell, mm): any systematic contact error
    /// whose direction is unknown.
    ContactBiasPerCell,
    /// Robot 1's joint-1 zero offset (deg; true = reported + value): the estimate turns by −value
    /// about b1's z axis, its translation by `−value·ẑ×T`.
    R1Joint1Offset,
    /// Robot 2's joint-1 zero offset (deg): the estimate turns by +value about base 2's z axis, no
    /// translation change. One parameter for all cells.
    R2Joint1Offset,
    /// Robot 2's joint-1 offset per cell (deg): e.g. a gravity deflection of its S axis that depends
    /// on how it hangs (wall: the S axis carries the arm's weight).
    R2Joint1PerCell,
    /// Anisotropic alignment noise: σ along the approach axis = k·σ across it (parameter k).
    AnisotropicNoise,
    /// One noise σ per cell (2 extra parameters).
    SigmaPerCell,
    /// The teach points spread wider (or narrower) than the assumed 1 m tetrahedron: the edge is
    /// fitted on [`SPREAD_GRID_M`]. A wider layout shrinks the rotation errors, not the translation
    /// errors, like anisotropic noise does, so the two compete for the same signature.
    LayoutSpread,
    /// A contact (TCP) offset constant over an experiment's 4 points and random between experiments,
    /// N(0, τ²·I) mm: it moves the translation, not the rotation (e.g. a pin re-seated or the TCP
    /// re-taught between experiments). One parameter τ.
    ContactOffsetPerExperiment,
}

impl Candidate {
    /// All candidates, in report order.
    pub const ALL: [Candidate; 9] = [
        Candidate::TipOffset,
        Candidate::ContactBiasPerCell,
        Candidate::R1Joint1Offset,
        Candidate::R2Joint1Offset,
        Candidate::R2Joint1PerCell,
        Candidate::AnisotropicNoise,
        Candidate::SigmaPerCell,
        Candidate::LayoutSpread,
        Candidate::ContactOffsetPerExperiment,
    ];

    /// The name used in reports and JSON.
    pub fn name(self) -> &'static str {
        match self {
            Candidate::TipOffset => "tip_offset",
            Candidate::ContactBiasPerCell => "contact_bias_per_cell",
            Candidate::R1Joint1Offset => "r1_joint1_offset",
            Candidate::R2Joint1Offset => "r2_joint1_offset",
            Candidate::R2Joint1PerCell => "r2_joint1_offset_per_cell",
            Candidate::AnisotropicNoise => "anisotropic_noise",
            Candidate::SigmaPerCell => "sigma_per_cell",
            Candidate::LayoutSpread => "layout_spread",
            Candidate::ContactOffsetPerExperiment => "contact_offset_per_experiment",
        }
    }

    /// One line on what it models.
    pub fn description(self) -> &'static str {
        match self {
            Candidate::TipOffset => {
                "tip length error along the approach axis (both tips summed), one for all cells"
            }
            Candidate::ContactBiasPerCell => {
                "constant contact/translation bias per cell, direction free"
            }
            Candidate::R1Joint1Offset => "robot 1 joint-1 zero offset (rotation about b1 z)",
            Candidate::R2Joint1Offset => {
                "robot 2 joint-1 zero offset (rotation about b2 z), one for all cells"
            }
            Candidate::R2Joint1PerCell => {
                "robot 2 joint-1 offset/deflection per cell (mount-dependent gravity load)"
            }
            Candidate::AnisotropicNoise => {
                "alignment noise larger (or smaller) along the approach axis"
            }
            Candidate::SigmaPerCell => "a different noise level per cell",
            Candidate::LayoutSpread => {
                "teach points spread wider or narrower than a 1 m tetrahedron"
            }
            Candidate::ContactOffsetPerExperiment => {
                "contact/TCP offset constant within an experiment, random between experiments"
            }
        }
    }

    fn index(self) -> usize {
        Candidate::ALL.iter().position(|c| *c == self).unwrap_or(0)
    }

    /// Candidates that cannot be combined with this one (nested or collinear).
    fn family(self) -> u8 {
        match self {
            Candidate::TipOffset | Candidate::ContactBiasPerCell => 0,
            Candidate::R1Joint1Offset => 1,
            Candidate::R2Joint1Offset | Candidate::R2Joint1PerCell => 2,
            Candidate::AnisotropicNoise => 3,
            Candidate::SigmaPerCell => 4,
            Candidate::LayoutSpread => 5,
            Candidate::ContactOffsetPerExperiment => 6,
        }
    }
}

/// One signed observation (generic estimate).
struct Obs {
    cell: PaperCell,
    /// `(Δ mm, ω mrad)` on the cell's observed dims.
    y: DVector<f64>,
    /// True `b1_from_b2` of the experiment.
    truth: Isometry3<f64>,
    approach: Vector3<f64>,
    cov_perp: DMatrix<f64>,
    cov_along: DMatrix<f64>,
    /// `(cov_perp, cov_along)` per tetrahedron edge of [`SPREAD_GRID_M`].
    covs: Vec<(DMatrix<f64>, DMatrix<f64>)>,
    /// Per candidate (in [`Candidate::ALL`] order): parameter names (qualified, unit, report scale)
    /// and mean columns per unit parameter (6 rows: Δ mm, ω mrad).
    columns: Vec<ParamColumns>,
}

type ParamColumns = (Vec<(String, &'static str, f64)>, Vec<Vector6<f64>>);

fn restrict(m: &Matrix6<f64>, dims: &[usize]) -> DMatrix<f64> {
    DMatrix::from_fn(dims.len(), dims.len(), |i, j| m[(dims[i], dims[j])])
}

fn observations(exps: &[Experiment], sims: &[CellSim]) -> Vec<Obs> {
    exps.iter()
        .map(|e| {
            let dims = e.cell.observed_dims();
            let y6 = e.signed_generic();
            let sim = &sims[e.cell.index()];
            let mut o = Obs {
                cell: e.cell,
                y: DVector::from_iterator(dims.len(), dims.iter().map(|&d| y6[d])),
                truth: e.b1_from_b2_true,
                approach: sim.ctx.approach,
                cov_perp: restrict(&sim.cov_perp, dims),
                cov_along: restrict(&sim.cov_along, dims),
                covs: sim
                    .spread_covs
                    .iter()
                    .map(|(p, a)| (restrict(p, dims), restrict(a, dims)))
                    .collect(),
                columns: Vec::new(),
            };
            o.columns = Candidate::ALL
                .iter()
                .map(|&c| {
                    let mut names = Vec::new();
                    let mut cols = Vec::new();
                    for (n, u, sc, col) in columns(c, &o) {
                        names.push((format!("{}.{}", c.name(), n), u, sc));
                        cols.push(col);
                    }
                    (names, cols)
                })
                .collect();
            o
        })
        .collect()
}

/// Parameter columns of a candidate for one observation (6 rows: Δ mm, ω mrad), with names/units.
fn columns(c: Candidate, o: &Obs) -> Vec<(String, &'static str, f64, Vector6<f64>)> {
    // (name, unit, report scale: reported value = β·scale, column per unit β)
    let z = Vector3::z();
    let t_m = o.truth.translation.vector;
    let z2 = o.truth.rotation * z;
    let mrad_to_deg = 180.0 / std::f64::consts::PI / MRAD_PER_RAD;
    let cell_cols =
        |k: usize, col: Vector6<f64>| -> Vec<(String, &'static str, f64, Vector6<f64>)> {
            PaperCell::ALL
                .iter()
                .map(|&c| {
                    (
                        format!(
                            "{}[{}]",
                            ["x", "y", "z"].get(k).copied().unwrap_or("value"),
                            c.label()
                        ),
                        "",
                        1.0,
                        if c == o.cell { col } else { Vector6::zeros() },
                    )
                })
                .collect()
        };
    match c {
        Candidate::TipOffset => {
            let a = -o.approach;
            vec![(
                "tip".into(),
                "mm",
                1.0,
                Vector6::new(a.x, a.y, a.z, 0.0, 0.0, 0.0),
            )]
        }
        Candidate::ContactBiasPerCell => {
            let mut v = Vec::new();
            for k in 0..3 {
                let mut col = Vector6::zeros();
                col[k] = 1.0;
                for (n, _, s, c) in cell_cols(k, col) {
                    v.push((n, "mm", s, c));
                }
            }
            v
        }
        Candidate::R1Joint1Offset => {
            // value δ (mrad internally): ω = −δ·ẑ, ΔT = −δ·ẑ×T (T in m, δ in mrad → mm).
            let dt = -z.cross(&t_m);
            vec![(
                "offset".into(),
                "deg",
                mrad_to_deg,
                Vector6::new(dt.x, dt.y, dt.z, 0.0, 0.0, -1.0),
            )]
        }
        Candidate::R2Joint1Offset => vec![(
            "offset".into(),
            "deg",
            mrad_to_deg,
            Vector6::new(0.0, 0.0, 0.0, z2.x, z2.y, z2.z),
        )],
        Candidate::R2Joint1PerCell => PaperCell::ALL
            .iter()
            .map(|&c| {
                (
                    format!("offset[{}]", c.label()),
                    "deg",
                    mrad_to_deg,
                    if c == o.cell {
                        Vector6::new(0.0, 0.0, 0.0, z2.x, z2.y, z2.z)
                    } else {
                        Vector6::zeros()
                    },
                )
            })
            .collect(),
        Candidate::AnisotropicNoise
        | Candidate::SigmaPerCell
        | Candidate::LayoutSpread
        | Candidate::ContactOffsetPerExperiment => Vec::new(),
    }
}

/// A model: a set of candidates on top of the isotropic baseline.
#[derive(Debug, Clone)]
struct ModelFit {
    beta: Vec<f64>,
    beta_se: Vec<f64>,
    names: Vec<(String, &'static str, f64)>,
    sigma2: [f64; 3],
    shape: Shape,
    loglik: f64,
    n_params: usize,
}

/// Gaussian log-density of each observation under a fitted model.
fn obs_loglik(o: &Obs, mean: &DVector<f64>, sigma2: f64, shape: Shape) -> f64 {
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

fn design(cands: &[Candidate], o: &Obs) -> (DMatrix<f64>, Vec<(String, &'static str, f64)>) {
    let dims = o.cell.observed_dims();
    let mut cols: Vec<&Vector6<f64>> = Vec::new();
    let mut names = Vec::new();
    for &c in cands {
        let (n, v) = &o.columns[c.index()];
        names.extend(n.iter().cloned());
        cols.extend(v.iter());
    }
    let j = DMatrix::from_fn(dims.len(), cols.len(), |i, k| cols[k][dims[i]]);
    (j, names)
}

/// Covariance shape of the signed error per σ² (mm², mrad²): anisotropy `k`, per-experiment
/// contact offset `rho` (τ/σ) and layout index `g` into [`SPREAD_GRID_M`].
#[derive(Debug, Clone, Copy, PartialEq)]
struct Shape {
    k: f64,
    rho: f64,
    g: usize,
}

impl Shape {
    const BASE: Shape = Shape {
        k: 1.0,
        rho: 0.0,
        g: SPREAD_BASE,
    };
}

/// `Σp + k²·Σa + ρ²·I_translation` of one observation.
fn shape_cov(o: &Obs, shape: Shape) -> DMatrix<f64> {
    let (cov_perp, cov_along) = &o.covs[shape.g];
    let mut cov = cov_perp + cov_along * (shape.k * shape.k);
    // The first three observed components are the translation (mm) in every cell.
    for i in 0..3 {
        cov[(i, i)] += shape.rho * shape.rho;
    }
    cov
}

fn fit_fixed_k(cands: &[Candidate], data: &[&Obs], shape: Shape) -> Option<ModelFit> {
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

fn fit_model(cands: &[Candidate], data: &[&Obs]) -> Option<ModelFit> {
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
const SHAPE_SEARCH: Maximize1dOptions = Maximize1dOptions {
    grid_steps: 16,
    golden_iterations: 30,
    profile_interval: false,
    bisection_iterations: 0,
};

/// Range of ρ = τ/σ searched by the per-experiment contact offset (0 is tried too).
const RHO_RANGE: [f64; 2] = [0.05, 20.0];

/// [`fit_model`] at the tetrahedron edge `SPREAD_GRID_M[g]`: the noise-shape parameters (k, ρ)
/// by 1-D searches, alternated when both are present.
fn fit_model_at(cands: &[Candidate], data: &[&Obs], g: usize) -> Option<ModelFit> {
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

fn mean_of(cands: &[Candidate], o: &Obs, beta: &[f64]) -> DVector<f64> {
    let (j, _) = design(cands, o);
    if beta.is_empty() {
        return DVector::zeros(o.y.len());
    }
    j * DVector::from_column_slice(beta)
}

/// Leave-one-experiment-out held-out log-likelihood (sum over experiments).
fn heldout(cands: &[Candidate], data: &[Obs]) -> f64 {
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

fn candidate_result(
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
        .map(|((n, u, s), (b, se))| ParamEstimate {
            name: n.clone(),
            value: b * s,
            unit: u.to_string(),
            ci95: [(b - 1.96 * se) * s, (b + 1.96 * se) * s],
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

/// Signed errors of one published experiment (generic estimate).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SignedRow {
    /// Experiment number.
    pub experiment: u32,
    /// The cell.
    pub cell: PaperCell,
    /// `T_est − T_true`, mm, b1 axes.
    pub dt_mm: [f64; 3],
    /// `log(R_est·R_trueᵀ)`, degrees, b1 axes (floor–floor/ceiling: only z is published faithfully).
    pub rot_deg: [f64; 3],
}

/// What the isotropic model gets wrong about one cell's signed errors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellFinding {
    /// The cell.
    pub cell: PaperCell,
    /// Names of the observed components (`dx_mm`, …, `wz_deg`).
    pub components: Vec<String>,
    /// Mean signed error per component (mm or degrees).
    pub mean: Vec<f64>,
    /// Mean / its standard error under the baseline σ̂ (|z| > 2 suggests a bias).
    pub z: Vec<f64>,
    /// Experiments sharing the majority sign, per component (5 of 5 has p = 1/16 by chance).
    pub same_sign: Vec<usize>,
    /// Test of a zero mean: `n·ȳᵀ(σ̂²Σ)⁻¹ȳ` ~ χ²(components).
    pub mean_chi2: f64,
    /// Its p-value.
    pub mean_p_value: f64,
    /// Published median e_rot1/e_tran1, degrees per mm.
    pub ratio_published: f64,
    /// Simulated band of the median of 5 ratios at σ̂ (isotropic model).
    pub ratio_sim: Band,
    /// Published mean gain of the constrained method, e_tran1 − e_tran2, mm.
    pub gain_tran_published_mm: f64,
    /// Simulated band of the mean of 5 at σ̂, mm.
    pub gain_tran_sim_mm: Band,
    /// Published mean gain, e_rot1 − e_rot2, degrees.
    pub gain_rot_published_deg: f64,
    /// Simulated band of the mean of 5 at σ̂, degrees.
    pub gain_rot_sim_deg: Band,
}

/// `handclasp paper diagnose`: the study, what the isotropic simulation gets wrong, the candidates and
/// the named cause.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PaperDiagnosis {
    /// The σ fit and published-vs-simulated rows.
    pub study: PaperStudy,
    /// Signed errors of the generic estimates.
    pub signed: Vec<SignedRow>,
    /// Per-cell findings under the baseline.
    pub cells: Vec<CellFinding>,
    /// The baseline (isotropic σ, no bias) on the signed errors.
    pub baseline: CandidateResult,
    /// Each candidate alone.
    pub candidates: Vec<CandidateResult>,
    /// The model forward selection ends with (equal to the baseline when nothing is selected).
    pub selected: CandidateResult,
    /// The named cause: candidate names joined by " + ", or "none significant".
    pub cause: String,
    /// Plain statements of what can and cannot be concluded.
    pub conclusions: Vec<String>,
}

/// Runs the diagnosis on Table 1.
pub fn run_paper_diagnosis(opts: &StudyOptions) -> Result<PaperDiagnosis, PaperError> {
    diagnose_experiments(&table1_experiments()?, opts)
}

const COMPONENT_NAMES: [&str; 6] = ["dx_mm", "dy_mm", "dz_mm", "wx_deg", "wy_deg", "wz_deg"];

/// Runs the diagnosis on any set of experiments (≥ 2 per cell).
pub fn diagnose_experiments(
    exps: &[Experiment],
    opts: &StudyOptions,
) -> Result<PaperDiagnosis, PaperError> {
    opts.validate()?;
    let truths = truths_of(exps)?;
    let sims = build_sims(&truths, opts.seed, opts.trials);
    let study = study_with(exps, opts, &sims, &truths);
    let data = observations(exps, &sims);
    let deg = |mrad: f64| mrad / MRAD_PER_RAD * 180.0 / std::f64::consts::PI;
    let signed = exps
        .iter()
        .map(|e| {
            let y = e.signed_generic();
            SignedRow {
                experiment: e.number,
                cell: e.cell,
                dt_mm: [y[0], y[1], y[2]],
                rot_deg: [deg(y[3]), deg(y[4]), deg(y[5])],
            }
        })
        .collect();
    let fail = || {
        PaperError::Experiments(
            "the baseline model could not be fitted (degenerate covariance)".into(),
        )
    };
    let (baseline, base_fit) = candidate_result(&[], &data, None).ok_or_else(fail)?;
    let base_held = baseline.heldout_loglik;
    let mut baseline = baseline;
    baseline.description = "isotropic alignment noise, one σ, no bias".into();

    // Per-cell findings under the baseline σ̂.
    let sigma_base = base_fit.sigma2[0].sqrt();
    let generic_sigma = study
        .common
        .iter()
        .find(|t| t.method == PaperMethod::Generic)
        .map(|t| t.common.sigma_mm)
        .unwrap_or(sigma_base);
    let cells: Vec<CellFinding> = PaperCell::ALL
        .iter()
        .map(|&cell| {
            cell_finding(
                cell,
                exps,
                &data,
                &sims[cell.index()],
                sigma_base,
                generic_sigma,
            )
        })
        .collect();

    let candidates: Vec<CandidateResult> = Candidate::ALL
        .iter()
        .filter_map(|&c| candidate_result(&[c], &data, Some((&base_fit, base_held))).map(|r| r.0))
        .collect();

    // Forward selection.
    let mut chosen: Vec<Candidate> = Vec::new();
    let mut current = (baseline.clone(), base_fit.clone());
    loop {
        let remaining: Vec<Candidate> = Candidate::ALL
            .iter()
            .copied()
            .filter(|c| chosen.iter().all(|d| d.family() != c.family()))
            .collect();
        if remaining.is_empty() {
            break;
        }
        let alpha = ALPHA / remaining.len() as f64;
        let best = remaining
            .iter()
            .filter_map(|&c| {
                let mut set = chosen.clone();
                set.push(c);
                let (r, m) =
                    candidate_result(&set, &data, Some((&current.1, current.0.heldout_loglik)))?;
                (r.lr_p_value < alpha && r.heldout_loglik > current.0.heldout_loglik)
                    .then_some((c, r, m))
            })
            .filter(|(_, r, _)| r.aic < current.0.aic)
            .max_by(|a, b| a.1.heldout_loglik.total_cmp(&b.1.heldout_loglik));
        let Some((c, r, m)) = best else { break };
        if r.aic >= current.0.aic {
            break;
        }
        chosen.push(c);
        current = (r, m);
    }
    // Report the selected model's LR and held-out gain against the baseline.
    let selected = if chosen.is_empty() {
        baseline.clone()
    } else {
        candidate_result(&chosen, &data, Some((&base_fit, base_held)))
            .map(|r| r.0)
            .unwrap_or_else(|| current.0.clone())
    };
    let cause = if chosen.is_empty() {
        "none significant".to_string()
    } else {
        chosen
            .iter()
            .map(|c| c.name())
            .collect::<Vec<_>>()
            .join(" + ")
    };
    let conclusions = conclusions(&study, &cells, &selected, baseline.aic, &cause);
    Ok(PaperDiagnosis {
        study,
        signed,
        cells,
        baseline,
        candidates,
        selected,
        cause,
        conclusions,
    })
}

fn cell_finding(
    cell: PaperCell,
    exps: &[Experiment],
    data: &[Obs],
    sim: &CellSim,
    sigma_base: f64,
    generic_sigma: f64,
) -> CellFinding {
    let dims = cell.observed_dims();
    let obs: Vec<&Obs> = data.iter().filter(|o| o.cell == cell).collect();
    let n = obs.len().max(1) as f64;
    let d = dims.len();
    let mut mean = DVector::zeros(d);
    for o in &obs {
        mean += &o.y;
    }
    mean /= n;
    let cov = (&obs[0].cov_perp + &obs[0].cov_along) * (sigma_base * sigma_base);
    let chi2 = cov
        .clone()
        .cholesky()
        .map(|ch| n * mean.dot(&ch.solve(&mean)))
        .unwrap_or(f64::NAN);
    let to_unit = |k: usize, v: f64| {
        if dims[k] >= 3 {
            v / MRAD_PER_RAD * 180.0 / std::f64::consts::PI
        } else {
            v
        }
    };
    let z = (0..d).map(|k| mean[k] / (cov[(k, k)] / n).sqrt()).collect();
    let same_sign = (0..d)
        .map(|k| {
            let pos = obs.iter().filter(|o| o.y[k] > 0.0).count();
            pos.max(obs.len() - pos)
        })
        .collect();
    // Ratio and gain: published vs simulated statistics of 5 at the generic common σ̂.
    let mine: Vec<&Experiment> = exps.iter().filter(|e| e.cell == cell).collect();
    let k = mine.len().max(1);
    let mut ratios: Vec<f64> = mine
        .iter()
        .map(|e| e.e_rot_deg[0] / e.e_tran_mm[0])
        .collect();
    ratios.sort_by(f64::total_cmp);
    let ratio_published = quantile(&ratios, 0.5);
    let g = sim.errors_at(PaperMethod::Generic, generic_sigma);
    let c = sim.errors_at(PaperMethod::Constrained, generic_sigma);
    let groups = g.len() / k;
    // Groups of k consecutive trials (independent draws).
    let mut med = Vec::with_capacity(groups);
    let mut gt = Vec::with_capacity(groups);
    let mut gr = Vec::with_capacity(groups);
    for gi in 0..groups {
        let idx = gi * k..(gi + 1) * k;
        let mut r: Vec<f64> = idx.clone().map(|i| g[i].1 / g[i].0).collect();
        r.sort_by(f64::total_cmp);
        med.push(quantile(&r, 0.5));
        gt.push(idx.clone().map(|i| g[i].0 - c[i].0).sum::<f64>() / k as f64);
        gr.push(idx.map(|i| g[i].1 - c[i].1).sum::<f64>() / k as f64);
    }
    let kf = k as f64;
    CellFinding {
        cell,
        components: dims
            .iter()
            .map(|&i| COMPONENT_NAMES[i].to_string())
            .collect(),
        mean: (0..d).map(|i| to_unit(i, mean[i])).collect(),
        z,
        same_sign,
        mean_chi2: chi2,
        mean_p_value: chi2_sf(chi2, d),
        ratio_published,
        ratio_sim: Band::of(med),
        gain_tran_published_mm: mine
            .iter()
            .map(|e| e.e_tran_mm[0] - e.e_tran_mm[1])
            .sum::<f64>()
            / kf,
        gain_tran_sim_mm: Band::of(gt),
        gain_rot_published_deg: mine
            .iter()
            .map(|e| e.e_rot_deg[0] - e.e_rot_deg[1])
            .sum::<f64>()
            / kf,
        gain_rot_sim_deg: Band::of(gr),
    }
}

fn conclusions(
    study: &PaperStudy,
    cells: &[CellFinding],
    selected: &CandidateResult,
    baseline_aic: f64,
    cause: &str,
) -> Vec<String> {
    let mut out = Vec::new();
    for t in &study.common {
        out.push(format!(
            "{}: one alignment noise σ̂ = {:.2} mm [{:.2}, {:.2}] explains the published error sizes of all cells (LR p = {:.3}{}).",
            t.method.name(),
            t.common.sigma_mm,
            t.common.ci95_mm[0],
            t.common.ci95_mm[1],
            t.p_value,
            if t.p_value < ALPHA { ", rejected: the cells differ" } else { "" }
        ));
    }
    for c in cells {
        if c.mean_p_value < ALPHA {
            let parts: Vec<String> = c
                .components
                .iter()
                .zip(c.mean.iter().zip(&c.same_sign))
                .map(|(n, (m, s))| format!("{n} {m:+.3} ({s}/5 same sign)"))
                .collect();
            out.push(format!(
                "{}: the signed errors share a direction, which isotropic noise cannot produce (χ² = {:.1}, p = {:.2e}): {}.",
                c.cell.label(),
                c.mean_chi2,
                c.mean_p_value,
                parts.join(", ")
            ));
        }
        if c.ratio_sim.outside(c.ratio_published) {
            out.push(format!(
                "{}: the published e_rot/e_tran ratio ({:.4} °/mm) is outside what isotropic noise gives ({:.4}–{:.4}).",
                c.cell.label(),
                c.ratio_published,
                c.ratio_sim.p05,
                c.ratio_sim.p95
            ));
        }
        if c.gain_tran_sim_mm.outside(c.gain_tran_published_mm)
            || c.gain_rot_sim_deg.outside(c.gain_rot_published_deg)
        {
            out.push(format!(
                "{}: the constrained method's published mean gain ({:+.2} mm, {:+.3}°) differs from the simulated one ({:+.2} mm [{:+.2}, {:+.2}], {:+.3}° [{:+.3}, {:+.3}]).",
                c.cell.label(),
                c.gain_tran_published_mm,
                c.gain_rot_published_deg,
                c.gain_tran_sim_mm.p50,
                c.gain_tran_sim_mm.p05,
                c.gain_tran_sim_mm.p95,
                c.gain_rot_sim_deg.p50,
                c.gain_rot_sim_deg.p05,
                c.gain_rot_sim_deg.p95
            ));
        }
    }
    // Interpret the selected candidates physically.
    for name in &selected.candidates {
        let p = |n: &str| selected.params.iter().find(|p| p.name.starts_with(n));
        let line = match name.as_str() {
            "anisotropic_noise" => p("anisotropic_noise.k").map(|k| {
                let dir = if k.value < 1.0 { "smaller" } else { "larger" };
                format!(
                    "anisotropic_noise: the alignment error along the approach axis is {dir} than across it (k = {:.2} [{:.2}, {:.2}]); {}",
                    k.value,
                    k.ci95[0],
                    k.ci95[1],
                    if k.value < 1.0 {
                        "touching tips fix the gap along the axis, the operator's error is lateral, so the estimates' rotation errors are smaller relative to their translation errors than isotropic noise gives"
                    } else {
                        "the tips' contact along the axis is the poorly judged direction"
                    }
                )
            }),
            "layout_spread" => p("layout_spread.edge").map(|e| {
                format!(
                    "layout_spread: the teach points are better explained by a {:.2} m tetrahedron (grid interval [{:.2}, {:.2}] m) than by the assumed {PAPER_SPREAD_M} m{}",
                    e.value,
                    e.ci95[0],
                    e.ci95[1],
                    if e.value >= SPREAD_GRID_M[SPREAD_GRID_M.len() - 1] {
                        " (at the largest edge tried: the robots' reach allows little more, so it partly stands in for another rotation-shrinking effect)"
                    } else {
                        ""
                    }
                )
            }),
            other => Some(format!(
                "{other}: {}",
                selected
                    .params
                    .iter()
                    .filter(|q| q.name.starts_with(other))
                    .map(|q| format!("{} = {:.3} {} [{:.3}, {:.3}]", q.name, q.value, q.unit, q.ci95[0], q.ci95[1]))
                    .collect::<Vec<_>>()
                    .join("; ")
            )),
        };
        out.extend(line);
    }
    let mean_selected = selected.candidates.iter().any(|c| {
        matches!(
            c.as_str(),
            "tip_offset"
                | "contact_bias_per_cell"
                | "r1_joint1_offset"
                | "r2_joint1_offset"
                | "r2_joint1_offset_per_cell"
        )
    });
    for c in cells.iter().filter(|c| c.mean_p_value < ALPHA) {
        if !mean_selected {
            out.push(format!(
                "{}: its shared direction is significant under isotropic noise (p = {:.1e}) but no bias candidate passes the corrected selection once the noise shape is extended: a systematic error there (e.g. robot 2's joint-1 offset on the wall) is possible but not established by 5 experiments.",
                c.cell.label(),
                c.mean_p_value
            ));
        }
    }
    if cause == "none significant" {
        out.push("No candidate improves on isotropic noise significantly (Bonferroni-corrected LR test, AIC and held-out prediction): the published errors are consistent with noise alone at this sample size.".into());
    } else {
        out.push(format!(
            "Named cause: {cause} (LR = {:.1}, df {}, p = {:.2e}; ΔAIC = {:+.1} vs the baseline; held-out log-likelihood gain {:+.1} over the leave-one-experiment-out predictions).",
            selected.lr_statistic, selected.lr_df, selected.lr_p_value,
            selected.aic - baseline_aic, selected.heldout_gain
        ));
        out.push("Table 1 holds no raw points: a named cause is the best of the candidates tried, consistent with the signed errors; other effects with the same signature (e.g. a CMM-frame or base-marker error) cannot be excluded from these data.".into());
    }
    out.push("The floor-floor and floor-ceiling calib1 angles are printed with φ = 0, which loses the tilt's direction; only their yaw enters the signed analysis.".into());
    out
}

/// Readable text of the diagnosis (the study first).
pub fn render_diagnosis_text(d: &PaperDiagnosis) -> String {
    let mut s = render_text(&d.study);
    let _ = writeln!(
        s,
        "\nSigned errors of the generic estimates (b1 axes; estimate − truth):"
    );
    let _ = writeln!(
        s,
        "{:>3} {:<14} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8}",
        "exp", "cell", "dx mm", "dy mm", "dz mm", "wx °", "wy °", "wz °"
    );
    for r in &d.signed {
        let _ = writeln!(
            s,
            "{:>3} {:<14} {:>7.1} {:>7.1} {:>7.1} {:>8.3} {:>8.3} {:>8.3}",
            r.experiment,
            r.cell.label(),
            r.dt_mm[0],
            r.dt_mm[1],
            r.dt_mm[2],
            r.rot_deg[0],
            r.rot_deg[1],
            r.rot_deg[2]
        );
    }
    let _ = writeln!(
        s,
        "\nPer cell, under isotropic noise at the baseline σ̂ = {:.2} mm:",
        d.baseline.sigma_mm[0]
    );
    for c in &d.cells {
        let comps: Vec<String> = c
            .components
            .iter()
            .zip(c.mean.iter().zip(c.z.iter().zip(&c.same_sign)))
            .map(|(n, (m, (z, ss)))| format!("{n} {m:+.3} (z {z:+.1}, {ss}/5)"))
            .collect();
        let _ = writeln!(
            s,
            "{:<14} mean: {}\n{:<14} zero-mean test χ² = {:.1} (df {}), p = {:.2e}; e_rot/e_tran median {:.4} °/mm vs sim [{:.4}, {:.4}]; constrained gain {:+.2} mm / {:+.3}° vs sim {:+.2} [{:+.2}, {:+.2}] mm / {:+.3} [{:+.3}, {:+.3}]°",
            c.cell.label(),
            comps.join(", "),
            "",
            c.mean_chi2,
            c.components.len(),
            c.mean_p_value,
            c.ratio_published,
            c.ratio_sim.p05,
            c.ratio_sim.p95,
            c.gain_tran_published_mm,
            c.gain_rot_published_deg,
            c.gain_tran_sim_mm.p50,
            c.gain_tran_sim_mm.p05,
            c.gain_tran_sim_mm.p95,
            c.gain_rot_sim_deg.p50,
            c.gain_rot_sim_deg.p05,
            c.gain_rot_sim_deg.p95,
        );
    }
    let _ = writeln!(
        s,
        "\nCandidate extensions (fitted by maximum likelihood on the 15 signed errors):"
    );
    let _ = writeln!(
        s,
        "{:<28} {:>3} {:>9} {:>8} {:>8} {:>9} {:>10}  parameters",
        "model", "k", "loglik", "AIC", "LR", "p", "held-out Δ"
    );
    let line = |s: &mut String, r: &CandidateResult| {
        let name = if r.candidates.is_empty() {
            "baseline".to_string()
        } else {
            r.candidates.join("+")
        };
        let params: Vec<String> = r
            .params
            .iter()
            .map(|p| {
                format!(
                    "{} = {:.3} {} [{:.3}, {:.3}]",
                    p.name, p.value, p.unit, p.ci95[0], p.ci95[1]
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "{:<28} {:>3} {:>9.2} {:>8.2} {:>8.2} {:>9.2e} {:>+10.2}  {}",
            name,
            r.n_params,
            r.loglik,
            r.aic,
            r.lr_statistic,
            r.lr_p_value,
            r.heldout_gain,
            params.join("; ")
        );
    };
    line(&mut s, &d.baseline);
    for r in &d.candidates {
        line(&mut s, r);
    }
    let _ = writeln!(s, "selected:");
    line(&mut s, &d.selected);
    let _ = writeln!(s, "\nNamed cause: {}", d.cause);
    for c in &d.conclusions {
        let _ = writeln!(s, "- {c}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The linear-scaling claim: per trial, `bias + σ·slope` from the σ = 1 mm simulation equals a
    /// direct simulation at σ = 3 mm with the same random numbers, for both methods and all cells
    /// (including the floor–wall constrained method, whose bias is the truth's 0.126° off-family
    /// tilt). The neglected second-order term is absolute, of order σ²/spread in translation
    /// (9e-3 mm at 3 mm over 1 m) and (σ/spread)² rad in rotation (5e-4°), so the tolerance is twice
    /// that plus 1 % of the error (the first-order slope is itself estimated at σ = 1 mm).
    #[test]
    fn errors_scale_linearly_with_sigma() {
        const LINEAR_REL_TOL: f64 = 0.01;
        let sigma: f64 = 3.0;
        let second_order_mm = 2.0 * sigma * sigma / (PAPER_SPREAD_M * MM_PER_M);
        let second_order_deg =
            2.0 * (sigma / (PAPER_SPREAD_M * MM_PER_M)).powi(2) * 180.0 / std::f64::consts::PI;
        let truths = table1_truths().unwrap();
        let seed = 99;
        let trials = 200;
        let mut worst: f64 = 0.0;
        for cell in PaperCell::ALL {
            let ctx = CellContext::new(cell, truths[cell.index()]);
            let sim = CellSim::build(ctx.clone(), seed, trials);
            assert_eq!(sim.bias[0].len(), trials);
            let stream = (cell.index() as u64 + 1) << 40;
            for method in PaperMethod::ALL {
                let scaled = sim.errors_at(method, sigma);
                for (t, &(st, sr)) in scaled.iter().enumerate() {
                    let mut rng = trial_rng(seed, stream + t as u64);
                    let d = draw(&ctx, PAPER_SPREAD_M, &mut rng);
                    let (p1, p2) = reported(&ctx, &d, sigma, None, &PlantedEffects::default());
                    let est = fit_both(&ctx, &p1, &p2).unwrap();
                    let (dt, dr) = paper_errors(cell, &ctx.truth, &est[method.index()]);
                    assert!(
                        (dt - st).abs() <= LINEAR_REL_TOL * dt + second_order_mm,
                        "{cell:?} {method:?} trial {t}: e_tran {dt} vs scaled {st}"
                    );
                    assert!(
                        (dr - sr).abs() <= LINEAR_REL_TOL * dr + second_order_deg,
                        "{cell:?} {method:?} trial {t}: e_rot {dr} vs scaled {sr}"
                    );
                    worst = worst.max((dt - st).abs() / dt).max((dr - sr).abs() / dr);
                }
            }
        }
        // Not vacuous: the deviation exists (nonlinearity) but is small.
        assert!(worst > 0.0, "worst {worst}");
    }

    /// The isotropic covariance splits into across + along the approach axis (linear regime): the
    /// trace of the σ = 1 mm generic covariance equals the sum of the parts' traces to 5 %
    /// (Monte Carlo noise of 400 trials on a sample covariance is a few %).
    #[test]
    fn anisotropic_parts_add_up() {
        const MC_REL_TOL: f64 = 0.05;
        let truths = table1_truths().unwrap();
        for cell in PaperCell::ALL {
            let sim = CellSim::build(CellContext::new(cell, truths[cell.index()]), 5, 400);
            let full: Vec<[f64; 9]> = sim.slope[0].clone();
            let tr_full = cov6(&full).trace();
            let tr_parts = (sim.cov_perp + sim.cov_along).trace();
            assert!(
                (tr_full / tr_parts - 1.0).abs() < MC_REL_TOL,
                "{cell:?}: {tr_full} vs {tr_parts}"
            );
        }
    }

    /// The published errors, recomputed with this module's reading of the paper's metrics, agree with
    /// Table 1's (e_tran ±0.2 mm; e_rot ±0.01°, the table's rounding plus the small-angle tilt).
    #[test]
    fn paper_metrics_reproduce_table1() {
        const E_TRAN_TOL_MM: f64 = 0.2;
        const E_ROT_TOL_DEG: f64 = 0.01;
        for e in table1_experiments().unwrap() {
            for m in 0..2 {
                let (t, r) = paper_errors(e.cell, &e.b1_from_b2_true, &e.estimate[m]);
                assert!(
                    (t - e.e_tran_mm[m]).abs() <= E_TRAN_TOL_MM + 1e-9, // 1e-9: round-off of decimals sitting on the tolerance
                    "exp {} m{m}: {t}",
                    e.number
                );
                assert!(
                    (r - e.e_rot_deg[m]).abs() <= E_ROT_TOL_DEG + 1e-9,
                    "exp {} m{m}: {r}",
                    e.number
                );
            }
        }
    }
}

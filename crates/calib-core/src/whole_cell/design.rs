//! Greedy experiment design: choose observations that minimise the predicted cooperative error
//! (A-optimal) or maximise the information volume (D-optimal), by rank-k Woodbury updates.

use kinematics::Axis;
use nalgebra::{DMatrix, Isometry3, Matrix6, Translation3, UnitQuaternion, Vector3, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use super::accuracy::ConfigPair;
use super::{
    CellEstimate, CellFitError, CellParam, CellProblem, Evaluator, Observation, ParamLayout,
};

/// Seeded draws of the placement error behind [`DesignPrediction::e_tran_m`] and
/// [`DesignPrediction::e_rot_rad`].
pub const PLACEMENT_DRAWS: usize = 2000;

/// σ of the weak prior put on the unpenalised unknowns (placement, nuisances) so that the
/// design's information matrix is invertible before any observation: 10 (m or rad). Its
/// information, 0.01, is negligible next to a single observation's.
pub const WEAK_PRIOR_SIGMA: f64 = 10.0;

/// The design criterion.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum DesignCriterion {
    /// A-optimal for cooperative accuracy: minimise the predicted mean cooperative variance
    /// `mean_k trace(J_v,k·Σ·J_v,kᵀ)` over the evaluation pairs (m²).
    CooperativeA,
    /// D-optimal: maximise `log det` of the posterior information.
    D,
}

/// Result of [`greedy_design`].
#[derive(Debug, Clone, Serialize)]
pub struct DesignResult {
    /// Chosen candidate indices, in the order chosen.
    pub chosen: Vec<usize>,
    /// The criterion at the chosen set: for A, the predicted cooperative rms
    /// `sqrt(mean trace Σ_v)`, m; for D, `log det A` of the information (dimensionless).
    pub criterion: f64,
    /// The criterion after each pick (same unit).
    pub history: Vec<f64>,
}

struct DesignSetup {
    /// Whitened Jacobian block of each candidate.
    blocks: Vec<DMatrix<f64>>,
    /// Prior information (with the weak prior).
    info0: DMatrix<f64>,
    /// `M = mean_k J_v,kᵀ·J_v,k`.
    m: DMatrix<f64>,
}

fn setup(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    eval_pairs: &[ConfigPair],
) -> Result<DesignSetup, CellFitError> {
    if candidates.is_empty() {
        return Err(CellFitError::InvalidInput(
            "design: no candidate observations".into(),
        ));
    }
    let ev = Evaluator::new(problem, layout);
    let n = layout.len();
    let blocks = candidates
        .iter()
        .map(|c| {
            let l = ev.linearise(c, at, true)?;
            Ok(&l.whitening * &l.jacobian)
        })
        .collect::<Result<Vec<_>, CellFitError>>()?;
    let mut info0 = layout.prior_sqrt_info.transpose() * &layout.prior_sqrt_info;
    for j in 0..n {
        if layout.prior_sigma(j) == 0.0 {
            info0[(j, j)] += 1.0 / (WEAK_PRIOR_SIGMA * WEAK_PRIOR_SIGMA);
        }
    }
    // The placement's own prior (`[b1_from_b2] sigma_mm/sigma_deg`, a shared trunk's identity
    // held at 1 µm / 1 µrad), as `calibrate --cell` adds its rows to every fit: without it a
    // placement the cell holds was predicted as if free (a shared trunk's e_tran 1.1 mm for a
    // placement held at 1 µm). Columns 0..6 are the placement's ([`ParamLayout::new`]).
    if let Some(pp) = &problem.placement_prior {
        for row in pp.linearise(&at.b1_from_b2).1 {
            for a in 0..6 {
                for b in 0..6 {
                    info0[(a, b)] += row[a] * row[b];
                }
            }
        }
    }
    let mut m = DMatrix::zeros(n, n);
    for pair in eval_pairs {
        let (_, jv) = ev.cooperative_vector(at, pair, true)?;
        m += jv.transpose() * &jv;
    }
    m /= eval_pairs.len().max(1) as f64;
    Ok(DesignSetup { blocks, info0, m })
}

fn criterion_value(
    crit: DesignCriterion,
    sigma: &DMatrix<f64>,
    info: &DMatrix<f64>,
    m: &DMatrix<f64>,
) -> f64 {
    match crit {
        DesignCriterion::CooperativeA => (m * sigma).trace().max(0.0).sqrt(),
        DesignCriterion::D => info
            .clone()
            .cholesky()
            .map(|c| 2.0 * c.l().diagonal().iter().map(|v| v.ln()).sum::<f64>())
            .unwrap_or(f64::NEG_INFINITY),
    }
}

/// Greedily chooses `n` of `candidates` (linearised at `at`, normally the nominal cell at its
/// nominal placement) for the criterion, with rank-k Woodbury updates of the posterior
/// covariance (see the module documentation). `eval_pairs` are the configuration pairs of the
/// cooperative criterion (A); D ignores them.
///
/// Errors: `n` larger than the candidate count, no candidates, no evaluation pairs for A, or a
/// candidate the models reject.
pub fn greedy_design(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    eval_pairs: &[ConfigPair],
    n: usize,
    criterion: DesignCriterion,
) -> Result<DesignResult, CellFitError> {
    if n > candidates.len() {
        return Err(CellFitError::InvalidInput(format!(
            "design: {n} observations asked from {} candidates; give more candidates or a smaller n",
            candidates.len()
        )));
    }
    if criterion == DesignCriterion::CooperativeA && eval_pairs.is_empty() {
        return Err(CellFitError::InvalidInput(
            "design: the cooperative criterion needs evaluation pairs".into(),
        ));
    }
    let s = setup(problem, layout, at, candidates, eval_pairs)?;
    let (mut sigma, _) = super::solve::sym_inverse(&s.info0);
    let mut info = s.info0.clone();
    let mut chosen: Vec<usize> = Vec::with_capacity(n);
    let mut taken = vec![false; candidates.len()];
    let mut history = Vec::with_capacity(n);
    for _ in 0..n {
        // G = Σ·M·Σ for the A criterion.
        let g = match criterion {
            DesignCriterion::CooperativeA => Some(&sigma * &s.m * &sigma),
            DesignCriterion::D => None,
        };
        let mut best: Option<(usize, f64)> = None;
        for (c, b) in s.blocks.iter().enumerate() {
            if taken[c] {
                continue;
            }
            let bs = b * &sigma;
            let k = b.nrows();
            let smat = DMatrix::identity(k, k) + &bs * b.transpose();
            let Some(chol) = smat.clone().cholesky() else {
                continue;
            };
            let gain = match &g {
                // Decrease of trace(M·Σ): trace(S⁻¹·B·G·Bᵀ).
                Some(g) => (chol.solve(&(b * g * b.transpose()))).trace(),
                // Increase of log det: log det S.
                None => 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>(),
            };
            if best.is_none_or(|(_, bg)| gain > bg) {
                best = Some((c, gain));
            }
        }
        let Some((c, _)) = best else { break };
        let b = &s.blocks[c];
        let bs = b * &sigma;
        let k = b.nrows();
        let smat = DMatrix::identity(k, k) + &bs * b.transpose();
        let chol = smat.cholesky().ok_or_else(|| {
            CellFitError::InvalidInput("design: information update is not positive definite".into())
        })?;
        // Σ' = Σ − (BΣ)ᵀ·S⁻¹·(BΣ).
        sigma -= bs.transpose() * chol.solve(&bs);
        sigma = (&sigma + sigma.transpose()) * 0.5;
        info += b.transpose() * b;
        taken[c] = true;
        chosen.push(c);
        history.push(criterion_value(criterion, &sigma, &info, &s.m));
    }
    let criterion_now = history
        .last()
        .copied()
        .unwrap_or_else(|| criterion_value(criterion, &sigma, &info, &s.m));
    Ok(DesignResult {
        chosen,
        criterion: criterion_now,
        history,
    })
}

/// The criterion of a given subset `chosen` of `candidates` (for comparing a design with, e.g.,
/// random subsets): A: predicted cooperative rms, m; D: `log det` of the information.
///
/// Errors: an index out of range, or as [`greedy_design`].
pub fn design_criterion(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    chosen: &[usize],
    eval_pairs: &[ConfigPair],
    criterion: DesignCriterion,
) -> Result<f64, CellFitError> {
    if let Some(&bad) = chosen.iter().find(|&&c| c >= candidates.len()) {
        return Err(CellFitError::InvalidInput(format!(
            "design: candidate index {bad} is out of range ({} candidates)",
            candidates.len()
        )));
    }
    let (s, info, sigma) = subset_posterior(problem, layout, at, candidates, chosen, eval_pairs)?;
    Ok(criterion_value(criterion, &sigma, &info, &s.m))
}

/// `(setup, information, covariance)` of the chosen subset (indices checked by the caller).
fn subset_posterior(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    chosen: &[usize],
    eval_pairs: &[ConfigPair],
) -> Result<(DesignSetup, DMatrix<f64>, DMatrix<f64>), CellFitError> {
    let picked: Vec<Observation> = chosen.iter().map(|&c| candidates[c].clone()).collect();
    let s = setup(problem, layout, at, &picked, eval_pairs)?;
    let mut info = s.info0.clone();
    for b in &s.blocks {
        info += b.transpose() * b;
    }
    let (sigma, _) = super::solve::sym_inverse(&info);
    Ok((s, info, sigma))
}

/// The error covariance of a design's calibration in parts ([`super::PredictionSplit`]): the
/// chosen subset `chosen` of `candidates` linearised at `at`, estimated with the tolerance prior
/// scaled by `prior_scale` (1: the tolerances, as the design criterion assumes; a smaller scale
/// as `calibrate --cell`'s evidence may choose, [`super::PRIOR_SCALES`]) for a truth drawn from
/// the tolerances. At scale 1 the parts sum to the design's posterior `A⁻¹`.
///
/// Errors: an index out of range, a non-positive scale, or as [`greedy_design`].
pub fn design_split(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    chosen: &[usize],
    prior_scale: f64,
) -> Result<super::PredictionSplit, CellFitError> {
    if let Some(&bad) = chosen.iter().find(|&&c| c >= candidates.len()) {
        return Err(CellFitError::InvalidInput(format!(
            "design: candidate index {bad} is out of range ({} candidates)",
            candidates.len()
        )));
    }
    if !(prior_scale.is_finite() && prior_scale > 0.0) {
        return Err(CellFitError::InvalidInput(format!(
            "design: prior scale {prior_scale} must be positive"
        )));
    }
    let (_, info, _) = subset_posterior(problem, layout, at, candidates, chosen, &[])?;
    let lambda = layout.prior_sqrt_info.transpose() * &layout.prior_sqrt_info;
    // The data's information with the weak prior of the unpenalised columns.
    let hd = &info - &lambda;
    Ok(super::PredictionSplit::of_information(
        &hd,
        &lambda,
        prior_scale,
    ))
}

/// What a design predicts for the calibration of its observations (linearised at the design's
/// estimate, the posterior covariance `Σ = A⁻¹` of the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DesignPrediction {
    /// Predicted cooperative rms over the evaluation pairs, `sqrt(mean_k trace(J_v,k·Σ·J_v,kᵀ))`,
    /// m (the A criterion).
    pub cooperative_rms_m: f64,
    /// Predicted rms of the paper's `e_tran` (eq 34: largest |component| of the translation
    /// error of `b1_from_b2`), m, over [`PLACEMENT_DRAWS`] seeded draws of the placement error
    /// from its 6×6 posterior block.
    pub e_tran_m: f64,
    /// Predicted rms of the paper's `e_rot` (eq 33, largest |ZYZ angle difference|), rad, over
    /// the same draws.
    pub e_rot_rad: f64,
    /// `log det A` of the posterior information (the D criterion), dimensionless.
    pub log_det_info: f64,
}

/// The prediction of a given subset `chosen` of `candidates` ([`DesignPrediction`]): the
/// cooperative rms over `eval_pairs` (A), the placement's predicted `e_tran`/`e_rot` (seeded
/// draws, `seed`; the placement's true value taken as `at.b1_from_b2`) and `log det` (D).
///
/// Errors: an index out of range, no evaluation pairs, or as [`greedy_design`].
pub fn design_prediction(
    problem: &CellProblem,
    layout: &ParamLayout,
    at: &CellEstimate,
    candidates: &[Observation],
    chosen: &[usize],
    eval_pairs: &[ConfigPair],
    seed: u64,
) -> Result<DesignPrediction, CellFitError> {
    if let Some(&bad) = chosen.iter().find(|&&c| c >= candidates.len()) {
        return Err(CellFitError::InvalidInput(format!(
            "design: candidate index {bad} is out of range ({} candidates)",
            candidates.len()
        )));
    }
    if eval_pairs.is_empty() {
        return Err(CellFitError::InvalidInput(
            "design: the cooperative prediction needs evaluation pairs".into(),
        ));
    }
    let (s, info, sigma) = subset_posterior(problem, layout, at, candidates, chosen, eval_pairs)?;
    // Placement block: columns of ρ (translation) then φ (rotation), b1 axes.
    let mut cols = [0usize; 6];
    for (k, axis) in Axis::ALL.into_iter().enumerate() {
        let missing = || {
            CellFitError::InvalidInput(
                "design: the layout does not fit b1_from_b2 (placement columns missing)".into(),
            )
        };
        cols[k] = layout
            .column(&CellParam::PlacementTranslation { axis })
            .ok_or_else(missing)?;
        cols[k + 3] = layout
            .column(&CellParam::PlacementRotation { axis })
            .ok_or_else(missing)?;
    }
    let block = Matrix6::from_fn(|a, b| sigma[(cols[a], cols[b])]);
    let eig = block.symmetric_eigen();
    let root =
        eig.eigenvectors * Matrix6::from_diagonal(&eig.eigenvalues.map(|e| e.max(0.0).sqrt()));
    let x = at.b1_from_b2;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut sum_t, mut sum_r) = (0.0, 0.0);
    for _ in 0..PLACEMENT_DRAWS {
        let z = Vector6::from_fn(|_, _| StandardNormal.sample(&mut rng));
        let d = root * z;
        // The left perturbation of the module documentation: X ← Translation(ρ)·Rotation(φ)·X.
        let est = Isometry3::from_parts(
            Translation3::from(Vector3::new(d[0], d[1], d[2])),
            UnitQuaternion::identity(),
        ) * Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_scaled_axis(Vector3::new(d[3], d[4], d[5])),
        ) * x;
        sum_t += crate::e_tran(&x, &est).powi(2);
        sum_r += crate::e_rot(&x, &est).powi(2);
    }
    let draws = PLACEMENT_DRAWS as f64;
    Ok(DesignPrediction {
        cooperative_rms_m: criterion_value(DesignCriterion::CooperativeA, &sigma, &info, &s.m),
        e_tran_m: (sum_t / draws).sqrt(),
        e_rot_rad: (sum_r / draws).sqrt(),
        log_det_info: criterion_value(DesignCriterion::D, &sigma, &info, &s.m),
    })
}

#[cfg(test)]
mod tests {
    use super::super::fixtures::{sim_cell, Cell};
    use super::super::{Noise3, ObservationKind, Tolerance};
    use super::*;
    use nalgebra::Matrix3;

    /// Relative agreement of two evaluations of the same posterior (round-off of the two
    /// inverses only).
    const SAME_REL: f64 = 1e-9;

    /// `design_prediction` agrees with `design_criterion` on A and D for the same subset, and its
    /// predicted e_tran lies between the bounds the placement's translation covariance
    /// `Σ_t = [I −[t]×]·Σ_ρφ·[I −[t]×]ᵀ` (the left perturbation) sets for an rms of the largest
    /// |component|: `sqrt(max diag Σ_t) ≤ rms ≤ sqrt(trace Σ_t)`, up to the draws' sampling error.
    #[test]
    fn prediction_matches_the_criterion_and_bounds_e_tran() {
        let sc = sim_cell(Cell::Wall, Tolerance::default(), false, 3);
        let p = sc.problem();
        let x = sc.truth.b1_from_b2;
        let cands: Vec<Observation> = sc
            .eval_pairs(30, 0.8, 4)
            .into_iter()
            .enumerate()
            .map(|(i, pair)| Observation {
                row: i + 1,
                kind: ObservationKind::Coincident {
                    q1: pair.q1,
                    q2: pair.q2,
                    tool1: 0,
                    tool2: 0,
                    noise: Noise3::Isotropic { sigma_m: 3e-4 },
                },
            })
            .collect();
        let eval = sc.eval_pairs(20, 0.8, 5);
        let layout = ParamLayout::new(&p, &[]);
        let at = CellEstimate::nominal(&p, x);
        let chosen: Vec<usize> = (0..30).step_by(2).collect();
        let pred = design_prediction(&p, &layout, &at, &cands, &chosen, &eval, 1).unwrap();
        let a = design_criterion(
            &p,
            &layout,
            &at,
            &cands,
            &chosen,
            &eval,
            DesignCriterion::CooperativeA,
        )
        .unwrap();
        let d =
            design_criterion(&p, &layout, &at, &cands, &chosen, &eval, DesignCriterion::D).unwrap();
        assert!((pred.cooperative_rms_m - a).abs() <= SAME_REL * a);
        assert!((pred.log_det_info - d).abs() <= SAME_REL * d.abs());
        let (_, _, sigma) = subset_posterior(&p, &layout, &at, &cands, &chosen, &eval).unwrap();
        let col = |param| layout.column(&param).unwrap();
        let rho: Vec<usize> = Axis::ALL
            .map(|axis| col(CellParam::PlacementTranslation { axis }))
            .to_vec();
        let phi: Vec<usize> = Axis::ALL
            .map(|axis| col(CellParam::PlacementRotation { axis }))
            .to_vec();
        let block = |r: &[usize], c: &[usize]| Matrix3::from_fn(|i, j| sigma[(r[i], c[j])]);
        let t = -x.translation.vector.cross_matrix();
        // δt = ρ + φ × t = ρ − [t]×·φ.
        let sigma_t = block(&rho, &rho)
            + t * block(&phi, &rho)
            + block(&rho, &phi) * t.transpose()
            + t * block(&phi, &phi) * t.transpose();
        let lo = sigma_t.diagonal().max().sqrt();
        let hi = sigma_t.trace().sqrt();
        // 2000 draws: the rms carries ~2 % sampling error; 5 % margin each side.
        assert!(
            pred.e_tran_m > 0.95 * lo && pred.e_tran_m < 1.05 * hi,
            "e_tran {:e} m outside [{lo:e}, {hi:e}]",
            pred.e_tran_m
        );
        assert!(pred.e_rot_rad.is_finite() && pred.e_rot_rad > 0.0);
        let e = design_prediction(&p, &layout, &at, &cands, &[30], &eval, 1).unwrap_err();
        assert!(e.to_string().contains("out of range"), "{e}");
    }
}

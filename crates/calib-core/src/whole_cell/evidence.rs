//! The prior scales of the whole-cell fit chosen from the session's own evidence: one common
//! scale, or one scale per parameter family (joint offsets, origin xyz, origin rpy, tool tips,
//! other terms), from `10⁻³` (the placement-only limit) up to ×[`MAX_PRIOR_SCALE`]; or a scale
//! the user fixes (`--tolerance-scale`).
//!
//! **The evidence.** At a linearisation point `θ₀` (the screened fit), the whitened data and
//! placement-prior rows are `r_F + J_F·Δ` and the kinematic prior rows `R_s·(θ₀ + Δ)`,
//! `R_s = R_p·S⁻¹` (`S` = each column's family scale; a common scale `s` gives `R_p/s`). The
//! MAP cost of this linear model is minimised exactly: `H = J_FᵀJ_F + Λ_s`, `Λ_s = R_sᵀR_s`,
//! `g = J_Fᵀr_F + Λ_s·θ₀`, `C* = ‖r_F‖² + θ₀ᵀΛ_sθ₀ − gᵀH⁻¹g`, and its Laplace (here exact)
//! log evidence is `log Z(S) = −C*/2 − log det H/2 + log det(R_sR_sᵀ)/2` up to a constant
//! common to every `S` (the unpenalised unknowns' flat prior). One linearisation serves every
//! candidate, so the search costs one Cholesky factor of `H` per candidate, not a fit.
//!
//! **The choice.** (1) The common scale of largest `log Z` over [`PRIOR_SCALES`]. (2) From it,
//! coordinate ascent over the families (each family's scale over [`PRIOR_SCALES`] with the
//! others held, sweeps until nothing changes, at most [`FAMILY_SWEEPS`]). (3) The per-family
//! scales are kept only when they beat the common scale by more than
//! [`FAMILY_EVIDENCE_MARGIN`] nats per family whose scale differs from the common one (a Bayes
//! factor of e² ≈ 7.4 each, "positive" evidence on the Kass–Raftery scale): with one session's
//! noise, separate scales that the evidence barely prefers are not stable, and the common scale
//! is kept. The report gives both evidences and the decision.
//!
//! **The covariance** of the chosen estimator is its error covariance under a reference prior
//! `S_ref` per column: where the evidence widened a family, the widened prior (the data said
//! the robots are further off than stated); where it shrank one, the widest scale up to the
//! stated tolerances that the evidence does not reject by more than
//! [`REFERENCE_EVIDENCE_MARGIN`] nats ([`reference_scales`]): the stated tolerances when the
//! data cannot tell (so the prediction keeps the kinematic error a shrunk fit may leave), less
//! when the data show the family near nominal (a prediction that assumed tolerance-sized errors
//! there would be several times the error measured: 0.96 against 0.35 mm on sim-cell's mixed
//! session). A scale the caller fixed keeps `max(S, 1)`. The formula:
//! `H⁻¹·(J_FᵀJ_F + R_sᵀ·M·Mᵀ·R_s)·H⁻¹`, `M = R_kk·S⁻¹·S_ref·R_kk⁻¹` on the penalised block
//! (`M = I`: the posterior `H⁻¹`).

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::layout::CellParam;
use super::solve::{assemble, sym_inverse, CellFit};
use super::{CellEstimate, CellFitError, CellProblem, ParamLayout};

/// The largest prior scale the evidence may choose: the tolerances ×100.
pub const MAX_PRIOR_SCALE: f64 = 100.0;

/// The scales the evidence compares (every prior σ of a family, or of all, multiplied by `s`),
/// largest first: ×100 down to ×2 (the robots further off than their tolerances), 1 (the
/// tolerances as given), halved down to 1/16, and 1e-3, the placement-only limit (the kinematic
/// parameters held at their nominal values by a prior 1000 times tighter than the tolerances;
/// the same columns, so the evidence and the error covariance stay comparable).
pub const PRIOR_SCALES: [f64; 13] = [
    MAX_PRIOR_SCALE,
    64.0,
    32.0,
    16.0,
    8.0,
    4.0,
    2.0,
    1.0,
    0.5,
    0.25,
    0.125,
    0.0625,
    1e-3,
];

/// Nats of log evidence per family whose scale differs from the common one that the per-family
/// scales must gain over the best common scale to be kept (a Bayes factor of e² each).
pub const FAMILY_EVIDENCE_MARGIN: f64 = 2.0;

/// Coordinate-ascent sweeps over the families, at most.
pub const FAMILY_SWEEPS: usize = 4;

/// How the prior scales were set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum ScaleMethod {
    /// One scale for every family, of largest evidence.
    EvidenceCommon,
    /// One scale per family, of largest evidence, kept because it beat the common scale by the
    /// margin ([`FAMILY_EVIDENCE_MARGIN`] per differing family).
    EvidencePerFamily,
    /// Fixed by the caller (`--tolerance-scale`); no evidence choice.
    Fixed,
    /// No kinematic parameter with a prior is fitted: nothing to scale.
    NoPrior,
}

/// The scale of one family of penalised parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FamilyScale {
    /// The family: the parameters' kind (`joint_offset`, `origin_xyz`, `origin_rpy`, `tip`,
    /// `joint_scale`, `compliance`, `periodic`).
    pub family: &'static str,
    /// Its fitted columns.
    pub parameters: usize,
    /// The scale applied (prior σ = scale × tolerance/√3).
    pub scale: f64,
}

/// The prior scales [`super::calibrate_cell`] applied and why.
#[derive(Debug, Clone, Serialize)]
pub struct PriorScaleChoice {
    /// The common scale of largest evidence (or the fixed scale); equal to every family's scale
    /// unless [`PriorScaleChoice::method`] is [`ScaleMethod::EvidencePerFamily`].
    pub scale: f64,
    /// The scale applied to each family.
    pub families: Vec<FamilyScale>,
    /// How the scales were set.
    pub method: ScaleMethod,
    /// `(s, log evidence)` for every common scale of [`PRIOR_SCALES`] (natural log, up to a
    /// constant common to all scales; linearised at the screened fit, see the module docs).
    pub log_evidence: Vec<(f64, f64)>,
    /// Log evidence of the best per-family scales (`None` when not searched).
    pub family_log_evidence: Option<f64>,
    /// A sentence for people: which scales and why (the evidence values).
    pub why: String,
}

impl PriorScaleChoice {
    /// No prior to scale (a placement-only model).
    pub(crate) fn none() -> Self {
        PriorScaleChoice {
            scale: 1.0,
            families: Vec::new(),
            method: ScaleMethod::NoPrior,
            log_evidence: Vec::new(),
            family_log_evidence: None,
            why: "no kinematic parameter with a prior is fitted".into(),
        }
    }

    /// The scale of `family` (1 if absent).
    pub fn family_scale(&self, family: &str) -> f64 {
        self.families
            .iter()
            .find(|f| f.family == family)
            .map_or(1.0, |f| f.scale)
    }
}

/// The family of a penalised unknown; `None` for an unpenalised one (placement, nuisances).
pub fn prior_family(p: &CellParam) -> Option<&'static str> {
    match p {
        CellParam::Kinematic { param, .. } => Some(match param.kind_name() {
            "periodic_sin" | "periodic_cos" => "periodic",
            k => k,
        }),
        CellParam::ToolTip { .. } => Some("tip"),
        _ => None,
    }
}

/// The linear model of the MAP problem at one estimate (see the module docs).
pub(crate) struct LinearModel {
    /// `J_FᵀJ_F` (data and placement-prior rows).
    a: DMatrix<f64>,
    /// `J_Fᵀr_F`.
    b: DVector<f64>,
    /// `‖r_F‖²`.
    c: f64,
    /// `θ₀`.
    theta0: DVector<f64>,
    /// `R_p` at scale 1.
    r_p: DMatrix<f64>,
    /// Penalised columns.
    penalised: Vec<usize>,
    /// Family index of each penalised column (into `families`).
    family_of: Vec<usize>,
    /// Families present, first-appearance order, with their column counts.
    pub(crate) families: Vec<(&'static str, usize)>,
}

impl LinearModel {
    /// Linearises the MAP problem of `layout` (scale 1) at `fit`'s estimate on its active rows:
    /// from the fit's own linearisation at its optimum when it has one with `layout`'s columns
    /// (the data rows do not depend on the prior scales; the same values a new linearisation
    /// gives), else evaluated now.
    pub(crate) fn new(
        problem: &CellProblem,
        layout: &ParamLayout,
        fit: &CellFit,
    ) -> Result<Self, CellFitError> {
        let est = &fit.estimate;
        let (j_f, r_f) = if layout.params == fit.layout.params {
            let lin = fit.linearisation(problem)?;
            fixed_rows(problem, est, &lin.rows.j, &lin.rows.r, fit.residual_rows)
        } else {
            let sys = assemble(problem, layout, est, &fit.active, None, true)?;
            let p = layout.prior_sqrt_info.nrows();
            let m = sys.r.len();
            let fixed: Vec<usize> = (0..sys.data_rows).chain(sys.data_rows + p..m).collect();
            (sys.j.select_rows(&fixed), sys.r.select_rows(&fixed))
        };
        let r_p = layout.prior_sqrt_info.clone();
        let penalised: Vec<usize> = (0..layout.len())
            .filter(|&j| r_p.column(j).norm_squared() > 0.0)
            .collect();
        let mut families: Vec<(&'static str, usize)> = Vec::new();
        let family_of = penalised
            .iter()
            .map(|&j| {
                let f = prior_family(&layout.params[j]).unwrap_or("other");
                match families.iter().position(|(n, _)| *n == f) {
                    Some(k) => {
                        families[k].1 += 1;
                        k
                    }
                    None => {
                        families.push((f, 1));
                        families.len() - 1
                    }
                }
            })
            .collect();
        Ok(LinearModel {
            a: j_f.transpose() * &j_f,
            b: j_f.transpose() * &r_f,
            c: r_f.norm_squared(),
            theta0: layout.values(est),
            r_p,
            penalised,
            family_of,
            families,
        })
    }

    /// Per-column scales (1 on unpenalised columns) from per-family scales.
    pub(crate) fn column_scales(&self, family_scales: &[f64]) -> DVector<f64> {
        let mut s = DVector::from_element(self.theta0.len(), 1.0);
        for (k, &j) in self.penalised.iter().enumerate() {
            s[j] = family_scales[self.family_of[k]];
        }
        s
    }

    /// `log Z` at per-family scales; `None` when `H` or `R_sR_sᵀ` is singular.
    pub(crate) fn log_evidence(&self, family_scales: &[f64]) -> Option<f64> {
        let s = self.column_scales(family_scales);
        let r_s = scale_columns(&self.r_p, &s);
        let lambda = r_s.transpose() * &r_s;
        let h = &self.a + &lambda;
        let g = &self.b + &lambda * &self.theta0;
        let chol = h.cholesky()?;
        let logdet_h = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
        let delta = chol.solve(&(-&g));
        let cost = self.c + self.theta0.dot(&(&lambda * &self.theta0)) + g.dot(&delta);
        let rr = (&r_s * r_s.transpose()).cholesky()?;
        let logdet_p = 2.0 * rr.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
        let z = -0.5 * cost - 0.5 * logdet_h + 0.5 * logdet_p;
        z.is_finite().then_some(z)
    }
}

/// The rows of the MAP problem the prior scales leave fixed: the first `data_rows` whitened data
/// rows of `j`, `r` (a fit's linearisation), then the placement prior's at `est` (as
/// [`super::solve::assemble`] stacks them after the layout's prior rows).
fn fixed_rows(
    problem: &CellProblem,
    est: &CellEstimate,
    j: &DMatrix<f64>,
    r: &DVector<f64>,
    data_rows: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let (pr, pj) = problem
        .placement_prior
        .map(|pp| pp.linearise(&est.b1_from_b2))
        .unwrap_or_default();
    let n = j.ncols();
    let mut j_f = DMatrix::zeros(data_rows + pr.len(), n);
    let mut r_f = DVector::zeros(data_rows + pr.len());
    j_f.rows_mut(0, data_rows).copy_from(&j.rows(0, data_rows));
    r_f.rows_mut(0, data_rows).copy_from(&r.rows(0, data_rows));
    for (k, (rv, jv)) in pr.iter().zip(&pj).enumerate() {
        r_f[data_rows + k] = *rv;
        for (c, v) in jv.iter().enumerate() {
            j_f[(data_rows + k, c)] = *v;
        }
    }
    (j_f, r_f)
}

/// `m·diag(1/s)`: column `j` divided by `s[j]`.
fn scale_columns(m: &DMatrix<f64>, s: &DVector<f64>) -> DMatrix<f64> {
    let mut out = m.clone();
    for (j, mut col) in out.column_iter_mut().enumerate() {
        col /= s[j];
    }
    out
}

/// `layout` with each column's prior σ multiplied by `s[j]` (`R_p·diag(1/s)`).
pub(crate) fn scaled_layout(layout: &ParamLayout, s: &DVector<f64>) -> ParamLayout {
    let mut l = layout.clone();
    l.prior_sqrt_info = scale_columns(&layout.prior_sqrt_info, s);
    l
}

/// Formats a scale for people: `1e-3`, `0.0625`, `1`, `16`.
pub fn format_scale(s: f64) -> String {
    if s < 0.01 {
        format!("{s:e}")
    } else {
        format!("{s}")
    }
}

/// The evidence's choice at `model` (see the module docs), each family's scale at most
/// `cap(family)` (1 everywhere: the stated tolerances, shrunk or held; `MAX_PRIOR_SCALE / w`
/// for tolerances already widened by `w`, so that the product of all scale changes stays within
/// ×[`MAX_PRIOR_SCALE`]): the per-family scales and the choice's record. `None` when no
/// candidate has a finite evidence.
pub(crate) fn choose(model: &LinearModel, cap: &dyn Fn(&str) -> f64) -> Option<PriorScaleChoice> {
    let nf = model.families.len();
    let caps: Vec<f64> = model.families.iter().map(|(f, _)| cap(f)).collect();
    let allowed = |f: usize, s: f64| s <= caps[f] * (1.0 + 1e-12);
    let widest = caps.iter().copied().fold(0.0, f64::max);
    // A common scale s applies min(s, cap) to each family.
    let common_scales = |s: f64| -> Vec<f64> { caps.iter().map(|&c| s.min(c)).collect() };
    let curve: Vec<(f64, f64)> = PRIOR_SCALES
        .iter()
        .filter(|&&s| s <= widest * (1.0 + 1e-12))
        .filter_map(|&s| model.log_evidence(&common_scales(s)).map(|z| (s, z)))
        .collect();
    let &(common, common_z) = curve.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let common_applied = common_scales(common);
    let mut scales = common_applied.clone();
    let mut best_z = common_z;
    for _ in 0..FAMILY_SWEEPS {
        let mut changed = false;
        for f in 0..nf {
            for &s in &PRIOR_SCALES {
                if s == scales[f] || !allowed(f, s) {
                    continue;
                }
                let mut trial = scales.clone();
                trial[f] = s;
                if let Some(z) = model.log_evidence(&trial) {
                    if z > best_z {
                        best_z = z;
                        scales = trial;
                        changed = true;
                    }
                }
            }
        }
        if !changed {
            break;
        }
    }
    let differing = scales
        .iter()
        .zip(&common_applied)
        .filter(|(s, c)| s != c)
        .count();
    let gain = best_z - common_z;
    let per_family = differing > 0 && gain > FAMILY_EVIDENCE_MARGIN * differing as f64;
    let applied = if per_family {
        scales.clone()
    } else {
        common_applied.clone()
    };
    let listed = |sc: &[f64]| {
        model
            .families
            .iter()
            .zip(sc)
            .map(|((f, _), s)| format!("{f} ×{}", format_scale(*s)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let z1 = curve.iter().find(|(s, _)| *s == 1.0).map(|c| c.1);
    let vs_one = match z1 {
        Some(z1) if common != 1.0 => format!(" ({:+.1} nats over scale 1)", common_z - z1),
        _ => String::new(),
    };
    let why = if differing == 0 {
        format!(
            "common scale {} has the largest log evidence ({common_z:.1}){vs_one}; no family \
             gains by a scale of its own",
            format_scale(common)
        )
    } else if per_family {
        format!(
            "per-family scales ({}) gain {gain:.1} nats of log evidence over the best common scale \
             {} ({common_z:.1}){vs_one}, more than {FAMILY_EVIDENCE_MARGIN} per differing family \
             ({differing})",
            listed(&scales),
            format_scale(common)
        )
    } else {
        format!(
            "common scale {} has the largest log evidence ({common_z:.1}){vs_one}; per-family \
             scales ({}) gain only {gain:.1} nats, not more than {FAMILY_EVIDENCE_MARGIN} per \
             differing family ({differing}): not stable, not used",
            format_scale(common),
            listed(&scales)
        )
    };
    Some(PriorScaleChoice {
        scale: common,
        families: family_scales(model, &applied),
        method: if per_family {
            ScaleMethod::EvidencePerFamily
        } else {
            ScaleMethod::EvidenceCommon
        },
        log_evidence: curve,
        family_log_evidence: (differing > 0).then_some(best_z),
        why,
    })
}

/// A fixed common scale `scale` (`--tolerance-scale`), with the evidence curve for the record.
pub(crate) fn fixed(model: &LinearModel, scale: f64) -> PriorScaleChoice {
    let nf = model.families.len();
    let curve: Vec<(f64, f64)> = PRIOR_SCALES
        .iter()
        .filter_map(|&s| model.log_evidence(&vec![s; nf]).map(|z| (s, z)))
        .collect();
    let best = curve
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|&(s, _)| format!("; the evidence would have chosen {}", format_scale(s)))
        .unwrap_or_default();
    PriorScaleChoice {
        scale,
        families: family_scales(model, &vec![scale; nf]),
        method: ScaleMethod::Fixed,
        log_evidence: curve,
        family_log_evidence: None,
        why: format!(
            "fixed at {} by the caller (--tolerance-scale){best}",
            format_scale(scale)
        ),
    }
}

fn family_scales(model: &LinearModel, scales: &[f64]) -> Vec<FamilyScale> {
    model
        .families
        .iter()
        .zip(scales)
        .map(|(&(family, parameters), &scale)| FamilyScale {
            family,
            parameters,
            scale,
        })
        .collect()
}

/// Log evidence a reference scale may lose against the chosen scales before it is rejected as
/// the reference of the prediction (`reference_scales`, in `evidence.rs`): the per-family margin
/// [`FAMILY_EVIDENCE_MARGIN`].
pub const REFERENCE_EVIDENCE_MARGIN: f64 = FAMILY_EVIDENCE_MARGIN;

/// The reference scale of each family for the prediction (see the module docs): the largest
/// scale from `chosen[f]` up to `upper[f]` (the stated tolerances, or the chosen scale where it
/// widened them) whose log evidence, with the other families at their chosen scales, is within
/// [`REFERENCE_EVIDENCE_MARGIN`] nats of the chosen scales'. Where the data cannot tell the
/// scales apart (high noise, a family the session barely sees), that is the stated tolerances,
/// so the prediction keeps the error a shrunk fit may leave; where the data show a family near
/// nominal (the evidence prefers a small scale by more than the margin), the prediction does
/// not assume the tolerance-sized errors the data rule out.
pub(crate) fn reference_scales(model: &LinearModel, chosen: &[f64], upper: &[f64]) -> Vec<f64> {
    let Some(best) = model.log_evidence(chosen) else {
        return upper.to_vec();
    };
    let mut out = chosen.to_vec();
    for f in 0..chosen.len() {
        if upper[f] <= chosen[f] {
            continue;
        }
        let mut candidates: Vec<f64> = PRIOR_SCALES
            .iter()
            .copied()
            .filter(|&c| c > chosen[f] && c < upper[f])
            .collect();
        candidates.push(upper[f]);
        candidates.sort_by(|a, b| b.total_cmp(a));
        for c in candidates {
            let mut trial = chosen.to_vec();
            trial[f] = c;
            if model
                .log_evidence(&trial)
                .is_some_and(|z| z >= best - REFERENCE_EVIDENCE_MARGIN)
            {
                out[f] = c;
                break;
            }
        }
    }
    out
}

/// The error covariance of `fit` (fitted at column scales `s`) under the reference prior
/// `s_ref` per column ([`reference_scales`]; see the module docs).
pub(crate) fn reference_covariance(
    problem: &CellProblem,
    fit: &CellFit,
    s: &DVector<f64>,
    s_ref: &DVector<f64>,
) -> Result<DMatrix<f64>, CellFitError> {
    if s == s_ref {
        return Ok(fit.covariance.clone());
    }
    let h = fit.information(problem)?;
    let r_s = &fit.layout.prior_sqrt_info;
    let lambda = r_s.transpose() * r_s;
    let penalised: Vec<usize> = (0..r_s.ncols())
        .filter(|&j| r_s.column(j).norm_squared() > 0.0)
        .collect();
    // R_kk at scale 1 and M = R_kk·S⁻¹·S_ref·R_kk⁻¹.
    let r_kk = DMatrix::from_fn(r_s.nrows(), penalised.len(), |a, b| {
        r_s[(a, penalised[b])] * s[penalised[b]]
    });
    let Some(r_inv) = r_kk.clone().try_inverse() else {
        return Ok(fit.covariance.clone());
    };
    let ratio = DMatrix::from_diagonal(&DVector::from_iterator(
        penalised.len(),
        penalised.iter().map(|&j| s_ref[j] / s[j]),
    ));
    let m = &r_kk * ratio * r_inv;
    let middle = &h - &lambda + r_s.transpose() * (&m * m.transpose()) * r_s;
    let (h_inv, _) = sym_inverse(&h);
    Ok(&h_inv * middle * &h_inv)
}

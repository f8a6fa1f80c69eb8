//! Identifiability of candidate parameters: columns projected out of the `b1_from_b2` span and of
//! the fitted parameters, no-effect / confounded / parallel groups, and the detectable size.

use super::fit::{check_params, linearise, IdentFit, Linearisation};
use super::model::{IdentifyError, TipModel};
use crate::stats::normal_quantile;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Identifiability verdict of one candidate parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum IdentStatus {
    /// Its column is not in the span of the base frame and fitted parameters.
    Identifiable,
    /// It does not move either tip at these configurations (zero column).
    NoEffect,
    /// Its column lies in the span of `b1_from_b2`'s 6 columns (and the fitted parameters): it is
    /// absorbed by the base-frame fit.
    ConfoundedWithBase,
}

/// Identifiability of one candidate.
#[derive(Debug, Clone)]
pub struct ParamIdent {
    /// Catalogue index.
    pub param: usize,
    /// Norm of its raw residual-Jacobian column (m per parameter unit).
    pub column_norm: f64,
    /// Norm after projecting out `b1_from_b2` and the fitted parameters (score-test column).
    pub projected_norm: f64,
    /// Norm after projecting out rigid motions of both base frames and the fitted parameters,
    /// divided by `column_norm` (0 when the column is zero): the fraction of its effect that no
    /// base-frame fit can absorb.
    pub ratio: f64,
    /// Verdict.
    pub status: IdentStatus,
}

/// Identifiability of a catalogue at a fit.
#[derive(Debug, Clone)]
pub struct Identifiability {
    /// Per candidate, in the order given.
    pub params: Vec<ParamIdent>,
    /// Groups (≥ 2 members, catalogue indices) of identifiable candidates whose projected columns
    /// are parallel (|cos| above the threshold): the data cannot tell them apart.
    pub groups: Vec<Vec<usize>>,
    /// Columns projected out of the fit's span (`b1_from_b2` and fitted parameters), one per
    /// candidate (3n rows): the score test's columns.
    pub projected: DMatrix<f64>,
    /// Columns projected out of the rigid motions of both base frames and the fitted parameters:
    /// the verdicts, groups and [`Identifiability::family`] use these.
    pub gauge_projected: DMatrix<f64>,
}

/// Rank and conditioning of a family of candidates after projecting out the base frame.
#[derive(Debug, Clone)]
pub struct FamilyIdent {
    /// Numerical rank of the family's projected columns, each scaled by its raw norm (members
    /// without effect excluded): the number of independent directions the data can estimate.
    pub rank: usize,
    /// Number of candidates in the family.
    pub size: usize,
    /// Singular values of the unit-normalised projected columns of the family's non-zero raw
    /// columns, descending (dimensionless).
    pub singular_values: Vec<f64>,
    /// Condition number `s_max/s_min` over those singular values (infinite when rank-deficient).
    pub condition: f64,
}

impl Identifiability {
    /// Rank and condition of the candidates at positions `members` (positions in `params`).
    pub fn family(&self, members: &[usize]) -> FamilyIdent {
        let cols: Vec<DVector<f64>> = members
            .iter()
            .filter(|&&m| {
                self.params[m].column_norm > 0.0 && self.params[m].status != IdentStatus::NoEffect
            })
            .map(|&m| {
                let c = self.gauge_projected.column(m).into_owned();
                c / self.params[m].column_norm
            })
            .collect();
        if cols.is_empty() {
            return FamilyIdent {
                rank: 0,
                size: members.len(),
                singular_values: vec![],
                condition: f64::INFINITY,
            };
        }
        let a = DMatrix::from_columns(&cols);
        let mut s: Vec<f64> = a.singular_values().iter().cloned().collect();
        s.sort_by(|x, y| y.total_cmp(x));
        // The columns are scaled by their RAW norms, so a singular value is the fraction of a
        // unit effect that survives the projection: compare it with RANK_TOL absolutely (a
        // family whose members are all confounded with the base has rank 0).
        let smax = s[0];
        let rank = s.iter().filter(|&&v| v > RANK_TOL).count();
        let condition = if rank == s.len() && rank > 0 {
            smax / s[s.len() - 1]
        } else {
            f64::INFINITY
        };
        FamilyIdent {
            rank,
            size: members.len(),
            singular_values: s,
            condition,
        }
    }
}

/// Relative tolerance below which a projected column counts as zero (confounded), and for ranks.
/// Exactly confounded columns project to ~1e-12 relative; 1e-6 leaves margin for round-off and
/// for the curvature of the fit while still flagging any parameter whose identifiable part is a
/// millionth of its effect (it could never be estimated from handclasp data anyway).
pub const RANK_TOL: f64 = 1e-6;

/// RMS tip displacement (m) of a parameter at its typical magnitude ([`TipModel::param_scale`])
/// below which it counts as having no effect: 0.1 µm, a thousandth of the smallest handclasp
/// noise (0.1 mm); even at 20× its typical magnitude such a parameter moves the tips by 2 µm RMS,
/// which no handclasp session can see (noncentrality < 0.1 with 60 points at σ = 0.1 mm).
/// (It was 1 nm: then robot 2's joint-1 compliance on a floor–floor cell, whose only torque comes
/// from the 0.001° tilt of Table 1's placement, counted as "identifiable" with a minimum
/// detectable value of ~4000 deg/(kN·m).)
pub const NO_EFFECT_M: f64 = 1e-7;

/// Projects candidate columns out of the base frame and the fit's parameters at `fit`'s solution.
/// `group_cos` (e.g. 0.999) is the |cos| above which two projected columns count as parallel.
pub fn analyze_identifiability(
    model: &dyn TipModel,
    fit: &IdentFit,
    candidates: &[usize],
    group_cos: f64,
) -> Result<Identifiability, IdentifyError> {
    identifiability_and_linearisation(model, fit, candidates, group_cos).map(|(id, _)| id)
}

/// [`analyze_identifiability`] and the linearisation it was computed from (at `fit`'s state,
/// Jacobian columns `[b1_from_b2; fit.params; candidates]`): the selection scores candidates
/// with its residuals, which are those of `linearise(…, &[], false)` at that state bit for bit
/// (the tips do not depend on the Jacobian columns asked for), so no second pass over the
/// points is needed.
pub(super) fn identifiability_and_linearisation(
    model: &dyn TipModel,
    fit: &IdentFit,
    candidates: &[usize],
    group_cos: f64,
) -> Result<(Identifiability, Linearisation), IdentifyError> {
    check_params(model, candidates)?;
    let lin = linearise(
        model,
        &fit.points,
        &fit.b1_from_b2,
        &fit.params,
        &fit.values,
        candidates,
        true,
    )?;
    let base_cols = 6 + fit.params.len();
    let raw = lin
        .jacobian
        .columns(base_cols, candidates.len())
        .into_owned();
    let n = fit.points.len();
    // The two projections are independent: computed side by side on rayon's current pool (each
    // the same arithmetic as alone, so the result does not depend on the thread count).
    let (projected, gauge_projected) = rayon::join(
        || {
            // Scoring projection: out of the 6 b1_from_b2 columns and the fitted parameters.
            let basis = orthonormal_basis(&lin.jacobian.columns(0, base_cols).into_owned());
            &raw - &basis * (basis.transpose() * &raw)
        },
        || {
            // Gauge projection for the verdicts: a rigid motion of EITHER base frame. Robot 2's
            // base motion is spanned by the fit's columns (rotation about points X·p2); robot
            // 1's base motion rotates about its own tips p1, which differ from X·p2 by the
            // residuals. Adding the 3 columns [p1]ₓ makes "confounded with a base frame" exact
            // whatever the noise (without them, a robot-1 joint-1 offset would look
            // identifiable to the size of the residuals).
            let mut gauge = DMatrix::zeros(3 * n, base_cols + 3);
            gauge
                .columns_mut(0, base_cols)
                .copy_from(&lin.jacobian.columns(0, base_cols));
            for (row, (p1, w)) in lin.p1_b1.iter().zip(&lin.weights).enumerate() {
                gauge
                    .fixed_view_mut::<3, 3>(3 * row, base_cols)
                    .copy_from(&(w * p1.cross_matrix()));
            }
            let gauge_basis = orthonormal_basis(&gauge);
            &raw - &gauge_basis * (gauge_basis.transpose() * &raw)
        },
    );
    let mut params = Vec::with_capacity(candidates.len());
    for (c, &p) in candidates.iter().enumerate() {
        let column_norm = raw.column(c).norm();
        let projected_norm = projected.column(c).norm();
        let gauge_norm = gauge_projected.column(c).norm();
        let rms_effect = column_norm * model.param_scale(p) / ((3 * n) as f64).sqrt();
        let (ratio, status) = if rms_effect < NO_EFFECT_M || !column_norm.is_finite() {
            (0.0, IdentStatus::NoEffect)
        } else {
            let ratio = gauge_norm / column_norm;
            if ratio < RANK_TOL {
                (ratio, IdentStatus::ConfoundedWithBase)
            } else {
                (ratio, IdentStatus::Identifiable)
            }
        };
        params.push(ParamIdent {
            param: p,
            column_norm,
            projected_norm,
            ratio,
            status,
        });
    }
    let groups = parallel_groups(&gauge_projected, &params, group_cos);
    Ok((
        Identifiability {
            params,
            groups,
            projected,
            gauge_projected,
        },
        lin,
    ))
}

fn parallel_groups(
    projected: &DMatrix<f64>,
    params: &[ParamIdent],
    group_cos: f64,
) -> Vec<Vec<usize>> {
    let m = params.len();
    let mut group_of: Vec<Option<usize>> = vec![None; m];
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // Each identifiable column normalised once (not once per pair: 80 candidates at 6,000
    // residual rows made this a tenth of a diagnosis); the same values, so the same groups.
    let unit: Vec<Option<DVector<f64>>> = (0..m)
        .into_par_iter()
        .map(|a| {
            (params[a].status == IdentStatus::Identifiable).then(|| projected.column(a).normalize())
        })
        .collect();
    // Per column, the later columns parallel to it: every pair's test on rayon's current pool
    // (the same dot products as one at a time), the groups then formed in column order below.
    let parallel_to: Vec<Vec<usize>> = (0..m)
        .into_par_iter()
        .map(|a| {
            let Some(ua) = &unit[a] else {
                return Vec::new();
            };
            ((a + 1)..m)
                .filter(|&b| {
                    unit[b]
                        .as_ref()
                        .is_some_and(|ub| ua.dot(ub).abs() > group_cos)
                })
                .collect()
        })
        .collect();
    for a in 0..m {
        if group_of[a].is_some() || unit[a].is_none() {
            continue;
        }
        let mut members = vec![a];
        members.extend(parallel_to[a].iter().filter(|&&b| group_of[b].is_none()));
        if members.len() > 1 {
            let gi = groups.len();
            for &mm in &members {
                group_of[mm] = Some(gi);
            }
            groups.push(members.iter().map(|&mm| params[mm].param).collect());
        }
    }
    groups
}

/// Orthonormal basis of the column space of `a` (numerical rank, relative 1e-10 on unit-scaled
/// columns).
fn orthonormal_basis(a: &DMatrix<f64>) -> DMatrix<f64> {
    let n = a.ncols();
    let mut scaled = a.clone();
    for j in 0..n {
        let norm = scaled.column(j).norm();
        if norm > 0.0 {
            scaled.column_mut(j).scale_mut(1.0 / norm);
        }
    }
    let svd = scaled.svd(true, false);
    let u = svd.u.expect("SVD computed with U");
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&i| svd.singular_values[i] > 1e-10 * smax.max(1e-300))
        .collect();
    DMatrix::from_columns(&keep.iter().map(|&i| u.column(i)).collect::<Vec<_>>())
}

/// Smallest |value| of each candidate this design detects with 80% power in the first selection
/// step (two-sided z test at `α/m`, `m` = identifiable candidates): `(z_{1−α/2m} + z_{0.8})·σ/‖p_j‖`
/// with `p_j` the column projected out of the base frame, in the parameter's unit; infinite for
/// candidates that are not identifiable. `sigma` is the per-axis noise σ, m.
pub fn min_detectable(ident: &Identifiability, alpha: f64, sigma: f64) -> Vec<f64> {
    let m = ident
        .params
        .iter()
        .filter(|p| p.status == IdentStatus::Identifiable)
        .count()
        .max(1);
    let k = normal_quantile(1.0 - alpha / (2.0 * m as f64)) + normal_quantile(0.8);
    ident
        .params
        .iter()
        .map(|p| {
            if p.status == IdentStatus::Identifiable && p.projected_norm > 0.0 {
                k * sigma / p.projected_norm
            } else {
                f64::INFINITY
            }
        })
        .collect()
}

//! Base-parameter reduction: which kinematic parameters the observations cannot determine
//! (see the module documentation of [`crate::whole_cell`]).

use nalgebra::{DMatrix, DMatrixView, DVector, DVectorView};
use rayon::prelude::*;
use serde::Serialize;

use super::solve::assemble;
use super::{CellEstimate, CellFitError, CellParam, CellProblem, ParamLayout};

/// A kinematic column whose remaining norm, after projecting out the unpenalised unknowns and
/// the kinematic columns kept before it (pivoted Gram–Schmidt), is at most this fraction of its
/// raw norm is undetermined by the data.
///
/// Why 1 %: a confounding that is exact where the model fits the data (robot 1 turning about its
/// base axis and `b1_from_b2` turning with it, say) is only approximate at a linearisation point
/// whose residuals are of relative size ε (kinematic errors of ~1 mm on ~1 m arms: ε ≈ 1e-3, more
/// with 4 mm noise), so such columns keep a fraction ~ε of their norm. And a column with less
/// than 1 % of its effect independent carries, in prior-σ units, at most 1e-4 of its raw
/// information: unless the data are ~10⁴ times more informative than the prior it is decided by
/// the prior anyway, so holding it (or merging it, which keeps its prior) loses nothing.
pub const RANK_TOL: f64 = 1e-2;

/// A kinematic column whose data information, in prior-σ units (the squared norm of its
/// whitened, prior-scaled column, the prior's own information being 1), is at most this is
/// decided by the prior: it is held at nominal ([`ReductionReason::PriorDecided`]) and never
/// kept as a pivot for other columns to merge into.
///
/// Why 1e-8: alone, such a column's posterior σ differs from its prior σ by a relative
/// `1 − 1/√(1 + info) ≤ info/2 = 5e-9`, far below anything the fit reports, so holding it loses
/// nothing. Keeping it does harm: the relative [`RANK_TOL`] test passes on its own tiny norm, and
/// a column that depends on the kept ones only through it gets a merge coefficient of (its own
/// residual) / (that norm) ≥ 1e4 × its residual, in prior-σ units. Measured: face
/// contacts whose normals all lie along robot 1's flange z leave the tools' sideways offsets with
/// information ≤ 2e-15 (`cells/ctu-motoman.toml`, 40 rows), and merging onto them gave
/// coefficients of 3e7 … 3e9 and merged prior σ of metres; the smallest information of a column
/// those sessions do see was 1.5e-5, three orders above the threshold. Unchanged by it: every
/// existing test, the golden outputs and the CTU study's outputs (byte-identical).
pub const PRIOR_INFO_TOL: f64 = 1e-8;

/// A column that only a held placement motion tells apart from the unpenalised unknowns and the
/// columns kept before it (see [`reduce_layout`]) is kept only if the data carry at least this
/// much information on it, in prior-σ units (the prior's own being 1): the boundary where the
/// data, not the prior, decide it ([`Reduction::data_determined`], and the held/free boundary
/// of the placement's motions). Below it the prior decides the column, and keeping it as a
/// pivot merged others onto it with coefficients of 6 … 30 prior σ (CTU session of
/// `tools/bench/ctu_diagnose.sh`: robot 2's tip z, information 2.6e-3, independent fraction
/// 1.1 %, just over [`RANK_TOL`]). Chosen after that measurement (the rule of commit ba240fa,
/// without it, was run on CTU first).
pub const HELD_ONLY_MIN_INFO: f64 = 1.0;

/// Why a parameter was dropped.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "reason", rename_all = "snake_case")]
#[non_exhaustive]
pub enum ReductionReason {
    /// It moves no observed tip.
    NoEffect,
    /// A shared trunk's parameter ([`super::CellRobot::shared_joints`]) that moves both arms'
    /// tips alike, which the rows (handclasps, contacts: where the hands meet) do not see.
    MovesBothHandsAlike,
    /// Its effect is a rigid motion the placement `b1_from_b2` absorbs: a free placement, or a
    /// motion of it that its prior ([`super::PlacementPrior`]) holds more loosely than the data
    /// see it (a motion the prior holds more tightly absorbs nothing: it is fixed for the rank
    /// test).
    ConfoundedWithPlacement,
    /// Its effect is absorbed by the placement together with the nuisance unknowns (tracker
    /// frames, planes, contact distances).
    ConfoundedWithNuisance,
    /// The data carry at most [`PRIOR_INFO_TOL`] of its prior information: the prior decides
    /// it, so it is held at nominal (e.g. a tool's sideways offset when every observation is a
    /// distance along the flange z).
    PriorDecided,
    /// Its effect is a combination of kept parameters (and the unpenalised unknowns): those
    /// parameters now stand for it (their prior covariance carries its prior).
    MergedInto {
        /// The kept parameters (readable names) with their coefficients in prior-σ units
        /// (`|c| ≥ 1e-6`).
        into: Vec<(String, f64)>,
    },
}

/// One dropped parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ReductionEntry {
    /// The parameter.
    pub param: CellParam,
    /// Readable name.
    pub name: String,
    /// Why.
    pub reason: ReductionReason,
    /// Fraction of its (whitened, prior-scaled) effect left after projecting out the unknowns
    /// that absorb it (0 … [`RANK_TOL`]; any value for [`ReductionReason::PriorDecided`]).
    pub independent_fraction: f64,
    /// A sentence for people, e.g. "robot 2 origin_xyz joint 1 x is confounded with b1_from_b2".
    pub message: String,
}

/// Result of [`reduce`].
#[derive(Debug, Clone)]
pub struct Reduction {
    /// The reduced layout: dropped parameters removed, the merged prior in `prior_sqrt_info`.
    pub layout: ParamLayout,
    /// What was dropped and why.
    pub dropped: Vec<ReductionEntry>,
    /// Kinematic parameters kept.
    pub kept: usize,
    /// Directions of the kept kinematic parameters (in prior-σ units, unpenalised unknowns
    /// projected out) where the data carry at least as much information as the prior
    /// (singular value ≥ 1).
    pub data_determined: usize,
    /// Directions where the prior dominates (singular value < 1): the prior decides them.
    pub prior_dominated: usize,
}

/// Finds and removes the structurally undetermined kinematic parameters of `problem`'s
/// observations `active`, linearised at `estimate` (normally the nominal robots at the starting
/// placement). See the module documentation for the maths.
///
/// Errors: as the linearisation (invalid input, model failures).
pub fn reduce(
    problem: &CellProblem,
    estimate: &CellEstimate,
    active: &[usize],
) -> Result<Reduction, CellFitError> {
    reduce_layout(problem, &ParamLayout::new(problem, &[]), estimate, active)
}

/// [`reduce`] within the unknowns of `full` (a fit's layout: the parameters it does not hold
/// stay held): which of its penalised columns the observations `active`, linearised at
/// `estimate`, cannot determine. The rank test reads each column's prior σ off the diagonal of
/// `full`'s prior information ([`ParamLayout::prior_sigma`]), so the returned layout's merged
/// prior is built from those σ (a non-diagonal prior of `full` is not carried over); `dropped`
/// is what callers of a fitted layout use ([`super::placement_rotation_posterior`]).
///
/// A placement prior ([`super::PlacementPrior`]: `[b1_from_b2] sigma_mm/sigma_deg`, a shared
/// trunk's identity) holds the motions of `b1_from_b2` it knows better than the data see them
/// (held: the data's information on that motion, the nuisances projected out, is below the
/// prior's; the private `free_placement_directions` states the rule): those are fixed for the
/// rank test, which then reads the data rows only, and the rest absorb as a free placement
/// does. A shared trunk
/// held still (identity at 1 µm / 1 µrad) thus keeps the shoulders; a placement the data see
/// through is the free registration it was. A column that only the held motions tell apart
/// (the same Gram–Schmidt with the whole placement free, run on the same pivots, leaves it at
/// most [`RANK_TOL`] of its raw norm) is a pivot only if the data carry at least
/// [`HELD_ONLY_MIN_INFO`] of its prior information: else the prior decides it.
///
/// Errors: as [`reduce`].
pub fn reduce_layout(
    problem: &CellProblem,
    full: &ParamLayout,
    estimate: &CellEstimate,
    active: &[usize],
) -> Result<Reduction, CellFitError> {
    let sys = assemble(problem, full, estimate, active, None, true)?;
    // The data rows, read in place (the prior rows after them are not the reduction's).
    let jd = sys.j.rows(0, sys.data_rows);
    let n = full.len();
    let sig: Vec<f64> = (0..n).map(|j| full.prior_sigma(j)).collect();
    let unpen: Vec<usize> = (0..n).filter(|&j| sig[j] == 0.0).collect();
    let kin: Vec<usize> = (0..n).filter(|&j| sig[j] > 0.0).collect();
    let placement: Vec<usize> = (0..6).collect();
    let nuisance: Vec<usize> = unpen.iter().copied().filter(|&j| j >= 6).collect();
    // The placement prior's whitened rows (after the data's and the kinematic prior's).
    let prior_rows = sys.data_rows + full.prior_sqrt_info.nrows();
    let l_place = sys
        .j
        .view((prior_rows, 0), (sys.j.nrows() - prior_rows, 6))
        .into_owned();
    let free = free_placement_directions(&jd, &nuisance, &l_place);
    // All six free (no prior, or one the data see better than it holds): the old projection,
    // byte for byte.
    let (q_all, q_place) = if free.ncols() == 6 {
        (
            orthonormal_basis(&jd.select_columns(&unpen)),
            orthonormal_basis(&jd.select_columns(&placement)),
        )
    } else {
        let p_free = jd.select_columns(&placement) * &free;
        let mut absorbing = jd.select_columns(&nuisance);
        let nn = absorbing.ncols();
        absorbing = absorbing.insert_columns(nn, p_free.ncols(), 0.0);
        absorbing.columns_mut(nn, p_free.ncols()).copy_from(&p_free);
        (orthonormal_basis(&absorbing), orthonormal_basis(&p_free))
    };
    let project = |q: &DMatrix<f64>, a: &DMatrix<f64>| a - q * (q.transpose() * a);
    // Kinematic columns in prior-σ units.
    let mut a_raw = jd.select_columns(&kin);
    for (c, &j) in kin.iter().enumerate() {
        a_raw.column_mut(c).scale_mut(sig[j]);
    }
    let a = project(&q_all, &a_raw);
    let raw_norm: Vec<f64> = (0..kin.len()).map(|c| a_raw.column(c).norm()).collect();
    let max_raw = raw_norm.iter().cloned().fold(0.0, f64::max);
    // Pivoted modified Gram–Schmidt with a relative (own-norm) rank test.
    let k = kin.len();
    let own: Vec<f64> = (0..k).map(|c| a.column(c).norm()).collect();
    let mut work = a.clone();
    let mut remaining: Vec<usize> = (0..k).collect();
    let mut kept_order: Vec<usize> = Vec::new();
    let mut q_cols: Vec<DVector<f64>> = Vec::new();
    // Each column's current norm (the pivot test reads it once per step, not per comparison).
    let mut norm: Vec<f64> = (0..k).map(|c| work.column(c).norm()).collect();
    // With held placement motions, the same Gram–Schmidt with the whole placement free (the
    // projection without a prior), run alongside on the same pivots: a column new only through
    // the held motions (its free-placement norm at most `RANK_TOL` of its raw norm) is a pivot
    // only if the data carry at least its prior's information on it (`norm² ≥ 1`, prior-σ
    // units: [`HELD_ONLY_MIN_INFO`]); else the prior decides it and it is dropped like any column
    // the rank test does not keep (it would be a pivot the data barely see, others merging onto
    // it with large coefficients).
    let mut free_gs = (free.ncols() < 6).then(|| {
        let w = project(&orthonormal_basis(&jd.select_columns(&unpen)), &a_raw);
        let nf: Vec<f64> = (0..k).map(|c| w.column(c).norm()).collect();
        (w, nf)
    });
    // Columns only the held motions tell apart from the unpenalised unknowns, with less data
    // information than [`HELD_ONLY_MIN_INFO`]: reported as a free placement would report them.
    let held_only: Vec<bool> = (0..k)
        .map(|c| {
            free_gs.as_ref().is_some_and(|(_, nf)| {
                nf[c] <= RANK_TOL * raw_norm[c] && own[c].powi(2) < HELD_ONLY_MIN_INFO
            })
        })
        .collect();
    // The whole placement's motions, for reporting those columns.
    let q_place_all = if held_only.contains(&true) {
        orthonormal_basis(&jd.select_columns(&placement))
    } else {
        DMatrix::zeros(jd.nrows(), 0)
    };
    loop {
        let best = remaining
            .iter()
            .copied()
            .filter(|&c| {
                raw_norm[c] > 0.0
                    && raw_norm[c].powi(2) > PRIOR_INFO_TOL
                    && norm[c] > RANK_TOL * raw_norm[c]
                    && free_gs.as_ref().is_none_or(|(_, nf)| {
                        nf[c] > RANK_TOL * raw_norm[c] || norm[c].powi(2) >= HELD_ONLY_MIN_INFO
                    })
            })
            .max_by(|&x, &y| norm[x].total_cmp(&norm[y]));
        let Some(p) = best else { break };
        let q = work.column(p).normalize();
        remaining.retain(|&c| c != p);
        project_out(&mut work, &q, &remaining, &mut norm);
        if let Some((w, nf)) = free_gs.as_mut() {
            if nf[p] > 0.0 {
                let qf = w.column(p).normalize();
                project_out(w, &qf, &remaining, nf);
            }
        }
        kept_order.push(p);
        q_cols.push(q);
    }
    // Dependency coefficients of each dropped column on the kept ones: least squares in the
    // projected space, a_j ≈ A_keep·c.
    let a_keep = a.select_columns(&kept_order);
    // No kept column (no kinematic unknown, or none the data determine): nothing to merge into,
    // and nalgebra's SVD of a matrix without columns would panic.
    let ls = (!kept_order.is_empty()).then(|| a_keep.svd(true, true));
    let mut dropped = Vec::new();
    // The parameters `full` holds stay held in the reduced layout.
    let mut fixed: Vec<CellParam> = ParamLayout::new(problem, &[])
        .params
        .into_iter()
        .filter(|p| full.column(p).is_none())
        .collect();
    // Merged prior covariance over the kept columns, prior-σ units (starts at I).
    let kk = kept_order.len();
    let mut prior_cov = DMatrix::<f64>::identity(kk, kk);
    let mut dropped_cols = remaining.clone();
    dropped_cols.sort_unstable();
    // A one-robot cell (no observation of robot 2): there is no placement to speak of, and the
    // nuisance unknowns (the tracker frame, the plane) stand where the robot's base is seen from.
    let robot2_seen = active.iter().any(|&i| {
        let kind = &problem.observations[i].kind;
        kind.kind().two_robot()
            || matches!(
                kind,
                super::ObservationKind::Tracker {
                    robot: crate::Robot::Two,
                    ..
                } | super::ObservationKind::Plane {
                    robot: crate::Robot::Two,
                    ..
                }
            )
    });
    // A shared trunk: b1_from_b2 is the identity its prior holds (the arms' one base).
    let shared_trunk = problem.robot2.shared_joints > 0;
    for &c in &dropped_cols {
        let param = full.params[kin[c]].clone();
        let name = param.describe(problem);
        let (reason, message) = if raw_norm[c] <= 1e-12 * max_raw.max(1e-300) {
            if on_shared_trunk(problem, &param) {
                (
                    ReductionReason::MovesBothHandsAlike,
                    format!(
                        "{name} is the shared trunk's: it moves both hands alike, and these rows \
                         see only where the hands meet: held at 0 (a tracker or plane row of \
                         either arm sees it)"
                    ),
                )
            } else {
                (
                    ReductionReason::NoEffect,
                    format!("{name} moves no observed tip: held at 0"),
                )
            }
        } else if own[c] <= RANK_TOL * raw_norm[c] || held_only[c] {
            let q = if held_only[c] { &q_place_all } else { &q_place };
            let in_place = project(q, &a_raw.columns(c, 1).into_owned()).norm();
            if in_place <= RANK_TOL * raw_norm[c] || nuisance.is_empty() {
                (
                    ReductionReason::ConfoundedWithPlacement,
                    if shared_trunk {
                        format!(
                            "{name} moves robot 2's tips against robot 1's as a move of \
                             b1_from_b2 would, which the shared trunk holds at the identity: \
                             held at 0"
                        )
                    } else if robot2_seen {
                        format!(
                            "{name} is confounded with b1_from_b2: held at 0, the placement \
                             absorbs it"
                        )
                    } else {
                        format!(
                            "{name} is confounded with the robot's base frame: held at 0, the \
                             tracker/plane unknowns absorb it"
                        )
                    },
                )
            } else {
                (
                    ReductionReason::ConfoundedWithNuisance,
                    if shared_trunk {
                        format!(
                            "{name} is confounded with the tracker/plane/contact unknowns (and \
                             b1_from_b2, which the shared trunk holds at the identity): held at \
                             0, they absorb it"
                        )
                    } else if robot2_seen {
                        format!(
                            "{name} is confounded with b1_from_b2 and the tracker/plane/contact \
                             unknowns: held at 0, they absorb it"
                        )
                    } else {
                        format!(
                            "{name} is confounded with the tracker/plane unknowns (where the \
                             measuring device sees the robot's base): held at 0, they absorb it"
                        )
                    },
                )
            }
        } else if raw_norm[c].powi(2) <= PRIOR_INFO_TOL {
            (
                ReductionReason::PriorDecided,
                format!(
                    "{name} is barely seen by the data (information {:.1e} of its prior's): \
                     held at 0, the prior decides it",
                    raw_norm[c].powi(2)
                ),
            )
        } else {
            let coeff = ls
                .as_ref()
                .and_then(|ls| ls.solve(&a.column(c).into_owned(), 1e-12).ok())
                .unwrap_or_else(|| DVector::zeros(kk));
            prior_cov += &coeff * coeff.transpose();
            let into: Vec<(String, f64)> = kept_order
                .iter()
                .zip(coeff.iter())
                .filter(|(_, v)| v.abs() >= 1e-6)
                .map(|(&kc, &v)| (full.params[kin[kc]].describe(problem), v))
                .collect();
            let names: Vec<String> = into.iter().map(|(s, v)| format!("{v:+.3}·{s}")).collect();
            (
                ReductionReason::MergedInto { into },
                format!(
                    "{name} cannot be separated from {}: merged into them (held at 0)",
                    names.join(", ")
                ),
            )
        };
        fixed.push(param.clone());
        let independent_fraction = if raw_norm[c] > 0.0 {
            work.column(c).norm() / raw_norm[c]
        } else {
            0.0
        };
        dropped.push(ReductionEntry {
            param,
            independent_fraction,
            name,
            reason,
            message,
        });
    }
    let mut layout = ParamLayout::new(problem, &fixed);
    // The merged prior: Σ_keep = D·prior_cov·D; R_p = L⁻¹ with Σ_keep = L·Lᵀ.
    let new_cols: Vec<usize> = kept_order
        .iter()
        .map(|&kc| {
            layout
                .column(&full.params[kin[kc]])
                .expect("kept parameters are in the reduced layout")
        })
        .collect();
    let d = DVector::from_iterator(kk, kept_order.iter().map(|&kc| sig[kin[kc]]));
    let cov = DMatrix::from_fn(kk, kk, |x, y| prior_cov[(x, y)] * d[x] * d[y]);
    let l_inv = cov
        .cholesky()
        .and_then(|c| c.l().try_inverse())
        .ok_or_else(|| {
            CellFitError::InvalidInput("merged prior covariance is not positive definite".into())
        })?;
    let mut r_p = DMatrix::zeros(kk, layout.len());
    for (x, &cx) in new_cols.iter().enumerate() {
        for y in 0..kk {
            r_p[(y, cx)] = l_inv[(y, x)];
        }
    }
    layout.prior_sqrt_info = r_p;
    let data_determined = match &ls {
        Some(ls) => ls.singular_values.iter().filter(|&&v| v >= 1.0).count(),
        None => 0,
    };
    Ok(Reduction {
        layout,
        dropped,
        kept: kk,
        data_determined,
        prior_dominated: kk - data_determined,
    })
}

/// The placement directions a placement prior does not hold: the columns (placement
/// perturbation coordinates `(ρ, φ)`, 6 × f) of a basis of the motions of `b1_from_b2` that
/// [`reduce_layout`] lets absorb kinematic columns. `jd` is the whitened data Jacobian,
/// `nuisance` its unpenalised columns other than the placement's (0..6), `l_place` the
/// placement prior's whitened rows (none: no prior).
///
/// The rule ("held" is what the prior decides, "free" what the data do; the same boundary as
/// [`Reduction::data_determined`]): in the prior's metric (`G = LᵀL`), the data information on
/// the placement with the nuisance unknowns (and the motions the prior leaves unpenalised)
/// projected out is `H = MᵀM`, `M = (I − Q₀Q₀ᵀ)·P·W`, `W = V₊·g₊^{−½}` (`G = V·diag(g)·Vᵀ`,
/// `V₊` its directions with `g > 1e-12·max g`, `V₀` the rest). Each eigenvector `z` of `H`
/// with eigenvalue `s²` (the data's information over the prior's along `W·z`) is
/// - **held** if `s² < 1`: the prior holds that motion more tightly than the data see it, so
///   it is fixed for the rank test (no column is projected onto it: a parameter moving the
///   hands as that motion would is seen by the data, and the fit tells it apart from the
///   placement through the prior), or
/// - **free** otherwise, or if the data do not see it at all (`s² ≤ 1e-12·max(1, max s²)`:
///   it absorbs nothing either way): the data decide it, it absorbs as an unpenalised unknown
///   does. The unpenalised directions `V₀` are free.
///
/// The rank test then runs on the data rows only, as without a prior: the prior rows never
/// enter the Gram–Schmidt, so no column is kept, or is a pivot for others to merge into, by
/// what the prior rows alone tell apart (a column whose projected norm would live mostly in
/// the prior rows gave merge coefficients of 2 … 37 prior σ on the CTU session). Without a
/// prior, or with one the data see through in all six motions, all six are free: the old
/// projection.
fn free_placement_directions(
    jd: &DMatrixView<'_, f64>,
    nuisance: &[usize],
    l_place: &DMatrix<f64>,
) -> DMatrix<f64> {
    /// Relative size below which an eigenvalue counts as zero (the module's SVD cut-off).
    const ZERO_REL: f64 = 1e-12;
    let identity = DMatrix::<f64>::identity(6, 6);
    if l_place.nrows() == 0 {
        return identity;
    }
    let g = (l_place.transpose() * l_place).symmetric_eigen();
    let g_max = g.eigenvalues.iter().cloned().fold(0.0, f64::max);
    if g_max.is_nan() || g_max <= 0.0 {
        return identity;
    }
    let (pos, zero): (Vec<usize>, Vec<usize>) =
        (0..6).partition(|&i| g.eigenvalues[i] > ZERO_REL * g_max);
    let v0 = g.eigenvectors.select_columns(&zero);
    let mut w = g.eigenvectors.select_columns(&pos);
    for (c, &i) in pos.iter().enumerate() {
        w.column_mut(c).scale_mut(1.0 / g.eigenvalues[i].sqrt());
    }
    let placement: Vec<usize> = (0..6).collect();
    let p = jd.select_columns(&placement);
    let mut before = jd.select_columns(nuisance);
    let nn = before.ncols();
    before = before.insert_columns(nn, v0.ncols(), 0.0);
    before.columns_mut(nn, v0.ncols()).copy_from(&(&p * &v0));
    let q0 = orthonormal_basis(&before);
    let pw = &p * &w;
    let m = &pw - &q0 * (q0.transpose() * &pw);
    let h = (m.transpose() * m).symmetric_eigen();
    let s2_max = h.eigenvalues.iter().cloned().fold(1.0, f64::max);
    let free_w: Vec<usize> = (0..pos.len())
        .filter(|&i| h.eigenvalues[i] >= 1.0 || h.eigenvalues[i] <= ZERO_REL * s2_max)
        .collect();
    let dirs = &w * h.eigenvectors.select_columns(&free_w);
    let mut free = v0;
    let nz = free.ncols();
    free = free.insert_columns(nz, dirs.ncols(), 0.0);
    free.columns_mut(nz, dirs.ncols()).copy_from(&dirs);
    if free.ncols() == 6 {
        // All free: the identity spans the same motions and keeps the old projection exact.
        return identity;
    }
    free
}

/// Elements of `work`'s columns per rayon task in [`project_out`] (~0.5 MB: far above the cost
/// of scheduling a task; a session of a few hundred rows runs as one task).
const PROJECT_ELEMENTS_PER_TASK: usize = 1 << 16;

/// One step of the pivoted Gram–Schmidt of [`reduce_layout`]: each column `c` of `columns`
/// loses its component along the unit vector `q`, in place, element by element as `w − q·d`
/// with `d = q·w`, and `norm[c]` becomes its new norm. The columns are independent, so they
/// run on rayon's current pool with the same values as one loop over them (the loop was 45 %
/// of a 2,000-row session's reduction, measured at load 12: 39 pivots over 97 columns of 6,000
/// rows).
fn project_out(work: &mut DMatrix<f64>, q: &DVector<f64>, columns: &[usize], norm: &mut [f64]) {
    let m = work.nrows();
    if m == 0 {
        return;
    }
    let mut todo = vec![false; work.ncols()];
    for &c in columns {
        todo[c] = true;
    }
    let new_norms: Vec<(usize, f64)> = work
        .as_mut_slice()
        .par_chunks_mut(m)
        .with_min_len((PROJECT_ELEMENTS_PER_TASK / m).max(1))
        .enumerate()
        .filter(|(c, _)| todo[*c])
        .map(|(c, col)| {
            let d = q.dot(&DVectorView::from_slice(col, m));
            (c, subtract_and_norm(col, q.as_slice(), d))
        })
        .collect();
    for (c, v) in new_norms {
        norm[c] = v;
    }
}

/// `w ← w − q·d` element by element, returning the new `‖w‖` summed as nalgebra's `norm` of a
/// dynamic vector sums it (eight running sums over the elements in blocks of eight, combined
/// as `((a0 + a4) + (a1 + a5)) + …`, then the leftover elements one by one; nalgebra 0.35's
/// `dotx`): the same bits as the subtraction followed by `norm()`, in one pass over `w`
/// instead of two (the projection step reads each 6,000-row column three times otherwise).
fn subtract_and_norm(w: &mut [f64], q: &[f64], d: f64) -> f64 {
    let m = w.len().min(q.len());
    let mut acc = [0.0f64; 8];
    let mut i = 0;
    while m - i >= 8 {
        for (k, a) in acc.iter_mut().enumerate() {
            let v = w[i + k] - q[i + k] * d;
            w[i + k] = v;
            *a += v * v;
        }
        i += 8;
    }
    let mut sum = 0.0f64;
    sum += acc[0] + acc[4];
    sum += acc[1] + acc[5];
    sum += acc[2] + acc[6];
    sum += acc[3] + acc[7];
    for k in i..m {
        let v = w[k] - q[k] * d;
        w[k] = v;
        sum += v * v;
    }
    // `norm_squared` adds each column's sum to a zero (one column here).
    let mut norm_squared = 0.0f64;
    norm_squared += sum;
    norm_squared.sqrt()
}

/// Orthonormal basis of the column space (SVD, singular values above 1e-10 of the largest).
fn orthonormal_basis(m: &DMatrix<f64>) -> DMatrix<f64> {
    if m.ncols() == 0 {
        return DMatrix::zeros(m.nrows(), 0);
    }
    let svd = m.clone().svd(true, false);
    let u = svd.u.expect("u requested");
    let smax = svd.singular_values.iter().cloned().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&i| svd.singular_values[i] > 1e-10 * smax && smax > 0.0)
        .collect();
    u.select_columns(&keep)
}

/// True if `param` is one of a shared trunk's parameters (robot 1's columns at the first
/// [`super::CellRobot::shared_joints`] chain joints, which robot 2's trunk shares; not an arm
/// link's lumped coefficient on a trunk joint, which is that arm's own).
fn on_shared_trunk(problem: &CellProblem, param: &CellParam) -> bool {
    let k = problem.robot2.shared_joints;
    matches!(param, CellParam::Kinematic { robot: crate::Robot::One, param: p }
        if k > 0 && p.joint().is_some_and(|j| j < k) && !kinematics::is_branch_param(p, k))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`subtract_and_norm`] gives the bits of `w − q·d` then nalgebra's `norm()`, at lengths
    /// below, at and around multiples of its blocks of eight, and on values whose sums round.
    #[test]
    fn subtract_and_norm_equals_the_subtraction_then_norm_bit_for_bit() {
        for m in [0usize, 1, 3, 7, 8, 9, 15, 16, 17, 64, 101, 6001] {
            let q = DVector::from_fn(m, |i, _| ((i as f64) * 0.713).sin() / (m as f64).sqrt());
            let w0 = DVector::from_fn(m, |i, _| ((i * 37 % 101) as f64 - 50.0) * 1.0e-3 + 1.0e-9);
            let d = q.dot(&w0);
            let mut expected = w0.clone();
            for (w, qi) in expected.iter_mut().zip(q.iter()) {
                *w -= qi * d;
            }
            let mut got = w0.clone();
            let norm = subtract_and_norm(got.as_mut_slice(), q.as_slice(), d);
            assert_eq!(got, expected, "m = {m}");
            assert_eq!(norm.to_bits(), expected.norm().to_bits(), "m = {m}");
        }
    }
}

//! Scoring a cell on observations it was not fitted to (`handclasp validate`): the residuals of
//! every observation with the robots and the placement held at a given estimate, the session's
//! nuisances (tracker frames, planes, fitted contact distances) either given or refitted on one
//! half of each group's rows and scored on the other.
//!
//! 1. [`hold_cell`]: the problem with both robots' tolerances at zero and the placement held by
//!    a prior of σ [`HOLD_SIGMA`] at the estimate's (so only nuisances move in a fit).
//! 2. [`fit_nuisances`]: the nuisances of a session given the cell (used on the calibration
//!    session for [`NuisanceMode::Fixed`]).
//! 3. [`held_out_residuals`]: each observation's raw and whitened residual, its nuisance never
//!    fitted on it under [`NuisanceMode::Split`].
//! 4. Cross-validation's held-out scoring, shared by `calibrate --cell --export`'s do-no-harm
//!    check and `diagnose`'s held-out criterion: [`sub_problem`] (the rows of a fold as a problem
//!    of their own), [`held_out_pieces`] (a fold's rows split into units by nuisance group, the
//!    pieces too small to refit their nuisance kept in training) and [`score_held_out`] (a
//!    unit's residuals under a training fit's cell, its nuisance refitted on half its rows as in
//!    3).

use nalgebra::DVector;

use super::{
    fit_cell_with, initial_estimate_at, CellEstimate, CellFitError, CellProblem, Evaluator,
    GroupKind, Kind, ParamLayout, PlacementPrior, SolveOptions, Tolerance,
};

/// σ (m and rad) of the placement prior that holds the cell's placement while nuisances are
/// fitted: far below any measurement, far above round-off.
pub const HOLD_SIGMA: f64 = 1e-7;

/// Fewest rows of a group with a fitted nuisance under [`NuisanceMode::Split`], per group kind
/// ([`GroupKind::index`]: contact, tracker, plane): each half must determine the nuisance (a
/// distance from 1 row, a tracker frame or a plane from 3 rows).
pub const MIN_SPLIT_ROWS: [usize; GroupKind::ALL.len()] = [2, 6, 6];

/// Where the nuisances of the scored session come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum NuisanceMode {
    /// Given: the estimate's nuisances are used as they are (e.g. fitted on the calibration
    /// session by [`fit_nuisances`] and matched by group name).
    Fixed,
    /// Each group's nuisance fitted on alternate rows of the group (1st, 3rd, …) with the cell
    /// held, the other rows scored, and back: no scored row is predicted by a nuisance fitted
    /// on it.
    Split,
}

/// One observation's held-out residual.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldOutResidual {
    /// Index into the problem's observations.
    pub index: usize,
    /// Its kind.
    pub kind: Kind,
    /// Its nuisance group, if any.
    pub group: Option<(GroupKind, usize)>,
    /// The residual (1 or 3 values), m.
    pub raw_m: DVector<f64>,
    /// The whitened residual (unit covariance under the stated noise).
    pub whitened: DVector<f64>,
    /// Stated σ of each residual, m (`sqrt diag (WᵀW)⁻¹`; NaN when `W` is singular).
    pub sigma_m: DVector<f64>,
}

/// `problem` with the cell held: both robots' tolerances zero (no kinematic unknown) and the
/// placement held at `b1_from_b2` by a prior of σ [`HOLD_SIGMA`].
pub fn hold_cell(problem: &CellProblem, b1_from_b2: nalgebra::Isometry3<f64>) -> CellProblem {
    let mut p = problem.clone();
    p.robot1.tolerance = Tolerance::none();
    p.robot2.tolerance = Tolerance::none();
    p.placement_prior = Some(PlacementPrior {
        nominal_b1_from_b2: b1_from_b2,
        sigma_m: HOLD_SIGMA,
        sigma_rad: HOLD_SIGMA,
    });
    p
}

/// `cell` (its placement and robot corrections) with the nuisances of `problem` fitted on the
/// observations `rows` (indices into `problem.observations`), the cell held ([`hold_cell`]).
/// Groups without rows among `rows` keep their starting values.
///
/// Errors: a group whose starting value cannot be formed from its rows (a tracker frame or
/// plane from fewer than 3 points), or model failures at an observation.
pub fn fit_nuisances(
    problem: &CellProblem,
    cell: &CellEstimate,
    rows: &[usize],
    options: &SolveOptions,
) -> Result<CellEstimate, CellFitError> {
    let held = hold_cell(problem, cell.b1_from_b2);
    let layout = ParamLayout::new(&held, &[]);
    // The starting nuisances are registered on the held cell's tips, not nominal's.
    let mut at = CellEstimate::nominal(&held, cell.b1_from_b2);
    at.robot1 = cell.robot1.clone();
    at.robot2 = cell.robot2.clone();
    let start = initial_estimate_at(&held, at, Some(cell.b1_from_b2), rows)?;
    let fit = fit_cell_with(&held, layout, rows, Some(&start), options)?;
    let mut out = fit.estimate;
    // The prior holds the placement to σ HOLD_SIGMA; report the cell's own.
    out.b1_from_b2 = cell.b1_from_b2;
    Ok(out)
}

/// The residual of every observation of `problem` at the cell `estimate` (its placement and
/// robot corrections), in observation order, with the nuisances per `mode`: under
/// [`NuisanceMode::Fixed`] those of `estimate`; under [`NuisanceMode::Split`] each group's
/// fitted on alternate rows (by [`fit_nuisances`], all groups at once) and scored on the
/// others. Observations without a nuisance (coincident rows, contacts of a given distance)
/// are scored as they are.
///
/// Errors: under `Split`, a group with a fitted nuisance and fewer than [`MIN_SPLIT_ROWS`] rows
/// (the message names it); an estimate that does not fit the problem; model failures.
pub fn held_out_residuals(
    problem: &CellProblem,
    estimate: &CellEstimate,
    mode: NuisanceMode,
    options: &SolveOptions,
) -> Result<Vec<HeldOutResidual>, CellFitError> {
    estimate.check(problem)?;
    let held = hold_cell(problem, estimate.b1_from_b2);
    let layout = ParamLayout::new(&held, &[]);
    let n = problem.observations.len();
    // Which half of its group each observation is in (None: scored at `estimate` as it is).
    let mut half: Vec<Option<usize>> = vec![None; n];
    if mode == NuisanceMode::Split {
        let mut seen: Vec<((GroupKind, usize), usize)> = Vec::new();
        for (i, o) in problem.observations.iter().enumerate() {
            let Some(key) = o.kind.group() else { continue };
            if !has_nuisance(problem, key) {
                continue;
            }
            let rank = match seen.iter_mut().find(|(k, _)| *k == key) {
                Some((_, c)) => {
                    *c += 1;
                    *c - 1
                }
                None => {
                    seen.push((key, 1));
                    0
                }
            };
            half[i] = Some(rank % 2);
        }
        for ((kind, g), count) in &seen {
            let need = MIN_SPLIT_ROWS[kind.index()];
            if *count < need {
                return Err(CellFitError::InvalidInput(format!(
                    "{} group `{}` has {count} row(s); fitting its nuisance on half of them and \
                     scoring the other half needs at least {need}: record more rows in it, or \
                     take the nuisances from the calibration session",
                    kind.name(),
                    group_name(problem, (*kind, *g)),
                )));
            }
        }
    }
    let mut estimates = [estimate.clone(), estimate.clone()];
    if half.iter().any(Option::is_some) {
        for (h, e) in estimates.iter_mut().enumerate() {
            let fit_rows: Vec<usize> = (0..n).filter(|&i| half[i] == Some(h)).collect();
            *e = fit_nuisances(problem, estimate, &fit_rows, options)?;
        }
    }
    let ev = Evaluator::new(&held, &layout);
    problem
        .observations
        .iter()
        .enumerate()
        .map(|(i, o)| {
            // Scored with the nuisance fitted on the other half.
            let est = match half[i] {
                Some(h) => &estimates[1 - h],
                None => estimate,
            };
            let l = ev.linearise(o, est, false)?;
            let w = &l.whitening;
            let sigma_m = match (w.transpose() * w).try_inverse() {
                Some(cov) => cov.diagonal().map(|v| v.max(0.0).sqrt()),
                None => DVector::from_element(w.nrows(), f64::NAN),
            };
            Ok(HeldOutResidual {
                index: i,
                kind: o.kind.kind(),
                group: o.kind.group(),
                whitened: w * &l.residual,
                raw_m: l.residual,
                sigma_m,
            })
        })
        .collect()
}

/// The sub-problem of the observations `rows` (indices into `problem.observations`, in that
/// order), its groups renumbered to the ones these rows use (in order of first use).
pub fn sub_problem(problem: &CellProblem, rows: &[usize]) -> CellProblem {
    let mut maps: [Vec<Option<usize>>; 3] = [
        vec![None; problem.contacts.len()],
        vec![None; problem.trackers.len()],
        vec![None; problem.planes.len()],
    ];
    let mut p = CellProblem {
        observations: Vec::with_capacity(rows.len()),
        trackers: Vec::new(),
        planes: Vec::new(),
        contacts: Vec::new(),
        ..problem.clone()
    };
    for &i in rows {
        let mut o = problem.observations[i].clone();
        if let Some((k, g)) = o.kind.group() {
            let new = match maps[k.index()][g] {
                Some(n) => n,
                None => {
                    let n = match k {
                        GroupKind::Contact => {
                            p.contacts.push(problem.contacts[g].clone());
                            p.contacts.len() - 1
                        }
                        GroupKind::Tracker => {
                            p.trackers.push(problem.trackers[g].clone());
                            p.trackers.len() - 1
                        }
                        GroupKind::Plane => {
                            p.planes.push(problem.planes[g].clone());
                            p.planes.len() - 1
                        }
                    };
                    maps[k.index()][g] = Some(n);
                    n
                }
            };
            if let Some(group) = o.kind.group_mut() {
                *group = new;
            }
        }
        p.observations.push(o);
    }
    // The other arm's joints of a shared trunk, for the rows kept only.
    p.other_arm_q
        .retain(|row, _| p.observations.iter().any(|o| o.row == *row));
    p
}

/// The held-out residuals of `unit` (indices into `problem.observations`, normally the rows of
/// one nuisance group, or rows without one, in a held-out fold) under the cell of `cell` (a
/// training fit's estimate: its placement and robot corrections): [`held_out_residuals`] of the
/// unit's [`sub_problem`] under [`NuisanceMode::Split`], so a group's nuisance (tracker frame,
/// scale and drift as the group fits them, plane, fitted contact distance) is refitted on
/// alternate rows of the unit with the cell held and never predicts a row it was fitted on;
/// rows without a nuisance (coincident, contacts of a given distance) are scored as they are.
/// Each result's `index` is the row's index in `problem`.
///
/// Errors: a group of the unit with a fitted nuisance and fewer than [`MIN_SPLIT_ROWS`] rows
/// (keep such pieces in training: [`held_out_pieces`]), or model failures.
pub fn score_held_out(
    problem: &CellProblem,
    unit: &[usize],
    cell: &CellEstimate,
    options: &SolveOptions,
) -> Result<Vec<HeldOutResidual>, CellFitError> {
    let sub = sub_problem(problem, unit);
    let mut est = CellEstimate::nominal(&sub, cell.b1_from_b2);
    for (g, c) in sub.contacts.iter().enumerate() {
        est.contact_distance_m[g] = c.distance_m;
    }
    est.robot1 = cell.robot1.clone();
    est.robot2 = cell.robot2.clone();
    let mut out = held_out_residuals(&sub, &est, NuisanceMode::Split, options)?;
    for r in &mut out {
        r.index = unit[r.index];
    }
    Ok(out)
}

/// The held-out units of a fold: the fold's rows `fold` (indices into `problem.observations`)
/// split by nuisance group (the rows without a group form one unit), in order of first
/// appearance, and the rows that stay in training. A group's piece is held out when it can
/// refit its nuisance on half its rows (at least its kind's [`MIN_SPLIT_ROWS`] rows) and the
/// group's rows of `used` outside the piece are none or enough to start the training fit's
/// nuisance (half that minimum: 3 for a tracker frame or a plane); otherwise the piece stays in
/// training (returned second). Groups without a fitted nuisance (contacts of a given distance)
/// have the same minimum: their rows are few and scoring them alone says little.
pub fn held_out_pieces(
    problem: &CellProblem,
    used: &[usize],
    fold: &[usize],
) -> (Vec<Vec<usize>>, Vec<usize>) {
    let mut keys: Vec<Option<(GroupKind, usize)>> = Vec::new();
    let mut units: Vec<Vec<usize>> = Vec::new();
    for &i in fold {
        let key = problem.observations[i].kind.group();
        match keys.iter().position(|k| *k == key) {
            Some(u) => units[u].push(i),
            None => {
                keys.push(key);
                units.push(vec![i]);
            }
        }
    }
    let rest = |key: (GroupKind, usize), piece: usize| {
        used.iter()
            .filter(|&&i| problem.observations[i].kind.group() == Some(key))
            .count()
            .saturating_sub(piece)
    };
    let mut scored = Vec::new();
    let mut kept = Vec::new();
    for (u, k) in units.into_iter().zip(&keys) {
        let ok = k.is_none_or(|key| {
            let min = MIN_SPLIT_ROWS[key.0.index()];
            let rest = rest(key, u.len());
            u.len() >= min && (rest == 0 || rest >= min.div_ceil(2))
        });
        if ok {
            scored.push(u);
        } else {
            kept.extend(u);
        }
    }
    (scored, kept)
}

/// Whether group `key` of `problem` has a fitted nuisance (a tracker frame, a plane, or a
/// contact distance that is not given).
fn has_nuisance(problem: &CellProblem, key: (GroupKind, usize)) -> bool {
    match key.0 {
        GroupKind::Contact => problem.contacts[key.1].fit_distance,
        GroupKind::Tracker | GroupKind::Plane => true,
    }
}

/// The name of group `key` of `problem`.
pub fn group_name(problem: &CellProblem, key: (GroupKind, usize)) -> &str {
    match key.0 {
        GroupKind::Contact => &problem.contacts[key.1].name,
        GroupKind::Tracker => &problem.trackers[key.1].name,
        GroupKind::Plane => &problem.planes[key.1].name,
    }
}

/// `to` (an estimate of `to_problem`) with every nuisance of `to_problem` taken from the group
/// of the same kind and name in `from_problem` (its value in `from`): the tracker frames (with
/// scale and drift), planes and fitted contact distances of a calibration session, carried to
/// a new session of the same cell ([`NuisanceMode::Fixed`]). Contact groups of a given
/// distance keep theirs.
///
/// Errors: a group of `to_problem` with a fitted nuisance that `from_problem` does not have
/// (the message names it).
pub fn carry_nuisances(
    from_problem: &CellProblem,
    from: &CellEstimate,
    to_problem: &CellProblem,
    to: &CellEstimate,
) -> Result<CellEstimate, CellFitError> {
    let mut out = to.clone();
    let find = |kind: GroupKind, name: &str| {
        let names: Vec<&str> = match kind {
            GroupKind::Contact => from_problem
                .contacts
                .iter()
                .map(|g| g.name.as_str())
                .collect(),
            GroupKind::Tracker => from_problem
                .trackers
                .iter()
                .map(|g| g.name.as_str())
                .collect(),
            GroupKind::Plane => from_problem
                .planes
                .iter()
                .map(|g| g.name.as_str())
                .collect(),
        };
        names.iter().position(|n| *n == name).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "{} group `{name}` of the scored session is not in the calibration session \
                 (its groups: {}); a nuisance can only be carried over by name: rename the \
                 group, or refit it on half its rows",
                kind.name(),
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            ))
        })
    };
    for (g, t) in to_problem.trackers.iter().enumerate() {
        let f = find(GroupKind::Tracker, &t.name)?;
        out.tracker_from_anchor[g] = from.tracker_from_anchor[f];
        out.tracker_scale[g] = from.tracker_scale[f];
        out.tracker_drift_m[g] = from.tracker_drift_m[f];
    }
    for (g, p) in to_problem.planes.iter().enumerate() {
        let f = find(GroupKind::Plane, &p.name)?;
        out.planes[g] = from.planes[f];
    }
    for (g, c) in to_problem.contacts.iter().enumerate() {
        if c.fit_distance {
            let f = find(GroupKind::Contact, &c.name)?;
            out.contact_distance_m[g] = from.contact_distance_m[f];
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};

    use super::*;
    use crate::whole_cell::fixtures::{sim_cell, Cell};
    use crate::whole_cell::{Noise3, Observation, ObservationKind, TrackerGroup};
    use crate::Robot;

    /// Noise-free data: a residual at the truth is round-off and the solver's stop (the LM's
    /// relative step tolerance on metre-sized frames), far below any measurement (1 µm).
    const EXACT_M: f64 = 1e-6;

    /// A tracker frame 2 m away, turned 30° about a tilted axis.
    fn tracker_from_b1() -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(1.2, -0.8, 1.5),
            UnitQuaternion::from_scaled_axis(Vector3::new(0.1, -0.2, 0.45)),
        )
    }

    /// The sim cell's problem with `n` coincident rows (noise 1 nm) and a tracker group "t"
    /// (anchored at robot 1) of `n` noise-free rows of robot 1's true tip at the same joints,
    /// and its truth with the tracker frame at `frame`.
    fn problem(n: usize, frame: Isometry3<f64>) -> (CellProblem, CellEstimate) {
        let sc = sim_cell(Cell::Floor, Tolerance::default(), false, 7);
        let mut p = sc.problem();
        let coincident = sc.coincident(n, 1e-9, 0.7, 3);
        let mut obs = coincident.clone();
        for (k, o) in coincident.iter().enumerate() {
            let ObservationKind::Coincident { q1, .. } = &o.kind else {
                unreachable!()
            };
            let tip = sc.true_tip(Robot::One, 0, q1);
            obs.push(Observation {
                row: n + k + 1,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q: q1.clone(),
                    tool: 0,
                    group: 0,
                    p_tracker: tracker_from_b1() * Point3::from(tip),
                    noise: Noise3::Isotropic { sigma_m: 1e-4 },
                },
            });
        }
        p.observations = obs;
        p.trackers = vec![TrackerGroup {
            name: "t".into(),
            anchor: Robot::One,
            initial_tracker_from_anchor: None,
            fit_scale: false,
            fit_drift: false,
        }];
        let mut truth = sc.truth.clone();
        truth.tracker_from_anchor = vec![frame];
        truth.tracker_scale = vec![0.0];
        truth.tracker_drift_m = vec![Vector3::zeros()];
        (p, truth)
    }

    /// At the true cell, split scoring recovers the unknown tracker frame from half the rows
    /// (every residual ~0); fixed scoring with the true frame agrees, with a wrong one does
    /// not; a group too small to split is refused by name.
    #[test]
    fn split_and_fixed_scoring_at_the_truth() {
        let (p, truth) = problem(10, Isometry3::identity());
        let options = SolveOptions::default();
        let split = held_out_residuals(&p, &truth, NuisanceMode::Split, &options).unwrap();
        assert_eq!(split.len(), 20);
        assert_eq!(split[0].kind, Kind::Coincident);
        assert_eq!(split[12].group, Some((GroupKind::Tracker, 0)));
        for r in &split {
            assert!(r.raw_m.norm() < EXACT_M, "{r:?}");
        }
        // The tracker frame fitted on all rows is the true one; carried over, it scores ~0.
        let all: Vec<usize> = (0..20).collect();
        let fitted = fit_nuisances(&p, &truth, &all, &options).unwrap();
        let moved = fitted.tracker_from_anchor[0].inverse() * tracker_from_b1();
        assert!(moved.translation.vector.norm() < EXACT_M, "{moved}");
        assert_eq!(fitted.b1_from_b2, truth.b1_from_b2);
        let carried = carry_nuisances(&p, &fitted, &p, &truth).unwrap();
        let fixed = held_out_residuals(&p, &carried, NuisanceMode::Fixed, &options).unwrap();
        assert!(fixed.iter().all(|r| r.raw_m.norm() < EXACT_M));
        // The identity frame as given: the tracker rows are metres off.
        let wrong = held_out_residuals(&p, &truth, NuisanceMode::Fixed, &options).unwrap();
        assert!(wrong[10..].iter().all(|r| r.raw_m.norm() > 0.1));
        // Five tracker rows cannot be split into two halves of three.
        let (small, truth) = problem(5, Isometry3::identity());
        let err = held_out_residuals(&small, &truth, NuisanceMode::Split, &options)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("tracker group `t` has 5 row(s)") && err.contains("at least 6"),
            "{err}"
        );
        // A group missing from the calibration session is named.
        let mut renamed = p.clone();
        renamed.trackers[0].name = "u".into();
        let err = carry_nuisances(&p, &fitted, &renamed, &truth)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("tracker group `u`") && err.contains("its groups: t"),
            "{err}"
        );
    }
}

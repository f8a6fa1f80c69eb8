//! Starting values of the fit: the placement, tracker frames and planes from the data at
//! nominal kinematics.

use crate::Robot;
use nalgebra::{Isometry3, Matrix3, Point3, Unit, Vector3};

use crate::registration::rigid_fit_fast;

use super::cell::CellFitError;
use super::layout::{CellEstimate, ParamLayout, PlaneEstimate};
use super::observations::{CellProblem, ObservationKind};
use super::residuals::Evaluator;

/// Starting values: `b1_from_b2` (given, or a rigid fit of the coincident rows at nominal),
/// tracker frames (given, or a rigid fit) and planes (given, or a least-squares plane).
pub fn initial_estimate(
    problem: &CellProblem,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    active: &[usize],
) -> Result<CellEstimate, CellFitError> {
    let at = CellEstimate::nominal(problem, Isometry3::identity());
    initial_estimate_at(problem, at, initial_b1_from_b2, active)
}

/// [`initial_estimate`] with the robots of `at` (their corrections and tool tips, e.g. a
/// training fit's held while a held-out piece's nuisances are refitted) in place of nominal:
/// the starting frames and planes are registered on the tips `at` puts the tools at (a robot
/// whose tools all start at one tip has one point per pose at nominal, which no piece of one
/// pose can register). The result carries `at`'s robots.
pub(crate) fn initial_estimate_at(
    problem: &CellProblem,
    at: CellEstimate,
    initial_b1_from_b2: Option<Isometry3<f64>>,
    active: &[usize],
) -> Result<CellEstimate, CellFitError> {
    let layout = ParamLayout::new(problem, &[]);
    let ev = Evaluator::new(problem, &layout);
    let mut est = at;
    let x = match initial_b1_from_b2 {
        Some(x) => x,
        None => {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for &i in active {
                let o = &problem.observations[i];
                if let ObservationKind::Coincident {
                    q1,
                    q2,
                    tool1,
                    tool2,
                    ..
                } = &o.kind
                {
                    a.push(Point3::from(
                        ev.robot_tip(&est, Robot::One, *tool1, q1, Some(q2), false, o.row)?
                            .0,
                    ));
                    b.push(Point3::from(
                        ev.robot_tip(&est, Robot::Two, *tool2, q2, Some(q1), false, o.row)?
                            .0,
                    ));
                }
            }
            rigid_fit_fast(&a, &b).ok_or_else(|| {
                CellFitError::InvalidInput(format!(
                    "no starting b1_from_b2: {} coincident row(s) (need ≥ 3 not on a line); \
                     give an initial b1_from_b2",
                    a.len()
                ))
            })?
        }
    };
    est.b1_from_b2 = x;
    for (g, grp) in problem.trackers.iter().enumerate() {
        if let Some(t) = grp.initial_tracker_from_anchor {
            est.tracker_from_anchor[g] = t;
            continue;
        }
        let (mut meas, mut model) = (Vec::new(), Vec::new());
        for &i in active {
            let o = &problem.observations[i];
            if let ObservationKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                ..
            } = &o.kind
            {
                if *group == g {
                    let q_other = problem.other_arm_q.get(&o.row).map(Vec::as_slice);
                    let (p, _) = ev
                        .tip_in_anchor(&est, *robot, *tool, q, q_other, grp.anchor, false, o.row)?;
                    meas.push(*p_tracker);
                    model.push(Point3::from(p));
                }
            }
        }
        est.tracker_from_anchor[g] = rigid_fit_fast(&meas, &model).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "tracker group `{}`: {} row(s), need ≥ 3 not on a line for a starting frame; \
                 add rows or give initial_tracker_from_anchor",
                grp.name,
                meas.len()
            ))
        })?;
    }
    for (g, grp) in problem.planes.iter().enumerate() {
        if let Some((n, d)) = grp.initial {
            est.planes[g] = PlaneEstimate {
                normal_anchor: n,
                offset_m: d,
            };
            continue;
        }
        let mut pts = Vec::new();
        for &i in active {
            let o = &problem.observations[i];
            if let ObservationKind::Plane {
                robot,
                q,
                tool,
                group,
                ..
            } = &o.kind
            {
                if *group == g {
                    let q_other = problem.other_arm_q.get(&o.row).map(Vec::as_slice);
                    pts.push(
                        ev.tip_in_anchor(
                            &est, *robot, *tool, q, q_other, grp.anchor, false, o.row,
                        )?
                        .0,
                    );
                }
            }
        }
        est.planes[g] = fit_plane(&pts).ok_or_else(|| {
            CellFitError::InvalidInput(format!(
                "plane group `{}`: {} row(s), need ≥ 3 not on a line for a starting plane; add \
                 rows or give an initial plane",
                grp.name,
                pts.len()
            ))
        })?;
    }
    Ok(est)
}

/// Least-squares plane through points (normal = smallest principal axis).
fn fit_plane(pts: &[Vector3<f64>]) -> Option<PlaneEstimate> {
    if pts.len() < 3 {
        return None;
    }
    let c = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let mut m = Matrix3::zeros();
    for p in pts {
        m += (p - c) * (p - c).transpose();
    }
    let eig = m.symmetric_eigen();
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    if eig.eigenvalues[idx[1]] <= 1e-12 * eig.eigenvalues[idx[2]].max(1e-300) {
        return None;
    }
    let n = Unit::new_normalize(eig.eigenvectors.column(idx[0]).into_owned());
    Some(PlaneEstimate {
        normal_anchor: n,
        offset_m: n.dot(&c),
    })
}

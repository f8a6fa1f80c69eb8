//! The diagnosis problem ([`diagnosis_problem`]: the cell's problem with widened tolerances,
//! compliance and joint-periodic errors) and what its observations touch: robots, tools,
//! joints and nuisance groups.

use calib_core::whole_cell::{CellProblem, GroupKind, ObservationKind, Tolerance};
use calib_core::Robot;
use handclasp_cell::problem::{cell_problem, FitModel};
use handclasp_cell::Cell;
use handclasp_cell::Session;
use kinematics::gravity_torques;

use super::CellDiagnoseOptions;
use crate::DiagnoseError;

pub(super) fn uses_robot(kind: &ObservationKind, r: Robot) -> bool {
    kind.tools().iter().any(|(rr, _)| *rr == r)
}

/// Whether the observations `rows` of `problem` determine the placement `b1_from_b2`: a
/// coincident or contact row (it ties both robots), or a tracker or plane group with rows of
/// both robots (a frame or plane seen from both bases). Otherwise the fit holds the placement
/// where it started (the cell's, or its prior) and an export keeps the cell's.
pub(crate) fn placement_observed(problem: &CellProblem, rows: &[usize]) -> bool {
    // Per tracker or plane group: the robots its rows use.
    let mut seen: Vec<((GroupKind, usize), Robot)> = Vec::new();
    for &i in rows {
        let kind = &problem.observations[i].kind;
        let robots = kind.tools();
        if robots.len() == 2 {
            return true;
        }
        let (Some(key), Some((r, _))) = (kind.group(), robots.first()) else {
            continue;
        };
        match seen.iter().find(|(k, _)| *k == key) {
            Some((_, first)) if first != r => return true,
            Some(_) => {}
            None => seen.push((key, *r)),
        }
    }
    false
}

/// The diagnosis problem: the cell's whole-cell problem with widened tolerances and compliance
/// where the URDF has inertials (see the [`cell_diagnosis`](crate::cell_diagnosis)
/// documentation).
pub fn diagnosis_problem(
    cell: &Cell,
    session: &Session,
    options: &CellDiagnoseOptions,
) -> Result<CellProblem, DiagnoseError> {
    let mut problem = cell_problem(cell, session, FitModel::Kinematic);
    let w = options.prior_widening;
    if !(w.is_finite() && w > 0.0) {
        return Err(DiagnoseError::Session {
            path: "<options>".into(),
            message: format!("prior widening {w} must be finite and > 0 (default 10)"),
        });
    }
    for r in [Robot::One, Robot::Two] {
        let max_tau = max_gravity_torque(&problem, r)?;
        let rb = if r == Robot::One {
            &mut problem.robot1
        } else {
            &mut problem.robot2
        };
        let t = rb.tolerance;
        let offset = t.joint_offset_rad * w;
        rb.tolerance = Tolerance {
            joint_offset_rad: offset,
            origin_xyz_m: t.origin_xyz_m * w,
            origin_rpy_rad: t.origin_rpy_rad * w,
            tip_m: t.tip_m * w,
            joint_scale: t.joint_scale.map(|s| s * w),
            compliance_rad_per_nm: match t.compliance_rad_per_nm {
                Some(c) => Some(c * w),
                None if max_tau > 0.0 && offset > 0.0 => Some(offset / max_tau),
                None => None,
            },
            periodic_rad: match t.periodic_rad {
                Some(p) => Some(p * w),
                None if offset > 0.0 => Some(offset),
                None => None,
            },
            // Without masses the compliance is tested as lumped coefficients (compliance × mass
            // moment, kinematics::lumped), which need none.
            lumped_compliance_rad: match t.lumped_compliance_rad {
                Some(c) => Some(c * w),
                None if max_tau == 0.0
                    && offset > 0.0
                    && massless(&rb.model)
                    && !kinematics::lumped_params(&rb.model).is_empty() =>
                {
                    Some(calib_core::whole_cell::LUMPED_COMPLIANCE_TOLERANCE_RAD)
                }
                None => None,
            },
        };
    }
    Ok(problem)
}

/// True if the model carries no mass (its URDF has no inertials, or only massless ones).
pub(crate) fn massless(model: &kinematics::RobotModel) -> bool {
    model.inertials().iter().all(|i| i.mass == 0.0)
}

/// Largest |gravity torque| (N·m) of robot `r` over the problem's postures; 0 without inertials.
fn max_gravity_torque(problem: &CellProblem, r: Robot) -> Result<f64, DiagnoseError> {
    let rb = problem.robot(r);
    if rb.model.inertials().is_empty() {
        return Ok(0.0);
    }
    let mut max = 0.0f64;
    for o in &problem.observations {
        for (rr, q) in o.kind.joints() {
            if rr == r {
                let tau = gravity_torques(&rb.model, q, &rb.g_base).map_err(|source| {
                    DiagnoseError::Model {
                        robot: r.number(),
                        point: o.row,
                        source,
                    }
                })?;
                max = tau.iter().fold(max, |m, t| m.max(t.abs()));
            }
        }
    }
    Ok(max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell_diagnosis::tests::mixed_session;
    use crate::cell_diagnosis::CellDiagnoseOptions;

    /// Rows of `p` whose kind is `name` and whose tools include robot `r` (any robot: `None`).
    fn rows_of(p: &CellProblem, name: &str, r: Option<Robot>) -> Vec<usize> {
        (0..p.observations.len())
            .filter(|&i| {
                let k = &p.observations[i].kind;
                k.name() == name && r.is_none_or(|r| uses_robot(k, r))
            })
            .collect()
    }

    #[test]
    fn the_placement_is_observed_by_rows_that_tie_both_robots() {
        let cell = Cell::default_floor_wall();
        let session = mixed_session(&cell, 36, 3);
        let p = diagnosis_problem(&cell, &session, &CellDiagnoseOptions::default()).unwrap();
        for kind in ["coincident", "contact"] {
            let rows = rows_of(&p, kind, None);
            assert!(!rows.is_empty() && placement_observed(&p, &rows), "{kind}");
        }
        // Tracker (plane) rows of one robot: each group is seen from one base only.
        for kind in ["tracker", "plane"] {
            for r in [Robot::One, Robot::Two] {
                let rows = rows_of(&p, kind, Some(r));
                assert!(!rows.is_empty(), "{kind} rows of {r}");
                assert!(!placement_observed(&p, &rows), "{kind} rows of {r} alone");
            }
            // The simulated session's one group of the kind holds rows of both robots.
            let both = rows_of(&p, kind, None);
            assert!(placement_observed(&p, &both), "{kind} rows of both robots");
        }
        assert!(!placement_observed(&p, &[]));
    }
}

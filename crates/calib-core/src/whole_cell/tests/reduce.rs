//! The base-parameter reduction ([`reduce`]): what the placement absorbs, what is merged, and the
//! placement-only layout.

use super::*;

/// The reduction on a floor–floor cell with every default tolerance (origin rpy included):
/// both robots' first-joint origins are rigid motions of a base (confounded with
/// `b1_from_b2`), and a joint offset about z and the same joint's origin yaw cannot be told
/// apart (one is merged into the other). The fit on the reduced layout still converges.
#[test]
fn reduction_names_what_the_placement_absorbs_and_what_is_merged() {
    let sc = sim_cell(Cell::Floor, Tolerance::default(), false, 21);
    let p = coincident_problem(&sc, 40, 3e-4, 22);
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let init = initial_estimate(&p, None, &active).unwrap();
    let red = reduce(&p, &init, &active).unwrap();
    for d in &red.dropped {
        eprintln!("{}", d.message);
    }
    eprintln!(
        "kept {} (data-determined {}, prior-dominated {})",
        red.kept, red.data_determined, red.prior_dominated
    );
    for r in [Robot::One, Robot::Two] {
        for axis in kinematics::Axis::ALL {
            let p = CellParam::Kinematic {
                robot: r,
                param: ErrorParam::OriginXyz { joint: 0, axis },
            };
            let e = red
                .dropped
                .iter()
                .find(|d| d.param == p)
                .unwrap_or_else(|| panic!("{r} joint 1 origin {axis} not dropped"));
            assert!(
                matches!(
                    e.reason,
                    ReductionReason::ConfoundedWithPlacement | ReductionReason::MergedInto { .. }
                ),
                "{}",
                e.message
            );
        }
    }
    assert!(red.dropped.iter().any(|d| matches!(
        d.reason,
        ReductionReason::ConfoundedWithPlacement
    ) && d.message.contains("confounded with b1_from_b2")));
    assert!(red
        .dropped
        .iter()
        .any(|d| matches!(d.reason, ReductionReason::MergedInto { .. })));
    assert_eq!(
        red.kept + red.dropped.len(),
        ParamLayout::new(&p, &[]).len() - 6
    );
    let fit = fit_cell_with(
        &p,
        red.layout,
        &active,
        Some(&init),
        &SolveOptions::default(),
    )
    .unwrap();
    assert_eq!(fit.stopped, StopReason::Converged);
    assert!(!fit.singular, "the reduced problem is fully determined");
}

/// Regression (the placement-only model in `handclasp calibrate --cell --model placement`): with
/// every tolerance 0 there is no kinematic unknown; the reduction used to panic in nalgebra's SVD
/// of a matrix without columns. It now keeps nothing and drops nothing.
#[test]
fn reduction_without_kinematic_unknowns_is_empty() {
    let none = Tolerance {
        joint_offset_rad: 0.0,
        origin_xyz_m: 0.0,
        origin_rpy_rad: 0.0,
        tip_m: 0.0,
        joint_scale: None,
        compliance_rad_per_nm: None,
        periodic_rad: None,
        lumped_compliance_rad: None,
    };
    let sc = sim_cell(Cell::Floor, none, false, 31);
    let p = coincident_problem(&sc, 12, 3e-4, 32);
    let active: Vec<usize> = (0..p.observations.len()).collect();
    let init = initial_estimate(&p, None, &active).unwrap();
    let red = reduce(&p, &init, &active).unwrap();
    assert_eq!(red.kept, 0);
    assert!(red.dropped.is_empty());
}

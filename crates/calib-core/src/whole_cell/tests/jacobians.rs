//! Every analytic residual Jacobian (all five observation kinds, every column kind) against
//! central differences.

use super::*;

/// Central-difference step per column: 1e-6 in the column's unit moves a tip by ~1e-6 m for
/// metres and radians (arms ~1 m); a scale by q·1e-6 ≤ 3e-6 rad; a compliance multiplies
/// torques up to ~5e3 N·m (HP20), so its step is 2e-10 rad/(N·m) for the same tip motion.
fn fd_step(p: &CellParam) -> f64 {
    match p {
        CellParam::Kinematic {
            param: ErrorParam::Compliance { .. },
            ..
        } => 2e-10,
        _ => 1e-6,
    }
}

/// Tolerance on the residual change over a central step (m): truncation ~h²·|r'''| ≲ 1e-12 m and
/// round-off ~eps·|r|/1 ≈ 1e-15 m per evaluation, so |Δ| ≤ 1e-12 m + 1e-6 relative (the
/// manifold retractions are exact to second order, which central differences cancel).
const FD_TOL_M: f64 = 1e-12;

const FD_TOL_REL: f64 = 1e-6;

/// Every observation's analytic Jacobian column of `layout` against central differences of its
/// residual at `est` (within [`FD_TOL_M`] + [`FD_TOL_REL`] relative), naming the seed, row and
/// column of a mismatch.
fn assert_rows_match_central_differences(
    p: &CellProblem,
    layout: &ParamLayout,
    ev: &Evaluator,
    est: &CellEstimate,
    seed: u64,
) {
    for o in &p.observations {
        let lin = ev.linearise(o, est, true).unwrap();
        for (j, param) in layout.params.iter().enumerate() {
            let h = fd_step(param);
            let mut d = DVector::zeros(layout.len());
            d[j] = h;
            let plus = ev.linearise(o, &layout.apply(est, &d), false).unwrap();
            let minus = ev.linearise(o, &layout.apply(est, &(-d)), false).unwrap();
            let fd = (plus.residual - minus.residual) / 2.0;
            let an = lin.jacobian.column(j) * h;
            let diff = (&fd - &an).norm();
            assert!(
                diff <= FD_TOL_M + FD_TOL_REL * an.norm(),
                "seed {seed} row {} ({}) column {}: analytic {:?} fd {:?}",
                o.row,
                o.kind.name(),
                param.describe(p),
                an.as_slice(),
                fd.as_slice()
            );
        }
    }
}

#[test]
fn every_jacobian_matches_central_differences() {
    for seed in [1u64, 2, 3] {
        let (p, est) = every_kind(seed);
        p.check().expect("valid problem");
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        assert_rows_match_central_differences(&p, &layout, &ev, &est, seed);
        // The cooperative vector's Jacobian as well.
        let pair = ConfigPair {
            q1: random_q(&p.robot1.model, &mut ChaCha8Rng::seed_from_u64(seed)),
            q2: random_q(&p.robot2.model, &mut ChaCha8Rng::seed_from_u64(seed + 9)),
            tool1: 1,
            tool2: 0,
        };
        let (_, jv) = ev.cooperative_vector(&est, &pair, true).unwrap();
        for (j, param) in layout.params.iter().enumerate() {
            let h = fd_step(param);
            let mut d = DVector::zeros(layout.len());
            d[j] = h;
            let (vp, _) = ev
                .cooperative_vector(&layout.apply(&est, &d), &pair, false)
                .unwrap();
            let (vm, _) = ev
                .cooperative_vector(&layout.apply(&est, &(-d)), &pair, false)
                .unwrap();
            let fd = (vp - vm) / 2.0;
            let an = Vector3::from_fn(|a, _| jv[(a, j)] * h);
            assert!((fd - an).norm() <= FD_TOL_M + FD_TOL_REL * an.norm());
        }
    }
}

/// The face-contact rows of [`every_kind`] (two per seed, generic normals, a fitted contact
/// distance, scale, compliance and periodic errors of both robots, the wall cell's rotated
/// placement): every column's analytic derivative matches central differences within
/// [`FD_TOL_M`] + [`FD_TOL_REL`] (step [`fd_step`]). Not vacuous: the placement is far from the
/// identity, the faces slide (the tip-to-tip vector has a tangential part, so the normals'
/// rotation enters), and every robot-2 kinematic column and placement rotation column is
/// non-zero on at least one row.
#[test]
fn face_contact_jacobian_matches_central_differences() {
    for seed in [1u64, 2, 3] {
        let (p, est) = every_kind(seed);
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        assert!(est.b1_from_b2.rotation.angle() > 1.0);
        let faces: Vec<&Observation> = p
            .observations
            .iter()
            .filter(|o| matches!(o.kind, ObservationKind::FaceContact { .. }))
            .collect();
        assert_eq!(faces.len(), 2);
        let mut touched = vec![false; layout.len()];
        for o in faces {
            let lin = ev.linearise(o, &est, true).unwrap();
            for (j, param) in layout.params.iter().enumerate() {
                let h = fd_step(param);
                let mut d = DVector::zeros(layout.len());
                d[j] = h;
                let plus = ev.linearise(o, &layout.apply(&est, &d), false).unwrap();
                let minus = ev.linearise(o, &layout.apply(&est, &(-d)), false).unwrap();
                let fd = (plus.residual[0] - minus.residual[0]) / 2.0;
                let an = lin.jacobian[(0, j)] * h;
                assert!(
                    (fd - an).abs() <= FD_TOL_M + FD_TOL_REL * an.abs(),
                    "seed {seed} row {} column {}: analytic {an:e} fd {fd:e}",
                    o.row,
                    param.describe(&p)
                );
                touched[j] |= an != 0.0;
            }
        }
        for (j, param) in layout.params.iter().enumerate() {
            let must = match param {
                CellParam::Kinematic { robot, .. } => *robot == Robot::Two,
                CellParam::PlacementRotation { .. } | CellParam::ContactDistance { .. } => true,
                _ => false,
            };
            assert!(
                !must || touched[j],
                "seed {seed}: column {} has no effect on any face row",
                param.describe(&p)
            );
        }
    }
}

/// The simulated humanoid (`robots/humanoid.urdf`): torso_4 follows −(torso_1 + torso_2).
const HUMANOID: &str = include_str!("../../../../../robots/humanoid.urdf");

/// A shared-trunk problem with a coupled torso joint: the humanoid's right arm (robot 1) and
/// left arm (robot 2, its first 4 chain joints robot 1's), coincident, contact, tracker and
/// plane rows with equal trunk joints on the two-robot rows, and random errors on every fitted
/// parameter (the shared joints' copies equal).
fn shared_trunk(seed: u64) -> (CellProblem, CellEstimate) {
    let (mut p, _) = every_kind(seed);
    let coupling = kinematics::JointCoupling {
        joint: "torso_4".into(),
        terms: vec![("torso_1".into(), -1.0), ("torso_2".into(), -1.0)],
        offset: 0.01,
    };
    let arm = |tool: &str| {
        kinematics::RobotModel::from_urdf_str(HUMANOID, tool)
            .and_then(|m| m.with_couplings(std::slice::from_ref(&coupling)))
            .expect("humanoid")
    };
    p.robot1.model = arm("right_tool0");
    p.robot2.model = arm("left_tool0");
    p.robot2.shared_joints = 4;
    p.robot1.g_base = Vector3::new(0.0, 0.0, -9.81);
    p.robot2.g_base = p.robot1.g_base;
    p.robot1.tolerance.compliance_rad_per_nm = None;
    p.robot2.tolerance.compliance_rad_per_nm = None;
    p.placement_prior = None;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x7a11);
    let pair = |rng: &mut ChaCha8Rng| {
        let q1 = random_q(&p.robot1.model, rng);
        let mut q2 = random_q(&p.robot2.model, rng);
        q2[..3].copy_from_slice(&q1[..3]);
        (q1, q2)
    };
    let mut obs = Vec::new();
    let (q1, q2) = pair(&mut rng);
    obs.push(ObservationKind::Coincident {
        q1,
        q2,
        tool1: 0,
        tool2: 0,
        noise: Noise3::Isotropic { sigma_m: 3e-4 },
    });
    let (q1, q2) = pair(&mut rng);
    obs.push(ObservationKind::Contact {
        q1,
        q2,
        tool1: 1,
        tool2: 0,
        group: 0,
        sigma_m: 2e-4,
    });
    for (robot, group) in [(Robot::One, 0usize), (Robot::Two, 0), (Robot::Two, 1)] {
        obs.push(ObservationKind::Tracker {
            robot,
            q: random_q(&p.robot(robot).model, &mut rng),
            tool: 0,
            group,
            p_tracker: Point3::new(0.3, -0.2, 1.1),
            noise: Noise3::Isotropic { sigma_m: 1e-4 },
        });
        obs.push(ObservationKind::Plane {
            robot,
            q: random_q(&p.robot(robot).model, &mut rng),
            tool: 0,
            group,
            sigma_m: 1e-4,
        });
    }
    p.observations = obs
        .into_iter()
        .enumerate()
        .map(|(row, kind)| Observation { row: row + 1, kind })
        .collect();
    let mut est = CellEstimate::nominal(&p, Isometry3::identity());
    for r in Robot::BOTH {
        let rb = p.robot(r).clone();
        for param in rb.fitted_params() {
            let v = rng.random_range(-1e-3..1e-3);
            if r == Robot::One {
                est.robot1.errors.set(param, v);
            } else if param.joint().is_none_or(|j| j >= 4) {
                est.robot2.errors.set(param, v);
            }
        }
    }
    for param in p.robot1.fitted_params() {
        if param.joint().is_some_and(|j| j < 4) {
            est.robot2.errors.set(param, est.robot1.errors.get(param));
        }
    }
    (p, est)
}

/// Shared trunk and coupled joint: robot 2's shared parameters have no columns of their own
/// (robot 1's columns hold them), the coupled joint torso_4 (chain joint 4) has its own
/// offset and origin columns, and every analytic Jacobian column (the tied ones add both arms'
/// derivatives) matches central differences of the residuals with both copies moved.
#[test]
fn shared_trunk_and_coupled_joint_jacobians_match_central_differences() {
    for seed in [4u64, 5] {
        let (p, est) = shared_trunk(seed);
        p.check().expect("valid problem");
        let layout = ParamLayout::new(&p, &[]);
        let kin = |r: Robot, joint: usize| {
            layout.params.iter().any(|c| {
                matches!(c, CellParam::Kinematic { robot, param } if *robot == r && param.joint() == Some(joint))
            })
        };
        assert!(
            kin(Robot::One, 3),
            "torso_4 (chain joint 4) has its own parameters"
        );
        assert!(
            !kin(Robot::Two, 0) && !kin(Robot::Two, 3),
            "the trunk is robot 1's columns"
        );
        assert!(kin(Robot::Two, 4), "robot 2's arm has its own columns");
        let ev = Evaluator::new(&p, &layout);
        assert_rows_match_central_differences(&p, &layout, &ev, &est, seed);
        // A step moves both copies of a shared parameter alike.
        let moved = layout.apply(&est, &DVector::from_element(layout.len(), 1e-4));
        for param in p.robot1.fitted_params() {
            if param.joint().is_some_and(|j| j < 4) {
                assert_eq!(
                    moved.robot1.errors.get(param),
                    moved.robot2.errors.get(param)
                );
            }
        }
    }
}

/// [`shared_trunk`] with gravity compliance on the trunk carrying both arms
/// ([`kinematics::trunk`]): lumped coefficients fitted on both robots (robot 2's arm links on
/// the trunk joints its own columns, its trunk links robot 1's), physical compliance fitted
/// too (the URDF has masses), the other arm's joints given for every tracker and plane row
/// (`other_arm_q`), and random values of every fitted parameter (the shared copies equal).
fn shared_trunk_compliant(seed: u64) -> (CellProblem, CellEstimate) {
    let (mut p, _) = shared_trunk(seed);
    for rb in [&mut p.robot1, &mut p.robot2] {
        rb.tolerance.lumped_compliance_rad = Some(LUMPED_COMPLIANCE_TOLERANCE_RAD);
        rb.tolerance.compliance_rad_per_nm = Some(1e-4);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xb7a1);
    for o in &p.observations {
        if let ObservationKind::Tracker { robot, q, .. } | ObservationKind::Plane { robot, q, .. } =
            &o.kind
        {
            let mut q_other = random_q(&p.robot(robot.other()).model, &mut rng);
            q_other[..3].copy_from_slice(&q[..3]);
            p.other_arm_q.insert(o.row, q_other);
        }
    }
    let mut est = CellEstimate::nominal(&p, Isometry3::identity());
    let k = p.robot2.shared_joints;
    let value = |param: ErrorParam, rng: &mut ChaCha8Rng| match param {
        ErrorParam::Compliance { .. } => rng.random_range(0.0..2e-4),
        ErrorParam::LumpedCompliance { .. } => rng.random_range(-5e-3..5e-3),
        _ => rng.random_range(-1e-3..1e-3),
    };
    for param in p.robot1.fitted_params() {
        est.robot1.errors.set(param, value(param, &mut rng));
    }
    for param in p.robot2.fitted_params() {
        let shared =
            param.joint().is_some_and(|j| j < k) && !kinematics::is_branch_param(&param, k);
        let v = if shared {
            est.robot1.errors.get(param)
        } else {
            value(param, &mut rng)
        };
        est.robot2.errors.set(param, v);
    }
    (p, est)
}

/// Compliance on a shared trunk (issue 22): robot 2's arm links' lumped coefficients on the
/// trunk joints have columns of their own, its trunk links' do not; every analytic column
/// (with the other arm's branch coefficients and its share of each trunk joint's physical
/// compliance) matches central differences of every residual kind; and the other arm's
/// posture changes a one-robot row's residual (the trunk carries both arms).
#[test]
fn shared_trunk_compliance_jacobians_match_central_differences() {
    for seed in [6u64, 7] {
        let (p, est) = shared_trunk_compliant(seed);
        p.check().expect("valid problem");
        let layout = ParamLayout::new(&p, &[]);
        let k = p.robot2.shared_joints;
        let has = |r: Robot, branch: bool| {
            layout.params.iter().any(|c| {
                matches!(c, CellParam::Kinematic { robot, param: param @ ErrorParam::LumpedCompliance { joint, .. } }
                    if *robot == r && *joint < k && kinematics::is_branch_param(param, k) == branch)
            })
        };
        assert!(
            has(Robot::Two, true),
            "robot 2's arm on the trunk: its own columns"
        );
        assert!(
            !has(Robot::Two, false),
            "the trunk links: robot 1's columns"
        );
        assert!(has(Robot::One, true) && has(Robot::One, false));
        let ev = Evaluator::new(&p, &layout);
        assert_rows_match_central_differences(&p, &layout, &ev, &est, seed);
        let tracker = p
            .observations
            .iter()
            .find(|o| o.kind.name() == "tracker")
            .expect("a tracker row");
        let mut moved = p.clone();
        let q_other = moved.other_arm_q.get_mut(&tracker.row).expect("given");
        q_other[5] += 0.3;
        let ev_moved = Evaluator::new(&moved, &layout);
        let a = ev.linearise(tracker, &est, false).unwrap().residual;
        let b = ev_moved.linearise(tracker, &est, false).unwrap().residual;
        assert!(
            (a - b).norm() > 1e-7,
            "the other arm's elbow moves the trunk's deflection"
        );
    }
}

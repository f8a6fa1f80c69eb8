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

#[test]
fn every_jacobian_matches_central_differences() {
    for seed in [1u64, 2, 3] {
        let (p, est) = every_kind(seed);
        p.check().expect("valid problem");
        let layout = ParamLayout::new(&p, &[]);
        let ev = Evaluator::new(&p, &layout);
        for o in &p.observations {
            let lin = ev.linearise(o, &est, true).unwrap();
            for (j, param) in layout.params.iter().enumerate() {
                let h = fd_step(param);
                let mut d = DVector::zeros(layout.len());
                d[j] = h;
                let plus = ev.linearise(o, &layout.apply(&est, &d), false).unwrap();
                let minus = ev.linearise(o, &layout.apply(&est, &(-d)), false).unwrap();
                let fd = (plus.residual - minus.residual) / 2.0;
                let an = lin.jacobian.column(j) * h;
                let diff = (&fd - &an).norm();
                assert!(
                    diff <= FD_TOL_M + FD_TOL_REL * an.norm(),
                    "seed {seed} row {} ({}) column {}: analytic {:?} fd {:?}",
                    o.row,
                    o.kind.name(),
                    param.describe(&p),
                    an.as_slice(),
                    fd.as_slice()
                );
            }
        }
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

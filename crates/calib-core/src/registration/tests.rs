//! Registration tests: exact recovery, fast vs full paths, closed forms vs brute force, degeneracy
//! errors, weights, Jacobian vs central differences, predicted vs Monte Carlo uncertainty.

use super::family::{family, Family};
use super::*;
use crate::metrics::{e_tran, geodesic_angle};
use kinematics::euler::rotation_from_zyz;
use nalgebra::{
    DMatrix, Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

/// Zero-noise recovery: exact methods, only round-off on metre-scale data.
const EXACT_TOL: f64 = 1e-9;

/// A tetrahedron-ish set of n points in b2 (m), within about 1 m.
fn cloud(n: usize, seed: u64) -> Vec<Point3<f64>> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            Point3::new(
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.8..0.8),
                rng.random_range(0.0..1.2),
            )
        })
        .collect()
}

fn pairs_for(x: &Isometry3<f64>, p_b2: &[Point3<f64>]) -> PointPairs {
    PointPairs::new(p_b2.iter().map(|p| x * p).collect(), p_b2.to_vec()).unwrap()
}

fn iso(t: [f64; 3], r: Rotation3<f64>) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// A true `b1_from_b2` compatible with the mounts: `L1ᵀ·Rz(γ)·L2`, or `L1ᵀ·wall(α, β)` etc.
fn truth_for(mounts: &MountPair, a: f64, b: f64) -> Isometry3<f64> {
    let r = match (
        mounts.robot1.level_from_base(),
        mounts.robot2.level_from_base(),
    ) {
        (Some(l1), Some(l2)) => {
            l1.inverse() * Rotation3::from_axis_angle(&Vector3::z_axis(), a) * l2
        }
        (Some(l1), None) => l1.inverse() * wall_rotation(a, b),
        (None, Some(l2)) => wall_rotation(a, b) * l2,
        (None, None) => unreachable!(),
    };
    iso([0.04, 1.48, 0.05], r)
}

fn all_mounts() -> Vec<MountPair> {
    let tilt = Mount::Tilt { rx: 0.3, ry: -0.2 };
    let wall_roll = Mount::Tilt {
        rx: PI / 2.0,
        ry: 0.7,
    };
    vec![
        MountPair::floor_floor(),
        MountPair::floor_ceiling(),
        MountPair::floor_wall(),
        MountPair {
            robot1: tilt,
            robot2: wall_roll,
        },
        MountPair {
            robot1: Mount::Ceiling,
            robot2: tilt,
        },
        MountPair {
            robot1: tilt,
            robot2: Mount::Wall,
        },
        MountPair {
            robot1: Mount::Wall,
            robot2: Mount::Floor,
        },
        MountPair {
            robot1: Mount::Wall,
            robot2: wall_roll,
        },
    ]
}

#[test]
fn exact_recovery_every_method_and_mount() {
    for (k, mounts) in all_mounts().iter().enumerate() {
        for &(a, b) in &[(-0.78, 0.3), (2.9, -1.2), (PI, 0.0), (1e-9, PI)] {
            let truth = truth_for(mounts, a, b);
            for n in [4, 7] {
                let pairs = pairs_for(&truth, &cloud(n, 7 + k as u64));
                for method in Method::ALL {
                    let f = fit(&pairs, method, mounts).unwrap();
                    assert!(
                        e_tran(&truth, &f.b1_from_b2) < EXACT_TOL
                            && geodesic_angle(&truth, &f.b1_from_b2) < EXACT_TOL,
                        "{mounts} {} a={a} b={b} n={n}: {:?}",
                        method.name(),
                        f.b1_from_b2
                    );
                    assert!(f.residuals.iter().all(|r| r.norm() < EXACT_TOL));
                    assert!(f.condition >= 1.0 && f.condition.is_finite());
                }
                let p1: Vec<_> = pairs.p_b1.clone();
                let x = rigid_fit_fast(&p1, &pairs.p_b2).unwrap();
                assert!(geodesic_angle(&truth, &x) < EXACT_TOL && e_tran(&truth, &x) < EXACT_TOL);
                let x = constrained_fast(&p1, &pairs.p_b2, mounts).unwrap();
                assert!(
                    geodesic_angle(&truth, &x) < EXACT_TOL,
                    "{mounts} fast constrained"
                );
                if n == 4 {
                    let a4: [Point3<f64>; 4] = [p1[0], p1[1], p1[2], p1[3]];
                    let b4: [Point3<f64>; 4] =
                        [pairs.p_b2[0], pairs.p_b2[1], pairs.p_b2[2], pairs.p_b2[3]];
                    for affine in [false, true] {
                        let x = generic_fast(&a4, &b4, affine).unwrap();
                        assert!(geodesic_angle(&truth, &x) < EXACT_TOL);
                        assert!(e_tran(&truth, &x) < EXACT_TOL);
                    }
                    let x = paper_fast(&a4, &b4, mounts).unwrap();
                    assert!(
                        geodesic_angle(&truth, &x) < EXACT_TOL,
                        "{mounts} fast paper"
                    );
                    assert!(e_tran(&truth, &x) < EXACT_TOL);
                }
            }
        }
    }
}

/// Noisy data: the fast kernels give the same answer as the documented slow paths.
#[test]
fn fast_paths_match_slow_paths_with_noise() {
    let noise = Normal::new(0.0, 0.5e-3).unwrap();
    for (k, mounts) in all_mounts().iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + k as u64);
        let truth = truth_for(mounts, 0.4, -0.9);
        let p_b2 = cloud(4, 200 + k as u64);
        let p_b1: Vec<_> = p_b2
            .iter()
            .map(|p| {
                truth * p
                    + Vector3::new(
                        noise.sample(&mut rng),
                        noise.sample(&mut rng),
                        noise.sample(&mut rng),
                    )
            })
            .collect();
        let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
        let a4 = [p_b1[0], p_b1[1], p_b1[2], p_b1[3]];
        let b4 = [p_b2[0], p_b2[1], p_b2[2], p_b2[3]];
        let pairs_close = |x: &Isometry3<f64>, y: &Isometry3<f64>| {
            e_tran(x, y) < 1e-10 && geodesic_angle(x, y) < 1e-10
        };
        assert!(pairs_close(
            &rigid_lsq(&pairs, None).unwrap().b1_from_b2,
            &rigid_fit_fast(&p_b1, &p_b2).unwrap()
        ));
        assert!(pairs_close(
            &generic_4point(&pairs, false).unwrap().b1_from_b2,
            &generic_fast(&a4, &b4, false).unwrap()
        ));
        assert!(
            pairs_close(
                &paper_constrained(&pairs, mounts).unwrap().b1_from_b2,
                &paper_fast(&a4, &b4, mounts).unwrap()
            ),
            "{mounts}"
        );
        assert!(pairs_close(
            &constrained_lsq(&pairs, mounts, &ConstrainedOptions::default())
                .unwrap()
                .b1_from_b2,
            &constrained_fast(&p_b1, &p_b2, mounts).unwrap()
        ));
    }
}

/// Brute force over a family: a fine grid followed by a coordinate-wise golden refinement is a
/// slow but assumption-free maximiser of tr(RᵀM).
fn brute_force_max(f: impl Fn(f64, f64) -> f64, two_d: bool) -> f64 {
    let steps = 360;
    let mut best = (0.0, 0.0, f64::NEG_INFINITY);
    for i in 0..steps {
        let a = -PI + 2.0 * PI * i as f64 / steps as f64;
        for jj in 0..(if two_d { steps } else { 1 }) {
            let b = -PI + 2.0 * PI * jj as f64 / steps as f64;
            let v = f(a, b);
            if v > best.2 {
                best = (a, b, v);
            }
        }
    }
    // Local refinement by shrinking pattern search.
    let (mut a, mut b, mut v) = best;
    let mut h = 2.0 * PI / steps as f64;
    while h > 1e-10 {
        let mut improved = false;
        for (da, db) in [(h, 0.0), (-h, 0.0), (0.0, h), (0.0, -h)] {
            if !two_d && db != 0.0 {
                continue;
            }
            let nv = f(a + da, b + db);
            if nv > v {
                a += da;
                b += db;
                v = nv;
                improved = true;
            }
        }
        if !improved {
            h *= 0.5;
        }
    }
    v
}

/// Closed forms (eq 11, eq 30, the yaw form for tilts, the wall 1-D search) reach the brute-force
/// minimum of ‖R − M‖_F over their family, for random (non-rotation) M. Tolerance: the pattern
/// search stops at a 1e-10 rad step, so the objective agrees to ~1e-9.
#[test]
fn closed_forms_match_brute_force() {
    const OBJ_TOL: f64 = 1e-8;
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    for trial in 0..12 {
        let m = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0))
            + if trial % 2 == 0 {
                Matrix3::identity()
            } else {
                Matrix3::zeros()
            };
        for mounts in all_mounts() {
            let r = project_rotation_family(&m, &mounts).unwrap();
            let ours = (r.matrix() - m).norm();
            let fam = |a: f64, b: f64| -> f64 {
                let t = truth_for(&mounts, a, b);
                -(t.rotation.to_rotation_matrix().matrix() - m).norm()
            };
            let two_d = matches!(family(&mounts).unwrap(), Family::Wall { .. });
            let brute = -brute_force_max(fam, two_d);
            assert!(
                ours <= brute + OBJ_TOL,
                "{mounts}: ours {ours} brute {brute}"
            );
            // The result is in the family: reconstruct and compare.
            assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
        }
        // eq 11 and eq 30 literally.
        let ff = project_rotation_family(&m, &MountPair::floor_floor()).unwrap();
        let th = (m[(1, 0)] - m[(0, 1)]).atan2(m[(0, 0)] + m[(1, 1)]);
        assert!(
            (ff.matrix() - Rotation3::from_axis_angle(&Vector3::z_axis(), th).matrix()).amax()
                < 1e-12
        );
        let fc = project_rotation_family(&m, &MountPair::floor_ceiling()).unwrap();
        let (al, be) = (m[(0, 0)] - m[(1, 1)], m[(1, 0)] + m[(0, 1)]);
        let nn = (al * al + be * be).sqrt();
        let eq30 = Matrix3::new(
            al / nn,
            be / nn,
            0.0,
            be / nn,
            -al / nn,
            0.0,
            0.0,
            0.0,
            -1.0,
        );
        assert!((fc.matrix() - eq30).amax() < 1e-12);
    }
}

#[test]
fn nearest_rotation_guards_reflection() {
    let m = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
    let r = nearest_rotation(&m);
    assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
    let r = nearest_rotation(&(rotation_from_zyz([0.3, 1.0, -2.0]).matrix() * 3.0));
    assert!((r.matrix() - rotation_from_zyz([0.3, 1.0, -2.0]).matrix()).amax() < 1e-12);
}

#[test]
fn degeneracy_errors_name_points_and_singular_values() {
    let truth = truth_for(&MountPair::floor_floor(), 0.5, 0.0);
    // Collinear.
    let line: Vec<_> = (0..4)
        .map(|i| Point3::new(0.3 * i as f64, 0.1 * i as f64, 0.2))
        .collect();
    let e = rigid_lsq(&pairs_for(&truth, &line), None).unwrap_err();
    match &e {
        CalibError::Collinear {
            rows,
            singular_values_mm,
            ..
        } => {
            assert_eq!(rows, &vec![1, 2, 3, 4]);
            assert!(singular_values_mm[1] < 1e-6);
        }
        other => panic!("{other}"),
    }
    assert!(e.to_string().contains("collinear"));
    // Coplanar: fine for lsq, an error for the 4-point methods.
    let plane = vec![
        Point3::new(0.0, 0.0, 0.5),
        Point3::new(1.0, 0.0, 0.5),
        Point3::new(0.0, 1.0, 0.5),
        Point3::new(1.0, 1.0, 0.5),
    ];
    let pairs = pairs_for(&truth, &plane);
    assert!(rigid_lsq(&pairs, None).is_ok());
    for m in [Method::Generic, Method::GenericAffine, Method::Paper] {
        let e = fit(&pairs, m, &MountPair::floor_floor()).unwrap_err();
        assert!(matches!(e, CalibError::Coplanar { .. }), "{e}");
        assert!(e.to_string().contains("lsq"));
    }
    // Too few.
    let e = rigid_lsq(&pairs_for(&truth, &plane[..2]), None).unwrap_err();
    assert!(matches!(
        e,
        CalibError::TooFewPoints {
            needed: 3,
            got: 2,
            ..
        }
    ));
    let e = generic_4point(&pairs_for(&truth, &cloud(3, 1)), false).unwrap_err();
    assert!(matches!(
        e,
        CalibError::TooFewPoints {
            needed: 4,
            got: 3,
            ..
        }
    ));
    // Two walls unsupported.
    let wall2 = MountPair {
        robot1: Mount::Wall,
        robot2: Mount::Wall,
    };
    let e = constrained_lsq(&pairs, &wall2, &ConstrainedOptions::default()).unwrap_err();
    assert!(matches!(e, CalibError::UnsupportedMounts { .. }));
    // Non-finite.
    let mut bad = pairs_for(&truth, &cloud(5, 3));
    bad.p_b2[2].x = f64::NAN;
    assert!(matches!(
        rigid_lsq(&bad, None),
        Err(CalibError::NonFinite { row: 3, .. })
    ));
    assert!(rigid_fit_fast(&bad.p_b1, &bad.p_b2).is_none());
    // Weights.
    let good = pairs_for(&truth, &cloud(5, 3));
    assert!(rigid_lsq(&good, Some(&[1.0, 2.0])).is_err());
    assert!(rigid_lsq(&good, Some(&[1.0, -2.0, 1.0, 1.0, 1.0])).is_err());
}

/// Weighted lsq: a zero-weighted corrupted point has no effect.
#[test]
fn weights_are_honoured() {
    let truth = truth_for(&MountPair::floor_floor(), 0.5, 0.0);
    let mut pairs = pairs_for(&truth, &cloud(6, 9));
    pairs.p_b1[5].x += 0.05;
    let f = rigid_lsq(&pairs, Some(&[1.0, 1.0, 1.0, 1.0, 1.0, 0.0])).unwrap();
    assert!(geodesic_angle(&truth, &f.b1_from_b2) < EXACT_TOL);
    assert!(e_tran(&truth, &f.b1_from_b2) < EXACT_TOL);
}

/// Central-difference check of the fit Jacobian. Step 1e-6 (rad or m): truncation error
/// O(h²·‖p‖) ≈ 1e-12 and round-off ≈ 1e-16/1e-6 = 1e-10, so 1e-7 is a safe tolerance.
#[test]
fn fit_jacobian_matches_central_differences() {
    const H: f64 = 1e-6;
    const JAC_TOL: f64 = 1e-7;
    let truth = truth_for(&MountPair::floor_wall(), 0.4, 1.1);
    let pairs = pairs_for(&truth, &cloud(5, 11));
    let w = [1.0, 2.0, 0.5, 1.0, 3.0];
    let axes = family_axes(
        &MountPair::floor_wall(),
        &truth.rotation.to_rotation_matrix(),
    )
    .unwrap();
    let k = axes.len() + 3;
    let mut j = DMatrix::zeros(15, k);
    fill_fit_jacobian(&pairs, &w, &truth, &axes, &mut j);
    let res = |x: &Isometry3<f64>| -> Vec<f64> {
        let mut out = vec![];
        for ((p1, p2), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(&w) {
            let r = (p1 - x * p2) * wi.sqrt();
            out.extend([r.x, r.y, r.z]);
        }
        out
    };
    for c in 0..k {
        let pert = |s: f64| -> Isometry3<f64> {
            if c < axes.len() {
                Isometry3::rotation(axes[c] * s) * truth
            } else {
                let mut t = Vector3::zeros();
                t[c - axes.len()] = s;
                Isometry3::translation(t.x, t.y, t.z) * truth
            }
        };
        let (rp, rm) = (res(&pert(H)), res(&pert(-H)));
        for i in 0..15 {
            let fd = (rp[i] - rm[i]) / (2.0 * H);
            assert!(
                (fd - j[(i, c)]).abs() < JAC_TOL,
                "col {c} row {i}: fd {fd} vs {}",
                j[(i, c)]
            );
        }
    }
    // The point-by-point accumulation that the uncertainty uses equals JᵀJ of the checked
    // Jacobian (entries of order 10: round-off 1e-13).
    let jtj = fit_jtj(&pairs, &w, &truth, &axes);
    assert!((jtj - j.transpose() * &j).amax() < 1e-12);
}

/// The predicted uncertainty matches a small seeded Monte Carlo: the empirical RMS translation
/// error over 300 trials lies within 25 % of the predicted one (sampling error of an RMS over 300
/// trials of a 3-D error is ≈ 4 %; the prediction uses σ̂ per fit, averaged here).
#[test]
fn predicted_uncertainty_matches_monte_carlo() {
    let sigma = 0.3e-3;
    let noise = Normal::new(0.0, sigma).unwrap();
    let p_b2 = cloud(8, 5);
    for mounts in [MountPair::floor_floor(), MountPair::floor_wall()] {
        let truth = truth_for(&mounts, 0.3, 0.8);
        let work = Point3::new(1.5, 0.5, 0.8);
        for method in [Method::Lsq, Method::Constrained] {
            let (mut emp, mut pred, trials) = (0.0, 0.0, 300);
            for t in 0..trials {
                let mut rng = ChaCha8Rng::seed_from_u64(1000 + t);
                let p_b1: Vec<_> = p_b2
                    .iter()
                    .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng)))
                    .collect();
                let f = fit(
                    &PointPairs::new(p_b1, p_b2.clone()).unwrap(),
                    method,
                    &mounts,
                )
                .unwrap();
                emp += (f.b1_from_b2 * work - truth * work).norm_squared();
                let u = f.uncertainty.expect("uncertainty for lsq fits");
                pred += u.tre_rms_m(&f.b1_from_b2, &work).powi(2);
            }
            let (emp, pred) = ((emp / trials as f64).sqrt(), (pred / trials as f64).sqrt());
            assert!(
                (emp / pred - 1.0).abs() < 0.25,
                "{mounts} {}: emp {emp} pred {pred}",
                method.name()
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    /// Moving b1 rigidly by G changes the fit to G·X (left invariance), for every method whose
    /// family is closed under that motion (lsq, generic: any G; constrained/paper floor–floor:
    /// G a yaw plus translation, which keeps robot 1 on the floor).
    #[test]
    fn fit_is_invariant_under_rigid_motion(
        yaw in -PI..PI, tx in -2.0..2.0f64, ty in -2.0..2.0f64, tz in -1.0..1.0f64,
        rx in -PI..PI, ry in -1.5..1.5f64, seed in 0u64..1000,
    ) {
        let mounts = MountPair::floor_floor();
        let truth = truth_for(&mounts, 0.7, 0.0);
        let noise = Normal::new(0.0, 1e-3).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p_b2 = cloud(6, seed);
        let p_b1: Vec<_> = p_b2.iter()
            .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng))).collect();
        let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
        let g_any = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(rx, ry, yaw));
        let g_yaw = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(0.0, 0.0, yaw));
        for (method, g) in [(Method::Lsq, g_any), (Method::Generic, g_any),
                            (Method::Constrained, g_yaw), (Method::Paper, g_yaw)] {
            let moved = PointPairs::new(p_b1.iter().map(|p| g * p).collect(), p_b2.clone()).unwrap();
            let f0 = fit(&pairs, method, &mounts).unwrap();
            let f1 = fit(&moved, method, &mounts).unwrap();
            let expect = g * f0.b1_from_b2;
            prop_assert!(e_tran(&expect, &f1.b1_from_b2) < 1e-9, "{}", method.name());
            prop_assert!(geodesic_angle(&expect, &f1.b1_from_b2) < 1e-9);
            for (a, b) in f0.residuals.iter().zip(&f1.residuals) {
                prop_assert!((a.norm() - b.norm()).abs() < 1e-9);
            }
        }
    }
}

/// [`fit_fast`] is the allocation-free twin of [`fit`]: every method on 4 points (the closed
/// forms) and on 7 (the affine least squares then eq 12), noisy data (1 mm), each paper mount
/// pair; agreement to round-off (m, rad).
#[test]
fn fit_fast_matches_fit_for_every_method() {
    const SAME_MATHS_TOL: f64 = 1e-9;
    for mounts in [
        MountPair::floor_floor(),
        MountPair::floor_wall(),
        MountPair::floor_ceiling(),
    ] {
        let truth = truth_for(&mounts, 0.7, -0.3);
        for n in [4, 7] {
            let p_b2 = cloud(n, 11 + n as u64);
            let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
            let noise = Normal::new(0.0, 1e-3).unwrap();
            let p_b1: Vec<Point3<f64>> = p_b2
                .iter()
                .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng)))
                .collect();
            let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
            for method in Method::ALL {
                let fast = fit_fast(method, &mounts, &p_b1, &p_b2).unwrap();
                let slow = fit(&pairs, method, &mounts).unwrap().b1_from_b2;
                assert!(
                    (fast.translation.vector - slow.translation.vector).amax() < SAME_MATHS_TOL
                        && fast.rotation.angle_to(&slow.rotation) < SAME_MATHS_TOL,
                    "{mounts:?} n={n} {}",
                    method.name()
                );
            }
        }
    }
    // Too few points or mismatched lengths: None, not a panic.
    let p = cloud(3, 1);
    assert!(fit_fast(Method::Paper, &MountPair::floor_floor(), &p, &p).is_none());
    assert!(fit_fast(Method::Lsq, &MountPair::floor_floor(), &p, &p[..2]).is_none());
}

/// The points of `repro/calibrate_huge_coords.csv` (issue 10): six exact rigid pairs at about
/// 1e153 mm (given here in m). The plain cross-covariance overflows (‖M‖²_F ≈ 1e600).
fn huge_coords_pairs() -> PointPairs {
    let rows: [[f64; 6]; 6] = [
        [1.0e153, 0.0, 5.0e152, -4.161468e152, -9.092974e152, 5.0e152],
        [0.0, 1.0e153, 5.0e152, 9.092974e152, -4.161468e152, 5.0e152],
        [
            5.0e152,
            5.0e152,
            1.2e153,
            2.465753e152,
            -6.627221e152,
            1.2e153,
        ],
        [
            6.0e152,
            2.0e152,
            9.0e152,
            -6.782862e151,
            -6.288078e152,
            9.0e152,
        ],
        [
            2.0e152,
            7.0e152,
            7.0e152,
            5.532788e152,
            -4.731623e152,
            7.0e152,
        ],
        [
            9.0e152,
            9.0e152,
            6.0e152,
            4.438355e152,
            -1.1929e153,
            6.0e152,
        ],
    ];
    let p = |v: &[f64]| Point3::new(v[0], v[1], v[2]) * 1e-3;
    PointPairs::new(
        rows.iter().map(|r| p(&r[..3])).collect(),
        rows.iter().map(|r| p(&r[3..])).collect(),
    )
    .unwrap()
}

/// Asserts that `f` is a finite proper rotation (orthonormal, det +1) to `tol`.
fn assert_proper_rotation(f: &Fit, tol: f64) {
    let r = f.b1_from_b2.rotation.to_rotation_matrix().into_inner();
    assert!(r.iter().all(|v| v.is_finite()), "{} {r}", f.method.name());
    assert!((r.transpose() * r - Matrix3::identity()).amax() < tol);
    assert!((r.determinant() - 1.0).abs() < tol);
    assert!(f
        .b1_from_b2
        .translation
        .vector
        .iter()
        .all(|v| v.is_finite()));
    assert!(f.residuals.iter().all(|v| v.iter().all(|c| c.is_finite())));
}

/// Regression (issue 10, `calibrate_huge_coords.csv`): `lsq` returned Ok with a NaN pose. Every
/// method now returns a finite proper rotation, found by rescaling: the file's rotation is
/// Rz(2 rad) (its b2 points are Rz(−2)·p_b1, printed to 7 digits, hence the 1e-6 rad tolerance),
/// and every residual is small relative to the 1e150 m coordinates.
#[test]
fn calibrate_huge_coords() {
    let pairs = huge_coords_pairs();
    let truth = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 2.0);
    for method in Method::ALL {
        let f = fit(&pairs, method, &MountPair::floor_floor()).unwrap();
        assert_proper_rotation(&f, 1e-9);
        let angle = f.b1_from_b2.rotation.angle_to(&truth);
        assert!(angle < 1e-6, "{}: {angle}", method.name());
        assert!(f.residual_rms_m() < 1e144, "{}", method.name());
    }
}

/// Regression (issue 10): a NaN or infinite tilt angle gave Ok with an all-NaN rotation from
/// `constrained`; such a mount is now refused by name, for every method that uses mounts.
#[test]
fn tilt_mount_nan_or_infinite_is_refused() {
    let pairs = pairs_for(&Isometry3::identity(), &cloud(6, 3));
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mounts = MountPair {
            robot1: Mount::Floor,
            robot2: Mount::Tilt { rx: bad, ry: 0.1 },
        };
        assert!(mounts.validate().is_err());
        for method in [Method::Constrained, Method::Paper] {
            let e = fit(&pairs, method, &mounts).unwrap_err();
            assert!(
                matches!(e, CalibError::InvalidOption { .. }) && e.to_string().contains("finite"),
                "{e}"
            );
        }
    }
    assert!(Mount::parse("tilt:nan,0").is_err());
    assert!(Mount::parse("tilt:inf,0").is_err());
}

/// Orthonormality and det +1 tolerance of the property below (round-off on a 3×3 rotation).
const PROPER_ROTATION_TOL: f64 = 1e-9;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// Any Ok fit is a finite proper rotation: arbitrary finite point sets (4–8 pairs, unrelated
    /// b1 and b2 points), coordinates in [−1, 1] times 10^e with e from −150 to 150 per robot, for
    /// every method and every paper mount pair; each fit either errors or passes the check.
    #[test]
    fn any_ok_fit_is_a_finite_proper_rotation(
        raw in proptest::collection::vec(proptest::array::uniform6(-1.0..1.0f64), 4..9),
        e1 in -150i32..150, e2 in -150i32..150,
    ) {
        let (s1, s2) = (10f64.powi(e1), 10f64.powi(e2));
        let p_b1 = raw.iter().map(|r| Point3::new(r[0], r[1], r[2]) * s1).collect();
        let p_b2 = raw.iter().map(|r| Point3::new(r[3], r[4], r[5]) * s2).collect();
        let pairs = PointPairs::new(p_b1, p_b2).unwrap();
        for mounts in [MountPair::floor_floor(), MountPair::floor_wall(), MountPair::floor_ceiling()] {
            for method in Method::ALL {
                if let Ok(f) = fit(&pairs, method, &mounts) {
                    let r = f.b1_from_b2.rotation.to_rotation_matrix().into_inner();
                    prop_assert!(r.iter().all(|v| v.is_finite()), "{}", method.name());
                    prop_assert!((r.transpose() * r - Matrix3::identity()).amax() < PROPER_ROTATION_TOL);
                    prop_assert!((r.determinant() - 1.0).abs() < PROPER_ROTATION_TOL);
                    prop_assert!(f.b1_from_b2.translation.vector.iter().all(|v| v.is_finite()));
                }
            }
        }
    }
}

/// `fit_unconstrained` needs no mounts: it equals `fit` with any mounts for the methods that
/// ignore them, and refuses the two that use them, naming `fit`.
#[test]
fn fit_unconstrained_matches_fit_and_refuses_mount_methods() {
    let truth = iso([1.4, -0.2, 0.05], rotation_from_zyz([0.3, 0.1, -0.4]));
    let pairs = pairs_for(&truth, &cloud(8, 11));
    for method in Method::ALL {
        if method.uses_mounts() {
            let err = fit_unconstrained(&pairs, method).unwrap_err();
            assert!(matches!(err, CalibError::InvalidOption { .. }), "{err}");
            assert!(err.to_string().contains("calib_core::fit("), "{err}");
        } else {
            let free = fit_unconstrained(&pairs, method).unwrap();
            let with_mounts = fit(&pairs, method, &MountPair::floor_floor()).unwrap();
            assert_eq!(free, with_mounts, "{}", method.name());
            assert!(e_tran(&truth, &free.b1_from_b2) < EXACT_TOL);
        }
    }
}

/// A fit serialises with SI units: the method by name, the translation in metres, the rotation
/// as nalgebra's quaternion `[x, y, z, w]`, the uncertainty's fields by name.
#[test]
fn fit_serialises_in_si_units() {
    let truth = iso(
        [1.5, 0.25, -0.1],
        Rotation3::from_axis_angle(&Vector3::z_axis(), 0.5),
    );
    let p_b2 = cloud(6, 3);
    let mut pairs = pairs_for(&truth, &p_b2);
    // Small noise so that the uncertainty is not zero.
    pairs.p_b1[0].x += 1e-4;
    let f = fit(&pairs, Method::Constrained, &MountPair::floor_floor()).unwrap();
    let json: serde_json::Value = serde_json::to_value(&f).unwrap();
    assert_eq!(json["method"], "constrained");
    let t = &json["b1_from_b2"]["translation"];
    let t_x = t[0].as_f64().unwrap();
    assert!(
        (t_x - f.b1_from_b2.translation.vector.x).abs() < EXACT_TOL,
        "{json}"
    );
    let q = &json["b1_from_b2"]["rotation"];
    assert_eq!(q[3].as_f64().unwrap(), f.b1_from_b2.rotation.w, "{json}");
    assert_eq!(json["residuals"].as_array().unwrap().len(), 6);
    let u = f.uncertainty.as_ref().unwrap();
    assert_eq!(
        json["uncertainty"]["sigma_point_m"].as_f64().unwrap(),
        u.sigma_point_m
    );
    assert_eq!(
        json["uncertainty"]["covariance"].as_array().unwrap().len(),
        36
    );
    let mounts = serde_json::to_value(MountPair {
        robot1: Mount::Floor,
        robot2: Mount::Tilt { rx: 0.1, ry: -0.2 },
    })
    .unwrap();
    assert_eq!(mounts["robot1"], "floor");
    assert_eq!(mounts["robot2"]["tilt"]["ry"].as_f64().unwrap(), -0.2);
}

/// `rigid_fit_fast_indexed` equals `rigid_fit_fast` of the gathered points bit for bit (the
/// masked-blunder check's subsets rely on it: its JSON was byte-identical before and after), and
/// an index out of range or fewer than 3 indices gives `None`.
#[test]
fn indexed_rigid_fit_equals_the_gathered_fit() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let x = Isometry3::new(Vector3::new(0.4, -0.2, 0.1), Vector3::new(0.3, -0.5, 1.1));
    let p_b2: Vec<Point3<f64>> = (0..200)
        .map(|_| Point3::new(rng.random(), rng.random(), rng.random()))
        .collect();
    let pairs = pairs_for(&x, &p_b2);
    let idx: Vec<usize> = (0..200).filter(|i| i % 3 != 1).collect();
    let p1: Vec<Point3<f64>> = idx.iter().map(|&i| pairs.p_b1[i]).collect();
    let p2: Vec<Point3<f64>> = idx.iter().map(|&i| pairs.p_b2[i]).collect();
    let gathered = rigid_fit_fast(&p1, &p2).unwrap();
    let indexed = rigid_fit_fast_indexed(&pairs.p_b1, &pairs.p_b2, &idx).unwrap();
    assert_eq!(gathered.translation.vector, indexed.translation.vector);
    assert_eq!(gathered.rotation.coords, indexed.rotation.coords);
    assert!(rigid_fit_fast_indexed(&pairs.p_b1, &pairs.p_b2, &[0, 1, 200]).is_none());
    assert!(rigid_fit_fast_indexed(&pairs.p_b1, &pairs.p_b2, &[0, 1]).is_none());
}

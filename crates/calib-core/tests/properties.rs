//! Property tests of the registration methods (issue 10, "Fuzzing and properties"), extending
//! `registration/tests.rs::any_ok_fit_is_a_finite_proper_rotation` (finite points of any scale,
//! the paper's three mount pairs) to what the `fit` fuzz target feeds: NaN, ±∞ and f64::MAX
//! coordinates mixed into otherwise good sets, tilted and wall mounts on either robot, per-point
//! weights, and the allocation-free twins (`fit_fast`).

use calib_core::{
    constrained_lsq, fit, fit_fast, rigid_lsq, ConstrainedOptions, Method, Mount, MountPair,
    PointPairs,
};
use nalgebra::{Isometry3, Matrix3, Point3};
use proptest::prelude::*;

/// Orthonormality and det +1 tolerance (round-off on a 3×3 rotation).
const PROPER_ROTATION_TOL: f64 = 1e-9;

fn check_finite_proper(x: &Isometry3<f64>, what: &str) -> Result<(), TestCaseError> {
    let r = x.rotation.to_rotation_matrix().into_inner();
    prop_assert!(r.iter().all(|v| v.is_finite()), "{what}: {r}");
    prop_assert!(
        (r.transpose() * r - Matrix3::identity()).amax() < PROPER_ROTATION_TOL,
        "{what}: not orthonormal {r}"
    );
    prop_assert!(
        (r.determinant() - 1.0).abs() < PROPER_ROTATION_TOL,
        "{what}: det {}",
        r.determinant()
    );
    prop_assert!(
        x.translation.vector.iter().all(|v| v.is_finite()),
        "{what}: translation {}",
        x.translation.vector
    );
    Ok(())
}

fn mount() -> impl Strategy<Value = Mount> {
    prop_oneof![
        Just(Mount::Floor),
        Just(Mount::Ceiling),
        Just(Mount::Wall),
        (-3.2..3.2f64, -3.2..3.2f64).prop_map(|(rx, ry)| Mount::Tilt { rx, ry }),
    ]
}

/// A coordinate that is usually an ordinary metre value and sometimes a poison value.
fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        20 => -2.0..2.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(f64::MAX),
        1 => Just(-f64::MAX),
        1 => Just(f64::MIN_POSITIVE),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Every method (and its fast twin) on 3–10 pairs, each coordinate ordinary or poisoned,
    /// arbitrary mounts and optional weights (some zero, negative or NaN): every Ok fit is a
    /// finite proper rotation with a finite translation; nothing panics.
    #[test]
    fn any_ok_fit_is_a_finite_proper_rotation_also_with_poison_tilts_and_weights(
        raw in proptest::collection::vec(proptest::array::uniform6(coordinate()), 3..11),
        robot1 in mount(),
        robot2 in mount(),
        weights in proptest::option::of(proptest::collection::vec(
            prop_oneof![8 => 0.0..2.0f64, 1 => Just(-1.0), 1 => Just(f64::NAN)], 10)),
    ) {
        let p_b1: Vec<Point3<f64>> = raw.iter().map(|r| Point3::new(r[0], r[1], r[2])).collect();
        let p_b2: Vec<Point3<f64>> = raw.iter().map(|r| Point3::new(r[3], r[4], r[5])).collect();
        let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
        let mounts = MountPair { robot1, robot2 };
        for method in Method::ALL {
            if let Ok(f) = fit(&pairs, method, &mounts) {
                check_finite_proper(&f.b1_from_b2, method.name())?;
            }
            if let Some(x) = fit_fast(method, &mounts, &p_b1, &p_b2) {
                check_finite_proper(&x, &format!("{} (fit_fast)", method.name()))?;
            }
        }
        if let Some(mut w) = weights {
            w.truncate(pairs.len());
            if let Ok(f) = rigid_lsq(&pairs, Some(&w)) {
                check_finite_proper(&f.b1_from_b2, "weighted lsq")?;
            }
            let options = ConstrainedOptions { weights: Some(w) };
            if let Ok(f) = constrained_lsq(&pairs, &mounts, &options) {
                check_finite_proper(&f.b1_from_b2, "weighted constrained")?;
            }
        }
    }
}

/// Regression (found by the property above, shrunk input): three pairs at the origin, one b2
/// coordinate NaN, floor–floor. `fit_fast(Constrained)` returned `Some` of a NaN transform; every
/// fast kernel now returns `None` for a non-finite result, as `constrained_lsq` errors.
#[test]
fn constrained_fast_three_origin_pairs_one_nan() {
    let p_b1 = vec![Point3::origin(); 3];
    let mut p_b2 = vec![Point3::origin(); 3];
    p_b2[2].z = f64::NAN;
    let mounts = MountPair::floor_floor();
    for method in Method::ALL {
        assert_eq!(
            fit_fast(method, &mounts, &p_b1, &p_b2),
            None,
            "{}",
            method.name()
        );
    }
    let pairs = PointPairs::new(p_b1, p_b2).unwrap();
    assert!(constrained_lsq(&pairs, &mounts, &ConstrainedOptions::default()).is_err());
}

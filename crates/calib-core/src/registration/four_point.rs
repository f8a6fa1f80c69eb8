//! The paper's 4-point methods: the affine `H = A·B⁻¹` from homogeneous point columns (n = 4, or
//! the affine least squares for n > 4), the rotation from its 3×3 block (nearest rotation or the
//! mounts' family), and the translation of eq (12).

use super::checks::{check_pairs, fit_rescued, spread_singular_values};
use super::family::project_rotation_family;
use super::method::{residuals, Fit, Method};
use super::mount::MountPair;
use super::rotation::nearest_rotation;
use crate::error::CalibError;
use crate::points::PointPairs;
use nalgebra::{DMatrix, Isometry3, Matrix3, Point3, Translation3, UnitQuaternion, Vector3};

/// Affine `H = A·Bᵀ(B·Bᵀ)⁻¹` (= `A·B⁻¹` for n = 4); returns H's 3×3 block and translation column.
/// Errors: `B·Bᵀ` singular (coplanar points), or H not finite (overflow).
fn affine_lsq(
    pairs: &PointPairs,
    method: Method,
) -> Result<(Matrix3<f64>, Vector3<f64>), CalibError> {
    let n = pairs.p_b1.len();
    let mut a = DMatrix::zeros(4, n);
    let mut b = DMatrix::zeros(4, n);
    for k in 0..n {
        for r in 0..3 {
            a[(r, k)] = pairs.p_b1[k][r];
            b[(r, k)] = pairs.p_b2[k][r];
        }
        a[(3, k)] = 1.0;
        b[(3, k)] = 1.0;
    }
    let bbt = &b * b.transpose();
    let inv = bbt.try_inverse().ok_or_else(|| coplanar_error(pairs))?;
    let h = &a * b.transpose() * inv;
    if !h.iter().all(|v| v.is_finite()) {
        return Err(CalibError::NumericalFailure {
            method: method.name().into(),
            message: "the affine solve H = A·B⁻¹ overflowed".into(),
        });
    }
    let m = Matrix3::from_fn(|i, j| h[(i, j)]);
    Ok((m, Vector3::new(h[(0, 3)], h[(1, 3)], h[(2, 3)])))
}

/// The affine `H = A·B⁻¹` of the 4-point generic method (A, B: homogeneous point columns).
/// Returns `(M, t_H)`: H's 3×3 block and its translation column. `None` if B is singular
/// (coplanar points) or H is not finite.
///
/// Computed without the 4×4 inverse: H maps each `p2_k` to `p1_k`, so with the edge matrices
/// `D1 = [p1_2 − p1_1, p1_3 − p1_1, p1_4 − p1_1]` and `D2` likewise, `M·D2 = D1`, hence
/// `M = D1·D2⁻¹` and `t_H = p1_1 − M·p2_1` (`|det B| = |det D2|`, so B is singular exactly when
/// D2 is). Same solution as the 4×4 solve, to round-off (tested).
pub(super) fn affine_4point(
    p_b1: &[Point3<f64>; 4],
    p_b2: &[Point3<f64>; 4],
) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let edges =
        |p: &[Point3<f64>; 4]| Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let d2_inv = edges(p_b2).try_inverse()?;
    let m = edges(p_b1) * d2_inv;
    let t = p_b1[0].coords - m * p_b2[0].coords;
    (m.iter().chain(t.iter()).all(|v| v.is_finite())).then_some((m, t))
}

/// eq (12): `T = (1/n)·Σ (p1_i − R·p2_i)`, evaluated as `c1 − R·c2` (c the centroids; the same
/// sum regrouped, one rotation instead of n).
pub(super) fn translation_eq12(
    p_b1: &[Point3<f64>],
    p_b2: &[Point3<f64>],
    q: &UnitQuaternion<f64>,
) -> Vector3<f64> {
    let n = p_b1.len() as f64;
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for (a, b) in p_b1.iter().zip(p_b2) {
        c1 += a.coords;
        c2 += b.coords;
    }
    c1 / n - q * (c2 / n)
}

fn four_point_condition(pairs: &PointPairs) -> f64 {
    let sv = spread_singular_values(&pairs.p_b2);
    if sv[2] > 0.0 {
        sv[0] / sv[2]
    } else {
        f64::INFINITY
    }
}

fn coplanar_error(pairs: &PointPairs) -> CalibError {
    CalibError::Coplanar {
        rows: (0..pairs.p_b1.len()).map(|i| pairs.row(i)).collect(),
        robot: 2,
        singular_values_mm: spread_singular_values(&pairs.p_b2).map(|s| s * 1e3),
    }
}

/// The paper's generic method (\[8\]): `H = A·B⁻¹` from 4 non-coplanar points (homogeneous columns),
/// the Frobenius-nearest rotation of H's 3×3 block, then the translation: eq (12)
/// `T = (1/n)Σ(p1ᵢ − R·p2ᵢ)` when `affine_translation` is false, H's own column when true.
/// With n > 4 points H is the affine least-squares solution. Errors: fewer than 4 points,
/// collinear or coplanar points, non-finite values.
pub fn generic_4point(pairs: &PointPairs, affine_translation: bool) -> Result<Fit, CalibError> {
    fit_rescued(pairs, |p| generic_4point_raw(p, affine_translation))
}

fn generic_4point_raw(pairs: &PointPairs, affine_translation: bool) -> Result<Fit, CalibError> {
    let method = if affine_translation {
        Method::GenericAffine
    } else {
        Method::Generic
    };
    check_pairs(pairs, method)?;
    let (m, t_h) = affine_lsq(pairs, method)?;
    let q = UnitQuaternion::from_rotation_matrix(&nearest_rotation(&m));
    let t = if affine_translation {
        t_h
    } else {
        translation_eq12(&pairs.p_b1, &pairs.p_b2, &q)
    };
    let b1_from_b2 = Isometry3::from_parts(Translation3::from(t), q);
    Ok(Fit {
        method,
        residuals: residuals(pairs, &b1_from_b2),
        b1_from_b2,
        condition: four_point_condition(pairs),
        uncertainty: None,
    })
}

/// The paper's constrained method: the generic `H = A·B⁻¹`, its 3×3 block projected onto the
/// rotations the mounts allow ([`project_rotation_family`]: eq 11 floor–floor, eq 30 floor–ceiling,
/// eqs 16–21 floor–wall, the yaw closed form for known tilts), then eq (12).
/// Errors: as [`generic_4point`], plus two wall mounts.
pub fn paper_constrained(pairs: &PointPairs, mounts: &MountPair) -> Result<Fit, CalibError> {
    fit_rescued(pairs, |p| paper_constrained_raw(p, mounts))
}

fn paper_constrained_raw(pairs: &PointPairs, mounts: &MountPair) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Paper)?;
    let (m, _) = affine_lsq(pairs, Method::Paper)?;
    let q = UnitQuaternion::from_rotation_matrix(&project_rotation_family(&m, mounts)?);
    let t = translation_eq12(&pairs.p_b1, &pairs.p_b2, &q);
    let b1_from_b2 = Isometry3::from_parts(Translation3::from(t), q);
    Ok(Fit {
        method: Method::Paper,
        residuals: residuals(pairs, &b1_from_b2),
        b1_from_b2,
        condition: four_point_condition(pairs),
        uncertainty: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registration::rotation::tests::lcg;
    use nalgebra::Matrix4;
    /// The 4-point affine solve by edge matrices equals `H = A·B⁻¹` with the 4×4 inverse (relative
    /// round-off on metre-scale points), and coplanar points give `None`.
    #[test]
    fn affine_4point_equals_the_4x4_solve() {
        let mut next = lcg(4242);
        for _ in 0..200 {
            let p1: [Point3<f64>; 4] = std::array::from_fn(|_| Point3::new(next(), next(), next()));
            let p2: [Point3<f64>; 4] = std::array::from_fn(|_| {
                Point3::new(next(), next(), next()) + Vector3::new(1.5, 0.5, 1.5)
            });
            let (m, t) = affine_4point(&p1, &p2).unwrap();
            let mut a = Matrix4::zeros();
            let mut b = Matrix4::zeros();
            for k in 0..4 {
                for r in 0..3 {
                    a[(r, k)] = p1[k][r];
                    b[(r, k)] = p2[k][r];
                }
                a[(3, k)] = 1.0;
                b[(3, k)] = 1.0;
            }
            let h = a * b.try_inverse().unwrap();
            // Random point sets can be ill-conditioned; scale the tolerance by the condition.
            let tol = 1e-12 * h.amax().max(1.0) * b.try_inverse().unwrap().amax().max(1.0);
            assert!((h.fixed_view::<3, 3>(0, 0) - m).amax() < tol, "{h} {m}");
            assert!((h.fixed_view::<3, 1>(0, 3) - t).amax() < tol);
        }
        let flat: [Point3<f64>; 4] = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(1.0, 1.0, 0.0),
        ];
        assert!(affine_4point(&flat, &flat).is_none());
    }
}

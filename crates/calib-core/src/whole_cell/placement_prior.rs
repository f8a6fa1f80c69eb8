//! An optional prior on the placement `b1_from_b2` around a known nominal (cells whose two arms
//! share one base, so the placement is known up to a small error).

use nalgebra::{Isometry3, Matrix3, Matrix6, Vector3, Vector6};

use super::CellFitError;

/// A Gaussian prior on `b1_from_b2` around `nominal_b1_from_b2`: the six prior rows are
/// `[t_δ/σ_m; log(R_δ)/σ_rad]` with `δ = b1_from_b2·nominal⁻¹` (translation in m, rotation
/// vector in rad, both expressed in `b1`). A σ of 0 leaves that half of the placement
/// unpenalised (free, as without a prior).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacementPrior {
    /// The nominal (known) placement of base 2 in base 1.
    pub nominal_b1_from_b2: Isometry3<f64>,
    /// Standard deviation of each translation component of `δ`, m (0: unpenalised).
    pub sigma_m: f64,
    /// Standard deviation of each rotation-vector component of `δ`, rad (0: unpenalised).
    pub sigma_rad: f64,
}

impl PlacementPrior {
    /// Checks that both σ are finite and ≥ 0 and the nominal is finite.
    pub fn check(&self) -> Result<(), CellFitError> {
        for (name, v) in [("sigma_m", self.sigma_m), ("sigma_rad", self.sigma_rad)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CellFitError::InvalidInput(format!(
                    "placement prior `{name}` is {v}; it must be finite and ≥ 0"
                )));
            }
        }
        let t = self.nominal_b1_from_b2.translation.vector;
        let q = self.nominal_b1_from_b2.rotation.coords;
        if !(t.iter().chain(q.iter()).all(|v| v.is_finite())) {
            return Err(CellFitError::InvalidInput(
                "placement prior: the nominal b1_from_b2 is not finite".into(),
            ));
        }
        Ok(())
    }

    /// Number of prior rows: 3 per half with σ > 0 (0, 3 or 6).
    pub fn rows(&self) -> usize {
        3 * usize::from(self.sigma_m > 0.0) + 3 * usize::from(self.sigma_rad > 0.0)
    }

    /// The whitened prior residual at `b1_from_b2` and its Jacobian with respect to the
    /// solver's left perturbation `(ρ, φ)` of the placement (`X ← Translation(ρ)·Rotation(φ)·X`),
    /// [`Self::rows`] rows × 6 columns: `∂t/∂ρ = I`, `∂t/∂φ = −[t_δ]×`,
    /// `∂log R/∂φ = J_l⁻¹(log R_δ)`, each divided by its σ.
    pub fn linearise(&self, b1_from_b2: &Isometry3<f64>) -> (Vec<f64>, Vec<[f64; 6]>) {
        let delta = b1_from_b2 * self.nominal_b1_from_b2.inverse();
        let t = delta.translation.vector;
        let w = delta.rotation.scaled_axis();
        let mut full_r = Vector6::zeros();
        full_r.fixed_rows_mut::<3>(0).copy_from(&t);
        full_r.fixed_rows_mut::<3>(3).copy_from(&w);
        let mut full_j = Matrix6::zeros();
        full_j
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&Matrix3::identity());
        full_j.fixed_view_mut::<3, 3>(0, 3).copy_from(&-skew(&t));
        full_j
            .fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&left_jacobian_inverse(&w));
        let mut r = Vec::with_capacity(self.rows());
        let mut j = Vec::with_capacity(self.rows());
        for (start, sigma) in [(0, self.sigma_m), (3, self.sigma_rad)] {
            if sigma > 0.0 {
                for k in start..start + 3 {
                    r.push(full_r[k] / sigma);
                    j.push(std::array::from_fn(|c| full_j[(k, c)] / sigma));
                }
            }
        }
        (r, j)
    }
}

/// `[v]×`, the cross-product matrix.
fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Inverse of the SO(3) left Jacobian at rotation vector `w` (rad):
/// `I − ½[w]× + (1/θ² − (1+cos θ)/(2θ sin θ))[w]×²`, series `1/12` for small θ.
fn left_jacobian_inverse(w: &Vector3<f64>) -> Matrix3<f64> {
    let theta = w.norm();
    let k = skew(w);
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        1.0 / (theta * theta) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() - 0.5 * k + c * k * k
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    /// Central-difference step (m, rad).
    const STEP: f64 = 1e-6;
    /// Agreement of analytic and central-difference Jacobians (whitened units).
    const JAC_TOL: f64 = 1e-6;

    fn prior() -> PlacementPrior {
        PlacementPrior {
            nominal_b1_from_b2: Isometry3::new(
                Vector3::new(1.2, -0.3, 0.05),
                Vector3::new(0.1, -0.2, 2.9),
            ),
            sigma_m: 0.01,
            sigma_rad: 0.02,
        }
    }

    #[test]
    fn jacobian_matches_central_differences() {
        let p = prior();
        // Large deviations on purpose, so the −[t]× and J_l⁻¹ terms matter.
        let x = Isometry3::new(Vector3::new(0.2, 0.1, -0.3), Vector3::new(0.4, -0.7, 0.3))
            * p.nominal_b1_from_b2;
        let (_, j) = p.linearise(&x);
        assert_eq!(j.len(), 6);
        for c in 0..6 {
            let mut d = [0.0; 6];
            d[c] = STEP;
            let shift = |s: f64| {
                let rho = Vector3::new(d[0], d[1], d[2]) * s;
                let phi = Vector3::new(d[3], d[4], d[5]) * s;
                p.linearise(&(Isometry3::new(rho, phi) * x)).0
            };
            let (rp, rm) = (shift(1.0), shift(-1.0));
            for k in 0..6 {
                let num = (rp[k] - rm[k]) / (2.0 * STEP);
                assert!(
                    (num - j[k][c]).abs() < JAC_TOL * (1.0 + num.abs()),
                    "row {k} col {c}: analytic {} vs numeric {num}",
                    j[k][c]
                );
            }
        }
    }

    #[test]
    fn residual_is_zero_at_nominal_and_whitened_off_it() {
        let p = prior();
        let (r, _) = p.linearise(&p.nominal_b1_from_b2);
        assert!(r.iter().all(|v| v.abs() < 1e-12), "{r:?}");
        let x = Translation3::new(0.03, 0.0, 0.0) * p.nominal_b1_from_b2;
        let (r, _) = p.linearise(&x);
        assert!((r[0] - 3.0).abs() < 1e-9, "{r:?}");
    }

    #[test]
    fn zero_sigma_drops_rows_and_bad_sigma_is_rejected() {
        let mut p = prior();
        p.sigma_rad = 0.0;
        assert_eq!(p.rows(), 3);
        assert_eq!(p.linearise(&p.nominal_b1_from_b2).1.len(), 3);
        p.sigma_m = f64::NAN;
        let e = p.check().unwrap_err().to_string();
        assert!(e.contains("sigma_m"), "{e}");
    }
}

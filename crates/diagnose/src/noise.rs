//! The cell's stated noise at a session's configurations ([`NoiseModel`]: alignment,
//! repeatability of both robots, encoder quantisation) and the seeded Monte Carlo of the
//! rigid-fit residual RMS it predicts ([`simulate_rms`]).

use handclasp_cell::{Cell, CellRobot};
use nalgebra::{Isometry3, Matrix3, Matrix3xX, Point3, Vector3};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use crate::DiagnoseError;

/// The cell's noise at the session's configurations: per point, the Cholesky-free pieces needed
/// to draw the residual noise `r = δ1 + J1·u1 − ε − R·(δ2 + J2·u2)` (alignment `ε` per b1 axis,
/// repeatability `δ` isotropic per robot, encoder quantisation `u` uniform in ±resolution/2),
/// and its effective per-axis variance.
pub struct NoiseModel {
    /// Alignment noise σ per b1 axis, m.
    alignment: Vector3<f64>,
    /// Repeatability σ of each robot, isotropic, m.
    repeatability: f64,
    /// Encoder resolution, rad (quantisation uniform in ±resolution/2).
    resolution: f64,
    /// Robot 1's tip position Jacobians, b1 axes.
    j1: Vec<Matrix3xX<f64>>,
    /// Robot 2's tip position Jacobians rotated into b1 axes.
    j2_b1: Vec<Matrix3xX<f64>>,
    /// Mean over points of trace(Σ_i)/3, m².
    pub sigma2_eff: f64,
}

impl NoiseModel {
    /// The noise of `cell` at joint vectors `q1`, `q2` (rad), robot 2's Jacobians turned into
    /// b1 axes by `r_x` (the rotation of `b1_from_b2`). Errors: a joint vector the model rejects.
    pub fn new(
        cell: &Cell,
        q1: &[Vec<f64>],
        q2: &[Vec<f64>],
        r_x: &Matrix3<f64>,
    ) -> Result<Self, DiagnoseError> {
        let noise = &cell.noise;
        let jac = |robot: &CellRobot, which: u8, point: usize, q: &[f64]| {
            kinematics::tip_position_jacobian(&robot.model, q, &robot.flange_from_tip).map_err(
                |source| DiagnoseError::Model {
                    robot: which,
                    point: point + 1,
                    source,
                },
            )
        };
        let mut j1 = Vec::with_capacity(q1.len());
        let mut j2_b1 = Vec::with_capacity(q1.len());
        let q_var = noise.encoder_resolution_rad.powi(2) / 12.0;
        let mut sum = 0.0;
        for (i, (a, b)) in q1.iter().zip(q2).enumerate() {
            let ja = jac(&cell.robot1, 1, i, a)?;
            let jb = r_x * jac(&cell.robot2, 2, i, b)?;
            sum += noise.alignment_m.norm_squared()
                + 6.0 * noise.repeatability_m.powi(2)
                + q_var * (ja.norm_squared() + jb.norm_squared());
            j1.push(ja);
            j2_b1.push(jb);
        }
        Ok(Self {
            alignment: noise.alignment_m,
            repeatability: noise.repeatability_m,
            resolution: noise.encoder_resolution_rad,
            sigma2_eff: sum / (3.0 * q1.len().max(1) as f64),
            j1,
            j2_b1,
        })
    }

    /// Covariance of point `i`'s residual noise, b1 axes, m².
    fn covariance(&self, i: usize) -> Matrix3<f64> {
        let q_var = self.resolution.powi(2) / 12.0;
        Matrix3::from_diagonal(&self.alignment.component_mul(&self.alignment))
            + Matrix3::identity() * (2.0 * self.repeatability.powi(2))
            + (&self.j1[i] * self.j1[i].transpose() + &self.j2_b1[i] * self.j2_b1[i].transpose())
                * q_var
    }

    /// Whitening matrices `σ̄·Σ_i^{-1/2}` (σ̄² = `sigma2_eff`); unit matrices when
    /// the cell states no noise.
    pub fn whitening(&self) -> Vec<Matrix3<f64>> {
        let sbar = self.sigma2_eff.sqrt();
        (0..self.j1.len())
            .map(|i| {
                let eig = self.covariance(i).symmetric_eigen();
                if eig.eigenvalues.min() <= 1e-30 || sbar <= 0.0 {
                    return Matrix3::identity();
                }
                let d = Matrix3::from_diagonal(&eig.eigenvalues.map(|l| sbar / l.sqrt()));
                eig.eigenvectors * d * eig.eigenvectors.transpose()
            })
            .collect()
    }

    /// One draw of point `i`'s residual noise, b1 axes, m.
    fn draw(&self, i: usize, rng: &mut impl Rng) -> Vector3<f64> {
        let g = |rng: &mut dyn rand::RngCore| -> f64 { StandardNormal.sample(rng) };
        let mut r = -self
            .alignment
            .component_mul(&Vector3::new(g(rng), g(rng), g(rng)));
        if self.repeatability > 0.0 {
            r += self.repeatability * Vector3::new(g(rng), g(rng), g(rng));
            r -= self.repeatability * Vector3::new(g(rng), g(rng), g(rng));
        }
        if self.resolution > 0.0 {
            let h = self.resolution / 2.0;
            for (j, sign) in [(&self.j1[i], 1.0), (&self.j2_b1[i], -1.0)] {
                for c in 0..j.ncols() {
                    r += sign * rng.random_range(-h..=h) * j.column(c);
                }
            }
        }
        r
    }
}

/// MC distribution (ascending) of the rigid-fit residual RMS (m, 3-D per point) for data
/// `p1 = x·p2 + d + noise`. Trial `t` draws from `trial_rng(seed, t)`; the trials run in
/// parallel on rayon's current pool, and the result does not depend on the thread count.
pub fn simulate_rms(
    p2: &[Point3<f64>],
    x: &Isometry3<f64>,
    d: &[Vector3<f64>],
    noise: &NoiseModel,
    seed: u64,
    trials: usize,
) -> Vec<f64> {
    let mut out: Vec<f64> = (0..trials)
        .into_par_iter()
        .map(|t| {
            let mut rng = calib_core::stats::trial_rng(seed, t as u64);
            let p1: Vec<Point3<f64>> = p2
                .iter()
                .zip(d)
                .enumerate()
                .map(|(i, (p, di))| x * p + di + noise.draw(i, &mut rng))
                .collect();
            let fit = calib_core::rigid_fit_fast(&p1, p2).unwrap_or(*x);
            let rss: f64 = p1
                .iter()
                .zip(p2)
                .map(|(a, b)| (a - fit * b).norm_squared())
                .sum();
            (rss / p2.len() as f64).sqrt()
        })
        .collect();
    out.sort_by(f64::total_cmp);
    out
}

//! The identification problem of a session for `calib_core::identify`: the tips of both robots
//! from the kinematic-error model (`kinematics::true_base_from_tip`) and their analytic
//! Jacobians (`kinematics::tip_error_jacobian`) for the catalogue's parameters.

use calib_core::identify::{IdentifyError, Robot, TipEval, TipModel};
use kinematics::{ErrorParam, KinematicErrors};
use nalgebra::{Matrix3, Matrix3xX, Point3};
use sim_cell::Cell;

use crate::catalogue::{Candidate, EffectKind};

/// The identification problem of a session: tips from the kinematic-error model.
pub struct SessionModel<'a> {
    cell: &'a Cell,
    q1: &'a [Vec<f64>],
    q2: &'a [Vec<f64>],
    candidates: &'a [Candidate],
    /// Per-point whitening matrices (empty: unit weights).
    weights: Vec<Matrix3<f64>>,
}

impl<'a> SessionModel<'a> {
    /// Wraps a cell, joint vectors (rad) and a catalogue.
    pub fn new(
        cell: &'a Cell,
        q1: &'a [Vec<f64>],
        q2: &'a [Vec<f64>],
        candidates: &'a [Candidate],
    ) -> Self {
        Self {
            cell,
            q1,
            q2,
            candidates,
            weights: Vec::new(),
        }
    }

    /// Sets per-point whitening matrices (see `calib_core::identify::TipModel::weight`), one per
    /// point.
    pub fn with_weights(mut self, weights: Vec<Matrix3<f64>>) -> Self {
        self.weights = weights;
        self
    }

    /// The two robots' error sets for parameters `params = values`.
    pub fn errors(&self, params: &[usize], values: &[f64]) -> (KinematicErrors, KinematicErrors) {
        let mut e1 = KinematicErrors::zero(self.cell.robot1.model.dof());
        let mut e2 = KinematicErrors::zero(self.cell.robot2.model.dof());
        for (&p, &v) in params.iter().zip(values) {
            let c = &self.candidates[p];
            match c.robot() {
                Robot::One => e1.set(c.param(), v),
                Robot::Two => e2.set(c.param(), v),
            }
        }
        (e1, e2)
    }
}

impl TipModel for SessionModel<'_> {
    fn n_points(&self) -> usize {
        self.q1.len()
    }
    fn n_params(&self) -> usize {
        self.candidates.len()
    }
    fn param_robot(&self, j: usize) -> Robot {
        self.candidates[j].robot()
    }
    fn param_prior(&self, j: usize) -> f64 {
        // Each (robot, kind) family equally likely a priori: 1/family size.
        let c = &self.candidates[j];
        let size = self
            .candidates
            .iter()
            .filter(|o| o.robot() == c.robot() && o.kind() == c.kind())
            .count();
        1.0 / size.max(1) as f64
    }
    fn weight(&self, point: usize) -> Matrix3<f64> {
        self.weights
            .get(point)
            .copied()
            .unwrap_or_else(Matrix3::identity)
    }
    fn param_scale(&self, j: usize) -> f64 {
        match self.candidates[j].kind() {
            // 1 mrad, 1 mm, 1e-3, and 1e-6 rad/(N·m) (≈ 0.06 deg/(kN·m)).
            EffectKind::Compliance => 1e-6,
            _ => 1e-3,
        }
    }
    fn eval(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<TipEval, IdentifyError> {
        let (e1, e2) = self.errors(params, values);
        let merr = |e: kinematics::KinematicsError| IdentifyError::Model {
            point,
            source: Box::new(e),
        };
        let (r1, r2) = (&self.cell.robot1, &self.cell.robot2);
        let p1 = kinematics::true_base_from_tip(
            &r1.model,
            &e1,
            &self.q1[point],
            &r1.flange_from_tip,
            &r1.g_base,
        )
        .map_err(merr)?;
        let p2 = kinematics::true_base_from_tip(
            &r2.model,
            &e2,
            &self.q2[point],
            &r2.flange_from_tip,
            &r2.g_base,
        )
        .map_err(merr)?;
        let mut jacobian = Matrix3xX::zeros(jacobian_params.len());
        if !jacobian_params.is_empty() {
            for (robot, setup, errors, q) in [
                (Robot::One, r1, &e1, &self.q1[point]),
                (Robot::Two, r2, &e2, &self.q2[point]),
            ] {
                let cols: Vec<usize> = (0..jacobian_params.len())
                    .filter(|&c| self.candidates[jacobian_params[c]].robot() == robot)
                    .collect();
                if cols.is_empty() {
                    continue;
                }
                let eps: Vec<ErrorParam> = cols
                    .iter()
                    .map(|&c| self.candidates[jacobian_params[c]].param())
                    .collect();
                let j = kinematics::tip_error_jacobian(
                    &setup.model,
                    errors,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                    &eps,
                )
                .map_err(merr)?;
                for (k, &c) in cols.iter().enumerate() {
                    jacobian.set_column(c, &j.column(k));
                }
            }
        }
        Ok(TipEval {
            p1_b1: Point3::from(p1.translation.vector),
            p2_b2: Point3::from(p2.translation.vector),
            jacobian,
        })
    }
}

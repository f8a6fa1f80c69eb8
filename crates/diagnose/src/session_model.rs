//! The identification problem of a session for `calib_core::identify`: the tips of both robots
//! from the kinematic-error model (`kinematics::true_base_from_tip`) and their analytic
//! Jacobians (`kinematics::tip_error_jacobian`) for the catalogue's parameters.
//!
//! Two caches keep the evaluation from redoing work, without changing a single bit of its
//! results: each robot's nominal tips (zero errors) are computed once, when the model is built
//! (the fits of the selection evaluate a robot without fitted parameters at its nominal tips over
//! and over), and each thread keeps the two robots' error sets of the last parameter values it
//! evaluated (a fit evaluates every point at the same values) and the split by robot of the last
//! Jacobian parameter list it was asked for.
//!
//! The inputs are checked once, not at every point: each robot's tip offset and gravity when
//! the model is built, each candidate's parameter against its robot's model, each error set
//! when it is built, and each point's joint values by its nominal tip. Where all of these hold
//! the unchecked kinematics run (`kinematics::true_base_from_tip_unchecked`,
//! `tip_error_jacobian_unchecked`, `true_tip_with_error_jacobian_unchecked`: the same values,
//! bit for bit); otherwise the checked functions, which name the failure.

use std::cell::RefCell;
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};

use calib_core::identify::{IdentifyError, TipEval, TipModel};
use calib_core::Robot;
use handclasp_cell::{Cell, CellRobot};
use kinematics::{ErrorParam, KinematicErrors};
use nalgebra::{Matrix3, Matrix3xX, Point3};

use crate::catalogue::{Candidate, EffectKind};

/// Source of [`SessionModel`] ids (keys of the per-thread error-set cache).
static NEXT_MODEL_ID: AtomicU64 = AtomicU64::new(0);

/// The two robots' error sets built for one model at one parameter vector.
struct CachedErrors {
    /// [`SessionModel::id`] of the model that built them.
    model: u64,
    /// The parameters (catalogue indices).
    params: Vec<usize>,
    /// Their values, compared bit for bit.
    values: Vec<u64>,
    /// The error sets.
    errors: Rc<ErrorSets>,
}

/// The two robots' error sets at one parameter vector, and whether each passed
/// [`KinematicErrors::check`] against its robot's model.
struct ErrorSets {
    /// Robot 1's and robot 2's errors.
    robot: [KinematicErrors; 2],
    /// Whether each is valid for its robot's model.
    valid: [bool; 2],
    /// Whether each is all zero ([`KinematicErrors::is_zero`]).
    zero: [bool; 2],
}

/// A Jacobian parameter list split by robot: for robot 1 and robot 2, the positions in the
/// list of that robot's parameters, their kinematic parameters, and whether every one of them
/// passed [`ErrorParam::check_model`] against its robot's model.
struct JacobianSplit {
    /// [`SessionModel::id`] of the model that built it.
    model: u64,
    /// The Jacobian parameters (catalogue indices).
    params: Vec<usize>,
    /// Per robot, the positions in `params` of its parameters.
    columns: [Vec<usize>; 2],
    /// Per robot, those parameters' kinematic parameters.
    errors: [Vec<ErrorParam>; 2],
    /// Per robot, whether each of them is valid for its model.
    valid: [bool; 2],
}

thread_local! {
    /// The error sets this thread built last (see the module documentation).
    static LAST_ERRORS: RefCell<Option<CachedErrors>> = const { RefCell::new(None) };
    /// The Jacobian parameter split this thread built last.
    static LAST_SPLIT: RefCell<Option<Rc<JacobianSplit>>> = const { RefCell::new(None) };
}

/// The identification problem of a session: tips from the kinematic-error model.
pub struct SessionModel<'a> {
    /// Unique per model: the key of the per-thread error-set cache.
    id: u64,
    cell: &'a Cell,
    q1: &'a [Vec<f64>],
    q2: &'a [Vec<f64>],
    candidates: &'a [Candidate],
    /// Per-point whitening matrices (empty: unit weights).
    weights: Vec<Matrix3<f64>>,
    /// Per point, robot 1's and robot 2's nominal tips (`true_base_from_tip` with zero errors),
    /// each in its own base frame, m; `None` where that evaluation fails (a bad joint vector:
    /// [`TipModel::eval`] then reports the failure).
    nominal_tips: Vec<[Option<Point3<f64>>; 2]>,
    /// Per robot, whether its tip offset and gravity pass `kinematics::check_tip_inputs`.
    inputs_valid: [bool; 2],
    /// Per candidate, whether its parameter passes [`ErrorParam::check_model`] against its
    /// robot's model.
    param_valid: Vec<bool>,
}

impl<'a> SessionModel<'a> {
    /// Wraps a cell, joint vectors (rad) and a catalogue.
    pub fn new(
        cell: &'a Cell,
        q1: &'a [Vec<f64>],
        q2: &'a [Vec<f64>],
        candidates: &'a [Candidate],
    ) -> Self {
        let nominal = |robot: &CellRobot, q: &[f64]| {
            let zero = KinematicErrors::zero_for(&robot.model);
            tip_b(robot, &zero, q).ok()
        };
        let nominal_tips = q1
            .iter()
            .zip(q2)
            .map(|(a, b)| [nominal(&cell.robot1, a), nominal(&cell.robot2, b)])
            .collect();
        let inputs_valid = [&cell.robot1, &cell.robot2].map(|r| {
            let zero = KinematicErrors::zero_for(&r.model);
            kinematics::check_tip_inputs(&r.model, &zero, &r.flange_from_tip, &r.g_base, &[])
                .is_ok()
        });
        let param_valid = candidates
            .iter()
            .map(|c| {
                let robot = match c.robot() {
                    Robot::One => &cell.robot1,
                    Robot::Two => &cell.robot2,
                };
                c.param().check_model(&robot.model).is_ok()
            })
            .collect();
        Self {
            id: NEXT_MODEL_ID.fetch_add(1, Ordering::Relaxed),
            cell,
            q1,
            q2,
            candidates,
            weights: Vec::new(),
            nominal_tips,
            inputs_valid,
            param_valid,
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
        let mut e1 = KinematicErrors::zero_for(&self.cell.robot1.model);
        let mut e2 = KinematicErrors::zero_for(&self.cell.robot2.model);
        for (&p, &v) in params.iter().zip(values) {
            let c = &self.candidates[p];
            match c.robot() {
                Robot::One => e1.set(c.param(), v),
                Robot::Two => e2.set(c.param(), v),
            }
        }
        (e1, e2)
    }

    /// [`SessionModel::errors`] (and their checks) through this thread's cache of the last error
    /// sets built.
    fn cached_errors(&self, params: &[usize], values: &[f64]) -> Rc<ErrorSets> {
        let hit = LAST_ERRORS.with_borrow(|last| {
            last.as_ref()
                .filter(|c| {
                    c.model == self.id
                        && c.params == params
                        && c.values.len() == values.len()
                        && c.values.iter().zip(values).all(|(&a, b)| a == b.to_bits())
                })
                .map(|c| Rc::clone(&c.errors))
        });
        if let Some(errors) = hit {
            return errors;
        }
        let (e1, e2) = self.errors(params, values);
        let valid = [
            e1.check(&self.cell.robot1.model).is_ok(),
            e2.check(&self.cell.robot2.model).is_ok(),
        ];
        let zero = [e1.is_zero(), e2.is_zero()];
        let errors = Rc::new(ErrorSets {
            robot: [e1, e2],
            valid,
            zero,
        });
        LAST_ERRORS.set(Some(CachedErrors {
            model: self.id,
            params: params.to_vec(),
            values: values.iter().map(|v| v.to_bits()).collect(),
            errors: Rc::clone(&errors),
        }));
        errors
    }

    /// The tip of robot `robot` (0: robot 1, 1: robot 2) at point `point` with the error sets
    /// `errors`, its base frame, m: what `true_base_from_tip` returns, bit for bit. When the
    /// errors are zero, that is the nominal tip computed in [`SessionModel::new`]; when they and
    /// the point's inputs (which the nominal tip checked) are valid, the unchecked FK; otherwise
    /// the checked one, which names the failure.
    fn tip(
        &self,
        point: usize,
        robot: usize,
        errors: &ErrorSets,
    ) -> Result<Point3<f64>, IdentifyError> {
        let e = &errors.robot[robot];
        let (setup, q) = if robot == 0 {
            (&self.cell.robot1, &self.q1[point])
        } else {
            (&self.cell.robot2, &self.q2[point])
        };
        if let Some(nominal) = self.nominal_tips.get(point).and_then(|t| t[robot]) {
            if errors.zero[robot] {
                return Ok(nominal);
            }
            if errors.valid[robot] {
                let tip = kinematics::true_base_from_tip_unchecked(
                    &setup.model,
                    e,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                );
                return Ok(Point3::from(tip.translation.vector));
            }
        }
        tip_b(setup, e, q).map_err(|e| model_error(point, e))
    }

    /// [`SessionModel::cached_errors`]' counterpart for Jacobian parameter lists: the split of
    /// `jacobian_params` by robot, through this thread's cache of the last split built.
    fn split(&self, jacobian_params: &[usize]) -> Rc<JacobianSplit> {
        let hit = LAST_SPLIT.with_borrow(|last| {
            last.as_ref()
                .filter(|c| c.model == self.id && c.params == jacobian_params)
                .map(Rc::clone)
        });
        if let Some(split) = hit {
            return split;
        }
        let mut columns = [Vec::new(), Vec::new()];
        let mut errors = [Vec::new(), Vec::new()];
        let mut valid = [true, true];
        for (c, &p) in jacobian_params.iter().enumerate() {
            let r = match self.candidates[p].robot() {
                Robot::One => 0,
                Robot::Two => 1,
            };
            columns[r].push(c);
            errors[r].push(self.candidates[p].param());
            valid[r] &= self.param_valid[p];
        }
        let split = Rc::new(JacobianSplit {
            model: self.id,
            params: jacobian_params.to_vec(),
            columns,
            errors,
            valid,
        });
        LAST_SPLIT.set(Some(Rc::clone(&split)));
        split
    }

    /// Whether robot `robot`'s evaluation at `point` with `errors` may skip the checks: its
    /// nominal tip (which checked the joint values) exists, its tip offset and gravity are valid,
    /// and so are its errors.
    fn checked_once(&self, point: usize, robot: usize, errors: &ErrorSets) -> bool {
        self.inputs_valid[robot]
            && errors.valid[robot]
            && self
                .nominal_tips
                .get(point)
                .is_some_and(|t| t[robot].is_some())
    }

    /// Robot `robot`'s setup and joint values at `point`.
    fn robot_at(&self, point: usize, robot: usize) -> (&CellRobot, &[f64]) {
        if robot == 0 {
            (&self.cell.robot1, &self.q1[point])
        } else {
            (&self.cell.robot2, &self.q2[point])
        }
    }

    /// Robot `robot`'s Jacobian columns of `split` at point `point` (see
    /// [`TipEval::jacobian`]): unchecked when [`SessionModel::checked_once`] and the split's
    /// parameters allow it, else `kinematics::tip_error_jacobian`.
    fn robot_jacobian(
        &self,
        point: usize,
        robot: usize,
        errors: &ErrorSets,
        split: &JacobianSplit,
    ) -> Result<Matrix3xX<f64>, IdentifyError> {
        let (setup, q) = self.robot_at(point, robot);
        let (e, eps) = (&errors.robot[robot], &split.errors[robot]);
        if split.valid[robot] && self.checked_once(point, robot, errors) {
            return Ok(kinematics::tip_error_jacobian_unchecked(
                &setup.model,
                e,
                q,
                &setup.flange_from_tip,
                &setup.g_base,
                eps,
            ));
        }
        kinematics::tip_error_jacobian(
            &setup.model,
            e,
            q,
            &setup.flange_from_tip,
            &setup.g_base,
            eps,
        )
        .map_err(|e| model_error(point, e))
    }

    /// The tips and Jacobian of [`TipModel::eval`] at `point`: robot 1's tip, robot 2's tip,
    /// then robot 1's and robot 2's Jacobian columns, as if computed in that order (the first
    /// failure in that order is returned). A robot with non-zero errors that may skip the checks
    /// gets its tip and columns from one walk of its chain
    /// (`kinematics::true_tip_with_error_jacobian_unchecked`, bit for bit the two calls).
    fn eval_at(
        &self,
        point: usize,
        errors: &ErrorSets,
        jacobian_params: &[usize],
    ) -> Result<TipEval, IdentifyError> {
        let mut jacobian = Matrix3xX::zeros(jacobian_params.len());
        if jacobian_params.is_empty() {
            return Ok(TipEval {
                p1_b1: self.tip(point, 0, errors)?,
                p2_b2: self.tip(point, 1, errors)?,
                jacobian,
            });
        }
        let split = self.split(jacobian_params);
        let mut tips = [Point3::origin(); 2];
        let mut done = [false; 2];
        for robot in 0..2 {
            let e = &errors.robot[robot];
            let cols = &split.columns[robot];
            if !cols.is_empty()
                && !errors.zero[robot]
                && split.valid[robot]
                && self.checked_once(point, robot, errors)
            {
                let (setup, q) = self.robot_at(point, robot);
                let (pose, j) = kinematics::true_tip_with_error_jacobian_unchecked(
                    &setup.model,
                    e,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                    &split.errors[robot],
                );
                tips[robot] = Point3::from(pose.translation.vector);
                for (k, &c) in cols.iter().enumerate() {
                    jacobian.set_column(c, &j.column(k));
                }
                done[robot] = true;
            } else {
                tips[robot] = self.tip(point, robot, errors)?;
            }
        }
        for (robot, &done) in done.iter().enumerate() {
            let cols = &split.columns[robot];
            if done || cols.is_empty() {
                continue;
            }
            let j = self.robot_jacobian(point, robot, errors, &split)?;
            for (k, &c) in cols.iter().enumerate() {
                jacobian.set_column(c, &j.column(k));
            }
        }
        Ok(TipEval {
            p1_b1: tips[0],
            p2_b2: tips[1],
            jacobian,
        })
    }

    /// The Jacobian columns of the catalogue parameters `jacobian_params` at point `point` with
    /// the two robots' error sets `errors` (see [`TipEval::jacobian`]).
    fn jacobian(
        &self,
        point: usize,
        errors: &ErrorSets,
        jacobian_params: &[usize],
    ) -> Result<Matrix3xX<f64>, IdentifyError> {
        let mut jacobian = Matrix3xX::zeros(jacobian_params.len());
        if jacobian_params.is_empty() {
            return Ok(jacobian);
        }
        let split = self.split(jacobian_params);
        for robot in 0..2 {
            let cols = &split.columns[robot];
            if cols.is_empty() {
                continue;
            }
            let j = self.robot_jacobian(point, robot, errors, &split)?;
            for (k, &c) in cols.iter().enumerate() {
                jacobian.set_column(c, &j.column(k));
            }
        }
        Ok(jacobian)
    }
}

/// A robot's true tip position in its nominal base frame (`kinematics::true_base_from_tip`), m.
fn tip_b(
    robot: &CellRobot,
    errors: &KinematicErrors,
    q: &[f64],
) -> Result<Point3<f64>, kinematics::KinematicsError> {
    kinematics::true_base_from_tip(
        &robot.model,
        errors,
        q,
        &robot.flange_from_tip,
        &robot.g_base,
    )
    .map(|x| Point3::from(x.translation.vector))
}

/// The identification's error for a failure of the kinematic model at `point`.
fn model_error(point: usize, e: kinematics::KinematicsError) -> IdentifyError {
    IdentifyError::Model {
        point,
        source: Box::new(e),
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
        let errors = self.cached_errors(params, values);
        self.eval_at(point, &errors, jacobian_params)
    }
    fn eval_jacobian(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<Matrix3xX<f64>, IdentifyError> {
        let errors = self.cached_errors(params, values);
        self.jacobian(point, &errors, jacobian_params)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::catalogue::catalogue;
    use sim_cell::{generate_session, trial_rng, Layout, SessionSpec};

    /// The caches change no bit: at every point, for parameter sets on neither, one or both
    /// robots (zero and non-zero values, the same values twice so that the per-thread cache is
    /// hit), `eval` gives exactly the tips of the checked `true_base_from_tip` and the columns
    /// of `tip_error_jacobian`, and `eval_jacobian` exactly `eval`'s Jacobian.
    #[test]
    fn eval_is_the_checked_fk_bit_for_bit() {
        let cell = Cell::default_floor_wall();
        let spec = SessionSpec::new(8, Layout::Random, 0.8);
        let session = generate_session(&cell, &spec, &mut trial_rng(3, 0)).expect("session");
        let q1: Vec<Vec<f64>> = session.points.iter().map(|p| p.q1.clone()).collect();
        let q2: Vec<Vec<f64>> = session.points.iter().map(|p| p.q2.clone()).collect();
        let cands = catalogue(
            cell.robot1.model.chain_joints().len(),
            cell.robot2.model.chain_joints().len(),
        );
        let model = SessionModel::new(&cell, &q1, &q2, &cands);
        let r1 = (0..cands.len()).find(|&c| cands[c].robot() == Robot::One);
        let r2 = (0..cands.len())
            .rev()
            .find(|&c| cands[c].robot() == Robot::Two);
        let (r1, r2) = (
            r1.expect("robot 1 candidate"),
            r2.expect("robot 2 candidate"),
        );
        let all: Vec<usize> = (0..cands.len()).collect();
        let cases: [(Vec<usize>, Vec<f64>); 5] = [
            (vec![], vec![]),
            (vec![r1], vec![0.0]),
            (vec![r1], vec![2e-3]),
            (vec![r2], vec![-1e-3]),
            (vec![r1, r2], vec![1e-3, 3e-4]),
        ];
        for (params, values) in &cases {
            let (e1, e2) = model.errors(params, values);
            for _repeat in 0..2 {
                for i in 0..q1.len() {
                    let got = model.eval(i, params, values, &all).expect("eval");
                    for (robot, errors, q, tip) in [
                        (&cell.robot1, &e1, &q1[i], got.p1_b1),
                        (&cell.robot2, &e2, &q2[i], got.p2_b2),
                    ] {
                        let want = kinematics::true_base_from_tip(
                            &robot.model,
                            errors,
                            q,
                            &robot.flange_from_tip,
                            &robot.g_base,
                        )
                        .expect("fk");
                        assert_eq!(tip.coords, want.translation.vector, "point {i}");
                    }
                    for (c, &p) in all.iter().enumerate() {
                        let (robot, errors, q) = match cands[p].robot() {
                            Robot::One => (&cell.robot1, &e1, &q1[i]),
                            Robot::Two => (&cell.robot2, &e2, &q2[i]),
                        };
                        let want = kinematics::tip_error_jacobian(
                            &robot.model,
                            errors,
                            q,
                            &robot.flange_from_tip,
                            &robot.g_base,
                            &[cands[p].param()],
                        )
                        .expect("jacobian");
                        assert_eq!(got.jacobian.column(c), want.column(0), "point {i}");
                    }
                    let jac = model
                        .eval_jacobian(i, params, values, &all)
                        .expect("jacobian");
                    assert_eq!(jac, got.jacobian);
                }
            }
        }
    }

    /// The per-thread cache is per model: two models whose catalogues give the same parameter
    /// index different meanings, evaluated in turn at the same values on the same thread, each
    /// give their own tips.
    #[test]
    fn the_error_set_cache_is_per_model() {
        let cell = Cell::default_floor_wall();
        let spec = SessionSpec::new(4, Layout::Random, 0.8);
        let session = generate_session(&cell, &spec, &mut trial_rng(5, 0)).expect("session");
        let q1: Vec<Vec<f64>> = session.points.iter().map(|p| p.q1.clone()).collect();
        let q2: Vec<Vec<f64>> = session.points.iter().map(|p| p.q2.clone()).collect();
        let cands = catalogue(
            cell.robot1.model.chain_joints().len(),
            cell.robot2.model.chain_joints().len(),
        );
        let reversed: Vec<Candidate> = cands.iter().rev().cloned().collect();
        let a = SessionModel::new(&cell, &q1, &q2, &cands);
        let b = SessionModel::new(&cell, &q1, &q2, &reversed);
        let (params, values) = ([0usize], [2e-3]);
        for _repeat in 0..2 {
            for model in [&a, &b] {
                let got = model.eval(1, &params, &values, &[]).expect("eval");
                let (e1, e2) = model.errors(&params, &values);
                let want = |robot: &CellRobot, e: &KinematicErrors, q: &[f64]| {
                    tip_b(robot, e, q).expect("fk")
                };
                assert_eq!(got.p1_b1, want(&cell.robot1, &e1, &q1[1]));
                assert_eq!(got.p2_b2, want(&cell.robot2, &e2, &q2[1]));
            }
        }
        // The two models do evaluate different parameters.
        let ta = a.eval(1, &params, &values, &[]).expect("eval");
        let tb = b.eval(1, &params, &values, &[]).expect("eval");
        assert!(ta.p1_b1 != tb.p1_b1 || ta.p2_b2 != tb.p2_b2);
    }

    /// A non-finite parameter value is still reported as the kinematic model's error (the
    /// cached error sets fail their check, so the checked FK runs), and the model evaluates
    /// normally afterwards.
    #[test]
    fn a_non_finite_value_is_still_an_error() {
        let cell = Cell::default_floor_wall();
        let spec = SessionSpec::new(6, Layout::Random, 0.8);
        let session = generate_session(&cell, &spec, &mut trial_rng(4, 0)).expect("session");
        let q1: Vec<Vec<f64>> = session.points.iter().map(|p| p.q1.clone()).collect();
        let q2: Vec<Vec<f64>> = session.points.iter().map(|p| p.q2.clone()).collect();
        let cands = catalogue(
            cell.robot1.model.chain_joints().len(),
            cell.robot2.model.chain_joints().len(),
        );
        let model = SessionModel::new(&cell, &q1, &q2, &cands);
        for _repeat in 0..2 {
            let err = model.eval(2, &[0], &[f64::NAN], &[]).unwrap_err();
            assert!(
                matches!(err, IdentifyError::Model { point: 2, .. }),
                "{err}"
            );
        }
        assert!(model.eval(2, &[0], &[1e-3], &[]).is_ok());
    }
}

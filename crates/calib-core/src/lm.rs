//! The one Levenberg–Marquardt solver of the crate, used by [`crate::identify`] and
//! [`crate::whole_cell`].
//!
//! The problem and the solver are apart (as in `rust-cv/levenberg-marquardt`): a problem
//! ([`LeastSquaresProblem`]) gives residuals `r(x)` and their Jacobian `J` at a point `x` of its own
//! manifold and moves a point by a step; the solver ([`minimize`]) owns the damping, the constants
//! and the reason it stopped ([`StopReason`]). It minimises `C(x) = ‖r(x)‖²`:
//!
//! 1. At the current point: `H = JᵀJ`, `g = Jᵀr`. If [`LmOptions::predicted_decrease_stop`] is on
//!    and the undamped Gauss–Newton step predicts a decrease `gᵀH⁻¹g` below
//!    `cost_tolerance·C`, stop: [`StopReason::Converged`].
//! 2. Damped step: `(H + λ·D)·δ = −g`, `D = diag(max(H_ii, DIAG_FLOOR_REL·max_k H_kk,
//!    COST_FLOOR))` (Marquardt's scaling, so the step does not depend on the columns' units; the
//!    floor damps a column the data do not see). When the Cholesky factorisation fails,
//!    [`SingularStep`] says what to do.
//! 3. Trial `x' = retract(x, δ)`: when `C(x') ≤ C(x)` the step is accepted (`λ ← max(λ/10,
//!    MIN_DAMPING)`); else `λ ← 10·λ` and back to 2, at most [`LmOptions::max_damping_tries`] times
//!    and while `λ ≤` [`LmOptions::max_damping`] (else: [`StopReason::NoDescent`]).
//! 4. After an accepted step: [`StopReason::Converged`] when the relative decrease is below
//!    `cost_tolerance`, [`StopReason::StepTooSmall`] when `‖δ‖` is below `step_tolerance`; else
//!    the next iteration, up to [`LmOptions::max_iterations`] ([`StopReason::IterationCap`]).
//!
//! A trial point the model cannot evaluate, or whose cost is not finite, ends the solve with
//! [`StopReason::NonFinite`] at the last finite point. Errors of the problem at the start or at
//! an accepted point are returned as errors.
//!
//! The two callers keep their own schedules ([`LmOptions::whole_cell`], [`LmOptions::identify`]),
//! so each fit gives the numbers it gave with its own loop.

use nalgebra::{DMatrix, DVector};

use crate::stop::StopReason;

/// Each damped diagonal entry is at least this fraction of the largest diagonal entry of `H`,
/// so that a column the data (nearly) do not see is damped too.
const DIAG_FLOOR_REL: f64 = 1e-12;
/// Smallest cost (and damped diagonal entry) the relative tests divide by: keeps them finite
/// when the cost is exactly 0 (noise-free data).
pub(crate) const COST_FLOOR: f64 = 1e-300;
/// Factor by which λ is raised after a rejected step and lowered after an accepted one.
const DAMPING_FACTOR: f64 = 10.0;
/// Smallest λ after an accepted step (the next iteration's first damping).
const MIN_DAMPING: f64 = 1e-12;
/// Singular values below this (absolute) are treated as zero by the pseudo-inverse step of
/// [`SingularStep::PseudoInverse`].
const PSEUDO_INVERSE_EPS: f64 = 1e-14;

/// What the solver does when the damped normal matrix `H + λ·D` has no Cholesky factor (it is
/// not numerically positive definite).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SingularStep {
    /// Raise λ by the damping factor (10) and try again, as for a rejected step.
    RaiseDamping,
    /// Take the pseudo-inverse step (SVD, singular values below 1e-14 dropped).
    PseudoInverse,
}

/// An invalid [`LmOptions`] setting: the option, its value and what it must be.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("Levenberg–Marquardt option `{option}` is {value}; it must be {requirement}")]
#[non_exhaustive]
pub struct LmOptionError {
    /// The option's name (the setter without `with_`).
    pub option: &'static str,
    /// The value given.
    pub value: String,
    /// What the value must be.
    pub requirement: String,
}

/// Settings of the Levenberg–Marquardt solver, checked when set (each `with_…` setter returns
/// an [`LmOptionError`] for a value out of range, so a value read back is always valid).
///
/// Two schedules: [`LmOptions::whole_cell`] (the default) and [`LmOptions::identify`]; each
/// setting's doc gives both defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmOptions {
    max_iterations: usize,
    cost_tolerance: f64,
    predicted_decrease_stop: bool,
    step_tolerance: f64,
    initial_damping: f64,
    max_damping: f64,
    max_damping_tries: usize,
    singular_step: SingularStep,
}

impl Default for LmOptions {
    /// [`LmOptions::whole_cell`].
    fn default() -> Self {
        Self::whole_cell()
    }
}

impl LmOptions {
    /// The whole-cell MAP fits' schedule ([`crate::whole_cell::SolveOptions`]): 100 iterations
    /// (a well-posed cell converges in 3–10), cost tolerance 1e-10 with the predicted-decrease
    /// stop, no step test, λ from 1e-3 up to 1e10 with no limit on the tries, and
    /// [`SingularStep::RaiseDamping`].
    pub const fn whole_cell() -> Self {
        Self {
            max_iterations: 100,
            cost_tolerance: 1e-10,
            predicted_decrease_stop: true,
            step_tolerance: 0.0,
            initial_damping: 1e-3,
            max_damping: 1e10,
            max_damping_tries: usize::MAX,
            singular_step: SingularStep::RaiseDamping,
        }
    }

    /// The identification fits' schedule ([`crate::identify::fit`]): 50 iterations, cost
    /// tolerance 1e-12 without the predicted-decrease stop, step tolerance 1e-15, λ from 1e-3 up
    /// to 1e12 in at most 30 tries per iteration, and [`SingularStep::PseudoInverse`].
    pub const fn identify() -> Self {
        Self {
            max_iterations: 50,
            cost_tolerance: 1e-12,
            predicted_decrease_stop: false,
            step_tolerance: 1e-15,
            initial_damping: 1e-3,
            max_damping: 1e12,
            max_damping_tries: 30,
            singular_step: SingularStep::PseudoInverse,
        }
    }

    /// Iteration cap (≥ 1; whole cell 100, identify 50): reaching it stops with
    /// [`StopReason::IterationCap`].
    pub fn max_iterations(&self) -> usize {
        self.max_iterations
    }

    /// Converged ([`StopReason::Converged`]) when an accepted step lowers the cost by less than
    /// this fraction (finite, > 0; whole cell 1e-10, identify 1e-12).
    pub fn cost_tolerance(&self) -> f64 {
        self.cost_tolerance
    }

    /// Whether the solver also stops as converged, before damping, when the undamped
    /// Gauss–Newton step predicts a decrease `gᵀH⁻¹g` below `cost_tolerance·C` (whole cell on,
    /// identify off).
    pub fn predicted_decrease_stop(&self) -> bool {
        self.predicted_decrease_stop
    }

    /// An accepted step shorter than this (Euclidean norm over the columns, in their units;
    /// finite, ≥ 0, 0 = never) stops with [`StopReason::StepTooSmall`] (whole cell 0,
    /// identify 1e-15).
    pub fn step_tolerance(&self) -> f64 {
        self.step_tolerance
    }

    /// Initial damping λ relative to `diag(H)` (finite, > 0, at most
    /// [`LmOptions::max_damping`]; both schedules 1e-3).
    pub fn initial_damping(&self) -> f64 {
        self.initial_damping
    }

    /// Largest damping λ tried (finite, ≥ [`LmOptions::initial_damping`]; whole cell 1e10,
    /// identify 1e12): when no λ up to it lowers the cost the solver stops with
    /// [`StopReason::NoDescent`].
    pub fn max_damping(&self) -> f64 {
        self.max_damping
    }

    /// Damped steps tried per iteration at most (≥ 1; whole cell unlimited, identify 30).
    pub fn max_damping_tries(&self) -> usize {
        self.max_damping_tries
    }

    /// What to do when the damped matrix has no Cholesky factor (whole cell
    /// [`SingularStep::RaiseDamping`], identify [`SingularStep::PseudoInverse`]).
    pub fn singular_step(&self) -> SingularStep {
        self.singular_step
    }

    /// Sets [`LmOptions::max_iterations`]. Error: 0.
    pub fn with_max_iterations(self, max_iterations: usize) -> Result<Self, LmOptionError> {
        if max_iterations == 0 {
            return Err(bad("max_iterations", max_iterations, "at least 1"));
        }
        Ok(Self {
            max_iterations,
            ..self
        })
    }

    /// Sets [`LmOptions::cost_tolerance`]. Error: not finite or ≤ 0.
    pub fn with_cost_tolerance(self, cost_tolerance: f64) -> Result<Self, LmOptionError> {
        if !(cost_tolerance.is_finite() && cost_tolerance > 0.0) {
            return Err(bad("cost_tolerance", cost_tolerance, "finite and > 0"));
        }
        Ok(Self {
            cost_tolerance,
            ..self
        })
    }

    /// Sets [`LmOptions::predicted_decrease_stop`].
    pub fn with_predicted_decrease_stop(self, predicted_decrease_stop: bool) -> Self {
        Self {
            predicted_decrease_stop,
            ..self
        }
    }

    /// Sets [`LmOptions::step_tolerance`]. Error: not finite or < 0.
    pub fn with_step_tolerance(self, step_tolerance: f64) -> Result<Self, LmOptionError> {
        if !(step_tolerance.is_finite() && step_tolerance >= 0.0) {
            return Err(bad("step_tolerance", step_tolerance, "finite and ≥ 0"));
        }
        Ok(Self {
            step_tolerance,
            ..self
        })
    }

    /// Sets [`LmOptions::initial_damping`]. Error: not finite, ≤ 0, or above
    /// [`LmOptions::max_damping`].
    pub fn with_initial_damping(self, initial_damping: f64) -> Result<Self, LmOptionError> {
        if !(initial_damping.is_finite() && initial_damping > 0.0) {
            return Err(bad("initial_damping", initial_damping, "finite and > 0"));
        }
        if initial_damping > self.max_damping {
            return Err(bad(
                "initial_damping",
                initial_damping,
                format!("at most max_damping ({:e})", self.max_damping),
            ));
        }
        Ok(Self {
            initial_damping,
            ..self
        })
    }

    /// Sets [`LmOptions::max_damping`]. Error: not finite, or below
    /// [`LmOptions::initial_damping`].
    pub fn with_max_damping(self, max_damping: f64) -> Result<Self, LmOptionError> {
        if !(max_damping.is_finite() && max_damping >= self.initial_damping) {
            return Err(bad(
                "max_damping",
                max_damping,
                format!(
                    "finite and at least initial_damping ({:e})",
                    self.initial_damping
                ),
            ));
        }
        Ok(Self {
            max_damping,
            ..self
        })
    }

    /// Sets [`LmOptions::max_damping_tries`]. Error: 0.
    pub fn with_max_damping_tries(self, max_damping_tries: usize) -> Result<Self, LmOptionError> {
        if max_damping_tries == 0 {
            return Err(bad("max_damping_tries", max_damping_tries, "at least 1"));
        }
        Ok(Self {
            max_damping_tries,
            ..self
        })
    }

    /// Sets [`LmOptions::singular_step`].
    pub fn with_singular_step(self, singular_step: SingularStep) -> Self {
        Self {
            singular_step,
            ..self
        }
    }
}

fn bad(
    option: &'static str,
    value: impl std::fmt::Display,
    requirement: impl Into<String>,
) -> LmOptionError {
    LmOptionError {
        option,
        value: value.to_string(),
        requirement: requirement.into(),
    }
}

/// Residuals and Jacobian at a point, as the solver reads them (the problem's system may hold
/// more: unweighted residuals, row offsets, …).
pub(crate) trait Linearised {
    /// The (whitened) residuals `r`; the cost is `‖r‖²`.
    fn residuals(&self) -> &DVector<f64>;
    /// `∂r/∂δ`, one column per step entry (empty when only the residuals were evaluated).
    fn jacobian(&self) -> &DMatrix<f64>;
}

/// A nonlinear least-squares problem `min_x ‖r(x)‖²` over a point `x` of the problem's own
/// manifold (the solver only ever sees steps `δ`, one entry per Jacobian column).
pub(crate) trait LeastSquaresProblem {
    /// The iterate (e.g. a placement and parameter values).
    type Point;
    /// What evaluating or linearising at a point gives.
    type System: Linearised;
    /// The problem's error (bad input, a model failure).
    type Error;

    /// Residuals and Jacobian at the starting point.
    fn linearise(&self, at: &Self::Point) -> Result<Self::System, Self::Error>;

    /// Residuals only (no Jacobian) at a trial point; `Ok(None)` when the model cannot be
    /// evaluated there in a way that means the step left its domain (non-finite values).
    fn evaluate(&self, at: &Self::Point) -> Result<Option<Self::System>, Self::Error>;

    /// Residuals and Jacobian at an accepted trial point `at`, whose residuals `evaluated` came
    /// from [`LeastSquaresProblem::evaluate`] (a problem may reuse them).
    fn relinearise(
        &self,
        at: &Self::Point,
        evaluated: Self::System,
    ) -> Result<Self::System, Self::Error>;

    /// `at` moved by `step` on the problem's manifold.
    fn retract(&self, at: &Self::Point, step: &DVector<f64>) -> Self::Point;
}

/// Where the solver stopped: `X` the problem's point, `S` its system.
pub(crate) struct Minimum<X, S> {
    /// The last accepted point (the start if no step was accepted).
    pub point: X,
    /// Its residuals and Jacobian.
    pub system: S,
    /// Its cost `‖r‖²` (the value compared when its step was accepted).
    pub cost: f64,
    /// Iterations used (an iteration ends with an accepted step or a stop).
    pub iterations: usize,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// `JᵀJ` of `system` when the last iteration formed it (a stop on the predicted decrease),
    /// so that the caller need not form it again.
    pub information: Option<DMatrix<f64>>,
}

/// Minimises `‖r(x)‖²` from `start` by Levenberg–Marquardt (the steps in the module doc).
/// Errors: the problem's, at the start or at an accepted point.
pub(crate) fn minimize<P: LeastSquaresProblem>(
    problem: &P,
    start: P::Point,
    options: &LmOptions,
) -> Result<Minimum<P::Point, P::System>, P::Error> {
    let mut point = start;
    let mut system = problem.linearise(&point)?;
    let mut cost = system.residuals().norm_squared();
    let mut lambda = options.initial_damping;
    let mut iterations = 0;
    let mut stopped = StopReason::IterationCap;
    let mut information = None;
    while iterations < options.max_iterations {
        iterations += 1;
        let jt = system.jacobian().transpose();
        let h = &jt * system.jacobian();
        let g = &jt * system.residuals();
        if options.predicted_decrease_stop {
            // Predicted decrease of the undamped Gauss–Newton step.
            let predicted = match h.clone().cholesky() {
                Some(c) => g.dot(&c.solve(&g)),
                None => f64::INFINITY,
            };
            if predicted.is_finite() && predicted < options.cost_tolerance * cost.max(COST_FLOOR) {
                stopped = StopReason::Converged;
                information = Some(h);
                break;
            }
        }
        let dmax = (0..h.nrows()).map(|i| h[(i, i)]).fold(0.0, f64::max);
        let floor = (DIAG_FLOOR_REL * dmax).max(COST_FLOOR);
        let mut accepted = false;
        let mut non_finite = false;
        let mut tries = 0;
        while tries < options.max_damping_tries && lambda <= options.max_damping {
            tries += 1;
            let mut a = h.clone();
            for i in 0..a.nrows() {
                a[(i, i)] += lambda * h[(i, i)].max(floor);
            }
            let step = match a.clone().cholesky() {
                Some(c) => -c.solve(&g),
                None => match options.singular_step {
                    SingularStep::RaiseDamping => {
                        lambda *= DAMPING_FACTOR;
                        continue;
                    }
                    SingularStep::PseudoInverse => {
                        match a.svd(true, true).solve(&(-&g), PSEUDO_INVERSE_EPS) {
                            Ok(s) => s,
                            Err(_) => break,
                        }
                    }
                },
            };
            let trial_point = problem.retract(&point, &step);
            let Some(trial) = problem.evaluate(&trial_point)? else {
                non_finite = true;
                break;
            };
            let trial_cost = trial.residuals().norm_squared();
            if !trial_cost.is_finite() {
                non_finite = true;
                break;
            }
            if trial_cost <= cost {
                let rel = (cost - trial_cost) / cost.max(COST_FLOOR);
                system = problem.relinearise(&trial_point, trial)?;
                point = trial_point;
                cost = trial_cost;
                lambda = (lambda / DAMPING_FACTOR).max(MIN_DAMPING);
                accepted = true;
                if rel < options.cost_tolerance {
                    stopped = StopReason::Converged;
                } else if step.norm() < options.step_tolerance {
                    stopped = StopReason::StepTooSmall;
                }
                break;
            }
            lambda *= DAMPING_FACTOR;
        }
        if non_finite {
            stopped = StopReason::NonFinite;
            break;
        }
        if !accepted {
            stopped = StopReason::NoDescent;
            break;
        }
        if stopped != StopReason::IterationCap {
            break;
        }
    }
    Ok(Minimum {
        point,
        system,
        cost,
        iterations,
        stopped,
        information,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    /// Residuals and Jacobian of the toy problem.
    struct ToySystem {
        r: DVector<f64>,
        j: DMatrix<f64>,
    }

    impl Linearised for ToySystem {
        fn residuals(&self) -> &DVector<f64> {
            &self.r
        }
        fn jacobian(&self) -> &DMatrix<f64> {
            &self.j
        }
    }

    /// How the toy problem misbehaves.
    #[derive(Clone, Copy, PartialEq)]
    enum Fault {
        None,
        /// The Jacobian has the wrong sign: every damped step goes uphill.
        WrongSign,
        /// No trial point can be evaluated (`evaluate` gives `None`).
        Unevaluable,
        /// Every trial point's residuals are infinite.
        InfiniteCost,
    }

    /// `r_i = a·exp(−b·t_i) − y_i` at `t_i = i/2`, `i = 0..20`, with `y` from `a = 2`, `b = 0.3`
    /// plus a fixed ±0.01 alternation (so the minimum's cost is not 0); the point is `(a, b)`.
    struct Toy {
        fault: Fault,
        evaluations: Cell<usize>,
    }

    impl Toy {
        fn new(fault: Fault) -> Self {
            Self {
                fault,
                evaluations: Cell::new(0),
            }
        }

        fn system(&self, x: &DVector<f64>, jacobian: bool) -> ToySystem {
            let n = 20;
            let sign = if self.fault == Fault::WrongSign {
                -1.0
            } else {
                1.0
            };
            let mut r = DVector::zeros(n);
            let mut j = DMatrix::zeros(if jacobian { n } else { 0 }, 2);
            for i in 0..n {
                let t = i as f64 / 2.0;
                let y = 2.0 * (-0.3 * t).exp() + if i % 2 == 0 { 0.01 } else { -0.01 };
                let e = (-x[1] * t).exp();
                r[i] = x[0] * e - y;
                if jacobian {
                    j[(i, 0)] = sign * e;
                    j[(i, 1)] = sign * (-x[0] * t * e);
                }
            }
            ToySystem { r, j }
        }
    }

    impl LeastSquaresProblem for Toy {
        type Point = DVector<f64>;
        type System = ToySystem;
        type Error = String;

        fn linearise(&self, at: &DVector<f64>) -> Result<ToySystem, String> {
            Ok(self.system(at, true))
        }

        fn evaluate(&self, at: &DVector<f64>) -> Result<Option<ToySystem>, String> {
            self.evaluations.set(self.evaluations.get() + 1);
            Ok(match self.fault {
                Fault::Unevaluable => None,
                Fault::InfiniteCost => Some(ToySystem {
                    r: DVector::from_element(20, f64::INFINITY),
                    j: DMatrix::zeros(0, 2),
                }),
                _ => Some(self.system(at, false)),
            })
        }

        fn relinearise(&self, at: &DVector<f64>, _: ToySystem) -> Result<ToySystem, String> {
            self.linearise(at)
        }

        fn retract(&self, at: &DVector<f64>, step: &DVector<f64>) -> DVector<f64> {
            at + step
        }
    }

    fn start() -> DVector<f64> {
        DVector::from_vec(vec![1.0, 0.1])
    }

    /// Both schedules reach the toy's minimum and say so: the gradient `Jᵀr` there is below
    /// 1e-6 of its norm at the start (whole cell: a predicted decrease below 1e-10 of the cost
    /// leaves a gradient ~1e-8; measured 1.7e-8 against 6.8 at the start).
    #[test]
    fn both_schedules_converge_on_the_toy_problem() {
        let gradient = |s: &ToySystem| (s.j.transpose() * &s.r).norm();
        let g0 = gradient(&Toy::new(Fault::None).system(&start(), true));
        for options in [LmOptions::whole_cell(), LmOptions::identify()] {
            let toy = Toy::new(Fault::None);
            let min = minimize(&toy, start(), &options).unwrap();
            assert_eq!(min.stopped, StopReason::Converged, "{options:?}");
            let g = gradient(&min.system);
            assert!(
                g < 1e-6 * g0,
                "gradient {g} vs {g0} at the start ({options:?})"
            );
            assert!((min.point[0] - 2.0).abs() < 0.05 && (min.point[1] - 0.3).abs() < 0.05);
            assert_eq!(min.cost, min.system.r.norm_squared());
        }
    }

    #[test]
    fn the_iteration_cap_is_a_stop_reason() {
        let toy = Toy::new(Fault::None);
        let options = LmOptions::whole_cell().with_max_iterations(1).unwrap();
        let min = minimize(&toy, start(), &options).unwrap();
        assert_eq!((min.stopped, min.iterations), (StopReason::IterationCap, 1));
        assert!(min.cost < toy.system(&start(), false).r.norm_squared());
    }

    /// A Jacobian of the wrong sign sends every damped step uphill: the solver gives up at its
    /// largest damping with [`StopReason::NoDescent`] at the start (what `calibrate --cell`
    /// printed as `"step_too_small"` before the two loops became one; it prints `"no_descent"`).
    #[test]
    fn no_damped_step_downhill_is_no_descent() {
        for options in [LmOptions::whole_cell(), LmOptions::identify()] {
            let toy = Toy::new(Fault::WrongSign);
            let min = minimize(&toy, start(), &options).unwrap();
            assert_eq!(min.stopped, StopReason::NoDescent);
            assert_eq!(min.stopped.name(), "no_descent");
            assert_eq!((min.iterations, min.point.clone()), (1, start()));
            // λ went from 1e-3 past the cap, ×10 per try.
            let tries = toy.evaluations.get();
            let expected = (options.max_damping() / options.initial_damping()).log10();
            assert!((tries as f64 - expected).abs() <= 1.0, "{tries} tries");
        }
    }

    /// A trial the model cannot evaluate, or whose cost is infinite, ends the solve with
    /// [`StopReason::NonFinite`] at the last finite point (here the start).
    #[test]
    fn a_step_out_of_the_domain_is_non_finite() {
        for fault in [Fault::Unevaluable, Fault::InfiniteCost] {
            for options in [LmOptions::whole_cell(), LmOptions::identify()] {
                let toy = Toy::new(fault);
                let min = minimize(&toy, start(), &options).unwrap();
                assert_eq!(min.stopped, StopReason::NonFinite);
                assert_eq!(min.point, start());
                assert_eq!(toy.evaluations.get(), 1, "the first bad trial stops it");
            }
        }
    }

    /// With a step tolerance above the first step's length, the first accepted step stops the
    /// solve with [`StopReason::StepTooSmall`] (the cost test has not passed: the step lowered
    /// the cost by far more than the tolerance).
    #[test]
    fn a_short_accepted_step_is_step_too_small() {
        let toy = Toy::new(Fault::None);
        let options = LmOptions::identify().with_step_tolerance(1e3).unwrap();
        let min = minimize(&toy, start(), &options).unwrap();
        assert_eq!((min.stopped, min.iterations), (StopReason::StepTooSmall, 1));
        assert!(min.cost < 0.5 * toy.system(&start(), false).r.norm_squared());
    }

    /// At the minimum, the predicted-decrease stop ends the solve before any trial step; without
    /// it the solver tries at least one.
    #[test]
    fn the_predicted_decrease_stop_needs_no_trial_at_a_minimum() {
        let toy = Toy::new(Fault::None);
        let at_min = minimize(&toy, start(), &LmOptions::whole_cell())
            .unwrap()
            .point;
        let toy = Toy::new(Fault::None);
        let min = minimize(&toy, at_min.clone(), &LmOptions::whole_cell()).unwrap();
        assert_eq!((min.stopped, min.iterations), (StopReason::Converged, 1));
        assert_eq!(toy.evaluations.get(), 0);
        let toy = Toy::new(Fault::None);
        let off = LmOptions::whole_cell().with_predicted_decrease_stop(false);
        let min = minimize(&toy, at_min, &off).unwrap();
        assert!(min.stopped.converged(), "{:?}", min.stopped);
        assert!(toy.evaluations.get() >= 1);
    }

    /// Each setter refuses what its doc refuses, naming the option, and keeps the rest.
    #[test]
    fn options_are_checked_when_set() {
        let o = LmOptions::default();
        assert_eq!(o, LmOptions::whole_cell());
        let refused = [
            o.with_max_iterations(0).unwrap_err(),
            o.with_cost_tolerance(0.0).unwrap_err(),
            o.with_cost_tolerance(f64::NAN).unwrap_err(),
            o.with_step_tolerance(-1e-9).unwrap_err(),
            o.with_step_tolerance(f64::INFINITY).unwrap_err(),
            o.with_initial_damping(0.0).unwrap_err(),
            o.with_initial_damping(2e10).unwrap_err(),
            o.with_max_damping(1e-4).unwrap_err(),
            o.with_max_damping(f64::INFINITY).unwrap_err(),
            o.with_max_damping_tries(0).unwrap_err(),
        ];
        let names: Vec<&str> = refused.iter().map(|e| e.option).collect();
        assert_eq!(
            names,
            [
                "max_iterations",
                "cost_tolerance",
                "cost_tolerance",
                "step_tolerance",
                "step_tolerance",
                "initial_damping",
                "initial_damping",
                "max_damping",
                "max_damping",
                "max_damping_tries"
            ]
        );
        let msg = o.with_initial_damping(2e10).unwrap_err().to_string();
        assert!(msg.contains("initial_damping") && msg.contains("at most max_damping (1e10)"));
        let set = o
            .with_max_iterations(7)
            .and_then(|o| o.with_cost_tolerance(1e-6))
            .and_then(|o| o.with_step_tolerance(0.0))
            .and_then(|o| o.with_max_damping(1e12))
            .and_then(|o| o.with_initial_damping(1e11))
            .and_then(|o| o.with_max_damping_tries(3))
            .unwrap()
            .with_singular_step(SingularStep::PseudoInverse);
        assert_eq!(
            (
                set.max_iterations(),
                set.cost_tolerance(),
                set.step_tolerance(),
                set.initial_damping(),
                set.max_damping(),
                set.max_damping_tries(),
                set.singular_step(),
                set.predicted_decrease_stop()
            ),
            (
                7,
                1e-6,
                0.0,
                1e11,
                1e12,
                3,
                SingularStep::PseudoInverse,
                true
            )
        );
    }
}

//! Kinematic identification from handclasp data: fit `b1_from_b2` jointly with a chosen set of
//! kinematic error parameters, and decide which parameters the data actually support.
//!
//! # Measurement model
//! For handclasp `i` the two controllers report joint vectors `q1_i`, `q2_i`. With `f_r(q; θ_r)` the
//! TRUE tip position of robot `r` in its NOMINAL base frame (metres), the model is
//!
//! `f1(q1_i; θ1) = b1_from_b2 · f2(q2_i; θ2) + ε_i`,  `ε_i ~ N(0, σ²·I₃)`,
//!
//! so each point gives the 3 residuals `r_i = f1 − b1_from_b2·f2` (m). The tip functions and their
//! parameter Jacobians come from a [`TipModel`] (in handclasp, `kinematics::true_base_from_tip` and
//! `kinematics::tip_error_jacobian`, wrapped by the `diagnose` crate's `session_model`); this module does no file I/O
//! and knows nothing of units beyond "the model's own parameter units".
//!
//! # Maths
//! - **Fit** ([`fit`]): Levenberg–Marquardt on `Σ‖r_i‖²` with analytic Jacobians. `b1_from_b2` is
//!   perturbed on the manifold, `X ← Translation(ρ)·Rotation(φ)·X`, so `∂r/∂ρ = −I₃` and
//!   `∂r/∂φ = [X·f2]ₓ`; a robot-1 parameter's column is `+∂f1/∂θ`, a robot-2 one `−R_X·∂f2/∂θ`.
//!   The covariance is `σ̂²·(JᵀJ)⁻¹` with `σ̂² = RSS/(3n − 6 − k)`.
//! - **Weights** ([`TipModel::weight`]): each point's residual can be whitened by `W_i` (in
//!   handclasp, `σ̄·Σ_i^{-1/2}` from the cell's stated noise: anisotropic alignment, repeatability,
//!   encoder resolution through the joint Jacobians). RSS, σ̂, the F tests and the covariance use
//!   the whitened residuals, so the tests keep their size under anisotropic noise whatever its
//!   overall scale (σ̂ estimates it); residuals and RMS figures stay unweighted, in metres.
//! - **Identifiability** ([`analyze_identifiability`]): each candidate's Jacobian column is projected
//!   out of the span of the 6 `b1_from_b2` columns and of the already fitted parameters. A column
//!   that is zero to begin with has no effect on the tips; one whose projection is (nearly) zero is
//!   confounded with the base frame (or with the fitted parameters); candidates whose projected
//!   columns are (nearly) parallel are mutually confounded and reported as a group.
//! - **Selection** ([`forward_select`]): forward selection. Each step screens every identifiable
//!   candidate with a score test (`ΔRSS_j ≈ (p_jᵀr)²/‖p_j‖²`, `p_j` the projected column), refits the
//!   best with LM, and accepts it only if (a) the F test `ΔRSS/(RSS_new/dof)` against `F(1, dof)` is
//!   significant at `α/m` (Bonferroni over the `m` candidates screened, which bounds the chance of a
//!   false alarm at each step by `α` whatever the candidate picked), (b) the K-fold held-out residual
//!   RMS decreases (each fold's training fit one Gauss–Newton step from the fit on every point,
//!   [`kfold_rms_of_fit`]; [`SelectionOptions::refit_every_fold`] refits the folds by LM), and
//!   (c) BIC decreases. It stops at the first step that fails. After each
//!   accepted step every selected parameter is re-screened against the others and swapped for a
//!   better one when a refit lowers the RSS (greedy steps can pick a proxy of a true effect), and
//!   a backward elimination drops any parameter whose F test no longer passes at `α/m₀`.
//!   The selection stops ([`SelectionStop`]) at a rejected step, at `max_effects`, at
//!   `max_steps` forward steps, or when an accepted step leads back to a selected set already
//!   visited (a candidate accepted forward and dropped backward would otherwise be re-accepted
//!   forever), so its number of LM fits is bounded.
//! - **Which one** ([`Selection::groups`]): for each selected parameter, the candidates the data
//!   cannot tell apart from it: its parallel group plus the best-scoring replacements
//!   ([`RESCREEN_REFITS`] refits with the others kept) whose RSS is within `χ²₁(0.95)·σ̂²` of its
//!   own (a likelihood-ratio confidence set for "which one").
//! - **Search**: each forward step refits the [`FORWARD_REFITS`] best-scoring candidates and keeps
//!   the one with the smallest RSS (the score is only a one-step linear prediction). A refit
//!   whose outcome the score already decides is skipped ([`refit_is_needed`]: the score predicts
//!   the refit's RSS within [`PREDICTION_SLACK_SIGMA2`]`·σ̂²` plus [`PREDICTION_SLACK_REL`] of the
//!   predicted change), in the forward step, the re-screen and the backward elimination (Wald
//!   predictions of the partial F tests); [`SelectionOptions::refit_every_ranked`] refits them
//!   all, with the same selection whenever the bound holds.
//! - **Detectability** ([`min_detectable`]): the smallest |value| of each candidate the design
//!   detects with 80 % power, `(z_{1−α/2m} + z_{0.8})·σ/‖p_j‖`.
//! - **Intervals**: `θ̂ ± t_{0.975, dof}·se`, `se` from the covariance.
//!
//! # Threads
//! The tip model is evaluated at the points in parallel, and the independent fits of a step (the
//! folds of [`kfold_rms`], the refits of the best-scoring candidates, the re-screen's
//! replacements, the backward elimination's and [`partial_f_tests`]' reduced fits) run in
//! parallel, all on rayon's current pool. Every result is assembled and every choice made in the
//! sequential order, so a selection is bit-identical whatever the thread count.

// File order (each file uses only files before it): model, fit, identifiability, selection;
// placement uses fit.
mod fit;
mod identifiability;
mod model;
mod placement;
mod selection;
#[cfg(test)]
mod tests;

pub use fit::*;
pub use identifiability::*;
pub use model::*;
pub use placement::*;
pub use selection::*;

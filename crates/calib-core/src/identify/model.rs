//! The identification's data model: the tip model that evaluates both tips and their parameter
//! Jacobians (and says which [`Robot`] a parameter belongs to), and the errors.

use crate::Robot;
use nalgebra::{Matrix3, Matrix3xX, Point3};

/// Errors of the identification. Non-convergence is not an error (see [`IdentFit::stopped`](super::IdentFit::stopped)).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// Too few handclasp points for the number of unknowns.
    #[error(
        "too few handclasp points: {n} given, but fitting b1_from_b2 (6 unknowns) plus {params} \
         error parameter(s) with enough redundancy to test anything needs at least {needed} points \
         (3 residuals per point); record more handclasp points"
    )]
    TooFewPoints {
        /// Points given.
        n: usize,
        /// Error parameters asked for.
        params: usize,
        /// Points needed.
        needed: usize,
    },
    /// The tip model failed at a point (the model's own error is the source).
    #[error("tip model failed at handclasp point {point} (0-based)")]
    Model {
        /// 0-based point index.
        point: usize,
        /// The model's error.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The tip model returned a Jacobian with the wrong number of columns.
    #[error(
        "tip model returned a Jacobian with {columns} columns at handclasp point {point} (0-based), \
         but {requested} parameters were requested: the model must return one column per requested \
         parameter"
    )]
    JacobianShape {
        /// 0-based point index.
        point: usize,
        /// Columns returned.
        columns: usize,
        /// Parameters requested.
        requested: usize,
    },
    /// A parameter index outside the model's catalogue.
    #[error("parameter index {index} is out of range: the model has {len} parameters")]
    BadParam {
        /// The index given.
        index: usize,
        /// Catalogue size.
        len: usize,
    },
    /// Non-finite values (NaN/inf) from the model.
    #[error("non-finite tip position or Jacobian at handclasp point {point} (0-based): check the input for NaN or huge values")]
    NonFinite {
        /// 0-based point index.
        point: usize,
    },
    /// Invalid options.
    #[error("invalid identification option `{field}`: {message}")]
    BadOption {
        /// The field.
        field: &'static str,
        /// What is wrong and the valid range.
        message: String,
    },
}

/// Tip positions of both robots at one handclasp, and their Jacobian with respect to parameters.
#[derive(Debug, Clone)]
pub struct TipEval {
    /// Robot 1's true tip in its nominal base frame `b1`, m.
    pub p1_b1: Point3<f64>,
    /// Robot 2's true tip in its nominal base frame `b2`, m.
    pub p2_b2: Point3<f64>,
    /// One column per requested Jacobian parameter: `∂p_r/∂θ_j` for the robot `r` that parameter `j`
    /// belongs to, in that robot's base axes (m per parameter unit).
    pub jacobian: Matrix3xX<f64>,
}

/// A handclasp data set with a catalogue of candidate error parameters, indexed `0..n_params()`.
/// The fits call [`TipModel::eval`] for many points at once from rayon's threads (hence `Sync`);
/// each call must give the same result whatever thread makes it.
pub trait TipModel: Sync {
    /// Number of handclasp points.
    fn n_points(&self) -> usize;
    /// Number of parameters in the catalogue.
    fn n_params(&self) -> usize;
    /// The robot parameter `j` belongs to.
    fn param_robot(&self, j: usize) -> Robot;
    /// Typical magnitude of parameter `j` in its own unit (e.g. 1e-3 rad, 1e-3 m): a parameter
    /// whose typical magnitude moves the tips by less than a nanometre (RMS) counts as having no
    /// effect. Default 1.
    fn param_scale(&self, _j: usize) -> f64 {
        1.0
    }
    /// Whitening matrix `W_i` of point `i`'s residual (default identity): the fit minimises
    /// `Σ‖W_i·r_i‖²`. For a noise covariance `Σ_i` use `W_i = σ̄·Σ_i^{-1/2}` (σ̄ a typical σ, so
    /// that whitened residuals stay in metres); then the F tests hold their size under
    /// anisotropic noise.
    fn weight(&self, _point: usize) -> Matrix3<f64> {
        Matrix3::identity()
    }
    /// Prior weight of parameter `j` (default 1), used only to name one member of a group of
    /// candidates the data cannot tell apart (e.g. `1/size` of its family, so that each family
    /// is a priori equally likely).
    fn param_prior(&self, _j: usize) -> f64 {
        1.0
    }
    /// Evaluates point `point` with parameters `params[k] = values[k]` (all others zero), and the
    /// Jacobian columns of the parameters `jacobian_params` (empty: no Jacobian needed).
    fn eval(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<TipEval, IdentifyError>;
    /// The Jacobian columns of `jacobian_params` at point `point` with parameters
    /// `params[k] = values[k]`: the `jacobian` of [`TipModel::eval`] with the same arguments, bit
    /// for bit. The fit calls it where it already has the tips at that state; a model can
    /// override it to skip computing them again. Default: `eval(…).jacobian`.
    fn eval_jacobian(
        &self,
        point: usize,
        params: &[usize],
        values: &[f64],
        jacobian_params: &[usize],
    ) -> Result<Matrix3xX<f64>, IdentifyError> {
        self.eval(point, params, values, jacobian_params)
            .map(|e| e.jacobian)
    }
}

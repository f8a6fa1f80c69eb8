//! The registration methods ([`Method`]), their result ([`Fit`]) and its covariance ([`Uncertainty`]).

use crate::points::PointPairs;
use nalgebra::{Isometry3, Matrix3, Matrix6, Point3, Vector3};
use serde::Serialize;

/// A calibration method (see the module table). Serialises as its [`Method::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The 4-point generic method with the eq (12) translation.
    Generic,
    /// The 4-point generic method with the affine H's own translation.
    GenericAffine,
    /// The paper's constrained projection for the given mounts, then eq (12).
    Paper,
    /// Rigid least squares over all rotations.
    Lsq,
    /// Installation-constrained least squares.
    Constrained,
}

impl Method {
    /// All methods, in display order.
    pub const ALL: [Method; 5] = [
        Method::Generic,
        Method::GenericAffine,
        Method::Paper,
        Method::Lsq,
        Method::Constrained,
    ];

    /// The method's name: "generic", "generic-affine", "paper", "lsq" or "constrained".
    pub fn name(self) -> &'static str {
        match self {
            Method::Generic => "generic",
            Method::GenericAffine => "generic-affine",
            Method::Paper => "paper",
            Method::Lsq => "lsq",
            Method::Constrained => "constrained",
        }
    }

    /// Parses a method name as given by [`Method::name`].
    pub fn from_name(text: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == text.trim())
    }

    /// Whether the method uses the installation ([`crate::MountPair`]): `paper` and `constrained`
    /// do; `generic`, `generic-affine` and `lsq` ignore it (run them with
    /// [`crate::fit_unconstrained`]).
    pub fn uses_mounts(self) -> bool {
        matches!(self, Method::Paper | Method::Constrained)
    }

    /// Minimum number of points the method needs.
    pub fn min_points(self) -> usize {
        match self {
            Method::Generic | Method::GenericAffine | Method::Paper => 4,
            Method::Lsq | Method::Constrained => 3,
        }
    }
}

/// Covariance of a fitted `b1_from_b2` and the errors it predicts.
///
/// Perturbation convention (as in `calib_core::identify`): `X = Translation(δt)·Rotation(δθ)·X̂`,
/// with `δθ` (rad) and `δt` (m) in b1 axes; [`Uncertainty::covariance`] is ordered `[δθ; δt]`.
/// It is `σ̂²·G·(JᵀJ)⁻¹·Gᵀ` with `σ̂² = RSS/(3n − k)` (k free parameters, G mapping them to `[δθ; δt]`),
/// i.e. it assumes isotropic, independent point noise and a correct mount model.
///
/// Serialises (serde) with SI units as named on the fields; `covariance` as nalgebra writes a
/// matrix: its 36 entries in column-major order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Uncertainty {
    /// 6×6 covariance of `[δθ (rad); δt (m)]`.
    pub covariance: Matrix6<f64>,
    /// Per-coordinate point noise σ estimated from the residuals, m.
    pub sigma_point_m: f64,
    /// Degrees of freedom of the residual (3n − k).
    pub dof: usize,
    /// Predicted 1σ of e_tran (eq 34): the largest per-axis standard deviation of T, m.
    pub e_tran_1sigma_m: f64,
    /// Predicted 1σ rotation error: square root of the largest eigenvalue of the δθ covariance, rad.
    pub e_rot_1sigma_rad: f64,
}

impl Uncertainty {
    /// Covariance (m²) of the mapped point `b1_from_b2 · p_b2` for a work point `p_b2` (m, b2 frame):
    /// the target registration error.
    pub fn covariance_at(&self, b1_from_b2: &Isometry3<f64>, p_b2: &Point3<f64>) -> Matrix3<f64> {
        let y = b1_from_b2 * p_b2;
        let mut j = nalgebra::Matrix3x6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-y.coords.cross_matrix()));
        j.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        j * self.covariance * j.transpose()
    }

    /// Predicted RMS position error (m) of a work point `p_b2` mapped into b1 (target registration error):
    /// `√tr(covariance_at)`.
    pub fn tre_rms_m(&self, b1_from_b2: &Isometry3<f64>, p_b2: &Point3<f64>) -> f64 {
        self.covariance_at(b1_from_b2, p_b2).trace().max(0.0).sqrt()
    }
}

/// The [`Uncertainty`] of a fit with parameter covariance `covariance` (`[δθ (rad); δt (m)]`, the
/// order of [`Uncertainty::covariance`]), point noise `sigma` (m) and `dof` residual degrees of
/// freedom: fills the 1-σ translation error at the b2 origin and the 1-σ rotation error.
pub(crate) fn build_uncertainty(
    covariance: Matrix6<f64>,
    sigma: f64,
    dof: usize,
    b1_from_b2: &Isometry3<f64>,
) -> Uncertainty {
    let mut u = Uncertainty {
        covariance,
        sigma_point_m: sigma,
        dof,
        e_tran_1sigma_m: 0.0,
        e_rot_1sigma_rad: 0.0,
    };
    let c_t = u.covariance_at(b1_from_b2, &Point3::origin());
    u.e_tran_1sigma_m = (0..3)
        .map(|i| c_t[(i, i)].max(0.0).sqrt())
        .fold(0.0, f64::max);
    let c_r: Matrix3<f64> = covariance.fixed_view::<3, 3>(0, 0).into_owned();
    u.e_rot_1sigma_rad = c_r.symmetric_eigenvalues().max().max(0.0).sqrt();
    u
}

/// The result of a fit.
///
/// Serialises (serde) with SI units: `b1_from_b2` as nalgebra writes an `Isometry3`
/// (`rotation`: the unit quaternion `[x, y, z, w]`, `translation`: `[x, y, z]` in m), `residuals`
/// as `[x, y, z]` in m, `method` as its name.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Fit {
    /// The method that produced it.
    pub method: Method,
    /// The fitted transform: `p_b1 = b1_from_b2 · p_b2`.
    pub b1_from_b2: Isometry3<f64>,
    /// Per-point residuals `p_b1 − b1_from_b2 · p_b2`, m (a fit residual, not an accuracy).
    pub residuals: Vec<Vector3<f64>>,
    /// Conditioning figure (≥ 1, larger is worse). For the 4-point affine methods: σ₁/σ₃ of the
    /// centred b2 points (the affine solve's conditioning). For `lsq`/`constrained`: √cond(JᵀJ) of the
    /// fit's Jacobian with the rotation columns scaled by the points' RMS radius.
    pub condition: f64,
    /// Covariance and predicted errors; `Some` for `lsq` and `constrained` when 3n exceeds the
    /// number of free parameters, `None` for the 4-point projection methods.
    pub uncertainty: Option<Uncertainty>,
}

impl Fit {
    /// RMS of the residual norms, m (how well the points agree with each other, not an accuracy).
    pub fn residual_rms_m(&self) -> f64 {
        if self.residuals.is_empty() {
            return 0.0;
        }
        (self.residuals.iter().map(|r| r.norm_squared()).sum::<f64>() / self.residuals.len() as f64)
            .sqrt()
    }
}

/// Per-point residuals `p_b1 − b1_from_b2 · p_b2`, m.
pub(crate) fn residuals(pairs: &PointPairs, b1_from_b2: &Isometry3<f64>) -> Vec<Vector3<f64>> {
    pairs
        .p_b1
        .iter()
        .zip(&pairs.p_b2)
        .map(|(a, b)| a - b1_from_b2 * b)
        .collect()
}

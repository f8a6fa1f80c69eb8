//! The cell's description: the error type, the robots with their tools, gravity and
//! manufacturing tolerances (the prior), and the noise of 3-row observations.

use crate::Robot;
use kinematics::{Axis, ErrorParam, RobotModel};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

/// Errors of the whole-cell calibration. Non-convergence is not an error (see
/// [`crate::StopReason`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CellFitError {
    /// Invalid input: the message names the observation row or field and the fix.
    #[error("{0}")]
    InvalidInput(String),
    /// The kinematic model rejected an observation's joint angles or parameters.
    #[error("observation row {row}: {message}")]
    Kinematics {
        /// 1-based source row of the observation.
        row: usize,
        /// What the kinematics reported.
        message: String,
    },
    /// A residual or Jacobian is not finite at an observation (NaN input or a diverged iterate).
    #[error(
        "observation row {row}: non-finite residual or Jacobian; check the joint angles and group \
         values for NaN or huge numbers"
    )]
    NonFinite {
        /// 1-based source row.
        row: usize,
    },
    /// After rejecting blunders too few observation rows remain to fit the unknowns.
    #[error("{}", too_few_rows_text(*remaining, *needed, rejected_rows))]
    TooFewRows {
        /// Residual rows (scalars) left.
        remaining: usize,
        /// Residual rows needed.
        needed: usize,
        /// 1-based source rows rejected as blunders: the rows to re-record.
        rejected_rows: Vec<usize>,
    },
}

/// The message of [`CellFitError::TooFewRows`]: the rows to re-record when blunders were
/// rejected, else that the session is too small for the unknowns.
fn too_few_rows_text(remaining: usize, needed: usize, rejected_rows: &[usize]) -> String {
    if rejected_rows.is_empty() {
        format!(
            "the session gives only {remaining} residual rows, but the fit needs at least \
             {needed}: record more rows, or fit fewer unknowns (--model placement, or tighter \
             [robotN.tolerance])"
        )
    } else {
        format!(
            "only {remaining} residual rows remain after rejecting blunders at rows \
             {rejected_rows:?}, but the fit needs at least {needed}; re-record rows \
             {rejected_rows:?}"
        )
    }
}

/// The 0-based slot of `robot` in per-robot arrays.
pub(super) fn robot_slot(robot: Robot) -> usize {
    usize::from(robot.number() - 1)
}

/// Manufacturing tolerances of one robot, the source of the prior. **Convention**: a tolerance
/// is the half-width of a uniform band, so the prior of each parameter is `N(0, (tol/√3)²)` and a
/// truth drawn from `U(±tol)` has exactly the prior's variance. A tolerance of `0` (or `None`)
/// means "not fitted": the parameter is held at zero.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tolerance {
    /// Joint zero offset, rad. Default 0.05° (8.73e-4 rad).
    pub joint_offset_rad: f64,
    /// Joint origin position, each axis, m (URDF `<origin xyz>`, parent link frame). Default 0.5 mm.
    pub origin_xyz_m: f64,
    /// Joint origin orientation, each of roll/pitch/yaw, rad. Default 0.05°.
    pub origin_rpy_rad: f64,
    /// Tool tip offset, each axis, m (flange axes), per tool. Default 0.5 mm.
    pub tip_m: f64,
    /// Joint scale (gear ratio) error, ratio. Default `None` (not fitted).
    pub joint_scale: Option<f64>,
    /// Joint compliance under gravity, rad/(N·m). Default `None` (not fitted).
    pub compliance_rad_per_nm: Option<f64>,
    /// Joint-angle-periodic error, first harmonic: each of the `sin` and `cos` amplitudes, rad
    /// ([`kinematics::KinematicErrors::periodic_sin`]). Default `None` (not fitted).
    pub periodic_rad: Option<f64>,
    /// Lumped gravity compliance (joint compliance × reduced first moment, no masses needed;
    /// [`kinematics::lumped`]): each coefficient, rad. Default `None` (not fitted); `calibrate
    /// --cell --model kinematic+compliance` sets [`LUMPED_COMPLIANCE_TOLERANCE_RAD`].
    pub lumped_compliance_rad: Option<f64>,
}

/// The tolerance of each lumped-compliance coefficient when the model asks for them and the
/// cell says nothing: 0.5° (8.7e-3 rad), the deflection of a joint of 100 µrad/(N·m) under
/// ~9 kg·m of carried first moment, wide enough for a humanoid's torso and an industrial
/// arm's shoulder alike (a weak prior: the data decide).
pub const LUMPED_COMPLIANCE_TOLERANCE_RAD: f64 = 0.5 * std::f64::consts::PI / 180.0;

impl Default for Tolerance {
    fn default() -> Self {
        Self {
            joint_offset_rad: 0.05f64.to_radians(),
            origin_xyz_m: 0.5e-3,
            origin_rpy_rad: 0.05f64.to_radians(),
            tip_m: 0.5e-3,
            joint_scale: None,
            compliance_rad_per_nm: None,
            periodic_rad: None,
            lumped_compliance_rad: None,
        }
    }
}

impl Tolerance {
    /// All tolerances zero: nothing of the robot is fitted (a placement-only fit).
    pub fn none() -> Self {
        Self {
            joint_offset_rad: 0.0,
            origin_xyz_m: 0.0,
            origin_rpy_rad: 0.0,
            tip_m: 0.0,
            joint_scale: None,
            compliance_rad_per_nm: None,
            periodic_rad: None,
            lumped_compliance_rad: None,
        }
    }

    /// Prior standard deviation `tol/√3` of a kinematic parameter (0: not fitted). The mount
    /// parameters are never fitted (they are the base placement's job).
    pub fn prior_sigma(&self, p: ErrorParam) -> f64 {
        let tol = match p {
            ErrorParam::JointOffset { .. } => self.joint_offset_rad,
            ErrorParam::JointScale { .. } => self.joint_scale.unwrap_or(0.0),
            ErrorParam::OriginXyz { .. } => self.origin_xyz_m,
            ErrorParam::OriginRpy { .. } => self.origin_rpy_rad,
            ErrorParam::Tip { .. } => self.tip_m,
            ErrorParam::Compliance { .. } => self.compliance_rad_per_nm.unwrap_or(0.0),
            ErrorParam::PeriodicSin { .. } | ErrorParam::PeriodicCos { .. } => {
                self.periodic_rad.unwrap_or(0.0)
            }
            ErrorParam::LumpedCompliance { .. } => self.lumped_compliance_rad.unwrap_or(0.0),
            ErrorParam::MountXyz { .. } | ErrorParam::MountRpy { .. } => 0.0,
        };
        tol / 3f64.sqrt()
    }

    pub(super) fn check(&self, robot: Robot) -> Result<(), CellFitError> {
        let fields = [
            ("joint_offset_rad", self.joint_offset_rad),
            ("origin_xyz_m", self.origin_xyz_m),
            ("origin_rpy_rad", self.origin_rpy_rad),
            ("tip_m", self.tip_m),
            ("joint_scale", self.joint_scale.unwrap_or(0.0)),
            (
                "compliance_rad_per_nm",
                self.compliance_rad_per_nm.unwrap_or(0.0),
            ),
            ("periodic_rad", self.periodic_rad.unwrap_or(0.0)),
            (
                "lumped_compliance_rad",
                self.lumped_compliance_rad.unwrap_or(0.0),
            ),
        ];
        for (field, v) in fields {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CellFitError::InvalidInput(format!(
                    "{robot} tolerance `{field}` is {v}; give a finite value ≥ 0 (0: not fitted)"
                )));
            }
        }
        Ok(())
    }
}

/// Largest distance between two tools' starting tips, m, at which they are one tip given for
/// both ([`CellRobot::tips_unknown`]): 1 µm, far below any real offset between two markers and
/// far above the rounding of a tip written in mm.
pub const COINCIDENT_TIP_M: f64 = 1e-6;

/// A named tool point on a robot's flange (the handclasp tip, a tracker reflector, …).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Tool {
    /// Name, for messages and reports.
    pub name: String,
    /// Nominal tip offset in the flange (`tool0`) frame, m.
    pub flange_from_tip: Vector3<f64>,
}

/// One robot of the cell: its nominal model, its tools, gravity and tolerances.
#[derive(Debug, Clone)]
pub struct CellRobot {
    /// Nominal kinematic model.
    pub model: RobotModel,
    /// Tool points (at least one); observations name them by index.
    pub tools: Vec<Tool>,
    /// Gravity acceleration in this robot's nominal base frame, m/s² (used by compliance).
    pub g_base: Vector3<f64>,
    /// Tolerances: the prior, and which parameters are fitted.
    pub tolerance: Tolerance,
    /// Robot 2 of a shared-trunk cell: its first `shared_joints` chain joints are robot 1's
    /// (the same physical joints), so their kinematic parameters are robot 1's columns (one set,
    /// fitted once, with robot 1's tolerances; see [`ParamLayout`](super::ParamLayout)). 0
    /// otherwise, and always 0 for robot 1.
    pub shared_joints: usize,
}

impl CellRobot {
    /// Whether the cell does not know this robot's tool tips: two or more of its tools start at
    /// the same tip (within [`COINCIDENT_TIP_M`]; the cell gave one tip for several tools, e.g.
    /// four mocap markers on one link all started at the cell's `tip_mm`) and its tolerance fits
    /// tips. Such tips are no correction of a nominal robot but nuisances of every model, the
    /// nominal one included: the do-no-harm check's reference and a placement-only fit fit them
    /// as the calibration does ([`super::region_harm_check`]).
    pub fn tips_unknown(&self) -> bool {
        self.tolerance.tip_m > 0.0
            && self.tools.iter().enumerate().any(|(i, a)| {
                self.tools[i + 1..]
                    .iter()
                    .any(|b| (a.flange_from_tip - b.flange_from_tip).norm() <= COINCIDENT_TIP_M)
            })
    }

    /// The kinematic parameters fitted for this robot (tolerance > 0), in catalogue order: per
    /// joint offset, scale, origin xyz, origin rpy, compliance, periodic sin, periodic cos, then
    /// the lumped-compliance coefficients ([`kinematics::lumped_params`]). Tip offsets are per
    /// tool and not in this list; mounts are never fitted.
    pub fn fitted_params(&self) -> Vec<ErrorParam> {
        let mut out = Vec::new();
        // Per chain joint: a coupled joint has its own offset, origin and compliance.
        for joint in 0..self.model.chain_joints().len() {
            let mut cand = vec![
                ErrorParam::JointOffset { joint },
                ErrorParam::JointScale { joint },
            ];
            cand.extend(Axis::ALL.map(|axis| ErrorParam::OriginXyz { joint, axis }));
            cand.extend(Axis::ALL.map(|axis| ErrorParam::OriginRpy { joint, axis }));
            cand.push(ErrorParam::Compliance { joint });
            cand.push(ErrorParam::PeriodicSin { joint });
            cand.push(ErrorParam::PeriodicCos { joint });
            out.extend(cand.into_iter().filter(|&p| self.prior_sigma(p) > 0.0));
        }
        if self.tolerance.lumped_compliance_rad.unwrap_or(0.0) > 0.0 {
            out.extend(kinematics::lumped_params(&self.model));
        }
        out
    }

    /// Prior standard deviation of kinematic parameter `p` of this robot (0: not fitted):
    /// [`Tolerance::prior_sigma`], except at a prismatic joint, whose zero offset is a length
    /// (m: its prior is the origin tolerance `origin_xyz_m/√3`, the same length band), whose
    /// scale is an encoder scale (the ratio `joint_scale`), and which has no gravity compliance
    /// or once-per-turn term in this model (0: not fitted).
    pub fn prior_sigma(&self, p: ErrorParam) -> f64 {
        let prismatic = p
            .joint()
            .and_then(|j| self.model.chain_joints().get(j))
            .is_some_and(|j| j.kind.is_prismatic());
        if !prismatic {
            return self.tolerance.prior_sigma(p);
        }
        match p {
            ErrorParam::JointOffset { .. } => self.tolerance.origin_xyz_m / 3f64.sqrt(),
            ErrorParam::Compliance { .. }
            | ErrorParam::PeriodicSin { .. }
            | ErrorParam::PeriodicCos { .. }
            | ErrorParam::LumpedCompliance { .. } => 0.0,
            _ => self.tolerance.prior_sigma(p),
        }
    }
}

/// Noise of a 3-row observation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub enum Noise3 {
    /// Independent, equal σ on each axis, m.
    Isotropic {
        /// Standard deviation per axis, m.
        sigma_m: f64,
    },
    /// Full covariance of the 3 residuals, m², in the residual's frame (symmetric positive
    /// definite).
    Covariance {
        /// The covariance, m².
        cov_m2: Matrix3<f64>,
    },
}

impl Noise3 {
    /// The same noise with each σ multiplied by `s` (a covariance by `s²`).
    pub fn scaled(self, s: f64) -> Noise3 {
        match self {
            Noise3::Isotropic { sigma_m } => Noise3::Isotropic {
                sigma_m: sigma_m * s,
            },
            Noise3::Covariance { cov_m2 } => Noise3::Covariance {
                cov_m2: cov_m2 * (s * s),
            },
        }
    }

    /// The whitening matrix `W = L⁻¹` with `Σ = L·Lᵀ` (Cholesky), so `W·r` has unit covariance.
    pub(super) fn whitening(&self, row: usize) -> Result<Matrix3<f64>, CellFitError> {
        match *self {
            Noise3::Isotropic { sigma_m } => {
                if sigma_m.is_finite() && sigma_m > 0.0 {
                    Ok(Matrix3::identity() / sigma_m)
                } else {
                    Err(CellFitError::InvalidInput(format!(
                        "observation row {row}: noise σ {sigma_m} m must be finite and > 0"
                    )))
                }
            }
            Noise3::Covariance { cov_m2 } => {
                let sym = (cov_m2 - cov_m2.transpose()).amax() <= 1e-12 * cov_m2.amax();
                let l = cov_m2
                    .cholesky()
                    .filter(|_| sym && cov_m2.iter().all(|v| v.is_finite()))
                    .and_then(|c| c.l().try_inverse());
                l.ok_or_else(|| {
                    CellFitError::InvalidInput(format!(
                        "observation row {row}: noise covariance is not symmetric positive \
                         definite ({cov_m2:?} m²)"
                    ))
                })
            }
        }
    }
}

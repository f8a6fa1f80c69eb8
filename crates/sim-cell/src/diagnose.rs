//! The `handclasp diagnose` engine: what the nominal models get wrong in a measured session.
//!
//! Steps (issue #5): (1) baseline fit of `b1_from_b2` with the nominal models, the residual RMS the
//! cell's stated noise (alignment, repeatability, encoder resolution) predicts at these very joint
//! configurations (seeded Monte Carlo), a χ² test and the residual structure (correlations with
//! joints, position and reach); (2) the catalogue of candidate error parameters with
//! identifiability per family; (3) forward selection (`calib_core::identify::forward_select`);
//! (4) the gain; (5) export of corrected URDFs and of a cell with the calibrated `b1_from_b2`.
//!
//! The maths lives in `calib_core::identify`; this module wires it to the kinematic error model
//! (`kinematics::true_base_from_tip`, `kinematics::tip_error_jacobian`), to the cell
//! ([`crate::cell::Cell`]) and to sessions. Inside, SI units; the report speaks mm and degrees
//! (field names carry the unit).
//!
//! Mount tilts are confounded with the rotation of `b1_from_b2` in handclasp residuals (a turned
//! base only turns the fit), so they are never selected from the residuals. The report instead
//! compares the calibrated `b1_from_b2` with the cell's stated one ([`PlacementReport`],
//! [`mount_tilt_test`]): if the cell states the true placement of the nominal bases (as a
//! simulation's cell does), robot 2's tilt turns the fit's rotation only, while robot 1's turns
//! it AND moves its translation by `−a1 × t`, which tells the robots apart. A significant tilt
//! (no-tilt hypothesis rejected at [`ALPHA_TILT`], component at `ALPHA_TILT/2`) is named in
//! `effects` as `mount_tilt` with robot, axis, value and 95% interval. If the cell's placement is
//! not the truth (e.g. a nominal drawing), such an effect reads as "the placement differs from
//! the cell's as this tilt would make it".

use std::path::{Path, PathBuf};

use calib_core::identify::{
    self, IdentStatus, IdentifyError, Robot, SelectionOptions, TipEval, TipModel,
};
use calib_core::stats::{chi2_sf, fraction_below, pearson, quantile, t_quantile, t_two_sided_p};
use kinematics::{Axis, ErrorParam, KinematicErrors};
use nalgebra::{Isometry3, Matrix3, Matrix3xX, Point3, Vector3};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use crate::cell::{Cell, CellRobot};
use crate::session::Session;
use crate::SimError;

pub use kinematics::{rotation_from_zyz, zyz_from_rotation};

/// Errors of the diagnosis: bad files or inputs. Each names the file/row/field and the fix.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The session does not fit the cell (joint counts, units, tips vs FK, too few points).
    #[error("session {path}: {message}")]
    Session {
        /// The session file (or `<memory>`).
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// The cell or session could not be read.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The identification failed on the input.
    #[error("identification: {0}")]
    Identify(#[from] IdentifyError),
}

/// Largest distance (m) between a session's reported tip and FK of its joint columns with the
/// cell's tip offset: 0.2 mm covers the rounding of a file and the encoder resolution.
pub const FK_TOLERANCE_M: f64 = 2e-4;

/// Checks a session against the cell: joint counts, units (radians under `*_deg`, metres under
/// `*_mm`), joint limits, the reported tips against FK of the joint columns with the cell's tip
/// offsets, and that there are enough points to identify anything. `path` is named in messages.
pub fn check_session(cell: &Cell, s: &Session, path: &Path) -> Result<(), DiagnoseError> {
    let serr = |message: String| DiagnoseError::Session {
        path: path.to_path_buf(),
        message,
    };
    let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
    for p in &s.points {
        if p.q1.len() != d1 || p.q2.len() != d2 {
            return Err(serr(format!(
                "point {}: {} joint value(s) for robot 1 and {} for robot 2, but the cell's URDFs have {d1} ({}) and {d2} ({}): \
                 use the session recorded with this cell, or the cell of this session",
                p.point,
                p.q1.len(),
                p.q2.len(),
                cell.robot1.model.name(),
                cell.robot2.model.name()
            )));
        }
    }
    let n = s.points.len();
    let needed = identify::min_points(1);
    if n < needed {
        return Err(serr(format!(
            "{n} handclasp point(s): too few to identify anything; fitting b1_from_b2 (6 unknowns) and one error \
             parameter with a meaningful test needs at least {needed} points, and the full catalogue 20–60 \
             (40 recommended)"
        )));
    }
    let max_q = s
        .points
        .iter()
        .flat_map(|p| p.q1.iter().chain(&p.q2))
        .fold(0.0f64, |a, v| a.max(v.abs()));
    if max_q.to_degrees() <= std::f64::consts::PI + 1e-9 {
        return Err(serr(format!(
            "every joint angle is within ±{:.3} degrees — these look like radians written as degrees: convert them to degrees",
            max_q.to_degrees()
        )));
    }
    let max_p = s
        .points
        .iter()
        .flat_map(|p| [p.p_b1, p.p_b2])
        .fold(0.0f64, |a, p| a.max(p.coords.amax()));
    if max_p < 0.01 {
        return Err(serr(format!(
            "every tip coordinate is below {:.4} mm — these look like metres written as millimetres: convert them to millimetres",
            max_p * 1000.0
        )));
    }
    for p in &s.points {
        for (r, setup, q, tip) in [
            (1, &cell.robot1, &p.q1, &p.p_b1),
            (2, &cell.robot2, &p.q2, &p.p_b2),
        ] {
            let row = p.point;
            setup
                .model
                .check_q(q)
                .map_err(|e| serr(format!("point {row}, robot {r}: {e}")))?;
            let fk = kinematics::base_from_tip(&setup.model, q, &setup.flange_from_tip)
                .map_err(|e| serr(format!("point {row}, robot {r}: {e}")))?;
            let d = (fk.translation.vector - tip.coords).norm();
            if d > FK_TOLERANCE_M {
                return Err(serr(format!(
                    "point {row}: robot {r}'s tip columns differ by {:.3} mm from FK of its joint columns with \
                     the cell's tip offset ({} mm): wrong cell, wrong tip_mm, or tips not in mm / not in the robot's base frame",
                    d * 1000.0,
                    fmt3(&(setup.flange_from_tip * 1000.0))
                )));
            }
        }
    }
    Ok(())
}

fn fmt3(v: &Vector3<f64>) -> String {
    format!("[{:.3}, {:.3}, {:.3}]", v.x, v.y, v.z)
}

/// Kind of a candidate effect (the six kinds).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    /// A joint's zero offset.
    JointOffset,
    /// A joint origin's translation along x, y or z (parent frame).
    LinkLength,
    /// The tip offset error, tool0 frame.
    TipOffset,
    /// A base tilt about its x or y axis.
    MountTilt,
    /// A joint's deflection under gravity.
    Compliance,
    /// A joint's gear-ratio error.
    JointScale,
}

impl EffectKind {
    /// The kind's name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Self::JointOffset => "joint_offset",
            Self::LinkLength => "link_length",
            Self::TipOffset => "tip_offset",
            Self::MountTilt => "mount_tilt",
            Self::Compliance => "compliance",
            Self::JointScale => "joint_scale",
        }
    }
    /// Output unit.
    pub fn unit(self) -> &'static str {
        match self {
            Self::JointOffset | Self::MountTilt => "deg",
            Self::LinkLength | Self::TipOffset => "mm",
            Self::JointScale => "ratio",
            Self::Compliance => "deg/(kN·m)",
        }
    }
    /// Factor from SI (rad, m, ratio, rad/(N·m)) to the output unit.
    pub fn to_output(self) -> f64 {
        match self {
            Self::JointOffset | Self::MountTilt => 180.0 / std::f64::consts::PI,
            Self::LinkLength | Self::TipOffset => 1000.0,
            Self::JointScale => 1.0,
            Self::Compliance => 180.0 / std::f64::consts::PI * 1000.0,
        }
    }
}

/// One candidate of the catalogue.
#[derive(Debug, Clone, Copy)]
pub struct Candidate {
    /// Kind.
    pub kind: EffectKind,
    /// Robot, 1 or 2.
    pub robot: u8,
    /// 0-based joint, where it applies.
    pub joint: Option<usize>,
    /// Axis, where it applies.
    pub axis: Option<Axis>,
    /// The kinematic-error parameter.
    pub param: ErrorParam,
}

impl Candidate {
    /// Readable name, e.g. `robot 2 joint_offset joint 3` or `robot 1 link_length joint 2 x`.
    pub fn label(&self) -> String {
        let mut s = format!("robot {} {}", self.robot, self.kind.name());
        if let Some(j) = self.joint {
            s += &format!(" joint {}", j + 1);
        }
        if let Some(a) = self.axis {
            s += &format!(" {}", axis_name(a));
        }
        s
    }
}

fn axis_name(a: Axis) -> &'static str {
    match a {
        Axis::X => "x",
        Axis::Y => "y",
        Axis::Z => "z",
    }
}

/// The full catalogue for two robots with `dof1`, `dof2` joints.
pub fn catalogue(dof1: usize, dof2: usize) -> Vec<Candidate> {
    let mut c = Vec::new();
    for (robot, dof) in [(1u8, dof1), (2u8, dof2)] {
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::JointOffset,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::JointOffset { joint: j },
            });
        }
        for j in 0..dof {
            for a in [Axis::X, Axis::Y, Axis::Z] {
                c.push(Candidate {
                    kind: EffectKind::LinkLength,
                    robot,
                    joint: Some(j),
                    axis: Some(a),
                    param: ErrorParam::OriginXyz { joint: j, axis: a },
                });
            }
        }
        for a in [Axis::X, Axis::Y, Axis::Z] {
            c.push(Candidate {
                kind: EffectKind::TipOffset,
                robot,
                joint: None,
                axis: Some(a),
                param: ErrorParam::Tip { axis: a },
            });
        }
        for a in [Axis::X, Axis::Y] {
            c.push(Candidate {
                kind: EffectKind::MountTilt,
                robot,
                joint: None,
                axis: Some(a),
                param: ErrorParam::MountRpy { axis: a },
            });
        }
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::Compliance,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::Compliance { joint: j },
            });
        }
        for j in 0..dof {
            c.push(Candidate {
                kind: EffectKind::JointScale,
                robot,
                joint: Some(j),
                axis: None,
                param: ErrorParam::JointScale { joint: j },
            });
        }
    }
    c
}

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
            if c.robot == 1 {
                e1.set(c.param, v);
            } else {
                e2.set(c.param, v);
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
        if self.candidates[j].robot == 1 {
            Robot::One
        } else {
            Robot::Two
        }
    }
    fn param_prior(&self, j: usize) -> f64 {
        // Each (robot, kind) family equally likely a priori: 1/family size.
        let c = &self.candidates[j];
        let size = self
            .candidates
            .iter()
            .filter(|o| o.robot == c.robot && o.kind == c.kind)
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
        match self.candidates[j].kind {
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
                (1u8, r1, &e1, &self.q1[point]),
                (2u8, r2, &e2, &self.q2[point]),
            ] {
                let cols: Vec<usize> = (0..jacobian_params.len())
                    .filter(|&c| self.candidates[jacobian_params[c]].robot == robot)
                    .collect();
                if cols.is_empty() {
                    continue;
                }
                let eps: Vec<ErrorParam> = cols
                    .iter()
                    .map(|&c| self.candidates[jacobian_params[c]].param)
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

/// Options of the diagnosis.
#[derive(Debug, Clone)]
pub struct DiagnoseOptions {
    /// Seed of the Monte Carlo simulations (default 1).
    pub seed: u64,
    /// Monte Carlo trials for the predicted residual distributions (default 400).
    pub trials: usize,
    /// Selection settings (α = 0.04 family-wise per step, 10 folds).
    pub selection: SelectionOptions,
    /// Truth of `b1_from_b2` (e.g. from a CMM), for e_tran/e_rot before and after.
    pub truth: Option<Isometry3<f64>>,
    /// Uncertainty of the cell's stated `b1_from_b2` angles, degrees, in the placement check
    /// (default 0.001°: the rounding of a cell file written with 3 decimals, conservatively).
    pub placement_sd_deg: f64,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            trials: 400,
            selection: SelectionOptions::default(),
            truth: None,
            placement_sd_deg: 0.001,
        }
    }
}

/// `b1_from_b2` in file units.
#[derive(Debug, Clone, Serialize)]
pub struct PoseReport {
    /// Translation, mm.
    pub xyz_mm: [f64; 3],
    /// ZYZ angles, degrees, `R = Rz(φ)·Ry(θ)·Rz(ψ)`.
    pub zyz_deg: [f64; 3],
}

impl PoseReport {
    /// From an isometry; the ZYZ branch nearest `reference` (rad), e.g. the cell's angles.
    pub fn from_isometry(x: &Isometry3<f64>, reference: [f64; 3]) -> Self {
        let t = x.translation.vector * 1000.0;
        let z = kinematics::zyz_nearest(&x.rotation.to_rotation_matrix(), reference);
        Self {
            xyz_mm: [t.x, t.y, t.z],
            zyz_deg: [z[0].to_degrees(), z[1].to_degrees(), z[2].to_degrees()],
        }
    }
}

/// The calibrated `b1_from_b2` against the cell's stated one. Handclasp residuals cannot see a
/// mount tilt (it only turns the fit), but if the cell states the TRUE placement of the nominal
/// bases (as a simulation's cell does), the fitted rotation shows it: `R_fit = R_cell·exp([a]ₓ)`,
/// `a` in base-2 axes, which is a tilt of robot 2's base by `a` (or of robot 1's by
/// `−R_cell·a`, which also moves the translation: [`mount_tilt_test`] uses both to tell the
/// robots apart; the `tilt_*` fields here are the rotation-only check).
#[derive(Debug, Clone, Serialize)]
pub struct PlacementReport {
    /// `a` about base 2's x and y axes (a mount tilt of robot 2), degrees.
    pub tilt_b2_deg: [f64; 2],
    /// 95% intervals of the two tilt components, degrees.
    pub tilt_b2_ci95_deg: [[f64; 2]; 2],
    /// Two-sided p-values of the two tilt components.
    pub tilt_b2_p_value: [f64; 2],
    /// Whether a tilt component is significant at 5% (Bonferroni over the two).
    pub tilt_significant: bool,
    /// The same rotation as a tilt of robot 1's base about its x, y, z axes, degrees.
    pub robot1_equivalent_deg: [f64; 3],
    /// `a` about base 2's z axis (a yaw of robot 2's base), degrees, and its 95% interval.
    pub yaw_b2_deg: f64,
    /// 95% interval of the yaw, degrees.
    pub yaw_b2_ci95_deg: [f64; 2],
    /// Fitted minus stated translation, b1 axes, mm.
    pub dxyz_mm: [f64; 3],
    /// Standard errors of `dxyz_mm`, mm.
    pub dxyz_se_mm: [f64; 3],
    /// The mount-tilt test (rotation AND translation against the cell's placement): which
    /// robot's base is tilted; its significant components are named in `effects`.
    pub mount_tilt: MountTiltTest,
}

/// One named effect.
#[derive(Debug, Clone, Serialize)]
pub struct EffectReport {
    /// Kind.
    pub kind: EffectKind,
    /// Robot, 1 or 2.
    pub robot: u8,
    /// 1-based joint, or null.
    pub joint: Option<usize>,
    /// "x" | "y" | "z", or null.
    pub axis: Option<&'static str>,
    /// Estimate, true minus nominal, in `unit`.
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
    /// 95% interval (t quantile), in `unit`.
    pub ci95: [f64; 2],
    /// Candidates the data cannot tell apart from this one (labels), including itself.
    pub confounded_with: Vec<String>,
    /// Partial F-test p-value in the final model (refit without it), unadjusted; it was
    /// selected at the Bonferroni level `α/m`. For a `mount_tilt` (named from the placement,
    /// [`mount_tilt_test`]): the component's two-sided p, named below `ALPHA_TILT / 2`.
    pub p_value: f64,
}

/// A significant correlation of the residuals.
#[derive(Debug, Clone, Serialize)]
pub struct CorrelationReport {
    /// Residual component: "x", "y", "z" (b1 axes) or "norm".
    pub residual: String,
    /// Against what: "r1_q3", "r2_q1", "x", "y", "z" (robot 1 tip in b1), "reach1", "reach2".
    pub against: String,
    /// Pearson r.
    pub r: f64,
    /// Bonferroni-adjusted p-value.
    pub p_adjusted: f64,
}

/// The smallest effect of one candidate this session can detect (80% power, first step).
#[derive(Debug, Clone, Serialize)]
pub struct DetectableReport {
    /// Candidate label, e.g. `robot 2 joint_offset joint 3`.
    pub label: String,
    /// Smallest detectable |value|, in `unit` (cell σ).
    pub value: f64,
    /// Unit.
    pub unit: &'static str,
}

/// Identifiability of one family.
#[derive(Debug, Clone, Serialize)]
pub struct FamilyReport {
    /// Robot.
    pub robot: u8,
    /// Kind.
    pub kind: EffectKind,
    /// Candidates in the family.
    pub size: usize,
    /// Rank after projecting out the base frames.
    pub rank: usize,
    /// Condition number of the unit-scaled projected columns (null when rank-deficient).
    pub condition: Option<f64>,
    /// Singular values (dimensionless, unit-scaled columns).
    pub singular_values: Vec<f64>,
    /// Members confounded with a base frame (absorbed by `b1_from_b2`).
    pub confounded_with_base: Vec<String>,
    /// For each member of `confounded_with_base` (same order), the base-frame motion it is
    /// equivalent to, e.g. `rotation of robot 1's base about its (0.000, 0.000, 1.000) axis
    /// (base yaw)`.
    pub confounded_as: Vec<String>,
    /// Members that do not move the tip at these configurations.
    pub no_effect: Vec<String>,
}

/// The diagnosis report (`--json` prints it).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnoseReport {
    /// Named effects.
    pub effects: Vec<EffectReport>,
    /// Residual RMS (3-D per point) of the nominal fit, mm.
    pub rms_before_mm: f64,
    /// Residual RMS of the extended model, mm.
    pub rms_after_mm: f64,
    /// K-fold held-out residual RMS, nominal model, mm.
    pub heldout_rms_before_mm: f64,
    /// K-fold held-out residual RMS, extended model, mm.
    pub heldout_rms_after_mm: f64,
    /// Calibrated `b1_from_b2` (extended model).
    pub b1_from_b2: PoseReport,
    /// `b1_from_b2` of the nominal fit.
    pub b1_from_b2_before: PoseReport,
    /// Points.
    pub n_points: usize,
    /// The cell's noise as an effective σ per axis at these configurations (alignment,
    /// repeatability of both robots and encoder resolution, RMS over points), mm.
    pub sigma_cell_mm: f64,
    /// σ estimated from the nominal fit, mm.
    pub sigma_hat_before_mm: f64,
    /// σ estimated from the extended fit, mm.
    pub sigma_hat_after_mm: f64,
    /// Predicted RMS under the cell's noise (MC median), mm.
    pub predicted_rms_mm: f64,
    /// MC 5–95% band of the predicted RMS, mm.
    pub predicted_rms_band_mm: [f64; 2],
    /// Fraction of MC trials whose RMS is below the measured one.
    pub measured_rms_percentile: f64,
    /// χ² test of RSS/σ² with 3n−6 dof: upper-tail p-value.
    pub chi2_p_value: f64,
    /// Significant residual correlations of the nominal fit (Bonferroni 5%).
    pub correlations: Vec<CorrelationReport>,
    /// Significant residual correlations left by the extended model (Bonferroni 5%).
    pub correlations_after: Vec<CorrelationReport>,
    /// χ² test of the extended model's (whitened) RSS/σ² with its residual dof: upper-tail p.
    pub chi2_p_value_after: f64,
    /// Identifiability per family.
    pub families: Vec<FamilyReport>,
    /// Smallest detectable |value| per identifiable candidate under this session's design and
    /// the cell's σ.
    pub min_detectable: Vec<DetectableReport>,
    /// Groups of mutually confounded candidates (labels).
    pub confounded_groups: Vec<Vec<String>>,
    /// Predicted 1-σ translation error of `b1_from_b2`, before / after, mm.
    pub predicted_e_tran_mm: [f64; 2],
    /// Predicted 1-σ rotation error, before / after, degrees.
    pub predicted_e_rot_deg: [f64; 2],
    /// e_tran against the truth, before / after, mm (when truth given).
    pub truth_e_tran_mm: Option<[f64; 2]>,
    /// e_rot (eq 33: ZYZ angles, branch nearest the truth, wrapped, ∞-norm) against the truth,
    /// before / after, degrees (when truth given).
    pub truth_e_rot_deg: Option<[f64; 2]>,
    /// Geodesic rotation error against the truth, before / after, degrees (when truth given).
    pub truth_geodesic_deg: Option<[f64; 2]>,
    /// Re-simulation with the extended model: MC median of the nominal-fit RMS it predicts, mm
    /// (to compare with `rms_before_mm`), and the measured RMS's percentile in it.
    pub resimulated_rms_before_mm: f64,
    /// Percentile of the measured nominal RMS in the re-simulated distribution.
    pub resimulated_percentile: f64,
    /// 5–95% band of the re-simulated nominal-fit RMS, mm.
    pub resimulated_rms_band_mm: [f64; 2],
    /// Percentile of the extended model's residual RMS among noise-only simulations of a
    /// correct model (near 50% when the extended model explains the data).
    pub rms_after_percentile: f64,
    /// The calibrated `b1_from_b2` against the cell's stated one (mount tilts).
    pub placement: PlacementReport,
    /// Selection steps in words.
    pub steps: Vec<String>,
    /// Whether the final LM fit converged.
    pub converged: bool,
}

/// The cell's noise at the session's configurations: per point, the Cholesky-free pieces needed
/// to draw the residual noise `r = δ1 + J1·u1 − ε − R·(δ2 + J2·u2)` (alignment `ε` per b1 axis,
/// repeatability `δ` isotropic per robot, encoder quantisation `u` uniform in ±resolution/2),
/// and its effective per-axis variance.
struct NoiseModel {
    alignment: Vector3<f64>,
    repeatability: f64,
    resolution: f64,
    /// Robot 1's tip position Jacobians, b1 axes.
    j1: Vec<Matrix3xX<f64>>,
    /// Robot 2's tip position Jacobians rotated into b1 axes.
    j2_b1: Vec<Matrix3xX<f64>>,
    /// Mean over points of trace(Σ_i)/3, m².
    sigma2_eff: f64,
}

impl NoiseModel {
    fn new(
        cell: &Cell,
        q1: &[Vec<f64>],
        q2: &[Vec<f64>],
        r_x: &Matrix3<f64>,
    ) -> Result<Self, DiagnoseError> {
        let noise = &cell.noise;
        let jac = |robot: &CellRobot, q: &[f64]| {
            kinematics::tip_position_jacobian(&robot.model, q, &robot.flange_from_tip).map_err(
                |e| DiagnoseError::Session {
                    path: PathBuf::from("<session>"),
                    message: e.to_string(),
                },
            )
        };
        let mut j1 = Vec::with_capacity(q1.len());
        let mut j2_b1 = Vec::with_capacity(q1.len());
        let q_var = noise.encoder_resolution_rad.powi(2) / 12.0;
        let mut sum = 0.0;
        for (a, b) in q1.iter().zip(q2) {
            let ja = jac(&cell.robot1, a)?;
            let jb = r_x * jac(&cell.robot2, b)?;
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
    fn whitening(&self) -> Vec<Matrix3<f64>> {
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
/// `p1 = x·p2 + d + noise`. Trial `t` draws from `trial_rng(seed, t)`.
fn simulate_rms(
    p2: &[Point3<f64>],
    x: &Isometry3<f64>,
    d: &[Vector3<f64>],
    noise: &NoiseModel,
    seed: u64,
    trials: usize,
) -> Vec<f64> {
    let mut out: Vec<f64> = (0..trials)
        .map(|t| {
            let mut rng = crate::trial_rng(seed, t as u64);
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

/// Pearson correlations of the residual components (b1 axes) and norms with each joint angle,
/// the tip position (b1) and each robot's reach (tip distance from its base origin); those
/// significant at 5% after a Bonferroni correction over all pairs tested.
fn correlations(session: &Session, residuals: &[Vector3<f64>]) -> Vec<CorrelationReport> {
    let n = residuals.len();
    let pts = &session.points;
    let mut targets: Vec<(String, Vec<f64>)> = Vec::new();
    for r in [1u8, 2] {
        let dof = pts
            .first()
            .map_or(0, |p| if r == 1 { p.q1.len() } else { p.q2.len() });
        for k in 0..dof {
            targets.push((
                format!("r{r}_q{}", k + 1),
                pts.iter()
                    .map(|p| if r == 1 { p.q1[k] } else { p.q2[k] })
                    .collect(),
            ));
        }
    }
    for (a, name) in ["x", "y", "z"].iter().enumerate() {
        targets.push((name.to_string(), pts.iter().map(|p| p.p_b1[a]).collect()));
    }
    targets.push((
        "reach1".into(),
        pts.iter().map(|p| p.p_b1.coords.norm()).collect(),
    ));
    targets.push((
        "reach2".into(),
        pts.iter().map(|p| p.p_b2.coords.norm()).collect(),
    ));
    let comps: Vec<(String, Vec<f64>)> = vec![
        ("x".into(), residuals.iter().map(|r| r.x).collect()),
        ("y".into(), residuals.iter().map(|r| r.y).collect()),
        ("z".into(), residuals.iter().map(|r| r.z).collect()),
        ("norm".into(), residuals.iter().map(|r| r.norm()).collect()),
    ];
    let tests = (targets.len() * comps.len()) as f64;
    let mut out = Vec::new();
    for (cn, cv) in &comps {
        for (tn, tv) in &targets {
            let r = pearson(cv, tv);
            let stat = r * ((n as f64 - 2.0) / (1.0 - r * r).max(1e-300)).sqrt();
            let p = t_two_sided_p(stat, n.saturating_sub(2));
            let p_adj = (p * tests).min(1.0);
            if p_adj < 0.05 {
                out.push(CorrelationReport {
                    residual: cn.clone(),
                    against: tn.clone(),
                    r,
                    p_adjusted: p_adj,
                });
            }
        }
    }
    out
}

/// Joint vectors of a session (rad): `(q1s, q2s)`.
fn joints(session: &Session) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    (
        session.points.iter().map(|p| p.q1.clone()).collect(),
        session.points.iter().map(|p| p.q2.clone()).collect(),
    )
}

fn placement_report(fit: &identify::IdentFit, cell: &Cell, sd_deg: f64) -> PlacementReport {
    let pr = identify::placement_rotation(fit, &cell.b1_from_b2, sd_deg.to_radians());
    let t = t_quantile(0.975, fit.dof);
    let ci = |i: usize| {
        [
            (pr.a_b2[i] - t * pr.std_error[i]).to_degrees(),
            (pr.a_b2[i] + t * pr.std_error[i]).to_degrees(),
        ]
    };
    PlacementReport {
        tilt_b2_deg: [pr.a_b2.x.to_degrees(), pr.a_b2.y.to_degrees()],
        tilt_b2_ci95_deg: [ci(0), ci(1)],
        tilt_b2_p_value: [pr.p_value.x, pr.p_value.y],
        tilt_significant: pr.p_value.x.min(pr.p_value.y) < 0.05 / 2.0,
        robot1_equivalent_deg: [
            pr.a1_b1.x.to_degrees(),
            pr.a1_b1.y.to_degrees(),
            pr.a1_b1.z.to_degrees(),
        ],
        yaw_b2_deg: pr.a_b2.z.to_degrees(),
        yaw_b2_ci95_deg: ci(2),
        dxyz_mm: [pr.dt_b1.x * 1e3, pr.dt_b1.y * 1e3, pr.dt_b1.z * 1e3],
        dxyz_se_mm: [
            pr.dt_std_error.x * 1e3,
            pr.dt_std_error.y * 1e3,
            pr.dt_std_error.z * 1e3,
        ],
        mount_tilt: mount_tilt_test(fit, cell, sd_deg.to_radians()),
    }
}

/// Level of the mount-tilt test against the cell's placement ([`mount_tilt_test`]): the
/// no-tilt hypothesis is rejected when its χ² upper-tail p is below this, and a tilt component
/// is named when its two-sided p is below `ALPHA_TILT / 2` (Bonferroni over x and y). 1% so that it
/// adds at most ~1% to the residual selection's false alarms on noise-only sessions (5%
/// family-wise, in practice 2.5–5%; BENCHMARKS.md, "diagnose").
pub const ALPHA_TILT: f64 = 0.01;

/// Standard deviation (m, per axis) of the cell's stated `b1_from_b2` translation in the
/// mount-tilt test: the paper's Table 1 prints xyz to 0.1 mm (rounding sd 0.029 mm), taken
/// conservatively as 0.05 mm.
pub const PLACEMENT_SD_XYZ_M: f64 = 5e-5;

/// The mount-tilt test: which robot's base is tilted, if any, when the cell states the TRUE
/// placement of the nominal bases (see [`mount_tilt_test`]).
#[derive(Debug, Clone, Serialize)]
pub struct MountTiltTest {
    /// χ² of the hypotheses no tilt (both base yaws free) / robot 1's base turned (tilt and
    /// yaw) / robot 2's, GLS on the placement difference.
    pub chi2: [f64; 3],
    /// Their degrees of freedom (6 − rank).
    pub dof: [usize; 3],
    /// Upper-tail p of the no-tilt hypothesis.
    pub p_no_tilt: f64,
    /// The robot whose tilt explains the difference best (smaller χ²), when no tilt is rejected
    /// at [`ALPHA_TILT`].
    pub robot: Option<u8>,
    /// Upper-tail p of the chosen hypothesis (a goodness-of-fit check: below [`ALPHA_TILT`],
    /// no mount tilt explains the difference and none is named).
    pub p_fit: f64,
    /// The chosen robot's tilt about its base x and y axes, degrees (`mount_rpy` x, y).
    pub tilt_deg: [f64; 2],
    /// Their 95% intervals, degrees.
    pub tilt_ci95_deg: [[f64; 2]; 2],
    /// Their two-sided p-values.
    pub tilt_p_value: [f64; 2],
    /// The other robot, when its tilt explains the difference as well (both hypotheses pass
    /// their χ² test): a tilt about the line joining the two bases turns both alike, so the data
    /// cannot tell which base it is; the choice then goes to the fewer tilt components.
    pub alternative: Option<u8>,
    /// The alternative robot's significant tilt axes.
    pub alternative_axes: Vec<&'static str>,
}

/// The placement difference `d = (φ, δt)` predicted by tilts/yaws `θ = [a1x, a1y, ψ1, a2x, a2y,
/// ψ2]` (rad): the true base `i` is the nominal one turned by `Rot(rpy = (aix, aiy, 0))·Rz(ψi)`
/// (ψ: the base yaw, equivalent to a joint-1 offset), so the fit sees
/// `X̂ = M1⁻¹·X·M2`; `φ = log(R̂·Rᵀ)` (b1 axes), `δt = t̂ − t`.
fn tilt_prediction(x: &Isometry3<f64>, th: &[f64; 6]) -> [f64; 6] {
    let m = |a: f64, b: f64, psi: f64| {
        let r = kinematics::rotation_from_rpy(&Vector3::new(a, b, 0.0))
            * nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), psi);
        Isometry3::from_parts(nalgebra::Translation3::identity(), r.into())
    };
    let xh = m(th[0], th[1], th[2]).inverse() * x * m(th[3], th[4], th[5]);
    let phi = (xh.rotation * x.rotation.inverse()).scaled_axis();
    let dt = xh.translation.vector - x.translation.vector;
    [phi.x, phi.y, phi.z, dt.x, dt.y, dt.z]
}

/// Tests for a mount tilt by comparing the fitted `b1_from_b2` (`X̂`) with the cell's (`X`),
/// assuming the cell states the TRUE placement of the nominal bases (as a simulation's cell
/// does). A tilt of robot 2's base by `a2` (b2 axes) gives `X̂ = X·exp([a2]ₓ)`: the rotation
/// turns by `R·a2`, the translation does not move. A tilt of robot 1's base by `a1` (b1 axes)
/// gives `X̂ = exp(−[a1]ₓ)·X` (the points measured in the nominal b1 are the true ones turned
/// back): the rotation turns by `−a1` AND the translation moves by `−a1 × t` (≈ 1.5 mm for
/// 0.05° at |t| ≈ 1.7 m, against an s.e. of ~0.1–0.2 mm), which is what tells the robots apart.
///
/// `d = (φ, δt)` with covariance from the fit (left perturbation: `φ`, `δt = ρ − [t̂]ₓφ`) plus
/// the cell's stated-angle sd `sd_rad` and [`PLACEMENT_SD_XYZ_M`]. Hypotheses (a base yaw is
/// confounded with that robot's joint-1 offset: a nuisance, never a mount tilt): H0 no tilt
/// (both yaws free), H1 robot 1's base turned (tilt about x, y and its yaw), H2 robot 2's;
/// generalised least squares (Gauss–Newton on the exact [`tilt_prediction`]). H0 rejected at
/// [`ALPHA_TILT`] → the hypothesis that passes its own χ² test at [`ALPHA_TILT`]; if both pass (a
/// turn about the line joining the two bases looks the same for both robots), the one with fewer
/// significant tilt components, then the smaller χ² (the other is recorded as `alternative`).
/// If neither passes, the difference is no mount tilt (e.g. a base-frame translation) and
/// nothing is named. Components are named at `ALPHA_TILT / 2` each (Bonferroni over x and y), not
/// both on the joint test: a zero component named would be a false cause.
pub fn mount_tilt_test(fit: &identify::IdentFit, cell: &Cell, sd_rad: f64) -> MountTiltTest {
    use nalgebra::{DMatrix, DVector, Matrix6};
    let x = cell.b1_from_b2;
    let r = x.rotation.to_rotation_matrix().into_inner();
    let t = x.translation.vector;
    let xh = fit.b1_from_b2;
    let phi = (xh.rotation * x.rotation.inverse()).scaled_axis();
    let dt = xh.translation.vector - t;
    let d = DVector::from_row_slice(&[phi.x, phi.y, phi.z, dt.x, dt.y, dt.z]);
    // Covariance of d from the fit's (ρ, φ) covariance.
    let mut j = Matrix6::<f64>::zeros();
    j.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&Matrix3::identity());
    j.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&Matrix3::identity());
    j.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(-xh.translation.vector.cross_matrix()));
    let sx: Matrix6<f64> = fit.covariance.fixed_view::<6, 6>(0, 0).into_owned();
    let mut c = j * sx * j.transpose();
    for i in 0..3 {
        c[(i, i)] += sd_rad * sd_rad;
        c[(3 + i, 3 + i)] += PLACEMENT_SD_XYZ_M * PLACEMENT_SD_XYZ_M;
    }
    let empty = MountTiltTest {
        chi2: [f64::NAN; 3],
        dof: [0; 3],
        p_no_tilt: 1.0,
        robot: None,
        p_fit: 1.0,
        tilt_deg: [0.0; 2],
        tilt_ci95_deg: [[0.0; 2]; 2],
        tilt_p_value: [1.0; 2],
        alternative: None,
        alternative_axes: Vec::new(),
    };
    let Some(chol) = nalgebra::Cholesky::new(DMatrix::from_iterator(6, 6, c.iter().copied()))
    else {
        return empty;
    };
    let l = chol.l();
    let whiten = |v: &DVector<f64>| {
        l.solve_lower_triangular(v)
            .unwrap_or_else(|| DVector::zeros(6))
    };
    // Linear columns at θ = 0 (rad → d): [a1x, a1y, ψ1, a2x, a2y, ψ2].
    let mut a_full = DMatrix::<f64>::zeros(6, 6);
    for (k, e) in [Vector3::x(), Vector3::y(), Vector3::z()]
        .iter()
        .enumerate()
    {
        let rot1 = -e;
        let tr1 = -e.cross(&t);
        let rot2 = r * e;
        for i in 0..3 {
            a_full[(i, k)] = rot1[i];
            a_full[(3 + i, k)] = tr1[i];
            a_full[(i, 3 + k)] = rot2[i];
        }
    }
    // GLS fit of a hypothesis (columns `cols` of θ): (θ, χ², dof, cov θ).
    let gls = |cols: &[usize]| {
        let a = a_full.select_columns(cols);
        let aw = DMatrix::from_columns(
            &(0..cols.len())
                .map(|k| whiten(&a.column(k).into_owned()))
                .collect::<Vec<_>>(),
        );
        let svd = aw.clone().svd(true, true);
        let smax = svd.singular_values.max();
        let tol = smax * 1e-9;
        let rank = svd.singular_values.iter().filter(|&&s| s > tol).count();
        let pinv = svd
            .clone()
            .pseudo_inverse(tol)
            .unwrap_or_else(|_| DMatrix::zeros(cols.len(), 6));
        let mut th = [0.0; 6];
        let mut chi2 = f64::NAN;
        for _ in 0..4 {
            let pred = DVector::from_row_slice(&tilt_prediction(&x, &th));
            let rw = whiten(&(&d - pred));
            chi2 = rw.norm_squared();
            let step = &pinv * rw;
            for (k, &col) in cols.iter().enumerate() {
                th[col] += step[k];
            }
        }
        let pred = DVector::from_row_slice(&tilt_prediction(&x, &th));
        chi2 = whiten(&(&d - pred)).norm_squared().min(chi2);
        let cov = &pinv * pinv.transpose();
        (th, chi2, 6 - rank, cov)
    };
    let h0 = gls(&[2, 5]);
    let hyp = [gls(&[0, 1, 2]), gls(&[3, 4, 5])];
    let p0 = chi2_sf(h0.1, h0.2);
    let mut out = MountTiltTest {
        chi2: [h0.1, hyp[0].1, hyp[1].1],
        dof: [h0.2, hyp[0].2, hyp[1].2],
        p_no_tilt: p0,
        ..empty
    };
    if p0.is_nan() || p0 >= ALPHA_TILT {
        return out;
    }
    // Per hypothesis: p of its χ², the tilt components (rad), their s.e., their p-values.
    let tq = t_quantile(0.975, fit.dof);
    let stats = |h: &(_, f64, usize, DMatrix<f64>), off: usize| {
        let th: &[f64; 6] = &h.0;
        let comp = [0, 1].map(|k| {
            let v = th[off + k];
            let se = h.3[(k, k)].max(0.0).sqrt();
            let p = if se > 0.0 {
                t_two_sided_p(v / se, fit.dof)
            } else {
                1.0
            };
            (v, se, p)
        });
        let n_sig = comp.iter().filter(|c| c.2 < ALPHA_TILT / 2.0).count();
        (chi2_sf(h.1, h.2), comp, n_sig)
    };
    let st = [stats(&hyp[0], 0), stats(&hyp[1], 3)];
    let acceptable = |i: usize| st[i].0 >= ALPHA_TILT && st[i].2 > 0;
    // Among the hypotheses that explain the difference, the one needing fewer tilt components
    // (a tilt about the line joining the bases is the same for both robots), then the smaller χ².
    let i = match (acceptable(0), acceptable(1)) {
        (true, true) => {
            if st[0].2 != st[1].2 {
                usize::from(st[1].2 < st[0].2)
            } else {
                usize::from(hyp[1].1 < hyp[0].1)
            }
        }
        (true, false) => 0,
        (false, true) => 1,
        (false, false) => usize::from(hyp[1].1 < hyp[0].1),
    };
    out.robot = Some(i as u8 + 1);
    out.alternative = (acceptable(0) && acceptable(1)).then_some(2 - i as u8);
    out.p_fit = st[i].0;
    for (k, &(v, se, p)) in st[i].1.iter().enumerate() {
        out.tilt_deg[k] = v.to_degrees();
        out.tilt_ci95_deg[k] = [(v - tq * se).to_degrees(), (v + tq * se).to_degrees()];
        out.tilt_p_value[k] = p;
    }
    if let Some(j) = out.alternative {
        let (_, comp, _) = &st[j as usize - 1];
        out.alternative_axes = (0..2)
            .filter(|&k| comp[k].2 < ALPHA_TILT / 2.0)
            .map(|k| if k == 0 { "x" } else { "y" })
            .collect();
    }
    out
}

/// The mount tilts [`mount_tilt_test`] names: the chosen robot's significant components.
fn mount_tilt_effects(test: &MountTiltTest) -> Vec<EffectReport> {
    let Some(robot) = test.robot else {
        return Vec::new();
    };
    if test.p_fit.is_nan() || test.p_fit < ALPHA_TILT {
        return Vec::new();
    }
    (0..2)
        .filter(|&k| test.tilt_p_value[k] < ALPHA_TILT / 2.0)
        .map(|k| {
            let axis = if k == 0 { "x" } else { "y" };
            EffectReport {
                kind: EffectKind::MountTilt,
                robot,
                joint: None,
                axis: Some(axis),
                value: test.tilt_deg[k],
                unit: EffectKind::MountTilt.unit(),
                ci95: test.tilt_ci95_deg[k],
                confounded_with: std::iter::once(format!("robot {robot} mount_tilt {axis}"))
                    .chain(test.alternative.iter().flat_map(|r| {
                        test.alternative_axes
                            .iter()
                            .map(move |a| format!("robot {r} mount_tilt {a}"))
                    }))
                    .collect(),
                p_value: test.tilt_p_value[k],
            }
        })
        .collect()
}

/// The base-frame motion a confounded candidate is equivalent to: its residual column regressed
/// on the 6 columns of `b1_from_b2` at the fit, expressed as a twist of the candidate's robot's
/// base (robot 2: the right perturbation of `b1_from_b2`, in b2 axes).
fn describe_confounding(
    model: &SessionModel<'_>,
    fit: &identify::IdentFit,
    cand: usize,
    robot: u8,
) -> String {
    let n = fit.points.len();
    let x = fit.b1_from_b2;
    let r_x = x.rotation.to_rotation_matrix().into_inner();
    let mut a = nalgebra::DMatrix::zeros(3 * n, 6);
    let mut b = nalgebra::DVector::zeros(3 * n);
    for (row, &i) in fit.points.iter().enumerate() {
        let Ok(e) = model.eval(i, &[], &[], &[cand]) else {
            return "a base-frame motion".into();
        };
        let y = x * e.p2_b2;
        a.fixed_view_mut::<3, 3>(3 * row, 0)
            .copy_from(&(-Matrix3::identity()));
        a.fixed_view_mut::<3, 3>(3 * row, 3)
            .copy_from(&y.coords.cross_matrix());
        let col: Vector3<f64> = e.jacobian.column(0).into_owned();
        let col = if robot == 1 { col } else { -(r_x * col) };
        b.fixed_rows_mut::<3>(3 * row).copy_from(&col);
    }
    let Ok(c) = a.svd(true, true).solve(&b, 1e-12) else {
        return "a base-frame motion".into();
    };
    let rho = Vector3::new(c[0], c[1], c[2]);
    let phi = Vector3::new(c[3], c[4], c[5]);
    // Twist in the robot's own base axes (robot 2: right perturbation X·exp(ξ2)).
    // Robot 1: a motion ξ1 of its base changes r by +ξ1 while the fit's left perturbation c
    // changes r by −c, so ξ1 = −c.
    let (rho_r, phi_r) = if robot == 1 {
        (-rho, -phi)
    } else {
        (
            r_x.transpose() * (rho + phi.cross(&x.translation.vector)),
            r_x.transpose() * phi,
        )
    };
    // A rotation moves points 1 m away by |φ|·1 m: compare with the translation.
    if phi_r.norm() * 1.0 > 0.1 * rho_r.norm() && phi_r.norm() > 0.0 {
        let u = phi_r.normalize();
        let name = if u.z.abs() > 0.99 {
            "base yaw"
        } else if u.z.abs() < 0.1 {
            "base tilt"
        } else {
            "base rotation"
        };
        let mut text = format!(
            "rotation of robot {robot}'s base about its ({:.3}, {:.3}, {:.3}) axis ({name})",
            u.x, u.y, u.z
        );
        if rho_r.norm() > 1e-3 * phi_r.norm() {
            let v = rho_r.normalize();
            text += &format!(
                " with a translation along ({:.3}, {:.3}, {:.3})",
                v.x, v.y, v.z
            );
        }
        text
    } else if rho_r.norm() > 0.0 {
        let v = rho_r.normalize();
        format!(
            "translation of robot {robot}'s base along its ({:.3}, {:.3}, {:.3}) axis",
            v.x, v.y, v.z
        )
    } else {
        "a base-frame motion".into()
    }
}

/// Runs the full diagnosis of a session on its cell (the cell's stated `[robotN.errors]`, if
/// any, are NOT used: the nominal models are the URDFs). Errors: a session that does not fit the
/// cell ([`check_session`]) or a model failure.
pub fn diagnose(
    cell: &Cell,
    session: &Session,
    options: &DiagnoseOptions,
) -> Result<DiagnoseReport, DiagnoseError> {
    check_session(cell, session, Path::new("<session>"))?;
    let cands = catalogue(cell.robot1.model.dof(), cell.robot2.model.dof());
    let (q1, q2) = joints(session);
    // The cell's noise at these configurations: residuals are whitened by it, so the F tests
    // hold their size under anisotropic alignment noise.
    let r_cell = cell.b1_from_b2.rotation.to_rotation_matrix().into_inner();
    let noise = NoiseModel::new(cell, &q1, &q2, &r_cell)?;
    let model = SessionModel::new(cell, &q1, &q2, &cands).with_weights(noise.whitening());
    let all: Vec<usize> = (0..cands.len()).collect();
    let sel = identify::forward_select(&model, &all, &options.selection)?;
    let base = &sel.baseline;
    let fit = &sel.fit;
    let n = session.points.len();
    let reference = zyz_from_rotation(&cell.b1_from_b2.rotation.to_rotation_matrix());
    // 1. Baseline against the cell's noise, simulated at these configurations.
    let mut p2_nom = Vec::with_capacity(n);
    let mut d = Vec::with_capacity(n);
    for i in 0..n {
        let nom = model.eval(i, &[], &[], &[])?;
        let ext = model.eval(i, &fit.params, &fit.values, &[])?;
        p2_nom.push(nom.p2_b2);
        // The deterministic discrepancy the nominal fit sees if the extended model is true.
        d.push((nom.p1_b1 - ext.p1_b1) - fit.b1_from_b2.rotation * (nom.p2_b2 - ext.p2_b2));
    }
    let zeros = vec![Vector3::zeros(); n];
    let mc = simulate_rms(
        &p2_nom,
        &base.b1_from_b2,
        &zeros,
        &noise,
        options.seed,
        options.trials,
    );
    let chi2 = |f: &identify::IdentFit| {
        if noise.sigma2_eff > 0.0 {
            chi2_sf(f.rss / noise.sigma2_eff, f.dof)
        } else if f.rss > 0.0 {
            0.0
        } else {
            1.0
        }
    };
    let chi2_p = chi2(base);
    let chi2_after = chi2(fit);
    // 4. Re-simulation with the extended model.
    let remc = simulate_rms(
        &p2_nom,
        &fit.b1_from_b2,
        &d,
        &noise,
        options.seed.wrapping_add(0x5eed),
        options.trials,
    );
    let partial = identify::partial_f_tests(&model, fit, &options.selection.fit)?;
    let mut effects: Vec<EffectReport> = fit
        .params
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let c = &cands[p];
            let f = c.kind.to_output();
            let (lo, hi) = fit.interval(k, 0.95);
            EffectReport {
                kind: c.kind,
                robot: c.robot,
                joint: c.joint.map(|j| j + 1),
                axis: c.axis.map(axis_name),
                value: fit.values[k] * f,
                unit: c.kind.unit(),
                ci95: [lo * f, hi * f],
                confounded_with: sel
                    .groups
                    .get(k)
                    .map(|g| g.iter().map(|&m| cands[m].label()).collect())
                    .unwrap_or_default(),
                p_value: partial[k].1,
            }
        })
        .collect();
    // Mount tilts: not from the residuals (they only turn the fit) but from the placement.
    let placement = placement_report(fit, cell, options.placement_sd_deg);
    effects.extend(mount_tilt_effects(&placement.mount_tilt));
    // 2. Families.
    let id = &sel.identifiability;
    let mut families = Vec::new();
    for robot in [1u8, 2] {
        for kind in [
            EffectKind::JointOffset,
            EffectKind::LinkLength,
            EffectKind::TipOffset,
            EffectKind::MountTilt,
            EffectKind::Compliance,
            EffectKind::JointScale,
        ] {
            let members: Vec<usize> = (0..cands.len())
                .filter(|&m| cands[m].robot == robot && cands[m].kind == kind)
                .collect();
            let fam = id.family(&members);
            let with = |st: IdentStatus| {
                members
                    .iter()
                    .filter(|&&m| id.params[m].status == st)
                    .map(|&m| cands[m].label())
                    .collect()
            };
            families.push(FamilyReport {
                robot,
                kind,
                size: fam.size,
                rank: fam.rank,
                condition: fam.condition.is_finite().then_some(fam.condition),
                singular_values: fam.singular_values,
                confounded_as: members
                    .iter()
                    .filter(|&&m| id.params[m].status == IdentStatus::ConfoundedWithBase)
                    .map(|&m| describe_confounding(&model, base, m, cands[m].robot))
                    .collect(),
                confounded_with_base: with(IdentStatus::ConfoundedWithBase),
                no_effect: with(IdentStatus::NoEffect),
            });
        }
    }
    let (truth_e_tran_mm, truth_e_rot_deg, truth_geodesic_deg) = match &options.truth {
        Some(t) => {
            let et = |x: &Isometry3<f64>| calib_core::e_tran(t, x) * 1000.0;
            let er = |x: &Isometry3<f64>| calib_core::e_rot(t, x).to_degrees();
            let eg = |x: &Isometry3<f64>| calib_core::geodesic_angle(t, x).to_degrees();
            (
                Some([et(&base.b1_from_b2), et(&fit.b1_from_b2)]),
                Some([er(&base.b1_from_b2), er(&fit.b1_from_b2)]),
                Some([eg(&base.b1_from_b2), eg(&fit.b1_from_b2)]),
            )
        }
        None => (None, None, None),
    };
    let steps = sel
        .steps
        .iter()
        .map(|s| {
            format!(
                "{}: {} (F = {:.2}, p = {:.2e} vs α/m = {:.2e} over {} screened; held-out RMS {:.4} → {:.4} mm; BIC {:.1} → {:.1})",
                cands[s.param].label(),
                if s.accepted { "accepted" } else { "rejected" },
                s.f_stat, s.p_value, s.threshold, s.screened,
                s.heldout_rms_before * 1000.0, s.heldout_rms_after * 1000.0, s.bic_before, s.bic_after
            )
        })
        .collect();
    let sigma = noise.sigma2_eff.sqrt();
    Ok(DiagnoseReport {
        effects,
        rms_before_mm: base.rms() * 1000.0,
        rms_after_mm: fit.rms() * 1000.0,
        heldout_rms_before_mm: sel.heldout_rms_before * 1000.0,
        heldout_rms_after_mm: sel.heldout_rms_after * 1000.0,
        b1_from_b2: PoseReport::from_isometry(&fit.b1_from_b2, reference),
        b1_from_b2_before: PoseReport::from_isometry(&base.b1_from_b2, reference),
        n_points: n,
        sigma_cell_mm: sigma * 1000.0,
        sigma_hat_before_mm: base.sigma_hat * 1000.0,
        sigma_hat_after_mm: fit.sigma_hat * 1000.0,
        predicted_rms_mm: quantile(&mc, 0.5) * 1000.0,
        predicted_rms_band_mm: [quantile(&mc, 0.05) * 1000.0, quantile(&mc, 0.95) * 1000.0],
        measured_rms_percentile: fraction_below(&mc, base.rms()),
        chi2_p_value: chi2_p,
        correlations: correlations(session, &base.residuals),
        correlations_after: correlations(session, &fit.residuals),
        chi2_p_value_after: chi2_after,
        families,
        min_detectable: identify::min_detectable(id, options.selection.alpha, sigma)
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(m, v)| DetectableReport {
                label: cands[m].label(),
                value: v * cands[m].kind.to_output(),
                unit: cands[m].kind.unit(),
            })
            .collect(),
        confounded_groups: id
            .groups
            .iter()
            .map(|g| g.iter().map(|&m| cands[m].label()).collect())
            .collect(),
        predicted_e_tran_mm: [
            base.predicted_translation_error() * 1000.0,
            fit.predicted_translation_error() * 1000.0,
        ],
        predicted_e_rot_deg: [
            base.predicted_rotation_error().to_degrees(),
            fit.predicted_rotation_error().to_degrees(),
        ],
        truth_e_tran_mm,
        truth_e_rot_deg,
        truth_geodesic_deg,
        resimulated_rms_before_mm: quantile(&remc, 0.5) * 1000.0,
        resimulated_percentile: fraction_below(&remc, base.rms()),
        resimulated_rms_band_mm: [
            quantile(&remc, 0.05) * 1000.0,
            quantile(&remc, 0.95) * 1000.0,
        ],
        rms_after_percentile: fraction_below(&mc, fit.rms()),
        placement,
        steps,
        converged: fit.converged(),
    })
}

/// Reads a session CSV for `cell` with sim-cell's reader, after a unit pre-check that names the
/// likely mistake (radians under `*_deg`, metres under `*_mm`), then [`check_session`].
pub fn load_session(path: &Path, cell: &Cell) -> Result<Session, DiagnoseError> {
    let text = std::fs::read_to_string(path).map_err(|e| io_err(path, e))?;
    let serr = |message: String| DiagnoseError::Session {
        path: path.to_path_buf(),
        message,
    };
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    if let Some(header) = lines.next() {
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let (mut max_deg, mut max_mm, mut rows) = (0.0f64, 0.0f64, 0usize);
        for line in lines {
            rows += 1;
            for (name, v) in names.iter().zip(line.split(',')) {
                let Ok(v) = v.trim().parse::<f64>() else {
                    continue;
                };
                if name.ends_with("_deg") {
                    max_deg = max_deg.max(v.abs());
                } else if name.ends_with("_mm") {
                    max_mm = max_mm.max(v.abs());
                }
            }
        }
        if rows > 0 && max_deg > 0.0 && max_deg <= std::f64::consts::PI + 1e-9 {
            return Err(serr(format!(
                "every joint angle is within ±{max_deg:.3} — these look like radians, but the columns are *_deg: convert them to degrees"
            )));
        }
        if rows > 0 && max_mm > 0.0 && max_mm < 10.0 {
            return Err(serr(format!(
                "every tip coordinate is within ±{max_mm:.4} — these look like metres, but the columns are *_mm: convert them to millimetres"
            )));
        }
    }
    let session = match Session::parse_csv(&text, path, cell) {
        Ok(s) => s,
        Err(e) => {
            return Err(match unit_hint(&text, cell) {
                Some(hint) => serr(format!("{e}\n{hint}")),
                None => e.into(),
            })
        }
    };
    check_session(cell, &session, path)?;
    Ok(session)
}

/// When a session's tips do not match FK of its joints, tries the usual unit mistakes on its
/// first rows (angles in radians under `*_deg`, tips in metres under `*_mm`) and says which one
/// makes every tried row consistent (within 1 mm), if any.
fn unit_hint(text: &str, cell: &Cell) -> Option<String> {
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let names: Vec<String> = lines
        .next()?
        .split(',')
        .map(|h| h.trim().to_string())
        .collect();
    let col = |n: &str| names.iter().position(|h| h == n);
    let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
    let q_cols = |r: u8, d: usize| -> Option<Vec<usize>> {
        (1..=d).map(|k| col(&format!("r{r}_q{k}_deg"))).collect()
    };
    let (c1, c2) = (q_cols(1, d1)?, q_cols(2, d2)?);
    let t_cols: Vec<usize> = [
        "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
    ]
    .iter()
    .map(|n| col(n))
    .collect::<Option<_>>()?;
    let rows: Vec<Vec<f64>> = lines
        .take(5)
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse().unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    let consistent = |angle_scale: f64, length_scale: f64| {
        rows.iter().all(|v| {
            let get = |c: &[usize]| {
                c.iter()
                    .map(|&i| v.get(i).copied().unwrap_or(f64::NAN) * angle_scale)
                    .collect::<Vec<f64>>()
            };
            let (q1, q2) = (get(&c1), get(&c2));
            let t: Vec<f64> = t_cols
                .iter()
                .map(|&i| v.get(i).copied().unwrap_or(f64::NAN) * length_scale)
                .collect();
            if !q1.iter().chain(&q2).chain(&t).all(|x| x.is_finite()) {
                return false;
            }
            let f1 = kinematics::base_from_tip_unchecked(
                &cell.robot1.model,
                &q1,
                &cell.robot1.flange_from_tip,
            );
            let f2 = kinematics::base_from_tip_unchecked(
                &cell.robot2.model,
                &q2,
                &cell.robot2.flange_from_tip,
            );
            (f1.translation.vector - Vector3::new(t[0], t[1], t[2])).norm() < 1e-3
                && (f2.translation.vector - Vector3::new(t[3], t[4], t[5])).norm() < 1e-3
        })
    };
    let deg = std::f64::consts::PI / 180.0;
    if consistent(1.0, 1e-3) {
        Some("the joint columns are consistent with the tips if read as RADIANS: the columns are *_deg, so convert the angles to degrees".into())
    } else if consistent(deg, 1.0) {
        Some("the tip columns are consistent with the joints if read as METRES: the columns are *_mm, so convert the tips to millimetres".into())
    } else if consistent(1.0, 1.0) {
        Some("the session is consistent if its angles are radians and its tips metres: the columns are *_deg and *_mm, so convert both".into())
    } else {
        None
    }
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> DiagnoseError {
    DiagnoseError::Io {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Finds joint `name`'s element in URDF text: `(start of "<joint", index of "</joint>")`.
fn joint_span(xml: &str, name: &str) -> Result<(usize, usize), String> {
    let mut from = 0;
    while let Some(i) = xml[from..].find("<joint") {
        let open = from + i;
        let end_tag = xml[open..]
            .find('>')
            .map(|e| open + e)
            .ok_or_else(|| format!("unterminated <joint> near byte {open}"))?;
        let tag = &xml[open..end_tag];
        if tag.contains(&format!("name=\"{name}\"")) || tag.contains(&format!("name='{name}'")) {
            let close = xml[open..]
                .find("</joint>")
                .map(|c| open + c)
                .ok_or_else(|| format!("joint `{name}` has no </joint>"))?;
            return Ok((open, close));
        }
        from = end_tag;
    }
    Err(format!("joint `{name}` not found in the URDF text"))
}

/// Byte range of an `<origin>` attribute's value (if present) and byte index of the `<origin`
/// tag (if present).
type OriginAttr = (Option<(usize, usize)>, Option<usize>);

/// Reads (and returns the byte range of) attribute `attr` of the `<origin>` element of the
/// joint at `span`; `None` when the joint has no `<origin>` or the origin lacks the attribute.
fn origin_attr(xml: &str, span: (usize, usize), attr: &str) -> Result<OriginAttr, String> {
    let block = &xml[span.0..span.1];
    let Some(o) = block.find("<origin") else {
        return Ok((None, None));
    };
    let o_abs = span.0 + o;
    let o_end = xml[o_abs..]
        .find('>')
        .map(|e| o_abs + e)
        .ok_or("unterminated <origin>")?;
    let pat = format!("{attr}=\"");
    match xml[o_abs..o_end].find(&pat) {
        Some(a) => {
            let start = o_abs + a + pat.len();
            let end = start + xml[start..].find('"').ok_or("unterminated attribute")?;
            Ok((Some((start, end)), Some(o_abs)))
        }
        None => Ok((None, Some(o_abs))),
    }
}

fn parse3(text: &str, what: &str) -> Result<Vector3<f64>, String> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("{what}: bad number `{t}`"))
        })
        .collect::<Result<_, _>>()?;
    if v.len() != 3 {
        return Err(format!("{what}: needs 3 numbers, found {}", v.len()));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

/// Sets the `<origin>` attribute `attr` (`xyz` or `rpy`) of the joint at `span` to `v`
/// (inserting the attribute, or an `<origin>` element, when missing).
fn set_origin_attr(
    xml: &mut String,
    span: (usize, usize),
    attr: &str,
    v: &Vector3<f64>,
) -> Result<(), String> {
    let text = format!("{:.9} {:.9} {:.9}", v.x, v.y, v.z);
    match origin_attr(xml, span, attr)? {
        (Some((s, e)), _) => xml.replace_range(s..e, &text),
        (None, Some(o)) => xml.insert_str(o + "<origin".len(), &format!(" {attr}=\"{text}\"")),
        (None, None) => {
            let at = span.0 + xml[span.0..].find('>').ok_or("unterminated <joint>")? + 1;
            xml.insert_str(at, &format!("\n    <origin {attr}=\"{text}\"/>"));
        }
    }
    Ok(())
}

/// Applies the identified errors of one robot to its URDF text, keeping everything else byte for
/// byte: a `link_length` error is added to the joint's `<origin xyz>`; a `joint_offset` δ is
/// folded into the joint's `<origin rpy>` (`R(rpy') = R(rpy)·Rot(axis, δ)`, exact for any URDF
/// consumer) and recorded as `<calibration rising="δ"/>` (rad; informational, as in ROS, where
/// calibration does not move the kinematics). `errors` are in SI units.
pub fn correct_urdf_text(
    xml: &str,
    model: &kinematics::RobotModel,
    errors: &KinematicErrors,
) -> Result<String, String> {
    let mut out = xml.to_string();
    for (k, joint) in model.joints().iter().enumerate() {
        let dxyz = errors
            .origin_xyz
            .get(k)
            .copied()
            .unwrap_or_else(Vector3::zeros);
        let offset = errors.joint_offset.get(k).copied().unwrap_or(0.0);
        if dxyz == Vector3::zeros() && offset == 0.0 {
            continue;
        }
        let name = &joint.name;
        if dxyz != Vector3::zeros() {
            let span = joint_span(&out, name)?;
            let xyz = match origin_attr(&out, span, "xyz")?.0 {
                Some((s, e)) => parse3(&out[s..e], &format!("joint `{name}` origin xyz"))?,
                None => Vector3::zeros(),
            };
            set_origin_attr(&mut out, span, "xyz", &(xyz + dxyz))?;
        }
        if offset != 0.0 {
            let span = joint_span(&out, name)?;
            let rpy = match origin_attr(&out, span, "rpy")?.0 {
                Some((s, e)) => parse3(&out[s..e], &format!("joint `{name}` origin rpy"))?,
                None => Vector3::zeros(),
            };
            let r = kinematics::rotation_from_rpy(&rpy)
                * nalgebra::Rotation3::from_axis_angle(&joint.axis, offset);
            let (roll, pitch, yaw) = r.euler_angles();
            set_origin_attr(&mut out, span, "rpy", &Vector3::new(roll, pitch, yaw))?;
            let span = joint_span(&out, name)?;
            out.insert_str(
                span.1,
                &format!(
                    "  <!-- handclasp diagnose: joint offset {offset:.9} rad folded into origin rpy -->\n    <calibration rising=\"{offset:.9}\"/>\n  "
                ),
            );
        }
    }
    Ok(out)
}

/// The identified errors of both robots (SI) from a report's effects.
pub fn effects_to_errors(
    cell: &Cell,
    effects: &[EffectReport],
) -> (KinematicErrors, KinematicErrors) {
    let mut e = [
        KinematicErrors::zero(cell.robot1.model.dof()),
        KinematicErrors::zero(cell.robot2.model.dof()),
    ];
    let cands = catalogue(cell.robot1.model.dof(), cell.robot2.model.dof());
    for eff in effects {
        let hit = cands.iter().find(|c| {
            c.kind == eff.kind
                && c.robot == eff.robot
                && c.joint.map(|j| j + 1) == eff.joint
                && c.axis.map(axis_name) == eff.axis
        });
        if let Some(c) = hit {
            e[(c.robot - 1) as usize].set(c.param, eff.value / c.kind.to_output());
        }
    }
    let [e1, e2] = e;
    (e1, e2)
}

/// Writes the extended model to `dir`: `robot1_corrected.urdf`, `robot2_corrected.urdf` (joint
/// origins and offsets, see [`correct_urdf_text`]), `cell_corrected.toml` (the calibrated
/// `b1_from_b2`, corrected tip offsets, URDF paths to the corrected files, and the joint-scale and
/// compliance errors, which URDF cannot express, as `[robotN.errors]`) and `effects.json`.
/// Returns the files written.
pub fn export_corrected(
    cell: &Cell,
    report: &DiagnoseReport,
    b1_from_b2: &Isometry3<f64>,
    dir: &Path,
) -> Result<Vec<PathBuf>, DiagnoseError> {
    std::fs::create_dir_all(dir)
        .map_err(|e| io_err(dir, format!("cannot create the export folder: {e}")))?;
    let (e1, e2) = effects_to_errors(cell, &report.effects);
    let mut written = Vec::new();
    let mut out = cell.clone();
    out.base_dir = dir.to_path_buf();
    out.b1_from_b2 = *b1_from_b2;
    for (robot, errors) in [(1u8, &e1), (2u8, &e2)] {
        let setup = cell.robot(robot);
        let xml =
            std::fs::read_to_string(&setup.urdf_path).map_err(|e| io_err(&setup.urdf_path, e))?;
        let corrected = correct_urdf_text(&xml, &setup.model, errors)
            .map_err(|m| io_err(&setup.urdf_path, m))?;
        let file = format!("robot{robot}_corrected.urdf");
        let path = dir.join(&file);
        std::fs::write(&path, &corrected).map_err(|e| io_err(&path, e))?;
        let model = kinematics::RobotModel::from_urdf_str(&corrected, &setup.tool_link)
            .map_err(|e| io_err(&path, format!("the corrected URDF does not load: {e}")))?;
        written.push(path.clone());
        let r = if robot == 1 {
            &mut out.robot1
        } else {
            &mut out.robot2
        };
        r.model = model;
        r.urdf = file;
        r.urdf_path = path;
        r.flange_from_tip = setup.flange_from_tip + errors.tip;
        let mut rest = KinematicErrors::zero(setup.model.dof());
        rest.joint_scale = errors.joint_scale.clone();
        rest.compliance = errors.compliance.clone();
        r.errors = rest;
    }
    // Robot 2's gravity follows the calibrated placement.
    out.robot2.g_base = out.b1_from_b2.rotation.inverse() * out.robot1.g_base;
    let cell_path = dir.join("cell_corrected.toml");
    let text = format!(
        "# Written by `handclasp diagnose --export`: the extended model (corrected URDFs, tip offsets,\n# calibrated b1_from_b2; joint scale and compliance as [robotN.errors]).\n{}",
        out.to_toml_string()
    );
    std::fs::write(&cell_path, text).map_err(|e| io_err(&cell_path, e))?;
    written.push(cell_path);
    let eff_path = dir.join("effects.json");
    let eff = serde_json::to_string_pretty(&report.effects).map_err(|e| io_err(&eff_path, e))?;
    std::fs::write(&eff_path, eff).map_err(|e| io_err(&eff_path, e))?;
    written.push(eff_path);
    Ok(written)
}
/// Readable text of a report.
pub fn render_text(r: &DiagnoseReport) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "handclasp diagnose: {} points, cell noise σ = {:.3} mm per axis (alignment, repeatability, encoders; effective)",
        r.n_points, r.sigma_cell_mm
    );
    let _ = writeln!(s, "\n1. Baseline (nominal models)");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} mm; predicted under the cell's noise {:.3} mm (5–95%: {:.3}–{:.3}); measured at MC percentile {:.1}%",
        r.rms_before_mm, r.predicted_rms_mm, r.predicted_rms_band_mm[0], r.predicted_rms_band_mm[1], 100.0 * r.measured_rms_percentile
    );
    let _ = writeln!(
        s,
        "   χ² test of RSS/σ²: p = {:.3e} ({}); σ̂ = {:.3} mm per axis",
        r.chi2_p_value,
        if r.chi2_p_value < 0.05 {
            "the nominal model does NOT explain the data"
        } else {
            "consistent with noise"
        },
        r.sigma_hat_before_mm
    );
    if r.correlations.is_empty() {
        let _ = writeln!(s, "   no significant residual correlation (Bonferroni 5%)");
    }
    for c in &r.correlations {
        let _ = writeln!(
            s,
            "   residual {} correlates with {}: r = {:+.2} (adjusted p = {:.1e})",
            c.residual, c.against, c.r, c.p_adjusted
        );
    }
    let _ = writeln!(
        s,
        "\n2. Identifiability from these handclasps (rank / size, condition)"
    );
    for f in &r.families {
        let cond = f.condition.map_or("∞".to_string(), |c| format!("{c:.1}"));
        let _ = write!(
            s,
            "   robot {} {:<13} rank {}/{} cond {}",
            f.robot,
            f.kind.name(),
            f.rank,
            f.size,
            cond
        );
        if !f.confounded_with_base.is_empty() {
            let pairs: Vec<String> = f
                .confounded_with_base
                .iter()
                .zip(&f.confounded_as)
                .map(|(c, a)| format!("{c} ≡ {a}"))
                .collect();
            let _ = write!(s, "; confounded with the base frame: {}", pairs.join("; "));
        }
        if !f.no_effect.is_empty() {
            let _ = write!(s, "; no effect here: {}", f.no_effect.join(", "));
        }
        let _ = writeln!(s);
    }
    for g in &r.confounded_groups {
        let _ = writeln!(s, "   indistinguishable: {}", g.join(" ≡ "));
    }
    let _ = writeln!(s, "\n3. Model selection");
    for st in &r.steps {
        let _ = writeln!(s, "   {st}");
    }
    if r.effects.is_empty() {
        let _ = writeln!(s, "   no significant effect: noise alone explains the data");
    }
    for e in &r.effects {
        let _ = writeln!(
            s,
            "   {} robot {}{}{}: {:+.4} {} (95%: {:+.4} … {:+.4}){}",
            e.kind.name(),
            e.robot,
            e.joint.map_or(String::new(), |j| format!(" joint {j}")),
            e.axis.map_or(String::new(), |a| format!(" axis {a}")),
            e.value,
            e.unit,
            e.ci95[0],
            e.ci95[1],
            if e.kind == EffectKind::MountTilt {
                format!(
                    " [from the placement check, section 5{}]",
                    if e.confounded_with.len() > 1 {
                        format!("; or any of: {}", e.confounded_with.join(", "))
                    } else {
                        String::new()
                    }
                )
            } else if e.confounded_with.len() > 1 {
                format!(" [or any of: {}]", e.confounded_with.join(", "))
            } else {
                String::new()
            }
        );
    }
    let _ = writeln!(s, "\n4. Gain");
    let _ = writeln!(
        s,
        "   residual RMS {:.3} → {:.3} mm; held-out (K-fold) {:.3} → {:.3} mm",
        r.rms_before_mm, r.rms_after_mm, r.heldout_rms_before_mm, r.heldout_rms_after_mm
    );
    let _ = writeln!(
        s,
        "   predicted b1_from_b2 accuracy: {:.3} → {:.3} mm, {:.4} → {:.4} deg (1σ)",
        r.predicted_e_tran_mm[0],
        r.predicted_e_tran_mm[1],
        r.predicted_e_rot_deg[0],
        r.predicted_e_rot_deg[1]
    );
    if let (Some(t), Some(a), Some(g)) =
        (r.truth_e_tran_mm, r.truth_e_rot_deg, r.truth_geodesic_deg)
    {
        let _ = writeln!(
            s,
            "   against the truth: e_tran {:.3} → {:.3} mm, e_rot {:.4} → {:.4} deg (geodesic {:.4} → {:.4} deg)",
            t[0], t[1], a[0], a[1], g[0], g[1]
        );
    }
    let _ = writeln!(
        s,
        "   re-simulated with the extended model: nominal-fit RMS {:.3} mm predicted vs {:.3} measured (percentile {:.1}%)",
        r.resimulated_rms_before_mm, r.rms_before_mm, 100.0 * r.resimulated_percentile
    );
    let _ = writeln!(
        s,
        "   extended model's residual RMS at percentile {:.1}% of noise-only simulations of a correct model; χ² p = {:.3}; {} significant residual correlation(s) left",
        100.0 * r.rms_after_percentile,
        r.chi2_p_value_after,
        r.correlations_after.len()
    );
    let _ = writeln!(
        s,
        "   b1_from_b2: xyz {:.3?} mm, zyz {:.4?} deg",
        r.b1_from_b2.xyz_mm, r.b1_from_b2.zyz_deg
    );
    let p = &r.placement;
    let _ = writeln!(
        s,
        "\n5. Placement against the cell's b1_from_b2 (mount tilts: invisible in the residuals)"
    );
    let _ = writeln!(
        s,
        "   turn of base 2 about its x: {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); about its y: {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); about its z: {:+.4} deg",
        p.tilt_b2_deg[0],
        p.tilt_b2_ci95_deg[0][0],
        p.tilt_b2_ci95_deg[0][1],
        p.tilt_b2_p_value[0],
        p.tilt_b2_deg[1],
        p.tilt_b2_ci95_deg[1][0],
        p.tilt_b2_ci95_deg[1][1],
        p.tilt_b2_p_value[1],
        p.yaw_b2_deg
    );
    let _ = writeln!(
        s,
        "   translation minus the cell's: {:+.3?} mm (s.e. {:.3?} mm)",
        p.dxyz_mm, p.dxyz_se_mm
    );
    if p.tilt_significant {
        let _ = writeln!(
            s,
            "   significant turn (Bonferroni 5%): as a turn of robot 2's base as above, or of robot 1's by {:+.4?} deg \
             about its x, y, z (which would also move the translation by −a1 × t)",
            p.robot1_equivalent_deg
        );
    } else {
        let _ = writeln!(s, "   no significant turn against the cell's placement");
    }
    let m = &p.mount_tilt;
    let _ = writeln!(
        s,
        "   mount-tilt test (rotation and translation; base yaws are nuisances): χ² no tilt {:.2} ({} dof, p = {:.2e}), \
         robot 1 tilted {:.2} ({} dof), robot 2 tilted {:.2} ({} dof)",
        m.chi2[0], m.dof[0], m.p_no_tilt, m.chi2[1], m.dof[1], m.chi2[2], m.dof[2]
    );
    match m.robot {
        None => {
            let _ = writeln!(
                s,
                "   no mount tilt (level {ALPHA_TILT}): the cell's placement explains the fit up to base yaws"
            );
        }
        Some(r) if m.p_fit < ALPHA_TILT => {
            let _ = writeln!(
                s,
                "   the placement differs from the cell's (p = {:.2e}) but no mount tilt explains it (best: robot {r}, \
                 χ² p = {:.2e}): a wrong cell placement or a base-frame translation; nothing named",
                m.p_no_tilt, m.p_fit
            );
        }
        Some(r) => {
            let _ = writeln!(
                s,
                "   robot {r}'s mount is tilted: x {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}), y {:+.4} deg (95%: {:+.4} … {:+.4}, p = {:.2e}); \
                 significant components (p < {}) are named in 3.{}",
                m.tilt_deg[0], m.tilt_ci95_deg[0][0], m.tilt_ci95_deg[0][1], m.tilt_p_value[0],
                m.tilt_deg[1], m.tilt_ci95_deg[1][0], m.tilt_ci95_deg[1][1], m.tilt_p_value[1],
                ALPHA_TILT / 2.0,
                m.alternative.map_or(String::new(), |a| format!(
                    " (robot {a}'s tilt about {} explains it as well — a turn about the line joining the bases; \
                     the fewer components chosen)",
                    m.alternative_axes.join(", ")
                ))
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The corrected URDF (offsets folded into origin rpy, lengths added to origin xyz) gives the
    /// same tips as the nominal URDF with the error model, at random postures.
    #[test]
    fn corrected_urdf_matches_the_error_model() {
        let cell = Cell::default_floor_floor();
        for robot in [&cell.robot1, &cell.robot2] {
            let dof = robot.model.dof();
            let mut e = KinematicErrors::zero(dof);
            for k in 0..dof {
                e.set(
                    ErrorParam::JointOffset { joint: k },
                    1e-3 * (k as f64 + 1.0),
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::X,
                    },
                    -2e-4 * k as f64,
                );
                e.set(
                    ErrorParam::OriginXyz {
                        joint: k,
                        axis: Axis::Z,
                    },
                    3e-4,
                );
            }
            let xml = std::fs::read_to_string(&robot.urdf_path).expect("URDF");
            let fixed = correct_urdf_text(&xml, &robot.model, &e).expect("corrected");
            assert!(fixed.contains("<calibration rising="));
            let corrected =
                kinematics::RobotModel::from_urdf_str(&fixed, &robot.tool_link).expect("loads");
            let mut rng = crate::trial_rng(3, 0);
            for _ in 0..20 {
                let q: Vec<f64> = robot
                    .model
                    .joints()
                    .iter()
                    .map(|j| rng.random_range(j.lower.max(-2.0)..j.upper.min(2.0)))
                    .collect();
                let want = kinematics::true_base_from_tip(
                    &robot.model,
                    &e,
                    &q,
                    &robot.flange_from_tip,
                    &robot.g_base,
                )
                .expect("fk");
                let got =
                    kinematics::base_from_tip(&corrected, &q, &robot.flange_from_tip).expect("fk");
                // The text carries 9 decimals (1 nm, 1 nrad): agreement to 1e-8 m.
                let d = (want.translation.vector - got.translation.vector).norm();
                assert!(d < 1e-8, "{}: {d} m", robot.model.name());
            }
        }
    }

    #[test]
    fn catalogue_covers_every_kind_once_per_member() {
        let c = catalogue(7, 6);
        // Per robot: offsets + 3 lengths per joint + 3 tip + 2 tilts + compliance + scale.
        assert_eq!(c.len(), (7 * 6 + 5) + (6 * 6 + 5));
        let labels: std::collections::HashSet<String> = c.iter().map(Candidate::label).collect();
        assert_eq!(labels.len(), c.len());
    }
}

//! The one-call whole-cell calibration a CLI needs: starting values, base-parameter reduction,
//! MAP fit with blunder screening, and a serialisable report.

use nalgebra::Isometry3;
use serde::Serialize;

use super::blunders::{fit_screened, RejectedRow, ScreenOptions};
use super::reduce::{reduce, Reduction, ReductionEntry};
use super::solve::{CellFit, FittedParam, SolveOptions, StopReason};
use super::{initial_estimate, CellFitError, CellProblem};

/// Result of [`calibrate_cell`].
#[derive(Debug, Clone)]
pub struct CellCalibration {
    /// The MAP fit on the reduced unknowns without the rejected rows.
    pub fit: CellFit,
    /// What the data cannot determine (dropped or merged) and why.
    pub reduction: Reduction,
    /// Rejected blunders.
    pub rejected: Vec<RejectedRow>,
}

/// A serialisable summary of a calibration (SI units: m, rad; field names say so).
#[derive(Debug, Clone, Serialize)]
pub struct CalibrationReport {
    /// Base 2 in base 1 (translation m, unit quaternion).
    pub b1_from_b2: Isometry3<f64>,
    /// Every fitted unknown with prior and posterior σ.
    pub parameters: Vec<FittedParam>,
    /// Dropped / merged parameters and why.
    pub unidentifiable: Vec<ReductionEntry>,
    /// Rejected rows with their size in σ.
    pub rejected_points: Vec<RejectedRow>,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// Solver iterations of the final fit.
    pub iterations: usize,
    /// Data χ² of the final fit and its residual rows.
    pub data_chi2: f64,
    /// Residual rows used.
    pub residual_rows: usize,
}

impl CellCalibration {
    /// The serialisable summary.
    pub fn report(&self, problem: &CellProblem) -> CalibrationReport {
        CalibrationReport {
            b1_from_b2: self.fit.estimate.b1_from_b2,
            parameters: self.fit.parameters(problem),
            unidentifiable: self.reduction.dropped.clone(),
            rejected_points: self.rejected.clone(),
            stopped: self.fit.stopped,
            iterations: self.fit.iterations,
            data_chi2: self.fit.data_chi2,
            residual_rows: self.fit.residual_rows,
        }
    }
}

/// Calibrates the whole cell: starting values ([`initial_estimate`]), base-parameter reduction
/// at the start ([`reduce`]), then the screened MAP fit ([`fit_screened`]) on the reduced
/// unknowns.
///
/// Errors: invalid input, no starting placement, model failures, or too few rows after
/// rejecting blunders (naming the rows to re-record).
///
/// # Examples
/// Two identical 3-joint arms, robot 2's base 1.4 m along robot 1's x axis and turned by π
/// about z. Robot 2 visits 12 configurations; robot 1 meets each tip (inverse kinematics),
/// so the rows are noise-free handclasps of nominal robots. The fit recovers the placement.
/// ```
/// use calib_core::whole_cell::{
///     calibrate_cell, CellProblem, CellRobot, Noise3, Observation, ObservationKind,
///     ScreenOptions, SolveOptions, StopReason, Tolerance, Tool,
/// };
/// use kinematics::{base_from_tip, ik_tip_position, IkOptions, RobotModel};
/// use nalgebra::{Isometry3, Point3, Vector3};
///
/// const ARM: &str = r#"<robot name="arm">
///   <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool0"/>
///   <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
///     <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
///   <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
///     <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
///   <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
///     <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
///   <joint name="l3-tool0" type="fixed"><parent link="l3"/><child link="tool0"/>
///     <origin xyz="0.4 0 0"/></joint>
/// </robot>"#;
///
/// let model = RobotModel::from_urdf_str(ARM, "tool0")?;
/// let tool = Tool { name: "tip".into(), flange_from_tip: Vector3::new(0.0, 0.0, 0.1) };
/// let robot = |g_base| CellRobot {
///     model: model.clone(),
///     tools: vec![tool.clone()],
///     g_base,
///     tolerance: Tolerance::default(),
/// };
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.4, 0.0, 0.0), Vector3::new(0.0, 0.0, std::f64::consts::PI));
/// let g_b1 = Vector3::new(0.0, 0.0, -9.81);
///
/// let mut observations = Vec::new();
/// for a in [-0.3, 0.0, 0.3] {
///     for (b, c) in [(-0.4, 0.3), (-0.4, 0.9), (0.2, 0.3), (0.2, 0.9)] {
///         let q2 = vec![a, b, c];
///         let p_b2 = base_from_tip(&model, &q2, &tool.flange_from_tip)?.translation.vector;
///         let p_b1 = b1_from_b2 * Point3::from(p_b2);
///         let sol = ik_tip_position(&model, &p_b1, &tool.flange_from_tip, &IkOptions::default())?;
///         assert!(sol.reachable());
///         observations.push(Observation {
///             row: observations.len() + 1,
///             kind: ObservationKind::Coincident {
///                 q1: sol.q,
///                 q2,
///                 tool1: 0,
///                 tool2: 0,
///                 noise: Noise3::Isotropic { sigma_m: 1e-4 },
///             },
///         });
///     }
/// }
/// let problem = CellProblem {
///     robot1: robot(g_b1),
///     robot2: robot(b1_from_b2.rotation.inverse() * g_b1),
///     observations,
///     trackers: vec![],
///     planes: vec![],
///     contacts: vec![],
/// };
///
/// let cal = calibrate_cell(&problem, &SolveOptions::default(), &ScreenOptions::default())?;
/// assert_eq!(cal.fit.stopped, StopReason::Converged);
/// assert!(cal.rejected.is_empty());
/// let fitted = cal.fit.estimate.b1_from_b2;
/// // Noise-free data: the placement is recovered to well below the stated σ (0.1 mm).
/// assert!((fitted.translation.vector - b1_from_b2.translation.vector).norm() < 1e-6);
/// assert!(fitted.rotation.angle_to(&b1_from_b2.rotation) < 1e-6);
/// println!("{} parameters dropped or merged", cal.reduction.dropped.len());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn calibrate_cell(
    problem: &CellProblem,
    solve: &SolveOptions,
    screen: &ScreenOptions,
) -> Result<CellCalibration, CellFitError> {
    problem.check()?;
    let all: Vec<usize> = (0..problem.observations.len()).collect();
    let start = initial_estimate(problem, solve.initial_b1_from_b2, &all)?;
    let reduction = reduce(problem, &start, &all)?;
    let screened = fit_screened(problem, Some(reduction.layout.clone()), solve, screen)?;
    Ok(CellCalibration {
        fit: screened.fit,
        reduction,
        rejected: screened.rejected,
    })
}

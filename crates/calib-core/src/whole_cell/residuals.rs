//! Residuals of each observation kind and their analytic Jacobians ([`Evaluator`]); the maths
//! is in the module documentation of [`crate::whole_cell`].

use std::borrow::Cow;
use std::sync::OnceLock;

use kinematics::{
    branch_deflections, branch_regressor, branch_torques, is_branch_param, tip_error_jacobian,
    true_base_from_tip, true_tip_with_error_jacobian, Axis, ErrorParam, KinematicErrors,
    KinematicsError, PreparedTip,
};
use nalgebra::{DMatrix, DVector, Point3, Unit, Vector3};

use super::cell::{robot_slot, CellFitError, CellRobot, Tool};
use super::layout::{tangent_basis, CellEstimate, ParamLayout};
use super::observations::{CellProblem, Observation, ObservationKind};
use crate::Robot;

/// Smallest `‖n1_b1 − n2_b1‖` of a face contact (2 for flush faces): below it the two
/// outward normals point nearly the same way and the mean normal `n̄` is undefined.
pub const MIN_FACE_NORMAL_SUM: f64 = 1e-6;

/// Maps a kinematics error of `robot` at observation `row` to the fit's error.
fn kinematics_error(robot: Robot, row: usize) -> impl Fn(KinematicsError) -> CellFitError + Copy {
    move |e| CellFitError::Kinematics {
        row,
        message: format!("{robot}: {e}"),
    }
}

/// Sparse 3-row Jacobian: (column, ∂/∂column).
type Cols3 = Vec<(usize, Vector3<f64>)>;

/// Robot 1's and robot 2's tips in b1 with their Jacobian columns.
type TwoTips = ((Vector3<f64>, Cols3), (Vector3<f64>, Cols3));

/// The other arm's load on a shared trunk at one observation ([`kinematics::trunk`]): the
/// deflection it adds to each trunk joint (rad, added to the joint's zero offset), its gravity
/// torques (N·m, for the trunk joints' physical compliance columns) and, with the Jacobian, the
/// other arm's branch coefficients' columns as (layout column, trunk joint, factor): the tip's
/// column is the trunk joint's offset column times the factor.
struct TrunkLoad {
    deflection: Vec<f64>,
    torque: Vec<f64>,
    branch: Vec<(usize, usize, f64)>,
}

/// A linearised observation: residuals and Jacobian rows (unwhitened and the whitening).
#[derive(Debug, Clone)]
pub struct ObservationLinearisation {
    /// Residuals (1 or 3), m, unwhitened.
    pub residual: DVector<f64>,
    /// Jacobian rows (1 or 3) × layout columns, unwhitened.
    pub jacobian: DMatrix<f64>,
    /// Whitening matrix (1×1 or 3×3): `W·r` has unit covariance.
    pub whitening: DMatrix<f64>,
}

/// One robot's kinematic errors with one tool's fitted tip at an estimate, formed once per
/// estimate instead of at every observation ([`AtEstimate`]).
struct ToolErrors<'m> {
    /// The errors, `tip` the tool's fitted tip error.
    errors: KinematicErrors,
    /// These errors with the tool's offset, the robot's gravity and the evaluator's Jacobian
    /// parameters of the robot, checked and prepared ([`PreparedTip`]) when they pass the
    /// checks: then each observation checks only its joint values and walks the prepared chain
    /// (the same values and, on failure, the same errors as the checked functions, which run
    /// otherwise).
    prepared: Option<PreparedTip<'m>>,
}

/// An estimate with each robot's kinematic errors for each of its tools formed and checked at
/// most once (on first use, from any thread), so that evaluating many observations at one
/// estimate does not copy and re-check the robots' errors at each (see [`Evaluator::at`]).
pub struct AtEstimate<'e> {
    est: &'e CellEstimate,
    /// Per robot slot, per tool.
    tools: [Vec<OnceLock<ToolErrors<'e>>>; 2],
}

impl<'e> AtEstimate<'e> {
    /// The estimate.
    pub fn estimate(&self) -> &'e CellEstimate {
        self.est
    }
}

/// Evaluates residuals and analytic Jacobians of observations at an estimate.
pub struct Evaluator<'a> {
    problem: &'a CellProblem,
    layout: &'a ParamLayout,
    /// Jacobian parameter lists per robot: fitted kin params then tip x, y, z.
    jac_params: [Vec<ErrorParam>; 2],
    /// Smallest and largest source row of each tracker group (its drift's order span).
    tracker_span: Vec<(usize, usize)>,
}

impl<'a> Evaluator<'a> {
    /// An evaluator of `problem` with unknowns `layout`.
    pub fn new(problem: &'a CellProblem, layout: &'a ParamLayout) -> Self {
        let jp = |slot: usize| {
            let mut v: Vec<ErrorParam> = layout.robots[slot].kin.iter().map(|k| k.0).collect();
            v.extend(Axis::ALL.map(|axis| ErrorParam::Tip { axis }));
            v
        };
        Self {
            problem,
            layout,
            jac_params: [jp(0), jp(1)],
            tracker_span: (0..problem.trackers.len())
                .map(|g| problem.tracker_row_span(g))
                .collect(),
        }
    }

    /// `est` prepared for evaluating many observations: each robot's errors per tool are formed
    /// and checked once, on first use ([`AtEstimate`]). The `_at` methods take it; the methods
    /// that take the estimate prepare it for their one call.
    pub fn at<'e>(&self, est: &'e CellEstimate) -> AtEstimate<'e>
    where
        'a: 'e,
    {
        let slots = |robot: Robot| {
            (0..self.problem.robot(robot).tools.len())
                .map(|_| OnceLock::new())
                .collect()
        };
        AtEstimate {
            est,
            tools: [slots(Robot::One), slots(Robot::Two)],
        }
    }

    /// `robot`'s cell robot, the definition of its `tool` and its kinematic errors with that
    /// tool's fitted tip at `at`; an error naming `row` when the robot has no such tool.
    fn tool_context<'s, 'e>(
        &self,
        at: &'s AtEstimate<'e>,
        robot: Robot,
        tool: usize,
        row: usize,
    ) -> Result<(&'a CellRobot, &'a Tool, &'s ToolErrors<'e>), CellFitError>
    where
        'a: 'e,
    {
        let rb = self.problem.robot(robot);
        let no_tool = || {
            CellFitError::InvalidInput(format!("observation row {row}: {robot} has no tool {tool}"))
        };
        let tool_def = rb.tools.get(tool).ok_or_else(no_tool)?;
        let slot = robot_slot(robot);
        let cell = at.tools[slot].get(tool).ok_or_else(no_tool)?;
        let prepared = cell.get_or_init(|| {
            let errors = at.est.robot(robot).errors_for_tool(tool);
            let prepared = PreparedTip::new(
                &rb.model,
                &errors,
                &tool_def.flange_from_tip,
                &rb.g_base,
                &self.jac_params[slot],
            )
            .ok();
            ToolErrors { errors, prepared }
        });
        Ok((rb, tool_def, prepared))
    }

    /// The other arm's load on the trunk when `robot`'s tip is evaluated with the other arm at
    /// `q_other` (`None`: not a shared-trunk cell, or the row does not give the other arm's
    /// joints), with the branch columns when `want_jac`. The other arm's physical compliance
    /// part uses the trunk joints' compliance of `errors` (`robot`'s copy of the shared values).
    fn trunk_load(
        &self,
        est: &CellEstimate,
        robot: Robot,
        errors: &KinematicErrors,
        q_other: Option<&[f64]>,
        want_jac: bool,
        row: usize,
    ) -> Result<Option<TrunkLoad>, CellFitError> {
        let k = self.problem.robot2.shared_joints;
        let Some(q_other) = q_other.filter(|_| k > 0) else {
            return Ok(None);
        };
        let other = robot.other();
        let orb = self.problem.robot(other);
        let other_errors = &est.robot(other).errors;
        let kin_err = kinematics_error(other, row);
        let mut deflection = branch_deflections(
            &orb.model,
            &other_errors.lumped_compliance,
            q_other,
            &orb.g_base,
            k,
        )
        .map_err(kin_err)?;
        let compliant = errors.compliance[..k].iter().any(|&c| c != 0.0);
        let wants_torque = want_jac
            && self.layout.robots[robot_slot(robot)]
                .kin
                .iter()
                .any(|(p, _)| matches!(p, ErrorParam::Compliance { joint } if *joint < k));
        let torque = if compliant || wants_torque {
            branch_torques(&orb.model, q_other, &orb.g_base, k).map_err(kin_err)?
        } else {
            vec![0.0; k]
        };
        for (j, d) in deflection.iter_mut().enumerate() {
            *d += errors.compliance[j] * torque[j];
        }
        let mut branch = Vec::new();
        if want_jac {
            let lay = &self.layout.robots[robot_slot(other)];
            let (params, cols): (Vec<ErrorParam>, Vec<usize>) = lay
                .kin
                .iter()
                .filter(|(p, _)| is_branch_param(p, k))
                .copied()
                .unzip();
            if !params.is_empty() {
                let reg = branch_regressor(&orb.model, q_other, &orb.g_base, k, &params)
                    .map_err(kin_err)?;
                branch = cols
                    .into_iter()
                    .zip(reg)
                    .map(|(c, (joint, factor))| (c, joint, factor))
                    .collect();
            }
        }
        Ok(Some(TrunkLoad {
            deflection,
            torque,
            branch,
        }))
    }

    /// Tip of `robot`'s `tool` at `q` in its own base frame, m, and its Jacobian columns; on a
    /// shared trunk with the other arm at `q_other`, the trunk carries the other arm too.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn robot_tip(
        &self,
        est: &CellEstimate,
        robot: Robot,
        tool: usize,
        q: &[f64],
        q_other: Option<&[f64]>,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError> {
        self.robot_tip_at(&self.at(est), robot, tool, q, q_other, want_jac, row)
    }

    /// [`Evaluator::robot_tip`] at a prepared estimate.
    #[allow(clippy::too_many_arguments)]
    fn robot_tip_at<'e>(
        &self,
        at: &AtEstimate<'e>,
        robot: Robot,
        tool: usize,
        q: &[f64],
        q_other: Option<&[f64]>,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError>
    where
        'a: 'e,
    {
        let slot = robot_slot(robot);
        let (rb, tool_def, prepared) = self.tool_context(at, robot, tool, row)?;
        let kin_err = kinematics_error(robot, row);
        let lay = &self.layout.robots[slot];
        let tip_col = lay.tip_col[tool];
        let load = self.trunk_load(at.est, robot, &prepared.errors, q_other, want_jac, row)?;
        let mut errors = Cow::Borrowed(&prepared.errors);
        if let Some(load) = &load {
            for (o, d) in errors
                .to_mut()
                .joint_offset
                .iter_mut()
                .zip(&load.deflection)
            {
                *o += d;
            }
        }
        // The errors prepared once for the estimate are these errors (no trunk load added).
        let ready = prepared.prepared.as_ref().filter(|_| load.is_none());
        let mut cols = Cols3::new();
        if want_jac && (!lay.kin.is_empty() || tip_col.iter().any(Option::is_some)) {
            // Always the kinematic columns and all three tip axes; unfitted axes are skipped.
            // The tip and its Jacobian from one walk of the chain (the same values as
            // `true_base_from_tip` and `tip_error_jacobian`). Under a trunk load, the trunk
            // joints' offset columns too (the branch columns are multiples of them).
            let loaded_params;
            let params = match &load {
                Some(load) => {
                    let mut v = self.jac_params[slot].clone();
                    v.extend(
                        (0..load.deflection.len()).map(|joint| ErrorParam::JointOffset { joint }),
                    );
                    loaded_params = v;
                    &loaded_params
                }
                None => &self.jac_params[slot],
            };
            let (pose, j) = if let Some(ready) = ready {
                ready.tip_with_error_jacobian(q).map_err(kin_err)?
            } else {
                true_tip_with_error_jacobian(
                    &rb.model,
                    &errors,
                    q,
                    &tool_def.flange_from_tip,
                    &rb.g_base,
                    params,
                )
                .map_err(kin_err)?
            };
            cols.reserve(lay.kin.len() + 3);
            for (k, &(_, c)) in lay.kin.iter().enumerate() {
                cols.push((c, j.column(k).into_owned()));
            }
            let k0 = lay.kin.len();
            for (a, c) in tip_col.iter().enumerate() {
                if let Some(c) = c {
                    cols.push((*c, j.column(k0 + a).into_owned()));
                }
            }
            if let Some(load) = &load {
                let offset_col = |joint: usize| j.column(k0 + 3 + joint).into_owned();
                push_load_columns(&mut cols, lay.kin.iter().map(|k| k.0), load, offset_col);
            }
            return Ok((pose.translation.vector, cols));
        }
        let t = &tool_def.flange_from_tip;
        let pose = if let Some(ready) = ready {
            ready.tip(q).map_err(kin_err)?
        } else {
            true_base_from_tip(&rb.model, &errors, q, t, &rb.g_base).map_err(kin_err)?
        };
        Ok((pose.translation.vector, cols))
    }

    /// Tip of `robot`'s tool in base `anchor`'s frame and its Jacobian columns (including the
    /// placement's when the frames differ); `q_other` as [`Evaluator::robot_tip`].
    #[allow(clippy::too_many_arguments)]
    pub(super) fn tip_in_anchor(
        &self,
        est: &CellEstimate,
        robot: Robot,
        tool: usize,
        q: &[f64],
        q_other: Option<&[f64]>,
        anchor: Robot,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError> {
        let at = self.at(est);
        self.tip_in_anchor_at(&at, robot, tool, q, q_other, anchor, want_jac, row)
    }

    /// [`Evaluator::tip_in_anchor`] at a prepared estimate.
    #[allow(clippy::too_many_arguments)]
    fn tip_in_anchor_at<'e>(
        &self,
        at: &AtEstimate<'e>,
        robot: Robot,
        tool: usize,
        q: &[f64],
        q_other: Option<&[f64]>,
        anchor: Robot,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError>
    where
        'a: 'e,
    {
        let est = at.est;
        let (f, cols) = self.robot_tip_at(at, robot, tool, q, q_other, want_jac, row)?;
        if robot == anchor {
            return Ok((f, cols));
        }
        let x = &est.b1_from_b2;
        let r_x = x.rotation.to_rotation_matrix().into_inner();
        if robot == Robot::Two {
            // g = X·f2; ∂g/∂ρ = I, ∂g/∂φ_i = e_i × g, ∂g/∂θ2 = R_X·J2.
            let g = (x * Point3::from(f)).coords;
            let mut out: Cols3 = cols.into_iter().map(|(c, v)| (c, r_x * v)).collect();
            if want_jac {
                for (i, axis) in Axis::ALL.iter().enumerate() {
                    out.push((i, axis.unit()));
                    out.push((3 + i, axis.unit().cross(&g)));
                }
            }
            Ok((g, out))
        } else {
            // g = X⁻¹·f1; with X' = exp(ξ)·X, X'⁻¹·f1 = X⁻¹·(f1 − ρ − φ×f1) to first order.
            let g = (x.inverse() * Point3::from(f)).coords;
            let r_t = r_x.transpose();
            let mut out: Cols3 = cols.into_iter().map(|(c, v)| (c, r_t * v)).collect();
            if want_jac {
                for (i, axis) in Axis::ALL.iter().enumerate() {
                    out.push((i, -(r_t * axis.unit())));
                    out.push((3 + i, -(r_t * axis.unit().cross(&f))));
                }
            }
            Ok((g, out))
        }
    }

    /// Both robots' tips of a two-robot row in b1 and their Jacobian columns
    /// ([`Evaluator::tip_in_anchor`]), each arm loading a shared trunk for the other.
    fn both_tips_in_b1<'e>(
        &self,
        at: &AtEstimate<'e>,
        [q1, q2]: [&[f64]; 2],
        [tool1, tool2]: [usize; 2],
        want_jac: bool,
        row: usize,
    ) -> Result<TwoTips, CellFitError>
    where
        'a: 'e,
    {
        let one = self.tip_in_anchor_at(
            at,
            Robot::One,
            tool1,
            q1,
            Some(q2),
            Robot::One,
            want_jac,
            row,
        )?;
        let two = self.tip_in_anchor_at(
            at,
            Robot::Two,
            tool2,
            q2,
            Some(q1),
            Robot::One,
            want_jac,
            row,
        )?;
        Ok((one, two))
    }

    /// A unit vector fixed in `robot`'s tip frame (`n_tip`, e.g. a face normal), rotated into
    /// b1 (`R(b1_from_tip)·n_tip`; for robot 2 `R(b1_from_b2)·R(b2_from_tip)·n_tip`), and its
    /// Jacobian columns: the kinematic parameters (and a shared trunk's load from the other arm
    /// at `q_other`, as [`Evaluator::robot_tip`]) and, for robot 2, the placement rotation
    /// (`∂/∂φ_i = e_i × n_b1`; translations and tip offsets do not rotate it).
    ///
    /// The kinematic columns are exact without a rotation Jacobian: the tip is affine in the
    /// tool offset, `p(t) = o + R·(t + tip)`, so `R·n = p(t + n) − p(t)` and
    /// `∂(R·n)/∂θ = ∂p(t + n)/∂θ − ∂p(t)/∂θ`, two [`tip_error_jacobian`]s (the compliance
    /// torques do not depend on the tool offset).
    #[allow(clippy::too_many_arguments)]
    fn normal_in_b1<'e>(
        &self,
        at: &AtEstimate<'e>,
        robot: Robot,
        tool: usize,
        q: &[f64],
        q_other: Option<&[f64]>,
        n_tip: &Unit<Vector3<f64>>,
        want_jac: bool,
        row: usize,
    ) -> Result<(Vector3<f64>, Cols3), CellFitError>
    where
        'a: 'e,
    {
        let est = at.est;
        let slot = robot_slot(robot);
        let (rb, tool_def, prepared) = self.tool_context(at, robot, tool, row)?;
        let mut errors = prepared.errors.clone();
        let kin_err = kinematics_error(robot, row);
        let lay = &self.layout.robots[slot];
        let load = self.trunk_load(est, robot, &errors, q_other, want_jac, row)?;
        if let Some(load) = &load {
            for (o, d) in errors.joint_offset.iter_mut().zip(&load.deflection) {
                *o += d;
            }
        }
        let t = tool_def.flange_from_tip;
        let base_from_tip =
            true_base_from_tip(&rb.model, &errors, q, &t, &rb.g_base).map_err(kin_err)?;
        let n_base = base_from_tip.rotation * n_tip.into_inner();
        let mut cols = Cols3::new();
        let has_branch = load.as_ref().is_some_and(|l| !l.branch.is_empty());
        if want_jac && (!lay.kin.is_empty() || has_branch) {
            let mut params = self.jac_params[slot][..lay.kin.len()].to_vec();
            let k0 = params.len();
            if let Some(load) = &load {
                params.extend(
                    (0..load.deflection.len()).map(|joint| ErrorParam::JointOffset { joint }),
                );
            }
            let shifted = t + n_tip.into_inner();
            let j_t = tip_error_jacobian(&rb.model, &errors, q, &t, &rb.g_base, &params)
                .map_err(kin_err)?;
            let j_n = tip_error_jacobian(&rb.model, &errors, q, &shifted, &rb.g_base, &params)
                .map_err(kin_err)?;
            for (k, &(_, c)) in lay.kin.iter().enumerate() {
                cols.push((c, j_n.column(k) - j_t.column(k)));
            }
            if let Some(load) = &load {
                let offset_col = |joint: usize| j_n.column(k0 + joint) - j_t.column(k0 + joint);
                push_load_columns(&mut cols, lay.kin.iter().map(|k| k.0), load, offset_col);
            }
        }
        if robot == Robot::One {
            return Ok((n_base, cols));
        }
        let r_x = est.b1_from_b2.rotation.to_rotation_matrix().into_inner();
        let n_b1 = r_x * n_base;
        let mut out: Cols3 = cols.into_iter().map(|(c, v)| (c, r_x * v)).collect();
        if want_jac {
            for (i, axis) in Axis::ALL.iter().enumerate() {
                out.push((3 + i, axis.unit().cross(&n_b1)));
            }
        }
        Ok((n_b1, out))
    }

    /// Residuals, Jacobian rows (layout columns) and whitening of one observation at `est`.
    pub fn linearise(
        &self,
        obs: &Observation,
        est: &CellEstimate,
        want_jac: bool,
    ) -> Result<ObservationLinearisation, CellFitError> {
        self.linearise_at(obs, &self.at(est), want_jac)
    }

    /// [`Evaluator::linearise`] at a prepared estimate ([`Evaluator::at`]): the same values,
    /// without forming and checking the robots' errors again for each observation.
    pub fn linearise_at<'e>(
        &self,
        obs: &Observation,
        at: &AtEstimate<'e>,
        want_jac: bool,
    ) -> Result<ObservationLinearisation, CellFitError>
    where
        'a: 'e,
    {
        let est = at.est;
        let row = obs.row;
        let n = self.layout.len();
        let rows = obs.kind.rows();
        let mut jac = DMatrix::zeros(if want_jac { rows } else { 0 }, n);
        let put3 = |jac: &mut DMatrix<f64>, cols: &Cols3, sign: f64| {
            for (c, v) in cols {
                for a in 0..3 {
                    jac[(a, *c)] += sign * v[a];
                }
            }
        };
        let put1 = |jac: &mut DMatrix<f64>, cols: &Cols3, w: &Vector3<f64>| {
            for (c, v) in cols {
                jac[(0, *c)] += w.dot(v);
            }
        };
        let (residual, whitening) = match &obs.kind {
            ObservationKind::Coincident {
                q1,
                q2,
                tool1,
                tool2,
                noise,
            } => {
                let ((p1, c1), (g2, c2)) =
                    self.both_tips_in_b1(at, [q1, q2], [*tool1, *tool2], want_jac, row)?;
                if want_jac {
                    put3(&mut jac, &c1, 1.0);
                    put3(&mut jac, &c2, -1.0);
                }
                let w = noise.whitening(row)?;
                (
                    DVector::from_column_slice((p1 - g2).as_slice()),
                    DMatrix::from_column_slice(3, 3, w.as_slice()),
                )
            }
            ObservationKind::Contact {
                q1,
                q2,
                tool1,
                tool2,
                group,
                sigma_m,
            } => {
                let ((p1, c1), (g2, c2)) =
                    self.both_tips_in_b1(at, [q1, q2], [*tool1, *tool2], want_jac, row)?;
                let e = p1 - g2;
                let dist = e.norm();
                let u = if dist > 0.0 { e / dist } else { Vector3::x() };
                if want_jac {
                    put1(&mut jac, &c1, &u);
                    put1(&mut jac, &c2, &(-u));
                    if let Some(c) = self.layout.contact_col[*group] {
                        jac[(0, c)] -= 1.0;
                    }
                }
                (
                    DVector::from_element(1, dist - est.contact_distance_m[*group]),
                    DMatrix::from_element(1, 1, 1.0 / sigma_m),
                )
            }
            ObservationKind::FaceContact {
                q1,
                q2,
                tool1,
                tool2,
                n1_tip,
                n2_tip,
                group,
                sigma_m,
            } => {
                let ((p1, c1), (g2, c2)) =
                    self.both_tips_in_b1(at, [q1, q2], [*tool1, *tool2], want_jac, row)?;
                let (n1, cn1) =
                    self.normal_in_b1(at, Robot::One, *tool1, q1, Some(q2), n1_tip, want_jac, row)?;
                let (n2, cn2) =
                    self.normal_in_b1(at, Robot::Two, *tool2, q2, Some(q1), n2_tip, want_jac, row)?;
                // n̄ = m/‖m‖, m = n1 − n2; ∂(n̄·e) = n̄·∂e + wᵀ·∂m, w = (I − n̄n̄ᵀ)·e/‖m‖.
                let m = n1 - n2;
                let m_len = m.norm();
                if !(m_len.is_finite() && m_len > MIN_FACE_NORMAL_SUM) {
                    return Err(CellFitError::InvalidInput(format!(
                        "observation row {row}: the two face normals point the same way in b1 \
                         (‖n1 − n2‖ = {m_len:.2e}), so the faces do not face each other; give \
                         each face's OUTWARD normal (flush faces have n2 = −n1 in b1)"
                    )));
                }
                let n_bar = m / m_len;
                let e = g2 - p1;
                let along = n_bar.dot(&e);
                if want_jac {
                    put1(&mut jac, &c2, &n_bar);
                    put1(&mut jac, &c1, &(-n_bar));
                    let w = (e - n_bar * along) / m_len;
                    put1(&mut jac, &cn1, &w);
                    put1(&mut jac, &cn2, &(-w));
                    if let Some(c) = self.layout.contact_col[*group] {
                        jac[(0, c)] -= 1.0;
                    }
                }
                (
                    DVector::from_element(1, along - est.contact_distance_m[*group]),
                    DMatrix::from_element(1, 1, 1.0 / sigma_m),
                )
            }
            ObservationKind::Tracker {
                robot,
                q,
                tool,
                group,
                p_tracker,
                noise,
            } => {
                let anchor = self.problem.trackers[*group].anchor;
                let q_other = self.problem.other_arm_q.get(&row).map(Vec::as_slice);
                let (g, cols) =
                    self.tip_in_anchor_at(at, *robot, *tool, q, q_other, anchor, want_jac, row)?;
                let t = &est.tracker_from_anchor[*group];
                let tg = (t * Point3::from(g)).coords;
                // Scale and drift (see TrackerGroup): m = (1 + s)·(T·g + u·δ); `k = 1 + s`.
                let (s, drift) = (est.tracker_scale[*group], est.tracker_drift_m[*group]);
                let (first, last) = self.tracker_span[*group];
                let u = if last > first {
                    (row as f64 - first as f64) / (last - first) as f64 - 0.5
                } else {
                    0.0
                };
                let k = 1.0 + s;
                // Untouched when both are zero, so that fits without them are bit-identical.
                let at_u = if drift == Vector3::zeros() {
                    tg
                } else {
                    tg + drift * u
                };
                let m = if s == 0.0 { at_u } else { at_u * k };
                if want_jac {
                    let r_t = t.rotation.to_rotation_matrix().into_inner() * k;
                    let moved: Cols3 = cols.into_iter().map(|(c, v)| (c, r_t * v)).collect();
                    put3(&mut jac, &moved, 1.0);
                    let c0 = self.layout.tracker_col[*group];
                    for (i, axis) in Axis::ALL.iter().enumerate() {
                        for a in 0..3 {
                            jac[(a, c0 + i)] += k * axis.unit()[a];
                            jac[(a, c0 + 3 + i)] += k * axis.unit().cross(&tg)[a];
                        }
                    }
                    if let Some(c) = self.layout.tracker_scale_col[*group] {
                        for a in 0..3 {
                            jac[(a, c)] += at_u[a];
                        }
                    }
                    if let Some(c) = self.layout.tracker_drift_col[*group] {
                        for a in 0..3 {
                            jac[(a, c + a)] += k * u;
                        }
                    }
                }
                let w = noise.whitening(row)?;
                (
                    DVector::from_column_slice((m - p_tracker.coords).as_slice()),
                    DMatrix::from_column_slice(3, 3, w.as_slice()),
                )
            }
            ObservationKind::Plane {
                robot,
                q,
                tool,
                group,
                sigma_m,
            } => {
                let anchor = self.problem.planes[*group].anchor;
                let q_other = self.problem.other_arm_q.get(&row).map(Vec::as_slice);
                let (g, cols) =
                    self.tip_in_anchor_at(at, *robot, *tool, q, q_other, anchor, want_jac, row)?;
                let plane = &est.planes[*group];
                let nrm = plane.normal_anchor.into_inner();
                if want_jac {
                    put1(&mut jac, &cols, &nrm);
                    let (u, v) = tangent_basis(&plane.normal_anchor);
                    let c0 = self.layout.plane_col[*group];
                    jac[(0, c0)] += u.dot(&g);
                    jac[(0, c0 + 1)] += v.dot(&g);
                    jac[(0, c0 + 2)] -= 1.0;
                }
                (
                    DVector::from_element(1, nrm.dot(&g) - plane.offset_m),
                    DMatrix::from_element(1, 1, 1.0 / sigma_m),
                )
            }
        };
        if !residual.iter().chain(jac.iter()).all(|v| v.is_finite()) {
            return Err(CellFitError::NonFinite { row });
        }
        Ok(ObservationLinearisation {
            residual,
            jacobian: jac,
            whitening,
        })
    }

    /// The cooperative vector `v = f1(q1) − b1_from_b2·f2(q2)` (m, b1 axes) and its Jacobian
    /// (3 × layout columns) at `est`.
    pub fn cooperative_vector(
        &self,
        est: &CellEstimate,
        pair: &super::ConfigPair,
        want_jac: bool,
    ) -> Result<(Vector3<f64>, DMatrix<f64>), CellFitError> {
        self.cooperative_vector_at(&self.at(est), pair, want_jac)
    }

    /// [`Evaluator::cooperative_vector`] at a prepared estimate ([`Evaluator::at`]).
    pub fn cooperative_vector_at<'e>(
        &self,
        at: &AtEstimate<'e>,
        pair: &super::ConfigPair,
        want_jac: bool,
    ) -> Result<(Vector3<f64>, DMatrix<f64>), CellFitError>
    where
        'a: 'e,
    {
        let ((p1, c1), (g2, c2)) = self.both_tips_in_b1(
            at,
            [&pair.q1, &pair.q2],
            [pair.tool1, pair.tool2],
            want_jac,
            0,
        )?;
        let mut jac = DMatrix::zeros(3, if want_jac { self.layout.len() } else { 0 });
        if want_jac {
            for (c, v) in &c1 {
                for a in 0..3 {
                    jac[(a, *c)] += v[a];
                }
            }
            for (c, v) in &c2 {
                for a in 0..3 {
                    jac[(a, *c)] -= v[a];
                }
            }
        }
        Ok((p1 - g2, jac))
    }
}

/// The trunk load's columns ([`TrunkLoad`]): each branch coefficient of the other arm, and the
/// other arm's part of each trunk joint's physical compliance column (its torque), as multiples
/// of the trunk joints' offset columns `offset_col`; `kin` the robot's kinematic parameters in
/// layout order (their columns are `cols`' first entries).
fn push_load_columns(
    cols: &mut Cols3,
    kin: impl Iterator<Item = ErrorParam>,
    load: &TrunkLoad,
    offset_col: impl Fn(usize) -> Vector3<f64>,
) {
    let extra: Cols3 = kin
        .zip(cols.iter())
        .filter_map(|(p, &(c, _))| match p {
            ErrorParam::Compliance { joint } if joint < load.torque.len() => {
                Some((c, offset_col(joint) * load.torque[joint]))
            }
            _ => None,
        })
        .collect();
    cols.extend(extra);
    cols.extend(
        load.branch
            .iter()
            .map(|&(c, joint, factor)| (c, offset_col(joint) * factor)),
    );
}

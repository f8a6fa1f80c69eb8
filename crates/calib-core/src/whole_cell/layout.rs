//! The unknowns: the values of every unknown ([`CellEstimate`]), the fit's columns and prior
//! ([`ParamLayout`], [`CellParam`]) and the manifold updates that apply a step to an estimate.

use kinematics::{Axis, ErrorParam, KinematicErrors};
use nalgebra::{DMatrix, DVector, Isometry3, Unit, Vector3};
use serde::Serialize;

use super::cell::{CellFitError, CellRobot};
use super::observations::CellProblem;
use crate::Robot;

/// The kinematic corrections of one robot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotCorrection {
    /// Kinematic errors (the `tip` field is unused: tips are per tool).
    pub errors: KinematicErrors,
    /// Tip offset error of each tool, m, flange axes (added to [`Tool::flange_from_tip`](super::Tool::flange_from_tip)).
    pub tool_tip_m: Vec<Vector3<f64>>,
}

impl RobotCorrection {
    /// No corrections for `robot`.
    pub fn zero(robot: &CellRobot) -> Self {
        Self {
            errors: KinematicErrors::zero_for(&robot.model),
            tool_tip_m: vec![Vector3::zeros(); robot.tools.len()],
        }
    }

    /// The errors with tool `tool`'s tip error in the `tip` field.
    pub fn errors_for_tool(&self, tool: usize) -> KinematicErrors {
        let mut e = self.errors.clone();
        e.tip = self.tool_tip_m[tool];
        e
    }
}

/// A plane `{p : n·p = d}` in its anchor's base frame.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PlaneEstimate {
    /// Unit normal, anchor base axes.
    pub normal_anchor: Unit<Vector3<f64>>,
    /// Offset `d`, m.
    pub offset_m: f64,
}

/// Values of every unknown of the cell: the placement, both robots' corrections and the
/// nuisance unknowns. Used as the fit's state and result, and as the truth in studies.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CellEstimate {
    /// Base 2 in base 1.
    pub b1_from_b2: Isometry3<f64>,
    /// Robot 1's corrections.
    pub robot1: RobotCorrection,
    /// Robot 2's corrections.
    pub robot2: RobotCorrection,
    /// `tracker_from_b{anchor}` of each tracker group (at the middle of its recording when its
    /// drift is fitted; see [`TrackerGroup`](super::TrackerGroup)).
    pub tracker_from_anchor: Vec<Isometry3<f64>>,
    /// Scale error `s` of each tracker group, ratio (0 unless fitted). Omitted from the
    /// serialised form when all zero.
    #[serde(skip_serializing_if = "all_zero")]
    pub tracker_scale: Vec<f64>,
    /// Drift `δ` of each tracker group's translation over its normalised recording order, m per
    /// unit order, tracker axes (0 unless fitted). Omitted from the serialised form when all zero.
    #[serde(skip_serializing_if = "all_zero3")]
    pub tracker_drift_m: Vec<Vector3<f64>>,
    /// Each plane group's plane.
    pub planes: Vec<PlaneEstimate>,
    /// Each contact group's distance, m.
    pub contact_distance_m: Vec<f64>,
}

impl CellEstimate {
    /// Nominal robots (no corrections), the given placement and groups at identity / unit z /
    /// their given distance.
    pub fn nominal(problem: &CellProblem, b1_from_b2: Isometry3<f64>) -> Self {
        Self {
            b1_from_b2,
            robot1: RobotCorrection::zero(&problem.robot1),
            robot2: RobotCorrection::zero(&problem.robot2),
            tracker_from_anchor: vec![Isometry3::identity(); problem.trackers.len()],
            tracker_scale: vec![0.0; problem.trackers.len()],
            tracker_drift_m: vec![Vector3::zeros(); problem.trackers.len()],
            planes: vec![
                PlaneEstimate {
                    normal_anchor: Vector3::z_axis(),
                    offset_m: 0.0
                };
                problem.planes.len()
            ],
            contact_distance_m: problem.contacts.iter().map(|c| c.distance_m).collect(),
        }
    }

    /// Checks that the estimate fits `problem`: one correction per joint and tool of each robot,
    /// one value per group, all finite. Errors name the field.
    pub fn check(&self, problem: &CellProblem) -> Result<(), CellFitError> {
        self.check_robots(problem)?;
        if self.tracker_from_anchor.len() != problem.trackers.len()
            || self.tracker_scale.len() != problem.trackers.len()
            || self.tracker_drift_m.len() != problem.trackers.len()
            || self.planes.len() != problem.planes.len()
            || self.contact_distance_m.len() != problem.contacts.len()
        {
            return Err(CellFitError::InvalidInput(format!(
                "cell estimate: {} tracker frame(s) ({} scale(s), {} drift(s)), {} plane(s), {} \
                 contact distance(s) for {}, {} and {} group(s); build it with \
                 CellEstimate::nominal for this problem",
                self.tracker_from_anchor.len(),
                self.tracker_scale.len(),
                self.tracker_drift_m.len(),
                self.planes.len(),
                self.contact_distance_m.len(),
                problem.trackers.len(),
                problem.planes.len(),
                problem.contacts.len()
            )));
        }
        Ok(())
    }

    /// The robot part of [`CellEstimate::check`] (what the cooperative vector needs).
    pub fn check_robots(&self, problem: &CellProblem) -> Result<(), CellFitError> {
        let bad = |what: String| {
            Err(CellFitError::InvalidInput(format!(
                "cell estimate: {what}; build it with CellEstimate::nominal for this problem"
            )))
        };
        for r in [Robot::One, Robot::Two] {
            let rb = problem.robot(r);
            let c = self.robot(r);
            if let Err(e) = c.errors.check(&rb.model) {
                return bad(format!("{r}: {e}"));
            }
            if c.tool_tip_m.len() != rb.tools.len() {
                return bad(format!(
                    "{r} has {} tool tip error(s) for {} tool(s)",
                    c.tool_tip_m.len(),
                    rb.tools.len()
                ));
            }
            if !c.tool_tip_m.iter().all(|t| t.iter().all(|v| v.is_finite())) {
                return bad(format!("{r} has a non-finite tool tip error"));
            }
        }
        if !self
            .b1_from_b2
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite())
            || !self
                .b1_from_b2
                .rotation
                .coords
                .iter()
                .all(|v| v.is_finite())
        {
            return bad("b1_from_b2 is not finite".into());
        }
        Ok(())
    }

    /// Robot 1's or 2's corrections.
    pub fn robot(&self, robot: Robot) -> &RobotCorrection {
        if robot == Robot::One {
            &self.robot1
        } else {
            &self.robot2
        }
    }

    fn robot_mut(&mut self, robot: Robot) -> &mut RobotCorrection {
        if robot == Robot::One {
            &mut self.robot1
        } else {
            &mut self.robot2
        }
    }
}

/// One scalar unknown of the fit.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum CellParam {
    /// Left translation perturbation of `b1_from_b2`, m, b1 axes.
    PlacementTranslation {
        /// Axis.
        axis: Axis,
    },
    /// Left rotation perturbation of `b1_from_b2`, rad, b1 axes.
    PlacementRotation {
        /// Axis.
        axis: Axis,
    },
    /// A kinematic parameter of a robot (its own unit).
    Kinematic {
        /// 1 or 2.
        robot: Robot,
        /// The parameter.
        param: ErrorParam,
    },
    /// A tool's tip offset error, m, flange axes.
    ToolTip {
        /// 1 or 2.
        robot: Robot,
        /// Tool index.
        tool: usize,
        /// Axis.
        axis: Axis,
    },
    /// Left translation perturbation of a tracker frame, m.
    TrackerTranslation {
        /// Group index.
        group: usize,
        /// Axis.
        axis: Axis,
    },
    /// Left rotation perturbation of a tracker frame, rad.
    TrackerRotation {
        /// Group index.
        group: usize,
        /// Axis.
        axis: Axis,
    },
    /// A tracker group's scale error `s`, ratio (see [`TrackerGroup`](super::TrackerGroup)).
    TrackerScale {
        /// Group index.
        group: usize,
    },
    /// A tracker group's translation drift `δ`, m per unit of normalised recording order,
    /// tracker axes (see [`TrackerGroup`](super::TrackerGroup)).
    TrackerDrift {
        /// Group index.
        group: usize,
        /// Axis.
        axis: Axis,
    },
    /// A plane normal's tangent perturbation (direction 0 or 1 of its tangent basis), rad.
    PlaneNormal {
        /// Group index.
        group: usize,
        /// 0 or 1.
        direction: usize,
    },
    /// A plane's offset, m.
    PlaneOffset {
        /// Group index.
        group: usize,
    },
    /// A contact group's distance, m.
    ContactDistance {
        /// Group index.
        group: usize,
    },
}

impl CellParam {
    /// True for the kinematic parameters (the ones with a prior).
    pub fn is_kinematic(&self) -> bool {
        matches!(
            self,
            CellParam::Kinematic { .. } | CellParam::ToolTip { .. }
        )
    }

    /// A readable name, e.g. `robot 2 origin_xyz joint 3 x`.
    pub fn describe(&self, problem: &CellProblem) -> String {
        match self {
            CellParam::PlacementTranslation { axis } => format!("b1_from_b2 translation {axis}"),
            CellParam::PlacementRotation { axis } => format!("b1_from_b2 rotation {axis}"),
            CellParam::Kinematic { robot, param } => format!("{robot} {param}"),
            CellParam::ToolTip { robot, tool, axis } => format!(
                "{robot} tool `{}` tip {axis}",
                problem.robot(*robot).tools[*tool].name
            ),
            CellParam::TrackerTranslation { group, axis } => {
                format!(
                    "tracker `{}` translation {axis}",
                    problem.trackers[*group].name
                )
            }
            CellParam::TrackerRotation { group, axis } => {
                format!(
                    "tracker `{}` rotation {axis}",
                    problem.trackers[*group].name
                )
            }
            CellParam::TrackerScale { group } => {
                format!("tracker `{}` scale", problem.trackers[*group].name)
            }
            CellParam::TrackerDrift { group, axis } => {
                format!("tracker `{}` drift {axis}", problem.trackers[*group].name)
            }
            CellParam::PlaneNormal { group, direction } => {
                format!("plane `{}` normal {direction}", problem.planes[*group].name)
            }
            CellParam::PlaneOffset { group } => {
                format!("plane `{}` offset", problem.planes[*group].name)
            }
            CellParam::ContactDistance { group } => {
                format!("contact `{}` distance", problem.contacts[*group].name)
            }
        }
    }
}

#[derive(Debug, Clone)]
pub(super) struct RobotLayout {
    /// Fitted kinematic parameters (tips excluded) and their columns.
    pub(super) kin: Vec<(ErrorParam, usize)>,
    /// Column of each axis of each tool's tip error, if fitted.
    pub(super) tip_col: Vec<[Option<usize>; 3]>,
}

/// The unknowns of a fit and their prior: column `j` of every Jacobian is `params[j]`.
#[derive(Debug, Clone)]
pub struct ParamLayout {
    /// The unknowns, in column order: placement (6), robot 1, robot 2, trackers (6 each, then
    /// the fitted scale (1) and drift (3) of that group), planes (3 each), fitted contact
    /// distances.
    pub params: Vec<CellParam>,
    /// Square-root prior information `R_p` (rows × `params.len()`): the prior cost is
    /// `‖R_p·θ‖²` with `θ` the parameter values (zero on unpenalised columns).
    pub prior_sqrt_info: DMatrix<f64>,
    pub(super) robots: [RobotLayout; 2],
    pub(super) tracker_col: Vec<usize>,
    /// Column of each tracker group's scale, if fitted.
    pub(super) tracker_scale_col: Vec<Option<usize>>,
    /// First of the three columns of each tracker group's drift, if fitted.
    pub(super) tracker_drift_col: Vec<Option<usize>>,
    pub(super) plane_col: Vec<usize>,
    pub(super) contact_col: Vec<Option<usize>>,
}

impl ParamLayout {
    /// The layout of `problem` with every parameter its tolerances select, except those in
    /// `fixed` (held at their current value, normally 0), and a diagonal prior `1/σ` with
    /// `σ = tol/√3`.
    pub fn new(problem: &CellProblem, fixed: &[CellParam]) -> Self {
        let mut params: Vec<CellParam> = Vec::new();
        for axis in Axis::ALL {
            params.push(CellParam::PlacementTranslation { axis });
        }
        for axis in Axis::ALL {
            params.push(CellParam::PlacementRotation { axis });
        }
        let mut sigmas: Vec<f64> = vec![0.0; 6];
        let mut robots = Vec::new();
        for r in [Robot::One, Robot::Two] {
            let rb = problem.robot(r);
            let mut kin = Vec::new();
            // Robot 2's shared joints (a shared trunk) have robot 1's parameters: robot 1's
            // columns, no columns of their own, so the Jacobians add into them and a step moves
            // both robots' copies alike. Robot 2's arm links' lumped coefficients on the trunk
            // joints are its own (each arm's weight on the trunk, `kinematics::trunk`).
            let shared = |p: &ErrorParam| {
                r == Robot::Two
                    && p.joint().is_some_and(|j| j < rb.shared_joints)
                    && !kinematics::is_branch_param(p, rb.shared_joints)
            };
            if let Some(robot1) = robots.first() {
                let robot1: &RobotLayout = robot1;
                kin.extend(robot1.kin.iter().filter(|(p, _)| shared(p)).copied());
            }
            for p in rb.fitted_params() {
                if shared(&p) {
                    continue;
                }
                let cp = CellParam::Kinematic { robot: r, param: p };
                if fixed.contains(&cp) {
                    continue;
                }
                kin.push((p, params.len()));
                params.push(cp);
                sigmas.push(rb.prior_sigma(p));
            }
            let mut tip_col = Vec::new();
            for tool in 0..rb.tools.len() {
                let mut cols = [None; 3];
                if rb.tolerance.tip_m > 0.0 {
                    for (a, &axis) in Axis::ALL.iter().enumerate() {
                        let p = CellParam::ToolTip {
                            robot: r,
                            tool,
                            axis,
                        };
                        if fixed.contains(&p) {
                            continue;
                        }
                        cols[a] = Some(params.len());
                        params.push(p);
                        sigmas.push(rb.tolerance.tip_m / 3f64.sqrt());
                    }
                }
                tip_col.push(cols);
            }
            robots.push(RobotLayout { kin, tip_col });
        }
        let mut tracker_col = Vec::new();
        let mut tracker_scale_col = Vec::new();
        let mut tracker_drift_col = Vec::new();
        for (group, t) in problem.trackers.iter().enumerate() {
            tracker_col.push(params.len());
            for axis in Axis::ALL {
                params.push(CellParam::TrackerTranslation { group, axis });
            }
            for axis in Axis::ALL {
                params.push(CellParam::TrackerRotation { group, axis });
            }
            sigmas.extend([0.0; 6]);
            tracker_scale_col.push(t.fit_scale.then(|| {
                params.push(CellParam::TrackerScale { group });
                sigmas.push(0.0);
                params.len() - 1
            }));
            tracker_drift_col.push(t.fit_drift.then(|| {
                let c = params.len();
                for axis in Axis::ALL {
                    params.push(CellParam::TrackerDrift { group, axis });
                }
                sigmas.extend([0.0; 3]);
                c
            }));
        }
        let mut plane_col = Vec::new();
        for group in 0..problem.planes.len() {
            plane_col.push(params.len());
            params.push(CellParam::PlaneNormal {
                group,
                direction: 0,
            });
            params.push(CellParam::PlaneNormal {
                group,
                direction: 1,
            });
            params.push(CellParam::PlaneOffset { group });
            sigmas.extend([0.0; 3]);
        }
        let mut contact_col = Vec::new();
        for (group, c) in problem.contacts.iter().enumerate() {
            if c.fit_distance {
                contact_col.push(Some(params.len()));
                params.push(CellParam::ContactDistance { group });
                sigmas.push(0.0);
            } else {
                contact_col.push(None);
            }
        }
        let penal: Vec<usize> = (0..params.len()).filter(|&j| sigmas[j] > 0.0).collect();
        let mut prior_sqrt_info = DMatrix::zeros(penal.len(), params.len());
        for (i, &j) in penal.iter().enumerate() {
            prior_sqrt_info[(i, j)] = 1.0 / sigmas[j];
        }
        let [r1, r2]: [RobotLayout; 2] = robots.try_into().expect("two robots");
        Self {
            params,
            prior_sqrt_info,
            robots: [r1, r2],
            tracker_col,
            tracker_scale_col,
            tracker_drift_col,
            plane_col,
            contact_col,
        }
    }

    /// Number of unknowns.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// True if there are no unknowns (never: the placement is always fitted).
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }

    /// Column of a parameter, if fitted.
    pub fn column(&self, p: &CellParam) -> Option<usize> {
        self.params.iter().position(|q| q == p)
    }

    /// Prior standard deviation of column `j` from the diagonal of the prior information (0 for
    /// unpenalised columns).
    pub fn prior_sigma(&self, j: usize) -> f64 {
        let info: f64 = self.prior_sqrt_info.column(j).norm_squared();
        if info > 0.0 {
            1.0 / info.sqrt()
        } else {
            0.0
        }
    }

    /// The values of the parameters in `estimate` (0 on the manifold perturbation columns of the
    /// placement, trackers and plane normals, which are relative to the current value).
    pub fn values(&self, estimate: &CellEstimate) -> DVector<f64> {
        let mut v = DVector::zeros(self.len());
        for (slot, r) in [Robot::One, Robot::Two].into_iter().enumerate() {
            let corr = estimate.robot(r);
            for &(p, c) in &self.robots[slot].kin {
                v[c] = corr.errors.get(p);
            }
            for (tool, cols) in self.robots[slot].tip_col.iter().enumerate() {
                for (a, c) in cols.iter().enumerate() {
                    if let Some(c) = c {
                        v[*c] = corr.tool_tip_m[tool][a];
                    }
                }
            }
        }
        for (g, c) in self.tracker_scale_col.iter().enumerate() {
            if let Some(c) = c {
                v[*c] = estimate.tracker_scale[g];
            }
        }
        for (g, c) in self.tracker_drift_col.iter().enumerate() {
            if let Some(c) = c {
                v.rows_mut(*c, 3).copy_from(&estimate.tracker_drift_m[g]);
            }
        }
        for (g, c) in self.plane_col.iter().enumerate() {
            v[c + 2] = estimate.planes[g].offset_m;
        }
        for (g, c) in self.contact_col.iter().enumerate() {
            if let Some(c) = c {
                v[*c] = estimate.contact_distance_m[g];
            }
        }
        v
    }

    /// Applies a step `delta` (one entry per column) to `estimate`: placement and tracker frames
    /// by left perturbation `X ← Translation(ρ)·Rotation(φ)·X`, plane normals by
    /// `n ← normalise(n + a·u + b·v)` with `(u, v)` [`tangent_basis`]`(n)`, everything else
    /// additively.
    pub fn apply(&self, estimate: &CellEstimate, delta: &DVector<f64>) -> CellEstimate {
        let mut e = estimate.clone();
        let left = |x: &Isometry3<f64>, c: usize| {
            let rho = Vector3::new(delta[c], delta[c + 1], delta[c + 2]);
            let phi = Vector3::new(delta[c + 3], delta[c + 4], delta[c + 5]);
            Isometry3::new(rho, phi) * x
        };
        e.b1_from_b2 = left(&estimate.b1_from_b2, 0);
        for (slot, r) in [Robot::One, Robot::Two].into_iter().enumerate() {
            let corr = e.robot_mut(r);
            for &(p, c) in &self.robots[slot].kin {
                corr.errors.add(p, delta[c]);
            }
            for (tool, cols) in self.robots[slot].tip_col.iter().enumerate() {
                for (a, c) in cols.iter().enumerate() {
                    if let Some(c) = c {
                        corr.tool_tip_m[tool][a] += delta[*c];
                    }
                }
            }
        }
        for (g, &c) in self.tracker_col.iter().enumerate() {
            e.tracker_from_anchor[g] = left(&estimate.tracker_from_anchor[g], c);
        }
        for (g, c) in self.tracker_scale_col.iter().enumerate() {
            if let Some(c) = c {
                e.tracker_scale[g] += delta[*c];
            }
        }
        for (g, c) in self.tracker_drift_col.iter().enumerate() {
            if let Some(c) = c {
                e.tracker_drift_m[g] += delta.fixed_rows::<3>(*c);
            }
        }
        for (g, &c) in self.plane_col.iter().enumerate() {
            let n = estimate.planes[g].normal_anchor;
            let (u, v) = tangent_basis(&n);
            e.planes[g].normal_anchor =
                Unit::new_normalize(n.into_inner() + u * delta[c] + v * delta[c + 1]);
            e.planes[g].offset_m += delta[c + 2];
        }
        for (g, c) in self.contact_col.iter().enumerate() {
            if let Some(c) = c {
                e.contact_distance_m[g] += delta[*c];
            }
        }
        e
    }
}

/// True if every entry is exactly zero (serde's skip test of the tracker scales).
fn all_zero(v: &[f64]) -> bool {
    v.iter().all(|&x| x == 0.0)
}

/// True if every vector is exactly zero (serde's skip test of the tracker drifts).
fn all_zero3(v: &[Vector3<f64>]) -> bool {
    v.iter().all(|x| x.iter().all(|&c| c == 0.0))
}

/// A deterministic orthonormal basis `(u, v)` of the plane orthogonal to `n`.
pub fn tangent_basis(n: &Unit<Vector3<f64>>) -> (Vector3<f64>, Vector3<f64>) {
    let a = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let u = n.cross(&a).normalize();
    let v = n.cross(&u);
    (u, v)
}

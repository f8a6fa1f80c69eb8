//! Simulated sessions of every observation kind ([`generate_kind_session`]): coincident
//! handclasps, contacts at a distance, flush face contacts, tracker measurements of one robot's tool and plane
//! touches, or a mix, each with its own noise and seeded truth for the nuisances (a tracker
//! frame somewhere in the cell, a plane through the common workspace, a contact distance).
//! Teach points come from a layout, an explicit list or a plan (a session whose joint angles
//! seed the inverse kinematics, so the simulated robots take the planned poses).

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::SimError;
use crate::layout::teach_points;
use crate::simulate::{
    approach_directions, gauss3, generate_session, quantise, solve_true_tool, tool_errors,
    unreachable, PointFailure, SessionSpec, MAX_LAYOUT_ATTEMPTS,
};
use crate::trunk::{Meeting, TRUNK_LOAD_PASSES};
use calib_core::whole_cell::tangent_basis;
use calib_core::Robot;
use handclasp_cell::cell::Cell;
use handclasp_cell::{Session, SessionKind, SessionObservation, SessionPoint};
use kinematics::{base_from_tip, true_base_from_tip};

/// Which observation kinds a simulated session holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SimKind {
    /// Coincident handclasps only (exactly [`generate_session`] unless a plan is given).
    Coincident,
    /// Contacts: the two tips a known distance apart along the approach line.
    Contact,
    /// Face contacts: two flat faces flush, normal to the approach line, the tips the contact
    /// distance apart along it and the faces slid on each other (`face_slide_m`).
    FaceContact,
    /// Tracker rows, robots 1 and 2 alternating, one tracker frame (group `tracker`).
    Tracker,
    /// Plane touches, robots 1 and 2 alternating, one plane (group `plane`).
    Plane,
    /// The kinds in turn: coincident, contact, tracker (robot 1), plane (robot 1), tracker
    /// (robot 2), plane (robot 2), coincident, …
    Mixed,
}

/// Group name of the simulated contact rows.
pub const CONTACT_GROUP: &str = "contact";
/// Group name of the simulated tracker rows.
pub const TRACKER_GROUP: &str = "tracker";
/// Group name of the simulated plane rows.
pub const PLANE_GROUP: &str = "plane";

/// Noise and settings of the non-coincident kinds (SI; defaults in brackets). The coincident
/// rows take the cell's `[noise]`; every kind also carries both robots' repeatability and the
/// encoder quantisation of the cell.
#[derive(Debug, Clone, PartialEq)]
pub struct KindSpec {
    /// What to simulate [`SimKind::Coincident`].
    pub kind: SimKind,
    /// True distance between the two tips of a contact, m [0.1].
    pub contact_distance_m: f64,
    /// σ of a contact's distance, m [0.2 mm].
    pub contact_sigma_m: f64,
    /// Write the contact distance into the rows (known) instead of leaving it to be fitted
    /// [false]. Contacts and face contacts share the distance, its σ and this switch.
    pub contact_known: bool,
    /// Largest slide of a face contact's faces on each other, m, per tangent axis [5 mm].
    pub face_slide_m: f64,
    /// Largest tilt of a face contact's face normal from the approach direction (robot 1's
    /// flange z), rad [20°]: which face of a polyhedral marker touches varies from row to row.
    pub face_tilt_max_rad: f64,
    /// σ per axis of a tracker measurement, m [0.05 mm].
    pub tracker_sigma_m: f64,
    /// The tool a tracker measures, by name ([`handclasp_cell::CellRobot::tool_index`]) \[`tip`, [`handclasp_cell::cell::TIP_TOOL`]\].
    pub tracker_tool: String,
    /// σ of a plane touch (the tip's distance from the plane), m [0.1 mm].
    pub plane_sigma_m: f64,
    /// Largest tilt of the simulated plane from level, rad [20°].
    pub plane_max_tilt_rad: f64,
}

impl Default for KindSpec {
    fn default() -> Self {
        KindSpec {
            kind: SimKind::Coincident,
            contact_distance_m: 0.1,
            contact_sigma_m: 0.2e-3,
            contact_known: false,
            face_slide_m: 5e-3,
            face_tilt_max_rad: 20f64.to_radians(),
            tracker_sigma_m: 0.05e-3,
            tracker_tool: handclasp_cell::cell::TIP_TOOL.into(),
            plane_sigma_m: 0.1e-3,
            plane_max_tilt_rad: 20f64.to_radians(),
        }
    }
}

/// The seeded truth of a simulated session's nuisances (m, rad, b1 frame).
#[derive(Debug, Clone, PartialEq)]
pub struct NuisanceTruth {
    /// The tracker frame: `tracker_from_b1`.
    pub tracker_from_b1: Isometry3<f64>,
    /// The plane `{p_b1 : n·p_b1 = d}`: unit normal (b1) and offset d, m.
    pub plane_b1: (Unit<Vector3<f64>>, f64),
    /// The contact distance, m.
    pub contact_distance_m: f64,
}

/// One teach point: where (b1, m) and, from a plan, the planned joints (rad) to seed the IK.
#[derive(Debug, Clone, PartialEq)]
pub struct Teach {
    /// Robot 1's tip (the meeting point), m, b1.
    pub p_b1: Point3<f64>,
    /// Planned joints `(q1, q2)`, rad, if any.
    pub planned: Option<(Vec<f64>, Vec<f64>)>,
}

/// Teach points from a plan (a session of this cell, e.g. `handclasp plan`'s `plan.csv`): each
/// coincident row's robot 1 nominal tip (`p_b1`), with both robots' joints as IK seeds.
/// Errors: the plan has rows of other kinds or no row.
pub fn teach_from_plan(plan: &Session) -> Result<Vec<Teach>, SimError> {
    if !plan.is_handclasp_only() || plan.points.is_empty() {
        return Err(SimError::InvalidInput(format!(
            "a plan must hold coincident handclasps at the default tips only (it has {} of them and {} other rows)",
            plan.points.len(),
            plan.observations.len()
        )));
    }
    Ok(plan
        .points
        .iter()
        .map(|p| Teach {
            p_b1: p.p_b1,
            planned: Some((p.q1.clone(), p.q2.clone())),
        })
        .collect())
}

fn check_spec(k: &KindSpec) -> Result<(), SimError> {
    for (name, v, zero_ok) in [
        (
            "contact distance (--contact-distance-mm)",
            k.contact_distance_m,
            true,
        ),
        ("contact σ (--contact-sigma-mm)", k.contact_sigma_m, false),
        ("face slide (--face-slide-mm)", k.face_slide_m, true),
        ("face tilt (--face-tilt-deg)", k.face_tilt_max_rad, true),
        ("tracker σ (--tracker-sigma-mm)", k.tracker_sigma_m, false),
        ("plane σ (--plane-sigma-mm)", k.plane_sigma_m, false),
        ("plane tilt", k.plane_max_tilt_rad, true),
    ] {
        if !(v.is_finite() && (v > 0.0 || (zero_ok && v == 0.0))) {
            return Err(SimError::InvalidInput(format!(
                "the {name} is {v}; give a finite value {} (mm)",
                if zero_ok { "≥ 0" } else { "> 0" }
            )));
        }
    }
    Ok(())
}

/// The kind of teach point `i` (0-based) and, for one-robot kinds, its robot (always robot 1
/// in a one-robot cell, `one_robot`).
fn kind_of(kind: SimKind, i: usize, one_robot: bool) -> (SimKind, Robot) {
    let alternate = if one_robot || i.is_multiple_of(2) {
        Robot::One
    } else {
        Robot::Two
    };
    match kind {
        SimKind::Mixed => match i % 6 {
            0 => (SimKind::Coincident, Robot::One),
            1 => (SimKind::Contact, Robot::One),
            2 => (SimKind::Tracker, Robot::One),
            3 => (SimKind::Plane, Robot::One),
            4 => (SimKind::Tracker, Robot::Two),
            _ => (SimKind::Plane, Robot::Two),
        },
        other => (other, alternate),
    }
}

/// Draws the nuisance truth: a tracker 2–3 m from the teach centre, level to ±2°, turned
/// anywhere about the vertical; a plane through the centre tilted up to
/// `plane_max_tilt_rad` from level; the contact distance of `k`.
fn draw_truth(
    cell: &Cell,
    centre: &Point3<f64>,
    k: &KindSpec,
    rng: &mut impl Rng,
) -> NuisanceTruth {
    let up = Unit::new_normalize(-cell.robot1.g_base);
    let level = Rotation3::rotation_between(&Vector3::z(), &up).unwrap_or_else(Rotation3::identity);
    let yaw: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let dist: f64 = rng.random_range(2.0..3.0);
    let small = 2f64.to_radians();
    let tilt = Vector3::new(
        rng.random_range(-small..small),
        rng.random_range(-small..small),
        0.0,
    );
    let heading: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let tracker_in_level = Vector3::new(dist * yaw.cos(), dist * yaw.sin(), 0.3);
    let b1_from_tracker = Isometry3::from_parts(
        Translation3::from(centre.coords + level * tracker_in_level),
        UnitQuaternion::from_rotation_matrix(&level)
            * UnitQuaternion::from_scaled_axis(tilt)
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), heading),
    );
    let az: f64 = rng.random_range(0.0..std::f64::consts::TAU);
    let t: f64 = rng.random_range(0.0..=k.plane_max_tilt_rad);
    let n_level = Vector3::new(t.sin() * az.cos(), t.sin() * az.sin(), t.cos());
    let n = Unit::new_normalize(level * n_level);
    NuisanceTruth {
        tracker_from_b1: b1_from_tracker.inverse(),
        plane_b1: (n, n.dot(&centre.coords)),
        contact_distance_m: k.contact_distance_m,
    }
}

/// Simulates a session of `kinds.kind` on `cell` with teach points from `spec` (a layout draw,
/// redrawn up to [`MAX_LAYOUT_ATTEMPTS`] times until every point is reachable, or
/// `spec.points_b1`) or, when `plan` is given, from the plan ([`teach_from_plan`]). Returns the
/// session and the nuisances' truth, drawn first from `rng`.
///
/// Per kind (truth = the cell's true robots, reported joints quantised as in
/// [`generate_session`], tips in the rows by the nominal models):
/// - coincident: as [`generate_session`] (which it calls when there is no plan);
/// - contact: robot 2's true tip at `p + (d + σ_c·ν)·û`, `û` the approach direction of robot 1;
/// - face contact: the touching faces' normal `n` is the approach direction `û` tilted by
///   `θ ~ U(0, face_tilt_max_rad)` toward azimuth `φ ~ U(0, 2π)` of the tangent basis
///   `(t1, t2)` of `û` ([`calib_core::whole_cell::tangent_basis`]):
///   `n = cos θ·û + sin θ·(cos φ·t1 + sin φ·t2)` (which face of a polyhedral marker touches
///   varies); robot 2's true tip at `p + (d + σ_c·ν)·n + a·e1 + b·e2`, a slide of the faces
///   with `a, b ~ U(±face_slide_m)` along the tangent basis `(e1, e2)` of `n`; robot 1's face
///   normal is `n` and robot 2's `−n` (flush), written in each tip frame with the TRUE robot's
///   rotation at the reported (quantised) joints: `n1_tip = R1ᵀ·n`, `n2_tip = R2ᵀ·R_Xᵀ·(−n)`;
/// - tracker: the robot's true tool point at `p`, measured as `tracker_from_b1·p + N(0, σ_t²I)`;
/// - plane: the true tip at `p` projected onto the plane and moved `σ_p·ν` along its normal,
///   approached along the normal where reachable.
///
/// Errors: an invalid spec (naming the setting), a tracker tool the robot lacks, or a teach
/// point no robot reaches (naming it).
pub fn generate_kind_session(
    cell: &Cell,
    spec: &SessionSpec,
    kinds: &KindSpec,
    plan: Option<&[Teach]>,
    rng: &mut impl Rng,
) -> Result<(Session, NuisanceTruth), SimError> {
    check_spec(kinds)?;
    if cell.one_robot && !matches!(kinds.kind, SimKind::Tracker | SimKind::Plane) {
        return Err(SimError::InvalidInput(format!(
            "--kind {}: this kind needs two robots, but the cell has only [robot1]; a one-robot \
             cell is simulated with --kind tracker or --kind plane",
            match kinds.kind {
                SimKind::Coincident => "coincident",
                SimKind::Contact => "contact",
                SimKind::FaceContact => "face_contact",
                _ => "mixed",
            }
        )));
    }
    let centre = spec.centre_b1.unwrap_or(cell.centre_b1);
    if kinds.kind == SimKind::Coincident && plan.is_none() {
        let truth = NuisanceTruth {
            tracker_from_b1: Isometry3::identity(),
            plane_b1: (Vector3::z_axis(), centre.z),
            contact_distance_m: kinds.contact_distance_m,
        };
        return Ok((generate_session(cell, spec, rng)?, truth));
    }
    let tracker_tools =
        [Robot::One, Robot::Two].map(|r| cell.robot(r).tool_index(&kinds.tracker_tool));
    if matches!(kinds.kind, SimKind::Tracker | SimKind::Mixed) {
        for (r, t) in cell.robots().iter().zip(&tracker_tools) {
            if t.is_none() {
                return Err(SimError::InvalidInput(format!(
                    "--tracker-tool `{}`: {r} has no such tool; its tools are {} (add it to [robot{}.tools] of the cell)",
                    kinds.tracker_tool,
                    cell.robot(*r).tool_names().join(", "),
                    r.number()
                )));
            }
        }
    }
    let truth = draw_truth(cell, &centre, kinds, rng);
    let sim = Sim {
        cell,
        kinds,
        truth: &truth,
        tracker_tools: tracker_tools.map(|t| t.unwrap_or(0)),
    };
    if let Some(teach) = plan {
        let mut session = Session::default();
        for (i, t) in teach.iter().enumerate() {
            sim.row(t, i, &mut session, rng)
                .map_err(|(robot, why)| unreachable(cell, i + 1, &t.p_b1, robot, &why, None))?;
        }
        return Ok((session, truth));
    }
    if let Some(points) = &spec.points_b1 {
        let mut session = Session::default();
        for (i, p) in points.iter().enumerate() {
            if !p.iter().all(|x| x.is_finite()) {
                return Err(SimError::InvalidInput(format!(
                    "teach point {} is not finite",
                    i + 1
                )));
            }
            let t = Teach {
                p_b1: *p,
                planned: None,
            };
            sim.row(&t, i, &mut session, rng)
                .map_err(|(robot, why)| unreachable(cell, i + 1, p, robot, &why, None))?;
        }
        return Ok((session, truth));
    }
    if spec.n == 0 {
        return Err(SimError::InvalidInput(
            "a session needs at least 1 point".into(),
        ));
    }
    if !(spec.spread_m.is_finite() && spec.spread_m > 0.0) {
        return Err(SimError::InvalidInput(format!(
            "spread {} mm must be a positive length (e.g. 1000)",
            spec.spread_m * 1e3
        )));
    }
    let mut last_fail = None;
    'draw: for _ in 0..MAX_LAYOUT_ATTEMPTS {
        let pts = teach_points(spec.layout, spec.n, spec.spread_m, &centre, rng);
        let mut session = Session::default();
        for (i, p) in pts.iter().enumerate() {
            let t = Teach {
                p_b1: *p,
                planned: None,
            };
            if let Err((robot, why)) = sim.row(&t, i, &mut session, rng) {
                last_fail = Some((i + 1, *p, robot, why));
                continue 'draw;
            }
        }
        return Ok((session, truth));
    }
    let (i, p, robot, why) = last_fail.unwrap_or((1, centre, Robot::One, String::new()));
    Err(unreachable(cell, i, &p, robot, &why, Some(spec)))
}

struct Sim<'a> {
    cell: &'a Cell,
    kinds: &'a KindSpec,
    truth: &'a NuisanceTruth,
    tracker_tools: [usize; 2],
}

impl Sim<'_> {
    /// Simulates teach point `i` (0-based, label `i + 1`) and appends its row.
    fn row(
        &self,
        t: &Teach,
        i: usize,
        session: &mut Session,
        rng: &mut impl Rng,
    ) -> Result<(), PointFailure> {
        let label = i + 1;
        let (kind, robot) = kind_of(self.kinds.kind, i, self.cell.one_robot);
        match kind {
            SimKind::Coincident => {
                let eps = gauss3(rng, &self.cell.noise.alignment_m);
                let (q1, q2) = self.pair(t, rng, |_| eps)?;
                let tip = |r: Robot, q: &[f64]| -> Result<Point3<f64>, PointFailure> {
                    let c = self.cell.robot(r);
                    base_from_tip(&c.model, q, &c.flange_from_tip)
                        .map(|x| Point3::from(x.translation.vector))
                        .map_err(|e| (r, e.to_string()))
                };
                session.points.push(SessionPoint {
                    point: label,
                    p_b1: tip(Robot::One, &q1)?,
                    p_b2: tip(Robot::Two, &q2)?,
                    q1,
                    q2,
                });
            }
            SimKind::Contact => {
                let nu: f64 = rng.sample(StandardNormal);
                let d = self.truth.contact_distance_m + self.kinds.contact_sigma_m * nu;
                let (q1, q2) = self.pair(t, rng, |u| u * d)?;
                session.observations.push(SessionObservation {
                    point: label,
                    kind: SessionKind::Contact {
                        q1,
                        q2,
                        tool1: 0,
                        tool2: 0,
                        group: CONTACT_GROUP.into(),
                        distance_m: self
                            .kinds
                            .contact_known
                            .then_some(self.truth.contact_distance_m),
                        sigma_m: self.kinds.contact_sigma_m,
                    },
                });
            }
            SimKind::FaceContact => {
                let nu: f64 = rng.sample(StandardNormal);
                let d = self.truth.contact_distance_m + self.kinds.contact_sigma_m * nu;
                let slide = self.kinds.face_slide_m;
                let a: f64 = rng.random_range(-slide..=slide);
                let b: f64 = rng.random_range(-slide..=slide);
                let theta: f64 = rng.random_range(0.0..=self.kinds.face_tilt_max_rad);
                let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                // The face normal for approach direction `u` (b1).
                let normal = |u: Vector3<f64>| {
                    let (t1, t2) = tangent_basis(&Unit::new_normalize(u));
                    Unit::new_normalize(
                        u * theta.cos() + (t1 * phi.cos() + t2 * phi.sin()) * theta.sin(),
                    )
                };
                let (q1, q2, approach) = self.pair_along(t, rng, |u| {
                    let n = normal(u);
                    let (e1, e2) = tangent_basis(&n);
                    n.into_inner() * d + e1 * a + e2 * b
                })?;
                let u = normal(approach).into_inner();
                let cell = self.cell;
                // Each tip frame's true rotation at the row: on a shared trunk with the trunk
                // deflected by the other arm's weight (`q_other`), as the tips were solved and
                // as the fit models the normals (µrad, but the same truth throughout).
                let rotation = |r: Robot, q: &[f64], q_other: &[f64]| {
                    let own = cell.robot(r);
                    let loaded;
                    let c = if cell.shared_joints > 0 {
                        loaded = crate::trunk::loaded(cell, r, own, q_other)?;
                        &loaded
                    } else {
                        own
                    };
                    true_base_from_tip(
                        &c.model,
                        &tool_errors(c, 0),
                        q,
                        &c.flange_from_tip,
                        &c.g_base,
                    )
                    .map(|x| x.rotation)
                    .map_err(|e| (r, e.to_string()))
                };
                let n1_tip = Unit::new_normalize(rotation(Robot::One, &q1, &q2)?.inverse() * u);
                let n2_b2 = cell.b1_from_b2.rotation.inverse() * -u;
                let n2_tip = Unit::new_normalize(rotation(Robot::Two, &q2, &q1)?.inverse() * n2_b2);
                session.observations.push(SessionObservation {
                    point: label,
                    kind: SessionKind::FaceContact {
                        q1,
                        q2,
                        tool1: 0,
                        tool2: 0,
                        n1_tip,
                        n2_tip,
                        group: CONTACT_GROUP.into(),
                        distance_m: self
                            .kinds
                            .contact_known
                            .then_some(self.truth.contact_distance_m),
                        sigma_m: self.kinds.contact_sigma_m,
                    },
                });
            }
            SimKind::Tracker => {
                let tool = self.tracker_tools[usize::from(robot.number() - 1)];
                let (q, p_true_b1, q_other) = self.one(robot, tool, &t.p_b1, None, t, rng)?;
                if let Some(q_other) = q_other {
                    session.other_arm_q.insert(label, q_other);
                }
                let noise = gauss3(rng, &Vector3::repeat(self.kinds.tracker_sigma_m));
                session.observations.push(SessionObservation {
                    point: label,
                    kind: SessionKind::Tracker {
                        robot,
                        q,
                        tool,
                        group: TRACKER_GROUP.into(),
                        p_tracker: self.truth.tracker_from_b1 * p_true_b1 + noise,
                        sigma_m: self.kinds.tracker_sigma_m,
                    },
                });
            }
            _ => {
                let (n, d) = self.truth.plane_b1;
                let nu: f64 = rng.sample(StandardNormal);
                let on_plane = t.p_b1 - n.into_inner() * (n.dot(&t.p_b1.coords) - d);
                let target = on_plane + n.into_inner() * (self.kinds.plane_sigma_m * nu);
                let (q, _, q_other) = self.one(robot, 0, &target, Some(-n), t, rng)?;
                if let Some(q_other) = q_other {
                    session.other_arm_q.insert(label, q_other);
                }
                session.observations.push(SessionObservation {
                    point: label,
                    kind: SessionKind::Plane {
                        robot,
                        q,
                        tool: 0,
                        group: PLANE_GROUP.into(),
                        sigma_m: self.kinds.plane_sigma_m,
                    },
                });
            }
        }
        Ok(())
    }

    /// Both robots' reported joints for a meeting at `t.p_b1`: robot 1's true tip at `p + δ1`,
    /// robot 2's at `p + offset(û) + δ2` (b1), `û` the approach direction; head-on approaches
    /// tried in turn (the planned flange axes first, with the planned joints as seeds).
    fn pair(
        &self,
        t: &Teach,
        rng: &mut impl Rng,
        offset: impl Fn(Vector3<f64>) -> Vector3<f64>,
    ) -> Result<(Vec<f64>, Vec<f64>), PointFailure> {
        self.pair_along(t, rng, offset).map(|(q1, q2, _)| (q1, q2))
    }

    /// [`Sim::pair`], with the approach direction `û` (b1, unit) the meeting took.
    fn pair_along(
        &self,
        t: &Teach,
        rng: &mut impl Rng,
        offset: impl Fn(Vector3<f64>) -> Vector3<f64>,
    ) -> Result<Meeting, PointFailure> {
        let cell = self.cell;
        let rep = Vector3::repeat(cell.noise.repeatability_m);
        let d1 = gauss3(rng, &rep);
        let d2 = gauss3(rng, &rep);
        let b2_from_b1 = cell.b1_from_b2.inverse();
        let mut dirs = Vec::new();
        if let Some((q1, _)) = &t.planned {
            if let Ok(f) = base_from_tip(&cell.robot1.model, q1, &cell.robot1.flange_from_tip) {
                dirs.push(Unit::new_normalize(f.rotation * Vector3::z()));
            }
        }
        dirs.extend(crate::simulate::meeting_directions(cell, &t.p_b1));
        let seeds = t
            .planned
            .as_ref()
            .map(|(a, b)| (a.as_slice(), b.as_slice()));
        if cell.shared_joints > 0 {
            let target2 = |u: &Vector3<f64>| b2_from_b1 * (t.p_b1 + offset(*u)) + d2;
            return crate::trunk::meet_on_trunk(cell, &(t.p_b1 + d1), &target2, &dirs, seeds, rng);
        }
        let mut last = (Robot::One, String::new());
        for d in dirs {
            let target1 = t.p_b1 + d1;
            let target2 = b2_from_b1 * (t.p_b1 + offset(d.into_inner())) + d2;
            let Some(mut q1) =
                solve_true_tool(&cell.robot1, 0, &target1, Some(d), seeds.map(|s| s.0))
            else {
                last = (Robot::One, "robot 1 cannot reach it head-on".into());
                continue;
            };
            let axis2 = Unit::new_normalize(b2_from_b1.rotation * -d.into_inner());
            let Some(mut q2) =
                solve_true_tool(&cell.robot2, 0, &target2, Some(axis2), seeds.map(|s| s.1))
            else {
                last = (Robot::Two, "robot 2 cannot reach it head-on".into());
                continue;
            };
            quantise(&cell.robot1, &mut q1, cell.noise.encoder_resolution_rad);
            quantise(&cell.robot2, &mut q2, cell.noise.encoder_resolution_rad);
            return Ok((q1, q2, d.into_inner()));
        }
        Err(last)
    }

    /// One robot's reported joints with its true tool point at `target_b1` (+ repeatability),
    /// approached along `axis_b1` if reachable, else along the handclasp directions, else in any
    /// orientation; returns them with the true tool point after quantisation (b1) and, on a
    /// shared-trunk cell, the other arm's posture ([`Sim::other_arm`]), whose weight deflects
    /// the trunk joints by their compliance ([`crate::trunk::branch_offsets`]): the inverse kinematics
    /// is redone [`crate::trunk::TRUNK_LOAD_PASSES`] times with that deflection at the last solution's trunk.
    #[allow(clippy::type_complexity)] // (joints, true tool point, the other arm's joints)
    fn one(
        &self,
        robot: Robot,
        tool: usize,
        target_b1: &Point3<f64>,
        axis_b1: Option<Unit<Vector3<f64>>>,
        t: &Teach,
        rng: &mut impl Rng,
    ) -> Result<(Vec<f64>, Point3<f64>, Option<Vec<f64>>), PointFailure> {
        let cell = self.cell;
        let c = cell.robot(robot);
        let rep = gauss3(rng, &Vector3::repeat(cell.noise.repeatability_m));
        let b_from_b1 = match robot {
            Robot::One => Isometry3::identity(),
            Robot::Two => cell.b1_from_b2.inverse(),
        };
        let target = b_from_b1 * target_b1 + rep;
        let seed = t.planned.as_ref().map(|(a, b)| match robot {
            Robot::One => a.as_slice(),
            Robot::Two => b.as_slice(),
        });
        let mut q_other = (cell.shared_joints > 0).then(|| self.other_arm(robot, rng));
        let mut axes: Vec<Option<Unit<Vector3<f64>>>> = axis_b1.into_iter().map(Some).collect();
        axes.extend(approach_directions(cell, target_b1).into_iter().map(|d| {
            // Robot 2 approaches from the other side in a handclasp.
            let d = if robot == Robot::Two { -d } else { d };
            Some(d)
        }));
        axes.push(None);
        // The robot as it is at this row: its errors, plus the trunk's deflection under the
        // other arm at `q` (the trunk's joints taken from `q`).
        let loaded = |q: &[f64], q_other: &mut Vec<f64>| -> Result<_, PointFailure> {
            let trunk = cell.shared_independent_joints().min(q.len());
            q_other[..trunk].copy_from_slice(&q[..trunk]);
            crate::trunk::loaded(cell, robot, c, q_other)
        };
        for axis in axes {
            let axis_b = axis.map(|a| Unit::new_normalize(b_from_b1.rotation * a.into_inner()));
            let Some(mut q) = solve_true_tool(c, tool, &target, axis_b, seed) else {
                continue;
            };
            let mut true_robot = c.clone();
            if let Some(q_other) = q_other.as_mut() {
                for _ in 0..TRUNK_LOAD_PASSES {
                    true_robot = loaded(&q, q_other)?;
                    match solve_true_tool(&true_robot, tool, &target, axis_b, Some(&q)) {
                        Some(again) => q = again,
                        None => break,
                    }
                }
            }
            quantise(c, &mut q, cell.noise.encoder_resolution_rad);
            if let Some(q_other) = q_other.as_mut() {
                true_robot = loaded(&q, q_other)?;
            }
            let flange_from_tool = c.flange_from_tool(tool).unwrap_or(c.flange_from_tip);
            let tip = true_base_from_tip(
                &true_robot.model,
                &tool_errors(&true_robot, tool),
                &q,
                &flange_from_tool,
                &true_robot.g_base,
            )
            .map_err(|e| (robot, e.to_string()))?;
            let p_b1 = b_from_b1.inverse() * Point3::from(tip.translation.vector);
            return Ok((q, p_b1, q_other));
        }
        Err((robot, format!("{robot} cannot reach it")))
    }

    /// The other arm's posture at a one-robot row of `robot` on a shared-trunk cell: each of
    /// its independent joints uniform in the middle 80 % of its limits (clipped to ±3 rad or
    /// m); the trunk's are overwritten with the measured arm's ([`Sim::one`]).
    fn other_arm(&self, robot: Robot, rng: &mut impl Rng) -> Vec<f64> {
        crate::trunk::draw_in_middle(self.cell.robot(robot.other()).model.joints(), rng)
    }
}

/// Reads teach points (`sim-cell session --points-csv`): a CSV with columns `x_mm,y_mm,z_mm`
/// (robot 1's tip, base 1, mm; found by name, any order, extra columns ignored; comma,
/// semicolon or tab separated), one point per row. Returns them in m.
///
/// Errors name the line and column: a missing column, a value that is not a finite number, no
/// point at all.
pub fn read_points_b1_csv(path: &std::path::Path) -> Result<Vec<Point3<f64>>, SimError> {
    let text = kinematics::input::read_input_text(path, "points CSV").map_err(|e| match e {
        kinematics::input::InputError::Io { source, .. } => SimError::io(path, source),
        other => SimError::Format(handclasp_cell::FormatError::InputFile(other)),
    })?;
    parse_points_b1_csv(&text, path)
}

/// Parses the text of [`read_points_b1_csv`].
pub fn parse_points_b1_csv(
    text: &str,
    path: &std::path::Path,
) -> Result<Vec<Point3<f64>>, SimError> {
    let err = |message: String| SimError::Session {
        path: path.to_path_buf(),
        message,
    };
    let mut reader = calib_core::csv_reader(text);
    let headers = reader
        .headers()
        .map_err(|e| err(format!("line 1: the header is not valid CSV: {e}")))?
        .clone();
    let names = ["x_mm", "y_mm", "z_mm"];
    let mut idx = [0usize; 3];
    for (a, name) in names.iter().enumerate() {
        idx[a] = headers.iter().position(|h| h == *name).ok_or_else(|| {
            err(format!(
                "line 1: the header has no column `{name}`; a points file has the columns x_mm,y_mm,z_mm \
                 (robot 1's tip in base 1, mm, one point per row)"
            ))
        })?;
    }
    let mut out = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            err(format!("line {line}: not valid CSV: {e}"))
        })?;
        let line = record.position().map_or(0, |p| p.line());
        if record.iter().all(str::is_empty) {
            continue;
        }
        let mut p = [0.0; 3];
        for a in 0..3 {
            let c = record.get(idx[a]).unwrap_or("");
            p[a] = c
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    err(format!(
                        "line {line}, column `{}`: `{c}` is not a finite number (mm)",
                        names[a]
                    ))
                })?
                * 1e-3;
        }
        out.push(Point3::from(p));
    }
    if out.is_empty() {
        return Err(err(
            "no point: give one row of x_mm,y_mm,z_mm per teach point".into(),
        ));
    }
    Ok(out)
}

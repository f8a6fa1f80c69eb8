//! What part of the robots' workspace a session saw: per joint, the range the session's joint
//! vectors cover against the joint's limits; per robot, the region of its tool points against
//! its reach, sampled from its model within the joint limits.
//!
//! A calibration is checked where it has data; away from it, the fitted corrections extrapolate
//! (issue 20: joint offsets that absorb gravity sag in two small grids change sign elsewhere).
//! This report says how far "away" reaches: a joint whose session range is a tenth of its
//! travel, a reach shell the session never visits.
//!
//! # Definitions ([`session_coverage`])
//! - **Rows of a robot**: every observation that carries its joints (coincident, contact and
//!   face-contact rows for both robots; tracker and plane rows for theirs).
//! - **Joint range**: `[min_i q_j, max_i q_j]` over those rows against `[lower_j, upper_j]`;
//!   `fraction = (max − min)/(upper − lower)` (a continuous joint's travel is taken as 2π).
//! - **Cylindrical frame of a robot**: the line of its first joint's axis at `q = 0` (through
//!   that joint's origin, in the robot's base frame). A tool point's `height` is its coordinate
//!   along the axis, its `radius` its distance from the line, its `azimuth` the angle about it
//!   (zero along the base x axis projected on the plane normal to the axis, or base y when x is
//!   parallel to the axis).
//! - **Region of the session's tool points**: each row's nominal tool point (FK of the row's
//!   joints with its tool) in the robot's base frame: the box in x, y, z and the cylinder
//!   `[radius] × [height] × [azimuth arc]`, the arc being the shortest one holding every
//!   azimuth (the complement of the largest gap between them).
//! - **Reach**: the same quantities over [`ENVELOPE_SAMPLES`] joint vectors drawn uniformly
//!   within the joint limits (seeded: [`crate::stats::trial_rng`]`(seed, robot number)`), tool 0
//!   (the cell's tip). `reach_fraction_in_region` is the fraction of those samples that fall
//!   inside the session's cylinder: how much of the robot's reach the session's region spans.
//!   The reach ignores collisions (self, the other robot, the cell's fixtures), so it overstates
//!   what the robot can use; a fraction well below 1 still means the calibration is asked to
//!   extrapolate there.

use std::f64::consts::PI;

use kinematics::base_from_tip;
use nalgebra::{Point3, Unit, Vector3};
use rand::Rng;
use serde::Serialize;

use super::{CellFitError, CellProblem, CellRobot};
use crate::Robot;

/// Joint vectors drawn within the limits to sample each robot's reach.
pub const ENVELOPE_SAMPLES: usize = 4000;

/// One joint's coverage (SI: rad, or m for a prismatic joint).
#[derive(Debug, Clone, PartialEq)]
pub struct JointCoverage {
    /// The URDF joint name.
    pub name: String,
    /// Smallest and largest value over the robot's rows.
    pub session_range: [f64; 2],
    /// The joint's limits (a continuous joint: `[−π, π]`).
    pub limits: [f64; 2],
    /// `(max − min)/(upper − lower)`, in `[0, 1]`.
    pub fraction: f64,
    /// True for a prismatic joint (values in m).
    pub prismatic: bool,
}

/// A region of tool points in one robot's base frame (m, rad): a box and a cylinder about the
/// first joint's axis (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointRegion {
    /// Smallest x, y, z, m.
    pub min: Vector3<f64>,
    /// Largest x, y, z, m.
    pub max: Vector3<f64>,
    /// Smallest and largest distance from the first joint's axis, m.
    pub radius: [f64; 2],
    /// Smallest and largest coordinate along the first joint's axis, m.
    pub height: [f64; 2],
    /// Start and length of the shortest azimuth arc holding every point, rad (start in
    /// `[−π, π)`, length in `[0, 2π]`).
    pub azimuth_arc: [f64; 2],
}

/// One robot's coverage.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotCoverage {
    /// Which robot.
    pub robot: Robot,
    /// Observations that carry its joints.
    pub rows: usize,
    /// Per independent joint, chain order.
    pub joints: Vec<JointCoverage>,
    /// The region of the session's tool points (`None` without rows).
    pub session: Option<PointRegion>,
    /// The region of the sampled reach (tool 0).
    pub reach: PointRegion,
    /// Fraction of the reach samples inside the session's cylinder (0 without rows).
    pub reach_fraction_in_region: f64,
}

/// Both robots' coverage ([`session_coverage`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SessionCoverage {
    /// Robot 1, then robot 2.
    pub robots: [RobotCoverage; 2],
    /// Reach samples per robot ([`ENVELOPE_SAMPLES`]).
    pub reach_samples: usize,
    /// Seed of the reach samples.
    pub seed: u64,
}

/// The cylindrical frame of a robot: origin and unit axis of its first joint at `q = 0`, and
/// the azimuth's zero direction.
struct Cylinder {
    origin: Point3<f64>,
    axis: Unit<Vector3<f64>>,
    zero: Unit<Vector3<f64>>,
}

impl Cylinder {
    fn of(robot: &CellRobot) -> Cylinder {
        let (origin, axis) = match robot.model.chain_joints().first() {
            Some(j) => {
                let base_from_joint =
                    j.fixed_prefix * kinematics::origin_isometry(&j.origin_xyz, &j.origin_rpy);
                (
                    Point3::from(base_from_joint.translation.vector),
                    Unit::new_normalize(base_from_joint.rotation * j.axis.into_inner()),
                )
            }
            None => (Point3::origin(), Vector3::z_axis()),
        };
        let zero = [Vector3::x(), Vector3::y()]
            .into_iter()
            .find_map(|v| Unit::try_new(v - axis.into_inner() * axis.dot(&v), 1e-6))
            .unwrap_or(Vector3::x_axis());
        Cylinder { origin, axis, zero }
    }

    /// `(radius, height, azimuth)` of `p`.
    fn coordinates(&self, p: &Point3<f64>) -> (f64, f64, f64) {
        let d = p - self.origin;
        let height = self.axis.dot(&d);
        let radial = d - self.axis.into_inner() * height;
        let y = self.axis.cross(&self.zero);
        (
            radial.norm(),
            height,
            y.dot(&radial).atan2(self.zero.dot(&radial)),
        )
    }
}

/// The region of `points` (non-empty) in `cyl`'s frame.
fn region(cyl: &Cylinder, points: &[Point3<f64>]) -> PointRegion {
    let mut min = Vector3::repeat(f64::INFINITY);
    let mut max = Vector3::repeat(f64::NEG_INFINITY);
    let mut radius = [f64::INFINITY, f64::NEG_INFINITY];
    let mut height = [f64::INFINITY, f64::NEG_INFINITY];
    let mut azimuths = Vec::with_capacity(points.len());
    for p in points {
        min = min.inf(&p.coords);
        max = max.sup(&p.coords);
        let (r, h, a) = cyl.coordinates(p);
        radius = [radius[0].min(r), radius[1].max(r)];
        height = [height[0].min(h), height[1].max(h)];
        azimuths.push(a);
    }
    PointRegion {
        min,
        max,
        radius,
        height,
        azimuth_arc: shortest_arc(&mut azimuths),
    }
}

/// `[start, length]` of the shortest arc holding every angle of `a` (rad, in `[−π, π]`): the
/// complement of the largest gap between consecutive sorted angles (the wrap-around gap
/// included). `[0, 0]` for no angle.
fn shortest_arc(a: &mut [f64]) -> [f64; 2] {
    if a.is_empty() {
        return [0.0, 0.0];
    }
    a.sort_by(f64::total_cmp);
    let n = a.len();
    // The gap after a[i] (the last one wraps to a[0] + 2π).
    let gap = |i: usize| {
        if i + 1 < n {
            a[i + 1] - a[i]
        } else {
            a[0] + 2.0 * PI - a[n - 1]
        }
    };
    let widest = (0..n)
        .max_by(|&i, &j| gap(i).total_cmp(&gap(j)))
        .unwrap_or(n - 1);
    let start = a[(widest + 1) % n];
    let length = 2.0 * PI - gap(widest);
    let start = if start >= PI { start - 2.0 * PI } else { start };
    [start, length.clamp(0.0, 2.0 * PI)]
}

/// Whether azimuth `a` lies on the arc `[start, start + length]` (rad).
fn on_arc(a: f64, arc: [f64; 2]) -> bool {
    (a - arc[0]).rem_euclid(2.0 * PI) <= arc[1] + 1e-12
}

/// The coverage of one robot from its rows' `(q, tool)` (see [`session_coverage`]).
fn robot_coverage(
    robot: Robot,
    r: &CellRobot,
    rows: &[(&[f64], usize)],
    seed: u64,
) -> Result<RobotCoverage, CellFitError> {
    let model = &r.model;
    let joints = model
        .joints()
        .iter()
        .enumerate()
        .map(|(j, joint)| {
            let limits = if joint.lower.is_finite() && joint.upper.is_finite() {
                [joint.lower, joint.upper]
            } else {
                [-PI, PI]
            };
            let (lo, hi) = rows
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, (q, _)| {
                    (acc.0.min(q[j]), acc.1.max(q[j]))
                });
            let travel = limits[1] - limits[0];
            let fraction = if rows.is_empty() || travel <= 0.0 {
                0.0
            } else {
                ((hi - lo) / travel).clamp(0.0, 1.0)
            };
            JointCoverage {
                name: joint.name.clone(),
                session_range: if rows.is_empty() {
                    [0.0, 0.0]
                } else {
                    [lo, hi]
                },
                limits,
                fraction,
                prismatic: joint.kind.is_prismatic(),
            }
        })
        .collect::<Vec<_>>();
    let cyl = Cylinder::of(r);
    let tool_point = |q: &[f64], tool: usize| {
        let flange_from_tip = r
            .tools
            .get(tool)
            .map_or_else(Vector3::zeros, |t| t.flange_from_tip);
        base_from_tip(model, q, &flange_from_tip)
            .map(|b| Point3::from(b.translation.vector))
            .map_err(|e| CellFitError::InvalidInput(format!("coverage: {robot}: {e}")))
    };
    let session_points = rows
        .iter()
        .map(|(q, tool)| tool_point(q, *tool))
        .collect::<Result<Vec<_>, _>>()?;
    let mut rng = crate::stats::trial_rng(seed, u64::from(robot.number()));
    let reach_points = (0..ENVELOPE_SAMPLES)
        .map(|_| {
            let q: Vec<f64> = joints
                .iter()
                .map(|j| rng.random_range(j.limits[0]..=j.limits[1]))
                .collect();
            tool_point(&q, 0)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let reach = region(&cyl, &reach_points);
    let session = (!session_points.is_empty()).then(|| region(&cyl, &session_points));
    let reach_fraction_in_region = session.map_or(0.0, |s| {
        let inside = reach_points
            .iter()
            .filter(|p| {
                let (rad, h, a) = cyl.coordinates(p);
                rad >= s.radius[0]
                    && rad <= s.radius[1]
                    && h >= s.height[0]
                    && h <= s.height[1]
                    && on_arc(a, s.azimuth_arc)
            })
            .count();
        inside as f64 / reach_points.len() as f64
    });
    Ok(RobotCoverage {
        robot,
        rows: rows.len(),
        joints,
        session,
        reach,
        reach_fraction_in_region,
    })
}

/// The coverage of `problem`'s observations (all of them, rejected blunders included: their
/// joints are still where the session went) against both robots' joint limits and reach (see
/// the module documentation). Seeded (`seed`): identical for a seed on any machine.
///
/// Errors: an observation whose joints or tool the robot's model rejects (its message names
/// the robot).
pub fn session_coverage(problem: &CellProblem, seed: u64) -> Result<SessionCoverage, CellFitError> {
    let mut rows: [Vec<(&[f64], usize)>; 2] = [Vec::new(), Vec::new()];
    for o in &problem.observations {
        for ((robot, q), (_, tool)) in o.kind.joints().into_iter().zip(o.kind.tools()) {
            rows[usize::from(robot.number() - 1)].push((q, tool));
        }
    }
    let one = robot_coverage(Robot::One, &problem.robot1, &rows[0], seed)?;
    let two = robot_coverage(Robot::Two, &problem.robot2, &rows[1], seed)?;
    Ok(SessionCoverage {
        robots: [one, two],
        reach_samples: ENVELOPE_SAMPLES,
        seed,
    })
}

/// One joint's coverage in file units: degrees (mm for a prismatic joint).
#[derive(Debug, Clone, Serialize)]
pub struct JointCoverageReport {
    /// Share of the joint's travel the session spans, in `[0, 1]`.
    pub fraction: f64,
    /// 1-based joint number (chain order of the independent joints).
    pub joint: usize,
    /// `[lower, upper]` limits.
    pub limits: [f64; 2],
    /// The URDF joint name.
    pub name: String,
    /// `[min, max]` over the session's rows.
    pub session_range: [f64; 2],
    /// `deg`, or `mm` for a prismatic joint.
    pub unit: &'static str,
}

/// A region of tool points in file units (mm, degrees), in the robot's own base frame.
#[derive(Debug, Clone, Serialize)]
pub struct PointRegionReport {
    /// Start and length of the shortest azimuth arc about the first joint's axis holding every
    /// point, degrees.
    pub azimuth_arc_deg: [f64; 2],
    /// Smallest and largest coordinate along the first joint's axis, mm.
    pub height_mm: [f64; 2],
    /// Largest x, y, z, mm.
    pub max_mm: [f64; 3],
    /// Smallest x, y, z, mm.
    pub min_mm: [f64; 3],
    /// Smallest and largest distance from the first joint's axis, mm.
    pub radius_mm: [f64; 2],
}

impl From<&PointRegion> for PointRegionReport {
    fn from(r: &PointRegion) -> Self {
        let mm = |v: [f64; 2]| v.map(|x| x * 1e3);
        PointRegionReport {
            azimuth_arc_deg: r.azimuth_arc.map(f64::to_degrees),
            height_mm: mm(r.height),
            max_mm: [r.max.x * 1e3, r.max.y * 1e3, r.max.z * 1e3],
            min_mm: [r.min.x * 1e3, r.min.y * 1e3, r.min.z * 1e3],
            radius_mm: mm(r.radius),
        }
    }
}

/// One robot's coverage in file units.
#[derive(Debug, Clone, Serialize)]
pub struct RobotCoverageReport {
    /// Per joint.
    pub joints: Vec<JointCoverageReport>,
    /// The sampled reach (tool 0, joint limits only).
    pub reach: PointRegionReport,
    /// Fraction of the reach samples inside the session's cylinder.
    pub reach_fraction_in_region: f64,
    /// The robot.
    pub robot: Robot,
    /// Observations that carry its joints.
    pub rows: usize,
    /// The session's tool points (`null` without rows).
    pub session: Option<PointRegionReport>,
}

/// The session's coverage in file units (mm, degrees; `handclasp calibrate --cell` and
/// `diagnose` print it as `coverage`). JSON keys in alphabetical order.
#[derive(Debug, Clone, Serialize)]
pub struct CoverageReport {
    /// Reach samples per robot.
    pub reach_samples: usize,
    /// Robot 1, then robot 2.
    pub robots: Vec<RobotCoverageReport>,
    /// Seed of the reach samples.
    pub seed: u64,
}

impl From<&SessionCoverage> for CoverageReport {
    fn from(c: &SessionCoverage) -> Self {
        let robots = c
            .robots
            .iter()
            .map(|r| RobotCoverageReport {
                joints: r
                    .joints
                    .iter()
                    .enumerate()
                    .map(|(j, jc)| {
                        let (unit, per) = if jc.prismatic {
                            ("mm", 1e3)
                        } else {
                            ("deg", 1f64.to_degrees())
                        };
                        JointCoverageReport {
                            fraction: jc.fraction,
                            joint: j + 1,
                            limits: jc.limits.map(|v| v * per),
                            name: jc.name.clone(),
                            session_range: jc.session_range.map(|v| v * per),
                            unit,
                        }
                    })
                    .collect(),
                reach: PointRegionReport::from(&r.reach),
                reach_fraction_in_region: r.reach_fraction_in_region,
                robot: r.robot,
                rows: r.rows,
                session: r.session.as_ref().map(PointRegionReport::from),
            })
            .collect();
        CoverageReport {
            reach_samples: c.reach_samples,
            robots,
            seed: c.seed,
        }
    }
}

/// A joint whose session range spans less than this share of its travel is narrowly covered
/// (see [`CoverageReport::warnings`]).
pub const NARROW_JOINT_FRACTION: f64 = 0.1;

/// A session whose tool-point region holds less than this share of a robot's sampled reach
/// covers it narrowly (see [`CoverageReport::warnings`]).
pub const NARROW_REACH_FRACTION: f64 = 0.01;

impl CoverageReport {
    /// One `warning: …` line (without the prefix) per robot whose coverage is narrow: a joint
    /// spanning less than [`NARROW_JOINT_FRACTION`] of its travel, or a tool-point region
    /// holding less than [`NARROW_REACH_FRACTION`] of the reach samples. Both thresholds are
    /// flags for the user, not inputs of any fit. Every session is an extrapolation outside its
    /// region (the text report gives the numbers); these flag a session that is a spot: a
    /// 30-point session in a 0.8 m cube of the shipped floor–floor cell's shared workspace
    /// spans 17–20 % of the least-used joints' travel and a region holding 2–5 % of each
    /// robot's reach, the intended use, and is not flagged. Below a tenth of a joint's travel,
    /// or a hundredth of the reach, terms the region does not vary (gravity sag, a scale) are
    /// absorbed by offsets that can change sign elsewhere (issue 20's CTU exports were fitted
    /// in two small grids and the self-contact zone).
    pub fn warnings(&self) -> Vec<String> {
        self.robots
            .iter()
            .filter(|r| r.rows > 0)
            .filter_map(|r| {
                let narrow: Vec<String> = r
                    .joints
                    .iter()
                    .filter(|j| j.fraction < NARROW_JOINT_FRACTION)
                    .map(|j| format!("j{} {:.0} %", j.joint, j.fraction * 100.0))
                    .collect();
                let small_region = r.reach_fraction_in_region < NARROW_REACH_FRACTION;
                if narrow.is_empty() && !small_region {
                    return None;
                }
                let mut causes = Vec::new();
                if !narrow.is_empty() {
                    causes.push(format!(
                        "joints spanning under {:.0} % of their travel ({})",
                        NARROW_JOINT_FRACTION * 100.0,
                        narrow.join(", ")
                    ));
                }
                if small_region {
                    causes.push(format!(
                        "tool points in a region holding {:.0} % of its reach (under {:.0} %)",
                        r.reach_fraction_in_region * 100.0,
                        NARROW_REACH_FRACTION * 100.0
                    ));
                }
                Some(format!(
                    "narrow coverage of robot {}: {}; the calibration is extrapolated outside \
                     the session's region: check it on poses where the robot will work \
                     (`handclasp validate`) before using it there",
                    r.robot.number(),
                    causes.join("; ")
                ))
            })
            .collect()
    }

    /// The text lines of the report (no trailing newline on each): per robot, one line of the
    /// joints' covered share and one of the tool points' region against the reach.
    pub fn text_lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "coverage (the session against the joint limits and the reach sampled at {} joint vectors within them; \
             a calibration is extrapolated outside it):",
            self.reach_samples
        )];
        for r in &self.robots {
            let joints: Vec<String> = r
                .joints
                .iter()
                .map(|j| {
                    format!(
                        "j{} {:.0}..{:.0} of {:.0}..{:.0} {} ({:.0} %)",
                        j.joint,
                        j.session_range[0],
                        j.session_range[1],
                        j.limits[0],
                        j.limits[1],
                        j.unit,
                        j.fraction * 100.0
                    )
                })
                .collect();
            out.push(format!(
                "  robot {} ({} rows) joints: {}",
                r.robot.number(),
                r.rows,
                joints.join(", ")
            ));
            let reach = &r.reach;
            match &r.session {
                None => out.push(format!(
                    "  robot {}: no row carries its joints; reach radius {:.0}..{:.0} mm, height {:.0}..{:.0} mm",
                    r.robot.number(),
                    reach.radius_mm[0],
                    reach.radius_mm[1],
                    reach.height_mm[0],
                    reach.height_mm[1]
                )),
                Some(s) => out.push(format!(
                    "  robot {} tool points: radius {:.0}..{:.0} mm of reach {:.0}..{:.0}, height {:.0}..{:.0} mm of {:.0}..{:.0}, \
                     azimuth arc {:.0}° of {:.0}°; {:.0} % of the reach lies in this region",
                    r.robot.number(),
                    s.radius_mm[0],
                    s.radius_mm[1],
                    reach.radius_mm[0],
                    reach.radius_mm[1],
                    s.height_mm[0],
                    s.height_mm[1],
                    reach.height_mm[0],
                    reach.height_mm[1],
                    s.azimuth_arc_deg[1],
                    reach.azimuth_arc_deg[1],
                    r.reach_fraction_in_region * 100.0
                )),
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Angles tolerance of the arc tests, rad (round-off of ±π arithmetic only).
    const ARC_TOL: f64 = 1e-12;

    #[test]
    fn shortest_arc_wraps_around_pi() {
        // Points at 170°, −170°, 180°: the arc is 20° long, starting at 170°.
        let mut a = vec![170f64.to_radians(), (-170f64).to_radians(), PI];
        let [start, len] = shortest_arc(&mut a);
        assert!((len - 20f64.to_radians()).abs() < ARC_TOL, "{len}");
        assert!((start - 170f64.to_radians()).abs() < ARC_TOL, "{start}");
        assert!(on_arc(PI, [start, len]) && on_arc(-175f64.to_radians(), [start, len]));
        assert!(!on_arc(0.0, [start, len]));
        // One angle: a zero-length arc at it; none: empty.
        assert_eq!(shortest_arc(&mut [0.5]), [0.5, 0.0]);
        assert_eq!(shortest_arc(&mut []), [0.0, 0.0]);
        // Evenly spread: the arc is the whole circle less one gap.
        let mut even: Vec<f64> = (0..4).map(|k| -PI + k as f64 * PI / 2.0).collect();
        assert!((shortest_arc(&mut even)[1] - 1.5 * PI).abs() < ARC_TOL);
    }

    /// A 3-joint arm: joint 1 about z at 0.3 m, joints 2 and 3 about y, links 0.5 and 0.4 m
    /// along x; limits ±3, ±2, ±2.5 rad.
    const ARM: &str = r#"<robot name="arm">
      <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool0"/>
      <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
        <origin xyz="0 0 0.3"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
        <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
      <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
        <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
      <joint name="l3-tool0" type="fixed"><parent link="l3"/><child link="tool0"/>
        <origin xyz="0.4 0 0"/></joint>
    </robot>"#;

    /// Exact equality up to the round-off of FK and atan2 (1e-12 m or rad).
    const EXACT: f64 = 1e-12;

    /// The coverage numbers of a constructed session: robot 1 tracked at three joint vectors
    /// with the arm stretched out (joint 1 at −0.5, 0, 0.5 rad; the tip 0.1 m along the flange
    /// z), robot 2 touching a plane at the very joint vectors the reach of robot 2 is sampled
    /// at (so its session region holds the whole reach: fraction 1).
    #[test]
    fn coverage_of_a_constructed_session() {
        use super::super::{Noise3, Observation, ObservationKind, PlaneGroup, TrackerGroup};
        use crate::whole_cell::Tool;
        let model = kinematics::RobotModel::from_urdf_str(ARM, "tool0").unwrap();
        let robot = CellRobot {
            model: model.clone(),
            tools: vec![Tool {
                name: "tip".into(),
                flange_from_tip: Vector3::new(0.0, 0.0, 0.1),
            }],
            g_base: Vector3::new(0.0, 0.0, -9.81),
            tolerance: super::super::Tolerance::default(),
            shared_joints: 0,
        };
        let seed = 5;
        let mut observations = Vec::new();
        for (k, a) in [-0.5, 0.0, 0.5].into_iter().enumerate() {
            observations.push(Observation {
                row: k + 1,
                kind: ObservationKind::Tracker {
                    robot: Robot::One,
                    q: vec![a, 0.0, 0.0],
                    tool: 0,
                    group: 0,
                    p_tracker: Point3::origin(),
                    noise: Noise3::Isotropic { sigma_m: 1e-4 },
                },
            });
        }
        // Robot 2's rows: the reach samples themselves (same generator, same draw order).
        let mut rng = crate::stats::trial_rng(seed, 2);
        let limits = [(-3.0, 3.0), (-2.0, 2.0), (-2.5, 2.5)];
        for k in 0..ENVELOPE_SAMPLES {
            let q: Vec<f64> = limits
                .iter()
                .map(|&(lo, hi)| rng.random_range(lo..=hi))
                .collect();
            observations.push(Observation {
                row: 10 + k,
                kind: ObservationKind::Plane {
                    robot: Robot::Two,
                    q,
                    tool: 0,
                    group: 0,
                    sigma_m: 1e-4,
                },
            });
        }
        let problem = CellProblem {
            robot1: robot.clone(),
            robot2: robot,
            observations,
            trackers: vec![TrackerGroup {
                name: "t".into(),
                anchor: Robot::One,
                initial_tracker_from_anchor: None,
                fit_scale: false,
                fit_drift: false,
            }],
            planes: vec![PlaneGroup {
                name: "p".into(),
                anchor: Robot::Two,
                initial: None,
            }],
            contacts: vec![],
            placement_prior: None,
            other_arm_q: Default::default(),
        };
        let c = session_coverage(&problem, seed).unwrap();
        let [one, two] = &c.robots;
        assert_eq!((one.rows, two.rows), (3, ENVELOPE_SAMPLES));
        // Joint 1 spans 1 rad of its 6; joints 2 and 3 do not move.
        assert_eq!(one.joints[0].session_range, [-0.5, 0.5]);
        assert!((one.joints[0].fraction - 1.0 / 6.0).abs() < EXACT);
        assert_eq!(one.joints[0].limits, [-3.0, 3.0]);
        assert_eq!((one.joints[1].fraction, one.joints[2].fraction), (0.0, 0.0));
        // Stretched out: the tip at radius 0.9 m, 0.1 m above joint 1's origin, azimuths ±0.5.
        let s = one.session.unwrap();
        for (v, want) in [
            (s.radius[0], 0.9),
            (s.radius[1], 0.9),
            (s.height[0], 0.1),
            (s.height[1], 0.1),
            (s.azimuth_arc[0], -0.5),
            (s.azimuth_arc[1], 1.0),
            (s.max.x, 0.9),
            (s.min.x, 0.9 * 0.5f64.cos()),
            (s.max.z, 0.4),
        ] {
            assert!((v - want).abs() < EXACT, "{v} vs {want}: {s:?}");
        }
        // A zero-thickness shell holds no reach sample; the reach's radius stays within the
        // farthest the tip can be from joint 1's axis: link 1 (0.5 m) radial, then link 2 and
        // the tip offset (0.4 m and 0.1 m at right angles, in one vertical plane) radial too:
        // 0.5 + √(0.4² + 0.1²).
        assert_eq!(one.reach_fraction_in_region, 0.0);
        assert!(one.reach.radius[1] <= 0.5 + 0.17f64.sqrt() + EXACT);
        assert!(one.reach.radius[1] > 0.8, "{:?}", one.reach);
        // Robot 2's session is its reach: same region, every sample inside.
        assert_eq!(two.session.unwrap(), two.reach);
        assert_eq!(two.reach_fraction_in_region, 1.0);
        // The report in mm and degrees, and its text.
        let r = CoverageReport::from(&c);
        assert!((r.robots[0].joints[0].session_range[1] - 0.5f64.to_degrees()).abs() < 1e-9);
        assert!((r.robots[0].session.as_ref().unwrap().radius_mm[0] - 900.0).abs() < 1e-9);
        let text = r.text_lines().join("\n");
        assert!(
            text.contains("robot 1 (3 rows) joints: j1 -29..29 of -172..172 deg (17 %)"),
            "{text}"
        );
        assert!(
            text.contains("0 % of the reach lies in this region"),
            "{text}"
        );
        // Robot 1 is narrow on every count, robot 2 (its whole reach) on none.
        let w = r.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with(
                "narrow coverage of robot 1: joints spanning under 10 % of their travel \
                 (j2 0 %, j3 0 %); tool points in a region holding 0 % of its reach"
            ),
            "{}",
            w[0]
        );
    }
}

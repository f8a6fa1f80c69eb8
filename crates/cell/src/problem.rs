//! The whole-cell calibration problem of a [`Cell`] and a measured [`Session`]
//! ([`calib_core::whole_cell`]): the cell's two nominal robots with their tools (tool 0 = the
//! tip, then `[robotN.tools]`), gravity from the mounts, the noise of each handclasp from the
//! cell's `[noise]`, the prior from `[robotN.tolerance]`, and one observation per session row
//! (coincident, contact, face contact, tracker or plane, with their own σ) with one nuisance
//! group per named `group` of each kind (contacts and face contacts share the contact groups).
//!
//! Noise of a handclasp (b1 axes): the operator's alignment error (σ per b1 axis,
//! `noise.alignment_mm`) plus both robots' repeatability (`noise.repeatability_mm`, isotropic, so
//! robot 2's rotates into b1 unchanged): `Σ = diag(σ_align²) + 2·σ_rep²·I`. The encoder
//! quantisation (`noise.encoder_resolution_deg`, a uniform error of variance step²/12 per joint,
//! ≈ 0.01 mm at the tip for 0.001° on a 1.5 m arm) is left out.

use calib_core::whole_cell::{
    CellEstimate, CellProblem, CellRobot as WholeCellRobot, ConfigPair, GroupKind, Noise3,
    Observation, ObservationKind, RobotCorrection, Tolerance, Tool, MIN_FACE_NORMAL_SUM,
};
use nalgebra::{Matrix3, Unit, Vector3};

use calib_core::whole_cell::{ContactGroup, PlacementPrior, PlaneGroup, TrackerGroup};
use calib_core::Robot;
use kinematics::base_from_tip;

use crate::cell::{Cell, CellRobot, TIP_TOOL};
use crate::session::{FaceNormals, Session, SessionRow};

/// Which unknowns the whole-cell fit estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FitModel {
    /// `b1_from_b2` only: both robots held at their nominal models (every tolerance 0, but the
    /// tips of a robot whose tools start at one tip, which the cell does not know:
    /// `calib_core::whole_cell::CellRobot::tips_unknown`), a weighted least-squares placement
    /// from the same session.
    Placement,
    /// `b1_from_b2` with every kinematic parameter the robots' tolerances select (MAP).
    Kinematic,
    /// [`FitModel::Kinematic`] plus each robot's lumped gravity compliance (compliance × mass
    /// moment, no masses needed: `kinematics::lumped`), each coefficient with the tolerance
    /// `calib_core::whole_cell::LUMPED_COMPLIANCE_TOLERANCE_RAD` (0.5°), on the joints that can
    /// have them.
    KinematicCompliance,
}

fn robot(r: &CellRobot, model: FitModel, shared_joints: usize) -> WholeCellRobot {
    let mut out = WholeCellRobot {
        shared_joints,
        model: r.model.clone(),
        tools: std::iter::once(Tool {
            name: TIP_TOOL.into(),
            flange_from_tip: r.flange_from_tip,
        })
        .chain(r.tools.iter().cloned())
        .collect(),
        g_base: r.g_base,
        tolerance: match model {
            FitModel::Placement => Tolerance::none(),
            FitModel::Kinematic => r.tolerance,
            FitModel::KinematicCompliance => Tolerance {
                lumped_compliance_rad: Some(
                    calib_core::whole_cell::LUMPED_COMPLIANCE_TOLERANCE_RAD,
                ),
                ..r.tolerance
            },
        },
    };
    // Tips the cell does not know (several tools started at one tip) are nuisances of every
    // model, the placement-only one included (calib_core's `do_no_harm` module docs).
    if model == FitModel::Placement {
        out.tolerance.tip_m = r.tolerance.tip_m;
        if !out.tips_unknown() {
            out.tolerance.tip_m = 0.0;
        }
    }
    out
}

/// Covariance of one handclasp's residual `p1_b1 − b1_from_b2·p2_b2`, m², b1 axes (see the module
/// documentation). A cell with no noise at all gets 1 µm per axis, so the fit stays defined.
pub fn handclasp_covariance(cell: &Cell) -> Matrix3<f64> {
    let a = cell.noise.alignment_m;
    let rep2 = 2.0 * cell.noise.repeatability_m.powi(2);
    let floor = 1e-6f64.powi(2);
    Matrix3::from_diagonal(&Vector3::new(
        (a.x * a.x + rep2).max(floor),
        (a.y * a.y + rep2).max(floor),
        (a.z * a.z + rep2).max(floor),
    ))
}

/// The index of contact group `name`, added (with a fitted distance when `distance_m` is `None`,
/// and an empty nominal-distance sum) when it is new.
fn contact_group(
    contacts: &mut Vec<ContactGroup>,
    sums: &mut Vec<(f64, usize)>,
    name: &str,
    distance_m: Option<f64>,
) -> usize {
    contacts
        .iter()
        .position(|c| c.name == name)
        .unwrap_or_else(|| {
            contacts.push(ContactGroup {
                name: name.to_string(),
                distance_m: distance_m.unwrap_or(0.0),
                fit_distance: distance_m.is_none(),
            });
            sums.push((0.0, 0));
            contacts.len() - 1
        })
}

/// The whole-cell problem of `cell` and `session`: one observation per session row in row
/// order ([`Session::rows`]; row = the CSV's `point` label). Coincident handclasps carry the
/// cell's handclasp noise ([`handclasp_covariance`]), the other kinds their row's `sigma_m`.
/// Each distinct `group` name of a kind becomes one nuisance group, in order of first
/// appearance: a tracker frame or plane anchored at its rows' robot's base (robot 1's when the
/// group holds rows of both robots), a contact distance (shared by the `contact` and
/// `face_contact` rows of one name) held at the rows' `distance_m` or, when empty, fitted from
/// the mean nominal distance of its rows (along the mean face normal for face contacts). Tool `k` of a robot is the cell
/// robot's tool `k` (0 = `tip_mm`). `model` selects the unknowns ([`FitModel`]). The session
/// must have been read for this cell ([`Session::read_csv`] checks joint counts and tool
/// names); [`CellProblem::check`] reports anything else by row. On a shared-trunk cell the
/// other arm's joints of one-robot rows ([`Session::other_arm_q`]) become
/// [`CellProblem::other_arm_q`]. The cell's
/// `b1_from_b2_sigma`, if any, becomes a placement prior around `cell.b1_from_b2`.
pub fn cell_problem(cell: &Cell, session: &Session, model: FitModel) -> CellProblem {
    let cov_m2 = handclasp_covariance(cell);
    let isotropic = cov_m2[(0, 0)] == cov_m2[(1, 1)] && cov_m2[(1, 1)] == cov_m2[(2, 2)];
    let noise = if isotropic {
        Noise3::Isotropic {
            sigma_m: cov_m2[(0, 0)].sqrt(),
        }
    } else {
        Noise3::Covariance { cov_m2 }
    };
    let mut trackers: Vec<TrackerGroup> = Vec::new();
    let mut planes: Vec<PlaneGroup> = Vec::new();
    let mut contacts: Vec<ContactGroup> = Vec::new();
    // Per contact group with a fitted distance: (sum of nominal distances, count), m.
    let mut contact_sums: Vec<(f64, usize)> = Vec::new();
    let anchored = |name: &str, robot: Robot, groups: &mut Vec<(String, Robot)>| match groups
        .iter()
        .position(|(n, _)| n == name)
    {
        Some(g) => {
            if groups[g].1 != robot {
                groups[g].1 = Robot::One;
            }
            g
        }
        None => {
            groups.push((name.to_string(), robot));
            groups.len() - 1
        }
    };
    let mut tracker_anchor: Vec<(String, Robot)> = Vec::new();
    let mut plane_anchor: Vec<(String, Robot)> = Vec::new();
    let mut observations = Vec::with_capacity(session.len());
    for row in session.rows() {
        let kind = match row {
            SessionRow::Point(p) => ObservationKind::Coincident {
                q1: p.q1.clone(),
                q2: p.q2.clone(),
                tool1: 0,
                tool2: 0,
                noise,
            },
            SessionRow::Observation(o) => {
                let s = &o.kind;
                // A one-robot row's group is anchored at its robot's base.
                let robot = s.single().map_or(Robot::One, |(r, _, _)| r);
                let group = match (s.kind().group(), s.group()) {
                    (Some(GroupKind::Contact), Some(name)) => {
                        let distance_m = s.distance_m();
                        let g = contact_group(&mut contacts, &mut contact_sums, name, distance_m);
                        if distance_m.is_none() {
                            if let Some(d) = s.pair().and_then(|(q1, q2, tool1, tool2)| {
                                nominal_distance(cell, q1, q2, tool1, tool2, s.face_normals())
                            }) {
                                contact_sums[g].0 += d;
                                contact_sums[g].1 += 1;
                            }
                        }
                        g
                    }
                    (Some(GroupKind::Tracker), Some(name)) => {
                        anchored(name, robot, &mut tracker_anchor)
                    }
                    (Some(GroupKind::Plane), Some(name)) => {
                        anchored(name, robot, &mut plane_anchor)
                    }
                    _ => 0,
                };
                s.observation(noise, group)
            }
        };
        observations.push(Observation {
            row: row.point(),
            kind,
        });
    }
    for (c, (sum, n)) in contacts.iter_mut().zip(contact_sums) {
        if c.fit_distance && n > 0 {
            c.distance_m = sum / n as f64;
        }
    }
    trackers.extend(
        tracker_anchor
            .into_iter()
            .map(|(name, anchor)| TrackerGroup {
                name,
                anchor,
                initial_tracker_from_anchor: None,
                fit_scale: false,
                fit_drift: false,
            }),
    );
    planes.extend(plane_anchor.into_iter().map(|(name, anchor)| PlaneGroup {
        name,
        anchor,
        initial: None,
    }));
    CellProblem {
        robot1: robot(&cell.robot1, model, 0),
        robot2: robot(&cell.robot2, model, cell.shared_joints),
        observations,
        trackers,
        planes,
        contacts,
        placement_prior: cell.b1_from_b2_sigma.map(|s| PlacementPrior {
            nominal_b1_from_b2: cell.b1_from_b2,
            sigma_m: s.sigma_m,
            sigma_rad: s.sigma_rad,
        }),
        other_arm_q: other_arm_q(cell, session),
    }
}

/// The other arm's joints of each one-robot row that gives them ([`Session::other_arm_q`]), by
/// row, on a shared-trunk cell (empty on any other): the trunk's independent joints are the
/// row's own values (the reader checked they agree to the file's 6 decimals; one trunk has one
/// posture, so the fit sees exactly one).
fn other_arm_q(cell: &Cell, session: &Session) -> std::collections::BTreeMap<usize, Vec<f64>> {
    if cell.shared_joints == 0 {
        return Default::default();
    }
    let trunk = cell.shared_independent_joints();
    session
        .observations
        .iter()
        .filter_map(|o| {
            let (_, q, _) = o.kind.single()?;
            let mut q_other = session.other_arm_q.get(&o.point)?.clone();
            let n = trunk.min(q.len()).min(q_other.len());
            q_other[..n].copy_from_slice(&q[..n]);
            Some((o.point, q_other))
        })
        .collect()
}

/// Distance between the two tools' nominal points at `(q1, q2)` with the cell's `b1_from_b2`, m:
/// the Euclidean distance, or with face normals `(n1_tip, n2_tip)` the distance along the mean
/// normal `n̄·(p2_b1 − p1_b1)` of a face contact (`None` if the normals face the same way).
fn nominal_distance(
    cell: &Cell,
    q1: &[f64],
    q2: &[f64],
    tool1: usize,
    tool2: usize,
    normals: Option<FaceNormals>,
) -> Option<f64> {
    let f1 = base_from_tip(
        &cell.robot1.model,
        q1,
        &cell.robot1.flange_from_tool(tool1)?,
    )
    .ok()?;
    let f2 = base_from_tip(
        &cell.robot2.model,
        q2,
        &cell.robot2.flange_from_tool(tool2)?,
    )
    .ok()?;
    let p2_b1 = cell.b1_from_b2 * nalgebra::Point3::from(f2.translation.vector);
    let e = p2_b1.coords - f1.translation.vector;
    match normals {
        None => Some(e.norm()),
        Some((n1_tip, n2_tip)) => {
            let n1 = f1.rotation * n1_tip.into_inner();
            let n2 = cell.b1_from_b2.rotation * (f2.rotation * n2_tip.into_inner());
            let n_bar = Unit::try_new(n1 - n2, MIN_FACE_NORMAL_SUM)?;
            Some(n_bar.dot(&e))
        }
    }
}

/// Most configuration pairs [`session_config_pairs`] returns (a 100-point session's 10 000 pairs
/// are all kept).
pub const MAX_CONFIG_PAIRS: usize = 10_000;

/// Every configuration pair `(q1_i, q2_j)` of the session (`n1·n2` pairs, row-major in `i`): the
/// session's own workspace, over which the calibration's cooperative accuracy is predicted.
/// The `q1`s are robot 1's joints of every row that has them (coincident, contact and face-contact rows, and
/// robot 1's tracker and plane rows), the `q2`s robot 2's, in row order; tool 0 (the tips).
/// For a handclasp-only session that is every `(q1_i, q2_j)` of its points. Above
/// [`MAX_CONFIG_PAIRS`] pairs, each `q1_i` is paired with `⌊MAX_CONFIG_PAIRS / n1⌋` evenly spaced
/// `q2`s shifted by `i`, so every `q1` and every `q2` still appears: deterministic, at most
/// `max(MAX_CONFIG_PAIRS, n1)` pairs.
pub fn session_config_pairs(session: &Session) -> Vec<ConfigPair> {
    let (mut q1s, mut q2s): (Vec<&[f64]>, Vec<&[f64]>) = (Vec::new(), Vec::new());
    for row in session.rows() {
        match row {
            SessionRow::Point(p) => {
                q1s.push(&p.q1);
                q2s.push(&p.q2);
            }
            SessionRow::Observation(o) => {
                if let Some((q1, q2, _, _)) = o.kind.pair() {
                    q1s.push(q1);
                    q2s.push(q2);
                } else if let Some((robot, q, _)) = o.kind.single() {
                    if robot == Robot::One {
                        q1s.push(q);
                    } else {
                        q2s.push(q);
                    }
                }
            }
        }
    }
    let (n1, n2) = (q1s.len(), q2s.len());
    let pair = |i: usize, j: usize| ConfigPair {
        q1: q1s[i].to_vec(),
        q2: q2s[j].to_vec(),
        tool1: 0,
        tool2: 0,
    };
    if n1 * n2 <= MAX_CONFIG_PAIRS {
        return (0..n1)
            .flat_map(|i| (0..n2).map(move |j| (i, j)))
            .map(|(i, j)| pair(i, j))
            .collect();
    }
    // `per_row` evenly spaced q2s per q1, shifted by one per row, so that every q2 appears
    // (the spacing n1·n2/MAX_CONFIG_PAIRS is at most n1 while n2 ≤ MAX_CONFIG_PAIRS).
    let per_row = (MAX_CONFIG_PAIRS / n1).max(1);
    (0..n1)
        .flat_map(|i| (0..per_row).map(move |m| (i, (m * n2 / per_row + i) % n2)))
        .map(|(i, j)| pair(i, j))
        .collect()
}

/// The session's own meeting pairs `(q1_i, q2_i)`: one per two-robot row (a coincident
/// handclasp, a contact or a face contact), in row order, with that row's tools. This is the pair set of the
/// project's **cooperative accuracy** (the error of `tip1 − X·tip2` where the two tools meet, as
/// `handclasp plan` and `sim-cell sweep --mode robot` measure it over held-out handclasp
/// poses); [`session_config_pairs`] pairs every `q1` with every `q2` instead (vectors up to the
/// workspace's size, a different and larger quantity). Tracker and plane rows give no pair;
/// empty when the session has no two-robot row.
pub fn session_meeting_pairs(session: &Session) -> Vec<ConfigPair> {
    session
        .rows()
        .into_iter()
        .filter_map(|row| match row {
            SessionRow::Point(p) => Some(ConfigPair {
                q1: p.q1.clone(),
                q2: p.q2.clone(),
                tool1: 0,
                tool2: 0,
            }),
            SessionRow::Observation(o) => o.kind.pair().map(|(q1, q2, tool1, tool2)| ConfigPair {
                q1: q1.to_vec(),
                q2: q2.to_vec(),
                tool1,
                tool2,
            }),
        })
        .collect()
}

/// The cell's truth as an estimate of `problem` (built by [`cell_problem`] from this cell): the
/// cell's `b1_from_b2` and each robot's true kinematic errors (`[robotN.errors]`, the tip error
/// as tool 0's; the extra tools are exact), for
/// [`calib_core::whole_cell::measure_cooperative_error`] in studies and tests.
pub fn truth_estimate(cell: &Cell, problem: &CellProblem) -> CellEstimate {
    let mut est = CellEstimate::nominal(problem, cell.b1_from_b2);
    let correction = |r: &CellRobot| {
        let mut errors = r.errors.clone();
        let tip = errors.tip;
        errors.tip = Vector3::zeros();
        let mut tool_tip_m = vec![Vector3::zeros(); 1 + r.tools.len()];
        tool_tip_m[0] = tip;
        RobotCorrection { errors, tool_tip_m }
    };
    est.robot1 = correction(&cell.robot1);
    est.robot2 = correction(&cell.robot2);
    est
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::coincident_session;

    #[test]
    fn problem_has_one_row_per_point_and_the_cells_prior() {
        let cell = Cell::default_floor_floor();
        let session = coincident_session(&cell, 8);
        let p = cell_problem(&cell, &session, FitModel::Kinematic);
        p.check().unwrap();
        assert_eq!(p.observations.len(), 8);
        assert_eq!(p.observations[4].row, session.points[4].point);
        assert_eq!(p.robot2.tolerance, cell.robot2.tolerance);
        let p0 = cell_problem(&cell, &session, FitModel::Placement);
        assert!(p0.robot1.fitted_params().is_empty());
        assert_eq!(session_config_pairs(&session).len(), 64);
        let meeting = session_meeting_pairs(&session);
        assert_eq!(meeting.len(), 8);
        assert!(meeting
            .iter()
            .zip(&session.points)
            .all(|(m, p)| m.q1 == p.q1 && m.q2 == p.q2 && m.tool1 == 0 && m.tool2 == 0));
        // σ² = 0.3² + 2·0.03² mm² per axis for the shipped floor–floor cell.
        let c = handclasp_covariance(&cell);
        assert!((c[(0, 0)] - (0.3e-3f64.powi(2) + 2.0 * 0.03e-3f64.powi(2))).abs() < 1e-15);
    }

    /// Above MAX_CONFIG_PAIRS the pairs are thinned deterministically, keeping every q1 and q2.
    #[test]
    fn config_pairs_are_capped_and_cover_every_row() {
        let points = (0..150)
            .map(|i| crate::SessionPoint {
                point: i + 1,
                q1: vec![i as f64],
                q2: vec![-(i as f64)],
                p_b1: nalgebra::Point3::origin(),
                p_b2: nalgebra::Point3::origin(),
            })
            .collect();
        let s = Session::from_points(points);
        let pairs = session_config_pairs(&s);
        assert!(pairs.len() <= MAX_CONFIG_PAIRS && pairs.len() > MAX_CONFIG_PAIRS / 2);
        for i in 0..150 {
            assert!(pairs.iter().any(|p| p.q1[0] == i as f64));
            assert!(pairs.iter().any(|p| p.q2[0] == -(i as f64)));
        }
        let small = Session::from_points(s.points[..100].to_vec());
        assert_eq!(session_config_pairs(&small).len(), 10_000);
    }
}

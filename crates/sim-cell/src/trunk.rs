//! Rows with both arms of a shared-trunk cell (`[robot2] shares`): a handclasp, a contact or a
//! face contact needs both arms' joints to agree on the trunk. The trunk's independent joints are
//! drawn once ([`draw_trunk`]; a plan's trunk first), then each arm is solved by inverse
//! kinematics with the trunk held ([`kinematics::RobotModel::with_joints_held`]) so that both
//! tips reach their targets; the truth loads the trunk with both arms ([`branch_offsets`]: each
//! arm's weight deflects the trunk joints for the other arm's tip too).

use calib_core::Robot;
use handclasp_cell::cell::{Cell, CellRobot};
use nalgebra::{Point3, Unit, Vector3};
use rand::Rng;

use crate::simulate::{quantise, solve_true_tool, PointFailure};

/// Trunk postures drawn per meeting point before it is declared unreachable (after the plan's
/// trunk, when there is one): the arms' common workspace moves with the trunk.
pub(crate) const TRUNK_DRAWS: usize = 8;

/// How many times a meeting's inverse kinematics is redone with the trunk's deflection under
/// the other arm at the last solution: 2 (the deflection moves the trunk by µrad, and its change
/// with that move is second order).
pub(crate) const TRUNK_LOAD_PASSES: usize = 2;

/// Both robots' reported joints `(q1, q2)` (rad) of a meeting and the approach direction `û`
/// it took (b1, unit).
pub(crate) type Meeting = (Vec<f64>, Vec<f64>, Vector3<f64>);

/// The trunk's independent joints (rad, or m for a prismatic joint; robot 1's first
/// [`Cell::shared_independent_joints`]), each uniform in the middle 80 % of its limits (clipped to
/// ±3 rad or m), as the other arm of a one-robot row is drawn.
pub(crate) fn draw_trunk(cell: &Cell, rng: &mut impl Rng) -> Vec<f64> {
    draw_in_middle(
        &cell.robot1.model.joints()[..cell.shared_independent_joints()],
        rng,
    )
}

/// One value per joint of `joints` (rad, or m for a prismatic joint), each uniform in the middle
/// 80 % of its limits clipped to ±3 rad or m, drawn in order: the trunk of a handclasp
/// ([`draw_trunk`]) and the other arm of a one-robot row on a shared-trunk cell.
pub(crate) fn draw_in_middle(joints: &[kinematics::Joint], rng: &mut impl Rng) -> Vec<f64> {
    joints
        .iter()
        .map(|j| {
            let (lo, hi) = (j.lower.max(-3.0), j.upper.min(3.0));
            let margin = 0.1 * (hi - lo);
            rng.random_range(lo + margin..=hi - margin)
        })
        .collect()
}

/// The deflection (rad, m for a prismatic joint; one entry per chain joint of `robot`, zero
/// beyond the trunk) of the trunk joints under the other arm at `q_other` (its independent
/// joints, the trunk's equal to the row's): each trunk joint's compliance (the cell's
/// `compliance_deg_per_knm`) times the other arm's gravity torque on it
/// ([`kinematics::trunk::branch_torques`], from the other URDF's masses), plus the
/// deflection of the other arm's lumped coefficients on the trunk joints
/// ([`kinematics::trunk::branch_deflections`]).
pub(crate) fn branch_offsets(
    cell: &Cell,
    robot: Robot,
    q_other: &[f64],
) -> Result<Vec<f64>, PointFailure> {
    let (me, other) = (cell.robot(robot), cell.robot(robot.other()));
    let k = cell.shared_joints;
    let fail = |e: kinematics::KinematicsError| (robot, format!("the trunk's load: {e}"));
    let torques =
        kinematics::trunk::branch_torques(&other.model, q_other, &other.g_base, k).map_err(fail)?;
    let lumped = kinematics::trunk::branch_deflections(
        &other.model,
        &other.errors.lumped_compliance,
        q_other,
        &other.g_base,
        k,
    )
    .map_err(fail)?;
    let mut out = vec![0.0; me.errors.joint_offset.len()];
    for j in 0..k.min(out.len()) {
        out[j] = me.errors.compliance.get(j).copied().unwrap_or(0.0) * torques[j] + lumped[j];
    }
    Ok(out)
}

/// `robot` as it is at a row where the other arm stands at `q_other`: its errors plus the
/// trunk's deflection under the other arm ([`branch_offsets`]).
pub(crate) fn loaded(
    cell: &Cell,
    robot: Robot,
    c: &CellRobot,
    q_other: &[f64],
) -> Result<CellRobot, PointFailure> {
    let mut r = c.clone();
    for (o, d) in r
        .errors
        .joint_offset
        .iter_mut()
        .zip(branch_offsets(cell, robot, q_other)?)
    {
        *o += d;
    }
    Ok(r)
}

/// Both robots' reported joints `(q1, q2)`, rad (m for a prismatic joint).
type JointPair = (Vec<f64>, Vec<f64>);

/// `robot` of `cell` with the trunk's joints held at `trunk` (for its inverse kinematics).
fn held(cell: &Cell, robot: Robot, trunk: &[f64]) -> Option<CellRobot> {
    let mut c = cell.robot(robot).clone();
    c.model = c.model.with_joints_held(trunk).ok()?;
    Some(c)
}

/// Both arms' reported joints with the trunk at `trunk`: robot 1's true tip at `target1` (b1,
/// m) with its flange z along `d` (b1), robot 2's at `target2` (b2, m) with its flange z along
/// `−d`; the truth loaded by both arms ([`loaded`], [`TRUNK_LOAD_PASSES`] passes); quantised to
/// the encoder resolution. `None` when an arm does not reach its target.
fn meet_at(
    cell: &Cell,
    trunk: &[f64],
    target1: &Point3<f64>,
    target2: &Point3<f64>,
    d: &Unit<Vector3<f64>>,
    seeds: Option<(&[f64], &[f64])>,
) -> Result<Option<JointPair>, PointFailure> {
    let (Some(h1), Some(h2)) = (held(cell, Robot::One, trunk), held(cell, Robot::Two, trunk))
    else {
        return Ok(None);
    };
    let axis2 = Unit::new_normalize(cell.b1_from_b2.inverse().rotation * -d.into_inner());
    // A seed holds the planned trunk; with another trunk only its arm joints help.
    let seed = |s: &[f64]| {
        let mut s = s.to_vec();
        s[..trunk.len()].copy_from_slice(trunk);
        s
    };
    let (s1, s2) = match seeds {
        Some((a, b)) if a.len() >= trunk.len() && b.len() >= trunk.len() => {
            (Some(seed(a)), Some(seed(b)))
        }
        _ => (None, None),
    };
    let Some(mut q1) = solve_true_tool(&h1, 0, target1, Some(*d), s1.as_deref()) else {
        return Ok(None);
    };
    let Some(mut q2) = solve_true_tool(&h2, 0, target2, Some(axis2), s2.as_deref()) else {
        return Ok(None);
    };
    for _ in 0..TRUNK_LOAD_PASSES {
        let l1 = loaded(cell, Robot::One, &h1, &q2)?;
        let l2 = loaded(cell, Robot::Two, &h2, &q1)?;
        let (Some(a), Some(b)) = (
            solve_true_tool(&l1, 0, target1, Some(*d), Some(&q1)),
            solve_true_tool(&l2, 0, target2, Some(axis2), Some(&q2)),
        ) else {
            return Ok(None);
        };
        (q1, q2) = (a, b);
    }
    let res = cell.noise.encoder_resolution_rad;
    quantise(&cell.robot1, &mut q1, res);
    quantise(&cell.robot2, &mut q2, res);
    Ok(Some((q1, q2)))
}

/// A meeting of both arms of a shared-trunk cell: robot 1's true tip at `target1` (b1, m),
/// robot 2's at `target2(û)` (b2, m) for approach direction `û` (b1, unit; robot 1's flange z
/// along `û`, robot 2's along `−û`). Trunk postures tried in turn: the plan's (`planned`, whose
/// joints also seed the arms), then [`TRUNK_DRAWS`] draws ([`draw_trunk`]); for each, the
/// directions `dirs` in turn. Errors: no trunk and direction reached by both arms (naming the
/// last arm that failed).
pub(crate) fn meet_on_trunk(
    cell: &Cell,
    target1: &Point3<f64>,
    target2: &dyn Fn(&Vector3<f64>) -> Point3<f64>,
    dirs: &[Unit<Vector3<f64>>],
    planned: Option<(&[f64], &[f64])>,
    rng: &mut impl Rng,
) -> Result<Meeting, PointFailure> {
    let k = cell.shared_independent_joints();
    let mut trunks: Vec<Vec<f64>> = planned
        .filter(|(a, _)| a.len() >= k)
        .map(|(a, _)| a[..k].to_vec())
        .into_iter()
        .collect();
    trunks.extend((0..TRUNK_DRAWS).map(|_| draw_trunk(cell, rng)));
    for trunk in &trunks {
        for d in dirs {
            let t2 = target2(&d.into_inner());
            if let Some((q1, q2)) = meet_at(cell, trunk, target1, &t2, d, planned)? {
                return Ok((q1, q2, d.into_inner()));
            }
        }
    }
    Err((
        Robot::Two,
        format!(
            "the arms do not meet there head-on on a shared trunk ({} trunk postures and {} \
             approach directions tried)",
            trunks.len(),
            dirs.len()
        ),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn humanoid_trunk() -> Cell {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../cells/humanoid-trunk.toml");
        Cell::from_toml_file(&p).unwrap()
    }

    /// The humanoid without noise and with 2°/(kN·m) on every joint, the trunk's once (robot
    /// 2's trunk entries are robot 1's), so both arms load the trunk.
    fn loaded_humanoid_trunk() -> Cell {
        let mut cell = humanoid_trunk();
        cell.noise.alignment_m = Vector3::zeros();
        cell.noise.repeatability_m = 0.0;
        cell.noise.encoder_resolution_rad = 0.0;
        let c = 2f64.to_radians() * 1e-3;
        for r in [&mut cell.robot1, &mut cell.robot2] {
            r.errors.compliance = vec![c; r.errors.joint_offset.len()];
        }
        cell
    }

    /// The tolerance of the true tips meeting, m (the true-robot Newton's, with the load passes'
    /// second-order residue).
    const MEET_TOL_M: f64 = 1e-7;
    /// Largest angle from head-on of the true flange axes, rad: the nominal inverse kinematics
    /// aims them, and the truth's errors (hundredths of a degree per joint) tilt them by less.
    const HEAD_ON_RAD: f64 = 0.0175;

    /// A handclasp on the humanoid's shared trunk (its compliance on, so both arms load the
    /// trunk; no noise): both arms report one trunk posture, and the TRUE tips, each arm
    /// deflected by the other's weight at the reported joints, meet head-on.
    #[test]
    fn a_handclasp_on_a_shared_trunk_agrees_on_the_trunk_and_the_true_tips_meet() {
        let cell = loaded_humanoid_trunk();
        let p = Point3::new(0.35, 0.0, 1.45);
        let dirs = crate::simulate::meeting_directions(&cell, &p);
        let mut rng = crate::trial_rng(3, 0);
        let (q1, q2, u) = meet_on_trunk(&cell, &p, &|_| p, &dirs, None, &mut rng).unwrap();
        let k = cell.shared_independent_joints();
        assert_eq!(q1[..k], q2[..k]);
        let tip = |robot: Robot, q: &[f64], other: &[f64]| {
            let r = loaded(&cell, robot, cell.robot(robot), other).unwrap();
            kinematics::true_base_from_tip(&r.model, &r.errors, q, &r.flange_from_tip, &r.g_base)
                .unwrap()
        };
        let (t1, t2) = (tip(Robot::One, &q1, &q2), tip(Robot::Two, &q2, &q1));
        let gap = (t1.translation.vector - t2.translation.vector).norm();
        assert!(gap < MEET_TOL_M, "the true tips are {gap:e} m apart");
        assert!((t1.translation.vector - p.coords).norm() < MEET_TOL_M);
        // Head-on: robot 1's flange z along û, robot 2's against it.
        let z = |t: &nalgebra::Isometry3<f64>| t.rotation * Vector3::z();
        assert!(z(&t1).angle(&u) < HEAD_ON_RAD && z(&t2).angle(&-u) < HEAD_ON_RAD);
        // Without the other arm's load the tips would not meet: the load is in the truth.
        let unloaded = kinematics::true_base_from_tip(
            &cell.robot1.model,
            &cell.robot1.errors,
            &q1,
            &cell.robot1.flange_from_tip,
            &cell.robot1.g_base,
        )
        .unwrap();
        assert!((unloaded.translation.vector - p.coords).norm() > 10.0 * MEET_TOL_M);
    }

    /// Face contacts on the shared trunk (compliance on, no noise): the written face normals,
    /// mapped to b1 by each arm's TRUE rotation with the trunk deflected by the other arm's
    /// weight (the truth the tips were solved in, and the fit's model of the normals), are
    /// flush (`n1 = −n2`); without the load they are not (they used to be written from the
    /// unloaded rotations).
    #[test]
    fn face_contact_normals_carry_the_trunk_load() {
        let cell = loaded_humanoid_trunk();
        let mut spec = crate::SessionSpec::new(6, crate::Layout::Random, 0.3);
        spec.centre_b1 = Some(Point3::new(0.35, 0.0, 1.45));
        let kinds = crate::KindSpec {
            kind: crate::SimKind::FaceContact,
            ..crate::KindSpec::default()
        };
        let (s, _) =
            crate::generate_kind_session(&cell, &spec, &kinds, None, &mut crate::trial_rng(5, 0))
                .unwrap();
        assert_eq!(s.observations.len(), 6);
        // Each normal in b1 through the arm's true rotation, with or without the trunk's load.
        let in_b1 = |robot: Robot, q: &[f64], other: &[f64], n_tip: &Vector3<f64>, load: bool| {
            let r = if load {
                loaded(&cell, robot, cell.robot(robot), other).unwrap()
            } else {
                cell.robot(robot).clone()
            };
            let t = kinematics::true_base_from_tip(
                &r.model,
                &r.errors,
                q,
                &r.flange_from_tip,
                &r.g_base,
            )
            .unwrap();
            let b1_from_b = match robot {
                Robot::One => nalgebra::UnitQuaternion::identity(),
                Robot::Two => cell.b1_from_b2.rotation,
            };
            b1_from_b * (t.rotation * n_tip)
        };
        let mut unloaded_gap = 0.0f64;
        for o in &s.observations {
            let handclasp_cell::SessionKind::FaceContact {
                q1,
                q2,
                n1_tip,
                n2_tip,
                ..
            } = &o.kind
            else {
                panic!("a face contact: {o:?}");
            };
            let gap = |load: bool| {
                (in_b1(Robot::One, q1, q2, n1_tip, load) + in_b1(Robot::Two, q2, q1, n2_tip, load))
                    .norm()
            };
            assert!(gap(true) < FLUSH_TOL_RAD, "not flush: {:e}", gap(true));
            unloaded_gap = unloaded_gap.max(gap(false));
        }
        assert!(unloaded_gap > 1e3 * FLUSH_TOL_RAD, "{unloaded_gap:e}");
    }

    /// Two unit normals written flush, compared after the same rotations: round-off only.
    const FLUSH_TOL_RAD: f64 = 1e-12;
}

//! FK, Jacobians and IK of the shipped robots (`robots/*.urdf`, tool link `tool0`) and the
//! kinematics crate's prismatic and coupled-joint fixtures on arbitrary joint vectors, tips,
//! targets and options. No call may panic; an FK or Jacobian that accepts
//! its input returns finite values; every Ok IK solution is finite and within the joint limits,
//! and a converged one puts the tip on its target to the stated tolerance.
#![no_main]

use handclasp_fuzz as common;

use arbitrary::Arbitrary;
use calib_core::nalgebra;
use kinematics::{
    base_from_flange, base_from_tip, geometric_jacobian, ik_tip_position, tip_position_jacobian,
    IkOptions, IkStatus, JacobianFrame, RobotModel,
};
use libfuzzer_sys::fuzz_target;
use nalgebra::{Point3, Unit, Vector3};

#[derive(Debug, Arbitrary)]
enum Angle {
    /// Any f64 bit pattern, rad.
    Raw(f64),
    /// A fraction of the joint's range (±π for a continuous joint): inside the limits.
    InRange(u16),
}

fn joints(model: &RobotModel, angles: &[Angle]) -> Vec<f64> {
    angles
        .iter()
        .zip(model.joints().iter().cycle())
        .map(|(a, j)| match *a {
            Angle::Raw(v) => v,
            Angle::InRange(u) => {
                let (lo, hi) = if j.lower.is_finite() && j.upper.is_finite() {
                    (j.lower, j.upper)
                } else {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                };
                lo + (hi - lo) * f64::from(u) / f64::from(u16::MAX)
            }
        })
        .collect()
}

#[derive(Debug, Arbitrary)]
enum Target {
    Raw([f64; 3]),
    /// Millimetres.
    Mm([i16; 3]),
    /// FK of a joint vector (reachable by construction when inside the limits).
    Fk(Vec<Angle>),
}

#[derive(Debug, Arbitrary)]
struct Input {
    robot: u8,
    q: Vec<Angle>,
    tip_mm: [i16; 3],
    raw_tip: Option<[f64; 3]>,
    target: Target,
    tool_axis: Option<[f64; 3]>,
    preferred_q: Option<Vec<Angle>>,
    initial_q: Option<Vec<Angle>>,
    /// Tolerance exponent: 10^-(1 + e % 12) m; or any raw value.
    tolerance: Result<u8, f64>,
    max_iterations: u8,
    restarts: u8,
}

fn finite(v: impl IntoIterator<Item = f64>) -> bool {
    v.into_iter().all(f64::is_finite)
}

fuzz_target!(|input: Input| {
    let robots: Vec<&RobotModel> = common::robots()
        .iter()
        .chain(common::fixture_robots())
        .map(|(_, m)| m)
        .collect();
    let model = robots[usize::from(input.robot) % robots.len()];
    let q = joints(model, &input.q);
    let tip = match input.raw_tip {
        Some(t) => Vector3::from(t),
        None => {
            Vector3::new(
                f64::from(input.tip_mm[0]),
                f64::from(input.tip_mm[1]),
                f64::from(input.tip_mm[2]),
            ) * 1e-3
        }
    };
    if let Ok(p) = base_from_flange(model, &q) {
        assert!(finite(p.translation.vector.iter().copied()), "FK {p:?}");
    }
    if let Ok(p) = base_from_tip(model, &q, &tip) {
        assert!(finite(p.translation.vector.iter().copied()), "FK tip {p:?}");
    }
    for frame in [JacobianFrame::Base, JacobianFrame::Tip] {
        if let Ok(j) = geometric_jacobian(model, &q, &tip, frame) {
            assert!(finite(j.iter().copied()), "Jacobian {j}");
        }
    }
    if let Ok(j) = tip_position_jacobian(model, &q, &tip) {
        assert!(finite(j.iter().copied()), "position Jacobian {j}");
    }

    let target = match &input.target {
        Target::Raw(p) => Point3::from(*p),
        Target::Mm(p) => Point3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2])) * 1e-3,
        Target::Fk(a) => match base_from_tip(model, &joints(model, a), &tip) {
            Ok(p) => Point3::from(p.translation.vector),
            Err(_) => return,
        },
    };
    let tolerance_m = match input.tolerance {
        Ok(e) => 10f64.powi(-(1 + i32::from(e % 12))),
        Err(raw) => raw,
    };
    let options = IkOptions {
        tool_axis_base: input
            .tool_axis
            .map(|a| Unit::new_normalize(Vector3::from(a))),
        preferred_q: input.preferred_q.as_ref().map(|a| joints(model, a)),
        initial_q: input.initial_q.as_ref().map(|a| joints(model, a)),
        tolerance_m,
        axis_tolerance_rad: 1e-6,
        max_iterations: usize::from(input.max_iterations % 100),
        restarts: usize::from(input.restarts % 6),
    };
    let Ok(sol) = ik_tip_position(model, &target, &tip, &options) else {
        return;
    };
    assert_eq!(sol.q.len(), model.dof());
    assert!(finite(sol.q.iter().copied()), "IK q {:?}", sol.q);
    if let Err(e) = model.check_q(&sol.q) {
        panic!("IK returned a joint vector outside the limits: {e}");
    }
    if sol.status == IkStatus::Converged {
        let p = base_from_tip(model, &sol.q, &tip).expect("checked above");
        let err = (p.translation.vector - target.coords).norm();
        // The solver's own error figure and a fresh FK differ only by round-off of the target's
        // magnitude.
        let round_off = 1e-12 * (1.0 + target.coords.norm());
        assert!(
            err <= options.tolerance_m + round_off,
            "converged IK misses its target by {err} m (tolerance {} m)",
            options.tolerance_m
        );
    }
});

//! `diagnose::diagnose_session` on FK-consistent sessions built from fuzz bytes, so that the
//! engine itself (noise model, catalogue, forward selection, report) runs, not just the input
//! checks.
//!
//! The session: a shipped cell (`cells/*.toml`), optionally with hidden kinematic errors on
//! either robot; per point robot 1's reported joints are a fraction of each joint's range
//! (inside the limits), the physical contact point is robot 1's TRUE tip, and robot 2's joints
//! come from its nominal IK to that point (points it cannot reach are left out). Optional
//! joint noise (clamped into the limits) is added to the reported joints, and the tip columns
//! are the nominal FK of the reported joints, as a controller writes them. The diagnosis runs
//! with a small budget (few Monte Carlo trials, few selection steps, short LM fits).
#![no_main]

use handclasp_fuzz as common;

use arbitrary::Arbitrary;
use calib_core::identify::SelectionOptions;
use calib_core::LmOptions;
use calib_core::nalgebra;
use diagnose::{diagnose_session, DiagnoseOptions};
use handclasp_cell::{Session, SessionPoint};
use kinematics::{
    base_from_tip, ik_tip_position, true_base_from_tip, IkOptions, KinematicErrors, RobotModel,
};
use libfuzzer_sys::fuzz_target;
use nalgebra::Point3;

#[derive(Debug, Arbitrary)]
struct HiddenError {
    robot2: bool,
    joint: u8,
    /// 0 offset, 1–3 origin xyz, 4–6 origin rpy, 7 scale, 8 tip, 9 compliance.
    kind: u8,
    /// × 1e-5 (m or rad; compliance × 1e-7 rad/(N·m)).
    value: i8,
}

#[derive(Debug, Arbitrary)]
struct Input {
    cell: u8,
    points: Vec<Vec<u16>>,
    errors: Vec<HiddenError>,
    /// Joint noise σ-like amplitude, × 1e-6 rad per unit of each point's noise byte.
    noise: Option<(u8, Vec<i8>)>,
    seed: u64,
    max_steps: u8,
}

fn add_error(errors: &mut KinematicErrors, e: &HiddenError) {
    let n = errors.dof();
    let j = usize::from(e.joint) % n;
    let v = f64::from(e.value) * 1e-5;
    match e.kind % 10 {
        0 => errors.joint_offset[j] += v,
        k @ 1..=3 => errors.origin_xyz[j][usize::from(k - 1)] += v,
        k @ 4..=6 => errors.origin_rpy[j][usize::from(k - 4)] += v,
        7 => errors.joint_scale[j] += v,
        8 => errors.tip[j % 3] += v,
        _ => errors.compliance[j] += v.abs() * 1e-2,
    }
}

fn range(model: &RobotModel, k: usize) -> (f64, f64) {
    let j = &model.joints()[k];
    if j.lower.is_finite() && j.upper.is_finite() {
        (j.lower, j.upper)
    } else {
        (-std::f64::consts::PI, std::f64::consts::PI)
    }
}

fn perturb(model: &RobotModel, q: &mut [f64], noise: &[i8], amplitude: f64, offset: usize) {
    for (k, v) in q.iter_mut().enumerate() {
        let n = noise.get(offset + k).copied().unwrap_or(0);
        let (lo, hi) = range(model, k);
        *v = (*v + f64::from(n) * amplitude).clamp(lo, hi);
    }
}

fuzz_target!(|input: Input| {
    if input.points.len() > 24 || input.errors.len() > 12 {
        return;
    }
    let cells = common::cells();
    let mut cell = cells[usize::from(input.cell) % cells.len()].clone();
    for e in &input.errors {
        let robot = if e.robot2 {
            &mut cell.robot2
        } else {
            &mut cell.robot1
        };
        add_error(&mut robot.errors, e);
    }
    let (r1, r2) = (&cell.robot1, &cell.robot2);
    let b2_from_b1 = cell.b1_from_b2.inverse();
    let ik = IkOptions {
        tolerance_m: 1e-9,
        max_iterations: 100,
        restarts: 3,
        ..IkOptions::default()
    };
    let mut points = Vec::new();
    for (i, fractions) in input.points.iter().enumerate() {
        let mut q1: Vec<f64> = (0..r1.model.dof())
            .map(|k| {
                let (lo, hi) = range(&r1.model, k);
                let f = fractions.get(k).copied().unwrap_or(u16::MAX / 2);
                lo + (hi - lo) * f64::from(f) / f64::from(u16::MAX)
            })
            .collect();
        let Ok(b1_from_tip1) =
            true_base_from_tip(&r1.model, &r1.errors, &q1, &r1.flange_from_tip, &r1.g_base)
        else {
            return; // errors the true model refuses (none are generated): nothing to test
        };
        let contact_b2 = b2_from_b1 * Point3::from(b1_from_tip1.translation.vector);
        let Ok(sol) = ik_tip_position(&r2.model, &contact_b2, &r2.flange_from_tip, &ik) else {
            continue;
        };
        if !sol.reachable() {
            continue;
        }
        let mut q2 = sol.q;
        if let Some((amplitude, noise)) = &input.noise {
            let a = f64::from(*amplitude) * 1e-6;
            let n1 = r1.model.dof();
            perturb(&r1.model, &mut q1, noise, a, 0);
            perturb(&r2.model, &mut q2, noise, a, n1);
        }
        let p_b1 = base_from_tip(&r1.model, &q1, &r1.flange_from_tip).expect("within limits");
        let p_b2 = base_from_tip(&r2.model, &q2, &r2.flange_from_tip).expect("IK q within limits");
        points.push(SessionPoint {
            point: i + 1,
            q1,
            q2,
            p_b1: Point3::from(p_b1.translation.vector),
            p_b2: Point3::from(p_b2.translation.vector),
        });
    }
    let session = Session::from_points(points);
    let options = DiagnoseOptions {
        seed: input.seed,
        trials: 12,
        selection: SelectionOptions {
            max_steps: 1 + usize::from(input.max_steps % 3),
            folds: 4,
            fit: LmOptions::identify()
                .with_max_iterations(8)
                .expect("8 iterations is a valid cap"),
            ..SelectionOptions::default()
        },
        ..DiagnoseOptions::default()
    };
    if let Ok(report) = diagnose_session(&cell, &session, &options) {
        let _ = diagnose::render_text(&report);
    }
});

//! Inverse kinematics to a tip position (m, base frame), optionally with the flange z axis along a
//! given direction, by damped least squares (Levenberg–Marquardt) within the joint limits.
//!
//! Joint limits are enforced by clamping every step (projection). For redundant problems the
//! left-over freedom moves toward `preferred_q` by a null-space term while the error is above
//! 1e-6 (m or rad); the final steps are pure Gauss–Newton so the solve reaches `tolerance_m`.
//! Restarts come from a fixed, deterministic set of seeds; a target that no seed reaches is
//! reported as [`IkStatus::Unreachable`] with the best joint vector found.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix6xX, Point3, Unit, Vector3};

use crate::error::KinematicsError;
use crate::fk::check_tip;
use crate::jacobian::jacobian_base_into;
use crate::model::RobotModel;

/// Options of [`ik_tip_position`].
#[derive(Debug, Clone, PartialEq)]
pub struct IkOptions {
    /// Desired direction of the flange z axis in the base frame (None: position only).
    pub tool_axis_base: Option<Unit<Vector3<f64>>>,
    /// Joint vector (rad) the redundant freedom is pulled toward (None: none).
    pub preferred_q: Option<Vec<f64>>,
    /// First seed (rad); None: `preferred_q`, else the middle of the joint ranges.
    pub initial_q: Option<Vec<f64>>,
    /// Position tolerance, m. Default 1e-10.
    pub tolerance_m: f64,
    /// Axis tolerance, rad (used with `tool_axis_base`). Default 1e-10.
    pub axis_tolerance_rad: f64,
    /// Iterations per seed. Default 100.
    pub max_iterations: usize,
    /// Number of extra deterministic seeds tried after the first. Default 16.
    pub restarts: usize,
}

impl Default for IkOptions {
    fn default() -> Self {
        IkOptions {
            tool_axis_base: None,
            preferred_q: None,
            initial_q: None,
            tolerance_m: 1e-10,
            axis_tolerance_rad: 1e-10,
            max_iterations: 100,
            restarts: 16,
        }
    }
}

/// Outcome of an IK solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IkStatus {
    /// Tolerances met.
    Converged,
    /// No seed met the tolerances: the target is out of reach (or too close to a limit/singularity).
    Unreachable,
}

/// Result of [`ik_tip_position`].
#[derive(Debug, Clone, PartialEq)]
pub struct IkSolution {
    /// Joint vector, rad, within the limits (best found if unreachable).
    pub q: Vec<f64>,
    /// Whether the tolerances were met.
    pub status: IkStatus,
    /// Remaining tip position error, m.
    pub position_error_m: f64,
    /// Remaining angle between the flange z axis and the requested axis, rad (0 if none requested).
    pub axis_error_rad: f64,
    /// Iterations used, over all seeds.
    pub iterations: usize,
}

impl IkSolution {
    /// True when the solve converged.
    pub fn reachable(&self) -> bool {
        self.status == IkStatus::Converged
    }
}

struct Work {
    frames: Vec<Isometry3<f64>>,
    jac: Matrix6xX<f64>,
}

/// Residual (target − current) and task Jacobian rows at q; returns (position error, axis error).
fn residual(
    model: &RobotModel,
    q: &[f64],
    target: &Point3<f64>,
    tip: &Vector3<f64>,
    axis: Option<&(Vector3<f64>, Vector3<f64>, Vector3<f64>)>,
    w: &mut Work,
    e: &mut DVector<f64>,
    j: &mut DMatrix<f64>,
) -> (f64, f64) {
    let t = jacobian_base_into(model, q, tip, &mut w.frames, &mut w.jac);
    let ep = target.coords - t.translation.vector;
    for r in 0..3 {
        e[r] = ep[r];
        for c in 0..q.len() {
            j[(r, c)] = w.jac[(r, c)];
        }
    }
    let mut axis_err = 0.0;
    if let Some((a, u, v)) = axis {
        let z = t.rotation * Vector3::z();
        axis_err = z.cross(a).norm().atan2(z.dot(a));
        e[3] = -u.dot(&z);
        e[4] = -v.dot(&z);
        for c in 0..q.len() {
            let om = Vector3::new(w.jac[(3, c)], w.jac[(4, c)], w.jac[(5, c)]);
            let dz = om.cross(&z);
            j[(3, c)] = u.dot(&dz);
            j[(4, c)] = v.dot(&dz);
        }
    }
    (ep.norm(), axis_err)
}

fn clamp_q(model: &RobotModel, q: &mut [f64]) {
    for (qi, jt) in q.iter_mut().zip(model.joints()) {
        *qi = qi.clamp(jt.lower, jt.upper);
    }
}

/// The deterministic seeds: middle of the ranges, then a fixed low-discrepancy pattern.
fn seeds(model: &RobotModel, first: Option<Vec<f64>>, restarts: usize) -> Vec<Vec<f64>> {
    let mid: Vec<f64> = model
        .joints()
        .iter()
        .map(|j| {
            if j.lower.is_finite() && j.upper.is_finite() {
                0.0f64.clamp(j.lower, j.upper)
            } else {
                0.0
            }
        })
        .collect();
    let mut out = vec![first.unwrap_or_else(|| mid.clone())];
    // Halton-like fractions in (-0.5, 0.5) of each joint's span (capped at 2π).
    const PRIMES: [f64; 8] = [2.0, 3.0, 5.0, 7.0, 11.0, 13.0, 17.0, 19.0];
    for s in 1..=restarts {
        let q = model
            .joints()
            .iter()
            .enumerate()
            .map(|(i, j)| {
                let b = PRIMES[i % PRIMES.len()];
                let (mut f, mut k, mut inv) = (0.0, s, 1.0 / b);
                while k > 0 {
                    f += (k as f64 % b) * inv;
                    k = (k as f64 / b) as usize;
                    inv /= b;
                }
                let (lo, hi) = if j.lower.is_finite() && j.upper.is_finite() {
                    (j.lower, j.upper)
                } else {
                    (-std::f64::consts::PI, std::f64::consts::PI)
                };
                let span = (hi - lo).min(std::f64::consts::TAU);
                let c = 0.5 * (lo + hi);
                (c + (f - 0.5) * span * 0.9).clamp(lo, hi)
            })
            .collect();
        out.push(q);
    }
    out
}

fn check_vec(model: &RobotModel, v: &Option<Vec<f64>>, what: &str) -> Result<(), KinematicsError> {
    if let Some(v) = v {
        if v.len() != model.dof() || v.iter().any(|x| !x.is_finite()) {
            return Err(KinematicsError::InvalidInput(format!(
                "IkOptions::{what} must hold {} finite angles in rad, got {:?}",
                model.dof(),
                v
            )));
        }
    }
    Ok(())
}

/// Joint angles (rad) that put the tip at `p_base_tip` (m, base frame), with the tip at
/// `flange_from_tip` (m, flange frame), within the joint limits.
///
/// Non-convergence is [`IkStatus::Unreachable`], not an error. Errors: non-finite target or tip,
/// option vectors of the wrong length or non-finite, non-positive tolerances.
pub fn ik_tip_position(
    model: &RobotModel,
    p_base_tip: &Point3<f64>,
    flange_from_tip: &Vector3<f64>,
    options: &IkOptions,
) -> Result<IkSolution, KinematicsError> {
    check_tip(flange_from_tip)?;
    if p_base_tip.iter().any(|v| !v.is_finite()) {
        return Err(KinematicsError::InvalidInput(format!(
            "IK target {:?} m is not finite",
            p_base_tip.coords.as_slice()
        )));
    }
    if !(options.tolerance_m > 0.0 && options.axis_tolerance_rad > 0.0) {
        return Err(KinematicsError::InvalidInput(
            "IK tolerances must be positive (tolerance_m, axis_tolerance_rad)".into(),
        ));
    }
    check_vec(model, &options.preferred_q, "preferred_q")?;
    check_vec(model, &options.initial_q, "initial_q")?;
    let axis = match options.tool_axis_base {
        Some(a) if a.iter().all(|x| x.is_finite()) => {
            let a = a.into_inner();
            let helper = if a.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
            let u = a.cross(&helper).normalize();
            let v = a.cross(&u);
            Some((a, u, v))
        }
        Some(_) => {
            return Err(KinematicsError::InvalidInput(
                "tool axis is not finite".into(),
            ))
        }
        None => None,
    };
    let n = model.dof();
    let rows = if axis.is_some() { 5 } else { 3 };
    let mut w = Work {
        frames: Vec::with_capacity(n),
        jac: Matrix6xX::zeros(n),
    };
    let mut e = DVector::zeros(rows);
    let mut j = DMatrix::zeros(rows, n);
    let mut e_try = DVector::zeros(rows);
    let mut j_try = DMatrix::zeros(rows, n);
    let first = options.initial_q.clone().or_else(|| options.preferred_q.clone());
    let mut best: Option<IkSolution> = None;
    let mut total_iters = 0;
    let tol_ok = |pe: f64, ae: f64| pe <= options.tolerance_m && (axis.is_none() || ae <= options.axis_tolerance_rad);
    for seed in seeds(model, first, options.restarts) {
        let mut q = seed;
        clamp_q(model, &mut q);
        let (mut pe, mut ae) = residual(model, &q, p_base_tip, flange_from_tip, axis.as_ref(), &mut w, &mut e, &mut j);
        let mut cost = e.norm_squared();
        let mut lambda2 = 1e-4;
        let mut q_try = q.clone();
        let mut converged = tol_ok(pe, ae);
        let mut it = 0;
        while !converged && it < options.max_iterations {
            it += 1;
            // dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e
            let mut a = &j * j.transpose();
            for d in 0..rows {
                a[(d, d)] += lambda2;
            }
            let Some(chol) = a.clone().cholesky() else {
                lambda2 *= 10.0;
                continue;
            };
            let mut dq = j.transpose() * chol.solve(&e);
            if let Some(pref) = &options.preferred_q {
                if n > rows && cost.sqrt() > 1e-6 {
                    let diff = DVector::from_iterator(n, pref.iter().zip(&q).map(|(p, c)| 0.2 * (p - c)));
                    let proj = j.transpose() * chol.solve(&(&j * &diff));
                    dq += diff - proj;
                }
            }
            for k in 0..n {
                q_try[k] = q[k] + dq[k];
            }
            clamp_q(model, &mut q_try);
            let (pe2, ae2) = residual(model, &q_try, p_base_tip, flange_from_tip, axis.as_ref(), &mut w, &mut e_try, &mut j_try);
            let cost2 = e_try.norm_squared();
            if cost2 < cost || tol_ok(pe2, ae2) {
                std::mem::swap(&mut q, &mut q_try);
                std::mem::swap(&mut e, &mut e_try);
                std::mem::swap(&mut j, &mut j_try);
                cost = cost2;
                pe = pe2;
                ae = ae2;
                lambda2 = (lambda2 * 0.1).max(1e-18);
                converged = tol_ok(pe, ae);
            } else {
                lambda2 *= 10.0;
                if lambda2 > 1e6 {
                    break;
                }
            }
        }
        total_iters += it;
        let sol = IkSolution {
            q,
            status: if converged { IkStatus::Converged } else { IkStatus::Unreachable },
            position_error_m: pe,
            axis_error_rad: ae,
            iterations: total_iters,
        };
        if converged {
            return Ok(sol);
        }
        let better = best
            .as_ref()
            .is_none_or(|b| sol.position_error_m + sol.axis_error_rad < b.position_error_m + b.axis_error_rad);
        if better {
            best = Some(sol);
        }
    }
    let mut b = best.expect("at least one seed");
    b.iterations = total_iters;
    Ok(b)
}

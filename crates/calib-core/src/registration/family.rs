//! The rotations a mount pair allows and the projection of a matrix onto them (see the module table
//! of [`crate::registration`]): the yaw family `R = L1ᵀ·Rz(γ)·L2` (closed form) and the paper's wall
//! family `Rz(β)·Ry(−90°)·Rz(α)` (1-D global search in β, then Newton).

use super::mount::MountPair;
use super::rotation::rotation_maximizing_trace;
use crate::error::CalibError;
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::f64::consts::PI;

/// Which rotations a mount pair allows: `R = P·V·Q` with V a yaw `Rz(γ)` or the wall family.
pub(super) enum Family {
    Yaw { p: Matrix3<f64>, q: Matrix3<f64> },
    Wall { p: Matrix3<f64>, q: Matrix3<f64> },
}

pub(super) fn family(mounts: &MountPair) -> Result<Family, CalibError> {
    mounts.validate()?;
    match (
        mounts.robot1.level_from_base(),
        mounts.robot2.level_from_base(),
    ) {
        (Some(l1), Some(l2)) => Ok(Family::Yaw {
            p: l1.matrix().transpose(),
            q: *l2.matrix(),
        }),
        (Some(l1), None) => Ok(Family::Wall {
            p: l1.matrix().transpose(),
            q: Matrix3::identity(),
        }),
        (None, Some(l2)) => Ok(Family::Wall {
            p: Matrix3::identity(),
            q: *l2.matrix(),
        }),
        (None, None) => Err(CalibError::UnsupportedMounts {
            mounts: mounts.to_string(),
            message: "both robots on the wall family leaves the rotation almost free; give one robot's mount as a known tilt (Mount::Tilt, `tilt:RX,RY` in degrees) or use method lsq".into(),
        }),
    }
}

/// `Rz(β)·Ry(−90°)·Rz(α)`, the paper's wall family (eq 16).
pub fn wall_rotation(alpha: f64, beta: f64) -> Rotation3<f64> {
    Rotation3::from_axis_angle(&Vector3::z_axis(), beta)
        * Rotation3::from_axis_angle(&Vector3::y_axis(), -PI / 2.0)
        * Rotation3::from_axis_angle(&Vector3::z_axis(), alpha)
}

/// Samples of β for the global search of the wall family.
const WALL_SAMPLES: usize = 72;
/// Newton iterations for the wall family.
const WALL_NEWTON_ITER: usize = 30;

/// The paper's floor–wall solution (eqs 16–21): `(α, β)` (rad) maximising `tr(Rᵀ·M)` over
/// `R = Rz(β)·Ry(−90°)·Rz(α)`, i.e. minimising `‖R − M‖_F`. Global: for fixed β the best α is
/// closed form, and the remaining 1-D function of β is sampled at 5° and refined by Newton.
pub fn wall_family_angles(m: &Matrix3<f64>) -> (f64, f64) {
    // R = [[−sβsα, −sβcα, −cβ], [cβsα, cβcα, −sβ], [cα, −sα, 0]]; tr(RᵀM) = uᵀKv + aᵀu + bᵀv
    // with u = (cβ, sβ), v = (cα, sα).
    let k = nalgebra::Matrix2::new(m[(1, 1)], m[(1, 0)], -m[(0, 1)], -m[(0, 0)]);
    let a = nalgebra::Vector2::new(-m[(0, 2)], -m[(1, 2)]);
    let b = nalgebra::Vector2::new(m[(2, 0)], -m[(2, 1)]);
    let f = |beta: f64| {
        let u = nalgebra::Vector2::new(beta.cos(), beta.sin());
        (k.transpose() * u + b).norm() + a.dot(&u)
    };
    let mut best_beta = 0.0;
    let mut best_f = f64::NEG_INFINITY;
    for i in 0..WALL_SAMPLES {
        let beta = -PI + 2.0 * PI * (i as f64) / WALL_SAMPLES as f64;
        let v = f(beta);
        if v > best_f {
            best_f = v;
            best_beta = beta;
        }
    }
    let beta = wall_newton(&k, &a, &b, best_beta, WALL_NEWTON_ITER);
    let beta = if f(beta) >= best_f { beta } else { best_beta };
    (wall_alpha(&k, &b, beta), beta)
}

/// Newton refinement of β for the wall family (falls back to a small gradient step when f'' ≥ 0).
fn wall_newton(
    k: &nalgebra::Matrix2<f64>,
    a: &nalgebra::Vector2<f64>,
    b: &nalgebra::Vector2<f64>,
    mut beta: f64,
    iters: usize,
) -> f64 {
    for _ in 0..iters {
        let (s, c) = beta.sin_cos();
        let u = nalgebra::Vector2::new(c, s);
        let du = nalgebra::Vector2::new(-s, c);
        let g = k.transpose() * u + b;
        let gd = k.transpose() * du;
        let gdd = -(k.transpose() * u);
        let ng = g.norm();
        if ng < 1e-300 {
            break;
        }
        let f1 = g.dot(&gd) / ng + a.dot(&du);
        let f2 =
            (gd.norm_squared() + g.dot(&gdd)) / ng - g.dot(&gd).powi(2) / ng.powi(3) - a.dot(&u);
        let step = if f2 < 0.0 {
            -f1 / f2
        } else {
            (f1 * 1e-2).clamp(-0.1, 0.1)
        };
        let step = step.clamp(-0.5, 0.5);
        beta += step;
        if step.abs() < 1e-15 {
            break;
        }
    }
    beta
}

fn wall_alpha(k: &nalgebra::Matrix2<f64>, b: &nalgebra::Vector2<f64>, beta: f64) -> f64 {
    let u = nalgebra::Vector2::new(beta.cos(), beta.sin());
    let g = k.transpose() * u + b;
    g.y.atan2(g.x)
}

/// Fast wall-family solve from a starting β (Newton only); used by the allocation-free paths.
fn wall_family_angles_near(m: &Matrix3<f64>) -> (f64, f64) {
    let k = nalgebra::Matrix2::new(m[(1, 1)], m[(1, 0)], -m[(0, 1)], -m[(0, 0)]);
    let a = nalgebra::Vector2::new(-m[(0, 2)], -m[(1, 2)]);
    let b = nalgebra::Vector2::new(m[(2, 0)], -m[(2, 1)]);
    // The family's third column is (−cβ, −sβ, 0): start from that of M's nearest rotation
    // (M itself may be a cross-covariance, far from a rotation).
    let r0 = rotation_maximizing_trace(m)
        .map(|q| q.to_rotation_matrix().into_inner())
        .unwrap_or(*m);
    let beta0 = (-r0[(1, 2)]).atan2(-r0[(0, 2)]);
    let beta = wall_newton(&k, &a, &b, beta0, 10);
    (wall_alpha(&k, &b, beta), beta)
}

/// Projects `m` onto the rotations the mounts allow: the member maximising `tr(Rᵀ·M)`
/// (= minimising `‖R − M‖_F`). Floor–floor is eq (11), floor–ceiling eq (30), floor–wall eqs (16–21);
/// other known tilts use the same yaw-about-gravity closed form. Errors for two wall mounts.
pub fn project_rotation_family(
    m: &Matrix3<f64>,
    mounts: &MountPair,
) -> Result<Rotation3<f64>, CalibError> {
    project_impl(m, mounts, false)
}

fn project_impl(
    m: &Matrix3<f64>,
    mounts: &MountPair,
    fast_wall: bool,
) -> Result<Rotation3<f64>, CalibError> {
    Ok(match family(mounts)? {
        Family::Yaw { p, q } => {
            let mp = p.transpose() * m * q.transpose();
            let gamma = (mp[(1, 0)] - mp[(0, 1)]).atan2(mp[(0, 0)] + mp[(1, 1)]);
            let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), gamma);
            Rotation3::from_matrix_unchecked(p * rz.matrix() * q)
        }
        Family::Wall { p, q } => {
            let mp = p.transpose() * m * q.transpose();
            let (alpha, beta) = if fast_wall {
                wall_family_angles_near(&mp)
            } else {
                wall_family_angles(&mp)
            };
            Rotation3::from_matrix_unchecked(p * wall_rotation(alpha, beta).matrix() * q)
        }
    })
}

/// Fast projection (wall family by Newton from M's own third column): for the allocation-free paths.
pub(super) fn project_rotation_family_fast(
    m: &Matrix3<f64>,
    mounts: &MountPair,
) -> Option<Rotation3<f64>> {
    project_impl(m, mounts, true).ok()
}

/// Free rotation axes (b1 frame, unit) of the mounts' family at rotation `r`.
pub(crate) fn family_axes(
    mounts: &MountPair,
    r: &Rotation3<f64>,
) -> Result<Vec<Vector3<f64>>, CalibError> {
    Ok(match family(mounts)? {
        Family::Yaw { p, .. } => vec![p * Vector3::z()],
        Family::Wall { p, q } => {
            // R = P·V·Q ⇒ V = Pᵀ·R·Qᵀ; β axis P·e_z, α axis P·V·e_z.
            let v = p.transpose() * r.matrix() * q.transpose();
            vec![p * Vector3::z(), p * v * Vector3::z()]
        }
    })
}

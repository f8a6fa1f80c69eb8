//! Registration of `b1_from_b2` from handclasp point pairs: the paper's methods and better ones.
//!
//! All fits take points in metres (`p_b1` in robot 1's base frame, `p_b2` in robot 2's) and return
//! `b1_from_b2` with `p_b1 ≈ b1_from_b2 · p_b2`.
//!
//! | method | cost minimised | points |
//! |---|---|---|
//! | `generic` ([`generic_4point`]) | exact affine `H = A·B⁻¹`, nearest rotation of its 3×3 block, eq (12) | 4 (n > 4: affine least squares), not coplanar |
//! | `generic-affine` | as `generic` but H's own translation column | same |
//! | `paper` ([`paper_constrained`]) | `H`'s block projected onto the mounts' rotation family (eqs 11, 30, 16–21), eq (12) | same |
//! | `lsq` ([`rigid_lsq`]) | `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` over all rotations (Arun/Umeyama/Horn, no scale) | ≥ 3, not collinear |
//! | `constrained` ([`constrained_lsq`]) | the same cost, with R restricted to the mounts' family inside the fit | ≥ 3, not collinear |
//!
//! # Mount families
//! A [`Mount`] gives a base's orientation relative to a level frame (z up, against gravity):
//! `level_from_base = L`, with `L = I` (floor), `Rx(180°)` (ceiling), `Rx(rx)·Ry(ry)` (tilt).
//! With both mounts known, `R = L1ᵀ·Rz(γ)·L2`: one free angle, the yaw about gravity.
//! [`Mount::Wall`] is the paper's wall family: only "this base's z axis is horizontal" is known,
//! which leaves two free angles, `Rz(β)·Ry(−90°)·Rz(α)` in the level frame.
//! In every case the best member maximises `tr(Rᵀ·M)` (M = the affine block for `paper`, the
//! cross-covariance for `constrained`), which is the same as minimising `‖R − M‖_F`:
//! - yaw family: closed form `γ = atan2(M'₁₀ − M'₀₁, M'₀₀ + M'₁₁)` with `M' = L1·M·L2ᵀ`
//!   (this is eq 11 for floor–floor and eq 30 for floor–ceiling);
//! - wall family: for a fixed β the best α is closed form, which leaves a 1-D maximisation of
//!   `f(β) = ‖Kᵀu(β) + b‖ + aᵀu(β)`, solved globally by sampling then Newton.

use crate::error::CalibError;
use crate::fast::rotation_maximizing_trace;
use crate::points::PointPairs;
use nalgebra::{
    DMatrix, Isometry3, Matrix3, Matrix6, Point3, Rotation3, Translation3, UnitQuaternion, Vector3,
};
use std::f64::consts::PI;
use std::fmt;

/// Relative singular value (σ₂/σ₁ of the centred points) below which points count as collinear.
pub const COLLINEAR_REL: f64 = 1e-3;
/// Relative singular value (σ₃/σ₁ of the centred points) below which points count as coplanar
/// for the 4-point affine methods.
pub const COPLANAR_REL: f64 = 1e-3;

/// How a robot base is installed, relative to a level frame whose z axis points up (against gravity).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mount {
    /// On the floor: base z up (`level_from_base = I`).
    Floor,
    /// Hanging from the ceiling: base z down (`level_from_base = Rx(180°)`).
    Ceiling,
    /// The paper's wall family: base z horizontal, roll about it unknown (two free angles).
    Wall,
    /// A known tilt: `level_from_base = Rx(rx)·Ry(ry)`, radians (a wall with known roll is
    /// `Tilt { rx: ±90°, ry }`, an inclined pedestal a small tilt).
    Tilt {
        /// Rotation about the level x axis, rad.
        rx: f64,
        /// Rotation about the (rotated) y axis, rad.
        ry: f64,
    },
}

impl Mount {
    /// `level_from_base` rotation for a mount with a known gravity direction; `None` for [`Mount::Wall`].
    pub fn level_from_base(&self) -> Option<Rotation3<f64>> {
        match *self {
            Mount::Floor => Some(Rotation3::identity()),
            Mount::Ceiling => Some(Rotation3::from_axis_angle(&Vector3::x_axis(), PI)),
            Mount::Wall => None,
            Mount::Tilt { rx, ry } => Some(
                Rotation3::from_axis_angle(&Vector3::x_axis(), rx)
                    * Rotation3::from_axis_angle(&Vector3::y_axis(), ry),
            ),
        }
    }

    /// Parses `floor`, `ceiling`, `wall` or `tilt:RX,RY` (degrees). The error text says what is accepted.
    pub fn parse(text: &str) -> Result<Mount, CalibError> {
        let t = text.trim().to_ascii_lowercase();
        let bad = |msg: &str| CalibError::InvalidOption {
            name: "mount".into(),
            value: text.into(),
            message: format!(
                "{msg}; expected floor, ceiling, wall or tilt:RX,RY (degrees, e.g. tilt:90,0)"
            ),
        };
        match t.as_str() {
            "floor" => Ok(Mount::Floor),
            "ceiling" => Ok(Mount::Ceiling),
            "wall" => Ok(Mount::Wall),
            _ => {
                let rest = t
                    .strip_prefix("tilt:")
                    .ok_or_else(|| bad("unknown mount"))?;
                let parts: Vec<&str> = rest.split(',').collect();
                if parts.len() != 2 {
                    return Err(bad("tilt needs two angles"));
                }
                let rx: f64 = parts[0]
                    .trim()
                    .parse()
                    .map_err(|_| bad("RX is not a number"))?;
                let ry: f64 = parts[1]
                    .trim()
                    .parse()
                    .map_err(|_| bad("RY is not a number"))?;
                if !rx.is_finite() || !ry.is_finite() || rx.abs() > 360.0 || ry.abs() > 360.0 {
                    return Err(bad("tilt angles must be finite degrees within ±360"));
                }
                Ok(Mount::Tilt {
                    rx: rx.to_radians(),
                    ry: ry.to_radians(),
                })
            }
        }
    }
}

impl fmt::Display for Mount {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Mount::Floor => write!(f, "floor"),
            Mount::Ceiling => write!(f, "ceiling"),
            Mount::Wall => write!(f, "wall"),
            Mount::Tilt { rx, ry } => write!(f, "tilt:{},{}", rx.to_degrees(), ry.to_degrees()),
        }
    }
}

/// The installation of both robots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MountPair {
    /// Robot 1's mount.
    pub robot1: Mount,
    /// Robot 2's mount.
    pub robot2: Mount,
}

impl MountPair {
    /// Both on the floor (the paper's eq 11).
    pub fn floor_floor() -> Self {
        MountPair {
            robot1: Mount::Floor,
            robot2: Mount::Floor,
        }
    }
    /// Robot 1 on the floor, robot 2 on a wall (eqs 16–21).
    pub fn floor_wall() -> Self {
        MountPair {
            robot1: Mount::Floor,
            robot2: Mount::Wall,
        }
    }
    /// Robot 1 on the floor, robot 2 on the ceiling (eq 30).
    pub fn floor_ceiling() -> Self {
        MountPair {
            robot1: Mount::Floor,
            robot2: Mount::Ceiling,
        }
    }
    /// Parses `floor-floor`, `floor-wall` or `floor-ceiling` (the paper's three cells).
    pub fn parse_paper(text: &str) -> Result<Self, CalibError> {
        match text.trim().to_ascii_lowercase().as_str() {
            "floor-floor" => Ok(Self::floor_floor()),
            "floor-wall" => Ok(Self::floor_wall()),
            "floor-ceiling" => Ok(Self::floor_ceiling()),
            _ => Err(CalibError::InvalidOption {
                name: "mounts".into(),
                value: text.into(),
                message:
                    "expected floor-floor, floor-wall or floor-ceiling (or give --mount1/--mount2)"
                        .into(),
            }),
        }
    }
}

impl fmt::Display for MountPair {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}-{}", self.robot1, self.robot2)
    }
}

/// A calibration method (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// The 4-point generic method with the eq (12) translation.
    Generic,
    /// The 4-point generic method with the affine H's own translation.
    GenericAffine,
    /// The paper's constrained projection for the given mounts, then eq (12).
    Paper,
    /// Rigid least squares over all rotations.
    Lsq,
    /// Installation-constrained least squares.
    Constrained,
}

impl Method {
    /// All methods, in display order.
    pub const ALL: [Method; 5] = [
        Method::Generic,
        Method::GenericAffine,
        Method::Paper,
        Method::Lsq,
        Method::Constrained,
    ];

    /// The method's name: "generic", "generic-affine", "paper", "lsq" or "constrained".
    pub fn name(self) -> &'static str {
        match self {
            Method::Generic => "generic",
            Method::GenericAffine => "generic-affine",
            Method::Paper => "paper",
            Method::Lsq => "lsq",
            Method::Constrained => "constrained",
        }
    }

    /// Parses a method name as given by [`Method::name`].
    pub fn from_name(text: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == text.trim())
    }

    /// Minimum number of points the method needs.
    pub fn min_points(self) -> usize {
        match self {
            Method::Generic | Method::GenericAffine | Method::Paper => 4,
            Method::Lsq | Method::Constrained => 3,
        }
    }
}

/// Covariance of a fitted `b1_from_b2` and the errors it predicts.
///
/// Perturbation convention (as in `calib_core::identify`): `X = Translation(δt)·Rotation(δθ)·X̂`,
/// with `δθ` (rad) and `δt` (m) in b1 axes; [`Uncertainty::covariance`] is ordered `[δθ; δt]`.
/// It is `σ̂²·G·(JᵀJ)⁻¹·Gᵀ` with `σ̂² = RSS/(3n − k)` (k free parameters, G mapping them to `[δθ; δt]`),
/// i.e. it assumes isotropic, independent point noise and a correct mount model.
#[derive(Debug, Clone, PartialEq)]
pub struct Uncertainty {
    /// 6×6 covariance of `[δθ (rad); δt (m)]`.
    pub covariance: Matrix6<f64>,
    /// Per-coordinate point noise σ estimated from the residuals, m.
    pub sigma_point_m: f64,
    /// Degrees of freedom of the residual (3n − k).
    pub dof: usize,
    /// Predicted 1σ of e_tran (eq 34): the largest per-axis standard deviation of T, m.
    pub e_tran_1sigma_m: f64,
    /// Predicted 1σ rotation error: square root of the largest eigenvalue of the δθ covariance, rad.
    pub e_rot_1sigma_rad: f64,
}

impl Uncertainty {
    /// Covariance (m²) of the mapped point `b1_from_b2 · p_b2` for a work point `p_b2` (m, b2 frame):
    /// the target registration error.
    pub fn covariance_at(&self, b1_from_b2: &Isometry3<f64>, p_b2: &Point3<f64>) -> Matrix3<f64> {
        let y = b1_from_b2 * p_b2;
        let mut j = nalgebra::Matrix3x6::zeros();
        j.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(-skew(&y.coords)));
        j.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        j * self.covariance * j.transpose()
    }

    /// Predicted RMS position error (m) of a work point `p_b2` mapped into b1 (target registration error):
    /// `√tr(covariance_at)`.
    pub fn tre_rms_m(&self, b1_from_b2: &Isometry3<f64>, p_b2: &Point3<f64>) -> f64 {
        self.covariance_at(b1_from_b2, p_b2).trace().max(0.0).sqrt()
    }
}

/// The result of a fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    /// The method that produced it.
    pub method: Method,
    /// The fitted transform: `p_b1 = b1_from_b2 · p_b2`.
    pub b1_from_b2: Isometry3<f64>,
    /// Per-point residuals `p_b1 − b1_from_b2 · p_b2`, m (a fit residual, not an accuracy).
    pub residuals: Vec<Vector3<f64>>,
    /// Conditioning figure (≥ 1, larger is worse). For the 4-point affine methods: σ₁/σ₃ of the
    /// centred b2 points (the affine solve's conditioning). For `lsq`/`constrained`: √cond(JᵀJ) of the
    /// fit's Jacobian with the rotation columns scaled by the points' RMS radius.
    pub condition: f64,
    /// Covariance and predicted errors; `Some` for `lsq` and `constrained` when 3n exceeds the
    /// number of free parameters, `None` for the 4-point projection methods.
    pub uncertainty: Option<Uncertainty>,
}

impl Fit {
    /// RMS of the residual norms, m (how well the points agree with each other, not an accuracy).
    pub fn residual_rms_m(&self) -> f64 {
        if self.residuals.is_empty() {
            return 0.0;
        }
        (self.residuals.iter().map(|r| r.norm_squared()).sum::<f64>() / self.residuals.len() as f64)
            .sqrt()
    }
}

/// Skew-symmetric matrix `[v]×` (so `[v]×·w = v × w`).
pub(crate) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The rotation nearest `m` in the Frobenius norm: `argmin ‖R − M‖_F` over `RᵀR = I, det R = +1`
/// (eqs 1–3). SVD `M = U·Σ·Vᵀ`, `R = U·diag(1, 1, det(U·Vᵀ))·Vᵀ` (the determinant guard avoids a
/// reflection). For rank(M) ≤ 1 the minimiser is not unique and one of them is returned; non-finite
/// input returns the identity.
pub fn nearest_rotation(m: &Matrix3<f64>) -> Rotation3<f64> {
    if !m.iter().all(|v| v.is_finite()) {
        return Rotation3::identity();
    }
    let svd = m.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Rotation3::identity();
    };
    let d = (u * v_t).determinant();
    let mut s = Matrix3::identity();
    if d < 0.0 {
        s[(2, 2)] = -1.0;
    }
    Rotation3::from_matrix_unchecked(u * s * v_t)
}

/// Which rotations a mount pair allows: `R = P·V·Q` with V a yaw `Rz(γ)` or the wall family.
enum Family {
    Yaw { p: Matrix3<f64>, q: Matrix3<f64> },
    Wall { p: Matrix3<f64>, q: Matrix3<f64> },
}

fn family(mounts: &MountPair) -> Result<Family, CalibError> {
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
            message: "both robots on the wall family leaves the rotation almost free; give one robot's tilt (--mount1/--mount2 tilt:RX,RY) or use method lsq".into(),
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
pub(crate) fn project_rotation_family_fast(
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

/// Singular values (m, descending) of the centred points.
pub fn spread_singular_values(points: &[Point3<f64>]) -> [f64; 3] {
    if points.is_empty() {
        return [0.0; 3];
    }
    let n = points.len() as f64;
    let c = points
        .iter()
        .fold(Vector3::zeros(), |acc, p| acc + p.coords)
        / n;
    let mut s = Matrix3::zeros();
    for p in points {
        let d = p.coords - c;
        s += d * d.transpose();
    }
    let mut ev: Vec<f64> = s
        .symmetric_eigenvalues()
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    [ev[0], ev[1], ev[2]]
}

/// Checks lengths, finiteness, point count and collinearity (and coplanarity when `need_volume`).
fn check_pairs(pairs: &PointPairs, method: Method) -> Result<(), CalibError> {
    let n = pairs.p_b1.len();
    if n != pairs.p_b2.len() {
        return Err(CalibError::LengthMismatch {
            what: "p_b1 and p_b2".into(),
            a: n,
            b: pairs.p_b2.len(),
        });
    }
    for i in 0..n {
        if !pairs.p_b1[i]
            .iter()
            .chain(pairs.p_b2[i].iter())
            .all(|v| v.is_finite())
        {
            return Err(CalibError::NonFinite {
                row: pairs.row(i),
                what: "a coordinate".into(),
            });
        }
    }
    if n < method.min_points() {
        return Err(CalibError::TooFewPoints {
            method: method.name().into(),
            needed: method.min_points(),
            got: n,
        });
    }
    let rows: Vec<usize> = (0..n).map(|i| pairs.row(i)).collect();
    for (robot, pts) in [(1u8, &pairs.p_b1), (2u8, &pairs.p_b2)] {
        let sv = spread_singular_values(pts);
        let sv_mm = sv.map(|s| s * 1e3);
        if sv[1] <= COLLINEAR_REL * sv[0] {
            return Err(CalibError::Collinear {
                rows: rows.clone(),
                robot,
                singular_values_mm: sv_mm,
            });
        }
        if method.min_points() == 4 && sv[2] <= COPLANAR_REL * sv[0] {
            return Err(CalibError::Coplanar {
                rows: rows.clone(),
                robot,
                singular_values_mm: sv_mm,
            });
        }
    }
    Ok(())
}

pub(crate) fn residuals(pairs: &PointPairs, b1_from_b2: &Isometry3<f64>) -> Vec<Vector3<f64>> {
    pairs
        .p_b1
        .iter()
        .zip(&pairs.p_b2)
        .map(|(a, b)| a - b1_from_b2 * b)
        .collect()
}

/// Affine `H = A·Bᵀ(B·Bᵀ)⁻¹` (= `A·B⁻¹` for n = 4); returns H's 3×3 block and translation column.
fn affine_lsq(pairs: &PointPairs) -> Option<(Matrix3<f64>, Vector3<f64>)> {
    let n = pairs.p_b1.len();
    let mut a = DMatrix::zeros(4, n);
    let mut b = DMatrix::zeros(4, n);
    for k in 0..n {
        for r in 0..3 {
            a[(r, k)] = pairs.p_b1[k][r];
            b[(r, k)] = pairs.p_b2[k][r];
        }
        a[(3, k)] = 1.0;
        b[(3, k)] = 1.0;
    }
    let bbt = &b * b.transpose();
    let inv = bbt.try_inverse()?;
    let h = &a * b.transpose() * inv;
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    let m = Matrix3::from_fn(|i, j| h[(i, j)]);
    Some((m, Vector3::new(h[(0, 3)], h[(1, 3)], h[(2, 3)])))
}

fn translation_eq12(pairs: &PointPairs, r: &Rotation3<f64>) -> Vector3<f64> {
    let n = pairs.p_b1.len() as f64;
    pairs
        .p_b1
        .iter()
        .zip(&pairs.p_b2)
        .fold(Vector3::zeros(), |acc, (a, b)| {
            acc + (a.coords - r * b.coords)
        })
        / n
}

fn four_point_condition(pairs: &PointPairs) -> f64 {
    let sv = spread_singular_values(&pairs.p_b2);
    if sv[2] > 0.0 {
        sv[0] / sv[2]
    } else {
        f64::INFINITY
    }
}

fn coplanar_error(pairs: &PointPairs) -> CalibError {
    CalibError::Coplanar {
        rows: (0..pairs.p_b1.len()).map(|i| pairs.row(i)).collect(),
        robot: 2,
        singular_values_mm: spread_singular_values(&pairs.p_b2).map(|s| s * 1e3),
    }
}

/// The paper's generic method ([8]): `H = A·B⁻¹` from 4 non-coplanar points (homogeneous columns),
/// the Frobenius-nearest rotation of H's 3×3 block, then the translation: eq (12)
/// `T = (1/n)Σ(p1ᵢ − R·p2ᵢ)` when `affine_translation` is false, H's own column when true.
/// With n > 4 points H is the affine least-squares solution. Errors: fewer than 4 points,
/// collinear or coplanar points, non-finite values.
pub fn generic_4point(pairs: &PointPairs, affine_translation: bool) -> Result<Fit, CalibError> {
    let method = if affine_translation {
        Method::GenericAffine
    } else {
        Method::Generic
    };
    check_pairs(pairs, method)?;
    let (m, t_h) = affine_lsq(pairs).ok_or_else(|| coplanar_error(pairs))?;
    let r = nearest_rotation(&m);
    let t = if affine_translation {
        t_h
    } else {
        translation_eq12(pairs, &r)
    };
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    Ok(Fit {
        method,
        residuals: residuals(pairs, &b1_from_b2),
        b1_from_b2,
        condition: four_point_condition(pairs),
        uncertainty: None,
    })
}

/// The paper's constrained method: the generic `H = A·B⁻¹`, its 3×3 block projected onto the
/// rotations the mounts allow ([`project_rotation_family`]: eq 11 floor–floor, eq 30 floor–ceiling,
/// eqs 16–21 floor–wall, the yaw closed form for known tilts), then eq (12).
/// Errors: as [`generic_4point`], plus two wall mounts.
pub fn paper_constrained(pairs: &PointPairs, mounts: &MountPair) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Paper)?;
    let (m, _) = affine_lsq(pairs).ok_or_else(|| coplanar_error(pairs))?;
    let r = project_rotation_family(&m, mounts)?;
    let t = translation_eq12(pairs, &r);
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    Ok(Fit {
        method: Method::Paper,
        residuals: residuals(pairs, &b1_from_b2),
        b1_from_b2,
        condition: four_point_condition(pairs),
        uncertainty: None,
    })
}

fn weights_checked(pairs: &PointPairs, weights: Option<&[f64]>) -> Result<Vec<f64>, CalibError> {
    let n = pairs.p_b1.len();
    match weights {
        None => Ok(vec![1.0; n]),
        Some(w) => {
            if w.len() != n {
                return Err(CalibError::LengthMismatch {
                    what: "weights and points".into(),
                    a: w.len(),
                    b: n,
                });
            }
            for (i, &wi) in w.iter().enumerate() {
                if !wi.is_finite() || wi < 0.0 {
                    return Err(CalibError::NonFinite {
                        row: pairs.row(i),
                        what: format!("weight {wi} (must be finite and ≥ 0)"),
                    });
                }
            }
            if w.iter().filter(|&&x| x > 0.0).count() < 3 {
                return Err(CalibError::TooFewPoints {
                    method: "lsq (points with weight > 0)".into(),
                    needed: 3,
                    got: w.iter().filter(|&&x| x > 0.0).count(),
                });
            }
            Ok(w.to_vec())
        }
    }
}

fn weighted_cross(pairs: &PointPairs, w: &[f64]) -> (Vector3<f64>, Vector3<f64>, Matrix3<f64>) {
    let sw: f64 = w.iter().sum();
    let mut c1 = Vector3::zeros();
    let mut c2 = Vector3::zeros();
    for ((a, b), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(w) {
        c1 += a.coords * *wi;
        c2 += b.coords * *wi;
    }
    c1 /= sw;
    c2 /= sw;
    let mut m = Matrix3::zeros();
    for ((a, b), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(w) {
        m += (a.coords - c1) * (b.coords - c2).transpose() * *wi;
    }
    (c1, c2, m)
}

/// Jacobian of the weighted residuals `√wᵢ·(p1ᵢ − X·p2ᵢ)` with respect to rotations about `axes`
/// (b1 frame, left perturbation, rad) followed by `δt` (m): column for axis a is `√wᵢ·(X·p2ᵢ) × a`,
/// translation block `−√wᵢ·I`. Written into `j` (3n × (axes + 3)).
pub(crate) fn fill_fit_jacobian(
    pairs: &PointPairs,
    w: &[f64],
    b1_from_b2: &Isometry3<f64>,
    axes: &[Vector3<f64>],
    j: &mut DMatrix<f64>,
) {
    for i in 0..pairs.p_b1.len() {
        let sw = w[i].sqrt();
        let y = b1_from_b2 * pairs.p_b2[i];
        for (c, a) in axes.iter().enumerate() {
            let col = y.coords.cross(a) * sw;
            for r in 0..3 {
                j[(3 * i + r, c)] = col[r];
            }
        }
        for r in 0..3 {
            j[(3 * i + r, axes.len() + r)] = -sw;
        }
    }
}

/// Uncertainty and conditioning for a least-squares fit with free rotation axes `axes` (b1 frame)
/// plus a free translation.
fn lsq_uncertainty(
    pairs: &PointPairs,
    w: &[f64],
    b1_from_b2: &Isometry3<f64>,
    res: &[Vector3<f64>],
    axes: &[Vector3<f64>],
) -> (f64, Option<Uncertainty>) {
    let n = pairs.p_b1.len();
    let k = axes.len() + 3;
    // Jacobian of r_i = p1 − X·p2 w.r.t. [rotation angles about axes; δt]: [ (X p2) × a ; −I ].
    let mut j = DMatrix::zeros(3 * n, k);
    let mut g = nalgebra::DMatrix::zeros(6, k);
    for (c, a) in axes.iter().enumerate() {
        for r in 0..3 {
            g[(r, c)] = a[r];
        }
    }
    for r in 0..3 {
        g[(3 + r, axes.len() + r)] = 1.0;
    }
    fill_fit_jacobian(pairs, w, b1_from_b2, axes, &mut j);
    let radius = {
        let sv = spread_singular_values(&pairs.p_b2);
        ((sv[0] * sv[0] + sv[1] * sv[1] + sv[2] * sv[2]) / n as f64)
            .sqrt()
            .max(1e-12)
    };
    let mut j_scaled = DMatrix::zeros(3 * n, k);
    for i in 0..3 * n {
        for c in 0..k {
            j_scaled[(i, c)] = if c < axes.len() {
                j[(i, c)] / radius
            } else {
                j[(i, c)]
            };
        }
    }
    let jtj = j.transpose() * &j;
    let js = j_scaled.transpose() * &j_scaled;
    let ev = js.symmetric_eigenvalues();
    let (mn, mx) = ev
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &e| (a.min(e), b.max(e)));
    let condition = if mn > 0.0 {
        (mx / mn).sqrt()
    } else {
        f64::INFINITY
    };
    let m_eff = 3 * w.iter().filter(|&&x| x > 0.0).count();
    if m_eff <= k {
        return (condition, None);
    }
    let dof = m_eff - k;
    let rss: f64 = res.iter().zip(w).map(|(r, wi)| wi * r.norm_squared()).sum();
    let sigma2 = rss / dof as f64;
    let Some(inv) = jtj.try_inverse() else {
        return (condition, None);
    };
    let cov_dyn = &g * inv * g.transpose() * sigma2;
    let covariance = Matrix6::from_fn(|r, c| cov_dyn[(r, c)]);
    let unc = build_uncertainty(covariance, sigma2.sqrt(), dof, b1_from_b2);
    (condition, Some(unc))
}

pub(crate) fn build_uncertainty(
    covariance: Matrix6<f64>,
    sigma: f64,
    dof: usize,
    b1_from_b2: &Isometry3<f64>,
) -> Uncertainty {
    let mut u = Uncertainty {
        covariance,
        sigma_point_m: sigma,
        dof,
        e_tran_1sigma_m: 0.0,
        e_rot_1sigma_rad: 0.0,
    };
    let c_t = u.covariance_at(b1_from_b2, &Point3::origin());
    u.e_tran_1sigma_m = (0..3)
        .map(|i| c_t[(i, i)].max(0.0).sqrt())
        .fold(0.0, f64::max);
    let c_r: Matrix3<f64> = covariance.fixed_view::<3, 3>(0, 0).into_owned();
    u.e_rot_1sigma_rad = c_r.symmetric_eigenvalues().max().max(0.0).sqrt();
    u
}

/// Rigid least squares (Arun/Umeyama/Horn, no scale): minimises `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` over all
/// rotations R and translations T; `weights` default to 1 (must be finite and ≥ 0, at least 3 > 0).
/// Needs n ≥ 3 non-collinear points. The result carries the covariance from the residuals and the
/// Jacobian ([`Uncertainty`]) when n ≥ 3 (3n > 6).
///
/// # Examples
/// ```
/// use calib_core::{rigid_lsq, PointPairs};
/// use nalgebra::{Isometry3, Point3, Vector3};
/// let b1_from_b2 = Isometry3::new(Vector3::new(1.0, 0.5, 0.0), Vector3::new(0.0, 0.0, 0.7));
/// let p_b2 = vec![Point3::new(0.0, 0.0, 0.0), Point3::new(1.0, 0.0, 0.0),
///                 Point3::new(0.0, 1.0, 0.2), Point3::new(0.3, 0.2, 1.0)];
/// let p_b1 = p_b2.iter().map(|p| b1_from_b2 * p).collect();
/// let fit = rigid_lsq(&PointPairs::new(p_b1, p_b2).unwrap(), None).unwrap();
/// assert!((fit.b1_from_b2.translation.vector - b1_from_b2.translation.vector).norm() < 1e-9);
/// ```
pub fn rigid_lsq(pairs: &PointPairs, weights: Option<&[f64]>) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Lsq)?;
    let w = weights_checked(pairs, weights)?;
    let (c1, c2, m) = weighted_cross(pairs, &w);
    let r = nearest_rotation(&m);
    let t = c1 - r * c2;
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    let res = residuals(pairs, &b1_from_b2);
    let axes = [Vector3::x(), Vector3::y(), Vector3::z()];
    let (condition, uncertainty) = lsq_uncertainty(pairs, &w, &b1_from_b2, &res, &axes);
    Ok(Fit {
        method: Method::Lsq,
        b1_from_b2,
        residuals: res,
        condition,
        uncertainty,
    })
}

/// Options of [`constrained_lsq`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ConstrainedOptions {
    /// Per-point weights (default: all 1), finite and ≥ 0.
    pub weights: Option<Vec<f64>>,
}

/// Installation-constrained least squares: minimises `Σ wᵢ‖p1ᵢ − R·p2ᵢ − T‖²` with R restricted to
/// the mounts' family inside the fit (not a projection of an unconstrained estimate): with both
/// gravity directions known only the yaw about gravity is free (closed form), with a [`Mount::Wall`]
/// the paper's two angles (1-D global search, see the module doc). The optimum over the family is
/// the member maximising `tr(Rᵀ·M)` with M the weighted cross-covariance, and `T = c1 − R·c2`.
/// Needs n ≥ 3 non-collinear points (the constraint would allow 2, but then nothing checks it).
pub fn constrained_lsq(
    pairs: &PointPairs,
    mounts: &MountPair,
    options: &ConstrainedOptions,
) -> Result<Fit, CalibError> {
    check_pairs(pairs, Method::Constrained)?;
    let w = weights_checked(pairs, options.weights.as_deref())?;
    let (c1, c2, m) = weighted_cross(pairs, &w);
    let r = project_rotation_family(&m, mounts)?;
    let t = c1 - r * c2;
    let b1_from_b2 = Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&r),
    );
    let res = residuals(pairs, &b1_from_b2);
    let axes = family_axes(mounts, &r)?;
    let (condition, uncertainty) = lsq_uncertainty(pairs, &w, &b1_from_b2, &res, &axes);
    Ok(Fit {
        method: Method::Constrained,
        b1_from_b2,
        residuals: res,
        condition,
        uncertainty,
    })
}

/// Runs `method` on `pairs` (the mounts are used by `paper` and `constrained` only).
pub fn fit(pairs: &PointPairs, method: Method, mounts: &MountPair) -> Result<Fit, CalibError> {
    match method {
        Method::Generic => generic_4point(pairs, false),
        Method::GenericAffine => generic_4point(pairs, true),
        Method::Paper => paper_constrained(pairs, mounts),
        Method::Lsq => rigid_lsq(pairs, None),
        Method::Constrained => constrained_lsq(pairs, mounts, &ConstrainedOptions::default()),
    }
}

/// Quaternion from the fast Horn solver, for callers that want it (same as [`nearest_rotation`]).
pub fn nearest_rotation_horn(m: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    rotation_maximizing_trace(m).map(|q| q.to_rotation_matrix())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fast::{generic_fast, paper_fast, rigid_fit_fast};
    use crate::metrics::{e_tran, geodesic_angle};
    use kinematics::euler::rotation_from_zyz;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Zero-noise recovery: exact methods, only round-off on metre-scale data.
    const EXACT_TOL: f64 = 1e-9;

    /// A tetrahedron-ish set of n points in b2 (m), within about 1 m.
    fn cloud(n: usize, seed: u64) -> Vec<Point3<f64>> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                Point3::new(
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                    rng.random_range(0.0..1.2),
                )
            })
            .collect()
    }

    fn pairs_for(x: &Isometry3<f64>, p_b2: &[Point3<f64>]) -> PointPairs {
        PointPairs::new(p_b2.iter().map(|p| x * p).collect(), p_b2.to_vec()).unwrap()
    }

    fn iso(t: [f64; 3], r: Rotation3<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }

    /// A true `b1_from_b2` compatible with the mounts: `L1ᵀ·Rz(γ)·L2`, or `L1ᵀ·wall(α, β)` etc.
    fn truth_for(mounts: &MountPair, a: f64, b: f64) -> Isometry3<f64> {
        let r = match (
            mounts.robot1.level_from_base(),
            mounts.robot2.level_from_base(),
        ) {
            (Some(l1), Some(l2)) => {
                l1.inverse() * Rotation3::from_axis_angle(&Vector3::z_axis(), a) * l2
            }
            (Some(l1), None) => l1.inverse() * wall_rotation(a, b),
            (None, Some(l2)) => wall_rotation(a, b) * l2,
            (None, None) => unreachable!(),
        };
        iso([0.04, 1.48, 0.05], r)
    }

    fn all_mounts() -> Vec<MountPair> {
        let tilt = Mount::Tilt { rx: 0.3, ry: -0.2 };
        let wall_roll = Mount::Tilt {
            rx: PI / 2.0,
            ry: 0.7,
        };
        vec![
            MountPair::floor_floor(),
            MountPair::floor_ceiling(),
            MountPair::floor_wall(),
            MountPair {
                robot1: tilt,
                robot2: wall_roll,
            },
            MountPair {
                robot1: Mount::Ceiling,
                robot2: tilt,
            },
            MountPair {
                robot1: tilt,
                robot2: Mount::Wall,
            },
            MountPair {
                robot1: Mount::Wall,
                robot2: Mount::Floor,
            },
            MountPair {
                robot1: Mount::Wall,
                robot2: wall_roll,
            },
        ]
    }

    #[test]
    fn exact_recovery_every_method_and_mount() {
        for (k, mounts) in all_mounts().iter().enumerate() {
            for &(a, b) in &[(-0.78, 0.3), (2.9, -1.2), (PI, 0.0), (1e-9, PI)] {
                let truth = truth_for(mounts, a, b);
                for n in [4, 7] {
                    let pairs = pairs_for(&truth, &cloud(n, 7 + k as u64));
                    for method in Method::ALL {
                        let f = fit(&pairs, method, mounts).unwrap();
                        assert!(
                            e_tran(&truth, &f.b1_from_b2) < EXACT_TOL
                                && geodesic_angle(&truth, &f.b1_from_b2) < EXACT_TOL,
                            "{mounts} {} a={a} b={b} n={n}: {:?}",
                            method.name(),
                            f.b1_from_b2
                        );
                        assert!(f.residuals.iter().all(|r| r.norm() < EXACT_TOL));
                        assert!(f.condition >= 1.0 && f.condition.is_finite());
                    }
                    let p1: Vec<_> = pairs.p_b1.clone();
                    let x = rigid_fit_fast(&p1, &pairs.p_b2).unwrap();
                    assert!(
                        geodesic_angle(&truth, &x) < EXACT_TOL && e_tran(&truth, &x) < EXACT_TOL
                    );
                    let x = crate::fast::constrained_fast(&p1, &pairs.p_b2, mounts).unwrap();
                    assert!(
                        geodesic_angle(&truth, &x) < EXACT_TOL,
                        "{mounts} fast constrained"
                    );
                    if n == 4 {
                        let a4: [Point3<f64>; 4] = [p1[0], p1[1], p1[2], p1[3]];
                        let b4: [Point3<f64>; 4] =
                            [pairs.p_b2[0], pairs.p_b2[1], pairs.p_b2[2], pairs.p_b2[3]];
                        for affine in [false, true] {
                            let x = generic_fast(&a4, &b4, affine).unwrap();
                            assert!(geodesic_angle(&truth, &x) < EXACT_TOL);
                            assert!(e_tran(&truth, &x) < EXACT_TOL);
                        }
                        let x = paper_fast(&a4, &b4, mounts).unwrap();
                        assert!(
                            geodesic_angle(&truth, &x) < EXACT_TOL,
                            "{mounts} fast paper"
                        );
                        assert!(e_tran(&truth, &x) < EXACT_TOL);
                    }
                }
            }
        }
    }

    /// Noisy data: the fast kernels give the same answer as the documented slow paths.
    #[test]
    fn fast_paths_match_slow_paths_with_noise() {
        let noise = Normal::new(0.0, 0.5e-3).unwrap();
        for (k, mounts) in all_mounts().iter().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(100 + k as u64);
            let truth = truth_for(mounts, 0.4, -0.9);
            let p_b2 = cloud(4, 200 + k as u64);
            let p_b1: Vec<_> = p_b2
                .iter()
                .map(|p| {
                    truth * p
                        + Vector3::new(
                            noise.sample(&mut rng),
                            noise.sample(&mut rng),
                            noise.sample(&mut rng),
                        )
                })
                .collect();
            let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
            let a4 = [p_b1[0], p_b1[1], p_b1[2], p_b1[3]];
            let b4 = [p_b2[0], p_b2[1], p_b2[2], p_b2[3]];
            let pairs_close = |x: &Isometry3<f64>, y: &Isometry3<f64>| {
                e_tran(x, y) < 1e-10 && geodesic_angle(x, y) < 1e-10
            };
            assert!(pairs_close(
                &rigid_lsq(&pairs, None).unwrap().b1_from_b2,
                &rigid_fit_fast(&p_b1, &p_b2).unwrap()
            ));
            assert!(pairs_close(
                &generic_4point(&pairs, false).unwrap().b1_from_b2,
                &generic_fast(&a4, &b4, false).unwrap()
            ));
            assert!(
                pairs_close(
                    &paper_constrained(&pairs, mounts).unwrap().b1_from_b2,
                    &paper_fast(&a4, &b4, mounts).unwrap()
                ),
                "{mounts}"
            );
            assert!(pairs_close(
                &constrained_lsq(&pairs, mounts, &ConstrainedOptions::default())
                    .unwrap()
                    .b1_from_b2,
                &crate::fast::constrained_fast(&p_b1, &p_b2, mounts).unwrap()
            ));
        }
    }

    /// Brute force over a family: a fine grid followed by a coordinate-wise golden refinement is a
    /// slow but assumption-free maximiser of tr(RᵀM).
    fn brute_force_max(f: impl Fn(f64, f64) -> f64, two_d: bool) -> f64 {
        let steps = 360;
        let mut best = (0.0, 0.0, f64::NEG_INFINITY);
        for i in 0..steps {
            let a = -PI + 2.0 * PI * i as f64 / steps as f64;
            for jj in 0..(if two_d { steps } else { 1 }) {
                let b = -PI + 2.0 * PI * jj as f64 / steps as f64;
                let v = f(a, b);
                if v > best.2 {
                    best = (a, b, v);
                }
            }
        }
        // Local refinement by shrinking pattern search.
        let (mut a, mut b, mut v) = best;
        let mut h = 2.0 * PI / steps as f64;
        while h > 1e-10 {
            let mut improved = false;
            for (da, db) in [(h, 0.0), (-h, 0.0), (0.0, h), (0.0, -h)] {
                if !two_d && db != 0.0 {
                    continue;
                }
                let nv = f(a + da, b + db);
                if nv > v {
                    a += da;
                    b += db;
                    v = nv;
                    improved = true;
                }
            }
            if !improved {
                h *= 0.5;
            }
        }
        v
    }

    /// Closed forms (eq 11, eq 30, the yaw form for tilts, the wall 1-D search) reach the brute-force
    /// minimum of ‖R − M‖_F over their family, for random (non-rotation) M. Tolerance: the pattern
    /// search stops at a 1e-10 rad step, so the objective agrees to ~1e-9.
    #[test]
    fn closed_forms_match_brute_force() {
        const OBJ_TOL: f64 = 1e-8;
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        for trial in 0..12 {
            let m = Matrix3::from_fn(|_, _| rng.random_range(-1.0..1.0))
                + if trial % 2 == 0 {
                    Matrix3::identity()
                } else {
                    Matrix3::zeros()
                };
            for mounts in all_mounts() {
                let r = project_rotation_family(&m, &mounts).unwrap();
                let ours = (r.matrix() - m).norm();
                let fam = |a: f64, b: f64| -> f64 {
                    let t = truth_for(&mounts, a, b);
                    -(t.rotation.to_rotation_matrix().matrix() - m).norm()
                };
                let two_d = matches!(family(&mounts).unwrap(), Family::Wall { .. });
                let brute = -brute_force_max(fam, two_d);
                assert!(
                    ours <= brute + OBJ_TOL,
                    "{mounts}: ours {ours} brute {brute}"
                );
                // The result is in the family: reconstruct and compare.
                assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
            }
            // eq 11 and eq 30 literally.
            let ff = project_rotation_family(&m, &MountPair::floor_floor()).unwrap();
            let th = (m[(1, 0)] - m[(0, 1)]).atan2(m[(0, 0)] + m[(1, 1)]);
            assert!(
                (ff.matrix() - Rotation3::from_axis_angle(&Vector3::z_axis(), th).matrix()).amax()
                    < 1e-12
            );
            let fc = project_rotation_family(&m, &MountPair::floor_ceiling()).unwrap();
            let (al, be) = (m[(0, 0)] - m[(1, 1)], m[(1, 0)] + m[(0, 1)]);
            let nn = (al * al + be * be).sqrt();
            let eq30 = Matrix3::new(
                al / nn,
                be / nn,
                0.0,
                be / nn,
                -al / nn,
                0.0,
                0.0,
                0.0,
                -1.0,
            );
            assert!((fc.matrix() - eq30).amax() < 1e-12);
        }
    }

    #[test]
    fn nearest_rotation_guards_reflection() {
        let m = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
        let r = nearest_rotation(&m);
        assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
        let r = nearest_rotation(&(rotation_from_zyz([0.3, 1.0, -2.0]).matrix() * 3.0));
        assert!((r.matrix() - rotation_from_zyz([0.3, 1.0, -2.0]).matrix()).amax() < 1e-12);
    }

    #[test]
    fn degeneracy_errors_name_points_and_singular_values() {
        let truth = truth_for(&MountPair::floor_floor(), 0.5, 0.0);
        // Collinear.
        let line: Vec<_> = (0..4)
            .map(|i| Point3::new(0.3 * i as f64, 0.1 * i as f64, 0.2))
            .collect();
        let e = rigid_lsq(&pairs_for(&truth, &line), None).unwrap_err();
        match &e {
            CalibError::Collinear {
                rows,
                singular_values_mm,
                ..
            } => {
                assert_eq!(rows, &vec![1, 2, 3, 4]);
                assert!(singular_values_mm[1] < 1e-6);
            }
            other => panic!("{other}"),
        }
        assert!(e.to_string().contains("collinear"));
        // Coplanar: fine for lsq, an error for the 4-point methods.
        let plane = vec![
            Point3::new(0.0, 0.0, 0.5),
            Point3::new(1.0, 0.0, 0.5),
            Point3::new(0.0, 1.0, 0.5),
            Point3::new(1.0, 1.0, 0.5),
        ];
        let pairs = pairs_for(&truth, &plane);
        assert!(rigid_lsq(&pairs, None).is_ok());
        for m in [Method::Generic, Method::GenericAffine, Method::Paper] {
            let e = fit(&pairs, m, &MountPair::floor_floor()).unwrap_err();
            assert!(matches!(e, CalibError::Coplanar { .. }), "{e}");
            assert!(e.to_string().contains("lsq"));
        }
        // Too few.
        let e = rigid_lsq(&pairs_for(&truth, &plane[..2]), None).unwrap_err();
        assert!(matches!(
            e,
            CalibError::TooFewPoints {
                needed: 3,
                got: 2,
                ..
            }
        ));
        let e = generic_4point(&pairs_for(&truth, &cloud(3, 1)), false).unwrap_err();
        assert!(matches!(
            e,
            CalibError::TooFewPoints {
                needed: 4,
                got: 3,
                ..
            }
        ));
        // Two walls unsupported.
        let wall2 = MountPair {
            robot1: Mount::Wall,
            robot2: Mount::Wall,
        };
        let e = constrained_lsq(&pairs, &wall2, &ConstrainedOptions::default()).unwrap_err();
        assert!(matches!(e, CalibError::UnsupportedMounts { .. }));
        // Non-finite.
        let mut bad = pairs_for(&truth, &cloud(5, 3));
        bad.p_b2[2].x = f64::NAN;
        assert!(matches!(
            rigid_lsq(&bad, None),
            Err(CalibError::NonFinite { row: 3, .. })
        ));
        assert!(rigid_fit_fast(&bad.p_b1, &bad.p_b2).is_none());
        // Weights.
        let good = pairs_for(&truth, &cloud(5, 3));
        assert!(rigid_lsq(&good, Some(&[1.0, 2.0])).is_err());
        assert!(rigid_lsq(&good, Some(&[1.0, -2.0, 1.0, 1.0, 1.0])).is_err());
    }

    /// Weighted lsq: a zero-weighted corrupted point has no effect.
    #[test]
    fn weights_are_honoured() {
        let truth = truth_for(&MountPair::floor_floor(), 0.5, 0.0);
        let mut pairs = pairs_for(&truth, &cloud(6, 9));
        pairs.p_b1[5].x += 0.05;
        let f = rigid_lsq(&pairs, Some(&[1.0, 1.0, 1.0, 1.0, 1.0, 0.0])).unwrap();
        assert!(geodesic_angle(&truth, &f.b1_from_b2) < EXACT_TOL);
        assert!(e_tran(&truth, &f.b1_from_b2) < EXACT_TOL);
    }

    /// Central-difference check of the fit Jacobian. Step 1e-6 (rad or m): truncation error
    /// O(h²·‖p‖) ≈ 1e-12 and round-off ≈ 1e-16/1e-6 = 1e-10, so 1e-7 is a safe tolerance.
    #[test]
    fn fit_jacobian_matches_central_differences() {
        const H: f64 = 1e-6;
        const JAC_TOL: f64 = 1e-7;
        let truth = truth_for(&MountPair::floor_wall(), 0.4, 1.1);
        let pairs = pairs_for(&truth, &cloud(5, 11));
        let w = [1.0, 2.0, 0.5, 1.0, 3.0];
        let axes = family_axes(
            &MountPair::floor_wall(),
            &truth.rotation.to_rotation_matrix(),
        )
        .unwrap();
        let k = axes.len() + 3;
        let mut j = DMatrix::zeros(15, k);
        fill_fit_jacobian(&pairs, &w, &truth, &axes, &mut j);
        let res = |x: &Isometry3<f64>| -> Vec<f64> {
            let mut out = vec![];
            for ((p1, p2), wi) in pairs.p_b1.iter().zip(&pairs.p_b2).zip(&w) {
                let r = (p1 - x * p2) * wi.sqrt();
                out.extend([r.x, r.y, r.z]);
            }
            out
        };
        for c in 0..k {
            let pert = |s: f64| -> Isometry3<f64> {
                if c < axes.len() {
                    Isometry3::rotation(axes[c] * s) * truth
                } else {
                    let mut t = Vector3::zeros();
                    t[c - axes.len()] = s;
                    Isometry3::translation(t.x, t.y, t.z) * truth
                }
            };
            let (rp, rm) = (res(&pert(H)), res(&pert(-H)));
            for i in 0..15 {
                let fd = (rp[i] - rm[i]) / (2.0 * H);
                assert!(
                    (fd - j[(i, c)]).abs() < JAC_TOL,
                    "col {c} row {i}: fd {fd} vs {}",
                    j[(i, c)]
                );
            }
        }
    }

    /// The predicted uncertainty matches a small seeded Monte Carlo: the empirical RMS translation
    /// error over 300 trials lies within 25 % of the predicted one (sampling error of an RMS over 300
    /// trials of a 3-D error is ≈ 4 %; the prediction uses σ̂ per fit, averaged here).
    #[test]
    fn predicted_uncertainty_matches_monte_carlo() {
        let sigma = 0.3e-3;
        let noise = Normal::new(0.0, sigma).unwrap();
        let p_b2 = cloud(8, 5);
        for mounts in [MountPair::floor_floor(), MountPair::floor_wall()] {
            let truth = truth_for(&mounts, 0.3, 0.8);
            let work = Point3::new(1.5, 0.5, 0.8);
            for method in [Method::Lsq, Method::Constrained] {
                let (mut emp, mut pred, trials) = (0.0, 0.0, 300);
                for t in 0..trials {
                    let mut rng = ChaCha8Rng::seed_from_u64(1000 + t);
                    let p_b1: Vec<_> = p_b2
                        .iter()
                        .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng)))
                        .collect();
                    let f = fit(
                        &PointPairs::new(p_b1, p_b2.clone()).unwrap(),
                        method,
                        &mounts,
                    )
                    .unwrap();
                    emp += (f.b1_from_b2 * work - truth * work).norm_squared();
                    let u = f.uncertainty.expect("uncertainty for lsq fits");
                    pred += u.tre_rms_m(&f.b1_from_b2, &work).powi(2);
                }
                let (emp, pred) = ((emp / trials as f64).sqrt(), (pred / trials as f64).sqrt());
                assert!(
                    (emp / pred - 1.0).abs() < 0.25,
                    "{mounts} {}: emp {emp} pred {pred}",
                    method.name()
                );
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Moving b1 rigidly by G changes the fit to G·X (left invariance), for every method whose
        /// family is closed under that motion (lsq, generic: any G; constrained/paper floor–floor:
        /// G a yaw plus translation, which keeps robot 1 on the floor).
        #[test]
        fn fit_is_invariant_under_rigid_motion(
            yaw in -PI..PI, tx in -2.0..2.0f64, ty in -2.0..2.0f64, tz in -1.0..1.0f64,
            rx in -PI..PI, ry in -1.5..1.5f64, seed in 0u64..1000,
        ) {
            let mounts = MountPair::floor_floor();
            let truth = truth_for(&mounts, 0.7, 0.0);
            let noise = Normal::new(0.0, 1e-3).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let p_b2 = cloud(6, seed);
            let p_b1: Vec<_> = p_b2.iter()
                .map(|p| truth * p + Vector3::from_fn(|_, _| noise.sample(&mut rng))).collect();
            let pairs = PointPairs::new(p_b1.clone(), p_b2.clone()).unwrap();
            let g_any = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(rx, ry, yaw));
            let g_yaw = Isometry3::new(Vector3::new(tx, ty, tz), Vector3::new(0.0, 0.0, yaw));
            for (method, g) in [(Method::Lsq, g_any), (Method::Generic, g_any),
                                (Method::Constrained, g_yaw), (Method::Paper, g_yaw)] {
                let moved = PointPairs::new(p_b1.iter().map(|p| g * p).collect(), p_b2.clone()).unwrap();
                let f0 = fit(&pairs, method, &mounts).unwrap();
                let f1 = fit(&moved, method, &mounts).unwrap();
                let expect = g * f0.b1_from_b2;
                prop_assert!(e_tran(&expect, &f1.b1_from_b2) < 1e-9, "{}", method.name());
                prop_assert!(geodesic_angle(&expect, &f1.b1_from_b2) < 1e-9);
                for (a, b) in f0.residuals.iter().zip(&f1.residuals) {
                    prop_assert!((a.norm() - b.norm()).abs() < 1e-9);
                }
            }
        }
    }
}

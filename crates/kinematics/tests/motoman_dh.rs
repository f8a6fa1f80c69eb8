//! The CTU dual-arm Motoman URDFs (`robots/motoman_{right,left}_arm.urdf`) against the standard DH
//! product they were generated from (`/work/shared/data/ctu-motoman/README.md`, "Robot model").
//!
//! The DH product is written out here independently of the URDF loader:
//! `T_i = Rz(offset_i + q_i) · Tz(d_i) · Tx(a_i) · Rx(alpha_i)`, chain TT, S, L, U, R, B, T, EE with
//! joint values `[E = 0, S, L, U, R, B, T, 0]`; the base frame is the start of row TT (common to
//! both arms). The end-effector rows are tip offsets in `tool0` (the frame after row T).

use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

use kinematics::{base_from_flange, base_from_tip, RobotModel};
use nalgebra::{Isometry3, Matrix4, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Position agreement, m (the brief's bound; round-off is ~1e-15 m on these 2 m chains).
const POS_TOL_M: f64 = 1e-9;
/// Orientation agreement, rad (geodesic angle between the two rotations).
const ROT_TOL_RAD: f64 = 1e-9;
/// Random configurations per arm.
const N_CONFIGS: usize = 500;

/// One DH row: `(a [m], d [m], alpha [rad], offset [rad])`.
type Row = (f64, f64, f64, f64);

/// Rows S, L, U, R, B, T, identical for both arms.
const ARM_ROWS: [Row; 6] = [
    (0.150, 1.4159, -FRAC_PI_2, 0.0),
    (0.614, 0.0, PI, -FRAC_PI_2),
    (0.200, 0.0, -FRAC_PI_2, 0.0),
    (0.0, -0.640, FRAC_PI_2, 0.0),
    (0.030, 0.0, FRAC_PI_2, -FRAC_PI_2),
    (0.0, 0.200, 0.0, 0.0),
];
/// Row TT: alpha = ±15° (right +, left −), offset −π/2, driven by E (0 here).
const TT_D_M: f64 = -0.263;
const TT_ALPHA_DEG: f64 = 15.0;
/// EE row of the marker dodecahedron (both arms).
const EE_MARKER: Row = (0.0, 0.354, 0.0, 0.0);
/// EE rows of the Leica reflector.
const EE_REFLECTOR_RIGHT: Row = (0.045, 0.245, 0.0, -0.38);
const EE_REFLECTOR_LEFT: Row = (0.05, 0.25, 0.0, 0.0);

/// `Rz(theta) · Tz(d) · Tx(a) · Rx(alpha)` as a 4×4 homogeneous matrix, written out.
fn dh(a: f64, d: f64, alpha: f64, theta: f64) -> Matrix4<f64> {
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = alpha.sin_cos();
    #[rustfmt::skip]
    let m = Matrix4::new(
        ct,  -st * ca,  st * sa, a * ct,
        st,   ct * ca, -ct * sa, a * st,
        0.0,  sa,       ca,      d,
        0.0,  0.0,      0.0,     1.0,
    );
    m
}

/// base_from_EE by the DH product; `ee = None` stops after row T (tool0).
fn dh_base_from(tt_alpha: f64, q: &[f64], ee: Option<Row>) -> Matrix4<f64> {
    let e = 0.0;
    let mut m = dh(0.0, TT_D_M, tt_alpha, -FRAC_PI_2 + e);
    for (&(a, d, alpha, offset), &qi) in ARM_ROWS.iter().zip(q) {
        m *= dh(a, d, alpha, offset + qi);
    }
    if let Some((a, d, alpha, offset)) = ee {
        m *= dh(a, d, alpha, offset);
    }
    m
}

/// The EE row's origin in the frame after row T, m.
fn tip_of(ee: Row) -> Vector3<f64> {
    dh(ee.0, ee.1, ee.2, ee.3)
        .fixed_view::<3, 1>(0, 3)
        .into_owned()
}

fn load(name: &str) -> RobotModel {
    let p = format!("{}/../../robots/{name}.urdf", env!("CARGO_MANIFEST_DIR"));
    RobotModel::from_urdf_file(Path::new(&p), "tool0").unwrap()
}

/// Largest position (m) and rotation (rad) difference between an isometry and a 4×4 matrix.
fn difference(urdf: &Isometry3<f64>, dh: &Matrix4<f64>) -> (f64, f64) {
    let h = urdf.to_homogeneous();
    let dp = (h.fixed_view::<3, 1>(0, 3) - dh.fixed_view::<3, 1>(0, 3)).norm();
    let r = h.fixed_view::<3, 3>(0, 0).transpose() * dh.fixed_view::<3, 3>(0, 0);
    // Geodesic angle from the trace, clamped against round-off; for tiny angles use the
    // skew part, which is accurate where acos is not.
    let skew = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    );
    let cos = ((r.trace() - 1.0) / 2.0).clamp(-1.0, 1.0);
    let angle = (0.5 * skew.norm()).atan2(cos);
    (dp, angle)
}

fn check_arm(name: &str, tt_alpha: f64, reflector: Row, seed: u64) {
    let model = load(name);
    assert_eq!(model.dof(), 6, "{name}: six revolute joints");
    let names: Vec<&str> = model.joints().iter().map(|j| j.name.as_str()).collect();
    assert_eq!(
        names,
        ["joint_s", "joint_l", "joint_u", "joint_r", "joint_b", "joint_t"],
        "{name}: joint order S, L, U, R, B, T"
    );
    assert_eq!(model.root_link(), "base_link");
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut worst = (0.0_f64, 0.0_f64);
    // The zero pose, the straight wrist, exact ±180° on T, then random poses within the limits.
    let mut configs: Vec<Vec<f64>> = vec![
        vec![0.0; 6],
        vec![0.0, 0.0, 0.0, 0.0, FRAC_PI_2, 0.0],
        vec![0.0, 0.0, 0.0, 0.0, 0.0, PI],
        vec![0.0, 0.0, 0.0, 0.0, 0.0, -PI],
    ];
    for _ in 0..N_CONFIGS {
        configs.push(
            model
                .joints()
                .iter()
                .map(|j| rng.random_range(j.lower..j.upper))
                .collect(),
        );
    }
    for q in &configs {
        let flange = base_from_flange(&model, q).unwrap();
        let (dp, dr) = difference(&flange, &dh_base_from(tt_alpha, q, None));
        for ee in [EE_MARKER, reflector] {
            // A tip offset is a point: its position must equal the DH product through the EE row;
            // its orientation is tool0's (the EE row's own Rz(offset), −0.38 rad for the right
            // reflector, turns only the EE frame, which no observation in the data uses).
            let tip = base_from_tip(&model, q, &tip_of(ee)).unwrap();
            let mut through_ee = dh_base_from(tt_alpha, q, Some(ee));
            let tool0 = dh_base_from(tt_alpha, q, None);
            through_ee
                .fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&tool0.fixed_view::<3, 3>(0, 0));
            let (tp, tr) = difference(&tip, &through_ee);
            worst = (worst.0.max(tp), worst.1.max(tr));
        }
        worst = (worst.0.max(dp), worst.1.max(dr));
        assert!(
            dp < POS_TOL_M && dr < ROT_TOL_RAD,
            "{name} at q = {q:?}: URDF vs DH differ by {dp:e} m, {dr:e} rad"
        );
    }
    assert!(
        worst.0 < POS_TOL_M && worst.1 < ROT_TOL_RAD,
        "{name}: worst tip difference {:e} m, {:e} rad",
        worst.0,
        worst.1
    );
}

#[test]
fn right_arm_urdf_equals_dh_product() {
    check_arm(
        "motoman_right_arm",
        TT_ALPHA_DEG.to_radians(),
        EE_REFLECTOR_RIGHT,
        12,
    );
}

#[test]
fn left_arm_urdf_equals_dh_product() {
    check_arm(
        "motoman_left_arm",
        -TT_ALPHA_DEG.to_radians(),
        EE_REFLECTOR_LEFT,
        13,
    );
}

#[test]
fn tip_offsets_in_tool0_mm() {
    // The values the cell file and the docs give (mm): dodecahedron on z; the right reflector's
    // EE row turns its a = 45 mm by offset −0.38 rad.
    let marker = tip_of(EE_MARKER) * 1e3;
    assert!((marker - Vector3::new(0.0, 0.0, 354.0)).norm() < 1e-9);
    let right = tip_of(EE_REFLECTOR_RIGHT) * 1e3;
    let expected = Vector3::new(45.0 * 0.38_f64.cos(), -45.0 * 0.38_f64.sin(), 245.0);
    assert!((right - expected).norm() < 1e-9);
    assert!((right.x - 41.7899).abs() < 1e-4 && (right.y + 16.6914).abs() < 1e-4);
    let left = tip_of(EE_REFLECTOR_LEFT) * 1e3;
    assert!((left - Vector3::new(50.0, 0.0, 250.0)).norm() < 1e-9);
}

#[test]
fn the_arms_differ_only_by_the_turntable_row_tilt() {
    // Same q on both arms: the left base_from_flange is the right one with row TT's alpha negated.
    // The two tips must differ (a URDF swap would pass the other tests only if both tilts agreed).
    let (right, left) = (load("motoman_right_arm"), load("motoman_left_arm"));
    let q = [0.3, 0.2, -0.1, 0.5, 1.2, -0.4];
    let r = base_from_flange(&right, &q).unwrap().translation.vector;
    let l = base_from_flange(&left, &q).unwrap().translation.vector;
    assert!((r - l).norm() > 0.1, "right {r:?} vs left {l:?}");
}

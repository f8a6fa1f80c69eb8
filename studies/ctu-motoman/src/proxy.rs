//! A model-vs-model proxy of the hidden whole-workspace set (issue 12: ~600 right-arm poses over
//! the whole workspace, nominal ≈ 3.0 mm rms there). No measurement is involved: a seeded set of
//! right-arm joint vectors spread over the URDF's joint limits is predicted by a reference model
//! (the `all` calibration), and each other model is scored against those predictions with the
//! issue's protocol (one rigid registration + the reflector offset fitted on one half, scored on
//! the other half, both ways). The result is how far two MODELS differ over the whole
//! workspace, not how far either is from the real arm.

use handclasp_cell::Cell;
use kinematics::{true_base_from_tip, KinematicErrors};
use nalgebra::{Point3, Vector3};

use crate::data::{Pose, Recording, Role};
use crate::study::{score_recording, summarise, Summary, REFLECTOR_RIGHT_M};

/// Seed of the proxy's joint vectors.
pub const PROXY_SEED: u64 = 600;
/// Number of proxy poses (the hidden set's size).
pub const PROXY_POSES: usize = 600;
/// Lowest height of the right arm's T flange (tool0 origin) of a proxy pose, m (common base
/// frame): the lowest tool0 of any pose of the dataset, so that the proxy stays above the tables
/// the cell works on.
fn lowest_tool0_z_m(cell: &Cell, recordings: &[Recording]) -> anyhow::Result<f64> {
    let r = &cell.robot1;
    let zero = KinematicErrors::zero(6);
    let mut z = f64::INFINITY;
    for rec in recordings.iter().filter(|rec| rec.right_arm) {
        for p in &rec.poses {
            let t = true_base_from_tip(&r.model, &zero, &p.q_right, &Vector3::zeros(), &r.g_base)?;
            z = z.min(t.translation.z);
        }
    }
    Ok(z)
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The proxy's right-arm joint vectors, rad: uniform in the URDF's joint limits (seed
/// [`PROXY_SEED`]), kept when tool0 is at least as high as the lowest tool0 of the dataset and
/// at least 0.3 m from the S axis (outside the arm's own body). Returns (poses, draws).
pub fn proxy_joints(
    cell: &Cell,
    recordings: &[Recording],
) -> anyhow::Result<(Vec<Vec<f64>>, usize)> {
    let r = &cell.robot1;
    let z_min = lowest_tool0_z_m(cell, recordings)?;
    let zero = KinematicErrors::zero(6);
    let limits: Vec<(f64, f64)> = r
        .model
        .joints()
        .iter()
        .map(|j| (j.lower, j.upper))
        .collect();
    anyhow::ensure!(
        limits
            .iter()
            .all(|(lo, hi)| lo.is_finite() && hi.is_finite() && lo < hi),
        "the right arm's URDF needs finite joint limits for the proxy set"
    );
    let mut state = PROXY_SEED;
    let (mut out, mut draws) = (Vec::new(), 0usize);
    while out.len() < PROXY_POSES {
        draws += 1;
        anyhow::ensure!(
            draws < 100 * PROXY_POSES,
            "fewer than 1 in 100 joint draws is above the tables"
        );
        let q: Vec<f64> = limits
            .iter()
            .map(|(lo, hi)| {
                lo + (hi - lo) * (splitmix64(&mut state) >> 11) as f64 / (1u64 << 53) as f64
            })
            .collect();
        let t = true_base_from_tip(&r.model, &zero, &q, &Vector3::zeros(), &r.g_base)?;
        let p = t.translation.vector;
        if p.z >= z_min && p.xy().norm() >= 0.3 {
            out.push(q);
        }
    }
    Ok((out, draws))
}

/// The reference model's reflector positions at `joints` as a right-arm tracker recording (the
/// "tracker" frame is the common base). `reference` is the right arm's correction with `tip` = 0.
pub fn reference_recording(
    cell: &Cell,
    joints: &[Vec<f64>],
    reference: &KinematicErrors,
) -> anyhow::Result<Recording> {
    let r = &cell.robot1;
    let reflector = Vector3::from(REFLECTOR_RIGHT_M);
    let poses = joints
        .iter()
        .map(|q| {
            let t = true_base_from_tip(&r.model, reference, q, &reflector, &r.g_base)?;
            Ok(Pose {
                q_right: q.clone(),
                q_left: vec![0.0; 6],
                p_tracker: Some(Point3::from(t.translation.vector)),
                faces: None,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Recording {
        name: "proxy_whole_workspace".into(),
        role: Role::Tracker,
        pattern: "proxy",
        right_arm: true,
        poses,
    })
}

/// The held-out difference between `model` (the right arm's correction) and the reference
/// recording, with the protocol. The `tip` field of `model` (a marker centre) is ignored.
pub fn model_difference(
    cell: &Cell,
    reference: &Recording,
    model: &KinematicErrors,
) -> anyhow::Result<Summary> {
    let mut m = model.clone();
    m.tip = Vector3::zeros();
    let zero = KinematicErrors::zero(6);
    let s = score_recording(cell, reference, (&m, &zero), None)?;
    Ok(summarise(&s.iter().map(|p| p.error_m).collect::<Vec<_>>()))
}

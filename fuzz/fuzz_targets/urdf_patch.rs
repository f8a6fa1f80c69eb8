//! `kinematics::patch_urdf_text` + `verify_patched_urdf` on arbitrary text with arbitrary small
//! corrections.
//!
//! Input layout (so that the seed corpus can be `robots/*.urdf` behind a short header):
//! - byte 0: bit 0 set = use the model loaded from the text itself (tool link `tool0`) when it
//!   loads; otherwise the shipped robot `(byte0 >> 1) % 4` (`common::ROBOT_FILES`), whose text
//!   may then differ from the fuzzed one;
//! - byte 1: number of corrections k (mod 16), then k × 4 bytes: joint (mod dof), kind (mod 10:
//!   offset, origin x/y/z, origin roll/pitch/yaw, then joint scale, tip, mount — the last three
//!   are not URDF-expressible and must be refused), value i16 × 1e-6 (m or rad; `i16::MIN` = NaN);
//! - the rest: the URDF text (UTF-8).
//!
//! An Ok patch must verify again and reload with the model's joint count.
#![no_main]

use handclasp_fuzz as common;

use kinematics::{patch_urdf_text, verify_patched_urdf, KinematicErrors, RobotModel};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let [sel, k, rest @ ..] = data else {
        return;
    };
    let k = usize::from(*k % 16);
    if rest.len() < 4 * k {
        return;
    }
    let (corr, text) = rest.split_at(4 * k);
    let Ok(text) = std::str::from_utf8(text) else {
        return;
    };
    let own;
    let model = match (sel & 1 == 1)
        .then(|| RobotModel::from_urdf_str(text, "tool0").ok())
        .flatten()
    {
        Some(m) => {
            own = m;
            &own
        }
        None => &common::robots()[usize::from(sel >> 1) % common::ROBOT_FILES.len()].1,
    };
    // One error entry per chain joint (coupled joints included).
    let n = model.chain_joints().len();
    if n == 0 {
        return;
    }
    let mut errors = KinematicErrors::zero(n);
    for c in corr.chunks_exact(4) {
        let j = usize::from(c[0]) % n;
        let raw = i16::from_le_bytes([c[2], c[3]]);
        let v = if raw == i16::MIN {
            f64::NAN
        } else {
            f64::from(raw) * 1e-6
        };
        match c[1] % 10 {
            0 => errors.joint_offset[j] += v,
            1..=3 => errors.origin_xyz[j][usize::from(c[1] % 10 - 1)] += v,
            4..=6 => errors.origin_rpy[j][usize::from(c[1] % 10 - 4)] += v,
            7 => errors.joint_scale[j] += v,
            8 => errors.tip[j % 3] += v,
            _ => errors.mount_xyz[j % 3] += v,
        }
    }
    let Ok(patched) = patch_urdf_text(text, model, &errors) else {
        return;
    };
    let worst = verify_patched_urdf(&patched, model, &errors).expect("an Ok patch verifies again");
    assert!(
        worst <= kinematics::PATCH_TOLERANCE_M,
        "deviation {worst} m"
    );
    let reloaded = RobotModel::from_urdf_str(&patched, model.tool_link()).expect("reloads");
    assert_eq!(reloaded.chain_joints().len(), n);
});

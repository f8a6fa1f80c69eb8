//! URDF text → `RobotModel`: any text, any tool link name. Input: the URDF text, optionally
//! followed by a NUL byte and the tool link name (default `tool0`, so the seed corpus is plain
//! URDF files). A model that loads must give a finite flange pose at a joint vector inside its
//! limits.
#![no_main]

use kinematics::{base_from_flange, RobotModel};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let (xml, tool) = match text.rfind('\0') {
        Some(i) => (&text[..i], &text[i + 1..]),
        None => (text, "tool0"),
    };
    let Ok(model) = RobotModel::from_urdf_str(xml, tool) else {
        return;
    };
    // Each joint at 0 clamped into its limits (the middle of a range that excludes 0).
    let q: Vec<f64> = model
        .joints()
        .iter()
        .map(|j| 0.0f64.clamp(j.lower, j.upper))
        .collect();
    let pose = base_from_flange(&model, &q).expect("q inside the limits is accepted");
    assert!(
        pose.translation.vector.iter().all(|v| v.is_finite())
            && pose.rotation.coords.iter().all(|v| v.is_finite()),
        "a loaded model gives a non-finite flange pose {pose:?}"
    );
});

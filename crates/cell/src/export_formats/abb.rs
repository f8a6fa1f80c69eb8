//! ABB MultiMove: robot 2's base frame as the `ROB_2` instance of the `ROBOT` type in MOC.cfg
//! (topic Motion).
//!
//! Convention, checked against:
//! - MOC.cfg `ROBOT` attributes `-base_frame_pos_x/_y/_z` are **metres** and
//!   `-base_frame_orient_u0.._u3` are the quaternion **q1..q4**: ABB's own RWS client library reads
//!   them so (`ros-industrial/abb_librws`, `src/rws_interface.cpp`, `RWSInterface::getCFGRobots`:
//!   `base_frame_pos_x` × 1e3 to mm, `base_frame_orient_u0` → `rot.q1`, …), and a controller
//!   backup shows the form (`ebruun/ECL_robotic_cell`,
//!   `_controller_backups/4600-COMPAS_RRC_BACKUP/SYSPAR/MOC.cfg`: `-base_frame_pos_x 3.69928 …
//!   -base_frame_orient_u0 0.707061 … -base_frame_orient_u3 -0.707152`).
//! - RAPID `orient` is `q1..q4 = w, x, y, z`, `q1` the scalar part (ABB, *Technical reference
//!   manual – RAPID Instructions, Functions and Data types*, data type `orient`; restated in
//!   Roboception's rc_visard NG manual, "ABB pose format": `(x, y, z, w) = (q2, q3, q4, q1)`,
//!   <https://doc.rc-visard-ng.com/v25.10/en/pose_format_abb.html>). The sign is free; `q1 ≥ 0` is
//!   this export's choice ([`kinematics::quaternion_wxyz`]), as the issue asked.
//! - The base frame of a robot is its pose in the **world** frame; in a MultiMove system the world
//!   is shared, here robot 1's base, so `ROB_1` keeps the identity (the defaults: position 0,
//!   `u0 = 1`) and `ROB_2` gets `b1_from_b2`.
//!
//! The file is a fragment, not a loadable MOC.cfg: a `ROBOT` instance loaded with "replace"
//! would lose its other attributes (robot type, joints). The opening comment says so. The
//! controller stores these attributes with ~7 significant digits (the backup above), far finer
//! than any calibration.

use nalgebra::Isometry3;

use super::{metres, number, unit, AbbBaseFrame, Header};

/// The file name.
pub const FILE: &str = "abb_moc_base_frame.cfg";

/// The MOC.cfg instance name of robot 2 (the MultiMove default).
pub const ROB2: &str = "ROB_2";

/// The fragment: opening comment, then the `ROB_2` instance with the six base frame attributes.
pub(crate) fn render(v: &AbbBaseFrame, header: &Header<'_>) -> String {
    let mut s = header.lines(
        "# ",
        &[
            "Convention: ABB MOC.cfg, topic Motion, type ROBOT, base frame of ROB_2 in the world frame (= robot 1's base):",
            "base_frame_pos_x/y/z in metres; base_frame_orient_u0..u3 = q1..q4 = w, x, y, z of a unit quaternion, q1 >= 0.",
            "ROB_1 keeps the identity base frame (pos 0 0 0, u0 1, u1 u2 u3 0).",
            "A FRAGMENT, not a loadable MOC.cfg: type the values on the FlexPendant (Control Panel > Configuration >",
            "Motion > Robot > ROB_2 > Base Frame x, y, z, q1..q4; restart the controller) or merge the attributes into",
            "the ROB_2 instance of your MOC.cfg. Do not load this file with 'replace': the instance would lose its",
            "other attributes.",
        ],
    );
    s.push_str("ROBOT:\n\n");
    s.push_str(&format!(
        "      -name \"{ROB2}\" -base_frame_pos_x {} -base_frame_pos_y {}\\\n      -base_frame_pos_z {} -base_frame_orient_u0 {}\\\n      -base_frame_orient_u1 {} -base_frame_orient_u2 {}\\\n      -base_frame_orient_u3 {}\n",
        metres(v.x_m),
        metres(v.y_m),
        metres(v.z_m),
        unit(v.q1),
        unit(v.q2),
        unit(v.q3),
        unit(v.q4)
    ));
    s
}

/// The `ROB_2` base frame of a MOC.cfg text (this fragment or a whole file): attributes the
/// instance omits take ABB's defaults (position 0, `u0 = 1`, `u1..u3 = 0`).
pub fn parse_base_frame(text: &str) -> Result<AbbBaseFrame, String> {
    // Join continuation lines; drop comments.
    let joined: String = text
        .lines()
        .filter(|l| !l.trim_start().starts_with('#'))
        .map(|l| l.trim_end().trim_end_matches('\\'))
        .collect::<Vec<_>>()
        .join(" ");
    let tokens: Vec<&str> = joined.split_whitespace().collect();
    let start = tokens
        .windows(2)
        .position(|w| w[0] == "-name" && w[1] == format!("\"{ROB2}\""))
        .ok_or_else(|| format!("no `-name \"{ROB2}\"` instance"))?;
    let mut v = AbbBaseFrame {
        x_m: 0.0,
        y_m: 0.0,
        z_m: 0.0,
        q1: 1.0,
        q2: 0.0,
        q3: 0.0,
        q4: 0.0,
    };
    let mut i = start + 2;
    while i < tokens.len() && tokens[i] != "-name" {
        let key = tokens[i];
        let slot = match key {
            "-base_frame_pos_x" => Some(&mut v.x_m),
            "-base_frame_pos_y" => Some(&mut v.y_m),
            "-base_frame_pos_z" => Some(&mut v.z_m),
            "-base_frame_orient_u0" => Some(&mut v.q1),
            "-base_frame_orient_u1" => Some(&mut v.q2),
            "-base_frame_orient_u2" => Some(&mut v.q3),
            "-base_frame_orient_u3" => Some(&mut v.q4),
            _ => None,
        };
        if let Some(slot) = slot {
            let value = tokens
                .get(i + 1)
                .ok_or_else(|| format!("{key} has no value"))?;
            *slot = number(value, key)?;
            i += 2;
        } else {
            i += 1;
        }
    }
    Ok(v)
}

/// The placement of [`parse_base_frame`]'s numbers; an error for a non-unit quaternion.
pub(crate) fn parse(text: &str) -> Result<Isometry3<f64>, String> {
    let v = parse_base_frame(text)?;
    v.placement().ok_or_else(|| {
        format!(
            "q1..q4 = {} {} {} {} is not a unit quaternion",
            v.q1, v.q2, v.q3, v.q4
        )
    })
}

//! Fanuc: robot 2's base frame as a user frame of robot 1 (direct entry).
//!
//! Convention, checked against:
//! - X, Y, Z in mm; W, P, R in degrees, rotations about the **fixed** x, y, z axes of the
//!   reference frame, applied W first, then P, then R: `R = Rz(R)·Ry(P)·Rx(W)` (Roboception/Basler
//!   rc_visard manual, "FANUC XYZ-WPR format",
//!   <https://docs.baslerweb.com/stereovisard/rc_visard/en/pose_format_fanuc.html>; RoboDK's
//!   `robodk.robomath.Pose_2_Fanuc`, `RoboDK/RoboDK-API`, `Python/robodk/robomath.py`, the same
//!   decomposition as KUKA's with the angles listed in the opposite order). This agrees with the
//!   issue.
//! - A user frame's values are its pose in the robot's world frame (SETUP > Frames > User Frame >
//!   Direct Entry takes X, Y, Z, W, P, R). With robot 1's world at its base (the Fanuc default),
//!   the user frame at robot 2's base is `b1_from_b2`.
//! - At P = ±90° only R ∓ W is defined; the file has W = 0 ([`kinematics::cardan`]).

use nalgebra::Isometry3;

use super::{deg, listing, mm, parse_listing, FanucFrame, Header};

/// The file name.
pub const FILE: &str = "fanuc_user_frame.txt";

/// The file: opening comment (`!`, as in TP programs), then the six values.
pub(crate) fn render(v: &FanucFrame, header: &Header<'_>) -> String {
    let mut s = header.lines(
        "! ",
        &[
            "Convention: Fanuc user frame, X Y Z in mm, W P R in degrees about the FIXED x, y, z axes, applied W, then P,",
            "then R: R = Rz(R)*Ry(P)*Rx(W). Reference: robot 1's world frame (= its base).",
            "On robot 1: MENU > SETUP > Frames > [OTHER] User Frame > choose a free frame > DETAIL > [METHOD] Direct Entry,",
            "type the six values below; the user frame is then robot 2's base frame.",
        ],
    );
    s.push_str(&listing(&[
        ("X", mm(v.x_mm), "mm"),
        ("Y", mm(v.y_mm), "mm"),
        ("Z", mm(v.z_mm), "mm"),
        ("W", deg(v.w_deg), "deg"),
        ("P", deg(v.p_deg), "deg"),
        ("R", deg(v.r_deg), "deg"),
    ]));
    s
}

/// The six values of a listing written by this module.
pub fn parse_frame(text: &str) -> Result<FanucFrame, String> {
    parse_listing(text, "!", ["X", "Y", "Z", "W", "P", "R"]).map(FanucFrame::from_listed)
}

pub(crate) fn parse(text: &str) -> Result<Isometry3<f64>, String> {
    parse_frame(text).map(|v| v.placement())
}

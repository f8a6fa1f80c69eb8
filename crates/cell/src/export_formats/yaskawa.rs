//! Yaskawa Motoman: robot 2's base frame as a user frame of robot 1.
//!
//! Convention, checked against:
//! - X, Y, Z in mm; Rx, Ry, Rz in degrees, rotations about the **fixed** x, y, z axes applied Rx,
//!   then Ry, then Rz: `R = Rz(Rz)·Ry(Ry)·Rx(Rx)` (Roboception/Basler rc_visard manual, "Yaskawa Pose
//!   Format", <https://docs.baslerweb.com/stereovisard/rc_cube/en/pose_format_yaskawa>;
//!   RoboDK's `robodk.robomath.Pose_2_Motoman`, `RoboDK/RoboDK-API`, `Python/robodk/robomath.py`,
//!   which is `pose_2_xyzrpw`, the same fixed-axis decomposition as Fanuc's). This agrees with the
//!   issue.
//! - A user frame (USER COORDINATE) is given in the robot coordinates of its robot; with robot 1's
//!   robot coordinates at its base, the user frame at robot 2's base is `b1_from_b2`.
//! - At Ry = ±90° only Rz ∓ Rx is defined; the file has Rx = 0 ([`kinematics::cardan`]).

use nalgebra::Isometry3;

use super::{deg, listing, mm, parse_listing, Header, YaskawaFrame};

/// The file name.
pub const FILE: &str = "yaskawa_user_frame.txt";

/// The file: opening comment (`'`, as in INFORM jobs), then the six values.
pub(crate) fn render(v: &YaskawaFrame, header: &Header<'_>) -> String {
    let mut s = header.lines(
        "' ",
        &[
            "Convention: Yaskawa user frame, X Y Z in mm, Rx Ry Rz in degrees about the FIXED x, y, z axes, applied Rx,",
            "then Ry, then Rz: R = Rz(Rz)*Ry(Ry)*Rx(Rx). Reference: robot 1's robot coordinates (= its base).",
            "On robot 1's pendant: ROBOT > USER COORDINATE > choose a free user frame number, select the numeric",
            "display and type the six values below (editing values needs the management security mode).",
        ],
    );
    s.push_str(&listing(&[
        ("X", mm(v.x_mm), "mm"),
        ("Y", mm(v.y_mm), "mm"),
        ("Z", mm(v.z_mm), "mm"),
        ("Rx", deg(v.rx_deg), "deg"),
        ("Ry", deg(v.ry_deg), "deg"),
        ("Rz", deg(v.rz_deg), "deg"),
    ]));
    s
}

/// The six values of a listing written by this module.
pub fn parse_frame(text: &str) -> Result<YaskawaFrame, String> {
    parse_listing(text, "'", ["X", "Y", "Z", "Rx", "Ry", "Rz"]).map(YaskawaFrame::from_listed)
}

pub(crate) fn parse(text: &str) -> Result<Isometry3<f64>, String> {
    parse_frame(text).map(|v| v.placement())
}

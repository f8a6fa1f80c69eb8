//! KUKA: robot 2's root frame in a world that is robot 1's base, as a KRL `FRAME`.
//!
//! Convention, checked against:
//! - KRL `FRAME {X, Y, Z, A, B, C}`: X, Y, Z in mm; A, B, C in degrees, A about z, B about the new
//!   y', C about the new x'', i.e. `R = Rz(A)·Ry(B)·Rx(C)` (Roboception/Basler rc_visard manual,
//!   "KUKA XYZ-ABC format", <https://docs.baslerweb.com/stereovisard/rc_visard/en/pose_format_kuka.html>;
//!   RoboDK's `robodk.robomath.KUKA_2_Pose`/`Pose_2_KUKA`, `RoboDK/RoboDK-API`,
//!   `Python/robodk/robomath.py`: `transl(x,y,z)·rotz(A)·roty(B)·rotx(C)`). This agrees with the
//!   issue.
//! - `$ROBROOT` (in `$MACHINE.DAT`, or set by RoboTeam / WorkVisual) is the robot's root point in
//!   the world frame; `BASE_DATA[n]` (in `$CONFIG.DAT`) is a base frame in the world frame. With
//!   the world at robot 1's base (robot 1's `$ROBROOT` all zero), robot 2's `$ROBROOT` and a base of
//!   robot 1 at robot 2's base are the same six numbers, `b1_from_b2`.
//! - At B = ±90° only A ∓ C is defined; the file has C = 0 ([`kinematics::cardan`]).

use nalgebra::Isometry3;

use super::{deg, mm, number, Header, KukaFrame};

/// The file name.
pub const FILE: &str = "kuka_robroot.dat";

/// The KRL frame literal `{X …,Y …,Z …,A …,B …,C …}`.
fn frame_literal(v: &KukaFrame) -> String {
    format!(
        "{{X {},Y {},Z {},A {},B {},C {}}}",
        mm(v.x_mm),
        mm(v.y_mm),
        mm(v.z_mm),
        deg(v.a_deg),
        deg(v.b_deg),
        deg(v.c_deg)
    )
}

/// The file: opening comment (KRL comments start with `;`), then robot 2's `$ROBROOT` line.
pub(crate) fn render(v: &KukaFrame, header: &Header<'_>) -> String {
    let mut s = header.lines(
        "; ",
        &[
            "Convention: KUKA KRL FRAME, X Y Z in mm, A B C in degrees, R = Rz(A)*Ry(B)*Rx(C) (A about z, B about y', C about x'').",
            "World = robot 1's base: robot 1's $ROBROOT is {X 0,Y 0,Z 0,A 0,B 0,C 0}; the line below is robot 2's root in it.",
            "The same six numbers are robot 2's base seen from robot 1: enter them as a BASE_DATA[n] of robot 1",
            "($CONFIG.DAT, or smartHMI: Start-up > Calibrate > Base > Numeric input) to address robot 2's base.",
        ],
    );
    s.push_str(&format!("FRAME $ROBROOT={}\n", frame_literal(v)));
    s
}

/// The numbers of the first `FRAME $ROBROOT={…}` line (case-insensitive keys).
pub fn parse_frame(text: &str) -> Result<KukaFrame, String> {
    let line = text
        .lines()
        .map(str::trim)
        .find(|l| {
            l.to_ascii_uppercase()
                .replace(' ', "")
                .starts_with("FRAME$ROBROOT=")
        })
        .ok_or("no `FRAME $ROBROOT={...}` line")?;
    let inner = line
        .split_once('{')
        .and_then(|(_, rest)| rest.split_once('}'))
        .map(|(inner, _)| inner)
        .ok_or("the $ROBROOT line has no {...}")?;
    let mut values: [Option<f64>; 6] = [None; 6];
    for item in inner.split(',') {
        let mut parts = item.split_whitespace();
        let (Some(key), Some(value)) = (parts.next(), parts.next()) else {
            return Err(format!("`{item}` is not `KEY value`"));
        };
        let k = ["X", "Y", "Z", "A", "B", "C"]
            .iter()
            .position(|k| k.eq_ignore_ascii_case(key))
            .ok_or_else(|| format!("unknown FRAME component `{key}`"))?;
        values[k] = Some(number(value, key)?);
    }
    let mut out = [0.0; 6];
    for (k, v) in values.iter().enumerate() {
        out[k] =
            v.ok_or_else(|| format!("component {} missing", ["X", "Y", "Z", "A", "B", "C"][k]))?;
    }
    Ok(KukaFrame::from_listed(out))
}

pub(crate) fn parse(text: &str) -> Result<Isometry3<f64>, String> {
    parse_frame(text).map(|v| v.placement())
}

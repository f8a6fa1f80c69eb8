//! How each robot base is installed: [`Mount`] (`level_from_base`) and [`MountPair`].

use crate::error::CalibError;
use nalgebra::{Rotation3, Vector3};
use std::f64::consts::PI;
use std::fmt;

/// How a robot base is installed, relative to a level frame whose z axis points up (against gravity).
///
/// Serialises (serde) as `"floor"`, `"ceiling"`, `"wall"` or `{"tilt": {"rx": …, "ry": …}}` (rad).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mount {
    /// On the floor: base z up (`level_from_base = I`).
    Floor,
    /// Hanging from the ceiling: base z down (`level_from_base = Rx(180°)`).
    Ceiling,
    /// The paper's wall family: base z horizontal, roll about it unknown (two free angles).
    Wall,
    /// A known tilt: `level_from_base = Rx(rx)·Ry(ry)`, radians (a wall with known roll is
    /// `Tilt { rx: ±90°, ry }`, an inclined pedestal a small tilt). Both angles must be finite:
    /// [`Mount::validate`] (called by every fit that uses the mounts) refuses NaN or ±∞.
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

    /// Checks that a [`Mount::Tilt`]'s angles are finite (a NaN or infinite angle gives no
    /// rotation). Errors: [`CalibError::InvalidOption`] naming the angle.
    pub fn validate(&self) -> Result<(), CalibError> {
        if let Mount::Tilt { rx, ry } = *self {
            if !rx.is_finite() || !ry.is_finite() {
                return Err(CalibError::InvalidOption {
                    name: "mount".into(),
                    value: format!("Tilt {{ rx: {rx}, ry: {ry} }} (rad)"),
                    message: "tilt angles must be finite; give the mount's measured tilt".into(),
                });
            }
        }
        Ok(())
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

/// The installation of both robots. Serialises (serde) as `{"robot1": …, "robot2": …}`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
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
    /// Checks both mounts ([`Mount::validate`]).
    pub fn validate(&self) -> Result<(), CalibError> {
        self.robot1.validate()?;
        self.robot2.validate()
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
                    "expected floor-floor, floor-wall or floor-ceiling (or give each robot's mount)"
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

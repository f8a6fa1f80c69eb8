//! The cell's two robots: [`Robot`], the workspace's one robot type.

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::fmt;

/// One of the cell's two robots: the workspace's one robot type. Serialised as the integer 1 or 2;
/// displayed as "robot 1" / "robot 2".
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Robot {
    /// Robot 1 (its base frame is `b1`, the frame the fit maps into).
    One,
    /// Robot 2 (its base frame is `b2`).
    Two,
}

impl Robot {
    /// Both robots, robot 1 first.
    pub const BOTH: [Robot; 2] = [Robot::One, Robot::Two];

    /// The robot's number: 1 or 2.
    pub fn number(self) -> u8 {
        match self {
            Robot::One => 1,
            Robot::Two => 2,
        }
    }

    /// The other robot of the cell.
    pub fn other(self) -> Robot {
        match self {
            Robot::One => Robot::Two,
            Robot::Two => Robot::One,
        }
    }

    /// The robot with number 1 or 2; `None` for any other number.
    pub fn from_number(number: u8) -> Option<Robot> {
        match number {
            1 => Some(Robot::One),
            2 => Some(Robot::Two),
            _ => None,
        }
    }
}

impl fmt::Display for Robot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "robot {}", self.number())
    }
}

impl Serialize for Robot {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_u8(self.number())
    }
}

impl<'de> Deserialize<'de> for Robot {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let number = u8::deserialize(deserializer)?;
        Robot::from_number(number)
            .ok_or_else(|| serde::de::Error::custom(format!("robot must be 1 or 2, got {number}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn robot_serialises_as_its_number_and_displays_it() {
        assert_eq!(serde_json::to_string(&Robot::BOTH).unwrap(), "[1,2]");
        let back: Vec<Robot> = serde_json::from_str("[2,1]").unwrap();
        assert_eq!(back, vec![Robot::Two, Robot::One]);
        let e = serde_json::from_str::<Robot>("3").unwrap_err();
        assert!(e.to_string().contains("robot must be 1 or 2, got 3"), "{e}");
        assert_eq!(Robot::One.to_string(), "robot 1");
        assert_eq!(Robot::Two.number(), 2);
        assert_eq!(Robot::from_number(0), None);
    }
}

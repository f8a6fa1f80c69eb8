//! A coordinate axis of a frame: x, y or z.

use std::fmt;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    Z,
}

impl Axis {
    /// The three axes in order x, y, z.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The unit vector along the axis.
    pub fn unit(self) -> Vector3<f64> {
        let mut v = Vector3::zeros();
        v[self.index()] = 1.0;
        v
    }

    /// `"x"`, `"y"` or `"z"`.
    pub fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }

    /// 0, 1 or 2 (the component index).
    pub fn index(self) -> usize {
        match self {
            Axis::X => 0,
            Axis::Y => 1,
            Axis::Z => 2,
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[test]
    fn axis_deserializes_from_lowercase_names() {
        use serde::de::{value::StrDeserializer, IntoDeserializer};
        for a in Axis::ALL {
            let d: StrDeserializer<'_, serde::de::value::Error> = a.name().into_deserializer();
            assert_eq!(Axis::deserialize(d).unwrap(), a);
        }
        let d: StrDeserializer<'_, serde::de::value::Error> = "X".into_deserializer();
        assert!(
            Axis::deserialize(d).is_err(),
            "upper case is not an axis name"
        );
    }

    #[test]
    fn unit_name_and_index_agree() {
        assert_eq!(Axis::Y.unit(), Vector3::y());
        assert_eq!(Axis::Z.name(), "z");
        for (i, a) in Axis::ALL.into_iter().enumerate() {
            assert_eq!(a.index(), i);
            assert_eq!(a.unit()[i], 1.0);
            assert_eq!(a.to_string(), a.name());
        }
    }
}

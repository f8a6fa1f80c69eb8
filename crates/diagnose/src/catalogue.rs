//! The catalogue of candidate causes: every kinematic-error parameter of either robot that the
//! diagnosis may name, grouped in six kinds ([`EffectKind`]), and the way back from a report's
//! effects to [`KinematicErrors`].

use calib_core::Robot;
use handclasp_cell::Cell;
use kinematics::{Axis, ErrorParam, KinematicErrors};
use serde::Serialize;

use crate::report::EffectReport;

/// Kind of a candidate effect: joint offset, link length, tip offset, mount tilt, compliance,
/// joint scale. Serialised in snake case (`joint_offset`, …), as [`EffectKind::name`] says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum EffectKind {
    /// A joint's zero offset.
    JointOffset,
    /// A joint origin's translation along x, y or z (parent frame).
    LinkLength,
    /// The tip offset error, tool0 frame.
    TipOffset,
    /// A base tilt about its x or y axis.
    MountTilt,
    /// A joint's deflection under gravity.
    Compliance,
    /// A joint's gear-ratio error.
    JointScale,
}

impl EffectKind {
    /// Every kind, in report order.
    pub const ALL: [EffectKind; 6] = [
        EffectKind::JointOffset,
        EffectKind::LinkLength,
        EffectKind::TipOffset,
        EffectKind::MountTilt,
        EffectKind::Compliance,
        EffectKind::JointScale,
    ];

    /// The kind of a kinematic-error parameter; `None` for parameters outside the catalogue
    /// (origin rotations, mount translations).
    pub fn of(param: ErrorParam) -> Option<EffectKind> {
        match param {
            ErrorParam::JointOffset { .. } => Some(Self::JointOffset),
            ErrorParam::OriginXyz { .. } => Some(Self::LinkLength),
            ErrorParam::Tip { .. } => Some(Self::TipOffset),
            ErrorParam::MountRpy {
                axis: Axis::X | Axis::Y,
            } => Some(Self::MountTilt),
            ErrorParam::Compliance { .. } => Some(Self::Compliance),
            ErrorParam::JointScale { .. } => Some(Self::JointScale),
            _ => None,
        }
    }

    /// The kind's name in the report.
    pub fn name(self) -> &'static str {
        match self {
            Self::JointOffset => "joint_offset",
            Self::LinkLength => "link_length",
            Self::TipOffset => "tip_offset",
            Self::MountTilt => "mount_tilt",
            Self::Compliance => "compliance",
            Self::JointScale => "joint_scale",
        }
    }

    /// Output unit.
    pub fn unit(self) -> &'static str {
        match self {
            Self::JointOffset | Self::MountTilt => "deg",
            Self::LinkLength | Self::TipOffset => "mm",
            Self::JointScale => "ratio",
            Self::Compliance => "deg/(kN·m)",
        }
    }

    /// Factor from SI (rad, m, ratio, rad/(N·m)) to the output unit.
    pub fn to_output(self) -> f64 {
        match self {
            Self::JointOffset | Self::MountTilt => 180.0 / std::f64::consts::PI,
            Self::LinkLength | Self::TipOffset => 1000.0,
            Self::JointScale => 1.0,
            Self::Compliance => 180.0 / std::f64::consts::PI * 1000.0,
        }
    }
}

/// One candidate of the catalogue: a kinematic-error parameter of one robot. Its kind, joint
/// and axis follow from the parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    robot: Robot,
    param: ErrorParam,
    kind: EffectKind,
}

impl Candidate {
    /// The candidate for `param` of `robot`; `None` when the parameter is of no catalogue kind
    /// ([`EffectKind::of`]).
    pub fn new(robot: Robot, param: ErrorParam) -> Option<Self> {
        EffectKind::of(param).map(|kind| Self { robot, param, kind })
    }
    /// The robot.
    pub fn robot(&self) -> Robot {
        self.robot
    }
    /// The kinematic-error parameter (SI units).
    pub fn param(&self) -> ErrorParam {
        self.param
    }
    /// Kind.
    pub fn kind(&self) -> EffectKind {
        self.kind
    }
    /// 0-based joint, where it applies.
    pub fn joint(&self) -> Option<usize> {
        self.param.joint()
    }
    /// Axis, where it applies.
    pub fn axis(&self) -> Option<Axis> {
        self.param.axis()
    }

    /// Readable name, e.g. `robot 2 joint_offset joint 3` or `robot 1 link_length joint 2 x`.
    pub fn label(&self) -> String {
        let mut s = format!("robot {} {}", self.robot.number(), self.kind.name());
        if let Some(j) = self.joint() {
            s += &format!(" joint {}", j + 1);
        }
        if let Some(a) = self.axis() {
            s += &format!(" {}", a.name());
        }
        s
    }
}

/// The full catalogue for two robots with `dof1`, `dof2` joints, per robot in the order joint
/// offsets, link lengths (x, y, z per joint), tip offset (x, y, z), mount tilts (x, y),
/// compliances, joint scales.
pub fn catalogue(dof1: usize, dof2: usize) -> Vec<Candidate> {
    let mut params = Vec::new();
    for (robot, dof) in [(Robot::One, dof1), (Robot::Two, dof2)] {
        let xyz = [Axis::X, Axis::Y, Axis::Z];
        params.extend((0..dof).map(|joint| (robot, ErrorParam::JointOffset { joint })));
        params.extend(
            (0..dof)
                .flat_map(|joint| xyz.map(|axis| (robot, ErrorParam::OriginXyz { joint, axis }))),
        );
        params.extend(xyz.map(|axis| (robot, ErrorParam::Tip { axis })));
        params.extend([Axis::X, Axis::Y].map(|axis| (robot, ErrorParam::MountRpy { axis })));
        params.extend((0..dof).map(|joint| (robot, ErrorParam::Compliance { joint })));
        params.extend((0..dof).map(|joint| (robot, ErrorParam::JointScale { joint })));
    }
    params
        .into_iter()
        .filter_map(|(robot, param)| Candidate::new(robot, param))
        .collect()
}

/// The identified errors of both robots (SI) from a report's effects (robot 1's, robot 2's).
/// Effects that match no candidate of the cell's catalogue are skipped.
pub fn effects_to_errors(
    cell: &Cell,
    effects: &[EffectReport],
) -> (KinematicErrors, KinematicErrors) {
    let mut e1 = KinematicErrors::zero_for(&cell.robot1.model);
    let mut e2 = KinematicErrors::zero_for(&cell.robot2.model);
    let cands = catalogue(
        cell.robot1.model.chain_joints().len(),
        cell.robot2.model.chain_joints().len(),
    );
    for eff in effects {
        let hit = cands.iter().find(|c| {
            c.kind() == eff.kind
                && c.robot() == eff.robot
                && c.joint().map(|j| j + 1) == eff.joint
                && c.axis().map(Axis::name) == eff.axis
        });
        if let Some(c) = hit {
            let errors = match c.robot() {
                Robot::One => &mut e1,
                Robot::Two => &mut e2,
            };
            errors.set(c.param(), eff.value / c.kind().to_output());
        }
    }
    (e1, e2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_covers_every_kind_once_per_member() {
        let c = catalogue(7, 6);
        // Per robot: offsets + 3 lengths per joint + 3 tip + 2 tilts + compliance + scale.
        assert_eq!(c.len(), (7 * 6 + 5) + (6 * 6 + 5));
        let labels: std::collections::HashSet<String> = c.iter().map(Candidate::label).collect();
        assert_eq!(labels.len(), c.len());
        for kind in EffectKind::ALL {
            assert!(c.iter().any(|m| m.kind() == kind), "{kind:?} missing");
        }
    }

    /// Labels name the robot as 1/2, joints 1-based and axes by letter (the text report and
    /// `confounded_with` carry them).
    #[test]
    fn labels_read_as_before() {
        let c = Candidate::new(Robot::Two, ErrorParam::JointOffset { joint: 2 }).unwrap();
        assert_eq!(c.label(), "robot 2 joint_offset joint 3");
        let c = Candidate::new(
            Robot::One,
            ErrorParam::OriginXyz {
                joint: 1,
                axis: Axis::X,
            },
        )
        .unwrap();
        assert_eq!(c.label(), "robot 1 link_length joint 2 x");
        let c = Candidate::new(Robot::One, ErrorParam::MountRpy { axis: Axis::Y }).unwrap();
        assert_eq!(c.label(), "robot 1 mount_tilt y");
        assert!(Candidate::new(Robot::One, ErrorParam::MountRpy { axis: Axis::Z }).is_none());
        assert!(Candidate::new(Robot::One, ErrorParam::MountXyz { axis: Axis::X }).is_none());
    }
}

//! Typed errors of the kinematics crate: loading a model ([`ModelError`]) and evaluating it
//! ([`KinematicsError`]). Every message says what is wrong and how to fix it.

use std::path::PathBuf;

/// Failure to build a [`crate::RobotModel`] from a URDF.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The URDF file could not be read.
    #[error("cannot read URDF file {path}: {source}; check the path (relative paths are from the current directory)")]
    Io {
        /// The file that was opened.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The URDF file is over the input limit, binary or not UTF-8 ([`crate::input`]).
    #[error(transparent)]
    Input(#[from] crate::input::InputError),
    /// The text is not a URDF the parser understands.
    #[error("{source_name}: not a valid URDF: {message}; fix the XML (every <joint> needs <parent>, <child> and, for revolute joints, <limit>)")]
    Parse {
        /// File path or `"<string>"`.
        source_name: String,
        /// The parser's message.
        message: String,
    },
    /// The requested tool link (or a link a joint refers to) does not exist.
    #[error("{source_name}: link `{link}` not found; known links: {known}; name an existing link")]
    MissingLink {
        /// File path or `"<string>"`.
        source_name: String,
        /// The missing link.
        link: String,
        /// Comma-separated list of the links that exist.
        known: String,
    },
    /// A link is the child of more than one joint, or the chain loops.
    #[error("{source_name}: link `{link}` is the child of several joints or lies on a loop; a URDF must be a tree")]
    NotATree {
        /// File path or `"<string>"`.
        source_name: String,
        /// The offending link.
        link: String,
    },
    /// A xacro file (by its `.xacro` extension, or `<xacro:…>` elements / `${…}` substitutions in its text) was given.
    #[error("{source_name}: this is a xacro file, not a URDF; expand it first: `xacro {source_name} > robot.urdf` (ROS 2: `ros2 run xacro xacro …`, ROS 1: `rosrun xacro xacro …`) and load robot.urdf")]
    Xacro {
        /// File path or `"<string>"`.
        source_name: String,
    },
    /// A `<mimic>` joint on the chain follows a joint that is not on the chain.
    #[error("{source_name}: joint `{joint}` on the chain to the tool link mimics joint `{mimicked}` (<mimic>), which is not a moving joint of that chain (a coupled joint must follow joints of its own chain); choose a tool link whose chain holds both joints, or one before `{joint}`")]
    MimicJoint {
        /// File path or `"<string>"`.
        source_name: String,
        /// The mimic joint.
        joint: String,
        /// The joint it follows.
        mimicked: String,
    },
    /// A declared coupling ([`crate::RobotModel::with_couplings`]) cannot be applied.
    #[error("{source_name}: the coupling of joint `{joint}`: {problem}")]
    BadCoupling {
        /// File path or `"<string>"` of the URDF.
        source_name: String,
        /// The coupled joint.
        joint: String,
        /// What is wrong and how to fix it.
        problem: String,
    },
    /// The joint origins add up to an implausible length: the file is probably in millimetres.
    #[error("{source_name}: the joint origins of the chain add up to {length:.1} m (joint `{joint}` alone {origin:.1} m); URDF lengths are metres and this file looks like it is written in millimetres: divide every <origin xyz> (and <inertial> origin) by 1000")]
    LooksLikeMillimetres {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint with the longest origin.
        joint: String,
        /// Its origin's length as written, "m".
        origin: f64,
        /// Sum of the chain's origin lengths as written, "m".
        length: f64,
    },
    /// A joint type other than revolute, continuous, prismatic or fixed lies on the chain.
    #[error("{source_name}: joint `{joint}` is of type {kind}, which is unsupported; only revolute, continuous, prismatic and fixed joints are")]
    UnsupportedJoint {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// Its URDF type.
        kind: String,
    },
    /// A moving joint has a zero or non-finite axis.
    #[error("{source_name}: joint `{joint}` has axis {axis:?}, which is zero or not finite; give a non-zero <axis xyz=\"...\"/>")]
    ZeroAxis {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// The axis as written.
        axis: [f64; 3],
    },
    /// Joint limits are not finite, lower > upper, or (revolute) lower == upper.
    #[error("{source_name}: joint `{joint}` has limits lower={lower} rad, upper={upper} rad; a revolute joint needs <limit lower=\"..\" upper=\"..\"/> with finite lower < upper in radians")]
    BadLimits {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// Lower limit, rad.
        lower: f64,
        /// Upper limit, rad.
        upper: f64,
    },
    /// A prismatic joint's limits are not finite or lower ≥ upper.
    #[error("{source_name}: joint `{joint}` has limits lower={lower} m, upper={upper} m; a prismatic joint needs <limit lower=\"..\" upper=\"..\"/> with finite lower < upper in metres")]
    BadLinearLimits {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// Lower limit, m.
        lower: f64,
        /// Upper limit, m.
        upper: f64,
    },
    /// Prismatic limits beyond [`crate::MAX_PRISMATIC_TRAVEL_M`]: almost surely written in
    /// millimetres.
    #[error("{source_name}: joint `{joint}` is prismatic with limits lower={lower}, upper={upper}, which look like millimetres; URDF limits of a prismatic joint are metres: divide them by 1000")]
    LimitsLookLikeMillimetres {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// Lower limit as written.
        lower: f64,
        /// Upper limit as written.
        upper: f64,
    },
    /// Revolute limits beyond ±2 turns: almost surely written in degrees.
    #[error("{source_name}: joint `{joint}` has limits lower={lower}, upper={upper}, which look like degrees; URDF limits are radians: write them as degrees·π/180")]
    LimitsLookLikeDegrees {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
        /// Lower limit as written.
        lower: f64,
        /// Upper limit as written.
        upper: f64,
    },
    /// A non-finite number in an origin.
    #[error("{source_name}: joint `{joint}` has a non-finite <origin>; fix its xyz/rpy")]
    BadOrigin {
        /// File path or `"<string>"`.
        source_name: String,
        /// The joint.
        joint: String,
    },
    /// The chain from the root to the tool link has no moving joint.
    #[error("{source_name}: no revolute, continuous or prismatic joint between the root and `{tool_link}`; choose a tool link at the end of the arm")]
    NoActuatedJoints {
        /// File path or `"<string>"`.
        source_name: String,
        /// The requested tool link.
        tool_link: String,
    },
}

/// Failure to evaluate a model at given inputs (bad joint vector, bad target, ...).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum KinematicsError {
    /// Joint vector of the wrong length.
    #[error("joint vector has {got} values but {robot} has {expected} joints; give one angle per joint, in chain order")]
    WrongLength {
        /// Robot name.
        robot: String,
        /// Number of actuated joints.
        expected: usize,
        /// Number of values given.
        got: usize,
    },
    /// Joint vector of the wrong length for a chain with coupled joints.
    #[error("joint vector has {got} values but {robot} has {expected} independent joints (the coupled joints {coupled} follow them); give one value per independent joint, in chain order")]
    WrongLengthCoupled {
        /// Robot name.
        robot: String,
        /// Number of independent joints.
        expected: usize,
        /// Number of values given.
        got: usize,
        /// The coupled joints, comma separated.
        coupled: String,
    },
    /// A joint value is NaN or infinite.
    #[error("joint {index} ({joint}) is {value}, not a finite number; give finite angles")]
    NotFinite {
        /// 1-based joint number.
        index: usize,
        /// Joint name.
        joint: String,
        /// The value.
        value: f64,
    },
    /// A joint value is plainly in degrees where radians are expected.
    #[error("joint {index} ({joint}) is {value} rad, which looks like degrees ({value} deg is inside the limits {lower_deg:.1}..{upper_deg:.1} deg); convert degrees to radians (x·π/180)")]
    LooksLikeDegrees {
        /// 1-based joint number.
        index: usize,
        /// Joint name.
        joint: String,
        /// The value given, rad.
        value: f64,
        /// Lower limit, deg.
        lower_deg: f64,
        /// Upper limit, deg.
        upper_deg: f64,
    },
    /// A joint value is outside the joint limits.
    #[error("joint {index} ({joint}) is {value_deg:.3} deg, outside its limits {lower_deg:.3}..{upper_deg:.3} deg; move it inside the range")]
    OutOfLimits {
        /// 1-based joint number.
        index: usize,
        /// Joint name.
        joint: String,
        /// The value, deg.
        value_deg: f64,
        /// Lower limit, deg.
        lower_deg: f64,
        /// Upper limit, deg.
        upper_deg: f64,
    },
    /// A prismatic joint's value is plainly in millimetres where metres are expected.
    #[error("joint {index} ({joint}) is {value} m, which looks like millimetres ({value} mm is inside the limits {lower_mm:.1}..{upper_mm:.1} mm); a prismatic joint's value is in metres: divide by 1000")]
    LooksLikeMillimetres {
        /// 1-based joint number.
        index: usize,
        /// Joint name.
        joint: String,
        /// The value given, m.
        value: f64,
        /// Lower limit, mm.
        lower_mm: f64,
        /// Upper limit, mm.
        upper_mm: f64,
    },
    /// A prismatic joint's value is outside its limits.
    #[error("joint {index} ({joint}) is {value_mm:.3} mm, outside its limits {lower_mm:.3}..{upper_mm:.3} mm; move it inside the range")]
    OutOfLinearLimits {
        /// 1-based joint number.
        index: usize,
        /// Joint name.
        joint: String,
        /// The value, mm.
        value_mm: f64,
        /// Lower limit, mm.
        lower_mm: f64,
        /// Upper limit, mm.
        upper_mm: f64,
    },
    /// Another input (target, tip offset, option) is invalid.
    #[error("invalid input: {0}")]
    InvalidInput(String),
}

/// Failure to write a corrected URDF ([`crate::patch_urdf_text`], [`crate::verify_patched_urdf`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum UrdfPatchError {
    /// The kinematic errors do not fit the model (wrong length, not finite).
    #[error("{0}")]
    Errors(KinematicsError),
    /// Errors that a URDF cannot express, each with where it belongs instead.
    #[error("robot `{robot}`: these errors cannot be written into a URDF: {what}")]
    NotExpressible {
        /// The robot (URDF) name.
        robot: String,
        /// Each non-zero parameter kind, its joints and where it belongs instead.
        what: String,
    },
    /// The text is not well-formed XML, or not a `<robot>`.
    #[error("the URDF text is not usable XML: {0}; fix the file (it must load as a URDF)")]
    Xml(String),
    /// No `<joint>` of the model's joint name is a direct child of `<robot>`.
    #[error("no <joint name=\"{joint}\"> under <robot> (joints inside <transmission> and comments do not count); patch the text the model was loaded from")]
    JointNotFound {
        /// The joint name.
        joint: String,
    },
    /// Two `<joint>` elements of the same name under `<robot>`.
    #[error("two <joint name=\"{joint}\"> elements under <robot> (lines {} and {}); a URDF's joint names are unique: remove one", lines.0, lines.1)]
    DuplicateJoint {
        /// The joint name.
        joint: String,
        /// 1-based lines of the first two.
        lines: (u32, u32),
    },
    /// A joint's `<origin>` (or `<calibration>`) cannot be read.
    #[error("joint `{joint}`, line {line}: {message}")]
    BadOrigin {
        /// The joint name.
        joint: String,
        /// 1-based line.
        line: u32,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// The patched text does not load as a URDF.
    #[error("the patched URDF does not load: {0}")]
    Reload(Box<ModelError>),
    /// The patched URDF does not reproduce the error model.
    #[error("the patched URDF does not reproduce the kinematic errors: {message}")]
    Verification {
        /// Where and by how much it deviates.
        message: String,
    },
}

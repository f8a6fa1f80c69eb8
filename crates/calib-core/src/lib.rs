#![doc = include_str!("../README.md")]

mod error;
mod fit_report;
pub mod identify;
mod lm;
mod masking;
mod metrics;
mod mount_check;
pub mod paper;
mod points;
mod pose;
mod registration;
mod robot;
mod robust;
pub mod selection;
mod soft;
pub mod stats;
mod stop;
pub mod whole_cell;

/// The nalgebra this crate's API is written in (`Isometry3`, `Point3`, `Matrix6`, …), the same
/// one `kinematics` re-exports. Use `calib_core::nalgebra::…` (or pin the same nalgebra version,
/// see the README) so your types are the ones these functions take.
pub use nalgebra;

pub use error::CalibError;
pub use fit_report::{
    FitReport, MountCheckReport, OutliersReport, SoftMountReport, StreamedFitReport,
    UncertaintyReport,
};
pub use kinematics::{
    rotation_from_zyz, wrap_angle, zyz_canonical, zyz_canonical_within, zyz_from_rotation,
    zyz_nearest, ZYZ_CANONICAL_TILT_RAD,
};
pub use lm::{LmOptionError, LmOptions, SingularStep};
pub use masking::{
    masked_blunders, MaskedBlunders, CONCENTRATION_STEPS, ROBUST_CANDIDATES, ROBUST_SEED,
};
pub use metrics::{
    e_rot, e_rot_fast, e_rot_raw, e_rot_zyz, e_tran, geodesic_angle, ErotTruth, TrialErrors,
    ZYZ_SINGULAR_BAND_RAD,
};
pub use mount_check::{mount_check, MountCheck, MOUNT_CHECK_ALPHA};
pub use points::{
    csv_delimiter, csv_reader, parse_points_csv, read_points_csv, strip_bom, PointPairs,
    DUPLICATE_DISTANCE_M, METRES_LIMIT_MM, SPREAD_RATIO_LIMIT,
};
pub use pose::{PoseForms, PoseMmDeg};
pub use registration::{
    affine_lsq_fast, constrained_fast, constrained_lsq, fit, fit_fast, fit_unconstrained,
    generic_4point, generic_fast, nearest_rotation, paper_constrained, paper_fast,
    project_rotation_family, rigid_fit_fast, rigid_lsq, rotation_maximizing_trace,
    spread_singular_values, wall_family_angles, wall_rotation, ConstrainedOptions, Fit, Method,
    Mount, MountPair, Uncertainty, COLLINEAR_REL, COPLANAR_REL,
};
pub use robot::Robot;
pub use robust::{
    explain_misfit, leave_one_out, leave_one_out_four_point, leave_one_out_linearised,
    leave_one_out_of_fit, median_residual_m, misfit_threshold_m, MisfitCause, OutlierReport,
    DEFAULT_EXPECTED_NOISE_M, EXACT_LOO_MAX_POINTS, MISFIT_FALSE_ALARM, OUTLIER_FACTOR,
    OUTLIER_MIN_M,
};
pub use soft::{constrained_soft, SoftFit};
pub use stop::StopReason;

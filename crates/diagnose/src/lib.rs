#![doc = include_str!("../README.md")]
//!
//! # The five steps of [`diagnose_session`]
//! 1. **Baseline** ([`engine`]): fit `b1_from_b2` with the nominal models; compare the residual
//!    RMS with what the cell's stated noise predicts at these very joint configurations
//!    ([`noise`], a seeded Monte Carlo), a χ² test, and the residual correlations with joints,
//!    position and reach ([`residuals`]).
//! 2. **Catalogue and identifiability** ([`mod@catalogue`], [`session_model`]): every candidate
//!    error parameter of both robots, with rank and conditioning per (robot, kind) family.
//! 3. **Selection**: forward selection by `calib_core::identify::forward_select`; mount tilts
//!    are named from the placement instead ([`mount_tilt`]), since in handclasp residuals they
//!    only turn the fit.
//! 4. **Gain**: residual and held-out RMS before and after, predicted and (given a truth)
//!    measured accuracy of `b1_from_b2`, a re-simulation with the extended model ([`report`]
//!    renders it all).
//! 5. **Export** ([`export`]): corrected URDFs and a cell with the calibrated `b1_from_b2`.
//!
//! Sessions with contact, tracker or plane rows take the whole-cell path instead:
//! [`diagnose_cell_session`] ([`cell_diagnosis`], [`cell_report`]), exported by
//! [`export_cell_diagnosis`].
//!
//! Inside, SI units (m, rad); the report speaks mm and degrees, and its field names carry the
//! unit.

use std::path::PathBuf;

pub mod catalogue;
pub mod cell_diagnosis;
pub mod cell_report;
pub mod do_no_harm;
pub mod engine;
pub mod export;
pub mod input;
pub mod mount_tilt;
pub mod noise;
pub mod report;
pub mod residuals;
pub mod session_model;

pub use catalogue::{catalogue, effects_to_errors, Candidate, EffectKind};
pub use cell_diagnosis::{
    candidate_families, diagnose_cell_session, diagnosis_problem, CellDiagnoseOptions, Family,
    FamilyKind, FoldDesign,
};
pub use cell_report::{render_cell_text, CellDiagnoseReport, FittedModel, RejectedFamilyReport};
pub use engine::{
    diagnose_screened_session_with_progress, diagnose_session, diagnose_session_with_progress,
    screen_session, DiagnoseOptions, ScreenedSession,
};
pub use export::{
    export_cell_diagnosis, export_cell_diagnosis_with, export_corrected,
    CELL_DIAGNOSIS_EXPORT_NAMES, CORRECTED_EXPORT_NAMES,
};
pub use input::{check_session, load_session, FK_TOLERANCE_M};
pub use mount_tilt::{
    mount_tilt_test, placement, MountTiltFit, Placement, TiltStop, ALPHA_TILT, PLACEMENT_SD_XYZ_M,
};
pub use report::{
    render_text, CorrelationReport, DetectableReport, DiagnoseReport, EffectReport, FamilyReport,
    MountTiltTest, PlacementReport, PoseReport, RejectedPointReport,
};
pub use session_model::SessionModel;

/// Errors of the diagnosis: bad files or inputs. Each names the file, row or field and the fix.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DiagnoseError {
    /// A file could not be read or written.
    #[error("{path}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The session does not fit the cell (joint counts, units, tips vs FK, too few points).
    #[error("session {path}: {message}")]
    Session {
        /// The session file (or `<session>` for a session in memory).
        path: PathBuf,
        /// What is wrong and the fix.
        message: String,
    },
    /// The session file could not be read; `hint` names the unit mistake that explains it.
    #[error("{hint}")]
    SessionUnits {
        /// The likely unit mistake and its fix.
        hint: String,
        /// The session reader's error.
        #[source]
        source: handclasp_cell::FormatError,
    },
    /// The cell or session file could not be read ([`handclasp_cell::FormatError`]).
    #[error(transparent)]
    Format(#[from] handclasp_cell::FormatError),
    /// A robot model rejected a session's joint vector.
    #[error("robot {robot}, point {point}")]
    Model {
        /// Robot, 1 or 2.
        robot: u8,
        /// 1-based point of the session.
        point: usize,
        /// The kinematics error.
        #[source]
        source: kinematics::KinematicsError,
    },
    /// The export folder could not be created.
    #[error("cannot create the export folder {path}")]
    ExportFolder {
        /// The folder.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// An exported file, read back from its temporary file, does not load.
    #[error("{path}: {message}")]
    Export {
        /// The URDF (source or written).
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The effects could not be serialised.
    #[error("{path}")]
    Json {
        /// The file being written.
        path: PathBuf,
        /// serde_json's error.
        #[source]
        source: serde_json::Error,
    },
    /// The identification failed on the input.
    #[error("identification")]
    Identify(#[from] calib_core::identify::IdentifyError),
}

impl DiagnoseError {
    /// Shorthand for [`DiagnoseError::Io`].
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

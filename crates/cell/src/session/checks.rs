//! The input checks every command runs on a session before it uses it (`import` before writing,
//! `calibrate --cell`, `diagnose` and `plan`), so that a file one command refuses is refused by
//! all, with the same words: no rows, radians under `*_deg` columns, metres under `*_mm`
//! columns, and duplicate coincident handclasps (calib-core's rule,
//! [`calib_core::PointPairs::check_duplicates`]).
//!
//! These are checks of the input alone; whether the fit agrees with the data is a separate
//! check after the fit. The tips against FK of the joints (a wrong tip, cell or unit) are checked
//! row by row when the session is read ([`super::TIP_CONSISTENCY_MM`]).

use super::Session;

/// Every joint angle of the coincident rows within ±this (degrees) reads as radians written
/// under `*_deg` columns: an angle in radians never exceeds π, and a real session moves some joint
/// by more than 3.1°.
pub const RADIANS_LIMIT_DEG: f64 = std::f64::consts::PI + 1e-9;

/// Every tip coordinate of the coincident rows within ±this (mm) reads as metres written under
/// `*_mm` columns: no robot's reach is 10 mm.
pub const METRES_LIMIT_MM: f64 = 10.0;

/// A session that no command should use, and the fix. [`check_session_inputs`] gives it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SessionCheckError {
    /// The file has a header and no data row.
    #[error(
        "the session has a header but no data rows: there is nothing to calibrate; record the \
         handclasp points (one row per point) or give the session file that holds them"
    )]
    NoRows,
    /// Every joint angle is within ±[`RADIANS_LIMIT_DEG`].
    #[error(
        "every joint angle is within ±{max_deg:.3} degrees — these look like radians written as \
         degrees (the columns are *_deg): convert them to degrees (× 180/π), or set the joint unit \
         to rad in the import map"
    )]
    RadiansAsDegrees {
        /// The largest |angle| of the coincident rows, as read (degrees).
        max_deg: f64,
    },
    /// Every tip coordinate is within ±[`METRES_LIMIT_MM`].
    #[error(
        "every tip coordinate is within ±{max_mm:.4} mm — these look like metres written as \
         millimetres (the columns are *_mm): convert them to millimetres (× 1000)"
    )]
    MetresAsMillimetres {
        /// The largest |tip coordinate| of the coincident rows, as read (mm).
        max_mm: f64,
    },
    /// Two coincident handclasps of one robot closer than calib-core's
    /// [`calib_core::DUPLICATE_DISTANCE_M`] (a row recorded twice).
    #[error(
        "data rows {row_a} and {row_b} (`point` {point_a} and {point_b}): duplicate handclasp point (robot {robot}'s tips are \
         {distance_mm:.4} mm apart, closer than {limit_mm} mm); every command refuses it, as a \
         repeated row would count twice and shrink the stated uncertainty: delete one of the two \
         rows, or record a new point at least 100 mm away"
    )]
    Duplicate {
        /// The first row's 1-based index among the coincident rows (file order).
        row_a: usize,
        /// The second row's index.
        row_b: usize,
        /// The first row's `point` number.
        point_a: usize,
        /// The second row's `point` number.
        point_b: usize,
        /// The robot whose tips coincide, 1 or 2.
        robot: u8,
        /// Their distance, mm.
        distance_mm: f64,
        /// The duplicate distance, mm.
        limit_mm: f64,
    },
}

/// The input checks shared by every command (see the module doc), in this order: no rows,
/// radians, metres, duplicates. Rows of other kinds than coincident handclasps count as rows; the
/// unit and duplicate checks read the coincident rows (`Session::points`) and pass when there are
/// none. O(n) expected time (the duplicate search is a grid).
///
/// # Errors
/// The first [`SessionCheckError`] found.
pub fn check_session_inputs(session: &Session) -> Result<(), SessionCheckError> {
    if session.is_empty() {
        return Err(SessionCheckError::NoRows);
    }
    let points = &session.points;
    if points.is_empty() {
        return Ok(());
    }
    let max_deg = points
        .iter()
        .flat_map(|p| p.q1.iter().chain(&p.q2))
        .fold(0.0f64, |a, v| a.max(v.abs()))
        .to_degrees();
    if max_deg <= RADIANS_LIMIT_DEG {
        return Err(SessionCheckError::RadiansAsDegrees { max_deg });
    }
    let max_mm = points
        .iter()
        .flat_map(|p| [p.p_b1, p.p_b2])
        .fold(0.0f64, |a, p| a.max(p.coords.amax()))
        * 1e3;
    if max_mm < METRES_LIMIT_MM {
        return Err(SessionCheckError::MetresAsMillimetres { max_mm });
    }
    let (p_b1, p_b2) = session.tips();
    let pairs = calib_core::PointPairs {
        p_b1,
        p_b2,
        rows: (1..=points.len()).collect(),
    };
    if let Err(calib_core::CalibError::Duplicate {
        row_a,
        row_b,
        robot,
        distance_mm,
    }) = pairs.check_duplicates()
    {
        // Rows numbered 1..=n above, in `points` order.
        return Err(SessionCheckError::Duplicate {
            row_a,
            row_b,
            point_a: points[row_a - 1].point,
            point_b: points[row_b - 1].point,
            robot,
            distance_mm,
            limit_mm: calib_core::DUPLICATE_DISTANCE_M * 1e3,
        });
    }
    Ok(())
}

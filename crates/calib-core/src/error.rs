//! The typed error of calib-core.

use std::path::PathBuf;

/// Everything that can be wrong with the input of a calibration. Each message names the place
/// (file, line, column or point rows), what is wrong, and how to fix it.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CalibError {
    /// The file could not be opened or read (the operating system's error is the source).
    #[error("{path}: cannot read the file")]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is over the input limit, binary or not UTF-8 (`kinematics::input`).
    #[error(transparent)]
    Input(#[from] kinematics::input::InputError),
    /// The CSV is malformed at a line (wrong number of fields, bad quoting, …).
    #[error("{path}, line {line}: malformed CSV: {message}. Fix: every line needs the same columns as the header")]
    Csv {
        /// The file.
        path: PathBuf,
        /// 1-based line in the file (the header is line 1).
        line: usize,
        /// The CSV reader's message.
        message: String,
    },
    /// A required column is absent from the header.
    #[error("{path}: missing column `{column}` (header has: {found}). Fix: the header must contain r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm (any order; other columns are ignored)")]
    MissingColumn {
        /// The file.
        path: PathBuf,
        /// The missing column.
        column: String,
        /// The columns that were found, comma-separated.
        found: String,
    },
    /// A cell is empty, not a number, or not finite.
    #[error("{path}, line {line}, column `{column}`: {problem} (`{value}`). Fix: {fix}")]
    BadCell {
        /// The file.
        path: PathBuf,
        /// 1-based line in the file.
        line: usize,
        /// The column name.
        column: String,
        /// The cell's text.
        value: String,
        /// What is wrong.
        problem: &'static str,
        /// How to fix it.
        fix: &'static str,
    },
    /// The points of one robot are all within a few units of the origin: metres given where mm were expected.
    #[error("{path}: robot {robot}'s coordinates are all below {limit_mm} in magnitude: they look like metres, but the file must be in millimetres. Fix: multiply robot {robot}'s x, y, z by 1000")]
    LooksLikeMetres {
        /// The file.
        path: PathBuf,
        /// 1 or 2.
        robot: u8,
        /// The magnitude limit used, mm.
        limit_mm: f64,
    },
    /// The two robots' point clouds differ in size by a large factor: a rigid motion cannot relate them.
    #[error("{source_name}: robot 1's points spread {spread1_mm:.3} mm (RMS radius) but robot 2's spread {spread2_mm:.3} mm, a factor {ratio:.1}; a rigid motion preserves distances. Fix: give both robots in millimetres (one of them looks like metres or inches)")]
    SpreadMismatch {
        /// The file or data set.
        source_name: String,
        /// RMS distance of robot 1's points from their centroid, mm.
        spread1_mm: f64,
        /// RMS distance of robot 2's points from their centroid, mm.
        spread2_mm: f64,
        /// The larger over the smaller.
        ratio: f64,
    },
    /// Two handclasp points coincide.
    #[error("rows {row_a} and {row_b}: duplicate handclasp point (robot {robot}'s points are {distance_mm:.4} mm apart). Fix: delete one of the two rows, or record a new point at least 100 mm away")]
    Duplicate {
        /// Source row of the first point.
        row_a: usize,
        /// Source row of the second point.
        row_b: usize,
        /// The robot whose points coincide (1 or 2).
        robot: u8,
        /// Their distance, mm.
        distance_mm: f64,
    },
    /// Fewer points than the method needs.
    #[error("method `{method}` needs at least {needed} handclasp points, got {got}. Fix: record more points (spread ≥ 1 m apart, not on one line or plane)")]
    TooFewPoints {
        /// The method's name.
        method: String,
        /// Points needed.
        needed: usize,
        /// Points given.
        got: usize,
    },
    /// `p_b1` and `p_b2` (or weights) have different lengths.
    #[error("{what}: lengths differ ({a} vs {b}). Fix: give one entry per handclasp point")]
    LengthMismatch {
        /// Which arrays.
        what: String,
        /// First length.
        a: usize,
        /// Second length.
        b: usize,
    },
    /// A coordinate or weight is NaN or infinite.
    #[error("row {row}: {what} is not finite. Fix: remove or re-record the point")]
    NonFinite {
        /// Source row.
        row: usize,
        /// What is not finite.
        what: String,
    },
    /// The points lie (nearly) on one line: the rotation about that line is undetermined.
    #[error("points in rows {rows:?} are collinear (singular values of the centred robot-{robot} points, mm: {singular_values_mm:?}). Fix: add a point well off the line through them")]
    Collinear {
        /// Source rows of the points.
        rows: Vec<usize>,
        /// Which robot's points were tested (1 or 2).
        robot: u8,
        /// Singular values of the centred point matrix, mm, descending.
        singular_values_mm: [f64; 3],
    },
    /// The points lie (nearly) in one plane: the 4-point affine solve is singular.
    #[error("points in rows {rows:?} are coplanar (singular values of the centred robot-{robot} points, mm: {singular_values_mm:?}); the 4-point method needs a tetrahedron. Fix: move one point well off the plane of the others, or use method `lsq`/`constrained`, which accept coplanar points")]
    Coplanar {
        /// Source rows of the points.
        rows: Vec<usize>,
        /// Which robot's points were tested (1 or 2).
        robot: u8,
        /// Singular values of the centred point matrix, mm, descending.
        singular_values_mm: [f64; 3],
    },
    /// The mount pair is not supported by the requested method.
    #[error("mounts {mounts}: {message}")]
    UnsupportedMounts {
        /// The mount pair, as text.
        mounts: String,
        /// Why, and what to do instead.
        message: String,
    },
    /// An option is out of range.
    #[error("invalid option `{name}` = {value}: {message}")]
    InvalidOption {
        /// The option.
        name: String,
        /// Its value, as text.
        value: String,
        /// What is allowed.
        message: String,
    },
    /// The embedded paper table is malformed (a build defect, reported rather than panicking).
    #[error("paper table, line {line}: {message}")]
    PaperTable {
        /// 1-based line.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A fit produced no finite proper rotation and translation, even after centring and rescaling
    /// the points (floating-point overflow or underflow: coordinates far outside any robot's reach).
    #[error("method `{method}`: {message}. Fix: check the units and magnitudes of the coordinates (mm, within the robots' reach)")]
    NumericalFailure {
        /// The method that failed.
        method: String,
        /// What was not finite or not a rotation.
        message: String,
    },
}

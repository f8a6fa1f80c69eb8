//! Handclasp point pairs and their CSV input.
//!
//! CSV format (as a controller exports it, or as `sim-cell` writes a session): a header with at least
//! `r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm` in any order; other columns (`point`,
//! `r1_q1_deg`, …) are ignored. Robot 1's point is in base 1, robot 2's in base 2, millimetres.
//! The reader converts to metres and rejects, naming the line and the fix: missing columns, empty or
//! non-numeric or non-finite cells, duplicate points, coordinates that look like metres, and a large
//! spread mismatch between the two robots.

use crate::error::CalibError;
use nalgebra::Point3;
use std::path::Path;

/// Paired handclasp points: `p_b1[i]` (base 1, m) and `p_b2[i]` (base 2, m) are the same physical point.
#[derive(Debug, Clone, PartialEq)]
pub struct PointPairs {
    /// Robot 1's tip points in base 1, m.
    pub p_b1: Vec<Point3<f64>>,
    /// Robot 2's tip points in base 2, m.
    pub p_b2: Vec<Point3<f64>>,
    /// 1-based source rows for messages (for a CSV: the line number, header = line 1).
    pub rows: Vec<usize>,
}

/// Two points of one robot closer than this (m) are duplicates.
pub const DUPLICATE_DISTANCE_M: f64 = 1e-4;
/// If every |coordinate| of a robot is below this (mm), the file was written in metres.
pub const METRES_LIMIT_MM: f64 = 5.0;
/// A ratio of the two robots' RMS spreads above this is rejected as a unit mismatch.
pub const SPREAD_RATIO_LIMIT: f64 = 20.0;

impl PointPairs {
    /// Pairs with rows numbered 1..=n. Errors if the lengths differ.
    pub fn new(p_b1: Vec<Point3<f64>>, p_b2: Vec<Point3<f64>>) -> Result<Self, CalibError> {
        if p_b1.len() != p_b2.len() {
            return Err(CalibError::LengthMismatch {
                what: "p_b1 and p_b2".into(),
                a: p_b1.len(),
                b: p_b2.len(),
            });
        }
        let rows = (1..=p_b1.len()).collect();
        Ok(PointPairs { p_b1, p_b2, rows })
    }

    /// Number of point pairs.
    pub fn len(&self) -> usize {
        self.p_b1.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.p_b1.is_empty()
    }

    /// The source row of point `i` (falls back to `i + 1` when `rows` is short).
    pub fn row(&self, i: usize) -> usize {
        self.rows.get(i).copied().unwrap_or(i + 1)
    }

    /// The pairs without point `i` (for leave-one-out).
    pub fn without(&self, i: usize) -> PointPairs {
        let keep = |v: &Vec<Point3<f64>>| {
            v.iter()
                .enumerate()
                .filter(|(k, _)| *k != i)
                .map(|(_, p)| *p)
                .collect::<Vec<_>>()
        };
        PointPairs {
            p_b1: keep(&self.p_b1),
            p_b2: keep(&self.p_b2),
            rows: (0..self.len())
                .filter(|k| *k != i)
                .map(|k| self.row(k))
                .collect(),
        }
    }

    /// Checks for duplicate points: two points closer than [`DUPLICATE_DISTANCE_M`] in either
    /// robot. The error ([`CalibError::Duplicate`]) names the first such pair in row order (by the
    /// first row, then the second, then robot 1 before robot 2) with its [`PointPairs::row`]s.
    ///
    /// O(n log n) time in every case, identical points included (a sorted grid of cubes of the
    /// distance's size, see the private `first_close_pair`).
    pub fn check_duplicates(&self) -> Result<(), CalibError> {
        let mut first: Option<(usize, usize, u8, f64)> = None;
        for (robot, pts) in [(1u8, &self.p_b1), (2u8, &self.p_b2)] {
            if let Some((i, j, d)) = first_close_pair(pts, DUPLICATE_DISTANCE_M) {
                if first.is_none_or(|(a, b, _, _)| (i, j) < (a, b)) {
                    first = Some((i, j, robot, d));
                }
            }
        }
        match first {
            Some((i, j, robot, d)) => Err(CalibError::Duplicate {
                row_a: self.row(i),
                row_b: self.row(j),
                robot,
                distance_mm: d * 1e3,
            }),
            None => Ok(()),
        }
    }

    /// Checks for duplicate points ([`PointPairs::check_duplicates`]) and for a
    /// spread mismatch beyond [`SPREAD_RATIO_LIMIT`]. `source_name` names the data in messages.
    pub fn check_consistency(&self, source_name: &str) -> Result<(), CalibError> {
        let n = self.len();
        self.check_duplicates()?;
        if n >= 2 {
            let s1 = rms_spread(&self.p_b1);
            let s2 = rms_spread(&self.p_b2);
            let ratio = s1.max(s2) / s1.min(s2).max(f64::MIN_POSITIVE);
            if ratio > SPREAD_RATIO_LIMIT {
                return Err(CalibError::SpreadMismatch {
                    source_name: source_name.into(),
                    spread1_mm: s1 * 1e3,
                    spread2_mm: s2 * 1e3,
                    ratio,
                });
            }
        }
        Ok(())
    }
}

/// The pair `(i, j)`, `i < j`, of points closer than `limit` (m) that comes first in index order
/// (smallest `i`, then smallest `j`), with its distance.
///
/// The points are sorted into a grid of cubes of side `limit / 1.75` (below `limit / √3`, so two
/// points of one cube are always closer than `limit`, and a point's partners lie within two cubes
/// along each axis). The first index of the answer is then the smallest index of its cube (else
/// that cube's smallest index would pair with it first), so only each cube's smallest index is
/// tried, against the ≤ 125 cubes around it: each cube is read by at most 125 such tries, in every
/// case, identical points included. The second index is one scan of the points after the first.
///
/// The grid is a sorted array of packed cube keys (16 bytes a point: at 1e6 points 16 MB, where a
/// hash map of cubes took ~135 MB and was the command's memory peak): the five cubes along z of
/// one (x, y) column are one key range, found by binary search. O(n log n) time. Points whose
/// cubes do not fit the packing (a spread beyond ~2 million cubes along an axis, a non-finite
/// coordinate, more than `u32::MAX` points) take [`first_close_pair_hashed`], the same search over
/// a hash map.
fn first_close_pair(points: &[Point3<f64>], limit: f64) -> Option<(usize, usize, f64)> {
    if points.len() < 2 || limit.is_nan() || limit <= 0.0 {
        return None;
    }
    let side = limit / 1.75;
    let Some(grid) = SortedGrid::new(points, side) else {
        return first_close_pair_hashed(points, limit);
    };
    let close = |a: usize, b: usize| (points[a] - points[b]).norm() < limit;
    let first = grid.firsts().into_iter().find(|&i| {
        let c = grid.cube(&points[i]);
        (-2i64..=2).any(|dx| {
            (-2i64..=2).any(|dy| {
                grid.column(c[0] + dx, c[1] + dy, c[2] - 2, c[2] + 2)
                    .any(|j| j > i && close(i, j))
            })
        })
    })?;
    let j = (first + 1..points.len()).find(|&j| close(first, j))?;
    Some((first, j, (points[first] - points[j]).norm()))
}

/// Bits per axis of a packed cube key ([`SortedGrid`]).
const CUBE_BITS: u32 = 21;

/// The points' cubes as a sorted array of `(packed key, point index)`: key `x·2⁴² + y·2²¹ + z` of
/// the cube's coordinates counted from two cubes below the points' lowest cube (so the ±2
/// neighbours of every occupied cube are non-negative and fit the 21 bits).
struct SortedGrid {
    /// `(key, index)` ascending: the points of one cube are a run, lowest index first.
    entries: Vec<(u64, u32)>,
    /// Cube side, m.
    side: f64,
    /// The lowest cube's coordinates minus 2.
    origin: [i64; 3],
}

impl SortedGrid {
    /// The grid of `points` with cubes of side `side` (m), or `None` when it cannot be packed
    /// (a non-finite coordinate, a spread beyond `2²¹ − 5` cubes along an axis, or more than
    /// `u32::MAX` points).
    fn new(points: &[Point3<f64>], side: f64) -> Option<Self> {
        if points.len() > u32::MAX as usize {
            return None;
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points {
            for a in 0..3 {
                if !p[a].is_finite() {
                    return None;
                }
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let span_limit = ((1u64 << CUBE_BITS) - 5) as f64;
        let mut origin = [0i64; 3];
        for a in 0..3 {
            let (l, h) = ((lo[a] / side).floor(), (hi[a] / side).floor());
            // Written so that a NaN (an overflowing quotient) fails the test.
            let packable = h - l < span_limit && l.abs() <= 1e15 && h.abs() <= 1e15;
            if !packable {
                return None;
            }
            origin[a] = l as i64 - 2;
        }
        let mut grid = SortedGrid {
            entries: Vec::new(),
            side,
            origin,
        };
        let mut entries: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let c = grid.cube(p);
                (Self::key(c[0], c[1], c[2]), k as u32)
            })
            .collect();
        entries.sort_unstable();
        grid.entries = entries;
        Some(grid)
    }

    /// The cube coordinates of `p`, counted from `origin` (each in `2..2²¹ − 2`).
    fn cube(&self, p: &Point3<f64>) -> [i64; 3] {
        [0, 1, 2].map(|a| (p[a] / self.side).floor() as i64 - self.origin[a])
    }

    /// The packed key of cube `(x, y, z)`, each in `0..2²¹`.
    fn key(x: i64, y: i64, z: i64) -> u64 {
        ((x as u64) << (2 * CUBE_BITS)) | ((y as u64) << CUBE_BITS) | z as u64
    }

    /// Each occupied cube's smallest point index, ascending.
    fn firsts(&self) -> Vec<usize> {
        let mut firsts: Vec<usize> = self
            .entries
            .iter()
            .enumerate()
            .filter(|(k, e)| *k == 0 || self.entries[k - 1].0 != e.0)
            .map(|(_, e)| e.1 as usize)
            .collect();
        firsts.sort_unstable();
        firsts
    }

    /// The indices of the points in cubes `(x, y, z_lo..=z_hi)` (one key range).
    fn column(&self, x: i64, y: i64, z_lo: i64, z_hi: i64) -> impl Iterator<Item = usize> + '_ {
        let (lo, hi) = (Self::key(x, y, z_lo), Self::key(x, y, z_hi));
        let start = self.entries.partition_point(|e| e.0 < lo);
        self.entries[start..]
            .iter()
            .take_while(move |e| e.0 <= hi)
            .map(|e| e.1 as usize)
    }
}

/// [`first_close_pair`] over a hash map of cubes: the fallback for points the sorted grid cannot
/// pack. O(n) expected time; ~135 bytes a point.
fn first_close_pair_hashed(points: &[Point3<f64>], limit: f64) -> Option<(usize, usize, f64)> {
    let side = limit / 1.75;
    // Saturating casts: absurd coordinates (beyond ~1e14 m) share the edge cubes, which only
    // costs time; distances are always checked.
    let key = |p: &Point3<f64>| -> [i64; 3] {
        [
            (p.x / side).floor() as i64,
            (p.y / side).floor() as i64,
            (p.z / side).floor() as i64,
        ]
    };
    // FxHash: the keys are our own cube indices (no untrusted hashing concern), and each point
    // probes up to 125 cubes, so SipHash's cost dominated at 1e6 points.
    let mut grid: rustc_hash::FxHashMap<[i64; 3], Vec<usize>> =
        rustc_hash::FxHashMap::with_capacity_and_hasher(points.len(), Default::default());
    for (k, p) in points.iter().enumerate() {
        grid.entry(key(p)).or_default().push(k); // indices ascending within each cube
    }
    let mut firsts: Vec<usize> = grid.values().map(|v| v[0]).collect();
    firsts.sort_unstable();
    let close = |a: usize, b: usize| (points[a] - points[b]).norm() < limit;
    let first = firsts.into_iter().find(|&i| {
        let c = key(&points[i]);
        (-2i64..=2).any(|dx| {
            (-2i64..=2).any(|dy| {
                (-2i64..=2).any(|dz| {
                    let n = [
                        c[0].saturating_add(dx),
                        c[1].saturating_add(dy),
                        c[2].saturating_add(dz),
                    ];
                    grid.get(&n)
                        .is_some_and(|v| v.iter().any(|&j| j > i && close(i, j)))
                })
            })
        })
    })?;
    let j = (first + 1..points.len()).find(|&j| close(first, j))?;
    Some((first, j, (points[first] - points[j]).norm()))
}

fn rms_spread(points: &[Point3<f64>]) -> f64 {
    let n = points.len() as f64;
    let c = points
        .iter()
        .fold(nalgebra::Vector3::zeros(), |a, p| a + p.coords)
        / n;
    (points
        .iter()
        .map(|p| (p.coords - c).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt()
}

const COLUMNS: [&str; 6] = [
    "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
];

/// Drops a leading UTF-8 byte-order mark (spreadsheet programs write one), so that the first
/// header name reads as typed.
pub fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// The field delimiter of CSV text, read from its header line (its first line): whichever of
/// comma, semicolon and tab occurs most often there (a spreadsheet set to a European locale writes
/// `;`, a copy from a table writes tabs); comma when none occurs or on a tie with comma.
pub fn csv_delimiter(text: &str) -> u8 {
    let header = strip_bom(text).lines().next().unwrap_or("");
    let count = |c: char| header.chars().filter(|&h| h == c).count();
    let (commas, semicolons, tabs) = (count(','), count(';'), count('\t'));
    if semicolons > commas && semicolons >= tabs {
        b';'
    } else if tabs > commas && tabs > semicolons {
        b'\t'
    } else {
        b','
    }
}

/// A CSV reader over `text` as the toolkit reads its input files: a leading UTF-8 BOM dropped,
/// the delimiter taken from the header line ([`csv_delimiter`]), fields trimmed, and rows of any
/// length accepted (the caller checks each row's length and names its line, which the `csv`
/// crate's own length error does not say in the toolkit's words).
pub fn csv_reader(text: &str) -> csv::Reader<&[u8]> {
    let text = strip_bom(text);
    csv::ReaderBuilder::new()
        .delimiter(csv_delimiter(text))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes())
}

/// Reads handclasp points from a CSV in millimetres (see the module doc) and returns them in metres.
///
/// Errors (each naming the file, line/column and the fix): unreadable file, malformed CSV, missing
/// column, empty / non-numeric / non-finite cell, no data rows, duplicate points, coordinates that look
/// like metres (all |value| < 5 for a robot), a robot spread ≥ 20× the other's.
pub fn read_points_csv(path: &Path) -> Result<PointPairs, CalibError> {
    let pairs = {
        let text = kinematics::input::read_input_text(path, "points CSV").map_err(|e| match e {
            kinematics::input::InputError::Io { path, source } => CalibError::Io { path, source },
            other => CalibError::Input(other),
        })?;
        parse_rows(&text, path)?
        // The file's text goes here, before the checks below sort the points (1e6 rows: 57 MB
        // of text and 32 MB of sort keys need not be held at once).
    };
    pairs.check_consistency(&path.display().to_string())?;
    Ok(pairs)
}

/// Parses CSV text as [`read_points_csv`] does; `path` is used in messages only.
///
/// The header may start with a UTF-8 BOM, and fields may be separated by commas, semicolons or
/// tabs (detected from the header line, see [`csv_delimiter`]).
pub fn parse_points_csv(text: &str, path: &Path) -> Result<PointPairs, CalibError> {
    let pairs = parse_rows(text, path)?;
    pairs.check_consistency(&path.display().to_string())?;
    Ok(pairs)
}

/// The rows of [`parse_points_csv`] with every per-cell and units check, before the checks of
/// the points against each other ([`PointPairs::check_consistency`]).
fn parse_rows(text: &str, path: &Path) -> Result<PointPairs, CalibError> {
    let text = strip_bom(text);
    let delimiter = csv_delimiter(text);
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(delimiter)
        .trim(csv::Trim::All)
        .flexible(false)
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| CalibError::Csv {
            path: path.to_path_buf(),
            line: 1,
            message: e.to_string(),
        })?
        .clone();
    let mut idx = [0usize; 6];
    for (k, col) in COLUMNS.iter().enumerate() {
        idx[k] =
            headers
                .iter()
                .position(|h| h == *col)
                .ok_or_else(|| CalibError::MissingColumn {
                    path: path.to_path_buf(),
                    column: col.to_string(),
                    found: kinematics::input::cap_echo(
                        &headers.iter().collect::<Vec<_>>().join(","),
                    ),
                })?;
    }
    // At most one data row per line after the header: the vectors are allocated once.
    let lines = text.bytes().filter(|&b| b == b'\n').count();
    let mut pairs = PointPairs {
        p_b1: Vec::with_capacity(lines),
        p_b2: Vec::with_capacity(lines),
        rows: Vec::with_capacity(lines),
    };
    for record in reader.records() {
        let record = record.map_err(|e| CalibError::Csv {
            path: path.to_path_buf(),
            line: e.position().map(|p| p.line() as usize).unwrap_or(0),
            message: e.to_string(),
        })?;
        let line = record.position().map(|p| p.line() as usize).unwrap_or(0);
        if record.iter().all(|c| c.is_empty()) {
            continue; // blank line
        }
        let mut v = [0.0f64; 6];
        for k in 0..6 {
            let cell = record.get(idx[k]).unwrap_or("");
            let bad = |problem: &'static str, fix: &'static str| CalibError::BadCell {
                path: path.to_path_buf(),
                line,
                column: COLUMNS[k].into(),
                value: kinematics::input::cap_echo(cell),
                problem,
                fix,
            };
            if cell.is_empty() {
                return Err(bad(
                    "empty cell",
                    "fill in the coordinate in millimetres, or delete the row",
                ));
            }
            let x: f64 = cell.parse().map_err(|_| {
                if cell.replacen(',', ".", 1).parse::<f64>().is_ok() {
                    bad(
                        "not a number (a decimal comma)",
                        "write the decimal separator as a point (1234.5, not 1234,5); separate the fields by `;` or tabs if you keep commas elsewhere",
                    )
                } else {
                    bad(
                        "not a number",
                        "write a plain decimal number in millimetres (e.g. 1234.5)",
                    )
                }
            })?;
            if !x.is_finite() {
                return Err(bad(
                    "not finite",
                    "re-record the point; NaN/inf cannot be calibrated",
                ));
            }
            v[k] = x;
        }
        pairs.p_b1.push(Point3::new(v[0], v[1], v[2]) * 1e-3);
        pairs.p_b2.push(Point3::new(v[3], v[4], v[5]) * 1e-3);
        pairs.rows.push(line);
    }
    if pairs.is_empty() {
        return Err(CalibError::TooFewPoints {
            method: format!("any (file {} has no data rows)", path.display()),
            needed: 3,
            got: 0,
        });
    }
    for (robot, pts) in [(1u8, &pairs.p_b1), (2u8, &pairs.p_b2)] {
        if pts
            .iter()
            .all(|p| p.iter().all(|c| c.abs() * 1e3 < METRES_LIMIT_MM))
        {
            return Err(CalibError::LooksLikeMetres {
                path: path.to_path_buf(),
                robot,
                limit_mm: METRES_LIMIT_MM,
            });
        }
    }
    Ok(pairs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<PointPairs, CalibError> {
        parse_points_csv(text, Path::new("points.csv"))
    }

    const GOOD: &str = "point,r1_q1_deg,r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n\
        1,0.0,1000,0,500,10,20,30\n\
        2,0.0,0,1000,500,-990,1020,30\n\
        3,0.0,500,500,1200,-490,520,730\n";

    #[test]
    fn reads_and_converts_mm_to_m() {
        let p = parse(GOOD).unwrap();
        assert_eq!(p.len(), 3);
        assert_eq!(p.rows, vec![2, 3, 4]);
        assert!((p.p_b1[0].x - 1.0).abs() < 1e-12);
        assert!((p.p_b2[2].z - 0.73).abs() < 1e-12);
    }

    #[test]
    fn column_order_free() {
        let t = "r2_z_mm,r2_y_mm,r2_x_mm,r1_z_mm,r1_y_mm,r1_x_mm\n30,20,10,500,0,1000\n40,900,10,500,880,1000\n";
        let p = parse(t).unwrap();
        assert!((p.p_b2[0].x - 0.010).abs() < 1e-12);
        assert!((p.p_b1[1].y - 0.88).abs() < 1e-12);
    }

    #[test]
    fn missing_column_named() {
        let e = parse("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm\n1,2,3,4,5\n").unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.contains("r2_z_mm") && msg.contains("points.csv"),
            "{msg}"
        );
    }

    #[test]
    fn empty_and_nan_cells_name_line_and_column() {
        let t = GOOD.replace("-990", "");
        let msg = parse(&t).unwrap_err().to_string();
        assert!(
            msg.contains("line 3") && msg.contains("r2_x_mm") && msg.contains("empty"),
            "{msg}"
        );
        let t = GOOD.replace("-990", "NaN");
        let msg = parse(&t).unwrap_err().to_string();
        assert!(
            msg.contains("line 3") && msg.contains("not finite"),
            "{msg}"
        );
        let t = GOOD.replace("-990", "abc");
        let msg = parse(&t).unwrap_err().to_string();
        assert!(msg.contains("not a number"), "{msg}");
    }

    #[test]
    fn ragged_row_is_an_error() {
        let t = format!("{GOOD}4,0.0,1,2\n");
        let e = parse(&t).unwrap_err();
        assert!(matches!(e, CalibError::Csv { line: 5, .. }), "{e}");
    }

    #[test]
    fn metres_detected() {
        let t = "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n1.0,0,0.5,0.01,0.02,0.03\n0,1.0,0.5,-0.99,1.02,0.03\n";
        let msg = parse(t).unwrap_err().to_string();
        assert!(msg.contains("metres") && msg.contains("multiply"), "{msg}");
    }

    #[test]
    fn spread_mismatch_detected() {
        // Robot 2 in metres-times-something: spreads 1000× apart, but not all below 5.
        let t = "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n\
                 1000,0,500,10,20,30\n0,1000,500,9,21,30\n500,500,1200,9.5,20.5,30.7\n";
        let e = parse(t).unwrap_err();
        assert!(matches!(e, CalibError::SpreadMismatch { .. }), "{e}");
    }

    #[test]
    fn duplicates_detected() {
        let t = format!("{GOOD}4,0.0,1000,0,500,10,20,30\n");
        let e = parse(&t).unwrap_err();
        match e {
            CalibError::Duplicate { row_a, row_b, .. } => assert_eq!((row_a, row_b), (2, 5)),
            other => panic!("expected duplicate, got {other}"),
        }
    }

    /// The shared reader drops the BOM, takes `;` from the header, trims fields and accepts a
    /// short row (the callers name its line).
    #[test]
    fn csv_reader_drops_bom_detects_delimiter_and_accepts_short_rows() {
        let mut r = csv_reader("\u{feff}a; b ;c\n1;2;3\n4;5\n");
        let headers: Vec<String> = r.headers().unwrap().iter().map(str::to_string).collect();
        assert_eq!(headers, ["a", "b", "c"]);
        let lens: Vec<usize> = r.records().map(|row| row.unwrap().len()).collect();
        assert_eq!(lens, [3, 2]);
    }

    /// A spreadsheet in a European locale writes `;`; a copy from a table writes tabs; both read
    /// like the comma file.
    #[test]
    fn semicolon_separated_points() {
        let want = parse(GOOD).unwrap();
        assert_eq!(parse(&GOOD.replace(',', ";")).unwrap(), want);
        assert_eq!(parse(&GOOD.replace(',', "\t")).unwrap(), want);
        assert_eq!(csv_delimiter("a;b;c\n1,5;2;3\n"), b';');
        assert_eq!(csv_delimiter("a\tb\n"), b'\t');
        assert_eq!(csv_delimiter("a,b\n"), b',');
        assert_eq!(csv_delimiter(""), b',');
    }

    /// Semicolons with decimal commas (`1000,5`): the message names the decimal comma and the fix.
    #[test]
    fn decimal_comma_points() {
        let t = GOOD.replace(',', ";").replace("-990", "-990,5");
        let msg = parse(&t).unwrap_err().to_string();
        assert!(
            msg.contains("decimal comma") && msg.contains("r2_x_mm") && msg.contains("line 3"),
            "{msg}"
        );
    }

    /// A UTF-8 BOM before a header whose first column is a coordinate.
    #[test]
    fn bom_points() {
        let t = "r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n1000,0,500,10,20,30\n0,1000,500,-990,1020,30\n";
        let want = parse(t).unwrap();
        assert_eq!(parse(&format!("\u{feff}{t}")).unwrap(), want);
        assert_eq!(
            parse(&format!("\u{feff}{}", t.replace(',', ";"))).unwrap(),
            want
        );
    }

    /// Every row duplicated, in a shuffled order: the first pair in row order is named, as the
    /// pairwise scan named it.
    #[test]
    fn every_row_duplicated_points() {
        let mut t = GOOD.to_string();
        for line in GOOD.lines().skip(1).collect::<Vec<_>>().iter().rev() {
            t += line;
            t += "\n";
        }
        match parse(&t).unwrap_err() {
            CalibError::Duplicate {
                row_a,
                row_b,
                robot,
                ..
            } => {
                assert_eq!((row_a, row_b, robot), (2, 7, 1))
            }
            other => panic!("expected duplicate, got {other}"),
        }
        let pts: Vec<Point3<f64>> = (0..200)
            .map(|k| Point3::new(k as f64 * 1e-3, 0.0, 0.0))
            .collect();
        assert_eq!(first_close_pair(&pts, DUPLICATE_DISTANCE_M), None);
        let mut near = pts.clone();
        near[150] = near[40] + nalgebra::Vector3::new(0.0, 5e-5, 0.0);
        near[190] = near[10] + nalgebra::Vector3::new(0.0, 0.0, 5e-5);
        let (i, j, d) = first_close_pair(&near, DUPLICATE_DISTANCE_M).unwrap();
        assert_eq!((i, j), (10, 190));
        assert!((d - 5e-5).abs() < 1e-15);
    }

    #[test]
    fn no_rows() {
        let e = parse("r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm\n").unwrap_err();
        assert!(matches!(e, CalibError::TooFewPoints { got: 0, .. }));
    }
}

#[cfg(test)]
mod close_pair_tests {
    use super::*;
    use proptest::prelude::*;

    /// The first close pair in index order by comparing every pair (the definition).
    fn brute_force(points: &[Point3<f64>], limit: f64) -> Option<(usize, usize)> {
        (0..points.len())
            .flat_map(|i| (i + 1..points.len()).map(move |j| (i, j)))
            .find(|&(i, j)| (points[i] - points[j]).norm() < limit)
    }

    proptest! {
        /// The grid search names the same pair as the pairwise definition, on clustered points
        /// (many close pairs, coincident ones included) at the duplicate distance.
        #[test]
        fn grid_search_matches_every_pair(
            raw in proptest::collection::vec((0u8..6, 0u8..6, 0u8..6, 0u8..3), 0..60)
        ) {
            let step = DUPLICATE_DISTANCE_M * 0.45;
            let points: Vec<Point3<f64>> = raw
                .iter()
                .map(|&(x, y, z, j)| {
                    Point3::new(
                        x as f64 * step + j as f64 * 1e-6,
                        y as f64 * step,
                        z as f64 * step - 0.5,
                    )
                })
                .collect();
            let want = brute_force(&points, DUPLICATE_DISTANCE_M);
            let got = first_close_pair(&points, DUPLICATE_DISTANCE_M).map(|(i, j, _)| (i, j));
            prop_assert_eq!(got, want);
            let hashed =
                first_close_pair_hashed(&points, DUPLICATE_DISTANCE_M).map(|(i, j, _)| (i, j));
            prop_assert_eq!(hashed, want);
        }
    }

    /// Points the sorted grid cannot pack (a spread of 1,000 km, beyond 2²¹ cubes of 57 µm; a
    /// NaN coordinate) take the hash map and still name the first close pair.
    #[test]
    fn unpackable_points_take_the_hash_map() {
        let mut far: Vec<Point3<f64>> = (0..50)
            .map(|k| Point3::new(k as f64 * 1e-3, 0.0, 0.0))
            .collect();
        far.push(Point3::new(1e6, 0.0, 0.0));
        far.push(far[7] + nalgebra::Vector3::new(0.0, 3e-5, 0.0));
        assert!(SortedGrid::new(&far, DUPLICATE_DISTANCE_M / 1.75).is_none());
        assert_eq!(
            first_close_pair(&far, DUPLICATE_DISTANCE_M).map(|(i, j, _)| (i, j)),
            Some((7, 51))
        );
        let mut nan = far[..50].to_vec();
        nan[3] = Point3::new(f64::NAN, 0.0, 0.0);
        nan.push(nan[20]);
        assert!(SortedGrid::new(&nan, DUPLICATE_DISTANCE_M / 1.75).is_none());
        assert_eq!(
            first_close_pair(&nan, DUPLICATE_DISTANCE_M).map(|(i, j, _)| (i, j)),
            Some((20, 50))
        );
    }

    /// 200 000 identical points (the case that was quadratic: 100 000 rows took > 120 s) and
    /// 200 000 points jittered within the distance: linear time, the first pair named. The
    /// bound is loose for a debug build on a shared machine; a quadratic scan takes hours.
    #[test]
    fn identical_and_clustered_points_are_linear() {
        const N: usize = 200_000;
        const TIME_LIMIT_S: f64 = 20.0;
        let same = vec![Point3::new(0.3, -0.2, 1.1); N];
        let jittered: Vec<Point3<f64>> = (0..N)
            .map(|k| {
                Point3::new(
                    0.3 + (k % 97) as f64 * 1e-7,
                    -0.2,
                    1.1 + (k % 89) as f64 * 1e-7,
                )
            })
            .collect();
        for points in [same, jittered] {
            let start = std::time::Instant::now();
            let (i, j, _) = first_close_pair(&points, DUPLICATE_DISTANCE_M).unwrap();
            assert_eq!((i, j), (0, 1));
            let secs = start.elapsed().as_secs_f64();
            assert!(secs < TIME_LIMIT_S, "{secs} s for {N} points");
        }
    }
}

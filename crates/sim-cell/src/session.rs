//! Handclasp sessions: what the two controllers report at each teach point (joint angles and
//! nominal-model tip positions), simulated on a [`Cell`] or read from / written to CSV.
//!
//! CSV: header `point,r1_q1_deg,…,r1_qN_deg,r2_q1_deg,…,r2_qM_deg,r1_x_mm,r1_y_mm,r1_z_mm,
//! r2_x_mm,r2_y_mm,r2_z_mm` (N, M = the models' joint counts, URDF chain order), one row per point,
//! degrees and millimetres with 6 decimals; tips in each robot's own base frame. It is valid input
//! to `handclasp calibrate` (calib-core's reader ignores the joint columns).

use crate::cell::{Cell, CellRobot};
use crate::error::SimError;
use crate::layout::{teach_points, Layout};
use calib_core::{PointPairs, Robot};
use kinematics::{
    base_from_tip, ik_tip_position, tip_joint_jacobian_true, true_base_from_tip, IkOptions,
};
use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use rand::Rng;
use rand_distr::StandardNormal;
use std::path::Path;

/// Layout draws tried before a session is declared unreachable.
pub const MAX_LAYOUT_ATTEMPTS: usize = 20;
/// Tolerance of the true-robot Newton correction: the true tip is within this of its target, m.
pub const TRUE_TIP_TOL_M: f64 = 1e-9;
/// Newton iterations of the true-robot correction.
const TRUE_NEWTON_ITER: usize = 30;
/// Largest allowed mismatch between a session row's tip columns and FK of its joint columns, mm.
pub const TIP_CONSISTENCY_MM: f64 = 0.01;

/// One teach point as the controllers report it.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionPoint {
    /// Point number (1-based label, the CSV `point` column).
    pub point: usize,
    /// Robot 1's reported joint angles, rad, URDF chain order.
    pub q1: Vec<f64>,
    /// Robot 2's reported joint angles, rad.
    pub q2: Vec<f64>,
    /// Robot 1's tip by its nominal model, m, base 1.
    pub p_b1: Point3<f64>,
    /// Robot 2's tip by its nominal model, m, base 2.
    pub p_b2: Point3<f64>,
}

/// A handclasp session.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// The points, in teaching order.
    pub points: Vec<SessionPoint>,
}

/// What to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct SessionSpec {
    /// Number of teach points (≥ 1).
    pub n: usize,
    /// Layout of the teach points.
    pub layout: Layout,
    /// Layout size, m (see [`crate::layout`]).
    pub spread_m: f64,
    /// Centre of the layout, m, b1 (None: the cell's `centre_b1`).
    pub centre_b1: Option<Point3<f64>>,
    /// Explicit teach points, m, b1 (overrides `n`/`layout`/`spread_m`; an unreachable one is an
    /// error naming it).
    pub points_b1: Option<Vec<Point3<f64>>>,
}

impl SessionSpec {
    /// `n` points of `layout` with `spread_m` around the cell's centre.
    pub fn new(n: usize, layout: Layout, spread_m: f64) -> Self {
        SessionSpec {
            n,
            layout,
            spread_m,
            centre_b1: None,
            points_b1: None,
        }
    }
}

impl Session {
    /// The nominal tips `(p_b1, p_b2)`, m.
    pub fn tips(&self) -> (Vec<Point3<f64>>, Vec<Point3<f64>>) {
        (
            self.points.iter().map(|p| p.p_b1).collect(),
            self.points.iter().map(|p| p.p_b2).collect(),
        )
    }

    /// The tips as calib-core point pairs (rows = point numbers).
    pub fn to_point_pairs(&self) -> PointPairs {
        let (p_b1, p_b2) = self.tips();
        PointPairs {
            p_b1,
            p_b2,
            rows: self.points.iter().map(|p| p.point).collect(),
        }
    }

    /// The CSV columns (see the module docs) for joint counts `dof1`, `dof2`.
    pub fn csv_header(dof1: usize, dof2: usize) -> Vec<String> {
        let mut header = vec!["point".to_string()];
        for (r, d) in [(1, dof1), (2, dof2)] {
            for k in 1..=d {
                header.push(format!("r{r}_q{k}_deg"));
            }
        }
        header.extend(
            [
                "r1_x_mm", "r1_y_mm", "r1_z_mm", "r2_x_mm", "r2_y_mm", "r2_z_mm",
            ]
            .map(String::from),
        );
        header
    }

    /// The CSV text (see the module docs) for joint counts `dof1`, `dof2`.
    pub fn to_csv_string(&self, dof1: usize, dof2: usize) -> String {
        let mut out = csv::Writer::from_writer(Vec::new());
        // Writing to memory cannot fail, and every field is plain ASCII.
        let _ = out.write_record(Session::csv_header(dof1, dof2));
        for p in &self.points {
            let mut record = vec![p.point.to_string()];
            for q in p.q1.iter().chain(&p.q2) {
                record.push(format!("{:.6}", q.to_degrees()));
            }
            for v in [&p.p_b1, &p.p_b2] {
                for a in 0..3 {
                    record.push(format!("{:.6}", v[a] * 1e3));
                }
            }
            let _ = out.write_record(&record);
        }
        let bytes = out.into_inner().unwrap_or_default();
        String::from_utf8(bytes).unwrap_or_default()
    }

    /// Writes the session CSV for `cell`'s robots.
    pub fn write_csv(&self, path: &Path, cell: &Cell) -> Result<(), SimError> {
        std::fs::write(
            path,
            self.to_csv_string(cell.robot1.model.dof(), cell.robot2.model.dof()),
        )
        .map_err(|e| SimError::io(path, e))
    }

    /// Reads a session CSV for `cell` (see [`Session::parse_csv`]).
    pub fn read_csv(path: &Path, cell: &Cell) -> Result<Session, SimError> {
        let text = std::fs::read_to_string(path).map_err(|e| SimError::io(path, e))?;
        Session::parse_csv(&text, path, cell)
    }

    /// Parses session CSV text with the rules of calib-core's points reader
    /// ([`calib_core::parse_points_csv`]): a UTF-8 BOM and CRLF line ends are accepted, fields may be
    /// quoted and separated by commas, semicolons or tabs (detected from the header line,
    /// [`calib_core::csv_delimiter`]), columns are found by header name in any order and extra columns are ignored, blank
    /// lines are skipped. Every column of `cell`'s joint counts must be present and every value
    /// finite; each row's tip columns must match FK of its joint columns with the cell's nominal
    /// models and tip offsets within [`TIP_CONSISTENCY_MM`] (catches a wrong cell, tip or unit).
    /// Errors name the line and column and say what would work.
    pub fn parse_csv(text: &str, path: &Path, cell: &Cell) -> Result<Session, SimError> {
        let err = |message: String| SimError::Session {
            path: path.to_path_buf(),
            message,
        };
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let want = Session::csv_header(d1, d2);
        let text = calib_core::strip_bom(text);
        let mut reader = csv::ReaderBuilder::new()
            .delimiter(calib_core::csv_delimiter(text))
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(text.as_bytes());
        let headers = reader
            .headers()
            .map_err(|e| err(format!("line 1: the header is not valid CSV: {e}")))?
            .clone();
        if headers.iter().all(str::is_empty) {
            return Err(err("the file is empty; expected a header line".into()));
        }
        let mut idx = Vec::with_capacity(want.len());
        for name in &want {
            let k = headers.iter().position(|h| h == name).ok_or_else(|| {
                let unused: Vec<String> = headers
                    .iter()
                    .filter(|h| !want.iter().any(|w| w == h))
                    .map(|h| format!("`{h}`"))
                    .collect();
                let unused = if unused.is_empty() {
                    String::new()
                } else if headers.len() == 1 {
                    format!(
                        " (the header reads as the single column {}: separate the fields by commas, semicolons or tabs)",
                        unused.join(", ")
                    )
                } else {
                    format!(" (columns not used: {})", unused.join(", "))
                };
                err(format!(
                    "line 1: the header has no column `{name}`{unused}, which this cell ({} with {d1} joints, {} with {d2}) needs; \
                     the header must hold these columns (any order, extra columns ignored): {}",
                    cell.robot1.model.name(),
                    cell.robot2.model.name(),
                    want.join(","),
                ))
            })?;
            idx.push(k);
        }
        let mut points = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                err(format!("line {line}: not valid CSV: {e}"))
            })?;
            let line_no = record.position().map_or(0, |p| p.line());
            if record.iter().all(str::is_empty) {
                continue;
            }
            if record.len() != headers.len() {
                return Err(err(format!(
                    "line {line_no}: {} values but the header has {} columns",
                    record.len(),
                    headers.len()
                )));
            }
            let cells: Vec<&str> = idx.iter().map(|&k| record.get(k).unwrap_or("")).collect();
            let point: usize = cells[0].parse().map_err(|_| {
                err(format!(
                    "line {line_no}, column `point`: `{}` is not a point number (1, 2, …)",
                    cells[0]
                ))
            })?;
            let mut v = Vec::with_capacity(cells.len() - 1);
            for (k, c) in cells.iter().enumerate().skip(1) {
                let x: f64 = c
                    .parse()
                    .ok()
                    .filter(|x: &f64| x.is_finite())
                    .ok_or_else(|| {
                        err(format!(
                            "line {line_no}, column `{}`: `{c}` is not a finite number",
                            want[k]
                        ))
                    })?;
                v.push(x);
            }
            let q1: Vec<f64> = v[..d1].iter().map(|x| x.to_radians()).collect();
            let q2: Vec<f64> = v[d1..d1 + d2].iter().map(|x| x.to_radians()).collect();
            let t = &v[d1 + d2..];
            let p_b1 = Point3::new(t[0], t[1], t[2]) * 1e-3;
            let p_b2 = Point3::new(t[3], t[4], t[5]) * 1e-3;
            for (r, robot, q, p) in [(1, &cell.robot1, &q1, &p_b1), (2, &cell.robot2, &q2, &p_b2)] {
                let fk = base_from_tip(&robot.model, q, &robot.flange_from_tip)
                    .map_err(|e| err(format!("line {line_no}: robot {r}'s joint columns: {e}")))?;
                let d_mm = (fk.translation.vector - p.coords).norm() * 1e3;
                if d_mm > TIP_CONSISTENCY_MM {
                    return Err(err(format!(
                        "line {line_no}: robot {r}'s tip columns are {d_mm:.3} mm from the nominal FK of its joint columns \
                         (tip_mm = {:?}); check the cell (URDF, tip_mm) and that angles are in degrees and lengths in mm",
                        (robot.flange_from_tip * 1e3).as_slice()
                    )));
                }
            }
            points.push(SessionPoint {
                point,
                q1,
                q2,
                p_b1,
                p_b2,
            });
        }
        Ok(Session { points })
    }
}

/// Head-on approach directions (b1, unit) to try for a point, best first: along the line between
/// the shoulders, from robot 1's shoulder to the point, then those turned ±30°/±60° about the
/// vertical and tilted ±30°.
fn approach_directions(cell: &Cell, p: &Point3<f64>) -> Vec<Unit<Vector3<f64>>> {
    let s1 = cell
        .robot1
        .model
        .joints()
        .first()
        .map_or(Vector3::zeros(), |j| j.origin_xyz);
    let s2 = cell.b1_from_b2
        * Point3::from(
            cell.robot2
                .model
                .joints()
                .first()
                .map_or(Vector3::zeros(), |j| j.origin_xyz),
        );
    let up = -cell.robot1.g_base.normalize();
    let mut base = Vec::new();
    for d in [s2.coords - s1, p.coords - s1] {
        if let Some(u) = Unit::try_new(d, 1e-9) {
            base.push(u);
        }
    }
    let mut out = base.clone();
    for b in &base {
        for deg in [30.0f64, -30.0, 60.0, -60.0] {
            out.push(Rotation3::from_axis_angle(&Unit::new_normalize(up), deg.to_radians()) * *b);
        }
        let side = b.cross(&up);
        if let Some(side) = Unit::try_new(side, 1e-9) {
            for deg in [30.0f64, -30.0] {
                out.push(Rotation3::from_axis_angle(&side, deg.to_radians()) * *b);
            }
        }
    }
    out
}

/// Reported joints (rad, continuous) that put the TRUE robot's tip at `target` (m, nominal base):
/// nominal IK with the flange z along `axis`, then Newton steps on the true model
/// (`∂p/∂q_rep` of the true robot, minimum-norm). `None` if unreachable or outside the limits.
fn solve_true(
    robot: &CellRobot,
    target: &Point3<f64>,
    axis: Option<Unit<Vector3<f64>>>,
) -> Option<Vec<f64>> {
    let opts = IkOptions {
        tool_axis_base: axis,
        tolerance_m: 1e-9,
        axis_tolerance_rad: 1e-7,
        restarts: 8,
        ..IkOptions::default()
    };
    let sol = ik_tip_position(&robot.model, target, &robot.flange_from_tip, &opts).ok()?;
    if !sol.reachable() {
        return None;
    }
    let mut q = sol.q;
    if robot.errors.is_zero() {
        return Some(q);
    }
    for _ in 0..TRUE_NEWTON_ITER {
        let tip = true_base_from_tip(
            &robot.model,
            &robot.errors,
            &q,
            &robot.flange_from_tip,
            &robot.g_base,
        )
        .ok()?;
        let e = target.coords - tip.translation.vector;
        if e.norm() < TRUE_TIP_TOL_M {
            return Some(q);
        }
        let j = tip_joint_jacobian_true(
            &robot.model,
            &robot.errors,
            &q,
            &robot.flange_from_tip,
            &robot.g_base,
        )
        .ok()?;
        let jjt: Matrix3<f64> = &j * j.transpose();
        let y = jjt.try_inverse()? * e;
        let dq = j.transpose() * y;
        for ((qi, d), jt) in q.iter_mut().zip(dq.iter()).zip(robot.model.joints()) {
            *qi = (*qi + d).clamp(jt.lower, jt.upper);
        }
    }
    None
}

fn quantise(robot: &CellRobot, q: &mut [f64], resolution: f64) {
    if resolution > 0.0 {
        for (qi, jt) in q.iter_mut().zip(robot.model.joints()) {
            let mut v = (*qi / resolution).round() * resolution;
            if v > jt.upper {
                v -= resolution;
            }
            if v < jt.lower {
                v += resolution;
            }
            *qi = v;
        }
    }
}

fn gauss3(rng: &mut impl Rng, sigma: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        sigma.x * rng.sample::<f64, _>(StandardNormal),
        sigma.y * rng.sample::<f64, _>(StandardNormal),
        sigma.z * rng.sample::<f64, _>(StandardNormal),
    )
}

/// Why one point failed: (the robot that failed, message).
type PointFailure = (Robot, String);

/// Simulates one teach point `p` (true meeting point, m, b1). Robot 1's true tip is at `p`,
/// robot 2's at `p + ε` (alignment); the reported joints put the true tips there up to
/// repeatability `δ` (unseen by the encoders), quantised to the encoder resolution; the tips are
/// what the nominal models compute from the reported joints.
fn simulate_point(
    cell: &Cell,
    p: &Point3<f64>,
    label: usize,
    rng: &mut impl Rng,
) -> Result<SessionPoint, PointFailure> {
    let eps = gauss3(rng, &cell.noise.alignment_m);
    let rep = Vector3::repeat(cell.noise.repeatability_m);
    let d1 = gauss3(rng, &rep);
    let d2 = gauss3(rng, &rep);
    let b2_from_b1 = cell.b1_from_b2.inverse();
    let target1 = p + d1;
    let target2 = b2_from_b1 * (p + eps) + d2;
    let mut last = (Robot::One, String::new());
    for d in approach_directions(cell, p) {
        let Some(mut q1) = solve_true(&cell.robot1, &target1, Some(d)) else {
            last = (Robot::One, "robot 1 cannot reach it head-on".into());
            continue;
        };
        let axis2 = Unit::new_normalize(b2_from_b1.rotation * -d.into_inner());
        let Some(mut q2) = solve_true(&cell.robot2, &target2, Some(axis2)) else {
            last = (Robot::Two, "robot 2 cannot reach it head-on".into());
            continue;
        };
        quantise(&cell.robot1, &mut q1, cell.noise.encoder_resolution_rad);
        quantise(&cell.robot2, &mut q2, cell.noise.encoder_resolution_rad);
        let t1 = base_from_tip(&cell.robot1.model, &q1, &cell.robot1.flange_from_tip)
            .map_err(|e| (Robot::One, e.to_string()))?;
        let t2 = base_from_tip(&cell.robot2.model, &q2, &cell.robot2.flange_from_tip)
            .map_err(|e| (Robot::Two, e.to_string()))?;
        return Ok(SessionPoint {
            point: label,
            q1,
            q2,
            p_b1: Point3::from(t1.translation.vector),
            p_b2: Point3::from(t2.translation.vector),
        });
    }
    Err(last)
}

/// Simulates a handclasp session on `cell` (see [`simulate_point`] for one point's model): teach
/// points from `spec` (a layout draw, redrawn up to [`MAX_LAYOUT_ATTEMPTS`] times until both robots
/// reach every point head-on, or the explicit points). Seeded by `rng` alone.
///
/// Errors: an invalid spec, or a teach point outside the common workspace (naming the point, the
/// robot and what would work).
pub fn generate_session(
    cell: &Cell,
    spec: &SessionSpec,
    rng: &mut impl Rng,
) -> Result<Session, SimError> {
    if !(spec.spread_m.is_finite() && spec.spread_m > 0.0) && spec.points_b1.is_none() {
        return Err(SimError::InvalidInput(format!(
            "spread {} mm must be a positive length (e.g. 1000)",
            spec.spread_m * 1e3
        )));
    }
    let centre = spec.centre_b1.unwrap_or(cell.centre_b1);
    if let Some(points) = &spec.points_b1 {
        let mut out = Vec::with_capacity(points.len());
        for (i, p) in points.iter().enumerate() {
            if !p.iter().all(|x| x.is_finite()) {
                return Err(SimError::InvalidInput(format!(
                    "teach point {} is not finite",
                    i + 1
                )));
            }
            match simulate_point(cell, p, i + 1, rng) {
                Ok(sp) => out.push(sp),
                Err((robot, why)) => return Err(unreachable(cell, i + 1, p, robot, &why, None)),
            }
        }
        return Ok(Session { points: out });
    }
    if spec.n == 0 {
        return Err(SimError::InvalidInput(
            "a session needs at least 1 point (4 for every method)".into(),
        ));
    }
    let mut last_fail = None;
    'draw: for _ in 0..MAX_LAYOUT_ATTEMPTS {
        let pts = teach_points(spec.layout, spec.n, spec.spread_m, &centre, rng);
        let mut out = Vec::with_capacity(spec.n);
        for (i, p) in pts.iter().enumerate() {
            match simulate_point(cell, p, i + 1, rng) {
                Ok(sp) => out.push(sp),
                Err((robot, why)) => {
                    last_fail = Some((i + 1, *p, robot, why));
                    continue 'draw;
                }
            }
        }
        return Ok(Session { points: out });
    }
    let (i, p, robot, why) = last_fail.unwrap_or((1, centre, Robot::One, String::new()));
    Err(unreachable(cell, i, &p, robot, &why, Some(spec)))
}

fn unreachable(
    cell: &Cell,
    point: usize,
    p: &Point3<f64>,
    robot: Robot,
    why: &str,
    spec: Option<&SessionSpec>,
) -> SimError {
    let c = cell.centre_b1 * 1e3;
    let hint = match spec {
        Some(s) => format!(
            "no draw of {MAX_LAYOUT_ATTEMPTS} {} layouts with spread {:.0} mm fitted; reduce the spread or move the centre toward ({:.0}, {:.0}, {:.0}) mm",
            s.layout, s.spread_m * 1e3, c.x, c.y, c.z
        ),
        None => format!("move it toward the common workspace centre ({:.0}, {:.0}, {:.0}) mm", c.x, c.y, c.z),
    };
    SimError::Unreachable {
        point,
        p_b1_mm: [p.x * 1e3, p.y * 1e3, p.z * 1e3],
        message: format!("{why} ({}); {hint}", cell.robot(robot).model.name()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A session saved by a spreadsheet in a European locale (`;`) or copied from a table (tabs),
    /// with or without a BOM, reads like the comma file; the message for an unknown separator
    /// shows the header it found.
    #[test]
    fn semicolon_separated_session() {
        let cell = Cell::default_floor_wall();
        let spec = SessionSpec::new(5, Layout::Random, 0.8);
        let session = generate_session(&cell, &spec, &mut crate::trial_rng(3, 0)).unwrap();
        let (d1, d2) = (cell.robot1.model.dof(), cell.robot2.model.dof());
        let text = session.to_csv_string(d1, d2);
        let p = Path::new("session.csv");
        let want = Session::parse_csv(&text, p, &cell).unwrap();
        for sep in [";", "\t"] {
            let variant = text.replace(',', sep);
            assert_eq!(
                Session::parse_csv(&variant, p, &cell).unwrap(),
                want,
                "{sep:?}"
            );
            let bom = format!("\u{feff}{variant}");
            assert_eq!(
                Session::parse_csv(&bom, p, &cell).unwrap(),
                want,
                "BOM {sep:?}"
            );
        }
        let e = Session::parse_csv(&text.replace(',', "|"), p, &cell)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no column `point`")
                && e.contains("point|r1_q1_deg")
                && e.contains("semicolons or tabs"),
            "{e}"
        );
    }
}

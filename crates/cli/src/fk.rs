//! `handclasp fk`: joint angles (deg) to the tip pose in the robot's base frame, as a pendant
//! shows it: x, y, z in mm and ZYZ φ, θ, ψ in degrees (`R = Rz(φ)·Ry(θ)·Rz(ψ)`).
//!
//! A prismatic (linear) joint, such as a track or a torso lift, takes its value in millimetres
//! in the same `--q-deg` list: `--q-deg 250,30,-10,…` is a 250 mm lift then the arm's angles in
//! degrees (`--json` then adds `q_units`). A coupled joint (a URDF `<mimic>`) is computed from the
//! others and takes no value: the list has one value per independent joint.
//!
//! `handclasp fk --robot robots/hp20.urdf --q-deg 0,10,-20,0,30,0 --tip-mm 0,0,150 --json` prints
//! `{"xyz_mm": [x, y, z], "zyz_deg": [φ, θ, ψ], "rotation": [[…], […], […]], …}` for
//! `base_from_tip`; without `--json` a readable table.
//!
//! With `--cell CELL --robot 1|2` the robot is the cell's, with everything the cell models: the
//! URDF plus the `[robotN.errors]` terms (joint offsets and scales, origin errors, the base's mount
//! error, compliance under the cell's gravity; `kinematics::true_base_from_flange`). `--q-csv FILE`
//! then evaluates one pose per row (columns `q1_deg` … `qN_deg`) and writes
//! `x_mm,y_mm,z_mm,qw,qx,qy,qz` (see [`run_batch`]).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use calib_core::{PoseForms, Robot};
use kinematics::input::cap_echo;
use kinematics::{base_from_tip, true_base_from_flange, KinematicErrors, ModelError, RobotModel};
use nalgebra::{Isometry3, Translation3, Vector3};
use serde::Serialize;

/// Arguments of `handclasp fk`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The robot: its URDF file (e.g. robots/hp20.urdf), or with --cell the robot of the cell,
    /// 1 or 2.
    #[arg(long)]
    pub robot: String,
    /// A cell file (TOML, e.g. a calibrated cell): FK with everything it models for robot
    /// --robot 1|2: the URDF and the [robotN.errors] terms a URDF cannot hold (joint scale,
    /// compliance under gravity, mount error). The pose is in that robot's nominal base frame.
    #[arg(long)]
    pub cell: Option<PathBuf>,
    /// The flange link the chain ends at (with --cell: the cell's tool_link).
    #[arg(long, default_value = "tool0", conflicts_with = "cell")]
    pub tool_link: String,
    /// Joint values, comma separated, in chain order from the base (one per joint): degrees
    /// for rotary joints, millimetres for prismatic (linear) joints such as a track or a lift.
    /// A joint that follows another (a URDF mimic joint) takes no value.
    #[arg(long, allow_hyphen_values = true, required_unless_present = "q_csv")]
    pub q_deg: Option<String>,
    /// A CSV of joint angles (with --cell): columns q1_deg … qN_deg in chain order, one pose per
    /// row; other columns are ignored (named on stderr) unless given as --id-column. Comma,
    /// semicolon or tab separated.
    #[arg(long, conflicts_with = "q_deg", requires = "cell")]
    pub q_csv: Option<PathBuf>,
    /// With --q-csv: a column copied as the first output column (e.g. a pose id).
    #[arg(long, requires = "q_csv")]
    pub id_column: Option<String>,
    /// With --q-csv: the output CSV (x_mm,y_mm,z_mm,qw,qx,qy,qz; default: standard output).
    #[arg(long, requires = "q_csv")]
    pub out: Option<PathBuf>,
    /// Tip offset in the flange frame, mm: x,y,z (the measuring pin; 0,0,150 = 150 mm along the
    /// flange z axis). With --cell it is taken as given (the cell's tip and its tip error are not
    /// added; see --cell-tip). Default 0,0,0: the tool0 pose.
    #[arg(long, allow_hyphen_values = true, conflicts_with = "cell_tip")]
    pub tip_mm: Option<String>,
    /// With --cell: use the cell's calibrated tip (its tip_mm plus [robotN.errors] tip_mm).
    #[arg(long, requires = "cell")]
    pub cell_tip: bool,
    /// Print one JSON object instead of the table (single pose only).
    #[arg(long, conflicts_with = "q_csv")]
    pub json: bool,
    /// Also list (on stderr) the URDF joints and links outside the base-to-flange chain, which
    /// are ignored.
    #[arg(long)]
    pub verbose: bool,
}

/// A prismatic joint value under 1 mm (not 0) on a travel longer than this, mm, is warned about as
/// metres written as millimetres.
const PRISMATIC_METRES_SPAN_MM: f64 = 100.0;

/// Tip offsets whose every coordinate is below this (mm) but not all zero look like metres.
const TIP_METRES_LIMIT_MM: f64 = calib_core::METRES_LIMIT_MM;

/// Stderr lines listing what a URDF holds beyond the modelled chain (for `--verbose`).
pub(crate) fn ignored_branches_text(model: &RobotModel, what: &str) -> String {
    let mut s = format!(
        "{what}: {} ({} joints), base link {}, flange {}",
        model.name(),
        model.dof(),
        model.base_link(),
        model.tool_link()
    );
    if model.ignored_joints().is_empty() && model.ignored_links().is_empty() {
        s += "; no URDF joint or link outside the chain";
    } else {
        s += &format!(
            "; ignored (outside the base-to-flange chain): joints [{}], links [{}]",
            model.ignored_joints().join(", "),
            model.ignored_links().join(", ")
        );
    }
    s
}

/// Prints (stderr) [`ignored_branches_text`] for both robots of a cell (for `--verbose`).
pub(crate) fn print_cell_branches(cell: &handclasp_cell::Cell) {
    for &r in cell.robots() {
        let label = format!("robot {}", r.number());
        eprintln!("{}", ignored_branches_text(&cell.robot(r).model, &label));
    }
}

/// Parses a comma-separated list of finite numbers given to `flag`; `expected` names what the
/// count must be, for the message.
pub(crate) fn parse_list(
    flag: &str,
    text: &str,
    expected: Option<(usize, &str)>,
) -> anyhow::Result<Vec<f64>> {
    let mut out = Vec::new();
    for (i, item) in text.split(',').enumerate() {
        let item = item.trim();
        let v: f64 = item.parse().map_err(|_| {
            anyhow::anyhow!(
                "{flag}: value {} is `{item}`, not a number; give comma-separated numbers such as 0,10,-20",
                i + 1
            )
        })?;
        if !v.is_finite() {
            bail!(
                "{flag}: value {} is {item}, not a finite number; give finite numbers",
                i + 1
            );
        }
        out.push(v);
    }
    if let Some((n, what)) = expected {
        if out.len() != n {
            bail!(
                "{flag} has {} value{} but {what}; give exactly {n}, comma separated",
                out.len(),
                if out.len() == 1 { "" } else { "s" }
            );
        }
    }
    Ok(out)
}

/// Parses `--tip-mm` (x,y,z mm) into metres. A tip whose every coordinate is below
/// [`TIP_METRES_LIMIT_MM`] but not all zero is refused as metres written as millimetres (a
/// measuring pin of 0.15 mm does not exist; 0,0,0.15 means 150 mm).
pub(crate) fn parse_tip(text: &str) -> anyhow::Result<Vector3<f64>> {
    let v = parse_list(
        "--tip-mm",
        text,
        Some((3, "a tip offset has 3 (x,y,z in mm)")),
    )?;
    let tip_mm = Vector3::new(v[0], v[1], v[2]);
    if tip_mm != Vector3::zeros() && tip_mm.iter().all(|c| c.abs() < TIP_METRES_LIMIT_MM) {
        bail!(
            "--tip-mm {text} is within {TIP_METRES_LIMIT_MM} mm of the flange: this looks like metres; \
             --tip-mm is in millimetres, so multiply by 1000 (--tip-mm {},{},{})",
            v[0] * 1000.0,
            v[1] * 1000.0,
            v[2] * 1000.0
        );
    }
    Ok(tip_mm * 1e-3)
}

/// Loads the robot model with a message that says what to fix.
pub(crate) fn load_robot(path: &Path, tool_link: &str) -> anyhow::Result<RobotModel> {
    RobotModel::from_urdf_file(path, tool_link)
        .map_err(|e| match e {
            // The library names the missing link; the flag that chooses it is the binary's.
            ModelError::MissingLink { ref link, .. } if link == tool_link => anyhow::anyhow!(
                "{e} (the flange link is chosen with --tool-link, e.g. --tool-link tool0)"
            ),
            e => anyhow::Error::new(e),
        })
        .context("--robot: cannot load the robot model")
}

/// Parses `--q-deg` against the model: count and joint limits, each value in its joint's CLI
/// unit ([`joint_unit`]: degrees, millimetres for a prismatic joint). Returns
/// `(q_si, q_as_given)` (rad or m; deg or mm).
pub(crate) fn parse_q_deg(
    flag: &str,
    text: &str,
    model: &RobotModel,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let what = if model.has_coupled_joints() {
        let coupled: Vec<&str> = model
            .chain_joints()
            .iter()
            .filter(|j| j.is_coupled())
            .map(|j| j.name.as_str())
            .collect();
        format!(
            "{} has {} independent joints (the coupled joints {} follow them)",
            model.name(),
            model.dof(),
            coupled.join(", ")
        )
    } else {
        format!("{} has {} joints", model.name(), model.dof())
    };
    let q_deg = parse_list(flag, text, Some((model.dof(), &what)))?;
    for (i, (j, &v)) in model.joints().iter().zip(&q_deg).enumerate() {
        check_joint_value(flag, i, j, v)?;
        // Under 1 mm on a travel of more than 100 mm: probably metres.
        if j.kind.is_prismatic()
            && v != 0.0
            && v.abs() < 1.0
            && (j.upper - j.lower) * 1e3 > PRISMATIC_METRES_SPAN_MM
        {
            eprintln!(
                "warning: {flag}: joint {} ({}) is prismatic and {v} mm; its values are millimetres: if you meant {v} m, give {}",
                i + 1,
                j.name,
                v * 1e3
            );
        }
    }
    let q_si = model
        .joints()
        .iter()
        .zip(&q_deg)
        .map(|(j, &v)| from_cli_unit(j, v))
        .collect();
    Ok((q_si, q_deg))
}

/// Checks joint `i`'s value `v` in its CLI unit ([`joint_unit`]) against the joint's limits
/// (with the library's slack: 1e-9 rad, 1e-9 m); `at` names where the value came from (a flag,
/// or a file's line and column).
fn check_joint_value(at: &str, i: usize, j: &kinematics::Joint, v: f64) -> anyhow::Result<()> {
    if j.kind.is_prismatic() {
        let (lo, hi) = (j.lower * 1e3, j.upper * 1e3);
        if v < lo - 1e-6 || v > hi + 1e-6 {
            bail!(
                "{at}: joint {} ({}) is prismatic and {v} mm, outside its limits {lo:.3}..{hi:.3} mm; give a travel inside the range (millimetres, not metres)",
                i + 1,
                j.name
            );
        }
    } else {
        let (lo, hi) = (j.lower.to_degrees(), j.upper.to_degrees());
        let slack = 1e-9f64.to_degrees();
        if v < lo - slack || v > hi + slack {
            bail!(
                "{at}: joint {} ({}) is {v} deg, outside its limits {lo:.3}..{hi:.3} deg; give an angle inside the range (degrees, not radians)",
                i + 1,
                j.name
            );
        }
    }
    Ok(())
}

/// A joint value in its CLI unit ([`joint_unit`]: deg, or mm for a prismatic joint) in SI (rad
/// or m); the inverse of [`to_cli_unit`].
pub(crate) fn from_cli_unit(joint: &kinematics::Joint, v: f64) -> f64 {
    if joint.kind.is_prismatic() {
        v * 1e-3
    } else {
        v.to_radians()
    }
}

/// The CLI unit of a joint's value: `"mm"` for a prismatic joint, `"deg"` otherwise.
pub(crate) fn joint_unit(joint: &kinematics::Joint) -> &'static str {
    if joint.kind.is_prismatic() {
        "mm"
    } else {
        "deg"
    }
}

/// A joint value (rad, or m for a prismatic joint) in its CLI unit ([`joint_unit`]).
pub(crate) fn to_cli_unit(joint: &kinematics::Joint, v: f64) -> f64 {
    if joint.kind.is_prismatic() {
        v * 1e3
    } else {
        v.to_degrees()
    }
}

/// Readable lines of a pose (mm, deg, rotation rows).
pub(crate) fn pose_table(pose: &PoseForms) -> String {
    let (t, zyz, m) = (pose.xyz_mm, pose.zyz_deg, pose.rotation);
    let mut s = String::new();
    s += &format!(
        "  {:>12} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "x_mm", "y_mm", "z_mm", "phi_deg", "theta_deg", "psi_deg"
    );
    s += &format!(
        "  {:>12.4} {:>12.4} {:>12.4} {:>12.5} {:>12.5} {:>12.5}\n",
        t[0], t[1], t[2], zyz[0], zyz[1], zyz[2]
    );
    s += "  rotation (base axes, columns = tip x, y, z):\n";
    for row in m {
        s += &format!("  {:>12.8} {:>12.8} {:>12.8}\n", row[0], row[1], row[2]);
    }
    s
}

/// What `handclasp fk` prints for one pose: the robot, the joints and tip it was given, and
/// `base_from_tip` in every form ([`PoseForms`]). `--json` serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this report
/// was before it had types).
#[derive(Debug, Clone, Serialize)]
struct FkReport {
    /// `--cell`, when given (absent from the JSON otherwise).
    #[serde(skip_serializing_if = "Option::is_none")]
    cell: Option<String>,
    /// The joint values, chain order: degrees, millimetres for a prismatic joint.
    q_deg: Vec<f64>,
    /// Each value's unit (`"deg"` or `"mm"`), only for a robot with a prismatic joint (then
    /// `q_deg` mixes units).
    #[serde(skip_serializing_if = "Option::is_none")]
    q_units: Option<Vec<&'static str>>,
    /// `base_from_tip`'s unit quaternion `[w, x, y, z]`.
    quaternion_wxyz: [f64; 4],
    /// The robot's name (URDF).
    robot: String,
    /// `base_from_tip`'s rotation matrix, row-major.
    rotation: [[f64; 3]; 3],
    /// The tip offset used, flange frame, mm.
    tip_mm: [f64; 3],
    /// The flange link the chain ends at.
    tool_link: String,
    /// `base_from_tip`'s translation, mm.
    xyz_mm: [f64; 3],
    /// `base_from_tip`'s ZYZ angles (canonical branch), degrees.
    zyz_deg: [f64; 3],
}

impl FkReport {
    /// `base_from_tip` again as one value.
    fn base_from_tip(&self) -> PoseForms {
        PoseForms {
            quaternion_wxyz: self.quaternion_wxyz,
            rotation: self.rotation,
            xyz_mm: self.xyz_mm,
            zyz_deg: self.zyz_deg,
        }
    }
}

/// The text report of one pose.
fn render_text(r: &FkReport) -> String {
    let tip = r.tip_mm;
    let mut s = format!(
        "{} ({} joints), flange {}, tip ({}, {}, {}) mm in the flange frame{}\n",
        r.robot,
        r.q_deg.len(),
        r.tool_link,
        tip[0],
        tip[1],
        tip[2],
        match &r.cell {
            Some(cell) => format!(", with the errors of cell {cell}"),
            None => String::new(),
        }
    );
    s += "base_from_tip (ZYZ: R = Rz(phi)·Ry(theta)·Rz(psi)):\n";
    s += &pose_table(&r.base_from_tip());
    s
}

/// The robot that `fk` evaluates: a bare URDF, or a cell's robot with its error terms.
struct FkRobot {
    model: RobotModel,
    /// The cell's `[robotN.errors]` (zero for a bare URDF).
    errors: KinematicErrors,
    /// Gravity in the robot's nominal base frame, m/s² (the cell's; compliance only).
    g_base: Vector3<f64>,
    /// The tip offset used, m, flange frame.
    flange_from_tip: Vector3<f64>,
    /// `Some(cell path)` with --cell.
    cell: Option<PathBuf>,
}

impl FkRobot {
    /// `base_from_tip` at `q` (rad): the nominal FK for a bare URDF, the cell's true FK
    /// (`true_base_from_flange` · tip) with --cell.
    fn base_from_tip(&self, q: &[f64]) -> Result<Isometry3<f64>, kinematics::KinematicsError> {
        if self.cell.is_none() {
            return base_from_tip(&self.model, q, &self.flange_from_tip);
        }
        let base_from_flange = true_base_from_flange(&self.model, &self.errors, q, &self.g_base)?;
        Ok(base_from_flange * Translation3::from(self.flange_from_tip))
    }
}

fn load_fk_robot(args: &Args) -> anyhow::Result<FkRobot> {
    let Some(cell_path) = &args.cell else {
        let model = load_robot(Path::new(&args.robot), &args.tool_link)?;
        let flange_from_tip = parse_tip(args.tip_mm.as_deref().unwrap_or("0,0,0"))?;
        return Ok(FkRobot {
            errors: KinematicErrors::zero(model.dof()),
            model,
            g_base: Vector3::zeros(),
            flange_from_tip,
            cell: None,
        });
    };
    let which = match args.robot.trim() {
        "1" => Robot::One,
        "2" => Robot::Two,
        other => bail!(
            "--robot {other}: with --cell, --robot is the cell's robot, 1 or 2 (a URDF path is \
             for use without --cell)"
        ),
    };
    let cell = handclasp_cell::Cell::from_toml_file(cell_path)
        .with_context(|| format!("--cell {}", cell_path.display()))?;
    if which == Robot::Two && !cell.has_robot2() {
        bail!(
            "--robot 2: {} is a one-robot cell ([robot1] only); use --robot 1",
            cell_path.display()
        );
    }
    let robot = cell.robot(which);
    let flange_from_tip = if args.cell_tip {
        robot.flange_from_tip + robot.errors.tip
    } else {
        parse_tip(args.tip_mm.as_deref().unwrap_or("0,0,0"))?
    };
    Ok(FkRobot {
        model: robot.model.clone(),
        errors: robot.errors.clone(),
        g_base: robot.g_base,
        flange_from_tip,
        cell: Some(cell_path.clone()),
    })
}

/// Runs `handclasp fk`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = load_fk_robot(&args)?;
    if args.verbose {
        eprintln!("{}", ignored_branches_text(&robot.model, "--robot"));
    }
    if let Some(q_csv) = &args.q_csv {
        return run_batch(
            &robot,
            q_csv,
            args.id_column.as_deref(),
            args.out.as_deref(),
        );
    }
    let q_text = args
        .q_deg
        .as_deref()
        .context("give --q-deg (one pose) or --q-csv (with --cell)")?;
    let model = &robot.model;
    let tip = robot.flange_from_tip;
    let (q, q_deg) = parse_q_deg("--q-deg", q_text, model)?;
    let base_from_tip = robot.base_from_tip(&q).context("--q-deg")?;
    let PoseForms {
        quaternion_wxyz,
        rotation,
        xyz_mm,
        zyz_deg,
    } = PoseForms::from_isometry(&base_from_tip);
    let report = FkReport {
        cell: robot.cell.as_ref().map(|c| c.display().to_string()),
        q_deg,
        q_units: model
            .has_prismatic_joints()
            .then(|| model.joints().iter().map(joint_unit).collect()),
        quaternion_wxyz,
        robot: model.name().to_string(),
        rotation,
        tip_mm: [tip.x * 1e3, tip.y * 1e3, tip.z * 1e3],
        tool_link: model.tool_link().to_string(),
        xyz_mm,
        zyz_deg,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

/// Angles whose magnitudes all stay below this, deg, while some exceed [`RADIANS_MIN_DEG`] look
/// like radians written in a degree column (π rad = 180°, so a radian file never exceeds it).
const RADIANS_MAX_DEG: f64 = std::f64::consts::PI + 1e-9;
/// See [`RADIANS_MAX_DEG`]: below this every pose is near zero and the test means nothing, deg.
const RADIANS_MIN_DEG: f64 = 0.1;

/// `fk --q-csv`: one pose per row of `q_csv` (columns `q1_deg` … `qN_deg`; other columns ignored
/// and named on stderr, `id_column` copied first), written as `x_mm,y_mm,z_mm,qw,qx,qy,qz`
/// (`base_from_tip` in the robot's nominal base frame; the quaternion with `qw ≥ 0`, full f64
/// precision) to `out` or standard output.
///
/// Errors name the line and column: a missing or extra `qK_deg`, an empty or non-finite value,
/// an angle outside the joint's limits. A file whose angles all lie within ±π is warned about on
/// stderr as radians written as degrees.
fn run_batch(
    robot: &FkRobot,
    q_csv: &Path,
    id_column: Option<&str>,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    let name = q_csv.display().to_string();
    // A spinner on a terminal's stderr (a million poses take seconds), unless the CSV goes to
    // that terminal too.
    let show = crate::progress::shown(false)
        && (out.is_some() || !std::io::IsTerminal::is_terminal(&std::io::stdout()));
    let progress = crate::progress::Progress::new(show, "reading the joint CSV");
    let raw = kinematics::input::read_input_text(q_csv, "joint CSV")
        .with_context(|| format!("--q-csv {name}"))?;
    let text = calib_core::strip_bom(&raw);
    let mut reader = csv::ReaderBuilder::new()
        .delimiter(calib_core::csv_delimiter(text))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = reader
        .headers()
        .with_context(|| format!("{name}: cannot read the header"))?
        .iter()
        .map(str::to_string)
        .collect();
    let model = &robot.model;
    let dof = model.dof();
    // Column `qK_deg` for a rotary joint, `qK_mm` for a prismatic one (as the session file's
    // `rN_qK_mm`): the header names the unit.
    let mut q_cols = Vec::with_capacity(dof);
    for (k0, joint) in model.joints().iter().enumerate() {
        let k = k0 + 1;
        let unit = joint_unit(joint);
        let col = format!("q{k}_{unit}");
        let other = format!("q{k}_{}", if unit == "mm" { "deg" } else { "mm" });
        match header.iter().position(|h| *h == col) {
            Some(i) => q_cols.push(i),
            None if header.contains(&other) => bail!(
                "{name}: column `{other}` but joint {k} ({}) of {} is {}: name the column `{col}` and give {}",
                joint.name,
                model.name(),
                if unit == "mm" { "prismatic (a length)" } else { "rotary (an angle)" },
                if unit == "mm" { "millimetres" } else { "degrees" }
            ),
            None => bail!(
                "{name}: missing column `{col}` (header has: {}); {} has {dof} joints: give one column per joint in chain order, qK_deg for a rotary joint and qK_mm for a prismatic one",
                cap_echo(&header.join(",")),
                model.name()
            ),
        }
    }
    let extra_q: Vec<&String> = header
        .iter()
        .filter(|h| {
            h.strip_prefix('q')
                .and_then(|r| r.strip_suffix("_deg").or_else(|| r.strip_suffix("_mm")))
                .and_then(|k| k.parse::<usize>().ok())
                .is_some_and(|k| k == 0 || k > dof)
        })
        .collect();
    if let Some(col) = extra_q.first() {
        bail!(
            "{name}: column `{}` but {} has {dof} joints (q1 … q{dof}); is this the other robot's file?",
            cap_echo(col),
            model.name()
        );
    }
    let id_index = match id_column {
        None => None,
        Some(id) => Some(header.iter().position(|h| h == id).with_context(|| {
            format!(
                "{name}: no column `{id}` for --id-column (header has: {})",
                cap_echo(&header.join(","))
            )
        })?),
    };
    let ignored: Vec<&str> = header
        .iter()
        .enumerate()
        .filter(|(i, _)| !q_cols.contains(i) && Some(*i) != id_index)
        .map(|(_, h)| h.as_str())
        .collect();
    if !ignored.is_empty() {
        progress.eprintln(&format!(
            "note: {name}: ignoring column(s) {} (give one with --id-column to copy it to the output)",
            cap_echo(&ignored.join(", "))
        ));
    }

    // Two passes over the text, no row kept: the first checks every row (a bad row is refused
    // before anything is written) and finds the largest angle, the second computes and writes.
    // A file is streamed into a temporary file beside --out and renamed (never a truncated CSV
    // under --out's name; a million poses are never held in memory); stdout is streamed.
    let rows = BatchRows {
        name: &name,
        text,
        header: &header,
        q_cols: &q_cols,
        id_index,
        model,
    };
    let mut count = 0usize;
    let mut max_abs = 0.0f64;
    rows.for_each(|_, _, q_deg| {
        count += 1;
        // The radians check looks at the rotary joints only (a prismatic joint's mm can be small).
        max_abs = model
            .joints()
            .iter()
            .zip(q_deg)
            .filter(|(j, _)| !j.kind.is_prismatic())
            .fold(max_abs, |m, (_, v)| m.max(v.abs()));
        Ok(())
    })?;
    if count == 0 {
        bail!("{name}: no rows after the header; give one pose per row");
    }
    if max_abs <= RADIANS_MAX_DEG && max_abs > RADIANS_MIN_DEG {
        progress.eprintln(&format!(
            "warning: {name}: every angle is within ±{:.4} deg (largest {max_abs}): these look like radians; the columns are degrees (multiply by 180/π)",
            RADIANS_MAX_DEG
        ));
    }

    let mut head: Vec<&str> = Vec::new();
    if let Some(id) = id_column {
        head.push(id);
    }
    head.extend(["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"]);
    progress.phase(format!("computing {count} poses"));
    let write_poses = |sink: &mut dyn Write| -> anyhow::Result<()> {
        let mut writer = csv::Writer::from_writer(std::io::BufWriter::new(sink));
        writer.write_record(&head)?;
        let mut record: Vec<String> = Vec::with_capacity(8);
        rows.for_each(|line, id, q_deg| {
            let q: Vec<f64> = model
                .joints()
                .iter()
                .zip(q_deg)
                .map(|(j, &v)| from_cli_unit(j, v))
                .collect();
            let pose = robot
                .base_from_tip(&q)
                .with_context(|| format!("{name}, line {line}"))?;
            let t = pose.translation.vector * 1e3;
            let mut quat = *pose.rotation.quaternion();
            if quat.w < 0.0 {
                quat = -quat;
            }
            record.clear();
            if let Some(id) = id {
                record.push(id.to_string());
            }
            for v in [t.x, t.y, t.z, quat.w, quat.i, quat.j, quat.k] {
                record.push(v.to_string());
            }
            writer.write_record(&record)?;
            Ok(())
        })?;
        writer.flush()?;
        Ok(())
    };
    match out {
        Some(path) => handclasp_cell::output::write_atomically_with(path, write_poses)
            .with_context(|| format!("--out {}", path.display()))?,
        None => write_poses(&mut std::io::stdout().lock())?,
    }
    progress.finish();
    if let Some(path) = out {
        eprintln!("wrote {count} poses to {}", path.display());
    }
    Ok(())
}

/// The rows of `fk --q-csv`'s joint CSV, read from its text as often as needed (no row is kept).
struct BatchRows<'a> {
    name: &'a str,
    text: &'a str,
    header: &'a [String],
    q_cols: &'a [usize],
    id_index: Option<usize>,
    model: &'a RobotModel,
}

impl BatchRows<'_> {
    /// Calls `f(line, id, q_deg)` for each row in order (line numbers 1-based, the header is
    /// line 1), after checking each angle: a number, finite, inside its joint's limits.
    ///
    /// # Errors
    /// The first malformed row (naming the file, line and column, and the fix), or `f`'s error.
    fn for_each(
        &self,
        mut f: impl FnMut(usize, Option<&str>, &[f64]) -> anyhow::Result<()>,
    ) -> anyhow::Result<()> {
        let name = self.name;
        let mut reader = csv::ReaderBuilder::new()
            .delimiter(calib_core::csv_delimiter(self.text))
            .trim(csv::Trim::All)
            .from_reader(self.text.as_bytes());
        let mut q_deg = Vec::with_capacity(self.q_cols.len());
        for (i, record) in reader.records().enumerate() {
            let line = i + 2;
            let record = record.with_context(|| format!("{name}, line {line}: malformed CSV"))?;
            q_deg.clear();
            for (k, &c) in self.q_cols.iter().enumerate() {
                let cell = record.get(c).unwrap_or("");
                let col = &self.header[c];
                let v: f64 = cell.parse().map_err(|_| {
                    anyhow::anyhow!("{name}, line {line}, column `{col}`: `{}` is not a number; give the joint's value in the column's unit (deg, or mm for a prismatic joint)", cap_echo(cell))
                })?;
                if !v.is_finite() {
                    bail!("{name}, line {line}, column `{col}`: {cell} is not a finite value");
                }
                let joint = &self.model.joints()[k];
                check_joint_value(&format!("{name}, line {line}, column `{col}`"), k, joint, v)?;
                q_deg.push(v);
            }
            let id = self.id_index.map(|c| record.get(c).unwrap_or(""));
            f(line, id, &q_deg)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(cell: Option<&str>) -> FkReport {
        let pose = PoseForms::from_isometry(&Isometry3::translation(1.0, -0.25, 0.5));
        FkReport {
            cell: cell.map(String::from),
            q_deg: vec![0.0; 6],
            q_units: None,
            quaternion_wxyz: pose.quaternion_wxyz,
            robot: "hp20".into(),
            rotation: pose.rotation,
            tip_mm: [0.0, 0.0, 150.0],
            tool_link: "tool0".into(),
            xyz_mm: pose.xyz_mm,
            zyz_deg: pose.zyz_deg,
        }
    }

    #[test]
    fn text_of_one_pose() {
        let text = render_text(&report(Some("cells/x.toml")));
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "hp20 (6 joints), flange tool0, tip (0, 0, 150) mm in the flange frame, with the errors of cell cells/x.toml"
        );
        assert_eq!(
            lines[1],
            "base_from_tip (ZYZ: R = Rz(phi)·Ry(theta)·Rz(psi)):"
        );
        assert_eq!(
            lines[3],
            format!(
                "  {:>12.4} {:>12.4} {:>12.4} {:>12.5} {:>12.5} {:>12.5}",
                1000.0, -250.0, 500.0, 0.0, 0.0, 0.0
            )
        );
        assert_eq!(lines.len(), 8);
        assert!(render_text(&report(None)).starts_with(
            "hp20 (6 joints), flange tool0, tip (0, 0, 150) mm in the flange frame\n"
        ));
    }

    /// The JSON's keys in the order of the `serde_json::Value` it was; `cell` only with --cell.
    #[test]
    fn json_keys_in_value_order() {
        for cell in [None, Some("c.toml")] {
            let json = crate::test_support::json_in_value_order(&report(cell));
            assert_eq!(json.contains("\"cell\""), cell.is_some());
        }
    }
}

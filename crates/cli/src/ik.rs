//! `handclasp ik`: a tip position in the robot's base frame (mm) to joint angles (deg), within the
//! joint limits, optionally with the flange z axis along a given direction (`--axis`, base frame;
//! in a handclasp the two tips meet head-on).
//!
//! `handclasp ik --robot robots/hp20.urdf --xyz-mm 1000,300,800 --tip-mm 0,0,150 [--axis 1,0,0]
//! [--json]` prints `{"reachable": bool, "q_deg": […], …}`. An unreachable target is a result
//! (`"reachable": false`, exit status 0, `q_deg` the closest joint vector found), not an error.
//! A target whose every coordinate is below calib-core's `METRES_LIMIT_MM` (5 mm) is refused as
//! metres written as millimetres, and so is a `--tip-mm` below 5 mm in every coordinate.
//! A prismatic joint's value (a track, a lift) is in millimetres, in `q_deg` as in the table;
//! the JSON then names each value's unit in `q_units`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{bail, Context};
use calib_core::PoseForms;
use kinematics::{base_from_tip, ik_tip_position, IkOptions};
use nalgebra::{Point3, Unit, Vector3};
use serde::Serialize;

use crate::fk::{
    ignored_branches_text, joint_unit, load_robot, parse_list, parse_q_deg, parse_tip, pose_table,
    to_cli_unit,
};

/// Arguments of `handclasp ik`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The robot's URDF file (e.g. robots/hp20.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// The flange link the chain ends at.
    #[arg(long, default_value = "tool0")]
    pub tool_link: String,
    /// Target tip position in the base frame, mm: x,y,z.
    #[arg(long, allow_hyphen_values = true)]
    pub xyz_mm: String,
    /// Tip offset in the flange frame, mm: x,y,z (0,0,150 = a 150 mm pin along the flange z;
    /// a tip below 5 mm in every coordinate is refused as metres).
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub tip_mm: String,
    /// Desired direction of the flange z axis in the base frame: x,y,z (any length > 0).
    #[arg(long, allow_hyphen_values = true)]
    pub axis: Option<String>,
    /// Joint angles (deg) the solver starts from and, for a 7-axis arm, the posture the
    /// redundant freedom is pulled toward. Default: all zero (clamped into the limits).
    #[arg(long, allow_hyphen_values = true)]
    pub preferred_deg: Option<String>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Also list (on stderr) the URDF joints and links outside the base-to-flange chain, which
    /// are ignored.
    #[arg(long)]
    pub verbose: bool,
}

/// Runs `handclasp ik`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = load_robot(&args.robot, &args.tool_link)?;
    if args.verbose {
        eprintln!("{}", ignored_branches_text(&model, "--robot"));
    }
    let tip = parse_tip(&args.tip_mm)?;
    let xyz = parse_list(
        "--xyz-mm",
        &args.xyz_mm,
        Some((3, "a target position has 3 (x,y,z in mm)")),
    )?;
    if xyz.iter().all(|c| c.abs() < calib_core::METRES_LIMIT_MM) {
        bail!(
            "--xyz-mm {} is within {} mm of the base origin, inside the robot's base: these look like metres; \
             --xyz-mm is in millimetres, so multiply by 1000 (--xyz-mm {},{},{})",
            args.xyz_mm,
            calib_core::METRES_LIMIT_MM,
            xyz[0] * 1000.0,
            xyz[1] * 1000.0,
            xyz[2] * 1000.0
        );
    }
    let target = Point3::new(xyz[0], xyz[1], xyz[2]) * 1e-3;
    let axis = match &args.axis {
        None => None,
        Some(text) => {
            let a = parse_list("--axis", text, Some((3, "a direction has 3 (x,y,z)")))?;
            let v = Vector3::new(a[0], a[1], a[2]);
            if v.norm() < 1e-12 {
                bail!("--axis {text} is the zero vector; give a direction such as 0,0,-1");
            }
            Some(Unit::new_normalize(v))
        }
    };
    let preferred = match &args.preferred_deg {
        None => None,
        Some(text) => Some(parse_q_deg("--preferred-deg", text, &model)?.0),
    };
    let options = IkOptions {
        tool_axis_base: axis,
        preferred_q: preferred,
        ..IkOptions::default()
    };
    let sol = ik_tip_position(&model, &target, &tip, &options).context("ik")?;
    // Degrees, and millimetres for a prismatic joint.
    let q_deg: Vec<f64> = model
        .joints()
        .iter()
        .zip(&sol.q)
        .map(|(j, &x)| to_cli_unit(j, x))
        .collect();
    // `q_deg` mixes units when a joint is prismatic: then the report says each one.
    let q_units = model
        .has_prismatic_joints()
        .then(|| model.joints().iter().map(joint_unit).collect());
    let reached = base_from_tip(&model, &sol.q, &tip).context("ik result")?;
    let report = IkReport {
        axis_error_deg: sol.axis_error_rad.to_degrees(),
        iterations: sol.iterations,
        position_error_mm: sol.position_error_m * 1e3,
        q_deg,
        q_units,
        reachable: sol.reachable(),
        reached: PoseForms::from_isometry(&reached),
        robot: model.name().to_string(),
        target_xyz_mm: xyz,
        tip_mm: [tip.x * 1e3, tip.y * 1e3, tip.z * 1e3],
        tool_link: model.tool_link().to_string(),
        axis_given: axis.is_some(),
        joint_names: model.joints().iter().map(|j| j.name.clone()).collect(),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(())
}

/// What `handclasp ik` prints: the solution, its errors and the pose it reaches, with the robot,
/// target and tip it was given. `--json` serialises it; [`render_text`] reads it.
///
/// Fields in alphabetical order: the JSON key order (that of the `serde_json::Value` this report
/// was before it had types); the two text-only fields at the end are not serialised.
#[derive(Debug, Clone, Serialize)]
struct IkReport {
    /// Angle between the flange z axis and `--axis`, degrees (0 without `--axis`).
    axis_error_deg: f64,
    /// Solver iterations.
    iterations: usize,
    /// Distance from the tip to the target, mm.
    position_error_mm: f64,
    /// The joint values found (the closest found when unreachable): degrees, millimetres for a
    /// prismatic joint.
    q_deg: Vec<f64>,
    /// Each value's unit (`"deg"` or `"mm"`), only for a robot with a prismatic joint.
    #[serde(skip_serializing_if = "Option::is_none")]
    q_units: Option<Vec<&'static str>>,
    /// Whether the target is reached within the joint limits.
    reachable: bool,
    /// `base_from_tip` at `q_deg`.
    reached: PoseForms,
    /// The robot's name (URDF).
    robot: String,
    /// `--xyz-mm`.
    target_xyz_mm: Vec<f64>,
    /// The tip offset, flange frame, mm.
    tip_mm: [f64; 3],
    /// The flange link the chain ends at.
    tool_link: String,
    /// Whether `--axis` was given (text only).
    #[serde(skip)]
    axis_given: bool,
    /// The chain's joint names (text only).
    #[serde(skip)]
    joint_names: Vec<String>,
}

/// The text report.
fn render_text(r: &IkReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &IkReport) -> std::fmt::Result {
    let xyz = &r.target_xyz_mm;
    if r.reachable {
        writeln!(
            s,
            "{}: target ({}, {}, {}) mm reached (error {:.2e} mm{}).",
            r.robot,
            xyz[0],
            xyz[1],
            xyz[2],
            r.position_error_mm,
            if r.axis_given {
                format!(", axis error {:.2e} deg", r.axis_error_deg)
            } else {
                String::new()
            }
        )?;
    } else {
        writeln!(
            s,
            "{}: target ({}, {}, {}) mm is UNREACHABLE within the joint limits{}; closest found: {:.3} mm away{}.",
            r.robot,
            xyz[0],
            xyz[1],
            xyz[2],
            if r.axis_given { " with that axis" } else { "" },
            r.position_error_mm,
            if r.axis_given {
                format!(", axis {:.3} deg off", r.axis_error_deg)
            } else {
                String::new()
            }
        )?;
    }
    match &r.q_units {
        Some(units) => {
            writeln!(s, "  {:>4} {:>14} {:>12} {:>4}", "#", "joint", "q", "unit")?;
            let rows = r.joint_names.iter().zip(&r.q_deg).zip(units);
            for (i, ((name, v), unit)) in rows.enumerate() {
                writeln!(s, "  {:>4} {:>14} {:>12.6} {:>4}", i + 1, name, v, unit)?;
            }
        }
        None => {
            writeln!(s, "  {:>4} {:>14} {:>12}", "#", "joint", "q_deg")?;
            for (i, (name, v)) in r.joint_names.iter().zip(&r.q_deg).enumerate() {
                writeln!(s, "  {:>4} {:>14} {:>12.6}", i + 1, name, v)?;
            }
        }
    }
    writeln!(s, "tip pose at these angles:")?;
    write!(s, "{}", pose_table(&r.reached))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    fn report(reachable: bool, axis_given: bool) -> IkReport {
        IkReport {
            axis_error_deg: 0.5,
            iterations: 12,
            position_error_mm: if reachable { 1e-6 } else { 812.5 },
            q_deg: vec![10.0, -20.0],
            q_units: None,
            reachable,
            reached: PoseForms::from_isometry(&Isometry3::identity()),
            robot: "hp20".into(),
            target_xyz_mm: vec![1200.0, 0.0, 900.5],
            tip_mm: [0.0, 0.0, 150.0],
            tool_link: "tool0".into(),
            axis_given,
            joint_names: vec!["joint_1".into(), "joint_2".into()],
        }
    }

    #[test]
    fn text_of_a_reached_and_an_unreachable_target() {
        let text = render_text(&report(true, true));
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "hp20: target (1200, 0, 900.5) mm reached (error 1.00e-6 mm, axis error 5.00e-1 deg)."
        );
        assert_eq!(
            lines[2],
            format!("  {:>4} {:>14} {:>12.6}", 1, "joint_1", 10.0)
        );
        assert_eq!(lines[4], "tip pose at these angles:");
        let text = render_text(&report(false, false));
        assert!(text.starts_with(
            "hp20: target (1200, 0, 900.5) mm is UNREACHABLE within the joint limits; closest found: 812.500 mm away.\n"
        ));
        let text = render_text(&report(false, true));
        assert!(text.starts_with(
            "hp20: target (1200, 0, 900.5) mm is UNREACHABLE within the joint limits with that axis; closest found: 812.500 mm away, axis 0.500 deg off.\n"
        ));
    }

    /// The JSON's keys in the order of the `serde_json::Value` it was; the text-only fields are
    /// not serialised.
    #[test]
    fn json_keys_in_value_order() {
        let json = crate::test_support::json_in_value_order(&report(true, true));
        assert!(!json.contains("joint_names") && !json.contains("axis_given"));
    }
}

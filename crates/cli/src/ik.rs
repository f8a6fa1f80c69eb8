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

use std::path::PathBuf;

use anyhow::{bail, Context};
use kinematics::{base_from_tip, ik_tip_position, IkOptions};
use nalgebra::{Point3, Unit, Vector3};
use serde_json::json;

use crate::fk::{
    ignored_branches_text, joint_unit, load_robot, parse_list, parse_q_deg, parse_tip, pose_json,
    pose_table, to_cli_unit,
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
    /// Joint angles (deg; mm for a prismatic joint) the solver starts from and, for a 7-axis
    /// arm, the posture the redundant freedom is pulled toward. Default: all zero (clamped into
    /// the limits).
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
    let units: Vec<&str> = model.joints().iter().map(joint_unit).collect();
    let prismatic = model.has_prismatic_joints();
    let reached = base_from_tip(&model, &sol.q, &tip).context("ik result")?;
    if args.json {
        let mut v = json!({
            "reachable": sol.reachable(),
            "q_deg": q_deg,
            "position_error_mm": sol.position_error_m * 1e3,
            "axis_error_deg": sol.axis_error_rad.to_degrees(),
            "iterations": sol.iterations,
            "robot": model.name(),
            "tool_link": model.tool_link(),
            "target_xyz_mm": xyz,
            "tip_mm": [tip.x * 1e3, tip.y * 1e3, tip.z * 1e3],
            "reached": pose_json(&reached),
        });
        if prismatic {
            // `q_deg` then mixes units: say each one.
            v["q_units"] = json!(units);
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        if sol.reachable() {
            println!(
                "{}: target ({}, {}, {}) mm reached (error {:.2e} mm{}).",
                model.name(),
                xyz[0],
                xyz[1],
                xyz[2],
                sol.position_error_m * 1e3,
                if axis.is_some() {
                    format!(", axis error {:.2e} deg", sol.axis_error_rad.to_degrees())
                } else {
                    String::new()
                }
            );
        } else {
            println!(
                "{}: target ({}, {}, {}) mm is UNREACHABLE within the joint limits{}; closest found: {:.3} mm away{}.",
                model.name(),
                xyz[0],
                xyz[1],
                xyz[2],
                if axis.is_some() { " with that axis" } else { "" },
                sol.position_error_m * 1e3,
                if axis.is_some() {
                    format!(", axis {:.3} deg off", sol.axis_error_rad.to_degrees())
                } else {
                    String::new()
                }
            );
        }
        if prismatic {
            println!("  {:>4} {:>14} {:>12} {:>4}", "#", "joint", "q", "unit");
            for (i, ((j, v), unit)) in model.joints().iter().zip(&q_deg).zip(&units).enumerate() {
                println!("  {:>4} {:>14} {:>12.6} {:>4}", i + 1, j.name, v, unit);
            }
        } else {
            println!("  {:>4} {:>14} {:>12}", "#", "joint", "q_deg");
            for (i, (j, v)) in model.joints().iter().zip(&q_deg).enumerate() {
                println!("  {:>4} {:>14} {:>12.6}", i + 1, j.name, v);
            }
        }
        println!("tip pose at these angles:");
        print!("{}", pose_table(&reached));
    }
    Ok(())
}

//! `handclasp fk`: joint angles (deg) to the tip pose in the robot's base frame, as a pendant
//! shows it: x, y, z in mm and ZYZ φ, θ, ψ in degrees (`R = Rz(φ)·Ry(θ)·Rz(ψ)`).
//!
//! `handclasp fk --robot robots/hp20.urdf --q-deg 0,10,-20,0,30,0 --tip-mm 0,0,150 --json` prints
//! `{"xyz_mm": [x, y, z], "zyz_deg": [φ, θ, ψ], "rotation": [[…], […], […]], …}` for
//! `base_from_tip`; without `--json` a readable table.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use kinematics::{base_from_tip, zyz_from_rotation, ModelError, RobotModel};
use nalgebra::{Isometry3, Vector3};
use serde_json::{json, Value};

/// Arguments of `handclasp fk`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The robot's URDF file (e.g. robots/hp20.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// The flange link the chain ends at.
    #[arg(long, default_value = "tool0")]
    pub tool_link: String,
    /// Joint angles in degrees, comma separated, in chain order from the base (one per joint).
    #[arg(long, allow_hyphen_values = true)]
    pub q_deg: String,
    /// Tip offset in the flange frame, mm: x,y,z (the measuring pin; 0,0,150 = 150 mm along the
    /// flange z axis).
    #[arg(long, default_value = "0,0,0", allow_hyphen_values = true)]
    pub tip_mm: String,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
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

/// Parses `--tip-mm` (x,y,z mm) into metres.
pub(crate) fn parse_tip(text: &str) -> anyhow::Result<Vector3<f64>> {
    let v = parse_list(
        "--tip-mm",
        text,
        Some((3, "a tip offset has 3 (x,y,z in mm)")),
    )?;
    Ok(Vector3::new(v[0], v[1], v[2]) * 1e-3)
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

/// Parses `--q-deg` against the model: count and joint limits (in degrees). Returns
/// `(q_rad, q_deg)`.
pub(crate) fn parse_q_deg(
    flag: &str,
    text: &str,
    model: &RobotModel,
) -> anyhow::Result<(Vec<f64>, Vec<f64>)> {
    let what = format!("{} has {} joints", model.name(), model.dof());
    let q_deg = parse_list(flag, text, Some((model.dof(), &what)))?;
    for (i, (j, &v)) in model.joints().iter().zip(&q_deg).enumerate() {
        let (lo, hi) = (j.lower.to_degrees(), j.upper.to_degrees());
        // Same 1e-9 rad slack as the library's check.
        let slack = 1e-9f64.to_degrees();
        if v < lo - slack || v > hi + slack {
            bail!(
                "{flag}: joint {} ({}) is {v} deg, outside its limits {lo:.3}..{hi:.3} deg; give an angle inside the range (degrees, not radians)",
                i + 1,
                j.name
            );
        }
    }
    Ok((q_deg.iter().map(|v| v.to_radians()).collect(), q_deg))
}

/// JSON of a pose: `xyz_mm`, `zyz_deg`, `rotation` (row-major 3×3), `quaternion_wxyz`.
pub(crate) fn pose_json(base_from_tip: &Isometry3<f64>) -> Value {
    let t = base_from_tip.translation.vector * 1e3;
    let r = base_from_tip.rotation.to_rotation_matrix();
    let zyz = zyz_from_rotation(&r);
    let m = r.matrix();
    let q = base_from_tip.rotation;
    json!({
        "xyz_mm": [t.x, t.y, t.z],
        "zyz_deg": [zyz[0].to_degrees(), zyz[1].to_degrees(), zyz[2].to_degrees()],
        "rotation": [
            [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
            [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
            [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
        ],
        "quaternion_wxyz": [q.w, q.i, q.j, q.k],
    })
}

/// Readable lines of a pose (mm, deg, rotation rows).
pub(crate) fn pose_table(base_from_tip: &Isometry3<f64>) -> String {
    let t = base_from_tip.translation.vector * 1e3;
    let r = base_from_tip.rotation.to_rotation_matrix();
    let zyz = zyz_from_rotation(&r).map(f64::to_degrees);
    let m = r.matrix();
    let mut s = String::new();
    s += &format!(
        "  {:>12} {:>12} {:>12} {:>12} {:>12} {:>12}\n",
        "x_mm", "y_mm", "z_mm", "phi_deg", "theta_deg", "psi_deg"
    );
    s += &format!(
        "  {:>12.4} {:>12.4} {:>12.4} {:>12.5} {:>12.5} {:>12.5}\n",
        t.x, t.y, t.z, zyz[0], zyz[1], zyz[2]
    );
    s += "  rotation (base axes, columns = tip x, y, z):\n";
    for row in 0..3 {
        s += &format!(
            "  {:>12.8} {:>12.8} {:>12.8}\n",
            m[(row, 0)],
            m[(row, 1)],
            m[(row, 2)]
        );
    }
    s
}

/// Runs `handclasp fk`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let model = load_robot(&args.robot, &args.tool_link)?;
    let tip = parse_tip(&args.tip_mm)?;
    let (q, q_deg) = parse_q_deg("--q-deg", &args.q_deg, &model)?;
    let base_from_tip = base_from_tip(&model, &q, &tip).context("--q-deg")?;
    if args.json {
        let mut v = pose_json(&base_from_tip);
        v["robot"] = json!(model.name());
        v["tool_link"] = json!(model.tool_link());
        v["q_deg"] = json!(q_deg);
        v["tip_mm"] = json!([tip.x * 1e3, tip.y * 1e3, tip.z * 1e3]);
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        println!(
            "{} ({} joints), flange {}, tip ({}, {}, {}) mm in the flange frame",
            model.name(),
            model.dof(),
            model.tool_link(),
            tip.x * 1e3,
            tip.y * 1e3,
            tip.z * 1e3
        );
        println!("base_from_tip (ZYZ: R = Rz(phi)·Ry(theta)·Rz(psi)):");
        print!("{}", pose_table(&base_from_tip));
    }
    Ok(())
}

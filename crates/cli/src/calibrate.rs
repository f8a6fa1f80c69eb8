//! `handclasp calibrate POINTS.csv`: fit `b1_from_b2` from handclasp points.
//!
//! Input: a CSV with `r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm` (any order, other columns
//! ignored; a sim-cell session file works as it stands). Output: `b1_from_b2` as x, y, z (mm) and
//! ZYZ φ, θ, ψ (deg, the controller's convention), the rotation matrix, the quaternion, per-point
//! residuals (mm), the conditioning, the predicted uncertainty and leave-one-out outlier flags.
//!
//! Default method: `constrained` when mounts are given, otherwise `lsq`.

use anyhow::{bail, Context};
use calib_core::{
    constrained_soft, explain_misfit, fit, leave_one_out, median_residual_m, mount_check,
    read_points_csv, zyz_canonical, Fit, Method, Mount, MountPair, PointPairs, MOUNT_CHECK_ALPHA,
};
use serde_json::{json, Value};
use std::path::PathBuf;

/// Arguments of `handclasp calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// CSV of handclasp points (mm): columns r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm.
    /// Required unless --cell is given.
    #[arg(required_unless_present = "cell", conflicts_with = "cell")]
    pub points: Option<PathBuf>,
    /// Whole-cell calibration: the cell TOML (robots, tips, noise, [robotN.tolerance]).
    #[arg(long, requires = "session", conflicts_with_all = ["mounts", "mount1", "mount2", "method", "tilt_sigma_deg"])]
    pub cell: Option<PathBuf>,
    /// With --cell: the session CSV (point, r1_q*_deg, r2_q*_deg, r1_x_mm … r2_z_mm).
    #[arg(long, requires = "cell")]
    pub session: Option<PathBuf>,
    /// With --cell: kinematic (b1_from_b2 and every identifiable kinematic parameter of both
    /// robots, MAP with the cell's tolerances) or placement (b1_from_b2 only).
    #[arg(long, requires = "cell", value_enum, default_value = "kinematic")]
    pub model: crate::calibrate_cell::ModelArg,
    /// With --cell: write DIR/cell.toml, DIR/robot1.urdf and DIR/robot2.urdf (the calibrated cell).
    /// DIR must be new or empty, unless --force (files of the same names are overwritten).
    #[arg(long, requires = "cell")]
    pub export: Option<PathBuf>,
    /// The paper's cells: floor-floor, floor-wall or floor-ceiling (robot 1 is on the floor).
    #[arg(long, conflicts_with_all = ["mount1", "mount2"])]
    pub mounts: Option<String>,
    /// Robot 1's mount: floor, ceiling, wall or tilt:RX,RY (degrees; level_from_base = Rx·Ry).
    #[arg(long, requires = "mount2")]
    pub mount1: Option<String>,
    /// Robot 2's mount: floor, ceiling, wall or tilt:RX,RY (degrees; level_from_base = Rx·Ry).
    #[arg(long, requires = "mount1")]
    pub mount2: Option<String>,
    /// generic | generic-affine | paper | lsq | constrained | all. Default: constrained when mounts
    /// are given, else lsq.
    #[arg(long)]
    pub method: Option<String>,
    /// Soft mount for `constrained`: prior σ of the mount tilt, degrees. The fit then estimates the
    /// actual tilt instead of imposing the nominal one.
    #[arg(long)]
    pub tilt_sigma_deg: Option<f64>,
    /// Point noise σ per coordinate for the soft mount, mm.
    #[arg(long, default_value_t = 0.5)]
    pub point_sigma_mm: f64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Expected handclasp alignment noise, mm: a fit whose median residual norm exceeds it fails
    /// with the likely data mistake (rows out of order, swapped axes, wrong units, wrong robot
    /// order) and the worst rows, unless --force is given.
    #[arg(long, default_value_t = calib_core::DEFAULT_EXPECTED_NOISE_M * 1e3)]
    pub expected_noise_mm: f64,
    /// Keep a fit whose residuals exceed --expected-noise-mm (a warning is printed on stderr);
    /// with --cell --export, write into a non-empty folder.
    #[arg(long)]
    pub force: bool,
    /// With --cell: also list (on stderr) each URDF's joints and links outside the
    /// base-to-flange chain, which are ignored.
    #[arg(long, requires = "cell")]
    pub verbose: bool,
}

/// Validated configuration.
struct Config {
    points: PathBuf,
    mounts: Option<MountPair>,
    methods: Vec<Method>,
    all: bool,
    json: bool,
    soft: Option<(f64, f64)>,
    /// Expected alignment noise, m (`--expected-noise-mm`).
    expected_noise_m: f64,
    force: bool,
}

fn config(args: Args) -> anyhow::Result<Config> {
    let mounts = match (&args.mounts, &args.mount1, &args.mount2) {
        (Some(m), _, _) => {
            Some(MountPair::parse_paper(m).context("--mounts (or give --mount1 and --mount2)")?)
        }
        (None, Some(a), Some(b)) => Some(MountPair {
            robot1: Mount::parse(a).context("--mount1")?,
            robot2: Mount::parse(b).context("--mount2")?,
        }),
        _ => None,
    };
    let method_text = args.method.clone().unwrap_or_else(|| {
        if mounts.is_some() {
            "constrained".into()
        } else {
            "lsq".into()
        }
    });
    let (methods, all) = if method_text == "all" {
        if mounts.is_some() {
            (
                vec![
                    Method::Generic,
                    Method::GenericAffine,
                    Method::Paper,
                    Method::Lsq,
                    Method::Constrained,
                ],
                true,
            )
        } else {
            (
                vec![Method::Generic, Method::GenericAffine, Method::Lsq],
                true,
            )
        }
    } else {
        let Some(m) = Method::from_name(&method_text) else {
            bail!(
                "--method {method_text}: unknown method; use generic, generic-affine, paper, lsq, constrained or all"
            );
        };
        (vec![m], false)
    };
    if mounts.is_none()
        && methods
            .iter()
            .any(|m| matches!(m, Method::Paper | Method::Constrained))
    {
        bail!(
            "--method {method_text} needs the installation: give --mounts floor-floor|floor-wall|floor-ceiling, or --mount1 and --mount2"
        );
    }
    let soft = match args.tilt_sigma_deg {
        None => None,
        Some(t) => {
            if !methods.contains(&Method::Constrained) {
                bail!("--tilt-sigma-deg applies to --method constrained (or all)");
            }
            let valid = |v: f64| v.is_finite() && v > 0.0;
            if !valid(t) || !valid(args.point_sigma_mm) {
                bail!("--tilt-sigma-deg and --point-sigma-mm must be finite and > 0");
            }
            Some((t.to_radians(), args.point_sigma_mm * 1e-3))
        }
    };
    if !(args.expected_noise_mm.is_finite() && args.expected_noise_mm > 0.0) {
        bail!(
            "--expected-noise-mm {}: must be finite and > 0 (the handclasp alignment noise, mm)",
            args.expected_noise_mm
        );
    }
    let points = args
        .points
        .context("give the points CSV (or --cell CELL --session SESSION)")?;
    Ok(Config {
        expected_noise_m: args.expected_noise_mm * 1e-3,
        force: args.force,
        soft,
        points,
        mounts,
        methods,
        all,
        json: args.json,
    })
}

/// Runs `handclasp calibrate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.cell.is_some() {
        return crate::calibrate_cell::run(args);
    }
    let cfg = config(args)?;
    let pairs = read_points_csv(&cfg.points)?;
    let mounts = cfg.mounts.unwrap_or_else(MountPair::floor_floor);
    if !cfg.all {
        let method = cfg.methods[0];
        let out = fit_report(&pairs, method, &mounts, &cfg)
            .with_context(|| format!("{}: method {}", cfg.points.display(), method.name()))?;
        if cfg.json {
            println!("{}", serde_json::to_string_pretty(&out)?);
        } else {
            print_text(&out);
        }
        return Ok(());
    }
    let mut methods = serde_json::Map::new();
    for &m in &cfg.methods {
        let v = match fit_report(&pairs, m, &mounts, &cfg) {
            Ok(v) => v,
            Err(e) => json!({"method": m.name(), "error": format!("{e:#}")}),
        };
        methods.insert(m.name().to_string(), v);
    }
    if cfg.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({"methods": methods}))?
        );
    } else {
        for v in methods.values() {
            print_text(v);
            println!();
        }
    }
    Ok(())
}

/// Fits one method (the soft-mount variant for `constrained` when asked) and builds its report.
/// The methods that impose the mounts also get the mounts' F-test against the points.
fn fit_report(
    pairs: &PointPairs,
    method: Method,
    mounts: &MountPair,
    cfg: &Config,
) -> anyhow::Result<Value> {
    let mut v = if let (Method::Constrained, Some((tilt_sigma, point_sigma))) = (method, cfg.soft) {
        let soft = constrained_soft(pairs, mounts, tilt_sigma, point_sigma)?;
        plausible(pairs, &soft.fit, mounts, cfg)?;
        let mut v = report(pairs, &soft.fit, cfg.mounts.as_ref());
        v["soft_mount"] = json!({
            "tilt_sigma_deg": tilt_sigma.to_degrees(),
            "point_sigma_mm": point_sigma * 1e3,
            "tilt_estimate_deg": soft.tilt_angle_rad.to_degrees(),
            "tilt_vector_deg_b1": [soft.tilt_rad.x.to_degrees(), soft.tilt_rad.y.to_degrees(), soft.tilt_rad.z.to_degrees()],
        });
        v
    } else {
        let f = fit(pairs, method, mounts)?;
        plausible(pairs, &f, mounts, cfg)?;
        report(pairs, &f, cfg.mounts.as_ref())
    };
    if matches!(method, Method::Paper | Method::Constrained) && cfg.mounts.is_some() {
        // Fewer than 3 usable points already failed the fit above; anything else is reported.
        if let Ok(c) = mount_check(pairs, mounts) {
            v["mount_check"] = json!({
                "consistent": c.consistent(),
                "alpha": MOUNT_CHECK_ALPHA,
                "f_statistic": c.f_statistic,
                "p_value": c.p_value,
                "constraints": c.constraints,
                "dof": c.dof_free,
                "rotation_gap_deg": c.rotation_gap_rad.to_degrees(),
                "rms_constrained_mm": mm((c.rss_constrained_m2 / pairs.len() as f64).sqrt()),
                "rms_free_mm": mm((c.rss_free_m2 / pairs.len() as f64).sqrt()),
            });
        }
    }
    Ok(v)
}

/// Rows listed as the worst in a misfit error.
const WORST_ROWS: usize = 5;

/// Fails when the fit's median residual norm exceeds the expected alignment noise: such residuals
/// come from a data mistake, not from noise. The error names each mistake whose correction, refitted,
/// brings the median back below the noise ([`calib_core::explain_misfit`]; ties cannot be told apart
/// and are listed together), and the worst rows. With `--force` it only warns on stderr. For the
/// methods that impose mounts it fails only when the free rigid fit is implausible too (otherwise
/// the mounts are wrong, and the mount check says so).
fn plausible(pairs: &PointPairs, f: &Fit, mounts: &MountPair, cfg: &Config) -> anyhow::Result<()> {
    let median = median_residual_m(f);
    if median <= cfg.expected_noise_m {
        return Ok(());
    }
    // With imposed mounts: if the free rigid fit agrees with the noise, the points are fine and
    // the mounts are wrong, which the mount check reports (with its advice) instead.
    if matches!(f.method, Method::Paper | Method::Constrained) {
        if let Ok(free) = fit(pairs, Method::Lsq, mounts) {
            if median_residual_m(&free) <= cfg.expected_noise_m {
                return Ok(());
            }
        }
    }
    let mut worst: Vec<(usize, f64)> = f
        .residuals
        .iter()
        .enumerate()
        .map(|(i, r)| (pairs.row(i), r.norm()))
        .collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1));
    let worst_txt = worst
        .iter()
        .take(WORST_ROWS)
        .map(|(row, r)| format!("row {row} ({} mm)", mm_text(r * 1e3)))
        .collect::<Vec<_>>()
        .join(", ");
    let found = explain_misfit(pairs, f.method, mounts, cfg.expected_noise_m);
    let cause = match found.first() {
        Some(&(_, best)) => {
            // Equal medians (to 1 %) are the same correction seen differently (e.g. any reflection
            // of one robot's axes under a free rotation): list them together.
            let tied: Vec<String> = found
                .iter()
                .filter(|c| c.1 <= best * 1.01 + 1e-12)
                .map(|c| c.0.to_string())
                .collect();
            format!(
                "likely cause (refitting with it corrected gives median {:.3} mm): {}",
                best * 1e3,
                tied.join("; or ")
            )
        }
        None => "none of the checked causes explains it (rows shifted by ±1–3, one robot's axes swapped or negated, one robot ×1000 or ×0.001, robots swapped); check the recording and the mounts".into(),
    };
    let msg = format!(
        "the residuals are far beyond the alignment noise: median |r| {} mm > expected {} mm (--expected-noise-mm), residual RMS {} mm; {cause}; worst rows: {worst_txt}. Fix the file, or raise --expected-noise-mm, or give --force to keep this fit",
        mm_text(median * 1e3),
        mm_text(cfg.expected_noise_m * 1e3),
        mm_text(f.residual_rms_m() * 1e3)
    );
    if cfg.force {
        eprintln!("WARNING ({}, kept by --force): {msg}", f.method.name());
        return Ok(());
    }
    bail!("{msg}")
}

/// A length in mm for a message: 3 decimals, scientific notation from 1e6 mm.
fn mm_text(v_mm: f64) -> String {
    if v_mm.abs() < 1e6 {
        format!("{v_mm:.3}")
    } else {
        format!("{v_mm:.3e}")
    }
}

/// The text of a failed mount check: what the points say and what to do about it.
fn mount_warning(c: &Value) -> Option<String> {
    if c["consistent"].as_bool() != Some(false) {
        return None;
    }
    let gap = c["rotation_gap_deg"].as_f64().unwrap_or(f64::NAN);
    let advice = if gap > 2.0 {
        "the mounts look wrong: check --mounts, or the sign and axis of --mount1/--mount2 tilt:RX,RY"
    } else {
        "the mount is nominal only: use --tilt-sigma-deg to estimate the actual tilt, or method lsq"
    };
    Some(format!(
        "WARNING: the points disagree with the mounts (F = {:.1}, p = {:.1e} < {}): the free rigid fit is {gap:.3}° from the nearest rotation they allow, and imposing them raises the residual RMS from {:.3} to {:.3} mm; {advice}",
        c["f_statistic"].as_f64().unwrap_or(f64::NAN),
        c["p_value"].as_f64().unwrap_or(f64::NAN),
        c["alpha"].as_f64().unwrap_or(f64::NAN),
        c["rms_free_mm"].as_f64().unwrap_or(f64::NAN),
        c["rms_constrained_mm"].as_f64().unwrap_or(f64::NAN),
    ))
}

fn mm(v: f64) -> f64 {
    (v * 1e3 * 1e6).round() / 1e6
}

fn deg(v: f64) -> f64 {
    (v.to_degrees() * 1e9).round() / 1e9
}

/// The JSON object of one fit (all lengths mm, angles degrees).
fn report(pairs: &PointPairs, f: &Fit, mounts: Option<&MountPair>) -> Value {
    let x = &f.b1_from_b2;
    let r = x.rotation.to_rotation_matrix();
    let zyz = zyz_canonical(&r);
    let q = x.rotation;
    let rows: Vec<usize> = (0..pairs.len()).map(|i| pairs.row(i)).collect();
    let uncertainty = f.uncertainty.as_ref().map(|u| {
        let tre: Vec<f64> = pairs
            .p_b2
            .iter()
            .map(|p| mm(u.tre_rms_m(x, p)))
            .collect();
        json!({
            "sigma_point_mm": mm(u.sigma_point_m),
            "dof": u.dof,
            "e_tran_1sigma_mm": mm(u.e_tran_1sigma_m),
            "e_rot_1sigma_deg": deg(u.e_rot_1sigma_rad),
            "tre_rms_mm_at_points": tre,
            "covariance_order": "[dθx, dθy, dθz (rad, b1 axes), dtx, dty, dtz (m)]",
            "covariance": (0..6).map(|i| (0..6).map(|j| u.covariance[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
        })
    });
    // Leave-one-out needs one point more than the method; the 4-point methods with 4 points have none.
    let outliers = leave_one_out(pairs, f.method, mounts.unwrap_or(&MountPair::floor_floor()))
        .ok()
        .map(|rep| {
            json!({
                "loo_residuals_mm": rep.loo_residuals_m.iter().map(|v| mm(*v)).collect::<Vec<_>>(),
                "thresholds_mm": rep.thresholds_m.iter().map(|v| mm(*v)).collect::<Vec<_>>(),
                "flagged_rows": rep.flagged_rows(),
            })
        });
    json!({
        "method": f.method.name(),
        "mounts": mounts.map(|m| m.to_string()),
        "points": pairs.len(),
        "b1_from_b2": {
            "xyz_mm": [mm(x.translation.x), mm(x.translation.y), mm(x.translation.z)],
            "zyz_deg": [deg(zyz[0]), deg(zyz[1]), deg(zyz[2])],
            "rotation": (0..3).map(|i| (0..3).map(|j| r[(i, j)]).collect::<Vec<_>>()).collect::<Vec<_>>(),
            "quaternion_wxyz": [q.w, q.i, q.j, q.k],
        },
        "rows": rows,
        "residuals_mm": f.residuals.iter().map(|v| [mm(v.x), mm(v.y), mm(v.z)]).collect::<Vec<_>>(),
        "residual_norms_mm": f.residuals.iter().map(|v| mm(v.norm())).collect::<Vec<_>>(),
        "residual_rms_mm": mm(f.residual_rms_m()),
        "condition": f.condition,
        "uncertainty": uncertainty,
        "outliers": outliers,
    })
}

fn arr(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
        .unwrap_or_default()
}

fn print_text(v: &Value) {
    let name = v["method"].as_str().unwrap_or("?");
    if let Some(e) = v["error"].as_str() {
        println!("== method {name}: not applicable: {e}");
        return;
    }
    let mounts = v["mounts"].as_str().unwrap_or("none given");
    println!(
        "== method {name} (mounts: {mounts}, {} points)",
        v["points"]
    );
    let b = &v["b1_from_b2"];
    let xyz = arr(&b["xyz_mm"]);
    let zyz = arr(&b["zyz_deg"]);
    println!(
        "b1_from_b2:  x {:.3} mm  y {:.3} mm  z {:.3} mm   φ {:.4}°  θ {:.4}°  ψ {:.4}°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
        xyz[0], xyz[1], xyz[2], zyz[0], zyz[1], zyz[2]
    );
    println!("rotation:");
    if let Some(rows) = b["rotation"].as_array() {
        for row in rows {
            let r = arr(row);
            println!("  [{:>10.7} {:>10.7} {:>10.7}]", r[0], r[1], r[2]);
        }
    }
    let q = arr(&b["quaternion_wxyz"]);
    println!(
        "quaternion (w, x, y, z): {:.9} {:.9} {:.9} {:.9}",
        q[0], q[1], q[2], q[3]
    );
    println!("residuals p_b1 − b1_from_b2·p_b2 (mm; agreement between points, NOT an accuracy):");
    let rows = arr(&v["rows"]);
    let norms = arr(&v["residual_norms_mm"]);
    let flagged: Vec<f64> = arr(&v["outliers"]["flagged_rows"]);
    let loo = arr(&v["outliers"]["loo_residuals_mm"]);
    let thresholds = arr(&v["outliers"]["thresholds_mm"]);
    if let Some(res) = v["residuals_mm"].as_array() {
        for (i, r) in res.iter().enumerate() {
            let r = arr(r);
            let row = rows.get(i).copied().unwrap_or(0.0);
            let flag = if flagged.contains(&row) {
                "  <-- suspect handclasp (leave-one-out)"
            } else {
                ""
            };
            let loo_txt = loo
                .get(i)
                .map(|l| format!("  leave-one-out {l:.3} (limit {:.3})", thresholds[i]))
                .unwrap_or_default();
            println!(
                "  row {:>4}: {:>8.3} {:>8.3} {:>8.3}  |r| {:.3}{loo_txt}{flag}",
                row, r[0], r[1], r[2], norms[i]
            );
        }
    }
    println!(
        "residual RMS: {:.3} mm",
        v["residual_rms_mm"].as_f64().unwrap_or(f64::NAN)
    );
    println!(
        "condition: {:.2} (≥ 1; larger is worse)",
        v["condition"].as_f64().unwrap_or(f64::NAN)
    );
    let u = &v["uncertainty"];
    if u.is_null() {
        println!("predicted uncertainty: not computed for this method (use lsq or constrained)");
    } else {
        println!(
            "predicted uncertainty (1σ, from residuals and Jacobian): e_tran {:.3} mm, rotation {:.4}°, point noise σ {:.3} mm ({} dof)",
            u["e_tran_1sigma_mm"].as_f64().unwrap_or(f64::NAN),
            u["e_rot_1sigma_deg"].as_f64().unwrap_or(f64::NAN),
            u["sigma_point_mm"].as_f64().unwrap_or(f64::NAN),
            u["dof"]
        );
        let tre = arr(&u["tre_rms_mm_at_points"]);
        if !tre.is_empty() {
            let max = tre.iter().cloned().fold(0.0, f64::max);
            println!("  predicted error at the handclasp points (TRE, RMS): up to {max:.3} mm");
        }
    }
    if !v["soft_mount"].is_null() {
        println!(
            "soft mount: estimated relative tilt {:.4}° (prior σ {:.3}°)",
            v["soft_mount"]["tilt_estimate_deg"]
                .as_f64()
                .unwrap_or(f64::NAN),
            v["soft_mount"]["tilt_sigma_deg"]
                .as_f64()
                .unwrap_or(f64::NAN)
        );
    }
    if let Some(w) = mount_warning(&v["mount_check"]) {
        println!("{w}");
    } else if !v["mount_check"].is_null() {
        println!(
            "mount check: the points agree with the mounts (F-test p = {:.3})",
            v["mount_check"]["p_value"].as_f64().unwrap_or(f64::NAN)
        );
    }
    if v["outliers"].is_null() {
        println!("outliers: not checked (leave-one-out needs one point more than the method)");
    } else if flagged.is_empty() {
        println!("outliers: none (no leave-one-out residual above its limit)");
    } else {
        println!(
            "outliers: rows {:?} look like bad handclasps; re-record them",
            flagged.iter().map(|r| *r as usize).collect::<Vec<_>>()
        );
    }
}

//! `handclasp calibrate POINTS.csv`: fit `b1_from_b2` from handclasp points.
//!
//! Input: a CSV with `r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm` (any order, other columns
//! ignored; a sim-cell session file works as it stands). Output: `b1_from_b2` as x, y, z (mm) and
//! ZYZ φ, θ, ψ (deg, the controller's convention), the rotation matrix, the quaternion, per-point
//! residuals (mm), the conditioning, the predicted uncertainty and leave-one-out outlier flags.
//!
//! Default method: `constrained` when mounts are given, otherwise `lsq`.

use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::PathBuf;

use anyhow::{bail, Context};
use calib_core::{
    read_points_csv, FitReport, Method, Mount, MountCheckReport, MountPair, PointPairs,
    StreamedFitReport,
};
use cli_support::cell_report::{printed_zyz, PRINTED_TILT_DEG};
use cli_support::points::{
    all_methods, points_report_streamed, AllMethods, MethodOutcome, PointsError, PointsOptions,
    CLI_HINTS,
};

use crate::calibrate_cell::CellArgs;
use crate::progress::Progress;

/// Arguments of `handclasp calibrate`: the points path's own ([`PointsArgs`]), the whole-cell
/// path's own ([`CellArgs`], chosen by `--cell`), and the two flags both paths take.
///
/// `display_order` keeps `--help` in the order the options had when the two paths shared one
/// struct: the two groups' options first, then `--json`, `--expected-noise-mm`, `--force`,
/// `--verbose`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The whole-cell path's arguments.
    #[command(flatten)]
    pub cell: CellArgs,
    /// The points path's arguments.
    #[command(flatten)]
    pub points: PointsArgs,
    /// Print one JSON object instead of the table.
    #[arg(long, display_order = 100)]
    pub json: bool,
    /// Keep a fit whose residuals exceed --expected-noise-mm (a warning is printed on stderr);
    /// with --cell, keep a fit the result check refuses (its findings become `warning:` lines).
    /// To write a --cell --export into a non-empty folder, use --overwrite.
    #[arg(long, display_order = 102)]
    pub force: bool,
}

/// The points path's own arguments of `handclasp calibrate` (`calibrate POINTS.csv`).
#[derive(clap::Args, Debug)]
pub struct PointsArgs {
    /// CSV of handclasp points (mm): columns r1_x_mm,r1_y_mm,r1_z_mm,r2_x_mm,r2_y_mm,r2_z_mm.
    /// Required unless --cell is given.
    #[arg(required_unless_present = "cell", conflicts_with = "cell")]
    pub points: Option<PathBuf>,
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
    /// Expected handclasp alignment noise σ per axis, mm: a fit whose median residual norm exceeds
    /// the bound this σ allows for its number of points and method (calib_core::misfit_threshold_m,
    /// 0.1 % false alarms; ~2.2σ at 20 points) fails with the likely data mistake (rows out of
    /// order, swapped axes, wrong units, wrong robot order) and the worst rows, unless --force is
    /// given. With every --mounts setting: when only the mounts disagree, a warning says so.
    #[arg(long, default_value_t = calib_core::DEFAULT_EXPECTED_NOISE_M * 1e3, display_order = 101)]
    pub expected_noise_mm: f64,
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

/// The points path's configuration from its arguments and the command's `--json`, `--force`.
fn config(args: PointsArgs, json: bool, force: bool) -> anyhow::Result<Config> {
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
        (all_methods(mounts.is_some()), true)
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
        force,
        soft,
        points,
        mounts,
        methods,
        all,
        json,
    })
}

/// Runs `handclasp calibrate`: the whole-cell path with `--cell`, else the points path.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.cell.cell.is_some() {
        return crate::calibrate_cell::run(args.cell, args.json, args.force);
    }
    let cfg = config(args.points, args.json, args.force)?;
    // A spinner on a terminal's stderr (a million points take seconds): drawn while the CSV is
    // read and fitted, and while the report is written when stdout is not that terminal too;
    // cleared before anything is printed on a terminal's stdout.
    let stdout_is_terminal = std::io::stdout().is_terminal();
    let progress = Progress::new(crate::progress::shown(false), "reading the points CSV");
    let pairs = read_points_csv(&cfg.points)?;
    let writing = |progress: &Progress| {
        if stdout_is_terminal {
            progress.finish();
        } else {
            progress.phase("writing the report");
        }
    };
    if !cfg.all {
        let method = cfg.methods[0];
        progress.phase(format!(
            "fitting {} points (method {})",
            pairs.len(),
            method.name()
        ));
        let report = fit_report(&pairs, method, &cfg, &progress).map_err(|e| {
            progress.finish();
            let e = anyhow::Error::from(e).context(format!(
                "{}: method {}",
                cfg.points.display(),
                method.name()
            ));
            refusal_json(e, cfg.json)
        })?;
        // The JSON's per-point arrays are written from the fit and the points as they are
        // serialised (`StreamedFitReport`), never held as the report's vectors.
        writing(&progress);
        if cfg.json {
            crate::json_out::print_pretty(&report)?;
        } else {
            print!("{}", render_text(&report.into_report()));
        }
        return Ok(());
    }
    let mut report = AllMethods::default();
    for &m in &cfg.methods {
        progress.phase(format!(
            "fitting {} points (method {})",
            pairs.len(),
            m.name()
        ));
        report.insert(
            m,
            fit_report(&pairs, m, &cfg, &progress).map(StreamedFitReport::into_report),
        );
    }
    drop(pairs);
    writing(&progress);
    if cfg.json {
        crate::json_out::print_pretty(&report)?;
    } else {
        for outcome in report.methods.values() {
            print!("{}", outcome_text(outcome));
            println!();
        }
    }
    Ok(())
}

/// With `--json`, a refused fit (a misfit, [`PointsError::Misfit`]) prints its refusal object
/// on stdout ([`cli_support::result_check::Refusal`], key `misfit`) before the error goes on to
/// `error:` and exit 1. Returns `e`.
fn refusal_json(e: anyhow::Error, json: bool) -> anyhow::Error {
    if json {
        if let Some(PointsError::Misfit(m)) = e.downcast_ref::<PointsError>() {
            let mut refusal = cli_support::result_check::Refusal::new(
                "calibrate",
                cli_support::error_chain_text(e.as_ref()),
            );
            refusal.misfit = Some(m);
            if let Err(print) = crate::json_out::print_pretty(&refusal) {
                eprintln!("error: {print:#}");
            }
        }
    }
    e
}

/// The text of one method's outcome under `--method all`.
fn outcome_text(outcome: &MethodOutcome) -> String {
    match outcome {
        MethodOutcome::Fit(r) => render_text(r),
        MethodOutcome::NotApplicable { error, method } => {
            format!("== method {}: not applicable: {error}\n", method.name())
        }
    }
}

/// Fits one method through [`cli_support::points::points_report_streamed`] (the library the
/// Python package shares) and prints its warnings (a misfit kept by `--force`) on stderr, out
/// of the spinner's way.
fn fit_report<'a>(
    pairs: &'a PointPairs,
    method: Method,
    cfg: &Config,
    progress: &Progress,
) -> Result<StreamedFitReport<'a>, PointsError> {
    let options = PointsOptions {
        method,
        mounts: cfg.mounts,
        soft: cfg.soft,
        expected_noise_m: cfg.expected_noise_m,
        force: cfg.force,
    };
    let fitted = points_report_streamed(pairs, &options, CLI_HINTS)?;
    for w in &fitted.warnings {
        progress.eprintln(w);
    }
    Ok(fitted.report)
}

/// The text of a failed mount check: what the points say and what to do about it.
fn mount_warning(c: &MountCheckReport) -> Option<String> {
    if c.consistent {
        return None;
    }
    let gap = c.rotation_gap_deg;
    let advice = if gap > 2.0 {
        "the mounts look wrong: check --mounts, or the sign and axis of --mount1/--mount2 tilt:RX,RY"
    } else {
        "the mount is nominal only: use --tilt-sigma-deg to estimate the actual tilt, or method lsq"
    };
    Some(format!(
        "WARNING: the points disagree with the mounts (F = {:.1}, p = {:.1e} < {}): the free rigid fit is {gap:.3}° from the nearest rotation they allow, and imposing them raises the residual RMS from {:.3} to {:.3} mm; {advice}",
        c.f_statistic, c.p_value, c.alpha, c.rms_free_mm, c.rms_constrained_mm,
    ))
}

/// The text report of one fit (mm, degrees).
fn render_text(r: &FitReport) -> String {
    let mut s = String::new();
    // Writing into a String cannot fail.
    let _ = write_text(&mut s, r);
    s
}

fn write_text(s: &mut String, r: &FitReport) -> std::fmt::Result {
    let name = r.method.name();
    let mounts = r.mounts.as_deref().unwrap_or("none given");
    writeln!(
        s,
        "== method {name} (mounts: {mounts}, {} points)",
        r.points
    )?;
    let b = &r.b1_from_b2;
    // A tilt that prints as θ 0.0000° (or 180.0000°) leaves φ and ψ undefined apart: printed as
    // the pure yaw (the JSON keeps the exact angles).
    let (zyz, _) = printed_zyz(b, PRINTED_TILT_DEG);
    let xyz = b.xyz_mm;
    writeln!(
        s,
        "b1_from_b2:  x {:.3} mm  y {:.3} mm  z {:.3} mm   φ {:.4}°  θ {:.4}°  ψ {:.4}°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
        xyz[0], xyz[1], xyz[2], zyz[0], zyz[1], zyz[2]
    )?;
    writeln!(s, "rotation:")?;
    for row in &b.rotation {
        writeln!(s, "  [{:>10.7} {:>10.7} {:>10.7}]", row[0], row[1], row[2])?;
    }
    let q = b.quaternion_wxyz;
    writeln!(
        s,
        "quaternion (w, x, y, z): {:.9} {:.9} {:.9} {:.9}",
        q[0], q[1], q[2], q[3]
    )?;
    writeln!(
        s,
        "residuals p_b1 − b1_from_b2·p_b2 (mm; agreement between points, NOT an accuracy):"
    )?;
    let (flagged, loo, thresholds): (&[usize], &[f64], &[f64]) = match &r.outliers {
        Some(o) => (&o.flagged_rows, &o.loo_residuals_mm, &o.thresholds_mm),
        None => (&[], &[], &[]),
    };
    for (i, res) in r.residuals_mm.iter().enumerate() {
        let row = r.rows.get(i).copied().unwrap_or(0);
        let flag = match (flagged.contains(&row), loo.get(i).zip(thresholds.get(i))) {
            (false, _) => "",
            (true, Some((l, t))) if l <= t => "  <-- suspect handclasp (robust fit of the others)",
            (true, _) => "  <-- suspect handclasp (leave-one-out)",
        };
        let loo_txt = loo
            .get(i)
            .map(|l| format!("  leave-one-out {l:.3} (limit {:.3})", thresholds[i]))
            .unwrap_or_default();
        writeln!(
            s,
            "  row {:>4}: {:>8.3} {:>8.3} {:>8.3}  |r| {:.3}{loo_txt}{flag}",
            row, res[0], res[1], res[2], r.residual_norms_mm[i]
        )?;
    }
    writeln!(s, "residual RMS: {:.3} mm", r.residual_rms_mm)?;
    writeln!(s, "condition: {:.2} (≥ 1; larger is worse)", r.condition)?;
    match &r.uncertainty {
        None => writeln!(
            s,
            "predicted uncertainty: not computed for this method (use lsq or constrained)"
        )?,
        Some(u) => {
            writeln!(
                s,
                "predicted uncertainty (1σ, from residuals and Jacobian): e_tran {:.3} mm, rotation {:.4}°, point noise σ {:.3} mm ({} dof)",
                u.e_tran_1sigma_mm, u.e_rot_1sigma_deg, u.sigma_point_mm, u.dof
            )?;
            if !u.tre_rms_mm_at_points.is_empty() {
                let max = u.tre_rms_mm_at_points.iter().cloned().fold(0.0, f64::max);
                writeln!(
                    s,
                    "  predicted error at the handclasp points (TRE, RMS): up to {max:.3} mm"
                )?;
            }
        }
    }
    if let Some(soft) = &r.soft_mount {
        writeln!(
            s,
            "soft mount: estimated relative tilt {:.4}° (prior σ {:.3}°)",
            soft.tilt_estimate_deg, soft.tilt_sigma_deg
        )?;
    }
    if let Some(c) = &r.mount_check {
        match mount_warning(c) {
            Some(w) => writeln!(s, "{w}")?,
            None => writeln!(
                s,
                "mount check: the points agree with the mounts (F-test p = {:.3})",
                c.p_value
            )?,
        }
    }
    match &r.outliers {
        None => writeln!(
            s,
            "outliers: not checked (leave-one-out needs one point more than the method)"
        ),
        Some(o) if o.flagged_rows.is_empty() => writeln!(
            s,
            "outliers: none (no leave-one-out residual above its limit)"
        ),
        Some(o) => writeln!(
            s,
            "outliers: rows {:?} look like bad handclasps; re-record them",
            o.flagged_rows
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::{OutliersReport, PoseForms, SoftMountReport, UncertaintyReport};
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    use std::collections::BTreeMap;

    /// A constrained fit of three points, the second flagged, with every optional part.
    fn report() -> FitReport {
        FitReport {
            b1_from_b2: PoseForms {
                quaternion_wxyz: [0.5, 0.5, -0.5, 0.5],
                rotation: [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
                xyz_mm: [1303.3, -102.3, 1386.3],
                zyz_deg: [180.0, 89.874, -179.997],
            },
            condition: 10.875,
            method: Method::Constrained,
            mount_check: Some(MountCheckReport {
                alpha: 0.001,
                consistent: false,
                constraints: 2,
                dof: 3,
                f_statistic: 33.71,
                p_value: 2.4e-6,
                rms_constrained_mm: 0.911,
                rms_free_mm: 0.625,
                rotation_gap_deg: 0.114,
            }),
            mounts: Some("floor-wall".into()),
            outliers: Some(OutliersReport {
                flagged_rows: vec![3],
                loo_residuals_mm: vec![0.5, 9.25, 0.75],
                thresholds_mm: vec![2.0, 2.5, 3.0],
            }),
            points: 3,
            residual_norms_mm: vec![0.25, 6.5, 0.5],
            residual_rms_mm: 3.76,
            residuals_mm: vec![[0.1, -0.2, 0.1], [6.0, 2.5, 0.0], [0.0, 0.0, -0.5]],
            rows: vec![2, 3, 4],
            soft_mount: Some(SoftMountReport {
                point_sigma_mm: 0.5,
                tilt_estimate_deg: 0.11321,
                tilt_sigma_deg: 0.5,
                tilt_vector_deg_b1: [0.1, 0.05, 0.0],
            }),
            uncertainty: Some(UncertaintyReport {
                covariance: [[0.0; 6]; 6],
                covariance_order: "",
                dof: 3,
                e_rot_1sigma_deg: 0.0299,
                e_tran_1sigma_mm: 0.484,
                sigma_point_mm: 0.567,
                tre_rms_mm_at_points: vec![0.4, 0.519, 0.3],
            }),
        }
    }

    /// Every line from a typed field: the flagged row marked, the leave-one-out limits, the
    /// soft mount and a mount warning with the nominal-mount advice (gap ≤ 2°).
    #[test]
    fn text_of_a_constrained_fit_with_a_flagged_row() {
        let text = render_text(&report());
        let expected = [
            "== method constrained (mounts: floor-wall, 3 points)",
            "b1_from_b2:  x 1303.300 mm  y -102.300 mm  z 1386.300 mm   φ 180.0000°  θ 89.8740°  ψ -179.9970°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
            "rotation:",
            "  [ 0.0000000  0.0000000  1.0000000]",
            "  [ 1.0000000  0.0000000  0.0000000]",
            "  [ 0.0000000  1.0000000  0.0000000]",
            "quaternion (w, x, y, z): 0.500000000 0.500000000 -0.500000000 0.500000000",
            "residuals p_b1 − b1_from_b2·p_b2 (mm; agreement between points, NOT an accuracy):",
            "  row    2:    0.100   -0.200    0.100  |r| 0.250  leave-one-out 0.500 (limit 2.000)",
            "  row    3:    6.000    2.500    0.000  |r| 6.500  leave-one-out 9.250 (limit 2.500)  <-- suspect handclasp (leave-one-out)",
            "  row    4:    0.000    0.000   -0.500  |r| 0.500  leave-one-out 0.750 (limit 3.000)",
            "residual RMS: 3.760 mm",
            "condition: 10.88 (≥ 1; larger is worse)",
            "predicted uncertainty (1σ, from residuals and Jacobian): e_tran 0.484 mm, rotation 0.0299°, point noise σ 0.567 mm (3 dof)",
            "  predicted error at the handclasp points (TRE, RMS): up to 0.519 mm",
            "soft mount: estimated relative tilt 0.1132° (prior σ 0.500°)",
            "WARNING: the points disagree with the mounts (F = 33.7, p = 2.4e-6 < 0.001): the free rigid fit is 0.114° from the nearest rotation they allow, and imposing them raises the residual RMS from 0.625 to 0.911 mm; the mount is nominal only: use --tilt-sigma-deg to estimate the actual tilt, or method lsq",
            "outliers: rows [3] look like bad handclasps; re-record them",
        ];
        assert_eq!(text.lines().collect::<Vec<_>>(), expected);
    }

    /// A placement with no tilt at the printed resolution (two floor robots: θ ≈ 0) prints as the
    /// pure yaw, not as a pair of large φ and −ψ (stop 28: points mode printed the raw ZYZ, e.g.
    /// φ 48.3° θ 0.0000° ψ −48.3°, where the whole-cell report already printed the yaw alone).
    #[test]
    fn text_of_an_untilted_placement_is_the_pure_yaw() {
        let mut r = report();
        let yaw = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.3)
            * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1e-7);
        r.b1_from_b2 = PoseForms::from_isometry(&Isometry3::from_parts(
            Translation3::new(1.0, 2.0, 0.0),
            yaw,
        ));
        let line = render_text(&r).lines().nth(1).unwrap().to_string();
        let want = format!(
            "b1_from_b2:  x 1000.000 mm  y 2000.000 mm  z 0.000 mm   φ 0.0000°  θ 0.0000°  ψ {:.4}°  (ZYZ, R = Rz(φ)·Ry(θ)·Rz(ψ))",
            0.3f64.to_degrees()
        );
        assert_eq!(line, want);
    }

    /// A 4-point projection fit: no uncertainty, no leave-one-out, mounts agreeing; and a
    /// method that does not apply.
    #[test]
    fn text_without_the_optional_parts_and_not_applicable() {
        let mut r = report();
        r.method = Method::Paper;
        r.mounts = None;
        r.uncertainty = None;
        r.outliers = None;
        r.soft_mount = None;
        if let Some(c) = r.mount_check.as_mut() {
            c.consistent = true;
            c.p_value = 0.8741;
        }
        let text = render_text(&r);
        for line in [
            "== method paper (mounts: none given, 3 points)",
            "  row    3:    6.000    2.500    0.000  |r| 6.500",
            "predicted uncertainty: not computed for this method (use lsq or constrained)",
            "mount check: the points agree with the mounts (F-test p = 0.874)",
            "outliers: not checked (leave-one-out needs one point more than the method)",
        ] {
            assert!(
                text.lines().any(|l| l == line),
                "{line:?} missing in\n{text}"
            );
        }
        assert!(!text.contains("soft mount") && !text.contains("TRE"));
        let na = MethodOutcome::NotApplicable {
            error: "needs 4 points".into(),
            method: Method::GenericAffine,
        };
        assert_eq!(
            outcome_text(&na),
            "== method generic-affine: not applicable: needs 4 points\n"
        );
    }

    /// `--method all`'s JSON: the methods by name in alphabetical order, a method that does not
    /// apply as `{"error", "method"}`, the fit's optional parts absent when not run.
    #[test]
    fn all_methods_json() {
        let mut fit = report();
        fit.mount_check = None;
        fit.soft_mount = None;
        let mut methods = BTreeMap::new();
        methods.insert(Method::Lsq.name(), MethodOutcome::Fit(Box::new(fit)));
        methods.insert(
            Method::Generic.name(),
            MethodOutcome::NotApplicable {
                error: "e".into(),
                method: Method::Generic,
            },
        );
        let json = crate::test_support::json_in_value_order(&AllMethods { methods });
        assert!(
            json.starts_with(
                r#"{"methods":{"generic":{"error":"e","method":"generic"},"lsq":{"b1_from_b2""#
            ),
            "{json}"
        );
        assert!(!json.contains("mount_check") && !json.contains("soft_mount"));
    }
}

//! A calibrated model: the MAP fit of a recording set with one (parameter set, prior σ) spec,
//! its export as a cell folder (cell.toml, right_arm.urdf, left_arm.urdf, parameters.csv) with
//! the export's departure from the fit measured, the calibrations of one cross-validated choice
//! (chosen, without and with compliance, with the marker centres), and the report of a fit's
//! significant effects.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use calib_core::whole_cell::{CellFit, CellParam, CellProblem, ObservationKind};
use handclasp_cell::Cell;
use handclasp_cell::{export_calibrated_cell, ExportNames};
use kinematics::{true_base_from_tip, ErrorParam};

use crate::cv::Choice;
use crate::data::Recording;
use crate::study::{
    build_problem, corrections, fit, residuals, ModelSpec, NoiseLevels, COMPLIANT_JOINTS,
};

/// Right arm = robot 1, left arm = robot 2.
fn export_names(header: &str) -> ExportNames<'_> {
    ExportNames {
        cell: "cell.toml",
        robot1_urdf: "right_arm.urdf",
        robot2_urdf: "left_arm.urdf",
        header,
    }
}

/// Writes every fitted parameter with its posterior σ (mm, mrad) to `path`.
fn write_parameters(path: &Path, problem: &CellProblem, f: &CellFit) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    writeln!(w, "parameter,unit,value,sigma,prior_sigma")?;
    for p in f.parameters(problem) {
        let (unit, k) = unit(&p.param);
        writeln!(
            w,
            "\"{}\",{unit},{:.6},{:.6},{:.6}",
            p.name,
            p.value * k,
            p.posterior_sigma * k,
            p.prior_sigma * k
        )?;
    }
    Ok(())
}

/// The unit of a parameter in the reports and its factor from SI: mrad for angles, mm else.
fn unit(p: &CellParam) -> (&'static str, f64) {
    match p {
        CellParam::Kinematic {
            param:
                kinematics::ErrorParam::JointOffset { .. } | kinematics::ErrorParam::OriginRpy { .. },
            ..
        }
        | CellParam::PlacementRotation { .. }
        | CellParam::TrackerRotation { .. }
        | CellParam::PlaneNormal { .. } => ("mrad", 1e3),
        _ => ("mm", 1e3),
    }
}

/// A calibrated model: its name, fit, problem and parameter set.
#[derive(Clone)]
pub struct Calibrated {
    /// The model's name in the score rows and output folders (`self`, `planes`, `all`, …).
    pub name: String,
    /// The whole-cell problem it was fitted on (its recordings' rows and parameter layout).
    pub problem: CellProblem,
    /// The MAP fit: estimate, posterior and residuals.
    pub fit: CellFit,
    /// The parameter set and prior σ it was fitted with.
    pub spec: ModelSpec,
}

/// The MAP fit of `recs` with `spec`; `name` labels the score rows.
pub fn calibrate(
    cell: &Cell,
    name: String,
    recs: &[&Recording],
    spec: ModelSpec,
    noise: &NoiseLevels,
) -> anyhow::Result<Calibrated> {
    let b = build_problem(cell, recs, Some(spec), noise);
    let f = fit(&b, None, None).with_context(|| format!("calibrating {name}"))?;
    println!(
        "{name} ({} σ {}): {} after {} iterations, {} rows, data χ² {:.1}; contact distance {}{}",
        spec.set.name(),
        spec.sigma,
        f.stopped.name(),
        f.iterations,
        f.residual_rows,
        f.data_chi2,
        b.problem
            .contacts
            .iter()
            .zip(&f.estimate.contact_distance_m)
            .map(|(g, d)| format!("{} {:.3} mm", g.name, d * 1e3))
            .collect::<Vec<_>>()
            .join(", "),
        compliance_text(&f)
    );
    if spec.set.marker() {
        let m = |t: &nalgebra::Vector3<f64>| {
            format!("({:+.2}, {:+.2}, {:+.2})", t.x * 1e3, t.y * 1e3, t.z * 1e3)
        };
        println!(
            "  marker centre offsets (tool0, mm): right {}, left {}",
            m(&f.estimate.robot1.tool_tip_m[0]),
            m(&f.estimate.robot2.tool_tip_m[0])
        );
    }
    Ok(Calibrated {
        name,
        problem: b.problem,
        fit: f,
        spec,
    })
}

/// The fitted compliances of L and U of both arms, as text (empty without compliance).
fn compliance_text(f: &CellFit) -> String {
    let mut out = String::new();
    for (arm, e) in [
        ("right", &f.estimate.robot1.errors),
        ("left", &f.estimate.robot2.errors),
    ] {
        let c: Vec<String> = COMPLIANT_JOINTS
            .iter()
            .map(|&joint| format!("{:.2}", e.get(ErrorParam::Compliance { joint }) * 1e6))
            .collect();
        if c.iter().any(|v| v != "0.00") {
            out += &format!("; {arm} compliance L, U {} µrad/(N·m)", c.join(", "));
        }
    }
    out
}

/// Exports `c` as `out/folder/` (cell.toml, right_arm.urdf, left_arm.urdf, parameters.csv) and
/// measures the export's departure from the fit at every pose of `recs` (marker tips of both
/// arms): with compliance, the fit takes gravity torques from the NOMINAL geometry and the
/// exported cell from the corrected URDF (`handclasp_cell::export_calibrated_cell`'s caveat).
/// Returns (rms, max) of that departure, m.
pub fn export(
    cell: &Cell,
    c: &Calibrated,
    folder: &str,
    recs: &[&Recording],
    out: &Path,
    how: &str,
) -> anyhow::Result<(f64, f64)> {
    let dir = out.join(folder);
    let header = format!(
        "# Written by `cargo run --release -p ctu-motoman`: the CTU dual-arm Motoman cell calibrated from\n\
         # {how}.\n# robot1 = right arm, robot2 = left arm; parameter set {} with prior σ {} mrad / mm.\n\
         # Joint offsets and origins are in right_arm.urdf / left_arm.urdf.\n",
        c.spec.set.name(),
        c.spec.sigma
    );
    let written = export_calibrated_cell(cell, &c.fit.estimate, &dir, &export_names(&header))
        .with_context(|| format!("exporting {}", dir.display()))?;
    write_parameters(&dir.join("parameters.csv"), &c.problem, &c.fit)?;
    for w in &written {
        println!("wrote {}", w.display());
    }
    let exported = Cell::from_toml_file(&dir.join("cell.toml"))?;
    let (mut sum2, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    // The fitted marker centre (tool 0 tip error) is in the `tip` field.
    let (fit_right, fit_left) = corrections(&c.fit);
    for (setup, fitted, exp) in [
        (&cell.robot1, &fit_right, &exported.robot1),
        (&cell.robot2, &fit_left, &exported.robot2),
    ] {
        let right = std::ptr::eq(setup, &cell.robot1);
        for rec in recs {
            for pose in &rec.poses {
                let q = if right { &pose.q_right } else { &pose.q_left };
                let want = true_base_from_tip(
                    &setup.model,
                    fitted,
                    q,
                    &setup.flange_from_tip,
                    &setup.g_base,
                )?;
                let got = true_base_from_tip(
                    &exp.model,
                    &exp.errors,
                    q,
                    &exp.flange_from_tip,
                    &exp.g_base,
                )?;
                let d = (want.translation.vector - got.translation.vector).norm();
                sum2 += d * d;
                max = max.max(d);
                n += 1;
            }
        }
    }
    let rms = (sum2 / n.max(1) as f64).sqrt();
    println!(
        "  exported cell vs the fit at the {n} marker tips of its recordings: rms {:.3} µm, max {:.3} µm",
        rms * 1e6,
        max * 1e6
    );
    Ok((rms, max))
}

/// The calibrations of one recording set: the rule's choice over every candidate (exported as
/// `out/name/`), and its choices among the candidates without and with compliance (scored as
/// `name` and `name+c`; the latter exported as `out/name+c/` to measure the export caveat). The
/// chosen model is one of the two, or else fitted and scored as `name*`. With marker-centre
/// candidates, their choice is scored as `name+m` and exported as `out/name+m/`.
pub struct Calibrations {
    /// Rule over every candidate.
    pub chosen: Calibrated,
    /// Rule over the candidates without compliance and without marker centres (the study before
    /// either was a candidate).
    pub without: Calibrated,
    /// Rule over the candidates with compliance.
    pub with: Calibrated,
    /// Rule over the candidates with the marker centres (when there are such candidates).
    pub marker: Option<Calibrated>,
}

impl Calibrations {
    /// The models to score, each once: `without`, `with`, `marker`, and `chosen` when it is
    /// none of these.
    pub fn scored(&self) -> Vec<&Calibrated> {
        let mut v = vec![&self.without, &self.with];
        v.extend(self.marker.as_ref());
        if self.chosen.name.ends_with('*') {
            v.push(&self.chosen);
        }
        v
    }
}

/// Fits the three models of [`Calibrations`] (each spec once) and exports the chosen one to
/// `out/name/` and the compliance one to `out/name+c/`.
pub fn calibrate_all(
    cell: &Cell,
    name: &str,
    recs: &[&Recording],
    choice: &Choice,
    noise: &NoiseLevels,
    out: &Path,
    how: &str,
) -> anyhow::Result<Calibrations> {
    let without = calibrate(
        cell,
        name.to_string(),
        recs,
        choice.without_compliance,
        noise,
    )?;
    let with = calibrate(
        cell,
        format!("{name}+c"),
        recs,
        choice.with_compliance,
        noise,
    )?;
    let marker = choice
        .with_marker
        .map(|spec| calibrate(cell, format!("{name}+m"), recs, spec, noise))
        .transpose()?;
    let chosen = if choice.spec == without.spec {
        renamed(&without, name)
    } else if choice.spec == with.spec {
        renamed(&with, &format!("{name}+c"))
    } else if let Some(m) = marker.as_ref().filter(|m| m.spec == choice.spec) {
        renamed(m, &format!("{name}+m"))
    } else {
        calibrate(cell, format!("{name}*"), recs, choice.spec, noise)?
    };
    println!("exporting {} as {name}/", chosen.name);
    export(cell, &chosen, name, recs, out, how)?;
    export(cell, &with, &format!("{name}+c"), recs, out, how)?;
    if let Some(m) = &marker {
        export(cell, m, &format!("{name}+m"), recs, out, how)?;
    }
    Ok(Calibrations {
        chosen,
        without,
        with,
        marker,
    })
}

/// `c` under another name (the score rows' label).
fn renamed(c: &Calibrated, name: &str) -> Calibrated {
    Calibrated {
        name: name.to_string(),
        ..c.clone()
    }
}

/// The rms of the contact rows' residuals (centre distance, or for `FaceContact` rows the
/// distance along the faces' mean normal, minus the fitted contact distance) of a calibration, m.
pub fn contact_rms(c: &Calibrated) -> anyhow::Result<f64> {
    let res = residuals(&c.problem, &c.fit, &c.fit.estimate)?;
    let (mut s2, mut n) = (0.0, 0usize);
    for (o, (r, _)) in c.problem.observations.iter().zip(&res) {
        if matches!(
            o.kind,
            ObservationKind::Contact { .. } | ObservationKind::FaceContact { .. }
        ) {
            s2 += r * r;
            n += 1;
        }
    }
    Ok((s2 / n.max(1) as f64).sqrt())
}

/// The kinematic parameters of the `all` fit whose value is beyond 3 posterior σ, with a 95 %
/// interval (± 1.96 σ), mm / mrad.
pub fn print_effects(c: &Calibrated) {
    println!(
        "effects in the `all` fit ({} σ {}), |value| > 3 posterior σ, 95 % interval:",
        c.spec.set.name(),
        c.spec.sigma
    );
    for p in c.fit.parameters(&c.problem) {
        if !matches!(p.param, CellParam::Kinematic { .. }) || p.posterior_sigma <= 0.0 {
            continue;
        }
        if (p.value / p.posterior_sigma).abs() > 3.0 {
            let (u, k) = unit(&p.param);
            println!(
                "  {:<40} {:+8.3} {u} [{:+8.3}, {:+8.3}] (prior σ {:.3})",
                p.name,
                p.value * k,
                (p.value - 1.96 * p.posterior_sigma) * k,
                (p.value + 1.96 * p.posterior_sigma) * k,
                p.prior_sigma * k
            );
        }
    }
}

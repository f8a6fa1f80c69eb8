//! The held-out tracker score table: every model scored on every tracker file with the honest
//! protocol (plus the per-file rigid-geometry column), printed, written as `scores.csv` and drawn
//! (`scores_per_file.svg`, `residual_vs_joint.svg`); and the `--score-every-self-candidate`
//! diagnostic, which scores every `self` CV candidate the same way and selects nothing.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use calib_core::StopReason;
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use crate::contact_report::leica_contact_only;
use crate::cv::Choice;
use crate::data::Recording;
use crate::plot;
use crate::splits::exported_column;
use crate::study::{
    build_problem, corrections, fit, held_out_nuisance_cost, score_recording, summarise,
    NoiseLevels, ScoredPose, Summary,
};

/// One row of the score table.
pub struct ScoreRow {
    /// The tracker file's name (without `_dataset.csv`).
    pub file: String,
    /// The arm that carries the reflector in that file (`right` or `left`).
    pub arm: &'static str,
    /// The scored model's name.
    pub model: String,
    /// Whether the model's kinematics are held out from the tracker files.
    pub held_out: bool,
    /// The held-out error over the file's poses (rms, median, p95, max, mm).
    pub summary: Summary,
}

/// A model to score: its name, its (right, left) corrections, and whether its kinematics are
/// held out from the tracker files (`false` for the models that saw their tracker values).
pub type ScoredModel = (String, KinematicErrors, KinematicErrors, bool);

/// Scores every model of `models` on every recording of `trackers` (honest protocol), and what a
/// rigid-geometry calibration of each file alone leaves (`file_geometry`). Returns the score
/// rows and, per (file, model), the scored poses.
#[allow(clippy::type_complexity)]
pub fn score_models(
    cell: &Cell,
    models: &[ScoredModel],
    trackers: &[&Recording],
) -> anyhow::Result<(Vec<ScoreRow>, Vec<(String, String, Vec<ScoredPose>)>)> {
    let zero = KinematicErrors::zero(6);
    let mut rows: Vec<ScoreRow> = Vec::new();
    let mut per_pose: Vec<(String, String, Vec<ScoredPose>)> = Vec::new();
    for rec in trackers {
        let arm = if rec.right_arm { "right" } else { "left" };
        for (name, r, l, held_out) in models {
            let s = score_recording(cell, rec, (r, l), None)?;
            let errs: Vec<f64> = s.iter().map(|p| p.error_m).collect();
            rows.push(ScoreRow {
                file: rec.name.clone(),
                arm,
                model: name.clone(),
                held_out: *held_out,
                summary: summarise(&errs),
            });
            per_pose.push((rec.name.clone(), name.to_string(), s));
        }
        // What a rigid-geometry calibration of this file alone leaves (offsets + lengths, weak
        // prior 10 mrad / 10 mm, fitted on the fitting half with the registration).
        let s = score_recording(cell, rec, (&zero, &zero), Some(10.0))?;
        let errs: Vec<f64> = s.iter().map(|p| p.error_m).collect();
        rows.push(ScoreRow {
            file: rec.name.clone(),
            arm,
            model: "file_geometry".into(),
            held_out: true,
            summary: summarise(&errs),
        });
    }
    Ok((rows, per_pose))
}

/// Writes `out/scores.csv` (its `exported` column from `exported`, see
/// [`crate::splits::exported_folders`]) and the figures `out/scores_per_file.svg` (rms per file
/// of `names`) and `out/residual_vs_joint.svg` (residual against each joint angle, nominal vs
/// `self_name`).
pub fn write_score_files(
    out: &Path,
    rows: &[ScoreRow],
    per_pose: &[(String, String, Vec<ScoredPose>)],
    trackers: &[&Recording],
    names: &[&str],
    self_name: &str,
    exported: &[(String, Vec<String>)],
) -> anyhow::Result<()> {
    write_scores(&out.join("scores.csv"), rows, exported)?;
    plot::per_file_svg(
        &out.join("scores_per_file.svg"),
        &rows_for_plot(rows, trackers, names),
    )?;
    plot::residual_vs_joint_svg(
        &out.join("residual_vs_joint.svg"),
        per_pose,
        trackers,
        self_name,
    )?;
    println!(
        "wrote {}, {}, {}",
        out.join("scores.csv").display(),
        out.join("scores_per_file.svg").display(),
        out.join("residual_vs_joint.svg").display()
    );
    Ok(())
}

/// Diagnostic (selects nothing): every CV candidate of `choice` fitted on `recs` and scored on
/// every tracker file; prints and writes `out/self_candidates.csv` with the number of files on
/// which each beats nominal (`rows` holds nominal's scores).
pub fn score_every_candidate(
    cell: &Cell,
    recs: &[&Recording],
    choice: &Choice,
    noise: &NoiseLevels,
    trackers: &[&Recording],
    rows: &[ScoreRow],
    out: &Path,
) -> anyhow::Result<()> {
    let path = out.join("self_candidates.csv");
    let mut w = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
    write!(w, "set,sigma,cv,chosen")?;
    for t in trackers {
        write!(w, ",{}_rms_mm", t.name)?;
    }
    writeln!(
        w,
        ",files_better_than_nominal,pooled_rms_mm,leica_self_contact_rms_mm"
    )?;
    let leica = leica_contact_only(trackers);
    let leica_refs: Vec<&Recording> = leica.iter().collect();
    println!(
        "DIAGNOSTIC (uses tracker scores, selects nothing): every `self` candidate (σ grid {}) fitted on all self-contact files; \
         files (of {}) where it beats nominal, pooled rms mm:",
        choice.grid,
        trackers.len()
    );
    for row in &choice.table {
        let (spec, cv) = (&row.spec, row.pooled.e);
        let b = build_problem(cell, recs, Some(*spec), noise);
        let f = fit(&b, None, None)?;
        if f.stopped != StopReason::Converged {
            println!(
                "  NOT CONVERGED: {} σ {} on all self-contact files: {} after {} iterations",
                spec.set.name(),
                spec.sigma,
                f.stopped.name(),
                f.iterations
            );
        }
        let (r, l) = corrections(&f);
        let (mut better, mut s2, mut n) = (0usize, 0.0, 0usize);
        write!(
            w,
            "{},{},{cv:.6},{}",
            spec.set.name(),
            spec.sigma,
            *spec == choice.spec
        )?;
        for t in trackers {
            let s = score_recording(cell, t, (&r, &l), None)?;
            let sum = summarise(&s.iter().map(|p| p.error_m).collect::<Vec<_>>());
            let nominal = rows
                .iter()
                .find(|x| x.file == t.name && x.model == "nominal")
                .context("nominal score missing")?;
            better += usize::from(sum.rms_mm < nominal.summary.rms_mm);
            s2 += sum.rms_mm.powi(2) * sum.n as f64;
            n += sum.n;
            write!(w, ",{:.4}", sum.rms_mm)?;
        }
        let pooled = (s2 / n.max(1) as f64).sqrt();
        let e2 = held_out_nuisance_cost(cell, &leica_refs, (&r, &l), noise)?;
        let leica_rms = (e2.iter().sum::<f64>() / e2.len().max(1) as f64).sqrt() * noise.contact_m;
        writeln!(w, ",{better},{pooled:.4},{:.4}", leica_rms * 1e3)?;
        println!(
            "  {:<16} σ {:<4} CV {cv:.4}: better on {better:>2}, pooled {pooled:.3}; leica_self contact rms {:.3}; fitted contact distance {:.3} mm",
            spec.set.name(),
            spec.sigma,
            leica_rms * 1e3,
            f.estimate.contact_distance_m.first().copied().unwrap_or(f64::NAN) * 1e3
        );
    }
    println!("wrote {}", path.display());
    Ok(())
}

/// The rms per tracker file of each of `models` and of the file-geometry column (NaN where
/// absent), the series of `scores_per_file.svg`.
fn rows_for_plot(
    rows: &[ScoreRow],
    trackers: &[&Recording],
    models: &[&str],
) -> Vec<(String, Vec<f64>)> {
    models
        .iter()
        .chain(std::iter::once(&"file_geometry"))
        .map(|m| {
            let v = trackers
                .iter()
                .map(|t| {
                    rows.iter()
                        .find(|r| r.file == t.name && r.model == *m)
                        .map(|r| r.summary.rms_mm)
                        .unwrap_or(f64::NAN)
                })
                .collect();
            (m.to_string(), v)
        })
        .collect()
}

/// Prints the held-out rms of `models` (in this order, nominal first) and the file-geometry
/// column per tracker file, and the pooled rms.
pub fn print_scores(rows: &[ScoreRow], trackers: &[&Recording], models: &[&str]) {
    println!(
        "held-out tracker rms, mm (registration + reflector fitted on one half, scored on the other, both ways; \
         +c = with L/U gravity compliance; median/p95/max in scores.csv):"
    );
    print!("  {:<26} {:>5} {:>4}", "file", "arm", "n");
    for m in models.iter().chain(std::iter::once(&"file geom")) {
        print!(" {m:>9}");
    }
    println!();
    let mut pooled = vec![(0.0f64, 0usize); models.len() + 1];
    for t in trackers {
        let get = |m: &str| rows.iter().find(|r| r.file == t.name && r.model == m);
        let Some(nom) = get("nominal") else { continue };
        print!("  {:<26} {:>5} {:>4}", t.name, nom.arm, nom.summary.n);
        for (k, m) in models
            .iter()
            .chain(std::iter::once(&"file_geometry"))
            .enumerate()
        {
            if let Some(r) = get(m) {
                let s = r.summary;
                let flag = if k > 0 && k < models.len() && s.rms_mm > nom.summary.rms_mm {
                    "!"
                } else {
                    " "
                };
                print!(" {:>8.3}{flag}", s.rms_mm);
                pooled[k].0 += s.rms_mm.powi(2) * s.n as f64;
                pooled[k].1 += s.n;
            }
        }
        println!();
    }
    print!("  {:<26} {:>5} {:>4}", "pooled", "", pooled[0].1);
    for (s2, n) in pooled {
        print!(" {:>8.3} ", (s2 / n.max(1) as f64).sqrt());
    }
    println!();
    println!("  (! = worse than nominal in rms; `all`/`all+c` saw these files' tracker values, so they are not held out)");
}

/// For each model of `models`: on how many tracker files it beats nominal, split into the files
/// whose pattern is in `selection` (used to CHOOSE the `self` and `planes` models, so not a clean test of the
/// choice) and the others (the evaluation files, never used in any such choice), with the
/// pooled rms of each part.
pub fn print_selection_split(
    rows: &[ScoreRow],
    trackers: &[&Recording],
    models: &[&str],
    selection: &[&str],
) {
    println!(
        "no-tracker models on the selection files ({}; used for the tracker choice) and the evaluation files (the rest; never used in a no-tracker choice):",
        selection.join(", ")
    );
    for m in models {
        for (part, used) in [("selection", true), ("evaluation", false)] {
            let (mut better, mut files, mut s2, mut s2_nom, mut n) = (0, 0, 0.0, 0.0, 0usize);
            for t in trackers
                .iter()
                .filter(|t| selection.contains(&t.pattern) == used)
            {
                let get = |name: &str| rows.iter().find(|r| r.file == t.name && r.model == name);
                let (Some(nom), Some(r)) = (get("nominal"), get(m)) else {
                    continue;
                };
                files += 1;
                better += usize::from(r.summary.rms_mm < nom.summary.rms_mm);
                s2 += r.summary.rms_mm.powi(2) * r.summary.n as f64;
                s2_nom += nom.summary.rms_mm.powi(2) * nom.summary.n as f64;
                n += r.summary.n;
            }
            let n = n.max(1) as f64;
            println!(
                "  {m:<10} {part:<10}: better than nominal on {better} of {files} files; pooled {:.3} mm (nominal {:.3})",
                (s2 / n).sqrt(),
                (s2_nom / n).sqrt()
            );
        }
    }
}

/// Writes the score rows (n, rms, median, p95, max in mm, and the folder the row's model was
/// exported to, empty when none: [`crate::splits::exported_column`]) to `path`.
fn write_scores(
    path: &Path,
    rows: &[ScoreRow],
    exported: &[(String, Vec<String>)],
) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    writeln!(
        w,
        "file,arm,model,kinematics_held_out,n,rms_mm,median_mm,p95_mm,max_mm,exported"
    )?;
    for r in rows {
        let s = r.summary;
        writeln!(
            w,
            "{},{},{},{},{},{:.4},{:.4},{:.4},{:.4},{}",
            r.file,
            r.arm,
            r.model,
            r.held_out,
            s.n,
            s.rms_mm,
            s.median_mm,
            s.p95_mm,
            s.max_mm,
            exported_column(exported, &r.model)
        )?;
    }
    Ok(())
}

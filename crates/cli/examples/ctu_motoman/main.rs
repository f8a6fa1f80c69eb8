//! The CTU dual-arm Motoman study (issue 12): calibrate the real cell three ways from the
//! dataset's recordings, score nominal and calibrated models on every tracker file with the
//! honest protocol, and report what the model gets wrong.
//!
//! ```sh
//! cargo run --release --example ctu_motoman -- --data ../shared/data/ctu-motoman --out DIR
//! ```
//!
//! Writes `DIR/{self,planes,all}/` (cell.toml, right_arm.urdf, left_arm.urdf, parameters.csv,
//! cv.csv; the cross-validated choice), `DIR/{self,planes,all}+c/` (the choice among the
//! candidates with L/U gravity compliance, same files but cv.csv), `DIR/{self,planes}+m/` (the
//! choice among the candidates with the marker centres), `DIR/scores.csv`,
//! `DIR/scores_per_file.svg`, `DIR/residual_vs_joint.svg`, `DIR/contact_pairs.{csv,svg}` (the
//! self-contacts' face pairs), `DIR/proxy.csv` (the hidden-set proxy, model vs model) and, with
//! `--score-every-self-candidate`, `DIR/self_candidates.csv`. Method and findings:
//! docs/ctu-motoman-findings.md (sections "Rust study" and "Contact geometry, the headline
//! target and a hidden-set proxy").
//!
//! One job: the study's driver — arguments, which model is fitted on which recordings, export,
//! and the printed/CSV reports. Reading the dataset is `data`, the fits and the scoring protocol
//! are `study`, the cross-validated choice is `cv`, the face-contact geometry is `contact`, the
//! proxy set is `proxy`, the figures are `plot`.

mod contact;
mod cv;
mod data;
mod plot;
mod proxy;
mod study;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use calib_core::whole_cell::{CellFit, CellParam, CellProblem, ObservationKind};
use clap::Parser;
use kinematics::{true_base_from_tip, ErrorParam, KinematicErrors};
use sim_cell::{export_calibrated_cell, Cell, ExportNames};

use cv::{cross_validate, print_cv, write_cv, Choice, CvRule};
use data::{read_dataset, Recording, Role};
use study::{
    build_problem, corrections, fit, held_out_nuisance_cost, noise_from_nominal, residuals,
    score_recording, summarise, ModelSpec, NoiseLevels, ParamSet, ScoredPose, Summary,
    COMPLIANT_JOINTS,
};

/// The CTU dual-arm Motoman study: three calibrations (self-contact; + planes; + tracker), each
/// exported as a cell, scored on every tracker file (registration and reflector fitted on one
/// half of a file, scored on the other half, both ways). Lengths in mm, angles in degrees/mrad.
#[derive(Parser, Debug)]
struct Args {
    /// The dataset folder (holds README.md and the *_dataset.csv files), read in place.
    #[arg(long)]
    data: PathBuf,
    /// Output folder (created): self/, planes/, all/, scores.csv and the SVG figures.
    #[arg(long)]
    out: PathBuf,
    /// How cross-validation picks the parameter set and prior σ: `one-se` (the simplest
    /// candidate within one standard error of the smallest CV error; default) or `min` (the
    /// smallest CV error).
    #[arg(long, value_enum, default_value_t = CvRule::OneSe)]
    cv_rule: CvRule,
    /// Contact σ of the no-tracker self-contacts in the fits that fit the marker centres:
    /// `nominal` (default: the nominal model's contact residual, as every other candidate) or
    /// `marker` (the residual of the fit with only the marker centres, nominal joints: the noise
    /// rule applied to the marker model). Held-out CV errors use `nominal` units either way.
    #[arg(long, value_enum, default_value_t = MarkerContactSigma::Nominal)]
    marker_contact_sigma: MarkerContactSigma,
    /// Diagnostic, selects nothing: also fit EVERY `self` CV candidate on all the self-contact
    /// files and score each on every tracker file, to `DIR/self_candidates.csv` (does any
    /// self-contact model beat nominal everywhere?). Adds about half a minute.
    #[arg(long)]
    score_every_self_candidate: bool,
    /// The folds of the `self` cross-validation: `pattern` (default: leave one contact pattern
    /// out, upper vs lower) or `face-pair` (leave one of the 8 face pairs out; the held-out
    /// pair's contact distance is refitted, so it scores the scatter within the pair).
    #[arg(long, value_enum, default_value_t = SelfFolds::Pattern)]
    self_cv_folds: SelfFolds,
}

/// `--self-cv-folds`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum SelfFolds {
    /// Leave one contact pattern out (upper, lower).
    Pattern,
    /// Leave one face pair out.
    FacePair,
}

/// `--marker-contact-sigma`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum MarkerContactSigma {
    /// The nominal model's contact residual.
    Nominal,
    /// The residual of the marker-only fit.
    Marker,
}

/// Right arm = robot 1, left arm = robot 2.
fn export_names(header: &str) -> ExportNames<'_> {
    ExportNames {
        cell: "cell.toml",
        robot1_urdf: "right_arm.urdf",
        robot2_urdf: "left_arm.urdf",
        header,
    }
}

/// The repository root (the cell and URDFs of the nominal model live there).
fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
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
struct Calibrated {
    name: String,
    problem: CellProblem,
    fit: CellFit,
    spec: ModelSpec,
}

/// The MAP fit of `recs` with `spec`; `name` labels the score rows.
fn calibrate(
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
/// exported cell from the corrected URDF (`sim_cell::export_calibrated_cell`'s caveat).
/// Returns (rms, max) of that departure, m.
fn export(
    cell: &Cell,
    c: &Calibrated,
    folder: &str,
    recs: &[&Recording],
    out: &Path,
    how: &str,
) -> anyhow::Result<(f64, f64)> {
    let dir = out.join(folder);
    let header = format!(
        "# Written by `cargo run --example ctu_motoman`: the CTU dual-arm Motoman cell calibrated from\n\
         # {how}.\n# robot1 = right arm, robot2 = left arm; parameter set {} with prior σ {} mrad / mm \
         (chosen by grouped CV).\n# Joint offsets and origins are in right_arm.urdf / left_arm.urdf.\n",
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
struct Calibrations {
    /// Rule over every candidate.
    chosen: Calibrated,
    /// Rule over the candidates without compliance and without marker centres (the study before
    /// either was a candidate).
    without: Calibrated,
    /// Rule over the candidates with compliance.
    with: Calibrated,
    /// Rule over the candidates with the marker centres (when there are such candidates).
    marker: Option<Calibrated>,
}

impl Calibrations {
    /// The models to score, each once: `without`, `with`, `marker`, and `chosen` when it is
    /// none of these.
    fn scored(&self) -> Vec<&Calibrated> {
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
fn calibrate_all(
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

/// One row of the score table.
struct ScoreRow {
    file: String,
    arm: &'static str,
    model: String,
    held_out: bool,
    summary: Summary,
}

fn main() -> std::process::ExitCode {
    match run(Args::parse()) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    if !args.data.is_dir() {
        bail!(
            "--data {}: no such folder; give the ctu-motoman dataset folder, e.g. \
             --data ../shared/data/ctu-motoman",
            args.data.display()
        );
    }
    let recordings = read_dataset(&args.data)?;
    let cell_path = repo_root().join("cells/ctu-motoman.toml");
    let cell = Cell::from_toml_file(&cell_path)?;
    if cell.b1_from_b2_sigma.is_none() {
        bail!(
            "{}: no `[b1_from_b2] sigma_mm, sigma_deg`; the study holds the common base by that \
             placement prior (both DH tables start at one base frame)",
            cell_path.display()
        );
    }
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}", args.out.display()))?;
    println!(
        "read {} recordings ({} poses) from {}",
        recordings.len(),
        recordings.iter().map(|r| r.poses.len()).sum::<usize>(),
        args.data.display()
    );

    // Noise of each class: the nominal model's residual (nuisances fitted on every recording).
    let mut noise = noise_from_nominal(&cell, &recordings)?;
    println!(
        "noise σ from the nominal fit (rms per scalar row): contact {:.3} mm, leica_self contact {:.3} mm, plane {:.3} mm, tracker {:.3} mm/axis",
        noise.contact_m * 1e3,
        noise.leica_contact_m * 1e3,
        noise.plane_m * 1e3,
        noise.tracker_m * 1e3
    );

    let by_role = |roles: &[Role]| -> Vec<&Recording> {
        recordings
            .iter()
            .filter(|r| roles.contains(&r.role))
            .collect()
    };
    if args.marker_contact_sigma == MarkerContactSigma::Marker {
        let m = calibrate(
            &cell,
            "marker only (for the contact σ)".into(),
            &by_role(&[Role::SelfContact]),
            ModelSpec {
                set: ParamSet::OffsetsMarker,
                sigma: 0.0,
            },
            &noise,
        )?;
        noise.marker_contact_m = Some(contact_rms(&m)?);
        println!(
            "--marker-contact-sigma marker: contact σ of the marker-centre fits {:.3} mm",
            contact_rms(&m)? * 1e3
        );
    }
    let nuisance_score = |test: &[&Recording], corr: (&KinematicErrors, &KinematicErrors)| {
        held_out_nuisance_cost(&cell, test, corr, &noise)
    };

    // --- self: no-tracker self-contact only; CV leaves one contact pattern out.
    let self_recs = by_role(&[Role::SelfContact]);
    let (pair_recs, pair_folds) = {
        let ring = contact::fit_ring(&cell, &self_recs)?;
        contact::split_by_face_pair(&cell, &self_recs, &ring)?
    };
    let (cv_recs, cv_folds, cv_title): (Vec<&Recording>, Vec<&str>, &str) = match args.self_cv_folds
    {
        SelfFolds::Pattern => (
            self_recs.clone(),
            vec!["self_upper", "self_lower"],
            "CV self (leave one contact pattern out, upper vs lower; held-out contact rms in σ units):",
        ),
        SelfFolds::FacePair => (
            pair_recs.iter().collect(),
            pair_folds,
            "CV self (--self-cv-folds face-pair: leave one face pair out of 8, its distance refitted; held-out contact rms in σ units):",
        ),
    };
    let self_choice = cross_validate(
        &cell,
        &cv_recs,
        &ParamSet::WITH_MARKER,
        &cv_folds,
        &noise,
        args.cv_rule,
        &nuisance_score,
    )?;
    print_cv(
        cv_title,
        "held-out rms",
        &ParamSet::WITH_MARKER,
        &self_choice,
    );
    let cal_self = calibrate_all(
        &cell,
        "self",
        &self_recs,
        &self_choice,
        &noise,
        &args.out,
        "the no-tracker self-contact files only (no tracker value used)",
    )?;
    println!("self done at {:.1} s", t0.elapsed().as_secs_f64());
    write_cv(
        &args.out.join("self/cv.csv"),
        &self_choice,
        "heldout_rms_sigma",
    )?;
    let leica_self = by_role(&[Role::TrackerSelfContact]);
    contact_report(&cell, &self_recs, &leica_self, &cal_self, &noise, &args.out)?;

    // --- planes: self-contact + no-tracker planes; CV leaves one pattern out (5).
    let plane_recs = by_role(&[Role::SelfContact, Role::Plane]);
    let plane_choice = cross_validate(
        &cell,
        &plane_recs,
        &ParamSet::WITH_MARKER,
        &["self_upper", "self_lower", "wall", "higher", "lower"],
        &noise,
        args.cv_rule,
        &nuisance_score,
    )?;
    print_cv(
        "CV planes (leave one pattern out of 5: self upper/lower, wall, higher, lower table; held-out rms in σ units):",
        "held-out rms",
        &ParamSet::WITH_MARKER,
        &plane_choice,
    );
    let cal_planes = calibrate_all(
        &cell,
        "planes",
        &plane_recs,
        &plane_choice,
        &noise,
        &args.out,
        "the no-tracker self-contact and plane-contact files (no tracker value used)",
    )?;
    println!("planes done at {:.1} s", t0.elapsed().as_secs_f64());
    write_cv(
        &args.out.join("planes/cv.csv"),
        &plane_choice,
        "heldout_rms_sigma",
    )?;

    // --- all: everything, tracker files included; CV holds out whole tracker patterns and
    // scores them with the honest protocol (mm).
    let all_recs: Vec<&Recording> = recordings.iter().collect();
    let tracker_score = |test: &[&Recording], corr: (&KinematicErrors, &KinematicErrors)| {
        let mut e2 = Vec::new();
        for r in test {
            for p in score_recording(&cell, r, corr, None)? {
                e2.push((p.error_m * 1e3).powi(2));
            }
        }
        Ok(e2)
    };
    let all_choice = cross_validate(
        &cell,
        &all_recs,
        &ParamSet::ALL,
        &["right_grid", "left_grid", "leica_table", "leica_self"],
        &noise,
        args.cv_rule,
        &tracker_score,
    )?;
    print_cv(
        "CV all (hold out whole tracker files: right grid, left grid, the 6 table/wall files, the 4 leica_self files; held-out tracker rms, mm):",
        "held-out tracker rms",
        &ParamSet::ALL,
        &all_choice,
    );
    let cal_all = calibrate_all(
        &cell,
        "all",
        &all_recs,
        &all_choice,
        &noise,
        &args.out,
        "every recording of the dataset, tracker files included",
    )?;
    println!("all done at {:.1} s", t0.elapsed().as_secs_f64());
    write_cv(
        &args.out.join("all/cv.csv"),
        &all_choice,
        "heldout_tracker_rms_mm",
    )?;
    // Do the self-contacts agree with the tracker-derived joint offsets? The marker centres fitted
    // on the no-tracker self-contacts with the joints held at `all`'s.
    {
        let b = build_problem(
            &cell,
            &self_recs,
            Some(ModelSpec {
                set: ParamSet::OffsetsMarker,
                sigma: 0.0,
            }),
            &noise,
        );
        let (r, l) = corrections(&cal_all.chosen.fit);
        let f = fit(&b, None, Some((&r, &l)))?;
        let c = Calibrated {
            name: "marker at all".into(),
            problem: b.problem,
            fit: f,
            spec: cal_all.chosen.spec,
        };
        println!(
            "self-contact residual with the marker centres fitted and the joints held at `all` (tracker-derived): {:.3} mm",
            contact_rms(&c)? * 1e3
        );
    }

    // --- scores on every tracker file: each calibration without and with compliance.
    let zero = KinematicErrors::zero(6);
    let models: Vec<(String, KinematicErrors, KinematicErrors, bool)> =
        std::iter::once(("nominal".to_string(), zero.clone(), zero.clone(), true))
            .chain(
                [&cal_self, &cal_planes, &cal_all]
                    .iter()
                    .flat_map(|c| c.scored())
                    .map(|c| {
                        let (r, l) = corrections(&c.fit);
                        (c.name.clone(), r, l, !c.name.starts_with("all"))
                    }),
            )
            .collect();
    let mut rows: Vec<ScoreRow> = Vec::new();
    let mut per_pose: Vec<(String, String, Vec<ScoredPose>)> = Vec::new();
    let trackers = by_role(&[Role::Tracker, Role::TrackerSelfContact]);
    for rec in &trackers {
        let arm = if rec.right_arm { "right" } else { "left" };
        for (name, r, l, held_out) in &models {
            let s = score_recording(&cell, rec, (r, l), None)?;
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
        let s = score_recording(&cell, rec, (&zero, &zero), Some(10.0))?;
        let errs: Vec<f64> = s.iter().map(|p| p.error_m).collect();
        rows.push(ScoreRow {
            file: rec.name.clone(),
            arm,
            model: "file_geometry".into(),
            held_out: true,
            summary: summarise(&errs),
        });
    }
    let names: Vec<&str> = models.iter().map(|m| m.0.as_str()).collect();
    print_scores(&rows, &trackers, &names);
    if args.score_every_self_candidate {
        score_every_candidate(
            &cell,
            &self_recs,
            &self_choice,
            &noise,
            &trackers,
            &rows,
            &args.out,
        )?;
    }
    write_scores(&args.out.join("scores.csv"), &rows)?;
    plot::per_file_svg(
        &args.out.join("scores_per_file.svg"),
        &rows_for_plot(&rows, &trackers, &names),
    )?;
    plot::residual_vs_joint_svg(
        &args.out.join("residual_vs_joint.svg"),
        &per_pose,
        &trackers,
        &cal_self.chosen.name,
    )?;
    println!(
        "wrote {}, {}, {}",
        args.out.join("scores.csv").display(),
        args.out.join("scores_per_file.svg").display(),
        args.out.join("residual_vs_joint.svg").display()
    );
    let reference = corrections(&cal_all.chosen.fit).0;
    let mut compared: Vec<(String, KinematicErrors)> = vec![("nominal".into(), zero.clone())];
    for c in [&cal_self, &cal_planes] {
        compared.push((
            format!("{} (exported)", c.chosen.name),
            corrections(&c.chosen.fit).0,
        ));
        if let Some(m) = c.marker.as_ref().filter(|m| m.name != c.chosen.name) {
            compared.push((m.name.clone(), corrections(&m.fit).0));
        }
    }
    compared.push((cal_all.with.name.clone(), corrections(&cal_all.with.fit).0));
    proxy_report(&cell, &recordings, &reference, &compared, &args.out)?;
    print_effects(&cal_all.chosen);
    for (folder, c) in [("self", &cal_self.chosen), ("planes", &cal_planes.chosen)] {
        println!(
            "{folder} (exported): {} σ {} — see {folder}/parameters.csv",
            c.spec.set.name(),
            c.spec.sigma,
        );
    }
    println!("done in {:.1} s", t0.elapsed().as_secs_f64());
    Ok(())
}

/// The rms of the contact rows' residuals (centre distance minus the fitted contact distance)
/// of a calibration, m.
fn contact_rms(c: &Calibrated) -> anyhow::Result<f64> {
    let res = residuals(&c.problem, &c.fit, &c.fit.estimate)?;
    let (mut s2, mut n) = (0.0, 0usize);
    for (o, (r, _)) in c.problem.observations.iter().zip(&res) {
        if matches!(o.kind, ObservationKind::Contact { .. }) {
            s2 += r * r;
            n += 1;
        }
    }
    Ok((s2 / n.max(1) as f64).sqrt())
}

/// Contact geometry (`contact` module): the measured ring of face normals, the face pairs of the
/// no-tracker self-contacts and of `leica_self`, the along-normal distance per pair at nominal,
/// with only the marker centres fitted (nominal joints) and at the `self` models; the contact
/// residual before and after; the `leica_self` contact scatter (no tracker value: an
/// independent check of the `self` models). Writes `out/contact_pairs.csv` and
/// `out/contact_pairs.svg`.
fn contact_report(
    cell: &Cell,
    self_recs: &[&Recording],
    leica_self: &[&Recording],
    cal_self: &Calibrations,
    noise: &NoiseLevels,
    out: &Path,
) -> anyhow::Result<()> {
    let ring = contact::fit_ring(cell, self_recs)?;
    println!(
        "contact geometry (nominal kinematics): {} contact directions in the tool0 frames at polar angle {:.2} ± {:.2}° \
         (ideal ring face: arctan 2 = {:.2}°), ring azimuth φ0 = {:.2}° + k·72°, largest azimuth departure {:.2}°",
        ring.n,
        ring.polar_mean_rad.to_degrees(),
        ring.polar_sd_rad.to_degrees(),
        contact::ring_polar_angle().to_degrees(),
        ring.phi0_rad.to_degrees(),
        ring.azimuth_max_dev_rad.to_degrees()
    );
    let marker_only = calibrate(
        cell,
        "marker only".into(),
        self_recs,
        ModelSpec {
            set: ParamSet::OffsetsMarker,
            sigma: 0.0,
        },
        noise,
    )?;
    let zero = KinematicErrors::zero(6);
    let mut models: Vec<(String, KinematicErrors, KinematicErrors, Option<f64>)> =
        vec![("nominal".into(), zero.clone(), zero.clone(), None)];
    for c in std::iter::once(&marker_only)
        .chain(std::iter::once(&cal_self.chosen))
        .chain(
            cal_self
                .marker
                .iter()
                .filter(|m| m.name != cal_self.chosen.name),
        )
    {
        let (r, l) = corrections(&c.fit);
        models.push((c.name.clone(), r, l, Some(contact_rms(c)?)));
    }
    let corr: Vec<(&KinematicErrors, &KinematicErrors)> =
        models.iter().map(|m| (&m.1, &m.2)).collect();
    let rows = contact::pair_table(cell, self_recs, &ring, &corr)?;
    println!(
        "face pairs of the no-tracker self-contacts ({} pairs; along-normal centre distance mean ± sd, mm; misalignment of the \
         two face normals at nominal, deg):",
        rows.len()
    );
    print!("  {:<8} {:>4}", "(R, L)", "n");
    for m in &models {
        print!(" {:>18}", m.0);
    }
    println!(" {:>14}", "misalign");
    for r in &rows {
        print!(
            "  {:<8} {:>4}",
            format!("({}, {})", r.pair.0, r.pair.1),
            r.n
        );
        for (mu, sd) in &r.along {
            print!(" {:>10.2} ± {:>5.2}", mu * 1e3, sd * 1e3);
        }
        println!(
            " {:>6.3} ± {:.3}",
            r.misalign.0.to_degrees(),
            r.misalign.1.to_degrees()
        );
    }
    print!("  {:<13}", "rms about one distance, mm:");
    for m in 0..models.len() {
        print!(" {:>18.3}", contact::along_rms_about_common(&rows, m) * 1e3);
    }
    println!();
    print!("  {:<13}", "contact residual (fit), mm:");
    for m in &models {
        let v = m.3.unwrap_or(noise.contact_m);
        print!(" {:>18.3}", v * 1e3);
    }
    println!("  (centre distance minus the fitted distance; nominal = the noise σ above)");
    let names: Vec<String> = models
        .iter()
        .map(|m| m.0.replace([' ', '+'], "_"))
        .collect();
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    contact::write_pair_table(&out.join("contact_pairs.csv"), &rows, &name_refs)?;
    plot::contact_pairs_svg(
        &out.join("contact_pairs.svg"),
        &rows,
        &models.iter().map(|m| m.0.as_str()).collect::<Vec<_>>(),
    )?;
    let leica_rows = contact::pair_table(cell, leica_self, &ring, &corr[..1])?;
    println!(
        "leica_self face pairs: {}",
        leica_rows
            .iter()
            .map(|r| format!(
                "({}, {}) n {} along {:.2} ± {:.2} mm",
                r.pair.0,
                r.pair.1,
                r.n,
                r.along[0].0 * 1e3,
                r.along[0].1 * 1e3
            ))
            .collect::<Vec<_>>()
            .join("; ")
    );
    // Independent check without tracker values: the leica_self contact rows alone (their tracker
    // values dropped), contact distance refitted, at each model's corrections.
    let contact_only = leica_contact_only(leica_self);
    let refs: Vec<&Recording> = contact_only.iter().collect();
    print!("leica_self contact scatter (no tracker value; distance refitted), rms mm:");
    for m in &models {
        let e2 = held_out_nuisance_cost(cell, &refs, (&m.1, &m.2), noise)?;
        let rms = (e2.iter().sum::<f64>() / e2.len().max(1) as f64).sqrt() * noise.contact_m;
        print!(" {} {:.3};", m.0, rms * 1e3);
    }
    println!();
    Ok(())
}

/// The `leica_self` recordings among `recs` as no-tracker self-contacts (their tracker values
/// dropped): contact rows only, scored in the no-tracker contact σ.
fn leica_contact_only(recs: &[&Recording]) -> Vec<Recording> {
    recs.iter()
        .filter(|r| r.role == Role::TrackerSelfContact)
        .map(|r| Recording {
            role: Role::SelfContact,
            poses: r
                .poses
                .iter()
                .map(|p| data::Pose {
                    p_tracker: None,
                    ..p.clone()
                })
                .collect(),
            ..(*r).clone()
        })
        .collect()
}

/// Diagnostic (selects nothing): every CV candidate of `choice` fitted on `recs` and scored on
/// every tracker file; prints and writes `out/self_candidates.csv` with the number of files on
/// which each beats nominal (`rows` holds nominal's scores).
fn score_every_candidate(
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
        "DIAGNOSTIC (uses tracker scores, selects nothing): every `self` candidate fitted on all self-contact files; \
         files (of {}) where it beats nominal, pooled rms mm:",
        trackers.len()
    );
    for (spec, cv, _) in &choice.table {
        let b = build_problem(cell, recs, Some(*spec), noise);
        let f = fit(&b, None, None)?;
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
            "  {:<16} σ {:<4} CV {cv:.4}: better on {better:>2}, pooled {pooled:.3}; leica_self contact rms {:.3}",
            spec.set.name(),
            spec.sigma,
            leica_rms * 1e3
        );
    }
    println!("wrote {}", path.display());
    Ok(())
}

/// The hidden-set proxy (`proxy` module): the difference between each model of `compared` and
/// the reference (`all`) over a seeded whole-workspace set of right-arm poses, with the issue's
/// protocol. MODEL vs MODEL, not model vs measurement. Writes `out/proxy.csv`.
fn proxy_report(
    cell: &Cell,
    recordings: &[Recording],
    reference: &KinematicErrors,
    compared: &[(String, KinematicErrors)],
    out: &Path,
) -> anyhow::Result<()> {
    let (joints, draws) = proxy::proxy_joints(cell, recordings)?;
    let mut r = reference.clone();
    r.tip = nalgebra::Vector3::zeros();
    let rec = proxy::reference_recording(cell, &joints, &r)?;
    println!(
        "hidden-set PROXY (model vs model, no measurement): {} right-arm poses (seed {}, {draws} draws in the URDF limits, tool0 above \
         the dataset's lowest and ≥ 0.3 m from the S axis), each model vs `all`, registration + reflector on one half, scored on the other:",
        joints.len(),
        proxy::PROXY_SEED
    );
    let path = out.join("proxy.csv");
    let mut w = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
    writeln!(w, "model,reference,n,rms_mm,median_mm,p95_mm,max_mm")?;
    for (name, m) in compared {
        let s = proxy::model_difference(cell, &rec, m)?;
        println!(
            "  {name:<22} vs all: rms {:.3} mm, median {:.3}, p95 {:.3}, max {:.3}",
            s.rms_mm, s.median_mm, s.p95_mm, s.max_mm
        );
        writeln!(
            w,
            "{name},all,{},{:.4},{:.4},{:.4},{:.4}",
            s.n, s.rms_mm, s.median_mm, s.p95_mm, s.max_mm
        )?;
    }
    println!("wrote {}", path.display());
    Ok(())
}

/// The kinematic parameters of the `all` fit whose value is beyond 3 posterior σ, with a 95 %
/// interval (± 1.96 σ), mm / mrad.
fn print_effects(c: &Calibrated) {
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
fn print_scores(rows: &[ScoreRow], trackers: &[&Recording], models: &[&str]) {
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

fn write_scores(path: &Path, rows: &[ScoreRow]) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    writeln!(
        w,
        "file,arm,model,kinematics_held_out,n,rms_mm,median_mm,p95_mm,max_mm"
    )?;
    for r in rows {
        let s = r.summary;
        writeln!(
            w,
            "{},{},{},{},{},{:.4},{:.4},{:.4},{:.4}",
            r.file, r.arm, r.model, r.held_out, s.n, s.rms_mm, s.median_mm, s.p95_mm, s.max_mm
        )?;
    }
    Ok(())
}

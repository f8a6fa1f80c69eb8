//! The CTU dual-arm Motoman study (issue 12): calibrate the real cell three ways from the
//! dataset's recordings, score nominal and calibrated models on every tracker file with the
//! honest protocol, and report what the model gets wrong.
//!
//! ```sh
//! cargo run --release -p ctu-motoman -- --data ../shared/data/ctu-motoman --out DIR
//! ```
//!
//! Writes `DIR/{self,planes,all}/` (cell.toml, right_arm.urdf, left_arm.urdf, parameters.csv;
//! the region-held-out do-no-harm choice, docs/region-protocol.md), `DIR/file-cv/{self,planes,all}/`
//! (the same files and cv.csv: the file-held-out CV / tracker-selection choice, which
//! `--skip-region-protocol` leaves in `DIR/{self,planes,all}/`), `DIR/{self,planes,all}+c/` (the choice among the
//! candidates with L/U gravity compliance, same files but cv.csv), `DIR/{self,planes}+m/` (the
//! choice among the candidates with the marker centres), `DIR/scores.csv`,
//! `DIR/scores_per_file.svg`, `DIR/residual_vs_joint.svg`, `DIR/contact_pairs.{csv,svg}` (the
//! self-contacts' face pairs), `DIR/proxy.csv` (the hidden-set proxy, model vs model),
//! `DIR/split_robustness{,_per_split}.csv` (the exported models over `--splits` random half
//! splits) and, with `--score-every-self-candidate`, `DIR/self_candidates.csv`. Method and findings:
//! studies/ctu-motoman/docs/findings.md (sections "Rust study" and "Contact geometry, the headline
//! target and a hidden-set proxy").
//!
//! One job: the study's outline — arguments, which model is fitted on which recordings and in
//! what order, which models are scored and compared. The parts are the library's modules (see
//! its documentation, `ctu_motoman`).

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use clap::Parser;
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use ctu_motoman::{contact, splits};

use ctu_motoman::calibrated::{
    calibrate, calibrate_all, contact_rms, export, print_effects, Calibrated, Calibrations,
};
use ctu_motoman::contact_report::{contact_model_comparison, contact_report, marker_at_report};
use ctu_motoman::cv::{cross_validate, print_cv, write_cv, Choice, CvRule, HeldOutScore};
use ctu_motoman::data::{
    read_dataset, self_selection_recordings, Recording, Role, SELF_SELECTION_PATTERNS,
};
use ctu_motoman::proxy_report::proxy_report;
use ctu_motoman::region::{print_region, region_protocol, write_region_csv, REGION_MODELS};
use ctu_motoman::scores::{
    print_scores, print_selection_split, score_every_candidate, score_models, write_score_files,
    ScoredModel,
};
use ctu_motoman::study::{
    corrections, held_out_nuisance_rows, noise_from_nominal, score_recording, ModelSpec,
    NoiseLevels, ParamSet, RowKind, SigmaGrid,
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
    /// How cross-validation picks the parameter set and prior σ: `one-se` (default: the simplest
    /// candidate within one standard error of the smallest CV error of EVERY observation kind,
    /// contact and plane; when none is, the one with the smallest largest shortfall in SEs),
    /// `pooled-one-se` (stop 13's rule: one-SE on the error of all kinds pooled) or `min` (the
    /// smallest pooled CV error). With one kind (`self`, `all`) `one-se` is the one-SE rule.
    #[arg(long, value_enum, default_value_t = CvRule::OneSe)]
    cv_rule: CvRule,
    /// The prior σ values cross-validation chooses from, for all three models (every parameter
    /// set is a candidate at each value): 2 to 8 positive, finite, strictly increasing numbers,
    /// comma-separated. One number s is s mrad for joint offsets, s mm for joint origin
    /// positions (link lengths) and s mrad of deflection at 50 N·m for the L/U compliance. The
    /// default was fixed in stop 9, before any evaluation score was seen, and the exported
    /// models are chosen on it. 10 is not in it: with link lengths free and no length reference
    /// (the contact distance and the planes are fitted), σ 10 lets the whole chain shrink (the
    /// self + planes fit at σ 10 hit the iteration cap at a contact distance of 61.5 mm). Give
    /// another grid to measure beyond its edge (e.g. 0.1,0.3,1,3,10); the output files then
    /// name it.
    #[arg(long, value_name = "LIST", default_value_t = SigmaGrid::default())]
    sigma_grid: SigmaGrid,
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
    /// How the exported `self` and `planes` models (parameter set and prior σ) are chosen. Their
    /// VALUES always come from their own no-tracker files. `tracker` (default; the issue's
    /// protocol: "cross-validation on the self-contact sets, the grids and the tracker
    /// self-contact sets"): every candidate, fitted on the model's files, is scored with the
    /// honest protocol on the SELECTION files (right grid, left grid, the four leica_self files)
    /// and the CV rule picks; the six table/wall tracker files are never used in the choice and
    /// are the evaluation. `cv`: CV on the model's own files (stop 13/14's choice; see
    /// --self-cv-folds). The other choice is fitted and scored too, for comparison.
    #[arg(long, value_enum, default_value_t = Select::Tracker)]
    select: Select,
    /// The observation model of the self-contact rows (no-tracker and `leica_self`): `distance`
    /// (default: the marker centres are the fitted contact distance apart, `Contact`) or `face`
    /// (the distance between the centres along the touching ring faces' mean normal,
    /// `FaceContact`; each pose's faces are assigned at nominal kinematics, the normals fixed in
    /// the marker frames; same contact groups and σ, and the faces may slide). Everything else
    /// (CV, the tracker selection, export, scores) runs unchanged on these rows.
    #[arg(long, value_enum, default_value_t = ContactModel::Distance)]
    contact_model: ContactModel,
    /// How many seeded random half splits of every tracker file the exported models are also
    /// scored over (`DIR/split_robustness.csv`; split 0 is the score table's split). Reporting
    /// only: it chooses nothing.
    #[arg(long, default_value_t = splits::DEFAULT_SPLITS,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    splits: usize,
    /// Skip the region-held-out protocol (docs/region-protocol.md; `DIR/region_held_out.csv`,
    /// `DIR/region_candidates.csv`; without it `DIR/NAME/` keeps the file-held-out choice and
    /// nothing is moved to `DIR/file-cv/`), which fits every candidate of each
    /// model once per training set it needs (several hundred fits, about ten minutes on two
    /// cores). The other outputs do not depend on it.
    #[arg(long)]
    skip_region_protocol: bool,
}

/// `--contact-model`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum ContactModel {
    /// Centre distance.
    Distance,
    /// Distance along the touching faces' mean normal.
    Face,
}

/// `--select`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
enum Select {
    /// Candidates scored on the grids and the leica_self tracker files.
    Tracker,
    /// CV on the model's own (no-tracker) files.
    Cv,
}

/// A no-tracker model (`self` or `planes`): the calibrations of the choice `--select` made, and
/// the other choice's model (named `NAME(cv)` or `NAME(trk)`), fitted for comparison.
struct NoTrackerModel {
    /// The choice `--select` made.
    choice: Choice,
    cal: Calibrations,
    other: Calibrated,
}

/// Chooses, fits and exports the no-tracker model `name` from `recs`: `cv_choice` is the CV on
/// its own files; the tracker choice fits every candidate on `recs` and scores it on `selection`
/// (the recordings of [`self_selection_recordings`], one held-out fold) with `tracker_score`.
/// Writes `out/name/cv.csv` (the choice made), `cv_tracker_selection.csv` and `cv_own.csv`.
#[allow(clippy::too_many_arguments)]
fn no_tracker_model(
    cell: &Cell,
    name: &str,
    recs: &[&Recording],
    cv_choice: Choice,
    selection: &[Recording],
    noise: &NoiseLevels,
    args: &Args,
    tracker_score: &HeldOutScore,
    how: &str,
) -> anyhow::Result<NoTrackerModel> {
    // Every candidate is trained on `recs` (the only recordings whose pattern is not
    // "selection") and scored on the selection files.
    let pool: Vec<&Recording> = recs.iter().copied().chain(selection).collect();
    let tracker_choice = cross_validate(
        cell,
        &pool,
        &ParamSet::WITH_MARKER,
        &args.sigma_grid,
        &["selection"],
        noise,
        args.cv_rule,
        tracker_score,
    )?;
    print_cv(
        &format!(
            "choice of {name} by the tracker selection files (each candidate fitted on the {name} files only, scored on the right grid, left grid and the 4 leica_self files; held-out tracker rms, mm; the table/wall files are not used):"
        ),
        "held-out tracker rms",
        &ParamSet::WITH_MARKER,
        &tracker_choice,
    );
    let dir = args.out.join(name);
    std::fs::create_dir_all(&dir).with_context(|| format!("{}", dir.display()))?;
    write_cv(
        &dir.join("cv_tracker_selection.csv"),
        &tracker_choice,
        "heldout_tracker_rms_mm",
    )?;
    write_cv(&dir.join("cv_own.csv"), &cv_choice, "heldout_rms_sigma")?;
    let (choice, other, other_name, criterion, chosen_how) = match args.select {
        Select::Tracker => (
            tracker_choice,
            cv_choice,
            format!("{name}(cv)"),
            "heldout_tracker_rms_mm",
            "held-out tracker rms on the grids and the leica_self files",
        ),
        Select::Cv => (
            cv_choice,
            tracker_choice,
            format!("{name}(trk)"),
            "heldout_rms_sigma",
            "grouped CV on these files",
        ),
    };
    let cal = calibrate_all(
        cell,
        name,
        recs,
        &choice,
        noise,
        &args.out,
        &format!(
            "{how} (no tracker value in the fit;\n# the set and prior σ chosen by their {chosen_how}{})",
            grid_clause(&args.sigma_grid)
        ),
    )?;
    write_cv(&dir.join("cv.csv"), &choice, criterion)?;
    let other = calibrate(cell, other_name, recs, other.spec, noise)?;
    Ok(NoTrackerModel { cal, other, choice })
}

/// The words the exported cells' header adds to how a model was chosen: nothing with the
/// default σ grid (its files stay as they were), else the grid used, starting a new `# ` line.
fn grid_clause(grid: &SigmaGrid) -> String {
    if grid.is_default() {
        String::new()
    } else {
        format!(
            ",\n# over the prior σ grid {grid} mrad / mm (--sigma-grid; default {})",
            SigmaGrid::default()
        )
    }
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

/// `--contact-model face`: sets the touching faces of every self-contact pose (no-tracker and
/// `leica_self`; the ring measured on the no-tracker self-contacts, faces assigned at nominal
/// kinematics), so that their rows are built as `FaceContact`, and prints how far the faces
/// slide at nominal.
fn face_contact_rows(cell: &Cell, recordings: &mut [Recording]) -> anyhow::Result<()> {
    let ring = {
        let self_recs: Vec<&Recording> = recordings
            .iter()
            .filter(|r| r.role == Role::SelfContact)
            .collect();
        contact::fit_ring(cell, &self_recs)?
    };
    let n = contact::assign_face_normals(cell, recordings, &ring)?;
    println!(
        "--contact-model face: {n} self-contact rows are face contacts (ring φ0 = {:.2}°)",
        ring.phi0_rad.to_degrees()
    );
    let zero = KinematicErrors::zero(6);
    for role in [Role::SelfContact, Role::TrackerSelfContact] {
        let mut c = Vec::new();
        for rec in recordings.iter().filter(|r| r.role == role) {
            c.extend(contact::face_contacts(cell, rec, &ring, (&zero, &zero))?);
        }
        println!(
            "  {} at nominal: {}",
            if role == Role::SelfContact {
                "no-tracker self-contacts"
            } else {
                "leica_self contacts"
            },
            contact::slide_summary(&c)
        );
    }
    Ok(())
}

/// The region-held-out protocol (docs/region-protocol.md) for `self`, `planes` and `all`: per
/// model the export choice and the nested figure per region, printed and appended to
/// `DIR/region_held_out.csv` / `DIR/region_candidates.csv` as each model finishes. The export
/// choice is the model's default export (README, "Which model each folder holds"): the old
/// choice's `DIR/NAME/` moves to `DIR/file-cv/NAME/`, and the do-no-harm choice, refitted on
/// all the model's files, is exported as `DIR/NAME/`; when the choice is nominal, `DIR/NAME/`
/// holds only `NOMINAL.txt`, which says so and why (the nominal cell is
/// `cells/ctu-motoman.toml`).
fn region_protocol_report(
    cell: &Cell,
    recordings: &[Recording],
    noise: &NoiseLevels,
    args: &Args,
) -> anyhow::Result<()> {
    for (k, model) in REGION_MODELS.iter().enumerate() {
        let outcome = region_protocol(cell, recordings, model, &args.sigma_grid, noise)?;
        let export_choice = outcome.export()?;
        let nested = outcome.nested()?;
        print_region(&outcome, &export_choice, &nested);
        write_region_csv(&args.out, &outcome, &export_choice, &nested, k == 0)?;
        let folder = model.name.to_string();
        let old = args.out.join(model.name);
        if old.is_dir() {
            let kept = args.out.join("file-cv").join(model.name);
            std::fs::create_dir_all(args.out.join("file-cv"))?;
            if kept.exists() {
                std::fs::remove_dir_all(&kept)
                    .with_context(|| format!("removing {}", kept.display()))?;
            }
            std::fs::rename(&old, &kept)
                .with_context(|| format!("moving {} to {}", old.display(), kept.display()))?;
            println!(
                "  {}/ (the file-held-out CV / tracker-selection choice) moved to file-cv/{}/",
                model.name, model.name
            );
        }
        match export_choice.rule.choice {
            Some(c) => {
                let recs: Vec<&Recording> = recordings
                    .iter()
                    .filter(|r| model.roles.contains(&r.role))
                    .collect();
                let cal = calibrate(cell, folder.clone(), &recs, outcome.candidates[c], noise)?;
                export(
                    cell,
                    &cal,
                    &folder,
                    &recs,
                    &args.out,
                    &format!(
                        "the {} model's files, the set and prior σ chosen by the region-held-out\n\
                         # do-no-harm rule (docs/region-protocol.md){}",
                        model.name,
                        grid_clause(&args.sigma_grid)
                    ),
                )?;
            }
            None => {
                let dir = args.out.join(&folder);
                std::fs::create_dir_all(&dir)?;
                let note = dir.join("NOMINAL.txt");
                std::fs::write(
                    &note,
                    format!(
                        "The region-held-out do-no-harm rule (docs/region-protocol.md) chose the nominal \
                         model for `{}`: no candidate is better than nominal in every held-out region \
                         (or none is better by more than one SE). Use cells/ctu-motoman.toml; the \
                         per-region ratios are in ../region_candidates.csv.\n",
                        model.name
                    ),
                )
                .with_context(|| format!("{}", note.display()))?;
                println!(
                    "  {folder}: the choice is nominal; wrote {} (the nominal cell is \
                     cells/ctu-motoman.toml)",
                    note.display()
                );
            }
        }
    }
    Ok(())
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
    // The old (file-held-out CV) choices' folders as they are when the run ends: the region
    // protocol moves `self/`, `planes/`, `all/` to `file-cv/`, so every table labels them so.
    let region_protocol = !args.skip_region_protocol;
    let final_folder = |f: &str| splits::final_folder(f, region_protocol);
    if !args.data.is_dir() {
        bail!(
            "--data {}: no such folder; give the ctu-motoman dataset folder, e.g. \
             --data ../shared/data/ctu-motoman",
            args.data.display()
        );
    }
    let mut recordings = read_dataset(&args.data)?;
    let cell_path = ctu_motoman::repo_root().join("cells/ctu-motoman.toml");
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

    if args.contact_model == ContactModel::Face {
        // The σ above stay the distance model's (measured before the faces are set), so the
        // two models are fitted with the same weights.
        face_contact_rows(&cell, &mut recordings)?;
    }

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
        held_out_nuisance_rows(&cell, test, corr, &noise)
    };
    // The honest protocol on held-out tracker files (mm), one squared error per point.
    let tracker_score = |test: &[&Recording], corr: (&KinematicErrors, &KinematicErrors)| {
        let mut e2 = Vec::new();
        for r in test {
            for p in score_recording(&cell, r, corr, None)? {
                e2.push((RowKind::Tracker, (p.error_m * 1e3).powi(2)));
            }
        }
        Ok(e2)
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
    let contact_choice = cross_validate(
        &cell,
        &cv_recs,
        &ParamSet::WITH_MARKER,
        &args.sigma_grid,
        &cv_folds,
        &noise,
        args.cv_rule,
        &nuisance_score,
    )?;
    print_cv(
        cv_title,
        "held-out rms",
        &ParamSet::WITH_MARKER,
        &contact_choice,
    );
    let selection = self_selection_recordings(&recordings);
    let self_model = no_tracker_model(
        &cell,
        "self",
        &self_recs,
        contact_choice,
        &selection,
        &noise,
        &args,
        &tracker_score,
        "the no-tracker self-contact files only",
    )?;
    println!("self done at {:.1} s", t0.elapsed().as_secs_f64());
    let cal_self = &self_model.cal;
    let self_exported = format!("self (exported to {}/)", final_folder("self"));
    let leica_self = by_role(&[Role::TrackerSelfContact]);
    contact_report(&cell, &self_recs, &leica_self, cal_self, &noise, &args.out)?;
    if args.contact_model == ContactModel::Face {
        contact_model_comparison(
            &cell,
            &self_recs,
            &[
                (&self_exported, cal_self.chosen.spec),
                (&self_model.other.name, self_model.other.spec),
                // face_contact.py's pattern-CV choice (same set and σ, like for like).
                (
                    "face_contact.py's choice",
                    ModelSpec {
                        set: ParamSet::OffsetsMarker,
                        sigma: 0.3,
                    },
                ),
            ],
            &noise,
        )?;
    }

    // --- planes: self-contact + no-tracker planes; CV leaves one pattern out (5).
    let plane_recs = by_role(&[Role::SelfContact, Role::Plane]);
    let plane_choice = cross_validate(
        &cell,
        &plane_recs,
        &ParamSet::WITH_MARKER,
        &args.sigma_grid,
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
    let planes_model = no_tracker_model(
        &cell,
        "planes",
        &plane_recs,
        plane_choice,
        &selection,
        &noise,
        &args,
        &tracker_score,
        "the no-tracker self-contact and plane-contact files",
    )?;
    println!("planes done at {:.1} s", t0.elapsed().as_secs_f64());
    let cal_planes = &planes_model.cal;

    // --- all: everything, tracker files included; CV holds out whole tracker patterns and
    // scores them with the honest protocol (mm).
    let all_recs: Vec<&Recording> = recordings.iter().collect();
    let all_choice = cross_validate(
        &cell,
        &all_recs,
        &ParamSet::ALL,
        &args.sigma_grid,
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
        &format!(
            "every recording of the dataset, tracker files included (the set and prior σ chosen by\n\
             # grouped CV, whole tracker files held out{})",
            grid_clause(&args.sigma_grid)
        ),
    )?;
    println!("all done at {:.1} s", t0.elapsed().as_secs_f64());
    write_cv(
        &args.out.join("all/cv.csv"),
        &all_choice,
        "heldout_tracker_rms_mm",
    )?;
    // Do the self-contacts agree with the tracker-derived joint offsets?
    marker_at_report(&cell, &self_recs, &cal_all.chosen, &noise)?;

    // --- scores on every tracker file: each calibration without and with compliance.
    let zero = KinematicErrors::zero(6);
    let models: Vec<ScoredModel> =
        std::iter::once(("nominal".to_string(), zero.clone(), zero.clone(), true))
            .chain(
                [cal_self, cal_planes, &cal_all]
                    .iter()
                    .flat_map(|c| c.scored())
                    .chain([&self_model.other, &planes_model.other])
                    .map(|c| {
                        let (r, l) = corrections(&c.fit);
                        (c.name.clone(), r, l, !c.name.starts_with("all"))
                    }),
            )
            .collect();
    let trackers = by_role(&[Role::Tracker, Role::TrackerSelfContact]);
    let (rows, per_pose) = score_models(&cell, &models, &trackers)?;
    let names: Vec<&str> = models.iter().map(|m| m.0.as_str()).collect();
    print_scores(&rows, &trackers, &names);
    let exported = splits::exported_folders(
        &args.out,
        &[
            ("self", cal_self),
            ("planes", cal_planes),
            ("all", &cal_all),
        ],
        region_protocol,
    )?;
    splits::print_exported(&exported);
    print_selection_split(
        &rows,
        &trackers,
        &[
            &cal_self.chosen.name,
            &self_model.other.name,
            &cal_planes.chosen.name,
            &planes_model.other.name,
        ],
        &SELF_SELECTION_PATTERNS,
    );
    if args.score_every_self_candidate {
        score_every_candidate(
            &cell,
            &self_recs,
            &self_model.choice,
            &noise,
            &trackers,
            &rows,
            &args.out,
        )?;
    }
    write_score_files(
        &args.out,
        &rows,
        &per_pose,
        &trackers,
        &names,
        &cal_self.chosen.name,
        &exported,
    )?;
    splits::split_robustness(&cell, &models, &trackers, &exported, args.splits, &args.out)?;
    println!(
        "split robustness done at {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    let reference = corrections(&cal_all.chosen.fit).0;
    let mut compared: Vec<(String, KinematicErrors)> = vec![("nominal".into(), zero.clone())];
    for (folder, c) in [("self", cal_self), ("planes", cal_planes)] {
        compared.push((
            format!("{} (exported to {}/)", c.chosen.name, final_folder(folder)),
            corrections(&c.chosen.fit).0,
        ));
        if let Some(m) = c.marker.as_ref().filter(|m| m.name != c.chosen.name) {
            compared.push((m.name.clone(), corrections(&m.fit).0));
        }
    }
    for m in [&self_model, &planes_model] {
        compared.push((m.other.name.clone(), corrections(&m.other.fit).0));
    }
    compared.push((cal_all.with.name.clone(), corrections(&cal_all.with.fit).0));
    let reference_label = format!("{} ({}/)", cal_all.chosen.name, final_folder("all"));
    proxy_report(
        &cell,
        &recordings,
        &reference,
        &reference_label,
        &compared,
        &args.out,
    )?;
    if !args.skip_region_protocol {
        region_protocol_report(&cell, &recordings, &noise, &args)?;
        println!(
            "region protocol done at {:.1} s",
            t0.elapsed().as_secs_f64()
        );
    }
    print_effects(&cal_all.chosen);
    for (folder, c) in [("self", &cal_self.chosen), ("planes", &cal_planes.chosen)] {
        let folder = final_folder(folder);
        println!(
            "{folder} (the file-held-out choice): {} σ {} (σ grid {}) — see {folder}/parameters.csv",
            c.spec.set.name(),
            c.spec.sigma,
            args.sigma_grid,
        );
    }
    println!("done in {:.1} s", t0.elapsed().as_secs_f64());
    Ok(())
}

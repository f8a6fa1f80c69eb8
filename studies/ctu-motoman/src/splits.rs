//! How much one split decides: the exported models scored on every tracker file over K seeded
//! random half splits (`--splits K`), with the score table's own protocol
//! ([`score_recording_split`]: registration + reflector refitted on one half per split, the
//! kinematics held), printed and written as `split_robustness.csv` and
//! `split_robustness_per_split.csv`; and which score-table row was exported to which folder
//! (the `exported` column of `scores.csv`).
//!
//! The small tracker files (16–25 poses: 8–12 per half against the 9 parameters of the
//! registration and the reflector) make one split's per-file figure noisy, so "better than
//! nominal on 12 of 12 files" at [`SPLIT_SEED`] is one draw; these counts say how often it holds.

use std::collections::HashSet;
use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context};
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use crate::calibrated::Calibrations;
use crate::data::Recording;
use crate::study::{halves, score_recording_split, summarise, SPLIT_SEED};

/// Default of `--splits`: the number of random half splits per tracker file. 50, not 100:
/// measured, 100 splits of the 8 scored models cost 16–18 s of CPU, 7.5 s wall at load 1.8 and
/// 15 s at load 2.5 on the 2 shared cores (the whole run 29 s and 49 s, against 21 s without
/// them); 50 splits cost 4 s wall at load 1.8. A count k of 50 has a binomial standard error of
/// at most 7 points in 100; `--splits 100` for finer counts.
pub const DEFAULT_SPLITS: usize = 50;
/// Threads over which the (file, model, split) scores are spread. Each score is independent and
/// the results are put back in a fixed order, so the result does not depend on this number.
pub const SPLIT_THREADS: usize = 2;
/// Step between candidate seeds (the splitmix64 increment, ⌊2⁶⁴/φ⌋): candidate `j` is
/// `SPLIT_SEED + j·SEED_STEP` (wrapping), so candidate 0 is [`SPLIT_SEED`].
const SEED_STEP: u64 = 0x9E37_79B9_7F4A_7C15;
/// Candidate seeds tried per wanted split before [`split_seeds`] gives up (only reached when
/// the file has barely more distinct half splits than asked for).
const CANDIDATES_PER_SPLIT: usize = 100;

/// Candidate seed `j` of the split sequence (candidate 0 = [`SPLIT_SEED`]).
pub fn candidate_seed(j: usize) -> u64 {
    SPLIT_SEED.wrapping_add((j as u64).wrapping_mul(SEED_STEP))
}

/// The half holding row 0 of the split of `n` rows with seed `seed` (row indices, ascending):
/// it names the partition (the protocol scores both ways, so halves A/B and B/A are the same
/// split).
pub fn partition_key(n: usize, seed: u64) -> Vec<usize> {
    let (a, b) = halves(n, seed);
    if a.first() == Some(&0) {
        a
    } else {
        b
    }
}

/// The seeds of `k` distinct half splits of `n` rows: the candidate seeds ([`candidate_seed`])
/// in order, skipping a candidate whose partition an earlier one already gave (16 rows have
/// only 6435 partitions, so 100 free draws would repeat one about half the time). Split 0 is
/// [`SPLIT_SEED`], the score table's split. Fails when `n < 2` or when `k` distinct splits are
/// not found among `k·100` candidates (lower `--splits`).
pub fn split_seeds(n: usize, k: usize) -> anyhow::Result<Vec<u64>> {
    if n < 2 {
        bail!("{n} tracker rows cannot be split in two halves");
    }
    let mut seen: HashSet<Vec<usize>> = HashSet::new();
    let mut seeds = Vec::with_capacity(k);
    for j in 0..k.saturating_mul(CANDIDATES_PER_SPLIT) {
        if seeds.len() == k {
            break;
        }
        let seed = candidate_seed(j);
        if seen.insert(partition_key(n, seed)) {
            seeds.push(seed);
        }
    }
    if seeds.len() < k {
        bail!(
            "found only {} distinct half splits of {n} rows for --splits {k}; lower --splits",
            seeds.len()
        );
    }
    Ok(seeds)
}

/// One tracker file over the splits.
#[derive(Debug, Clone, PartialEq)]
pub struct SplitFile {
    /// Recording name.
    pub file: String,
    /// The measured arm, `right` or `left`.
    pub arm: &'static str,
    /// Tracker rows (poses with a tracker position), split in halves.
    pub rows: usize,
    /// The seed of each split, split 0 first ([`split_seeds`]).
    pub seeds: Vec<u64>,
    /// Held-out rms, mm, `[model][split]` (models in [`SplitTable::models`] order).
    pub rms_mm: Vec<Vec<f64>>,
}

/// The held-out rms of every model on every tracker file over the splits.
#[derive(Debug, Clone, PartialEq)]
pub struct SplitTable {
    /// Model names, in the order given.
    pub models: Vec<String>,
    /// One entry per tracker file, in the order given.
    pub files: Vec<SplitFile>,
}

/// Scores every model of `models` (name, right and left corrections) on every recording of
/// `trackers` over `k` distinct half splits per file ([`split_seeds`]), with the score table's
/// protocol ([`score_recording_split`]; the kinematics held, registration + reflector refitted
/// per split). The scores are spread over `threads` threads; the result does not depend on
/// their number. Fails when a file cannot be split `k` ways or a fit fails.
pub fn score_splits(
    cell: &Cell,
    models: &[(&str, &KinematicErrors, &KinematicErrors)],
    trackers: &[&Recording],
    k: usize,
    threads: usize,
) -> anyhow::Result<SplitTable> {
    let mut files = Vec::with_capacity(trackers.len());
    for rec in trackers {
        let rows = rec.poses.iter().filter(|p| p.p_tracker.is_some()).count();
        let seeds = split_seeds(rows, k).with_context(|| rec.name.clone())?;
        files.push(SplitFile {
            file: rec.name.clone(),
            arm: if rec.right_arm { "right" } else { "left" },
            rows,
            seeds,
            rms_mm: Vec::new(),
        });
    }
    // Job j = (file, model, split) in that nesting order; thread t takes j ≡ t (mod threads).
    let jobs: Vec<(usize, usize, usize)> = (0..trackers.len())
        .flat_map(|f| (0..models.len()).flat_map(move |m| (0..k).map(move |s| (f, m, s))))
        .collect();
    let score = |&(f, m, s): &(usize, usize, usize)| -> anyhow::Result<f64> {
        let (rec, file) = (trackers[f], &files[f]);
        let (name, right, left) = models[m];
        let scored = score_recording_split(cell, rec, (right, left), None, file.seeds[s])
            .with_context(|| format!("split {s} of {} for {name}", rec.name))?;
        if scored.len() != file.rows {
            bail!(
                "{}: the split was drawn over {} tracker rows but {} were scored",
                rec.name,
                file.rows,
                scored.len()
            );
        }
        let errors: Vec<f64> = scored.iter().map(|p| p.error_m).collect();
        Ok(summarise(&errors).rms_mm)
    };
    let slots = crate::in_job_order(&jobs, threads, &score);
    let mut values = slots.into_iter();
    for file in &mut files {
        for _ in models {
            let mut per_split = Vec::with_capacity(k);
            for _ in 0..k {
                per_split.push(values.next().context("a split was not scored")??);
            }
            file.rms_mm.push(per_split);
        }
    }
    Ok(SplitTable {
        models: models.iter().map(|m| m.0.to_string()).collect(),
        files,
    })
}

/// A model's figures on one file over the splits, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileSummary {
    /// Splits in which the model's rms is below nominal's.
    pub wins: usize,
    /// Mean rms over the splits.
    pub mean_mm: f64,
    /// Smallest rms over the splits.
    pub min_mm: f64,
    /// Largest rms over the splits.
    pub max_mm: f64,
}

/// A model's verdict over every file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelVerdict {
    /// Splits in which the model's rms is below nominal's on every file at once.
    pub every_file_wins: usize,
    /// Whether its mean rms over the splits is below nominal's on every file.
    pub mean_below_everywhere: bool,
}

impl SplitTable {
    /// The index of the model `name`.
    fn model(&self, name: &str) -> anyhow::Result<usize> {
        self.models
            .iter()
            .position(|m| m == name)
            .with_context(|| format!("model {name} was not scored over the splits"))
    }

    /// The figures of model `m` (index) on file `f` (index) against nominal.
    pub fn summary(&self, f: usize, m: usize) -> anyhow::Result<FileSummary> {
        let nominal = &self.files[f].rms_mm[self.model("nominal")?];
        let v = &self.files[f].rms_mm[m];
        Ok(FileSummary {
            wins: v.iter().zip(nominal).filter(|(x, n)| x < n).count(),
            mean_mm: v.iter().sum::<f64>() / v.len().max(1) as f64,
            min_mm: v.iter().copied().fold(f64::INFINITY, f64::min),
            max_mm: v.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }

    /// The verdict of model `m` (index) over every file against nominal.
    pub fn verdict(&self, m: usize) -> anyhow::Result<ModelVerdict> {
        let nom = self.model("nominal")?;
        let k = self.files.first().map_or(0, |f| f.seeds.len());
        let every_file_wins = (0..k)
            .filter(|&s| self.files.iter().all(|f| f.rms_mm[m][s] < f.rms_mm[nom][s]))
            .count();
        let mut mean_below_everywhere = true;
        for f in 0..self.files.len() {
            mean_below_everywhere &= self.summary(f, m)?.mean_mm < self.summary(f, nom)?.mean_mm;
        }
        Ok(ModelVerdict {
            every_file_wins,
            mean_below_everywhere,
        })
    }
}

/// Where the folder `folder/` of an old (file-held-out CV) choice is when the run ends: the
/// region-held-out protocol (`region_protocol` true: the study without
/// `--skip-region-protocol`) moves `self/`, `planes/` and `all/` ([`crate::region::REGION_MODELS`])
/// to `file-cv/NAME/` and writes its own choice in their place, so a row of the old choice is
/// labelled `file-cv/NAME`; every other folder (`self+c/`, `planes+m/`, …) stays where it is.
pub fn final_folder(folder: &str, region_protocol: bool) -> String {
    if region_protocol
        && crate::region::REGION_MODELS
            .iter()
            .any(|m| m.name == folder)
    {
        format!("file-cv/{folder}")
    } else {
        folder.to_string()
    }
}

/// The folders of `out` that score-table rows were exported to, as `calibrate_all` writes them:
/// for each `(name, calibrations)`, the chosen model to `name/`, the compliance choice to
/// `name+c/`, the marker choice to `name+m/` ([`exported_rows`]).
pub fn exported_folders(
    out: &Path,
    calibrations: &[(&str, &Calibrations)],
    region_protocol: bool,
) -> anyhow::Result<Vec<(String, Vec<String>)>> {
    let mut pairs: Vec<(String, String)> = Vec::new();
    for (name, c) in calibrations {
        pairs.push((c.chosen.name.clone(), name.to_string()));
        pairs.push((c.with.name.clone(), format!("{name}+c")));
        if let Some(m) = &c.marker {
            pairs.push((m.name.clone(), format!("{name}+m")));
        }
    }
    exported_rows(out, &pairs, region_protocol)
}

/// The exported folders of score-table rows: `pairs` holds `(row, folder)` as written now (a
/// `cell.toml` in `out/folder/`); each folder is labelled where it is when the run ends
/// ([`final_folder`]: `file-cv/self` for the old `self/` when the region protocol runs). One
/// entry per exported row (a row can own two folders: `self+c` is `self/` and `self+c/` when the
/// rule chose it), rows and folders in `pairs`' order. Fails when a folder holds no
/// `cell.toml` (this list and the export would disagree).
pub fn exported_rows(
    out: &Path,
    pairs: &[(String, String)],
    region_protocol: bool,
) -> anyhow::Result<Vec<(String, Vec<String>)>> {
    let mut rows: Vec<(String, Vec<String>)> = Vec::new();
    for (row, folder) in pairs {
        let cell = out.join(folder).join("cell.toml");
        if !cell.is_file() {
            bail!(
                "{}: missing, but row {row} is listed as exported to {folder}/",
                cell.display()
            );
        }
        let label = final_folder(folder, region_protocol);
        match rows.iter_mut().find(|r| &r.0 == row) {
            Some(r) => r.1.push(label),
            None => rows.push((row.clone(), vec![label])),
        }
    }
    Ok(rows)
}

/// The `exported` column of a score-table row `model`: the folder it was exported to, or empty.
/// A row exported twice (`self+c`, the chosen `self/` and the compliance export `self+c/`) gets
/// the first, the chosen model's folder, so that the column names one folder, as
/// `tools/ctu-motoman/score_fk.py` reads it; the printed footnote ([`print_exported`]) lists both.
pub fn exported_column(exported: &[(String, Vec<String>)], model: &str) -> String {
    exported
        .iter()
        .find(|r| r.0 == model)
        .and_then(|r| r.1.first().cloned())
        .unwrap_or_default()
}

/// Every folder the row `model` was exported to, `, `-separated (empty when none).
fn exported_list(exported: &[(String, Vec<String>)], model: &str) -> String {
    exported
        .iter()
        .find(|r| r.0 == model)
        .map(|r| r.1.join(", "))
        .unwrap_or_default()
}

/// Prints, under the score table, which row was exported to which folder.
pub fn print_exported(exported: &[(String, Vec<String>)]) {
    let list: Vec<String> = exported
        .iter()
        .flat_map(|(row, folders)| folders.iter().map(move |f| format!("{f}/ = {row}")))
        .collect();
    println!(
        "  exported: {} (scores.csv column `exported` holds each row's first folder, where it is \
         when the run ends; the other rows were not exported)",
        list.join(", ")
    );
}

/// The split-robustness report: scores nominal and every exported row of `models` (name,
/// right and left corrections, kinematics held out from the tracker files) on every tracker
/// file over `k` half splits ([`score_splits`]), prints per file and model the wins over
/// nominal and the mean, min and max rms, and per model on how many splits it beats nominal on
/// every file and whether its mean beats nominal's on every file; writes
/// `out/split_robustness.csv` (one row per file and model) and
/// `out/split_robustness_per_split.csv` (one row per file, model and split). mm throughout.
pub fn split_robustness(
    cell: &Cell,
    models: &[(String, KinematicErrors, KinematicErrors, bool)],
    trackers: &[&Recording],
    exported: &[(String, Vec<String>)],
    k: usize,
    out: &Path,
) -> anyhow::Result<()> {
    let chosen: Vec<_> = models
        .iter()
        .filter(|m| m.0 == "nominal" || exported.iter().any(|e| e.0 == m.0))
        .collect();
    let scored: Vec<(&str, &KinematicErrors, &KinematicErrors)> =
        chosen.iter().map(|m| (m.0.as_str(), &m.1, &m.2)).collect();
    let table = score_splits(cell, &scored, trackers, k, SPLIT_THREADS)?;
    println!(
        "HOW MUCH ONE SPLIT DECIDES: held-out tracker rms over {k} seeded random half splits per file \
         (split 0 = the table above; the kinematics held, registration + reflector refitted on each \
         half); per file: splits better than nominal, mean [min, max] rms, mm:"
    );
    let nom = table.model("nominal")?;
    let mut verdicts = Vec::new();
    for (m, (name, _, _, held_out)) in chosen.iter().map(|c| &**c).enumerate() {
        let folders = exported_list(exported, name);
        println!(
            "  {name}{}{}:",
            if folders.is_empty() {
                String::new()
            } else {
                format!(" (exported as {})", folders)
            },
            if *held_out {
                ""
            } else {
                " — saw these files' tracker values, not held out"
            }
        );
        for (f, file) in table.files.iter().enumerate() {
            let s = table.summary(f, m)?;
            let wins = if m == nom {
                "        ".to_string()
            } else {
                format!("{:>3}/{:<4}", s.wins, k)
            };
            println!(
                "    {:<26} {:>5} {:>4}  {wins} {:>7.3} [{:.3}, {:.3}]",
                file.file, file.arm, file.rows, s.mean_mm, s.min_mm, s.max_mm
            );
        }
        if m != nom {
            verdicts.push((name.as_str(), folders, table.verdict(m)?));
        }
    }
    println!("  per model, against nominal on the same splits:");
    for (name, folders, v) in &verdicts {
        println!(
            "    {name:<10} {:<16} beats nominal on every file in {:>3} of {k} splits; mean rms over splits below nominal's on every file: {}",
            if folders.is_empty() { "".to_string() } else { format!("({})", folders) },
            v.every_file_wins,
            if v.mean_below_everywhere { "yes" } else { "no" }
        );
    }
    println!(
        "  (\"better than nominal on N of {} files\" from the table above is ONE draw, split 0; the \
         small files decide it by their split)",
        table.files.len()
    );
    write_robustness(out, &table, &chosen, exported)?;
    Ok(())
}

/// Writes `out/split_robustness.csv` and `out/split_robustness_per_split.csv`.
fn write_robustness(
    out: &Path,
    table: &SplitTable,
    models: &[&(String, KinematicErrors, KinematicErrors, bool)],
    exported: &[(String, Vec<String>)],
) -> anyhow::Result<()> {
    let path = out.join("split_robustness.csv");
    let mut w = std::fs::File::create(&path).with_context(|| format!("{}", path.display()))?;
    writeln!(
        w,
        "file,arm,n_rows,model,exported,kinematics_held_out,splits,wins_over_nominal,\
         mean_rms_mm,min_rms_mm,max_rms_mm,split0_rms_mm,model_every_file_wins,\
         model_mean_below_nominal_every_file"
    )?;
    let nom = table.model("nominal")?;
    for (f, file) in table.files.iter().enumerate() {
        for (m, (name, _, _, held_out)) in models.iter().map(|c| &**c).enumerate() {
            let s = table.summary(f, m)?;
            let (wins, every, below) = if m == nom {
                (String::new(), String::new(), String::new())
            } else {
                let v = table.verdict(m)?;
                (
                    s.wins.to_string(),
                    v.every_file_wins.to_string(),
                    v.mean_below_everywhere.to_string(),
                )
            };
            writeln!(
                w,
                "{},{},{},{name},{},{held_out},{},{wins},{:.4},{:.4},{:.4},{:.4},{every},{below}",
                file.file,
                file.arm,
                file.rows,
                exported_column(exported, name),
                file.seeds.len(),
                s.mean_mm,
                s.min_mm,
                s.max_mm,
                file.rms_mm[m][0],
            )?;
        }
    }
    let per_split = out.join("split_robustness_per_split.csv");
    let mut w =
        std::fs::File::create(&per_split).with_context(|| format!("{}", per_split.display()))?;
    writeln!(w, "file,arm,model,split,seed,rms_mm")?;
    for file in &table.files {
        for (m, name) in table.models.iter().enumerate() {
            for (s, seed) in file.seeds.iter().enumerate() {
                writeln!(
                    w,
                    "{},{},{name},{s},{seed},{:.4}",
                    file.file, file.arm, file.rms_mm[m][s]
                )?;
            }
        }
    }
    println!("wrote {}, {}", path.display(), per_split.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With the region protocol, the old choices' folders are labelled where the protocol moves
    /// them (`file-cv/NAME`); the `+c`/`+m` folders, and every folder without the protocol, keep
    /// their names; a folder without `cell.toml` is refused.
    #[test]
    fn old_choices_are_labelled_by_the_folder_they_end_in() {
        let dir = tempfile::tempdir().unwrap();
        for f in ["self", "self+c", "planes"] {
            std::fs::create_dir_all(dir.path().join(f)).unwrap();
            std::fs::write(dir.path().join(f).join("cell.toml"), "").unwrap();
        }
        let pairs: Vec<(String, String)> = [
            ("self+c", "self"),
            ("self+c", "self+c"),
            ("planes", "planes"),
        ]
        .iter()
        .map(|(r, f)| (r.to_string(), f.to_string()))
        .collect();
        let moved = exported_rows(dir.path(), &pairs, true).unwrap();
        assert_eq!(
            moved,
            vec![
                (
                    "self+c".to_string(),
                    vec!["file-cv/self".to_string(), "self+c".to_string()]
                ),
                ("planes".to_string(), vec!["file-cv/planes".to_string()]),
            ]
        );
        assert_eq!(exported_column(&moved, "self+c"), "file-cv/self");
        assert_eq!(exported_column(&moved, "planes+m"), "");
        let kept = exported_rows(dir.path(), &pairs, false).unwrap();
        assert_eq!(exported_column(&kept, "self+c"), "self");
        assert_eq!(final_folder("all", true), "file-cv/all");
        assert_eq!(final_folder("all+c", true), "all+c");
        let missing = vec![("all".to_string(), "all".to_string())];
        let e = exported_rows(dir.path(), &missing, true).unwrap_err();
        assert!(
            e.to_string()
                .contains("row all is listed as exported to all/"),
            "{e}"
        );
    }
}

//! The region-held-out protocol (issue 20), as written in
//! `studies/ctu-motoman/docs/region-protocol.md` before any of its scores was computed: each
//! model (`self`, `planes`, `all`) chooses among its candidates by the do-no-harm rule on
//! regions it was not trained on, and is reported on each region by a choice and a fit that
//! never saw that region.
//!
//! 1. Regions of the recordings: [`Region::of`]; the models' training and evaluation regions:
//!    [`REGION_MODELS`].
//! 2. Nominal's score per region, and every candidate fitted on every training set the protocol
//!    needs (`T(m)` minus one or two regions) and scored on the held-out regions:
//!    [`region_protocol`] (the fits run on [`crate::cv::CV_THREADS`] threads, results in job
//!    order).
//! 3. The choice on a set of regions `S` with `H0` already held out: [`RegionOutcome::choose`],
//!    the library's rule [`calib_core::selection::do_no_harm`] on the ratios to nominal.
//! 4. The export choice (`S = E(m)`, `H0 = ∅`) and the nested figure per region `r`
//!    (`S = E(m) ∖ {r}`, `H0 = {r}`): [`RegionOutcome::export`], [`RegionOutcome::nested`].
//! 5. The report and its CSV files: [`print_region`], [`write_region_csv`].
//!
//! Interpretation, fixed before the protocol was run (the protocol says nominal is always a
//! candidate but lists no place for it in the order of simplicity): nominal, with no kinematic
//! parameter, is the simplest candidate, so the one-SE rule of step 3 takes nominal when its mean
//! ratio, 1, is within one SE of the best eligible candidate's.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::Path;

use anyhow::Context;
use calib_core::selection::{do_no_harm, DoNoHarmChoice};
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use crate::cv::CV_THREADS;
use crate::data::{Recording, Role};
use crate::study::{
    build_problem, corrections, fit, score_recording, ModelSpec, NoiseLevels, ParamSet, SigmaGrid,
};

/// A region of the arms' workspaces: every recording belongs to exactly one (the protocol's
/// table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Region {
    /// `leica_right_hand_6x6x6`: the right arm's tracker grid.
    RightGrid,
    /// `leica_left_hand_6x6x6`: the left arm's tracker grid.
    LeftGrid,
    /// The self-contact files, with and without the tracker.
    SelfZone,
    /// The higher table's plane files, with and without the tracker.
    HigherTable,
    /// The lower table's.
    LowerTable,
    /// The wall table's.
    WallTable,
}

impl Region {
    /// Every region, in the protocol's order.
    pub const ALL: [Region; 6] = [
        Region::RightGrid,
        Region::LeftGrid,
        Region::SelfZone,
        Region::HigherTable,
        Region::LowerTable,
        Region::WallTable,
    ];

    /// The region's name in tables (the protocol's).
    pub fn name(self) -> &'static str {
        match self {
            Region::RightGrid => "right_grid",
            Region::LeftGrid => "left_grid",
            Region::SelfZone => "self_zone",
            Region::HigherTable => "higher_table",
            Region::LowerTable => "lower_table",
            Region::WallTable => "wall_table",
        }
    }

    /// The region of the recording named `name` (base name, e.g. `leica_lower_table2_5x5`);
    /// `None` for a file the protocol does not use (the repeatability files).
    pub fn of(name: &str) -> Option<Region> {
        if name.contains("_rep_") {
            return None;
        }
        match name {
            "leica_right_hand_6x6x6" => Some(Region::RightGrid),
            "leica_left_hand_6x6x6" => Some(Region::LeftGrid),
            _ if name.contains("_self_") => Some(Region::SelfZone),
            _ if name.contains("higher_table") => Some(Region::HigherTable),
            _ if name.contains("lower_table") => Some(Region::LowerTable),
            _ if name.contains("wall_table") => Some(Region::WallTable),
            _ => None,
        }
    }
}

/// One exported model of the protocol: its files, candidates and regions.
#[derive(Debug, Clone, Copy)]
pub struct RegionModel {
    /// `self`, `planes` or `all`.
    pub name: &'static str,
    /// The roles of the recordings its fit may use (as before the protocol).
    pub roles: &'static [Role],
    /// Its parameter sets, simplest first (each with every σ of the grid is a candidate).
    pub sets: &'static [ParamSet],
    /// `T(m)`: the regions whose files its fit may use.
    pub training: &'static [Region],
    /// `E(m)`: the regions it is evaluated on.
    pub evaluation: &'static [Region],
}

/// Every region but the self-contact zone.
const NOT_SELF: [Region; 5] = [
    Region::RightGrid,
    Region::LeftGrid,
    Region::HigherTable,
    Region::LowerTable,
    Region::WallTable,
];

/// The three models of the protocol.
pub const REGION_MODELS: [RegionModel; 3] = [
    RegionModel {
        name: "self",
        roles: &[Role::SelfContact],
        sets: &ParamSet::WITH_MARKER,
        training: &[Region::SelfZone],
        evaluation: &NOT_SELF,
    },
    RegionModel {
        name: "planes",
        roles: &[Role::SelfContact, Role::Plane],
        sets: &ParamSet::WITH_MARKER,
        training: &[
            Region::SelfZone,
            Region::HigherTable,
            Region::LowerTable,
            Region::WallTable,
        ],
        evaluation: &NOT_SELF,
    },
    RegionModel {
        name: "all",
        roles: &[
            Role::SelfContact,
            Role::Plane,
            Role::Tracker,
            Role::TrackerSelfContact,
        ],
        sets: &ParamSet::ALL,
        training: &Region::ALL,
        evaluation: &Region::ALL,
    },
];

/// A region's score: the pooled 3-D rms over its tracker poses (mm) and their count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegionScore {
    /// Pooled held-out rms, mm.
    pub rms_mm: f64,
    /// Tracker poses scored.
    pub poses: usize,
}

/// The tracker recordings of region `r` (the files the score reads).
fn region_trackers(recordings: &[Recording], r: Region) -> Vec<&Recording> {
    recordings
        .iter()
        .filter(|x| matches!(x.role, Role::Tracker | Role::TrackerSelfContact))
        .filter(|x| Region::of(&x.name) == Some(r))
        .collect()
}

/// The study's tracker protocol on region `r` at corrections `corr`: registration and
/// reflector fitted on one seeded half of each tracker file, scored on the other, both ways;
/// pooled over the region's files.
pub fn region_score(
    cell: &Cell,
    recordings: &[Recording],
    r: Region,
    corr: (&KinematicErrors, &KinematicErrors),
) -> anyhow::Result<RegionScore> {
    let (mut sum2, mut poses) = (0.0, 0usize);
    for rec in region_trackers(recordings, r) {
        for p in score_recording(cell, rec, corr, None)? {
            sum2 += (p.error_m * 1e3).powi(2);
            poses += 1;
        }
    }
    anyhow::ensure!(
        poses > 0,
        "region {} has no tracker pose to score",
        r.name()
    );
    Ok(RegionScore {
        rms_mm: (sum2 / poses as f64).sqrt(),
        poses,
    })
}

/// The training regions `T(m) ∖ held`, in region order.
fn training_minus(model: &RegionModel, held: &[Region]) -> Vec<Region> {
    model
        .training
        .iter()
        .copied()
        .filter(|r| !held.contains(r))
        .collect()
}

/// Everything the protocol measured for one model.
#[derive(Debug, Clone)]
pub struct RegionOutcome {
    /// The model.
    pub model: RegionModel,
    /// Its candidates, simplest first (nominal, the simplest of all, is implicit).
    pub candidates: Vec<ModelSpec>,
    /// Nominal's score on each evaluation region.
    pub nominal: BTreeMap<Region, RegionScore>,
    /// `scores[(training regions, region)][c]`: candidate c fitted on the model's files of those
    /// training regions, scored on the region (mm).
    pub scores: BTreeMap<(Vec<Region>, Region), Vec<f64>>,
}

/// One choice of the protocol: the regions it looked at, what was held out before it, and the
/// rule's decision.
#[derive(Debug, Clone)]
pub struct RegionChoice {
    /// `S`, in region order.
    pub regions: Vec<Region>,
    /// `H0`.
    pub held: Vec<Region>,
    /// The rule's decision (candidate indices into [`RegionOutcome::candidates`]).
    pub rule: DoNoHarmChoice,
}

/// The nested figure of one region: the choice made without it, and that choice's score on it.
#[derive(Debug, Clone)]
pub struct NestedFigure {
    /// The held-out region `r`.
    pub region: Region,
    /// The choice on `E(m) ∖ {r}` with `r` held out.
    pub choice: RegionChoice,
    /// The chosen candidate's score on `r` when fitted on `T(m) ∖ {r}` (nominal's when the
    /// choice is nominal), mm.
    pub rms_mm: f64,
    /// Nominal's score on `r`.
    pub nominal: RegionScore,
}

impl NestedFigure {
    /// The figure over nominal's.
    pub fn ratio(&self) -> f64 {
        self.rms_mm / self.nominal.rms_mm
    }
}

impl RegionOutcome {
    /// The rule on regions `s_regions` with `held` already held out: each candidate's score on
    /// each `s` when fitted on `T(m) ∖ (held ∪ {s})`, over nominal's.
    pub fn choose(&self, s_regions: &[Region], held: &[Region]) -> anyhow::Result<RegionChoice> {
        let nominal: Vec<f64> = s_regions.iter().map(|s| self.nominal[s].rms_mm).collect();
        let mut rows = vec![Vec::with_capacity(s_regions.len()); self.candidates.len()];
        for &s in s_regions {
            let mut h = held.to_vec();
            h.push(s);
            let key = (training_minus(&self.model, &h), s);
            let scores = self
                .scores
                .get(&key)
                .with_context(|| format!("no score of {} trained on {:?}", s.name(), key.0))?;
            for (row, &v) in rows.iter_mut().zip(scores) {
                row.push(v);
            }
        }
        Ok(RegionChoice {
            regions: s_regions.to_vec(),
            held: held.to_vec(),
            rule: do_no_harm(&nominal, &rows)?,
        })
    }

    /// The export choice: `S = E(m)`, `H0 = ∅`.
    pub fn export(&self) -> anyhow::Result<RegionChoice> {
        self.choose(self.model.evaluation, &[])
    }

    /// The nested figure of every evaluation region `r`: the choice on `E(m) ∖ {r}` with `r`
    /// held out, its candidate fitted on `T(m) ∖ {r}` and scored on `r`.
    pub fn nested(&self) -> anyhow::Result<Vec<NestedFigure>> {
        self.model
            .evaluation
            .iter()
            .map(|&r| {
                let s: Vec<Region> = self
                    .model
                    .evaluation
                    .iter()
                    .copied()
                    .filter(|&x| x != r)
                    .collect();
                let choice = self.choose(&s, &[r])?;
                let nominal = self.nominal[&r];
                let rms_mm = match choice.rule.choice {
                    Some(c) => self.scores[&(training_minus(&self.model, &[r]), r)][c],
                    None => nominal.rms_mm,
                };
                Ok(NestedFigure {
                    region: r,
                    choice,
                    rms_mm,
                    nominal,
                })
            })
            .collect()
    }

    /// The name of candidate `c` of a choice (`None`: nominal).
    pub fn name_of(&self, c: Option<usize>) -> String {
        match c {
            Some(c) => format!(
                "{} σ {}",
                self.candidates[c].set.name(),
                self.candidates[c].sigma
            ),
            None => "nominal".to_string(),
        }
    }
}

/// The protocol's measurements for `model`: nominal on each evaluation region, and each
/// candidate (the model's sets × `grid`) fitted on every training set the export choice and
/// the nested figures need (`T(m)` minus `{s}` and minus `{r, s}`, `r ≠ s` in `E(m)`), scored
/// on the held-out regions of that set. Fits are spread over [`CV_THREADS`] threads; the
/// results do not depend on that number.
pub fn region_protocol(
    cell: &Cell,
    recordings: &[Recording],
    model: &RegionModel,
    grid: &SigmaGrid,
    noise: &NoiseLevels,
) -> anyhow::Result<RegionOutcome> {
    let candidates: Vec<ModelSpec> = model
        .sets
        .iter()
        .flat_map(|&set| {
            grid.values()
                .iter()
                .map(move |&sigma| ModelSpec { set, sigma })
        })
        .collect();
    let zero = KinematicErrors::zero(6);
    let mut nominal = BTreeMap::new();
    for &r in model.evaluation {
        nominal.insert(r, region_score(cell, recordings, r, (&zero, &zero))?);
    }
    // Training set → the regions scored with it.
    let mut needs: BTreeMap<Vec<Region>, BTreeSet<Region>> = BTreeMap::new();
    for &s in model.evaluation {
        needs
            .entry(training_minus(model, &[s]))
            .or_default()
            .insert(s);
        for &r in model.evaluation.iter().filter(|&&r| r != s) {
            needs
                .entry(training_minus(model, &[r, s]))
                .or_default()
                .insert(s);
        }
    }
    let trainings: Vec<(&Vec<Region>, &BTreeSet<Region>)> = needs.iter().collect();
    let jobs: Vec<(usize, usize)> = (0..trainings.len())
        .flat_map(|t| (0..candidates.len()).map(move |c| (t, c)))
        .collect();
    let run = |(t, c): (usize, usize)| -> anyhow::Result<Vec<f64>> {
        let (train, scored) = trainings[t];
        let recs: Vec<&Recording> = recordings
            .iter()
            .filter(|x| model.roles.contains(&x.role))
            .filter(|x| Region::of(&x.name).is_some_and(|r| train.contains(&r)))
            .collect();
        let spec = candidates[c];
        let b = build_problem(cell, &recs, Some(spec), noise);
        let f = fit(&b, None, None).with_context(|| {
            format!(
                "{} region protocol: {} σ {} trained on {}",
                model.name,
                spec.set.name(),
                spec.sigma,
                names(train)
            )
        })?;
        let (r, l) = corrections(&f);
        scored
            .iter()
            .map(|&s| Ok(region_score(cell, recordings, s, (&r, &l))?.rms_mm))
            .collect()
    };
    // Job k goes to thread k % CV_THREADS; the results come back in job order.
    let results = crate::in_job_order(&jobs, CV_THREADS, &|&job: &(usize, usize)| run(job));
    let mut scores: BTreeMap<(Vec<Region>, Region), Vec<f64>> = BTreeMap::new();
    for (&(t, _), got) in jobs.iter().zip(results) {
        let got = got?;
        let (train, scored) = trainings[t];
        for (&s, v) in scored.iter().zip(got) {
            scores.entry((train.clone(), s)).or_default().push(v);
        }
    }
    Ok(RegionOutcome {
        model: *model,
        candidates,
        nominal,
        scores,
    })
}

/// Region names joined by `+` (`-` for none).
fn names(regions: &[Region]) -> String {
    if regions.is_empty() {
        return "-".into();
    }
    regions
        .iter()
        .map(|r| r.name())
        .collect::<Vec<_>>()
        .join("+")
}

/// Prints one model's protocol: nominal per region, the export choice's table of ratios (with
/// eligibility, the choice and what was withheld) and the nested figure per region.
pub fn print_region(o: &RegionOutcome, export: &RegionChoice, nested: &[NestedFigure]) {
    let m = &o.model;
    println!(
        "region-held-out protocol (docs/region-protocol.md), model {}: trained on {}, evaluated on {}",
        m.name,
        names(m.training),
        names(m.evaluation)
    );
    println!(
        "  nominal per region (pooled held-out tracker rms, mm): {}",
        m.evaluation
            .iter()
            .map(|r| format!(
                "{} {:.4} ({} poses)",
                r.name(),
                o.nominal[r].rms_mm,
                o.nominal[r].poses
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "  export choice (S = E, nothing else held out): ratio to nominal per region, each fitted without it:"
    );
    print!("  {:<16} {:>4}", "set", "σ");
    for r in &export.regions {
        print!(" {:>12}", r.name());
    }
    println!(" {:>7} {:>7}", "mean", "SE");
    let rule = &export.rule;
    for (c, spec) in o.candidates.iter().enumerate() {
        print!("  {:<16} {:>4}", spec.set.name(), spec.sigma);
        for v in &rule.ratios[c] {
            print!(" {v:>12.4}");
        }
        let mark = if rule.choice == Some(c) {
            " *"
        } else if rule.eligible[c] {
            " +"
        } else if rule.withheld.contains(&c) {
            " withheld"
        } else {
            ""
        };
        println!(
            " {:>7.4} {:>7.4}{mark}",
            rule.mean_ratio[c], rule.se_ratio[c]
        );
    }
    println!(
        "  (+ eligible: ratio ≤ 1 in every region; * chosen; withheld: better than nominal in some region, worse in another)"
    );
    println!(
        "  export choice: {}{}",
        o.name_of(rule.choice),
        match (rule.best, rule.threshold) {
            (Some(b), Some(t)) => format!(
                " (best eligible {} mean ratio {:.4}, one-SE threshold {:.4})",
                o.name_of(Some(b)),
                rule.mean_ratio[b],
                t
            ),
            _ => " (no candidate is eligible: nominal)".to_string(),
        }
    );
    println!(
        "  withheld: {} of {} candidates (better than nominal in some region, worse in another)",
        rule.withheld.len(),
        o.candidates.len()
    );
    println!("  nested figure per region (choice and fit without the region, scored on it):");
    for n in nested {
        let verdict = if n.ratio() < 1.0 {
            "beats nominal"
        } else if n.choice.rule.choice.is_none() {
            "nominal (nothing eligible or within one SE)"
        } else {
            "DOES NOT beat nominal"
        };
        println!(
            "    {:<13} chosen without it: {:<26} {:.4} mm vs nominal {:.4} mm, ratio {:.4}: {verdict}",
            n.region.name(),
            o.name_of(n.choice.rule.choice),
            n.rms_mm,
            n.nominal.rms_mm,
            n.ratio()
        );
    }
}

/// Appends one model's protocol to the two CSV files in `out` (created with their headers when
/// `first`): `region_held_out.csv` (one row per evaluation region: the nested figure, the
/// choice made without it, nominal, ratio) and `region_candidates.csv` (every choice's table:
/// per candidate and region the ratio, with eligibility, choice and withholding).
pub fn write_region_csv(
    out: &Path,
    o: &RegionOutcome,
    export: &RegionChoice,
    nested: &[NestedFigure],
    first: bool,
) -> anyhow::Result<()> {
    let open = |name: &str| -> anyhow::Result<std::fs::File> {
        let path = out.join(name);
        std::fs::OpenOptions::new()
            .create(true)
            .write(true)
            .append(!first)
            .truncate(first)
            .open(&path)
            .with_context(|| format!("{}", path.display()))
    };
    let mut w = open("region_held_out.csv")?;
    if first {
        writeln!(
            w,
            "model,region,poses,chosen_without_region,rms_mm,nominal_rms_mm,ratio,beats_nominal,export_choice"
        )?;
    }
    for n in nested {
        writeln!(
            w,
            "{},{},{},{},{:.6},{:.6},{:.6},{},{}",
            o.model.name,
            n.region.name(),
            n.nominal.poses,
            o.name_of(n.choice.rule.choice),
            n.rms_mm,
            n.nominal.rms_mm,
            n.ratio(),
            n.ratio() < 1.0,
            o.name_of(export.rule.choice)
        )?;
    }
    let mut w = open("region_candidates.csv")?;
    if first {
        writeln!(
            w,
            "model,choice,held_out,set,sigma_mrad_or_mm,region,rms_mm,nominal_rms_mm,ratio,mean_ratio,se_ratio,eligible,chosen,withheld"
        )?;
    }
    let choices =
        std::iter::once(("export", export)).chain(nested.iter().map(|n| ("nested", &n.choice)));
    for (what, ch) in choices {
        for (c, spec) in o.candidates.iter().enumerate() {
            for (k, &s) in ch.regions.iter().enumerate() {
                let ratio = ch.rule.ratios[c][k];
                writeln!(
                    w,
                    "{},{what},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{},{},{}",
                    o.model.name,
                    names(&ch.held),
                    spec.set.name(),
                    spec.sigma,
                    s.name(),
                    ratio * o.nominal[&s].rms_mm,
                    o.nominal[&s].rms_mm,
                    ratio,
                    ch.rule.mean_ratio[c],
                    ch.rule.se_ratio[c],
                    ch.rule.eligible[c],
                    ch.rule.choice == Some(c),
                    ch.rule.withheld.contains(&c)
                )?;
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::data::RECORDINGS;

    #[test]
    fn every_recording_is_in_the_protocols_region() {
        let files = |r: Region| {
            RECORDINGS
                .iter()
                .filter(|x| Region::of(x.0) == Some(r))
                .count()
        };
        // The protocol's table: 1 grid file each, 8 self-contact files, 4 files per table.
        assert_eq!(Region::ALL.map(files), [1, 1, 8, 4, 4, 4]);
        assert_eq!(Region::of("leica_rep_self1"), None);
        assert_eq!(Region::of("leica_rep_table2"), None);
        assert_eq!(Region::of("leica_rep_wall1"), None);
    }

    #[test]
    fn the_models_regions_are_the_protocols() {
        let [s, p, a] = REGION_MODELS;
        assert_eq!((s.name, s.training), ("self", &[Region::SelfZone][..]));
        assert_eq!(p.training.len(), 4);
        assert!(
            !p.training.contains(&Region::RightGrid) && !p.training.contains(&Region::LeftGrid)
        );
        for m in [s, p] {
            assert_eq!(m.evaluation, &NOT_SELF[..]);
            assert_eq!(m.sets, &ParamSet::WITH_MARKER[..]);
        }
        assert_eq!(
            (a.training, a.evaluation),
            (&Region::ALL[..], &Region::ALL[..])
        );
        assert_eq!(a.sets, &ParamSet::ALL[..]);
        // Every file a model may use lies in one of its training regions.
        for m in REGION_MODELS {
            for (name, role, _, _) in RECORDINGS.iter().filter(|x| m.roles.contains(&x.1)) {
                let r = Region::of(name).unwrap();
                assert!(m.training.contains(&r), "{} {name} {role:?}", m.name);
            }
        }
    }

    #[test]
    fn training_minus_removes_only_training_regions() {
        let [s, p, _] = REGION_MODELS;
        assert_eq!(
            training_minus(&s, &[Region::RightGrid]),
            vec![Region::SelfZone]
        );
        assert_eq!(
            training_minus(&p, &[Region::LowerTable, Region::LeftGrid]),
            vec![Region::SelfZone, Region::HigherTable, Region::WallTable]
        );
    }
}

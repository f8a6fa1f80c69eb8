//! The study's cross-validated choice of a model: every (parameter set, prior σ) candidate is
//! fitted with one group of recordings held out at a time, the held-out group is scored per
//! observation kind, and the per-kind one-standard-error rule (or `--cv-rule pooled-one-se` /
//! `min`) picks the candidate; plus the CV table's printing and CSV.
//!
//! The per-kind rule (fixed by the lead in stop 14, before it was run; see
//! studies/ctu-motoman/docs/findings.md, "The `planes` criterion, per kind"): for each observation kind
//! k of the held-out rows (contact, plane, tracker) the CV error `e_k(c)` of candidate c and its
//! standard error `SE_k(c)`; `best_k` = the candidate with the smallest `e_k`; c qualifies when
//! `e_k(c) ≤ e_k(best_k) + SE_k(best_k)` for every k; the choice is the simplest qualifying
//! candidate (table order), or, when none qualifies, the one minimising
//! `max_k (e_k(c) − e_k(best_k)) / SE_k(best_k)`. With one kind this is the one-SE rule.
//! The rules themselves are the library's ([`calib_core::selection`]); this module holds the
//! study's folds, fits and tables.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use calib_core::selection::argmin;
pub use calib_core::selection::{per_kind_one_se, pooled_one_se, CvError, PerKindPick};
use calib_core::StopReason;
use handclasp_cell::Cell;
use kinematics::KinematicErrors;

use crate::data::Recording;
use crate::study::{
    build_problem, corrections, fit, ModelSpec, NoiseLevels, ParamSet, RowKind, SigmaGrid,
};

/// `--cv-rule`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CvRule {
    /// The per-kind one-SE rule: the simplest candidate within one SE of the smallest CV error
    /// of EVERY observation kind (contact, plane) at once; with one kind, the one-SE rule.
    OneSe,
    /// Stop 13's rule, kept to reproduce its choice: the one-SE rule on the pooled CV error
    /// (every held-out row of every kind in one rms, in σ units).
    PooledOneSe,
    /// The smallest pooled CV error.
    Min,
}

impl CvRule {
    /// The rule's name in the printed report.
    pub fn name(self) -> &'static str {
        match self {
            CvRule::OneSe => "per-kind one-SE rule",
            CvRule::PooledOneSe => "pooled one-SE rule",
            CvRule::Min => "smallest pooled CV error",
        }
    }
}

/// The held-out rows of one candidate: (kind, squared error) per held-out scalar row or tracker
/// point (σ units, or mm² for tracker scores).
pub type HeldOutRows = Vec<(RowKind, f64)>;

/// Scores held-out recordings at given (right, left) corrections: their [`HeldOutRows`].
pub type HeldOutScore<'a> = dyn Fn(&[&Recording], (&KinematicErrors, &KinematicErrors)) -> anyhow::Result<HeldOutRows>
    + Sync
    + 'a;

/// Threads over which the CV candidates are spread (each candidate is independent and the table
/// keeps the candidate order, so the result does not depend on this number).
pub const CV_THREADS: usize = 2;

/// How one training fit of a CV fold ended (printed when it did not converge, so that a
/// candidate whose fits misbehave is seen, not hidden behind its CV error).
#[derive(Debug, Clone, PartialEq)]
pub struct FoldFit {
    /// The held-out fold (the training set is every other recording).
    pub fold: String,
    /// Why the solver stopped.
    pub stopped: StopReason,
    /// Iterations used.
    pub iterations: usize,
    /// The fitted distance of each contact group of the training problem, m (a chain that
    /// shrinks under a loose prior shows here first: the distance starts at about 116 mm).
    pub contact_distance_m: Vec<f64>,
}

/// One candidate's row of the CV table.
#[derive(Debug, Clone)]
pub struct CvRow {
    /// The candidate.
    pub spec: ModelSpec,
    /// The training fit of each fold, in fold order.
    pub fold_fits: Vec<FoldFit>,
    /// Every held-out row of every kind pooled in one rms (stop 13's criterion).
    pub pooled: CvError,
    /// The CV error of each kind, in the order of [`Choice::kinds`].
    pub by_kind: Vec<CvError>,
    /// Whether the candidate qualifies under the per-kind rule over every candidate.
    pub qualifies: bool,
}

/// One cross-validated choice.
pub struct Choice {
    /// The rule that made the choices.
    pub rule: CvRule,
    /// The prior σ grid the candidates were built from.
    pub grid: SigmaGrid,
    /// The choice of the rule over every candidate (exported).
    pub spec: ModelSpec,
    /// The rule's choice among the candidates without compliance.
    pub without_compliance: ModelSpec,
    /// The rule's choice among the candidates with compliance.
    pub with_compliance: ModelSpec,
    /// The rule's choice among the candidates with the marker centres (`None`: no such set).
    pub with_marker: Option<ModelSpec>,
    /// The candidate with the smallest pooled criterion.
    pub min_spec: ModelSpec,
    /// Standard error of the smallest pooled criterion.
    pub min_se: f64,
    /// The observation kinds of the held-out rows, in [`RowKind`] order.
    pub kinds: Vec<RowKind>,
    /// Per kind: the candidate with the smallest CV error of that kind, and that error.
    pub best: Vec<(ModelSpec, CvError)>,
    /// The choice of stop 13's pooled one-SE rule over every candidate (for the comparison).
    pub pooled_one_se: ModelSpec,
    /// When no candidate qualified under the per-kind rule (over every candidate): the chosen
    /// candidate's largest shortfall `max_k (e_k − e_k(best_k)) / SE_k(best_k)`.
    pub shortfall: Option<f64>,
    /// Every candidate, simplest first.
    pub table: Vec<CvRow>,
}

/// One CV candidate's held-out rows and the training fit of each fold.
type Evaluated = (HeldOutRows, Vec<FoldFit>);

/// Grouped CV: for every spec (each of `sets` with each prior σ of `grid`), train on all
/// recordings but one held-out group and score the
/// held-out group with `score` (one (kind, squared error) per held-out scalar or point), over
/// the groups; the criteria are the rms `e = sqrt(mean e²)` of every row (pooled) and of each
/// kind's rows, each with standard error `SE = sd(e²) / (2·e·sqrt(n))` (delta method). The
/// candidates are ordered simplest first (offsets before offsets + lengths, then the smaller
/// prior σ) and `rule` picks one ([`per_kind_one_se`] by default), over every candidate and
/// within the subsets without compliance, with compliance and with the marker centres.
#[allow(clippy::too_many_arguments)]
pub fn cross_validate(
    cell: &Cell,
    recs: &[&Recording],
    sets: &[ParamSet],
    grid: &SigmaGrid,
    folds: &[&str],
    noise: &NoiseLevels,
    rule: CvRule,
    score: &HeldOutScore,
) -> anyhow::Result<Choice> {
    let specs: Vec<ModelSpec> = sets
        .iter()
        .flat_map(|&set| {
            grid.values()
                .iter()
                .map(move |&sigma| ModelSpec { set, sigma })
        })
        .collect();
    let evaluate = |spec: ModelSpec| -> anyhow::Result<Evaluated> {
        let mut e2: HeldOutRows = Vec::new();
        let mut fold_fits = Vec::with_capacity(folds.len());
        for fold in folds {
            let train: Vec<&Recording> = recs
                .iter()
                .copied()
                .filter(|r| r.pattern != *fold)
                .collect();
            let test: Vec<&Recording> = recs
                .iter()
                .copied()
                .filter(|r| r.pattern == *fold)
                .collect();
            let b = build_problem(cell, &train, Some(spec), noise);
            let f = fit(&b, None, None)
                .with_context(|| format!("CV fold {fold}, {} σ {}", spec.set.name(), spec.sigma))?;
            fold_fits.push(FoldFit {
                fold: fold.to_string(),
                stopped: f.stopped,
                iterations: f.iterations,
                contact_distance_m: f.estimate.contact_distance_m.clone(),
            });
            let (r, l) = corrections(&f);
            e2.extend(score(&test, (&r, &l))?);
        }
        Ok((e2, fold_fits))
    };
    // Candidate k goes to thread k % CV_THREADS; the results come back in candidate order.
    let rows = crate::in_job_order(&specs, CV_THREADS, &|spec: &ModelSpec| evaluate(*spec))
        .into_iter()
        .collect::<anyhow::Result<Vec<_>>>()?;
    let kinds_of = |r: &[(RowKind, f64)]| {
        let mut k: Vec<RowKind> = r.iter().map(|x| x.0).collect();
        k.sort();
        k.dedup();
        k
    };
    let kinds = kinds_of(&rows.first().context("no CV candidate")?.0);
    let mut table: Vec<CvRow> = Vec::with_capacity(specs.len());
    for (spec, (r, fold_fits)) in specs.iter().zip(rows) {
        if kinds_of(&r) != kinds {
            anyhow::bail!(
                "CV candidate {} σ {}: its held-out rows have other kinds than the first \
                 candidate's (the folds must score the same rows for every candidate)",
                spec.set.name(),
                spec.sigma
            );
        }
        let all: Vec<f64> = r.iter().map(|x| x.1).collect();
        let by_kind = kinds
            .iter()
            .map(|&k| {
                let e2: Vec<f64> = r.iter().filter(|x| x.0 == k).map(|x| x.1).collect();
                CvError::from_squares(&e2)
            })
            .collect();
        table.push(CvRow {
            spec: *spec,
            fold_fits,
            pooled: CvError::from_squares(&all),
            by_kind,
            qualifies: false,
        });
    }
    // The rule within the candidates `keep` accepts: (choice, per-kind pick over them).
    let pick = |keep: &dyn Fn(ParamSet) -> bool,
                rule: CvRule|
     -> anyhow::Result<(ModelSpec, PerKindPick)> {
        let sub: Vec<&CvRow> = table.iter().filter(|t| keep(t.spec.set)).collect();
        let pooled: Vec<CvError> = sub.iter().map(|t| t.pooled).collect();
        let per_kind = per_kind_one_se(&sub.iter().map(|t| t.by_kind.clone()).collect::<Vec<_>>())
            .context("no CV candidate")?;
        let index = match rule {
            CvRule::OneSe => per_kind.index,
            CvRule::PooledOneSe => pooled_one_se(&pooled).context("no CV candidate")?,
            CvRule::Min => argmin(&pooled.iter().map(|c| c.e).collect::<Vec<_>>())
                .context("no CV candidate")?,
        };
        Ok((sub[index].spec, per_kind))
    };
    let (spec, per_kind) = pick(&|_| true, rule)?;
    let pooled_one_se_spec = pick(&|_| true, CvRule::PooledOneSe)?.0;
    let without_compliance = pick(&|s| !s.compliance() && !s.marker(), rule)?.0;
    let with_compliance = pick(&|s| s.compliance(), rule)?.0;
    let with_marker = if sets.iter().any(|s| s.marker()) {
        Some(pick(&|s| s.marker(), rule)?.0)
    } else {
        None
    };
    let min_row = &table[argmin(&table.iter().map(|t| t.pooled.e).collect::<Vec<_>>())
        .context("no CV candidate")?];
    let (min_spec, min_se) = (min_row.spec, min_row.pooled.se);
    let best = per_kind
        .best
        .iter()
        .enumerate()
        .map(|(k, &c)| (table[c].spec, table[c].by_kind[k]))
        .collect();
    for (row, q) in table.iter_mut().zip(&per_kind.qualifies) {
        row.qualifies = *q;
    }
    Ok(Choice {
        rule,
        grid: grid.clone(),
        spec,
        without_compliance,
        with_compliance,
        with_marker,
        min_spec,
        min_se,
        kinds,
        best,
        pooled_one_se: pooled_one_se_spec,
        shortfall: if rule == CvRule::OneSe {
            per_kind.shortfall
        } else {
            None
        },
        table,
    })
}

/// Prints the CV table of `c`: the pooled criterion as a grid (rows: parameter sets, columns:
/// prior σ of `c.grid`; `*` the choice) and, with more than one observation kind, every
/// candidate's error per kind with its SE and whether it qualifies under the per-kind rule
/// (`+`); then the choice, naming the grid and whether it sits at the grid's edge, and every
/// training fit that did not converge.
pub fn print_cv(title: &str, unit: &str, sets: &[ParamSet], c: &Choice) {
    println!("{title}");
    print!("  {:<16}", "set \\ σ");
    for s in c.grid.values() {
        print!(" {s:>8}");
    }
    println!();
    for &set in sets {
        print!("  {:<16}", set.name());
        for row in c.table.iter().filter(|r| r.spec.set == set) {
            let mark = if row.spec == c.spec { "*" } else { " " };
            print!(" {:>7.4}{mark}", row.pooled.e);
        }
        println!();
    }
    if c.kinds.len() > 1 {
        println!(
            "  per kind ({unit}, SE in brackets; + = qualifies: within one SE of the smallest of \
             EVERY kind; * = chosen):"
        );
        print!("  {:<16} {:>4} {:>8}", "set", "σ", "pooled");
        for k in &c.kinds {
            print!(" {:>18}", k.name());
        }
        println!();
        for row in &c.table {
            print!(
                "  {:<16} {:>4} {:>8.4}",
                row.spec.set.name(),
                row.spec.sigma,
                row.pooled.e
            );
            for e in &row.by_kind {
                print!("   {:>7.4} ({:.4})", e.e, e.se);
            }
            let q = if row.qualifies { "+" } else { " " };
            let star = if row.spec == c.spec { "*" } else { " " };
            println!(" {q}{star}");
        }
        println!(
            "  smallest per kind: {}",
            c.kinds
                .iter()
                .zip(&c.best)
                .map(|(k, (s, e))| format!(
                    "{} {} σ {} ({:.4}, threshold {:.4})",
                    k.name(),
                    s.set.name(),
                    s.sigma,
                    e.e,
                    e.e + e.se
                ))
                .collect::<Vec<_>>()
                .join("; ")
        );
    }
    println!(
        "  smallest {unit}{}: {} σ {} (SE {:.4}); chosen (*) by the {} over the σ grid {}: {} with σ = {} mrad / mm{}",
        if c.kinds.len() > 1 { " (pooled)" } else { "" },
        c.min_spec.set.name(),
        c.min_spec.sigma,
        c.min_se,
        c.rule.name(),
        c.grid,
        c.spec.set.name(),
        c.spec.sigma,
        match c.shortfall {
            Some(s) => format!(" (no candidate qualifies; its largest shortfall is {s:.2} SE)"),
            None => String::new(),
        }
    );
    if c.kinds.len() > 1 && c.pooled_one_se != c.spec {
        println!(
            "  stop 13's pooled one-SE rule would choose {} σ {}",
            c.pooled_one_se.set.name(),
            c.pooled_one_se.sigma
        );
    }
    println!(
        "  the rule within the sets without compliance: {} σ {}; within those with: {} σ {}",
        c.without_compliance.set.name(),
        c.without_compliance.sigma,
        c.with_compliance.set.name(),
        c.with_compliance.sigma
    );
    if let Some(m) = c.with_marker {
        println!(
            "  the rule within the sets with the marker centres: {} σ {}",
            m.set.name(),
            m.sigma
        );
    }
    if let Some(edge) = grid_edge(c.grid.values(), c.spec.sigma) {
        println!(
            "  the chosen σ {} is the {edge} value of the grid {} (--sigma-grid measures beyond it)",
            c.spec.sigma, c.grid
        );
    }
    for row in &c.table {
        for f in row
            .fold_fits
            .iter()
            .filter(|f| f.stopped != StopReason::Converged)
        {
            println!(
                "  NOT CONVERGED: {} σ {} trained without fold {}: {} after {} iterations; \
                 contact distance {} mm",
                row.spec.set.name(),
                row.spec.sigma,
                f.fold,
                f.stopped.name(),
                f.iterations,
                f.contact_distance_m
                    .iter()
                    .map(|d| format!("{:.3}", d * 1e3))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
}

/// `Some("smallest")` or `Some("largest")` when `sigma` is that end of `grid` (values
/// increasing), else `None`.
fn grid_edge(grid: &[f64], sigma: f64) -> Option<&'static str> {
    if grid.last() == Some(&sigma) {
        Some("largest")
    } else if grid.first() == Some(&sigma) {
        Some("smallest")
    } else {
        None
    }
}

/// Writes the CV table of `c` to `path`: one row per candidate with the pooled criterion
/// (`criterion` names its column) and its SE, then `e_<kind>,se_<kind>` per observation kind,
/// `qualifies` (per-kind rule over every candidate) and `chosen`.
pub fn write_cv(path: &Path, c: &Choice, criterion: &str) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    write!(w, "set,sigma_mrad_or_mm,{criterion},se")?;
    for k in &c.kinds {
        write!(w, ",e_{0},se_{0}", k.name())?;
    }
    writeln!(w, ",qualifies,chosen")?;
    for row in &c.table {
        write!(
            w,
            "{},{},{:.6},{:.6}",
            row.spec.set.name(),
            row.spec.sigma,
            row.pooled.e,
            row.pooled.se
        )?;
        for e in &row.by_kind {
            write!(w, ",{:.6},{:.6}", e.e, e.se)?;
        }
        writeln!(w, ",{},{}", row.qualifies, row.spec == c.spec)?;
    }
    Ok(())
}

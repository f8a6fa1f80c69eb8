//! The study's cross-validated choice of a model: every (parameter set, prior σ) candidate is
//! fitted with one group of recordings held out at a time, the held-out group is scored, and the
//! one-standard-error rule (or `--cv-rule min`) picks the candidate; plus the CV table's printing
//! and CSV.

use std::io::Write;
use std::path::Path;

use anyhow::Context;
use kinematics::KinematicErrors;
use sim_cell::Cell;

use crate::data::Recording;
use crate::study::{build_problem, corrections, fit, ModelSpec, NoiseLevels, ParamSet, SIGMA_GRID};

/// `--cv-rule`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CvRule {
    /// The simplest candidate within one standard error of the smallest CV error.
    OneSe,
    /// The smallest CV error.
    Min,
}

/// Scores held-out recordings at given (right, left) corrections: one squared error per
/// held-out scalar row or tracker point.
pub type HeldOutScore<'a> = dyn Fn(&[&Recording], (&KinematicErrors, &KinematicErrors)) -> anyhow::Result<Vec<f64>>
    + Sync
    + 'a;

/// Threads over which the CV candidates are spread (each candidate is independent and the table
/// keeps the candidate order, so the result does not depend on this number).
pub const CV_THREADS: usize = 2;

/// One cross-validated choice.
pub struct Choice {
    /// The choice of the rule over every candidate (exported).
    pub spec: ModelSpec,
    /// The rule's choice among the candidates without compliance.
    pub without_compliance: ModelSpec,
    /// The rule's choice among the candidates with compliance.
    pub with_compliance: ModelSpec,
    /// The rule's choice among the candidates with the marker centres (`None`: no such set).
    pub with_marker: Option<ModelSpec>,
    /// The candidate with the smallest criterion.
    pub min_spec: ModelSpec,
    /// Standard error of the smallest criterion.
    pub min_se: f64,
    /// (spec, criterion, its standard error) of every candidate.
    pub table: Vec<(ModelSpec, f64, f64)>,
}

/// Grouped CV: for every spec, train on all recordings but one held-out group and score the
/// held-out group with `score` (one squared error per held-out scalar or point), pooled over the
/// groups; the criterion is the rms `c = sqrt(mean e²)` with standard error
/// `SE = sd(e²) / (2·c·sqrt(n))` (delta method). The choice is the one-standard-error rule:
/// the simplest candidate (offsets before offsets + lengths, then the smaller prior σ) whose
/// criterion is within one SE of the smallest. Chosen before the tracker scores were looked at,
/// as the standard guard against a minimum that noise picked.
pub fn cross_validate(
    cell: &Cell,
    recs: &[&Recording],
    sets: &[ParamSet],
    folds: &[&str],
    noise: &NoiseLevels,
    rule: CvRule,
    score: &HeldOutScore,
) -> anyhow::Result<Choice> {
    let specs: Vec<ModelSpec> = sets
        .iter()
        .flat_map(|&set| SIGMA_GRID.map(|sigma| ModelSpec { set, sigma }))
        .collect();
    let evaluate = |spec: ModelSpec| -> anyhow::Result<(ModelSpec, f64, f64)> {
        let mut e2: Vec<f64> = Vec::new();
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
            let (r, l) = corrections(&f);
            e2.extend(score(&test, (&r, &l))?);
        }
        let n = e2.len().max(1) as f64;
        let mean = e2.iter().sum::<f64>() / n;
        let var = e2.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let c = mean.sqrt();
        Ok((spec, c, var.sqrt() / (2.0 * c * n.sqrt())))
    };
    // Candidate k goes to thread k % CV_THREADS; the results are put back in candidate order.
    let mut slots: Vec<Option<anyhow::Result<(ModelSpec, f64, f64)>>> =
        (0..specs.len()).map(|_| None).collect();
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..CV_THREADS)
            .map(|t| {
                let (specs, evaluate) = (&specs, &evaluate);
                scope.spawn(move || {
                    (t..specs.len())
                        .step_by(CV_THREADS)
                        .map(|k| (k, evaluate(specs[k])))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for h in handles {
            for (k, r) in h.join().expect("a CV thread panicked") {
                slots[k] = Some(r);
            }
        }
    });
    let table = slots
        .into_iter()
        .map(|s| s.context("a CV candidate was not evaluated")?)
        .collect::<anyhow::Result<Vec<_>>>()?;
    let pick = |keep: &dyn Fn(ParamSet) -> bool| -> anyhow::Result<(ModelSpec, ModelSpec, f64)> {
        let sub: Vec<&(ModelSpec, f64, f64)> = table.iter().filter(|t| keep(t.0.set)).collect();
        let &&(min_spec, min_c, min_se) = sub
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .context("no CV candidate")?;
        // Table order is already simplest first: set, then σ ascending.
        let spec = match rule {
            CvRule::Min => min_spec,
            CvRule::OneSe => sub
                .iter()
                .find(|t| t.1 <= min_c + min_se)
                .map_or(min_spec, |t| t.0),
        };
        Ok((spec, min_spec, min_se))
    };
    let (spec, min_spec, min_se) = pick(&|_| true)?;
    Ok(Choice {
        spec,
        without_compliance: pick(&|s| !s.compliance() && !s.marker())?.0,
        with_compliance: pick(&|s| s.compliance())?.0,
        with_marker: if sets.iter().any(|s| s.marker()) {
            Some(pick(&|s| s.marker())?.0)
        } else {
            None
        },
        min_spec,
        min_se,
        table,
    })
}

/// Prints the CV table of `c` (rows: parameter sets, columns: prior σ; `*` the choice).
pub fn print_cv(title: &str, unit: &str, sets: &[ParamSet], c: &Choice) {
    println!("{title}");
    print!("  {:<16}", "set \\ σ");
    for s in SIGMA_GRID {
        print!(" {s:>8}");
    }
    println!();
    for &set in sets {
        print!("  {:<16}", set.name());
        for (spec, v, _) in c.table.iter().filter(|(s, _, _)| s.set == set) {
            let mark = if *spec == c.spec { "*" } else { " " };
            print!(" {v:>7.4}{mark}");
        }
        println!();
    }
    println!(
        "  smallest {unit}: {} σ {} (SE {:.4}); chosen (*): {} with σ = {} mrad / mm",
        c.min_spec.set.name(),
        c.min_spec.sigma,
        c.min_se,
        c.spec.set.name(),
        c.spec.sigma
    );
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
}

/// Writes the CV table of `c` to `path` (one row per candidate; `criterion` names the column).
pub fn write_cv(path: &Path, c: &Choice, criterion: &str) -> anyhow::Result<()> {
    let mut w = std::fs::File::create(path).with_context(|| format!("{}", path.display()))?;
    writeln!(w, "set,sigma_mrad_or_mm,{criterion},se,chosen")?;
    for (s, v, se) in &c.table {
        writeln!(
            w,
            "{},{},{v:.6},{se:.6},{}",
            s.set.name(),
            s.sigma,
            *s == c.spec
        )?;
    }
    Ok(())
}

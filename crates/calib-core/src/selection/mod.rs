//! Choosing a model from held-out scores: the workspace's one home of the selection rules that
//! the studies and `diagnose` apply to cross-validation results.
//!
//! 1. **CV error of a candidate**: [`CvError::from_squares`], the held-out rms of squared errors
//!    and its delta-method standard error.
//! 2. **One-standard-error rules** over candidates listed simplest first: [`pooled_one_se`] (one
//!    error per candidate) and [`per_kind_one_se`] (one error per observation kind, every kind
//!    at once, with a fallback when none qualifies).
//! 3. **Significance of a consistent gain**: [`one_sample_t`], the t statistic of per-unit gains.
//! 4. **The do-no-harm rule** over held-out *regions*: [`do_no_harm`], from a table of per-region
//!    scores of each candidate and of the nominal model (the rule of
//!    `studies/ctu-motoman/docs/region-protocol.md`); [`region_harm`], its one-sided paired test
//!    of one region (a candidate is harmful there when it is worse than nominal with
//!    significance), and [`judge_harm`], the session-wide judge over every held-out region and
//!    observation kind at a stated false-alarm rate ([`HARM_FALSE_ALARM`]), which both
//!    `diagnose --export` and `calibrate --cell --export` apply.
//! 5. **The folds of region-held-out CV**: [`regions`], seeded k-means++ clusters of the
//!    session's joint vectors.
//!
//! Every rule takes candidates in the caller's order of simplicity (simplest first) and breaks
//! ties towards the simpler candidate. Nothing here fits a model: the callers hold the folds,
//! the fits and the scores.

pub mod regions;
#[cfg(test)]
mod tests;

/// A CV error: the held-out rms `e` of a candidate (in the units of its scores: σ units, mm, …)
/// and its standard error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CvError {
    /// Held-out rms, `sqrt(mean e²)`.
    pub e: f64,
    /// Its standard error, `sd(e²) / (2·e·sqrt(n))` (delta method).
    pub se: f64,
}

impl CvError {
    /// The CV error of held-out squared errors `e2` (one per row or point). The sample standard
    /// deviation divides by `n − 1` (by 1 with a single value, whose SE is then 0). Empty `e2`:
    /// `e = 0` and `se = NaN`; a zero rms gives `se = NaN` too (0/0), which no rule reads as a
    /// gain.
    pub fn from_squares(e2: &[f64]) -> CvError {
        let n = e2.len().max(1) as f64;
        let mean = e2.iter().sum::<f64>() / n;
        let var = e2.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let c = mean.sqrt();
        CvError {
            e: c,
            se: var.sqrt() / (2.0 * c * n.sqrt()),
        }
    }
}

/// The index of the smallest value (the first on a tie, in `f64::total_cmp` order, so a NaN
/// is never the smallest unless every value is NaN). `None` for an empty slice.
pub fn argmin(values: &[f64]) -> Option<usize> {
    (0..values.len()).min_by(|&a, &b| values[a].total_cmp(&values[b]))
}

/// The one-SE rule on one (pooled) CV error per candidate, simplest first: the first candidate
/// with `e ≤ e_min + SE_min`, where `e_min` is the smallest error ([`argmin`]) and `SE_min`
/// its standard error. `None` without candidates.
pub fn pooled_one_se(pooled: &[CvError]) -> Option<usize> {
    let e: Vec<f64> = pooled.iter().map(|c| c.e).collect();
    let min = argmin(&e)?;
    pooled
        .iter()
        .position(|c| c.e <= pooled[min].e + pooled[min].se)
}

/// The per-kind one-SE rule's pick among candidates listed simplest first.
#[derive(Debug, Clone, PartialEq)]
pub struct PerKindPick {
    /// Index of the chosen candidate.
    pub index: usize,
    /// Whether each candidate qualifies (within one SE of each kind's best, on every kind).
    pub qualifies: Vec<bool>,
    /// Per kind, the index of the candidate with the smallest error (the first on a tie).
    pub best: Vec<usize>,
    /// `None` when the choice qualifies; else its largest shortfall in SEs (the fallback).
    pub shortfall: Option<f64>,
}

/// The per-kind one-SE rule on `errors[c][k]` (candidate c, simplest first; observation kind
/// k): `best_k` = argmin_c e_k(c); c qualifies when `e_k(c) ≤ e_k(best_k) + SE_k(best_k)` for
/// every k; the pick is the first qualifying candidate, or, when none qualifies, the one
/// minimising `max_k (e_k(c) − e_k(best_k)) / SE_k(best_k)` (the first on a tie; a zero SE
/// counts a positive difference as infinitely many SEs). With one kind this is
/// [`pooled_one_se`]. `None` without candidates or kinds, or when the candidates disagree on
/// the number of kinds.
pub fn per_kind_one_se(errors: &[Vec<CvError>]) -> Option<PerKindPick> {
    let kinds = errors.first()?.len();
    if kinds == 0 || errors.iter().any(|c| c.len() != kinds) {
        return None;
    }
    let best: Vec<usize> = (0..kinds)
        .map(|k| {
            let e: Vec<f64> = errors.iter().map(|c| c[k].e).collect();
            argmin(&e).unwrap_or(0)
        })
        .collect();
    let qualifies: Vec<bool> = errors
        .iter()
        .map(|c| {
            (0..kinds).all(|k| {
                let b = errors[best[k]][k];
                c[k].e <= b.e + b.se
            })
        })
        .collect();
    if let Some(index) = qualifies.iter().position(|&q| q) {
        return Some(PerKindPick {
            index,
            qualifies,
            best,
            shortfall: None,
        });
    }
    let shortfall = |c: &[CvError]| -> f64 {
        (0..kinds)
            .map(|k| {
                let b = errors[best[k]][k];
                let d = c[k].e - b.e;
                if b.se > 0.0 {
                    d / b.se
                } else if d > 0.0 {
                    f64::INFINITY
                } else {
                    0.0
                }
            })
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let shortfalls: Vec<f64> = errors.iter().map(|c| shortfall(c)).collect();
    let index = argmin(&shortfalls)?;
    Some(PerKindPick {
        index,
        shortfall: Some(shortfalls[index]),
        qualifies,
        best,
    })
}

/// The one-sample t statistic of `values` (e.g. the relative held-out gains of the units a
/// candidate touches): `mean / sqrt(var / n)`, the sample variance dividing by `n − 1`. A zero
/// variance gives `+∞` when the mean is positive, else 0 (a constant gain is certain; a constant
/// loss or no change is no evidence of a gain). Fewer than two values: NaN (no variance to judge
/// by; the caller decides what a gain of one unit is worth).
pub fn one_sample_t(values: &[f64]) -> f64 {
    if values.len() < 2 {
        return f64::NAN;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    if var > 0.0 {
        mean / (var / n).sqrt()
    } else if mean > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// Invalid input to [`do_no_harm`]. Each names the region or candidate (0-based, in the order
/// given) and what a valid table holds.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SelectionError {
    /// No region to judge on.
    #[error(
        "no region scores: the do-no-harm rule needs the nominal model's score in at least one \
         held-out region"
    )]
    NoRegions,
    /// A candidate's row has another length than the nominal row.
    #[error(
        "candidate {candidate} has {got} region scores but the nominal model has {expected}: \
         give every candidate a score in every region, in the same region order"
    )]
    RegionCount {
        /// The candidate (0-based).
        candidate: usize,
        /// Its number of scores.
        got: usize,
        /// The nominal model's number of scores.
        expected: usize,
    },
    /// The nominal model's score of a region is not a positive finite number.
    #[error(
        "the nominal model's score in region {region} is {value}: it must be finite and > 0 \
         (a region whose nominal error is 0 cannot show harm; leave it out)"
    )]
    NominalScore {
        /// The region (0-based).
        region: usize,
        /// The score given.
        value: f64,
    },
    /// A candidate's score of a region is not a finite number ≥ 0.
    #[error(
        "candidate {candidate}'s score in region {region} is {value}: scores are held-out errors, \
         finite and ≥ 0 (score a failed fit as such, or leave the candidate out)"
    )]
    CandidateScore {
        /// The candidate (0-based).
        candidate: usize,
        /// The region (0-based).
        region: usize,
        /// The score given.
        value: f64,
    },
    /// The false-alarm rate given to [`judge_harm`] is not a probability.
    #[error(
        "false-alarm rate {0}: the do-no-harm judge needs a rate in (0, 1), e.g. 0.05 \
         (HARM_FALSE_ALARM)"
    )]
    FalseAlarm(f64),
}

/// What [`do_no_harm`] decided, with the numbers it decided on.
#[derive(Debug, Clone, PartialEq)]
pub struct DoNoHarmChoice {
    /// `ratios[c][s]`: candidate c's held-out score in region s over the nominal model's.
    pub ratios: Vec<Vec<f64>>,
    /// Each candidate's mean ratio over the regions.
    pub mean_ratio: Vec<f64>,
    /// Each candidate's standard error of its mean ratio: the sample standard deviation of its
    /// ratios (dividing by `|S| − 1`, by 1 with one region) over `sqrt(|S|)`.
    pub se_ratio: Vec<f64>,
    /// Whether each candidate is eligible: its ratio is ≤ 1 in every region.
    pub eligible: Vec<bool>,
    /// The eligible candidate with the smallest mean ratio (the first on a tie); `None` when no
    /// candidate is eligible.
    pub best: Option<usize>,
    /// The one-SE threshold, `mean_ratio[best] + se_ratio[best]`; `None` without `best`.
    pub threshold: Option<f64>,
    /// The choice: `Some(c)`, or `None` for the nominal model (no candidate is eligible, or the
    /// nominal model, simplest of all with mean ratio 1, is within the threshold).
    pub choice: Option<usize>,
    /// The candidates withheld for harm: ineligible ones that are better than nominal (ratio
    /// < 1) in at least one region. Ascending.
    pub withheld: Vec<usize>,
}

/// The do-no-harm choice among candidates from their held-out scores per region.
///
/// `nominal[s]` is the nominal model's score (an error: smaller is better, e.g. a held-out rms
/// in mm) in held-out region s; `candidates[c][s]` is candidate c's score in region s, fitted
/// without region s (the caller's folds). Candidates are listed simplest first; the nominal
/// model is a candidate too, simpler than all of them, with ratio 1 in every region.
///
/// 1. `ratio(c, s) = candidates[c][s] / nominal[s]`.
/// 2. c is **eligible** when `ratio(c, s) ≤ 1` for every region s: it does no harm in any
///    region it was not trained on.
/// 3. `best` = the eligible candidate of smallest mean ratio; the **one-SE rule** then takes the
///    simplest eligible candidate (the nominal model first) whose mean ratio is ≤ `mean(best) +
///    SE(best)`, SE = sd of best's ratios / `sqrt(|S|)`.
/// 4. No eligible candidate: the nominal model.
///
/// # Errors
/// [`SelectionError`] when there is no region, when a candidate's row is not as long as
/// `nominal`, when a nominal score is not finite and > 0, or a candidate score not finite and
/// ≥ 0.
///
/// # Examples
/// ```
/// use calib_core::selection::do_no_harm;
/// // Nominal's held-out rms (mm) in three regions, and two candidates, simplest first.
/// let nominal = [0.40, 0.50, 0.60];
/// let offsets = vec![0.30, 0.55, 0.30]; // better on average, but worse in region 1
/// let physical = vec![0.36, 0.45, 0.50]; // better everywhere
/// let c = do_no_harm(&nominal, &[offsets, physical]).unwrap();
/// assert_eq!(c.eligible, vec![false, true]);
/// assert_eq!(c.choice, Some(1));
/// assert_eq!(c.withheld, vec![0]);
/// ```
pub fn do_no_harm(
    nominal: &[f64],
    candidates: &[Vec<f64>],
) -> Result<DoNoHarmChoice, SelectionError> {
    if nominal.is_empty() {
        return Err(SelectionError::NoRegions);
    }
    if let Some((region, &value)) = nominal
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v > 0.0))
    {
        return Err(SelectionError::NominalScore { region, value });
    }
    for (candidate, row) in candidates.iter().enumerate() {
        if row.len() != nominal.len() {
            return Err(SelectionError::RegionCount {
                candidate,
                got: row.len(),
                expected: nominal.len(),
            });
        }
        if let Some((region, &value)) = row
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v >= 0.0))
        {
            return Err(SelectionError::CandidateScore {
                candidate,
                region,
                value,
            });
        }
    }
    let regions = nominal.len() as f64;
    let ratios: Vec<Vec<f64>> = candidates
        .iter()
        .map(|row| row.iter().zip(nominal).map(|(c, n)| c / n).collect())
        .collect();
    let mean_ratio: Vec<f64> = ratios
        .iter()
        .map(|r| r.iter().sum::<f64>() / regions)
        .collect();
    let se_ratio: Vec<f64> = ratios
        .iter()
        .zip(&mean_ratio)
        .map(|(r, m)| {
            let var = r.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (regions - 1.0).max(1.0);
            (var / regions).sqrt()
        })
        .collect();
    let eligible: Vec<bool> = ratios.iter().map(|r| r.iter().all(|&v| v <= 1.0)).collect();
    let withheld: Vec<usize> = (0..candidates.len())
        .filter(|&c| !eligible[c] && ratios[c].iter().any(|&v| v < 1.0))
        .collect();
    let eligible_means: Vec<f64> = mean_ratio
        .iter()
        .zip(&eligible)
        .map(|(&m, &e)| if e { m } else { f64::INFINITY })
        .collect();
    let best = argmin(&eligible_means).filter(|&b| eligible[b]);
    let threshold = best.map(|b| mean_ratio[b] + se_ratio[b]);
    // The nominal model (mean ratio 1, the simplest) first, then the candidates in order.
    let choice = match threshold {
        Some(t) if 1.0 > t => (0..candidates.len()).find(|&c| eligible[c] && mean_ratio[c] <= t),
        _ => None,
    };
    Ok(DoNoHarmChoice {
        ratios,
        mean_ratio,
        se_ratio,
        eligible,
        best,
        threshold,
        choice,
        withheld,
    })
}

/// The one-sided t value of a single paired test at [`HARM_FALSE_ALARM`] under normal errors
/// (`Φ⁻¹(0.95)` ≈ 1.645): [`region_harm`]'s threshold when one region is judged alone. The
/// session-wide judge [`judge_harm`] sets its own per-comparison thresholds from
/// [`HARM_FALSE_ALARM`], the number of comparisons and each one's row count.
pub const HARM_T: f64 = 1.644_853_626_951_472_2;

/// The chance, per checked session, that the do-no-harm judge [`judge_harm`] calls a model
/// harmful when it is not (one-sided: worse than nominal with significance in some region and
/// kind). 5 %, the conventional level, fixed before any session was judged: one healthy
/// session in twenty may lose its corrections to a false alarm (the safe model is then
/// exported and the warning says why, `--force` keeps the full model).
pub const HARM_FALSE_ALARM: f64 = 0.05;

/// Fewest held-out rows of one observation kind in one fold for the kind to be judged on its
/// own by [`judge_harm`]; a fold's kinds with fewer rows are pooled (see there). Eight: the
/// fewest rows of a region of the do-no-harm check (`MIN_HARM_REGION_ROWS`), so a kind is
/// judged alone exactly when it could have been a region on its own. The paired t of squared
/// errors is skewed (differences of χ² values); below a few rows its one-sided tail is far from
/// Student's, above it Student's quantile at `n − 1` degrees of freedom
/// ([`crate::stats::t_quantile`]) absorbs the small-sample width. Chosen from the check's
/// structure, not from any score.
pub const MIN_KIND_ROWS: usize = 8;

/// One region's verdict of [`region_harm`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RegionHarm {
    /// The candidate's held-out rms over nominal's in the region, `sqrt(Σe²_c / Σe²_nominal)`.
    pub ratio: f64,
    /// The t statistic ([`one_sample_t`]) of the paired per-row gains `e²_nominal − e²_c`:
    /// negative when the candidate is worse (NaN with fewer than two rows).
    pub t: f64,
    /// Harmful: `t ≤ −t_harm` (worse than nominal with significance).
    pub harmful: bool,
}

/// The do-no-harm test of one model in one named fold, as the reports give it (`diagnose`'s
/// `do_no_harm.steps[].folds[]`, `calibrate --cell --export`'s `do_no_harm.folds[]`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FoldHarm {
    /// The fold's name (`region 1`, `fold 2`, `block 3`, …).
    pub fold: String,
    /// The model's held-out rms over nominal's in the fold, all its rows pooled.
    pub ratio: f64,
    /// The paired t of the per-row gains, all rows pooled (negative: worse than nominal).
    pub t: f64,
    /// Worse than nominal with significance in some comparison of the fold (`kinds`).
    pub harmful: bool,
    /// The fold's comparisons ([`judge_harm`]): one per observation kind with at least
    /// [`MIN_KIND_ROWS`] rows, the others pooled (not serialised when empty).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub kinds: Vec<KindHarm>,
}

impl FoldHarm {
    /// The verdict `harm` of [`region_harm`] in the fold named `fold`, with its per-kind verdicts
    /// `kinds` (empty when not judged per kind).
    pub fn new(fold: &str, harm: &RegionHarm, kinds: Vec<KindHarm>) -> Self {
        FoldHarm {
            fold: fold.to_string(),
            ratio: harm.ratio,
            t: harm.t,
            harmful: harm.harmful,
            kinds,
        }
    }
}

/// One comparison of [`judge_harm`]: the held-out rows of one observation kind of a fold (or
/// of several small kinds pooled).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct KindHarm {
    /// The observation kind (`coincident`, `contact`, `tracker`, `plane`, …), or the kinds
    /// pooled, joined by `+` (`contact+plane`), in order of first appearance.
    pub kind: String,
    /// Held-out rows in the comparison.
    pub rows: usize,
    /// The model's held-out rms over nominal's on those rows.
    pub ratio: f64,
    /// The paired t of their per-row gains (negative: worse than nominal; NaN below two rows).
    pub t: f64,
    /// The one-sided threshold it was judged at (harmful when `t ≤ −t_harm`): Student's t
    /// quantile at `rows − 1` degrees of freedom and the Šidák level of the session's
    /// comparisons ([`judge_harm`]).
    pub t_harm: f64,
    /// Worse than nominal with significance on those rows.
    pub harmful: bool,
}

/// One fold's held-out rows for [`judge_harm`]: the fold's name, each row's observation kind,
/// and its squared held-out error (e.g. whitened residual norm²) under nominal and under the
/// candidate, each fitted without the fold.
#[derive(Debug, Clone, PartialEq)]
pub struct FoldRows<'a> {
    /// The fold's name (`region 1`, …).
    pub name: String,
    /// Row `i`'s observation kind.
    pub kinds: Vec<&'a str>,
    /// Row `i`'s squared held-out error under nominal.
    pub nominal_e2: Vec<f64>,
    /// Row `i`'s squared held-out error under the candidate.
    pub candidate_e2: Vec<f64>,
}

/// The verdict of [`judge_harm`] over a session's folds.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct HarmJudgement {
    /// The per-session false-alarm rate the thresholds hold ([`HARM_FALSE_ALARM`]).
    pub false_alarm: f64,
    /// The number of comparisons made over all folds (the Šidák family).
    pub comparisons: usize,
    /// Each comparison's one-sided level `1 − (1 − false_alarm)^(1/comparisons)`.
    pub alpha_each: f64,
    /// Each fold's verdict, in fold order.
    pub folds: Vec<FoldHarm>,
}

impl HarmJudgement {
    /// Whether the candidate is harmful in any fold.
    pub fn harmful(&self) -> bool {
        self.folds.iter().any(|f| f.harmful)
    }
}

/// The comparisons of one fold: groups of row indices with their label.
fn fold_comparisons(kinds: &[&str]) -> Vec<(String, Vec<usize>)> {
    let mut order: Vec<&str> = Vec::new();
    for k in kinds {
        if !order.contains(k) {
            order.push(k);
        }
    }
    let rows_of = |k: &str| -> Vec<usize> { (0..kinds.len()).filter(|&i| kinds[i] == k).collect() };
    let (big, small): (Vec<&str>, Vec<&str>) = order
        .iter()
        .partition(|k| rows_of(k).len() >= MIN_KIND_ROWS);
    if big.is_empty() {
        // No kind has enough rows alone: the whole fold is one comparison.
        return vec![(order.join("+"), (0..kinds.len()).collect())];
    }
    let mut out: Vec<(String, Vec<usize>)> =
        big.iter().map(|k| (k.to_string(), rows_of(k))).collect();
    if !small.is_empty() {
        let mut rows: Vec<usize> = small.iter().flat_map(|k| rows_of(k)).collect();
        rows.sort_unstable();
        if rows.len() >= MIN_KIND_ROWS {
            out.push((small.join("+"), rows));
        } else {
            // Too few to judge alone: pooled with the fold's largest kind.
            let largest = (0..out.len()).max_by_key(|&c| out[c].1.len()).unwrap_or(0);
            out[largest].0 = format!("{}+{}", out[largest].0, small.join("+"));
            out[largest].1.extend(rows);
            out[largest].1.sort_unstable();
        }
    }
    out
}

/// The session-wide do-no-harm judge: is the candidate worse than nominal, with significance,
/// in some fold? Each fold's rows are cut into **comparisons**: one per observation kind with
/// at least [`MIN_KIND_ROWS`] rows (a model that makes the tracker rows of a region worse is
/// not excused by better handclasps there: the kinds have different σ and counts, so a pooled
/// sum would let the larger decide); the rows of the fold's smaller kinds pooled into one more
/// comparison when they reach [`MIN_KIND_ROWS`], else into the fold's largest comparison; a
/// fold with no kind of [`MIN_KIND_ROWS`] rows is one comparison. With `m` comparisons over all
/// folds, each is judged at the Šidák level `α_m = 1 − (1 − false_alarm)^(1/m)`: harmful when
/// the paired t of its per-row gains `e²_nominal − e²_c` is `≤ −t_{n−1}(1 − α_m)` (Student's
/// quantile at its `n − 1` degrees of freedom), so a harmless model is called harmful
/// somewhere in the session with probability at most `false_alarm` when the comparisons are
/// independent (Šidák's bound also holds for positively dependent tests, as folds sharing
/// training rows are). A comparison of fewer than two rows is never harmful.
///
/// # Errors
/// [`SelectionError::NoRegions`] when `folds` is empty or a fold has no row;
/// [`SelectionError::RegionCount`] when a fold's slices differ in length;
/// [`SelectionError::CandidateScore`] when a value is not finite and ≥ 0;
/// [`SelectionError::FalseAlarm`] when `false_alarm` is not in (0, 1).
///
/// # Examples
/// ```
/// use calib_core::selection::{judge_harm, FoldRows, HARM_FALSE_ALARM};
/// let mut kinds = vec!["coincident"; 8];
/// kinds.extend(["tracker"; 8]);
/// let nominal = vec![1.0, 1.2, 0.9, 1.1, 1.0, 0.8, 1.1, 0.9, 1.0, 1.2, 0.9, 1.1, 1.0, 0.8, 1.1, 0.9];
/// // Better on the handclasps, much worse on the tracker rows.
/// let candidate: Vec<f64> = nominal
///     .iter()
///     .enumerate()
///     .map(|(i, e)| if i < 8 { 0.5 * e } else { 3.0 * e })
///     .collect();
/// let fold = FoldRows { name: "region 1".into(), kinds, nominal_e2: nominal, candidate_e2: candidate };
/// let j = judge_harm(&[fold], HARM_FALSE_ALARM).unwrap();
/// assert_eq!(j.comparisons, 2);
/// assert!(j.harmful());
/// assert!(j.folds[0].kinds[1].harmful && !j.folds[0].kinds[0].harmful);
/// ```
pub fn judge_harm(folds: &[FoldRows], false_alarm: f64) -> Result<HarmJudgement, SelectionError> {
    if !(false_alarm > 0.0 && false_alarm < 1.0) {
        return Err(SelectionError::FalseAlarm(false_alarm));
    }
    if folds.is_empty() {
        return Err(SelectionError::NoRegions);
    }
    let mut plans = Vec::with_capacity(folds.len());
    for f in folds {
        if f.kinds.len() != f.nominal_e2.len() {
            return Err(SelectionError::RegionCount {
                candidate: 0,
                got: f.kinds.len(),
                expected: f.nominal_e2.len(),
            });
        }
        // Validates lengths and values (the pooled verdict's threshold is set below).
        let pooled = region_harm(&f.nominal_e2, &f.candidate_e2, f64::INFINITY)?;
        plans.push((pooled, fold_comparisons(&f.kinds)));
    }
    let m: usize = plans.iter().map(|(_, c)| c.len()).sum();
    let alpha_each = 1.0 - (1.0 - false_alarm).powf(1.0 / m.max(1) as f64);
    let mut out = Vec::with_capacity(folds.len());
    for (f, (pooled, comps)) in folds.iter().zip(plans) {
        let mut kinds = Vec::with_capacity(comps.len());
        for (label, rows) in comps {
            let n: Vec<f64> = rows.iter().map(|&i| f.nominal_e2[i]).collect();
            let c: Vec<f64> = rows.iter().map(|&i| f.candidate_e2[i]).collect();
            let t_harm = if rows.len() >= 2 {
                crate::stats::t_quantile(1.0 - alpha_each, rows.len() - 1)
            } else {
                f64::INFINITY
            };
            let h = region_harm(&n, &c, t_harm)?;
            kinds.push(KindHarm {
                kind: label,
                rows: rows.len(),
                ratio: h.ratio,
                t: h.t,
                t_harm,
                harmful: h.harmful,
            });
        }
        let harmful = kinds.iter().any(|k| k.harmful);
        out.push(FoldHarm::new(
            &f.name,
            &RegionHarm { harmful, ..pooled },
            kinds,
        ));
    }
    Ok(HarmJudgement {
        false_alarm,
        comparisons: m,
        alpha_each,
        folds: out,
    })
}

/// The do-no-harm test of one held-out region: `nominal_e2[i]` and `candidate_e2[i]` are the
/// squared held-out errors (e.g. whitened residual norms²) of the same row `i` of the region
/// under the nominal model and the candidate, each fitted without the region. The candidate is
/// **harmful** in the region when the one-sided paired t of the gains is `≤ −t_harm` ([`HARM_T`]
/// is a single test's value at [`HARM_FALSE_ALARM`]; [`judge_harm`] judges a whole session). A region of fewer than two rows
/// is never judged harmful (no variance to judge by).
///
/// # Errors
/// [`SelectionError::RegionCount`] when the two slices differ in length (candidate 0),
/// [`SelectionError::NoRegions`] when they are empty, [`SelectionError::CandidateScore`] when a
/// value is not finite and ≥ 0 (region 0, candidate 0 for the candidate, 1 for nominal).
///
/// # Examples
/// ```
/// use calib_core::selection::{region_harm, HARM_T};
/// let nominal = [1.0, 1.2, 0.9, 1.1, 1.0, 0.8];
/// let worse: Vec<f64> = nominal.iter().map(|e| 2.0 * e + 0.1).collect();
/// assert!(region_harm(&nominal, &worse, HARM_T).unwrap().harmful);
/// let better: Vec<f64> = nominal.iter().map(|e| 0.5 * e).collect();
/// assert!(!region_harm(&nominal, &better, HARM_T).unwrap().harmful);
/// ```
pub fn region_harm(
    nominal_e2: &[f64],
    candidate_e2: &[f64],
    t_harm: f64,
) -> Result<RegionHarm, SelectionError> {
    if nominal_e2.is_empty() {
        return Err(SelectionError::NoRegions);
    }
    if candidate_e2.len() != nominal_e2.len() {
        return Err(SelectionError::RegionCount {
            candidate: 0,
            got: candidate_e2.len(),
            expected: nominal_e2.len(),
        });
    }
    for (candidate, values) in [candidate_e2, nominal_e2].iter().enumerate() {
        if let Some(&value) = values.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
            return Err(SelectionError::CandidateScore {
                candidate,
                region: 0,
                value,
            });
        }
    }
    let (n, c): (f64, f64) = (nominal_e2.iter().sum(), candidate_e2.iter().sum());
    let ratio = if n > 0.0 {
        (c / n).sqrt()
    } else if c > 0.0 {
        f64::INFINITY
    } else {
        1.0
    };
    let gains: Vec<f64> = nominal_e2
        .iter()
        .zip(candidate_e2)
        .map(|(a, b)| a - b)
        .collect();
    let t = one_sample_t(&gains);
    Ok(RegionHarm {
        ratio,
        t,
        harmful: t <= -t_harm,
    })
}

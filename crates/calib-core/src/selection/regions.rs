//! Regions of joint space: the folds of region-held-out cross-validation (issue 20). A region
//! is a cluster of the session's joint vectors, so a fold that holds one out asks the model to
//! extrapolate to postures it did not see, not to interpolate between neighbours.
//!
//! 1. [`joint_features`]: each observation's joint vectors, every joint normalised by its limit
//!    span (a joint the row does not use is missing, `NaN`).
//! 2. [`region_count`]: how many regions a number of rows affords.
//! 3. [`joint_regions`]: how many regions, from the session's cluster structure, then where:
//!    - **natural clusters** (seed-free): the rows' minimum spanning tree is cut at every edge
//!      longer than [`cluster_gap_ratio`] times its median positive edge (a gap no session
//!      without clusters shows but one time in [`CLUSTER_FALSE_ALARM`]⁻¹), and a cluster short of
//!      the minimum size is merged into its nearest neighbour (single linkage). When 3 to `k`
//!      clusters remain, their count is the number of regions and their centres start Lloyd's
//!      iterations (a fixed count `rows/min_rows` cut a 72-row session of four posture clusters
//!      into 6 regions of 12, and each held-out region then sat beside training rows of its own
//!      cluster). Lloyd's iterations move rows between the clusters: a compact cluster far from
//!      the others keeps its rows, but the regions are not the clusters as cut. Measured on a
//!      20,000-row session: clusters [14, 19341, 599, 23, 23] became regions [10727, 599, 8628,
//!      23, 23] (the 14-row cluster's centre walked into the long one and took half of it). Tried
//!      at stop 35 and reverted: the clusters as cut, with no Lloyd step, made a 72-row
//!      region-limited session's regions [18, 42, 12] and the diagnosis lost the compliance it
//!      must find there (`diagnose`'s test `region_limited_compliance_truth_exports_no_offsets_
//!      that_extrapolate_badly`: holding out 42 of 72 rows leaves too few to fit); a rule that
//!      keeps clusters whole and every fold trainable is open (issue 20);
//!    - otherwise (no structure, or too little for three regions, or more clusters than `k`):
//!      `k = min(rows/min_rows, max_regions)` regions by seeded k-means++;
//!
//!    in both cases Lloyd's assignment keeps every region at the minimum size (a region short
//!    of rows takes the rows that cost least to move from regions above it), so a session gets
//!    the regions its size allows even where its postures do not cluster; regions numbered in
//!    order of their first row.
//!
//! No crate does this under the workspace's MSRV with nalgebra vectors and a seeded
//! `ChaCha8Rng` in forty lines, so it is written here.

use rand::Rng;

use crate::whole_cell::CellProblem;
use crate::Robot;

mod spanning_tree;
use spanning_tree::spanning_tree;

/// Most regions [`region_count`] gives.
pub const MAX_REGIONS: usize = 6;
/// Fewest regions a region-held-out design needs (below, the caller falls back to its groups).
pub const MIN_REGIONS: usize = 3;
/// Fewest rows (observations) of a joint-space region of a region-held-out design
/// (`diagnose --cv-folds regions`, `calibrate --cell`'s do-no-harm check): twelve rows are
/// enough for the paired t of [`super::region_harm`] and, in `diagnose`, to refit a tracker
/// frame or a plane on half of a region's piece of a group.
pub const MIN_REGION_ROWS: usize = 12;
/// Seed of the k-means++ draw of every region-held-out design in the workspace (`diagnose
/// --cv-folds regions`, `calibrate --cell`'s do-no-harm check, the prediction's model-error
/// term): one seed, so one session gets the same regions from every command.
pub const REGION_SEED: u64 = 20;
/// Probability that a session without clusters (rows uniform on a line, the worst case) has a
/// gap [`cluster_gap_ratio`] calls a cluster boundary: one in a thousand.
pub const CLUSTER_FALSE_ALARM: f64 = 1e-3;
/// Lloyd iterations of [`joint_regions`] at most (it stops earlier when no label changes).
const LLOYD_ITERATIONS: usize = 100;

/// The regions of `rows` rows with at least `min_rows` rows each: `min(rows / min_rows,
/// MAX_REGIONS)` (0 when `min_rows` is 0).
pub fn region_count(rows: usize, min_rows: usize) -> usize {
    rows.checked_div(min_rows).unwrap_or(0).min(MAX_REGIONS)
}

/// The features of observations `rows` of `problem`: per row, robot 1's joints then robot 2's,
/// each `(q − lower)/(upper − lower)` (a span over 2π, a continuous joint's, counts as 2π; a
/// zero span as 1), `NaN` for the joints of a robot the row does not use.
pub fn joint_features(problem: &CellProblem, rows: &[usize]) -> Vec<Vec<f64>> {
    let spans = |r: Robot| -> Vec<(f64, f64)> {
        problem
            .robot(r)
            .model
            .joints()
            .iter()
            .map(|j| {
                let span = (j.upper - j.lower).min(std::f64::consts::TAU);
                let lower = if j.lower.is_finite() { j.lower } else { 0.0 };
                (lower, if span > 0.0 { span } else { 1.0 })
            })
            .collect()
    };
    let s = [spans(Robot::One), spans(Robot::Two)];
    rows.iter()
        .map(|&i| {
            let mut f = vec![f64::NAN; s[0].len() + s[1].len()];
            for (robot, q) in problem.observations[i].kind.joints() {
                let (k, off) = match robot {
                    Robot::One => (0, 0),
                    Robot::Two => (1, s[0].len()),
                };
                for (j, (&v, &(lo, span))) in q.iter().zip(&s[k]).enumerate() {
                    f[off + j] = (v - lo) / span;
                }
            }
            f
        })
        .collect()
}

/// Regions of joint space found by [`joint_regions`].
#[derive(Debug, Clone, PartialEq)]
pub struct Regions {
    /// The region of each feature row (0-based, numbered in order of first appearance).
    pub labels: Vec<usize>,
    /// Rows per region.
    pub sizes: Vec<usize>,
    /// Each region's centre (mean feature vector after imputation).
    pub centres: Vec<Vec<f64>>,
    /// The seed of the k-means++ draw.
    pub seed: u64,
}

fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum()
}

fn nearest(x: &[f64], centres: &[Vec<f64>]) -> usize {
    let d: Vec<f64> = centres.iter().map(|c| dist2(x, c)).collect();
    super::argmin(&d).unwrap_or(0)
}

/// The nearest-centre labels of `x`, then, while a region holds fewer than `min_rows` rows, the
/// row that costs least to move (`‖p − c_short‖² − ‖p − c_own‖²`, the first on a tie) from a
/// region holding more than `min_rows` into the smallest short region (the first on a tie).
/// Every region ends with at least `min_rows` rows when `x.len() ≥ centres.len() · min_rows`
/// (a short region always finds a region above the minimum to take from; each move fills a
/// short region by one and leaves the giver at the minimum or above).
fn assign_min_size(x: &[Vec<f64>], centres: &[Vec<f64>], min_rows: usize) -> Vec<usize> {
    let mut labels: Vec<usize> = x.iter().map(|p| nearest(p, centres)).collect();
    let mut sizes = vec![0usize; centres.len()];
    for &l in &labels {
        sizes[l] += 1;
    }
    if x.len() < centres.len() * min_rows {
        return labels;
    }
    while let Some(short) = (0..centres.len())
        .filter(|&c| sizes[c] < min_rows)
        .min_by_key(|&c| sizes[c])
    {
        let cost: Vec<f64> = x
            .iter()
            .zip(&labels)
            .map(|(p, &l)| {
                if sizes[l] > min_rows {
                    dist2(p, &centres[short]) - dist2(p, &centres[l])
                } else {
                    f64::INFINITY
                }
            })
            .collect();
        let Some(row) = super::argmin(&cost).filter(|&i| cost[i].is_finite()) else {
            break;
        };
        sizes[labels[row]] -= 1;
        sizes[short] += 1;
        labels[row] = short;
    }
    labels
}

/// Lloyd's iterations from `centres` with [`assign_min_size`]'s assignment: labels and the
/// updated centres (each the mean of its rows; with the minimum kept no region is empty).
/// Stops when no label changes or after [`LLOYD_ITERATIONS`].
fn lloyd_min_size(
    x: &[Vec<f64>],
    mut centres: Vec<Vec<f64>>,
    min_rows: usize,
) -> (Vec<usize>, Vec<Vec<f64>>) {
    let mut labels = assign_min_size(x, &centres, min_rows);
    for _ in 0..LLOYD_ITERATIONS {
        for (c, centre) in centres.iter_mut().enumerate() {
            let members: Vec<&Vec<f64>> = x
                .iter()
                .zip(&labels)
                .filter(|(_, &l)| l == c)
                .map(|(p, _)| p)
                .collect();
            if !members.is_empty() {
                for (d, v) in centre.iter_mut().enumerate() {
                    *v = members.iter().map(|p| p[d]).sum::<f64>() / members.len() as f64;
                }
            }
        }
        let next = assign_min_size(x, &centres, min_rows);
        if next == labels {
            break;
        }
        labels = next;
    }
    (labels, centres)
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

/// The gap a tree edge must exceed to separate two natural clusters, in units of the
/// session's typical neighbour distance (the median positive edge of the spanning tree), for
/// `n` rows: `(ln(n − 1) + ln(1/CLUSTER_FALSE_ALARM)) / ln 2`, about 15 for 40 rows and 21 for
/// 2,000. Chosen from the geometry of data without clusters, never from a score: for rows
/// drawn uniformly on a line (the heaviest-tailed case: in more dimensions neighbour distances
/// concentrate) the tree's edges are the spacings, about exponential, so the longest of the
/// `n − 1` exceeds `ρ` medians with probability about `(n − 1)·2^(−ρ)`, which this `ρ` holds at
/// [`CLUSTER_FALSE_ALARM`].
pub fn cluster_gap_ratio(n: usize) -> f64 {
    let edges = n.saturating_sub(1).max(1) as f64;
    (edges.ln() - CLUSTER_FALSE_ALARM.ln()) / std::f64::consts::LN_2
}

/// The session's natural clusters, when it has `MIN_REGIONS..=k` of them at `min_rows` rows
/// each: `None` otherwise.
///
/// 1. The spanning tree of the rows ([`spanning_tree`]) is cut at every edge longer than
///    [`cluster_gap_ratio`]`(n)` times its median positive edge: the components are the compact
///    clusters, whose rows are closer to one another than any structure-free session's rows
///    are apart.
/// 2. While a cluster has fewer than `min_rows` rows, the smallest (the one with the lowest
///    first row on a tie) is merged into its nearest neighbour (the cluster its shortest tree
///    edge leads to, single linkage).
/// 3. The clusters left are the regions when there are `MIN_REGIONS` to `k` of them. With one
///    or two (no structure, or too little to hold out three regions) or more than `k` the
///    caller cuts `k` regions by k-means instead.
///
/// No randomness: the same rows give the same clusters on any machine and thread count.
fn natural_clusters(
    features: &[Vec<f64>],
    x: &[Vec<f64>],
    min_rows: usize,
    k: usize,
) -> Option<Vec<usize>> {
    let n = x.len();
    let edges = spanning_tree(features, x);
    let mut positive: Vec<f64> = edges.iter().map(|e| e.0).filter(|&l| l > 0.0).collect();
    if positive.is_empty() {
        return None;
    }
    positive.sort_by(f64::total_cmp);
    let m = positive.len();
    let median = if m % 2 == 1 {
        positive[m / 2]
    } else {
        0.5 * (positive[m / 2 - 1] + positive[m / 2])
    };
    let tau = cluster_gap_ratio(n) * median;
    let mut parent: Vec<usize> = (0..n).collect();
    for &(length, a, b) in &edges {
        if length <= tau {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            parent[ra.max(rb)] = ra.min(rb);
        }
    }
    loop {
        let roots: Vec<usize> = (0..n).map(|i| find(&mut parent, i)).collect();
        let mut size = vec![0usize; n];
        for &r in &roots {
            size[r] += 1;
        }
        // Roots are each cluster's lowest row, so the lowest root is the lowest first row.
        let Some(small) = (0..n)
            .filter(|&r| size[r] > 0 && size[r] < min_rows)
            .min_by_key(|&r| (size[r], r))
        else {
            break;
        };
        let Some(&(_, a, b)) = edges
            .iter()
            .filter(|&&(_, a, b)| (roots[a] == small) != (roots[b] == small))
            .min_by(|p, q| p.0.total_cmp(&q.0))
        else {
            break;
        };
        let (ra, rb) = (roots[a], roots[b]);
        parent[ra.max(rb)] = ra.min(rb);
    }
    let roots: Vec<usize> = (0..n).map(|i| find(&mut parent, i)).collect();
    let mut order: Vec<usize> = Vec::new();
    let labels: Vec<usize> = roots
        .iter()
        .map(|r| match order.iter().position(|o| o == r) {
            Some(p) => p,
            None => {
                order.push(*r);
                order.len() - 1
            }
        })
        .collect();
    (MIN_REGIONS..=k).contains(&order.len()).then_some(labels)
}

/// Regions of `features` (rows × dimensions; `NaN` = missing, imputed by its column's mean, 0
/// for a column with no value) with at least `min_rows` rows each, at most `k = min(
/// region_count(rows, min_rows), max_regions)` of them. When the rows form 3 to `k` natural
/// clusters (see the module documentation: a cut of the spanning tree at
/// [`cluster_gap_ratio`] median edges, clusters short of `min_rows` merged into their nearest
/// neighbour) there are that many regions, Lloyd's iterations starting from the clusters'
/// centres; otherwise `k`, from `k` centres drawn by k-means++ from `stats::trial_rng(seed,
/// 0)`. Either way Lloyd's assignment keeps every region at `min_rows` rows or more
/// (minimum-size k-means with a greedy assignment: a short region takes the rows that cost
/// least to move). Deterministic for a seed, on any machine and thread count (the structure
/// has no randomness). `None` when `k < MIN_REGIONS` (too few rows) or k-means++ finds fewer
/// than [`MIN_REGIONS`] distinct postures.
///
/// Cost: the spanning tree takes `rows²/2` distances (20,000 rows: 2·10⁸), computed exactly
/// (a subsample's tree would see a coarser structure: its median edge is longer, so it misses
/// the small clusters whose gaps all rows show) as a dense loop over rows grouped by their
/// missing joints, on rayon's current pool, the same tree on any thread count (module
/// `spanning_tree`).
pub fn joint_regions(
    features: &[Vec<f64>],
    min_rows: usize,
    max_regions: usize,
    seed: u64,
) -> Option<Regions> {
    let n = features.len();
    let k = region_count(n, min_rows).min(max_regions);
    if k < MIN_REGIONS {
        return None;
    }
    let x = imputed(features);
    match natural_clusters(features, &x, min_rows, k) {
        // The natural clusters seed Lloyd's iterations: a compact cluster far from the others
        // keeps its rows (its centre is the nearest for all of them), the stragglers merged
        // into a neighbour go to the centre nearest to them, and rows of a long cluster can
        // go to a neighbour's centre (see the module documentation).
        Some(labels) => {
            let start = numbered(&x, &labels, seed).centres;
            let (labels, _) = lloyd_min_size(&x, start, min_rows);
            Some(numbered(&x, &labels, seed))
        }
        None => kmeans_regions(&x, k, min_rows, seed),
    }
}

/// `features` with every missing value (`NaN`) replaced by its column's mean (0 for a column
/// with no value): the rows k-means sees.
fn imputed(features: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let dims = features.first().map_or(0, Vec::len);
    let means: Vec<f64> = (0..dims)
        .map(|d| {
            let v: Vec<f64> = features
                .iter()
                .map(|f| f[d])
                .filter(|v| v.is_finite())
                .collect();
            if v.is_empty() {
                0.0
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        })
        .collect();
    features
        .iter()
        .map(|f| {
            f.iter()
                .zip(&means)
                .map(|(&v, &m)| if v.is_finite() { v } else { m })
                .collect()
        })
        .collect()
}

/// `k` regions of the imputed rows `x` without natural clusters: k-means++ centres drawn from
/// `stats::trial_rng(seed, 0)`, then [`lloyd_min_size`]. `None` when k-means++ finds fewer than
/// [`MIN_REGIONS`] distinct postures.
fn kmeans_regions(x: &[Vec<f64>], k: usize, min_rows: usize, seed: u64) -> Option<Regions> {
    let n = x.len();
    // k-means++: the first centre uniform, each next one with probability ∝ D².
    let mut rng = crate::stats::trial_rng(seed, 0);
    let mut centres = vec![x[rng.random_range(0..n)].clone()];
    while centres.len() < k {
        let d2: Vec<f64> = x
            .iter()
            .map(|p| dist2(p, &centres[nearest(p, &centres)]))
            .collect();
        let total: f64 = d2.iter().sum();
        if total <= 0.0 {
            break;
        }
        let mut u = rng.random::<f64>() * total;
        let pick = d2
            .iter()
            .position(|&d| {
                u -= d;
                u <= 0.0
            })
            .unwrap_or(n - 1);
        centres.push(x[pick].clone());
    }
    if centres.len() < MIN_REGIONS {
        return None;
    }
    let (labels, _) = lloyd_min_size(x, centres, min_rows);
    Some(numbered(x, &labels, seed))
}

/// The [`Regions`] of `labels` over the imputed features `x`: regions renumbered in order of
/// their first row, each centre the mean of its rows.
fn numbered(x: &[Vec<f64>], labels: &[usize], seed: u64) -> Regions {
    let mut order: Vec<usize> = Vec::new();
    for &l in labels {
        if !order.contains(&l) {
            order.push(l);
        }
    }
    let labels: Vec<usize> = labels
        .iter()
        .map(|l| order.iter().position(|o| o == l).unwrap_or(0))
        .collect();
    let dims = x.first().map_or(0, Vec::len);
    let mut centres = vec![vec![0.0; dims]; order.len()];
    let mut sizes = vec![0usize; order.len()];
    for (p, &l) in x.iter().zip(&labels) {
        sizes[l] += 1;
        for (c, v) in centres[l].iter_mut().zip(p) {
            *c += v;
        }
    }
    for (centre, &size) in centres.iter_mut().zip(&sizes) {
        for c in centre.iter_mut() {
            *c /= size.max(1) as f64;
        }
    }
    Regions {
        labels,
        sizes,
        centres,
        seed,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// Three well-separated blobs of 20 rows (one feature missing on every third row).
    fn blobs(seed: u64) -> (Vec<Vec<f64>>, Vec<usize>) {
        let mut rng = crate::stats::trial_rng(seed, 1);
        let centres = [[0.1, 0.1, 0.1], [0.9, 0.1, 0.5], [0.5, 0.9, 0.9]];
        let mut x = Vec::new();
        let mut truth = Vec::new();
        for i in 0..60 {
            let c = i % 3;
            let mut f: Vec<f64> = centres[c]
                .iter()
                .map(|v| v + 0.03 * (rng.random::<f64>() - 0.5))
                .collect();
            if i % 7 == 0 {
                f[2] = f64::NAN;
            }
            x.push(f);
            truth.push(c);
        }
        (x, truth)
    }

    #[test]
    fn separated_blobs_are_found_and_every_region_is_large_enough() {
        let (x, truth) = blobs(3);
        // 60 rows at ≥ 20 rows each: 3 regions, which must be the blobs.
        let r = joint_regions(&x, 20, MAX_REGIONS, 7).expect("regions");
        assert_eq!(r.sizes, vec![20, 20, 20]);
        for (a, b) in r.labels.iter().zip(&truth) {
            assert_eq!(
                a, b,
                "region labels follow the blobs (numbered by first row)"
            );
        }
        // At ≥ 10 rows, up to 6 regions, each with ≥ 10 rows, every blob split not merged.
        let r = joint_regions(&x, 10, MAX_REGIONS, 7).expect("regions");
        assert!(r.sizes.iter().all(|&s| s >= 10), "{:?}", r.sizes);
        assert!(r.sizes.len() >= MIN_REGIONS);
        for region in 0..r.sizes.len() {
            let blobs: std::collections::BTreeSet<usize> = r
                .labels
                .iter()
                .zip(&truth)
                .filter(|(l, _)| **l == region)
                .map(|(_, t)| *t)
                .collect();
            assert_eq!(blobs.len(), 1, "region {region} spans blobs {blobs:?}");
        }
    }

    #[test]
    fn same_seed_same_regions_and_too_few_rows_give_none() {
        let (x, _) = blobs(4);
        assert_eq!(
            joint_regions(&x, 8, MAX_REGIONS, 11),
            joint_regions(&x, 8, MAX_REGIONS, 11)
        );
        assert_eq!(joint_regions(&x[..20], 8, MAX_REGIONS, 11), None);
        assert_eq!(region_count(100, 12), 6);
        assert_eq!(region_count(40, 12), 3);
        assert_eq!(region_count(40, 0), 0);
        // Identical rows: one posture cannot be cut into regions.
        let same = vec![vec![0.5, 0.5]; 40];
        assert_eq!(joint_regions(&same, 8, MAX_REGIONS, 1), None);
    }

    /// `rows` joint vectors of `dims` joints drawn uniformly over their normalised spans: a
    /// session whose postures form no clusters.
    fn uniform(rows: usize, dims: usize, seed: u64) -> Vec<Vec<f64>> {
        let mut rng = crate::stats::trial_rng(seed, 2);
        (0..rows)
            .map(|_| (0..dims).map(|_| rng.random::<f64>()).collect())
            .collect()
    }

    /// A uniform session of 40 handclasps (two six-joint robots) gets the regions its size
    /// allows for each caller's minimum and cap (the do-no-harm check's 8 rows and 3 regions,
    /// `diagnose`'s 12 and 6, the prediction's 4 and 5, 8 and 5), every region at the minimum
    /// or above, on every seed (before the minimum-size assignment small clusters were dropped
    /// one after another and many seeds fell below three regions).
    #[test]
    fn a_uniform_forty_row_session_gets_the_regions_its_size_allows() {
        for (min, max) in [(8, 3), (12, MAX_REGIONS), (4, 5), (8, 5)] {
            let k = region_count(40, min).min(max);
            for seed in 0..30 {
                let x = uniform(40, 12, seed);
                let r = joint_regions(&x, min, max, REGION_SEED)
                    .unwrap_or_else(|| panic!("min {min} max {max} seed {seed}: no regions"));
                assert_eq!(
                    r.sizes.len(),
                    k,
                    "min {min} max {max} seed {seed}: {:?}",
                    r.sizes
                );
                assert!(r.sizes.iter().all(|&s| s >= min), "{:?}", r.sizes);
                assert_eq!(r.sizes.iter().sum::<usize>(), 40);
            }
        }
    }

    /// Four well-separated clusters of 20 rows (six joints, ±0.02 of the span about corners
    /// 0.5 apart, one joint missing on every fifth row) get exactly four regions, one per
    /// cluster, at the do-no-harm check's minimum (8 rows, at most 6 regions: a fixed count
    /// would cut them into 6) and `diagnose`'s (12 rows, at most 6), on every seed.
    #[test]
    fn four_separated_clusters_get_four_regions_one_per_cluster() {
        let corners = [
            [0.2, 0.2, 0.2, 0.5, 0.5, 0.5],
            [0.7, 0.2, 0.2, 0.5, 0.2, 0.5],
            [0.2, 0.7, 0.5, 0.2, 0.5, 0.7],
            [0.7, 0.7, 0.7, 0.7, 0.5, 0.2],
        ];
        for seed in 0..20 {
            let mut rng = crate::stats::trial_rng(seed, 3);
            let mut x = Vec::new();
            let mut truth = Vec::new();
            for i in 0..80 {
                let c = (i * 7 + i / 4) % 4;
                let mut f: Vec<f64> = corners[c]
                    .iter()
                    .map(|v| v + 0.04 * (rng.random::<f64>() - 0.5))
                    .collect();
                if i % 5 == 0 {
                    f[3] = f64::NAN;
                }
                x.push(f);
                truth.push(c);
            }
            for min in [8, 12] {
                assert_eq!(region_count(80, min).min(MAX_REGIONS), 6);
                let r = joint_regions(&x, min, MAX_REGIONS, REGION_SEED).expect("regions");
                assert_eq!(r.sizes, vec![20; 4], "seed {seed} min {min}");
                for region in 0..4 {
                    let clusters: std::collections::BTreeSet<usize> = r
                        .labels
                        .iter()
                        .zip(&truth)
                        .filter(|(l, _)| **l == region)
                        .map(|(_, t)| *t)
                        .collect();
                    assert_eq!(
                        clusters.len(),
                        1,
                        "seed {seed}: region {region} spans {clusters:?}"
                    );
                }
            }
        }
    }

    /// The gap ratio is the documented false-alarm bound: `(n − 1)·2^(−ρ)` is
    /// `CLUSTER_FALSE_ALARM`.
    #[test]
    fn the_gap_ratio_holds_the_false_alarm_rate() {
        for n in [12, 40, 72, 2000] {
            let rho = cluster_gap_ratio(n);
            let rate = (n - 1) as f64 * 2f64.powf(-rho);
            assert!((rate - CLUSTER_FALSE_ALARM).abs() < 1e-12, "n {n}: {rate}");
        }
        assert!(cluster_gap_ratio(40) > 15.0 && cluster_gap_ratio(40) < 15.5);
    }

    proptest::proptest! {
        /// For any session with at least `MIN_REGIONS` distinct postures and rows for
        /// `MIN_REGIONS` regions: exactly `min(region_count, max)` regions, each with at least
        /// the minimum rows, labels `0..k` numbered in order of first row, sizes matching the
        /// labels.
        #[test]
        fn every_region_has_the_minimum_and_none_is_lost(
            rows in 12usize..90, dims in 1usize..13, min in 2usize..13, max in 3usize..7,
            seed in 0u64..1000,
        ) {
            let x = uniform(rows, dims, seed);
            let k = region_count(rows, min).min(max);
            let r = joint_regions(&x, min, max, seed);
            if k < MIN_REGIONS {
                proptest::prop_assert!(r.is_none());
            } else {
                let r = r.expect("uniform rows are distinct");
                proptest::prop_assert_eq!(r.sizes.len(), k);
                proptest::prop_assert!(r.sizes.iter().all(|&s| s >= min), "{:?}", &r.sizes);
                let mut first = 0;
                for &l in &r.labels {
                    proptest::prop_assert!(l <= first);
                    if l == first {
                        first += 1;
                    }
                }
                for (c, &size) in r.sizes.iter().enumerate() {
                    proptest::prop_assert_eq!(r.labels.iter().filter(|&&l| l == c).count(), size);
                }
            }
        }
    }
}

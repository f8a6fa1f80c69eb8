//! Regions of joint space: the folds of region-held-out cross-validation (issue 20). A region
//! is a cluster of the session's joint vectors, so a fold that holds one out asks the model to
//! extrapolate to postures it did not see, not to interpolate between neighbours.
//!
//! 1. [`joint_features`]: each observation's joint vectors, every joint normalised by its limit
//!    span (a joint the row does not use is missing, `NaN`).
//! 2. [`region_count`]: how many regions a number of rows affords.
//! 3. [`joint_regions`]: seeded k-means++ (missing features imputed by their column mean), then
//!    regions smaller than the minimum merged into their nearest neighbours; regions numbered in
//!    order of their first row.
//!
//! No crate does this under the workspace's MSRV with nalgebra vectors and a seeded
//! `ChaCha8Rng` in forty lines, so it is written here.

use rand::Rng;

use crate::whole_cell::CellProblem;
use crate::Robot;

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

/// Lloyd's iterations from `centres`: labels and the updated centres (a centre that loses every
/// row keeps its place).
fn lloyd(x: &[Vec<f64>], mut centres: Vec<Vec<f64>>) -> (Vec<usize>, Vec<Vec<f64>>) {
    let mut labels: Vec<usize> = x.iter().map(|p| nearest(p, &centres)).collect();
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
        let next: Vec<usize> = x.iter().map(|p| nearest(p, &centres)).collect();
        if next == labels {
            break;
        }
        labels = next;
    }
    (labels, centres)
}

/// Seeded k-means++ regions of `features` (rows × dimensions; `NaN` = missing, imputed by its
/// column's mean, 0 for a column with no value): `k = min(region_count(rows, min_rows),
/// max_regions)` centres
/// drawn by k-means++ from `stats::trial_rng(seed, 0)`, Lloyd's iterations, then while a region
/// holds fewer than `min_rows` rows its centre is dropped and the rows reassigned (Lloyd again),
/// so every region has at least `min_rows` rows. `None` when fewer than [`MIN_REGIONS`] regions
/// remain (too few rows, or too few distinct postures).
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
    let x: Vec<Vec<f64>> = features
        .iter()
        .map(|f| {
            f.iter()
                .zip(&means)
                .map(|(&v, &m)| if v.is_finite() { v } else { m })
                .collect()
        })
        .collect();
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
    let (mut labels, mut centres) = lloyd(&x, centres);
    loop {
        let sizes: Vec<usize> = (0..centres.len())
            .map(|c| labels.iter().filter(|&&l| l == c).count())
            .collect();
        let Some(small) = (0..centres.len()).find(|&c| sizes[c] < min_rows) else {
            break;
        };
        // The smallest such region goes (the first on a tie).
        let small = (0..centres.len())
            .filter(|&c| sizes[c] < min_rows)
            .min_by_key(|&c| sizes[c])
            .unwrap_or(small);
        centres.remove(small);
        (labels, centres) = lloyd(&x, centres);
    }
    if centres.len() < MIN_REGIONS {
        return None;
    }
    // Number the regions in order of their first row.
    let mut order: Vec<usize> = Vec::new();
    for &l in &labels {
        if !order.contains(&l) {
            order.push(l);
        }
    }
    let labels: Vec<usize> = labels
        .iter()
        .map(|l| order.iter().position(|o| o == l).unwrap_or(0))
        .collect();
    let centres: Vec<Vec<f64>> = order.iter().map(|&o| centres[o].clone()).collect();
    let sizes = (0..centres.len())
        .map(|c| labels.iter().filter(|&&l| l == c).count())
        .collect();
    Some(Regions {
        labels,
        sizes,
        centres,
        seed,
    })
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
}

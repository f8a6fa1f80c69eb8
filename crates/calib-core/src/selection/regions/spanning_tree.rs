//! The exact minimum spanning tree of [`super::joint_regions`]' feature rows, fast at 20,000 rows
//! (issue 25): Prim's algorithm as before (`n − 1` passes, each updating every row outside the
//! tree from the row that joined last), with the same distances, the same arithmetic in the same
//! order and the same tie-breaks, so the tree is bit-identical to the plain loop's. What changes is
//! the memory layout and the threads:
//!
//! 1. **Groups** ([`Groups::new`]): rows with the same missing joints (a tracker row of robot 1,
//!    a handclasp row, …: a session has a handful) form a group, stored column by column
//!    (`cols[d·cap + p]`), so that the distance of a row to every row of a group is a plain dense
//!    loop over the joints the two groups have in common ([`Metric`], one per pair of groups),
//!    vectorised across rows; each row's sum still runs over the joints in their order.
//! 2. **Outside rows only**: a group keeps the rows outside the tree first (a row that joins is
//!    swapped with the group's last outside row), so a pass reads only those.
//! 3. **Threads**: a group's update is cut into blocks of [`BLOCK_ROWS`] rows, run on rayon's
//!    current pool when the group has more than [`PARALLEL_ROWS`] outside rows; each block
//!    returns its nearest row and the blocks' minimum is taken by `(distance, row index)`: a
//!    total order, so the tree is the same on any thread count.

use rayon::prelude::*;

/// Rows per block of a pass (the block's sums live on the stack: 8 KB).
const BLOCK_ROWS: usize = 1024;
/// Outside rows of a group above which a pass runs its blocks on rayon's pool (below, one
/// block's work is a few µs, about rayon's cost of scheduling it).
const PARALLEL_ROWS: usize = 4 * BLOCK_ROWS;

/// The distance between the rows of two groups (of `partial_dist2`): over their common
/// joints, scaled by `features / common`; with none in common, over every imputed feature,
/// unscaled.
#[derive(Debug, Clone)]
enum Metric {
    /// The joints both groups have, in order, and the scale `(sum · features) / common`.
    Common {
        dims: Vec<usize>,
        features: f64,
        common: f64,
    },
    /// No joint in common: the squared distance of the imputed rows, every feature.
    Imputed { dims: Vec<usize> },
}

impl Metric {
    fn dims(&self) -> &[usize] {
        match self {
            Metric::Common { dims, .. } | Metric::Imputed { dims } => dims,
        }
    }

    /// The distance from a row's sum of squared differences over [`Metric::dims`].
    fn finish(&self, sum: f64) -> f64 {
        match self {
            Metric::Common {
                features, common, ..
            } => sum * features / common,
            Metric::Imputed { .. } => sum,
        }
    }
}

/// One group's rows: those outside the tree first (`outside` of them), column-major.
#[derive(Debug)]
struct Group {
    /// Each row's index in the caller's rows.
    rows: Vec<usize>,
    /// The imputed features, `cols[d · rows.len() + p]` for row `p` of the group.
    cols: Vec<f64>,
    /// Each outside row's squared distance to its nearest tree row, and that row.
    best: Vec<(f64, usize)>,
    /// Rows outside the tree: positions `0..outside`.
    outside: usize,
}

impl Group {
    /// Moves the row at `p` into the tree (swapped with the last outside row).
    fn join(&mut self, p: usize, dims: usize) {
        let last = self.outside - 1;
        let cap = self.rows.len();
        self.rows.swap(p, last);
        self.best.swap(p, last);
        for d in 0..dims {
            self.cols.swap(d * cap + p, d * cap + last);
        }
        self.outside = last;
    }
}

/// The rows grouped by their missing features, and the metric of every pair of groups.
#[derive(Debug)]
struct Groups {
    groups: Vec<Group>,
    /// `metrics[g][h]`: rows of group `g` against a row of group `h`.
    metrics: Vec<Vec<Metric>>,
    /// Each row's group.
    group_of: Vec<usize>,
    /// Each row's position in its group (it moves as rows join the tree).
    pos: Vec<usize>,
    dims: usize,
}

impl Groups {
    /// Groups of `features` (missing = not finite) over the imputed rows `x`, numbered in order of
    /// their first row.
    fn new(features: &[Vec<f64>], x: &[Vec<f64>]) -> Groups {
        let dims = x.first().map_or(0, Vec::len);
        let mut masks: Vec<Vec<bool>> = Vec::new();
        let mut members: Vec<Vec<usize>> = Vec::new();
        let mut group_of = Vec::with_capacity(x.len());
        let mut pos = Vec::with_capacity(x.len());
        for (i, f) in features.iter().enumerate() {
            let mask: Vec<bool> = f.iter().map(|v| v.is_finite()).collect();
            let g = match masks.iter().position(|m| *m == mask) {
                Some(g) => g,
                None => {
                    masks.push(mask);
                    members.push(Vec::new());
                    masks.len() - 1
                }
            };
            group_of.push(g);
            pos.push(members[g].len());
            members[g].push(i);
        }
        let groups = members
            .into_iter()
            .map(|rows| {
                let cap = rows.len();
                let mut cols = vec![0.0; dims * cap];
                for (p, &i) in rows.iter().enumerate() {
                    for (d, &v) in x[i].iter().enumerate() {
                        cols[d * cap + p] = v;
                    }
                }
                Group {
                    best: vec![(f64::INFINITY, 0); cap],
                    outside: cap,
                    rows,
                    cols,
                }
            })
            .collect();
        let metrics = masks
            .iter()
            .map(|a| {
                masks
                    .iter()
                    .map(|b| {
                        let common: Vec<usize> = (0..dims.min(a.len()).min(b.len()))
                            .filter(|&d| a[d] && b[d])
                            .collect();
                        if common.is_empty() {
                            Metric::Imputed {
                                dims: (0..dims).collect(),
                            }
                        } else {
                            Metric::Common {
                                features: a.len() as f64,
                                common: common.len() as f64,
                                dims: common,
                            }
                        }
                    })
                    .collect()
            })
            .collect();
        Groups {
            groups,
            metrics,
            group_of,
            pos,
            dims,
        }
    }

    /// Moves row `i` into the tree.
    fn join(&mut self, i: usize) {
        let grp = &mut self.groups[self.group_of[i]];
        let p = self.pos[i];
        let moved = grp.rows[grp.outside - 1];
        grp.join(p, self.dims);
        self.pos[moved] = p;
        self.pos[i] = grp.outside;
    }
}

/// The nearer of two candidates `(squared distance, row index, group, position)`: the shorter,
/// the lower row index on a tie (a total order on the distances a pass produces, which are never
/// NaN: a NaN distance never replaces a best).
fn nearer(
    a: Option<(f64, usize, usize, usize)>,
    b: Option<(f64, usize, usize, usize)>,
) -> Option<(f64, usize, usize, usize)> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.0 < a.0 || (b.0 == a.0 && b.1 < a.1) {
            b
        } else {
            a
        }),
        (a, None) => a,
        (None, b) => b,
    }
}

/// One block of a pass: the rows `start..start + best.len()` of a group (columns `cols`, `cap`
/// rows per column) get their distance to the row `q` (imputed features, index `from`) by
/// `metric`, keep it when shorter than their best; the block's nearest row.
#[allow(clippy::too_many_arguments)]
fn update_block(
    cols: &[f64],
    cap: usize,
    rows: &[usize],
    start: usize,
    best: &mut [(f64, usize)],
    q: &[f64],
    from: usize,
    metric: &Metric,
    group: usize,
) -> Option<(f64, usize, usize, usize)> {
    let m = best.len();
    let mut sums = [0.0f64; BLOCK_ROWS];
    let sums = &mut sums[..m];
    for &d in metric.dims() {
        let qd = q[d];
        let col = &cols[d * cap + start..d * cap + start + m];
        for (s, &v) in sums.iter_mut().zip(col) {
            let t = v - qd;
            *s += t * t;
        }
    }
    let mut nearest: Option<(f64, usize, usize, usize)> = None;
    for (p, (b, &s)) in best.iter_mut().zip(sums.iter()).enumerate() {
        let dist = metric.finish(s);
        if dist < b.0 {
            *b = (dist, from);
        }
        nearest = nearer(nearest, Some((b.0, rows[start + p], group, start + p)));
    }
    nearest
}

/// The minimum spanning tree of the feature rows (`features` with their missing values, `x`
/// imputed; distances `partial_dist2`), by Prim's algorithm from row 0 (the lowest row
/// on a tie, and a row keeps its first nearest tree row on a tie): its `n − 1` edges `(length,
/// a, b)`, `a` in the tree when `b` joined. O(n²) distances, no randomness, the same on any
/// thread count (see the module documentation).
pub(super) fn spanning_tree(features: &[Vec<f64>], x: &[Vec<f64>]) -> Vec<(f64, usize, usize)> {
    let n = x.len();
    let mut edges = Vec::with_capacity(n.saturating_sub(1));
    if n == 0 {
        return edges;
    }
    let mut g = Groups::new(features, x);
    g.join(0);
    let mut last = 0;
    for _ in 1..n {
        let last_group = g.group_of[last];
        let q = &x[last];
        let mut next: Option<(f64, usize, usize, usize)> = None;
        for (h, grp) in g.groups.iter_mut().enumerate() {
            let outside = grp.outside;
            if outside == 0 {
                continue;
            }
            let metric = &g.metrics[h][last_group];
            let cap = grp.rows.len();
            let (cols, rows) = (&grp.cols, &grp.rows);
            let best = &mut grp.best[..outside];
            let found = if outside > PARALLEL_ROWS {
                best.par_chunks_mut(BLOCK_ROWS)
                    .enumerate()
                    .map(|(b, block)| {
                        update_block(cols, cap, rows, b * BLOCK_ROWS, block, q, last, metric, h)
                    })
                    .reduce(|| None, nearer)
            } else {
                best.chunks_mut(BLOCK_ROWS)
                    .enumerate()
                    .map(|(b, block)| {
                        update_block(cols, cap, rows, b * BLOCK_ROWS, block, q, last, metric, h)
                    })
                    .fold(None, nearer)
            };
            next = nearer(next, found);
        }
        let Some((_, j, h, p)) = next else { break };
        let (d2, a) = g.groups[h].best[p];
        edges.push((d2.sqrt(), a, j));
        g.join(j);
        last = j;
    }
    edges
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// The squared distance of two feature rows over the joints both use, scaled by the number
    /// of features over the number used (the usual distance with missing values: a tracker row
    /// of robot 1 is as near a two-robot row as their robot 1 joints are); with no joint in
    /// common, the distance of the imputed rows `xa`, `xb` (the one k-means sees). The
    /// definition [`spanning_tree`] computes (stop 33's code, kept as the reference).
    fn partial_dist2(a: &[f64], b: &[f64], xa: &[f64], xb: &[f64]) -> f64 {
        let (mut sum, mut used) = (0.0, 0usize);
        for (u, v) in a.iter().zip(b) {
            if u.is_finite() && v.is_finite() {
                sum += (u - v).powi(2);
                used += 1;
            }
        }
        if used == 0 {
            xa.iter().zip(xb).map(|(x, y)| (x - y).powi(2)).sum()
        } else {
            sum * a.len() as f64 / used as f64
        }
    }

    /// Stop 33's spanning tree (the plain O(n²) loop of Prim's algorithm over [`partial_dist2`]),
    /// kept as the reference the fast tree must reproduce bit for bit.
    fn reference_tree(features: &[Vec<f64>], x: &[Vec<f64>]) -> Vec<(f64, usize, usize)> {
        let n = x.len();
        let mut edges = Vec::with_capacity(n.saturating_sub(1));
        if n == 0 {
            return edges;
        }
        let mut in_tree = vec![false; n];
        let mut best = vec![(f64::INFINITY, 0usize); n];
        let mut last = 0;
        in_tree[0] = true;
        for _ in 1..n {
            let mut next: Option<usize> = None;
            for i in 0..n {
                if in_tree[i] {
                    continue;
                }
                let d = partial_dist2(&features[i], &features[last], &x[i], &x[last]);
                if d < best[i].0 {
                    best[i] = (d, last);
                }
                if next.is_none_or(|j| best[i].0 < best[j].0) {
                    next = Some(i);
                }
            }
            let Some(j) = next else { break };
            in_tree[j] = true;
            edges.push((best[j].0.sqrt(), best[j].1, j));
            last = j;
        }
        edges
    }

    /// A session of `rows` rows over two six-joint robots: two-robot rows (kinds 0 and 3), robot
    /// 1's (kind 1) and robot 2's (kind 2) one-robot rows, the kind uniform in `0..kinds` (the other robot's joints missing: one-robot rows of different robots
    /// share no joint, so their distance is the imputed one), joints on a grid of `levels`
    /// values per span when `levels > 0` (many equal distances: the tie-breaks decide), else
    /// uniform; the imputed rows as `joint_regions` builds them.
    fn session(rows: usize, levels: u32, kinds: u32, seed: u64) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
        let mut rng = crate::stats::trial_rng(seed, 4);
        let features: Vec<Vec<f64>> = (0..rows)
            .map(|_| {
                let kind = rng.random_range(0..kinds);
                (0..12)
                    .map(|d| {
                        let v = if levels > 0 {
                            f64::from(rng.random_range(0..levels)) / f64::from(levels)
                        } else {
                            rng.random::<f64>()
                        };
                        match kind {
                            1 if d >= 6 => f64::NAN,
                            2 if d < 6 => f64::NAN,
                            _ => v,
                        }
                    })
                    .collect()
            })
            .collect();
        let x = super::super::imputed(&features);
        (features, x)
    }

    /// The first edge where two trees differ (length to the bit, either end), if any.
    fn first_difference(
        fast: &[(f64, usize, usize)],
        slow: &[(f64, usize, usize)],
    ) -> Option<String> {
        if fast.len() != slow.len() {
            return Some(format!("{} edges vs {}", fast.len(), slow.len()));
        }
        fast.iter()
            .zip(slow)
            .position(|(a, b)| a.0.to_bits() != b.0.to_bits() || a.1 != b.1 || a.2 != b.2)
            .map(|k| format!("edge {k}: {:?} vs {:?}", fast[k], slow[k]))
    }

    /// The same tree, bit for bit, as stop 33's loop: on sessions with missing joints (three
    /// groups, every pair metric), with many equal distances (a coarse grid, duplicated rows),
    /// and a single row; and on a session large enough for the threaded
    /// pass (more than `PARALLEL_ROWS` rows in a group) in 1-, 2- and 3-thread pools.
    #[test]
    fn the_tree_is_stop_33s_bit_for_bit_on_any_thread_count() {
        let check = |f: &[Vec<f64>], x: &[Vec<f64>], what: &str| {
            let diff = first_difference(&spanning_tree(f, x), &reference_tree(f, x));
            assert!(diff.is_none(), "{what}: {diff:?}");
        };
        for seed in 0..6 {
            for levels in [0, 2, 3] {
                let (f, x) = session(300, levels, 4, seed);
                check(&f, &x, &format!("seed {seed} levels {levels}"));
            }
        }
        let (f, x) = session(1, 0, 4, 1);
        check(&f, &x, "one row");
        let (mut f, _) = session(40, 0, 4, 2);
        f.extend(f.clone());
        let x = super::super::imputed(&f);
        check(&f, &x, "every row twice");
        // Two-robot rows only: one group of more than PARALLEL_ROWS rows, threaded passes.
        let (f, x) = session(PARALLEL_ROWS + 3 * BLOCK_ROWS / 2, 4, 1, 7);
        let slow = reference_tree(&f, &x);
        for threads in [1, 2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let diff = first_difference(&pool.install(|| spanning_tree(&f, &x)), &slow);
            assert!(diff.is_none(), "{threads} threads: {diff:?}");
        }
    }
}

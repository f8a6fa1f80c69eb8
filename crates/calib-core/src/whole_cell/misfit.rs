//! Blunders or misfit: one rule for the rows a blunder screen would reject. A blunder is a
//! row that disagrees with every reasonable model; a misfit is many rows, or rows clustered in
//! joint space or in time. [`classify_rejections`] says which.
//!
//! 1. share: more than [`MISFIT_SHARE_ALONE`] of the rows rejected, or more than
//!    [`MISFIT_SHARE`] (and at least [`MISFIT_MIN_ROWS`]) while the rows are, robustly, far
//!    noisier than stated (`rest_noise_scale` above `noisy_above`: the rows the screen keeps
//!    disagree with the model too; isolated blunders leave the rest at the stated noise);
//! 2. time: at least [`CLUSTER_MIN_ROWS`] rejected rows within [`TIME_WINDOW`] of the session's
//!    rows in recording order;
//! 3. joint space: at least [`CLUSTER_MIN_ROWS`] rejected rows, all in the lowest or all in the
//!    highest [`JOINT_TAIL`] of one joint's values (chance: `2·joints·0.2⁴` ≈ 4 % for 13
//!    joints);
//! 4. the largest systematic pattern: the joint whose value correlates most with the rows'
//!    whitened residual size (Pearson, over every row).

use serde::Serialize;

use super::solve::{assemble, CellFit};
use super::{CellFitError, CellProblem};
use crate::Robot;

/// More than this share of the rows rejected, the rest noisier than stated, is a misfit (5 %).
pub const MISFIT_SHARE: f64 = 0.05;
/// More than this share of the rows rejected is a misfit whatever the rest (20 %).
pub const MISFIT_SHARE_ALONE: f64 = 0.2;
/// ... and at least this many rows.
pub const MISFIT_MIN_ROWS: usize = 3;
/// Clusters need at least this many rejected rows.
pub const CLUSTER_MIN_ROWS: usize = 4;
/// A time cluster: the rejected rows within this share of the session's rows (25 %).
pub const TIME_WINDOW: f64 = 0.25;
/// A joint-space cluster: the rejected rows all within this tail of one joint's values (20 %).
pub const JOINT_TAIL: f64 = 0.2;

/// Where rejected rows cluster in joint space.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointCluster {
    /// The robot (1 or 2).
    pub robot: u8,
    /// The joint, 1-based.
    pub joint: usize,
    /// `"low"` or `"high"`: which tail of the joint's values.
    pub tail: &'static str,
    /// The rejected rows' range of that joint, degrees.
    pub range_deg: [f64; 2],
}

/// The joint whose value correlates most with the residual size.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualPattern {
    /// The robot (1 or 2).
    pub robot: u8,
    /// The joint, 1-based.
    pub joint: usize,
    /// Pearson correlation of the joint's value with the rows' whitened residual size.
    pub correlation: f64,
}

/// The rows a screen would reject, classified.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RejectionPattern {
    /// True when the rejections are a model misfit (share or cluster), not blunders.
    pub misfit: bool,
    /// Rows the screen would reject.
    pub rejected_rows: usize,
    /// The session's rows.
    pub rows: usize,
    /// `rejected_rows / rows`.
    pub share: f64,
    /// The first and last source row of a time cluster (`None`: none).
    pub time_cluster: Option<[usize; 2]>,
    /// A joint-space cluster (`None`: none).
    pub joint_cluster: Option<JointCluster>,
    /// The largest systematic pattern (`None` without joints to correlate).
    pub pattern: Option<ResidualPattern>,
}

impl RejectionPattern {
    /// One line: the share, where the rows cluster, the largest pattern.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "{} of {} rows ({:.0} %) would be rejected as blunders",
            self.rejected_rows,
            self.rows,
            100.0 * self.share
        );
        if let Some([a, b]) = self.time_cluster {
            s.push_str(&format!("; they cluster in time (rows {a}–{b})"));
        }
        if let Some(c) = &self.joint_cluster {
            s.push_str(&format!(
                "; they cluster in joint space (robot {} joint {} {}: {:.1}..{:.1}°)",
                c.robot, c.joint, c.tail, c.range_deg[0], c.range_deg[1]
            ));
        }
        if let Some(p) = &self.pattern {
            s.push_str(&format!(
                "; the residuals follow robot {} joint {} most (correlation {:+.2})",
                p.robot, p.joint, p.correlation
            ));
        }
        s
    }
}

/// Classifies the observations `rejected` (indices into `problem.observations`) of a screen
/// at `fit` (whose residuals give the pattern), the rows' robust noise scale being
/// `rest_noise_scale` (`noisy_above`: the scale above which the rows are noisier than
/// stated): see the module documentation.
///
/// # Errors
/// The residuals cannot be evaluated.
pub fn classify_rejections(
    problem: &CellProblem,
    fit: &CellFit,
    rejected: &[usize],
    rest_noise_scale: f64,
    noisy_above: f64,
) -> Result<RejectionPattern, CellFitError> {
    let n = problem.observations.len();
    let k = rejected.len();
    let share = if n == 0 { 0.0 } else { k as f64 / n as f64 };
    let by_share = share > MISFIT_SHARE_ALONE
        || (k >= MISFIT_MIN_ROWS && share > MISFIT_SHARE && rest_noise_scale > noisy_above);
    let mut sorted = rejected.to_vec();
    sorted.sort_unstable();
    let time_cluster = (k >= CLUSTER_MIN_ROWS)
        .then(|| {
            let window = ((TIME_WINDOW * n as f64).floor() as usize).max(k);
            let span = sorted[k - 1] - sorted[0] + 1;
            (span <= window && span < n).then(|| {
                [
                    problem.observations[sorted[0]].row,
                    problem.observations[sorted[k - 1]].row,
                ]
            })
        })
        .flatten();
    let joint_cluster = if k >= CLUSTER_MIN_ROWS && k < n {
        joint_cluster(problem, &sorted)
    } else {
        None
    };
    let all: Vec<usize> = (0..n).collect();
    let sys = assemble(problem, &fit.layout, &fit.estimate, &all, None, false)?;
    let sizes: Vec<f64> = all
        .iter()
        .enumerate()
        .map(|(b, &i)| {
            let dim = problem.observations[i].kind.rows();
            sys.r.rows(sys.block_start[b], dim).norm() / (dim as f64).sqrt()
        })
        .collect();
    Ok(RejectionPattern {
        misfit: by_share || time_cluster.is_some() || joint_cluster.is_some(),
        rejected_rows: k,
        rows: n,
        share,
        time_cluster,
        joint_cluster,
        pattern: pattern(problem, &sizes),
    })
}

/// One joint's values over the observations that carry it: `(robot, joint, [(obs, value)])`.
type JointValues = (Robot, usize, Vec<(usize, f64)>);

/// Each joint's [`JointValues`].
fn joint_values(problem: &CellProblem) -> Vec<JointValues> {
    let mut out = Vec::new();
    for robot in Robot::BOTH {
        for j in 0..problem.robot(robot).model.dof() {
            let mut v = Vec::new();
            for (i, o) in problem.observations.iter().enumerate() {
                for (r, q) in o.kind.joints() {
                    if r == robot {
                        if let Some(x) = q.get(j) {
                            v.push((i, *x));
                        }
                    }
                }
            }
            out.push((robot, j, v));
        }
    }
    out
}

fn joint_cluster(problem: &CellProblem, rejected: &[usize]) -> Option<JointCluster> {
    for (robot, j, values) in joint_values(problem) {
        let mut all: Vec<f64> = values.iter().map(|v| v.1).collect();
        if all.len() < 2 * CLUSTER_MIN_ROWS {
            continue;
        }
        all.sort_by(f64::total_cmp);
        let tail = ((JOINT_TAIL * all.len() as f64).floor() as usize).max(1);
        let (lo, hi) = (all[tail - 1], all[all.len() - tail]);
        if lo >= hi {
            continue;
        }
        let mine: Vec<f64> = values
            .iter()
            .filter(|(i, _)| rejected.binary_search(i).is_ok())
            .map(|v| v.1)
            .collect();
        if mine.len() < CLUSTER_MIN_ROWS {
            continue;
        }
        let min = mine.iter().copied().fold(f64::INFINITY, f64::min);
        let max = mine.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let side = if max <= lo {
            Some("low")
        } else if min >= hi {
            Some("high")
        } else {
            None
        };
        if let Some(tail) = side {
            return Some(JointCluster {
                robot: robot.number(),
                joint: j + 1,
                tail,
                range_deg: [min.to_degrees(), max.to_degrees()],
            });
        }
    }
    None
}

fn pattern(problem: &CellProblem, sizes: &[f64]) -> Option<ResidualPattern> {
    let mut best: Option<ResidualPattern> = None;
    for (robot, j, values) in joint_values(problem) {
        if values.len() < 3 {
            continue;
        }
        let xs: Vec<f64> = values.iter().map(|v| v.1).collect();
        let ys: Vec<f64> = values.iter().map(|v| sizes[v.0]).collect();
        let Some(r) = pearson(&xs, &ys) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| r.abs() > b.correlation.abs()) {
            best = Some(ResidualPattern {
                robot: robot.number(),
                joint: j + 1,
                correlation: r,
            });
        }
    }
    best
}

fn pearson(x: &[f64], y: &[f64]) -> Option<f64> {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    let d = (sxx * syy).sqrt();
    (d > 0.0 && d.is_finite()).then(|| sxy / d)
}

#[cfg(test)]
mod tests {
    use super::pearson;

    /// A line correlates ±1; a constant has no correlation.
    #[test]
    fn pearson_of_lines_and_constants() {
        let x = [1.0, 2.0, 3.0, 4.0];
        assert!((pearson(&x, &[2.0, 4.0, 6.0, 8.0]).unwrap() - 1.0).abs() < 1e-12);
        assert!((pearson(&x, &[8.0, 6.0, 4.0, 2.0]).unwrap() + 1.0).abs() < 1e-12);
        assert!(pearson(&x, &[1.0; 4]).is_none());
    }
}

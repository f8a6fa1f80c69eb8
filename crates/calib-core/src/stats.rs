//! The workspace's one home of statistics: tail probabilities and quantiles of the usual
//! distributions (through `statrs`), sample quantiles with distribution-free confidence intervals,
//! correlation, a tested 1-D maximiser of a log-likelihood with its profile interval, and the
//! seeded generator of one Monte Carlo trial ([`trial_rng`]).
//!
//! Conventions: `dof` is an integer count of degrees of freedom; a distribution with `dof = 0` is
//! undefined and every function says what it returns then (NaN for quantiles and χ² tails, 1 for
//! the p-values of tests, so that an undefined test never rejects). Sample data passed as `sorted`
//! must be ascending and finite ([`sorted_finite`] makes such a vector).

use statrs::distribution::{ChiSquared, ContinuousCDF, FisherSnedecor, Normal, StudentsT};

/// The generator of Monte Carlo trial `index` under master `seed`: ChaCha8 seeded with `seed`,
/// stream `index`. Any trial can be replayed alone, and results never depend on thread count.
pub fn trial_rng(seed: u64, index: u64) -> rand_chacha::ChaCha8Rng {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(index);
    rng
}

/// z of a two-sided 95 % normal interval, `Φ⁻¹(0.975)`.
pub const Z95: f64 = 1.959_963_984_540_054;

/// `χ²₁(0.95)`: the 95 % quantile of χ² with one degree of freedom (a 95 % profile-likelihood
/// interval is where the log-likelihood is within half of it of its maximum).
pub const CHI2_1_95: f64 = 3.841_458_820_694_124;

/// Upper tail probability `P(χ²(dof) > x)`: the p-value of a χ² statistic `x`. NaN for `dof = 0`
/// or NaN `x`; 1 for `x ≤ 0`, 0 for `x = +∞`.
pub fn chi2_sf(x: f64, dof: usize) -> f64 {
    if dof == 0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    ChiSquared::new(dof as f64)
        .map(|d| d.sf(x))
        .unwrap_or(f64::NAN)
}

/// Upper tail probability `P(χ²(dof) > x)` for a real `dof > 0` (a scaled-χ² approximation's
/// fractional degrees of freedom). NaN for `dof ≤ 0` or NaN `x`; 1 for `x ≤ 0`.
pub fn chi2_sf_real(x: f64, dof: f64) -> f64 {
    if dof.is_nan() || dof <= 0.0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    ChiSquared::new(dof).map(|d| d.sf(x)).unwrap_or(f64::NAN)
}

/// Quantile `p ∈ (0, 1)` of χ² with a real `dof > 0`. NaN outside those ranges.
pub fn chi2_quantile_real(p: f64, dof: f64) -> f64 {
    if !(dof > 0.0 && p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    ChiSquared::new(dof)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

/// Quantile `p ∈ (0, 1)` of Student's t with `dof` degrees of freedom. NaN for `dof = 0`.
pub fn t_quantile(p: f64, dof: usize) -> f64 {
    if dof == 0 {
        return f64::NAN;
    }
    StudentsT::new(0.0, 1.0, dof as f64)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

/// Two-sided p-value `P(|T| > |t|)` of a Student-t statistic with `dof` degrees of freedom
/// (1 for `dof = 0` or NaN `t`: an undefined test never rejects).
pub fn t_two_sided_p(t: f64, dof: usize) -> f64 {
    if dof == 0 || t.is_nan() {
        return 1.0;
    }
    StudentsT::new(0.0, 1.0, dof as f64)
        .map(|d| (2.0 * d.sf(t.abs())).min(1.0))
        .unwrap_or(1.0)
}

/// Upper tail probability `P(F(d1, d2) > f)`: the p-value of an F statistic (1 for `d1 = 0`,
/// `d2 = 0`, NaN `f` or `f ≤ 0`: an undefined test never rejects).
pub fn f_sf(f: f64, d1: usize, d2: usize) -> f64 {
    if d1 == 0 || d2 == 0 || f.is_nan() || f <= 0.0 {
        return 1.0;
    }
    FisherSnedecor::new(d1 as f64, d2 as f64)
        .map(|d| d.sf(f))
        .unwrap_or(1.0)
}

/// p-value of a one-parameter F test, `P(F(1, dof) > f)` (see [`f_sf`]).
pub fn f_test_p_value(f: f64, dof: usize) -> f64 {
    f_sf(f, 1, dof)
}

/// The standard normal distribution function `Φ(x)`.
pub fn normal_cdf(x: f64) -> f64 {
    Normal::new(0.0, 1.0).map(|d| d.cdf(x)).unwrap_or(f64::NAN)
}

/// Quantile `p ∈ (0, 1)` of the standard normal distribution, `Φ⁻¹(p)`.
pub fn normal_quantile(p: f64) -> f64 {
    Normal::new(0.0, 1.0)
        .map(|d| d.inverse_cdf(p))
        .unwrap_or(f64::NAN)
}

/// A quantile estimate with its 95 % confidence interval (same unit as the data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantileCi {
    /// The sample quantile (linear interpolation between order statistics).
    pub value: f64,
    /// Lower end of the 95 % interval.
    pub lower: f64,
    /// Upper end of the 95 % interval.
    pub upper: f64,
}

/// Sample quantile `q ∈ [0, 1]` of ascending `sorted` data, linear interpolation between order
/// statistics (numpy's default, so that figures compare with the numpy baselines). NaN for empty
/// data.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let lo = h.floor() as usize;
    let hi = h.ceil() as usize;
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

/// Quantile `q` of ascending `sorted` data with a distribution-free 95 % confidence interval:
/// the order statistics at ranks `n·q ∓ z·√(n·q·(1−q))` (normal approximation to the binomial
/// count of samples below the true quantile), clamped to the data. NaN for empty data.
pub fn quantile_ci(sorted: &[f64], q: f64) -> QuantileCi {
    let n = sorted.len();
    if n == 0 {
        return QuantileCi {
            value: f64::NAN,
            lower: f64::NAN,
            upper: f64::NAN,
        };
    }
    let nf = n as f64;
    let half = Z95 * (nf * q * (1.0 - q)).sqrt();
    let lo_rank = (nf * q - half).floor().max(1.0) as usize; // 1-based
    let hi_rank = (nf * q + half).ceil().min(nf) as usize;
    QuantileCi {
        value: quantile(sorted, q),
        lower: sorted[lo_rank.max(1) - 1],
        upper: sorted[hi_rank.max(1) - 1],
    }
}

/// The finite values, ascending (NaN and infinities dropped).
pub fn sorted_finite(values: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v
}

/// Fraction of ascending `sorted` data strictly below `v` (the empirical CDF just left of `v`);
/// 0 for empty data.
pub fn fraction_below(sorted: &[f64], v: f64) -> f64 {
    sorted.partition_point(|&s| s < v) as f64 / sorted.len().max(1) as f64
}

/// Pearson's correlation coefficient of two equally long samples; 0 when either has no spread
/// (variance sum below 1e-300) or fewer than two values.
pub fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    if n < 2 {
        return 0.0;
    }
    let nf = n as f64;
    let (ma, mb) = (
        a[..n].iter().sum::<f64>() / nf,
        b[..n].iter().sum::<f64>() / nf,
    );
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    if saa <= 1e-300 || sbb <= 1e-300 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Settings of [`maximize_log_1d`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Maximize1dOptions {
    /// Grid intervals over `[ln lo, ln hi]` (the grid has `grid_steps + 1` points); the maximum
    /// must be the only one within a grid interval of the best grid point. Default 60.
    pub grid_steps: usize,
    /// Golden-section iterations inside the bracket around the best grid point (each shrinks it
    /// by 0.618). Default 40.
    pub golden_iterations: usize,
    /// Whether to compute the 95 % profile interval. Default true.
    pub profile_interval: bool,
    /// Bisection steps per end of the profile interval. Default 40.
    pub bisection_iterations: usize,
}

impl Default for Maximize1dOptions {
    fn default() -> Self {
        Self {
            grid_steps: 60,
            golden_iterations: 40,
            profile_interval: true,
            bisection_iterations: 40,
        }
    }
}

/// The result of [`maximize_log_1d`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Maximum1d {
    /// The maximiser `x̂` (in `x`, not `ln x`).
    pub argmax: f64,
    /// The maximum `f(x̂)`.
    pub max: f64,
    /// 95 % profile interval `{x : f(x) ≥ f(x̂) − χ²₁(0.95)/2}` (bisection on each side); an end
    /// equal to `lo` or `hi` means the interval is not bounded there. `[NaN, NaN]` when not asked.
    pub ci95: [f64; 2],
}

/// Maximises a smooth 1-D log-likelihood `f(x)` of a positive scale `x` over `[lo, hi]`
/// (`0 < lo < hi`), searching in `ln x`: a uniform grid, then golden section between the grid
/// neighbours of the best grid point (the better of the two is kept), then, if asked, the profile
/// 95 % interval by bisection on `2·(f̂ − f) = χ²₁(0.95)`.
///
/// Costs `grid_steps + 1 + golden_iterations + 2` evaluations, plus `2·bisection_iterations + 2`
/// for the interval. The maximum must be unimodal within a grid interval of the best grid point.
///
/// # Examples
/// ```
/// use calib_core::stats::{maximize_log_1d, Maximize1dOptions};
/// // A Gaussian log-likelihood in ln x, peaked at x = 2 with σ = 0.1 in ln x.
/// let f = |x: f64| -0.5 * ((x.ln() - 2f64.ln()) / 0.1).powi(2);
/// let m = maximize_log_1d(&f, 0.1, 10.0, &Maximize1dOptions::default());
/// assert!((m.argmax - 2.0).abs() < 1e-6);
/// // The profile interval is ±1.96 σ in ln x.
/// assert!((m.ci95[0].ln() - (2f64.ln() - 0.196)).abs() < 1e-4);
/// ```
pub fn maximize_log_1d(
    f: &impl Fn(f64) -> f64,
    lo: f64,
    hi: f64,
    options: &Maximize1dOptions,
) -> Maximum1d {
    let (l0, l1) = (lo.ln(), hi.ln());
    let steps = options.grid_steps.max(1);
    let grid: Vec<(f64, f64)> = (0..=steps)
        .map(|i| {
            let s = l0 + (l1 - l0) * i as f64 / steps as f64;
            (s, f(s.exp()))
        })
        .collect();
    let best = grid
        .iter()
        .enumerate()
        .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
        .map(|(i, _)| i)
        .unwrap_or(0);
    let a = grid[best.saturating_sub(1)].0;
    let b = grid[(best + 1).min(steps)].0;
    let (s_hat, l_hat) = golden_max(&|s: f64| f(s.exp()), a, b, options.golden_iterations);
    let (s_hat, l_hat) = if grid[best].1 > l_hat {
        grid[best]
    } else {
        (s_hat, l_hat)
    };
    if !options.profile_interval {
        return Maximum1d {
            argmax: s_hat.exp(),
            max: l_hat,
            ci95: [f64::NAN; 2],
        };
    }
    let target = l_hat - 0.5 * CHI2_1_95;
    let crossing = |inner: f64, outer: f64| -> f64 {
        if f(outer.exp()) >= target {
            return outer;
        }
        let (mut i, mut o) = (inner, outer);
        for _ in 0..options.bisection_iterations {
            let m = 0.5 * (i + o);
            if f(m.exp()) >= target {
                i = m;
            } else {
                o = m;
            }
        }
        0.5 * (i + o)
    };
    let lower = crossing(s_hat, l0);
    let upper = crossing(s_hat, l1);
    Maximum1d {
        argmax: s_hat.exp(),
        max: l_hat,
        ci95: [lower.exp(), upper.exp()],
    }
}

/// Golden-section search for the maximum of a unimodal `f` on `[a, b]`: `(x̂, f(x̂))` after
/// `iters` shrinking steps.
fn golden_max(f: &impl Fn(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc >= fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    if fc >= fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Published table values are given to 4–6 digits; statrs agrees far better than that.
    const TABLE_TOL: f64 = 1e-9;

    #[test]
    fn tails_match_tables() {
        assert!((chi2_sf(3.841_458_820_694_124, 1) - 0.05).abs() < TABLE_TOL);
        assert!((chi2_sf(5.991_464_547_107_979, 2) - 0.05).abs() < TABLE_TOL);
        assert!((chi2_sf(11.070_497_693_516_35, 5) - 0.05).abs() < TABLE_TOL);
        assert_eq!(chi2_sf(0.0, 3), 1.0);
        assert!((chi2_sf_real(11.070_497_693_516_35, 5.0) - 0.05).abs() < TABLE_TOL);
        assert!(chi2_sf_real(1.0, 0.0).is_nan());
        assert!((chi2_quantile_real(0.95, 5.0) - 11.070_497_693_516_35).abs() < 1e-6);
        assert!(chi2_quantile_real(0.95, 0.0).is_nan());
        assert_eq!(chi2_sf(f64::INFINITY, 3), 0.0);
        assert!((t_quantile(0.975, 10) - 2.228_138_851_986_274).abs() < TABLE_TOL);
        assert!((t_two_sided_p(2.228_138_851_986_274, 10) - 0.05).abs() < TABLE_TOL);
        assert!((f_test_p_value(4.964_602_743_730_711, 10) - 0.05).abs() < TABLE_TOL);
        assert!((f_sf(3.325_834_530_413_011, 5, 10) - 0.05).abs() < TABLE_TOL);
        assert!((normal_quantile(0.975) - Z95).abs() < TABLE_TOL);
        assert!((chi2_sf(CHI2_1_95, 1) - 0.05).abs() < TABLE_TOL);
    }

    #[test]
    fn zero_dof_is_undefined_and_never_rejects() {
        assert!(chi2_sf(1.0, 0).is_nan());
        assert!(t_quantile(0.975, 0).is_nan());
        assert_eq!(t_two_sided_p(100.0, 0), 1.0);
        assert_eq!(f_test_p_value(100.0, 0), 1.0);
        assert_eq!(f_sf(100.0, 0, 5), 1.0);
    }

    #[test]
    fn quantile_interpolates_like_numpy() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile(&v, 0.5), 2.5);
        assert_eq!(quantile(&v, 0.0), 1.0);
        assert_eq!(quantile(&v, 1.0), 4.0);
        // numpy.quantile([1, 2, 3, 4], 0.9) = 3.7
        assert!((quantile(&v, 0.9) - 3.7).abs() < 1e-15);
        assert!(quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn ci_brackets_the_estimate_and_covers_the_true_median() {
        // Uniform grid 0..1: the true median 0.5 must lie inside, and the interval shrinks with n.
        let small: Vec<f64> = (0..100).map(|i| i as f64 / 99.0).collect();
        let large: Vec<f64> = (0..10_000).map(|i| i as f64 / 9999.0).collect();
        let a = quantile_ci(&small, 0.5);
        let b = quantile_ci(&large, 0.5);
        assert!(a.lower <= a.value && a.value <= a.upper);
        assert!(a.lower < 0.5 && a.upper > 0.5);
        assert!(b.upper - b.lower < a.upper - a.lower);
        let p95 = quantile_ci(&small, 0.95);
        assert!(p95.lower < 0.95 && p95.upper >= 0.95);
    }

    #[test]
    fn sorted_finite_drops_nan_and_sorts() {
        let v = sorted_finite([3.0, f64::NAN, 1.0, f64::INFINITY, 2.0]);
        assert_eq!(v, vec![1.0, 2.0, 3.0]);
        assert_eq!(fraction_below(&v, 2.0), 1.0 / 3.0);
        assert_eq!(fraction_below(&[], 2.0), 0.0);
    }

    #[test]
    fn pearson_of_lines_and_constants() {
        let a = [1.0, 2.0, 3.0, 4.0];
        assert!((pearson(&a, &[2.0, 4.0, 6.0, 8.0]) - 1.0).abs() < 1e-15);
        assert!((pearson(&a, &[8.0, 6.0, 4.0, 2.0]) + 1.0).abs() < 1e-15);
        assert_eq!(pearson(&a, &[5.0; 4]), 0.0);
        assert_eq!(pearson(&[1.0], &[2.0]), 0.0);
    }

    /// The maximiser finds a known peak, and its profile interval is the analytic one: for
    /// `f = −½((ln x − μ)/s)²` the interval is `μ ± √χ²₁(0.95)·s` in `ln x`.
    #[test]
    fn maximiser_finds_peak_and_profile_interval() {
        const PEAK_TOL: f64 = 1e-7;
        let (mu, s) = (0.3f64, 0.2f64);
        let f = |x: f64| -0.5 * ((x.ln() - mu) / s).powi(2);
        let m = maximize_log_1d(&f, 0.05, 20.0, &Maximize1dOptions::default());
        assert!((m.argmax.ln() - mu).abs() < PEAK_TOL, "{m:?}");
        assert!(m.max.abs() < 1e-12);
        let half = CHI2_1_95.sqrt() * s;
        assert!((m.ci95[0].ln() - (mu - half)).abs() < PEAK_TOL, "{m:?}");
        assert!((m.ci95[1].ln() - (mu + half)).abs() < PEAK_TOL, "{m:?}");

        // A coarse grid without the interval still finds the peak, and says NaN for the interval.
        let coarse = Maximize1dOptions {
            grid_steps: 16,
            golden_iterations: 30,
            profile_interval: false,
            ..Default::default()
        };
        let m = maximize_log_1d(&f, 0.05, 20.0, &coarse);
        assert!((m.argmax.ln() - mu).abs() < 1e-5, "{m:?}");
        assert!(m.ci95[0].is_nan() && m.ci95[1].is_nan());
    }

    /// A peak at the edge of the range: the maximiser stays inside, and the unbounded side of the
    /// interval reports the range's end.
    #[test]
    fn maximiser_at_the_edge_reports_unbounded_side() {
        let f = |x: f64| -x; // increasing toward lo
        let m = maximize_log_1d(&f, 0.1, 10.0, &Maximize1dOptions::default());
        assert!((m.argmax - 0.1).abs() < 1e-6, "{m:?}");
        assert!((m.ci95[0] - 0.1).abs() < 1e-12, "{m:?}");
        assert!(m.ci95[1] > 0.1 && m.ci95[1] < 10.0);
    }
}

//! Quantiles with distribution-free confidence intervals (order statistics).

/// z of a two-sided 95 % normal interval.
pub const Z95: f64 = 1.959_963_984_540_054;

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
/// statistics (numpy's default). NaN for empty data.
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

/// Sorts finite values ascending (NaN dropped).
pub fn sorted_finite(values: impl IntoIterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_interpolates_like_numpy() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile(&v, 0.5), 2.5);
        assert_eq!(quantile(&v, 0.0), 1.0);
        assert_eq!(quantile(&v, 1.0), 4.0);
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
}

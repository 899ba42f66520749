//! Statistics of a metric over runs: descriptive summaries (mean, std, IQM, normal CI),
//! seeded stratified bootstrap CIs, and paired comparisons between two conditions.
//!
//! Pure functions over f64 slices. NaN values (undefined per-run rates) are excluded and
//! counted, never propagated; a statistic that is undefined (no values, std of one value)
//! is NaN. Randomness only comes from a `ChaCha8Rng` seeded by the caller.

mod bootstrap;
mod paired;

pub use bootstrap::{Statistic, paired_bootstrap_ci, stratified_bootstrap_ci};
pub use paired::{
    Direction, Pairs, match_pairs, normal_sf, probability_of_improvement, wilcoxon_signed_rank_p,
};

use serde::{Deserialize, Serialize};

/// z quantile of a two-sided 95 % normal interval.
pub const Z_95: f64 = 1.959_963_984_540_054;

/// A sample with its NaN values removed.
#[derive(Debug, Clone, PartialEq)]
pub struct Finite {
    /// The non-NaN values, in their original order.
    pub values: Vec<f64>,
    /// How many NaN values were dropped.
    pub nan_count: usize,
}

/// Drops (and counts) the NaN values of `values`.
pub fn finite(values: &[f64]) -> Finite {
    let kept: Vec<f64> = values.iter().copied().filter(|v| !v.is_nan()).collect();
    Finite {
        nan_count: values.len() - kept.len(),
        values: kept,
    }
}

/// A confidence interval `[low, high]` (NaN bounds when undefined).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub low: f64,
    pub high: f64,
}

impl Interval {
    /// The undefined interval.
    pub const NAN: Interval = Interval {
        low: f64::NAN,
        high: f64::NAN,
    };
}

/// The descriptive statistics of one group of runs.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Values used (NaNs excluded).
    pub n: usize,
    /// NaN values excluded.
    pub nan_count: usize,
    pub mean: f64,
    /// Sample standard deviation (n − 1).
    pub std: f64,
    /// Interquartile mean.
    pub iqm: f64,
    /// Normal 95 % CI of the mean, see [`ci95_normal`].
    pub ci95: Interval,
}

/// Mean, std, IQM and normal 95 % CI of `values` (NaNs excluded and counted).
pub fn summarize(values: &[f64]) -> Summary {
    let clean = finite(values);
    let v = &clean.values;
    Summary {
        n: v.len(),
        nan_count: clean.nan_count,
        mean: mean(v),
        std: std(v),
        iqm: iqm(v),
        ci95: ci95_normal(v),
    }
}

/// Arithmetic mean of the non-NaN values (NaN if there are none).
pub fn mean(values: &[f64]) -> f64 {
    let (sum, n) = values
        .iter()
        .filter(|v| !v.is_nan())
        .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// Sample standard deviation (divisor n − 1) of the non-NaN values (NaN for fewer than 2).
pub fn std(values: &[f64]) -> f64 {
    let clean = finite(values);
    let n = clean.values.len();
    if n < 2 {
        return f64::NAN;
    }
    let m = mean(&clean.values);
    let ss: f64 = clean.values.iter().map(|v| (v - m) * (v - m)).sum();
    (ss / (n - 1) as f64).sqrt()
}

/// Interquartile mean of the non-NaN values: sort, drop `floor(n / 4)` values at each end,
/// average the rest (rliable's `scipy.stats.trim_mean(x, 0.25)`). NaN if there are none.
pub fn iqm(values: &[f64]) -> f64 {
    let mut v = finite(values).values;
    v.sort_by(f64::total_cmp);
    let cut = v.len() / 4;
    mean(&v[cut..v.len() - cut])
}

/// Normal 95 % CI of the mean: `mean ± 1.96 · std / √n` (z quantile, not Student's t:
/// with few runs per group it is too narrow; prefer the bootstrap CIs there). NaN for n < 2.
pub fn ci95_normal(values: &[f64]) -> Interval {
    let clean = finite(values);
    let n = clean.values.len();
    if n < 2 {
        return Interval::NAN;
    }
    let (m, s) = (mean(&clean.values), std(&clean.values));
    let half = Z_95 * s / (n as f64).sqrt();
    Interval {
        low: m - half,
        high: m + half,
    }
}

/// The `p`-quantile (0 ≤ p ≤ 1) of sorted values with linear interpolation between order
/// statistics (`h = (n − 1) p`, NumPy's default `linear` method). NaN when empty.
pub fn quantile_sorted(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let h = (sorted.len() - 1) as f64 * p.clamp(0.0, 1.0);
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(sorted.len() - 1);
    sorted[lo] + (h - lo as f64) * (sorted[hi] - sorted[lo])
}

#[cfg(test)]
mod tests {
    use super::*;
    use statrs::statistics::Statistics;

    #[test]
    fn mean_and_std_agree_with_statrs_and_skip_nans() {
        let data = [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0];
        let with_nan = [2.0, f64::NAN, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0];
        // Reference: statrs' `Statistics::mean` / `std_dev` (n − 1) on the same data.
        assert!((mean(&with_nan) - data.mean()).abs() < 1e-15);
        assert!((std(&with_nan) - data.std_dev()).abs() < 1e-15);
        let s = summarize(&with_nan);
        assert_eq!((s.n, s.nan_count), (8, 1));
        assert!(mean(&[f64::NAN]).is_nan() && std(&[1.0]).is_nan());
    }

    #[test]
    fn iqm_drops_a_quarter_at_each_end() {
        // By hand: n = 8 drops 2 per end → mean(3, 4, 5, 6) = 4.5.
        assert_eq!(iqm(&[8.0, 1.0, 7.0, 2.0, 6.0, 3.0, 5.0, 4.0]), 4.5);
        // n = 5 drops 1 per end → mean(2, 3, 100) = 35; n = 3 drops nothing.
        assert_eq!(iqm(&[1.0, 2.0, 3.0, 100.0, 1000.0]), 35.0);
        assert_eq!(iqm(&[1.0, 2.0, 6.0]), 3.0);
    }

    #[test]
    fn normal_ci_by_hand() {
        // mean 5, std 2 (n − 1), n = 4: half width 1.959963984540054 · 2 / 2.
        let ci = ci95_normal(&[3.0, 3.0, 7.0, 7.0]);
        let s = std(&[3.0, 3.0, 7.0, 7.0]);
        assert!((s - (16.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!((ci.low - (5.0 - Z_95 * s / 2.0)).abs() < 1e-15);
        assert!((ci.high - (5.0 + Z_95 * s / 2.0)).abs() < 1e-15);
        assert!(ci95_normal(&[1.0]).low.is_nan());
    }

    #[test]
    fn quantiles_interpolate_like_numpy() {
        // numpy.percentile([1, 2, 3, 4], [2.5, 50, 97.5]) = [1.075, 2.5, 3.925].
        let v = [1.0, 2.0, 3.0, 4.0];
        assert!((quantile_sorted(&v, 0.025) - 1.075).abs() < 1e-12);
        assert_eq!(quantile_sorted(&v, 0.5), 2.5);
        assert!((quantile_sorted(&v, 0.975) - 3.925).abs() < 1e-12);
    }
}

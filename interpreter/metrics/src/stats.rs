//! Statistics of a metric over runs: descriptive summaries (mean, std, IQM, median, the mean
//! without the extremes, Student-t CI),
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

/// The values a metric can take: a confidence interval never leaves them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Range {
    pub low: f64,
    pub high: f64,
}

impl Range {
    /// Any real value.
    pub const UNBOUNDED: Range = Range {
        low: f64::NEG_INFINITY,
        high: f64::INFINITY,
    };
    /// Zero or more (rates, distances, speeds).
    pub const NON_NEGATIVE: Range = Range {
        low: 0.0,
        high: f64::INFINITY,
    };
}

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
    /// The median.
    pub median: f64,
    /// The mean without the largest and the smallest value ([`trimmed_mean`]).
    pub trimmed_mean: f64,
    /// Student-t 95 % CI of the mean within the metric's range, see [`ci95_t`].
    pub ci95: Interval,
}

/// Mean, std, IQM, median, the trimmed mean and the Student-t 95 % CI of `values` within
/// `range` (NaNs excluded and counted).
pub fn summarize(values: &[f64], range: Range) -> Summary {
    let clean = finite(values);
    let v = &clean.values;
    Summary {
        n: v.len(),
        nan_count: clean.nan_count,
        mean: mean(v),
        std: std(v),
        iqm: iqm(v),
        median: median(v),
        trimmed_mean: trimmed_mean(v),
        ci95: ci95_t(v, range),
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

/// The median of the non-NaN values (the mean of the middle two for an even count; NaN if
/// there are none).
pub fn median(values: &[f64]) -> f64 {
    let mut v = finite(values).values;
    v.sort_by(f64::total_cmp);
    quantile_sorted(&v, 0.5)
}

/// The mean of the non-NaN values without the largest and the smallest one: SigmaRL's
/// evaluation drops its best and its worst environment before it averages (NaN for fewer than
/// three values, where nothing would be left to average or the trim would be all but one).
pub fn trimmed_mean(values: &[f64]) -> f64 {
    let mut v = finite(values).values;
    if v.len() < 3 {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    mean(&v[1..v.len() - 1])
}

/// Student-t 95 % CI of the mean, `mean ± t(0.975; n − 1) · std / √n`, intersected with
/// `range` (a rate of collisions has no interval below 0: the part outside the values the
/// metric can take holds no mean). NaN for n < 2.
///
/// Student's t, not the normal z: groups hold few independent units (9 in the paper's
/// design), where z = 1.96 is too narrow (t(0.975; 8) = 2.306).
pub fn ci95_t(values: &[f64], range: Range) -> Interval {
    let clean = finite(values);
    let n = clean.values.len();
    if n < 2 {
        return Interval::NAN;
    }
    let (m, s) = (mean(&clean.values), std(&clean.values));
    let half = t_quantile_975(n - 1) * s / (n as f64).sqrt();
    Interval {
        low: (m - half).max(range.low),
        high: (m + half).min(range.high),
    }
}

/// The 0.975 quantile of Student's t with `degrees_of_freedom` (≥ 1).
pub fn t_quantile_975(degrees_of_freedom: usize) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    StudentsT::new(0.0, 1.0, degrees_of_freedom as f64).map_or(f64::NAN, |t| t.inverse_cdf(0.975))
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
        let s = summarize(&with_nan, Range::UNBOUNDED);
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
    fn median_and_trimmed_mean_by_hand() {
        // Sorted 1, 2, 3, 100: the median is (2 + 3)/2; the trimmed mean drops 1 and 100.
        let data = [3.0, 100.0, 1.0, f64::NAN, 2.0];
        assert_eq!(median(&data), 2.5);
        assert_eq!(trimmed_mean(&data), 2.5);
        // Odd count: the middle value; the trim drops one value at each end only.
        assert_eq!(median(&[5.0, 1.0, 9.0]), 5.0);
        assert_eq!(trimmed_mean(&[5.0, 1.0, 9.0, 9.0, 1.0]), 5.0);
        assert!(trimmed_mean(&[1.0, 2.0]).is_nan() && median(&[f64::NAN]).is_nan());
        let s = summarize(&data, Range::UNBOUNDED);
        assert_eq!((s.median, s.trimmed_mean), (2.5, 2.5));
    }

    #[test]
    fn t_ci_by_hand() {
        // mean 5, std √(16/3) (n − 1), n = 4: half width t(0.975; 3) · s / 2, with
        // t(0.975; 3) = 3.182446305284263 (tables; scipy.stats.t.ppf(0.975, 3)).
        let ci = ci95_t(&[3.0, 3.0, 7.0, 7.0], Range::UNBOUNDED);
        let s = std(&[3.0, 3.0, 7.0, 7.0]);
        assert!((s - (16.0f64 / 3.0).sqrt()).abs() < 1e-15);
        let t3 = 3.182_446_305_284_263;
        assert!((ci.low - (5.0 - t3 * s / 2.0)).abs() < 1e-9, "{ci:?}");
        assert!((ci.high - (5.0 + t3 * s / 2.0)).abs() < 1e-9, "{ci:?}");
        assert!(ci95_t(&[1.0], Range::UNBOUNDED).low.is_nan());
        // t(0.975; 8) = 2.306004135204166, t(0.975; 26) = 2.055529438642871.
        assert!((t_quantile_975(8) - 2.306_004_135_204_166).abs() < 1e-9);
        assert!((t_quantile_975(26) - 2.055_529_438_642_871).abs() < 1e-9);
    }

    #[test]
    fn intervals_stay_in_the_metric_range() {
        // One collision in nine runs: the unbounded interval reaches below zero.
        let values = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 6.0];
        let open = ci95_t(&values, Range::UNBOUNDED);
        assert!(open.low < 0.0);
        let bounded = ci95_t(&values, Range::NON_NEGATIVE);
        assert_eq!(bounded.low, 0.0);
        assert_eq!(bounded.high, open.high);
        let capped = ci95_t(
            &[99.0, 100.0, 100.0],
            Range {
                low: 0.0,
                high: 100.0,
            },
        );
        assert_eq!(capped.high, 100.0);
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

//! Percentile bootstrap CIs from a seeded `ChaCha8Rng`: stratified (of the mean or IQM of a
//! group) and paired (of the mean difference).
//!
//! The draws are fully specified here (see [`uniform_index`]), so a seed gives the same
//! interval on every machine and with every version of `rand`.

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};

use super::{Interval, finite, iqm, mean, quantile_sorted};

/// The statistic a bootstrap CI is computed for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Statistic {
    Mean,
    /// Interquartile mean, see [`super::iqm`].
    Iqm,
}

impl Statistic {
    fn of(self, values: &[f64]) -> f64 {
        match self {
            Statistic::Mean => mean(values),
            Statistic::Iqm => iqm(values),
        }
    }
}

/// Stratified percentile bootstrap CI of `statistic` over all values of all strata.
///
/// NaN values are dropped from every stratum first. Each of `resamples` resamples draws,
/// stratum by stratum in the given order, as many values with replacement as the stratum
/// has (empty strata contribute nothing), and computes the statistic of their union. The
/// interval is the `(1 − confidence) / 2` and `(1 + confidence) / 2` quantiles of the
/// resampled statistics ([`quantile_sorted`]). The generator is
/// `ChaCha8Rng::seed_from_u64(seed)`. NaN interval when there are no values or no resamples.
pub fn stratified_bootstrap_ci(
    strata: &[&[f64]],
    statistic: Statistic,
    resamples: usize,
    seed: u64,
    confidence: f64,
) -> Interval {
    let strata: Vec<Vec<f64>> = strata.iter().map(|s| finite(s).values).collect();
    let total: usize = strata.iter().map(Vec::len).sum();
    if total == 0 || resamples == 0 {
        return Interval::NAN;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut draw = Vec::with_capacity(total);
    let mut stats = Vec::with_capacity(resamples);
    for _ in 0..resamples {
        draw.clear();
        for stratum in &strata {
            for _ in 0..stratum.len() {
                draw.push(stratum[uniform_index(&mut rng, stratum.len())]);
            }
        }
        stats.push(statistic.of(&draw));
    }
    percentile_interval(stats, confidence)
}

/// Paired percentile bootstrap CI of the mean of `a[i] − b[i]`.
///
/// Pairs with a NaN on either side are dropped first. Each resample draws `n` pair indices
/// with replacement from `ChaCha8Rng::seed_from_u64(seed)`; the interval is taken as in
/// [`stratified_bootstrap_ci`]. NaN interval when no pair is left, the slices differ in
/// length, or `resamples` is 0.
pub fn paired_bootstrap_ci(a: &[f64], b: &[f64], resamples: usize, seed: u64, confidence: f64) -> Interval {
    if a.len() != b.len() {
        return Interval::NAN;
    }
    let diffs: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| x - y)
        .filter(|d| !d.is_nan())
        .collect();
    stratified_bootstrap_ci(&[&diffs], Statistic::Mean, resamples, seed, confidence)
}

fn percentile_interval(mut stats: Vec<f64>, confidence: f64) -> Interval {
    stats.retain(|s| !s.is_nan());
    stats.sort_by(f64::total_cmp);
    let alpha = 1.0 - confidence.clamp(0.0, 1.0);
    Interval {
        low: quantile_sorted(&stats, alpha / 2.0),
        high: quantile_sorted(&stats, 1.0 - alpha / 2.0),
    }
}

/// An index uniform in `0..n` (n ≥ 1) from the generator's `next_u64`, by Lemire's unbiased
/// multiply-and-reject method: `m = x · n` (128 bit); reject while the low 64 bits are below
/// `2^64 mod n`; the index is the high 64 bits.
pub fn uniform_index(rng: &mut ChaCha8Rng, n: usize) -> usize {
    let n = n as u64;
    let threshold = n.wrapping_neg() % n;
    loop {
        let m = u128::from(rng.next_u64()) * u128::from(n);
        if (m as u64) >= threshold {
            return (m >> 64) as usize;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_interval() {
        let a = [1.0, 2.0, 3.0, 4.0, 10.0];
        let b = [0.5, f64::NAN, 0.7];
        let ci = |seed| stratified_bootstrap_ci(&[&a, &b], Statistic::Mean, 2000, seed, 0.95);
        assert_eq!(ci(7), ci(7));
        assert_ne!(ci(7), ci(8));
    }

    #[test]
    fn bootstrap_intervals_bracket_the_statistic() {
        let a: Vec<f64> = (0..40).map(|i| (i as f64 * 0.37).sin() * 3.0 + 5.0).collect();
        for statistic in [Statistic::Mean, Statistic::Iqm] {
            let ci = stratified_bootstrap_ci(&[&a[..20], &a[20..]], statistic, 4000, 1, 0.95);
            let s = statistic.of(&a);
            assert!(ci.low < s && s < ci.high, "{statistic:?}: {ci:?} vs {s}");
            // The mean's percentile CI is close to the t one (n = 40: t ≈ 2.02 σ/√n).
            if statistic == Statistic::Mean {
                let normal = super::super::ci95_t(&a, super::super::Range::UNBOUNDED);
                assert!((ci.low - normal.low).abs() < 0.15 && (ci.high - normal.high).abs() < 0.15);
            }
        }
    }

    #[test]
    fn a_constant_sample_has_a_point_interval() {
        let ci = stratified_bootstrap_ci(&[&[2.0; 6]], Statistic::Iqm, 100, 3, 0.95);
        assert_eq!((ci.low, ci.high), (2.0, 2.0));
        let d = paired_bootstrap_ci(&[3.0, 4.0, 5.0], &[2.0, 3.0, 4.0], 100, 3, 0.95);
        assert_eq!((d.low, d.high), (1.0, 1.0));
        assert!(
            stratified_bootstrap_ci(&[&[]], Statistic::Mean, 100, 3, 0.95)
                .low
                .is_nan()
        );
    }

    #[test]
    fn uniform_indices_cover_the_range_evenly() {
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut counts = [0usize; 3];
        for _ in 0..30_000 {
            counts[uniform_index(&mut rng, 3)] += 1;
        }
        // Binomial(30000, 1/3): σ ≈ 82; allow 5 σ.
        assert!(counts.iter().all(|&c| c.abs_diff(10_000) < 410), "{counts:?}");
    }
}

//! Comparing two conditions run on the same keys (e.g. fidelities sharing initial states and
//! seeds): matching by key, the Wilcoxon signed-rank test, and rliable's probability of
//! improvement.

use std::collections::BTreeMap;

/// Values of two conditions matched by key.
#[derive(Debug, Clone, PartialEq)]
pub struct Pairs<K> {
    /// Keys present in both, ascending, without a NaN on either side.
    pub keys: Vec<K>,
    /// First condition's values, aligned with `keys`.
    pub a: Vec<f64>,
    /// Second condition's values, aligned with `keys`.
    pub b: Vec<f64>,
    /// Keys present in only one of the two.
    pub unmatched: usize,
    /// Matched keys dropped because a value was NaN.
    pub nan_pairs: usize,
}

/// Matches the values of `a` and `b` by key (keys are unique per side; a repeated key keeps
/// its last value).
pub fn match_pairs<K: Ord + Clone>(
    a: impl IntoIterator<Item = (K, f64)>,
    b: impl IntoIterator<Item = (K, f64)>,
) -> Pairs<K> {
    let a: BTreeMap<K, f64> = a.into_iter().collect();
    let mut b: BTreeMap<K, f64> = b.into_iter().collect();
    let mut pairs = Pairs {
        keys: Vec::new(),
        a: Vec::new(),
        b: Vec::new(),
        unmatched: 0,
        nan_pairs: 0,
    };
    for (key, x) in a {
        match b.remove(&key) {
            None => pairs.unmatched += 1,
            Some(y) if x.is_nan() || y.is_nan() => pairs.nan_pairs += 1,
            Some(y) => {
                pairs.keys.push(key);
                pairs.a.push(x);
                pairs.b.push(y);
            }
        }
    }
    pairs.unmatched += b.len();
    pairs
}

/// Two-sided p-value of the Wilcoxon signed-rank test of `a[i] − b[i]` (scipy's
/// `wilcoxon(a, b)` with `zero_method='wilcox'`).
///
/// Pairs with a NaN and zero differences are dropped; `|d|` is ranked with average ranks
/// for ties; `T = min(W+, W−)`. With n ≤ 25 non-zero differences and no ties, the exact
/// null distribution gives `p = min(1, 2 P(W ≤ T))`. Otherwise the normal approximation
/// with tie correction (`σ² = n(n+1)(2n+1)/24 − Σ(t³ − t)/48`) and continuity correction:
/// `z = (T − n(n+1)/4 + 0.5) / σ`, `p = 2 P(Z ≥ |z|)` (scipy's `correction=True`).
/// NaN when no non-zero difference is left or the slices differ in length.
pub fn wilcoxon_signed_rank_p(a: &[f64], b: &[f64]) -> f64 {
    if a.len() != b.len() {
        return f64::NAN;
    }
    let mut d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(x, y)| x - y)
        .filter(|d| !d.is_nan() && *d != 0.0)
        .collect();
    let n = d.len();
    if n == 0 {
        return f64::NAN;
    }

    // Average ranks of |d| and the tie groups.
    d.sort_by(|x, y| x.abs().total_cmp(&y.abs()));
    let (mut w_plus, mut w_minus, mut tie_term) = (0.0, 0.0, 0.0);
    let mut start = 0;
    while start < n {
        let mut end = start + 1;
        while end < n && d[end].abs() == d[start].abs() {
            end += 1;
        }
        let rank = (start + 1 + end) as f64 / 2.0;
        for v in &d[start..end] {
            if *v > 0.0 {
                w_plus += rank;
            } else {
                w_minus += rank;
            }
        }
        let t = (end - start) as f64;
        tie_term += t * t * t - t;
        start = end;
    }
    let t_stat = f64::min(w_plus, w_minus);
    let nf = n as f64;

    if n <= 25 && tie_term == 0.0 {
        // Exact: counts of subsets of {1..n} by rank sum.
        let max_sum = n * (n + 1) / 2;
        let mut counts = vec![0.0f64; max_sum + 1];
        counts[0] = 1.0;
        for r in 1..=n {
            for s in (r..=max_sum).rev() {
                counts[s] += counts[s - r];
            }
        }
        let t = t_stat as usize;
        let below: f64 = counts[..=t].iter().sum();
        return (2.0 * below / 2f64.powi(n as i32)).min(1.0);
    }
    let mean = nf * (nf + 1.0) / 4.0;
    let var = nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0;
    if var <= 0.0 {
        return f64::NAN;
    }
    let correction = 0.5 * (t_stat - mean).signum();
    let z = (t_stat - mean - correction) / var.sqrt();
    (2.0 * normal_sf(z.abs())).min(1.0)
}

/// Which way a metric improves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// ↑ metrics (e.g. AS when speed is the goal).
    HigherIsBetter,
    /// ↓ metrics (CRA-A, CRA-L, CD).
    LowerIsBetter,
}

/// Probability that a run of condition `x` improves on a run of condition `y`, as rliable's
/// `probability_of_improvement` for one task: the Mann-Whitney U statistic over all
/// `len(x) · len(y)` combinations divided by their number, where "improves" is `x > y` for
/// ↑ metrics and `x < y` for ↓ metrics, and ties count ½. NaN values are dropped; NaN if a
/// side is empty. (rliable averages this over tasks; do so over groups if needed.)
pub fn probability_of_improvement(x: &[f64], y: &[f64], direction: Direction) -> f64 {
    let x: Vec<f64> = x.iter().copied().filter(|v| !v.is_nan()).collect();
    let y: Vec<f64> = y.iter().copied().filter(|v| !v.is_nan()).collect();
    if x.is_empty() || y.is_empty() {
        return f64::NAN;
    }
    let mut wins = 0.0;
    for xi in &x {
        for yj in &y {
            let better = match direction {
                Direction::HigherIsBetter => xi > yj,
                Direction::LowerIsBetter => xi < yj,
            };
            if better {
                wins += 1.0;
            } else if xi == yj {
                wins += 0.5;
            }
        }
    }
    wins / (x.len() * y.len()) as f64
}

/// Upper tail `P(Z ≥ z)` of the standard normal distribution, `erfc(z / √2) / 2`, to about
/// 1e-15 relative.
pub fn normal_sf(z: f64) -> f64 {
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Complementary error function: the series `erf(x) = 2/√π e^(−x²) Σ 2ⁿ x^(2n+1) /
/// (1·3···(2n+1))` for |x| < 3, the continued fraction of `erfc` (modified Lentz) beyond.
fn erfc(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    let two_over_sqrt_pi = std::f64::consts::FRAC_2_SQRT_PI;
    if x < 3.0 {
        let mut term = x;
        let mut sum = x;
        for n in 1..200 {
            term *= 2.0 * x * x / (2 * n + 1) as f64;
            sum += term;
            if term < sum * 1e-17 {
                break;
            }
        }
        return 1.0 - two_over_sqrt_pi * (-x * x).exp() * sum;
    }
    // erfc(x) = e^(−x²)/√π · 1 / (x + (1/2) / (x + 1 / (x + (3/2) / (x + 2 / (x + …))))).
    let tiny = 1e-300;
    let mut f = x;
    let (mut c, mut d) = (x, 0.0);
    for k in 1..500 {
        let a = k as f64 / 2.0;
        d = x + a * d;
        d = if d.abs() < tiny { tiny } else { d };
        c = x + a / c;
        c = if c.abs() < tiny { tiny } else { c };
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    two_over_sqrt_pi / 2.0 * (-x * x).exp() / f
}

#[cfg(test)]
mod tests {
    use super::*;
    use statrs::distribution::{ContinuousCDF, Normal};

    #[test]
    fn normal_tail_agrees_with_statrs() {
        // Reference: statrs' Normal(0, 1).sf, whose erfc is accurate to ~1e-10 relative
        // (measured against the tabulated values below), hence the tolerance.
        let normal = Normal::standard();
        for z in [
            -3.0,
            -1.0,
            0.0,
            0.5,
            1.0,
            1.959963984540054,
            2.5,
            4.0,
            4.3,
            6.0,
            9.0,
        ] {
            let (ours, theirs) = (normal_sf(z), normal.sf(z));
            assert!(
                (ours - theirs).abs() <= 1e-9 * theirs,
                "z = {z}: {ours} vs {theirs}"
            );
        }
        assert!((normal_sf(1.959963984540054) - 0.025).abs() < 1e-15);
    }

    #[test]
    fn erfc_matches_tabulated_values() {
        // erfc(0.5), erfc(1), erfc(2), erfc(4) (mpmath.erfc's digits, rounded to f64).
        for (x, v) in [
            (0.5, 0.479_500_122_186_953_5),
            (1.0, 0.157_299_207_050_285_13),
            (2.0, 0.004_677_734_981_047_266),
            (4.0, 1.541_725_790_028_002e-8),
        ] {
            assert!(
                ((erfc(x) - v) / v).abs() < 1e-13,
                "erfc({x}) = {} vs {v}",
                erfc(x)
            );
        }
    }

    #[test]
    fn exact_wilcoxon_by_hand() {
        // All 5 differences positive: T = 0, P(W ≤ 0) = 1/32, p = 2/32
        // (scipy.stats.wilcoxon([1, 2, 3, 4, 5]) gives 0.0625).
        assert_eq!(
            wilcoxon_signed_rank_p(&[1.0, 2.0, 3.0, 4.0, 5.0], &[0.0; 5]),
            0.0625
        );
        // d = 1, −2, 3, 4, −5, 6: W− = 2 + 5 = 7 = T. Subsets of {1..6} with sum ≤ 7:
        // sums 0..7 have 1, 1, 1, 2, 2, 3, 4, 4 subsets → 18; p = 2 · 18 / 64 = 0.5625.
        let d = [1.0, -2.0, 3.0, 4.0, -5.0, 6.0];
        assert_eq!(wilcoxon_signed_rank_p(&d, &[0.0; 6]), 0.5625);
        // Zeros are dropped (zero_method 'wilcox'), so this is the first case again.
        assert_eq!(
            wilcoxon_signed_rank_p(&[1.0, 2.0, 0.0, 3.0, 4.0, 5.0], &[0.0; 6]),
            0.0625
        );
        assert!(wilcoxon_signed_rank_p(&[1.0], &[1.0]).is_nan());
    }

    #[test]
    fn normal_wilcoxon_with_ties_by_hand() {
        // d = 1, 1, −1, 2, 2, 3: |d| ranks 2, 2, 2, 4.5, 4.5, 6; W− = 2, W+ = 19, T = 2.
        // mean 10.5; σ² = 6·7·13/24 − ((27 − 3) + (8 − 2))/48 = 22.75 − 0.625 = 22.125;
        // z = (2 − 10.5 + 0.5)/√22.125; p = 2 · sf(|z|), sf from statrs.
        let d = [1.0, 1.0, -1.0, 2.0, 2.0, 3.0];
        let z: f64 = (2.0 - 10.5 + 0.5) / 22.125f64.sqrt();
        let expected = 2.0 * Normal::standard().sf(z.abs());
        assert!((wilcoxon_signed_rank_p(&d, &[0.0; 6]) - expected).abs() < 1e-9 * expected);
    }

    #[test]
    fn probability_of_improvement_by_hand() {
        // x = {1, 2, 3}, y = {2, 2}: x > y in 2 of 6 combinations, ties in 2 → (2 + 1)/6.
        let (x, y) = ([1.0, 2.0, 3.0], [2.0, 2.0]);
        assert_eq!(probability_of_improvement(&x, &y, Direction::HigherIsBetter), 0.5);
        let (x, y) = ([3.0, 4.0, f64::NAN], [1.0, 2.0, 3.0]);
        // ↑: 5 wins + 1 tie of 6 → 5.5/6; ↓: 0 wins + 1 tie → 0.5/6.
        assert_eq!(
            probability_of_improvement(&x, &y, Direction::HigherIsBetter),
            5.5 / 6.0
        );
        assert_eq!(
            probability_of_improvement(&x, &y, Direction::LowerIsBetter),
            0.5 / 6.0
        );
    }

    #[test]
    fn pairs_match_by_key_and_count_the_rest() {
        let a = [("r1", 1.0), ("r2", f64::NAN), ("r3", 3.0), ("r4", 4.0)];
        let b = [("r3", 2.5), ("r1", 0.5), ("r2", 1.0), ("r9", 9.0)];
        let p = match_pairs(a, b);
        assert_eq!(p.keys, vec!["r1", "r3"]);
        assert_eq!((p.a, p.b), (vec![1.0, 3.0], vec![0.5, 2.5]));
        assert_eq!((p.unmatched, p.nan_pairs), (2, 1));
    }
}

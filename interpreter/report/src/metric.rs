//! The four metrics as the summary shows them: identifiers, labels, units, the direction of
//! improvement and the display precision of Table 2.
//!
//! This module owns presentation facts about metrics; it computes no metric.

use cpmx_metrics::stats::{Direction, Range};
use cpmx_metrics::{MetricsConfig, RunMetrics};

/// A metric of the summary, in the column order of the paper's Table 2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Metric {
    /// Agent-agent collision events per travelled distance (lower is better).
    CraA,
    /// Distance driven outside the own lane per travelled distance (lower is better).
    CraL,
    /// Mean centre-line deviation [m] (lower is better).
    Cd,
    /// Mean speed [m/s] (higher is better: hesitation and stops lower it).
    As,
    /// SigmaRL's share of samples with two cars' outlines crossing [%] (lower is better).
    CrAa,
    /// SigmaRL's share of samples with a car's outline crossing its road's boundaries [%]
    /// (lower is better).
    CrAl,
}

impl Metric {
    /// The paper's four metrics, in table order: every summary shows them.
    pub const ALL: [Metric; 4] = [Metric::CraA, Metric::CraL, Metric::Cd, Metric::As];

    /// The paper's four and SigmaRL's per-sample collision rates, in table order.
    pub const WITH_PER_SAMPLE: [Metric; 6] = [
        Metric::CraA,
        Metric::CraL,
        Metric::Cd,
        Metric::As,
        Metric::CrAa,
        Metric::CrAl,
    ];

    /// Its column in `per_run.csv` and its key in `summary.json`.
    pub fn id(self) -> &'static str {
        match self {
            Metric::CraA => "cra_a",
            Metric::CraL => "cra_l",
            Metric::Cd => "cd_m",
            Metric::As => "as_mps",
            Metric::CrAa => "cr_aa_pct",
            Metric::CrAl => "cr_al_pct",
        }
    }

    /// The paper's name.
    pub fn label(self) -> &'static str {
        match self {
            Metric::CraA => "CRA-A",
            Metric::CraL => "CRA-L",
            Metric::Cd => "CD",
            Metric::As => "AS",
            Metric::CrAa => "CR-AA",
            Metric::CrAl => "CR-AL",
        }
    }

    /// Which way the metric improves: CRA-A, CRA-L and CD lower, AS higher.
    pub fn direction(self) -> Direction {
        match self {
            Metric::As => Direction::HigherIsBetter,
            _ => Direction::LowerIsBetter,
        }
    }

    /// `↑` or `↓`, as the paper marks the direction of improvement.
    pub fn arrow(self) -> &'static str {
        match self.direction() {
            Direction::HigherIsBetter => "↑",
            Direction::LowerIsBetter => "↓",
        }
    }

    /// Decimals shown in the tables (the paper's: rates 2, metres and speeds 3; SigmaRL's
    /// percentages 2).
    pub fn decimals(self) -> usize {
        match self {
            Metric::CraA | Metric::CraL | Metric::CrAa | Metric::CrAl => 2,
            Metric::Cd | Metric::As => 3,
        }
    }

    /// The values the metric can take: every rate, distance and speed is at least 0, and
    /// CRA-L (metres outside the lane per distance driven) at most its normalising distance,
    /// a share of samples at most 100 %.
    pub fn range(self, units: Units) -> Range {
        match self {
            Metric::CraL => Range {
                low: 0.0,
                high: units.cra_l_per_distance_m,
            },
            Metric::CrAa | Metric::CrAl => Range {
                low: 0.0,
                high: 100.0,
            },
            Metric::CraA | Metric::Cd | Metric::As => Range::NON_NEGATIVE,
        }
    }

    /// This metric's value in one run (NaN when undefined).
    pub fn of(self, metrics: &RunMetrics) -> f64 {
        match self {
            Metric::CraA => metrics.cra_a,
            Metric::CraL => metrics.cra_l,
            Metric::Cd => metrics.cd_m,
            Metric::As => metrics.as_mps,
            Metric::CrAa => metrics.cr_aa_pct,
            Metric::CrAl => metrics.cr_al_pct,
        }
    }
}

/// The distances the two rates are normalised by, which their units name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Units {
    /// CRA-A counts events per this distance [m].
    pub cra_a_per_distance_m: f64,
    /// CRA-L counts metres outside the lane per this distance [m].
    pub cra_l_per_distance_m: f64,
    /// Whether the runs also measure SigmaRL's per-sample collision rates.
    pub per_sample_collisions: bool,
}

impl Units {
    /// The units of the runs' metrics: those of the first run's parameters (the runs of one
    /// spec share them), or the paper's defaults when there are no runs.
    pub fn of_runs<'a>(mut metrics: impl Iterator<Item = &'a RunMetrics>) -> Units {
        let config = metrics.next().map_or_else(MetricsConfig::default, |m| m.config);
        Units {
            cra_a_per_distance_m: config.cra_a.per_distance_m,
            cra_l_per_distance_m: config.cra_l.per_distance_m,
            per_sample_collisions: config.per_sample_collisions,
        }
    }

    /// The metrics the runs measure, in table order: the paper's four, and SigmaRL's
    /// per-sample collision rates when the spec asks for them.
    pub fn metrics(self) -> &'static [Metric] {
        if self.per_sample_collisions {
            &Metric::WITH_PER_SAMPLE
        } else {
            &Metric::ALL
        }
    }

    /// The unit as plain text: `events/100 m`, `m/100 m`, `m`, `m/s`.
    pub fn text(self, metric: Metric) -> String {
        match metric {
            Metric::CraA => format!("events/{} m", self.cra_a_per_distance_m),
            Metric::CraL => format!("m/{} m", self.cra_l_per_distance_m),
            Metric::Cd => "m".into(),
            Metric::As => "m/s".into(),
            Metric::CrAa | Metric::CrAl => "% of samples".into(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_name_the_normalising_distance() {
        let units = Units::of_runs(std::iter::empty());
        assert_eq!(units.text(Metric::CraA), "events/100 m");
        assert_eq!(units.text(Metric::CraL), "m/100 m");
        let other = Units {
            cra_a_per_distance_m: 1000.0,
            cra_l_per_distance_m: 0.5,
            per_sample_collisions: false,
        };
        assert_eq!(other.text(Metric::CraA), "events/1000 m");
        assert_eq!(other.text(Metric::CraL), "m/0.5 m");
    }

    #[test]
    fn lane_violation_cannot_exceed_the_distance_driven() {
        let units = Units::of_runs(std::iter::empty());
        assert_eq!(Metric::CraL.range(units).high, 100.0);
        assert_eq!(Metric::CraA.range(units).low, 0.0);
        assert_eq!(Metric::As.range(units).high, f64::INFINITY);
    }

    #[test]
    fn only_speed_improves_upwards() {
        let arrows: Vec<&str> = Metric::ALL.iter().map(|m| m.arrow()).collect();
        assert_eq!(arrows, ["↓", "↓", "↓", "↑"]);
    }
}

//! Which runs are independent units. A repetition whose recording is bit-identical to an
//! earlier repetition of the same fidelity, policy and initial configuration is a copy (a
//! deterministic fidelity and policy give the same run every time): it adds no information,
//! so statistics count it once. Every table says how many runs and how many distinct units
//! it used.
//!
//! This module owns that rule and nothing else; it compares recordings by their digest
//! ([`RunRecord::recording_sha256`]), never by their metrics (two different runs can share
//! every metric value).

use crate::RunRecord;

/// The runs of `runs` that are not copies of an earlier run, in their order: the first run
/// of each (fidelity, policy, initial configuration, recording digest).
pub fn distinct_units<'a>(runs: impl IntoIterator<Item = &'a RunRecord>) -> Vec<&'a RunRecord> {
    let mut seen: Vec<(&str, &str, &str, &str)> = Vec::new();
    let mut units = Vec::new();
    for run in runs {
        let cell = cell_of(run);
        if !seen.contains(&cell) {
            seen.push(cell);
            units.push(run);
        }
    }
    units
}

fn cell_of(run: &RunRecord) -> (&str, &str, &str, &str) {
    (
        run.plan.fidelity.as_str(),
        run.plan.policy.as_str(),
        run.plan.initial_configuration.as_str(),
        run.recording_sha256.as_str(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{copy_of, record};

    #[test]
    fn identical_repetitions_are_one_unit() {
        let first = record("sim", "p", "i1", 1, [0.0, 1.0, 0.1, 0.5]);
        let runs = vec![
            first.clone(),
            copy_of(&first, 2),
            copy_of(&first, 3),
            record("sim", "p", "i2", 1, [0.0, 1.0, 0.1, 0.5]),
        ];
        let units = distinct_units(&runs);
        let keys: Vec<&str> = units.iter().map(|r| r.plan.key.as_str()).collect();
        assert_eq!(keys, ["sim/p/i1/rep1", "sim/p/i2/rep1"]);
    }

    #[test]
    fn equal_metrics_with_different_recordings_stay_two_units() {
        let a = record("twin", "p", "i1", 1, [0.0, 1.0, 0.1, 0.5]);
        let b = record("twin", "p", "i1", 2, [0.0, 1.0, 0.1, 0.5]);
        assert_eq!(distinct_units(&[a, b]).len(), 2);
    }

    #[test]
    fn the_same_recording_in_another_cell_is_not_a_copy() {
        let a = record("sim", "p", "i1", 1, [0.0; 4]);
        let mut b = record("sim-mpc", "p", "i1", 1, [0.0; 4]);
        b.recording_sha256.clone_from(&a.recording_sha256);
        assert_eq!(distinct_units(&[a, b]).len(), 2);
    }
}

//! The enter/exit hysteresis that turns a pair's per-sample overlap into collision events
//! (SigmaRL's `get_agent_agent_collision_timesteps`).
//!
//! This module owns the counting rule only; it knows nothing of geometry.

use crate::config::Hysteresis;

/// Samples at which collision events start, for one pair of agents.
///
/// A sample is overlapping when its signed distance is `< 0` (0 is no contact; NaN counts as
/// free). Counters of consecutive overlapping and free samples run through time; outside a
/// collision, the `enter`-th consecutive overlapping sample starts an event (stamped at that
/// sample); inside one, `exit` consecutive free samples end it.
pub fn event_samples(signed_distances_m: &[f64], hysteresis: Hysteresis) -> Vec<usize> {
    let mut events = Vec::new();
    let (mut overlapping, mut free) = (0usize, 0usize);
    let mut in_collision = false;
    for (k, &d) in signed_distances_m.iter().enumerate() {
        if d < 0.0 {
            overlapping += 1;
            free = 0;
            if !in_collision && overlapping >= hysteresis.enter {
                events.push(k);
                in_collision = true;
            }
        } else {
            free += 1;
            overlapping = 0;
            if in_collision && free >= hysteresis.exit {
                in_collision = false;
            }
        }
    }
    events
}

/// Number of maximal runs of consecutive overlapping samples.
pub fn overlap_episodes(signed_distances_m: &[f64]) -> usize {
    let mut episodes = 0;
    let mut previous = false;
    for &d in signed_distances_m {
        let now = d < 0.0;
        if now && !previous {
            episodes += 1;
        }
        previous = now;
    }
    episodes
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCRIPT: Hysteresis = Hysteresis { enter: 3, exit: 5 };

    fn pattern(text: &str) -> Vec<f64> {
        text.chars()
            .map(|c| if c == 'x' { -0.01 } else { 0.01 })
            .collect()
    }

    #[test]
    fn the_event_is_stamped_at_the_third_overlapping_sample() {
        assert_eq!(event_samples(&pattern("..xxxx.."), SCRIPT), vec![4]);
        assert!(event_samples(&pattern("..xx.xx.."), SCRIPT).is_empty());
    }

    #[test]
    fn four_free_samples_do_not_release_five_do() {
        assert_eq!(event_samples(&pattern("xxx....xxx"), SCRIPT), vec![2]);
        assert_eq!(event_samples(&pattern("xxx.....xxx"), SCRIPT), vec![2, 10]);
    }

    #[test]
    fn zero_distance_is_no_contact() {
        assert!(event_samples(&[0.0, 0.0, 0.0, 0.0], SCRIPT).is_empty());
        assert_eq!(overlap_episodes(&pattern(".xx..x.xxx")), 3);
    }

    mod properties {
        use super::*;
        use proptest::prelude::*;

        /// Overlap (true) / free (false) patterns and a hysteresis.
        fn case() -> impl Strategy<Value = (Vec<bool>, Hysteresis)> {
            (
                proptest::collection::vec(any::<bool>(), 0..80),
                1..6usize,
                1..8usize,
            )
                .prop_map(|(p, enter, exit)| (p, Hysteresis { enter, exit }))
        }

        fn distances(pattern: &[bool]) -> Vec<f64> {
            pattern.iter().map(|&o| if o { -0.01 } else { 0.0 }).collect()
        }

        proptest! {
            #![proptest_config(ProptestConfig { failure_persistence: None, ..ProptestConfig::default() })]
            #[test]
            fn runs_shorter_than_enter_never_count((pattern, h) in case()) {
                let longest = pattern
                    .split(|o| !o)
                    .map(<[bool]>::len)
                    .max()
                    .unwrap_or(0);
                if longest < h.enter {
                    prop_assert!(event_samples(&distances(&pattern), h).is_empty());
                }
            }

            #[test]
            fn events_never_exceed_overlap_episodes((pattern, h) in case()) {
                let d = distances(&pattern);
                let events = event_samples(&d, h);
                prop_assert!(events.len() <= overlap_episodes(&d));
                // Each event is stamped at an overlapping sample that ends a run of `enter`.
                for &k in &events {
                    prop_assert!(k + 1 >= h.enter);
                    prop_assert!(pattern[k + 1 - h.enter..=k].iter().all(|&o| o));
                }
            }
        }
    }
}

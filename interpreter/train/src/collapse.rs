//! Noticing a training that has fallen back to where it started.
//!
//! SigmaRL's best-actor rule reads `episode_reward_mean` alone. When a training collapses the
//! way the randomised twin's did (docs/transfer.md: episodes shortening to a few steps, every
//! one ending in a collision), that mean can stay flat while the policy unlearns, and the rule
//! keeps an actor from the collapse without a word. The learning curve's `collisions` column
//! shows it plainly: a training that has learned collides about half as often as its first
//! iterations or less, and one that collapses climbs back to their level.
//!
//! The rule, over means of [`WINDOW`] consecutive iterations: the first window is the untrained
//! level; the training *has learned* once a window falls to half of it or lower; it *has
//! collapsed* at the first later window back at [`BACK_FRACTION`] of it or higher. Every
//! training shipped with the repository that did not collapse stays below 0.6 of its untrained
//! level once it has learned; the randomised twin's seeds reach 1.3–1.4.

/// Iterations averaged in a window.
pub const WINDOW: usize = 10;

/// The fraction of the untrained level at which a training that has learned counts as collapsed.
pub const BACK_FRACTION: f64 = 0.75;

/// A window of iterations and its mean collisions per iteration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Window {
    /// The first and last iteration of the window.
    pub iterations: (u64, u64),
    /// Mean collisions per iteration over the window.
    pub collisions_per_iteration: f64,
}

/// A collapse: the untrained level, the lowest window before the collapse, and the first window
/// back near the untrained level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Collapse {
    /// The first window (the policy as initialised).
    pub untrained: Window,
    /// The lowest window before the collapse.
    pub learned: Window,
    /// The first window after `learned` at [`BACK_FRACTION`] of the untrained level or higher.
    pub back: Window,
}

impl std::fmt::Display for Collapse {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let show = |w: &Window| {
            format!(
                "{:.0} (iterations {}–{})",
                w.collisions_per_iteration, w.iterations.0, w.iterations.1
            )
        };
        write!(
            f,
            "collisions per iteration are back at {}, {:.0} % of the untrained policy's {}, \
             after falling to {}",
            show(&self.back),
            100.0 * self.back.collisions_per_iteration / self.untrained.collisions_per_iteration,
            show(&self.untrained),
            show(&self.learned),
        )
    }
}

/// The first collapse in `points`, `(iteration, collisions)` in iteration order (a learning
/// curve's `collisions` column, [`crate::curve::column_points`]); `None` while the training
/// has not learned or has not fallen back.
pub fn find(points: &[(f64, f64)]) -> Option<Collapse> {
    let mut watch = Watch::default();
    points
        .iter()
        .find_map(|&(iteration, collisions)| watch.push(iteration, collisions))
}

/// The rule fed one iteration at a time, as a training makes them: it keeps the last
/// [`WINDOW`] iterations and what it has seen so far, so each iteration costs a window's sum
/// however long the curve.
#[derive(Debug, Clone, Default)]
pub struct Watch {
    /// The last [`WINDOW`] `(iteration, collisions)` points, oldest first.
    recent: std::collections::VecDeque<(f64, f64)>,
    /// The first window, once there is one.
    untrained: Option<Window>,
    /// The lowest window since the training learned.
    learned: Option<Window>,
    /// The first collapse, once seen (the watch then stops looking).
    collapse: Option<Collapse>,
}

impl Watch {
    /// Adds one iteration; the collapse if this iteration completes the first window that
    /// shows it, else `None`.
    pub fn push(&mut self, iteration: f64, collisions: f64) -> Option<Collapse> {
        if self.collapse.is_some() {
            return None;
        }
        if self.recent.len() == WINDOW {
            self.recent.pop_front();
        }
        self.recent.push_back((iteration, collisions));
        if self.recent.len() < WINDOW {
            return None;
        }
        let window = Window {
            iterations: (self.recent[0].0 as u64, self.recent[WINDOW - 1].0 as u64),
            collisions_per_iteration: self.recent.iter().map(|p| p.1).sum::<f64>() / WINDOW as f64,
        };
        let Some(untrained) = self.untrained else {
            self.untrained = Some(window);
            return None;
        };
        // An untrained policy that never collides has nothing to fall back to.
        if untrained.collisions_per_iteration <= 0.0 {
            return None;
        }
        let level = window.collisions_per_iteration / untrained.collisions_per_iteration;
        match self.learned {
            Some(low) if level >= BACK_FRACTION => {
                self.collapse = Some(Collapse {
                    untrained,
                    learned: low,
                    back: window,
                });
                return self.collapse;
            }
            Some(low) if window.collisions_per_iteration < low.collisions_per_iteration => {
                self.learned = Some(window)
            }
            None if level <= 0.5 => self.learned = Some(window),
            _ => {}
        }
        None
    }

    /// The first collapse seen so far.
    pub fn collapse(&self) -> Option<Collapse> {
        self.collapse
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(values: impl IntoIterator<Item = f64>) -> Vec<(f64, f64)> {
        values
            .into_iter()
            .enumerate()
            .map(|(i, v)| ((i + 1) as f64, v))
            .collect()
    }

    #[test]
    fn a_training_that_learns_and_wobbles_has_not_collapsed() {
        // 800 -> 100, a dip to 350 (under 0.75 of 800) and back: at25's seed 1 dips like this.
        let mut values: Vec<f64> = (0..100).map(|i| 800.0 - 7.0 * i as f64).collect();
        values.extend(std::iter::repeat_n(350.0, 30));
        values.extend(std::iter::repeat_n(100.0, 100));
        assert_eq!(find(&curve(values)), None);
    }

    #[test]
    fn the_watch_says_a_collapse_once_at_the_iteration_that_shows_it() {
        let mut values = vec![900.0; 10];
        values.extend(std::iter::repeat_n(150.0, 20));
        values.extend(std::iter::repeat_n(1000.0, 30));
        let points = curve(values);
        let mut watch = Watch::default();
        let said: Vec<(usize, Collapse)> = points
            .iter()
            .enumerate()
            .filter_map(|(i, &(iteration, collisions))| Some((i, watch.push(iteration, collisions)?)))
            .collect();
        assert_eq!(said.len(), 1);
        assert_eq!(Some(said[0].1), find(&points));
        assert_eq!(said[0].1.back.iterations.1, points[said[0].0].0 as u64);
        assert_eq!(watch.collapse(), Some(said[0].1));
    }

    #[test]
    fn a_training_that_never_learns_has_not_collapsed() {
        assert_eq!(find(&curve(std::iter::repeat_n(800.0, 200))), None);
        assert_eq!(find(&curve(std::iter::repeat_n(0.0, 200))), None);
        assert_eq!(find(&curve([5.0; 9])), None);
    }

    #[test]
    fn a_training_back_at_its_untrained_level_has_collapsed_at_the_first_such_window() {
        let mut values = vec![900.0; 10];
        values.extend(std::iter::repeat_n(200.0, 50));
        values.extend(std::iter::repeat_n(150.0, 10));
        values.extend(std::iter::repeat_n(1000.0, 50));
        let collapse = find(&curve(values)).expect("a collapse");
        assert_eq!(collapse.untrained.iterations, (1, 10));
        assert_eq!(collapse.learned.collisions_per_iteration, 150.0);
        assert_eq!(collapse.learned.iterations, (61, 70));
        // Back at 0.75 * 900 = 675: 150 * 4/10 + 1000 * 6/10 = 660 is not, 150 * 3/10 + 1000 * 7/10 = 745 is.
        assert_eq!(collapse.back.iterations, (68, 77));
        assert_eq!(
            collapse.to_string(),
            "collisions per iteration are back at 745 (iterations 68–77), 83 % of the untrained \
             policy's 900 (iterations 1–10), after falling to 150 (iterations 61–70)"
        );
    }

    /// The repository's own trainings: the randomised twin's collapsed, the others did not.
    #[test]
    fn the_shipped_trainings_are_told_apart() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../experiments/policies");
        let collapsed = |folder: &str| {
            let text = std::fs::read_to_string(format!("{root}/{folder}/learning_curve.csv")).unwrap();
            find(&crate::curve::column_points(&text, "collisions"))
        };
        for folder in ["at25/1", "at25/2", "at25/3", "communication/1"] {
            assert_eq!(collapsed(folder), None, "{folder}");
        }
        for seed in 1..=3 {
            assert_eq!(collapsed(&format!("domain-shift/intersection/{seed}")), None);
        }
        for seed in 1..=3 {
            assert_eq!(collapsed(&format!("transfer/sim-mpc/{seed}")), None);
        }
        for seed in 1..=3 {
            assert!(
                collapsed(&format!("transfer/twin-random/{seed}")).is_some(),
                "{seed}"
            );
        }
        let twin = collapsed("transfer/twin-random/1").expect("the randomised twin's collapse");
        // docs/training.md quotes it.
        assert_eq!(
            twin.to_string(),
            "collisions per iteration are back at 600 (iterations 450–459), 76 % of the untrained \
             policy's 790 (iterations 1–10), after falling to 147 (iterations 290–299)"
        );
    }
}

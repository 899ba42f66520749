//! The input delay line of the lab's simulated vehicles (`SimulationVehicle.cxx`,
//! `INPUT_DELAY = 4` steps of 20 ms = 80 ms for throttle and steering alike).
//!
//! Owns a FIFO of commands on a fixed step; knows nothing of what a command means.

use std::collections::VecDeque;

use crate::{SensingError, check_range};

/// Delays commands by a whole number of fixed steps.
///
/// The line starts full of a neutral command (the lab's history arrays start at zero:
/// throttle 0, servo 0), so for the first `delay_steps` steps the neutral command acts.
#[derive(Debug, Clone, PartialEq)]
pub struct ActuationDelay<C> {
    line: VecDeque<C>,
}

impl<C: Copy> ActuationDelay<C> {
    /// A delay of `delay_ms` on steps of `step_s`, rounded to the nearest whole number of
    /// steps (80 ms on 20 ms steps: 4). `delay_ms` must lie in [0, 10000], `step_s` in
    /// (0, 10].
    pub fn new(delay_ms: f64, step_s: f64, neutral: C) -> Result<Self, SensingError> {
        let delay_ms = check_range("delay_ms", delay_ms, 0.0, 10_000.0, "in [0, 10000]")?;
        let step_s = check_range("step_s", step_s, f64::MIN_POSITIVE, 10.0, "in (0, 10]")?;
        let steps = (delay_ms / 1000.0 / step_s).round() as usize;
        Ok(Self {
            line: std::iter::repeat_n(neutral, steps).collect(),
        })
    }

    /// The delay in steps.
    pub fn delay_steps(&self) -> usize {
        self.line.len()
    }

    /// Feed this step's command; returns the command that acts now (the one fed
    /// `delay_steps` steps ago, or `command` itself without delay).
    pub fn push(&mut self, command: C) -> C {
        self.line.push_back(command);
        self.line.pop_front().unwrap_or(command)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delays_by_exactly_n_steps() {
        let mut delay = ActuationDelay::new(80.0, 0.02, (0.0, 0.0)).unwrap();
        assert_eq!(delay.delay_steps(), 4);
        let applied: Vec<_> = (1..=10).map(|k| delay.push((k as f64, -(k as f64)))).collect();
        for (k, out) in applied.iter().enumerate() {
            let step = k + 1;
            let expected = if step <= 4 {
                (0.0, 0.0)
            } else {
                ((step - 4) as f64, -((step - 4) as f64))
            };
            assert_eq!(*out, expected, "step {step}");
        }
    }

    #[test]
    fn zero_delay_passes_commands_through() {
        let mut delay = ActuationDelay::new(0.0, 0.02, 0).unwrap();
        assert_eq!(delay.delay_steps(), 0);
        assert_eq!(delay.push(7), 7);
        assert_eq!(delay.push(8), 8);
    }

    #[test]
    fn delays_round_to_whole_steps() {
        assert_eq!(ActuationDelay::new(70.0, 0.02, 0).unwrap().delay_steps(), 4);
        assert_eq!(ActuationDelay::new(69.0, 0.02, 0).unwrap().delay_steps(), 3);
        assert_eq!(ActuationDelay::new(100.0, 0.1, 0).unwrap().delay_steps(), 1);
    }

    #[test]
    fn invalid_parameters_are_errors() {
        assert!(ActuationDelay::new(-1.0, 0.02, 0).is_err());
        assert!(ActuationDelay::new(f64::NAN, 0.02, 0).is_err());
        assert!(ActuationDelay::new(80.0, 0.0, 0).is_err());
    }
}

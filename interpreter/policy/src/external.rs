//! Policies decided outside cpmx's crates, in the same process: a [`Decider`] (the `cpmx`
//! Python package binds a Python callable as one) gets every agent's observation and state at
//! each step and returns one action per agent. [`ExternalPolicy`] forms the observation as
//! [`crate::MlpPolicy`] does (SigmaRL's design, with its one-step memory of footprint
//! corners), so a network written in another language sees exactly what `mlp:` would.

use std::sync::Arc;

use cpmx_vehicle::Command;

use crate::memory::ObservationMemory;
use crate::observation::{ObservationInput, SigmarlObservation};
use crate::policy::{Policy, PolicyError, check_commands};

/// The values of an agent's state handed to a [`Decider`], in this order: x [m], y [m],
/// yaw [rad], signed speed [m/s], steering [rad].
pub const STATE_FIELDS: [&str; 5] = ["x_m", "y_m", "yaw_rad", "speed_mps", "steering_rad"];

/// One step's decision for all agents.
pub trait Decider: std::fmt::Debug + Send + Sync {
    /// `observations`: `agents × observation_size` values (agent-major; empty when the
    /// policy has no observation design); `states`: `agents × STATE_FIELDS.len()` values;
    /// `actions` receives `agents × 2` values: target speed [m/s] and steering [rad].
    fn decide(
        &self,
        observations: &[f32],
        observation_size: usize,
        states: &[f64],
        actions: &mut [f64],
    ) -> Result<(), String>;
}

/// A [`Policy`] whose decisions a [`Decider`] makes.
#[derive(Debug, Clone)]
pub struct ExternalPolicy {
    decider: Arc<dyn Decider>,
    observation: Option<SigmarlObservation>,
    memory: ObservationMemory,
    states: Vec<f64>,
    actions: Vec<f64>,
}

impl ExternalPolicy {
    /// The same policy drawing its observation's noise (if the design adds any) from `rng`.
    pub fn with_noise_stream(mut self, rng: rand_chacha::ChaCha20Rng) -> Self {
        self.memory.set_noise_stream(rng);
        self
    }

    /// A policy that observes with `observation` (none: states only) and asks `decider`.
    pub fn new(decider: Arc<dyn Decider>, observation: Option<SigmarlObservation>) -> Self {
        ExternalPolicy {
            decider,
            observation,
            memory: ObservationMemory::default(),
            states: Vec::new(),
            actions: Vec::new(),
        }
    }
}

impl Policy for ExternalPolicy {
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
        check_commands(input, out)?;
        let agents = input.agents.len();

        // The observation, with SigmaRL's memory of the previous corners (as `MlpPolicy`).
        let size = self.observation.map_or(0, |o| o.size());
        let observations: &[f32] = match &self.observation {
            Some(o) => self.memory.observe(o, input)?,
            None => &[],
        };

        // The states, then the decision.
        self.states.clear();
        for a in input.agents {
            self.states
                .extend([a.x_m, a.y_m, a.yaw_rad, a.speed_mps, a.steering_rad]);
        }
        self.actions.clear();
        self.actions.resize(agents * 2, 0.0);
        self.decider
            .decide(observations, size, &self.states, &mut self.actions)
            .map_err(PolicyError::External)?;
        for (command, action) in out.iter_mut().zip(self.actions.chunks_exact(2)) {
            if !(action[0].is_finite() && action[1].is_finite()) {
                return Err(PolicyError::External(format!(
                    "returned a non-finite action ({}, {})",
                    action[0], action[1]
                )));
            }
            *command = Command {
                speed_mps: action[0],
                steering_rad: action[1],
            };
        }
        Ok(())
    }

    fn reset(&mut self) {
        self.memory.forget();
    }

    fn fork(&mut self) -> Box<dyn Policy> {
        Box::new(self.clone())
    }
}

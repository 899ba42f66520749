//! SigmaRL's observation over time: the observation of every agent, with each agent's footprint
//! of the previous step remembered (SigmaRL's observation reads the previous corners), one rule
//! for every policy that observes (network, process and Python policies).

use cpmx_vehicle::{Footprint, footprint_corners};
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

use crate::observation::{ObservationError, ObservationInput, SigmarlObservation};

/// The observations of the last step and the footprints they remember. Allocates only when the
/// agent count grows.
#[derive(Debug, Clone, Default)]
pub(crate) struct ObservationMemory {
    observations: Vec<f32>,
    previous_corners: Vec<Footprint>,
    current_corners: Vec<Footprint>,
    /// The stream of the observation's uniform noise, when the design adds noise.
    noise: Option<ChaCha20Rng>,
}

impl ObservationMemory {
    /// Observes every agent with `design` (with the caller's previous corners if given, else
    /// this memory's of the previous call) and remembers this step's corners.
    pub(crate) fn observe(
        &mut self,
        design: &SigmarlObservation,
        input: &ObservationInput<'_>,
    ) -> Result<&[f32], ObservationError> {
        self.observe_into(design, input, None)
    }

    /// [`ObservationMemory::observe`], also writing the agent in each neighbour slot (see
    /// [`SigmarlObservation::observe_all_with_neighbours`]).
    pub(crate) fn observe_with_neighbours(
        &mut self,
        design: &SigmarlObservation,
        input: &ObservationInput<'_>,
        neighbours: &mut [Option<usize>],
    ) -> Result<&[f32], ObservationError> {
        self.observe_into(design, input, Some(neighbours))
    }

    fn observe_into(
        &mut self,
        design: &SigmarlObservation,
        input: &ObservationInput<'_>,
        neighbours: Option<&mut [Option<usize>]>,
    ) -> Result<&[f32], ObservationError> {
        let agents = input.agents.len();
        self.observations.resize(agents * design.size(), 0.0);
        if self.previous_corners.len() != agents {
            self.previous_corners.clear();
        }
        let remembered = (!self.previous_corners.is_empty()).then_some(self.previous_corners.as_slice());
        let observed = ObservationInput {
            previous_corners: input.previous_corners.or(remembered),
            ..*input
        };
        match neighbours {
            Some(neighbours) => {
                design.observe_all_with_neighbours(&observed, &mut self.observations, neighbours)?
            }
            None => design.observe_all(&observed, &mut self.observations)?,
        }
        if design.uniform_noise > 0.0 {
            let rng = self.noise.as_mut().ok_or(ObservationError::NoNoiseStream)?;
            for value in &mut self.observations {
                *value += design.uniform_noise * rng.random::<f32>();
            }
        }
        self.current_corners.resize(agents, Footprint::default());
        for (slot, a) in self.current_corners.iter_mut().zip(input.agents) {
            *slot = footprint_corners(input.vehicle, a.x_m, a.y_m, a.yaw_rad);
        }
        std::mem::swap(&mut self.previous_corners, &mut self.current_corners);
        Ok(&self.observations)
    }

    /// The observations of the last call (`agents * size` values, agent-major).
    pub(crate) fn observations(&self) -> &[f32] {
        &self.observations
    }

    /// Forgets the previous step (a new episode).
    pub(crate) fn forget(&mut self) {
        self.previous_corners.clear();
    }

    /// Draws the observation's noise from `rng` (the run's `observation-noise` stream).
    pub(crate) fn set_noise_stream(&mut self, rng: ChaCha20Rng) {
        self.noise = Some(rng);
    }

    /// A memory that remembers what this one does (for a policy's fork), its noise from a
    /// fresh stream seeded from this one's (so a lookahead does not repeat the run's draws).
    pub(crate) fn remembering(&mut self) -> ObservationMemory {
        ObservationMemory {
            previous_corners: self.previous_corners.clone(),
            noise: self
                .noise
                .as_mut()
                .map(|rng| ChaCha20Rng::seed_from_u64(rng.next_u64())),
            ..ObservationMemory::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::AgentPaths;
    use crate::observation::AgentState;
    use cpmx_vehicle::VehicleParams;

    #[test]
    fn noise_is_uniform_below_its_level_and_drawn_from_the_given_stream() {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = AgentPaths::new([1, 2].map(|id| map.reference_path(id).unwrap()));
        let agents = [0.3, -0.5].map(|x_m| AgentState {
            x_m,
            yaw_rad: 0.1,
            velocity_mps: [0.4, 0.0],
            ..AgentState::default()
        });
        let input = ObservationInput {
            agents: &agents,
            paths: &paths,
            vehicle: &VehicleParams::MU_CAR,
            previous_corners: None,
            neighbours: None,
        };
        let plain = SigmarlObservation::default();
        let noisy = SigmarlObservation {
            uniform_noise: 0.016,
            ..plain
        };
        let clean = ObservationMemory::default()
            .observe(&plain, &input)
            .unwrap()
            .to_vec();
        // Without a stream the noisy design refuses to observe rather than draw from nowhere.
        assert_eq!(
            ObservationMemory::default().observe(&noisy, &input).unwrap_err(),
            ObservationError::NoNoiseStream
        );
        let observe = |seed: u64| {
            let mut memory = ObservationMemory::default();
            memory.set_noise_stream(ChaCha20Rng::seed_from_u64(seed));
            memory.observe(&noisy, &input).unwrap().to_vec()
        };
        let (a, b, c) = (observe(1), observe(1), observe(2));
        assert_eq!(a, b);
        assert_ne!(a, c);
        for (noisy, clean) in a.iter().zip(&clean) {
            let added = noisy - clean;
            assert!((0.0..0.0161).contains(&added), "{added}");
        }
        let mean = a.iter().zip(&clean).map(|(n, c)| n - c).sum::<f32>() / a.len() as f32;
        assert!((0.004..0.012).contains(&mean), "{mean}");
    }
}

//! A training environment's `communication` and `perception` layers: what each agent knows of
//! the others at each step, with the layers' parameters drawn per episode (as the vehicle
//! layers are) from the environment's stream `train/neighbours/<e>`, and the layers' own draws
//! (lost messages, detections, noise) from `train/communication/<e>` and
//! `train/perception/<e>`. Without the layers nothing here exists and the observations are
//! SigmaRL's.

use cpmx_policy::{AgentState, NeighbourViews};
use cpmx_sensing::NeighbourKnowledge;
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{CommunicationLayer, PerceptionLayer};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// The layers a training fidelity puts between the agents (distributions allowed).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct NeighbourLayers {
    pub communication: Option<CommunicationLayer>,
    pub perception: Option<PerceptionLayer>,
}

impl NeighbourLayers {
    /// Whether any layer is given.
    pub fn any(&self) -> bool {
        self.communication.is_some() || self.perception.is_some()
    }
}

/// One environment's layers.
#[derive(Debug, Clone)]
pub(crate) struct EnvNeighbours {
    layers: NeighbourLayers,
    draws: ChaCha20Rng,
    knowledge: NeighbourKnowledge,
}

impl EnvNeighbours {
    /// The layers of environment `env` of a training run with `seed`, or `None` without any.
    pub(crate) fn new(layers: &NeighbourLayers, agents: usize, seed: u64, env: usize) -> Option<Self> {
        if !layers.any() {
            return None;
        }
        let draws = ChaCha20Rng::from_seed(stream_key(seed, &format!("train/neighbours/{env}")));
        let first = Self::draw_layers(layers, &mut draws.clone());
        let knowledge = cpmx_stack::neighbour_knowledge(agents, first.0.as_ref(), first.1.as_ref(), |name| {
            stream_key(seed, &format!("train/{name}/{env}"))
        });
        Some(EnvNeighbours {
            layers: layers.clone(),
            draws,
            knowledge,
        })
    }

    /// The layers with their distributions drawn from `rng`.
    fn draw_layers(
        layers: &NeighbourLayers,
        rng: &mut ChaCha20Rng,
    ) -> (Option<CommunicationLayer<f64>>, Option<PerceptionLayer<f64>>) {
        let mut draw =
            |_: &str, d: &cpmx_spec::model::Distribution, range| cpmx_stack::draw_value(d, range, rng);
        let communication = layers.communication.as_ref().map(|c| c.draw(&mut draw));
        let perception = layers.perception.as_ref().map(|p| p.draw(&mut draw));
        (communication, perception)
    }

    /// A new episode: the layers' parameters drawn again, nothing heard yet.
    pub(crate) fn start_episode(&mut self) {
        let (communication, perception) = Self::draw_layers(&self.layers, &mut self.draws);
        self.knowledge.set_params(
            communication.as_ref().map(cpmx_stack::communication_params),
            perception.as_ref().map(cpmx_stack::perception_params),
        );
    }

    /// What each agent knows of the others at `t_s` into the episode, given their `states`.
    pub(crate) fn observe(&mut self, t_s: f64, states: &[AgentState]) -> &NeighbourViews {
        self.knowledge.step(t_s, states)
    }

    /// Appends the state for a checkpoint.
    pub(crate) fn save(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.draws.get_word_pos().to_le_bytes());
        self.knowledge.save(out);
    }

    /// Restores [`EnvNeighbours::save`] bytes from `bytes[*at..]`.
    pub(crate) fn load(&mut self, bytes: &[u8], at: &mut usize) -> Result<(), String> {
        let pos = bytes
            .get(*at..*at + 16)
            .ok_or("the neighbour layers' state is truncated")?;
        *at += 16;
        self.draws
            .set_word_pos(u128::from_le_bytes(pos.try_into().map_err(|_| "position")?));
        self.knowledge.load(bytes, at)
    }
}

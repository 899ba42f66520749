//! A drawn fidelity's `communication` and `perception` layers as the parameters of
//! `cpmx_sensing::NeighbourKnowledge`, with the random streams they draw from: one rule for
//! `cpmx run` (the sim and twin engines, the lab driver) and `cpmx train`.

use cpmx_sensing::{CommunicationParams, NeighbourKnowledge, PerceptionParams};
use cpmx_spec::model::{CommunicationLayer, PerceptionLayer};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// The communication layer's parameters in seconds (defaults filled in).
pub fn communication_params(layer: &CommunicationLayer<f64>) -> CommunicationParams {
    CommunicationParams {
        latency_s: layer.latency_ms.unwrap_or(0.0) / 1000.0,
        rate_hz: layer.rate_hz,
        drop_probability: layer.drop_probability.unwrap_or(0.0),
        range_m: layer.range_m,
        max_age_s: layer.max_age_ms.map(|ms| ms / 1000.0),
    }
}

/// The perception layer's parameters in radians (defaults filled in; a field of view of
/// 360° or more is all around).
pub fn perception_params(layer: &PerceptionLayer<f64>) -> PerceptionParams {
    PerceptionParams {
        range_m: layer.range_m,
        field_of_view_rad: layer
            .field_of_view_deg
            .filter(|&deg| deg < 360.0)
            .map(f64::to_radians),
        noise_position_m: layer.noise_position_m.unwrap_or(0.0),
        noise_yaw_rad: layer.noise_yaw_rad.unwrap_or(0.0),
        detection_probability: layer.detection_probability.unwrap_or(1.0),
    }
}

/// What `agents` agents know of each other through the layers, drawing from the streams
/// `streams("communication")` and `streams("perception")` (the run's named streams).
pub fn neighbour_knowledge(
    agents: usize,
    communication: Option<&CommunicationLayer<f64>>,
    perception: Option<&PerceptionLayer<f64>>,
    streams: impl Fn(&str) -> [u8; 32],
) -> NeighbourKnowledge {
    NeighbourKnowledge::new(
        agents,
        communication.map(|c| {
            (
                communication_params(c),
                ChaCha20Rng::from_seed(streams("communication")),
            )
        }),
        perception.map(|p| {
            (
                perception_params(p),
                ChaCha20Rng::from_seed(streams("perception")),
            )
        }),
    )
}

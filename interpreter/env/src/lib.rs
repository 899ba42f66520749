//! SigmaRL's training scenario as vectorised environments, apart from the learner: E
//! environments of N agents on a set of reference paths, with SigmaRL's start sampling,
//! whole-environment and single-agent resets, the float32 kinematic bicycle
//! (`cpmx-vehicle`), SigmaRL's observation (`cpmx-policy`) and its reward as explicit terms.
//!
//! This crate owns stepping, rewarding and resetting training environments. It reads no spec
//! and knows no network: the learner hands in actions and gets observations, rewards and done
//! flags back.
//!
//! # Use
//! ```text
//! let paths = cpmx_env::sigmarl_intersection_paths(Path::new("cpm.xml"))?;   // the 24 paths
//! let mut env = VecEnv::new(EnvConfig::default(), &paths, seed)?;           // placed already
//! let obs = env.reset_all();                        // [E][N][obs_dim] f32, flattened
//! let r = env.step(&actions);                       // actions: [E][N][2] (speed, steering)
//! // r.observations (next), r.rewards [E*N], r.done [E] (== r.terminated), r.episode_reward,
//! // r.reward_terms (means), r.collisions, r.resets, r.agents (every term and flag)
//! ```
//! Randomness: environment `e` draws its starts from the ChaCha stream `train/env/<e>` of
//! the seed (`cpmx_spec::matrix::stream_key`), so results do not depend on threads.

mod config;
mod from_spec;
mod neighbours;
mod paths;
mod render;
mod result;
mod reward;
mod stack_world;
mod starts;
mod state;
mod vec_env;

use std::path::Path;

use cpmx_world::{Map, MapError, PathSet, ReferencePath};

pub use config::{
    CentreLineTerm, ConfigError, EnvConfig, NearAgentsTerm, NearBoundaryTerm, Plant, ProgressTerm, Ramp,
    ResetRule, ResetScope, RewardConfig, ScenarioConfig, SpeedTerm, StartRule, SteeringChangeTerm, TimeTerm,
    TtcTerm, VelocityToPointsTerm,
};
pub use cpmx_vehicle::{Walls, cross_properly, rectangle_crosses_segment, rectangles_cross};
pub use from_spec::{config_from_training, training_paths};
pub use neighbours::NeighbourLayers;
pub use paths::{TrainingPath, prepare_paths};
pub use render::{AGENT_COLOURS, RgbImage};
pub use result::{AgentStepInfo, CollisionCounts, ResetCounts, RewardTermMeans, StepResult};
pub use reward::{RewardInput, RewardTerms, decreasing, reward};
pub use stack_world::StackPlant;
pub use starts::{Placement, draw_placement, placement_at};
pub use vec_env::VecEnv;

/// SigmaRL's 24 open intersection paths of the CPM Lab map file at `map_file`
/// (`cpm_scenario_probabilities = [1, 0, 0]`), numbered 0..23 as SigmaRL numbers them.
pub fn sigmarl_intersection_paths(map_file: &Path) -> Result<Vec<ReferencePath>, MapError> {
    let map = Map::load(map_file)?.with_path_set(PathSet::Intersection)?;
    Ok(map.reference_paths().cloned().collect())
}

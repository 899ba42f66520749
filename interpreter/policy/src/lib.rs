//! Policies for cpmx: SigmaRL's observation design, MLP actors of any layer sizes loaded from
//! safetensors or from SigmaRL's PyTorch checkpoints with their output heads, policy processes in any
//! language (`process`), policies decided in the same process by another language (`external`:
//! the Python package's callables), XP-MARL's ranked actors that observe their neighbours'
//! actions, and built-in baselines.
//!
//! This crate owns deciding commands from states. It never steps vehicles, reads specs or
//! computes metrics; its only randomness is the `ChaCha20Rng` a caller hands to [`MlpPolicy`].
//!
//! # How an engine uses it
//!
//! Once per run:
//! - `let paths = AgentPaths::new(ref_paths.iter());` (agent `i` follows `ref_paths[i]`);
//! - build a policy, boxed as `Box<dyn Policy>` if the spec may name either kind:
//!   - `mlp: {weights}` -> `MlpPolicy::from_file(&weights, SigmarlObservation { ..Default::default() },
//!     ActionMode::Mean | ActionMode::Sample, ChaCha20Rng::from_seed(stream_seed))?`
//!     (loading fails with a typed [`ActorError`] naming a missing tensor or a wrong shape or
//!     dtype; `cpmx validate` can call [`check_input_size`] / [`MlpActor::input_size`]);
//!   - `builtin: lane-follow` -> `LaneFollow::new(LaneFollowParams::default())`.
//!
//! Once per policy step, for all agents at once:
//! ```text
//! let input = ObservationInput { agents: &states, paths: &paths, vehicle: &params, previous_corners: None };
//! policy.act(&input, &mut commands)?;   // commands[i]: target speed and steering of agent i
//! ```
//! `states[i]` is an [`AgentState`] (position, yaw, speed, velocity vector as the vehicle
//! model reports it). [`MlpPolicy`] remembers the previous call's footprint corners itself
//! (SigmaRL's one-step lag for agent 0); call [`Policy::reset`] when a run restarts.
//! Everything is preallocated after the first call; the observation, network and head run
//! batched over all agents. [`MlpPolicy::outputs`] gives `loc`, `scale` and the action per
//! agent for recordings.

pub mod action;
pub mod actor;
pub mod external;
pub mod geometry;
pub mod lane_follow;
mod layers;
mod memory;
pub mod observation;
pub mod policy;
pub mod priority;
pub mod process;
pub mod together;
pub mod torch;

pub use action::{ActionHead, ActionMode, ActionOutput, OutputHead};
pub use actor::{Activation, ActorError, ActorWorkspace, MlpActor, MlpLayout};
pub use external::{Decider, ExternalPolicy, STATE_FIELDS};
pub use geometry::{AgentPaths, PreparedPath, Segments};
pub use lane_follow::{LaneFollow, LaneFollowParams};
pub use observation::{
    AgentState, BoundaryCorners, NeighbourView, NeighbourViews, ObservationError, ObservationInput,
    SigmarlObservation,
};
pub use policy::{MlpPolicy, Network, Policy, PolicyError, check_input_size};
pub use priority::{PrioritizedPolicy, Ranking, SlotFilling};
pub use process::{PROTOCOL_VERSION, ProcessConfig, ProcessPolicy};
pub use together::{PolicyCall, SharedPasses};

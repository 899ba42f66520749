//! Policies for cpmx: SigmaRL's observation design, the SigmaRL MLP actor loaded from
//! safetensors, and built-in baselines.

pub mod action;
pub mod actor;
pub mod geometry;
mod kernel;
pub mod observation;
pub mod policy;

pub use action::{ActionHead, ActionMode, ActionOutput};
pub use actor::{ActorError, ActorWorkspace, MlpActor, MlpLayout};
pub use geometry::{AgentPaths, PreparedPath, Segments};
pub use observation::{AgentState, BoundaryCorners, ObservationError, ObservationInput, SigmarlObservation};
pub use policy::{MlpPolicy, Policy, PolicyError, check_input_size};

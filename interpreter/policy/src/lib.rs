//! Policies for cpmx: SigmaRL's observation design, the SigmaRL MLP actor loaded from
//! safetensors, and built-in baselines.

pub mod geometry;
pub mod observation;

pub use geometry::{AgentPaths, PreparedPath, Segments};
pub use observation::{AgentState, BoundaryCorners, ObservationError, ObservationInput, SigmarlObservation};

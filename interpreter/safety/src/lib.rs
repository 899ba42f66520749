//! Safety filters: layers between a policy's action and the vehicle that change the action as
//! little as they can to keep the vehicle safe. [`cbf`] is SigmaRL's control-barrier-function
//! QP of the ITSC 2025 paper (one vehicle against its lane's boundaries, solved with
//! clarabel), on the pseudo-distance of [`pseudo_distance`]; [`agents`] solves a step's
//! vehicles together where rows between them keep them apart (SigmaRL's later centralised QP). The crate computes what a filter
//! does for one vehicle and step; [`layer`] is a fidelity's `safety:` layer as the engines and
//! the training environments run it; [`margins`] evaluates the rows under a joint action
//! without solving (SigmaRL's CBF-informed reward).

pub mod agents;
pub mod cbf;
pub mod layer;
pub mod margins;
pub mod predictor;
pub mod pseudo_distance;
mod qp;

pub use agents::{AgentRows, PairMargin, PairRow, StepOutcome, Vehicle, filter_step};
pub use cbf::{Arithmetic, CbfOutcome, CbfParameters, CbfRow, CbfState, Fallback, Side, filter};
pub use predictor::{MarginPredictor, PredictorError};
pub use pseudo_distance::Boundary;

/// `x` rounded to the nearest `float16` (ties to even), as NumPy and torch round.
pub fn float16(x: f32) -> f32 {
    f32::from(half::f16::from_f32(x))
}

//! Executes cpmx runs: an [`Experiment`] prepared once from a checked spec, one [`Engine`] per
//! kind of fidelity (sim, twin, and the lab driver with its emulator in [`lab`]), the runner
//! that executes a matrix in parallel, and the run folder it writes. Engines produce
//! recordings; metrics are computed from recordings only.

mod check_starts;
mod checks;
mod engine;
mod experiment;
pub mod folder;
mod fresh;
mod groups;
pub mod lab;
mod memo;
mod onnx;
mod pipeline;
mod policies;
mod randomise;
mod replace;
mod runner;
mod safety;
mod sim;
mod starts;
pub mod store;
#[cfg(test)]
mod together_tests;
mod twin;

pub use checks::BuildChecks;
pub use cpmx_stack::{CONTROL_PERIOD_S, GreyBoxMpcModel, VehicleStack};
pub use cpmx_stack::{control_periods, trajectory_points};
pub use engine::{Engine, Operator, RunError, RunInputs, engine_for};
pub use experiment::{
    Experiment, PrepareError, Scoring, footprint_params, load_map, load_map_spec, load_margin_predictors,
    metrics_config, vehicle_params,
};
pub use fresh::FreshRuns;
pub use policies::{NeighbourActionSource, PreparedPolicy, observation};
pub use runner::{RunOptions, RunOutcome, Shard, execute, inputs_hash, measure, measure_recording, simulate};
pub use sim::SimEngine;
pub use starts::{ConfigurationStarts, InitialState, initial_states};
pub use twin::{TwinEngine, planner};

//! The benchmark's metrics (CRA-A, CRA-L, CD, AS) of one run, computed from its recording
//! only, exactly as SigmaRL's evaluation script does (with its variants made explicit), and
//! the statistics that aggregate them over runs.
//!
//! Modules: `config` (parameters), `resample` (time grid), `collision` (signed distances
//! between footprints), `hysteresis` (events), `lane` (own-lane violation tests),
//! `evaluate` (one run), `output` (the serialised result, table formatting), `stats`
//! (aggregation and paired comparisons).
//!
//! Choices where the spec leaves room: `geometry: mtv` is the true signed distance (parry's
//! penetration depth / Euclidean distance), `sigmarl-mtv` the script's corner rule; the
//! CRA-L slack shrinks the footprint (see [`CraLConfig::slack`]). Everything is computed in
//! f64; against the script's float32 arithmetic the reference cases agree exactly in every
//! event and violation sample and within 2.1e-7 relative in every continuous output.
//!
//! This crate never looks inside an engine and never draws an unseeded random number.

pub mod collision;
mod config;
mod evaluate;
pub mod hysteresis;
pub mod lane;
mod output;
pub mod resample;
pub mod stats;

pub use config::{
    CollisionGeometry, CraAConfig, CraLConfig, EventCount, Hysteresis, LaneBoundaries, MetricsConfig,
    Rotate180,
};
pub use evaluate::{PathGeometry, evaluate};
pub use output::{AgentMetrics, PairEvent, RunMetrics, format_float};

/// Why metrics could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricsError {
    /// A parameter is out of its range.
    #[error("metric parameter `{what}` is invalid: {value}")]
    InvalidParameter { what: &'static str, value: f64 },
    /// No agents or no samples (also after `max_steps`).
    #[error("the recording has no samples or no agents")]
    EmptyRecording,
    /// A row does not have one entry per agent (or times and rows differ in number).
    #[error("sample {sample} has {found} entries, expected {expected}")]
    RaggedRecording {
        sample: usize,
        found: usize,
        expected: usize,
    },
    /// Sample times must increase strictly.
    #[error("the recording's sample times do not increase strictly")]
    TimesNotIncreasing,
    /// An agent's reference path is not among those given.
    #[error("agent {agent}: reference path {id} is not in the map")]
    UnknownRefPath { agent: usize, id: usize },
}

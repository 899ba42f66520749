//! Faults `cpmx lab emulate` plays against the lab driver, so that a session in a lab that
//! misbehaves can be rehearsed and replayed: samples lost, late, repeated or out of order on the
//! lab's topics, vehicles that leave the state lists or lose their positioning fixes, a
//! middleware that pauses or restarts, a clock offset, vehicles placed off their starts or
//! with a low battery. The same mapping is a lab fidelity's `faults:` or the file given to
//! `cpmx lab emulate --faults`. The driver (`cpmx run`) ignores it, and it does not enter a
//! run's input hash.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::parameter::Parameter;

/// Faults the emulator plays in every run it serves. Times are seconds of the run's clock from
/// its first tick and may be distributions (`{uniform: [1, 3]}`), drawn per run from the
/// faults' `seed` and the run's seed, so a failing run replays with the same draws.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LabFaults {
    /// Seed of every random draw of the faults (with each run's seed). Default: 0.
    #[serde(default)]
    pub seed: u64,
    /// Faults of single DDS samples, per topic.
    #[serde(default, skip_serializing_if = "TopicFaults::is_empty")]
    pub topics: TopicFaults,
    /// Vehicles that leave the state lists for a while (`for_s`) or for good.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub leave_lists: Vec<ListOutage>,
    /// Vehicles whose positioning fixes stop for a while or for good: their
    /// `IPS_update_age_nanoseconds` grows, they drive on dead reckoning, and their controller
    /// stops them once it passes 3 s.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ips_loss: Vec<VehicleOutage>,
    /// The middleware stops ticking for `for_s`, then resumes. In simulated time the lab's
    /// clock stops with it; in real time the vehicles drive on.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pauses: Vec<Pause>,
    /// The middleware restarts: a new DDS participant, which waits for the planner's
    /// announcements and sends a new start trigger, mid-run.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub restarts: Vec<Restart>,
    /// The emulator's clock runs this far ahead of the driver's (negative: behind) [ms].
    #[serde(default, skip_serializing_if = "is_zero")]
    pub clock_offset_ms: f64,
    /// Vehicles placed off their run's start (the preflight refuses them).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub misplaced: Vec<Misplacement>,
    /// Vehicles that report a low battery voltage.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub low_battery: Vec<LowBattery>,
}

fn is_zero(value: &f64) -> bool {
    *value == 0.0
}

impl LabFaults {
    /// Whether nothing is faulty.
    pub fn is_empty(&self) -> bool {
        self == &LabFaults {
            seed: self.seed,
            ..LabFaults::default()
        }
    }
}

/// Faults of the samples of the topics the emulator writes (`vehicleStateList`,
/// `systemTrigger`) and reads (`vehicleCommandTrajectory`).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TopicFaults {
    /// The middleware's ticks to the planner.
    #[serde(rename = "vehicleStateList", default, skip_serializing_if = "Option::is_none")]
    pub vehicle_state_list: Option<SampleFaults>,
    /// The planner's trajectories to the vehicles.
    #[serde(
        rename = "vehicleCommandTrajectory",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub vehicle_command_trajectory: Option<SampleFaults>,
    /// The start and stop triggers.
    #[serde(rename = "systemTrigger", default, skip_serializing_if = "Option::is_none")]
    pub system_trigger: Option<SampleFaults>,
}

impl TopicFaults {
    /// Whether no topic has faults.
    pub fn is_empty(&self) -> bool {
        self == &TopicFaults::default()
    }

    /// Each topic with faults: its DDS name and its faults.
    pub fn each(&self) -> impl Iterator<Item = (&'static str, &SampleFaults)> {
        [
            ("vehicleStateList", &self.vehicle_state_list),
            ("vehicleCommandTrajectory", &self.vehicle_command_trajectory),
            ("systemTrigger", &self.system_trigger),
        ]
        .into_iter()
        .filter_map(|(name, faults)| Some((name, faults.as_ref()?)))
    }
}

/// What happens to single samples of a topic, each drawn per sample.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SampleFaults {
    /// Probability that a sample is lost.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub drop: f64,
    /// Probability that a sample arrives twice.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub duplicate: f64,
    /// Probability that a sample is held back and arrives after the next one.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub reorder: f64,
    /// Probability that a sample is late by `delay_ms`.
    #[serde(default)]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub delay: f64,
    /// How late a delayed sample is [ms] (a number or a distribution, drawn per sample).
    /// Default: 50.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub delay_ms: Option<Parameter>,
}

/// A restart of the middleware.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Restart {
    /// When [s from the run's first tick] (a number or a distribution drawn per run).
    pub at_s: Parameter,
    /// The probability that a run has this fault (drawn per run). Default: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub probability: Option<f64>,
}

/// A pause of the middleware.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Pause {
    /// When it begins [s from the run's first tick] (a number or a distribution drawn per run).
    pub at_s: Parameter,
    /// How long no tick comes [s] (a number or a distribution drawn per run).
    pub for_s: Parameter,
    /// The probability that a run has this fault (drawn per run). Default: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub probability: Option<f64>,
}

/// A fault of one vehicle for a while or for good.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct VehicleOutage {
    /// The lab's vehicle id (one of the lab fidelity's `vehicle_ids`).
    pub vehicle: u8,
    /// When it begins [s from the run's first tick] (a number or a distribution drawn per run).
    pub at_s: Parameter,
    /// How long it lasts [s] (a number or a distribution drawn per run). Default: for good.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub for_s: Option<Parameter>,
    /// The probability that a run has this fault (drawn per run). Default: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub probability: Option<f64>,
}

/// A vehicle that leaves the state lists.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ListOutage {
    /// The lab's vehicle id (one of the lab fidelity's `vehicle_ids`).
    pub vehicle: u8,
    /// When it leaves [s from the run's first tick] (a number or a distribution drawn per run).
    pub at_s: Parameter,
    /// How long it stays away [s] (a number or a distribution drawn per run). Default: for good.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub for_s: Option<Parameter>,
    /// The probability that a run has this fault (drawn per run). Default: 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 0.0, max = 1.0))]
    pub probability: Option<f64>,
    /// How the lists show it meanwhile. Default: `missing`.
    #[serde(default)]
    pub listed: ListedAs,
}

/// How a state list shows a vehicle whose states do not arrive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ListedAs {
    /// No entry.
    #[default]
    Missing,
    /// A default-constructed entry (all zeros, `create_stamp` 0), as the lab's middleware
    /// lists an id without data.
    Empty,
    /// Its last state again, with its old stamps.
    Stale,
}

/// A vehicle standing off its run's start.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Misplacement {
    /// The lab's vehicle id.
    pub vehicle: u8,
    /// Offset from the start along x and y [m].
    #[serde(default)]
    pub offset_m: [f64; 2],
    /// Heading offset [deg].
    #[serde(default)]
    pub yaw_deg: f64,
}

/// A vehicle whose battery is low.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LowBattery {
    /// The lab's vehicle id.
    pub vehicle: u8,
    /// The voltage it reports [V].
    #[schemars(range(min = 0.0, max = 20.0))]
    pub voltage_v: f64,
}

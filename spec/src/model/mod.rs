//! The experiment language as Rust types: one struct per section of spec-language.md.
//!
//! These types are the contract. Their doc comments become the JSON Schema's descriptions,
//! and serde reads them from a spec whose `stdlib:` references are already expanded (see
//! `crate::resolve`), so a field that takes a preset has the preset's own type here and is
//! marked for the schema with `PresetOr<T>`.

mod experiment;
mod faults;
mod fidelity;
mod metrics;
mod parameter;
mod policy;
mod preset;
mod safety;
mod start;
mod training;

pub use experiment::{
    AfterControlHorizon, MapFile, MapFormat, MapSpec, OnCollision, Planner, RefPathDefinition, Spec,
    SpeedAfterHc, SteeringAfterHc, StopAtPathEnd, Timing, VehicleSpec,
};
pub use faults::{
    LabFaults, ListOutage, ListedAs, LowBattery, Misplacement, Pause, Restart, SampleFaults, TopicFaults,
    VehicleOutage,
};
pub use fidelity::{
    ActuationLayer, ActuationModel, CommunicationLayer, Control, DEFAULT_IPS_AGE_LIMIT_S, DynamicsLayer,
    Fidelity, FollowerSolver, FollowerSpec, GreyBoxModel, IdealKeyword, KinematicKeyword, LabDriver,
    LabFidelity, Misplaced, PerceptionLayer, Preflight, SensingLayer, SensingModel, SimulatedFidelity,
};
pub use metrics::{
    AsSpec, Bootstrap, CdSpec, CollisionCount, CollisionGeometry, Compare, CraASpec, CraLBoundaries,
    CraLSpec, GroupKey, Hysteresis, MetricsSpec, PairedTest, ReportSpec, Statistic,
};
pub use parameter::{
    Distribution, DrawnFidelity, NamedParameter, NormalDistribution, Parameter, ParameterRange,
};
pub use policy::{
    ActionMode, BuiltinPolicy, CheckpointPick, LaneFollowParams, MlpActivation, MlpSpec, NeighbourActions,
    ObservationDesign, ObservationSpec, OnnxSpec, OutputHead, PolicySpec, PriorityKeyword, PrioritySpec,
    ProcessSpec, SigmarlPriority, SigmarlTag, TrainedActor, TrainedChoice,
};
pub use preset::PresetOr;
pub use safety::{CbfAgents, CbfFilter, CbfWeights, SafetyLayer};
pub use start::{
    AgentStart, DEFAULT_OFF_ROAD_TOLERANCE_M, ExplicitConfiguration, FromPoses, FromPosesSpec, FromRuns,
    FromRunsSpec, InitialConfiguration, Pose, SampleDraw, SamplePlacement, SampleSpec, SampledStarts,
};
pub use training::{
    Activation, AlgorithmSpec, CbfMarginsSpec, CentreLineSpec, KeptActors, Lookahead, MappoSpec,
    NearAgentsSpec, NearBoundarySpec, NetworkSpec, PathSetName, ProgressSpec, RampShape, ResetScopeName,
    RewardSpec, SpeedSpec, SteeringChangeSpec, TimeSpec, TrainingFidelities, TrainingReset, TrainingScenario,
    TrainingSpec, TrainingStart, TtcSpec, ValueLoss, VelocityToPointsSpec,
};

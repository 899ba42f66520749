//! The CPM Lab's middleware for cpmx: the lab's DDS message types with byte-exact XCDR1
//! encoding, its topics, domains and QoS, and a pure-Rust DDS transport (rustdds) that
//! the lab driver (`driver: cpm-dds`) and `cpmx lab emulate` share.
//!
//! Modules: `messages` (IDL types, CDR encode/decode), `topics` (names, type names,
//! domains, QoS profiles), `transport` (participant, typed readers and writers), `error`.
//!
//! This crate moves lab messages; it knows nothing of ticks, planners, engines or metrics.

mod error;
pub mod messages;
pub mod topics;
mod transport;

pub use error::LabError;
pub use messages::{
    Header, KeyedLabMessage, LabMessage, PathPoint, Pose2D, ReadyStatus, StopRequest, SystemTrigger,
    TimeStamp, TrajectoryPoint, UnkeyedLabMessage, VehicleCommandDirect, VehicleCommandPathTracking,
    VehicleCommandSpeedCurvature, VehicleCommandTrajectory, VehicleObservation, VehicleState,
    VehicleStateList, decode_cdr, encode_cdr,
};
pub use topics::{MAX_DOMAIN_ID, QosProfile, TopicDef};
pub use transport::{DiscoveryConfig, KeyedReader, KeyedWriter, LabParticipant, Reader, Writer};

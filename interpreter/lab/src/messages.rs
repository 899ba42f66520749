//! The CPM Lab's DDS message types, mirrored field for field from the lab's IDL
//! (`cpm_lib/dds_idl/*.idl`, RTI Connext 6.0) so that rustdds' CDR serializer produces
//! the XCDR1 bytes an RTI peer writes and expects.
//!
//! Field order is the wire order and must never change; field names are the IDL names
//! (snake_cased where the IDL is not) so a reader can compare them with the lab's IDL —
//! units are therefore in the doc comments, not in the names. Integer widths follow the
//! IDL: `octet` → `u8`, `long` → `i32`, `unsigned long long` → `u64`, `double` → `f64`,
//! `boolean` → `bool`, `string` → `String`, `sequence<T>` → `Vec<T>`.
//!
//! Types marked `//@key` in the IDL implement rustdds' [`Keyed`] with the key
//! `vehicle_id: u8`, as the lab keys its instances. [`encode_cdr`] and [`decode_cdr`] give
//! the exact body bytes (after the 4-byte encapsulation header) that go on the wire.
//!
//! This module owns the wire shape only; it does not know topics, QoS or participants.

use rustdds::{CDRDeserializerAdapter, CDRSerializerAdapter, Keyed, RepresentationIdentifier, no_key};
use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::error::LabError;

/// A lab message type: serialisable as XCDR1 and registered under a DDS type name.
pub trait LabMessage: Serialize + DeserializeOwned + Clone + Send + 'static {
    /// The type name the lab's `rtiddsgen` code registers (the bare IDL struct name).
    const TYPE_NAME: &'static str;
}

/// A keyed lab message: one DDS instance per vehicle, keyed by the IDL's `vehicle_id`.
pub trait KeyedLabMessage: LabMessage + Keyed<K = u8> {}

/// An unkeyed lab message: a `NO_KEY` topic with a single instance.
pub trait UnkeyedLabMessage: LabMessage {}

/// IDL `TimeStamp`: a point in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize)]
pub struct TimeStamp {
    /// Nanoseconds since 1970-01-01 UTC (`CLOCK_REALTIME`), or the simulated clock.
    pub nanoseconds: u64,
}

impl TimeStamp {
    /// The stamp `u64::MAX` that a `SystemTrigger` uses to mean "stop".
    pub const STOP: TimeStamp = TimeStamp {
        nanoseconds: u64::MAX,
    };
}

/// IDL `Header`: when a sample was made and from when a receiver may use it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Header {
    /// Creation time of the sample.
    pub create_stamp: TimeStamp,
    /// The receiver may use the sample only at or after this time.
    pub valid_after_stamp: TimeStamp,
}

/// IDL `Pose2D`: a planar pose in the lab's map frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2D {
    /// Position x in metres.
    pub x: f64,
    /// Position y in metres.
    pub y: f64,
    /// Heading in radians, counter-clockwise from +x.
    pub yaw: f64,
}

/// IDL `VehicleObservation` (key `vehicle_id`): a pose measured by the indoor positioning
/// system (topic `vehicleObservation`), or a simulated vehicle's ground truth
/// (topic `vehiclePoseSimulated`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleObservation {
    /// The observed vehicle.
    pub vehicle_id: u8,
    /// Stamps; the IPS sets `create = valid_after = camera frame time`.
    pub header: Header,
    /// The observed pose.
    pub pose: Pose2D,
}

/// IDL `VehicleState` (key `vehicle_id`): the vehicle's calibrated sensor data and fused
/// pose, published at 50 Hz.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleState {
    /// The sending vehicle.
    pub vehicle_id: u8,
    /// Stamps; vehicles set `valid_after = create + 60 ms`.
    pub header: Header,
    /// Pose fused from IMU, odometer and IPS.
    pub pose: Pose2D,
    /// Nanoseconds since the last IPS pose update (IDL `IPS_update_age_nanoseconds`);
    /// above 10 s the pose is unreliable.
    pub ips_update_age_nanoseconds: u64,
    /// Odometer distance in metres.
    pub odometer_distance: f64,
    /// Forward acceleration in m/s².
    pub imu_acceleration_forward: f64,
    /// Leftward acceleration in m/s².
    pub imu_acceleration_left: f64,
    /// Upward acceleration in m/s².
    pub imu_acceleration_up: f64,
    /// Unfiltered integrated gyro yaw in radians.
    pub imu_yaw: f64,
    /// Yaw rate in rad/s.
    pub imu_yaw_rate: f64,
    /// Odometer speed in m/s.
    pub speed: f64,
    /// Battery voltage in volts.
    pub battery_voltage: f64,
    /// Motor current in amperes.
    pub motor_current: f64,
    /// Throttle the mid-level controller just applied, in [-1, 1].
    pub motor_throttle: f64,
    /// Steering servo command just applied, in [-1, 1] (1 = full left).
    pub steering_servo: f64,
    /// False for the lab's simulated vehicles.
    pub is_real: bool,
}

/// IDL `VehicleStateList` (no key): the middleware's per-period tick to the planner.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleStateList {
    /// The tick's time in nanoseconds; planners use it instead of their own clock.
    pub t_now: u64,
    /// The middleware period in milliseconds.
    pub period_ms: u64,
    /// Newest state per active vehicle (default-constructed entries for vehicles without
    /// data: consumers must filter on `create_stamp`).
    pub state_list: Vec<VehicleState>,
    /// Newest IPS observation per active vehicle (same default-entry rule).
    pub vehicle_observation_list: Vec<VehicleObservation>,
    /// The vehicle ids the middleware serves (IDL `sequence<long>`).
    pub active_vehicle_ids: Vec<i32>,
}

/// IDL `TrajectoryPoint`: one timed point of a Hermite reference trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TrajectoryPoint {
    /// The time of the point.
    pub t: TimeStamp,
    /// Position x in metres.
    pub px: f64,
    /// Position y in metres.
    pub py: f64,
    /// Velocity x in m/s.
    pub vx: f64,
    /// Velocity y in m/s.
    pub vy: f64,
}

/// IDL `VehicleCommandTrajectory` (key `vehicle_id`): a reference trajectory for one
/// vehicle's on-board MPC.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleCommandTrajectory {
    /// The commanded vehicle.
    pub vehicle_id: u8,
    /// Stamps; the command becomes active at `valid_after_stamp`.
    pub header: Header,
    /// The points; one message must cover its whole active window.
    pub trajectory_points: Vec<TrajectoryPoint>,
}

/// IDL `PathPoint`: a pose on a path with its arc length.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PathPoint {
    /// The pose.
    pub pose: Pose2D,
    /// Arc length from the first point in metres.
    pub s: f64,
}

/// IDL `VehicleCommandPathTracking` (key `vehicle_id`): a closed path and a speed.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleCommandPathTracking {
    /// The commanded vehicle.
    pub vehicle_id: u8,
    /// Stamps.
    pub header: Header,
    /// The path (≥ 2 points, `s[0] = 0`, strictly increasing `s`, closed).
    pub path: Vec<PathPoint>,
    /// Speed in m/s.
    pub speed: f64,
}

/// IDL `VehicleCommandSpeedCurvature` (key `vehicle_id`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleCommandSpeedCurvature {
    /// The commanded vehicle.
    pub vehicle_id: u8,
    /// Stamps.
    pub header: Header,
    /// Speed in m/s.
    pub speed: f64,
    /// Curvature in 1/m.
    pub curvature: f64,
}

/// IDL `VehicleCommandDirect` (key `vehicle_id`): raw actuator commands.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct VehicleCommandDirect {
    /// The commanded vehicle.
    pub vehicle_id: u8,
    /// Stamps.
    pub header: Header,
    /// Throttle in [-1, 1] (1 full forward, 0 brake, -1 full reverse).
    pub motor_throttle: f64,
    /// Steering servo in [-1, 1] (1 full left).
    pub steering_servo: f64,
}

/// IDL `ReadyStatus` (no key): a participant announces it is ready (e.g. `hlc_<id>`).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ReadyStatus {
    /// The sender, e.g. `hlc_3`.
    pub source_id: String,
    /// Next expected trigger time (simulated time), arbitrary in real time.
    pub next_start_stamp: TimeStamp,
}

/// IDL `SystemTrigger` (no key): start (`next_start`) or stop ([`TimeStamp::STOP`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct SystemTrigger {
    /// Start time of the run or next step; `u64::MAX` stops.
    pub next_start: TimeStamp,
}

impl SystemTrigger {
    /// Whether this trigger stops the run.
    pub fn is_stop(&self) -> bool {
        self.next_start == TimeStamp::STOP
    }
}

/// IDL `StopRequest` (key `vehicle_id`): a planner asks the control center to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct StopRequest {
    /// The vehicle whose planner asks to stop.
    pub vehicle_id: u8,
}

/// Implements [`LabMessage`] with the IDL struct name as type name.
macro_rules! lab_message {
    ($($ty:ident),* $(,)?) => {$(
        impl LabMessage for $ty {
            const TYPE_NAME: &'static str = stringify!($ty);
        }
    )*};
}

/// Implements [`Keyed`] on `vehicle_id` and [`KeyedLabMessage`].
macro_rules! keyed_by_vehicle_id {
    ($($ty:ident),* $(,)?) => {$(
        impl Keyed for $ty {
            type K = u8;
            fn key(&self) -> u8 {
                self.vehicle_id
            }
        }
        impl KeyedLabMessage for $ty {}
    )*};
}

lab_message!(
    VehicleObservation,
    VehicleState,
    VehicleStateList,
    VehicleCommandTrajectory,
    VehicleCommandPathTracking,
    VehicleCommandSpeedCurvature,
    VehicleCommandDirect,
    ReadyStatus,
    SystemTrigger,
    StopRequest,
);

keyed_by_vehicle_id!(
    VehicleObservation,
    VehicleState,
    VehicleCommandTrajectory,
    VehicleCommandPathTracking,
    VehicleCommandSpeedCurvature,
    VehicleCommandDirect,
    StopRequest,
);

impl UnkeyedLabMessage for VehicleStateList {}
impl UnkeyedLabMessage for ReadyStatus {}
impl UnkeyedLabMessage for SystemTrigger {}

/// The XCDR1 little-endian body of `value` (without the encapsulation header), exactly as
/// rustdds puts it on the wire.
pub fn encode_cdr<T: LabMessage>(value: &T) -> Result<Vec<u8>, LabError> {
    <CDRSerializerAdapter<T> as no_key::SerializerAdapter<T>>::to_bytes(value)
        .map(|bytes| bytes.to_vec())
        .map_err(|source| LabError::Encode {
            type_name: T::TYPE_NAME,
            reason: source.to_string(),
        })
}

/// Decodes an XCDR1 little-endian body (without the encapsulation header), as rustdds'
/// readers do.
pub fn decode_cdr<T: LabMessage>(body: &[u8]) -> Result<T, LabError> {
    <CDRDeserializerAdapter<T> as no_key::DeserializerAdapter<T>>::from_bytes(
        body,
        RepresentationIdentifier::CDR_LE,
    )
    .map_err(|source| LabError::Decode {
        type_name: T::TYPE_NAME,
        reason: source.to_string(),
    })
}

#[cfg(test)]
mod tests;

//! One simulated µCar with the lab's on-board stack, apart from what drives it: the plant
//! (`plants.rs`: the kinematic bicycle of sim-mpc or the lab's grey-box model of the twin), the
//! actuation delay, on-car sensing and the 50 Hz MPC trajectory follower (`stack.rs`); several vehicles' steps with their MPCs
//! solved together in SIMD lanes (`together.rs`). The twin
//! engine drives several from the planner, `cpmx lab emulate` from trajectories received over
//! DDS, `cpmx train` in a `control: trajectory` fidelity; none owns the vehicle. Also here: how
//! plans are timed for the vehicles on their nanosecond clock (`timing.rs`) and how a
//! randomised fidelity is drawn (`randomise.rs`) and what its `communication` and `perception`
//! layers let agents know of each other (`neighbours.rs`), one rule for every driver of the
//! vehicles.

mod neighbours;
mod plants;
mod randomise;
mod stack;
mod stops;
mod timing;
mod together;

pub use neighbours::{communication_params, neighbour_knowledge, perception_params};
pub use plants::GreyBoxMpcModel;
pub use randomise::{draw_fidelity, draw_value};
pub use stack::{
    CONTROL_PERIOD_NS, CONTROL_PERIOD_S, NOMINAL_BATTERY_V, STATE_VALID_AFTER_NS, STATE_VALID_AFTER_S,
    StampedState, VehicleStack,
};
pub use stops::FollowerStops;
pub use timing::{
    DecisionSchedule, RUN_START_NS, VEHICLE_LEAD_NS, VEHICLE_LEAD_S, anchor_ns, anchored_time_ns,
    control_periods, duration_ns, max_state_age_ns, trajectory_points,
};
pub use together::step_together;

/// Where one agent starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialState {
    pub ref_path: usize,
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    pub speed_mps: f64,
}

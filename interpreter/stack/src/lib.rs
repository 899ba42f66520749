//! One simulated µCar with the lab's on-board stack, apart from what drives it: the plant
//! (`plants.rs`: the kinematic bicycle of sim-mpc or the lab's grey-box model of the twin), the
//! actuation delay, on-car sensing and the 50 Hz MPC trajectory follower (`stack.rs`). The twin
//! engine drives several from the planner, `cpmx lab emulate` from trajectories received over
//! DDS; neither owns the vehicle, so anything else that needs the lab's vehicles in the loop can
//! use them too.

mod plants;
mod stack;

pub use plants::GreyBoxMpcModel;
pub use stack::{CONTROL_PERIOD_S, STATE_VALID_AFTER_S, StampedState, VehicleStack};

/// Where one agent starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InitialState {
    pub ref_path: usize,
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    pub speed_mps: f64,
}

//! Vehicle-side trajectory follower: the CPM Lab's mid-level controller in trajectory mode.
//!
//! A planner sends timed reference trajectories ([`TrajectoryCommand`], stamps in integer
//! nanoseconds as the lab's messages carry them); every 20 ms the [`Follower`] picks the newest
//! valid one, applies the lab's stop rules and asks the [`Mpc`] for the plant input, found by
//! the lab's 20 warm-started gradient steps ([`Solver::Gradient`], what [`MpcConfig::lab`]
//! selects) or by an exact QP ([`Solver::Qp`], clarabel). The MPC keeps the lab's input
//! history, also across rejections (`mpc.rs`), and samples its reference on the lab's
//! nanosecond window (`window.rs`). It works over any [`Model`]; [`BicycleModel`] adapts
//! `cpmx_vehicle::KinematicBicycle`.
//!
//! This crate owns following a trajectory. It never steps the plant, estimates states,
//! plans trajectories or draws random numbers.
//!
//! ```text
//! let model = BicycleModel { bicycle: KinematicBicycle::new(VehicleParams::MU_CAR) };
//! let mut follower = Follower::new(Mpc::new(model, MpcConfig::lab(BICYCLE_MOVE_WEIGHTS)), FollowerConfig::default());
//! follower.receive(TrajectoryCommand { create_stamp_ns, valid_after_ns, trajectory });
//! let out = follower.control(t_now_ns, &StateEstimate { state, ips_update_age_ns: 0 });
//! // apply BicycleModel::to_command(&out.input) for 20 ms; out.status says Following / Stopped(reason)
//! ```

mod follower;
mod gradient;
mod lanes;
mod model;
mod mpc;
mod qp;
mod trajectory;
mod window;

pub use follower::{
    Follower, FollowerConfig, MAX_PENDING_COMMANDS, Output, StateEstimate, Status, StopReason,
    TrajectoryCommand,
};
pub use gradient::solve as solve_one;
pub use gradient::{
    GRADIENT_ITERATIONS, GradientResult, LEARNING_RATE, MOMENTUM_RATE, Prediction, RESET_VALUE,
    ScalarPrediction, StepJacobians, WarmStart,
};
pub use lanes::{LaneJob, LanesPrediction, WIDEST_LANES, solve_lanes, solve_together};
pub use model::{
    BicycleModel, Computed, HELD_TERMS, Held, InputLimits, LOW_SPEED_MPS, MODEL_NUMBERS, Model, RealModel,
    as_matrices, unwrap_near,
};
pub use mpc::{
    BICYCLE_MOVE_WEIGHTS, Begun, CONTROL_MOVES, LAB_MOVE_WEIGHTS, Mpc, MpcConfig, PREDICTION_STEPS, Pending,
    Problem, Rejection, Solution, Solver,
};
pub use qp::FEEDFORWARD_PULL;
pub use trajectory::{Trajectory, TrajectoryError, TrajectoryPoint, TrajectorySample, seconds_from_ns};
pub use window::{prediction_window_ns, sample_time_ns};

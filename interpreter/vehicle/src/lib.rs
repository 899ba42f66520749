//! Vehicle models: the kinematic bicycle exactly as SigmaRL integrates it (and as VMAS moved it
//! in SigmaRL 1.2.0), the CPM Lab's identified grey-box µCar, and the rectangular footprint that
//! observations and metrics share.
//!
//! This crate owns vehicle parameters, state and one integration step. It knows nothing of
//! maps, policies or metrics, and draws no random numbers.

mod bicycle;
mod bicycle_f32;
mod crossing;
mod footprint;
mod greybox;
mod vmas;

pub use bicycle::{BicycleState, Command, KinematicBicycle, Precision, StepOutput};
pub use crossing::{Walls, cross_properly, rectangle_crosses_segment, rectangles_cross};
pub use footprint::{Footprint, footprint_corners};
pub use greybox::{
    GreyBoxDerivative, GreyBoxError, GreyBoxInput, GreyBoxParams, GreyBoxState, GreyBoxStep, GreyBoxVehicle,
    LAB_GREYBOX_PARAMETERS, MAX_SUBSTEPS,
};
pub use vmas::{VMAS_DRAG, VmasMotion, VmasStep};

/// Geometry and limits of a vehicle (SigmaRL's `AGENTS`; the CPM Lab µCar at 1:18).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VehicleParams {
    /// Overall length of the body [m].
    pub length_m: f64,
    /// Overall width of the body [m].
    pub width_m: f64,
    /// Distance between the axles [m].
    pub wheelbase_m: f64,
    /// Distance from the centre of gravity to the rear axle [m] (`l_r`).
    pub rear_axle_m: f64,
    /// Steering limit [rad], symmetric.
    pub max_steering_rad: f64,
    /// Steering-rate limit [rad/s], symmetric.
    pub max_steering_rate_rad_s: f64,
    /// Acceleration range [m/s^2] (min, max).
    pub accel_mps2: (f64, f64),
    /// Speed command limit [m/s], symmetric (SigmaRL never applies its `min_speed`).
    pub max_speed_mps: f64,
}

impl VehicleParams {
    /// The CPM Lab µCar as SigmaRL's training scenario defines it.
    pub const MU_CAR: VehicleParams = VehicleParams {
        length_m: 0.22,
        width_m: 0.107,
        wheelbase_m: 0.15,
        rear_axle_m: 0.075,
        max_steering_rad: 0.541_052_04,
        max_steering_rate_rad_s: std::f64::consts::FRAC_PI_2,
        accel_mps2: (-5.0, 5.0),
        max_speed_mps: 1.0,
    };
}

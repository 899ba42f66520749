//! States between the lab's `VehicleState` and the planner's kinematic bicycle (the paper's
//! §Observation): position and yaw pass unchanged, the normalised steering servo is
//! denormalised with the vehicle's steering limit, and the speed becomes a velocity through
//! the bicycle's slip angle. The emulator uses the inverse map to report its vehicles.

use cpmx_lab::{Header, Pose2D, TimeStamp, VehicleState};
use cpmx_recording::AgentSample;
use cpmx_vehicle::{BicycleState, KinematicBicycle, VehicleParams};

/// The planner's state of a vehicle the lab reports, or `None` when the report is not
/// finite (a broken sample counts as missing).
///
/// σ = σ_max · `steering_servo` (the servo clipped to [-1, 1]); the speed is the odometer
/// speed, from which the planner's bicycle derives the velocity
/// `v·[cos(ψ + β), sin(ψ + β)]` with β = atan(l_r / l_wb · tan σ).
pub fn policy_state(state: &VehicleState, vehicle: &VehicleParams) -> Option<BicycleState> {
    let values = [
        state.pose.x,
        state.pose.y,
        state.pose.yaw,
        state.speed,
        state.steering_servo,
    ];
    if values.iter().any(|v| !v.is_finite()) {
        return None;
    }
    Some(BicycleState {
        x_m: state.pose.x,
        y_m: state.pose.y,
        yaw_rad: state.pose.yaw,
        speed_mps: state.speed,
        steering_rad: vehicle.max_steering_rad * state.steering_servo.clamp(-1.0, 1.0),
    })
}

/// What the run records of a reported state: the pose (yaw wrapped to (-π, π]), the velocity
/// through the slip angle and the steering angle.
pub fn recorded_sample(state: &BicycleState, vehicle: &VehicleParams) -> AgentSample {
    AgentSample {
        x_m: state.x_m,
        y_m: state.y_m,
        yaw_rad: cpmx_sensing::wrap_angle_rad(state.yaw_rad),
        velocity_mps: KinematicBicycle::new(*vehicle).velocity_mps(state),
        steering_rad: state.steering_rad,
    }
}

/// The lab's `VehicleState` of a simulated vehicle that reported `reported`, stamped
/// `create_ns` and valid from `valid_after_ns` (the lab's vehicles: create + 60 ms): pose,
/// odometer speed and the steering servo σ / σ_max; sensor fields the planner does not read
/// stay zero.
pub fn lab_state(
    vehicle_id: u8,
    reported: &BicycleState,
    create_ns: u64,
    valid_after_ns: u64,
    vehicle: &VehicleParams,
) -> VehicleState {
    let servo = servo_of(reported.steering_rad, vehicle.max_steering_rad);
    VehicleState {
        vehicle_id,
        header: Header {
            create_stamp: TimeStamp {
                nanoseconds: create_ns,
            },
            valid_after_stamp: TimeStamp {
                nanoseconds: valid_after_ns,
            },
        },
        pose: Pose2D {
            x: reported.x_m,
            y: reported.y_m,
            yaw: reported.yaw_rad,
        },
        speed: reported.speed_mps,
        steering_servo: servo,
        is_real: false,
        ..VehicleState::default()
    }
}

/// The servo in [-1, 1] for `steering_rad`: σ / σ_max, nudged by an ulp where that makes
/// the driver's σ_max · servo give back `steering_rad` exactly (for almost every angle), so
/// that the emulator's reports reach the planner as the twin engine's planner sees them.
fn servo_of(steering_rad: f64, max_steering_rad: f64) -> f64 {
    if max_steering_rad.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) || !steering_rad.is_finite() {
        return 0.0;
    }
    let servo = (steering_rad / max_steering_rad).clamp(-1.0, 1.0);
    [servo, servo.next_up(), servo.next_down()]
        .into_iter()
        .find(|s| (-1.0..=1.0).contains(s) && max_steering_rad * s == steering_rad)
        .unwrap_or(servo)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mu_car() -> VehicleParams {
        VehicleParams {
            length_m: 0.22,
            width_m: 0.107,
            wheelbase_m: 0.15,
            rear_axle_m: 0.075,
            max_steering_rad: 31f64.to_radians(),
            max_steering_rate_rad_s: 90f64.to_radians(),
            accel_mps2: (-5.0, 5.0),
            max_speed_mps: 1.0,
        }
    }

    #[test]
    fn steering_is_denormalised_and_speed_becomes_velocity_through_the_slip_angle() {
        let vehicle = mu_car();
        let lab = VehicleState {
            vehicle_id: 2,
            pose: Pose2D {
                x: 1.0,
                y: 2.0,
                yaw: 0.5,
            },
            speed: 0.6,
            steering_servo: 0.5,
            ..VehicleState::default()
        };
        let state = policy_state(&lab, &vehicle).expect("finite");
        assert_eq!(state.steering_rad, 15.5f64.to_radians());
        assert_eq!(
            (state.x_m, state.y_m, state.yaw_rad, state.speed_mps),
            (1.0, 2.0, 0.5, 0.6)
        );

        // The paper: β = atan(l_r / l_wb · tan σ), v = |v|·(cos, sin)(ψ + β).
        let beta = (0.5 * state.steering_rad.tan()).atan();
        let sample = recorded_sample(&state, &vehicle);
        assert!((sample.velocity_mps[0] - 0.6 * (0.5 + beta).cos()).abs() < 1e-12);
        assert!((sample.velocity_mps[1] - 0.6 * (0.5 + beta).sin()).abs() < 1e-12);
    }

    #[test]
    fn the_emulators_report_maps_back_to_the_same_state() {
        let vehicle = mu_car();
        let reported = BicycleState {
            x_m: 3.0,
            y_m: 0.4,
            yaw_rad: -2.0,
            speed_mps: 0.45,
            steering_rad: -0.2,
        };
        let lab = lab_state(4, &reported, 123, 60_000_123, &vehicle);
        assert_eq!(lab.header.create_stamp.nanoseconds, 123);
        assert_eq!(lab.header.valid_after_stamp.nanoseconds, 60_000_123);
        let back = policy_state(&lab, &vehicle).expect("finite");
        assert_eq!(back.steering_rad, reported.steering_rad);
        let mut exact = 0;
        for k in 0..1000 {
            let steering_rad = -0.5 + f64::from(k) * 1e-3 + 1e-9;
            let report = BicycleState {
                steering_rad,
                ..reported
            };
            let lab = lab_state(4, &report, 123, 60_000_123, &vehicle);
            let back = policy_state(&lab, &vehicle).expect("finite");
            assert!((back.steering_rad - steering_rad).abs() <= 2.0 * f64::EPSILON * steering_rad.abs());
            exact += usize::from(back.steering_rad == steering_rad);
        }
        assert!(exact >= 900, "{exact} of 1000 exact");
        assert_eq!(back.x_m, reported.x_m);
        assert_eq!(back.speed_mps, reported.speed_mps);
    }

    #[test]
    fn non_finite_reports_and_saturated_servos() {
        let vehicle = mu_car();
        let broken = VehicleState {
            speed: f64::NAN,
            ..VehicleState::default()
        };
        assert!(policy_state(&broken, &vehicle).is_none());
        let saturated = VehicleState {
            steering_servo: 3.0,
            ..VehicleState::default()
        };
        let state = policy_state(&saturated, &vehicle).expect("finite");
        assert_eq!(state.steering_rad, vehicle.max_steering_rad);
    }
}

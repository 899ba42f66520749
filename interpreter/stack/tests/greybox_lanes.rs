//! The grey-box MPCs of several vehicles, each with its own identified parameters and battery
//! voltage (the randomised twin), solved together in lanes give each vehicle's own bits: the
//! scalar solve remembers its last power, the lanes compute every one.

use cpmx_follower::{
    LAB_MOVE_WEIGHTS, Model, MpcConfig, Problem, ScalarPrediction, WarmStart, solve_lanes, solve_one,
};
use cpmx_stack::GreyBoxMpcModel;
use cpmx_vehicle::{GreyBoxParams, LAB_GREYBOX_PARAMETERS};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn bits<const N: usize>(values: &[[f64; N]]) -> Vec<u64> {
    values.iter().flatten().map(|v| v.to_bits()).collect()
}

#[test]
fn grey_box_mpcs_in_lanes_give_each_vehicles_bits() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let config = MpcConfig::lab(LAB_MOVE_WEIGHTS);
    let mut vehicles: [GreyBoxMpcModel; 8] = std::array::from_fn(|_| {
        let parameters = LAB_GREYBOX_PARAMETERS.map(|p| p * rng.random_range(0.9..1.1));
        GreyBoxMpcModel::new(GreyBoxParams {
            parameters,
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        })
        .expect("parameters near the lab's")
    });
    let mut lanes_warm: [WarmStart<2>; 8] = std::array::from_fn(|_| WarmStart::reset());
    let mut own_warm = lanes_warm;
    for period in 0..40 {
        for v in &mut vehicles {
            v.set_battery_voltage_v(rng.random_range(7.0..8.2));
        }
        let problems: [Problem<4, 2>; 8] = std::array::from_fn(|_| {
            let (speed, yaw) = (rng.random_range(0.0..1.0), rng.random_range(-3.0f64..3.0));
            let x0 = [
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                yaw,
                speed,
            ];
            let turn = rng.random_range(-2.0..2.0);
            Problem {
                x0,
                reference_m: std::array::from_fn(|k| {
                    let t = 0.05 * (k + 1) as f64;
                    let heading = yaw + turn * t;
                    [
                        x0[0] + speed * t * heading.cos(),
                        x0[1] + speed * t * heading.sin(),
                    ]
                }),
                // Throttles at zero (the motor term's slope), at and beyond the limits.
                previous_input: [
                    [0.0, 1.0, -1.0, 1.3, 0.2][period % 5],
                    rng.random_range(-1.0..1.0),
                ],
            }
        });
        let together = solve_lanes(vehicles.each_ref(), &config, &problems, lanes_warm.each_mut());
        for i in 0..8 {
            let p = &problems[i];
            let alone = solve_one(
                &ScalarPrediction(&vehicles[i]),
                &config,
                &p.x0,
                &p.reference_m,
                &p.previous_input,
                &mut own_warm[i],
            );
            let at = format!("period {period}, vehicle {i}");
            assert_eq!(bits(&together[i].moves), bits(&alone.moves), "{at}: moves");
            assert_eq!(
                together[i].objective.to_bits(),
                alone.objective.to_bits(),
                "{at}: objective"
            );
            assert_eq!(
                bits(&together[i].predicted_m),
                bits(&alone.predicted_m),
                "{at}: positions"
            );
            assert_eq!(
                bits(&lanes_warm[i].u_next),
                bits(&own_warm[i].u_next),
                "{at}: warm start"
            );
            assert_eq!(
                bits(&lanes_warm[i].momentum),
                bits(&own_warm[i].momentum),
                "{at}: momentum"
            );
        }
    }
}

/// The MPC model's steps remember the last few throttles' powers (the delay compensation steps
/// through the last three inputs every decision): each step keeps the bits of the grey-box car's
/// own Euler step, whatever it remembers, at any battery voltage.
#[test]
fn remembered_step_powers_keep_the_euler_steps_bits() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let params = GreyBoxParams {
        parameters: LAB_GREYBOX_PARAMETERS,
        euler_step_s: 0.02,
        battery_voltage_v: 7.8,
    };
    let mut model = GreyBoxMpcModel::new(params).expect("the lab's parameters");
    let car = cpmx_vehicle::GreyBoxVehicle::new(params).expect("the lab's parameters");
    // A history that shifts by one input a decision, with repeats, zero, negative and clamped
    // throttles.
    let inputs: Vec<[f64; 2]> = (0..60)
        .map(|k| match k % 7 {
            0 => [0.0, 0.1],
            1 => [1.7, -0.2],
            _ => [rng.random_range(-1.2..1.2), rng.random_range(-1.0..1.0)],
        })
        .collect();
    for (decision, window) in inputs.windows(3).enumerate() {
        let voltage_v = 7.0 + 0.02 * decision as f64;
        model.set_battery_voltage_v(voltage_v);
        let mut state = [0.1, -0.3, 0.4, rng.random_range(0.0..1.2)];
        for u in window {
            let own = car.euler_step(
                &cpmx_vehicle::GreyBoxState {
                    x_m: state[0],
                    y_m: state[1],
                    yaw_rad: state[2],
                    speed_mps: state[3],
                },
                &cpmx_vehicle::GreyBoxInput {
                    throttle: u[0],
                    steering_servo: u[1],
                    battery_voltage_v: voltage_v,
                },
                0.02,
            );
            let next = model.step(&state, u, 0.02);
            assert_eq!(
                bits(&[next]),
                bits(&[[own.x_m, own.y_m, own.yaw_rad, own.speed_mps]]),
                "decision {decision}, input {u:?}"
            );
            state = next;
        }
    }
}

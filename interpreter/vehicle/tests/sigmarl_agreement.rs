//! Agreement of the kinematic bicycle with SigmaRL's own steps
//! (`shared/reference/dynamics/bicycle_steps.json`, 200 cases).
//!
//! SigmaRL computes in float32. The f32 path matches every value to within one float32
//! ulp (torch evaluates tan/atan/sin/cos with SLEEF, which is not bit-identical to a
//! correctly rounded result); the f64 path to within 7e-7.

use cpmx_vehicle::{BicycleState, Command, KinematicBicycle, Precision, StepOutput, VehicleParams};
use serde_json::Value;

fn cases() -> Vec<Value> {
    let text = cpmx_testdata::read_reference("dynamics/bicycle_steps.json");
    let root: Value = serde_json::from_str(&text).expect("valid JSON");
    root["cases"].as_array().expect("cases").clone()
}

fn num(v: &Value) -> f64 {
    v.as_f64().expect("number")
}

/// A recorded float32 value (shortest decimal) as the exact f32 it denotes.
fn recorded(v: &Value) -> f64 {
    f64::from(num(v) as f32)
}

/// Largest absolute difference per output group over all cases.
#[derive(Debug, Default)]
struct MaxErr {
    state: f64,
    velocity: f64,
    sideslip: f64,
    clamped: f64,
    exact_cases: usize,
}

fn compare(precision: Precision) -> MaxErr {
    let model = KinematicBicycle::new(VehicleParams::MU_CAR);
    let mut err = MaxErr::default();
    let all = cases();
    assert_eq!(all.len(), 200);
    for case in &all {
        let s = &case["state"];
        let state = BicycleState {
            x_m: num(&s["x"]),
            y_m: num(&s["y"]),
            yaw_rad: num(&s["yaw"]),
            speed_mps: num(&s["speed"]),
            steering_rad: num(&s["steering"]),
        };
        let command = Command {
            speed_mps: num(&case["action"]["speed_cmd"]),
            steering_rad: num(&case["action"]["steering_cmd"]),
        };
        let out: StepOutput = model.step_with_precision(&state, command, num(&case["dt"]), precision);

        let n = &case["next_state"];
        let got = out.state;
        let state_err = [
            (got.x_m, &n["x"]),
            (got.y_m, &n["y"]),
            (got.yaw_rad, &n["yaw"]),
            (got.speed_mps, &n["speed"]),
            (got.steering_rad, &n["steering"]),
        ]
        .iter()
        .map(|(g, want)| (g - recorded(want)).abs())
        .fold(0.0, f64::max);
        let vel_err = (0..2)
            .map(|i| (out.velocity_mps[i] - recorded(&case["next_vel"][i])).abs())
            .fold(0.0, f64::max);
        let slip_err = (out.sideslip_rad - recorded(&case["next_sideslip"])).abs();
        let clamped = model.clamp_command(command);
        let clamp_err = match precision {
            // The f32 path clamps f32 values against f32 limits.
            Precision::F32 => {
                let limit = VehicleParams::MU_CAR.max_steering_rad as f32;
                let v = (command.speed_mps as f32).clamp(-1.0, 1.0);
                let d = (command.steering_rad as f32).clamp(-limit, limit);
                (f64::from(v) - recorded(&case["action_clamped"]["speed_cmd"]))
                    .abs()
                    .max((f64::from(d) - recorded(&case["action_clamped"]["steering_cmd"])).abs())
            }
            Precision::F64 => (clamped.speed_mps - num(&case["action_clamped"]["speed_cmd"]))
                .abs()
                .max((clamped.steering_rad - num(&case["action_clamped"]["steering_cmd"])).abs()),
        };
        if state_err == 0.0 && vel_err == 0.0 && slip_err == 0.0 {
            err.exact_cases += 1;
        }
        err.state = err.state.max(state_err);
        err.velocity = err.velocity.max(vel_err);
        err.sideslip = err.sideslip.max(slip_err);
        err.clamped = err.clamped.max(clamp_err);
    }
    eprintln!("{precision:?}: {err:?}");
    err
}

#[test]
fn f32_path_agrees_with_sigmarl_to_one_float32_ulp() {
    let err = compare(Precision::F32);
    // One ulp of a float32 value below 2 (yaw can reach about 4) is at most 2.4e-7; positions,
    // speed and steering are bit-exact in practice.
    assert!(err.state <= 1.2e-7, "state {:e}", err.state);
    assert!(err.velocity <= 6.0e-8, "velocity {:e}", err.velocity);
    assert!(err.sideslip <= 1.5e-8, "sideslip {:e}", err.sideslip);
    assert_eq!(err.clamped, 0.0, "clamped command");
    assert!(err.exact_cases >= 130, "bit-exact cases {}", err.exact_cases);
}

#[test]
fn f64_path_agrees_with_sigmarl_to_float32_round_off() {
    let err = compare(Precision::F64);
    assert!(err.state <= 7.0e-7, "state {:e}", err.state);
    assert!(err.velocity <= 7.0e-7, "velocity {:e}", err.velocity);
    assert!(err.sideslip <= 7.0e-7, "sideslip {:e}", err.sideslip);
    assert_eq!(err.clamped, 0.0, "clamped command");
}

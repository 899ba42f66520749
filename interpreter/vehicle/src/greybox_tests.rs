use super::*;

fn lab() -> GreyBoxVehicle {
    GreyBoxVehicle::new(GreyBoxParams::LAB).expect("lab parameters are valid")
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// The §4 equations written out once more, independently of the model code.
fn by_hand(s: [f64; 4], f: f64, servo: f64, v_batt: f64, h: f64) -> [f64; 4] {
    let p = LAB_GREYBOX_PARAMETERS;
    let d = servo + p[8];
    let speed = p[0] * s[3] * (1.0 + p[1] * d * d);
    let heading = s[2] + p[2] * d + p[9];
    let sign = if f >= 0.0 { 1.0 } else { -1.0 };
    [
        s[0] + h * speed * heading.cos(),
        s[1] + h * speed * heading.sin(),
        s[2] + h * p[3] * s[3] * d,
        s[3] + h * (p[4] * s[3] + (p[5] + p[6] * v_batt) * sign * f.abs().powf(p[7])),
    ]
}

/// State, throttle, servo, voltage [V], Euler step [s], expected state.
type Case = ([f64; 4], f64, f64, f64, f64, [f64; 4]);

#[test]
fn one_euler_step_matches_the_formula_evaluated_by_hand() {
    // (state, throttle, servo, voltage, h, expected; expected values computed with Python).
    let cases: [Case; 4] = [
        (
            [1.0, 2.0, 0.3, 1.5],
            0.5,
            -0.2,
            7.8,
            0.02,
            [
                1.0290502577050793,
                2.0075533741218696,
                0.28207691495424,
                1.5134748055022629,
            ],
        ),
        (
            [0.0; 4],
            1.0,
            0.0,
            7.8,
            0.02,
            [0.0, 0.0, 0.0, 0.19789158000000004],
        ),
        (
            [3.2, 0.4, -2.5, 0.8],
            -0.3,
            1.0,
            7.5,
            0.02,
            [
                3.190807068620035,
                0.3899430218158291,
                -2.441195919491072,
                0.7276967447205364,
            ],
        ),
        (
            [0.5, 3.9, 3.0, -0.4],
            0.0,
            -1.0,
            8.0,
            0.05,
            [
                0.5163857776869066,
                3.8941409230608732,
                3.06891793936384,
                -0.35618544,
            ],
        ),
    ];
    let model = lab();
    for (s, f, servo, v_batt, h, expected) in cases {
        let state = GreyBoxState {
            x_m: s[0],
            y_m: s[1],
            yaw_rad: s[2],
            speed_mps: s[3],
        };
        let input = GreyBoxInput {
            throttle: f,
            steering_servo: servo,
            battery_voltage_v: v_batt,
        };
        let next = model.euler_step(&state, &input, h);
        let got = [next.x_m, next.y_m, next.yaw_rad, next.speed_mps];
        let hand = by_hand(s, f, servo, v_batt, h);
        for i in 0..4 {
            assert!(
                close(got[i], expected[i], 1e-14),
                "case {s:?}: {got:?} vs {expected:?}"
            );
            assert!(close(got[i], hand[i], 1e-14), "case {s:?}: {got:?} vs {hand:?}");
        }
    }
}

#[test]
fn step_substeps_at_the_euler_step() {
    let model = lab();
    let start = GreyBoxState {
        x_m: 1.0,
        y_m: 1.0,
        yaw_rad: 0.5,
        speed_mps: 0.7,
    };
    let input = model.input(0.4, 0.3);

    // 0.1 s is exactly five Euler steps of 20 ms.
    let out = model.step(&start, &input, 0.1).unwrap();
    let mut manual = start;
    let mut odometer_m = 0.0;
    for _ in 0..5 {
        manual = model.euler_step(&manual, &input, 0.02);
        odometer_m += 0.02 * manual.speed_mps;
    }
    assert_eq!(out.state, manual);
    assert!(close(out.odometer_increment_m, odometer_m, 1e-15));
    assert!(close(
        out.yaw_increment_rad,
        manual.yaw_rad - start.yaw_rad,
        1e-15
    ));
    assert_eq!(out.velocity_mps, model.velocity_mps(&manual, 0.3));

    // 0.05 s is two whole steps and one of 10 ms.
    let out = model.step(&start, &input, 0.05).unwrap();
    let two = model.euler_step(&model.euler_step(&start, &input, 0.02), &input, 0.02);
    let expected = model.euler_step(&two, &input, 0.05 - 2.0 * 0.02);
    assert!(close(out.state.x_m, expected.x_m, 1e-15));
    assert!(close(out.state.speed_mps, expected.speed_mps, 1e-15));

    // Zero duration changes nothing.
    let out = model.step(&start, &input, 0.0).unwrap();
    assert_eq!(out.state, start);
    assert_eq!(out.odometer_increment_m, 0.0);
}

#[test]
fn steady_state_speed_at_full_throttle_is_4_52_mps() {
    let model = lab();
    let input = model.input(1.0, 0.0);
    let mut state = GreyBoxState::default();
    for _ in 0..50 {
        state = model.step(&state, &input, 0.2).unwrap().state; // 10 s ≈ 22 time constants
    }
    let analytic = model.steady_state_speed_mps(1.0, 7.8);
    assert!(close(analytic, 4.5166, 1e-4), "{analytic}");
    assert!(close(state.speed_mps, analytic, 1e-6), "{}", state.speed_mps);
    assert!(close(model.steady_state_speed_mps(1.0, 7.5), 4.17, 0.01));
    assert!(close(model.steady_state_speed_mps(1.0, 8.0), 4.75, 0.01));
}

#[test]
fn curvature_at_full_effective_steering_is_3_56_per_metre() {
    let model = lab();
    // δ' = 1 needs the servo at 1 - p9.
    let servo = 1.0 - LAB_GREYBOX_PARAMETERS[8];
    assert!(close(model.effective_steering(servo), 1.0, 1e-15));
    let state = GreyBoxState {
        speed_mps: 1.2,
        ..GreyBoxState::default()
    };
    let d = model.derivative(&state, &model.input(0.0, servo));

    // Per odometer metre (ψ̇ / v): p4.
    let per_odometer_m = d.yaw_rate_rad_s / state.speed_mps;
    assert!(close(per_odometer_m, 3.56, 0.005), "{per_odometer_m}");

    // Per metre travelled in the map frame: p4 / (p1·(1 + p2)) ≈ 4.135, which is what the
    // lab's speed-curvature feed-forward (0.241857 servo per 1/m) assumes.
    let path_speed = d.x_mps.hypot(d.y_mps);
    let per_map_m = d.yaw_rate_rad_s / path_speed;
    assert!(close(per_map_m, 1.0 / 0.241857, 0.002), "{per_map_m}");
}

#[test]
fn standing_car_without_throttle_stays_put() {
    let model = lab();
    let start = GreyBoxState {
        x_m: 2.0,
        y_m: 1.0,
        yaw_rad: 1.0,
        speed_mps: 0.0,
    };
    let out = model.step(&start, &model.input(0.0, 0.7), 1.0).unwrap();
    assert_eq!(out.state, start);
}

#[test]
fn inputs_are_clamped_to_the_unit_interval() {
    let model = lab();
    let state = GreyBoxState {
        speed_mps: 1.0,
        ..GreyBoxState::default()
    };
    let over = model.derivative(&state, &model.input(3.0, -5.0));
    let at = model.derivative(&state, &model.input(1.0, -1.0));
    assert_eq!(over, at);
}

#[test]
fn invalid_parameters_and_durations_are_errors() {
    let mut params = GreyBoxParams::LAB;
    params.parameters[4] = f64::NAN;
    assert!(matches!(
        GreyBoxVehicle::new(params),
        Err(GreyBoxError::Parameter { number: 5, .. })
    ));
    let params = GreyBoxParams {
        euler_step_s: 0.0,
        ..GreyBoxParams::LAB
    };
    assert!(matches!(
        GreyBoxVehicle::new(params),
        Err(GreyBoxError::EulerStep { .. })
    ));
    let params = GreyBoxParams {
        battery_voltage_v: -1.0,
        ..GreyBoxParams::LAB
    };
    assert!(matches!(
        GreyBoxVehicle::new(params),
        Err(GreyBoxError::BatteryVoltage { .. })
    ));

    let model = lab();
    let state = GreyBoxState::default();
    let input = model.input(0.5, 0.0);
    for dt_s in [-0.1, f64::NAN, f64::INFINITY, 1e9] {
        assert!(matches!(
            model.step(&state, &input, dt_s),
            Err(GreyBoxError::Duration { .. })
        ));
    }
}

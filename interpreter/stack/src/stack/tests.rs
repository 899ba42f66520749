use super::*;
use cpmx_follower::StopReason;
use cpmx_spec::model::{ActuationModel, Control, GreyBoxModel, SimulatedFidelity};

const MS: u64 = 1_000_000;

fn twin_without_sensing() -> DrawnFidelity {
    SimulatedFidelity {
        control: Control::Trajectory,
        dynamics: DynamicsLayer::GreyBox(GreyBoxModel {
            parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS,
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        }),
        sensing: None,
        actuation: Some(ActuationLayer::Model(ActuationModel { delay_ms: 80.0 })),
        follower: None,
        communication: None,
        perception: None,
        safety: None,
    }
}

/// A left arc of radius 0.5 m at 0.5 m/s from the origin, heading +x, points every 0.1 s
/// from the run's start.
fn left_arc() -> Vec<TrajectoryPoint> {
    let (speed, radius) = (0.5, 0.5);
    (0..30u64)
        .map(|k| {
            let t = k as f64 * 0.1;
            let a = speed * t / radius;
            TrajectoryPoint {
                t_ns: RUN_START_NS + k * 100 * MS,
                x_m: radius * a.sin(),
                y_m: radius * (1.0 - a.cos()),
                vx_mps: speed * a.cos(),
                vy_mps: speed * a.sin(),
            }
        })
        .collect()
}

fn start() -> InitialState {
    InitialState {
        ref_path: 0,
        x_m: 0.0,
        y_m: 0.0,
        yaw_rad: 0.0,
        speed_mps: 0.5,
    }
}

/// The lab's vehicles report the servo command the MPC has just computed, and the
/// planner reads it as σ = σ_max · servo: not the servo the plant applies 80 ms later, and
/// not the grey-box curvature's angle with its offset p9.
#[test]
fn a_vehicle_reports_its_current_servo_command_as_sigma_max_times_servo() {
    let vehicle = VehicleParams::MU_CAR;
    let mut stack = VehicleStack::new(&twin_without_sensing(), vehicle, &start(), 1, 0).unwrap();
    stack.receive(left_arc(), RUN_START_NS, RUN_START_NS);
    let mut servos = Vec::new();
    for k in 0..10 {
        assert_eq!(
            stack.step(RUN_START_NS + k * CONTROL_PERIOD_NS),
            Status::Following
        );
        let servo = stack.command()[1];
        servos.push(servo);
        let reported = stack.reported_state();
        assert_eq!(
            reported.steering_rad,
            vehicle.max_steering_rad * servo.clamp(-1.0, 1.0)
        );
    }
    // The servo moves into the turn within the delay, so the delayed one would differ.
    assert!(servos[9] > 0.2 && servos[5] > servos[1] + 0.1, "{servos:?}");
    // What is recorded carries the same steering.
    let sample = stack.true_sample();
    assert_eq!(sample.steering_rad, stack.reported_state().steering_rad);
    let speed = sample.velocity_mps[0].hypot(sample.velocity_mps[1]);
    let VehicleStack::GreyBox(v) = &stack else {
        unreachable!("a grey-box vehicle")
    };
    assert!(
        (speed - v.plant.speed_mps(&v.state)).abs() < 1e-12,
        "odometer speed is recorded"
    );
}

/// The twin with the lab's positioning system, losing every frame with `lost`.
fn twin_with_ips(drop_probability: f64) -> DrawnFidelity {
    SimulatedFidelity {
        sensing: Some(SensingLayer::Model(SensingModel {
            rate_hz: 50.0,
            latency_ms: 60.0,
            noise_position_m: 0.002,
            noise_yaw_rad: 0.01,
            drop_probability,
            fusion_gain: 0.3,
        })),
        ..twin_without_sensing()
    }
}

/// Straight along +x at 0.5 m/s, points every 0.1 s for 1.5 s from `from_ns`.
fn straight(from_ns: u64) -> Vec<TrajectoryPoint> {
    (0..16)
        .map(|k| {
            let t_ns = from_ns + k * 100 * MS;
            TrajectoryPoint {
                t_ns,
                x_m: 0.5 * (t_ns - RUN_START_NS) as f64 * 1e-9,
                y_m: 0.0,
                vx_mps: 0.5,
                vy_mps: 0.0,
            }
        })
        .collect()
}

/// Drives 4 s along a fresh straight trajectory every 0.1 s; the statuses and the
/// reported IPS ages of every step.
fn drive_straight(fidelity: &DrawnFidelity) -> (Vec<Status>, Vec<u64>) {
    let mut stack = VehicleStack::new(fidelity, VehicleParams::MU_CAR, &start(), 9, 0).unwrap();
    let (mut statuses, mut ages) = (Vec::new(), Vec::new());
    for k in 0..200 {
        let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS;
        if k % 5 == 0 {
            stack.receive(straight(now_ns), now_ns, now_ns);
        }
        statuses.push(stack.step(now_ns));
        ages.push(
            stack
                .listed_state(now_ns + CONTROL_PERIOD_NS + STATE_VALID_AFTER_NS)
                .ips_update_age_ns,
        );
    }
    (statuses, ages)
}

/// The lab's controller stops a car whose IPS updates are older than 3 s ("Lost IPS
/// position reference"); the age comes from the positioning system, so a car that loses
/// every frame stops 3 s into the run, and one that loses the lab's 1 in 20 never does.
#[test]
fn a_car_that_loses_its_positions_stops_after_3_s() {
    let (statuses, ages) = drive_straight(&twin_with_ips(1.0));
    for (k, status) in (0..).zip(&statuses) {
        // Since the run's start, the last fix: the lab stops above 3 s, not at 3 s.
        let since_start_ns = k * CONTROL_PERIOD_NS;
        let lost = matches!(status, Status::Stopped(StopReason::LostIps { .. }));
        assert_eq!(
            lost,
            since_start_ns > 3_000 * MS,
            "at {since_start_ns} ns: {status:?}"
        );
        assert_eq!(ages[k as usize], since_start_ns + CONTROL_PERIOD_NS);
    }

    let (statuses, ages) = drive_straight(&twin_with_ips(0.05));
    assert!(statuses.iter().all(|s| *s == Status::Following), "{statuses:?}");
    // The start counts as a fix until the first frame arrives (at 80 ms, 60 ms old).
    assert!(
        ages[2..].iter().all(|&a| (60 * MS..200 * MS).contains(&a)),
        "{ages:?}"
    );
    assert!(
        ages.iter().any(|&a| a > 70 * MS),
        "a dropped frame makes the age grow"
    );

    let (_, ages) = drive_straight(&twin_without_sensing());
    assert!(ages.iter().all(|&a| a == 0), "ideal sensing: {ages:?}");
}

/// The middleware lists the newest state whose `valid_after = create + 60 ms` has passed;
/// before the first step, the start.
#[test]
fn the_middleware_lists_states_60_ms_after_their_creation() {
    let vehicle = VehicleParams::MU_CAR;
    let mut stack = VehicleStack::new(&twin_without_sensing(), vehicle, &start(), 1, 0).unwrap();
    let initial = stack.listed_state(RUN_START_NS);
    assert_eq!(initial.create_ns, RUN_START_NS - STATE_VALID_AFTER_NS);
    assert_eq!((initial.state.x_m, initial.state.speed_mps), (0.0, 0.5));
    stack.receive(left_arc(), RUN_START_NS, RUN_START_NS);
    let mut reports = Vec::new();
    for k in 0..5 {
        let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS;
        stack.step(now_ns);
        reports.push((now_ns + CONTROL_PERIOD_NS, stack.reported_state()));
    }
    // At the tick 100 ms after the start the states of 60, 80 and 100 ms are not valid yet;
    // the state of 40 ms is from 100 ms on, not a nanosecond earlier.
    let listed = stack.listed_state(RUN_START_NS + 100 * MS);
    assert_eq!(listed.create_ns, reports[1].0);
    assert_eq!(listed.state, reports[1].1);
    assert_eq!(
        stack.listed_state(RUN_START_NS + 100 * MS - 1).create_ns,
        reports[0].0
    );
    assert_eq!(stack.listed_state(RUN_START_NS + 80 * MS).create_ns, reports[0].0);
    assert_eq!(
        stack.listed_state(RUN_START_NS + 70 * MS).create_ns,
        RUN_START_NS - STATE_VALID_AFTER_NS
    );
}

/// A vehicle counts its periods and those its follower stopped it in, by reason: a trajectory
/// whose speed jumps between 0 and 5 m/s every 0.1 s (about 100 m/s²) is refused by the lab's
/// MPC (limit 20 m/s²) in every period it is the newest command.
#[test]
fn a_vehicle_counts_the_periods_its_follower_stopped_it_in() {
    let mut stack =
        VehicleStack::new(&twin_without_sensing(), VehicleParams::MU_CAR, &start(), 3, 0).unwrap();
    for k in 0..10 {
        let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS;
        if k == 5 {
            let mut abrupt = straight(now_ns);
            for (i, point) in abrupt.iter_mut().enumerate() {
                point.vx_mps = if i % 2 == 0 { 0.0 } else { 5.0 };
            }
            stack.receive(abrupt, now_ns, now_ns);
        } else if k < 5 {
            stack.receive(straight(now_ns), now_ns, now_ns);
        }
        let status = stack.step(now_ns);
        assert_eq!(
            matches!(status, Status::Stopped(StopReason::Rejected(_))),
            k >= 5,
            "period {k}: {status:?}"
        );
    }
    assert_eq!(
        stack.stops(),
        crate::FollowerStops {
            periods: 10,
            refused: 5,
            ..Default::default()
        }
    );
}

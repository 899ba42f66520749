//! Closed-loop tests with the kinematic bicycle (µCar, 20 ms steps) as plant.

mod common;

use common::{PERIOD_NS, PERIOD_S, circle, command_at, lane_change, run};
use cpmx_follower::{
    BICYCLE_MOVE_WEIGHTS, BicycleModel, Follower, FollowerConfig, Mpc, MpcConfig, Rejection, StateEstimate,
    Status, StopReason,
};
use cpmx_vehicle::{BicycleState, KinematicBicycle, VehicleParams};

const MS: u64 = 1_000_000;

fn bicycle() -> KinematicBicycle {
    KinematicBicycle::new(VehicleParams::MU_CAR)
}

/// The follower for a plant without actuation delay.
fn follower(delay_steps: usize) -> Follower<BicycleModel, 5, 2> {
    let config = MpcConfig {
        delay_steps,
        ..MpcConfig::lab(BICYCLE_MOVE_WEIGHTS)
    };
    Follower::new(
        Mpc::new(BicycleModel { bicycle: bicycle() }, config),
        FollowerConfig::default(),
    )
}

fn plant(state: &[f64; 5], input: &[f64; 2]) -> [f64; 5] {
    let out = bicycle().step(
        &BicycleModel::to_state(state),
        BicycleModel::to_command(input),
        PERIOD_S,
    );
    BicycleModel::from_state(&out.state)
}

fn start(reference: common::Reference) -> [f64; 5] {
    let (p, v) = reference(0.0);
    BicycleModel::from_state(&BicycleState {
        x_m: p[0],
        y_m: p[1],
        yaw_rad: v[1].atan2(v[0]),
        speed_mps: v[0].hypot(v[1]),
        steering_rad: 0.0,
    })
}

#[test]
fn follows_a_circle() {
    let run = run(&mut follower(0), plant, circle, start(circle), 0, 600);
    assert!(run.always_following());
    let (mean, max) = run.error_stats(3.0, 12.0);
    eprintln!("circle: mean {:.2} mm, max {:.2} mm", mean * 1e3, max * 1e3);
    assert!(mean < 0.01 && max < 0.03, "mean {mean} max {max}");
}

#[test]
fn follows_a_lane_change() {
    let run = run(&mut follower(0), plant, lane_change, start(lane_change), 0, 300);
    assert!(run.always_following());
    let (mean, max) = run.error_stats(1.0, 6.0);
    eprintln!("lane change: mean {:.2} mm, max {:.2} mm", mean * 1e3, max * 1e3);
    assert!(mean < 0.01 && max < 0.03, "mean {mean} max {max}");
}

#[test]
fn compensates_a_known_actuation_delay() {
    // Plant applies inputs 3 periods late; the MPC predicts over them as the lab does.
    let run = run(&mut follower(3), plant, circle, start(circle), 3, 600);
    assert!(run.always_following());
    let (mean, max) = run.error_stats(3.0, 12.0);
    eprintln!(
        "circle, 60 ms delay: mean {:.2} mm, max {:.2} mm",
        mean * 1e3,
        max * 1e3
    );
    assert!(mean < 0.01 && max < 0.03, "mean {mean} max {max}");
}

#[test]
fn too_little_lead_time_stops_the_car() {
    let mut f = follower(0);
    // The window needs points until t + 0.05 + 5·0.05 = t + 0.30 s; send 0.2 s of lead.
    f.receive(command_at(lane_change, 0, 200 * MS));
    let state = start(lane_change);
    let out = f.control(
        0,
        &StateEstimate {
            state,
            ips_update_age_ns: 0,
        },
    );
    assert_eq!(out.input, [0.0, 0.0]);
    assert!(matches!(
        out.status,
        Status::Stopped(StopReason::Rejected(Rejection::InsufficientLeadTime { .. }))
    ));

    // And the plant, given the stop input, brakes to a halt.
    let mut x = state;
    for _ in 0..20 {
        x = plant(&x, &out.input);
    }
    assert_eq!(x[3], 0.0);
}

#[test]
fn first_point_in_the_future_stops_the_car() {
    let mut f = follower(0);
    let mut command = command_at(circle, 1000 * MS, 1000 * MS);
    command.valid_after_ns = 0;
    f.receive(command);
    let out = f.control(
        0,
        &StateEstimate {
            state: start(circle),
            ips_update_age_ns: 0,
        },
    );
    assert!(matches!(
        out.status,
        Status::Stopped(StopReason::Rejected(Rejection::FirstPointInFuture { .. }))
    ));
}

#[test]
fn a_stale_command_stops_the_car() {
    let mut f = follower(0);
    f.receive(command_at(circle, 0, 3000 * MS));
    let mut state = start(circle);
    for n in 0..60 {
        let t_ns = n * PERIOD_NS;
        let out = f.control(
            t_ns,
            &StateEstimate {
                state,
                ips_update_age_ns: 0,
            },
        );
        state = plant(&state, &out.input);
        // Fresh while younger than 1 s, then the lab's "No new commands received".
        if t_ns < 1000 * MS {
            assert_eq!(out.status, Status::Following, "at {t_ns} ns");
        } else {
            assert_eq!(
                out.status,
                Status::Stopped(StopReason::StaleCommand { age_ns: t_ns }),
                "at {t_ns} ns"
            );
            assert_eq!(out.input, [0.0, 0.0]);
        }
    }
}

#[test]
fn no_command_and_lost_ips_stop_the_car() {
    let mut f = follower(0);
    let estimate = StateEstimate {
        state: start(circle),
        ips_update_age_ns: 0,
    };
    assert_eq!(
        f.control(0, &estimate).status,
        Status::Stopped(StopReason::NoCommand)
    );
    f.receive(command_at(circle, 0, 1000 * MS));
    // The lab stops on an IPS age above 3 s (`> 3000000000ull`), not at 3 s.
    let at_limit = StateEstimate {
        ips_update_age_ns: 3000 * MS,
        ..estimate
    };
    assert_eq!(f.control(20 * MS, &at_limit).status, Status::Following);
    let lost = StateEstimate {
        ips_update_age_ns: 3000 * MS + 1,
        ..estimate
    };
    assert_eq!(
        f.control(40 * MS, &lost).status,
        Status::Stopped(StopReason::LostIps {
            age_ns: 3000 * MS + 1
        })
    );
    let nan = StateEstimate {
        state: [f64::NAN; 5],
        ..estimate
    };
    assert!(matches!(
        f.control(60 * MS, &nan).status,
        Status::Stopped(StopReason::Rejected(Rejection::NonFiniteState))
    ));
}

#[test]
fn a_command_waits_for_its_valid_after_and_the_newest_wins() {
    let mut f = follower(0);
    let mut later = command_at(circle, 0, 2000 * MS);
    later.create_stamp_ns = 100 * MS;
    later.valid_after_ns = 500 * MS;
    f.receive(later);
    f.receive(command_at(circle, 0, 2000 * MS));
    let estimate = StateEstimate {
        state: start(circle),
        ips_update_age_ns: 0,
    };
    f.control(0, &estimate);
    assert_eq!(f.current_command().unwrap().valid_after_ns, 0);
    f.control(500 * MS - 1, &estimate);
    assert_eq!(f.current_command().unwrap().valid_after_ns, 0);
    f.control(500 * MS, &estimate);
    assert_eq!(f.current_command().unwrap().valid_after_ns, 500 * MS);
    // Of two commands with the same creation stamp, the later arrival wins (`Reader.hpp:116`).
    let mut first = command_at(circle, 600 * MS, 2000 * MS);
    let mut second = first.clone();
    first.create_stamp_ns = 600 * MS;
    second.create_stamp_ns = 600 * MS;
    second.trajectory = command_at(lane_change, 600 * MS, 2000 * MS).trajectory;
    f.receive(first);
    f.receive(second.clone());
    f.control(600 * MS, &estimate);
    assert_eq!(f.current_command(), Some(&second));
}

#[test]
fn identical_inputs_give_identical_bits() {
    let a = run(&mut follower(3), plant, circle, start(circle), 3, 150);
    let b = run(&mut follower(3), plant, circle, start(circle), 3, 150);
    let bits = |r: &common::Run<5, 2>| -> Vec<u64> {
        r.states
            .iter()
            .flatten()
            .chain(r.outputs.iter().flat_map(|o| o.input.iter()))
            .map(|v| v.to_bits())
            .collect()
    };
    assert_eq!(bits(&a), bits(&b));
}

#[test]
fn a_kept_solver_gives_the_bits_of_a_new_one() {
    let mut kept = Mpc::new(
        BicycleModel { bicycle: bicycle() },
        MpcConfig::lab(BICYCLE_MOVE_WEIGHTS),
    );
    for n in 0..20 {
        let t_ns = n * 100 * MS;
        let command = command_at(lane_change, t_ns, 1000 * MS);
        let (p, v) = lane_change(n as f64 * 0.1);
        let state = [
            p[0] + 0.01,
            p[1] - 0.02,
            v[1].atan2(v[0]) + 0.05,
            0.55,
            0.01 * n as f64,
        ];
        // A clone starts without a solver, so it builds a new one.
        let fresh = kept.clone().solve(t_ns, &state, &command.trajectory).unwrap();
        let reused = kept.solve(t_ns, &state, &command.trajectory).unwrap();
        assert_eq!(fresh.input.map(f64::to_bits), reused.input.map(f64::to_bits));
    }
}

/// Times `Mpc::solve` on the circle (run with `--ignored --nocapture`).
#[test]
#[ignore]
fn solve_time() {
    let mut mpc = Mpc::new(
        BicycleModel { bicycle: bicycle() },
        MpcConfig::lab(BICYCLE_MOVE_WEIGHTS),
    );
    let command = command_at(circle, 1000 * MS, 1000 * MS);
    let (p, v) = circle(1.0);
    let state = [p[0], p[1], v[1].atan2(v[0]), 0.5, 0.2];
    // Least mean over batches: robust against other processes on a shared machine.
    let per_solve = (0..20)
        .map(|_| {
            let started = std::time::Instant::now();
            for _ in 0..100 {
                std::hint::black_box(mpc.solve(1000 * MS, &state, &command.trajectory).unwrap());
            }
            started.elapsed() / 100
        })
        .min()
        .unwrap();
    eprintln!("one MPC solve: {per_solve:?}");
}

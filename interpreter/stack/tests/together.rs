//! Vehicles stepped together, their MPCs solved in lanes (`step_together`), drive exactly as
//! each stepped alone: grey-box cars with their own identified parameters, delays, positioning
//! noise and clocks, bicycles (sim-mpc) and a QP follower in the same call, vehicles without a
//! command and with stale ones; every true state and command compared bit for bit, 4 s of
//! 50 Hz steps.

use cpmx_follower::TrajectoryPoint;
use cpmx_spec::model::{
    ActuationLayer, ActuationModel, Control, DrawnFidelity, DynamicsLayer, FollowerSolver, FollowerSpec,
    GreyBoxModel, KinematicKeyword, SensingLayer, SensingModel, SimulatedFidelity,
};
use cpmx_stack::{CONTROL_PERIOD_NS, InitialState, RUN_START_NS, VehicleStack, step_together};
use cpmx_vehicle::{LAB_GREYBOX_PARAMETERS, VehicleParams};

const MS: u64 = 1_000_000;

/// Vehicle `i`'s fidelity: grey-box cars with parameters and delays of their own, every third
/// with the lab's positioning; a few bicycles; one QP follower.
fn fidelity(i: usize) -> DrawnFidelity {
    let scale = 1.0 + 0.02 * (i as f64 - 6.0);
    let dynamics = if i % 7 == 5 {
        DynamicsLayer::Kinematic(KinematicKeyword::Kinematic)
    } else {
        DynamicsLayer::GreyBox(GreyBoxModel {
            parameters: LAB_GREYBOX_PARAMETERS.map(|p| p * scale),
            euler_step_s: 0.02,
            battery_voltage_v: 7.8,
        })
    };
    SimulatedFidelity {
        control: Control::Trajectory,
        dynamics,
        sensing: i.is_multiple_of(3).then_some(SensingLayer::Model(SensingModel {
            rate_hz: 50.0,
            latency_ms: 60.0,
            noise_position_m: 0.002,
            noise_yaw_rad: 0.01,
            drop_probability: 0.05,
            fusion_gain: 0.5,
        })),
        actuation: Some(ActuationLayer::Model(ActuationModel {
            delay_ms: 40.0 + 10.0 * (i % 5) as f64,
        })),
        follower: (i == 9).then_some(FollowerSpec {
            solver: FollowerSolver::Qp,
        }),
        communication: None,
        perception: None,
        safety: None,
    }
}

/// An arc of radius `radius_m` at `speed_mps` from `start`, points every 0.1 s from `from_ns`.
fn arc(start: &InitialState, speed_mps: f64, radius_m: f64, from_ns: u64) -> Vec<TrajectoryPoint> {
    let t0_s = (from_ns - RUN_START_NS) as f64 * 1e-9;
    (0..20u64)
        .map(|k| {
            let t_s = t0_s + k as f64 * 0.1;
            let a = speed_mps * t_s / radius_m;
            let heading = start.yaw_rad + a;
            TrajectoryPoint {
                t_ns: from_ns + k * 100 * MS,
                x_m: start.x_m + radius_m * (heading.sin() - start.yaw_rad.sin()),
                y_m: start.y_m - radius_m * (heading.cos() - start.yaw_rad.cos()),
                vx_mps: speed_mps * heading.cos(),
                vy_mps: speed_mps * heading.sin(),
            }
        })
        .collect()
}

fn start(i: usize) -> InitialState {
    InitialState {
        ref_path: 0,
        x_m: 0.3 * i as f64,
        y_m: -0.2 * i as f64,
        yaw_rad: 0.4 * i as f64 - 2.0,
        speed_mps: 0.1 * (i % 6) as f64,
    }
}

fn fleet(n: usize) -> Vec<VehicleStack> {
    (0..n)
        .map(|i| VehicleStack::new(&fidelity(i), VehicleParams::MU_CAR, &start(i), 40 + i as u64, i).unwrap())
        .collect()
}

fn bits(stack: &VehicleStack) -> Vec<u64> {
    let s = stack.true_sample();
    let [u, v] = stack.command();
    [
        s.x_m,
        s.y_m,
        s.yaw_rad,
        s.velocity_mps[0],
        s.velocity_mps[1],
        s.steering_rad,
        u,
        v,
    ]
    .iter()
    .map(|x| x.to_bits())
    .collect()
}

#[test]
fn vehicles_stepped_together_drive_as_each_alone() {
    // 17 vehicles: two runs of eight grey-box cars' lanes, pairs and singles besides.
    let n = 17;
    let (mut alone, mut together) = (fleet(n), fleet(n));
    // Each vehicle's clock is offset by whole periods, as the training's agents' are.
    let offset_ns = |i: usize| (i % 4) as u64 * CONTROL_PERIOD_NS;
    for k in 0..200u64 {
        if k % 5 == 0 {
            for i in 0..n {
                // Vehicle 4 never gets a command; vehicle 7's stop after 1.4 s and go stale.
                if i == 4 || (i == 7 && k > 70) {
                    continue;
                }
                let now_ns = RUN_START_NS + k * CONTROL_PERIOD_NS + offset_ns(i);
                let points = arc(
                    &start(i),
                    0.3 + 0.05 * (i % 8) as f64,
                    0.6 + 0.3 * (i % 5) as f64,
                    now_ns,
                );
                alone[i].receive(points.clone(), now_ns, now_ns);
                together[i].receive(points, now_ns, now_ns);
            }
        }
        for (i, stack) in alone.iter_mut().enumerate() {
            stack.step(RUN_START_NS + k * CONTROL_PERIOD_NS + offset_ns(i));
        }
        step_together(
            together
                .iter_mut()
                .enumerate()
                .map(|(i, stack)| (stack, RUN_START_NS + k * CONTROL_PERIOD_NS + offset_ns(i))),
        );
        for i in 0..n {
            assert_eq!(bits(&together[i]), bits(&alone[i]), "step {k}, vehicle {i}");
        }
    }
    // The cars drove: the comparison is not of vehicles standing still.
    let moved = (0..n)
        .filter(|&i| (alone[i].true_sample().x_m - start(i).x_m).abs() > 0.1)
        .count();
    assert!(moved > n / 2, "{moved} of {n} vehicles moved");
}

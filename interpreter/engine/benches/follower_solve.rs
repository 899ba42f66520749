//! One MPC decision of the µCar's trajectory follower, per solver and model
//! (`cargo bench -p cpmx-engine --bench follower_solve`): the lab's 20 warm-started gradient
//! steps (`gradient`, the default) and the exact QP (`qp`, clarabel), on the lab's grey-box
//! model with the lab's 3-step delay compensation (the twin) and on the kinematic bicycle
//! without it (sim-mpc).
//!
//! Each iteration is one control period of a closed loop: solve at `t`, move the model 20 ms
//! with the answer, `t += 20 ms`, so warm starts and the cached QP solver are used as in a run.
//! The reference is a circle of radius 0.6 m at 0.5 m/s (the lab's turns are 0.5–0.6 m);
//! after 19 s the loop starts over with a fresh MPC.

use std::hint::black_box;

use cpmx_engine::GreyBoxMpcModel;
use cpmx_follower::{
    BICYCLE_MOVE_WEIGHTS, BicycleModel, LAB_MOVE_WEIGHTS, Model, Mpc, MpcConfig, Solver, Trajectory,
    TrajectoryPoint,
};
use cpmx_vehicle::{GreyBoxParams, KinematicBicycle, VehicleParams};
use criterion::{Criterion, criterion_group, criterion_main};

const PERIOD_S: f64 = 0.02;
const PERIOD_NS: u64 = 20_000_000;
const RADIUS_M: f64 = 0.6;
const SPEED_MPS: f64 = 0.5;
/// The loop starts over after this long (the reference lasts 20 s) [ns].
const LOOP_NS: u64 = 19_000_000_000;

/// The circle from the origin heading +x, points every 0.1 s for 20 s.
fn circle() -> Trajectory {
    let points = (0..=200u32)
        .map(|k| {
            let t = f64::from(k) * 0.1;
            let a = SPEED_MPS * t / RADIUS_M;
            TrajectoryPoint {
                t_ns: u64::from(k) * 100_000_000,
                x_m: RADIUS_M * a.sin(),
                y_m: RADIUS_M * (1.0 - a.cos()),
                vx_mps: SPEED_MPS * a.cos(),
                vy_mps: SPEED_MPS * a.sin(),
            }
        })
        .collect();
    Trajectory::new(points).expect("a valid trajectory")
}

/// One closed-loop control period per iteration from `start`.
fn bench_loop<M: Model<NX, 2> + Clone, const NX: usize>(
    c: &mut Criterion,
    name: &str,
    mpc: Mpc<M, NX, 2>,
    start: [f64; NX],
) {
    let trajectory = circle();
    let (mut current, mut state, mut t_ns) = (mpc.clone(), start, 0);
    c.bench_function(name, |b| {
        b.iter(|| {
            if t_ns > LOOP_NS {
                (current, state, t_ns) = (mpc.clone(), start, 0);
            }
            let input = match current.solve(t_ns, &state, &trajectory) {
                Ok(solution) => solution.input,
                Err(_) => current.model().stop_input(&state),
            };
            state = current.model().step(&state, black_box(&input), PERIOD_S);
            t_ns += PERIOD_NS;
        })
    });
}

fn follower_solve(c: &mut Criterion) {
    let grey_box = GreyBoxMpcModel::new(GreyBoxParams::LAB).expect("the lab's parameters");
    let bicycle = BicycleModel {
        bicycle: KinematicBicycle::new(VehicleParams::MU_CAR),
    };
    for (solver, word) in [(Solver::Gradient, "gradient"), (Solver::Qp, "qp")] {
        let twin = MpcConfig {
            solver,
            ..MpcConfig::lab(LAB_MOVE_WEIGHTS)
        };
        bench_loop(
            c,
            &format!("follower/greybox/{word}"),
            Mpc::new(grey_box.clone(), twin),
            [0.0, 0.0, 0.0, SPEED_MPS],
        );
        let sim_mpc = MpcConfig {
            solver,
            delay_steps: 0,
            ..MpcConfig::lab(BICYCLE_MOVE_WEIGHTS)
        };
        bench_loop(
            c,
            &format!("follower/bicycle/{word}"),
            Mpc::new(bicycle, sim_mpc),
            [0.0, 0.0, 0.0, SPEED_MPS, 0.0],
        );
    }
}

criterion_group!(benches, follower_solve);
criterion_main!(benches);

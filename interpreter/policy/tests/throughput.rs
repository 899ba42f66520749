//! Throughput of observation + actor + action head (`cargo test --release -p cpmx-policy
//! --test throughput -- --ignored --nocapture`). The target: 100k agent-steps/s on
//! one core.

mod common;

use std::time::Instant;

use common::{reference_file, reference_paths};
use cpmx_policy::{
    ActionMode, AgentPaths, AgentState, MlpPolicy, ObservationInput, Policy, SigmarlObservation,
};
use cpmx_vehicle::{Command, VehicleParams};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

fn measure(agents: usize, steps: usize) -> (f64, f64) {
    let all = reference_paths();
    let paths = AgentPaths::new((0..agents).map(|i| &all[(i * 7) % all.len()]));
    let vehicle = VehicleParams::MU_CAR;
    let weights = reference_file("policy/actor.safetensors");
    let mut policy = MlpPolicy::from_file(
        weights.as_ref(),
        SigmarlObservation::default(),
        ActionMode::Mean,
        ChaCha20Rng::seed_from_u64(0),
    )
    .unwrap();
    let mut states: Vec<AgentState> = (0..agents)
        .map(|i| {
            let p = paths.paths[i].center_points[10];
            AgentState {
                x_m: p[0],
                y_m: p[1],
                yaw_rad: 0.3 * i as f64,
                speed_mps: 0.4,
                velocity_mps: [0.3, 0.2],
                steering_rad: 0.0,
            }
        })
        .collect();
    let mut commands = vec![Command::default(); agents];
    let (mut observe_s, start) = (0.0, Instant::now());
    for t in 0..steps {
        for s in &mut states {
            s.x_m += 1e-4 * (t % 7) as f64;
        }
        let input = ObservationInput {
            agents: &states,
            paths: &paths,
            vehicle: &vehicle,
            previous_corners: None,
            neighbours: None,
        };
        let t0 = Instant::now();
        SigmarlObservation::default()
            .observe_all(&input, &mut vec![0.0; agents * 32])
            .unwrap();
        observe_s += t0.elapsed().as_secs_f64();
        policy.act(&input, &mut commands).unwrap();
    }
    let total_s = start.elapsed().as_secs_f64() - observe_s;
    let n = (agents * steps) as f64;
    (n / total_s, n / observe_s)
}

#[test]
#[ignore = "timing; run in release"]
fn agent_steps_per_second() {
    for (agents, steps) in [(4, 20_000), (64, 2_000)] {
        let (policy_rate, observation_rate) = measure(agents, steps);
        eprintln!(
            "{agents} agents: {policy_rate:.0} agent-steps/s (observation + actor + head), \
             {observation_rate:.0} observations/s alone"
        );
    }
}

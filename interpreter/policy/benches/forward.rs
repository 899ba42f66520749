//! Policy throughput (`cargo bench -p cpmx-policy --bench forward`), in agent-steps:
//!
//! - `policy/actor_forward_3`: the reference actor's forward pass alone for 3 agents;
//! - `policy/observation_3`: SigmaRL's observation of 3 agents on CPM Lab reference paths;
//! - `policy/act_3`: both plus the action head, as an engine calls it once per step.
//!
//! Needs SigmaRL's reference data at `../shared/reference` next to the repository.

#[path = "../tests/common/mod.rs"]
mod common;

use std::hint::black_box;

use common::{json, nums, reference_file, reference_paths};
use cpmx_policy::{
    ActionMode, AgentPaths, AgentState, MlpActor, MlpLayout, MlpPolicy, ObservationInput, Policy,
    SigmarlObservation,
};
use cpmx_vehicle::{Command, VehicleParams};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// Agents of the paper design.
const AGENTS: usize = 3;

/// The reference actor's weights.
fn weights() -> std::path::PathBuf {
    reference_file("policy/actor.safetensors")
}

/// The first step of SigmaRL's reference rollout (3 agents on paths 6, 2, 3).
fn rollout_start() -> (AgentPaths, Vec<AgentState>) {
    let root = json("rollouts/rollout_1.json");
    let all = reference_paths();
    let paths = AgentPaths::new(nums(&root["ref_path_ids"]).iter().map(|&i| &all[i as usize]));
    let step = &root["steps"][0];
    let states = (0..AGENTS)
        .map(|i| {
            let num = |v: &serde_json::Value| v.as_f64().expect("a number");
            AgentState {
                x_m: num(&step["pos"][i][0]),
                y_m: num(&step["pos"][i][1]),
                yaw_rad: num(&step["rot"][i]),
                speed_mps: num(&step["speed"][i]),
                velocity_mps: [num(&step["vel"][i][0]), num(&step["vel"][i][1])],
                steering_rad: 0.0,
            }
        })
        .collect();
    (paths, states)
}

fn policy_throughput(c: &mut Criterion) {
    let mut group = c.benchmark_group("policy");
    group.throughput(Throughput::Elements(AGENTS as u64));

    // The forward pass alone, on the first three test vectors.
    let actor = MlpActor::load(&weights(), &MlpLayout::sigmarl()).expect("the reference actor");
    let layout = json("policy/actor_layout.json");
    let obs: Vec<f32> = layout["test_vectors"].as_array().expect("test vectors")[..AGENTS]
        .iter()
        .flat_map(|v| nums(&v["obs"]))
        .map(|x| x as f32)
        .collect();
    let mut ws = actor.workspace(AGENTS);
    let mut raw = vec![0.0f32; AGENTS * actor.output_size()];
    group.bench_function("actor_forward_3", |b| {
        b.iter(|| {
            actor
                .forward(black_box(&obs), &mut ws, &mut raw)
                .expect("forward")
        })
    });

    // The observation alone, and the whole policy step.
    let (paths, states) = rollout_start();
    let vehicle = VehicleParams::MU_CAR;
    let input = ObservationInput {
        agents: &states,
        paths: &paths,
        vehicle: &vehicle,
        previous_corners: None,
        neighbours: None,
    };
    let design = SigmarlObservation::default();
    let mut observations = vec![0.0f32; AGENTS * design.size()];
    group.bench_function("observation_3", |b| {
        b.iter(|| {
            design
                .observe_all(black_box(&input), &mut observations)
                .expect("observation")
        })
    });
    let mut policy =
        MlpPolicy::new(actor, design, ActionMode::Mean, ChaCha20Rng::seed_from_u64(0)).expect("the policy");
    let mut commands = vec![Command::default(); AGENTS];
    group.bench_function("act_3", |b| {
        b.iter(|| policy.act(black_box(&input), &mut commands).expect("act"))
    });
    group.finish();
}

criterion_group!(benches, policy_throughput);
criterion_main!(benches);

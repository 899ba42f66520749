//! Collection throughput of the training environments (`cargo bench -p cpmx-env --bench
//! env_steps`), in env-steps per second (one env-step = all 4 agents of one environment:
//! move, collisions, reward terms, observations, resets), with uniform random commands,
//! which crash into a boundary every few steps and so reset far more often than a trained
//! policy. SigmaRL collects 258 env-steps/s on one core of the reference machine.
//!
//! - `env/step_32x4_1thread`: SigmaRL's 32 environments of 4 agents, on the calling thread;
//! - `env/step_32x4_rayon`: the same spread over rayon's threads.
//!
//! Needs SigmaRL's reference map at `../shared/reference/maps/cpm.xml`.

use std::hint::black_box;

use cpmx_env::{EnvConfig, StepResult, VecEnv, sigmarl_intersection_paths};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

fn bench_steps(c: &mut Criterion) {
    let paths = sigmarl_intersection_paths(&cpmx_testdata::reference_file("maps/cpm.xml")).expect("map");
    let config = EnvConfig::default();
    let envs = config.scenario.envs;
    let n = envs * config.scenario.agents;
    // A pool of pre-drawn commands, so that drawing them is not measured.
    let mut rng = ChaCha20Rng::seed_from_u64(1);
    let actions: Vec<Vec<f32>> = (0..256)
        .map(|_| {
            (0..n)
                .flat_map(|_| [rng.random_range(-1.0f32..1.0), rng.random_range(-0.541f32..0.541)])
                .collect()
        })
        .collect();
    let mut group = c.benchmark_group("env");
    group.throughput(Throughput::Elements(envs as u64));
    for (name, parallel) in [("step_32x4_1thread", false), ("step_32x4_rayon", true)] {
        let mut env = VecEnv::new(config.clone(), &paths, 1).expect("env");
        env.set_parallel(parallel);
        let mut result = StepResult::default();
        let mut k = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                env.step_into(black_box(&actions[k % actions.len()]), &mut result);
                k += 1;
                black_box(&result.rewards);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_steps);
criterion_main!(benches);

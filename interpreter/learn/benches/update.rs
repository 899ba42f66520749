//! One MAPPO minibatch step at SigmaRL's sizes (`cargo bench -p cpmx-learn --bench update`):
//! the actor 32 -> 256 x 3 -> 4 over 2,048 agent rows and the centralised critic
//! 128 -> 256 x 3 -> 1 over 512 env-steps, forward, PPO loss, backward, joint clipping and
//! Adam, reported in FLOP/s (2 per multiply-add of the three products per layer; the input
//! layers need no input gradient): 2.18 GFLOP per step, 240 steps per iteration.
//!
//! Peak for comparison (`peak/fma`): independent chains of the widest FMA the CPU has (AVX-512
//! where present, else AVX2), i.e. what one core can do at its current clock; the bench
//! measures it rather than assuming a clock. The width matters: a Zen 4 core splits a 512-bit
//! FMA into two 256-bit halves (the same peak either way), an Intel core with two AVX-512 FMA
//! units does twice the 256-bit figure. Run with one thread, nothing else running:
//! `RAYON_NUM_THREADS=1 cargo bench -p cpmx-learn --bench update`. The README's performance
//! section has the figures of each machine the project ran on. A 240-step update needs 524
//! GFLOP.

use std::hint::black_box;

use cpmx_kernels::{Mat, gemm};
use cpmx_learn::mlp::{Mlp, Tape};
use cpmx_learn::optim::{AdamConfig, AdamState, clip_grad_norm};
use cpmx_learn::ppo::{LossConfig, LossInput, ppo_loss};
use cpmx_learn::tanh_normal;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

const SAMPLES: usize = 512;
const AGENTS: usize = 4;
const HIGH: [f32; 2] = [1.0, 0.541_052_04];

struct Step {
    actor: Mlp,
    critic: Mlp,
    adam_actor: AdamState,
    adam_critic: AdamState,
    obs: Vec<f32>,
    action: Vec<f32>,
    log_prob: Vec<f32>,
    advantage: Vec<f32>,
    target: Vec<f32>,
    eps: Vec<f32>,
    ta: Tape,
    tc: Tape,
    d_raw: Vec<f32>,
    d_value: Vec<f32>,
    ga: Vec<f32>,
    gc: Vec<f32>,
    t: u64,
}

impl Step {
    fn new() -> Self {
        let mut rng = ChaCha20Rng::seed_from_u64(3);
        let actor = Mlp::init(&[32, 256, 256, 256, 4], &mut rng);
        let critic = Mlp::init(&[128, 256, 256, 256, 1], &mut rng);
        let entries = SAMPLES * AGENTS;
        let obs: Vec<f32> = (0..SAMPLES * 128).map(|_| rng.random_range(-1.0..1.0)).collect();
        let mut ta = Tape::default();
        actor.forward(&obs, entries, &mut ta);
        let mut action = Vec::new();
        let mut log_prob = Vec::new();
        for raw in ta.output().chunks_exact(4) {
            let p = tanh_normal::params(raw, f32::INFINITY);
            let a = tanh_normal::sample(
                &p,
                [rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)],
                HIGH,
            );
            action.extend(a);
            log_prob.push(tanh_normal::log_prob(&p, a, HIGH).log_prob as f32);
        }
        Step {
            adam_actor: AdamState::new(actor.params.len()),
            adam_critic: AdamState::new(critic.params.len()),
            ga: vec![0.0; actor.params.len()],
            gc: vec![0.0; critic.params.len()],
            actor,
            critic,
            obs,
            action,
            log_prob,
            advantage: (0..entries).map(|_| rng.random_range(-0.5..0.5)).collect(),
            target: (0..entries).map(|_| rng.random_range(-0.5..0.5)).collect(),
            eps: (0..entries * 2).map(|_| rng.random_range(-1.5..1.5)).collect(),
            ta,
            tc: Tape::default(),
            d_raw: vec![0.0; entries * 4],
            d_value: vec![0.0; SAMPLES],
            t: 0,
        }
    }

    fn flops(&self) -> u64 {
        let entries = SAMPLES * AGENTS;
        2 * (self.actor.forward_macs(entries)
            + self.actor.backward_macs(entries)
            + self.critic.forward_macs(SAMPLES)
            + self.critic.backward_macs(SAMPLES))
    }

    fn run(&mut self) {
        let config = LossConfig {
            clip_epsilon: 0.2,
            entropy_coef: 5e-4,
            critic_coef: 1.0,
            high: HIGH,
            max_scale: f32::INFINITY,
        };
        self.actor.forward(&self.obs, SAMPLES * AGENTS, &mut self.ta);
        self.critic.forward(&self.obs, SAMPLES, &mut self.tc);
        let input = LossInput {
            action: &self.action,
            log_prob_old: &self.log_prob,
            advantage: &self.advantage,
            value_target: &self.target,
            entropy_eps: &self.eps,
        };
        ppo_loss(
            &config,
            self.ta.output(),
            self.tc.output(),
            &input,
            &mut self.d_raw,
            &mut self.d_value,
        );
        self.actor.backward(&mut self.ta, &self.d_raw, &mut self.ga);
        self.critic.backward(&mut self.tc, &self.d_value, &mut self.gc);
        clip_grad_norm(&mut [&mut self.ga, &mut self.gc], 1.0);
        self.t += 1;
        let adam = AdamConfig::default();
        self.adam_actor
            .step(&adam, self.t, 1e-5, &mut self.actor.params, &self.ga);
        self.adam_critic
            .step(&adam, self.t, 1e-5, &mut self.critic.params, &self.gc);
    }
}

/// Steps of every chain in one call of [`fma_peak`].
const PEAK_STEPS: usize = 100_000;

/// The widest fused multiply-add this CPU runs, as many independent chains as keep every FMA
/// unit busy: 12 chains of 16 lanes with AVX-512 (two 512-bit units with 4 cycles of latency
/// need 8), else 12 of 8 lanes with AVX2. Returns the FLOP one call of the function does.
fn fma_peak() -> (u64, fn() -> f32) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU has AVX-512F.
            return ((12 * 16 * 2 * PEAK_STEPS) as u64, || unsafe { fma_peak_avx512() });
        }
        if cpmx_kernels::gemm::has_fma() {
            // SAFETY: the CPU has AVX2 and FMA.
            return ((12 * 8 * 2 * PEAK_STEPS) as u64, || unsafe { fma_peak_avx2() });
        }
    }
    (1, || 0.0)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn fma_peak_avx512() -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm512_set1_ps(0.0); 12];
    let a = _mm512_set1_ps(black_box(0.999_999));
    let b = _mm512_set1_ps(black_box(1e-7));
    for _ in 0..PEAK_STEPS {
        for x in acc.iter_mut() {
            *x = _mm512_fmadd_ps(*x, a, b);
        }
    }
    let mut sum = _mm512_setzero_ps();
    for x in acc {
        sum = _mm512_add_ps(sum, x);
    }
    _mm512_reduce_add_ps(sum)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_peak_avx2() -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_set1_ps(0.0); 12];
    let a = _mm256_set1_ps(black_box(0.999_999));
    let b = _mm256_set1_ps(black_box(1e-7));
    for _ in 0..PEAK_STEPS {
        for x in acc.iter_mut() {
            *x = _mm256_fmadd_ps(*x, a, b);
        }
    }
    let mut sum = _mm256_setzero_ps();
    for x in acc {
        sum = _mm256_add_ps(sum, x);
    }
    let mut out = [0.0f32; 8];
    // SAFETY: `out` holds 8 values.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), sum) };
    out.iter().sum()
}

fn bench(c: &mut Criterion) {
    // As the trainer does: the step runs inside a pool of `RAYON_NUM_THREADS` (default: all
    // cores), so that its parallel loops start on the calling thread instead of waking a
    // worker for each.
    let threads = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    let mut step = Step::new();
    let mut group = c.benchmark_group("update");
    group.throughput(Throughput::Elements(step.flops()));
    group.bench_function("minibatch_step_flop", |b| b.iter(|| pool.install(|| step.run())));
    group.finish();
    // The parts, to see where the time goes.
    let mut group = c.benchmark_group("parts");
    let (m, n, k) = (2048, 256, 256);
    let a: Vec<f32> = (0..m * k).map(|i| (i as f32 * 0.37).sin()).collect();
    let b: Vec<f32> = (0..k * n).map(|i| (i as f32 * 0.11).cos()).collect();
    let mut out = vec![0.0f32; m * n];
    group.throughput(Throughput::Elements((2 * m * n * k) as u64));
    group.bench_function("gemm_2048x256x256_flop", |bch| {
        bch.iter(|| {
            gemm(
                m,
                n,
                k,
                Mat::rows(&a, k),
                Mat::transposed(&b, k),
                &mut out,
                n,
                true,
            )
        })
    });
    group.bench_function("gemm_dw_256x256x2048_flop", |bch| {
        bch.iter(|| {
            gemm(
                n,
                k,
                m,
                Mat::transposed(&a, k),
                Mat::rows(&a, k),
                &mut out,
                k,
                false,
            )
        })
    });
    let entries = SAMPLES * AGENTS;
    group.throughput(Throughput::Elements(2 * step.actor.forward_macs(entries)));
    group.bench_function("actor_forward_flop", |bch| {
        bch.iter(|| step.actor.forward(&step.obs, entries, &mut step.ta))
    });
    let mut v: Vec<f32> = (0..entries * 768)
        .map(|i| (i as f32 * 0.01).sin() * 3.0)
        .collect();
    group.throughput(Throughput::Elements(v.len() as u64));
    group.bench_function("tanh_values", |bch| {
        bch.iter(|| cpmx_kernels::tanh(black_box(&mut v)))
    });
    group.throughput(Throughput::Elements(entries as u64));
    step.run();
    group.bench_function("ppo_loss_entries", |bch| {
        bch.iter(|| {
            let config = LossConfig {
                clip_epsilon: 0.2,
                entropy_coef: 5e-4,
                critic_coef: 1.0,
                high: HIGH,
                max_scale: f32::INFINITY,
            };
            let input = LossInput {
                action: &step.action,
                log_prob_old: &step.log_prob,
                advantage: &step.advantage,
                value_target: &step.target,
                entropy_eps: &step.eps,
            };
            ppo_loss(
                &config,
                step.ta.output(),
                step.tc.output(),
                &input,
                &mut step.d_raw,
                &mut step.d_value,
            )
        })
    });
    group.finish();
    let mut group = c.benchmark_group("peak");
    let (peak_flop, peak) = fma_peak();
    group.throughput(Throughput::Elements(peak_flop));
    group.bench_function("fma_flop", |b| b.iter(|| black_box(peak())));
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench
}
criterion_main!(benches);

//! Agreement with SigmaRL's own MAPPO pieces (`shared/reference/training/ppo_cases.json`,
//! `critic.safetensors`, `policy/actor.safetensors`): TanhNormal log-probabilities, the GAE
//! trajectory, the critic's values, and one PPO minibatch's losses and per-tensor gradient
//! norms; plus finite-difference checks of the networks' gradients.

use cpmx_learn::mlp::{Mlp, Tape};
use cpmx_learn::optim::squared_norm;
use cpmx_learn::ppo::{LossConfig, LossInput, gae, ppo_loss};
use cpmx_learn::tanh_normal;
use serde_json::Value;

fn json() -> Value {
    let text = cpmx_testdata::read_reference("training/ppo_cases.json");
    serde_json::from_str(&text).unwrap()
}

/// All numbers of a nested JSON array, flattened.
fn flat(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(a) => a.iter().flat_map(flat).collect(),
        Value::Number(n) => vec![n.as_f64().unwrap()],
        Value::Bool(b) => vec![f64::from(u8::from(*b))],
        other => panic!("not a number: {other}"),
    }
}

fn f32s(v: &Value) -> Vec<f32> {
    flat(v).into_iter().map(|x| x as f32).collect()
}

fn network(file: &str, prefix: &str) -> Mlp {
    Mlp::from_safetensors(
        &std::fs::read(cpmx_testdata::reference_file(file)).unwrap(),
        prefix,
    )
    .unwrap()
}

fn rel(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs().max(1e-12)
}

const HIGH: [f32; 2] = [1.0, 0.541_052_04];

#[test]
fn tanh_normal_log_probs_match_all_40_cases() {
    let data = json();
    let cases = data["tanh_normal_log_prob"]["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 40);
    let mut worst = 0.0f64;
    for (i, case) in cases.iter().enumerate() {
        let (loc, scale, action) = (f32s(&case["loc"]), f32s(&case["scale"]), f32s(&case["action"]));
        let p = tanh_normal::Params {
            loc: [loc[0], loc[1]],
            scale: [scale[0], scale[1]],
            dscale_dz: [1.0, 1.0],
        };
        let got = tanh_normal::log_prob(&p, [action[0], action[1]], HIGH).log_prob;
        let want = case["log_prob"].as_f64().unwrap();
        // float32 reference values: 1e-6 relative or 2e-6 absolute.
        let err = (got - want).abs() / want.abs().max(2.0);
        worst = worst.max(err);
        assert!(err < 1e-6, "case {i}: {got} vs {want}");
        let mean = tanh_normal::mean_action(&p, HIGH);
        let want_mean = f32s(&case["deterministic_action"]);
        assert!(
            (mean[0] - want_mean[0]).abs() < 2e-7 && (mean[1] - want_mean[1]).abs() < 2e-7,
            "case {i}"
        );
    }
    eprintln!("worst log-prob error {worst:e}");
}

#[test]
fn gae_matches_torchrl() {
    let data = json();
    let g = &data["gae"];
    let reward = f32s(&g["reward"]);
    let done: Vec<bool> = flat(&g["done"]).iter().map(|&d| d != 0.0).collect();
    assert_eq!(flat(&g["done"]), flat(&g["terminated"]));
    let value: Vec<f32> = g["state_value"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v[0].as_f64().unwrap() as f32)
        .collect();
    let next: Vec<f32> = g["next_state_value"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v[0].as_f64().unwrap() as f32)
        .collect();
    // Our layout: T + 1 values; next_state_value[t] = value[t + 1] except after a done step
    // (a reset), where the bootstrap is multiplied by 0 anyway.
    let steps = done.len();
    for t in 0..steps - 1 {
        if !done[t] {
            assert_eq!(next[t], value[t + 1], "step {t}");
        }
    }
    let mut values = value.clone();
    values.push(next[steps - 1]);
    let mut advantage = vec![0.0; reward.len()];
    let mut target = vec![0.0; reward.len()];
    gae(0.99, 0.9, &reward, &done, &values, &mut advantage, &mut target);
    let (want_a, want_t) = (flat(&g["advantage"]), flat(&g["value_target"]));
    for i in 0..reward.len() {
        assert!(
            (f64::from(advantage[i]) - want_a[i]).abs() < 1e-6,
            "advantage {i}"
        );
        assert!((f64::from(target[i]) - want_t[i]).abs() < 1e-6, "target {i}");
    }
}

/// The minibatch, the networks and our loss with its gradients.
struct Minibatch {
    actor: Mlp,
    critic: Mlp,
    obs: Vec<f32>,
    action: Vec<f32>,
    log_prob_old: Vec<f32>,
    advantage: Vec<f32>,
    target: Vec<f32>,
    eps: Vec<f32>,
    samples: usize,
}

fn minibatch() -> (Minibatch, Value) {
    let data = json();
    let mb = data["ppo_minibatch"].clone();
    let m = Minibatch {
        actor: network("policy/actor.safetensors", "actor"),
        critic: network("training/critic.safetensors", "critic"),
        obs: f32s(&mb["observation"]),
        action: f32s(&mb["action"]),
        log_prob_old: f32s(&mb["sample_log_prob_old"]),
        advantage: f32s(&mb["advantage"]),
        target: f32s(&mb["value_target"]),
        eps: f32s(&mb["entropy_mc_noise_eps"]),
        samples: mb["n_samples"].as_u64().unwrap() as usize,
    };
    (m, mb)
}

/// Losses and gradients `(actor grad, critic grad)` of the minibatch.
fn loss_and_grads(
    m: &Minibatch,
    actor: &Mlp,
    critic: &Mlp,
) -> (cpmx_learn::Losses, Vec<f32>, Vec<f32>, Vec<f32>, Vec<f32>) {
    let (mut ta, mut tc) = (Tape::default(), Tape::default());
    let entries = m.log_prob_old.len();
    actor.forward(&m.obs, entries, &mut ta);
    critic.forward(&m.obs, m.samples, &mut tc);
    let config = LossConfig {
        clip_epsilon: 0.2,
        entropy_coef: 5e-4,
        critic_coef: 1.0,
        high: HIGH,
        max_scale: f32::INFINITY,
    };
    let input = LossInput {
        action: &m.action,
        log_prob_old: &m.log_prob_old,
        advantage: &m.advantage,
        value_target: &m.target,
        entropy_eps: &m.eps,
    };
    let mut d_raw = vec![0.0; entries * 4];
    let mut d_value = vec![0.0; m.samples];
    let losses = ppo_loss(
        &config,
        ta.output(),
        tc.output(),
        &input,
        &mut d_raw,
        &mut d_value,
    );
    let raw = ta.output().to_vec();
    let values = tc.output().to_vec();
    let mut ga = vec![0.0; actor.params.len()];
    let mut gc = vec![0.0; critic.params.len()];
    actor.backward(&mut ta, &d_raw, &mut ga);
    critic.backward(&mut tc, &d_value, &mut gc);
    (losses, ga, gc, raw, values)
}

#[test]
fn ppo_minibatch_losses_and_gradient_norms_match_sigmarl() {
    let (m, mb) = minibatch();
    let (losses, ga, gc, raw, values) = loss_and_grads(&m, &m.actor, &m.critic);

    // The actor's loc/scale and the critic's values (float32 forward passes).
    let (loc, scale) = (flat(&mb["loc"]), flat(&mb["scale"]));
    let mut worst_param = 0.0f64;
    for (i, r) in raw.chunks_exact(4).enumerate() {
        let p = tanh_normal::params(r, f32::INFINITY);
        for c in 0..2 {
            worst_param = worst_param
                .max((f64::from(p.loc[c]) - loc[2 * i + c]).abs())
                .max((f64::from(p.scale[c]) - scale[2 * i + c]).abs());
        }
    }
    let want_values = flat(&mb["state_value_new"]);
    let worst_value = (0..m.samples)
        .map(|s| (f64::from(values[s]) - want_values[4 * s]).abs())
        .fold(0.0, f64::max);
    let lp_new = flat(&mb["log_prob_new"]);
    let worst_lp = raw
        .chunks_exact(4)
        .enumerate()
        .map(|(i, r)| {
            let lp = tanh_normal::log_prob(
                &tanh_normal::params(r, f32::INFINITY),
                [m.action[2 * i], m.action[2 * i + 1]],
                HIGH,
            )
            .log_prob;
            (lp - lp_new[i]).abs() / lp_new[i].abs().max(1.0)
        })
        .fold(0.0, f64::max);
    eprintln!("loc/scale {worst_param:e}, value {worst_value:e}, log-prob {worst_lp:e}");
    // The reference log-probabilities are torch's float32 values (a float64 NumPy re-run
    // agrees to 7e-6); ours start from float32 loc/scale within 5e-7 of torch's, and
    // d log p / d loc reaches (u - loc) / scale^2 ~ 30 at the batch's small steering scales.
    assert!(worst_param < 1e-6 && worst_value < 1e-6 && worst_lp < 3e-5);

    // The three losses.
    let out = &mb["outputs"];
    for (name, got) in [
        ("loss_objective", losses.objective),
        ("loss_critic", losses.critic),
        ("loss_entropy", losses.entropy_loss),
        ("entropy", losses.entropy),
        ("total_loss", losses.total()),
    ] {
        let want = out[name].as_f64().unwrap();
        eprintln!("{name}: {got} vs {want} ({:e})", rel(got, want));
        assert!(rel(got, want) < 1e-5, "{name}");
    }
    assert_eq!(losses.clip_fraction, out["clip_fraction"].as_f64().unwrap());

    // Per-tensor gradient norms before clipping, and the total.
    let norms = mb["grad_norm_per_tensor_before_clipping"].as_object().unwrap();
    let mut total = 0.0;
    for (net, grad, prefix) in [
        (&m.actor, &ga, "actor_network_params.module.0.module.0.params"),
        (&m.critic, &gc, "critic_network_params.module.params"),
    ] {
        for (suffix, at, len) in net.tensors() {
            let (layer, kind) = suffix.split_once('.').unwrap();
            let key = format!("{prefix}.{}.{kind}", 2 * layer.parse::<usize>().unwrap());
            let want = norms[&key].as_f64().unwrap();
            let sq = squared_norm(&grad[at..at + len]);
            total += sq;
            let got = sq.sqrt();
            eprintln!("{key}: {got} vs {want} ({:e})", rel(got, want));
            assert!(rel(got, want) < 1e-5, "{key}");
        }
    }
    let want_total = mb["grad_norm_total_before_clipping"].as_f64().unwrap();
    assert!(rel(total.sqrt(), want_total) < 1e-5);
}

/// A small synthetic minibatch (2 agents, 6 observations, networks 6 -> 8 -> 8 -> 4 and
/// 12 -> 8 -> 8 -> 1) whose actions are drawn near the policy, so the loss is smooth and every
/// term carries gradient.
fn synthetic() -> Minibatch {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha20Rng::seed_from_u64(7);
    let actor = Mlp::init(&[6, 8, 8, 4], &mut rng);
    let critic = Mlp::init(&[12, 8, 8, 1], &mut rng);
    let samples = 10;
    let entries = samples * 2;
    let obs: Vec<f32> = (0..samples * 12).map(|_| rng.random_range(-1.5..1.5)).collect();
    let mut tape = Tape::default();
    actor.forward(&obs, entries, &mut tape);
    let mut action = Vec::new();
    let mut log_prob_old = Vec::new();
    for raw in tape.output().chunks_exact(4) {
        let p = tanh_normal::params(raw, f32::INFINITY);
        let eps = [rng.random_range(-1.0..1.0f32), rng.random_range(-1.0..1.0f32)];
        let a = tanh_normal::sample(&p, eps, HIGH);
        action.extend(a);
        log_prob_old
            .push(tanh_normal::log_prob(&p, a, HIGH).log_prob as f32 + rng.random_range(-0.05..0.05f32));
    }
    Minibatch {
        actor,
        critic,
        obs,
        action,
        log_prob_old,
        advantage: (0..entries).map(|_| rng.random_range(-1.0..1.0)).collect(),
        target: (0..entries).map(|_| rng.random_range(-2.0..2.0)).collect(),
        eps: (0..entries * 2).map(|_| rng.random_range(-1.5..1.5)).collect(),
        samples,
    }
}

/// Central differences of the whole loss (objective + value + entropy terms, through both
/// networks and the TanhNormal head) against the backward pass, for every parameter of every
/// tensor of the synthetic minibatch. The networks run in float32; the step h = 1e-2 with
/// Richardson extrapolation `(4 D(h/2) - D(h)) / 3` (error O(h^4)) keeps the truncation error
/// below 1e-6, and the tolerance (1 % or 2e-4 absolute) covers float32 round-off of the loss
/// (about 1e-7 relative of a loss of order 1, divided by the step).
#[test]
fn network_gradients_match_central_differences() {
    let m = synthetic();
    let (_, ga, gc, _, _) = loss_and_grads(&m, &m.actor, &m.critic);
    let mut worst = 0.0f64;
    for critic_side in [false, true] {
        let net = if critic_side { &m.critic } else { &m.actor };
        let grad = if critic_side { &gc } else { &ga };
        for (i, &analytic) in grad.iter().enumerate() {
            let eval = |delta: f32| {
                let mut p = net.clone();
                p.params[i] += delta;
                let (actor, critic) = if critic_side {
                    (&m.actor, &p)
                } else {
                    (&p, &m.critic)
                };
                loss_and_grads(&m, actor, critic).0.total()
            };
            let h = 1e-2f32;
            let d = |h: f32| (eval(h) - eval(-h)) / f64::from(2.0 * h);
            let numeric = (4.0 * d(h / 2.0) - d(h)) / 3.0;
            let analytic = f64::from(analytic);
            let err = (numeric - analytic).abs();
            worst = worst.max(err / (analytic.abs() + 1e-3));
            assert!(
                err < 0.01 * analytic.abs() + 2e-4,
                "{} param {i}: numeric {numeric} analytic {analytic}",
                if critic_side { "critic" } else { "actor" }
            );
        }
    }
    eprintln!("worst relative gradient error {worst:e}");
}

/// The trainer's MLP (FMA products) and the inference actor (`cpmx-policy`'s kernels) read
/// the same file and agree on SigmaRL's 36 actor test vectors; `to_actor` hands the weights
/// over unchanged.
#[test]
fn training_and_inference_networks_agree() {
    let bytes = std::fs::read(cpmx_testdata::reference_file("policy/actor.safetensors")).unwrap();
    let mlp = Mlp::from_safetensors(&bytes, "actor").unwrap();
    let actor = cpmx_policy::MlpActor::from_bytes_inferred(&bytes, "actor").unwrap();
    assert_eq!(mlp.to_actor().unwrap(), actor);
    let text = cpmx_testdata::read_reference("policy/actor_layout.json");
    let layout: Value = serde_json::from_str(&text).unwrap();
    let vectors = layout["test_vectors"].as_array().unwrap();
    let obs: Vec<f32> = vectors.iter().flat_map(|v| f32s(&v["obs"])).collect();
    let mut tape = Tape::default();
    mlp.forward(&obs, vectors.len(), &mut tape);
    let mut ws = actor.workspace(vectors.len());
    let mut raw = vec![0.0f32; vectors.len() * 4];
    actor.forward(&obs, &mut ws, &mut raw).unwrap();
    let want: Vec<f64> = vectors.iter().flat_map(|v| flat(&v["raw_output"])).collect();
    // One running FMA sum per output (training) against blocked sums (inference) and torch:
    // within 1e-6 relative (outputs reach 3.5).
    for ((&train, &infer), &torch) in tape.output().iter().zip(&raw).zip(&want) {
        let scale = torch.abs().max(1.0);
        assert!(
            (f64::from(train) - torch).abs() < 1e-6 * scale,
            "{train} vs torch {torch}"
        );
        assert!(
            f64::from(train - infer).abs() < 1e-6 * scale,
            "{train} vs inference {infer}"
        );
    }
}

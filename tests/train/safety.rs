//! Training with the safety filter in the loop (a fidelity's `safety:` layer, applied to the
//! learner's actions as `cpmx run` applies it to a policy's) and with SigmaRL's CBF-informed
//! reward (`reward.cbf_margins`: the filter's rows under the joint sampled action).

use crate::column;

/// A small scenario trained in the sim, in the sim with the filter, and through the planner
/// with the filter, each with the CBF-informed reward beside SigmaRL's paper-era reward.
const FILTERED: &str = "cpmx: 1
name: filtered-training
map: {file: maps/cpm.xml}
timing: {dt: 0.1, steps: 30}
agents: 2
policies:
  - {name: plain, mlp: {trained: {seed: 5, fidelity: sim, dir: OUT}}}
  - {name: through-filter, mlp: {trained: {seed: 5, fidelity: sim-safe, dir: OUT}}}
initial_configurations:
  - name: crossing
    agents:
      - {ref_path: 6, arc_length: 0.3}
      - {ref_path: 2, arc_length: 0.3}
repetitions: 1
seed: 1
fidelities:
  sim: {control: direct, dynamics: kinematic}
  sim-safe: {control: direct, dynamics: kinematic, safety: stdlib:sigmarl-cbf}
  sim-mpc-safe: {control: trajectory, dynamics: kinematic, safety: stdlib:sigmarl-cbf}
planner: {control_horizon: 4, prediction_horizon: 12}
training:
  fidelity: [sim, sim-safe, sim-mpc-safe]
  scenario: {extends: stdlib:sigmarl-intersection, envs: 4, agents: 2, episode_steps: 32}
  reward: {extends: stdlib:sigmarl-at25-reward, cbf_margins: {threshold: 0.1}}
  algorithm:
    extends: stdlib:mappo-sigmarl
    mappo: {frames_per_iteration: 128, minibatch: 64, epochs: 2}
  network: {hidden: [32, 32], activation: tanh}
  observation: stdlib:sigmarl
  iterations: 3
  seeds: [5]
";

/// The filter changes the untrained actors' actions in both plants and says so in the curve
/// (a fidelity without it has no such columns); the CBF-informed term is logged, never
/// positive, and costs something while the actors are random; one thread and two give the
/// same actors and curves; the actor trained through the filter runs in every fidelity.
#[test]
fn training_through_the_filter_and_with_the_cbf_informed_reward() {
    let (dir, _) = crate::train_with_one_and_two_threads("train-filtered", FILTERED);
    let out = dir.join("out");
    let header = |fidelity: &str| {
        let curve = std::fs::read_to_string(out.join(fidelity).join("5/learning_curve.csv")).unwrap();
        curve.lines().next().unwrap().to_owned()
    };
    assert!(!header("sim").contains("filtered"), "{}", header("sim"));
    for (fidelity, last) in [
        ("sim-safe", ",filtered,filter_fallbacks"),
        ("sim-mpc-safe", ",filtered,filter_fallbacks,follower_stopped"),
    ] {
        assert!(header(fidelity).ends_with(last), "{}", header(fidelity));
        let filtered = column(&out.join(fidelity), 5, "filtered");
        assert!(filtered.iter().sum::<f64>() > 0.0, "{fidelity}: {filtered:?}");
    }
    for fidelity in ["sim", "sim-safe", "sim-mpc-safe"] {
        let margins = column(&out.join(fidelity), 5, "reward_cbf_margins");
        assert!(margins.iter().all(|&m| m <= 0.0), "{fidelity}: {margins:?}");
        assert!(margins.iter().any(|&m| m < 0.0), "{fidelity}: {margins:?}");
    }
    let per_run = crate::run_trained_spec(&dir, "train-filtered.yaml");
    for fidelity in ["sim", "sim-safe", "sim-mpc-safe"] {
        assert!(
            per_run.contains(&format!("{fidelity}/through-filter/crossing/rep1")),
            "{fidelity}: {per_run}"
        );
    }
}

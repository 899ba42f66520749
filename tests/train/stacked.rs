//! Training in the lab's control architecture (`control: trajectory`) and in a twin
//! randomised per episode, from one spec.

use crate::column;

/// The small scenario in the lab's control architecture: a `control: trajectory` fidelity
/// (`sim-mpc`) and a twin whose actuation delay and positioning noise are drawn per episode.
const STACKED: &str = "cpmx: 1
name: stacked
map: {file: maps/cpm.xml}
timing: {dt: 0.1, steps: 30}
agents: 2
policies:
  - {name: from-sim-mpc, mlp: {trained: {seed: 3, fidelity: sim-mpc, dir: OUT}}}
  - {name: from-twin, mlp: {trained: {seed: 3, fidelity: twin-random, dir: OUT}}}
initial_configurations:
  - name: crossing
    agents:
      - {ref_path: 6, arc_length: 0.3}
      - {ref_path: 2, arc_length: 0.3}
repetitions: 1
seed: 1
fidelities:
  sim: {control: direct, dynamics: kinematic}
  sim-mpc: {control: trajectory, dynamics: kinematic}
  twin-random:
    control: trajectory
    dynamics: stdlib:mu-car-greybox
    sensing: {extends: stdlib:cpm-ips, noise_position_m: {uniform: [0, 0.004]}}
    actuation: {delay_ms: {uniform: [40, 120]}}
planner: {control_horizon: 4, prediction_horizon: 12}
training:
  fidelity: [sim-mpc, twin-random]
  scenario: {extends: stdlib:sigmarl-intersection, envs: 4, agents: 2, episode_steps: 32}
  reward: stdlib:sigmarl-at25-reward
  algorithm:
    extends: stdlib:mappo-sigmarl
    mappo: {frames_per_iteration: 128, minibatch: 64, epochs: 2}
  network: {hidden: [32, 32], activation: tanh}
  observation: stdlib:sigmarl
  iterations: 3
  seeds: [3]
";

/// Training through the planner and the MPC follower, and in a twin randomised per episode,
/// from one spec that lists both fidelities: 3 iterations each give the same actors and curves
/// with one thread and two, the curve of the randomised twin says what was drawn, and both
/// actors run in every fidelity.
#[test]
fn training_in_the_labs_control_architecture_is_deterministic_and_its_actors_run_everywhere() {
    let (dir, table) = crate::train_with_one_and_two_threads("train-stacked", STACKED);
    assert!(table.contains("| twin-random seed 3 | 3 |"), "{table}");
    let out = dir.join("out");
    let curve = std::fs::read_to_string(out.join("twin-random/3/learning_curve.csv")).unwrap();
    assert!(
        curve.contains(",draws,drawn_sensing.noise_position_m,drawn_actuation.delay_ms,"),
        "{curve}"
    );
    let delays = column(&out.join("twin-random"), 3, "drawn_actuation.delay_ms");
    let draws = column(&out.join("twin-random"), 3, "draws");
    assert!(
        draws.iter().sum::<f64>() > 0.0,
        "episodes ended and were drawn anew"
    );
    assert!(
        delays
            .iter()
            .zip(&draws)
            .all(|(d, &n)| n == 0.0 || (40.0..120.0).contains(d)),
        "{delays:?}"
    );
    // The curves of both stacked fidelities count the periods the lab's follower stopped a
    // car in; it refuses some of the untrained actor's jittery plans through the kinematic
    // MPC (16-25 periods an iteration; none in these few twin episodes).
    for fidelity in ["sim-mpc", "twin-random"] {
        let text = std::fs::read_to_string(out.join(fidelity).join("3/learning_curve.csv")).unwrap();
        let header = text.lines().next().unwrap_or_default();
        assert!(header.ends_with(",follower_stopped"), "{fidelity}: {header}");
    }
    let stopped = column(&out.join("sim-mpc"), 3, "follower_stopped");
    assert!(stopped.iter().all(|&n| n > 0.0), "{stopped:?}");
    // Both actors in every fidelity.
    let per_run = crate::run_trained_spec(&dir, "train-stacked.yaml");
    for fidelity in ["sim", "sim-mpc", "twin-random"] {
        for policy in ["from-sim-mpc", "from-twin"] {
            assert!(
                per_run.contains(&format!("{fidelity}/{policy}/crossing/rep1")),
                "{fidelity}/{policy}: {per_run}"
            );
        }
    }
}

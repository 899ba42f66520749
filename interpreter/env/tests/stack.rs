//! Environments whose vehicles run the lab's control architecture (`control: trajectory`):
//! they move through planner and follower, randomise their fidelity per episode, give the same
//! results on any number of threads, and a saved state restores by replay to exactly the same
//! continuation.

use cpmx_env::{EnvConfig, Plant, StackPlant, StepResult, VecEnv, sigmarl_intersection_paths};
use cpmx_planner::{PlannerParams, SteeringAfterHc};
use cpmx_spec::model::{
    ActuationLayer, ActuationModel, Control, Distribution, DynamicsLayer, GreyBoxModel, KinematicKeyword,
    Lookahead, Parameter, SensingLayer, SensingModel, SimulatedFidelity,
};
use cpmx_world::ReferencePath;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

fn paths() -> Vec<ReferencePath> {
    sigmarl_intersection_paths(&cpmx_testdata::reference_file("maps/cpm.xml")).expect("map")
}

const PAPER_PLANNER: PlannerParams = PlannerParams {
    control_horizon: 4,
    prediction_horizon: 12,
    step_s: 0.1,
    steering_after: SteeringAfterHc::LinearToZero,
};

/// sim-mpc: the kinematic bicycle behind the planner and the MPC follower.
fn sim_mpc() -> SimulatedFidelity {
    SimulatedFidelity {
        control: Control::Trajectory,
        dynamics: DynamicsLayer::Kinematic(KinematicKeyword::Kinematic),
        sensing: None,
        actuation: None,
        follower: None,
        communication: None,
        perception: None,
        safety: None,
    }
}

/// The twin with a randomised actuation delay and positioning noise.
fn random_twin() -> SimulatedFidelity {
    let fixed = Parameter::Fixed;
    let uniform = |low, high| Parameter::Drawn(Distribution::Uniform([low, high]));
    SimulatedFidelity {
        control: Control::Trajectory,
        dynamics: DynamicsLayer::GreyBox(GreyBoxModel {
            parameters: cpmx_vehicle::LAB_GREYBOX_PARAMETERS.map(fixed),
            euler_step_s: fixed(0.02),
            battery_voltage_v: fixed(7.8),
        }),
        sensing: Some(SensingLayer::Model(SensingModel {
            rate_hz: fixed(50.0),
            latency_ms: fixed(60.0),
            noise_position_m: uniform(0.0, 0.004),
            noise_yaw_rad: fixed(0.01),
            drop_probability: fixed(0.05),
            fusion_gain: fixed(0.3),
        })),
        actuation: Some(ActuationLayer::Model(ActuationModel {
            delay_ms: uniform(40.0, 120.0),
        })),
        follower: None,
        communication: None,
        perception: None,
        safety: None,
    }
}

fn config(fidelity: SimulatedFidelity, envs: usize) -> EnvConfig {
    let mut c = EnvConfig::default();
    c.scenario.envs = envs;
    c.plant = Plant::Stack(Box::new(StackPlant {
        fidelity,
        planner: PAPER_PLANNER,
        lookahead: Lookahead::Actor,
    }));
    c
}

/// Commands that drive forward with some steering, from their own stream.
fn actions(rng: &mut ChaCha20Rng, n: usize) -> Vec<f32> {
    (0..n)
        .flat_map(|_| [rng.random_range(0.3f32..1.0), rng.random_range(-0.3f32..0.3)])
        .collect()
}

fn rollout(env: &mut VecEnv, steps: usize, seed: u64) -> Vec<StepResult> {
    let mut rng = ChaCha20Rng::seed_from_u64(seed);
    let n = env.num_envs() * env.num_agents();
    (0..steps).map(|_| env.step(&actions(&mut rng, n))).collect()
}

#[test]
fn vehicles_follow_their_plans_and_the_observation_sees_what_they_report() {
    let paths = paths();
    let mut stacked = VecEnv::new(config(sim_mpc(), 4), &paths, 1).unwrap();
    let mut direct_config = config(sim_mpc(), 4);
    direct_config.plant = Plant::Direct;
    let mut direct = VecEnv::new(direct_config, &paths, 1).unwrap();
    // The same starts: placement does not depend on the plant.
    assert_eq!(stacked.placements(2), direct.placements(2));
    let a = rollout(&mut stacked, 40, 3);
    let b = rollout(&mut direct, 40, 3);
    // The follower tracks the policy's plan, so the cars move about as far as in SigmaRL's
    // simulation, but not the same way: they differ.
    assert_ne!(a[5].observations, b[5].observations);
    let moved = |r: &[StepResult]| r.iter().map(|s| s.reward_terms.progress).sum::<f64>();
    let (stack_progress, direct_progress) = (moved(&a), moved(&b));
    assert!(
        stack_progress > 0.3 * direct_progress && stack_progress < 3.0 * direct_progress,
        "{stack_progress} vs {direct_progress}"
    );
    assert!(a.iter().all(|r| r.rewards.iter().all(|v| v.is_finite())));
    assert!(stacked.failure().is_none());
    // A fixed fidelity draws nothing.
    assert!(a.iter().all(|r| r.draws == 0));
    assert!(stacked.randomised_parameters().is_empty());
}

#[test]
fn randomised_episodes_draw_in_range_and_threads_do_not_matter() {
    let paths = paths();
    let mut serial = VecEnv::new(config(random_twin(), 6), &paths, 2).unwrap();
    serial.set_parallel(false);
    let mut parallel = VecEnv::new(config(random_twin(), 6), &paths, 2).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
    let a = rollout(&mut serial, 130, 4);
    let b = pool.install(|| rollout(&mut parallel, 130, 4));
    assert_eq!(a, b);
    assert_eq!(
        serial.randomised_parameters(),
        ["sensing.noise_position_m", "actuation.delay_ms"]
    );
    let draws: u64 = a.iter().map(|r| r.draws).sum();
    assert!(
        draws >= 6,
        "every environment ended an episode within 127 steps: {draws}"
    );
    let (noise, delay): (f64, f64) = a
        .iter()
        .filter(|r| r.draws > 0)
        .map(|r| (r.drawn_parameter_sums[0], r.drawn_parameter_sums[1]))
        .fold((0.0, 0.0), |(n, d), (x, y)| (n + x, d + y));
    let (noise, delay) = (noise / draws as f64, delay / draws as f64);
    assert!((0.0..0.004).contains(&noise), "{noise}");
    assert!((40.0..120.0).contains(&delay), "{delay}");
}

#[test]
fn a_saved_state_restores_by_replay_to_the_same_continuation() {
    let paths = paths();
    let mut a = VecEnv::new(config(random_twin(), 3), &paths, 5).unwrap();
    rollout(&mut a, 57, 6);
    let saved = a.save_state();
    // Another environment (other seed, other history) takes the state over.
    let mut b = VecEnv::new(config(random_twin(), 3), &paths, 77).unwrap();
    rollout(&mut b, 9, 1);
    b.load_state(&saved).expect("loads");
    assert_eq!(b.save_state(), saved);
    let (ra, rb) = (rollout(&mut a, 150, 8), rollout(&mut b, 150, 8));
    for (k, (x, y)) in ra.iter().zip(&rb).enumerate() {
        assert_eq!(x, y, "step {k} after the restore");
    }
    // A damaged state changes nothing.
    let before = b.save_state();
    assert!(b.load_state(&saved[..saved.len() - 9]).is_err());
    assert_eq!(b.save_state(), before);
}

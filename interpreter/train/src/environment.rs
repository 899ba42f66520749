//! The join of the scenario and the learner: `cpmx-env`'s [`VecEnv`] as a
//! [`cpmx_learn::Environment`]. The learner sees observations, rewards, done flags, the mean
//! of each reward term and the collision and reset counts; the environment's state goes into
//! the learner's checkpoints.

use cpmx_env::{EnvConfig, RewardConfig, RewardTermMeans, StepResult, VecEnv};
use cpmx_learn::Environment;
use cpmx_world::ReferencePath;

/// The reward terms `learning_curve.csv` has a column for (`reward_<term>`), in the order of
/// [`cpmx_learn::StepResult::reward_term_means`]: SigmaRL's five always (so a SigmaRL reward's
/// curve keeps its columns), every other term the reward has, and `total`, the clamped
/// reward, last.
pub fn reward_term_names(reward: &RewardConfig) -> Vec<&'static str> {
    let mut names = vec![
        "progress",
        "near_boundary",
        "near_agents_ttc",
        "collide_agents",
        "collide_boundary",
    ];
    if reward.speed.is_some() {
        names.push("speed");
    }
    if reward.centre_line.is_some() {
        names.push("centre_line");
    }
    if reward.near_agents.is_some() {
        names.push("near_agents");
    }
    if reward.velocity_to_points.is_some() {
        names.push("velocity_to_points");
    }
    if reward.time.is_some() {
        names.push("time");
    }
    if reward.steering_change.is_some() {
        names.push("steering_change");
    }
    if reward.cbf_margins.is_some() {
        names.push("cbf_margins");
    }
    names.push("total");
    names
}

fn term_mean(means: &RewardTermMeans, name: &str) -> f64 {
    match name {
        "progress" => means.progress,
        "near_boundary" => means.near_boundary,
        "near_agents_ttc" => means.near_agents_ttc,
        "collide_agents" => means.collide_agents,
        "collide_boundary" => means.collide_boundary,
        "speed" => means.speed,
        "centre_line" => means.centre_line,
        "near_agents" => means.near_agents,
        "velocity_to_points" => means.velocity_to_points,
        "time" => means.time,
        "steering_change" => means.steering_change,
        "cbf_margins" => means.cbf_margins,
        _ => means.total,
    }
}

/// SigmaRL's training scenario stepped for the learner.
#[derive(Debug)]
pub struct TrainingEnv {
    env: VecEnv,
    /// The terms reported, from [`reward_term_names`].
    terms: Vec<&'static str>,
    /// Reused between steps.
    result: StepResult,
}

impl TrainingEnv {
    /// `config.scenario.envs` environments on `paths` with the random streams of `seed`.
    pub fn new(config: EnvConfig, paths: &[ReferencePath], seed: u64) -> Result<Self, cpmx_env::ConfigError> {
        Ok(TrainingEnv {
            terms: reward_term_names(&config.reward),
            env: VecEnv::new(config, paths, seed)?,
            result: StepResult::default(),
        })
    }
}

impl Environment for TrainingEnv {
    fn num_envs(&self) -> usize {
        self.env.num_envs()
    }

    fn num_agents(&self) -> usize {
        self.env.num_agents()
    }

    fn obs_dim(&self) -> usize {
        self.env.obs_dim()
    }

    fn reward_terms(&self) -> Vec<String> {
        self.terms.iter().map(|t| (*t).to_owned()).collect()
    }

    fn reset_all(&mut self) -> Vec<f32> {
        self.env.reset_all()
    }

    fn step(&mut self, actions: &[f32]) -> Result<cpmx_learn::StepResult, String> {
        self.env.step_into(actions, &mut self.result);
        if let Some(failure) = self.env.failure() {
            return Err(failure.to_owned());
        }
        let r = &self.result;
        let t = &r.reward_terms;
        Ok(cpmx_learn::StepResult {
            observations: r.observations.clone(),
            rewards: r.rewards.clone(),
            done: r.done.clone(),
            reward_term_means: self.terms.iter().map(|name| term_mean(t, name)).collect(),
            collisions: r.collisions.with_agents + r.collisions.with_boundary,
            env_resets: r.resets.environments,
            agent_resets: r.resets.agents,
            drawn_parameter_sums: r.drawn_parameter_sums.clone(),
            draws: r.draws,
            filtered: r.filtered,
            filter_fallbacks: r.filter_fallbacks,
            follower_stopped: r.follower_stopped,
        })
    }

    fn set_actor(&mut self, actor: &cpmx_learn::Mlp) -> Result<(), String> {
        if !self.env.has_stacks() {
            return Ok(());
        }
        let actor = actor.to_actor().map_err(|e| e.to_string())?;
        self.env.set_actor(&actor).map_err(|e| e.to_string())
    }

    fn randomised_parameters(&self) -> Vec<String> {
        self.env.randomised_parameters()
    }

    fn filters(&self) -> bool {
        self.env.config().safety.is_some()
    }

    fn follows(&self) -> bool {
        self.env.has_stacks()
    }

    fn save_state(&self) -> Vec<u8> {
        self.env.save_state()
    }

    fn load_state(&mut self, state: &[u8]) -> Result<(), String> {
        self.env.load_state(state)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cpmx_env::{Plant, StackPlant, sigmarl_intersection_paths};
    use cpmx_learn::{Hyperparameters, Trainer};
    use cpmx_spec::model::{
        ActuationLayer, ActuationModel, Control, Distribution, DynamicsLayer, KinematicKeyword, Lookahead,
        Parameter, SimulatedFidelity,
    };
    use rand::SeedableRng;
    use rand_chacha::ChaCha20Rng;

    /// sim-mpc with an actuation delay drawn per episode, 3 environments of 2 agents.
    fn stacked_env(seed: u64) -> TrainingEnv {
        stacked_env_with(seed, Lookahead::Actor)
    }

    fn stacked_env_with(seed: u64, lookahead: Lookahead) -> TrainingEnv {
        let map = cpmx_testdata::reference_file("maps/cpm.xml");
        let paths = sigmarl_intersection_paths(&map).expect("the CPM Lab map of SigmaRL's reference data");
        let mut config = EnvConfig::default();
        config.scenario.envs = 3;
        config.scenario.agents = 2;
        config.scenario.episode_steps = 24;
        config.plant = Plant::Stack(Box::new(StackPlant {
            fidelity: SimulatedFidelity {
                control: Control::Trajectory,
                dynamics: DynamicsLayer::Kinematic(KinematicKeyword::Kinematic),
                sensing: None,
                actuation: Some(ActuationLayer::Model(ActuationModel {
                    delay_ms: Parameter::Drawn(Distribution::Uniform([20.0, 100.0])),
                })),
                follower: None,
                communication: None,
                perception: None,
                safety: None,
            },
            planner: cpmx_planner::PlannerParams {
                control_horizon: 4,
                prediction_horizon: 12,
                step_s: 0.1,
                steering_after: cpmx_planner::SteeringAfterHc::LinearToZero,
            },
            lookahead,
        }));
        TrainingEnv::new(config, &paths, seed).expect("environment")
    }

    fn hyperparameters() -> Hyperparameters {
        Hyperparameters {
            frames_per_batch: 3 * 20,
            minibatch_size: 30,
            num_epochs: 2,
            actor_hidden: vec![16],
            critic_hidden: vec![16],
            ..Hyperparameters::sigmarl(5)
        }
    }

    /// The observations of 30 steps of fixed actions after the learner handed over an actor
    /// initialised from `actor_seed`.
    fn observations_with_actor(lookahead: Lookahead, actor_seed: u64) -> Vec<Vec<f32>> {
        let mut env = stacked_env_with(5, lookahead);
        let sizes = [env.obs_dim(), 16, 4];
        let actor = cpmx_learn::Mlp::init(&sizes, &mut ChaCha20Rng::seed_from_u64(actor_seed));
        env.set_actor(&actor).unwrap();
        env.reset_all();
        let actions: Vec<f32> = (0..env.num_envs() * env.num_agents())
            .flat_map(|i| [0.4 + 0.05 * i as f32, 0.1])
            .collect();
        (0..30)
            .map(|_| env.step(&actions).unwrap().observations)
            .collect()
    }

    /// `lookahead: actor` plans Hc with the actor handed over, so another actor drives the
    /// vehicles elsewhere; `lookahead: hold` holds the learner's action and never asks it.
    #[test]
    fn the_lookahead_plans_with_the_actor_or_holds_the_action() {
        assert_ne!(
            observations_with_actor(Lookahead::Actor, 1),
            observations_with_actor(Lookahead::Actor, 2)
        );
        let held = observations_with_actor(Lookahead::Hold, 1);
        assert_eq!(held, observations_with_actor(Lookahead::Hold, 2));
        assert_ne!(held, observations_with_actor(Lookahead::Actor, 1));
    }

    /// A trainer restored from a checkpoint mid-episode (the vehicle stacks replayed, the
    /// planner's lookahead handed the restored actor) continues to the same weights, curve rows
    /// and checkpoint as one that never stopped.
    #[test]
    fn a_stacked_run_resumes_exactly_through_the_learner() {
        let mut whole = Trainer::new(stacked_env(4), hyperparameters(), 4).unwrap();
        let mut records = Vec::new();
        for _ in 0..2 {
            records.push(whole.iterate().unwrap());
        }
        let saved = whole.checkpoint();
        let mut resumed = Trainer::resume(stacked_env(99), hyperparameters(), &saved).unwrap();
        for _ in 0..2 {
            let (mut a, mut b) = (whole.iterate().unwrap(), resumed.iterate().unwrap());
            for r in [&mut a, &mut b] {
                (r.collect_seconds, r.update_seconds) = (0.0, 0.0);
            }
            assert_eq!(a, b);
            records.push(a);
        }
        assert_eq!(whole.actor().params, resumed.actor().params);
        assert_eq!(whole.checkpoint(), resumed.checkpoint());
        // Episodes of 23 steps end within each iteration's 20 steps per environment: the
        // delay was drawn anew, in its range.
        let drawn: Vec<f64> = records
            .iter()
            .filter(|r| r.draws > 0)
            .map(|r| r.drawn_parameter_means[0])
            .collect();
        assert!(
            !drawn.is_empty() && drawn.iter().all(|d| (20.0..100.0).contains(d)),
            "{drawn:?}"
        );
    }
}

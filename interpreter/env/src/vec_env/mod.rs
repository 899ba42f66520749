//! [`VecEnv`]: E independent environments of N agents, stepped together (in parallel with
//! rayon; every environment owns its random stream, so results do not depend on the number
//! of threads).
//!
//! One step of one environment, in SigmaRL's order (VMAS `step`, then `reward` for every
//! agent, `observation`, `done`; `road_traffic.py`):
//! 1. every agent moves by one float32 kinematic-bicycle step;
//! 2. the step counter is incremented; corners, collisions and entry/exit contacts are
//!    computed for the new states;
//! 3. each agent's reward (boundary distances of agent 0 with its corners of the start of the
//!    step when the observation lags them), then its short-term reference points are renewed;
//! 4. the observations of the new states;
//! 5. done (collision or step counter = `episode_steps - 1`, by the reset rules); a done
//!    environment is re-placed whole and returns its reset observation for the next action;
//!    otherwise agents on their entry or exit line are re-placed alone, keeping the
//!    pre-reset observation of this step (SigmaRL's stale observation).

use cpmx_policy::{ActionMode, AgentPaths, MlpActor, MlpPolicy};
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::Lookahead;
use cpmx_world::{Point, ReferencePath};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;
use rayon::prelude::*;
use std::sync::Arc;

use cpmx_safety::layer::{self, Lane, LayerFilter};

use crate::config::{ConfigError, EnvConfig, Plant};
use crate::neighbours::EnvNeighbours;
use crate::paths::{TrainingPath, prepare_paths};
use crate::result::{AgentStepInfo, StepResult, StepTotals};
use crate::stack_world::StackWorld;
use crate::starts::Placement;

mod episode;

use cpmx_stack::step_together;
use episode::{Agent, Env, Moving, Scratch, StepEnd};

/// The vehicles whose loops one call steps together when environments drive the lab's
/// stack: three passes of eight SIMD lanes.
const LOOP_VEHICLES: usize = 3 * cpmx_follower::WIDEST_LANES;

/// E environments of N agents on a set of reference paths. See the crate documentation.
#[derive(Debug)]
pub struct VecEnv {
    config: EnvConfig,
    paths: Vec<TrainingPath>,
    envs: Vec<Env>,
    obs_dim: usize,
    parallel: bool,
}

impl VecEnv {
    /// `config.scenario.envs` environments on `paths` (the path set agents are drawn from),
    /// with random streams `train/env/<e>` of `seed` (see `cpmx_spec::matrix`). The
    /// environments are placed (as by [`VecEnv::reset_all`]) before this returns.
    pub fn new(config: EnvConfig, paths: &[ReferencePath], seed: u64) -> Result<Self, ConfigError> {
        config.check()?;
        // Each path's lane (its shared road boundaries), for the filter and the CBF rows.
        let lanes: Option<Arc<[Lane]>> = if config.safety.is_some() || config.reward.cbf_margins.is_some() {
            let lane_of = |p: &ReferencePath| {
                Some((
                    layer::boundary(&p.left_boundary_shared)?,
                    layer::boundary(&p.right_boundary_shared)?,
                ))
            };
            Some(
                paths
                    .iter()
                    .map(lane_of)
                    .collect::<Option<Arc<[Lane]>>>()
                    .ok_or(ConfigError::Lanes)?,
            )
        } else {
            None
        };
        let paths = prepare_paths(paths, config.scenario.start.first_index)?;
        let (n, points) = (
            config.scenario.agents,
            config
                .reward
                .progress
                .as_ref()
                .map_or(0, |p| p.point_weights.len()),
        );
        let stack_rng =
            |e: usize| ChaCha20Rng::from_seed(stream_key(seed, &format!("train/randomisation/{e}")));
        let mut stacks = Vec::with_capacity(config.scenario.envs);
        for e in 0..config.scenario.envs {
            stacks.push(match &config.plant {
                Plant::Direct => None,
                Plant::Stack(plant) => Some(
                    StackWorld::new(plant, config.vehicle, config.dt_s, stack_rng(e))
                        .map_err(ConfigError::Stack)?,
                ),
            });
        }
        let filter = match (&config.safety, &lanes) {
            (Some(parameters), Some(lanes)) => {
                Some(LayerFilter::new(parameters.clone(), lanes.clone(), vec![0; n]))
            }
            _ => None,
        };
        let envs = stacks
            .into_iter()
            .enumerate()
            .map(|(e, stack)| Env {
                agents: vec![
                    Agent {
                        placement: crate::starts::placement_at(&paths[0], 0, paths[0].start_indices.0, 0.0),
                        prev_pos: [0.0; 2],
                        short_term: vec![[0.0; 2]; points],
                        prev_steering_cmd_rad: 0.0,
                    };
                    n
                ],
                paths: AgentPaths::from_shared(vec![paths[0].prepared.clone(); n]),
                counter: 0,
                rng: ChaCha20Rng::from_seed(stream_key(seed, &format!("train/env/{e}"))),
                episode_reward: vec![0.0; n],
                corners_start: vec![[[0.0; 2]; 4]; n],
                stack,
                failure: None,
                final_observation: None,
                neighbours: EnvNeighbours::new(&config.neighbours, n, seed, e),
                filter: filter.clone(),
                lanes: lanes.clone(),
                scratch: Scratch::default(),
            })
            .collect();
        let obs_dim = config.observation.size();
        let mut env = VecEnv {
            config,
            paths,
            envs,
            obs_dim,
            parallel: true,
        };
        env.reset_all();
        if let Some(failure) = env.failure() {
            return Err(ConfigError::Stack(failure.to_owned()));
        }
        Ok(env)
    }

    /// Hands the environments the learner's current actor: the planner of a
    /// `control: trajectory` plant looks ahead with its mean actions (nothing else uses it, nor
    /// a plant whose lookahead holds the learner's action).
    pub fn set_actor(&mut self, actor: &MlpActor) -> Result<(), ConfigError> {
        match &self.config.plant {
            Plant::Stack(plant) if plant.lookahead == Lookahead::Actor => {}
            _ => return Ok(()),
        }
        let policy = MlpPolicy::new(
            actor.clone(),
            self.config.observation,
            ActionMode::Mean,
            ChaCha20Rng::from_seed([0; 32]),
        )
        .map_err(|e| ConfigError::Stack(e.to_string()))?;
        for env in &mut self.envs {
            if let Some(stack) = &mut env.stack {
                stack.set_lookahead(policy.clone());
            }
        }
        Ok(())
    }

    /// Why a vehicle stack failed, if one did (the environments cannot go on).
    pub fn failure(&self) -> Option<&str> {
        self.envs.iter().find_map(|e| e.failure.as_deref())
    }

    /// Names of the fidelity parameters drawn per episode, in the order of
    /// [`StepResult::drawn_parameter_sums`].
    pub fn randomised_parameters(&self) -> Vec<String> {
        match &self.config.plant {
            Plant::Direct => Vec::new(),
            Plant::Stack(plant) => plant.randomised_parameters(),
        }
    }

    /// Number of environments E.
    pub fn num_envs(&self) -> usize {
        self.envs.len()
    }

    /// Agents per environment N.
    pub fn num_agents(&self) -> usize {
        self.config.scenario.agents
    }

    /// Values per observation.
    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// The configuration.
    pub fn config(&self) -> &EnvConfig {
        &self.config
    }

    /// Whether steps keep the observation each ending episode ended in, before the reset
    /// replaces it ([`StepResult::final_observations`]; Gymnasium's `final_obs`). Off by
    /// default: the learner bootstraps nothing from it.
    pub fn set_keep_final_observations(&mut self, keep: bool) {
        let size = self.num_agents() * self.obs_dim;
        for env in &mut self.envs {
            env.final_observation = keep.then(|| vec![0.0; size]);
        }
    }

    /// Re-places the environments whose `mask` entry is true (new random starts, step
    /// counters and returns zeroed) and writes their observations into their rows of
    /// `observations` (`[E][N][obs_dim]`); the other rows are left as they are.
    pub fn reset_masked(&mut self, mask: &[bool], observations: &mut [f32]) {
        let (config, paths) = (&self.config, &self.paths);
        let chunk = self.num_agents() * self.obs_dim;
        for ((env, out), _) in self
            .envs
            .iter_mut()
            .zip(observations.chunks_mut(chunk))
            .zip(mask)
            .filter(|(_, reset)| **reset)
        {
            env.reset_whole(config, paths);
            env.observe(config, None, out);
            if let Some(stack) = &mut env.stack {
                stack.take_fresh_draw();
            }
        }
    }

    /// Whether [`VecEnv::step`] spreads environments over rayon's threads (default: yes; the
    /// results are the same either way).
    pub fn set_parallel(&mut self, parallel: bool) {
        self.parallel = parallel;
    }

    /// Re-places every environment (new random starts, step counters and returns zeroed) and
    /// returns the observations, `[E][N][obs_dim]` flattened.
    pub fn reset_all(&mut self) -> Vec<f32> {
        let mut obs = vec![0.0f32; self.envs.len() * self.num_agents() * self.obs_dim];
        let (config, paths) = (&self.config, &self.paths);
        let chunk = self.num_agents() * self.obs_dim;
        for (env, out) in self.envs.iter_mut().zip(obs.chunks_mut(chunk)) {
            env.reset_whole(config, paths);
            env.observe(config, None, out);
            if let Some(stack) = &mut env.stack {
                stack.take_fresh_draw();
            }
        }
        obs
    }

    /// Places agent `agent` of environment `env` as given (a reset of that agent without
    /// drawing), and sets the step counter. For replaying recorded episodes.
    pub fn place(&mut self, env: usize, agent: usize, placement: Placement, step_counter: u32) {
        let (config, paths) = (&self.config, &self.paths);
        let e = &mut self.envs[env];
        e.set(config, paths, agent, placement);
        e.counter = step_counter;
    }

    /// The current observation of environment `env` (as returned after a reset).
    pub fn observe(&self, env: usize) -> Vec<f32> {
        let mut out = vec![0.0; self.num_agents() * self.obs_dim];
        self.envs[env].observe_const(&self.config, &mut out);
        out
    }

    /// The current placement (state, path, point) of every agent of environment `env`.
    pub fn placements(&self, env: usize) -> Vec<Placement> {
        self.envs[env].agents.iter().map(|a| a.placement).collect()
    }

    /// The agents' placements in environment `env`, or `None` when there is no such
    /// environment.
    pub fn placements_checked(&self, env: usize) -> Option<Vec<Placement>> {
        (env < self.envs.len()).then(|| self.placements(env))
    }

    /// Every road boundary of the path set, for drawing.
    pub(crate) fn outlines(&self) -> impl Iterator<Item = &[Point]> {
        self.paths
            .iter()
            .flat_map(|p| p.outline.iter().map(Vec::as_slice))
    }

    /// The centre line of path `index` of the path set.
    pub(crate) fn path_centre(&self, index: usize) -> Vec<Point> {
        self.paths
            .get(index)
            .map(|p| p.prepared.center_points.clone())
            .unwrap_or_default()
    }

    /// Size of the path set agents are placed on.
    pub(crate) fn path_count(&self) -> usize {
        self.paths.len()
    }

    /// What [`VecEnv::save_state`] stores of environment `env`: counter, random stream,
    /// running returns, placements and the agents' previous steering commands.
    pub(crate) fn env_parts(&self, env: usize) -> (u32, &ChaCha20Rng, &[f32], Vec<Placement>, Vec<f64>) {
        let e = &self.envs[env];
        let steering = e.agents.iter().map(|a| a.prev_steering_cmd_rad).collect();
        (
            e.counter,
            &e.rng,
            &e.episode_reward,
            self.placements(env),
            steering,
        )
    }

    /// Sets environment `env` to a saved state: every agent re-placed (which renews its
    /// short-term points and start corners), then counter, stream, returns and the previous
    /// steering commands.
    pub(crate) fn restore_env(
        &mut self,
        env: usize,
        counter: u32,
        rng: ChaCha20Rng,
        returns: &[f32],
        placements: &[Placement],
        prev_steering_cmds_rad: &[f64],
    ) {
        let (config, paths) = (&self.config, &self.paths);
        let e = &mut self.envs[env];
        for (i, &p) in placements.iter().enumerate() {
            e.set(config, paths, i, p);
        }
        for (a, &c) in e.agents.iter_mut().zip(prev_steering_cmds_rad) {
            a.prev_steering_cmd_rad = c;
        }
        e.counter = counter;
        e.rng = rng;
        e.episode_reward.copy_from_slice(returns);
    }

    /// Environment `env`'s vehicle stacks, if its plant has them.
    pub(crate) fn env_neighbours(&self, env: usize) -> Option<&EnvNeighbours> {
        self.envs.get(env).and_then(|e| e.neighbours.as_ref())
    }

    pub(crate) fn set_env_neighbours(&mut self, env: usize, neighbours: EnvNeighbours) {
        if let Some(e) = self.envs.get_mut(env) {
            e.neighbours = Some(neighbours);
        }
    }

    pub(crate) fn stack_world(&self, env: usize) -> Option<&StackWorld> {
        self.envs[env].stack.as_ref()
    }

    /// Whether the plant runs vehicle stacks (`control: trajectory`).
    pub fn has_stacks(&self) -> bool {
        matches!(self.config.plant, Plant::Stack(_))
    }

    /// Environment `env`'s vehicle stacks as saved in `r` (see `stack_world.rs`).
    pub(crate) fn load_stack_world(
        &self,
        env: usize,
        r: &mut crate::state::Reader<'_>,
    ) -> Result<StackWorld, String> {
        let (Some(world), Plant::Stack(plant)) = (&self.envs[env].stack, &self.config.plant) else {
            return Err("this environment has no vehicle stacks".into());
        };
        world.load(plant, self.config.vehicle, self.num_agents(), r)
    }

    /// Replaces environment `env`'s vehicle stacks.
    pub(crate) fn set_stack_world(&mut self, env: usize, world: StackWorld) {
        self.envs[env].stack = Some(world);
    }

    /// The current step counter of environment `env`.
    pub fn step_counter(&self, env: usize) -> u32 {
        self.envs[env].counter
    }

    /// One step of every environment with `actions` (`[E][N][2]` flattened: speed command
    /// [m/s], steering command [rad]).
    ///
    /// # Panics
    /// If `actions` does not hold `E * N * 2` values (a caller's programming error).
    pub fn step(&mut self, actions: &[f32]) -> StepResult {
        let mut result = StepResult::new(self.num_envs(), self.num_agents(), self.obs_dim);
        self.step_into(actions, &mut result);
        result
    }

    /// [`VecEnv::step`] into a reused result.
    #[allow(clippy::type_complexity)]
    pub fn step_into(&mut self, actions: &[f32], result: &mut StepResult) {
        let (e, n, d) = (self.num_envs(), self.num_agents(), self.obs_dim);
        assert_eq!(
            actions.len(),
            e * n * 2,
            "actions must hold envs x agents x 2 values"
        );
        result.resize(e, n, d);
        let (config, paths) = (&self.config, &self.paths);
        // First halves: commands, filters; the sim's bicycles step, the stacks' periods are planned.
        let begin = |(env, act): (&mut Env, &[f32])| env.begin_step(config, act);
        let moving: Vec<Moving> = if self.parallel {
            self.envs
                .par_iter_mut()
                .zip(actions.par_chunks(n * 2))
                .with_min_len(2)
                .map(begin)
                .collect()
        } else {
            self.envs
                .iter_mut()
                .zip(actions.chunks(n * 2))
                .map(begin)
                .collect()
        };
        // The vehicle stacks' loops, the vehicles of several environments stepped together so
        // that their MPCs fill the SIMD lanes (each vehicle keeps the bits of its own step).
        if moving.iter().any(Moving::loops_pending) {
            let envs_together = LOOP_VEHICLES.div_ceil(n).max(1);
            let step_loops = |(envs, moving): (&mut [Env], &[Moving])| {
                let periods = envs.iter().map(Env::loop_periods).max().unwrap_or(0);
                for sub in 0..periods {
                    step_together(
                        envs.iter_mut()
                            .zip(moving)
                            .filter(|(_, moving)| moving.loops_pending())
                            .flat_map(|(env, _)| env.loop_vehicles(sub)),
                    );
                }
            };
            if self.parallel {
                self.envs
                    .par_chunks_mut(envs_together)
                    .zip(moving.par_chunks(envs_together))
                    .for_each(step_loops);
            } else {
                self.envs
                    .chunks_mut(envs_together)
                    .zip(moving.chunks(envs_together))
                    .for_each(step_loops);
            }
        }
        // Second halves: collisions, rewards, observations, resets.
        let work = |(((env, moving), obs), (rew, (ret, info))): (
            ((&mut Env, Moving), &mut [f32]),
            (&mut [f32], (&mut [f32], &mut [AgentStepInfo])),
        )| env.end_step(config, paths, moving, obs, rew, ret, info);
        let outcomes: Vec<(StepEnd, StepTotals)> = if self.parallel {
            self.envs
                .par_iter_mut()
                .zip(moving)
                .zip(result.observations.par_chunks_mut(n * d))
                .zip(
                    result.rewards.par_chunks_mut(n).zip(
                        result
                            .episode_reward
                            .par_chunks_mut(n)
                            .zip(result.agents.par_chunks_mut(n)),
                    ),
                )
                .with_min_len(2)
                .map(work)
                .collect()
        } else {
            self.envs
                .iter_mut()
                .zip(moving)
                .zip(result.observations.chunks_mut(n * d))
                .zip(
                    result.rewards.chunks_mut(n).zip(
                        result
                            .episode_reward
                            .chunks_mut(n)
                            .zip(result.agents.chunks_mut(n)),
                    ),
                )
                .map(work)
                .collect()
        };
        // Sums in environment order: the same on any number of threads.
        let mut totals = StepTotals::default();
        for (i, (end, t)) in outcomes.into_iter().enumerate() {
            result.done[i] = end.done;
            result.terminated[i] = end.done;
            result.truncated[i] = end.time_limit;
            totals.add(&t);
        }
        // The observations the ended episodes ended in, when kept.
        result.final_observations.clear();
        if self.envs.iter().any(|env| env.final_observation.is_some()) {
            let chunk = n * d;
            result.final_observations.resize(e * chunk, 0.0);
            for ((env, out), done) in self
                .envs
                .iter()
                .zip(result.final_observations.chunks_mut(chunk))
                .zip(&result.done)
            {
                if let (true, Some(last)) = (*done, &env.final_observation) {
                    out.copy_from_slice(last);
                }
            }
        }
        result.set_totals(totals, e * n);
        // The fidelity parameters of the episodes that began at this step.
        result.drawn_parameter_sums.clear();
        result.draws = 0;
        for env in &mut self.envs {
            if let Some(drawn) = env.stack.as_mut().and_then(StackWorld::take_fresh_draw) {
                result.drawn_parameter_sums.resize(drawn.len(), 0.0);
                for (sum, v) in result.drawn_parameter_sums.iter_mut().zip(drawn) {
                    *sum += v;
                }
                result.draws += 1;
            }
        }
    }
}

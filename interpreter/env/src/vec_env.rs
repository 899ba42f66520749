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

use cpmx_policy::{
    ActionMode, AgentPaths, AgentState, BoundaryCorners, MlpActor, MlpPolicy, ObservationInput,
};
use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::Lookahead;
use cpmx_vehicle::{BicycleState, Command, Footprint, KinematicBicycle, Precision, footprint_corners};
use cpmx_world::{Point, ReferencePath};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;
use rayon::prelude::*;

use crate::collision::{rectangle_crosses_segment, rectangles_cross};
use crate::config::{ConfigError, EnvConfig, Plant, ResetScope};
use crate::neighbours::EnvNeighbours;
use crate::paths::{TrainingPath, prepare_paths};
use crate::result::{AgentStepInfo, StepResult, StepTotals};
use crate::reward::{RewardInput, reward};
use crate::stack_world::StackWorld;
use crate::starts::{Placement, draw_placement};

/// One agent of one environment.
#[derive(Debug, Clone)]
struct Agent {
    placement: Placement,
    /// Position at the start of the step (after any reset).
    prev_pos: Point,
    /// Short-term reference points for the next progress reward.
    short_term: Vec<Point>,
    /// The steering command of the agent's previous step, clamped to the limit (0 after a
    /// placement) [rad].
    prev_steering_cmd_rad: f64,
}

/// One environment.
#[derive(Debug)]
struct Env {
    agents: Vec<Agent>,
    paths: AgentPaths,
    counter: u32,
    rng: ChaCha20Rng,
    /// RewardSum per agent since the last whole reset.
    episode_reward: Vec<f32>,
    /// Corners at the start of the step.
    corners_start: Vec<Footprint>,
    /// The vehicle stacks, when the plant is the lab's control architecture.
    stack: Option<StackWorld>,
    /// The first failure of a vehicle stack (the environment is broken from there on).
    failure: Option<String>,
    /// The observation of the states the last episode ended in, when kept
    /// ([`VecEnv::set_keep_final_observations`]).
    final_observation: Option<Vec<f32>>,
    /// The fidelity's communication and perception layers, if any.
    neighbours: Option<EnvNeighbours>,
    scratch: Scratch,
}

/// How one environment's step ended.
#[derive(Debug, Clone, Copy, Default)]
struct StepEnd {
    /// The episode ended (and the environment was re-placed).
    done: bool,
    /// It ended by the time limit alone.
    time_limit: bool,
}

/// Per-step buffers of one environment.
#[derive(Debug, Clone, Default)]
struct Scratch {
    states: Vec<AgentState>,
    positions: Vec<Point>,
    velocities: Vec<[f64; 2]>,
    corners: Vec<Footprint>,
    with_agents: Vec<bool>,
    with_boundary: Vec<bool>,
    on_line: Vec<bool>,
    closest: Vec<usize>,
    avoid: Vec<Point>,
    /// This step's steering commands, clamped to the limit [rad].
    steering_cmds: Vec<f64>,
}

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
        let work = |(((env, act), obs), (rew, (ret, info))): (
            ((&mut Env, &[f32]), &mut [f32]),
            (&mut [f32], (&mut [f32], &mut [AgentStepInfo])),
        )| env.step(config, paths, act, obs, rew, ret, info);
        let outcomes: Vec<(StepEnd, StepTotals)> = if self.parallel {
            self.envs
                .par_iter_mut()
                .zip(actions.par_chunks(n * 2))
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
                .zip(actions.chunks(n * 2))
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

impl Env {
    /// Places agent `i` as given: state, path, short-term points, start corners.
    fn set(&mut self, config: &EnvConfig, paths: &[TrainingPath], i: usize, placement: Placement) {
        let path = &paths[placement.path];
        self.paths.paths[i] = path.prepared.clone();
        let s = placement.state;
        let pos = [s.x_m, s.y_m];
        let agent = &mut self.agents[i];
        agent.placement = placement;
        agent.prev_pos = pos;
        agent.prev_steering_cmd_rad = 0.0;
        if let Some(progress) = &config.reward.progress {
            let c = path.prepared.center.nearest(pos).map_or(0, |n| n.segment + 1);
            fill_short_term(path, c, progress.spacing, &mut agent.short_term);
        }
        self.corners_start[i] = footprint_corners(&config.vehicle, s.x_m, s.y_m, s.yaw_rad);
    }

    /// A whole-environment reset: agents placed in order, each away from those before it.
    /// Returns whether a placement had to be relaxed.
    fn reset_whole(&mut self, config: &EnvConfig, paths: &[TrainingPath]) -> bool {
        let mut relaxed = false;
        let mut avoid = std::mem::take(&mut self.scratch.avoid);
        avoid.clear();
        for i in 0..self.agents.len() {
            let (p, r) = draw_placement(&mut self.rng, paths, &config.scenario.start, &avoid);
            relaxed |= r;
            avoid.push([p.state.x_m, p.state.y_m]);
            self.set(config, paths, i, p);
        }
        self.scratch.avoid = avoid;
        self.counter = 0;
        self.episode_reward.fill(0.0);
        if let Some(neighbours) = &mut self.neighbours {
            neighbours.start_episode();
        }
        if let (Some(stack), Plant::Stack(plant)) = (&mut self.stack, &config.plant) {
            let placements: Vec<Placement> = self.agents.iter().map(|a| a.placement).collect();
            if let Err(e) = stack.reset_whole(plant, config.vehicle, &placements) {
                self.failure.get_or_insert(e);
            }
        }
        relaxed
    }

    /// A single-agent reset: agent `i` away from all others at their current positions.
    fn reset_agent(&mut self, config: &EnvConfig, paths: &[TrainingPath], i: usize) -> bool {
        let mut avoid = std::mem::take(&mut self.scratch.avoid);
        avoid.clear();
        avoid.extend(
            self.agents
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, a)| [a.placement.state.x_m, a.placement.state.y_m]),
        );
        let (p, relaxed) = draw_placement(&mut self.rng, paths, &config.scenario.start, &avoid);
        self.scratch.avoid = avoid;
        self.set(config, paths, i, p);
        if let Some(stack) = &mut self.stack
            && let Err(e) = stack.reset_agent(config.vehicle, i, &p)
        {
            self.failure.get_or_insert(e);
        }
        relaxed
    }

    /// Fills `scratch.states` from the agents.
    fn collect_states(&mut self) {
        self.scratch.states.clear();
        self.scratch.states.extend(
            self.agents
                .iter()
                .map(|a| AgentState::from_bicycle(&a.placement.state, a.placement.velocity_mps)),
        );
    }

    /// Observations of the current states into `out` (`previous` corners for the lag); with
    /// vehicle stacks, of the states the vehicles report and their previous tick's corners.
    /// With neighbour layers, what each agent knows of the others comes from the states
    /// observed, at the episode's time; a planner plans its next period with the same views.
    fn observe(&mut self, config: &EnvConfig, previous: Option<&[Footprint]>, out: &mut [f32]) {
        let t_s = f64::from(self.counter) * config.dt_s;
        if let Some(stack) = &mut self.stack {
            let states = stack.observed_states(&KinematicBicycle::new(config.vehicle));
            let views = self.neighbours.as_mut().map(|n| n.observe(t_s, &states));
            observe_into(config, &states, &self.paths, stack.previous_corners(), views, out);
            if let Some(views) = views {
                stack.set_neighbours(Some(views));
            }
            return;
        }
        self.collect_states();
        let views = self
            .neighbours
            .as_mut()
            .map(|n| n.observe(t_s, &self.scratch.states));
        observe_into(config, &self.scratch.states, &self.paths, previous, views, out);
    }

    /// Observations of the current states without the lag (as right after a reset).
    fn observe_const(&self, config: &EnvConfig, out: &mut [f32]) {
        let states: Vec<AgentState> = self
            .agents
            .iter()
            .map(|a| AgentState::from_bicycle(&a.placement.state, a.placement.velocity_mps))
            .collect();
        observe_into(config, &states, &self.paths, None, None, out);
    }

    /// One step; returns whether the environment was done (and has been reset), and why.
    #[allow(clippy::too_many_arguments)]
    fn step(
        &mut self,
        config: &EnvConfig,
        paths: &[TrainingPath],
        actions: &[f32],
        obs: &mut [f32],
        rewards: &mut [f32],
        returns: &mut [f32],
        info: &mut [AgentStepInfo],
    ) -> (StepEnd, StepTotals) {
        let n = self.agents.len();
        let model = KinematicBicycle::new(config.vehicle);
        let s = &mut self.scratch;
        s.positions.clear();
        s.velocities.clear();
        s.corners.clear();
        s.steering_cmds.clear();

        // 1. Move: one bicycle step, or a planning period of the vehicle stacks.
        let commands: Vec<Command> = actions
            .chunks_exact(2)
            .map(|act| Command {
                speed_mps: f64::from(act[0]),
                steering_rad: f64::from(act[1]),
            })
            .collect();
        let limit = config.vehicle.max_steering_rad;
        s.steering_cmds
            .extend(commands.iter().map(|c| c.steering_rad.clamp(-limit, limit)));
        let moved: Vec<(BicycleState, [f64; 2])> = match &mut self.stack {
            None => self
                .agents
                .iter()
                .zip(&commands)
                .map(|(a, &command)| {
                    let out =
                        model.step_with_precision(&a.placement.state, command, config.dt_s, Precision::F32);
                    (out.state, out.velocity_mps)
                })
                .collect(),
            Some(stack) => match stack.advance(&commands, &self.paths, &config.vehicle) {
                Ok(moved) => moved,
                Err(e) => {
                    self.failure.get_or_insert(e);
                    self.agents
                        .iter()
                        .map(|a| (a.placement.state, a.placement.velocity_mps))
                        .collect()
                }
            },
        };
        for (a, (state, velocity_mps)) in self.agents.iter_mut().zip(moved) {
            a.placement.state = state;
            a.placement.velocity_mps = velocity_mps;
            s.positions.push([state.x_m, state.y_m]);
            s.velocities.push(velocity_mps);
            s.corners.push(footprint_corners(
                &config.vehicle,
                state.x_m,
                state.y_m,
                state.yaw_rad,
            ));
        }
        self.counter += 1;

        // 2. Collisions and line contacts of the new states.
        s.with_agents.clear();
        s.with_agents.resize(n, false);
        for i in 0..n {
            for j in i + 1..n {
                if rectangles_cross(&s.corners[i], &s.corners[j]) {
                    s.with_agents[i] = true;
                    s.with_agents[j] = true;
                }
            }
        }
        s.with_boundary.clear();
        s.on_line.clear();
        for (a, c) in self.agents.iter().zip(&s.corners) {
            let path = &paths[a.placement.path];
            s.with_boundary.push(path.boundaries.crossed_by(c));
            let touches = |l: Option<[Point; 2]>| l.is_some_and(|l| rectangle_crosses_segment(c, l));
            s.on_line.push(touches(path.entry) || touches(path.exit));
        }

        // 3. Rewards, then the short-term points of the new positions.
        let mut totals = StepTotals::default();
        let lag = config.observation.boundary_corners == BoundaryCorners::LaggedForFirstAgent;
        let half_width = config.vehicle.width_m / 2.0;
        let max_step_m = config.vehicle.max_speed_mps * config.dt_s;
        s.closest.clear();
        for i in 0..n {
            let path = &self.paths.paths[i];
            let pos = s.positions[i];
            let corners = if lag && i == 0 {
                &self.corners_start[0]
            } else {
                &s.corners[i]
            };
            let boundary_distance_m = [&path.left_shared, &path.right_shared]
                .iter()
                .map(|side| {
                    let centre = side.distance_m(pos) - half_width;
                    corners.iter().map(|&c| side.distance_m(c)).fold(centre, f64::min)
                })
                .fold(f64::INFINITY, f64::min);
            let a = &self.agents[i];
            let nearest = path.center.nearest(pos);
            let yaw_rad = nearest.map_or(0.0, |n| paths[a.placement.path].center_yaw_rad[n.segment]);
            let terms = reward(
                &config.reward,
                &RewardInput {
                    pos,
                    prev_pos: a.prev_pos,
                    short_term: &a.short_term,
                    path_direction: [yaw_rad.cos(), yaw_rad.sin()],
                    centre_line_distance_m: nearest.map_or(0.0, |n| n.distance_m),
                    boundary_distance_m,
                    agent: i,
                    positions: &s.positions,
                    velocities: &s.velocities,
                    collides_with_agents: s.with_agents[i],
                    collides_with_boundary: s.with_boundary[i],
                    max_step_m,
                    max_speed_mps: config.vehicle.max_speed_mps,
                    steering_commands_rad: [s.steering_cmds[i], a.prev_steering_cmd_rad],
                    max_steering_rad: config.vehicle.max_steering_rad,
                },
            );
            s.closest.push(nearest.map_or(0, |n| n.segment + 1));
            let r = terms.total as f32;
            rewards[i] = r;
            self.episode_reward[i] += r;
            returns[i] = self.episode_reward[i];
            info[i] = AgentStepInfo {
                terms,
                collides_with_agents: s.with_agents[i],
                collides_with_boundary: s.with_boundary[i],
                touches_entry_or_exit: s.on_line[i],
                reset: false,
            };
            totals.add_agent(&info[i]);
        }
        if let Some(progress) = &config.reward.progress {
            for (a, &c) in self.agents.iter_mut().zip(&s.closest) {
                fill_short_term(&paths[a.placement.path], c, progress.spacing, &mut a.short_term);
            }
        }
        for (a, &c) in self.agents.iter_mut().zip(&s.steering_cmds) {
            a.prev_steering_cmd_rad = c;
        }

        // 4. Observations of the new states (agent 0 with the corners of the start of the step);
        // with vehicle stacks, of what the vehicles report.
        let corners_start = std::mem::take(&mut self.corners_start);
        self.observe(config, Some(&corners_start), obs);
        self.corners_start = corners_start;
        let s = &self.scratch;

        // 5. Done and resets.
        let rules = config.scenario.reset;
        let collided = s.with_agents.iter().chain(&s.with_boundary).any(|&c| c);
        let time_limit = self.counter == config.scenario.episode_steps - 1;
        let ended = (rules.on_collision == ResetScope::Environment && collided)
            || (rules.on_entry_or_exit_line == ResetScope::Environment && s.on_line.iter().any(|&l| l));
        let done = time_limit || ended;
        if done {
            if let Some(last) = &mut self.final_observation {
                last.copy_from_slice(obs);
            }
            totals.env_resets += 1;
            totals.starts_relaxed += u64::from(self.reset_whole(config, paths));
            self.observe(config, None, obs);
        } else {
            #[allow(clippy::needless_range_loop)]
            for i in 0..n {
                let s = &self.scratch;
                let by_collision =
                    rules.on_collision == ResetScope::Agent && (s.with_agents[i] || s.with_boundary[i]);
                let by_line = rules.on_entry_or_exit_line == ResetScope::Agent && s.on_line[i];
                if by_collision || by_line {
                    totals.agent_resets += 1;
                    totals.starts_relaxed += u64::from(self.reset_agent(config, paths, i));
                    info[i].reset = true;
                }
            }
        }
        // The next step starts here.
        for (i, a) in self.agents.iter_mut().enumerate() {
            let st = a.placement.state;
            a.prev_pos = [st.x_m, st.y_m];
            self.corners_start[i] = footprint_corners(&config.vehicle, st.x_m, st.y_m, st.yaw_rad);
        }
        let end = StepEnd {
            done,
            time_limit: time_limit && !ended,
        };
        (end, totals)
    }
}

/// Short-term points `c + 1 + k * spacing` of SigmaRL's long-term path.
fn fill_short_term(path: &TrainingPath, closest: usize, spacing: usize, out: &mut [Point]) {
    let extension = out.len() * spacing;
    for (k, q) in out.iter_mut().enumerate() {
        *q = path.long_term_point(closest + 1 + k * spacing, extension);
    }
}

/// SigmaRL's observation of `states` into `out`.
fn observe_into(
    config: &EnvConfig,
    states: &[AgentState],
    paths: &AgentPaths,
    previous: Option<&[Footprint]>,
    neighbours: Option<&cpmx_policy::NeighbourViews>,
    out: &mut [f32],
) {
    let input = ObservationInput {
        agents: states,
        paths,
        vehicle: &config.vehicle,
        previous_corners: previous,
        neighbours,
    };
    // Sizes and paths are fixed at construction (checked there), so this cannot fail.
    config
        .observation
        .observe_all(&input, out)
        .expect("observation buffers sized at construction");
}

//! One environment of a [`VecEnv`](super::VecEnv): its agents, random stream, episode reward
//! and step buffers, and the step in SigmaRL's order (the module `vec_env` lists it): move,
//! count, collide, reward, observe, done and re-place.

use cpmx_policy::{AgentPaths, AgentState, BoundaryCorners, ObservationInput};
use cpmx_vehicle::{BicycleState, Command, Footprint, KinematicBicycle, Precision, footprint_corners};
use cpmx_world::Point;
use rand_chacha::ChaCha20Rng;
use std::sync::Arc;

use cpmx_safety::layer::{Lane, LayerFilter};
use cpmx_safety::margins::joint_margins;
use cpmx_safety::{CbfState, Vehicle};

use crate::config::{EnvConfig, Plant, ResetScope};
use crate::neighbours::EnvNeighbours;
use crate::paths::TrainingPath;
use crate::result::{AgentStepInfo, StepTotals};
use crate::reward::{RewardInput, reward};
use crate::stack_world::StackWorld;
use crate::starts::{Placement, draw_placement};
use cpmx_stack::VehicleStack;
use cpmx_vehicle::{rectangle_crosses_segment, rectangles_cross};

/// One agent of one environment.
#[derive(Debug, Clone)]
pub(super) struct Agent {
    pub(super) placement: Placement,
    /// Position at the start of the step (after any reset).
    pub(super) prev_pos: Point,
    /// Short-term reference points for the next progress reward.
    pub(super) short_term: Vec<Point>,
    /// The steering command of the agent's previous step, clamped to the limit (0 after a
    /// placement) [rad].
    pub(super) prev_steering_cmd_rad: f64,
}

/// One environment.
#[derive(Debug)]
pub(super) struct Env {
    pub(super) agents: Vec<Agent>,
    pub(super) paths: AgentPaths,
    pub(super) counter: u32,
    pub(super) rng: ChaCha20Rng,
    /// RewardSum per agent since the last whole reset.
    pub(super) episode_reward: Vec<f32>,
    /// Corners at the start of the step.
    pub(super) corners_start: Vec<Footprint>,
    /// The vehicle stacks, when the plant is the lab's control architecture.
    pub(super) stack: Option<StackWorld>,
    /// The first failure of a vehicle stack (the environment is broken from there on).
    pub(super) failure: Option<String>,
    /// The observation of the states the last episode ended in, when kept
    /// ([`VecEnv::set_keep_final_observations`]).
    pub(super) final_observation: Option<Vec<f32>>,
    /// The fidelity's communication and perception layers, if any.
    pub(super) neighbours: Option<EnvNeighbours>,
    /// The fidelity's safety filter, if any (each agent in its path's lane).
    pub(super) filter: Option<LayerFilter>,
    /// Each training path's lane, when the filter or the CBF-informed reward needs them.
    pub(super) lanes: Option<Arc<[Lane]>>,
    pub(super) scratch: Scratch,
}

/// A step between [`Env::begin_step`] and [`Env::end_step`].
pub(super) struct Moving {
    /// The CBF-informed reward's margins of the sampled actions, if the reward has the term.
    cbf_margins: Option<Vec<f64>>,
    /// The true states after the step (state, velocity); `None` while the vehicle stacks'
    /// loops are still to step.
    moved: Option<Vec<(BicycleState, [f64; 2])>>,
}

impl Moving {
    /// Whether the vehicle stacks' loops are still to step before [`Env::end_step`].
    pub(super) fn loops_pending(&self) -> bool {
        self.moved.is_none()
    }
}

/// How one environment's step ended.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct StepEnd {
    /// The episode ended (and the environment was re-placed).
    pub(super) done: bool,
    /// It ended by the time limit alone.
    pub(super) time_limit: bool,
}

/// Per-step buffers of one environment.
#[derive(Debug, Clone, Default)]
pub(super) struct Scratch {
    pub(super) states: Vec<AgentState>,
    pub(super) positions: Vec<Point>,
    pub(super) velocities: Vec<[f64; 2]>,
    pub(super) corners: Vec<Footprint>,
    pub(super) with_agents: Vec<bool>,
    pub(super) with_boundary: Vec<bool>,
    pub(super) on_line: Vec<bool>,
    pub(super) closest: Vec<usize>,
    pub(super) avoid: Vec<Point>,
    /// This step's steering commands, clamped to the limit [rad].
    pub(super) steering_cmds: Vec<f64>,
    /// The states and velocities the safety filter sees this step.
    pub(super) filter_states: Vec<BicycleState>,
    pub(super) filter_velocities: Vec<[f64; 2]>,
    /// Per agent, the periods of this step its follower stopped it in (vehicle stacks only).
    pub(super) follower_stopped: Vec<u32>,
}

impl Env {
    /// Places agent `i` as given: state, path, short-term points, start corners.
    pub(super) fn set(&mut self, config: &EnvConfig, paths: &[TrainingPath], i: usize, placement: Placement) {
        let path = &paths[placement.path];
        self.paths.paths[i] = path.prepared.clone();
        let s = placement.state;
        let pos = [s.x_m, s.y_m];
        if let Some(filter) = &mut self.filter {
            filter.set_lane(i, placement.path);
        }
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
    pub(super) fn reset_whole(&mut self, config: &EnvConfig, paths: &[TrainingPath]) -> bool {
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
    pub(super) fn reset_agent(&mut self, config: &EnvConfig, paths: &[TrainingPath], i: usize) -> bool {
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
    pub(super) fn collect_states(&mut self) {
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
    pub(super) fn observe(&mut self, config: &EnvConfig, previous: Option<&[Footprint]>, out: &mut [f32]) {
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
    pub(super) fn observe_const(&self, config: &EnvConfig, out: &mut [f32]) {
        let states: Vec<AgentState> = self
            .agents
            .iter()
            .map(|a| AgentState::from_bicycle(&a.placement.state, a.placement.velocity_mps))
            .collect();
        observe_into(config, &states, &self.paths, None, None, out);
    }

    /// The first half of a step (the whole step: `begin_step`, the loops if pending,
    /// [`Env::end_step`], which returns whether the environment was done and has been reset,
    /// and why): the actions as commands, the CBF-informed reward's margins of
    /// the sampled actions, then the safety filter; the sim's bicycle steps, the vehicle
    /// stacks' planning period is planned and its loops left to step
    /// ([`Moving::loops_pending`]: with [`StackWorld::loop_vehicles`], perhaps beside other
    /// environments' vehicles) before [`Env::end_step`].
    pub(super) fn begin_step(&mut self, config: &EnvConfig, actions: &[f32]) -> Moving {
        let model = KinematicBicycle::new(config.vehicle);
        let s = &mut self.scratch;
        s.steering_cmds.clear();
        let mut commands: Vec<Command> = actions
            .chunks_exact(2)
            .map(|act| Command {
                speed_mps: f64::from(act[0]),
                steering_rad: f64::from(act[1]),
            })
            .collect();
        let cbf_margins = self.cbf_margin_rewards(config, &commands);
        if let (Some(filter), None) = (&mut self.filter, &self.stack) {
            let s = &mut self.scratch;
            s.filter_states.clear();
            s.filter_states
                .extend(self.agents.iter().map(|a| a.placement.state));
            s.filter_velocities.clear();
            s.filter_velocities
                .extend(self.agents.iter().map(|a| a.placement.velocity_mps));
            filter.apply(&s.filter_states, &s.filter_velocities, &mut commands);
        }
        let s = &mut self.scratch;
        let limit = config.vehicle.max_steering_rad;
        s.steering_cmds
            .extend(commands.iter().map(|c| c.steering_rad.clamp(-limit, limit)));
        let unmoved = |agents: &[Agent]| {
            agents
                .iter()
                .map(|a| (a.placement.state, a.placement.velocity_mps))
                .collect()
        };
        let moved = match &mut self.stack {
            None => Some(
                self.agents
                    .iter()
                    .zip(&commands)
                    .map(|(a, &command)| {
                        let out = model.step_with_precision(
                            &a.placement.state,
                            command,
                            config.dt_s,
                            Precision::F32,
                        );
                        (out.state, out.velocity_mps)
                    })
                    .collect(),
            ),
            Some(stack) => match stack.plan(&commands, &self.paths, &config.vehicle, self.filter.as_mut()) {
                Ok(()) => None,
                Err(e) => {
                    self.failure.get_or_insert(e);
                    Some(unmoved(&self.agents))
                }
            },
        };
        Moving { cbf_margins, moved }
    }

    /// The vehicles' loop periods in a step (none without vehicle stacks).
    pub(super) fn loop_periods(&self) -> usize {
        self.stack.as_ref().map_or(0, StackWorld::substeps)
    }

    /// The vehicles' loops of a step whose loops are pending (see [`Env::begin_step`]).
    pub(super) fn loop_vehicles(&mut self, sub: usize) -> impl Iterator<Item = (&mut VehicleStack, u64)> {
        self.stack
            .iter_mut()
            .flat_map(move |stack| stack.loop_vehicles(sub))
    }

    /// The second half of a step (after [`Env::begin_step`] and the loops): collisions,
    /// rewards, observations, done and resets.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn end_step(
        &mut self,
        config: &EnvConfig,
        paths: &[TrainingPath],
        moving: Moving,
        obs: &mut [f32],
        rewards: &mut [f32],
        returns: &mut [f32],
        info: &mut [AgentStepInfo],
    ) -> (StepEnd, StepTotals) {
        let n = self.agents.len();
        let Moving { cbf_margins, moved } = moving;
        let s = &mut self.scratch;
        s.follower_stopped.clear();
        let moved = match (moved, &mut self.stack) {
            (Some(moved), _) => moved,
            (None, Some(stack)) => {
                stack.take_follower_stopped(&mut s.follower_stopped);
                stack.finish_period()
            }
            (None, None) => unreachable!("loops are pending only with vehicle stacks"),
        };
        s.follower_stopped.resize(n, 0);
        let mut totals = StepTotals::default();
        s.positions.clear();
        s.velocities.clear();
        s.corners.clear();
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
        if let Some(filter) = &mut self.filter {
            let counts = filter.take_counts();
            totals.filtered += counts.changed;
            totals.filter_fallbacks += counts.infeasible + counts.not_finite + counts.unsolved;
        }
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
                    cbf_margins: cbf_margins.as_ref().map_or(0.0, |m| m[i]),
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
                follower_stopped_periods: s.follower_stopped[i],
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

impl Env {
    /// Each agent's CBF-informed reward (before its weight) for the joint `commands` in the
    /// current states; `None` without the term.
    fn cbf_margin_rewards(&self, config: &EnvConfig, commands: &[Command]) -> Option<Vec<f64>> {
        let term = config.reward.cbf_margins.as_ref()?;
        let lanes = self.lanes.as_ref()?;
        let vehicles: Vec<Vehicle<'_>> = self
            .agents
            .iter()
            .zip(commands)
            .map(|(a, c)| {
                let s = a.placement.state;
                let lane = &lanes[a.placement.path];
                Vehicle {
                    // SigmaRL 1.6.0's margins take the signed speed of the state.
                    state: CbfState {
                        x_m: s.x_m as f32,
                        y_m: s.y_m as f32,
                        yaw_rad: s.yaw_rad as f32,
                        speed_mps: s.speed_mps as f32,
                        steering_rad: s.steering_rad as f32,
                    },
                    nominal: [c.speed_mps as f32, c.steering_rad as f32],
                    left: &lane.0,
                    right: &lane.1,
                }
            })
            .collect();
        Some(
            joint_margins(&term.parameters, &vehicles)
                .iter()
                .map(|m| m.reward(term.threshold))
                .collect(),
        )
    }
}

/// Short-term points `c + 1 + k * spacing` of SigmaRL's long-term path.
pub(super) fn fill_short_term(path: &TrainingPath, closest: usize, spacing: usize, out: &mut [Point]) {
    let extension = out.len() * spacing;
    for (k, q) in out.iter_mut().enumerate() {
        *q = path.long_term_point(closest + 1 + k * spacing, extension);
    }
}

/// SigmaRL's observation of `states` into `out`.
pub(super) fn observe_into(
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

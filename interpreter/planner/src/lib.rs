//! The planner of `control: trajectory` (the paper's §Action): every planning period the policy
//! is rolled out for Hc steps on *predicted* states of all agents (kinematic bicycle,
//! observations recomputed on the predicted states), then the last speed command is held and
//! the steering command brought to zero (or held) until Hp. The result is one timed trajectory
//! per agent, in the form the CPM Lab's vehicles follow (t, x, y, vx, vy).
//!
//! This crate owns the rollout and the after-Hc rule. It does not follow trajectories (the
//! follower does), measure anything, or know where states come from.

use cpmx_policy::{AgentPaths, AgentState, NeighbourViews, ObservationInput, Policy, PolicyError};
use cpmx_vehicle::{BicycleState, Command, Footprint, KinematicBicycle, VehicleParams, footprint_corners};

/// Steering between Hc and Hp.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SteeringAfterHc {
    /// Linearly from the last policy command to zero at Hp (the paper).
    LinearToZero,
    /// Keep the last policy command.
    Hold,
}

/// The horizons and the rule after Hc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannerParams {
    /// Hc: policy steps rolled out on predicted states (≥ 1).
    pub control_horizon: usize,
    /// Hp: steps of the trajectory (≥ Hc).
    pub prediction_horizon: usize,
    /// Length of one step [s] (the policy's `dt`).
    pub step_s: f64,
    pub steering_after: SteeringAfterHc,
}

/// One point of a planned trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlannedPoint {
    /// Absolute time [s].
    pub t_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    /// Velocity in the map frame [m/s].
    pub velocity_mps: [f64; 2],
    pub speed_mps: f64,
    pub steering_rad: f64,
}

/// A planned trajectory of one agent: Hp + 1 points, the first at the planning time.
pub type PlannedTrajectory = Vec<PlannedPoint>;

/// A layer between the policy's commands and the rollout (a fidelity's `safety:` filter): it
/// may change each rolled-out step's commands, given the predicted states and velocities.
pub trait CommandFilter {
    /// Changes `commands` for agents in `states`, moving at `velocities_mps`.
    fn filter(&mut self, states: &[BicycleState], velocities_mps: &[[f64; 2]], commands: &mut [Command]);
}

/// Where the first step's commands come from.
enum FirstStep<'a> {
    /// The policy, on the real states (the further steps go to its fork).
    Policy(&'a mut dyn Policy),
    /// Given; `lookahead` acts on the predicted states.
    Commands {
        first: &'a [Command],
        lookahead: &'a mut dyn Policy,
    },
}

/// Rolls policies out into trajectories.
#[derive(Debug, Clone)]
pub struct Planner {
    params: PlannerParams,
    model: KinematicBicycle,
    /// Corners of the agents at the previous planning time (SigmaRL's lagged corners), if any.
    previous_corners: Option<Vec<Footprint>>,
    /// What each agent knows of the others (a fidelity's communication and perception
    /// layers), for every policy call of the next plans; `None`: everything exactly.
    neighbours: Option<NeighbourViews>,
}

impl Planner {
    pub fn new(params: PlannerParams, vehicle: VehicleParams) -> Self {
        Self {
            params,
            model: KinematicBicycle::new(vehicle),
            previous_corners: None,
            neighbours: None,
        }
    }

    /// What each agent knows of the others when it plans next (`None`: everything exactly).
    /// A neighbour known exactly is predicted over the lookahead as without the layers; one
    /// known from an older message or with perception noise stays as known.
    pub fn set_neighbours(&mut self, views: Option<&NeighbourViews>) {
        match (views, &mut self.neighbours) {
            (None, slot) => *slot = None,
            (Some(views), Some(slot)) => slot.clone_from(views),
            (Some(views), slot) => *slot = Some(views.clone()),
        }
    }

    pub fn params(&self) -> &PlannerParams {
        &self.params
    }

    /// Plans from the agents' current states at time `t_s`.
    ///
    /// The first policy call sees the real states (with the previous planning time's corners,
    /// as SigmaRL's observation expects); every further call sees the predicted states of the
    /// step before, with the corners of the step before that. `policy` is called Hc times.
    pub fn plan(
        &mut self,
        policy: &mut dyn Policy,
        states: &[BicycleState],
        paths: &AgentPaths,
        t_s: f64,
    ) -> Result<Vec<PlannedTrajectory>, PolicyError> {
        self.roll_out(FirstStep::Policy(policy), None, states, paths, t_s)
    }

    /// [`Planner::plan`] with each of the Hc rolled-out steps' commands through `filter`
    /// before they move the predicted cars (the steps after Hc hold the filtered commands).
    pub fn plan_filtered(
        &mut self,
        policy: &mut dyn Policy,
        filter: &mut dyn CommandFilter,
        states: &[BicycleState],
        paths: &AgentPaths,
        t_s: f64,
    ) -> Result<Vec<PlannedTrajectory>, PolicyError> {
        self.roll_out(FirstStep::Policy(policy), Some(filter), states, paths, t_s)
    }

    /// [`Planner::plan`] with the first step's commands already chosen (a learner's sampled
    /// actions on the observation of `states`): `lookahead` is called on the predicted states
    /// of the further Hc - 1 steps only; with a `filter`, every rolled-out step's commands go
    /// through it (as in [`Planner::plan_filtered`]).
    pub fn plan_from_commands(
        &mut self,
        first: &[Command],
        lookahead: &mut dyn Policy,
        filter: Option<&mut dyn CommandFilter>,
        states: &[BicycleState],
        paths: &AgentPaths,
        t_s: f64,
    ) -> Result<Vec<PlannedTrajectory>, PolicyError> {
        self.roll_out(
            FirstStep::Commands { first, lookahead },
            filter,
            states,
            paths,
            t_s,
        )
    }

    fn roll_out(
        &mut self,
        mut first_step: FirstStep<'_>,
        mut filter: Option<&mut dyn CommandFilter>,
        states: &[BicycleState],
        paths: &AgentPaths,
        t_s: f64,
    ) -> Result<Vec<PlannedTrajectory>, PolicyError> {
        let mut commands = vec![Command::default(); states.len()];
        let mut fork: Option<Box<dyn Policy>> = None;
        let mut rollout = self.begin(states, paths, t_s);
        while let Some(input) = rollout.input() {
            // The real policy sees the real states once per planning time; the predicted
            // steps go to a fork, so they leave its memory (and random stream) untouched.
            match (&mut first_step, rollout.step()) {
                (FirstStep::Policy(policy), 0) => {
                    policy.act(&input, &mut commands)?;
                    fork = Some(policy.fork());
                }
                (FirstStep::Policy(_), _) => {
                    if let Some(fork) = fork.as_mut() {
                        fork.act(&input, &mut commands)?;
                    }
                }
                (FirstStep::Commands { first, .. }, 0) => {
                    if first.len() != commands.len() {
                        return Err(PolicyError::CommandCount {
                            found: first.len(),
                            agents: commands.len(),
                        });
                    }
                    commands.copy_from_slice(first);
                }
                (FirstStep::Commands { lookahead, .. }, _) => lookahead.act(&input, &mut commands)?,
            }
            rollout.apply(&mut commands, filter.as_deref_mut());
        }
        Ok(rollout.finish())
    }

    /// A plan from the agents' current states at time `t_s`, taken one rolled-out step at a
    /// time (for callers that gather several plans' policy calls into one; [`Planner::plan`]
    /// is this with one policy).
    pub fn begin<'a>(&'a mut self, states: &[BicycleState], paths: &'a AgentPaths, t_s: f64) -> Rollout<'a> {
        let predicted: Vec<BicycleState> = states.to_vec();
        let trajectories = predicted.iter().map(|s| vec![self.point(s, t_s)]).collect();
        let corners_before = self.previous_corners.take();
        let n = states.len();
        let mut rollout = Rollout {
            planner: self,
            paths,
            t_s,
            step: 0,
            predicted,
            trajectories,
            corners_before,
            agents: vec![AgentState::default(); n],
            velocities: vec![[0.0; 2]; n],
            last: vec![Command::default(); n],
        };
        rollout.observe_predicted();
        rollout
    }

    /// Forgets the previous planning time (a run restarts).
    pub fn reset(&mut self) {
        self.previous_corners = None;
    }

    fn advance(
        &self,
        predicted: &mut [BicycleState],
        commands: &[Command],
        trajectories: &mut [PlannedTrajectory],
        t0_s: f64,
        k: usize,
    ) {
        let t_s = t0_s + (k + 1) as f64 * self.params.step_s;
        for ((state, command), trajectory) in predicted.iter_mut().zip(commands).zip(trajectories.iter_mut())
        {
            *state = self.model.step(state, *command, self.params.step_s).state;
            trajectory.push(self.point(state, t_s));
        }
    }

    fn point(&self, state: &BicycleState, t_s: f64) -> PlannedPoint {
        PlannedPoint {
            t_s,
            x_m: state.x_m,
            y_m: state.y_m,
            yaw_rad: state.yaw_rad,
            velocity_mps: self.model.velocity_mps(state),
            speed_mps: state.speed_mps,
            steering_rad: state.steering_rad,
        }
    }
}

/// A plan under way ([`Planner::begin`]): for each of the Hc rolled-out steps, what the policy
/// sees ([`Rollout::input`]) and then its commands ([`Rollout::apply`]); then the steps to Hp
/// ([`Rollout::finish`]). The first step's input has the real states (with the previous planning
/// time's corners, as SigmaRL's observation expects), every further one the predicted states of
/// the step before, with the corners of the step before that.
pub struct Rollout<'a> {
    planner: &'a mut Planner,
    paths: &'a AgentPaths,
    t_s: f64,
    /// The rolled-out steps done.
    step: usize,
    predicted: Vec<BicycleState>,
    trajectories: Vec<PlannedTrajectory>,
    corners_before: Option<Vec<Footprint>>,
    /// The predicted states as the policy observes them, and their velocities.
    agents: Vec<AgentState>,
    velocities: Vec<[f64; 2]>,
    /// The commands of the last rolled-out step.
    last: Vec<Command>,
}

impl Rollout<'_> {
    /// The rolled-out steps done (the next one's index).
    pub fn step(&self) -> usize {
        self.step
    }

    /// What the policy sees at the next rolled-out step; `None` once Hc steps are rolled out.
    pub fn input(&self) -> Option<ObservationInput<'_>> {
        (self.step < self.planner.params.control_horizon).then(|| ObservationInput {
            agents: &self.agents,
            paths: self.paths,
            vehicle: &self.planner.model.params,
            previous_corners: self.corners_before.as_deref(),
            neighbours: self.planner.neighbours.as_ref(),
        })
    }

    /// The next rolled-out step with the policy's `commands` (changed by `filter` first, if
    /// given, on the predicted states): the predicted cars move one step.
    pub fn apply<'o>(&mut self, commands: &mut [Command], filter: Option<&mut (dyn CommandFilter + 'o)>) {
        if let Some(filter) = filter {
            filter.filter(&self.predicted, &self.velocities, commands);
        }
        let vehicle = self.planner.model.params;
        let corners_now: Vec<Footprint> = self
            .predicted
            .iter()
            .map(|s| footprint_corners(&vehicle, s.x_m, s.y_m, s.yaw_rad))
            .collect();
        if self.step == 0 {
            self.planner.previous_corners = Some(corners_now.clone());
        }
        self.corners_before = Some(corners_now);
        self.planner.advance(
            &mut self.predicted,
            commands,
            &mut self.trajectories,
            self.t_s,
            self.step,
        );
        self.last.copy_from_slice(commands);
        self.step += 1;
        self.observe_predicted();
    }

    /// The trajectories: after the Hc rolled-out steps, the last speed command held and the
    /// steering brought to zero (or held) until Hp.
    pub fn finish(mut self) -> Vec<PlannedTrajectory> {
        let p = self.planner.params;
        let remaining = p.prediction_horizon.saturating_sub(p.control_horizon);
        let mut commands = self.last.clone();
        for j in 0..remaining {
            for (command, last) in commands.iter_mut().zip(&self.last) {
                let fraction = match p.steering_after {
                    SteeringAfterHc::LinearToZero => 1.0 - (j + 1) as f64 / remaining as f64,
                    SteeringAfterHc::Hold => 1.0,
                };
                *command = Command {
                    speed_mps: last.speed_mps,
                    steering_rad: last.steering_rad * fraction,
                };
            }
            self.planner.advance(
                &mut self.predicted,
                &commands,
                &mut self.trajectories,
                self.t_s,
                p.control_horizon + j,
            );
        }
        self.trajectories
    }

    /// The predicted states as the policy observes them, with their velocities.
    fn observe_predicted(&mut self) {
        let model = &self.planner.model;
        for ((agent, velocity), state) in self
            .agents
            .iter_mut()
            .zip(&mut self.velocities)
            .zip(&self.predicted)
        {
            *velocity = model.velocity_mps(state);
            *agent = AgentState::from_bicycle(state, *velocity);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A policy that always commands the same and counts its calls.
    struct Constant {
        command: Command,
        calls: usize,
    }

    impl Policy for Constant {
        fn act(&mut self, _: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
            self.calls += 1;
            out.fill(self.command);
            Ok(())
        }
        fn reset(&mut self) {}

        fn fork(&mut self) -> Box<dyn Policy> {
            Box::new(Constant {
                command: self.command,
                calls: 0,
            })
        }
    }

    fn plan(params: PlannerParams, command: Command) -> (Vec<PlannedTrajectory>, usize) {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = AgentPaths::new([map.reference_path(1).unwrap()]);
        let mut planner = Planner::new(params, VehicleParams::MU_CAR);
        let mut policy = Constant { command, calls: 0 };
        let start = BicycleState {
            speed_mps: 0.5,
            ..BicycleState::default()
        };
        let trajectories = planner.plan(&mut policy, &[start], &paths, 2.0).unwrap();
        (trajectories, policy.calls)
    }

    const PAPER: PlannerParams = PlannerParams {
        control_horizon: 4,
        prediction_horizon: 12,
        step_s: 0.1,
        steering_after: SteeringAfterHc::LinearToZero,
    };

    #[test]
    fn the_policy_sees_the_real_state_once_and_the_trajectory_has_hp_steps() {
        let (trajectories, calls) = plan(
            PAPER,
            Command {
                speed_mps: 0.5,
                steering_rad: 0.2,
            },
        );
        assert_eq!(calls, 1, "the other Hc - 1 calls go to the fork");
        assert_eq!(trajectories[0].len(), 13);
        assert!((trajectories[0][12].t_s - 3.2).abs() < 1e-12);
    }

    #[test]
    fn steering_goes_to_zero_by_hp_and_speed_is_held() {
        let (trajectories, _) = plan(
            PAPER,
            Command {
                speed_mps: 0.5,
                steering_rad: 0.2,
            },
        );
        let last = trajectories[0].last().unwrap();
        assert!(last.steering_rad.abs() < 1e-12, "{}", last.steering_rad);
        assert!(
            trajectories[0][5..]
                .iter()
                .all(|p| (p.speed_mps - 0.5).abs() < 1e-12)
        );
    }

    #[test]
    fn hold_keeps_the_last_steering() {
        let params = PlannerParams {
            steering_after: SteeringAfterHc::Hold,
            ..PAPER
        };
        let (trajectories, _) = plan(
            params,
            Command {
                speed_mps: 0.5,
                steering_rad: 0.2,
            },
        );
        assert!((trajectories[0].last().unwrap().steering_rad - 0.2).abs() < 1e-12);
    }

    #[test]
    fn given_first_commands_replace_the_policys_first_call() {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = AgentPaths::new([map.reference_path(1).unwrap()]);
        let start = BicycleState {
            speed_mps: 0.5,
            ..BicycleState::default()
        };
        let command = Command {
            speed_mps: 0.5,
            steering_rad: 0.2,
        };
        let mut policy = Constant { command, calls: 0 };
        let planned = Planner::new(PAPER, VehicleParams::MU_CAR)
            .plan(&mut policy, &[start], &paths, 2.0)
            .unwrap();
        let mut lookahead = Constant { command, calls: 0 };
        let given = Planner::new(PAPER, VehicleParams::MU_CAR)
            .plan_from_commands(&[command], &mut lookahead, None, &[start], &paths, 2.0)
            .unwrap();
        assert_eq!(planned, given, "the same commands give the same plan");
        assert_eq!(lookahead.calls, 3, "Hc - 1 predicted steps");
        // The first step follows the given command, not the lookahead's.
        let mut straight = Constant {
            command: Command {
                speed_mps: 0.5,
                steering_rad: 0.0,
            },
            calls: 0,
        };
        let turned = Planner::new(PAPER, VehicleParams::MU_CAR)
            .plan_from_commands(&[command], &mut straight, None, &[start], &paths, 2.0)
            .unwrap();
        assert!(turned[0][1].steering_rad > 0.0 && turned[0][2].steering_rad == 0.0);
    }

    #[test]
    fn hc_equal_to_hp_is_the_policy_alone() {
        let params = PlannerParams {
            control_horizon: 3,
            prediction_horizon: 3,
            ..PAPER
        };
        let (trajectories, calls) = plan(
            params,
            Command {
                speed_mps: 0.3,
                steering_rad: 0.0,
            },
        );
        assert_eq!((calls, trajectories[0].len()), (1, 4));
    }
}

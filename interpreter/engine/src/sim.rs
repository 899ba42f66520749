//! The sim engine (`control: direct, dynamics: kinematic`): SigmaRL's loop. Every `dt` the
//! policy sees all agents' states and its command goes straight into the kinematic bicycle
//! (through the fidelity's `safety:` filter, when it has one), stepped as SigmaRL 1.5.0 on
//! does (one Euler step), with `kinematic-rk4` as SigmaRL 1.4.0 does (integrated over the
//! step), or with `kinematic-vmas` as SigmaRL 1.2.0's VMAS does (direct commands, drag).
//!
//! The recording holds the state *before* each action, t = 0 … (steps − 1)·dt, as SigmaRL's
//! evaluation receives them; so the metrics of a run equal `cpmx evaluate` of its trajectory.

use cpmx_metrics::collision::{PlacedBox, mtv_distance_m};
use cpmx_policy::{AgentState, ObservationInput, Policy, PolicyCall, SharedPasses};
use cpmx_recording::{AgentSample, Recording};
use cpmx_spec::model::{DynamicsLayer, KinematicKeyword, OnCollision};
use cpmx_vehicle::{BicycleState, Command, KinematicBicycle, VmasMotion};

use cpmx_spec::matrix::stream_key;

use crate::engine::{Engine, RunError, RunInputs};
use crate::replace::{Leave, Replacements};
use crate::starts::InitialState;

/// Runge–Kutta substeps of a `kinematic-rk4` step (within about 1e-6 m of SigmaRL 1.4.0's dopri5).
const RK4_SUBSTEPS: u32 = 5;

/// SigmaRL's simulation: direct control of the kinematic bicycle.
#[derive(Debug, Clone, Copy, Default)]
pub struct SimEngine;

impl Engine for SimEngine {
    fn run(&self, inputs: &RunInputs<'_>) -> Result<Recording, RunError> {
        crate::engine::run_alone(self, inputs)
    }

    /// The runs step by step in lock-step, the calls of the policies that run one actor
    /// sharing its network pass ([`SharedPasses`]); runs share no state and the kernels give
    /// each row the bits it has alone, so each run has the bits it has alone.
    fn run_together(&self, inputs: &[RunInputs<'_>]) -> Vec<Result<Recording, RunError>> {
        let mut runs: Vec<Result<SimRun<'_>, RunError>> = inputs.iter().map(SimRun::new).collect();
        let steps = runs.iter().flatten().map(|run| run.steps).max().unwrap_or(0);
        let mut passes = SharedPasses::default();
        for step in 0..steps {
            let mut acting = Vec::with_capacity(runs.len());
            let mut calls = Vec::with_capacity(runs.len());
            for (i, slot) in runs.iter_mut().enumerate() {
                if let Ok(run) = slot
                    && run.is_driving(step)
                {
                    calls.push(run.observe(step));
                    acting.push(i);
                }
            }
            let results = passes.act(&mut calls);
            drop(calls);
            for (i, acted) in acting.into_iter().zip(results) {
                if let Ok(run) = &mut runs[i]
                    && let Err(error) = acted.map_err(RunError::from).and_then(|()| run.advance(step))
                {
                    runs[i] = Err(error);
                }
            }
        }
        runs.into_iter().map(|run| run.map(SimRun::finish)).collect()
    }

    fn steps_together(&self) -> bool {
        true
    }
}

/// A sim run under way: its cars, policy and layers, and what it recorded.
struct SimRun<'a> {
    inputs: &'a RunInputs<'a>,
    steps: u32,
    dt_s: f64,
    model: KinematicBicycle,
    integration: KinematicKeyword,
    paths: cpmx_policy::AgentPaths,
    states: Vec<BicycleState>,
    velocities: Vec<[f64; 2]>,
    /// VMAS's yaw rates (`kinematic-vmas` only): from rest, as SigmaRL places its agents.
    yaw_rates_rad_s: Vec<f64>,
    policy: Box<dyn Policy>,
    recording: Recording,
    safety: Option<cpmx_safety::layer::LayerFilter>,
    knowledge: cpmx_sensing::NeighbourKnowledge,
    agents: Vec<AgentState>,
    commands: Vec<Command>,
    /// `replace-agent`: the leaving and placing of cars, the recording's agent in each slot (a
    /// replaced car's slot gets a new one), the slots whose cars leave once the policy has
    /// acted on their last state, and the replacements by reason.
    replacements: Option<Replacements>,
    agent_in_slot: Vec<usize>,
    leaving: Vec<Option<Leave>>,
    replaced: std::collections::BTreeMap<&'static str, u32>,
    /// Ended early (`on_collision: end-run`).
    ended: bool,
}

impl<'a> SimRun<'a> {
    /// Places the agents and prepares their paths, the policy and the layers.
    fn new(inputs: &'a RunInputs<'a>) -> Result<Self, RunError> {
        let experiment = inputs.experiment;
        let spec = &experiment.spec;
        let model = KinematicBicycle::new(experiment.vehicle);
        let integration = match inputs.fidelity.map(|f| &f.dynamics) {
            Some(DynamicsLayer::Kinematic(keyword)) => *keyword,
            _ => KinematicKeyword::Kinematic,
        };
        let starts = inputs.starts;
        let paths = inputs.agent_paths()?;
        let states: Vec<BicycleState> = starts.iter().map(initial_bicycle_state).collect();
        let velocities: Vec<[f64; 2]> = states.iter().map(|s| model.velocity_mps(s)).collect();
        let policy = inputs.policy()?;
        let recording = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: Vec::with_capacity(spec.timing.steps as usize),
            ref_paths: starts.iter().map(|s| s.ref_path).collect(),
            samples: Vec::with_capacity(spec.timing.steps as usize),
        };
        let safety = crate::safety::filter_of_run(
            inputs.fidelity.and_then(|f| f.safety.as_ref()),
            inputs,
            &recording.ref_paths,
        )?;
        let replacements = match spec.on_collision {
            OnCollision::ReplaceAgent => Some(
                Replacements::new(
                    inputs.map(),
                    &recording.ref_paths,
                    experiment.vehicle,
                    stream_key(inputs.plan.seed, "replace-agent"),
                )
                .map_err(RunError::Replacement)?,
            ),
            _ => None,
        };
        let n = states.len();
        Ok(SimRun {
            inputs,
            steps: spec.timing.steps,
            dt_s: spec.timing.dt,
            model,
            integration,
            paths,
            states,
            velocities,
            yaw_rates_rad_s: vec![0.0; n],
            policy,
            recording,
            safety,
            knowledge: inputs.neighbour_knowledge(),
            agents: vec![AgentState::default(); n],
            commands: vec![Command::default(); n],
            replacements,
            agent_in_slot: (0..n).collect(),
            leaving: vec![None; n],
            replaced: Default::default(),
            ended: false,
        })
    }

    /// Whether the run still drives at `step`.
    fn is_driving(&self, step: u32) -> bool {
        !self.ended && step < self.steps
    }

    /// Records the state the policy acts on at `step` and returns the policy's call on it.
    fn observe(&mut self, step: u32) -> PolicyCall<'_> {
        // Times on a clean decimal grid (0.3, not 0.30000000000000004).
        self.recording
            .times_s
            .push((f64::from(step) * self.dt_s * 1e9).round() / 1e9);
        let mut row = vec![AgentSample::ABSENT; self.recording.ref_paths.len()];
        for ((state, velocity), &agent) in self.states.iter().zip(&self.velocities).zip(&self.agent_in_slot) {
            row[agent] = sample(state, *velocity);
        }
        self.recording.samples.push(row);

        for ((agent, state), velocity) in self.agents.iter_mut().zip(&self.states).zip(&self.velocities) {
            *agent = AgentState::from_bicycle(state, *velocity);
        }
        let t_s = f64::from(step) * self.dt_s;
        let active = self.knowledge.is_active();
        let views = self.knowledge.step(t_s, &self.agents);
        PolicyCall {
            policy: self.policy.as_mut(),
            input: ObservationInput {
                agents: &self.agents,
                paths: &self.paths,
                vehicle: &self.inputs.experiment.vehicle,
                previous_corners: None,
                neighbours: active.then_some(views),
            },
            commands: &mut self.commands,
        }
    }

    /// After the policy's call at `step`: the safety filter, the cars that leave and come
    /// (`replace-agent`), one step of the bicycles, and the collisions as the spec asks.
    fn advance(&mut self, step: u32) -> Result<(), RunError> {
        let experiment = self.inputs.experiment;
        let spec = &experiment.spec;
        let (model, dt_s) = (self.model, self.dt_s);
        if let Some(filter) = &mut self.safety {
            filter.apply(&self.states, &self.velocities, &mut self.commands);
        }
        if let Some(replacements) = &mut self.replacements
            && step + 1 < spec.timing.steps
        {
            // The cars that collided at the last step leave; new ones act on the command
            // their slot's policy chose from the collision's state (SigmaRL's stale one).
            // (None is placed in the last step: its first sample would not be recorded.)
            let t_s = f64::from(step) * dt_s;
            for (slot, why) in self
                .leaving
                .iter()
                .enumerate()
                .filter_map(|(slot, why)| Some((slot, (*why)?)))
            {
                let (ref_path, prepared, state) =
                    replacements.place(slot, &self.states).ok_or_else(|| {
                        RunError::Replacement(format!("no free place for a new car at t = {t_s:.2} s"))
                    })?;
                self.states[slot] = state;
                self.velocities[slot] = model.velocity_mps(&state);
                self.paths.paths[slot] = prepared;
                self.agent_in_slot[slot] = self.recording.ref_paths.len();
                self.recording.ref_paths.push(ref_path);
                *self.replaced.entry(why.statistic()).or_default() += 1;
            }
        }
        for (((state, velocity), yaw_rate_rad_s), command) in self
            .states
            .iter_mut()
            .zip(&mut self.velocities)
            .zip(&mut self.yaw_rates_rad_s)
            .zip(&self.commands)
        {
            (*state, *velocity) = match self.integration {
                KinematicKeyword::Kinematic => {
                    let out = model.step(state, *command, dt_s);
                    (out.state, out.velocity_mps)
                }
                KinematicKeyword::KinematicRk4 => {
                    let out = model.step_rk4(state, *command, dt_s, RK4_SUBSTEPS);
                    (out.state, out.velocity_mps)
                }
                KinematicKeyword::KinematicVmas => {
                    let motion = VmasMotion {
                        velocity_mps: *velocity,
                        yaw_rate_rad_s: *yaw_rate_rad_s,
                    };
                    let out = model.step_vmas(state, motion, *command, dt_s);
                    *yaw_rate_rad_s = out.motion.yaw_rate_rad_s;
                    (out.state, out.motion.velocity_mps)
                }
            };
        }

        // Collisions, as the spec asks.
        if let Some(replacements) = &self.replacements {
            self.leaving = replacements.leaving(&self.states);
        } else if spec.on_collision != OnCollision::Continue {
            let colliding = colliding_agents(&self.states, &experiment.vehicle);
            if colliding.iter().any(|&c| c) {
                match spec.on_collision {
                    OnCollision::EndRun => self.ended = true,
                    OnCollision::ResetAgent => {
                        for (i, _) in colliding.iter().enumerate().filter(|(_, c)| **c) {
                            self.states[i] = initial_bicycle_state(&self.inputs.starts[i]);
                            self.velocities[i] = model.velocity_mps(&self.states[i]);
                            self.yaw_rates_rad_s[i] = 0.0;
                        }
                        self.policy.reset();
                    }
                    OnCollision::Continue | OnCollision::ReplaceAgent => {}
                }
            }
        }
        Ok(())
    }

    /// What the run recorded, with its layers' counts and replacements.
    fn finish(mut self) -> Recording {
        let recording = &mut self.recording;
        if let Some(filter) = &self.safety {
            crate::safety::record(filter, recording);
        }
        if self.replacements.is_some() {
            // Agents placed later are absent from the rows recorded before them.
            let agents = recording.ref_paths.len();
            for row in &mut recording.samples {
                row.resize(agents, AgentSample::ABSENT);
            }
            let count = |name: &str| f64::from(self.replaced.get(name).copied().unwrap_or(0));
            let reasons = [Leave::Collision, Leave::OffRoad, Leave::PathEnd].map(Leave::statistic);
            let total: f64 = reasons.iter().map(|name| count(name)).sum();
            recording.statistics.insert("replaced".into(), total);
            for name in reasons {
                recording.statistics.insert(name.into(), count(name));
            }
        }
        self.recording
    }
}

fn initial_bicycle_state(start: &InitialState) -> BicycleState {
    BicycleState {
        x_m: start.x_m,
        y_m: start.y_m,
        yaw_rad: start.yaw_rad,
        speed_mps: start.speed_mps,
        steering_rad: 0.0,
    }
}

/// A recorded sample; yaw wrapped to (−π, π] for readers of the file.
fn sample(state: &BicycleState, velocity_mps: [f64; 2]) -> AgentSample {
    AgentSample {
        x_m: state.x_m,
        y_m: state.y_m,
        yaw_rad: wrap_pi(state.yaw_rad),
        velocity_mps,
        steering_rad: state.steering_rad,
    }
}

fn wrap_pi(angle_rad: f64) -> f64 {
    let wrapped = angle_rad.sin().atan2(angle_rad.cos());
    if wrapped == -std::f64::consts::PI {
        std::f64::consts::PI
    } else {
        wrapped
    }
}

/// Whether any two footprints overlap (true minimum-translation-vector distance < 0).
pub(crate) fn any_overlap(
    poses: impl Iterator<Item = cpmx_sensing::Pose2>,
    vehicle: &cpmx_vehicle::VehicleParams,
) -> bool {
    let states: Vec<BicycleState> = poses
        .map(|p| BicycleState {
            x_m: p.x_m,
            y_m: p.y_m,
            yaw_rad: p.yaw_rad,
            ..BicycleState::default()
        })
        .collect();
    colliding_agents(&states, vehicle).iter().any(|&c| c)
}

/// Which agents' footprints overlap another's (true minimum-translation-vector distance < 0).
fn colliding_agents(states: &[BicycleState], vehicle: &cpmx_vehicle::VehicleParams) -> Vec<bool> {
    let boxes: Vec<PlacedBox> = states
        .iter()
        .map(|s| PlacedBox::from_pose(vehicle, s.x_m, s.y_m, s.yaw_rad))
        .collect();
    let mut colliding = vec![false; states.len()];
    for i in 0..boxes.len() {
        for j in i + 1..boxes.len() {
            if mtv_distance_m(&boxes[i], &boxes[j]) < 0.0 {
                colliding[i] = true;
                colliding[j] = true;
            }
        }
    }
    colliding
}

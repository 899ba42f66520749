//! The sim engine (`control: direct, dynamics: kinematic`): SigmaRL's loop. Every `dt` the
//! policy sees all agents' states and its command goes straight into the kinematic bicycle
//! (through the fidelity's `safety:` filter, when it has one), stepped as SigmaRL 1.5.0 on
//! does (one Euler step), with `kinematic-rk4` as SigmaRL 1.4.0 does (integrated over the
//! step), or with `kinematic-vmas` as SigmaRL 1.2.0's VMAS does (direct commands, drag).
//!
//! The recording holds the state *before* each action, t = 0 … (steps − 1)·dt, as SigmaRL's
//! evaluation receives them; so the metrics of a run equal `cpmx evaluate` of its trajectory.

use cpmx_metrics::collision::{PlacedBox, mtv_distance_m};
use cpmx_policy::{AgentState, ObservationInput};
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
        let experiment = inputs.experiment;
        let spec = &experiment.spec;
        let model = KinematicBicycle::new(experiment.vehicle);
        let dt_s = spec.timing.dt;
        let integration = match inputs.fidelity.map(|f| &f.dynamics) {
            Some(DynamicsLayer::Kinematic(keyword)) => *keyword,
            _ => KinematicKeyword::Kinematic,
        };

        // Place the agents and prepare their paths.
        let starts = inputs.starts;
        let mut paths = inputs.agent_paths()?;
        let mut states: Vec<BicycleState> = starts.iter().map(initial_bicycle_state).collect();
        let mut velocities: Vec<[f64; 2]> = states.iter().map(|s| model.velocity_mps(s)).collect();
        // VMAS's yaw rates (`kinematic-vmas` only): from rest, as SigmaRL places its agents.
        let mut yaw_rates_rad_s = vec![0.0; states.len()];
        let mut policy = inputs.policy()?;

        let mut recording = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: Vec::with_capacity(spec.timing.steps as usize),
            ref_paths: starts.iter().map(|s| s.ref_path).collect(),
            samples: Vec::with_capacity(spec.timing.steps as usize),
        };
        let mut safety = crate::safety::filter_of_run(
            inputs.fidelity.and_then(|f| f.safety.as_ref()),
            inputs,
            &recording.ref_paths,
        )?;
        let mut knowledge = inputs.neighbour_knowledge();
        let mut agents = vec![AgentState::default(); states.len()];
        // `replace-agent`: the recording's agent in each slot (a replaced car's slot gets a new
        // one), and the slots whose cars leave once the policy has acted on their last state.
        let mut replacements = match spec.on_collision {
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
        let mut agent_in_slot: Vec<usize> = (0..states.len()).collect();
        let mut replaced = std::collections::BTreeMap::<&str, u32>::new();
        let mut leaving: Vec<Option<Leave>> = vec![None; states.len()];
        let mut commands = vec![Command::default(); states.len()];

        for step in 0..spec.timing.steps {
            // Record the state the policy acts on.
            // Times on a clean decimal grid (0.3, not 0.30000000000000004).
            recording
                .times_s
                .push((f64::from(step) * dt_s * 1e9).round() / 1e9);
            let mut row = vec![AgentSample::ABSENT; recording.ref_paths.len()];
            for ((state, velocity), &agent) in states.iter().zip(&velocities).zip(&agent_in_slot) {
                row[agent] = sample(state, *velocity);
            }
            recording.samples.push(row);

            // Decide and move.
            for ((agent, state), velocity) in agents.iter_mut().zip(&states).zip(&velocities) {
                *agent = AgentState::from_bicycle(state, *velocity);
            }
            let t_s = f64::from(step) * dt_s;
            let active = knowledge.is_active();
            let views = knowledge.step(t_s, &agents);
            let input = ObservationInput {
                agents: &agents,
                paths: &paths,
                vehicle: &experiment.vehicle,
                previous_corners: None,
                neighbours: active.then_some(views),
            };
            policy.act(&input, &mut commands)?;
            if let Some(filter) = &mut safety {
                filter.apply(&states, &velocities, &mut commands);
            }
            if let Some(replacements) = &mut replacements
                && step + 1 < spec.timing.steps
            {
                // The cars that collided at the last step leave; new ones act on the command
                // their slot's policy chose from the collision's state (SigmaRL's stale one).
                // (None is placed in the last step: its first sample would not be recorded.)
                for (slot, why) in leaving
                    .iter()
                    .enumerate()
                    .filter_map(|(slot, why)| Some((slot, (*why)?)))
                {
                    let (ref_path, prepared, state) = replacements.place(slot, &states).ok_or_else(|| {
                        RunError::Replacement(format!("no free place for a new car at t = {t_s:.2} s"))
                    })?;
                    states[slot] = state;
                    velocities[slot] = model.velocity_mps(&state);
                    paths.paths[slot] = prepared;
                    agent_in_slot[slot] = recording.ref_paths.len();
                    recording.ref_paths.push(ref_path);
                    *replaced.entry(why.statistic()).or_default() += 1;
                }
            }
            for (((state, velocity), yaw_rate_rad_s), command) in states
                .iter_mut()
                .zip(&mut velocities)
                .zip(&mut yaw_rates_rad_s)
                .zip(&commands)
            {
                (*state, *velocity) = match integration {
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
            if let Some(replacements) = &replacements {
                leaving = replacements.leaving(&states);
            } else if spec.on_collision != OnCollision::Continue {
                let colliding = colliding_agents(&states, &experiment.vehicle);
                if colliding.iter().any(|&c| c) {
                    match spec.on_collision {
                        OnCollision::EndRun => break,
                        OnCollision::ResetAgent => {
                            for (i, _) in colliding.iter().enumerate().filter(|(_, c)| **c) {
                                states[i] = initial_bicycle_state(&starts[i]);
                                velocities[i] = model.velocity_mps(&states[i]);
                                yaw_rates_rad_s[i] = 0.0;
                            }
                            policy.reset();
                        }
                        OnCollision::Continue | OnCollision::ReplaceAgent => {}
                    }
                }
            }
        }
        if let Some(filter) = &safety {
            crate::safety::record(filter, &mut recording);
        }
        if replacements.is_some() {
            // Agents placed later are absent from the rows recorded before them.
            let agents = recording.ref_paths.len();
            for row in &mut recording.samples {
                row.resize(agents, AgentSample::ABSENT);
            }
            let count = |name: &str| f64::from(replaced.get(name).copied().unwrap_or(0));
            let reasons = [Leave::Collision, Leave::OffRoad, Leave::PathEnd].map(Leave::statistic);
            let total: f64 = reasons.iter().map(|name| count(name)).sum();
            recording.statistics.insert("replaced".into(), total);
            for name in reasons {
                recording.statistics.insert(name.into(), count(name));
            }
        }
        Ok(recording)
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

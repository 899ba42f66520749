//! One network pass for several policies' calls: when runs step in lock-step, the policies of
//! the same actor (one `MlpActor`'s weights, shared by `Arc`) observe their agents into one
//! matrix, the actor runs once over all its rows, and each policy maps its own rows to commands
//! with its own output head and random stream. The kernels give every row the same bits
//! whatever rows surround it (`cpmx-kernels`: one running sum over the depth per element), so
//! each call has the bits of its own [`Policy::act`] (the tests below); a pass over many rows
//! is compute-bound where one run's few rows stream the weights from memory.
//!
//! This module owns the grouping and the shared buffers; observing and the output head are
//! [`MlpPolicy`]'s.

use cpmx_vehicle::Command;

use crate::actor::{ActorWorkspace, MlpActor};
use crate::observation::ObservationInput;
use crate::policy::{MlpPolicy, Policy, PolicyError};

/// One policy call: the policy, what it sees and where its commands go.
pub struct PolicyCall<'a> {
    /// The policy to call.
    pub policy: &'a mut dyn Policy,
    /// What it observes.
    pub input: ObservationInput<'a>,
    /// One command per agent of `input`.
    pub commands: &'a mut [Command],
}

/// The buffers of shared passes, kept between calls (they grow to the largest pass).
#[derive(Debug, Default)]
pub struct SharedPasses {
    rows: Vec<f32>,
    raw: Vec<f32>,
    workspace: Option<ActorWorkspace>,
}

impl SharedPasses {
    /// Makes every call, each with the result its own `act` gives: the calls whose policies
    /// run one actor on cpmx's kernels ([`Policy::as_mlp`]) share that actor's pass, every
    /// other call acts alone. Calls are made in order within each group.
    pub fn act(&mut self, calls: &mut [PolicyCall<'_>]) -> Vec<Result<(), PolicyError>> {
        let actors: Vec<Option<MlpActor>> = calls
            .iter_mut()
            .map(|call| call.policy.as_mlp().and_then(|mlp| mlp.actor().cloned()))
            .collect();
        let mut results: Vec<Option<Result<(), PolicyError>>> = (0..calls.len()).map(|_| None).collect();
        for first in 0..calls.len() {
            if results[first].is_some() {
                continue;
            }
            let group: Vec<usize> = match &actors[first] {
                Some(actor) => (first..calls.len())
                    .filter(|&i| results[i].is_none())
                    .filter(|&i| actors[i].as_ref().is_some_and(|other| other.same_weights(actor)))
                    .collect(),
                None => vec![first],
            };
            match (&actors[first], group.len()) {
                (Some(actor), 2..) => self.pass(actor, calls, &group, &mut results),
                _ => {
                    let call = &mut calls[first];
                    results[first] = Some(call.policy.act(&call.input, call.commands));
                }
            }
        }
        results
            .into_iter()
            .map(|result| result.expect("every call made"))
            .collect()
    }

    /// One pass of `actor` for the calls of `group` (all [`MlpPolicy`]s of that actor).
    fn pass(
        &mut self,
        actor: &MlpActor,
        calls: &mut [PolicyCall<'_>],
        group: &[usize],
        results: &mut [Option<Result<(), PolicyError>>],
    ) {
        self.rows.clear();
        // Each observed call and its first row.
        let mut observed: Vec<(usize, usize)> = Vec::with_capacity(group.len());
        let mut agents = 0;
        for &i in group {
            let call = &mut calls[i];
            match mlp(call.policy).observe(&call.input, call.commands) {
                Ok(rows) => {
                    self.rows.extend_from_slice(rows);
                    observed.push((i, agents));
                    agents += call.input.agents.len();
                }
                Err(error) => results[i] = Some(Err(error)),
            }
        }
        let outputs = actor.output_size();
        self.raw.resize(agents * outputs, 0.0);
        let workspace = match &mut self.workspace {
            Some(workspace) if workspace.serves(actor, agents) => workspace,
            slot => slot.insert(actor.workspace(agents)),
        };
        let passed = actor.forward(&self.rows, workspace, &mut self.raw);
        for (i, first_row) in observed {
            let call = &mut calls[i];
            let rows = call.input.agents.len();
            results[i] = Some(match &passed {
                Ok(()) => {
                    let raw = &self.raw[first_row * outputs..(first_row + rows) * outputs];
                    mlp(call.policy).act_on_outputs(raw, call.commands);
                    Ok(())
                }
                Err(error) => Err(PolicyError::Network(error.to_string())),
            });
        }
    }
}

/// A grouped call's policy (grouped calls are [`MlpPolicy`]s, see [`SharedPasses::act`]).
fn mlp<'p>(policy: &'p mut (dyn Policy + '_)) -> &'p mut MlpPolicy {
    policy.as_mlp().expect("grouped calls are MLP policies")
}

#[cfg(test)]
mod tests {
    //! Calls of one actor made together have the bits of each call made alone: policies of
    //! different run streams and noise, sampling and not, with different agent counts, beside
    //! a policy of another actor and a policy that is no network.

    use super::*;
    use crate::actor::Activation;
    use crate::observation::SigmarlObservation;
    use crate::{ActionMode, AgentPaths, AgentState, LaneFollow, LaneFollowParams};
    use cpmx_vehicle::VehicleParams;
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha20Rng;

    /// An actor of random weights for SigmaRL's observation (two hidden layers of 32).
    fn actor(seed: u64) -> MlpActor {
        let sizes = [SigmarlObservation::default().size(), 32, 32, 4];
        let mut rng = ChaCha20Rng::seed_from_u64(seed);
        let tensors: Vec<(Vec<f32>, Vec<f32>)> = sizes
            .windows(2)
            .map(|pair| {
                let scale = 1.0 / (pair[0] as f32).sqrt();
                let mut draw =
                    |n: usize| -> Vec<f32> { (0..n).map(|_| scale * rng.random_range(-1.0..1.0)).collect() };
                (draw(pair[0] * pair[1]), draw(pair[1]))
            })
            .collect();
        let layers: Vec<(&[f32], &[f32])> = tensors
            .iter()
            .map(|(w, b)| (w.as_slice(), b.as_slice()))
            .collect();
        MlpActor::from_layers(&sizes, &layers, Activation::Tanh).unwrap()
    }

    fn policy(actor: &MlpActor, mode: ActionMode, stream: u64) -> MlpPolicy {
        MlpPolicy::new(
            actor.clone(),
            SigmarlObservation::default(),
            mode,
            ChaCha20Rng::seed_from_u64(stream),
        )
        .unwrap()
    }

    #[test]
    fn calls_together_have_the_bits_of_calls_alone() {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = [
            AgentPaths::new([1, 4, 7].map(|id| map.reference_path(id).unwrap())),
            AgentPaths::new([2, 9].map(|id| map.reference_path(id).unwrap())),
        ];
        let agents = |n: usize, shift: f64| -> Vec<AgentState> {
            (0..n)
                .map(|i| AgentState {
                    x_m: 1.5 + 0.3 * i as f64 + shift,
                    y_m: 2.0 - 0.2 * i as f64,
                    yaw_rad: 0.4 * i as f64,
                    speed_mps: 0.5,
                    ..AgentState::default()
                })
                .collect()
        };
        let states = [
            agents(3, 0.0),
            agents(2, 0.1),
            agents(3, 0.2),
            agents(2, 0.3),
            agents(3, 0.4),
        ];
        let vehicle = VehicleParams::MU_CAR;
        let input = |k: usize| ObservationInput {
            agents: &states[k],
            paths: &paths[usize::from(states[k].len() == 2)],
            vehicle: &vehicle,
            previous_corners: None,
            neighbours: None,
        };
        let (one, other) = (actor(1), actor(2));
        let make = || -> Vec<Box<dyn Policy>> {
            vec![
                Box::new(policy(&one, ActionMode::Mean, 1)),
                Box::new(policy(&one, ActionMode::Sample, 2)),
                Box::new(policy(&other, ActionMode::Sample, 3)),
                Box::new(LaneFollow::new(LaneFollowParams::default())),
                Box::new(policy(&one, ActionMode::Sample, 4)),
            ]
        };
        let (mut alone, mut together) = (make(), make());
        let mut passes = SharedPasses::default();
        // Three steps: the policies' memories (previous corners) and streams carry over.
        for _ in 0..3 {
            let mut expected: Vec<Vec<Command>> =
                states.iter().map(|s| vec![Command::default(); s.len()]).collect();
            for (k, policy) in alone.iter_mut().enumerate() {
                policy.act(&input(k), &mut expected[k]).unwrap();
            }
            let mut found: Vec<Vec<Command>> =
                states.iter().map(|s| vec![Command::default(); s.len()]).collect();
            let mut calls: Vec<PolicyCall<'_>> = together
                .iter_mut()
                .zip(&mut found)
                .enumerate()
                .map(|(k, (policy, commands))| PolicyCall {
                    policy: policy.as_mut(),
                    input: input(k),
                    commands,
                })
                .collect();
            assert!(passes.act(&mut calls).iter().all(Result::is_ok));
            assert_eq!(found, expected);
        }
        // A call whose command buffer does not fit fails alone; the others still act.
        let mut short = vec![Command::default(); 1];
        let mut fits = vec![Command::default(); 2];
        let (first, rest) = together.split_at_mut(1);
        let mut calls = vec![
            PolicyCall {
                policy: first[0].as_mut(),
                input: input(0),
                commands: &mut short,
            },
            PolicyCall {
                policy: rest[3].as_mut(),
                input: input(1),
                commands: &mut fits,
            },
        ];
        let results = passes.act(&mut calls);
        assert!(matches!(results[0], Err(PolicyError::CommandCount { .. })));
        assert!(results[1].is_ok());
        assert_ne!(fits, vec![Command::default(); 2]);
    }
}

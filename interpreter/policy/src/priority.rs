//! XP-MARL (SigmaRL 1.2.0, ICRA 2025): actors that observe the actions of their neighbours
//! chosen earlier in the same step. Each step the agents are ranked (SigmaRL's learned priority
//! policy, a random permutation, or no order), then act one after another in rank order; an
//! agent's action slots hold, for each neighbour its observation already shows (nearest
//! first), that neighbour's action if it has acted this step and the fidelity's communication
//! layer delivers it at once, else zeros. The opponent-modelling baseline fills the slots
//! instead with every neighbour's tentative action: what the same actor chooses for it with the
//! slots empty.
//!
//! This module owns the ranking and the order of the passes; observation, network and head are
//! [`MlpPolicy`](crate::MlpPolicy)'s. One agent's outputs do not depend on the batch it runs in,
//! so an agent acting alone gets the bits it would get in a batch.

use cpmx_vehicle::Command;
use rand::{Rng, RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

use crate::action::{ActionHead, ActionMode, ActionOutput, OutputHead};
use crate::actor::{ActorWorkspace, MlpActor};
use crate::memory::ObservationMemory;
use crate::observation::{NeighbourView, ObservationInput, SigmarlObservation};
use crate::policy::{Policy, PolicyError, check_commands, check_input_size, fork_stream, write_commands};

/// `safe_tanh` bound of the priority score's TanhNormal.
const SCORE_BOUND: f32 = 1.0 - 1e-6;

/// How the agents are ordered within a step.
#[derive(Debug, Clone)]
pub enum Ranking {
    /// SigmaRL's priority policy: an MLP from each agent's observation without the action
    /// slots to the location and scale of a TanhNormal score on [-1, 1]. The score's mode,
    /// `clamp(tanh(loc))` in float32, ranks the agents, the highest first; equal scores keep
    /// the agents' order.
    Learned(Box<MlpActor>),
    /// A fresh uniform permutation every step (Fisher–Yates on the run's `priority` stream).
    Random(Box<ChaCha20Rng>),
    /// No order: every agent acts at once with its action slots empty.
    Unranked,
}

/// What fills the action slots.
#[derive(Debug, Clone)]
pub enum SlotFilling {
    /// The actions of higher-ranked neighbours, ranked as given (XP-MARL).
    Propagated(Ranking),
    /// Every neighbour's tentative action (opponent modelling): two batched passes.
    Tentative,
}

/// An actor whose observation ends in its neighbours' actions (see the module docs).
#[derive(Debug, Clone)]
pub struct PrioritizedPolicy {
    observation: SigmarlObservation,
    actor: MlpActor,
    workspace: ActorWorkspace,
    filling: SlotFilling,
    priority_workspace: Option<ActorWorkspace>,
    head: ActionHead,
    output: OutputHead,
    mode: ActionMode,
    rng: ChaCha20Rng,
    memory: ObservationMemory,
    rows: Vec<f32>,
    bases: Vec<f32>,
    neighbours: Vec<Option<usize>>,
    raw: Vec<f32>,
    scores: Vec<f32>,
    order: Vec<usize>,
    acted: Vec<Option<[f32; 2]>>,
    outputs: Vec<ActionOutput>,
}

impl PrioritizedPolicy {
    /// An actor over `observation` (which must have action slots) with `filling`'s slots;
    /// fails if the actor's input is not the observation's size, its outputs are not what
    /// `output` reads, or a priority network does not map the observation without the slots to
    /// a score's 2 parameters. `rng` is the policy-sampling stream ([`ActionMode::Sample`]).
    pub fn new(
        actor: MlpActor,
        observation: SigmarlObservation,
        filling: SlotFilling,
        output: OutputHead,
        mode: ActionMode,
        rng: ChaCha20Rng,
    ) -> Result<Self, PolicyError> {
        check_input_size(&observation, &actor)?;
        if actor.output_size() != output.raw_size() {
            return Err(PolicyError::OutputSize {
                found: actor.output_size(),
                expected: output.raw_size(),
                what: output.describe(),
            });
        }
        let base = observation.size() - observation.action_slot_count();
        let priority_workspace = match &filling {
            SlotFilling::Propagated(Ranking::Learned(priority)) => {
                if priority.input_size() != base {
                    return Err(PolicyError::InputSize {
                        observation: base,
                        network: priority.input_size(),
                    });
                }
                if priority.output_size() != 2 {
                    return Err(PolicyError::OutputSize {
                        found: priority.output_size(),
                        expected: 2,
                        what: "the location and pre-scale of the priority score",
                    });
                }
                Some(priority.workspace(0))
            }
            _ => None,
        };
        Ok(PrioritizedPolicy {
            workspace: actor.workspace(0),
            observation,
            actor,
            filling,
            priority_workspace,
            head: ActionHead::default(),
            output,
            mode,
            rng,
            memory: ObservationMemory::default(),
            rows: Vec::new(),
            bases: Vec::new(),
            neighbours: Vec::new(),
            raw: Vec::new(),
            scores: Vec::new(),
            order: Vec::new(),
            acted: Vec::new(),
            outputs: Vec::new(),
        })
    }

    /// The same policy drawing its observation's noise (if the design adds any) from `rng`.
    pub fn with_noise_stream(mut self, rng: ChaCha20Rng) -> Self {
        self.memory.set_noise_stream(rng);
        self
    }

    /// The same policy with the actions' box of `head` (the checkpoint's release's car).
    pub fn with_action_head(mut self, head: ActionHead) -> Self {
        self.head = head;
        self
    }

    /// The order the agents acted in at the last call (agent per turn; empty when unranked).
    pub fn order(&self) -> &[usize] {
        &self.order
    }

    /// Distribution parameters and actions of the last call, one per agent.
    pub fn outputs(&self) -> &[ActionOutput] {
        &self.outputs
    }

    /// The observations the applied actions were chosen from at the last call (`agents *
    /// size` values, agent-major, action slots filled).
    pub fn observations(&self) -> &[f32] {
        &self.rows
    }

    /// Sizes the buffers for `agents` (allocates only when the count grows).
    fn prepare(&mut self, agents: usize) {
        let size = self.observation.size();
        self.rows.resize(agents * size, 0.0);
        self.neighbours.resize(agents * self.observation.neighbours, None);
        self.raw.resize(agents * self.output.raw_size().max(2), 0.0);
        self.outputs.resize(agents, ActionOutput::default());
        self.acted.clear();
        self.acted.resize(agents, None);
        if self.workspace.capacity() < agents {
            self.workspace = self.actor.workspace(agents);
        }
        if let (Some(workspace), SlotFilling::Propagated(Ranking::Learned(priority))) =
            (&mut self.priority_workspace, &self.filling)
            && workspace.capacity() < agents
        {
            *workspace = priority.workspace(agents);
        }
    }

    /// Ranks the agents into `self.order` from the observations without their slots.
    fn rank(&mut self, agents: usize) -> Result<(), PolicyError> {
        let SlotFilling::Propagated(ranking) = &mut self.filling else {
            self.order.clear();
            return Ok(());
        };
        self.order.clear();
        self.order.extend(0..agents);
        match ranking {
            Ranking::Unranked => self.order.clear(),
            Ranking::Random(rng) => {
                for i in (1..agents).rev() {
                    self.order.swap(i, rng.random_range(0..=i));
                }
            }
            Ranking::Learned(priority) => {
                let (size, slots) = (self.observation.size(), self.observation.action_slot_count());
                let base = size - slots;
                self.bases.clear();
                for row in self.rows.chunks_exact(size) {
                    self.bases.extend_from_slice(&row[..base]);
                }
                self.scores.resize(agents * 2, 0.0);
                let workspace = self
                    .priority_workspace
                    .as_mut()
                    .expect("built with the learned ranking");
                priority.forward(&self.bases, workspace, &mut self.scores)?;
                // The score's mode, once per agent, where its location was.
                for pair in self.scores.chunks_exact_mut(2) {
                    pair[0] = pair[0].tanh().clamp(-SCORE_BOUND, SCORE_BOUND);
                }
                let scores = &self.scores;
                self.order
                    .sort_by(|&a, &b| scores[2 * b].total_cmp(&scores[2 * a]));
            }
        }
        Ok(())
    }

    /// Writes into agent `i`'s slots the actions `self.acted` holds of its observed neighbours
    /// that the communication layer lets it hear at once (zeros for the rest).
    fn fill_slots(&mut self, input: &ObservationInput<'_>, i: usize) {
        let (size, k) = (self.observation.size(), self.observation.neighbours);
        let start = (i + 1) * size - self.observation.action_slot_count();
        for (slot, neighbour) in self.neighbours[i * k..(i + 1) * k].iter().enumerate() {
            let heard = neighbour.and_then(|j| {
                let exact = input
                    .neighbours
                    .is_none_or(|v| v.get(i, j) == NeighbourView::Exact);
                if exact { self.acted[j] } else { None }
            });
            let [speed, steering] = heard.unwrap_or([0.0; 2]);
            self.rows[start + 2 * slot] = speed;
            self.rows[start + 2 * slot + 1] = steering;
        }
    }

    /// Runs the actor on agents `first..first + count` of `self.rows` and maps their outputs.
    fn decide(&mut self, first: usize, count: usize) -> Result<(), PolicyError> {
        let (size, raw_size) = (self.observation.size(), self.output.raw_size());
        let rows = &self.rows[first * size..(first + count) * size];
        let raw = &mut self.raw[first * raw_size..(first + count) * raw_size];
        self.actor.forward(rows, &mut self.workspace, raw)?;
        for (i, raw) in (first..first + count).zip(raw.chunks_exact(raw_size)) {
            self.outputs[i] = self.output.map(&self.head, raw, self.mode, &mut self.rng);
        }
        Ok(())
    }
}

impl Policy for PrioritizedPolicy {
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
        check_commands(input, out)?;
        let agents = input.agents.len();
        self.prepare(agents);
        let observed = self
            .memory
            .observe_with_neighbours(&self.observation, input, &mut self.neighbours)?;
        self.rows.copy_from_slice(observed);
        self.rank(agents)?;
        match &self.filling {
            SlotFilling::Tentative => {
                self.decide(0, agents)?;
                for (acted, output) in self.acted.iter_mut().zip(&self.outputs) {
                    *acted = Some(output.action);
                }
                for i in 0..agents {
                    self.fill_slots(input, i);
                }
                self.decide(0, agents)?;
            }
            SlotFilling::Propagated(_) if self.order.is_empty() => self.decide(0, agents)?,
            SlotFilling::Propagated(_) => {
                for turn in 0..agents {
                    let i = self.order[turn];
                    self.fill_slots(input, i);
                    self.decide(i, 1)?;
                    self.acted[i] = Some(self.outputs[i].action);
                }
            }
        }
        write_commands(&self.outputs, out);
        Ok(())
    }

    fn reset(&mut self) {
        self.memory.forget();
    }

    fn fork(&mut self) -> Box<dyn Policy> {
        let mut copy = self.clone();
        copy.memory = self.memory.remembering();
        copy.rng = fork_stream(self.mode, &mut self.rng);
        if let (
            SlotFilling::Propagated(Ranking::Random(own)),
            SlotFilling::Propagated(Ranking::Random(theirs)),
        ) = (&mut self.filling, &mut copy.filling)
        {
            **theirs = ChaCha20Rng::seed_from_u64(own.next_u64());
        }
        Box::new(copy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::actor::Activation;
    use crate::geometry::AgentPaths;
    use crate::observation::{AgentState, NeighbourViews};
    use cpmx_vehicle::VehicleParams;

    /// One nearest neighbour observed, with its two action slots at the end.
    fn design() -> SigmarlObservation {
        SigmarlObservation {
            neighbours: 1,
            action_slots: true,
            ..SigmarlObservation::default()
        }
    }

    /// A linear actor whose speed location is 0.5 plus the sum of the action slots (so its
    /// speed tells what it heard), and a priority network scoring the own speed.
    fn networks() -> (MlpActor, MlpActor) {
        let size = design().size();
        let mut weight = vec![0.0; 4 * size];
        weight[size - 2] = 1.0;
        weight[size - 1] = 1.0;
        let actor =
            MlpActor::from_layers(&[size, 4], &[(&weight, &[0.5, 0.0, 0.0, 0.0])], Activation::Tanh).unwrap();
        let base = size - 2;
        let mut score = vec![0.0; 2 * base];
        score[0] = 1.0;
        let priority = MlpActor::from_layers(&[base, 2], &[(&score, &[0.0, 0.0])], Activation::Tanh).unwrap();
        (actor, priority)
    }

    /// Agent 2 is agent 0's nearest neighbour, agent 0 the nearest of agents 1 and 2; agent 1
    /// drives fastest, then agent 2, then agent 0.
    fn agents() -> Vec<AgentState> {
        [(0.3, 0.0, 0.1), (-0.5, 0.2, 0.3), (1.0, 0.4, 0.2)]
            .iter()
            .map(|&(x_m, y_m, speed)| AgentState {
                x_m,
                y_m,
                yaw_rad: 0.1,
                speed_mps: speed,
                velocity_mps: [speed, 0.0],
                steering_rad: 0.0,
            })
            .collect()
    }

    fn speeds(filling: SlotFilling, views: Option<&NeighbourViews>) -> (Vec<f32>, Vec<usize>) {
        let map = cpmx_world::Map::builtin("intersection").unwrap();
        let paths = AgentPaths::new([1, 2, 3].map(|id| map.reference_path(id).unwrap()));
        let agents = agents();
        let input = ObservationInput {
            agents: &agents,
            paths: &paths,
            vehicle: &VehicleParams::MU_CAR,
            previous_corners: None,
            neighbours: views,
        };
        let (actor, _) = networks();
        let rng = ChaCha20Rng::seed_from_u64(0);
        let mut policy = PrioritizedPolicy::new(
            actor,
            design(),
            filling,
            OutputHead::SigmarlTanhNormal,
            ActionMode::Mean,
            rng,
        )
        .unwrap();
        let mut out = vec![Command::default(); 3];
        policy.act(&input, &mut out).unwrap();
        (
            out.iter().map(|c| c.speed_mps as f32).collect(),
            policy.order().to_vec(),
        )
    }

    #[test]
    fn higher_ranks_act_first_and_lower_ranks_hear_them() {
        let learned = || SlotFilling::Propagated(Ranking::Learned(Box::new(networks().1)));
        let (speeds, order) = speeds(learned(), None);
        assert_eq!(order, [1, 2, 0]);
        let alone = 0.5f32.tanh();
        // Agents 1 and 2 act before their neighbour (agent 0) and hear nothing; agent 0 acts
        // last and hears agent 2's action.
        let heard = (0.5 + alone).tanh();
        assert_close(&speeds, &[heard, alone, alone]);

        // Without a ranking nobody hears anything; with tentative actions everybody does.
        let (unranked, order) = self::speeds(SlotFilling::Propagated(Ranking::Unranked), None);
        assert!(order.is_empty());
        assert_close(&unranked, &[alone; 3]);
        let (tentative, _) = self::speeds(SlotFilling::Tentative, None);
        assert_close(&tentative, &[heard; 3]);

        // An action is heard only through an exact view: agent 0 knowing agent 2 from an older
        // message does not hear its action of this step.
        let mut views = NeighbourViews::exact(3);
        views.set(0, 2, NeighbourView::Known(agents()[2]));
        let (late, _) = self::speeds(learned(), Some(&views));
        assert_close(&late, &[alone; 3]);
    }

    fn assert_close(found: &[f32], expected: &[f32]) {
        let close = found.iter().zip(expected).all(|(a, b)| (a - b).abs() < 1e-6);
        assert!(
            close && found.len() == expected.len(),
            "{found:?} != {expected:?}"
        );
    }

    #[test]
    fn random_ranks_are_permutations_drawn_from_the_stream() {
        let random =
            |seed| SlotFilling::Propagated(Ranking::Random(Box::new(ChaCha20Rng::seed_from_u64(seed))));
        let (first, order) = speeds(random(7), None);
        let mut sorted = order.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, [0, 1, 2]);
        assert_eq!(speeds(random(7), None), (first, order));
        let orders: std::collections::BTreeSet<Vec<usize>> =
            (0..20).map(|seed| speeds(random(seed), None).1).collect();
        assert!(orders.len() > 3, "{orders:?}");
    }

    #[test]
    fn a_priority_network_must_fit_the_observation_without_its_slots() {
        let (actor, _) = networks();
        let wrong = MlpActor::from_layers(&[5, 2], &[(&[0.0; 10], &[0.0; 2])], Activation::Tanh).unwrap();
        let error = PrioritizedPolicy::new(
            actor,
            design(),
            SlotFilling::Propagated(Ranking::Learned(Box::new(wrong))),
            OutputHead::SigmarlTanhNormal,
            ActionMode::Mean,
            ChaCha20Rng::seed_from_u64(0),
        )
        .unwrap_err();
        assert!(error.to_string().contains("network expects 5 inputs"), "{error}");
    }
}

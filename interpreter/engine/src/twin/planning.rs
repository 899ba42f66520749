//! The plans of several twin runs at one tick, made together: each run's planner rolls its
//! policy out over Hc on its own predicted states ([`Rollout`]), one rolled-out step at a time
//! across the runs, so that the policies' calls of each step go to
//! [`SharedPasses`] together and the runs of one actor share its network pass. A run's calls
//! are the ones [`cpmx_planner::Planner::plan`] makes (the policy on the listed states, its fork
//! on the predicted ones; the safety filter on every rolled-out step), with the same bits.
//!
//! This module owns the interleaving; the rollout is `cpmx-planner`'s, the pass
//! `cpmx-policy`'s.

use cpmx_planner::{CommandFilter, PlannedTrajectory, Rollout};
use cpmx_policy::{Policy, PolicyCall, SharedPasses};
use cpmx_safety::layer::LayerFilter;
use cpmx_stack::StampedState;
use cpmx_vehicle::Command;

use crate::engine::RunError;

/// A run's plan under way at a tick.
pub(super) struct Planning<'r> {
    rollout: Rollout<'r>,
    /// The run's policy: the first rolled-out step's.
    policy: &'r mut dyn Policy,
    /// Its fork, for the predicted steps (made after the first).
    fork: Option<Box<dyn Policy>>,
    filter: Option<&'r mut LayerFilter>,
    commands: Vec<Command>,
    /// The states the middleware listed, which the plan starts from.
    listed: Vec<StampedState>,
}

impl<'r> Planning<'r> {
    /// A plan of `rollout` by `policy` (through `filter`, if any) from the `listed` states.
    pub(super) fn new(
        rollout: Rollout<'r>,
        policy: &'r mut dyn Policy,
        filter: Option<&'r mut LayerFilter>,
        listed: Vec<StampedState>,
    ) -> Self {
        Planning {
            rollout,
            policy,
            fork: None,
            filter,
            commands: vec![Command::default(); listed.len()],
            listed,
        }
    }
}

/// A run's plan: its trajectories and the listed states they start from.
pub(super) type Plan = (Vec<PlannedTrajectory>, Vec<StampedState>);

/// Makes every plan (each tagged with its run's index), the calls of each rolled-out step
/// together; a run whose policy fails has that error, the others go on.
pub(super) fn plan_together(
    mut plannings: Vec<(usize, Planning<'_>)>,
    passes: &mut SharedPasses,
) -> Vec<(usize, Result<Plan, RunError>)> {
    let mut done: Vec<(usize, Result<Plan, RunError>)> = Vec::with_capacity(plannings.len());
    loop {
        let mut calls: Vec<PolicyCall<'_>> = Vec::with_capacity(plannings.len());
        for (_, planning) in &mut plannings {
            let Planning {
                rollout,
                policy,
                fork,
                commands,
                ..
            } = planning;
            let Some(input) = rollout.input() else { continue };
            // The real policy sees the real states once per planning time; the predicted
            // steps go to its fork, so they leave its memory (and random stream) untouched.
            let policy: &mut dyn Policy = match fork {
                Some(fork) => fork.as_mut(),
                None => &mut **policy,
            };
            calls.push(PolicyCall {
                policy,
                input,
                commands,
            });
        }
        if calls.is_empty() {
            break;
        }
        let results = passes.act(&mut calls);
        drop(calls);
        // Every planning with an input made a call, in order.
        let mut results = results.into_iter();
        let mut going = Vec::with_capacity(plannings.len());
        for (run, mut planning) in plannings {
            if planning.rollout.input().is_none() {
                going.push((run, planning));
                continue;
            }
            match results.next().expect("a result per call") {
                Ok(()) => {
                    if planning.fork.is_none() {
                        planning.fork = Some(planning.policy.fork());
                    }
                    let filter = planning
                        .filter
                        .as_deref_mut()
                        .map(|f| f as &mut dyn CommandFilter);
                    planning.rollout.apply(&mut planning.commands, filter);
                    going.push((run, planning));
                }
                Err(error) => done.push((run, Err(error.into()))),
            }
        }
        plannings = going;
    }
    done.extend(
        plannings
            .into_iter()
            .map(|(run, planning)| (run, Ok((planning.rollout.finish(), planning.listed)))),
    );
    done
}

//! The spec checks that need the interpreter: which fidelities this build can run, and what
//! only the map and the networks can tell (reference path ids, starts that leave the road or
//! overlap, regions, weights whose tensors do not fit the observation).

use std::path::Path;

use cpmx_policy::ActorError;
use cpmx_spec::model::{Fidelity, MapSpec};
use cpmx_spec::{CheckContext, InterpreterChecks, Problem, Resources, Spec};
use cpmx_world::Map;

use crate::experiment::{PrepareError, load_map_spec};
use crate::policies::{load_network, observation};

/// The checks of this build of cpmx.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuildChecks;

impl InterpreterChecks for BuildChecks {
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String> {
        unsupported_reason(fidelity)
    }

    fn check(&self, spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
        check_weights(spec, resources, ctx);
        check_control_period(spec, ctx);
        check_onnx(spec, resources, ctx);
        check_processes(spec, resources, ctx);
        let Some(map) = checked_map(&spec.map, resources.map_file.as_deref(), "/map", ctx) else {
            return;
        };
        let own_maps: Vec<Option<Map>> = spec
            .initial_configurations
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let own = c.own_map()?;
                let file = resources
                    .configuration_map_files
                    .get(i)
                    .and_then(Option::as_deref);
                checked_map(own, file, &format!("/initial_configurations/{i}/map"), ctx)
            })
            .collect();
        let maps: Vec<Option<&Map>> = spec
            .initial_configurations
            .iter()
            .zip(&own_maps)
            .map(|(c, own)| match c.own_map() {
                Some(_) => own.as_ref(),
                None => Some(&map),
            })
            .collect();
        crate::check_starts::check_starts(spec, resources, &maps, ctx);
    }
}

/// The map a `map:` value at `pointer` names, loaded; `None`, with the problem said at its
/// key, when it does not load (or, for a file the data path did not find, was said missing).
fn checked_map(map: &MapSpec, file: Option<&Path>, pointer: &str, ctx: &mut CheckContext<'_>) -> Option<Map> {
    if matches!(map, MapSpec::File(_) | MapSpec::Sigmarl(_)) && file.is_none() {
        // The data path did not find the file: the spec's checks said so.
        return None;
    }
    match load_map_spec(map, file) {
        Ok(map) => Some(map),
        Err(e) => {
            let at = match (map, &e) {
                (MapSpec::File(_), PrepareError::Map(cpmx_world::MapError::UnknownRegion { .. })) => {
                    "/region"
                }
                (MapSpec::File(_), PrepareError::RefPath { .. }) => "/ref_paths",
                (MapSpec::File(_), _) => "/file",
                (MapSpec::Builtin(_), _) => "",
                (MapSpec::Sigmarl(_), _) => "/sigmarl",
            };
            let span = ctx.span(&format!("{pointer}{at}"));
            ctx.push(
                Problem::error(
                    "cpmx::map::invalid",
                    format!("the map cannot be used: {e}"),
                    span,
                    "this map",
                )
                .with_help("fix the map file, or name another one"),
            );
            None
        }
    }
}

/// Why this build cannot run a fidelity, or `None` when it can. `control: trajectory` runs
/// every layer stack (twin engine); `control: direct` drives the kinematic bicycle with ideal
/// sensing and actuation (SigmaRL's simulation; the spec's checks refuse other layers with it);
/// the lab driver runs whatever discovery rustdds can do (no initial peers beyond this host).
pub(crate) fn unsupported_reason(fidelity: &Fidelity) -> Option<String> {
    match fidelity {
        Fidelity::Lab(lab) => crate::lab::discovery_config(lab).err(),
        Fidelity::Simulated(_) => None,
    }
}

/// A fidelity that runs the lab's vehicle stack (planned trajectories, or the lab itself) steps
/// its vehicles every 0.02 s. The lab, and trainings through such a fidelity, need a policy
/// step of whole periods; a simulated stack decides at the first period at or after each step
/// (`cpmx_stack::DecisionSchedule`), which a warning says, and needs a step of one period at
/// least.
fn check_control_period(spec: &Spec, ctx: &mut CheckContext<'_>) {
    let dt_s = spec.timing.dt;
    if cpmx_stack::control_periods(dt_s).is_some() {
        return;
    }
    let trained: Vec<&str> = spec
        .training
        .as_ref()
        .map(|t| t.fidelity.names().iter().map(String::as_str).collect())
        .unwrap_or_default();
    let schedulable = cpmx_stack::DecisionSchedule::new(dt_s).is_some();
    let (mut refused, mut scheduled) = (Vec::new(), Vec::new());
    for (name, fidelity) in &spec.fidelities {
        match fidelity {
            Fidelity::Lab(_) => refused.push(name.as_str()),
            Fidelity::Simulated(s) if s.control == cpmx_spec::model::Control::Trajectory => {
                if schedulable && !trained.contains(&name.as_str()) {
                    scheduled.push(name.as_str());
                } else {
                    refused.push(name.as_str());
                }
            }
            Fidelity::Simulated(_) => {}
        }
    }
    let names = |names: &[&str]| {
        format!(
            "fidelit{} `{}`",
            if names.len() == 1 { "y" } else { "ies" },
            names.join("`, `")
        )
    };
    let period_s = cpmx_stack::CONTROL_PERIOD_S;
    if !refused.is_empty() {
        let span = ctx.span("/timing/dt");
        ctx.push(
            Problem::error(
                "cpmx::check::control-period",
                format!(
                    "`timing.dt: {dt_s}` is no multiple of the vehicles' {period_s} s control period, which {} \
                     run{} on{}",
                    names(&refused),
                    if refused.len() == 1 { "s" } else { "" },
                    if trained.iter().any(|t| refused.contains(t)) {
                        " (and the training steps through)"
                    } else {
                        ""
                    },
                ),
                span,
                "not a whole number of periods",
            )
            .with_help("choose a step of 0.02 s periods (e.g. 0.04 or 0.06), or drive those fidelities with `control: direct`"),
        );
    }
    if !scheduled.is_empty() {
        let span = ctx.span("/timing/dt");
        ctx.push(
            Problem::warning(
                "cpmx::check::control-period",
                format!(
                    "`timing.dt: {dt_s}` is no multiple of the vehicles' {period_s} s control period: in {} \
                     the policy decides at the first period at or after each step (the steps between \
                     decisions alternate, e.g. 0.04 and 0.06 s for 0.05 s), as a lab acting on its \
                     vehicles' periods would",
                    names(&scheduled)
                ),
                span,
                "decisions on the vehicles' periods",
            )
            .with_help("a step of whole 0.02 s periods decides exactly every step"),
        );
    }
}

/// Every network loads, its layers chain, its first layer takes the observation's values and
/// its last gives what the output head reads; a failure names the tensor and both shapes, with
/// a help line for that case.
fn check_weights(spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
    for (i, (policy, weights)) in spec.policies.iter().zip(&resources.weights).enumerate() {
        let (Some(path), Some(design), Some(mlp)) = (weights, &policy.observation, &policy.mlp) else {
            continue;
        };
        let obs = observation(design);
        let Err(e) = load_network(mlp, &obs, path) else {
            continue;
        };
        let file_key = match (&mlp.sigmarl, &mlp.trained) {
            (Some(_), _) => "sigmarl",
            (None, Some(_)) => "trained",
            (None, None) => "weights",
        };
        let (pointer, help) = match &e {
            ActorError::InputSize { observation, .. } => (
                format!("/policies/{i}/observation"),
                format!(
                    "the observation design here gives {observation} values; set `observation:` to the design this network was trained with"
                ),
            ),
            ActorError::OutputSize { expected, .. } => (
                format!("/policies/{i}/mlp/{file_key}"),
                format!(
                    "declare the head the network was trained with: `output: sigmarl-tanh-normal` reads 4 outputs, \
                     `deterministic-tanh` and `deterministic-clip` read 2 (this one reads {expected})"
                ),
            ),
            ActorError::Chain { .. } | ActorError::Rank { .. } => (
                format!("/policies/{i}/mlp/{file_key}"),
                "each `PREFIX.N.weight` must be [outputs, inputs] with inputs equal to the previous layer's outputs; export the actor's state_dict again".to_owned(),
            ),
            ActorError::NoLayers { .. } | ActorError::AmbiguousPrefix { .. } | ActorError::MissingTensor { .. } => (
                format!("/policies/{i}/mlp/{file_key}"),
                "name the layers `PREFIX.N.weight` and `PREFIX.N.bias` (the state_dict of a torch nn.Sequential), one network per file".to_owned(),
            ),
            ActorError::Dtype { .. } => (
                format!("/policies/{i}/mlp/{file_key}"),
                "store the tensors as float32".to_owned(),
            ),
            ActorError::Checkpoint(_) => (
                format!("/policies/{i}/mlp/{file_key}"),
                "name the checkpoint as SigmaRL's training saved it (torch.save's archive); a truncated or re-packed copy does not read".to_owned(),
            ),
            _ => (
                format!("/policies/{i}/mlp/{file_key}"),
                "is this a safetensors file? (`safetensors.torch.save_file(actor.state_dict(), ...)` writes one)".to_owned(),
            ),
        };
        let span = ctx.span(&pointer);
        ctx.push(
            Problem::error(
                "cpmx::policy::weights",
                format!("policy `{}`: {e}", policy.name),
                span,
                "this network",
            )
            .with_help(help),
        );
    }
}

/// Every ONNX graph loads, takes the observation's values and gives what the output head
/// reads; a failure names the input or output and both shapes.
fn check_onnx(spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
    use crate::onnx::OnnxLoadError;
    for (i, (policy, file)) in spec.policies.iter().zip(&resources.weights).enumerate() {
        let (Some(path), Some(design), Some(onnx)) = (file, &policy.observation, &policy.onnx) else {
            continue;
        };
        let obs = observation(design);
        let Err(e) = crate::onnx::load(onnx, obs.size(), path) else {
            continue;
        };
        let (pointer, help) = match &e {
            OnnxLoadError::NotBuilt => (
                format!("/policies/{i}/onnx"),
                "build cpmx with its default features (`cargo install --path .`), which include `onnx`".to_owned(),
            ),
            OnnxLoadError::InputSize(_) => (
                format!("/policies/{i}/onnx/file"),
                format!(
                    "the observation design here gives {} values; set `observation:` to the design this network was trained with, \
                     or export the network that takes it",
                    obs.size()
                ),
            ),
            OnnxLoadError::OutputSize(_) => (
                format!("/policies/{i}/onnx/file"),
                "declare the head the network was trained with: `output: sigmarl-tanh-normal` reads 4 values per agent, \
                 `deterministic-tanh` and `deterministic-clip` read 2; export the graph up to the actor's raw outputs"
                    .to_owned(),
            ),
            OnnxLoadError::Other(_) => (
                format!("/policies/{i}/onnx/file"),
                "export the actor alone, float32, with one input `[batch, observation]` and one output `[batch, 4]` \
                 (torch.onnx.export(actor, example, FILE, dynamic_axes={...: {0: \"batch\"}}))"
                    .to_owned(),
            ),
        };
        let span = ctx.span(&pointer);
        ctx.push(
            Problem::error(
                "cpmx::policy::onnx",
                format!("policy `{}`: {e}", policy.name),
                span,
                "this network",
            )
            .with_help(help),
        );
    }
}

/// Every policy process's program can be found: a path (with a `/`) relative to the spec's
/// folder, or a name on `PATH`.
fn check_processes(spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
    for (i, policy) in spec.policies.iter().enumerate() {
        let Some(program) = policy.process.as_ref().and_then(|p| p.command.first()) else {
            continue;
        };
        let path = std::path::Path::new(program);
        let found = if program.contains('/') {
            resources.spec_dir.join(path).is_file()
        } else {
            std::env::var_os("PATH")
                .is_some_and(|dirs| std::env::split_paths(&dirs).any(|d| d.join(path).is_file()))
        };
        if !found {
            let span = ctx.span(&format!("/policies/{i}/process/command/0"));
            ctx.push(
                Problem::error(
                    "cpmx::policy::process",
                    format!("policy `{}`: program `{program}` not found", policy.name),
                    span,
                    "this program",
                )
                .with_help(if program.contains('/') {
                    format!(
                        "paths are relative to the spec's folder {}",
                        resources.spec_dir.display()
                    )
                } else {
                    "install it, or give its path".to_owned()
                }),
            );
        }
    }
}

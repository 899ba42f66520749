//! The spec checks that need the interpreter: which fidelities this build can run, and what
//! only the map and the networks can tell (reference path ids, starts that leave the road or
//! overlap, regions, weights whose tensors do not fit the observation).

use cpmx_metrics::collision::{PlacedBox, mtv_distance_m};
use cpmx_policy::ActorError;
use cpmx_spec::model::{Fidelity, InitialConfiguration, MapSpec, SampleSpec};
use cpmx_spec::{CheckContext, InterpreterChecks, Problem, Resources, Spec};
use cpmx_vehicle::{VehicleParams, footprint_corners};
use cpmx_world::Map;

use crate::experiment::{PrepareError, load_map, load_network, observation, vehicle_params};
use crate::starts::{explicit_start, sample_starts};

/// The checks of this build of cpmx.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuildChecks;

impl InterpreterChecks for BuildChecks {
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String> {
        unsupported_reason(fidelity)
    }

    fn check(&self, spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
        check_weights(spec, resources, ctx);
        check_onnx(spec, resources, ctx);
        check_processes(spec, resources, ctx);
        if matches!(spec.map, MapSpec::File(_)) && resources.map_file.is_none() {
            // The data path did not find the file: the spec's checks said so.
            return;
        }
        let map = match load_map(spec, resources.map_file.as_deref()) {
            Ok(map) => map,
            Err(e) => {
                let pointer = match (&spec.map, &e) {
                    (MapSpec::File(_), PrepareError::Map(cpmx_world::MapError::UnknownRegion { .. })) => {
                        "/map/region"
                    }
                    (MapSpec::File(_), PrepareError::RefPath { .. }) => "/map/ref_paths",
                    (MapSpec::File(_), _) => "/map/file",
                    (MapSpec::Builtin(_), _) => "/map",
                };
                let span = ctx.span(pointer);
                ctx.push(
                    Problem::error(
                        "cpmx::map::invalid",
                        format!("the map cannot be used: {e}"),
                        span,
                        "this map",
                    )
                    .with_help("fix the map file, or name another one"),
                );
                return;
            }
        };
        check_starts(spec, &map, ctx);
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
        let (pointer, help) = match &e {
            ActorError::InputSize { observation, .. } => (
                format!("/policies/{i}/observation"),
                format!(
                    "the observation design here gives {observation} values; set `observation:` to the design this network was trained with"
                ),
            ),
            ActorError::OutputSize { expected, .. } => (
                format!("/policies/{i}/mlp/weights"),
                format!(
                    "declare the head the network was trained with: `output: sigmarl-tanh-normal` reads 4 outputs, \
                     `deterministic-tanh` and `deterministic-clip` read 2 (this one reads {expected})"
                ),
            ),
            ActorError::Chain { .. } | ActorError::Rank { .. } => (
                format!("/policies/{i}/mlp/weights"),
                "each `PREFIX.N.weight` must be [outputs, inputs] with inputs equal to the previous layer's outputs; export the actor's state_dict again".to_owned(),
            ),
            ActorError::NoLayers { .. } | ActorError::AmbiguousPrefix { .. } | ActorError::MissingTensor { .. } => (
                format!("/policies/{i}/mlp/weights"),
                "name the layers `PREFIX.N.weight` and `PREFIX.N.bias` (the state_dict of a torch nn.Sequential), one network per file".to_owned(),
            ),
            ActorError::Dtype { .. } => (
                format!("/policies/{i}/mlp/weights"),
                "store the tensors as float32".to_owned(),
            ),
            _ => (
                format!("/policies/{i}/mlp/weights"),
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

/// Explicit starts name paths of the map, stand on the road and do not overlap.
fn check_starts(spec: &Spec, map: &Map, ctx: &mut CheckContext<'_>) {
    let vehicle = vehicle_params(&spec.vehicle);
    let ids = map.valid_path_ids();
    let range = match (ids.first(), ids.last()) {
        (Some(first), Some(last)) if last - first + 1 == ids.len() => format!("{first}..={last}"),
        _ => format!("{ids:?}"),
    };
    for (c, configuration) in spec.initial_configurations.iter().enumerate() {
        if let InitialConfiguration::Sampled(sampled) = configuration {
            check_sampled_starts(spec, c, &sampled.sample, map, &vehicle, ctx);
        }
        let InitialConfiguration::Explicit(e) = configuration else {
            continue;
        };
        let mut placed: Vec<(usize, PlacedBox)> = Vec::new();
        for (a, agent) in e.agents.iter().enumerate() {
            let pointer = format!("/initial_configurations/{c}/agents/{a}");
            if map.reference_path(agent.ref_path as usize).is_none() {
                let span = ctx.span(&format!("{pointer}/ref_path"));
                ctx.push(
                    Problem::error(
                        "cpmx::map::ref-path",
                        format!("the map has no reference path {}", agent.ref_path),
                        span,
                        "unknown reference path",
                    )
                    .with_help(format!("this map's reference paths are {range}")),
                );
                continue;
            }
            let start = match explicit_start(agent, map) {
                Ok(start) => start,
                Err(reason) => {
                    let length_m = map
                        .reference_path(agent.ref_path as usize)
                        .map_or(0.0, |p| p.center_line.length_m());
                    let span = ctx.span(&format!("{pointer}/arc_length"));
                    ctx.push(
                        Problem::error(
                            "cpmx::map::arc-length",
                            format!("agent {a} of `{}`: {reason}", e.name),
                            span,
                            "beyond the path's end",
                        )
                        .with_help(format!(
                            "an arc length on path {} lies in [0, {length_m:.3}] m; `cpmx validate` of a \
                             spec with only `cpmx`, `name` and `map` lists every path's length",
                            agent.ref_path
                        )),
                    );
                    continue;
                }
            };
            let corners = footprint_corners(&vehicle, start.x_m, start.y_m, start.yaw_rad);
            if map.footprint_on_road(start.ref_path, &corners) == Some(false) {
                let span = ctx.span(&pointer);
                ctx.push(
                    Problem::error(
                        "cpmx::map::off-road",
                        format!(
                            "agent {a} of `{}` starts off the road of path {}",
                            e.name, start.ref_path
                        ),
                        span,
                        "footprint leaves the road",
                    )
                    .with_help("start on the path (`arc_length`) or move the `pose` onto its lanes"),
                );
            }
            let this = PlacedBox::from_pose(&vehicle, start.x_m, start.y_m, start.yaw_rad);
            if let Some((other, _)) = placed.iter().find(|(_, b)| mtv_distance_m(b, &this) < 0.0) {
                let span = ctx.span(&pointer);
                ctx.push(
                    Problem::error(
                        "cpmx::map::overlap",
                        format!(
                            "agents {other} and {a} of `{}` start on top of each other",
                            e.name
                        ),
                        span,
                        "overlaps another start",
                    )
                    .with_help("move one of them along its path"),
                );
            }
            placed.push((a, this));
        }
    }
}

/// Every draw of a `sample:` entry finds a place for every agent, as `cpmx run` will draw them
/// (the same stream): the first draw that does not is an error at the entry.
fn check_sampled_starts(
    spec: &Spec,
    entry: usize,
    sample: &SampleSpec,
    map: &Map,
    vehicle: &VehicleParams,
    ctx: &mut CheckContext<'_>,
) {
    let Some((index, reason)) = (0..sample.count).find_map(|index| {
        sample_starts(sample, index, spec.agents as usize, map, vehicle)
            .err()
            .map(|reason| (index, reason))
    }) else {
        return;
    };
    let span = ctx.span(&format!("/initial_configurations/{entry}/sample"));
    ctx.push(
        Problem::error(
            "cpmx::map::no-room",
            format!(
                "draw {} of {} of this sample cannot place {} agents: {reason}",
                index + 1,
                sample.count,
                spec.agents
            ),
            span,
            "no room on this map",
        )
        .with_help("lower `agents` or `min_gap`, or name a larger map"),
    );
}

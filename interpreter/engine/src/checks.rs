//! The spec checks that need the interpreter: which fidelities this build can run, and what
//! only the map and the networks can tell (reference path ids, starts that leave the road or
//! overlap, regions, weights whose tensors do not fit the observation).

use cpmx_metrics::collision::{PlacedBox, mtv_distance_m};
use cpmx_policy::{MlpActor, MlpLayout};
use cpmx_spec::model::{
    ActuationLayer, Control, DynamicsLayer, Fidelity, InitialConfiguration, MapSpec, SensingLayer,
    SimulatedFidelity,
};
use cpmx_spec::{CheckContext, InterpreterChecks, Problem, Resources, Spec};
use cpmx_vehicle::footprint_corners;
use cpmx_world::Map;

use crate::experiment::{PrepareError, load_map, observation, vehicle_params};
use crate::starts::explicit_start;

/// The checks of this build of cpmx.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuildChecks;

impl InterpreterChecks for BuildChecks {
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String> {
        unsupported_reason(fidelity)
    }

    fn check(&self, spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
        check_weights(spec, resources, ctx);
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
/// sensing and actuation (SigmaRL's simulation); the lab driver runs whatever discovery
/// rustdds can do (no initial peers beyond this host).
pub(crate) fn unsupported_reason(fidelity: &Fidelity) -> Option<String> {
    match fidelity {
        Fidelity::Lab(lab) => crate::lab::discovery_config(lab).err(),
        Fidelity::Simulated(SimulatedFidelity {
            control: Control::Trajectory,
            ..
        }) => None,
        Fidelity::Simulated(SimulatedFidelity {
            control: Control::Direct,
            dynamics,
            sensing,
            actuation,
            follower,
        }) => {
            let mut extra = Vec::new();
            if matches!(dynamics, DynamicsLayer::GreyBox(_)) {
                extra.push("grey-box dynamics");
            }
            if matches!(sensing, Some(SensingLayer::Model(_))) {
                extra.push("a sensing model");
            }
            if matches!(actuation, Some(ActuationLayer::Model(_))) {
                extra.push("an actuation model");
            }
            if follower.is_some() {
                extra.push("a `follower`");
            }
            (!extra.is_empty()).then(|| {
                format!(
                    "`control: direct` applies actions to the kinematic bicycle; {} need `control: trajectory`",
                    extra.join(", ")
                )
            })
        }
    }
}

/// Every network loads with the shapes its observation needs.
fn check_weights(spec: &Spec, resources: &Resources, ctx: &mut CheckContext<'_>) {
    for (i, (policy, weights)) in spec.policies.iter().zip(&resources.weights).enumerate() {
        let (Some(path), Some(design)) = (weights, &policy.observation) else {
            continue;
        };
        let layout = MlpLayout {
            input_size: observation(design).size(),
            ..MlpLayout::sigmarl()
        };
        if let Err(e) = MlpActor::load(path, &layout) {
            let span = ctx.span(&format!("/policies/{i}/mlp/weights"));
            ctx.push(
                Problem::error(
                    "cpmx::policy::weights",
                    format!("policy `{}`: {e}", policy.name),
                    span,
                    "these weights",
                )
                .with_help(format!(
                    "the observation `{}` has {} values; the network's first layer must take that many inputs",
                    policy.name,
                    layout.input_size
                )),
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
            let Ok(start) = explicit_start(agent, map) else {
                continue;
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

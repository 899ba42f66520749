//! An experiment ready to run: the spec's map, vehicle, policies and named initial
//! configurations turned into interpreter values, once, before any run starts.

use std::path::Path;
use std::sync::Arc;

use cpmx_metrics::{
    CollisionGeometry as MetricGeometry, CraAConfig, CraLConfig, EventCount, Hysteresis, MetricsConfig,
};
use cpmx_policy::{BoundaryCorners, MlpActor, MlpLayout, SigmarlObservation};
use cpmx_spec::model::{
    CollisionCount, CollisionGeometry, MapSpec, MetricsSpec, ObservationSpec, PolicySpec, VehicleSpec,
};
use cpmx_spec::{CheckedSpec, Spec};
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

use crate::starts::{InitialState, initial_states};

/// Why an experiment could not be prepared.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    #[error("cannot load the map: {0}")]
    Map(#[from] cpmx_world::MapError),
    #[error("reference path {id}: {source}")]
    RefPath { id: u32, source: cpmx_world::PathError },
    #[error("policy `{policy}`: {source}")]
    Actor {
        policy: String,
        source: cpmx_policy::ActorError,
    },
    #[error("initial configuration `{name}`: {reason}")]
    Start { name: String, reason: String },
    #[error(
        "policy `{policy}` names the actor trained with seed {seed}, which was not found: run `cpmx train` first"
    )]
    NotTrained { policy: String, seed: u64 },
}

/// A policy as the spec defines it, with its network loaded once.
#[derive(Debug, Clone)]
pub enum PreparedPolicy {
    Mlp {
        actor: Arc<MlpActor>,
        observation: SigmarlObservation,
        sample: bool,
    },
    LaneFollow(cpmx_spec::model::LaneFollowParams),
}

/// Everything a run needs that does not depend on the run.
#[derive(Debug, Clone)]
pub struct Experiment {
    pub spec: Spec,
    pub map: Arc<Map>,
    pub vehicle: VehicleParams,
    pub metrics: MetricsConfig,
    pub policies: Vec<(String, PreparedPolicy)>,
    /// Initial states by configuration name, in matrix order.
    pub starts: Vec<(String, Vec<InitialState>)>,
}

impl Experiment {
    /// Loads the map and the networks and places every initial configuration.
    pub fn prepare(checked: &CheckedSpec) -> Result<Experiment, PrepareError> {
        let spec = &checked.spec;
        let map = Arc::new(load_map(spec, checked.resources.map_file.as_deref())?);
        let vehicle = vehicle_params(&spec.vehicle);
        let mut policies = Vec::new();
        for (policy, weights) in spec.policies.iter().zip(&checked.resources.weights) {
            policies.push((policy.name.clone(), prepare_policy(policy, weights.as_deref())?));
        }
        let starts = initial_states(spec, &checked.configurations, &checked.resources, &map, &vehicle)?;
        Ok(Experiment {
            spec: spec.clone(),
            map,
            vehicle,
            metrics: metrics_config(&spec.metrics),
            policies,
            starts,
        })
    }

    pub fn policy(&self, name: &str) -> Option<&PreparedPolicy> {
        self.policies.iter().find(|(n, _)| n == name).map(|(_, p)| p)
    }

    pub fn start(&self, configuration: &str) -> Option<&[InitialState]> {
        self.starts
            .iter()
            .find(|(n, _)| n == configuration)
            .map(|(_, s)| s.as_slice())
    }
}

/// The spec's map: built-in or from its file, restricted to a region, with the spec's own paths.
pub fn load_map(spec: &Spec, map_file: Option<&Path>) -> Result<Map, PrepareError> {
    match &spec.map {
        MapSpec::Builtin(name) => Ok(Map::builtin(name.trim_start_matches(cpmx_spec::STDLIB_PREFIX))?),
        MapSpec::File(file) => {
            let path = map_file.unwrap_or(Path::new(&file.file));
            let mut map = match file.format {
                None => Map::load(path)?,
                Some(cpmx_spec::model::MapFormat::Commonroad) => {
                    Map::load_with_format(path, cpmx_world::MapFormat::CommonRoad)?
                }
                Some(cpmx_spec::model::MapFormat::Lanelet2) => {
                    Map::load_with_format(path, cpmx_world::MapFormat::Lanelet2Osm)?
                }
            };
            if let Some(region) = &file.region {
                map = map.with_region(region)?;
            }
            for definition in &file.ref_paths {
                map.add_reference_path(definition.id as usize, &definition.lanelets)
                    .map_err(|source| PrepareError::RefPath {
                        id: definition.id,
                        source,
                    })?;
            }
            Ok(map)
        }
    }
}

/// The spec's vehicle in the interpreter's units.
pub fn vehicle_params(v: &VehicleSpec) -> VehicleParams {
    VehicleParams {
        length_m: v.length,
        width_m: v.width,
        wheelbase_m: v.wheelbase,
        rear_axle_m: v.rear_axle,
        max_steering_rad: v.max_steering_deg.to_radians(),
        max_steering_rate_rad_s: v.max_steering_rate_deg_s.to_radians(),
        accel_mps2: (v.accel[0], v.accel[1]),
        max_speed_mps: v.max_speed,
    }
}

/// The spec's observation design as the policy crate's.
pub fn observation(o: &ObservationSpec) -> SigmarlObservation {
    SigmarlObservation {
        neighbours: o.observed_agents as usize,
        reference_points: o.ref_points as usize,
        reference_point_stride: o.ref_point_stride as usize,
        position_norm_m: o.position_scale_m,
        speed_norm_mps: o.speed_scale_mps,
        distance_norm_m: o.distance_scale_m,
        observe_center_line_distance: o.center_line_distance,
        observe_boundary_distances: o.boundary_distances,
        boundary_corners: if o.agent0_boundary_lag {
            BoundaryCorners::LaggedForFirstAgent
        } else {
            BoundaryCorners::Current
        },
        ..SigmarlObservation::default()
    }
}

/// Loads a policy's network (once per experiment).
pub fn prepare_policy(policy: &PolicySpec, weights: Option<&Path>) -> Result<PreparedPolicy, PrepareError> {
    match (&policy.mlp, weights) {
        (Some(mlp), found) => {
            let observation = observation(policy.observation.as_ref().expect("defaulted to stdlib:sigmarl"));
            let layout = MlpLayout {
                input_size: observation.size(),
                ..MlpLayout::sigmarl()
            };
            let path = match (found, &mlp.weights, &mlp.trained) {
                (Some(path), _, _) => path,
                (None, Some(weights), _) => Path::new(weights),
                (None, None, trained) => {
                    return Err(PrepareError::NotTrained {
                        policy: policy.name.clone(),
                        seed: trained.as_ref().map_or(0, |t| t.seed),
                    });
                }
            };
            let actor = MlpActor::load(path, &layout).map_err(|source| PrepareError::Actor {
                policy: policy.name.clone(),
                source,
            })?;
            let sample = policy.action == Some(cpmx_spec::model::ActionMode::Sample);
            Ok(PreparedPolicy::Mlp {
                actor: Arc::new(actor),
                observation,
                sample,
            })
        }
        (None, _) => Ok(PreparedPolicy::LaneFollow(
            policy.lane_follow.clone().unwrap_or_default(),
        )),
    }
}

/// The spec's metric parameters as the metrics crate's.
pub fn metrics_config(m: &MetricsSpec) -> MetricsConfig {
    let defaults = MetricsConfig::sigmarl_script(100.0);
    let cra_a = m.cra_a.as_ref().map_or(defaults.cra_a, |c| CraAConfig {
        hysteresis: Hysteresis {
            enter: c.hysteresis.enter as usize,
            exit: c.hysteresis.exit as usize,
        },
        geometry: match c.geometry {
            CollisionGeometry::Mtv => MetricGeometry::Mtv,
            CollisionGeometry::SigmarlMtv => MetricGeometry::SigmarlMtv,
        },
        count: match c.count {
            CollisionCount::PerAgent => EventCount::PerAgent,
            CollisionCount::PerPair => EventCount::PerPair,
        },
        per_distance_m: c.per_distance_m,
    });
    let cra_l = m.cra_l.as_ref().map_or(defaults.cra_l, |c| CraLConfig {
        slack: c.slack,
        per_distance_m: c.per_distance_m,
    });
    MetricsConfig {
        sample_period_s: m.sample_period_s,
        cra_a,
        cra_l,
        max_steps: None,
        rotate180: None,
    }
}

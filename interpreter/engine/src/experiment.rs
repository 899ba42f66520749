//! An experiment ready to run: the spec's map, vehicle, policies and named initial
//! configurations turned into interpreter values, once, before any run starts.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use cpmx_metrics::{
    CollisionGeometry as MetricGeometry, CraAConfig, CraLConfig, EventCount, Hysteresis, LaneBoundaries,
    MetricsConfig,
};
use cpmx_spec::model::{
    CollisionCount, CollisionGeometry, CraLBoundaries, MapSpec, MetricsSpec, VehicleSpec,
};
use cpmx_spec::{CheckedSpec, Spec};
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

use crate::memo::Memo;
use crate::policies::{PreparedPolicy, prepare_policy};
use crate::starts::{ConfigurationStarts, InitialState, initial_states, start_of};

/// Why an experiment could not be prepared.
#[derive(Debug, thiserror::Error)]
pub enum PrepareError {
    #[error("cannot load the map: {0}")]
    Map(#[from] cpmx_world::MapError),
    /// A map file that does not load; the error's location is a line of that file.
    #[error("cannot load the map {}: {source}", path.display())]
    MapFile {
        path: std::path::PathBuf,
        source: cpmx_world::MapError,
    },
    #[error("cannot build the map's reference paths: {0}")]
    Paths(cpmx_world::PathError),
    #[error("reference path {id}: {source}")]
    RefPath { id: u64, source: cpmx_world::PathError },
    #[error("policy `{policy}`: {source}")]
    Actor {
        policy: String,
        source: cpmx_policy::ActorError,
    },
    #[error("policy `{policy}`: {source}")]
    Onnx {
        policy: String,
        source: crate::onnx::OnnxLoadError,
    },
    #[error(
        "policy `{policy}`: its SigmaRL checkpoint was not found (run `cpmx validate` for where it was looked for)"
    )]
    Checkpoint { policy: String },
    #[error("policy `{policy}`: {reason}")]
    Priority { policy: String, reason: String },
    #[error("initial configuration `{name}`: {reason}")]
    Start { name: String, reason: String },
    /// A safety layer's margin network that does not load (the reason names the file).
    #[error("the safety layer's margin network: {0}")]
    MarginPredictor(String),
    #[error(
        "policy `{policy}` names the actor trained with seed {seed}, which was not found: run `cpmx train` first"
    )]
    NotTrained { policy: String, seed: u64 },
}

/// Everything a run needs that does not depend on the run.
#[derive(Debug, Clone)]
pub struct Experiment {
    /// The spec with the run matrix's fidelities (one per point of a sweep).
    pub spec: Spec,
    /// The spec's `map`: where configurations without their own map run, and training.
    pub map: Arc<Map>,
    /// The maps of the configurations that name their own, by configuration name.
    pub configuration_maps: BTreeMap<String, Arc<Map>>,
    /// The vehicle the runs simulate and the policies observe.
    pub vehicle: VehicleParams,
    /// The vehicle whose footprint the metrics score (`metrics.footprint`, else `vehicle`).
    pub footprint: VehicleParams,
    pub metrics: MetricsConfig,
    /// The metrics of the points of a metric parameter's sweep, by matrix fidelity.
    pub metrics_by_fidelity: BTreeMap<String, MetricsConfig>,
    pub policies: Vec<(String, PreparedPolicy)>,
    /// Initial states by configuration name, in matrix order.
    pub starts: Vec<(String, ConfigurationStarts)>,
    /// The margin networks the safety layers name, loaded, by the name the spec gives them.
    pub margin_predictors: BTreeMap<String, Arc<cpmx_safety::MarginPredictor>>,
}

/// What scoring recorded runs needs: the spec, its map, vehicle and metric parameters. No
/// network, no start: `cpmx report` and `cpmx evaluate` need only the map.
#[derive(Debug, Clone)]
pub struct Scoring {
    pub spec: Spec,
    /// The spec's `map`.
    pub map: Arc<Map>,
    /// The maps of the configurations that name their own, by configuration name.
    pub configuration_maps: BTreeMap<String, Arc<Map>>,
    /// The vehicle the runs simulated.
    pub vehicle: VehicleParams,
    /// The vehicle whose footprint the metrics score (`metrics.footprint`, else `vehicle`).
    pub footprint: VehicleParams,
    pub metrics: MetricsConfig,
    /// The metrics of the points of a metric parameter's sweep, by matrix fidelity.
    pub metrics_by_fidelity: BTreeMap<String, MetricsConfig>,
}

/// The metric parameters of every point of a metric's sweep, by matrix fidelity.
fn swept_metrics(checked: &CheckedSpec) -> BTreeMap<String, MetricsConfig> {
    checked
        .fidelity_points
        .iter()
        .filter_map(|(name, point)| {
            let metrics = point.metrics.as_ref()?;
            Some((name.clone(), metrics_config(metrics, &checked.spec.timing)))
        })
        .collect()
}

impl Scoring {
    /// Loads the spec's map.
    pub fn prepare(checked: &CheckedSpec) -> Result<Scoring, PrepareError> {
        let spec = &checked.spec;
        Ok(Scoring {
            spec: spec.clone(),
            map: Arc::new(load_map(spec, checked.resources.map_file.as_deref())?),
            configuration_maps: load_configuration_maps(spec, &checked.configurations, &checked.resources)?,
            vehicle: vehicle_params(&spec.vehicle),
            footprint: footprint_params(spec),
            metrics: metrics_config(&spec.metrics, &spec.timing),
            metrics_by_fidelity: swept_metrics(checked),
        })
    }

    /// The map the runs of `configuration` drive on.
    pub fn map_of(&self, configuration: &str) -> &Arc<Map> {
        self.configuration_maps.get(configuration).unwrap_or(&self.map)
    }

    /// The distinct maps the runs drive on: the spec's first, then the configurations' own in
    /// the order of their names.
    pub fn maps(&self) -> Vec<&Arc<Map>> {
        let mut maps = vec![&self.map];
        for map in self.configuration_maps.values() {
            if !maps.iter().any(|known| Arc::ptr_eq(known, map)) {
                maps.push(map);
            }
        }
        maps
    }

    /// The index in [`Scoring::maps`] of the map the runs of `configuration` drive on.
    pub fn map_index(&self, configuration: &str) -> usize {
        let map = self.map_of(configuration);
        self.maps()
            .iter()
            .position(|known| Arc::ptr_eq(known, map))
            .unwrap_or(0)
    }

    /// Whether some configurations drive on another map than the spec's.
    pub fn has_several_maps(&self) -> bool {
        !self.configuration_maps.is_empty()
    }

    /// The metrics of one recording of `configuration` with the spec's metric parameters.
    pub fn measure(
        &self,
        configuration: &str,
        recording: &cpmx_recording::Recording,
    ) -> Result<cpmx_metrics::RunMetrics, String> {
        let map = self.map_of(configuration);
        crate::runner::measure_recording(map, &self.footprint, &self.metrics, recording)
    }

    /// The metrics of a planned run's recording (its matrix fidelity's metric parameters, its
    /// configuration's map).
    pub fn measure_in(
        &self,
        plan: &cpmx_spec::RunPlan,
        recording: &cpmx_recording::Recording,
    ) -> Result<cpmx_metrics::RunMetrics, String> {
        let metrics = self
            .metrics_by_fidelity
            .get(&plan.fidelity)
            .unwrap_or(&self.metrics);
        let map = self.map_of(&plan.initial_configuration);
        crate::runner::measure_recording(map, &self.footprint, metrics, recording)
    }
}

impl Experiment {
    /// The part of the experiment that scores its recordings.
    pub fn scoring(&self) -> Scoring {
        Scoring {
            spec: self.spec.clone(),
            map: self.map.clone(),
            configuration_maps: self.configuration_maps.clone(),
            vehicle: self.vehicle,
            footprint: self.footprint,
            metrics: self.metrics,
            metrics_by_fidelity: self.metrics_by_fidelity.clone(),
        }
    }

    /// Loads the map and the networks and places every initial configuration.
    pub fn prepare(checked: &CheckedSpec) -> Result<Experiment, PrepareError> {
        let run_spec = checked.run_spec();
        let spec = &run_spec;
        let map = Arc::new(load_map(spec, checked.resources.map_file.as_deref())?);
        let vehicle = vehicle_params(&spec.vehicle);
        let mut policies = Vec::new();
        for (i, (policy, weights)) in spec.policies.iter().zip(&checked.resources.weights).enumerate() {
            let priority = checked.resources.priorities.get(i).and_then(Option::as_deref);
            let mut prepared = match prepare_policy(policy, weights.as_deref(), priority) {
                Err(PrepareError::NotTrained { seed, .. }) => PreparedPolicy::NotTrained { seed },
                other => other?,
            };
            if let PreparedPolicy::Process { dir, .. } = &mut prepared {
                dir.clone_from(&checked.resources.spec_dir);
            }
            policies.push((policy.name.clone(), prepared));
        }
        let configuration_maps = load_configuration_maps(spec, &checked.configurations, &checked.resources)?;
        let starts = initial_states(
            spec,
            &checked.configurations,
            &checked.resources,
            (&map, &configuration_maps),
            &vehicle,
        )?;
        Ok(Experiment {
            spec: spec.clone(),
            map,
            configuration_maps,
            vehicle,
            footprint: footprint_params(spec),
            metrics: metrics_config(&spec.metrics, &spec.timing),
            metrics_by_fidelity: swept_metrics(checked),
            policies,
            starts,
            margin_predictors: load_margin_predictors(&checked.resources)?,
        })
    }

    /// Binds the decider of the `python: {}` policy called `name`; an error names the
    /// policies that can be bound when `name` is none of them.
    pub fn bind(&mut self, name: &str, decider: Arc<dyn cpmx_policy::Decider>) -> Result<(), String> {
        let bindable = |experiment: &Experiment| -> Vec<String> {
            experiment
                .policies
                .iter()
                .filter(|(_, p)| matches!(p, PreparedPolicy::External { .. }))
                .map(|(n, _)| format!("`{n}`"))
                .collect()
        };
        let names = bindable(self);
        match self.policies.iter_mut().find(|(n, _)| n == name) {
            Some((_, PreparedPolicy::External { decider: slot, .. })) => {
                *slot = Some(decider);
                Ok(())
            }
            Some(_) => Err(format!(
                "policy `{name}` is not bound from Python (only `python: {{}}` policies are){}",
                if names.is_empty() {
                    String::new()
                } else {
                    format!("; these are: {}", names.join(", "))
                }
            )),
            None => Err(format!(
                "the spec has no policy `{name}`{}",
                if names.is_empty() {
                    "; it has no `python: {}` policy to bind".to_owned()
                } else {
                    format!("; its `python: {{}}` policies are {}", names.join(", "))
                }
            )),
        }
    }

    /// The `python: {}` policies nothing has been bound to yet.
    pub fn unbound(&self) -> Vec<&str> {
        self.policies
            .iter()
            .filter(|(_, p)| matches!(p, PreparedPolicy::External { decider: None, .. }))
            .map(|(n, _)| n.as_str())
            .collect()
    }

    /// The `mlp: {trained}` policies whose actors are not there yet, with their seeds.
    pub fn not_trained(&self) -> Vec<(&str, u64)> {
        self.policies
            .iter()
            .filter_map(|(n, p)| match p {
                PreparedPolicy::NotTrained { seed } => Some((n.as_str(), *seed)),
                _ => None,
            })
            .collect()
    }

    pub fn policy(&self, name: &str) -> Option<&PreparedPolicy> {
        self.policies.iter().find(|(n, _)| n == name).map(|(_, p)| p)
    }

    /// Where a planned run starts.
    pub fn start(&self, plan: &cpmx_spec::RunPlan) -> Option<&[InitialState]> {
        start_of(&self.starts, plan)
    }

    /// The map the runs of `configuration` drive on.
    pub fn map_of(&self, configuration: &str) -> &Arc<Map> {
        self.configuration_maps.get(configuration).unwrap_or(&self.map)
    }
}

/// The maps of the configurations whose entry names its own `map`, by configuration name
/// (each entry's map loaded once and shared by its configurations).
pub fn load_configuration_maps(
    spec: &Spec,
    configurations: &[cpmx_spec::matrix::NamedConfiguration],
    resources: &cpmx_spec::Resources,
) -> Result<BTreeMap<String, Arc<Map>>, PrepareError> {
    let mut by_entry: BTreeMap<usize, Arc<Map>> = BTreeMap::new();
    let mut out = BTreeMap::new();
    for configuration in configurations {
        let entry = configuration.source.entry();
        let Some(own) = spec.initial_configurations.get(entry).and_then(|c| c.own_map()) else {
            continue;
        };
        let map = match by_entry.get(&entry) {
            Some(map) => map.clone(),
            None => {
                let file = resources
                    .configuration_map_files
                    .get(entry)
                    .and_then(Option::as_deref);
                let map = Arc::new(load_map_spec(own, file)?);
                by_entry.insert(entry, map.clone());
                map
            }
        };
        out.insert(configuration.name.clone(), map);
    }
    Ok(out)
}

/// The spec's map: built-in or from its file, restricted to a region, with the spec's own paths.
pub fn load_map(spec: &Spec, map_file: Option<&Path>) -> Result<Map, PrepareError> {
    load_map_spec(&spec.map, map_file)
}

/// A spec's `map:` value as a map (`map_file`: where the data path found its file).
pub fn load_map_spec(map: &MapSpec, map_file: Option<&Path>) -> Result<Map, PrepareError> {
    match map {
        MapSpec::Builtin(name) => Ok(Map::builtin(name.trim_start_matches(cpmx_spec::STDLIB_PREFIX))?),
        MapSpec::File(file) => {
            let path = map_file.unwrap_or(Path::new(&file.file));
            let format = match file.format {
                None => cpmx_world::MapFormat::Auto,
                Some(cpmx_spec::model::MapFormat::Commonroad) => cpmx_world::MapFormat::CommonRoad,
                Some(cpmx_spec::model::MapFormat::Lanelet2) => cpmx_world::MapFormat::Lanelet2Osm,
            };
            let map_error = |source| PrepareError::MapFile {
                path: path.to_owned(),
                source,
            };
            let text = std::fs::read_to_string(path).map_err(|source| {
                map_error(cpmx_world::MapError::Io {
                    path: path.to_owned(),
                    source,
                })
            })?;
            let mut map = MAPS
                .get_or_parse((format, text), |(format, text)| Map::from_str(text, *format))
                .map_err(map_error)?;
            if let Some(region) = &file.region {
                map = map.with_region(region)?;
            }
            if file.tag == Some(cpmx_spec::model::SigmarlTag::V1_2_0) {
                map = map
                    .with_shared_join(cpmx_world::SharedJoin::LikeOwn)
                    .map_err(PrepareError::Paths)?;
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
        MapSpec::Sigmarl(scenario) => {
            let table_path = map_file.unwrap_or(Path::new(scenario.table_file()));
            let read = |path: &Path| {
                std::fs::read_to_string(path).map_err(|source| PrepareError::MapFile {
                    path: path.to_owned(),
                    source: cpmx_world::MapError::Io {
                        path: path.to_owned(),
                        source,
                    },
                })
            };
            let table = cpmx_world::ScenarioTable::parse(&read(table_path)?).map_err(|source| {
                PrepareError::MapFile {
                    path: table_path.to_owned(),
                    source,
                }
            })?;
            let Some(entry) = table
                .scenarios
                .get(&scenario.sigmarl)
                .filter(|e| e.map_path.ends_with(".osm"))
            else {
                let known: Vec<&str> = table.osm_scenarios().map(|(name, _)| name).collect();
                return Err(PrepareError::Map(cpmx_world::MapError::UnknownScenario {
                    name: scenario.sigmarl.clone(),
                    known: known.join(", "),
                }));
            };
            let path = table_path
                .parent()
                .unwrap_or(Path::new("."))
                .join(&entry.map_path);
            let text = read(&path)?;
            let lane_width_m = scenario.lane_width_m.unwrap_or(entry.lane_width);
            Map::from_sigmarl_osm(&text, entry, lane_width_m)
                .map_err(|source| PrepareError::MapFile { path, source })
        }
    }
}

/// The maps parsed in this process, by format and text.
static MAPS: Memo<(cpmx_world::MapFormat, String), Map> = Memo::new();

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

/// The vehicle whose footprint the spec's metrics score: `metrics.footprint`, else `vehicle`.
pub fn footprint_params(spec: &Spec) -> VehicleParams {
    vehicle_params(spec.metrics.footprint.as_ref().unwrap_or(&spec.vehicle))
}

/// The margin networks the spec's safety layers name (`safety.cbf.agents.predictor`), loaded
/// from `torch.save`'s files as SigmaRL saves them (the state dict under `model_state_dict`,
/// the error bound a NumPy scalar under `error_upper_bound`), by the name the spec gives them.
pub fn load_margin_predictors(
    resources: &cpmx_spec::Resources,
) -> Result<BTreeMap<String, Arc<cpmx_safety::MarginPredictor>>, PrepareError> {
    resources
        .margin_predictors
        .iter()
        .map(|(name, path)| {
            let failed = PrepareError::MarginPredictor;
            let tensors = cpmx_policy::torch::read_state_dict_under(path, "model_state_dict")
                .map_err(|e| failed(e.to_string()))?;
            let bound = cpmx_policy::torch::read_float32_scalar(path, "error_upper_bound")
                .map_err(|e| failed(e.to_string()))?;
            let layers: Vec<(String, Vec<usize>, Vec<f32>)> =
                tensors.into_iter().map(|t| (t.name, t.shape, t.values)).collect();
            let predictor = cpmx_safety::MarginPredictor::new(&layers, f64::from(bound))
                .map_err(|e| failed(format!("{}: {e}", path.display())))?;
            Ok((name.clone(), Arc::new(predictor)))
        })
        .collect()
}

/// The spec's metric parameters as the metrics crate's.
pub fn metrics_config(m: &MetricsSpec, timing: &cpmx_spec::model::Timing) -> MetricsConfig {
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
        boundaries: match c.boundaries {
            None | Some(CraLBoundaries::OwnLane) => LaneBoundaries::OwnLane,
            Some(CraLBoundaries::Road) => LaneBoundaries::Road,
        },
    });
    MetricsConfig {
        sample_period_s: m.sample_period_s,
        cra_a,
        cra_l,
        max_steps: None,
        rotate180: None,
        end_at_path_end: timing.stop_at_path_end == cpmx_spec::model::StopAtPathEnd::EndAgent,
        per_sample_collisions: m.per_sample_collisions.is_some(),
    }
}

//! From a checked spec's `training:` section to what a training run needs: the environment
//! configuration and the reference paths agents are placed on (`cpmx-env`), the learner's
//! hyperparameters (`cpmx-learn`), the seeds, and a fingerprint of everything that shapes the
//! weights, so that `--resume` never continues a run with changed inputs.

use std::collections::BTreeMap;

use cpmx_env::{EnvConfig, Plant, StackPlant, config_from_training, training_paths};
use cpmx_learn::Hyperparameters;
use cpmx_spec::CheckedSpec;
use cpmx_spec::model::{
    Activation, Control, DynamicsLayer, Fidelity, KinematicKeyword, Lookahead, TrainingSpec, ValueLoss,
};
use cpmx_world::ReferencePath;
use sha2::{Digest, Sha256};

/// Why a spec cannot be trained.
#[derive(Debug, thiserror::Error)]
pub enum SetupError {
    /// The spec has no `training:` section.
    #[error("the spec has no `training:` section")]
    NoTraining,
    /// The map did not load (or the scenario's path set is not one of its sets).
    #[error(transparent)]
    Map(#[from] cpmx_engine::PrepareError),
    /// The scenario selects no reference path.
    #[error("the training scenario places agents on no reference path ({0})")]
    NoPaths(String),
    /// The fidelity to train in is one the trainer cannot step yet.
    #[error("cannot train in fidelity `{name}`: {reason}")]
    Fidelity { name: String, reason: String },
    /// A choice of the section the learner does not implement.
    #[error("{0}")]
    Unsupported(String),
    /// The environment or the hyperparameters do not fit together.
    #[error("{0}")]
    Invalid(String),
    /// `initial_actor` names a file that is not there or not an actor.
    #[error("`initial_actor: {file}`: {reason}")]
    InitialActor { file: String, reason: String },
}

/// Everything a training run of one spec needs, for any of its seeds.
#[derive(Debug, Clone)]
pub struct TrainingSetup {
    /// The spec's name (the default output folder is `out/<name>-train`).
    pub spec_name: String,
    /// The environments' configuration.
    pub env: EnvConfig,
    /// The reference paths agents are placed on.
    pub paths: Vec<ReferencePath>,
    /// The learner's hyperparameters (`n_iters` = the section's `iterations`).
    pub hyperparameters: Hyperparameters,
    /// The seeds, in the spec's order.
    pub seeds: Vec<u64>,
    /// What shapes each seed's weights ([`TrainingSetup::fingerprint`]).
    fingerprints: Fingerprints,
    /// The resolved `training:` section (presets expanded), as JSON.
    pub resolved: serde_json::Value,
    /// The actor each seed starts from (`initial_actor`), read, by seed; empty for a random
    /// start.
    pub initial_actors: BTreeMap<u64, cpmx_learn::Mlp>,
    /// The iterations whose actors a seed's folder keeps in `actors/` (`keep_actors_every`).
    pub kept_actors: cpmx_spec::model::KeptActors,
}

/// The fingerprints of a training's seeds: one for every seed, unless each seed starts from
/// its own actor (`initial_actor` with `{seed}`).
#[derive(Debug, Clone)]
enum Fingerprints {
    /// The same inputs for every seed, listed or not.
    Shared(String),
    /// By seed: only the listed seeds have one.
    PerSeed(BTreeMap<u64, String>),
}

impl TrainingSetup {
    /// SHA-256 (hex) of what shapes the weights of `seed`: the resolved `training:` section,
    /// the vehicle, `timing.dt`, the map's content and the content of the actor the seed
    /// starts from. None for a seed the spec does not list when each seed starts from its
    /// own actor.
    pub fn fingerprint(&self, seed: u64) -> Option<&str> {
        match &self.fingerprints {
            Fingerprints::Shared(f) => Some(f),
            Fingerprints::PerSeed(by_seed) => by_seed.get(&seed).map(String::as_str),
        }
    }

    /// Names of the fidelity parameters drawn per episode (the learning curve's `drawn_`
    /// columns); none unless the fidelity to train in is randomised.
    pub fn randomised_parameters(&self) -> Vec<String> {
        match &self.env.plant {
            Plant::Direct => Vec::new(),
            Plant::Stack(plant) => plant.randomised_parameters(),
        }
    }

    /// The fidelities the spec trains in (`training.fidelity`), in order.
    pub fn fidelities(checked: &CheckedSpec) -> Result<Vec<String>, SetupError> {
        let training = checked.spec.training.as_ref().ok_or(SetupError::NoTraining)?;
        Ok(training.fidelity.names().to_vec())
    }

    /// Reads the spec's training section for training in `fidelity` (one of
    /// [`TrainingSetup::fidelities`]) and loads its map.
    pub fn prepare(checked: &CheckedSpec, fidelity: &str) -> Result<TrainingSetup, SetupError> {
        Self::prepare_at(checked, fidelity, "")
    }

    /// [`TrainingSetup::prepare`] at the point `point` of the section's sweeps (`lr=0.001`;
    /// `""` without sweeps: the section as written).
    pub fn prepare_at(
        checked: &CheckedSpec,
        fidelity: &str,
        point: &str,
    ) -> Result<TrainingSetup, SetupError> {
        let spec = &checked.spec;
        spec.training.as_ref().ok_or(SetupError::NoTraining)?;
        let at = match checked.training_points.iter().find(|p| p.name == point) {
            Some(at) => at,
            None if point.is_empty() => checked.training_points.first().ok_or(SetupError::NoTraining)?,
            None => {
                let names: Vec<&str> = checked.training_points.iter().map(|p| p.name.as_str()).collect();
                return Err(SetupError::Invalid(format!(
                    "the training section has no point `{point}` (its points: {})",
                    names.join(", ")
                )));
            }
        };
        let training = &at.training;
        let plant = plant_of(checked, fidelity, training.lookahead)?;
        check_learner_choices(training)?;
        let map = cpmx_engine::load_map(spec, checked.resources.map_file.as_deref())?;
        let paths = training_paths(&map, training).map_err(cpmx_engine::PrepareError::Map)?;
        if paths.is_empty() {
            return Err(SetupError::NoPaths(describe_paths(training)));
        }
        if let Some(ids) = &training.scenario.ref_paths
            && training.scenario.path_set.is_none()
            && training.scenario.region.is_none()
            && paths.len() != ids.len()
        {
            let known: Vec<u32> = ids
                .iter()
                .copied()
                .filter(|&id| map.reference_path(id as usize).is_some())
                .collect();
            let missing: Vec<String> = ids
                .iter()
                .filter(|id| !known.contains(id))
                .map(u32::to_string)
                .collect();
            return Err(SetupError::NoPaths(format!(
                "the map has no reference path {}",
                missing.join(", ")
            )));
        }
        let vehicle = cpmx_engine::vehicle_params(&spec.vehicle);
        let observation = cpmx_engine::observation(&training.observation);
        let mut env = config_from_training(training, observation, vehicle, spec.timing.dt, plant);
        if let Some(Fidelity::Simulated(f)) = spec.fidelities.get(fidelity) {
            env.neighbours = cpmx_env::NeighbourLayers {
                communication: f.communication.clone(),
                perception: f.perception.clone(),
            };
            // The filter as `cpmx run` applies it in this fidelity (the same parameters,
            // lanes and circles).
            if let Some(layer) = &f.safety {
                let predictors = cpmx_engine::load_margin_predictors(&checked.resources)?;
                let predictor = layer
                    .cbf
                    .agents
                    .as_ref()
                    .and_then(|a| a.predictor.as_ref())
                    .and_then(|name| predictors.get(name).cloned());
                env.safety = Some(cpmx_safety::layer::parameters(
                    layer,
                    &vehicle,
                    &cpmx_engine::footprint_params(spec),
                    spec.timing.dt,
                    predictor,
                ));
            }
        }
        env.check().map_err(|e| SetupError::Invalid(e.to_string()))?;
        let hyperparameters = hyperparameters(training, &vehicle);
        // The section as it trains this fidelity: the same as a spec that names it alone.
        let mut resolved = at.resolved.clone();
        if let Some(object) = resolved.as_object_mut() {
            object.insert("fidelity".to_owned(), serde_json::Value::from(fidelity));
        }
        let mut initial_actors = BTreeMap::new();
        let fingerprints = if training.initial_actor.is_none() {
            Fingerprints::Shared(fingerprint(checked, &resolved, &env.plant, None)?)
        } else {
            let mut by_seed = BTreeMap::new();
            for &seed in &training.seeds {
                let (actor, bytes) = read_initial_actor(checked, training, seed)?;
                by_seed.insert(seed, fingerprint(checked, &resolved, &env.plant, Some(&bytes))?);
                initial_actors.insert(seed, actor);
            }
            match training.initial_actor.as_deref() {
                Some(file) if !file.contains("{seed}") => {
                    Fingerprints::Shared(by_seed.into_values().next().unwrap_or_default())
                }
                _ => Fingerprints::PerSeed(by_seed),
            }
        };
        Ok(TrainingSetup {
            spec_name: spec.name.clone(),
            env,
            paths,
            hyperparameters,
            seeds: training.seeds.clone(),
            fingerprints,
            resolved,
            initial_actors,
            kept_actors: training.kept_actors(),
        })
    }
}

/// The learner's hyperparameters a training section declares; the action range is the
/// vehicle's (SigmaRL: speed ±1 m/s, steering ±31°).
fn hyperparameters(training: &TrainingSpec, vehicle: &cpmx_vehicle::VehicleParams) -> Hyperparameters {
    let m = &training.algorithm.mappo;
    let hidden: Vec<usize> = training.network.hidden.iter().map(|&w| w as usize).collect();
    Hyperparameters {
        n_iters: u64::from(training.iterations),
        frames_per_batch: m.frames_per_iteration as usize,
        num_epochs: m.epochs as usize,
        minibatch_size: m.minibatch as usize,
        lr: m.lr,
        lr_min: m.lr_min,
        max_grad_norm: m.max_grad_norm,
        clip_epsilon: m.clip,
        gamma: m.gamma,
        lmbda: m.lambda,
        entropy_eps: m.entropy,
        critic_warmup_iterations: u64::from(m.critic_warmup_iterations),
        max_scale: m.max_scale.map_or(f32::INFINITY, |bound| bound as f32),
        actor_hidden: hidden.clone(),
        critic_hidden: hidden,
        action_high: [vehicle.max_speed_mps as f32, vehicle.max_steering_rad as f32],
        ..Hyperparameters::sigmarl(u64::from(training.iterations))
    }
}

/// The plant of the fidelity to train in (its `safety:` filter, if any, goes into the
/// environment's configuration): SigmaRL's simulation for `control: direct` (the
/// kinematic bicycle with exact states: the spec's checks refuse other layers with it), the
/// lab's control architecture with the fidelity's layers and the spec's planner (and the
/// section's `lookahead`) for `control: trajectory`; a lab driver is refused.
fn plant_of(checked: &CheckedSpec, name: &str, lookahead: Lookahead) -> Result<Plant, SetupError> {
    let refuse = |reason: &str| {
        Err(SetupError::Fidelity {
            name: name.to_owned(),
            reason: reason.to_owned(),
        })
    };
    match checked.spec.fidelities.get(name) {
        None => refuse("the spec defines no such fidelity"),
        Some(Fidelity::Lab(_)) => refuse("it drives the lab; policies train in simulation only"),
        Some(Fidelity::Simulated(f))
            if matches!(
                f.dynamics,
                DynamicsLayer::Kinematic(KinematicKeyword::KinematicRk4 | KinematicKeyword::KinematicVmas)
            ) =>
        {
            refuse(
                "it integrates with `kinematic-rk4` or `kinematic-vmas`, and training environments step SigmaRL's \
             single Euler step only: train in a fidelity with `dynamics: kinematic`",
            )
        }
        Some(Fidelity::Simulated(f)) if f.control == Control::Trajectory => {
            let Some(planner) = &checked.spec.planner else {
                return refuse(
                    "it plans trajectories (`control: trajectory`), and the spec has no `planner`",
                );
            };
            Ok(Plant::Stack(Box::new(StackPlant {
                fidelity: f.clone(),
                planner: cpmx_engine::planner(
                    planner,
                    checked.spec.timing.dt,
                    cpmx_engine::vehicle_params(&checked.spec.vehicle),
                )
                .params()
                .to_owned(),
                lookahead,
            })))
        }
        // The spec's checks refuse `control: direct` with any layer but the kinematic bicycle.
        Some(Fidelity::Simulated(_)) => Ok(Plant::Direct),
    }
}

/// The learner trains tanh networks with SigmaRL's smooth-L1 value loss.
fn check_learner_choices(training: &TrainingSpec) -> Result<(), SetupError> {
    if training.network.activation != Activation::Tanh {
        return Err(SetupError::Unsupported(
            "`training.network.activation: relu`: the learner trains tanh networks (SigmaRL's) so far".into(),
        ));
    }
    if training.algorithm.mappo.value_loss != ValueLoss::SmoothL1 {
        return Err(SetupError::Unsupported(
            "`value_loss: mse`: the learner implements SigmaRL's smooth-l1 value loss so far".into(),
        ));
    }
    Ok(())
}

fn describe_paths(training: &TrainingSpec) -> String {
    let s = &training.scenario;
    match (&s.path_set, &s.region, &s.ref_paths) {
        (Some(set), _, _) => format!("path set {set:?}"),
        (None, Some(region), _) => format!("no reference path runs through region `{region}`"),
        (None, None, Some(ids)) if ids.is_empty() => "`ref_paths` is empty".into(),
        (None, None, _) => "the map has no reference paths".into(),
    }
}

/// The actor `seed` starts from (`initial_actor` with `{seed}` replaced) and its bytes.
fn read_initial_actor(
    checked: &CheckedSpec,
    training: &TrainingSpec,
    seed: u64,
) -> Result<(cpmx_learn::Mlp, Vec<u8>), SetupError> {
    let file = training.initial_actor_of(seed).unwrap_or_default();
    let path = checked.resources.initial_actors.get(&seed).cloned();
    let fail = |reason: String| SetupError::InitialActor {
        file: file.clone(),
        reason,
    };
    let path = path.ok_or_else(|| {
        fail("not found next to the spec or on the data path (`cpmx validate` says where it looked)".into())
    })?;
    let bytes = std::fs::read(&path).map_err(|e| fail(format!("{}: {e}", path.display())))?;
    let actor = cpmx_learn::Mlp::from_safetensors(&bytes, "actor").map_err(|e| fail(e.to_string()))?;
    Ok((actor, bytes))
}

/// SHA-256 over the resolved training section, vehicle, dt, the map file's bytes and the
/// bytes of the actor the training starts from (not its path: where it lies does not matter).
fn fingerprint(
    checked: &CheckedSpec,
    training: &serde_json::Value,
    plant: &Plant,
    initial_actor: Option<&[u8]>,
) -> Result<String, SetupError> {
    let mut hasher = Sha256::new();
    hasher.update(b"cpmx/training/v2\0");
    // A seed's run does not depend on which other seeds the spec lists: seeds may be added
    // (or dropped) without refusing the folders already trained.
    let mut training = training.clone();
    if let Some(object) = training.as_object_mut() {
        object.remove("seeds");
        // Which actors the folder keeps besides the best and the last does not shape them.
        object.shift_remove("keep_actors_every");
        // Only the planner has a lookahead (SigmaRL's simulation trains alike with either),
        // and the default, written or not, is what actors trained before the key existed had.
        // (`shift_remove`: the order of the other keys stays as written.)
        if matches!(plant, Plant::Direct) || object.get("lookahead").is_some_and(|v| v == "actor") {
            object.shift_remove("lookahead");
        }
    }
    let path_of_initial_actor = training
        .as_object_mut()
        .and_then(|o| o.shift_remove("initial_actor"));
    hasher.update(training.to_string().as_bytes());
    // The actor started from, by content (written only when given: the fingerprints of
    // trainings from a random start stay as they were).
    if let (Some(_), Some(bytes)) = (path_of_initial_actor, initial_actor) {
        hasher.update(b"\0initial_actor\0");
        hasher.update(bytes);
    }
    // The map by content: where its file lies and how it is pinned do not matter.
    let mut map = checked.resolved.get("map").cloned().unwrap_or_default();
    if let Some(object) = map.as_object_mut() {
        object.remove("file");
        object.remove("sha256");
    }
    let vehicle = checked.resolved.get("vehicle").cloned().unwrap_or_default();
    for value in [vehicle, map] {
        hasher.update([0u8]);
        hasher.update(value.to_string().as_bytes());
    }
    hasher.update([0u8]);
    hasher.update(checked.spec.timing.dt.to_bits().to_le_bytes());
    // The vehicles' stack: the fidelity's layers and the planner (SigmaRL's simulation has no
    // parameters beyond the vehicle and `dt`).
    if matches!(plant, Plant::Stack(_)) {
        let name = training
            .get("fidelity")
            .and_then(|v| v.as_str())
            .unwrap_or_default();
        let resolved = &checked.resolved;
        let fidelity = resolved.get("fidelities").and_then(|f| f.get(name)).cloned();
        for value in [
            fidelity.unwrap_or_default(),
            resolved.get("planner").cloned().unwrap_or_default(),
        ] {
            hasher.update([1u8]);
            hasher.update(value.to_string().as_bytes());
        }
    }
    // SigmaRL's simulation with a communication or perception layer: those layers (written
    // only when given, so that fingerprints of actors trained without them stay as they were).
    if matches!(plant, Plant::Direct) {
        let name = training
            .get("fidelity")
            .and_then(|v| v.as_str())
            .unwrap_or_default();
        let fidelity = checked.resolved.get("fidelities").and_then(|f| f.get(name));
        for key in ["communication", "perception"] {
            if let Some(layer) = fidelity.and_then(|f| f.get(key)) {
                hasher.update([2u8]);
                hasher.update(key.as_bytes());
                hasher.update(layer.to_string().as_bytes());
            }
        }
    }
    if let Some(file) = &checked.resources.map_file {
        let bytes = std::fs::read(file).map_err(|e| {
            SetupError::Map(cpmx_engine::PrepareError::Map(cpmx_world::MapError::Io {
                path: file.clone(),
                source: e,
            }))
        })?;
        hasher.update(Sha256::digest(&bytes));
    }
    Ok(format!("{:x}", hasher.finalize()))
}

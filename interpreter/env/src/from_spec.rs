//! The bridge from a spec's `training:` section to an [`EnvConfig`] and the path set agents
//! are placed on. The observation design and the vehicle come in already converted (the
//! engine owns those conversions: `cpmx_engine::observation`).

use cpmx_policy::SigmarlObservation;
use cpmx_safety::margins::MarginParameters;
use cpmx_safety::{AgentRows, Arithmetic, CbfParameters};
use cpmx_spec::model::{CbfMarginsSpec, PathSetName, RampShape, ResetScopeName, TrainingSpec};
use cpmx_vehicle::VehicleParams;
use cpmx_world::{Map, MapError, PathSet, ReferencePath};

use crate::config::{
    CbfMarginsTerm, CentreLineTerm, EnvConfig, NearAgentsTerm, NearBoundaryTerm, Plant, ProgressTerm, Ramp,
    ResetRule, ResetScope, RewardConfig, ScenarioConfig, SpeedTerm, StartRule, SteeringChangeTerm, TimeTerm,
    TtcTerm, VelocityToPointsTerm,
};

/// The environment configuration a `training:` section declares, with the plant of its
/// fidelity.
pub fn config_from_training(
    training: &TrainingSpec,
    observation: SigmarlObservation,
    vehicle: VehicleParams,
    dt_s: f64,
    plant: Plant,
) -> EnvConfig {
    let s = &training.scenario;
    let r = &training.reward;
    let ramp = |shape: RampShape| match shape {
        RampShape::Linear => Ramp::Linear,
        RampShape::Exponential => Ramp::Exponential,
    };
    let scope = |n: ResetScopeName| match n {
        ResetScopeName::Environment => ResetScope::Environment,
        ResetScopeName::Agent => ResetScope::Agent,
        ResetScopeName::None => ResetScope::None,
    };
    EnvConfig {
        scenario: ScenarioConfig {
            agents: s.agents as usize,
            envs: s.envs as usize,
            episode_steps: s.episode_steps,
            start: StartRule {
                first_index: s.start.first_index as usize,
                speed_mps: (s.start.speed_mps[0], s.start.speed_mps[1]),
                min_gap_m: s.start.min_gap_m,
                ..StartRule::default()
            },
            reset: ResetRule {
                on_collision: scope(s.reset.on_collision),
                on_entry_or_exit_line: scope(s.reset.on_entry_or_exit_line),
            },
        },
        reward: RewardConfig {
            progress: r.progress.as_ref().map(|p| ProgressTerm {
                weight: p.weight,
                point_weights: p
                    .point_weights
                    .clone()
                    .unwrap_or_else(|| ProgressTerm::sigmarl_weights(p.points as usize)),
                spacing: p.spacing as usize,
            }),
            near_boundary: r.near_boundary.as_ref().map(|b| NearBoundaryTerm {
                penalty: b.penalty,
                within_m: b.within_m,
                shape: ramp(b.shape),
            }),
            near_agents: r.near_agents.as_ref().map(|a| NearAgentsTerm {
                penalty: a.penalty,
                from_m: a.from_m,
                to_m: a.to_m,
                shape: ramp(a.shape),
            }),
            velocity_to_points: r.velocity_to_points.as_ref().map(|v| VelocityToPointsTerm {
                weight: v.weight,
                against_path_factor: v.against_path_factor,
            }),
            time: r.time.as_ref().map(|t| TimeTerm { weight: t.weight }),
            steering_change: r.steering_change.as_ref().map(|c| SteeringChangeTerm {
                penalty: c.penalty,
                threshold_rad: c.threshold_rad,
            }),
            cbf_margins: r
                .cbf_margins
                .as_ref()
                .map(|c| cbf_margins_term(c, &vehicle, dt_s)),
            near_agents_ttc: r.near_agents_ttc.as_ref().map(|t| TtcTerm {
                penalty: t.penalty,
                within_m: t.within_m,
                horizon_s: t.horizon_s,
                safe_distance_m: t.safe_distance_m,
            }),
            speed: r.speed.as_ref().map(|v| SpeedTerm {
                weight: v.weight,
                against_path_factor: v.against_path_factor,
            }),
            centre_line: r.centre_line.as_ref().map(|c| CentreLineTerm {
                penalty: c.penalty,
                scale_m: c.scale_m,
            }),
            collide_agents: r.collide_agents.unwrap_or(0.0),
            collide_boundary: r.collide_boundary.unwrap_or(0.0),
            clamp: r.clamp.map(|[low, high]| (low, high)),
        },
        observation,
        vehicle,
        dt_s,
        plant,
        neighbours: crate::neighbours::NeighbourLayers::default(),
        safety: None,
    }
}

/// The CBF-informed term for `vehicle` stepping every `dt_s`: SigmaRL 1.6.0's rows
/// (`CBFQP.initialize_params`: finite differences of 2 cm, no safety buffer, every pair of
/// agents, its pinned NumPy 1.26's arithmetic) and its conversion of commands (speed from
/// −0.5 m/s, the rates to ±5 m/s² and ±π/2 rad/s: its `AGENTS`).
fn cbf_margins_term(spec: &CbfMarginsSpec, vehicle: &VehicleParams, dt_s: f64) -> CbfMarginsTerm {
    let circles = spec.circles as usize;
    let agents = AgentRows {
        length_m: vehicle.length_m,
        width_m: vehicle.width_m,
        range_m: f64::INFINITY,
        predictor: None,
    };
    let sigmarl = CbfParameters::sigmarl(dt_s);
    CbfMarginsTerm {
        weight: spec.weight,
        threshold: spec.threshold,
        parameters: MarginParameters {
            rows: CbfParameters {
                circles,
                length_m: vehicle.length_m,
                rear_axle_m: vehicle.rear_axle_m,
                wheelbase_m: vehicle.wheelbase_m,
                circle_radius_m: agents.circle_radius_m(circles),
                gain: spec.gain,
                step_s: f64::from(spec.horizon_steps) * dt_s,
                acceleration_limit_mps2: 5.0,
                steering_rate_limit_radps: std::f64::consts::FRAC_PI_2,
                speed_range_mps: [-0.5, vehicle.max_speed_mps as f32],
                max_steering_rad: vehicle.max_steering_rad as f32,
                agents: Some(agents),
                arithmetic: Arithmetic::Numpy1,
                ..sigmarl
            },
            command_step_s: dt_s,
        },
    }
}

/// The reference paths a training scenario places agents on: one of SigmaRL's path sets, the
/// listed ids of `map` (ids the map lacks are left out: the caller compares the count), or
/// the paths of a region.
pub fn training_paths(map: &Map, training: &TrainingSpec) -> Result<Vec<ReferencePath>, MapError> {
    let s = &training.scenario;
    let map = match (s.path_set, &s.region) {
        (Some(set), _) => map.with_path_set(match set {
            PathSetName::Entire => PathSet::Entire,
            PathSetName::Intersection => PathSet::Intersection,
            PathSetName::MergeIn => PathSet::MergeIn,
            PathSetName::MergeOut => PathSet::MergeOut,
        })?,
        (None, Some(region)) => map.with_region(region)?,
        (None, None) => map.clone(),
    };
    match &s.ref_paths {
        Some(ids) if s.path_set.is_none() && s.region.is_none() => Ok(ids
            .iter()
            .filter_map(|&id| map.reference_path(id as usize).cloned())
            .collect()),
        _ => Ok(map.reference_paths().cloned().collect()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn preset(kind: cpmx_stdlib::PresetKind, name: &str) -> serde_json::Value {
        serde_saphyr::from_str(cpmx_stdlib::preset(kind, name).expect("preset").yaml).expect("yaml")
    }

    #[test]
    fn sigmarls_presets_give_the_default_configuration() {
        use cpmx_stdlib::PresetKind as K;
        let training: TrainingSpec = serde_json::from_value(serde_json::json!({
            "scenario": preset(K::TrainingScenario, "sigmarl-intersection"),
            "reward": preset(K::Reward, "sigmarl-reward"),
            "algorithm": preset(K::Algorithm, "mappo-sigmarl"),
            "observation": preset(K::Observation, "sigmarl"),
            "iterations": 1,
            "seeds": [1],
        }))
        .expect("training section");
        let config = config_from_training(
            &training,
            SigmarlObservation::default(),
            VehicleParams::MU_CAR,
            0.1,
            Plant::Direct,
        );
        let default = EnvConfig::default();
        let (got, want) = (&config.scenario, &default.scenario);
        assert_eq!(
            (got.agents, got.envs, got.episode_steps),
            (want.agents, want.envs, want.episode_steps)
        );
        assert_eq!(got.reset, want.reset);
        assert_eq!(
            (got.start.first_index, got.start.speed_mps),
            (want.start.first_index, want.start.speed_mps)
        );
        assert!((got.start.min_gap_m - want.start.min_gap_m).abs() < 1e-9);
        let (got, want) = (config.reward, default.reward);
        let (p, q) = (got.progress.as_ref().unwrap(), want.progress.as_ref().unwrap());
        assert_eq!(
            (p.weight, p.spacing, p.point_weights.len()),
            (q.weight, q.spacing, 3)
        );
        for (a, b) in p.point_weights.iter().zip(&q.point_weights) {
            assert!((a - b).abs() < 1e-12);
        }
        assert_eq!(got.near_boundary, want.near_boundary);
        assert_eq!(got.near_agents_ttc, want.near_agents_ttc);
        assert_eq!(
            (got.collide_agents, got.collide_boundary, got.clamp),
            (want.collide_agents, want.collide_boundary, want.clamp)
        );
    }
}

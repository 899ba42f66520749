//! SigmaRL's checkpoints as the language reads them: which file of a checkpoint folder a policy
//! takes (`pick`), the `*_data.json` SigmaRL saved beside it, and the observation its
//! `parameters` describe. Every parameter that changes what the actor sees is honoured (mapped
//! to a field of [`ObservationSpec`]) or refused with its name and value; parameters that only
//! steer training, saving or drawing are listed as such; a parameter this module does not know
//! is refused, so nothing is silently ignored. The tensors themselves are read by the
//! interpreter (`cpmx-policy`'s `torch` module).

use std::path::{Path, PathBuf};

use serde_json::{Map, Value};

use crate::model::{CheckpointPick, NeighbourActions, ObservationDesign, ObservationSpec, VehicleSpec};

/// The files of one SigmaRL actor.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointFiles {
    /// The actor's state dict (`*_policy.pth`).
    pub policy: PathBuf,
    /// SigmaRL's `SaveData` for the run (`*_data.json`), when there is one.
    pub data: Option<PathBuf>,
}

/// The files of the checkpoint at `path` (a `*_policy.pth`, or a folder from which `pick`
/// takes one).
pub fn locate(path: &Path, pick: Option<CheckpointPick>) -> Result<CheckpointFiles, String> {
    if !path.is_dir() {
        if let Some(pick) = pick {
            return Err(format!(
                "`pick: {}` chooses among the actors of a folder, and {} is a file",
                pick.label(),
                path.display()
            ));
        }
        return Ok(CheckpointFiles {
            data: data_beside(path),
            policy: path.to_owned(),
        });
    }
    let names = file_names(path)?;
    let pick = pick.unwrap_or_default();
    let chosen = match pick {
        CheckpointPick::Final => names.iter().find(|n| *n == "final_policy.pth").cloned(),
        CheckpointPick::Best => names
            .iter()
            .filter_map(|n| Some((best_reward(n)?, n)))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, n)| n.clone()),
    };
    let Some(chosen) = chosen else {
        let policies: Vec<&String> = names.iter().filter(|n| n.ends_with("_policy.pth")).collect();
        let wanted = match pick {
            CheckpointPick::Best => "no `reward<r>_policy.pth` (the actor at the best reward)",
            CheckpointPick::Final => "no `final_policy.pth` (the actor after the last iteration)",
        };
        return Err(if policies.is_empty() {
            format!("{} holds {wanted}, nor any other `*_policy.pth`", path.display())
        } else {
            format!(
                "{} holds {wanted}; it holds {}",
                path.display(),
                policies
                    .iter()
                    .map(|n| format!("`{n}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        });
    };
    let policy = path.join(chosen);
    Ok(CheckpointFiles {
        data: data_beside(&policy),
        policy,
    })
}

/// The priority network of an XP-MARL run at `path`: a `*_priority_policy.pth`, or from a
/// folder `reward<r>_priority_policy.pth` (`best`, the highest `r`) or
/// `final_priority_policy.pth` (`final`).
pub fn locate_priority(path: &Path, pick: CheckpointPick) -> Result<PathBuf, String> {
    if !path.is_dir() {
        return Ok(path.to_owned());
    }
    let names = file_names(path)?;
    let chosen = match pick {
        CheckpointPick::Final => names.iter().find(|n| *n == "final_priority_policy.pth").cloned(),
        CheckpointPick::Best => names
            .iter()
            .filter_map(|n| {
                let r = n.strip_prefix("reward")?.strip_suffix("_priority_policy.pth")?;
                Some((r.parse::<f64>().ok().filter(|r| r.is_finite())?, n))
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, n)| n.clone()),
    };
    chosen.map(|n| path.join(n)).ok_or_else(|| {
        format!(
            "{} holds no {} (SigmaRL saves a priority policy only for `prioritization_method: marl`)",
            path.display(),
            match pick {
                CheckpointPick::Best => "`reward<r>_priority_policy.pth`",
                CheckpointPick::Final => "`final_priority_policy.pth`",
            }
        )
    })
}

/// The names of the files in a folder, sorted.
fn file_names(dir: &Path) -> Result<Vec<String>, String> {
    let entries = std::fs::read_dir(dir).map_err(|e| format!("cannot list {}: {e}", dir.display()))?;
    let mut names: Vec<String> = entries
        .filter_map(Result::ok)
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().into_string().ok())
        .collect();
    names.sort();
    Ok(names)
}

/// `r` of `reward<r>_policy.pth` (not of a priority policy, `reward<r>_priority_policy.pth`).
fn best_reward(name: &str) -> Option<f64> {
    name.strip_prefix("reward")?
        .strip_suffix("_policy.pth")?
        .parse::<f64>()
        .ok()
        .filter(|r| r.is_finite())
}

/// The `*_data.json` of a `<stem>_policy.pth`: `<stem>_data.json` beside it, else the folder's
/// only `*_data.json` stem (SigmaRL saves one per best actor; every one holds the run's
/// parameters), the highest reward's when there are several.
fn data_beside(policy: &Path) -> Option<PathBuf> {
    let dir = policy.parent()?;
    let name = policy.file_name()?.to_str()?;
    let stem = name
        .strip_suffix("_policy.pth")
        .unwrap_or(name.strip_suffix(".pth")?);
    let own = dir.join(format!("{stem}_data.json"));
    if own.is_file() {
        return Some(own);
    }
    let names = file_names(if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    })
    .ok()?;
    names
        .iter()
        .filter(|n| n.ends_with("_data.json"))
        .max_by(|a, b| {
            let reward = |n: &str| {
                n.strip_prefix("reward")
                    .and_then(|r| r.strip_suffix("_data.json")?.parse::<f64>().ok())
            };
            reward(a)
                .unwrap_or(f64::NEG_INFINITY)
                .total_cmp(&reward(b).unwrap_or(f64::NEG_INFINITY))
        })
        .map(|n| dir.join(n))
}

/// The `parameters` object of a `*_data.json`.
pub fn read_parameters(data: &Path) -> Result<Map<String, Value>, String> {
    let text = std::fs::read_to_string(data).map_err(|e| format!("cannot read {}: {e}", data.display()))?;
    let value: Value =
        serde_json::from_str(&text).map_err(|e| format!("{} is not JSON: {e}", data.display()))?;
    match value.get("parameters") {
        Some(Value::Object(parameters)) => Ok(parameters.clone()),
        Some(_) => Err(format!("`parameters` of {} is not an object", data.display())),
        None => Err(format!(
            "{} has no `parameters` (is it SigmaRL's `SaveData`?)",
            data.display()
        )),
    }
}

/// A parameter that keeps the actor from being run as it was trained: its name, its value and
/// why.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub name: String,
    pub value: Value,
    pub reason: String,
}

impl std::fmt::Display for Refusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "`{}: {}`: {}", self.name, self.value, self.reason)
    }
}

/// Parameters whose value cpmx's observation has built in: any other value is refused.
const FIXED: [(&str, bool, &str); 7] = [
    (
        "is_partial_observation",
        true,
        "cpmx observes the nearest agents only, not every agent",
    ),
    (
        "is_use_mtv_distance",
        false,
        "cpmx measures agent distances centre to centre, not by MTV",
    ),
    (
        "is_apply_mask",
        false,
        "cpmx does not mask distant or unrelated agents",
    ),
    (
        "is_observe_distance_to_boundaries",
        true,
        "cpmx observes the distances to the boundaries, not their nearest points",
    ),
    (
        "is_observe_ref_path_other_agents",
        false,
        "cpmx does not observe the other agents' reference paths",
    ),
    (
        "is_obs_noise",
        false,
        "cpmx adds SigmaRL 1.2.0's sensor noise (`is_add_noise`), not the later releases' `is_obs_noise`",
    ),
    (
        "is_using_cbf",
        false,
        "the actor was trained behind SigmaRL's CBF safety filter, which cpmx does not apply",
    ),
];

/// Parameters that do not change what the actor observes or how its output is read: training,
/// saving, drawing, and settings that act only with a refused one (noise levels without noise,
/// communication noise without priorities, the CBF's circles without the CBF). `lane_width`
/// sizes SigmaRL's OSM maps only; on the CPM Lab map the scenario's 0.15 m is used.
const NEUTRAL: [&str; 53] = [
    "n_agents",
    "device",
    "scenario_name",
    "n_iters",
    "num_epochs",
    "minibatch_size",
    "lr",
    "lr_min",
    "max_grad_norm",
    "clip_epsilon",
    "gamma",
    "lmbda",
    "entropy_eps",
    "max_steps",
    "num_vmas_envs",
    "frames_per_batch",
    "total_frames",
    "is_save_intermediate_model",
    "is_load_model",
    "is_load_final_model",
    "episode_reward_mean_current",
    "episode_reward_intermediate",
    "where_to_save",
    "is_continue_train",
    "n_steps_stored",
    "is_testing_mode",
    "is_save_simulation_video",
    "is_visualize_short_term_path",
    "is_visualize_lane_boundary",
    "is_visualize_extra_info",
    "is_save_eval_results",
    "is_load_out_td",
    "is_real_time_rendering",
    "render_title",
    "is_prb",
    "is_challenging_initial_state_buffer",
    "cpm_scenario_probabilities",
    "prioritization_method",
    "is_communication_noise",
    "communication_noise_level",
    "is_using_centralized_cbf",
    "is_using_pseudo_distance",
    "n_circles_approximate_vehicle",
    "experiment_type",
    "random_seed",
    "lane_width",
    "reset_agent_fixed_duration",
    "model_name",
    "obs_noise_level",
    "ref_path_idx",
    "is_visualize_short_term_path_other_agents",
    "dt",
    "scenario_type",
];

/// The scenarios whose lane width SigmaRL takes for the observation's distance normaliser
/// (`SCENARIOS[...]["lane_width"]`, not `parameters.lane_width`), with that width [m].
const SCENARIO_LANE_WIDTHS_M: [(&str, f64); 2] = [("CPM_entire", 0.15), ("CPM_mixed", 0.15)];

/// The observation an actor was trained with, from its checkpoint's `parameters`, for a run of
/// `vehicle` (SigmaRL normalises positions by 10 vehicle lengths and speeds by the maximum
/// speed) at the policy step `dt_s`; or every parameter that cannot be honoured.
pub fn observation(
    parameters: &Map<String, Value>,
    vehicle: &VehicleSpec,
    dt_s: f64,
) -> Result<ObservationSpec, Vec<Refusal>> {
    let mut refusals = Vec::new();
    let mut refuse = |name: &str, value: &Value, reason: String| {
        refusals.push(Refusal {
            name: name.to_owned(),
            value: value.clone(),
            reason,
        })
    };
    for (name, value) in parameters {
        if let Some((_, expected, reason)) = FIXED.iter().find(|(n, _, _)| n == name) {
            if value.as_bool() != Some(*expected) {
                refuse(name, value, (*reason).to_owned());
            }
        } else if !NEUTRAL.contains(&name.as_str()) && !HONOURED.contains(&name.as_str()) {
            refuse(
                name,
                value,
                "a parameter cpmx does not know: whether it changes what the actor observes cannot be told"
                    .to_owned(),
            );
        }
    }
    let count =
        |name: &str, default: u64, max: u64, refuse: &mut dyn FnMut(&str, &Value, String)| match parameters
            .get(name)
        {
            None => Some(default),
            Some(value) => match value.as_u64() {
                Some(n) if n <= max => Some(n),
                _ => {
                    refuse(
                        name,
                        value,
                        format!("cpmx's observation takes a whole number up to {max}"),
                    );
                    None
                }
            },
        };
    let flag = |name: &str, default: bool, refuse: &mut dyn FnMut(&str, &Value, String)| match parameters
        .get(name)
    {
        None => Some(default),
        Some(value) => value.as_bool().or_else(|| {
            refuse(name, value, "not true or false".to_owned());
            None
        }),
    };
    let ref_points = count("n_points_short_term", 3, 32, &mut refuse).filter(|&n| {
        n >= 1 || {
            refuse(
                "n_points_short_term",
                &Value::from(n),
                "cpmx observes at least one reference point".to_owned(),
            );
            false
        }
    });
    let observed_agents = count("n_nearing_agents_observed", 2, 16, &mut refuse);
    let center_line_distance = flag("is_observe_distance_to_center_line", true, &mut refuse);
    let steering = flag("is_obs_steering", false, &mut refuse);
    let neighbour_vertices = flag("is_observe_vertices", true, &mut refuse);
    let neighbour_distance = flag("is_observe_distance_to_agents", true, &mut refuse);
    let noise = flag("is_add_noise", false, &mut refuse);
    let ego_view = flag("is_ego_view", true, &mut refuse);
    let propagated = flag("is_using_prioritized_marl", false, &mut refuse);
    let tentative = flag("is_using_opponent_modeling", false, &mut refuse);
    let neighbour_actions = match (propagated, tentative) {
        (Some(true), Some(true)) => {
            refuse(
                "is_using_opponent_modeling",
                &Value::Bool(true),
                "together with `is_using_prioritized_marl`, which SigmaRL never trained: whose actions fill the \
                 slots cannot be told"
                    .to_owned(),
            );
            None
        }
        (Some(true), Some(false)) => Some(NeighbourActions::Propagated),
        (Some(false), Some(true)) => Some(NeighbourActions::Tentative),
        (Some(false), Some(false)) => Some(NeighbourActions::None),
        _ => None,
    };
    let lane_width_m = match parameters.get("scenario_type") {
        None => Some(0.15),
        Some(value) => {
            let width = value
                .as_str()
                .and_then(|s| SCENARIO_LANE_WIDTHS_M.iter().find(|(n, _)| *n == s))
                .map(|(_, w)| *w);
            if width.is_none() {
                refuse(
                    "scenario_type",
                    value,
                    "cpmx knows the lane width SigmaRL normalises with for the CPM Lab's scenarios \
                     (`CPM_entire`, `CPM_mixed`) only"
                        .to_owned(),
                );
            }
            width
        }
    };
    if let Some(value) = parameters.get("dt")
        && value.as_f64().is_none_or(|dt| (dt - dt_s).abs() > 1e-9)
    {
        refuse(
            "dt",
            value,
            format!("the actor was trained at another step than the spec's `timing.dt: {dt_s}`"),
        );
    }
    if !refusals.is_empty() {
        return Err(refusals);
    }
    match (
        ref_points,
        observed_agents,
        center_line_distance,
        steering,
        lane_width_m,
        neighbour_actions,
        (neighbour_vertices, neighbour_distance, noise, ego_view),
    ) {
        (
            Some(ref_points),
            Some(observed_agents),
            Some(center_line_distance),
            Some(steering),
            Some(lane_width_m),
            Some(neighbour_actions),
            (Some(neighbour_vertices), Some(neighbour_distance), Some(noise), Some(ego_view)),
        ) => {
            Ok(ObservationSpec {
                design: ObservationDesign::Sigmarl,
                observed_agents: observed_agents as u32,
                ref_points: ref_points as u32,
                // SigmaRL's `sample_interval_ref_path`, fixed in its scenario.
                ref_point_stride: 2,
                position_scale_m: 10.0 * vehicle.length,
                speed_scale_mps: vehicle.max_speed,
                distance_scale_m: 3.0 * lane_width_m,
                boundary_distances: true,
                center_line_distance,
                agent0_boundary_lag: true,
                steering,
                neighbour_actions,
                neighbour_vertices,
                neighbour_distance,
                // SigmaRL 1.2.0's sensor noise: U[0, 0.2 × the car's width) on every value.
                uniform_noise: if noise { 0.2 * vehicle.width } else { 0.0 },
                // SigmaRL's world (VMAS's x and y semi-dimensions of its CPM scenarios, which
                // its environment keeps on every map).
                bird_view_scale_m: (!ego_view).then_some([4.5, 4.0]),
            })
        }
        _ => Err(refusals),
    }
}

/// Parameters mapped to a field of the observation.
const HONOURED: [&str; 10] = [
    "is_ego_view",
    "is_observe_vertices",
    "is_observe_distance_to_agents",
    "is_add_noise",
    "n_points_short_term",
    "n_nearing_agents_observed",
    "is_observe_distance_to_center_line",
    "is_obs_steering",
    "is_using_prioritized_marl",
    "is_using_opponent_modeling",
];

#[cfg(test)]
mod tests {
    use super::*;

    fn mu_car() -> VehicleSpec {
        VehicleSpec {
            length: 0.16,
            width: 0.08,
            wheelbase: 0.15,
            rear_axle: 0.075,
            max_steering_deg: 31.0,
            max_steering_rate_deg_s: 900.0,
            accel: [-5.0, 5.0],
            max_speed: 1.0,
        }
    }

    fn parameters(pairs: &[(&str, Value)]) -> Map<String, Value> {
        pairs.iter().map(|(k, v)| ((*k).to_owned(), v.clone())).collect()
    }

    #[test]
    fn the_papers_settings_give_sigmarls_observation_for_the_vehicle() {
        let p = parameters(&[
            ("n_points_short_term", 3.into()),
            ("n_nearing_agents_observed", 2.into()),
            ("is_ego_view", true.into()),
            ("scenario_type", "CPM_mixed".into()),
            ("lane_width", 0.3.into()),
            ("dt", 0.1.into()),
            ("lr", 1e-4.into()),
        ]);
        let o = observation(&p, &mu_car(), 0.1).unwrap();
        assert_eq!((o.ref_points, o.observed_agents, o.ref_point_stride), (3, 2, 2));
        assert_eq!(o.position_scale_m, 1.6);
        assert!((o.distance_scale_m - 0.45).abs() < 1e-12);
        assert!(o.boundary_distances && o.center_line_distance && !o.steering);
    }

    #[test]
    fn every_setting_cpmx_cannot_honour_is_refused_by_name_and_value() {
        let p = parameters(&[
            ("is_observe_distance_to_boundaries", false.into()),
            ("is_obs_noise", true.into()),
            ("is_new_thing", 3.into()),
            ("scenario_type", "intersection_1".into()),
            ("dt", 0.05.into()),
            ("n_points_short_term", 0.into()),
        ]);
        let refusals = observation(&p, &mu_car(), 0.1).unwrap_err();
        let mut names: Vec<&str> = refusals.iter().map(|r| r.name.as_str()).collect();
        names.sort_unstable();
        assert_eq!(
            names,
            [
                "dt",
                "is_new_thing",
                "is_obs_noise",
                "is_observe_distance_to_boundaries",
                "n_points_short_term",
                "scenario_type"
            ]
        );
        assert_eq!(refusals.len(), 6);
        let text: Vec<String> = refusals.iter().map(ToString::to_string).collect();
        assert!(text.iter().any(|t| {
            t.starts_with("`is_observe_distance_to_boundaries: false`: cpmx observes the distances")
        }));
        assert!(
            text.iter()
                .any(|t| t.starts_with("`is_new_thing: 3`: a parameter cpmx does not know"))
        );
    }

    /// SigmaRL 1.2.0's observation switches (ITSC 2024's ablations, XP-MARL's action slots)
    /// become the observation's fields.
    #[test]
    fn release_1_2_0_switches_are_honoured() {
        let p = parameters(&[
            ("is_ego_view", false.into()),
            ("is_observe_vertices", false.into()),
            ("is_observe_distance_to_agents", false.into()),
            ("is_add_noise", true.into()),
            ("is_using_prioritized_marl", true.into()),
            ("dt", 0.05.into()),
        ]);
        let o = observation(&p, &mu_car(), 0.05).unwrap();
        assert_eq!(o.bird_view_scale_m, Some([4.5, 4.0]));
        assert!(!o.neighbour_vertices && !o.neighbour_distance);
        assert!((o.uniform_noise - 0.2 * mu_car().width).abs() < 1e-15);
        assert_eq!(o.neighbour_actions, NeighbourActions::Propagated);
        let both = parameters(&[
            ("is_using_prioritized_marl", true.into()),
            ("is_using_opponent_modeling", true.into()),
        ]);
        let refusals = observation(&both, &mu_car(), 0.1).unwrap_err();
        assert_eq!(refusals.len(), 1);
        assert_eq!(refusals[0].name, "is_using_opponent_modeling");
    }

    #[test]
    fn the_best_actor_of_a_folder_is_the_highest_reward() {
        let dir = std::env::temp_dir().join(format!("cpmx-sigmarl-locate-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for name in [
            "reward3.5_policy.pth",
            "reward4.25_policy.pth",
            "reward9.0_priority_policy.pth",
            "final_policy.pth",
            "reward4.25_data.json",
        ] {
            std::fs::write(dir.join(name), b"").unwrap();
        }
        let best = locate(&dir, None).unwrap();
        assert_eq!(best.policy, dir.join("reward4.25_policy.pth"));
        assert_eq!(best.data, Some(dir.join("reward4.25_data.json")));
        let last = locate(&dir, Some(CheckpointPick::Final)).unwrap();
        assert_eq!(last.policy, dir.join("final_policy.pth"));
        assert_eq!(last.data, Some(dir.join("reward4.25_data.json")));
        let file = locate(&dir.join("final_policy.pth"), Some(CheckpointPick::Best)).unwrap_err();
        assert!(
            file.starts_with("`pick: best` chooses among the actors of a folder"),
            "{file}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
        let empty = locate(Path::new("/"), None).unwrap_err();
        assert!(empty.contains("no `reward<r>_policy.pth`"), "{empty}");
    }
}

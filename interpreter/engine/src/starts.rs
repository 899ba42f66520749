//! Initial states of every named configuration: explicit starts (arc length or pose), starts
//! sampled on the map from the configuration's own seed, measured starts of recorded runs, and
//! measured starts per run from a poses file (each policy and repetition its own).

use std::collections::BTreeMap;
use std::path::Path;

use cpmx_recording::Recording;
use cpmx_spec::Resources;
use cpmx_spec::RunPlan;
use cpmx_spec::matrix::{ConfigurationSource, NamedConfiguration, stream_key};
use cpmx_spec::model::{
    AgentStart, FromPosesSpec, InitialConfiguration, SampleDraw, SamplePlacement, SampleSpec, Spec,
};
use cpmx_spec::poses::MeasuredPoses;
use cpmx_vehicle::{VehicleParams, footprint_corners};
use cpmx_world::Map;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

use crate::experiment::PrepareError;
use crate::replace::TestingPaths;

pub use cpmx_stack::InitialState;

/// A run of a configuration: its policy and repetition.
pub type RunOf<'a> = (&'a str, u32);

/// Where the runs of one configuration start.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigurationStarts {
    /// Every run starts here.
    Shared(Vec<InitialState>),
    /// Each run from its own measured start, by policy and repetition.
    PerRun(BTreeMap<(String, u32), Vec<InitialState>>),
}

impl ConfigurationStarts {
    /// The start of the run of `policy`'s `repetition`.
    pub fn of_run(&self, policy: &str, repetition: u32) -> Option<&[InitialState]> {
        match self {
            ConfigurationStarts::Shared(states) => Some(states),
            ConfigurationStarts::PerRun(runs) => {
                runs.get(&(policy.to_owned(), repetition)).map(Vec::as_slice)
            }
        }
    }

    /// One start of the configuration (the first run's, for a measured one).
    pub fn any(&self) -> Option<&[InitialState]> {
        match self {
            ConfigurationStarts::Shared(states) => Some(states),
            ConfigurationStarts::PerRun(runs) => runs.values().next().map(Vec::as_slice),
        }
    }

    /// Every start of the configuration, with the run it is that run's (`None` for a shared
    /// one).
    pub fn each(&self) -> Vec<(Option<RunOf<'_>>, &[InitialState])> {
        match self {
            ConfigurationStarts::Shared(states) => vec![(None, states.as_slice())],
            ConfigurationStarts::PerRun(runs) => runs
                .iter()
                .map(|((policy, repetition), states)| {
                    (Some((policy.as_str(), *repetition)), states.as_slice())
                })
                .collect(),
        }
    }
}

/// The start of a planned run among the configurations' starts.
pub fn start_of<'a>(
    starts: &'a [(String, ConfigurationStarts)],
    plan: &RunPlan,
) -> Option<&'a [InitialState]> {
    starts
        .iter()
        .find(|(name, _)| *name == plan.initial_configuration)
        .and_then(|(_, s)| s.of_run(&plan.policy, plan.repetition))
}

/// Initial states of every configuration, by name, in order: each on its own map where its
/// entry names one (`configuration_maps`, by name), else on the spec's `map`.
pub fn initial_states(
    spec: &Spec,
    configurations: &[NamedConfiguration],
    resources: &Resources,
    (map, configuration_maps): (&Map, &BTreeMap<String, std::sync::Arc<Map>>),
    vehicle: &VehicleParams,
) -> Result<Vec<(String, ConfigurationStarts)>, PrepareError> {
    configurations
        .iter()
        .map(|c| {
            let map = configuration_maps.get(&c.name).map_or(map, |own| own.as_ref());
            let fail = |reason: String| PrepareError::Start {
                name: c.name.clone(),
                reason,
            };
            let states = match (&c.source, &spec.initial_configurations) {
                (ConfigurationSource::Measured { entry }, entries) => match &entries[*entry] {
                    InitialConfiguration::FromPoses(f) => {
                        let poses = resources.poses.get(*entry).and_then(Option::as_ref);
                        let poses = poses.ok_or_else(|| fail("the poses file was not read".into()))?;
                        return Ok((
                            c.name.clone(),
                            measured_starts(spec, &f.from_poses, poses, &c.name).map_err(fail)?,
                        ));
                    }
                    _ => return Err(fail("not a `from_poses` configuration".into())),
                },
                (ConfigurationSource::Explicit { entry }, entries) => match &entries[*entry] {
                    InitialConfiguration::Explicit(e) => e
                        .agents
                        .iter()
                        .map(|a| explicit_start(a, map))
                        .collect::<Result<Vec<_>, _>>()
                        .map_err(fail)?,
                    _ => return Err(fail("not an explicit configuration".into())),
                },
                (ConfigurationSource::Sampled { entry, index }, entries) => match &entries[*entry] {
                    InitialConfiguration::Sampled(s) => {
                        let agents = entries[*entry].agents(spec.agents);
                        if s.sample.draw == SampleDraw::PerRepetition {
                            let mut runs = BTreeMap::new();
                            for repetition in 1..=spec.repetitions {
                                let draw = Draw {
                                    index: *index,
                                    repetition: Some(repetition),
                                };
                                let states =
                                    sample_starts(&s.sample, draw, agents, map, vehicle).map_err(fail)?;
                                for policy in &spec.policies {
                                    runs.insert((policy.name.clone(), repetition), states.clone());
                                }
                            }
                            return Ok((c.name.clone(), ConfigurationStarts::PerRun(runs)));
                        }
                        let draw = Draw {
                            index: *index,
                            repetition: None,
                        };
                        sample_starts(&s.sample, draw, agents, map, vehicle).map_err(fail)?
                    }
                    _ => return Err(fail("not a sampled configuration".into())),
                },
                (ConfigurationSource::Recorded { entry, run_key }, _) => {
                    let dir = resources.from_runs.get(*entry).and_then(Option::as_deref);
                    recorded_start(dir, run_key).map_err(fail)?
                }
            };
            Ok((c.name.clone(), ConfigurationStarts::Shared(states)))
        })
        .collect()
}

/// The measured start of every run of `configuration`: each policy's rows (by its label) for
/// every repetition.
fn measured_starts(
    spec: &Spec,
    from: &FromPosesSpec,
    poses: &MeasuredPoses,
    configuration: &str,
) -> Result<ConfigurationStarts, String> {
    let mut runs = BTreeMap::new();
    for policy in &spec.policies {
        let label = from.label_of(&policy.name);
        for repetition in 1..=spec.repetitions {
            let row = poses.row(label, configuration, repetition).ok_or_else(|| {
                format!(
                    "the poses file has no row for `{}` (label `{label}`), repetition {repetition}",
                    policy.name
                )
            })?;
            let states = row
                .vehicles
                .iter()
                .map(|v| InitialState {
                    ref_path: v.ref_path as usize,
                    x_m: v.x_m,
                    y_m: v.y_m,
                    yaw_rad: v.yaw_rad,
                    speed_mps: 0.0,
                })
                .collect();
            runs.insert((policy.name.clone(), repetition), states);
        }
    }
    Ok(ConfigurationStarts::PerRun(runs))
}

/// A start given in the spec.
pub fn explicit_start(start: &AgentStart, map: &Map) -> Result<InitialState, String> {
    let ref_path = start.ref_path as usize;
    let speed_mps = start.speed.unwrap_or(0.0);
    if let Some(pose) = &start.pose {
        return Ok(InitialState {
            ref_path,
            x_m: pose.x,
            y_m: pose.y,
            yaw_rad: pose.yaw_rad(),
            speed_mps,
        });
    }
    let path = map
        .reference_path(ref_path)
        .ok_or_else(|| format!("the map has no reference path {ref_path}"))?;
    let arc_length_m = start.arc_length.unwrap_or(0.0);
    let (x_m, y_m, yaw_rad) = map.pose_at(ref_path, arc_length_m).ok_or_else(|| {
        format!(
            "`arc_length: {arc_length_m}` lies outside reference path {ref_path}, an open path \
             {:.3} m long",
            path.center_line.length_m()
        )
    })?;
    Ok(InitialState {
        ref_path,
        x_m,
        y_m,
        yaw_rad,
        speed_mps,
    })
}

/// Which draw of a sample entry: the entry's `index`-th configuration, and with `draw:
/// per-repetition` the repetition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Draw {
    pub index: u32,
    pub repetition: Option<u32>,
}

impl Draw {
    /// The name of the draw's random stream under the entry's seed.
    fn stream(self) -> String {
        match self.repetition {
            None => format!("starts/{}", self.index),
            Some(repetition) => format!("starts/{}/rep{repetition}", self.index),
        }
    }
}

/// A draw of a sample entry: each agent on a uniformly chosen path at a uniform arc length,
/// on the road, at least `min_gap` from the others (rejection sampling). The stream is keyed
/// by the entry's own seed, so configurations do not change with the spec's `seed`.
pub fn sample_starts(
    sample: &SampleSpec,
    draw: Draw,
    agents: usize,
    map: &Map,
    vehicle: &VehicleParams,
) -> Result<Vec<InitialState>, String> {
    const TRIES_PER_AGENT: usize = 10_000;
    let mut rng = ChaCha20Rng::from_seed(stream_key(sample.seed, &draw.stream()));
    if sample.placement == SamplePlacement::Sigmarl {
        return sigmarl_starts(sample, &mut rng, agents, map, vehicle);
    }
    let ids = map.valid_path_ids();
    if ids.is_empty() {
        return Err("the map has no reference paths".into());
    }
    let mut states: Vec<InitialState> = Vec::with_capacity(agents);
    for agent in 0..agents {
        let placed = (0..TRIES_PER_AGENT).find_map(|_| {
            let ref_path = ids[rng.random_range(0..ids.len())];
            let length_m = map.reference_path(ref_path)?.center_line.length_m();
            // Keep clear of the path's ends so the car starts on it, heading along it.
            let margin_m = vehicle.length_m;
            if length_m <= 2.0 * margin_m {
                return None;
            }
            let arc_length_m = rng.random_range(margin_m..length_m - margin_m);
            let (x_m, y_m, yaw_rad) = map.pose_at(ref_path, arc_length_m)?;
            let corners = footprint_corners(vehicle, x_m, y_m, yaw_rad);
            let clear = states
                .iter()
                .all(|s| (s.x_m - x_m).hypot(s.y_m - y_m) >= sample.min_gap.max(vehicle.length_m));
            (clear && map.footprint_on_road(ref_path, &corners) == Some(true)).then_some(InitialState {
                ref_path,
                x_m,
                y_m,
                yaw_rad,
                speed_mps: 0.0,
            })
        });
        match placed {
            Some(state) => states.push(state),
            None => {
                return Err(format!(
                    "no free place for agent {agent} with min_gap {} m",
                    sample.min_gap
                ));
            }
        }
    }
    Ok(states)
}

/// SigmaRL's testing-mode starts (`sample: {placement: sigmarl}`): the agents placed in order,
/// each clear of those before it by `min_gap`, as `on_collision: replace-agent` places a car.
fn sigmarl_starts(
    sample: &SampleSpec,
    rng: &mut ChaCha20Rng,
    agents: usize,
    map: &Map,
    vehicle: &VehicleParams,
) -> Result<Vec<InitialState>, String> {
    let paths = TestingPaths::of_map(map)?;
    let mut states: Vec<InitialState> = Vec::with_capacity(agents);
    for agent in 0..agents {
        let placed: Vec<[f64; 2]> = states.iter().map(|s| [s.x_m, s.y_m]).collect();
        let (ref_path, placement) = paths
            .draw(rng, sample.min_gap, vehicle.max_speed_mps, &placed)
            .ok_or_else(|| {
                format!(
                    "no free place for agent {agent} with min_gap {} m",
                    sample.min_gap
                )
            })?;
        states.push(InitialState {
            ref_path,
            x_m: placement.state.x_m,
            y_m: placement.state.y_m,
            yaw_rad: placement.state.yaw_rad,
            speed_mps: placement.state.speed_mps,
        });
    }
    Ok(states)
}

/// The first sample of a recorded run (its measured initial poses and speeds).
fn recorded_start(dir: Option<&Path>, run_key: &str) -> Result<Vec<InitialState>, String> {
    let dir = dir.ok_or("the run folder was not found")?;
    let path = dir.join("runs").join(run_key).join("trajectory.csv");
    let file = std::fs::File::open(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let recording = Recording::read_csv(file).map_err(|e| format!("{}: {e}", path.display()))?;
    let first = recording.samples.first().ok_or("the recording is empty")?;
    Ok(first
        .iter()
        .zip(&recording.ref_paths)
        .map(|(s, &ref_path)| InitialState {
            ref_path,
            x_m: s.x_m,
            y_m: s.y_m,
            yaw_rad: s.yaw_rad,
            speed_mps: s.velocity_mps[0].hypot(s.velocity_mps[1]),
        })
        .collect())
}

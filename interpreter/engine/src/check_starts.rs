//! The checks of where runs start, which need the map: explicit starts name paths of the map,
//! stand on the road (or within the configuration's `off_road_tolerance_m` of it, with a
//! warning that gives the distance) and do not overlap; every draw of a sample finds room; and
//! every measured start of a poses file, run by run, the same way (a start the lab drove from
//! is warned about, not refused, within the tolerance).

use cpmx_metrics::collision::{PlacedBox, mtv_distance_m};
use cpmx_spec::model::{FromPosesSpec, InitialConfiguration, SampleDraw, SampleSpec};
use cpmx_spec::poses::MeasuredPoses;
use cpmx_spec::{CheckContext, Problem, Resources, Spec};
use cpmx_vehicle::{VehicleParams, footprint_corners};
use cpmx_world::Map;

use crate::experiment::vehicle_params;
use crate::starts::{Draw, InitialState, explicit_start, sample_starts};

/// Every start of the spec's configurations, each entry on its map (`maps`, by entry: `None`
/// where the entry's own map did not load, which was said).
pub(crate) fn check_starts(
    spec: &Spec,
    resources: &Resources,
    maps: &[Option<&Map>],
    ctx: &mut CheckContext<'_>,
) {
    let vehicle = vehicle_params(&spec.vehicle);
    // A start stands on the road with the car the runs simulate and, where the metrics score
    // another (the lab's µCar, whose measured poses a spec may start from), with that one too.
    let mut cars = vec![("", vehicle)];
    if spec.metrics.footprint.is_some() {
        let footprint = crate::experiment::footprint_params(spec);
        if (footprint.length_m, footprint.width_m) != (vehicle.length_m, vehicle.width_m) {
            cars.push(("the metrics' footprint", footprint));
        }
    }
    for (c, configuration) in spec.initial_configurations.iter().enumerate() {
        let Some(map) = maps.get(c).copied().flatten() else {
            continue;
        };
        match configuration {
            InitialConfiguration::Sampled(sampled) => {
                let agents = configuration.agents(spec.agents);
                check_sampled_starts(spec, c, &sampled.sample, agents, map, &vehicle, ctx);
            }
            InitialConfiguration::Explicit(e) => check_explicit(c, e, map, &cars, ctx),
            InitialConfiguration::FromPoses(f) => {
                if let Some(poses) = resources.poses.get(c).and_then(Option::as_ref) {
                    check_measured(spec, c, &f.from_poses, poses, map, &cars, ctx);
                }
            }
            InitialConfiguration::FromRuns(_) => {}
        }
    }
}

/// The map's path ids as the help of an unknown one says them.
fn path_range(map: &Map) -> String {
    let ids = map.valid_path_ids();
    match (ids.first(), ids.last()) {
        (Some(first), Some(last)) if last - first + 1 == ids.len() => format!("{first}..={last}"),
        _ => format!("{ids:?}"),
    }
}

/// The cars whose footprint a start must keep on the road: the simulated vehicle (no label),
/// and the metrics' footprint where it is another car.
type Cars<'a> = [(&'a str, VehicleParams)];

/// What is wrong with where one start stands: off the road beyond the tolerance (an error),
/// off it within the tolerance (a warning), or on it; with the car that reaches farthest.
enum Footing {
    OnRoad,
    Tolerated(f64, String),
    OffRoad(f64, String),
}

fn footing(start: &InitialState, map: &Map, cars: &Cars<'_>, tolerance_m: f64) -> Footing {
    let worst = cars
        .iter()
        .filter_map(|(label, car)| {
            let corners = footprint_corners(car, start.x_m, start.y_m, start.yaw_rad);
            let off_m = map.footprint_off_road_m(start.ref_path, &corners)?;
            let whose = if label.is_empty() {
                "its footprint".to_owned()
            } else {
                format!("{label} ({} m × {} m)", car.length_m, car.width_m)
            };
            Some((off_m, whose))
        })
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match worst {
        None => Footing::OnRoad,
        Some((0.0, _)) => Footing::OnRoad,
        Some((off_m, whose)) if off_m <= tolerance_m => Footing::Tolerated(off_m, whose),
        Some((off_m, whose)) => Footing::OffRoad(off_m, whose),
    }
}

/// The problem of a start beside or off the road (`what` names it), if any.
fn footing_problem(
    start: &InitialState,
    map: &Map,
    cars: &Cars<'_>,
    tolerance_m: f64,
    what: &str,
    span: cpmx_spec::ByteSpan,
) -> Option<Problem> {
    let ref_path = start.ref_path;
    match footing(start, map, cars, tolerance_m) {
        Footing::OnRoad => None,
        Footing::Tolerated(off_m, whose) => Some(
            Problem::warning(
                "cpmx::map::near-road",
                format!(
                    "{what}: {whose} reaches {} beyond the road of path {ref_path}; it runs, as it is \
                     within `off_road_tolerance_m: {tolerance_m}`",
                    millimetres(off_m)
                ),
                span,
                "just off the road",
            )
            .with_help("a measured start a little beside the road (positioning noise) is run as measured"),
        ),
        Footing::OffRoad(off_m, whose) => Some(
            Problem::error(
                "cpmx::map::off-road",
                format!(
                    "{what} starts off the road of path {ref_path}: {whose} reaches {} beyond it, more \
                     than `off_road_tolerance_m: {tolerance_m}`",
                    millimetres(off_m)
                ),
                span,
                "footprint leaves the road",
            )
            .with_help(
                "start on the path (`arc_length`), move the `pose` onto its lanes, or raise \
                 `off_road_tolerance_m` for measured starts",
            ),
        ),
    }
}

/// A distance beyond the road as a message says it: to a tenth of a millimetre, and a
/// footprint that only touches past it (floating-point dust) as such.
fn millimetres(off_m: f64) -> String {
    if off_m < 0.5e-4 {
        "less than 0.1 mm".to_owned()
    } else {
        format!("{:.1} mm", off_m * 1e3)
    }
}

/// An explicit configuration's starts.
fn check_explicit(
    c: usize,
    e: &cpmx_spec::model::ExplicitConfiguration,
    map: &Map,
    cars: &Cars<'_>,
    ctx: &mut CheckContext<'_>,
) {
    let vehicle = &cars[0].1;
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
                .with_help(format!("this map's reference paths are {}", path_range(map))),
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
        let what = format!("agent {a} of `{}`", e.name);
        let span = ctx.span(&pointer);
        if let Some(problem) = footing_problem(&start, map, cars, e.off_road_tolerance_m, &what, span) {
            ctx.push(problem);
        }
        let this = PlacedBox::from_pose(vehicle, start.x_m, start.y_m, start.yaw_rad);
        if let Some((other, _)) = placed.iter().find(|(_, b)| mtv_distance_m(b, &this) < 0.0) {
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

/// The starts of a poses file, run by run: every path known, every footprint on the road (or
/// within the tolerance), no two vehicles of a run on top of each other (a warning: the lab
/// measured them so).
fn check_measured(
    spec: &Spec,
    c: usize,
    from: &FromPosesSpec,
    poses: &MeasuredPoses,
    map: &Map,
    cars: &Cars<'_>,
    ctx: &mut CheckContext<'_>,
) {
    let vehicle = &cars[0].1;
    let span = ctx.span(&format!("/initial_configurations/{c}/from_poses/file"));
    let tolerance_m = from.off_road_tolerance_m;
    let labels: Vec<&str> = spec.policies.iter().map(|p| from.label_of(&p.name)).collect();
    for row in poses.rows.iter().filter(|r| labels.contains(&r.label.as_str())) {
        let run = format!("{}/{}-{}", row.label, row.configuration, row.repetition);
        let mut placed: Vec<(usize, PlacedBox)> = Vec::new();
        for (a, pose) in row.vehicles.iter().enumerate() {
            let what = format!(
                "vehicle {} of `{run}` (line {} of {})",
                a + 1,
                row.line,
                from.file
            );
            let ref_path = pose.ref_path as usize;
            if map.reference_path(ref_path).is_none() {
                ctx.push(
                    Problem::error(
                        "cpmx::map::ref-path",
                        format!("{what} follows reference path {ref_path}, which the map has not"),
                        span,
                        "unknown reference path",
                    )
                    .with_help(format!("this map's reference paths are {}", path_range(map))),
                );
                continue;
            }
            let start = InitialState {
                ref_path,
                x_m: pose.x_m,
                y_m: pose.y_m,
                yaw_rad: pose.yaw_rad,
                speed_mps: 0.0,
            };
            if let Some(problem) = footing_problem(&start, map, cars, tolerance_m, &what, span) {
                ctx.push(problem);
            }
            let this = PlacedBox::from_pose(vehicle, start.x_m, start.y_m, start.yaw_rad);
            if let Some((other, _)) = placed.iter().find(|(_, b)| mtv_distance_m(b, &this) < 0.0) {
                ctx.push(
                    Problem::warning(
                        "cpmx::map::overlap",
                        format!(
                            "vehicles {} and {} of `{run}` (line {}) start overlapping",
                            other + 1,
                            a + 1,
                            row.line
                        ),
                        span,
                        "measured overlapping",
                    )
                    .with_help("the run starts as measured; its first samples may count as a collision"),
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
    agents: usize,
    map: &Map,
    vehicle: &VehicleParams,
    ctx: &mut CheckContext<'_>,
) {
    let repetitions: Vec<Option<u32>> = match sample.draw {
        SampleDraw::PerConfiguration => vec![None],
        SampleDraw::PerRepetition => (1..=spec.repetitions).map(Some).collect(),
    };
    let mut draws = (0..sample.count).flat_map(|index| {
        repetitions
            .iter()
            .map(move |&repetition| Draw { index, repetition })
    });
    let Some((draw, reason)) = draws.find_map(|draw| {
        sample_starts(sample, draw, agents, map, vehicle)
            .err()
            .map(|reason| (draw, reason))
    }) else {
        return;
    };
    let which = match draw.repetition {
        None => format!("draw {} of {}", draw.index + 1, sample.count),
        Some(repetition) => format!(
            "the draw of repetition {repetition} of configuration {}",
            draw.index + 1
        ),
    };
    let span = ctx.span(&format!("/initial_configurations/{entry}/sample"));
    ctx.push(
        Problem::error(
            "cpmx::map::no-room",
            format!("{which} of this sample cannot place {agents} agents: {reason}"),
            span,
            "no room on this map",
        )
        .with_help("lower `agents` or `min_gap`, or name a larger map"),
    );
}

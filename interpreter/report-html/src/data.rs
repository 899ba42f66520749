//! The JSON the page draws from: the maps (boundaries simplified for display; the spec's, then
//! those of configurations with their own, each run naming its), the vehicle's
//! footprint, every run on the metrics' time grid (so the metrics' sample indices of
//! collision events and lane violations point at drawn states), the pairs of runs that
//! replay together, Figure 3's choices, and the learning curves.
//!
//! Display only: coordinates are rounded to a millimetre (or the map's scale) and polylines
//! simplified; the metrics were computed from every sample of the recording. The runs' states
//! together hold at most [`REPLAY_BUDGET`] vehicle samples: beyond it every run is drawn at
//! every `stride`-th sample of the grid (the page says so), so that an experiment of many long
//! runs still gives a page a browser opens. Each agent's states cover only the samples it is
//! present in (agents that come and go under `on_collision: replace-agent`).

use std::collections::BTreeMap;

use cpmx_metrics::resample::resample;
use cpmx_recording::AgentSample;
use cpmx_world::Point;
use serde::Serialize;
use serde_json::{Value, json};

use crate::{Page, PageRun};

/// The most vehicle samples the page's runs hold together (about 25 MB of page).
pub const REPLAY_BUDGET: usize = 1_000_000;

/// The data of the page (what the insta snapshots hold), written in this order.
#[derive(Serialize)]
pub struct PageData<'a> {
    experiment: &'a str,
    /// The runs are drawn at every `stride`-th sample of the metrics' grid (1: every one).
    pub(crate) stride: usize,
    maps: Vec<Value>,
    vehicle: Value,
    runs: Vec<RunData<'a>>,
    pairs: Vec<Value>,
    figure3: Vec<Value>,
    learning_curves: Vec<Value>,
}

/// The data of the page.
pub fn page_data<'a>(page: &Page<'a>) -> PageData<'a> {
    let maps = page
        .maps
        .iter()
        .enumerate()
        .map(|(index, map)| map_data(map, page.runs.iter().filter(|run| run.map == index)))
        .collect();
    let stride = replay_stride(&page.runs);
    PageData {
        experiment: &page.summary.experiment,
        stride,
        maps,
        vehicle: json!({"length_m": page.vehicle.length_m, "width_m": page.vehicle.width_m}),
        runs: page.runs.iter().map(|run| run_data(run, stride)).collect(),
        pairs: pairs(&page.runs),
        figure3: figure3(&page.runs, page.summary),
        learning_curves: page
            .learning_curves
            .iter()
            .map(|c| {
                json!({
                    "name": c.name,
                    "iteration": c.iterations,
                    "episode_reward_mean": c.episode_reward_mean,
                })
            })
            .collect(),
    }
}

/// One map as the page draws it: its bounds, its lanelets' boundaries and the centre lines of
/// the reference paths `runs` follow, simplified by a tolerance invisible at any size the page
/// draws it (at most 1/2000 of its diagonal, at least 1 mm).
fn map_data<'a>(map: &cpmx_world::Map, runs: impl Iterator<Item = &'a PageRun<'a>>) -> Value {
    let bounds = map.bounds();
    let diagonal_m = (bounds.max_x_m - bounds.min_x_m).hypot(bounds.max_y_m - bounds.min_y_m);
    let tolerance_m = (diagonal_m / 2000.0).max(0.001);
    let lanelets: Vec<Value> = map
        .lanelets()
        .flat_map(|l| [&l.left_boundary, &l.right_boundary])
        .map(|line| flat(&simplify(&line.points, tolerance_m)))
        .collect();
    let mut paths: BTreeMap<String, Value> = BTreeMap::new();
    for run in runs {
        for id in &run.recording.ref_paths {
            if let Some(path) = map.reference_path(*id) {
                paths
                    .entry(id.to_string())
                    .or_insert_with(|| flat(&simplify(&path.center_line.points, tolerance_m)));
            }
        }
    }
    json!({
        "bounds": [round(bounds.min_x_m), round(bounds.min_y_m), round(bounds.max_x_m), round(bounds.max_y_m)],
        "lanelets": lanelets,
        "paths": paths,
    })
}

/// One run: its place in the matrix, metrics, and each agent's states on the metrics' grid.
/// Written field by field in this order (the page's script reads it by name).
#[derive(Serialize)]
struct RunData<'a> {
    key: &'a str,
    fidelity: &'a str,
    policy: &'a str,
    configuration: &'a str,
    repetition: u32,
    /// The run's map: its index in the page's `maps`.
    map: usize,
    pair: String,
    metrics: RunMetricsData,
    /// Seconds between two drawn samples.
    dt: f64,
    /// Drawn samples.
    samples: usize,
    ref_paths: &'a [usize],
    agents: Vec<AgentData>,
    /// Per collision event: sample, first agent, second agent.
    collisions: Vec<[usize; 3]>,
    /// Per lane-violation sample: agent, sample.
    violations: Vec<[usize; 2]>,
}

/// A run's metrics as the page shows them (rounded; null when not finite).
#[derive(Serialize)]
struct RunMetricsData {
    cra_a: Option<f64>,
    cra_l: Option<f64>,
    cd_m: Option<f64>,
    as_mps: Option<f64>,
}

/// One agent's states on the drawn samples from its first, `first`, to its last.
#[derive(Serialize)]
struct AgentData {
    first: usize,
    x: Vec<Option<f64>>,
    y: Vec<Option<f64>>,
    yaw: Vec<Option<f64>>,
    v: Vec<Option<f64>>,
}

/// The stride that keeps the runs' vehicle samples within [`REPLAY_BUDGET`].
fn replay_stride(runs: &[PageRun<'_>]) -> usize {
    let total: usize = runs
        .iter()
        .map(|run| {
            let r = run.recording;
            (0..r.agent_count())
                .map(|agent| r.span(agent).len())
                .sum::<usize>()
        })
        .sum();
    total.div_ceil(REPLAY_BUDGET).max(1)
}

fn run_data<'a>(run: &PageRun<'a>, stride: usize) -> RunData<'a> {
    let (plan, metrics) = (&run.record.plan, &run.record.metrics);
    let period_s = metrics.config.sample_period_s;
    let grid = resample(run.recording, period_s);
    let rows: Vec<&Vec<AgentSample>> = grid
        .samples
        .iter()
        .take(metrics.num_samples)
        .step_by(stride)
        .collect();
    let agents = (0..run.recording.agent_count())
        .map(|agent| {
            let present = |row: &&Vec<AgentSample>| row.get(agent).is_some_and(AgentSample::is_present);
            let first = rows.iter().position(present).unwrap_or(rows.len());
            let end = rows.iter().rposition(present).map_or(first, |last| last + 1);
            let column = |f: &dyn Fn(&AgentSample) -> f64, digits: i32| -> Vec<Option<f64>> {
                rows[first..end]
                    .iter()
                    .map(|row| row.get(agent).and_then(|s| rounded(f(s), digits)))
                    .collect()
            };
            AgentData {
                first,
                x: column(&|s| s.x_m, 3),
                y: column(&|s| s.y_m, 3),
                yaw: column(&|s| s.yaw_rad, 3),
                v: column(&|s| s.velocity_mps[0].hypot(s.velocity_mps[1]), 2),
            }
        })
        .collect();
    let mut violations: Vec<[usize; 2]> = metrics
        .agents
        .iter()
        .enumerate()
        .flat_map(|(agent, a)| a.violation_samples.iter().map(move |&k| [agent, k / stride]))
        .collect();
    violations.dedup();
    RunData {
        key: &plan.key,
        fidelity: &plan.fidelity,
        policy: &plan.policy,
        configuration: &plan.initial_configuration,
        repetition: plan.repetition,
        map: run.map,
        pair: plan.pair_key(),
        metrics: RunMetricsData {
            cra_a: rounded(metrics.cra_a, 4),
            cra_l: rounded(metrics.cra_l, 4),
            cd_m: rounded(metrics.cd_m, 5),
            as_mps: rounded(metrics.as_mps, 4),
        },
        dt: period_s * stride as f64,
        samples: rows.len(),
        ref_paths: &run.recording.ref_paths,
        agents,
        collisions: metrics
            .pair_events
            .iter()
            .map(|e| [e.sample / stride, e.agents[0], e.agents[1]])
            .collect(),
        violations,
    }
}

/// The runs that replay together: one list of run indices per pair key (policy, initial
/// configuration, repetition), in matrix order.
fn pairs(runs: &[PageRun<'_>]) -> Vec<Value> {
    let mut order: Vec<String> = Vec::new();
    let mut members: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, run) in runs.iter().enumerate() {
        let key = run.record.plan.pair_key();
        if !members.contains_key(&key) {
            order.push(key.clone());
        }
        members.entry(key).or_default().push(i);
    }
    order
        .into_iter()
        .map(|key| json!({"key": key, "runs": members[&key]}))
        .collect()
}

/// Figure 3 of the paper for each initial configuration: a run to show the setup from (its
/// first sample: starts are shared by every run of the configuration), and per group of the
/// summary (its `group_by`: a fidelity and policy by default) the run of the configuration whose
/// CD is closest to the group's mean CD, so that a caption never quotes a mean pooled over
/// policies the reader did not ask to pool. Captions name policies: the configuration's
/// (every one starts from the setup) and each group's (more than one when it pools them).
fn figure3(runs: &[PageRun<'_>], summary: &cpmx_report::Summary) -> Vec<Value> {
    let mut configurations: Vec<&str> = Vec::new();
    for run in runs {
        let c = run.record.plan.initial_configuration.as_str();
        if !configurations.contains(&c) {
            configurations.push(c);
        }
    }
    let in_group = |run: &PageRun<'_>, group: &cpmx_report::Group| {
        summary
            .group_by
            .iter()
            .zip(&group.key)
            .all(|(&axis, value)| cpmx_report::axis_value(&run.record.plan, axis) == value)
    };
    configurations
        .into_iter()
        .map(|configuration| {
            let of_configuration = |i: &usize| runs[*i].record.plan.initial_configuration == configuration;
            let setup = (0..runs.len()).find(of_configuration);
            let policies = distinct(
                (0..runs.len())
                    .filter(of_configuration)
                    .map(|i| &runs[i].record.plan.policy),
            );
            let representatives: Vec<Value> = summary
                .groups
                .iter()
                .filter_map(|group| {
                    let mean = group
                        .metric(cpmx_report::Metric::Cd)
                        .map_or(f64::NAN, |m| m.stats.mean);
                    let gap = |i: usize| {
                        let cd = runs[i].record.metrics.cd_m;
                        if cd.is_finite() && mean.is_finite() {
                            (cd - mean).abs()
                        } else {
                            f64::INFINITY
                        }
                    };
                    let best = (0..runs.len())
                        .filter(of_configuration)
                        .filter(|&i| in_group(&runs[i], group))
                        .min_by(|&a, &b| gap(a).total_cmp(&gap(b)))?;
                    let group_policies = distinct(
                        runs.iter()
                            .filter(|run| in_group(run, group))
                            .map(|run| &run.record.plan.policy),
                    );
                    Some(json!({
                        "group": group.key.join(" · "),
                        "group_policies": group_policies,
                        "policy": runs[best].record.plan.policy,
                        "fidelity": runs[best].record.plan.fidelity,
                        "mean_cd_m": number(mean, 5),
                        "run": best,
                    }))
                })
                .collect();
            json!({
                "configuration": configuration,
                "policies": policies,
                "setup": setup,
                "representatives": representatives,
            })
        })
        .collect()
}

/// The distinct values, in order of first appearance.
pub(crate) fn distinct<'a>(values: impl IntoIterator<Item = &'a String>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for value in values {
        if !out.contains(&value.as_str()) {
            out.push(value);
        }
    }
    out
}

/// A polyline without the points that lie within `tolerance_m` of the line through their
/// neighbours kept (Douglas-Peucker), first and last point always kept.
fn simplify(points: &[Point], tolerance_m: f64) -> Vec<Point> {
    if points.len() < 3 {
        return points.to_vec();
    }
    let mut keep = vec![false; points.len()];
    keep[0] = true;
    keep[points.len() - 1] = true;
    let mut stack = vec![(0, points.len() - 1)];
    while let Some((first, last)) = stack.pop() {
        let (a, b) = (points[first], points[last]);
        let (mut farthest, mut distance) = (first, 0.0);
        for (i, &p) in points.iter().enumerate().take(last).skip(first + 1) {
            let d = distance_to_segment(p, a, b);
            if d > distance {
                (farthest, distance) = (i, d);
            }
        }
        if distance > tolerance_m {
            keep[farthest] = true;
            stack.push((first, farthest));
            stack.push((farthest, last));
        }
    }
    points
        .iter()
        .zip(keep)
        .filter(|(_, k)| *k)
        .map(|(p, _)| *p)
        .collect()
}

fn distance_to_segment(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let length2 = dx * dx + dy * dy;
    let t = if length2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// `[x0, y0, x1, y1, ...]`, rounded to a millimetre.
fn flat(points: &[Point]) -> Value {
    Value::from(
        points
            .iter()
            .flat_map(|&[x, y]| [round(x), round(y)])
            .collect::<Vec<f64>>(),
    )
}

fn round(value: f64) -> f64 {
    // `+ 0.0` turns -0.0 into 0.0.
    (value * 1000.0).round() / 1000.0 + 0.0
}

/// A finite value with `digits` decimals; `null` otherwise.
fn number(value: f64, digits: i32) -> Value {
    rounded(value, digits).map_or(Value::Null, |v| json!(v))
}

/// `value` rounded to `digits` decimals; `None` when it is not finite.
fn rounded(value: f64, digits: i32) -> Option<f64> {
    if !value.is_finite() {
        return None;
    }
    let scale = 10f64.powi(digits);
    Some((value * scale).round() / scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simplifying_keeps_corners_and_drops_collinear_points() {
        let line: Vec<Point> = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [2.0, 0.0001],
            [3.0, 0.0],
            [3.0, 1.0],
            [3.0, 2.0],
        ];
        assert_eq!(simplify(&line, 0.001), vec![[0.0, 0.0], [3.0, 0.0], [3.0, 2.0]]);
        assert_eq!(simplify(&line[..2], 0.001).len(), 2);
    }
}

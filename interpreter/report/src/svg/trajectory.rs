//! The map of one run: lanelet boundaries in light grey, each agent's reference path dashed
//! and its trajectory solid in its own colour, start markers, and footprints at collision
//! events (red) and at the first sample of each lane-violation episode (orange). y points up.

use std::fmt::Write;

use cpmx_metrics::RunMetrics;
use cpmx_metrics::resample::resample;
use cpmx_recording::{AgentSample, Recording};
use cpmx_vehicle::{VehicleParams, footprint_corners};
use cpmx_world::{Bounds, Map, Point};

use super::{colour, open, path_data, px};

/// The largest drawing [px]: any map, from the 4.5 m lab to a few hundred metres, is scaled
/// to fit (keeping its aspect ratio), with a scale bar.
const MAX_WIDTH_PX: f64 = 900.0;
const MAX_HEIGHT_PX: f64 = 800.0;
/// Blank border around the drawing [px] (the scale bar sits in the bottom one).
const MARGIN_PX: f64 = 30.0;

/// The SVG of one run on its map.
///
/// The recording is put on the metrics' time grid first (`metrics.config.sample_period_s`,
/// its `rotate180`, and `metrics.num_samples` samples), so that the sample indices of
/// `metrics` (pair events, violation samples) point at the drawn states. Indices outside
/// the recording are skipped.
pub fn trajectory_svg(
    map: &Map,
    recording: &Recording,
    metrics: &RunMetrics,
    vehicle: &VehicleParams,
) -> String {
    // Put the states in the metrics' frame and time grid.
    let states = metric_states(recording, metrics);
    let frame = Frame::new(map, &states);
    let mut out = open(frame.width_px, frame.height_px);
    let _ = writeln!(
        out,
        "<title>{} agents over {} samples; red: collision events, orange: lane violations</title>",
        recording.agent_count(),
        states.len()
    );

    // The road, then each agent's reference path.
    out.push_str("<g class=\"lanelets\" fill=\"none\" stroke=\"#c8c8c8\" stroke-width=\"1\">\n");
    for lanelet in map.lanelets() {
        for boundary in [&lanelet.left_boundary, &lanelet.right_boundary] {
            let _ = writeln!(out, "<path d=\"{}\"/>", frame.path(&boundary.points));
        }
    }
    out.push_str("</g>\n");
    for (agent, &id) in recording.ref_paths.iter().enumerate() {
        if let Some(path) = map.reference_path(id) {
            let _ = writeln!(
                out,
                "<path class=\"ref-path\" d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-opacity=\"0.5\" stroke-dasharray=\"6 4\"/>",
                frame.path(&path.center_line.points),
                colour(agent)
            );
        }
    }

    // Trajectories and start markers.
    for (agent, &ref_path) in recording.ref_paths.iter().enumerate() {
        let points: Vec<Point> = states
            .iter()
            .filter_map(|row| row.get(agent))
            .map(|s| [s.x_m, s.y_m])
            .collect();
        let _ = writeln!(
            out,
            "<path class=\"trajectory\" data-agent=\"{agent}\" d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\">\
             <title>agent {agent}, reference path {ref_path}</title></path>",
            frame.path(&points),
            colour(agent)
        );
        if let Some(&[x, y]) = points.first() {
            let (cx, cy) = frame.to_px(x, y);
            let _ = writeln!(
                out,
                "<circle class=\"start\" cx=\"{}\" cy=\"{}\" r=\"4\" fill=\"{}\" stroke=\"black\"/>",
                px(cx),
                px(cy),
                colour(agent)
            );
        }
    }

    // Footprints at collision events and at the start of each lane-violation episode.
    for event in &metrics.pair_events {
        for agent in event.agents {
            footprint(
                &mut out,
                &frame,
                &states,
                vehicle,
                (event.sample, agent),
                Mark::Collision,
            );
        }
    }
    for (agent, a) in metrics.agents.iter().enumerate() {
        for (i, &sample) in a.violation_samples.iter().enumerate() {
            let starts_episode = i == 0 || a.violation_samples[i - 1] + 1 != sample;
            if starts_episode {
                footprint(
                    &mut out,
                    &frame,
                    &states,
                    vehicle,
                    (sample, agent),
                    Mark::Violation,
                );
            }
        }
    }
    scale_bar(&mut out, &frame);
    out.push_str("</svg>\n");
    out
}

/// A bar of a round length (1, 2 or 5 × 10^k m, about a fifth of the drawing) with its label,
/// in the bottom-left corner.
fn scale_bar(out: &mut String, frame: &Frame) {
    let length_m = super::round_length_m((frame.bounds.max_x_m - frame.bounds.min_x_m) / 5.0);
    let length_px = length_m * frame.scale_px_per_m;
    let y = frame.height_px - MARGIN_PX / 2.0;
    let _ = writeln!(
        out,
        "<g class=\"scale-bar\"><path d=\"M{x0} {y} L{x1} {y}\" stroke=\"black\" stroke-width=\"2\"/>\
         <text x=\"{tx}\" y=\"{ty}\">{label}</text></g>",
        x0 = px(MARGIN_PX),
        x1 = px(MARGIN_PX + length_px),
        y = px(y),
        tx = px(MARGIN_PX + length_px + 6.0),
        ty = px(y + 4.0),
        label = super::length_label(length_m)
    );
}

/// The states the metrics saw: resampled, rotated as `rotate180` asks, truncated.
fn metric_states(recording: &Recording, metrics: &RunMetrics) -> Vec<Vec<AgentSample>> {
    let period_s = metrics.config.sample_period_s;
    let consistent = recording.samples.len() == recording.times_s.len();
    let grid = if consistent && period_s.is_finite() && period_s > 0.0 {
        resample(recording, period_s).into_owned()
    } else {
        recording.clone()
    };
    let rotate = |s: &AgentSample| match metrics.config.rotate180 {
        Some(r) => AgentSample {
            x_m: 2.0 * r.centre_m[0] - s.x_m,
            y_m: 2.0 * r.centre_m[1] - s.y_m,
            yaw_rad: s.yaw_rad + std::f64::consts::PI,
            ..*s
        },
        None => *s,
    };
    grid.samples
        .iter()
        .take(metrics.num_samples)
        .map(|row| row.iter().map(rotate).collect())
        .collect()
}

/// Why a footprint is drawn.
#[derive(Debug, Clone, Copy)]
enum Mark {
    Collision,
    Violation,
}

/// Draws one agent's footprint at one sample (nothing when either is out of range).
fn footprint(
    out: &mut String,
    frame: &Frame,
    states: &[Vec<AgentSample>],
    vehicle: &VehicleParams,
    at: (usize, usize),
    mark: Mark,
) {
    let (sample, agent) = at;
    let Some(s) = states.get(sample).and_then(|row| row.get(agent)) else {
        return;
    };
    let (class, fill) = match mark {
        Mark::Collision => ("collision", "#ff0000"),
        Mark::Violation => ("violation", "#ffa500"),
    };
    let corners = footprint_corners(vehicle, s.x_m, s.y_m, s.yaw_rad);
    let points: Vec<String> = corners
        .iter()
        .map(|&[x, y]| {
            let (u, v) = frame.to_px(x, y);
            format!("{},{}", px(u), px(v))
        })
        .collect();
    let _ = writeln!(
        out,
        "<polygon class=\"{class}\" data-agent=\"{agent}\" data-sample=\"{sample}\" points=\"{}\" \
         fill=\"{fill}\" fill-opacity=\"0.45\" stroke=\"{}\"/>",
        points.join(" "),
        colour(agent)
    );
}

/// Map metres to SVG pixels, y up, scaled to fit the largest drawing.
struct Frame {
    bounds: Bounds,
    scale_px_per_m: f64,
    width_px: f64,
    height_px: f64,
}

impl Frame {
    /// A frame around the map and every drawn state.
    fn new(map: &Map, states: &[Vec<AgentSample>]) -> Frame {
        let b = map.bounds();
        let corners = [[b.min_x_m, b.min_y_m], [b.max_x_m, b.max_y_m]];
        let positions = states
            .iter()
            .flatten()
            .map(|s| [s.x_m, s.y_m])
            .filter(|p| p[0].is_finite() && p[1].is_finite());
        let bounds = Bounds::of(corners.into_iter().chain(positions)).unwrap_or(b);
        let (width_m, height_m) = (
            (bounds.max_x_m - bounds.min_x_m).max(1e-3),
            (bounds.max_y_m - bounds.min_y_m).max(1e-3),
        );
        let scale_px_per_m =
            ((MAX_WIDTH_PX - 2.0 * MARGIN_PX) / width_m).min((MAX_HEIGHT_PX - 2.0 * MARGIN_PX) / height_m);
        Frame {
            bounds,
            scale_px_per_m,
            width_px: width_m * scale_px_per_m + 2.0 * MARGIN_PX,
            height_px: height_m * scale_px_per_m + 2.0 * MARGIN_PX,
        }
    }

    fn to_px(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            MARGIN_PX + (x_m - self.bounds.min_x_m) * self.scale_px_per_m,
            MARGIN_PX + (self.bounds.max_y_m - y_m) * self.scale_px_per_m,
        )
    }

    fn path(&self, points: &[Point]) -> String {
        path_data(points.iter().map(|&[x, y]| self.to_px(x, y)))
    }
}

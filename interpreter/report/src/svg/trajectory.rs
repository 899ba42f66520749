//! The map of one run: lanelet boundaries in light grey, each agent's reference path dashed
//! and its trajectory solid in its own colour, start markers, and the events in inks no
//! agent takes, drawn so that they hide no trajectory: a lane-violation episode as a
//! translucent grey band under the trajectory's stretch with a hollow ring where it starts,
//! a collision event as the two vehicles' outlines (unfilled) and a black cross between
//! them. A legend above the map says so. y points up.

use std::fmt::Write;
use std::sync::{Arc, Mutex};

use cpmx_metrics::RunMetrics;
use cpmx_metrics::resample::resample;
use cpmx_recording::{AgentSample, Recording};
use cpmx_vehicle::{VehicleParams, footprint_corners};
use cpmx_world::{Bounds, Map, Point};

use super::{AGENT_COLOURS, COLLISION_INK, VIOLATION_INK, colour, open, path_data, px};

/// The largest drawing [px]: any map, from the 4.5 m lab to a few hundred metres, is scaled
/// to fit (keeping its aspect ratio), with a scale bar.
const MAX_WIDTH_PX: f64 = 900.0;
const MAX_HEIGHT_PX: f64 = 800.0;
/// Blank border around the drawing [px] (the scale bar sits in the bottom one).
const MARGIN_PX: f64 = 30.0;

/// The SVG of one run on its map (see [`MapDrawing`] to draw many runs on one map).
pub fn trajectory_svg(
    map: &Map,
    recording: &Recording,
    metrics: &RunMetrics,
    vehicle: &VehicleParams,
) -> String {
    MapDrawing::new(map).trajectory_svg(recording, metrics, vehicle)
}

/// A map that runs are drawn on: the road of each frame is drawn once and reused by every run
/// drawn in the same frame (the runs of a folder mostly share one; threads share it too).
pub struct MapDrawing<'a> {
    map: &'a Map,
    /// The road layer per frame, by the frame's numbers' bits.
    roads: Mutex<Vec<([u64; 6], Arc<str>)>>,
}

/// Frames whose road is kept.
const ROADS_KEPT: usize = 8;

impl<'a> MapDrawing<'a> {
    /// Draws on `map`.
    pub fn new(map: &'a Map) -> Self {
        Self {
            map,
            roads: Mutex::new(Vec::new()),
        }
    }

    /// The lanelets' boundaries in `frame`, drawn once per frame.
    fn road(&self, frame: &Frame) -> Arc<str> {
        let key = frame.key();
        let mut roads = self
            .roads
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some((_, road)) = roads.iter().find(|(k, _)| *k == key) {
            return road.clone();
        }
        let mut road =
            String::from("<g class=\"lanelets\" fill=\"none\" stroke=\"#c8c8c8\" stroke-width=\"1\">\n");
        for lanelet in self.map.lanelets() {
            for boundary in [&lanelet.left_boundary, &lanelet.right_boundary] {
                let _ = writeln!(road, "<path d=\"{}\"/>", frame.path(&boundary.points));
            }
        }
        road.push_str("</g>\n");
        let road: Arc<str> = road.into();
        if roads.len() == ROADS_KEPT {
            roads.remove(0);
        }
        roads.push((key, road.clone()));
        road
    }

    /// The SVG of one run on the map.
    ///
    /// The recording is put on the metrics' time grid first (`metrics.config.sample_period_s`,
    /// its `rotate180`, and `metrics.num_samples` samples), so that the sample indices of
    /// `metrics` (pair events, violation samples) point at the drawn states. Indices outside
    /// the recording are skipped.
    pub fn trajectory_svg(
        &self,
        recording: &Recording,
        metrics: &RunMetrics,
        vehicle: &VehicleParams,
    ) -> String {
        let map = self.map;
        // Put the states in the metrics' frame and time grid.
        let states = metric_states(recording, metrics);
        let mut frame = Frame::new(map, &states);
        let lines = legend_lines(recording.agent_count(), frame.width_px - 2.0 * MARGIN_PX);
        frame.lower_by(LEGEND_LINE_PX * (lines.len() - 1) as f64);
        let mut out = open(frame.width_px, frame.height_px);
        let _ = writeln!(
            out,
            "<title>{} agents over {} samples; black cross and outlines: collision events; grey band and ring: \
             lane violations</title>",
            recording.agent_count(),
            states.len()
        );

        // The road, then each agent's reference path.
        out.push_str(&self.road(&frame));
        draw_run(
            &mut out, map, &frame, &states, recording, metrics, vehicle, &lines,
        );
        out
    }
}

/// Everything of a run's figure after the road: violations, reference paths, trajectories,
/// starts, collisions, legend and scale bar.
#[allow(clippy::too_many_arguments)]
fn draw_run(
    out: &mut String,
    map: &Map,
    frame: &Frame,
    states: &[Vec<AgentSample>],
    recording: &Recording,
    metrics: &RunMetrics,
    vehicle: &VehicleParams,
    lines: &[Vec<Entry>],
) {
    // Lane violations under everything an agent draws: a band along each episode.
    let episodes = violation_episodes(metrics);
    for &(agent, first, last) in &episodes {
        let points: Vec<Point> = (first..=last)
            .filter_map(|k| states.get(k).and_then(|row| row.get(agent)))
            .filter(|s| s.is_present())
            .map(|s| [s.x_m, s.y_m])
            .collect();
        if !points.is_empty() {
            let _ = writeln!(
                out,
                "<path class=\"violation-band\" data-agent=\"{agent}\" d=\"{}\" fill=\"none\" stroke=\"{VIOLATION_INK}\" \
                 stroke-opacity=\"0.25\" stroke-width=\"7\" stroke-linecap=\"round\" stroke-linejoin=\"round\"/>",
                frame.path(&points)
            );
        }
    }
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

    // Trajectories (over the samples each agent is present in) and start markers.
    for (agent, &ref_path) in recording.ref_paths.iter().enumerate() {
        let points: Vec<Point> = states
            .iter()
            .filter_map(|row| row.get(agent))
            .filter(|s| s.is_present())
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

    // Collision events over the trajectories, unfilled: the vehicles' outlines and a cross
    // between them.
    for event in &metrics.pair_events {
        let mut centres = Vec::new();
        for agent in event.agents {
            centres.extend(outline(out, frame, states, vehicle, (event.sample, agent)));
        }
        if let [(x0, y0), (x1, y1)] = centres[..] {
            let (x, y) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            let _ = writeln!(
                out,
                "<path class=\"collision-mark\" data-sample=\"{}\" d=\"M{} {} L{} {} M{} {} L{} {}\" \
                 stroke=\"{COLLISION_INK}\" stroke-width=\"2.5\"/>",
                event.sample,
                px(x - 5.0),
                px(y - 5.0),
                px(x + 5.0),
                px(y + 5.0),
                px(x - 5.0),
                px(y + 5.0),
                px(x + 5.0),
                px(y - 5.0)
            );
        }
    }
    // A hollow ring where each lane-violation episode starts.
    for &(agent, first, _) in &episodes {
        if let Some(s) = states
            .get(first)
            .and_then(|row| row.get(agent))
            .filter(|s| s.is_present())
        {
            let (cx, cy) = frame.to_px(s.x_m, s.y_m);
            let _ = writeln!(
                out,
                "<circle class=\"violation\" data-agent=\"{agent}\" data-sample=\"{first}\" cx=\"{}\" cy=\"{}\" r=\"5\" \
                 fill=\"none\" stroke=\"{VIOLATION_INK}\" stroke-width=\"1.5\"/>",
                px(cx),
                px(cy)
            );
        }
    }
    legend(out, lines);
    scale_bar(out, frame);
    out.push_str("</svg>\n");
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

/// Each lane-violation episode (consecutive violation samples of one agent) as `(agent,
/// first sample, last sample)`.
fn violation_episodes(metrics: &RunMetrics) -> Vec<(usize, usize, usize)> {
    let mut episodes = Vec::new();
    for (agent, a) in metrics.agents.iter().enumerate() {
        for &sample in &a.violation_samples {
            match episodes.last_mut() {
                Some((last_agent, _, last)) if *last_agent == agent && *last + 1 == sample => *last = sample,
                _ => episodes.push((agent, sample, sample)),
            }
        }
    }
    episodes
}

/// Draws one agent's footprint at one sample as an unfilled outline, and returns its centre
/// in pixels (nothing when either is out of range or the agent is absent then).
fn outline(
    out: &mut String,
    frame: &Frame,
    states: &[Vec<AgentSample>],
    vehicle: &VehicleParams,
    at: (usize, usize),
) -> Option<(f64, f64)> {
    let (sample, agent) = at;
    let s = states
        .get(sample)
        .and_then(|row| row.get(agent))
        .filter(|s| s.is_present())?;
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
        "<polygon class=\"collision\" data-agent=\"{agent}\" data-sample=\"{sample}\" points=\"{}\" \
         fill=\"none\" stroke=\"{COLLISION_INK}\" stroke-width=\"1.5\"/>",
        points.join(" ")
    );
    Some(frame.to_px(s.x_m, s.y_m))
}

/// Height of one line of the legend [px].
const LEGEND_LINE_PX: f64 = 16.0;

/// A mark the legend explains.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Entry {
    Agent(usize),
    Violation,
    Collision,
}

impl Entry {
    fn label(self) -> String {
        match self {
            Entry::Agent(agent) => format!("agent {agent}"),
            Entry::Violation => "lane violation (band: its stretch)".into(),
            Entry::Collision => "collision (vehicles outlined)".into(),
        }
    }

    /// Its width on a line [px]: a 20 px icon, the label (sans-serif at 11 px, about 6 px a
    /// character) and a gap.
    fn width_px(self) -> f64 {
        28.0 + 6.0 * self.label().chars().count() as f64 + 12.0
    }

    /// The icon, 20 px wide from `x`, centred on `y`, and the label.
    fn draw(self, out: &mut String, x: f64, y: f64) {
        let (y0, ty) = (px(y), px(y + 4.0));
        let _ = match self {
            Entry::Agent(agent) => write!(
                out,
                "<path d=\"M{} {y0} L{} {y0}\" stroke=\"{}\" stroke-width=\"3\"/>",
                px(x + 2.0),
                px(x + 18.0),
                colour(agent)
            ),
            Entry::Violation => write!(
                out,
                "<path d=\"M{} {y0} L{} {y0}\" stroke=\"{VIOLATION_INK}\" stroke-opacity=\"0.25\" stroke-width=\"7\" \
                 stroke-linecap=\"round\"/><circle cx=\"{}\" cy=\"{y0}\" r=\"5\" fill=\"none\" stroke=\"{VIOLATION_INK}\" \
                 stroke-width=\"1.5\"/>",
                px(x + 4.0),
                px(x + 18.0),
                px(x + 5.0)
            ),
            Entry::Collision => write!(
                out,
                "<path d=\"M{} {} L{} {} M{} {} L{} {}\" stroke=\"{COLLISION_INK}\" stroke-width=\"2.5\"/>",
                px(x + 5.0),
                px(y - 5.0),
                px(x + 15.0),
                px(y + 5.0),
                px(x + 5.0),
                px(y + 5.0),
                px(x + 15.0),
                px(y - 5.0)
            ),
        };
        let _ = writeln!(
            out,
            "<text x=\"{}\" y=\"{ty}\">{}</text>",
            px(x + 24.0),
            self.label()
        );
    }
}

/// The legend's entries (each agent's colour, up to the palette's length, then the event
/// marks) in lines no wider than `width_px`.
fn legend_lines(agents: usize, width_px: f64) -> Vec<Vec<Entry>> {
    let entries = (0..agents.min(AGENT_COLOURS.len()))
        .map(Entry::Agent)
        .chain([Entry::Violation, Entry::Collision]);
    let mut lines: Vec<Vec<Entry>> = vec![Vec::new()];
    let mut used_px = 0.0;
    for entry in entries {
        let line = lines.last_mut().expect("a line");
        if !line.is_empty() && used_px + entry.width_px() > width_px {
            lines.push(vec![entry]);
            used_px = entry.width_px();
        } else {
            line.push(entry);
            used_px += entry.width_px();
        }
    }
    lines
}

/// The legend in the top margin, one line under another.
fn legend(out: &mut String, lines: &[Vec<Entry>]) {
    out.push_str("<g class=\"legend\" font-size=\"11\">\n");
    for (n, line) in lines.iter().enumerate() {
        let y = MARGIN_PX / 2.0 + 2.0 + n as f64 * LEGEND_LINE_PX;
        let mut x = MARGIN_PX;
        for &entry in line {
            entry.draw(out, x, y);
            x += entry.width_px();
        }
    }
    out.push_str("</g>\n");
}

/// Map metres to SVG pixels, y up, scaled to fit the largest drawing.
struct Frame {
    bounds: Bounds,
    /// The top margin (the legend's lines) [px].
    top_px: f64,
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
            top_px: MARGIN_PX,
            scale_px_per_m,
            width_px: width_m * scale_px_per_m + 2.0 * MARGIN_PX,
            height_px: height_m * scale_px_per_m + 2.0 * MARGIN_PX,
        }
    }

    /// Room for `extra_px` more of the top margin: the drawing moves down, the frame grows.
    fn lower_by(&mut self, extra_px: f64) {
        self.top_px += extra_px;
        self.height_px += extra_px;
    }

    fn to_px(&self, x_m: f64, y_m: f64) -> (f64, f64) {
        (
            MARGIN_PX + (x_m - self.bounds.min_x_m) * self.scale_px_per_m,
            self.top_px + (self.bounds.max_y_m - y_m) * self.scale_px_per_m,
        )
    }

    fn path(&self, points: &[Point]) -> String {
        path_data(points.iter().map(|&[x, y]| self.to_px(x, y)))
    }

    /// The numbers that place map coordinates in the drawing, as bits: equal keys draw the
    /// same map the same way.
    fn key(&self) -> [u64; 6] {
        [
            self.bounds.min_x_m.to_bits(),
            self.bounds.max_x_m.to_bits(),
            self.bounds.min_y_m.to_bits(),
            self.bounds.max_y_m.to_bits(),
            self.top_px.to_bits(),
            self.scale_px_per_m.to_bits(),
        ]
    }
}

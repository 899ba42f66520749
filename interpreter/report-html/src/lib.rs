//! The run folder's `report.html`: one self-contained page (no network, no CDN; it works from
//! `file://` and as a CI artefact) with the summary tables, the paper's Figure 3 for every
//! initial configuration, replays of any run with the runs of the other fidelities side by
//! side in sync, the metric distributions and the learning curves of a training.
//!
//! Modules: `data` (the JSON the page draws from: map, runs decimated for display, Figure 3's
//! choices; snapshot-tested), `tables` (the summary as HTML tables). The page's style and
//! script are `assets/page.css` and `assets/replay.js`, embedded at build time.
//!
//! Like every renderer of cpmx this crate reads no file and runs no engine: the caller hands
//! it the summary, the map and the recordings. The output is a pure function of them.

mod data;
mod tables;

use std::fmt::Write as _;

use cpmx_recording::Recording;
use cpmx_report::{Metric, RunRecord, Summary, distribution_svg};
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

pub use data::page_data;

/// One run of the page: its record (plan, metrics) and its recording.
#[derive(Debug, Clone, Copy)]
pub struct PageRun<'a> {
    pub record: &'a RunRecord,
    pub recording: &'a Recording,
}

/// A learning curve of a training in the folder: `episode_reward_mean` per iteration.
#[derive(Debug, Clone, PartialEq)]
pub struct LearningCurve {
    /// What trained (e.g. the seed's folder name).
    pub name: String,
    pub iterations: Vec<f64>,
    pub episode_reward_mean: Vec<f64>,
}

/// Everything the page shows.
#[derive(Debug, Clone)]
pub struct Page<'a> {
    pub summary: &'a Summary,
    pub description: Option<&'a str>,
    pub map: &'a Map,
    pub vehicle: &'a VehicleParams,
    /// The runs, in matrix order.
    pub runs: Vec<PageRun<'a>>,
    pub learning_curves: Vec<LearningCurve>,
}

const STYLE: &str = include_str!("../assets/page.css");
const SCRIPT: &str = include_str!("../assets/replay.js");

/// The whole page.
pub fn report_html(page: &Page<'_>) -> String {
    let name = tables::escape(&page.summary.experiment);
    let mut out = format!(
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>cpmx: {name}</title>\n<style>\n{STYLE}</style>\n</head>\n<body>\n"
    );

    // The header and the table of contents.
    let units: usize = page.summary.groups.iter().map(|g| g.units).sum();
    let _ = writeln!(
        out,
        "<header><h1>{name}</h1>{}<p class=\"counts\">{} runs ({units} independent units), written by cpmx</p>\
         <nav><a href=\"#summary\">Summary</a> · <a href=\"#figure3\">Initial configurations</a> · \
         <a href=\"#replay\">Replay</a> · <a href=\"#runs\">Runs</a> · <a href=\"#distributions\">Distributions</a>{}</nav></header>",
        page.description
            .map(|d| format!("<p>{}</p>", tables::escape(d)))
            .unwrap_or_default(),
        page.runs.len(),
        if page.learning_curves.is_empty() {
            ""
        } else {
            " · <a href=\"#training\">Training</a>"
        }
    );

    // The tables.
    out.push_str("<section id=\"summary\"><h2>Summary</h2>\n");
    out.push_str(&tables::summary_tables(page.summary));
    out.push_str("</section>\n");

    // Figure 3, the replay and the run list are drawn by the script from the data.
    out.push_str(
        "<section id=\"figure3\"><h2>Initial configurations and representative runs</h2>\n\
         <p>For each initial configuration: the setup with each agent's reference path, then per row of the summary \
         (fidelity and policy unless the spec pools) the run whose CD is closest to that row's mean (as the \
         paper chooses its Figure 3). \
         Red: collision events; orange: lane violations.</p>\n<div id=\"figure3-body\"></div></section>\n\
         <section id=\"replay\"><h2>Replay</h2>\n<p>The runs of one policy, initial configuration and \
         repetition in every fidelity, in sync (the paired design). Choose a run in the table below.</p>\n\
         <div class=\"controls\"><button id=\"play\" type=\"button\">Play</button>\
         <input id=\"scrub\" type=\"range\" min=\"0\" max=\"0\" value=\"0\" aria-label=\"time\">\
         <label>speed <select id=\"speed\"><option>0.5</option><option selected>1</option><option>2</option>\
         <option>4</option><option>8</option></select>×</label> <span id=\"clock\">t = 0.0 s</span>\
         <span id=\"replay-title\"></span></div>\n<div id=\"replay-body\" class=\"panels\"></div></section>\n\
         <section id=\"runs\"><h2>Runs</h2><div id=\"runs-body\"></div></section>\n",
    );

    // Distributions, and the training's learning curves.
    let curves = cpmx_report::sensitivity_svgs(page.summary);
    if !curves.is_empty() {
        out.push_str(
            "<section id=\"sensitivity\"><h2>Sensitivity</h2>\n<p>Each metric against a swept \
             parameter: per line the other sweeps' values and the policy held fixed; points are a \
             row's mean over its independent units, bars its t 95 % interval.</p><div class=\"panels\">\n",
        );
        for (_, svg) in &curves {
            out.push_str(svg);
        }
        out.push_str("</div></section>\n");
    }
    out.push_str("<section id=\"distributions\"><h2>Metric distributions</h2><div class=\"panels\">\n");
    for metric in Metric::ALL {
        out.push_str("<figure>");
        out.push_str(&distribution_svg(page.summary, metric));
        out.push_str("</figure>\n");
    }
    out.push_str("</div></section>\n");
    if !page.learning_curves.is_empty() {
        out.push_str(
            "<section id=\"training\"><h2>Training</h2><p>episode_reward_mean per iteration.</p>\
             <canvas id=\"learning-curves\" width=\"900\" height=\"360\"></canvas></section>\n",
        );
    }

    // The data and the script.
    let json = page_data(page).to_string().replace("</", "<\\/");
    let _ = write!(
        out,
        "<script id=\"cpmx-data\" type=\"application/json\">{json}</script>\n<script>\n{SCRIPT}</script>\n</body>\n</html>\n"
    );
    out
}

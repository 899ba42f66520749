//! The run folder's `report.html`: one self-contained page (no network, no CDN; it works from
//! `file://` and as a CI artefact) with the summary tables, the paper's Figure 3 for every
//! initial configuration, replays of any run with the runs of the other fidelities side by
//! side in sync, the sensitivity curves of sweeps, the metric distributions and the learning
//! curves of a training. Figures share a grid that uses the page's width (three a row on a
//! wide screen, one on a phone), and every caption names the policies its figure shows.
//!
//! Modules: `data` (the JSON the page draws from: map, runs decimated for display, Figure 3's
//! choices; snapshot-tested), `tables` (the summary as HTML tables), `figures` (the SVG
//! figures and their captions). The page's style and script are `assets/page.css` and
//! `assets/replay.js` (the canvases: Figure 3, replays, learning curves), embedded at build
//! time.
//!
//! Like every renderer of cpmx this crate reads no file and runs no engine: the caller hands
//! it the summary, the map and the recordings. The output is a pure function of them.

mod data;
mod figures;
mod tables;

use std::fmt::Write as _;

use cpmx_recording::Recording;
use cpmx_report::{RunRecord, Summary};
use cpmx_vehicle::VehicleParams;
use cpmx_world::Map;

pub use data::{PageData, page_data};

/// One run of the page: its record (plan, metrics) and its recording.
#[derive(Debug, Clone, Copy)]
pub struct PageRun<'a> {
    pub record: &'a RunRecord,
    pub recording: &'a Recording,
    /// The run's map: its index in [`Page::maps`].
    pub map: usize,
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
    /// The maps the runs drive on: the spec's first, then those of configurations with their
    /// own.
    pub maps: Vec<&'a Map>,
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
    let sensitivity = cpmx_report::sensitivity_svgs(page.summary);
    let units: usize = page.summary.groups.iter().map(|g| g.units).sum();
    let _ = writeln!(
        out,
        "<header><h1>{name}</h1>{}<p class=\"counts\">{} runs ({units} independent units), written by cpmx</p>\
         <nav><a href=\"#summary\">Summary</a> · <a href=\"#figure3\">Initial configurations</a> · \
         <a href=\"#replay\">Replay</a> · <a href=\"#runs\">Runs</a> · {}<a href=\"#distributions\">Distributions</a>{}</nav></header>",
        page.description
            .map(|d| format!("<p>{}</p>", tables::escape(d)))
            .unwrap_or_default(),
        page.runs.len(),
        if sensitivity.is_empty() {
            ""
        } else {
            "<a href=\"#sensitivity\">Sensitivity</a> · "
        },
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
    let data = page_data(page);
    let thinned = if data.stride > 1 {
        format!(
            " Runs are drawn at one sample in {} of the metrics' grid: the page holds at most {} vehicle \
             samples (the metrics used every sample).",
            data.stride,
            data::REPLAY_BUDGET
        )
    } else {
        String::new()
    };
    out.push_str(&format!(
        "<section id=\"figure3\"><h2>Initial configurations and representative runs</h2>\n\
         <p>For each initial configuration: the setup with each agent's reference path, then per row of the summary \
         (fidelity and policy unless the spec pools) the run whose CD is closest to that row's mean (as the \
         paper chooses its Figure 3). \
         Agents take colour-blind-safe colours (Okabe and Ito's); lane violations and collision events are marked \
         in inks no agent takes, without hiding the trajectories.</p>\n\
         <div id=\"figure3-legend\" class=\"legend\"></div>\n<div id=\"figure3-body\"></div></section>\n\
         <section id=\"replay\"><h2>Replay</h2>\n<p>The runs of one policy, initial configuration and \
         repetition in every fidelity, in sync (the paired design). Choose a run in the table below.{thinned}</p>\n\
         <div class=\"controls\"><button id=\"play\" type=\"button\">Play</button>\
         <input id=\"scrub\" type=\"range\" min=\"0\" max=\"0\" value=\"0\" aria-label=\"time\">\
         <label>speed <select id=\"speed\"><option>0.5</option><option selected>1</option><option>2</option>\
         <option>4</option><option>8</option></select>×</label> <span id=\"clock\">t = 0.0 s</span>\
         <span id=\"replay-title\"></span></div>\n<div id=\"replay-legend\" class=\"legend\"></div>\n\
         <div id=\"replay-body\" class=\"panels\"></div></section>\n\
         <section id=\"runs\"><h2>Runs</h2><div id=\"runs-body\"></div></section>\n",
    ));

    // The sensitivity curves of sweeps, the distributions, and the training's learning curves.
    figures::sensitivity(&mut out, page.summary, &page.runs, &sensitivity);
    figures::distributions(&mut out, page.summary, &page.runs);
    if !page.learning_curves.is_empty() {
        let names: Vec<&str> = page.learning_curves.iter().map(|c| c.name.as_str()).collect();
        let _ = writeln!(
            out,
            "<section id=\"training\"><h2>Training</h2><div class=\"panels\"><figure class=\"panel full\">\
             <canvas id=\"learning-curves\" style=\"aspect-ratio: 2.5\"></canvas><figcaption>episode_reward_mean per \
             iteration of the policies this folder trained: {}</figcaption></figure></div></section>",
            tables::escape(&names.join(", "))
        );
    }

    // The data and the script.
    // Strings, numbers and arrays under string keys: serialising them cannot fail.
    let json = serde_json::to_string(&data)
        .expect("the page's data serialises")
        .replace("</", "<\\/");
    let _ = write!(
        out,
        "<script id=\"cpmx-data\" type=\"application/json\">{json}</script>\n<script>\n{SCRIPT}</script>\n</body>\n</html>\n"
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The quoted `#RRGGBB` colours of the script's line that starts with `start`.
    fn script_colours(start: &str) -> Vec<String> {
        let line = SCRIPT
            .lines()
            .map(str::trim)
            .find(|line| line.starts_with(start))
            .unwrap_or_else(|| panic!("the script has `{start}`"));
        line.split('"')
            .filter(|part| part.starts_with('#'))
            .map(str::to_uppercase)
            .collect()
    }

    #[test]
    fn the_script_draws_agents_and_events_in_the_plots_colours() {
        let upper = |colours: &[&str]| colours.iter().map(|c| c.to_uppercase()).collect::<Vec<_>>();
        let agents = script_colours("const COLOURS");
        assert_eq!(agents, upper(&cpmx_report::AGENT_COLOURS));
        let inks = script_colours("const COLLISION_INK");
        assert_eq!(
            inks,
            upper(&[cpmx_report::COLLISION_INK, cpmx_report::VIOLATION_INK])
        );
        assert!(
            inks.iter().all(|ink| !agents.contains(ink)),
            "no event ink is an agent's colour"
        );
    }
}

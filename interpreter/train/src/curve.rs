//! `learning_curve.csv` (one row per iteration) and its SVG.
//!
//! Columns: `iteration, samples, episode_reward_mean` (SigmaRL's: the mean return of the
//! episodes that ended in the iteration's batch, rounded to 2 decimals; empty when none
//! ended), `episodes`, `reward_<term>` (the mean of each reward term over the batch's
//! agent-steps, `reward_total` the clamped reward), `collisions` (agent-steps crossing another
//! agent or the road boundary, each counted per crossing), `env_resets`, `agent_resets`, for a
//! randomised fidelity `draws` (episodes whose parameters were drawn in the batch) and
//! `drawn_<parameter>` (the mean drawn value), the update's means over its minibatch steps
//! (`policy_loss, value_loss, entropy_loss,
//! grad_norm, clip_fraction`), `lr`, `best` (1 when the actor became the best one), wall
//! time `collect_s, update_s`, and the mean pre-tanh scale of the sampled actions
//! `action_scale_speed, action_scale_steering` (the policy's noise: it grows when a training
//! collapses), and with a safety layer in the fidelity `filtered` (agent-steps whose action
//! it changed; with vehicle stacks, of every rolled-out step) and `filter_fallbacks`
//! (agent-steps it had no answer for), and in a `control: trajectory` fidelity
//! `follower_stopped` (the 50 Hz periods in which the lab's follower stopped a vehicle once
//! commanded: a refused trajectory, a command too old, positioning lost). Everything but the wall times is the same on any machine and thread count. A
//! curve written before the scale columns existed gets them empty on a resume.

use std::fmt::Write as _;

use cpmx_learn::IterationRecord;

/// The CSV header line (without newline) for the reward terms `terms`
/// ([`crate::reward_term_names`]), the fidelity parameters drawn per episode `drawn` (none
/// unless the fidelity is randomised), when the fidelity `filters` its actions through a
/// safety layer its counts, and when its vehicles run the lab's follower (`follows`) its stops.
pub fn header(terms: &[&str], drawn: &[String], filters: bool, follows: bool) -> String {
    let mut h = String::from("iteration,samples,episode_reward_mean,episodes");
    for term in terms {
        let _ = write!(h, ",reward_{term}");
    }
    h.push_str(",collisions,env_resets,agent_resets");
    if !drawn.is_empty() {
        h.push_str(",draws");
        for name in drawn {
            let _ = write!(h, ",drawn_{name}");
        }
    }
    h.push_str(",policy_loss,value_loss,entropy_loss,grad_norm,clip_fraction,lr,best,collect_s,update_s");
    h.push_str(",action_scale_speed,action_scale_steering");
    if filters {
        h.push_str(",filtered,filter_fallbacks");
    }
    if follows {
        h.push_str(",follower_stopped");
    }
    h
}

/// One CSV row (without newline).
pub fn row(r: &IterationRecord) -> String {
    let mut s = format!("{},{},", r.iteration, r.samples);
    if r.episode_reward_mean.is_finite() {
        let _ = write!(s, "{:.2}", r.episode_reward_mean);
    }
    let _ = write!(s, ",{}", r.episodes);
    for v in &r.reward_term_means {
        let _ = write!(s, ",{v}");
    }
    let _ = write!(s, ",{},{},{}", r.collisions, r.env_resets, r.agent_resets);
    if !r.drawn_parameter_means.is_empty() {
        let _ = write!(s, ",{}", r.draws);
        for mean in &r.drawn_parameter_means {
            s.push(',');
            if mean.is_finite() {
                let _ = write!(s, "{mean}");
            }
        }
    }
    let _ = write!(
        s,
        ",{},{},{},{},{},{},{},{:.3},{:.3}",
        r.policy_loss,
        r.value_loss,
        r.entropy_loss,
        r.grad_norm,
        r.clip_fraction,
        r.lr,
        u8::from(r.best),
        r.collect_seconds,
        r.update_seconds
    );
    let _ = write!(s, ",{},{}", r.action_scale_means[0], r.action_scale_means[1]);
    if let Some(f) = &r.filter {
        let _ = write!(s, ",{},{}", f.changed, f.fallbacks);
    }
    if let Some(stopped) = r.follower_stopped {
        let _ = write!(s, ",{stopped}");
    }
    s
}

/// The rows of a learning curve file up to and including iteration `last` (what a checkpoint
/// of iteration `last` continues from), header first. Rows after it (written before a kill
/// that came before their checkpoint) are dropped.
/// A row with fewer columns than `header` (written before the last columns existed) gets them
/// empty.
pub fn rows_through(text: &str, last: u64, header: String) -> Vec<String> {
    let columns = header.split(',').count();
    let mut lines = vec![header];
    lines.extend(
        text.lines()
            .skip(1)
            .filter(|line| iteration_of(line).is_some_and(|k| k <= last))
            .map(|line| {
                let missing = columns.saturating_sub(line.split(',').count());
                format!("{line}{}", ",".repeat(missing))
            }),
    );
    lines
}

fn iteration_of(line: &str) -> Option<u64> {
    line.split(',').next()?.parse().ok()
}

/// `(iteration, episode_reward_mean)` of every row that has a reward.
pub fn reward_points(text: &str) -> Vec<(f64, f64)> {
    text.lines()
        .skip(1)
        .filter_map(|line| {
            let mut fields = line.split(',');
            let k: f64 = fields.next()?.parse().ok()?;
            let reward: f64 = fields.nth(1)?.parse().ok()?;
            Some((k, reward))
        })
        .collect()
}

/// `(iteration, value)` of `column` (found by its header) in every row where it is a number;
/// empty when the curve has no such column.
pub fn column_points(text: &str, column: &str) -> Vec<(f64, f64)> {
    let mut lines = text.lines();
    let Some(index) = lines
        .next()
        .and_then(|header| header.split(',').position(|c| c == column))
    else {
        return Vec::new();
    };
    lines
        .filter_map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            Some((fields.first()?.parse().ok()?, fields.get(index)?.parse().ok()?))
        })
        .collect()
}

/// `(iteration, episode_reward_mean)` of the last row marked `best`.
pub fn last_best(text: &str) -> Option<(u64, f64)> {
    let mut lines = text.lines();
    let best = lines.next()?.split(',').position(|c| c == "best")?;
    lines.rev().find_map(|line| {
        let fields: Vec<&str> = line.split(',').collect();
        (fields.get(best) == Some(&"1")).then(|| Some((fields[0].parse().ok()?, fields[2].parse().ok()?)))?
    })
}

/// A curve of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    /// Legend text.
    pub name: String,
    /// `(iteration, value)`: `episode_reward_mean` unless the chart says otherwise.
    pub points: Vec<(f64, f64)>,
}

/// Ten distinct colours (matplotlib's tab10, in an order that keeps the first ones apart).
const COLOURS: [&str; 10] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
    "#17becf",
];

/// A line chart of `episode_reward_mean` over iterations, one line per series.
pub fn svg(title: &str, series: &[Series]) -> String {
    column_svg(title, "episode_reward_mean", series)
}

/// A line chart of a learning-curve column (`y_label`, e.g. `collisions`) over iterations, one
/// line per series.
pub fn column_svg(title: &str, y_label: &str, series: &[Series]) -> String {
    let (w, h) = (720.0, 380.0);
    let (left, right, top, bottom) = (64.0, 160.0, 36.0, 48.0);
    let all = series.iter().flat_map(|s| s.points.iter());
    let (mut x_max, mut y_min, mut y_max) = (1.0f64, f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y) in all {
        x_max = x_max.max(x);
        y_min = y_min.min(y);
        y_max = y_max.max(y);
    }
    if !y_min.is_finite() {
        (y_min, y_max) = (-1.0, 1.0);
    }
    let y_step = nice_step((y_max - y_min).max(0.1) / 5.0);
    let (y_lo, y_hi) = (
        (y_min / y_step).floor() * y_step,
        (y_max / y_step).ceil() * y_step,
    );
    let y_hi = if y_hi <= y_lo { y_lo + y_step } else { y_hi };
    let x_step = nice_step(x_max / 6.0).max(1.0);
    let x_hi = (x_max / x_step).ceil() * x_step;
    let (pw, ph) = (w - left - right, h - top - bottom);
    let px = |x: f64| left + (x / x_hi) * pw;
    let py = |y: f64| top + (1.0 - (y - y_lo) / (y_hi - y_lo)) * ph;
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n\
         <text x=\"{left}\" y=\"22\" font-size=\"14\">{}</text>\n",
        escape(title)
    );
    let mut y = y_lo;
    while y <= y_hi + y_step * 1e-6 {
        let v = py(y);
        let _ = writeln!(
            s,
            "<line x1=\"{left}\" y1=\"{v:.1}\" x2=\"{:.1}\" y2=\"{v:.1}\" stroke=\"#ddd\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{}</text>",
            left + pw,
            left - 6.0,
            v + 4.0,
            trim(y)
        );
        y += y_step;
    }
    let mut x = 0.0;
    while x <= x_hi + 1e-9 {
        let u = px(x);
        let _ = writeln!(
            s,
            "<line x1=\"{u:.1}\" y1=\"{:.1}\" x2=\"{u:.1}\" y2=\"{:.1}\" stroke=\"#999\"/>\
             <text x=\"{u:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>",
            top + ph,
            top + ph + 5.0,
            top + ph + 18.0,
            trim(x)
        );
        x += x_step;
    }
    let _ = writeln!(
        s,
        "<rect x=\"{left}\" y=\"{top}\" width=\"{pw}\" height=\"{ph}\" fill=\"none\" stroke=\"#333\"/>\n\
         <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">iteration</text>\n\
         <text transform=\"translate(16 {:.1}) rotate(-90)\" text-anchor=\"middle\">{y_label}</text>",
        left + pw / 2.0,
        h - 10.0,
        top + ph / 2.0
    );
    for (i, curve) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        let points: Vec<String> = curve
            .points
            .iter()
            .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
            .collect();
        let _ = writeln!(
            s,
            "<polyline fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\" points=\"{}\"/>\n\
             <line x1=\"{:.1}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"{colour}\" stroke-width=\"3\"/>\
             <text x=\"{:.1}\" y=\"{:.1}\">{}</text>",
            points.join(" "),
            left + pw + 12.0,
            top + 10.0 + 18.0 * i as f64,
            left + pw + 30.0,
            top + 10.0 + 18.0 * i as f64,
            left + pw + 36.0,
            top + 14.0 + 18.0 * i as f64,
            escape(&curve.name)
        );
    }
    s.push_str("</svg>\n");
    s
}

/// 1, 2 or 5 times a power of ten, at least `raw`.
fn nice_step(raw: f64) -> f64 {
    let power = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * power)
}

fn trim(v: f64) -> String {
    let text = format!("{v:.2}");
    let text = text.trim_end_matches('0').trim_end_matches('.');
    if text == "-0" { "0".into() } else { text.into() }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_column_is_found_by_its_header() {
        let text = "iteration,samples,episode_reward_mean,collisions\n1,10,-0.5,7\n2,20,0.25,x\n3,30,0.5,4\n";
        assert_eq!(column_points(text, "collisions"), [(1.0, 7.0), (3.0, 4.0)]);
        assert_eq!(column_points(text, "episode_reward_mean"), reward_points(text));
        assert!(column_points(text, "missing").is_empty());
    }

    use super::*;

    fn record(k: u64, reward: f64) -> IterationRecord {
        IterationRecord {
            iteration: k,
            samples: 64 * k,
            episode_reward_mean: reward,
            episodes: 2,
            reward_term_means: vec![0.01, -0.002, 0.0, -0.5, 0.0, 0.008],
            collisions: 3,
            env_resets: 2,
            agent_resets: 1,
            draws: 0,
            drawn_parameter_means: Vec::new(),
            policy_loss: -0.01,
            value_loss: 0.2,
            entropy_loss: -0.001,
            grad_norm: 1.5,
            clip_fraction: 0.1,
            lr: 1e-4,
            best: k == 1,
            collect_seconds: 0.25,
            update_seconds: 0.5,
            action_scale_means: [0.75, 1.5],
            filter: None,
            follower_stopped: None,
        }
    }

    #[test]
    fn rows_have_the_headers_columns_and_read_back() {
        let terms = [
            "progress",
            "near_boundary",
            "near_agents_ttc",
            "collide_agents",
            "collide_boundary",
            "total",
        ];
        let columns = header(&terms, &[], false, false).split(',').count();
        let text = format!(
            "{}\n{}\n{}\n",
            header(&terms, &[], false, false),
            row(&record(1, -0.25)),
            row(&record(2, f64::NAN))
        );
        for line in text.lines() {
            assert_eq!(line.split(',').count(), columns, "{line}");
        }
        assert_eq!(reward_points(&text), vec![(1.0, -0.25)]);
        assert_eq!(last_best(&text), Some((1, -0.25)));
        assert_eq!(rows_through(&text, 1, header(&terms, &[], false, false)).len(), 2);
        assert_eq!(rows_through(&text, 5, header(&terms, &[], false, false)).len(), 3);
        assert!(text.lines().nth(1).unwrap().ends_with(",0.75,1.5"));
        // A curve written before the scale columns: resumed, its rows get them empty.
        let old: String = text
            .lines()
            .map(|l| l.rsplitn(3, ',').last().unwrap().to_owned() + "\n")
            .collect();
        let resumed = rows_through(&old, 5, header(&terms, &[], false, false));
        assert!(resumed[1].ends_with(",,"), "{}", resumed[1]);
        assert!(resumed.iter().all(|l| l.split(',').count() == columns));
        // A randomised fidelity adds the draws and a column per drawn parameter.
        let drawn = ["actuation.delay_ms".to_owned()];
        let randomised = IterationRecord {
            draws: 4,
            drawn_parameter_means: vec![81.5],
            ..record(3, 0.5)
        };
        let (h, r) = (header(&terms, &drawn, false, false), row(&randomised));
        assert!(
            h.contains(",agent_resets,draws,drawn_actuation.delay_ms,policy_loss,"),
            "{h}"
        );
        assert!(r.contains(",2,1,4,81.5,-0.01,"), "{r}");
        assert_eq!(h.split(',').count(), r.split(',').count());
    }

    #[test]
    fn the_chart_draws_every_series() {
        let series = [
            Series {
                name: "seed 1".into(),
                points: vec![(1.0, -0.5), (2.0, 0.1), (3.0, 0.2)],
            },
            Series {
                name: "seed <2>".into(),
                points: vec![(1.0, -0.1)],
            },
        ];
        let svg = svg("learning", &series);
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("seed &lt;2&gt;"));
        assert!(svg.ends_with("</svg>\n"));
    }

    #[test]
    fn steps_are_round_numbers() {
        assert_eq!(nice_step(0.13), 0.2);
        assert_eq!(nice_step(170.0), 200.0);
        assert_eq!(nice_step(3.0), 5.0);
    }
}

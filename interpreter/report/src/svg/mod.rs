//! Plots as hand-written SVG text: the map with each agent's trajectory (`trajectory`), the
//! per-run distribution of a metric per group (`distribution`), a metric against a swept
//! parameter (`sensitivity`), and their value axis (`axis`).
//!
//! This module owns the SVG helpers (number format, colours, escaping). Agents, groups and
//! lines take Okabe–Ito's colour-blind-safe colours; events (collisions, lane violations) are
//! drawn in black and grey, which no agent takes. Every drawing has a `viewBox`, so a page
//! scales it to any width. Coordinates are written with one decimal of a pixel, so the bytes
//! are stable; no fonts are embedded (text uses the viewer's sans-serif).

use std::fmt::Write as _;

mod axis;
mod distribution;
mod sensitivity;
mod trajectory;

pub use distribution::distribution_svg;
pub use sensitivity::{SensitivityPlot, sensitivity_svgs};
pub use trajectory::{MapDrawing, trajectory_svg};

/// Agent and group colours: Okabe–Ito's without black (as `cpmx-env`'s `render.rs` draws
/// agents), distinguishable with every common colour-vision deficiency; cycled. `report.html`'s
/// script draws agents in the same colours (a test of `cpmx-report-html` keeps them equal).
pub const AGENT_COLOURS: [&str; 7] = [
    "#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442",
];

/// The ink of collision marks (no agent's colour).
pub const COLLISION_INK: &str = "#000000";
/// The ink of lane-violation marks (no agent's colour).
pub const VIOLATION_INK: &str = "#404040";

/// The colour of agent or group `index`.
fn colour(index: usize) -> &'static str {
    AGENT_COLOURS[index % AGENT_COLOURS.len()]
}

/// A pixel coordinate with one decimal (`-0.0` written as `0.0`).
fn px(value: f64) -> String {
    let mut text = String::new();
    push_px(&mut text, value);
    text
}

/// Appends [`px`]`(value)` to `out`: the text of `format!("{value:.1}")` (with `-0.0` written
/// as `0.0`), written from the rounded tenths where they are certain. `value · 10` is within
/// half an ulp of the exact tenths, so unless its fraction lies within 1e-6 of one half (or the
/// value is huge or not finite) it rounds as the exact decimal does; those cases go to `format!`.
/// A figure writes tens of thousands of coordinates; formatting each through `fmt` was a
/// twentieth of a sim run's whole process.
fn push_px(out: &mut String, value: f64) {
    let tenths = value * 10.0;
    let fraction = tenths - tenths.floor();
    let certain = tenths.is_finite() && tenths.abs() < 1e12 && (fraction - 0.5).abs() >= 1e-6;
    if !certain {
        let text = format!("{value:.1}");
        out.push_str(if text == "-0.0" { "0.0" } else { &text });
        return;
    }
    let rounded = tenths.round() as i64;
    if rounded < 0 {
        out.push('-');
    }
    let magnitude = rounded.unsigned_abs();
    let _ = write!(out, "{}.{}", magnitude / 10, magnitude % 10);
}

/// Text with XML's special characters escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The opening `<svg>` tag of a `width_px` x `height_px` drawing with a white background.
fn open(width_px: f64, height_px: f64) -> String {
    let (w, h) = (px(width_px), px(height_px));
    format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
         font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"{w}\" height=\"{h}\" fill=\"white\"/>\n"
    )
}

/// A round length for a scale bar: the largest 1, 2 or 5 × 10^k m not above `at_most_m`.
fn round_length_m(at_most_m: f64) -> f64 {
    if !(at_most_m.is_finite() && at_most_m > 0.0) {
        return 1.0;
    }
    let power = 10f64.powf(at_most_m.log10().floor());
    [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * power)
        .find(|&length| length <= at_most_m * (1.0 + 1e-9))
        .unwrap_or(power)
}

/// `50 cm`, `1 m`, `200 m`, `2 km`.
fn length_label(length_m: f64) -> String {
    if length_m >= 1000.0 {
        format!("{} km", length_m / 1000.0)
    } else if length_m >= 1.0 {
        format!("{length_m} m")
    } else {
        format!("{} cm", (length_m * 100.0).round())
    }
}

/// A path through `points` (`M x y L x y ...`); empty for no points.
fn path_data(points: impl IntoIterator<Item = (f64, f64)>) -> String {
    let mut d = String::new();
    for (i, (x, y)) in points.into_iter().enumerate() {
        if i > 0 {
            d.push(' ');
        }
        d.push(if i == 0 { 'M' } else { 'L' });
        push_px(&mut d, x);
        d.push(' ');
        push_px(&mut d, y);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helpers_write_stable_text() {
        assert_eq!(px(-0.04), "0.0");
        assert_eq!(px(12.345), "12.3");
        assert_eq!(path_data([(0.0, 1.0), (2.0, 3.0)]), "M0.0 1.0 L2.0 3.0");
        assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
        assert_eq!(colour(8), colour(1));
        assert!(!AGENT_COLOURS.contains(&COLLISION_INK) && !AGENT_COLOURS.contains(&VIOLATION_INK));
    }

    /// What `px` wrote before its fast path: `format!` with one decimal.
    fn px_by_format(value: f64) -> String {
        let text = format!("{value:.1}");
        if text == "-0.0" { "0.0".into() } else { text }
    }

    #[test]
    fn px_writes_what_format_writes_at_ties_and_edges() {
        for value in [
            0.05,
            0.15,
            0.25,
            0.35,
            -0.05,
            -0.25,
            2.45,
            1e11,
            -1e11,
            1e12,
            1e13,
            1e300,
            -0.0,
            0.0,
            f64::MIN_POSITIVE,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            123.45,
            99.95,
            -99.95,
        ] {
            assert_eq!(px(value), px_by_format(value), "{value:e}");
        }
    }

    proptest::proptest! {
        #[test]
        fn px_writes_what_format_writes(
            pixel in -5000.0f64..5000.0,
            bits in proptest::num::u64::ANY,
            tenth in -100_000i64..100_000,
        ) {
            proptest::prop_assert_eq!(px(pixel), px_by_format(pixel));
            let any = f64::from_bits(bits);
            proptest::prop_assert_eq!(px(any), px_by_format(any));
            // Values near a tie of the tenths (x.x5).
            let near = (tenth as f64 + 0.5) / 10.0;
            for value in [near, near.next_up(), near.next_down()] {
                proptest::prop_assert_eq!(px(value), px_by_format(value));
            }
        }
    }

    #[test]
    fn scale_bars_have_round_lengths() {
        assert_eq!(round_length_m(0.9), 0.5);
        assert_eq!(round_length_m(1.0), 1.0);
        assert_eq!(round_length_m(84.0), 50.0);
        assert_eq!(round_length_m(190.0), 100.0);
        assert_eq!(round_length_m(0.25), 0.2);
        assert_eq!(length_label(0.5), "50 cm");
        assert_eq!(length_label(200.0), "200 m");
        assert_eq!(length_label(2000.0), "2 km");
    }
}

//! The value axis of the plots (distributions, sensitivity curves): the range of the values
//! padded by 5 %, and for a constant (a metric that is zero in every run, say) the range from
//! zero to it, so a flat sample shows flat at its true size, never on an axis of ±0.001;
//! tick labels at round values with light grid lines.

use std::fmt::Write;

use super::px;
use crate::table::fixed;

/// A vertical value range drawn from `top_px` down over `height_px`.
pub(super) struct Axis {
    pub low: f64,
    pub high: f64,
    /// The one value of every point, when there is exactly one.
    pub constant: Option<f64>,
    pub top_px: f64,
    pub height_px: f64,
}

impl Axis {
    /// The axis of every finite value of `values`.
    pub fn of(values: impl IntoIterator<Item = f64>, top_px: f64, height_px: f64) -> Axis {
        let (low, high) = values
            .into_iter()
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(v), h.max(v))
            });
        Axis::around(low, high, top_px, height_px)
    }

    /// The axis of values from `low` to `high` (`low > high`: no value): their range padded
    /// by 5 %; a constant from zero to it; zero or no value [0, 1].
    pub fn around(low: f64, high: f64, top_px: f64, height_px: f64) -> Axis {
        let constant = (low == high).then_some(low);
        let (low, high) = if low > high {
            (0.0, 1.0)
        } else if low == high {
            match low {
                0.0 => (0.0, 1.0),
                v => (v.min(0.0), v.max(0.0)),
            }
        } else {
            (low, high)
        };
        let pad = 0.05 * (high - low);
        Axis {
            low: low - pad,
            high: high + pad,
            constant,
            top_px,
            height_px,
        }
    }

    /// The pixel row of `value`.
    pub fn to_px(&self, value: f64) -> f64 {
        self.top_px + self.height_px * (self.high - value) / (self.high - self.low)
    }

    /// The axis line at `left_px`, and tick labels left of it with light grid lines to
    /// `right_px` at round values (`font_size` px).
    pub fn draw(&self, out: &mut String, left_px: f64, right_px: f64, font_size: u32) {
        let _ = writeln!(
            out,
            "<line class=\"axis\" x1=\"{x}\" y1=\"{}\" x2=\"{x}\" y2=\"{}\" stroke=\"black\"/>",
            px(self.top_px),
            px(self.top_px + self.height_px),
            x = px(left_px)
        );
        let (step, decimals) = nice_step((self.high - self.low) / 5.0);
        let first = (self.low / step).ceil();
        for k in 0..12 {
            let value = (first + k as f64) * step;
            if value > self.high {
                break;
            }
            let y = px(self.to_px(value));
            let _ = writeln!(
                out,
                "<line x1=\"{}\" y1=\"{y}\" x2=\"{}\" y2=\"{y}\" stroke=\"#e0e0e0\"/>\
                 <text class=\"tick\" x=\"{}\" y=\"{y}\" text-anchor=\"end\" dominant-baseline=\"middle\" \
                 font-size=\"{font_size}\">{}</text>",
                px(left_px),
                px(right_px),
                px(left_px - 6.0),
                fixed(value, decimals)
            );
        }
    }

    /// `every run: 0.00` (or what `what` names) at the right end of a line at `y_px`, when
    /// every value is the same.
    pub fn note_constant(&self, out: &mut String, what: &str, decimals: usize, right_px: f64, y_px: f64) {
        if let Some(value) = self.constant {
            let _ = writeln!(
                out,
                "<text class=\"constant\" x=\"{}\" y=\"{}\" text-anchor=\"end\" font-size=\"11\" font-weight=\"bold\">\
                 {what}: {}</text>",
                px(right_px),
                px(y_px),
                fixed(value, decimals)
            );
        }
    }
}

/// The smallest step of the form {1, 2, 5} x 10^k (k from -12) that is at least `raw`,
/// with the decimals it needs.
fn nice_step(raw: f64) -> (f64, usize) {
    for exponent in -12i32..=15 {
        for multiple in [1, 2, 5] {
            // Parsing gives the correctly rounded value of the decimal, with no accumulated error.
            let step: f64 = format!("{multiple}e{exponent}").parse().unwrap_or(f64::INFINITY);
            if step >= raw {
                return (step, (-exponent).max(0) as usize);
            }
        }
    }
    (raw.max(1e15), 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_values_get_an_axis_of_their_size() {
        let range = |low, high| {
            let a = Axis::around(low, high, 0.0, 100.0);
            (a.low, a.high)
        };
        // Zero everywhere, and no value at all: [0, 1] (padded).
        assert_eq!(range(0.0, 0.0), (-0.05, 1.05));
        assert_eq!(range(f64::INFINITY, f64::NEG_INFINITY), (-0.05, 1.05));
        // A constant: from zero to it.
        let (low, high) = range(0.4, 0.4);
        assert!(
            (low + 0.02).abs() < 1e-12 && (high - 0.42).abs() < 1e-12,
            "{low} {high}"
        );
        let (low, high) = range(-2.0, -2.0);
        assert!(
            (low + 2.1).abs() < 1e-12 && (high - 0.1).abs() < 1e-12,
            "{low} {high}"
        );
        // Varying values: their range, padded.
        let (low, high) = range(1.0, 3.0);
        assert!((low - 0.9).abs() < 1e-12 && (high - 3.1).abs() < 1e-12);
        let axis = |low, high| Axis::around(low, high, 0.0, 100.0);
        assert_eq!(axis(0.0, 0.0).constant, Some(0.0));
        assert_eq!(axis(1.0, 3.0).constant, None);
        assert_eq!(axis(f64::INFINITY, f64::NEG_INFINITY).constant, None);
        assert_eq!(Axis::of([f64::NAN, 2.0, 2.0], 0.0, 100.0).constant, Some(2.0));
        // Pixels: the top of the range at the top.
        let a = Axis::of([0.0, 1.0], 10.0, 100.0);
        assert!((a.to_px(a.high) - 10.0).abs() < 1e-12 && (a.to_px(a.low) - 110.0).abs() < 1e-12);
    }

    #[test]
    fn steps_are_round() {
        assert_eq!(nice_step(2.3), (5.0, 0));
        assert_eq!(nice_step(0.0013).1, 3);
        assert!((nice_step(0.0013).0 - 0.002).abs() < 1e-15);
        assert_eq!(nice_step(0.0), (1e-12, 12));
        assert_eq!(nice_step(f64::NAN).1, 0);
    }
}

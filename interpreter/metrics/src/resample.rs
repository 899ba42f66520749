//! Resampling a recording to the metrics' sample period.
//!
//! This module owns the time grid of the metrics: a recording already on the grid is used
//! untouched (so reference cases stay exact); any other is interpolated linearly
//! (position, velocity, steering) and along the shortest arc (yaw).

use std::borrow::Cow;

use cpmx_recording::{AgentSample, Recording};

/// Relative tolerance (of the period) within which a sample time counts as on the grid.
pub const ON_GRID_TOLERANCE: f64 = 1e-6;

/// The recording on the grid `times_s[0] + k · period_s` (k = 0, 1, … up to the last sample
/// time): borrowed unchanged when every sample already lies on that grid, else interpolated.
///
/// Expects strictly increasing times and one entry per agent in every row (the caller checks).
pub fn resample(recording: &Recording, period_s: f64) -> Cow<'_, Recording> {
    let times = &recording.times_s;
    let Some(&start_s) = times.first() else {
        return Cow::Borrowed(recording);
    };
    let on_grid = times
        .iter()
        .enumerate()
        .all(|(k, &t)| (t - (start_s + k as f64 * period_s)).abs() <= ON_GRID_TOLERANCE * period_s);
    if on_grid {
        return Cow::Borrowed(recording);
    }

    // Grid times up to the last sample (a grid point within tolerance of it is kept).
    let end_s = times[times.len() - 1];
    let count = ((end_s - start_s) / period_s + ON_GRID_TOLERANCE).floor() as usize + 1;
    let mut out = Recording {
        notes: recording.notes.clone(),
        latency_s: recording.latency_s.clone(),
        statistics: Default::default(),
        times_s: Vec::with_capacity(count),
        ref_paths: recording.ref_paths.clone(),
        samples: Vec::with_capacity(count),
    };
    let mut upper = 1;
    for k in 0..count {
        let t_s = (start_s + k as f64 * period_s).min(end_s);
        // First recorded time at or after t_s (times are increasing).
        while upper < times.len() - 1 && times[upper] < t_s {
            upper += 1;
        }
        let row = if times.len() == 1 {
            recording.samples[0].clone()
        } else {
            let (t0, t1) = (times[upper - 1], times[upper]);
            let w = ((t_s - t0) / (t1 - t0)).clamp(0.0, 1.0);
            let (r0, r1) = (&recording.samples[upper - 1], &recording.samples[upper]);
            r0.iter().zip(r1).map(|(a, b)| interpolate(a, b, w)).collect()
        };
        out.times_s.push(t_s);
        out.samples.push(row);
    }
    Cow::Owned(out)
}

/// `a + w (b − a)`, with the yaw turned along the shortest arc.
fn interpolate(a: &AgentSample, b: &AgentSample, w: f64) -> AgentSample {
    let lerp = |x: f64, y: f64| x + w * (y - x);
    let turn = (b.yaw_rad - a.yaw_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    AgentSample {
        x_m: lerp(a.x_m, b.x_m),
        y_m: lerp(a.y_m, b.y_m),
        yaw_rad: a.yaw_rad + w * turn,
        velocity_mps: [
            lerp(a.velocity_mps[0], b.velocity_mps[0]),
            lerp(a.velocity_mps[1], b.velocity_mps[1]),
        ],
        steering_rad: lerp(a.steering_rad, b.steering_rad),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x_m: f64, yaw_rad: f64) -> AgentSample {
        AgentSample {
            x_m,
            y_m: 0.0,
            yaw_rad,
            velocity_mps: [x_m, 0.0],
            steering_rad: f64::NAN,
        }
    }

    #[test]
    fn a_recording_on_the_grid_is_borrowed() {
        let r = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: vec![0.0, 0.1, 0.2 + 1e-12],
            ref_paths: vec![0],
            samples: vec![
                vec![sample(0.0, 0.0)],
                vec![sample(1.0, 0.0)],
                vec![sample(2.0, 0.0)],
            ],
        };
        assert!(matches!(resample(&r, 0.1), Cow::Borrowed(_)));
    }

    #[test]
    fn a_coarse_recording_is_interpolated_with_yaw_on_the_short_arc() {
        let r = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: vec![0.0, 0.2],
            ref_paths: vec![0],
            samples: vec![vec![sample(0.0, 3.0)], vec![sample(2.0, -3.0)]],
        };
        let out = resample(&r, 0.1);
        assert_eq!(out.times_s.len(), 3);
        let mid = out.samples[1][0];
        assert!((mid.x_m - 1.0).abs() < 1e-12);
        // Half-way from 3 rad to -3 rad through ±π, not through 0.
        let expected = 3.0 + (std::f64::consts::TAU - 6.0) / 2.0;
        assert!((mid.yaw_rad - expected).abs() < 1e-12);
        assert!(mid.steering_rad.is_nan());
        assert_eq!(out.samples[2][0].x_m, 2.0);
    }
}

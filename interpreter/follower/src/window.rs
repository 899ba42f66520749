//! The MPC's reference window as the lab builds it (`interpolate_reference_trajectory`,
//! `MpcController.cxx:351-471`): the six sample times in integer nanoseconds, the checks of a
//! trajectory against them, and the samples with the lab's acceleration and curvature checks.
//!
//! This module owns when the reference is sampled and which references are refused. It does
//! not optimise or keep history; `mpc.rs` does.
//!
//! Time as the lab keeps it: the window starts `delay_steps` control periods and one MPC step
//! after `t_now` and its sample `i` lies `i` MPC steps later. The lab writes these as
//! `uint64_t t_start = t_now + 3 * (dt_control_loop * 1e9) + (dt_MPC * 1e9)` (`:366`),
//! `t_end = t_start + 5 * (dt_MPC * 1e9)` (`:367`) and `t_start + i * (dt_MPC * 1e9)` (`:404`):
//! the stamps and step counts are converted to `double`, added, and the sum truncated back to
//! nanoseconds. [`prediction_window_ns`] and [`sample_time_ns`] evaluate exactly these
//! expressions. Below 2⁵³ ns (104 days) every term is exact, so the times are whole-nanosecond
//! sums (`t_now + 110 ms`, `t_now + 360 ms`); on the lab's wall clock they round to the
//! double grid as the lab's do. The trajectory's first and last point are then compared with
//! them as integers (`:376`: refused when `t_first >= t_start`; `:387`: refused when
//! `t_last < t_end`), so a first point exactly 110 ms ahead is refused and a last point exactly
//! 360 ms ahead is accepted, at any time.

use crate::mpc::{MpcConfig, PREDICTION_STEPS, Rejection};
use crate::trajectory::{Trajectory, TrajectorySample};

/// The first and last sample times of the prediction window at `t_now_ns`, as the lab
/// computes them (`MpcController.cxx:366-367`) [ns].
pub fn prediction_window_ns<const NU: usize>(t_now_ns: u64, config: &MpcConfig<NU>) -> (u64, u64) {
    let control_period_ns = config.control_period_s * 1e9;
    let mpc_step_ns = config.mpc_step_s * 1e9;
    // `as` truncates toward zero as C++'s conversion to uint64_t does (and saturates where
    // C++ is undefined).
    let start_ns = (t_now_ns as f64 + config.delay_steps as f64 * control_period_ns + mpc_step_ns) as u64;
    let end_ns = (start_ns as f64 + (PREDICTION_STEPS - 1) as f64 * mpc_step_ns) as u64;
    (start_ns, end_ns)
}

/// The time of sample `i` of a window starting at `start_ns`, as the lab computes it
/// (`MpcController.cxx:404`) [ns].
pub fn sample_time_ns<const NU: usize>(start_ns: u64, i: usize, config: &MpcConfig<NU>) -> u64 {
    (start_ns as f64 + i as f64 * (config.mpc_step_s * 1e9)) as u64
}

/// The six reference samples of `trajectory` for a decision at `t_now_ns`, or the lab's
/// reason to refuse it, checked in the lab's order.
pub(crate) fn reference_window<const NU: usize>(
    t_now_ns: u64,
    trajectory: &Trajectory,
    config: &MpcConfig<NU>,
) -> Result<[TrajectorySample; PREDICTION_STEPS], Rejection> {
    let c = config;
    if trajectory.points().len() < 2 {
        return Err(Rejection::TooFewPoints);
    }
    let (window_start_ns, window_end_ns) = prediction_window_ns(t_now_ns, c);
    if trajectory.start_ns() >= window_start_ns {
        return Err(Rejection::FirstPointInFuture {
            first_ns: trajectory.start_ns(),
            window_start_ns,
        });
    }
    if trajectory.end_ns() < window_end_ns {
        return Err(Rejection::InsufficientLeadTime {
            missing_ns: window_end_ns - trajectory.end_ns(),
        });
    }

    let mut samples = [TrajectorySample::default(); PREDICTION_STEPS];
    for (i, slot) in samples.iter_mut().enumerate() {
        let t_ns = sample_time_ns(window_start_ns, i, c);
        // Inside [first point, last point] after the checks above; the lab asserts it.
        let s = trajectory
            .sample(t_ns)
            .map_err(|_| Rejection::InsufficientLeadTime { missing_ns: 0 })?;
        for a in s.acceleration_mps2 {
            if a.abs() > c.max_reference_accel_mps2 {
                return Err(Rejection::LargeAcceleration { accel_mps2: a });
            }
        }
        let (speed_mps, curvature_per_m) = s.lab_speed_and_curvature();
        if speed_mps.abs() > c.curvature_check_speed_mps && curvature_per_m.abs() > c.max_curvature_per_m {
            return Err(Rejection::LargeCurvature { curvature_per_m });
        }
        *slot = s;
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mpc::BICYCLE_MOVE_WEIGHTS;
    use crate::trajectory::TrajectoryPoint;

    const MS: u64 = 1_000_000;

    fn lab() -> MpcConfig<2> {
        MpcConfig::lab(BICYCLE_MOVE_WEIGHTS)
    }

    /// `MpcController.cxx:366-367, 404` transcribed: the lab's constants are doubles, its
    /// stamps `uint64_t`, its step counts `int` and `size_t`.
    fn lab_window(t_now: u64) -> (u64, [u64; 6]) {
        let (dt_control_loop, dt_mpc): (f64, f64) = (0.02, 0.05);
        let t_start = (t_now as f64 + 3.0 * (dt_control_loop * 1e9) + (dt_mpc * 1e9)) as u64;
        let t_end = (t_start as f64 + 5.0 * (dt_mpc * 1e9)) as u64;
        let samples = std::array::from_fn(|i| (t_start as f64 + i as f64 * (dt_mpc * 1e9)) as u64);
        assert_eq!(samples[5], t_end);
        (t_start, samples)
    }

    /// Below 2⁵³ ns the window is `t_now + 110 ms … t_now + 360 ms` in steps of 50 ms, exactly.
    #[test]
    fn the_window_is_whole_nanoseconds_after_the_decision() {
        let c = lab();
        for t_now_ns in [
            0,
            1,
            200 * MS,
            5_200 * MS,
            1_234_560 * MS,
            9_999_980 * MS,
            10_000_000 * MS + 7,
        ] {
            let (start, end) = prediction_window_ns(t_now_ns, &c);
            assert_eq!((start, end), (t_now_ns + 110 * MS, t_now_ns + 360 * MS));
            for i in 0..PREDICTION_STEPS {
                assert_eq!(sample_time_ns(start, i, &c), start + i as u64 * 50 * MS);
            }
            assert_eq!(lab_window(t_now_ns).0, start);
        }
    }

    /// On the lab's wall clock (ns since 1970, beyond 2⁵³) the sums round to the double grid
    /// (256 ns there) exactly as the lab's.
    #[test]
    fn on_the_wall_clock_the_window_rounds_as_the_labs() {
        let c = lab();
        for t_now_ns in [
            1_700_000_000_123_456_789,
            1_764_000_000_000_000_000,
            u64::from(u32::MAX) << 31,
        ] {
            let (start, samples) = lab_window(t_now_ns);
            assert_eq!(prediction_window_ns(t_now_ns, &c), (start, samples[5]));
            for (i, t) in samples.iter().enumerate() {
                assert_eq!(sample_time_ns(start, i, &c), *t);
            }
        }
    }

    fn straight(times_ns: &[u64]) -> Trajectory {
        Trajectory::new(
            times_ns
                .iter()
                .map(|&t_ns| TrajectoryPoint {
                    t_ns,
                    x_m: 0.5 * (t_ns - times_ns[0]) as f64 * 1e-9,
                    y_m: 0.0,
                    vx_mps: 0.5,
                    vy_mps: 0.0,
                })
                .collect(),
        )
        .expect("increasing times")
    }

    /// The lab refuses a first point at the window's start (`t_first >= t_start`) and accepts
    /// a last point at its end (`t_last < t_end` refuses), at small and large times alike,
    /// where the same stamps in f64 seconds are off by a rounding and decide either way.
    #[test]
    fn the_window_boundaries_decide_as_the_lab_at_any_time() {
        let c = lab();
        for t_now_ns in [0, 200 * MS, 5_200 * MS, 1_234_560 * MS, 9_999_980 * MS] {
            let (start, end) = (t_now_ns + 110 * MS, t_now_ns + 360 * MS);
            // First point exactly at the window's start: refused.
            let at_start = straight(&[start, end]);
            assert_eq!(
                reference_window(t_now_ns, &at_start, &c).unwrap_err(),
                Rejection::FirstPointInFuture {
                    first_ns: start,
                    window_start_ns: start
                }
            );
            // One nanosecond earlier, last point exactly at the window's end: accepted.
            let just_before = straight(&[start - 1, end]);
            let samples = reference_window(t_now_ns, &just_before, &c).expect("accepted");
            assert_eq!(samples[0].t_ns, start);
            assert_eq!(samples[5].t_ns, end);
            // Last point one nanosecond short: refused, 1 ns missing.
            let short = straight(&[start - 1, end - 1]);
            assert_eq!(
                reference_window(t_now_ns, &short, &c).unwrap_err(),
                Rejection::InsufficientLeadTime { missing_ns: 1 }
            );
        }
    }

    #[test]
    fn fewer_than_two_points_are_refused_first() {
        let single = straight(&[0]);
        assert_eq!(
            reference_window(0, &single, &lab()).unwrap_err(),
            Rejection::TooFewPoints
        );
    }

    /// A curvature check as the lab's: |κ| > 50 /m only above 0.1 m/s.
    #[test]
    fn sharp_curves_are_refused_only_when_moving() {
        let c = lab();
        let turn = |speed_mps: f64| {
            // A circle of radius 1 cm at `speed_mps`, points every 10 ms.
            let r = 0.01;
            let w = speed_mps / r;
            Trajectory::new(
                (0..60)
                    .map(|k| {
                        let t = k as f64 * 0.01;
                        TrajectoryPoint {
                            t_ns: k * 10 * MS,
                            x_m: r * (w * t).sin(),
                            y_m: r * (1.0 - (w * t).cos()),
                            vx_mps: speed_mps * (w * t).cos(),
                            vy_mps: speed_mps * (w * t).sin(),
                        }
                    })
                    .collect(),
            )
            .unwrap()
        };
        assert!(matches!(
            reference_window(0, &turn(0.15), &c),
            Err(Rejection::LargeCurvature { .. })
        ));
        assert!(reference_window(0, &turn(0.05), &c).is_ok());
    }
}

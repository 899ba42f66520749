//! Timed reference trajectories as the CPM Lab sends them (`TrajectoryPoint`: t, px, py, vx,
//! vy) and their cubic Hermite interpolation exactly as the lab's `TrajectoryInterpolation`.
//!
//! This module owns validation of the points and sampling position, velocity and
//! acceleration at a time. It knows nothing of vehicles or controllers.
//!
//! Time: as in the lab's messages (`TimeStamp{nanoseconds: u64}`), a point's time and a query
//! time are integer nanoseconds; segments are chosen by comparing them as integers, and only
//! the interpolation converts them to seconds, as `TrajectoryInterpolation.cxx:12-14` does
//! (`double(ns) / 1e9` for the segment's ends and the query, then `Δt = t_end − t_start`,
//! `τ = (t − t_start) / Δt`), so that the same stamps give the lab's bits.
//!
//! Extrapolation: the lab never extrapolates. A query selects the segment whose end point
//! is the first point (from the second on) with `t >= query`; the controller rejects a
//! trajectory that does not cover its window before sampling it. [`Trajectory::sample`]
//! therefore returns [`TrajectoryError::OutOfRange`] before the first point and after the
//! last one instead of evaluating a polynomial outside its segment.

use thiserror::Error;

/// One point of a reference trajectory (the lab's `TrajectoryPoint`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryPoint {
    /// Time of the point on the vehicle clock [ns] (the lab's `t().nanoseconds()`).
    pub t_ns: u64,
    /// Position x in the map frame [m].
    pub x_m: f64,
    /// Position y in the map frame [m].
    pub y_m: f64,
    /// Velocity x in the map frame [m/s].
    pub vx_mps: f64,
    /// Velocity y in the map frame [m/s].
    pub vy_mps: f64,
}

/// Why a list of points is not a trajectory, or why it cannot be sampled.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum TrajectoryError {
    /// No points at all.
    #[error("trajectory has no points")]
    Empty,
    /// A position or velocity of a point is NaN or infinite.
    #[error("trajectory point {index} has a non-finite value")]
    NonFinite {
        /// Index of the offending point.
        index: usize,
    },
    /// Times do not strictly increase (the Hermite segment would divide by zero).
    #[error("trajectory point {index} is not later than the point before it")]
    NotIncreasing {
        /// Index of the offending point.
        index: usize,
    },
    /// The query time lies outside `[first point, last point]` (or only one point exists).
    #[error("time {t_ns} ns lies outside the trajectory")]
    OutOfRange {
        /// The query time [ns].
        t_ns: u64,
    },
}

/// A validated trajectory: at least one point, finite values, strictly increasing times.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    points: Vec<TrajectoryPoint>,
}

/// The interpolated reference at one time.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TrajectorySample {
    /// Query time [ns].
    pub t_ns: u64,
    /// Position [m].
    pub position_m: [f64; 2],
    /// Velocity [m/s].
    pub velocity_mps: [f64; 2],
    /// Acceleration [m/s²].
    pub acceleration_mps2: [f64; 2],
}

impl TrajectorySample {
    /// Speed `|v|` [m/s].
    pub fn speed_mps(&self) -> f64 {
        cpmx_math::hypot(self.velocity_mps[0], self.velocity_mps[1])
    }

    /// Speed and signed curvature as the lab's `TrajectoryInterpolation.cxx:59-60` computes
    /// them: `speed = sqrt(vx² + vy²)`, `κ = (vx·ay − vy·ax)/speed³` (NaN or infinite when
    /// standing; the lab's check looks at κ only above 0.1 m/s). [m/s], [1/m]
    pub fn lab_speed_and_curvature(&self) -> (f64, f64) {
        let [vx, vy] = self.velocity_mps;
        let [ax, ay] = self.acceleration_mps2;
        let speed = (vx * vx + vy * vy).sqrt();
        (speed, (vx * ay - vy * ax) / (speed * speed * speed))
    }

    /// Direction of travel `atan2(vy, vx)` [rad] (0 when standing, as `atan2(0, 0)`).
    pub fn yaw_rad(&self) -> f64 {
        cpmx_math::atan2(self.velocity_mps[1], self.velocity_mps[0])
    }

    /// Signed curvature `(vx·ay − vy·ax)/|v|³` [1/m]; 0 when standing (where the lab's
    /// formula gives NaN, which its checks also let pass).
    pub fn curvature_per_m(&self) -> f64 {
        let speed = self.speed_mps();
        if speed <= f64::EPSILON {
            return 0.0;
        }
        let [vx, vy] = self.velocity_mps;
        let [ax, ay] = self.acceleration_mps2;
        (vx * ay - vy * ax) / (speed * speed * speed)
    }
}

impl Trajectory {
    /// Validates `points` (non-empty, finite, strictly increasing in time).
    pub fn new(points: Vec<TrajectoryPoint>) -> Result<Self, TrajectoryError> {
        if points.is_empty() {
            return Err(TrajectoryError::Empty);
        }
        for (index, p) in points.iter().enumerate() {
            let finite = [p.x_m, p.y_m, p.vx_mps, p.vy_mps].iter().all(|v| v.is_finite());
            if !finite {
                return Err(TrajectoryError::NonFinite { index });
            }
            if index > 0 && p.t_ns <= points[index - 1].t_ns {
                return Err(TrajectoryError::NotIncreasing { index });
            }
        }
        Ok(Self { points })
    }

    /// The points, sorted by time.
    pub fn points(&self) -> &[TrajectoryPoint] {
        &self.points
    }

    /// Time of the first point [ns].
    pub fn start_ns(&self) -> u64 {
        self.points[0].t_ns
    }

    /// Time of the last point [ns].
    pub fn end_ns(&self) -> u64 {
        self.points[self.points.len() - 1].t_ns
    }

    /// Position, velocity and acceleration at `t_ns` by the lab's cubic Hermite spline.
    pub fn sample(&self, t_ns: u64) -> Result<TrajectorySample, TrajectoryError> {
        // The lab's segment (`MpcController.cxx:415-423`): end point = the first point from
        // index 1 on with t >= query.
        if !(self.start_ns()..=self.end_ns()).contains(&t_ns) || self.points.len() < 2 {
            return Err(TrajectoryError::OutOfRange { t_ns });
        }
        let end = 1 + self.points[1..].partition_point(|p| p.t_ns < t_ns);
        let (p0, p1) = (&self.points[end - 1], &self.points[end]);
        Ok(hermite(p0, p1, t_ns))
    }
}

/// A stamp in seconds as the lab converts it (`double(nanoseconds) / 1e9`).
pub fn seconds_from_ns(t_ns: u64) -> f64 {
    t_ns as f64 / 1e9
}

/// The lab's `TrajectoryInterpolation` on one segment (tangents are `v·Δt`), its arithmetic
/// in its order.
fn hermite(p0: &TrajectoryPoint, p1: &TrajectoryPoint, t_ns: u64) -> TrajectorySample {
    let (t_start_s, t_end_s) = (seconds_from_ns(p0.t_ns), seconds_from_ns(p1.t_ns));
    let t_now_s = seconds_from_ns(t_ns);
    let dt = t_end_s - t_start_s;
    let tau = (t_now_s - t_start_s) / dt;
    let tau2 = tau * tau;
    let tau3 = tau * tau2;

    // Basis, first and second derivatives with respect to tau.
    let basis = [
        2.0 * tau3 - 3.0 * tau2 + 1.0,
        tau3 - 2.0 * tau2 + tau,
        -2.0 * tau3 + 3.0 * tau2,
        tau3 - tau2,
    ];
    let d_basis = [
        6.0 * tau2 - 6.0 * tau,
        3.0 * tau2 - 4.0 * tau + 1.0,
        -6.0 * tau2 + 6.0 * tau,
        3.0 * tau2 - 2.0 * tau,
    ];
    let dd_basis = [
        12.0 * tau - 6.0,
        6.0 * tau - 4.0,
        -12.0 * tau + 6.0,
        6.0 * tau - 2.0,
    ];

    let axis = |pos0: f64, vel0: f64, pos1: f64, vel1: f64| {
        let c = [pos0, vel0 * dt, pos1, vel1 * dt];
        let dot = |b: &[f64; 4]| c[0] * b[0] + c[1] * b[1] + c[2] * b[2] + c[3] * b[3];
        (dot(&basis), dot(&d_basis) / dt, dot(&dd_basis) / (dt * dt))
    };
    let (x, vx, ax) = axis(p0.x_m, p0.vx_mps, p1.x_m, p1.vx_mps);
    let (y, vy, ay) = axis(p0.y_m, p0.vy_mps, p1.y_m, p1.vy_mps);
    TrajectorySample {
        t_ns,
        position_m: [x, y],
        velocity_mps: [vx, vy],
        acceleration_mps2: [ax, ay],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const MS: u64 = 1_000_000;

    fn point(t_ns: u64, x_m: f64, vx_mps: f64) -> TrajectoryPoint {
        TrajectoryPoint {
            t_ns,
            x_m,
            y_m: 0.0,
            vx_mps,
            vy_mps: 0.0,
        }
    }

    #[test]
    fn rejects_empty_nan_and_unsorted_points() {
        assert_eq!(Trajectory::new(vec![]), Err(TrajectoryError::Empty));
        assert_eq!(
            Trajectory::new(vec![point(0, f64::NAN, 0.0)]),
            Err(TrajectoryError::NonFinite { index: 0 })
        );
        assert_eq!(
            Trajectory::new(vec![point(0, 0.0, 0.0), point(0, 1.0, 0.0)]),
            Err(TrajectoryError::NotIncreasing { index: 1 })
        );
    }

    #[test]
    fn single_point_and_outside_times_are_out_of_range() {
        let single = Trajectory::new(vec![point(1000 * MS, 0.0, 0.0)]).unwrap();
        assert_eq!(
            single.sample(1000 * MS),
            Err(TrajectoryError::OutOfRange { t_ns: 1000 * MS })
        );
        let two = Trajectory::new(vec![point(10 * MS, 0.0, 1.0), point(1010 * MS, 1.0, 1.0)]).unwrap();
        assert!(two.sample(10 * MS - 1).is_err());
        assert!(two.sample(1010 * MS + 1).is_err());
        assert!(two.sample(10 * MS).is_ok() && two.sample(1010 * MS).is_ok());
    }

    #[test]
    fn reproduces_constant_velocity_and_endpoints() {
        let traj = Trajectory::new(vec![
            point(0, 0.0, 0.5),
            point(100 * MS, 0.05, 0.5),
            point(300 * MS, 0.15, 0.5),
        ])
        .unwrap();
        for t_ms in [0, 50, 100, 170, 300] {
            let s = traj.sample(t_ms * MS).unwrap();
            assert_relative_eq!(s.position_m[0], 0.5e-3 * t_ms as f64, epsilon = 1e-12);
            assert_relative_eq!(s.velocity_mps[0], 0.5, epsilon = 1e-12);
            assert_relative_eq!(s.acceleration_mps2[0], 0.0, epsilon = 1e-10);
        }
    }

    #[test]
    fn reproduces_a_cubic_exactly() {
        // x(t) = t³ − t, v(t) = 3t² − 1: Hermite interpolation of a cubic is exact.
        let f = |t: f64| t * t * t - t;
        let df = |t: f64| 3.0 * t * t - 1.0;
        let traj =
            Trajectory::new(vec![point(0, f(0.0), df(0.0)), point(400 * MS, f(0.4), df(0.4))]).unwrap();
        let s = traj.sample(250 * MS).unwrap();
        assert_relative_eq!(s.position_m[0], f(0.25), epsilon = 1e-12);
        assert_relative_eq!(s.velocity_mps[0], df(0.25), epsilon = 1e-12);
        assert_relative_eq!(s.acceleration_mps2[0], 6.0 * 0.25, epsilon = 1e-10);
    }

    #[test]
    fn curvature_of_a_circle() {
        let r = 0.6;
        let w = 0.5 / r;
        let p = |i: u64| {
            let t = 0.1 * i as f64;
            TrajectoryPoint {
                t_ns: i * 100 * MS,
                x_m: r * (w * t).cos(),
                y_m: r * (w * t).sin(),
                vx_mps: -r * w * (w * t).sin(),
                vy_mps: r * w * (w * t).cos(),
            }
        };
        let traj = Trajectory::new((0..5).map(p).collect()).unwrap();
        let s = traj.sample(150 * MS).unwrap();
        assert_relative_eq!(s.curvature_per_m(), 1.0 / r, max_relative = 1e-3);
        assert_relative_eq!(s.speed_mps(), 0.5, max_relative = 1e-4);
        let (speed, curvature) = s.lab_speed_and_curvature();
        assert_relative_eq!(speed, 0.5, max_relative = 1e-4);
        assert_relative_eq!(curvature, 1.0 / r, max_relative = 1e-3);
    }

    /// `TrajectoryInterpolation.cxx:12-60` transcribed line by line, for one axis.
    fn lab_interpolation(t_now_ns: u64, start: &TrajectoryPoint, end: &TrajectoryPoint) -> [f64; 4] {
        let t_start = start.t_ns as f64 / 1e9;
        let t_end = end.t_ns as f64 / 1e9;
        let t_now = t_now_ns as f64 / 1e9;
        let delta_t = t_end - t_start;
        let tau = (t_now - t_start) / delta_t;
        let tau2 = tau * tau;
        let tau3 = tau * tau2;
        let position_start_x = start.x_m;
        let position_end_x = end.x_m;
        let velocity_start_x = start.vx_mps * delta_t;
        let velocity_end_x = end.vx_mps * delta_t;
        let p0 = 2.0 * tau3 - 3.0 * tau2 + 1.0;
        let m0 = tau3 - 2.0 * tau2 + tau;
        let p1 = -2.0 * tau3 + 3.0 * tau2;
        let m1 = tau3 - tau2;
        let dp0 = 6.0 * tau2 - 6.0 * tau;
        let dm0 = 3.0 * tau2 - 4.0 * tau + 1.0;
        let dp1 = -6.0 * tau2 + 6.0 * tau;
        let dm1 = 3.0 * tau2 - 2.0 * tau;
        let ddp0 = 12.0 * tau - 6.0;
        let ddm0 = 6.0 * tau - 4.0;
        let ddp1 = -12.0 * tau + 6.0;
        let ddm1 = 6.0 * tau - 2.0;
        [
            tau,
            position_start_x * p0 + velocity_start_x * m0 + position_end_x * p1 + velocity_end_x * m1,
            (position_start_x * dp0 + velocity_start_x * dm0 + position_end_x * dp1 + velocity_end_x * dm1)
                / delta_t,
            (position_start_x * ddp0
                + velocity_start_x * ddm0
                + position_end_x * ddp1
                + velocity_end_x * ddm1)
                / (delta_t * delta_t),
        ]
    }

    /// Far from the clock's origin the lab's conversion to seconds before subtracting rounds
    /// τ; the interpolation rounds as it does (the same bits), not as a subtraction in whole
    /// nanoseconds would.
    #[test]
    fn interpolates_with_the_labs_conversions_at_any_time() {
        for base_ns in [
            0,
            5_200_000_000,
            1_234_560_000_000,
            9_999_980_000_000,
            1_700_000_000_123_456_789,
        ] {
            let a = TrajectoryPoint {
                t_ns: base_ns + 100 * MS,
                x_m: 1.25,
                y_m: 0.0,
                vx_mps: 0.4,
                vy_mps: 0.0,
            };
            let b = TrajectoryPoint {
                t_ns: base_ns + 200 * MS,
                x_m: 1.3,
                y_m: 0.0,
                vx_mps: 0.6,
                vy_mps: 0.0,
            };
            let traj = Trajectory::new(vec![a, b]).unwrap();
            for offset_ns in [100 * MS, 130 * MS + 7, 160 * MS, 200 * MS] {
                let t_ns = base_ns + offset_ns;
                let s = traj.sample(t_ns).unwrap();
                let [_, x, vx, ax] = lab_interpolation(t_ns, &a, &b);
                assert_eq!(
                    (s.position_m[0].to_bits(), s.velocity_mps[0].to_bits()),
                    (x.to_bits(), vx.to_bits())
                );
                assert_eq!(s.acceleration_mps2[0].to_bits(), ax.to_bits());
            }
        }
    }
}

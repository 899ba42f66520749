//! Timed reference trajectories as the CPM Lab sends them (`TrajectoryPoint`: t, px, py, vx,
//! vy) and their cubic Hermite interpolation exactly as the lab's `TrajectoryInterpolation`.
//!
//! This module owns validation of the points and sampling position, velocity and
//! acceleration at a time. It knows nothing of vehicles or controllers.
//!
//! Extrapolation: the lab never extrapolates. A query selects the segment whose end point
//! is the first point (from the second on) with `t >= query`; the controller rejects a
//! trajectory that does not cover its window before sampling it. [`Trajectory::sample`]
//! therefore returns [`TrajectoryError::OutOfRange`] before the first point and after the
//! last one instead of evaluating a polynomial outside its segment.

use thiserror::Error;

/// One point of a reference trajectory (the lab's `TrajectoryPoint`, time in seconds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryPoint {
    /// Time of the point on the vehicle clock [s].
    pub t_s: f64,
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
    /// A field of a point is NaN or infinite.
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
    #[error("time {t_s} s lies outside the trajectory")]
    OutOfRange {
        /// The query time [s].
        t_s: f64,
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
    /// Query time [s].
    pub t_s: f64,
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
        self.velocity_mps[0].hypot(self.velocity_mps[1])
    }

    /// Direction of travel `atan2(vy, vx)` [rad] (0 when standing, as `atan2(0, 0)`).
    pub fn yaw_rad(&self) -> f64 {
        self.velocity_mps[1].atan2(self.velocity_mps[0])
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
            let finite = [p.t_s, p.x_m, p.y_m, p.vx_mps, p.vy_mps]
                .iter()
                .all(|v| v.is_finite());
            if !finite {
                return Err(TrajectoryError::NonFinite { index });
            }
            if index > 0 && p.t_s <= points[index - 1].t_s {
                return Err(TrajectoryError::NotIncreasing { index });
            }
        }
        Ok(Self { points })
    }

    /// The points, sorted by time.
    pub fn points(&self) -> &[TrajectoryPoint] {
        &self.points
    }

    /// Time of the first point [s].
    pub fn start_s(&self) -> f64 {
        self.points[0].t_s
    }

    /// Time of the last point [s].
    pub fn end_s(&self) -> f64 {
        self.points[self.points.len() - 1].t_s
    }

    /// Position, velocity and acceleration at `t_s` by the lab's cubic Hermite spline.
    pub fn sample(&self, t_s: f64) -> Result<TrajectorySample, TrajectoryError> {
        // The lab's segment: end point = first point from index 1 on with t >= query.
        let out_of_range = TrajectoryError::OutOfRange { t_s };
        if !(t_s >= self.start_s() && t_s <= self.end_s()) || self.points.len() < 2 {
            return Err(out_of_range);
        }
        let end = 1 + self.points[1..].partition_point(|p| p.t_s < t_s);
        let (p0, p1) = (&self.points[end - 1], &self.points[end]);
        Ok(hermite(p0, p1, t_s))
    }
}

/// The lab's `TrajectoryInterpolation` on one segment (tangents are `v·Δt`).
fn hermite(p0: &TrajectoryPoint, p1: &TrajectoryPoint, t_s: f64) -> TrajectorySample {
    let dt = p1.t_s - p0.t_s;
    let tau = (t_s - p0.t_s) / dt;
    let (tau2, tau3) = (tau * tau, tau * tau * tau);

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
        t_s,
        position_m: [x, y],
        velocity_mps: [vx, vy],
        acceleration_mps2: [ax, ay],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn point(t_s: f64, x_m: f64, vx_mps: f64) -> TrajectoryPoint {
        TrajectoryPoint {
            t_s,
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
            Trajectory::new(vec![point(0.0, f64::NAN, 0.0)]),
            Err(TrajectoryError::NonFinite { index: 0 })
        );
        assert_eq!(
            Trajectory::new(vec![point(0.0, 0.0, 0.0), point(0.0, 1.0, 0.0)]),
            Err(TrajectoryError::NotIncreasing { index: 1 })
        );
    }

    #[test]
    fn single_point_and_outside_times_are_out_of_range() {
        let single = Trajectory::new(vec![point(1.0, 0.0, 0.0)]).unwrap();
        assert!(matches!(
            single.sample(1.0),
            Err(TrajectoryError::OutOfRange { .. })
        ));
        let two = Trajectory::new(vec![point(0.0, 0.0, 1.0), point(1.0, 1.0, 1.0)]).unwrap();
        assert!(two.sample(-0.01).is_err());
        assert!(two.sample(1.01).is_err());
        assert!(two.sample(f64::NAN).is_err());
    }

    #[test]
    fn reproduces_constant_velocity_and_endpoints() {
        let traj = Trajectory::new(vec![
            point(0.0, 0.0, 0.5),
            point(0.1, 0.05, 0.5),
            point(0.3, 0.15, 0.5),
        ])
        .unwrap();
        for t in [0.0, 0.05, 0.1, 0.17, 0.3] {
            let s = traj.sample(t).unwrap();
            assert_relative_eq!(s.position_m[0], 0.5 * t, epsilon = 1e-12);
            assert_relative_eq!(s.velocity_mps[0], 0.5, epsilon = 1e-12);
            assert_relative_eq!(s.acceleration_mps2[0], 0.0, epsilon = 1e-10);
        }
    }

    #[test]
    fn reproduces_a_cubic_exactly() {
        // x(t) = t³ − t, v(t) = 3t² − 1: Hermite interpolation of a cubic is exact.
        let f = |t: f64| t * t * t - t;
        let df = |t: f64| 3.0 * t * t - 1.0;
        let traj = Trajectory::new(vec![point(0.0, f(0.0), df(0.0)), point(0.4, f(0.4), df(0.4))]).unwrap();
        let s = traj.sample(0.25).unwrap();
        assert_relative_eq!(s.position_m[0], f(0.25), epsilon = 1e-12);
        assert_relative_eq!(s.velocity_mps[0], df(0.25), epsilon = 1e-12);
        assert_relative_eq!(s.acceleration_mps2[0], 6.0 * 0.25, epsilon = 1e-10);
    }

    #[test]
    fn curvature_of_a_circle() {
        let r = 0.6;
        let w = 0.5 / r;
        let p = |t: f64| TrajectoryPoint {
            t_s: t,
            x_m: r * (w * t).cos(),
            y_m: r * (w * t).sin(),
            vx_mps: -r * w * (w * t).sin(),
            vy_mps: r * w * (w * t).cos(),
        };
        let traj = Trajectory::new((0..5).map(|i| p(0.1 * f64::from(i))).collect()).unwrap();
        let s = traj.sample(0.15).unwrap();
        assert_relative_eq!(s.curvature_per_m(), 1.0 / r, max_relative = 1e-3);
        assert_relative_eq!(s.speed_mps(), 0.5, max_relative = 1e-4);
    }
}

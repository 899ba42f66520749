//! The sensing chain of one car as the lab's simulated vehicle runs it each 20 ms period:
//! an IPS frame of the true pose, the localization's dead-reckoning step, then the fixes that
//! arrived. A convenience over [`IpsModel`] and [`Localization`]; it also keeps the age of
//! the newest fix that arrived, which the car reports as `IPS_update_age_nanoseconds` and its
//! controller stops on after 3 s (`Controller.cxx`: "Lost IPS position reference").
//!
//! The age is the lab's (`cpm::Reader::get_sample`): the time since the measurement stamp of
//! the newest observation received, whether or not the localization used it; dropped frames
//! and the IPS latency make it grow. Before the first fix the car's start counts as one (the
//! localization starts at the true pose, as a car that converged on fixes before the run).

use rand_chacha::ChaCha20Rng;

use crate::{
    Estimate, IpsModel, IpsParams, Localization, LocalizationParams, OdometryReading, Pose2, SensingError,
};

/// Positioning system and localization of one car, sharing one random stream.
#[derive(Debug, Clone, PartialEq)]
pub struct OnCarSensing {
    ips: IpsModel,
    localization: Localization,
    /// The measurement time of the newest fix that arrived [s].
    newest_fix_s: f64,
    /// Whether the fixes stop reaching the car (the positioning lost it; `cpmx lab emulate`'s
    /// fault): frames are still drawn, so the random stream stays as without the fault.
    fixes_lost: bool,
}

impl OnCarSensing {
    /// The chain for a car that starts at `initial_pose` at `start_time_s`.
    pub fn new(
        ips: &IpsParams,
        localization: &LocalizationParams,
        initial_pose: Pose2,
        initial_speed_mps: f64,
        start_time_s: f64,
    ) -> Result<Self, SensingError> {
        Ok(Self {
            ips: IpsModel::new(ips)?,
            localization: Localization::new(localization, initial_pose, initial_speed_mps, start_time_s)?,
            newest_fix_s: start_time_s,
            fixes_lost: false,
        })
    }

    /// One control period ending at `time_s` (= start + k·period) with the car at
    /// `true_pose` after moving as `reading` says. Draw order: the IPS frame's draws (if a
    /// frame is due), then the gyro drift.
    pub fn step(
        &mut self,
        time_s: f64,
        true_pose: Pose2,
        reading: &OdometryReading,
        rng: &mut ChaCha20Rng,
    ) -> Estimate {
        let mut fixes = self.ips.step(time_s, true_pose, rng);
        self.localization.step(reading, rng);
        if self.fixes_lost {
            fixes.clear();
        }
        for fix in &fixes {
            self.newest_fix_s = self.newest_fix_s.max(fix.measured_at_s);
            self.localization.apply_fix(fix);
        }
        self.localization.estimate()
    }

    /// Stops (or resumes) the fixes reaching the car: it drives on dead reckoning and the age
    /// of its newest fix grows.
    pub fn lose_fixes(&mut self, lost: bool) {
        self.fixes_lost = lost;
    }

    /// Time since the newest fix that arrived was measured, at `time_s` [s] (never negative).
    pub fn ips_update_age_s(&self, time_s: f64) -> f64 {
        (time_s - self.newest_fix_s).max(0.0)
    }

    /// The car's current belief.
    pub fn estimate(&self) -> Estimate {
        self.localization.estimate()
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    fn drive(seed: u8) -> Vec<Estimate> {
        let start = Pose2 {
            x_m: 1.0,
            y_m: 2.0,
            yaw_rad: 0.5,
        };
        let mut chain =
            OnCarSensing::new(&IpsParams::LAB, &LocalizationParams::LAB, start, 0.0, 0.0).unwrap();
        let mut rng = ChaCha20Rng::from_seed([seed; 32]);
        let reading = OdometryReading {
            distance_increment_m: 0.01,
            yaw_increment_rad: 0.0,
            speed_mps: 0.5,
        };
        (1..=250)
            .map(|k| {
                let t = f64::from(k) * 0.02;
                let truth = Pose2 {
                    x_m: 1.0 + 0.5 * t * 0.5_f64.cos(),
                    y_m: 2.0 + 0.5 * t * 0.5_f64.sin(),
                    ..start
                };
                chain.step(t, truth, &reading, &mut rng)
            })
            .collect()
    }

    #[test]
    fn the_chain_is_deterministic_given_the_stream_and_tracks_the_truth() {
        let a = drive(1);
        assert_eq!(a, drive(1));
        assert_ne!(a, drive(2));
        let last = a[a.len() - 1];
        assert!((last.time_s - 5.0).abs() < 1e-12);
        let truth_x = 1.0 + 0.5 * 5.0 * 0.5_f64.cos();
        assert!((last.pose.x_m - truth_x).abs() < 0.01, "{last:?}");
    }

    fn still(chain: &mut OnCarSensing, rng: &mut ChaCha20Rng, k: u32) -> f64 {
        let t = f64::from(k) * 0.02;
        let reading = OdometryReading {
            distance_increment_m: 0.0,
            yaw_increment_rad: 0.0,
            speed_mps: 0.0,
        };
        chain.step(t, Pose2::default(), &reading, rng);
        chain.ips_update_age_s(t)
    }

    /// Fixes arrive 60 ms after they are measured, so the age is at least the latency; a
    /// dropped frame makes it grow by a frame; a positioning system that delivers nothing
    /// makes it grow with time from the start.
    #[test]
    fn the_ips_age_counts_from_the_newest_fix_that_arrived() {
        let mut rng = ChaCha20Rng::from_seed([3; 32]);
        let lossless = IpsParams {
            drop_probability: 0.0,
            ..IpsParams::LAB
        };
        let mut chain =
            OnCarSensing::new(&lossless, &LocalizationParams::LAB, Pose2::default(), 0.0, 0.0).unwrap();
        let ages: Vec<f64> = (1..=50).map(|k| still(&mut chain, &mut rng, k)).collect();
        // The start counts as a fix until the first frame (taken at 20 ms) arrives at 80 ms.
        assert!((ages[2] - 0.06).abs() < 1e-9, "{ages:?}");
        assert!(ages[4..].iter().all(|a| (a - 0.06).abs() < 1e-9), "{ages:?}");

        let lab = IpsParams::LAB;
        let mut chain =
            OnCarSensing::new(&lab, &LocalizationParams::LAB, Pose2::default(), 0.0, 0.0).unwrap();
        let ages: Vec<f64> = (1..=2000).map(|k| still(&mut chain, &mut rng, k)).collect();
        let longer = ages.iter().filter(|&&a| a > 0.06 + 1e-9).count();
        assert!(
            longer > 50 && longer < 200,
            "about one frame in 20 dropped: {longer}"
        );
        assert!(
            ages.iter().all(|&a| a < 0.3),
            "{:?}",
            ages.iter().copied().fold(0.0, f64::max)
        );

        let lost = IpsParams {
            drop_probability: 1.0,
            ..IpsParams::LAB
        };
        let mut chain =
            OnCarSensing::new(&lost, &LocalizationParams::LAB, Pose2::default(), 0.0, 0.0).unwrap();
        let last = (1..=200).map(|k| still(&mut chain, &mut rng, k)).last().unwrap();
        assert!((last - 4.0).abs() < 1e-9, "{last}");
    }
}

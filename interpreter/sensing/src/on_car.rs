//! The sensing chain of one car as the lab's simulated vehicle runs it each 20 ms period:
//! an IPS frame of the true pose, the localization's dead-reckoning step, then the fixes that
//! arrived. A convenience over [`IpsModel`] and [`Localization`]; owns nothing else.

use rand_chacha::ChaCha20Rng;

use crate::{
    Estimate, IpsModel, IpsParams, Localization, LocalizationParams, OdometryReading, Pose2, SensingError,
};

/// Positioning system and localization of one car, sharing one random stream.
#[derive(Debug, Clone, PartialEq)]
pub struct OnCarSensing {
    ips: IpsModel,
    localization: Localization,
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
        let fixes = self.ips.step(time_s, true_pose, rng);
        self.localization.step(reading, rng);
        for fix in &fixes {
            self.localization.apply_fix(fix);
        }
        self.localization.estimate()
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
}

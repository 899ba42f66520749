use cpmx_vehicle::{GreyBoxParams, GreyBoxState, GreyBoxVehicle};
use rand::SeedableRng;

use super::*;
use crate::{IpsModel, IpsParams};

fn rng(seed: u8) -> ChaCha20Rng {
    ChaCha20Rng::from_seed([seed; 32])
}

fn exact() -> LocalizationParams {
    LocalizationParams {
        imu_drift_per_step_rad: 0.0,
        ..LocalizationParams::LAB
    }
}

fn yaw_error_rad(a: f64, b: f64) -> f64 {
    wrap_angle_rad(a - b).abs()
}

/// A unicycle on a circle, moved exactly as dead reckoning assumes (yaw first, then the
/// distance along the new yaw): 0.5 m/s, 2 rad/s.
fn unicycle_reading() -> OdometryReading {
    OdometryReading {
        distance_increment_m: 0.01,
        yaw_increment_rad: 0.04,
        speed_mps: 0.5,
    }
}

fn unicycle_step(pose: Pose2, reading: &OdometryReading) -> Pose2 {
    let yaw_rad = pose.yaw_rad + reading.yaw_increment_rad;
    Pose2 {
        x_m: pose.x_m + reading.distance_increment_m * yaw_rad.cos(),
        y_m: pose.y_m + reading.distance_increment_m * yaw_rad.sin(),
        yaw_rad,
    }
}

#[test]
fn exact_dead_reckoning_without_noise_stays_exact() {
    // With and without ideal (noise-free, 60 ms late) fixes.
    for with_fixes in [false, true] {
        let start = Pose2 {
            x_m: 2.0,
            y_m: 1.0,
            yaw_rad: 0.3,
        };
        let mut truth = start;
        let mut loc = Localization::new(&exact(), start, 0.5, 0.0).unwrap();
        let ideal = IpsParams {
            noise_position_m: 0.0,
            noise_yaw_rad: 0.0,
            drop_probability: 0.0,
            ..IpsParams::LAB
        };
        let mut ips = IpsModel::new(&ideal).unwrap();
        let mut rng = rng(1);
        let mut applied = 0;
        for k in 1..=1000 {
            let reading = unicycle_reading();
            truth = unicycle_step(truth, &reading);
            let fixes = ips.step(f64::from(k) * 0.02, truth, &mut rng);
            let estimate = loc.step(&reading, &mut rng);
            if with_fixes {
                for fix in &fixes {
                    assert_eq!(loc.apply_fix(fix), FixOutcome::Applied);
                    applied += 1;
                }
            }
            let estimate = if with_fixes { loc.estimate() } else { estimate };
            assert!((estimate.pose.x_m - truth.x_m).abs() < 1e-9, "step {k}");
            assert!((estimate.pose.y_m - truth.y_m).abs() < 1e-9, "step {k}");
            assert!(
                yaw_error_rad(estimate.pose.yaw_rad, truth.yaw_rad) < 1e-9,
                "step {k}"
            );
            assert_eq!(estimate.speed_mps, 0.5);
        }
        assert_eq!(applied, if with_fixes { 997 } else { 0 });
    }
}

/// Largest position and yaw errors of the estimate over a 20 s circle drive of the grey-box
/// car (throttle 0.2, servo 0.5: ≈ 0.54 m/s on a ≈ 0.55 m radius), sensing as given.
fn circle_drive(ips: Option<IpsParams>, drift_per_step_rad: f64) -> (f64, f64) {
    let car = GreyBoxVehicle::new(GreyBoxParams::LAB).unwrap();
    let input = car.input(0.2, 0.5);
    let mut state = GreyBoxState {
        x_m: 2.25,
        y_m: 1.0,
        ..GreyBoxState::default()
    };
    let pose_of = |s: &GreyBoxState| Pose2 {
        x_m: s.x_m,
        y_m: s.y_m,
        yaw_rad: s.yaw_rad,
    };
    let params = LocalizationParams {
        imu_drift_per_step_rad: drift_per_step_rad,
        ..LocalizationParams::LAB
    };
    let mut loc = Localization::new(&params, pose_of(&state), 0.0, 0.0).unwrap();
    let mut ips = ips.map(|p| IpsModel::new(&p).unwrap());
    let mut rng = rng(9);
    let (mut max_position_m, mut max_yaw_rad) = (0.0_f64, 0.0_f64);
    for k in 1..=1000 {
        let out = car.step(&state, &input, 0.02).unwrap();
        state = out.state;
        let reading = OdometryReading {
            distance_increment_m: out.odometer_increment_m,
            yaw_increment_rad: out.yaw_increment_rad,
            speed_mps: state.speed_mps,
        };
        let fixes = match ips.as_mut() {
            Some(ips) => ips.step(f64::from(k) * 0.02, pose_of(&state), &mut rng),
            None => Vec::new(),
        };
        loc.step(&reading, &mut rng);
        for fix in &fixes {
            loc.apply_fix(fix);
        }
        let estimate = loc.estimate().pose;
        max_position_m = max_position_m.max((estimate.x_m - state.x_m).hypot(estimate.y_m - state.y_m));
        max_yaw_rad = max_yaw_rad.max(yaw_error_rad(estimate.yaw_rad, state.yaw_rad));
    }
    (max_position_m, max_yaw_rad)
}

#[test]
fn fixes_bound_the_drift_of_a_circle_drive() {
    let noise_free = IpsParams {
        noise_position_m: 0.0,
        noise_yaw_rad: 0.0,
        ..IpsParams::LAB
    };
    let drift = LocalizationParams::LAB.imu_drift_per_step_rad;

    // Gyro drift and the model terms dead reckoning ignores (p1, p2, p3, p10), corrected by
    // late, partly dropped, noise-free fixes.
    let (position_m, yaw_rad) = circle_drive(Some(noise_free), drift);
    assert!(
        position_m < 0.01 && yaw_rad < 0.01,
        "with fixes: {position_m} m, {yaw_rad} rad"
    );

    // The lab's full IPS (noise ±2 mm, ±0.01 rad).
    let (lab_position_m, lab_yaw_rad) = circle_drive(Some(IpsParams::LAB), drift);
    assert!(
        lab_position_m < 0.01 && lab_yaw_rad < 0.01,
        "lab IPS: {lab_position_m} m, {lab_yaw_rad} rad"
    );

    // Without fixes the same drive drifts away.
    let (free_position_m, free_yaw_rad) = circle_drive(None, drift);
    assert!(
        free_position_m > 0.05 && free_yaw_rad > 0.04,
        "no fixes: {free_position_m} m, {free_yaw_rad} rad"
    );
    println!(
        "max error over 20 s: fixes {position_m:.4} m {yaw_rad:.4} rad; lab IPS \
         {lab_position_m:.4} m {lab_yaw_rad:.4} rad; no fixes {free_position_m:.4} m {free_yaw_rad:.4} rad"
    );
}

#[test]
fn a_fix_blends_its_slot_and_reprocesses_later_states() {
    let params = LocalizationParams {
        fusion_gain: 1.0,
        ..exact()
    };
    let mut loc = Localization::new(&params, Pose2::default(), 0.0, 0.0).unwrap();
    let mut rng = rng(2);
    let reading = OdometryReading {
        distance_increment_m: 0.01,
        yaw_increment_rad: 0.0,
        speed_mps: 0.5,
    };
    for _ in 0..10 {
        loc.step(&reading, &mut rng);
    }
    // Slot 7 covers [0.14, 0.16); with gain 1 it becomes the fix, three more steps follow.
    let fix = PoseFix {
        measured_at_s: 0.15,
        pose: Pose2 {
            x_m: 1.0,
            y_m: 2.0,
            yaw_rad: 0.0,
        },
    };
    assert_eq!(loc.apply_fix(&fix), FixOutcome::Applied);
    let estimate = loc.estimate();
    assert!((estimate.pose.x_m - 1.03).abs() < 1e-12 && (estimate.pose.y_m - 2.0).abs() < 1e-12);
    assert!((estimate.time_s - 0.2).abs() < 1e-12);

    assert_eq!(loc.apply_fix(&fix), FixOutcome::SlotTaken);
    let future = PoseFix {
        measured_at_s: 0.22,
        ..fix
    };
    assert_eq!(loc.apply_fix(&future), FixOutcome::FromTheFuture);
    let before_start = PoseFix {
        measured_at_s: 0.01,
        ..fix
    };
    assert_eq!(loc.apply_fix(&before_start), FixOutcome::TooOld);
}

#[test]
fn fixes_older_than_the_buffer_are_ignored() {
    let params = LocalizationParams {
        buffer_len: 8,
        ..exact()
    };
    let mut loc = Localization::new(&params, Pose2::default(), 0.0, 0.0).unwrap();
    let mut rng = rng(3);
    for _ in 0..20 {
        loc.step(&OdometryReading::default(), &mut rng);
    }
    // Slots 13..=20 are buffered; 13 has no predecessor.
    let at = |t: f64| PoseFix {
        measured_at_s: t,
        pose: Pose2 {
            x_m: 1.0,
            ..Pose2::default()
        },
    };
    assert_eq!(loc.apply_fix(&at(0.26)), FixOutcome::TooOld);
    assert_eq!(loc.apply_fix(&at(0.28)), FixOutcome::Applied);
    assert_eq!(loc.apply_fix(&at(f64::NAN)), FixOutcome::TooOld);
    let aged = LocalizationParams {
        max_fix_age_s: 0.05,
        ..exact()
    };
    let mut loc = Localization::new(&aged, Pose2::default(), 0.0, 0.0).unwrap();
    for _ in 0..20 {
        loc.step(&OdometryReading::default(), &mut rng);
    }
    assert_eq!(loc.apply_fix(&at(0.34)), FixOutcome::TooOld);
    assert_eq!(loc.apply_fix(&at(0.36)), FixOutcome::Applied);
}

#[test]
fn yaw_blends_on_the_circle() {
    let params = LocalizationParams {
        fusion_gain: 0.5,
        ..exact()
    };
    let start = Pose2 {
        yaw_rad: 3.1,
        ..Pose2::default()
    };
    let mut loc = Localization::new(&params, start, 0.0, 0.0).unwrap();
    loc.step(&OdometryReading::default(), &mut rng(4));
    let fix = PoseFix {
        measured_at_s: 0.02,
        pose: Pose2 {
            yaw_rad: -3.1,
            ..Pose2::default()
        },
    };
    loc.apply_fix(&fix);
    // Halfway across ±π, not through zero.
    let yaw = loc.estimate().pose.yaw_rad;
    assert!(yaw_error_rad(yaw, std::f64::consts::PI) < 1e-12, "{yaw}");
}

#[test]
fn gyro_drift_is_one_draw_per_step_within_its_bound() {
    let mut loc = Localization::new(&LocalizationParams::LAB, Pose2::default(), 0.0, 0.0).unwrap();
    let mut rng = rng(5);
    let mut previous = 0.0;
    let mut total = 0.0;
    for _ in 0..1000 {
        let yaw = loc.step(&OdometryReading::default(), &mut rng).pose.yaw_rad;
        let drift = yaw - previous;
        assert!((0.0..1e-4).contains(&drift), "{drift}");
        total += drift;
        previous = yaw;
    }
    // Mean 5e-5 rad per step.
    assert!((total / 1000.0 - 5e-5).abs() < 5e-6, "{total}");
}

#[test]
fn invalid_parameters_are_errors() {
    let lab = LocalizationParams::LAB;
    for params in [
        LocalizationParams { period_s: 0.0, ..lab },
        LocalizationParams { buffer_len: 1, ..lab },
        LocalizationParams {
            fusion_gain: 1.1,
            ..lab
        },
        LocalizationParams {
            imu_drift_per_step_rad: f64::NAN,
            ..lab
        },
        LocalizationParams {
            max_fix_age_s: -1.0,
            ..lab
        },
    ] {
        assert!(
            Localization::new(&params, Pose2::default(), 0.0, 0.0).is_err(),
            "{params:?}"
        );
    }
    assert!(Localization::new(&lab, Pose2::default(), 0.0, f64::NAN).is_err());
}

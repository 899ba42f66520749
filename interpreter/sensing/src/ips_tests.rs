use rand::SeedableRng;

use super::*;

fn rng(seed: u8) -> ChaCha20Rng {
    ChaCha20Rng::from_seed([seed; 32])
}

fn ideal() -> IpsParams {
    IpsParams {
        rate_hz: 50.0,
        latency_ms: 0.0,
        noise_position_m: 0.0,
        noise_yaw_rad: 0.0,
        drop_probability: 0.0,
    }
}

/// The true pose along a made-up path at step k (yaw beyond π to exercise the wrap).
fn truth(k: u32) -> Pose2 {
    let t = f64::from(k) * 0.02;
    Pose2 {
        x_m: 1.0 + 0.5 * t,
        y_m: 2.0 - 0.1 * t,
        yaw_rad: 3.0 + 0.4 * t,
    }
}

#[test]
fn ideal_ips_returns_the_true_pose_every_frame() {
    let mut ips = IpsModel::new(&ideal()).unwrap();
    let mut rng = rng(1);
    for k in 0..200 {
        let t = f64::from(k) * 0.02;
        let fixes = ips.step(t, truth(k), &mut rng);
        let expected = Pose2 {
            yaw_rad: wrap_angle_rad(truth(k).yaw_rad),
            ..truth(k)
        };
        assert_eq!(
            fixes,
            vec![PoseFix {
                measured_at_s: t,
                pose: expected
            }],
            "step {k}"
        );
    }
}

#[test]
fn latency_delivers_late_with_the_measurement_stamp() {
    let params = IpsParams {
        latency_ms: 60.0,
        ..ideal()
    };
    let mut ips = IpsModel::new(&params).unwrap();
    let mut rng = rng(2);
    for k in 0..100 {
        let t = f64::from(k) * 0.02;
        let fixes = ips.step(t, truth(k), &mut rng);
        if k < 3 {
            assert!(fixes.is_empty(), "step {k}: {fixes:?}");
        } else {
            assert_eq!(fixes.len(), 1, "step {k}");
            let measured_at_s = f64::from(k - 3) * 0.02;
            assert!((fixes[0].measured_at_s - measured_at_s).abs() < 1e-12);
            assert_eq!(fixes[0].pose.x_m, truth(k - 3).x_m);
        }
    }
}

#[test]
fn drop_rate_over_ten_thousand_frames_is_within_one_percent() {
    for drop_probability in [0.05, 0.3] {
        let params = IpsParams {
            drop_probability,
            ..ideal()
        };
        let mut ips = IpsModel::new(&params).unwrap();
        let mut rng = rng(3);
        let delivered: usize = (0..10_000)
            .map(|k| ips.step(f64::from(k) * 0.02, truth(0), &mut rng).len())
            .sum();
        let rate = 1.0 - delivered as f64 / 10_000.0;
        assert!(
            (rate - drop_probability).abs() < 0.01,
            "p = {drop_probability}: rate {rate}"
        );
    }
}

#[test]
fn noise_is_uniform_within_its_half_widths() {
    let params = IpsParams {
        noise_position_m: 0.002,
        noise_yaw_rad: 0.01,
        ..ideal()
    };
    let mut ips = IpsModel::new(&params).unwrap();
    let mut rng = rng(4);
    let (mut max_x, mut max_yaw, mut sum_x) = (0.0_f64, 0.0_f64, 0.0);
    let pose = Pose2 {
        x_m: 1.0,
        y_m: 1.0,
        yaw_rad: 0.5,
    };
    for k in 0..5_000 {
        for fix in ips.step(f64::from(k) * 0.02, pose, &mut rng) {
            let (ex, ey, eyaw) = (fix.pose.x_m - 1.0, fix.pose.y_m - 1.0, fix.pose.yaw_rad - 0.5);
            assert!(ex.abs() <= 0.002 + 1e-15 && ey.abs() <= 0.002 + 1e-15);
            assert!(eyaw.abs() <= 0.01 + 1e-15);
            max_x = max_x.max(ex.abs());
            max_yaw = max_yaw.max(eyaw.abs());
            sum_x += ex;
        }
    }
    assert!(max_x > 0.00199 && max_yaw > 0.00999);
    assert!((sum_x / 5_000.0).abs() < 5e-5);
}

#[test]
fn same_stream_gives_the_same_fixes() {
    let run = |seed| {
        let mut ips = IpsModel::new(&IpsParams::LAB).unwrap();
        let mut rng = rng(seed);
        (0..500)
            .flat_map(|k| ips.step(f64::from(k) * 0.02, truth(k), &mut rng))
            .collect::<Vec<_>>()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn a_slow_caller_gets_one_frame_per_call() {
    let mut ips = IpsModel::new(&ideal()).unwrap();
    let mut rng = rng(7);
    for k in 0..10 {
        let t = f64::from(k) * 0.1;
        assert_eq!(ips.step(t, truth(0), &mut rng).len(), 1);
    }
}

#[test]
fn invalid_parameters_are_errors() {
    for params in [
        IpsParams {
            rate_hz: 0.0,
            ..ideal()
        },
        IpsParams {
            latency_ms: -1.0,
            ..ideal()
        },
        IpsParams {
            noise_position_m: f64::NAN,
            ..ideal()
        },
        IpsParams {
            noise_yaw_rad: -0.1,
            ..ideal()
        },
        IpsParams {
            drop_probability: 1.5,
            ..ideal()
        },
    ] {
        assert!(IpsModel::new(&params).is_err(), "{params:?}");
    }
}

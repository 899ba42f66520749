//! The MPC over the lab's grey-box model (§4), implemented here from the equations: shows
//! that a `Model` adapter for it is small, and that the lab's configuration (throttle and
//! servo move weights, 3-step delay compensation) tracks with the lab simulator's 4-step
//! input delay.

mod common;

use common::greybox::GreyBox;
use common::{PERIOD_S, circle, lane_change, run};
use cpmx_follower::{Follower, FollowerConfig, LAB_MOVE_WEIGHTS, Model, Mpc, MpcConfig};

fn follower() -> Follower<GreyBox, 4, 2> {
    Follower::new(
        Mpc::new(GreyBox, MpcConfig::lab(LAB_MOVE_WEIGHTS)),
        FollowerConfig::default(),
    )
}

fn start(reference: common::Reference) -> [f64; 4] {
    let (p, v) = reference(0.0);
    [p[0], p[1], v[1].atan2(v[0]), v[0].hypot(v[1])]
}

fn plant(x: &[f64; 4], u: &[f64; 2]) -> [f64; 4] {
    GreyBox.step(x, u, PERIOD_S)
}

#[test]
fn follows_a_circle_with_the_lab_simulators_delay() {
    let run = run(&mut follower(), plant, circle, start(circle), 4, 600);
    assert!(run.always_following());
    let (mean, max) = run.error_stats(3.0, 12.0);
    eprintln!(
        "grey box circle, 80 ms delay: mean {:.2} mm, max {:.2} mm",
        mean * 1e3,
        max * 1e3
    );
    assert!(mean < 0.015 && max < 0.03, "mean {mean} max {max}");
}

#[test]
fn follows_a_lane_change_with_the_lab_simulators_delay() {
    let run = run(&mut follower(), plant, lane_change, start(lane_change), 4, 300);
    assert!(run.always_following());
    let (mean, max) = run.error_stats(1.0, 6.0);
    eprintln!(
        "grey box lane change, 80 ms delay: mean {:.2} mm, max {:.2} mm",
        mean * 1e3,
        max * 1e3
    );
    assert!(mean < 0.015 && max < 0.03, "mean {mean} max {max}");
}

//! What a rejection leaves behind, and the window's boundaries, as the lab's
//! `MpcController.cxx` and `Controller.cxx` decide them (the lab's grey-box model and
//! configuration).
//!
//! The lab shifts its output history only at the end of `MpcController::update`
//! (`:186-194`): a refused reference returns before it (`:163-173`), a large objective stops
//! inside `optimize_control_inputs` and returns to it with the stop outputs (`:323-334`); both
//! reset the optimiser. Its controller's own stops (no command, stale command, lost IPS;
//! `Controller.cxx:376-395`) do not call the MPC at all.

mod common;

use common::PERIOD_NS;
use common::greybox::GreyBox;
use cpmx_follower::{
    Follower, FollowerConfig, LAB_MOVE_WEIGHTS, Model, Mpc, MpcConfig, Rejection, StateEstimate, Status,
    StopReason, Trajectory, TrajectoryCommand, TrajectoryPoint, WarmStart,
};

const MS: u64 = 1_000_000;
/// The clock when the tests start deciding: 5.2 s, where f64 seconds are not whole.
const T0_NS: u64 = 5_200 * MS;
const SPEED_MPS: f64 = 0.5;

fn mpc() -> Mpc<GreyBox, 4, 2> {
    Mpc::new(GreyBox, MpcConfig::lab(LAB_MOVE_WEIGHTS))
}

/// Straight along +x at 0.5 m/s (x = 0 at `T0_NS`), `offset_y_m` to the left, with points at
/// the given times.
fn straight(times_ns: &[u64], offset_y_m: f64) -> Trajectory {
    Trajectory::new(
        times_ns
            .iter()
            .map(|&t_ns| TrajectoryPoint {
                t_ns,
                x_m: SPEED_MPS * (t_ns as f64 - T0_NS as f64) * 1e-9,
                y_m: offset_y_m,
                vx_mps: SPEED_MPS,
                vy_mps: 0.0,
            })
            .collect(),
    )
    .expect("increasing times")
}

/// Points every 100 ms from 200 ms before `t_ns` to 1 s after.
fn good(t_ns: u64) -> Trajectory {
    let times: Vec<u64> = (0..=12).map(|k| t_ns - 200 * MS + k * 100 * MS).collect();
    straight(&times, 0.0)
}

/// The car on the reference at `t_ns`, slightly off to make the inputs work.
fn state_at(t_ns: u64) -> [f64; 4] {
    [SPEED_MPS * (t_ns as f64 - T0_NS as f64) * 1e-9, 0.01, 0.02, 0.45]
}

fn bits(input: [f64; 2]) -> [u64; 2] {
    input.map(f64::to_bits)
}

/// `k` accepted decisions from `T0_NS` on, one per period.
fn drive(mpc: &mut Mpc<GreyBox, 4, 2>, periods: u64) {
    for k in 0..periods {
        let t_ns = T0_NS + k * PERIOD_NS;
        mpc.solve(t_ns, &state_at(t_ns), &good(t_ns)).expect("accepted");
    }
}

fn history(mpc: &Mpc<GreyBox, 4, 2>) -> Vec<[f64; 2]> {
    mpc.input_history().copied().collect()
}

/// Every refused reference leaves the history and the previous input as they were and resets
/// the warm start; the next accepted decision then uses the outputs from before the
/// rejections: however many there were, it gives the bits of one.
#[test]
fn a_refused_reference_shifts_nothing_and_the_next_decision_uses_the_history_before_it() {
    let mut a = mpc();
    drive(&mut a, 5);
    let before = history(&a);
    let previous = *a.previous_input();
    assert_eq!(before.len(), 3);
    assert_eq!(previous, before[2]);
    assert_ne!(*a.warm_start(), WarmStart::reset());
    let mut b = a.clone();

    // Four refusals of four kinds, one period each.
    let t = |k: u64| T0_NS + k * PERIOD_NS;
    let refused = [
        // First point at the window's start (t + 110 ms).
        straight(&[t(5) + 110 * MS, t(5) + 500 * MS], 0.0),
        // Last point 1 ns before the window's end (t + 360 ms).
        straight(&[t(6) - 100 * MS, t(6) + 360 * MS - 1], 0.0),
        // One point.
        straight(&[t(7)], 0.0),
        // 0.5 m sideways within 100 ms: |a_y| far above 20 m/s².
        Trajectory::new(vec![
            TrajectoryPoint {
                t_ns: t(8) - 100 * MS,
                x_m: 0.0,
                y_m: 0.0,
                vx_mps: SPEED_MPS,
                vy_mps: 0.0,
            },
            TrajectoryPoint {
                t_ns: t(8) + 200 * MS,
                x_m: 0.15,
                y_m: 0.5,
                vx_mps: SPEED_MPS,
                vy_mps: 0.0,
            },
            TrajectoryPoint {
                t_ns: t(8) + 1000 * MS,
                x_m: 0.55,
                y_m: 0.5,
                vx_mps: SPEED_MPS,
                vy_mps: 0.0,
            },
        ])
        .unwrap(),
    ];
    for (k, trajectory) in (5..).zip(&refused) {
        let rejection = a.solve(t(k), &state_at(t(k)), trajectory).unwrap_err();
        assert!(!rejection.shifts_stop_input(), "{rejection:?}");
        assert_eq!(history(&a), before, "after {rejection:?}");
        assert_eq!(*a.previous_input(), previous);
        assert_eq!(*a.warm_start(), WarmStart::reset());
    }
    let rejection = b.solve(t(5), &state_at(t(5)), &refused[0]).unwrap_err();
    assert!(matches!(rejection, Rejection::FirstPointInFuture { .. }));

    // The next accepted decision: the same from one refusal as from four.
    let after_four = a.solve(t(9), &state_at(t(9)), &good(t(9))).expect("accepted");
    let after_one = b.solve(t(9), &state_at(t(9)), &good(t(9))).expect("accepted");
    assert_eq!(bits(after_four.input), bits(after_one.input));
    // And it entered the history as the newest output.
    assert_eq!(history(&a), vec![before[1], before[2], after_four.input]);
}

/// A large objective stops after optimising: the stop outputs are shifted into the history as
/// an accepted output is, the warm start is reset, and the next decision predicts with them.
#[test]
fn a_large_objective_shifts_the_stop_outputs() {
    let mut a = mpc();
    drive(&mut a, 5);
    let before = history(&a);
    let mut refused_reference = a.clone();

    let t5 = T0_NS + 5 * PERIOD_NS;
    let state = state_at(t5);
    // The reference 0.5 m to the left: Σ wₖ²·0.25 m² = 4.25 ≥ 1.5.
    let far: Vec<u64> = (0..=12).map(|k| t5 - 200 * MS + k * 100 * MS).collect();
    let rejection = a.solve(t5, &state, &straight(&far, 0.5)).unwrap_err();
    let Rejection::LargeObjective { objective } = rejection else {
        panic!("{rejection:?}")
    };
    assert!(objective >= 1.5);
    let stop = GreyBox.stop_input(&state);
    assert_eq!(stop, [-0.225, 0.0]);
    assert_eq!(history(&a), vec![before[1], before[2], stop]);
    assert_eq!(*a.previous_input(), stop);
    assert_eq!(*a.warm_start(), WarmStart::reset());

    // A refused reference in its place shifts nothing; the next decisions differ.
    refused_reference
        .solve(t5, &state, &straight(&[t5 + 110 * MS, t5 + 600 * MS], 0.0))
        .unwrap_err();
    let t6 = t5 + PERIOD_NS;
    let after_objective = a.solve(t6, &state_at(t6), &good(t6)).expect("accepted");
    let after_reference = refused_reference
        .solve(t6, &state_at(t6), &good(t6))
        .expect("accepted");
    assert_ne!(bits(after_objective.input), bits(after_reference.input));
}

/// The controller's own stops do not call the MPC: its history, previous input and warm start
/// stay as they were, so the next accepted decision is the one the MPC would have made
/// without them.
#[test]
fn the_controllers_own_stops_leave_the_mpc_as_it_was() {
    let mut f = Follower::new(mpc(), FollowerConfig::default());
    let estimate = |t_ns: u64, ips_update_age_ns: u64| StateEstimate {
        state: state_at(t_ns),
        ips_update_age_ns,
    };
    let command = |t_ns: u64| TrajectoryCommand {
        create_stamp_ns: t_ns,
        valid_after_ns: t_ns,
        trajectory: good(t_ns),
    };

    // Before any command: stopped, the MPC untouched.
    assert_eq!(
        f.control(T0_NS - PERIOD_NS, &estimate(T0_NS - PERIOD_NS, 0))
            .status,
        Status::Stopped(StopReason::NoCommand)
    );
    assert_eq!(history(f.mpc()), vec![[0.0; 2]; 3]);
    assert_eq!(*f.mpc().warm_start(), WarmStart::reset());

    f.receive(command(T0_NS));
    for k in 0..5 {
        let t_ns = T0_NS + k * PERIOD_NS;
        assert_eq!(f.control(t_ns, &estimate(t_ns, 0)).status, Status::Following);
    }
    let untouched = f.mpc().clone();

    // Lost IPS for three periods, then the command goes stale.
    for k in 5..8 {
        let t_ns = T0_NS + k * PERIOD_NS;
        let out = f.control(t_ns, &estimate(t_ns, 3_000 * MS + 1));
        assert!(matches!(out.status, Status::Stopped(StopReason::LostIps { .. })));
        assert_eq!(out.input, GreyBox.stop_input(&state_at(t_ns)));
    }
    let stale_ns = T0_NS + 1_000 * MS;
    assert_eq!(
        f.control(stale_ns, &estimate(stale_ns, 0)).status,
        Status::Stopped(StopReason::StaleCommand { age_ns: 1_000 * MS })
    );
    assert_eq!(history(f.mpc()), history(&untouched));
    assert_eq!(f.mpc().previous_input(), untouched.previous_input());
    assert_eq!(f.mpc().warm_start(), untouched.warm_start());

    // A new command: the decision of the MPC as it was before the stops.
    let t_ns = stale_ns + PERIOD_NS;
    f.receive(command(t_ns));
    let out = f.control(t_ns, &estimate(t_ns, 0));
    let expected = untouched
        .clone()
        .solve(t_ns, &state_at(t_ns), &good(t_ns))
        .expect("accepted");
    assert_eq!(out.status, Status::Following);
    assert_eq!(bits(out.input), bits(expected.input));
}

/// The window's boundaries as the lab decides them, at times where the same stamps in f64
/// seconds round (5.2 s, 1234.56 s, 9999.98 s): a first point exactly 110 ms ahead is refused,
/// one a nanosecond earlier accepted; a last point exactly 360 ms ahead is accepted, one a
/// nanosecond earlier refused.
#[test]
fn the_window_boundaries_decide_as_the_lab_at_large_times() {
    for t_now_ns in [
        200 * MS,
        5_200 * MS,
        1_234_560 * MS,
        9_999_980 * MS,
        10_000_000 * MS,
    ] {
        let decide = |first_ns: u64, last_ns: u64| {
            let mut f = Follower::new(mpc(), FollowerConfig::default());
            f.receive(TrajectoryCommand {
                create_stamp_ns: t_now_ns,
                valid_after_ns: t_now_ns,
                trajectory: straight(&[first_ns, last_ns], 0.0),
            });
            // On the reference at the decision (x relative to T0 is irrelevant here: only the
            // window decides).
            let x0 = SPEED_MPS * (t_now_ns as f64 - T0_NS as f64) * 1e-9;
            f.control(
                t_now_ns,
                &StateEstimate {
                    state: [x0, 0.0, 0.0, SPEED_MPS],
                    ips_update_age_ns: 0,
                },
            )
            .status
        };
        let (start, end) = (t_now_ns + 110 * MS, t_now_ns + 360 * MS);
        assert_eq!(
            decide(start, end + 100 * MS),
            Status::Stopped(StopReason::Rejected(Rejection::FirstPointInFuture {
                first_ns: start,
                window_start_ns: start
            })),
            "at {t_now_ns} ns"
        );
        assert_eq!(decide(start - 1, end), Status::Following, "at {t_now_ns} ns");
        assert_eq!(
            decide(start - 1, end - 1),
            Status::Stopped(StopReason::Rejected(Rejection::InsufficientLeadTime {
                missing_ns: 1
            })),
            "at {t_now_ns} ns"
        );
    }
}

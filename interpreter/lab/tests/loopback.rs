//! Two participants in one process on domain 217, same host only (interface and peer
//! 127.0.0.1): the middleware side publishes a `VehicleStateList`, the planner side
//! answers with a `VehicleCommandTrajectory`, each over the lab's topic and QoS.

use std::time::{Duration, Instant};

use cpmx_lab::{
    DiscoveryConfig, Header, LabError, LabParticipant, Pose2D, TimeStamp, TrajectoryPoint,
    VehicleCommandTrajectory, VehicleState, VehicleStateList, topics,
};

/// A domain no real lab uses (the lab: 21, the middleware: 1).
const TEST_DOMAIN_ID: u16 = 217;

/// The whole exchange must finish within this budget.
const BUDGET: Duration = Duration::from_secs(10);

/// How long to wait for a best-effort sample before writing it again.
const RESEND_PERIOD: Duration = Duration::from_millis(200);

fn state_list() -> VehicleStateList {
    let state = VehicleState {
        vehicle_id: 3,
        header: Header {
            create_stamp: TimeStamp { nanoseconds: 100 },
            valid_after_stamp: TimeStamp {
                nanoseconds: 60_000_100,
            },
        },
        pose: Pose2D {
            x: 2.25,
            y: 2.0,
            yaw: 1.5,
        },
        speed: 0.5,
        is_real: false,
        ..VehicleState::default()
    };
    VehicleStateList {
        t_now: 400_000_000,
        period_ms: 400,
        state_list: vec![state],
        vehicle_observation_list: Vec::new(),
        active_vehicle_ids: vec![3],
    }
}

fn command() -> VehicleCommandTrajectory {
    let point = |k: u64| TrajectoryPoint {
        t: TimeStamp {
            nanoseconds: 1_400_000_000 + k * 100_000_000,
        },
        px: 2.25,
        py: 2.0 + 0.05 * k as f64,
        vx: 0.0,
        vy: 0.5,
    };
    VehicleCommandTrajectory {
        vehicle_id: 3,
        header: Header {
            create_stamp: TimeStamp {
                nanoseconds: 400_000_000,
            },
            valid_after_stamp: TimeStamp {
                nanoseconds: 1_400_000_000,
            },
        },
        trajectory_points: (0..4).map(point).collect(),
    }
}

/// Time left of the budget that started at `started`.
fn left(started: Instant) -> Duration {
    BUDGET.saturating_sub(started.elapsed())
}

#[test]
fn state_list_and_trajectory_cross_between_two_participants() -> Result<(), LabError> {
    let started = Instant::now();
    let config = DiscoveryConfig::loopback(TEST_DOMAIN_ID);
    let middleware = LabParticipant::new(&config)?;
    let planner = LabParticipant::new(&config)?;
    assert_eq!(middleware.domain_id(), TEST_DOMAIN_ID);

    let list_writer = middleware.writer(&topics::VEHICLE_STATE_LIST)?;
    let mut list_reader = planner.reader(&topics::VEHICLE_STATE_LIST)?;
    let command_writer = planner.keyed_writer(&topics::VEHICLE_COMMAND_TRAJECTORY)?;
    let mut command_reader = middleware.keyed_reader(&topics::VEHICLE_COMMAND_TRAJECTORY)?;

    // Best effort: publish once discovery has matched the endpoints, and again until the
    // reader has it (a sample written before the reader has matched the writer is lost, as
    // best effort allows; the lab's middleware re-publishes every tick for the same reason).
    list_writer.wait_for_readers(1, left(started))?;
    let list = state_list();
    let received = loop {
        list_writer.write(list.clone())?;
        match list_reader.wait_take(RESEND_PERIOD.min(left(started))) {
            Ok(received) => break received,
            Err(LabError::Timeout { .. }) if started.elapsed() < BUDGET => continue,
            Err(e) => return Err(e),
        }
    };
    assert!(
        !received.is_empty() && received.iter().all(|r| *r == list),
        "{received:?}"
    );

    command_writer.wait_for_readers(1, left(started))?;
    let cmd = command();
    command_writer.write(cmd.clone())?;
    let received = command_reader.wait_take(left(started))?;
    assert_eq!(received, vec![cmd]);

    // Nothing else arrives (at most late copies of a re-sent list), and the non-blocking
    // helpers return at once.
    assert!(list_reader.take()?.iter().all(|r| *r == list));
    assert!(command_reader.read()?.is_empty());
    assert!(started.elapsed() < BUDGET);
    Ok(())
}

#[test]
fn ready_status_reaches_a_late_reader_through_transient_local() -> Result<(), LabError> {
    let started = Instant::now();
    let config = DiscoveryConfig::loopback(TEST_DOMAIN_ID + 1);
    let planner = LabParticipant::new(&config)?;
    let writer = planner.writer(&topics::READY_STATUS)?;
    let ready = cpmx_lab::ReadyStatus {
        source_id: "hlc_3".to_owned(),
        next_start_stamp: TimeStamp { nanoseconds: 11_111 },
    };
    writer.write(ready.clone())?;

    // The middleware joins after the announcement was written.
    let middleware = LabParticipant::new(&config)?;
    let mut reader = middleware.reader(&topics::READY_STATUS)?;
    let received = reader.wait_take(left(started))?;
    assert_eq!(received, vec![ready]);
    Ok(())
}

#[test]
fn waits_end_with_a_timeout_error() -> Result<(), LabError> {
    let participant = LabParticipant::new(&DiscoveryConfig::loopback(TEST_DOMAIN_ID + 2))?;
    let mut reader = participant.reader(&topics::SYSTEM_TRIGGER)?;
    let started = Instant::now();
    let result = reader.wait_take(Duration::from_millis(50));
    assert!(matches!(
        result,
        Err(LabError::Timeout {
            topic: "systemTrigger",
            ..
        })
    ));
    assert!(started.elapsed() < Duration::from_secs(2));
    Ok(())
}

#[test]
fn unsupported_configurations_are_typed_errors() {
    let remote = DiscoveryConfig {
        domain_id: 21,
        initial_peers: vec!["192.168.1.249".parse().expect("address")],
        interface: None,
    };
    assert!(matches!(
        LabParticipant::new(&remote),
        Err(LabError::UnsupportedInitialPeer { .. })
    ));
    assert!(matches!(
        LabParticipant::new(&DiscoveryConfig::loopback(233)),
        Err(LabError::DomainOutOfRange { domain: 233 })
    ));
}

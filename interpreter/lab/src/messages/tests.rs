//! Byte tests: for every message type, the XCDR1 little-endian body written out by hand
//! from the IDL and the reference's §2.1 layouts (8-byte members aligned to 8 relative to
//! the body start, sequences as u32 count + elements, strings as u32 length incl. NUL +
//! bytes + NUL), compared with rustdds' serializer, then decoded back.

use super::*;

/// Hand-assembled expected bytes; `at` pins the offset a field must start at.
#[derive(Default)]
struct Expected(Vec<u8>);

impl Expected {
    fn at(self, offset: usize) -> Self {
        assert_eq!(self.0.len(), offset, "hand layout is off");
        self
    }
    fn pad(mut self, count: usize) -> Self {
        self.0.extend(std::iter::repeat_n(0, count));
        self
    }
    fn u8(mut self, v: u8) -> Self {
        self.0.push(v);
        self
    }
    fn u32(mut self, v: u32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn i32(mut self, v: i32) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(mut self, v: u64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn f64(mut self, v: f64) -> Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn raw(mut self, bytes: &[u8]) -> Self {
        self.0.extend_from_slice(bytes);
        self
    }
}

/// Serialises, compares with `expected`, decodes back and compares with `value`.
fn assert_wire<T: LabMessage + PartialEq + std::fmt::Debug>(value: &T, expected: &[u8]) {
    let body = encode_cdr(value).expect("encodes");
    assert_eq!(body, expected, "{} bytes differ", T::TYPE_NAME);
    let back: T = decode_cdr(&body).expect("decodes");
    assert_eq!(&back, value);
}

fn header(create_ns: u64, valid_after_ns: u64) -> Header {
    Header {
        create_stamp: TimeStamp {
            nanoseconds: create_ns,
        },
        valid_after_stamp: TimeStamp {
            nanoseconds: valid_after_ns,
        },
    }
}

fn pose(x: f64, y: f64, yaw: f64) -> Pose2D {
    Pose2D { x, y, yaw }
}

fn state(vehicle_id: u8, base: f64) -> VehicleState {
    VehicleState {
        vehicle_id,
        header: header(1_000 + u64::from(vehicle_id), 2_000 + u64::from(vehicle_id)),
        pose: pose(base, base + 0.5, base + 0.25),
        ips_update_age_nanoseconds: 20_000_000,
        odometer_distance: 12.5,
        imu_acceleration_forward: 0.125,
        imu_acceleration_left: -0.25,
        imu_acceleration_up: 9.75,
        imu_yaw: 1.5,
        imu_yaw_rate: -0.5,
        speed: 0.75,
        battery_voltage: 7.8,
        motor_current: 0.2,
        motor_throttle: 0.3,
        steering_servo: -0.1,
        is_real: true,
    }
}

/// The layout of a `VehicleState` whose `vehicle_id` sits at body offset `start`: the
/// header is aligned to the next multiple of 8, every later member follows unpadded.
fn expect_state(e: Expected, s: &VehicleState, start: usize) -> Expected {
    let aligned = (start + 1).next_multiple_of(8);
    e.at(start)
        .u8(s.vehicle_id)
        .pad(aligned - start - 1)
        .at(aligned)
        .u64(s.header.create_stamp.nanoseconds)
        .u64(s.header.valid_after_stamp.nanoseconds)
        .at(aligned + 16)
        .f64(s.pose.x)
        .f64(s.pose.y)
        .f64(s.pose.yaw)
        .at(aligned + 40)
        .u64(s.ips_update_age_nanoseconds)
        .at(aligned + 48)
        .f64(s.odometer_distance)
        .f64(s.imu_acceleration_forward)
        .f64(s.imu_acceleration_left)
        .f64(s.imu_acceleration_up)
        .f64(s.imu_yaw)
        .f64(s.imu_yaw_rate)
        .f64(s.speed)
        .f64(s.battery_voltage)
        .f64(s.motor_current)
        .at(aligned + 120)
        .f64(s.motor_throttle)
        .f64(s.steering_servo)
        .at(aligned + 136)
        .u8(u8::from(s.is_real))
}

#[test]
fn system_trigger_is_one_u64_and_stop_is_all_ones() {
    let start = SystemTrigger {
        next_start: TimeStamp {
            nanoseconds: 0x0102_0304_0506_0708,
        },
    };
    assert_wire(&start, &[8, 7, 6, 5, 4, 3, 2, 1]);
    let stop = SystemTrigger {
        next_start: TimeStamp::STOP,
    };
    assert_wire(&stop, &[0xff; 8]);
    assert!(stop.is_stop() && !start.is_stop());
}

#[test]
fn stop_request_is_one_octet() {
    assert_wire(&StopRequest { vehicle_id: 7 }, &[7]);
}

#[test]
fn ready_status_string_has_length_with_nul_then_stamp_at_16() {
    let ready = ReadyStatus {
        source_id: "hlc_3".to_owned(),
        next_start_stamp: TimeStamp { nanoseconds: 11_111 },
    };
    // u32 6 @0, "hlc_3\0" @4..10, pad to 16, u64 11111 = 0x2B67 @16..24.
    let expected = [
        6, 0, 0, 0, b'h', b'l', b'c', b'_', b'3', 0, 0, 0, 0, 0, 0, 0, 0x67, 0x2b, 0, 0, 0, 0, 0, 0,
    ];
    assert_wire(&ready, &expected);
}

#[test]
fn vehicle_observation_is_48_bytes() {
    let obs = VehicleObservation {
        vehicle_id: 3,
        header: header(1_700_000_000_000_000_000, 1_700_000_000_020_000_000),
        pose: pose(1.0, 2.5, -0.75),
    };
    let expected = Expected::default()
        .u8(3)
        .pad(7)
        .at(8)
        .u64(1_700_000_000_000_000_000)
        .u64(1_700_000_000_020_000_000)
        .at(24)
        .raw(&[0, 0, 0, 0, 0, 0, 0xf0, 0x3f]) // 1.0
        .raw(&[0, 0, 0, 0, 0, 0, 0x04, 0x40]) // 2.5
        .raw(&[0, 0, 0, 0, 0, 0, 0xe8, 0xbf]) // -0.75
        .at(48);
    assert_wire(&obs, &expected.0);
}

#[test]
fn vehicle_state_is_145_bytes_with_is_real_last() {
    let s = state(5, 1.25);
    let expected = expect_state(Expected::default(), &s, 0).at(145);
    assert_wire(&s, &expected.0);
}

#[test]
fn vehicle_state_list_pads_each_element_relative_to_the_body() {
    let list = VehicleStateList {
        t_now: 1_700_000_000_400_000_000,
        period_ms: 400,
        state_list: vec![state(1, 0.5), state(7, 3.0)],
        vehicle_observation_list: vec![VehicleObservation {
            vehicle_id: 1,
            header: header(10, 20),
            pose: pose(0.5, 1.0, 0.25),
        }],
        active_vehicle_ids: vec![1, 7],
    };
    // t_now @0, period @8, count 2 @16; state 0 id @20, header @24 … is_real @160;
    // state 1 id @161, header @168 … is_real @304; pad to 308, count 1 @308, observation
    // id @312, header @320, pose @336..360; count 2 @360, ids @364, @368 → 372 bytes.
    let e = Expected::default().u64(list.t_now).at(8).u64(400).at(16).u32(2);
    let e = expect_state(e, &list.state_list[0], 20).at(161);
    let e = expect_state(e, &list.state_list[1], 161).at(305);
    let expected = e
        .pad(3)
        .at(308)
        .u32(1)
        .at(312)
        .u8(1)
        .pad(7)
        .at(320)
        .u64(10)
        .u64(20)
        .at(336)
        .f64(0.5)
        .f64(1.0)
        .f64(0.25)
        .at(360)
        .u32(2)
        .i32(1)
        .i32(7)
        .at(372);
    assert_wire(&list, &expected.0);
}

#[test]
fn empty_vehicle_state_list_is_28_bytes() {
    let list = VehicleStateList {
        t_now: 5,
        period_ms: 200,
        ..VehicleStateList::default()
    };
    let expected = Expected::default().u64(5).u64(200).u32(0).u32(0).u32(0).at(28);
    assert_wire(&list, &expected.0);
}

#[test]
fn vehicle_command_trajectory_is_32_plus_40_per_point() {
    let cmd = VehicleCommandTrajectory {
        vehicle_id: 2,
        header: header(100, 1_000_000_100),
        trajectory_points: vec![
            TrajectoryPoint {
                t: TimeStamp {
                    nanoseconds: 1_000_000_000,
                },
                px: 1.0,
                py: 2.0,
                vx: 0.5,
                vy: 0.0,
            },
            TrajectoryPoint {
                t: TimeStamp {
                    nanoseconds: 1_200_000_000,
                },
                px: 1.1,
                py: 2.0,
                vx: 0.5,
                vy: -0.0,
            },
        ],
    };
    let mut e = Expected::default()
        .u8(2)
        .pad(7)
        .at(8)
        .u64(100)
        .u64(1_000_000_100)
        .at(24)
        .u32(2)
        .pad(4)
        .at(32);
    for p in &cmd.trajectory_points {
        e = e.u64(p.t.nanoseconds).f64(p.px).f64(p.py).f64(p.vx).f64(p.vy);
    }
    let expected = e.at(32 + 40 * 2);
    assert_wire(&cmd, &expected.0);
}

#[test]
fn vehicle_command_path_tracking_has_speed_after_the_points() {
    let cmd = VehicleCommandPathTracking {
        vehicle_id: 4,
        header: header(7, 8),
        path: vec![
            PathPoint {
                pose: pose(0.0, 0.0, 0.0),
                s: 0.0,
            },
            PathPoint {
                pose: pose(1.0, 0.0, 0.5),
                s: 1.0,
            },
        ],
        speed: 0.8,
    };
    let mut e = Expected::default()
        .u8(4)
        .pad(7)
        .u64(7)
        .u64(8)
        .at(24)
        .u32(2)
        .pad(4)
        .at(32);
    for p in &cmd.path {
        e = e.f64(p.pose.x).f64(p.pose.y).f64(p.pose.yaw).f64(p.s);
    }
    let expected = e.at(96).f64(0.8).at(104);
    assert_wire(&cmd, &expected.0);
}

#[test]
fn speed_curvature_and_direct_commands_are_40_bytes() {
    let sc = VehicleCommandSpeedCurvature {
        vehicle_id: 9,
        header: header(1, 2),
        speed: 0.6,
        curvature: -1.5,
    };
    let expected = Expected::default()
        .u8(9)
        .pad(7)
        .u64(1)
        .u64(2)
        .at(24)
        .f64(0.6)
        .f64(-1.5)
        .at(40);
    assert_wire(&sc, &expected.0);

    let direct = VehicleCommandDirect {
        vehicle_id: 10,
        header: header(3, 4),
        motor_throttle: 0.25,
        steering_servo: -1.0,
    };
    let expected = Expected::default()
        .u8(10)
        .pad(7)
        .u64(3)
        .u64(4)
        .at(24)
        .f64(0.25)
        .f64(-1.0)
        .at(40);
    assert_wire(&direct, &expected.0);
}

#[test]
fn decoding_tolerates_rtps_alignment_padding_after_the_body() {
    // RTPS pads serialized payloads to a multiple of 4; 145 B state ⇒ 3 trailing bytes.
    let s = state(6, 2.0);
    let mut body = encode_cdr(&s).expect("encodes");
    body.extend_from_slice(&[0, 0, 0]);
    assert_eq!(decode_cdr::<VehicleState>(&body).expect("decodes"), s);
}

#[test]
fn truncated_bodies_are_decode_errors_not_panics() {
    let body = encode_cdr(&state(6, 2.0)).expect("encodes");
    for len in [0, 1, 8, 100, 144] {
        let result = decode_cdr::<VehicleState>(&body[..len]);
        assert!(
            matches!(
                result,
                Err(LabError::Decode {
                    type_name: "VehicleState",
                    ..
                })
            ),
            "{len}"
        );
    }
    let list = encode_cdr(&VehicleStateList::default()).expect("encodes");
    assert!(decode_cdr::<VehicleStateList>(&list[..20]).is_err());
}

#[test]
fn keyed_types_key_on_vehicle_id_with_rti_key_hash() {
    use rustdds::Key;
    let s = state(42, 0.0);
    assert_eq!(s.key(), 42);
    // RTI and rustdds: key hash = big-endian CDR of the key members, zero-padded to 16 B.
    let mut expected = [0u8; 16];
    expected[0] = 42;
    assert_eq!(s.key().hash_key(false).to_vec(), expected.to_vec());
    assert_eq!(StopRequest { vehicle_id: 3 }.key(), 3);
}

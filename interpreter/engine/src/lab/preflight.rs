//! The preflight: before a lab run plans its first tick, the lab's state lists must show every
//! vehicle of the run reporting, with a fresh positioning fix, a charged battery, and standing
//! at its planned start (position and heading within the spec's tolerances). Until they do
//! the driver keeps the vehicles standing and the operator is shown the table: each vehicle,
//! where it is, where it should be and how far off it is. A misplaced vehicle is accepted with
//! `misplaced: record`; the run then starts where the vehicles stand and records it.

use std::fmt::Write as _;

use cpmx_lab::{VehicleState, VehicleStateList};
use cpmx_spec::model::{Misplaced, Preflight};

use crate::starts::InitialState;

/// What a state list says about the run's vehicles.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Verdict {
    /// One row per vehicle, in agent order.
    rows: Vec<Row>,
    position_tolerance_m: f64,
    heading_tolerance_deg: f64,
}

/// One vehicle in the preflight's table.
#[derive(Debug, Clone, PartialEq)]
struct Row {
    vehicle_id: u8,
    /// Where it reports to be: x, y [m], yaw [rad]; `None` when it does not report.
    at: Option<[f64; 3]>,
    /// Its planned start.
    planned: [f64; 3],
    /// Problems other than its place (no state, old fix, low battery).
    problems: Vec<String>,
    /// Off its start beyond the tolerances.
    misplaced: bool,
}

impl Row {
    /// Distance [m] and heading difference [deg] from the planned start.
    fn off(&self) -> Option<(f64, f64)> {
        let at = self.at?;
        let distance_m = (at[0] - self.planned[0]).hypot(at[1] - self.planned[1]);
        let heading_deg = cpmx_sensing::wrap_angle_rad(at[2] - self.planned[2])
            .abs()
            .to_degrees();
        Some((distance_m, heading_deg))
    }
}

/// Checks the newest state of each vehicle in `list` against the preflight.
pub(super) fn check(
    preflight: &Preflight,
    list: &VehicleStateList,
    vehicle_ids: &[u8],
    starts: &[InitialState],
) -> Verdict {
    let rows = vehicle_ids
        .iter()
        .zip(starts)
        .map(|(id, start)| {
            let planned = [start.x_m, start.y_m, start.yaw_rad];
            let state = newest_state(list, *id);
            let mut row = Row {
                vehicle_id: *id,
                at: state.map(|s| [s.pose.x, s.pose.y, s.pose.yaw]),
                planned,
                problems: Vec::new(),
                misplaced: false,
            };
            let Some(state) = state else {
                row.problems.push("no state in the lab's list".into());
                return row;
            };
            let age_ms = state.ips_update_age_nanoseconds as f64 / 1e6;
            if age_ms > preflight.max_ips_age_ms {
                row.problems.push(format!(
                    "positioning fix {age_ms:.0} ms old (at most {} ms)",
                    preflight.max_ips_age_ms
                ));
            }
            if state.battery_voltage.is_nan() || state.battery_voltage < preflight.min_battery_v {
                row.problems.push(format!(
                    "battery {:.2} V (at least {} V)",
                    state.battery_voltage, preflight.min_battery_v
                ));
            }
            if let Some((distance_m, heading_deg)) = row.off() {
                row.misplaced = !(distance_m <= preflight.position_tolerance_m
                    && heading_deg <= preflight.heading_tolerance_deg);
            }
            row
        })
        .collect();
    Verdict {
        rows,
        position_tolerance_m: preflight.position_tolerance_m,
        heading_tolerance_deg: preflight.heading_tolerance_deg,
    }
}

/// The newest usable state of vehicle `id` in `list` (default-constructed entries and
/// non-finite poses are none).
fn newest_state(list: &VehicleStateList, id: u8) -> Option<&VehicleState> {
    list.state_list
        .iter()
        .filter(|s| s.vehicle_id == id && s.header.create_stamp.nanoseconds > 0)
        .filter(|s| [s.pose.x, s.pose.y, s.pose.yaw].iter().all(|v| v.is_finite()))
        .max_by_key(|s| s.header.create_stamp)
}

impl Verdict {
    /// Whether the run may start: nothing but misplaced vehicles, and those only if recorded.
    pub fn passes(&self, misplaced: Misplaced) -> bool {
        self.rows
            .iter()
            .all(|r| r.problems.is_empty() && (!r.misplaced || misplaced == Misplaced::Record))
    }

    /// One line: how many vehicles have which problems.
    pub fn headline(&self) -> String {
        let misplaced = self.rows.iter().filter(|r| r.misplaced).count();
        let other = self.rows.iter().filter(|r| !r.problems.is_empty()).count();
        let mut parts = Vec::new();
        if misplaced > 0 {
            parts.push(format!(
                "{misplaced} of {} vehicles off their planned start (tolerance {} m, {}°)",
                self.rows.len(),
                self.position_tolerance_m,
                self.heading_tolerance_deg
            ));
        }
        if other > 0 {
            parts.push(format!("{other} of {} vehicles not ready", self.rows.len()));
        }
        if parts.is_empty() {
            parts.push(format!("all {} vehicles ready", self.rows.len()));
        }
        parts.join("; ")
    }

    /// The table: each vehicle, where it is, where it should be, how far off, what is wrong.
    pub fn table(&self) -> String {
        let mut out = format!(
            "{:>7}  {:<24}  {:<24}  {:<16}  {}\n",
            "vehicle", "at (x m, y m, yaw °)", "planned (x m, y m, yaw °)", "off", "check"
        );
        let pose = |p: [f64; 3]| format!("({:.3}, {:.3}, {:.1})", p[0], p[1], p[2].to_degrees());
        for row in &self.rows {
            let at = row.at.map_or_else(|| "-".to_owned(), pose);
            let off = row.off().map_or_else(
                || "-".to_owned(),
                |(d, h)| format!("{:.1} cm, {h:.1}°", d * 100.0),
            );
            let mut check = row.problems.clone();
            if row.misplaced {
                check.push("off its start".into());
            }
            if check.is_empty() {
                check.push("ok".into());
            }
            let _ = writeln!(
                out,
                "{:>7}  {at:<24}  {:<24}  {off:<16}  {}",
                row.vehicle_id,
                pose(row.planned),
                check.join("; ")
            );
        }
        out
    }

    /// A note of where the misplaced vehicles started, for the run's record.
    pub fn recorded_starts(&self) -> Option<String> {
        let moved: Vec<String> = self
            .rows
            .iter()
            .filter(|r| r.misplaced)
            .filter_map(|r| {
                let at = r.at?;
                let (d, h) = r.off()?;
                Some(format!(
                    "vehicle {} at ({:.3}, {:.3}, {:.1}°), planned ({:.3}, {:.3}, {:.1}°): {:.1} cm, {h:.1}° off",
                    r.vehicle_id,
                    at[0],
                    at[1],
                    at[2].to_degrees(),
                    r.planned[0],
                    r.planned[1],
                    r.planned[2].to_degrees(),
                    d * 100.0
                ))
            })
            .collect();
        (!moved.is_empty()).then(|| {
            format!(
                "started off the planned start (`misplaced: record`; the recording's first sample is \
                 the actual start): {}",
                moved.join("; ")
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use cpmx_lab::{Header, Pose2D, TimeStamp};

    use super::*;

    fn state(id: u8, x: f64, yaw: f64) -> VehicleState {
        VehicleState {
            vehicle_id: id,
            header: Header {
                create_stamp: TimeStamp { nanoseconds: 5 },
                valid_after_stamp: TimeStamp { nanoseconds: 5 },
            },
            pose: Pose2D { x, y: 1.0, yaw },
            ips_update_age_nanoseconds: 40_000_000,
            battery_voltage: 7.8,
            ..VehicleState::default()
        }
    }

    fn start(x_m: f64) -> InitialState {
        InitialState {
            ref_path: 0,
            x_m,
            y_m: 1.0,
            yaw_rad: 0.0,
            speed_mps: 0.0,
        }
    }

    #[test]
    fn a_vehicle_ten_centimetres_off_is_refused_with_the_table() {
        let list = VehicleStateList {
            state_list: vec![state(1, 0.5, 0.0), state(2, 2.1, 0.0)],
            ..VehicleStateList::default()
        };
        let verdict = check(&Preflight::default(), &list, &[1, 2], &[start(0.5), start(2.0)]);
        assert!(!verdict.passes(Misplaced::Wait));
        assert!(verdict.passes(Misplaced::Record));
        let table = verdict.table();
        assert!(table.contains("(2.100, 1.000, 0.0)"), "{table}");
        assert!(table.contains("(2.000, 1.000, 0.0)"), "{table}");
        assert!(table.contains("10.0 cm, 0.0°"), "{table}");
        assert!(table.contains("off its start"), "{table}");
        assert!(
            verdict.headline().contains("1 of 2 vehicles off"),
            "{}",
            verdict.headline()
        );
        let note = verdict.recorded_starts().expect("a misplaced vehicle");
        assert!(note.contains("vehicle 2 at (2.100, 1.000, 0.0°)"), "{note}");
    }

    #[test]
    fn silent_stale_and_flat_vehicles_are_not_ready_whatever_the_option() {
        let mut old = state(1, 0.5, 0.0);
        old.ips_update_age_nanoseconds = 2_000_000_000;
        let mut flat = state(3, 4.0, 0.05);
        flat.battery_voltage = 6.5;
        let list = VehicleStateList {
            state_list: vec![old, flat],
            ..VehicleStateList::default()
        };
        let verdict = check(
            &Preflight::default(),
            &list,
            &[1, 2, 3],
            &[start(0.5), start(2.0), start(4.0)],
        );
        assert!(!verdict.passes(Misplaced::Record));
        let table = verdict.table();
        assert!(table.contains("positioning fix 2000 ms old"), "{table}");
        assert!(table.contains("no state in the lab's list"), "{table}");
        assert!(table.contains("battery 6.50 V"), "{table}");
        assert!(!table.contains("off its start"), "2.9° is within 5°: {table}");
    }
}

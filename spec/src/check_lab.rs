//! Checks of a lab fidelity's `faults` (or a `cpmx lab emulate --faults` file) that the schema
//! cannot state: the vehicles they name are the lab's, and their times are times.

use crate::check::{CheckContext, check_distribution};
use crate::diagnostic::Problem;
use crate::model::{LabFaults, Parameter, ParameterRange};

/// Times from a run's start: 0 or later.
const START_TIME: ParameterRange = ParameterRange {
    min: 0.0,
    min_exclusive: false,
    max: f64::INFINITY,
};

/// Durations: above 0.
const DURATION: ParameterRange = ParameterRange {
    min: 0.0,
    min_exclusive: true,
    max: f64::INFINITY,
};

/// Checks `faults` found at the JSON pointer `pointer`, for a lab with `vehicle_ids`.
pub(crate) fn check_faults(
    faults: &LabFaults,
    vehicle_ids: &[u8],
    pointer: &str,
    ctx: &mut CheckContext<'_>,
) {
    let vehicles = faults
        .leave_lists
        .iter()
        .enumerate()
        .map(|(i, f)| ("leave_lists", i, f.vehicle))
        .chain(
            faults
                .ips_loss
                .iter()
                .enumerate()
                .map(|(i, f)| ("ips_loss", i, f.vehicle)),
        )
        .chain(
            faults
                .misplaced
                .iter()
                .enumerate()
                .map(|(i, f)| ("misplaced", i, f.vehicle)),
        )
        .chain(
            faults
                .low_battery
                .iter()
                .enumerate()
                .map(|(i, f)| ("low_battery", i, f.vehicle)),
        );
    for (key, i, vehicle) in vehicles {
        if !vehicle_ids.contains(&vehicle) {
            let span = ctx.span(&format!("{pointer}/{key}/{i}/vehicle"));
            ctx.push(
                Problem::error(
                    "cpmx::check::faults",
                    format!("the faults name vehicle {vehicle}, which the lab fidelity does not drive"),
                    span,
                    "not in `vehicle_ids`",
                )
                .with_help(format!("the lab's vehicles are {vehicle_ids:?}")),
            );
        }
    }

    // Times and durations, drawn per run.
    let mut times: Vec<(String, &Parameter, ParameterRange)> = Vec::new();
    for (i, f) in faults.leave_lists.iter().enumerate() {
        times.push((format!("leave_lists/{i}/at_s"), &f.at_s, START_TIME));
        if let Some(for_s) = &f.for_s {
            times.push((format!("leave_lists/{i}/for_s"), for_s, DURATION));
        }
    }
    for (i, f) in faults.ips_loss.iter().enumerate() {
        times.push((format!("ips_loss/{i}/at_s"), &f.at_s, START_TIME));
        if let Some(for_s) = &f.for_s {
            times.push((format!("ips_loss/{i}/for_s"), for_s, DURATION));
        }
    }
    for (i, f) in faults.pauses.iter().enumerate() {
        times.push((format!("pauses/{i}/at_s"), &f.at_s, START_TIME));
        times.push((format!("pauses/{i}/for_s"), &f.for_s, DURATION));
    }
    for (i, f) in faults.restarts.iter().enumerate() {
        times.push((format!("restarts/{i}/at_s"), &f.at_s, START_TIME));
    }
    for (topic, f) in faults.topics.each() {
        if let Some(delay) = &f.delay_ms {
            times.push((format!("topics/{topic}/delay_ms"), delay, START_TIME));
        }
    }
    for (at, value, range) in times {
        let at = format!("{pointer}/{at}");
        let what = format!("`{}`", at.rsplit('/').next().unwrap_or_default());
        match value {
            Parameter::Fixed(v) if !range.contains(*v) => {
                let span = ctx.span(&at);
                ctx.push(Problem::error(
                    "cpmx::check::faults",
                    format!("{what} of a fault is {v}, outside {range}"),
                    span,
                    format!("outside {range}"),
                ));
            }
            Parameter::Fixed(_) => {}
            Parameter::Drawn(distribution) => check_distribution(&what, &at, *distribution, range, ctx),
        }
    }
}

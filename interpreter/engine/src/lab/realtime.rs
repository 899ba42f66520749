//! The emulator on the wall clock, as the lab runs: the vehicles step every 20 ms and the
//! middleware ticks every period whether the planner answered or not. A command is handed to
//! its vehicle when it arrives and taken at the vehicle's next step, so a late plan finds the
//! car further along and an expired one makes it stop, as on the cars. A pause silences the
//! middleware while the vehicles drive on; a restart brings a new participant and a new start
//! trigger (the vehicles catch up on their steps afterwards, on the same clock).
//!
//! The vehicles' clock is tied to the wall clock at the run's start: step `k` is due
//! `k · 20 ms` after it. Every list carries the run's start trigger (the trigger's writer is
//! reliable: a lost one comes again). The run ends `timing.steps` ticks after the first tick
//! the planner answered with a trajectory (ticks before, while its preflight keeps the
//! vehicles standing, do not count), when the planner, having driven, stops every vehicle (its
//! safe stop), or when it is silent for the lab fidelity's `timeout_s`.

use std::thread;
use std::time::{Duration, Instant};

use super::emulator::{EmulateError, EmulatorEvent, RunRules};
use super::safe_stop::is_stop_command;
use super::stage::Stage;
use super::wire::Wire;
use cpmx_stack::{CONTROL_PERIOD_NS, RUN_START_NS};

/// How long the emulator sleeps between looks at its readers.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// Plays one run on the wall clock.
pub(super) fn play(
    stage: &mut Stage,
    wire: &mut Wire,
    rules: &RunRules,
    on_event: &mut dyn FnMut(EmulatorEvent),
) -> Result<EmulatorEvent, EmulateError> {
    let substeps = stage.dt_ns / CONTROL_PERIOD_NS;
    let mut start = stage.start_trigger(stage.tick_ns(0));
    // Per vehicle: whether the newest command it received stops it.
    let mut stopped = vec![false; stage.ids.len()];
    let mut last_planned: Option<u64> = None;
    let mut first_driven: Option<u64> = None;
    let mut last_answer = Instant::now();
    let mut restarts = stage.faults.restarts.clone().into_iter().peekable();
    let origin = Instant::now();
    let mut step: u64 = 0;
    loop {
        let now_ns = RUN_START_NS + step * CONTROL_PERIOD_NS;

        // Until the step is due: commands reach their vehicles as they arrive.
        let due = origin + Duration::from_nanos(step * CONTROL_PERIOD_NS);
        loop {
            for command in wire.commands()? {
                let Some(tick) = stage.tick_of(&command) else {
                    continue;
                };
                let stop = is_stop_command(&command);
                if !stop {
                    first_driven = Some(first_driven.map_or(tick, |first| first.min(tick)));
                    last_planned = last_planned.max(Some(tick));
                }
                if let Some(agent) = stage.ids.iter().position(|id| *id == command.vehicle_id) {
                    stopped[agent] = stop;
                }
                last_answer = Instant::now();
                stage.receive(&command);
            }
            // A planner that drove and now stops every vehicle has ended the run.
            if let (Some(first), Some(last)) = (first_driven, last_planned)
                && stopped.iter().all(|s| *s)
            {
                let ticks = (last - first + 1) as usize;
                return Ok(if ticks >= rules.steps {
                    EmulatorEvent::Finished { ticks }
                } else {
                    EmulatorEvent::Ended { ticks }
                });
            }
            wire.flush()?;
            if wire.other_run_announced(rules.stamp)? {
                return Ok(EmulatorEvent::Superseded {
                    ticks: driven(first_driven, step / substeps) as usize,
                });
            }
            if last_answer.elapsed() >= rules.timeout {
                return Ok(EmulatorEvent::Abandoned {
                    ticks: driven(first_driven, step / substeps) as usize,
                });
            }
            if Instant::now() >= due {
                break;
            }
            thread::sleep(POLL_INTERVAL);
        }

        // A tick: the run's end, the middleware's faults, the list.
        if step.is_multiple_of(substeps) {
            let tick = step / substeps;
            if driven(first_driven, tick) >= rules.steps as u64 {
                return Ok(EmulatorEvent::Finished {
                    ticks: driven(first_driven, tick) as usize,
                });
            }
            if restarts.next_if(|at_ns| *at_ns <= now_ns).is_some() {
                on_event(EmulatorEvent::Fault(format!("restarting at tick {tick}")));
                if !wire.restart(rules.stamp, &stage.ids, rules.timeout)? {
                    return Ok(EmulatorEvent::Abandoned {
                        ticks: driven(first_driven, tick) as usize,
                    });
                }
                // The vehicles drove on meanwhile: their steps catch up from here.
                start = stage.start_trigger(now_ns);
            }
            let paused = stage.faults.paused(now_ns);
            if paused && !stage.faults.paused(now_ns.saturating_sub(stage.dt_ns)) {
                on_event(EmulatorEvent::Fault(format!("paused at tick {tick}")));
            }
            if !paused {
                wire.send_trigger(start);
                let list = stage.list(now_ns);
                wire.send_list(list);
                wire.flush()?;
            }
        }
        stage.step(now_ns);
        if rules.on_collision && step.is_multiple_of(substeps) && stage.collided() {
            return Ok(EmulatorEvent::Finished {
                ticks: driven(first_driven, step / substeps) as usize,
            });
        }
        step += 1;
    }
}

/// Ticks since the first one the planner drove (none before it).
fn driven(first_driven: Option<u64>, tick: u64) -> u64 {
    first_driven.map_or(0, |first| tick.saturating_sub(first))
}

//! The emulator on the wall clock, as the lab runs: the vehicles step every 20 ms and the
//! middleware ticks every period whether the planner answered or not. A command is handed to
//! its vehicle when it arrives and taken at the vehicle's next step, so a late plan finds the
//! car further along and an expired one makes it stop, as on the cars. A pause silences the
//! middleware while the vehicles drive on; a restart brings a new participant and a new start
//! trigger (the vehicles catch up on their steps afterwards, on the same clock).
//!
//! The vehicles' clock is tied to the wall clock at the run's start: step `k` is due
//! `k · 20 ms` after it. Every list carries the run's start trigger (the trigger's writer is
//! reliable: a lost one comes again). The run ends once the planner answered `timing.steps`
//! ticks with trajectories (ticks before, while its preflight keeps the vehicles standing, do
//! not count, nor do ticks it missed: a planner that skips a list, or a pause, does not shorten
//! its run), when the planner, having driven, stops every vehicle (its safe stop), or when it
//! is silent for the lab fidelity's `timeout_s`.

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
    // The ticks the planner answered with a trajectory: how many, and the newest.
    let mut planned: usize = 0;
    let mut last_planned: Option<u64> = None;
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
                if !stop && last_planned.is_none_or(|last| tick > last) {
                    planned += 1;
                    last_planned = Some(tick);
                }
                if let Some(agent) = stage.ids.iter().position(|id| *id == command.vehicle_id) {
                    stopped[agent] = stop;
                }
                last_answer = Instant::now();
                stage.receive(&command);
            }
            // A planner that drove and now stops every vehicle has ended the run.
            if planned > 0 && stopped.iter().all(|s| *s) {
                return Ok(if planned >= rules.steps {
                    EmulatorEvent::Finished { ticks: planned }
                } else {
                    EmulatorEvent::Ended { ticks: planned }
                });
            }
            wire.flush()?;
            if wire.other_run_announced(rules.stamp)? {
                return Ok(EmulatorEvent::Superseded { ticks: planned });
            }
            if last_answer.elapsed() >= rules.timeout {
                return Ok(EmulatorEvent::Abandoned { ticks: planned });
            }
            if Instant::now() >= due {
                break;
            }
            thread::sleep(POLL_INTERVAL);
        }

        // A tick: the run's end, the middleware's faults, the list.
        if step.is_multiple_of(substeps) {
            let tick = step / substeps;
            if planned >= rules.steps {
                return Ok(EmulatorEvent::Finished { ticks: planned });
            }
            if restarts.next_if(|at_ns| *at_ns <= now_ns).is_some() {
                on_event(EmulatorEvent::Fault(format!("restarting at tick {tick}")));
                if !wire.restart(rules.stamp, &stage.ids, rules.timeout)? {
                    return Ok(EmulatorEvent::Abandoned { ticks: planned });
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
            return Ok(EmulatorEvent::Finished { ticks: planned });
        }
        step += 1;
    }
}

//! The emulator in simulated time, as the lab's `--simulated_time` mode: the clock advances by
//! `timing.dt` only when every vehicle's command for the tick arrived, so a run is as fast as
//! the driver, does not depend on the machine's load, and replays exactly. Unanswered lists
//! are sent again every [`RESEND_INTERVAL`] (a best-effort topic), each with the run's start
//! trigger (a reliable one: a lost trigger comes again). A pause stops the lab's clock with the
//! middleware (the planner sees a silence, the vehicles do not move); a restart brings a new
//! participant and a new start trigger at the tick. The run ends after `timing.steps` ticks
//! the planner drove, or when, having driven, it stops every vehicle (its safe stop).

use std::thread;
use std::time::{Duration, Instant};

use cpmx_lab::{SystemTrigger, VehicleCommandTrajectory, VehicleStateList};

use super::emulator::{EmulateError, EmulatorEvent, RunRules};
use super::safe_stop::is_stop_command;
use super::stage::Stage;
use super::wire::Wire;

/// How often the emulator polls its readers.
const POLL_INTERVAL: Duration = Duration::from_millis(1);

/// How long an unanswered state list (and the start trigger) waits before it is re-sent.
pub const RESEND_INTERVAL: Duration = Duration::from_millis(100);

/// Plays one run in lock-step until it has `steps` ticks driven by the planner (ticks before
/// its first trajectory, while its preflight keeps the vehicles standing, do not count).
pub(super) fn play(
    stage: &mut Stage,
    wire: &mut Wire,
    rules: &RunRules,
    on_event: &mut dyn FnMut(EmulatorEvent),
) -> Result<EmulatorEvent, EmulateError> {
    let mut start = stage.start_trigger(stage.tick_ns(0));
    let mut driven = 0;
    let mut driving = false;
    let mut restarts = stage.faults.restarts.clone().into_iter().peekable();
    let mut pauses = stage.faults.pauses.clone();
    let mut tick = 0;
    while driven < rules.steps {
        let tick_ns = stage.tick_ns(tick);

        // The middleware's faults due at this tick.
        if let Some(i) = pauses.iter().position(|p| p.from_ns <= tick_ns) {
            let pause = pauses.remove(i);
            let for_ns = pause.until_ns.map_or(u64::MAX, |u| u - pause.from_ns);
            on_event(EmulatorEvent::Fault(format!(
                "paused for {:.2} s at tick {tick}",
                for_ns as f64 / 1e9
            )));
            let resume = Instant::now() + Duration::from_nanos(for_ns.min(rules.timeout_ns()));
            while Instant::now() < resume {
                if wire.other_run_announced(rules.stamp)? {
                    return Ok(EmulatorEvent::Superseded { ticks: driven });
                }
                wire.flush()?;
                thread::sleep(POLL_INTERVAL);
            }
        }
        if restarts.next_if(|at_ns| *at_ns <= tick_ns).is_some() {
            on_event(EmulatorEvent::Fault(format!("restarting at tick {tick}")));
            if !wire.restart(rules.stamp, &stage.ids, rules.timeout)? {
                return Ok(EmulatorEvent::Abandoned { ticks: driven });
            }
            start = stage.start_trigger(tick_ns);
        }

        // Report the vehicles' states and wait for their trajectories.
        let list = stage.list(tick_ns);
        let commands = match exchange(wire, &list, start, stage, rules)? {
            Answer::Commands(commands) => commands,
            Answer::Silent => return Ok(EmulatorEvent::Abandoned { ticks: driven }),
            Answer::OtherRun => return Ok(EmulatorEvent::Superseded { ticks: driven }),
        };
        // The trajectories take effect in the order they came (a planner that drove and now
        // only stops its vehicles has ended its run), and the vehicles run until the next tick.
        for command in &commands {
            stage.receive(command);
        }
        if commands.iter().all(is_stop_command) {
            if driving {
                return Ok(EmulatorEvent::Ended { ticks: driven });
            }
        } else {
            driving = true;
        }
        if driving {
            driven += 1;
        }
        stage.run_period(tick_ns);
        if rules.on_collision && stage.collided() {
            break;
        }
        tick += 1;
    }
    Ok(EmulatorEvent::Finished { ticks: driven })
}

/// How a tick's exchange ended.
enum Answer {
    /// The commands made at the tick or later, at least one per vehicle, in the order they
    /// came.
    Commands(Vec<VehicleCommandTrajectory>),
    /// Nothing for the timeout.
    Silent,
    /// The planner announced another run.
    OtherRun,
}

/// Publishes `list` with the run's current start trigger (the middleware's trigger writer is
/// reliable: a driver that lost it, or a restart's, hears it again) until every vehicle was
/// sent a command made at the list's tick or later: its plan for the tick, or a stop (which
/// the planner stamps by the lab's clock it extrapolates, so later than the tick). Every such
/// command that came by then is returned, in order: a stop sent right after the tick's plan
/// takes over from it, as on the car.
fn exchange(
    wire: &mut Wire,
    list: &VehicleStateList,
    start: SystemTrigger,
    stage: &Stage,
    rules: &RunRules,
) -> Result<Answer, EmulateError> {
    let started = Instant::now();
    let mut sent: Option<Instant> = None;
    let mut answered = vec![false; stage.ids.len()];
    let mut commands = Vec::new();
    loop {
        if sent.is_none_or(|s| s.elapsed() >= RESEND_INTERVAL) {
            wire.send_trigger(start);
            wire.send_list(list.clone());
            sent = Some(Instant::now());
        }
        wire.flush()?;
        for command in wire.commands()? {
            let slot = stage.ids.iter().position(|id| *id == command.vehicle_id);
            if let Some(i) = slot
                && command.header.create_stamp.nanoseconds >= list.t_now
            {
                answered[i] = true;
                commands.push(command);
            }
        }
        if answered.iter().all(|a| *a) {
            return Ok(Answer::Commands(commands));
        }
        if wire.other_run_announced(rules.stamp)? {
            return Ok(Answer::OtherRun);
        }
        if started.elapsed() >= rules.timeout {
            return Ok(Answer::Silent);
        }
        thread::sleep(POLL_INTERVAL);
    }
}

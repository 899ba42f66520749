//! The faults of one emulated run, drawn from the spec's (or `--faults` file's) `faults`: the
//! events on the vehicles' clock ([`FaultPlan`]) and the channels through which the emulator's
//! samples pass on each faulty topic ([`FaultyChannel`]: lost, repeated, held back, late).
//!
//! Every draw comes from a ChaCha stream keyed by the run's seed and a name that holds the
//! faults' `seed` (`faults/<seed>/events`, `faults/<seed>/topic/<name>`), so a run replays
//! with the same faults: the same events at the same times, and the same fate for the n-th
//! sample of a topic. (When the n-th sample is sent depends on the driver's timing in real
//! time; in simulated time it does not.)

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{LabFaults, ListedAs, Parameter, ParameterRange, SampleFaults};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha20Rng;

use super::ns_from_s;
use cpmx_stack::RUN_START_NS;

/// A sample held back to arrive after the next one is released at the latest after this.
const MAX_HOLD: Duration = Duration::from_millis(300);

/// The default lateness of a delayed sample [ms].
const DEFAULT_DELAY_MS: f64 = 50.0;

/// A span of the vehicles' clock: from `from_ns`, until `until_ns` (for good when `None`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Span {
    pub from_ns: u64,
    pub until_ns: Option<u64>,
}

impl Span {
    /// Whether `t_ns` lies in the span.
    pub fn contains(&self, t_ns: u64) -> bool {
        t_ns >= self.from_ns && self.until_ns.is_none_or(|until| t_ns < until)
    }
}

/// The faults of one run, on the vehicles' clock (tick 0 at [`RUN_START_NS`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub(super) struct FaultPlan {
    /// Per agent: when it is missing from the lists, and how the lists show it.
    pub leave_lists: Vec<(usize, Span, ListedAs)>,
    /// Per agent: when its positioning fixes do not reach it.
    pub ips_loss: Vec<(usize, Span)>,
    /// When the middleware does not tick.
    pub pauses: Vec<Span>,
    /// When the middleware restarts.
    pub restarts: Vec<u64>,
    /// The emulator's clock minus the driver's [ns].
    pub clock_offset_ns: i64,
    /// Per agent: its offset from its start (x, y [m], yaw [rad]).
    pub misplaced: Vec<(usize, [f64; 3])>,
    /// Per agent: the battery voltage it reports [V].
    pub low_battery: Vec<(usize, f64)>,
    /// What this run has, for the emulator's log.
    pub description: Vec<String>,
}

impl FaultPlan {
    /// The faults of the run with `run_seed`, for the lab's `vehicle_ids` (in agent order).
    pub fn draw(faults: &LabFaults, vehicle_ids: &[u8], run_seed: u64) -> FaultPlan {
        let mut rng = ChaCha20Rng::from_seed(stream_key(run_seed, &format!("faults/{}/events", faults.seed)));
        let agent = |id: u8| vehicle_ids.iter().position(|v| *v == id);
        let mut plan = FaultPlan {
            clock_offset_ns: (faults.clock_offset_ms * 1e6).round() as i64,
            ..FaultPlan::default()
        };
        if faults.clock_offset_ms != 0.0 {
            plan.description
                .push(format!("clock offset {} ms", faults.clock_offset_ms));
        }
        for f in &faults.leave_lists {
            let happens = occurs(f.probability, &mut rng);
            let span = span(&f.at_s, f.for_s.as_ref(), &mut rng);
            if let (true, Some(a)) = (happens, agent(f.vehicle)) {
                plan.description.push(format!(
                    "vehicle {} leaves the lists {}",
                    f.vehicle,
                    describe(span)
                ));
                plan.leave_lists.push((a, span, f.listed));
            }
        }
        for f in &faults.ips_loss {
            let happens = occurs(f.probability, &mut rng);
            let span = span(&f.at_s, f.for_s.as_ref(), &mut rng);
            if let (true, Some(a)) = (happens, agent(f.vehicle)) {
                plan.description.push(format!(
                    "vehicle {} loses its positioning fixes {}",
                    f.vehicle,
                    describe(span)
                ));
                plan.ips_loss.push((a, span));
            }
        }
        for f in &faults.pauses {
            let happens = occurs(f.probability, &mut rng);
            let span = span(&f.at_s, Some(&f.for_s), &mut rng);
            if happens {
                plan.description
                    .push(format!("the middleware pauses {}", describe(span)));
                plan.pauses.push(span);
            }
        }
        for f in &faults.restarts {
            let happens = occurs(f.probability, &mut rng);
            let at_ns = RUN_START_NS + ns_from_s(value(&f.at_s, &mut rng));
            if happens {
                plan.description.push(format!(
                    "the middleware restarts at {:.2} s",
                    (at_ns - RUN_START_NS) as f64 / 1e9
                ));
                plan.restarts.push(at_ns);
            }
        }
        for f in &faults.misplaced {
            if let Some(a) = agent(f.vehicle) {
                plan.description.push(format!(
                    "vehicle {} placed ({}, {}) m, {}° off its start",
                    f.vehicle, f.offset_m[0], f.offset_m[1], f.yaw_deg
                ));
                plan.misplaced
                    .push((a, [f.offset_m[0], f.offset_m[1], f.yaw_deg.to_radians()]));
            }
        }
        for f in &faults.low_battery {
            if let Some(a) = agent(f.vehicle) {
                plan.description
                    .push(format!("vehicle {} reports {} V", f.vehicle, f.voltage_v));
                plan.low_battery.push((a, f.voltage_v));
            }
        }
        for (topic, f) in faults.topics.each() {
            plan.description.push(format!(
                "{topic}: drop {}, duplicate {}, reorder {}, delay {}",
                f.drop, f.duplicate, f.reorder, f.delay
            ));
        }
        plan.restarts.sort_unstable();
        plan
    }

    /// Whether the middleware is paused at `t_ns`.
    pub fn paused(&self, t_ns: u64) -> bool {
        self.pauses.iter().any(|p| p.contains(t_ns))
    }
}

/// Whether an event with `probability` (default 1) happens in this run (one draw always).
fn occurs(probability: Option<f64>, rng: &mut ChaCha20Rng) -> bool {
    let u: f64 = rng.random();
    u < probability.unwrap_or(1.0)
}

/// A time or duration: the number, or a draw (one draw always, so that the stream does not
/// depend on which are numbers) [s].
fn value(parameter: &Parameter, rng: &mut ChaCha20Rng) -> f64 {
    const ANY: ParameterRange = ParameterRange {
        min: 0.0,
        min_exclusive: false,
        max: f64::INFINITY,
    };
    match parameter {
        Parameter::Drawn(d) => cpmx_stack::draw_value(d, ANY, rng),
        Parameter::Fixed(v) => {
            let _: f64 = rng.random();
            *v
        }
    }
}

/// The span from `at_s` for `for_s` (for good without one).
fn span(at_s: &Parameter, for_s: Option<&Parameter>, rng: &mut ChaCha20Rng) -> Span {
    let from_ns = RUN_START_NS + ns_from_s(value(at_s, rng));
    let until_ns = for_s.map(|f| from_ns + ns_from_s(value(f, rng)));
    Span { from_ns, until_ns }
}

/// `at 1.20 s for 0.50 s`, `at 1.20 s for good`.
fn describe(span: Span) -> String {
    let at_s = (span.from_ns - RUN_START_NS) as f64 / 1e9;
    match span.until_ns {
        Some(until) => format!("at {at_s:.2} s for {:.2} s", (until - span.from_ns) as f64 / 1e9),
        None => format!("at {at_s:.2} s for good"),
    }
}

/// The samples of one topic on their way: each is lost, repeated, held back until the next
/// one has passed, or late, as its topic's faults draw.
#[derive(Debug)]
pub(super) struct FaultyChannel<T> {
    faults: Option<SampleFaults>,
    rng: ChaCha20Rng,
    /// Samples on their way, with the time they arrive, in order of sending.
    queue: VecDeque<(Instant, T)>,
    /// A sample held back until the next one passes (or [`MAX_HOLD`]).
    held: Option<(Instant, T)>,
}

impl<T: Clone> FaultyChannel<T> {
    /// The channel of `topic` for the run with `run_seed` (faultless without `faults`).
    pub fn new(faults: Option<&LabFaults>, topic: &str, run_seed: u64) -> Self {
        let seed = faults.map_or(0, |f| f.seed);
        let faults = faults.and_then(|f| {
            f.topics
                .each()
                .find(|(name, _)| *name == topic)
                .map(|(_, f)| f.clone())
        });
        Self {
            faults,
            rng: ChaCha20Rng::from_seed(stream_key(run_seed, &format!("faults/{seed}/topic/{topic}"))),
            queue: VecDeque::new(),
            held: None,
        }
    }

    /// Sends `sample` at `now`. Draws per sample, always all of them: drop, duplicate, delay
    /// (and its lateness), reorder.
    pub fn send(&mut self, sample: T, now: Instant) {
        let Some(faults) = &self.faults else {
            self.queue.push_back((now, sample));
            return;
        };
        let (drop, duplicate, delay, reorder): (f64, f64, f64, f64) = (
            self.rng.random(),
            self.rng.random(),
            self.rng.random(),
            self.rng.random(),
        );
        let late_ms = match &faults.delay_ms {
            Some(p) => value(p, &mut self.rng),
            None => {
                let _: f64 = self.rng.random();
                DEFAULT_DELAY_MS
            }
        };
        if drop < faults.drop {
            return;
        }
        let arrives = if delay < faults.delay {
            now + Duration::from_secs_f64(late_ms.max(0.0) / 1e3)
        } else {
            now
        };
        if reorder < faults.reorder && self.held.is_none() {
            self.held = Some((arrives, sample));
            return;
        }
        if duplicate < faults.duplicate {
            self.queue.push_back((arrives, sample.clone()));
        }
        self.queue.push_back((arrives, sample));
        // A sample held back arrives after this one.
        if let Some((held_arrives, held)) = self.held.take() {
            self.queue.push_back((held_arrives.max(arrives), held));
        }
    }

    /// The samples that have arrived by `now`, in the order they arrive.
    pub fn arrived(&mut self, now: Instant) -> Vec<T> {
        if let Some((arrives, _)) = &self.held
            && now.duration_since(*arrives) >= MAX_HOLD
            && let Some((_, held)) = self.held.take()
        {
            self.queue.push_back((now, held));
        }
        let mut out = Vec::new();
        let mut kept = VecDeque::with_capacity(self.queue.len());
        for (arrives, sample) in self.queue.drain(..) {
            if arrives <= now {
                out.push(sample);
            } else {
                kept.push_back((arrives, sample));
            }
        }
        self.queue = kept;
        out
    }
}

#[cfg(test)]
mod tests {
    use cpmx_spec::model::{ListOutage, Restart, TopicFaults};

    use super::*;

    fn faults(topic: SampleFaults) -> LabFaults {
        LabFaults {
            seed: 3,
            topics: TopicFaults {
                vehicle_state_list: Some(topic),
                ..TopicFaults::default()
            },
            ..LabFaults::default()
        }
    }

    #[test]
    fn a_faultless_channel_delivers_everything_at_once_in_order() {
        let mut channel = FaultyChannel::new(None, "vehicleStateList", 1);
        let now = Instant::now();
        for k in 0..5 {
            channel.send(k, now);
        }
        assert_eq!(channel.arrived(now), [0, 1, 2, 3, 4]);
    }

    #[test]
    fn faults_lose_repeat_and_reorder_samples_and_replay_with_the_seed() {
        let all = faults(SampleFaults {
            drop: 0.2,
            duplicate: 0.2,
            reorder: 0.2,
            ..SampleFaults::default()
        });
        let play = |run_seed| {
            let mut channel = FaultyChannel::new(Some(&all), "vehicleStateList", run_seed);
            let now = Instant::now();
            (0..200).for_each(|k| channel.send(k, now));
            channel.arrived(now + MAX_HOLD)
        };
        let got = play(7);
        assert_eq!(got, play(7), "the same run replays");
        assert_ne!(got, play(8), "another run draws others");
        let distinct: std::collections::BTreeSet<_> = got.iter().collect();
        assert!(distinct.len() < 200, "some were lost");
        assert!(got.len() > distinct.len(), "some came twice");
        assert!(got.windows(2).any(|w| w[1] < w[0]), "some came out of order");
    }

    #[test]
    fn late_samples_arrive_later() {
        let late = faults(SampleFaults {
            delay: 1.0,
            delay_ms: Some(Parameter::Fixed(40.0)),
            ..SampleFaults::default()
        });
        let mut channel = FaultyChannel::new(Some(&late), "vehicleStateList", 1);
        let now = Instant::now();
        channel.send(1, now);
        assert!(channel.arrived(now).is_empty());
        assert_eq!(channel.arrived(now + Duration::from_millis(40)), [1]);
    }

    #[test]
    fn events_are_drawn_per_run_and_for_the_lab_s_vehicles() {
        let faults = LabFaults {
            seed: 1,
            leave_lists: vec![ListOutage {
                vehicle: 2,
                at_s: Parameter::Drawn(cpmx_spec::model::Distribution::Uniform([1.0, 2.0])),
                for_s: None,
                probability: None,
                listed: ListedAs::Stale,
            }],
            restarts: vec![Restart {
                at_s: Parameter::Fixed(0.5),
                probability: Some(0.0),
            }],
            ..LabFaults::default()
        };
        let plan = FaultPlan::draw(&faults, &[1, 2], 9);
        assert_eq!(plan, FaultPlan::draw(&faults, &[1, 2], 9));
        let (agent, span, listed) = plan.leave_lists[0];
        assert_eq!((agent, listed, span.until_ns), (1, ListedAs::Stale, None));
        assert!((RUN_START_NS + 1_000_000_000..RUN_START_NS + 2_000_000_000).contains(&span.from_ns));
        assert!(span.contains(u64::MAX));
        assert!(plan.restarts.is_empty(), "probability 0");
        assert_ne!(
            FaultPlan::draw(&faults, &[1, 2], 10).leave_lists[0].1,
            span,
            "another run, another time"
        );
    }
}

//! How agents learn each other's states when global state is not given: the `communication`
//! layer (each agent broadcasts its state; messages are delayed, sent at a rate, lost, out of
//! range, too old) and the `perception` layer (each agent's own sensors detect the others
//! within range and field of view, with noise and missed detections). [`NeighbourKnowledge`]
//! keeps both for the agents of one run (or one training environment) and gives, at each
//! policy step, what each agent knows of each other ([`NeighbourViews`]), from which its
//! observation is formed.
//!
//! Rules (docs/language.md says them to users):
//! - An agent broadcasts at policy steps, first at the run's start, then whenever `1 /
//!   rate_hz` has passed since its last message (every step without `rate_hz`). A message
//!   carries the sender's state at that step; it reaches a receiver `latency_ms` later, unless
//!   it is lost (independently per receiver, `drop_probability`) or the receiver is farther than
//!   `range_m` from the sender when it is sent.
//! - A receiver knows the last message it received from each sender, as it was sent (not
//!   extrapolated); after `max_age_ms` without a newer one the sender counts as unheard.
//! - Perception detects another agent whose centre is within `range_m` and within
//!   `field_of_view_deg` about the observer's heading, with `detection_probability`, and sees it
//!   with Gaussian noise on position (`noise_position_m` per axis) and heading
//!   (`noise_yaw_rad`); speed and steering as they are.
//! - Seen this step beats heard; neither heard nor seen is absent.
//! - A view that is exact this very step (a message of this step without latency, a perfect
//!   detection) is [`NeighbourView::Exact`], so ideal layers give the same bits as none.
//!
//! Random draws come from the caller's streams, one per layer, in a fixed order (senders,
//! then receivers, ascending), and only where a parameter makes them necessary.

use cpmx_policy::{AgentState, NeighbourView, NeighbourViews};
use rand::RngExt;
use rand_chacha::ChaCha20Rng;
use rand_distr::{Distribution, StandardNormal};

/// The `communication` layer's parameters (drawn: every one a number).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommunicationParams {
    /// Delay from sending to receiving [s].
    pub latency_s: f64,
    /// Messages per second; `None`: one every policy step.
    pub rate_hz: Option<f64>,
    /// Probability that a message does not reach a receiver.
    pub drop_probability: f64,
    /// Farthest receiver [m]; `None`: unlimited.
    pub range_m: Option<f64>,
    /// Age [s] after which a sender counts as unheard; `None`: never.
    pub max_age_s: Option<f64>,
}

/// The `perception` layer's parameters (drawn: every one a number).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerceptionParams {
    /// Farthest detection [m]; `None`: unlimited.
    pub range_m: Option<f64>,
    /// Field of view [rad], centred on the heading; `None`: all around.
    pub field_of_view_rad: Option<f64>,
    /// Standard deviation of the position noise per axis [m].
    pub noise_position_m: f64,
    /// Standard deviation of the heading noise [rad].
    pub noise_yaw_rad: f64,
    /// Probability of detecting an agent in range and view at a step.
    pub detection_probability: f64,
}

/// A message on its way.
#[derive(Debug, Clone, Copy)]
struct Message {
    sender: usize,
    receiver: usize,
    sent_s: f64,
    arrives_s: f64,
    state: AgentState,
}

/// The communication layer of one run.
#[derive(Debug, Clone)]
struct Communication {
    params: CommunicationParams,
    rng: ChaCha20Rng,
    /// When each sender last sent.
    last_sent_s: Vec<Option<f64>>,
    in_flight: Vec<Message>,
    /// `[receiver][sender]`: the last message received (time sent, state).
    heard: Vec<Option<(f64, AgentState)>>,
}

/// The perception layer of one run.
#[derive(Debug, Clone)]
struct Perception {
    params: PerceptionParams,
    rng: ChaCha20Rng,
}

/// What the agents of one run know of each other, step by step.
#[derive(Debug, Clone)]
pub struct NeighbourKnowledge {
    agents: usize,
    communication: Option<Communication>,
    perception: Option<Perception>,
    views: NeighbourViews,
}

/// Reads little-endian values of a saved state.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let slice = self
            .bytes
            .get(self.at..self.at + n)
            .ok_or_else(|| "the neighbour layers' state is truncated".to_string())?;
        self.at += n;
        Ok(slice)
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().map_err(|_| "u64")?))
    }
    fn u128(&mut self) -> Result<u128, String> {
        Ok(u128::from_le_bytes(
            self.take(16)?.try_into().map_err(|_| "u128")?,
        ))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn state(&mut self) -> Result<AgentState, String> {
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = self.f64()?;
        }
        Ok(AgentState {
            x_m: v[0],
            y_m: v[1],
            yaw_rad: v[2],
            speed_mps: v[3],
            velocity_mps: [v[4], v[5]],
            steering_rad: v[6],
        })
    }
}

/// Times within this of each other are the same instant (policy steps are sums of `dt`).
const SAME_INSTANT_S: f64 = 1e-9;

impl NeighbourKnowledge {
    /// The layers of a run of `agents` agents, each with its own random stream.
    pub fn new(
        agents: usize,
        communication: Option<(CommunicationParams, ChaCha20Rng)>,
        perception: Option<(PerceptionParams, ChaCha20Rng)>,
    ) -> Self {
        NeighbourKnowledge {
            agents,
            communication: communication.map(|(params, rng)| Communication {
                params,
                rng,
                last_sent_s: vec![None; agents],
                in_flight: Vec::new(),
                heard: vec![None; agents * agents],
            }),
            perception: perception.map(|(params, rng)| Perception { params, rng }),
            views: NeighbourViews::exact(agents),
        }
    }

    /// New parameters for the layers this knowledge has (a training episode's draw); what was
    /// heard is forgotten, the random streams go on.
    pub fn set_params(
        &mut self,
        communication: Option<CommunicationParams>,
        perception: Option<PerceptionParams>,
    ) {
        if let (Some(c), Some(params)) = (&mut self.communication, communication) {
            c.params = params;
        }
        if let (Some(p), Some(params)) = (&mut self.perception, perception) {
            p.params = params;
        }
        self.reset();
    }

    /// Appends everything needed to continue exactly (parameters, streams, messages in flight
    /// and heard) to `out`, for training checkpoints.
    pub fn save(&self, out: &mut Vec<u8>) {
        let f = |out: &mut Vec<u8>, v: f64| out.extend_from_slice(&v.to_bits().to_le_bytes());
        let opt = |out: &mut Vec<u8>, v: Option<f64>| f(out, v.unwrap_or(f64::NAN));
        let state = |out: &mut Vec<u8>, s: &AgentState| {
            for v in [
                s.x_m,
                s.y_m,
                s.yaw_rad,
                s.speed_mps,
                s.velocity_mps[0],
                s.velocity_mps[1],
                s.steering_rad,
            ] {
                f(out, v);
            }
        };
        if let Some(c) = &self.communication {
            let p = c.params;
            f(out, p.latency_s);
            opt(out, p.rate_hz);
            f(out, p.drop_probability);
            opt(out, p.range_m);
            opt(out, p.max_age_s);
            out.extend_from_slice(&c.rng.get_word_pos().to_le_bytes());
            for last in &c.last_sent_s {
                opt(out, *last);
            }
            out.extend_from_slice(&(c.in_flight.len() as u64).to_le_bytes());
            for m in &c.in_flight {
                out.extend_from_slice(&(m.sender as u64).to_le_bytes());
                out.extend_from_slice(&(m.receiver as u64).to_le_bytes());
                f(out, m.sent_s);
                f(out, m.arrives_s);
                state(out, &m.state);
            }
            for heard in &c.heard {
                match heard {
                    None => out.push(0),
                    Some((sent, s)) => {
                        out.push(1);
                        f(out, *sent);
                        state(out, s);
                    }
                }
            }
        }
        if let Some(p) = &self.perception {
            let q = p.params;
            opt(out, q.range_m);
            opt(out, q.field_of_view_rad);
            f(out, q.noise_position_m);
            f(out, q.noise_yaw_rad);
            f(out, q.detection_probability);
            out.extend_from_slice(&p.rng.get_word_pos().to_le_bytes());
        }
    }

    /// Restores what [`NeighbourKnowledge::save`] wrote from `bytes[*at..]` (advancing `at`);
    /// the knowledge must have the same layers and agents.
    pub fn load(&mut self, bytes: &[u8], at: &mut usize) -> Result<(), String> {
        let mut r = Cursor { bytes, at: *at };
        let n = self.agents;
        let opt = |v: f64| (!v.is_nan()).then_some(v);
        if let Some(c) = &mut self.communication {
            c.params = CommunicationParams {
                latency_s: r.f64()?,
                rate_hz: opt(r.f64()?),
                drop_probability: r.f64()?,
                range_m: opt(r.f64()?),
                max_age_s: opt(r.f64()?),
            };
            c.rng.set_word_pos(r.u128()?);
            for last in &mut c.last_sent_s {
                *last = opt(r.f64()?);
            }
            let count = r.u64()? as usize;
            c.in_flight.clear();
            for _ in 0..count {
                let (sender, receiver) = (r.u64()? as usize, r.u64()? as usize);
                if sender >= n || receiver >= n {
                    return Err("a message between agents this environment lacks".into());
                }
                let (sent_s, arrives_s) = (r.f64()?, r.f64()?);
                let state = r.state()?;
                c.in_flight.push(Message {
                    sender,
                    receiver,
                    sent_s,
                    arrives_s,
                    state,
                });
            }
            for heard in &mut c.heard {
                *heard = match r.take(1)?[0] {
                    0 => None,
                    _ => Some((r.f64()?, r.state()?)),
                };
            }
        }
        if let Some(p) = &mut self.perception {
            p.params = PerceptionParams {
                range_m: opt(r.f64()?),
                field_of_view_rad: opt(r.f64()?),
                noise_position_m: r.f64()?,
                noise_yaw_rad: r.f64()?,
                detection_probability: r.f64()?,
            };
            p.rng.set_word_pos(r.u128()?);
        }
        *at = r.at;
        Ok(())
    }

    /// Whether any layer stands between the agents.
    pub fn is_active(&self) -> bool {
        self.communication.is_some() || self.perception.is_some()
    }

    /// Forgets what was heard (a new episode; the random streams go on).
    pub fn reset(&mut self) {
        if let Some(c) = &mut self.communication {
            c.last_sent_s.fill(None);
            c.in_flight.clear();
            c.heard.fill(None);
        }
        self.views = NeighbourViews::exact(self.agents);
    }

    /// The policy step at time `t_s` with the agents' `states` (as the planner or policy sees
    /// them): sends, delivers and perceives, and returns what each agent knows of the others.
    pub fn step(&mut self, t_s: f64, states: &[AgentState]) -> &NeighbourViews {
        let n = self.agents.min(states.len());
        if let Some(c) = &mut self.communication {
            c.send(t_s, states);
            c.deliver(t_s);
        }
        for observer in 0..n {
            for other in 0..n {
                if observer == other {
                    continue;
                }
                let seen = self
                    .perception
                    .as_mut()
                    .map(|p| p.detect(&states[observer], &states[other]));
                let view = match seen {
                    Some(Some(view)) => view,
                    Some(None) if self.communication.is_none() => NeighbourView::Absent,
                    _ => self
                        .communication
                        .as_ref()
                        .map_or(NeighbourView::Exact, |c| c.view(observer, other, t_s)),
                };
                self.views.set(observer, other, view);
            }
        }
        &self.views
    }
}

impl Communication {
    /// Every sender whose turn it is broadcasts its state to every receiver in range.
    fn send(&mut self, t_s: f64, states: &[AgentState]) {
        let n = states.len().min(self.last_sent_s.len());
        for sender in 0..n {
            let due = match (self.last_sent_s[sender], self.params.rate_hz) {
                (None, _) | (Some(_), None) => true,
                (Some(last), Some(rate)) => t_s - last >= 1.0 / rate - SAME_INSTANT_S,
            };
            if !due {
                continue;
            }
            self.last_sent_s[sender] = Some(t_s);
            let from = &states[sender];
            for receiver in (0..n).filter(|&r| r != sender) {
                let to = &states[receiver];
                let in_range = self
                    .params
                    .range_m
                    .is_none_or(|range| (to.x_m - from.x_m).hypot(to.y_m - from.y_m) <= range);
                let lost = self.params.drop_probability > 0.0
                    && self.rng.random::<f64>() < self.params.drop_probability;
                if in_range && !lost {
                    self.in_flight.push(Message {
                        sender,
                        receiver,
                        sent_s: t_s,
                        arrives_s: t_s + self.params.latency_s,
                        state: *from,
                    });
                }
            }
        }
    }

    /// Messages whose time has come reach their receivers (a newer message replaces an older).
    fn deliver(&mut self, t_s: f64) {
        let n = self.last_sent_s.len();
        let heard = &mut self.heard;
        self.in_flight.retain(|m| {
            if m.arrives_s > t_s + SAME_INSTANT_S {
                return true;
            }
            let slot = &mut heard[m.receiver * n + m.sender];
            if slot.is_none_or(|(sent, _)| sent <= m.sent_s) {
                *slot = Some((m.sent_s, m.state));
            }
            false
        });
    }

    /// What `receiver` knows of `sender` at `t_s`.
    fn view(&self, receiver: usize, sender: usize, t_s: f64) -> NeighbourView {
        let n = self.last_sent_s.len();
        match self.heard[receiver * n + sender] {
            None => NeighbourView::Absent,
            Some((sent_s, _))
                if self
                    .params
                    .max_age_s
                    .is_some_and(|max| t_s - sent_s > max + SAME_INSTANT_S) =>
            {
                NeighbourView::Absent
            }
            Some((sent_s, _)) if (t_s - sent_s).abs() <= SAME_INSTANT_S => NeighbourView::Exact,
            Some((_, state)) => NeighbourView::Known(state),
        }
    }
}

impl Perception {
    /// Whether `observer` detects `other` this step, and how it sees it (`None`: not detected).
    fn detect(&mut self, observer: &AgentState, other: &AgentState) -> Option<NeighbourView> {
        let p = self.params;
        let (dx, dy) = (other.x_m - observer.x_m, other.y_m - observer.y_m);
        if p.range_m.is_some_and(|range| dx.hypot(dy) > range) {
            return None;
        }
        if let Some(fov) = p.field_of_view_rad {
            let bearing = dy.atan2(dx) - observer.yaw_rad;
            let off =
                (bearing + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            if off.abs() > fov / 2.0 {
                return None;
            }
        }
        if p.detection_probability < 1.0 && self.rng.random::<f64>() >= p.detection_probability {
            return None;
        }
        if p.noise_position_m == 0.0 && p.noise_yaw_rad == 0.0 {
            return Some(NeighbourView::Exact);
        }
        let mut noise = |std: f64| {
            if std > 0.0 {
                let z: f64 = StandardNormal.sample(&mut self.rng);
                std * z
            } else {
                0.0
            }
        };
        let (ex, ey, eyaw) = (
            noise(p.noise_position_m),
            noise(p.noise_position_m),
            noise(p.noise_yaw_rad),
        );
        let yaw_rad = other.yaw_rad + eyaw;
        let speed = other.velocity_norm_mps();
        Some(NeighbourView::Known(AgentState {
            x_m: other.x_m + ex,
            y_m: other.y_m + ey,
            yaw_rad,
            // The velocity as a tracker reports it: the true speed along the seen heading.
            velocity_mps: [speed * yaw_rad.cos(), speed * yaw_rad.sin()],
            ..*other
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn states(xs: &[f64]) -> Vec<AgentState> {
        xs.iter()
            .map(|&x| AgentState {
                x_m: x,
                speed_mps: 0.5,
                velocity_mps: [0.5, 0.0],
                ..AgentState::default()
            })
            .collect()
    }

    fn rng(k: u8) -> ChaCha20Rng {
        ChaCha20Rng::from_seed([k; 32])
    }

    const IDEAL: CommunicationParams = CommunicationParams {
        latency_s: 0.0,
        rate_hz: None,
        drop_probability: 0.0,
        range_m: None,
        max_age_s: None,
    };

    #[test]
    fn ideal_layers_know_everything_exactly() {
        let perfect = PerceptionParams {
            range_m: None,
            field_of_view_rad: None,
            noise_position_m: 0.0,
            noise_yaw_rad: 0.0,
            detection_probability: 1.0,
        };
        let mut k = NeighbourKnowledge::new(3, Some((IDEAL, rng(1))), Some((perfect, rng(2))));
        for step in 0..5 {
            assert!(k.step(step as f64 * 0.1, &states(&[0.0, 1.0, 5.0])).all_exact());
        }
    }

    #[test]
    fn latency_rate_range_and_age_decide_what_is_heard() {
        let params = CommunicationParams {
            latency_s: 0.1,
            rate_hz: Some(5.0),
            range_m: Some(2.0),
            max_age_s: Some(0.35),
            ..IDEAL
        };
        let mut k = NeighbourKnowledge::new(3, Some((params, rng(1))), None);
        let s0 = states(&[0.0, 1.0, 5.0]);
        // t = 0: sent, not yet arrived.
        let v = k.step(0.0, &s0).clone();
        assert_eq!(v.get(0, 1), NeighbourView::Absent);
        // t = 0.1: the message of t = 0 arrives, as it was sent; agent 2 is out of range.
        let s1 = states(&[0.05, 1.05, 5.05]);
        let v = k.step(0.1, &s1).clone();
        assert_eq!(v.get(0, 1), NeighbourView::Known(s0[1]));
        assert_eq!(v.get(0, 2), NeighbourView::Absent);
        // t = 0.2: next message sent (5 Hz), still in flight: the old one is heard.
        let v = k.step(0.2, &s1).clone();
        assert_eq!(v.get(1, 0), NeighbourView::Known(s0[0]));
        // t = 0.3: the message of 0.2 arrives.
        let v = k.step(0.3, &s1).clone();
        assert_eq!(v.get(1, 0), NeighbourView::Known(s1[0]));
        // Agent 1 moves out of range: its messages stop; after 0.35 s it is unheard.
        let far = states(&[0.05, 9.0, 5.05]);
        for step in 4..=7 {
            k.step(step as f64 * 0.1, &far);
        }
        let v = k.step(0.8, &far).clone();
        assert_eq!(v.get(0, 1), NeighbourView::Absent);
    }

    #[test]
    fn every_message_lost_leaves_everyone_unheard() {
        let params = CommunicationParams {
            drop_probability: 1.0,
            ..IDEAL
        };
        let mut k = NeighbourKnowledge::new(2, Some((params, rng(3))), None);
        for step in 0..10 {
            let v = k.step(step as f64 * 0.1, &states(&[0.0, 1.0])).clone();
            assert_eq!(v.get(0, 1), NeighbourView::Absent);
        }
    }

    #[test]
    fn perception_sees_within_range_and_view_with_noise() {
        let params = PerceptionParams {
            range_m: Some(2.0),
            field_of_view_rad: Some(std::f64::consts::FRAC_PI_2),
            noise_position_m: 0.01,
            noise_yaw_rad: 0.0,
            detection_probability: 1.0,
        };
        let mut k = NeighbourKnowledge::new(3, None, Some((params, rng(4))));
        // Agent 0 faces +x: agent 1 ahead within range, agent 2 ahead out of range; agent 1
        // faces +x too, so agent 0 is behind it.
        let v = k.step(0.0, &states(&[0.0, 1.0, 3.0])).clone();
        let NeighbourView::Known(seen) = v.get(0, 1) else {
            panic!("agent 1 is ahead within range: {:?}", v.get(0, 1));
        };
        assert!((seen.x_m - 1.0).abs() < 0.05 && seen.x_m != 1.0);
        assert_eq!(v.get(0, 2), NeighbourView::Absent);
        assert_eq!(v.get(1, 0), NeighbourView::Absent);
    }
}

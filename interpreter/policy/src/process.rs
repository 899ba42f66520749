//! A policy in another process, in any language: cpmx starts the process once per run and
//! talks to it over stdin/stdout in JSON lines (protocol `cpmx-policy` version 1, documented
//! in `docs/policy-process.md`).
//!
//! ```text
//! cpmx -> process  {"type":"hello","protocol":1, seed, dt_s, agents, vehicle, paths, observation_size}
//! process -> cpmx  {"type":"ready","protocol":1}
//! cpmx -> process  {"type":"step","step":k,"t_s":..,"prediction":false,"agents":[...],"observations":[[..]]}
//! process -> cpmx  {"actions":[[speed_mps, steering_rad], ...]}      (one per agent)
//! ...
//! cpmx -> process  {"type":"end"}                                     (then stdin closes)
//! ```
//!
//! This module owns the process's life (start, timeouts, stderr capture, end) and the
//! protocol's messages. A crash, a hang past the timeout or a malformed answer is a
//! [`PolicyError::Process`] with the last lines of the process's stderr; the engine fails only
//! that run. Forks (the planner's look-ahead) share the process and mark their steps as
//! predictions.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command as Spawn, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use cpmx_vehicle::Command;
use serde_json::{Value, json};

use crate::memory::ObservationMemory;
use crate::observation::{ObservationInput, SigmarlObservation};
use crate::policy::{Policy, PolicyError, check_commands};

/// The protocol version this build speaks.
pub const PROTOCOL_VERSION: u64 = 1;
/// Bytes of the process's stderr kept for error messages (the end of it).
const STDERR_KEPT: usize = 4000;

/// How to start a policy process and what to tell it.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessConfig {
    /// Program and arguments.
    pub command: Vec<String>,
    /// Working directory (the spec's folder).
    pub dir: PathBuf,
    /// Longest wait for one answer [s].
    pub timeout_s: f64,
    /// The observation to compute and send with every step, if asked for.
    pub observation: Option<SigmarlObservation>,
    /// The run's seed.
    pub seed: u64,
    /// The policy step [s].
    pub dt_s: f64,
    /// The policy's name in the spec.
    pub name: String,
}

/// The running process, shared by a policy and its forks.
struct Channel {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<std::io::Result<String>>,
    stderr: Arc<Mutex<Vec<u8>>>,
    stderr_thread: Option<JoinHandle<()>>,
    timeout: Duration,
    program: String,
    /// Why it failed, once it has (every later call fails the same way).
    failed: Option<String>,
}

impl Channel {
    fn start(config: &ProcessConfig) -> Result<Channel, PolicyError> {
        let program = config.command.join(" ");
        let Some((exe, args)) = config.command.split_first() else {
            return Err(PolicyError::Process("has an empty command".into()));
        };
        let mut child = Spawn::new(exe)
            .args(args)
            .current_dir(&config.dir)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                PolicyError::Process(format!(
                    "`{program}` could not be started in {}: {e}",
                    config.dir.display()
                ))
            })?;
        let (Some(stdout), Some(mut err_pipe)) = (child.stdout.take(), child.stderr.take()) else {
            return Err(PolicyError::Process(format!("`{program}`: no pipes")));
        };
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let stop = line.is_err();
                if tx.send(line).is_err() || stop {
                    break;
                }
            }
        });
        let stderr = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&stderr);
        let stderr_thread = std::thread::spawn(move || {
            let mut buf = [0u8; 4096];
            while let Ok(n) = err_pipe.read(&mut buf) {
                if n == 0 {
                    break;
                }
                if let Ok(mut kept) = sink.lock() {
                    kept.extend_from_slice(&buf[..n]);
                    let excess = kept.len().saturating_sub(STDERR_KEPT);
                    kept.drain(..excess);
                }
            }
        });
        Ok(Channel {
            stdin: child.stdin.take(),
            child,
            lines,
            stderr,
            stderr_thread: Some(stderr_thread),
            timeout: Duration::from_secs_f64(config.timeout_s.max(0.001)),
            program,
            failed: None,
        })
    }

    /// Send one message and read one answer line.
    fn ask(&mut self, message: &Value, what: &str) -> Result<String, PolicyError> {
        if let Some(reason) = &self.failed {
            return Err(PolicyError::Process(reason.clone()));
        }
        let result = self.exchange(message, what);
        if let Err(reason) = &result {
            let reason = self.fail(reason);
            return Err(PolicyError::Process(reason));
        }
        result.map_err(PolicyError::Process)
    }

    fn exchange(&mut self, message: &Value, what: &str) -> Result<String, String> {
        let stdin = self.stdin.as_mut().ok_or("has closed its input")?;
        let mut line = message.to_string();
        line.push('\n');
        stdin
            .write_all(line.as_bytes())
            .and_then(|()| stdin.flush())
            .map_err(|e| format!("could not be sent {what} ({e})"))?;
        match self.lines.recv_timeout(self.timeout) {
            Ok(Ok(answer)) => Ok(answer),
            Ok(Err(e)) => Err(format!("sent unreadable output for {what} ({e})")),
            Err(RecvTimeoutError::Timeout) => Err(format!(
                "did not answer {what} within {} s",
                self.timeout.as_secs_f64()
            )),
            Err(RecvTimeoutError::Disconnected) => Err(format!("closed its output before answering {what}")),
        }
    }

    /// Marks the channel failed: ends the process, and returns the reason with its exit
    /// status and the end of its stderr.
    fn fail(&mut self, reason: &str) -> String {
        let status = self.finish(Duration::from_millis(200));
        let stderr = self.stderr_text();
        let mut message = format!("`{}` {reason}", self.program);
        if let Some(status) = status {
            message.push_str(&format!("; it {status}"));
        }
        if stderr.is_empty() {
            message.push_str("; its stderr is empty");
        } else {
            message.push_str(&format!("; its stderr ends:\n{stderr}"));
        }
        self.failed = Some(message.clone());
        message
    }

    /// Closes stdin, waits up to `grace` for the process to exit, kills it otherwise; returns
    /// how it ended ("exited with status 1", "was killed").
    fn finish(&mut self, grace: Duration) -> Option<String> {
        drop(self.stdin.take());
        let deadline = Instant::now() + grace;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(status)) => break Some(describe(status)),
                Ok(None) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(5)),
                Ok(None) => {
                    let _ = self.child.kill();
                    let _ = self.child.wait();
                    break Some("was killed by cpmx".to_owned());
                }
                Err(_) => break None,
            }
        };
        if let Some(t) = self.stderr_thread.take() {
            let _ = t.join();
        }
        status
    }

    fn stderr_text(&self) -> String {
        let bytes = self.stderr.lock().map(|b| b.clone()).unwrap_or_default();
        String::from_utf8_lossy(&bytes).trim_end().to_owned()
    }
}

fn describe(status: std::process::ExitStatus) -> String {
    match status.code() {
        Some(code) => format!("exited with status {code}"),
        None => format!("ended by a signal ({status})"),
    }
}

impl Drop for Channel {
    fn drop(&mut self) {
        if self.failed.is_none()
            && let Some(stdin) = self.stdin.as_mut()
        {
            let _ = stdin.write_all(b"{\"type\":\"end\"}\n");
            let _ = stdin.flush();
        }
        self.finish(Duration::from_secs(2));
    }
}

/// A policy answered by a process (see the module documentation).
pub struct ProcessPolicy {
    channel: Arc<Mutex<Channel>>,
    config: Arc<ProcessConfig>,
    /// Whether this is a fork whose steps are predictions.
    prediction: bool,
    /// Steps answered so far by this policy (a fork continues its parent's count).
    step: u64,
    /// Whether the hello was sent (shared with forks through the channel's first use).
    greeted: Arc<Mutex<bool>>,
    /// The steering each agent was last commanded [rad].
    steering_rad: Vec<f64>,
    memory: ObservationMemory,
}

impl std::fmt::Debug for ProcessPolicy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProcessPolicy")
            .field("command", &self.config.command)
            .field("prediction", &self.prediction)
            .field("step", &self.step)
            .finish_non_exhaustive()
    }
}

impl ProcessPolicy {
    /// The same policy drawing its observation's noise (if the design adds any) from `rng`.
    pub fn with_noise_stream(mut self, rng: rand_chacha::ChaCha20Rng) -> Self {
        self.memory.set_noise_stream(rng);
        self
    }

    /// Starts the process (one per run).
    pub fn start(config: ProcessConfig) -> Result<Self, PolicyError> {
        let channel = Channel::start(&config)?;
        Ok(ProcessPolicy {
            channel: Arc::new(Mutex::new(channel)),
            config: Arc::new(config),
            prediction: false,
            step: 0,
            greeted: Arc::new(Mutex::new(false)),
            steering_rad: Vec::new(),
            memory: ObservationMemory::default(),
        })
    }

    fn hello(&self, input: &ObservationInput<'_>) -> Value {
        let mut seen = std::collections::BTreeSet::new();
        let paths: Vec<Value> = input
            .paths
            .paths
            .iter()
            .filter(|p| seen.insert(p.id))
            .map(|p| json!({"id": p.id, "is_loop": p.is_loop, "center_line": p.center_points}))
            .collect();
        let v = input.vehicle;
        json!({
            "type": "hello",
            "protocol": PROTOCOL_VERSION,
            "policy": self.config.name,
            "seed": self.config.seed,
            "dt_s": self.config.dt_s,
            "agents": input.agents.len(),
            "vehicle": {
                "length_m": v.length_m,
                "width_m": v.width_m,
                "wheelbase_m": v.wheelbase_m,
                "max_speed_mps": v.max_speed_mps,
                "max_steering_rad": v.max_steering_rad,
            },
            "paths": paths,
            "observation_size": self.config.observation.map(|o| o.size()),
        })
    }

    fn step_message(&self, input: &ObservationInput<'_>) -> Value {
        let agents: Vec<Value> = input
            .agents
            .iter()
            .zip(&input.paths.paths)
            .zip(&self.steering_rad)
            .map(|((a, p), steering)| {
                json!({
                    "x_m": a.x_m, "y_m": a.y_m, "yaw_rad": a.yaw_rad, "speed_mps": a.speed_mps,
                    "vx_mps": a.velocity_mps[0], "vy_mps": a.velocity_mps[1],
                    "steering_rad": steering, "ref_path": p.id,
                })
            })
            .collect();
        let mut message = json!({
            "type": "step",
            "step": self.step,
            "t_s": (self.step as f64 * self.config.dt_s * 1e9).round() / 1e9,
            "prediction": self.prediction,
            "agents": agents,
        });
        if let Some(o) = self.config.observation {
            let rows: Vec<&[f32]> = self.memory.observations().chunks(o.size().max(1)).collect();
            message["observations"] = json!(rows);
        }
        message
    }
}

/// Reads `{"actions": [[speed, steering], ...]}` with one finite pair per agent.
fn parse_actions(answer: &str, agents: usize, out: &mut [Command]) -> Result<(), String> {
    let shown: String = answer.chars().take(200).collect();
    let bad = |why: String| {
        format!(
            "answered out of protocol ({why}); expected {{\"actions\": [[speed_mps, steering_rad], ...]}} \
             with {agents} pairs, got: {shown}"
        )
    };
    let value: Value = serde_json::from_str(answer).map_err(|e| bad(format!("not JSON: {e}")))?;
    let actions = value
        .get("actions")
        .and_then(Value::as_array)
        .ok_or_else(|| bad("no `actions` list".into()))?;
    if actions.len() != agents {
        return Err(bad(format!("{} actions for {agents} agents", actions.len())));
    }
    for (i, (a, slot)) in actions.iter().zip(out.iter_mut()).enumerate() {
        let pair = a
            .as_array()
            .filter(|p| p.len() == 2)
            .and_then(|p| Some([p[0].as_f64()?, p[1].as_f64()?]))
            .filter(|p| p.iter().all(|v| v.is_finite()))
            .ok_or_else(|| bad(format!("action {i} is not two finite numbers")))?;
        *slot = Command {
            speed_mps: pair[0],
            steering_rad: pair[1],
        };
    }
    Ok(())
}

impl Policy for ProcessPolicy {
    fn act(&mut self, input: &ObservationInput<'_>, out: &mut [Command]) -> Result<(), PolicyError> {
        check_commands(input, out)?;
        let agents = input.agents.len();
        self.steering_rad.resize(agents, 0.0);

        // The observation, when asked for (with SigmaRL's memory of the previous corners).
        if let Some(o) = self.config.observation {
            self.memory.observe(&o, input)?;
        }

        let mut channel = self
            .channel
            .lock()
            .map_err(|_| PolicyError::Process("channel is poisoned".into()))?;
        let mut greeted = self
            .greeted
            .lock()
            .map_err(|_| PolicyError::Process("channel is poisoned".into()))?;
        if !*greeted {
            let answer = channel.ask(&self.hello(input), "the hello")?;
            let ok = serde_json::from_str::<Value>(&answer).ok().is_some_and(|v| {
                v.get("type").and_then(Value::as_str) == Some("ready")
                    && v.get("protocol").and_then(Value::as_u64) == Some(PROTOCOL_VERSION)
            });
            if !ok {
                let shown: String = answer.chars().take(200).collect();
                let reason = channel.fail(&format!(
                    "answered the hello out of protocol: expected {{\"type\": \"ready\", \"protocol\": {PROTOCOL_VERSION}}}, got: {shown}"
                ));
                return Err(PolicyError::Process(reason));
            }
            *greeted = true;
        }
        drop(greeted);
        let what = format!(
            "{}step {} (t = {} s)",
            if self.prediction { "predicted " } else { "" },
            self.step,
            self.step as f64 * self.config.dt_s
        );
        let answer = channel.ask(&self.step_message(input), &what)?;
        if let Err(reason) = parse_actions(&answer, agents, out) {
            let reason = channel.fail(&format!("at {what} {reason}"));
            return Err(PolicyError::Process(reason));
        }
        drop(channel);
        for (s, c) in self.steering_rad.iter_mut().zip(out.iter()) {
            *s = c.steering_rad;
        }
        self.step += 1;
        Ok(())
    }

    fn reset(&mut self) {
        self.memory.forget();
        self.steering_rad.clear();
    }

    fn fork(&mut self) -> Box<dyn Policy> {
        Box::new(ProcessPolicy {
            channel: Arc::clone(&self.channel),
            config: Arc::clone(&self.config),
            prediction: true,
            step: self.step,
            greeted: Arc::clone(&self.greeted),
            steering_rad: self.steering_rad.clone(),
            memory: self.memory.remembering(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_are_checked() {
        let mut out = [Command::default(); 2];
        assert!(parse_actions("{\"actions\": [[0.5, 0.1], [0.2, -0.1]]}", 2, &mut out).is_ok());
        assert_eq!(out[1].steering_rad, -0.1);
        for bad in [
            "nonsense",
            "{\"actions\": [[0.5, 0.1]]}",
            "{\"actions\": [[0.5, 0.1], [0.2]]}",
            "{\"actions\": [[0.5, 0.1], [0.2, null]]}",
            "{\"action\": []}",
        ] {
            let e = parse_actions(bad, 2, &mut out).expect_err(bad);
            assert!(e.contains("out of protocol"), "{e}");
        }
    }
}

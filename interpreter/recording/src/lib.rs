//! Recordings: the sampled states of every agent of one run, the only thing an engine hands
//! on and the only thing metrics read. Also the `trajectory.csv` format of cli.md.
//!
//! This crate owns the data type and its file format; it computes nothing from them.

use std::io::{Read, Write};

/// One agent's state at one sample time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AgentSample {
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    /// Velocity in the map frame [m/s].
    pub velocity_mps: [f64; 2],
    /// Steering angle [rad]; NaN when the source did not record it.
    pub steering_rad: f64,
}

/// The states of all agents over time: `samples[k][agent]` at `times_s[k]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Sample times [s] from the run's start, strictly increasing.
    pub times_s: Vec<f64>,
    /// Reference path id of each agent.
    pub ref_paths: Vec<usize>,
    /// One row per sample time, one entry per agent.
    pub samples: Vec<Vec<AgentSample>>,
    /// What the engine noticed without failing (e.g. late lab ticks). Not part of
    /// `trajectory.csv`; the run folder keeps them in `metrics.json`.
    pub notes: Vec<String>,
    /// A lab run's planning latency at each sample's tick [s]: from the tick's state list
    /// arriving to its commands sent (empty for simulated runs). Not part of
    /// `trajectory.csv`; the run folder keeps it in `metrics.json` (or `failed.json`).
    pub latency_s: Vec<f64>,
    /// Numbers a layer counted over the run, by name (`safety.changed`: agent-steps whose action
    /// the safety filter changed, ...). Not part of `trajectory.csv`; the run folder keeps them
    /// in `metrics.json` and `per_run.csv` has a column for each.
    pub statistics: std::collections::BTreeMap<String, f64>,
}

/// Why a trajectory file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    #[error("cannot read the trajectory: {0}")]
    Csv(#[from] csv::Error),
    #[error("line {line}: column `{column}` is missing")]
    MissingColumn { line: u64, column: &'static str },
    #[error("line {line}: column `{column}`: `{value}` is not a number")]
    BadNumber {
        line: u64,
        column: &'static str,
        value: String,
    },
    #[error("line {line}: agent {agent} appears twice at t = {t_s} s")]
    DuplicateSample { line: u64, agent: usize, t_s: f64 },
    #[error("t = {t_s} s has {found} agents, the recording has {expected}")]
    MissingAgents { t_s: f64, found: usize, expected: usize },
    #[error("line {line}: agent {agent} changes its reference path")]
    RefPathChanged { line: u64, agent: usize },
    #[error("line {line}: time goes backwards")]
    TimeBackwards { line: u64 },
    #[error("the recording has no samples")]
    Empty,
}

/// The header of `trajectory.csv`.
pub const TRAJECTORY_HEADER: [&str; 9] = ["t", "agent", "x", "y", "yaw", "vx", "vy", "steering", "ref_path"];

impl Recording {
    pub fn agent_count(&self) -> usize {
        self.ref_paths.len()
    }

    /// Writes `trajectory.csv`: one row per sample and agent, in time then agent order.
    /// Floats are written with Rust's shortest round-trip formatting, so reading back is exact.
    pub fn write_csv<W: Write>(&self, out: W) -> Result<(), csv::Error> {
        let mut writer = csv::Writer::from_writer(out);
        writer.write_record(TRAJECTORY_HEADER)?;
        for (t_s, row) in self.times_s.iter().zip(&self.samples) {
            for (agent, s) in row.iter().enumerate() {
                let steering = if s.steering_rad.is_nan() {
                    String::new()
                } else {
                    s.steering_rad.to_string()
                };
                writer.write_record([
                    t_s.to_string(),
                    agent.to_string(),
                    s.x_m.to_string(),
                    s.y_m.to_string(),
                    s.yaw_rad.to_string(),
                    s.velocity_mps[0].to_string(),
                    s.velocity_mps[1].to_string(),
                    steering,
                    self.ref_paths[agent].to_string(),
                ])?;
            }
        }
        writer.flush()?;
        Ok(())
    }

    /// Reads `trajectory.csv` (columns by name; extra columns ignored; `steering` may be empty).
    pub fn read_csv<R: Read>(input: R) -> Result<Recording, RecordingError> {
        let mut reader = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(input);
        let headers = reader.headers()?.clone();
        let col = |name: &'static str| headers.iter().position(|h| h == name);
        let required = ["t", "agent", "x", "y", "yaw", "vx", "vy", "ref_path"];
        let mut columns = [0; 8];
        for (column, name) in columns.iter_mut().zip(required) {
            *column = col(name).ok_or(RecordingError::MissingColumn {
                line: 1,
                column: name,
            })?;
        }
        let [
            t_col,
            agent_col,
            x_col,
            y_col,
            yaw_col,
            vx_col,
            vy_col,
            ref_path_col,
        ] = columns;
        let steering_col = col("steering");

        let mut recording = Recording::default();
        let mut ref_paths: Vec<Option<usize>> = Vec::new();
        for record in reader.records() {
            let record = record?;
            let line = record.position().map_or(0, |p| p.line());
            let field = |index: usize, name: &'static str| -> Result<&str, RecordingError> {
                record
                    .get(index)
                    .ok_or(RecordingError::MissingColumn { line, column: name })
            };
            let number = |index: usize, name: &'static str| -> Result<f64, RecordingError> {
                let value = field(index, name)?;
                value.parse::<f64>().map_err(|_| RecordingError::BadNumber {
                    line,
                    column: name,
                    value: value.to_string(),
                })
            };
            let integer = |index: usize, name: &'static str| -> Result<usize, RecordingError> {
                let value = field(index, name)?;
                value.parse::<usize>().map_err(|_| RecordingError::BadNumber {
                    line,
                    column: name,
                    value: value.to_string(),
                })
            };
            let t_s = number(t_col, "t")?;
            let agent = integer(agent_col, "agent")?;
            let ref_path = integer(ref_path_col, "ref_path")?;
            let steering_rad = match steering_col.and_then(|i| record.get(i)) {
                Some(v) if !v.is_empty() => v.parse::<f64>().map_err(|_| RecordingError::BadNumber {
                    line,
                    column: "steering",
                    value: v.to_string(),
                })?,
                _ => f64::NAN,
            };
            let sample = AgentSample {
                x_m: number(x_col, "x")?,
                y_m: number(y_col, "y")?,
                yaw_rad: number(yaw_col, "yaw")?,
                velocity_mps: [number(vx_col, "vx")?, number(vy_col, "vy")?],
                steering_rad,
            };

            // A new time opens a new row.
            match recording.times_s.last() {
                Some(&last) if last == t_s => {}
                Some(&last) if t_s < last => return Err(RecordingError::TimeBackwards { line }),
                _ => {
                    recording.times_s.push(t_s);
                    recording.samples.push(Vec::new());
                }
            }
            if ref_paths.len() <= agent {
                ref_paths.resize(agent + 1, None);
            }
            match ref_paths[agent] {
                Some(existing) if existing != ref_path => {
                    return Err(RecordingError::RefPathChanged { line, agent });
                }
                _ => ref_paths[agent] = Some(ref_path),
            }
            let row = recording.samples.last_mut().expect("a row was just opened");
            if row.len() <= agent {
                row.resize(
                    agent + 1,
                    AgentSample {
                        x_m: f64::NAN,
                        ..sample
                    },
                );
            } else if !row[agent].x_m.is_nan() {
                return Err(RecordingError::DuplicateSample { line, agent, t_s });
            }
            row[agent] = sample;
        }

        // Every agent must be present at every time.
        let agent_count = ref_paths.len();
        if agent_count == 0 || recording.times_s.is_empty() {
            return Err(RecordingError::Empty);
        }
        for (t_s, row) in recording.times_s.iter().zip(&recording.samples) {
            let found = row.iter().filter(|s| !s.x_m.is_nan()).count();
            if found != agent_count {
                return Err(RecordingError::MissingAgents {
                    t_s: *t_s,
                    found,
                    expected: agent_count,
                });
            }
        }
        recording.ref_paths = ref_paths
            .into_iter()
            .map(|r| r.expect("every agent has a row"))
            .collect();
        Ok(recording)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(x_m: f64) -> AgentSample {
        AgentSample {
            x_m,
            y_m: 0.5,
            yaw_rad: 0.1,
            velocity_mps: [0.3, -0.1],
            steering_rad: 0.05,
        }
    }

    #[test]
    fn csv_round_trip_is_exact() {
        let recording = Recording {
            notes: Vec::new(),
            latency_s: Vec::new(),
            statistics: Default::default(),
            times_s: vec![0.0, 0.1],
            ref_paths: vec![6, 1 << 40],
            samples: vec![
                vec![sample(1.0 / 3.0), sample(2.0)],
                vec![sample(0.1 + 0.2), sample(2.5)],
            ],
        };
        let mut bytes = Vec::new();
        recording.write_csv(&mut bytes).unwrap();
        assert_eq!(Recording::read_csv(bytes.as_slice()).unwrap(), recording);
    }

    #[test]
    fn a_missing_agent_is_an_error() {
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,1,1,0,0,0,,3\n0,1,1,1,0,0,0,,3\n0.1,0,1,1,0,0,0,,3\n";
        let err = Recording::read_csv(text.as_bytes()).unwrap_err();
        assert!(
            matches!(
                err,
                RecordingError::MissingAgents {
                    found: 1,
                    expected: 2,
                    ..
                }
            ),
            "{err}"
        );
    }

    #[test]
    fn a_truncated_line_is_an_error_not_a_panic() {
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,1,1,0,0,0,,3\n0.1,0";
        assert!(Recording::read_csv(text.as_bytes()).is_err());
    }
}

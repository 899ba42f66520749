//! Recordings: the sampled states of every agent of one run, the only thing an engine hands
//! on and the only thing metrics read. Also the `trajectory.csv` format of cli.md.
//!
//! This crate owns the data type and its file format; it computes nothing from them.

mod decimal;

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
///
/// An agent is present over one unbroken range of samples: every agent of most recordings
/// from the first sample to the last, while under `on_collision: replace-agent` a car that
/// collided leaves and the car placed instead is a new agent that appears later. Samples of an
/// absent agent are [`AgentSample::ABSENT`] (NaN), and `trajectory.csv` has no rows for them.
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

impl AgentSample {
    /// The sample of an agent that is not present at that time.
    pub const ABSENT: AgentSample = AgentSample {
        x_m: f64::NAN,
        y_m: f64::NAN,
        yaw_rad: f64::NAN,
        velocity_mps: [f64::NAN; 2],
        steering_rad: f64::NAN,
    };

    /// Whether the agent is present in this sample (an absent one's position is NaN).
    pub fn is_present(&self) -> bool {
        !self.x_m.is_nan()
    }
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
    #[error(
        "agent {agent} is missing at t = {t_s} s, between samples it has (an agent is present \
         over one unbroken range of times)"
    )]
    GapInAgent { agent: usize, t_s: f64 },
    #[error("agent {agent} has no rows (agents are numbered 0, 1, ... without holes)")]
    UnusedAgent { agent: usize },
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

    /// The samples `agent` is present in (`first..end`; empty if never).
    pub fn span(&self, agent: usize) -> std::ops::Range<usize> {
        let present = |row: &Vec<AgentSample>| row.get(agent).is_some_and(AgentSample::is_present);
        match self.samples.iter().position(present) {
            Some(first) => {
                first
                    ..self
                        .samples
                        .iter()
                        .rposition(present)
                        .map_or(first, |last| last + 1)
            }
            None => 0..0,
        }
    }

    /// Whether every agent is present in every sample (no agent came or left).
    pub fn is_complete(&self) -> bool {
        self.samples
            .iter()
            .all(|row| row.iter().all(AgentSample::is_present))
    }

    /// Writes `trajectory.csv`: one row per sample and present agent, in time then agent order.
    /// Floats are written with Rust's shortest round-trip formatting, so reading back is exact.
    /// Every field is a number (or an empty steering), so no field needs CSV quoting: the rows
    /// are written directly, as the `csv` crate would write them (`decimal.rs` gives `Display`'s
    /// bytes several times faster).
    pub fn write_csv<W: Write>(&self, mut out: W) -> Result<(), csv::Error> {
        let mut text = Vec::with_capacity(64 * (self.samples.len() * self.ref_paths.len() + 1));
        text.extend_from_slice(TRAJECTORY_HEADER.join(",").as_bytes());
        text.push(b'\n');
        for (&t_s, row) in self.times_s.iter().zip(&self.samples) {
            for (agent, s) in row.iter().enumerate().filter(|(_, s)| s.is_present()) {
                decimal::push_display(&mut text, t_s);
                // Writing to a Vec cannot fail; integers through `write!` allocate nothing.
                let _ = write!(text, ",{agent}");
                for value in [s.x_m, s.y_m, s.yaw_rad, s.velocity_mps[0], s.velocity_mps[1]] {
                    text.push(b',');
                    decimal::push_display(&mut text, value);
                }
                text.push(b',');
                if !s.steering_rad.is_nan() {
                    decimal::push_display(&mut text, s.steering_rad);
                }
                let _ = writeln!(text, ",{}", self.ref_paths[agent]);
            }
        }
        out.write_all(&text)?;
        out.flush()?;
        Ok(())
    }

    /// The recording as reading back its `trajectory.csv` gives it, without writing and
    /// reading the file: the samples only (no notes, latencies or statistics), every NaN the
    /// one `read_csv` parses. `None` when the file would not read back as this recording
    /// (a sample time without a present agent, times not increasing, an agent without samples
    /// or with a gap, an infinite position): a caller reads the file then.
    pub fn stored_copy(mut self) -> Option<Recording> {
        let increasing = self.times_s.windows(2).all(|pair| pair[0] < pair[1]);
        let rows_fit = self.samples.len() == self.times_s.len()
            && self
                .samples
                .iter()
                .all(|row| row.len() == self.ref_paths.len() && row.iter().any(AgentSample::is_present));
        let spans_unbroken = (0..self.ref_paths.len()).all(|agent| {
            let span = self.span(agent);
            !span.is_empty() && self.samples[span].iter().all(|row| row[agent].is_present())
        });
        let positions_finite = self
            .samples
            .iter()
            .flatten()
            .filter(|s| s.is_present())
            .all(|s| s.x_m.is_finite() && s.y_m.is_finite());
        if self.times_s.is_empty() || !(increasing && rows_fit && spans_unbroken && positions_finite) {
            return None;
        }
        let canonical = |value: f64| if value.is_nan() { f64::NAN } else { value };
        for sample in self.samples.iter_mut().flatten() {
            *sample = if sample.is_present() {
                AgentSample {
                    x_m: sample.x_m,
                    y_m: sample.y_m,
                    yaw_rad: canonical(sample.yaw_rad),
                    velocity_mps: sample.velocity_mps.map(canonical),
                    steering_rad: canonical(sample.steering_rad),
                }
            } else {
                AgentSample::ABSENT
            };
        }
        Some(Recording {
            times_s: self.times_s,
            ref_paths: self.ref_paths,
            samples: self.samples,
            ..Recording::default()
        })
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
            let position = |index: usize, name: &'static str| -> Result<f64, RecordingError> {
                // A position must be a number: NaN marks an absent agent in memory.
                let value = number(index, name)?;
                if value.is_finite() {
                    Ok(value)
                } else {
                    Err(RecordingError::BadNumber {
                        line,
                        column: name,
                        value: value.to_string(),
                    })
                }
            };
            let sample = AgentSample {
                x_m: position(x_col, "x")?,
                y_m: position(y_col, "y")?,
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
                row.resize(agent + 1, AgentSample::ABSENT);
            } else if row[agent].is_present() {
                return Err(RecordingError::DuplicateSample { line, agent, t_s });
            }
            row[agent] = sample;
        }

        // Every agent is present over one unbroken range of times (rows of agents that came
        // later or left earlier are absent).
        let agent_count = ref_paths.len();
        if agent_count == 0 || recording.times_s.is_empty() {
            return Err(RecordingError::Empty);
        }
        for row in &mut recording.samples {
            row.resize(agent_count, AgentSample::ABSENT);
        }
        for (agent, ref_path) in ref_paths.iter().enumerate() {
            if ref_path.is_none() {
                return Err(RecordingError::UnusedAgent { agent });
            }
            let span = recording.span(agent);
            if let Some(k) = span.clone().find(|&k| !recording.samples[k][agent].is_present()) {
                return Err(RecordingError::GapInAgent {
                    agent,
                    t_s: recording.times_s[k],
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
    fn the_rows_are_what_the_csv_crate_writes() {
        let recording = Recording {
            times_s: vec![0.0, 0.1],
            ref_paths: vec![6, 1 << 40],
            samples: vec![
                vec![
                    sample(1.0 / 3.0),
                    AgentSample {
                        steering_rad: f64::NAN,
                        ..sample(-0.0)
                    },
                ],
                vec![sample(1e-7), sample(2.5e16)],
            ],
            ..Recording::default()
        };
        let mut expected = csv::Writer::from_writer(Vec::new());
        expected.write_record(TRAJECTORY_HEADER).unwrap();
        for (t_s, row) in recording.times_s.iter().zip(&recording.samples) {
            for (agent, s) in row.iter().enumerate() {
                let steering = if s.steering_rad.is_nan() {
                    String::new()
                } else {
                    s.steering_rad.to_string()
                };
                expected
                    .write_record([
                        t_s.to_string(),
                        agent.to_string(),
                        s.x_m.to_string(),
                        s.y_m.to_string(),
                        s.yaw_rad.to_string(),
                        s.velocity_mps[0].to_string(),
                        s.velocity_mps[1].to_string(),
                        steering,
                        recording.ref_paths[agent].to_string(),
                    ])
                    .unwrap();
            }
        }
        let mut written = Vec::new();
        recording.write_csv(&mut written).unwrap();
        assert_eq!(
            String::from_utf8(written).unwrap(),
            String::from_utf8(expected.into_inner().unwrap()).unwrap()
        );
    }

    #[test]
    fn agents_may_come_late_and_leave_early_and_round_trip() {
        let gone = AgentSample::ABSENT;
        let recording = Recording {
            times_s: vec![0.0, 0.1, 0.2],
            ref_paths: vec![6, 2, 9],
            samples: vec![
                vec![sample(1.0), sample(2.0), gone],
                vec![sample(1.1), gone, sample(3.0)],
                vec![sample(1.2), gone, sample(3.1)],
            ],
            ..Recording::default()
        };
        assert_eq!(recording.span(0), 0..3);
        assert_eq!(recording.span(1), 0..1);
        assert_eq!(recording.span(2), 1..3);
        assert!(!recording.is_complete());
        let mut bytes = Vec::new();
        recording.write_csv(&mut bytes).unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert_eq!(text.lines().count(), 1 + 6, "no rows for absent agents:\n{text}");
        let back = Recording::read_csv(bytes.as_slice()).unwrap();
        assert_eq!(back.ref_paths, recording.ref_paths);
        for (a, b) in back
            .samples
            .iter()
            .flatten()
            .zip(recording.samples.iter().flatten())
        {
            assert_eq!(a.is_present(), b.is_present());
            if a.is_present() {
                assert_eq!(a, b);
            }
        }
    }

    #[test]
    fn a_gap_in_an_agent_is_an_error() {
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,1,1,0,0,0,,3\n0,1,1,1,0,0,0,,3\n\
                    0.1,0,1,1,0,0,0,,3\n0.2,0,1,1,0,0,0,,3\n0.2,1,1,1,0,0,0,,3\n";
        let err = Recording::read_csv(text.as_bytes()).unwrap_err();
        assert!(
            matches!(err, RecordingError::GapInAgent { agent: 1, t_s } if t_s == 0.1),
            "{err}"
        );
    }

    #[test]
    fn an_agent_number_without_rows_or_a_nan_position_is_an_error() {
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,1,1,0,0,0,,3\n0,2,1,1,0,0,0,,3\n";
        let err = Recording::read_csv(text.as_bytes()).unwrap_err();
        assert!(matches!(err, RecordingError::UnusedAgent { agent: 1 }), "{err}");
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,NaN,1,0,0,0,,3\n";
        let err = Recording::read_csv(text.as_bytes()).unwrap_err();
        assert!(
            matches!(err, RecordingError::BadNumber { column: "x", .. }),
            "{err}"
        );
    }

    #[test]
    fn a_truncated_line_is_an_error_not_a_panic() {
        let text = "t,agent,x,y,yaw,vx,vy,steering,ref_path\n0,0,1,1,0,0,0,,3\n0.1,0";
        assert!(Recording::read_csv(text.as_bytes()).is_err());
    }

    /// The bits of every number of a recording, absent samples included.
    fn bits(recording: &Recording) -> Vec<u64> {
        let samples = recording.samples.iter().flatten().flat_map(|s| {
            [
                s.x_m,
                s.y_m,
                s.yaw_rad,
                s.velocity_mps[0],
                s.velocity_mps[1],
                s.steering_rad,
            ]
        });
        recording
            .times_s
            .iter()
            .copied()
            .chain(samples)
            .map(f64::to_bits)
            .collect()
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { failure_persistence: None, cases: 2_000, ..Default::default() })]

        /// `stored_copy` is what writing and reading back gives, or `None` where that would
        /// differ or fail: recordings with agents that come and go, equal or decreasing times,
        /// gaps, NaN and infinite values of any sign and payload.
        #[test]
        fn the_stored_copy_is_what_reading_back_gives(
            agents in 1usize..4,
            rows in proptest::collection::vec(
                (proptest::prelude::any::<bool>(), proptest::collection::vec((0u8..8, proptest::prelude::any::<f64>(), -3.0f64..3.0), 4)),
                1..6,
            ),
            equal_time in 0usize..8,
        ) {
            let mut recording = Recording {
                ref_paths: (0..agents).map(|a| 3 * a + 1).collect(),
                notes: vec!["a note".into()],
                latency_s: vec![0.01],
                ..Recording::default()
            };
            for (k, (gap, cells)) in rows.iter().enumerate() {
                let t_s = if k == equal_time { k.saturating_sub(1) as f64 * 0.1 } else { k as f64 * 0.1 };
                recording.times_s.push(t_s);
                recording.samples.push(
                    cells[..agents]
                        .iter()
                        .map(|&(kind, odd, value)| match kind {
                            0 if *gap => AgentSample::ABSENT,
                            1 => AgentSample { steering_rad: f64::from_bits(0xfff8_0000_0000_0001), ..sample(value) },
                            2 => AgentSample { yaw_rad: odd, ..sample(value) },
                            3 if *gap => AgentSample { x_m: f64::INFINITY, ..sample(value) },
                            _ => sample(value),
                        })
                        .collect(),
                );
            }
            let mut bytes = Vec::new();
            recording.write_csv(&mut bytes).unwrap();
            let back = Recording::read_csv(bytes.as_slice());
            if let Some(copy) = recording.clone().stored_copy() {
                let back = back.expect("a stored copy reads back");
                proptest::prop_assert_eq!(bits(&copy), bits(&back));
                proptest::prop_assert_eq!(&copy.ref_paths, &back.ref_paths);
                proptest::prop_assert!(copy.notes.is_empty() && copy.latency_s.is_empty());
            }
        }
    }
}

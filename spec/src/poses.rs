//! Measured start poses listed per run in a CSV file (`from_poses:`), as the paper published
//! the lab's: a row per run, naming the policy's label, the initial configuration and the
//! repetition, then each vehicle's pose and reference path. See [`FromPosesSpec`] for the
//! layout; this module reads the file and answers which row a run starts from.

use std::path::Path;

use crate::model::FromPosesSpec;

/// One vehicle's measured start.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredPose {
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
    /// The reference path it follows (the map's numbering).
    pub ref_path: u64,
}

/// One row: the start of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// The row's line in the file (1-based; the header is line 1).
    pub line: usize,
    /// The label of the policy that started from it (`seed1`).
    pub label: String,
    /// The initial configuration (`init2`).
    pub configuration: String,
    /// 1-based.
    pub repetition: u32,
    /// Vehicle by vehicle.
    pub vehicles: Vec<MeasuredPose>,
}

/// The rows of a poses file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeasuredPoses {
    pub rows: Vec<PoseRow>,
}

/// Why a poses file cannot be read: the line (1-based; 0 for the file as a whole) and what is
/// wrong there.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{reason}", if *line == 0 { String::new() } else { format!("line {line}: ") })]
pub struct PosesError {
    pub line: usize,
    pub reason: String,
}

fn error(line: usize, reason: impl Into<String>) -> PosesError {
    PosesError {
        line,
        reason: reason.into(),
    }
}

/// How the key of a row is given.
enum KeyColumns {
    /// `policy`, `initial_configuration`, `repetition`.
    Named {
        label: usize,
        configuration: usize,
        repetition: usize,
    },
    /// `file`: `.../<label>/<configuration>-<repetition>.<ext>`.
    File(usize),
}

impl MeasuredPoses {
    /// Reads a poses file.
    pub fn read(path: &Path) -> Result<MeasuredPoses, PosesError> {
        let text = std::fs::read_to_string(path).map_err(|e| error(0, e.to_string()))?;
        Self::parse(&text)
    }

    /// Parses the text of a poses file.
    pub fn parse(text: &str) -> Result<MeasuredPoses, PosesError> {
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .flexible(true)
            .from_reader(text.as_bytes());
        let header = reader.headers().map_err(|e| error(1, e.to_string()))?.clone();
        if header.is_empty() {
            return Err(error(0, "the file is empty"));
        }
        let header: Vec<&str> = header.iter().collect();
        let column = |name: &str| header.iter().position(|h| *h == name);
        let keys = match (
            column("policy"),
            column("initial_configuration"),
            column("repetition"),
        ) {
            (Some(label), Some(configuration), Some(repetition)) => KeyColumns::Named {
                label,
                configuration,
                repetition,
            },
            _ => KeyColumns::File(column("file").ok_or_else(|| {
                error(
                    1,
                    "the header names neither `policy`, `initial_configuration` and `repetition` nor \
                     `file`",
                )
            })?),
        };
        let paths = column("ref_path_ids").ok_or_else(|| error(1, "the header has no `ref_path_ids`"))?;
        let mut pose_columns = Vec::new();
        for k in 1.. {
            let x = column(&format!("v{k}_x"));
            let y = column(&format!("v{k}_y"));
            let yaw = column(&format!("v{k}_theta")).or_else(|| column(&format!("v{k}_yaw")));
            match (x, y, yaw) {
                (Some(x), Some(y), Some(yaw)) => pose_columns.push([x, y, yaw]),
                (None, None, None) => break,
                _ => {
                    return Err(error(
                        1,
                        format!("vehicle {k} needs the columns `v{k}_x`, `v{k}_y` and `v{k}_theta`"),
                    ));
                }
            }
        }
        if pose_columns.is_empty() {
            return Err(error(
                1,
                "the header has no pose columns (`v1_x`, `v1_y`, `v1_theta`, ...)",
            ));
        }
        let mut rows: Vec<PoseRow> = Vec::new();
        for record in reader.records() {
            let record = record.map_err(|e| error(line_at(text, e.position()), e.to_string()))?;
            let line = line_at(text, record.position());
            let cells: Vec<&str> = record.iter().collect();
            if cells.len() != header.len() {
                return Err(error(
                    line,
                    format!("{} values for the header's {} columns", cells.len(), header.len()),
                ));
            }
            let (label, configuration, repetition) = match keys {
                KeyColumns::Named {
                    label,
                    configuration,
                    repetition,
                } => {
                    let repetition = cells[repetition].parse::<u32>().map_err(|_| {
                        error(
                            line,
                            format!("repetition `{}` is not a whole number", cells[repetition]),
                        )
                    })?;
                    (
                        cells[label].to_owned(),
                        cells[configuration].to_owned(),
                        repetition,
                    )
                }
                KeyColumns::File(file) => run_of_file(cells[file]).ok_or_else(|| {
                    error(
                        line,
                        format!(
                            "`{}` does not end in `<label>/<configuration>-<repetition>.<ext>`",
                            cells[file]
                        ),
                    )
                })?,
            };
            if repetition == 0 {
                return Err(error(line, "repetitions count from 1"));
            }
            let ids: Vec<&str> = cells[paths].split('|').map(str::trim).collect();
            if ids.len() != pose_columns.len() {
                return Err(error(
                    line,
                    format!(
                        "`ref_path_ids` names {} paths for {} vehicles",
                        ids.len(),
                        pose_columns.len()
                    ),
                ));
            }
            let mut vehicles = Vec::with_capacity(ids.len());
            for (k, (columns, id)) in pose_columns.iter().zip(&ids).enumerate() {
                let number = |c: usize| -> Result<f64, PosesError> {
                    let value = cells[c].parse::<f64>().ok().filter(|v| v.is_finite());
                    value.ok_or_else(|| {
                        error(
                            line,
                            format!("`{}` = `{}` is not a finite number", header[c], cells[c]),
                        )
                    })
                };
                let ref_path = id.parse::<u64>().map_err(|_| {
                    error(
                        line,
                        format!("vehicle {}'s reference path `{id}` is not a path id", k + 1),
                    )
                })?;
                vehicles.push(MeasuredPose {
                    x_m: number(columns[0])?,
                    y_m: number(columns[1])?,
                    yaw_rad: number(columns[2])?,
                    ref_path,
                });
            }
            if let Some(earlier) = rows
                .iter()
                .find(|r| r.label == label && r.configuration == configuration && r.repetition == repetition)
            {
                return Err(error(
                    line,
                    format!(
                        "`{label}`, `{configuration}`, repetition {repetition} has a row already (line {})",
                        earlier.line
                    ),
                ));
            }
            rows.push(PoseRow {
                line,
                label,
                configuration,
                repetition,
                vehicles,
            });
        }
        if rows.is_empty() {
            return Err(error(0, "the file has a header but no rows"));
        }
        Ok(MeasuredPoses { rows })
    }

    /// The configurations the file names, in the order they first appear.
    pub fn configurations(&self) -> Vec<&str> {
        let mut names: Vec<&str> = Vec::new();
        for row in &self.rows {
            if !names.contains(&row.configuration.as_str()) {
                names.push(&row.configuration);
            }
        }
        names
    }

    /// The row a run starts from.
    pub fn row(&self, label: &str, configuration: &str, repetition: u32) -> Option<&PoseRow> {
        self.rows
            .iter()
            .find(|r| r.label == label && r.configuration == configuration && r.repetition == repetition)
    }
}

/// `(label, configuration, repetition)` of a path ending in `<label>/<configuration>-<rep>.<ext>`.
fn run_of_file(path: &str) -> Option<(String, String, u32)> {
    let mut parts = path.rsplit(['/', '\\']);
    let name = parts.next()?;
    let label = parts.next()?;
    let stem = name.rsplit_once('.').map_or(name, |(stem, _)| stem);
    let (configuration, repetition) = stem.rsplit_once('-')?;
    let repetition = repetition.parse().ok()?;
    (!label.is_empty() && !configuration.is_empty())
        .then(|| (label.to_owned(), configuration.to_owned(), repetition))
}

impl FromPosesSpec {
    /// The label of the file's rows that policy `policy` started from.
    pub fn label_of<'a>(&'a self, policy: &'a str) -> &'a str {
        self.policies.get(policy).map_or(policy, String::as_str)
    }
}

/// The 1-based line of a record at `position` in `text`, counted from its byte offset: on
/// `\r\n` endings (the paper's poses.csv has them) the csv crate places a record at the `\n`
/// that ends the line before it, and counts its lines one short.
fn line_at(text: &str, position: Option<&csv::Position>) -> usize {
    position.map_or(0, |p| {
        let bytes = text.as_bytes();
        let mut start = (p.byte() as usize).min(bytes.len());
        while start < bytes.len() && matches!(bytes[start], b'\r' | b'\n') {
            start += 1;
        }
        bytes[..start].iter().filter(|&&b| b == b'\n').count() + 1
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER_LAYOUT: &str = "id,file,v1_x,v1_y,v1_theta,v2_x,v2_y,v2_theta,ref_path_ids
1,results/physical_lab/seed1/init1-1.td,1.9,3.2,-1.2,3.1,1.9,-0.02,3|5
2,results/physical_lab/seed1/init1-2.td,1.9,3.2,-1.2,3.1,1.9,-0.01,3|5
3,results/physical_lab/seed2/init2-1.td,1.3,1.9,-0.03,3.1,2.2,-3.1,6|1
";

    #[test]
    fn the_papers_layout_names_each_run_by_its_file() {
        let poses = MeasuredPoses::parse(PAPER_LAYOUT).unwrap();
        assert_eq!(poses.configurations(), ["init1", "init2"]);
        let row = poses.row("seed1", "init1", 2).unwrap();
        assert_eq!(row.line, 3);
        // Windows line endings (as the paper's file has them) count the same lines.
        let crlf = MeasuredPoses::parse(&PAPER_LAYOUT.replace('\n', "\r\n")).unwrap();
        assert_eq!(crlf.row("seed1", "init1", 1).unwrap().line, 2);
        assert_eq!(crlf.row("seed2", "init2", 1).unwrap().line, 4);
        assert_eq!(row.vehicles.len(), 2);
        assert_eq!(row.vehicles[1].yaw_rad, -0.01);
        assert_eq!(row.vehicles[1].ref_path, 5);
        assert!(poses.row("seed2", "init1", 1).is_none());
    }

    #[test]
    fn named_key_columns_and_yaw() {
        let text = "policy,initial_configuration,repetition,v1_x,v1_y,v1_yaw,ref_path_ids\na,c,1,1,2,0.5,7\n";
        let poses = MeasuredPoses::parse(text).unwrap();
        assert_eq!(poses.row("a", "c", 1).unwrap().vehicles[0].ref_path, 7);
    }

    #[test]
    fn bad_rows_are_located() {
        let cases = [
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\ns/i-1.td,1,x,0,3\n",
                "line 2: `v1_y` = `x` is not a finite number",
            ),
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\ns/i-1.td,1,2,0,3|4\n",
                "line 2: `ref_path_ids` names 2 paths for 1 vehicles",
            ),
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\ns/i-1.td,1,2\n",
                "line 2: 3 values for the header's 5 columns",
            ),
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\nrun.td,1,2,0,3\n",
                "line 2: `run.td` does not end in `<label>/<configuration>-<repetition>.<ext>`",
            ),
            (
                "file,v1_x,v1_y,ref_path_ids\n",
                "line 1: vehicle 1 needs the columns `v1_x`, `v1_y` and `v1_theta`",
            ),
            (
                "file,x,ref_path_ids\n",
                "line 1: the header has no pose columns (`v1_x`, `v1_y`, `v1_theta`, ...)",
            ),
            (
                "x,v1_x,v1_y,v1_theta,ref_path_ids\n",
                "line 1: the header names neither `policy`, `initial_configuration` and `repetition` nor `file`",
            ),
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\ns/i-1.td,1,2,0,3\ns/i-1.td,1,2,0,3\n",
                "line 3: `s`, `i`, repetition 1 has a row already (line 2)",
            ),
            (
                "file,v1_x,v1_y,v1_theta,ref_path_ids\n",
                "the file has a header but no rows",
            ),
            ("", "the file is empty"),
        ];
        for (text, message) in cases {
            assert_eq!(
                MeasuredPoses::parse(text).unwrap_err().to_string(),
                message,
                "{text}"
            );
        }
    }

    #[test]
    fn a_label_is_the_policy_unless_mapped() {
        let spec = FromPosesSpec {
            file: "poses.csv".into(),
            sha256: None,
            policies: [("paper-seed1".to_owned(), "seed1".to_owned())].into(),
            off_road_tolerance_m: 0.02,
        };
        assert_eq!(spec.label_of("paper-seed1"), "seed1");
        assert_eq!(spec.label_of("seed2"), "seed2");
    }
}

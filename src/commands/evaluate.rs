//! `cpmx evaluate SPEC RECORDING.csv`: the spec's metrics of a recording made elsewhere, as one
//! JSON object with every metric and the raw counts behind it.

use std::path::Path;

use cpmx_engine::{Experiment, measure};
use cpmx_recording::Recording;

use super::{Failure, load_checked};
use crate::DataArgs;

pub fn run(spec: &Path, recording: &Path, data: &DataArgs) -> Result<(), Failure> {
    let checked = load_checked(spec, data)?;
    let experiment = Experiment::prepare(&checked).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let file = std::fs::File::open(recording).map_err(|e| {
        eprintln!("error: cannot read `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    let recording_data = Recording::read_csv(file).map_err(|e| {
        eprintln!("error: `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    let metrics = measure(&experiment, &recording_data).map_err(|e| {
        eprintln!("error: `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    println!("{}", serde_json::to_string_pretty(&metrics).unwrap_or_default());
    Ok(())
}

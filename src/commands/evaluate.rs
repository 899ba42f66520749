//! `cpmx evaluate SPEC RECORDING.csv`: the spec's metrics of a recording made elsewhere, as one
//! JSON object with every metric and the raw counts behind it. Needs only the spec's map.

use std::io::IsTerminal;
use std::path::Path;

use cpmx_engine::Scoring;
use cpmx_recording::Recording;
use cpmx_spec::{CheckScope, DataPath, SpecSource};

use super::Failure;
use crate::DataArgs;

pub fn run(spec: &Path, recording: &Path, data: &DataArgs) -> Result<(), Failure> {
    let source = SpecSource::read(spec).map_err(|e| {
        eprintln!("error: cannot read spec `{}`: {e}", spec.display());
        Failure::InvalidInput
    })?;
    let data_path = DataPath::new(
        &source.dir,
        &data.data,
        std::env::var("CPMX_DATA").ok().as_deref(),
    );
    let checked = cpmx_spec::check_scoped(
        &source,
        &data_path,
        &cpmx_engine::BuildChecks,
        CheckScope::Measure,
    )
    .map_err(|d| {
        eprint!("{}", cpmx_spec::render(&d, std::io::stderr().is_terminal()));
        Failure::InvalidInput
    })?;
    let scoring = Scoring::prepare(&checked).map_err(|e| {
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
    let metrics = scoring.measure(&recording_data).map_err(|e| {
        eprintln!("error: `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    println!("{}", serde_json::to_string_pretty(&metrics).unwrap_or_default());
    Ok(())
}

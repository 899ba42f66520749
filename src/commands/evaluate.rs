//! `cpmx evaluate SPEC RECORDING.csv [--configuration NAME]`: the spec's metrics of a recording
//! made elsewhere, as one JSON object with every metric and the raw counts behind it. Needs only
//! the spec's map (or the named configuration's own).

use std::io::IsTerminal;
use std::path::Path;

use cpmx_engine::Scoring;
use cpmx_recording::Recording;
use cpmx_spec::{CheckScope, DataPath, SpecSource};

use super::Failure;
use crate::DataArgs;

pub fn run(
    spec: &Path,
    recording: &Path,
    configuration: Option<&str>,
    data: &DataArgs,
) -> Result<(), Failure> {
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
    let configuration = match configuration {
        Some(name) if !checked.configurations.iter().any(|c| c.name == name) => {
            let known: Vec<&str> = checked.configurations.iter().map(|c| c.name.as_str()).collect();
            eprintln!(
                "error: the spec has no initial configuration `{name}`; its configurations are {}",
                known.join(", ")
            );
            return Err(Failure::InvalidInput);
        }
        Some(name) => name,
        None if scoring.has_several_maps() => {
            let own: Vec<&str> = scoring.configuration_maps.keys().map(String::as_str).collect();
            eprintln!(
                "error: the spec's configurations drive on several maps; say which one the recording drove on with `--configuration NAME` (those with a map of their own: {})",
                own.join(", ")
            );
            return Err(Failure::InvalidInput);
        }
        // No configuration names a map of its own: every one is on the spec's `map`.
        None => "",
    };
    let file = std::fs::File::open(recording).map_err(|e| {
        eprintln!("error: cannot read `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    let recording_data = Recording::read_csv(file).map_err(|e| {
        eprintln!("error: `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    let metrics = scoring.measure(configuration, &recording_data).map_err(|e| {
        eprintln!("error: `{}`: {e}", recording.display());
        Failure::InvalidInput
    })?;
    println!("{}", serde_json::to_string_pretty(&metrics).unwrap_or_default());
    Ok(())
}

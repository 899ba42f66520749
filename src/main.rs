//! `cpmx`: the command line over the spec and interpreter crates. Thin by design: it parses
//! arguments, calls the crates, renders diagnostics and maps outcomes to exit codes
//! (0 success, 1 invalid input, 2 usage error, 3 some runs failed, 130 interrupted).

mod commands;
mod interrupt;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Reproducible sim-to-real experiments for multi-agent motion planners in the CPM Lab.
#[derive(Debug, Parser)]
#[command(name = "cpmx", version, about, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Where relative files of a spec are looked up besides the spec's folder.
#[derive(Debug, Clone, clap::Args)]
pub struct DataArgs {
    /// A folder to look up maps, weights and run folders in (repeatable; after the spec's
    /// folder, before `CPMX_DATA`).
    #[arg(long = "data", value_name = "DIR")]
    pub data: Vec<PathBuf>,
}

/// What `cpmx schema` prints.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum SchemaFormat {
    Json,
    Markdown,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Check specs against the schema and for meaning; print every problem.
    Validate {
        /// The spec files.
        #[arg(required = true)]
        specs: Vec<PathBuf>,
        #[command(flatten)]
        data: DataArgs,
    },
    /// Print the run matrix of a spec, with every run's start poses.
    Plan {
        /// The spec file.
        spec: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value_t = commands::plan::PlanFormat::Table)]
        format: commands::plan::PlanFormat,
        #[command(flatten)]
        data: DataArgs,
    },
    /// Execute the run matrix and write the run folder.
    Run(commands::run::RunArgs),
    /// Train one policy per seed of the spec's `training:` section (MAPPO, as SigmaRL).
    Train(commands::train::TrainArgs),
    /// Recompute and summarise stored runs (several folders merge).
    Report(commands::report::ReportArgs),
    /// The spec's metrics of a recording made elsewhere, as JSON (needs only the spec's map).
    Evaluate {
        /// The spec whose map, vehicle and metrics score the recording.
        spec: PathBuf,
        /// A trajectory CSV (header `t,agent,x,y,yaw,vx,vy,steering,ref_path`).
        recording: PathBuf,
        /// The initial configuration whose map the recording drove on, when the spec's
        /// configurations name maps of their own (default: the spec's `map`).
        #[arg(long, value_name = "NAME")]
        configuration: Option<String>,
        #[command(flatten)]
        data: DataArgs,
    },
    /// Print the JSON Schema of the language (draft 2020-12), or the language reference.
    Schema {
        /// `json`: the JSON Schema (`cpmx.schema.json`); `markdown`: the reference
        /// (`docs/language.md`).
        #[arg(long, value_enum, default_value_t = SchemaFormat::Json)]
        format: SchemaFormat,
    },
    /// List the standard library's presets, or print one (`cpmx stdlib at25-paper`).
    Stdlib {
        /// A preset's name, with or without `stdlib:`; omit it to list them all.
        name: Option<String>,
    },
    /// A trained actor as an ONNX model that any ONNX runtime loads.
    #[cfg(feature = "onnx")]
    Export(commands::export::ExportArgs),
    /// The CPM Lab: `cpmx lab emulate SPEC` plays the lab for the spec's lab fidelity.
    Lab {
        #[command(subcommand)]
        command: commands::lab::LabCommand,
    },
}

/// Set to `1`, cpmx parses its arguments (exit 2 on a usage error, as always) and stops there
/// with exit 0: how the documentation's test checks commands too long to run (trainings,
/// benchmarks) against the current flags. Not for users; undocumented in `--help`.
const PARSE_ONLY: &str = "CPMX_PARSE_ONLY";

/// The build that runs or trains: version and commit (recorded in a run folder's
/// `provenance.json` and a training's `run.json`).
fn made_by() -> String {
    match option_env!("CPMX_COMMIT") {
        Some(commit) if !commit.is_empty() => {
            format!("cpmx {} (commit {commit})", env!("CARGO_PKG_VERSION"))
        }
        _ => format!("cpmx {}", env!("CARGO_PKG_VERSION")),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if std::env::var_os(PARSE_ONLY).is_some_and(|v| v == "1") {
        return ExitCode::SUCCESS;
    }
    let outcome = match cli.command {
        Command::Validate { specs, data } => commands::validate::run(&specs, &data),
        Command::Plan { spec, format, data } => commands::plan::run(&spec, format, &data),
        Command::Run(args) => commands::run::run(&args),
        Command::Train(args) => commands::train::run(&args),
        Command::Report(args) => commands::report::run(&args),
        Command::Evaluate {
            spec,
            recording,
            configuration,
            data,
        } => commands::evaluate::run(&spec, &recording, configuration.as_deref(), &data),
        Command::Lab { command } => commands::lab::run(&command),
        #[cfg(feature = "onnx")]
        Command::Export(args) => commands::export::run(&args),
        Command::Stdlib { name } => commands::stdlib::run(name.as_deref()),
        Command::Schema { format } => {
            match format {
                SchemaFormat::Json => print!("{}", cpmx_spec::schema::json_schema_text()),
                SchemaFormat::Markdown => print!("{}", cpmx_spec::reference::language_reference_markdown()),
            }
            Ok(())
        }
    };
    match outcome {
        Ok(()) => ExitCode::SUCCESS,
        Err(code) => ExitCode::from(code as u8),
    }
}

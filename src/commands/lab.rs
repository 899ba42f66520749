//! `cpmx lab emulate SPEC`: plays the CPM Lab (middleware and vehicles) over its DDS topics
//! from a simulated fidelity of the spec, for the lab driver's tests and rehearsals.

use std::path::PathBuf;

use cpmx_engine::Experiment;
use cpmx_engine::lab::{Emulator, EmulatorEvent};

use super::{Failure, load_checked};
use crate::DataArgs;

/// The `cpmx lab` commands.
#[derive(Debug, clap::Subcommand)]
pub enum LabCommand {
    /// Play the CPM Lab for the spec's lab fidelity, driven by a simulated fidelity; runs until
    /// stopped (Ctrl-C).
    Emulate(EmulateArgs),
}

/// Options of `cpmx lab emulate`.
#[derive(Debug, clap::Args)]
pub struct EmulateArgs {
    /// The spec file; its lab fidelity gives the domain, the vehicle ids and the timeout.
    pub spec: PathBuf,
    /// The simulated `control: trajectory` fidelity that plays the lab. Default: the spec's
    /// first one (e.g. `twin`).
    #[arg(long, value_name = "NAME")]
    pub fidelity: Option<String>,
    /// Serve this many runs, then exit (default: until stopped).
    #[arg(long, value_name = "N")]
    pub runs: Option<usize>,
    #[command(flatten)]
    pub data: DataArgs,
}

pub fn run(command: &LabCommand) -> Result<(), Failure> {
    match command {
        LabCommand::Emulate(args) => emulate(args),
    }
}

fn emulate(args: &EmulateArgs) -> Result<(), Failure> {
    let checked = load_checked(&args.spec, &args.data)?;
    let experiment = Experiment::prepare(&checked).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let emulator = Emulator::new(&checked, &experiment, args.fidelity.as_deref()).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })?;
    let lab = emulator.lab();
    eprintln!(
        "emulating the CPM Lab for fidelity `{}` (domain {}, vehicles {:?}) with fidelity `{}`, in simulated time; Ctrl-C to stop",
        emulator.lab_name(),
        lab.domain,
        lab.vehicle_ids,
        emulator.fidelity_name()
    );
    let mut on_event = |event: EmulatorEvent| match event {
        EmulatorEvent::Waiting => eprintln!("waiting for a planner (ReadyStatus hlc_<id> for every vehicle)"),
        EmulatorEvent::Started { run, seed } => eprintln!("run {run} (seed {seed}) started"),
        EmulatorEvent::Finished { ticks } => eprintln!("run finished after {ticks} ticks"),
        EmulatorEvent::Abandoned { ticks } => eprintln!(
            "the planner stopped answering after {ticks} ticks ({} s); run abandoned",
            lab.timeout_s
        ),
    };
    emulator.serve(args.runs, &mut on_event).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })
}

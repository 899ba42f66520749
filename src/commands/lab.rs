//! `cpmx lab emulate SPEC`: plays the CPM Lab (middleware and vehicles) over its DDS topics
//! from a simulated fidelity of the spec, for the lab driver's tests and rehearsals, in
//! simulated or real time, with the lab fidelity's faults or those of `--faults FILE`.

use std::io::IsTerminal;
use std::path::PathBuf;

use cpmx_engine::Experiment;
use cpmx_engine::lab::{Emulator, EmulatorClock, EmulatorEvent};

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
    /// The spec file; its lab fidelity gives the domain, the vehicle ids, the timeout and the
    /// faults to play.
    pub spec: PathBuf,
    /// The simulated `control: trajectory` fidelity that plays the lab. Default: the spec's
    /// first one (e.g. `twin`).
    #[arg(long, value_name = "NAME")]
    pub fidelity: Option<String>,
    /// Serve this many runs, then exit (default: until stopped).
    #[arg(long, value_name = "N")]
    pub runs: Option<usize>,
    /// Play the faults of this YAML file (the mapping of a lab fidelity's `faults:`) instead
    /// of the spec's.
    #[arg(long, value_name = "FILE")]
    pub faults: Option<PathBuf>,
    /// Run on the wall clock, as the lab does: the middleware ticks every period whether the
    /// planner answered or not (default: simulated time, in lock-step with the planner).
    #[arg(long)]
    pub real_time: bool,
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
    let emulator = match &args.faults {
        Some(path) => {
            let faults = read_faults(path, &emulator.lab().vehicle_ids)?;
            emulator.with_faults(Some(faults))
        }
        None => emulator,
    };
    let clock = if args.real_time {
        EmulatorClock::RealTime
    } else {
        EmulatorClock::Simulated
    };
    let emulator = emulator.with_clock(clock);
    let lab = emulator.lab();
    eprintln!(
        "emulating the CPM Lab for fidelity `{}` (domain {}, vehicles {:?}) with fidelity `{}`, in {}{}; Ctrl-C to stop",
        emulator.lab_name(),
        lab.domain,
        lab.vehicle_ids,
        emulator.fidelity_name(),
        match clock {
            EmulatorClock::Simulated => "simulated time",
            EmulatorClock::RealTime => "real time",
        },
        emulator
            .faults()
            .map_or(String::new(), |f| format!(", with faults (seed {})", f.seed))
    );
    let mut on_event = |event: EmulatorEvent| match event {
        EmulatorEvent::Waiting => eprintln!("waiting for a planner (ReadyStatus hlc_<id> for every vehicle)"),
        EmulatorEvent::Started { run, seed, faults } if faults.is_empty() => {
            eprintln!("run {run} (seed {seed}) started");
        }
        EmulatorEvent::Started { run, seed, faults } => {
            eprintln!("run {run} (seed {seed}) started; faults: {}", faults.join("; "));
        }
        EmulatorEvent::Fault(what) => eprintln!("fault: {what}"),
        EmulatorEvent::Stopped { commanded, standing } => {
            eprintln!("vehicles commanded to stop: {commanded:?}; standing at the run's end: {standing:?}")
        }
        EmulatorEvent::Finished { ticks } => eprintln!("run finished after {ticks} ticks"),
        EmulatorEvent::Ended { ticks } => {
            eprintln!("the planner stopped its vehicles after {ticks} ticks; run ended");
        }
        EmulatorEvent::Abandoned { ticks } => eprintln!(
            "the planner stopped answering after {ticks} ticks ({} s); run abandoned",
            lab.timeout_s
        ),
        EmulatorEvent::Superseded { ticks } => {
            eprintln!("the planner announced another run after {ticks} ticks; run abandoned");
        }
        EmulatorEvent::FollowerStopped(stops) => {
            if let Some(note) = stops.note() {
                eprintln!("{note}");
            }
        }
    };
    emulator.serve(args.runs, &mut on_event).map_err(|e| {
        eprintln!("error: {e}");
        Failure::InvalidInput
    })
}

/// A faults file, checked as the spec's `faults:` is (located diagnostics).
fn read_faults(path: &std::path::Path, vehicle_ids: &[u8]) -> Result<cpmx_spec::model::LabFaults, Failure> {
    let source = cpmx_spec::SpecSource::read(path).map_err(|e| {
        eprintln!("error: {}: {e}", path.display());
        Failure::InvalidInput
    })?;
    cpmx_spec::check_faults(&source, vehicle_ids).map_err(|diagnostics| {
        eprint!(
            "{}",
            cpmx_spec::render(&diagnostics, std::io::stderr().is_terminal())
        );
        eprintln!("{}: {} errors", path.display(), diagnostics.len());
        Failure::InvalidInput
    })
}

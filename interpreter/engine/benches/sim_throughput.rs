//! Sim throughput (`cargo bench -p cpmx-engine --bench sim_throughput`): the paper design's
//! `sim` fidelity through the public engine API, as `tests/sigmarl_rollout.rs` drives it.
//!
//! - `sim/paper_seed1_init1`: one run of the reference actor on the CPM Lab map, 3 agents,
//!   180 steps; throughput in agent-steps (the target: 100,000 agent-steps/s on one core);
//! - `sim/paper_27_runs`: all 27 `sim` runs of the paper's benchmark `experiments/at25-cpmx.yaml`
//!   (3 actors x 3 configurations x 3 repetitions), one after the other on one thread.
//!
//! Needs SigmaRL's reference data at `../shared/reference` next to the repository.

use std::hint::black_box;
use std::path::{Path, PathBuf};

use cpmx_engine::{Engine, Experiment, RunInputs, SimEngine};
use cpmx_spec::{CheckedSpec, DataPath, RunPlan, SpecSource};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};

/// Agents of the paper design.
const AGENTS: u64 = 3;
/// Steps of the paper design (18 s at 0.1 s).
const STEPS: u64 = 180;

/// SigmaRL's reference data (the CPM Lab map and the actors).
fn reference() -> PathBuf {
    cpmx_testdata::reference()
}

/// The paper design's `sim` setup for the reference actor and its first configuration.
fn paper_seed1_spec() -> String {
    format!(
        "cpmx: 1\nname: sim-throughput\nmap: {{file: maps/cpm.xml}}\nvehicle: stdlib:mu-car\n\
         timing: {{dt: 0.1, steps: {STEPS}}}\nagents: {AGENTS}\n\
         policies:\n  - {{name: seed1, mlp: {{weights: policy/actor.safetensors}}, \
         observation: stdlib:sigmarl, action: mean}}\n\
         initial_configurations:\n  - name: init1\n    agents:\n\
         \x20     - {{ref_path: 6, arc_length: 0.3}}\n\
         \x20     - {{ref_path: 2, arc_length: 0.3}}\n\
         \x20     - {{ref_path: 3, arc_length: 0.3}}\n\
         repetitions: 1\nseed: 2026\n\
         fidelities:\n  sim: {{control: direct, dynamics: kinematic}}\n"
    )
}

/// Check a spec whose data files are looked up in the reference folder.
fn check(name: &str, dir: &Path, text: String) -> CheckedSpec {
    let source = SpecSource {
        name: name.into(),
        dir: dir.to_owned(),
        text,
    };
    // As `cpmx run --data ../shared/reference`: the spec's folder (its trained actors) first.
    let data = [reference()];
    cpmx_spec::check(
        &source,
        &DataPath::new(dir, &data, None),
        &cpmx_engine::BuildChecks,
    )
    .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)))
}

/// Run one planned run through the sim engine; returns the number of recorded steps.
fn run(experiment: &Experiment, plan: &RunPlan) -> usize {
    let starts = experiment.start(plan).expect("the plan's initial configuration");
    let recording = SimEngine
        .run(&RunInputs {
            experiment,
            plan,
            starts,
            fidelity: None,
            stop: None,
            operator: None,
            timing: false,
        })
        .expect("the sim run");
    recording.samples.len()
}

fn sim_throughput(c: &mut Criterion) {
    let mut group = c.benchmark_group("sim");

    // One run: reference actor, CPM Lab map, 3 agents, 180 steps.
    let checked = check("sim-throughput.yaml", &reference(), paper_seed1_spec());
    let experiment = Experiment::prepare(&checked).expect("the experiment");
    let plan = checked.plan().into_iter().next().expect("one run");
    assert_eq!(run(&experiment, &plan), STEPS as usize);
    group.throughput(Throughput::Elements(AGENTS * STEPS));
    group.bench_function("paper_seed1_init1", |b| {
        b.iter(|| run(black_box(&experiment), black_box(&plan)))
    });

    // The paper design's 27 sim runs, sequentially.
    let experiments = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../experiments");
    let text = std::fs::read_to_string(experiments.join("at25-cpmx.yaml")).expect("the paper's benchmark");
    let checked = check("at25-cpmx.yaml", &experiments, text);
    let experiment = Experiment::prepare(&checked).expect("the experiment");
    let plans: Vec<RunPlan> = checked
        .plan()
        .into_iter()
        .filter(|p| p.fidelity == "sim")
        .collect();
    assert_eq!(plans.len(), 27);
    group.throughput(Throughput::Elements(plans.len() as u64 * AGENTS * STEPS));
    group.sample_size(10);
    group.bench_function("paper_27_runs", |b| {
        b.iter(|| {
            plans
                .iter()
                .map(|p| run(black_box(&experiment), p))
                .sum::<usize>()
        })
    });
    group.finish();
}

criterion_group!(benches, sim_throughput);
criterion_main!(benches);

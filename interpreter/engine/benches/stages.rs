//! Where the time of a run goes, stage by stage (`cargo bench -p cpmx-engine --bench stages`),
//! on the first twin run and the first sim run of the paper's benchmark `experiments/at25-cpmx.yaml`
//! (3 agents x 18 s):
//!
//! - `stages/twin_run`, `stages/sim_run`: the engine alone (policy, planner, follower, plant,
//!   sensing for the twin; policy and bicycle for the sim) and its metrics (`simulate`);
//! - `stages/metrics`: the metrics of the twin run's recording alone (CRA-A, CRA-L, CD, speed);
//! - `stages/recording`: writing the recording's `trajectory.csv` (into memory);
//! - `stages/report`: the run's trajectory figure (SVG).
//!
//! The follower's decisions have their own bench (`follower_solve`), the actor's forward pass
//! too (`cargo bench -p cpmx-policy --bench forward`); the shares of the stages inside a whole
//! command are measured with `perf` (docs/performance.md). Needs SigmaRL's reference data at
//! `../shared/reference` next to the repository.

use std::hint::black_box;
use std::path::Path;

use cpmx_engine::{Experiment, measure_recording, simulate};
use cpmx_spec::{CheckedSpec, DataPath, RunPlan, SpecSource};
use criterion::{Criterion, criterion_group, criterion_main};

/// The paper's benchmark, checked with the reference data.
fn at25() -> CheckedSpec {
    let experiments = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../experiments");
    let source = SpecSource {
        name: "at25-cpmx.yaml".into(),
        dir: experiments.clone(),
        text: std::fs::read_to_string(experiments.join("at25-cpmx.yaml")).expect("the paper's benchmark"),
    };
    // As `cpmx run --data ../shared/reference`: the spec's folder (its trained actors) first.
    let data = [cpmx_testdata::reference()];
    cpmx_spec::check(
        &source,
        &DataPath::new(&experiments, &data, None),
        &cpmx_engine::BuildChecks,
    )
    .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)))
}

fn first_of(plans: &[RunPlan], fidelity: &str) -> RunPlan {
    plans
        .iter()
        .find(|p| p.fidelity == fidelity)
        .unwrap_or_else(|| panic!("a {fidelity} run"))
        .clone()
}

fn stages(c: &mut Criterion) {
    let checked = at25();
    let experiment = Experiment::prepare(&checked).expect("the experiment");
    let plans = checked.plan();
    let (twin, sim) = (first_of(&plans, "twin"), first_of(&plans, "sim"));
    let (recording, metrics) = simulate(&experiment, &twin).expect("the twin run");
    let mut group = c.benchmark_group("stages");
    group.sample_size(20);
    group.bench_function("twin_run", |b| {
        b.iter(|| simulate(black_box(&experiment), black_box(&twin)).expect("the twin run"))
    });
    group.bench_function("sim_run", |b| {
        b.iter(|| simulate(black_box(&experiment), black_box(&sim)).expect("the sim run"))
    });
    group.bench_function("metrics", |b| {
        b.iter(|| {
            measure_recording(
                &experiment.map,
                &experiment.footprint,
                &experiment.metrics,
                black_box(&recording),
            )
            .expect("the metrics")
        })
    });
    group.bench_function("recording", |b| {
        b.iter(|| {
            let mut csv = Vec::with_capacity(1 << 20);
            recording.write_csv(&mut csv).expect("the CSV");
            csv.len()
        })
    });
    group.bench_function("report", |b| {
        b.iter(|| {
            cpmx_report::trajectory_svg(
                &experiment.map,
                black_box(&recording),
                &metrics,
                &experiment.footprint,
            )
            .len()
        })
    });
    group.finish();
}

criterion_group!(benches, stages);
criterion_main!(benches);

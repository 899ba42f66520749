//! The twin engine against the sim: sim-mpc (the lab's control stack on the kinematic model)
//! follows the sim closely, and the grey-box twin with noise and delay off follows sim-mpc.
//! Every fidelity plans from the states the vehicles report (measured position, yaw, speed and
//! σ = σ_max · servo command, 60 ms old) with the lab's MPC solver; the exact QP is checked on
//! straight driving here and through the CPM Lab intersection's turns in `twin_turns.rs`.

use std::path::PathBuf;

use cpmx_engine::{Experiment, simulate};
use cpmx_spec::{DataPath, SpecSource};

const SPEC: &str = "\
cpmx: 1
name: twin-agreement
map: stdlib:intersection
timing: {dt: 0.1, steps: 60}
agents: 2
policies:
  - {name: baseline, builtin: lane-follow}
initial_configurations:
  - name: following
    agents:
      - {ref_path: 7, arc_length: 0.8}
      - {ref_path: 7, arc_length: 0.2}
  - name: turning
    agents:
      - {ref_path: 2, arc_length: 0.3}
      - {ref_path: 9, arc_length: 0.3}
repetitions: 1
seed: 5
fidelities:
  sim: {control: direct, dynamics: kinematic}
  sim-mpc: {control: trajectory, dynamics: kinematic}
  twin-ideal: {control: trajectory, dynamics: stdlib:mu-car-greybox}
  twin-ideal-qp: {control: trajectory, dynamics: stdlib:mu-car-greybox, follower: {solver: qp}}
planner: {control_horizon: 4, prediction_horizon: 12}
";

fn experiment() -> (Experiment, Vec<cpmx_spec::RunPlan>) {
    let source = SpecSource {
        name: "twin.yaml".into(),
        dir: PathBuf::from("."),
        text: SPEC.into(),
    };
    let checked = cpmx_spec::check(
        &source,
        &DataPath::new(&source.dir, &[], None),
        &cpmx_engine::BuildChecks,
    )
    .unwrap_or_else(|d| panic!("{}", cpmx_spec::render(&d, false)));
    (Experiment::prepare(&checked).unwrap(), checked.plan())
}

/// Largest distance between the same agent at the same sample in two runs [m].
fn largest_gap_m(a: &cpmx_recording::Recording, b: &cpmx_recording::Recording) -> f64 {
    a.samples
        .iter()
        .zip(&b.samples)
        .flat_map(|(ra, rb)| {
            ra.iter()
                .zip(rb)
                .map(|(p, q)| (p.x_m - q.x_m).hypot(p.y_m - q.y_m))
        })
        .fold(0.0, f64::max)
}

fn run(
    experiment: &Experiment,
    plans: &[cpmx_spec::RunPlan],
    fidelity: &str,
    configuration: &str,
) -> cpmx_recording::Recording {
    let plan = plans
        .iter()
        .find(|p| p.fidelity == fidelity && p.initial_configuration == configuration)
        .unwrap();
    simulate(experiment, plan).unwrap().0
}

#[test]
fn sim_mpc_follows_the_sim() {
    let (experiment, plans) = experiment();
    for configuration in ["following", "turning"] {
        let sim = run(&experiment, &plans, "sim", configuration);
        let mpc = run(&experiment, &plans, "sim-mpc", configuration);
        let gap = largest_gap_m(&sim, &mpc);
        eprintln!("{configuration}: sim vs sim-mpc {gap:.4} m");
        assert!(gap < 0.05, "{configuration}: sim-mpc strays {gap} m from the sim");
    }
}

#[test]
fn the_twin_without_noise_and_delay_follows_sim_mpc() {
    let (experiment, plans) = experiment();

    // Driving behind each other: the same trajectory within 10 cm.
    let mpc = run(&experiment, &plans, "sim-mpc", "following");
    let twin = run(&experiment, &plans, "twin-ideal", "following");
    let gap = largest_gap_m(&mpc, &twin);
    eprintln!("following: sim-mpc vs twin-ideal {gap:.4} m");
    assert!(gap < 0.05, "the grey-box twin strays {gap} m from sim-mpc");
    let qp = run(&experiment, &plans, "twin-ideal-qp", "following");
    let gap = largest_gap_m(&twin, &qp);
    eprintln!("following: twin-ideal vs twin-ideal-qp {gap:.4} m");
    assert!(gap < 0.05, "the QP follower strays {gap} m from the lab's solver");

    // Turning through the intersection (the cars yield to each other, so their timing may
    // differ): the same lane keeping and no collisions.
    for configuration in ["following", "turning"] {
        let metrics = |fidelity| {
            let plan = plans
                .iter()
                .find(|p| p.fidelity == fidelity && p.initial_configuration == configuration)
                .unwrap();
            simulate(&experiment, plan).unwrap().1
        };
        let (mpc, twin) = (metrics("sim-mpc"), metrics("twin-ideal"));
        eprintln!(
            "{configuration}: CD sim-mpc {:.4} m, twin-ideal {:.4} m",
            mpc.cd_m, twin.cd_m
        );
        assert!(
            (twin.cd_m - mpc.cd_m).abs() < 0.01,
            "{configuration}: CD {} vs {}",
            twin.cd_m,
            mpc.cd_m
        );
        assert_eq!((mpc.a2a_events, twin.a2a_events), (0, 0), "{configuration}");
    }
}

//! The `communication` and `perception` layers end to end: ideal layers give the same runs as
//! none, bit for bit (sim, twin, the training environment); a link that loses every message and
//! a perception layer change the runs; a sweep's points are runs of their own with a row each
//! and sensitivity curves in the report.

mod support;

use support::{cpmx, ok, scratch};

const SPEC: &str = "cpmx: 1
name: neighbours
map: stdlib:intersection
timing: {dt: 0.1, steps: 60}
agents: 4
policies:
  - {name: network, mlp: {weights: WEIGHTS}, observation: stdlib:sigmarl, action: mean}
initial_configurations:
  - name: crossing
    agents:
      - {ref_path: 1, arc_length: 0.3}
      - {ref_path: 4, arc_length: 0.2}
      - {ref_path: 7, arc_length: 0.3}
      - {ref_path: 11, arc_length: 0.2}
repetitions: 1
seed: 11
fidelities:
  sim: {control: direct, dynamics: kinematic}
  sim-ideal: {control: direct, dynamics: kinematic, communication: {}, perception: {}}
  sim-deaf: {control: direct, dynamics: kinematic, communication: {drop_probability: 1}}
  sim-late: {control: direct, dynamics: kinematic, communication: {latency_ms: 300, rate_hz: 5, max_age_ms: 1000}}
  sim-eyes: {control: direct, dynamics: kinematic, perception: {range_m: 1.0, field_of_view_deg: 120, noise_position_m: 0.01, noise_yaw_rad: 0.02, detection_probability: 0.9}}
  mpc:
    control: trajectory
    dynamics: kinematic
  mpc-ideal:
    control: trajectory
    dynamics: kinematic
    communication: {latency_ms: 0, drop_probability: 0}
  mpc-deaf:
    control: trajectory
    dynamics: kinematic
    communication: {drop_probability: 1}
planner: {control_horizon: 4, prediction_horizon: 12}
on_collision: continue
metrics: stdlib:at25
report: {group_by: [fidelity, policy]}
";

/// Writes the spec with SigmaRL's reference actor (a network that reacts to its neighbours).
fn spec_in(dir: &std::path::Path, text: &str) -> std::path::PathBuf {
    let weights = support::reference().join("policy/actor.safetensors");
    let path = dir.join("neighbours.yaml");
    std::fs::write(&path, text.replace("WEIGHTS", weights.to_str().unwrap())).unwrap();
    path
}

fn trajectory(out: &std::path::Path, fidelity: &str) -> Vec<u8> {
    std::fs::read(out.join(format!("runs/{fidelity}/network/crossing/rep1/trajectory.csv"))).unwrap()
}

#[test]
fn ideal_layers_change_nothing_and_real_ones_do() {
    let dir = scratch("neighbours");
    let spec = spec_in(&dir, SPEC);
    let out = dir.join("out");
    ok(&cpmx(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        trajectory(&out, "sim") == trajectory(&out, "sim-ideal"),
        "an ideal layer changed sim"
    );
    assert!(
        trajectory(&out, "mpc") == trajectory(&out, "mpc-ideal"),
        "an ideal layer changed sim-mpc"
    );
    for changed in ["sim-deaf", "sim-late", "sim-eyes"] {
        assert!(
            trajectory(&out, "sim") != trajectory(&out, changed),
            "{changed} drove as sim"
        );
    }
    assert!(
        trajectory(&out, "mpc") != trajectory(&out, "mpc-deaf"),
        "mpc-deaf drove as mpc"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_sweep_grid_gives_a_row_per_point_sensitivity_curves_and_a_folder_report_reads() {
    let dir = scratch("sweep");
    let text = SPEC.replace(
        "  sim-deaf: {control: direct, dynamics: kinematic, communication: {drop_probability: 1}}\n",
        "  sim-deaf: {control: direct, dynamics: kinematic, communication: {drop_probability: {sweep: [0, 0.5, 1]}, latency_ms: {sweep: [0, 200]}}}\n",
    );
    let spec = spec_in(&dir, &text);
    let plan = ok(&cpmx(&["plan", spec.to_str().unwrap(), "--format", "csv"]));
    for p in ["0", "0.5", "1"] {
        for l in ["0", "200"] {
            assert!(
                plan.contains(&format!(
                    "sim-deaf@drop_probability={p}+latency_ms={l}/network/crossing/rep1"
                )),
                "{plan}"
            );
        }
    }
    let out = dir.join("out");
    let table = ok(&cpmx(&[
        "run",
        spec.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--only",
        "fidelity=sim,sim-deaf",
    ]));
    for p in ["0", "0.5", "1"] {
        assert!(
            table.contains(&format!(
                "| sim-deaf@drop_probability={p}+latency_ms=200 | network |"
            )),
            "{table}"
        );
    }
    // Without losses and latency the link is ideal: that point is the sim run.
    assert!(trajectory(&out, "sim") == trajectory(&out, "sim-deaf@drop_probability=0+latency_ms=0"));
    for parameter in ["drop_probability", "latency_ms"] {
        assert!(
            out.join(format!("plots/sensitivity-sim-deaf-{parameter}-cra_a.svg"))
                .is_file(),
            "{parameter}"
        );
    }
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(page.contains("id=\"sensitivity\""));
    // The folder is a database a later `cpmx report` reads back to the same summary.
    let summary = std::fs::read(out.join("summary.md")).unwrap();
    ok(&cpmx(&["report", out.to_str().unwrap()]));
    assert_eq!(std::fs::read(out.join("summary.md")).unwrap(), summary);
    std::fs::remove_dir_all(&dir).ok();
}

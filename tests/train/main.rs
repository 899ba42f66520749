//! `cpmx train` end to end: a small scenario learns, the weights do not depend on the thread
//! count, a run killed with SIGKILL resumes to the weights of an uninterrupted one, and bad
//! input (a run that exists, a changed spec, a damaged checkpoint, an unknown seed, paths the
//! map lacks) gets a diagnostic and leaves every trained file as it was.

#[path = "../support/mod.rs"]
mod support;

mod kept;
mod safety;
mod stacked;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use support::{files, ok, reference, scratch, unwrapped};

/// A small training spec: SigmaRL's intersection scenario, reward and MAPPO with fewer and
/// smaller pieces (`{iterations}`, `{extra}` replaced).
const SMALL: &str = "cpmx: 1
name: small
map: {file: maps/cpm.xml}
timing: {dt: 0.1, steps: 40}
agents: 2
policies:
  - {name: trained, mlp: {trained: {seed: 7, dir: DIR}}}
initial_configurations:
  - name: crossing
    agents:
      - {ref_path: 6, arc_length: 0.3}
      - {ref_path: 2, arc_length: 0.3}
repetitions: 1
seed: 1
fidelities:
  sim: {control: direct, dynamics: kinematic}
training:
  scenario: {extends: stdlib:sigmarl-intersection, envs: 8, agents: 2, episode_steps: 64}
  reward: stdlib:sigmarl-reward
  algorithm:
    extends: stdlib:mappo-sigmarl
    mappo: {frames_per_iteration: 256, minibatch: 64, epochs: 4, lr: 1.0e-3, lr_min: 1.0e-4}
  network: {hidden: [32, 32], activation: tanh}
  observation: stdlib:sigmarl
  iterations: ITERATIONS
  seeds: [7, 8]
";

/// The text of `spec` with `from` replaced by `to`; fails when `from` is not in it (an edit that
/// changes nothing would test the spec as it was).
fn edited(spec: &Path, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(spec).unwrap();
    assert!(text.contains(from), "{} has no `{from}`", spec.display());
    text.replace(from, to)
}

/// Writes the small spec into `dir` (training into `dir/out`) and returns its path.
fn small_spec(dir: &Path, iterations: u32) -> PathBuf {
    let out = dir.join("out");
    let text = SMALL
        .replace("ITERATIONS", &iterations.to_string())
        .replace("DIR", out.to_str().unwrap());
    let path = dir.join("small.yaml");
    std::fs::write(&path, text).unwrap();
    path
}

/// `cpmx train SPEC --out DIR/out ARGS` with the reference data.
fn train(dir: &Path, spec: &Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("train")
        .arg(spec)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--data")
        .arg(reference())
        .args(args)
        .env_remove("CPMX_DATA")
        .output()
        .expect("cpmx runs")
}

/// `cpmx train SPEC --out DIR/out --only seed=SEED --jobs 1` started in the background, once
/// it has checkpointed `iterations` of the seed (or two minutes passed): the trainer, still
/// running unless it finished.
fn training_in_background(dir: &Path, spec: &Path, seed: u64, iterations: u64) -> std::process::Child {
    let child = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("train")
        .arg(spec)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--data")
        .arg(reference())
        .args(["--only", &format!("seed={seed}"), "--jobs", "1"])
        .env_remove("CPMX_DATA")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let run_json = dir.join("out").join(seed.to_string()).join("run.json");
    let deadline = Instant::now() + Duration::from_secs(120);
    while Instant::now() < deadline
        && std::fs::read_to_string(&run_json)
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|v| v["iterations_done"].as_u64())
            .unwrap_or(0)
            < iterations
    {
        std::thread::sleep(Duration::from_millis(2));
    }
    child
}

/// The files of a training folder without the wall-time columns of the learning curve and
/// the files that name the inputs and the build.
fn weights_and_curves(out: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    files(out)
        .into_iter()
        .map(|(path, bytes)| {
            if path.extension().is_some_and(|e| e == "csv") {
                let text = String::from_utf8(bytes).unwrap();
                let header: Vec<&str> = text.lines().next().unwrap_or_default().split(',').collect();
                let wall = |i: &usize| matches!(header.get(*i), Some(&"collect_s") | Some(&"update_s"));
                let trimmed: Vec<String> = text
                    .lines()
                    .map(|l| {
                        let cells: Vec<&str> = l.split(',').collect();
                        (0..cells.len())
                            .filter(|i| !wall(i))
                            .map(|i| cells[i])
                            .collect::<Vec<_>>()
                            .join(",")
                    })
                    .collect();
                (path, trimmed.join("\n").into_bytes())
            } else {
                (path, bytes)
            }
        })
        // run.json names the build, spec.yaml is the input (its `--out` differs), `.lock` is the
        // folder's lock (empty).
        .filter(|(path, _)| {
            let name = path.to_string_lossy();
            !name.ends_with(".json") && !name.ends_with("spec.yaml") && !name.ends_with(".lock")
        })
        .collect()
}

/// `column` of every row of a learning curve.
fn column(out: &Path, seed: u64, column: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(out.join(seed.to_string()).join("learning_curve.csv")).unwrap();
    let mut lines = text.lines();
    let index = lines
        .next()
        .unwrap()
        .split(',')
        .position(|c| c == column)
        .expect("column");
    lines
        .map(|l| l.split(',').nth(index).unwrap().parse().unwrap_or(f64::NAN))
        .collect()
}

#[test]
fn a_small_scenario_learns_and_the_trained_actor_runs() {
    let dir = scratch("train-learns");
    let spec = small_spec(&dir, 24);
    let table = ok(&train(&dir, &spec, &["--only", "seed=7"]));
    assert!(table.contains("| seed 7 | 24 |"), "{table}");
    let out = dir.join("out");
    for file in [
        "actor.safetensors",
        "actor.last.safetensors",
        "critic.safetensors",
        "checkpoint.safetensors",
        "learning_curve.csv",
        "learning_curve.svg",
        "run.json",
    ] {
        assert!(out.join("7").join(file).is_file(), "{file}");
    }
    assert!(!out.join("8").exists(), "--only seed=7 trains seed 7 alone");
    // The mean reward per agent-step rises: the agents learn to make progress.
    let reward = column(&out, 7, "reward_total");
    let mean = |r: &[f64]| r.iter().sum::<f64>() / r.len() as f64;
    let (first, last) = (mean(&reward[..4]), mean(&reward[reward.len() - 4..]));
    assert!(last > first + 0.01, "reward per step {first:.4} -> {last:.4}");
    // The trained actor is an ordinary `mlp` policy of the same spec.
    let run_out = dir.join("run");
    ok(&Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["run", spec.to_str().unwrap(), "--out", run_out.to_str().unwrap()])
        .arg("--data")
        .arg(reference())
        .env_remove("CPMX_DATA")
        .output()
        .unwrap());
    let per_run = std::fs::read_to_string(run_out.join("per_run.csv")).unwrap();
    assert!(per_run.contains("sim/trained/crossing/rep1"), "{per_run}");
    // The run folder keeps the policy's learning curve, and its report draws it.
    let kept = std::fs::read_to_string(run_out.join("training/trained/learning_curve.csv")).unwrap();
    let trained = std::fs::read_to_string(dir.join("out/7/learning_curve.csv")).unwrap();
    assert_eq!(kept, trained);
    let page = std::fs::read_to_string(run_out.join("report.html")).unwrap();
    assert!(
        page.contains("\"learning_curves\":[{"),
        "the page's data names the curve"
    );

    // The actor is the one this spec's training section trained: no warning. Once the section
    // changes (or the folder loses its run.json), validate says so at the policy's `trained`.
    let validate = |spec: &Path| {
        Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .args(["validate", spec.to_str().unwrap(), "--data"])
            .arg(reference())
            .env_remove("CPMX_DATA")
            .output()
            .unwrap()
    };
    let same = validate(&spec);
    assert!(same.status.success());
    assert!(
        !String::from_utf8_lossy(&same.stderr).contains("trained-elsewhere"),
        "{}",
        String::from_utf8_lossy(&same.stderr)
    );
    let changed = dir.join("changed.yaml");
    std::fs::write(&changed, edited(&spec, "lr: 1.0e-3", "lr: 2.0e-3")).unwrap();
    let out = validate(&changed);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "a warning, not an error: {stderr}");
    assert!(stderr.contains("cpmx::check::trained-elsewhere"), "{stderr}");
    assert!(
        stderr.contains("changed.yaml:7:"),
        "at the policy's line: {stderr}"
    );
    assert!(stderr.contains("trained with other inputs"), "{stderr}");
    std::fs::remove_file(dir.join("out/7/run.json")).unwrap();
    let stderr = String::from_utf8_lossy(&validate(&spec).stderr).into_owned();
    assert!(stderr.contains("no run.json beside the actor"), "{stderr}");
}

/// `stdlib:sigmarl-shaped-reward` adds the paper's speed and centre-line terms: the learning curve
/// gets their columns after SigmaRL's five, and the agents learn to drive faster along their
/// paths.
#[test]
fn the_shaped_reward_logs_its_terms_and_the_agents_speed_up() {
    let dir = scratch("train-shaped");
    let spec = small_spec(&dir, 24);
    let text = edited(
        &spec,
        "reward: stdlib:sigmarl-reward\n",
        "reward: stdlib:sigmarl-shaped-reward\n",
    );
    std::fs::write(&spec, text).unwrap();
    ok(&train(&dir, &spec, &["--only", "seed=7"]));
    let out = dir.join("out");
    let header = std::fs::read_to_string(out.join("7/learning_curve.csv")).unwrap();
    assert!(
        header.starts_with(
            "iteration,samples,episode_reward_mean,episodes,reward_progress,reward_near_boundary,\
             reward_near_agents_ttc,reward_collide_agents,reward_collide_boundary,reward_speed,\
             reward_centre_line,reward_total,"
        ),
        "{}",
        header.lines().next().unwrap()
    );
    let speed = column(&out, 7, "reward_speed");
    let centre = column(&out, 7, "reward_centre_line");
    assert!(centre.iter().all(|&c| c < 0.0), "{centre:?}");
    let mean = |r: &[f64]| r.iter().sum::<f64>() / r.len() as f64;
    let (first, last) = (mean(&speed[..4]), mean(&speed[speed.len() - 4..]));
    assert!(last > first + 0.01, "speed term per step {first:.4} -> {last:.4}");
}

#[test]
fn one_and_two_threads_give_identical_actors() {
    let (one, two) = (scratch("train-jobs1"), scratch("train-jobs2"));
    for (dir, jobs) in [(&one, "1"), (&two, "2")] {
        let spec = small_spec(dir, 2);
        ok(&train(dir, &spec, &["--jobs", jobs]));
    }
    let (a, b) = (
        weights_and_curves(&one.join("out")),
        weights_and_curves(&two.join("out")),
    );
    assert_eq!(
        a.len(),
        13,
        "two seeds of six compared files and the overview chart"
    );
    assert_same_files(&a, &b);
}

/// Trains the spec `text` (its `OUT` the training folder) with one thread and with two, in
/// scratch folders `<name>-1` and `<name>-2`; asserts both trained the same files and returns
/// the first folder and `cpmx train`'s table.
fn train_with_one_and_two_threads(name: &str, text: &str) -> (PathBuf, String) {
    let mut trained = Vec::new();
    for jobs in ["1", "2"] {
        let dir = scratch(&format!("{name}-{jobs}"));
        let out = dir.join("out");
        let spec = dir.join(format!("{name}.yaml"));
        std::fs::write(&spec, text.replace("OUT", out.to_str().unwrap())).unwrap();
        let table = ok(&train(&dir, &spec, &["--jobs", jobs]));
        trained.push((dir, table, weights_and_curves(&out)));
    }
    assert_same_files(&trained[0].2, &trained[1].2);
    let (dir, table, _) = trained.swap_remove(0);
    (dir, table)
}

/// `cpmx run` of the spec `name` in `dir` (written by [`train_with_one_and_two_threads`], whose
/// actors it names) into `dir/run`; its `per_run.csv`.
fn run_trained_spec(dir: &Path, name: &str) -> String {
    let run_out = dir.join("run");
    ok(&Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args([
            "run",
            dir.join(name).to_str().unwrap(),
            "--out",
            run_out.to_str().unwrap(),
        ])
        .arg("--data")
        .arg(reference())
        .env_remove("CPMX_DATA")
        .output()
        .unwrap());
    std::fs::read_to_string(run_out.join("per_run.csv")).unwrap()
}

/// Two folders' files are equal; names the ones that are not (their bytes are long).
fn assert_same_files(a: &[(PathBuf, Vec<u8>)], b: &[(PathBuf, Vec<u8>)]) {
    let names = |f: &[(PathBuf, Vec<u8>)]| f.iter().map(|(p, _)| p.clone()).collect::<Vec<_>>();
    assert_eq!(names(a), names(b));
    let differing: Vec<String> = a
        .iter()
        .zip(b)
        .filter(|(x, y)| x.1 != y.1)
        .map(|(x, _)| x.0.display().to_string())
        .collect();
    assert!(differing.is_empty(), "these files differ: {differing:?}");
}

#[test]
fn a_killed_run_resumes_to_the_weights_of_an_uninterrupted_one() {
    let (whole, killed) = (scratch("train-whole"), scratch("train-killed"));
    let iterations = 12;
    ok(&train(
        &whole,
        &small_spec(&whole, iterations),
        &["--only", "seed=7"],
    ));

    let spec = small_spec(&killed, iterations);
    // SIGKILL once a few iterations are checkpointed, wherever the run is then.
    let mut child = training_in_background(&killed, &spec, 7, 3);
    child.kill().unwrap();
    let status = child.wait().unwrap();
    // Without --resume the folder is refused as it is.
    let before = files(&killed.join("out"));
    let refused = train(&killed, &spec, &["--only", "seed=7"]);
    assert_eq!(refused.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&refused.stderr).contains("--resume"));
    assert_eq!(files(&killed.join("out")), before);

    let resumed = train(&killed, &spec, &["--only", "seed=7", "--resume"]);
    let stderr = String::from_utf8_lossy(&resumed.stderr).into_owned();
    ok(&resumed);
    if status.success() {
        eprintln!("note: the run finished before it was killed; resumed a finished run");
        assert!(stderr.contains("already trained"), "{stderr}");
    } else {
        assert!(stderr.contains("resuming after iteration"), "{stderr}");
    }
    assert_same_files(
        &weights_and_curves(&whole.join("out/7")),
        &weights_and_curves(&killed.join("out/7")),
    );
}

/// A second `cpmx train` on a seed folder that another one is writing (a `--resume` typed while
/// the first still finishes its iteration) is refused: two writers would mix their iterations
/// in the learning curve.
#[test]
fn a_seed_folder_being_trained_is_refused_to_a_second_trainer() {
    let dir = scratch("train-busy");
    // More iterations than the test lasts: the first is still training when the second comes.
    let spec = small_spec(&dir, 100_000);
    // Once the first has checkpointed an iteration, it holds the folder.
    let mut first = training_in_background(&dir, &spec, 7, 1);
    assert!(first.try_wait().unwrap().is_none(), "the first trainer stopped");
    let mut second = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("train")
        .arg(&spec)
        .arg("--out")
        .arg(dir.join("out"))
        .arg("--data")
        .arg(reference())
        .args(["--only", "seed=7", "--resume"])
        .env_remove("CPMX_DATA")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // A refusal comes before any training; a second writer would still be training.
    let deadline = Instant::now() + Duration::from_secs(60);
    while second.try_wait().unwrap().is_none() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    let refused = second.try_wait().unwrap().is_some();
    for child in [&mut first, &mut second] {
        let _ = child.kill();
    }
    first.wait().unwrap();
    let second = second.wait_with_output().unwrap();
    assert!(refused, "a second trainer on the seed was not refused");
    assert_eq!(second.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&second.stderr);
    assert!(stderr.contains("being trained by another"), "{stderr}");
    // Once the first is gone its lock is too: the folder is refused only for what it holds (a
    // run to continue with `--resume`).
    let after = train(&dir, &spec, &["--only", "seed=7"]);
    assert_eq!(after.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&after.stderr);
    assert!(stderr.contains("already holds seed 7"), "{stderr}");
}

#[test]
fn bad_input_is_refused_and_nothing_trained_is_lost() {
    let dir = scratch("train-bad");
    let spec = small_spec(&dir, 2);
    ok(&train(&dir, &spec, &["--only", "seed=8"]));
    let trained = files(&dir.join("out"));

    // An unknown seed: a usage error naming the spec's seeds.
    let out = train(&dir, &spec, &["--only", "seed=9"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the spec's seeds: 7, 8"));
    // So are an unknown fidelity and an axis `cpmx train` does not select by.
    let out = train(&dir, &spec, &["--only", "fidelity=twin"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("the spec's fidelities: sim"));
    let out = train(&dir, &spec, &["--only", "policy=trained"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("by `seed` or `fidelity`"));

    // A changed spec does not continue the folder's run.
    let changed = dir.join("changed.yaml");
    std::fs::write(&changed, edited(&spec, "lr: 1.0e-3", "lr: 2.0e-3")).unwrap();
    let out = train(&dir, &changed, &["--only", "seed=8", "--resume"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("different training section"));

    // A truncated checkpoint: a diagnostic, exit 1, the folder as it was.
    let checkpoint = dir.join("out/8/checkpoint.safetensors");
    let bytes = std::fs::read(&checkpoint).unwrap();
    std::fs::write(&checkpoint, &bytes[..bytes.len() / 2]).unwrap();
    let damaged = files(&dir.join("out"));
    let out = train(&dir, &spec, &["--only", "seed=8", "--resume"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("checkpoint"));
    assert_eq!(files(&dir.join("out")), damaged);
    std::fs::write(&checkpoint, &bytes).unwrap();
    assert_eq!(files(&dir.join("out")), trained);

    // Reference paths the map lacks: a diagnostic before anything is written.
    let text = edited(
        &spec,
        "{extends: stdlib:sigmarl-intersection, envs: 8, agents: 2, episode_steps: 64}",
        "{ref_paths: [1, 400], envs: 8, agents: 2, episode_steps: 64, \
             start: {first_index: 3, speed_mps: [0, 1], min_gap_m: 0.37}, \
             reset: {on_collision: environment, on_entry_or_exit_line: agent}}",
    );
    let lacking = dir.join("lacking.yaml");
    std::fs::write(&lacking, text).unwrap();
    let elsewhere = scratch("train-bad-paths");
    let out = train(&elsewhere, &lacking, &[]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("400"), "{stderr}");
    assert!(!elsewhere.join("out").exists());
}

#[test]
fn a_spec_that_only_trains_trains_and_has_nothing_to_run() {
    let dir = scratch("train-only");
    let spec = dir.join("only.yaml");
    std::fs::write(
        &spec,
        "cpmx: 1\nname: only\nmap: {file: maps/cpm.xml}\ntraining:\n  \
         scenario: {extends: stdlib:sigmarl-intersection, envs: 4, agents: 2}\n  reward: stdlib:sigmarl-reward\n  \
         algorithm: {extends: stdlib:mappo-sigmarl, mappo: {frames_per_iteration: 64, minibatch: 32, epochs: 1}}\n  \
         network: {hidden: [16], activation: tanh}\n  iterations: 1\n  seeds: [3]\n",
    )
    .unwrap();
    let table = ok(&train(&dir, &spec, &[]));
    assert!(table.contains("| seed 3 | 1 |"), "{table}");
    let run = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .arg("run")
        .arg(&spec)
        .arg("--out")
        .arg(dir.join("runs"))
        .arg("--data")
        .arg(reference())
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&run.stderr).contains("only trains"));
    assert!(!dir.join("runs").exists());
}

#[test]
fn a_policy_not_trained_yet_refuses_its_runs_and_lets_the_others_run() {
    let dir = scratch("train-not-yet");
    let spec = small_spec(&dir, 2);
    let text = edited(
        &spec,
        "policies:\n",
        "policies:\n  - {name: baseline, builtin: lane-follow}\n",
    );
    std::fs::write(&spec, text).unwrap();
    let run = |only: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_cpmx"))
            .args([
                "run",
                spec.to_str().unwrap(),
                "--out",
                dir.join("run").to_str().unwrap(),
            ])
            .args(only)
            .arg("--data")
            .arg(reference())
            .env_remove("CPMX_DATA")
            .output()
            .expect("cpmx runs")
    };
    let refused = run(&[]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("policy `trained` names the actor trained with seed 7, which was not found"),
        "{stderr}"
    );
    assert!(stderr.contains("--only policy="), "{stderr}");
    assert!(!dir.join("run").exists(), "nothing is written for a refused run");
    let table = ok(&run(&["--only", "policy=baseline"]));
    assert!(table.contains("baseline"), "{table}");
}

#[test]
fn a_training_starts_from_the_actor_it_names() {
    // A curriculum: seed 7 trained one iteration, then continued by a training that starts from
    // its actor. The file's content is part of the fingerprint; a missing one is located.
    let (first, second) = (scratch("train-initial-first"), scratch("train-initial-second"));
    let spec = small_spec(&first, 1);
    ok(&train(&first, &spec, &["--only", "seed=7"]));
    let actor = first.join("out/7/actor.last.safetensors");
    assert!(actor.is_file());
    let continued = small_spec(&second, 1);
    let text = edited(
        &continued,
        "  iterations: 1\n",
        &format!("  initial_actor: {}\n  iterations: 1\n", actor.display()),
    );
    std::fs::write(&continued, text).unwrap();
    ok(&train(&second, &continued, &["--only", "seed=7"]));
    let fingerprint = |dir: &Path| -> String {
        let run: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("out/7/run.json")).unwrap()).unwrap();
        run["fingerprint"].as_str().unwrap().to_owned()
    };
    assert_ne!(
        fingerprint(&first),
        fingerprint(&second),
        "the start is part of the fingerprint"
    );
    let missing = edited(
        &continued,
        &actor.display().to_string(),
        "no-such-actor.safetensors",
    );
    std::fs::write(&continued, missing).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["validate", continued.to_str().unwrap(), "--data"])
        .arg(reference())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("initial actor `no-such-actor.safetensors` was not found"),
        "{stderr}"
    );
    let out = train(&second, &continued, &["--only", "seed=8"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("`initial_actor: no-such-actor.safetensors`: not found"),
        "{stderr}"
    );
}

#[test]
fn each_seed_starts_from_its_own_actor_with_the_seed_in_the_path() {
    // `{seed}` in `initial_actor`: seeds 7 and 8 continue the actors that seeds 7 and 8 of a
    // first training made. Each seed's fingerprint is the one a spec naming its file gets.
    let (first, second, single) = (
        scratch("train-per-seed-first"),
        scratch("train-per-seed-second"),
        scratch("train-per-seed-single"),
    );
    ok(&train(&first, &small_spec(&first, 1), &[]));
    let template = first.join("out/{seed}/actor.last.safetensors");
    let continued = small_spec(&second, 1);
    let text = edited(
        &continued,
        "  iterations: 1\n",
        &format!("  initial_actor: {}\n  iterations: 1\n", template.display()),
    );
    std::fs::write(&continued, text).unwrap();
    ok(&train(&second, &continued, &[]));
    let fingerprint = |dir: &Path, seed: u64| -> String {
        let run = std::fs::read_to_string(dir.join(format!("out/{seed}/run.json"))).unwrap();
        let run: serde_json::Value = serde_json::from_str(&run).unwrap();
        run["fingerprint"].as_str().unwrap().to_owned()
    };
    assert_ne!(
        fingerprint(&second, 7),
        fingerprint(&second, 8),
        "two starts, two fingerprints"
    );
    let named = small_spec(&single, 1);
    let eight = first.join("out/8/actor.last.safetensors");
    let text = edited(
        &named,
        "  iterations: 1\n",
        &format!("  initial_actor: {}\n  iterations: 1\n", eight.display()),
    );
    std::fs::write(&named, text).unwrap();
    ok(&train(&single, &named, &["--only", "seed=8"]));
    assert_eq!(fingerprint(&single, 8), fingerprint(&second, 8));
    // A seed whose file is missing is named with its own path.
    std::fs::remove_file(first.join("out/8/actor.last.safetensors")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["validate", continued.to_str().unwrap(), "--data"])
        .arg(reference())
        .output()
        .unwrap();
    let stderr = unwrapped(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("/out/8/actor.last.safetensors` was not found"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("/out/7/actor.last.safetensors` was not found"),
        "{stderr}"
    );
}

#[test]
fn a_shard_past_the_last_training_run_says_it_has_nothing_to_do() {
    // An array job of more tasks than seeds: the extra task says so and writes nothing.
    let dir = scratch("train-empty-shard");
    let spec = small_spec(&dir, 1);
    let out = train(&dir, &spec, &["--shard", "4/4"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("shard 4/4 holds none of the 2 training runs: nothing to train here"),
        "{stderr}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).is_empty(), "no empty table");
}

#[test]
fn shards_of_a_swept_training_merge_into_the_unsharded_folder_byte_for_byte() {
    let (whole, sharded) = (scratch("train-unsharded"), scratch("train-sharded"));
    for dir in [&whole, &sharded] {
        let spec = small_spec(dir, 2);
        let text = edited(&spec, "lr: 1.0e-3", "lr: {sweep: [1.0e-3, 3.0e-4]}");
        std::fs::write(&spec, text).unwrap();
    }
    ok(&train(&whole, &whole.join("small.yaml"), &[]));
    for shard in ["1/3", "2/3", "3/3"] {
        ok(&train(&sharded, &sharded.join("small.yaml"), &["--shard", shard]));
    }
    let (a, b) = (
        weights_and_curves(&whole.join("out")),
        weights_and_curves(&sharded.join("out")),
    );
    let actors = a.iter().filter(|(p, _)| p.ends_with("actor.safetensors")).count();
    assert_eq!(
        actors,
        4,
        "two points x two seeds: {:?}",
        a.iter().map(|f| &f.0).collect::<Vec<_>>()
    );
    assert_same_files(&a, &b);
    // The run.json of each training run is the same too (same build, same inputs).
    for (path, _) in &a {
        if path.ends_with("actor.safetensors") {
            let run = path.with_file_name("run.json");
            assert_eq!(
                std::fs::read(whole.join("out").join(&run)).unwrap(),
                std::fs::read(sharded.join("out").join(&run)).unwrap(),
                "{}",
                run.display()
            );
        }
    }
}

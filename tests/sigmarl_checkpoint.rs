//! The paper's own actors as SigmaRL saved them (`mlp: {sigmarl}`), from the lab's measured
//! starts (`from_poses`): the paper's design runs straight from the reference data; a checkpoint
//! and its documented safetensors conversion are one actor to the bit; damaged, re-packed and
//! foreign `.pth` files and `data.json` settings cpmx cannot honour are refused with a located
//! diagnostic and exit 1.

mod support;

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use support::{cpmx, cpmx_in, ok, python, reference, root, scratch, unwrapped as flat};

/// A spec in `dir` running the paper's design with `policies` (YAML list items) from the lab's
/// poses, `runs` of them (`--only`), with `vehicle`.
fn spec(dir: &Path, name: &str, policies: &str, vehicle: &str) -> PathBuf {
    let text = format!(
        "cpmx: 1
name: {name}
map: {{file: maps/cpm.xml}}
vehicle: {vehicle}
timing: {{dt: 0.1, steps: 40}}
agents: 3
policies:
{policies}
initial_configurations:
  - from_poses: {{file: paper-at25/poses.csv, policies: {{paper: seed1}}}}
repetitions: 3
seed: 1
fidelities:
  sim: {{control: direct, dynamics: kinematic}}
metrics: {{extends: stdlib:at25, footprint: stdlib:mu-car}}
report: {{group_by: [fidelity]}}
"
    );
    let path = dir.join(format!("{name}.yaml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// `cpmx COMMAND SPEC --data REFERENCE` in `dir`: its exit code and its diagnostics with
/// miette's wrapping undone.
fn cpmx_spec(dir: &Path, command: &str, spec: &Path, reference: &Path) -> (Option<i32>, String) {
    let out = cpmx_in(
        dir,
        &[
            command,
            spec.to_str().unwrap(),
            "--data",
            reference.to_str().unwrap(),
        ],
    );
    (out.status.code(), flat(&out.stderr))
}

/// `cpmx export CHECKPOINT --format safetensors --out OUT`, which must succeed.
fn export_safetensors(checkpoint: &Path, out: &Path) {
    ok(&cpmx(&[
        "export",
        checkpoint.to_str().unwrap(),
        "--format",
        "safetensors",
        "--out",
        out.to_str().unwrap(),
    ]));
}

#[test]
fn the_papers_design_validates_from_the_data_path_with_every_measured_start() {
    let reference = reference();
    let out = cpmx(&[
        "validate",
        "experiments/at25.yaml",
        "--data",
        reference.to_str().unwrap(),
    ]);
    let text = ok(&out);
    assert!(text.contains("ok: experiments/at25.yaml: 81 runs"), "{text}");
    // The lab measured µCars: the starts whose µCar reaches past the lane are warned about
    // (vehicle 1 of every seed's init1, 3-13 mm; one other by less than 0.1 mm), though the
    // 0.16 m car the actors drive stands on the road.
    let stderr = flat(&out.stderr);
    assert!(
        stderr.contains(
            "vehicle 1 of `seed1/init1-1` (line 2 of paper-at25/poses.csv): the metrics' footprint (0.22 m × 0.107 m) reaches 8.3 mm beyond the road of path 3"
        ),
        "{stderr}"
    );
    assert!(stderr.contains("vehicle 1 of `seed3/init1-1` (line 20 of paper-at25/poses.csv): the metrics' footprint (0.22 m × 0.107 m) reaches 12.5 mm"), "{stderr}");
    assert!(stderr.contains("vehicle 3 of `seed1/init1-3` (line 4 of paper-at25/poses.csv): the metrics' footprint (0.22 m × 0.107 m) reaches less than 0.1 mm"), "{stderr}");
    assert_eq!(stderr.matches("cpmx::map::near-road").count(), 10, "{stderr}");
    let plan = ok(&cpmx(&[
        "plan",
        "experiments/at25.yaml",
        "--data",
        reference.to_str().unwrap(),
        "--format",
        "json",
    ]));
    let plan: serde_json::Value = serde_json::from_str(&plan).unwrap();
    let starts = plan["starts"].as_object().unwrap();
    // 27 measured starts: each policy's three configurations, three repetitions each.
    assert_eq!(starts.len(), 27, "{:?}", starts.keys().collect::<Vec<_>>());
    let first = &starts["init1/seed1/rep1"][0];
    assert_eq!(first["x_m"], 1.941467285);
    assert_eq!(first["ref_path"], 3);
    assert_eq!(starts["init1/seed1/rep2"][0]["y_m"], 3.266045094);
}

#[test]
fn a_measured_start_just_off_the_road_is_warned_about_with_its_distance_not_refused() {
    let reference = reference();
    let dir = scratch("poses-mu-car");
    let policies = "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}}";
    // The µCar is wider than the actors' car: one lab start reaches 8 mm past the lane.
    let path = spec(&dir, "poses", policies, "stdlib:mu-car");
    let (code, stderr) = cpmx_spec(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains(
            "vehicle 1 of `seed1/init1-1` (line 2 of paper-at25/poses.csv): its footprint reaches 8.3 mm beyond the road of path 3"
        ),
        "{stderr}"
    );
    // A tolerance below it refuses the start, saying by how much.
    let strict = std::fs::read_to_string(&path).unwrap().replace(
        "policies: {paper: seed1}}",
        "policies: {paper: seed1}, off_road_tolerance_m: 0.005}",
    );
    std::fs::write(&path, strict).unwrap();
    let (code, stderr) = cpmx_spec(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("its footprint reaches 8.3 mm beyond it, more than `off_road_tolerance_m: 0.005`"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_poses_file_without_a_runs_row_is_refused_naming_the_run() {
    let reference = reference();
    let dir = scratch("poses-missing");
    let rows: Vec<String> = std::fs::read_to_string(reference.join("paper-at25/poses.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.contains("seed1/init2-3"))
        .map(str::to_owned)
        .collect();
    std::fs::create_dir_all(dir.join("paper-at25")).unwrap();
    std::fs::write(dir.join("paper-at25/poses.csv"), rows.join("\n")).unwrap();
    let path = spec(
        &dir,
        "missing",
        "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}}",
        "stdlib:sigmarl-2025",
    );
    let (code, stderr) = cpmx_spec(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("has no row for `paper` (label `seed1`), `init2`, repetition 3"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The documented conversion (docs/policies.md, "SigmaRL's actor") as the docs give it, run
/// with the test venv's PyTorch on `checkpoint`, writing `out`.
fn documented_conversion(python: &Path, checkpoint: &Path, out: &Path) {
    let docs = std::fs::read_to_string(root().join("docs/policies.md")).unwrap();
    let section = &docs[docs.find("## SigmaRL's actor").expect("the section")..];
    let code = &section[section.find("```python\n").expect("a Python block") + 10..];
    let code = &code[..code.find("```").unwrap()];
    assert!(code.contains("\"reward0.05_policy.pth\"") && code.contains("\"actor.safetensors\""));
    let code = code
        .replace(
            "\"reward0.05_policy.pth\"",
            &format!("{:?}", checkpoint.display().to_string()),
        )
        .replace(
            "\"actor.safetensors\"",
            &format!("{:?}", out.display().to_string()),
        );
    let mut child = Command::new(python)
        .arg("-")
        .stdin(std::process::Stdio::piped())
        .spawn()
        .expect("python runs");
    child.stdin.take().unwrap().write_all(code.as_bytes()).unwrap();
    assert!(
        child.wait().unwrap().success(),
        "the documented conversion failed"
    );
}

#[test]
fn cpmx_export_gives_the_documented_conversions_bits() {
    let reference = reference();
    let Some(python) = python("cpmx_export_gives_the_documented_conversions_bits") else {
        return;
    };
    let dir = scratch("export-checkpoint");
    for seed in ["seed1", "seed2", "seed3"] {
        let checkpoint = reference.join(format!("paper-at25/{seed}"));
        let converted = dir.join(format!("{seed}-python.safetensors"));
        let pth = std::fs::read_dir(&checkpoint)
            .unwrap()
            .filter_map(Result::ok)
            .map(|e| e.path())
            .find(|p| p.to_string_lossy().ends_with("_policy.pth") && !p.ends_with("final_policy.pth"))
            .unwrap();
        documented_conversion(&python, &pth, &converted);
        let exported = dir.join(format!("{seed}-cpmx.safetensors"));
        export_safetensors(&checkpoint, &exported);
        assert_eq!(
            std::fs::read(&exported).unwrap(),
            std::fs::read(&converted).unwrap(),
            "{seed}: cpmx export differs from the documented conversion"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_checkpoint_and_its_conversion_drive_the_same_trajectories_bit_for_bit() {
    let reference = reference();
    let dir = scratch("checkpoint-bits");
    let converted = dir.join("seed1.safetensors");
    export_safetensors(&reference.join("paper-at25/seed1"), &converted);
    let checkpoint = spec(
        &dir,
        "checkpoint",
        "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}}",
        "stdlib:sigmarl-2025",
    );
    // The observation data.json describes, written out: SigmaRL's with 10 lengths of the
    // 0.16 m car as the position scale.
    let file = spec(
        &dir,
        "file",
        "  - name: paper
    mlp: {weights: seed1.safetensors}
    observation: {extends: stdlib:sigmarl, position_scale_m: 1.6}",
        "stdlib:sigmarl-2025",
    );
    for path in [&checkpoint, &file] {
        let (code, stderr) = cpmx_spec(&dir, "run", path, &reference);
        assert_eq!(code, Some(0), "{stderr}");
    }
    for configuration in ["init1", "init2", "init3"] {
        for rep in 1..=3 {
            let run = format!("runs/sim/paper/{configuration}/rep{rep}/trajectory.csv");
            let a = std::fs::read(dir.join("out/checkpoint").join(&run)).unwrap();
            let b = std::fs::read(dir.join("out/file").join(&run)).unwrap();
            assert!(
                a == b,
                "{run}: the checkpoint and its conversion drive differently"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A copy of seed 1's checkpoint folder in `dir` with its actor's bytes replaced by `actor`.
fn damaged_checkpoint(dir: &Path, reference: &Path, actor: &[u8]) -> PathBuf {
    let folder = dir.join("paper-at25/seed1");
    std::fs::create_dir_all(&folder).unwrap();
    for entry in std::fs::read_dir(reference.join("paper-at25/seed1")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_owned();
        if path.to_string_lossy().ends_with("_data.json") {
            std::fs::copy(&path, folder.join(&name)).unwrap();
        } else if path.to_string_lossy().ends_with("_policy.pth") && !path.ends_with("final_policy.pth") {
            std::fs::write(folder.join(&name), actor).unwrap();
        }
    }
    std::fs::copy(
        reference.join("paper-at25/poses.csv"),
        dir.join("paper-at25/poses.csv"),
    )
    .unwrap();
    folder
}

/// The archive of `pth` written again by the zip crate: its entries' `(name, bytes)` under
/// `rename`, compressed with `method`.
fn rezipped(pth: &[u8], rename: impl Fn(&str) -> String, method: zip::CompressionMethod) -> Vec<u8> {
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(pth)).unwrap();
    let mut out = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for i in 0..archive.len() {
        let mut entry = archive.by_index(i).unwrap();
        let name = rename(&entry.name().unwrap());
        let mut bytes = Vec::new();
        std::io::Read::read_to_end(&mut entry, &mut bytes).unwrap();
        let options = zip::write::SimpleFileOptions::default().compression_method(method);
        out.start_file(name, options).unwrap();
        out.write_all(&bytes).unwrap();
    }
    out.finish().unwrap().into_inner()
}

#[test]
fn damaged_repacked_and_foreign_checkpoints_are_refused_naming_the_file() {
    let reference = reference();
    let original = std::fs::read(reference.join("paper-at25/seed1/reward4.35_policy.pth")).unwrap();
    let safetensors = std::fs::read(reference.join("policy/actor.safetensors")).unwrap();
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        (
            "truncated",
            original[..original.len() / 2].to_vec(),
            "truncated or damaged file",
        ),
        (
            "cut-short",
            original[..original.len() - 10].to_vec(),
            "truncated or damaged file",
        ),
        (
            "deflated",
            rezipped(&original, str::to_owned, zip::CompressionMethod::Deflated),
            "is compressed (Deflated); torch.save stores every entry uncompressed",
        ),
        (
            "no-folder",
            rezipped(
                &original,
                |n| {
                    n.split_once('/')
                        .map_or(n.to_owned(), |(_, rest)| rest.to_owned())
                },
                zip::CompressionMethod::Stored,
            ),
            "is not inside a folder of the archive",
        ),
        (
            "text",
            b"not a checkpoint\n".to_vec(),
            "is not a PyTorch checkpoint",
        ),
        ("safetensors", safetensors, "is not a PyTorch checkpoint"),
        ("empty", Vec::new(), "is not a PyTorch checkpoint"),
    ];
    for (name, bytes, expected) in cases {
        let dir = scratch(&format!("pth-{name}"));
        damaged_checkpoint(&dir, &reference, &bytes);
        let path = spec(
            &dir,
            name,
            "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}}",
            "stdlib:sigmarl-2025",
        );
        for command in ["validate", "run"] {
            let (code, stderr) = cpmx_spec(&dir, command, &path, &reference);
            assert_eq!(code, Some(1), "{name}, {command}: {stderr}");
            assert!(
                stderr.contains("reward4.35_policy.pth") && stderr.contains(expected),
                "{name}, {command}: {stderr}"
            );
            assert!(!stderr.contains("panicked"), "{name}: {stderr}");
        }
        std::fs::remove_dir_all(&dir).ok();
    }
}

#[test]
fn data_json_settings_cpmx_cannot_honour_are_refused_by_name_and_value() {
    let reference = reference();
    let dir = scratch("data-json");
    let folder = damaged_checkpoint(
        &dir,
        &reference,
        &std::fs::read(reference.join("paper-at25/seed1/reward4.35_policy.pth")).unwrap(),
    );
    let data = folder.join("reward4.35_data.json");
    let text = std::fs::read_to_string(&data)
        .unwrap()
        .replace(
            "\"is_observe_distance_to_boundaries\": true",
            "\"is_observe_distance_to_boundaries\": false",
        )
        .replace("\"is_obs_noise\": false", "\"is_obs_noise\": true");
    std::fs::write(&data, text).unwrap();
    let path = spec(
        &dir,
        "settings",
        "  - {name: paper, mlp: {sigmarl: paper-at25/seed1}}",
        "stdlib:sigmarl-2025",
    );
    let (code, stderr) = cpmx_spec(&dir, "validate", &path, &reference);
    assert_eq!(code, Some(1), "{stderr}");
    for expected in [
        "policy `paper` was trained with `is_observe_distance_to_boundaries: false`: cpmx observes the distances",
        "policy `paper` was trained with `is_obs_noise: true`: cpmx adds SigmaRL 1.2.0's sensor noise",
        "settings.yaml:",
    ] {
        assert!(stderr.contains(expected), "{expected}\n{stderr}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

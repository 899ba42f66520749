//! `cpmx export`: a trained actor as ONNX that onnxruntime loads, with the actor's outputs.

mod support;

use std::process::Command;

use support::{cpmx, ok, python, reference, root, scratch};

#[test]
fn an_exported_actor_runs_in_onnxruntime_as_the_actor() {
    let Some(python) = python("an_exported_actor_runs_in_onnxruntime_as_the_actor") else {
        return;
    };
    let dir = scratch("export");
    let actor = reference().join("policy/actor.safetensors");
    let model = dir.join("actor.onnx");
    let printed = ok(&cpmx(&[
        "export",
        actor.to_str().unwrap(),
        "--format",
        "onnx",
        "--out",
        model.to_str().unwrap(),
    ]));
    assert!(
        printed.contains("[batch, 32]") && printed.contains("[batch, 4]"),
        "{printed}"
    );
    let check = Command::new(python)
        .arg(root().join("tests/python/onnxruntime_check.py"))
        .args([model.as_os_str(), actor.as_os_str()])
        .arg("tanh")
        .output()
        .expect("python runs");
    // In units of float32 rounding (see the script): a float32 evaluation of the same network
    // is within a few, a wrong network thousands away.
    let roundings: f64 = ok(&check).trim().parse().expect("a number");
    assert!(
        roundings < 32.0,
        "onnxruntime differs from the actor by {roundings} float32 roundings"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_training_folder_exports_beside_its_actor() {
    let dir = scratch("export-folder");
    let seed = dir.join("1");
    std::fs::create_dir_all(&seed).unwrap();
    std::fs::copy(
        reference().join("policy/actor.safetensors"),
        seed.join("actor.safetensors"),
    )
    .unwrap();
    ok(&cpmx(&["export", seed.to_str().unwrap(), "--format", "onnx"]));
    assert!(seed.join("actor.onnx").is_file());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn what_is_not_an_actor_is_refused() {
    let dir = scratch("export-bad");
    let out = cpmx(&["export", dir.to_str().unwrap(), "--format", "onnx"]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("actor.safetensors"), "{stderr}");
    let text = dir.join("notes.txt");
    std::fs::write(&text, "not weights").unwrap();
    let out = cpmx(&["export", text.to_str().unwrap(), "--format", "onnx"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("safetensors"));
    std::fs::remove_dir_all(&dir).ok();
}

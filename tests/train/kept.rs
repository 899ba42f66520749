//! `keep_actors_every`: a seed's folder keeps the actor of every Nth iteration, which a policy
//! names by `iteration` and `cpmx run` drives; keeping them changes neither the weights nor the
//! fingerprint (a run trained without the key resumes with it).

use std::path::Path;
use std::process::Command;

use crate::support::{ok, reference, scratch};
use crate::{edited, small_spec, train};

#[test]
fn the_kept_actors_are_the_iterations_actors_and_run_as_policies() {
    let dir = scratch("train-kept");
    let spec = small_spec(&dir, 4);
    let keeping = edited(
        &spec,
        "  iterations: 4\n",
        "  iterations: 4\n  keep_actors_every: 2\n",
    )
    .replace("trained: {seed: 7,", "trained: {seed: 8, iteration: 2,");
    std::fs::write(&spec, &keeping).unwrap();
    ok(&train(&dir, &spec, &["--only", "seed=8"]));
    let out = dir.join("out/8");
    let kept = [2, 4].map(|k| std::fs::read(out.join(format!("actors/{k}.safetensors"))).unwrap());
    for k in [1, 3] {
        assert!(
            !out.join(format!("actors/{k}.safetensors")).exists(),
            "iteration {k}"
        );
    }
    assert_eq!(
        kept[1],
        std::fs::read(out.join("actor.last.safetensors")).unwrap()
    );
    assert_ne!(kept[0], kept[1], "two iterations' actors");
    // The same weights and fingerprint as the training without the key.
    let plain = scratch("train-kept-plain");
    let plain_spec = small_spec(&plain, 4);
    ok(&train(&plain, &plain_spec, &["--only", "seed=8"]));
    assert_eq!(
        std::fs::read(plain.join("out/8/actor.last.safetensors")).unwrap(),
        kept[1]
    );
    let fingerprint = |dir: &Path| {
        let run: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("out/8/run.json")).unwrap()).unwrap();
        run["fingerprint"].clone()
    };
    assert_eq!(fingerprint(&dir), fingerprint(&plain));
    // The policy names iteration 2 of seed 8, and `cpmx run` drives that actor.
    let run_out = dir.join("run");
    ok(&Command::new(env!("CARGO_BIN_EXE_cpmx"))
        .args(["run", spec.to_str().unwrap(), "--out", run_out.to_str().unwrap()])
        .arg("--data")
        .arg(reference())
        .env_remove("CPMX_DATA")
        .output()
        .unwrap());
    let resolved = std::fs::read_to_string(run_out.join("spec.resolved.yaml")).unwrap();
    let pinned = format!("sha256: {}", cpmx_spec::sha256_hex(&kept[0]));
    assert!(
        resolved.contains(&pinned),
        "iteration 2's actor pinned:\n{resolved}"
    );
}

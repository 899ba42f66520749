//! The files a spec names, found on the data path: the map, weights, recorded run folders, and
//! pinned files whose content must match; a located problem with the folders tried for each
//! one missing.

use std::path::PathBuf;

use crate::check::{CheckContext, Resources};
use crate::diagnostic::{ByteSpan, Problem};
use crate::model::{InitialConfiguration, MapSpec, Spec};
use crate::paths::{DataPath, NotFound};

/// A problem for a file that is on none of the data path's folders.
pub(crate) fn missing_file(
    what: &str,
    file: &str,
    tried: &[PathBuf],
    option: &str,
    span: ByteSpan,
) -> Problem {
    let places: Vec<String> = tried.iter().map(|p| format!("  {}", p.display())).collect();
    Problem::error(
        "cpmx::check::missing-file",
        format!("{what} `{file}` was not found"),
        span,
        "not found",
    )
    .with_help(format!(
        "looked in:\n{}\nput it next to the spec, or name its folder with {option} or `CPMX_DATA`",
        places.join("\n")
    ))
}

/// A problem for a pinned file: missing, or present only with other content.
pub(crate) fn missing_pinned(
    what: &str,
    file: &str,
    sha256: Option<&str>,
    missing: &NotFound,
    option: &str,
    span: ByteSpan,
) -> Problem {
    let Some(expected) = sha256.filter(|_| !missing.other_content.is_empty()) else {
        let mut problem = missing_file(what, file, &missing.tried, option, span);
        if let Some(expected) = sha256 {
            problem.message = format!("{what} `{file}` (sha256 {}…) was not found", &expected[..12]);
        }
        return problem;
    };
    let others: Vec<String> = missing
        .other_content
        .iter()
        .map(|(path, found)| format!("  {} has sha256 {found}", path.display()))
        .collect();
    Problem::error(
        "cpmx::check::file-content",
        format!("no {what} `{file}` with sha256 {expected}"),
        span,
        "pinned to other content",
    )
    .with_help(format!(
        "found only other versions:\n{}\nname the folder of the pinned version with {option}, or remove \
         `sha256` to take any",
        others.join("\n")
    ))
}

/// Which files a check must find.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CheckScope {
    /// Everything a run needs: map, weights, recorded run folders.
    Run,
    /// What measuring recorded runs needs (`cpmx report`, `cpmx evaluate`): the map only.
    Measure,
}

/// The file a `map:` value names (SigmaRL's scenario table for `{sigmarl}`), found on the data
/// path; a missing one is an error at `pointer` (`/map`, or a configuration's own `map`).
fn find_map_file(
    map: &MapSpec,
    pointer: &str,
    data: &DataPath,
    ctx: &mut CheckContext<'_>,
) -> Option<PathBuf> {
    let (what, file, sha256, at) = match map {
        MapSpec::Builtin(_) => return None,
        MapSpec::Sigmarl(map) => (
            "SigmaRL's scenario table",
            map.table_file(),
            map.sha256.as_deref(),
            if map.table.is_some() { "table" } else { "sigmarl" },
        ),
        MapSpec::File(map) => ("map file", map.file.as_str(), map.sha256.as_deref(), "file"),
    };
    match data.find_pinned(file, sha256) {
        Ok(path) => Some(path),
        Err(missing) => {
            let span = ctx.span(&format!("{pointer}/{at}"));
            ctx.push(missing_pinned(what, file, sha256, &missing, data.option, span));
            None
        }
    }
}

pub(crate) fn find_files(
    spec: &Spec,
    data: &DataPath,
    scope: CheckScope,
    ctx: &mut CheckContext<'_>,
) -> Resources {
    let mut resources = Resources {
        spec_dir: data
            .folders
            .first()
            .cloned()
            .unwrap_or_else(|| PathBuf::from(".")),
        ..Resources::default()
    };
    resources.map_file = find_map_file(&spec.map, "/map", data, ctx);
    resources.configuration_map_files = spec
        .initial_configurations
        .iter()
        .enumerate()
        .map(|(i, c)| {
            c.own_map()
                .and_then(|map| find_map_file(map, &format!("/initial_configurations/{i}/map"), data, ctx))
        })
        .collect();
    for (name, fidelity) in &spec.fidelities {
        let crate::model::Fidelity::Simulated(simulated) = fidelity else {
            continue;
        };
        let Some(file) = simulated
            .safety
            .as_ref()
            .and_then(|s| s.cbf.agents.as_ref())
            .and_then(|a| a.predictor.as_ref())
        else {
            continue;
        };
        match data.find(file) {
            Ok(path) => {
                resources.margin_predictors.insert(file.clone(), path);
            }
            Err(_) if scope == CheckScope::Measure => {}
            Err(tried) => {
                let span = ctx.span(&format!(
                    "/fidelities/{}/safety/cbf/agents/predictor",
                    crate::yaml::escape_pointer(name)
                ));
                ctx.push(missing_file("margin network", file, &tried, data.option, span));
            }
        }
    }
    let mut observations = vec![None; spec.policies.len()];
    for (i, policy) in spec.policies.iter().enumerate() {
        let found = policy
            .mlp
            .as_ref()
            .and_then(|mlp| match (&mlp.weights, &mlp.trained) {
                (Some(weights), _) => match data.find_pinned(weights, mlp.sha256.as_deref()) {
                    Ok(path) => Some(path),
                    Err(_) if scope == CheckScope::Measure => None,
                    Err(missing) => {
                        let span = ctx.span(&format!("/policies/{i}/mlp/weights"));
                        ctx.push(missing_pinned(
                            "weight file",
                            weights,
                            mlp.sha256.as_deref(),
                            &missing,
                            data.option,
                            span,
                        ));
                        None
                    }
                },
                (None, Some(_)) if scope == CheckScope::Measure => None,
                (None, Some(trained)) => crate::check_trained::find_trained(spec, i, trained, data, ctx),
                (None, None) => {
                    let found = crate::check_checkpoint::find_checkpoint(spec, i, mlp, data, scope, ctx);
                    observations[i] = found.observation;
                    found.policy
                }
            })
            .or_else(|| {
                let onnx = policy.onnx.as_ref()?;
                match data.find_pinned(&onnx.file, onnx.sha256.as_deref()) {
                    Ok(path) => Some(path),
                    Err(_) if scope == CheckScope::Measure => None,
                    Err(missing) => {
                        let span = ctx.span(&format!("/policies/{i}/onnx/file"));
                        ctx.push(missing_pinned(
                            "ONNX file",
                            &onnx.file,
                            onnx.sha256.as_deref(),
                            &missing,
                            data.option,
                            span,
                        ));
                        None
                    }
                }
            });
        resources.weights.push(found);
        let priority =
            crate::check_checkpoint::find_priority(spec, i, observations[i].as_ref(), data, scope, ctx);
        resources.priorities.push(priority);
    }
    resources.observations = observations;
    if let Some(training) = &spec.training {
        let mut missing = std::collections::BTreeSet::new();
        for &seed in &training.seeds {
            let Some(file) = training.initial_actor_of(seed) else {
                break;
            };
            match data.find(&file) {
                Ok(path) => {
                    resources.initial_actors.insert(seed, path);
                }
                // `cpmx train` reads files as scoring does; it says a missing one when it trains.
                Err(_) if scope == CheckScope::Measure => {}
                Err(tried) => {
                    if missing.insert(file.clone()) {
                        let span = ctx.span("/training/initial_actor");
                        ctx.push(missing_file("initial actor", &file, &tried, data.option, span));
                    }
                }
            }
        }
    }
    for (i, c) in spec.initial_configurations.iter().enumerate() {
        resources.poses.push(match c {
            InitialConfiguration::FromPoses(f) => {
                crate::check_poses::find_poses(spec, i, &f.from_poses, data, scope, ctx)
            }
            _ => None,
        });
    }
    if scope == CheckScope::Measure {
        resources.from_runs = vec![None; spec.initial_configurations.len()];
        return resources;
    }
    for (i, c) in spec.initial_configurations.iter().enumerate() {
        let found = match c {
            InitialConfiguration::FromRuns(f) => match data.find(&f.from_runs.dir) {
                Ok(path) if path.join("matrix.csv").is_file() => {
                    if crate::matrix::recorded_runs(&path, &f.from_runs.fidelity).is_empty() {
                        let span = ctx.span(&format!("/initial_configurations/{i}/from_runs/fidelity"));
                        ctx.push(
                            Problem::error(
                                "cpmx::check::from-runs",
                                format!(
                                    "`{}` holds no runs of fidelity `{}`",
                                    path.display(),
                                    f.from_runs.fidelity
                                ),
                                span,
                                "no matching runs",
                            )
                            .with_help(
                                "name the fidelity the recorded runs used (see the folder's matrix.csv)",
                            ),
                        );
                    }
                    Some(path)
                }
                Ok(path) => {
                    let span = ctx.span(&format!("/initial_configurations/{i}/from_runs/dir"));
                    ctx.push(
                        Problem::error(
                            "cpmx::check::from-runs",
                            format!("`{}` is not a run folder of cpmx", path.display()),
                            span,
                            "no matrix.csv here",
                        )
                        .with_help("name a folder written by `cpmx run`"),
                    );
                    None
                }
                Err(tried) => {
                    let span = ctx.span(&format!("/initial_configurations/{i}/from_runs/dir"));
                    ctx.push(missing_file(
                        "run folder",
                        &f.from_runs.dir,
                        &tried,
                        data.option,
                        span,
                    ));
                    None
                }
            },
            _ => None,
        };
        resources.from_runs.push(found);
    }
    resources
}

//! `from_poses:` entries: the poses file found on the data path and read, and every run of the
//! matrix given its row (each policy's label, each configuration, each repetition), with the
//! file's line in the diagnostic of a row that is wrong.

use crate::check::CheckContext;
use crate::check_files::{CheckScope, missing_pinned};
use crate::diagnostic::Problem;
use crate::model::{FromPosesSpec, Spec};
use crate::paths::DataPath;
use crate::poses::MeasuredPoses;

/// The poses of the `from_poses` entry `entry`, found and read; its problems reported (in the
/// `Run` scope).
pub(crate) fn find_poses(
    spec: &Spec,
    entry: usize,
    from: &FromPosesSpec,
    data: &DataPath,
    scope: CheckScope,
    ctx: &mut CheckContext<'_>,
) -> Option<MeasuredPoses> {
    let base = format!("/initial_configurations/{entry}/from_poses");
    let path = match data.find_pinned(&from.file, from.sha256.as_deref()) {
        Ok(path) => path,
        Err(_) if scope == CheckScope::Measure => return None,
        Err(missing) => {
            let span = ctx.span(&format!("{base}/file"));
            ctx.push(missing_pinned(
                "poses file",
                &from.file,
                from.sha256.as_deref(),
                &missing,
                data.option,
                span,
            ));
            return None;
        }
    };
    let poses = match MeasuredPoses::read(&path) {
        Ok(poses) => poses,
        Err(e) => {
            if scope == CheckScope::Run {
                let span = ctx.span(&format!("{base}/file"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::poses",
                        format!("cannot read the poses file {}: {e}", path.display()),
                        span,
                        "not a poses file",
                    )
                    .with_help(POSES_LAYOUT),
                );
            }
            return None;
        }
    };
    if scope == CheckScope::Run {
        check_coverage(spec, entry, from, &poses, &path.display().to_string(), ctx);
    }
    Some(poses)
}

const POSES_LAYOUT: &str = "a row per run: `policy`, `initial_configuration`, `repetition` (or a `file` column \
     ending in `<label>/<configuration>-<repetition>.<ext>`), `v<k>_x`, `v<k>_y`, `v<k>_theta` for each \
     vehicle and `ref_path_ids` (`3|5|5`)";

/// Every policy of the spec has a row for each configuration of the file and each repetition,
/// with one pose per agent; configuration names are names of the language; the mapping names
/// policies of the spec.
fn check_coverage(
    spec: &Spec,
    entry: usize,
    from: &FromPosesSpec,
    poses: &MeasuredPoses,
    file: &str,
    ctx: &mut CheckContext<'_>,
) {
    let base = format!("/initial_configurations/{entry}/from_poses");
    for (policy, label) in &from.policies {
        if !spec.policies.iter().any(|p| &p.name == policy) {
            let span = ctx.spans(&format!(
                "{base}/policies/{}",
                crate::yaml::escape_pointer(policy)
            ));
            ctx.push(
                Problem::error(
                    "cpmx::check::poses",
                    format!("`{policy}` (mapped to the file's `{label}`) is not a policy of the spec"),
                    span.key.unwrap_or(span.value),
                    "unknown policy",
                )
                .with_help("the keys of `policies:` are the spec's policies, the values the file's labels"),
            );
        }
    }
    let span = ctx.span(&format!("{base}/file"));
    let configurations = poses.configurations();
    for configuration in &configurations {
        let valid = configuration
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
            && !configuration.starts_with('-');
        if !valid {
            ctx.push(
                Problem::error(
                    "cpmx::check::poses",
                    format!("{file} names the configuration `{configuration}`, not a name of cpmx"),
                    span,
                    "configuration name",
                )
                .with_help("configuration names are lower-case letters, digits and `-`"),
            );
            return;
        }
    }
    let mut missing = Vec::new();
    for policy in &spec.policies {
        let label = from.label_of(&policy.name);
        for configuration in &configurations {
            for repetition in 1..=spec.repetitions {
                match poses.row(label, configuration, repetition) {
                    None => missing.push(format!(
                        "`{}` (label `{label}`), `{configuration}`, repetition {repetition}",
                        policy.name
                    )),
                    Some(row) if row.vehicles.len() != spec.agents as usize => ctx.push(
                        Problem::error(
                            "cpmx::check::poses",
                            format!(
                                "line {} of {file} places {} vehicles, but the spec has `agents: {}`",
                                row.line,
                                row.vehicles.len(),
                                spec.agents
                            ),
                            span,
                            "agent count",
                        )
                        .with_help("give the file's vehicle count as `agents`"),
                    ),
                    Some(_) => {}
                }
            }
        }
    }
    if let Some(first) = missing.first() {
        ctx.push(
            Problem::error(
                "cpmx::check::poses",
                format!(
                    "{file} has no row for {first}{}",
                    match missing.len() {
                        1 => String::new(),
                        n => format!(" and {} more runs", n - 1),
                    }
                ),
                span,
                "runs without a start",
            )
            .with_help(
                "every policy needs a row for each configuration and repetition; give a policy the file's \
                 label of its rows with `policies: {POLICY: LABEL}`, or lower `repetitions`",
            ),
        );
    }
}

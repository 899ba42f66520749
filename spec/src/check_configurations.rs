//! The checks of the initial configurations that need no map: an explicit configuration places
//! the spec's number of agents (or any number on its own map), a `sample` entry's own agent
//! count needs its own map, and each agent's start is given one way.

use crate::check::CheckContext;
use crate::diagnostic::Problem;
use crate::model::{InitialConfiguration, Spec};

/// A sample entry places another number of agents than the spec's `agents` only on its own map.
fn check_sample_agents(
    spec: &Spec,
    entry: usize,
    s: &crate::model::SampledStarts,
    ctx: &mut CheckContext<'_>,
) {
    let Some(agents) = s.sample.agents else {
        return;
    };
    if s.map.is_some() || agents == spec.agents {
        return;
    }
    let span = ctx.span(&format!("/initial_configurations/{entry}/sample/agents"));
    ctx.push(
        Problem::error(
            "cpmx::check::agent-count",
            format!(
                "this sample places {agents} agent{}, but the spec has `agents: {}` on its map",
                if agents == 1 { "" } else { "s" },
                spec.agents
            ),
            span,
            format!("{agents} agents"),
        )
        .with_help("give the entry its own `map`, or change `agents`"),
    );
}

/// Each configuration entry's agent count and each agent's start, at the entry's line.
pub(crate) fn check_configurations(spec: &Spec, ctx: &mut CheckContext<'_>) {
    for (i, c) in spec.initial_configurations.iter().enumerate() {
        if let InitialConfiguration::Sampled(s) = c {
            check_sample_agents(spec, i, s, ctx);
        }
        let InitialConfiguration::Explicit(e) = c else {
            continue;
        };
        let base = format!("/initial_configurations/{i}");
        if e.map.is_none() && e.agents.len() != spec.agents as usize {
            let span = ctx.span(&format!("{base}/agents"));
            ctx.push(
                Problem::error(
                    "cpmx::check::agent-count",
                    format!(
                        "initial configuration `{}` places {} agent{}, but the spec has `agents: {}`",
                        e.name,
                        e.agents.len(),
                        if e.agents.len() == 1 { "" } else { "s" },
                        spec.agents
                    ),
                    span,
                    format!("{} entries", e.agents.len()),
                )
                .with_help("give one entry per agent, or change `agents`"),
            );
        }
        for (j, a) in e.agents.iter().enumerate() {
            let agent = format!("{base}/agents/{j}");
            if a.arc_length.is_some() && a.pose.is_some() {
                let spans = ctx.spans(&format!("{agent}/pose"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::start",
                        "a start is given twice: by `arc_length` and by `pose`",
                        spans.key.unwrap_or(spans.value),
                        "second start",
                    )
                    .with_help("keep one of them"),
                );
            }
            if let Some(pose) = &a.pose
                && pose.yaw.is_some()
                && pose.yaw_deg.is_some()
            {
                let spans = ctx.spans(&format!("{agent}/pose/yaw"));
                ctx.push(
                    Problem::error(
                        "cpmx::check::start",
                        "the heading is given twice: as `yaw` and as `yaw_deg`",
                        spans.key.unwrap_or(spans.value),
                        "second heading",
                    )
                    .with_help("keep one of them"),
                );
            }
        }
    }
}

//! The report section's checks: its grouping, the comparison's reference (a fidelity or a
//! policy of the spec), and, once sweeps have made their points, that every fidelity compared
//! with a reference fidelity has reference runs to pair with.
//!
//! A fidelity swept on its own layers becomes one fidelity per point (`sim@latency_ms=100`)
//! and no longer has runs under its bare name; a fidelity compared with it pairs only when it
//! is swept alike (the reference's point with its values, [`crate::sweep::paired_reference`]). Without
//! this check such a spec validates and its comparison table is empty.

use std::collections::HashSet;

use indexmap::IndexMap;

use crate::check::CheckContext;
use crate::diagnostic::Problem;
use crate::model::Spec;
use crate::sweep::{FidelityPoint, base_fidelity, is_reference, paired_reference};
use crate::yaml::SpannedDocument;

const AT: &str = "/report/compare/reference";

/// The problems of the comparison's reference among the run matrix's fidelities `points`.
pub(crate) fn check_reference(
    spec: &Spec,
    points: &IndexMap<String, FidelityPoint>,
    doc: &SpannedDocument,
) -> Vec<Problem> {
    let Some(compare) = &spec.report.compare else {
        return Vec::new();
    };
    let reference = compare.reference.as_str();
    if spec.policies.iter().any(|p| p.name == reference) {
        // Policies are compared within each fidelity or point, whatever is swept.
        return Vec::new();
    }
    let is_name = |name: &str| points.contains_key(name);
    let reference_points: Vec<&str> = points
        .keys()
        .map(String::as_str)
        .filter(|name| is_reference(name, reference) && *name != reference)
        .collect();
    if reference.contains('@') && !is_name(reference) {
        let base = base_fidelity(reference);
        let others: Vec<&str> = points
            .keys()
            .map(String::as_str)
            .filter(|name| is_reference(name, base))
            .collect();
        return vec![
            Problem::error(
                "cpmx::check::reference",
                format!("`compare.reference` names `{reference}`, which is not a fidelity of the run matrix"),
                doc.label_span(AT),
                "no such point",
            )
            .with_help(format!("the points of `{base}`: {}", others.join(", "))),
        ];
    }
    let unpaired: Vec<&str> = points
        .keys()
        .map(String::as_str)
        .filter(|name| !is_reference(name, reference))
        .filter(|name| {
            !is_name(&paired_reference(
                name,
                reference,
                points.keys().map(String::as_str),
            ))
        })
        .collect();
    if unpaired.is_empty() {
        return Vec::new();
    }
    let first = reference_points.first().copied().unwrap_or(reference);
    vec![
        Problem::error(
            "cpmx::check::reference",
            format!(
                "the reference `{reference}` is swept (its points: {}), and {} no point of it to pair with: \
                 the comparison would be empty",
                reference_points.join(", "),
                match unpaired.as_slice() {
                    [one] => format!("fidelity `{one}` has"),
                    many => format!("fidelities `{}` have", many.join("`, `")),
                }
            ),
            doc.label_span(AT),
            "swept",
        )
        .with_help(format!(
            "name one point as the reference (`reference: {first}`), compare with a fidelity that is not swept, \
             or sweep the same parameter with the same values in the others"
        )),
    ]
}

/// `report.group_by` names each axis once; `report.compare.reference` names a fidelity or a
/// policy of the spec, not both.
pub(crate) fn check_report(spec: &Spec, ctx: &mut CheckContext<'_>) {
    // A point of a swept fidelity (`sim@latency_ms=0`) is checked once the points exist
    // (`check_compare`).
    // The reference names a fidelity (compared with every other fidelity) or a policy (with
    // every other policy); a name that is both is ambiguous.
    if let Some(compare) = &spec.report.compare {
        let reference = compare.reference.as_str();
        let is_fidelity = spec
            .fidelities
            .contains_key(crate::sweep::base_fidelity(reference));
        let is_policy = spec.policies.iter().any(|p| p.name == reference);
        let span = ctx.span("/report/compare/reference");
        if is_fidelity && is_policy {
            ctx.push(
                Problem::error(
                    "cpmx::check::reference",
                    format!("`compare.reference` names `{reference}`, which is both a fidelity and a policy"),
                    span,
                    "ambiguous",
                )
                .with_help("rename the fidelity or the policy"),
            );
        } else if !is_fidelity && !is_policy {
            let names: Vec<String> = spec
                .fidelities
                .keys()
                .cloned()
                .chain(spec.policies.iter().map(|p| p.name.clone()))
                .collect();
            let mut p = Problem::error(
                "cpmx::check::reference",
                format!(
                    "`compare.reference` names `{reference}`, which is neither a fidelity nor a policy of the spec"
                ),
                span,
                "unknown fidelity or policy",
            );
            p = match crate::schema::did_you_mean(reference, &names) {
                Some(best) => p.with_suggestion(best),
                None => p.with_help(format!("fidelities and policies: {}", names.join(", "))),
            };
            ctx.push(p);
        }
    }
    let mut seen = HashSet::new();
    for (i, key) in spec.report.group_by.iter().enumerate() {
        if !seen.insert(key) {
            let span = ctx.span(&format!("/report/group_by/{i}"));
            ctx.push(Problem::error(
                "cpmx::check::duplicate-name",
                "grouped twice by the same axis",
                span,
                "repeated",
            ));
        }
    }
}

//! The report's comparison against the run matrix, once sweeps have made their points: every
//! fidelity compared with `report.compare.reference` must have reference runs to pair with.
//!
//! A fidelity swept on its own layers becomes one fidelity per point (`sim@latency_ms=100`)
//! and no longer has runs under its bare name; a fidelity compared with it pairs only when it
//! is swept alike (the reference's point with its values, [`crate::sweep::paired_reference`]). Without
//! this check such a spec validates and its comparison table is empty.

use indexmap::IndexMap;

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

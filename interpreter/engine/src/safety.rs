//! A fidelity's `safety:` layer in the sim and twin engines: `cpmx-safety`'s
//! [`LayerFilter`] with each agent in its reference path's lane; what the filter did goes to
//! the run's statistics and notes (the run folder's `metrics.json`; `per_run.csv`'s
//! `safety.*` columns).

use cpmx_recording::Recording;
use cpmx_safety::layer::{self, LayerFilter};
use cpmx_spec::model::SafetyLayer;

use crate::engine::{RunError, RunInputs};

/// The filter of a run whose fidelity has the safety `layer`, if any, for agents on
/// `ref_paths` of the run's map (each path's left and right road boundaries). With the run's
/// `timing`, the filter times its steps (`cpmx run --timing`).
pub(crate) fn filter_of_run(
    layer: Option<&SafetyLayer>,
    inputs: &RunInputs<'_>,
    ref_paths: &[usize],
) -> Result<Option<LayerFilter>, RunError> {
    let Some(layer) = layer else {
        return Ok(None);
    };
    let experiment = inputs.experiment;
    let timing = inputs.timing;
    let lanes = ref_paths
        .iter()
        .map(|&id| {
            let path = inputs.map().reference_path(id)?;
            Some((
                layer::boundary(&path.left_boundary_shared)?,
                layer::boundary(&path.right_boundary_shared)?,
            ))
        })
        .collect::<Option<std::sync::Arc<[_]>>>()
        .ok_or(RunError::SafetyLanes)?;
    let predictor = layer
        .cbf
        .agents
        .as_ref()
        .and_then(|a| a.predictor.as_ref())
        .and_then(|name| experiment.margin_predictors.get(name).cloned());
    let parameters = layer::parameters(
        layer,
        &experiment.vehicle,
        &experiment.footprint,
        experiment.spec.timing.dt,
        predictor,
    );
    Ok(Some(
        LayerFilter::new(parameters, lanes, (0..ref_paths.len()).collect()).with_timing(timing),
    ))
}

/// What the filter did over the run, into its notes and statistics.
pub(crate) fn record(filter: &LayerFilter, recording: &mut Recording) {
    recording.notes.push(filter.counts().note());
    recording.statistics.extend(filter.counts().statistics());
}

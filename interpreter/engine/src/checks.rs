//! The spec checks that need the interpreter: which fidelities this build can run, and (with
//! the map loader) reference paths and starts.

use cpmx_spec::model::{ActuationLayer, Control, DynamicsLayer, Fidelity, SensingLayer, SimulatedFidelity};
use cpmx_spec::{CheckContext, InterpreterChecks, Resources, Spec};

/// The checks of this build of cpmx.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuildChecks;

impl InterpreterChecks for BuildChecks {
    fn cannot_run(&self, fidelity: &Fidelity) -> Option<String> {
        match fidelity {
            Fidelity::Lab(_) => Some("the lab driver (`driver: cpm-dds`) is not part of this build".into()),
            Fidelity::Simulated(SimulatedFidelity {
                control,
                dynamics,
                sensing,
                actuation,
            }) => {
                let mut missing = Vec::new();
                if *control == Control::Trajectory {
                    missing.push("`control: trajectory` (the Hc/Hp planner and MPC follower)");
                }
                if matches!(dynamics, DynamicsLayer::GreyBox(_)) {
                    missing.push("grey-box dynamics");
                }
                if matches!(sensing, Some(SensingLayer::Model(_))) {
                    missing.push("a sensing model");
                }
                if matches!(actuation, Some(ActuationLayer::Model(_))) {
                    missing.push("an actuation model");
                }
                (!missing.is_empty()).then(|| {
                    format!(
                        "it needs {}, which the twin engine will bring",
                        missing.join(", ")
                    )
                })
            }
        }
    }

    fn check(&self, _spec: &Spec, _resources: &Resources, _ctx: &mut CheckContext<'_>) {}
}

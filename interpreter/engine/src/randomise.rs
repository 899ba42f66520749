//! Domain randomisation in `cpmx run`: a fidelity's parameters given as distributions are drawn
//! once per run from the run's `randomisation` stream, in the order of
//! [`SimulatedFidelity::parameters`]. The runner draws, hands the drawn fidelity to the engine
//! (`RunInputs::fidelity`) and records what was drawn (`metrics.json`'s `drawn_parameters`);
//! the lab emulator draws the same way for the runs it plays. Runs that differ only in fidelity share their seed, so a parameter
//! randomised alike in two fidelities takes the same value in paired runs.

use cpmx_spec::matrix::stream_key;
use cpmx_spec::model::{DrawnFidelity, SimulatedFidelity};
use rand::SeedableRng;
use rand_chacha::ChaCha20Rng;

/// The fidelity of one run with its distributions drawn, and the drawn values by parameter
/// name (in drawing order), from the run's `randomisation` stream (the rule:
/// [`cpmx_stack::draw_fidelity`]).
pub fn draw_for_run(fidelity: &SimulatedFidelity, run_seed: u64) -> (DrawnFidelity, Vec<(String, f64)>) {
    let mut rng = ChaCha20Rng::from_seed(stream_key(run_seed, "randomisation"));
    cpmx_stack::draw_fidelity(fidelity, &mut rng)
}

#[cfg(test)]
mod tests {
    use super::*;
    use cpmx_spec::model::{
        ActuationLayer, ActuationModel, Control, Distribution, DynamicsLayer, KinematicKeyword,
        NormalDistribution, Parameter,
    };

    fn delayed(delay_ms: Parameter) -> SimulatedFidelity {
        SimulatedFidelity {
            control: Control::Trajectory,
            dynamics: DynamicsLayer::Kinematic(KinematicKeyword::Kinematic),
            sensing: None,
            actuation: Some(ActuationLayer::Model(ActuationModel { delay_ms })),
            follower: None,
            communication: None,
            perception: None,
            safety: None,
        }
    }

    fn delay_of(f: &DrawnFidelity) -> f64 {
        match &f.actuation {
            Some(ActuationLayer::Model(a)) => a.delay_ms,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn draws_follow_the_run_seed_and_stay_in_range() {
        let uniform = delayed(Parameter::Drawn(Distribution::Uniform([40.0, 120.0])));
        let (a, drawn_a) = draw_for_run(&uniform, 7);
        let (b, _) = draw_for_run(&uniform, 7);
        let (c, _) = draw_for_run(&uniform, 8);
        assert_eq!(delay_of(&a), delay_of(&b));
        assert_ne!(delay_of(&a), delay_of(&c));
        assert_eq!(drawn_a, vec![("actuation.delay_ms".to_owned(), delay_of(&a))]);

        let values: Vec<f64> = (0..2000)
            .map(|seed| delay_of(&draw_for_run(&uniform, seed).0))
            .collect();
        assert!(values.iter().all(|v| (40.0..120.0).contains(v)));
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        assert!((mean - 80.0).abs() < 2.0, "{mean}");

        // A normal near the range's lower end is truncated there: no negative delay.
        let normal = delayed(Parameter::Drawn(Distribution::Normal(NormalDistribution {
            mean: 5.0,
            std: 10.0,
        })));
        let values: Vec<f64> = (0..2000)
            .map(|seed| delay_of(&draw_for_run(&normal, seed).0))
            .collect();
        assert!(values.iter().all(|v| *v >= 0.0));
        assert!(values.iter().any(|v| *v < 5.0) && values.iter().any(|v| *v > 15.0));

        // Numbers are kept and not recorded.
        let fixed = delayed(Parameter::Fixed(80.0));
        let (f, drawn) = draw_for_run(&fixed, 7);
        assert_eq!(delay_of(&f), 80.0);
        assert!(drawn.is_empty());
    }
}

//! Drawing a randomised fidelity: every layer parameter given as a distribution
//! (`{uniform: [a, b]}`, `{normal: {mean, std}}`) replaced by a value drawn from a stream, in
//! the order of [`SimulatedFidelity::parameters`]. One rule for `cpmx run` (a draw per run from
//! the run's `randomisation` stream) and `cpmx train` (a draw per episode from the
//! environment's stream), so a fidelity means the same distribution of vehicles in both.

use cpmx_spec::model::{Distribution, DrawnFidelity, ParameterRange, SimulatedFidelity};
use rand::RngExt;
use rand_chacha::ChaCha20Rng;
use rand_distr::{Distribution as _, StandardNormal};

/// How often a normal draw outside the parameter's range is drawn again before it is clamped
/// (`cpmx validate` keeps the mean inside the range, so this is never reached in practice).
const MAX_REDRAWS: usize = 1000;

/// `fidelity` with its distributions drawn from `rng`, and the drawn values by parameter name
/// (in drawing order; numbers given as numbers are kept and not listed).
pub fn draw_fidelity(
    fidelity: &SimulatedFidelity,
    rng: &mut ChaCha20Rng,
) -> (DrawnFidelity, Vec<(String, f64)>) {
    let mut drawn = Vec::new();
    let fidelity = fidelity.draw(|name, distribution, range| {
        let value = draw_value(distribution, range, rng);
        drawn.push((name.to_owned(), value));
        value
    });
    (fidelity, drawn)
}

/// One value of `distribution` inside `range` (a normal is drawn again until it falls inside).
pub fn draw_value(distribution: &Distribution, range: ParameterRange, rng: &mut ChaCha20Rng) -> f64 {
    match *distribution {
        Distribution::Uniform([low, high]) => low + (high - low) * rng.random::<f64>(),
        Distribution::Normal(n) => {
            for _ in 0..MAX_REDRAWS {
                let z: f64 = StandardNormal.sample(rng);
                let value = n.mean + n.std * z;
                if range.contains(value) {
                    return value;
                }
            }
            n.mean.clamp(range.min, range.max)
        }
    }
}

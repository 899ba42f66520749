//! From raw network outputs to commands: SigmaRL's `NormalParamExtractor` + `TanhNormal`
//! output mapping, deterministic (mean) or sampled.
//!
//! This module owns the output mapping and the only random draws of a policy (from the
//! caller's ChaCha20 stream); it knows nothing of observations or vehicles.

use rand::Rng;
use rand_chacha::ChaCha20Rng;
use rand_distr::{Distribution, StandardNormal};

/// How a command is chosen from the action distribution.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ActionMode {
    /// The deterministic action `high * clamp(tanh(loc))` (SigmaRL at test time).
    #[default]
    Mean,
    /// A sample `high * clamp(tanh(loc + scale * N(0, 1)))` (SigmaRL in training), with
    /// N(0, 1) drawn as float32 from a `ChaCha20Rng`, speed before steering, agent by agent.
    Sample,
}

/// `log(expm1(0.99))`: the bias of torchrl's `biased_softplus_1.0` (scale 1 for raw 0).
const SCALE_BIAS: f32 = 0.525_458_7;
/// Lower bound of the scale.
const SCALE_MIN: f32 = 1e-4;
/// `safe_tanh` bound of TanhNormal.
const TANH_BOUND: f32 = 1.0 - 1e-6;

/// One agent's distribution parameters and chosen action.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ActionOutput {
    /// Gaussian location `[speed, steering]` (before tanh).
    pub loc: [f32; 2],
    /// Gaussian scale `[speed, steering]`.
    pub scale: [f32; 2],
    /// The action `[speed m/s, steering rad]`.
    pub action: [f32; 2],
}

/// The action box half-ranges of the TanhNormal (the box is symmetric about 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActionHead {
    /// `[max speed m/s, max steering rad]`.
    pub high: [f32; 2],
    /// torchrl 0.2.1's TanhNormal (SigmaRL 1.2.0): the location is shifted into the box and
    /// back, `(loc + high) - high` in float32, before tanh; that moves its last bits.
    pub shift_location: bool,
}

impl Default for ActionHead {
    /// SigmaRL's box: speed ±1 m/s, steering ±31°.
    fn default() -> Self {
        ActionHead {
            high: [1.0, 0.541_052_04],
            shift_location: false,
        }
    }
}

impl ActionHead {
    /// Map 4 raw outputs `[loc_v, loc_δ, pre_scale_v, pre_scale_δ]` to an action. `rng` is only
    /// used by [`ActionMode::Sample`].
    pub fn map(&self, raw: &[f32; 4], mode: ActionMode, rng: &mut ChaCha20Rng) -> ActionOutput {
        let loc = [raw[0], raw[1]];
        let scale = [scale_of(raw[2]), scale_of(raw[3])];
        let mut action = [0.0; 2];
        for c in 0..2 {
            let centre = if self.shift_location {
                (loc[c] + self.high[c]) - self.high[c]
            } else {
                loc[c]
            };
            let pre = match mode {
                ActionMode::Mean => centre,
                ActionMode::Sample => centre + scale[c] * standard_normal(rng),
            };
            action[c] = self.high[c] * pre.tanh().clamp(-TANH_BOUND, TANH_BOUND);
        }
        ActionOutput { loc, scale, action }
    }
}

/// How a network's raw outputs become an action (`mlp: {output: ...}`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OutputHead {
    /// SigmaRL's: 4 raw outputs `[loc_v, loc_δ, pre_scale_v, pre_scale_δ]`, a TanhNormal in
    /// the action box (mean or sampled, see [`ActionMode`]).
    #[default]
    SigmarlTanhNormal,
    /// 2 raw outputs `[v, δ]`, action `high * tanh(raw)` (a deterministic policy squashed into
    /// the box, as TD3/DDPG actors end).
    DeterministicTanh,
    /// 2 raw outputs `[v m/s, δ rad]` taken as the action, clipped to the box.
    DeterministicClip,
}

impl OutputHead {
    /// Raw outputs the network must produce.
    pub fn raw_size(self) -> usize {
        match self {
            OutputHead::SigmarlTanhNormal => 4,
            OutputHead::DeterministicTanh | OutputHead::DeterministicClip => 2,
        }
    }

    /// The name a spec uses (`output: ...`).
    pub fn name(self) -> &'static str {
        match self {
            OutputHead::SigmarlTanhNormal => "sigmarl-tanh-normal",
            OutputHead::DeterministicTanh => "deterministic-tanh",
            OutputHead::DeterministicClip => "deterministic-clip",
        }
    }

    /// What the raw outputs are, for diagnostics.
    pub fn describe(self) -> &'static str {
        match self {
            OutputHead::SigmarlTanhNormal => "2 locations and 2 pre-scales of a TanhNormal",
            OutputHead::DeterministicTanh => "speed and steering before tanh",
            OutputHead::DeterministicClip => "speed [m/s] and steering [rad]",
        }
    }

    /// Map one agent's raw outputs (`raw_size()` values) to an action in `box_`'s range.
    /// Only the TanhNormal draws from `rng`, and only in [`ActionMode::Sample`].
    pub fn map(
        self,
        box_: &ActionHead,
        raw: &[f32],
        mode: ActionMode,
        rng: &mut ChaCha20Rng,
    ) -> ActionOutput {
        match (self, raw) {
            (OutputHead::SigmarlTanhNormal, &[a, b, c, d]) => box_.map(&[a, b, c, d], mode, rng),
            (OutputHead::DeterministicTanh, &[v, d]) => ActionOutput {
                loc: [v, d],
                scale: [0.0; 2],
                action: [box_.high[0] * v.tanh(), box_.high[1] * d.tanh()],
            },
            (OutputHead::DeterministicClip, &[v, d]) => ActionOutput {
                loc: [v, d],
                scale: [0.0; 2],
                action: [
                    v.clamp(-box_.high[0], box_.high[0]),
                    d.clamp(-box_.high[1], box_.high[1]),
                ],
            },
            _ => ActionOutput::default(),
        }
    }
}

/// `max(softplus(raw + bias) + 0.01, 1e-4)` with torch's softplus (linear above 20).
fn scale_of(raw: f32) -> f32 {
    let x = raw + SCALE_BIAS;
    let softplus = if x > 20.0 { x } else { x.exp().ln_1p() };
    (softplus + 0.01).max(SCALE_MIN)
}

fn standard_normal<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    StandardNormal.sample(rng)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn zero_raw_output_gives_unit_scale_and_zero_action() {
        let mut rng = ChaCha20Rng::seed_from_u64(0);
        let out = ActionHead::default().map(&[0.0; 4], ActionMode::Mean, &mut rng);
        assert!((out.scale[0] - 1.0).abs() < 1e-6);
        assert_eq!(out.action, [0.0, 0.0]);
    }

    #[test]
    fn deterministic_heads() {
        let mut rng = ChaCha20Rng::seed_from_u64(0);
        let b = ActionHead::default();
        let t = OutputHead::DeterministicTanh.map(&b, &[0.5, -100.0], ActionMode::Mean, &mut rng);
        assert_eq!(t.action, [0.5f32.tanh(), -b.high[1]]);
        let c = OutputHead::DeterministicClip.map(&b, &[0.3, -100.0], ActionMode::Sample, &mut rng);
        assert_eq!(c.action, [0.3, -b.high[1]]);
        assert_eq!(OutputHead::SigmarlTanhNormal.raw_size(), 4);
    }

    #[test]
    fn actions_stay_inside_the_box() {
        let mut rng = ChaCha20Rng::seed_from_u64(1);
        let head = ActionHead::default();
        let out = head.map(&[50.0, -50.0, 3.0, 3.0], ActionMode::Sample, &mut rng);
        assert!(out.action[0] < 1.0 && out.action[1] > -head.high[1]);
    }
}

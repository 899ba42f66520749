//! The arithmetic a map's geometry is computed in. SigmaRL stores coordinates as `float32`
//! torch tensors and does all path arithmetic in `float32`; reproducing its reference paths
//! bit for bit means doing the same. Values are always held as `f64` (widened exactly).

/// Precision of map coordinates and of the path arithmetic.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Numerics {
    /// As SigmaRL (torch default dtype): coordinates are rounded to `f32` on load (text ->
    /// `f64` -> `f32`, as Python's `float()` then `torch.tensor` do) and every mean, difference
    /// and blend is computed in `f32`.
    Float32,
    /// Plain `f64` throughout (maps written by this project, lanelet2 maps in projected
    /// coordinates where `f32` would lose centimetres).
    Float64,
}

impl Numerics {
    /// Rounds a coordinate read from a file to this precision (`None` if it does not fit).
    pub fn coordinate(self, value: f64) -> Option<f64> {
        let v = match self {
            Numerics::Float32 => f64::from(value as f32),
            Numerics::Float64 => value,
        };
        v.is_finite().then_some(v)
    }

    /// `(a + b) / 2` per coordinate.
    pub fn mean(self, a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
        match self {
            Numerics::Float32 => [
                f64::from((a[0] as f32 + b[0] as f32) / 2.0),
                f64::from((a[1] as f32 + b[1] as f32) / 2.0),
            ],
            Numerics::Float64 => [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0],
        }
    }

    /// `b - a` per coordinate.
    pub fn diff(self, a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
        match self {
            Numerics::Float32 => [
                f64::from(b[0] as f32 - a[0] as f32),
                f64::from(b[1] as f32 - a[1] as f32),
            ],
            Numerics::Float64 => [b[0] - a[0], b[1] - a[1]],
        }
    }

    /// Euclidean distance `|b - a|` (torch's `norm` of the difference).
    pub fn distance(self, a: [f64; 2], b: [f64; 2]) -> f64 {
        match self {
            Numerics::Float32 => {
                let dx = b[0] as f32 - a[0] as f32;
                let dy = b[1] as f32 - a[1] as f32;
                f64::from((dx * dx + dy * dy).sqrt())
            }
            Numerics::Float64 => (b[0] - a[0]).hypot(b[1] - a[1]),
        }
    }

    /// `atan2(v[1], v[0])` [rad], in `f32` (as torch) for [`Numerics::Float32`].
    pub fn atan2(self, v: [f64; 2]) -> f64 {
        match self {
            Numerics::Float32 => f64::from((v[1] as f32).atan2(v[0] as f32)),
            Numerics::Float64 => v[1].atan2(v[0]),
        }
    }

    /// `n` points linearly spaced from `s` to `e`, both included, as SigmaRL blends
    /// boundaries: weights `w = torch.linspace(0, 1, n)` and points `(1 - w) s + w e`.
    /// torch's CPU linspace computes `w_i = i * step` for the first half and
    /// `1 - (n - 1 - i) * step` for the second half, with `step = 1 / (n - 1)`.
    pub fn blend(self, s: [f64; 2], e: [f64; 2], n: usize) -> Vec<[f64; 2]> {
        let last = n.saturating_sub(1).max(1);
        match self {
            Numerics::Float32 => {
                let step = 1.0f32 / last as f32;
                (0..n)
                    .map(|i| {
                        let w = if i < n / 2 {
                            i as f32 * step
                        } else {
                            1.0 - (last - i) as f32 * step
                        };
                        let lerp = |a: f64, b: f64| f64::from((1.0 - w) * a as f32 + w * b as f32);
                        [lerp(s[0], e[0]), lerp(s[1], e[1])]
                    })
                    .collect()
            }
            Numerics::Float64 => {
                let step = 1.0 / last as f64;
                (0..n)
                    .map(|i| {
                        let w = if i < n / 2 {
                            i as f64 * step
                        } else {
                            1.0 - (last - i) as f64 * step
                        };
                        [(1.0 - w) * s[0] + w * e[0], (1.0 - w) * s[1] + w * e[1]]
                    })
                    .collect()
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn float32_rounds_through_f64_like_python() {
        let v = Numerics::Float32.coordinate(2.339834290).unwrap();
        assert_eq!(v, f64::from(2.339834290f64 as f32));
        assert!(Numerics::Float32.coordinate(1e39).is_none());
        assert!(Numerics::Float64.coordinate(f64::NAN).is_none());
    }

    #[test]
    fn blend_includes_both_ends() {
        for numerics in [Numerics::Float32, Numerics::Float64] {
            let q = numerics.blend([0.0, 1.0], [7.0, 8.0], 8);
            assert_eq!(q.len(), 8);
            assert_eq!(q[0], [0.0, 1.0]);
            assert_eq!(q[7], [7.0, 8.0]);
        }
    }
}

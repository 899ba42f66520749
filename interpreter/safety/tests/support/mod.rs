//! The lanes of the cases computed with SigmaRL's own code: a straight lane of half-width
//! 0.15 m (points every 0.05 m for x in −2..2) and a lane on a circle of radius 1 m (the left
//! boundary at 0.85 m, the right at 1.15 m, every 0.05 rad from −1.5 rad), as `float32`
//! polylines.

use cpmx_safety::Boundary;

#[derive(Debug, Clone, Copy)]
pub enum Lane {
    Straight,
    Arc,
}

impl Lane {
    pub fn boundaries(self) -> (Boundary, Boundary) {
        let line = |f: &dyn Fn(f64) -> [f64; 2], n: usize, start: f64, step: f64| -> Boundary {
            Boundary::new(
                (0..n)
                    .map(|i| f(start + step * i as f64))
                    .map(|p| [p[0] as f32, p[1] as f32])
                    .collect(),
            )
            .unwrap()
        };
        match self {
            // np.linspace(-2, 2, 81)
            Lane::Straight => (
                line(&|x| [x, 0.15], 81, -2.0, 0.05),
                line(&|x| [x, -0.15], 81, -2.0, 0.05),
            ),
            Lane::Arc => (
                line(&|t| [0.85 * t.cos(), 0.85 * t.sin()], 61, -1.5, 0.05),
                line(&|t| [1.15 * t.cos(), 1.15 * t.sin()], 61, -1.5, 0.05),
            ),
        }
    }
}

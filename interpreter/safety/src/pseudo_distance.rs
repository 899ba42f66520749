//! The pseudo-distance of a point to a boundary polyline (SigmaRL's `PseudoDistance`, the
//! ITSC 2025 paper's smooth distance): for each segment, the point is taken into the segment's
//! frame, projected along the line that blends the tangents at the segment's two ends, and
//! its distance to that projection is kept where the projection falls on the segment; the
//! smallest over the segments, rounded to `float16` as SigmaRL returns it. Computed in `f32`
//! in SigmaRL's order of operations (`sigmarl/pseudo_distance.py` at tag 1.4.0).

/// What SigmaRL puts where no segment's projection falls on the segment.
pub const NO_PROJECTION: f32 = 1000.0;

/// A boundary polyline with what SigmaRL computes of each segment for every query: its frame's
/// rotation, its length, and the slopes of the pseudo tangents (central differences inside,
/// one-sided at the ends: `compute_pseudo_tangent_vector`) at its ends in that frame. They
/// depend on the points alone, so they are computed once; the values are the same `f32`
/// operations SigmaRL repeats per query.
///
/// The segments are also cut into blocks of [`BLOCK_SEGMENTS`] with their bounding boxes: a
/// segment's pseudo-distance is never below the point's distance to the segment (its
/// projection lies on it), so a block whose box is farther than the best distance found cannot
/// hold a smaller one and is skipped; the answer is the full search's, bit for bit.
#[derive(Debug, Clone, PartialEq)]
pub struct Boundary {
    points: Vec<[f32; 2]>,
    segments: Vec<Segment>,
    /// `[x_min, x_max, y_min, y_max]` of each block's segments.
    blocks: Vec<[f32; 4]>,
}

/// Segments per block of a boundary.
const BLOCK_SEGMENTS: usize = 16;

/// One segment in its own frame.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Segment {
    base: [f32; 2],
    cos: f32,
    sin: f32,
    length: f32,
    slope_base: f32,
    slope_tip: f32,
}

impl Boundary {
    /// A boundary through `points` (in driving direction); `None` with fewer than two.
    pub fn new(points: Vec<[f32; 2]>) -> Option<Boundary> {
        let n = points.len();
        if n < 2 {
            return None;
        }
        let diff = |a: [f32; 2], b: [f32; 2]| [b[0] - a[0], b[1] - a[1]];
        let tangents: Vec<[f32; 2]> = (0..n)
            .map(|i| match i {
                0 => diff(points[0], points[1]),
                _ if i == n - 1 => diff(points[n - 2], points[n - 1]),
                _ => diff(points[i - 1], points[i + 1]),
            })
            .collect();
        let segments = points
            .windows(2)
            .zip(tangents.windows(2))
            .map(|(pair, tangent)| {
                let (b, t) = (pair[0], pair[1]);
                let bt = [t[0] - b[0], t[1] - b[1]];
                let theta = bt[1].atan2(bt[0]);
                let (sin, cos) = (theta.sin(), theta.cos());
                // The rotation into the segment's frame: [[cos, sin], [-sin, cos]].
                let rotate = |v: [f32; 2]| [cos * v[0] + sin * v[1], -sin * v[0] + cos * v[1]];
                let slope = |t: [f32; 2]| if t[0] != 0.0 { t[1] / t[0] } else { 1e-8 };
                Segment {
                    base: b,
                    cos,
                    sin,
                    length: bt[1].mul_add(bt[1], bt[0] * bt[0]).sqrt(),
                    slope_base: slope(rotate(tangent[0])),
                    slope_tip: slope(rotate(tangent[1])),
                }
            })
            .collect();
        let blocks = (0..n - 1)
            .step_by(BLOCK_SEGMENTS)
            .map(|start| {
                let block = &points[start..n.min(start + BLOCK_SEGMENTS + 1)];
                block.iter().fold(
                    [f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY],
                    |b, p| [b[0].min(p[0]), b[1].max(p[0]), b[2].min(p[1]), b[3].max(p[1])],
                )
            })
            .collect();
        Some(Boundary {
            points,
            segments,
            blocks,
        })
    }

    /// The polyline's points.
    pub fn points(&self) -> &[[f32; 2]] {
        &self.points
    }

    /// The pseudo-distance of `q` [m], rounded to `float16` (exactly representable in `f32`);
    /// [`NO_PROJECTION`] where no segment takes the point.
    pub fn pseudo_distance(&self, q: [f32; 2]) -> f32 {
        // The nearest block first, then every block that could hold a smaller distance.
        let box_distance = |b: &[f32; 4]| {
            let dx = (b[0] - q[0]).max(q[0] - b[1]).max(0.0);
            let dy = (b[2] - q[1]).max(q[1] - b[3]).max(0.0);
            dx.hypot(dy)
        };
        let nearest = (0..self.blocks.len())
            .map(|i| (i, box_distance(&self.blocks[i])))
            .fold((0, f32::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
            .0;
        let mut best = self.block_distance(nearest, q, NO_PROJECTION);
        for (i, bounds) in self.blocks.iter().enumerate() {
            // float16 may round a distance down by 2⁻¹¹ of it, f32 by far less: a margin of a
            // thousandth (and a micrometre) keeps every block that might hold the minimum.
            if i != nearest && box_distance(bounds) * 0.999 - 1e-6 <= best {
                best = self.block_distance(i, q, best);
            }
        }
        best
    }

    /// The smallest of `best` and the pseudo-distances of block `block`'s segments to `q`.
    fn block_distance(&self, block: usize, q: [f32; 2], mut best: f32) -> f32 {
        let start = block * BLOCK_SEGMENTS;
        for s in &self.segments[start..self.segments.len().min(start + BLOCK_SEGMENTS)] {
            let v = [q[0] - s.base[0], q[1] - s.base[1]];
            let (x, y) = (s.cos * v[0] + s.sin * v[1], -s.sin * v[0] + s.cos * v[1]);
            let lambda = (x + y * s.slope_base) / (s.length - y * (s.slope_tip - s.slope_base));
            if !(0.0..1.0).contains(&lambda) {
                continue;
            }
            let n = [x - lambda * s.length, y];
            let distance = crate::float16(n[1].mul_add(n[1], n[0] * n[0]).sqrt());
            // torch.min keeps the first of equal values (the same value); a NaN never wins.
            if distance < best {
                best = distance;
            }
        }
        best
    }

    /// The pseudo-distance by the full search over every segment (what the blocks must equal).
    #[cfg(test)]
    fn pseudo_distance_full(&self, q: [f32; 2]) -> f32 {
        (0..self.blocks.len()).fold(NO_PROJECTION, |best, block| self.block_distance(block, q, best))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(y: f32) -> Boundary {
        Boundary::new((0..81).map(|i| [-2.0 + 0.05 * i as f32, y]).collect()).unwrap()
    }

    #[test]
    fn on_a_straight_boundary_it_is_the_distance_to_the_line() {
        let left = straight(0.15);
        let d = left.pseudo_distance([0.013, 0.08]);
        assert!((d - 0.07).abs() < 1e-4, "{d}");
        // float16: the value is one of its numbers.
        assert_eq!(crate::float16(d), d);
    }

    proptest::proptest! {
        /// On a wavy boundary of 200 points, every query gets the full search's bits.
        #[test]
        fn the_blocks_give_the_full_searchs_answer(
            x in -1.0f32..11.0,
            y in -2.0f32..2.0,
            wave in 0.0f32..0.5,
        ) {
            let boundary = Boundary::new(
                (0..200).map(|i| {
                    let t = i as f32 * 0.05;
                    [t, wave * (t * 1.7).sin()]
                }).collect(),
            ).unwrap();
            let q = [x, y];
            proptest::prop_assert_eq!(
                boundary.pseudo_distance(q).to_bits(),
                boundary.pseudo_distance_full(q).to_bits()
            );
        }
    }

    #[test]
    fn past_the_polyline_no_segment_takes_the_point() {
        assert_eq!(straight(0.15).pseudo_distance([3.0, 0.0]), NO_PROJECTION);
        assert!(Boundary::new(vec![[0.0, 0.0]]).is_none());
    }
}

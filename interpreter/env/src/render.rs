//! A picture of one environment for people watching a training (Gymnasium's and PettingZoo's
//! `render_mode="rgb_array"`): the reference paths' road boundaries in grey, each agent's
//! centre line in a light shade of its colour, and the vehicles' footprints to scale, in
//! colour-blind-safe colours (Okabe–Ito). Drawn into an RGB buffer by plain scan conversion:
//! a frame costs a few hundred microseconds.

use cpmx_vehicle::footprint_corners;
use cpmx_world::Point;

use crate::VecEnv;

/// An RGB image, rows from the top, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    /// `height × width × 3` bytes.
    pub pixels: Vec<u8>,
}

/// Okabe–Ito's colours (without black), distinguishable with every common colour-vision
/// deficiency; agent `i` takes colour `i mod 7`.
pub const AGENT_COLOURS: [[u8; 3]; 7] = [
    [0, 114, 178],   // blue
    [230, 159, 0],   // orange
    [0, 158, 115],   // bluish green
    [204, 121, 167], // reddish purple
    [86, 180, 233],  // sky blue
    [213, 94, 0],    // vermillion
    [240, 228, 66],  // yellow
];

const BACKGROUND: [u8; 3] = [255, 255, 255];
const ROAD_EDGE: [u8; 3] = [150, 150, 150];
const OUTLINE: [u8; 3] = [0, 0, 0];
const MARGIN_PX: f64 = 8.0;

impl VecEnv {
    /// Environment `env` drawn `width_px` pixels wide (the height follows the paths'
    /// extent), or `None` when `env` is out of range.
    pub fn render_rgb(&self, env: usize, width_px: usize) -> Option<RgbImage> {
        let placements = self.placements_checked(env)?;
        let outlines: Vec<&[Point]> = self.outlines().collect();
        let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in outlines.iter().flat_map(|l| l.iter()) {
            for k in 0..2 {
                min[k] = min[k].min(p[k]);
                max[k] = max[k].max(p[k]);
            }
        }
        if !(min[0] < max[0] && min[1] < max[1]) {
            return None;
        }
        let width = width_px.max(32);
        let scale = (width as f64 - 2.0 * MARGIN_PX) / (max[0] - min[0]);
        let height = ((max[1] - min[1]) * scale + 2.0 * MARGIN_PX).ceil() as usize;
        let mut canvas = Canvas {
            image: RgbImage {
                width,
                height,
                pixels: BACKGROUND.repeat(width * height),
            },
            to_px: Box::new(move |p: Point| {
                [
                    MARGIN_PX + (p[0] - min[0]) * scale,
                    height as f64 - MARGIN_PX - (p[1] - min[1]) * scale,
                ]
            }),
        };
        for line in &outlines {
            canvas.polyline(line, ROAD_EDGE);
        }
        for (i, placement) in placements.iter().enumerate() {
            let colour = AGENT_COLOURS[i % AGENT_COLOURS.len()];
            let light = colour.map(|c| ((u16::from(c) + 2 * 255) / 3) as u8);
            canvas.polyline(&self.path_centre(placement.path), light);
        }
        let vehicle = self.config().vehicle;
        for (i, placement) in placements.iter().enumerate() {
            let s = placement.state;
            let corners = footprint_corners(&vehicle, s.x_m, s.y_m, s.yaw_rad);
            canvas.fill_polygon(&corners, AGENT_COLOURS[i % AGENT_COLOURS.len()]);
            let mut closed = corners.to_vec();
            closed.push(corners[0]);
            canvas.polyline(&closed, OUTLINE);
        }
        Some(canvas.image)
    }
}

/// An image with the map-to-pixel transform.
struct Canvas {
    image: RgbImage,
    to_px: Box<dyn Fn(Point) -> [f64; 2]>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, colour: [u8; 3]) {
        let (w, h) = (self.image.width as i64, self.image.height as i64);
        if (0..w).contains(&x) && (0..h).contains(&y) {
            let at = ((y * w + x) * 3) as usize;
            self.image.pixels[at..at + 3].copy_from_slice(&colour);
        }
    }

    /// A one-pixel polyline (DDA along the longer axis of each segment).
    fn polyline(&mut self, points: &[Point], colour: [u8; 3]) {
        for w in points.windows(2) {
            let (a, b) = ((self.to_px)(w[0]), (self.to_px)(w[1]));
            let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0) as i64;
            for k in 0..=steps {
                let t = k as f64 / steps as f64;
                let x = a[0] + t * (b[0] - a[0]);
                let y = a[1] + t * (b[1] - a[1]);
                self.put(x.round() as i64, y.round() as i64, colour);
            }
        }
    }

    /// A filled polygon (even-odd scan conversion at pixel centres).
    fn fill_polygon(&mut self, corners: &[Point], colour: [u8; 3]) {
        let px: Vec<[f64; 2]> = corners.iter().map(|&c| (self.to_px)(c)).collect();
        let (top, bottom) = px.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(t, b), p| {
            (t.min(p[1]), b.max(p[1]))
        });
        let (first, last) = (top.floor().max(0.0) as i64, bottom.ceil() as i64);
        for y in first..=last.min(self.image.height as i64 - 1) {
            let yc = y as f64 + 0.5;
            let mut crossings: Vec<f64> = Vec::new();
            for (i, a) in px.iter().enumerate() {
                let b = px[(i + 1) % px.len()];
                if (a[1] <= yc) != (b[1] <= yc) {
                    crossings.push(a[0] + (yc - a[1]) / (b[1] - a[1]) * (b[0] - a[0]));
                }
            }
            crossings.sort_by(f64::total_cmp);
            for pair in crossings.chunks_exact(2) {
                let (from, to) = ((pair[0] - 0.5).ceil() as i64, (pair[1] - 0.5).floor() as i64);
                for x in from..=to {
                    self.put(x, y, colour);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_filled_square_covers_its_pixels_and_no_others() {
        let mut canvas = Canvas {
            image: RgbImage {
                width: 10,
                height: 10,
                pixels: BACKGROUND.repeat(100),
            },
            to_px: Box::new(|p| p),
        };
        canvas.fill_polygon(&[[2.0, 2.0], [6.0, 2.0], [6.0, 6.0], [2.0, 6.0]], [1, 2, 3]);
        let filled = canvas.image.pixels.chunks(3).filter(|p| p == &[1, 2, 3]).count();
        assert_eq!(filled, 16);
        let at = |x: usize, y: usize| &canvas.image.pixels[(y * 10 + x) * 3..(y * 10 + x) * 3 + 3];
        assert_eq!(at(2, 2), [1, 2, 3]);
        assert_eq!(at(6, 6), BACKGROUND);
    }
}

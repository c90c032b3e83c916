//! Backgrounds behind the markers, painted in image space.
//!
//! `clutter` scatters dark and light shapes that look like parts of tags
//! (discs, rings, squares, square frames, L-shaped corners, 2 x 2 checkers),
//! the things that make a detector propose false candidates.

use std::path::PathBuf;
use std::sync::Arc;

use rand::RngExt;
use serde::Serialize;
use tiny_skia::FillRule;

use crate::coverage::{Canvas, Rasterizer};
use crate::polygon::ellipse;
use crate::rng::SynthRng;

/// A background.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum BackgroundKind {
    /// One grey level.
    Flat {
        /// Reflectance 0..1.
        level: f64,
    },
    /// A linear ramp between two levels.
    Gradient {
        /// Level at the start side.
        from: f64,
        /// Level at the end side.
        to: f64,
        /// Direction of increase, radians from x (towards y).
        angle: f64,
    },
    /// Random tag-like shapes on a flat base.
    Clutter {
        /// Base level.
        base: f64,
        /// Number of shapes.
        count: usize,
        /// Smallest shape size in pixels.
        min_size_px: f64,
        /// Largest shape size in pixels.
        max_size_px: f64,
    },
    /// An image file, stretched to the image size.
    Image {
        /// The file as given in the spec.
        path: PathBuf,
        /// Its grey levels, 0..1, already resized to the camera's size.
        #[serde(skip)]
        pixels: Arc<Vec<f32>>,
    },
    /// A rotated, scaled crop of a photograph (sampled specs): output pixel
    /// `p` shows the source at `centre + R(-angle) (p - image centre) /
    /// scale`, bilinear.
    Photo {
        /// The file as given in the spec.
        path: PathBuf,
        /// Rotation, radians.
        angle: f64,
        /// Output pixels per source pixel.
        scale: f64,
        /// Source point at the image centre, source pixel-centre coordinates.
        centre: [f64; 2],
        /// The photograph in grey.
        #[serde(skip)]
        source: Arc<image::GrayImage>,
    },
}

/// A background and its distance (for defocus).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Background {
    /// What it looks like.
    #[serde(flatten)]
    pub kind: BackgroundKind,
    /// Distance from the camera in metres, used for defocus blur.
    pub distance_m: f64,
}

fn rotated_square(c: [f64; 2], half: f64, angle: f64) -> Vec<[f64; 2]> {
    let (s, co) = angle.sin_cos();
    [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
        .iter()
        .map(|&[x, y]| {
            [
                c[0] + half * (co * x - s * y),
                c[1] + half * (s * x + co * y),
            ]
        })
        .collect()
}

fn transform(poly: &[[f64; 2]], c: [f64; 2], scale: f64, angle: f64) -> Vec<[f64; 2]> {
    let (s, co) = angle.sin_cos();
    poly.iter()
        .map(|&[x, y]| {
            let (x, y) = (x * scale, y * scale);
            [c[0] + co * x - s * y, c[1] + s * x + co * y]
        })
        .collect()
}

/// Paints a rotated, scaled view of `source` (bilinear, edges clamped).
fn paint_photo(
    canvas: &mut Canvas,
    source: &image::GrayImage,
    angle: f64,
    scale: f64,
    centre: [f64; 2],
) {
    let (w, h) = (canvas.width, canvas.height);
    let (sw, sh) = (source.width() as usize, source.height() as usize);
    if sw == 0 || sh == 0 {
        return;
    }
    let raw = source.as_raw();
    let (s, c) = angle.sin_cos();
    let (ox, oy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    let at = |x: usize, y: usize| f64::from(raw[y.min(sh - 1) * sw + x.min(sw - 1)]) / 255.0;
    for y in 0..h {
        for x in 0..w {
            let (dx, dy) = ((x as f64 - ox) / scale, (y as f64 - oy) / scale);
            let u = (centre[0] + c * dx + s * dy).clamp(0.0, (sw - 1) as f64);
            let v = (centre[1] - s * dx + c * dy).clamp(0.0, (sh - 1) as f64);
            let (x0, y0) = (u.floor() as usize, v.floor() as usize);
            let (fx, fy) = (u - x0 as f64, v - y0 as f64);
            let top = at(x0, y0) * (1.0 - fx) + at(x0 + 1, y0) * fx;
            let bot = at(x0, y0 + 1) * (1.0 - fx) + at(x0 + 1, y0 + 1) * fx;
            canvas.data[y * w + x] = (top * (1.0 - fy) + bot * fy) as f32;
        }
    }
}

impl Background {
    /// Paints the background over the whole canvas. `rng` drives clutter.
    pub fn paint(&self, canvas: &mut Canvas, raster: &mut Rasterizer, rng: &mut SynthRng) {
        let (w, h) = (canvas.width, canvas.height);
        match &self.kind {
            BackgroundKind::Flat { level } => canvas.data.fill(*level as f32),
            BackgroundKind::Gradient { from, to, angle } => {
                let (s, c) = angle.sin_cos();
                // Project every pixel on the direction; map the extremes of
                // the image to `from` and `to`.
                let corners = [
                    (0.0, 0.0),
                    (w as f64, 0.0),
                    (0.0, h as f64),
                    (w as f64, h as f64),
                ];
                let proj: Vec<f64> = corners.iter().map(|&(x, y)| x * c + y * s).collect();
                let lo = proj.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = proj.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                for y in 0..h {
                    for x in 0..w {
                        let t = ((x as f64 + 0.5) * c + (y as f64 + 0.5) * s - lo) / (hi - lo);
                        canvas.data[y * w + x] = (from + t * (to - from)) as f32;
                    }
                }
            }
            BackgroundKind::Clutter {
                base,
                count,
                min_size_px,
                max_size_px,
            } => {
                canvas.data.fill(*base as f32);
                for _ in 0..*count {
                    paint_clutter_shape(canvas, raster, rng, *min_size_px, *max_size_px);
                }
            }
            BackgroundKind::Image { pixels, .. } => canvas.data.copy_from_slice(pixels),
            BackgroundKind::Photo {
                angle,
                scale,
                centre,
                source,
                ..
            } => paint_photo(canvas, source, *angle, *scale, *centre),
        }
    }
}

fn paint_clutter_shape(
    canvas: &mut Canvas,
    raster: &mut Rasterizer,
    rng: &mut SynthRng,
    min: f64,
    max: f64,
) {
    let (w, h) = (canvas.width as f64, canvas.height as f64);
    let size = rng.random_range(min..=max.max(min));
    let c = [
        rng.random_range(-0.1 * w..1.1 * w),
        rng.random_range(-0.1 * h..1.1 * h),
    ];
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    // Mostly dark ink-like shapes, some light ones.
    let level = if rng.random_bool(0.75) {
        rng.random_range(0.03..0.3)
    } else {
        rng.random_range(0.7..0.97)
    } as f32;
    let r = size / 2.0;
    let circle_n = ((r * 2.0).ceil() as usize).clamp(24, 720);
    let (polys, rule) = match rng.random_range(0..6u32) {
        0 => (vec![ellipse(c, [r, r], 0.0, circle_n)], FillRule::Winding),
        1 => (
            vec![
                ellipse(c, [r, r], 0.0, circle_n),
                ellipse(c, [r * rng.random_range(0.5..0.85), r * 0.7], 0.0, circle_n),
            ],
            FillRule::EvenOdd,
        ),
        2 => (vec![rotated_square(c, r, angle)], FillRule::Winding),
        3 => (
            vec![
                rotated_square(c, r, angle),
                rotated_square(c, r * rng.random_range(0.55..0.85), angle),
            ],
            FillRule::EvenOdd,
        ),
        4 => {
            let t = rng.random_range(0.15..0.35);
            let l = vec![
                [-1.0, -1.0],
                [1.0, -1.0],
                [1.0, -1.0 + 2.0 * t],
                [-1.0 + 2.0 * t, -1.0 + 2.0 * t],
                [-1.0 + 2.0 * t, 1.0],
                [-1.0, 1.0],
            ];
            (vec![transform(&l, c, r, angle)], FillRule::Winding)
        }
        _ => {
            let q = vec![[-1.0, -1.0], [0.0, -1.0], [0.0, 0.0], [-1.0, 0.0]];
            let q2 = vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
            (
                vec![transform(&q, c, r, angle), transform(&q2, c, r, angle)],
                FillRule::Winding,
            )
        }
    };
    // Shapes are given in pixel-centre coordinates; the rasteriser wants
    // pixel-corner ones.
    let polys: Vec<Vec<[f64; 2]>> = polys
        .into_iter()
        .map(|p| p.into_iter().map(|q| [q[0] + 0.5, q[1] + 0.5]).collect())
        .collect();
    canvas.fill(raster, &polys, rule, level);
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn clutter_is_reproducible_and_varied() {
        let bg = Background {
            kind: BackgroundKind::Clutter {
                base: 0.6,
                count: 30,
                min_size_px: 5.0,
                max_size_px: 40.0,
            },
            distance_m: 3.0,
        };
        let mut r = Rasterizer::new();
        let draw = |seed| {
            let mut c = Canvas::new(160, 120, 0.0);
            bg.paint(
                &mut c,
                &mut Rasterizer::new(),
                &mut SynthRng::seed_from_u64(seed),
            );
            c
        };
        let (a, b, d) = (draw(1), draw(1), draw(2));
        assert_eq!(a, b);
        assert_ne!(a, d);
        let dark = a.data.iter().filter(|&&v| v < 0.35).count();
        assert!(dark > 200, "{dark}");
        let mut g = Canvas::new(10, 4, 0.0);
        Background {
            kind: BackgroundKind::Gradient {
                from: 0.2,
                to: 0.8,
                angle: 0.0,
            },
            distance_m: 3.0,
        }
        .paint(&mut g, &mut r, &mut SynthRng::seed_from_u64(0));
        assert!(g.data[0] < g.data[9] && (g.data[0] - 0.23).abs() < 1e-6);
    }
}

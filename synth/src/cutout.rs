//! Occluders given as an image with alpha (a photographed hand or cable
//! cut out in any editor), laid on the marker plane.
//!
//! A [`Cutout`] places an [`AlphaImage`] in the unit square of the marker
//! square ([`crate::occlusion`]'s frame): its centre at `centre`, its width
//! `width` marker squares (the height follows the image's aspect), turned
//! by `angle` radians (x towards y, like the frame). It is drawn through
//! the marker's pose like every occluder, with the image's own grey levels
//! blended by its alpha; its outline (for overlays, depth checks and the
//! rasteriser's coverage) is the placed rectangle.
//!
//! Its coverage is the alpha integrated over the marker square, measured on
//! a grid of [`COVERAGE_GRID`]^2 cell centres of the square; a point is
//! hidden (for the truth's corner visibility and the scenario checks) when
//! the alpha there is at least [`HIDDEN_ALPHA`].

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

/// Largest side of a cutout image, pixels (memory: 4 floats a pixel).
pub const MAX_CUTOUT_SIDE_PX: u32 = 4096;
/// Alpha from which a point counts as hidden.
pub const HIDDEN_ALPHA: f64 = 0.5;
/// Sample points per side of the marker square when alpha coverage is
/// measured: the error is at most about the outline length inside the
/// square over this (under 1/512 of the square for a convex blob), well
/// below the 0.005 tolerance of a pattern's stated coverage.
pub const COVERAGE_GRID: usize = 512;
/// Sub-samples per pixel side when a cutout is drawn (its image is
/// usually finer than the pixels it lands on; bilinear alone would alias).
pub const DRAW_SUPERSAMPLE: usize = 3;

/// The grey levels and alpha of a cutout, 0..1, premultiplied grey.
#[derive(Debug, Clone, PartialEq)]
pub struct AlphaImage {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Grey times alpha, row-major.
    premultiplied: Vec<f32>,
    /// Alpha, row-major.
    alpha: Vec<f32>,
}

impl AlphaImage {
    /// Reads a PNG (or any format the `image` crate reads) that has an
    /// alpha channel; `Err` says why it cannot be used.
    pub fn load(path: &Path) -> Result<Self, String> {
        let img = image::open(path).map_err(|e| e.to_string())?;
        if !img.color().has_alpha() {
            return Err(format!(
                "has no alpha channel ({:?}); save it as a PNG with transparency",
                img.color()
            ));
        }
        let la = img.to_luma_alpha16();
        let (w, h) = la.dimensions();
        if w == 0 || h == 0 || w > MAX_CUTOUT_SIDE_PX || h > MAX_CUTOUT_SIDE_PX {
            return Err(format!(
                "is {w}x{h} px; sides of 1..={MAX_CUTOUT_SIDE_PX} px are allowed"
            ));
        }
        let n = (w * h) as usize;
        let (mut premultiplied, mut alpha) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for p in la.pixels() {
            let (g, a) = (f32::from(p.0[0]) / 65535.0, f32::from(p.0[1]) / 65535.0);
            premultiplied.push(g * a);
            alpha.push(a);
        }
        if alpha.iter().all(|&a| a == 0.0) {
            return Err("is fully transparent".into());
        }
        Ok(Self {
            width: w as usize,
            height: h as usize,
            premultiplied,
            alpha,
        })
    }

    /// Bilinear (premultiplied grey, alpha) at pixel-centre coordinates
    /// `(x, y)`; transparent outside the image.
    #[must_use]
    pub fn sample(&self, x: f64, y: f64) -> (f32, f32) {
        let (w, h) = (self.width as i64, self.height as i64);
        if !(x > -1.0 && y > -1.0 && x < w as f64 && y < h as f64) {
            return (0.0, 0.0);
        }
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let mut out = (0.0f32, 0.0f32);
        for (dx, dy, wt) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let (xi, yi) = (x0 + dx, y0 + dy);
            if xi >= 0 && yi >= 0 && xi < w && yi < h && wt > 0.0 {
                let k = (yi * w + xi) as usize;
                out.0 += wt * self.premultiplied[k];
                out.1 += wt * self.alpha[k];
            }
        }
        out
    }
}

/// A cutout placed in the unit square of the marker square.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Cutout {
    /// The image file as written in the pattern file.
    pub image: PathBuf,
    /// Centre of the image, unit-square coordinates.
    pub centre: [f64; 2],
    /// Width of the image, marker squares.
    pub width: f64,
    /// Rotation, radians (x towards y).
    pub angle: f64,
    /// The pixels.
    #[serde(skip)]
    pub pixels: Arc<AlphaImage>,
}

impl Cutout {
    /// Marker squares per image pixel.
    fn pixel_size(&self) -> f64 {
        self.width / self.pixels.width as f64
    }

    /// Image pixel-centre coordinates of unit-square point `p`.
    #[must_use]
    pub fn to_image(&self, p: [f64; 2]) -> [f64; 2] {
        let (s, c) = self.angle.sin_cos();
        let (dx, dy) = (p[0] - self.centre[0], p[1] - self.centre[1]);
        let k = 1.0 / self.pixel_size();
        let (u, v) = ((c * dx + s * dy) * k, (-s * dx + c * dy) * k);
        [
            u + self.pixels.width as f64 / 2.0 - 0.5,
            v + self.pixels.height as f64 / 2.0 - 0.5,
        ]
    }

    /// (premultiplied grey, alpha) at unit-square point `p`.
    #[must_use]
    pub fn sample(&self, p: [f64; 2]) -> (f32, f32) {
        let q = self.to_image(p);
        self.pixels.sample(q[0], q[1])
    }

    /// Alpha at unit-square point `p`.
    #[must_use]
    pub fn alpha(&self, p: [f64; 2]) -> f64 {
        f64::from(self.sample(p).1)
    }

    /// The placed image's outline (TL, BL, BR, TR of the image), unit-square
    /// coordinates, a whole image pixel beyond the outer pixel centres:
    /// where bilinear alpha has faded to 0.
    #[must_use]
    pub fn outline(&self) -> Vec<[f64; 2]> {
        let ps = self.pixel_size();
        let (hw, hh) = (
            (self.pixels.width as f64 / 2.0 + 0.5) * ps,
            (self.pixels.height as f64 / 2.0 + 0.5) * ps,
        );
        let (s, c) = self.angle.sin_cos();
        [[-hw, -hh], [-hw, hh], [hw, hh], [hw, -hh]]
            .iter()
            .map(|&[x, y]| {
                [
                    self.centre[0] + c * x - s * y,
                    self.centre[1] + s * x + c * y,
                ]
            })
            .collect()
    }

    /// The same cutout turned by `k` quarter turns about the square's
    /// centre (as [`crate::occlusion`] turns generated patterns).
    #[must_use]
    pub fn quarter_turns(&self, k: u32) -> Self {
        let mut out = self.clone();
        for _ in 0..k % 4 {
            let (x, y) = (out.centre[0] - 0.5, out.centre[1] - 0.5);
            out.centre = [0.5 - y, 0.5 + x];
            out.angle += std::f64::consts::FRAC_PI_2;
        }
        out
    }
}

/// Mean of `opacity` over the cell centres of a [`COVERAGE_GRID`]^2 grid on
/// the unit square: the alpha-weighted fraction of the square covered.
#[must_use]
pub fn grid_coverage(opacity: impl Fn([f64; 2]) -> f64) -> f64 {
    let n = COVERAGE_GRID;
    let mut sum = 0.0;
    for j in 0..n {
        let y = (j as f64 + 0.5) / n as f64;
        let mut row = 0.0;
        for i in 0..n {
            row += opacity([(i as f64 + 0.5) / n as f64, y]);
        }
        sum += row;
    }
    sum / (n * n) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(side: u32) -> AlphaImage {
        let img = image::RgbaImage::from_fn(side, side, |x, y| {
            let r = side as f64 / 2.0;
            let d = (x as f64 + 0.5 - r).hypot(y as f64 + 0.5 - r);
            image::Rgba([40, 40, 40, if d < r - 1.0 { 255 } else { 0 }])
        });
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("d.png");
        img.save(&p).unwrap();
        AlphaImage::load(&p).unwrap()
    }

    #[test]
    fn coverage_is_the_alpha_inside_the_square() {
        let pixels = Arc::new(disc(200));
        let c = Cutout {
            image: "d.png".into(),
            centre: [0.5, 0.5],
            width: 0.6,
            angle: 0.3,
            pixels,
        };
        let cov = grid_coverage(|p| c.alpha(p));
        // A disc of radius ~0.297 (0.3 less a pixel).
        let want = std::f64::consts::PI * (0.3 - 0.003f64).powi(2);
        assert!((cov - want).abs() < 0.005, "{cov} vs {want}");
        assert!(c.alpha([0.5, 0.5]) > 0.99 && c.alpha([0.05, 0.05]) == 0.0);
        // Half outside the square: about half the disc counts.
        let half = Cutout {
            centre: [0.0, 0.5],
            ..c.clone()
        };
        let cov_half = grid_coverage(|p| half.alpha(p));
        assert!((cov_half - want / 2.0).abs() < 0.005, "{cov_half}");
        // A quarter turn moves the centre around the square's centre.
        let t = half.quarter_turns(1);
        assert!((t.centre[0] - 0.5).abs() < 1e-12 && (t.centre[1] - 0.0).abs() < 1e-12);
    }
}

//! What happens to the light after the scene is painted: illumination,
//! defocus and motion blur, sensor noise, 8-bit quantisation, JPEG.
//!
//! The canvas holds reflectance-like values (0 black ink .. 1 white); the
//! illumination field multiplies them; 1.0 after lighting maps to 255 DN.

use image::GrayImage;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use crate::coverage::{Canvas, Rasterizer};
use crate::error::{Result, SynthError};
use crate::rng::SynthRng;

/// A soft-edged shadow: a polygon in pixel-centre image coordinates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Shadow {
    /// Polygon vertices, pixel-centre coordinates.
    pub polygon: Vec<[f64; 2]>,
    /// Fraction of the light removed inside, 0..1.
    pub darkness: f64,
    /// Gaussian sigma of the penumbra in pixels (0 = hard edge).
    pub softness_px: f64,
    /// When the polygon is a half-plane (sampled specs): `[nx, ny, c]`,
    /// the inside being `nx x + ny y > c` (`(nx, ny)` a unit vector). The
    /// penumbra is then computed in closed form, `Phi(d / sigma)` of the
    /// signed distance `d`, instead of rasterising and blurring the mask
    /// (the blur of a whole-image mask at sigma up to 15 px was a fifth of
    /// a sampled image's time). Not written when absent, so older datasets
    /// keep their bytes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub half_plane: Option<[f64; 3]>,
}

/// Beyond this many sigmas from a half-plane shadow's edge, the penumbra
/// is taken as 0 or 1 (Phi(-6) = 1e-9, far below one grey level).
const PENUMBRA_REACH_SIGMAS: f64 = 6.0;

/// The error function, Abramowitz and Stegun (1964) formula 7.1.26
/// (absolute error below 1.5e-7, far below one grey level).
fn erf(x: f64) -> f64 {
    const P: f64 = 0.327_591_1;
    const A: [f64; 5] = [
        0.254_829_592,
        -0.284_496_736,
        1.421_413_741,
        -1.453_152_027,
        1.061_405_429,
    ];
    let t = 1.0 / (1.0 + P * x.abs());
    let poly = t * (A[0] + t * (A[1] + t * (A[2] + t * (A[3] + t * A[4]))));
    let y = 1.0 - poly * (-x * x).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// `1 / s` for the penumbra of a half-plane shadow of Gaussian sigma
/// `sigma` seen by a pixel: `s^2 = sigma^2 + 1/12` adds the variance of the
/// pixel's own width (a unit box) to the penumbra's.
fn penumbra_scale(sigma: f64) -> f64 {
    1.0 / (sigma * sigma + 1.0 / 12.0).sqrt()
}

/// The share of a half-plane shadow's darkness at `z` penumbra scales from
/// its edge (positive inside): the standard normal CDF.
fn penumbra(z: f64) -> f64 {
    if z >= PENUMBRA_REACH_SIGMAS {
        1.0
    } else if z <= -PENUMBRA_REACH_SIGMAS {
        0.0
    } else {
        0.5 * (1.0 + erf(z / std::f64::consts::SQRT_2))
    }
}

/// A specular glare: light reflected straight into the lens by a glossy
/// print or laminate, a Gaussian blob added on top of the diffuse image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Glare {
    /// Centre, pixel-centre coordinates.
    pub centre: [f64; 2],
    /// Gaussian sigma, pixels.
    pub sigma_px: f64,
    /// Added value at the centre (reflectance units: 1 = paper white at
    /// gain 1).
    pub peak: f64,
}

/// Illumination over the image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Lighting {
    /// Overall gain (exposure): 1 maps reflectance 1 to 255 DN.
    pub gain: f64,
    /// Linear ramp: relative change of the light from the image centre to
    /// its right edge (x) and bottom edge (y), times 2 across the image.
    pub gradient: [f64; 2],
    /// Fall-off at the image corners, `E = 1 - v (r / r_corner)^2`.
    pub vignetting: f64,
    /// Shadows.
    pub shadows: Vec<Shadow>,
    /// Specular glares (sampled specs only; not written when empty, so
    /// older datasets keep their bytes).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub glares: Vec<Glare>,
}

impl Default for Lighting {
    fn default() -> Self {
        Self {
            gain: 1.0,
            gradient: [0.0; 2],
            vignetting: 0.0,
            shadows: Vec::new(),
            glares: Vec::new(),
        }
    }
}

/// Sensor model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Sensor {
    /// Gaussian read noise, standard deviation in DN.
    pub read_noise_dn: f64,
    /// Full-well capacity in electrons at 255 DN, for shot noise (Poisson,
    /// approximated by a Gaussian of variance = electrons); 0 turns shot
    /// noise off.
    pub full_well_e: f64,
}

/// Straight-line motion blur.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MotionBlur {
    /// Length of the smear in pixels.
    pub length_px: f64,
    /// Direction, radians from the x axis (towards y).
    pub angle: f64,
}

/// Optional image degradations.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct Effects {
    /// Motion blur.
    pub motion_blur: Option<MotionBlur>,
    /// JPEG compression round trip at this quality (1..=100); the stored
    /// file is still a lossless PNG of the decoded JPEG.
    pub jpeg_quality: Option<u8>,
    /// Defocus as one Gaussian blur over the whole image, sigma in pixels
    /// (sampled specs; the depth-dependent lens defocus is
    /// [`crate::camera::Defocus`]). Not written when absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blur_sigma_px: Option<f64>,
}

/// Normalised Gaussian kernel of radius `ceil(3 sigma)`.
fn gaussian_kernel(sigma: f64) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let sum: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= sum);
    kernel
}

/// Separable Gaussian blur with clamp-to-edge borders.
#[must_use]
pub fn gaussian_blur(canvas: &Canvas, sigma: f64) -> Canvas {
    if sigma < 0.05 {
        return canvas.clone();
    }
    let kernel = gaussian_kernel(sigma);
    let radius = kernel.len() / 2;
    let (w, h) = (canvas.width, canvas.height);
    let mut tmp = vec![0.0f32; w * h];
    // Rows: copy into a buffer padded by repeating the edge pixels, so the
    // inner loop has no bounds clamping.
    let mut padded = vec![0.0f32; w + 2 * radius];
    for y in 0..h {
        let row = &canvas.data[y * w..(y + 1) * w];
        padded[..radius].fill(row[0]);
        padded[radius..radius + w].copy_from_slice(row);
        padded[radius + w..].fill(row[w - 1]);
        let out = &mut tmp[y * w..(y + 1) * w];
        for (k, &kv) in kernel.iter().enumerate() {
            for (o, p) in out.iter_mut().zip(&padded[k..k + w]) {
                *o += kv * p;
            }
        }
    }
    let mut out = Canvas::new(w, h, 0.0);
    for y in 0..h {
        for (k, &kv) in kernel.iter().enumerate() {
            let yi = (y as isize + k as isize - radius as isize).clamp(0, h as isize - 1) as usize;
            let src = &tmp[yi * w..(yi + 1) * w];
            let dst = &mut out.data[y * w..(y + 1) * w];
            for (d, s) in dst.iter_mut().zip(src) {
                *d += kv * s;
            }
        }
    }
    out
}

impl Lighting {
    /// Whether the lighting changes anything.
    #[must_use]
    pub fn is_identity(&self) -> bool {
        self.gain == 1.0
            && self.gradient == [0.0, 0.0]
            && self.vignetting == 0.0
            && self.shadows.is_empty()
            && self.glares.is_empty()
    }

    /// Multiplies the canvas by the illumination field.
    pub fn apply(&self, canvas: &mut Canvas, raster: &mut Rasterizer) {
        if self.is_identity() {
            return;
        }
        let (w, h) = (canvas.width, canvas.height);
        let mut light = Canvas::new(w, h, 1.0);
        for s in &self.shadows {
            if let Some([nx, ny, c]) = s.half_plane {
                // A hard edge (sigma 0) by pixel area along the normal.
                let hard = s.softness_px <= 0.0;
                let k = if hard {
                    1.0
                } else {
                    penumbra_scale(s.softness_px)
                };
                let full = 1.0 - s.darkness as f32;
                for y in 0..h {
                    let row = &mut light.data[y * w..(y + 1) * w];
                    let d0 = ny * y as f64 - c;
                    for (x, l) in row.iter_mut().enumerate() {
                        let z = (d0 + nx * x as f64) * k;
                        let m = if hard {
                            (z + 0.5).clamp(0.0, 1.0)
                        } else if z <= -PENUMBRA_REACH_SIGMAS {
                            continue;
                        } else if z >= PENUMBRA_REACH_SIGMAS {
                            *l *= full;
                            continue;
                        } else {
                            penumbra(z)
                        };
                        *l *= 1.0 - (s.darkness * m) as f32;
                    }
                }
                continue;
            }
            // The shadow's mask, on the part of the image it can reach
            // (its bounding box grown by the blur's reach).
            let reach = (3.0 * s.softness_px).ceil() + 2.0;
            let (mut x0, mut y0, mut x1, mut y1) = (
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            );
            for p in &s.polygon {
                (x0, y0, x1, y1) = (x0.min(p[0]), y0.min(p[1]), x1.max(p[0]), y1.max(p[1]));
            }
            let bx0 = (x0 - reach).floor().clamp(0.0, w as f64) as usize;
            let by0 = (y0 - reach).floor().clamp(0.0, h as f64) as usize;
            let bx1 = (x1 + reach).ceil().clamp(0.0, w as f64) as usize;
            let by1 = (y1 + reach).ceil().clamp(0.0, h as f64) as usize;
            if bx1 <= bx0 || by1 <= by0 {
                continue;
            }
            let (cw, ch) = (bx1 - bx0, by1 - by0);
            let mut mask = Canvas::new(cw, ch, 0.0);
            let poly: Vec<[f64; 2]> = s
                .polygon
                .iter()
                .map(|p| [p[0] + 0.5 - bx0 as f64, p[1] + 0.5 - by0 as f64])
                .collect();
            mask.fill(raster, &[poly], tiny_skia::FillRule::Winding, 1.0);
            let mask = gaussian_blur(&mask, s.softness_px);
            for y in 0..ch {
                let l = &mut light.data[(by0 + y) * w + bx0..(by0 + y) * w + bx1];
                for (l, m) in l.iter_mut().zip(&mask.data[y * cw..(y + 1) * cw]) {
                    *l *= 1.0 - s.darkness as f32 * m;
                }
            }
        }
        // E = gain (1 + gx dx / (w/2) + gy dy / (h/2)) (1 - v r^2 / r_corner^2),
        // r^2 = dx^2 + dy^2 from the image centre: sums of per-column and
        // per-row terms, precomputed.
        let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
        let rc2 = (cx * cx + cy * cy).max(1.0);
        let col: Vec<(f32, f32)> = (0..w)
            .map(|x| {
                let dx = x as f64 - cx;
                (
                    (self.gradient[0] * dx / (w as f64 / 2.0)) as f32,
                    (self.vignetting * dx * dx / rc2) as f32,
                )
            })
            .collect();
        let gain = self.gain as f32;
        for y in 0..h {
            let dy = y as f64 - cy;
            let ramp_y = 1.0 + (self.gradient[1] * dy / (h as f64 / 2.0)) as f32;
            let vig_y = 1.0 - (self.vignetting * dy * dy / rc2) as f32;
            let row = &mut canvas.data[y * w..(y + 1) * w];
            let lrow = &light.data[y * w..(y + 1) * w];
            for ((p, l), &(rx, vx)) in row.iter_mut().zip(lrow).zip(&col) {
                let e = (gain * (ramp_y + rx) * (vig_y - vx)).max(0.0);
                *p *= e * l;
            }
        }
        for g in &self.glares {
            add_glare(canvas, g);
        }
    }
}

/// Adds a glare blob within `4 sigma` of its centre.
fn add_glare(canvas: &mut Canvas, g: &Glare) {
    let (w, h) = (canvas.width, canvas.height);
    let reach = 4.0 * g.sigma_px;
    let x0 = (g.centre[0] - reach).floor().clamp(0.0, w as f64) as usize;
    let x1 = (g.centre[0] + reach).ceil().clamp(0.0, w as f64) as usize;
    let y0 = (g.centre[1] - reach).floor().clamp(0.0, h as f64) as usize;
    let y1 = (g.centre[1] + reach).ceil().clamp(0.0, h as f64) as usize;
    let k = -1.0 / (2.0 * g.sigma_px * g.sigma_px);
    for y in y0..y1 {
        let dy = y as f64 - g.centre[1];
        for x in x0..x1 {
            let dx = x as f64 - g.centre[0];
            canvas.data[y * w + x] += (g.peak * ((dx * dx + dy * dy) * k).exp()) as f32;
        }
    }
}

/// Depth-dependent blur: each pixel takes the blur its own `sigma` asks
/// for, interpolated between copies of the image blurred at a ladder of
/// sigmas (0, 0.5, 1, 2, 4, ... px). A layered approximation of a
/// spatially varying point spread function.
pub fn variable_blur(canvas: &Canvas, sigma: &[f32]) -> Canvas {
    let max = sigma.iter().copied().fold(0.0f32, f32::max);
    if max < 0.05 {
        return canvas.clone();
    }
    let mut levels = vec![0.0f32, 0.5];
    while *levels.last().expect("non-empty") < max {
        let next = levels.last().expect("non-empty") * 2.0;
        levels.push(next);
    }
    let blurred: Vec<Canvas> = levels
        .iter()
        .map(|&s| gaussian_blur(canvas, f64::from(s)))
        .collect();
    let mut out = canvas.clone();
    for (i, o) in out.data.iter_mut().enumerate() {
        let s = sigma[i];
        let k = levels
            .partition_point(|&l| l <= s)
            .clamp(1, levels.len() - 1);
        let (l0, l1) = (levels[k - 1], levels[k]);
        let t = ((s - l0) / (l1 - l0)).clamp(0.0, 1.0);
        *o = blurred[k - 1].data[i] * (1.0 - t) + blurred[k].data[i] * t;
    }
    out
}

/// Straight-line motion blur: the mean of bilinear samples along a segment
/// of the given length through each pixel, clamp-to-edge. The sample
/// offsets are the same for every pixel, so their bilinear weights add up to
/// one small convolution kernel, applied as shifted copies of a padded image.
#[must_use]
pub fn motion_blur(canvas: &Canvas, blur: MotionBlur) -> Canvas {
    if blur.length_px < 0.05 {
        return canvas.clone();
    }
    let (w, h) = (canvas.width, canvas.height);
    let n = (blur.length_px.ceil() as usize).max(1) * 2 + 1;
    let (s, c) = blur.angle.sin_cos();
    let mut taps: Vec<((isize, isize), f32)> = Vec::new();
    let mut add = |d: (isize, isize), wgt: f64| {
        if wgt == 0.0 {
            return;
        }
        match taps.iter_mut().find(|t| t.0 == d) {
            Some(t) => t.1 += wgt as f32,
            None => taps.push((d, wgt as f32)),
        }
    };
    for k in 0..n {
        let t = (k as f64 / (n - 1) as f64 - 0.5) * blur.length_px;
        let (dx, dy) = (t * c, t * s);
        let (ix, iy) = (dx.floor(), dy.floor());
        let (fx, fy) = (dx - ix, dy - iy);
        let (ix, iy) = (ix as isize, iy as isize);
        let wk = 1.0 / n as f64;
        add((ix, iy), wk * (1.0 - fx) * (1.0 - fy));
        add((ix + 1, iy), wk * fx * (1.0 - fy));
        add((ix, iy + 1), wk * (1.0 - fx) * fy);
        add((ix + 1, iy + 1), wk * fx * fy);
    }
    let r = taps
        .iter()
        .map(|t| t.0 .0.unsigned_abs().max(t.0 .1.unsigned_abs()))
        .max()
        .unwrap_or(0);
    // Padded copy, edges repeated.
    let pw = w + 2 * r;
    let mut padded = vec![0.0f32; pw * (h + 2 * r)];
    for py in 0..h + 2 * r {
        let sy = (py as isize - r as isize).clamp(0, h as isize - 1) as usize;
        let src = &canvas.data[sy * w..(sy + 1) * w];
        let row = &mut padded[py * pw..(py + 1) * pw];
        row[..r].fill(src[0]);
        row[r..r + w].copy_from_slice(src);
        row[r + w..].fill(src[w - 1]);
    }
    let mut out = Canvas::new(w, h, 0.0);
    for y in 0..h {
        let dst = &mut out.data[y * w..(y + 1) * w];
        for &((dx, dy), wgt) in &taps {
            let py = (y as isize + dy + r as isize) as usize;
            let px = (dx + r as isize) as usize;
            let src = &padded[py * pw + px..py * pw + px + w];
            for (d, s) in dst.iter_mut().zip(src) {
                *d += wgt * s;
            }
        }
    }
    out
}

/// Exposes the canvas to 8-bit digital numbers: `255 * value`, plus shot
/// and read noise, rounded and clamped.
pub fn quantise(canvas: &Canvas, sensor: &Sensor, rng: &mut SynthRng) -> GrayImage {
    let noisy = sensor.read_noise_dn > 0.0 || sensor.full_well_e > 0.0;
    let read_var = (sensor.read_noise_dn * sensor.read_noise_dn) as f32;
    let shot = if sensor.full_well_e > 0.0 {
        (255.0 * 255.0 / sensor.full_well_e) as f32
    } else {
        0.0
    };
    let data: Vec<u8> = canvas
        .data
        .iter()
        .map(|&v| {
            let mut dn = 255.0 * v;
            if noisy {
                let var = read_var + shot * v.max(0.0);
                let g: f32 = StandardNormal.sample(rng);
                dn += var.sqrt() * g;
            }
            // Round half up; the float-to-int cast truncates, which is
            // floor for the non-negative values left after the clamp (and
            // much faster than calling floor).
            (dn + 0.5).clamp(0.0, 255.0) as u8
        })
        .collect();
    GrayImage::from_raw(canvas.width as u32, canvas.height as u32, data)
        .expect("canvas size matches its data")
}

/// Encodes as JPEG at `quality` and decodes again.
pub fn jpeg_round_trip(img: &GrayImage, quality: u8) -> Result<GrayImage> {
    let mut buf = Vec::new();
    let err = |e: image::ImageError| SynthError::Image {
        path: "(JPEG round trip)".into(),
        message: e.to_string(),
    };
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, quality)
        .encode_image(img)
        .map_err(err)?;
    Ok(
        image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg)
            .map_err(err)?
            .to_luma8(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn half_plane_shadows_match_the_blurred_polygon() {
        let (w, h) = (120usize, 90usize);
        let (p, a) = ([50.0f64, 40.0f64], 0.4f64);
        let (d, n) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
        let l = 1000.0;
        let polygon = vec![
            [p[0] - l * d[0], p[1] - l * d[1]],
            [p[0] + l * d[0], p[1] + l * d[1]],
            [p[0] + l * d[0] + l * n[0], p[1] + l * d[1] + l * n[1]],
            [p[0] - l * d[0] + l * n[0], p[1] - l * d[1] + l * n[1]],
        ];
        for softness_px in [1.0, 1.5, 6.0] {
            let shadow = |half_plane| Lighting {
                shadows: vec![Shadow {
                    polygon: polygon.clone(),
                    darkness: 0.6,
                    softness_px,
                    half_plane,
                }],
                ..Lighting::default()
            };
            let mut r = Rasterizer::default();
            let mut a_img = Canvas::new(w, h, 1.0);
            shadow(None).apply(&mut a_img, &mut r);
            let mut b_img = Canvas::new(w, h, 1.0);
            let c = n[0] * p[0] + n[1] * p[1];
            shadow(Some([n[0], n[1], c])).apply(&mut b_img, &mut r);
            let worst = a_img
                .data
                .iter()
                .zip(&b_img.data)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max);
            // Within a grey level (1/255); the polygon's clamp-to-edge
            // blur differs near the image border by construction, so
            // compare away from it.
            let inner = (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| {
                    let m = 3 * softness_px as usize + 2;
                    x >= m && y >= m && x + m < w && y + m < h
                })
                .map(|(x, y)| (a_img.data[y * w + x] - b_img.data[y * w + x]).abs())
                .fold(0.0f32, f32::max);
            assert!(
                inner < 1.0 / 255.0,
                "softness {softness_px}: {inner} (all {worst})"
            );
            // Deep inside: the full darkness; deep outside: none.
            assert!((b_img.data[89 * w] - 0.4).abs() < 1e-6);
            assert!((b_img.data[119] - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn blur_preserves_mean_and_flat_fields() {
        let mut c = Canvas::new(40, 30, 0.25);
        c.data[15 * 40 + 20] = 10.0;
        let b = gaussian_blur(&c, 2.0);
        let (s0, s1): (f32, f32) = (c.data.iter().sum(), b.data.iter().sum());
        assert!((s0 - s1).abs() < 1e-3, "{s0} {s1}");
        let flat = Canvas::new(20, 20, 0.7);
        assert!(motion_blur(
            &flat,
            MotionBlur {
                length_px: 5.0,
                angle: 0.3
            }
        )
        .data
        .iter()
        .all(|v| (v - 0.7).abs() < 1e-5));
        let sig = vec![3.0f32; 400];
        assert!(variable_blur(&flat, &sig)
            .data
            .iter()
            .all(|v| (v - 0.7).abs() < 1e-5));
    }

    #[test]
    fn quantisation_and_noise() {
        let c = Canvas::new(100, 100, 0.5);
        let mut rng = SynthRng::seed_from_u64(1);
        let clean = quantise(&c, &Sensor::default(), &mut rng);
        assert!(clean.pixels().all(|p| p.0[0] == 128));
        let noisy = quantise(
            &c,
            &Sensor {
                read_noise_dn: 2.0,
                full_well_e: 0.0,
            },
            &mut rng,
        );
        let mean = noisy.pixels().map(|p| f64::from(p.0[0])).sum::<f64>() / 1e4;
        let var = noisy
            .pixels()
            .map(|p| (f64::from(p.0[0]) - mean).powi(2))
            .sum::<f64>()
            / 1e4;
        // Rounding noisy values is unbiased: the mean stays 127.5.
        assert!(
            (mean - 127.5).abs() < 0.1 && (var.sqrt() - 2.0).abs() < 0.15,
            "{mean} {var}"
        );
    }

    #[test]
    fn lighting_gain_and_shadow() {
        let mut c = Canvas::new(20, 10, 0.5);
        let mut r = Rasterizer::new();
        Lighting {
            gain: 1.2,
            shadows: vec![Shadow {
                polygon: vec![[-0.5, -0.5], [9.5, -0.5], [9.5, 9.5], [-0.5, 9.5]],
                darkness: 0.5,
                softness_px: 0.0,
                half_plane: None,
            }],
            ..Lighting::default()
        }
        .apply(&mut c, &mut r);
        assert!((c.data[5] - 0.3).abs() < 1e-6 && (c.data[15] - 0.6).abs() < 1e-6);
    }
}

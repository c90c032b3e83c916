//! No false positives: tag-free scenes full of discs, squares, fake tags
//! (a black disc around a white square with random cells), text-like
//! strokes and noise give no detection of either family.

use crate::common;

use common::{fill_poly, in_poly, Rng};
use coppertag::{Detector, DetectorConfig};
use image::GrayImage;

fn disc(c: [f64; 2], r: f64) -> Vec<[f64; 2]> {
    (0..48)
        .map(|k| {
            let t = k as f64 / 48.0 * std::f64::consts::TAU;
            [c[0] + r * t.cos(), c[1] + r * t.sin()]
        })
        .collect()
}

fn quad(c: [f64; 2], s: f64, rot: f64, skew: f64) -> Vec<[f64; 2]> {
    [[-0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.5, -0.5]]
        .iter()
        .map(|p| {
            let (x, y) = (p[0] * s, p[1] * s * skew);
            [
                c[0] + x * rot.cos() - y * rot.sin(),
                c[1] + x * rot.sin() + y * rot.cos(),
            ]
        })
        .collect()
}

/// One cluttered 640 x 480 scene.
pub fn clutter(seed: u64) -> GrayImage {
    let mut rng = Rng::new(seed);
    let bg = rng.range(60.0, 220.0) as u8;
    let mut img = GrayImage::from_pixel(640, 480, image::Luma([bg]));
    let n = 5 + (rng.next_u64() % 25) as usize;
    for _ in 0..n {
        let c = [rng.range(0.0, 640.0), rng.range(0.0, 480.0)];
        let dark = rng.range(0.0, 80.0) as u8;
        let light = rng.range(170.0, 255.0) as u8;
        match rng.next_u64() % 5 {
            0 => fill_poly(
                &mut img,
                &disc(c, rng.range(4.0, 90.0)),
                if rng.uniform() < 0.5 { dark } else { light },
            ),
            1 => {
                let q = quad(
                    c,
                    rng.range(8.0, 150.0),
                    rng.range(0.0, 6.3),
                    rng.range(0.4, 1.0),
                );
                fill_poly(&mut img, &q, if rng.uniform() < 0.5 { dark } else { light });
            }
            2 => {
                // Fake tag: dark disc, light square, random cells.
                let s = rng.range(30.0, 160.0);
                let rot = rng.range(0.0, 6.3);
                let skew = rng.range(0.5, 1.0);
                fill_poly(&mut img, &disc(c, 0.82 * s), dark);
                fill_poly(&mut img, &quad(c, s, rot, skew), light);
                let n = if rng.uniform() < 0.5 { 14 } else { 8 };
                let step = 1.0 / (n as f64 + 2.0);
                for i in 0..n {
                    for j in 0..n {
                        if rng.uniform() < 0.5 {
                            let u = -0.5 + (1.5 + j as f64) * step;
                            let v = -0.5 + (1.5 + i as f64) * step;
                            let (x, y) = (u * s, v * s * skew);
                            let p = [
                                c[0] + x * rot.cos() - y * rot.sin(),
                                c[1] + x * rot.sin() + y * rot.cos(),
                            ];
                            fill_poly(&mut img, &quad(p, step * s * 1.02, rot, skew), dark);
                        }
                    }
                }
            }
            3 => {
                // Text-like: a line of strokes.
                let h = rng.range(6.0, 30.0);
                let mut x = c[0];
                for _ in 0..(3 + rng.next_u64() % 12) {
                    let w = rng.range(0.15, 0.6) * h;
                    let poly = vec![[x, c[1]], [x + w, c[1]], [x + w, c[1] + h], [x, c[1] + h]];
                    fill_poly(&mut img, &poly, dark);
                    if rng.uniform() < 0.5 {
                        let bar = vec![
                            [x, c[1]],
                            [x + 2.0 * w, c[1]],
                            [x + 2.0 * w, c[1] + 0.2 * h],
                            [x, c[1] + 0.2 * h],
                        ];
                        fill_poly(&mut img, &bar, dark);
                    }
                    x += w * rng.range(1.5, 3.0);
                }
            }
            _ => {
                // A frame: dark square with a light square inside.
                let s = rng.range(20.0, 160.0);
                let rot = rng.range(0.0, 6.3);
                fill_poly(&mut img, &quad(c, s * 1.25, rot, 1.0), dark);
                fill_poly(&mut img, &quad(c, s, rot, 1.0), light);
            }
        }
    }
    let sigma = rng.range(0.0, 8.0);
    for p in img.pixels_mut() {
        p.0[0] = (f64::from(p.0[0]) + rng.gauss() * sigma)
            .round()
            .clamp(0.0, 255.0) as u8;
    }
    img
}

/// False detections and quads decoded over `n` scenes. The scenes are
/// split across the machine's cores (one detector per rayon worker): the
/// single test of this file takes half a minute of CPU, and run on one
/// core it was the suite's last test long after the others had ended.
fn count_false(n: u64) -> (usize, usize) {
    use rayon::prelude::*;
    (0..n)
        .into_par_iter()
        .map_init(
            || Detector::new(DetectorConfig::default()).unwrap(),
            |det, seed| {
                let found = det.detect(&clutter(seed));
                if !found.is_empty() {
                    eprintln!("seed {seed}: {found:?}");
                }
                (found.len(), det.stats().decode_attempts)
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

#[test]
fn no_detections_in_clutter() {
    let (bad, attempts) = count_false(1000);
    eprintln!("1000 clutter images: {bad} false detections, {attempts} quads decoded");
    assert_eq!(bad, 0);
}

/// The row-by-row fill paints exactly the pixels whose centres `in_poly`
/// accepts anywhere in the image, so the scenes are what testing every
/// pixel made: on discs, turned and squashed quads, and random
/// (self-crossing) polygons with vertices on pixel centres and rows,
/// partly or wholly off the image; a polygon with no vertex, and an empty
/// image, paint nothing.
#[test]
fn the_row_fill_paints_exactly_the_pixels_in_poly_accepts() {
    let mut rng = Rng::new(77);
    for k in 0..300 {
        let c = [rng.range(-20.0, 140.0), rng.range(-20.0, 100.0)];
        let poly = match k % 3 {
            0 => disc(c, rng.range(1.0, 60.0)),
            1 => quad(
                c,
                rng.range(2.0, 90.0),
                rng.range(0.0, 6.3),
                rng.range(0.4, 1.0),
            ),
            _ => (0..3 + k % 9)
                .map(|_| {
                    let p = [c[0] + rng.range(-50.0, 50.0), c[1] + rng.range(-50.0, 50.0)];
                    // Every other polygon has its vertices on whole pixels.
                    if k % 2 == 0 {
                        p.map(f64::round)
                    } else {
                        p
                    }
                })
                .collect(),
        };
        let (w, h) = (120u32, 90u32);
        let mut by_rows = GrayImage::new(w, h);
        fill_poly(&mut by_rows, &poly, 255);
        let by_pixel = GrayImage::from_fn(w, h, |x, y| {
            image::Luma([if in_poly(&poly, [f64::from(x), f64::from(y)]) {
                255
            } else {
                0
            }])
        });
        assert_eq!(by_rows, by_pixel, "polygon {k}: {poly:?}");
    }
    let blank = GrayImage::new(40, 30);
    for poly in [vec![], disc([-50.0, 15.0], 20.0), disc([20.0, 90.0], 20.0)] {
        let mut img = blank.clone();
        fill_poly(&mut img, &poly, 255);
        assert_eq!(img, blank, "{poly:?}");
    }
    let mut empty = GrayImage::new(0, 0);
    fill_poly(&mut empty, &disc([0.0, 0.0], 5.0), 255);
}

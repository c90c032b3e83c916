//! Frames like the wild benchmark's: a lit, cluttered background of discs,
//! squares, rings and strokes; one to ten tags of both families at random
//! poses and sizes (log-uniform, from barely decodable to a quarter of the
//! frame), some partly hidden by the paper's occluders; blur and sensor
//! noise. Shared by `benches/wild.rs` and the tests that need realistic
//! frames of any size.

use coppertag::Family;
use image::GrayImage;

use super::{fill_poly, Camera, Occluder, Rng, Scene, SCENARIOS};

/// Most tags in a frame (at least one).
const MAX_TAGS: u64 = 10;
/// Shortest and longest data-square side of a tag, in pixels per 1080
/// lines of image height (the wild set's range, from barely decodable to
/// a quarter of the frame).
const TAG_SIDE_PX: (f64, f64) = (22.0, 260.0);
/// Background shapes per frame: at least `CLUTTER.0`, plus up to
/// `CLUTTER.1` more.
const CLUTTER: (u64, u64) = (30, 60);
/// Chance that a tag is partly hidden by one of the paper's occluders,
/// and the fraction of its data square hidden then.
const OCCLUDED: f64 = 0.3;
const OCCLUDED_FRAC: (f64, f64) = (0.05, 0.2);
/// Gaussian blur sigma (px at 1080p) and noise sigma (grey levels) ranges.
const BLUR: (f64, f64) = (0.4, 1.4);
const NOISE: (f64, f64) = (1.0, 4.0);
/// Tries to place a tag clear of the tags already placed.
const PLACE_TRIES: usize = 20;

/// The paper's camera scaled to `height` lines (same field of view).
pub fn camera(height: u32) -> Camera {
    let k = f64::from(height) / f64::from(super::CAMERA.height);
    Camera {
        width: (f64::from(super::CAMERA.width) * k).round() as u32,
        height,
        f: super::CAMERA.f * k,
    }
}

/// A regular `n`-gon of radius `r` around `c`, squashed by `skew` along
/// its turned y axis.
fn polygon(c: [f64; 2], r: f64, n: usize, turn: f64, skew: f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|k| {
            let t = k as f64 / n as f64 * std::f64::consts::TAU + std::f64::consts::FRAC_PI_4;
            let (x, y) = (r * t.cos(), r * t.sin() * skew);
            [
                c[0] + x * turn.cos() - y * turn.sin(),
                c[1] + x * turn.sin() + y * turn.cos(),
            ]
        })
        .collect()
}

/// A lit background (a linear gradient) with clutter: discs, squares,
/// rings (a disc with a lighter disc inside) and thin strokes.
fn background(rng: &mut Rng, w: u32, h: u32) -> GrayImage {
    let base = rng.range(70.0, 180.0);
    let (gx, gy) = (rng.range(-60.0, 60.0), rng.range(-60.0, 60.0));
    let mut img = GrayImage::from_fn(w, h, |x, y| {
        let v = base + gx * f64::from(x) / f64::from(w) + gy * f64::from(y) / f64::from(h);
        image::Luma([v.clamp(0.0, 255.0) as u8])
    });
    let scale = f64::from(h) / 1080.0;
    let n = CLUTTER.0 + rng.next_u64() % (CLUTTER.1 + 1);
    for _ in 0..n {
        let c = [rng.range(0.0, f64::from(w)), rng.range(0.0, f64::from(h))];
        let r = rng.range(6.0, 160.0) * scale;
        let dark = rng.range(0.0, 90.0) as u8;
        let light = rng.range(160.0, 255.0) as u8;
        let grey = if rng.uniform() < 0.5 { dark } else { light };
        let (turn, skew) = (rng.range(0.0, 6.3), rng.range(0.3, 1.0));
        match rng.next_u64() % 4 {
            0 => fill_poly(&mut img, &polygon(c, r, 48, turn, skew), grey),
            1 => fill_poly(&mut img, &polygon(c, r, 4, turn, skew), grey),
            2 => {
                fill_poly(&mut img, &polygon(c, r, 48, turn, skew), dark);
                fill_poly(&mut img, &polygon(c, 0.6 * r, 48, turn, skew), light);
            }
            _ => {
                let t = rng.range(1.5, 6.0) * scale;
                fill_poly(&mut img, &polygon(c, r, 4, turn, t / r), grey);
            }
        }
    }
    img
}

/// A random pose of a tag in `cam`'s view, or `None` when its bounding box
/// would meet one in `taken` (pixels, grown by a margin).
fn place(rng: &mut Rng, cam: &Camera, taken: &[[f64; 4]]) -> Option<(Scene, [f64; 4])> {
    let k = f64::from(cam.height) / 1080.0;
    // log-uniform size: as many small tags as large ones.
    let side = (rng.range(TAG_SIDE_PX.0.ln(), TAG_SIDE_PX.1.ln())).exp() * k;
    let d = cam.f * super::TAG_SIDE_M / side;
    let (u, v) = (
        rng.range(0.1, 0.9) * f64::from(cam.width),
        rng.range(0.1, 0.9) * f64::from(cam.height),
    );
    let t = [(u - cam.cx()) * d / cam.f, (v - cam.cy()) * d / cam.f, d];
    let r = super::rotation(
        rng.range(-0.7, 0.7),
        rng.range(-0.7, 0.7),
        rng.range(-3.1, 3.1),
    );
    let family = if rng.uniform() < 0.5 {
        Family::ct14()
    } else {
        Family::ct8()
    };
    let span = family.max_id() - family.min_id() + 1;
    let id = family.min_id() + rng.next_u64() % span;
    let h = cam.homography(&r, t, super::TAG_SIDE_M);
    let mut s = Scene::new(family, id, cam.width, cam.height, h);
    let outline = [[-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0], [1.0, -1.0]];
    let mut bb = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for p in outline {
        let q = s.h.map(p)?;
        bb = [
            bb[0].min(q[0]),
            bb[1].min(q[1]),
            bb[2].max(q[0]),
            bb[3].max(q[1]),
        ];
    }
    let margin = 0.2 * side;
    let clear = |o: &[f64; 4]| {
        bb[2] + margin < o[0]
            || o[2] + margin < bb[0]
            || bb[3] + margin < o[1]
            || o[3] + margin < bb[1]
    };
    if !taken.iter().all(clear) {
        return None;
    }
    s.white = rng.range(170.0, 250.0) as u8;
    s.black = rng.range(5.0, 70.0) as u8;
    if rng.uniform() < OCCLUDED {
        let kind = SCENARIOS[(rng.next_u64() % SCENARIOS.len() as u64) as usize];
        let frac = rng.range(OCCLUDED_FRAC.0, OCCLUDED_FRAC.1);
        let turn = (rng.next_u64() % 4) as u32;
        let grey = rng.range(0.0, 255.0) as u8;
        s.occluders = super::occluders(kind, frac, turn, rng.uniform())
            .into_iter()
            .map(|poly| Occluder { poly, grey })
            .collect();
    }
    Some((s, bb))
}

/// One wild-like frame from `cam` and its number of tags.
pub fn wild_frame(seed: u64, cam: &Camera) -> (GrayImage, usize) {
    let mut rng = Rng::new(seed);
    let mut img = background(&mut rng, cam.width, cam.height);
    let want = 1 + rng.next_u64() % MAX_TAGS;
    let mut taken = Vec::new();
    for _ in 0..want {
        let placed = (0..PLACE_TRIES).find_map(|_| place(&mut rng, cam, &taken));
        if let Some((scene, bb)) = placed {
            scene.paint(&mut img);
            taken.push(bb);
        }
    }
    let k = f64::from(cam.height) / 1080.0;
    let blur = rng.range(BLUR.0, BLUR.1) * k;
    let mut img = imageproc::filter::gaussian_blur_f32(&img, blur as f32);
    let noise = rng.range(NOISE.0, NOISE.1);
    for p in img.pixels_mut() {
        let v = f64::from(p.0[0]) + rng.gauss() * noise;
        p.0[0] = v.round().clamp(0.0, 255.0) as u8;
    }
    (img, taken.len())
}

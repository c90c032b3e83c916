//! The ground-truth corners are where the rendered pixels put them.
//!
//! A large marker is rendered without noise (ink 0, paper 1) and the edges of
//! its marker square are measured from the pixels alone: in each pixel row
//! (or column) across an edge, the white area of a window straddling the
//! edge equals the distance from the window's side to the edge at the row's
//! centre, exactly for a straight edge under exact-area anti-aliasing. Lines
//! (no distortion) or local quadratics (with distortion: edges are curves)
//! fitted to those positions are intersected, and the intersections must lie
//! within 0.02 px of the ground-truth corners.

use std::path::Path;

use coppertag_synth::coverage::Rasterizer;
use coppertag_synth::scene::MarkerTruth;
use coppertag_synth::DatasetSpec;
use image::GrayImage;

const TOLERANCE_PX: f64 = 0.02;
/// Half-width of the window across an edge, pixels.
const HALF_WINDOW: i64 = 6;
/// Rows this close to a corner see the other edge: skipped.
const CORNER_GAP: f64 = 10.0;

fn render(
    system: &str,
    rotation: [f64; 3],
    translation: [f64; 3],
    distortion: [f64; 5],
) -> (GrayImage, MarkerTruth) {
    let text = format!(
        r#"
[camera]
width = 1600
height = 1400
fx = 3000.0
fy = 3010.0
cx = 801.3
cy = 699.7
distortion = {distortion:?}

[print]
ink = 0.0
paper = 1.0

[background]
kind = "flat"
level = 0.5

[[markers]]
system = "{system}"
id = 3
size_m = 0.1
translation = {translation:?}
rotation = {rotation:?}
"#
    );
    let spec = DatasetSpec::from_toml(&text, Path::new("geometry-test.toml")).unwrap();
    let out = spec
        .scene(0)
        .unwrap()
        .render(&mut Rasterizer::new())
        .unwrap();
    let truth = out.markers[0].clone();
    (out.image, truth)
}

/// Edge positions measured along one edge from `a` to `b` (pixel-centre
/// coordinates), skipping `from` and `to` pixels at its ends: points
/// `(along, across)` where `along` is the row (or column) coordinate and
/// `across` the edge's position in it. `vertical` is true when rows were
/// scanned (the edge is mostly vertical).
fn edge_samples(
    img: &GrayImage,
    a: [f64; 2],
    b: [f64; 2],
    from: f64,
    to: f64,
) -> (bool, Vec<(f64, f64)>) {
    let vertical = (b[1] - a[1]).abs() > (b[0] - a[0]).abs();
    // Work in (along, across) = (y, x) for vertical edges, (x, y) otherwise.
    let sw = |p: [f64; 2]| if vertical { (p[1], p[0]) } else { (p[0], p[1]) };
    let (a_al, a_ac) = sw(a);
    let (b_al, b_ac) = sw(b);
    let (lo, hi) = (a_al.min(b_al), a_al.max(b_al));
    let px = |al: i64, ac: i64| -> f64 {
        let (x, y) = if vertical { (ac, al) } else { (al, ac) };
        f64::from(img.get_pixel(x as u32, y as u32).0[0]) / 255.0
    };
    let mut out = Vec::new();
    let mut al = (lo + from).ceil() as i64;
    while (al as f64) <= hi - to {
        let t = (al as f64 - a_al) / (b_al - a_al);
        let guess = a_ac + t * (b_ac - a_ac);
        let (i0, i1) = (
            guess.round() as i64 - HALF_WINDOW,
            guess.round() as i64 + HALF_WINDOW,
        );
        let white: f64 = (i0..=i1).map(|i| px(al, i)).sum();
        // The white side: towards the centre for CopperTag (white data
        // square), away from it for peers (white quiet zone), told by the
        // pixel at the window's far end.
        let white_high = px(al, i1) > px(al, i0);
        let pos = if white_high {
            i1 as f64 + 0.5 - white
        } else {
            i0 as f64 - 0.5 + white
        };
        out.push((al as f64, pos));
        al += 1;
    }
    (vertical, out)
}

/// Least-squares polynomial `across = sum c_k along^k` (degree 1 or 2),
/// centred at `origin` for conditioning.
fn fit(samples: &[(f64, f64)], degree: usize, origin: f64) -> Vec<f64> {
    let n = degree + 1;
    let a = nalgebra::DMatrix::from_fn(samples.len(), n, |r, k| {
        (samples[r].0 - origin).powi(k as i32)
    });
    let b = nalgebra::DVector::from_iterator(samples.len(), samples.iter().map(|s| s.1));
    let c = a.svd(true, true).solve(&b, 1e-12).expect("least squares");
    c.iter().copied().collect()
}

/// A fitted edge curve as a function of the point: signed residual.
struct Curve {
    vertical: bool,
    coef: Vec<f64>,
    origin: f64,
    rms: f64,
}

impl Curve {
    fn new(vertical: bool, samples: &[(f64, f64)], degree: usize) -> Self {
        let origin = samples.iter().map(|s| s.0).sum::<f64>() / samples.len() as f64;
        let coef = fit(samples, degree, origin);
        let mut c = Curve {
            vertical,
            coef,
            origin,
            rms: 0.0,
        };
        c.rms = (samples
            .iter()
            .map(|&(s, v)| (c.across(s) - v).powi(2))
            .sum::<f64>()
            / samples.len() as f64)
            .sqrt();
        c
    }
    fn across(&self, along: f64) -> f64 {
        let u = along - self.origin;
        self.coef
            .iter()
            .enumerate()
            .map(|(k, c)| c * u.powi(k as i32))
            .sum()
    }
    /// Residual of a point: its across coordinate minus the curve's.
    fn residual(&self, p: [f64; 2]) -> f64 {
        let (al, ac) = if self.vertical {
            (p[1], p[0])
        } else {
            (p[0], p[1])
        };
        ac - self.across(al)
    }
}

/// Intersection of two curves by Newton's method from `start`.
fn intersect(c1: &Curve, c2: &Curve, start: [f64; 2]) -> [f64; 2] {
    let mut p = start;
    for _ in 0..50 {
        let f = [c1.residual(p), c2.residual(p)];
        let h = 1e-6;
        let d = |c: &Curve, k: usize| {
            let mut q = p;
            q[k] += h;
            (c.residual(q) - c.residual(p)) / h
        };
        let j = [[d(c1, 0), d(c1, 1)], [d(c2, 0), d(c2, 1)]];
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        let dx = (f[0] * j[1][1] - f[1] * j[0][1]) / det;
        let dy = (j[0][0] * f[1] - j[1][0] * f[0]) / det;
        p = [p[0] - dx, p[1] - dy];
        if dx.abs() + dy.abs() < 1e-12 {
            break;
        }
    }
    p
}

/// Measures the four corners: edge `e` joins corner `e` to corner `e + 1`
/// (TL-BL, BL-BR, BR-TR, TR-TL). Without distortion one line per edge over
/// its middle; with distortion one quadratic per edge end, fitted over the
/// `local` pixels next to the corner.
fn measured_corners(img: &GrayImage, t: &MarkerTruth, local: Option<f64>) -> [[f64; 2]; 4] {
    let c = t.corners;
    // curves[e] = (curve near corner e, curve near corner e + 1).
    let mut curves: Vec<(Curve, Curve)> = Vec::new();
    for e in 0..4 {
        let (a, b) = (c[e], c[(e + 1) % 4]);
        match local {
            None => {
                let (v, s) = edge_samples(img, a, b, CORNER_GAP, CORNER_GAP);
                assert!(s.len() > 100);
                let line = Curve::new(v, &s, 1);
                let line2 = Curve::new(v, &s, 1);
                assert!(line.rms < 0.01, "edge {e}: rms {}", line.rms);
                curves.push((line, line2));
            }
            Some(len) => {
                let (v, s) = edge_samples(img, a, b, CORNER_GAP, CORNER_GAP);
                let (al_a, al_b) = if v { (a[1], b[1]) } else { (a[0], b[0]) };
                let near = |al0: f64| -> Vec<(f64, f64)> {
                    s.iter()
                        .copied()
                        .filter(|&(al, _)| (al - al0).abs() <= len)
                        .collect()
                };
                let qa = Curve::new(v, &near(al_a), 2);
                let qb = Curve::new(v, &near(al_b), 2);
                assert!(
                    qa.rms < 0.01 && qb.rms < 0.01,
                    "edge {e}: rms {} {}",
                    qa.rms,
                    qb.rms
                );
                curves.push((qa, qb));
            }
        }
    }
    std::array::from_fn(|k| {
        // Corner k ends edge k - 1 and starts edge k.
        let prev = &curves[(k + 3) % 4].1;
        let next = &curves[k].0;
        intersect(prev, next, c[k])
    })
}

fn check(system: &str, rotation: [f64; 3], translation: [f64; 3], distortion: [f64; 5]) -> f64 {
    let (img, truth) = render(system, rotation, translation, distortion);
    assert!(truth.side_px > 250.0, "large marker: {}", truth.side_px);
    let local = distortion.iter().any(|&d| d != 0.0).then_some(90.0);
    let got = measured_corners(&img, &truth, local);
    let mut worst = 0.0f64;
    for (k, (g, t)) in got.iter().zip(&truth.corners).enumerate() {
        let err = (g[0] - t[0]).hypot(g[1] - t[1]);
        assert!(
            err < TOLERANCE_PX,
            "{system} rot {rotation:?} dist {distortion:?}: corner {k} measured {g:?}, truth {t:?}, error {err:.4} px"
        );
        worst = worst.max(err);
    }
    worst
}

const POSES: [([f64; 3], [f64; 3]); 3] = [
    ([0.0, 0.0, 0.0], [0.0013, -0.0021, 0.5]),
    ([0.21, -0.33, 0.37], [0.011, 0.007, 0.47]),
    ([-0.3, 0.18, -1.1], [-0.017, 0.012, 0.52]),
];

#[test]
fn corners_from_pixels_match_truth_without_distortion() {
    let mut worst = 0.0f64;
    for (rot, t) in POSES {
        worst = worst.max(check("coppertag", rot, t, [0.0; 5]));
        worst = worst.max(check("apriltag3", rot, t, [0.0; 5]));
    }
    eprintln!("worst corner error without distortion: {worst:.4} px");
}

#[test]
fn corners_from_pixels_match_truth_with_distortion() {
    let dist = [-0.25, 0.12, 0.0007, -0.0005, -0.02];
    let mut worst = 0.0f64;
    for (rot, t) in POSES {
        // Off-centre, where distortion bends the edges most.
        let t = [t[0] + 0.06, t[1] - 0.05, t[2]];
        worst = worst.max(check("coppertag", rot, t, dist));
    }
    eprintln!("worst corner error with distortion: {worst:.4} px");
}

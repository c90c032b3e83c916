//! Test scenes: a CopperTag seen through a pinhole camera, rendered by
//! supersampling the vector tag geometry (`coppertag::geometry`), with
//! optional occluders, blur and noise, and exact ground-truth corners.
//!
//! The detector crate cannot use the synth crate (synth depends on it), so
//! this is a small independent renderer: each output pixel is the average
//! of a 4 x 4 grid of point samples (a pixel spans [x - 0.5, x + 0.5]),
//! each sample mapped to tag units through the inverse homography and
//! painted by the last shape, in painting order, that contains it.
#![allow(dead_code)]

use coppertag::geometry::{tag_shapes, Element, Paint, Shape, CORNERS};
use coppertag::homography::Homography;
use coppertag::Family;
use image::GrayImage;
use nalgebra::{Matrix3, Vector3};

pub mod wild;

/// The paper's camera: 1920 x 1080, fx = fy = 2730 px.
#[derive(Debug, Clone, Copy)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub f: f64,
}

pub const CAMERA: Camera = Camera {
    width: 1920,
    height: 1080,
    f: 2730.0,
};

/// Data-square side of the paper's 0.1 m printed tag.
pub const TAG_SIDE_M: f64 = 0.05;

impl Camera {
    pub fn cx(&self) -> f64 {
        (f64::from(self.width) - 1.0) / 2.0
    }
    pub fn cy(&self) -> f64 {
        (f64::from(self.height) - 1.0) / 2.0
    }
    /// Homography from tag units (data square side 1) to pixel-centre
    /// coordinates for a tag of side `s` metres at rotation `r`,
    /// translation `t` (camera frame, metres).
    pub fn homography(&self, r: &Matrix3<f64>, t: [f64; 3], s: f64) -> Homography {
        let k = Matrix3::new(
            self.f,
            0.0,
            self.cx(),
            0.0,
            self.f,
            self.cy(),
            0.0,
            0.0,
            1.0,
        );
        let m = Matrix3::from_columns(&[
            r.column(0) * s,
            r.column(1) * s,
            Vector3::new(t[0], t[1], t[2]),
        ]);
        Homography::from_matrix(k * m)
    }
}

/// Rotation about x, then y, then z (radians).
pub fn rotation(ax: f64, ay: f64, az: f64) -> Matrix3<f64> {
    // nalgebra's roll-pitch-yaw is Rz(az) * Ry(ay) * Rx(ax).
    nalgebra::Rotation3::from_euler_angles(ax, ay, az).into_inner()
}

/// A polygon painted over the tag, in tag units (on the tag plane).
#[derive(Debug, Clone)]
pub struct Occluder {
    pub poly: Vec<[f64; 2]>,
    pub grey: u8,
}

/// One scene.
#[derive(Debug, Clone)]
pub struct Scene {
    pub width: u32,
    pub height: u32,
    pub family: &'static Family,
    pub id: u64,
    /// Tag units to pixels.
    pub h: Homography,
    pub occluders: Vec<Occluder>,
    /// Paper white and ink black grey levels.
    pub white: u8,
    pub black: u8,
    /// Background grey level.
    pub background: u8,
    /// Gaussian blur sigma (pixels), 0 for none.
    pub blur: f32,
    /// Gaussian noise sigma (grey levels).
    pub noise: f64,
    pub seed: u64,
}

impl Scene {
    pub fn new(family: &'static Family, id: u64, width: u32, height: u32, h: Homography) -> Self {
        Scene {
            width,
            height,
            family,
            id,
            h,
            occluders: Vec::new(),
            white: 230,
            black: 25,
            background: 150,
            blur: 0.0,
            noise: 0.0,
            seed: 1,
        }
    }

    /// Ground-truth corners TL, BL, BR, TR.
    pub fn corners(&self) -> [[f64; 2]; 4] {
        CORNERS.map(|c| self.h.map(c).unwrap())
    }

    pub fn render(&self) -> GrayImage {
        let mut img =
            GrayImage::from_pixel(self.width, self.height, image::Luma([self.background]));
        self.paint(&mut img);
        if self.blur > 0.0 {
            img = blur_around(&img, self.blur, self.painted_box(), self.background);
        }
        if self.noise > 0.0 {
            let mut rng = Rng::new(self.seed);
            for p in img.pixels_mut() {
                let v = f64::from(p.0[0]) + rng.gauss() * self.noise;
                p.0[0] = v.round().clamp(0.0, 255.0) as u8;
            }
        }
        img
    }

    /// The pixels [`Scene::paint`] may change, `[xa, xb) x [ya, yb)`: the
    /// bounding box of the printed tag and its occluders, a pixel grown.
    pub fn painted_box(&self) -> [u32; 4] {
        // Bounding box of the printed tag (and occluders) in pixels.
        let mut outline: Vec<[f64; 2]> = vec![[-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0], [1.0, -1.0]];
        for o in &self.occluders {
            outline.extend(o.poly.iter().copied());
        }
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in &outline {
            if let Some(q) = self.h.map(*p) {
                x0 = x0.min(q[0]);
                y0 = y0.min(q[1]);
                x1 = x1.max(q[0]);
                y1 = y1.max(q[1]);
            }
        }
        let xa = (x0.floor() - 1.0).max(0.0) as u32;
        let ya = (y0.floor() - 1.0).max(0.0) as u32;
        let xb = ((x1.ceil() + 1.0).max(0.0) as u32).min(self.width);
        let yb = ((y1.ceil() + 1.0).max(0.0) as u32).min(self.height);
        [xa, ya, xb, yb]
    }

    /// Paints the tag and its occluders over `img` (which must be
    /// `width` x `height`), without blur or noise: several scenes painted
    /// into one image make a frame with several tags. Samples off the
    /// printed tag keep the pixel already in `img` (the plain background
    /// in [`Scene::render`]).
    pub fn paint(&self, img: &mut GrayImage) {
        let painter = TagPainter::new(self.family, self.id);
        let inv = Homography::from_matrix(self.h.matrix().try_inverse().unwrap());
        let [xa, ya, xb, yb] = self.painted_box();
        let value = |x: f64, y: f64, under: f64| -> f64 {
            let Some(t) = inv.map([x, y]) else {
                return under;
            };
            for o in self.occluders.iter().rev() {
                if in_poly(&o.poly, t) {
                    return f64::from(o.grey);
                }
            }
            if t[0].abs() > 1.0 || t[1].abs() > 1.0 {
                return under;
            }
            if painter.black(t) {
                f64::from(self.black)
            } else {
                f64::from(self.white)
            }
        };
        for y in ya..yb {
            for x in xa..xb {
                let (fx, fy) = (f64::from(x), f64::from(y));
                let under = f64::from(img.get_pixel(x, y).0[0]);
                let value = |x: f64, y: f64| value(x, y, under);
                // Adaptive supersampling: uniform pixels need one sample.
                let c = [
                    value(fx - 0.45, fy - 0.45),
                    value(fx + 0.45, fy - 0.45),
                    value(fx - 0.45, fy + 0.45),
                    value(fx + 0.45, fy + 0.45),
                    value(fx, fy),
                ];
                let v = if c.iter().all(|&v| v == c[0]) {
                    c[0]
                } else {
                    let mut s = 0.0;
                    for j in 0..4 {
                        for i in 0..4 {
                            s += value(
                                fx - 0.5 + (f64::from(i) + 0.5) / 4.0,
                                fy - 0.5 + (f64::from(j) + 0.5) / 4.0,
                            );
                        }
                    }
                    s / 16.0
                };
                img.put_pixel(x, y, image::Luma([v.round().clamp(0.0, 255.0) as u8]));
            }
        }
    }
}

/// Point-in-shape painter for one tag.
pub struct TagPainter {
    elements: Vec<Element>,
    /// Per element, the bounding box (x0, y0, x1, y1) of each stroke of
    /// a [`Shape::Strokes`], grown by half the stroke width.
    boxes: Vec<Vec<[f64; 4]>>,
    cells: Vec<bool>,
    n: usize,
}

impl TagPainter {
    pub fn new(family: &Family, id: u64) -> Self {
        let elements = tag_shapes(family, id).unwrap();
        let cells = coppertag::grid_code::encode_cells(family, id).unwrap();
        let boxes = elements
            .iter()
            .map(|e| match &e.shape {
                Shape::Strokes { lines, width } => lines
                    .iter()
                    .map(|l| {
                        let r = width / 2.0;
                        l.iter()
                            .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, q| {
                                [
                                    b[0].min(q[0] - r),
                                    b[1].min(q[1] - r),
                                    b[2].max(q[0] + r),
                                    b[3].max(q[1] + r),
                                ]
                            })
                    })
                    .collect(),
                _ => Vec::new(),
            })
            .collect();
        TagPainter {
            elements,
            boxes,
            cells,
            n: family.grid(),
        }
    }

    /// Whether tag point `p` (tag units) is black.
    pub fn black(&self, p: [f64; 2]) -> bool {
        for (e, boxes) in self.elements.iter().zip(&self.boxes).rev() {
            if self.contains(&e.shape, boxes, p) {
                return e.paint == Paint::Black;
            }
        }
        false
    }

    fn contains(&self, s: &Shape, boxes: &[[f64; 4]], p: [f64; 2]) -> bool {
        let [x, y] = p;
        match s {
            Shape::Rect { x0, y0, x1, y1 } => x >= *x0 && x < *x1 && y >= *y0 && y < *y1,
            Shape::Disc { cx, cy, r } => (x - cx).powi(2) + (y - cy).powi(2) < r * r,
            Shape::Annulus {
                cx,
                cy,
                r_in,
                r_out,
            } => {
                let d2 = (x - cx).powi(2) + (y - cy).powi(2);
                d2 >= r_in * r_in && d2 < r_out * r_out
            }
            Shape::Rects(_) => {
                let step = 1.0 / (self.n as f64 + 2.0);
                let col = ((x + 0.5) / step).floor() - 1.0;
                let row = ((y + 0.5) / step).floor() - 1.0;
                if col < 0.0 || row < 0.0 || col >= self.n as f64 || row >= self.n as f64 {
                    return false;
                }
                // Painted cells are the black ones.
                self.cells[row as usize * self.n + col as usize]
            }
            Shape::Strokes { lines, width } => lines.iter().zip(boxes).any(|(l, b)| {
                // Most samples are far from a digit: its bounding box
                // answers them without a distance to every segment.
                (b[0]..=b[2]).contains(&x)
                    && (b[1]..=b[3]).contains(&y)
                    && l.windows(2).any(|w| seg_dist(p, w[0], w[1]) <= width / 2.0)
            }),
        }
    }
}

fn seg_dist(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let ap = [p[0] - a[0], p[1] - a[1]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if l2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1]) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((ap[0] - t * ab[0]).powi(2) + (ap[1] - t * ab[1]).powi(2)).sqrt()
}

/// Even-odd point in polygon.
pub fn in_poly(poly: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut inside = false;
    let n = poly.len();
    let mut j = n - 1;
    for i in 0..n {
        let (a, b) = (poly[i], poly[j]);
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
        {
            inside = !inside;
        }
        j = i;
    }
    inside
}

/// `gaussian_blur_f32(img, sigma)` where `img` is grey `level` outside
/// `[xa, xb) x [ya, yb)`, computed on that box grown by twice the kernel's
/// radius alone: every pixel farther from the box blurs a window of that
/// one level, summed in the same order, so it takes the value a 1 x 1
/// image of that level blurs to; and inside the grown box every window
/// reads the same levels as in the whole image (the crop's clamped edge is
/// that level too, after either pass). Blurring whole 1080p frames around
/// a small tag was a third of the occlusion and clean-sweep tests' time.
pub fn blur_around(
    img: &GrayImage,
    sigma: f32,
    [xa, ya, xb, yb]: [u32; 4],
    level: u8,
) -> GrayImage {
    use imageproc::filter::gaussian_blur_f32;
    let (w, h) = img.dimensions();
    // imageproc's kernel radius: ceil(2 sigma).
    let radius = (2.0 * sigma).ceil() as u32;
    let margin = 2 * radius + 2;
    let (cx0, cy0) = (xa.saturating_sub(margin), ya.saturating_sub(margin));
    let (cx1, cy1) = ((xb + margin).min(w), (yb + margin).min(h));
    if xa >= xb || ya >= yb || (cx0, cy0, cx1, cy1) == (0, 0, w, h) {
        return gaussian_blur_f32(img, sigma);
    }
    let far = gaussian_blur_f32(&GrayImage::from_pixel(1, 1, image::Luma([level])), sigma);
    let mut out = GrayImage::from_pixel(w, h, *far.get_pixel(0, 0));
    let crop = image::imageops::crop_imm(img, cx0, cy0, cx1 - cx0, cy1 - cy0).to_image();
    image::imageops::replace(
        &mut out,
        &gaussian_blur_f32(&crop, sigma),
        cx0.into(),
        cy0.into(),
    );
    out
}

/// Paints grey `v` on the pixels of `img` whose centres lie inside `poly`
/// (pixels), by the same even-odd test as [`in_poly`], row by row over the
/// polygon's box: a row's edge crossings are computed once, by `in_poly`'s
/// own expression, and a pixel is inside when an odd number of them lie
/// to its right, so the pixels painted are exactly those `in_poly`
/// accepts. Testing every pixel of the box against every edge was over a
/// quarter of the clutter test's time (48-gon discs of up to 180 px).
pub fn fill_poly(img: &mut GrayImage, poly: &[[f64; 2]], v: u8) {
    let (w, h) = (f64::from(img.width()), f64::from(img.height()));
    let (mut x0, mut y0) = (f64::INFINITY, f64::INFINITY);
    let (mut x1, mut y1) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
    for p in poly {
        x0 = x0.min(p[0]);
        y0 = y0.min(p[1]);
        x1 = x1.max(p[0]);
        y1 = y1.max(p[1]);
    }
    // The pixel centres within both the polygon's box and the image.
    let (x0, y0, x1, y1) = (x0.max(0.0), y0.max(0.0), x1.min(w - 1.0), y1.min(h - 1.0));
    if !(x0 <= x1 && y0 <= y1) {
        return;
    }
    let (cols, rows) = (x0 as u32..=x1 as u32, y0 as u32..=y1 as u32);
    let n = poly.len();
    let mut crossings: Vec<f64> = Vec::with_capacity(n);
    for y in rows {
        let py = f64::from(y);
        crossings.clear();
        let mut j = n.wrapping_sub(1);
        for i in 0..n {
            let (a, b) = (poly[i], poly[j]);
            if (a[1] > py) != (b[1] > py) {
                crossings.push((b[0] - a[0]) * (py - a[1]) / (b[1] - a[1]) + a[0]);
            }
            j = i;
        }
        if crossings.is_empty() {
            continue;
        }
        crossings.sort_by(f64::total_cmp);
        // Crossings at or left of the pixel: the others lie to its right.
        let mut left = 0;
        for x in cols.clone() {
            let px = f64::from(x);
            while left < crossings.len() && crossings[left] <= px {
                left += 1;
            }
            if (crossings.len() - left) % 2 == 1 {
                img.put_pixel(x, y, image::Luma([v]));
            }
        }
    }
}

/// Area of `poly` inside the data square (fraction of it), by sampling.
pub fn covered_fraction(polys: &[Vec<[f64; 2]>]) -> f64 {
    let n = 100;
    let mut c = 0;
    for j in 0..n {
        for i in 0..n {
            let p = [
                -0.5 + (i as f64 + 0.5) / n as f64,
                -0.5 + (j as f64 + 0.5) / n as f64,
            ];
            if polys.iter().any(|q| in_poly(q, p)) {
                c += 1;
            }
        }
    }
    c as f64 / (n * n) as f64
}

/// The occlusion scenarios of the paper (figure 5, table II).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Occlusion {
    /// One corner cut off.
    Triangle,
    /// One side (two corners) hidden.
    SameSide,
    /// A band across the middle, breaking two opposite sides.
    Symmetry,
    /// Two opposite corners cut off.
    Diagonal,
    /// A patch inside the data square.
    Inner,
}

pub const SCENARIOS: [Occlusion; 5] = [
    Occlusion::Triangle,
    Occlusion::SameSide,
    Occlusion::Symmetry,
    Occlusion::Diagonal,
    Occlusion::Inner,
];

fn rot_poly(poly: Vec<[f64; 2]>, quarter_turns: u32) -> Vec<[f64; 2]> {
    poly.into_iter()
        .map(|mut p| {
            for _ in 0..quarter_turns % 4 {
                p = [-p[1], p[0]];
            }
            p
        })
        .collect()
}

/// The canonical occluders of a scenario covering `frac` of the data square
/// (tag units), turned by `turn` quarter turns, clipped to the data square
/// (the polygons live in the data-square unit square). `jitter` in [0, 1)
/// moves the cut for procedural variants.
pub fn occluders(kind: Occlusion, frac: f64, turn: u32, jitter: f64) -> Vec<Vec<[f64; 2]>> {
    occluders_within(kind, frac, turn, jitter, 0.5)
}

/// Clips a polygon to the square `[-h, h]^2` (Sutherland-Hodgman).
pub fn clip_square(poly: &[[f64; 2]], h: f64) -> Vec<[f64; 2]> {
    let mut out = poly.to_vec();
    // Each edge as (axis, sign): keep points with sign * p[axis] <= h.
    for (axis, sign) in [(0usize, 1.0f64), (0, -1.0), (1, 1.0), (1, -1.0)] {
        let inp = std::mem::take(&mut out);
        let n = inp.len();
        for i in 0..n {
            let (a, b) = (inp[i], inp[(i + 1) % n]);
            let (da, db) = (sign * a[axis] - h, sign * b[axis] - h);
            if da <= 0.0 {
                out.push(a);
            }
            if (da < 0.0) != (db < 0.0) && da != db {
                let t = da / (da - db);
                out.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        if out.is_empty() {
            break;
        }
    }
    out
}

/// [`occluders`] clipped to `[-reach, reach]^2` instead: 0.5 is the data
/// square, 0.625 adds the black frame, 1 the whole printed tag.
pub fn occluders_within(
    kind: Occlusion,
    frac: f64,
    turn: u32,
    jitter: f64,
    reach: f64,
) -> Vec<Vec<[f64; 2]>> {
    const F: f64 = 3.0;
    let polys = match kind {
        Occlusion::Triangle => {
            // Cut TL along x + y = -1 + L; area L^2 / 2 (skewed by jitter).
            let l = (2.0 * frac).sqrt();
            let k = 1.0 + 0.6 * (jitter - 0.5);
            let (lx, ly) = (l * k, l / k);
            let a = [-0.5 + lx, -0.5];
            let b = [-0.5, -0.5 + ly];
            let d = [a[0] - b[0], a[1] - b[1]];
            vec![vec![
                [a[0] + F * d[0], a[1] + F * d[1]],
                [b[0] - F * d[0], b[1] - F * d[1]],
                [-F, -F],
            ]]
        }
        Occlusion::SameSide => {
            let y = -0.5 + frac;
            let tilt = 0.1 * (jitter - 0.5);
            vec![vec![
                [-F, -F],
                [F, -F],
                [F, y - tilt * F],
                [-F, y + tilt * F],
            ]]
        }
        Occlusion::Symmetry => {
            let hw = frac / 2.0;
            let c = 0.3 * (jitter - 0.5);
            vec![vec![[c - hw, -F], [c + hw, -F], [c + hw, F], [c - hw, F]]]
        }
        Occlusion::Diagonal => {
            let mut tl = occluders_within(Occlusion::Triangle, frac / 2.0, 0, jitter, 10.0);
            let br = rot_poly(tl[0].clone(), 2);
            tl.push(br);
            // Cut TR and BL instead of TL and BR on odd turns below.
            tl
        }
        Occlusion::Inner => {
            // A square patch of area frac, off centre.
            let h = frac.sqrt() / 2.0;
            let (cx, cy) = (0.12 * (jitter - 0.5), 0.1 * (0.5 - jitter));
            vec![vec![
                [cx - h, cy - h],
                [cx - h, cy + h],
                [cx + h, cy + h],
                [cx + h, cy - h],
            ]]
        }
    };
    polys
        .into_iter()
        .map(|p| clip_square(&rot_poly(p, turn), reach))
        .filter(|p| p.len() >= 3)
        .collect()
}

/// Small deterministic PRNG (xorshift64*), Box-Muller normals.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }
    pub fn gauss(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Largest distance between matching corners.
pub fn corner_errors(found: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> [f64; 4] {
    std::array::from_fn(|i| {
        ((found[i][0] - truth[i][0]).powi(2) + (found[i][1] - truth[i][1]).powi(2)).sqrt()
    })
}

/// The farthest corner of `found` from `truth` (px).
pub fn worst_corner_error(found: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> f64 {
    corner_errors(found, truth).into_iter().fold(0.0, f64::max)
}

/// The wild benchmark's rough-corner rule: a detection of a tag whose data
/// square has a mean side of `side` px is rough when some corner lies
/// farther than this (px) from the truth: 3 px or 5% of the side, the
/// larger.
pub fn rough_bound(side: f64) -> f64 {
    3.0f64.max(0.05 * side)
}

/// A scene of the paper's simulation: tag of side 0.05 m at distance `d`
/// metres, rotated by `r`, centred in a 1920 x 1080 frame.
pub fn paper_scene(family: &'static Family, id: u64, d: f64, r: &Matrix3<f64>) -> Scene {
    let h = CAMERA.homography(r, [0.0, 0.0, d], TAG_SIDE_M);
    let mut s = Scene::new(family, id, CAMERA.width, CAMERA.height, h);
    s.blur = 0.6;
    s.noise = 2.0;
    s
}

/// A scene of tag `id` of `family` whose data square is about `side_px`
/// px seen face-on, turned by `r`, centred at `(px, py)` of a 640 x 480
/// frame of the paper's camera (the wild benchmark's VGA frame size).
pub fn vga_scene(
    family: &'static Family,
    id: u64,
    side_px: f64,
    r: &Matrix3<f64>,
    px: f64,
    py: f64,
) -> Scene {
    let d = CAMERA.f * TAG_SIDE_M / side_px;
    let h = CAMERA.homography(r, [0.0, 0.0, d], TAG_SIDE_M);
    let shift = Matrix3::new(
        1.0,
        0.0,
        px - CAMERA.cx(),
        0.0,
        1.0,
        py - CAMERA.cy(),
        0.0,
        0.0,
        1.0,
    );
    Scene::new(
        family,
        id,
        640,
        480,
        Homography::from_matrix(shift * h.matrix()),
    )
}

/// One crop of a `fixtures/wild/*-crops.csv` list: its image, the id of
/// the tag in it and the tag's true corners (TL, BL, BR, TR, the crop's
/// pixel-centre coordinates).
pub struct Crop {
    pub file: String,
    pub img: image::GrayImage,
    pub id: u64,
    pub truth: [[f64; 2]; 4],
}

/// The crops of `fixtures/wild/<list>`, in the list's order.
pub fn crops(list: &str) -> Vec<Crop> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/wild");
    let list = std::fs::read_to_string(dir.join(list)).unwrap();
    list.lines()
        .skip(1)
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let v: Vec<f64> = f[2..10].iter().map(|x| x.parse().unwrap()).collect();
            Crop {
                file: f[0].to_string(),
                img: image::open(dir.join(f[0])).unwrap().to_luma8(),
                id: f[1].parse().unwrap(),
                truth: [[v[0], v[1]], [v[2], v[3]], [v[4], v[5]], [v[6], v[7]]],
            }
        })
        .collect()
}

/// Runs the detector on each crop of `fixtures/wild/<list>` ([`crops`])
/// and checks that it finds exactly that crop's tag, every corner within
/// `max_err` px of the truth; returns the detections.
pub fn crops_found(list: &str, max_err: f64) -> Vec<coppertag::Detection> {
    let mut det = coppertag::Detector::new(coppertag::DetectorConfig::default()).unwrap();
    let mut found = Vec::new();
    for c in crops(list) {
        let out = det.detect(&c.img);
        assert_eq!(out.len(), 1, "{}: {out:?}", c.file);
        let d = &out[0];
        assert_eq!(d.id, c.id, "{}", c.file);
        let err = corner_errors(&d.corners, &c.truth)
            .into_iter()
            .fold(0.0, f64::max);
        assert!(err <= max_err, "{}: a corner {err:.2} px off", c.file);
        found.push(d.clone());
    }
    found
}

/// [`crops_found`] on the `count` crops of `fixtures/wild/<list>`, each
/// of which must report a sigma for its corners (the tag's model fitted).
pub fn crops_fitted(list: &str, max_err: f64, count: usize) -> Vec<coppertag::Detection> {
    let found = crops_found(list, max_err);
    assert_eq!(found.len(), count, "{list}");
    for d in &found {
        assert!(d.corner_sigma.is_some(), "{list}: not fitted: {d:?}");
    }
    found
}

/// [`crops_fitted`], each crop read by likelihood besides (the tags whose
/// cells no code reading reads).
pub fn crops_read_by_likelihood(
    list: &str,
    max_err: f64,
    count: usize,
) -> Vec<coppertag::Detection> {
    let found = crops_fitted(list, max_err, count);
    for d in &found {
        assert!(d.likelihood, "{list}: not a likelihood reading: {d:?}");
    }
    found
}

/// One ct14 tag `id` with a data square of about `side_px` px in a
/// 640 x 480 frame, tilted by up to `tilt` radians about each axis and
/// turned at random, placed at random away from the edges, blurred by
/// `blur` px, with noise of sigma `noise` grey levels: the blurred small
/// tags of the likelihood and rim tests.
pub fn blurred_vga_scene(
    id: u64,
    side_px: f64,
    blur: f32,
    tilt: f64,
    noise: f64,
    rng: &mut Rng,
) -> Scene {
    let r = rotation(
        rng.range(-tilt, tilt),
        rng.range(-tilt, tilt),
        rng.range(0.0, std::f64::consts::TAU),
    );
    let (px, py) = (rng.range(120.0, 520.0), rng.range(120.0, 360.0));
    let mut s = vga_scene(Family::ct14(), id, side_px, &r, px, py);
    s.blur = blur;
    s.noise = noise;
    s.seed = rng.next_u64();
    s
}

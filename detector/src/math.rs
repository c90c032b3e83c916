//! Small geometry helpers shared by the detector's stages and the decoder:
//! 2-D vector operations, line intersection, the one total-least-squares
//! line fit, bilinear sampling and the working-to-full-resolution
//! coordinate map. Kept in one place so that no stage owns (or duplicates)
//! them.

use crate::view::GrayView;

/// `a - b`.
#[inline]
pub(crate) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// Dot product.
#[inline]
pub(crate) fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// z component of the cross product; negative when `b` turns anticlockwise
/// on screen (y down) from `a`.
#[inline]
pub(crate) fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Euclidean length. The square root of the sum of squares rather than
/// `f64::hypot`: image coordinates are far from overflow, and libm's
/// `hypot` (careful scaling, one call per use) took 7% of a hard frame's
/// time.
#[inline]
pub(crate) fn norm(a: [f64; 2]) -> f64 {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

/// Shortest length [`unit()`] divides by: a zero vector stays near zero
/// instead of becoming NaN.
const UNIT_MIN_NORM: f64 = 1e-12;

/// `v` scaled to unit length (a zero vector stays near zero, not NaN).
#[inline]
pub(crate) fn unit(v: [f64; 2]) -> [f64; 2] {
    let n = norm(v).max(UNIT_MIN_NORM);
    [v[0] / n, v[1] / n]
}

/// Integer pixel position as a point.
#[inline]
pub(crate) fn fp(p: [i32; 2]) -> [f64; 2] {
    [f64::from(p[0]), f64::from(p[1])]
}

/// Two lines whose directions' sine is below this (relative to their
/// lengths) are treated as parallel by [`intersect`].
const PARALLEL_SIN: f64 = 1e-6;

/// Intersection of the line through `p` with direction `d` and the line
/// through `q` with direction `e`; `None` when (nearly) parallel.
#[inline]
pub(crate) fn intersect(p: [f64; 2], d: [f64; 2], q: [f64; 2], e: [f64; 2]) -> Option<[f64; 2]> {
    let den = cross(d, e);
    if den.abs() < PARALLEL_SIN * norm(d) * norm(e) {
        return None;
    }
    let t = cross(sub(q, p), e) / den;
    Some([p[0] + t * d[0], p[1] + t * d[1]])
}

/// A line from [`fit_line`]: the centroid of the points and a unit
/// direction (its sign is arbitrary).
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineFit {
    /// Centroid of the fitted points.
    pub centre: [f64; 2],
    /// Unit direction.
    pub dir: [f64; 2],
}

/// Total least squares line through `pts` (the principal axis of their
/// scatter matrix, in closed form); `None` for fewer than two points.
pub(crate) fn fit_line<I>(pts: I) -> Option<LineFit>
where
    I: Iterator<Item = [f64; 2]> + Clone,
{
    let (mut sx, mut sy, mut count) = (0.0, 0.0, 0usize);
    for p in pts.clone() {
        sx += p[0];
        sy += p[1];
        count += 1;
    }
    if count < 2 {
        return None;
    }
    let m = count as f64;
    let c = [sx / m, sy / m];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = sub(p, c);
        sxx += d[0] * d[0];
        sxy += d[0] * d[1];
        syy += d[1] * d[1];
    }
    let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some(LineFit {
        centre: c,
        dir: [th.cos(), th.sin()],
    })
}

/// Bilinear sample of an 8-bit image at a pixel-centre coordinate; `None`
/// outside the image.
#[inline]
pub(crate) fn sample_bilinear(img: &GrayView<'_>, x: f64, y: f64) -> Option<f64> {
    inside_image(img, [x, y]).then(|| bilinear_inside(img)(x, y))
}

/// Whether pixel-centre point `p` lies in `img` (never in an empty one).
#[inline]
fn inside_image(img: &GrayView<'_>, p: [f64; 2]) -> bool {
    let (w, h) = (img.width(), img.height());
    w > 0 && h > 0 && p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= (w - 1) as f64 && p[1] <= (h - 1) as f64
}

/// The bilinear sampler of [`sample_bilinear`] for points already known
/// to lie in `img` ([`inside_image`]); the image's sizes are read once,
/// for the many samples of a profile.
///
/// The pixel right of the upper-left one, `min(x0 + 1, w - 1)`, is
/// `x0 + 1` on an image two or more pixels wide (`x0 <= w - 2`) and `x0`
/// itself on one a pixel wide; likewise the row below. So the four pixels
/// lie at offsets fixed per image from the upper-left one, taken once
/// here rather than clamped at every sample: bilinear samples are a sixth
/// of a cluttered frame's instructions, and the clamps and row products
/// about an eighth of theirs. The pixels and the arithmetic are the same.
#[inline(always)]
fn bilinear_inside<'a>(img: &GrayView<'a>) -> impl Fn(f64, f64) -> f64 + 'a {
    let (w, h, stride, raw) = (img.width(), img.height(), img.stride(), img.data());
    let (xmax, ymax) = (w.saturating_sub(2), h.saturating_sub(2));
    let right = usize::from(w > 1);
    let down = if h > 1 { stride } else { 0 };
    move |x, y| {
        // x, y >= 0 here, so truncation is floor.
        let x0 = (x as u32).min(xmax);
        let y0 = (y as u32).min(ymax);
        let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
        let top_left = y0 as usize * stride + x0 as usize;
        let bottom_left = top_left + down;
        let p = |i: usize| GREY_F64[usize::from(raw[i])];
        let top = p(top_left) * (1.0 - fx) + p(top_left + right) * fx;
        let bot = p(bottom_left) * (1.0 - fx) + p(bottom_left + right) * fx;
        top * (1.0 - fy) + bot * fy
    }
}

/// Bilinear samples of `img` at the pixel-centre point `(x, y)` and one
/// pixel either side of it along each axis, `[centre, left, right, up,
/// down]`, the values [`sample_bilinear`] gives there; `None` unless all
/// five lie in the image (for which the four outer ones suffice).
///
/// Why not five calls: the print alignment's Gauss-Newton steps take an
/// image gradient at every template point, and those samples were a tenth
/// of a cluttered frame's time, most of it spent locating and
/// bounds-testing each sample's pixels. Here the pixels are read once, as
/// the 4 x 4 block around the centre, and the five samples are
/// interpolated from it with the centre's offsets within its pixel, after
/// checking that those are the offsets [`sample_bilinear`] computes for
/// each shifted point, so that the values are the same to the last bit.
/// Where they are not (a shifted coordinate rounded), and where the block
/// would reach past the image, the five points are sampled one by one.
pub(crate) fn bilinear_cross(img: &GrayView<'_>, x: f64, y: f64) -> Option<[f64; 5]> {
    let shifted = [
        [x, y],
        [x - 1.0, y],
        [x + 1.0, y],
        [x, y - 1.0],
        [x, y + 1.0],
    ];
    if !shifted[1..].iter().all(|&p| inside_image(img, p)) {
        return None;
    }
    let one_by_one = || Some(shifted.map(|p| bilinear_inside(img)(p[0], p[1])));
    let (w, h) = (img.width(), img.height());
    // 1 <= x <= w - 2 here (and so for y), so truncation is floor and the
    // block, from the pixel before the centre's, starts in the image. It
    // ends past the image only where x (or y) is its largest, w - 2, a
    // point left to the plain sampler.
    let (bx, by) = (x as u32 - 1, y as u32 - 1);
    if bx + 3 >= w || by + 3 >= h {
        return one_by_one();
    }
    let (stride, raw) = (img.stride(), img.data());
    let mut block = [[0.0; 4]; 4];
    for (r, out) in block.iter_mut().enumerate() {
        let at = (by as usize + r) * stride + bx as usize;
        let pixels: &[u8; 4] = raw.get(at..at + 4)?.try_into().ok()?;
        *out = pixels.map(|v| GREY_F64[usize::from(v)]);
    }
    // Each sample's offsets within its pixel, as `bilinear_inside`
    // computes them, are the centre's when its shifted coordinates are
    // exact (they are but where x + 1 rounds into the next power of two);
    // otherwise each sample is taken on its own.
    let (fx, fy) = (x - f64::from(bx + 1), y - f64::from(by + 1));
    let same = |v: f64, at: u32, f: f64| v - f64::from(at) == f;
    if !(same(x - 1.0, bx, fx)
        && same(x + 1.0, bx + 2, fx)
        && same(y - 1.0, by, fy)
        && same(y + 1.0, by + 2, fy))
    {
        return one_by_one();
    }
    let (gx, gy) = (1.0 - fx, 1.0 - fy);
    let at = |r: usize, c: usize| {
        let top = block[r][c] * gx + block[r][c + 1] * fx;
        let bot = block[r + 1][c] * gx + block[r + 1][c + 1] * fx;
        top * gy + bot * fy
    };
    Some([at(1, 1), at(1, 0), at(1, 2), at(0, 1), at(2, 1)])
}

/// Every grey level as an `f64`: a table look-up is cheaper than the
/// integer-to-float conversion in the bilinear samplers' inner loops (four
/// per sample), and gives the same values.
static GREY_F64: [f64; 256] = {
    let mut t = [0.0; 256];
    let mut i = 0;
    while i < 256 {
        t[i] = i as f64;
        i += 1;
    }
    t
};

/// The bilinear sampler of [`sample_bilinear`], without its bounds test,
/// for points inside the convex quad `q` (px), when all four of its
/// corners lie in `img` (so every point of it does): `None` otherwise.
/// For the many samples of a whole square (`pitch`), where the test and
/// the `Option` per point were most of a sample's cost.
pub(crate) fn sampler_within<'a>(
    img: &GrayView<'a>,
    q: &[[f64; 2]; 4],
) -> Option<impl Fn(f64, f64) -> f64 + 'a> {
    q.iter()
        .all(|&p| inside_image(img, p))
        .then(|| bilinear_inside(img))
}

/// Bilinear samples of `img` along a straight profile: at
/// `c + (k step) n` for `k` in `k0..=k1`, in order, appended to `out`.
/// `false`, with nothing appended, when any of them falls outside the
/// image.
///
/// Why not [`sample_bilinear`] per point: edge profiles (refinement and the
/// model fit) are a fifth of a frame's time, and most of a sample's cost
/// there was the bounds test and the `Option`. The points lie on a
/// segment, and each coordinate `c + (k step) n` is monotone in `k` in
/// floating point too (rounded products and sums are monotone), so the
/// two end points inside the image put every point inside; the samples
/// are then the same values [`sample_bilinear`] gives, computed the same
/// way.
pub(crate) fn sample_profile(
    img: &GrayView<'_>,
    c: [f64; 2],
    n: [f64; 2],
    step: f64,
    (k0, k1): (i32, i32),
    out: &mut Vec<f64>,
) -> bool {
    let at = |k: i32| {
        let t = f64::from(k) * step;
        [c[0] + t * n[0], c[1] + t * n[1]]
    };
    if k1 < k0 {
        return true;
    }
    if !(inside_image(img, at(k0)) && inside_image(img, at(k1))) {
        return false;
    }
    let sample = bilinear_inside(img);
    let start = out.len();
    out.resize(start + (k1 - k0) as usize + 1, 0.0);
    for (slot, k) in out[start..].iter_mut().zip(k0..) {
        let [x, y] = at(k);
        *slot = sample(x, y);
    }
    true
}

/// Working-image coordinates (after downsampling by `scale`) to full
/// resolution, both pixel-centre: working pixel `x` covers full pixels
/// `scale x .. scale x + scale - 1`, whose centre is
/// `scale x + (scale - 1) / 2`.
#[inline]
pub(crate) fn to_full(p: [f64; 2], scale: f64) -> [f64; 2] {
    let o = (scale - 1.0) / 2.0;
    [p[0] * scale + o, p[1] * scale + o]
}

/// Mean of the four corners of quad `q`.
pub(crate) fn centroid(q: &[[f64; 2]; 4]) -> [f64; 2] {
    [
        q.iter().map(|p| p[0]).sum::<f64>() / 4.0,
        q.iter().map(|p| p[1]).sum::<f64>() / 4.0,
    ]
}

/// Mean length of the four sides of quad `q`.
pub(crate) fn mean_side(q: &[[f64; 2]; 4]) -> f64 {
    (0..4).map(|i| norm(sub(q[(i + 1) % 4], q[i]))).sum::<f64>() / 4.0
}

/// Whether `p` is inside (or on the border of) the convex quad `q`.
pub(crate) fn inside(q: &[[f64; 2]; 4], p: [f64; 2]) -> bool {
    let mut sign = 0.0;
    for i in 0..4 {
        let a = q[i];
        let b = q[(i + 1) % 4];
        let c = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        if c == 0.0 {
            continue;
        }
        if sign == 0.0 {
            sign = c.signum();
        } else if c.signum() != sign {
            return false;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_line_through_noisy_points() {
        let pts = [[0.0, 1.0], [1.0, 2.1], [2.0, 2.9], [3.0, 4.0]];
        let f = fit_line(pts.iter().copied()).unwrap();
        assert!((f.dir[1] / f.dir[0] - 1.0).abs() < 0.05, "{f:?}");
        assert!((f.centre[0] - 1.5).abs() < 1e-12 && (f.centre[1] - 2.5).abs() < 1e-12);
        assert!(fit_line([[1.0, 1.0]].into_iter()).is_none());
    }

    #[test]
    fn intersects_and_rejects_parallel_lines() {
        let x = intersect([0.0, 0.0], [1.0, 0.0], [2.0, -1.0], [0.0, 1.0]).unwrap();
        assert_eq!(x, [2.0, 0.0]);
        assert!(intersect([0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [2.0, 0.0]).is_none());
    }

    #[test]
    fn samples_bilinearly_with_a_stride() {
        // 2 x 2 image in a buffer with stride 3 (the third byte is padding).
        let data = [0u8, 100, 255, 100, 200, 255];
        let v = GrayView::new(&data, 2, 2, 3).unwrap();
        assert_eq!(sample_bilinear(&v, 0.5, 0.5), Some(100.0));
        assert_eq!(sample_bilinear(&v, 1.0, 1.0), Some(200.0));
        assert_eq!(sample_bilinear(&v, 1.5, 0.0), None);
    }

    /// The sampler finds a sample's four pixels at offsets fixed per
    /// image; they must be the pixels a clamp to the last column and row
    /// picks, on images one pixel wide or tall too.
    #[test]
    fn samples_as_a_clamped_bilinear_on_images_of_any_size() {
        for (w, h, stride) in [
            (1u32, 1u32, 1usize),
            (1, 4, 2),
            (5, 1, 5),
            (3, 2, 4),
            (7, 5, 9),
        ] {
            let data: Vec<u8> = (0..stride * h as usize)
                .map(|i| (i * 53 % 251) as u8)
                .collect();
            let v = GrayView::new(&data, w, h, stride).unwrap();
            let px = |x: u32, y: u32| f64::from(data[y as usize * stride + x as usize]);
            for k in 0..=40 {
                for l in 0..=40 {
                    let x = f64::from(k) / 40.0 * f64::from(w - 1);
                    let y = f64::from(l) / 40.0 * f64::from(h - 1);
                    let (x0, y0) = (
                        (x as u32).min(w.saturating_sub(2)),
                        (y as u32).min(h.saturating_sub(2)),
                    );
                    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
                    let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
                    let top = px(x0, y0) * (1.0 - fx) + px(x1, y0) * fx;
                    let bot = px(x0, y1) * (1.0 - fx) + px(x1, y1) * fx;
                    let want = top * (1.0 - fy) + bot * fy;
                    assert_eq!(sample_bilinear(&v, x, y), Some(want), "{w}x{h} at {x}, {y}");
                }
            }
        }
    }

    #[test]
    fn samples_a_profile_as_point_by_point() {
        // A 7 x 5 gradient with a stride of 9; profiles at odd angles, some
        // ending exactly on the border, some leaving the image.
        let data: Vec<u8> = (0..9 * 5).map(|i| (i * 37 % 251) as u8).collect();
        let v = GrayView::new(&data, 7, 5, 9).unwrap();
        for (c, n, step, ks) in [
            ([3.2, 2.1], [0.6, 0.8], 0.5, (-4, 5)),
            ([0.0, 0.0], [1.0, 0.0], 1.0, (0, 6)),
            ([6.0, 4.0], [-0.28, -0.96], 0.25, (0, 16)),
            ([3.0, 2.0], [0.0, 1.0], 0.5, (-4, 5)),
            ([1.0, 1.0], [0.8, -0.6], 0.3, (-2, 9)),
        ] {
            let one: Option<Vec<f64>> = (ks.0..=ks.1)
                .map(|k| {
                    let t = f64::from(k) * step;
                    sample_bilinear(&v, c[0] + t * n[0], c[1] + t * n[1])
                })
                .collect();
            let mut out = vec![];
            let inside = sample_profile(&v, c, n, step, ks, &mut out);
            assert_eq!(inside, one.is_some(), "{c:?} {n:?}");
            if let Some(one) = one {
                assert_eq!(out, one);
            }
        }
        let mut out = vec![1.0];
        assert!(sample_profile(
            &v,
            [1.0, 1.0],
            [1.0, 0.0],
            1.0,
            (2, 1),
            &mut out
        ));
        assert_eq!(out, [1.0]);
    }

    #[test]
    fn samples_a_cross_as_point_by_point() {
        // A 7 x 5 image with a stride of 9: points inside, on every
        // border's last admissible value (1 and w - 2, where the 4 x 4
        // block reaches past the image with a zero weight), just beyond
        // it, and on the image's own border; 1.9999999999999998, whose
        // right neighbour rounds to 3.0, a pixel past the block.
        let data: Vec<u8> = (0..9 * 5).map(|i| (i * 37 % 251) as u8).collect();
        let v = GrayView::new(&data, 7, 5, 9).unwrap();
        let xs = [
            0.0,
            0.5,
            1.0,
            1.3,
            1.9999999999999998,
            2.0,
            3.75,
            4.9,
            5.0,
            5.0001,
            6.0,
            7.2,
        ];
        let ys = [
            0.0,
            0.99,
            1.0,
            1.5,
            1.9999999999999998,
            2.25,
            2.9,
            3.0,
            3.01,
            4.0,
        ];
        let mut inside = 0;
        for &x in &xs {
            for &y in &ys {
                let one: Option<Vec<f64>> = [
                    [x, y],
                    [x - 1.0, y],
                    [x + 1.0, y],
                    [x, y - 1.0],
                    [x, y + 1.0],
                ]
                .iter()
                .map(|p| sample_bilinear(&v, p[0], p[1]))
                .collect();
                let cross = bilinear_cross(&v, x, y);
                assert_eq!(cross.is_some(), one.is_some(), "({x}, {y})");
                if let (Some(c), Some(one)) = (cross, one) {
                    inside += 1;
                    assert_eq!(c.to_vec(), one, "({x}, {y})");
                }
            }
        }
        assert_eq!(inside, 7 * 6);
        // Too small for any cross.
        let tiny = GrayView::new(&data, 2, 2, 9).unwrap();
        assert_eq!(bilinear_cross(&tiny, 0.5, 0.5), None);
    }

    #[test]
    fn scales_pixel_centres() {
        assert_eq!(to_full([0.0, 0.0], 2.0), [0.5, 0.5]);
        assert_eq!(to_full([3.0, 1.0], 1.0), [3.0, 1.0]);
    }
}

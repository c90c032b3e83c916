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
#[inline(always)]
fn bilinear_inside<'a>(img: &GrayView<'a>) -> impl Fn(f64, f64) -> f64 + 'a {
    let (w, h, stride, raw) = (img.width(), img.height(), img.stride(), img.data());
    let (xmax, ymax) = (w.saturating_sub(2), h.saturating_sub(2));
    move |x, y| {
        // x, y >= 0 here, so truncation is floor.
        let x0 = (x as u32).min(xmax);
        let y0 = (y as u32).min(ymax);
        let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
        let x1 = (x0 + 1).min(w - 1) as usize;
        let y1 = (y0 + 1).min(h - 1) as usize;
        let (x0, r0, r1) = (x0 as usize, y0 as usize * stride, y1 * stride);
        let p = |i: usize| GREY_F64[usize::from(raw[i])];
        let top = p(r0 + x0) * (1.0 - fx) + p(r0 + x1) * fx;
        let bot = p(r1 + x0) * (1.0 - fx) + p(r1 + x1) * fx;
        top * (1.0 - fy) + bot * fy
    }
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
    fn scales_pixel_centres() {
        assert_eq!(to_full([0.0, 0.0], 2.0), [0.5, 0.5]);
        assert_eq!(to_full([3.0, 1.0], 1.0), [3.0, 1.0]);
    }
}

//! Stage 1: optional 2x downsampling and adaptive thresholding.
//!
//! The threshold is the local mean over a square window minus an offset
//! (the classic mean-C adaptive threshold, as in OpenCV's
//! `ADAPTIVE_THRESH_MEAN_C`). The window sums are kept as running column
//! sums updated row by row, which is the integral-image idea with O(width)
//! memory instead of O(width x height): a 20000 x 20000 frame needs no
//! 1.6 GB integral image.

use crate::view::GrayView;

/// Images smaller than this (px) in either direction are not downsampled:
/// there is nothing left to find at half their size.
pub(crate) const MIN_DOWNSAMPLE_SIZE: usize = 8;

/// Parameters of the threshold stage, from [`crate::DetectorConfig`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct ThresholdParams {
    /// Downsample 2x before thresholding (`downsample == 2`).
    pub downsample: bool,
    /// Radius of the mean window (working px): the window is
    /// `2 radius + 1` pixels square.
    pub radius: usize,
    /// A pixel is dark when more than this many grey levels below its
    /// window's mean.
    pub offset: u8,
}

/// Scale of the downsampled working image: [`downsample2`] halves both
/// sides.
pub(crate) const DOWNSAMPLE_FACTOR: f64 = 2.0;

/// The image segmentation runs on and its scale (full-resolution pixels
/// per working pixel): `img` itself, or its 2x downsampled copy (kept in
/// `small`) when `p.downsample` is set and the image is at least
/// [`MIN_DOWNSAMPLE_SIZE`] pixels each way.
pub(crate) fn working_image<'b>(
    img: GrayView<'b>,
    p: &ThresholdParams,
    small: &'b mut Vec<u8>,
) -> (GrayView<'b>, f64) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if p.downsample && w >= MIN_DOWNSAMPLE_SIZE && h >= MIN_DOWNSAMPLE_SIZE {
        let (w2, h2) = downsample2(img.data(), w, h, img.stride(), small);
        (GrayView::packed(small, w2, h2), DOWNSAMPLE_FACTOR)
    } else {
        (img, 1.0)
    }
}

/// [`adaptive_threshold`] of the working image with the stage's parameters.
pub(crate) fn threshold(
    work: &GrayView<'_>,
    p: &ThresholdParams,
    colsum: &mut Vec<u32>,
    out: &mut Vec<u8>,
) {
    adaptive_threshold(work, p.radius, p.offset, colsum, out);
}

/// 2 x 2 box downsampling of `src` (`w` x `h`, rows `stride` bytes apart)
/// into `dst`, which is resized to `(w / 2) x (h / 2)` (packed). Working
/// pixel `(x, y)` has its centre at full-resolution `(2x + 0.5, 2y + 0.5)`.
pub(crate) fn downsample2(
    src: &[u8],
    w: usize,
    h: usize,
    stride: usize,
    dst: &mut Vec<u8>,
) -> (usize, usize) {
    let (w2, h2) = (w / 2, h / 2);
    dst.clear();
    dst.resize(w2 * h2, 0);
    if w2 == 0 || h2 == 0 {
        return (w2, h2);
    }
    for (y, out) in dst.chunks_exact_mut(w2).enumerate() {
        let r0 = &src[2 * y * stride..2 * y * stride + 2 * w2];
        let r1 = &src[(2 * y + 1) * stride..(2 * y + 1) * stride + 2 * w2];
        for (x, o) in out.iter_mut().enumerate() {
            let s = u16::from(r0[2 * x])
                + u16::from(r0[2 * x + 1])
                + u16::from(r1[2 * x])
                + u16::from(r1[2 * x + 1]);
            *o = ((s + 2) >> 2) as u8;
        }
    }
    (w2, h2)
}

/// Adaptive threshold of `img` (`w` x `h`) into `out`, a `(w + 2) x (h + 2)`
/// buffer with a one-pixel zero border (what the border follower needs).
/// A pixel becomes 1 (dark, foreground) when it is more than `offset` grey
/// levels below the mean of the `(2 radius + 1)^2` window around it (the
/// window is clipped at the image border).
///
/// `colsum` is scratch space, resized here.
pub(crate) fn adaptive_threshold(
    img: &GrayView<'_>,
    radius: usize,
    offset: u8,
    colsum: &mut Vec<u32>,
    out: &mut Vec<u8>,
) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let pw = w + 2;
    out.clear();
    out.resize(pw * (h + 2), 0);
    if w == 0 || h == 0 {
        return;
    }
    let r = radius.max(1);
    colsum.clear();
    colsum.resize(w, 0);
    // Rows [top, bottom) are summed in colsum.
    let (mut top, mut bottom) = (0usize, 0usize);
    let off = u32::from(offset);
    for y in 0..h {
        let want_top = y.saturating_sub(r);
        let want_bottom = (y + r + 1).min(h);
        while bottom < want_bottom {
            let row = img.row(bottom);
            for (c, &p) in colsum.iter_mut().zip(row) {
                *c += u32::from(p);
            }
            bottom += 1;
        }
        while top < want_top {
            let row = img.row(top);
            for (c, &p) in colsum.iter_mut().zip(row) {
                *c -= u32::from(p);
            }
            top += 1;
        }
        let rows = (bottom - top) as u32;
        let row = img.row(y);
        let dst = &mut out[(y + 1) * pw + 1..(y + 1) * pw + 1 + w];
        // Horizontal running sum over colsum: clipped windows at both ends,
        // a tight loop with a constant count in between.
        let col = |x: usize| colsum[x];
        let mut sum: u32 = colsum[..(r + 1).min(w)].iter().sum();
        let mut x = 0;
        let threshold = |p: u8, sum: u32, count: u32| u8::from((u32::from(p) + off) * count < sum);
        // Left border: window [0, x + r].
        while x < w && x <= r {
            let right = (x + r + 1).min(w);
            if x > 0 && x + r < w {
                sum += col(x + r);
            }
            dst[x] = threshold(row[x], sum, rows * right as u32);
            x += 1;
        }
        // Interior: window [x - r, x + r] fully inside.
        let count = rows * (2 * r + 1) as u32;
        while x + r < w {
            sum = sum + col(x + r) - col(x - r - 1);
            dst[x] = threshold(row[x], sum, count);
            x += 1;
        }
        // Right border: window [x - r, w).
        while x < w {
            if x > r {
                sum -= col(x - r - 1);
            }
            dst[x] = threshold(row[x], sum, rows * (w - x.saturating_sub(r)) as u32);
            x += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_blocks() {
        let src = [0u8, 4, 8, 8, 0, 0, 8, 8, 100, 100, 200, 200];
        let mut dst = Vec::new();
        let (w, h) = downsample2(&src, 4, 3, 4, &mut dst);
        assert_eq!((w, h), (2, 1));
        assert_eq!(dst, vec![1, 8]);
    }

    #[test]
    fn running_sums_match_a_direct_window_mean() {
        let mut seed = 12345u64;
        for (w, h, r) in [(37, 23, 4), (5, 9, 6), (64, 3, 1), (1, 1, 3), (16, 16, 7)] {
            let img: Vec<u8> = (0..w * h)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    (seed >> 56) as u8
                })
                .collect();
            let (mut cs, mut out) = (Vec::new(), Vec::new());
            adaptive_threshold(&GrayView::packed(&img, w, h), r, 5, &mut cs, &mut out);
            for y in 0..h {
                for x in 0..w {
                    let (mut sum, mut count) = (0u32, 0u32);
                    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                        for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                            sum += u32::from(img[yy * w + xx]);
                            count += 1;
                        }
                    }
                    let want = u8::from((u32::from(img[y * w + x]) + 5) * count < sum);
                    assert_eq!(
                        out[(y + 1) * (w + 2) + x + 1],
                        want,
                        "{w}x{h} r{r} at {x},{y}"
                    );
                }
            }
        }
    }

    #[test]
    fn threshold_marks_dark_square_on_white() {
        let (w, h) = (20, 20);
        let mut img = vec![220u8; w * h];
        for y in 5..15 {
            for x in 5..15 {
                img[y * w + x] = 30;
            }
        }
        let (mut cs, mut out) = (Vec::new(), Vec::new());
        adaptive_threshold(&GrayView::packed(&img, w, h), 6, 5, &mut cs, &mut out);
        let at = |x: usize, y: usize| out[(y + 1) * (w + 2) + x + 1];
        assert_eq!(at(5, 5), 1);
        assert_eq!(at(4, 5), 0);
        assert_eq!(at(14, 14), 1);
        assert_eq!(at(15, 14), 0);
        // Border stays zero.
        assert!(out[..w + 2].iter().all(|&v| v == 0));
    }
}

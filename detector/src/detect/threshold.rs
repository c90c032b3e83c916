//! Stage 1: optional 2x downsampling and adaptive thresholding, in one
//! pass over the image.
//!
//! The threshold is the local mean over a square window minus an offset
//! (the classic mean-C adaptive threshold, as in OpenCV's
//! `ADAPTIVE_THRESH_MEAN_C`). The window sums are kept as running column
//! sums updated row by row, which is the integral-image idea (Crow,
//! "Summed-area tables for texture mapping", SIGGRAPH 1984) with O(width)
//! memory instead of O(width x height): a 20000 x 20000 frame needs no
//! 1.6 GB integral image.
//!
//! Why one pass: the stage reads every input pixel once and writes every
//! binary pixel once, so it is bound by memory traffic, not arithmetic.
//! Working row `y + radius` is downsampled (when asked) and added to the
//! column sums just before row `y` is thresholded, so the rows it reads
//! again (to add, to threshold, to subtract `2 radius + 1` rows later) are
//! still in cache. Each step is a plain loop over equal-length slices,
//! which the compiler turns into SIMD code; the one serial step is the
//! prefix sum along a row. The loops use wrapping arithmetic although no
//! value can overflow (bounds at each loop): with overflow checks on (the
//! `ci` profile's tests and speed gate), checked arithmetic would keep
//! them from being vectorised.

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

/// Scale of the downsampled working image: the downsampling halves both
/// sides.
pub(crate) const DOWNSAMPLE_FACTOR: f64 = 2.0;

/// Buffers of the threshold stage, kept between frames.
#[derive(Debug, Default)]
pub(crate) struct ThresholdScratch {
    /// The last `2 radius + 2` rows of the 2x downsampled working image
    /// (a ring, packed), when downsampling: all the window sums need, and
    /// small enough to stay in cache, where the whole working image (a
    /// quarter of the input) was written out and read back.
    small: Vec<u8>,
    /// Sum of each column over the window's rows.
    colsum: Vec<u32>,
    /// Prefix sums of `colsum` along the row (`width + 1` values,
    /// wrapping: only differences of nearby ones are used).
    prefix: Vec<u32>,
}

/// Size of the working image segmentation runs on and its scale
/// (full-resolution pixels per working pixel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Working {
    pub width: usize,
    pub height: usize,
    pub scale: f64,
}

/// The working image of stage 1 on `img`: `img` itself, or its 2x box
/// downsampling when `p.downsample` is set and `img` is at least
/// [`MIN_DOWNSAMPLE_SIZE`] pixels each way.
pub(crate) fn working(img: &GrayView<'_>, p: &ThresholdParams) -> Working {
    let (w, h) = (img.width() as usize, img.height() as usize);
    if p.downsample && w >= MIN_DOWNSAMPLE_SIZE && h >= MIN_DOWNSAMPLE_SIZE {
        Working {
            width: w / 2,
            height: h / 2,
            scale: DOWNSAMPLE_FACTOR,
        }
    } else {
        Working {
            width: w,
            height: h,
            scale: 1.0,
        }
    }
}

/// Stage 1 on `img`: `out` becomes the [adaptive
/// threshold](threshold_rows) of its [working image](working), a
/// `(w + 2) x (h + 2)` buffer with a one-pixel zero border (what the
/// border follower needs). Every byte of `out` is written, so it needs no
/// clearing between frames.
pub(crate) fn threshold(
    img: &GrayView<'_>,
    p: &ThresholdParams,
    s: &mut ThresholdScratch,
    out: &mut Vec<u8>,
) -> Working {
    let work = working(img, p);
    let rows = frame(&work, out);
    threshold_rows(img, p, &work, 0..work.height, s, rows);
    work
}

/// Sizes `out` for the thresholded `work` image, zeroes its top and bottom
/// border rows and returns the rows between them (`work.height` rows of
/// `work.width + 2` bytes), for [`threshold_rows`] to fill whole or in
/// bands.
pub(crate) fn frame<'o>(work: &Working, out: &'o mut Vec<u8>) -> &'o mut [u8] {
    let (w, h) = (work.width, work.height);
    let pw = w + 2;
    out.resize(pw * (h + 2), 0);
    if w == 0 || h == 0 {
        out.fill(0);
    }
    out[..pw].fill(0);
    out[(h + 1) * pw..].fill(0);
    &mut out[pw..(h + 1) * pw]
}

/// Rows `rows` of the adaptive threshold of `img`'s working image `work`
/// into `out` (those rows of the padded binary image, `work.width + 2`
/// bytes each, see [`frame`]). A pixel becomes 1 (dark, foreground) when
/// it is more than `p.offset` grey levels below the mean of the
/// `(2 radius + 1)^2` window around it (the window is clipped at the image
/// border). Each row's window sums are made from the working rows around
/// it alone, so any split of the rows into bands gives the same bytes as
/// one pass over them all; a band re-reads the `2 radius` working rows
/// around its ends.
pub(crate) fn threshold_rows(
    img: &GrayView<'_>,
    p: &ThresholdParams,
    work: &Working,
    rows: std::ops::Range<usize>,
    s: &mut ThresholdScratch,
    out: &mut [u8],
) {
    let (w, h) = (work.width, work.height);
    if w == 0 || h == 0 || rows.is_empty() {
        return;
    }
    let r = p.radius.max(1);
    let mut source = if work.scale == DOWNSAMPLE_FACTOR {
        // The working rows the band reads, `2 r + 2` at a time; every
        // byte is written by `Rows::produce` before it is read.
        let base = rows.start.saturating_sub(r);
        let end = (rows.end + r).min(h);
        let ring = (end - base).min(2 * r + 2);
        s.small.resize(w * ring, 0);
        Rows::Half {
            img: *img,
            small: &mut s.small,
            base,
            ring,
        }
    } else {
        Rows::Full(*img)
    };
    threshold_band(
        &mut source,
        rows,
        r,
        p.offset,
        &mut s.colsum,
        &mut s.prefix,
        out,
    );
}

/// Rows of the working image: the input's own, or made one by one (in
/// order) by 2x downsampling into `small`, which holds the last `ring`
/// of the working rows from `base` on (row `y` in slot `(y - base) % ring`;
/// a band needs rows `y - radius - 1 ..= y + radius` at row `y`).
enum Rows<'a, 'b> {
    Full(GrayView<'a>),
    Half {
        img: GrayView<'a>,
        small: &'b mut [u8],
        base: usize,
        ring: usize,
    },
}

impl Rows<'_, '_> {
    /// Working image size.
    fn size(&self) -> (usize, usize) {
        match self {
            Rows::Full(v) => (v.width() as usize, v.height() as usize),
            Rows::Half { img, .. } => (img.width() as usize / 2, img.height() as usize / 2),
        }
    }

    /// Makes row `y` readable by [`Rows::row`]; called once per row.
    fn produce(&mut self, y: usize) {
        if let Rows::Half {
            img,
            small,
            base,
            ring,
        } = self
        {
            let w = img.width() as usize / 2;
            downsample_row(
                img.row(2 * y),
                img.row(2 * y + 1),
                &mut small[(y - *base) % *ring * w..][..w],
            );
        }
    }

    /// Row `y` (after [`Rows::produce`] when downsampling).
    fn row(&self, y: usize) -> &[u8] {
        match self {
            Rows::Full(v) => v.row(y),
            Rows::Half {
                img,
                small,
                base,
                ring,
            } => {
                let w = img.width() as usize / 2;
                &small[(y - *base) % *ring * w..][..w]
            }
        }
    }
}

/// 2 x 2 box downsampling of rows `r0` and `r1` into `out` (rounded
/// mean): working pixel `x` has its centre at full-resolution `2x + 0.5`.
///
/// Each horizontal pair of bytes is read as one little-endian `u16`, whose
/// low and high bytes are the pair: the vectoriser handles masks and shifts
/// of 16-bit lanes well, where it leaves a loop reading every other byte
/// scalar.
fn downsample_row(r0: &[u8], r1: &[u8], out: &mut [u8]) {
    let (a, b) = (r0.as_chunks::<2>().0, r1.as_chunks::<2>().0);
    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
        let (a, b) = (u16::from_le_bytes(a), u16::from_le_bytes(b));
        // At most 4 * 255 + 2: no wrapping.
        let s = (a & 0xff)
            .wrapping_add(a >> 8)
            .wrapping_add(b & 0xff)
            .wrapping_add(b >> 8)
            .wrapping_add(2);
        *o = (s >> 2) as u8;
    }
}

/// `colsum += add - sub`, element-wise. `sub` is a row already in the
/// sums, so nothing goes below zero, and a column sums at most
/// `2 radius + 1` rows of 255.
fn slide(colsum: &mut [u32], add: &[u8], sub: &[u8]) {
    for ((c, &a), &s) in colsum.iter_mut().zip(add).zip(sub) {
        *c = c.wrapping_add(u32::from(a)).wrapping_sub(u32::from(s));
    }
}

/// `colsum += add`, element-wise (see [`slide`]).
fn add_row(colsum: &mut [u32], add: &[u8]) {
    for (c, &a) in colsum.iter_mut().zip(add) {
        *c = c.wrapping_add(u32::from(a));
    }
}

/// `colsum -= sub`, element-wise (see [`slide`]).
fn sub_row(colsum: &mut [u32], sub: &[u8]) {
    for (c, &s) in colsum.iter_mut().zip(sub) {
        *c = c.wrapping_sub(u32::from(s));
    }
}

/// Whether a pixel of grey `p` is dark: more than `offset` below the mean
/// `sum / count` of its window, compared without a division. No wrapping:
/// `count` is at most `(2 radius + 1)^2` with a radius of at most 200
/// ([`crate::DetectorConfig::threshold_radius`]), so the product is below
/// `510 * 401^2`.
#[inline(always)]
fn is_dark(p: u8, offset: u32, sum: u32, count: u32) -> u8 {
    u8::from(u32::from(p).wrapping_add(offset).wrapping_mul(count) < sum)
}

/// Integers below this are exact as `f32` (24-bit significand).
const EXACT_F32: u32 = 1 << 24;

/// Values summed at a time by [`prefix_sums`].
const PREFIX_BLOCK: usize = 8;

/// Running (inclusive, wrapping) sums of `v` into `out`. A block of
/// [`PREFIX_BLOCK`] values is summed on its own, then offset by the total
/// so far: the blocks' own sums do not wait for each other, so the
/// processor overlaps them, where one running total is a chain of
/// dependent additions, one per value.
fn prefix_sums(v: &[u32], out: &mut [u32]) {
    let (blocks, tail) = v.as_chunks::<PREFIX_BLOCK>();
    let (out_blocks, out_tail) = out.as_chunks_mut::<PREFIX_BLOCK>();
    let mut carry = 0u32;
    for (o, b) in out_blocks.iter_mut().zip(blocks) {
        let mut s = *b;
        for k in 1..PREFIX_BLOCK {
            s[k] = s[k].wrapping_add(s[k - 1]);
        }
        for (o, s) in o.iter_mut().zip(s) {
            *o = s.wrapping_add(carry);
        }
        carry = o[PREFIX_BLOCK - 1];
    }
    for (o, &t) in out_tail.iter_mut().zip(tail) {
        carry = carry.wrapping_add(t);
        *o = carry;
    }
}

/// Thresholds one row: `dst[x]` is [`is_dark`] of `row[x]` against the
/// window `[x - r, x + r]` (clipped to the row) of `colsum`, whose values
/// each sum `rows` image rows. `prefix` is scratch space.
fn threshold_row(
    row: &[u8],
    colsum: &[u32],
    rows: u32,
    r: usize,
    offset: u32,
    prefix: &mut Vec<u32>,
    dst: &mut [u8],
) {
    let w = row.len();
    // Prefix sums wrap: a window's sum is a difference of two of them,
    // which is exact as long as the window's own sum fits in a u32.
    prefix.resize(w + 1, 0);
    prefix[0] = 0;
    prefix_sums(colsum, &mut prefix[1..]);
    let clipped = |x: usize| {
        let (lo, hi) = (x.saturating_sub(r), (x + r + 1).min(w));
        let sum = prefix[hi].wrapping_sub(prefix[lo]);
        is_dark(row[x], offset, sum, rows * (hi - lo) as u32)
    };
    // Interior: windows [x - r, x + r] wholly inside, x in [r, w - r).
    let (start, end) = (r.min(w), w.saturating_sub(r).max(r.min(w)));
    for x in (0..start).chain(end..w) {
        dst[x] = clipped(x);
    }
    let n = end - start;
    if n == 0 {
        return;
    }
    let count = rows * (2 * r + 1) as u32;
    dark_run(
        &row[start..end],
        &prefix[2 * r + 1..][..n],
        &prefix[..n],
        count,
        offset,
        &mut dst[start..end],
    );
}

/// `dst[i]` is [`is_dark`] of `row[i]` against the window sum
/// `hi[i] - lo[i]` (wrapping) of `count` pixels, for a run of windows of
/// one size. Where every value involved stays below 2^24 (a radius up to
/// 90 whatever the offset, the default 10 included), the comparison is made
/// in `f32`, exactly (integers below 2^24 and their products there are
/// exact): SSE2, the x86-64 baseline, has no 32-bit integer multiply, and
/// the `f32` loop thresholds the interior 10% faster on 1080p frames.
fn dark_run(row: &[u8], hi: &[u32], lo: &[u32], count: u32, offset: u32, dst: &mut [u8]) {
    if (255 + offset).saturating_mul(count) < EXACT_F32 {
        let (c, off) = (count as f32, offset as f32);
        for (((d, &p), &hi), &lo) in dst.iter_mut().zip(row).zip(hi).zip(lo) {
            // Below 2^24: the signed conversion, which SSE2 has.
            let sum = hi.wrapping_sub(lo) as i32 as f32;
            *d = u8::from((f32::from(p) + off) * c < sum);
        }
    } else {
        for (((d, &p), &hi), &lo) in dst.iter_mut().zip(row).zip(hi).zip(lo) {
            *d = is_dark(p, offset, hi.wrapping_sub(lo), count);
        }
    }
}

/// Rows `rows` of the adaptive threshold of the working image `src` into
/// `out` (see [`threshold_rows`]). `colsum` and `prefix` are scratch
/// space, resized here.
fn threshold_band(
    src: &mut Rows<'_, '_>,
    rows: std::ops::Range<usize>,
    r: usize,
    offset: u8,
    colsum: &mut Vec<u32>,
    prefix: &mut Vec<u32>,
    out: &mut [u8],
) {
    let (w, h) = src.size();
    let pw = w + 2;
    let off = u32::from(offset);
    let y0 = rows.start;
    colsum.clear();
    colsum.resize(w, 0);
    // Rows [y0 - r, y0 + r] start in the sums; each later row y then adds
    // y + r and drops y - r - 1, each when it exists.
    for y in y0.saturating_sub(r)..(y0 + r + 1).min(h) {
        src.produce(y);
        add_row(colsum, src.row(y));
    }
    for (y, line) in rows.zip(out.chunks_exact_mut(pw)) {
        let step = y > y0;
        let (add, drop) = (y + r, if step { y.checked_sub(r + 1) } else { None });
        if step && add < h {
            src.produce(add);
        }
        match (step && add < h, drop) {
            (true, Some(d)) => slide(colsum, src.row(add), src.row(d)),
            (true, None) => add_row(colsum, src.row(add)),
            (false, Some(d)) => sub_row(colsum, src.row(d)),
            (false, None) => {}
        }
        let rows = ((y + r + 1).min(h) - y.saturating_sub(r)) as u32;
        line[0] = 0;
        line[pw - 1] = 0;
        threshold_row(src.row(y), colsum, rows, r, off, prefix, &mut line[1..=w]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The straightforward stage this module must match bit for bit: a
    /// whole downsampled image first, then every window summed directly.
    fn reference(img: &GrayView<'_>, p: &ThresholdParams) -> (Vec<u8>, Working) {
        let (w, h) = (img.width() as usize, img.height() as usize);
        let half = p.downsample && w >= MIN_DOWNSAMPLE_SIZE && h >= MIN_DOWNSAMPLE_SIZE;
        let (work, ww, wh, scale) = if half {
            let (w2, h2) = (w / 2, h / 2);
            let mut d = vec![0u8; w2 * h2];
            for y in 0..h2 {
                for x in 0..w2 {
                    let at = |dx: usize, dy: usize| u16::from(img.row(2 * y + dy)[2 * x + dx]);
                    d[y * w2 + x] = ((at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1) + 2) >> 2) as u8;
                }
            }
            (d, w2, h2, DOWNSAMPLE_FACTOR)
        } else {
            let d = (0..h).flat_map(|y| img.row(y).to_vec()).collect();
            (d, w, h, 1.0)
        };
        let r = p.radius.max(1);
        let mut out = vec![0u8; (ww + 2) * (wh + 2)];
        for y in 0..wh {
            for x in 0..ww {
                let (mut sum, mut count) = (0u32, 0u32);
                for yy in y.saturating_sub(r)..(y + r + 1).min(wh) {
                    for xx in x.saturating_sub(r)..(x + r + 1).min(ww) {
                        sum += u32::from(work[yy * ww + xx]);
                        count += 1;
                    }
                }
                let dark = (u32::from(work[y * ww + x]) + u32::from(p.offset)) * count < sum;
                out[(y + 1) * (ww + 2) + x + 1] = u8::from(dark);
            }
        }
        let size = Working {
            width: ww,
            height: wh,
            scale,
        };
        (out, size)
    }

    fn noise(n: usize, mut seed: u64) -> Vec<u8> {
        (0..n)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 56) as u8
            })
            .collect()
    }

    /// The fused stage on `img`, twice through the same buffers (the
    /// second time after a frame of another size, so stale contents would
    /// show).
    fn fused(img: &GrayView<'_>, p: &ThresholdParams) -> (Vec<u8>, Working) {
        let (mut s, mut out) = (ThresholdScratch::default(), Vec::new());
        let other = noise(31 * 17, 9);
        threshold(&GrayView::packed(&other, 31, 17), p, &mut s, &mut out);
        out.iter_mut().for_each(|v| *v = 3);
        let size = threshold(img, p, &mut s, &mut out);
        (out, size)
    }

    /// The stage in bands cut at `cuts` (working rows, any order, out of
    /// range ones ignored), each band with fresh buffers, as the detector's
    /// threads run it.
    fn banded(img: &GrayView<'_>, p: &ThresholdParams, cuts: &[usize]) -> (Vec<u8>, Working) {
        let work = working(img, p);
        let mut out = vec![7u8; 3];
        let rows = frame(&work, &mut out);
        let mut at: Vec<usize> = cuts.iter().map(|&c| c.min(work.height)).collect();
        at.extend([0, work.height]);
        at.sort_unstable();
        let pw = work.width + 2;
        let mut rest = rows;
        for b in at.windows(2) {
            let (band, tail) = rest.split_at_mut((b[1] - b[0]) * pw);
            let mut s = ThresholdScratch::default();
            threshold_rows(img, p, &work, b[0]..b[1], &mut s, band);
            rest = tail;
        }
        (out, work)
    }

    #[test]
    fn downsample_averages_blocks() {
        let src = [0u8, 4, 8, 8, 0, 0, 8, 8, 100, 100, 200, 200];
        let mut dst = [0u8; 2];
        downsample_row(&src[..4], &src[4..8], &mut dst);
        assert_eq!(dst, [1, 8]);
    }

    #[test]
    fn matches_the_reference_on_small_cases() {
        for (w, h, r) in [(37, 23, 4), (5, 9, 6), (64, 3, 1), (1, 1, 3), (16, 16, 7)] {
            for downsample in [false, true] {
                let img = noise(w * h, (w * 31 + h) as u64);
                let view = GrayView::packed(&img, w, h);
                let p = ThresholdParams {
                    downsample,
                    radius: r,
                    offset: 5,
                };
                assert_eq!(fused(&view, &p), reference(&view, &p), "{w}x{h} r{r}");
                let cuts = [1, h / 3, h / 2, h / 2 + 1];
                assert_eq!(
                    banded(&view, &p, &cuts),
                    reference(&view, &p),
                    "{w}x{h} r{r}"
                );
            }
        }
    }

    /// The `f32` comparison of [`dark_run`] against [`is_dark`] wherever
    /// it is used, at every grey level and at the sums where the answer
    /// turns, and the integer one beyond (the images of
    /// `matches_the_reference` are too small to reach it).
    #[test]
    fn the_float_comparison_is_exact() {
        for count in [1u32, 2, 441, 4_000, 32_000, 32_896, 32_897, 65_793, 160_801] {
            for offset in [0u32, 1, 6, 128, 255] {
                let (mut row, mut hi, mut lo) = (vec![], vec![], vec![]);
                for p in 0..=255u8 {
                    let edge = (u32::from(p) + offset) * count;
                    for sum in [edge.saturating_sub(1), edge, edge + 1, 0, 255 * count] {
                        row.push(p);
                        // A wrapped difference, as the prefix sums give.
                        hi.push(sum.wrapping_add(u32::MAX - 7));
                        lo.push(u32::MAX - 7);
                    }
                }
                let mut got = vec![9; row.len()];
                dark_run(&row, &hi, &lo, count, offset, &mut got);
                for (i, &g) in got.iter().enumerate() {
                    let want = is_dark(row[i], offset, hi[i].wrapping_sub(lo[i]), count);
                    assert_eq!(g, want, "count {count} offset {offset} p {}", row[i]);
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Any size (odd ones too), row stride, radius (up to the
        /// config's 200), offset and grey levels (smooth ramps and noise,
        /// whose thresholds sit at every level), with and without
        /// downsampling.
        #[test]
        fn matches_the_reference(
            w in 0usize..90,
            h in 0usize..70,
            pad in 0usize..5,
            radius in prop_oneof![1usize..12, 12usize..=200],
            offset: u8,
            downsample: bool,
            ramp in 0u32..4,
            seed: u64,
            cuts in proptest::collection::vec(0usize..40, 0..4),
        ) {
            let stride = w + pad;
            let data: Vec<u8> = noise(stride * h, seed)
                .into_iter()
                .enumerate()
                .map(|(i, v)| match ramp {
                    0 => v,
                    k => ((i % stride.max(1)) as u32 * k + (i / stride.max(1)) as u32) as u8 / 2 + v / 8,
                })
                .collect();
            let view = GrayView::new(&data, w as u32, h as u32, stride).unwrap();
            let p = ThresholdParams { downsample, radius, offset };
            let want = reference(&view, &p);
            prop_assert_eq!(&fused(&view, &p), &want);
            prop_assert_eq!(&banded(&view, &p, &cuts), &want);
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
        let p = ThresholdParams {
            downsample: false,
            radius: 6,
            offset: 5,
        };
        let (mut s, mut out) = (ThresholdScratch::default(), Vec::new());
        threshold(&GrayView::packed(&img, w, h), &p, &mut s, &mut out);
        let at = |x: usize, y: usize| out[(y + 1) * (w + 2) + x + 1];
        assert_eq!(at(5, 5), 1);
        assert_eq!(at(4, 5), 0);
        assert_eq!(at(14, 14), 1);
        assert_eq!(at(15, 14), 0);
        // Border stays zero.
        assert!(out[..w + 2].iter().all(|&v| v == 0));
    }
}

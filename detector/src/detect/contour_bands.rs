//! Stage 2 on the detector's worker threads: the border following of
//! `contours` in bands of rows, with the same borders, in the same order,
//! point for point, as the one raster scan over the whole image.
//!
//! Why the bands can be followed apart: Suzuki & Abe's scan starts every
//! border at one pixel, fixed by the image alone (an outer border at the
//! first pixel, in raster order, of its 8-connected foreground region; a
//! hole border just left of the first pixel of its 4-connected background
//! region), and following a border from a given start reads only which
//! pixels are foreground. The labels the scan writes only decide which
//! pixels are such starts. So each band runs the sequential scan over its
//! own rows, labelling them in place as the one scan does; a border it
//! follows may leave the band, and is followed to its end, through a copy
//! of the binary image as thresholded (the other bands label their own
//! rows meanwhile), packed one bit a pixel ([`pack`]) after stage 1.
//!
//! A band does not see the labels left by borders that start in the bands
//! above it, so it may take a pixel of such a border for a start. Such a
//! border is followed all the same (its labels inside the band are needed,
//! as in the one scan), and recognised as not starting there by where it
//! goes: above the band. An outer border starts at the first pixel of its
//! region, so one that starts in the band stays in and below it; one
//! whose region begins above the band reaches there. (One whose region
//! begins in the band but which the band took up at a later pixel is not
//! possible: the band started it at the region's first pixel and labelled
//! it.) A hole border starts in the row of its hole's first pixel and
//! reaches one row above it, so one that starts in the band reaches at
//! most the row above the band, while one whose hole begins above the
//! band reaches two rows above it. A border that does not start in the
//! band is dropped; a pixel that took it for an outer border is then
//! tested again as the start of a hole border, which the one scan, seeing
//! the pixel already on a border, would have done. Borders kept are those
//! of the one scan; the bands' lists, joined in band order, are in its
//! order.
//!
//! The cost: borders that cross into a band from above are followed once
//! more there, so bands are few (see [`BANDS_PER_THREAD`]); the copy is
//! made; and each band reads foreground from the copy and writes labels in
//! its rows.

use rayon::prelude::*;

use super::contours::{follow, offsets, scan, Border, Contours, Labels, EAST, WEST};
use super::parallel::Workers;

/// Bands per worker thread: one. Each border crossing a band edge is
/// followed once more for each band it reaches, which on the 4K frames of
/// the wild benchmark costs more than the better balance of more bands
/// gains (two threads, median per frame: 1.48-1.50 ms in two bands,
/// 1.63 ms in three or four; 1.88-1.94 ms in the one scan of one thread).
const BANDS_PER_THREAD: usize = 1;

/// Fewest rows of a band: borders crossing band edges are followed again
/// by the band below, so thin bands would follow many borders twice.
const MIN_BAND_ROWS: usize = 64;

/// Words of [`pack`]'s output per parallel piece: 4096 words, 256 KB of
/// the binary image.
const PACK_WORDS_PER_PIECE: usize = 4096;

/// `bits` made the binary image `bin` (0 for background, 1 for
/// foreground, as stage 1 writes it) packed one bit a pixel: bit `i % 64`
/// of word `i / 64` is `bin[i]`. On `workers`' threads; on the wild
/// benchmark's 4K frames it adds no measurable time to stage 1, where the
/// copy of bytes it replaces was made by stage 1's bands.
pub(crate) fn pack<W: Default + Send>(bin: &[u8], workers: &Workers<W>, bits: &mut Vec<u64>) {
    bits.clear();
    bits.resize(bin.len().div_ceil(64), 0);
    workers.install(|| {
        bits.par_chunks_mut(PACK_WORDS_PER_PIECE)
            .enumerate()
            .for_each(|(k, words)| pack_words(bin, k * PACK_WORDS_PER_PIECE, words));
    });
}

/// Words `first..` of [`pack`]'s output.
fn pack_words(bin: &[u8], first: usize, words: &mut [u64]) {
    for (j, w) in words.iter_mut().enumerate() {
        let at = (first + j) * 64;
        let bytes = &bin[at..(at + 64).min(bin.len())];
        *w = match bytes.first_chunk::<64>() {
            Some(b) => b
                .as_chunks::<8>()
                .0
                .iter()
                .enumerate()
                .fold(0, |m, (k, c)| m | (pack_8(c) << (8 * k))),
            None => bytes
                .iter()
                .enumerate()
                .fold(0, |m, (k, &v)| m | (u64::from(v & 1) << k)),
        };
    }
}

/// Eight bytes of 0 and 1 as eight bits (the first the lowest): each
/// byte's low bit moved to its place by one multiplication, whose
/// partial products never overlap, so nothing carries into the top byte
/// (a loop over the bits, which the compiler did not vectorise, made
/// stage 1 0.7 ms slower a 4K frame).
#[inline(always)]
fn pack_8(c: &[u8; 8]) -> u64 {
    let x = u64::from_le_bytes(*c) & 0x0101_0101_0101_0101;
    x.wrapping_mul(0x0102_0408_1020_4080) >> 56
}

/// Buffers of the banded scan, kept between frames.
#[derive(Debug, Default)]
pub(crate) struct BandScratch {
    /// The borders each band keeps.
    bands: Vec<Contours>,
}

/// A band's view of the image: its own rows (the labels, `own`), from
/// padded index `lo` on, labelled in place (the values of `contours`), and
/// the unlabelled copy of the whole image ([`pack`]'s bits) for telling
/// foreground.
struct Band<'a> {
    lo: usize,
    copy: &'a [u64],
    /// The border being followed does not start in the band if it visits
    /// a pixel before this one (see the module documentation).
    above: usize,
}

impl Labels for Band<'_> {
    #[inline(always)]
    fn fg(&self, _own: &[u8], i: usize) -> bool {
        // From the copy, in the band too: labelling turns foreground into
        // other non-zero values and leaves background zero, so the copy
        // tells foreground everywhere, with one load and no test of which
        // band the pixel is in (the banded scan took 1.7-2.4 ms a 4K frame
        // on one thread instead of 2.0-2.8 ms when it read its own rows
        // from the labels; the one scan 1.4-1.9 ms). One bit a pixel: a
        // 1080 x 1920 working image's copy is 260 KB, which stays in a
        // core's cache beside the labels, where a byte a pixel took 2 MB
        // (with 2 threads on the wild benchmark's 4K frames, stage 2 took
        // 1.1-1.3 ms a frame from a copy of bytes, 0.8-1.0 ms from bits).
        (self.copy[i >> 6] >> (i & 63)) & 1 != 0
    }

    #[inline(always)]
    fn bytes<'a>(&self, own: &'a [u8], range: std::ops::Range<usize>) -> &'a [u8] {
        &own[range.start - self.lo..range.end - self.lo]
    }

    #[inline(always)]
    fn visit(&self, own: &mut [u8], i: usize, east_zero: bool) -> bool {
        match own.get_mut(i.wrapping_sub(self.lo)) {
            Some(v) => {
                if east_zero {
                    *v = 3;
                } else if *v == 1 {
                    *v = 2;
                }
                false
            }
            // Outside the band the labels are another band's; only
            // where the border goes counts.
            None => i < self.above,
        }
    }
}

/// [`super::contours::find_contours`] of the padded binary image `bin`
/// (`pw` x `ph`) on `workers`' threads, in bands of rows, with `copy` an
/// unlabelled copy of `bin`; `bin` is left labelled (not quite as the one
/// scan leaves it: the labels are of no use after this stage).
#[allow(clippy::too_many_arguments)]
pub(crate) fn find_contours<W: Default + Send>(
    bin: &mut [u8],
    copy: &[u64],
    pw: usize,
    ph: usize,
    min_len: usize,
    max_len: usize,
    workers: &Workers<W>,
    s: &mut BandScratch,
    out: &mut Contours,
) {
    if pw < 3 || ph < 3 {
        out.points.clear();
        out.list.clear();
        return;
    }
    let h = ph - 2;
    let bands = (workers.threads() * BANDS_PER_THREAD).min(h / MIN_BAND_ROWS);
    let size = Size { pw, ph, bands };
    follow_bands(bin, copy, size, min_len, max_len, workers, s, out);
}

/// The padded image's row length and number of rows, and the bands it is
/// cut into.
#[derive(Debug, Clone, Copy)]
struct Size {
    pw: usize,
    ph: usize,
    bands: usize,
}

/// [`find_contours`] in `size.bands` bands of (about) equal rows, at
/// most one per row.
#[allow(clippy::too_many_arguments)]
fn follow_bands<W: Default + Send>(
    bin: &mut [u8],
    copy: &[u64],
    size: Size,
    min_len: usize,
    max_len: usize,
    workers: &Workers<W>,
    s: &mut BandScratch,
    out: &mut Contours,
) {
    let Size { pw, ph, bands } = size;
    out.points.clear();
    out.list.clear();
    let h = ph - 2;
    // Band k holds the padded rows from ends[k] to ends[k + 1].
    let bands = bands.clamp(1, h.max(1));
    let ends: Vec<usize> = (0..=bands).map(|k| 1 + k * h / bands).collect();
    s.bands.resize_with(bands, Contours::default);
    let mut rest = &mut bin[pw..(h + 1) * pw];
    let mut pieces = Vec::with_capacity(bands);
    for k in 0..bands {
        let (band, tail) = rest.split_at_mut((ends[k + 1] - ends[k]) * pw);
        pieces.push(band);
        rest = tail;
    }
    let off = offsets(pw);
    let parts = &mut s.bands;
    workers.install(|| {
        pieces
            .into_par_iter()
            .zip(parts.par_iter_mut())
            .enumerate()
            .for_each(|(k, (rows, part))| {
                part.points.clear();
                part.list.clear();
                let lo = ends[k] * pw;
                let band = Band { lo, copy, above: 0 };
                scan(&band, rows, pw, ends[k]..ends[k + 1], |own, i| {
                    start_in_band(&band, own, pw, i, &off, min_len, max_len, part);
                });
            });
    });
    // The first band's borders become the list; the others' are appended.
    std::mem::swap(out, &mut s.bands[0]);
    for part in &s.bands[1..] {
        let shift = out.points.len() as u32;
        out.points.extend_from_slice(&part.points);
        out.list.extend(part.list.iter().map(|c| {
            let mut c = *c;
            c.start += shift;
            c
        }));
    }
}

/// The band's step 1 at pixel `i`, one the scan's mask marked as starting
/// a border by the band's labels (so foreground: labels never turn back to
/// background; see `contours::start_mask`): an outer border, if the pixel
/// starts one, else a hole border. Its left and right neighbours are in
/// the band (the padded image's border columns are background).
#[allow(clippy::too_many_arguments)]
fn start_in_band(
    b: &Band<'_>,
    own: &mut [u8],
    pw: usize,
    i: usize,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) {
    let at = i - b.lo;
    if own[at] == 1 && own[at - 1] == 0 {
        let outer = Border {
            start: i,
            from: WEST,
            hole: false,
        };
        if follow_if_own(b, own, pw, outer, off, min_len, max_len, out) {
            return;
        }
    }
    if own[at] != 3 && own[at + 1] == 0 {
        let hole = Border {
            start: i,
            from: EAST,
            hole: true,
        };
        follow_if_own(b, own, pw, hole, off, min_len, max_len, out);
    }
}

/// Follows `border`, labelling it in the band, and keeps it in `out` (as
/// [`follow`] does) only if it starts at its start pixel in the one scan
/// over the whole image; returns whether it does.
#[allow(clippy::too_many_arguments)]
fn follow_if_own(
    b: &Band<'_>,
    own: &mut [u8],
    pw: usize,
    border: Border,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) -> bool {
    let (points, list) = (out.points.len(), out.list.len());
    // An outer border starting in the band stays in the band and below; a
    // hole border reaches at most one row above.
    let view = Band {
        above: if border.hole {
            b.lo.saturating_sub(pw)
        } else {
            b.lo
        },
        ..*b
    };
    let own_border = !follow(&view, own, pw, border, off, min_len, max_len, out);
    if !own_border {
        out.points.truncate(points);
        out.list.truncate(list);
    }
    own_border
}

#[cfg(test)]
mod tests {
    use super::super::contours;
    use super::*;

    /// The banded scan against the one scan, on 2 threads, in bands of
    /// every height from one row to the whole image.
    fn check(f: &[u8], pw: usize, ph: usize, what: &str) {
        let (mut want, mut got) = (Contours::default(), Contours::default());
        let mut g = f.to_vec();
        contours::find_contours(&mut g, pw, ph, 1, usize::MAX, &mut want);
        let mut g = Vec::new();
        let kinds = |c: &Contours| -> Vec<(u32, u32, bool)> {
            c.list.iter().map(|c| (c.start, c.len, c.hole)).collect()
        };
        let w = Workers::<()>::new(2, false).unwrap();
        let mut bits = Vec::new();
        pack(f, &w, &mut bits);
        let s = &mut BandScratch::default();
        let h = ph - 2;
        for bands in [1, 2, 3, 7, h / 5, h / 2, h] {
            let size = Size { pw, ph, bands };
            g.clear();
            g.extend_from_slice(f);
            follow_bands(&mut g, &bits, size, 1, usize::MAX, &w, s, &mut got);
            assert_eq!(got.points, want.points, "{what}, {bands} bands");
            assert_eq!(kinds(&got), kinds(&want), "{what}, {bands} bands");
        }
    }

    #[test]
    fn bands_find_the_borders_of_the_one_scan() {
        let mut seed = 11u64;
        // Heights that make bands of 64 rows and more, some uneven, and
        // shapes taller than a band.
        for (w, h, density) in [
            (70, 130, 2),
            (90, 257, 8),
            (130, 200, 30),
            (40, 300, 60),
            (200, 129, 4),
            (33, 51, 12),
            (1, 40, 1),
            (40, 1, 1),
        ] {
            for _ in 0..4 {
                let f = contours::random_binary(w, h, density, 30, &mut seed);
                check(&f, w + 2, h + 2, &format!("{w}x{h}"));
            }
        }
    }

    #[test]
    fn the_packed_copy_holds_each_pixel_in_its_bit() {
        let mut seed = 5u64;
        let w = Workers::<()>::new(2, false).unwrap();
        let mut bits = Vec::new();
        // Lengths around a word and a piece, with and without a ragged
        // last word.
        for n in [0, 1, 7, 8, 63, 64, 65, 200, 64 * PACK_WORDS_PER_PIECE + 9] {
            let bin: Vec<u8> = (0..n)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    u8::from(seed >> 63 == 1)
                })
                .collect();
            pack(&bin, &w, &mut bits);
            assert_eq!(bits.len(), n.div_ceil(64), "{n} pixels");
            for (i, &v) in bin.iter().enumerate() {
                assert_eq!(
                    (bits[i / 64] >> (i % 64)) & 1,
                    u64::from(v),
                    "{n} pixels, pixel {i}"
                );
            }
            assert!(bin.len().is_multiple_of(64) || bits.last().unwrap() >> (bin.len() % 64) == 0);
        }
    }

    #[test]
    fn rings_and_spirals_across_band_edges() {
        // Nested rings and a spiral 256 rows tall: borders that start in
        // the first band and run through all the others, holes whose first
        // pixel lies in a later band than their border's, and a region
        // whose only left edges lie in the band below its first pixel.
        let (w, h) = (120, 256);
        let pw = w + 2;
        let mut f = vec![0u8; pw * (h + 2)];
        let mut set = |x: usize, y: usize, v: u8| f[(y + 1) * pw + x + 1] = v;
        for r in 0..6 {
            let (x0, y0, x1, y1) = (4 * r, 8 * r, w - 1 - 4 * r, h - 1 - 8 * r);
            let v = u8::from(r % 2 == 0);
            for x in x0..=x1 {
                set(x, y0, v);
                set(x, y1, v);
            }
            for y in y0..=y1 {
                set(x0, y, v);
                set(x1, y, v);
            }
        }
        // A comb hanging from the top ring: teeth ending at band edges.
        for t in 0..10 {
            for y in 10..(64 * (t % 4) + 63).min(h - 10) {
                set(30 + 6 * t, y, 1);
            }
        }
        check(&f, pw, h + 2, "rings");
    }
}

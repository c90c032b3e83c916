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
//! own rows, reading the whole (unchanged) binary image and keeping its
//! labels in a buffer of its own, written only inside the band; a border
//! it follows may leave the band, and is followed to its end.
//!
//! A band does not see the labels left by borders that start in the bands
//! above it, so it may take a pixel of such a border for a start. Such a
//! border is followed all the same (its labels inside the band are needed,
//! as in the one scan), and recognised as not starting there: an outer
//! border that does starts at its own first pixel, so it passes no pixel
//! earlier in the raster; a hole border that does starts just left of the
//! first pixel of its hole, so the first background pixel it examines
//! (step 3.3) is the one right of its start. A border that fails its test
//! is dropped; a pixel that took it for an outer border is then tested
//! again as the start of a hole border, which the one scan, seeing the
//! pixel already on a border, would have done. Borders kept are those of
//! the one scan; the bands' lists, joined in band order, are in its order.
//!
//! The cost: borders that cross into a band from above are followed once
//! more there; bands are few (see [`BANDS_PER_THREAD`]).

use rayon::prelude::*;

use super::contours::{follow, offsets, scan, Border, Contours, Labels, EAST, SKIP_BLOCK, WEST};
use super::parallel::Workers;

/// Bands per worker thread: two, so that a thread slowed by another
/// process (or a band with more borders than the rest) leaves a band for
/// the other threads, while each border crossing a band edge is followed
/// once more for each band it reaches.
const BANDS_PER_THREAD: usize = 2;

/// Fewest rows of a band: borders crossing band edges are followed again
/// by the band below, so thin bands would follow many borders twice.
const MIN_BAND_ROWS: usize = 64;

/// Buffers of the banded scan, kept between frames.
#[derive(Debug, Default)]
pub(crate) struct BandScratch {
    /// The labels of every band, one byte per pixel of the padded image:
    /// 0 not on a border followed in the band, 2 on one, 3 on one with
    /// background on its right.
    labels: Vec<u8>,
    /// The borders each band keeps.
    bands: Vec<Contours>,
}

/// A band's view of the image: the shared binary image, and its own
/// labels for the rows from padded index `lo` on.
struct Band<'a> {
    bin: &'a [u8],
    labels: &'a mut [u8],
    lo: usize,
    /// Smallest pixel visited and background pixel examined by the border
    /// being followed.
    min_visited: usize,
    min_swept: usize,
}

impl Band<'_> {
    /// The band's label of pixel `i` (inside the band).
    fn label(&self, i: usize) -> u8 {
        self.labels[i - self.lo]
    }
}

impl Labels for Band<'_> {
    #[inline(always)]
    fn fg(&self, i: usize) -> bool {
        self.bin[i] != 0
    }

    #[inline(always)]
    fn block(&self, i: usize) -> Option<&[u8; SKIP_BLOCK + 2]> {
        self.bin[i..].first_chunk()
    }

    #[inline(always)]
    fn visit(&mut self, i: usize, east_zero: bool) {
        self.min_visited = self.min_visited.min(i);
        // Outside the band (below `lo`, the index wraps) the label is
        // another band's.
        if let Some(v) = self.labels.get_mut(i.wrapping_sub(self.lo)) {
            if east_zero {
                *v = 3;
            } else if *v == 0 {
                *v = 2;
            }
        }
    }

    #[inline(always)]
    fn swept(&mut self, i: usize) {
        self.min_swept = self.min_swept.min(i);
    }
}

/// [`super::contours::find_contours`] of the padded binary image `bin`
/// (`pw` x `ph`) on `workers`' threads, in bands of rows; `bin` is left
/// as it is.
#[allow(clippy::too_many_arguments)]
pub(crate) fn find_contours<W: Default + Send>(
    bin: &[u8],
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
    follow_bands(bin, size, min_len, max_len, workers, s, out);
}

/// The padded image's row length and number of rows, and the bands it is
/// cut into.
#[derive(Debug, Clone, Copy)]
struct Size {
    pw: usize,
    ph: usize,
    bands: usize,
}

/// [`find_contours`] in (about) `size.bands` bands of equal rows.
fn follow_bands<W: Default + Send>(
    bin: &[u8],
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
    let per = h.div_ceil(bands.max(1));
    s.labels.resize(pw * ph, 0);
    s.bands.resize_with(h.div_ceil(per), Contours::default);
    let off = offsets(pw);
    workers.install(|| {
        s.labels[pw..(h + 1) * pw]
            .par_chunks_mut(per * pw)
            .zip(s.bands.par_iter_mut())
            .enumerate()
            .for_each(|(k, (labels, part))| {
                labels.fill(0);
                part.points.clear();
                part.list.clear();
                let y0 = 1 + k * per;
                let mut band = Band {
                    bin,
                    labels,
                    lo: y0 * pw,
                    min_visited: usize::MAX,
                    min_swept: usize::MAX,
                };
                let rows = y0..(y0 + per).min(h + 1);
                scan(&mut band, pw, rows, |b, i| {
                    // Most pixels tested are not on an edge: the test is
                    // made here, inline, before the call.
                    let (v, west, east) = (bin[i], bin[i - 1], bin[i + 1]);
                    if v != 0 && (west == 0 || east == 0) {
                        start_in_band(b, pw, i, &off, min_len, max_len, part);
                    }
                });
            });
    });
    for part in &s.bands {
        let shift = out.points.len() as u32;
        out.points.extend_from_slice(&part.points);
        out.list.extend(part.list.iter().map(|c| {
            let mut c = *c;
            c.start += shift;
            c
        }));
    }
}

/// The band's step 1 at pixel `i`, a foreground pixel next to background
/// (see the module documentation): an outer border, if the pixel starts
/// one, else a hole border.
fn start_in_band(
    b: &mut Band<'_>,
    pw: usize,
    i: usize,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) {
    if b.label(i) == 0 && b.bin[i - 1] == 0 {
        let outer = Border {
            start: i,
            from: WEST,
            hole: false,
        };
        if follow_if_own(b, pw, outer, off, min_len, max_len, out) {
            return;
        }
    }
    if b.label(i) != 3 && b.bin[i + 1] == 0 {
        let hole = Border {
            start: i,
            from: EAST,
            hole: true,
        };
        follow_if_own(b, pw, hole, off, min_len, max_len, out);
    }
}

/// Follows `border`, labelling it in the band, and keeps it in `out` (as
/// [`follow`] does) only if it starts at its start pixel in the one scan
/// over the whole image; returns whether it does.
fn follow_if_own(
    b: &mut Band<'_>,
    pw: usize,
    border: Border,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) -> bool {
    b.min_visited = usize::MAX;
    b.min_swept = usize::MAX;
    let (points, list) = (out.points.len(), out.list.len());
    follow(b, pw, border, off, min_len, max_len, out);
    let own = if border.hole {
        b.min_swept == border.start + 1
    } else {
        b.min_visited == border.start
    };
    if !own {
        out.points.truncate(points);
        out.list.truncate(list);
    }
    own
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
        let kinds = |c: &Contours| -> Vec<(u32, u32, bool)> {
            c.list.iter().map(|c| (c.start, c.len, c.hole)).collect()
        };
        let w = Workers::<()>::new(2).unwrap();
        let s = &mut BandScratch::default();
        let h = ph - 2;
        for bands in [1, 2, 3, 7, h / 5, h / 2, h] {
            let size = Size { pw, ph, bands };
            follow_bands(f, size, 1, usize::MAX, &w, s, &mut got);
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

//! Stage 2: border following (Suzuki & Abe, "Topological structural analysis
//! of digitized binary images by border following", CVGIP 30(1), 1985,
//! algorithm 1), re-implemented on the thresholded image.
//!
//! Why not `imageproc::contours::find_contours`: it copies the image into an
//! `i32` label image and returns one `Vec` per contour, every frame. Here the
//! labels live in the `u8` binary buffer itself (the hierarchy is not needed,
//! only "visited" and "visited with background on the right"), and all
//! points go into one flat buffer the detector keeps between frames. The
//! scan finds the pixels that start borders 32 at a time (`start_mask`).
//!
//! Pixel values in the padded binary image: 0 background, 1 foreground not
//! yet on a followed border, 2 on a followed border, 3 on a followed border
//! whose right neighbour is background (Suzuki's negative NBD).

/// One followed border.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Contour {
    /// First point in [`Contours::points`].
    pub start: u32,
    /// Number of points.
    pub len: u32,
    /// Hole border (white region inside black) rather than outer border.
    pub hole: bool,
}

/// All borders of a frame, points in working-image pixel coordinates.
#[derive(Debug, Default)]
pub(crate) struct Contours {
    /// Points of every kept contour, one after the other.
    pub points: Vec<[i32; 2]>,
    /// The contours.
    pub list: Vec<Contour>,
}

impl Contours {
    /// Points of contour `c`.
    pub fn points_of(&self, c: &Contour) -> &[[i32; 2]] {
        &self.points[c.start as usize..(c.start + c.len) as usize]
    }
}

/// Longest border stored for a working image of `w` x `h` pixels:
/// `BORDER_PER_SIZE * (w + h) + BORDER_SLACK` points (twice the image
/// perimeter, plus slack for tiny images). Longer borders (noise filling
/// the frame) are followed, so they are marked, but not stored.
pub(crate) fn max_border_len(w: usize, h: usize) -> usize {
    BORDER_PER_SIZE * (w + h) + BORDER_SLACK
}

/// See [`max_border_len`].
const BORDER_PER_SIZE: usize = 4;
/// See [`max_border_len`].
const BORDER_SLACK: usize = 16;

/// Neighbour offsets, index increasing clockwise on screen (y down):
/// E, SE, S, SW, W, NW, N, NE.
const DX: [isize; 8] = [1, 1, 0, -1, -1, -1, 0, 1];
const DY: [isize; 8] = [0, 1, 1, 1, 0, -1, -1, -1];

/// Follows every border of the padded binary image `f` (`pw` x `ph`, zero
/// border of one pixel). Contours with fewer than `min_len` or more than
/// `max_len` points are followed (so they are marked) but not stored.
/// Stored points are in unpadded coordinates.
///
/// Every border is traversed with the foreground on its left (screen
/// coordinates, y down): outer borders anticlockwise on screen, hole
/// borders clockwise.
pub(crate) fn find_contours(
    f: &mut [u8],
    pw: usize,
    ph: usize,
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) {
    out.points.clear();
    out.list.clear();
    if pw < 3 || ph < 3 {
        return;
    }
    let off = offsets(pw);
    scan(&InPlace, f, pw, 1..ph - 1, |f, i| {
        start_border(f, pw, i, &off, min_len, max_len, out);
    });
}

/// The padded-index offsets of the eight neighbours (see [`DX`]) in an
/// image of row length `pw`.
pub(super) fn offsets(pw: usize) -> [isize; 8] {
    std::array::from_fn(|k| DY[k] * pw as isize + DX[k])
}

/// Suzuki & Abe's raster scan over the padded rows `rows` of an image of
/// row length `pw`, labelled in `own` (see [`Labels`]): calls
/// `start(own, i)`, in raster order, on each pixel `i` that may start a
/// border (see [`start_mask`]), and on no pixel that cannot.
pub(super) fn scan<L: Labels>(
    l: &L,
    own: &mut [u8],
    pw: usize,
    rows: std::ops::Range<usize>,
    mut start: impl FnMut(&mut [u8], usize),
) {
    for y in rows {
        let row = y * pw;
        let mut x = 1;
        while x < pw - 1 {
            let end = (x + SCAN_CHUNK).min(pw - 1);
            let bytes = l.bytes(own, row + x - 1..row + end + 1);
            let mut mask = match bytes.first_chunk() {
                Some(b) => start_mask(b),
                None => start_mask_short(bytes),
            };
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                start(own, row + x + j);
            }
            x = end;
        }
    }
}

/// Pixels of a row whose [`start_mask`] the scan makes at once.
const SCAN_CHUNK: usize = 32;

/// Whether pixel `v`, between `west` and `east`, starts a border as the
/// labels stand (Suzuki & Abe's step 1): an outer border at a foreground
/// pixel not yet followed with background on its left, a hole border at
/// one not on a border with background on its right (see the module
/// documentation for the labels).
#[inline(always)]
fn starts(west: u8, v: u8, east: u8) -> bool {
    // Without short circuits, so that the mask's loop is vectorised.
    (v == 1) & (west == 0) | (v.wrapping_sub(1) < 2) & (east == 0)
}

/// Bit `j` set where pixel `j + 1` of `b` [`starts`] a border as the
/// labels stand when the mask is made.
///
/// Why a mask made before the chunk's borders are followed may be used
/// while they are: following changes labels only from 1 to 2 or 3 and from
/// 2 to 3, which can make a pixel stop starting a border but never start
/// one, so the mask's bits are the starts and some pixels that no longer
/// are, which `start` tells by the labels again. And why a mask: in a
/// cluttered frame's binary image nearly every chunk holds an edge, and
/// testing its pixels one by one took a branch per pixel that the
/// processor could not predict (the scan, borders not followed, was
/// 1.3-1.6 ms of stage 2's 2.1-2.7 ms on the wild benchmark's 4K frames).
/// One pass over the bytes without early exit, which the compiler
/// vectorises; the scan then visits the set bits alone.
#[inline(always)]
fn start_mask(b: &[u8; SCAN_CHUNK + 2]) -> u32 {
    let mut m = 0u32;
    for j in 0..SCAN_CHUNK {
        m |= u32::from(starts(b[j], b[j + 1], b[j + 2])) << j;
    }
    m
}

/// [`start_mask`] of a chunk shorter than [`SCAN_CHUNK`] (a row's last).
fn start_mask_short(b: &[u8]) -> u32 {
    b.windows(3).enumerate().fold(0u32, |m, (j, w)| {
        m | u32::from(starts(w[0], w[1], w[2])) << j
    })
}

/// Follows the border starting at pixel `i` of the scan, if one does:
/// an outer border at a foreground pixel not yet followed with background
/// on its left, a hole border at a foreground pixel not on a border with
/// background on its right (Suzuki & Abe's step 1).
fn start_border(
    f: &mut [u8],
    pw: usize,
    i: usize,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) {
    let (west, v, east) = (f[i - 1], f[i], f[i + 1]);
    if starts(west, v, east) {
        // An outer border where one starts, else a hole border. Start
        // direction (i2): west for outer, east for hole.
        let outer = v == 1 && west == 0;
        let from = if outer { WEST } else { EAST };
        let border = Border {
            start: i,
            from,
            hole: !outer,
        };
        follow(&InPlace, f, pw, border, off, min_len, max_len, out);
    }
}

/// Direction index of the east neighbour (see [`DX`]): where a hole
/// border's search for its second pixel starts.
pub(super) const EAST: usize = 0;
/// Direction index of the west neighbour: where an outer border's search
/// starts.
pub(super) const WEST: usize = 4;

/// How border following reads and labels the image: whether a pixel is
/// foreground, and the labels of Suzuki & Abe's step 3.4, kept in a byte
/// buffer `own` passed alongside (its own argument, so that the compiler
/// knows the labels written are not the view's fields). The sequential
/// scan labels the binary image itself ([`InPlace`]); the banded scan
/// (`contour_bands`) labels a band's rows and reads the rest elsewhere.
pub(super) trait Labels {
    /// Whether pixel `i` is foreground.
    fn fg(&self, own: &[u8], i: usize) -> bool;
    /// The pixels `range` (padded indices, in the rows `own` labels):
    /// zero and non-zero bytes for background and foreground.
    fn bytes<'a>(&self, own: &'a [u8], range: std::ops::Range<usize>) -> &'a [u8];
    /// Step 3.4 at pixel `i` of the border: labelled as followed, and as
    /// followed with background on its right when `east_zero`. Returns
    /// whether the pixel tells that the border does not start where it
    /// was taken up (never, for the sequential scan).
    fn visit(&self, own: &mut [u8], i: usize, east_zero: bool) -> bool;
}

/// The labels kept in the binary image itself, `own` (the values of the
/// module documentation).
pub(super) struct InPlace;

impl Labels for InPlace {
    #[inline(always)]
    fn fg(&self, own: &[u8], i: usize) -> bool {
        own[i] != 0
    }

    #[inline(always)]
    fn bytes<'a>(&self, own: &'a [u8], range: std::ops::Range<usize>) -> &'a [u8] {
        &own[range]
    }

    #[inline(always)]
    fn visit(&self, own: &mut [u8], i: usize, east_zero: bool) -> bool {
        if east_zero {
            own[i] = 3;
        } else if own[i] == 1 {
            own[i] = 2;
        }
        false
    }
}

/// Where a border is followed from: its start pixel (padded index), the
/// direction of step 3.1's search ([`WEST`] for an outer border, [`EAST`]
/// for a hole border) and which kind it is.
#[derive(Debug, Clone, Copy)]
pub(super) struct Border {
    pub start: usize,
    pub from: usize,
    pub hole: bool,
}

/// Follows `b` (Suzuki & Abe's steps 3.1 to 3.5) in the padded image of
/// row length `pw`, labelling its pixels in `own` through `l`. Stores it
/// in `out` (in unpadded coordinates) when it has at least `min_len` and
/// at most `max_len` points. Returns whether a pixel of the border told
/// that it does not start at `b.start` ([`Labels::visit`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn follow<L: Labels>(
    l: &L,
    own: &mut [u8],
    pw: usize,
    b: Border,
    off: &[isize; 8],
    min_len: usize,
    max_len: usize,
    out: &mut Contours,
) -> bool {
    let Border { start, from, hole } = b;
    let first = out.points.len();
    // 3.1: clockwise from `from` for a non-zero neighbour.
    let Some(k1) = (0..8)
        .map(|s| (from + s) % 8)
        .find(|&k| l.fg(own, step(start, k, off)))
    else {
        // Isolated pixel.
        return l.visit(own, start, true);
    };
    let i1 = step(start, k1, off);
    // 3.2: i3 the border's pixel and `d` the direction from it to the
    // pixel before (i2), kept from the step that came, and (x, y) its
    // padded coordinates, moved along by the steps: neither is worked out
    // of the indices again at each step (a division and a search).
    let (mut i3, mut d) = (start, k1);
    let (mut x, mut y) = ((start % pw) as i32, (start / pw) as i32);
    let mut stored = true;
    let mut elsewhere = false;
    loop {
        if stored {
            if out.points.len() - first >= max_len {
                stored = false;
                out.points.truncate(first);
            } else {
                out.points.push([x - 1, y - 1]);
            }
        }
        // 3.3: counter-clockwise around i3, starting after i2 (which is
        // foreground, so the search ends at it at the latest).
        let mut k = d;
        let mut east_zero = false;
        for _ in 0..8 {
            k = (k + 7) % 8;
            if l.fg(own, step(i3, k, off)) {
                break;
            }
            if k == EAST {
                east_zero = true;
            }
        }
        let i4 = step(i3, k, off);
        // 3.4
        elsewhere |= l.visit(own, i3, east_zero);
        // 3.5
        if i4 == start && i3 == i1 {
            break;
        }
        i3 = i4;
        d = (k + 4) % 8;
        x += DX[k] as i32;
        y += DY[k] as i32;
    }
    let len = out.points.len() - first;
    if !stored || len < min_len {
        out.points.truncate(first);
        return elsewhere;
    }
    out.list.push(Contour {
        start: first as u32,
        len: len as u32,
        hole,
    });
    elsewhere
}

/// The padded index of the neighbour of pixel `i` in direction `k`.
#[inline(always)]
fn step(i: usize, k: usize, off: &[isize; 8]) -> usize {
    i.wrapping_add_signed(off[k])
}

/// A random binary image for tests (padded: `w` x `h` inside a border of
/// zeros): rectangles of both values up to 40 x `max_h` (long runs, nested
/// regions, holes), then salt noise.
#[cfg(test)]
pub(crate) fn random_binary(
    w: usize,
    h: usize,
    density: usize,
    max_h: usize,
    seed: &mut u64,
) -> Vec<u8> {
    let pw = w + 2;
    let mut f = vec![0u8; pw * (h + 2)];
    let mut next = |m: usize| {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 33) as usize % m.max(1)
    };
    for _ in 0..density * 4 {
        let (x0, y0) = (next(w), next(h));
        let (x1, y1) = ((x0 + next(40)).min(w), (y0 + next(max_h)).min(h));
        let v = u8::from(next(3) > 0);
        for y in y0..y1 {
            f[(y + 1) * pw + x0 + 1..(y + 1) * pw + x1 + 1].fill(v);
        }
    }
    for _ in 0..density * 20 {
        f[(next(h) + 1) * pw + next(w) + 1] ^= 1;
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn padded(rows: &[&str]) -> (Vec<u8>, usize, usize) {
        let (w, h) = (rows[0].len(), rows.len());
        let pw = w + 2;
        let mut f = vec![0u8; pw * (h + 2)];
        for (y, r) in rows.iter().enumerate() {
            for (x, c) in r.bytes().enumerate() {
                f[(y + 1) * pw + x + 1] = u8::from(c == b'#');
            }
        }
        (f, pw, h + 2)
    }

    fn signed_area(p: &[[i32; 2]]) -> i64 {
        let n = p.len();
        (0..n)
            .map(|i| {
                let (a, b) = (p[i], p[(i + 1) % n]);
                i64::from(a[0]) * i64::from(b[1]) - i64::from(b[0]) * i64::from(a[1])
            })
            .sum()
    }

    #[test]
    fn borders_have_the_foreground_on_their_left() {
        let (mut f, pw, ph) = padded(&[
            "........", ".######.", ".#....#.", ".#....#.", ".#....#.", ".######.", "........",
        ]);
        let mut c = Contours::default();
        find_contours(&mut f, pw, ph, 1, 1000, &mut c);
        assert_eq!(c.list.len(), 2);
        let outer = c.list.iter().find(|c| !c.hole).unwrap();
        let hole = c.list.iter().find(|c| c.hole).unwrap();
        assert_eq!(outer.len, 18);
        // Screen coordinates (y down): a positive shoelace sum is clockwise
        // on screen, i.e. the inside is on the right of the traversal.
        // Screen coordinates (y down): a negative shoelace sum is
        // anticlockwise on screen: the outer border has the ring (the
        // foreground) on its left.
        assert!(signed_area(c.points_of(outer)) < 0);
        // The hole's border runs through the ring pixels clockwise: the
        // hole on its right, the ring again on its left.
        assert!(signed_area(c.points_of(hole)) > 0);
        assert!(hole.len >= 12);
        assert_eq!(c.points_of(outer)[0], [1, 1]);
    }

    /// Suzuki & Abe's step 1 at pixel `i` of `f`, as they write it: the
    /// border that starts there, if one does.
    fn border_at(f: &[u8], i: usize) -> Option<Border> {
        let v = f[i];
        let outer = v == 1 && f[i - 1] == 0;
        let hole = !outer && (v == 1 || v == 2) && f[i + 1] == 0;
        (outer || hole).then_some(Border {
            start: i,
            from: if outer { WEST } else { EAST },
            hole,
        })
    }

    /// The scan without the start mask: every pixel tested.
    fn find_contours_pixelwise(f: &mut [u8], pw: usize, ph: usize, out: &mut Contours) {
        out.points.clear();
        out.list.clear();
        let off = offsets(pw);
        for i in (1..ph - 1).flat_map(|y| (1..pw - 1).map(move |x| y * pw + x)) {
            if let Some(b) = border_at(f, i) {
                follow(&InPlace, f, pw, b, &off, 1, usize::MAX, out);
            }
        }
    }

    #[test]
    fn the_start_mask_changes_nothing() {
        let mut seed = 7u64;
        for (w, h, density) in [(70, 40, 2), (33, 50, 8), (130, 20, 15), (17, 17, 1)] {
            let pw = w + 2;
            let mut f = random_binary(w, h, density, 12, &mut seed);
            let (mut a, mut b) = (Contours::default(), Contours::default());
            let mut g = f.clone();
            find_contours(&mut f, pw, h + 2, 1, usize::MAX, &mut a);
            find_contours_pixelwise(&mut g, pw, h + 2, &mut b);
            assert_eq!(a.points, b.points, "{w}x{h}");
            assert_eq!(a.list.len(), b.list.len());
            assert_eq!(f, g);
        }
    }

    /// Steps 3.1-3.5 as Suzuki & Abe write them: the neighbours searched
    /// one by one, each point's coordinates divided out of its index.
    fn follow_by_neighbours(f: &mut [u8], pw: usize, b: Border, out: &mut Contours) {
        let off = offsets(pw);
        let at = |i: usize, k: usize| (i as isize + off[k]) as usize;
        let direction = |a: usize, c: usize| (0..8).find(|&k| at(a, k) == c).unwrap();
        let first = out.points.len();
        let Some(k1) = (0..8)
            .map(|s| (b.from + s) % 8)
            .find(|&k| f[at(b.start, k)] != 0)
        else {
            f[b.start] = 3;
            return;
        };
        let i1 = at(b.start, k1);
        let (mut i2, mut i3) = (i1, b.start);
        loop {
            out.points
                .push([(i3 % pw) as i32 - 1, (i3 / pw) as i32 - 1]);
            let mut k = direction(i3, i2);
            let mut east_zero = false;
            let mut i4 = i3;
            for _ in 0..8 {
                k = (k + 7) % 8;
                if f[at(i3, k)] != 0 {
                    i4 = at(i3, k);
                    break;
                }
                east_zero |= k == EAST;
            }
            if east_zero {
                f[i3] = 3;
            } else if f[i3] == 1 {
                f[i3] = 2;
            }
            if i4 == b.start && i3 == i1 {
                break;
            }
            (i2, i3) = (i3, i4);
        }
        let len = (out.points.len() - first) as u32;
        out.list.push(Contour {
            start: first as u32,
            len,
            hole: b.hole,
        });
    }

    #[test]
    fn steps_follow_as_suzuki_and_abe_write_them() {
        let mut seed = 5u64;
        for (w, h, density) in [(60, 50, 2), (41, 70, 9), (120, 30, 25), (12, 12, 4)] {
            for _ in 0..5 {
                let pw = w + 2;
                let mut f = random_binary(w, h, density, 20, &mut seed);
                let mut g = f.clone();
                let (mut a, mut b) = (Contours::default(), Contours::default());
                find_contours(&mut f, pw, h + 2, 1, usize::MAX, &mut a);
                scan(&InPlace, &mut g, pw, 1..h + 1, |g, i| {
                    if let Some(border) = border_at(g, i) {
                        follow_by_neighbours(g, pw, border, &mut b);
                    }
                });
                assert!(a.list.len() > 3, "{w}x{h}: a test with borders");
                assert_eq!(a.points, b.points, "{w}x{h}");
                let kinds = |c: &Contours| -> Vec<(u32, u32, bool)> {
                    c.list.iter().map(|c| (c.start, c.len, c.hole)).collect()
                };
                assert_eq!(kinds(&a), kinds(&b), "{w}x{h}");
                assert_eq!(f, g, "{w}x{h}: the labels");
            }
        }
    }

    #[test]
    fn min_len_filters_specks() {
        let (mut f, pw, ph) = padded(&["#...", "....", "..##"]);
        let mut c = Contours::default();
        find_contours(&mut f, pw, ph, 2, 1000, &mut c);
        assert_eq!(c.list.len(), 1);
    }
}

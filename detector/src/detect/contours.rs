//! Stage 2: border following (Suzuki & Abe, "Topological structural analysis
//! of digitized binary images by border following", CVGIP 30(1), 1985,
//! algorithm 1), re-implemented on the thresholded image.
//!
//! Why not `imageproc::contours::find_contours`: it copies the image into an
//! `i32` label image and returns one `Vec` per contour, every frame. Here the
//! labels live in the `u8` binary buffer itself (the hierarchy is not needed,
//! only "visited" and "visited with background on the right"), and all
//! points go into one flat buffer the detector keeps between frames. The
//! scan itself skips long runs of equal pixels.
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
/// `start(own, i)` on each pixel `i` that may start a border, in raster
/// order, passing over runs of pixels that cannot.
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
            // Pixels [x, end) are passed over at once, or tested one by
            // one when they hold an edge.
            let end = (x + SKIP_BLOCK).min(pw - 1);
            if end < x + SKIP_BLOCK || !l.block(own, row + x - 1).is_some_and(uniform) {
                for i in row + x..row + end {
                    start(own, i);
                }
            }
            x = end;
        }
    }
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
    let v = f[i];
    if v == 0 {
        return;
    }
    let outer = v == 1 && f[i - 1] == 0;
    let hole = !outer && (v == 1 || v == 2) && f[i + 1] == 0;
    if outer || hole {
        // Start direction (i2): west for outer, east for hole.
        let from = if outer { WEST } else { EAST };
        let border = Border {
            start: i,
            from,
            hole,
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

/// Pixels the scan for border starts passes over at once when none of
/// them, nor their left and right neighbours, is on an edge between
/// background and foreground (see [`uniform`]).
pub(super) const SKIP_BLOCK: usize = 16;

/// Whether the bytes of `s` are all background (0) or all foreground
/// (non-zero). A border starts only at a foreground pixel next to
/// background on its left (outer) or right (hole), so no pixel strictly
/// inside such a run starts one. Border following changes labels only
/// from one non-zero value to another, so the test holds whenever it is
/// made. Written as a count over the whole slice (no early exit), which
/// the compiler vectorises.
pub(super) fn uniform(s: &[u8; SKIP_BLOCK + 2]) -> bool {
    let zeros = s.iter().fold(0u8, |n, &v| n.wrapping_add(u8::from(v == 0)));
    zeros == 0 || usize::from(zeros) == s.len()
}

/// How border following reads and labels the image: whether a pixel is
/// foreground, and the labels of Suzuki & Abe's step 3.4, kept in a byte
/// buffer `own` passed alongside (its own argument, so that the compiler
/// knows the labels written are not the view's fields). The sequential
/// scan labels the binary image itself ([`InPlace`]); the banded scan
/// (`contour_bands`) labels a band's rows and reads the rest elsewhere.
pub(super) trait Labels {
    /// Whether pixel `i` is foreground.
    fn fg(&self, own: &[u8], i: usize) -> bool;
    /// The [`SKIP_BLOCK`] + 2 pixels from `i` on, if `own` holds them
    /// (zero and non-zero bytes for background and foreground).
    fn block<'a>(&self, own: &'a [u8], i: usize) -> Option<&'a [u8; SKIP_BLOCK + 2]>;
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
    fn block<'a>(&self, own: &'a [u8], i: usize) -> Option<&'a [u8; SKIP_BLOCK + 2]> {
        own[i..].first_chunk()
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
    let at = |i: usize, k: usize| (i as isize + off[k]) as usize;
    let first = out.points.len();
    let push = |out: &mut Contours, i: usize| {
        out.points.push([(i % pw) as i32 - 1, (i / pw) as i32 - 1]);
    };
    // 3.1: clockwise from `from` for a non-zero neighbour.
    let mut i1 = None;
    for s in 0..8 {
        let k = (from + s) % 8;
        if l.fg(own, at(start, k)) {
            i1 = Some((at(start, k), k));
            break;
        }
    }
    let Some((i1, _)) = i1 else {
        // Isolated pixel.
        return l.visit(own, start, true);
    };
    // 3.2
    let (mut i2, mut i3) = (i1, start);
    let mut stored = true;
    let mut elsewhere = false;
    loop {
        if stored {
            if out.points.len() - first >= max_len {
                stored = false;
                out.points.truncate(first);
            } else {
                push(out, i3);
            }
        }
        // 3.3: counter-clockwise around i3, starting after i2.
        let d = direction(i3, i2, pw);
        let mut k = d;
        let mut east_zero = false;
        let mut i4 = i3;
        for _ in 0..8 {
            k = (k + 7) % 8;
            let n = at(i3, k);
            if l.fg(own, n) {
                i4 = n;
                break;
            }
            if k == EAST {
                east_zero = true;
            }
        }
        // 3.4
        elsewhere |= l.visit(own, i3, east_zero);
        // 3.5
        if i4 == start && i3 == i1 {
            break;
        }
        i2 = i3;
        i3 = i4;
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

/// Direction index from pixel `a` to its 8-neighbour `b`.
#[inline]
pub(super) fn direction(a: usize, b: usize, pw: usize) -> usize {
    let d = b as isize - a as isize;
    let pw = pw as isize;
    match d {
        1 => 0,
        x if x == pw + 1 => 1,
        x if x == pw => 2,
        x if x == pw - 1 => 3,
        -1 => 4,
        x if x == -pw - 1 => 5,
        x if x == -pw => 6,
        _ => 7,
    }
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

    /// The scan without block skipping: every pixel tested.
    fn find_contours_pixelwise(f: &mut [u8], pw: usize, ph: usize, out: &mut Contours) {
        out.points.clear();
        out.list.clear();
        let off: [isize; 8] = std::array::from_fn(|k| DY[k] * pw as isize + DX[k]);
        for i in (1..ph - 1).flat_map(|y| (1..pw - 1).map(move |x| y * pw + x)) {
            let v = f[i];
            let outer = v == 1 && f[i - 1] == 0;
            let hole = !outer && (v == 1 || v == 2) && f[i + 1] == 0;
            if outer || hole {
                let from = if outer { WEST } else { EAST };
                let b = Border {
                    start: i,
                    from,
                    hole,
                };
                follow(&InPlace, f, pw, b, &off, 1, usize::MAX, out);
            }
        }
    }

    #[test]
    fn block_skipping_changes_nothing() {
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

    #[test]
    fn min_len_filters_specks() {
        let (mut f, pw, ph) = padded(&["#...", "....", "..##"]);
        let mut c = Contours::default();
        find_contours(&mut f, pw, ph, 2, 1000, &mut c);
        assert_eq!(c.list.len(), 1);
    }
}

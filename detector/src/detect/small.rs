//! Stage 6b: a second, full-resolution look around disc rims too small to
//! read on the downsampled image.
//!
//! Downsampling halves the cost of segmentation, but a ct14 data square of
//! 20-40 px has cells of 1.3-2.5 px, under a pixel after halving: the white
//! margin between the cells and the black frame (one cell wide) vanishes
//! in the threshold, the data square's inner border merges with its cells
//! and no quad closes. The tag's black disc (radius about 0.82 of the data
//! square's side) is still a clean, large blob there, and the ellipse
//! stage finds its rim. So every rim of a small tag's size that no
//! detection explains marks a region worth segmenting again at full
//! resolution; the rest of the frame is not looked at twice, which keeps
//! the common case (large tags, or none) at the downsampled cost.
//!
//! Under about 40 px, a tag seen at an angle can still fail at full
//! resolution: its one-cell white margin is then a line one or two pixels
//! wide. Where the full-resolution look read nothing and the rim's middle
//! looks like cells, the region is looked at once more, upsampled 2x
//! (bilinear), and the candidates found there are decoded on the original
//! pixels.
//!
//! This is the "search at a second scale only where candidates are
//! small" idea; AprilTag 3 instead refines its decimated quads' edges at
//! full resolution (`refine_edges`), which needs a quad to exist first.

use super::decoding::Quad;
use super::ellipses::Ellipse;
use super::quads::Candidate;
use super::Detection;
use crate::geometry::CORNERS;
use crate::homography::Homography;
use crate::math::{centroid, inside, to_full};
use crate::view::GrayView;

/// Ratio of the disc's radius to the data square's side: the black disc
/// ends at about 0.82 S (the format's geometry, step 9).
const DISC_PER_SIDE: f64 = 0.82;

/// Largest data-square side (full px) looked at again: above it, cells are
/// over 2 px at half resolution (ct14: 64 / 16 / 2), enough for the
/// downsampled pass. A rim of a larger tag that did not decode there is
/// damaged, not too small, and a second look would only cost time.
pub(crate) const MAX_SIDE_PX: f64 = 64.0;

/// Largest data-square side (full px) whose region is looked at once
/// more, upsampled 2x, when the full-resolution look decoded nothing
/// there. Under about 40 px a ct14 cell is under 2.5 px and the one-cell
/// white margin inside the black disc, seen at an angle, is a line one or
/// two pixels wide: the threshold's 8-connected regions join it to the
/// cells and the data square's border does not close. Doubled, the margin
/// is 3-5 px wide and the square's border closes. On the wild set, of 60
/// missed tags under 40 px that the decoder reads with their true
/// corners, an 80 px crop around each found 6 at full resolution and 22
/// upsampled 2x; of 60 found ones, 58 and 50, hence "upsampled only when
/// the plain look found nothing".
const UPSAMPLE_BELOW_SIDE_PX: f64 = 40.0;

/// Most candidates the full-resolution look may have decoded (in vain) for
/// the region to be looked at upsampled. The upsampled look is for rims
/// whose data square closed no quad at full resolution; where several
/// quads of the rim were read and failed, the tag is damaged rather than
/// too small. On the wild set (3000 VGA frames, single-run medians), the
/// upsampled look after no candidate found 0.5 points more of the markers
/// at +4% of the median time per frame; after at most one, 0.8 points at
/// +7%; after any number, 1.0 point at +13%.
pub(crate) const MAX_PLAIN_READS_TO_UPSAMPLE: usize = 1;

/// Radius, in semi-major axes of the rim, of the middle of a rim looked at
/// by [`worth_upsampling`]: 0.35 a is about 0.29 of the data square's
/// side, inside the square at any tilt the rim stage keeps, where the
/// centre checker and the cells around it lie.
const INTERIOR_PER_AXIS: f64 = 0.35;

/// Least spread (max - min grey) of the rim's middle, as a share of the
/// spread over its whole region, for the upsampled look. On the wild set,
/// of about 10 500 regions the plain look read nothing in, the 96 that the
/// upsampled look read all had a share of at least 0.4; 48% of the others
/// had less than 0.3 (a dark blob or an empty ring).
const MIN_INTERIOR_SPREAD: f64 = 0.3;

/// Half-side, in semi-major axes of the rim, of the part of a region the
/// upsampled look segments ([`Region::tight`]): the black frame's outer
/// corners lie at 1.08 a; a little beyond for perspective. Upsampled, the
/// region costs four times its pixels, so it is cut to the tag.
const UPSAMPLE_PER_AXIS: f64 = 1.15;

/// Margin (full px) of that part beyond the tag: the adaptive threshold's
/// window (10 px of the upsampled image by default) needs background
/// around the black frame.
const UPSAMPLE_MARGIN_PX: f64 = 5.0;

/// Half-side of a region around a rim, in semi-major axes of the rim: the
/// data square's corners are 0.86 a from the centre, the black frame's
/// outer corners 1.08 a; 1.5 a adds the white surround the threshold
/// compares against and room for the rim's centre being off the tag's
/// (perspective).
const REGION_PER_AXIS: f64 = 1.5;

/// Extra margin (full px) on every side of a region: the adaptive
/// threshold's window needs some background beyond the tag's edge.
const REGION_MARGIN_PX: f64 = 6.0;

/// Most regions looked at per frame: bounds the time of a frame full of
/// small round clutter (each region costs about as much as a tag of that
/// size at full resolution).
pub(crate) const MAX_REGIONS: usize = 48;

/// Largest distance (in semi-major axes of the rim) from the rim's centre
/// to the centroid of a candidate taken as its data square. Under
/// perspective the rim's centre and the square's drift apart by a few
/// percent of the axis, but the rim of a disc partly hidden (an occluder,
/// a glare spot) is fitted to the arc left, smaller and off the tag's
/// centre. On the wild set, of the 233 full-resolution candidates within
/// 3 px of the true corners of tags the detector missed, 182 lay within
/// 0.5 a of their rim's centre and 27 more within 0.8 a; at 0.8 a the
/// detector found 19 more of the set's 6001 markers and lost 1 (none
/// rough, no false positive). The data square's corners lie at 0.86 a, so
/// a centroid farther still is a quad of the clutter beside the rim.
const MAX_CENTRE_OFFSET: f64 = 0.8;

/// Longest side (in semi-major axes of the rim) of a candidate taken as
/// its data square: the square's side is a / 0.82 = 1.22 a face-on and
/// shorter under tilt, longer against a rim fitted short to a partly
/// hidden disc (of the 233 candidates above, 210 had sides within 1.6 a
/// and 8 more within 1.9 a). 1.9 a stays under the printed tag's outer
/// square (2.44 a face-on), which is no data square and, taken, would use
/// the attempt that lets the region be looked at upsampled
/// ([`MAX_PLAIN_READS_TO_UPSAMPLE`]): at 2.4 a the detector lost 5 markers.
const MAX_SIDE_PER_AXIS: f64 = 1.9;

/// A rectangle of the full-resolution image, in whole pixels, around one
/// rim.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Region {
    /// Left column.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// Width.
    pub w: u32,
    /// Height.
    pub h: u32,
    /// The rim's centre (full px).
    centre: [f64; 2],
    /// The rim's semi-major axis (full px).
    axis: f64,
}

impl Region {
    /// The part of the region the upsampled look segments: the rim's
    /// square out to [`UPSAMPLE_PER_AXIS`] semi-major axes and
    /// [`UPSAMPLE_MARGIN_PX`] beyond, within the region; `None` if nothing
    /// of it lies there (a rim centred outside the image).
    pub(crate) fn tight(&self) -> Option<Region> {
        let half = UPSAMPLE_PER_AXIS * self.axis + UPSAMPLE_MARGIN_PX;
        let within = ([self.x0, self.y0], [self.x0 + self.w, self.y0 + self.h]);
        square_around(self.centre, self.axis, half, within)
    }

    fn contains(&self, o: &Region) -> bool {
        o.x0 >= self.x0
            && o.y0 >= self.y0
            && o.x0 + o.w <= self.x0 + self.w
            && o.y0 + o.h <= self.y0 + self.h
    }
}

/// The regions to segment again: one square per rim (`ellipses`, in
/// working px at `scale`) of a small tag's size whose centre lies on no
/// printed tag of `found` nor of a data square of a family not decoded
/// (`foreign`, see [`super::decoding::Decoded::foreign`]: the rim is that
/// tag's), clipped to the `width` x `height` image, in the
/// order the rims came, without regions inside an earlier one, at most
/// [`MAX_REGIONS`].
pub(crate) fn regions(
    ellipses: &[Ellipse],
    scale: f64,
    found: &[&Detection],
    foreign: &[Quad],
    width: u32,
    height: u32,
) -> Vec<Region> {
    let max_axis = DISC_PER_SIDE * MAX_SIDE_PX;
    let mut out: Vec<Region> = Vec::new();
    for e in ellipses {
        if out.len() >= MAX_REGIONS {
            break;
        }
        let a = e.a * scale;
        if a > max_axis {
            continue;
        }
        let c = to_full(e.centre, scale);
        if found.iter().any(|d| inside(&printed_square(d), c))
            || foreign.iter().any(|q| inside(&printed_square_of(q), c))
        {
            continue;
        }
        let half = REGION_PER_AXIS * a + REGION_MARGIN_PX;
        let Some(r) = square_around(c, a, half, ([0, 0], [width, height])) else {
            continue;
        };
        if out.iter().any(|o| o.contains(&r)) {
            continue;
        }
        out.push(r);
    }
    out
}

/// The region of whole pixels covering the square of half-side `half`
/// around the rim centre `c` (semi-major axis `axis`), clipped to the
/// pixels `within.0 .. within.1` (top-left inclusive, bottom-right
/// exclusive); `None` if nothing is left.
fn square_around(
    c: [f64; 2],
    axis: f64,
    half: f64,
    within: ([u32; 2], [u32; 2]),
) -> Option<Region> {
    let (lo, hi) = within;
    let clip = |v: f64, k: usize| v.clamp(f64::from(lo[k]), f64::from(hi[k])) as u32;
    let (x0, y0) = (clip(c[0] - half, 0), clip(c[1] - half, 1));
    let (x1, y1) = (
        clip((c[0] + half).ceil() + 1.0, 0),
        clip((c[1] + half).ceil() + 1.0, 1),
    );
    (x1 > x0 && y1 > y0).then_some(Region {
        x0,
        y0,
        w: x1 - x0,
        h: y1 - y0,
        centre: c,
        axis,
    })
}

/// Half-side, in data-square sides, of the square around a found tag in
/// which rims are its own: the printed tag reaches 1.0 (twice the data
/// square), and the blurred corners of its white square against a darker
/// background fit small "rims" just outside it.
const OWN_RIM_REACH: f64 = 1.3;

/// The square around `d` in which rims are its own ([`OWN_RIM_REACH`]),
/// or its data square if the homography cannot map it.
fn printed_square(d: &Detection) -> Quad {
    own_rim_square(&d.homography, d.corners)
}

/// [`printed_square`] of a data square with corners `q` (TL, BL, BR, TR in
/// some turn; the square does not depend on the turn).
fn printed_square_of(q: &Quad) -> Quad {
    Homography::from_points(&CORNERS, q).map_or(*q, |h| own_rim_square(&h, *q))
}

/// The square of [`OWN_RIM_REACH`] about the data square whose homography
/// is `h`, or `fallback` where `h` cannot map its corners.
fn own_rim_square(h: &Homography, fallback: Quad) -> Quad {
    let map = |p: [f64; 2]| h.map(p);
    let r = OWN_RIM_REACH;
    match (map([-r, -r]), map([-r, r]), map([r, r]), map([r, -r])) {
        (Some(a), Some(b), Some(c), Some(e)) => [a, b, c, e],
        _ => fallback,
    }
}

/// `c`, found in region `r` at full resolution (`zoom` 1) or upsampled
/// (`zoom` 2, [`upsample_2x`]), in full-image coordinates, if it can be
/// the data square of the region's rim (centred on it, no larger than it
/// allows): the other quads of a region are clutter beside the rim and are
/// not worth decoding.
pub(crate) fn of_rim(c: &Candidate, r: &Region, zoom: f64) -> Option<Candidate> {
    let (dx, dy) = (f64::from(r.x0), f64::from(r.y0));
    // Pixel centres: pixel u of the upsampled image is centred on
    // (u + 0.5) / zoom - 0.5 of the region.
    let back = |v: f64| (v + 0.5) / zoom - 0.5;
    let mv = |p: [f64; 2]| [back(p[0]) + dx, back(p[1]) + dy];
    let q = c.corners.map(mv);
    if dist(centroid(&q), r.centre) > MAX_CENTRE_OFFSET * r.axis {
        return None;
    }
    if (0..4).any(|i| dist(q[i], q[(i + 1) % 4]) > MAX_SIDE_PER_AXIS * r.axis) {
        return None;
    }
    let mut out = *c;
    out.corners = q;
    for e in out.edges.iter_mut().flatten() {
        e.incoming = e.incoming.map(mv);
        e.outgoing = e.outgoing.map(mv);
    }
    out.anchor = c.anchor.map(mv);
    Some(out)
}

/// `img` upsampled 2x into `out` (packed rows), bilinear on pixel
/// centres: output pixel u samples the input at u / 2 - 0.25, so each
/// output pixel is 3/4 of its own input pixel and 1/4 of the neighbour on
/// its side (the border pixel repeated). Separable: rows first, then
/// columns. Written here rather than taken from `image::imageops::resize`,
/// which allocates a float image per call and filters with wider kernels;
/// this is one pass over a small region. Returns the output's size.
pub(crate) fn upsample_2x(
    img: &GrayView<'_>,
    rows: &mut Vec<u16>,
    out: &mut Vec<u8>,
) -> (u32, u32) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let (w2, h2) = (2 * w, 2 * h);
    // Horizontal pass, kept in quarters (4 x the grey level).
    rows.clear();
    rows.resize(w2 * h, 0);
    for y in 0..h {
        let src = img.row(y);
        let dst = &mut rows[y * w2..(y + 1) * w2];
        for x in 0..w {
            let here = 3 * u16::from(src[x]);
            let left = u16::from(src[x.saturating_sub(1)]);
            let right = u16::from(src[(x + 1).min(w - 1)]);
            dst[2 * x] = here + left;
            dst[2 * x + 1] = here + right;
        }
    }
    // Vertical pass: 3/4 and 1/4 of the quarters, rounded (/16).
    out.clear();
    out.resize(w2 * h2, 0);
    for y in 0..h {
        let here = &rows[y * w2..(y + 1) * w2];
        let up = &rows[y.saturating_sub(1) * w2..][..w2];
        let down = &rows[(y + 1).min(h - 1) * w2..][..w2];
        for (k, other) in [(2 * y, up), (2 * y + 1, down)] {
            let dst = &mut out[k * w2..(k + 1) * w2];
            for ((d, &a), &b) in dst.iter_mut().zip(here).zip(other) {
                *d = ((3 * u32::from(a) + u32::from(b) + 8) / 16) as u8;
            }
        }
    }
    (w2 as u32, h2 as u32)
}

/// Least spread (max - min grey) of the rim's middle, as a share of the
/// spread over its whole region, for the region to be looked at at all
/// ([`worth_looking`]). A tag's cells and centre checker fill the middle
/// of its disc with dark and light; a solid blob or an empty ring of
/// clutter, which the rim stage finds as readily, leaves it flat. On the
/// wild set (3000 frames, 15 600 regions) the regions that read a tag had
/// a share of 0.17 or more, on its ct8 twin 0.35, on the sigma calibration
/// set 0.21; under 0.12 lay 30% of the regions that read nothing (4300 on
/// the wild set, 0.1 ms a frame of the looks' time; 60 of the 22 bench
/// frames' 292, 0.2 ms a frame). Looking at them costs a segmentation of
/// the region each.
const MIN_LOOK_SPREAD: f64 = 0.12;

/// Whether a region whose rim's middle is `m` is looked at again at full
/// resolution: the middle is not flat ([`MIN_LOOK_SPREAD`]).
pub(crate) fn worth_looking(m: Middle) -> bool {
    m.spread_at_least(MIN_LOOK_SPREAD)
}

/// Whether region `r`, whose rim's middle is `m`, gets the upsampled look:
/// its rim is small enough ([`UPSAMPLE_BELOW_SIDE_PX`]) and the middle of
/// the rim holds both dark and light pixels, as a tag's cells and centre
/// checker do, with a spread of at least [`MIN_INTERIOR_SPREAD`] of the
/// region's. A solid dark blob or an empty ring of clutter, which the rim
/// stage finds as readily as a tag's disc, is passed over.
pub(crate) fn worth_upsampling(r: &Region, m: Middle) -> bool {
    r.axis < DISC_PER_SIDE * UPSAMPLE_BELOW_SIDE_PX && m.spread_at_least(MIN_INTERIOR_SPREAD)
}

/// The grey-level spreads (max - min) of a region: of the middle of its
/// rim (within [`INTERIOR_PER_AXIS`] semi-major axes of the rim's centre)
/// and of the whole region. Measured once per region ([`Middle::of`]) for
/// both looks' tests ([`worth_looking`], [`worth_upsampling`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Middle {
    spread: u8,
    region: u8,
}

impl Middle {
    /// The spreads of region `r` of `img`.
    pub(crate) fn of(img: &GrayView<'_>, r: &Region) -> Self {
        let rad = INTERIOR_PER_AXIS * r.axis;
        let (mut lo, mut hi, mut all_lo, mut all_hi) = (u8::MAX, 0, u8::MAX, 0);
        for y in r.y0..r.y0 + r.h {
            let row = &img.row(y as usize)[r.x0 as usize..(r.x0 + r.w) as usize];
            let dy = f64::from(y) - r.centre[1];
            for (x, &v) in (r.x0..).zip(row) {
                all_lo = all_lo.min(v);
                all_hi = all_hi.max(v);
                let dx = f64::from(x) - r.centre[0];
                if dx * dx + dy * dy <= rad * rad {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
        }
        Self {
            spread: hi.saturating_sub(lo),
            region: all_hi.saturating_sub(all_lo),
        }
    }

    /// Whether the middle spreads at all, and by at least `share` of the
    /// region's spread.
    fn spread_at_least(self, share: f64) -> bool {
        self.spread > 0 && f64::from(self.spread) >= share * f64::from(self.region)
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rim(centre: [f64; 2], a: f64) -> Ellipse {
        Ellipse {
            centre,
            a,
            b: a * 0.8,
            anchor: centre,
            checker: false,
            axis: [1.0, 0.0],
            pieced: false,
        }
    }

    #[test]
    fn regions_cover_small_rims_only_and_stay_in_the_image() {
        // Working px at scale 2: a rim of semi-major axis 10 is 20 full px
        // (a data square of about 24 px); 40 is a 98 px square.
        let rims = [
            rim([20.0, 20.0], 10.0),
            rim([100.0, 60.0], 40.0),
            rim([2.0, 3.0], 8.0),
        ];
        let r = regions(&rims, 2.0, &[], &[], 320, 240);
        assert_eq!(r.len(), 2, "{r:?}");
        // Centre (40.5, 40.5) full px, half-side 1.5 x 20 + 6 = 36.
        assert_eq!((r[0].x0, r[0].y0, r[0].w, r[0].h), (4, 4, 74, 74));
        // Clipped at the image's top-left.
        assert_eq!((r[1].x0, r[1].y0), (0, 0));
        assert!(r.iter().all(|q| q.x0 + q.w <= 320 && q.y0 + q.h <= 240));
        // A data square of a family not decoded (24 px, about the first
        // rim's) takes its rim's region away, and only its.
        let q = [[28.5, 28.5], [28.5, 52.5], [52.5, 52.5], [52.5, 28.5]];
        let r = regions(&rims, 2.0, &[], &[q], 320, 240);
        assert_eq!(r.len(), 1, "{r:?}");
        assert_eq!((r[0].x0, r[0].y0), (0, 0));
    }

    #[test]
    fn the_upsampled_part_stays_in_its_region_or_is_none() {
        let r = regions(&[rim([20.0, 20.0], 10.0)], 2.0, &[], &[], 320, 240)[0];
        // Centre (40.5, 40.5), axis 20: half-side 1.15 x 20 + 5 = 28.
        let t = r.tight().unwrap();
        assert_eq!((t.x0, t.y0, t.w, t.h), (12, 12, 58, 58));
        assert!(r.contains(&t));
        // A rim centred off the image's left edge: its region holds only
        // the first columns, and the tighter square none of them.
        let off = regions(&[rim([-16.0, 50.0], 10.0)], 2.0, &[], &[], 320, 240);
        assert_eq!((off[0].x0, off[0].w), (0, 6), "{off:?}");
        assert!(off[0].tight().is_none());
    }

    #[test]
    fn upsampling_keeps_flat_grey_and_puts_pixel_centres_right() {
        let (mut rows, mut out) = (Vec::new(), Vec::new());
        let flat = [77u8; 12];
        let (w, h) = upsample_2x(&GrayView::packed(&flat, 4, 3), &mut rows, &mut out);
        assert_eq!((w, h), (8, 6));
        assert!(out.iter().all(|&v| v == 77));
        // A vertical step 0 | 160 between columns 1 and 2: output column u
        // samples u / 2 - 0.25, so columns 3 and 4 (1.25 and 1.75) are a
        // quarter and three quarters of the way up; rows are unchanged.
        let step: Vec<u8> = (0..12).map(|i| if i % 4 < 2 { 0 } else { 160 }).collect();
        upsample_2x(&GrayView::packed(&step, 4, 3), &mut rows, &mut out);
        for y in 0..6 {
            assert_eq!(
                &out[y * 8..y * 8 + 8],
                &[0, 0, 0, 40, 120, 160, 160, 160],
                "row {y}"
            );
        }
    }

    #[test]
    fn only_small_rims_with_a_patterned_middle_are_upsampled() {
        // A 60 x 60 image: a dark disc of radius 14 on white, at (30, 30).
        let disc = |inside: &dyn Fn(usize, usize) -> u8| -> Vec<u8> {
            (0..3600)
                .map(|i| {
                    let (x, y) = (i % 60, i / 60);
                    let d2 = (x as f64 - 30.0).powi(2) + (y as f64 - 30.0).powi(2);
                    if d2 <= 14.0 * 14.0 {
                        inside(x, y)
                    } else {
                        230
                    }
                })
                .collect()
        };
        let region = |axis: f64| Region {
            x0: 0,
            y0: 0,
            w: 60,
            h: 60,
            centre: [30.0, 30.0],
            axis,
        };
        let solid = disc(&|_, _| 20);
        let cells = disc(&|x, y| if (x / 2 + y / 2) % 2 == 0 { 20 } else { 220 });
        let (solid, cells) = (
            GrayView::packed(&solid, 60, 60),
            GrayView::packed(&cells, 60, 60),
        );
        let looked = |img: &GrayView<'_>, r: Region| worth_looking(Middle::of(img, &r));
        let upsampled = |img: &GrayView<'_>, r: Region| worth_upsampling(&r, Middle::of(img, &r));
        assert!(!upsampled(&solid, region(14.0)), "a solid blob");
        assert!(upsampled(&cells, region(14.0)), "a tag-like middle");
        // A rim of a 40 px data square or larger: the plain look suffices.
        let big = DISC_PER_SIDE * UPSAMPLE_BELOW_SIDE_PX;
        assert!(!upsampled(&cells, region(big)));
        // The plain look takes any rim whose middle is not flat, large or
        // not; a middle whose spread is a fifth of the region's (a faint
        // or blurred tag) is looked at though not upsampled.
        assert!(!looked(&solid, region(14.0)), "a solid blob");
        assert!(looked(&cells, region(big)), "a tag-like middle");
        let faint = disc(&|x, y| if (x / 2 + y / 2) % 2 == 0 { 20 } else { 62 });
        let faint = GrayView::packed(&faint, 60, 60);
        assert!(looked(&faint, region(14.0)));
        assert!(!upsampled(&faint, region(14.0)));
    }

    #[test]
    fn a_region_inside_another_is_dropped() {
        let rims = [rim([50.0, 50.0], 20.0), rim([50.5, 50.0], 10.0)];
        assert_eq!(regions(&rims, 2.0, &[], &[], 640, 480).len(), 1);
    }

    #[test]
    fn regions_stop_at_the_cap() {
        let rims: Vec<_> = (0..100)
            .map(|i| {
                rim(
                    [
                        10.0 + 30.0 * f64::from(i % 20),
                        10.0 + 30.0 * f64::from(i / 20),
                    ],
                    5.0,
                )
            })
            .collect();
        assert_eq!(regions(&rims, 2.0, &[], &[], 1280, 960).len(), MAX_REGIONS);
    }
}

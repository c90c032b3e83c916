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
//! This is the "search at a second scale only where candidates are
//! small" idea; AprilTag 3 instead refines its decimated quads' edges at
//! full resolution (`refine_edges`), which needs a quad to exist first.

use super::ellipses::Ellipse;
use super::quads::Candidate;
use super::Detection;
use crate::math::{inside, to_full};

/// Ratio of the disc's radius to the data square's side: the black disc
/// ends at about 0.82 S (the format's geometry, step 9).
const DISC_PER_SIDE: f64 = 0.82;

/// Largest data-square side (full px) looked at again: above it, cells are
/// over 2 px at half resolution (ct14: 64 / 16 / 2), enough for the
/// downsampled pass. A rim of a larger tag that did not decode there is
/// damaged, not too small, and a second look would only cost time.
pub(crate) const MAX_SIDE_PX: f64 = 64.0;

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
/// percent of the axis; the data square's corners lie at 0.86 a, so a
/// centroid farther than 0.35 a is a quad of the clutter beside the rim.
const MAX_CENTRE_OFFSET: f64 = 0.5;

/// Longest side (in semi-major axes of the rim) of a candidate taken as
/// its data square: the square's side is a / 0.82 = 1.22 a face-on and
/// shorter under tilt; 1.6 a leaves room for a rim fitted short.
const MAX_SIDE_PER_AXIS: f64 = 1.6;

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
    fn contains(&self, o: &Region) -> bool {
        o.x0 >= self.x0
            && o.y0 >= self.y0
            && o.x0 + o.w <= self.x0 + self.w
            && o.y0 + o.h <= self.y0 + self.h
    }
}

/// The regions to segment again: one square per rim (`ellipses`, in
/// working px at `scale`) of a small tag's size whose centre lies on no
/// printed tag of `found`, clipped to the `width` x `height` image, in the
/// order the rims came, without regions inside an earlier one, at most
/// [`MAX_REGIONS`].
pub(crate) fn regions(
    ellipses: &[Ellipse],
    scale: f64,
    found: &[&Detection],
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
        if found.iter().any(|d| inside(&printed_square(d), c)) {
            continue;
        }
        let half = REGION_PER_AXIS * a + REGION_MARGIN_PX;
        let clip = |v: f64, hi: u32| v.clamp(0.0, f64::from(hi)) as u32;
        let (x0, y0) = (clip(c[0] - half, width), clip(c[1] - half, height));
        let (x1, y1) = (
            clip((c[0] + half).ceil() + 1.0, width),
            clip((c[1] + half).ceil() + 1.0, height),
        );
        if x1 <= x0 || y1 <= y0 {
            continue;
        }
        let r = Region {
            x0,
            y0,
            w: x1 - x0,
            h: y1 - y0,
            centre: c,
            axis: a,
        };
        if out.iter().any(|o| o.contains(&r)) {
            continue;
        }
        out.push(r);
    }
    out
}

/// Half-side, in data-square sides, of the square around a found tag in
/// which rims are its own: the printed tag reaches 1.0 (twice the data
/// square), and the blurred corners of its white square against a darker
/// background fit small "rims" just outside it.
const OWN_RIM_REACH: f64 = 1.3;

/// The square around `d` in which rims are its own ([`OWN_RIM_REACH`]),
/// or its data square if the homography cannot map it.
fn printed_square(d: &Detection) -> [[f64; 2]; 4] {
    let map = |p: [f64; 2]| d.homography.map(p);
    let r = OWN_RIM_REACH;
    match (map([-r, -r]), map([-r, r]), map([r, r]), map([r, -r])) {
        (Some(a), Some(b), Some(c), Some(e)) => [a, b, c, e],
        _ => d.corners,
    }
}

/// `c`, found in region `r` at full resolution, in full-image
/// coordinates, if it can be the data square of the region's rim (centred
/// on it, no larger than it allows): the other quads of a region are
/// clutter beside the rim and are not worth decoding.
pub(crate) fn of_rim(c: &Candidate, r: &Region) -> Option<Candidate> {
    let (dx, dy) = (f64::from(r.x0), f64::from(r.y0));
    let mv = |p: [f64; 2]| [p[0] + dx, p[1] + dy];
    let q = c.corners.map(mv);
    let centroid = [
        (q[0][0] + q[1][0] + q[2][0] + q[3][0]) / 4.0,
        (q[0][1] + q[1][1] + q[2][1] + q[3][1]) / 4.0,
    ];
    if dist(centroid, r.centre) > MAX_CENTRE_OFFSET * r.axis {
        return None;
    }
    if (0..4).any(|i| dist(q[i], q[(i + 1) % 4]) > MAX_SIDE_PER_AXIS * r.axis) {
        return None;
    }
    let mut out = *c;
    out.corners = c.corners.map(mv);
    for e in out.edges.iter_mut().flatten() {
        e.incoming = e.incoming.map(mv);
        e.outgoing = e.outgoing.map(mv);
    }
    out.anchor = c.anchor.map(mv);
    Some(out)
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
        let r = regions(&rims, 2.0, &[], 320, 240);
        assert_eq!(r.len(), 2, "{r:?}");
        // Centre (40.5, 40.5) full px, half-side 1.5 x 20 + 6 = 36.
        assert_eq!((r[0].x0, r[0].y0, r[0].w, r[0].h), (4, 4, 74, 74));
        // Clipped at the image's top-left.
        assert_eq!((r[1].x0, r[1].y0), (0, 0));
        assert!(r.iter().all(|q| q.x0 + q.w <= 320 && q.y0 + q.h <= 240));
    }

    #[test]
    fn a_region_inside_another_is_dropped() {
        let rims = [rim([50.0, 50.0], 20.0), rim([50.5, 50.0], 10.0)];
        assert_eq!(regions(&rims, 2.0, &[], 640, 480).len(), 1);
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
        assert_eq!(regions(&rims, 2.0, &[], 1280, 960).len(), MAX_REGIONS);
    }
}

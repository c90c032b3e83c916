//! Stage 3b: corners from adjacent lines (second half of the paper's
//! Algorithm 1).
//!
//! Two consecutive lines of a border form a corner when they meet at more
//! than theta (22.5 degrees), their facing ends are closer than psi, and the
//! turn from the incoming to the outgoing line is anticlockwise on screen
//! (negative cross product in y-down coordinates). With lines oriented dark
//! on the right, that keeps exactly the convex corners of white regions:
//! the four corners of the white data square, each seen as the meeting of
//! two sides of the black frame.

use super::lines::{Line, Polygons};
use super::parallel::{collect_ranges, Workers};
use crate::math::{cross, intersect, norm, sub};

/// A straight piece of a border, start and end point.
pub(crate) type Segment = [[f64; 2]; 2];

/// A corner: where an incoming line meets an outgoing line.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Corner {
    /// Intersection of the two lines (working-image coordinates).
    pub pos: [f64; 2],
    /// Direction of the incoming line (arriving at the corner).
    pub din: [f64; 2],
    /// Direction of the outgoing line (leaving the corner).
    pub dout: [f64; 2],
    /// The incoming line piece, start and end (working-image coordinates):
    /// the edge seen on the side arriving at the corner.
    pub seg_in: Segment,
    /// The outgoing line piece, start and end.
    pub seg_out: Segment,
    /// Contour the lines came from.
    pub contour: u32,
    /// The incoming and outgoing lines (indices into the frame's lines):
    /// the quad search asks whether a side runs along one chain of
    /// bridged pieces (see `bridges`).
    pub lines: [u32; 2],
    /// A gap corner (see `bridges`): its lines meet across a gap cut by an
    /// occluder, so the point itself is computed, not seen.
    pub gap: bool,
}

/// Corner-forming parameters, from [`crate::DetectorConfig`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct CornerParams {
    /// Sine of theta, the smallest angle between the two lines (theta is
    /// `corner_min_angle_deg`); the sine also rejects angles above
    /// 180 - theta (hairpins).
    pub sin_min_angle: f64,
    /// psi: largest gap between the facing line ends (working px).
    pub max_gap: f64,
}

/// The intersection of a corner's two lines may lie at most this many times
/// psi from each facing line end: a shallow intersection far away is not a
/// corner.
pub(crate) const REACH_PER_GAP: f64 = 2.0;

fn corner(
    lines: &[Line],
    a: usize,
    b: usize,
    contour: u32,
    params: &CornerParams,
) -> Option<Corner> {
    let (l, m) = (&lines[a], &lines[b]);
    let s = cross(l.dir, m.dir);
    // Angle between the directions above theta (and below 180 - theta:
    // hairpins are not corners).
    if s.abs() < params.sin_min_angle {
        return None;
    }
    let d1 = norm(sub(l.pe, m.ps));
    let d2 = norm(sub(l.ps, m.pe));
    let (lin, lout) = if d1 < d2 && d1 < params.max_gap {
        (a, b)
    } else if d2 < d1 && d2 < params.max_gap {
        (b, a)
    } else {
        return None;
    };
    let (li, lo) = (&lines[lin], &lines[lout]);
    if cross(li.dir, lo.dir) >= 0.0 {
        return None;
    }
    let pos = intersect(li.pe, li.dir, lo.ps, lo.dir)?;
    // The corner must be near the facing ends (a shallow intersection far
    // away is not a corner).
    let reach = REACH_PER_GAP * params.max_gap;
    if norm(sub(pos, li.pe)) > reach || norm(sub(pos, lo.ps)) > reach {
        return None;
    }
    Some(Corner {
        pos,
        din: li.dir,
        dout: lo.dir,
        seg_in: [li.ps, li.pe],
        seg_out: [lo.ps, lo.pe],
        contour,
        lines: [lin as u32, lout as u32],
        gap: false,
    })
}

/// Forms the corners of every contour's consecutive lines (cyclically),
/// on `workers`' threads if given (in runs of borders, the same corners
/// either way).
pub(crate) fn find_corners<W: Default + Send>(
    polys: &Polygons,
    params: &CornerParams,
    workers: Option<&Workers<W>>,
    out: &mut Vec<Corner>,
) {
    out.clear();
    let n = polys.line_ranges.len();
    collect_ranges(workers, n, MIN_BORDERS_PER_PIECE, out, |r, out| {
        corners_of(polys, r, params, out);
    });
}

/// Fewest borders in one piece of [`find_corners`]' parallel work (a few
/// lines each, each pair a handful of operations).
const MIN_BORDERS_PER_PIECE: usize = 256;

/// The corners of the borders `range`, appended to `out`.
fn corners_of(
    polys: &Polygons,
    range: std::ops::Range<usize>,
    params: &CornerParams,
    out: &mut Vec<Corner>,
) {
    let first = range.start;
    for (ci, &(l0, l1)) in polys.line_ranges[range].iter().enumerate() {
        let ci = first + ci;
        let (l0, l1) = (l0 as usize, l1 as usize);
        let k = l1 - l0;
        if k < 2 {
            continue;
        }
        for i in 0..k {
            // With two lines only, one pair.
            if k == 2 && i == 1 {
                break;
            }
            let a = l0 + i;
            let b = l0 + (i + 1) % k;
            if let Some(c) = corner(&polys.lines, a, b, ci as u32, params) {
                out.push(c);
            }
        }
    }
}

//! Stage 3a: polygon approximation of every border and line fitting
//! (first half of the paper's Algorithm 1).
//!
//! Each closed border is approximated by the Douglas-Peucker algorithm
//! (Douglas & Peucker, "Algorithms for the reduction of the number of points
//! required to represent a digitized line or its caricature", 1973). Every
//! polygon side longer than tau becomes a line, refined by a total least
//! squares fit to the border points between its two vertices, with the
//! points nearest the vertices left out (they are where corners are rounded
//! by blur and thresholding; the paper re-runs DP within 7 px of each end
//! for the same purpose). Lines are oriented with the dark side on their
//! right; the border follower always has the dark side on its left, so
//! lines are simply reversed and no gradient has to be sampled.

use super::contours::Contours;
use super::parallel::Workers;
use crate::math::{cross, dot, fit_line, fp, norm, sub};

/// A fitted line segment in working-image coordinates, dark on its right.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line {
    /// Start point (projected onto the fitted line).
    pub ps: [f64; 2],
    /// End point.
    pub pe: [f64; 2],
    /// Unit direction from `ps` to `pe`.
    pub dir: [f64; 2],
}

/// Parameters of the line stage, from [`crate::DetectorConfig`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct LineParams {
    /// Douglas-Peucker tolerance: largest distance (working px) of a border
    /// point from the polygon side that replaces it.
    pub dp_epsilon: f64,
    /// tau: shortest polygon side (working px) that becomes a line.
    pub min_length: f64,
}

/// Lines and polygon vertices of every contour.
#[derive(Debug, Default)]
pub(crate) struct Polygons {
    /// DP vertex indices (into the contour's points) of every contour.
    pub vertices: Vec<u32>,
    /// Per contour: range into `vertices`.
    pub vertex_ranges: Vec<(u32, u32)>,
    /// All lines.
    pub lines: Vec<Line>,
    /// Per contour: range into `lines`, in traversal order.
    pub line_ranges: Vec<(u32, u32)>,
    stack: Vec<(usize, usize)>,
}

/// Fewest vertices of a border's polygon: vertices are never removed
/// below a triangle.
const MIN_POLYGON: usize = 3;

/// A chord shorter than this (px) is a point: distances are measured to it
/// instead of to the line through it.
const DEGENERATE_CHORD: f64 = 1e-9;

/// Two consecutive polygon sides turning by less than this (degrees) are
/// merged into one when the merged side stays within [`MERGE_SLACK`] times
/// the Douglas-Peucker tolerance of the border (digitised edges at small
/// angles are staircases, and DP can cut a short stair off a side).
const MERGE_TURN_DEG: f64 = 10.0;

/// Tolerance of a merged side, in multiples of the DP tolerance.
const MERGE_SLACK: f64 = 2.0;

/// A line fit leaves out one border point in `TRIM_DIVISOR` at each end of
/// its side, at most [`MAX_TRIM`]: those are where blur and thresholding
/// round the corners.
const TRIM_DIVISOR: usize = 6;

/// Most border points left out at each end of a side by the line fit.
const MAX_TRIM: usize = 2;

/// Douglas-Peucker on a closed border: vertex indices into `pts`, sorted.
/// The first split is at the point farthest from `pts[0]` (the border
/// follower starts at an extreme point, which is a vertex of the shape).
fn dp_closed(pts: &[[i32; 2]], eps: f64, stack: &mut Vec<(usize, usize)>, out: &mut Vec<u32>) {
    let n = pts.len();
    if n < MIN_POLYGON {
        return;
    }
    let first = out.len();
    let p0 = fp(pts[0]);
    let far = (1..n)
        .max_by(|&a, &b| {
            let da = norm(sub(fp(pts[a]), p0));
            let db = norm(sub(fp(pts[b]), p0));
            da.total_cmp(&db)
        })
        .unwrap_or(1);
    stack.clear();
    // Processed left to right: push the right half first.
    stack.push((far, n));
    stack.push((0, far));
    while let Some((i, j)) = stack.pop() {
        if j <= i + 1 {
            out.push(i as u32);
            continue;
        }
        let a = fp(pts[i]);
        let b = fp(pts[j % n]);
        let ab = sub(b, a);
        let l = norm(ab);
        let mut best = (0.0, i);
        for (m, p) in pts.iter().enumerate().take(j).skip(i + 1) {
            let ap = sub(fp(*p), a);
            let d = if l > DEGENERATE_CHORD {
                cross(ab, ap).abs() / l
            } else {
                norm(ap)
            };
            if d > best.0 {
                best = (d, m);
            }
        }
        if best.0 > eps {
            stack.push((best.1, j));
            stack.push((i, best.1));
        } else {
            out.push(i as u32);
        }
    }
    // The start point and the first split are forced vertices; drop each
    // when the border is straight through it (else it cuts a side in two).
    for forced in [far as u32, 0] {
        let v = &out[first..];
        let m = v.len();
        if m <= MIN_POLYGON {
            break;
        }
        let Some(k) = v.iter().position(|&x| x == forced) else {
            continue;
        };
        let a = v[(k + m - 1) % m] as usize;
        let b = v[(k + 1) % m] as usize;
        let b = if b <= a { b + n } else { b };
        if max_deviation(pts, a, b) <= eps {
            out.remove(first + k);
        }
    }
    // Digitised edges at small angles are staircases; DP can cut a short
    // stair off a side near its end. Merge sides that turn by less than
    // ten degrees when the merged side stays within twice the tolerance.
    let cos_merge = MERGE_TURN_DEG.to_radians().cos();
    let mut k = 0;
    while out.len() - first > MIN_POLYGON && k < out.len() - first {
        let v = &out[first..];
        let m = v.len();
        let (a, x, b) = (
            v[(k + m - 1) % m] as usize,
            v[k] as usize,
            v[(k + 1) % m] as usize,
        );
        let d1 = sub(fp(pts[x]), fp(pts[a]));
        let d2 = sub(fp(pts[b]), fp(pts[x]));
        let (n1, n2) = (norm(d1), norm(d2));
        let straight = n1 > 0.0 && n2 > 0.0 && dot(d1, d2) > cos_merge * n1 * n2;
        let b2 = if b <= a { b + n } else { b };
        if straight && max_deviation(pts, a, b2) <= MERGE_SLACK * eps {
            out.remove(first + k);
        } else {
            k += 1;
        }
    }
}

/// Largest distance of the points strictly between `i` and `j` (cyclic)
/// from the chord joining them.
fn max_deviation(pts: &[[i32; 2]], i: usize, j: usize) -> f64 {
    let n = pts.len();
    let a = fp(pts[i % n]);
    let ab = sub(fp(pts[j % n]), a);
    let l = norm(ab);
    (i + 1..j)
        .map(|m| {
            let ap = sub(fp(pts[m % n]), a);
            if l > DEGENERATE_CHORD {
                cross(ab, ap).abs() / l
            } else {
                norm(ap)
            }
        })
        .fold(0.0, f64::max)
}

/// The line of the polygon side through border points `i..=j` (cyclic
/// indices) of `pts`: [`fit_line`] to them, leaving out `trim` points at each end; oriented from `pts[i]` to
/// `pts[j]`, endpoints are those two points projected on the line.
pub(crate) fn side_line(pts: &[[i32; 2]], i: usize, j: usize, trim: usize) -> Option<Line> {
    let n = pts.len();
    let count = j - i + 1;
    if count < 2 + 2 * trim {
        return None;
    }
    let fit = fit_line((i + trim..=j - trim).map(|k| fp(pts[k % n])))?;
    let c = fit.centre;
    let mut dir = fit.dir;
    let a = fp(pts[i % n]);
    let b = fp(pts[j % n]);
    if dot(dir, sub(b, a)) < 0.0 {
        dir = [-dir[0], -dir[1]];
    }
    let ta = dot(sub(a, c), dir);
    let tb = dot(sub(b, c), dir);
    let ps = [c[0] + ta * dir[0], c[1] + ta * dir[1]];
    let pe = [c[0] + tb * dir[0], c[1] + tb * dir[1]];
    Some(Line { ps, pe, dir })
}

/// Approximates every contour and fits its lines (sides at least
/// `min_len` long). Lines of a contour are kept in traversal order; borders
/// are traversed with the dark side on the left, so each line is reversed
/// to have the dark side on its right.
/// On `workers`' threads if given, in runs of borders of about equal
/// points (the same polygons and lines either way).
pub(crate) fn extract<W: Default + Send>(
    contours: &Contours,
    params: &LineParams,
    workers: Option<&Workers<W>>,
    out: &mut Polygons,
) {
    out.vertices.clear();
    out.vertex_ranges.clear();
    out.lines.clear();
    out.line_ranges.clear();
    let n = contours.list.len();
    let Some(w) = workers else {
        extract_range(contours, 0..n, params, out);
        return;
    };
    let points = |i: usize| contours.list[i].len as usize;
    let parts = w.map_weighted(n, points, MIN_POINTS_PER_PIECE, |r| {
        let mut part = Polygons::default();
        extract_range(contours, r, params, &mut part);
        part
    });
    for part in parts {
        let (v, l) = (out.vertices.len() as u32, out.lines.len() as u32);
        out.vertices.extend(part.vertices);
        out.lines.extend(part.lines);
        let shift = |(a, b): (u32, u32), by: u32| (a + by, b + by);
        out.vertex_ranges
            .extend(part.vertex_ranges.into_iter().map(|r| shift(r, v)));
        out.line_ranges
            .extend(part.line_ranges.into_iter().map(|r| shift(r, l)));
    }
}

/// Fewest border points in one piece of [`extract`]'s parallel work (a
/// point costs some tens of nanoseconds; a piece should take more than
/// handing it to a thread). Pieces are cut by points, not borders: the
/// frame's longest borders hold most of its points.
const MIN_POINTS_PER_PIECE: usize = 2048;

/// [`extract`] of the borders `range`, appended to `out`.
fn extract_range(
    contours: &Contours,
    range: std::ops::Range<usize>,
    params: &LineParams,
    out: &mut Polygons,
) {
    let (eps, min_len) = (params.dp_epsilon, params.min_length);
    for c in &contours.list[range] {
        let pts = contours.points_of(c);
        let v0 = out.vertices.len();
        dp_closed(pts, eps, &mut out.stack, &mut out.vertices);
        let v1 = out.vertices.len();
        out.vertex_ranges.push((v0 as u32, v1 as u32));
        let l0 = out.lines.len();
        lines_of(pts, &out.vertices[v0..v1], min_len, &mut out.lines);
        out.line_ranges.push((l0 as u32, out.lines.len() as u32));
    }
}

fn lines_of(pts: &[[i32; 2]], verts: &[u32], min_len: f64, lines: &mut Vec<Line>) {
    let n = pts.len();
    let m = verts.len();
    if m < 2 {
        return;
    }
    for k in 0..m {
        let i = verts[k] as usize;
        let j = if k + 1 < m {
            verts[k + 1] as usize
        } else {
            verts[0] as usize + n
        };
        let chord = norm(sub(fp(pts[j % n]), fp(pts[i])));
        if chord < min_len {
            continue;
        }
        let trim = ((j - i) / TRIM_DIVISOR).min(MAX_TRIM);
        if let Some(mut l) = side_line(pts, i, j, trim) {
            std::mem::swap(&mut l.ps, &mut l.pe);
            l.dir = [-l.dir[0], -l.dir[1]];
            lines.push(l);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dp_square_has_four_vertices() {
        let mut pts = Vec::new();
        for x in 0..10 {
            pts.push([x, 0]);
        }
        for y in 0..10 {
            pts.push([10, y]);
        }
        for x in (1..=10).rev() {
            pts.push([x, 10]);
        }
        for y in (1..=10).rev() {
            pts.push([0, y]);
        }
        let mut out = Vec::new();
        dp_closed(&pts, 1.0, &mut Vec::new(), &mut out);
        assert_eq!(out.len(), 4, "{out:?}");
    }
}

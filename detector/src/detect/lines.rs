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

#[inline]
pub(crate) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
#[inline]
pub(crate) fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
#[inline]
pub(crate) fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}
#[inline]
pub(crate) fn norm(a: [f64; 2]) -> f64 {
    a[0].hypot(a[1])
}
/// `v` scaled to unit length (a zero vector stays near zero, not NaN).
#[inline]
pub(crate) fn unit(v: [f64; 2]) -> [f64; 2] {
    let n = norm(v).max(1e-12);
    [v[0] / n, v[1] / n]
}
#[inline]
fn fp(p: [i32; 2]) -> [f64; 2] {
    [f64::from(p[0]), f64::from(p[1])]
}

/// Douglas-Peucker on a closed border: vertex indices into `pts`, sorted.
/// The first split is at the point farthest from `pts[0]` (the border
/// follower starts at an extreme point, which is a vertex of the shape).
fn dp_closed(pts: &[[i32; 2]], eps: f64, stack: &mut Vec<(usize, usize)>, out: &mut Vec<u32>) {
    let n = pts.len();
    if n < 3 {
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
            let d = if l > 1e-9 {
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
        if m <= 3 {
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
    let cos_merge = 10f64.to_radians().cos();
    let mut k = 0;
    while out.len() - first > 3 && k < out.len() - first {
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
        if straight && max_deviation(pts, a, b2) <= 2.0 * eps {
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
            if l > 1e-9 {
                cross(ab, ap).abs() / l
            } else {
                norm(ap)
            }
        })
        .fold(0.0, f64::max)
}

/// Total least squares line through points `i..=j` (cyclic indices) of
/// `pts`, leaving out `trim` points at each end; oriented from `pts[i]` to
/// `pts[j]`, endpoints are those two points projected on the line.
pub(crate) fn fit_line(pts: &[[i32; 2]], i: usize, j: usize, trim: usize) -> Option<Line> {
    let n = pts.len();
    let count = j - i + 1;
    if count < 2 + 2 * trim {
        return None;
    }
    let (mut sx, mut sy) = (0.0, 0.0);
    let k0 = i + trim;
    let k1 = j - trim;
    let m = (k1 - k0 + 1) as f64;
    for k in k0..=k1 {
        let p = fp(pts[k % n]);
        sx += p[0];
        sy += p[1];
    }
    let c = [sx / m, sy / m];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for k in k0..=k1 {
        let p = sub(fp(pts[k % n]), c);
        sxx += p[0] * p[0];
        sxy += p[0] * p[1];
        syy += p[1] * p[1];
    }
    let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut dir = [th.cos(), th.sin()];
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
pub(crate) fn extract(contours: &Contours, eps: f64, min_len: f64, out: &mut Polygons) {
    out.vertices.clear();
    out.vertex_ranges.clear();
    out.lines.clear();
    out.line_ranges.clear();
    for c in &contours.list {
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
        let trim = ((j - i) / 6).min(2);
        if let Some(mut l) = fit_line(pts, i, j, trim) {
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

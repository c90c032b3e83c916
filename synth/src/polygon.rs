//! Plane polygon geometry for occluders: areas, clipping, union area,
//! point containment.
//!
//! Polygons are closed vertex lists `[x, y]` (the last vertex joins the
//! first) in any orientation; they may be concave but must not intersect
//! themselves.

/// Signed area by the shoelace formula (positive when counter-clockwise in
/// a y-up frame, i.e. clockwise on screen).
#[must_use]
pub fn signed_area(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    let mut a = 0.0;
    for i in 0..n {
        let p = poly[i];
        let q = poly[(i + 1) % n];
        a += p[0] * q[1] - q[0] * p[1];
    }
    0.5 * a
}

/// Area, whatever the orientation.
#[must_use]
pub fn area(poly: &[[f64; 2]]) -> f64 {
    signed_area(poly).abs()
}

/// Clips a polygon to the half-plane `a x + b y <= c`.
///
/// One stage of Sutherland-Hodgman clipping (I. E. Sutherland and G. W.
/// Hodgman, "Reentrant polygon clipping", CACM 17(1), 1974).
#[must_use]
pub fn clip_half_plane(poly: &[[f64; 2]], [a, b, c]: [f64; 3]) -> Vec<[f64; 2]> {
    let n = poly.len();
    let mut out = Vec::with_capacity(n + 2);
    let side = |p: [f64; 2]| a * p[0] + b * p[1] - c;
    for i in 0..n {
        let p = poly[i];
        let q = poly[(i + 1) % n];
        let (sp, sq) = (side(p), side(q));
        if sp <= 0.0 {
            out.push(p);
        }
        if (sp < 0.0 && sq > 0.0) || (sp > 0.0 && sq < 0.0) {
            let t = sp / (sp - sq);
            out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
        }
    }
    out
}

/// Clips a polygon to the axis-aligned box `[x0, x1] x [y0, y1]`
/// (Sutherland-Hodgman against the box's four sides). For a concave subject
/// the result may contain zero-width bridges along the box's sides; its
/// area is still exact.
#[must_use]
pub fn clip_to_box(poly: &[[f64; 2]], [x0, y0, x1, y1]: [f64; 4]) -> Vec<[f64; 2]> {
    let mut p = clip_half_plane(poly, [-1.0, 0.0, -x0]);
    p = clip_half_plane(&p, [1.0, 0.0, x1]);
    p = clip_half_plane(&p, [0.0, -1.0, -y0]);
    clip_half_plane(&p, [0.0, 1.0, y1])
}

/// Area of the part of `poly` inside the unit square `[0, 1]^2`.
#[must_use]
pub fn area_in_unit_square(poly: &[[f64; 2]]) -> f64 {
    area(&clip_to_box(poly, [0.0, 0.0, 1.0, 1.0]))
}

/// Crossing-number point-in-polygon test (the classic even-odd ray
/// casting test). Points exactly on an edge may go either way.
#[must_use]
pub fn contains(poly: &[[f64; 2]], [x, y]: [f64; 2]) -> bool {
    let n = poly.len();
    let mut inside = false;
    for i in 0..n {
        let p = poly[i];
        let q = poly[(i + 1) % n];
        if (p[1] > y) != (q[1] > y) {
            let xc = p[0] + (y - p[1]) / (q[1] - p[1]) * (q[0] - p[0]);
            if x < xc {
                inside = !inside;
            }
        }
    }
    inside
}

/// Parameter `t` along `p -> q` where it crosses the segment `r -> s`, if
/// the two segments cross.
fn crossing(p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]) -> Option<f64> {
    let d1 = [q[0] - p[0], q[1] - p[1]];
    let d2 = [s[0] - r[0], s[1] - r[1]];
    let den = d1[0] * d2[1] - d1[1] * d2[0];
    if den.abs() < 1e-300 {
        return None;
    }
    let w = [r[0] - p[0], r[1] - p[1]];
    let t = (w[0] * d2[1] - w[1] * d2[0]) / den;
    let u = (w[0] * d1[1] - w[1] * d1[0]) / den;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Area of the union of `polys` inside the box `[x0, x1] x [y0, y1]`.
///
/// Exact for straight-edged polygons by vertical slab decomposition: the x
/// coordinates of every vertex, every crossing of two edges and every
/// crossing of an edge with the box's top or bottom cut the box into slabs
/// in which no two boundaries cross, so the covered length of a vertical
/// line is linear in x across a slab and its value at the slab's middle
/// times the slab's width is the slab's covered area. (The idea of the
/// trapezoidal decomposition used in computational geometry texts, e.g.
/// de Berg et al., "Computational Geometry", ch. 6.) O(E^2 log E) for E
/// edges: fine for occluders.
#[must_use]
pub fn union_area_in_box(polys: &[Vec<[f64; 2]>], [x0, y0, x1, y1]: [f64; 4]) -> f64 {
    let edges: Vec<([f64; 2], [f64; 2])> = polys
        .iter()
        .filter(|p| p.len() >= 3)
        .flat_map(|p| (0..p.len()).map(move |i| (p[i], p[(i + 1) % p.len()])))
        .collect();
    let mut xs: Vec<f64> = vec![x0, x1];
    xs.extend(edges.iter().map(|(p, _)| p[0]));
    let bottom = ([x0 - 1.0, y1], [x1 + 1.0, y1]);
    let top = ([x0 - 1.0, y0], [x1 + 1.0, y0]);
    for (i, &(p, q)) in edges.iter().enumerate() {
        let (lo, hi) = (p[0].min(q[0]), p[0].max(q[0]));
        for &(r, s) in &edges[i + 1..] {
            if r[0].max(s[0]) < lo || r[0].min(s[0]) > hi {
                continue;
            }
            if let Some(t) = crossing(p, q, r, s) {
                xs.push(p[0] + t * (q[0] - p[0]));
            }
        }
        for (r, s) in [bottom, top] {
            if let Some(t) = crossing(p, q, r, s) {
                xs.push(p[0] + t * (q[0] - p[0]));
            }
        }
    }
    xs.retain(|x| (x0..=x1).contains(x));
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let mut total = 0.0;
    let mut intervals: Vec<(f64, f64)> = Vec::new();
    let mut ys: Vec<f64> = Vec::new();
    for w in xs.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b - a <= 0.0 {
            continue;
        }
        let xm = 0.5 * (a + b);
        intervals.clear();
        for poly in polys.iter().filter(|p| p.len() >= 3) {
            ys.clear();
            let n = poly.len();
            for i in 0..n {
                let (p, q) = (poly[i], poly[(i + 1) % n]);
                if (p[0] > xm) != (q[0] > xm) {
                    ys.push(p[1] + (xm - p[0]) / (q[0] - p[0]) * (q[1] - p[1]));
                }
            }
            ys.sort_by(f64::total_cmp);
            for pair in ys.chunks_exact(2) {
                let (lo, hi) = (pair[0].max(y0), pair[1].min(y1));
                if hi > lo {
                    intervals.push((lo, hi));
                }
            }
        }
        intervals.sort_by(|p, q| p.0.total_cmp(&q.0));
        let mut covered = 0.0;
        let mut cur: Option<(f64, f64)> = None;
        for &(lo, hi) in &intervals {
            match cur {
                Some((cl, ch)) if lo <= ch => cur = Some((cl, ch.max(hi))),
                Some((cl, ch)) => {
                    covered += ch - cl;
                    cur = Some((lo, hi));
                }
                None => cur = Some((lo, hi)),
            }
        }
        if let Some((cl, ch)) = cur {
            covered += ch - cl;
        }
        total += covered * (b - a);
    }
    total
}

/// Area of the union of `polys` inside the unit square.
#[must_use]
pub fn union_area_in_unit_square(polys: &[Vec<[f64; 2]>]) -> f64 {
    union_area_in_box(polys, [0.0, 0.0, 1.0, 1.0])
}

/// A regular `n`-gon approximating an ellipse with semi-axes `a`, `b`
/// rotated by `angle` radians about `centre`.
#[must_use]
pub fn ellipse(centre: [f64; 2], [a, b]: [f64; 2], angle: f64, n: usize) -> Vec<[f64; 2]> {
    let (s, c) = angle.sin_cos();
    (0..n)
        .map(|k| {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            let (x, y) = (a * t.cos(), b * t.sin());
            [centre[0] + c * x - s * y, centre[1] + s * x + c * y]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipping_a_triangle_over_a_corner() {
        // x + y <= 0.4, overhanging the top-left corner.
        let t = vec![[-0.2, -0.2], [0.6, -0.2], [-0.2, 0.6]];
        let a = area_in_unit_square(&t);
        assert!((a - 0.08).abs() < 1e-15, "{a}");
        assert!((union_area_in_unit_square(std::slice::from_ref(&t)) - 0.08).abs() < 1e-15);
        assert!(contains(&t, [0.0, 0.0]));
        assert!(!contains(&t, [1.0, 0.0]));
    }

    #[test]
    fn union_of_overlapping_and_concave_polygons() {
        let a = vec![[0.1, 0.1], [0.5, 0.1], [0.5, 0.5], [0.1, 0.5]];
        let b = vec![[0.3, 0.3], [0.7, 0.3], [0.7, 0.7], [0.3, 0.7]];
        // 0.16 + 0.16 - 0.04
        let u = union_area_in_unit_square(&[a, b]);
        assert!((u - 0.28).abs() < 1e-14, "{u}");
        // An L shape (concave), partly outside the square.
        let l = vec![
            [-0.5, -0.5],
            [0.5, -0.5],
            [0.5, 0.25],
            [0.25, 0.25],
            [0.25, 0.75],
            [-0.5, 0.75],
        ];
        let expect = 0.5 * 0.25 + 0.25 * 0.5;
        assert!((union_area_in_unit_square(std::slice::from_ref(&l)) - expect).abs() < 1e-14);
        assert!((area_in_unit_square(&l) - expect).abs() < 1e-14);
        // A slanted polygon crossing the square's top and bottom.
        let band = vec![[0.4, -0.3], [0.5, -0.3], [0.6, 1.3], [0.5, 1.3]];
        assert!((union_area_in_unit_square(std::slice::from_ref(&band)) - 0.1).abs() < 1e-14);
        assert!((area_in_unit_square(&band) - 0.1).abs() < 1e-14);
    }

    #[test]
    fn ellipse_area_converges() {
        let e = ellipse([0.5, 0.5], [0.3, 0.2], 0.4, 1024);
        let exact = std::f64::consts::PI * 0.06;
        assert!((area(&e) - exact).abs() / exact < 1e-4);
    }
}

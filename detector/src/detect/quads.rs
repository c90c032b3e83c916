//! Stage 5: candidate quadrilaterals (the paper's Algorithm 2).
//!
//! Corners are linked into a successor graph: corner `b` follows corner `a`
//! (anticlockwise on screen, the order TL, BL, BR, TR) when `b` lies on
//! `a`'s outgoing line, ahead of it, and `b`'s incoming line runs along the
//! same edge. A tag whose four corners are visible is a 4-cycle of that
//! graph. The occlusion cases of the paper are paths of the graph:
//!
//! - triangle: a path `a -> b -> c`; the fourth corner is where `c`'s
//!   outgoing line meets `a`'s incoming line;
//! - same-side: an edge `a -> b`; the two missing corners lie on the
//!   diagonals through the tag centre (the ellipse anchor), each on the
//!   line of the visible corner next to it;
//! - symmetry: two facing same-side pairs whose edges are broken in the
//!   middle. Because the successor test is geometric, not "same border",
//!   their four corners already form a 4-cycle across borders, which is
//!   the merge the paper does as a separate step;
//! - diagonal: two opposite corners with the anchor between them; each
//!   missing corner is where a line of one meets a line of the other.
//!
//! Every corner a case had to compute is marked estimated. The search runs
//! first on each border's own corners (tags found without any ellipse),
//! then on the corners around each ellipse, keeping only corners whose
//! inside (the cone between their two lines) faces the anchor. Candidates
//! are sorted real corners first, larger first, and near-duplicates
//! dropped. An estimated corner with a detected corner beside it also
//! gives a second candidate that uses the detected one (the paper's
//! Replace-Fake-Corners); both are kept, because the detected corner may be
//! where an occluder's edge crosses the tag's. The decoder settles it: of
//! the candidates over one tag, the reading with the fewest corrections
//! wins.

use super::corners::{intersect, Corner};
use super::ellipses::Ellipse;
use super::lines::{cross, dot, norm, sub, unit};

/// A candidate quad in working-image coordinates, corners anticlockwise on
/// screen (TL, BL, BR, TR up to a rotation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    /// Corner positions.
    pub corners: [[f64; 2]; 4],
    /// Which corners were computed rather than seen.
    pub estimated: [bool; 4],
    /// Index of the detected corner behind each real corner.
    pub source: [Option<u32>; 4],
    /// Tag centre estimate used for same-side recovery, if any.
    pub anchor: Option<[f64; 2]>,
    /// Number of real corners.
    pub real: usize,
    /// Area (working px^2).
    pub area: f64,
}

/// Parameters of the quad search.
#[derive(Debug, Clone, Copy)]
pub(crate) struct QuadParams {
    /// Shortest quad side (working px).
    pub min_side: f64,
    /// Cosine of the largest angle between two lines of the same edge.
    pub cos_edge: f64,
    /// Whether the occlusion cases run (else 4-cycles only).
    pub recover: bool,
    /// Cap on candidates per frame.
    pub max_candidates: usize,
    /// Largest distance of a detected corner replacing an estimated one
    /// (working px).
    pub replace_dist: f64,
}

/// Reusable buffers.
#[derive(Debug, Default)]
pub(crate) struct QuadScratch {
    group: Vec<u32>,
    succ: Vec<[u32; 4]>,
    nsucc: Vec<u8>,
}

/// Whether `b` follows `a` along an edge; returns the distance along it.
fn follows(a: &Corner, b: &Corner, p: &QuadParams) -> Option<f64> {
    let v = sub(b.pos, a.pos);
    let t = dot(v, a.dout);
    if t < p.min_side {
        return None;
    }
    if dot(a.dout, b.din) < p.cos_edge {
        return None;
    }
    let tol = 1.5 + 0.06 * t;
    if cross(a.dout, v).abs() > tol || cross(b.din, v).abs() > tol {
        return None;
    }
    Some(t)
}

fn valid_quad(q: &[[f64; 2]; 4], p: &QuadParams) -> Option<f64> {
    let mut area2 = 0.0;
    let mut lmin = f64::INFINITY;
    let mut lmax: f64 = 0.0;
    for i in 0..4 {
        let a = q[i];
        let b = q[(i + 1) % 4];
        let c = q[(i + 2) % 4];
        // Anticlockwise on screen: every turn has a negative cross product.
        if cross(sub(b, a), sub(c, b)) >= 0.0 {
            return None;
        }
        let l = norm(sub(b, a));
        lmin = lmin.min(l);
        lmax = lmax.max(l);
        area2 += cross(a, b);
    }
    if !(lmin >= p.min_side && lmax <= 12.0 * lmin && q.iter().flatten().all(|v| v.is_finite())) {
        return None;
    }
    Some(area2.abs() / 2.0)
}

fn push(
    out: &mut Vec<Candidate>,
    q: [[f64; 2]; 4],
    source: [Option<u32>; 4],
    anchor: Option<[f64; 2]>,
    p: &QuadParams,
) {
    if out.len() >= p.max_candidates {
        return;
    }
    if let Some(area) = valid_quad(&q, p) {
        let estimated = source.map(|s| s.is_none());
        out.push(Candidate {
            corners: q,
            estimated,
            source,
            anchor,
            real: source.iter().filter(|s| s.is_some()).count(),
            area,
        });
    }
}

/// Point `x` lies ahead of `p` along `d` (by more than `min`).
fn ahead(p: [f64; 2], d: [f64; 2], x: [f64; 2], min: f64) -> bool {
    dot(sub(x, p), d) > min
}

/// Candidates from one group of corners (indices into `corners`).
fn search_group(
    corners: &[Corner],
    group: &[u32],
    anchor: Option<[f64; 2]>,
    p: &QuadParams,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    let k = group.len();
    s.succ.clear();
    s.succ.resize(k, [0; 4]);
    s.nsucc.clear();
    s.nsucc.resize(k, 0);
    let mut has_pred = vec![false; k];
    for i in 0..k {
        let a = &corners[group[i] as usize];
        let mut best: [(f64, u32); 4] = [(f64::INFINITY, 0); 4];
        let mut nb = 0usize;
        for j in 0..k {
            if i == j {
                continue;
            }
            if let Some(t) = follows(a, &corners[group[j] as usize], p) {
                // Keep the nearest four successors.
                if nb < 4 {
                    best[nb] = (t, j as u32);
                    nb += 1;
                } else if let Some(w) = (0..4).max_by(|&x, &y| best[x].0.total_cmp(&best[y].0)) {
                    if t < best[w].0 {
                        best[w] = (t, j as u32);
                    }
                }
            }
        }
        for (m, b) in best.iter().take(nb).enumerate() {
            s.succ[i][m] = b.1;
            has_pred[b.1 as usize] = true;
        }
        s.nsucc[i] = nb as u8;
    }
    let succ = |i: usize| -> &[u32] { &s.succ[i][..s.nsucc[i] as usize] };
    let c = |i: u32| &corners[group[i as usize] as usize];
    let src = |i: u32| Some(group[i as usize]);
    for a in 0..k as u32 {
        for &b in succ(a as usize) {
            for &cc in succ(b as usize) {
                if cc == a {
                    continue;
                }
                let mut closed = false;
                for &d in succ(cc as usize) {
                    if d == a || d == b {
                        continue;
                    }
                    if succ(d as usize).contains(&a) {
                        closed = true;
                        // Each cycle once: start at its smallest index.
                        if a < b && a < cc && a < d {
                            let q = [c(a).pos, c(b).pos, c(cc).pos, c(d).pos];
                            push(out, q, [src(a), src(b), src(cc), src(d)], anchor, p);
                        }
                    }
                }
                if closed || !p.recover {
                    continue;
                }
                // Triangle: a -> b -> cc, fourth corner from the end lines.
                let (ca, cc_) = (c(a), c(cc));
                if let Some(d) = intersect(cc_.pos, cc_.dout, ca.pos, ca.din) {
                    if ahead(cc_.pos, cc_.dout, d, p.min_side)
                        && ahead(d, ca.din, ca.pos, p.min_side)
                    {
                        let q = [ca.pos, c(b).pos, cc_.pos, d];
                        push(out, q, [src(a), src(b), src(cc), None], anchor, p);
                    }
                }
            }
            // Same-side: a -> b and the centre.
            if let (true, Some(o)) = (p.recover, anchor) {
                let (ca, cb) = (c(a), c(b));
                let e1 = intersect(ca.pos, sub(o, ca.pos), cb.pos, cb.dout);
                let e2 = intersect(cb.pos, sub(o, cb.pos), ca.pos, ca.din);
                if let (Some(e1), Some(e2)) = (e1, e2) {
                    let r1 = norm(sub(o, ca.pos)) / norm(sub(e1, ca.pos)).max(1e-9);
                    let r2 = norm(sub(o, cb.pos)) / norm(sub(e2, cb.pos)).max(1e-9);
                    if ahead(cb.pos, cb.dout, e1, p.min_side)
                        && ahead(e2, ca.din, ca.pos, p.min_side)
                        && (0.3..0.7).contains(&r1)
                        && (0.3..0.7).contains(&r2)
                    {
                        let q = [ca.pos, cb.pos, e1, e2];
                        push(out, q, [src(a), src(b), None, None], anchor, p);
                    }
                }
            }
        }
    }
    // Diagonal: two opposite corners with the centre between them.
    if let (true, Some(o)) = (p.recover, anchor) {
        for a in 0..k as u32 {
            for cc in 0..k as u32 {
                if a == cc || succ(a as usize).contains(&cc) || succ(cc as usize).contains(&a) {
                    continue;
                }
                let (ca, cc_) = (c(a), c(cc));
                let diag = sub(cc_.pos, ca.pos);
                let dl = norm(diag);
                if dl < 2.0 * p.min_side {
                    continue;
                }
                let t = dot(sub(o, ca.pos), diag) / (dl * dl);
                if !(0.3..0.7).contains(&t) || cross(diag, sub(o, ca.pos)).abs() > 0.1 * dl * dl {
                    continue;
                }
                let b = intersect(ca.pos, ca.dout, cc_.pos, cc_.din);
                let d = intersect(cc_.pos, cc_.dout, ca.pos, ca.din);
                if let (Some(b), Some(d)) = (b, d) {
                    if ahead(ca.pos, ca.dout, b, p.min_side)
                        && ahead(b, cc_.din, cc_.pos, p.min_side)
                        && ahead(cc_.pos, cc_.dout, d, p.min_side)
                        && ahead(d, ca.din, ca.pos, p.min_side)
                    {
                        let q = [ca.pos, b, cc_.pos, d];
                        push(out, q, [src(a), None, src(cc), None], anchor, p);
                    }
                }
            }
        }
    }
}

/// Whether the corner's inside (between its outgoing line and its reversed
/// incoming line) faces `o`.
fn faces(c: &Corner, o: [f64; 2]) -> bool {
    let w = sub(o, c.pos);
    cross(c.dout, w) < 0.0 && cross(w, [-c.din[0], -c.din[1]]) < 0.0
}

/// Runs the whole search: per border, then per ellipse.
pub(crate) fn find_candidates(
    corners: &[Corner],
    ellipses: &[Ellipse],
    p: &QuadParams,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    out.clear();
    // Per border (corners are stored border by border).
    let mut i = 0;
    while i < corners.len() {
        let mut j = i + 1;
        while j < corners.len() && corners[j].contour == corners[i].contour {
            j += 1;
        }
        if j - i >= 3 {
            let mut group = std::mem::take(&mut s.group);
            group.clear();
            group.extend(i as u32..j as u32);
            search_group(corners, &group, None, p, s, out);
            s.group = group;
        }
        i = j;
    }
    // Around each ellipse.
    for e in ellipses {
        let o = e.anchor;
        let mut group = std::mem::take(&mut s.group);
        group.clear();
        let reach = 1.05 * e.a;
        for (ci, c) in corners.iter().enumerate() {
            let d = norm(sub(c.pos, e.centre));
            if d < reach && d > 0.25 * e.b && faces(c, o) {
                group.push(ci as u32);
            }
        }
        if group.len() >= 2 {
            search_group(corners, &group, Some(o), p, s, out);
        }
        s.group = group;
    }
    // Replace-Fake-Corners (the paper's Algorithm 2, line 18): an estimated
    // corner with a detected corner close by whose lines run along the
    // quad's two sides there becomes that real corner. The detected corner
    // may itself be false (where an occluder's edge crosses the tag's), so
    // the replacement is a new candidate and the original stays; the
    // decoder keeps whichever reads with fewer corrections.
    let n = out.len();
    for i in 0..n {
        let mut cand = out[i];
        let mut replaced = false;
        for k in 0..4 {
            if !cand.estimated[k] {
                continue;
            }
            let q = cand.corners;
            let din = unit(sub(q[k], q[(k + 3) % 4]));
            let dout = unit(sub(q[(k + 1) % 4], q[k]));
            let best = corners
                .iter()
                .enumerate()
                .filter(|(_, c)| {
                    norm(sub(c.pos, q[k])) < p.replace_dist
                        && dot(c.din, din) > p.cos_edge
                        && dot(c.dout, dout) > p.cos_edge
                })
                .min_by(|a, b| norm(sub(a.1.pos, q[k])).total_cmp(&norm(sub(b.1.pos, q[k]))));
            if let Some((ci, c)) = best {
                cand.corners[k] = c.pos;
                cand.estimated[k] = false;
                cand.source[k] = Some(ci as u32);
                cand.real += 1;
                replaced = true;
            }
        }
        if replaced && out.len() < p.max_candidates {
            out.push(cand);
        }
    }
    // Quads found on a border alone get the tag centre of a checker disc
    // that sits where their diagonals cross: refinement uses it to place
    // hidden corners.
    for cand in out.iter_mut().filter(|c| c.anchor.is_none() && c.real < 4) {
        let q = cand.corners;
        let Some(x) = intersect(q[0], sub(q[2], q[0]), q[1], sub(q[3], q[1])) else {
            continue;
        };
        let side = (0..4).map(|i| norm(sub(q[(i + 1) % 4], q[i]))).sum::<f64>() / 4.0;
        cand.anchor = ellipses
            .iter()
            .filter(|e| e.checker && norm(sub(e.anchor, x)) < 0.1 * side)
            .min_by(|a, b| norm(sub(a.anchor, x)).total_cmp(&norm(sub(b.anchor, x))))
            .map(|e| e.anchor);
    }
    // Best first: more real corners, then larger.
    out.sort_by(|a, b| b.real.cmp(&a.real).then(b.area.total_cmp(&a.area)));
    // Drop near-duplicates (same corners up to a rotation).
    let mut kept = 0;
    for i in 0..out.len() {
        let q = out[i];
        let dup = out[..kept]
            .iter()
            .any(|k| same_quad(&k.corners, &q.corners, 1.5));
        if !dup {
            out[kept] = q;
            kept += 1;
        }
    }
    out.truncate(kept);
}

fn same_quad(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4], tol: f64) -> bool {
    (0..4).any(|r| (0..4).all(|i| norm(sub(a[i], b[(i + r) % 4])) < tol))
}

//! Stage 6: sub-pixel corners at full resolution.
//!
//! Each side of a candidate quad that has visible edge pieces (the lines
//! of its real corners) is re-measured on the full-resolution image: at
//! points about a pixel apart along the visible pieces, the grey profile
//! across the edge is sampled (bilinear) and the position where it crosses
//! halfway between the local white (data square margin) and black (frame)
//! levels is taken as an edge point. For a symmetric blur that is where the
//! printed edge is. A total least squares line through the edge points,
//! refitted once without outliers, replaces the coarse line; this is done
//! twice, the second time in a narrow window around the first result.
//!
//! A corner's own line piece may cover only a little of its side (blur
//! chamfers the corner, an occluder cuts the side), so from each measured
//! corner the edge is also followed along the side for as long as it is
//! seen, and the fit runs over all of it.
//!
//! Corners are then intersections of adjacent refined sides: real corners
//! and the estimated corners of the triangle and diagonal cases (which are
//! intersections of visible sides by construction). A hidden corner next to
//! a side seen only over a short piece is put instead on the diagonal from
//! the opposite corner through the tag centre (the checker disc), cut with
//! the better seen side. The two estimated corners of a same-side quad are
//! recomputed on the diagonals through the tag centre.

use image::GrayImage;

use super::corners::{intersect, Corner};
use super::lines::{cross, dot, norm, sub, unit, Line};
use super::quads::Candidate;
use crate::decode::sample_bilinear;

/// A refined side: a point on it and its unit direction.
#[derive(Debug, Clone, Copy)]
struct SideLine {
    p: [f64; 2],
    d: [f64; 2],
    /// Length of the side the line was measured along (px).
    support: f64,
}

/// Reusable buffers.
#[derive(Debug, Default)]
pub(crate) struct RefineScratch {
    edge: Vec<[f64; 2]>,
    profile: Vec<f64>,
}

/// Working-image coordinates to full resolution.
#[inline]
pub(crate) fn to_full(p: [f64; 2], scale: f64) -> [f64; 2] {
    let o = (scale - 1.0) / 2.0;
    [p[0] * scale + o, p[1] * scale + o]
}

/// Corners of `cand` at full resolution, refined when `refine` is set.
pub(crate) fn refine_candidate(
    img: &GrayImage,
    cand: &Candidate,
    corners: &[Corner],
    lines: &[Line],
    scale: f64,
    refine: bool,
    s: &mut RefineScratch,
) -> [[f64; 2]; 4] {
    let q: [[f64; 2]; 4] = cand.corners.map(|p| to_full(p, scale));
    let side_len = (0..4)
        .map(|i| norm(sub(q[(i + 1) % 4], q[i])))
        .fold(0.0, f64::max);
    // Cell size of the finest family (14 cells + 2 margin cells).
    let cell = side_len / 16.0;
    let mut sides: [Option<SideLine>; 4] = [None; 4];
    for (i, side) in sides.iter_mut().enumerate() {
        let j = (i + 1) % 4;
        let mut segs: [Option<([f64; 2], [f64; 2])>; 2] = [None; 2];
        if let Some(ci) = cand.source[i] {
            let l = &lines[corners[ci as usize].lout as usize];
            segs[0] = Some((to_full(l.ps, scale), to_full(l.pe, scale)));
        }
        if let Some(cj) = cand.source[j] {
            let l = &lines[corners[cj as usize].lin as usize];
            segs[1] = Some((to_full(l.ps, scale), to_full(l.pe, scale)));
        }
        if segs.iter().all(Option::is_none) {
            continue;
        }
        // Coarse side: through the two corners when both are real, else
        // along the visible piece.
        let coarse = if cand.source[i].is_some() && cand.source[j].is_some() {
            SideLine {
                p: q[i],
                d: unit(sub(q[j], q[i])),
                support: norm(sub(q[j], q[i])),
            }
        } else {
            let (a, b) = segs
                .iter()
                .flatten()
                .next()
                .copied()
                .unwrap_or((q[i], q[j]));
            SideLine {
                p: a,
                d: unit(sub(b, a)),
                support: norm(sub(b, a)),
            }
        };
        if !refine {
            *side = Some(coarse);
            continue;
        }
        let mut line = fit_side(img, &coarse, &segs, cell, scale, 1, s)
            .and_then(|l| fit_side(img, &l, &segs, cell, scale, 2, s).or(Some(l)))
            .unwrap_or(coarse);
        // The corner's own line piece can be short (a chamfer where blur
        // rounds the corner, or a side cut by an occluder); follow the
        // edge from each measured end for as long as it is seen, then fit
        // again over all of it.
        let len = norm(sub(q[j], q[i]));
        let reach = 1.25 * len;
        // Only pieces that cover less than most of the side need it: a
        // clean tag's lines run corner to corner and cost nothing more.
        let short = |seg: Option<([f64; 2], [f64; 2])>| {
            seg.is_some_and(|(a, b)| norm(sub(b, a)) < 0.6 * len)
        };
        let from_i = short(segs[0])
            .then(|| track(img, &line, q[i], 1.0, reach, cell, s))
            .flatten();
        let from_j = short(segs[1])
            .then(|| track(img, &line, q[j], -1.0, reach, cell, s))
            .flatten();
        if from_i.is_some() || from_j.is_some() {
            let spans = [from_i.or(segs[0]), from_j.or(segs[1])];
            if let Some(l) = fit_side(img, &line, &spans, cell, scale, 2, s) {
                line = l;
            }
        }
        *side = Some(line);
    }
    let mut out = q;
    let modest = |x: [f64; 2], k: usize| norm(sub(x, q[k])) < 0.25 * side_len + 3.0 * scale;
    for k in 0..4 {
        if let (Some(a), Some(b)) = (sides[(k + 3) % 4], sides[k]) {
            if let Some(x) = intersect(a.p, a.d, b.p, b.d) {
                // Accept only a modest move (guards near-parallel sides).
                if modest(x, k) {
                    out[k] = x;
                }
            }
        }
    }
    // A hidden corner between two sides of which one is seen only over a
    // short piece: that side's direction is poorly known and its error is
    // magnified at the far corner. With the tag centre known, the corner is
    // on the diagonal from the opposite (measured) corner through the
    // centre; cut that with the better seen side instead.
    if let Some(o) = cand.anchor.map(|o| to_full(o, scale)) {
        let fixed = out;
        for k in 0..4 {
            if !cand.estimated[k] || cand.estimated[(k + 2) % 4] {
                continue;
            }
            let (Some(a), Some(b)) = (sides[(k + 3) % 4], sides[k]) else {
                continue;
            };
            if a.support.min(b.support) >= SHORT_SIDE * side_len {
                continue;
            }
            let opp = fixed[(k + 2) % 4];
            let best = if a.support >= b.support { a } else { b };
            if let Some(x) = intersect(opp, sub(o, opp), best.p, best.d) {
                if modest(x, k) {
                    out[k] = x;
                }
            }
        }
    }
    // Same-side: two adjacent estimated corners, on the diagonals.
    if let Some(o) = cand.anchor {
        let o = to_full(o, scale);
        for k in 0..4 {
            if !cand.estimated[k] {
                continue;
            }
            let opposite = out[(k + 2) % 4];
            if cand.estimated[(k + 2) % 4] {
                continue;
            }
            let known = if !cand.estimated[(k + 3) % 4] {
                sides[(k + 3) % 4]
            } else if !cand.estimated[(k + 1) % 4] {
                sides[k]
            } else {
                None
            };
            let both_known = sides[(k + 3) % 4].is_some() && sides[k].is_some();
            if let (Some(l), false) = (known, both_known) {
                if let Some(x) = intersect(opposite, sub(o, opposite), l.p, l.d) {
                    if norm(sub(x, q[k])) < 0.25 * side_len + 3.0 * scale {
                        out[k] = x;
                    }
                }
            }
        }
    }
    out
}

/// A side measured over less than this fraction of the quad's longest
/// side gives too uncertain a direction to place a hidden corner.
const SHORT_SIDE: f64 = 0.35;

/// Measures edge points along the visible pieces of one side and fits a
/// line. `pass` 1 uses a wide window, 2 a narrow one.
fn fit_side(
    img: &GrayImage,
    line: &SideLine,
    segs: &[Option<([f64; 2], [f64; 2])>; 2],
    cell: f64,
    scale: f64,
    pass: u32,
    s: &mut RefineScratch,
) -> Option<SideLine> {
    // Right normal: towards the black frame.
    let n = [-line.d[1], line.d[0]];
    let (w_white, w_black, step) = if pass == 1 {
        let slack = scale;
        (
            (0.8 * cell).clamp(1.0, 6.0) + slack,
            (1.6 * cell).clamp(1.5, 10.0) + slack,
            0.5,
        )
    } else {
        let w = (0.7 * cell).clamp(1.0, 4.0);
        (w, w, 0.25)
    };
    let margin = 1.5 + (0.8 * cell).min(4.0) + scale;
    s.edge.clear();
    for (a, b) in segs.iter().flatten() {
        // Project the piece onto the current line.
        let ta = dot(sub(*a, line.p), line.d);
        let tb = dot(sub(*b, line.p), line.d);
        let (t0, t1) = (ta.min(tb) + margin, ta.max(tb) - margin);
        if t1 <= t0 {
            continue;
        }
        let count = ((t1 - t0).ceil() as usize).clamp(2, 40);
        for k in 0..count {
            let t = t0 + (t1 - t0) * (k as f64 + 0.5) / count as f64;
            let c = [line.p[0] + t * line.d[0], line.p[1] + t * line.d[1]];
            if let Some(off) = edge_crossing(img, c, n, w_white, w_black, step, &mut s.profile) {
                s.edge.push([c[0] + off * n[0], c[1] + off * n[1]]);
            }
        }
    }
    let first = tls(&s.edge)?;
    // Drop outliers, refit.
    let res: Vec<f64> = s
        .edge
        .iter()
        .map(|p| cross(first.d, sub(*p, first.p)).abs())
        .collect();
    let mut sorted = res.clone();
    sorted.sort_by(f64::total_cmp);
    let med = sorted[sorted.len() / 2];
    let cut = (3.0 * 1.4826 * med).max(0.3);
    let mut i = 0;
    s.edge.retain(|_| {
        i += 1;
        res[i - 1] <= cut
    });
    let mut fit = tls(&s.edge)?;
    if dot(fit.d, line.d) < 0.0 {
        fit.d = [-fit.d[0], -fit.d[1]];
    }
    Some(fit)
}

/// Follows a side's edge from the corner `from` along `line` (forwards
/// when `sign` is 1, backwards when -1) for at most `reach` pixels, and
/// returns the span over which it was seen. The line is refitted as points
/// come in, so a coarse start direction is corrected on the way; the walk
/// stops where the edge has not been seen for half a cell (an occluder, or
/// the far corner).
fn track(
    img: &GrayImage,
    line: &SideLine,
    from: [f64; 2],
    sign: f64,
    reach: f64,
    cell: f64,
    s: &mut RefineScratch,
) -> Option<([f64; 2], [f64; 2])> {
    // Right normal of the side's own direction: towards the black frame.
    let n = [-line.d[1], line.d[0]];
    let mut d = [sign * line.d[0], sign * line.d[1]];
    // Start on the line, level with the corner.
    let t0 = dot(sub(from, line.p), line.d);
    let mut o = [line.p[0] + t0 * line.d[0], line.p[1] + t0 * line.d[1]];
    let w = (0.7 * cell).clamp(1.5, 4.0) + 1.0;
    // About 80 probes over a side, never more than half the stop gap apart.
    let gap = (0.5 * cell).max(4.0);
    let step = (reach / 80.0).clamp(1.0, 0.5 * gap);
    let start = 1.5 + (0.8 * cell).min(4.0);
    s.edge.clear();
    let mut last = None;
    let mut t = start;
    let mut since_fit = 0;
    while t < reach {
        let c = [o[0] + t * d[0], o[1] + t * d[1]];
        let seen =
            edge_crossing(img, c, n, w, w, 0.5, &mut s.profile).filter(|off| off.abs() <= 1.5);
        if let Some(off) = seen {
            s.edge.push([c[0] + off * n[0], c[1] + off * n[1]]);
            last = Some(t);
            since_fit += 1;
            if since_fit >= 16 {
                since_fit = 0;
                if let Some(f) = tls(&s.edge) {
                    let fd = if dot(f.d, d) < 0.0 {
                        [-f.d[0], -f.d[1]]
                    } else {
                        f.d
                    };
                    // Keep the parameter t: re-anchor o on the new line.
                    let tf = dot(sub(o, f.p), fd);
                    o = [f.p[0] + tf * fd[0], f.p[1] + tf * fd[1]];
                    d = fd;
                }
            }
        } else if last.map_or(t - start, |l| t - l) > gap {
            break;
        }
        t += step;
    }
    let end = last?;
    (s.edge.len() >= 3).then(|| {
        let a = [o[0] + start * d[0], o[1] + start * d[1]];
        let b = [o[0] + end * d[0], o[1] + end * d[1]];
        (a, b)
    })
}

/// Offset along `n` from `c` where the grey profile crosses halfway between
/// its white (negative side) and black (positive side) levels, nearest to
/// 0. `None` without contrast or crossing.
fn edge_crossing(
    img: &GrayImage,
    c: [f64; 2],
    n: [f64; 2],
    w_white: f64,
    w_black: f64,
    step: f64,
    prof: &mut Vec<f64>,
) -> Option<f64> {
    prof.clear();
    let k0 = -(w_white / step).round() as i32;
    let k1 = (w_black / step).round() as i32;
    for k in k0..=k1 {
        let t = f64::from(k) * step;
        prof.push(sample_bilinear(img, c[0] + t * n[0], c[1] + t * n[1])?);
    }
    let mid_k = (-k0) as usize;
    let white = prof[..=mid_k].iter().copied().fold(f64::MIN, f64::max);
    let black = prof[mid_k..].iter().copied().fold(f64::MAX, f64::min);
    if white - black < 12.0 {
        return None;
    }
    let level = 0.5 * (white + black);
    let mut best: Option<f64> = None;
    for i in 0..prof.len() - 1 {
        let (u, v) = (prof[i], prof[i + 1]);
        if u >= level && v < level {
            let f = (u - level) / (u - v);
            let t = (f64::from(k0) + i as f64 + f) * step;
            if best.is_none_or(|b| t.abs() < b.abs()) {
                best = Some(t);
            }
        }
    }
    best
}

fn tls(pts: &[[f64; 2]]) -> Option<SideLine> {
    if pts.len() < 3 {
        return None;
    }
    let m = pts.len() as f64;
    let (mut sx, mut sy) = (0.0, 0.0);
    for p in pts {
        sx += p[0];
        sy += p[1];
    }
    let c = [sx / m, sy / m];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let d = sub(*p, c);
        sxx += d[0] * d[0];
        sxy += d[0] * d[1];
        syy += d[1] * d[1];
    }
    let th = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let d = [th.cos(), th.sin()];
    let (mut t0, mut t1) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in pts {
        let t = dot(sub(*p, c), d);
        t0 = t0.min(t);
        t1 = t1.max(t);
    }
    Some(SideLine {
        p: c,
        d,
        support: t1 - t0,
    })
}

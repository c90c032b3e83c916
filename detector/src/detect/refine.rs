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
//! Corners are then intersections of adjacent refined sides: real corners
//! and the estimated corners of the triangle and diagonal cases (which are
//! intersections of visible sides by construction). The two estimated
//! corners of a same-side quad are recomputed on the diagonals through the
//! tag centre.

use image::GrayImage;

use super::corners::{intersect, Corner};
use super::lines::{cross, dot, norm, sub, Line};
use super::quads::Candidate;
use crate::decode::sample_bilinear;

/// A refined side: a point on it and its unit direction.
#[derive(Debug, Clone, Copy)]
struct SideLine {
    p: [f64; 2],
    d: [f64; 2],
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
            }
        };
        if !refine {
            *side = Some(coarse);
            continue;
        }
        let fine = fit_side(img, &coarse, &segs, cell, scale, 1, s)
            .and_then(|l| fit_side(img, &l, &segs, cell, scale, 2, s).or(Some(l)));
        *side = fine.or(Some(coarse));
    }
    let mut out = q;
    for k in 0..4 {
        let prev = sides[(k + 3) % 4];
        let next = sides[k];
        if let (Some(a), Some(b)) = (prev, next) {
            if let Some(x) = intersect(a.p, a.d, b.p, b.d) {
                // Accept only a modest move (guards near-parallel sides).
                if norm(sub(x, q[k])) < 0.25 * side_len + 3.0 * scale {
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

fn unit(v: [f64; 2]) -> [f64; 2] {
    let n = norm(v).max(1e-12);
    [v[0] / n, v[1] / n]
}

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
    Some(SideLine {
        p: c,
        d: [th.cos(), th.sin()],
    })
}

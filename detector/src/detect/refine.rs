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
//! twice, the second time in a narrow window around the first result. The
//! margin is only a cell wide, though: once the blur reaches across it,
//! the crossing lies outside the printed edge, and the second line is
//! moved back inwards by the bias that a model of the side shows at the
//! blur the first pass's profiles rose over (`edge_bias`).
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

use super::edge_bias::{self, BlurBias, Ruler};
use super::quads::Candidate;
use crate::math::{cross, dot, fit_line, intersect, norm, sample_profile, sub, to_full, unit};
use crate::view::GrayView;

/// Parameters of refinement, built once by [`crate::Detector::new`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct RefineParams {
    /// Re-measure the sides on the full-resolution image
    /// (`DetectorConfig::refine_corners`); else corners are the coarse
    /// ones scaled to full resolution.
    pub refine: bool,
    /// Cells across a tag side, margins included, of the finest family
    /// detected (ct14: 14 + 2): the measuring windows are sized in cells of
    /// that family, so they never reach past its margin.
    pub cells_per_side: f64,
    /// Smallest step (grey levels) between the white and black ends of a
    /// profile across an edge: flatter profiles show no edge.
    pub min_edge_contrast: f64,
}

/// Margin cells across a tag side besides the data grid: one white cell
/// on each side.
pub(crate) const MARGIN_CELLS: usize = 2;

/// Default of [`RefineParams::min_edge_contrast`] (grey levels).
pub(crate) const MIN_EDGE_CONTRAST: f64 = 12.0;

/// A corner moved by refinement by more than `MAX_MOVE_SIDE` times the
/// longest side plus `MAX_MOVE_PX` times the downsampling factor (px)
/// keeps its coarse position: such a move comes from near-parallel sides.
const MAX_MOVE_SIDE: f64 = 0.25;
/// See [`MAX_MOVE_SIDE`] (working px).
const MAX_MOVE_PX: f64 = 3.0;

/// A side measured over less than this fraction of the quad's longest
/// side gives too uncertain a direction to place a hidden corner.
const SHORT_SIDE: f64 = 0.35;

/// A corner's line piece shorter than this fraction of its side is
/// extended by following the edge ([`track`]).
const SHORT_PIECE: f64 = 0.6;

/// Edge following goes at most this many side lengths from the corner.
const TRACK_REACH: f64 = 1.25;

/// Windows of the first (wide) fitting pass across an edge, in cells of
/// the finest family, clamped to a range in px, plus the downsampling
/// factor (the coarse line's uncertainty): white side, ...
const WIDE_WHITE: (f64, f64, f64) = (0.8, 1.0, 6.0);
/// ... black side (the frame is two cells wide in ct14 terms), ...
const WIDE_BLACK: (f64, f64, f64) = (1.6, 1.5, 10.0);
/// ... and the profile's sampling step (px).
const WIDE_STEP: f64 = 0.5;

/// Window on both sides of the second (narrow) fitting pass: a fraction of
/// a cell clamped to px, ...
const NARROW: (f64, f64, f64) = (0.7, 1.0, 4.0);
/// ... and its sampling step (px).
const NARROW_STEP: f64 = 0.25;

/// Edge points are measured from this far (px) plus
/// `END_MARGIN_CELLS` cells (at most `END_MARGIN_MAX` px) inside each end
/// of a line piece: the ends are where blur rounds the corner.
const END_MARGIN_PX: f64 = 1.5;
/// See [`END_MARGIN_PX`] (cells).
const END_MARGIN_CELLS: f64 = 0.8;
/// See [`END_MARGIN_PX`] (px).
const END_MARGIN_MAX: f64 = 4.0;

/// Profiles measured per line piece: about one per pixel, within this
/// range.
const PROFILES_PER_PIECE: (usize, usize) = (2, 40);

/// Outliers of the first fit: residuals above `OUTLIER_SIGMAS` robust
/// standard deviations (`MAD_TO_SIGMA` times the median residual) are
/// dropped, but never those within `OUTLIER_FLOOR` px.
const OUTLIER_SIGMAS: f64 = 3.0;
/// Median absolute residual to standard deviation, for normal noise.
const MAD_TO_SIGMA: f64 = 1.4826;
/// See [`OUTLIER_SIGMAS`] (px).
const OUTLIER_FLOOR: f64 = 0.3;

/// Edge following: profile window (cells, clamped to px, plus
/// `TRACK_WINDOW_PAD` px), ...
const TRACK_WINDOW: (f64, f64, f64) = (0.7, 1.5, 4.0);
/// ... the pad added to it (px), ...
const TRACK_WINDOW_PAD: f64 = 1.0;
/// ... the profile's sampling step (px), ...
const TRACK_STEP: f64 = 0.5;
/// ... the gap after which the edge is lost (cells, at least
/// `TRACK_GAP_MIN` px), ...
const TRACK_GAP_CELLS: f64 = 0.5;
/// ... see [`TRACK_GAP_CELLS`] (px), ...
const TRACK_GAP_MIN: f64 = 4.0;
/// ... about this many probes over the reach, ...
const TRACK_PROBES: f64 = 80.0;
/// ... never closer than `TRACK_MIN_STEP` px, ...
const TRACK_MIN_STEP: f64 = 1.0;
/// ... but at least this many probes per stop gap (so that one missed
/// probe never ends the walk), ...
const TRACK_PROBES_PER_GAP: f64 = 2.0;
/// ... the largest offset (px) of an edge point from the current line, ...
const TRACK_MAX_OFFSET: f64 = 1.5;
/// ... and the points between two refits of the followed line.
const TRACK_REFIT: usize = 16;

/// Fewest edge points a side line is fitted to.
const MIN_EDGE_POINTS: usize = 3;

/// A refined side: a point on it and its unit direction.
#[derive(Debug, Clone, Copy)]
struct SideLine {
    p: [f64; 2],
    d: [f64; 2],
    /// Length of the side the line was measured along (px).
    support: f64,
}

/// A visible piece of a side at full resolution, start and end.
type Piece = ([f64; 2], [f64; 2]);

/// Reusable buffers.
#[derive(Debug, Default)]
pub(crate) struct RefineScratch {
    edge: Vec<[f64; 2]>,
    /// Rise widths (px) of the edge points of the last side fitted.
    widths: Vec<f64>,
    profile: Vec<f64>,
}

/// Corners of `cand` at full resolution (`scale` is the downsampling
/// factor of the working image), refined when [`RefineParams::refine`] is
/// set.
pub(crate) fn refine_candidate(
    img: &GrayView<'_>,
    cand: &Candidate,
    scale: f64,
    params: &RefineParams,
    s: &mut RefineScratch,
) -> [[f64; 2]; 4] {
    let q: [[f64; 2]; 4] = cand.corners.map(|p| to_full(p, scale));
    let side_len = (0..4)
        .map(|i| norm(sub(q[(i + 1) % 4], q[i])))
        .fold(0.0, f64::max);
    let cell = side_len / params.cells_per_side;
    let g = Gauge {
        img,
        cell,
        scale,
        params,
    };
    let full = |seg: [[f64; 2]; 2]| (to_full(seg[0], scale), to_full(seg[1], scale));
    let mut sides: [Option<SideLine>; 4] = [None; 4];
    let mut table = None;
    for (i, side) in sides.iter_mut().enumerate() {
        let j = (i + 1) % 4;
        // Side i runs from corner i (its outgoing piece) to corner j (its
        // incoming piece).
        let segs: [Option<Piece>; 2] = [
            cand.edges[i].map(|e| full(e.outgoing)),
            cand.edges[j].map(|e| full(e.incoming)),
        ];
        if segs.iter().all(Option::is_none) {
            continue;
        }
        // Coarse side: through the two corners when both are real, else
        // along the visible piece.
        let coarse = if cand.edges[i].is_some() && cand.edges[j].is_some() {
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
        if !params.refine {
            *side = Some(coarse);
            continue;
        }
        let wide = fit_side(&g, &coarse, &segs, Pass::Wide, s);
        let bias = blur_bias(&g, &mut s.widths, &mut table);
        let mut line = wide
            .and_then(|l| {
                fit_side(&g, &l, &segs, Pass::Narrow, s)
                    .map(|l| inwards(l, bias))
                    .or(Some(l))
            })
            .unwrap_or(coarse);
        // The corner's own line piece can be short (a chamfer where blur
        // rounds the corner, or a side cut by an occluder); follow the
        // edge from each measured end for as long as it is seen, then fit
        // again over all of it.
        let len = norm(sub(q[j], q[i]));
        let reach = TRACK_REACH * len;
        // Only pieces that cover less than most of the side need it: a
        // clean tag's lines run corner to corner and cost nothing more.
        let short =
            |seg: Option<Piece>| seg.is_some_and(|(a, b)| norm(sub(b, a)) < SHORT_PIECE * len);
        let from_i = short(segs[0])
            .then(|| track(&g, &line, q[i], 1.0, reach, s))
            .flatten();
        let from_j = short(segs[1])
            .then(|| track(&g, &line, q[j], -1.0, reach, s))
            .flatten();
        if from_i.is_some() || from_j.is_some() {
            let spans = [from_i.or(segs[0]), from_j.or(segs[1])];
            if let Some(l) = fit_side(&g, &line, &spans, Pass::Narrow, s) {
                line = inwards(l, bias);
            }
        }
        *side = Some(line);
    }
    let mut out = q;
    let modest =
        |x: [f64; 2], k: usize| norm(sub(x, q[k])) < MAX_MOVE_SIDE * side_len + MAX_MOVE_PX * scale;
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
                    if modest(x, k) {
                        out[k] = x;
                    }
                }
            }
        }
    }
    out
}

/// The two fitting passes over a side.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Wide windows around the coarse line.
    Wide,
    /// Narrow windows around the first result.
    Narrow,
}

/// What measuring along the sides of one candidate needs.
struct Gauge<'i, 'p> {
    /// The full-resolution image.
    img: &'p GrayView<'i>,
    /// Cell size of the candidate (px): its longest side over
    /// [`RefineParams::cells_per_side`].
    cell: f64,
    /// Downsampling factor of the working image the candidate was found on.
    scale: f64,
    /// The stage parameters.
    params: &'p RefineParams,
}

/// The windows and sampling step of a pass over a side of a candidate.
fn ruler(g: &Gauge<'_, '_>, pass: Pass) -> Ruler {
    match pass {
        // The coarse line is up to a working pixel off: slack for it.
        Pass::Wide => Ruler {
            white: window(WIDE_WHITE, g.cell) + g.scale,
            black: window(WIDE_BLACK, g.cell) + g.scale,
            step: WIDE_STEP,
        },
        Pass::Narrow => {
            let w = window(NARROW, g.cell);
            Ruler {
                white: w,
                black: w,
                step: NARROW_STEP,
            }
        }
    }
}

/// Blur (Gaussian sigma, in cells) under which a side's bias is left
/// alone: there the margin keeps its white and the model's bias stays
/// under 0.03 px. The profiles' rise then shows at most
/// [`edge_bias::GAUSS_QUARTILE_SPAN`] times that blur, and a sharp
/// candidate's sides cost no model at all.
const SHARP_SIGMA_CELLS: f64 = 0.3;

/// How far (px) the narrow pass measures a side outwards of the printed
/// edge under the blur that the wide pass's rises `widths` showed
/// ([`edge_bias`]); zero when they showed little. `table` is the
/// candidate's, made on its first blurred side.
fn blur_bias(g: &Gauge<'_, '_>, widths: &mut [f64], table: &mut Option<Option<BlurBias>>) -> f64 {
    if widths.is_empty() {
        return 0.0;
    }
    widths.sort_by(f64::total_cmp);
    let width = widths[widths.len() / 2];
    if width <= edge_bias::GAUSS_QUARTILE_SPAN * SHARP_SIGMA_CELLS * g.cell {
        return 0.0;
    }
    table
        .get_or_insert_with(|| {
            BlurBias::new(g.cell, &ruler(g, Pass::Wide), &ruler(g, Pass::Narrow))
        })
        .as_ref()
        .map_or(0.0, |t| t.at(width))
}

/// `line` moved `by` px towards the data square's inside (its left).
fn inwards(line: SideLine, by: f64) -> SideLine {
    let n = [-line.d[1], line.d[0]];
    SideLine {
        p: [line.p[0] - by * n[0], line.p[1] - by * n[1]],
        ..line
    }
}

/// `cell`-relative size `(factor, min, max)` of a window, in px.
#[inline]
fn window((factor, lo, hi): (f64, f64, f64), cell: f64) -> f64 {
    (factor * cell).clamp(lo, hi)
}

/// Measures edge points along the visible pieces of one side and fits a
/// line.
fn fit_side(
    g: &Gauge<'_, '_>,
    line: &SideLine,
    segs: &[Option<Piece>; 2],
    pass: Pass,
    s: &mut RefineScratch,
) -> Option<SideLine> {
    let (img, cell, scale) = (g.img, g.cell, g.scale);
    // Right normal: towards the black frame.
    let n = [-line.d[1], line.d[0]];
    let r = ruler(g, pass);
    let margin = END_MARGIN_PX + (END_MARGIN_CELLS * cell).min(END_MARGIN_MAX) + scale;
    let profile = Profile {
        w_white: r.white,
        w_black: r.black,
        step: r.step,
        min_contrast: g.params.min_edge_contrast,
        rise: pass == Pass::Wide,
    };
    s.edge.clear();
    s.widths.clear();
    // Where both corners of the side were formed on the same line piece
    // (every side of an unbroken quad), the two pieces are one: it is
    // measured once (refinement was a fifth of a clean frame's time) and
    // its points taken twice, as measuring it twice gave them. Doubling
    // every point changes no fit, but keeps the detections bit for bit.
    let same = segs[0].is_some() && segs[0] == segs[1];
    let pieces = if same { &segs[..1] } else { &segs[..] };
    for (a, b) in pieces.iter().flatten() {
        // Project the piece onto the current line.
        let ta = dot(sub(*a, line.p), line.d);
        let tb = dot(sub(*b, line.p), line.d);
        let (t0, t1) = (ta.min(tb) + margin, ta.max(tb) - margin);
        if t1 <= t0 {
            continue;
        }
        let count = ((t1 - t0).ceil() as usize).clamp(PROFILES_PER_PIECE.0, PROFILES_PER_PIECE.1);
        for k in 0..count {
            let t = t0 + (t1 - t0) * (k as f64 + 0.5) / count as f64;
            let c = [line.p[0] + t * line.d[0], line.p[1] + t * line.d[1]];
            if let Some((off, width)) = edge_crossing(img, c, n, &profile, &mut s.profile) {
                s.edge.push([c[0] + off * n[0], c[1] + off * n[1]]);
                if profile.rise {
                    s.widths.push(width);
                }
            }
        }
    }
    if same {
        s.edge.extend_from_within(..);
    }
    let first = edge_line(&s.edge)?;
    // Drop outliers, refit.
    let res: Vec<f64> = s
        .edge
        .iter()
        .map(|p| cross(first.d, sub(*p, first.p)).abs())
        .collect();
    let mut sorted = res.clone();
    sorted.sort_by(f64::total_cmp);
    let med = sorted[sorted.len() / 2];
    let cut = (OUTLIER_SIGMAS * MAD_TO_SIGMA * med).max(OUTLIER_FLOOR);
    let mut i = 0;
    s.edge.retain(|_| {
        i += 1;
        res[i - 1] <= cut
    });
    let mut fit = edge_line(&s.edge)?;
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
    g: &Gauge<'_, '_>,
    line: &SideLine,
    from: [f64; 2],
    sign: f64,
    reach: f64,
    s: &mut RefineScratch,
) -> Option<Piece> {
    let (img, cell) = (g.img, g.cell);
    // Right normal of the side's own direction: towards the black frame.
    let n = [-line.d[1], line.d[0]];
    let mut d = [sign * line.d[0], sign * line.d[1]];
    // Start on the line, level with the corner.
    let t0 = dot(sub(from, line.p), line.d);
    let mut o = [line.p[0] + t0 * line.d[0], line.p[1] + t0 * line.d[1]];
    let w = window(TRACK_WINDOW, cell) + TRACK_WINDOW_PAD;
    let profile = Profile {
        w_white: w,
        w_black: w,
        step: TRACK_STEP,
        min_contrast: g.params.min_edge_contrast,
        rise: false,
    };
    let gap = (TRACK_GAP_CELLS * cell).max(TRACK_GAP_MIN);
    let step = (reach / TRACK_PROBES).clamp(TRACK_MIN_STEP, gap / TRACK_PROBES_PER_GAP);
    let start = END_MARGIN_PX + (END_MARGIN_CELLS * cell).min(END_MARGIN_MAX);
    s.edge.clear();
    let mut last = None;
    let mut t = start;
    let mut since_fit = 0;
    while t < reach {
        let c = [o[0] + t * d[0], o[1] + t * d[1]];
        let seen = edge_crossing(img, c, n, &profile, &mut s.profile)
            .map(|(off, _)| off)
            .filter(|off| off.abs() <= TRACK_MAX_OFFSET);
        if let Some(off) = seen {
            s.edge.push([c[0] + off * n[0], c[1] + off * n[1]]);
            last = Some(t);
            since_fit += 1;
            if since_fit >= TRACK_REFIT {
                since_fit = 0;
                if let Some(f) = edge_line(&s.edge) {
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
    (s.edge.len() >= MIN_EDGE_POINTS).then(|| {
        let a = [o[0] + start * d[0], o[1] + start * d[1]];
        let b = [o[0] + end * d[0], o[1] + end * d[1]];
        (a, b)
    })
}

/// How a grey profile across an edge is sampled: window on the white
/// (negative) and black (positive) side of the probe point and step (px),
/// and the contrast it needs.
#[derive(Debug, Clone, Copy)]
struct Profile {
    w_white: f64,
    w_black: f64,
    step: f64,
    min_contrast: f64,
    /// Whether to measure the rise's width too (the wide pass's, which
    /// gives the side's blur): the other passes do without it.
    rise: bool,
}

/// Offset along `n` from `c` where the grey profile crosses halfway between
/// its white (negative side) and black (positive side) levels, nearest to
/// 0, and the width (px) of the profile's rise there (NaN unless
/// [`Profile::rise`]). `None` without contrast or crossing.
fn edge_crossing(
    img: &GrayView<'_>,
    c: [f64; 2],
    n: [f64; 2],
    p: &Profile,
    prof: &mut Vec<f64>,
) -> Option<(f64, f64)> {
    let step = p.step;
    prof.clear();
    let k0 = -(p.w_white / step).round() as i32;
    let k1 = (p.w_black / step).round() as i32;
    if !sample_profile(img, c, n, step, (k0, k1), prof) {
        return None;
    }
    let mid = (-k0) as usize;
    let (white, black) = edge_bias::levels(prof, mid);
    if white - black < p.min_contrast {
        return None;
    }
    let (t, at) = edge_bias::falling_crossing(prof, 0.5 * (white + black), mid, step)?;
    let width = if p.rise {
        edge_bias::rise_width(prof, black, white - black, at) * step
    } else {
        f64::NAN
    };
    Some((t, width))
}

/// The line through the edge points (at least [`MIN_EDGE_POINTS`]), with
/// the length of their projection on it as support.
fn edge_line(pts: &[[f64; 2]]) -> Option<SideLine> {
    if pts.len() < MIN_EDGE_POINTS {
        return None;
    }
    let fit = fit_line(pts.iter().copied())?;
    let (c, d) = (fit.centre, fit.dir);
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

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
//!   missing corner is where a line of one meets a line of the other;
//! - one corner (not in the paper): a corner alone, when the anchor is the
//!   centre checker's disc, makes a parallelogram around that centre
//!   (`one_corner`). An occluder over one corner cuts both sides next to
//!   it short, and at 30-40% coverage the corners at their other ends are
//!   often never formed. Such guessed candidates are decoded last of all.
//!
//! Every corner a case had to compute is marked estimated. The search runs
//! first on each border's own corners (tags found without any ellipse),
//! then on the corners around each ellipse, keeping only corners whose
//! inside (the cone between their two lines) faces the anchor, and last on
//! each linked component of borders (see `bridges`: a stick across the
//! frame splits the square's border), with its gap corners, keeping the
//! 4-cycles and triangles that cross borders only along bridged sides;
//! those linked candidates are decoded after all others. Candidates
//! are sorted real corners first, larger first (but a data square before
//! the printed outline around it), and near-duplicates dropped. An
//! estimated corner with a detected corner beside it also gives a second
//! candidate that uses the detected one (the paper's Replace-Fake-Corners);
//! both are kept, because the detected corner may be where an occluder's
//! edge crosses the tag's. The decoder settles it: of
//! the candidates over one tag, the reading with the fewest corrections
//! wins.

use std::ops::Range;

use super::bridges::Links;
use super::by_x::ByX;
use super::corners::{Corner, Segment};
use super::ellipses::Ellipse;
use super::parallel::{collect_ranges, collect_ranges_with, Workers};
use crate::math::{centroid, cross, dot, inside, intersect, mean_side, norm, sub, unit};

/// A candidate quad in working-image coordinates, corners anticlockwise on
/// screen (TL, BL, BR, TR up to a rotation).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Candidate {
    /// Corner positions.
    pub corners: [[f64; 2]; 4],
    /// Which corners were computed rather than seen.
    pub estimated: [bool; 4],
    /// The edge pieces of each real corner (its incoming and outgoing
    /// line, working px); `None` for estimated corners. Refinement measures
    /// the sides along them.
    pub edges: [Option<Edges>; 4],
    /// Tag centre estimate used for same-side recovery, if any.
    pub anchor: Option<[f64; 2]>,
    /// Number of real corners.
    pub real: usize,
    /// Area (working px^2).
    pub area: f64,
    /// Found by the linked pass, across borders joined by bridges: such
    /// candidates are decoded after all others but the guessed ones.
    pub linked: bool,
    /// Guessed from one corner and the tag centre (see `one_corner`):
    /// decoded last of all, and never as a rival reading of a tag already
    /// read, since three of its corners are a parallelogram's.
    pub guessed: bool,
    /// Made from a disc rim alone (`rim`): the corners and sides the rim
    /// predicts, and the print aligned to the image when it was. Its
    /// reading stands only on the tag's model fit
    /// (`decoding::rim_reading_stands`).
    pub rim: Option<super::rim::RimSeen>,
}

/// The two line pieces that meet at a detected corner.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Edges {
    /// The piece arriving at the corner (along the side before it).
    pub incoming: Segment,
    /// The piece leaving the corner (along the side after it).
    pub outgoing: Segment,
}

impl Edges {
    fn of(c: &Corner) -> Self {
        Self {
            incoming: c.seg_in,
            outgoing: c.seg_out,
        }
    }
}

/// Parameters of the quad search, built once by [`crate::Detector::new`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct QuadParams {
    /// Shortest quad side (working px); also how far ahead of a corner a
    /// computed corner must lie.
    pub min_side: f64,
    /// Cosine of the largest angle between two lines of the same edge (the
    /// outgoing line of one corner and the incoming line of the next).
    pub cos_edge: f64,
    /// Whether the occlusion cases run (else 4-cycles only).
    pub recover: bool,
    /// Cap on candidate quads per frame.
    pub max_candidates: usize,
    /// Largest distance of a detected corner replacing an estimated one
    /// (working px).
    pub replace_dist: f64,
}

/// Candidate quads kept per candidate decoded: the search keeps this many
/// times the decoding cap, so that the best ones survive the sort.
pub(crate) const CANDIDATES_PER_DECODE: usize = 4;

/// Successor test: largest distance (px) of a corner from the line of the
/// previous one, `EDGE_TOL + EDGE_TOL_SLOPE * distance along it` (lines
/// fitted to short pieces wander more far away).
const EDGE_TOL: f64 = 1.5;
/// Growth of the successor tolerance per pixel along the edge.
const EDGE_TOL_SLOPE: f64 = 0.06;

/// Most successors kept per corner (the nearest ones).
const MAX_SUCCESSORS: usize = 4;

/// Longest quad side against the shortest: flatter quads are not tags
/// (a tag at 85 degrees of tilt).
const MAX_ASPECT: f64 = 12.0;

/// Where the tag centre may lie along a diagonal (fraction of the diagonal
/// from the visible corner) in the same-side and diagonal cases: the
/// middle, give or take perspective.
const CENTRE_SPAN: std::ops::Range<f64> = 0.3..0.7;

/// Shortest distance (px) a same-side ratio divides by.
const MIN_DIVISOR: f64 = 1e-9;

/// Diagonal case: the two corners are at least this many shortest sides
/// apart, ...
const DIAGONAL_MIN_SIDES: f64 = 2.0;
/// ... and the centre lies within this fraction of the diagonal's length
/// off it.
const DIAGONAL_OFF_AXIS: f64 = 0.1;

/// Fewest corners of one border searched on their own (a triangle).
const MIN_BORDER_CORNERS: usize = 3;

/// Corners around an ellipse: closer to its centre than this many major
/// semi-axes (the data square's corners lie inside the rim), ...
const ELLIPSE_REACH: f64 = 1.05;
/// ... farther than this many minor semi-axes (not the checker's corners).
const ELLIPSE_HOLE: f64 = 0.25;
/// Fewest corners around an ellipse searched (a same-side pair).
const MIN_ELLIPSE_CORNERS: usize = 2;

/// A checker disc anchors a border-only quad when it is within this
/// fraction of the mean side from the crossing of the diagonals.
const ANCHOR_MATCH: f64 = 0.1;

/// Fewest seen corners of a linked candidate: a stick across the tag
/// leaves at least two corners with both their sides' pieces long enough
/// to be lines, and candidates with more computed corners (gap corners,
/// triangles) over the cells of large tags cost decoding time for nothing.
const MIN_LINKED_REAL: usize = 2;

/// Two candidates whose corners all agree within this (working px), up to
/// a rotation, are one.
const DUPLICATE_TOL: f64 = 1.5;

/// Fewest borders in one piece of the parallel search on each border
/// alone (most borders of a cluttered frame have a handful of corners).
const MIN_BORDERS_PER_PIECE: usize = 64;

/// Fewest ellipses in one piece of the parallel search around ellipses
/// (each looks at every corner of the frame).
const MIN_ELLIPSES_PER_PIECE: usize = 4;

/// Fewest candidates in one piece of the parallel Replace-Fake-Corners
/// step (each estimated corner looks at every corner of the frame).
const MIN_CANDIDATES_PER_PIECE: usize = 16;

/// Reusable buffers.
#[derive(Debug, Default)]
pub(crate) struct QuadScratch {
    group: Vec<u32>,
    /// The runs of corners (`start..end`) of the borders searched alone.
    borders: Vec<(u32, u32)>,
    linked: Vec<u32>,
    /// The runs of `linked` searched as one group each.
    runs: Vec<Range<usize>>,
    /// The candidates Replace-Fake-Corners adds.
    replaced: Vec<Candidate>,
    succ: Vec<[u32; MAX_SUCCESSORS]>,
    nsucc: Vec<u8>,
    /// Each candidate's centroid and mean side, for [`data_squares_first`].
    shape: Vec<([f64; 2], f64)>,
    /// Whether a candidate has its place in the new order yet.
    placed: Vec<bool>,
    /// The candidates in their new order.
    reordered: Vec<Candidate>,
    /// The candidates' indices in their sorted order.
    order: Vec<u32>,
    /// The frame's corners by x, for the searches near a point: a
    /// cluttered 4K frame has 500-800 corners and 300 candidates, and
    /// Replace-Fake-Corners, which scanned every corner for each estimated
    /// corner, took 0.2-0.3 ms of its 0.8 ms quad stage.
    by_x: ByX,
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
    let tol = EDGE_TOL + EDGE_TOL_SLOPE * t;
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
    if !(lmin >= p.min_side
        && lmax <= MAX_ASPECT * lmin
        && q.iter().flatten().all(|v| v.is_finite()))
    {
        return None;
    }
    Some(area2.abs() / 2.0)
}

fn push(
    out: &mut Vec<Candidate>,
    q: [[f64; 2]; 4],
    edges: [Option<Edges>; 4],
    anchor: Option<[f64; 2]>,
    p: &QuadParams,
) {
    if out.len() >= p.max_candidates {
        return;
    }
    if let Some(area) = valid_quad(&q, p) {
        let estimated = edges.map(|s| s.is_none());
        out.push(Candidate {
            corners: q,
            estimated,
            edges,
            anchor,
            real: edges.iter().filter(|s| s.is_some()).count(),
            area,
            linked: false,
            guessed: false,
            rim: None,
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
    links: Option<&Links>,
    p: &QuadParams,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    let k = group.len();
    s.succ.clear();
    s.succ.resize(k, [0; MAX_SUCCESSORS]);
    s.nsucc.clear();
    s.nsucc.resize(k, 0);
    for i in 0..k {
        let a = &corners[group[i] as usize];
        let mut best = [(f64::INFINITY, 0u32); MAX_SUCCESSORS];
        let mut nb = 0usize;
        for j in 0..k {
            if i == j {
                continue;
            }
            if let Some(t) = follows(a, &corners[group[j] as usize], p) {
                // Keep the nearest MAX_SUCCESSORS successors.
                if nb < MAX_SUCCESSORS {
                    best[nb] = (t, j as u32);
                    nb += 1;
                } else if let Some(w) =
                    (0..MAX_SUCCESSORS).max_by(|&x, &y| best[x].0.total_cmp(&best[y].0))
                {
                    if t < best[w].0 {
                        best[w] = (t, j as u32);
                    }
                }
            }
        }
        for (m, b) in best.iter().take(nb).enumerate() {
            s.succ[i][m] = b.1;
        }
        s.nsucc[i] = nb as u8;
    }
    let succ = |i: usize| -> &[u32] { &s.succ[i][..s.nsucc[i] as usize] };
    let c = |i: u32| &corners[group[i as usize] as usize];
    // Gap corners are computed, so estimated.
    let src = |i: u32| (!c(i).gap).then(|| Edges::of(c(i)));
    // In the linked pass, only paths across borders, along bridges.
    let across = |path: &[u32]| links.is_none_or(|l| bridged_path(path.iter().map(|&i| c(i)), l));
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
                        if a < b && a < cc && a < d && across(&[a, b, cc, d, a]) {
                            let q = [c(a).pos, c(b).pos, c(cc).pos, c(d).pos];
                            push(out, q, [src(a), src(b), src(cc), src(d)], anchor, p);
                        }
                    }
                }
                if closed || !p.recover || !across(&[a, b, cc]) {
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
                    let r1 = norm(sub(o, ca.pos)) / norm(sub(e1, ca.pos)).max(MIN_DIVISOR);
                    let r2 = norm(sub(o, cb.pos)) / norm(sub(e2, cb.pos)).max(MIN_DIVISOR);
                    if ahead(cb.pos, cb.dout, e1, p.min_side)
                        && ahead(e2, ca.din, ca.pos, p.min_side)
                        && CENTRE_SPAN.contains(&r1)
                        && CENTRE_SPAN.contains(&r2)
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
                if dl < DIAGONAL_MIN_SIDES * p.min_side {
                    continue;
                }
                let t = dot(sub(o, ca.pos), diag) / (dl * dl);
                if !CENTRE_SPAN.contains(&t)
                    || cross(diag, sub(o, ca.pos)).abs() > DIAGONAL_OFF_AXIS * dl * dl
                {
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

/// Runs the whole search: per border, then per ellipse, then across
/// linked borders. The searches around ellipses and across linked borders
/// and the Replace-Fake-Corners step run on `workers`' threads if given,
/// in pieces whose candidates are joined in order and cut at the cap: the
/// same candidates either way, since a candidate is added only while the
/// list has room, so the capped list is the start of the uncapped one.
#[allow(clippy::too_many_arguments)]
pub(crate) fn find_candidates<W: Default + Send>(
    all_corners: &[Corner],
    plain: usize,
    links: &Links,
    ellipses: &[Ellipse],
    p: &QuadParams,
    workers: Option<&Workers<W>>,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    out.clear();
    // The gap corners (after `plain`) only join the linked pass: elsewhere
    // they would pair every computed point with the rest.
    let corners = &all_corners[..plain];
    // Per border (corners are stored border by border), the borders in
    // pieces on `workers`' threads.
    let mut borders = std::mem::take(&mut s.borders);
    borders.clear();
    let mut start = 0;
    for border in corners.chunk_by(|a, b| a.contour == b.contour) {
        let end = start + border.len();
        if border.len() >= MIN_BORDER_CORNERS {
            borders.push((start as u32, end as u32));
        }
        start = end;
    }
    collect_ranges_with(
        workers,
        borders.len(),
        MIN_BORDERS_PER_PIECE,
        s,
        out,
        |r, s, out| {
            let mut group = std::mem::take(&mut s.group);
            for &(i, j) in &borders[r] {
                group.clear();
                group.extend(i..j);
                search_group(corners, &group, None, None, p, s, out);
            }
            s.group = group;
        },
    );
    out.truncate(p.max_candidates);
    s.borders = borders;
    let mut by_x = std::mem::take(&mut s.by_x);
    by_x.fill(corners.len(), |i| corners[i].pos[0]);
    // Around each ellipse.
    let n = ellipses.len();
    collect_ranges_with(workers, n, MIN_ELLIPSES_PER_PIECE, s, out, |r, s, out| {
        for e in &ellipses[r] {
            search_ellipse(corners, &by_x, e, p, s, out);
        }
    });
    out.truncate(p.max_candidates);
    // Replace-Fake-Corners (the paper's Algorithm 2, line 18): an estimated
    // corner with a detected corner close by whose lines run along the
    // quad's two sides there becomes that real corner. The detected corner
    // may itself be false (where an occluder's edge crosses the tag's), so
    // the replacement is a new candidate and the original stays; the
    // decoder keeps whichever reads with fewer corrections.
    let mut replaced = std::mem::take(&mut s.replaced);
    replaced.clear();
    let (found, n) = (&out[..], out.len());
    collect_ranges(
        workers,
        n,
        MIN_CANDIDATES_PER_PIECE,
        &mut replaced,
        |r, more| {
            for cand in &found[r] {
                if n + more.len() >= p.max_candidates {
                    break;
                }
                more.extend(with_real_corners(cand, corners, &by_x, p));
            }
        },
    );
    out.extend_from_slice(&replaced);
    out.truncate(p.max_candidates);
    s.replaced = replaced;
    s.by_x = by_x;
    search_linked(all_corners, links, p, workers, s, out);
    // Last, one corner and the centre, around each ellipse whose anchor is
    // the centre checker's disc.
    if p.recover {
        for e in ellipses.iter().filter(|e| e.checker) {
            for c in corners.iter().filter(|c| around(c, e)) {
                one_corner(c, e.anchor, p, out);
            }
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
        let side = mean_side(&q);
        cand.anchor = ellipses
            .iter()
            .filter(|e| e.checker && norm(sub(e.anchor, x)) < ANCHOR_MATCH * side)
            .min_by(|a, b| norm(sub(a.anchor, x)).total_cmp(&norm(sub(b.anchor, x))))
            .map(|e| e.anchor);
    }
    // Best first: linked candidates near the end, guessed ones last, then
    // more real corners, then larger. Their indices are sorted (stably, as
    // the candidates themselves were) and the candidates moved once: a
    // candidate is a few hundred bytes, and sorting 300-400 of them took
    // 0.06-0.2 ms of a cluttered 4K frame's quad stage.
    let mut order = std::mem::take(&mut s.order);
    order.clear();
    order.extend(0..out.len() as u32);
    order.sort_by(|&i, &j| {
        let (a, b) = (&out[i as usize], &out[j as usize]);
        (a.guessed, a.linked)
            .cmp(&(b.guessed, b.linked))
            .then(b.real.cmp(&a.real))
            .then(b.area.total_cmp(&a.area))
    });
    s.reordered.clear();
    s.reordered.extend(order.iter().map(|&i| out[i as usize]));
    std::mem::swap(out, &mut s.reordered);
    s.order = order;
    // Drop near-duplicates (same corners up to a rotation).
    let mut kept = 0;
    for i in 0..out.len() {
        let q = out[i];
        let dup = out[..kept]
            .iter()
            .any(|k| same_quad(&k.corners, &q.corners, DUPLICATE_TOL));
        if !dup {
            out[kept] = q;
            kept += 1;
        }
    }
    out.truncate(kept);
    data_squares_first(out, s);
}

/// Mean side of a data square over that of the printed square around it
/// (its outline, see `outline`): a half seen square on, a little less
/// under perspective (through a pinhole camera of 1400 px focal length,
/// 0.49 for a 10 cm tag 30 cm away at 60 degrees of tilt, 0.43 at 15 cm
/// and 70 degrees). The range leaves room for corners a working pixel off
/// on a small tag.
const DATA_SQUARE_SHARE: (f64, f64) = (0.35, 0.65);

/// Largest distance between the centroids of a data square's corners and
/// of its outline's, as a share of the outline's mean side: the same
/// point seen square on; under perspective 0.04 in the first case above,
/// 0.11 at 15 cm, 60 degrees of tilt and 30 of yaw.
const DATA_SQUARE_OFFSET: f64 = 0.15;

/// Moves every candidate with four seen corners that lies in the middle
/// of an earlier one as a data square lies in its printed outline to just
/// before it (one with an estimated corner stays: its reading would beat
/// the outline's, whose corners were seen, unseen itself). Sorted
/// larger first, a tag's paper outline comes before its own data square,
/// and the outline's reading (its sides measured, its grid sampled, every
/// reading tried on it and then on its middle half) is the dearer and the
/// weaker one: a reading of the data square's own quad beats it
/// (`decoding::Reading::beats`), and once that reads without
/// corrections the outline, whose centre lies inside it, is not decoded
/// at all. On a clean 1080p frame the outline's reading was three
/// quarters of the decoding stage.
fn data_squares_first(out: &mut Vec<Candidate>, s: &mut QuadScratch) {
    let n = out.len();
    s.shape.clear();
    s.shape.extend(
        out.iter()
            .map(|c| (centroid(&c.corners), mean_side(&c.corners))),
    );
    s.placed.clear();
    s.placed.resize(n, false);
    s.reordered.clear();
    for i in 0..n {
        if s.placed[i] {
            continue;
        }
        let (ci, si) = s.shape[i];
        for j in i + 1..n {
            let (cj, sj) = s.shape[j];
            let nested = !s.placed[j]
                && out[j].real == 4
                && (DATA_SQUARE_SHARE.0 * si..=DATA_SQUARE_SHARE.1 * si).contains(&sj)
                && norm(sub(cj, ci)) <= DATA_SQUARE_OFFSET * si
                && out[j].corners.iter().all(|&p| inside(&out[i].corners, p));
            if nested {
                s.placed[j] = true;
                s.reordered.push(out[j]);
            }
        }
        s.placed[i] = true;
        s.reordered.push(out[i]);
    }
    std::mem::swap(out, &mut s.reordered);
}

/// The search around ellipse `e`: the corners near its rim whose inside
/// faces its anchor (in index order, found in `by_x`), searched as one
/// group.
fn search_ellipse(
    corners: &[Corner],
    by_x: &ByX,
    e: &Ellipse,
    p: &QuadParams,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    let mut group = std::mem::take(&mut s.group);
    group.clear();
    let reach = ELLIPSE_REACH * e.a;
    group.extend(
        by_x.within(e.centre[0], reach)
            .iter()
            .filter(|&&ci| around(&corners[ci as usize], e)),
    );
    group.sort_unstable();
    if group.len() >= MIN_ELLIPSE_CORNERS {
        search_group(corners, &group, Some(e.anchor), None, p, s, out);
    }
    s.group = group;
}

/// Whether corner `c` is one of ellipse `e`'s: inside its rim, off its
/// centre, its inside facing the anchor.
fn around(c: &Corner, e: &Ellipse) -> bool {
    let d = norm(sub(c.pos, e.centre));
    d < ELLIPSE_REACH * e.a && d > ELLIPSE_HOLE * e.b && faces(c, e.anchor)
}

/// One corner `c`, with its two sides, and the tag centre `o` (the centre
/// checker's disc, unbiased under perspective): the quad where all else
/// failed, as when an occluder hides one corner and cuts both sides next
/// to it short, so that no other corner of the square is formed. The
/// opposite corner lies on the diagonal through `o` (straight in any
/// projection), as far beyond `o` as `c` is before it; the other two are
/// where the lines through it parallel to `c`'s sides meet them. That is a
/// parallelogram: refinement, which places hidden corners with the centre,
/// and the model fit correct the perspective, and the decoder judges it.
fn one_corner(c: &Corner, o: [f64; 2], p: &QuadParams, out: &mut Vec<Candidate>) {
    let e = [2.0 * o[0] - c.pos[0], 2.0 * o[1] - c.pos[1]];
    let (Some(b), Some(d)) = (
        intersect(c.pos, c.dout, e, c.din),
        intersect(c.pos, c.din, e, c.dout),
    ) else {
        return;
    };
    if !(ahead(c.pos, c.dout, b, p.min_side) && ahead(d, c.din, c.pos, p.min_side)) {
        return;
    }
    let n = out.len();
    push(
        out,
        [c.pos, b, e, d],
        [Some(Edges::of(c)), None, None, None],
        Some(o),
        p,
    );
    if let Some(cand) = out.get_mut(n) {
        cand.guessed = true;
    }
}

/// `cand` with each estimated corner replaced by the nearest detected
/// corner within [`QuadParams::replace_dist`] whose lines run along the
/// quad's two sides there (of the nearest, the first), found in `by_x`;
/// `None` if no corner was replaced.
fn with_real_corners(
    cand: &Candidate,
    corners: &[Corner],
    by_x: &ByX,
    p: &QuadParams,
) -> Option<Candidate> {
    let mut cand = *cand;
    let mut replaced = false;
    for k in 0..4 {
        if !cand.estimated[k] {
            continue;
        }
        let q = cand.corners;
        let din = unit(sub(q[k], q[(k + 3) % 4]));
        let dout = unit(sub(q[(k + 1) % 4], q[k]));
        let r = p.replace_dist;
        let best = by_x
            .within(q[k][0], r)
            .iter()
            .map(|&i| (i, &corners[i as usize]))
            .filter(|(_, c)| {
                norm(sub(c.pos, q[k])) < r
                    && dot(c.din, din) > p.cos_edge
                    && dot(c.dout, dout) > p.cos_edge
            })
            .min_by(|(i, a), (j, b)| {
                norm(sub(a.pos, q[k]))
                    .total_cmp(&norm(sub(b.pos, q[k])))
                    .then(i.cmp(j))
            })
            .map(|(_, c)| c);
        if let Some(c) = best {
            cand.corners[k] = c.pos;
            cand.estimated[k] = false;
            cand.edges[k] = Some(Edges::of(c));
            cand.real += 1;
            replaced = true;
        }
    }
    replaced.then_some(cand)
}

/// Whether a path of corners crosses borders only along bridges: it
/// visits at least two borders, and each step from one border to another
/// runs along one chain of bridged line pieces (the outgoing line of the
/// first corner and the incoming line of the next are pieces of one edge).
fn bridged_path<'a>(path: impl Iterator<Item = &'a Corner> + Clone, links: &Links) -> bool {
    let mut steps = path.clone().zip(path.skip(1));
    let mut crossed = false;
    let ok = steps.all(|(x, y)| {
        if x.contour == y.contour {
            return true;
        }
        crossed = true;
        links.chain(x.lines[1]) == links.chain(y.lines[0])
    });
    ok && crossed
}

/// The linked pass: the corners of each linked component of borders (two
/// or more borders joined by bridges) searched as one group, for quads
/// across those borders (see [`bridged_path`]). It runs last, so its
/// candidates never take the place of the other passes' under the cap.
fn search_linked<W: Default + Send>(
    corners: &[Corner],
    links: &Links,
    p: &QuadParams,
    workers: Option<&Workers<W>>,
    s: &mut QuadScratch,
    out: &mut Vec<Candidate>,
) {
    if !links.any() {
        return;
    }
    let mut linked = std::mem::take(&mut s.linked);
    linked.clear();
    linked.extend(
        (0..corners.len() as u32).filter(|&i| links.is_bridged(corners[i as usize].contour)),
    );
    linked.sort_by_key(|&i| (links.component(corners[i as usize].contour), i));
    let mut runs = std::mem::take(&mut s.runs);
    runs.clear();
    let mut at = 0;
    for run in linked.chunk_by(|&i, &j| {
        links.component(corners[i as usize].contour) == links.component(corners[j as usize].contour)
    }) {
        if run.len() >= MIN_BORDER_CORNERS {
            runs.push(at..at + run.len());
        }
        at += run.len();
    }
    let first = out.len();
    collect_ranges_with(workers, runs.len(), 1, s, out, |r, s, out| {
        for run in &runs[r] {
            search_group(corners, &linked[run.clone()], None, Some(links), p, s, out);
        }
    });
    out.truncate(p.max_candidates);
    let mut kept = first;
    for i in first..out.len() {
        if out[i].real >= MIN_LINKED_REAL {
            out[kept] = out[i];
            out[kept].linked = true;
            kept += 1;
        }
    }
    out.truncate(kept);
    s.linked = linked;
    s.runs = runs;
}

fn same_quad(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4], tol: f64) -> bool {
    // Squared distances: this runs on every pair of candidates.
    let tol2 = tol * tol;
    (0..4).any(|r| {
        (0..4).all(|i| {
            let d = sub(a[i], b[(i + r) % 4]);
            dot(d, d) < tol2
        })
    })
}

#[cfg(test)]
mod tests {
    //! Each occlusion case of the paper's Algorithm 2 on hand-built corners
    //! (and an ellipse for the tag centre): a 40 px square tag with corners
    //! TL (20, 20), BL (20, 60), BR (60, 60), TR (60, 20), anticlockwise on
    //! screen, centre (40, 40).
    use super::*;

    const TL: [f64; 2] = [20.0, 20.0];
    const BL: [f64; 2] = [20.0, 60.0];
    const BR: [f64; 2] = [60.0, 60.0];
    const TR: [f64; 2] = [60.0, 20.0];
    const CENTRE: [f64; 2] = [40.0, 40.0];

    fn params() -> QuadParams {
        QuadParams {
            min_side: 4.0,
            cos_edge: 20f64.to_radians().cos(),
            recover: true,
            max_candidates: 1600,
            replace_dist: 7.0,
        }
    }

    /// The corner at `pos` between the side arriving from `prev` and the
    /// side leaving towards `next`, seen on `contour`; its line pieces
    /// cover the 10 px next to it.
    fn corner(prev: [f64; 2], pos: [f64; 2], next: [f64; 2], contour: u32) -> Corner {
        let din = unit(sub(pos, prev));
        let dout = unit(sub(next, pos));
        let back = [pos[0] - 10.0 * din[0], pos[1] - 10.0 * din[1]];
        let ahead = [pos[0] + 10.0 * dout[0], pos[1] + 10.0 * dout[1]];
        Corner {
            pos,
            din,
            dout,
            seg_in: [back, pos],
            seg_out: [pos, ahead],
            contour,
            lines: [0, 0],
            gap: false,
        }
    }

    /// The disc rim around the tag, its anchor on the tag centre.
    fn rim() -> Ellipse {
        Ellipse {
            centre: CENTRE,
            a: 33.0,
            b: 33.0,
            anchor: CENTRE,
            checker: true,
            axis: [1.0, 0.0],
            pieced: false,
        }
    }

    fn search(corners: &[Corner], ellipses: &[Ellipse]) -> Vec<Candidate> {
        let mut out = Vec::new();
        find_candidates(
            corners,
            corners.len(),
            &Links::default(),
            ellipses,
            &params(),
            None::<&Workers<()>>,
            &mut QuadScratch::default(),
            &mut out,
        );
        out
    }

    /// The candidate over the tag (corners within 1e-6 px of the truth, up
    /// to a rotation of the list), with its estimated flags in TL, BL, BR,
    /// TR order.
    fn the_tag(cands: &[Candidate]) -> Option<[bool; 4]> {
        let truth = [TL, BL, BR, TR];
        cands.iter().find_map(|c| {
            (0..4).find_map(|r| {
                (0..4)
                    .all(|i| norm(sub(c.corners[(i + r) % 4], truth[i])) < 1e-6)
                    .then(|| std::array::from_fn(|i| c.estimated[(i + r) % 4]))
            })
        })
    }

    /// A seen quad with corners `q`, as the border search makes it.
    fn seen(q: [[f64; 2]; 4]) -> Candidate {
        let [a, b, c, d] = q;
        let corners = [
            corner(d, a, b, 0),
            corner(a, b, c, 0),
            corner(b, c, d, 0),
            corner(c, d, a, 0),
        ];
        search(&corners, &[])[0]
    }

    /// `q` scaled by `k` about `c` and shifted by `by`.
    fn scaled(q: [[f64; 2]; 4], c: [f64; 2], k: f64, by: [f64; 2]) -> [[f64; 2]; 4] {
        q.map(|p| {
            [
                c[0] + k * (p[0] - c[0]) + by[0],
                c[1] + k * (p[1] - c[1]) + by[1],
            ]
        })
    }

    #[test]
    fn a_data_square_is_decoded_before_its_outline() {
        let tag = [TL, BL, BR, TR];
        let outline = seen(scaled(tag, CENTRE, 2.0, [0.0, 0.0]));
        let data = seen(tag);
        // Sorted larger first: the outline, then elsewhere a large quad,
        // then the data square, then a quad too small to be the outline's
        // data square, then one off its middle.
        let other = seen(scaled(tag, CENTRE, 1.5, [200.0, 0.0]));
        let cell = seen(scaled(tag, CENTRE, 0.25, [0.0, 0.0]));
        let off = seen(scaled(tag, CENTRE, 0.5, [14.0, 0.0]));
        let mut out = vec![outline, other, data, cell, off];
        data_squares_first(&mut out, &mut QuadScratch::default());
        let order: Vec<f64> = out.iter().map(|c| c.corners[0][0]).collect();
        let want: Vec<f64> = [data, outline, other, cell, off]
            .iter()
            .map(|c| c.corners[0][0])
            .collect();
        assert_eq!(order, want);
        // A data square with a corner of its own estimated keeps its place:
        // its reading would beat the outline's (seen corners) unseen.
        let mut hidden = data;
        hidden.real = 3;
        hidden.estimated[2] = true;
        let mut out = vec![outline, hidden];
        data_squares_first(&mut out, &mut QuadScratch::default());
        assert_eq!(out[0].corners, outline.corners);
    }

    #[test]
    fn four_corners_form_a_quad() {
        let corners = [
            corner(TR, TL, BL, 0),
            corner(TL, BL, BR, 0),
            corner(BL, BR, TR, 0),
            corner(BR, TR, TL, 0),
        ];
        let cands = search(&corners, &[]);
        assert_eq!(the_tag(&cands), Some([false; 4]), "{cands:?}");
        assert!(cands[0].edges.iter().all(Option::is_some));
    }

    #[test]
    fn triangle_recovers_one_hidden_corner() {
        // TR hidden: a path TL -> BL -> BR; TR is where BR's outgoing line
        // meets TL's incoming line.
        let corners = [
            corner(TR, TL, BL, 0),
            corner(TL, BL, BR, 0),
            corner(BL, BR, TR, 0),
        ];
        let cands = search(&corners, &[]);
        assert_eq!(
            the_tag(&cands),
            Some([false, false, false, true]),
            "{cands:?}"
        );
        let no_recovery = {
            let mut out = Vec::new();
            let p = QuadParams {
                recover: false,
                ..params()
            };
            find_candidates(
                &corners,
                corners.len(),
                &Links::default(),
                &[],
                &p,
                None::<&Workers<()>>,
                &mut QuadScratch::default(),
                &mut out,
            );
            out
        };
        assert!(no_recovery.is_empty());
    }

    #[test]
    fn same_side_recovers_two_corners_from_the_centre() {
        // The right side hidden: TL -> BL seen, BR and TR on the diagonals
        // through the centre.
        let corners = [corner(TR, TL, BL, 0), corner(TL, BL, BR, 0)];
        assert!(the_tag(&search(&corners, &[])).is_none());
        let cands = search(&corners, &[rim()]);
        assert_eq!(
            the_tag(&cands),
            Some([false, false, true, true]),
            "{cands:?}"
        );
    }

    #[test]
    fn one_corner_and_the_checker_centre_guess_the_square_last() {
        // Only BR formed (an occluder over TL cut the sides next to BL and
        // TR short); a clutter quad's four corners beside the tag.
        let (a, b, c, d) = ([80.0, 80.0], [80.0, 100.0], [100.0, 100.0], [100.0, 80.0]);
        let mut corners = vec![corner(BL, BR, TR, 0)];
        corners.extend([
            corner(d, a, b, 1),
            corner(a, b, c, 1),
            corner(b, c, d, 1),
            corner(c, d, a, 1),
        ]);
        let cands = search(&corners, &[rim()]);
        assert_eq!(
            the_tag(&cands),
            Some([true, true, false, true]),
            "{cands:?}"
        );
        let last = cands.last().unwrap();
        assert!(last.guessed && last.real == 1, "{cands:?}");
        assert!(cands.iter().filter(|c| c.guessed).count() == 1);
        // The rim's own centre is biased under perspective: no guess
        // without the checker's disc.
        let biased = Ellipse {
            checker: false,
            ..rim()
        };
        assert!(the_tag(&search(&corners, &[biased])).is_none());
        assert!(search(&corners, &[biased]).iter().all(|c| !c.guessed));
    }

    #[test]
    fn symmetry_joins_corners_of_two_borders() {
        // A band across the middle splits the border in two: TL, BL on one,
        // BR, TR on the other. Neither border holds a tag alone; around the
        // rim the four corners close a cycle.
        let corners = [
            corner(TR, TL, BL, 0),
            corner(TL, BL, BR, 0),
            corner(BL, BR, TR, 1),
            corner(BR, TR, TL, 1),
        ];
        assert!(the_tag(&search(&corners, &[])).is_none());
        let cands = search(&corners, &[rim()]);
        assert_eq!(the_tag(&cands), Some([false; 4]), "{cands:?}");
    }

    #[test]
    fn diagonal_recovers_two_opposite_corners() {
        // BL and TR hidden: each is where a line of TL meets a line of BR.
        let corners = [corner(TR, TL, BL, 0), corner(BL, BR, TR, 0)];
        assert!(the_tag(&search(&corners, &[])).is_none());
        let cands = search(&corners, &[rim()]);
        assert_eq!(
            the_tag(&cands),
            Some([false, true, false, true]),
            "{cands:?}"
        );
    }

    #[test]
    fn linked_borders_close_a_quad_across_a_cut() {
        // A stick down the middle cuts the top and bottom sides: TL, BL on
        // border 0, BR, TR on border 1, no ellipse. The bottom and top
        // sides' pieces continue each other across a 10 px gap.
        use crate::detect::bridges::find_bridges;
        use crate::detect::lines::{Line, Polygons};
        let line = |ps: [f64; 2], pe: [f64; 2]| Line {
            ps,
            pe,
            dir: unit(sub(pe, ps)),
        };
        let mut polys = Polygons::default();
        polys.lines = vec![
            line(TL, BL),
            line(BL, [35.0, 60.0]),
            line([35.0, 20.0], TL),
            line([45.0, 60.0], BR),
            line(BR, TR),
            line(TR, [45.0, 20.0]),
        ];
        polys.line_ranges = vec![(0, 3), (3, 6)];
        let mut links = Links::default();
        find_bridges(&polys, None::<&Workers<()>>, &mut links);
        let with = |mut c: Corner, lines: [u32; 2]| {
            c.lines = lines;
            c
        };
        let corners = [
            with(corner(TR, TL, BL, 0), [2, 0]),
            with(corner(TL, BL, BR, 0), [0, 1]),
            with(corner(BL, BR, TR, 1), [3, 4]),
            with(corner(BR, TR, TL, 1), [4, 5]),
        ];
        assert!(the_tag(&search(&corners, &[])).is_none());
        let mut out = Vec::new();
        let s = &mut QuadScratch::default();
        let none = None::<&Workers<()>>;
        find_candidates(&corners, 4, &links, &[], &params(), none, s, &mut out);
        assert_eq!(the_tag(&out), Some([false; 4]), "{out:?}");
        assert!(out.iter().all(|c| c.linked));
    }

    /// [`with_real_corners`] as it was before [`ByX`]: a scan of
    /// every corner for each estimated one.
    fn with_real_corners_by_scan(
        cand: &Candidate,
        corners: &[Corner],
        p: &QuadParams,
    ) -> Option<[[f64; 2]; 4]> {
        let mut q = cand.corners;
        let mut replaced = false;
        for k in 0..4 {
            let din = unit(sub(q[k], q[(k + 3) % 4]));
            let dout = unit(sub(q[(k + 1) % 4], q[k]));
            let best = corners
                .iter()
                .filter(|c| {
                    norm(sub(c.pos, q[k])) < p.replace_dist
                        && dot(c.din, din) > p.cos_edge
                        && dot(c.dout, dout) > p.cos_edge
                })
                .min_by(|a, b| norm(sub(a.pos, q[k])).total_cmp(&norm(sub(b.pos, q[k]))));
            if let Some(c) = best {
                q[k] = c.pos;
                replaced = true;
            }
        }
        replaced.then_some(q)
    }

    proptest::proptest! {
        /// The searches near a point through [`ByX`] find what a
        /// scan of every corner finds: the corners around an ellipse, in
        /// index order, and the corners replacing estimated ones (of the
        /// nearest, the first). Positions on a coarse grid and few
        /// directions, so that many corners share an x, some a distance,
        /// and some run along the quad's sides; one is not finite.
        #[test]
        fn corners_by_x_find_what_a_scan_of_every_corner_finds(
            points in proptest::collection::vec((0u32..40, 0u32..40, 1u32..7, 0u32..4), 0..150),
            at in (0u32..40, 0u32..40),
            reach in 0u32..30,
        ) {
            let dir = |k: u32| {
                let t = f64::from(k) * std::f64::consts::FRAC_PI_4;
                [t.cos(), t.sin()]
            };
            let mut corners: Vec<Corner> = points
                .iter()
                .map(|&(x, y, i, o)| {
                    let pos = [f64::from(x) * 2.0, f64::from(y) * 2.0];
                    Corner { din: dir(i), dout: dir(o), ..corner(TL, pos, BL, 0) }
                })
                .collect();
            if let Some(c) = corners.first_mut() {
                c.pos[0] = f64::NAN;
            }
            let mut by_x = ByX::default();
            by_x.fill(corners.len(), |i| corners[i].pos[0]);
            let centre = [f64::from(at.0) * 2.0, f64::from(at.1) * 2.0];
            let e = Ellipse {
                centre,
                a: f64::from(reach),
                b: f64::from(reach) / 2.0,
                ..rim()
            };
            let s = &mut QuadScratch::default();
            let p = QuadParams {
                replace_dist: f64::from(reach) / 3.0,
                ..params()
            };
            search_ellipse(&corners, &by_x, &e, &p, s, &mut Vec::new());
            let all: Vec<u32> = (0..corners.len() as u32)
                .filter(|&i| around(&corners[i as usize], &e))
                .collect();
            proptest::prop_assert_eq!(&s.group, &all);
            // A 20 px square of estimated corners, the first at the point.
            let (x, y) = (centre[0], centre[1]);
            let cand = Candidate {
                corners: [[x, y], [x, y + 20.0], [x + 20.0, y + 20.0], [x + 20.0, y]],
                estimated: [true; 4],
                edges: [None; 4],
                anchor: None,
                real: 0,
                area: 400.0,
                linked: false,
                guessed: false,
                rim: None,
            };
            let got = with_real_corners(&cand, &corners, &by_x, &p);
            proptest::prop_assert_eq!(
                got.map(|c| c.corners),
                with_real_corners_by_scan(&cand, &corners, &p)
            );
        }
    }

    #[test]
    fn a_corner_off_its_side_is_not_a_successor() {
        let a = corner(TR, TL, BL, 0);
        let b = corner(TL, BL, BR, 0);
        assert!(follows(&a, &b, &params()).is_some());
        // BL moved 10 px sideways off TL's outgoing line.
        let off = corner(TL, [30.0, 60.0], BR, 0);
        assert!(follows(&a, &off, &params()).is_none());
    }
}

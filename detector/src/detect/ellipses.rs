//! Stage 4: ellipse candidates, the projected outer rim of the tag's disc.
//!
//! The paper uses AAMED (Meng et al., "Arc adjacency matrix-based fast
//! ellipse detection", IEEE TIP 2020). This is a simpler arc-based scheme
//! that has the property the detector needs, finding the rim when up to
//! about a third of it is hidden:
//!
//! 1. Arcs: maximal runs of a border's Douglas-Peucker polygon whose turns
//!    all bend towards the dark side by less than 80 degrees (the rim is the
//!    border of a dark disc, so it is convex towards the dark side; straight
//!    occluder edges and square corners break the runs). A junction that
//!    turns far more than the rest of its run also ends it, and a run that
//!    does not fit is trimmed from its worse end: where the rim meets an
//!    occluder, the border often bends onto the occluder's edge gently
//!    enough to pass the 80-degree test.
//! 2. Each arc spanning enough of an ellipse gets a direct least-squares
//!    ellipse fit (Fitzgibbon, Pilu & Fisher, "Direct least square fitting
//!    of ellipses", IEEE PAMI 1999, in the numerically stable form of Halir &
//!    Flusser 1998), accepted when the points fit it well.
//! 3. Arcs whose ellipses agree (an occluder splits the rim into several
//!    arcs, maybe in several borders) are merged and refitted together.
//!
//! Two sticks across a small tag cut its rim into pieces too short to fit
//! alone (under a third of the rim, or a dozen border points). Such
//! fragments are paired, each with the one nearby that fits one ellipse
//! with it best, and a pair that makes a good ellipse over enough of the
//! rim joins step 3 as if it were an arc (`group_fragments`). The image
//! then confirms that the pair's ellipse is a dark disc on white
//! (`rim::stands_out`), which most pairs of clutter's curves are not.
//!
//! The ellipse centre anchors the search for the tag's corners. Because the
//! centre of a projected circle is not the projection of its centre, the
//! centre checker's small white disc, when it is found near the ellipse
//! centre, gives the tag centre instead (its own projection bias is ten
//! times smaller).

use super::by_x::ByX;
use super::contours::Contours;
use super::lines::Polygons;
use super::parallel::{collect_ranges_with, Workers};
use crate::math::{cross, dot, fp, norm, sub};

/// A fitted ellipse in working-image coordinates.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ellipse {
    /// Centre.
    pub centre: [f64; 2],
    /// Semi-major axis.
    pub a: f64,
    /// Semi-minor axis.
    pub b: f64,
    /// Best estimate of the projected tag centre (the centre checker's disc
    /// when found, else the ellipse centre).
    pub anchor: [f64; 2],
    /// Whether `anchor` is the checker's disc (unbiased under perspective,
    /// unlike the rim's centre).
    pub checker: bool,
    /// Unit vector along the major axis (either way along it): with the
    /// axes, the rim's projection of the disc up to the tag's rotation
    /// about its centre (see `rim`).
    pub axis: [f64; 2],
    /// Fitted to paired rim fragments alone (see [`group_fragments`]):
    /// the image must confirm it (`rim::stands_out`).
    pub pieced: bool,
}

/// Largest turn (degrees) towards the dark side at a polygon vertex inside
/// an arc; sharper turns (square corners) end it.
const MAX_TURN_DEG: f64 = 80.0;

/// Smallest turn (degrees) towards the dark side inside an arc: straight or
/// outward junctions end it.
const MIN_TURN_DEG: f64 = 1.0;

/// A junction turning more than this many times the median turn of its run
/// (and more than [`OUTLIER_MIN_TURN_DEG`]) ends the run (see
/// `split_at_outliers`).
const OUTLIER_TURN_RATIO: f64 = 3.0;

/// Turns below this (degrees) never count as outliers of their run.
const OUTLIER_MIN_TURN_DEG: f64 = 30.0;

/// Most polygon sides trimmed off the ends of a run that does not fit an
/// ellipse as a whole.
const MAX_TRIM: usize = 4;

/// Fewest polygon sides of an arc (and junctions of a run whose median
/// turn is measured): fewer cannot tell a curve from a corner.
const MIN_ARC_SIDES: usize = 3;

/// An arc holds at least `min_arc_points / ARC_SHARE` border points.
const ARC_SHARE: usize = 2;

/// Sectors (of equal angle around the ellipse centre) used to measure how
/// much of an ellipse an arc covers.
const SECTORS: usize = 12;

/// An arc must have points in at least this many of the [`SECTORS`]
/// (4 of 12: a third of the rim).
const MIN_SECTORS: usize = 4;

/// Smallest ratio of minor to major semi-axis kept (a disc seen at up to
/// about 78 degrees of tilt).
const MIN_AXIS_RATIO: f64 = 0.2;

/// Arcs of one ellipse: centres closer than this fraction of the larger
/// major semi-axis, ...
const MERGE_CENTRE: f64 = 0.15;
/// ... major semi-axes within this fraction of the first arc's, ...
const MERGE_MAJOR: f64 = 0.2;
/// ... and minor semi-axes within this fraction of the larger one.
const MERGE_MINOR: f64 = 0.25;

/// Fewest points of a conic fit (five degrees of freedom, plus one).
const MIN_FIT_POINTS: usize = 6;

/// Numerical guards of the conic fit: point spread (px) and polygon area
/// below which the points are degenerate, ...
const MIN_SPREAD: f64 = 1e-9;
/// ... squared norm of a null eigenvector or gradient, ...
const NULL_VECTOR: f64 = 1e-30;
/// ... determinant of a conic without a centre (a parabola), ...
const SINGULAR_CENTRE: f64 = 1e-15;
/// ... and coefficient of a depressed cubic with a triple root.
const TRIPLE_ROOT: f64 = 1e-300;

/// Shortest hole border (points) looked at as the checker's white disc.
const MIN_CHECKER_POINTS: u32 = 4;

/// Size of the checker's white disc relative to the rim's major axis (its
/// diameter is about 0.2 S: ct14 1/6 of the data square, ct8 2/15; the
/// rim's is 1.64 S, so about 0.1).
const CHECKER_SIZE: std::ops::RangeInclusive<f64> = 0.04..=0.2;

/// Largest distance of the checker disc from the rim's centre, in major
/// semi-axes (perspective moves the rim's centre off the tag centre).
const CHECKER_OFFSET: f64 = 0.25;

/// Area of the checker disc against its bounding box (a disc fills pi/4).
const CHECKER_FILL: std::ops::RangeInclusive<f64> = 0.3..=0.95;

/// The ellipse stage looks at borders at least this many times
/// `DetectorConfig::min_contour_points` long: a rim is a long border.
pub(crate) const RIM_BORDER_FACTOR: usize = 2;

/// Parameters of the ellipse stage, built once by [`crate::Detector::new`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct EllipseParams {
    /// Smallest semi-minor axis kept (working px): smaller rims are too few
    /// pixels to fit.
    pub min_minor: f64,
    /// Smallest border length looked at (border points); arcs need half
    /// of it.
    pub min_arc_points: usize,
    /// Largest RMS (Sampson) distance of the border points from a fitted
    /// ellipse (working px).
    pub max_rms: f64,
    /// Whether rim fragments are paired ([`group_fragments`]): in the
    /// main look only. The small-tag look's regions are cut around rims
    /// already found, and there it would only cost time.
    pub pair_fragments: bool,
}

/// Reusable buffers.
#[derive(Debug, Default)]
pub(crate) struct EllipseScratch {
    arcs: Vec<Arc>,
    frags: Vec<Frag>,
    pts: Vec<[f64; 2]>,
    junctions: Junctions,
}

/// Per-border buffers for the turns at polygon vertices.
#[derive(Debug, Default)]
struct Junctions {
    /// Turn at each vertex towards the dark side (radians).
    turns: Vec<f64>,
    /// Whether an arc may continue through each vertex.
    ok: Vec<bool>,
    /// Vertices of the run being looked at, and their sorted turns.
    run: Vec<usize>,
    vals: Vec<f64>,
}

#[derive(Debug, Clone, Copy)]
struct Arc {
    contour: u32,
    /// First point index (into the contour) and number of points.
    start: u32,
    len: u32,
    fit: Conic,
    merged: bool,
    /// One of a pair of fragments ([`group_fragments`]).
    pieced: bool,
}

/// A run of a border that bends towards the dark side like a rim but made
/// no arc: too short, or covering too little of its own ellipse. Two
/// sticks across a small tag leave its rim in such pieces.
#[derive(Debug, Clone, Copy)]
struct Frag {
    contour: u32,
    /// First point index (into the contour) and number of points.
    start: u32,
    len: u32,
}

/// General conic A x^2 + B xy + C y^2 + D x + E y + F = 0 with its
/// geometric parameters.
#[derive(Debug, Clone, Copy)]
struct Conic {
    centre: [f64; 2],
    a: f64,
    b: f64,
    /// Unit vector along the major axis.
    axis: [f64; 2],
    rms: f64,
}

/// Finds ellipse candidates: the arcs of each border (on `workers`'
/// threads if given, in runs of borders of about equal points, the same
/// arcs in the same order either way), then merged.
pub(crate) fn find_ellipses<W: Default + Send>(
    contours: &Contours,
    polys: &Polygons,
    params: &EllipseParams,
    workers: Option<&Workers<W>>,
    scratch: &mut EllipseScratch,
    out: &mut Vec<Ellipse>,
) {
    out.clear();
    scratch.arcs.clear();
    scratch.frags.clear();
    let n = contours.list.len();
    match workers {
        None => arcs_of(contours, polys, 0..n, params, scratch),
        Some(w) => {
            let points = |i: usize| contours.list[i].len as usize;
            let parts = w.map_weighted(n, points, MIN_POINTS_PER_PIECE, |r| {
                let mut s = EllipseScratch::default();
                arcs_of(contours, polys, r, params, &mut s);
                (s.arcs, s.frags)
            });
            for (arcs, frags) in parts {
                scratch.arcs.extend(arcs);
                scratch.frags.extend(frags);
            }
        }
    }
    if params.pair_fragments {
        group_fragments(contours, params, workers, scratch);
    }
    merge(contours, params, scratch, out);
}

/// Fewest fragments in one piece of [`group_fragments`]' parallel fits (a
/// fragment has a few pairs within reach, each fit some microseconds).
const MIN_FRAGMENTS_PER_PIECE: usize = 64;

/// Fewest border points in one piece of [`find_ellipses`]' parallel work,
/// which is cut by points: the long borders, few, hold most of the work.
const MIN_POINTS_PER_PIECE: usize = 2048;

/// The arcs of the borders `range`, appended to `scratch.arcs`.
fn arcs_of(
    contours: &Contours,
    polys: &Polygons,
    range: std::ops::Range<usize>,
    params: &EllipseParams,
    scratch: &mut EllipseScratch,
) {
    let max_turn = MAX_TURN_DEG.to_radians();
    let min_turn = MIN_TURN_DEG.to_radians();
    let first = range.start;
    for (ci, c) in contours.list[range].iter().enumerate() {
        let ci = first + ci;
        if (c.len as usize) < params.min_arc_points {
            continue;
        }
        let pts = contours.points_of(c);
        let n = pts.len();
        let (v0, v1) = polys.vertex_ranges[ci];
        let verts = &polys.vertices[v0 as usize..v1 as usize];
        let m = verts.len();
        if m < MIN_ARC_SIDES {
            continue;
        }
        // Turning towards the dark side, which is left of the traversal:
        // a negative cross product on screen.
        let sign = -1.0;
        let vpt = |k: usize| fp(pts[verts[k % m] as usize]);
        // Turn at vertex k, between sides k-1 and k.
        let turn = |k: usize| {
            let a = sub(vpt(k), vpt(k + m - 1));
            let b = sub(vpt(k + 1), vpt(k));
            sign * cross(a, b).atan2(dot(a, b))
        };
        let mut jn = std::mem::take(&mut scratch.junctions);
        jn.turns.clear();
        jn.turns.extend((0..m).map(turn));
        jn.ok.clear();
        jn.ok
            .extend(jn.turns.iter().map(|&t| t > min_turn && t < max_turn));
        split_at_outliers(&mut jn);
        let ok = &jn.ok;
        // Start walking just after a bad junction (or anywhere if none).
        let first_bad = ok.iter().position(|&g| !g);
        let start = first_bad.unwrap_or(0);
        let mut k = 0;
        while k < m {
            // A run starts at vertex start+k and extends while junctions are good.
            let s = start + k;
            let mut e = s + 1;
            while e < start + m && ok[e % m] {
                e += 1;
            }
            if first_bad.is_none() {
                e = s + m;
            }
            if first_bad.is_none() {
                // A closed convex border: the whole of it.
                let i0 = verts[s % m] as usize;
                push_arc(pts, ci as u32, i0, i0 + n - 1, params, scratch);
            } else {
                let span = |a: usize, b: usize| {
                    let i0 = verts[a % m] as usize;
                    let mut i1 = verts[b % m] as usize;
                    if i1 <= i0 {
                        i1 += n;
                    }
                    (i0, i1)
                };
                // Where the rim meets an occluder the border turns onto
                // the occluder's edge, often by less than `max_turn`, so
                // a run may end in a side or two that are not rim. Trim
                // sides off the ends, the worse-fitting end first, until
                // the rest fits (at most MAX_TRIM sides).
                let (mut a, mut b) = (s, e);
                let mut trimmed = 0;
                let mut pushed = false;
                while b - a >= MIN_ARC_SIDES {
                    let (i0, i1) = span(a, b);
                    if push_arc(pts, ci as u32, i0, i1, params, scratch) {
                        pushed = true;
                        break;
                    }
                    if trimmed == MAX_TRIM {
                        break;
                    }
                    let rms = |a: usize, b: usize, sc: &mut EllipseScratch| {
                        let (i0, i1) = span(a, b);
                        arc_points(pts, i0, i1, sc);
                        fit_ellipse(&sc.pts).map_or(f64::INFINITY, |f| f.rms)
                    };
                    if b - a == MIN_ARC_SIDES {
                        break;
                    }
                    if rms(a + 1, b, scratch) <= rms(a, b - 1, scratch) {
                        a += 1;
                    } else {
                        b -= 1;
                    }
                    trimmed += 1;
                }
                // A run that made no arc may be a piece of a rim cut short.
                let (i0, i1) = span(s, e);
                if !pushed && e - s >= FRAG_MIN_SIDES && i1 - i0 + 1 >= FRAG_MIN_POINTS {
                    scratch.frags.push(Frag {
                        contour: ci as u32,
                        start: (i0 % n) as u32,
                        len: (i1 - i0 + 1) as u32,
                    });
                }
            }
            k = e - start;
        }
        scratch.junctions = jn;
    }
}

/// Where a rim runs into an occluder the border turns onto the occluder's
/// edge, often by less than the 80-degree limit. Douglas-Peucker turns
/// along one smooth arc are alike (about sqrt(8 eps / R) for curvature
/// radius R), so a junction turning more than three times the median of
/// its run, and by more than 30 degrees, ends the run there.
fn split_at_outliers(jn: &mut Junctions) {
    let Junctions {
        turns,
        ok,
        run,
        vals,
    } = jn;
    let m = turns.len();
    let Some(first_bad) = ok.iter().position(|&g| !g) else {
        return;
    };
    let mut flush = |run: &mut Vec<usize>, ok: &mut [bool]| {
        if run.len() >= MIN_ARC_SIDES {
            vals.clear();
            vals.extend(run.iter().map(|&k| turns[k]));
            vals.sort_by(f64::total_cmp);
            let limit =
                (OUTLIER_TURN_RATIO * vals[vals.len() / 2]).max(OUTLIER_MIN_TURN_DEG.to_radians());
            for &k in run.iter() {
                if turns[k] > limit {
                    ok[k] = false;
                }
            }
        }
        run.clear();
    };
    run.clear();
    for i in 1..=m {
        let k = (first_bad + i) % m;
        if ok[k] {
            run.push(k);
        } else {
            flush(run, ok);
        }
    }
    flush(run, ok);
}

fn arc_points(pts: &[[i32; 2]], i0: usize, i1: usize, scratch: &mut EllipseScratch) {
    let n = pts.len();
    scratch.pts.clear();
    scratch.pts.extend((i0..=i1).map(|k| fp(pts[k % n])));
}

/// Fits the border points `i0..=i1` (indices modulo the border length) and
/// keeps them as an arc when the fit is a good ellipse; returns whether it
/// was kept.
fn push_arc(
    pts: &[[i32; 2]],
    contour: u32,
    i0: usize,
    i1: usize,
    params: &EllipseParams,
    scratch: &mut EllipseScratch,
) -> bool {
    let n = pts.len();
    let len = i1 - i0 + 1;
    if len < params.min_arc_points / ARC_SHARE {
        return false;
    }
    arc_points(pts, i0, i1, scratch);
    let Some(fit) = fit_ellipse(&scratch.pts) else {
        return false;
    };
    if !(accept(&fit, params) && coverage(&scratch.pts, &fit) >= MIN_SECTORS) {
        return false;
    }
    scratch.arcs.push(Arc {
        contour,
        start: (i0 % n) as u32,
        len: len as u32,
        fit,
        merged: false,
        pieced: false,
    });
    true
}

fn accept(f: &Conic, params: &EllipseParams) -> bool {
    f.b >= params.min_minor && f.b >= MIN_AXIS_RATIO * f.a && f.rms <= params.max_rms
}

/// Number of 30-degree sectors (of 12) around the ellipse centre that hold
/// fitted points.
fn coverage(pts: &[[f64; 2]], f: &Conic) -> usize {
    let mut bins = [false; SECTORS];
    for p in pts {
        let d = sub(*p, f.centre);
        let ang = d[1].atan2(d[0]) + std::f64::consts::PI;
        let b = ((ang / (std::f64::consts::TAU / SECTORS as f64)) as usize).min(SECTORS - 1);
        bins[b] = true;
    }
    bins.iter().filter(|&&b| b).count()
}

/// Fewest polygon sides of a rim fragment: two, a bend.
const FRAG_MIN_SIDES: usize = 2;

/// Fewest border points of a rim fragment. On the wild set's 3000 frames,
/// with 6 as the least, the pairs whose ellipse lay at a true rim had 8
/// points or more in their shorter fragment in 95% of cases; a shorter
/// one is more often a bend of clutter, and every fragment costs fits.
const FRAG_MIN_POINTS: usize = 8;

/// Fragments are paired when their middles lie within this many times the
/// longer one's chord: two pieces of a rim on opposite sides of a stick,
/// each a sixth of the rim, lie 3 chords apart.
const FRAG_REACH: f64 = 3.0;

/// Least number of the [`SECTORS`] a pair's points cover: half the rim,
/// where a single arc needs [`MIN_SECTORS`]; two pieces of clutter fit an
/// ellipse far more often than one curve does.
const FRAG_MIN_SECTORS: usize = 6;

/// Largest RMS (Sampson) distance of a pair's points from its ellipse
/// (working px), under the arcs' `max_rms` (1 px by default): the pairs
/// that were rims fitted at a median of 0.45 px, those of clutter at 0.67.
const FRAG_MAX_RMS: f64 = 0.8;

/// Shortest chord of either fragment of a pair, in semi-major axes of
/// their ellipse: each must be a real piece of the rim (a sixth of a
/// circle has a chord of one radius), not a bend of clutter beside it.
const FRAG_MIN_CHORD: f64 = 0.6;

/// Least border points of a pair together, in semi-major axes of their
/// ellipse: with [`FRAG_MIN_CHORD`], the pairs of clutter fell from 94 000
/// to 16 000 on the wild set's 3000 frames, and the rims' from 123 to 86
/// (`FRAG_MIN_SECTORS` and `FRAG_MAX_RMS` included); the rest are tested
/// against the image (`rim::stands_out`).
const FRAG_MIN_LENGTH: f64 = 1.8;

/// Pairs of rim fragments (`scratch.frags`) that fit one ellipse together,
/// added to `scratch.arcs` as arcs of that ellipse, which [`merge`] then
/// merges like any arcs of one rim (with the arcs of the same rim, if any,
/// and then the pair's ellipse is no longer `pieced`).
///
/// Longest fragment first, each is paired with the fragment within
/// [`FRAG_REACH`] that fits one ellipse with it best (least RMS), and each
/// fragment is in one pair at most. A pair needs a good fit
/// ([`FRAG_MAX_RMS`], the ellipse stage's axis limits) over enough of the
/// rim ([`FRAG_MIN_SECTORS`], [`FRAG_MIN_CHORD`], [`FRAG_MIN_LENGTH`]),
/// both fragments bending towards the ellipse's centre.
///
/// Every pair each fragment could make is fitted first, on `workers`'
/// threads if given (a fit does not depend on which fragments are taken;
/// at 4K the fits took most of the ellipse stage), then the pairs are
/// taken as above, longest fragment first, each with its best partner
/// still free.
///
/// Each pair is fitted once, as the fragment that comes first in that
/// order and then the other: a fragment's pairs with one before it are
/// never looked at, since that one, when its turn came with this one free,
/// took a partner. (Both ways, as each fragment's pairs were fitted
/// before, the ellipse stage spent half its fits on pairs never looked at:
/// 0.3-0.9 ms of a cluttered 1080p frame went to pairing, 1.5-2.7 ms of a
/// 4K frame's.)
fn group_fragments<W: Default + Send>(
    contours: &Contours,
    params: &EllipseParams,
    workers: Option<&Workers<W>>,
    scratch: &mut EllipseScratch,
) {
    /// A fragment's points (in `pts`, `range`), its middle point and its
    /// chord (first to last point) and chord length.
    struct Piece {
        range: std::ops::Range<usize>,
        mid: [f64; 2],
        chord: [f64; 2],
        length: f64,
    }
    let frags = std::mem::take(&mut scratch.frags);
    let mut pts: Vec<[f64; 2]> = Vec::new();
    let pieces: Vec<Piece> = frags
        .iter()
        .map(|f| {
            let r0 = pts.len();
            pts.extend(border_run(contours, f.contour, f.start, f.len));
            let chord = sub(pts[pts.len() - 1], pts[r0]);
            Piece {
                range: r0..pts.len(),
                mid: pts[r0 + f.len as usize / 2],
                chord,
                length: norm(chord),
            }
        })
        .collect();
    // By the middle's x, to look only at the fragments within reach.
    let mut by_x = ByX::default();
    by_x.fill(pieces.len(), |i| pieces[i].mid[0]);
    // No pair is farther apart than this (see FRAG_REACH).
    let window = FRAG_REACH * pieces.iter().map(|f| f.length).fold(0.0, f64::max);
    let min_points = (params.min_arc_points / ARC_SHARE) as u32;
    // The order the pairs are taken in, longest fragment first, and each
    // fragment's place in it.
    let mut order: Vec<usize> = (0..frags.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(frags[i].len));
    let mut place = vec![0usize; frags.len()];
    for (k, &i) in order.iter().enumerate() {
        place[i] = k;
    }
    // Every pair that fits: by fragment, each one's partners after it in
    // `order`, in x order.
    let mut fits: Vec<(u32, u32, Conic)> = Vec::new();
    let mut buf = std::mem::take(&mut scratch.pts);
    collect_ranges_with(
        workers,
        frags.len(),
        MIN_FRAGMENTS_PER_PIECE,
        &mut buf,
        &mut fits,
        |r, buf, fits| {
            for i in r {
                let fi = &pieces[i];
                for &j in by_x.within(fi.mid[0], window) {
                    let j = j as usize;
                    if place[j] <= place[i] || frags[i].len + frags[j].len < min_points {
                        continue;
                    }
                    let fj = &pieces[j];
                    let gap = sub(fj.mid, fi.mid);
                    let apart = norm(gap);
                    if apart > FRAG_REACH * fi.length.max(fj.length) {
                        continue;
                    }
                    // Both middles lie on the ellipse, so its major
                    // semi-axis is at least half their distance: the fit's
                    // own checks below, made on that bound first, spare
                    // fits that cannot pass.
                    let least_a = apart / 2.0;
                    let together = f64::from(frags[i].len + frags[j].len);
                    if fi.length.min(fj.length) < FRAG_MIN_CHORD * least_a
                        || together < FRAG_MIN_LENGTH * least_a
                    {
                        continue;
                    }
                    // Each bends towards the other (both face the rim's
                    // centre): the dark side, where a rim's border turns (a
                    // negative cross product, see `arcs_of`).
                    if !(cross(fi.chord, gap) < 0.0 && cross(fj.chord, [-gap[0], -gap[1]]) < 0.0) {
                        continue;
                    }
                    buf.clear();
                    buf.extend_from_slice(&pts[fi.range.clone()]);
                    buf.extend_from_slice(&pts[fj.range.clone()]);
                    let Some(fit) = fit_ellipse(buf) else {
                        continue;
                    };
                    let faces = |f: &Piece| cross(f.chord, sub(fit.centre, f.mid)) < 0.0;
                    if accept(&fit, params)
                        && fit.rms <= FRAG_MAX_RMS
                        && fi.length.min(fj.length) >= FRAG_MIN_CHORD * fit.a
                        && together >= FRAG_MIN_LENGTH * fit.a
                        && coverage(buf, &fit) >= FRAG_MIN_SECTORS
                        && faces(fi)
                        && faces(fj)
                    {
                        fits.push((i as u32, j as u32, fit));
                    }
                }
            }
        },
    );
    scratch.pts = buf;
    // Fragment `i`'s pairs: `fits` holds the pieces' pairs in order
    // (`collect_ranges_with`), so by ascending fragment.
    let pairs_of = |i: usize| {
        let i = i as u32;
        let lo = fits.partition_point(|f| f.0 < i);
        &fits[lo..lo + fits[lo..].partition_point(|f| f.0 == i)]
    };
    let mut used = vec![false; frags.len()];
    for &i in &order {
        if used[i] {
            continue;
        }
        let mut best: Option<(usize, Conic)> = None;
        for &(_, j, fit) in pairs_of(i) {
            let j = j as usize;
            if !used[j] && best.is_none_or(|(_, b)| fit.rms < b.rms) {
                best = Some((j, fit));
            }
        }
        if let Some((j, fit)) = best {
            for k in [i, j] {
                used[k] = true;
                scratch.arcs.push(Arc {
                    contour: frags[k].contour,
                    start: frags[k].start,
                    len: frags[k].len,
                    fit,
                    merged: false,
                    pieced: true,
                });
            }
        }
    }
    scratch.frags = frags;
}

/// The `len` points of border `contour` from point `start` on (indices
/// modulo the border's length): an arc's or a fragment's.
fn border_run(
    contours: &Contours,
    contour: u32,
    start: u32,
    len: u32,
) -> impl Iterator<Item = [f64; 2]> + '_ {
    let pts = contours.points_of(&contours.list[contour as usize]);
    let n = pts.len();
    (0..len as usize).map(move |k| fp(pts[(start as usize + k) % n]))
}

fn merge(
    contours: &Contours,
    params: &EllipseParams,
    scratch: &mut EllipseScratch,
    out: &mut Vec<Ellipse>,
) {
    let arcs = &mut scratch.arcs;
    arcs.sort_by_key(|a| std::cmp::Reverse(a.len));
    for i in 0..arcs.len() {
        if arcs[i].merged {
            continue;
        }
        let base = arcs[i].fit;
        let mut members = vec![i];
        for (j, arc) in arcs.iter().enumerate().skip(i + 1) {
            if arc.merged {
                continue;
            }
            let f = arc.fit;
            let tol = MERGE_CENTRE * base.a.max(f.a);
            if norm(sub(f.centre, base.centre)) < tol
                && (f.a - base.a).abs() < MERGE_MAJOR * base.a
                && (f.b - base.b).abs() < MERGE_MINOR * base.b.max(f.b)
            {
                members.push(j);
            }
        }
        let mut fit = base;
        // A pair's ellipse, unless merged with arcs of a rim found whole.
        let mut pieced = arcs[i].pieced;
        if members.len() > 1 {
            scratch.pts.clear();
            for &j in &members {
                let a = arcs[j];
                scratch
                    .pts
                    .extend(border_run(contours, a.contour, a.start, a.len));
            }
            if let Some(f) = fit_ellipse(&scratch.pts) {
                if accept(&f, params) {
                    fit = f;
                    pieced = members.iter().all(|&j| arcs[j].pieced);
                    for &j in &members {
                        arcs[j].merged = true;
                    }
                }
            }
        }
        arcs[i].merged = true;
        out.push(Ellipse {
            pieced,
            centre: fit.centre,
            a: fit.a,
            b: fit.b,
            anchor: fit.centre,
            checker: false,
            axis: fit.axis,
        });
    }
}

/// Direct least-squares ellipse fit (Fitzgibbon et al. 1999; Halir &
/// Flusser 1998 numerically stable formulation). Points are centred and
/// scaled first. `None` when the points do not define an ellipse.
fn fit_ellipse(pts: &[[f64; 2]]) -> Option<Conic> {
    let n = pts.len();
    if n < MIN_FIT_POINTS {
        return None;
    }
    let nf = n as f64;
    let (mut mx, mut my) = (0.0, 0.0);
    for p in pts {
        mx += p[0];
        my += p[1];
    }
    mx /= nf;
    my /= nf;
    let mut r2 = 0.0;
    for p in pts {
        r2 += (p[0] - mx).powi(2) + (p[1] - my).powi(2);
    }
    let r = (r2 / nf).sqrt();
    if r < MIN_SPREAD {
        return None;
    }
    let s = std::f64::consts::SQRT_2 / r;
    // Scatter matrices.
    let mut s1 = [[0.0f64; 3]; 3];
    let mut s2 = [[0.0f64; 3]; 3];
    let mut s3 = [[0.0f64; 3]; 3];
    for p in pts {
        let x = (p[0] - mx) * s;
        let y = (p[1] - my) * s;
        let d1 = [x * x, x * y, y * y];
        let d2 = [x, y, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                s1[i][j] += d1[i] * d1[j];
                s2[i][j] += d1[i] * d2[j];
                s3[i][j] += d2[i] * d2[j];
            }
        }
    }
    let m1 = nalgebra::Matrix3::from_fn(|i, j| s1[i][j]);
    let m2 = nalgebra::Matrix3::from_fn(|i, j| s2[i][j]);
    let m3 = nalgebra::Matrix3::from_fn(|i, j| s3[i][j]);
    let t = -(m3.try_inverse()? * m2.transpose());
    let m = m1 + m2 * t;
    // Premultiply by the inverse of the constraint matrix C1.
    let mm = nalgebra::Matrix3::from_fn(|i, j| match i {
        0 => m[(2, j)] / 2.0,
        1 => -m[(1, j)],
        _ => m[(0, j)] / 2.0,
    });
    let mut best: Option<nalgebra::Vector3<f64>> = None;
    for lam in cubic_real_roots(&mm) {
        let a = mm - nalgebra::Matrix3::identity() * lam;
        let r0 = a.row(0).transpose();
        let r1 = a.row(1).transpose();
        let r2 = a.row(2).transpose();
        let cands = [r0.cross(&r1), r0.cross(&r2), r1.cross(&r2)];
        let v = cands
            .iter()
            .max_by(|p, q| p.norm_squared().total_cmp(&q.norm_squared()))
            .copied()?;
        if v.norm_squared() < NULL_VECTOR {
            continue;
        }
        if 4.0 * v[0] * v[2] - v[1] * v[1] > 0.0 {
            best = Some(v);
        }
    }
    let a1 = best?;
    let a2 = t * a1;
    let (ca, cb, cc, cd, ce, cf) = (a1[0], a1[1], a1[2], a2[0], a2[1], a2[2]);
    // Centre.
    let det = 4.0 * ca * cc - cb * cb;
    if det.abs() < SINGULAR_CENTRE {
        return None;
    }
    let x0 = (cb * ce - 2.0 * cc * cd) / det;
    let y0 = (cb * cd - 2.0 * ca * ce) / det;
    let f0 = cf + 0.5 * (cd * x0 + ce * y0);
    // Eigenvalues of [[A, B/2], [B/2, C]].
    let tr = ca + cc;
    let disc = ((ca - cc).powi(2) + cb * cb).sqrt();
    let l1 = 0.5 * (tr + disc);
    let l2 = 0.5 * (tr - disc);
    let (q1, q2) = (-f0 / l1, -f0 / l2);
    if !(q1 > 0.0 && q2 > 0.0) {
        return None;
    }
    let (ax1, ax2) = (q1.sqrt(), q2.sqrt());
    let (a, b) = if ax1 > ax2 { (ax1, ax2) } else { (ax2, ax1) };
    // The major axis is the eigenvector of the form's smaller eigenvalue
    // (the direction the form grows slowest along); the scaling of the
    // points is isotropic, so it keeps directions.
    let lmajor = if ax1 > ax2 { l1 } else { l2 };
    let (u, v) = ([0.5 * cb, lmajor - ca], [lmajor - cc, 0.5 * cb]);
    let e = if norm(u) >= norm(v) { u } else { v };
    let axis = if norm(e) > 0.0 {
        [e[0] / norm(e), e[1] / norm(e)]
    } else {
        // A circle: every direction is an axis.
        [1.0, 0.0]
    };
    // Sampson distances.
    let mut ss = 0.0;
    for p in pts {
        let x = (p[0] - mx) * s;
        let y = (p[1] - my) * s;
        let q = ca * x * x + cb * x * y + cc * y * y + cd * x + ce * y + cf;
        let gx = 2.0 * ca * x + cb * y + cd;
        let gy = cb * x + 2.0 * cc * y + ce;
        let g2 = gx * gx + gy * gy;
        if g2 > NULL_VECTOR {
            ss += q * q / g2;
        }
    }
    let rms = (ss / nf).sqrt() / s;
    let out = Conic {
        centre: [x0 / s + mx, y0 / s + my],
        a: a / s,
        b: b / s,
        axis,
        rms,
    };
    (out.centre.iter().all(|v| v.is_finite()) && out.a.is_finite()).then_some(out)
}

/// Real eigenvalues of a 3 x 3 matrix, from its characteristic cubic.
fn cubic_real_roots(m: &nalgebra::Matrix3<f64>) -> Vec<f64> {
    // lambda^3 + a lambda^2 + b lambda + c = 0.
    let tr = m.trace();
    let minors = m[(0, 0)] * m[(1, 1)] - m[(0, 1)] * m[(1, 0)] + m[(0, 0)] * m[(2, 2)]
        - m[(0, 2)] * m[(2, 0)]
        + m[(1, 1)] * m[(2, 2)]
        - m[(1, 2)] * m[(2, 1)];
    let (a, b, c) = (-tr, minors, -m.determinant());
    // Depressed cubic t^3 + p t + q with lambda = t - a/3.
    let p = b - a * a / 3.0;
    let q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
    let shift = -a / 3.0;
    let disc = q * q / 4.0 + p * p * p / 27.0;
    if disc > 0.0 {
        let sq = disc.sqrt();
        let u = (-q / 2.0 + sq).cbrt();
        let v = (-q / 2.0 - sq).cbrt();
        vec![u + v + shift]
    } else if p.abs() < TRIPLE_ROOT {
        vec![shift]
    } else {
        let r = (-p / 3.0).sqrt();
        let phi = ((3.0 * q) / (2.0 * p * r)).clamp(-1.0, 1.0).acos() / 3.0;
        (0..3)
            .map(|k| 2.0 * r * (phi - std::f64::consts::TAU * k as f64 / 3.0).cos() + shift)
            .collect()
    }
}

/// Replaces each ellipse's anchor by the centroid of the centre checker's
/// white disc when a small, round hole border sits near the ellipse centre.
pub(crate) fn find_anchors(contours: &Contours, ellipses: &mut [Ellipse]) {
    if ellipses.is_empty() {
        return;
    }
    for c in contours
        .list
        .iter()
        .filter(|c| c.hole && c.len >= MIN_CHECKER_POINTS)
    {
        let pts = contours.points_of(c);
        // Cheap bounding box first.
        let (mut x0, mut y0, mut x1, mut y1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
        for p in pts {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            y0 = y0.min(p[1]);
            y1 = y1.max(p[1]);
        }
        let bc = [f64::from(x0 + x1) / 2.0, f64::from(y0 + y1) / 2.0];
        let size = f64::from((x1 - x0).max(y1 - y0)) + 1.0;
        for e in ellipses.iter_mut() {
            // The checker disc's diameter is about 0.2 S (ct14: 1/6 of the
            // data square, ct8: 2/15), the rim's 1.64 S.
            let rel = size / (2.0 * e.a);
            if !CHECKER_SIZE.contains(&rel) || norm(sub(bc, e.centre)) > CHECKER_OFFSET * e.a {
                continue;
            }
            // Area and centroid of the polygon through the border pixels
            // (Green's theorem); the border runs through black pixels around
            // the hole, so the polygon is half a pixel too big all round,
            // which leaves the centroid unbiased.
            let n = pts.len();
            let (mut a2, mut cx, mut cy) = (0.0, 0.0, 0.0);
            for i in 0..n {
                let (p, q) = (fp(pts[i]), fp(pts[(i + 1) % n]));
                let w = cross(p, q);
                a2 += w;
                cx += (p[0] + q[0]) * w;
                cy += (p[1] + q[1]) * w;
            }
            if a2.abs() < MIN_SPREAD {
                continue;
            }
            let centroid = [cx / (3.0 * a2), cy / (3.0 * a2)];
            // Roundness: area against the bounding box (a disc fills pi/4).
            let fill = (a2.abs() / 2.0) / (size * size);
            if !CHECKER_FILL.contains(&fill) {
                continue;
            }
            if norm(sub(centroid, e.centre)) < norm(sub(e.anchor, e.centre)) || e.anchor == e.centre
            {
                e.anchor = centroid;
                e.checker = true;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_partial_ellipse() {
        let (cx, cy, a, b, th) = (50.0, 40.0, 30.0, 12.0, 0.4f64);
        let pts: Vec<[f64; 2]> = (0..60)
            .map(|k| {
                let t = k as f64 / 60.0 * 4.0; // about 230 degrees
                let (x, y) = (a * t.cos(), b * t.sin());
                [
                    cx + x * th.cos() - y * th.sin(),
                    cy + x * th.sin() + y * th.cos(),
                ]
            })
            .collect();
        let f = fit_ellipse(&pts).unwrap();
        assert!((f.centre[0] - cx).abs() < 1e-6 && (f.centre[1] - cy).abs() < 1e-6);
        assert!((f.a - a).abs() < 1e-6 && (f.b - b).abs() < 1e-6);
        assert!(f.rms < 1e-6);
    }

    /// The ellipses found in a `w` x `h` binary image whose dark pixels
    /// are those `dark` says, through the detector's own border and
    /// polygon stages, with fragments paired or not.
    fn ellipses_of(
        w: usize,
        h: usize,
        dark: impl Fn(f64, f64) -> bool,
        pair_fragments: bool,
    ) -> Vec<Ellipse> {
        let (pw, ph) = (w + 2, h + 2);
        let mut f = vec![0u8; pw * ph];
        for y in 0..h {
            for x in 0..w {
                f[(y + 1) * pw + x + 1] = u8::from(dark(x as f64, y as f64));
            }
        }
        let mut contours = Contours::default();
        crate::detect::contours::find_contours(&mut f, pw, ph, 12, usize::MAX, &mut contours);
        let mut polys = Polygons::default();
        let lp = crate::detect::lines::LineParams {
            dp_epsilon: 1.5,
            min_length: 4.0,
        };
        crate::detect::lines::extract::<()>(&contours, &lp, None, &mut polys);
        let params = EllipseParams {
            min_minor: 4.0,
            min_arc_points: 24,
            max_rms: 1.0,
            pair_fragments,
        };
        let mut out = Vec::new();
        find_ellipses::<()>(
            &contours,
            &polys,
            &params,
            None,
            &mut EllipseScratch::default(),
            &mut out,
        );
        out
    }

    /// A disc cut into four by two light sticks: each piece of its rim is
    /// under a third of it, so no arc fits alone; paired, two pieces give
    /// the rim (its border points lie half a pixel inside it).
    #[test]
    fn a_rim_cut_into_pieces_is_found_from_pairs_of_them() {
        let (c, r, sticks, width) = ([40.0, 36.0], 14.0, [0.5f64, 2.1], 3.0);
        let dark = |x: f64, y: f64| {
            let (dx, dy) = (x - c[0], y - c[1]);
            dx.hypot(dy) <= r
                && sticks
                    .iter()
                    .all(|&a| (dx * -a.sin() + dy * a.cos()).abs() > width / 2.0)
        };
        assert!(ellipses_of(80, 72, dark, false).is_empty());
        let found = ellipses_of(80, 72, dark, true);
        assert_eq!(found.len(), 1, "{found:?}");
        let e = found[0];
        assert!(e.pieced);
        assert!(norm(sub(e.centre, c)) < 0.1, "{e:?}");
        assert!(
            (e.a - (r - 0.5)).abs() < 0.2 && (e.b - (r - 0.5)).abs() < 0.2,
            "{e:?}"
        );
    }

    /// Three discs cut by sticks, close enough that pieces of two rims lie
    /// within each other's reach: each rim is found once, from pieces of
    /// its own (every pair is fitted once, in the order pairs are taken).
    #[test]
    fn rims_cut_into_pieces_side_by_side_are_each_found_from_their_own() {
        let discs = [
            ([40.0, 36.0], 14.0),
            ([76.0, 40.0], 12.0),
            ([56.0, 72.0], 13.0),
        ];
        let sticks = [0.5f64, 2.1];
        let dark = |x: f64, y: f64| {
            discs.iter().any(|&(c, r): &([f64; 2], f64)| {
                let (dx, dy) = (x - c[0], y - c[1]);
                dx.hypot(dy) <= r
                    && sticks
                        .iter()
                        .all(|&a| (dx * -a.sin() + dy * a.cos()).abs() > 1.5)
            })
        };
        assert!(ellipses_of(112, 96, dark, false).is_empty());
        let found = ellipses_of(112, 96, dark, true);
        assert_eq!(found.len(), discs.len(), "{found:?}");
        for (c, r) in discs {
            let e = found
                .iter()
                .find(|e| norm(sub(e.centre, c)) < 0.2)
                .unwrap_or_else(|| panic!("no rim at {c:?}: {found:?}"));
            assert!(e.pieced && (e.a - (r - 0.5)).abs() < 0.3, "{e:?}");
        }
    }

    #[test]
    fn a_sharp_turn_ends_an_arc() {
        let d = f64::to_radians;
        // A rim (turns of 15 degrees) running into an occluder's edge (60)
        // and on round to a square corner (-90, already bad).
        let split = |turns: Vec<f64>| {
            let mut jn = Junctions {
                ok: turns.iter().map(|&t| t > 0.0 && t < d(80.0)).collect(),
                turns,
                ..Junctions::default()
            };
            split_at_outliers(&mut jn);
            jn.ok
        };
        let mut turns = vec![d(15.0); 12];
        turns[8] = d(60.0);
        turns[11] = d(-90.0);
        let ok = split(turns);
        let bad: Vec<usize> = (0..12).filter(|&k| !ok[k]).collect();
        assert_eq!(bad, vec![8, 11]);
        // Even turns (a small ellipse: few sides, large turns) stay whole.
        let ok = split(vec![d(50.0), d(55.0), d(45.0), d(-90.0), d(52.0)]);
        assert_eq!(ok, vec![true, true, true, false, true]);
    }
}

//! Stage 3c: bridges between the pieces of one straight edge cut by an
//! occluder.
//!
//! A stick or a cable across a tag cuts the black frame's sides: the border
//! of the white data square splits into pieces on different borders (a
//! dark stick cuts the square apart, a light one cuts the frame in two), so
//! no border holds all four corners and no quad closes. Two line pieces
//! continue one another when they run the same way, dark on the same side,
//! along one straight line, with a gap between their facing ends. Such
//! pieces are joined into chains, and the borders they come from into
//! linked components, by union-find (Tarjan, "Efficiency of a good but not
//! linear set union algorithm", 1975). The quad search then looks for
//! quads across the borders of each linked component whose cross-border
//! sides run along one chain (see `quads`).
//!
//! Where the stick passes close to a corner, the piece of the side next to
//! the corner is shorter than tau and no line, so no corner forms there.
//! A gap corner is then where the side's line across the gap meets the
//! other side's line (see [`gap_corner`]); gap corners are looked for only
//! around linked borders, and only the linked quad search uses them.
//!
//! Pairs are found without comparing every two lines: lines are sorted by
//! the x of their start and of their end point, and each line looks only
//! at the lines whose facing end lies within its reach in x. Each pair is
//! seen once, from its longer line.

use super::corners::{Corner, CornerParams, REACH_PER_GAP};
use super::lines::{Line, Polygons};
use super::parallel::{collect_ranges, join, Workers};
use crate::math::{cross, dot, intersect, norm, sub};

/// Two pieces of one edge turn by at most this (degrees): the fit of a
/// short piece wanders by a few degrees, a different edge turns by more.
const BRIDGE_MAX_TURN_DEG: f64 = 8.0;

/// The gap between two pieces is at most this many times the longer
/// piece: a stick across a side leaves at least one piece of the side
/// longer than about half of the gap it cuts (sticks cross at steep
/// angles, or they would cover a corner), while the gaps between the
/// cells of one row are as long as the cells themselves.
const GAP_PER_LENGTH: f64 = 0.75;

/// Both lines of a gap corner are at least this share of the longest line
/// of the linked components they come from. A frame side cut by a stick
/// keeps a piece of at least about a quarter of the data square's side
/// (the stick leaves its corners clear), and the longest line of the
/// component is at most the paper's side, about twice the square's; the
/// edges of a large tag's cells, whose borders bridge each other along
/// rows, are mostly shorter than four cells (a ct14 grid has 14 a side)
/// and would otherwise make gap corners with one another everywhere.
const GAP_CORNER_MIN_SHARE: f64 = 0.125;

/// Each facing end lies within this distance (px) of the other piece's
/// line, ...
const BRIDGE_TOL: f64 = 1.5;
/// ... plus this much per pixel of gap (a line fitted to a short piece
/// wanders farther from the edge the farther it is extended).
const BRIDGE_TOL_SLOPE: f64 = 0.05;

/// The facing ends may overlap by this much (px) along the edge: the ends
/// of a line are its border's points projected on it, and the rounded
/// corners of an occluder's edge leave them a pixel short or long.
const BRIDGE_OVERLAP: f64 = 1.0;

/// Chains of bridged line pieces and linked components of borders.
#[derive(Debug, Default)]
pub(crate) struct Links {
    /// Per line: union-find parent (chains of bridged pieces).
    line_parent: Vec<u32>,
    /// Per border: union-find parent (linked components).
    border_parent: Vec<u32>,
    /// Per border: whether a bridge joins it to another border.
    bridged: Vec<bool>,
    /// Line indices sorted by the x of their start point.
    by_start: Vec<u32>,
    /// Line indices sorted by the x of their end point.
    by_end: Vec<u32>,
    /// Per line: its border.
    border_of: Vec<u32>,
    /// Line pairs bridged.
    pairs: Vec<(u32, u32)>,
    /// Gap corners found: incoming line, outgoing line, position.
    gaps: Vec<(u32, u32, [f64; 2])>,
    /// Per linked component (at its root border): its longest line.
    longest: Vec<f64>,
}

impl Links {
    /// The chain of line `l`: two lines with the same chain are pieces of
    /// one edge.
    pub(crate) fn chain(&self, l: u32) -> u32 {
        find(&self.line_parent, l)
    }

    /// The linked component of border `c`.
    pub(crate) fn component(&self, c: u32) -> u32 {
        find(&self.border_parent, c)
    }

    /// Whether border `c` is linked to another border by a bridge.
    pub(crate) fn is_bridged(&self, c: u32) -> bool {
        self.bridged[c as usize]
    }

    /// Whether any two borders were linked in this frame.
    pub(crate) fn any(&self) -> bool {
        self.bridged.iter().any(|&b| b)
    }
}

/// Root of `i`. No path compression, so that lookups need no `&mut`: the
/// chains and components of one frame hold a handful of lines or borders.
fn find(parent: &[u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        i = parent[i as usize];
    }
    i
}

fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (lo, hi) = (ra.min(rb), ra.max(rb));
    parent[hi as usize] = lo;
}

fn length(l: &Line) -> f64 {
    norm(sub(l.pe, l.ps))
}

/// Whether `b` continues `a` (in that order) across a gap: same direction
/// within [`BRIDGE_MAX_TURN_DEG`], `b` starting ahead of `a`'s end by at
/// most [`GAP_PER_LENGTH`] times the longer piece, each facing end near
/// the other's line.
fn continues(a: &Line, b: &Line) -> bool {
    if !same_way(a, b) {
        return false;
    }
    let g = sub(b.ps, a.pe);
    let gap = norm(g);
    if dot(g, a.dir) < -BRIDGE_OVERLAP || gap > GAP_PER_LENGTH * length(a).max(length(b)) {
        return false;
    }
    let tol = BRIDGE_TOL + BRIDGE_TOL_SLOPE * gap;
    cross(a.dir, g).abs() <= tol && cross(b.dir, g).abs() <= tol
}

/// Whether two lines run the same way within [`BRIDGE_MAX_TURN_DEG`].
fn same_way(a: &Line, b: &Line) -> bool {
    dot(a.dir, b.dir) >= BRIDGE_MAX_TURN_DEG.to_radians().cos()
}

/// The longer of two lines sees their pair (ties: the lower index).
fn sees(lines: &[Line], a: usize, b: usize) -> bool {
    let (la, lb) = (length(&lines[a]), length(&lines[b]));
    la > lb || (la == lb && a < b)
}

/// Lines `order` (sorted by `key`) whose key lies within `r` of `x`.
fn window<'a>(
    lines: &[Line],
    order: &'a [u32],
    key: fn(&Line) -> f64,
    x: f64,
    r: f64,
) -> &'a [u32] {
    let lo = order.partition_point(|&i| key(&lines[i as usize]) < x - r);
    let hi = order.partition_point(|&i| key(&lines[i as usize]) <= x + r);
    &order[lo..hi]
}

/// Whether `q` lies within `r` of `p` in y (the window already holds x).
/// Calls `visit(y, from, to)` for every line `y` whose end faces an end of
/// line `x` within `r` and which `x` sees ([`sees`]): first the lines
/// starting near `x`'s end (`from` = `x`, `to` = `y`), then those ending
/// near its start (`from` = `y`, `to` = `x`), each in the order of
/// `by_start` or `by_end`. The one neighbour search of the bridges and the
/// gap corners.
fn facing(
    lines: &[Line],
    by_start: &[u32],
    by_end: &[u32],
    x: usize,
    r: f64,
    mut visit: impl FnMut(usize, usize, usize),
) {
    let lx = &lines[x];
    for &y in window(lines, by_start, |l| l.ps[0], lx.pe[0], r) {
        let y = y as usize;
        if within(lines[y].ps, lx.pe, r) && y != x && sees(lines, x, y) {
            visit(y, x, y);
        }
    }
    for &y in window(lines, by_end, |l| l.pe[0], lx.ps[0], r) {
        let y = y as usize;
        if within(lines[y].pe, lx.ps, r) && y != x && sees(lines, x, y) {
            visit(y, y, x);
        }
    }
}

fn within(q: [f64; 2], p: [f64; 2], r: f64) -> bool {
    (q[1] - p[1]).abs() <= r
}

/// Fewest lines in one piece of the parallel neighbour searches of
/// [`find_bridges`] and [`add_gap_corners`].
const MIN_LINES_PER_PIECE: usize = 256;

/// Finds the bridges between the lines of `polys` and fills `out`; the
/// neighbour search on `workers`' threads if given (in runs of lines, the
/// same pairs in the same order either way).
pub(crate) fn find_bridges<W: Default + Send>(
    polys: &Polygons,
    workers: Option<&Workers<W>>,
    out: &mut Links,
) {
    let lines = &polys.lines;
    let n = lines.len();
    out.border_of.clear();
    out.border_of.resize(n, 0);
    for (c, &(l0, l1)) in polys.line_ranges.iter().enumerate() {
        out.border_of[l0 as usize..l1 as usize].fill(c as u32);
    }
    out.line_parent.clear();
    out.line_parent.extend(0..n as u32);
    out.border_parent.clear();
    out.border_parent.extend(0..polys.line_ranges.len() as u32);
    out.bridged.clear();
    out.bridged.resize(polys.line_ranges.len(), false);
    let sort = |order: &mut Vec<u32>, key: fn(&Line) -> f64| {
        order.clear();
        order.extend(0..n as u32);
        order.sort_by(|&i, &j| key(&lines[i as usize]).total_cmp(&key(&lines[j as usize])));
    };
    join(
        workers,
        || sort(&mut out.by_start, |l| l.ps[0]),
        || sort(&mut out.by_end, |l| l.pe[0]),
    );
    let mut pairs = std::mem::take(&mut out.pairs);
    pairs.clear();
    let (by_start, by_end) = (&out.by_start, &out.by_end);
    collect_ranges(workers, n, MIN_LINES_PER_PIECE, &mut pairs, |r, pairs| {
        for a in r {
            let la = &lines[a];
            let r = GAP_PER_LENGTH * length(la) + BRIDGE_OVERLAP;
            facing(lines, by_start, by_end, a, r, |b, from, to| {
                if same_way(la, &lines[b]) && continues(&lines[from], &lines[to]) {
                    pairs.push((from as u32, to as u32));
                }
            });
        }
    });
    for &(a, b) in &pairs {
        union(&mut out.line_parent, a, b);
        let (ca, cb) = (out.border_of[a as usize], out.border_of[b as usize]);
        if ca != cb {
            union(&mut out.border_parent, ca, cb);
            out.bridged[ca as usize] = true;
            out.bridged[cb as usize] = true;
        }
    }
    out.pairs = pairs;
}

/// Where the incoming line `a` and the outgoing line `b` would meet in a
/// corner (as in `corners`: anticlockwise, at more than theta) while one
/// of them stops short of the meeting point by a gap: an occluder cut the
/// piece of that side next to the corner, too short to be a line. One
/// line reaches the point within the corner reach, the other stops short
/// by at most [`GAP_PER_LENGTH`] times the longer line. With `apart` (the
/// lines are not consecutive on one border, so `corners` never paired
/// them) both may reach it: a corner across borders.
fn gap_corner(a: &Line, b: &Line, apart: bool, p: &CornerParams) -> Option<[f64; 2]> {
    let s = cross(a.dir, b.dir);
    if s > -p.sin_min_angle {
        return None;
    }
    let x = intersect(a.pe, a.dir, b.ps, b.dir)?;
    let reach = REACH_PER_GAP * p.max_gap;
    let gap = GAP_PER_LENGTH * length(a).max(length(b));
    // How far `a` stops before the point, and `b` starts after it.
    let (ea, eb) = (dot(sub(x, a.pe), a.dir), dot(sub(b.ps, x), b.dir));
    let near = |e: f64| e.abs() <= reach;
    let far = |e: f64| e > reach && e <= gap;
    let ok = (near(ea) && far(eb)) || (far(ea) && near(eb)) || (apart && near(ea) && near(eb));
    ok.then_some(x)
}

/// Whether line `b` follows line `a` on border `c` (cyclically): the pair
/// `corners` already tried.
fn consecutive(polys: &Polygons, c: u32, a: u32, b: u32) -> bool {
    let (l0, l1) = polys.line_ranges[c as usize];
    b == a + 1 || (a + 1 == l1 && b == l0)
}

/// Gap corners (see [`gap_corner`]) between lines of which at least one
/// lies on a border already linked by a bridge, appended to `corners` as
/// corners of the incoming line's border. Each joins the two lines'
/// borders into one linked component, so that the quad search across
/// linked borders sees it. Gap corners are looked for only next to
/// bridged borders: elsewhere, every cell edge of a large tag would make
/// them with the cells around it. The neighbour search runs on `workers`'
/// threads if given (the same corners either way).
pub(crate) fn add_gap_corners<W: Default + Send>(
    polys: &Polygons,
    p: &CornerParams,
    workers: Option<&Workers<W>>,
    links: &mut Links,
    corners: &mut Vec<Corner>,
) {
    if !links.any() {
        return;
    }
    let lines = &polys.lines;
    let reach = REACH_PER_GAP * p.max_gap;
    let mut gaps = std::mem::take(&mut links.gaps);
    gaps.clear();
    // The longest line of each component, at its root.
    links.longest.clear();
    links.longest.resize(links.bridged.len(), 0.0);
    for (l, line) in lines.iter().enumerate() {
        let root = find(&links.border_parent, links.border_of[l]) as usize;
        links.longest[root] = links.longest[root].max(length(line));
    }
    let near_bridged = |a: usize, b: usize| {
        links.bridged[links.border_of[a] as usize] || links.bridged[links.border_of[b] as usize]
    };
    // Both lines long against their components' longest line.
    let long_enough = |a: usize, b: usize| {
        let longest =
            [a, b].map(|l| links.longest[find(&links.border_parent, links.border_of[l]) as usize]);
        length(&lines[a]).min(length(&lines[b]))
            >= GAP_CORNER_MIN_SHARE * longest[0].max(longest[1])
    };
    // A line shorter than that share of its own component's longest line
    // cannot be in a gap corner: skip it before looking for partners.
    let eligible = |l: usize| {
        let root = find(&links.border_parent, links.border_of[l]) as usize;
        length(&lines[l]) >= GAP_CORNER_MIN_SHARE * links.longest[root]
    };
    // Where the pair's lines meet, if they make a gap corner.
    let meeting = |a: usize, b: usize| {
        let (ca, cb) = (links.border_of[a], links.border_of[b]);
        let apart = ca != cb || !consecutive(polys, ca, a as u32, b as u32);
        gap_corner(&lines[a], &lines[b], apart, p)
    };
    let n = lines.len();
    collect_ranges(workers, n, MIN_LINES_PER_PIECE, &mut gaps, |r, gaps| {
        for x in r.filter(|&x| eligible(x)) {
            let r = GAP_PER_LENGTH * length(&lines[x]) + reach;
            facing(
                lines,
                &links.by_start,
                &links.by_end,
                x,
                r,
                |y, from, to| {
                    if near_bridged(x, y) && eligible(y) && long_enough(from, to) {
                        if let Some(pos) = meeting(from, to) {
                            gaps.push((from as u32, to as u32, pos));
                        }
                    }
                },
            );
        }
    });
    // The borders are joined in the pairs' order, after every pair was
    // judged on the components as they were before.
    for &(a, b, pos) in &gaps {
        let (la, lb) = (&lines[a as usize], &lines[b as usize]);
        let (ca, cb) = (links.border_of[a as usize], links.border_of[b as usize]);
        union(&mut links.border_parent, ca, cb);
        links.bridged[ca as usize] = true;
        links.bridged[cb as usize] = true;
        corners.push(Corner {
            pos,
            din: la.dir,
            dout: lb.dir,
            seg_in: [la.ps, la.pe],
            seg_out: [lb.ps, lb.pe],
            contour: ca,
            lines: [a, b],
            gap: true,
        });
    }
    links.gaps = gaps;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(ps: [f64; 2], pe: [f64; 2]) -> Line {
        let d = sub(pe, ps);
        let l = norm(d);
        Line {
            ps,
            pe,
            dir: [d[0] / l, d[1] / l],
        }
    }

    #[test]
    fn pieces_of_one_edge_continue_across_a_gap() {
        let a = line([0.0, 0.0], [40.0, 0.0]);
        // 10 px gap, slightly off and turned: one edge.
        assert!(continues(&a, &line([50.0, 0.5], [90.0, 1.0])));
        // The wrong order, a turn, an offset, a gap too long: not.
        assert!(!continues(&line([50.0, 0.0], [90.0, 0.0]), &a));
        assert!(!continues(&a, &line([50.0, 0.0], [90.0, 20.0])));
        assert!(!continues(&a, &line([50.0, 5.0], [90.0, 5.0])));
        assert!(!continues(&a, &line([80.0, 0.0], [100.0, 0.0])));
    }

    #[test]
    fn a_corner_forms_across_a_cut_next_to_it() {
        let p = CornerParams {
            sin_min_angle: 22.5f64.to_radians().sin(),
            max_gap: 7.0,
        };
        // The right side up to (60, 20); the top side's piece starts 20 px
        // on, past a stick that hid the piece next to the corner.
        let right = line([60.0, 60.0], [60.0, 20.0]);
        let top = line([40.0, 20.0], [0.0, 20.0]);
        let x = gap_corner(&right, &top, false, &p).expect("gap corner");
        assert!(norm(sub(x, [60.0, 20.0])) < 1e-9, "{x:?}");
        // Clockwise (a reflex corner of the white square): none.
        let turned = line([80.0, 20.0], [120.0, 20.0]);
        assert!(gap_corner(&right, &turned, false, &p).is_none());
        // Both ends at the point: a plain corner, left to `corners` unless
        // the lines are apart.
        let near = line([60.0, 20.0], [20.0, 20.0]);
        assert!(gap_corner(&right, &near, false, &p).is_none());
        assert!(gap_corner(&right, &near, true, &p).is_some());
    }

    #[test]
    fn bridged_pieces_link_their_borders() {
        let mut polys = Polygons::default();
        polys.lines = vec![
            line([0.0, 0.0], [40.0, 0.0]),
            line([40.0, 0.0], [40.0, 30.0]),
            line([50.0, 0.0], [90.0, 0.0]),
            line([0.0, 60.0], [20.0, 60.0]),
        ];
        polys.line_ranges = vec![(0, 2), (2, 3), (3, 4)];
        let mut links = Links::default();
        find_bridges(&polys, None::<&Workers<()>>, &mut links);
        assert_eq!(links.chain(0), links.chain(2));
        assert_ne!(links.chain(0), links.chain(1));
        assert_eq!(links.component(0), links.component(1));
        assert!(links.is_bridged(0) && links.is_bridged(1) && !links.is_bridged(2));
        assert_ne!(links.component(2), links.component(0));
    }
}

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
//! Pairs are found without comparing every two lines: the start and the
//! end points of the lines are bucketed in square cells ([`EndGrid`]), and
//! each line looks only at the lines whose facing end lies within its
//! reach. Each pair is seen once, from its longer line.

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
    /// The lines' start points in cells.
    start_grid: EndGrid,
    /// The lines' end points in cells.
    end_grid: EndGrid,
    /// Per line: its border.
    border_of: Vec<u32>,
    /// Per line: its length (px).
    lengths: Vec<f64>,
    /// Per line: the longest line of its linked component (gap corners).
    line_longest: Vec<f64>,
    /// Line pairs bridged.
    pairs: Vec<(u32, u32)>,
    /// Gap corners found, in the order they are added ([`GapFound`]).
    gaps: Vec<GapFound>,
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

/// The longer of two lines (of `lengths`) sees their pair (ties: the
/// lower index).
fn sees(lengths: &[f64], a: usize, b: usize) -> bool {
    let (la, lb) = (lengths[a], lengths[b]);
    la > lb || (la == lb && a < b)
}

/// Side (px) of the cells of an [`EndGrid`]: about the reach of a short
/// line (a line of tau = 8 px reaches 7 px), so that a short line looks at
/// a few cells and a long one at the cells of its own reach.
const END_CELL_PX: f64 = 16.0;

/// Margin (px) an [`EndGrid`] search adds to its reach: far above the
/// rounding of image coordinates, far below a pixel.
const END_MARGIN_PX: f64 = 1e-6;

/// Most cells an [`EndGrid`] has along one axis; past that its cells grow
/// (only absurd coordinates get there: a 4K working image has 240).
const END_MAX_CELLS: f64 = 1024.0;

/// The start or the end points of the lines, bucketed in square cells,
/// so that the points near a point are found without scanning the frame
/// (a cluttered 1080p frame has about a thousand lines). Written here, not
/// taken from a spatial-index crate: a counting sort into cells is a few
/// lines, and the search needs no more.
#[derive(Debug, Default)]
struct EndGrid {
    /// Corner of cell (0, 0), px.
    origin: [f64; 2],
    /// Side of a cell, px.
    cell: f64,
    cols: usize,
    rows: usize,
    /// Per cell, row by row: where its run of `lines` starts (one entry
    /// more than cells).
    first: Vec<u32>,
    /// The lines whose point lies in each cell, cell by cell.
    lines: Vec<u32>,
    /// Scratch of the counting sort: the next free place of each cell.
    next: Vec<u32>,
}

impl EndGrid {
    /// Fills the grid with `point` of every line. Points that are not
    /// finite are left out (no reach holds them).
    fn fill(&mut self, lines: &[Line], point: fn(&Line) -> [f64; 2]) {
        let finite = |q: [f64; 2]| q[0].is_finite() && q[1].is_finite();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for q in lines.iter().map(point).filter(|&q| finite(q)) {
            for k in 0..2 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
            }
        }
        self.first.clear();
        self.lines.clear();
        if lo[0] > hi[0] {
            (self.cols, self.rows) = (0, 0);
            return;
        }
        self.origin = lo;
        self.cell = END_CELL_PX.max((hi[0] - lo[0]).max(hi[1] - lo[1]) / END_MAX_CELLS);
        self.cols = ((hi[0] - lo[0]) / self.cell) as usize + 1;
        self.rows = ((hi[1] - lo[1]) / self.cell) as usize + 1;
        let (origin, cell, cols, rows) = (self.origin, self.cell, self.cols, self.rows);
        let cell_of = |q: [f64; 2]| {
            let at = |k: usize, n: usize| (((q[k] - origin[k]) / cell) as usize).min(n - 1);
            at(1, rows) * cols + at(0, cols)
        };
        self.first.resize(cols * rows + 1, 0);
        for q in lines.iter().map(point).filter(|&q| finite(q)) {
            self.first[cell_of(q) + 1] += 1;
        }
        for c in 1..self.first.len() {
            self.first[c] += self.first[c - 1];
        }
        self.next.clear();
        self.next.extend_from_slice(&self.first);
        self.lines.resize(self.first[cols * rows] as usize, 0);
        for (l, line) in lines.iter().enumerate() {
            let q = point(line);
            if finite(q) {
                let c = cell_of(q);
                self.lines[self.next[c] as usize] = l as u32;
                self.next[c] += 1;
            }
        }
    }

    /// The cells `lo..=hi` along an axis of `n` cells starting at
    /// `origin` that can hold coordinates from `from` to `to`, if any.
    fn span(&self, from: f64, to: f64, origin: f64, n: usize) -> Option<(usize, usize)> {
        let (a, b) = ((from - origin) / self.cell, (to - origin) / self.cell);
        // Also false for NaN.
        if !(b >= 0.0 && a < n as f64) {
            return None;
        }
        Some((a.max(0.0) as usize, (b as usize).min(n - 1)))
    }

    /// Calls `visit` with every line whose point can lie within `r` of `p`
    /// in x and in y (a superset: the caller checks), in no useful order.
    fn near(&self, p: [f64; 2], r: f64, mut visit: impl FnMut(usize)) {
        // A hair wider than `r`, so that rounding at the bounds cannot
        // leave out a point the caller's check would keep.
        let r = r + END_MARGIN_PX;
        let Some((x0, x1)) = self.span(p[0] - r, p[0] + r, self.origin[0], self.cols) else {
            return;
        };
        let Some((y0, y1)) = self.span(p[1] - r, p[1] + r, self.origin[1], self.rows) else {
            return;
        };
        for row in y0..=y1 {
            let (c0, c1) = (row * self.cols + x0, row * self.cols + x1);
            for &l in &self.lines[self.first[c0] as usize..self.first[c1 + 1] as usize] {
                visit(l as usize);
            }
        }
    }
}

/// Whether `q` lies within `r` of `p` in x and in y (in x from `p - r`
/// to `p + r` as computed, as a band of a list sorted by x was cut when
/// the search took such bands: the corners found did not change).
fn within(q: [f64; 2], p: [f64; 2], r: f64) -> bool {
    q[0] >= p[0] - r && q[0] <= p[0] + r && (q[1] - p[1]).abs() <= r
}

/// Which end of a line `y` faced line `x` in [`facing`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Facing {
    /// `y` starts near `x`'s end: `x` then `y`.
    Ahead,
    /// `y` ends near `x`'s start: `y` then `x`.
    Behind,
}

/// Calls `visit(y, from, to, side)` for every line `y` whose end faces an
/// end of line `x` within `r` (in x and in y) and which `x` sees
/// ([`sees`]): the lines starting near `x`'s end (`from` = `x`, `to` =
/// `y`, [`Facing::Ahead`]) and those ending near its start (`from` = `y`,
/// `to` = `x`, [`Facing::Behind`]), in no useful order. The one neighbour
/// search of the bridges and the gap corners.
fn facing(
    lines: &[Line],
    links: &Links,
    x: usize,
    r: f64,
    mut visit: impl FnMut(usize, usize, usize, Facing),
) {
    let lx = &lines[x];
    links.start_grid.near(lx.pe, r, |y| {
        if within(lines[y].ps, lx.pe, r) && y != x && sees(&links.lengths, x, y) {
            visit(y, x, y, Facing::Ahead);
        }
    });
    links.end_grid.near(lx.ps, r, |y| {
        if within(lines[y].pe, lx.ps, r) && y != x && sees(&links.lengths, x, y) {
            visit(y, y, x, Facing::Behind);
        }
    });
}

/// A gap corner found between line `x` and a line `y` facing it.
#[derive(Debug)]
struct GapFound {
    x: u32,
    side: Facing,
    /// The x of `y`'s facing end.
    key: f64,
    y: u32,
    /// Where they meet.
    pos: [f64; 2],
}

impl GapFound {
    /// The incoming and the outgoing line.
    fn lines(&self) -> [u32; 2] {
        match self.side {
            Facing::Ahead => [self.x, self.y],
            Facing::Behind => [self.y, self.x],
        }
    }

    /// The order gap corners are added in, the same on any thread count:
    /// by line `x`, lines ahead of it before lines behind, then by the x
    /// of the facing end (ties by line), as a search along the lines
    /// sorted by x would meet them. The quad search takes corners in
    /// their order.
    fn order(a: &Self, b: &Self) -> std::cmp::Ordering {
        (a.x, a.side)
            .cmp(&(b.x, b.side))
            .then(a.key.total_cmp(&b.key))
            .then(a.y.cmp(&b.y))
    }
}

/// Fewest lines in one piece of the parallel neighbour searches of
/// [`find_bridges`] and [`add_gap_corners`].
const MIN_LINES_PER_PIECE: usize = 256;

/// Finds the bridges between the lines of `polys` and fills `out`; the
/// neighbour search on `workers`' threads if given (in runs of lines; the
/// chains and components do not depend on the order the pairs are found
/// in, [`union`] keeps the lowest index as root).
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
    out.lengths.clear();
    out.lengths.extend(lines.iter().map(length));
    out.line_parent.clear();
    out.line_parent.extend(0..n as u32);
    out.border_parent.clear();
    out.border_parent.extend(0..polys.line_ranges.len() as u32);
    out.bridged.clear();
    out.bridged.resize(polys.line_ranges.len(), false);
    join(
        workers,
        || out.start_grid.fill(lines, |l| l.ps),
        || out.end_grid.fill(lines, |l| l.pe),
    );
    let mut pairs = std::mem::take(&mut out.pairs);
    pairs.clear();
    let links = &*out;
    collect_ranges(workers, n, MIN_LINES_PER_PIECE, &mut pairs, |r, pairs| {
        for a in r {
            let la = &lines[a];
            let r = GAP_PER_LENGTH * links.lengths[a] + BRIDGE_OVERLAP;
            facing(lines, links, a, r, |b, from, to, _| {
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
    for (l, &len) in links.lengths.iter().enumerate() {
        let root = find(&links.border_parent, links.border_of[l]) as usize;
        links.longest[root] = links.longest[root].max(len);
    }
    let near_bridged = |a: usize, b: usize| {
        links.bridged[links.border_of[a] as usize] || links.bridged[links.border_of[b] as usize]
    };
    // Per line, the longest line of its component.
    links.line_longest.clear();
    for l in 0..links.lengths.len() {
        let root = find(&links.border_parent, links.border_of[l]) as usize;
        links.line_longest.push(links.longest[root]);
    }
    let share = |l: usize| GAP_CORNER_MIN_SHARE * links.line_longest[l];
    // Both lines long against their components' longest line.
    let long_enough =
        |a: usize, b: usize| links.lengths[a].min(links.lengths[b]) >= share(a).max(share(b));
    // A line shorter than that share of its own component's longest line
    // cannot be in a gap corner: skip it before looking for partners.
    let eligible = |l: usize| links.lengths[l] >= share(l);
    // Where the pair's lines meet, if they make a gap corner.
    let meeting = |a: usize, b: usize| {
        let (ca, cb) = (links.border_of[a], links.border_of[b]);
        let apart = ca != cb || !consecutive(polys, ca, a as u32, b as u32);
        gap_corner(&lines[a], &lines[b], apart, p)
    };
    let n = lines.len();
    let all = &*links;
    collect_ranges(workers, n, MIN_LINES_PER_PIECE, &mut gaps, |r, gaps| {
        for x in r.filter(|&x| eligible(x)) {
            let r = GAP_PER_LENGTH * links.lengths[x] + reach;
            facing(lines, all, x, r, |y, from, to, side| {
                if near_bridged(x, y) && eligible(y) && long_enough(from, to) {
                    if let Some(pos) = meeting(from, to) {
                        let l = &lines[y];
                        gaps.push(GapFound {
                            x: x as u32,
                            side,
                            key: if side == Facing::Ahead {
                                l.ps[0]
                            } else {
                                l.pe[0]
                            },
                            y: y as u32,
                            pos,
                        });
                    }
                }
            });
        }
    });
    gaps.sort_by(GapFound::order);
    // The borders are joined in that order, after every pair was judged
    // on the components as they were before.
    for g in &gaps {
        let ([a, b], pos) = (g.lines(), g.pos);
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

    /// `lines` on borders `ranges` (first and past-last line of each),
    /// and their bridges (one thread).
    fn bridged(lines: Vec<Line>, ranges: Vec<(u32, u32)>) -> (Polygons, Links) {
        let mut polys = Polygons::default();
        polys.lines = lines;
        polys.line_ranges = ranges;
        let mut links = Links::default();
        find_bridges(&polys, None::<&Workers<()>>, &mut links);
        (polys, links)
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

    proptest::proptest! {
        /// The grid of line ends finds exactly the facing ends a scan of
        /// every pair finds, lines short and long, packed or spread out,
        /// ends on the grid's cell bounds included (whole coordinates).
        #[test]
        fn the_grid_finds_every_facing_end_a_full_scan_finds(
            ends in proptest::collection::vec(
                (0u32..120, 0u32..90, 0u32..120, 0u32..90, 0u32..4), 2..60),
            r in 0.0f64..40.0,
        ) {
            let lines: Vec<Line> = ends
                .iter()
                .filter(|e| (e.0, e.1) != (e.2, e.3))
                .map(|&(a, b, c, d, fine)| {
                    let f = f64::from(fine) * 0.25;
                    line([f64::from(a) * 4.0 + f, f64::from(b) * 4.0], [f64::from(c) * 4.0, f64::from(d) * 4.0 - f])
                })
                .collect();
            let ranges = vec![(0, lines.len() as u32)];
            let (polys, links) = bridged(lines, ranges);
            let lines = &polys.lines;
            for x in 0..lines.len() {
                let mut got = Vec::new();
                facing(lines, &links, x, r, |y, from, to, side| got.push((side, y, from, to)));
                got.sort();
                let mut want = Vec::new();
                for y in (0..lines.len()).filter(|&y| y != x && sees(&links.lengths, x, y)) {
                    if within(lines[y].ps, lines[x].pe, r) {
                        want.push((Facing::Ahead, y, x, y));
                    }
                    if within(lines[y].pe, lines[x].ps, r) {
                        want.push((Facing::Behind, y, y, x));
                    }
                }
                want.sort();
                proptest::prop_assert_eq!(got, want);
            }
        }
    }

    #[test]
    fn a_line_end_that_is_not_finite_is_never_near() {
        let lines = vec![
            line([0.0, 0.0], [40.0, 0.0]),
            line([45.0, 0.0], [90.0, 0.0]),
            Line {
                ps: [f64::NAN, 0.0],
                pe: [42.0, f64::INFINITY],
                dir: [1.0, 0.0],
            },
        ];
        let (polys, links) = bridged(lines, vec![(0, 3)]);
        for x in 0..3 {
            for r in [5.0, 1e9, f64::NAN] {
                facing(&polys.lines, &links, x, r, |y, _, _, _| {
                    assert!(x != 2 && y != 2, "{x} {y} {r}");
                });
            }
        }
        // The finite pieces still bridge.
        assert_eq!(links.chain(0), links.chain(1));
    }

    #[test]
    fn bridged_pieces_link_their_borders() {
        let lines = vec![
            line([0.0, 0.0], [40.0, 0.0]),
            line([40.0, 0.0], [40.0, 30.0]),
            line([50.0, 0.0], [90.0, 0.0]),
            line([0.0, 60.0], [20.0, 60.0]),
        ];
        let (_, links) = bridged(lines, vec![(0, 2), (2, 3), (3, 4)]);
        assert_eq!(links.chain(0), links.chain(2));
        assert_ne!(links.chain(0), links.chain(1));
        assert_eq!(links.component(0), links.component(1));
        assert!(links.is_bridged(0) && links.is_bridged(1) && !links.is_bridged(2));
        assert_ne!(links.component(2), links.component(0));
    }
}

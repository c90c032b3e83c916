//! The printed tag's fixed look, everything but its cells and its id,
//! aligned to the image: where the rim look places a data square too
//! blurred or too small to make a quad of its own.
//!
//! The rim's ellipse and the gradients inside it predict the square to
//! within a tenth of its side or so (on the wild set the median was 8.8%,
//! over a cell of a ct14 tag), too far for the cells to be read. But most
//! of a printed tag does not depend on its id: the black frame, the white
//! disc, the bars below and beside the frame, the two ears, the black disc
//! and the white annulus that ends it (the format's geometry, items 1-9).
//! These fix the tag's projection, its rotation included (the bars and
//! ears are not symmetric), over an area several times the cells', so
//! they can be matched where the cells are blurred into each other.
//!
//! The match is the Lucas-Kanade image alignment (Lucas and Kanade 1981;
//! Baker and Matthews, "Lucas-Kanade 20 years on", 2004): Gauss-Newton
//! steps on the squared difference between the image, sampled through a
//! homography, and the template under a gain and an offset. Written here
//! because imageproc and kornia align whole images, not a template given
//! as a function of the tag's plane with parts left out. The template is
//! the print smoothed by a Gaussian (first wide, for a wide capture, then
//! narrow, for precision): a symmetric blur of the image (defocus, motion)
//! broadens the match's optimum without moving it.

use std::sync::OnceLock;

use nalgebra::{SMatrix, SVector};

use crate::family::Family;
use crate::geometry::{tag_shapes, Element, Paint, Part, Shape, B, CORNERS, R};
use crate::homography::{free_entries, Homography};
use crate::math::{bilinear_cross, sample_bilinear};
use crate::view::GrayView;

/// Half the side of the grid of template points in the tag's plane (units
/// of S, the data square's side): the printed tag is a square of side 2 S,
/// and its white border beyond the annulus (0.92 S) meets the background
/// at 1 S.
const REACH: f64 = 0.96;

/// Points per side of the template's grid over `[-REACH, REACH]`: 0.04 S
/// apart, a pixel on the smallest tags the rim look reads (24 px), 2.6 px
/// on its largest (64 px, cells of 4 px).
const GRID: usize = 48;

/// The cells' area left out of the template: everything within this
/// distance (units of S, the max norm) of the centre. The data square ends
/// at 0.5 S, and its one-cell white margin is S/16 wide for ct14 and S/10
/// for ct8: the white band 0.4375-0.5 is the margin in both families.
const CELLS_REACH: f64 = 0.5 - 1.0 / 16.0;

/// Width (units of S) of the Gaussian smoothing the template at each level
/// of the alignment, wide to narrow: 0.06 S is a cell of ct14 and half
/// the frame's width (a capture of about a cell either way), 0.025 S is
/// near a pixel on the smallest tags.
const SMOOTHING: [f64; 2] = [0.06, 0.025];

/// Samples per side of the stencil that smooths the template, over plus
/// or minus two widths.
const STENCIL: usize = 9;

/// Most Gauss-Newton steps per level.
const MAX_STEPS: usize = 12;

/// A step that moves no corner of the data square by more than this (px)
/// ends a level. At 0.05 px the wild set lost 8 markers of 3855 (the
/// last steps still matter at the limit of reading).
const CONVERGED_PX: f64 = 0.01;

/// Largest move (units of S) of a data-square corner in one step: a longer
/// step has left the basin of the match, and the alignment gives up.
const MAX_STEP_OF_SIDE: f64 = 0.25;

/// Image levels at or over this are taken as saturated (a glare on a
/// laminated tag) and left out: they show the glare, not the print.
const SATURATED: f64 = 250.0;

/// Smallest share of a level's points that must fall on the image (a
/// tag cut by the image's border aligns on the rest of it).
const MIN_POINT_SHARE: f64 = 0.25;

/// Smallest correlation between the aligned template and the image: below
/// it the fixed look is not there (a round shape of clutter).
pub(crate) const MIN_CORRELATION: f64 = 0.5;

/// Whether `shape` covers point `(u, v)` (tag units). Strokes (the id's
/// digits) are never asked: the id's area is left out of the template.
fn covers(shape: &Shape, u: f64, v: f64) -> bool {
    match shape {
        Shape::Rect { x0, y0, x1, y1 } => (*x0..=*x1).contains(&u) && (*y0..=*y1).contains(&v),
        Shape::Disc { cx, cy, r } => distance_within(u - cx, v - cy, 0.0, *r),
        Shape::Annulus {
            cx,
            cy,
            r_in,
            r_out,
        } => distance_within(u - cx, v - cy, *r_in, *r_out),
        Shape::Rects(rs) => rs
            .iter()
            .any(|r| (r[0]..=r[2]).contains(&u) && (r[1]..=r[3]).contains(&v)),
        Shape::Strokes { .. } => false,
    }
}

/// Relative margin around a radius within which [`distance_within`]
/// leaves the decision to `hypot`: the squared distance is computed to a
/// few parts in 10^16, so outside the margin it decides as `hypot` would.
const HYPOT_MARGIN: f64 = 1e-9;

/// Whether the length of `(du, dv)` lies in `[lo, hi]`, as
/// `(lo..=hi).contains(&du.hypot(dv))` decides it.
///
/// Why not `hypot` alone: building the template ([`template`]) asks
/// several hundred thousand points whether the print's discs and rings cover them,
/// and libm's `hypot`, careful about overflow, was a fifth of a
/// `coppertag detect` process on a small image. The squared distance
/// decides every point but those within [`HYPOT_MARGIN`] of a radius,
/// which `hypot` still decides, so the template is the same to the bit
/// (`template_is_its_definition`).
fn distance_within(du: f64, dv: f64, lo: f64, hi: f64) -> bool {
    let d2 = du * du + dv * dv;
    let (lo2, hi2) = (lo * lo, hi * hi);
    if d2 < lo2 * (1.0 - HYPOT_MARGIN) || d2 > hi2 * (1.0 + HYPOT_MARGIN) {
        return false;
    }
    if d2 > lo2 * (1.0 + HYPOT_MARGIN) && d2 < hi2 * (1.0 - HYPOT_MARGIN) {
        return true;
    }
    (lo..=hi).contains(&du.hypot(dv))
}

/// The parts of the print that no id or family changes: every shape of
/// [`tag_shapes`] but the id's digits, the cells and the centre checker,
/// in painting order.
fn fixed_shapes() -> &'static [Element] {
    static S: OnceLock<Vec<Element>> = OnceLock::new();
    S.get_or_init(|| {
        tag_shapes(Family::ct14(), 0)
            .map(|v| {
                v.into_iter()
                    .filter(|e| !matches!(e.part, Part::IdText | Part::Cells | Part::Checker))
                    .collect()
            })
            .unwrap_or_default()
    })
}

/// The grey level of the printed tag at `(u, v)` in the tag's plane
/// (units of S, centre at 0, y down), 0 black and 1 white, or `None` in
/// the cells' area and under the id's digits (the bar under the frame,
/// to the white disc's radius): the last fixed shape covering the point.
fn print_level(u: f64, v: f64) -> Option<f64> {
    let (au, av) = (u.abs(), v.abs());
    if au.max(av) < CELLS_REACH || (au < 0.5 && v > 0.5 + B && v <= R) {
        return None;
    }
    let paint = fixed_shapes()
        .iter()
        .rev()
        .find(|e| covers(&e.shape, u, v))
        .map_or(Paint::White, |e| e.paint);
    Some(if paint == Paint::White { 1.0 } else { 0.0 })
}

/// One level of the template: points in the tag's plane and the print's
/// level there, smoothed by one of the [`SMOOTHING`] widths.
struct Level {
    points: Vec<[f64; 2]>,
    values: Vec<f64>,
}

/// The template: a level per [`SMOOTHING`] width, wide to narrow, and
/// the wide level at its four quarter turns ([`fixed_look`]).
struct Template {
    levels: [Level; 2],
    /// The narrow level at every other grid point ([`align_quickly`]).
    sparse: Level,
    turns: Turns,
}

/// The wide level's grid outside the cells' area, with the template's
/// value at each point's quarter turns (the digits' area mid-grey): the
/// image is sampled once at the points, and each turn's correlation
/// pairs those samples with that turn's values.
struct Turns {
    points: Vec<[f64; 2]>,
    values: [Vec<f64>; 4],
}

/// Grid points a level takes, every `LEVEL_STRIDE[k]`-th of [`GRID`] in
/// each direction: the wide level is smooth over two grid steps, so a
/// quarter of the points carry what all do, at a quarter of the cost.
const LEVEL_STRIDE: [usize; 2] = [2, 1];

/// Builds the template ahead of the first frame ([`template`]), once per
/// process, which would otherwise land on the first frame with a rim to
/// align (the wild benchmark's slowest frame). On the 2.0 GHz Xeon the
/// project measures on, it takes 11 ms (24 ms before its stencils were
/// made once per width and its discs tested by squared distance, see
/// [`Stencil`] and [`distance_within`]; a `coppertag detect` process on a
/// 64 x 64 image, 30 runs, went from 49-54 ms to 37-39 ms). The four turns
/// of [`fixed_look`] are part of it.
pub(crate) fn prepare() {
    template();
}

/// The template, built once: the print's level smoothed by a Gaussian of
/// each width, where the cells and the digits count as mid-grey (half
/// the cells are black).
fn template() -> &'static Template {
    static T: OnceLock<Template> = OnceLock::new();
    T.get_or_init(|| {
        let step = 2.0 * REACH / (GRID - 1) as f64;
        let grid = |stride: usize| {
            (0..GRID)
                .step_by(stride)
                .flat_map(move |i| (0..GRID).step_by(stride).map(move |j| (i, j)))
                .map(move |(i, j)| [-REACH + j as f64 * step, -REACH + i as f64 * step])
        };
        let stencils = SMOOTHING.map(Stencil::new);
        let level_at = |k: usize, stride: usize| {
            let points: Vec<[f64; 2]> = grid(stride)
                .filter(|p| print_level(p[0], p[1]).is_some())
                .collect();
            let values = points.iter().map(|&p| smoothed(p, &stencils[k])).collect();
            Level { points, values }
        };
        // The grid points outside the cells' area, and the wide
        // template's value at each quarter turn of each.
        let quarter = |[u, v]: [f64; 2]| [-v, u];
        let turn = |p: [f64; 2], k: usize| (0..k).fold(p, |q, _| quarter(q));
        let points: Vec<[f64; 2]> = grid(LEVEL_STRIDE[0])
            .filter(|&p| p[0].abs().max(p[1].abs()) >= CELLS_REACH)
            .collect();
        let values = std::array::from_fn(|k| {
            points
                .iter()
                .map(|&p| smoothed(turn(p, k), &stencils[0]))
                .collect()
        });
        Template {
            levels: [level_at(0, LEVEL_STRIDE[0]), level_at(1, LEVEL_STRIDE[1])],
            sparse: level_at(1, 2),
            turns: Turns { points, values },
        }
    })
}

/// The smoothing stencil of one Gaussian width: its offsets along each
/// axis (plus or minus two widths), the weight of each offset pair and
/// their total, summed in the order [`smoothed`] takes them. Made once
/// per width rather than at each of the template's points (the weights
/// are the same for all of them; their `exp` was most of the rest of the
/// template's cost).
struct Stencil {
    offsets: [f64; STENCIL],
    weights: [[f64; STENCIL]; STENCIL],
    total: f64,
}

impl Stencil {
    fn new(s: f64) -> Self {
        let offsets = std::array::from_fn(|a| (a as f64 / (STENCIL - 1) as f64 * 4.0 - 2.0) * s);
        let weights =
            offsets.map(|du| offsets.map(|dv| (-(du * du + dv * dv) / (2.0 * s * s)).exp()));
        let mut total = 0.0;
        for w in weights.iter().flatten() {
            total += w;
        }
        Self {
            offsets,
            weights,
            total,
        }
    }
}

/// The print's level at `p` (tag units) smoothed by the Gaussian of
/// `stencil`, the cells and the digits counting as mid-grey (half the
/// cells are black).
fn smoothed(p: [f64; 2], stencil: &Stencil) -> f64 {
    let mut sum = 0.0;
    for (du, row) in stencil.offsets.iter().zip(&stencil.weights) {
        for (dv, w) in stencil.offsets.iter().zip(row) {
            sum += w * print_level(p[0] + du, p[1] + dv).unwrap_or(0.5);
        }
    }
    sum / stencil.total
}

/// A homography from the tag's plane (units of S) to image pixels, as its
/// eight free entries (the ninth is 1).
type H8 = [f64; 8];

fn map(h: &H8, p: [f64; 2]) -> Option<[f64; 2]> {
    let w = h[6] * p[0] + h[7] * p[1] + 1.0;
    (w > 1e-6).then(|| {
        [
            (h[0] * p[0] + h[1] * p[1] + h[2]) / w,
            (h[3] * p[0] + h[4] * p[1] + h[5]) / w,
        ]
    })
}

/// `h` after a turn of the tag's plane by `k` quarter turns about its
/// centre: `h Rot(k 90 degrees)`.
fn turned(h: &H8, k: usize) -> H8 {
    let (c, s) = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][k % 4];
    [
        h[0] * c + h[1] * s,
        -h[0] * s + h[1] * c,
        h[2],
        h[3] * c + h[4] * s,
        -h[3] * s + h[4] * c,
        h[5],
        h[6] * c + h[7] * s,
        -h[6] * s + h[7] * c,
    ]
}

/// The turn of `h` (a multiple of 90 degrees) under which the template's
/// level `t` correlates best with the image, and that correlation.
fn best_turn(img: &GrayView<'_>, h: &H8, t: &Level) -> Option<(f64, H8)> {
    (0..4)
        .filter_map(|k| {
            let h = turned(h, k);
            correlation(img, &h, t).map(|r| (r, h))
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// The data square's corners under `h`, TL, BL, BR, TR.
fn square(h: &H8) -> Option<[[f64; 2]; 4]> {
    let c = [[-0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.5, -0.5]].map(|p| map(h, p));
    Some([c[0]?, c[1]?, c[2]?, c[3]?])
}

/// The points of the template's `level` that `h` maps onto the image,
/// where the image is not saturated: each point, its template value, the
/// point on the image and the image's level there.
fn on_image<'a>(
    img: &'a GrayView<'_>,
    h: &'a H8,
    level: &'a Level,
) -> impl Iterator<Item = ([f64; 2], f64, [f64; 2], f64)> + 'a {
    level
        .points
        .iter()
        .zip(&level.values)
        .filter_map(move |(&p, &tv)| {
            let q = map(h, p)?;
            let iv = sample_bilinear(img, q[0], q[1]).filter(|&v| v < SATURATED)?;
            Some((p, tv, q, iv))
        })
}

/// Pearson correlation between the template's `level` and the image
/// under `h`, over its points on the image.
fn correlation(img: &GrayView<'_>, h: &H8, level: &Level) -> Option<f64> {
    let pts = &level.points;
    let (mut n, mut st, mut si, mut stt, mut sii, mut sti) = (0usize, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (_, tv, _, iv) in on_image(img, h, level) {
        n += 1;
        st += tv;
        si += iv;
        stt += tv * tv;
        sii += iv * iv;
        sti += tv * iv;
    }
    if (n as f64) < MIN_POINT_SHARE * pts.len() as f64 {
        return None;
    }
    let nf = n as f64;
    let vt = stt - st * st / nf;
    let vi = sii - si * si / nf;
    let c = sti - st * si / nf;
    (vt > 0.0 && vi > 0.0).then(|| c / (vt * vi).sqrt())
}

/// How well the print's fixed look shows in `img` where `h` (the tag's
/// plane, units of S, to px) puts the tag: the Pearson correlation of the
/// wide template with the image, as in [`correlation`], under the best of
/// the four quarter turns, as the turn is not known before a reading (0
/// on an image flat there). `None` when under [`MIN_POINT_SHARE`] of the
/// template falls on the image.
///
/// The wide level (smoothed by 0.06 S, a ct14 cell) because it is cheap
/// (a quarter of the points) and forgiving: a quad's refined corners are
/// within a pixel or so of the square, and the look is judged, not
/// aligned. The turns are taken on one sampling of the image ([`Turns`]):
/// a look costs about what one correlation does.
fn fixed_look(img: &GrayView<'_>, h: &H8) -> Option<f64> {
    let t = &template().turns;
    let (mut n, mut si, mut sii) = (0usize, 0.0, 0.0);
    let (mut st, mut stt, mut sti) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
    for (i, &p) in t.points.iter().enumerate() {
        let Some(iv) = map(h, p)
            .and_then(|q| sample_bilinear(img, q[0], q[1]))
            .filter(|&v| v < SATURATED)
        else {
            continue;
        };
        n += 1;
        si += iv;
        sii += iv * iv;
        for k in 0..4 {
            let tv = t.values[k][i];
            st[k] += tv;
            stt[k] += tv * tv;
            sti[k] += tv * iv;
        }
    }
    if n == 0 || (n as f64) < MIN_POINT_SHARE * t.points.len() as f64 {
        return None;
    }
    let nf = n as f64;
    let vi = sii - si * si / nf;
    if vi <= 0.0 {
        return Some(0.0);
    }
    (0..4)
        .filter_map(|k| {
            let vt = stt[k] - st[k] * st[k] / nf;
            (vt > 0.0).then(|| (sti[k] - st[k] * si / nf) / (vt * vi).sqrt())
        })
        .max_by(f64::total_cmp)
}

/// Least [`fixed_look`] of a refined candidate quad that is decoded
/// ([`shows_no_print`]). Most candidates of a cluttered frame are quads of
/// clutter, and each costs a whole failed reading (every reading the
/// decoder has, for each family: 0.25 ms at the median on the wild set),
/// where a printed tag shows its frame, disc, bars and ears around the
/// square. On the wild set's 3000 frames, of the 26 005 refined quads
/// that read nothing, 20% looked under 0.0 both as a data square and as
/// an outline, 26% under 0.05, 34% under 0.1 and 51% under 0.2; of the
/// 7535 that read (as a tag, a last resort or the other family's
/// square), 0, 2, 3 and 10. The lowest are low-contrast prints under a
/// black blob, whose Pearson correlation the blob dominates (a tag of the
/// wild set read at 0.10). Refused under 0.05 or 0.1, no detection of
/// the wild set changed (the two tags read through other quads), nor
/// under 0.05 of the calibration, jitter and tag-free sets: 0.05 keeps
/// half the way to the first good quads.
pub(crate) const MIN_QUAD_LOOK: f64 = 0.05;

/// Whether the refined candidate quad `q` (corners TL, BL, BR, TR, px)
/// shows no printed tag: the print's [`fixed_look`] is under
/// [`MIN_QUAD_LOOK`] both with `q` as the data square and with `q` as the
/// printed square's outline (the data square its middle half, see
/// `outline`). A look that cannot be judged (a tag mostly off the image)
/// refuses nothing.
#[cfg(test)]
pub(crate) fn shows_no_print(img: &GrayView<'_>, q: &[[f64; 2]; 4]) -> bool {
    quad_look(img, q).no_print
}

/// What the print's [`fixed_look`] makes of a refined quad
/// ([`quad_look`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct QuadLook {
    /// The look with the quad as the data square, where it can be judged.
    pub own: Option<f64>,
    /// Whether the quad shows no printed tag ([`shows_no_print`]).
    pub no_print: bool,
}

/// The print's [`fixed_look`] of the quad `q` (corners TL, BL, BR, TR, px)
/// as the data square, and whether it [shows no print](shows_no_print);
/// the look as the outline is taken only where the own look is under
/// [`MIN_QUAD_LOOK`].
pub(crate) fn quad_look(img: &GrayView<'_>, q: &[[f64; 2]; 4]) -> QuadLook {
    let Some(h) = Homography::from_points(&CORNERS, q).and_then(|h| free_entries(h.matrix()))
    else {
        return QuadLook {
            own: None,
            no_print: false,
        };
    };
    let own = fixed_look(img, &h);
    if !own.is_some_and(|r| r < MIN_QUAD_LOOK) {
        return QuadLook {
            own,
            no_print: false,
        };
    }
    // As the outline, `q` is the tag's plane at twice the scale: its data
    // square's point (u, v) lies where `h` puts (u / 2, v / 2).
    let half = |x: f64| x / 2.0;
    let inner: H8 = [
        half(h[0]),
        half(h[1]),
        h[2],
        half(h[3]),
        half(h[4]),
        h[5],
        half(h[6]),
        half(h[7]),
    ];
    QuadLook {
        own,
        no_print: fixed_look(img, &inner).is_some_and(|r| r < MIN_QUAD_LOOK),
    }
}

/// The result of [`align`]: the data square's corners (full-resolution
/// px, TL, BL, BR, TR of the printed tag, its rotation resolved) and the
/// correlation of the aligned template with the image.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Aligned {
    pub corners: [[f64; 2]; 4],
    pub correlation: f64,
}

/// The print's fixed look aligned to `img` from the affine prediction
/// `at(u, v) = c + m (u, v)` (tag units to px) known up to a rotation by
/// a multiple of 90 degrees: the rotation that correlates best, then
/// Gauss-Newton steps on each smoothing level. `None` when the steps leave
/// the basin or the template falls off the image.
pub(crate) fn align(img: &GrayView<'_>, m: [[f64; 2]; 2], c: [f64; 2]) -> Option<Aligned> {
    let tpl = template();
    align_on(
        img,
        m,
        c,
        &[(&tpl.levels[0], MAX_STEPS), (&tpl.levels[1], MAX_STEPS)],
    )
}

/// Gauss-Newton steps [`align_quickly`] takes on the whole narrow level
/// after the sparse one has converged.
const QUICK_FINAL_STEPS: usize = 3;

/// [`align`] at about half the cost, for prints aligned on the off chance
/// (`decoding::aligned_unread`): the narrow level is first stepped to
/// convergence on every other grid point, then [`QUICK_FINAL_STEPS`]
/// steps on all of them. On a small tag (a data square of 30 px or less)
/// the narrow level's points are about 0.6 px apart, twice as dense as
/// the pixels, and most of [`align`]'s time goes to its last steps, which
/// move the corners by hundredths of a pixel. Measured on the wild set's
/// first 1500 frames, on the 590 quads `aligned_unread` aligns: with
/// [`align`] 1.2 s and 43 readings that stand; the sparse level alone
/// 0.6 s and 39; then 2 or 4 steps on all points, 0.6 s and 42, 0.75 s
/// and 44 (the timings are noisy to a tenth). With 3, the whole wild
/// set gains the same 52 markers as with [`align`].
pub(crate) fn align_quickly(img: &GrayView<'_>, m: [[f64; 2]; 2], c: [f64; 2]) -> Option<Aligned> {
    let tpl = template();
    align_on(
        img,
        m,
        c,
        &[
            (&tpl.levels[0], MAX_STEPS),
            (&tpl.sparse, MAX_STEPS),
            (&tpl.levels[1], QUICK_FINAL_STEPS),
        ],
    )
}

/// [`align`] over `levels`, wide to narrow, each with its most steps; the
/// turn is chosen again on the second level, and the correlation is the
/// last level's.
fn align_on(
    img: &GrayView<'_>,
    m: [[f64; 2]; 2],
    c: [f64; 2],
    levels: &[(&Level, usize)],
) -> Option<Aligned> {
    let h0: H8 = [m[0][0], m[0][1], c[0], m[1][0], m[1][1], c[1], 0.0, 0.0];
    let mut h = best_turn(img, &h0, levels.first()?.0)?.1;
    let side = (m[0][0].hypot(m[1][0]) + m[0][1].hypot(m[1][1])) / 2.0;
    for (level, &(t, steps)) in levels.iter().enumerate() {
        if level == 1 {
            // The turn again, on the narrow template once the wide one has
            // placed the print: the bars and ears that tell the turns
            // apart are a few pixels wide on a small tag, and the wide
            // template blurs them into the disc.
            h = best_turn(img, &h, t)?.1;
        }
        // The perspective terms only on the narrow level: the wide one
        // cannot tell them from the blur.
        let free = if level == 0 { 6 } else { 8 };
        for _ in 0..steps {
            let before = square(&h)?;
            h = step(img, &h, t, free)?;
            let after = square(&h)?;
            let moved = (0..4)
                .map(|k| (after[k][0] - before[k][0]).hypot(after[k][1] - before[k][1]))
                .fold(0.0, f64::max);
            if moved > MAX_STEP_OF_SIDE * side {
                return None;
            }
            if moved < CONVERGED_PX {
                break;
            }
        }
    }
    let corners = square(&h)?;
    let correlation = correlation(img, &h, levels.last()?.0)?;
    Some(Aligned {
        corners,
        correlation,
    })
}

/// One Gauss-Newton step of `h` against the template's `level`, on the
/// first `free` of its entries (6: affine) and a gain and an offset.
fn step(img: &GrayView<'_>, h: &H8, level: &Level, free: usize) -> Option<H8> {
    const N: usize = 10;
    let pts = &level.points;
    // The normal equations' upper triangle, by rows: nalgebra's matrices
    // are stored by columns, and the sums along a row (the inner loop
    // below) then ran with a stride of N; here they run along contiguous
    // memory. The same sums in the same order as summed into the matrix.
    let mut upper = [[0.0f64; N]; N];
    let mut g = SVector::<f64, N>::zeros();
    // Gain and offset by least squares first, then the geometric step with
    // them as unknowns too.
    let mut samples = Vec::with_capacity(pts.len());
    let (mut n, mut st, mut si, mut stt, mut sti) = (0usize, 0.0, 0.0, 0.0, 0.0);
    // The points `on_image` gives whose gradient samples, a pixel either
    // side, lie in the image too.
    for (&p, &tv) in pts.iter().zip(&level.values) {
        let Some(q) = map(h, p) else {
            continue;
        };
        let Some([iv, xl, xr, yu, yd]) = bilinear_cross(img, q[0], q[1]) else {
            continue;
        };
        if iv >= SATURATED {
            continue;
        }
        samples.push((p, tv, q, iv, [(xr - xl) / 2.0, (yd - yu) / 2.0]));
        n += 1;
        st += tv;
        si += iv;
        stt += tv * tv;
        sti += tv * iv;
    }
    if (n as f64) < MIN_POINT_SHARE * pts.len() as f64 {
        return None;
    }
    let nf = n as f64;
    let vt = stt - st * st / nf;
    if vt <= 0.0 {
        return None;
    }
    let gain = (sti - st * si / nf) / vt;
    let offset = (si - gain * st) / nf;
    for (p, tv, q, iv, grad) in samples {
        let w = h[6] * p[0] + h[7] * p[1] + 1.0;
        let (u, v) = (p[0] / w, p[1] / w);
        let iw = 1.0 / w;
        // d(image sample)/d(entry), through the mapped point.
        let (gx, gy) = (grad[0], grad[1]);
        let j: [f64; N] = [
            gx * u,
            gx * v,
            gx * iw,
            gy * u,
            gy * v,
            gy * iw,
            -(gx * q[0] + gy * q[1]) * u,
            -(gx * q[0] + gy * q[1]) * v,
            -tv,
            -1.0,
        ];
        // Residual: image minus the template under gain and offset.
        let e = iv - (gain * tv + offset);
        for r in 0..N {
            g[r] += j[r] * e;
            let jr = j[r];
            for (a, &js) in upper[r][r..].iter_mut().zip(&j[r..]) {
                *a += jr * js;
            }
        }
    }
    let mut a = SMatrix::<f64, N, N>::from_fn(|r, s| upper[r.min(s)][r.max(s)]);
    // Entries held fixed: their rows and columns become the identity.
    for r in free..8 {
        for s in 0..N {
            a[(r, s)] = 0.0;
            a[(s, r)] = 0.0;
        }
        a[(r, r)] = 1.0;
        g[r] = 0.0;
    }
    let delta = a.cholesky()?.solve(&g);
    let mut out = *h;
    for (k, o) in out.iter_mut().enumerate() {
        *o -= delta[k];
    }
    Some(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use image::GrayImage;
    use proptest::prelude::*;

    /// [`covers`] as first written, with `hypot` for the discs and rings.
    fn covers_by_hypot(shape: &Shape, u: f64, v: f64) -> bool {
        match shape {
            Shape::Disc { cx, cy, r } => (u - cx).hypot(v - cy) <= *r,
            Shape::Annulus {
                cx,
                cy,
                r_in,
                r_out,
            } => (*r_in..=*r_out).contains(&(u - cx).hypot(v - cy)),
            other => covers(other, u, v),
        }
    }

    /// The template's value at `p` by its definition: every stencil
    /// weight computed where it is used, the shapes tested with `hypot`.
    fn smoothed_by_definition(p: [f64; 2], s: f64) -> f64 {
        let level = |u: f64, v: f64| {
            print_level(u, v)?;
            let paint = fixed_shapes()
                .iter()
                .rev()
                .find(|e| covers_by_hypot(&e.shape, u, v))
                .map_or(Paint::White, |e| e.paint);
            Some(if paint == Paint::White { 1.0 } else { 0.0 })
        };
        let (mut sum, mut wsum) = (0.0, 0.0);
        for a in 0..STENCIL {
            let du = (a as f64 / (STENCIL - 1) as f64 * 4.0 - 2.0) * s;
            for c in 0..STENCIL {
                let dv = (c as f64 / (STENCIL - 1) as f64 * 4.0 - 2.0) * s;
                let w = (-(du * du + dv * dv) / (2.0 * s * s)).exp();
                sum += w * level(p[0] + du, p[1] + dv).unwrap_or(0.5);
                wsum += w;
            }
        }
        sum / wsum
    }

    /// The template built once with its stencils made ahead and the
    /// squared-distance tests of [`distance_within`] is, to the bit, the
    /// template of its definition at every point of every level and turn:
    /// the alignment, and so every detection, is unchanged by the faster
    /// build.
    #[test]
    fn template_is_its_definition() {
        let t = template();
        let same = |points: &[[f64; 2]], values: &[f64], s: f64, turns: usize| {
            assert_eq!(points.len(), values.len());
            for (&p, &v) in points.iter().zip(values) {
                let q = (0..turns).fold(p, |[u, v], _| [-v, u]);
                let want = smoothed_by_definition(q, s);
                assert_eq!(
                    v.to_bits(),
                    want.to_bits(),
                    "at {q:?} (width {s}): {v} != {want}"
                );
            }
        };
        for (k, level) in t.levels.iter().enumerate() {
            same(&level.points, &level.values, SMOOTHING[k], 0);
        }
        same(&t.sparse.points, &t.sparse.values, SMOOTHING[1], 0);
        for (k, values) in t.turns.values.iter().enumerate() {
            same(&t.turns.points, values, SMOOTHING[0], k);
        }
    }

    proptest! {
        /// [`distance_within`] decides as `hypot` does, also for points
        /// on a radius or a few units in the last place from it.
        #[test]
        fn distance_within_is_hypot(
            angle in 0.0f64..std::f64::consts::TAU,
            lo in 0.0f64..0.9,
            width in 0.0f64..0.5,
            at in 0usize..3,
            ulps in -4i64..=4,
        ) {
            let hi = lo + width;
            let r = [lo, hi, (lo + hi) / 2.0][at];
            let r = f64::from_bits((r.to_bits() as i64 + ulps).max(0) as u64);
            let (du, dv) = (r * angle.cos(), r * angle.sin());
            prop_assert_eq!(
                distance_within(du, dv, lo, hi),
                (lo..=hi).contains(&du.hypot(dv))
            );
        }
    }

    #[test]
    fn the_print_has_its_fixed_parts() {
        // Frame black, margin white, the bar above the frame, the black
        // disc, the annulus; the cells and the id left out.
        assert_eq!(print_level(0.55, 0.0), Some(0.0));
        assert_eq!(print_level(0.47, 0.0), Some(1.0));
        assert_eq!(print_level(0.0, -0.66), Some(0.0));
        assert_eq!(print_level(0.0, -0.75), Some(0.0));
        assert_eq!(print_level(0.0, -0.89), Some(1.0));
        assert_eq!(print_level(0.1, 0.1), None);
        assert_eq!(print_level(0.0, 0.66), None);
        // Beside the frame: a white sliver in the upper half, then an ear;
        // the bar in the lower half.
        assert_eq!(print_level(0.65, -0.1), Some(1.0));
        assert_eq!(print_level(-0.695, -0.1), Some(0.0));
        assert_eq!(print_level(0.65, 0.2), Some(0.0));
    }

    /// `[[a, b], [c, d]]` times `[[e, f], [g, h]]`.
    fn mul(x: [[f64; 2]; 2], y: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
        std::array::from_fn(|i| std::array::from_fn(|j| x[i][0] * y[0][j] + x[i][1] * y[1][j]))
    }

    fn rot(a: f64) -> [[f64; 2]; 2] {
        [[a.cos(), -a.sin()], [a.sin(), a.cos()]]
    }

    const C: [f64; 2] = [80.0, 80.0];

    /// A 160 x 160 image of the whole printed ct14 tag 200 (every shape
    /// of `tag_shapes` but the digits) through the affine map `m` (tag
    /// units to px) about `C`, 4 x 4 supersampled, Gaussian-blurred by
    /// `blur` px; and its corners TL, BL, BR, TR.
    pub(crate) fn print(m: [[f64; 2]; 2], blur: f32) -> (GrayImage, [[f64; 2]; 4]) {
        let shapes = tag_shapes(Family::ct14(), 200).unwrap();
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let inv = [
            [m[1][1] / det, -m[0][1] / det],
            [-m[1][0] / det, m[0][0] / det],
        ];
        let img = GrayImage::from_fn(160, 160, |x, y| {
            let mut sum = 0.0;
            for k in 0..16 {
                let d = [
                    f64::from(x) - C[0] + (f64::from(k % 4) - 1.5) / 4.0,
                    f64::from(y) - C[1] + (f64::from(k / 4) - 1.5) / 4.0,
                ];
                let (u, v) = (
                    inv[0][0] * d[0] + inv[0][1] * d[1],
                    inv[1][0] * d[0] + inv[1][1] * d[1],
                );
                let black = u.abs().max(v.abs()) <= 1.0
                    && shapes
                        .iter()
                        .rev()
                        .find(|e| covers(&e.shape, u, v))
                        .is_some_and(|e| e.paint == Paint::Black);
                sum += if black { 25.0 } else { 215.0 };
            }
            image::Luma([(sum / 16.0) as u8])
        });
        let img = if blur > 0.0 {
            imageproc::filter::gaussian_blur_f32(&img, blur)
        } else {
            img
        };
        let corners = crate::geometry::CORNERS.map(|[u, v]| {
            [
                C[0] + m[0][0] * u + m[0][1] * v,
                C[1] + m[1][0] * u + m[1][1] * v,
            ]
        });
        (img, corners)
    }

    fn worst(q: &[[f64; 2]; 4], truth: &[[f64; 2]; 4]) -> f64 {
        (0..4)
            .map(|k| (q[k][0] - truth[k][0]).hypot(q[k][1] - truth[k][1]))
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_print_aligns_from_a_rough_prediction_through_blur() {
        // Small tilted tags (24-40 px squares), blurred over a ct14 cell,
        // from predictions off by 10% in size, 6 degrees in turn and a
        // pixel and a half in place (the rim's prediction on the wild set
        // was off by 8.8% of the side at the median): the corners within
        // 3% of the side, in the print's order.
        for (side, turn, k, phi, blur) in [
            (24.0, 0.3, 0.8, 0.4, 1.2),
            (30.0, 2.0, 0.6, -0.7, 1.5),
            (40.0, -1.2, 0.9, 1.9, 2.0),
        ] {
            let tilt = mul(mul(rot(phi), [[1.0, 0.0], [0.0, k]]), rot(-phi));
            let m = mul(tilt, rot(turn)).map(|r| r.map(|x| x * side));
            let (img, truth) = print(m, blur);
            let off = mul(rot(0.1), [[1.1, 0.0], [0.0, 0.95]]);
            let start = mul(m, off);
            let got = align(&GrayView::from(&img), start, [C[0] + 1.2, C[1] - 0.8])
                .expect("an alignment");
            assert!(got.correlation >= MIN_CORRELATION, "{got:?}");
            let e = worst(&got.corners, &truth);
            assert!(e < 0.03 * side, "side {side}: {e} px, {got:?} vs {truth:?}");
            // The prediction itself was well over that.
            let q = crate::geometry::CORNERS.map(|[u, v]| {
                [
                    C[0] + 1.2 + start[0][0] * u + start[0][1] * v,
                    C[1] - 0.8 + start[1][0] * u + start[1][1] * v,
                ]
            });
            assert!(worst(&q, &truth) > 0.08 * side);
        }
    }

    #[test]
    fn the_print_resolves_its_turn() {
        // Started a quarter turn off, a sharp 48 px tag comes back in its
        // own order: the bars and ears tell the turns apart.
        let m = rot(0.4).map(|r| r.map(|x| x * 48.0));
        let (img, truth) = print(m, 0.7);
        let got = align(
            &GrayView::from(&img),
            mul(m, rot(std::f64::consts::FRAC_PI_2)),
            C,
        )
        .expect("an alignment");
        assert!(worst(&got.corners, &truth) < 1.0, "{got:?} vs {truth:?}");
    }

    /// `q` scaled by `k` about [`C`].
    fn scaled(q: &[[f64; 2]; 4], k: f64) -> [[f64; 2]; 4] {
        q.map(|p| [C[0] + k * (p[0] - C[0]), C[1] + k * (p[1] - C[1])])
    }

    #[test]
    fn a_tags_square_or_outline_shows_the_print() {
        // Sharp or blurred, tilted, at any turn; the data square or the
        // printed square around it (twice its side); corners a pixel off.
        for (side, turn, k, blur) in [
            (48.0, 0.3, 1.0, 0.0),
            (36.0, 2.2, 0.6, 1.5),
            (24.0, -1.0, 0.8, 1.0),
        ] {
            let m = mul(rot(turn), [[1.0, 0.0], [0.0, k]]).map(|r| r.map(|x| x * side));
            let (img, q) = print(m, blur);
            let view = GrayView::from(&img);
            let h = Homography::from_points(&CORNERS, &q).unwrap();
            assert!(
                fixed_look(&view, &free_entries(h.matrix()).unwrap()).unwrap() > 0.5,
                "side {side}"
            );
            let off = [[1.0, -0.6], [-0.8, 0.9], [0.7, 1.0], [-1.0, -0.5]];
            let moved: [[f64; 2]; 4] =
                std::array::from_fn(|i| [q[i][0] + off[i][0], q[i][1] + off[i][1]]);
            assert!(!shows_no_print(&view, &moved), "side {side}");
            assert!(!shows_no_print(&view, &scaled(&q, 2.0)), "side {side}");
        }
    }

    #[test]
    fn a_tag_half_under_an_occluder_shows_the_print() {
        // A dark band over the upper third of the print and a light one
        // over the right third.
        let m = rot(0.5).map(|r| r.map(|x| x * 40.0));
        let (mut img, q) = print(m, 0.8);
        for y in 0..160 {
            for x in 0..160 {
                if y < 67 {
                    img.put_pixel(x, y, image::Luma([40]));
                } else if x > 93 {
                    img.put_pixel(x, y, image::Luma([200]));
                }
            }
        }
        assert!(!shows_no_print(&GrayView::from(&img), &q));
    }

    #[test]
    fn clutter_quads_show_no_print() {
        // A light card and a dark one on a grey table: their quads, and
        // their middle halves, show none of the print around them, while
        // a printed tag's square there does.
        let card = |inside: u8| {
            GrayImage::from_fn(160, 160, |x, y| {
                let on = (50..110).contains(&x) && (50..110).contains(&y);
                image::Luma([if on { inside } else { 120 }])
            })
        };
        let q = [[49.5, 49.5], [49.5, 109.5], [109.5, 109.5], [109.5, 49.5]];
        for inside in [230, 20] {
            assert!(
                shows_no_print(&GrayView::from(&card(inside)), &q),
                "{inside}"
            );
        }
        let (img, q) = print(rot(0.0).map(|r| r.map(|x| x * 60.0)), 0.0);
        assert!(!shows_no_print(&GrayView::from(&img), &q));
    }

    #[test]
    fn quads_that_cannot_be_judged_are_not_refused() {
        // A collapsed quad, one with a NaN corner, one off the image and
        // an absurdly large one: no panic, and nothing refused unseen.
        let img = GrayImage::from_pixel(160, 160, image::Luma([120]));
        let view = GrayView::from(&img);
        let p = [80.0, 80.0];
        for q in [
            [p; 4],
            [[f64::NAN, 10.0], [10.0, 60.0], [60.0, 60.0], [60.0, 10.0]],
            [
                [500.0, 500.0],
                [500.0, 560.0],
                [560.0, 560.0],
                [560.0, 500.0],
            ],
            [[-1e12, -1e12], [-1e12, 1e12], [1e12, 1e12], [1e12, -1e12]],
        ] {
            assert!(!shows_no_print(&view, &q), "{q:?}");
        }
    }

    #[test]
    fn a_blank_page_is_no_print() {
        let img = GrayImage::from_fn(160, 160, |x, _| image::Luma([100 + (x % 7) as u8]));
        let m = rot(0.2).map(|r| r.map(|x| x * 30.0));
        let got = align(&GrayView::from(&img), m, C);
        assert!(
            got.is_none_or(|a| a.correlation < MIN_CORRELATION),
            "{got:?}"
        );
    }
}

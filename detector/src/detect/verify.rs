//! Stage 7: the decoded tag checks and re-measures its own geometry.
//!
//! Once a reading names its family and id, the whole appearance of the
//! data square is known: the white margin, every black/white cell edge and
//! the centre checker, all in tag units. Corners measured where an
//! occluder's edge continues a side of the tag (dark tape flush with the
//! black frame, a stick across a corner) make a quad whose sides are the
//! right lines but whose cells are shifted; the Reed-Solomon code can
//! absorb the misread cells, so the id is right and the corners are not.
//! This stage
//!
//! 1. tests side shifts: each side moved outwards or inwards, in the tag
//!    plane, by whole and half cells; a shift is taken only when it makes
//!    clearly more cells agree with the decoded code
//!    ([`MIN_SHIFT_GAIN`]): that is the occluder-edge mistake undone;
//! 2. fits the homography to the model's edges at full resolution
//!    (iteratively reweighted least squares with Tukey's biweight, the
//!    scale from the median absolute residual; Hartley & Zisserman,
//!    "Multiple View Geometry", 2nd ed., section 4.8, for robust cost
//!    functions): each edge point is searched along the image normal of
//!    its predicted position; an edge hidden by an occluder shows no
//!    contrast there and gets no vote, an occluder's own edge gets a large
//!    residual and a weight of zero;
//!    The sides' edge points are first moved inwards by the blur bias of
//!    their half-level crossing (`edge_bias`: the white margin is one
//!    cell wide, and under blur the crossing moves out into the frame).
//!    An occluder's edge along a side, over the margin, agrees with
//!    itself all along and keeps its weights: a side whose points lie off
//!    where the rest of the fit puts them is fitted once more without a
//!    vote ([`OFF_SIDE_CELLS`]);
//! 3. reports the corners of the fitted homography, each with an
//!    uncertainty (px) from the fit's covariance, marks as estimated every
//!    corner that no visible edge near it supports, and rejects a reading
//!    whose fitted geometry no longer decodes to the same id (the fit
//!    contradicts its own cells);
//! 4. before rejecting, fits once more with each corner held near the
//!    reading's geometry (after any side shift) by a prior
//!    ([`PRIOR_SIGMA_CELLS`]): where an occluder cuts the sides near a
//!    hidden corner short, the visible edges leave a direction of the
//!    homography nearly free, and the free fit creeps along it on to the
//!    occluder's edges (on the wild set, readings with every corner within
//!    0.2 px of the truth were fitted 4-18 px away and rejected).

use crate::decode::{decode_quad_by, Accept, DecodeParams, Promising, QuadReading};
use crate::family::Family;
use crate::geometry::CORNERS;
use crate::grid_code::encode_cells;
use crate::homography::{free_entries, Homography};
use crate::math::{centroid, dot, mean_side, norm, sample_bilinear, sample_profile, sub};
use crate::view::GrayView;

use super::edge_bias::{self, BlurBias, Ruler, GAUSS_QUARTILE_SPAN};
use super::refine::MARGIN_CELLS;

use nalgebra::{Matrix3, SMatrix, SVector};

/// A side shift replaces the reading's quad only when it makes at least
/// this many more cells agree with the decoded code: a real shift of the
/// grid by a cell or more changes dozens of cells, noise a few.
pub(crate) const MIN_SHIFT_GAIN: usize = 4;

/// Side shifts tried, in cells, up to this fraction of the side (the
/// occluders of the field report cover up to 40% of the square).
const MAX_SHIFT_SIDE: f64 = 0.45;

/// Side shifts are tried in steps of this fraction of a cell.
const SHIFT_STEP_CELLS: f64 = 0.5;

/// The side-shift search tries every this many steps first, then the
/// steps around the best of those.
const COARSE_SHIFT_STEPS: i32 = 2;

/// Most cell-edge points measured per round of the fit: beyond it they are
/// taken at an even stride (ct14 has about 200; the fit's 8 unknowns
/// gain little from more, and each point costs a profile per round).
const MAX_CELL_POINTS: usize = 96;

/// Cells this small (px) or smaller are not sampled for the shift test:
/// their centres blur into their neighbours.
const MIN_SHIFT_CELL_PX: f64 = 1.8;

/// Cell edges are measured only where a cell is at least this big (px);
/// below it only the four sides of the data square are, unless a side
/// hides ([`MIN_SIDE_POINTS`]) or the sides alone do not fit (see
/// [`verify`]).
///
/// Why those two: an occluder along a side (flush tape, a block or a part
/// lying on the edge) leaves three sides, and three lines leave two of the
/// homography's eight unknowns free. The fit ran off along them, and the
/// reading was dropped as unfit, or, standing without a fit, kept the
/// quad's own corners. The cell edges beside the hidden side pin it down.
/// On the wild set (3000 frames) against the sides alone: 54 more markers
/// found and 4 lost, none rough (three of the new ones had been read
/// through a quad with a hidden corner 3.1-4.5 px off, and are found
/// within 0.6 px of the truth now); the calibration set 26 and 1, the ct8
/// twin 4 and 0. Of the 30 wild detections whose corners moved, 17 came
/// closer to the truth by over 0.3 px (the most, 2.1 to 0.2 px) and 6
/// went farther (the most, estimated corners, 0.33 to 1.86 px and 0.08 to
/// 1.16 px). A floor on the cell size changed nothing down to 1 px and
/// found fewer above it (at 1.5 px, 3 fewer wild markers; at 2 px, 20).
pub(crate) const MIN_CELL_EDGE_PX: f64 = 2.5;

/// Fewest edge points the fit's first round must measure on each side of
/// the data square for the sides to be fitted alone; with fewer on some
/// side, the cell edges are measured too, whatever their size
/// ([`MIN_CELL_EDGE_PX`]). A ct14 side has 30 points. On the wild set,
/// against 4: 2 found 7 fewer markers; 8 found 6 more, but turned two
/// detections under triangles rough (an estimated corner 3.1 and 3.8 px
/// off, moved there by the cells' fit); 12, more rough still.
const MIN_SIDE_POINTS: usize = 4;

/// Cell size (px) of a data square with corners `corners` and a grid of
/// `grid` cells a side (its one-cell margin included), the size the
/// thresholds above are in.
pub(crate) fn cell_px(corners: &[[f64; 2]; 4], grid: usize) -> f64 {
    mean_side(corners) / (grid + MARGIN_CELLS) as f64
}

/// Profile half-window across an edge: this fraction of a cell, ...
const WINDOW_CELLS: f64 = 0.8;
/// ... clamped to this range (px).
const WINDOW_PX: (f64, f64) = (1.2, 8.0);
/// Profile samples per half-window (at least a quarter pixel apart).
const WINDOW_SAMPLES: f64 = 8.0;
/// Finest profile sampling step (px).
const MIN_PROFILE_STEP: f64 = 0.25;

/// An edge shows when the step across it is at least this fraction of the
/// tag's contrast (and [`super::refine::MIN_EDGE_CONTRAST`]): an occluder
/// over both sides of an edge leaves a flat profile.
const MIN_CONTRAST_FRACTION: f64 = 0.35;

/// The second fit (made only when the free fit contradicts the reading)
/// holds each corner near the reading's geometry, as a prior of this many
/// cells' standard deviation. A reading that decodes has its geometry right
/// to about a cell (a grid off by a cell reads other cells); the data
/// outweigh the prior wherever the visible edges constrain the homography,
/// and the prior holds the directions they leave free. Chosen on the wild
/// set (3000 frames) with the calibration set (1000) as the check, each
/// against main before it (52.7% / 54.4% found): 0.25 found 53.5% / 54.9%
/// with no rough detection; a looser 0.5 found 53.3% with one rough (a
/// hidden corner 3.4 px off), a stiffer 0.15 53.8% with one rough (3.1 px).
/// Fitting every reading with this prior, rather than as a second chance,
/// found 53.7% but added a rough detection on the calibration set: a
/// reading whose hidden corner was 7 px off, which the free fit corrects
/// and the prior held 4 px off.
const PRIOR_SIGMA_CELLS: f64 = 0.25;

/// A side of the data square whose edge points lie, by their median, this
/// many cells further off the line the rest of the fit puts them on than
/// the other sides' do (their median) is taken for an occluder's edge and
/// fitted without (see `off_side`); only a side with at least half its
/// points measured is judged. The other sides' offset is taken off because
/// on a blurred tag every side sits a little off the cells (on the ct8
/// twin, an unoccluded 35 px tag had offsets of 0.06-0.33 cells, and
/// leaving its worst side out moved a corner from 0.97 to 2.72 px off).
/// On the wild set, the calibration set and the ct8 twin against no such
/// test: with 0.25, 13 detections came over 0.3 px closer to the truth
/// (the most, 4.14 to 0.91 px and 3.51 to 0.19 px: three of the ct8 twin's
/// four rough detections), one went farther (0.12 to 0.43 px), none was
/// lost and one wild marker was found anew; 0.2 brought 18 closer but
/// moved two corners from 1.13 to 2.29 px and from 0.37 to 2.23 px off;
/// 0.35 brought 7 closer and left two of those rough detections.
const OFF_SIDE_CELLS: f64 = 0.25;

/// Outer rounds: measure the edges along the current homography, then fit.
const MEASURE_ROUNDS: usize = 4;
/// Reweighted least-squares steps per round.
const FIT_STEPS: usize = 3;
/// Tukey biweight cut-off, in robust standard deviations (95% efficiency
/// for normal noise).
const TUKEY_C: f64 = 4.685;
/// Median absolute residual to standard deviation, for normal noise.
const MAD_TO_SIGMA: f64 = 1.4826;
/// Smallest robust scale (px): edge points closer than this to the model
/// are never down-weighted.
const MIN_SCALE_PX: f64 = 0.15;
/// The fit stops when no corner moved more than this (px) in a round.
const CONVERGED_PX: f64 = 0.02;

/// Fewest weighted edge points a fit needs (8 unknowns, and some to
/// spare to judge them).
const MIN_POINTS: usize = 16;

/// A corner is supported by the inlier edge points on each of its two
/// sides within this distance of it (tag units, the side is 1) ...
const SUPPORT_REACH: f64 = 0.3;
/// ... when each side has at least this many.
const MIN_SUPPORT: usize = 2;
/// An edge point with at least this biweight is an inlier.
const INLIER_WEIGHT: f64 = 0.5;

/// Floor of the reported corner uncertainty (px): edge positions of a
/// blurred, pixelated image carry a bias of about this much that no
/// residual shows. Set from the wild benchmark's measured corners (median
/// error 0.11 px once deblurred readings of defocused tags came in; with a
/// 0.1 px floor 88% of corners were within 2 sigma, with 0.12 px 93%), so
/// that share is not an independent check of this constant.
const SIGMA_FLOOR_PX: f64 = 0.12;

/// Corner uncertainty (px) per px of the edges' measured blur (sigma),
/// when it exceeds [`SIGMA_FLOOR_PX`]: the edges of a blurred tag are
/// located with a bias that grows with the blur (the white margin is one
/// cell wide, so its level sinks and the half-level crossing moves) and
/// that no residual shows. (Most of that bias is now taken off the sides,
/// see `edge_bias`; this term was kept as it was calibrated before, and
/// covers what the model of the side leaves.) On the wild set the median corner error of
/// fitted tags grew from 0.08 px on sharp tags to 0.5-0.8 px at a blur of
/// 1.5-2 px while the fit's own sigma stayed at 0.2-0.3 px. Chosen on a
/// calibration set apart from the benchmark (the wild set's ranges with
/// seed 7 instead of 2026, 1000 scenes: `make calibrate-sigma`), together
/// with `decoding::LIKELIHOOD_SIGMA_FACTOR`, so that the corners of tags
/// read by the code, of tags read by likelihood and all corners each lie
/// within 2 sigma of the truth at least 90% of the time: with 0.2 they do
/// 93.0%, 91.9% and 92.8%; with 0.15 91%, 86% and 90%. Estimated corners
/// stay below (87%).
const BLUR_BIAS: f64 = 0.2;

/// A fit whose four sides' blurs (each side's median edge width, as a
/// Gaussian sigma in px) differ by more than this (px) is taken for a tag
/// smeared by motion, and gets the smear's sigma floor
/// (`decoding::SMEAR_SIGMA_OF_SIDE`) as if a reading of the blur model had
/// confirmed it (`Verified::smeared`). A smear widens the two sides across
/// it and leaves the two along it sharp: the corner sigma's blur term takes
/// the median width of all sides (`BLUR_BIAS`), which a smear leaves at the
/// sharp sides', and a tag smeared 10 px but confirmed by the plain
/// likelihood reading had its corners reported at sigma 0.26 px, 4.8 px
/// off. A defocused tag blurs its four sides alike, and no sides differ
/// under motion at 45 degrees to them, where the median does see the
/// smear. Chosen on the dense calibration set
/// (`datasets/wild/calibration/coppertag-dense-calib.toml`, `make
/// calibrate-sigma`; the VGA calibration set never blurs its tags enough
/// to reach it) as the largest limit on a 0.25 px grid that puts more
/// than 95% of the corners of tags drawn with a motion blur of 3.6 px or
/// more within 2 sigma of the truth (the split `make calibrate-sigma`
/// prints): without it 91.8% (all corners 96.2%); 2.0 px 94.6%, 1.75 px
/// 95.1% (all 97.3%), 1.5 px 95.5%, 1.0 px 97.1%. From 1.0 to 2.0 px it
/// drops one of the set's 1127 markers found (a ct8 tag smeared 13 px
/// whose hidden corner, 0.27 px sure before, now has a sigma over the last
/// resorts' bound, `decoding::LAST_RESORT_SIGMA_PX`), at 0.75 px three.
/// The VGA calibration set is unchanged.
const SMEAR_SPREAD_PX: f64 = 1.75;

/// Step of the numerical derivative of the homography's mapping along an
/// edge (tag units).
const EPS: f64 = 1e-4;

/// One point of a model edge, in tag units.
#[derive(Debug, Clone, Copy)]
struct EdgePoint {
    /// Position.
    u: [f64; 2],
    /// Unit normal, from the white side to the black side.
    n: [f64; 2],
    /// Which data-square side (0..4, side `k` from corner `k` to `k + 1`)
    /// the point lies on; `None` for a cell edge.
    side: Option<usize>,
}

/// An edge point measured in the image.
#[derive(Debug, Clone, Copy)]
struct Measured {
    /// The model point.
    m: EdgePoint,
    /// Image position of the edge (px).
    x: [f64; 2],
    /// Image normal (unit).
    n: [f64; 2],
    /// Width of the edge's rise (px): the distance between where the
    /// profile crosses a quarter and three quarters of its step.
    width: f64,
}

/// The decoded tag's appearance inside its frame.
struct Model {
    /// Cell grid side.
    grid: usize,
    /// Cells, row-major, `true` = black; cells under the checker are black.
    black: Vec<bool>,
    /// Cells that are not under the checker.
    free: Vec<bool>,
    /// How many cells are not under the checker.
    free_cells: usize,
    /// Half side of the checker square and radius of its disc (tag units).
    checker: (f64, f64),
    /// Edge points of the four sides.
    sides: Vec<EdgePoint>,
    /// Edge points between cells of different colours.
    cells: Vec<EdgePoint>,
}

impl Model {
    fn new(family: &Family, id: u64) -> Option<Self> {
        let n = family.grid();
        let mut black = encode_cells(family, id).ok()?;
        let free: Vec<bool> = (0..n * n).map(|c| !family.is_covered(c)).collect();
        for (b, f) in black.iter_mut().zip(&free) {
            if !f {
                *b = true;
            }
        }
        let step = 1.0 / (n as f64 + 2.0);
        let k = family.checker_cells() as f64 * step;
        let free_cells = free.iter().filter(|&&f| f).count();
        let mut m = Self {
            grid: n,
            black,
            free,
            free_cells,
            checker: (k / 2.0, k / 3.0),
            sides: Vec::new(),
            cells: Vec::new(),
        };
        m.edges(step);
        Some(m)
    }

    /// Whether tag point `p` is black, inside the frame's inner band.
    fn is_black(&self, p: [f64; 2]) -> bool {
        let [u, v] = p;
        if u.abs() > 0.5 || v.abs() > 0.5 {
            return true;
        }
        let (half, r) = self.checker;
        if u.abs() < half && v.abs() < half {
            return u * u + v * v >= r * r;
        }
        let n = self.grid;
        let step = 1.0 / (n as f64 + 2.0);
        let col = ((u + 0.5) / step).floor() as i64 - 1;
        let row = ((v + 0.5) / step).floor() as i64 - 1;
        if col < 0 || row < 0 || col >= n as i64 || row >= n as i64 {
            return false;
        }
        self.black[row as usize * n + col as usize]
    }

    /// Edge points on the cell lattice: two per cell along each side (none
    /// in the half cell at a corner, where blur rounds it), one per cell
    /// edge between a black and a white cell.
    fn edges(&mut self, step: f64) {
        let lines = self.grid + 2;
        let e = step * 1e-3;
        for vertical in [true, false] {
            for a in 0..=lines {
                let c = -0.5 + a as f64 * step;
                for b in 0..lines {
                    let s0 = -0.5 + b as f64 * step;
                    let at = |s: f64, off: f64| if vertical { [c + off, s] } else { [s, c + off] };
                    let mid = s0 + 0.5 * step;
                    let (before, after) = (self.is_black(at(mid, -e)), self.is_black(at(mid, e)));
                    if before == after {
                        continue;
                    }
                    let sgn = if after { 1.0 } else { -1.0 };
                    let n = if vertical { [sgn, 0.0] } else { [0.0, sgn] };
                    let side = match (vertical, a) {
                        (true, 0) => Some(0),
                        (false, a) if a == lines => Some(1),
                        (true, a) if a == lines => Some(2),
                        (false, 0) => Some(3),
                        _ => None,
                    };
                    if side.is_some() {
                        for t in [0.25, 0.75] {
                            let first = b == 0 && t < 0.5;
                            let last = b + 1 == lines && t > 0.5;
                            if !(first || last) {
                                self.sides.push(EdgePoint {
                                    u: at(s0 + t * step, 0.0),
                                    n,
                                    side,
                                });
                            }
                        }
                    } else {
                        self.cells.push(EdgePoint {
                            u: at(mid, 0.0),
                            n,
                            side,
                        });
                    }
                }
            }
        }
    }

    /// Cells that agree with the code when sampled at their centres
    /// through `h`, thresholded at `level`.
    fn agreement(&self, img: &GrayView<'_>, h: &Homography, level: f64) -> usize {
        self.agreement_over(img, h, level, None).unwrap_or(0)
    }

    /// [`Model::agreement`] where, with a `bar`, only an agreement above
    /// it counts: that agreement, or `None` once the cells left to sample
    /// could not lift it above `bar` (every cell left agreeing). Without a
    /// bar, the agreement itself.
    ///
    /// Why: [`best_shift`] takes a shift only for an agreement above its
    /// best so far, and most shifts of a side fall well short; sampling
    /// every cell of each was most of its cost. The cells are sampled and
    /// counted alike either way, so an agreement above `bar` is the same
    /// number.
    fn agreement_over(
        &self,
        img: &GrayView<'_>,
        h: &Homography,
        level: f64,
        bar: Option<usize>,
    ) -> Option<usize> {
        let n = self.grid;
        let step = 1.0 / (n as f64 + 2.0);
        let mut agree = 0;
        let mut left = self.free_cells;
        for (c, (&b, &f)) in self.black.iter().zip(&self.free).enumerate() {
            if !f {
                continue;
            }
            if bar.is_some_and(|bar| agree + left <= bar) {
                return None;
            }
            left -= 1;
            let u = -0.5 + (1.5 + (c % n) as f64) * step;
            let v = -0.5 + (1.5 + (c / n) as f64) * step;
            let Some(s) = h.map([u, v]).and_then(|p| sample_bilinear(img, p[0], p[1])) else {
                continue;
            };
            if (s < level) == b {
                agree += 1;
            }
        }
        bar.is_none_or(|bar| agree > bar).then_some(agree)
    }

    /// Grey level halfway between the cells the code says are white and
    /// those it says are black, sampled through `h`.
    fn level(&self, img: &GrayView<'_>, h: &Homography) -> Option<f64> {
        let n = self.grid;
        let step = 1.0 / (n as f64 + 2.0);
        let (mut w, mut b) = (Vec::new(), Vec::new());
        for (c, (&blk, &f)) in self.black.iter().zip(&self.free).enumerate() {
            if !f {
                continue;
            }
            let u = -0.5 + (1.5 + (c % n) as f64) * step;
            let v = -0.5 + (1.5 + (c / n) as f64) * step;
            if let Some(s) = h.map([u, v]).and_then(|p| sample_bilinear(img, p[0], p[1])) {
                if blk {
                    b.push(s)
                } else {
                    w.push(s)
                }
            }
        }
        Some(0.5 * (median(&mut w)? + median(&mut b)?))
    }
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(v[mid])
}

/// A reading's geometry after verification.
#[derive(Debug, Clone)]
pub(crate) struct Verified {
    /// Corners TL, BL, BR, TR (px).
    pub corners: [[f64; 2]; 4],
    /// Which corners no visible edge supports.
    pub unsupported: [bool; 4],
    /// One-sigma uncertainty of each corner's position (px, radial).
    pub sigma: [f64; 4],
    /// Tag units to pixels.
    pub homography: Homography,
    /// Smeared by motion (see `decoding::SMEAR_SIGMA_OF_SIDE`): confirmed
    /// by a reading of the blur model, or with sides blurred as a smear's
    /// are ([`SMEAR_SPREAD_PX`]).
    pub smeared: bool,
}

/// What verification concluded about a reading.
#[derive(Debug, Clone)]
pub(crate) enum Verdict {
    /// The model fitted; take its geometry.
    Fitted(Verified),
    /// Too few edges to fit (a tiny or mostly hidden tag): the reading
    /// stands as it is.
    Unfit,
    /// The fitted geometry no longer reads as this tag: drop the reading.
    /// Carries the free fit's geometry when there was one: a likelihood
    /// reading whose fit keeps its corners may still stand (see
    /// `decoding::verify_one`).
    Contradicted(Option<Verified>),
}

/// Verifies the reading `id` of `family` whose corners (TL, BL, BR, TR,
/// canonical) are `corners`, whose white-to-black contrast is `contrast`
/// and which needed `corrected` Reed-Solomon corrections; `kind`, the
/// readings of the fitted geometry that may confirm it besides the code's
/// and the blur model's ([`Confirming`]).
/// `held`: whether a free fit that contradicts the reading gets a second
/// one held near the reading's geometry ([`PRIOR_SIGMA_CELLS`]). A code
/// reading near the code's limit gets none: held near its own quad, its
/// fit re-reads the cells that quad read, and confirms nothing. On the
/// wild set, such a reading (11 symbols corrected) under a white triangle
/// was read through a quad whose hidden corner lay 15 px off, along the
/// triangle's edge, and was held there once blurred sides were measured
/// without bias (its free fit moved the corner by a pixel and no longer
/// read); the second fits of 12 right readings with 8-10 corrections were
/// lost with it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn verify(
    img: &GrayView<'_>,
    family: &Family,
    id: u64,
    corners: &[[f64; 2]; 4],
    contrast: f64,
    corrected: usize,
    kind: Confirming,
    held: bool,
    decode: &DecodeParams,
) -> Verdict {
    let Some(model) = Model::new(family, id) else {
        return Verdict::Unfit;
    };
    let Some(h0) = Homography::from_points(&CORNERS, corners) else {
        return Verdict::Unfit;
    };
    let cell = cell_px(corners, model.grid);
    // A clean reading has every cell right already: no shift can win
    // cells, so the search (most of this stage's time) is skipped.
    let (h1, shifted) = if corrected > 0 && cell > MIN_SHIFT_CELL_PX {
        best_shift(img, &model, &h0)
    } else {
        (h0, false)
    };
    let fit_from = |h: &Homography, how| fit_model(img, &model, h, cell, contrast, how);
    let check_fit = |f: &Fit| check(img, family, id, f, decode, kind);
    // Where the sides alone do not fit a small tag, a second try with the
    // cell edges (see `MIN_CELL_EDGE_PX`).
    let (fit, second_try) = match fit_from(&h1, FitHow::default()) {
        Some(fit) => (fit, false),
        // The shifted quad stands on the cells alone; it must read.
        None if shifted => return check_fit(&Fit::unfitted(h1)),
        None if cell >= MIN_CELL_EDGE_PX => return Verdict::Unfit,
        None => match fit_from(
            &h1,
            FitHow {
                cell_edges: true,
                ..FitHow::default()
            },
        ) {
            Some(fit) => (fit, true),
            None => return Verdict::Unfit,
        },
    };
    // A side that is an occluder's edge gets no vote (`OFF_SIDE_CELLS`),
    // where the fit without it still reads and the corners off that side
    // are seen: without them, and without the side, the cells alone hold
    // the tag (partly hidden themselves, on the ct8 twin they moved a
    // hidden corner 7 px off along a diagonal occluder, and still read).
    let beside = |k: usize| !fit.unsupported[(k + 2) % 4] && !fit.unsupported[(k + 3) % 4];
    if let Some(k) = fit.off_side.filter(|&k| beside(k)) {
        let how = FitHow {
            without: Some(k),
            ..FitHow::default()
        };
        if let Some(f) = fit_from(&fit.h, how) {
            let v = check_fit(&f);
            if matches!(v, Verdict::Fitted(_)) {
                return v;
            }
        }
    }
    let verdict = check_fit(&fit);
    // A second try gets no held fit: a reading it contradicts stands or
    // falls as one its fit contradicts on a tag whose cells are too small
    // for their edges (`decoding::small_cells`), as if unfit.
    if second_try || !held || !matches!(verdict, Verdict::Contradicted(_)) {
        return verdict;
    }
    let free = map4(&fit.h).map(|corners| Verified {
        corners,
        unsupported: fit.unsupported,
        sigma: fit.sigma,
        homography: fit.h,
        smeared: fit.smeared,
    });
    // The free fit may have crept off along a direction the visible
    // edges leave free: once more, held near the reading's geometry.
    let Some(held) = fit_from(
        &h1,
        FitHow {
            prior: Some(PRIOR_SIGMA_CELLS),
            ..FitHow::default()
        },
    ) else {
        return Verdict::Contradicted(free);
    };
    match check_fit(&held) {
        Verdict::Contradicted(_) => Verdict::Contradicted(free),
        v => v,
    }
}

/// Which readings of a fitted geometry may confirm a reading, besides
/// those by the code and by the blur model at a plausible contrast.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Confirming {
    /// By the nearest codeword ([`crate::nearest`]): for a reading made
    /// so (an occluded tag).
    pub nearest: bool,
    /// A faint one (`crate::decode::QuadReading::faint`): for a faint
    /// reading. Any other reading is confirmed only as it would have been
    /// without faint readings, whose geometry is less sure.
    pub faint: bool,
    /// By the nearest codeword on cells levelled under glare
    /// (`crate::decode::QuadReading::glared`): for a reading made so.
    /// Tried for any other, it would confirm fitted corners that the
    /// other readings refuse.
    pub glared: bool,
    /// The reading family's correction limit (`decoding::Target`): a
    /// reading of another id past it is no reading of the fitted geometry,
    /// and does not contradict (see [`check`]).
    pub limit: usize,
}

/// The verdict on the geometry of `fit`: it must still decode to `id`, by
/// the readings `kind` allows.
///
/// The geometry is read with no limit on the corrections, so that a
/// reading of `id` resting on erasures confirms it. But the readings are
/// tried in turn and the first that decodes is taken: past the limit, the
/// code's erasures can decode another id first (with 18 symbols
/// corrected, say) where a later reading, within the limit, gives `id`. A
/// reading of another id is therefore taken only within the family's
/// limit ([`Confirming::limit`]), as a detection takes it: on the wild
/// set a tag under a stick, read with 9 corrections and fitted within
/// 0.3 px of its true corners, was dropped because its fit read as
/// another id with 18.
fn check(
    img: &GrayView<'_>,
    family: &Family,
    id: u64,
    fit: &Fit,
    decode: &DecodeParams,
    kind: Confirming,
) -> Verdict {
    let Some(corners) = map4(&fit.h) else {
        return Verdict::Contradicted(None);
    };
    let read = |limit| {
        let accept = Accept {
            nearest: kind.nearest,
            limit,
            smeared: true,
            promising: Promising::AlignOrSmear,
            glared: kind.glared,
        };
        decode_quad_by(img, family, &corners, decode, accept)
    };
    let reads_id = |r: &QuadReading| r.id == id && r.rotation.is_multiple_of(4);
    let reading = match read(None) {
        Some(r) if !reads_id(&r) => read(Some(kind.limit)),
        r => r,
    };
    match reading {
        Some(r) if reads_id(&r) && (kind.faint || !r.faint) => Verdict::Fitted(Verified {
            corners,
            unsupported: fit.unsupported,
            sigma: fit.sigma,
            homography: fit.h,
            smeared: r.smeared || fit.smeared,
        }),
        _ => Verdict::Contradicted(None),
    }
}

/// The four corners of the data square through `h`.
fn map4(h: &Homography) -> Option<[[f64; 2]; 4]> {
    let c = CORNERS.map(|p| h.map(p));
    Some([c[0]?, c[1]?, c[2]?, c[3]?])
}

/// `h` with the data square's side `k` moved outwards by `d` (tag units;
/// negative moves it inwards): the homography of the quad whose corners
/// are the moved square's, mapped through `h`.
fn with_side_moved(h: &Homography, k: usize, d: f64) -> Option<Homography> {
    let mut q = CORNERS;
    // Side k runs from corner k to corner k + 1.
    let (a, b) = (k, (k + 1) % 4);
    let out = match k {
        0 => [-d, 0.0],
        1 => [0.0, d],
        2 => [d, 0.0],
        _ => [0.0, -d],
    };
    for i in [a, b] {
        q[i] = [q[i][0] + out[0], q[i][1] + out[1]];
    }
    let img = [h.map(q[0])?, h.map(q[1])?, h.map(q[2])?, h.map(q[3])?];
    Homography::from_points(&CORNERS, &img)
}

/// The side shift whose cells agree best with the code, if it beats the
/// reading's own quad by [`MIN_SHIFT_GAIN`] cells.
fn best_shift(img: &GrayView<'_>, model: &Model, h: &Homography) -> (Homography, bool) {
    let Some(level) = model.level(img, h) else {
        return (*h, false);
    };
    let step = 1.0 / (model.grid as f64 + 2.0);
    let mut best = (model.agreement(img, h, level), *h);
    let base = best.0;
    let steps = (MAX_SHIFT_SIDE / (SHIFT_STEP_CELLS * step)).floor() as i32;
    // The agreement at shift `s` of side `k`, if it lies above `bar`
    // (any, with none): a shift at or below the bars the search compares
    // it with changes nothing (`Model::agreement_over`).
    let agreement_at = |k: usize, s: i32, bar: Option<usize>| {
        let d = f64::from(s) * SHIFT_STEP_CELLS * step;
        let hs = with_side_moved(h, k, d)?;
        Some((model.agreement_over(img, &hs, level, bar)?, hs))
    };
    for k in 0..4 {
        // Coarse to fine: every COARSE_SHIFT_STEPS-th shift, then the
        // shifts around the best of them (agreement changes smoothly with
        // the shift; a shift of a cell or more moves many cells).
        let mut side_best: Option<(usize, i32)> = None;
        for s in (-steps..=steps).filter(|s| *s != 0 && s % COARSE_SHIFT_STEPS == 0) {
            // Counted only above the side's best and the best so far.
            let bar = side_best.map(|(b, _)| b.min(best.0));
            if let Some((a, hs)) = agreement_at(k, s, bar) {
                if side_best.is_none_or(|(b, _)| a > b) {
                    side_best = Some((a, s));
                }
                if a > best.0 {
                    best = (a, hs);
                }
            }
        }
        let Some((_, s0)) = side_best else {
            continue;
        };
        for s in (s0 - COARSE_SHIFT_STEPS + 1)..(s0 + COARSE_SHIFT_STEPS) {
            if s == 0 || s == s0 || s.abs() > steps {
                continue;
            }
            if let Some((a, hs)) = agreement_at(k, s, Some(best.0)) {
                if a > best.0 {
                    best = (a, hs);
                }
            }
        }
    }
    if best.0 >= base + MIN_SHIFT_GAIN {
        (best.1, true)
    } else {
        (*h, false)
    }
}

/// A fitted homography and what the fit says about its corners.
struct Fit {
    h: Homography,
    unsupported: [bool; 4],
    sigma: [f64; 4],
    /// The side whose edge points, as a whole, lie off where the rest of
    /// the model puts them ([`OFF_SIDE_CELLS`]), if any.
    off_side: Option<usize>,
    /// Whether the sides' blurs differ as a smear's do
    /// ([`SMEAR_SPREAD_PX`]).
    smeared: bool,
}

impl Fit {
    /// A geometry that stands without a fit: no corner unsupported, no
    /// sigma.
    fn unfitted(h: Homography) -> Self {
        Self {
            h,
            unsupported: [false; 4],
            sigma: [f64::NAN; 4],
            off_side: None,
            smeared: false,
        }
    }
}

/// How [`fit_model`] fits.
#[derive(Clone, Copy, Default)]
struct FitHow {
    /// Each corner held near where the start puts it, by this many cells'
    /// standard deviation ([`PRIOR_SIGMA_CELLS`]).
    prior: Option<f64>,
    /// Measure the cell edges whatever their size.
    cell_edges: bool,
    /// A side whose points get no vote: an occluder's edge along it
    /// ([`OFF_SIDE_CELLS`]). The cell edges are measured then.
    without: Option<usize>,
}

/// Image-normalising similarity: centre `c`, scale `s` (px per unit).
#[derive(Clone, Copy)]
struct Norm {
    c: [f64; 2],
    s: f64,
}

impl Norm {
    fn to(&self, x: [f64; 2]) -> [f64; 2] {
        [(x[0] - self.c[0]) / self.s, (x[1] - self.c[1]) / self.s]
    }
    fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            1.0 / self.s,
            0.0,
            -self.c[0] / self.s,
            0.0,
            1.0 / self.s,
            -self.c[1] / self.s,
            0.0,
            0.0,
            1.0,
        )
    }
    fn inverse(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.s, 0.0, self.c[0], 0.0, self.s, self.c[1], 0.0, 0.0, 1.0,
        )
    }
}

/// The 8 parameters of a homography normalised to `m[2][2] = 1`.
type Params = SVector<f64, 8>;

fn params(m: &Matrix3<f64>) -> Option<Params> {
    free_entries(m).map(|e| Params::from_column_slice(&e))
}

fn matrix(p: &Params) -> Matrix3<f64> {
    Matrix3::new(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], 1.0)
}

/// Image of `u` under the parameters `p`, and its 2 x 8 Jacobian.
fn project(p: &Params, u: [f64; 2]) -> Option<([f64; 2], SMatrix<f64, 2, 8>)> {
    let w = p[6] * u[0] + p[7] * u[1] + 1.0;
    if w.abs() < 1e-9 {
        return None;
    }
    let x = (p[0] * u[0] + p[1] * u[1] + p[2]) / w;
    let y = (p[3] * u[0] + p[4] * u[1] + p[5]) / w;
    let (a, b) = (u[0] / w, u[1] / w);
    let j = SMatrix::<f64, 2, 8>::from_row_slice(&[
        a,
        b,
        1.0 / w,
        0.0,
        0.0,
        0.0,
        -x * a,
        -x * b,
        0.0,
        0.0,
        0.0,
        a,
        b,
        1.0 / w,
        -y * a,
        -y * b,
    ]);
    Some(([x, y], j))
}

/// Measures one model edge point through `h`: the image edge nearest to
/// its predicted position along the image normal, if the profile there
/// shows the edge's contrast.
fn measure(
    img: &GrayView<'_>,
    h: &Homography,
    m: &EdgePoint,
    window: f64,
    min_contrast: f64,
    prof: &mut Vec<f64>,
) -> Option<Measured> {
    let p = h.map(m.u)?;
    let t = [-m.n[1], m.n[0]];
    let a = h.map([m.u[0] - EPS * t[0], m.u[1] - EPS * t[1]])?;
    let b = h.map([m.u[0] + EPS * t[0], m.u[1] + EPS * t[1]])?;
    let tang = sub(b, a);
    let len = norm(tang);
    if len < 1e-12 {
        return None;
    }
    let mut n = [-tang[1] / len, tang[0] / len];
    let toward = sub(h.map([m.u[0] + EPS * m.n[0], m.u[1] + EPS * m.n[1]])?, p);
    if dot(n, toward) < 0.0 {
        n = [-n[0], -n[1]];
    }
    let step = profile_step(window);
    let k = (window / step).round() as i32;
    prof.clear();
    if !sample_profile(img, p, n, step, (-k, k), prof) {
        return None;
    }
    let (white, black) = edge_bias::levels(prof, k as usize);
    if white - black < min_contrast {
        return None;
    }
    let (off, _) = edge_bias::falling_crossing(prof, 0.5 * (white + black), k as usize, step)?;
    Some(Measured {
        m: *m,
        x: [p[0] + off * n[0], p[1] + off * n[1]],
        n,
        width: edge_bias::rise_width(prof, black, white - black, off / step + f64::from(k)) * step,
    })
}

/// Sampling step (px) of a profile across an edge, for a half-window of
/// `window` px.
fn profile_step(window: f64) -> f64 {
    (window / WINDOW_SAMPLES).max(MIN_PROFILE_STEP)
}

/// How far (px) each data-square side's points in `meas` lie outwards of
/// the printed edge: the blur bias of their half-level crossing
/// ([`edge_bias`]), the blur taken from the median rise of that side's
/// points (a moving camera blurs the sides across its motion only).
/// `cell` is the tag's cell (px), the margin's width.
fn blur_bias(meas: &[Measured], cell: f64, ruler: &Ruler) -> [f64; 4] {
    let mut bias = [0.0; 4];
    let Some(table) = BlurBias::new(cell, ruler, ruler) else {
        return bias;
    };
    let mut widths = Vec::new();
    for (k, b) in bias.iter_mut().enumerate() {
        widths.clear();
        widths.extend(meas.iter().filter(|q| q.m.side == Some(k)).map(|q| q.width));
        if let Some(width) = median(&mut widths) {
            *b = table.at(width);
        }
    }
    bias
}

/// Robust fit of the model's edges (the data square's sides, and its cell
/// edges where [`MIN_CELL_EDGE_PX`] says, or as `how` says), starting at
/// `h0`; with a prior (cells, see [`PRIOR_SIGMA_CELLS`]) each corner is
/// also held near where `h0` puts it, by that standard deviation against
/// the edges' robust one.
fn fit_model(
    img: &GrayView<'_>,
    model: &Model,
    h0: &Homography,
    cell: f64,
    contrast: f64,
    how: FitHow,
) -> Option<Fit> {
    let corners0 = map4(h0)?;
    let c = centroid(&corners0);
    let s = (cell * (model.grid as f64 + 2.0)).max(1.0);
    let nm = Norm { c, s };
    let mut p = params(&(nm.matrix() * h0.matrix()))?;
    let window = (WINDOW_CELLS * cell).clamp(WINDOW_PX.0, WINDOW_PX.1);
    let min_contrast = (MIN_CONTRAST_FRACTION * contrast).max(super::refine::MIN_EDGE_CONTRAST);
    let mut use_cells = how.cell_edges || how.without.is_some() || cell >= MIN_CELL_EDGE_PX;
    let ruler = Ruler {
        white: window,
        black: window,
        step: profile_step(window),
    };
    let mut prof = Vec::new();
    let mut side_bias = None;
    let mut meas: Vec<Measured> = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut scale;
    let mut a_mat = SMatrix::<f64, 8, 8>::zeros();
    for _ in 0..MEASURE_ROUNDS {
        let h = Homography::from_matrix(nm.inverse() * matrix(&p));
        let before = map4(&h)?;
        meas.clear();
        let mut measure_all = |points: &mut dyn Iterator<Item = &EdgePoint>, meas: &mut Vec<_>| {
            for m in points {
                if let Some(x) = measure(img, &h, m, window, min_contrast, &mut prof) {
                    meas.push(Measured { x: nm.to(x.x), ..x });
                }
            }
        };
        measure_all(
            &mut model.sides.iter().filter(|m| m.side != how.without),
            &mut meas,
        );
        if side_bias.is_none() && !use_cells {
            let seen = |k: usize| meas.iter().filter(|q| q.m.side == Some(k)).count();
            use_cells = (0..4).any(|k| seen(k) < MIN_SIDE_POINTS);
        }
        if use_cells {
            let stride = model.cells.len().div_ceil(MAX_CELL_POINTS).max(1);
            measure_all(&mut model.cells.iter().step_by(stride), &mut meas);
        }
        if meas.len() < MIN_POINTS {
            return None;
        }
        // The blur of each side, from the first round's profiles (later
        // rounds measure the same edges a little closer).
        let bias = *side_bias.get_or_insert_with(|| blur_bias(&meas, cell, &ruler));
        for q in &mut meas {
            if let Some(k) = q.m.side {
                let b = bias[k] / s;
                q.x = [q.x[0] - b * q.n[0], q.x[1] - b * q.n[1]];
            }
        }
        for _ in 0..FIT_STEPS {
            let rows: Vec<Option<(Row, f64)>> = meas.iter().map(|q| edge_row(&p, q)).collect();
            let res: Vec<f64> = rows
                .iter()
                .map(|row| row.map_or(f64::INFINITY, |(_, r)| r))
                .collect();
            let mut abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
            scale = (MAD_TO_SIGMA * median(&mut abs)?).max(MIN_SCALE_PX / s);
            weights = res.iter().map(|r| tukey(r / scale)).collect();
            let mut g = Params::zeros();
            a_mat = SMatrix::<f64, 8, 8>::zeros();
            for ((row, r), w) in rows.iter().zip(&res).zip(&weights) {
                if *w <= 0.0 {
                    continue;
                }
                let (row, _) = (*row)?;
                a_mat += *w * row.transpose() * row;
                g += *w * *r * row.transpose();
            }
            if let Some(cells) = how.prior {
                // Each corner's two coordinates as observations of where
                // `h0` put it, weighted as the edges are (in robust
                // standard deviations: `scale` is theirs).
                let w = (scale * s / (cells * cell)).powi(2);
                for (k, c0) in corners0.iter().enumerate() {
                    let (x, j) = project(&p, CORNERS[k])?;
                    let c0 = nm.to(*c0);
                    for a in 0..2 {
                        let row = j.row(a);
                        a_mat += w * row.transpose() * row;
                        g += w * (x[a] - c0[a]) * row.transpose();
                    }
                }
            }
            let delta = a_mat.lu().solve(&g)?;
            p -= delta;
        }
        let h = Homography::from_matrix(nm.inverse() * matrix(&p));
        let after = map4(&h)?;
        let moved = (0..4)
            .map(|k| norm(sub(after[k], before[k])))
            .fold(0.0, f64::max);
        if moved < CONVERGED_PX {
            break;
        }
    }
    if weights.iter().filter(|&&w| w >= INLIER_WEIGHT).count() < MIN_POINTS {
        return None;
    }
    let h = Homography::from_matrix(nm.inverse() * matrix(&p));
    // Support: inliers on both sides near each corner.
    let mut unsupported = [false; 4];
    for (k, flag) in unsupported.iter_mut().enumerate() {
        let corner = CORNERS[k];
        let near = |side: usize| {
            meas.iter()
                .zip(&weights)
                .filter(|(q, w)| {
                    **w >= INLIER_WEIGHT
                        && q.m.side == Some(side)
                        && norm(sub(q.m.u, corner)) <= SUPPORT_REACH
                })
                .count()
        };
        *flag = near((k + 3) % 4) < MIN_SUPPORT || near(k) < MIN_SUPPORT;
    }
    // Covariance of the parameters: residual variance over the weighted
    // normal matrix; propagated to each corner (px).
    let rows: Vec<Option<(Row, f64)>> = meas.iter().map(|q| edge_row(&p, q)).collect();
    let (mut rss, mut wsum) = (0.0, 0.0);
    for (row, w) in rows.iter().zip(&weights) {
        if let Some((_, r)) = row {
            rss += w * r * r;
            wsum += w;
        }
    }
    let var = rss / (wsum - 8.0).max(1.0);
    let cov = a_mat.try_inverse()? * var;
    // The edges' blur, from the width of their rise (a Gaussian edge of
    // sigma b rises from a quarter to three quarters over 1.349 b).
    let mut widths: Vec<f64> = meas
        .iter()
        .zip(&weights)
        .filter(|(_, w)| **w >= INLIER_WEIGHT)
        .map(|(q, _)| q.width)
        .collect();
    let blur = median(&mut widths).unwrap_or(0.0) / GAUSS_QUARTILE_SPAN;
    let floor = SIGMA_FLOOR_PX.max(BLUR_BIAS * blur);
    let smeared = sides_blur_spread(&meas, &weights, model.sides.len() / 4) > SMEAR_SPREAD_PX;
    let mut sigma = [0.0; 4];
    for (k, sg) in sigma.iter_mut().enumerate() {
        let (_, j) = project(&p, CORNERS[k])?;
        let cc = j * cov * j.transpose();
        let radial = (cc[(0, 0)] + cc[(1, 1)]).max(0.0).sqrt() * s;
        *sg = radial.hypot(floor);
    }
    let off_side = match how.without {
        None if use_cells && how.prior.is_none() => {
            off_side(&meas, &rows, &weights, cell / s, model.sides.len() / 4)
        }
        _ => None,
    };
    Some(Fit {
        h,
        unsupported,
        sigma,
        off_side,
        smeared,
    })
}

/// How much the blurs of the data square's sides differ (px, as Gaussian
/// sigmas): the largest of the sides' median edge widths less the
/// smallest, over the sides with inlier edge points at at least half their
/// `points` model points (as [`off_side`] judges a side); 0 with fewer
/// than two such sides. Why half: a side an occluder cuts short keeps a
/// few points beside the occluder's own blurred edge, whose widths are not
/// the side's (on the robustness set, 4 of its 1750 unblurred frames
/// were taken for smeared without this).
fn sides_blur_spread(meas: &[Measured], weights: &[f64], points: usize) -> f64 {
    let mut per_side: [Vec<f64>; 4] = Default::default();
    for (q, w) in meas.iter().zip(weights) {
        if let (Some(k), true) = (q.m.side, *w >= INLIER_WEIGHT) {
            per_side[k].push(q.width / GAUSS_QUARTILE_SPAN);
        }
    }
    let blurs: Vec<f64> = per_side
        .iter_mut()
        .filter(|v| 2 * v.len() >= points)
        .filter_map(|v| median(v))
        .collect();
    if blurs.len() < 2 {
        return 0.0;
    }
    let (lo, hi) = blurs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &b| {
            (lo.min(b), hi.max(b))
        });
    hi - lo
}

/// The data-square side whose edge points `meas` (their rows and
/// residuals at the fit, `rows`, see [`edge_row`]; weights `weights`), as
/// a whole, lie off the line the rest of the fit puts them on, further
/// than the other sides' by over [`OFF_SIDE_CELLS`] (`cell` is the cell
/// in the fit's units; a side is judged when at least half its `points`
/// model points were measured): the edge of an occluder flush along that
/// side, not the side. The worst such side, if any.
///
/// Why: a block or tape lying along a side, over part of the white margin,
/// shows an edge parallel to the side and inside it, as sharp as the
/// side's own and all along it. Each of its points agrees with the others,
/// so the robust weights keep them all, and the fit settles between them
/// and the cell edges, which put the side where it is: on the ct8 twin a
/// corner of such a tag was fitted 2.6 px off and claimed measured.
/// Leaving the side out is one linearised step from the converged fit
/// (the step is small: the cells outvote a side).
fn off_side(
    meas: &[Measured],
    rows: &[Option<(Row, f64)>],
    weights: &[f64],
    cell: f64,
    points: usize,
) -> Option<usize> {
    // Each side's median offset (cells) from the fit without it, and
    // whether enough of the side showed to judge it. The normal equations
    // without a side are the whole fit's less that side's own terms,
    // summed once per side (index 4: the cell edges).
    let mut sums = [(SMatrix::<f64, 8, 8>::zeros(), Params::zeros()); 5];
    for ((q, row), w) in meas.iter().zip(rows).zip(weights) {
        if let (Some((row, r)), true) = (row, *w > 0.0) {
            let (a, g) = &mut sums[q.m.side.map_or(4, |k| k.min(4))];
            *a += *w * row.transpose() * row;
            *g += *w * *r * row.transpose();
        }
    }
    let mut offsets = [(0.0, false); 4];
    for (k, o) in offsets.iter_mut().enumerate() {
        let (mut a, mut g) = (SMatrix::<f64, 8, 8>::zeros(), Params::zeros());
        for (j, (aj, gj)) in sums.iter().enumerate() {
            if j != k {
                a += aj;
                g += gj;
            }
        }
        let Some(delta) = a.lu().solve(&g) else {
            continue;
        };
        let mut off: Vec<f64> = meas
            .iter()
            .zip(rows)
            .filter(|(q, _)| q.m.side == Some(k))
            .filter_map(|(_, row)| row.map(|(row, r)| r - (row * delta)[0]))
            .collect();
        let seen = 2 * off.len() >= points;
        *o = (median(&mut off).map_or(0.0, |m| m.abs() / cell), seen);
    }
    let mut worst: Option<(usize, f64)> = None;
    for (k, &(m, seen)) in offsets.iter().enumerate() {
        let mut others: Vec<f64> = (0..4).filter(|&j| j != k).map(|j| offsets[j].0).collect();
        let excess = m - median(&mut others).unwrap_or(0.0);
        if seen && excess > OFF_SIDE_CELLS && worst.is_none_or(|(_, w)| excess > w) {
            worst = Some((k, excess));
        }
    }
    worst.map(|(k, _)| k)
}

/// One edge point's row of the fit's Jacobian, along its image normal.
type Row = SMatrix<f64, 1, 8>;

/// Edge point `q`'s [`Row`] at parameters `p` and its residual: how far
/// along the normal the model puts the edge beyond where it was measured.
fn edge_row(p: &Params, q: &Measured) -> Option<(Row, f64)> {
    let (x, j) = project(p, q.m.u)?;
    Some((q.n[0] * j.row(0) + q.n[1] * j.row(1), dot(q.n, sub(x, q.x))))
}

/// Tukey's biweight of a residual in robust standard deviations.
fn tukey(z: f64) -> f64 {
    let t = z / TUKEY_C;
    if t.abs() >= 1.0 {
        0.0
    } else {
        (1.0 - t * t).powi(2)
    }
}

//! Decoding a tag from four known corners.
//!
//! The data square is mapped into the image with a homography; every cell is
//! sampled over its central area; the black and white levels are measured on
//! the tag itself (the black frame just outside the data square and the
//! one-cell white margin just inside it), which is more robust than Otsu on
//! the cell samples alone: it works for grids that are nearly all black or
//! all white, and it tells how far each cell is from the threshold, so that
//! doubtful cells become Reed-Solomon erasures instead of errors.

use crate::deblur::deblur;
use crate::math::sample_bilinear;
use crate::view::GrayView;

use crate::family::Family;
use crate::geometry::{B, CORNERS};
use crate::grid_code::{decode_cells, encode_cells, rotate_cell, GridReading};
use crate::homography::{Homography, MIN_WEIGHT};
use crate::likelihood::{read_likely, read_likely_keeping, Codebook, LikelyFit};
use crate::motion::read_smeared;
use crate::nearest::{contradicts, read_nearest};
use crate::shaded::read_shaded;

/// A tag read from four corners.
#[derive(Debug, Clone, PartialEq)]
pub struct QuadReading {
    /// Decoded id.
    pub id: u64,
    /// Corners in canonical order TL, BL, BR, TR (pixel-centre coordinates).
    pub corners: [[f64; 2]; 4],
    /// Symbols the Reed-Solomon decoder corrected.
    pub corrected: usize,
    /// Symbols read as erasures (see [`crate::grid_code::GridReading`]).
    pub erased: usize,
    /// Symbols corrected that were not erased.
    pub errors: usize,
    /// Quarter turns between the corner list given and the canonical one.
    pub rotation: usize,
    /// Contrast between the measured white and black levels (0..255).
    pub contrast: f64,
    /// Read by likelihood: the cells were matched against every codeword,
    /// because the Reed-Solomon decoder could not read them (ct14 only):
    /// cell by cell for a tag whose hidden cells read confidently wrong
    /// (an ink-dark or paper-white occluder over a quarter or more of it),
    /// or as the blur shows each codeword (a small, blurred tag).
    /// `corrected` then counts the symbols a cell-by-cell reading got
    /// wrong, usually more than the code corrects.
    pub likelihood: bool,
    /// Read as under an occluder: a likelihood reading cell by cell, its
    /// misread cells confined to part of the grid (rather than as the blur
    /// shows each codeword), or a code reading under glare resting on more
    /// erasures than the family's limit (its glare-clipped cells erased).
    pub occluded: bool,
    /// Read as smeared by motion: a likelihood reading against codewords
    /// blurred along one direction (a tag moving during the exposure).
    /// The smear rounds the tag's corners off along it; the detector takes
    /// such a reading only from a quad whose four corners it measured.
    pub smeared: bool,
    /// Read by likelihood at a fitted contrast several times the one its
    /// frame and margin show: a tag blurred by more than about a cell, or
    /// one whose frame an occluder or glare covers, which may also have
    /// moved the quad. Its id is as sure as any likelihood reading's, its
    /// corners less so: the detector keeps such a reading only where the
    /// print's fixed look, aligned to the image, confirms them.
    pub faint: bool,
    /// Read by likelihood under a smooth light field fitted with each
    /// codeword, the cells the sensor clipped left out (a glare spot, a
    /// shadow's edge): the last of a quad's readings. A glare that washes
    /// out the frame also moves the quad's corners there, so such a
    /// reading is also `faint`, and the detector keeps it only where no
    /// other reading finds the tag.
    pub shaded: bool,
    /// Read at the levels of the clearer half of the frame and margin
    /// rings ([`clear_ring_levels`]): an occluder over part of the rings
    /// pulled their plain medians, the levels every other reading takes,
    /// together, and at them no reading of the quad read. Tried last, and
    /// the detector keeps such a reading only where no other reading finds
    /// the tag: its levels are a second guess that a rival quad of the
    /// same tag, read at them, could also pass.
    pub clear_ring: bool,
    /// Read by the nearest codeword ([`crate::nearest`]) on the cells
    /// levelled by their neighbours under a glare, the cells with no
    /// contrast around them left out ([`read_glare_nearest`]): a spot
    /// that clips half the square or more leaves too few whole symbols for
    /// the code, but enough cells for the codebook. A glare hides the
    /// corners under it too, so the detector keeps such a reading only
    /// with every corner seen, and only where no other reading finds the
    /// tag. Also `occluded` and `likelihood`.
    pub glared: bool,
}

fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(v[mid])
}

/// Offset of the outer samples of a cell from its centre, in cells: the
/// 3 x 3 samples span the central half of the cell.
const SAMPLE_SPREAD: f64 = 0.25;

/// The image point at tag coordinates `(u, v)` through `h`, sampled.
fn sample_at(img: &GrayView<'_>, h: &Homography, u: f64, v: f64) -> Option<f64> {
    let p = h.map([u, v])?;
    sample_bilinear(img, p[0], p[1])
}

/// Tag coordinate of the centre of cell `j` (row or column) of an `n` x `n`
/// grid whose cells are `step` wide.
fn cell_centre(j: usize, step: f64) -> f64 {
    cell_centre_at(j as f64, step)
}

/// [`cell_centre`] of a grid index that may lie outside the grid.
fn cell_centre_at(j: f64, step: f64) -> f64 {
    -0.5 + (1.5 + j) * step
}

/// Whether the four outermost samples of the grid [`sample_cells`] takes
/// (the same points, computed the same way) fall inside the image: a quad
/// whose grid leaves the image is refused before its cells are sampled.
fn grid_corners_inside(img: &GrayView<'_>, n: usize, h: &Homography) -> bool {
    let step = 1.0 / (n as f64 + 2.0);
    let lo = cell_centre(0, step) - SAMPLE_SPREAD * step;
    let hi = cell_centre(n - 1, step) + SAMPLE_SPREAD * step;
    [(lo, lo), (lo, hi), (hi, hi), (hi, lo)]
        .iter()
        .all(|&(u, v)| sample_at(img, h, u, v).is_some())
}

/// One darkness-agnostic grey value per cell (row-major): each cell
/// averages a 3 x 3 pattern over its central half, so blur and noise
/// average out while neighbouring cells stay out. `None` when a sample
/// falls outside the image.
///
/// The samples are the values [`cell_mean`] gives, computed the same way,
/// but each product of a homography entry with a sample's coordinate is
/// taken once per grid column or row rather than once per sample (a
/// cell's three columns of samples share their `u`, its three rows their
/// `v`, and every cell of a grid column or row shares them too); each
/// sum then adds the same products in the same order as
/// [`Homography::map`], so the cells are the same to the bit. Why: the
/// 3 x 3 samples of every cell, nine homography maps each, were about a
/// twentieth of a cluttered 1080p frame's instructions, most of it in
/// the products and the call per sample.
fn sample_cells(img: &GrayView<'_>, n: usize, h: &Homography) -> Option<Vec<f64>> {
    let step = 1.0 / (n as f64 + 2.0);
    let offs = [-SAMPLE_SPREAD * step, 0.0, SAMPLE_SPREAD * step];
    let m = h.matrix();
    let m: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]));
    // Per grid column (or row) k and sample a within its cells, the
    // products of matrix column `col` with the sample's coordinate, one
    // per homography row.
    let products = |col: usize| -> Vec<[[f64; 3]; 3]> {
        (0..n)
            .map(|k| {
                let centre = cell_centre(k, step);
                offs.map(|d| {
                    let x = centre + d;
                    [m[0][col] * x, m[1][col] * x, m[2][col] * x]
                })
            })
            .collect()
    };
    let (by_u, by_v) = (products(0), products(1));
    let mut cells = Vec::with_capacity(n * n);
    for pv in &by_v {
        for pu in &by_u {
            let mut sum = 0.0;
            for v in pv {
                for u in pu {
                    let z = u[2] + v[2] + m[2][2];
                    // `Homography::map`'s test, as it makes it.
                    if z.abs() > MIN_WEIGHT {
                        let (x, y) = (u[0] + v[0] + m[0][2], u[1] + v[1] + m[1][2]);
                        sum += sample_bilinear(img, x / z, y / z)?;
                    } else {
                        return None;
                    }
                }
            }
            cells.push(sum / 9.0);
        }
    }
    Some(cells)
}

/// The mean of the 3 x 3 samples over the central half of the cell at
/// grid row `i`, column `j` of a grid whose cells are `step` wide, through
/// `h`; the indices may lie outside the grid (-1 is the white margin, -2
/// the black frame's inner cell, `n` the margin on the far side). `None`
/// when a sample falls outside the image.
fn cell_mean(img: &GrayView<'_>, h: &Homography, step: f64, i: f64, j: f64) -> Option<f64> {
    let (cu, cv) = (cell_centre_at(j, step), cell_centre_at(i, step));
    let offs = [-SAMPLE_SPREAD * step, 0.0, SAMPLE_SPREAD * step];
    let mut sum = 0.0;
    for dv in offs {
        for du in offs {
            sum += sample_at(img, h, cu + du, cv + dv)?;
        }
    }
    Some(sum / 9.0)
}

/// The cells' whiteness through `h` (row-major): 0 at the tag's measured
/// `black`, 1 at its white, `contrast` grey levels above.
fn whiteness(
    img: &GrayView<'_>,
    n: usize,
    h: &Homography,
    black: f64,
    contrast: f64,
) -> Option<Vec<f64>> {
    let cells = sample_cells(img, n, h)?;
    Some(cells.iter().map(|v| (v - black) / contrast).collect())
}

/// The tag's own white and black levels seen through the homography `h`
/// of a family with `n` x `n` cells: the medians of the centre line of the
/// one-cell white margin and of the black frame's centre line, b/2
/// outside the data square (samples outside the image are skipped).
pub(crate) fn ring_levels(img: &GrayView<'_>, n: usize, h: &Homography) -> Option<(f64, f64)> {
    let at = |u: f64, v: f64| sample_at(img, h, u, v);
    let step = 1.0 / (n as f64 + 2.0);
    let mut white = Vec::with_capacity(4 * (n + 2));
    let mut black = Vec::with_capacity(4 * (n + 2));
    let m = 0.5 - 0.5 * step;
    let f = 0.5 + 0.5 * B;
    for k in 0..=n + 1 {
        let t = -0.5 + (k as f64 + 0.5) * step;
        for (u, v) in [(t, -m), (t, m), (-m, t), (m, t)] {
            if let Some(s) = at(u, v) {
                white.push(s);
            }
        }
        for (u, v) in [(t, -f), (t, f), (-f, t), (f, t)] {
            if let Some(s) = at(u, v) {
                black.push(s);
            }
        }
    }
    Some((median(&mut white)?, median(&mut black)?))
}

/// Share of the frame and margin rings' sample pairs that
/// [`clear_ring_levels`] keeps: the clearer half. An occluder over less
/// than half of the rings leaves that half clear of it. (A share is kept
/// rather than the pairs over a contrast, so that a quad that is no tag
/// cannot pick a few pairs that happen to differ.)
const CLEAR_PAIR_SHARE: f64 = 0.5;

/// Least contrast (grey levels) of the clear pairs' levels for the
/// decoder to try them ([`decode_quad_by`]): five times the decoder's
/// default least contrast, so that a quad whose rings are dull throughout
/// is not read twice.
const MIN_CLEAR_CONTRAST: f64 = 20.0;

/// The decoder tries the clear pairs' levels when the plain levels'
/// contrast is under this share of theirs: the plain medians were pulled
/// together by something over part of the rings. On the wild set (6001
/// markers, both families looked for), 0.8 read 18 more markers and lost
/// none; 0.7 read 14 more. Past it the clear levels are less a repair than
/// a second guess at levels the plain ones already gave: 0.9 read 29 more
/// and 1.0 32, but moved the corners of 8 and 10 markers found before
/// (two by 0.5 px or more, for the worse) and cost more retries.
const PLAIN_SHARE_OF_CLEAR: f64 = 0.8;

/// The tag's white and black levels from the frame and margin rings' pairs
/// of samples that show them: the margin's centre line and the frame's,
/// sampled at the same place along each side as [`ring_levels`] samples
/// them, the pairs ranked by white minus black, and of the clearer
/// [`CLEAR_PAIR_SHARE`] the median white and the median black. An occluder
/// as dark as the frame or as light as the margin over part of the rings
/// (the paper's diagonal and triangle patterns across two sides, a stick
/// along a side) shows the same grey in both samples of its pairs; with a
/// third of the rings under it, the plain medians [`ring_levels`] takes
/// can lie within a few grey levels of each other, and every cell then
/// reads as noise. `None` with fewer than 8 pairs inside the image.
pub(crate) fn clear_ring_levels(
    img: &GrayView<'_>,
    n: usize,
    h: &Homography,
) -> Option<(f64, f64)> {
    let at = |u: f64, v: f64| sample_at(img, h, u, v);
    let step = 1.0 / (n as f64 + 2.0);
    let m = 0.5 - 0.5 * step;
    let f = 0.5 + 0.5 * B;
    let mut pairs: Vec<(f64, f64)> = Vec::with_capacity(4 * (n + 2));
    for k in 0..=n + 1 {
        let t = -0.5 + (k as f64 + 0.5) * step;
        let sides = [
            ((t, -m), (t, -f)),
            ((t, m), (t, f)),
            ((-m, t), (-f, t)),
            ((m, t), (f, t)),
        ];
        for ((u, v), (uf, vf)) in sides {
            if let (Some(white), Some(black)) = (at(u, v), at(uf, vf)) {
                pairs.push((white, black));
            }
        }
    }
    if pairs.len() < 8 {
        return None;
    }
    pairs.sort_by(|a, b| (b.0 - b.1).total_cmp(&(a.0 - a.1)));
    let keep = ((pairs.len() as f64 * CLEAR_PAIR_SHARE).ceil() as usize).max(1);
    let mut white: Vec<f64> = pairs[..keep].iter().map(|p| p.0).collect();
    let mut black: Vec<f64> = pairs[..keep].iter().map(|p| p.1).collect();
    Some((median(&mut white)?, median(&mut black)?))
}

/// Cells read around each corner by [`frame_misread_at_corners`], counted
/// in from the corner along each side: -2 is the black frame's inner cell
/// (the frame is two cells wide), -1 the one-cell white margin, 0 to 2
/// the first data cells. Only the cells of the frame and the margin in
/// this block are read: an L of 16 cells along both sides from the corner.
const CORNER_BLOCK: [f64; 5] = [-2.0, -1.0, 0.0, 1.0, 2.0];

/// How many cells of the frame and the margin misread around each corner
/// (TL, BL, BR, TR) of a tag with `n` x `n` cells seen through `h`: of the
/// L of 16 cells along both sides from the corner ([`CORNER_BLOCK`]), the
/// frame's inner cells should read black and the margin's white, each
/// cell averaged over its central half as the decoder samples it, against
/// the tag's own black and white levels ([`ring_levels`]). A corner a cell
/// or more off puts several margin cells on the frame or frame cells
/// outside it; a corner under an occluder reads the occluder, which is not
/// both black and white. `None` when the levels cannot be measured or a
/// cell falls outside the image.
pub(crate) fn frame_misread_at_corners(
    img: &GrayView<'_>,
    n: usize,
    h: &Homography,
) -> Option<[usize; 4]> {
    let (white, black) = ring_levels(img, n, h)?;
    let contrast = white - black;
    if contrast <= 0.0 {
        return None;
    }
    let step = 1.0 / (n as f64 + 2.0);
    let last = (n - 1) as f64;
    let mut misread = [0; 4];
    for (k, wrong) in misread.iter_mut().enumerate() {
        let [su, sv] = CORNERS[k];
        // Grid index `a` cells in from the corner along an axis on whose
        // `s` side the corner lies.
        let index = |s: f64, a: f64| if s < 0.0 { a } else { last - a };
        for &a in &CORNER_BLOCK {
            for &b in &CORNER_BLOCK {
                if a >= 0.0 && b >= 0.0 {
                    continue;
                }
                let dark = a < -1.0 || b < -1.0;
                let y = (cell_mean(img, h, step, index(sv, a), index(su, b))? - black) / contrast;
                *wrong += usize::from((y < 0.5) != dark);
            }
        }
    }
    Some(misread)
}

/// Thresholds of the decoder, in grey levels of the 8-bit image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DecodeParams {
    /// Smallest difference between the tag's measured white (data-square
    /// margin) and black (frame) levels, grey levels: below it the quad is
    /// noise, not a tag. Default 4.
    pub min_contrast: f64,
    /// Second reading: cells whose grey value is within this fraction of
    /// the contrast from the threshold are erased, not guessed (Reed-Solomon
    /// corrects twice as many erasures as errors). Default 0.2.
    pub erase_fraction: f64,
}

impl Default for DecodeParams {
    fn default() -> Self {
        Self {
            min_contrast: 4.0,
            erase_fraction: 0.2,
        }
    }
}

/// Reads a tag of `family` whose data-square corners are `corners`, given in
/// the order TL, BL, BR, TR up to a rotation (any of the four cyclic shifts
/// of that order). Returns `None` when nothing decodes unambiguously.
///
/// The corners returned are the same points reordered so that corner 0 is
/// the tag's physical top-left corner (a likelihood reading of a blurred
/// tag may first move them, by up to 1.5 px, to where the cells fit the
/// codeword best). `img` is an `&image::GrayImage` or a [`GrayView`] of a
/// borrowed buffer.
pub fn decode_quad<'a>(
    img: impl Into<GrayView<'a>>,
    family: &Family,
    corners: &[[f64; 2]; 4],
) -> Option<QuadReading> {
    decode_quad_with(&img.into(), family, corners, &DecodeParams::default())
}

/// [`decode_quad`] with explicit thresholds.
///
/// A reading through the Reed-Solomon code is accepted within the
/// family's default limit ([`Family::default_correction_limit`], the
/// detector's too): for ct8, 3 of the 5 symbols its short code corrects;
/// for ct14 and any family made with [`Family::from_spec`], the code's
/// capacity (ct14: 9 symbols; an erased symbol counts half, and at most
/// that many may be erased: a grid with more of its symbols erased reads
/// as some id whatever it shows). Over it, the grid's other readings are
/// tried. The corners are taken as given, as the detector's verify stage
/// takes its fitted ones: a likelihood fit that leads without reading is
/// aligned to, and where that does not read, the grid is read as smeared
/// by motion.
pub fn decode_quad_with(
    img: &GrayView<'_>,
    family: &Family,
    corners: &[[f64; 2]; 4],
    params: &DecodeParams,
) -> Option<QuadReading> {
    let accept = Accept {
        nearest: true,
        limit: Some(family.default_correction_limit()),
        smeared: true,
        promising: Promising::AlignOrSmear,
        glared: true,
    };
    decode_quad_by(img, family, corners, params, accept)
}

/// Which readings a caller of [`decode_quad_by`] accepts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Accept {
    /// The reading of a tag smeared by motion ([`crate::motion`]). A smear
    /// rounds a tag's corners off along it, so a quad whose corner was not
    /// measured but inferred from the other three may have it where the
    /// smear ends: on the wild and calibration sets, 4 smeared readings of
    /// such quads put a corner 3.2 to 4.7 px off, while of those whose
    /// four corners were measured none was over 3 px. Such quads keep the
    /// grid's other readings.
    pub smeared: bool,
    /// The nearest-codeword reading of an occluded tag
    /// ([`crate::nearest`]): the verify stage checks a reading's fitted
    /// geometry with the readings that found it, so that a reading by the
    /// code is not confirmed by a looser one.
    pub nearest: bool,
    /// Most symbols a reading by the code may correct (see
    /// [`within_limit`]); a reading over it counts as none, and the next
    /// ways of reading the grid are tried.
    pub limit: Option<usize>,
    /// What a likelihood fit that leads without reading clearly leads to.
    pub promising: Promising,
    /// The reading under glare by the nearest codeword
    /// ([`read_glare_nearest`]), tried when nothing else reads, at the
    /// rings' plain levels.
    pub glared: bool,
}

/// What a likelihood fit whose best id leads without reading clearly
/// ([`LikelyFit::promising`]) leads to in [`read_blurred`]: the quad
/// aligned to that codeword ([`align`]: its corners moved by up to
/// [`ALIGN_MAX_MOVE_PX`] to where the cell centres fit it best) and read
/// again, the grid read as smeared by motion ([`read_smeared`]), or the
/// first and then the second. A tag smeared by motion often has a round
/// fit that leads without reading, and no alignment makes it read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Promising {
    /// The quad aligned and read again; no likelihood reading when that
    /// does not read. For a candidate's first reading (and the rim look's
    /// reading of its aligned print): trying the smear reading after a
    /// failed alignment there too found 46 more of the wild set's markers
    /// and lost 2, but moved 6 others' corners (wild and calibration sets)
    /// by 0.5 px or more for the worse, to up to 1.4 px off at a claimed
    /// sigma of 0.33 px.
    Align,
    /// Aligned and read again, then the smear reading if that does not
    /// read: for the verify stage's reading at the fitted corners, which
    /// only confirms the id where the model fit has placed the quad. On
    /// the wild set this confirmed readings of 27 more markers (none
    /// lost; one other's corners moved for the worse, to 1.2 px off), and
    /// 10 more on the sigma calibration set. Also [`decode_quad_with`]'s,
    /// which takes the corners it is given as they are.
    AlignOrSmear,
    /// The smear reading alone, no alignment: for the rim look's readings
    /// at small moves of the aligned print's quad and on the refined one,
    /// whose alignments would repeat the aligned print's own. On the wild
    /// set those were 60% of the rim look's grid fits (60 000) and read
    /// 4 markers; with the smear reading in their place the rim look read
    /// 8 more than with the verify stage's change alone (2 more on the
    /// calibration set), and none fewer.
    Smear,
}

/// Whether a reading's corrections fit a family's limit: at most `limit`
/// symbols corrected, or, when the reading erased symbols, errors and
/// erasures within the same share of the code's capacity with erasures at
/// half weight (`2 * errors + erased <= 2 * limit`). Reed-Solomon spends one
/// parity symbol on an erasure and two on an error, so a tag under a light
/// stick, whose hidden cells read grey and are erased, is not refused for
/// corrections the code made at half cost. The erasures themselves stay
/// within `limit`: an erased symbol matches any id, and a reading resting
/// on more of them than the limit says too little about the quad (on the
/// robustness set, 13 erasures read a tag through a quad with a corner
/// 9 px off).
pub(crate) fn within_limit(r: &GridReading, limit: usize) -> bool {
    r.corrected <= limit || (2 * r.errors + r.erased <= 2 * limit && r.erased <= limit)
}

/// [`decode_quad_with`], accepting what `accept` says.
pub(crate) fn decode_quad_by(
    img: &GrayView<'_>,
    family: &Family,
    corners: &[[f64; 2]; 4],
    params: &DecodeParams,
    accept: Accept,
) -> Option<QuadReading> {
    let n = family.grid();
    // The cheap refusals first (a grid leaving the image, no contrast
    // between margin and frame), then the cells.
    let (h, plain) = grid_and_levels(img, n, corners)?;
    // The cells are sampled once, for the plain levels and the clear ones.
    let mut cells = None;
    if plain.0 - plain.1 >= params.min_contrast {
        let sampled = sample_cells(img, n, &h)?;
        let at = Levelled::new(&sampled, plain);
        if let Some(r) = decode_at_levels(img, family, corners, params, accept, at, true) {
            return Some(r);
        }
        cells = Some(sampled);
    }
    // None read at the rings' plain levels: an occluder over part of the
    // rings may have pulled them together (see `clear_ring_levels`).
    let clear = clear_ring_levels(img, n, &h).filter(|clear| {
        let clear_contrast = clear.0 - clear.1;
        clear_contrast >= MIN_CLEAR_CONTRAST
            && plain.0 - plain.1 < PLAIN_SHARE_OF_CLEAR * clear_contrast
    });
    if let Some(clear) = clear {
        let cells = match &cells {
            Some(c) => c,
            None => cells.insert(sample_cells(img, n, &h)?),
        };
        // At the clear levels, the readings by the code and by the nearest
        // codeword only (see `decode_at_levels`).
        let at = Levelled::new(cells, clear);
        if let Some(r) = decode_at_levels(img, family, corners, params, accept, at, false) {
            return Some(QuadReading {
                clear_ring: true,
                ..r
            });
        }
    }
    // Last, under a glare, the cells the glare left against the codebook.
    if !accept.glared || plain.0 - plain.1 < params.min_contrast {
        return None;
    }
    read_glare_nearest(family, Levelled::new(&cells?, plain), corners)
}

/// The homography of an `n`-cell grid's data square at `corners` and its
/// rings' plain levels ([`ring_levels`]), unless the grid leaves the
/// image: what every reading of a quad starts with.
fn grid_and_levels(
    img: &GrayView<'_>,
    n: usize,
    corners: &[[f64; 2]; 4],
) -> Option<(Homography, (f64, f64))> {
    let h = Homography::from_points(&CORNERS, corners)?;
    if !grid_corners_inside(img, n, &h) {
        return None;
    }
    Some((h, ring_levels(img, n, &h)?))
}

/// The reading of a tag of `family` at `corners` by the Reed-Solomon code
/// alone, at the rings' plain levels, within `limit` corrections: as
/// [`decode_quad_by`] reads first, without the readings by the codebook
/// (likelihood, nearest codeword, shaded) or under glare, and without
/// their cost (the likelihood reading alone costs a score of every
/// codeword).
///
/// Why: for a detector that does not decode `family`, a plain reading is
/// enough to tell a quad of that family's tag, which it then skips, and
/// such a reading of a quad that is no tag of it is rare (on the wild
/// set, whose tags are all ct14, a ct14-only detector that asks it of
/// every quad that reads nothing found the same tags).
pub(crate) fn read_by_code(
    img: &GrayView<'_>,
    family: &Family,
    corners: &[[f64; 2]; 4],
    params: &DecodeParams,
    limit: usize,
) -> Option<QuadReading> {
    let n = family.grid();
    let (h, plain) = grid_and_levels(img, n, corners)?;
    if plain.0 - plain.1 < params.min_contrast {
        return None;
    }
    let accept = Accept {
        nearest: false,
        limit: Some(limit),
        smeared: false,
        promising: Promising::Align,
        glared: false,
    };
    let cells = sample_cells(img, n, &h)?;
    decode_at_levels(
        img,
        family,
        corners,
        params,
        accept,
        Levelled::new(&cells, plain),
        false,
    )
    // With no codebook reading asked for, the one other reading left is
    // the one under glare past the limit (`occluded`).
    .filter(|r| !r.likelihood && !r.occluded)
}

/// The nearest codeword ([`read_nearest`]) of the cells `at` of a tag
/// under a glare (some cell clipped, [`SATURATED_DN`]), each cell levelled
/// between the darkest and brightest around it ([`levelled_min_max`]) and
/// those with no contrast around them left out as grey: a reading
/// [`QuadReading::glared`], at `corners`.
///
/// Why: [`read_glared`] erases a symbol when any of its 8 cells is washed
/// out, so a spot over half the square leaves a handful of symbols, under
/// the bits it must keep to stand ([`GLARE_CHECK_BITS`]); on one of the
/// wild set's tags (45 px, its lower half clipped), 17 of 20 symbols were
/// erased while 104 cells read with 5 wrong, and every other codeword
/// disagreed with about half of them. Cell by cell against the codebook,
/// with the nearest codeword's own tests (a clear lead, misread cells
/// confined), the wild set's bar-scenario misses that read nowhere at
/// their true corners read 67 more of 403, none as a wrong id.
fn read_glare_nearest(
    family: &Family,
    at: Levelled<'_>,
    corners: &[[f64; 2]; 4],
) -> Option<QuadReading> {
    let book = family.codebook()?;
    let contrast = at.white - at.black;
    if !at.cells.iter().any(|&v| v >= SATURATED_DN) {
        return None;
    }
    let y: Vec<f64> = at.cells.iter().map(|v| (v - at.black) / contrast).collect();
    let x: Vec<f64> = levelled_min_max(&y, family.grid())
        .into_iter()
        .map(|v| v.unwrap_or(0.5))
        .collect();
    let near = read_nearest(book, &x)?;
    codeword_reading(
        family,
        &x,
        (near.id, near.rotation),
        corners,
        contrast,
        Method::Nearest,
    )
    .map(|r| QuadReading { glared: true, ..r })
}

/// A grid's cells as sampled, with the tag's white and black levels they
/// are read against.
#[derive(Clone, Copy)]
struct Levelled<'c> {
    cells: &'c [f64],
    white: f64,
    black: f64,
}

impl<'c> Levelled<'c> {
    fn new(cells: &'c [f64], (white, black): (f64, f64)) -> Self {
        Self {
            cells,
            white,
            black,
        }
    }
}

/// [`decode_quad_by`] on the cells `at`, sampled through `corners`, read
/// against the levels they come with; with `likely` false, without the
/// likelihood readings through blur and under a light field (the
/// readings by the code and by the nearest codeword only). Those are for
/// the plain levels: tried at the rings' clear levels too, they read 5
/// more of the wild set's markers (23 rather than 18) for 3-4% more median
/// time per frame on the wild benchmark's 1080p frames, against about 1%
/// without them.
#[allow(clippy::too_many_arguments)]
fn decode_at_levels(
    img: &GrayView<'_>,
    family: &Family,
    corners: &[[f64; 2]; 4],
    params: &DecodeParams,
    accept: Accept,
    at: Levelled<'_>,
    likely: bool,
) -> Option<QuadReading> {
    let n = family.grid();
    let black = at.black;
    let contrast = at.white - black;
    if contrast < params.min_contrast {
        return None;
    }
    let y: Vec<f64> = at.cells.iter().map(|v| (v - black) / contrast).collect();
    if flat(&y) {
        return None;
    }
    let is_blurred = blurred(&y);
    let fits = |r: &GridReading| accept.limit.is_none_or(|l| within_limit(r, l));
    // A reading of cells levelled by their neighbourhood reads more, so it
    // must leave a margin of the code's capacity unused.
    let cap = (family.code().parity() / 2).saturating_sub(SHADED_MARGIN);
    let levelled_fits = |r: &GridReading| r.corrected <= cap && fits(r);
    let reading = read_cells(family, &y, params.erase_fraction)
        .filter(fits)
        .or_else(|| {
            // Third chance, for a blurred tag only: undo the blur in cell
            // space, at the assumed width that leaves the fewest grey cells.
            if !is_blurred {
                return None;
            }
            let x = DEBLUR_SIGMAS
                .iter()
                .filter_map(|&sg| deblur(&y, n, sg))
                .min_by_key(|x| mid_band(x))?;
            read_cells(family, &x, params.erase_fraction).filter(fits)
        })
        .or_else(|| {
            // Last chance, for uneven light (glare, shadow, a gradient across
            // the tag): each cell against its neighbours rather than against
            // the tag's one black and one white level.
            read_cells(family, &locally_levelled(&y, n), params.erase_fraction)
                .filter(levelled_fits)
        });
    if let Some(r) = reading {
        return Some(reading_to_quad(r, corners, contrast, Method::Code));
    }
    // Under glare, a reading within the levelled reading's own bounds is
    // a code reading like the others; one past them, resting on erasures
    // alone, comes after the likelihood reading (which reads such a tag
    // with its geometry judged less strictly) and is judged by the verify
    // stage as a tag under an occluder.
    let glared = read_glared(family, &y, black, contrast, params.erase_fraction);
    if let Some(r) = glared.filter(levelled_fits) {
        return Some(reading_to_quad(r, corners, contrast, Method::Code));
    }
    // Then, for a family with few ids, the whole grid against every
    // codeword: as the blur shows each codeword (the blur model's
    // narrowest width, under half a cell, fits a sharp tag too, and its
    // trimmed score a tag in glare or partly hidden: tried on every grid
    // rather than on blurred-looking ones alone, it found 0.6% more of the
    // wild set's tags, none rough, and read none of the 16 000 quads there
    // that were no tag); last of all, cell by cell, for a tag whose hidden
    // cells read confidently wrong (an ink-dark or paper-white occluder).
    let book = family.codebook();
    // The likelihood reading's first-round dot products, for the shaded
    // reading's first round.
    let mut dots = Vec::new();
    let blurred = book.filter(|_| likely).and_then(|book| {
        read_blurred(
            img, family, book, &y, corners, black, contrast, accept, &mut dots,
        )
    });
    // A faint reading (see `QuadReading::faint`) comes after every other:
    // it needs the detector's alignment of the print to stand, which the
    // others do not.
    if blurred.as_ref().is_some_and(|r| !r.faint) {
        return blurred;
    }
    let nearest = book
        .filter(|_| accept.nearest)
        .and_then(|book| read_nearest(book, &y))
        .and_then(|near| {
            codeword_reading(
                family,
                &y,
                (near.id, near.rotation),
                corners,
                contrast,
                Method::Nearest,
            )
        });
    nearest
        .or_else(|| {
            glared
                .filter(|r| stands_past_limit(family, r))
                .map(|r| reading_to_quad(r, corners, contrast, Method::Glare))
        })
        .or(blurred)
        .or_else(|| {
            let book = book.filter(|_| likely)?;
            let clipped: Vec<bool> = y.iter().map(|&v| clipped(v, black, contrast)).collect();
            let fit = read_shaded(book, &y, &clipped, &dots)?;
            codeword_reading(
                family,
                &y,
                (fit.id, fit.rotation),
                corners,
                contrast,
                Method::Shaded,
            )
            .map(|r| QuadReading {
                faint: true,
                shaded: true,
                ..r
            })
        })
}

/// The reading of codeword `id` at `rotation` found by matching the whole
/// grid (cells' whiteness `y`) against the codebook: `corrected` counts
/// the symbols a cell-by-cell reading got wrong ([`misread_symbols`]).
fn codeword_reading(
    family: &Family,
    y: &[f64],
    (id, rotation): (u64, usize),
    corners: &[[f64; 2]; 4],
    contrast: f64,
    method: Method,
) -> Option<QuadReading> {
    let misread = misread_symbols(family, y, id, rotation)?;
    let reading = GridReading {
        id,
        rotation,
        corrected: misread,
        erased: 0,
        errors: misread,
    };
    Some(reading_to_quad(reading, corners, contrast, method))
}

/// The likelihood reading of a tag ([`read_likely`]) whose cells'
/// whiteness through `corners` is `y` (measured `black` level and
/// `contrast`): when one id leads without reading clearly, the quad is
/// aligned to that codeword ([`align`]) and read again, as
/// `accept.promising` says. When no round template fits, the codewords are
/// tried as a motion smear shows them ([`read_smeared`]) if smeared
/// readings are accepted.
#[allow(clippy::too_many_arguments)]
fn read_blurred(
    img: &GrayView<'_>,
    family: &Family,
    book: &Codebook,
    y: &[f64],
    corners: &[[f64; 2]; 4],
    black: f64,
    contrast: f64,
    accept: Accept,
    dots: &mut Vec<f64>,
) -> Option<QuadReading> {
    let n = family.grid();
    let round = read_likely_keeping(book, y, dots);
    let aligned = |fit: &LikelyFit| {
        let aligned = align(img, n, book, fit, corners)?;
        let h = Homography::from_points(&CORNERS, &aligned)?;
        let y = whiteness(img, n, &h, black, contrast)?;
        let again = read_likely(book, &y)?;
        again.reads().then_some((again, y, aligned))
    };
    // A smear along one direction fits no round template clearly.
    // (Tried only on grids that look blurred ([`blurred`]), with the
    // direction's bound at 0.55, it read 25 fewer of the wild set's tags,
    // for no time the wild set's timings could tell apart.)
    let smear = || {
        let fit = read_smeared(book, y).filter(LikelyFit::reads)?;
        Some((fit, y.to_vec(), *corners, Method::Smear))
    };
    let (fit, y, corners, method) = match round {
        Some(fit) if fit.reads() => (fit, y.to_vec(), *corners, Method::Blur),
        Some(fit) if fit.promising() && accept.promising != Promising::Smear => {
            match aligned(&fit) {
                Some((fit, y, corners)) => (fit, y, corners, Method::Blur),
                None if accept.promising == Promising::AlignOrSmear && accept.smeared => smear()?,
                None => return None,
            }
        }
        _ if accept.smeared => smear()?,
        _ => return None,
    };
    if contradicts(book, &y, fit.id, fit.rotation) {
        return None;
    }
    codeword_reading(
        family,
        &y,
        (fit.id, fit.rotation),
        &corners,
        contrast,
        method,
    )
    .map(|r| QuadReading {
        faint: fit.faint(),
        ..r
    })
}

/// First move (px) of a corner coordinate when a quad is aligned to a
/// codeword; halved whenever no move helps, down to [`ALIGN_LAST_STEP_PX`].
/// The quads of blurred tags the likelihood reading missed were 1-2 px off
/// at the median.
const ALIGN_STEP_PX: f64 = 0.5;
/// Last move tried (px).
const ALIGN_LAST_STEP_PX: f64 = 0.125;
/// Farthest a corner may move (px): a quad further off is another quad.
/// On the wild set 2.5 px let one occluded tag through with a corner
/// 4.8 px off; 1.5 px found one tag fewer and none rough.
const ALIGN_MAX_MOVE_PX: f64 = 1.5;
/// Most rounds of moves (each tries every coordinate both ways).
const ALIGN_ROUNDS: usize = 12;

/// `corners` moved, one coordinate at a time, to where the cells fit the
/// codeword of `fit` best (coordinate descent with a shrinking step: the
/// fit's score is smooth at the scale of a fraction of a cell). `None` when
/// the grid leaves the image.
fn align(
    img: &GrayView<'_>,
    n: usize,
    book: &Codebook,
    fit: &LikelyFit,
    corners: &[[f64; 2]; 4],
) -> Option<[[f64; 2]; 4]> {
    // One sample per cell centre: a ninth of the reading's samples, and
    // the template is the blurred cell centres' anyway.
    let step = 1.0 / (n as f64 + 2.0);
    let mut cells = vec![0.0; n * n];
    let mut fits = book.scorer(fit);
    let mut fit_at = |c: &[[f64; 2]; 4]| -> Option<f64> {
        let h = Homography::from_points(&CORNERS, c)?;
        for (k, v) in cells.iter_mut().enumerate() {
            *v = sample_at(img, &h, cell_centre(k % n, step), cell_centre(k / n, step))?;
        }
        fits(&cells)
    };
    // Each quad's score, once: after a round that moved a corner, the
    // next round tries again the moves the last accepted one left as they
    // were, and moving a corner back gives the quad before. On the wild
    // set 28 694 of the 207 468 quads scored (14%) had been scored before
    // in the same alignment; the median time per frame over 600 of its
    // frames fell by 1% (5.46 -> 5.40 ms). The score is a function of the
    // corners alone, so the alignment ends where it did.
    let mut scored: Vec<([[u64; 2]; 4], Option<f64>)> = Vec::new();
    let mut score = |c: &[[f64; 2]; 4]| -> Option<f64> {
        let key = c.map(|p| p.map(f64::to_bits));
        if let Some(&(_, s)) = scored.iter().find(|(k, _)| *k == key) {
            return s;
        }
        let s = fit_at(c);
        scored.push((key, s));
        s
    };
    let mut best = *corners;
    let mut best_score = score(&best)?;
    let mut step = ALIGN_STEP_PX;
    for _ in 0..ALIGN_ROUNDS {
        let mut moved = false;
        for k in 0..8 {
            for sign in [-1.0, 1.0] {
                let mut c = best;
                c[k / 2][k % 2] += sign * step;
                if (c[k / 2][k % 2] - corners[k / 2][k % 2]).abs() > ALIGN_MAX_MOVE_PX {
                    continue;
                }
                if let Some(s) = score(&c) {
                    if s < best_score {
                        (best, best_score, moved) = (c, s, true);
                        break;
                    }
                }
            }
        }
        if !moved {
            step /= 2.0;
            if step < ALIGN_LAST_STEP_PX {
                break;
            }
        }
    }
    Some(best)
}

/// Code symbols of tag `id` seen at `rotation` that the cells' whiteness
/// `y`, thresholded at a half, gets wrong: what a hard reading of the grid
/// would have had to correct.
fn misread_symbols(family: &Family, y: &[f64], id: u64, rotation: usize) -> Option<usize> {
    let black = encode_cells(family, id).ok()?;
    let n = family.grid();
    let bits = family.code().symbol_bits() as usize;
    let mut wrong = vec![false; family.code().n()];
    for (k, &cell) in family.code_cells().iter().enumerate() {
        if (y[rotate_cell(cell, n, rotation)] < 0.5) != black[cell] {
            wrong[k / bits] = true;
        }
    }
    Some(wrong.iter().filter(|&&w| w).count())
}

/// Half-width, in cells, of the neighbourhood each cell is levelled
/// against in [`locally_levelled`]: 5 x 5 cells hold about as many black as
/// white cells (the checkerboard mask balances them), while glare and
/// shadow change little over 5 of a 14-cell grid's cells.
const SHADING_RADIUS: usize = 2;

/// Reed-Solomon symbols a reading through [`locally_levelled`] must leave
/// uncorrected below the code's capacity. On the wild set the levelled
/// reading adds tags at every correction count; those read at the last
/// two counts of ct14's capacity (8 and 9) brought rough corners with
/// them, those below did not.
const SHADED_MARGIN: usize = 2;

/// Cells' whiteness `y` (n x n, row-major) levelled by their neighbours:
/// each cell minus the mean of the cells within [`SHADING_RADIUS`] (the
/// grid's edge clips the window), plus a half. An adaptive mean threshold
/// (as in Wellner's and Bradley and Roth's image thresholding) in cell
/// space: uneven light moves a cell and its neighbours together.
fn locally_levelled(y: &[f64], n: usize) -> Vec<f64> {
    (0..n * n)
        .map(|c| {
            let count: usize = window(y, n, c, SHADING_RADIUS).map(<[f64]>::len).sum();
            let sum: f64 = window(y, n, c, SHADING_RADIUS).flatten().sum();
            y[c] - sum / count as f64 + 0.5
        })
        .collect()
}

/// The rows of the window of cells within `r` of cell `c` of the `n` x `n`
/// grid `y` (row-major), top to bottom, each a slice; the grid's edge clips
/// the window.
fn window(y: &[f64], n: usize, c: usize, r: usize) -> impl Iterator<Item = &[f64]> {
    let (i, j) = (c / n, c % n);
    let (j0, j1) = (j.saturating_sub(r), (j + r).min(n - 1));
    (i.saturating_sub(r)..=(i + r).min(n - 1)).map(move |ii| &y[ii * n + j0..=ii * n + j1])
}

/// Blur widths (cells, Gaussian sigma) considered when the plain reading
/// of a blurred tag fails, from where isolated cells start to fade to
/// where neighbours weigh nearly as much as the cell itself; the one whose
/// deblurred cells are least grey is read.
const DEBLUR_SIGMAS: [f64; 3] = [0.45, 0.6, 0.75];

/// A tag looks blurred when at least this share of its cells sample in
/// the middle band ([`MID_BAND`]) between black and white: sharp cells
/// sample near 0 or 1.
const BLURRED_SHARE: f64 = 0.2;

/// Half-width of the middle band of whiteness (around 0.5).
const MID_BAND: f64 = 0.25;

/// Cells of whiteness `y` in the middle band ([`MID_BAND`]).
fn mid_band(y: &[f64]) -> usize {
    y.iter().filter(|v| (*v - 0.5).abs() < MID_BAND).count()
}

/// Least standard deviation of the cells' whiteness (in units of the
/// tag's own contrast between its margin and its frame) of a grid worth
/// reading. A tag's cells are about half black and half white (the mask
/// balances any codeword), so even blurred, shaded or partly hidden its
/// cells spread: every grid that read, by any of the readings below, had
/// at least 0.207 on the 3000 wild frames (11 154 readings, ct14) and 0.25
/// on the speed benchmark's 1080p and 4K frames (both families); a tag
/// faded to a third of its contrast with 40% of it under a flat occluder
/// still has 0.097 (see the test). A flat grid is the inside of a dark or
/// light shape between a margin and a frame of clutter: 10% of the wild
/// set's grids that read nothing (2593 of 25 917) were under 0.08, and
/// each went through every reading below (the likelihood readings score
/// the whole codebook) for nothing. (At 0.12, 12% and the same
/// detections; 0.08 keeps the margin below the faded, hidden tag.)
const FLAT_GRID_SPREAD: f64 = 0.08;

/// Whether the cells' whiteness `y` is too even to hold a code
/// ([`FLAT_GRID_SPREAD`]).
fn flat(y: &[f64]) -> bool {
    spread(y) < FLAT_GRID_SPREAD
}

/// Standard deviation of the cells' whiteness `y` (over all cells).
fn spread(y: &[f64]) -> f64 {
    let n = y.len() as f64;
    let mean = y.iter().sum::<f64>() / n;
    (y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt()
}

/// Whether the cells' whiteness `y` looks blurred ([`BLURRED_SHARE`]).
fn blurred(y: &[f64]) -> bool {
    mid_band(y) as f64 >= BLURRED_SHARE * y.len() as f64
}

/// Reads cells of whiteness `x` (0 black, 1 white) thresholded at a half;
/// second chance with the cells within `erase_fraction` of the threshold
/// erased.
fn read_cells(family: &Family, x: &[f64], erase_fraction: f64) -> Option<GridReading> {
    let bits: Vec<bool> = x.iter().map(|&v| v < 0.5).collect();
    decode_cells(family, &bits, &[]).or_else(|| {
        // Second chance: doubtful cells are erased.
        let doubtful: Vec<bool> = x
            .iter()
            .map(|&v| (v - 0.5).abs() < erase_fraction)
            .collect();
        doubtful
            .iter()
            .any(|&d| d)
            .then(|| decode_cells(family, &bits, &doubtful))
            .flatten()
    })
}

/// Grey level at or above which a cell's mean is taken as clipped by the
/// sensor: under a specular glare black and white cells alike read near
/// 255. Below 255 because a cell's mean takes bilinear samples reaching
/// into its clipped neighbours' edges and the sensor noise of the frame.
const SATURATED_DN: f64 = 245.0;

/// Whether a cell of whiteness `v` on a tag of `black` level and
/// `contrast` was clipped by the sensor ([`SATURATED_DN`]).
fn clipped(v: f64, black: f64, contrast: f64) -> bool {
    black + v * contrast >= SATURATED_DN
}

/// Cells' whiteness `y` read under glare, when a cell's mean grey level is
/// clipped ([`SATURATED_DN`]; the tag's `black` level and `contrast` give
/// the grey level back from `y`): each cell levelled between the darkest
/// and the brightest cell around it ([`levelled_min_max`]), where a glare
/// lifts black and white cells together and the tag's one black and one
/// white level read it all white; cells with no contrast around them
/// (clipped, or in a flat wash of glare) and those within
/// `erase_fraction * GLARE_ERASE_SHARE` of the threshold are erased. A
/// glare gives Reed-Solomon erasures more than errors: the cells it
/// clips are known to say nothing.
fn read_glared(
    family: &Family,
    y: &[f64],
    black: f64,
    contrast: f64,
    erase_fraction: f64,
) -> Option<GridReading> {
    if !y.iter().any(|&v| clipped(v, black, contrast)) {
        return None;
    }
    let x = levelled_min_max(y, family.grid());
    let bits: Vec<bool> = x.iter().map(|v| v.is_some_and(|v| v < 0.5)).collect();
    let erased: Vec<bool> = x
        .iter()
        .map(|v| v.is_none_or(|v| (v - 0.5).abs() < erase_fraction * GLARE_ERASE_SHARE))
        .collect();
    decode_cells(family, &bits, &erased)
}

/// Share of [`DecodeParams::erase_fraction`] within which a glared cell,
/// levelled by its neighbours, is erased rather than read. The levelled
/// contrast is that of the cell's own window, sharper than the tag's: on
/// the wild set's glared tags that the other readings miss at their true
/// corners, half the band read 48 of 424, the whole band 31, three
/// quarters 45.
const GLARE_ERASE_SHARE: f64 = 0.5;

/// Half-width, in cells, of the window of [`levelled_min_max`]: a glare
/// (a Gaussian spot a tenth to 0.4 of the tag's radius wide, in the wild
/// set) changes the light over a few cells, and a 3 x 3 window almost
/// always holds a black and a white cell. A 5 x 5 window read 14 of the
/// 424 tags above, the 3 x 3 one 48.
const GLARE_RADIUS: usize = 1;

/// Smallest span of whiteness (in the tag's contrast) within a cell's
/// window for [`levelled_min_max`] to read it: a window of one clipped
/// colour, or all grey, says nothing of the cell. 0.2 and 0.5 read 44 and
/// 45 of the 424 tags above, 0.35 48.
const MIN_LOCAL_RANGE: f64 = 0.35;

/// Cells' whiteness `y` (n x n, row-major) levelled between the darkest
/// and the brightest cell within [`GLARE_RADIUS`] (a min/max adaptive
/// threshold, as AprilTag 3 does with its tiles in the image, here in cell
/// space): `None` for a cell whose window spans less than
/// [`MIN_LOCAL_RANGE`].
fn levelled_min_max(y: &[f64], n: usize) -> Vec<Option<f64>> {
    (0..n * n)
        .map(|c| {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for &v in window(y, n, c, GLARE_RADIUS).flatten() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
            (hi - lo >= MIN_LOCAL_RANGE).then(|| (y[c] - lo) / (hi - lo))
        })
        .collect()
}

/// Bits a reading that erased `erased` symbols still checks beyond the
/// id: the bits of the symbols seen less those the id takes. A random
/// grid matches one of the family's codewords there with odds of one in
/// two to that power, at each of four rotations.
fn check_bits(family: &Family, erased: usize) -> u32 {
    let code = family.code();
    let ids = family.max_id() - family.min_id() + 1;
    let id_bits = u64::BITS - (ids - 1).leading_zeros();
    let seen = code.n().saturating_sub(erased) * code.symbol_bits() as usize;
    u32::try_from(seen)
        .unwrap_or(u32::MAX)
        .saturating_sub(id_bits)
}

/// Whether a glare reading past the code's usual limits stands: no
/// symbol corrected as an error, and [`GLARE_CHECK_BITS`] left.
fn stands_past_limit(family: &Family, r: &GridReading) -> bool {
    r.errors == 0 && check_bits(family, r.erased) >= GLARE_CHECK_BITS
}

/// Fewest [`check_bits`] a glare reading past the code's usual limits
/// must keep, with no symbol corrected as an error: odds of one in 2^24
/// (16 million) per rotation that a grid of no tag reads. ct14 may then
/// erase 16 of its 20 symbols, ct8 5 of its 15.
const GLARE_CHECK_BITS: u32 = 24;

/// How a grid was read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    /// Through the Reed-Solomon code.
    Code,
    /// Nearest codeword, cell by cell ([`crate::nearest`]).
    Nearest,
    /// Likelihood as the blur shows each codeword ([`read_likely`]).
    Blur,
    /// Likelihood as a motion smear shows each codeword ([`read_smeared`]).
    Smear,
    /// Through the Reed-Solomon code, under glare, on more erasures than
    /// the family's limit allows ([`read_glared`]).
    Glare,
    /// Likelihood under a smooth light field ([`read_shaded`]).
    Shaded,
}

fn reading_to_quad(
    r: GridReading,
    corners: &[[f64; 2]; 4],
    contrast: f64,
    method: Method,
) -> QuadReading {
    // A clockwise quarter turn of the grid moves corner c to position c - 1
    // of the TL, BL, BR, TR list, so physical corner c was seen at c - d.
    let d = r.rotation;
    let canonical = std::array::from_fn(|c| corners[(c + 4 - d % 4) % 4]);
    QuadReading {
        id: r.id,
        corners: canonical,
        corrected: r.corrected,
        erased: r.erased,
        errors: r.errors,
        rotation: d,
        contrast,
        likelihood: matches!(
            method,
            Method::Nearest | Method::Blur | Method::Smear | Method::Shaded
        ),
        smeared: method == Method::Smear,
        occluded: matches!(method, Method::Nearest | Method::Glare),
        faint: false,
        shaded: false,
        clear_ring: false,
        glared: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid_code::encode_cells;
    use crate::test_images::{cells_image, tag_image, INK};

    /// `sample_cells` takes each homography product once per grid column
    /// or row; its cells must be `cell_mean`'s to the bit, and it must
    /// fail exactly where some cell's samples leave the image.
    #[test]
    fn sampled_cells_are_the_cell_means_to_the_bit() {
        let fam = Family::ct14();
        let n = fam.grid();
        let cells = encode_cells(fam, fam.min_id() + 7).unwrap();
        let (img, q) = cells_image(n, &cells, 96.0, [160.0, 160.0], 0.3);
        let view = GrayView::from(&img);
        let step = 1.0 / (n as f64 + 2.0);
        // The quad as drawn, under perspective, and pushed past the
        // image's left edge.
        let tilted = [
            q[0],
            [q[1][0] - 9.0, q[1][1] + 4.0],
            q[2],
            [q[3][0] + 6.0, q[3][1]],
        ];
        let outside = q.map(|p| [p[0] - 150.0, p[1]]);
        for quad in [q, tilted, outside] {
            let h = Homography::from_points(&CORNERS, &quad).unwrap();
            let means: Option<Vec<f64>> = (0..n * n)
                .map(|c| cell_mean(&view, &h, step, (c / n) as f64, (c % n) as f64))
                .collect();
            let sampled = sample_cells(&view, n, &h);
            assert_eq!(sampled.is_some(), means.is_some(), "{quad:?}");
            if let (Some(s), Some(m)) = (sampled, means) {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&s), bits(&m), "{quad:?}");
            }
        }
    }

    /// `decode_quad` trusts a reading by the code with as many corrected
    /// symbols as the detector does by default
    /// ([`Family::default_correction_limit`]): ct8 with 3 symbols misread
    /// reads, with 4 (within its code's capacity of 5) it does not; ct14
    /// with 4 reads.
    #[test]
    fn decode_quad_corrects_as_many_symbols_as_the_detector() {
        let read = |fam: &Family, misread: usize| {
            let id = fam.min_id() + 42;
            let mut cells = encode_cells(fam, id).unwrap();
            let bits = fam.code().symbol_bits() as usize;
            for s in 0..misread {
                let c = fam.code_cells()[s * bits];
                cells[c] = !cells[c];
            }
            let (img, q) = cells_image(fam.grid(), &cells, 96.0, [160.0, 160.0], 0.3);
            decode_quad(&img, fam, &q).map(|r| (r.id == id, r.corrected))
        };
        assert_eq!(read(Family::ct8(), 3), Some((true, 3)));
        assert_eq!(read(Family::ct8(), 4), None);
        assert_eq!(read(Family::ct14(), 4), Some((true, 4)));
    }

    /// A dark occluder over the top 40% of the data square and over the
    /// frame and margin rings along the top and the left side (more than
    /// half of both rings) pulls the rings' plain medians together: the
    /// tag reads only at the clear pairs' levels, which are the print's
    /// own, and says so.
    #[test]
    fn a_tag_whose_rings_an_occluder_covers_reads_at_the_clear_pairs_levels() {
        use crate::test_images::PAGE;
        let fam = Family::ct14();
        let (side, c, turn) = (96.0, [160.0, 160.0], 0.3);
        let (clean, q) = tag_image(147, side, c, turn);
        let r = decode_quad(&clean, fam, &q).expect("the clean tag reads");
        assert_eq!(r.id, 147);
        assert!(!r.clear_ring, "{r:?}");
        let (cs, sn) = (turn.cos(), turn.sin());
        let mut img = clean.clone();
        for (x, y, p) in img.enumerate_pixels_mut() {
            let (dx, dy) = (f64::from(x) - c[0], f64::from(y) - c[1]);
            let (u, v) = ((cs * dx + sn * dy) / side, (-sn * dx + cs * dy) / side);
            if u.abs().max(v.abs()) < 0.7 && (v < -0.1 || u < -0.45) {
                p.0 = [INK + 30];
            }
        }
        let h = Homography::from_points(&CORNERS, &q).unwrap();
        let view: GrayView = (&img).into();
        let (white, black) = ring_levels(&view, fam.grid(), &h).unwrap();
        assert!(
            white - black < DecodeParams::default().min_contrast,
            "the plain levels must fail for the test to mean anything: {white} {black}"
        );
        let (white, black) = clear_ring_levels(&view, fam.grid(), &h).unwrap();
        assert!((white - f64::from(PAGE)).abs() < 10.0, "{white}");
        assert!((black - f64::from(INK)).abs() < 10.0, "{black}");
        let r = decode_quad(&img, fam, &q).expect("read at the clear levels");
        assert_eq!(r.id, 147);
        assert!(r.clear_ring, "{r:?}");
    }

    /// A quad whose rings show one grey throughout has no clear levels
    /// worth a second reading.
    #[test]
    fn flat_rings_have_no_clear_contrast() {
        let img = image::GrayImage::from_pixel(200, 200, image::Luma([120]));
        let q = [[50.0, 50.0], [50.0, 150.0], [150.0, 150.0], [150.0, 50.0]];
        let h = Homography::from_points(&CORNERS, &q).unwrap();
        let (white, black) = clear_ring_levels(&(&img).into(), 14, &h).unwrap();
        assert!(white - black < MIN_CLEAR_CONTRAST);
        assert!(decode_quad(&img, Family::ct14(), &q).is_none());
    }

    /// The grid of a shape that is no tag (a margin and a frame around a
    /// flat grey inside) is refused as flat before any reading, while a
    /// tag's grid never is, even at its worst: every ct14 id and 4096 ct8
    /// ids, their cells faded to a third of the contrast (deep blur) and
    /// the 40% of them nearest a corner hidden under a flat occluder of
    /// the grey that spreads them least, keep a spread a tenth above
    /// [`FLAT_GRID_SPREAD`].
    #[test]
    fn only_grids_of_no_tag_are_flat() {
        let (mut img, q) = tag_image(77, 96.0, [160.0, 160.0], 0.0);
        let fam = Family::ct14();
        assert!(decode_quad(&img, fam, &q).is_some());
        // Paint the data square's inside (within the margin) one grey.
        let inner = 96.0 * (0.5 - 1.0 / 16.0);
        for (x, y, p) in img.enumerate_pixels_mut() {
            if (f64::from(x) - 160.0).abs() < inner && (f64::from(y) - 160.0).abs() < inner {
                p.0 = [90];
            }
        }
        let h = Homography::from_points(&CORNERS, &q).unwrap();
        let (white, black) = ring_levels(&(&img).into(), fam.grid(), &h).unwrap();
        let y = whiteness(&(&img).into(), fam.grid(), &h, black, white - black).unwrap();
        assert!(flat(&y));
        assert!(decode_quad(&img, fam, &q).is_none());

        let mut least = f64::INFINITY;
        for (fam, ids) in [(Family::ct14(), 256u64), (Family::ct8(), 4096)] {
            let n = fam.grid();
            let hidden = |c: usize| {
                let (i, j) = (c / n, c % n);
                (i + j) as f64 <= (2.0 * 0.4 * (n * n) as f64).sqrt()
            };
            for id in 0..ids {
                let cells = encode_cells(fam, id).unwrap();
                let faded: Vec<f64> = cells
                    .iter()
                    .map(|&b| 0.5 + if b { -1.0 } else { 1.0 } / 6.0)
                    .collect();
                for grey in [0.0, 0.5, 1.0] {
                    let y: Vec<f64> = (0..n * n)
                        .map(|c| if hidden(c) { grey } else { faded[c] })
                        .collect();
                    least = least.min(spread(&y));
                }
            }
        }
        assert!(
            least >= 1.1 * FLAT_GRID_SPREAD,
            "a tag's grid spread only {least}"
        );
    }

    /// The frame and margin around each corner of a tag read as printed
    /// where the corners are right (no cell misread), and not around a
    /// corner placed 1.2 cells along a side from its place, nor around
    /// corners under a grey or a black occluder (several misread).
    #[test]
    fn frame_reads_as_printed_around_right_corners_only() {
        let n = Family::ct14().grid();
        let (mut img, q) = tag_image(77, 96.0, [160.0, 160.0], 0.3);
        let misread = |img: &image::GrayImage, q: &[[f64; 2]; 4]| {
            let h = Homography::from_points(&CORNERS, q).unwrap();
            frame_misread_at_corners(&img.into(), n, &h).unwrap()
        };
        assert_eq!(misread(&img, &q), [0; 4]);
        // BR moved 1.2 cells (of 96 / 16 px) further along the side from BL.
        let mut off = q;
        let along = [q[2][0] - q[1][0], q[2][1] - q[1][1]];
        for a in 0..2 {
            off[2][a] += along[a] * 1.2 / 16.0;
        }
        let m = misread(&img, &off);
        assert!(m[2] >= 3, "a corner 7 px off read as seen: {m:?}");
        assert_eq!(m[0], 0, "the opposite corner, where it was: {m:?}");
        // A grey disc over TR and a black one over BL, 14 px (2.3 cells)
        // in radius.
        for (k, grey) in [(3, 125u8), (1, INK)] {
            let c = q[k];
            for (x, y, p) in img.enumerate_pixels_mut() {
                if (f64::from(x) - c[0]).hypot(f64::from(y) - c[1]) <= 14.0 {
                    p.0 = [grey];
                }
            }
        }
        let m = misread(&img, &q);
        assert_eq!([m[0], m[2]], [0, 0], "{m:?}");
        assert!(
            m[1] >= 3 && m[3] >= 3,
            "corners under occluders read as seen: {m:?}"
        );
    }

    /// No count, rather than a panic or a made-up one, where the cells
    /// cannot be read: a tag running off the image, a flat image with no
    /// black-to-white contrast, a degenerate quad.
    #[test]
    fn frame_misreads_are_none_where_the_cells_cannot_be_read() {
        let n = Family::ct14().grid();
        let (img, q) = tag_image(77, 96.0, [160.0, 160.0], 0.3);
        let shifted = q.map(|[x, y]| [x + 150.0, y]);
        let h = Homography::from_points(&CORNERS, &shifted).unwrap();
        assert_eq!(frame_misread_at_corners(&(&img).into(), n, &h), None);
        let flat = image::GrayImage::from_pixel(320, 320, image::Luma([128]));
        let h = Homography::from_points(&CORNERS, &q).unwrap();
        assert_eq!(frame_misread_at_corners(&(&flat).into(), n, &h), None);
        let line = [
            [100.0, 100.0],
            [120.0, 120.0],
            [140.0, 140.0],
            [160.0, 160.0],
        ];
        assert!(Homography::from_points(&CORNERS, &line)
            .and_then(|h| frame_misread_at_corners(&(&img).into(), n, &h))
            .is_none());
    }

    /// Marsaglia's xorshift generator (2003) from `seed`: the random
    /// grids of the glare tests.
    fn xorshift(mut s: u64) -> impl FnMut() -> u64 {
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    /// Whiteness of a tag's cells under a glare spot: cells near the spot's
    /// centre are lifted by up to `peak` (1 = the whole black-to-white gap).
    fn under_glare(family: &Family, id: u64, peak: f64) -> Vec<f64> {
        let n = family.grid();
        let black = encode_cells(family, id).unwrap();
        let (ci, cj, r) = (3.0, 10.0, 5.0);
        black
            .iter()
            .enumerate()
            .map(|(c, &b)| {
                let (i, j) = ((c / n) as f64, (c % n) as f64);
                let d2 = (i - ci).powi(2) + (j - cj).powi(2);
                let base = if b { 0.0 } else { 1.0 };
                base + peak * (-d2 / (2.0 * r * r)).exp()
            })
            .collect()
    }

    #[test]
    fn levelling_reads_a_tag_the_global_threshold_loses_to_glare() {
        let fam = Family::ct14();
        let y = under_glare(fam, 77, 1.2);
        assert!(
            read_cells(fam, &y, 0.2).is_none(),
            "the glare must defeat the plain reading for this test to mean anything"
        );
        let levelled = locally_levelled(&y, fam.grid());
        let r = read_cells(fam, &levelled, 0.2).expect("read after levelling");
        assert_eq!(r.id, 77);
    }

    /// Whiteness of tag `id` (black at grey level 40, white at 200) under
    /// a glare spot of `peak` grey levels at cell (3, 10), clipped at 255
    /// as a sensor clips it; with the levels to read it by.
    fn under_clipped_glare(family: &Family, id: u64, peak: f64) -> (Vec<f64>, f64, f64) {
        let (black, contrast) = (40.0, 160.0);
        let y = under_glare(family, id, peak / contrast)
            .iter()
            .map(|v| ((black + v * contrast).min(255.0) - black) / contrast)
            .collect();
        (y, black, contrast)
    }

    #[test]
    fn a_glare_clipping_part_of_the_tag_reads_on_erasures_alone() {
        let fam = Family::ct14();
        let (y, black, contrast) = under_clipped_glare(fam, 77, 500.0);
        let n_clipped = y.iter().filter(|&&v| clipped(v, black, contrast)).count();
        assert!(n_clipped > 50, "{n_clipped} cells clipped");
        // Neither the tag's levels nor its neighbourhoods read it.
        assert!(read_cells(fam, &y, 0.2).is_none());
        let cap = fam.code().parity() / 2 - SHADED_MARGIN;
        assert!(read_cells(fam, &locally_levelled(&y, fam.grid()), 0.2)
            .is_none_or(|r| r.corrected > cap || !within_limit(&r, 9)));
        let r = read_glared(fam, &y, black, contrast, 0.2).expect("read under glare");
        assert_eq!((r.id, r.rotation, r.errors), (77, 0, 0));
        // Past the limit: it stands as a glare reading only.
        assert!(r.erased > 9, "{r:?}");
        assert!(check_bits(fam, r.erased) >= GLARE_CHECK_BITS);
    }

    /// Grey levels of the cells of tag `id` (black at 40, white at 200)
    /// under a glare spot centred on cell (8, 7): clipped at 255 within
    /// `radius` cells, a tail of 40 grey levels fading over two cells
    /// around it (which clips no cell by itself: at most 240).
    fn under_wide_glare(family: &Family, id: u64, radius: f64) -> Vec<f64> {
        let n = family.grid();
        let black = encode_cells(family, id).unwrap();
        black
            .iter()
            .enumerate()
            .map(|(c, &b)| {
                let (i, j) = ((c / n) as f64, (c % n) as f64);
                let d = ((i - 8.0).powi(2) + (j - 7.0).powi(2)).sqrt();
                let base = if b { 40.0 } else { 200.0 };
                if d < radius {
                    255.0
                } else {
                    (base + 40.0 * (-(d - radius).powi(2) / 8.0).exp()).min(255.0)
                }
            })
            .collect()
    }

    #[test]
    fn a_glare_over_half_the_tag_reads_by_the_nearest_codeword_of_what_it_left() {
        let fam = Family::ct14();
        let corners = [[10.0, 10.0], [10.0, 90.0], [90.0, 90.0], [90.0, 10.0]];
        for id in [5u64, 77, 230] {
            let cells = under_wide_glare(fam, id, 5.5);
            let n_clipped = cells.iter().filter(|&&v| v >= SATURATED_DN).count();
            assert!(n_clipped >= 90, "{n_clipped} of 196 cells clipped");
            let y: Vec<f64> = cells.iter().map(|v| (v - 40.0) / 160.0).collect();
            // The glare reading by the code keeps too few whole symbols: it
            // corrects more than a levelled reading may, and some as errors.
            let cap = fam.code().parity() / 2 - SHADED_MARGIN;
            assert!(read_glared(fam, &y, 40.0, 160.0, 0.2)
                .is_none_or(|r| !stands_past_limit(fam, &r) && r.corrected > cap));
            let r = read_glare_nearest(fam, Levelled::new(&cells, (200.0, 40.0)), &corners)
                .expect("read by the nearest codeword");
            assert_eq!((r.id, r.rotation), (id, 0));
            assert!(r.glared && r.occluded && r.likelihood, "{r:?}");
        }
        // Without a clipped cell, there is no glare to read under.
        let cells = under_wide_glare(fam, 77, 0.0);
        assert!(read_glare_nearest(fam, Levelled::new(&cells, (200.0, 40.0)), &corners).is_none());
    }

    #[test]
    fn clipped_grids_of_no_tag_read_as_no_codeword() {
        // Random grids under clipped glare spots from a few cells to the
        // whole grid: none may read as a tag.
        let mut next = xorshift(0x2545_F491_4F6C_DD1D);
        let fam = Family::ct14();
        let n = fam.grid();
        let corners = [[10.0, 10.0], [10.0, 90.0], [90.0, 90.0], [90.0, 10.0]];
        for k in 0..3000 {
            let reach = (1 + k % 30) as f64 * 0.25;
            let cells: Vec<f64> = (0..n * n)
                .map(|c| {
                    let (i, j) = ((c / n) as f64, (c % n) as f64);
                    let base = if next() & 1 == 1 { 200.0 } else { 40.0 };
                    let d2 = (i - 9.0).powi(2) + (j - 6.0).powi(2);
                    (base + 900.0 * (-d2 / (2.0 * reach * reach)).exp()).min(255.0)
                })
                .collect();
            let r = read_glare_nearest(fam, Levelled::new(&cells, (200.0, 40.0)), &corners);
            assert!(r.is_none(), "grid {k}: {r:?}");
        }
    }

    #[test]
    fn an_evenly_lit_tag_is_no_glare_reading() {
        let fam = Family::ct14();
        let (y, black, contrast) = under_clipped_glare(fam, 77, 0.0);
        assert!(read_glared(fam, &y, black, contrast, 0.2).is_none());
    }

    #[test]
    fn glare_readings_keep_24_bits_of_check_beyond_the_id() {
        // ct14: 20 symbols of 8 bits, 8 bits of id.
        assert!(check_bits(Family::ct14(), 16) >= GLARE_CHECK_BITS);
        assert!(check_bits(Family::ct14(), 17) < GLARE_CHECK_BITS);
        // ct8: 15 symbols of 4 bits, 16 bits of id.
        assert!(check_bits(Family::ct8(), 5) >= GLARE_CHECK_BITS);
        assert!(check_bits(Family::ct8(), 6) < GLARE_CHECK_BITS);
    }

    #[test]
    fn clipped_grids_of_no_tag_give_no_glare_reading_past_the_limit() {
        // Random grids under clipped glare spots of every size, from a few
        // cells to the whole grid: a reading past the limit would be a
        // wrong id (odds of 4 in 2^24 each with 24 bits of check; with 4
        // bits, 33 of these grids read).
        let mut next = xorshift(0x9E37_79B9_7F4A_7C15);
        let (black, contrast) = (40.0, 160.0);
        let mut past = 0;
        for fam in [Family::ct14(), Family::ct8()] {
            let n = fam.grid();
            for k in 0..4000 {
                let reach = (1 + k % 40) as f64 * 0.25 * n as f64 / 10.0;
                let y: Vec<f64> = (0..n * n)
                    .map(|c| {
                        let (i, j) = ((c / n) as f64, (c % n) as f64);
                        let base = (next() & 1) as f64;
                        let d2 = (i - 0.3 * n as f64).powi(2) + (j - 0.7 * n as f64).powi(2);
                        let v =
                            black + contrast * base + 400.0 * (-d2 / (2.0 * reach * reach)).exp();
                        (v.min(255.0) - black) / contrast
                    })
                    .collect();
                if let Some(r) = read_glared(fam, &y, black, contrast, 0.2) {
                    if !(within_limit(&r, 9) && r.corrected <= 7) && stands_past_limit(fam, &r) {
                        past += 1;
                    }
                }
            }
        }
        assert_eq!(past, 0, "grids of no tag read past the limit");
    }

    #[test]
    fn erasures_count_half_within_the_limit_but_never_beyond_it() {
        let r = |corrected, erased, errors| GridReading {
            id: 0,
            rotation: 0,
            corrected,
            erased,
            errors,
        };
        assert!(within_limit(&r(9, 0, 9), 9));
        assert!(!within_limit(&r(10, 0, 10), 9));
        // 2 errors and 12 erasures weigh 16 <= 18 but rest on 12 erasures.
        assert!(!within_limit(&r(14, 12, 2), 9));
        // 4 errors and 8 erasures: 16 <= 18, 8 erasures.
        assert!(within_limit(&r(12, 8, 4), 9));
        assert!(!within_limit(&r(14, 8, 6), 9));
    }

    #[test]
    fn levelling_keeps_an_evenly_lit_tag() {
        let fam = Family::ct14();
        let y = under_glare(fam, 200, 0.0);
        let r = read_cells(fam, &locally_levelled(&y, fam.grid()), 0.2).unwrap();
        assert_eq!((r.id, r.corrected), (200, 0));
    }

    #[test]
    fn levelling_subtracts_the_neighbourhood_mean() {
        // A 5 x 5 grid of one grey level stays at a half everywhere; a lone
        // bright cell rises above it by what it differs from its window.
        let mut y = vec![0.3; 25];
        assert!(locally_levelled(&y, 5)
            .iter()
            .all(|v| (v - 0.5).abs() < 1e-12));
        y[12] = 1.3;
        let l = locally_levelled(&y, 5);
        assert!((l[12] - (1.3 - (0.3 * 24.0 + 1.3) / 25.0 + 0.5)).abs() < 1e-12);
        // A corner cell's window is clipped to 3 x 3.
        assert!((l[0] - (0.3 - (0.3 * 8.0 + 1.3) / 9.0 + 0.5)).abs() < 1e-12);
    }
}

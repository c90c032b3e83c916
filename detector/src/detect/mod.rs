//! The detection pipeline: image in, decoded tags out.
//!
//! One driver, [`Detector::detect`], runs the stages in order, each in its
//! own (crate-private) module of plain functions, `detect/<stage>.rs`,
//! and each handing a plain value to the next
//! (the shape of the paper's section III.B and of AprilTag 3's
//! `apriltag_detector_detect`):
//!
//! 1. `threshold`: optional 2x downsampling, adaptive mean threshold;
//! 2. `contours`: border following (Suzuki & Abe 1985);
//! 3. `lines`, `corners` and `bridges`: Douglas-Peucker, line fits
//!    oriented dark on the right, anticlockwise corners (the paper's
//!    Algorithm 1); line pieces of one edge cut by an occluder bridged
//!    across the gap, linking their borders;
//! 4. `ellipses`: the disc rim as ellipse candidates from arcs, robust to
//!    a partly hidden rim;
//! 5. `quads`: candidate quads, with the triangle, same-side, symmetry and
//!    diagonal occlusion cases (the paper's Algorithm 2) and, last, one
//!    corner around the centre checker; each carries the edge pieces its
//!    corners were seen on;
//! 6. `decoding`: `refine` (sub-pixel corners along those edge pieces),
//!    `pitch` (which built-in family's cell grid the square shows: the
//!    other family is not read on it), then [`crate::decode_quad_with`]
//!    at full resolution (the cells read
//!    one by one through the Reed-Solomon code; for a ct14 tag the code
//!    cannot read, as a whole against every codeword, cell by cell or as
//!    the blur shows it: `likelihood`), rival readings of
//!    one tag; `small`: when the image was downsampled, stages 1-6 again
//!    at full resolution in the regions around disc rims too small to
//!    decode at half size; then one detection per tag;
//! 7. `verify`: the decoded tag's own model (margin, cell edges) re-fits
//!    each detection's homography with robust weights, gives each corner
//!    an uncertainty (growing with the edges' measured blur) and drops
//!    readings the fit contradicts.
//!
//! Every threshold is either a [`DetectorConfig`] setting or a named,
//! documented constant of its stage module; the stage parameter structs are
//! built from the config once, in [`Detector::new`]. Stage timings and
//! counts of the last frame are in [`DetectionStats`], kept apart from the
//! settings. The detector owns its buffers and resizes them per frame;
//! nothing has to be reset by callers.

pub(crate) mod bridges;
mod by_x;
mod config;
mod contour_bands;
pub(crate) mod contours;
pub(crate) mod corners;
pub(crate) mod decoding;
mod edge_bias;
pub(crate) mod ellipses;
pub(crate) mod lines;
mod outline;
mod parallel;
mod pitch;
mod print_align;
pub(crate) mod quads;
mod read_ahead;
pub(crate) mod refine;
pub(crate) mod reject;
mod rim;
pub(crate) mod small;
pub(crate) mod threshold;
pub(crate) mod verify;

use std::time::{Duration, Instant};

use serde::Serialize;

pub use config::{DetectorConfig, FamilySetting, CT8_MAX_CORRECTED, MAX_THREADS};

use parallel::Workers;
use rayon::prelude::*;

use crate::decode::DecodeParams;
use crate::homography::Homography;
use crate::view::GrayView;
use crate::Result;

/// One detected tag.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// Family name.
    pub family: String,
    /// Decoded id.
    pub id: u64,
    /// Data-square corners TL, BL, BR, TR (pixel-centre coordinates of the
    /// input image); corner 0 is always the tag's physical top-left.
    pub corners: [[f64; 2]; 4],
    /// Which corners were estimated (hidden, recovered from the other
    /// corners' lines or the tag centre, or with no visible edge of the
    /// tag near them) rather than measured.
    pub estimated: [bool; 4],
    /// One-sigma uncertainty of each corner (px, radial: the root of the
    /// trace of its 2 x 2 covariance), from the fit of the tag's model to
    /// its visible edges; for a small, blurred tag placed by the printed
    /// tag's fixed look aligned to the image where that fit found no
    /// geometry that reads (every corner then estimated), a share of the
    /// side; `None` when the tag was too small or too hidden for the fit
    /// and its corners are the side lines' intersections.
    pub corner_sigma: Option<[f64; 4]>,
    /// Reed-Solomon symbols corrected while decoding: 0 for a clean read;
    /// filter on it for confidence. For a tag read by likelihood
    /// ([`Detection::likelihood`]) it is the symbols a cell-by-cell reading
    /// got wrong, usually more than the code corrects.
    pub corrected: usize,
    /// Read by likelihood: a ct14 tag whose cells the Reed-Solomon decoder
    /// could not read (heavily occluded or blurred), matched against every
    /// codeword, cell by cell or as the blur shows it, clearly better than
    /// any other id. Such a reading is
    /// reported only when the fit of the tag's model to its edges confirms
    /// its geometry, or, on a tag placed by its aligned print whose fit
    /// found nothing that reads, with every corner estimated
    /// (`corner_sigma` is set either way).
    pub likelihood: bool,
    /// Read as under an occluder: a likelihood reading by its nearest
    /// codeword cell by cell, or a code reading under glare resting on
    /// more erasures than the family's limit (the verify stage judges such
    /// readings more strictly).
    #[serde(skip)]
    pub(crate) occluded: bool,
    /// Read in a small-tag region upsampled 2x (`small`): its hidden
    /// corners are judged as a nearest-codeword reading's are.
    #[serde(skip)]
    pub(crate) upsampled: bool,
    /// Placed rather than measured: read by the rim look (`rim`), on a tag
    /// too blurred or small to make a quad, or a faint reading
    /// (`faint`) confirmed by the aligned print. Its corners are the
    /// aligned print's or the model fit's, the verify stage keeps them,
    /// and their uncertainty has a floor in proportion to the side
    /// (`decoding::RIM_SIGMA_OF_SIDE`).
    #[serde(skip)]
    pub(crate) placed: bool,
    /// Read by likelihood at a faint contrast
    /// (`crate::decode::QuadReading::faint`): it stands only on the
    /// aligned print (`decoding::unless_faint`).
    #[serde(skip)]
    pub(crate) faint: bool,
    /// Kept only as a last resort: read under a smooth light field
    /// (`decode::QuadReading::shaded`) or at the levels of the clearer
    /// half of the frame and margin rings
    /// (`decode::QuadReading::clear_ring`).
    #[serde(skip)]
    pub(crate) last_resort: bool,
    /// Read by the nearest codeword on cells levelled under glare
    /// (`decode::QuadReading::glared`): it stands only with every corner
    /// seen, as a last resort, and only such a reading confirms it in the
    /// verify stage.
    #[serde(skip)]
    pub(crate) glared: bool,
    /// Placed on the aligned print with no fit of the model confirming it
    /// (`decoding::unfitted_on_aligned`): every corner estimated, its
    /// sigma a share of the side; kept only as a last resort.
    #[serde(skip)]
    pub(crate) unfitted: bool,
    /// Image of the tag center (intersection of the diagonals).
    pub center: [f64; 2],
    /// Measured contrast between the tag's white and black (grey levels).
    pub contrast: f64,
    /// Homography from tag units (data square side 1, center 0, y down) to
    /// image pixels; serialised row-major.
    pub homography: Homography,
}

/// Times of the pipeline stages for one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageTimes {
    /// Downsampling: zero, since the 2x downsampling is done in the
    /// threshold's single pass over the image (its time is in
    /// [`StageTimes::threshold`]); kept so that logs keep their columns.
    pub downsample: Duration,
    /// Downsampling and adaptive threshold (one pass).
    pub threshold: Duration,
    /// Border following.
    pub contours: Duration,
    /// Polygons and lines.
    pub lines: Duration,
    /// Corners. With worker threads ([`DetectorConfig::threads`]) the
    /// corners and the ellipses are found at once, and the time they took
    /// together is split between the two in proportion to each one's own.
    pub corners: Duration,
    /// Ellipses and their anchors (with worker threads, see
    /// [`StageTimes::corners`]).
    pub ellipses: Duration,
    /// Candidate quads.
    pub quads: Duration,
    /// Refinement and decoding.
    pub decode: Duration,
    /// The full-resolution second look around small disc rims (its own
    /// segmentation, refinement and decoding; see
    /// [`DetectorConfig::small_tags`]). With worker threads
    /// ([`DetectorConfig::threads`]) it also holds most of the model fits
    /// of [`StageTimes::verify`]: the tags found before it are fitted
    /// beside it.
    pub small: Duration,
    /// The last look, at the disc rims no stage before found a tag in: a
    /// quad predicted from each rim, its sides measured and decoded
    /// (`rim`).
    pub rim: Duration,
    /// One detection per tag, sorted.
    pub dedup: Duration,
    /// Model fit of each detection (with worker threads, of those the
    /// fits made beside [`StageTimes::small`] did not cover).
    pub verify: Duration,
    /// Whole frame: the whole call of [`Detector::detect`], with worker
    /// threads the time they take to come awake included (the stages
    /// above run once they are).
    pub total: Duration,
}

impl StageTimes {
    /// Every stage's name and time, in pipeline order, then `"total"`.
    pub fn iter(&self) -> impl Iterator<Item = (&'static str, Duration)> {
        [
            ("downsample", self.downsample),
            ("threshold", self.threshold),
            ("contours", self.contours),
            ("lines", self.lines),
            ("corners", self.corners),
            ("ellipses", self.ellipses),
            ("quads", self.quads),
            ("decode", self.decode),
            ("small", self.small),
            ("rim", self.rim),
            ("dedup", self.dedup),
            ("verify", self.verify),
            ("total", self.total),
        ]
        .into_iter()
    }
}

/// Statistics of the last frame (times and counts), for profiling and logs.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DetectionStats {
    /// Input size.
    pub width: u32,
    /// Input size.
    pub height: u32,
    /// Stage times.
    pub times: StageTimes,
    /// Borders kept.
    pub contours: usize,
    /// Lines fitted.
    pub lines: usize,
    /// Corners formed.
    pub corners: usize,
    /// Ellipses accepted.
    pub ellipses: usize,
    /// Candidate quads after de-duplication.
    pub candidates: usize,
    /// Candidates refined and decoded (the rest were inside a tag already
    /// found or over the cap), both passes.
    pub decode_attempts: usize,
    /// Regions around small disc rims taken for a second look at full
    /// resolution, those passed over at once for a flat middle included.
    pub small_regions: usize,
    /// Candidates the rim look predicted from disc rims alone and decoded
    /// (counted in `decode_attempts` too); it stops after
    /// `RIM_MAX_FAILED_RUN` (10) in a row that read nothing.
    pub rim_decodes: usize,
    /// Tags reported.
    pub detections: usize,
}

/// The stage parameter structs, built once from the [`DetectorConfig`].
#[derive(Debug, Clone, Copy)]
struct StageParams {
    threshold: threshold::ThresholdParams,
    /// Shortest border kept (points).
    min_contour_points: usize,
    lines: lines::LineParams,
    corners: corners::CornerParams,
    ellipses: ellipses::EllipseParams,
    quads: quads::QuadParams,
    decoding: decoding::DecodingParams<'static>,
}

impl StageParams {
    fn new(cfg: &DetectorConfig) -> Self {
        // The refinement windows are sized in cells of the finest family.
        let cells_per_side = cfg
            .families
            .iter()
            .map(|f| f.family.grid() + refine::MARGIN_CELLS)
            .max()
            .unwrap_or(0) as f64;
        Self {
            threshold: threshold::ThresholdParams {
                downsample: cfg.downsample == 2,
                radius: cfg.threshold_radius as usize,
                offset: cfg.threshold_offset,
            },
            min_contour_points: cfg.min_contour_points,
            lines: lines::LineParams {
                dp_epsilon: cfg.dp_epsilon,
                min_length: cfg.min_line_length,
            },
            corners: corners::CornerParams {
                sin_min_angle: cfg.corner_min_angle_deg.to_radians().sin(),
                max_gap: cfg.corner_max_gap,
            },
            ellipses: ellipses::EllipseParams {
                min_minor: cfg.ellipse_min_minor,
                min_arc_points: ellipses::RIM_BORDER_FACTOR * cfg.min_contour_points,
                max_rms: cfg.ellipse_max_rms,
                pair_fragments: true,
            },
            quads: quads::QuadParams {
                min_side: cfg.quad_min_side,
                cos_edge: cfg.edge_max_angle_deg.to_radians().cos(),
                recover: cfg.recover_occluded,
                max_candidates: cfg.max_candidates * quads::CANDIDATES_PER_DECODE,
                replace_dist: cfg.corner_max_gap,
            },
            decoding: decoding::DecodingParams {
                max_attempts: cfg.max_candidates,
                max_in_vain_run: usize::MAX,
                max_rivals: decoding::MAX_RIVALS,
                refine: refine::RefineParams {
                    refine: cfg.refine_corners,
                    cells_per_side,
                    min_edge_contrast: refine::MIN_EDGE_CONTRAST,
                },
                decode: DecodeParams::default(),
                fits: None,
                others: &[],
            },
        }
    }
}

/// Buffers kept between frames (the detector's own, and one per worker
/// thread when it has a pool).
#[derive(Debug, Default)]
struct Workspace {
    seg: Segmentation,
    rscratch: refine::RefineScratch,
    /// A small-tag region upsampled 2x, and its rows upsampled
    /// horizontally ([`small::upsample_2x`]).
    up: Vec<u8>,
    up_rows: Vec<u16>,
    /// The guessed candidates of a region's full-resolution look, kept
    /// for after its upsampled look ([`small_region`]).
    guessed: Vec<quads::Candidate>,
    /// The main look's disc rims, for the rim look ([`rim_look`]).
    rims: Vec<ellipses::Ellipse>,
    /// The rim look's candidates.
    rim_cands: Vec<quads::Candidate>,
}

/// The buffers of stages 1-5, from the working image to candidate quads.
#[derive(Debug, Default)]
struct Segmentation {
    tscratch: threshold::ThresholdScratch,
    binary: Vec<u8>,
    /// `binary` as thresholded, one bit a pixel, when stage 2 runs in
    /// bands: they label their rows of `binary` and read foreground here.
    copy: Vec<u64>,
    bscratch: contour_bands::BandScratch,
    contours: contours::Contours,
    polys: lines::Polygons,
    links: bridges::Links,
    corners: Vec<corners::Corner>,
    ellipses: Vec<ellipses::Ellipse>,
    escratch: ellipses::EllipseScratch,
    candidates: Vec<quads::Candidate>,
    qscratch: quads::QuadScratch,
}

/// Fewest working rows of a threshold band: each band re-reads the
/// `2 radius` rows around its ends (radius 10 by default), so shorter
/// bands would spend a good share of their time on rows of their
/// neighbours.
const MIN_BAND_ROWS: usize = 64;

/// Bands of the threshold per worker thread: two, so that a thread
/// slowed by another process leaves a band for the other threads to take.
const BANDS_PER_THREAD: usize = 2;

impl Segmentation {
    /// Stages 1 (downsampling and threshold) to 5 (candidate quads) on
    /// `img`, on `workers`' threads if given; the candidates are left in
    /// `self.candidates`, each stage's time added to `times`. Returns the
    /// working image's scale.
    fn run(
        &mut self,
        img: &GrayView<'_>,
        p: &StageParams,
        workers: Option<&Workers<Workspace>>,
        times: &mut StageTimes,
    ) -> f64 {
        let mut laps = Laps(Instant::now());
        let work = match workers {
            None => threshold::threshold(img, &p.threshold, &mut self.tscratch, &mut self.binary),
            Some(w) => threshold_bands(img, &p.threshold, w, &mut self.binary, &mut self.copy),
        };
        times.threshold += laps.lap();
        let (ww, wh) = (work.width, work.height);
        let (pw, ph) = (ww + 2, wh + 2);
        let (min_len, max_len) = (p.min_contour_points, contours::max_border_len(ww, wh));
        match workers {
            None => contours::find_contours(
                &mut self.binary,
                pw,
                ph,
                min_len,
                max_len,
                &mut self.contours,
            ),
            Some(w) => contour_bands::find_contours(
                &mut self.binary,
                &self.copy,
                pw,
                ph,
                min_len,
                max_len,
                w,
                &mut self.bscratch,
                &mut self.contours,
            ),
        }
        times.contours += laps.lap();
        lines::extract(&self.contours, &p.lines, workers, &mut self.polys);
        times.lines += laps.lap();
        // Stages 4a (corners) and 4b (ellipses) read the borders and lines
        // alone, so with worker threads they run at once, each split
        // further across the threads: the threads that finish their pieces
        // of one take pieces of the other rather than wait at the end of
        // each (on the wild benchmark's 4K frames, 2 threads, the two took
        // 2.4-2.5 ms a frame one after the other and 2.2-2.3 ms at once,
        // where one thread took 3.7-3.8 ms). The time they took together
        // is then split between
        // them in proportion to each one's own, so that the stages still
        // add up to the frame.
        let Self {
            contours,
            polys,
            links,
            corners,
            ellipses,
            escratch,
            ..
        } = self;
        let (contours, polys, scale) = (&*contours, &*polys, work.scale);
        let mut corners_of = move || {
            let t = Instant::now();
            corners::find_corners(polys, &p.corners, workers, corners);
            bridges::find_bridges(polys, workers, links);
            let plain = corners.len();
            bridges::add_gap_corners(polys, &p.corners, workers, links, corners);
            (plain, t.elapsed())
        };
        let mut ellipses_of = move || {
            let t = Instant::now();
            ellipses::find_ellipses(contours, polys, &p.ellipses, workers, escratch, ellipses);
            // A rim from fragments alone stands only where the image shows
            // a dark disc on white around it.
            ellipses.retain(|e| !e.pieced || rim::stands_out(img, e, scale));
            ellipses::find_anchors(contours, ellipses);
            t.elapsed()
        };
        let (plain, corners_time, ellipses_time) = match workers {
            None => {
                let (plain, c) = corners_of();
                (plain, c, ellipses_of())
            }
            Some(w) => {
                let ((plain, c), e) = w.install(|| rayon::join(corners_of, ellipses_of));
                let both = laps.lap();
                let share = c.as_secs_f64() / (c + e).as_secs_f64().max(f64::MIN_POSITIVE);
                let c = both.mul_f64(share.clamp(0.0, 1.0));
                (plain, c, both.saturating_sub(c))
            }
        };
        times.corners += corners_time;
        times.ellipses += ellipses_time;
        laps.lap();
        quads::find_candidates(
            &self.corners,
            plain,
            &self.links,
            &self.ellipses,
            &p.quads,
            workers,
            &mut self.qscratch,
            &mut self.candidates,
        );
        times.quads += laps.lap();
        work.scale
    }
}

/// How far under the smallest readable side (`decoding::RIM_MIN_CELL_PX`)
/// the side a rim predicts may be for its candidate to be decoded: the
/// prediction's own error (on the wild set the quads from the rim were
/// within 10% of the truth's area-equivalent side for 90% of the tags).
const RIM_SIDE_TOLERANCE: f64 = 0.1;

/// Largest cell (px) of a tag the rim look reads: a tag of larger cells
/// keeps the one-cell margin around its data square through the blur a
/// robot's camera sees, and makes a quad of its own. On the wild set
/// (defocus up to sigma 2 px, motion up to 6 px) the rim look read no tag
/// with cells over 2.8 px (ct14 sides of 44 px); on the wild benchmark's
/// 1080p frames with ct14 alone, the ct8 tags and large round clutter it
/// decoded instead cost 3-3.5 ms a frame.
const RIM_MAX_CELL_PX: f64 = 4.0;

/// Most rim candidates in a row the rim look decodes in vain before it
/// gives up on the frame's other rims (a candidate read, or found to be
/// another family's print, starts the count again). A rim costs 1-2.5 ms
/// to decode in vain (print alignment, the aligned read, up to six moved
/// reads, the refined read), and on photographs of printed text every
/// round letter is a rim: the slowest frame of the wild benchmark's
/// tag-free photographs (fp-photos 000087) spent 55 ms of its 67 ms on 22
/// such rims, none a tag. On the wild set (3000 frames, 1454 rim looks,
/// 258 tags read from the rim) the longest run of rims decoded in vain
/// before one that read was 7, and 241 of the 244 looks that read a tag
/// read each after at most 1 in vain; the cap leaves that margin, and a
/// board of many small tags, whose reads break the runs, is looked at
/// whole.
const RIM_MAX_FAILED_RUN: usize = 10;

/// Whether the anchor of rim `e` (working coordinates, `scale` full px per
/// working px) lies in any of the `quads` (full-resolution corners).
fn rim_inside<'a>(
    e: &ellipses::Ellipse,
    scale: f64,
    mut quads: impl Iterator<Item = &'a [[f64; 2]; 4]>,
) -> bool {
    let a = crate::math::to_full(e.anchor, scale);
    quads.any(|q| crate::math::inside(q, a))
}

/// The rim look: a candidate predicted from each of the disc `rims` of
/// the main look ([`rim::rim_candidate`], `scale` the main look's) whose
/// anchor lies in no tag `found` so far and in no data square of a family
/// not decoded (`foreign`, see [`decoding::Decoded::foreign`]), decoded in
/// the rims' order, at most `budget`, and no further once
/// [`RIM_MAX_FAILED_RUN`] in a row have read nothing. Returns the tags
/// found, the readings that stand only as last resorts
/// ([`decoding::last_resorts`]; see `decoding::unfitted_on_aligned`) and
/// the candidates decoded.
#[allow(clippy::too_many_arguments)]
fn rim_look(
    img: &GrayView<'_>,
    scale: f64,
    budget: usize,
    targets: &[decoding::Target],
    p: &decoding::DecodingParams,
    ws: &mut Workspace,
    rims: &[ellipses::Ellipse],
    found: &[decoding::Found],
    foreign: &[decoding::Quad],
) -> (Vec<decoding::Found>, Vec<decoding::Found>, usize) {
    // The smallest data square a rim reading may have (see
    // `decoding::RIM_MIN_CELL_PX`), less the rim's own uncertainty: a
    // rim too small for every family is not decoded.
    let cells = targets
        .iter()
        .map(|t| (t.family.grid() + refine::MARGIN_CELLS) as f64);
    let min_side = cells.clone().fold(f64::INFINITY, f64::min)
        * decoding::RIM_MIN_CELL_PX
        * (1.0 - RIM_SIDE_TOLERANCE);
    // And the largest: a tag of larger cells keeps a quad of its own.
    let max_side = cells.fold(0.0, f64::max) * RIM_MAX_CELL_PX * (1.0 + RIM_SIDE_TOLERANCE);
    let mut cands = std::mem::take(&mut ws.rim_cands);
    cands.clear();
    cands.extend(
        rims.iter()
            .filter(|e| !rim_inside(e, scale, found.iter().map(|f| &f.detection().corners)))
            .filter(|e| !rim_inside(e, scale, foreign.iter()))
            .filter(|e| {
                // Every side of the square the rim predicts lies between
                // its two axes over the rim's radius.
                let (long, short) = rim::side_bounds(e, scale);
                long >= min_side && short <= max_side
            })
            .filter_map(|e| rim::rim_candidate(img, e, scale)),
    );
    let params = decoding::DecodingParams {
        max_attempts: budget,
        max_in_vain_run: RIM_MAX_FAILED_RUN,
        ..*p
    };
    let out = decoding::decode_candidates(img, &cands, scale, targets, &params, &mut ws.rscratch);
    ws.rim_cands = cands;
    (out.found, out.last_resort, out.attempts)
}

/// Stage 1 ([`threshold::threshold`]) in bands of rows on `workers`'
/// threads, each with the buffers of the thread it runs on; the same bytes
/// as one pass. Then `copy` is made the image packed one bit a pixel
/// ([`contour_bands::pack`]): stage 2's bands (`contour_bands`) read the
/// image as thresholded there.
fn threshold_bands(
    img: &GrayView<'_>,
    p: &threshold::ThresholdParams,
    workers: &Workers<Workspace>,
    out: &mut Vec<u8>,
    copy: &mut Vec<u64>,
) -> threshold::Working {
    let work = threshold::working(img, p);
    let (w, h) = (work.width, work.height);
    let rows = threshold::frame(&work, out);
    let bands = (workers.threads() * BANDS_PER_THREAD)
        .min(h / MIN_BAND_ROWS)
        .max(1);
    let per = h.div_ceil(bands).max(1);
    let pw = w + 2;
    workers.install(|| {
        rows.par_chunks_mut(per * pw)
            .enumerate()
            .for_each(|(k, band)| {
                let y0 = k * per;
                let mut ws = workers.scratch();
                let rows = y0..(y0 + per).min(h);
                threshold::threshold_rows(img, p, &work, rows, &mut ws.seg.tscratch, band);
            });
    });
    contour_bands::pack(out, workers, copy);
    work
}

/// The full-resolution second look in one small-tag region `r` of `img`
/// whose rim's middle is not flat ([`small::worth_looking`]): stages 1-5
/// on the region at full resolution, then its rim's candidates
/// decoded, at most `budget` of them; for a rim of a very small tag where
/// that read nothing, the same on the region upsampled 2x; where still
/// nothing read, the full-resolution look's guessed candidates (see
/// `quads::one_corner`), kept back so that they neither count against the
/// upsampled look nor come before it. A rim whose square shows a family
/// not decoded ([`decoding::Decoded::foreign`]) is that family's tag, and
/// is not looked at further. Returns what the looks decoded.
fn small_region(
    img: &GrayView<'_>,
    r: &small::Region,
    d: &SmallPass<'_>,
    budget: usize,
    ws: &mut Workspace,
) -> decoding::Decoded {
    let middle = small::Middle::of(img, r);
    if !small::worth_looking(middle) {
        return decoding::Decoded::default();
    }
    let view = img.crop(r.x0, r.y0, r.w, r.h);
    let first = small_look(img, &view, r, 1.0, d, budget, ws);
    if !first.found.is_empty() || !first.foreign.is_empty() {
        return first;
    }
    let n = first.attempts;
    // The guessed candidates are taken before the upsampled look reuses
    // the segmentation's buffers.
    let mut guessed = std::mem::take(&mut ws.guessed);
    guessed.clear();
    guessed.extend(
        ws.seg
            .candidates
            .iter()
            .filter(|c| c.guessed)
            .filter_map(|c| small::of_rim(c, r, 1.0)),
    );
    let mut out = small_upsampled(img, r, middle, d, budget, n, ws);
    if out.found.is_empty()
        && out.foreign.is_empty()
        && out.attempts < budget
        && !guessed.is_empty()
    {
        let more = decode_small(img, &guessed, d, budget - out.attempts, ws);
        out = decoding::Decoded {
            attempts: out.attempts + more.attempts,
            ..more
        };
    }
    ws.guessed = guessed;
    let (mut last_resort, mut unread) = (first.last_resort, first.unread);
    last_resort.append(&mut out.last_resort);
    unread.append(&mut out.unread);
    decoding::Decoded {
        last_resort,
        unread,
        ..out
    }
}

/// The upsampled look of [`small_region`] after a full-resolution look
/// that read nothing in `n` candidates decoded, where the rim is small and
/// its middle (`middle`) patterned enough for it: what it decoded, its
/// attempts counting the `n` before it.
fn small_upsampled(
    img: &GrayView<'_>,
    r: &small::Region,
    middle: small::Middle,
    d: &SmallPass<'_>,
    budget: usize,
    n: usize,
    ws: &mut Workspace,
) -> decoding::Decoded {
    let none = decoding::Decoded {
        attempts: n,
        ..Default::default()
    };
    if n >= budget || n > small::MAX_PLAIN_READS_TO_UPSAMPLE || !small::worth_upsampling(r, middle)
    {
        return none;
    }
    let Some(t) = r.tight() else {
        return none;
    };
    // Nothing read at full resolution: once more upsampled 2x (see
    // `small::UPSAMPLE_BELOW_SIDE_PX`).
    let (mut rows, mut up) = (std::mem::take(&mut ws.up_rows), std::mem::take(&mut ws.up));
    let (w2, h2) = small::upsample_2x(&img.crop(t.x0, t.y0, t.w, t.h), &mut rows, &mut up);
    let zoomed = GrayView::packed(&up, w2 as usize, h2 as usize);
    let mut out = small_look(img, &zoomed, &t, 2.0, d, budget - n, ws);
    for f in &mut out.found {
        f.mark_upsampled();
    }
    // An upsampled reading's hidden corners never stand on the fit alone
    // (`decoding::hidden_corners_fitted`). Its shaded readings
    // (`decode::QuadReading::shaded`) go with them: the shaded reading was
    // measured without them.
    out.last_resort.clear();
    (ws.up_rows, ws.up) = (rows, up);
    out.attempts += n;
    out
}

/// Stages 1-5 on `view` (region `r` of `img`, at `zoom` times its
/// resolution), then the rim's candidates decoded on `img`, at most
/// `budget`; at full resolution (`zoom` 1) without the guessed ones, which
/// [`small_region`] decodes last.
fn small_look(
    img: &GrayView<'_>,
    view: &GrayView<'_>,
    r: &small::Region,
    zoom: f64,
    d: &SmallPass<'_>,
    budget: usize,
    ws: &mut Workspace,
) -> decoding::Decoded {
    // The regions' own stage times are not split out: they are the
    // `small` stage.
    let mut inner = StageTimes::default();
    ws.seg.run(view, d.full, None, &mut inner);
    let shifted: Vec<quads::Candidate> = ws
        .seg
        .candidates
        .iter()
        .filter(|c| zoom != 1.0 || !c.guessed)
        .filter_map(|c| small::of_rim(c, r, zoom))
        .collect();
    decode_small(img, &shifted, d, budget, ws)
}

/// A small-tag region's candidates (full-image coordinates) decoded on
/// `img`, at most `budget`.
fn decode_small(
    img: &GrayView<'_>,
    candidates: &[quads::Candidate],
    d: &SmallPass<'_>,
    budget: usize,
    ws: &mut Workspace,
) -> decoding::Decoded {
    decoding::decode_candidates(
        img,
        candidates,
        1.0,
        d.targets,
        &decoding::DecodingParams {
            max_attempts: budget,
            ..*d.decoding
        },
        &mut ws.rscratch,
    )
}

/// What [`small_region`] reads of the detector.
struct SmallPass<'a> {
    /// Stage parameters at full resolution.
    full: &'a StageParams,
    targets: &'a [decoding::Target],
    /// Decoding parameters of the frame (the budget aside).
    decoding: &'a decoding::DecodingParams<'a>,
}

/// Stage stopwatch: each [`Laps::lap`] returns the time since the last.
struct Laps(Instant);

impl Laps {
    fn lap(&mut self) -> Duration {
        let now = Instant::now();
        let d = now - self.0;
        self.0 = now;
        d
    }
}

/// The CopperTag detector. Create once, call [`Detector::detect`] per
/// frame; it reuses its buffers.
///
/// ```
/// use coppertag::{Detector, DetectorConfig, GrayView};
///
/// let mut detector = Detector::new(DetectorConfig::default())?;
/// // An owned image converts into a view...
/// let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/ct14/42.png");
/// let img = image::open(path).expect("fixture").to_luma8();
/// let found = detector.detect(&img);
/// assert_eq!((found[0].family.as_str(), found[0].id), ("ct14", 42));
/// println!("corners {:?}, {} corrected", found[0].corners, found[0].corrected);
///
/// // ...and a camera buffer (here 64 x 48 pixels, rows padded to 80 bytes)
/// // is used as it is, without a copy.
/// let frame = vec![200u8; 80 * 48];
/// let view = GrayView::new(&frame, 64, 48, 80)?;
/// assert!(detector.detect(view).is_empty());
/// # Ok::<(), coppertag::Error>(())
/// ```
#[derive(Debug)]
pub struct Detector {
    config: DetectorConfig,
    params: StageParams,
    /// `params` at full resolution, for the small-tag regions.
    full_params: StageParams,
    targets: Vec<decoding::Target>,
    /// The built-in families not in `targets`, at their default limits:
    /// their tags are recognised, not decoded
    /// (`decoding::DecodingParams::others`).
    others: Vec<decoding::Target>,
    ws: Workspace,
    /// The worker threads and their buffers, when
    /// [`DetectorConfig::threads`] asks for more than one.
    workers: Option<Workers<Workspace>>,
    stats: DetectionStats,
}

impl Detector {
    /// A detector with validated settings.
    pub fn new(config: DetectorConfig) -> Result<Self> {
        config.validate()?;
        print_align::prepare();
        let targets = config
            .families
            .iter()
            .map(decoding::Target::of)
            .collect::<Vec<_>>();
        // The families' codebooks for the likelihood reading are built
        // here too, not by the first frame that needs one: about 6 ms for
        // ct14, which made that frame (the first with a quad the code did
        // not read at once) the worst of a run, at three to four times a
        // frame's usual time (the 20 occlusion images: 10.7-11.2 ms for
        // the first, 2.7 ms at the median).
        for t in &targets {
            t.family.codebook();
        }
        let others = crate::family::Family::builtin()
            .iter()
            .filter(|f| !targets.iter().any(|t| t.family == **f))
            .filter_map(|f| FamilySetting::builtin(f.name()).ok())
            .map(|s| decoding::Target::of(&s))
            .collect();
        let full = DetectorConfig {
            downsample: 1,
            ..config.clone()
        };
        let threads = match config.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        let workers = if threads > 1 {
            Some(Workers::new(threads, config.pin_threads)?)
        } else {
            None
        };
        // The small-tag look pairs no rim fragments (see
        // `ellipses::EllipseParams::pair_fragments`).
        let mut full_params = StageParams::new(&full);
        full_params.ellipses.pair_fragments = false;
        Ok(Self {
            workers,
            params: StageParams::new(&config),
            full_params,
            config,
            targets,
            others,
            ws: Workspace::default(),
            stats: DetectionStats::default(),
        })
    }

    /// The settings.
    pub fn config(&self) -> &DetectorConfig {
        &self.config
    }

    /// Statistics of the last call to [`Detector::detect`].
    pub fn stats(&self) -> &DetectionStats {
        &self.stats
    }

    /// Finds and decodes every tag in `img` (an `&image::GrayImage`, or a
    /// [`GrayView`] of a borrowed buffer with any row stride). Detections
    /// are sorted by family and id; each physical tag is reported once.
    pub fn detect<'a>(&mut self, img: impl Into<GrayView<'a>>) -> Vec<Detection> {
        let img = img.into();
        // The whole frame runs on one of the pool's threads: the parallel
        // steps inside then hand work to the other threads by rayon's work
        // stealing, where each step entered from outside the pool would
        // wait for a pool thread to wake up and for the caller to be woken
        // again (tens of microseconds each, and a frame has dozens of
        // steps). The other threads stay awake for the frame: asleep, they
        // would be woken for each parallel step after a sequential one
        // (50 to 200 microseconds on the benchmark's virtual machine, a
        // tenth of a 4K frame in all). Taken out of `self` for the call; a
        // panic in a stage leaves the detector without its pool (one
        // thread), not broken.
        let t0 = Instant::now();
        let workers = self.workers.take();
        let out = match &workers {
            None => self.detect_on(img, None),
            Some(w) => w.install_awake(|| self.detect_on(img, Some(w))),
        };
        self.workers = workers;
        self.stats.times.total = t0.elapsed();
        out
    }

    /// [`Detector::detect`] with the pool `workers`, if any.
    fn detect_on(
        &mut self,
        img: GrayView<'_>,
        workers: Option<&Workers<Workspace>>,
    ) -> Vec<Detection> {
        let mut laps = Laps(Instant::now());
        let (p, ws) = (&self.params, &mut self.ws);
        // The frame's model fits, each made once ([`decoding::Fits`]).
        let fits = decoding::Fits::default();
        let dp = &decoding::DecodingParams {
            fits: Some(&fits),
            others: &self.others,
            ..p.decoding
        };
        let mut st = DetectionStats {
            width: img.width(),
            height: img.height(),
            ..DetectionStats::default()
        };
        let scale = ws.seg.run(&img, p, workers, &mut st.times);
        let seg = &ws.seg;
        (
            st.contours,
            st.lines,
            st.corners,
            st.ellipses,
            st.candidates,
        ) = (
            seg.contours.list.len(),
            seg.polys.lines.len(),
            seg.corners.len(),
            seg.ellipses.len(),
            seg.candidates.len(),
        );
        laps.lap();
        let cands = &ws.seg.candidates;
        let decoding::Decoded {
            mut found,
            mut foreign,
            mut attempts,
            mut last_resort,
            mut unread,
        } = match workers {
            None => {
                decoding::decode_candidates(&img, cands, scale, &self.targets, dp, &mut ws.rscratch)
            }
            Some(w) => read_ahead::decode_candidates_par(
                &img,
                cands,
                scale,
                &self.targets,
                dp,
                w,
                |s: &mut Workspace| &mut s.rscratch,
            ),
        };
        st.times.decode = laps.lap();
        // With worker threads, the fits of the tags found so far, made
        // beside the small-tag regions (see `decoding::verify_ahead`).
        let mut ahead = Vec::new();
        // The main look's rims, kept for the rim look: the small-tag
        // regions' looks reuse the segmentation's buffers.
        ws.rims.clear();
        ws.rims.extend_from_slice(&ws.seg.ellipses);
        if self.config.small_tags && scale > 1.0 {
            let seen: Vec<&Detection> = found.iter().map(|f| f.detection()).collect();
            let regions = small::regions(
                &ws.seg.ellipses,
                scale,
                &seen,
                &foreign,
                img.width(),
                img.height(),
            );
            st.small_regions = regions.len();
            let this = &SmallPass {
                full: &self.full_params,
                targets: &self.targets,
                decoding: dp,
            };
            match workers {
                None => {
                    for r in &regions {
                        let budget = dp.max_attempts.saturating_sub(attempts);
                        let more = small_region(&img, r, this, budget, ws);
                        attempts += more.attempts;
                        found.extend(more.found);
                        foreign.extend(more.foreign);
                        last_resort.extend(more.last_resort);
                        unread.extend(more.unread);
                    }
                }
                Some(w) => {
                    // Each region is looked at with every attempt left
                    // before the first; in order, a region whose run
                    // decoded more than were left after the regions
                    // before it is looked at again with what was left (a
                    // run with a smaller budget is the larger one's,
                    // stopped early). The tags found so far are fitted
                    // meanwhile, the threads taking regions and fits as
                    // they come free.
                    let left = dp.max_attempts.saturating_sub(attempts);
                    let (runs, fits): (Vec<_>, _) = w.install(|| {
                        rayon::join(
                            || {
                                regions
                                    .par_iter()
                                    .map(|r| small_region(&img, r, this, left, &mut w.scratch()))
                                    .collect()
                            },
                            || decoding::verify_ahead(&img, &found, &self.targets, dp),
                        )
                    });
                    ahead = fits;
                    for (r, run) in regions.iter().zip(runs) {
                        let budget = dp.max_attempts.saturating_sub(attempts);
                        let more = if run.attempts <= budget {
                            run
                        } else {
                            small_region(&img, r, this, budget, ws)
                        };
                        attempts += more.attempts;
                        found.extend(more.found);
                        foreign.extend(more.foreign);
                        last_resort.extend(more.last_resort);
                        unread.extend(more.unread);
                    }
                }
            }
            st.times.small = laps.lap();
        }
        // Last, the rims no tag was found in, from the rim alone. The rims
        // a reading covers are kept: verification may drop the reading.
        // The rim look on `rims` not in a tag of `found`, within the
        // decoding attempts left, which it counts in `attempts` and in
        // `rim_decodes`.
        let look = |ws: &mut Workspace,
                    rims: &[ellipses::Ellipse],
                    found: &[decoding::Found],
                    attempts: &mut usize,
                    rim_decodes: &mut usize,
                    last_resort: &mut Vec<decoding::Found>| {
            let budget = dp.max_attempts.saturating_sub(*attempts);
            let (more, last, n) = rim_look(
                &img,
                scale,
                budget,
                &self.targets,
                dp,
                ws,
                rims,
                found,
                &foreign,
            );
            *attempts += n;
            *rim_decodes += n;
            last_resort.extend(last);
            more
        };
        let covered = {
            let rims = std::mem::take(&mut ws.rims);
            let more = look(
                ws,
                &rims,
                &found,
                &mut attempts,
                &mut st.rim_decodes,
                &mut last_resort,
            );
            let covered: Vec<ellipses::Ellipse> = rims
                .iter()
                .filter(|e| rim_inside(e, scale, found.iter().map(|f| &f.detection().corners)))
                .copied()
                .collect();
            ws.rims = rims;
            found.extend(more);
            st.times.rim = laps.lap();
            covered
        };
        let mut out = match workers {
            None => {
                let out = decoding::one_per_tag(found);
                st.times.dedup = laps.lap();
                decoding::verify_all(&img, out, &self.targets, dp)
            }
            Some(w) => {
                let out = decoding::one_per_tag_indexed(found);
                st.times.dedup = laps.lap();
                decoding::verify_all_par(&img, out, ahead, &self.targets, dp, w)
            }
        };
        st.times.verify = laps.lap();
        // The rims whose covering reading verification dropped get the rim
        // look after all: on the wild set 51 markers that read at their
        // true corners lay under a rival reading the fit contradicted.
        let orphans: Vec<ellipses::Ellipse> = covered
            .into_iter()
            .filter(|e| !rim_inside(e, scale, out.iter().map(|d| &d.corners)))
            .collect();
        if !orphans.is_empty() {
            let more = look(
                ws,
                &orphans,
                &[],
                &mut attempts,
                &mut st.rim_decodes,
                &mut last_resort,
            );
            out.extend(decoding::verify_all(
                &img,
                decoding::one_per_tag(more),
                &self.targets,
                dp,
            ));
            st.times.rim += laps.lap();
        }
        // Last, the readings that stand only where no look found a tag.
        if !last_resort.is_empty() {
            let more = decoding::last_resorts(&img, last_resort, &out, &self.targets, dp);
            out.extend(more);
            st.times.verify += laps.lap();
        }
        if !unread.is_empty() {
            let aligned =
                decoding::aligned_unread(&img, &unread, &out, &foreign, &self.targets, dp);
            let more = decoding::last_resorts(&img, aligned, &out, &self.targets, dp);
            out.extend(more);
            st.times.verify += laps.lap();
        }
        st.decode_attempts = attempts;
        st.detections = out.len();
        // `total` is set by `detect`, around the pool's waking too.
        self.stats = st;
        out
    }
}

//! The detection pipeline: image in, decoded tags out.
//!
//! One driver, [`Detector::detect`], runs the stages in order, each in its
//! own module and each handing a plain value to the next (the shape of the
//! paper's section III.B and of AprilTag 3's driver):
//!
//! 1. [`threshold`]: optional 2x downsampling, adaptive mean threshold;
//! 2. [`contours`]: border following (Suzuki & Abe 1985);
//! 3. [`lines`] and [`corners`]: Douglas-Peucker, line fits oriented dark
//!    on the right, anticlockwise corners (the paper's Algorithm 1);
//! 4. [`ellipses`]: the disc rim as ellipse candidates from arcs, robust to
//!    a partly hidden rim;
//! 5. [`quads`]: candidate quads, with the triangle, same-side, symmetry and
//!    diagonal occlusion cases (the paper's Algorithm 2);
//! 6. [`refine`] then [`crate::decode_quad`] at full resolution: sub-pixel
//!    corners, grid sampling, Reed-Solomon; one detection per tag.
//!
//! Stage timings and counts of the last frame are in [`DetectionStats`],
//! kept apart from the settings ([`DetectorConfig`]). The detector owns its
//! buffers and resizes them per frame; nothing has to be reset by callers.

pub(crate) mod contours;
pub(crate) mod corners;
pub(crate) mod ellipses;
pub(crate) mod lines;
pub(crate) mod quads;
pub(crate) mod refine;
pub(crate) mod threshold;

use std::time::Instant;

use image::GrayImage;
use serde::{Deserialize, Serialize};

use crate::family::Family;
use crate::geometry::CORNERS;
use crate::homography::Homography;
use crate::{decode_quad, Error, Result};

/// Detector settings. Every field has a documented default
/// ([`DetectorConfig::default`]); [`Detector::new`] validates them.
///
/// Lengths marked "working px" are in pixels of the image the quads are
/// searched on, i.e. after downsampling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    /// Families to decode, by name (`"ct14"`, `"ct8"`). Default: both. Each
    /// extra family costs one decoding attempt per candidate quad.
    pub families: Vec<String>,
    /// Downsampling factor before segmentation: 1 (none) or 2. Quads are
    /// found on the reduced image, refined and decoded on the full one.
    /// Default 2; use 1 when data squares are smaller than about 40 px.
    pub downsample: u32,
    /// Radius of the adaptive threshold window (working px); the window is
    /// `2 r + 1` pixels square. Default 10. Larger copes with bigger tags
    /// and smoother light, smaller with stronger light gradients.
    pub threshold_radius: u32,
    /// A pixel is dark when it is more than this many grey levels below its
    /// window's mean. Default 6. Raise it for noisy images.
    pub threshold_offset: u8,
    /// Shortest border followed into the later stages (points). Default 12.
    pub min_contour_points: usize,
    /// Douglas-Peucker tolerance (working px). Default 1.5.
    pub dp_epsilon: f64,
    /// tau: shortest polygon side that becomes a line (working px).
    /// Default 8 (the paper uses 14 px at its resolution).
    pub min_line_length: f64,
    /// theta: smallest angle between two lines forming a corner, degrees.
    /// Default 22.5 (the paper's value).
    pub corner_min_angle_deg: f64,
    /// psi: largest gap between the ends of two lines forming a corner
    /// (working px). Default 7 (the paper's value).
    pub corner_max_gap: f64,
    /// Recover tags with hidden corners (triangle, same-side, symmetry and
    /// diagonal cases). Default true; false keeps only four-corner quads.
    pub recover_occluded: bool,
    /// Refine corners to sub-pixel accuracy at full resolution. Default
    /// true.
    pub refine_corners: bool,
    /// Most Reed-Solomon symbol corrections accepted, per family name;
    /// families not listed accept what their code corrects. Default: ct8 at
    /// most 3 of its 5 (its short code is the weak point for false reads),
    /// ct14 unlimited (9).
    pub max_corrected: Vec<(String, usize)>,
    /// Cap on candidate quads decoded per frame (bounds the time spent on
    /// cluttered frames). Default 400.
    pub max_candidates: usize,
}

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            families: vec!["ct14".into(), "ct8".into()],
            downsample: 2,
            threshold_radius: 10,
            threshold_offset: 6,
            min_contour_points: 12,
            dp_epsilon: 1.5,
            min_line_length: 8.0,
            corner_min_angle_deg: 22.5,
            corner_max_gap: 7.0,
            recover_occluded: true,
            refine_corners: true,
            max_corrected: vec![("ct8".into(), 3)],
            max_candidates: 400,
        }
    }
}

impl DetectorConfig {
    /// Checks every setting; the error names the first bad one.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |name: &'static str, reason: String| Err(Error::InvalidParameter { name, reason });
        if self.families.is_empty() {
            return bad("families", "at least one family is needed".into());
        }
        for f in &self.families {
            Family::by_name(f)?;
        }
        if !matches!(self.downsample, 1 | 2) {
            return bad(
                "downsample",
                format!("{} (must be 1 or 2)", self.downsample),
            );
        }
        if !(1..=200).contains(&self.threshold_radius) {
            return bad(
                "threshold_radius",
                format!("{} (must be 1..=200)", self.threshold_radius),
            );
        }
        if !(4..=100_000).contains(&self.min_contour_points) {
            return bad(
                "min_contour_points",
                format!("{} (must be 4..=100000)", self.min_contour_points),
            );
        }
        if !(self.dp_epsilon > 0.0 && self.dp_epsilon <= 10.0) {
            return bad(
                "dp_epsilon",
                format!("{} (must be in (0, 10])", self.dp_epsilon),
            );
        }
        if !(self.min_line_length >= 2.0 && self.min_line_length <= 1000.0) {
            return bad(
                "min_line_length",
                format!("{} (must be in [2, 1000])", self.min_line_length),
            );
        }
        if !(self.corner_min_angle_deg > 0.0 && self.corner_min_angle_deg < 90.0) {
            return bad(
                "corner_min_angle_deg",
                format!("{} (must be in (0, 90))", self.corner_min_angle_deg),
            );
        }
        if !(self.corner_max_gap > 0.0 && self.corner_max_gap <= 100.0) {
            return bad(
                "corner_max_gap",
                format!("{} (must be in (0, 100])", self.corner_max_gap),
            );
        }
        for (name, _) in &self.max_corrected {
            Family::by_name(name)?;
        }
        if self.max_candidates == 0 {
            return bad("max_candidates", "must be at least 1".into());
        }
        Ok(())
    }
}

/// One detected tag.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detection {
    /// Family name.
    pub family: &'static str,
    /// Decoded id.
    pub id: u64,
    /// Data-square corners TL, BL, BR, TR (pixel-centre coordinates of the
    /// input image); corner 0 is always the tag's physical top-left.
    pub corners: [[f64; 2]; 4],
    /// Which corners were estimated (hidden, recovered from the other
    /// corners' lines or the tag centre) rather than measured.
    pub estimated: [bool; 4],
    /// Reed-Solomon symbols corrected while decoding: 0 for a clean read;
    /// filter on it for confidence.
    pub corrected: usize,
    /// Image of the tag centre (intersection of the diagonals).
    pub center: [f64; 2],
    /// Measured contrast between the tag's white and black (grey levels).
    pub contrast: f64,
    /// Homography from tag units (data square side 1, centre 0, y down) to
    /// image pixels, row-major.
    pub homography: [[f64; 3]; 3],
}

/// Times of the pipeline stages for one frame, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StageTimes {
    /// Downsampling.
    pub downsample_ms: f64,
    /// Adaptive threshold.
    pub threshold_ms: f64,
    /// Border following.
    pub contours_ms: f64,
    /// Polygons and lines.
    pub lines_ms: f64,
    /// Corners.
    pub corners_ms: f64,
    /// Ellipses.
    pub ellipses_ms: f64,
    /// Candidate quads.
    pub quads_ms: f64,
    /// Refinement and decoding.
    pub decode_ms: f64,
    /// Whole frame.
    pub total_ms: f64,
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
    /// found or over the cap).
    pub decode_attempts: usize,
    /// Tags reported.
    pub detections: usize,
}

/// Buffers kept between frames.
#[derive(Debug, Default)]
struct Workspace {
    small: Vec<u8>,
    colsum: Vec<u32>,
    binary: Vec<u8>,
    contours: contours::Contours,
    polys: lines::Polygons,
    corners: Vec<corners::Corner>,
    ellipses: Vec<ellipses::Ellipse>,
    escratch: ellipses::EllipseScratch,
    candidates: Vec<quads::Candidate>,
    qscratch: quads::QuadScratch,
    rscratch: refine::RefineScratch,
}

/// The CopperTag detector. Create once, call [`Detector::detect`] per
/// frame; it reuses its buffers.
#[derive(Debug)]
pub struct Detector {
    config: DetectorConfig,
    families: Vec<(&'static Family, usize)>,
    ws: Workspace,
    stats: DetectionStats,
}

impl Detector {
    /// A detector with validated settings.
    pub fn new(config: DetectorConfig) -> Result<Self> {
        config.validate()?;
        let families = config
            .families
            .iter()
            .map(|f| {
                let fam = Family::by_name(f)?;
                let cap = fam.code().correctable();
                let max = config
                    .max_corrected
                    .iter()
                    .find(|(n, _)| n == fam.name())
                    .map_or(cap, |&(_, m)| m.min(cap));
                Ok((fam, max))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            config,
            families,
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

    /// Finds and decodes every tag in `img`. Detections are sorted by
    /// family and id; each physical tag is reported once.
    pub fn detect(&mut self, img: &GrayImage) -> Vec<Detection> {
        let t0 = Instant::now();
        let mut lap = t0;
        let mut tick = || {
            let now = Instant::now();
            let ms = (now - lap).as_secs_f64() * 1e3;
            lap = now;
            ms
        };
        let cfg = &self.config;
        let ws = &mut self.ws;
        let mut st = DetectionStats {
            width: img.width(),
            height: img.height(),
            ..DetectionStats::default()
        };
        let (w, h) = (img.width() as usize, img.height() as usize);
        // 1. Downsample.
        let scale = if cfg.downsample == 2 && w >= 8 && h >= 8 {
            2.0
        } else {
            1.0
        };
        let (ww, wh) = if scale == 2.0 {
            threshold::downsample2(img.as_raw(), w, h, &mut ws.small)
        } else {
            (w, h)
        };
        let work: &[u8] = if scale == 2.0 {
            &ws.small
        } else {
            img.as_raw()
        };
        st.times.downsample_ms = tick();
        // 1b. Threshold.
        threshold::adaptive_threshold(
            work,
            ww,
            wh,
            cfg.threshold_radius as usize,
            cfg.threshold_offset,
            &mut ws.colsum,
            &mut ws.binary,
        );
        st.times.threshold_ms = tick();
        // 2. Borders.
        let max_len = 4 * (ww + wh) + 16;
        contours::find_contours(
            &mut ws.binary,
            ww + 2,
            wh + 2,
            cfg.min_contour_points,
            max_len,
            &mut ws.contours,
        );
        st.contours = ws.contours.list.len();
        st.times.contours_ms = tick();
        // 3. Lines and corners.
        lines::extract(
            &ws.contours,
            cfg.dp_epsilon,
            cfg.min_line_length,
            &mut ws.polys,
        );
        st.lines = ws.polys.lines.len();
        st.times.lines_ms = tick();
        let cp = corners::CornerParams {
            sin_min_angle: cfg.corner_min_angle_deg.to_radians().sin(),
            max_gap: cfg.corner_max_gap,
        };
        corners::find_corners(&ws.polys, &cp, &mut ws.corners);
        st.corners = ws.corners.len();
        st.times.corners_ms = tick();
        // 4. Ellipses.
        let ep = ellipses::EllipseParams {
            min_minor: 4.0,
            min_arc_points: 2 * cfg.min_contour_points,
            max_rms: 1.0,
        };
        ellipses::find_ellipses(
            &ws.contours,
            &ws.polys,
            &ep,
            &mut ws.escratch,
            &mut ws.ellipses,
        );
        ellipses::find_anchors(&ws.contours, &mut ws.ellipses);
        st.ellipses = ws.ellipses.len();
        st.times.ellipses_ms = tick();
        // 5. Candidate quads.
        let qp = quads::QuadParams {
            min_side: 4.0,
            cos_edge: 20f64.to_radians().cos(),
            recover: cfg.recover_occluded,
            max_candidates: cfg.max_candidates * 4,
            replace_dist: cfg.corner_max_gap,
        };
        quads::find_candidates(
            &ws.corners,
            &ws.ellipses,
            &qp,
            &mut ws.qscratch,
            &mut ws.candidates,
        );
        st.candidates = ws.candidates.len();
        st.times.quads_ms = tick();
        // 6. Refine and decode, best candidates first.
        // A tag seen through an occluder usually has several candidate
        // quads (a triangle through a false corner on the occluder's edge,
        // a same-side recovery, ...) and a wrong one can still decode, the
        // Reed-Solomon code absorbing the misplaced cells. So a found tag
        // that needed corrections keeps a few more overlapping candidates
        // decoded, and the reading with the fewest corrections wins: the
        // right geometry explains the visible cells best.
        let mut found: Vec<Found> = Vec::new();
        for cand in ws.candidates.iter() {
            if st.decode_attempts >= cfg.max_candidates {
                break;
            }
            let centre = {
                let c = cand.corners.map(|p| refine::to_full(p, scale));
                [
                    (c[0][0] + c[1][0] + c[2][0] + c[3][0]) / 4.0,
                    (c[0][1] + c[1][1] + c[2][1] + c[3][1]) / 4.0,
                ]
            };
            let rival = found.iter().position(|f| inside(&f.det.corners, centre));
            if let Some(r) = rival {
                let f = &found[r];
                if f.det.corrected == 0 || f.rivals >= MAX_RIVALS {
                    continue;
                }
            }
            st.decode_attempts += 1;
            let q = refine::refine_candidate(
                img,
                cand,
                &ws.corners,
                &ws.polys.lines,
                scale,
                cfg.refine_corners,
                &mut ws.rscratch,
            );
            let mut best: Option<Detection> = None;
            for &(fam, max_corr) in &self.families {
                // A clean read cannot be beaten by another family.
                if best.as_ref().is_some_and(|b| b.corrected == 0) {
                    break;
                }
                let Some(r) = decode_quad(img, fam, &q) else {
                    continue;
                };
                if r.corrected > max_corr {
                    continue;
                }
                if best.as_ref().is_some_and(|b| b.corrected <= r.corrected) {
                    continue;
                }
                let d = r.rotation % 4;
                let estimated = std::array::from_fn(|c| cand.estimated[(c + 4 - d) % 4]);
                let Some(h) = Homography::from_points(&CORNERS, &r.corners) else {
                    continue;
                };
                let center = h.map([0.0, 0.0]).unwrap_or(centre);
                let m = h.matrix();
                best = Some(Detection {
                    family: fam.name(),
                    id: r.id,
                    corners: r.corners,
                    estimated,
                    corrected: r.corrected,
                    center,
                    contrast: r.contrast,
                    homography: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
                });
            }
            match (rival, best) {
                (Some(r), Some(b)) => {
                    let f = &mut found[r];
                    f.rivals += 1;
                    // Only a reading of the same tag competes; a different
                    // id inside a found tag is not trusted over it.
                    if b.family == f.det.family && b.id == f.det.id && better(&b, &f.det) {
                        f.det = b;
                    }
                }
                (Some(r), None) => found[r].rivals += 1,
                (None, Some(b)) => found.push(Found { det: b, rivals: 0 }),
                (None, None) => {}
            }
        }
        st.times.decode_ms = tick();
        // One detection per physical tag (candidates overlapping an earlier
        // find were skipped above; a later, larger quad may still contain an
        // earlier one).
        let mut out: Vec<Detection> = Vec::with_capacity(found.len());
        for Found { det: d, .. } in found {
            if let Some(o) = out
                .iter_mut()
                .find(|o| inside(&o.corners, d.center) || inside(&d.corners, o.center))
            {
                if better(&d, o) {
                    *o = d;
                }
            } else {
                out.push(d);
            }
        }
        out.sort_by(|a, b| a.family.cmp(b.family).then(a.id.cmp(&b.id)));
        st.detections = out.len();
        st.times.total_ms = (Instant::now() - t0).as_secs_f64() * 1e3;
        self.stats = st;
        out
    }
}

/// Extra candidates decoded for a tag already found with corrections.
const MAX_RIVALS: usize = 6;

/// A tag found in this frame and how many rival candidates were tried.
struct Found {
    det: Detection,
    rivals: usize,
}

/// Whether reading `a` of a tag is better than reading `b`: fewer Reed-
/// Solomon corrections, then more measured corners.
fn better(a: &Detection, b: &Detection) -> bool {
    let real = |d: &Detection| d.estimated.iter().filter(|&&e| !e).count();
    (std::cmp::Reverse(a.corrected), real(a)) > (std::cmp::Reverse(b.corrected), real(b))
}

/// Whether `p` is inside the convex quad `q`.
fn inside(q: &[[f64; 2]; 4], p: [f64; 2]) -> bool {
    let mut sign = 0.0;
    for i in 0..4 {
        let a = q[i];
        let b = q[(i + 1) % 4];
        let c = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]);
        if c == 0.0 {
            continue;
        }
        if sign == 0.0 {
            sign = c.signum();
        } else if c.signum() != sign {
            return false;
        }
    }
    true
}

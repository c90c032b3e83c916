//! The detector's settings: what a user tunes, serialisable for run logs.
//! The stage parameter structs are derived from it once, in
//! [`super::Detector::new`].

use serde::{Deserialize, Serialize};

use crate::family::Family;
pub use crate::family::CT8_MAX_CORRECTED;
use crate::{Error, Result};

/// One family the detector decodes, and how many Reed-Solomon symbol
/// corrections a reading of it may need.
///
/// Serialised as `{"family": "ct14", "max_corrected": null}` for a
/// built-in family, with the whole [`crate::family::FamilySpec`] in place of
/// the name for a family made with [`Family::from_spec`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FamilySetting {
    /// The family.
    pub family: Family,
    /// Most symbol corrections accepted; `None` (or more than the code
    /// corrects) accepts what the code corrects. Lower it to trade a few
    /// detections of damaged tags for fewer false reads.
    #[serde(default)]
    pub max_corrected: Option<usize>,
}

impl FamilySetting {
    /// A family with no limit of its own on corrections.
    pub fn new(family: Family) -> Self {
        Self {
            family,
            max_corrected: None,
        }
    }

    /// The built-in family `name` (`ct14`, `ct8`) with its default limit
    /// (ct8: [`CT8_MAX_CORRECTED`]).
    pub fn builtin(name: &str) -> Result<Self> {
        let family = Family::by_name(name)?.clone();
        let max_corrected = (name == "ct8").then_some(CT8_MAX_CORRECTED);
        Ok(Self {
            family,
            max_corrected,
        })
    }

    /// The same family with at most `max` corrections.
    pub fn with_max_corrected(mut self, max: usize) -> Self {
        self.max_corrected = Some(max);
        self
    }

    /// Corrections accepted: the limit, capped at what the code corrects.
    pub fn correction_limit(&self) -> usize {
        let cap = self.family.code().correctable();
        self.max_corrected.map_or(cap, |m| m.min(cap))
    }
}

/// Detector settings. Every field has a documented default
/// ([`DetectorConfig::default`]); [`crate::Detector::new`] validates them.
///
/// Lengths marked "working px" are in pixels of the image the quads are
/// searched on, i.e. after downsampling. The thresholds that are not
/// settings are named constants of their stage module
/// (`detect/{threshold,contours,lines,corners,ellipses,quads,refine,decoding}.rs`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DetectorConfig {
    /// Families to decode, in the order they are tried, each with its
    /// correction limit. Default: ct14 (no limit of its own), then ct8 (at
    /// most [`CT8_MAX_CORRECTED`]). Each extra family costs one decoding
    /// attempt per candidate quad.
    pub families: Vec<FamilySetting>,
    /// Downsampling factor before segmentation: 1 (none) or 2. Quads are
    /// found on the reduced image, refined and decoded on the full one.
    /// Default 2: small tags are then looked at again at full resolution
    /// (`small_tags`); 1 segments the whole frame at full resolution.
    pub downsample: u32,
    /// Radius of the adaptive threshold window (working px); the window is
    /// `2 r + 1` pixels square. Default 10. Larger copes with bigger tags
    /// and smoother light, smaller with stronger light gradients.
    pub threshold_radius: u32,
    /// A pixel is dark when it is more than this many grey levels below its
    /// window's mean. Default 6. Raise it for noisy images.
    pub threshold_offset: u8,
    /// Shortest border followed into the later stages (points). Default 12.
    /// The ellipse stage looks at borders of twice this length only.
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
    /// (working px). Default 7 (the paper's value). Also the farthest a
    /// detected corner may replace an estimated one.
    pub corner_max_gap: f64,
    /// Smallest semi-minor axis of a disc rim (working px). Default 4.
    pub ellipse_min_minor: f64,
    /// Largest RMS distance of the rim's border points from its fitted
    /// ellipse (working px). Default 1.
    pub ellipse_max_rms: f64,
    /// Shortest side of a candidate quad (working px). Default 4.
    pub quad_min_side: f64,
    /// Largest angle between two line pieces of one tag edge, degrees.
    /// Default 20.
    pub edge_max_angle_deg: f64,
    /// Recover tags with hidden corners (triangle, same-side, symmetry and
    /// diagonal cases). Default true; false keeps only four-corner quads.
    pub recover_occluded: bool,
    /// Refine corners to sub-pixel accuracy at full resolution. Default
    /// true.
    pub refine_corners: bool,
    /// With `downsample` 2: look again at full resolution around every
    /// disc rim of a tag too small to read at half size (data square under
    /// 64 px) that no detection explains. Default true. Finds data squares
    /// down to about 20 px at a fraction of the cost of `downsample` 1;
    /// false saves that time on frames with small round clutter.
    pub small_tags: bool,
    /// Cap on candidate quads decoded per frame (bounds the time spent on
    /// cluttered frames). Default 400.
    pub max_candidates: usize,
    /// Threads one call to [`crate::Detector::detect`] runs on. Default 1:
    /// the calling thread only, as a program that runs one detector per
    /// camera or per core wants. More splits the threshold and the border
    /// following into bands, the line, corner, ellipse and quad stages over
    /// borders, corners and candidates, decodes candidates, small-tag
    /// regions and verifications in parallel, on a thread pool of the
    /// detector's own (not rayon's global one), whose threads look for
    /// work without pause while a frame is detected (they sleep between
    /// frames). 0 means one thread per core the system reports. At most
    /// [`MAX_THREADS`]. The detections and [`crate::DetectionStats`] counts
    /// are the same for every value; only the times differ.
    pub threads: usize,
    /// With [`DetectorConfig::threads`] over 1: pin each of the detector's
    /// threads to a core of its own, among the cores the thread creating
    /// the detector may run on (left unpinned when there are fewer such
    /// cores than threads). Default true. Detectors made one after another
    /// in a program take the next cores in turn, so that several pinned
    /// detectors (one per camera, say) do not all land on the first ones.
    ///
    /// Why by default: left to the system, on the project's 2-core virtual
    /// machine both threads often ran on one core for milliseconds, the
    /// other core idle, worst after a pause between frames. `coppertag
    /// detect --json --stats` on 2 threads over the wild benchmark's 4K
    /// frames took 16.6 ms a frame unpinned and 10.7 ms pinned (17.2 ms on
    /// one thread), over its 1080p frames 6.3 and 5.7 ms (7.7 ms). False
    /// leaves the threads to the system: better when other busy programs
    /// share the machine's cores, since a pinned thread cannot move away
    /// from one of them.
    pub pin_threads: bool,
}

/// Largest [`DetectorConfig::threads`]: far more threads than stages can
/// keep busy on one frame, and a guard against a thread count mistaken for
/// something else (a pixel count, a negative number read unsigned).
pub const MAX_THREADS: usize = 256;

impl Default for DetectorConfig {
    fn default() -> Self {
        Self {
            families: vec![
                FamilySetting::new(Family::ct14().clone()),
                FamilySetting::new(Family::ct8().clone()).with_max_corrected(CT8_MAX_CORRECTED),
            ],
            downsample: 2,
            threshold_radius: 10,
            threshold_offset: 6,
            min_contour_points: 12,
            dp_epsilon: 1.5,
            min_line_length: 8.0,
            corner_min_angle_deg: 22.5,
            corner_max_gap: 7.0,
            ellipse_min_minor: 4.0,
            ellipse_max_rms: 1.0,
            quad_min_side: 4.0,
            edge_max_angle_deg: 20.0,
            recover_occluded: true,
            refine_corners: true,
            small_tags: true,
            max_candidates: 400,
            threads: 1,
            pin_threads: true,
        }
    }
}

impl DetectorConfig {
    /// The default settings with only the built-in families `names` (each
    /// with its default correction limit, see [`FamilySetting::builtin`]).
    pub fn with_builtin_families<S: AsRef<str>>(names: &[S]) -> Result<Self> {
        Ok(Self {
            families: names
                .iter()
                .map(|n| FamilySetting::builtin(n.as_ref()))
                .collect::<Result<_>>()?,
            ..Self::default()
        })
    }

    /// Checks every setting; the error names the first bad one.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |name: &'static str, reason: String| Err(Error::InvalidParameter { name, reason });
        if self.families.is_empty() {
            return bad("families", "at least one family is needed".into());
        }
        for (i, f) in self.families.iter().enumerate() {
            let name = f.family.name();
            if self.families[..i].iter().any(|g| g.family.name() == name) {
                return bad(
                    "families",
                    format!("family '{name}' is listed twice (detections name their family)"),
                );
            }
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
        let in_range = |name: &'static str, v: f64, lo: f64, lo_open: bool, hi: f64| {
            let above = if lo_open { v > lo } else { v >= lo };
            if above && v <= hi {
                Ok(())
            } else {
                let open = if lo_open { "(" } else { "[" };
                bad(name, format!("{v} (must be in {open}{lo}, {hi}])"))
            }
        };
        in_range("dp_epsilon", self.dp_epsilon, 0.0, true, 10.0)?;
        in_range("min_line_length", self.min_line_length, 2.0, false, 1000.0)?;
        if !(self.corner_min_angle_deg > 0.0 && self.corner_min_angle_deg < 90.0) {
            return bad(
                "corner_min_angle_deg",
                format!("{} (must be in (0, 90))", self.corner_min_angle_deg),
            );
        }
        in_range("corner_max_gap", self.corner_max_gap, 0.0, true, 100.0)?;
        in_range(
            "ellipse_min_minor",
            self.ellipse_min_minor,
            1.0,
            false,
            1000.0,
        )?;
        in_range("ellipse_max_rms", self.ellipse_max_rms, 0.0, true, 100.0)?;
        in_range("quad_min_side", self.quad_min_side, 1.0, false, 1000.0)?;
        if !(self.edge_max_angle_deg > 0.0 && self.edge_max_angle_deg < 90.0) {
            return bad(
                "edge_max_angle_deg",
                format!("{} (must be in (0, 90))", self.edge_max_angle_deg),
            );
        }
        if self.max_candidates == 0 {
            return bad("max_candidates", "must be at least 1".into());
        }
        if self.threads > MAX_THREADS {
            return bad(
                "threads",
                format!(
                    "{} (must be 0 for one per core, or 1..={MAX_THREADS})",
                    self.threads
                ),
            );
        }
        Ok(())
    }
}

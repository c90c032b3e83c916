//! `[sample]`: scenes whose parameters are drawn from a scrambled Halton
//! sequence ([`crate::halton`]) over declared ranges, instead of a sweep.
//!
//! A factor is written as a number (a constant, still recorded), a range
//! `[lo, hi]` (uniform over it) or a list `{ values = [...] }` (one of
//! them, equally often); categorical factors as a string or a list of
//! strings. A factor left out keeps the spec's own setting and is not
//! recorded. The format and `draws.csv` are documented in
//! `datasets/README.md`.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::Serialize;

use crate::error::Result;
use crate::markers::{MarkerModel, MarkerSystem};
use crate::occlusion::{self, Occlusion, Scenario, Style};
use crate::scene::Rendering;
use crate::toml_input::{steps, KeyLocator};

use super::rendering::MAX_MOTION_BLUR_PX;
use super::schema::SampleFile;

/// Most markers in one sampled frame: the field report's dense frames
/// show ten tags at once (it was 8 until the dense sets; the slots past 8
/// draw from coordinates appended after the older ones,
/// `draw::slot_base`, so every earlier draw stays as it was).
pub const MAX_MARKERS_PER_FRAME: usize = 12;
/// Most sampled scenes in one spec.
const MAX_SCENES: usize = 10_000_000;
/// Most repeats of one scene.
const MAX_REPEATS: usize = 1000;
/// Placeholder size of tag-free specs (never drawn).
const TAG_FREE_SIDE_PX: f64 = 32.0;
/// Smallest side of a background photograph, pixels (it is cropped,
/// rotated and scaled up to the frame).
const MIN_PHOTO_SIDE_PX: u32 = 64;
/// Largest tilt about either axis, degrees (beyond it the marker is seen
/// edge-on).
const MAX_TILT_DEG: f64 = 85.0;

/// A numeric factor.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Factor {
    /// Uniform over `[lo, hi]`.
    Range(f64, f64),
    /// One of the values, equally often.
    List(Vec<f64>),
    /// An event: present in a `share` of the images (or markers), drawn
    /// from `inner` then; absent otherwise, at the neutral value `off`.
    Shared {
        /// The draw when present.
        inner: Box<Factor>,
        /// Probability of being present, in (0, 1].
        share: f64,
        /// The value when absent (no blur, no glare, no JPEG step...).
        off: f64,
    },
}

/// Where a Halton coordinate `u` in [0, 1) falls for an event present in
/// a `share` of the draws: `None` below `1 - share` (absent), otherwise
/// `u` rescaled onto [0, 1). One coordinate serves both, so the present
/// draws keep the sequence's low discrepancy and the whole stays
/// deterministic.
#[must_use]
pub fn present(u: f64, share: f64) -> Option<f64> {
    let absent = 1.0 - share;
    (u >= absent).then(|| ((u - absent) / share).clamp(0.0, 1.0 - f64::EPSILON))
}

impl Factor {
    /// The value at the quantile `u` in [0, 1).
    #[must_use]
    pub fn at(&self, u: f64) -> f64 {
        match self {
            Factor::Range(lo, hi) => lo + u * (hi - lo),
            Factor::List(v) => v[pick(u, v.len())],
            Factor::Shared { inner, share, off } => {
                present(u, *share).map_or(*off, |v| inner.at(v))
            }
        }
    }

    /// An integer at the quantile `u`: ranges give each whole number in
    /// `[lo, hi]` equally often.
    #[must_use]
    pub fn at_int(&self, u: f64) -> i64 {
        match self {
            Factor::Range(lo, hi) => {
                let (lo, hi) = (lo.round() as i64, hi.round() as i64);
                lo + pick(u, (hi - lo + 1) as usize) as i64
            }
            Factor::List(v) => v[pick(u, v.len())].round() as i64,
            Factor::Shared { inner, share, off } => {
                present(u, *share).map_or(off.round() as i64, |v| inner.at_int(v))
            }
        }
    }

    /// Smallest and largest value.
    #[must_use]
    pub fn bounds(&self) -> (f64, f64) {
        match self {
            Factor::Range(lo, hi) => (*lo, *hi),
            Factor::List(v) => v
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                }),
            Factor::Shared { inner, off, .. } => {
                let (lo, hi) = inner.bounds();
                (lo.min(*off), hi.max(*off))
            }
        }
    }
}

/// Index `floor(u n)` of `n` choices, for `u` in [0, 1).
#[must_use]
pub fn pick(u: f64, n: usize) -> usize {
    ((u * n as f64) as usize).min(n.saturating_sub(1))
}

/// How the marker's distance is drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Size {
    /// Side of the marker square in pixels, seen face-on at the image
    /// centre (the distance follows from the focal length).
    SidePx(Factor),
    /// Depth of the marker centre, metres.
    DistanceM(Factor),
}

/// Which ids are drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum IdChoice {
    /// Any id of the family, equally often.
    Any,
    /// One of these (checked against every marker type).
    List(Vec<u64>),
}

/// A marker type that sampled frames place.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerType {
    /// System.
    pub system: MarkerSystem,
    /// Family.
    pub family: String,
    /// First and last id of the family.
    pub ids: (u64, u64),
}

/// Background of a sampled frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BackgroundChoice {
    /// A flat grey.
    Flat,
    /// A linear ramp.
    Gradient,
    /// Random shapes (`clutter_density` shapes per megapixel).
    Clutter,
    /// A rotated, scaled crop of one of `background_images`.
    Image,
}

impl BackgroundChoice {
    /// Name in files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            BackgroundChoice::Flat => "flat",
            BackgroundChoice::Gradient => "gradient",
            BackgroundChoice::Clutter => "clutter",
            BackgroundChoice::Image => "image",
        }
    }
}

/// What lies on a sampled marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum OccluderKind {
    /// Nothing.
    None,
    /// A generated occlusion of this scenario.
    Generated(Scenario),
    /// Pattern `k` of `occluder_files` (drawn as written, turned by a
    /// random number of quarter turns).
    File(usize),
}

/// The look of a sampled occluder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum OccluderStyle {
    /// A named style.
    Style(Style),
    /// As dark as the print's ink, no texture (tape or parts flush with
    /// the black frame).
    Ink,
}

impl OccluderStyle {
    /// Name in files.
    #[must_use]
    pub fn name(self) -> String {
        match self {
            OccluderStyle::Ink => "ink".into(),
            OccluderStyle::Style(s) => serde_json::to_value(s)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default(),
        }
    }
}

/// A validated `[sample]` table.
#[derive(Debug, Clone, Serialize)]
pub struct Sample {
    /// Number of sampled scenes.
    pub count: usize,
    /// Images per scene (only the sensor noise differs between them).
    pub repeats: usize,
    /// Printed side of the marker square, metres (the same for every
    /// system, so every system gets the same marker-square size in pixels).
    pub square_m: f64,
    /// Marker types placed (one drawn per marker when there are several).
    pub markers: Vec<MarkerType>,
    /// Markers per frame (at most [`MAX_MARKERS_PER_FRAME`]; 0 for
    /// tag-free frames).
    pub markers_per_frame: Option<Factor>,
    /// Distance or size.
    pub size: Size,
    /// Tilt about the marker's x axis, degrees.
    pub tilt_x_deg: Option<Factor>,
    /// Tilt about the marker's y axis, degrees.
    pub tilt_y_deg: Option<Factor>,
    /// In-plane rotation, degrees.
    pub roll_deg: Option<Factor>,
    /// Horizontal position of the marker centre in the range where the
    /// printed marker fits in the frame, 0 (left) to 1 (right).
    pub pos_x: Option<Factor>,
    /// Vertical position, 0 (top) to 1 (bottom).
    pub pos_y: Option<Factor>,
    /// Ids.
    pub id: IdChoice,
    /// Print contrast: paper minus ink reflectance (the paper stays that
    /// of `[print]`).
    pub contrast: Option<Factor>,
    /// Background kinds.
    pub background: Option<Vec<BackgroundChoice>>,
    /// Clutter shapes per megapixel.
    pub clutter_density: Option<Factor>,
    /// Background photographs: the `background_images` as written, then
    /// the file names of the `*.png` in `background_dir` (name order).
    pub background_images: Vec<PathBuf>,
    /// The photo directory as written in the spec (`--photos` may have
    /// replaced it; the digests say which photographs were used).
    pub background_dir: Option<PathBuf>,
    /// FNV-1a 64 digest of each photograph's size and grey pixels, so
    /// `dataset.json` identifies the photographs wherever they were read.
    pub background_digests: Vec<String>,
    /// Background photographs, grey, full size.
    #[serde(skip)]
    pub background_sources: Vec<Arc<image::GrayImage>>,
    /// Lighting ramp: relative change of the light across half the image.
    pub gradient: Option<Factor>,
    /// Darkness of a shadow across the image (0 = none).
    pub shadow_darkness: Option<Factor>,
    /// Peak of a specular glare on one drawn marker of the frame (0 = none).
    pub glare_peak: Option<Factor>,
    /// Defocus blur sigma, pixels.
    pub defocus_px: Option<Factor>,
    /// Motion blur length, pixels.
    pub motion_blur_px: Option<Factor>,
    /// Read noise, DN.
    pub read_noise_dn: Option<Factor>,
    /// Full well for shot noise, electrons (0 = none).
    pub full_well_e: Option<Factor>,
    /// JPEG quality (100 = JPEG at the best quality).
    pub jpeg_quality: Option<Factor>,
    /// Radial distortion k1.
    pub distortion_k1: Option<Factor>,
    /// Occluder kinds.
    pub occluder_kind: Option<Vec<OccluderKind>>,
    /// Share of the markers that get an occluder (one of `occluder_kind`);
    /// the others get none. `None`: every marker draws from the kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub occluder_share: Option<f64>,
    /// Pattern files whose patterns are occluder kinds (named by the
    /// pattern's name), as written; a directory is listed file by file.
    pub occluder_files: Vec<PathBuf>,
    /// Their patterns, in the same order.
    #[serde(skip)]
    pub occluder_patterns: Vec<Arc<Occlusion>>,
    /// Occluder coverage of the marker square.
    pub occluder_coverage: Option<Factor>,
    /// Occluder reflectance (overrides the style's fill, except for
    /// [`OccluderStyle::Ink`], which stays at the print's ink).
    pub occluder_fill: Option<Factor>,
    /// Occluder looks.
    pub occluder_style: Option<Vec<OccluderStyle>>,
}

/// Keys of a factor written as a table.
const TABLE_KEYS: [&str; 4] = ["values", "range", "share", "off"];

/// Reads factor `key` of `[sample]`, checking it lies in `[min, max]`.
struct Reader<'a, 'b> {
    loc: &'a KeyLocator<'b>,
}

impl Reader<'_, '_> {
    fn factor(
        &self,
        key: &str,
        v: Option<&toml::Value>,
        min: f64,
        max: f64,
    ) -> Result<Option<Factor>> {
        self.factor_with_off(key, v, (min, max), (min, max))
    }

    /// A factor whose values lie in `allowed` and whose `off` value (when
    /// it has a share) lies in `off_allowed`.
    fn factor_with_off(
        &self,
        key: &str,
        v: Option<&toml::Value>,
        allowed: (f64, f64),
        off_allowed: (f64, f64),
    ) -> Result<Option<Factor>> {
        let Some(v) = v else { return Ok(None) };
        let err = |m: String| {
            self.loc
                .err(steps!["sample", key], format!("sample.{key}: {m}"))
        };
        let num = |x: &toml::Value| match x {
            toml::Value::Float(f) => Some(*f),
            toml::Value::Integer(i) => Some(*i as f64),
            _ => None,
        };
        let range = |a: &[toml::Value]| -> Result<Factor> {
            let nums: Option<Vec<f64>> = a.iter().map(num).collect();
            match nums.as_deref() {
                Some([lo, hi]) => {
                    if lo > hi {
                        return Err(err(format!("range [{lo}, {hi}] has lo above hi")));
                    }
                    Ok(Factor::Range(*lo, *hi))
                }
                _ => Err(err(
                    "a range is [lo, hi] (two numbers); a list is { values = [...] }".into(),
                )),
            }
        };
        let (f, shared) = match v {
            toml::Value::Array(a) => (range(a)?, None),
            toml::Value::Table(t) => {
                if let Some(bad) = t.keys().find(|k| !TABLE_KEYS.contains(&k.as_str())) {
                    return Err(self.loc.err(
                        steps!["sample", key, bad.as_str()],
                        format!(
                            "sample.{key}: unknown key '{bad}' (a list is {{ values = [...] }}; an event is {{ range = [lo, hi] or values = [...], share = p, off = x }})"
                        ),
                    ));
                }
                let f = match (t.get("values"), t.get("range")) {
                    (Some(list), None) => {
                        let nums: Option<Vec<f64>> = list
                            .as_array()
                            .and_then(|a| a.iter().map(num).collect());
                        match nums {
                            Some(n) if !n.is_empty() => Factor::List(n),
                            _ => return Err(err("a list is { values = [numbers...] }".into())),
                        }
                    }
                    (None, Some(toml::Value::Array(a))) => range(a)?,
                    (None, Some(_)) => {
                        return Err(err("a range is [lo, hi] (two numbers)".into()))
                    }
                    (Some(_), Some(_)) => {
                        return Err(err("give one of values and range, not both".into()))
                    }
                    (None, None) => {
                        return Err(err(
                            "a list is { values = [numbers...] }; an event is { range = [lo, hi], share = p, off = x }"
                                .into(),
                        ))
                    }
                };
                let shared = match (t.get("share"), t.get("off")) {
                    (None, None) => None,
                    (Some(share), Some(off)) => {
                        let (Some(share), Some(off)) = (num(share), num(off)) else {
                            return Err(err("share and off are numbers".into()));
                        };
                        if !(share > 0.0 && share <= 1.0) {
                            return Err(err(format!(
                                "share must lie in (0, 1] (the probability the factor is present), got {share}"
                            )));
                        }
                        let (lo, hi) = off_allowed;
                        if !(off.is_finite() && off >= lo && off <= hi) {
                            return Err(err(format!(
                                "off (the value when absent) must lie in {lo}..={hi}, got {off}"
                            )));
                        }
                        Some((share, off))
                    }
                    _ => {
                        return Err(err(
                            "an event needs both share = p and off = x (its value when absent)"
                                .into(),
                        ))
                    }
                };
                (f, shared)
            }
            other => match num(other) {
                Some(x) => (Factor::List(vec![x]), None),
                None => {
                    return Err(err(
                        "give a number, a range [lo, hi] or a list { values = [...] }".into(),
                    ))
                }
            },
        };
        let values = match &f {
            Factor::Range(lo, hi) => vec![*lo, *hi],
            Factor::List(v) => v.clone(),
            Factor::Shared { inner, .. } => {
                let (a, b) = inner.bounds();
                vec![a, b]
            }
        };
        if values.iter().any(|x| !x.is_finite()) {
            return Err(err("values must be finite numbers".into()));
        }
        let (lo, hi) = f.bounds();
        let (min, max) = allowed;
        if !(lo >= min && hi <= max) {
            return Err(err(format!(
                "values must lie in {min}..={max} (got {lo}..={hi})"
            )));
        }
        Ok(Some(match shared {
            None => f,
            Some((share, off)) => Factor::Shared {
                inner: Box::new(f),
                share,
                off,
            },
        }))
    }

    fn strings(&self, key: &str, v: Option<&toml::Value>) -> Result<Option<Vec<String>>> {
        let Some(v) = v else { return Ok(None) };
        let list: Option<Vec<String>> = match v {
            toml::Value::String(s) => Some(vec![s.clone()]),
            toml::Value::Array(a) if !a.is_empty() => {
                a.iter().map(|x| x.as_str().map(str::to_string)).collect()
            }
            _ => None,
        };
        list.map(Some).ok_or_else(|| {
            self.loc.err(
                steps!["sample", key],
                format!("sample.{key}: give a name or a non-empty list of names"),
            )
        })
    }

    fn choices<T>(
        &self,
        key: &str,
        v: Option<&toml::Value>,
        parse: impl Fn(&str) -> Option<T>,
        allowed: &str,
    ) -> Result<Option<Vec<T>>> {
        let Some(names) = self.strings(key, v)? else {
            return Ok(None);
        };
        names
            .iter()
            .map(|n| {
                parse(n).ok_or_else(|| {
                    self.loc.err(
                        steps!["sample", key],
                        format!("sample.{key}: '{n}' is not one of {allowed}"),
                    )
                })
            })
            .collect::<Result<Vec<T>>>()
            .map(Some)
    }
}

/// A built-in occluder kind by name.
fn occluder_kind(name: &str) -> Option<OccluderKind> {
    if name == "none" {
        return Some(OccluderKind::None);
    }
    let s: Scenario = serde_json::from_value(serde_json::Value::String(name.into())).ok()?;
    (s != Scenario::Custom).then_some(OccluderKind::Generated(s))
}

/// Keys of `occluder_kind` written as a table.
const KIND_TABLE_KEYS: [&str; 2] = ["values", "share"];

/// `occluder_kind` as a plain name or list (returned as is, no share) or
/// as `{ values = [...], share = p }`: a marker is occluded with
/// probability `p`, by one of the values, and has no occluder otherwise.
fn occluder_kind_table(
    loc: &KeyLocator,
    v: Option<&toml::Value>,
) -> Result<(Option<toml::Value>, Option<f64>)> {
    let Some(toml::Value::Table(t)) = v else {
        return Ok((v.cloned(), None));
    };
    let err = |m: &str| {
        loc.err(
            steps!["sample", "occluder_kind"],
            format!("sample.occluder_kind: {m}"),
        )
    };
    if let Some(bad) = t.keys().find(|k| !KIND_TABLE_KEYS.contains(&k.as_str())) {
        return Err(loc.err(
            steps!["sample", "occluder_kind", bad.as_str()],
            format!(
                "sample.occluder_kind: unknown key '{bad}' (give a non-empty list of names, or {{ values = [names...], share = p }})"
            ),
        ));
    }
    let (Some(values), Some(share)) = (t.get("values"), t.get("share")) else {
        return Err(err(
            "give a non-empty list of names, or { values = [names...], share = p }",
        ));
    };
    let share = match share {
        toml::Value::Float(f) => *f,
        toml::Value::Integer(i) => *i as f64,
        _ => return Err(err("share is a number")),
    };
    if !(share > 0.0 && share <= 1.0) {
        return Err(err(&format!(
            "share must lie in (0, 1] (the probability a marker is occluded), got {share}"
        )));
    }
    Ok((Some(values.clone()), Some(share)))
}

/// The built-in occluder kinds, for messages.
const BUILT_IN_KINDS: &str =
    "none, triangle, same-side, symmetry, diagonal, inner, stick, cable, flush-tape, blob";

impl Sample {
    /// Name of an occluder kind in files.
    #[must_use]
    pub fn kind_name(&self, kind: OccluderKind) -> String {
        match kind {
            OccluderKind::None => "none".into(),
            OccluderKind::Generated(s) => s.name().into(),
            OccluderKind::File(k) => self.occluder_patterns[k].name.clone(),
        }
    }
}

/// The patterns of `occluder_files`: (file as shown, pattern).
fn occluder_files(
    loc: &KeyLocator,
    files: &[PathBuf],
    base_dir: &Path,
) -> Result<Vec<(PathBuf, Arc<Occlusion>)>> {
    let mut out: Vec<(PathBuf, Arc<Occlusion>)> = Vec::new();
    for (i, p) in files.iter().enumerate() {
        let at = |m: String| {
            loc.err(
                steps!["sample", "occluder_files", i],
                format!("sample.occluder_files: {m}"),
            )
        };
        let full = base_dir.join(p);
        let found = occlusion::pattern_files(&full).map_err(|e| at(e.to_string()))?;
        for f in found {
            // Errors inside a pattern file name that file, line and column.
            let occ = Occlusion::load(&f)?;
            if occluder_kind(&occ.name).is_some() || occ.name == "custom" {
                return Err(at(format!(
                    "{}: pattern name '{}' is a built-in occluder kind; give the pattern another name",
                    f.display(),
                    occ.name
                )));
            }
            if out.iter().any(|(_, o)| o.name == occ.name) {
                return Err(at(format!(
                    "{}: a second pattern named '{}'",
                    f.display(),
                    occ.name
                )));
            }
            let shown = if full.is_dir() {
                p.join(f.file_name().unwrap_or_default())
            } else {
                p.clone()
            };
            out.push((shown, Arc::new(occ)));
        }
    }
    Ok(out)
}

fn occluder_style(name: &str) -> Option<OccluderStyle> {
    if name == "ink" {
        return Some(OccluderStyle::Ink);
    }
    serde_json::from_value(serde_json::Value::String(name.into()))
        .ok()
        .map(OccluderStyle::Style)
}

/// A photograph as grey levels; `Err` says why it cannot be used.
fn load_photo(path: &Path) -> std::result::Result<image::GrayImage, String> {
    let img = image::open(path).map_err(|e| e.to_string())?.to_luma8();
    if img.width() < MIN_PHOTO_SIDE_PX || img.height() < MIN_PHOTO_SIDE_PX {
        return Err(format!("smaller than {MIN_PHOTO_SIDE_PX} px"));
    }
    Ok(img)
}

/// The `*.png` files of a photo directory, in file-name order.
fn photo_files(dir: &Path) -> std::result::Result<Vec<PathBuf>, String> {
    if !dir.is_dir() {
        return Err(format!(
            "no such directory (write the photographs with `python eval/peers/export_photos.py {}`, or give --photos DIR)",
            dir.display()
        ));
    }
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| e.to_string())?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "png") && p.is_file())
        .collect();
    files.sort();
    if files.is_empty() {
        return Err("no *.png photographs in this directory".into());
    }
    Ok(files)
}

/// FNV-1a (Fowler, Noll, Vo), 64 bits, over the width, height and grey
/// levels of a photograph, as 16 hex digits.
fn photo_digest(img: &image::GrayImage) -> String {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;
    let mut h = OFFSET;
    let size = [img.width().to_le_bytes(), img.height().to_le_bytes()];
    for b in size.iter().flatten().chain(img.as_raw().iter()) {
        h ^= u64::from(*b);
        h = h.wrapping_mul(PRIME);
    }
    format!("{h:016x}")
}

/// The validated `[sample]` of a spec whose base settings are `base`.
pub(super) fn sample(
    loc: &KeyLocator,
    sf: &SampleFile,
    base: &Rendering,
    base_dir: &Path,
    photos_dir: Option<&Path>,
) -> Result<Sample> {
    let r = Reader { loc };
    let at = |key: &str, m: String| loc.err(steps!["sample", key], format!("sample.{key}: {m}"));
    if sf.count == 0 || sf.count > MAX_SCENES {
        return Err(at(
            "count",
            format!("{} is outside 1..={MAX_SCENES}", sf.count),
        ));
    }
    if sf.repeats == 0 || sf.repeats > MAX_REPEATS {
        return Err(at(
            "repeats",
            format!("{} is outside 1..={MAX_REPEATS}", sf.repeats),
        ));
    }
    if !(sf.square_m > 0.0 && sf.square_m.is_finite()) {
        return Err(at(
            "square_m",
            format!("{} must be a positive number of metres", sf.square_m),
        ));
    }
    let markers_per_frame = r.factor(
        "markers_per_frame",
        sf.markers_per_frame.as_ref(),
        0.0,
        MAX_MARKERS_PER_FRAME as f64,
    )?;
    // Tag-free frames (false-positive sets) need no marker type.
    let tag_free = markers_per_frame
        .as_ref()
        .is_some_and(|f| f.bounds().1 < 0.5);
    if sf.markers.is_empty() && !tag_free {
        return Err(at(
            "markers",
            "give at least one marker type (or markers_per_frame = 0 for tag-free frames)".into(),
        ));
    }
    let mut markers = Vec::new();
    for (i, m) in sf.markers.iter().enumerate() {
        let ids = MarkerModel::id_range(m.system, m.family.as_deref()).map_err(|e| {
            loc.err(
                steps!["sample", "markers", i],
                format!("sample.markers[{i}]: {e}"),
            )
        })?;
        markers.push(MarkerType {
            system: m.system,
            family: m
                .family
                .clone()
                .unwrap_or_else(|| m.system.default_family().to_string()),
            ids,
        });
    }
    let id = match &sf.id {
        None => IdChoice::Any,
        Some(toml::Value::String(s)) if s == "any" => IdChoice::Any,
        Some(toml::Value::Array(a)) if !a.is_empty() => {
            let ids: Option<Vec<u64>> = a
                .iter()
                .map(|x| x.as_integer().and_then(|i| u64::try_from(i).ok()))
                .collect();
            let Some(ids) = ids else {
                return Err(at("id", "give \"any\" or a list of ids".into()));
            };
            for t in &markers {
                if let Some(bad) = ids.iter().find(|&&i| i < t.ids.0 || i > t.ids.1) {
                    return Err(at(
                        "id",
                        format!("{} has ids {}..={}, not {bad}", t.family, t.ids.0, t.ids.1),
                    ));
                }
            }
            IdChoice::List(ids)
        }
        Some(_) => return Err(at("id", "give \"any\" or a list of ids".into())),
    };
    let size = match (&sf.side_px, &sf.distance_m) {
        (Some(v), None) => Size::SidePx(r.factor("side_px", Some(v), 4.0, 4000.0)?.expect("given")),
        (None, Some(v)) => Size::DistanceM(
            r.factor("distance_m", Some(v), 0.05, 1000.0)?
                .expect("given"),
        ),
        // Not used when no marker is placed.
        (None, None) if tag_free => Size::SidePx(Factor::List(vec![TAG_FREE_SIDE_PX])),
        _ => {
            return Err(loc.err(
                steps!["sample"],
                "sample: give exactly one of side_px and distance_m".into(),
            ))
        }
    };
    let background = r.choices(
        "background",
        sf.background.as_ref(),
        |n| match n {
            "flat" => Some(BackgroundChoice::Flat),
            "gradient" => Some(BackgroundChoice::Gradient),
            "clutter" => Some(BackgroundChoice::Clutter),
            "image" => Some(BackgroundChoice::Image),
            _ => None,
        },
        "flat, gradient, clutter, image",
    )?;
    let wants_images = background
        .as_ref()
        .is_some_and(|b| b.contains(&BackgroundChoice::Image));
    for (key, empty) in [
        (
            "background_images",
            sf.background_images.as_ref().is_some_and(Vec::is_empty),
        ),
        (
            "occluder_files",
            sf.occluder_files.as_ref().is_some_and(Vec::is_empty),
        ),
    ] {
        if empty {
            return Err(at(key, "an empty list (leave the key out)".into()));
        }
    }
    let mut photos = Vec::new();
    for (i, p) in sf.background_images.iter().flatten().enumerate() {
        let full = base_dir.join(p);
        let img = load_photo(&full).map_err(|e| {
            loc.err(
                steps!["sample", "background_images", i],
                format!("sample.background_images: {}: {e}", full.display()),
            )
        })?;
        photos.push((p.clone(), img));
    }
    if photos_dir.is_some() && sf.background_dir.is_none() {
        return Err(loc.err(
            steps!["sample"],
            "--photos replaces sample.background_dir, which this spec does not have".into(),
        ));
    }
    if let Some(written) = &sf.background_dir {
        let dir = photos_dir.map_or_else(|| base_dir.join(written), Path::to_path_buf);
        let at_dir = |m: String| {
            loc.err(
                steps!["sample", "background_dir"],
                format!("sample.background_dir: {}: {m}", dir.display()),
            )
        };
        let files = photo_files(&dir).map_err(|m| {
            let from = if photos_dir.is_some() {
                " (the --photos directory)"
            } else {
                ""
            };
            at_dir(format!("{m}{from}"))
        })?;
        for f in files {
            let img = load_photo(&f).map_err(|e| at_dir(format!("{}: {e}", f.display())))?;
            let name = f.file_name().map(PathBuf::from).unwrap_or_default();
            photos.push((name, img));
        }
    }
    if wants_images && photos.is_empty() {
        return Err(at(
            "background",
            "\"image\" needs background_images or background_dir".into(),
        ));
    }
    let background_digests = photos.iter().map(|(_, img)| photo_digest(img)).collect();
    let (background_images, background_sources): (Vec<PathBuf>, Vec<Arc<image::GrayImage>>) =
        photos.into_iter().map(|(n, i)| (n, Arc::new(i))).unzip();
    let (occluder_files, occluder_patterns): (Vec<PathBuf>, Vec<Arc<Occlusion>>) = occluder_files(
        loc,
        sf.occluder_files.as_deref().unwrap_or_default(),
        base_dir,
    )?
    .into_iter()
    .unzip();
    let mut allowed = BUILT_IN_KINDS.to_string();
    for p in &occluder_patterns {
        allowed.push_str(", ");
        allowed.push_str(&p.name);
    }
    let (kind_names, occluder_share) = occluder_kind_table(loc, sf.occluder_kind.as_ref())?;
    let occluder_kind = r.choices(
        "occluder_kind",
        kind_names.as_ref(),
        |n| {
            occluder_kind(n).or_else(|| {
                occluder_patterns
                    .iter()
                    .position(|p| p.name == n)
                    .map(OccluderKind::File)
            })
        },
        &allowed,
    )?;
    if !occluder_patterns.is_empty() && occluder_kind.is_none() {
        return Err(at(
            "occluder_files",
            "the patterns are used through occluder_kind, which is missing".into(),
        ));
    }
    let occluder_coverage = r.factor(
        "occluder_coverage",
        sf.occluder_coverage.as_ref(),
        0.0,
        crate::floor_occluders::MAX_FLOOR_COVERAGE,
    )?;
    // Only generated occluders are sized to the drawn coverage.
    let occludes = occluder_kind
        .as_ref()
        .is_some_and(|k| k.iter().any(|k| matches!(k, OccluderKind::Generated(_))));
    if occludes {
        match &occluder_coverage {
            None => {
                return Err(at(
                    "occluder_kind",
                    "occluders need occluder_coverage".into(),
                ))
            }
            Some(c) if c.bounds().0 <= 0.0 => {
                return Err(at(
                    "occluder_coverage",
                    "coverage must be above 0 (use occluder_kind \"none\" for no occluder)".into(),
                ))
            }
            _ => {}
        }
    }
    let sample = Sample {
        count: sf.count,
        repeats: sf.repeats,
        square_m: sf.square_m,
        markers,
        markers_per_frame,
        size,
        tilt_x_deg: r.factor(
            "tilt_x_deg",
            sf.tilt_x_deg.as_ref(),
            -MAX_TILT_DEG,
            MAX_TILT_DEG,
        )?,
        tilt_y_deg: r.factor(
            "tilt_y_deg",
            sf.tilt_y_deg.as_ref(),
            -MAX_TILT_DEG,
            MAX_TILT_DEG,
        )?,
        roll_deg: r.factor("roll_deg", sf.roll_deg.as_ref(), -360.0, 360.0)?,
        pos_x: r.factor("pos_x", sf.pos_x.as_ref(), 0.0, 1.0)?,
        pos_y: r.factor("pos_y", sf.pos_y.as_ref(), 0.0, 1.0)?,
        id,
        contrast: r.factor("contrast", sf.contrast.as_ref(), 0.01, base.print.paper)?,
        background,
        clutter_density: r.factor(
            "clutter_density",
            sf.clutter_density.as_ref(),
            0.0,
            20_000.0,
        )?,
        background_images,
        background_dir: sf.background_dir.clone(),
        background_digests,
        background_sources,
        gradient: r.factor("gradient", sf.gradient.as_ref(), 0.0, 1.0)?,
        shadow_darkness: r.factor("shadow_darkness", sf.shadow_darkness.as_ref(), 0.0, 1.0)?,
        glare_peak: r.factor("glare_peak", sf.glare_peak.as_ref(), 0.0, 4.0)?,
        defocus_px: r.factor("defocus_px", sf.defocus_px.as_ref(), 0.0, 20.0)?,
        motion_blur_px: r.factor(
            "motion_blur_px",
            sf.motion_blur_px.as_ref(),
            0.0,
            MAX_MOTION_BLUR_PX,
        )?,
        read_noise_dn: r.factor("read_noise_dn", sf.read_noise_dn.as_ref(), 0.0, 100.0)?,
        full_well_e: r.factor("full_well_e", sf.full_well_e.as_ref(), 0.0, 1e7)?,
        // `off = 0` is "no JPEG step" (the image stays lossless).
        jpeg_quality: r.factor_with_off(
            "jpeg_quality",
            sf.jpeg_quality.as_ref(),
            (1.0, 100.0),
            (0.0, 100.0),
        )?,
        distortion_k1: r.factor("distortion_k1", sf.distortion_k1.as_ref(), -0.5, 0.5)?,
        occluder_kind,
        occluder_share,
        occluder_files,
        occluder_patterns,
        occluder_coverage,
        occluder_fill: r.factor("occluder_fill", sf.occluder_fill.as_ref(), 0.0, 1.0)?,
        occluder_style: r.choices(
            "occluder_style",
            sf.occluder_style.as_ref(),
            occluder_style,
            "ink, tape, cable, dirt, paint, cardboard, solid",
        )?,
    };
    if let Some(k1) = &sample.distortion_k1 {
        let (lo, hi) = k1.bounds();
        for k in [lo, hi] {
            let c = &base.camera;
            crate::camera::Camera::new(
                c.width,
                c.height,
                [c.fx, c.fy, c.cx, c.cy],
                [k, 0.0, 0.0, 0.0, 0.0],
            )
            .map_err(|e| at("distortion_k1", e.to_string()))?;
        }
    }
    Ok(sample)
}

/// A sampled value recorded in `draws.csv`.
#[derive(Debug, Clone, PartialEq)]
pub enum DrawValue {
    /// A number (written with Rust's `{}`).
    Number(f64),
    /// A category.
    Text(String),
}

impl std::fmt::Display for DrawValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DrawValue::Number(x) => write!(f, "{x}"),
            DrawValue::Text(s) => f.write_str(s),
        }
    }
}

/// One row of `draws.csv` (without the image index).
#[derive(Debug, Clone, PartialEq)]
pub struct Draw {
    /// The marker it belongs to (`marker_index` in truth.csv), or `None`
    /// for the whole image.
    pub marker: Option<usize>,
    /// Factor name, with its unit suffix.
    pub factor: &'static str,
    /// Value.
    pub value: DrawValue,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_event_is_absent_below_one_minus_its_share_and_spans_its_range_above() {
        let f = Factor::Shared {
            inner: Box::new(Factor::Range(2.0, 6.0)),
            share: 0.25,
            off: 0.0,
        };
        let n = 1000;
        let vals: Vec<f64> = (0..n).map(|k| f.at((k as f64 + 0.5) / n as f64)).collect();
        let absent = vals.iter().filter(|v| **v == 0.0).count();
        assert_eq!(absent, 750);
        let drawn: Vec<f64> = vals.iter().copied().filter(|v| *v != 0.0).collect();
        let (lo, hi) = drawn
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        assert!(
            (2.0..2.02).contains(&lo) && hi <= 6.0 && hi > 5.98,
            "{lo} {hi}"
        );
        // Uniform over the range when present: a quarter in each quarter.
        let first = drawn.iter().filter(|v| **v < 3.0).count();
        assert_eq!(first, drawn.len() / 4);
        assert_eq!(f.bounds(), (0.0, 6.0));
        // Whole numbers: the off value, or each of 50..=100 when present.
        let q = Factor::Shared {
            inner: Box::new(Factor::Range(50.0, 100.0)),
            share: 0.5,
            off: 0.0,
        };
        assert_eq!(q.at_int(0.49), 0);
        assert_eq!(q.at_int(0.5), 50);
        assert_eq!(q.at_int(0.999_999), 100);
        // A share of 1 is always present.
        assert_eq!(present(0.0, 1.0), Some(0.0));
        assert_eq!(present(0.3, 0.5), None);
    }
}

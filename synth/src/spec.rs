//! Dataset specs: a TOML file describing a camera, markers, a sweep of
//! poses and occlusions; validated into a [`DatasetSpec`] that yields one
//! [`Scene`] per image. The file format is documented in
//! `datasets/README.md`.
//!
//! Errors name the spec file, line and column: TOML syntax errors, unknown
//! keys and wrong types come from the TOML parser's spans; value errors
//! (negative sizes, a marker behind the camera, ...) point at the key that
//! holds the value.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};
use toml::Spanned;

use crate::background::{Background, BackgroundKind};
use crate::camera::{Camera, Defocus};
use crate::effects::{Effects, Lighting, MotionBlur, Sensor, Shadow};
use crate::error::{Result, SynthError};
use crate::markers::{MarkerModel, MarkerSystem};
use crate::occlusion::{self, Occlusion, Scenario, Style};
use crate::pose::{axis_rotation, Pose};
use crate::rng::{image_rng, Stream};
use crate::scene::{PlacedMarker, Print, Scene};

/// Line and column (from 1) of a byte offset.
#[must_use]
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// A TOML parse or type error as a [`SynthError::Input`] with position.
#[must_use]
pub fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> SynthError {
    let (line, column) = e.span().map_or((1, 1), |s| line_col(text, s.start));
    SynthError::Input {
        path: path.to_path_buf(),
        line,
        column,
        message: e.message().trim().to_string(),
    }
}

// ---------------------------------------------------------------------------
// File schema

fn default_one() -> usize {
    1
}
fn default_true() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DefocusFile {
    f_number: f64,
    focus_distance_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraFile {
    width: u32,
    height: u32,
    focal_length_mm: Option<f64>,
    pixel_pitch_um: Option<f64>,
    fx: Option<f64>,
    fy: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    #[serde(default)]
    distortion: [f64; 5],
    defocus: Option<DefocusFile>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct PrintFile {
    ink: Option<f64>,
    paper: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BackgroundFile {
    kind: String,
    level: Option<f64>,
    from: Option<f64>,
    to: Option<f64>,
    angle: Option<f64>,
    base: Option<f64>,
    count: Option<usize>,
    min_size_px: Option<f64>,
    max_size_px: Option<f64>,
    path: Option<PathBuf>,
    distance_m: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ShadowFile {
    polygon: Vec<[f64; 2]>,
    darkness: f64,
    #[serde(default)]
    softness_px: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LightingFile {
    gain: Option<f64>,
    gradient: Option<[f64; 2]>,
    vignetting: Option<f64>,
    #[serde(default)]
    shadow: Vec<ShadowFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorFile {
    #[serde(default)]
    read_noise_dn: f64,
    #[serde(default)]
    full_well_e: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionBlurFile {
    length_px: f64,
    #[serde(default)]
    angle: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EffectsFile {
    motion_blur: Option<MotionBlurFile>,
    jpeg_quality: Option<u8>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MarkerFile {
    system: MarkerSystem,
    family: Option<String>,
    id: u64,
    size_m: f64,
    translation: [f64; 3],
    #[serde(default)]
    rotation: [f64; 3],
    #[serde(default = "default_true")]
    occlude: bool,
}

/// What a sweep varies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SweepParam {
    /// Translation x, metres.
    X,
    /// Translation y, metres.
    Y,
    /// Translation z (distance along the optical axis), metres.
    Z,
    /// Rotation about the marker's own x axis, radians.
    Rx,
    /// Rotation about the marker's own y axis, radians.
    Ry,
    /// Rotation about the marker's own z axis (in-plane), radians.
    Rz,
}

impl SweepParam {
    /// Name in files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            SweepParam::X => "x",
            SweepParam::Y => "y",
            SweepParam::Z => "z",
            SweepParam::Rx => "rx",
            SweepParam::Ry => "ry",
            SweepParam::Rz => "rz",
        }
    }

    /// Whether the parameter is an angle.
    #[must_use]
    pub fn is_angle(self) -> bool {
        matches!(self, SweepParam::Rx | SweepParam::Ry | SweepParam::Rz)
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    param: SweepParam,
    from: f64,
    to: f64,
    step: Option<f64>,
    count: Option<usize>,
    unit: Option<String>,
    markers: Option<Vec<usize>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GenerateFile {
    scenario: Scenario,
    coverage: f64,
    count: usize,
    style: Option<Style>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OcclusionFile {
    #[serde(default)]
    patterns: Vec<Spanned<PathBuf>>,
    #[serde(default)]
    generate: Vec<Spanned<GenerateFile>>,
    style: Option<Style>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecFile {
    name: Option<String>,
    description: Option<String>,
    #[serde(default)]
    seed: u64,
    #[serde(default = "default_one")]
    images: usize,
    camera: Spanned<CameraFile>,
    print: Option<Spanned<PrintFile>>,
    background: Option<Spanned<BackgroundFile>>,
    lighting: Option<Spanned<LightingFile>>,
    sensor: Option<Spanned<SensorFile>>,
    effects: Option<Spanned<EffectsFile>>,
    #[serde(default)]
    markers: Vec<Spanned<MarkerFile>>,
    sweep: Option<Spanned<SweepFile>>,
    occlusion: Option<Spanned<OcclusionFile>>,
}

// ---------------------------------------------------------------------------
// Validated spec

/// A sweep of one pose parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sweep {
    /// What varies.
    pub param: SweepParam,
    /// The values, metres or radians.
    pub values: Vec<f64>,
    /// Markers it moves (indices into the spec's markers).
    pub markers: Vec<usize>,
}

/// A generator request: `count` random occlusions of a scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GenerateRequest {
    /// Scenario.
    pub scenario: Scenario,
    /// Exact coverage of each.
    pub coverage: f64,
    /// How many.
    pub count: usize,
    /// Look (random per occluder when `None`).
    pub style: Option<Style>,
}

/// The occlusions of a dataset: fixed patterns and generated ones.
#[derive(Debug, Clone, Default)]
pub struct OcclusionSet {
    /// Patterns read from files, in order.
    pub patterns: Vec<Arc<Occlusion>>,
    /// Pattern file of each, relative to the spec's directory as written.
    pub pattern_files: Vec<PathBuf>,
    /// Generator requests.
    pub generate: Vec<GenerateRequest>,
}

impl OcclusionSet {
    /// Number of occlusion variants (one image each per sweep value).
    #[must_use]
    pub fn len(&self) -> usize {
        self.patterns.len() + self.generate.iter().map(|g| g.count).sum::<usize>()
    }

    /// Whether there are none.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// A marker of the spec with its base pose.
#[derive(Debug, Clone)]
pub struct MarkerEntry {
    /// Shapes.
    pub model: Arc<MarkerModel>,
    /// Printed size, metres.
    pub size_m: f64,
    /// Pose before the sweep is applied.
    pub pose: Pose,
    /// Whether the spec's occlusions apply to it.
    pub occlude: bool,
}

/// What one image of a dataset is made of.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Frame {
    /// Image index.
    pub index: usize,
    /// Sweep value (metres or radians), if the spec sweeps.
    pub value: Option<f64>,
    /// Occlusion variant index, if the spec occludes.
    pub occlusion: Option<usize>,
    /// Repeat index (`images` in the spec).
    pub repeat: usize,
}

/// A validated dataset spec.
#[derive(Debug, Clone)]
pub struct DatasetSpec {
    /// The spec file.
    pub path: PathBuf,
    /// Its text, as read.
    pub text: String,
    /// Dataset name (the file stem unless given).
    pub name: String,
    /// Free text.
    pub description: String,
    /// Seed of every random choice.
    pub seed: u64,
    /// Images per sweep value and occlusion variant.
    pub repeat: usize,
    /// Camera.
    pub camera: Camera,
    /// Print reflectances.
    pub print: Print,
    /// Background.
    pub background: Background,
    /// Lighting.
    pub lighting: Lighting,
    /// Sensor.
    pub sensor: Sensor,
    /// Effects.
    pub effects: Effects,
    /// Markers.
    pub markers: Vec<MarkerEntry>,
    /// Sweep, if any.
    pub sweep: Option<Sweep>,
    /// Occlusions (empty when none).
    pub occlusion: OcclusionSet,
}

/// Locates keys in the spec text for error messages.
struct Locator<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Locator<'_> {
    /// An error at the line of `key` in the table that starts at `span`
    /// (the parser's span of a `[table]` is its header only, so the search
    /// runs on to the next header), or at the span's start.
    fn err(&self, span: Range<usize>, key: Option<&str>, message: String) -> SynthError {
        let mut offset = span.start;
        if let Some(key) = key {
            let start = span.start.min(self.text.len());
            let mut pos = start;
            for (n, line) in self.text[start..].split_inclusive('\n').enumerate() {
                let t = line.trim_start();
                if n > 0 && pos >= span.end && is_header(t) {
                    break;
                }
                if let Some(rest) = t.strip_prefix(key) {
                    if rest.trim_start().starts_with('=') {
                        offset = pos + (line.len() - t.len());
                        break;
                    }
                }
                pos += line.len();
            }
        }
        let (line, column) = line_col(self.text, offset);
        SynthError::Input {
            path: self.path.to_path_buf(),
            line,
            column,
            message,
        }
    }
}

/// Whether a (left-trimmed) line is a table header such as `[camera]` or
/// `[[markers]]` (and not the continuation of an array such as `[0.5, 1],`).
fn is_header(t: &str) -> bool {
    t.strip_prefix('[')
        .map(|r| r.trim_start_matches('['))
        .and_then(|r| r.chars().next())
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_' || c == '"')
}

fn check_unit(v: f64) -> bool {
    (0.0..=1.0).contains(&v)
}

impl DatasetSpec {
    /// Reads and validates a spec file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| SynthError::io(path, e))?;
        Self::from_toml(&text, path)
    }

    /// Validates a spec given as text; `path` names it in errors and
    /// relative paths inside it are relative to its directory.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        let file: SpecFile = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let loc = Locator { path, text };
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();

        // Camera.
        let cam_span = file.camera.span();
        let c = file.camera.get_ref();
        let in_camera = |e: SynthError, key: &str| match e {
            SynthError::InvalidParameter { name, reason } => loc.err(
                cam_span.clone(),
                Some(key),
                format!("camera: invalid {name}: {reason}"),
            ),
            other => other,
        };
        let mut camera = match (c.fx, c.focal_length_mm, c.pixel_pitch_um) {
            (Some(fx), _, _) => {
                let fy = c.fy.unwrap_or(fx);
                Camera::new(
                    c.width,
                    c.height,
                    [
                        fx,
                        fy,
                        c.cx.unwrap_or(crate::camera::centre(c.width)),
                        c.cy.unwrap_or(crate::camera::centre(c.height)),
                    ],
                    c.distortion,
                )
                .map_err(|e| in_camera(e, "fx"))?
                .with_lens(c.focal_length_mm, c.pixel_pitch_um)
            }
            (None, Some(f), Some(p)) => {
                let mut cam = Camera::from_lens(c.width, c.height, f, p)
                    .map_err(|e| in_camera(e, "focal_length_mm"))?;
                let cx = c.cx.unwrap_or(cam.cx);
                let cy = c.cy.unwrap_or(cam.cy);
                let fy = c.fy.unwrap_or(cam.fy);
                cam = Camera::new(c.width, c.height, [cam.fx, fy, cx, cy], c.distortion)
                    .map_err(|e| in_camera(e, "distortion"))?
                    .with_lens(Some(f), Some(p));
                cam
            }
            _ => return Err(loc.err(
                cam_span,
                None,
                "camera: give fx (and optionally fy, cx, cy) or focal_length_mm and pixel_pitch_um"
                    .into(),
            )),
        };
        if let Some(d) = &c.defocus {
            camera = camera
                .with_defocus(Defocus {
                    f_number: d.f_number,
                    focus_distance_m: d.focus_distance_m,
                })
                .map_err(|e| in_camera(e, "f_number"))?;
        }

        // Print.
        let print = match &file.print {
            None => Print::default(),
            Some(p) => {
                let d = Print::default();
                let pr = Print {
                    ink: p.get_ref().ink.unwrap_or(d.ink),
                    paper: p.get_ref().paper.unwrap_or(d.paper),
                };
                for (key, v) in [("ink", pr.ink), ("paper", pr.paper)] {
                    if !check_unit(v) {
                        return Err(loc.err(
                            p.span(),
                            Some(key),
                            format!("print.{key} = {v} is outside 0..=1"),
                        ));
                    }
                }
                pr
            }
        };

        let background = match &file.background {
            None => Background {
                kind: BackgroundKind::Flat { level: 0.5 },
                distance_m: 5.0,
            },
            Some(b) => Self::background(&loc, b, &base_dir, &camera)?,
        };
        let lighting = match &file.lighting {
            None => Lighting::default(),
            Some(l) => {
                let lf = l.get_ref();
                let lighting = Lighting {
                    gain: lf.gain.unwrap_or(1.0),
                    gradient: lf.gradient.unwrap_or([0.0; 2]),
                    vignetting: lf.vignetting.unwrap_or(0.0),
                    shadows: lf
                        .shadow
                        .iter()
                        .map(|s| Shadow {
                            polygon: s.polygon.clone(),
                            darkness: s.darkness,
                            softness_px: s.softness_px,
                        })
                        .collect(),
                };
                if !(lighting.gain >= 0.0 && lighting.gain.is_finite()) {
                    return Err(loc.err(
                        l.span(),
                        Some("gain"),
                        format!("lighting.gain = {} must be >= 0", lighting.gain),
                    ));
                }
                if !lighting.gradient.iter().all(|g| g.is_finite()) {
                    return Err(loc.err(
                        l.span(),
                        Some("gradient"),
                        "lighting.gradient must be finite".into(),
                    ));
                }
                if !check_unit(lighting.vignetting) {
                    return Err(loc.err(
                        l.span(),
                        Some("vignetting"),
                        format!(
                            "lighting.vignetting = {} is outside 0..=1",
                            lighting.vignetting
                        ),
                    ));
                }
                for s in &lighting.shadows {
                    let ok = check_unit(s.darkness)
                        && (0.0..=100.0).contains(&s.softness_px)
                        && s.polygon.len() >= 3
                        && s.polygon.iter().flatten().all(|v| v.is_finite());
                    if !ok {
                        return Err(loc.err(
                            l.span(),
                            Some("darkness"),
                            "lighting.shadow: needs a polygon of 3+ points, darkness in 0..=1 and softness_px in 0..=100".into(),
                        ));
                    }
                }
                lighting
            }
        };
        let sensor = match &file.sensor {
            None => Sensor::default(),
            Some(s) => {
                let sf = s.get_ref();
                for (key, v) in [
                    ("read_noise_dn", sf.read_noise_dn),
                    ("full_well_e", sf.full_well_e),
                ] {
                    if !(v >= 0.0 && v.is_finite()) {
                        return Err(loc.err(
                            s.span(),
                            Some(key),
                            format!("sensor.{key} = {v} must be >= 0"),
                        ));
                    }
                }
                Sensor {
                    read_noise_dn: sf.read_noise_dn,
                    full_well_e: sf.full_well_e,
                }
            }
        };
        let effects = match &file.effects {
            None => Effects::default(),
            Some(e) => {
                let ef = e.get_ref();
                if let Some(q) = ef.jpeg_quality {
                    if !(1..=100).contains(&q) {
                        return Err(loc.err(
                            e.span(),
                            Some("jpeg_quality"),
                            format!("effects.jpeg_quality = {q} is outside 1..=100"),
                        ));
                    }
                }
                if let Some(m) = &ef.motion_blur {
                    if !(m.length_px >= 0.0 && m.length_px <= 200.0 && m.angle.is_finite()) {
                        return Err(loc.err(
                            e.span(),
                            Some("motion_blur"),
                            format!(
                                "effects.motion_blur.length_px = {} is outside 0..=200",
                                m.length_px
                            ),
                        ));
                    }
                }
                Effects {
                    motion_blur: ef.motion_blur.as_ref().map(|m| MotionBlur {
                        length_px: m.length_px,
                        angle: m.angle,
                    }),
                    jpeg_quality: ef.jpeg_quality,
                }
            }
        };

        // Markers.
        // No markers is allowed: background-only images for false-positive
        // tests (their truth.csv has a header and no rows).
        let mut markers = Vec::new();
        for (i, m) in file.markers.iter().enumerate() {
            let mf = m.get_ref();
            if !(mf.size_m > 0.0 && mf.size_m.is_finite()) {
                return Err(loc.err(
                    m.span(),
                    Some("size_m"),
                    format!(
                        "markers[{i}].size_m = {} must be a positive number of metres",
                        mf.size_m
                    ),
                ));
            }
            if !mf
                .translation
                .iter()
                .chain(&mf.rotation)
                .all(|v| v.is_finite())
            {
                return Err(loc.err(
                    m.span(),
                    Some("translation"),
                    format!("markers[{i}]: translation and rotation must be finite"),
                ));
            }
            let model = MarkerModel::new(mf.system, mf.family.as_deref(), mf.id).map_err(|e| {
                let key = if matches!(e, SynthError::InvalidParameter { name: "family", .. })
                    || matches!(e, SynthError::Tag(coppertag::Error::UnknownFamily { .. }))
                {
                    "family"
                } else {
                    "id"
                };
                loc.err(m.span(), Some(key), format!("markers[{i}]: {e}"))
            })?;
            markers.push(MarkerEntry {
                model: Arc::new(model),
                size_m: mf.size_m,
                pose: Pose::from_rvec(mf.rotation, mf.translation),
                occlude: mf.occlude,
            });
        }

        // Sweep.
        let sweep = match &file.sweep {
            None => None,
            Some(s) => Some(Self::sweep(&loc, s, markers.len())?),
        };

        // Occlusion.
        let mut occl = OcclusionSet::default();
        if let Some(o) = &file.occlusion {
            let of = o.get_ref();
            for p in &of.patterns {
                let full = base_dir.join(p.get_ref());
                let files = occlusion::pattern_files(&full)
                    .map_err(|e| loc.err(p.span(), None, format!("occlusion.patterns: {e}")))?;
                for f in files {
                    let mut occ = Occlusion::load(&f)?;
                    if let Some(style) = of.style {
                        for oc in &mut occ.occluders {
                            oc.appearance = style.appearance();
                        }
                    }
                    let shown = p.get_ref().join(f.file_name().unwrap_or_default());
                    occl.pattern_files.push(if full.is_dir() {
                        shown
                    } else {
                        p.get_ref().clone()
                    });
                    occl.patterns.push(Arc::new(occ));
                }
            }
            for g in &of.generate {
                let gf = g.get_ref();
                let max = occlusion::max_coverage(gf.scenario);
                if !(gf.coverage > 0.0 && gf.coverage <= max) {
                    return Err(loc.err(
                        g.span(),
                        Some("coverage"),
                        format!(
                            "occlusion.generate: coverage {} is outside (0, {max}] for scenario {}",
                            gf.coverage,
                            gf.scenario.name()
                        ),
                    ));
                }
                if gf.count == 0 || gf.count > 1_000_000 {
                    return Err(loc.err(
                        g.span(),
                        Some("count"),
                        format!(
                            "occlusion.generate: count {} is outside 1..=1000000",
                            gf.count
                        ),
                    ));
                }
                occl.generate.push(GenerateRequest {
                    scenario: gf.scenario,
                    coverage: gf.coverage,
                    count: gf.count,
                    style: gf.style.or(of.style),
                });
            }
            if occl.is_empty() {
                return Err(loc.err(
                    o.span(),
                    None,
                    "occlusion: give patterns or generate".into(),
                ));
            }
        }

        if file.images == 0 || file.images > 1_000_000 {
            return Err(loc.err(
                0..text.len(),
                Some("images"),
                format!("images = {} is outside 1..=1000000", file.images),
            ));
        }
        let name = file.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "dataset".into())
        });
        let spec = DatasetSpec {
            path: path.to_path_buf(),
            text: text.to_string(),
            name,
            description: file.description.clone().unwrap_or_default(),
            seed: file.seed,
            repeat: file.images,
            camera,
            print,
            background,
            lighting,
            sensor,
            effects,
            markers,
            sweep,
            occlusion: occl,
        };
        let total = spec.image_count();
        if total == 0 || total > 10_000_000 {
            return Err(loc.err(
                0..0,
                None,
                format!("the spec describes {total} images; 1..=10000000 are allowed"),
            ));
        }
        spec.check_poses(&loc, &file)?;
        Ok(spec)
    }

    fn background(
        loc: &Locator,
        b: &Spanned<BackgroundFile>,
        base_dir: &Path,
        camera: &Camera,
    ) -> Result<Background> {
        let bf = b.get_ref();
        let span = b.span();
        let level = |key: &str, v: Option<f64>, default: f64| -> Result<f64> {
            let v = v.unwrap_or(default);
            if check_unit(v) {
                Ok(v)
            } else {
                Err(loc.err(
                    span.clone(),
                    Some(key),
                    format!("background.{key} = {v} is outside 0..=1"),
                ))
            }
        };
        let allowed: &[&str] = match bf.kind.as_str() {
            "flat" => &["level"],
            "gradient" => &["from", "to", "angle"],
            "clutter" => &["base", "count", "min_size_px", "max_size_px"],
            "image" => &["path"],
            other => {
                return Err(loc.err(
                    span,
                    Some("kind"),
                    format!(
                        "background.kind '{other}' is not one of flat, gradient, clutter, image"
                    ),
                ));
            }
        };
        let given = [
            ("level", bf.level.is_some()),
            ("from", bf.from.is_some()),
            ("to", bf.to.is_some()),
            ("angle", bf.angle.is_some()),
            ("base", bf.base.is_some()),
            ("count", bf.count.is_some()),
            ("min_size_px", bf.min_size_px.is_some()),
            ("max_size_px", bf.max_size_px.is_some()),
            ("path", bf.path.is_some()),
        ];
        for (key, is) in given {
            if is && !allowed.contains(&key) {
                return Err(loc.err(
                    span,
                    Some(key),
                    format!("background.{key} does not apply to kind = \"{}\"", bf.kind),
                ));
            }
        }
        let distance_m = bf.distance_m.unwrap_or(5.0);
        if !(distance_m > 0.0 && distance_m.is_finite()) {
            return Err(loc.err(
                span,
                Some("distance_m"),
                format!("background.distance_m = {distance_m} must be positive"),
            ));
        }
        let kind = match bf.kind.as_str() {
            "flat" => BackgroundKind::Flat {
                level: level("level", bf.level, 0.5)?,
            },
            "gradient" => BackgroundKind::Gradient {
                from: level("from", bf.from, 0.3)?,
                to: level("to", bf.to, 0.7)?,
                angle: bf.angle.unwrap_or(0.0),
            },
            "clutter" => {
                let min = bf.min_size_px.unwrap_or(12.0);
                let max = bf.max_size_px.unwrap_or(160.0);
                if !(min > 0.0 && max >= min && max <= 10_000.0) {
                    return Err(loc.err(span, Some("min_size_px"), format!("background: need 0 < min_size_px <= max_size_px <= 10000 (got {min}, {max})")));
                }
                let count = bf.count.unwrap_or(60);
                if count > 100_000 {
                    return Err(loc.err(
                        span,
                        Some("count"),
                        format!("background.count = {count} is more than 100000"),
                    ));
                }
                BackgroundKind::Clutter {
                    base: level("base", bf.base, 0.55)?,
                    count,
                    min_size_px: min,
                    max_size_px: max,
                }
            }
            _ => {
                let Some(p) = &bf.path else {
                    return Err(loc.err(
                        span,
                        Some("kind"),
                        "background.kind = \"image\" needs path".into(),
                    ));
                };
                let full = base_dir.join(p);
                let img = image::open(&full)
                    .map_err(|e| {
                        loc.err(
                            span.clone(),
                            Some("path"),
                            format!("background.path {}: {e}", full.display()),
                        )
                    })?
                    .to_luma8();
                let img = image::imageops::resize(
                    &img,
                    camera.width,
                    camera.height,
                    image::imageops::FilterType::Triangle,
                );
                BackgroundKind::Image {
                    path: p.clone(),
                    pixels: Arc::new(img.pixels().map(|q| f32::from(q.0[0]) / 255.0).collect()),
                }
            }
        };
        Ok(Background { kind, distance_m })
    }

    fn sweep(loc: &Locator, s: &Spanned<SweepFile>, n_markers: usize) -> Result<Sweep> {
        let sf = s.get_ref();
        let span = s.span();
        let unit = match (sf.unit.as_deref(), sf.param.is_angle()) {
            (None | Some("rad"), true) | (None | Some("m"), false) => 1.0,
            (Some("deg"), true) => std::f64::consts::PI / 180.0,
            (Some("mm"), false) => 1e-3,
            (Some(u), _) => {
                return Err(loc.err(
                    span,
                    Some("unit"),
                    format!(
                        "sweep.unit '{u}' does not fit param {} (angles: rad, deg; lengths: m, mm)",
                        sf.param.name()
                    ),
                ))
            }
        };
        if !(sf.from.is_finite() && sf.to.is_finite()) {
            return Err(loc.err(
                span,
                Some("from"),
                "sweep.from and sweep.to must be finite".into(),
            ));
        }
        let values: Vec<f64> = match (sf.step, sf.count) {
            (Some(step), None) => {
                if step.is_nan() || step <= 0.0 {
                    return Err(loc.err(
                        span,
                        Some("step"),
                        format!("sweep.step = {step} must be positive"),
                    ));
                }
                if sf.to < sf.from {
                    return Err(loc.err(
                        span,
                        Some("to"),
                        format!("sweep.to = {} is below sweep.from = {}", sf.to, sf.from),
                    ));
                }
                let n = (sf.to - sf.from) / step;
                let k = n.round();
                if (n - k).abs() > 1e-6 || k > 1e7 {
                    return Err(loc.err(
                        span,
                        Some("step"),
                        format!(
                            "sweep: from {} to {} is not a whole number of steps of {step}",
                            sf.from, sf.to
                        ),
                    ));
                }
                (0..=k as usize)
                    .map(|i| (sf.from + i as f64 * step) * unit)
                    .collect()
            }
            (None, Some(count)) => {
                if count == 0 || count > 10_000_000 {
                    return Err(loc.err(
                        span,
                        Some("count"),
                        format!("sweep.count = {count} is outside 1..=10000000"),
                    ));
                }
                if count == 1 {
                    vec![sf.from * unit]
                } else {
                    (0..count)
                        .map(|i| {
                            (sf.from + (sf.to - sf.from) * i as f64 / (count - 1) as f64) * unit
                        })
                        .collect()
                }
            }
            _ => {
                return Err(loc.err(
                    span,
                    None,
                    "sweep: give exactly one of step and count".into(),
                ))
            }
        };
        let markers = sf
            .markers
            .clone()
            .unwrap_or_else(|| (0..n_markers).collect());
        if let Some(&bad) = markers.iter().find(|&&m| m >= n_markers) {
            return Err(loc.err(
                span,
                Some("markers"),
                format!("sweep.markers: there is no marker {bad} (the spec has {n_markers})"),
            ));
        }
        Ok(Sweep {
            param: sf.param,
            values,
            markers,
        })
    }

    /// Number of images.
    #[must_use]
    pub fn image_count(&self) -> usize {
        let sweep = self.sweep.as_ref().map_or(1, |s| s.values.len());
        let occ = self.occlusion.len().max(1);
        sweep * occ * self.repeat
    }

    /// What image `index` is made of.
    #[must_use]
    pub fn frame(&self, index: usize) -> Frame {
        let occ_n = self.occlusion.len().max(1);
        let repeat = index % self.repeat;
        let rest = index / self.repeat;
        let occ = rest % occ_n;
        let s = rest / occ_n;
        Frame {
            index,
            value: self.sweep.as_ref().map(|sw| sw.values[s]),
            occlusion: (!self.occlusion.is_empty()).then_some(occ),
            repeat,
        }
    }

    /// The pose of marker `m` for a sweep value.
    #[must_use]
    pub fn pose(&self, m: usize, value: Option<f64>) -> Pose {
        let mut pose = self.markers[m].pose;
        if let (Some(sw), Some(v)) = (&self.sweep, value) {
            if sw.markers.contains(&m) {
                match sw.param {
                    SweepParam::X => pose.translation.x = v,
                    SweepParam::Y => pose.translation.y = v,
                    SweepParam::Z => pose.translation.z = v,
                    SweepParam::Rx => pose.rotation *= axis_rotation(0, v),
                    SweepParam::Ry => pose.rotation *= axis_rotation(1, v),
                    SweepParam::Rz => pose.rotation *= axis_rotation(2, v),
                }
            }
        }
        pose
    }

    /// The occlusion of variant `k` for image `index` (generated ones are
    /// drawn from the image's own random stream).
    pub fn occlusion_variant(&self, k: usize, index: usize) -> Result<Arc<Occlusion>> {
        if k < self.occlusion.patterns.len() {
            return Ok(self.occlusion.patterns[k].clone());
        }
        let mut j = k - self.occlusion.patterns.len();
        for g in &self.occlusion.generate {
            if j < g.count {
                let mut rng = image_rng(self.seed, index as u64, Stream::Occlusion);
                let name = format!("gen-{}-{:.4}-{j}", g.scenario.name(), g.coverage);
                return occlusion::generate(g.scenario, g.coverage, g.style, name, &mut rng)
                    .map(Arc::new);
            }
            j -= g.count;
        }
        unreachable!("occlusion variant {k} out of range")
    }

    /// The scene of image `index`.
    pub fn scene(&self, index: usize) -> Result<Scene> {
        let frame = self.frame(index);
        let occ = frame
            .occlusion
            .map(|k| self.occlusion_variant(k, index))
            .transpose()?;
        let markers = self
            .markers
            .iter()
            .enumerate()
            .map(|(i, m)| PlacedMarker {
                model: m.model.clone(),
                size_m: m.size_m,
                pose: self.pose(i, frame.value),
                occlusion: if m.occlude { occ.clone() } else { None },
            })
            .collect();
        Ok(Scene {
            camera: self.camera.clone(),
            print: self.print,
            background: self.background.clone(),
            lighting: self.lighting.clone(),
            sensor: self.sensor,
            effects: self.effects,
            markers,
            seed: self.seed,
            index: index as u64,
        })
    }

    /// Every distinct pose of every marker must be in front of the camera
    /// and inside the lens model's valid field.
    fn check_poses(&self, loc: &Locator, file: &SpecFile) -> Result<()> {
        let values: Vec<Option<f64>> = match &self.sweep {
            None => vec![None],
            Some(s) => s.values.iter().map(|&v| Some(v)).collect(),
        };
        // How far occluders reach from the marker-square centre, in marker
        // units (generated ones overhang the square by at most 0.25).
        let mut occ_reach = if self.occlusion.generate.is_empty() {
            0.0
        } else {
            0.75f64
        };
        for p in &self.occlusion.patterns {
            for v in p.occluders.iter().flat_map(|o| &o.polygon) {
                occ_reach = occ_reach.max((v[0] - 0.5).abs()).max((v[1] - 0.5).abs());
            }
        }
        for (i, m) in self.markers.iter().enumerate() {
            let unit = m.model.metres_per_unit(m.size_m);
            let e = if m.occlude {
                m.model.half_extent.max(occ_reach)
            } else {
                m.model.half_extent
            };
            for &v in &values {
                let pose = self.pose(i, v);
                let at = match v {
                    Some(v) => format!(
                        " at sweep {} = {v}",
                        self.sweep.as_ref().map_or("", |s| s.param.name())
                    ),
                    None => String::new(),
                };
                // The printed square's outline, 8 points a side.
                for k in 0..32 {
                    let t = f64::from(k % 8) / 8.0;
                    let p = match k / 8 {
                        0 => [-e + 2.0 * e * t, -e],
                        1 => [e, -e + 2.0 * e * t],
                        2 => [e - 2.0 * e * t, e],
                        _ => [-e, e - 2.0 * e * t],
                    };
                    let q = pose.apply(&nalgebra::Vector3::new(p[0] * unit, p[1] * unit, 0.0));
                    if q.z < 0.01 {
                        return Err(loc.err(
                            file.markers[i].span(),
                            Some("translation"),
                            format!("markers[{i}] is behind the camera{at}: part of it (or of its occluders) is at depth {:.3} m (at least 0.01 m in front is needed)", q.z),
                        ));
                    }
                    if self.camera.project(&q).is_none() {
                        return Err(loc.err(
                            file.markers[i].span(),
                            Some("translation"),
                            format!("markers[{i}]{at} (or its occluders) reaches outside the field where the distortion model is valid"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// The spec as JSON (for `dataset.json`): every resolved setting.
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        let markers: Vec<serde_json::Value> = self
            .markers
            .iter()
            .map(|m| {
                serde_json::json!({
                    "marker": m.model.system.name(),
                    "family": m.model.family,
                    "id": m.model.id,
                    "size_m": m.size_m,
                    "square_m": m.model.metres_per_unit(m.size_m),
                    "rvec": m.pose.rvec(),
                    "tvec": m.pose.tvec(),
                    "occlude": m.occlude,
                })
            })
            .collect();
        serde_json::json!({
            "name": self.name,
            "description": self.description,
            "seed": self.seed,
            "images_per_variant": self.repeat,
            "camera": self.camera,
            "print": self.print,
            "background": self.background,
            "lighting": self.lighting,
            "sensor": self.sensor,
            "effects": self.effects,
            "markers": markers,
            "sweep": self.sweep,
            "occlusion": {
                "patterns": self.occlusion.patterns.iter().zip(&self.occlusion.pattern_files).map(|(p, f)| serde_json::json!({
                    "file": f,
                    "name": p.name,
                    "scenario": p.scenario,
                    "coverage": p.coverage(),
                    "occluder_fractions": p.occluder_fractions(),
                    "occluders": p.occluders,
                })).collect::<Vec<_>>(),
                "generate": self.occlusion.generate,
            },
        })
    }
}

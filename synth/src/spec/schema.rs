//! The spec file as written: one struct per TOML table, deserialised by
//! serde. Unknown keys and wrong types are rejected here, by the parser,
//! with its positions; values are checked by the sibling modules.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::markers::MarkerSystem;
use crate::occlusion::{Scenario, Style};

fn default_one() -> usize {
    1
}
fn default_true() -> bool {
    true
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DefocusFile {
    pub f_number: f64,
    pub focus_distance_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraFile {
    pub width: u32,
    pub height: u32,
    pub focal_length_mm: Option<f64>,
    pub pixel_pitch_um: Option<f64>,
    pub fx: Option<f64>,
    pub fy: Option<f64>,
    pub cx: Option<f64>,
    pub cy: Option<f64>,
    #[serde(default)]
    pub distortion: [f64; 5],
    pub defocus: Option<DefocusFile>,
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct PrintFile {
    pub ink: Option<f64>,
    pub paper: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BackgroundFile {
    pub kind: String,
    pub level: Option<f64>,
    pub from: Option<f64>,
    pub to: Option<f64>,
    pub angle: Option<f64>,
    pub base: Option<f64>,
    pub count: Option<usize>,
    pub min_size_px: Option<f64>,
    pub max_size_px: Option<f64>,
    pub path: Option<PathBuf>,
    pub distance_m: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ShadowFile {
    pub polygon: Vec<[f64; 2]>,
    pub darkness: f64,
    #[serde(default)]
    pub softness_px: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LightingFile {
    pub gain: Option<f64>,
    pub gradient: Option<[f64; 2]>,
    pub vignetting: Option<f64>,
    #[serde(default)]
    pub shadow: Vec<ShadowFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SensorFile {
    #[serde(default)]
    pub read_noise_dn: f64,
    #[serde(default)]
    pub full_well_e: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MotionBlurFile {
    pub length_px: f64,
    #[serde(default)]
    pub angle: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EffectsFile {
    pub motion_blur: Option<MotionBlurFile>,
    pub jpeg_quality: Option<u8>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MarkerFile {
    pub system: MarkerSystem,
    pub family: Option<String>,
    pub id: u64,
    pub size_m: f64,
    pub translation: [f64; 3],
    #[serde(default)]
    pub rotation: [f64; 3],
    #[serde(default = "default_true")]
    pub occlude: bool,
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
pub(super) struct SweepFile {
    pub param: SweepParam,
    pub from: f64,
    pub to: f64,
    pub step: Option<f64>,
    pub count: Option<usize>,
    pub unit: Option<String>,
    pub markers: Option<Vec<usize>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GenerateFile {
    pub scenario: Scenario,
    pub coverage: f64,
    pub count: usize,
    pub style: Option<Style>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct OcclusionFile {
    #[serde(default)]
    pub patterns: Vec<PathBuf>,
    #[serde(default)]
    pub generate: Vec<GenerateFile>,
    pub style: Option<Style>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SpecFile {
    pub name: Option<String>,
    pub description: Option<String>,
    #[serde(default)]
    pub seed: u64,
    #[serde(default = "default_one")]
    pub images: usize,
    pub camera: CameraFile,
    pub print: Option<PrintFile>,
    pub background: Option<BackgroundFile>,
    pub lighting: Option<LightingFile>,
    pub sensor: Option<SensorFile>,
    pub effects: Option<EffectsFile>,
    #[serde(default)]
    pub markers: Vec<MarkerFile>,
    pub sweep: Option<SweepFile>,
    pub sample: Option<SampleFile>,
    pub occlusion: Option<OcclusionFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SampleMarkerFile {
    pub system: MarkerSystem,
    pub family: Option<String>,
}

/// `[sample]`: factors are kept as TOML values and read by
/// [`super::sample`] (a number, a `[lo, hi]` range, or `{ values = [...] }`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SampleFile {
    pub count: usize,
    #[serde(default = "default_one")]
    pub repeats: usize,
    pub square_m: f64,
    pub markers: Vec<SampleMarkerFile>,
    pub markers_per_frame: Option<toml::Value>,
    pub side_px: Option<toml::Value>,
    pub distance_m: Option<toml::Value>,
    pub tilt_x_deg: Option<toml::Value>,
    pub tilt_y_deg: Option<toml::Value>,
    pub roll_deg: Option<toml::Value>,
    pub pos_x: Option<toml::Value>,
    pub pos_y: Option<toml::Value>,
    pub id: Option<toml::Value>,
    pub contrast: Option<toml::Value>,
    pub background: Option<toml::Value>,
    pub clutter_density: Option<toml::Value>,
    pub background_images: Option<Vec<PathBuf>>,
    pub background_dir: Option<PathBuf>,
    pub gradient: Option<toml::Value>,
    pub shadow_darkness: Option<toml::Value>,
    pub glare_peak: Option<toml::Value>,
    pub defocus_px: Option<toml::Value>,
    pub motion_blur_px: Option<toml::Value>,
    pub read_noise_dn: Option<toml::Value>,
    pub full_well_e: Option<toml::Value>,
    pub jpeg_quality: Option<toml::Value>,
    pub distortion_k1: Option<toml::Value>,
    pub occluder_kind: Option<toml::Value>,
    pub occluder_files: Option<Vec<PathBuf>>,
    pub occluder_coverage: Option<toml::Value>,
    pub occluder_fill: Option<toml::Value>,
    pub occluder_style: Option<toml::Value>,
}

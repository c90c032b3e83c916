//! Dataset specs: a TOML file describing a camera, markers, a sweep of
//! poses and occlusions; validated into a [`DatasetSpec`] that yields one
//! [`Scene`](crate::scene::Scene) per image. The file format is documented
//! in `datasets/README.md`.
//!
//! - [`schema`]: the file as written (serde structs; the parser rejects
//!   unknown keys and wrong types with its own positions);
//! - one module per section for the value checks: [`camera`], the shared
//!   look of every image ([`rendering`]: print, background, lighting,
//!   sensor, effects), [`markers`], [`sweep`], [`occlusion`], and
//!   [`sample`] for sampled scenes;
//! - [`expand`]: images from the validated spec; [`draw`]: the scenes of
//!   a sampled spec.
//!
//! Errors name the spec file, line and column: value errors point at the
//! key that holds the value, found through the parser's spans
//! ([`crate::toml_input::KeyLocator`]).

use std::path::{Path, PathBuf};

use std::sync::Arc;

use crate::error::{Result, SynthError};
use crate::halton::ScrambledHalton;
use crate::scene::Rendering;
use crate::toml_input::{steps, toml_error, KeyLocator};

mod camera;
mod draw;
mod expand;
mod markers;
mod occlusion;
mod rendering;
mod sample;
mod schema;
mod sweep;

pub use draw::SampledScene;
pub use expand::Frame;
pub use markers::MarkerEntry;
pub use occlusion::{GenerateRequest, OcclusionSet};
pub use sample::{Draw, DrawValue, Sample};
pub use schema::SweepParam;
pub use sweep::Sweep;

/// Most images one spec may describe.
const MAX_IMAGES: usize = 10_000_000;
/// Most repeats (`images`) per sweep value and occlusion variant.
const MAX_REPEAT: usize = 1_000_000;

/// Settings from outside the spec file.
#[derive(Debug, Clone, Default)]
pub struct LoadOptions {
    /// Replaces `sample.background_dir` (photographs exported outside the
    /// repository, e.g. by `eval/peers/export_photos.py`); an error when
    /// the spec has no such key.
    pub photos_dir: Option<PathBuf>,
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
    /// Camera, print, background, lighting, sensor and effects.
    pub rendering: Rendering,
    /// Markers.
    pub markers: Vec<MarkerEntry>,
    /// Sweep, if any.
    pub sweep: Option<Sweep>,
    /// Occlusions (empty when none).
    pub occlusion: OcclusionSet,
    /// Sampled scenes, instead of a sweep.
    pub sample: Option<Sample>,
    /// The low-discrepancy points of `sample`, with the seed that
    /// scrambled them.
    halton: Option<(u64, Arc<ScrambledHalton>)>,
}

impl DatasetSpec {
    /// Replaces the seed (and re-scrambles the sampled scenes' sequence).
    pub fn set_seed(&mut self, seed: u64) {
        self.seed = seed;
        if self.sample.is_some() {
            self.halton = Some((seed, Arc::new(ScrambledHalton::new(draw::DIMS, seed))));
        }
    }

    /// Reads and validates a spec file.
    pub fn load(path: &Path) -> Result<Self> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// Reads and validates a spec file, with `options` from the command
    /// line.
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| SynthError::io(path, e))?;
        Self::from_toml_with(&text, path, options)
    }

    /// Validates a spec given as text; `path` names it in errors and
    /// relative paths inside it are relative to its directory.
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        Self::from_toml_with(text, path, &LoadOptions::default())
    }

    /// [`DatasetSpec::from_toml`] with `options` from the command line.
    pub fn from_toml_with(text: &str, path: &Path, options: &LoadOptions) -> Result<Self> {
        let file: schema::SpecFile =
            toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let loc = KeyLocator::new(path, text);
        let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();

        let camera = camera::camera(&loc, &file.camera)?;
        let rendering = rendering::rendering(&loc, &file, camera, &base_dir)?;
        let markers = markers::markers(&loc, &file.markers)?;
        let sweep = file
            .sweep
            .as_ref()
            .map(|s| sweep::sweep(&loc, s, markers.len()))
            .transpose()?;
        let occlusion = match &file.occlusion {
            None => OcclusionSet::default(),
            Some(o) => occlusion::occlusion_set(&loc, o, &base_dir)?,
        };
        let sample = match &file.sample {
            None => None,
            Some(sf) => {
                for (key, given) in [
                    ("sweep", file.sweep.is_some()),
                    ("occlusion", file.occlusion.is_some()),
                    ("markers", !file.markers.is_empty()),
                    ("images", file.images != 1),
                ] {
                    if given {
                        return Err(loc.err(
                            steps![key],
                            format!("{key} does not go with [sample] (a sampled spec draws its markers, poses and occluders; use sample.markers, sample.repeats and the occluder factors)"),
                        ));
                    }
                }
                Some(sample::sample(
                    &loc,
                    sf,
                    &rendering,
                    &base_dir,
                    options.photos_dir.as_deref(),
                )?)
            }
        };
        let halton = sample.as_ref().map(|_| {
            (
                file.seed,
                Arc::new(ScrambledHalton::new(draw::DIMS, file.seed)),
            )
        });
        if file.images == 0 || file.images > MAX_REPEAT {
            return Err(loc.err(
                steps!["images"],
                format!("images = {} is outside 1..={MAX_REPEAT}", file.images),
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
            rendering,
            markers,
            sweep,
            occlusion,
            sample,
            halton,
        };
        let total = spec.image_count();
        if total == 0 || total > MAX_IMAGES {
            return Err(loc.err(
                &[],
                format!("the spec describes {total} images; 1..={MAX_IMAGES} are allowed"),
            ));
        }
        spec.check_poses(&loc)?;
        if let Some(s) = &spec.sample {
            spec.check_sample_fit(s).map_err(|m| {
                let key = match s.size {
                    sample::Size::SidePx(_) => "side_px",
                    sample::Size::DistanceM(_) => "distance_m",
                };
                loc.err(steps!["sample", key], format!("sample.{key}: {m}"))
            })?;
        }
        Ok(spec)
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
        let r = &self.rendering;
        let mut json = serde_json::json!({
            "name": self.name,
            "description": self.description,
            "seed": self.seed,
            "images_per_variant": self.repeat,
            "camera": r.camera,
            "print": r.print,
            "background": r.background,
            "lighting": r.lighting,
            "sensor": r.sensor,
            "effects": r.effects,
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
        });
        // Only sampled specs have the key, so older datasets keep their bytes.
        if let (Some(s), Some(obj)) = (&self.sample, json.as_object_mut()) {
            obj.insert("sample".into(), serde_json::to_value(s).unwrap_or_default());
        }
        json
    }
}

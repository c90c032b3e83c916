//! From a validated spec to images: how many, what each is made of, and
//! the scene of each.

use std::sync::Arc;

use serde::Serialize;

use crate::error::Result;
use crate::occlusion::{self, Occlusion};
use crate::pose::{axis_rotation, Pose};
use crate::rng::{image_rng, Stream};
use crate::scene::{PlacedMarker, Scene};
use crate::toml_input::{steps, KeyLocator};

use super::schema::SweepParam;
use super::DatasetSpec;

/// How far generated occluders reach from the marker-square centre, in
/// marker units (they overhang the square by at most 0.25).
const GENERATED_OCCLUDER_REACH: f64 = 0.75;
/// Nearest depth a printed point may have, metres.
const MIN_DEPTH_M: f64 = 0.01;

/// What one image of a swept dataset is made of.
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

impl DatasetSpec {
    /// Number of images.
    #[must_use]
    pub fn image_count(&self) -> usize {
        if let Some(s) = &self.sample {
            return s.count * s.repeats;
        }
        let sweep = self.sweep.as_ref().map_or(1, |s| s.values.len());
        let occ = self.occlusion.len().max(1);
        sweep * occ * self.repeat
    }

    /// The images a thinned run renders (`every` = 10 in quick mode): every
    /// `every`-th image of a sweep; of a sampled spec, the first
    /// `count / every` scenes (rounded up) with all their renders.
    ///
    /// A prefix, not every `every`-th scene: a prefix of a Halton sequence
    /// is itself spread evenly over every factor, while every 10th point
    /// is not (its index is even and a multiple of 5, so the factors drawn
    /// in bases 2 and 5 would keep one half and one fifth of their range).
    /// And all renders of a scene, since a jitter group cut down to one
    /// render measures no jitter.
    #[must_use]
    pub fn thinned_indices(&self, every: usize) -> Vec<usize> {
        let every = every.max(1);
        match &self.sample {
            Some(s) => (0..s.count.div_ceil(every) * s.repeats).collect(),
            None => (0..self.image_count()).step_by(every).collect(),
        }
    }

    /// What image `index` is made of.
    #[must_use]
    pub fn frame(&self, index: usize) -> Frame {
        if let Some(s) = &self.sample {
            return Frame {
                index,
                value: None,
                occlusion: None,
                repeat: index % s.repeats,
            };
        }
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
        if let Some(sampled) = self.sampled_scene(index) {
            return sampled.map(|s| s.scene);
        }
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
            rendering: self.rendering.clone(),
            markers,
            seed: self.seed,
            index: index as u64,
            noise_index: index as u64,
        })
    }

    /// Every distinct pose of every marker must be in front of the camera
    /// and inside the lens model's valid field.
    pub(super) fn check_poses(&self, loc: &KeyLocator) -> Result<()> {
        let values: Vec<Option<f64>> = match &self.sweep {
            None => vec![None],
            Some(s) => s.values.iter().map(|&v| Some(v)).collect(),
        };
        let mut occ_reach = if self.occlusion.generate.is_empty() {
            0.0
        } else {
            GENERATED_OCCLUDER_REACH
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
                    if q.z < MIN_DEPTH_M {
                        return Err(loc.err(
                            steps!["markers", i, "translation"],
                            format!("markers[{i}] is behind the camera{at}: part of it (or of its occluders) is at depth {:.3} m (at least {MIN_DEPTH_M} m in front is needed)", q.z),
                        ));
                    }
                    if self.rendering.camera.project(&q).is_none() {
                        return Err(loc.err(
                            steps!["markers", i, "translation"],
                            format!("markers[{i}]{at} (or its occluders) reaches outside the field where the distortion model is valid"),
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}

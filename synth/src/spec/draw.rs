//! Drawing one sampled scene: every factor of `[sample]` from its own
//! coordinate of the scrambled Halton point of the scene, markers placed
//! in the frame without overlap, and every draw recorded.
//!
//! The coordinates are allocated once for all specs ([`IMAGE_DIMS`] for
//! the image, then [`MARKER_DIMS`] per marker slot), so two specs with the
//! same seed and ranges draw the same scenes whatever their marker system:
//! that is how the four systems see the same poses, occluders and effects.
//! Choices that are not factors (placement retries, the shape of a shadow
//! or an occluder) come from the scene's seeded random streams, which do
//! not depend on the system either.

use std::f64::consts::PI;
use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use rand::{RngExt, SeedableRng};

use crate::background::{Background, BackgroundKind};
use crate::camera::Camera;
use crate::effects::{Glare, MotionBlur, Shadow};
use crate::error::{Result, SynthError};
use crate::halton::ScrambledHalton;
use crate::markers::MarkerModel;
use crate::occlusion::{self, Appearance, Scenario, Style, Texture};
use crate::pose::{axis_rotation, Pose};
use crate::rng::{derive_seed, image_rng, Stream, SynthRng};
use crate::scene::{PlacedMarker, Scene};

use super::sample::{
    pick, BackgroundChoice, Draw, DrawValue, IdChoice, OccluderKind, OccluderStyle, Sample, Size,
    MAX_MARKERS_PER_FRAME,
};
use super::DatasetSpec;

/// Halton coordinates of the image-level factors.
pub const IMAGE_DIMS: usize = 20;
/// Halton coordinates of each marker slot.
pub const MARKER_DIMS: usize = 12;
/// Marker slots allocated first; the slots past them come after
/// [`EXTRA_DIMS`] ([`slot_base`]).
const FIRST_SLOTS: usize = 8;
/// Coordinates after the first marker slots (added later: appending keeps
/// every earlier coordinate, and so every earlier draw, as it was).
const EXTRA_DIMS: usize = 1;
/// All coordinates.
pub const DIMS: usize = IMAGE_DIMS + MAX_MARKERS_PER_FRAME * MARKER_DIMS + EXTRA_DIMS;

/// First coordinate of marker slot `slot`: the first [`FIRST_SLOTS`] lie
/// after the image's, the later ones (added with the dense sets) after
/// every coordinate allocated before them, so a spec of up to
/// [`FIRST_SLOTS`] markers draws what it drew before they existed.
fn slot_base(slot: usize) -> usize {
    if slot < FIRST_SLOTS {
        IMAGE_DIMS + slot * MARKER_DIMS
    } else {
        IMAGE_DIMS + FIRST_SLOTS * MARKER_DIMS + EXTRA_DIMS + (slot - FIRST_SLOTS) * MARKER_DIMS
    }
}

// Image-level coordinates.
const D_MARKERS: usize = 0;
const D_CONTRAST: usize = 1;
const D_BACKGROUND: usize = 2;
const D_CLUTTER: usize = 3;
const D_BG_IMAGE: usize = 4;
const D_GRADIENT: usize = 5;
const D_GRADIENT_ANGLE: usize = 6;
const D_SHADOW: usize = 7;
const D_SHADOW_OFFSET: usize = 8;
const D_SHADOW_ANGLE: usize = 9;
const D_GLARE: usize = 10;
const D_GLARE_X: usize = 11;
const D_GLARE_Y: usize = 12;
const D_DEFOCUS: usize = 13;
const D_MOTION: usize = 14;
const D_MOTION_ANGLE: usize = 15;
const D_READ_NOISE: usize = 16;
const D_FULL_WELL: usize = 17;
const D_JPEG: usize = 18;
const D_K1: usize = 19;
/// Which marker of the frame a glare lies on.
const D_GLARE_MARKER: usize = IMAGE_DIMS + FIRST_SLOTS * MARKER_DIMS;

// Marker-slot coordinates (offsets within a slot).
const M_SIZE: usize = 0;
const M_TILT_X: usize = 1;
const M_TILT_Y: usize = 2;
const M_ROLL: usize = 3;
const M_POS_X: usize = 4;
const M_POS_Y: usize = 5;
const M_ID: usize = 6;
const M_TYPE: usize = 7;
const M_OCC_KIND: usize = 8;
const M_OCC_COVERAGE: usize = 9;
const M_OCC_FILL: usize = 10;
const M_OCC_STYLE: usize = 11;

/// Half the side of the footprint kept free around each marker, marker
/// units: the printed CopperTag (the largest printed image of the four
/// systems), which is also the box occluders are clipped to
/// ([`crate::floor_occluders::OCCLUDER_BOX`]), so the layout is the same
/// for every system.
const FOOTPRINT_HALF: f64 = 1.0;
/// Pixels kept between a footprint and the image border.
const BORDER_MARGIN_PX: f64 = 2.0;
/// Pixels kept between the footprints of two markers.
const GAP_PX: f64 = 4.0;
/// Placement attempts of an extra marker before it is left out.
const PLACEMENT_ATTEMPTS: usize = 40;
/// Steps pulling the first marker towards the centre when perspective
/// pushes its footprint out of the frame.
const CENTRE_STEPS: usize = 12;
/// Nearest depth a footprint point may have, metres.
const MIN_DEPTH_M: f64 = 0.01;
/// Default level of a flat background and range of sampled levels
/// (mid greys: the print's own paper and ink must stay distinguishable).
const BACKGROUND_LEVELS: (f64, f64) = (0.2, 0.8);
/// Shadow penumbra range, pixels.
const SHADOW_SOFTNESS_PX: (f64, f64) = (1.0, 15.0);
/// Largest zoom of a background photograph beyond the smallest scale that
/// fills the frame at any rotation.
const PHOTO_ZOOM_MAX: f64 = 3.0;
/// Glare size relative to the glared marker's footprint radius.
const GLARE_SIGMA_REL: (f64, f64) = (0.1, 0.4);

/// A sampled scene: its markers, settings and draws.
#[derive(Debug, Clone)]
pub struct SampledScene {
    /// The scene.
    pub scene: Scene,
    /// Every draw, image-level first, then by marker.
    pub draws: Vec<Draw>,
}

struct Drawer<'a> {
    halton: &'a ScrambledHalton,
    point: u64,
    draws: Vec<Draw>,
}

impl Drawer<'_> {
    fn u(&self, d: usize) -> f64 {
        self.halton.value(self.point, d)
    }

    fn num(&mut self, marker: Option<usize>, factor: &'static str, v: f64) {
        self.draws.push(Draw {
            marker,
            factor,
            value: DrawValue::Number(v),
        });
    }

    fn text(&mut self, marker: Option<usize>, factor: &'static str, v: String) {
        self.draws.push(Draw {
            marker,
            factor,
            value: DrawValue::Text(v),
        });
    }
}

/// Where a marker lands: pose and footprint in pixels.
struct Placement {
    pose: Pose,
    centre_px: [f64; 2],
    radius_px: f64,
}

/// The footprint outline, 8 points a side, in marker units.
fn outline() -> impl Iterator<Item = [f64; 2]> {
    let e = FOOTPRINT_HALF;
    (0..32).map(move |k| {
        let t = f64::from(k % 8) / 8.0;
        match k / 8 {
            0 => [-e + 2.0 * e * t, -e],
            1 => [e, -e + 2.0 * e * t],
            2 => [e - 2.0 * e * t, e],
            _ => [-e, e - 2.0 * e * t],
        }
    })
}

/// The pose with rotation `rot` whose centre is seen at pixel `px` at
/// depth `z`, if its whole footprint is in front and inside the frame.
fn place(
    cam: &Camera,
    rot: &Rotation3<f64>,
    unit_m: f64,
    z: f64,
    px: [f64; 2],
) -> Option<Placement> {
    let t = cam.ray(px) * z;
    let pose = Pose {
        rotation: *rot,
        translation: t,
    };
    let centre = cam.project(&t)?;
    let (w, h) = (f64::from(cam.width), f64::from(cam.height));
    let mut radius: f64 = 0.0;
    for p in outline() {
        let q = pose.apply(&Vector3::new(p[0] * unit_m, p[1] * unit_m, 0.0));
        if q.z < MIN_DEPTH_M {
            return None;
        }
        let s = cam.project(&q)?;
        let m = BORDER_MARGIN_PX;
        if s[0] < m - 0.5 || s[1] < m - 0.5 || s[0] > w - 0.5 - m || s[1] > h - 0.5 - m {
            return None;
        }
        radius = radius.max((s[0] - centre[0]).hypot(s[1] - centre[1]));
    }
    Some(Placement {
        pose,
        centre_px: centre,
        radius_px: radius,
    })
}

/// The range of centre pixels (x, y) inside which the footprint fits, for
/// the footprint seen at the principal point; `None` when it does not fit
/// at all.
fn centre_range(
    cam: &Camera,
    rot: &Rotation3<f64>,
    unit_m: f64,
    z: f64,
) -> Option<[(f64, f64); 2]> {
    let c = [cam.cx, cam.cy];
    let t = cam.ray(c) * z;
    let pose = Pose {
        rotation: *rot,
        translation: t,
    };
    let (mut x0, mut y0, mut x1, mut y1) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for p in outline() {
        let q = pose.apply(&Vector3::new(p[0] * unit_m, p[1] * unit_m, 0.0));
        if q.z < MIN_DEPTH_M {
            return None;
        }
        let s = cam.project(&q)?;
        (x0, y0, x1, y1) = (
            x0.min(s[0] - c[0]),
            y0.min(s[1] - c[1]),
            x1.max(s[0] - c[0]),
            y1.max(s[1] - c[1]),
        );
    }
    let m = BORDER_MARGIN_PX;
    let (w, h) = (f64::from(cam.width), f64::from(cam.height));
    let xr = (m - 0.5 - x0, w - 0.5 - m - x1);
    let yr = (m - 0.5 - y0, h - 0.5 - m - y1);
    (xr.0 <= xr.1 && yr.0 <= yr.1).then_some([xr, yr])
}

/// The rotation of tilts and roll (degrees): about the marker's x, then
/// y, then z axis.
fn rotation(tx: f64, ty: f64, roll: f64) -> Rotation3<f64> {
    axis_rotation(0, tx.to_radians())
        * axis_rotation(1, ty.to_radians())
        * axis_rotation(2, roll.to_radians())
}

/// A polygon covering the part of a `w` x `h` image on one side of the
/// line through `p` at angle `a` (a big quadrilateral; drawing clips it).
fn half_plane(p: [f64; 2], a: f64, w: f64, h: f64) -> Vec<[f64; 2]> {
    let l = 2.0 * (w + h);
    let (d, n) = ([a.cos(), a.sin()], [-a.sin(), a.cos()]);
    vec![
        [p[0] - l * d[0], p[1] - l * d[1]],
        [p[0] + l * d[0], p[1] + l * d[1]],
        [p[0] + l * d[0] + l * n[0], p[1] + l * d[1] + l * n[1]],
        [p[0] - l * d[0] + l * n[0], p[1] - l * d[1] + l * n[1]],
    ]
}

impl DatasetSpec {
    /// The nearest marker at the steepest tilts must fit in the frame at
    /// its centre (`Err` says which).
    pub(super) fn check_sample_fit(&self, s: &Sample) -> std::result::Result<(), String> {
        if s.markers.is_empty() {
            return Ok(());
        }
        let ext = |f: &Option<super::sample::Factor>| {
            f.as_ref().map_or(vec![0.0], |f| {
                let (lo, hi) = f.bounds();
                vec![lo, hi, 0.0f64.clamp(lo, hi)]
            })
        };
        let z = match &s.size {
            Size::SidePx(f) => self.rendering.camera.fx * s.square_m / f.bounds().1,
            Size::DistanceM(f) => f.bounds().0,
        };
        for tx in ext(&s.tilt_x_deg) {
            for ty in ext(&s.tilt_y_deg) {
                for roll in [0.0, 45.0] {
                    let rot = rotation(tx, ty, roll);
                    if centre_range(&self.rendering.camera, &rot, s.square_m, z).is_none() {
                        return Err(format!(
                            "the nearest marker (depth {z:.3} m) tilted by {tx} and {ty} deg does not fit in the {}x{} frame with its footprint (twice the marker square)",
                            self.rendering.camera.width, self.rendering.camera.height
                        ));
                    }
                }
            }
        }
        Ok(())
    }

    /// The scene of sampled image `index`, with its draws; `None` for a
    /// spec without `[sample]`.
    pub fn sampled_scene(&self, index: usize) -> Option<Result<SampledScene>> {
        let sample = self.sample.as_ref()?;
        match &self.halton {
            Some((seed, h)) if *seed == self.seed => Some(self.draw_scene(sample, h, index)),
            // The seed was changed through the public field: scramble anew
            // (`set_seed` avoids doing it per image).
            _ => Some(self.draw_scene(sample, &ScrambledHalton::new(DIMS, self.seed), index)),
        }
    }

    fn draw_scene(
        &self,
        s: &Sample,
        halton: &ScrambledHalton,
        index: usize,
    ) -> Result<SampledScene> {
        let scene_no = index / s.repeats;
        let mut d = Drawer {
            halton,
            point: scene_no as u64,
            draws: Vec::new(),
        };
        let mut rng = image_rng(self.seed, scene_no as u64, Stream::Sample);
        let mut r = self.rendering.clone();
        let (w, h) = (f64::from(r.camera.width), f64::from(r.camera.height));

        if s.repeats > 1 {
            d.num(None, "jitter_group", scene_no as f64);
        }
        // Camera first: placement projects through it.
        if let Some(f) = &s.distortion_k1 {
            let k1 = f.at(d.u(D_K1));
            d.num(None, "distortion_k1", k1);
            let c = &r.camera;
            let mut cam = Camera::new(
                c.width,
                c.height,
                [c.fx, c.fy, c.cx, c.cy],
                [k1, 0.0, 0.0, 0.0, 0.0],
            )?
            .with_lens(c.focal_length_mm, c.pixel_pitch_um);
            cam.defocus = c.defocus;
            r.camera = cam;
        }
        if let Some(f) = &s.contrast {
            let c = f.at(d.u(D_CONTRAST));
            d.num(None, "contrast", c);
            r.print.ink = (r.print.paper - c).max(0.0);
        }
        if let Some(kinds) = &s.background {
            let kind = kinds[pick(d.u(D_BACKGROUND), kinds.len())];
            d.text(None, "background", kind.name().to_string());
            let (lo, hi) = BACKGROUND_LEVELS;
            r.background = Background {
                distance_m: r.background.distance_m,
                kind: match kind {
                    BackgroundChoice::Flat => BackgroundKind::Flat {
                        level: rng.random_range(lo..hi),
                    },
                    BackgroundChoice::Gradient => BackgroundKind::Gradient {
                        from: rng.random_range(lo..hi),
                        to: rng.random_range(lo..hi),
                        angle: rng.random_range(0.0..2.0 * PI),
                    },
                    BackgroundChoice::Clutter => {
                        let density = s
                            .clutter_density
                            .as_ref()
                            .map_or(200.0, |f| f.at(d.u(D_CLUTTER)));
                        d.num(None, "clutter_density", density);
                        BackgroundKind::Clutter {
                            base: rng.random_range(lo..hi),
                            count: (density * w * h / 1e6).round() as usize,
                            min_size_px: 12.0,
                            max_size_px: 160.0,
                        }
                    }
                    BackgroundChoice::Image => {
                        let k = pick(d.u(D_BG_IMAGE), s.background_images.len());
                        let src = &s.background_sources[k];
                        let (sw, sh) = (f64::from(src.width()), f64::from(src.height()));
                        // Any rotation of the frame must stay inside the
                        // photograph: its half-diagonal fits the inscribed
                        // circle at the smallest scale.
                        let half_diag = w.hypot(h) / 2.0;
                        let min_scale = half_diag / (sw.min(sh) / 2.0 - 1.0);
                        let scale = min_scale * rng.random_range(1.0..PHOTO_ZOOM_MAX);
                        let angle = rng.random_range(0.0..2.0 * PI);
                        let reach = half_diag / scale;
                        let centre = [
                            rng.random_range(reach..(sw - 1.0 - reach).max(reach + 1e-9)),
                            rng.random_range(reach..(sh - 1.0 - reach).max(reach + 1e-9)),
                        ];
                        d.text(
                            None,
                            "background_image",
                            s.background_images[k].display().to_string(),
                        );
                        d.num(None, "background_scale", scale);
                        d.num(None, "background_angle_deg", angle.to_degrees());
                        BackgroundKind::Photo {
                            path: s.background_images[k].clone(),
                            angle,
                            scale,
                            centre,
                            source: src.clone(),
                        }
                    }
                },
            };
        }
        if let Some(f) = &s.gradient {
            let g = f.at(d.u(D_GRADIENT));
            let a = 2.0 * PI * d.u(D_GRADIENT_ANGLE);
            d.num(None, "gradient", g);
            r.lighting.gradient = [g * a.cos(), g * a.sin()];
        }
        if let Some(f) = &s.shadow_darkness {
            let dark = f.at(d.u(D_SHADOW));
            d.num(None, "shadow_darkness", dark);
            if dark > 0.0 {
                let off = d.u(D_SHADOW_OFFSET);
                let a = 2.0 * PI * d.u(D_SHADOW_ANGLE);
                let p = [off * (w - 1.0), off * (h - 1.0)];
                // The polygon is the side of the line through p at angle a
                // towards its normal (-sin a, cos a).
                let n = [-a.sin(), a.cos()];
                r.lighting.shadows.push(Shadow {
                    polygon: half_plane(p, a, w, h),
                    darkness: dark,
                    softness_px: rng.random_range(SHADOW_SOFTNESS_PX.0..SHADOW_SOFTNESS_PX.1),
                    half_plane: Some([n[0], n[1], n[0] * p[0] + n[1] * p[1]]),
                });
            }
        }
        let glare = s.glare_peak.as_ref().map(|f| f.at(d.u(D_GLARE)));
        if let Some(g) = glare {
            d.num(None, "glare_peak", g);
        }
        if let Some(f) = &s.defocus_px {
            let v = f.at(d.u(D_DEFOCUS));
            d.num(None, "defocus_px", v);
            r.effects.blur_sigma_px = (v > 0.0).then_some(v);
        }
        if let Some(f) = &s.motion_blur_px {
            let v = f.at(d.u(D_MOTION));
            d.num(None, "motion_blur_px", v);
            r.effects.motion_blur = (v > 0.0).then_some(MotionBlur {
                length_px: v,
                angle: PI * d.u(D_MOTION_ANGLE),
            });
        }
        if let Some(f) = &s.read_noise_dn {
            let v = f.at(d.u(D_READ_NOISE));
            d.num(None, "read_noise_dn", v);
            r.sensor.read_noise_dn = v;
        }
        if let Some(f) = &s.full_well_e {
            let v = f.at(d.u(D_FULL_WELL));
            d.num(None, "full_well_e", v);
            r.sensor.full_well_e = v;
        }
        if let Some(f) = &s.jpeg_quality {
            // 0 is the `off` value of a JPEG event: no JPEG step.
            let q = f.at_int(d.u(D_JPEG)).clamp(0, 100);
            d.num(None, "jpeg_quality", q as f64);
            r.effects.jpeg_quality = (q > 0).then_some(q as u8);
        }

        // Markers.
        let wanted = s.markers_per_frame.as_ref().map_or(1, |f| {
            f.at_int(d.u(D_MARKERS))
                .clamp(0, MAX_MARKERS_PER_FRAME as i64) as usize
        });
        let mut placed: Vec<(Placement, usize)> = Vec::new();
        for slot in 0..wanted {
            let base = slot_base(slot);
            let u = |k: usize| halton.value(scene_no as u64, base + k);
            let tx = s.tilt_x_deg.as_ref().map_or(0.0, |f| f.at(u(M_TILT_X)));
            let ty = s.tilt_y_deg.as_ref().map_or(0.0, |f| f.at(u(M_TILT_Y)));
            let roll = s.roll_deg.as_ref().map_or(0.0, |f| f.at(u(M_ROLL)));
            let rot = rotation(tx, ty, roll);
            let unit_m = s.square_m;
            let z = match &s.size {
                Size::SidePx(f) => r.camera.fx * s.square_m / f.at(u(M_SIZE)),
                Size::DistanceM(f) => f.at(u(M_SIZE)),
            };
            let Some([xr, yr]) = centre_range(&r.camera, &rot, unit_m, z) else {
                if slot == 0 {
                    return Err(SynthError::Scene(format!(
                        "image {index}: the marker (depth {z:.3} m, tilts {tx:.1}, {ty:.1} deg) does not fit in the frame"
                    )));
                }
                continue;
            };
            let (mut px, mut py) = (
                s.pos_x.as_ref().map_or(0.5, |f| f.at(u(M_POS_X))),
                s.pos_y.as_ref().map_or(0.5, |f| f.at(u(M_POS_Y))),
            );
            let mut found = None;
            let attempts = if slot == 0 {
                CENTRE_STEPS + 1
            } else {
                PLACEMENT_ATTEMPTS
            };
            for attempt in 0..attempts {
                if attempt > 0 {
                    if slot == 0 {
                        // Towards the centre, reaching it at the last step.
                        let k = 1.0 - attempt as f64 / CENTRE_STEPS as f64;
                        px = 0.5 + (px - 0.5) * k;
                        py = 0.5 + (py - 0.5) * k;
                    } else {
                        px = rng.random_range(0.0..1.0);
                        py = rng.random_range(0.0..1.0);
                    }
                }
                let pixel = [xr.0 + px * (xr.1 - xr.0), yr.0 + py * (yr.1 - yr.0)];
                let Some(p) = place(&r.camera, &rot, unit_m, z, pixel) else {
                    continue;
                };
                let clear = placed.iter().all(|(q, _)| {
                    let dist =
                        (p.centre_px[0] - q.centre_px[0]).hypot(p.centre_px[1] - q.centre_px[1]);
                    dist > p.radius_px + q.radius_px + GAP_PX
                });
                if clear {
                    found = Some(p);
                    break;
                }
            }
            let Some(p) = found else {
                if slot == 0 {
                    return Err(SynthError::Scene(format!(
                        "image {index}: the marker (depth {z:.3} m) does not fit in the frame"
                    )));
                }
                continue;
            };
            let mi = placed.len();
            let side = r.camera.fx * s.square_m / z;
            d.num(Some(mi), "side_px", side);
            d.num(Some(mi), "distance_m", z);
            if s.tilt_x_deg.is_some() {
                d.num(Some(mi), "tilt_x_deg", tx);
            }
            if s.tilt_y_deg.is_some() {
                d.num(Some(mi), "tilt_y_deg", ty);
            }
            if s.roll_deg.is_some() {
                d.num(Some(mi), "roll_deg", roll);
            }
            d.num(Some(mi), "pos_x", p.centre_px[0] / (w - 1.0));
            d.num(Some(mi), "pos_y", p.centre_px[1] / (h - 1.0));
            placed.push((p, slot));
        }
        d.num(None, "markers_per_frame", placed.len() as f64);

        let mut markers = Vec::with_capacity(placed.len());
        for (mi, (p, slot)) in placed.iter().enumerate() {
            let base = slot_base(*slot);
            let u = |k: usize| halton.value(scene_no as u64, base + k);
            let t = &s.markers[pick(u(M_TYPE), s.markers.len())];
            // Which type was drawn, where there was a choice (the dense
            // sets mix CopperTag's families): a factor of its own, so the
            // report splits by it. A spec of one type records nothing, as
            // before.
            if s.markers.len() > 1 {
                d.text(Some(mi), "family", t.family.clone());
            }
            let id = match &s.id {
                IdChoice::Any => t.ids.0 + pick(u(M_ID), (t.ids.1 - t.ids.0 + 1) as usize) as u64,
                IdChoice::List(ids) => ids[pick(u(M_ID), ids.len())],
            };
            let model = MarkerModel::new(t.system, Some(t.family.as_str()), id)?;
            let size_m = s.square_m * 2.0 * model.half_extent;
            let occlusion = match &s.occluder_kind {
                None => None,
                Some(kinds) => {
                    let uk = u(M_OCC_KIND);
                    let kind = match s.occluder_share {
                        None => kinds[pick(uk, kinds.len())],
                        Some(share) => super::sample::present(uk, share)
                            .map_or(OccluderKind::None, |v| kinds[pick(v, kinds.len())]),
                    };
                    d.text(Some(mi), "occluder_kind", s.kind_name(kind));
                    match kind {
                        OccluderKind::None => {
                            d.num(Some(mi), "occluder_coverage", 0.0);
                            None
                        }
                        OccluderKind::File(k) => {
                            let mut occ_rng = SynthRng::seed_from_u64(derive_seed(
                                self.seed,
                                &[scene_no as u64, Stream::Occlusion as u64, *slot as u64],
                            ));
                            let turns = occ_rng.random_range(0..4u32);
                            let occ = s.occluder_patterns[k].quarter_turns(turns);
                            d.num(Some(mi), "occluder_turn_deg", f64::from(90 * turns));
                            d.num(Some(mi), "occluder_coverage", occ.coverage());
                            Some(Arc::new(occ))
                        }
                        OccluderKind::Generated(scenario) => {
                            let cov = s
                                .occluder_coverage
                                .as_ref()
                                .map_or(0.1, |f| f.at(u(M_OCC_COVERAGE)))
                                .min(occlusion::max_coverage(scenario));
                            let style = s
                                .occluder_style
                                .as_ref()
                                .map(|st| st[pick(u(M_OCC_STYLE), st.len())]);
                            let mut occ_rng = SynthRng::seed_from_u64(derive_seed(
                                self.seed,
                                &[scene_no as u64, Stream::Occlusion as u64, *slot as u64],
                            ));
                            let ink = Appearance {
                                fill: r.print.ink,
                                texture: Texture::None,
                            };
                            let mut appearance = match style {
                                Some(OccluderStyle::Style(st)) => st.appearance(),
                                Some(OccluderStyle::Ink) => ink,
                                None if scenario == Scenario::FlushTape => ink,
                                None => Style::Solid.appearance(),
                            };
                            // "ink" means as dark as the print's ink:
                            // the drawn fill is for the other looks.
                            if let (Some(f), false) =
                                (&s.occluder_fill, style == Some(OccluderStyle::Ink))
                            {
                                appearance.fill = f.at(u(M_OCC_FILL));
                            }
                            if let Some(st) = style {
                                d.text(Some(mi), "occluder_style", st.name());
                            }
                            d.num(Some(mi), "occluder_fill", appearance.fill);
                            let name = format!("sample-{}-{scene_no}-{mi}", scenario.name());
                            let occ = if crate::floor_occluders::is_floor_kind(scenario) {
                                crate::floor_occluders::generate(
                                    scenario,
                                    cov,
                                    appearance,
                                    name,
                                    &mut occ_rng,
                                )?
                            } else {
                                let mut o = occlusion::generate(
                                    scenario,
                                    cov,
                                    Some(Style::Solid),
                                    name,
                                    &mut occ_rng,
                                )?;
                                for oc in &mut o.occluders {
                                    oc.appearance = appearance;
                                }
                                o
                            };
                            d.num(Some(mi), "occluder_coverage", occ.coverage());
                            Some(Arc::new(occ))
                        }
                    }
                }
            };
            markers.push(PlacedMarker {
                model: Arc::new(model),
                size_m,
                pose: p.pose,
                occlusion,
            });
        }
        // The glare lies on one marker of the frame, drawn from its own
        // coordinate and recorded as `glare_marker`. Not always the first
        // marker: that one is in every frame and is the one pulled towards
        // the centre when it does not fit, so glare would go with those
        // placements; drawn, every marker is equally likely to carry it and
        // glared and unglared markers of the same frames can be compared.
        // (Anywhere in the frame would miss the small markers nearly
        // always and measure nothing.)
        if let Some(peak) = glare.filter(|g| *g > 0.0) {
            if !placed.is_empty() {
                let k = pick(d.u(D_GLARE_MARKER), placed.len());
                d.num(None, "glare_marker", k as f64);
                let p = &placed[k].0;
                let (gx, gy) = (d.u(D_GLARE_X) - 0.5, d.u(D_GLARE_Y) - 0.5);
                let rel = rng.random_range(GLARE_SIGMA_REL.0..GLARE_SIGMA_REL.1);
                r.lighting.glares.push(Glare {
                    centre: [
                        p.centre_px[0] + gx * p.radius_px,
                        p.centre_px[1] + gy * p.radius_px,
                    ],
                    sigma_px: (rel * p.radius_px).max(1.0),
                    peak,
                });
            }
        }
        let mut draws = d.draws;
        // Image-level rows first, then by marker; by factor within each.
        draws.sort_by(|a, b| a.marker.cmp(&b.marker).then_with(|| a.factor.cmp(b.factor)));
        Ok(SampledScene {
            scene: Scene {
                rendering: r,
                markers,
                seed: self.seed,
                index: scene_no as u64,
                noise_index: index as u64,
            },
            draws,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first slots keep the coordinates they had before the later
    /// slots were added (so the committed wild sets draw the same scenes),
    /// and every slot's coordinates are its own: no two slots, the image's
    /// coordinates or the glare's share one, and all lie below [`DIMS`].
    #[test]
    fn every_slot_has_its_own_coordinates_and_the_first_ones_did_not_move() {
        for slot in 0..FIRST_SLOTS {
            assert_eq!(slot_base(slot), IMAGE_DIMS + slot * MARKER_DIMS);
        }
        let mut owner = vec![None; DIMS];
        for (d, o) in owner.iter_mut().enumerate().take(IMAGE_DIMS) {
            *o = Some(format!("image {d}"));
        }
        owner[D_GLARE_MARKER] = Some("glare".to_string());
        for slot in 0..MAX_MARKERS_PER_FRAME {
            for k in 0..MARKER_DIMS {
                let d = slot_base(slot) + k;
                assert!(d < DIMS, "slot {slot} coordinate {k} is {d}");
                assert_eq!(owner[d], None, "slot {slot} coordinate {k}");
                owner[d] = Some(format!("slot {slot}"));
            }
        }
        assert!(owner.iter().all(Option::is_some), "unused coordinates");
    }
}

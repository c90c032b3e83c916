//! One image: a camera looking at markers (with occluders) in front of a
//! background, under some lighting; rendering and ground truth.
//!
//! Rendering order: background; markers from the farthest to the nearest,
//! each with its occluders on top; illumination; defocus; motion blur;
//! sensor noise and 8-bit quantisation; optional JPEG round trip. Marker
//! shapes go through the camera vertex by vertex
//! ([`crate::raster::element_polygons`] with a [`MarkerView`]) and are
//! filled with exact pixel coverage ([`crate::coverage`]).

use std::sync::Arc;

use image::GrayImage;
use nalgebra::Vector3;
use serde::Serialize;

use coppertag::geometry::Paint;

use crate::background::Background;
use crate::camera::Camera;
use crate::coverage::{Canvas, Rasterizer};
use crate::cutout::{Cutout, DRAW_SUPERSAMPLE};
use crate::effects::{self, Effects, Lighting, Sensor};
use crate::error::{Result, SynthError};
use crate::markers::{fractal_levels, MarkerModel, MarkerSystem, CORNERS};
use crate::occlusion::{Occlusion, Scenario, UNIT_CORNERS};
use crate::pose::Pose;
use crate::raster::{element_polygons, map_polygon, TagToPixel};
use crate::rng::{derive_seed, image_rng, Stream};

/// Reflectances of the print.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Print {
    /// Ink (black parts), 0..1.
    pub ink: f64,
    /// Paper (white parts), 0..1.
    pub paper: f64,
}

impl Default for Print {
    fn default() -> Self {
        Self {
            ink: 0.04,
            paper: 0.92,
        }
    }
}

/// A marker placed in the scene.
#[derive(Debug, Clone)]
pub struct PlacedMarker {
    /// The marker's shapes.
    pub model: Arc<MarkerModel>,
    /// Side of the printed image in metres.
    pub size_m: f64,
    /// Marker frame to camera frame.
    pub pose: Pose,
    /// Occluders laid on it.
    pub occlusion: Option<Arc<Occlusion>>,
}

/// The settings every image of a dataset shares (unless a sampled spec
/// draws them per image): camera, print, background, lighting, sensor and
/// effects.
#[derive(Debug, Clone)]
pub struct Rendering {
    /// Camera.
    pub camera: Camera,
    /// Print reflectances.
    pub print: Print,
    /// Background.
    pub background: Background,
    /// Illumination.
    pub lighting: Lighting,
    /// Sensor.
    pub sensor: Sensor,
    /// Blur and compression.
    pub effects: Effects,
}

/// Everything needed to render one image.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Camera, print, background, lighting, sensor and effects.
    pub rendering: Rendering,
    /// Markers.
    pub markers: Vec<PlacedMarker>,
    /// Dataset seed.
    pub seed: u64,
    /// Scene number (with the seed, picks the random streams of the
    /// background, occluders and textures): the image index, except in
    /// sampled specs with `repeats`, where the repeats of one scene share
    /// it.
    pub index: u64,
    /// Picks the sensor-noise stream: the image index.
    pub noise_index: u64,
}

/// A marker seen through the camera: maps marker units to pixels.
#[derive(Debug, Clone)]
pub struct MarkerView<'a> {
    camera: &'a Camera,
    pose: Pose,
    unit: f64,
    scale: f64,
}

impl<'a> MarkerView<'a> {
    /// The view of a marker whose marker unit is `unit_m` metres, posed at
    /// `pose`, printed out to `half_extent` marker units.
    #[must_use]
    pub fn new(camera: &'a Camera, pose: Pose, unit_m: f64, half_extent: f64) -> Self {
        let mut v = Self {
            camera,
            pose,
            unit: unit_m,
            scale: 1.0,
        };
        // Largest local magnification over a grid on the printed square,
        // by finite differences, with a margin.
        let mut scale = 1e-3f64;
        let d = 1e-4;
        for i in 0..=4 {
            for j in 0..=4 {
                let p = [
                    half_extent * (f64::from(i) / 2.0 - 1.0),
                    half_extent * (f64::from(j) / 2.0 - 1.0),
                ];
                let (Some(a), Some(bx), Some(by)) = (
                    v.project(p),
                    v.project([p[0] + d, p[1]]),
                    v.project([p[0], p[1] + d]),
                ) else {
                    continue;
                };
                scale = scale
                    .max((bx[0] - a[0]).hypot(bx[1] - a[1]) / d)
                    .max((by[0] - a[0]).hypot(by[1] - a[1]) / d);
            }
        }
        v.scale = scale * 1.1;
        v
    }

    /// A marker-unit point in the camera frame (metres).
    #[must_use]
    pub fn to_camera(&self, [x, y]: [f64; 2]) -> Vector3<f64> {
        self.pose
            .apply(&Vector3::new(x * self.unit, y * self.unit, 0.0))
    }

    /// A marker-unit point in pixel-centre coordinates.
    #[must_use]
    pub fn project(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        self.camera.project(&self.to_camera(p))
    }

    /// The marker-unit point seen at a pixel-centre coordinate, and its
    /// depth along the optical axis; `None` when the ray misses the plane.
    #[must_use]
    pub fn unproject(&self, pixel: [f64; 2]) -> Option<([f64; 2], f64)> {
        let ray = self.camera.ray(pixel);
        let n = self.pose.normal();
        let den = n.dot(&ray);
        if den.abs() < 1e-12 {
            return None;
        }
        let s = n.dot(&self.pose.translation) / den;
        if s <= 0.0 {
            return None;
        }
        let p = ray * s;
        let m = self.pose.rotation.inverse() * (p - self.pose.translation);
        Some(([m.x / self.unit, m.y / self.unit], p.z))
    }
}

impl TagToPixel for MarkerView<'_> {
    fn map(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        self.project(p).map(|q| [q[0] + 0.5, q[1] + 0.5])
    }
    fn scale(&self) -> f64 {
        self.scale
    }
    fn preserves_lines(&self) -> bool {
        !self.camera.has_distortion()
    }
}

/// Ground truth of one marker in one image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerTruth {
    /// Index of the marker in the spec.
    pub index: usize,
    /// System name (`coppertag`, `apriltag3`, `aruco3`, `stag`, `fractal`).
    pub marker: &'static str,
    /// Family or dictionary.
    pub family: String,
    /// Id.
    pub id: u64,
    /// Side of the printed image, metres.
    pub size_m: f64,
    /// Side of the marker square, metres.
    pub square_m: f64,
    /// Marker-square corners TL, BL, BR, TR in pixel-centre coordinates.
    pub corners: [[f64; 2]; 4],
    /// Whether each corner is inside the image.
    pub corner_in_image: [bool; 4],
    /// Whether each corner is inside the image and under no occluder.
    pub corner_visible: [bool; 4],
    /// Rotation vector (marker to camera), radians.
    pub rvec: [f64; 3],
    /// Rotation as a quaternion `[w, x, y, z]`.
    pub quaternion: [f64; 4],
    /// Translation of the marker-square centre, metres.
    pub tvec: [f64; 3],
    /// Mean side of the marker square in the image, pixels.
    pub side_px: f64,
    /// Occlusion applied, if any.
    pub occlusion: Option<OcclusionTruth>,
    /// A fractal marker's inner levels (the outer one is the marker
    /// square): level id and corners TL, BL, BR, TR in pixel-centre
    /// coordinates. Empty for the other systems.
    pub levels: Vec<(u32, [[f64; 2]; 4])>,
}

/// Ground truth of an occlusion on one marker.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OcclusionTruth {
    /// Pattern name.
    pub name: String,
    /// Scenario label.
    pub scenario: Scenario,
    /// Fraction of the marker square hidden (union of the occluders).
    pub coverage: f64,
    /// Fraction each occluder hides on its own.
    pub occluder_fractions: Vec<f64>,
    /// Occluder outlines in pixel-centre coordinates (for overlays).
    pub polygons_px: Vec<Vec<[f64; 2]>>,
}

/// A rendered image and its ground truth.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The 8-bit grey image.
    pub image: GrayImage,
    /// One entry per marker, in spec order.
    pub markers: Vec<MarkerTruth>,
}

/// Paints a cutout (an image with alpha on the marker plane) on the pixels
/// its outline `poly` (tiny-skia coordinates) touches: each pixel is the
/// mean of [`DRAW_SUPERSAMPLE`]^2 sub-samples, each the cutout's bilinear
/// premultiplied grey and alpha at the marker-plane point seen there,
/// blended over the pixel ("over" compositing, Porter and Duff 1984).
fn paint_cutout(
    data: &mut [f32],
    w: usize,
    h: usize,
    raster: &mut Rasterizer,
    poly: &[[f64; 2]],
    view: &MarkerView,
    cut: &Cutout,
) {
    let n = DRAW_SUPERSAMPLE;
    let inv = 1.0 / (n * n) as f32;
    raster.coverage(
        &[poly.to_vec()],
        tiny_skia::FillRule::Winding,
        w,
        h,
        |x, y, _| {
            let (mut pm, mut a) = (0.0f32, 0.0f32);
            for j in 0..n {
                for i in 0..n {
                    let q = [
                        x as f64 + (i as f64 + 0.5) / n as f64 - 0.5,
                        y as f64 + (j as f64 + 0.5) / n as f64 - 0.5,
                    ];
                    if let Some((p, _)) = view.unproject(q) {
                        let (g, al) = cut.sample([p[0] + 0.5, p[1] + 0.5]);
                        pm += g;
                        a += al;
                    }
                }
            }
            let px = &mut data[y * w + x];
            *px = pm * inv + *px * (1.0 - a * inv);
        },
    );
}

/// Depth of a marker's centre, for painting order.
fn centre_depth(m: &PlacedMarker) -> f64 {
    m.pose.translation.z
}

impl Scene {
    /// Renders the image and its ground truth. `raster` is scratch memory.
    pub fn render(&self, raster: &mut Rasterizer) -> Result<Rendered> {
        let cam = &self.rendering.camera;
        let (w, h) = (cam.width as usize, cam.height as usize);
        let mut canvas = Canvas::new(w, h, 0.0);
        let mut bg_rng = image_rng(self.seed, self.index, Stream::Background);
        self.rendering
            .background
            .paint(&mut canvas, raster, &mut bg_rng);
        let mut depth = cam
            .defocus
            .map(|_| vec![self.rendering.background.distance_m as f32; w * h]);

        let mut order: Vec<usize> = (0..self.markers.len()).collect();
        order.sort_by(|&a, &b| {
            centre_depth(&self.markers[b]).total_cmp(&centre_depth(&self.markers[a]))
        });
        let mut truths: Vec<Option<MarkerTruth>> = vec![None; self.markers.len()];
        for &mi in &order {
            let m = &self.markers[mi];
            let unit = m.model.metres_per_unit(m.size_m);
            let view = MarkerView::new(cam, m.pose, unit, m.model.half_extent);
            let colour = |p: Paint| match p {
                Paint::Black => self.rendering.print.ink as f32,
                Paint::White => self.rendering.print.paper as f32,
            };
            for el in &m.model.elements {
                let (polys, rule) = element_polygons(el, &view).ok_or_else(|| {
                    SynthError::Scene(format!(
                        "image {}: marker {mi} cannot be projected (behind the camera or outside the lens model)",
                        self.index
                    ))
                })?;
                canvas.fill(raster, &polys, rule, colour(el.paint));
            }
            if let Some(depth) = depth.as_mut() {
                let e = m.model.half_extent;
                let outline = [[-e, -e], [-e, e], [e, e], [e, -e]];
                if let Some(poly) = map_polygon(&outline, &view) {
                    raster.coverage(&[poly], tiny_skia::FillRule::Winding, w, h, |x, y, c| {
                        if c >= 0.5 {
                            if let Some((_, z)) = view.unproject([x as f64, y as f64]) {
                                depth[y * w + x] = z as f32;
                            }
                        }
                    });
                }
            }
            let mut occ_truth = None;
            if let Some(occ) = &m.occlusion {
                let mut polygons_px = Vec::new();
                for (k, o) in occ.occluders.iter().enumerate() {
                    let local: Vec<[f64; 2]> =
                        o.polygon.iter().map(|p| [p[0] - 0.5, p[1] - 0.5]).collect();
                    let poly = map_polygon(&local, &view).ok_or_else(|| {
                        SynthError::Scene(format!(
                            "image {}: an occluder of marker {mi} cannot be projected",
                            self.index
                        ))
                    })?;
                    let tex_seed = derive_seed(
                        self.seed,
                        &[self.index, Stream::Texture as u64, mi as u64, k as u64],
                    );
                    let app = o.appearance;
                    let flat = matches!(app.texture, crate::occlusion::Texture::None);
                    let data = &mut canvas.data;
                    if let Some(cut) = &o.cutout {
                        paint_cutout(data, w, h, raster, &poly, &view, cut);
                        polygons_px.push(poly.iter().map(|p| [p[0] - 0.5, p[1] - 0.5]).collect());
                        continue;
                    }
                    raster.coverage(
                        std::slice::from_ref(&poly),
                        tiny_skia::FillRule::Winding,
                        w,
                        h,
                        |x, y, c| {
                            let v = if flat {
                                app.fill
                            } else {
                                view.unproject([x as f64, y as f64])
                                    .map_or(app.fill, |(p, _)| {
                                        app.value(tex_seed, [p[0] + 0.5, p[1] + 0.5])
                                    })
                            } as f32;
                            let px = &mut data[y * w + x];
                            *px += (v - *px) * c;
                        },
                    );
                    polygons_px.push(poly.iter().map(|p| [p[0] - 0.5, p[1] - 0.5]).collect());
                }
                occ_truth = Some(OcclusionTruth {
                    name: occ.name.clone(),
                    scenario: occ.scenario,
                    coverage: occ.coverage(),
                    occluder_fractions: occ.occluder_fractions(),
                    polygons_px,
                });
            }
            truths[mi] = Some(self.truth(mi, &view, occ_truth)?);
        }

        self.rendering.lighting.apply(&mut canvas, raster);
        if let Some(depth) = &depth {
            let sigma: Vec<f32> = depth
                .iter()
                .map(|&z| cam.defocus_sigma_px(f64::from(z)) as f32)
                .collect();
            canvas = effects::variable_blur(&canvas, &sigma);
        }
        if let Some(sigma) = self.rendering.effects.blur_sigma_px {
            canvas = effects::gaussian_blur(&canvas, sigma);
        }
        if let Some(mb) = self.rendering.effects.motion_blur {
            canvas = effects::motion_blur(&canvas, mb);
        }
        let mut noise_rng = image_rng(self.seed, self.noise_index, Stream::Noise);
        let mut image = effects::quantise(&canvas, &self.rendering.sensor, &mut noise_rng);
        if let Some(q) = self.rendering.effects.jpeg_quality {
            image = effects::jpeg_round_trip(&image, q)?;
        }
        Ok(Rendered {
            image,
            markers: truths
                .into_iter()
                .map(|t| t.expect("every marker rendered"))
                .collect(),
        })
    }

    fn truth(
        &self,
        mi: usize,
        view: &MarkerView,
        occlusion: Option<OcclusionTruth>,
    ) -> Result<MarkerTruth> {
        let m = &self.markers[mi];
        let project = |p: [f64; 2]| {
            view.project(p).ok_or_else(|| {
                SynthError::Scene(format!(
                    "image {}: a corner of marker {mi} cannot be projected",
                    self.index
                ))
            })
        };
        let mut corners = [[0.0; 2]; 4];
        for (c, &p) in corners.iter_mut().zip(CORNERS.iter()) {
            *c = project(p)?;
        }
        let mut levels = Vec::new();
        if m.model.system == MarkerSystem::Fractal {
            for level in fractal_levels().iter().filter(|l| l.id != 0) {
                let mut c = [[0.0; 2]; 4];
                for (out, &p) in c.iter_mut().zip(level.corners.iter()) {
                    *out = project(p)?;
                }
                levels.push((level.id, c));
            }
        }
        let corner_in_image = corners.map(|c| self.rendering.camera.contains(c));
        let hidden = m
            .occlusion
            .as_ref()
            .map_or([false; 4], |o| UNIT_CORNERS.map(|c| o.hides(c)));
        let side_px = (0..4)
            .map(|i| {
                let (a, b) = (corners[i], corners[(i + 1) % 4]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .sum::<f64>()
            / 4.0;
        Ok(MarkerTruth {
            index: mi,
            marker: m.model.system.name(),
            family: m.model.family.clone(),
            id: m.model.id,
            size_m: m.size_m,
            square_m: m.model.metres_per_unit(m.size_m),
            corners,
            corner_in_image,
            corner_visible: std::array::from_fn(|i| corner_in_image[i] && !hidden[i]),
            rvec: m.pose.rvec(),
            quaternion: m.pose.quaternion(),
            tvec: m.pose.tvec(),
            side_px,
            occlusion,
            levels,
        })
    }
}

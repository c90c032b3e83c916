//! The look of every image: `[print]`, `[background]`, `[lighting]`,
//! `[sensor]` and `[effects]`, validated into the shared [`Rendering`]
//! settings (with the camera from [`super::camera`]).

use std::path::Path;
use std::sync::Arc;

use crate::background::{Background, BackgroundKind};
use crate::camera::Camera;
use crate::effects::{Effects, Lighting, MotionBlur, Sensor, Shadow};
use crate::error::Result;
use crate::scene::{Print, Rendering};
use crate::toml_input::{steps, KeyLocator};

use super::schema::{BackgroundFile, EffectsFile, LightingFile, PrintFile, SensorFile, SpecFile};

/// Largest clutter shape accepted, pixels.
const MAX_CLUTTER_SIZE_PX: f64 = 10_000.0;
/// Most clutter shapes accepted per image.
const MAX_CLUTTER_COUNT: usize = 100_000;
/// Longest motion blur accepted, pixels.
pub(super) const MAX_MOTION_BLUR_PX: f64 = 200.0;
/// Widest shadow edge accepted, pixels.
const MAX_SHADOW_SOFTNESS_PX: f64 = 100.0;

pub(super) fn check_unit(v: f64) -> bool {
    (0.0..=1.0).contains(&v)
}

/// The rendering settings of a spec, around its validated camera.
pub(super) fn rendering(
    loc: &KeyLocator,
    file: &SpecFile,
    camera: Camera,
    base_dir: &Path,
) -> Result<Rendering> {
    let print = match &file.print {
        None => Print::default(),
        Some(p) => print(loc, p)?,
    };
    let background = match &file.background {
        None => Background {
            kind: BackgroundKind::Flat { level: 0.5 },
            distance_m: 5.0,
        },
        Some(b) => background(loc, b, base_dir, &camera)?,
    };
    let lighting = match &file.lighting {
        None => Lighting::default(),
        Some(l) => lighting(loc, l)?,
    };
    let sensor = match &file.sensor {
        None => Sensor::default(),
        Some(s) => sensor(loc, s)?,
    };
    let effects = match &file.effects {
        None => Effects::default(),
        Some(e) => effects(loc, e)?,
    };
    Ok(Rendering {
        camera,
        print,
        background,
        lighting,
        sensor,
        effects,
    })
}

fn print(loc: &KeyLocator, p: &PrintFile) -> Result<Print> {
    let d = Print::default();
    let pr = Print {
        ink: p.ink.unwrap_or(d.ink),
        paper: p.paper.unwrap_or(d.paper),
    };
    for (key, v) in [("ink", pr.ink), ("paper", pr.paper)] {
        if !check_unit(v) {
            return Err(loc.err(
                steps!["print", key],
                format!("print.{key} = {v} is outside 0..=1"),
            ));
        }
    }
    Ok(pr)
}

fn lighting(loc: &KeyLocator, lf: &LightingFile) -> Result<Lighting> {
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
                half_plane: None,
            })
            .collect(),
        glares: Vec::new(),
    };
    if !(lighting.gain >= 0.0 && lighting.gain.is_finite()) {
        return Err(loc.err(
            steps!["lighting", "gain"],
            format!("lighting.gain = {} must be >= 0", lighting.gain),
        ));
    }
    if !lighting.gradient.iter().all(|g| g.is_finite()) {
        return Err(loc.err(
            steps!["lighting", "gradient"],
            "lighting.gradient must be finite".into(),
        ));
    }
    if !check_unit(lighting.vignetting) {
        return Err(loc.err(
            steps!["lighting", "vignetting"],
            format!(
                "lighting.vignetting = {} is outside 0..=1",
                lighting.vignetting
            ),
        ));
    }
    for (i, s) in lighting.shadows.iter().enumerate() {
        let ok = check_unit(s.darkness)
            && (0.0..=MAX_SHADOW_SOFTNESS_PX).contains(&s.softness_px)
            && s.polygon.len() >= 3
            && s.polygon.iter().flatten().all(|v| v.is_finite());
        if !ok {
            return Err(loc.err(
                steps!["lighting", "shadow", i],
                format!("lighting.shadow: needs a polygon of 3+ points, darkness in 0..=1 and softness_px in 0..={MAX_SHADOW_SOFTNESS_PX}"),
            ));
        }
    }
    Ok(lighting)
}

fn sensor(loc: &KeyLocator, sf: &SensorFile) -> Result<Sensor> {
    for (key, v) in [
        ("read_noise_dn", sf.read_noise_dn),
        ("full_well_e", sf.full_well_e),
    ] {
        if !(v >= 0.0 && v.is_finite()) {
            return Err(loc.err(
                steps!["sensor", key],
                format!("sensor.{key} = {v} must be >= 0"),
            ));
        }
    }
    Ok(Sensor {
        read_noise_dn: sf.read_noise_dn,
        full_well_e: sf.full_well_e,
    })
}

fn effects(loc: &KeyLocator, ef: &EffectsFile) -> Result<Effects> {
    if let Some(q) = ef.jpeg_quality {
        if !(1..=100).contains(&q) {
            return Err(loc.err(
                steps!["effects", "jpeg_quality"],
                format!("effects.jpeg_quality = {q} is outside 1..=100"),
            ));
        }
    }
    if let Some(m) = &ef.motion_blur {
        if !(m.length_px >= 0.0 && m.length_px <= MAX_MOTION_BLUR_PX && m.angle.is_finite()) {
            return Err(loc.err(
                steps!["effects", "motion_blur"],
                format!(
                    "effects.motion_blur.length_px = {} is outside 0..={MAX_MOTION_BLUR_PX}",
                    m.length_px
                ),
            ));
        }
    }
    Ok(Effects {
        motion_blur: ef.motion_blur.as_ref().map(|m| MotionBlur {
            length_px: m.length_px,
            angle: m.angle,
        }),
        jpeg_quality: ef.jpeg_quality,
        blur_sigma_px: None,
    })
}

fn background(
    loc: &KeyLocator,
    bf: &BackgroundFile,
    base_dir: &Path,
    camera: &Camera,
) -> Result<Background> {
    let level = |key: &str, v: Option<f64>, default: f64| -> Result<f64> {
        let v = v.unwrap_or(default);
        if check_unit(v) {
            Ok(v)
        } else {
            Err(loc.err(
                steps!["background", key],
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
                steps!["background", "kind"],
                format!("background.kind '{other}' is not one of flat, gradient, clutter, image"),
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
                steps!["background", key],
                format!("background.{key} does not apply to kind = \"{}\"", bf.kind),
            ));
        }
    }
    let distance_m = bf.distance_m.unwrap_or(5.0);
    if !(distance_m > 0.0 && distance_m.is_finite()) {
        return Err(loc.err(
            steps!["background", "distance_m"],
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
            if !(min > 0.0 && max >= min && max <= MAX_CLUTTER_SIZE_PX) {
                return Err(loc.err(
                    steps!["background", "min_size_px"],
                    format!("background: need 0 < min_size_px <= max_size_px <= {MAX_CLUTTER_SIZE_PX} (got {min}, {max})"),
                ));
            }
            let count = bf.count.unwrap_or(60);
            if count > MAX_CLUTTER_COUNT {
                return Err(loc.err(
                    steps!["background", "count"],
                    format!("background.count = {count} is more than {MAX_CLUTTER_COUNT}"),
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
                    steps!["background", "kind"],
                    "background.kind = \"image\" needs path".into(),
                ));
            };
            let full = base_dir.join(p);
            let pixels = load_grey_resized(&full, camera.width, camera.height).map_err(|e| {
                loc.err(
                    steps!["background", "path"],
                    format!("background.path {}: {e}", full.display()),
                )
            })?;
            BackgroundKind::Image {
                path: p.clone(),
                pixels,
            }
        }
    };
    Ok(Background { kind, distance_m })
}

/// An image file as grey levels 0..1, resized to `w` x `h` (triangle
/// filter).
fn load_grey_resized(
    path: &Path,
    w: u32,
    h: u32,
) -> std::result::Result<Arc<Vec<f32>>, image::ImageError> {
    let img = image::open(path)?.to_luma8();
    let img = image::imageops::resize(&img, w, h, image::imageops::FilterType::Triangle);
    Ok(Arc::new(
        img.pixels().map(|q| f32::from(q.0[0]) / 255.0).collect(),
    ))
}

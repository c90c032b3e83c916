//! `[camera]`: intrinsics from pixels (`fx`...) or from a lens and sensor
//! (`focal_length_mm`, `pixel_pitch_um`), distortion and defocus.

use crate::camera::{self, Camera, Defocus};
use crate::error::{Result, SynthError};
use crate::toml_input::{steps, KeyLocator};

use super::schema::CameraFile;

/// The validated camera of `c`.
pub(super) fn camera(loc: &KeyLocator, c: &CameraFile) -> Result<Camera> {
    let in_camera = |e: SynthError, key: &str| match e {
        SynthError::InvalidParameter { name, reason } => loc.err(
            steps!["camera", key],
            format!("camera: invalid {name}: {reason}"),
        ),
        other => other,
    };
    let mut cam =
        match (c.fx, c.focal_length_mm, c.pixel_pitch_um) {
            (Some(fx), _, _) => {
                let fy = c.fy.unwrap_or(fx);
                Camera::new(
                    c.width,
                    c.height,
                    [
                        fx,
                        fy,
                        c.cx.unwrap_or(camera::centre(c.width)),
                        c.cy.unwrap_or(camera::centre(c.height)),
                    ],
                    c.distortion,
                )
                .map_err(|e| in_camera(e, "fx"))?
                .with_lens(c.focal_length_mm, c.pixel_pitch_um)
            }
            (None, Some(f), Some(p)) => {
                let lens = Camera::from_lens(c.width, c.height, f, p)
                    .map_err(|e| in_camera(e, "focal_length_mm"))?;
                let cx = c.cx.unwrap_or(lens.cx);
                let cy = c.cy.unwrap_or(lens.cy);
                let fy = c.fy.unwrap_or(lens.fy);
                Camera::new(c.width, c.height, [lens.fx, fy, cx, cy], c.distortion)
                    .map_err(|e| in_camera(e, "distortion"))?
                    .with_lens(Some(f), Some(p))
            }
            _ => return Err(loc.err(
                steps!["camera"],
                "camera: give fx (and optionally fy, cx, cy) or focal_length_mm and pixel_pitch_um"
                    .into(),
            )),
        };
    if let Some(d) = &c.defocus {
        cam = cam
            .with_defocus(Defocus {
                f_number: d.f_number,
                focus_distance_m: d.focus_distance_m,
            })
            .map_err(|e| match e {
                SynthError::InvalidParameter { name, reason } => loc.err(
                    steps!["camera", "defocus", "f_number"],
                    format!("camera: invalid {name}: {reason}"),
                ),
                other => other,
            })?;
    }
    Ok(cam)
}

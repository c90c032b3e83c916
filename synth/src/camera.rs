//! Pinhole camera with OpenCV's lens distortion and thin-lens defocus.
//!
//! Frames and units: the camera frame is OpenCV's (x right, y down, z
//! forward along the optical axis), in metres. Image coordinates are
//! pixel-centre coordinates: the centre of the top-left pixel is (0, 0) and
//! pixel `i` spans `[i - 0.5, i + 0.5]`, which is also OpenCV's convention,
//! so `K` and the distortion coefficients here mean exactly what they mean
//! to `cv2.projectPoints`.
//!
//! Distortion: the Brown-Conrady model as OpenCV implements it ("plumb_bob"
//! in ROS and Foxglove): for normalised coordinates `(x, y)` with
//! `r^2 = x^2 + y^2`,
//! `x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)` and
//! `y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y`
//! (D. C. Brown, "Decentering distortion of lenses", 1966; OpenCV's
//! calib3d documentation). The polynomial folds back beyond some radius;
//! points past the first radius where the radial map stops increasing are
//! treated as not visible.
//!
//! Defocus: thin-lens circle of confusion. With focal length `f`, f-number
//! `N` (aperture `A = f / N`) and focus distance `s_f`, a point at depth `s`
//! is imaged as a disc of diameter `c = A |s - s_f| / s * f / (s_f - f)` on
//! the sensor, `c / pitch` pixels. The renderer blurs with a Gaussian of the
//! same second moment as that disc, `sigma = c_px / 4`.

use nalgebra::Vector3;
use serde::Serialize;

use crate::error::SynthError;

/// Thin-lens defocus settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Defocus {
    /// f-number `N` (focal length over aperture diameter).
    pub f_number: f64,
    /// Distance in focus, metres along the optical axis.
    pub focus_distance_m: f64,
}

/// A calibrated camera: image size, intrinsics, distortion, optional
/// physical lens data for defocus.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Focal length in pixels along x.
    pub fx: f64,
    /// Focal length in pixels along y.
    pub fy: f64,
    /// Principal point x, pixel-centre coordinates.
    pub cx: f64,
    /// Principal point y, pixel-centre coordinates.
    pub cy: f64,
    /// OpenCV distortion coefficients `[k1, k2, p1, p2, k3]`.
    pub distortion: [f64; 5],
    /// Lens focal length in millimetres, when known.
    pub focal_length_mm: Option<f64>,
    /// Pixel pitch in micrometres, when known.
    pub pixel_pitch_um: Option<f64>,
    /// Thin-lens defocus, when simulated.
    pub defocus: Option<Defocus>,
    /// Squared normalised radius up to which the distortion map is
    /// monotonic (infinite without radial distortion).
    #[serde(skip)]
    max_r2: f64,
}

/// Largest squared radius `s` in `(0, 16]` before the radial map
/// `r (1 + k1 r^2 + k2 r^4 + k3 r^6)` stops increasing, with a 2% margin.
fn monotonic_limit(k1: f64, k2: f64, k3: f64) -> f64 {
    let slope = |s: f64| 1.0 + 3.0 * k1 * s + 5.0 * k2 * s * s + 7.0 * k3 * s * s * s;
    let (mut lo, step) = (0.0f64, 1.0 / 1024.0);
    while lo < 16.0 {
        let hi = lo + step;
        if slope(hi) <= 0.0 {
            let (mut a, mut b) = (lo, hi);
            for _ in 0..60 {
                let m = 0.5 * (a + b);
                if slope(m) > 0.0 {
                    a = m;
                } else {
                    b = m;
                }
            }
            return a * 0.98;
        }
        lo = hi;
    }
    f64::INFINITY
}

impl Camera {
    /// A camera from explicit intrinsics; checks that every number is
    /// usable.
    pub fn new(
        width: u32,
        height: u32,
        [fx, fy, cx, cy]: [f64; 4],
        distortion: [f64; 5],
    ) -> Result<Self, SynthError> {
        let bad =
            |name: &'static str, reason: String| SynthError::InvalidParameter { name, reason };
        if width == 0 || height == 0 || width > 16384 || height > 16384 {
            return Err(bad(
                "camera.width/height",
                format!("{width} x {height} is outside 1..=16384"),
            ));
        }
        for (name, v) in [("fx", fx), ("fy", fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(bad(
                    name,
                    format!("{v} must be a positive number of pixels"),
                ));
            }
        }
        for (name, v) in [("cx", cx), ("cy", cy)] {
            if !v.is_finite() {
                return Err(bad(name, format!("{v} is not finite")));
            }
        }
        if distortion.iter().any(|d| !d.is_finite()) {
            return Err(bad("distortion", "coefficients must be finite".into()));
        }
        let [k1, k2, _, _, k3] = distortion;
        Ok(Self {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
            distortion,
            focal_length_mm: None,
            pixel_pitch_um: None,
            defocus: None,
            max_r2: monotonic_limit(k1, k2, k3),
        })
    }

    /// A camera with square pixels from a lens focal length (mm) and pixel
    /// pitch (µm), principal point at the image centre
    /// `((width - 1) / 2, (height - 1) / 2)`.
    pub fn from_lens(
        width: u32,
        height: u32,
        focal_length_mm: f64,
        pixel_pitch_um: f64,
    ) -> Result<Self, SynthError> {
        if !(focal_length_mm > 0.0 && pixel_pitch_um > 0.0) {
            return Err(SynthError::InvalidParameter {
                name: "focal_length_mm/pixel_pitch_um",
                reason: "both must be positive".into(),
            });
        }
        let f = focal_length_mm * 1000.0 / pixel_pitch_um;
        let mut cam = Self::new(
            width,
            height,
            [f, f, centre(width), centre(height)],
            [0.0; 5],
        )?;
        cam.focal_length_mm = Some(focal_length_mm);
        cam.pixel_pitch_um = Some(pixel_pitch_um);
        Ok(cam)
    }

    /// Sets the lens data that defocus needs.
    pub fn with_lens(mut self, focal_length_mm: Option<f64>, pixel_pitch_um: Option<f64>) -> Self {
        self.focal_length_mm = focal_length_mm;
        self.pixel_pitch_um = pixel_pitch_um;
        self
    }

    /// Enables thin-lens defocus; needs the focal length and pixel pitch.
    pub fn with_defocus(mut self, defocus: Defocus) -> Result<Self, SynthError> {
        let (Some(f_mm), Some(_)) = (self.focal_length_mm, self.pixel_pitch_um) else {
            return Err(SynthError::InvalidParameter {
                name: "camera.defocus",
                reason: "needs focal_length_mm and pixel_pitch_um in [camera]".into(),
            });
        };
        if !(defocus.f_number > 0.0 && defocus.f_number.is_finite()) {
            return Err(SynthError::InvalidParameter {
                name: "camera.defocus.f_number",
                reason: format!("{} must be positive", defocus.f_number),
            });
        }
        if !(defocus.focus_distance_m * 1000.0 > f_mm && defocus.focus_distance_m.is_finite()) {
            return Err(SynthError::InvalidParameter {
                name: "camera.defocus.focus_distance_m",
                reason: format!(
                    "{} m must be beyond the focal length ({f_mm} mm)",
                    defocus.focus_distance_m
                ),
            });
        }
        self.defocus = Some(defocus);
        Ok(self)
    }

    /// Whether any distortion coefficient is non-zero.
    #[must_use]
    pub fn has_distortion(&self) -> bool {
        self.distortion.iter().any(|&d| d != 0.0)
    }

    /// The 3 x 3 intrinsic matrix, row-major.
    #[must_use]
    pub fn k_matrix(&self) -> [f64; 9] {
        [self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0]
    }

    /// Applies the distortion model to normalised coordinates; `None` past
    /// the radius where the model folds back.
    #[must_use]
    pub fn distort(&self, [x, y]: [f64; 2]) -> Option<[f64; 2]> {
        let [k1, k2, p1, p2, k3] = self.distortion;
        let r2 = x * x + y * y;
        if r2 > self.max_r2 {
            return None;
        }
        let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        Some([
            x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
        ])
    }

    /// Inverts [`Camera::distort`] by fixed-point iteration (the method of
    /// OpenCV's `undistortPoints`).
    #[must_use]
    pub fn undistort(&self, [xd, yd]: [f64; 2]) -> [f64; 2] {
        if !self.has_distortion() {
            return [xd, yd];
        }
        let [k1, k2, p1, p2, k3] = self.distortion;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..30 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            let done = (nx - x).abs() + (ny - y).abs() < 1e-14;
            (x, y) = (nx, ny);
            if done {
                break;
            }
        }
        [x, y]
    }

    /// Projects a camera-frame point (metres) to pixel-centre coordinates;
    /// `None` when it is not in front of the camera or past the valid
    /// distortion radius.
    #[must_use]
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 2]> {
        if p.z.is_nan() || p.z <= 1e-9 {
            return None;
        }
        let [x, y] = self.distort([p.x / p.z, p.y / p.z])?;
        Some([self.fx * x + self.cx, self.fy * y + self.cy])
    }

    /// The viewing ray (z = 1) through a pixel-centre coordinate.
    #[must_use]
    pub fn ray(&self, [u, v]: [f64; 2]) -> Vector3<f64> {
        let [x, y] = self.undistort([(u - self.cx) / self.fx, (v - self.cy) / self.fy]);
        Vector3::new(x, y, 1.0)
    }

    /// Whether a pixel-centre point lies inside the image.
    #[must_use]
    pub fn contains(&self, [u, v]: [f64; 2]) -> bool {
        u >= -0.5
            && v >= -0.5
            && u <= f64::from(self.width) - 0.5
            && v <= f64::from(self.height) - 0.5
    }

    /// Gaussian blur sigma in pixels for a point at `depth_m` along the
    /// optical axis; 0 without defocus.
    #[must_use]
    pub fn defocus_sigma_px(&self, depth_m: f64) -> f64 {
        let (Some(d), Some(f_mm), Some(pitch_um)) =
            (self.defocus, self.focal_length_mm, self.pixel_pitch_um)
        else {
            return 0.0;
        };
        let f = f_mm * 1e-3;
        let aperture = f / d.f_number;
        let s = depth_m.max(1e-6);
        let coc = aperture * (s - d.focus_distance_m).abs() / s * f / (d.focus_distance_m - f);
        coc / (pitch_um * 1e-6) / 4.0
    }
}

/// The pixel-centre coordinate of the middle of `n` pixels, `(n - 1) / 2`.
#[must_use]
pub fn centre(n: u32) -> f64 {
    (f64::from(n) - 1.0) / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_camera_numbers() {
        let cam = Camera::from_lens(1920, 1080, 16.0, 5.86).unwrap();
        assert!((cam.fx - 2_730.375_426_621_16).abs() < 1e-6);
        assert_eq!((cam.cx, cam.cy), (959.5, 539.5));
        // A point on the axis lands on the principal point.
        let p = cam.project(&Vector3::new(0.0, 0.0, 2.0)).unwrap();
        assert_eq!(p, [959.5, 539.5]);
        assert!(cam.project(&Vector3::new(0.0, 0.0, -1.0)).is_none());
    }

    #[test]
    fn undistort_inverts_distort() {
        let cam = Camera::new(
            640,
            480,
            [500.0, 510.0, 320.0, 240.0],
            [-0.28, 0.09, 0.001, -0.0008, -0.01],
        )
        .unwrap();
        for &(x, y) in &[(0.1, -0.2), (-0.5, 0.35), (0.6, 0.4), (0.0, 0.0)] {
            let d = cam.distort([x, y]).unwrap();
            let u = cam.undistort(d);
            assert!(
                (u[0] - x).abs() < 1e-10 && (u[1] - y).abs() < 1e-10,
                "{x} {y} {u:?}"
            );
        }
        // Strong barrel distortion folds back: far points are refused.
        assert!(cam.max_r2.is_finite());
        assert!(cam.distort([3.0, 0.0]).is_none());
    }

    #[test]
    fn defocus_is_zero_at_focus_and_grows_away() {
        let cam = Camera::from_lens(1920, 1080, 16.0, 5.86)
            .unwrap()
            .with_defocus(Defocus {
                f_number: 2.0,
                focus_distance_m: 1.0,
            })
            .unwrap();
        assert!(cam.defocus_sigma_px(1.0) < 1e-12);
        let near = cam.defocus_sigma_px(0.5);
        let far = cam.defocus_sigma_px(2.0);
        // c = (8 mm)(0.5/0.5)(16/984) = 0.13 mm = 22.2 px -> sigma 5.5 px.
        assert!(
            (near - 0.008 * 1.0 * 0.016 / 0.984 / 5.86e-6 / 4.0).abs() < 1e-9,
            "{near}"
        );
        assert!(far > 0.0 && far < near);
    }
}

//! A recording's camera model: intrinsics and plumb_bob distortion from a
//! `sensor_msgs/msg/CameraInfo` or a `foxglove.CameraCalibration`, checked
//! before any pose is made from it.
//!
//! ROS and Foxglove calibrations use OpenCV's conventions (pixel-centre
//! coordinates, `D = [k1, k2, p1, p2, k3]`), which are the toolkit's own,
//! so `K` and `D` are used as they are: corners are undistorted with `D`,
//! then the pose is solved with `K`.

use crate::pose_error::CameraModel;

/// Distortion models that are read. `rational_polynomial` is read only
/// when its extra coefficients (k4, k5, k6) are zero, where it is
/// plumb_bob.
pub const DISTORTION_MODELS: &[&str] = &["plumb_bob", "rational_polynomial", "none", ""];

/// The calibration fields the toolkit uses, from whichever message.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Image width the calibration was made for.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// `K`, row-major.
    pub k: [f64; 9],
    /// Distortion model name.
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// Horizontal and vertical binning (0 and 1 both mean none).
    pub binning: (u32, u32),
    /// Region of interest `(x, y, width, height)`; all zero for the full image.
    pub roi: (u32, u32, u32, u32),
}

impl Calibration {
    /// The camera model, or what is wrong with the calibration.
    pub fn model(&self) -> Result<CameraModel, String> {
        let [fx, _, cx, _, fy, cy, ..] = self.k;
        for (name, v) in [("fx (K[0])", fx), ("fy (K[4])", fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("focal length {name} = {v} must be positive"));
            }
        }
        if !(cx.is_finite() && cy.is_finite()) {
            return Err(format!("principal point ({cx}, {cy}) is not finite"));
        }
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "image size {} x {} must not be zero",
                self.width, self.height
            ));
        }
        if self.binning.0 > 1 || self.binning.1 > 1 {
            return Err(format!(
                "binning {} x {} is not supported (the intrinsics would need rescaling)",
                self.binning.0, self.binning.1
            ));
        }
        let (rx, ry, rw, rh) = self.roi;
        let full =
            (rx, ry) == (0, 0) && (rw == 0 || rw == self.width) && (rh == 0 || rh == self.height);
        if !full {
            return Err(format!(
                "region of interest {rw} x {rh} at ({rx}, {ry}) is not supported"
            ));
        }
        let model = self.distortion_model.as_str();
        if !DISTORTION_MODELS.contains(&model) {
            return Err(format!(
                "distortion model '{model}' is not supported (plumb_bob is)"
            ));
        }
        if self.d.len() > 5 && self.d[5..].iter().any(|&c| c != 0.0) {
            return Err(format!(
                "distortion model '{model}' with {} coefficients: only k1, k2, p1, p2, k3 are supported",
                self.d.len()
            ));
        }
        if matches!(model, "none" | "") && self.d.iter().any(|&c| c != 0.0) {
            return Err("distortion coefficients without a distortion model".into());
        }
        let mut d = [0.0; 5];
        for (slot, &c) in d.iter_mut().zip(&self.d) {
            *slot = c;
        }
        CameraModel::new(self.width, self.height, [fx, fy, cx, cy], d).map_err(|e| e.to_string())
    }
}

impl From<&super::msgs::CameraInfo> for Calibration {
    fn from(m: &super::msgs::CameraInfo) -> Self {
        Self {
            width: m.width,
            height: m.height,
            k: m.k,
            distortion_model: m.distortion_model.clone(),
            d: m.d.clone(),
            binning: (m.binning_x, m.binning_y),
            roi: (m.roi.x_offset, m.roi.y_offset, m.roi.width, m.roi.height),
        }
    }
}

/// A `foxglove.CameraCalibration` in JSON (as `coppertag synth` writes it).
#[derive(Debug, serde::Deserialize)]
#[allow(non_snake_case)]
pub struct FoxgloveCalibration {
    width: u32,
    height: u32,
    #[serde(default)]
    distortion_model: String,
    #[serde(default)]
    D: Vec<f64>,
    K: [f64; 9],
    #[serde(default)]
    R: Option<[f64; 9]>,
    #[serde(default)]
    P: Option<[f64; 12]>,
    #[serde(default)]
    frame_id: String,
}

impl FoxgloveCalibration {
    /// The same calibration as a `sensor_msgs/msg/CameraInfo` stamped
    /// `stamp` (ns); a missing `R` is the identity and a missing `P` is
    /// `K` with a zero fourth column, as for a monocular camera.
    #[must_use]
    pub fn to_camera_info(&self, stamp: u64) -> super::msgs::CameraInfo {
        let k = self.K;
        super::msgs::CameraInfo {
            header: super::msgs::Header {
                stamp: super::msgs::Time::from_nanos(stamp),
                frame_id: self.frame_id.clone(),
            },
            height: self.height,
            width: self.width,
            distortion_model: self.distortion_model.clone(),
            d: self.D.clone(),
            k,
            r: self
                .R
                .unwrap_or([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]),
            p: self.P.unwrap_or([
                k[0], k[1], k[2], 0.0, k[3], k[4], k[5], 0.0, k[6], k[7], k[8], 0.0,
            ]),
            ..Default::default()
        }
    }
}

impl From<&FoxgloveCalibration> for Calibration {
    fn from(m: &FoxgloveCalibration) -> Self {
        Self {
            width: m.width,
            height: m.height,
            k: m.K,
            distortion_model: m.distortion_model.clone(),
            d: m.D.clone(),
            binning: (0, 0),
            roi: (0, 0, 0, 0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cal() -> Calibration {
        Calibration {
            width: 640,
            height: 480,
            k: [600.0, 0.0, 319.5, 0.0, 600.0, 239.5, 0.0, 0.0, 1.0],
            distortion_model: "plumb_bob".into(),
            d: vec![-0.1, 0.01, 0.0, 0.0, 0.0],
            binning: (0, 0),
            roi: (0, 0, 0, 0),
        }
    }

    #[test]
    fn checks_every_field_it_uses() {
        assert!(cal().model().is_ok());
        let mut c = cal();
        c.k[0] = 0.0;
        assert!(c.model().unwrap_err().contains("fx (K[0]) = 0"));
        let mut c = cal();
        c.distortion_model = "equidistant".into();
        assert!(c.model().unwrap_err().contains("equidistant"));
        let mut c = cal();
        c.distortion_model = "rational_polynomial".into();
        c.d = vec![-0.1, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        assert!(c.model().is_ok());
        c.d[6] = 0.2;
        assert!(c.model().is_err());
        let mut c = cal();
        c.binning = (2, 2);
        assert!(c.model().unwrap_err().contains("binning"));
        let mut c = cal();
        c.roi = (10, 10, 100, 100);
        assert!(c.model().unwrap_err().contains("region of interest"));
    }
}

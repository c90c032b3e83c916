//! Pose error of a detection, the same way for every system: the reported
//! corners are undistorted with the dataset's camera model, then one solver
//! gives the pose from them and the known marker-square side, and that pose
//! is compared with the ground truth.
//!
//! The solver is IPPE (Collins & Bartoli, "Infinitesimal Plane-based Pose
//! Estimation", IJCV 2014) as the `coppertag` library implements it
//! ([`coppertag::pose::tag_pose`]): closed form, no iteration, no tuning,
//! and it returns both solutions of the planar ambiguity, which is what the
//! flipped-pose share needs. Its marker frame (x from TL to TR, y from TL
//! to BL, z into the marker) is the dataset's, so the truth's rotation
//! vector and translation compare directly.

use std::path::Path;

use coppertag_synth::camera::Camera;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};
use crate::truth::TruthMarker;

/// A pose whose rotation is this far from the truth (degrees) is flipped
/// whatever else holds: the marker is seen from behind, or its corners
/// were reported in the wrong order (a quarter turn off).
pub const FLIP_ROTATION_DEG: f64 = 90.0;

/// The chosen IPPE solution counts as the wrong branch of the planar
/// ambiguity (a flip) only when the two solutions are at least this far
/// apart (degrees). Nearly face-on, both solutions lie within a few
/// degrees of each other and either is as good as the corners allow;
/// calling one of them "flipped" would count noise.
pub const FLIP_SEPARATION_DEG: f64 = 10.0;

/// The camera section of `dataset.json`, as far as poses need it.
#[derive(Deserialize)]
struct CameraParams {
    width: u32,
    height: u32,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    #[serde(default)]
    distortion: [f64; 5],
}

/// The dataset's camera: image size, intrinsics, OpenCV distortion, with
/// the renderer's own distortion model (so undistortion inverts exactly
/// what rendering applied).
#[derive(Debug, Clone, PartialEq)]
pub struct CameraModel {
    lens: Camera,
}

impl CameraModel {
    /// A camera from its size, `[fx, fy, cx, cy]` (pixel-centre
    /// coordinates) and `[k1, k2, p1, p2, k3]`.
    pub fn new(width: u32, height: u32, k: [f64; 4], distortion: [f64; 5]) -> Result<Self> {
        Camera::new(width, height, k, distortion)
            .map(|lens| Self { lens })
            .map_err(|e| EvalError::InvalidParameter {
                name: "camera",
                reason: e.to_string(),
            })
    }

    /// Reads the `camera` of `dir/dataset.json`.
    pub fn open(dir: &Path) -> Result<Self> {
        let path = dir.join("dataset.json");
        let text = std::fs::read_to_string(&path).map_err(|e| EvalError::io(&path, e))?;
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| EvalError::bad(&path, e.to_string()))?;
        let c: CameraParams = serde_json::from_value(v["camera"].clone())
            .map_err(|e| EvalError::bad(&path, format!("camera: {e}")))?;
        Self::new(c.width, c.height, [c.fx, c.fy, c.cx, c.cy], c.distortion)
            .map_err(|e| EvalError::bad(&path, e.to_string()))
    }

    /// Image area, megapixels.
    pub fn megapixels(&self) -> f64 {
        f64::from(self.lens.width) * f64::from(self.lens.height) / 1e6
    }

    /// A pixel of the distorted image moved to where an ideal pinhole with
    /// the same intrinsics would have imaged it.
    pub fn undistort_px(&self, p: [f64; 2]) -> [f64; 2] {
        let c = &self.lens;
        if !c.has_distortion() {
            return p;
        }
        let [x, y] = c.undistort([(p[0] - c.cx) / c.fx, (p[1] - c.cy) / c.fy]);
        [c.fx * x + c.cx, c.fy * y + c.cy]
    }

    /// Projects a camera-frame point (metres) into the distorted image.
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        self.lens.project(&Vector3::from(p))
    }

    /// Pose of a tag from its corners as detected in the distorted image:
    /// the corners are undistorted, then IPPE solves with the intrinsics.
    /// `side` is the data square's side (metres).
    pub fn tag_pose(
        &self,
        corners: &[[f64; 2]; 4],
        side: f64,
    ) -> coppertag::Result<coppertag::pose::TagPose> {
        let undistorted = corners.map(|p| self.undistort_px(p));
        coppertag::pose::tag_pose(&undistorted, &self.intrinsics(), side)
    }

    /// Image width and height the model was made for.
    pub fn size(&self) -> (u32, u32) {
        (self.lens.width, self.lens.height)
    }

    fn intrinsics(&self) -> coppertag::pose::Intrinsics {
        coppertag::pose::Intrinsics {
            fx: self.lens.fx,
            fy: self.lens.fy,
            cx: self.lens.cx,
            cy: self.lens.cy,
        }
    }
}

/// A detection's pose against the truth.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseError {
    /// Distance between estimated and true marker centres, mm.
    pub translation_mm: f64,
    /// The same as a percentage of the true distance to the camera.
    pub translation_pct: f64,
    /// Angle of the rotation between estimated and true orientation, deg.
    pub rotation_deg: f64,
    /// Wrong branch of the planar ambiguity, or more than
    /// [`FLIP_ROTATION_DEG`] off (see [`pose_error`]).
    pub flipped: bool,
    /// Estimated translation, metres (for jitter).
    pub translation: [f64; 3],
    /// Estimated rotation as a rotation vector, radians (for jitter).
    pub rvec: [f64; 3],
}

/// Rotation matrix of a rotation vector (Rodrigues).
pub fn rotation_of(rvec: [f64; 3]) -> Matrix3<f64> {
    nalgebra::Rotation3::new(Vector3::from(rvec)).into_inner()
}

/// Angle of the rotation `a^T b`, radians, accurate near 0 and pi:
/// `atan2(|skew part|, trace - 1)` (both are 2 sin and 2 cos of it).
pub fn angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let r = a.transpose() * b;
    let s = Vector3::new(
        r[(2, 1)] - r[(1, 2)],
        r[(0, 2)] - r[(2, 0)],
        r[(1, 0)] - r[(0, 1)],
    )
    .norm();
    s.atan2(r.trace() - 1.0)
}

fn matrix(rows: &[[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| rows[i][j])
}

/// Pose error of `corners` (as reported, distorted image) for the marker
/// `truth`; `None` when the truth has no pose or the corners give none (a
/// degenerate quadrilateral).
///
/// Flipped: the rotation error exceeds [`FLIP_ROTATION_DEG`], or IPPE's
/// other solution is closer to the true rotation than the one it chose
/// (smaller reprojection error) while the two are at least
/// [`FLIP_SEPARATION_DEG`] apart.
pub fn pose_error(
    corners: &[[f64; 2]; 4],
    truth: &TruthMarker,
    cam: &CameraModel,
) -> Option<PoseError> {
    let (rvec, t_true, side) = truth.pose()?;
    let undistorted = corners.map(|p| cam.undistort_px(p));
    let poses = coppertag::pose::tag_pose(&undistorted, &cam.intrinsics(), side).ok()?;
    let r_true = rotation_of(rvec);
    let r_best = matrix(&poses.best.rotation);
    let r_alt = matrix(&poses.alternative.rotation);
    let rot_best = angle_between(&r_best, &r_true).to_degrees();
    let rot_alt = angle_between(&r_alt, &r_true).to_degrees();
    let separation = angle_between(&r_best, &r_alt).to_degrees();
    let t_est = Vector3::from(poses.best.translation);
    let t_true = Vector3::from(t_true);
    let dt = (t_est - t_true).norm();
    let rv = nalgebra::Rotation3::from_matrix_unchecked(r_best).scaled_axis();
    Some(PoseError {
        translation_mm: dt * 1e3,
        translation_pct: 100.0 * dt / t_true.norm().max(f64::MIN_POSITIVE),
        rotation_deg: rot_best,
        flipped: rot_best > FLIP_ROTATION_DEG
            || (rot_alt < rot_best && separation >= FLIP_SEPARATION_DEG),
        translation: [t_est.x, t_est.y, t_est.z],
        rvec: [rv.x, rv.y, rv.z],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::test_marker;

    /// The four corners of a marker of side `s` at pose (rvec, t), as the
    /// renderer projects them (with distortion).
    fn project(cam: &CameraModel, rvec: [f64; 3], t: [f64; 3], s: f64) -> [[f64; 2]; 4] {
        let r = rotation_of(rvec);
        let h = s / 2.0;
        [[-h, -h], [-h, h], [h, h], [h, -h]].map(|m| {
            let p = r * Vector3::new(m[0], m[1], 0.0) + Vector3::from(t);
            cam.project([p.x, p.y, p.z]).unwrap()
        })
    }

    #[test]
    fn exact_corners_give_the_true_pose_through_distortion() {
        let cam = CameraModel::new(
            1280,
            720,
            [900.0, 905.0, 640.2, 359.7],
            [-0.21, 0.08, 0.001, -0.0005, -0.01],
        )
        .unwrap();
        for (rvec, t) in [
            ([0.4, -0.3, 1.1], [0.05, -0.03, 0.7]),
            ([-0.9, 0.2, -2.5], [-0.2, 0.1, 1.4]),
            ([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ] {
            let s = 0.08;
            let m = test_marker(0, 1, project(&cam, rvec, t, s), Some((rvec, t, s)));
            let e = pose_error(&m.corners(), &m, &cam).unwrap();
            // 1e-6 m and 1e-6 rad.
            assert!(e.translation_mm < 1e-3, "{e:?}");
            assert!(e.rotation_deg < 1e-6f64.to_degrees(), "{e:?}");
            assert!(!e.flipped, "{e:?}");
            for (got, want) in e.translation.iter().zip(t) {
                assert!((got - want).abs() < 1e-6, "{got} vs {want}");
            }
        }
    }

    #[test]
    fn corners_a_half_turn_round_are_a_flipped_pose() {
        let cam = CameraModel::new(640, 480, [600.0, 600.0, 319.5, 239.5], [0.0; 5]).unwrap();
        let (rvec, t, s) = ([0.3, 0.2, 0.1], [0.01, 0.02, 0.5], 0.05);
        let c = project(&cam, rvec, t, s);
        let m = test_marker(0, 1, c, Some((rvec, t, s)));
        let turned = [c[2], c[3], c[0], c[1]];
        let e = pose_error(&turned, &m, &cam).unwrap();
        assert!((e.rotation_deg - 180.0).abs() < 1e-6, "{e:?}");
        assert!(e.flipped);
        // A corner 2 px off: a small error, not a flip.
        let mut off = c;
        off[1][0] += 2.0;
        let e = pose_error(&off, &m, &cam).unwrap();
        assert!(e.translation_mm > 0.01 && !e.flipped, "{e:?}");
        // No pose in the truth: no error.
        let bare = test_marker(0, 1, c, None);
        assert!(pose_error(&c, &bare, &cam).is_none());
    }
}

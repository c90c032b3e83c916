//! Rigid poses of markers in the camera frame.
//!
//! A pose maps marker-frame points to camera-frame points,
//! `X_c = R X_m + t`, as OpenCV's `rvec`/`tvec` do. The marker frame has its
//! origin at the centre of the marker square, x to the right and y down in
//! the upright marker, and z into the marker (away from a camera that sees
//! its printed face), so the identity rotation shows the marker upright and
//! facing the camera. This is AprilTag 3's tag frame; OpenCV's ArUco frame
//! differs by a half turn about x (y up, z out of the marker).

use nalgebra::{Rotation3, UnitQuaternion, Vector3};

/// A rigid transform from the marker frame to the camera frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation `R`.
    pub rotation: Rotation3<f64>,
    /// Translation `t` in metres.
    pub translation: Vector3<f64>,
}

impl Pose {
    /// A pose from a rotation vector (axis times angle in radians, OpenCV's
    /// `rvec`) and a translation in metres.
    #[must_use]
    pub fn from_rvec(rvec: [f64; 3], tvec: [f64; 3]) -> Self {
        Self {
            rotation: Rotation3::from_scaled_axis(Vector3::from(rvec)),
            translation: Vector3::from(tvec),
        }
    }

    /// Maps a marker-frame point (metres) to the camera frame.
    #[must_use]
    pub fn apply(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }

    /// The rotation vector (OpenCV `rvec`), radians.
    #[must_use]
    pub fn rvec(&self) -> [f64; 3] {
        self.rotation.scaled_axis().into()
    }

    /// The rotation as a unit quaternion `[w, x, y, z]`, with `w >= 0`.
    #[must_use]
    pub fn quaternion(&self) -> [f64; 4] {
        let q = UnitQuaternion::from_rotation_matrix(&self.rotation);
        let s = if q.w < 0.0 { -1.0 } else { 1.0 };
        [s * q.w, s * q.i, s * q.j, s * q.k]
    }

    /// The translation `[x, y, z]`, metres.
    #[must_use]
    pub fn tvec(&self) -> [f64; 3] {
        self.translation.into()
    }

    /// The unit normal of the marker plane (its z axis) in the camera frame.
    #[must_use]
    pub fn normal(&self) -> Vector3<f64> {
        self.rotation * Vector3::z()
    }
}

/// Rotation by `angle` radians about axis 0 (x), 1 (y) or 2 (z).
#[must_use]
pub fn axis_rotation(axis: usize, angle: f64) -> Rotation3<f64> {
    let a = match axis {
        0 => Vector3::x_axis(),
        1 => Vector3::y_axis(),
        _ => Vector3::z_axis(),
    };
    Rotation3::from_axis_angle(&a, angle)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rvec_and_quaternion_round_trip() {
        let p = Pose::from_rvec([0.3, -0.2, 1.1], [0.1, 0.0, 2.0]);
        let r = p.rvec();
        assert!((r[0] - 0.3).abs() < 1e-12 && (r[2] - 1.1).abs() < 1e-12);
        let [w, x, y, z] = p.quaternion();
        assert!((w * w + x * x + y * y + z * z - 1.0).abs() < 1e-12);
        // Identity: the marker faces the camera, normal along +z.
        let id = Pose::from_rvec([0.0; 3], [0.0, 0.0, 1.0]);
        assert_eq!(id.normal(), Vector3::z());
        assert_eq!(id.quaternion(), [1.0, 0.0, 0.0, 0.0]);
    }
}

//! Tag pose from its four corners: Infinitesimal Plane-based Pose Estimation
//! (Collins & Bartoli, "Infinitesimal Plane-Based Pose Estimation", IJCV
//! 109(3), 2014), re-implemented.
//!
//! IPPE reads the two possible rotations of a plane off the Jacobian of the
//! model-to-image homography at the model origin, which is why a square
//! seen nearly face-on has two poses that both fit: [`tag_pose`] returns
//! both, the better one (smaller reprojection error) first.
//!
//! Tag frame: origin at the centre of the data square, x towards the right
//! side (from TL to TR), y towards the bottom (from TL to BL), z = x cross y
//! pointing into the tag, away from a camera that sees it; a tag facing the
//! camera squarely has the identity rotation. Units are those of the tag
//! side (metres in files). Camera frame: OpenCV's (x right, y down, z
//! forward).

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use crate::homography::Homography;
use crate::{Error, Result};

/// Pinhole camera intrinsics (pixels, pixel-centre convention; undistorted
/// image).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    /// Focal length along x.
    pub fx: f64,
    /// Focal length along y.
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
}

/// One pose of the tag in the camera frame: `X_cam = rotation * X_tag +
/// translation`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Pose {
    /// Rotation matrix, row-major.
    pub rotation: [[f64; 3]; 3],
    /// Translation (tag centre in the camera frame).
    pub translation: [f64; 3],
    /// RMS reprojection error of the four corners, pixels.
    pub reprojection_px: f64,
}

/// The two IPPE solutions, better first.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TagPose {
    /// Solution with the smaller reprojection error.
    pub best: Pose,
    /// The other solution of the planar ambiguity.
    pub alternative: Pose,
}

/// Pose of a tag from its corners (TL, BL, BR, TR pixels), the camera and
/// the side of the data square (`tag_side`, e.g. metres; half the printed
/// size).
pub fn tag_pose(corners: &[[f64; 2]; 4], k: &Intrinsics, tag_side: f64) -> Result<TagPose> {
    let bad = |name: &'static str, reason: &str| Error::InvalidParameter {
        name,
        reason: reason.into(),
    };
    let failed = |reason: &str| Error::PoseFailed {
        reason: reason.into(),
    };
    if !(tag_side.is_finite() && tag_side > 0.0) {
        return Err(bad("tag_side", "must be positive"));
    }
    if !(k.fx.is_finite() && k.fy.is_finite() && k.fx > 0.0 && k.fy > 0.0) {
        return Err(bad("intrinsics", "focal lengths must be positive"));
    }
    let h = tag_side / 2.0;
    let model = [[-h, -h], [-h, h], [h, h], [h, -h]];
    let norm: [[f64; 2]; 4] = corners.map(|p| [(p[0] - k.cx) / k.fx, (p[1] - k.cy) / k.fy]);
    let hom = Homography::from_points(&model, &norm)
        .ok_or_else(|| failed("degenerate quadrilateral (three corners collinear)"))?;
    let mut m = *hom.matrix();
    m /= m[(2, 2)];
    // Image of the model origin and the Jacobian there.
    let v = Vector2::new(m[(0, 2)], m[(1, 2)]);
    let j = Matrix2::new(
        m[(0, 0)] - m[(2, 0)] * v.x,
        m[(0, 1)] - m[(2, 1)] * v.x,
        m[(1, 0)] - m[(2, 0)] * v.y,
        m[(1, 1)] - m[(2, 1)] * v.y,
    );
    let (r1, r2) = ippe_rotations(&v, &j).ok_or_else(|| failed("no rotation fits the corners"))?;
    let mut poses = [r1, r2].map(|r| {
        let t = translation(&r, &model, &norm);
        let err = reprojection(&r, &t, &model, corners, k);
        Pose {
            rotation: std::array::from_fn(|i| std::array::from_fn(|c| r[(i, c)])),
            translation: [t.x, t.y, t.z],
            reprojection_px: err,
        }
    });
    if poses[1].reprojection_px < poses[0].reprojection_px {
        poses.swap(0, 1);
    }
    if poses.iter().any(|p| !p.reprojection_px.is_finite()) {
        return Err(failed("no finite pose"));
    }
    Ok(TagPose {
        best: poses[0],
        alternative: poses[1],
    })
}

/// The two rotations of IPPE (Collins & Bartoli 2014, section 4).
fn ippe_rotations(v: &Vector2<f64>, j: &Matrix2<f64>) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    // Rv: rotation taking the z axis onto the ray through v.
    let t = Vector3::new(v.x, v.y, 1.0).normalize();
    let z = Vector3::z();
    let axis = z.cross(&t);
    let s = axis.norm();
    let c = t.z;
    let rv = if s < 1e-14 {
        Matrix3::identity()
    } else {
        let k = axis / s;
        let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
        Matrix3::identity() + kx * s + kx * kx * (1.0 - c)
    };
    // B = [I2 | -v] Rv[:, 0..2]
    let b = Matrix2::new(
        rv[(0, 0)] - v.x * rv[(2, 0)],
        rv[(0, 1)] - v.x * rv[(2, 1)],
        rv[(1, 0)] - v.y * rv[(2, 0)],
        rv[(1, 1)] - v.y * rv[(2, 1)],
    );
    let a = b.try_inverse()? * j;
    // Largest singular value of A.
    let ata = a.transpose() * a;
    let (p, q, r) = (ata[(0, 0)], ata[(1, 1)], ata[(0, 1)]);
    let gamma = (0.5 * (p + q + ((p - q).powi(2) + 4.0 * r * r).sqrt())).sqrt();
    if gamma.is_nan() || gamma <= 1e-15 {
        return None;
    }
    let r22 = a / gamma;
    let bb = Matrix2::identity() - r22.transpose() * r22;
    let b0 = bb[(0, 0)].max(0.0).sqrt();
    let mut b1 = bb[(1, 1)].max(0.0).sqrt();
    if bb[(0, 1)] < 0.0 {
        b1 = -b1;
    }
    let build = |sign: f64| {
        let c1 = Vector3::new(r22[(0, 0)], r22[(1, 0)], sign * b0);
        let c2 = Vector3::new(r22[(0, 1)], r22[(1, 1)], sign * b1);
        let c3 = c1.cross(&c2);
        rv * Matrix3::from_columns(&[c1, c2, c3])
    };
    Some((build(1.0), build(-1.0)))
}

/// Least-squares translation for a rotation: each point gives
/// `(R X + t) x (u, v, 1) = 0`, two independent linear equations in `t`.
fn translation(r: &Matrix3<f64>, model: &[[f64; 2]; 4], norm: &[[f64; 2]; 4]) -> Vector3<f64> {
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for (x, u) in model.iter().zip(norm) {
        let p = r * Vector3::new(x[0], x[1], 0.0);
        // px + tx - u (pz + tz) = 0 ; py + ty - v (pz + tz) = 0
        let rows = [
            (Vector3::new(1.0, 0.0, -u[0]), u[0] * p.z - p.x),
            (Vector3::new(0.0, 1.0, -u[1]), u[1] * p.z - p.y),
        ];
        for (a, b) in rows {
            ata += a * a.transpose();
            atb += a * b;
        }
    }
    ata.try_inverse().map_or(Vector3::zeros(), |inv| inv * atb)
}

fn reprojection(
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    model: &[[f64; 2]; 4],
    corners: &[[f64; 2]; 4],
    k: &Intrinsics,
) -> f64 {
    let mut ss = 0.0;
    for (x, c) in model.iter().zip(corners) {
        let p = r * Vector3::new(x[0], x[1], 0.0) + t;
        if p.z <= 0.0 {
            return f64::INFINITY;
        }
        let u = k.fx * p.x / p.z + k.cx;
        let v = k.fy * p.y / p.z + k.cy;
        ss += (u - c[0]).powi(2) + (v - c[1]).powi(2);
    }
    (ss / 4.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot(ax: f64, ay: f64, az: f64) -> Matrix3<f64> {
        // nalgebra's roll-pitch-yaw is Rz(az) * Ry(ay) * Rx(ax).
        nalgebra::Rotation3::from_euler_angles(ax, ay, az).into_inner()
    }

    #[test]
    fn recovers_a_known_pose() {
        let k = Intrinsics {
            fx: 2730.0,
            fy: 2730.0,
            cx: 959.5,
            cy: 539.5,
        };
        let s = 0.05;
        for (ax, ay, az, t) in [
            (0.3, -0.5, 1.0, [0.05, -0.02, 0.8]),
            (-0.9, 0.2, 3.0, [-0.1, 0.05, 1.5]),
            (0.0, 0.0, 0.0, [0.0, 0.0, 1.0]),
            (1.2, 0.0, 0.5, [0.0, 0.0, 1.0]),
        ] {
            let r = rot(ax, ay, az);
            let tv = Vector3::from(t);
            let h = s / 2.0;
            let model = [[-h, -h], [-h, h], [h, h], [h, -h]];
            let corners = model.map(|x| {
                let p = r * Vector3::new(x[0], x[1], 0.0) + tv;
                [k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy]
            });
            let pose = tag_pose(&corners, &k, s).unwrap();
            let b = pose.best;
            assert!(b.reprojection_px < 1e-6, "{}", b.reprojection_px);
            for i in 0..3 {
                assert!((b.translation[i] - t[i]).abs() < 1e-6);
                for j in 0..3 {
                    assert!(
                        (b.rotation[i][j] - r[(i, j)]).abs() < 1e-6,
                        "{ax} {ay} {az}"
                    );
                }
            }
        }
    }

    #[test]
    fn rejects_bad_input() {
        let k = Intrinsics {
            fx: 1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
        };
        let c = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];
        assert!(tag_pose(&c, &k, 0.0).is_err());
        assert!(matches!(
            tag_pose(&[[0.0, 0.0]; 4], &k, 1.0),
            Err(Error::PoseFailed { .. })
        ));
    }
}

//! `coppertag.Detection` and `coppertag.Pose`: one found tag and one of its
//! two IPPE poses, as read-only Python objects with numpy arrays.

use coppertag::pose::{tag_pose, Intrinsics};
use nalgebra::{Matrix3, Rotation3, UnitQuaternion};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;

fn matrix<'py>(py: Python<'py>, rows: &[[f64; 3]; 3]) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((3, 3), |(r, c)| rows[r][c]).into_pyarray(py)
}

/// One detected tag (read-only).
///
/// Coordinates are pixel-centre: the centre of the top-left pixel is (0, 0),
/// x to the right, y down (OpenCV's convention). Corners are those of the
/// tag's white data square in the order top-left, bottom-left,
/// bottom-right, top-right of the tag as printed.
#[pyclass(frozen, module = "coppertag")]
pub struct Detection {
    inner: coppertag::Detection,
}

impl Detection {
    pub fn new(inner: coppertag::Detection) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl Detection {
    /// Family name: "ct14" or "ct8".
    #[getter]
    fn family(&self) -> &str {
        &self.inner.family
    }

    /// Decoded id.
    #[getter]
    fn id(&self) -> u64 {
        self.inner.id
    }

    /// Corners TL, BL, BR, TR as a 4 x 2 float64 array of (x, y) pixels.
    #[getter]
    fn corners<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = &self.inner.corners;
        Array2::from_shape_fn((4, 2), |(i, j)| c[i][j]).into_pyarray(py)
    }

    /// For each corner (TL, BL, BR, TR), whether it was hidden and estimated
    /// from the other corners' lines rather than measured.
    #[getter]
    fn estimated(&self) -> (bool, bool, bool, bool) {
        let e = self.inner.estimated;
        (e[0], e[1], e[2], e[3])
    }

    /// One-sigma uncertainty of each corner (TL, BL, BR, TR) in pixels,
    /// from the fit of the tag's own model to its visible edges; None when
    /// the tag was too small or too hidden for that fit.
    #[getter]
    fn corner_sigma(&self) -> Option<(f64, f64, f64, f64)> {
        self.inner.corner_sigma.map(|s| (s[0], s[1], s[2], s[3]))
    }

    /// Reed-Solomon symbols corrected while decoding (0 for a clean read);
    /// filter on it for confidence. For a tag read by likelihood, the
    /// symbols a cell-by-cell reading got wrong.
    #[getter]
    fn corrected(&self) -> usize {
        self.inner.corrected
    }

    /// True when the tag was read by likelihood: a blurred tag whose cells
    /// the Reed-Solomon decoder could not read, matched against every
    /// codeword; reported only with its geometry confirmed by the model fit.
    #[getter]
    fn likelihood(&self) -> bool {
        self.inner.likelihood
    }

    /// Image point (x, y) of the tag centre (where the diagonals cross).
    #[getter]
    fn center(&self) -> (f64, f64) {
        (self.inner.center[0], self.inner.center[1])
    }

    /// Measured contrast between the tag's white and black, grey levels.
    #[getter]
    fn contrast(&self) -> f64 {
        self.inner.contrast
    }

    /// 3 x 3 float64 homography from tag units (data square of side 1,
    /// centre at 0, y down) to image pixels.
    #[getter]
    fn homography<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix(py, &self.inner.homography.rows())
    }

    /// The tag's two poses in the camera frame (IPPE), the better one
    /// (smaller reprojection error) first.
    ///
    /// fx, fy, cx, cy: pinhole intrinsics in pixels (pixel-centre principal
    /// point) of an undistorted image; tag_size: side of the white data
    /// square (half the printed tag's side), in metres. Raises ValueError
    /// for bad intrinsics or size and PoseError when no pose fits.
    #[pyo3(signature = (fx, fy, cx, cy, tag_size))]
    fn pose(&self, fx: f64, fy: f64, cx: f64, cy: f64, tag_size: f64) -> PyResult<(Pose, Pose)> {
        let k = Intrinsics { fx, fy, cx, cy };
        let p = tag_pose(&self.inner.corners, &k, tag_size).map_err(crate::errors::to_py)?;
        Ok((Pose::new(p.best), Pose::new(p.alternative)))
    }

    fn __repr__(&self) -> String {
        let d = &self.inner;
        let flag = |b: bool| if b { "True" } else { "False" };
        let e = d.estimated.map(flag);
        format!(
            "Detection(family='{}', id={}, center=({:.2}, {:.2}), corrected={}, \
             estimated=({}, {}, {}, {}))",
            d.family, d.id, d.center[0], d.center[1], d.corrected, e[0], e[1], e[2], e[3]
        )
    }
}

/// One pose of a tag in the camera frame: X_cam = rotation @ X_tag +
/// translation (read-only).
///
/// Tag frame: origin at the data square's centre, x towards the tag's
/// right side, y towards its bottom, z into the tag (a tag squarely facing
/// the camera has the identity rotation). Camera frame: OpenCV's (x right,
/// y down, z forward). Translation in the unit of tag_size (metres).
#[pyclass(frozen, module = "coppertag")]
pub struct Pose {
    inner: coppertag::pose::Pose,
}

impl Pose {
    fn new(inner: coppertag::pose::Pose) -> Self {
        Self { inner }
    }
}

#[pymethods]
impl Pose {
    /// 3 x 3 float64 rotation matrix (tag frame to camera frame).
    #[getter]
    fn rotation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix(py, &self.inner.rotation)
    }

    /// The rotation as a rotation vector (axis times angle in radians,
    /// float64 of shape (3,)), as cv2.Rodrigues and cv2.solvePnP give it.
    #[getter]
    fn rotation_vector<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let r = &self.inner.rotation;
        let m = Matrix3::from_fn(|i, j| r[i][j]);
        // Through the quaternion (Shepperd's method inside nalgebra): the
        // matrix's own axis extraction loses the axis at 180 degrees, a
        // tag upside down in front of the camera.
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
        let v = q.scaled_axis();
        Array1::from_vec(vec![v.x, v.y, v.z]).into_pyarray(py)
    }

    /// Translation (tag centre in the camera frame), float64 of shape (3,),
    /// in the unit of tag_size (metres).
    #[getter]
    fn translation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from_vec(self.inner.translation.to_vec()).into_pyarray(py)
    }

    /// RMS reprojection error of the four corners, pixels.
    #[getter]
    fn reprojection_error(&self) -> f64 {
        self.inner.reprojection_px
    }

    fn __repr__(&self) -> String {
        let t = self.inner.translation;
        format!(
            "Pose(translation=[{:.4}, {:.4}, {:.4}], reprojection_error={:.3})",
            t[0], t[1], t[2], self.inner.reprojection_px
        )
    }
}

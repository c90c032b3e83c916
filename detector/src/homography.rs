//! Plane-to-plane homographies from four point pairs.
//!
//! The classic direct linear transform with h33 fixed to 1 (Hartley &
//! Zisserman, "Multiple View Geometry", 2nd ed., section 4.1), solved as an
//! 8 x 8 linear system with nalgebra's LU decomposition. Four points are all
//! a tag gives, so no least squares is needed.

use nalgebra::{Matrix3, SMatrix, SVector};

/// Smallest homogeneous weight (in absolute value) at which
/// [`Homography::map`] maps a point: nearer 0 the point lies on the line
/// at infinity.
pub(crate) const MIN_WEIGHT: f64 = 1e-12;

/// A 3 x 3 homography mapping points of one plane to another.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    m: Matrix3<f64>,
}

impl Homography {
    /// The homography taking each `src[i]` to `dst[i]`, or `None` when the
    /// points are degenerate (three of them collinear).
    pub fn from_points(src: &[[f64; 2]; 4], dst: &[[f64; 2]; 4]) -> Option<Self> {
        let mut a = SMatrix::<f64, 8, 8>::zeros();
        let mut b = SVector::<f64, 8>::zeros();
        for i in 0..4 {
            let [x, y] = src[i];
            let [u, v] = dst[i];
            let r = 2 * i;
            a.row_mut(r)
                .copy_from_slice(&[x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y]);
            a.row_mut(r + 1)
                .copy_from_slice(&[0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y]);
            b[r] = u;
            b[r + 1] = v;
        }
        let h = a.lu().solve(&b)?;
        if h.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let m = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], 1.0);
        // A near-singular matrix means collinear points slipped through LU.
        (m.determinant().abs() > 1e-12).then_some(Self { m })
    }

    /// Wraps a matrix.
    pub fn from_matrix(m: Matrix3<f64>) -> Self {
        Self { m }
    }

    /// The matrix.
    pub fn matrix(&self) -> &Matrix3<f64> {
        &self.m
    }

    /// The matrix as rows (row-major), the form it is serialised in.
    pub fn rows(&self) -> [[f64; 3]; 3] {
        std::array::from_fn(|i| std::array::from_fn(|j| self.m[(i, j)]))
    }

    /// Maps a point; `None` for points on the line at infinity.
    #[inline]
    pub fn map(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        // Written out rather than `self.m * Vector3`: nalgebra's generic
        // matrix-vector product (gemv, column by column) cost a seventh of
        // a cluttered frame's instructions here, in the decoder's grid
        // sampling. The sums run in gemv's order (column 0, 1, then 2), so
        // the results are the same to the bit.
        let m = &self.m;
        let row = |r: usize| m[(r, 0)] * p[0] + m[(r, 1)] * p[1] + m[(r, 2)];
        let (x, y, z) = (row(0), row(1), row(2));
        (z.abs() > MIN_WEIGHT).then(|| [x / z, y / z])
    }

    /// Whether the mapped point has positive homogeneous weight, i.e. lies
    /// on the visible side of a perspective projection.
    #[inline]
    pub fn in_front(&self, p: [f64; 2]) -> bool {
        let m = &self.m;
        m[(2, 0)] * p[0] + m[(2, 1)] * p[1] + m[(2, 2)] > 0.0
    }
}

/// The eight entries of a homography's matrix `m` other than its last,
/// divided by it (the matrix scaled to `m[2][2] = 1`), row-major: the
/// parameters the model fit and the print alignment move. `None` when
/// `m[2][2]` is (nearly) 0.
pub(crate) fn free_entries(m: &Matrix3<f64>) -> Option<[f64; 8]> {
    let z = m[(2, 2)];
    if z.abs() < 1e-12 {
        return None;
    }
    Some([
        m[(0, 0)] / z,
        m[(0, 1)] / z,
        m[(0, 2)] / z,
        m[(1, 0)] / z,
        m[(1, 1)] / z,
        m[(1, 2)] / z,
        m[(2, 0)] / z,
        m[(2, 1)] / z,
    ])
}

/// Serialised as its matrix, row-major (`[[h11, h12, h13], ...]`).
impl serde::Serialize for Homography {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        serde::Serialize::serialize(&self.rows(), s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_the_four_points() {
        let src = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];
        let dst = [[10.0, 12.0], [8.0, 50.0], [60.0, 55.0], [52.0, 9.0]];
        let h = Homography::from_points(&src, &dst).unwrap();
        for i in 0..4 {
            let p = h.map(src[i]).unwrap();
            assert!((p[0] - dst[i][0]).abs() < 1e-9 && (p[1] - dst[i][1]).abs() < 1e-9);
        }
    }

    #[test]
    fn collinear_points_are_rejected() {
        let src = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [1.0, 0.0]];
        let dst = [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [1.0, 0.0]];
        assert!(Homography::from_points(&src, &dst).is_none());
    }
}

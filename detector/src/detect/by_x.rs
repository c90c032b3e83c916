//! Points of a frame sorted by x, for searches of the points near a point
//! that should look at a band of the frame's width rather than at every
//! point: the quad search's corners (around an ellipse, near an estimated
//! corner) and the ellipse stage's rim fragments (the partners within
//! reach of each). A sorted list, not a grid: the points are a few hundred
//! to a few thousand a frame, and a band narrows them enough; written here
//! since a spatial-index crate would bring more than a sort and two binary
//! searches.

/// Margin (px) [`ByX::within`] adds to its reach: far above the rounding
/// of its bounds, far below a pixel, so that no point the caller's own
/// distance test keeps lies outside the band.
const MARGIN_PX: f64 = 1e-6;

/// The indices of points with a finite x, sorted by x (equal ones in index
/// order), and their x in the same order.
#[derive(Debug, Default)]
pub(crate) struct ByX {
    order: Vec<u32>,
    xs: Vec<f64>,
}

impl ByX {
    /// Sorts the points `0..n`, point `i` at x `x(i)`; those whose x is
    /// not finite are left out (no band holds them).
    pub(crate) fn fill(&mut self, n: usize, x: impl Fn(usize) -> f64) {
        self.order.clear();
        self.order
            .extend((0..n as u32).filter(|&i| x(i as usize).is_finite()));
        self.order
            .sort_by(|&i, &j| x(i as usize).total_cmp(&x(j as usize)));
        self.xs.clear();
        self.xs.extend(self.order.iter().map(|&i| x(i as usize)));
    }

    /// The points (indices, by x) whose x lies from `x - r` to `x + r`, a
    /// hair wider ([`MARGIN_PX`]): every point with a finite x within `r`
    /// of a point at `x`, and a few more the caller's own test leaves out
    /// (none if `x` or `r` is NaN).
    pub(crate) fn within(&self, x: f64, r: f64) -> &[u32] {
        let r = r + MARGIN_PX;
        let lo = self.xs.partition_point(|&v| v < x - r);
        let hi = self.xs.partition_point(|&v| v <= x + r).max(lo);
        &self.order[lo..hi]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::strategy::Strategy;

    proptest::proptest! {
        /// A band holds every point whose x is within reach, in x then
        /// index order, and nothing else farther than the margin; points
        /// whose x is not finite are in none.
        #[test]
        fn a_band_holds_the_points_within_reach(
            xs in proptest::collection::vec(proptest::prop_oneof![
                (0u32..50).prop_map(|v| f64::from(v) * 0.5),
                proptest::strategy::Just(f64::NAN),
                proptest::strategy::Just(f64::INFINITY),
            ], 0..80),
            x in -2.0f64..30.0,
            r in 0.0f64..10.0,
        ) {
            let mut by_x = ByX::default();
            by_x.fill(xs.len(), |i| xs[i]);
            let got = by_x.within(x, r);
            // In x order, equal ones in index order.
            let key = |&i: &u32| (xs[i as usize], i);
            proptest::prop_assert!(got.windows(2).all(|w| key(&w[0]) < key(&w[1])));
            // Every point within reach, and none past the margin.
            for i in 0..xs.len() as u32 {
                let d = (xs[i as usize] - x).abs();
                if d <= r {
                    proptest::prop_assert!(got.contains(&i), "{i}");
                }
                if got.contains(&i) {
                    proptest::prop_assert!(d <= r + 2.0 * MARGIN_PX, "{i}");
                }
            }
            proptest::prop_assert!(by_x.within(f64::NAN, r).is_empty());
        }
    }
}

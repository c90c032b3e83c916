//! Bins for a numeric factor, chosen from the values it took.
//!
//! Sampled factors come from a low-discrepancy sequence over their declared
//! range, so the values seen fill that range evenly; derived ones (the
//! marker's side in pixels, from distance and tilt) do not. Bins are
//! therefore cut at quantiles of the values pooled over every system (the
//! same scenes for all, so one set of edges serves all curves): each bin
//! holds about the same number of markers, and no bin is left with too few
//! markers for its rate to mean anything. The cut points are rounded to
//! [`EDGE_DIGITS`] significant digits so that they read well. A factor
//! with at most [`MAX_BINS`] distinct values (JPEG quality levels, markers
//! per frame) gets one bin per value instead.

use serde::{Deserialize, Serialize};

/// Most bins per factor: enough to show a curve's shape.
pub const MAX_BINS: usize = 8;

/// Fewest markers per bin wanted: a rate from 30 markers has a standard
/// error of at most 9 points, enough to tell 50% from 90%.
pub const MIN_PER_BIN: usize = 30;

/// Significant digits of a cut point.
pub const EDGE_DIGITS: i32 = 3;

/// How a factor's values are binned.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Bins {
    /// One bin per distinct value.
    Values(Vec<f64>),
    /// Ranges between cut points: bin 0 is `[lo, c1)`, bin k is
    /// `[c_k, c_k+1)`, the last `[c_last, hi]`, where `lo` and `hi` are the
    /// smallest and largest values seen.
    Ranges {
        /// Smallest value seen.
        lo: f64,
        /// Inner cut points, increasing.
        cuts: Vec<f64>,
        /// Largest value seen.
        hi: f64,
    },
}

fn round_sig(v: f64, digits: i32) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(digits - 1 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

impl Bins {
    /// Bins for `values` (non-finite values are ignored); `None` when fewer
    /// than two distinct values were seen (nothing to plot against).
    pub fn of(values: &[f64]) -> Option<Self> {
        let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        let mut distinct = v.clone();
        distinct.dedup();
        if distinct.len() < 2 {
            return None;
        }
        if distinct.len() <= MAX_BINS {
            return Some(Self::Values(distinct));
        }
        let n = v.len();
        let count = (n / MIN_PER_BIN).clamp(1, MAX_BINS);
        let (lo, hi) = (v[0], v[n - 1]);
        let mut cuts: Vec<f64> = (1..count)
            .map(|k| round_sig(v[k * n / count], EDGE_DIGITS))
            .filter(|&c| c > lo && c <= hi)
            .collect();
        cuts.dedup();
        Some(Self::Ranges { lo, cuts, hi })
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        match self {
            Self::Values(v) => v.len(),
            Self::Ranges { cuts, .. } => cuts.len() + 1,
        }
    }

    /// Whether there are no bins (never, for bins made by [`Bins::of`]).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The bin of `x`; values outside the range seen go to the nearest end
    /// bin; a value that is not one of [`Bins::Values`] has none.
    pub fn index(&self, x: f64) -> Option<usize> {
        match self {
            Self::Values(v) => v.iter().position(|&y| y == x),
            Self::Ranges { cuts, .. } => Some(cuts.partition_point(|&c| c <= x)),
        }
    }

    /// Lower and upper end of bin `k`.
    pub fn range(&self, k: usize) -> (f64, f64) {
        match self {
            Self::Values(v) => (v[k], v[k]),
            Self::Ranges { lo, cuts, hi } => (
                if k == 0 { *lo } else { cuts[k - 1] },
                cuts.get(k).copied().unwrap_or(*hi),
            ),
        }
    }

    /// Where bin `k` is drawn on a curve: its value, or its middle.
    pub fn centre(&self, k: usize) -> f64 {
        let (a, b) = self.range(k);
        0.5 * (a + b)
    }

    /// Bin `k` as text: `25` or `[20.5, 31.2)` (the last range closed).
    pub fn label(&self, k: usize) -> String {
        let (a, b) = self.range(k);
        match self {
            Self::Values(_) => format!("{a}"),
            Self::Ranges { .. } if k + 1 == self.len() => format!("[{a}, {b}]"),
            Self::Ranges { .. } => format!("[{a}, {b})"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_distinct_values_get_a_bin_each() {
        let b = Bins::of(&[50.0, 90.0, 70.0, 50.0, 90.0]).unwrap();
        assert_eq!(b, Bins::Values(vec![50.0, 70.0, 90.0]));
        assert_eq!(b.index(70.0), Some(1));
        assert_eq!(b.index(60.0), None);
        assert!(Bins::of(&[3.0, 3.0, 3.0]).is_none());
    }

    #[test]
    fn ranges_cut_at_quantiles() {
        // 0..240 evenly: 240 values, 8 bins of 30, cut at 30, 60, ... 210.
        let v: Vec<f64> = (0..240).map(f64::from).collect();
        let b = Bins::of(&v).unwrap();
        let Bins::Ranges { lo, cuts, hi } = &b else {
            panic!("{b:?}")
        };
        assert_eq!((*lo, *hi), (0.0, 239.0));
        assert_eq!(cuts, &[30.0, 60.0, 90.0, 120.0, 150.0, 180.0, 210.0]);
        assert_eq!(b.index(0.0), Some(0));
        assert_eq!(b.index(29.999), Some(0));
        assert_eq!(b.index(30.0), Some(1));
        assert_eq!(b.index(239.0), Some(7));
        assert_eq!(b.index(1e9), Some(7));
        assert_eq!(b.label(0), "[0, 30)");
        assert_eq!(b.label(7), "[210, 239]");
        assert_eq!(b.centre(1), 45.0);
        // 90 values: only 3 bins of 30.
        let v: Vec<f64> = (0..90).map(|i| 20.0 + f64::from(i) / 3.0).collect();
        assert_eq!(Bins::of(&v).unwrap().len(), 3);
        // Cut points are rounded to 3 significant digits.
        let v: Vec<f64> = (0..60).map(|i| 1.0 + f64::from(i) * 0.012345).collect();
        let Bins::Ranges { cuts, .. } = Bins::of(&v).unwrap() else {
            panic!()
        };
        assert_eq!(cuts, [1.37]);
    }
}

//! How honest a detector's corner uncertainties are: the share of corners
//! lying within [`SIGMA_MULTIPLE`] of their reported one-sigma uncertainty
//! from the true corner.
//!
//! The issue asks CopperTag for a per-corner uncertainty (px) that is
//! honest: on the wild set at least 90% of corners within 2 sigma of the
//! truth. A sigma that is too small promises a robot more than the corners
//! hold (a pose filter then trusts them too much); one that is too large
//! wastes them. The share is counted over every corner of every *found*
//! marker ([`crate::wild`]: correct or rough, i.e. the right id) whose
//! detection reports a sigma. Rough detections are kept: a corner far off
//! with a small sigma is exactly the dishonesty the figure must catch, and
//! leaving them out would flatter it. Markers read without a sigma
//! (CopperTag's tags too small or too hidden for its model fit, every
//! peer's detections) are not counted; a system with none has no share
//! ("-" in the report, not 0%).
//!
//! The error of a corner is its distance to the true corner and its sigma
//! radial (the root of the trace of its 2 x 2 covariance, as the detector
//! reports it), so the two compare directly. The share is split by corners
//! the detector says it estimated against those it observed, and by
//! readings by code against readings by likelihood, which the detector
//! scales differently (`LIKELIHOOD_SIGMA_FACTOR` in `detector/src/detect/
//! decoding.rs`; `make calibrate-sigma` prints every split on the
//! calibration set those constants were chosen on).

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use crate::wild::MarkerOutcome;

/// Multiple of the reported sigma within which a corner counts as covered:
/// the "within 2 sigma".
pub const SIGMA_MULTIPLE: f64 = 2.0;

/// Corners counted and those within [`SIGMA_MULTIPLE`] sigma.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Tally {
    /// Corners with a sigma.
    pub corners: usize,
    /// Of those, within the multiple of their sigma from the truth.
    pub within: usize,
}

impl Tally {
    /// within / corners; `None` without corners (nothing to say, which is
    /// not 0%).
    pub fn share(&self) -> Option<f64> {
        (self.corners > 0).then(|| self.within as f64 / self.corners as f64)
    }

    fn count(&mut self, within: bool) {
        self.corners += 1;
        self.within += usize::from(within);
    }

    fn merge(&mut self, other: &Tally) {
        self.corners += other.corners;
        self.within += other.within;
    }
}

/// The within-2-sigma figures of one system (or one system on one set).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct SigmaCoverage {
    /// Found markers whose detection reported a sigma (four corners each).
    pub detections: usize,
    /// Every such corner.
    pub all: Tally,
    /// Corners the detector observed.
    pub observed: Tally,
    /// Corners the detector says it estimated (hidden, or with no visible
    /// edge near them).
    pub estimated: Tally,
    /// Corners of tags read by the code (Reed-Solomon, cell by cell).
    pub code: Tally,
    /// Corners of tags read by likelihood.
    pub likelihood: Tally,
    /// Corners of tags drawn with a heavy motion blur
    /// ([`crate::wild_scenarios::HEAVY_MOTION_PX`] or more), which the
    /// detector floors as smeared (`SMEAR_SPREAD_PX` in
    /// `detector/src/detect/verify.rs` is chosen on this split of the dense
    /// calibration set).
    #[serde(default)]
    pub smeared: Tally,
}

/// Whether a corner `error_px` from the truth is within
/// [`SIGMA_MULTIPLE`] of its one-sigma uncertainty `sigma_px`.
pub fn within(error_px: f64, sigma_px: f64) -> bool {
    error_px <= SIGMA_MULTIPLE * sigma_px
}

impl SigmaCoverage {
    /// Counts the four corners of one detection.
    pub fn add(
        &mut self,
        errors_px: &[f64; 4],
        sigma_px: &[f64; 4],
        estimated: &[bool; 4],
        likelihood: bool,
        smeared: bool,
    ) {
        self.detections += 1;
        for k in 0..4 {
            let w = within(errors_px[k], sigma_px[k]);
            self.all.count(w);
            if estimated[k] {
                self.estimated.count(w)
            } else {
                self.observed.count(w)
            }
            if likelihood {
                self.likelihood.count(w)
            } else {
                self.code.count(w)
            }
            if smeared {
                self.smeared.count(w)
            }
        }
    }

    /// Adds another coverage's counts (another set of the same system).
    pub fn merge(&mut self, other: &SigmaCoverage) {
        self.detections += other.detections;
        for (a, b) in [
            (&mut self.all, &other.all),
            (&mut self.observed, &other.observed),
            (&mut self.estimated, &other.estimated),
            (&mut self.code, &other.code),
            (&mut self.likelihood, &other.likelihood),
            (&mut self.smeared, &other.smeared),
        ] {
            a.merge(b);
        }
    }

    /// The coverage of the found markers among `outcomes` that carry a
    /// sigma; `None` when none does (the system reports no uncertainty).
    pub fn of<'a>(outcomes: impl IntoIterator<Item = &'a MarkerOutcome>) -> Option<Self> {
        let mut c = SigmaCoverage::default();
        for o in outcomes.into_iter().filter(|o| o.found()) {
            if let (Some(e), Some(s)) = (&o.corner_errors_px, &o.corner_sigma) {
                let smeared = crate::wild_scenarios::heavy_motion(&o.factors);
                c.add(e, s, &o.estimated, o.likelihood, smeared);
            }
        }
        (c.detections > 0).then_some(c)
    }

    /// One line for a terminal: the overall share, then each split with
    /// its corner count.
    pub fn describe(&self) -> String {
        let part = |t: &Tally| {
            t.share().map_or("-".to_string(), |v| {
                format!("{:.1}% of {}", 100.0 * v, t.corners)
            })
        };
        let mut s = format!(
            "corners within {SIGMA_MULTIPLE} sigma: {} ({} detections with sigma)",
            part(&self.all),
            self.detections
        );
        let _ = write!(
            s,
            "; read by code {}, by likelihood {}; observed {}, estimated {}; \
             motion blur >= {} px {}",
            part(&self.code),
            part(&self.likelihood),
            part(&self.observed),
            part(&self.estimated),
            crate::wild_scenarios::HEAVY_MOTION_PX,
            part(&self.smeared)
        );
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wild::Status;

    fn found(errors: [f64; 4], sigma: Option<[f64; 4]>, estimated: [bool; 4]) -> MarkerOutcome {
        MarkerOutcome {
            index: 0,
            marker_index: 0,
            status: Status::Correct,
            corner_error_max_px: Some(errors.iter().copied().fold(0.0, f64::max)),
            corners: Some([[0.0; 2]; 4]),
            corner_errors_px: Some(errors),
            corner_sigma: sigma,
            estimated,
            likelihood: false,
            pose: None,
            read_at_truth: None,
            factors: Default::default(),
        }
    }

    #[test]
    fn known_errors_and_sigmas_give_the_known_share() {
        // Sigma 0.5 px: corners 0.3, 1.0 (exactly 2 sigma: within) and
        // 1.01, 4 px off: 2 of 4 within.
        let mut a = found(
            [0.3, 1.0, 1.01, 4.0],
            Some([0.5; 4]),
            [false, false, true, true],
        );
        a.status = Status::Rough;
        // Read by likelihood, sigma per corner: 3 of 4 within.
        let mut b = found([0.1, 0.9, 2.0, 0.0], Some([0.1, 0.5, 0.9, 0.0]), [false; 4]);
        b.likelihood = true;
        // b alone was drawn with a heavy motion blur (a's is just under).
        let motion = |px| {
            let mut f = crate::draws::Factors::new();
            f.insert("motion_blur_px".into(), crate::draws::FactorValue::Num(px));
            f
        };
        a.factors = motion(crate::wild_scenarios::HEAVY_MOTION_PX - 0.01);
        b.factors = motion(crate::wild_scenarios::HEAVY_MOTION_PX);
        // Missed markers and detections without sigma are not counted.
        let mut missed = found([0.0; 4], Some([1.0; 4]), [false; 4]);
        missed.status = Status::Missed;
        let bare = found([9.0; 4], None, [false; 4]);
        let c = SigmaCoverage::of([&a, &b, &missed, &bare]).unwrap();
        assert_eq!(c.detections, 2);
        assert_eq!(
            c.all,
            Tally {
                corners: 8,
                within: 5
            }
        );
        assert_eq!(c.all.share(), Some(5.0 / 8.0));
        // Estimated corners: a's last two (1.01 and 4 px, both out).
        assert_eq!((c.estimated.corners, c.estimated.within), (2, 0));
        assert_eq!((c.observed.corners, c.observed.within), (6, 5));
        assert_eq!((c.code.corners, c.code.within), (4, 2));
        assert_eq!((c.likelihood.corners, c.likelihood.within), (4, 3));
        assert_eq!((c.smeared.corners, c.smeared.within), (4, 3));
        let line = c.describe();
        assert!(line.contains("motion blur >= 3.6 px 75.0% of 4"), "{line}");
        assert!(line.contains("within 2 sigma: 62.5% of 8"), "{line}");
        assert!(line.contains("estimated 0.0% of 2"), "{line}");
        // Two sets of one system add up.
        let mut both = SigmaCoverage::of([&a]).unwrap();
        both.merge(&SigmaCoverage::of([&b]).unwrap());
        assert_eq!(both, c);
    }

    #[test]
    fn no_sigma_gives_no_share() {
        let bare = found([0.1; 4], None, [false; 4]);
        assert_eq!(SigmaCoverage::of([&bare]), None);
        assert_eq!(SigmaCoverage::of(std::iter::empty()), None);
        // A coverage without estimated corners has no share for them.
        let c = SigmaCoverage::of([&found([0.1; 4], Some([1.0; 4]), [false; 4])]).unwrap();
        assert_eq!(c.estimated.share(), None);
        assert_eq!(c.all.share(), Some(1.0));
        assert!(c.describe().contains("estimated -"), "{}", c.describe());
    }
}

//! The regression gate: a summary compared with a committed baseline.
//!
//! Fails when, for any detector and dataset in the baseline:
//! - the detection rate falls (at all: datasets and detectors are
//!   deterministic, so any drop is a real change);
//! - wrong ids, false positives or duplicates grow;
//! - the median or p95 real-corner error grows by more than
//!   [`Tolerances::corner_px`] or [`Tolerances::corner_fraction`] of its
//!   baseline, whichever is larger;
//! - our time relative to a peer's, measured on the same frames in one
//!   interleaved run ([`crate::speed`]), has grown by more than
//!   [`Tolerances::time_ratio`] beyond doubt: the whole noise band of the
//!   ratio lies above the baseline ratio times `1 + time_ratio`. Absolute
//!   times differ between machines, ratios much less; a band rather than a
//!   point keeps a busy machine from failing unchanged code.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::metrics::Summary;
use crate::speed::{RatioEstimate, SpeedReport};

/// What the gate remembers of one detector on one dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BaselineEntry {
    /// Detection rate.
    pub detection_rate: f64,
    /// Wrong ids.
    pub wrong_ids: usize,
    /// False positives.
    pub false_positives: usize,
    /// Duplicates.
    pub duplicates: usize,
    /// Median real-corner error, px.
    pub corner_median_px: f64,
    /// p95 real-corner error, px.
    pub corner_p95_px: f64,
    /// Median time per image, ms.
    pub time_median_ms: f64,
}

/// A baseline: entries by `detector/dataset`, plus our speed relative to
/// each peer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Baseline {
    /// How the baseline was made.
    pub made_by: String,
    /// Entries by `detector/dataset`.
    pub entries: BTreeMap<String, BaselineEntry>,
    /// Our time over the peer's (median of per-frame ratios, with its
    /// noise band when the baseline was made), by peer name.
    #[serde(default)]
    pub speed_ratio_vs: BTreeMap<String, RatioEstimate>,
}

/// Allowed drift.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Tolerances {
    /// Absolute corner-error growth allowed, px.
    pub corner_px: f64,
    /// Relative corner-error growth allowed.
    pub corner_fraction: f64,
    /// Relative growth of our time ratio to a peer allowed, beyond the
    /// noise band.
    pub time_ratio: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self {
            corner_px: 0.05,
            corner_fraction: 0.10,
            time_ratio: 0.25,
        }
    }
}

fn key(s: &Summary) -> String {
    format!("{}/{}", s.detector, s.dataset)
}

/// A baseline from summaries and, when given, a speed measurement.
pub fn baseline_of(summaries: &[Summary], speed: Option<&SpeedReport>, made_by: &str) -> Baseline {
    Baseline {
        made_by: made_by.into(),
        entries: summaries
            .iter()
            .map(|s| {
                (
                    key(s),
                    BaselineEntry {
                        detection_rate: s.detection_rate,
                        wrong_ids: s.wrong_ids,
                        false_positives: s.false_positives,
                        duplicates: s.duplicates,
                        corner_median_px: s.corner_error_real.median,
                        corner_p95_px: s.corner_error_real.p95,
                        time_median_ms: s.time_ms.median,
                    },
                )
            })
            .collect(),
        speed_ratio_vs: speed
            .map(|r| r.peers.iter().map(|(k, p)| (k.clone(), p.ratio)).collect())
            .unwrap_or_default(),
    }
}

/// Compares summaries with a baseline; returns the failures, one readable
/// line each (empty = pass).
pub fn check(baseline: &Baseline, summaries: &[Summary], tol: Tolerances) -> Vec<String> {
    let now: BTreeMap<String, &Summary> = summaries.iter().map(|s| (key(s), s)).collect();
    let mut fails = Vec::new();
    for (k, b) in &baseline.entries {
        let Some(s) = now.get(k) else {
            fails.push(format!("{k}: missing from this run"));
            continue;
        };
        if s.detection_rate < b.detection_rate - 1e-9 {
            fails.push(format!(
                "{k}: detection rate fell {:.2}% -> {:.2}%",
                100.0 * b.detection_rate,
                100.0 * s.detection_rate
            ));
        }
        for (what, was, is) in [
            ("wrong ids", b.wrong_ids, s.wrong_ids),
            ("false positives", b.false_positives, s.false_positives),
            ("duplicates", b.duplicates, s.duplicates),
        ] {
            if is > was {
                fails.push(format!("{k}: {what} grew {was} -> {is}"));
            }
        }
        for (what, was, is) in [
            (
                "median corner error",
                b.corner_median_px,
                s.corner_error_real.median,
            ),
            ("p95 corner error", b.corner_p95_px, s.corner_error_real.p95),
        ] {
            let allowed = was + tol.corner_px.max(tol.corner_fraction * was);
            if is > allowed {
                fails.push(format!(
                    "{k}: {what} grew {was:.3} -> {is:.3} px (allowed {allowed:.3})"
                ));
            }
        }
    }
    fails
}

/// One peer's speed verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedVerdict {
    /// Peer name.
    pub peer: String,
    /// The baseline's ratio.
    pub was: f64,
    /// This run's ratio and noise band (`None`: not measured).
    pub now: Option<RatioEstimate>,
    /// Largest ratio allowed.
    pub allowed: f64,
    /// Whether the whole band lies above `allowed` (or the peer is missing).
    pub failed: bool,
}

impl std::fmt::Display for SpeedVerdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.now {
            None => write!(f, "time vs {}: not measured in this run", self.peer),
            Some(n) => write!(
                f,
                "time vs {}: our time is {:.3}x the peer's (95% band {:.3}x-{:.3}x), baseline {:.3}x, \
                 fails only if the band lies wholly above {:.3}x: {}",
                self.peer,
                n.median,
                n.low,
                n.high,
                self.was,
                self.allowed,
                if self.failed { "FAILED" } else { "ok" }
            ),
        }
    }
}

/// Compares a speed measurement with the baseline's ratios: a peer fails
/// when the low end of this run's band exceeds the baseline ratio times
/// `1 + tol.time_ratio`, or when it was not measured.
pub fn check_speed(baseline: &Baseline, speed: &SpeedReport, tol: Tolerances) -> Vec<SpeedVerdict> {
    baseline
        .speed_ratio_vs
        .iter()
        .map(|(peer, was)| {
            let allowed = was.median * (1.0 + tol.time_ratio);
            let now = speed.peers.get(peer).map(|p| p.ratio);
            // A NaN band (no frames) fails too: it proves nothing.
            let failed = now.is_none_or(|n| n.low.is_nan() || n.low > allowed);
            SpeedVerdict {
                peer: peer.clone(),
                was: was.median,
                now,
                allowed,
                failed,
            }
        })
        .collect()
}

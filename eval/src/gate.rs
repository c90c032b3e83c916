//! The regression gate: a summary compared with a committed baseline.
//!
//! Fails when, for any detector and dataset in the baseline:
//! - the detection rate falls (at all: datasets and detectors are
//!   deterministic, so any drop is a real change);
//! - wrong ids, false positives or duplicates grow;
//! - the median or p95 real-corner error grows by more than
//!   [`Tolerances::corner_px`] or [`Tolerances::corner_fraction`] of its
//!   baseline, whichever is larger;
//! - our median time per image *relative to a peer measured in the same
//!   run* grows by more than [`Tolerances::time_ratio`] (25%): absolute
//!   times differ between machines, ratios much less.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::metrics::Summary;

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

/// A baseline: entries by `detector/dataset`, plus speed ratios by
/// `coppertag/peer`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Baseline {
    /// How the baseline was made.
    pub made_by: String,
    /// Entries by `detector/dataset`.
    pub entries: BTreeMap<String, BaselineEntry>,
    /// Our median time over the peer's, over all datasets they share a
    /// sweep in, by peer name.
    pub time_ratio_vs: BTreeMap<String, f64>,
}

/// Allowed drift.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Tolerances {
    /// Absolute corner-error growth allowed, px.
    pub corner_px: f64,
    /// Relative corner-error growth allowed.
    pub corner_fraction: f64,
    /// Relative growth of our time ratio to a peer allowed.
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

/// The sweep part of a dataset name (`coppertag-distance-z` -> `distance-z`).
fn sweep(dataset: &str) -> &str {
    dataset.split_once('-').map_or(dataset, |(_, rest)| rest)
}

/// Our median time over each peer's, from summaries of one run: the ratio
/// of the medians of per-dataset medians over the sweeps both ran.
pub fn time_ratios(summaries: &[Summary]) -> BTreeMap<String, f64> {
    let ours: BTreeMap<&str, f64> = summaries
        .iter()
        .filter(|s| s.detector == "coppertag" && s.time_ms.n > 0)
        .map(|s| (sweep(&s.dataset), s.time_ms.median))
        .collect();
    let mut by_peer: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for s in summaries
        .iter()
        .filter(|s| s.detector != "coppertag" && s.time_ms.n > 0)
    {
        if let Some(&o) = ours.get(sweep(&s.dataset)) {
            let e = by_peer.entry(s.detector.clone()).or_default();
            e.0 += o;
            e.1 += s.time_ms.median;
        }
    }
    by_peer
        .into_iter()
        .filter(|(_, (_, p))| *p > 0.0)
        .map(|(k, (o, p))| (k, o / p))
        .collect()
}

/// A baseline from summaries.
pub fn baseline_of(summaries: &[Summary], made_by: &str) -> Baseline {
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
        time_ratio_vs: time_ratios(summaries),
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
    let ratios = time_ratios(summaries);
    for (peer, was) in &baseline.time_ratio_vs {
        match ratios.get(peer) {
            None => fails.push(format!("time vs {peer}: not measured in this run")),
            Some(is) if *is > was * (1.0 + tol.time_ratio) => fails.push(format!(
                "time vs {peer}: our median time is {is:.3}x the peer's, was {was:.3}x (allowed {:.3}x)",
                was * (1.0 + tol.time_ratio)
            )),
            Some(_) => {}
        }
    }
    fails
}

//! The regression gate: a summary compared with a committed baseline.
//!
//! Fails when, for any detector and dataset in the baseline:
//! - the detection rate falls (at all: datasets and detectors are
//!   deterministic, so any drop is a real change);
//! - wrong ids, false positives or duplicates grow;
//! - the median or p95 real-corner error grows by more than
//!   [`Tolerances::corner_px`] or [`Tolerances::corner_fraction`] of its
//!   baseline, whichever is larger;
//! - our time relative to the peers', measured on the same frames in one
//!   interleaved run ([`crate::speed`]), has grown by more than
//!   [`Tolerances::time_ratio`] beyond doubt against most of them: the
//!   median over the peers of the low end of each ratio's noise band over
//!   its baseline ratio exceeds `1 + time_ratio` ([`SpeedCheck`]). Absolute
//!   times differ between machines, ratios much less; a band rather than a
//!   point keeps a busy machine from failing unchanged code, and the
//!   median over peers keeps one peer's own drift from failing it;
//! - for a system with a wild entry (the quick slice of the sampled
//!   "wild" sets, [`crate::wild_summary`]): the slice is not the same
//!   (another count of markers or tag-free images), its detection rate
//!   falls, or its rough detections, wrong ids, false positives on tagged
//!   frames or false positives per megapixel on tag-free frames grow. All
//!   of them are deterministic (same bytes in, same numbers out), so any
//!   change is real and there is no tolerance.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::metrics::Summary;
use crate::speed::{RatioEstimate, SpeedReport};
use crate::wild_summary::{SystemRow, WildSummary};

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
    /// Median time per image, ms, for the record (the gate checks speed
    /// with interleaved runs, [`SpeedCheck`]); `None` when the run's
    /// detector sessions ran side by side (the quick run scores detection
    /// only), whose times say little.
    #[serde(default)]
    pub time_median_ms: Option<f64>,
}

impl BaselineEntry {
    /// The entry of one run's summary.
    fn of(s: &Summary) -> Self {
        Self {
            detection_rate: s.detection_rate,
            wrong_ids: s.wrong_ids,
            false_positives: s.false_positives,
            duplicates: s.duplicates,
            corner_median_px: s.corner_error_real.median,
            corner_p95_px: s.corner_error_real.p95,
            time_median_ms: s.median_ms(),
        }
    }
}

/// What the gate remembers of one system on the wild slice (one row of
/// the wild table).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WildBaselineEntry {
    /// True markers counted (the slice's identity: a changed spec or
    /// slice changes it).
    pub markers: usize,
    /// Tag-free images (likewise).
    pub tag_free_images: usize,
    /// (correct + rough) / markers.
    pub detection_rate: f64,
    /// Rough detections: right id, a corner beyond the match distance.
    pub rough: usize,
    /// Detections of another id on a true marker.
    pub wrong_ids: usize,
    /// False positives on tagged frames.
    pub false_positives_tagged: usize,
    /// False positives per megapixel on tag-free frames (`None` without
    /// them).
    pub false_positives_per_mp: Option<f64>,
}

impl WildBaselineEntry {
    /// The entry of one wild-table row.
    pub fn of(r: &SystemRow) -> Self {
        Self {
            markers: r.markers,
            tag_free_images: r.tag_free_images,
            detection_rate: r.detection_rate,
            rough: r.rough,
            wrong_ids: r.wrong_ids,
            false_positives_tagged: r.false_positives_tagged,
            false_positives_per_mp: r.false_positives_per_mp,
        }
    }
}

/// Systems whose wild figures the gate keeps: the detector this toolkit
/// ships. The peers' wild figures are reported, not gated: a peer's
/// regression is not ours to fail on.
pub const WILD_GATED: &[&str] = &["coppertag"];

/// The key of a system's wild entry.
pub fn wild_key(system: &str) -> String {
    format!("{system}/wild")
}

/// The key of a system's entry for the dense sets
/// ([`crate::wild_summary::DENSE_SUFFIX`]).
pub fn dense_key(system: &str) -> String {
    format!("{system}/dense")
}

/// A baseline: entries by `detector/dataset`, the wild slice's entries by
/// `system/wild`, plus our speed relative to each peer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Baseline {
    /// How the baseline was made.
    pub made_by: String,
    /// Wild-slice entries by `system/wild`, and `system/dense` for the
    /// dense sets (systems in [`WILD_GATED`]).
    /// Written right after `made_by` so that adding them to an existing
    /// file only adds lines.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub wild: BTreeMap<String, WildBaselineEntry>,
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

/// The rows of `w` by their wild-entry key: `system/wild`, and
/// `system/dense` for the dense sets' rows.
fn wild_rows(w: &WildSummary) -> BTreeMap<String, &SystemRow> {
    let dense = w.dense.iter().flat_map(|d| d.systems.iter());
    w.systems
        .iter()
        .map(|r| (wild_key(&r.system), r))
        .chain(dense.map(|r| (dense_key(&r.system), r)))
        .collect()
}

/// The wild entries of the gated systems ([`WILD_GATED`]) in `w`, the
/// dense sets' rows too.
pub fn wild_entries_of(w: &WildSummary) -> BTreeMap<String, WildBaselineEntry> {
    wild_rows(w)
        .into_iter()
        .filter(|(_, r)| WILD_GATED.contains(&r.system.as_str()))
        .map(|(k, r)| (k, WildBaselineEntry::of(r)))
        .collect()
}

/// A baseline from summaries and, when given, a speed measurement and a
/// wild summary.
pub fn baseline_of(
    summaries: &[Summary],
    speed: Option<&SpeedReport>,
    wild: Option<&WildSummary>,
    made_by: &str,
) -> Baseline {
    Baseline {
        made_by: made_by.into(),
        wild: wild.map(wild_entries_of).unwrap_or_default(),
        entries: summaries
            .iter()
            .map(|s| (key(s), BaselineEntry::of(s)))
            .collect(),
        speed_ratio_vs: speed
            .map(|r| r.peers.iter().map(|(k, p)| (k.clone(), p.ratio)).collect())
            .unwrap_or_default(),
    }
}

/// Re-makes every part of `b` that the wild slice decides, keeping the
/// rest as it is, after a deliberate change to the wild specs: the wild
/// entries (from `w`) and the per-dataset entries of the wild slice's
/// datasets ([`WildSummary::all_datasets`]: the sampled scenes, their
/// jitter sets, the dense sets and the tag-free sets), which the sweep
/// check compares exactly too, from `summaries`. A wild dataset's entry
/// the summaries do not have (a run of fewer systems) is left as it was.
/// Returns how many per-dataset entries were written.
pub fn update_wild(b: &mut Baseline, summaries: &[Summary], w: &WildSummary) -> usize {
    b.wild = wild_entries_of(w);
    let mut n = 0;
    for s in summaries {
        if w.all_datasets().any(|d| *d == s.dataset) {
            b.entries.insert(key(s), BaselineEntry::of(s));
            n += 1;
        }
    }
    n
}

/// The exact checks shared by the sweep and wild entries: the detection
/// rate may not fall (beyond float rounding) and no count may grow.
fn exact_checks<const N: usize>(
    fails: &mut Vec<String>,
    k: &str,
    (rate_was, rate_is): (f64, f64),
    counts: [(&str, usize, usize); N],
) {
    if rate_is < rate_was - 1e-9 {
        fails.push(format!(
            "{k}: detection rate fell {:.2}% -> {:.2}%",
            100.0 * rate_was,
            100.0 * rate_is
        ));
    }
    for (what, was, is) in counts {
        if is > was {
            fails.push(format!("{k}: {what} grew {was} -> {is}"));
        }
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
        exact_checks(
            &mut fails,
            k,
            (b.detection_rate, s.detection_rate),
            [
                ("wrong ids", b.wrong_ids, s.wrong_ids),
                ("false positives", b.false_positives, s.false_positives),
                ("duplicates", b.duplicates, s.duplicates),
            ],
        );
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

/// Compares a wild summary with the baseline's wild entries; returns the
/// failures, one readable line each (empty = pass).
pub fn check_wild(baseline: &Baseline, wild: &WildSummary) -> Vec<String> {
    let now = wild_rows(wild);
    let mut fails = Vec::new();
    for (k, b) in &baseline.wild {
        let Some(r) = now.get(k) else {
            fails.push(format!("{k}: missing from this run"));
            continue;
        };
        let n = WildBaselineEntry::of(r);
        if (n.markers, n.tag_free_images) != (b.markers, b.tag_free_images) {
            fails.push(format!(
                "{k}: not the same slice ({} markers and {} tag-free images, baseline {} and {}); \
                 re-make the baseline if the wild specs changed on purpose",
                n.markers, n.tag_free_images, b.markers, b.tag_free_images
            ));
            continue;
        }
        exact_checks(
            &mut fails,
            k,
            (b.detection_rate, n.detection_rate),
            [
                ("rough detections", b.rough, n.rough),
                ("wrong ids", b.wrong_ids, n.wrong_ids),
                (
                    "false positives on tagged frames",
                    b.false_positives_tagged,
                    n.false_positives_tagged,
                ),
            ],
        );
        match (b.false_positives_per_mp, n.false_positives_per_mp) {
            (Some(was), Some(is)) if is > was + 1e-9 => fails.push(format!(
                "{k}: false positives per megapixel grew {was:.4} -> {is:.4}"
            )),
            (Some(_), None) => fails.push(format!("{k}: no tag-free frames in this run")),
            _ => {}
        }
    }
    fails
}

/// One peer's line of the speed check.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedVerdict {
    /// Peer name.
    pub peer: String,
    /// The baseline's ratio.
    pub was: f64,
    /// This run's ratio and noise band (`None`: not measured).
    pub now: Option<RatioEstimate>,
    /// The peer's own limit: the baseline ratio times `1 + time_ratio`.
    pub allowed: f64,
    /// Whether the whole band lies above `allowed` (or the peer is
    /// missing). One peer above its limit does not fail the gate by
    /// itself: see [`SpeedCheck`].
    pub above: bool,
}

impl SpeedVerdict {
    /// This run's ratio over the baseline's, at the low end of the band
    /// (`None`: not measured, or no band).
    fn growth_low(&self) -> Option<f64> {
        self.now.map(|n| n.low / self.was).filter(|g| g.is_finite())
    }
}

impl std::fmt::Display for SpeedVerdict {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.now {
            None => write!(f, "time vs {}: not measured in this run", self.peer),
            Some(n) => write!(
                f,
                "time vs {}: our time is {:.3}x the peer's (95% band {:.3}x-{:.3}x), baseline {:.3}x, \
                 limit {:.3}x: {}",
                self.peer,
                n.median,
                n.low,
                n.high,
                self.was,
                self.allowed,
                if self.above {
                    "band wholly above"
                } else {
                    "ok"
                }
            ),
        }
    }
}

/// The speed half of the gate: every peer's line, and the verdict.
///
/// A slowdown of ours lengthens our time against every peer alike; a
/// change in one peer's own time (its package, how a machine treats its
/// kind of code, the load while it ran) moves that peer's ratio alone, and
/// between runs on unchanged code such moves were larger than any
/// tolerance a real slowdown could be caught with. Measured in two clean
/// clones' CI runs of the same detector, a day apart, against a baseline
/// made on a busy machine: ours over STag's grew 1.13x and then 1.38x
/// (twice, measured again), while ours over AprilTag 3's grew 1.04x and
/// 1.05x and ours over the fractal marker's shrank to 0.84x. So the gate
/// judges the peers together: it fails when the median over the peers of
/// each one's growth at the low end of its band (this run's band's low
/// end over the baseline ratio) exceeds `1 + time_ratio`, that is when
/// our time grew beyond doubt against most peers. With four peers, one
/// peer drifting alone, in either direction, cannot decide it.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedCheck {
    /// One line per peer of the baseline.
    pub peers: Vec<SpeedVerdict>,
    /// Median over the measured peers of [`SpeedVerdict`]'s growth at the
    /// low end of the band (NaN when no peer was measured).
    pub growth_low: f64,
    /// Largest growth allowed: `1 + time_ratio`.
    pub allowed: f64,
    /// Whether the gate fails on speed: the median growth exceeds
    /// `allowed`, or a peer of the baseline was not measured (or measured
    /// on no frames), which proves nothing.
    pub failed: bool,
}

impl std::fmt::Display for SpeedCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let missing: Vec<&str> = self
            .peers
            .iter()
            .filter(|v| v.growth_low().is_none())
            .map(|v| v.peer.as_str())
            .collect();
        write!(
            f,
            "time against the peers: median growth over the baseline {:.3}x at the low end of \
             the bands, fails above {:.3}x",
            self.growth_low, self.allowed
        )?;
        if !missing.is_empty() {
            write!(f, "; not measured: {}", missing.join(", "))?;
        }
        write!(f, ": {}", if self.failed { "FAILED" } else { "ok" })
    }
}

/// Compares a speed measurement with the baseline's ratios (see
/// [`SpeedCheck`]).
pub fn check_speed(baseline: &Baseline, speed: &SpeedReport, tol: Tolerances) -> SpeedCheck {
    let peers: Vec<SpeedVerdict> = baseline
        .speed_ratio_vs
        .iter()
        .map(|(peer, was)| {
            let allowed = was.median * (1.0 + tol.time_ratio);
            let now = speed.peers.get(peer).map(|p| p.ratio);
            let above = now.is_none_or(|n| n.low.is_nan() || n.low > allowed);
            SpeedVerdict {
                peer: peer.clone(),
                was: was.median,
                now,
                allowed,
                above,
            }
        })
        .collect();
    let mut growth: Vec<f64> = peers.iter().filter_map(SpeedVerdict::growth_low).collect();
    let growth_low = crate::speed::median_of(&mut growth);
    let allowed = 1.0 + tol.time_ratio;
    let complete = growth.len() == peers.len();
    let failed = !peers.is_empty() && (!complete || growth_low.is_nan() || growth_low > allowed);
    SpeedCheck {
        peers,
        growth_low,
        allowed,
        failed,
    }
}

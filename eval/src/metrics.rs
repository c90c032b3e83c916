//! Metrics of a run against ground truth.
//!
//! A truth marker counts as found when a detection of the same family and
//! id has every corner within the match distance of the true corner: the
//! larger of [`MatchRule::min_px`] and [`MatchRule::side_fraction`] times
//! the marker's side in pixels (3 px or 5% of the side by default: a tag
//! 48 px wide must be located within 3 px, one 400 px wide within 20 px).
//! Other detections are duplicates (a second match of the same marker),
//! mislocated (right id, a corner too far), wrong ids (another id of the
//! family whose centre lies on a true marker) or false positives (anything
//! else).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::runlog::RunLog;
use crate::truth::{Dataset, TruthMarker};

/// When a detection counts as finding a marker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchRule {
    /// Smallest match distance, pixels.
    pub min_px: f64,
    /// Match distance as a fraction of the marker side.
    pub side_fraction: f64,
}

impl Default for MatchRule {
    fn default() -> Self {
        Self {
            min_px: 3.0,
            side_fraction: 0.05,
        }
    }
}

impl MatchRule {
    /// The match distance for marker `m`, px.
    pub fn tolerance(&self, m: &TruthMarker) -> f64 {
        self.min_px.max(self.side_fraction * m.side_px)
    }
}

/// Order statistics of a sample.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Stats {
    /// Sample size.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub median: f64,
    /// 95th percentile (nearest rank).
    pub p95: f64,
    /// Largest value.
    pub max: f64,
}

impl Stats {
    /// Statistics of `v` (NaN-free); all zeros for an empty sample.
    pub fn of(v: &[f64]) -> Self {
        if v.is_empty() {
            return Self::default();
        }
        let mut s = v.to_vec();
        s.sort_by(f64::total_cmp);
        let rank = |q: f64| s[((q * s.len() as f64).ceil() as usize).clamp(1, s.len()) - 1];
        let median = if s.len() % 2 == 1 {
            s[s.len() / 2]
        } else {
            0.5 * (s[s.len() / 2 - 1] + s[s.len() / 2])
        };
        Self {
            n: s.len(),
            mean: s.iter().sum::<f64>() / s.len() as f64,
            median,
            p95: rank(0.95),
            max: s[s.len() - 1],
        }
    }
}

/// JSON has no NaN: serde_json writes it as null; read null back as NaN.
fn null_as_nan<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

/// What happened to one image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageOutcome {
    /// Image index.
    pub index: usize,
    /// Swept parameter and value (radians or metres) and degrees.
    pub param: String,
    /// Value of the parameter (NaN, written as null, when there is none).
    #[serde(deserialize_with = "null_as_nan")]
    pub value: f64,
    /// Value in degrees for angles.
    pub value_deg: Option<f64>,
    /// Occlusion pattern, scenario and coverage.
    pub occlusion_pattern: String,
    /// Scenario label.
    pub occlusion_scenario: String,
    /// Exact coverage fraction.
    pub occlusion_coverage: f64,
    /// Markers in the image.
    pub markers: usize,
    /// Markers found.
    pub found: usize,
    /// Mean corner error of found markers' real corners, px (NaN, written
    /// as null, if none).
    #[serde(deserialize_with = "null_as_nan")]
    pub corner_error_px: f64,
    /// Detection time, ms.
    pub ms: Option<f64>,
}

/// Metrics of one run on one dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Detector name.
    pub detector: String,
    /// Detector version.
    pub version: String,
    /// Dataset name.
    pub dataset: String,
    /// Marker system of the dataset.
    pub marker: String,
    /// Images.
    pub images: usize,
    /// Images the detector failed to process.
    pub image_errors: usize,
    /// Markers in the ground truth.
    pub markers: usize,
    /// Markers found.
    pub found: usize,
    /// found / markers (1 when there are no markers).
    pub detection_rate: f64,
    /// Detections of another id on a true marker.
    pub wrong_ids: usize,
    /// Detections matching nothing.
    pub false_positives: usize,
    /// Extra detections of an already found marker.
    pub duplicates: usize,
    /// Right id, but a corner beyond the match distance.
    pub mislocated: usize,
    /// Error of real (observed) corners of found markers, px.
    pub corner_error_real: Stats,
    /// Error of estimated corners of found markers, px.
    pub corner_error_estimated: Stats,
    /// Detection time per image, ms.
    pub time_ms: Stats,
    /// CPU use over the run, percent of one core.
    pub cpu_percent: f64,
    /// Peak resident memory, MiB.
    pub peak_memory_mib: f64,
    /// Detector sessions that ran at once ([`crate::runner::RunInfo::sessions`]):
    /// `time_ms` is comparable with other runs only when this is 1.
    #[serde(default = "one_session")]
    pub sessions: usize,
    /// Match rule used.
    pub rule: MatchRule,
    /// Per image outcomes, for figures.
    pub per_image: Vec<ImageOutcome>,
}

fn one_session() -> usize {
    1
}

impl Summary {
    /// The run's median time per image (ms), when it was timed
    /// ([`crate::runner::timed`]): what the reports quote and the gate's
    /// baseline records.
    pub fn median_ms(&self) -> Option<f64> {
        crate::runner::timed(self.sessions).then_some(self.time_ms.median)
    }
}

/// Distance between two points (px).
pub(crate) fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Mean of a quad's four corners: where a detection is matched to a
/// marker (here and in `wild`).
pub(crate) fn centre(c: &[[f64; 2]; 4]) -> [f64; 2] {
    [
        c.iter().map(|p| p[0]).sum::<f64>() / 4.0,
        c.iter().map(|p| p[1]).sum::<f64>() / 4.0,
    ]
}

/// Evaluates a run against its dataset.
pub fn evaluate(run: &RunLog, dataset: &Dataset, rule: MatchRule) -> Summary {
    let mut s = Summary {
        detector: run.info.detector.clone(),
        version: run.info.version.clone(),
        dataset: dataset.name.clone(),
        marker: dataset.marker().to_string(),
        images: run.images.len(),
        image_errors: 0,
        markers: 0,
        found: 0,
        detection_rate: 1.0,
        wrong_ids: 0,
        false_positives: 0,
        duplicates: 0,
        mislocated: 0,
        corner_error_real: Stats::default(),
        corner_error_estimated: Stats::default(),
        time_ms: Stats::default(),
        cpu_percent: 0.0,
        peak_memory_mib: run.resources.peak_rss as f64 / (1u64 << 20) as f64,
        sessions: run.info.sessions,
        rule,
        per_image: Vec::new(),
    };
    if run.resources.wall_s > 0.0 {
        s.cpu_percent = 100.0 * run.resources.cpu_s / run.resources.wall_s;
    }
    let empty = Vec::new();
    let (mut real, mut est, mut times) = (Vec::new(), Vec::new(), Vec::new());
    let by_image: BTreeMap<&str, &crate::runlog::DetectionsMessage> = run
        .images
        .iter()
        .map(|m| (m.result.image.as_str(), m))
        .collect();
    for (index, image) in &dataset.images {
        let truth = dataset.truth.get(image).unwrap_or(&empty);
        s.markers += truth.len();
        let Some(msg) = by_image.get(image.as_str()) else {
            // An image the run never reached counts as an error.
            s.image_errors += 1;
            continue;
        };
        let r = &msg.result;
        if r.error.is_some() {
            s.image_errors += 1;
        }
        if let Some(ms) = r.ms {
            times.push(ms);
        }
        let mut used = vec![false; r.detections.len()];
        let mut found_here = 0;
        let mut errs_here = Vec::new();
        for m in truth {
            let tol = rule.tolerance(m);
            let tc = m.corners();
            let mut matched = false;
            for (k, d) in r.detections.iter().enumerate() {
                if used[k] || d.family != m.family || d.id != m.id {
                    continue;
                }
                let errs: Vec<f64> = (0..4).map(|c| dist(d.corners[c], tc[c])).collect();
                if errs.iter().all(|&e| e <= tol) {
                    used[k] = true;
                    if matched {
                        s.duplicates += 1;
                        continue;
                    }
                    matched = true;
                    for (&e, &estimated) in errs.iter().zip(&d.estimated) {
                        if estimated {
                            est.push(e);
                        } else {
                            real.push(e);
                            errs_here.push(e);
                        }
                    }
                } else if dist(centre(&d.corners), centre(&tc)) < m.side_px {
                    used[k] = true;
                    s.mislocated += 1;
                }
            }
            if matched {
                found_here += 1;
            }
        }
        // What is left: wrong ids on a true marker, or false positives.
        for (k, d) in r.detections.iter().enumerate() {
            if used[k] {
                continue;
            }
            let on_marker = truth
                .iter()
                .any(|m| dist(centre(&d.corners), centre(&m.corners())) < m.side_px / 2.0);
            if on_marker {
                s.wrong_ids += 1;
            } else {
                s.false_positives += 1;
            }
        }
        s.found += found_here;
        let first = truth.first();
        s.per_image.push(ImageOutcome {
            index: *index,
            param: first.map_or(String::new(), |m| m.param.clone()),
            value: first.and_then(|m| m.value).unwrap_or(f64::NAN),
            value_deg: first.and_then(|m| m.value_deg),
            occlusion_pattern: first.map_or(String::new(), |m| m.occlusion_pattern.clone()),
            occlusion_scenario: first.map_or(String::new(), |m| m.occlusion_scenario.clone()),
            occlusion_coverage: first.and_then(|m| m.occlusion_coverage).unwrap_or(0.0),
            markers: truth.len(),
            found: found_here,
            corner_error_px: if errs_here.is_empty() {
                f64::NAN
            } else {
                errs_here.iter().sum::<f64>() / errs_here.len() as f64
            },
            ms: r.ms,
        });
    }
    if s.markers > 0 {
        s.detection_rate = s.found as f64 / s.markers as f64;
    }
    s.corner_error_real = Stats::of(&real);
    s.corner_error_estimated = Stats::of(&est);
    s.time_ms = Stats::of(&times);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_are_order_statistics() {
        let s = Stats::of(&[4.0, 1.0, 3.0, 2.0]);
        assert_eq!((s.n, s.median, s.max, s.mean), (4, 2.5, 4.0, 2.5));
        assert_eq!(
            Stats::of(&(1..=100).map(f64::from).collect::<Vec<_>>()).p95,
            95.0
        );
        assert_eq!(Stats::of(&[]).n, 0);
    }
}

//! The wild benchmark's figures per system, from the marker-by-marker
//! outcomes of [`crate::wild`]: detection and rough rates, wrong ids,
//! false positives per megapixel, pose error, jitter, time, and detection
//! rate against every drawn factor.
//!
//! Jitter: the renders of one scene with fresh sensor noise share a
//! `jitter_group` draw. For each group, marker and system with at least
//! [`JITTER_MIN_RENDERS`] renders found: the spread of each corner (RMS
//! distance from its mean position, with the n - 1 divisor) combined over
//! the four corners as their root mean square; the spread of the estimated
//! translation (mm) likewise; and of the rotation, the RMS angle to the
//! renders' mean rotation (the chordal L2 mean: the sum of the rotation
//! matrices projected back onto SO(3)). The report gives the median over
//! groups. Only the first render of a group counts towards detection, pose,
//! corner-sigma and factor figures, so a scene rendered K times weighs as
//! one.
//!
//! Corner sigma ([`crate::sigma`]): the share of corners of found markers
//! (correct or rough) whose detection reports a one-sigma uncertainty that
//! lie within 2 sigma of the truth, over every tagged set of the system and
//! per set.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::binning::Bins;
use crate::draws::{left_off, FactorValue, JITTER_GROUP};
use crate::metrics::Stats;
use crate::pose_error::{angle_between, rotation_of};
use crate::report::SYSTEMS;
use crate::sigma::SigmaCoverage;
use crate::wild::{MarkerOutcome, Status, WildRun, SIDE_FACTOR};
use crate::wild_scenarios::{plain, scenario_rows, scenarios_csv, ScenarioRow};

/// Fewest found renders of a scene for its jitter to be measured.
pub const JITTER_MIN_RENDERS: usize = 2;

/// Share of markers a size bin must find for the system to "detect" that
/// size (the definition of the minimum detectable size).
pub const MIN_DETECTABLE_RATE: f64 = 0.9;

/// Fewest markers a system must have in a size bin for the bin to count
/// towards its minimum detectable size: a bin of fewer says nothing.
pub const MIN_DETECTABLE_MARKERS: usize = 10;

/// One system's row of the wild table.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SystemRow {
    /// Detector.
    pub system: String,
    /// Images of tagged sets (first renders of jitter groups only).
    pub images: usize,
    /// True markers.
    pub markers: usize,
    /// Found with every corner within the match distance.
    pub correct: usize,
    /// Found with the right id but a corner farther.
    pub rough: usize,
    /// Not found.
    pub missed: usize,
    /// (correct + rough) / markers.
    pub detection_rate: f64,
    /// rough / markers.
    pub rough_rate: f64,
    /// Detections of another id on a true marker.
    pub wrong_ids: usize,
    /// False positives on tagged sets.
    pub false_positives_tagged: usize,
    /// Images of tag-free sets.
    pub tag_free_images: usize,
    /// Their area, megapixels.
    pub tag_free_megapixels: f64,
    /// Detections on them.
    pub tag_free_false_positives: usize,
    /// Those per megapixel; `None` without a tag-free set.
    pub false_positives_per_mp: Option<f64>,
    /// False positives per megapixel of each tag-free set, by dataset
    /// (procedural clutter and natural photographs differ).
    #[serde(default)]
    pub false_positives_per_mp_by_set: BTreeMap<String, f64>,
    /// Translation error, mm, over found markers with a pose.
    pub translation_mm: Stats,
    /// Translation error, % of the true distance.
    pub translation_pct: Stats,
    /// Rotation error, degrees.
    pub rotation_deg: Stats,
    /// Share of those poses that are flipped.
    pub flipped_rate: f64,
    /// Jitter groups measured.
    pub jitter_groups: usize,
    /// Median over groups of the corner spread, px.
    pub jitter_corner_px: Option<f64>,
    /// Median over groups of the translation spread, mm.
    pub jitter_translation_mm: Option<f64>,
    /// Median over groups of the rotation spread, degrees.
    pub jitter_rotation_deg: Option<f64>,
    /// Detection time per image over every wild image, ms.
    pub time_ms: Stats,
    /// The minimum detectable size ([`min_detectable_side`]): the smallest
    /// side-in-pixels bin of the plain markers from which every bin has at
    /// least [`MIN_DETECTABLE_RATE`] found, as (low, high) px.
    pub min_detectable_side_px: Option<(f64, f64)>,
    /// Corners within 2 sigma of the truth, over the counted found markers
    /// of every tagged set whose detection reports a sigma; `None` when the
    /// system reports none (and in summaries written before the figure
    /// existed).
    #[serde(default)]
    pub corner_sigma: Option<SigmaCoverage>,
    /// The same per tagged set, by dataset (the wild set and the jitter
    /// set differ: the latter has no blur).
    #[serde(default)]
    pub corner_sigma_by_set: BTreeMap<String, SigmaCoverage>,
    /// Distance (px) to the true corner of each corner of the found
    /// markers (correct or rough) that the system reports as observed...
    #[serde(default)]
    pub corner_error_observed_px: Stats,
    /// ... and of each it reports as estimated (a hidden corner placed
    /// from the rest of the tag; empty for systems that flag none). The
    /// detector issue bounds the latter's 95th percentile (1.5 px): a
    /// corner a robot cannot see is still one it docks on.
    #[serde(default)]
    pub corner_error_estimated_px: Stats,
}

/// One bin (or category) of one factor for one system.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    /// Detector.
    pub system: String,
    /// Bin number (categories in label order).
    pub bin: usize,
    /// Bin or category as text.
    pub label: String,
    /// Where the bin is drawn (`None` for categories).
    pub centre: Option<f64>,
    /// Markers in the bin.
    pub markers: usize,
    /// Correct ones.
    pub correct: usize,
    /// Rough ones.
    pub rough: usize,
}

impl CurvePoint {
    /// (correct + rough) / markers.
    pub fn rate(&self) -> f64 {
        (self.correct + self.rough) as f64 / self.markers.max(1) as f64
    }
}

/// Detection rate against one factor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FactorCurve {
    /// Factor name, as in `draws.csv`.
    pub factor: String,
    /// Bins of a numeric factor; `None` for a categorical one.
    pub bins: Option<Bins>,
    /// One point per system and bin.
    pub points: Vec<CurvePoint>,
}

/// Everything the wild section reports.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct WildSummary {
    /// Datasets evaluated, by name.
    pub datasets: Vec<String>,
    /// One row per system, in the paper's order.
    pub systems: Vec<SystemRow>,
    /// One curve per factor, by name.
    pub factors: Vec<FactorCurve>,
    /// The scenarios and the main one's breakdown, per system
    /// ([`crate::wild_scenarios`]).
    #[serde(default)]
    pub scenarios: Vec<ScenarioRow>,
    /// The dense sets' figures ([`DENSE_SUFFIX`]), summarised apart: their
    /// 1080p frames of six to ten larger markers are not the wild set's
    /// scenes, and pooled with them they would move every figure above
    /// (rates, times, curves) by how many of each were drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dense: Option<Box<WildSummary>>,
}

/// Datasets whose name ends so are the dense sets
/// (`datasets/wild/*-dense.toml`, the field report's dense frames),
/// summarised apart ([`WildSummary::dense`]).
pub const DENSE_SUFFIX: &str = "-dense";

impl WildSummary {
    /// The CSV files of this summary, by name, and their contents:
    /// `wild-systems.csv`, `wild-factors.csv`, `wild-scenarios.csv`, and
    /// the dense sets' `dense-*.csv` when there are any (what
    /// `coppertag eval --wild` and the report both write).
    pub fn csv_files(&self) -> Vec<(String, String)> {
        let mut files = Vec::new();
        for (prefix, w) in
            std::iter::once(("wild", self)).chain(self.dense.as_deref().map(|d| ("dense", d)))
        {
            files.push((format!("{prefix}-systems.csv"), w.systems_csv()));
            files.push((format!("{prefix}-factors.csv"), w.factors_csv()));
            files.push((
                format!("{prefix}-scenarios.csv"),
                scenarios_csv(&w.scenarios),
            ));
        }
        files
    }

    /// Every dataset evaluated, the dense sets' too.
    pub fn all_datasets(&self) -> impl Iterator<Item = &String> {
        self.datasets
            .iter()
            .chain(self.dense.iter().flat_map(|d| d.datasets.iter()))
    }
}

/// Systems in report order ([`SYSTEMS`]: the paper's four, then the
/// fractal markers), then any others by name.
fn system_order(runs: &[&WildRun]) -> Vec<String> {
    let mut names: Vec<String> = runs.iter().map(|r| r.detector.clone()).collect();
    names.sort();
    names.dedup();
    let rank = |n: &String| SYSTEMS.iter().position(|s| s == n).unwrap_or(SYSTEMS.len());
    names.sort_by_key(|n| (rank(n), n.clone()));
    names
}

/// The outcomes that count towards detection, pose and factor figures:
/// every marker once, the first render of a jitter group standing for the
/// group.
fn counted(run: &WildRun) -> Vec<&MarkerOutcome> {
    let mut first: BTreeMap<(String, usize), usize> = BTreeMap::new();
    for o in &run.outcomes {
        if let Some(g) = o.factors.get(JITTER_GROUP) {
            let e = first.entry((g.label(), o.marker_index)).or_insert(o.index);
            *e = (*e).min(o.index);
        }
    }
    run.outcomes
        .iter()
        .filter(|o| {
            o.factors
                .get(JITTER_GROUP)
                .is_none_or(|g| first[&(g.label(), o.marker_index)] == o.index)
        })
        .collect()
}

fn sample_spread(points: &[Vector3<f64>]) -> f64 {
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    (points
        .iter()
        .map(|p| (p - mean).norm_squared())
        .sum::<f64>()
        / (n - 1.0))
        .sqrt()
}

/// Jitter of one group: (corner px, translation mm, rotation deg).
fn jitter_of(found: &[&MarkerOutcome]) -> Option<(f64, Option<f64>, Option<f64>)> {
    let corners: Vec<&[[f64; 2]; 4]> = found.iter().filter_map(|o| o.corners.as_ref()).collect();
    if corners.len() < JITTER_MIN_RENDERS {
        return None;
    }
    let mut var = 0.0;
    for c in 0..4 {
        let pts: Vec<Vector3<f64>> = corners
            .iter()
            .map(|q| Vector3::new(q[c][0], q[c][1], 0.0))
            .collect();
        var += sample_spread(&pts).powi(2);
    }
    let corner_px = (var / 4.0).sqrt();
    let poses: Vec<_> = found.iter().filter_map(|o| o.pose).collect();
    if poses.len() < JITTER_MIN_RENDERS {
        return Some((corner_px, None, None));
    }
    let t: Vec<Vector3<f64>> = poses
        .iter()
        .map(|p| Vector3::from(p.translation) * 1e3)
        .collect();
    let rots: Vec<Matrix3<f64>> = poses.iter().map(|p| rotation_of(p.rvec)).collect();
    let sum: Matrix3<f64> = rots.iter().sum();
    let svd = sum.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Some((corner_px, Some(sample_spread(&t)), None));
    };
    let d = (u * v_t).determinant().signum();
    let mean = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let ss: f64 = rots.iter().map(|r| angle_between(&mean, r).powi(2)).sum();
    let rot_deg = (ss / (rots.len() as f64 - 1.0)).sqrt().to_degrees();
    Some((corner_px, Some(sample_spread(&t)), Some(rot_deg)))
}

fn median(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| Stats::of(v).median)
}

fn share(n: usize, of: usize) -> f64 {
    if of == 0 {
        0.0
    } else {
        n as f64 / of as f64
    }
}

/// Aggregates wild runs into the report's figures, the dense sets'
/// ([`DENSE_SUFFIX`]) apart in [`WildSummary::dense`].
pub fn summarise(runs: &[WildRun]) -> WildSummary {
    let (dense, wild): (Vec<&WildRun>, Vec<&WildRun>) =
        runs.iter().partition(|r| r.dataset.ends_with(DENSE_SUFFIX));
    let mut w = summarise_set(&wild);
    if !dense.is_empty() {
        w.dense = Some(Box::new(summarise_set(&dense)));
    }
    w
}

/// [`summarise`] of one set of runs.
fn summarise_set(runs: &[&WildRun]) -> WildSummary {
    let systems = system_order(runs);
    let mut datasets: Vec<String> = runs.iter().map(|r| r.dataset.clone()).collect();
    datasets.sort();
    datasets.dedup();
    let curves = factor_curves(runs, &systems);
    let plain_sides = plain_side_curve(runs, &systems);
    let mut rows = Vec::new();
    for sys in &systems {
        let mine: Vec<&WildRun> = runs
            .iter()
            .copied()
            .filter(|r| &r.detector == sys)
            .collect();
        let tagged: Vec<&&WildRun> = mine.iter().filter(|r| !r.tag_free).collect();
        let free: Vec<&&WildRun> = mine.iter().filter(|r| r.tag_free).collect();
        let outcomes: Vec<&MarkerOutcome> = tagged.iter().flat_map(|r| counted(r)).collect();
        let count = |s: Status| outcomes.iter().filter(|o| o.status == s).count();
        let (correct, rough, missed) = (
            count(Status::Correct),
            count(Status::Rough),
            count(Status::Missed),
        );
        let markers = outcomes.len();
        let poses: Vec<_> = outcomes.iter().filter_map(|o| o.pose).collect();
        let pick = |f: fn(&crate::pose_error::PoseError) -> f64| {
            Stats::of(&poses.iter().map(f).collect::<Vec<_>>())
        };
        // Jitter groups: (dataset, group, marker) -> found renders.
        let mut groups: BTreeMap<(String, String, usize), Vec<&MarkerOutcome>> = BTreeMap::new();
        for r in &tagged {
            for o in r.outcomes.iter().filter(|o| o.found()) {
                if let Some(g) = o.factors.get(JITTER_GROUP) {
                    groups
                        .entry((r.dataset.clone(), g.label(), o.marker_index))
                        .or_default()
                        .push(o);
                }
            }
        }
        let (mut jc, mut jt, mut jr) = (Vec::new(), Vec::new(), Vec::new());
        for found in groups.values() {
            if let Some((c, t, r)) = jitter_of(found) {
                jc.push(c);
                jt.extend(t);
                jr.extend(r);
            }
        }
        let times: Vec<f64> = mine
            .iter()
            .flat_map(|r| r.times_ms.iter().copied())
            .collect();
        let corner_sigma_by_set: BTreeMap<String, SigmaCoverage> = {
            let mut by: BTreeMap<String, SigmaCoverage> = BTreeMap::new();
            for r in &tagged {
                if let Some(c) = SigmaCoverage::of(counted(r)) {
                    by.entry(r.dataset.clone()).or_default().merge(&c);
                }
            }
            by
        };
        let corner_sigma = corner_sigma_by_set.values().fold(None, |acc, c| {
            let mut all: SigmaCoverage = acc.unwrap_or_default();
            all.merge(c);
            Some(all)
        });
        let fp_free: usize = free.iter().map(|r| r.false_positives).sum();
        // A fold from +0: a sum of no f64 is -0.0, which the CSV would
        // print as "-0.0000" for a set without tag-free frames.
        let mp_free = free.iter().fold(0.0, |a, r| a + r.megapixels);
        let min_side = plain_sides
            .as_ref()
            .and_then(|c| min_detectable_side(c, sys));
        rows.push(SystemRow {
            system: sys.clone(),
            images: {
                let mut idx: Vec<(String, usize)> = tagged
                    .iter()
                    .flat_map(|r| {
                        counted(r)
                            .into_iter()
                            .map(move |o| (r.dataset.clone(), o.index))
                    })
                    .collect();
                idx.sort();
                idx.dedup();
                idx.len()
            },
            markers,
            correct,
            rough,
            missed,
            detection_rate: share(correct + rough, markers),
            rough_rate: share(rough, markers),
            wrong_ids: tagged.iter().map(|r| r.wrong_ids).sum(),
            false_positives_tagged: tagged.iter().map(|r| r.false_positives).sum(),
            tag_free_images: free.iter().map(|r| r.images).sum(),
            tag_free_megapixels: mp_free,
            tag_free_false_positives: fp_free,
            false_positives_per_mp: (mp_free > 0.0).then(|| fp_free as f64 / mp_free),
            false_positives_per_mp_by_set: {
                let mut by: BTreeMap<String, (usize, f64)> = BTreeMap::new();
                for r in &free {
                    let e = by.entry(r.dataset.clone()).or_default();
                    e.0 += r.false_positives;
                    e.1 += r.megapixels;
                }
                by.into_iter()
                    .filter(|(_, (_, mp))| *mp > 0.0)
                    .map(|(k, (n, mp))| (k, n as f64 / mp))
                    .collect()
            },
            translation_mm: pick(|p| p.translation_mm),
            translation_pct: pick(|p| p.translation_pct),
            rotation_deg: pick(|p| p.rotation_deg),
            flipped_rate: share(poses.iter().filter(|p| p.flipped).count(), poses.len()),
            jitter_groups: jc.len(),
            jitter_corner_px: median(&jc),
            jitter_translation_mm: median(&jt),
            jitter_rotation_deg: median(&jr),
            time_ms: Stats::of(&times),
            min_detectable_side_px: min_side,
            corner_sigma,
            corner_sigma_by_set,
            corner_error_observed_px: corner_errors(&outcomes, false),
            corner_error_estimated_px: corner_errors(&outcomes, true),
        });
    }
    WildSummary {
        datasets,
        systems: rows,
        factors: curves,
        scenarios: scenario_rows(&systems, |sys| {
            runs.iter()
                .copied()
                .filter(|r| r.detector == sys && !r.tag_free)
                .flat_map(counted)
                .collect()
        }),
        dense: None,
    }
}

/// The minimum detectable size of `system` on the plain markers' side
/// curve `sides`: the smallest bin (low, high px) from which every bin
/// with at least [`MIN_DETECTABLE_MARKERS`] of the system's markers finds
/// at least [`MIN_DETECTABLE_RATE`] of them; `None` when the largest such
/// bin does not.
///
/// Why plain markers (no occluder, no glare spot on the marker, sharp:
/// [`crate::wild_scenarios::plain`]): over every marker of the wild set
/// each size bin mixes in occluders, glare and blur up to the drawn
/// maxima, and no system reached the rate in any bin, so the figure the
/// detector issue asks for ("smaller than every peer's at equal printed
/// marker-square size") said nothing. The size a tag can be read down to
/// is a property of the marker and its detector in plain view; the other
/// nuisances have their own rows and curves. Why every larger bin: a
/// system that finds 90% of some small bin by chance but not of a larger
/// one has not shown it detects that size.
fn min_detectable_side(sides: &FactorCurve, system: &str) -> Option<(f64, f64)> {
    let bins = sides.bins.as_ref()?;
    let mine: Vec<&CurvePoint> = sides
        .points
        .iter()
        .filter(|p| p.system == system && p.markers >= MIN_DETECTABLE_MARKERS)
        .collect();
    let from = mine
        .iter()
        .rposition(|p| p.rate() < MIN_DETECTABLE_RATE)
        .map_or(0, |k| k + 1);
    mine.get(from).map(|p| bins.range(p.bin))
}

/// One marker's value of a factor: (system, value, outcome).
type Observation<'a> = (&'a str, &'a FactorValue, Status);

/// Detection rate against every factor any counted marker was drawn with
/// (the jitter group excepted: it names scenes, it is not a condition), a
/// factor whose value can say it was left off ([`left_off`]) over the
/// markers it was applied to.
fn factor_curves(runs: &[&WildRun], systems: &[String]) -> Vec<FactorCurve> {
    let mut by_factor: BTreeMap<&str, Vec<Observation>> = BTreeMap::new();
    for r in runs.iter().filter(|r| !r.tag_free) {
        for o in counted(r) {
            for (f, v) in &o.factors {
                if f != JITTER_GROUP && !left_off(f, v) {
                    by_factor.entry(f.as_str()).or_default().push((
                        r.detector.as_str(),
                        v,
                        o.status,
                    ));
                }
            }
        }
    }
    by_factor
        .into_iter()
        .filter_map(|(factor, obs)| curve(factor, &obs, systems))
        .collect()
}

/// Detection rate against the side in pixels over the counted markers in
/// plain view ([`plain`]), for [`min_detectable_side`].
fn plain_side_curve(runs: &[&WildRun], systems: &[String]) -> Option<FactorCurve> {
    let mut obs: Vec<Observation> = Vec::new();
    for r in runs.iter().filter(|r| !r.tag_free) {
        for o in counted(r).into_iter().filter(|o| plain(o)) {
            if let Some(v) = o.factors.get(SIDE_FACTOR) {
                obs.push((r.detector.as_str(), v, o.status));
            }
        }
    }
    curve(SIDE_FACTOR, &obs, systems)
}

/// The curve of `factor` from its observations `obs`: bins (or
/// categories) and each system's points; `None` for a numeric factor with
/// nothing to bin ([`Bins::of`]).
fn curve(factor: &str, obs: &[Observation], systems: &[String]) -> Option<FactorCurve> {
    let numeric: Option<Vec<f64>> = obs.iter().map(|(_, v, _)| v.as_num()).collect();
    let (bins, labels): (Option<Bins>, Vec<String>) = match &numeric {
        Some(values) => {
            let b = Bins::of(values)?;
            let labels = (0..b.len()).map(|k| b.label(k)).collect();
            (Some(b), labels)
        }
        None => {
            let mut l: Vec<String> = obs.iter().map(|(_, v, _)| v.label()).collect();
            l.sort();
            l.dedup();
            (None, l)
        }
    };
    let mut points = Vec::new();
    for sys in systems {
        let mut cells = vec![(0usize, 0usize, 0usize); labels.len()];
        for (_, v, status) in obs.iter().filter(|(s, _, _)| *s == sys.as_str()) {
            let k = match (&bins, v) {
                (Some(b), FactorValue::Num(x)) => b.index(*x),
                _ => labels.iter().position(|l| *l == v.label()),
            };
            let Some(k) = k else { continue };
            cells[k].0 += 1;
            match status {
                Status::Correct => cells[k].1 += 1,
                Status::Rough => cells[k].2 += 1,
                Status::Missed => {}
            }
        }
        if cells.iter().all(|c| c.0 == 0) {
            continue;
        }
        for (k, (n, correct, rough)) in cells.into_iter().enumerate() {
            points.push(CurvePoint {
                system: sys.clone(),
                bin: k,
                label: labels[k].clone(),
                centre: bins.as_ref().map(|b| b.centre(k)),
                markers: n,
                correct,
                rough,
            });
        }
    }
    Some(FactorCurve {
        factor: factor.to_string(),
        bins,
        points,
    })
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or(String::new(), |x| format!("{x:.digits$}"))
}

/// The corner-sigma columns of `wild-systems.csv`: counts, shares (empty
/// when there is nothing to share), and the overall share per set.
/// Statistics of the corner errors (px) of the found markers among
/// `outcomes`, over the corners reported as `estimated` or as observed.
fn corner_errors(outcomes: &[&MarkerOutcome], estimated: bool) -> Stats {
    let errors: Vec<f64> = outcomes
        .iter()
        .filter(|o| o.found())
        .filter_map(|o| Some((o.corner_errors_px?, o.estimated)))
        .flat_map(|(e, est)| {
            (0..4)
                .filter(move |&k| est[k] == estimated)
                .map(move |k| e[k])
        })
        .collect();
    Stats::of(&errors)
}

/// The corner-error columns of `wild-systems.csv`: count, median and p95
/// of the observed corners, then of the estimated ones (empty without any).
fn corner_error_columns(r: &SystemRow) -> String {
    let cols = |s: &Stats| {
        if s.n == 0 {
            "0,,".to_string()
        } else {
            format!("{},{:.4},{:.4}", s.n, s.median, s.p95)
        }
    };
    format!(
        "{},{}",
        cols(&r.corner_error_observed_px),
        cols(&r.corner_error_estimated_px)
    )
}

fn sigma_columns(r: &SystemRow) -> String {
    let Some(c) = &r.corner_sigma else {
        return ",,,,,,,\"\"".into();
    };
    let by_set: Vec<String> = r
        .corner_sigma_by_set
        .iter()
        .filter_map(|(k, v)| Some(format!("{k}={:.6}", v.all.share()?)))
        .collect();
    format!(
        "{},{},{},{},{},{},{},\"{}\"",
        c.detections,
        c.all.corners,
        opt(c.all.share(), 6),
        opt(c.observed.share(), 6),
        opt(c.estimated.share(), 6),
        opt(c.code.share(), 6),
        opt(c.likelihood.share(), 6),
        by_set.join(";")
    )
}

impl WildSummary {
    /// `wild-systems.csv`: one row per system.
    pub fn systems_csv(&self) -> String {
        let mut s = String::from(
            "system,images,markers,correct,rough,missed,detection_rate,rough_rate,wrong_ids,false_positives_tagged,\
             tag_free_images,tag_free_megapixels,tag_free_false_positives,false_positives_per_mp,\
             pose_n,translation_median_mm,translation_p95_mm,translation_median_pct,translation_p95_pct,\
             rotation_median_deg,rotation_p95_deg,flipped_rate,jitter_groups,jitter_corner_px,\
             jitter_translation_mm,jitter_rotation_deg,time_median_ms,time_p95_ms,time_max_ms,\
             min_detectable_side_lo_px,\
             min_detectable_side_hi_px,false_positives_per_mp_by_set,sigma_detections,sigma_corners,\
             within_2sigma,within_2sigma_observed,within_2sigma_estimated,within_2sigma_code,\
             within_2sigma_likelihood,within_2sigma_by_set,corner_error_observed_n,\
             corner_error_observed_median_px,corner_error_observed_p95_px,corner_error_estimated_n,\
             corner_error_estimated_median_px,corner_error_estimated_p95_px\n",
        );
        for r in &self.systems {
            // Empty time fields for untimed runs (sessions side by side).
            let timed = |v: f64| opt((r.time_ms.n > 0).then_some(v), 4);
            s.push_str(&format!(
                "{},{},{},{},{},{},{:.6},{:.6},{},{},{},{:.4},{},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.6},{},{},{},{},{},{},{},{},{},\"{}\",{},{}\n",
                r.system, r.images, r.markers, r.correct, r.rough, r.missed, r.detection_rate, r.rough_rate,
                r.wrong_ids, r.false_positives_tagged, r.tag_free_images, r.tag_free_megapixels,
                r.tag_free_false_positives, opt(r.false_positives_per_mp, 6), r.translation_mm.n,
                r.translation_mm.median, r.translation_mm.p95, r.translation_pct.median, r.translation_pct.p95,
                r.rotation_deg.median, r.rotation_deg.p95, r.flipped_rate, r.jitter_groups,
                opt(r.jitter_corner_px, 6), opt(r.jitter_translation_mm, 6), opt(r.jitter_rotation_deg, 6),
                timed(r.time_ms.median), timed(r.time_ms.p95), timed(r.time_ms.max),
                opt(r.min_detectable_side_px.map(|m| m.0), 3), opt(r.min_detectable_side_px.map(|m| m.1), 3),
                r.false_positives_per_mp_by_set
                    .iter()
                    .map(|(k, v)| format!("{k}={v:.6}"))
                    .collect::<Vec<_>>()
                    .join(";"),
                sigma_columns(r),
                corner_error_columns(r)
            ));
        }
        s
    }

    /// `wild-factors.csv`: one row per factor, bin and system.
    pub fn factors_csv(&self) -> String {
        let mut s =
            String::from("factor,kind,bin,label,lo,hi,system,markers,correct,rough,found_rate\n");
        for c in &self.factors {
            for p in &c.points {
                let (kind, lo, hi) = match &c.bins {
                    Some(b) => {
                        let (lo, hi) = b.range(p.bin);
                        ("numeric", format!("{lo}"), format!("{hi}"))
                    }
                    None => ("categorical", String::new(), String::new()),
                };
                // Labels may hold commas ("[1, 2)"): quote them.
                s.push_str(&format!(
                    "{},{kind},{},\"{}\",{lo},{hi},{},{},{},{},{:.6}\n",
                    c.factor,
                    p.bin,
                    p.label.replace('"', "\"\""),
                    p.system,
                    p.markers,
                    p.correct,
                    p.rough,
                    p.rate()
                ));
            }
        }
        s
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::draws::Factors;
    use crate::pose_error::PoseError;

    /// Marker 0 of image `index`, with `status` and `factors` and nothing
    /// else measured (also for `wild_scenarios`' tests).
    pub(crate) fn outcome(
        index: usize,
        status: Status,
        factors: &[(&str, FactorValue)],
    ) -> MarkerOutcome {
        MarkerOutcome {
            index,
            marker_index: 0,
            status,
            corner_error_max_px: None,
            corners: None,
            corner_errors_px: None,
            corner_sigma: None,
            estimated: [false; 4],
            likelihood: false,
            pose: None,
            read_at_truth: None,
            factors: factors
                .iter()
                .map(|(k, v)| (k.to_string(), v.clone()))
                .collect::<Factors>(),
        }
    }

    fn run(detector: &str, outcomes: Vec<MarkerOutcome>) -> WildRun {
        WildRun {
            detector: detector.into(),
            dataset: "d".into(),
            images: outcomes.len(),
            image_errors: 0,
            megapixels: 1.0,
            tag_free: false,
            false_positives: 0,
            wrong_ids: 0,
            duplicates: 0,
            times_ms: vec![1.0, 2.0, 3.0],
            outcomes,
        }
    }

    #[test]
    fn jitter_is_the_spread_over_renders_and_a_group_counts_once() {
        let group = [(JITTER_GROUP, FactorValue::Num(5.0))];
        let sq = [[10.0, 10.0], [10.0, 50.0], [50.0, 50.0], [50.0, 10.0]];
        let outcomes: Vec<MarkerOutcome> = [-1.0, 0.0, 1.0]
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                let mut o = outcome(10 + i, Status::Correct, &group);
                o.corners = Some(sq.map(|c| [c[0] + d, c[1]]));
                o.pose = Some(PoseError {
                    translation_mm: 1.0,
                    translation_pct: 0.1,
                    rotation_deg: 0.5,
                    flipped: false,
                    translation: [0.0, 0.0, 1.0 + d * 1e-3],
                    rvec: [0.0, 0.0, d * 0.01],
                });
                o
            })
            .collect();
        let s = summarise(&[run("coppertag", outcomes)]);
        let r = &s.systems[0];
        assert_eq!((r.markers, r.correct, r.jitter_groups), (1, 1, 1));
        assert!((r.jitter_corner_px.unwrap() - 1.0).abs() < 1e-12);
        assert!((r.jitter_translation_mm.unwrap() - 1.0).abs() < 1e-9);
        assert!((r.jitter_rotation_deg.unwrap() - 0.01f64.to_degrees()).abs() < 1e-9);
        assert_eq!(r.time_ms.median, 2.0);
        // One found render is not enough for a spread.
        let mut lone = outcome(20, Status::Correct, &group);
        lone.corners = Some(sq);
        let s = summarise(&[run("coppertag", vec![lone])]);
        assert_eq!(s.systems[0].jitter_groups, 0);
        assert!(s.systems[0].jitter_corner_px.is_none());
    }

    /// Runs without times (sessions side by side) leave the time fields of
    /// `wild-systems.csv` empty rather than 0 ms.
    #[test]
    fn untimed_runs_leave_the_time_fields_empty() {
        let field = |s: &WildSummary, name: &str| -> String {
            let csv = s.systems_csv();
            let mut lines = csv.lines();
            let col = lines
                .next()
                .unwrap()
                .split(',')
                .position(|h| h == name)
                .unwrap();
            lines
                .next()
                .unwrap()
                .split(',')
                .nth(col)
                .unwrap()
                .to_string()
        };
        let timed = summarise(&[run("coppertag", vec![outcome(0, Status::Correct, &[])])]);
        assert_eq!(field(&timed, "time_median_ms"), "2.0000");
        assert_eq!(field(&timed, "time_max_ms"), "3.0000");
        let mut untimed = run("coppertag", vec![outcome(0, Status::Correct, &[])]);
        untimed.times_ms.clear();
        let untimed = summarise(&[untimed]);
        assert_eq!(untimed.systems[0].time_ms.n, 0);
        for name in ["time_median_ms", "time_p95_ms", "time_max_ms"] {
            assert_eq!(field(&untimed, name), "", "{name}");
        }
        assert_eq!(field(&untimed, "correct"), "1");
    }

    #[test]
    fn corner_sigma_over_sets_and_none_without_sigma() {
        let sq = [[10.0, 10.0], [10.0, 50.0], [50.0, 50.0], [50.0, 10.0]];
        let with = |index: usize, errors: [f64; 4], factors: &[(&str, FactorValue)]| {
            let mut o = outcome(index, Status::Correct, factors);
            o.corners = Some(sq);
            o.corner_errors_px = Some(errors);
            o.corner_sigma = Some([0.5; 4]);
            o
        };
        // The wild set: 3 of 4 corners within 1 px, then 4 of 4.
        let wild = run(
            "coppertag",
            vec![with(0, [0.2, 0.4, 0.9, 1.5], &[]), with(1, [0.0; 4], &[])],
        );
        // A jitter group of two renders: only the first counts (0 of 4).
        let group = [(JITTER_GROUP, FactorValue::Num(1.0))];
        let mut jitter = run(
            "coppertag",
            vec![with(5, [2.0; 4], &group), with(6, [0.0; 4], &group)],
        );
        jitter.dataset = "j".into();
        // A peer reporting no sigma: no figure, not 0%.
        let mut peer = run("stag", vec![outcome(0, Status::Correct, &[])]);
        peer.outcomes[0].corners = Some(sq);
        peer.outcomes[0].corner_errors_px = Some([0.1; 4]);
        let s = summarise(&[wild, jitter, peer]);
        let ours = s.systems.iter().find(|r| r.system == "coppertag").unwrap();
        let c = ours.corner_sigma.unwrap();
        assert_eq!((c.detections, c.all.corners, c.all.within), (3, 12, 7));
        assert_eq!(ours.corner_sigma_by_set["d"].all.within, 7);
        assert_eq!(ours.corner_sigma_by_set["j"].all.within, 0);
        let stag = s.systems.iter().find(|r| r.system == "stag").unwrap();
        assert_eq!(stag.corner_sigma, None);
        assert!(stag.corner_sigma_by_set.is_empty());
        let csv = s.systems_csv();
        assert!(csv
            .lines()
            .next()
            .unwrap()
            .contains(",within_2sigma_by_set,corner_error_observed_n,"));
        let row = |sys: &str| {
            csv.lines()
                .find(|l| l.starts_with(sys))
                .unwrap()
                .to_string()
        };
        assert!(
            row("coppertag")
                .contains(",3,12,0.583333,0.583333,,0.583333,,\"d=0.875000;j=0.000000\","),
            "{csv}"
        );
        assert!(row("stag").contains(",,,,,,,\"\","), "{csv}");
        // Every row has as many columns as the header (quoted cells hold
        // no commas here).
        let cols = |l: &str| l.split(',').count();
        assert!(csv
            .lines()
            .all(|l| cols(l) == cols(csv.lines().next().unwrap())));
    }

    #[test]
    fn a_summary_written_before_corner_sigma_still_reads() {
        let s = summarise(&[run("coppertag", vec![outcome(0, Status::Missed, &[])])]);
        let mut v = serde_json::to_value(&s).unwrap();
        let row = v["systems"][0].as_object_mut().unwrap();
        assert!(row.remove("corner_sigma").is_some());
        assert!(row.remove("corner_sigma_by_set").is_some());
        let back: WildSummary = serde_json::from_value(v).unwrap();
        assert_eq!(back.systems[0].corner_sigma, None);
        assert_eq!(back, s);
    }

    /// The corner errors are split by what the system says of each corner,
    /// over found markers only.
    #[test]
    fn corner_errors_split_into_observed_and_estimated() {
        let mut found = outcome(0, Status::Correct, &[]);
        found.corner_errors_px = Some([0.1, 0.2, 1.5, 0.3]);
        found.estimated = [false, false, true, false];
        let mut rough = outcome(1, Status::Rough, &[]);
        rough.corner_errors_px = Some([0.4, 4.0, 2.5, 0.5]);
        rough.estimated = [false, true, true, false];
        // A miss has no corners; one given anyway does not count.
        let mut missed = outcome(2, Status::Missed, &[]);
        missed.corner_errors_px = Some([9.0; 4]);
        missed.estimated = [true; 4];
        let s = summarise(&[run("coppertag", vec![found, rough, missed])]);
        let r = &s.systems[0];
        let (obs, est) = (&r.corner_error_observed_px, &r.corner_error_estimated_px);
        assert_eq!((obs.n, obs.median, obs.max), (5, 0.3, 0.5));
        assert_eq!((est.n, est.max), (3, 4.0));
        assert!(s
            .systems_csv()
            .contains(",5,0.3000,0.5000,3,2.5000,4.0000\n"));
        // A system that flags no corner estimated has no estimated errors.
        let mut plain = outcome(0, Status::Correct, &[]);
        plain.corner_errors_px = Some([0.1; 4]);
        let s = summarise(&[run("apriltag3", vec![plain])]);
        assert_eq!(s.systems[0].corner_error_estimated_px.n, 0);
        assert!(s.systems_csv().ends_with(",4,0.1000,0.1000,0,,\n"));
    }

    /// The minimum detectable size counts only markers in plain view, and
    /// only a bin from which every larger bin reaches the rate.
    #[test]
    fn the_minimum_size_is_measured_in_plain_view_from_a_bin_on() {
        let num = FactorValue::Num;
        // (side px, found, markers, factors beside the side): at 20 px 9
        // of 10 plain markers are found but at 25 px only 8, so 20 px is
        // not detected; from 30 px on every plain bin is. The occluded,
        // glared and blurred markers of 30-40 px, all missed, and a bin of
        // too few markers (50 px, none found) do not count.
        type Case = (f64, usize, usize, Vec<(&'static str, FactorValue)>);
        let cases: [Case; 7] = [
            (20.0, 9, 10, vec![]),
            (25.0, 8, 10, vec![]),
            (30.0, 9, 10, vec![("defocus_px", num(0.2))]),
            (30.0, 0, 10, vec![("occluder_coverage", num(0.1))]),
            (
                35.0,
                0,
                10,
                vec![("glare_peak", num(1.0)), ("glare_marker", num(0.0))],
            ),
            (40.0, 0, 10, vec![("motion_blur_px", num(2.0))]),
            (50.0, 0, MIN_DETECTABLE_MARKERS - 1, vec![]),
        ];
        let mut outcomes = Vec::new();
        for (side, found, n, extra) in &cases {
            for k in 0..*n {
                let status = if k < *found {
                    Status::Correct
                } else {
                    Status::Missed
                };
                let mut f = vec![(SIDE_FACTOR, num(*side))];
                f.extend(extra.iter().cloned());
                outcomes.push(outcome(outcomes.len(), status, &f));
            }
        }
        // 40 px in plain view, all found.
        for _ in 0..10 {
            let f = [(SIDE_FACTOR, num(40.0)), ("motion_blur_px", num(1.0))];
            outcomes.push(outcome(outcomes.len(), Status::Correct, &f));
        }
        let s = summarise(&[run("coppertag", outcomes)]);
        assert_eq!(s.systems[0].min_detectable_side_px, Some((30.0, 30.0)));
        // Over every marker, the 30 and 40 px bins fall under the rate.
        let side = s.factors.iter().find(|c| c.factor == SIDE_FACTOR).unwrap();
        let all_40 = side.points.iter().find(|p| p.label == "40").unwrap();
        assert_eq!((all_40.markers, all_40.correct), (20, 10));
    }

    #[test]
    fn curves_per_factor_and_the_minimum_size() {
        // Side 20 px: 5 of 10 found; 30 px: 9 of 10 (one rough); 40 px: all.
        let mut outcomes = Vec::new();
        for (side, found) in [(20.0, 5), (30.0, 9), (40.0, 10)] {
            for k in 0..10 {
                let status = match k {
                    0 if side == 30.0 => Status::Rough,
                    k if k < found => Status::Correct,
                    _ => Status::Missed,
                };
                let kind = FactorValue::Text(if k % 2 == 0 { "stick" } else { "tape" }.into());
                outcomes.push(outcome(
                    outcomes.len(),
                    status,
                    &[
                        (SIDE_FACTOR, FactorValue::Num(side)),
                        ("occluder_kind", kind),
                    ],
                ));
            }
        }
        let s = summarise(&[
            run("coppertag", outcomes.clone()),
            run("apriltag3", outcomes[..10].to_vec()),
        ]);
        let sys: Vec<&str> = s.systems.iter().map(|r| r.system.as_str()).collect();
        assert_eq!(sys, ["apriltag3", "coppertag"]);
        let ours = &s.systems[1];
        assert_eq!(
            (ours.markers, ours.correct, ours.rough, ours.missed),
            (30, 23, 1, 6)
        );
        assert_eq!(ours.min_detectable_side_px, Some((30.0, 30.0)));
        assert_eq!(s.systems[0].min_detectable_side_px, None);
        let side = s.factors.iter().find(|c| c.factor == SIDE_FACTOR).unwrap();
        assert_eq!(side.bins, Some(Bins::Values(vec![20.0, 30.0, 40.0])));
        let ours_30 = side
            .points
            .iter()
            .find(|p| p.system == "coppertag" && p.bin == 1)
            .unwrap();
        assert_eq!(
            (ours_30.markers, ours_30.correct, ours_30.rough),
            (10, 8, 1)
        );
        let kind = s
            .factors
            .iter()
            .find(|c| c.factor == "occluder_kind")
            .unwrap();
        assert!(kind.bins.is_none());
        let labels: Vec<&str> = kind
            .points
            .iter()
            .filter(|p| p.system == "coppertag")
            .map(|p| p.label.as_str())
            .collect();
        assert_eq!(labels, ["stick", "tape"]);
        assert!(s
            .factors_csv()
            .contains("occluder_kind,categorical,0,\"stick\",,,coppertag,15,"));
    }

    /// A JPEG quality of 0 (no JPEG step) is left out of its curve, where
    /// it would sit below quality 30 as the lowest bin; a defocus of 0 (a
    /// sharp frame) stays in its own.
    #[test]
    fn frames_without_a_jpeg_step_are_not_its_lowest_quality() {
        // Quality 30: 2 of 10 found; 90: 8 of 10; no JPEG step: all 20.
        let mut outcomes = Vec::new();
        for (q, found, n) in [(30.0, 2, 10), (90.0, 8, 10), (0.0, 20, 20)] {
            for k in 0..n {
                let status = if k < found {
                    Status::Correct
                } else {
                    Status::Missed
                };
                outcomes.push(outcome(
                    outcomes.len(),
                    status,
                    &[
                        ("jpeg_quality", FactorValue::Num(q)),
                        (
                            "defocus_px",
                            FactorValue::Num(if q == 0.0 { 0.0 } else { 1.0 }),
                        ),
                    ],
                ));
            }
        }
        let s = summarise(&[run("coppertag", outcomes)]);
        let jpeg = s
            .factors
            .iter()
            .find(|c| c.factor == "jpeg_quality")
            .unwrap();
        assert_eq!(jpeg.bins, Some(Bins::Values(vec![30.0, 90.0])));
        let rates: Vec<(usize, usize)> =
            jpeg.points.iter().map(|p| (p.markers, p.correct)).collect();
        assert_eq!(rates, [(10, 2), (10, 8)]);
        let defocus = s.factors.iter().find(|c| c.factor == "defocus_px").unwrap();
        assert_eq!(defocus.bins, Some(Bins::Values(vec![0.0, 1.0])));
        assert_eq!(defocus.points.iter().map(|p| p.markers).sum::<usize>(), 40);
    }
}

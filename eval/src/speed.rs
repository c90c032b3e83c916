//! Our speed against each peer's, measured so that a busy machine cannot
//! fail the gate and a real slowdown cannot pass it.
//!
//! Comparing the median time of one run with the median of another, taken
//! minutes apart, measures the machine as much as the detectors: on a
//! shared 2-core machine 20-30% swings between runs are normal. So:
//!
//! 1. **Same frames.** For every sweep both systems ran
//!    (`coppertag-<sweep>` and `<peer>-<sweep>` under one work directory,
//!    rendered from the same scenes with each system's marker), up to
//!    [`SpeedOptions::frames_per_sweep`] image indices present in both,
//!    spread evenly over the sweep.
//! 2. **Interleaved.** [`SpeedOptions::reps`] rounds; in each round every
//!    frame is timed with ours and then with the peer, back to back, so a
//!    burst of load lands on both sides of a pair rather than on one run.
//! 3. **Best of the repetitions** per frame and side: for a deterministic
//!    program, the least disturbed run is the best estimate of its cost
//!    (Chen and Revels, "Robust benchmarking in noisy environments", 2016).
//! 4. **Per-frame ratios**, ours over the peer's; their median is the point
//!    estimate.
//! 5. **A noise band from the repetitions themselves**: a bootstrap that
//!    resamples the frames and, within each frame, each side's
//!    repetitions, and takes the 2.5th and 97.5th percentiles of the
//!    resampled medians (Efron and Tibshirani, "An Introduction to the
//!    Bootstrap", 1993, percentile interval). The gate
//!    ([`crate::gate::check_speed`]) judges the peers together: it fails
//!    only when the median over the peers of each band's low end, over
//!    that peer's baseline ratio, exceeds the allowed growth (a slowdown
//!    of ours shows against every peer; one peer's own drift shows
//!    against that peer alone).
//!
//! 6. **A failure is measured twice.** A burst of load that lands on one
//!    side more than the other (a compiler finishing, the page cache
//!    refilling after a build) can still push one measurement's whole band
//!    over the limit on unchanged code. When the check fails,
//!    [`confirm_failures`] measures every peer above its limit once more,
//!    as an independent block, and keeps both:
//!    the gate fails only when the second measurement fails too. A real
//!    slowdown fails both; a one-off blip fails one.
//!
//! The bootstrap draws from a fixed seed, so the same timings give the same
//! report bytes.

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use image::GrayImage;
use rand::{RngExt, SeedableRng};
use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};
use crate::metrics::Stats;
use crate::runner::{self, DetectorSpec};
use crate::truth::Dataset;

/// Share of the bootstrap distribution inside the noise band.
pub const CONFIDENCE: f64 = 0.95;

/// How the measurement is made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedOptions {
    /// Rounds over all frames (each frame is timed this often per side);
    /// at least 2, or there is no noise to estimate.
    pub reps: usize,
    /// Frames taken from each sweep, at most.
    pub frames_per_sweep: usize,
    /// Sweeps to use (for example `distance-z`); empty: every sweep both
    /// systems ran.
    pub sweeps: Vec<String>,
    /// Test-only: ours is made to take this many times as long, by burning
    /// CPU after each detection (1 = no change). Exists to prove that the
    /// gate rejects a real slowdown; recorded in the report.
    pub slowdown: f64,
    /// Bootstrap resamples.
    pub resamples: usize,
    /// Bootstrap seed.
    pub seed: u64,
}

impl Default for SpeedOptions {
    fn default() -> Self {
        Self {
            reps: 5,
            frames_per_sweep: 12,
            sweeps: Vec::new(),
            slowdown: 1.0,
            resamples: 2000,
            seed: 0x5eed,
        }
    }
}

/// Largest accepted [`SpeedOptions::reps`]: beyond it a run takes hours.
const MAX_REPS: usize = 100;
/// Largest accepted [`SpeedOptions::slowdown`].
const MAX_SLOWDOWN: f64 = 10.0;
/// Largest accepted [`SpeedOptions::resamples`].
const MAX_RESAMPLES: usize = 100_000;

impl SpeedOptions {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<()> {
        let bad =
            |name: &'static str, reason: String| Err(EvalError::InvalidParameter { name, reason });
        if !(2..=MAX_REPS).contains(&self.reps) {
            return bad("reps", format!("{} (2 to {MAX_REPS})", self.reps));
        }
        if self.frames_per_sweep == 0 {
            return bad("frames per sweep", "0 (at least 1)".into());
        }
        if !(self.slowdown.is_finite() && (1.0..=MAX_SLOWDOWN).contains(&self.slowdown)) {
            return bad(
                "slowdown",
                format!("{} (1 to {MAX_SLOWDOWN})", self.slowdown),
            );
        }
        if !(100..=MAX_RESAMPLES).contains(&self.resamples) {
            return bad(
                "resamples",
                format!("{} (100 to {MAX_RESAMPLES})", self.resamples),
            );
        }
        Ok(())
    }
}

/// One frame's times, ms, in round order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameTimes {
    /// Sweep name (`distance-z`).
    pub sweep: String,
    /// Image index in both datasets.
    pub index: usize,
    /// Our times.
    pub ours_ms: Vec<f64>,
    /// The peer's times.
    pub peer_ms: Vec<f64>,
}

impl FrameTimes {
    fn best(v: &[f64]) -> f64 {
        v.iter().copied().fold(f64::INFINITY, f64::min)
    }
    /// Our best time, ms.
    pub fn ours_best(&self) -> f64 {
        Self::best(&self.ours_ms)
    }
    /// The peer's best time, ms.
    pub fn peer_best(&self) -> f64 {
        Self::best(&self.peer_ms)
    }
}

/// Our time over the peer's: the median of per-frame ratios and its noise
/// band.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RatioEstimate {
    /// Median over frames of best-ours / best-peer.
    pub median: f64,
    /// Lower end of the [`CONFIDENCE`] bootstrap interval.
    pub low: f64,
    /// Upper end.
    pub high: f64,
}

/// One peer's comparison.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PeerSpeed {
    /// Our best-of-repetitions times over the frames, ms.
    pub ours_ms: Stats,
    /// The peer's, ms.
    pub peer_ms: Stats,
    /// The ratio.
    pub ratio: RatioEstimate,
    /// Every timing, for a later look or a re-estimate.
    pub frames: Vec<FrameTimes>,
}

/// A speed measurement against every peer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpeedReport {
    /// How it was measured.
    pub options: SpeedOptions,
    /// Machine description.
    pub machine: String,
    /// By peer name: the measurement the gate checks (for a peer measured
    /// twice, the second one).
    pub peers: BTreeMap<String, PeerSpeed>,
    /// Peers measured twice ([`confirm_failures`]): their first
    /// measurement, whose whole band lay above the baseline's limit. Kept
    /// so that a report shows every measurement it was made from.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub first_attempts: BTreeMap<String, PeerSpeed>,
}

/// Measures again, when `report` fails the speed check against
/// `baseline` ([`crate::gate::check_speed`]), every peer whose whole band
/// lies above its own limit (those that made it fail):
/// `measure_again(peer)` makes a fresh, independent measurement, which
/// replaces the first in `report.peers`; the first goes to
/// `report.first_attempts`. A report that passes is left alone, even with
/// one peer above its limit: that peer alone cannot fail the gate. Peers
/// missing from the report are not measured (the gate fails them as they
/// are). Returns the peers measured again.
pub fn confirm_failures(
    report: &mut SpeedReport,
    baseline: &crate::gate::Baseline,
    tol: crate::gate::Tolerances,
    mut measure_again: impl FnMut(&str) -> Result<PeerSpeed>,
) -> Result<Vec<String>> {
    let check = crate::gate::check_speed(baseline, report, tol);
    if !check.failed {
        return Ok(Vec::new());
    }
    let failed: Vec<String> = check
        .peers
        .into_iter()
        .filter(|v| v.above && v.now.is_some())
        .map(|v| v.peer)
        .collect();
    for peer in &failed {
        let again = measure_again(peer)?;
        if let Some(first) = report.peers.insert(peer.clone(), again) {
            report.first_attempts.insert(peer.clone(), first);
        }
    }
    Ok(failed)
}

/// Median of `v` (NaN when empty); sorts `v`.
pub(crate) fn median_of(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The ratio estimate of `frames`, with our times multiplied by
/// `scale_ours` (1 for the measurement itself; a saved run scaled by 1.4
/// is what a 40% slowdown would have measured).
pub fn estimate(
    frames: &[FrameTimes],
    resamples: usize,
    seed: u64,
    scale_ours: f64,
) -> RatioEstimate {
    let n = frames.len();
    if n == 0
        || frames
            .iter()
            .any(|f| f.ours_ms.is_empty() || f.peer_ms.is_empty())
    {
        return RatioEstimate {
            median: f64::NAN,
            low: f64::NAN,
            high: f64::NAN,
        };
    }
    let mut ratios: Vec<f64> = frames
        .iter()
        .map(|f| scale_ours * f.ours_best() / f.peer_best())
        .collect();
    let median = median_of(&mut ratios);
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(seed);
    let resample_best = |v: &[f64], rng: &mut rand::rngs::Xoshiro256PlusPlus| {
        (0..v.len())
            .map(|_| v[rng.random_range(0..v.len())])
            .fold(f64::INFINITY, f64::min)
    };
    let mut medians = Vec::with_capacity(resamples);
    let mut sample = vec![0.0; n];
    for _ in 0..resamples {
        for s in &mut sample {
            let f = &frames[rng.random_range(0..n)];
            let o = resample_best(&f.ours_ms, &mut rng);
            let p = resample_best(&f.peer_ms, &mut rng);
            *s = scale_ours * o / p;
        }
        medians.push(median_of(&mut sample));
    }
    medians.sort_by(f64::total_cmp);
    let at = |q: f64| medians[((q * (resamples - 1) as f64).round() as usize).min(resamples - 1)];
    let tail = 0.5 * (1.0 - CONFIDENCE);
    RatioEstimate {
        median,
        low: at(tail),
        high: at(1.0 - tail),
    }
}

/// Summarises one peer's frames.
pub fn peer_speed(frames: Vec<FrameTimes>, options: &SpeedOptions) -> PeerSpeed {
    let ours: Vec<f64> = frames.iter().map(FrameTimes::ours_best).collect();
    let peer: Vec<f64> = frames.iter().map(FrameTimes::peer_best).collect();
    PeerSpeed {
        ours_ms: Stats::of(&ours),
        peer_ms: Stats::of(&peer),
        ratio: estimate(&frames, options.resamples, options.seed, 1.0),
        frames,
    }
}

/// Up to `k` of `v`, evenly spread, first and last included.
fn spread<T: Clone>(v: &[T], k: usize) -> Vec<T> {
    if v.len() <= k {
        return v.to_vec();
    }
    if k == 1 {
        return vec![v[v.len() / 2].clone()];
    }
    (0..k)
        .map(|j| v[j * (v.len() - 1) / (k - 1)].clone())
        .collect()
}

/// A frame to time: our image (decoded once) and the peer's image path.
struct Pair {
    sweep: String,
    index: usize,
    ours: GrayImage,
    peer_image: String,
    peer_path: std::path::PathBuf,
}

/// The sweeps of `datasets` that ours ran, by name (`coppertag-<sweep>`).
fn our_sweeps(datasets: &Path) -> Result<Vec<String>> {
    let mut out: Vec<String> = std::fs::read_dir(datasets)
        .map_err(|e| EvalError::io(datasets, e))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_dir())
        .filter_map(|e| {
            e.file_name()
                .to_string_lossy()
                .strip_prefix("coppertag-")
                .map(str::to_string)
        })
        .collect();
    out.sort();
    Ok(out)
}

fn pairs_for(datasets: &Path, peer: &str, options: &SpeedOptions) -> Result<Vec<Pair>> {
    let wanted = if options.sweeps.is_empty() {
        our_sweeps(datasets)?
    } else {
        options.sweeps.clone()
    };
    let mut pairs = Vec::new();
    for sweep in wanted {
        let ours_dir = datasets.join(format!("coppertag-{sweep}"));
        let peer_dir = datasets.join(format!("{peer}-{sweep}"));
        if !peer_dir.is_dir() {
            if options.sweeps.is_empty() {
                continue;
            }
            return Err(EvalError::bad(
                &peer_dir,
                "no such dataset (was it rendered?)",
            ));
        }
        let ours = Dataset::open(&ours_dir)?;
        let theirs = Dataset::open(&peer_dir)?;
        let peer_by_index: BTreeMap<usize, &String> =
            theirs.images.iter().map(|(i, f)| (*i, f)).collect();
        let common: Vec<(usize, String, String)> = ours
            .images
            .iter()
            .filter_map(|(i, f)| Some((*i, f.clone(), peer_by_index.get(i)?.to_string())))
            .collect();
        for (index, ours_file, peer_file) in spread(&common, options.frames_per_sweep) {
            let path = ours.image_path(&ours_file);
            let img = image::open(&path)
                .map_err(|e| EvalError::bad(&path, format!("cannot read image: {e}")))?
                .to_luma8();
            pairs.push(Pair {
                sweep: sweep.clone(),
                index,
                ours: img,
                peer_path: theirs.image_path(&peer_file),
                peer_image: peer_file,
            });
        }
    }
    if pairs.is_empty() {
        return Err(EvalError::bad(
            datasets,
            format!("no sweep rendered for both coppertag and {peer}"),
        ));
    }
    Ok(pairs)
}

/// Burns CPU until `target_s` seconds have passed since `t0`: a slowdown
/// that loads the machine as real work would.
fn burn_until(t0: Instant, target_s: f64) {
    let mut x = 0u64;
    while t0.elapsed().as_secs_f64() < target_s {
        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
    }
}

/// Measures ours against each of `peers` on the frames rendered under
/// `datasets` (a `coppertag reproduce` work directory's `datasets/`);
/// `progress(done, total)` counts timed frames over all peers.
pub fn measure(
    datasets: &Path,
    ours: &coppertag::detect::DetectorConfig,
    peers: &[DetectorSpec],
    options: &SpeedOptions,
    mut progress: impl FnMut(usize, usize),
) -> Result<SpeedReport> {
    options.validate()?;
    let mut detector =
        coppertag::detect::Detector::new(ours.clone()).map_err(|e| EvalError::Detector {
            detector: "coppertag".into(),
            message: e.to_string(),
        })?;
    let mut plans = Vec::new();
    for peer in peers {
        plans.push((peer, pairs_for(datasets, peer.name(), options)?));
    }
    let total: usize = plans.iter().map(|(_, p)| p.len() * options.reps).sum();
    let mut done = 0;
    let mut out = BTreeMap::new();
    for (peer, pairs) in plans {
        let mut session = runner::start(peer)?;
        let mut times: Vec<(Vec<f64>, Vec<f64>)> = vec![(vec![], vec![]); pairs.len()];
        // One untimed call each, so that first-call costs (page faults,
        // lazy initialisation) are in neither side's numbers.
        let _ = detector.detect(&pairs[0].ours);
        session.detect(&pairs[0].peer_image, &pairs[0].peer_path)?;
        for _ in 0..options.reps {
            for (pair, t) in pairs.iter().zip(&mut times) {
                let t0 = Instant::now();
                let found = detector.detect(&pair.ours);
                let took = t0.elapsed().as_secs_f64();
                if options.slowdown > 1.0 {
                    burn_until(t0, took * options.slowdown);
                }
                let ours_ms = t0.elapsed().as_secs_f64() * 1e3;
                drop(found);
                let r = session.detect(&pair.peer_image, &pair.peer_path)?;
                let peer_ms = match (r.ms, r.error) {
                    (Some(ms), None) if ms.is_finite() && ms > 0.0 => ms,
                    (_, Some(e)) => {
                        return Err(EvalError::Detector {
                            detector: peer.name().into(),
                            message: format!("{}: {e}", pair.peer_path.display()),
                        })
                    }
                    _ => {
                        return Err(EvalError::Detector {
                            detector: peer.name().into(),
                            message: format!("{}: no time reported", pair.peer_path.display()),
                        })
                    }
                };
                t.0.push(ours_ms);
                t.1.push(peer_ms);
                done += 1;
                progress(done, total);
            }
        }
        let frames = pairs
            .iter()
            .zip(times)
            .map(|(p, (o, q))| FrameTimes {
                sweep: p.sweep.clone(),
                index: p.index,
                ours_ms: o,
                peer_ms: q,
            })
            .collect();
        out.insert(peer.name().to_string(), peer_speed(frames, options));
    }
    Ok(SpeedReport {
        options: options.clone(),
        machine: crate::resources::machine(),
        peers: out,
        first_attempts: BTreeMap::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames whose true ratio is `r`, with `noise` relative jitter drawn
    /// from a fixed sequence and occasional 3x outliers (a busy core).
    fn frames(r: f64, n: usize, reps: usize, noise: f64) -> Vec<FrameTimes> {
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(7);
        (0..n)
            .map(|i| {
                let peer = 10.0 + i as f64;
                let mut jitter = |base: f64| -> Vec<f64> {
                    (0..reps)
                        .map(|_| {
                            let busy = if rng.random_range(0.0..1.0) < 0.2 {
                                3.0
                            } else {
                                1.0
                            };
                            base * busy * (1.0 + rng.random_range(0.0..noise))
                        })
                        .collect()
                };
                FrameTimes {
                    sweep: "s".into(),
                    index: i,
                    ours_ms: jitter(peer * r),
                    peer_ms: jitter(peer),
                }
            })
            .collect()
    }

    #[test]
    fn the_band_holds_the_true_ratio_despite_outliers() {
        let f = frames(0.3, 60, 5, 0.05);
        let e = estimate(&f, 2000, 1, 1.0);
        assert!(e.low <= e.median && e.median <= e.high, "{e:?}");
        assert!(e.low < 0.3 * 1.06 && e.high > 0.3 * 0.94, "{e:?}");
        assert!(e.high - e.low < 0.05, "band too wide: {e:?}");
    }

    #[test]
    fn scaling_ours_scales_the_estimate() {
        let f = frames(0.3, 40, 5, 0.05);
        let a = estimate(&f, 500, 3, 1.0);
        let b = estimate(&f, 500, 3, 1.4);
        assert!((b.median / a.median - 1.4).abs() < 1e-9);
        assert!((b.low / a.low - 1.4).abs() < 1e-9);
    }

    #[test]
    fn same_seed_same_estimate() {
        let f = frames(0.5, 30, 4, 0.1);
        assert_eq!(estimate(&f, 300, 9, 1.0), estimate(&f, 300, 9, 1.0));
    }

    #[test]
    fn spread_keeps_ends_and_count() {
        let v: Vec<usize> = (0..26).collect();
        let s = spread(&v, 12);
        assert_eq!(s.len(), 12);
        assert_eq!((s[0], s[11]), (0, 25));
        assert_eq!(spread(&v[..5], 12).len(), 5);
    }

    #[test]
    fn options_out_of_range_are_refused() {
        for o in [
            SpeedOptions {
                reps: 1,
                ..Default::default()
            },
            SpeedOptions {
                frames_per_sweep: 0,
                ..Default::default()
            },
            SpeedOptions {
                slowdown: 0.5,
                ..Default::default()
            },
            SpeedOptions {
                slowdown: f64::NAN,
                ..Default::default()
            },
            SpeedOptions {
                resamples: 10,
                ..Default::default()
            },
        ] {
            assert!(o.validate().is_err(), "{o:?}");
        }
        assert!(SpeedOptions::default().validate().is_ok());
    }
}

//! Detection speed on realistic frames, on one thread and on two: frames
//! like the wild benchmark's (a lit, cluttered background of discs,
//! squares, rings and strokes; one to ten tags of both families at random poses and
//! sizes, some partly hidden; blur and sensor noise), one set at 1080p and
//! one at 4K, rendered from a fixed seed with the test renderer
//! (`tests/common`). The clean one-tag frames of `benches/detect.rs` are a
//! third set, for the per-stage split of the common path.
//!
//! For each set it prints, for a one-thread detector and two of
//! [`THREADS`] threads ([`coppertag::DetectorConfig::threads`]), one with
//! its threads pinned to cores as by default and one with them left to the
//! system ([`coppertag::DetectorConfig::pin_threads`]), timed in the same
//! run, frame by frame in turn, the median, 95th percentile and
//! maximum time per frame (each frame's time is its median over [`ROUNDS`]
//! runs, so one preempted run does not count), the median over frames of
//! every stage's time (from [`coppertag::Detector::stats`]) and the ratios
//! of the one-thread times to the others (it stops if the two detect
//! anything differently), and the machine's own ceiling for that speed-up
//! (as many one-thread detectors run side by side: see [`side_by_side`]);
//! criterion then times the whole set on one thread. Frames are rendered
//! once, before any timing.
//!
//! `cargo bench -p coppertag --bench wild`; set `COPPERTAG_BENCH_ROUNDS`
//! to change the number of runs per frame of the printed summary,
//! `COPPERTAG_BENCH_THREADS` to time another thread count against one
//! (1: the one-thread detector alone), `COPPERTAG_BENCH_FAMILIES` (say
//! `ct14`) to decode only some built-in families (default: the detector's
//! default families),
//! `COPPERTAG_BENCH_SETS` (say `clean_1080p,wild_4k`) to render and time
//! only some sets, `COPPERTAG_BENCH_FRAMES` to a directory to keep the
//! rendered frames there (PNG) and read them back on later runs (under
//! valgrind, rendering costs far more than detecting), and pass a
//! criterion filter that matches nothing (`-- summary-only`) to print the
//! summary alone.

use std::hash::{Hash, Hasher};
use std::time::{Duration, Instant};

use coppertag::{Detector, DetectorConfig, Family, StageTimes};
use criterion::{criterion_group, criterion_main, Criterion, SamplingMode};
use image::GrayImage;

#[path = "../tests/common/mod.rs"]
mod common;

use common::wild::{camera, wild_frame};

/// Seed of every rendered set: the frames are the same on every run.
const SEED: u64 = 0xC0FFEE;
/// Frames of the 1080p set.
const FRAMES_1080P: usize = 16;
/// Frames of the 4K set (each costs four 1080p frames).
const FRAMES_4K: usize = 4;
/// Runs per frame of the printed summary (its median is the frame's time),
/// unless `COPPERTAG_BENCH_ROUNDS` says otherwise.
const ROUNDS: usize = 5;
/// Threads of the detector timed against the one-thread detector, unless
/// `COPPERTAG_BENCH_THREADS` says otherwise (1 times the one-thread
/// detector alone).
const THREADS: usize = 2;

/// A set of frames and the number of tags placed in them.
struct FrameSet {
    name: &'static str,
    frames: Vec<GrayImage>,
    tags: usize,
}

fn wild_set(name: &'static str, height: u32, n: usize, seed: u64) -> FrameSet {
    let cam = camera(height);
    // Frames are rendered on every core, one thread per frame: each has
    // its own seed, so the set is the same however they are scheduled.
    // (Detection is timed afterwards, on one thread.)
    let (frames, counts): (Vec<_>, Vec<_>) = std::thread::scope(|scope| {
        let cam = &cam;
        let jobs: Vec<_> = (0..n)
            .map(|i| {
                scope
                    .spawn(move || cached(name, i, || wild_frame(seed.wrapping_add(i as u64), cam)))
            })
            .collect();
        jobs.into_iter()
            .map(|j| j.join().expect("frame rendered"))
            .unzip()
    });
    FrameSet {
        name,
        frames,
        tags: counts.iter().sum(),
    }
}

/// Frame `i` of set `name` and its number of tags: read from the
/// `COPPERTAG_BENCH_FRAMES` directory when it holds them (`<name>_<i>.png`
/// and `.txt`), else made by `render` (and saved there when the variable
/// is set).
fn cached(name: &str, i: usize, render: impl FnOnce() -> (GrayImage, usize)) -> (GrayImage, usize) {
    let Some(dir) = std::env::var_os("COPPERTAG_BENCH_FRAMES").map(std::path::PathBuf::from) else {
        return render();
    };
    let path = dir.join(format!("{name}_{i:02}"));
    let (png, txt) = (path.with_extension("png"), path.with_extension("txt"));
    let tags = std::fs::read_to_string(&txt)
        .ok()
        .and_then(|t| t.trim().parse().ok());
    if let (Ok(img), Some(tags)) = (image::open(&png), tags) {
        return (img.to_luma8(), tags);
    }
    let (img, tags) = render();
    std::fs::create_dir_all(&dir).expect("frames directory");
    img.save(&png).expect("frame saved");
    std::fs::write(&txt, format!("{tags}\n")).expect("tag count saved");
    (img, tags)
}

/// The clean one-tag frames of `benches/detect.rs`.
fn clean_set() -> FrameSet {
    let r = common::rotation(0.35, -0.25, 0.6);
    let frames = [1.0, 2.8]
        .iter()
        .enumerate()
        .map(|(i, &d)| {
            let scene = common::paper_scene(Family::ct14(), 42, d, &r);
            cached("clean_1080p", i, || (scene.render(), 1)).0
        })
        .collect::<Vec<_>>();
    FrameSet {
        name: "clean_1080p",
        tags: frames.len(),
        frames,
    }
}

/// Median (`q = 0.5`), 95th percentile (`q = 0.95`) and so on of `v`, by
/// the nearest rank.
fn quantile(v: &[Duration], q: f64) -> Duration {
    let mut s = v.to_vec();
    s.sort();
    let rank = ((q * s.len() as f64).ceil() as usize).clamp(1, s.len());
    s[rank - 1]
}

fn ms(d: Duration) -> String {
    format!("{:.2} ms", d.as_secs_f64() * 1e3)
}

/// One detector's times over a set: per frame, every run's stage times.
struct Timed {
    times: Vec<Vec<StageTimes>>,
    found: usize,
    digest: u64,
}

impl Timed {
    /// Per frame, the median over its runs of stage `name`'s time.
    fn stage(&self, name: &str) -> Vec<Duration> {
        self.times
            .iter()
            .map(|runs| {
                let v: Vec<Duration> = runs
                    .iter()
                    .map(|s| {
                        s.iter()
                            .find(|(n, _)| *n == name)
                            .map_or(Duration::ZERO, |(_, t)| t)
                    })
                    .collect();
                quantile(&v, 0.5)
            })
            .collect()
    }
}

/// Runs every frame `rounds` times on each detector of `dets` (round-robin
/// over the set; each frame on every detector in turn, the order turned
/// round every round, so that a busy spell of the machine falls on all of
/// them) and prints, per detector, the per-frame quantiles and the median
/// per-stage split, then the ratios of the first detector's quantiles to
/// the others'. Panics if the detectors disagree on any detection.
fn summary(dets: &mut [(String, Detector)], set: &FrameSet, rounds: usize) {
    let mut runs: Vec<Timed> = dets
        .iter()
        .map(|_| Timed {
            times: vec![Vec::new(); set.frames.len()],
            found: 0,
            digest: 0,
        })
        .collect();
    let mut digests: Vec<_> = dets
        .iter()
        .map(|_| std::collections::hash_map::DefaultHasher::new())
        .collect();
    for round in 0..rounds {
        for (i, frame) in set.frames.iter().enumerate() {
            let n = dets.len();
            for k in 0..n {
                let d = if (round + i) % 2 == 0 { k } else { n - 1 - k };
                let det = &mut dets[d].1;
                let found_here = det.detect(frame);
                if round == 0 {
                    runs[d].found += found_here.len();
                    // Every field, floats in their shortest exact form:
                    // any change of the detector's output shows as a new
                    // digest (the same on every run of one toolchain).
                    format!("{found_here:?}").hash(&mut digests[d]);
                }
                runs[d].times[i].push(det.stats().times);
            }
        }
    }
    for (r, h) in runs.iter_mut().zip(&digests) {
        r.digest = h.finish();
    }
    let quantiles = |r: &Timed| {
        let total = r.stage("total");
        [0.5, 0.95, 1.0].map(|q| quantile(&total, q))
    };
    for ((label, _), r) in dets.iter().zip(&runs) {
        let [med, p95, max] = quantiles(r);
        println!(
            "{} [{label}]: {} frames {}x{}, {} tags placed, {} found (digest {:016x}); per frame over {} runs: median {}, p95 {}, max {}",
            set.name,
            set.frames.len(),
            set.frames[0].width(),
            set.frames[0].height(),
            set.tags,
            r.found,
            r.digest,
            rounds,
            ms(med),
            ms(p95),
            ms(max),
        );
        let split: Vec<String> = StageTimes::default()
            .iter()
            .filter(|(n, _)| *n != "total")
            .map(|(n, _)| format!("{n} {}", ms(quantile(&r.stage(n), 0.5))))
            .collect();
        println!("  stage medians over frames: {}", split.join(", "));
    }
    let base = quantiles(&runs[0]);
    for ((label, _), r) in dets.iter().zip(&runs).skip(1) {
        assert_eq!(
            (r.found, r.digest),
            (runs[0].found, runs[0].digest),
            "{}: [{label}] and [{}] found different tags",
            set.name,
            dets[0].0
        );
        let q = quantiles(r);
        let ratio = |k: usize| base[k].as_secs_f64() / q[k].as_secs_f64().max(1e-12);
        println!(
            "  {} speed-up [{}] / [{label}]: median {:.2}x, p95 {:.2}x, max {:.2}x (same detections)",
            set.name,
            dets[0].0,
            ratio(0),
            ratio(1),
            ratio(2)
        );
    }
}

/// The machine's own ceiling for a speed-up on `n` threads: each frame of
/// `set` timed, round after round, on a one-thread detector alone and
/// on `n` one-thread detectors at once, each on a thread of its own and
/// each started on the frame at the same moment (a barrier). They share
/// nothing but the machine, so how much slower each runs beside the others
/// than alone is what the cores (shared caches, memory, a virtual
/// machine's host) take from any `n`-thread run, however well its work is
/// split: `n` threads can at best be `n / slow-down` times faster than
/// one. Prints the per-frame medians and that bound.
fn side_by_side(set: &FrameSet, n: usize, rounds: usize, make: impl Fn() -> Detector) {
    let mut dets: Vec<Detector> = (0..n).map(|_| make()).collect();
    let frames = set.frames.len();
    let (mut alone, mut together) = (vec![Vec::new(); frames], vec![Vec::new(); frames]);
    // The whole set alone, then the whole set side by side, the order
    // turned round every round: a machine that runs its cores faster while
    // one of them is idle keeps that pace for a while, and would otherwise
    // favour whichever came first. (The time alone is taken here again,
    // not from `summary`'s one-thread run, so that both sides of the
    // ratio see the same spells of the machine.)
    for round in 0..rounds {
        for together_now in [round % 2 == 1, round % 2 == 0] {
            for (i, frame) in set.frames.iter().enumerate() {
                if !together_now {
                    dets[0].detect(frame);
                    alone[i].push(dets[0].stats().times.total);
                    continue;
                }
                let start = std::sync::Barrier::new(n);
                let each: Vec<Duration> = std::thread::scope(|s| {
                    let jobs: Vec<_> = dets
                        .iter_mut()
                        .map(|d| {
                            let start = &start;
                            s.spawn(move || {
                                start.wait();
                                d.detect(frame);
                                d.stats().times.total
                            })
                        })
                        .collect();
                    jobs.into_iter()
                        .map(|j| j.join().expect("detector thread"))
                        .collect()
                });
                // Each detector's time is one measurement under the
                // others' load: their mean is the frame's.
                together[i].push(each.iter().sum::<Duration>() / n as u32);
            }
        }
    }
    let per_frame =
        |v: &[Vec<Duration>]| -> Vec<Duration> { v.iter().map(|r| quantile(r, 0.5)).collect() };
    let (a, t) = (
        quantile(&per_frame(&alone), 0.5),
        quantile(&per_frame(&together), 0.5),
    );
    let slow = t.as_secs_f64() / a.as_secs_f64().max(1e-12);
    println!(
        "  {} side by side: {n} one-thread detectors at once took a median {} per frame each, against {} alone ({slow:.2}x): on this machine now, {n} threads can be at most about {:.2}x faster than one",
        set.name,
        ms(t),
        ms(a),
        n as f64 / slow
    );
}

fn bench(c: &mut Criterion) {
    let t0 = Instant::now();
    let only = std::env::var("COPPERTAG_BENCH_SETS").ok();
    let wanted = |name: &str| {
        only.as_ref()
            .is_none_or(|o| o.split(',').any(|n| n == name))
    };
    let mut sets = Vec::new();
    if wanted("clean_1080p") {
        sets.push(clean_set());
    }
    if wanted("wild_1080p") {
        sets.push(wild_set("wild_1080p", 1080, FRAMES_1080P, SEED));
    }
    if wanted("wild_4k") {
        sets.push(wild_set("wild_4k", 2160, FRAMES_4K, SEED ^ 0x4B));
    }
    println!("frames rendered in {:.1} s", t0.elapsed().as_secs_f64());
    let rounds = std::env::var("COPPERTAG_BENCH_ROUNDS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(ROUNDS)
        .max(1);
    let threads = std::env::var("COPPERTAG_BENCH_THREADS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(THREADS);
    let families = std::env::var("COPPERTAG_BENCH_FAMILIES").ok();
    let detector = |threads: usize, pin_threads: bool| {
        let label = format!(
            "{threads} thread{}{}",
            if threads == 1 { "" } else { "s" },
            if threads > 1 && !pin_threads {
                ", unpinned"
            } else {
                ""
            }
        );
        let base = match &families {
            Some(f) => {
                let names: Vec<&str> = f.split(',').collect();
                DetectorConfig::with_builtin_families(&names)
                    .unwrap_or_else(|e| panic!("COPPERTAG_BENCH_FAMILIES={f}: {e}"))
            }
            None => DetectorConfig::default(),
        };
        let cfg = DetectorConfig {
            threads,
            pin_threads,
            ..base
        };
        (label, Detector::new(cfg).unwrap())
    };
    let mut dets = vec![detector(1, false)];
    if threads != 1 {
        dets.push(detector(threads, true));
        dets.push(detector(threads, false));
    }
    for set in &sets {
        summary(&mut dets, set, rounds);
        if threads > 1 {
            side_by_side(set, threads, rounds, || detector(1, false).1);
        }
    }
    let mut det = dets.swap_remove(0).1;
    let mut group = c.benchmark_group("wild");
    // A sample is a whole set (a third of a second and more): flat
    // sampling, ten of them, keeps the run under a minute.
    group.sample_size(10).sampling_mode(SamplingMode::Flat);
    for set in sets.iter().filter(|s| s.name != "clean_1080p") {
        group.bench_function(format!("{}_set_of_{}", set.name, set.frames.len()), |b| {
            b.iter(|| {
                for f in &set.frames {
                    det.detect(std::hint::black_box(f));
                }
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Detection speed on realistic frames, single-threaded: frames like the
//! wild benchmark's (a lit, cluttered background of discs, squares, rings
//! and strokes; one to ten tags of both families at random poses and
//! sizes, some partly hidden; blur and sensor noise), one set at 1080p and
//! one at 4K, rendered from a fixed seed with the test renderer
//! (`tests/common`). The clean one-tag frames of `benches/detect.rs` are a
//! third set, for the per-stage split of the common path.
//!
//! For each set it prints the median, 95th percentile and maximum time per
//! frame (each frame's time is its median over [`ROUNDS`] runs, so one
//! preempted run does not count) and the median over frames of every
//! stage's time (from [`coppertag::Detector::stats`]); criterion then times
//! the whole set. Frames are rendered once, before any timing.
//!
//! `cargo bench -p coppertag --bench wild`; set `COPPERTAG_BENCH_ROUNDS`
//! to change the number of runs per frame of the printed summary,
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

use common::{in_poly, Camera, Occluder, Rng, Scene, SCENARIOS};

/// Seed of every rendered set: the frames are the same on every run.
const SEED: u64 = 0xC0FFEE;
/// Frames of the 1080p set.
const FRAMES_1080P: usize = 16;
/// Frames of the 4K set (each costs four 1080p frames).
const FRAMES_4K: usize = 4;
/// Runs per frame of the printed summary (its median is the frame's time),
/// unless `COPPERTAG_BENCH_ROUNDS` says otherwise.
const ROUNDS: usize = 5;
/// Most tags in a frame (at least one).
const MAX_TAGS: u64 = 10;
/// Shortest and longest data-square side of a tag, in pixels per 1080
/// lines of image height (the wild set's range, from barely decodable to
/// a quarter of the frame).
const TAG_SIDE_PX: (f64, f64) = (22.0, 260.0);
/// Background shapes per frame: at least `CLUTTER.0`, plus up to
/// `CLUTTER.1` more.
const CLUTTER: (u64, u64) = (30, 60);
/// Chance that a tag is partly hidden by one of the paper's occluders,
/// and the fraction of its data square hidden then.
const OCCLUDED: f64 = 0.3;
const OCCLUDED_FRAC: (f64, f64) = (0.05, 0.2);
/// Gaussian blur sigma (px at 1080p) and noise sigma (grey levels) ranges.
const BLUR: (f64, f64) = (0.4, 1.4);
const NOISE: (f64, f64) = (1.0, 4.0);
/// Tries to place a tag clear of the tags already placed.
const PLACE_TRIES: usize = 20;

/// A set of frames and the number of tags placed in them.
struct FrameSet {
    name: &'static str,
    frames: Vec<GrayImage>,
    tags: usize,
}

/// The paper's camera scaled to `height` lines (same field of view).
fn camera(height: u32) -> Camera {
    let k = f64::from(height) / f64::from(common::CAMERA.height);
    Camera {
        width: (f64::from(common::CAMERA.width) * k).round() as u32,
        height,
        f: common::CAMERA.f * k,
    }
}

/// Fills polygon `poly` (pixels) with grey `v`, pixel centres inside.
fn fill(img: &mut GrayImage, poly: &[[f64; 2]], v: u8) {
    let (w, h) = (f64::from(img.width()), f64::from(img.height()));
    let (mut x0, mut y0, mut x1, mut y1) = (w, h, 0.0f64, 0.0f64);
    for p in poly {
        x0 = x0.min(p[0]);
        y0 = y0.min(p[1]);
        x1 = x1.max(p[0]);
        y1 = y1.max(p[1]);
    }
    let (xa, ya) = (x0.max(0.0) as u32, y0.max(0.0) as u32);
    let (xb, yb) = (x1.min(w - 1.0) as u32, y1.min(h - 1.0) as u32);
    for y in ya..=yb {
        for x in xa..=xb {
            if in_poly(poly, [f64::from(x), f64::from(y)]) {
                img.put_pixel(x, y, image::Luma([v]));
            }
        }
    }
}

/// A regular `n`-gon of radius `r` around `c`, squashed by `skew` along
/// its turned y axis.
fn polygon(c: [f64; 2], r: f64, n: usize, turn: f64, skew: f64) -> Vec<[f64; 2]> {
    (0..n)
        .map(|k| {
            let t = k as f64 / n as f64 * std::f64::consts::TAU + std::f64::consts::FRAC_PI_4;
            let (x, y) = (r * t.cos(), r * t.sin() * skew);
            [
                c[0] + x * turn.cos() - y * turn.sin(),
                c[1] + x * turn.sin() + y * turn.cos(),
            ]
        })
        .collect()
}

/// A lit background (a linear gradient) with clutter: discs, squares,
/// rings (a disc with a lighter disc inside) and thin strokes.
fn background(rng: &mut Rng, w: u32, h: u32) -> GrayImage {
    let base = rng.range(70.0, 180.0);
    let (gx, gy) = (rng.range(-60.0, 60.0), rng.range(-60.0, 60.0));
    let mut img = GrayImage::from_fn(w, h, |x, y| {
        let v = base + gx * f64::from(x) / f64::from(w) + gy * f64::from(y) / f64::from(h);
        image::Luma([v.clamp(0.0, 255.0) as u8])
    });
    let scale = f64::from(h) / 1080.0;
    let n = CLUTTER.0 + rng.next_u64() % (CLUTTER.1 + 1);
    for _ in 0..n {
        let c = [rng.range(0.0, f64::from(w)), rng.range(0.0, f64::from(h))];
        let r = rng.range(6.0, 160.0) * scale;
        let dark = rng.range(0.0, 90.0) as u8;
        let light = rng.range(160.0, 255.0) as u8;
        let grey = if rng.uniform() < 0.5 { dark } else { light };
        let (turn, skew) = (rng.range(0.0, 6.3), rng.range(0.3, 1.0));
        match rng.next_u64() % 4 {
            0 => fill(&mut img, &polygon(c, r, 48, turn, skew), grey),
            1 => fill(&mut img, &polygon(c, r, 4, turn, skew), grey),
            2 => {
                fill(&mut img, &polygon(c, r, 48, turn, skew), dark);
                fill(&mut img, &polygon(c, 0.6 * r, 48, turn, skew), light);
            }
            _ => {
                let t = rng.range(1.5, 6.0) * scale;
                fill(&mut img, &polygon(c, r, 4, turn, t / r), grey);
            }
        }
    }
    img
}

/// A random pose of a tag in `cam`'s view, or `None` when its bounding box
/// would meet one in `taken` (pixels, grown by a margin).
fn place(rng: &mut Rng, cam: &Camera, taken: &[[f64; 4]]) -> Option<(Scene, [f64; 4])> {
    let k = f64::from(cam.height) / 1080.0;
    // log-uniform size: as many small tags as large ones.
    let side = (rng.range(TAG_SIDE_PX.0.ln(), TAG_SIDE_PX.1.ln())).exp() * k;
    let d = cam.f * common::TAG_SIDE_M / side;
    let (u, v) = (
        rng.range(0.1, 0.9) * f64::from(cam.width),
        rng.range(0.1, 0.9) * f64::from(cam.height),
    );
    let t = [(u - cam.cx()) * d / cam.f, (v - cam.cy()) * d / cam.f, d];
    let r = common::rotation(
        rng.range(-0.7, 0.7),
        rng.range(-0.7, 0.7),
        rng.range(-3.1, 3.1),
    );
    let family = if rng.uniform() < 0.5 {
        Family::ct14()
    } else {
        Family::ct8()
    };
    let span = family.max_id() - family.min_id() + 1;
    let id = family.min_id() + rng.next_u64() % span;
    let h = cam.homography(&r, t, common::TAG_SIDE_M);
    let mut s = Scene::new(family, id, cam.width, cam.height, h);
    let outline = [[-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0], [1.0, -1.0]];
    let mut bb = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
    for p in outline {
        let q = s.h.map(p)?;
        bb = [
            bb[0].min(q[0]),
            bb[1].min(q[1]),
            bb[2].max(q[0]),
            bb[3].max(q[1]),
        ];
    }
    let margin = 0.2 * side;
    let clear = |o: &[f64; 4]| {
        bb[2] + margin < o[0]
            || o[2] + margin < bb[0]
            || bb[3] + margin < o[1]
            || o[3] + margin < bb[1]
    };
    if !taken.iter().all(clear) {
        return None;
    }
    s.white = rng.range(170.0, 250.0) as u8;
    s.black = rng.range(5.0, 70.0) as u8;
    if rng.uniform() < OCCLUDED {
        let kind = SCENARIOS[(rng.next_u64() % SCENARIOS.len() as u64) as usize];
        let frac = rng.range(OCCLUDED_FRAC.0, OCCLUDED_FRAC.1);
        let turn = (rng.next_u64() % 4) as u32;
        let grey = rng.range(0.0, 255.0) as u8;
        s.occluders = common::occluders(kind, frac, turn, rng.uniform())
            .into_iter()
            .map(|poly| Occluder { poly, grey })
            .collect();
    }
    Some((s, bb))
}

/// One wild-like frame from `cam` and its number of tags.
fn wild_frame(seed: u64, cam: &Camera) -> (GrayImage, usize) {
    let mut rng = Rng::new(seed);
    let mut img = background(&mut rng, cam.width, cam.height);
    let want = 1 + rng.next_u64() % MAX_TAGS;
    let mut taken = Vec::new();
    for _ in 0..want {
        let placed = (0..PLACE_TRIES).find_map(|_| place(&mut rng, cam, &taken));
        if let Some((scene, bb)) = placed {
            scene.paint(&mut img);
            taken.push(bb);
        }
    }
    let k = f64::from(cam.height) / 1080.0;
    let blur = rng.range(BLUR.0, BLUR.1) * k;
    let mut img = imageproc::filter::gaussian_blur_f32(&img, blur as f32);
    let noise = rng.range(NOISE.0, NOISE.1);
    for p in img.pixels_mut() {
        let v = f64::from(p.0[0]) + rng.gauss() * noise;
        p.0[0] = v.round().clamp(0.0, 255.0) as u8;
    }
    (img, taken.len())
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

/// Runs every frame `rounds` times (round-robin over the set) and prints
/// the per-frame quantiles and the median per-stage split.
fn summary(det: &mut Detector, set: &FrameSet, rounds: usize) {
    let mut times: Vec<Vec<StageTimes>> = vec![Vec::new(); set.frames.len()];
    let mut found = 0;
    let mut digest = std::collections::hash_map::DefaultHasher::new();
    for round in 0..rounds {
        for (frame, t) in set.frames.iter().zip(&mut times) {
            let found_here = det.detect(frame);
            if round == 0 {
                found += found_here.len();
                // Every field, floats in their shortest exact form: any
                // change of the detector's output shows as a new digest
                // (the same on every run of one toolchain).
                format!("{found_here:?}").hash(&mut digest);
            }
            t.push(det.stats().times);
        }
    }
    let stage = |name: &str| -> Vec<Duration> {
        times
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
    };
    let total = stage("total");
    println!(
        "{}: {} frames {}x{}, {} tags placed, {} found (digest {:016x}); per frame over {} runs: median {}, p95 {}, max {}",
        set.name,
        set.frames.len(),
        set.frames[0].width(),
        set.frames[0].height(),
        set.tags,
        found,
        digest.finish(),
        rounds,
        ms(quantile(&total, 0.5)),
        ms(quantile(&total, 0.95)),
        ms(quantile(&total, 1.0)),
    );
    let split: Vec<String> = StageTimes::default()
        .iter()
        .filter(|(n, _)| *n != "total")
        .map(|(n, _)| format!("{n} {}", ms(quantile(&stage(n), 0.5))))
        .collect();
    println!("  stage medians over frames: {}", split.join(", "));
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
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    for set in &sets {
        summary(&mut det, set, rounds);
    }
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

//! Detection speed on a 1920 x 1080 frame with one tag (the paper's camera,
//! tag at 1 m and at 2.8 m, slightly tilted), single-threaded: the whole
//! frame, then every pipeline stage on its own (criterion times each stage
//! with the detector's own stage clock, [`coppertag::StageTimes`], summed
//! over the iterations criterion asks for).
//!
//! `cargo bench -p coppertag --bench detect`

use std::time::Duration;

use coppertag::{Detector, DetectorConfig, Family};
use criterion::{criterion_group, criterion_main, Criterion};
use image::GrayImage;

#[path = "../tests/common/mod.rs"]
mod common;

fn frame(d: f64) -> (GrayImage, [[f64; 2]; 4]) {
    let r = common::rotation(0.35, -0.25, 0.6);
    let s = common::paper_scene(Family::ct14(), 42, d, &r);
    let truth = s.corners();
    (s.render(), truth)
}

fn bench(c: &mut Criterion) {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    // `make bench-python` times the Python binding on the very same frames.
    let save_to = std::env::var_os("COPPERTAG_BENCH_FRAMES").map(std::path::PathBuf::from);
    for d in [1.0, 2.8] {
        let (img, truth) = frame(d);
        if let Some(dir) = &save_to {
            std::fs::create_dir_all(dir).expect("frames directory");
            img.save(dir.join(format!("detect_1080p_one_tag_{d}m.png")))
                .expect("frame saved");
        }
        let found = det.detect(&img);
        assert_eq!(
            found.len(),
            1,
            "the benchmark frame must hold one detectable tag"
        );
        let err = found[0]
            .corners
            .iter()
            .zip(&truth)
            .map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]))
            .fold(0.0, f64::max);
        println!("tag at {d} m: largest corner error {err:.3} px");
        c.bench_function(&format!("detect_1080p_one_tag_{d}m"), |b| {
            b.iter(|| det.detect(std::hint::black_box(&img)))
        });
        let mut group = c.benchmark_group(format!("stage_1080p_one_tag_{d}m"));
        // Only the stages this frame spends time in: `downsample` is done
        // inside the threshold's pass, and `small` has nothing to look at
        // around a large tag; criterion refuses a stage that takes no time.
        det.detect(&img);
        let busy: Vec<&str> = det
            .stats()
            .times
            .iter()
            .filter(|(_, t)| !t.is_zero())
            .map(|(name, _)| name)
            .collect();
        for stage in busy {
            group.bench_function(stage, |b| {
                b.iter_custom(|iters| {
                    let mut sum = Duration::ZERO;
                    for _ in 0..iters {
                        det.detect(std::hint::black_box(&img));
                        sum += det
                            .stats()
                            .times
                            .iter()
                            .find(|(name, _)| *name == stage)
                            .map_or(Duration::ZERO, |(_, t)| t);
                    }
                    sum
                })
            });
        }
        group.finish();
        println!("  stats: {:?}", det.stats());
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);

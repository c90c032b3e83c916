//! Detection speed on a 1920 x 1080 frame with one tag (the paper's camera,
//! tag at 1 m, slightly tilted), single-threaded. Prints the median time of
//! every pipeline stage after the criterion runs.
//!
//! `cargo bench -p coppertag --bench detect`

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
    for d in [1.0, 2.8] {
        let (img, truth) = frame(d);
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
        // Per-stage medians over repeated runs.
        let mut runs: Vec<coppertag::StageTimes> = (0..200)
            .map(|_| {
                det.detect(&img);
                det.stats().times
            })
            .collect();
        let med = |f: &dyn Fn(&coppertag::StageTimes) -> f64,
                   runs: &mut Vec<coppertag::StageTimes>| {
            let mut v: Vec<f64> = runs.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        println!("per-stage median ms at {d} m:");
        type Field = (&'static str, fn(&coppertag::StageTimes) -> f64);
        let fields: [Field; 9] = [
            ("downsample", |t| t.downsample_ms),
            ("threshold", |t| t.threshold_ms),
            ("contours", |t| t.contours_ms),
            ("lines", |t| t.lines_ms),
            ("corners", |t| t.corners_ms),
            ("ellipses", |t| t.ellipses_ms),
            ("quads", |t| t.quads_ms),
            ("refine+decode", |t| t.decode_ms),
            ("total", |t| t.total_ms),
        ];
        for (name, f) in fields {
            println!("  {name:>14}: {:.3}", med(&f, &mut runs));
        }
        println!("  stats: {:?}", det.stats());
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);

//! Criterion benchmarks of dataset rendering at the paper's 1920 x 1080.
//!
//!     cargo bench -p coppertag-synth --bench synth
//!
//! - `render/*`: one image, scene to 8-bit pixels (no files);
//! - `png_encode`: PNG encoding of one rendered image;
//! - `dataset/*`: whole datasets written to disk, PNG + truth.csv +
//!   dataset.json + MCAP, reported in images per second (throughput).

use std::hint::black_box;
use std::path::{Path, PathBuf};

use coppertag_synth::coverage::Rasterizer;
use coppertag_synth::dataset::encode_png;
use coppertag_synth::{generate, DatasetSpec, GenerateOptions};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

fn paper(name: &str) -> DatasetSpec {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../datasets/paper")
        .join(format!("{name}.toml"));
    DatasetSpec::load(&path).expect("paper spec loads")
}

fn examples(name: &str) -> DatasetSpec {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../datasets/examples")
        .join(format!("{name}.toml"));
    DatasetSpec::load(&path).expect("example spec loads")
}

fn render(c: &mut Criterion) {
    let mut g = c.benchmark_group("render");
    g.sample_size(20);
    let near = paper("coppertag-distance-z");
    // z = 0.30 m (the largest marker, 910 px) and 1.0 m.
    for (label, index) in [("coppertag-z0.30", 0usize), ("coppertag-z1.00", 70)] {
        let scene = near.scene(index).unwrap();
        let mut r = Rasterizer::new();
        g.bench_function(label, |b| {
            b.iter(|| black_box(scene.render(&mut r).unwrap()))
        });
    }
    let stag = paper("stag-rotated-y");
    let scene = stag.scene(20).unwrap();
    let mut r = Rasterizer::new();
    g.bench_function("stag-ry-50deg", |b| {
        b.iter(|| black_box(scene.render(&mut r).unwrap()))
    });
    let busy = examples("robustness");
    let scene = busy.scene(0).unwrap();
    let mut r = Rasterizer::new();
    g.bench_function("robustness-example", |b| {
        b.iter(|| black_box(scene.render(&mut r).unwrap()))
    });
    g.finish();

    let img = near
        .scene(70)
        .unwrap()
        .render(&mut Rasterizer::new())
        .unwrap()
        .image;
    c.bench_function("png_encode", |b| {
        b.iter(|| black_box(encode_png(&img).unwrap()))
    });
}

fn dataset(c: &mut Criterion) {
    let mut g = c.benchmark_group("dataset");
    g.sample_size(10);
    let tmp = tempfile::tempdir().unwrap();
    for (name, every) in [("coppertag-distance-z", 5usize), ("aruco3-rotated-x", 3)] {
        let spec = paper(name);
        let n = spec.image_count().div_ceil(every);
        g.throughput(Throughput::Elements(n as u64));
        let out = tmp.path().join(name);
        let opts = GenerateOptions { every, force: true };
        g.bench_function(name, |b| {
            b.iter(|| black_box(generate(&spec, &out, &opts, &|_, _| {}).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(benches, render, dataset);
criterion_main!(benches);

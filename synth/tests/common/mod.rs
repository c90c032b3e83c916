//! Helpers shared by the synth integration tests: spec files on disk,
//! rendering in a thread pool of a given size, a dataset's files as bytes,
//! and the camera-effect lines of a sampled spec.

// Each test binary uses its own subset of these.
#![allow(dead_code, unused_macros, unused_imports)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use coppertag_synth::{
    generate, generate_shard, DatasetSpec, GenerateOptions, GenerateReport, Shard,
};

/// The camera and lighting factors of a `[sample]` section over their
/// whole ranges (a macro so that `concat!` can build constant specs).
macro_rules! camera_factors {
    () => {
        "gradient = [0, 0.4]
shadow_darkness = [0, 0.6]
glare_peak = [0, 1.5]
defocus_px = [0, 2]
motion_blur_px = [0, 6]
read_noise_dn = [0.5, 4]
full_well_e = [5000, 20000]
jpeg_quality = [50, 100]
distortion_k1 = [-0.15, 0.05]
"
    };
}
pub(crate) use camera_factors;

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Writes `text` to `dir/name` and loads it as a spec.
pub fn load(dir: &Path, name: &str, text: &str) -> DatasetSpec {
    DatasetSpec::load(&write(dir, name, text)).unwrap()
}

/// Every file below `dir`, by path relative to it, with its bytes.
pub fn read_tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// Renders `spec` (or one shard of it) into `out` on `threads` threads.
pub fn run(threads: usize, spec: &DatasetSpec, out: &Path, shard: Option<Shard>) {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| {
            generate_shard(spec, out, &GenerateOptions::default(), shard, &|_, _| {}).unwrap()
        });
}

/// Renders `spec` into `dir/a` on one thread and `dir/b` on two, asserts
/// that both hold the same files with the same bytes, and returns them.
pub fn same_bytes_on_1_and_2_threads(spec: &DatasetSpec, dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let (a, b) = (dir.join("a"), dir.join("b"));
    run(1, spec, &a, None);
    run(2, spec, &b, None);
    let (ta, tb) = (read_tree(&a), read_tree(&b));
    assert_eq!(ta.keys().collect::<Vec<_>>(), tb.keys().collect::<Vec<_>>());
    for (name, bytes) in &ta {
        assert!(bytes == &tb[name], "{name} differs between 1 and 2 threads");
    }
    ta
}

/// A CSV file's header and rows.
pub fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let mut rd = csv::Reader::from_path(path).unwrap();
    let header = rd.headers().unwrap().iter().map(String::from).collect();
    let rows = rd
        .records()
        .map(|r| r.unwrap().iter().map(String::from).collect())
        .collect();
    (header, rows)
}

/// Renders every `every`-th image of `spec` (quick mode) into `out`.
pub fn generate_every(spec: &DatasetSpec, out: &Path, every: usize) -> GenerateReport {
    generate(
        spec,
        out,
        &GenerateOptions {
            every,
            force: false,
        },
        &|_, _| {},
    )
    .unwrap()
}

//! Whole datasets: byte-identical reruns, the files' contents, and what a
//! failed or interrupted run leaves behind (nothing).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use coppertag_synth::foxglove::base64;
use coppertag_synth::{generate, DatasetSpec, GenerateOptions, SynthError};

use crate::common;
use common::{generate_every, read_tree, run, same_bytes_on_1_and_2_threads};

fn paper_patterns() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/occlusions/paper")
}

/// A small spec that turns on every feature: two marker systems, lens
/// distortion and defocus, clutter, lighting with a shadow, noise, motion
/// blur, JPEG, a sweep, pattern files and generated occlusions.
fn busy_spec(dir: &Path) -> PathBuf {
    let text = format!(
        r#"
name = "busy"
seed = 7
images = 1

[camera]
width = 320
height = 240
focal_length_mm = 4.0
pixel_pitch_um = 3.0
distortion = [-0.12, 0.03, 0.0005, -0.0003, 0.0]

[camera.defocus]
f_number = 2.0
focus_distance_m = 0.6

[background]
kind = "clutter"
base = 0.6
count = 25
min_size_px = 4
max_size_px = 40
distance_m = 2.0

[lighting]
gain = 1.05
gradient = [0.1, -0.05]
vignetting = 0.2

[[lighting.shadow]]
polygon = [[0, 0], [120, 0], [60, 200]]
darkness = 0.3
softness_px = 2.0

[sensor]
read_noise_dn = 1.5
full_well_e = 8000

[effects]
motion_blur = {{ length_px = 1.5, angle = 0.4 }}
jpeg_quality = 90

[[markers]]
system = "coppertag"
family = "ct8"
id = 1234
size_m = 0.06
translation = [-0.04, 0.0, 0.5]
rotation = [0.2, -0.3, 0.1]

[[markers]]
system = "aruco3"
id = 7
size_m = 0.05
translation = [0.05, 0.01, 0.7]
rotation = [0.0, 0.3, 0.0]
occlude = false

[sweep]
param = "ry"
unit = "deg"
from = -10
to = 10
step = 10
markers = [0]

[occlusion]
patterns = ["{p}/05-1-triangle.toml", "{p}/20-3-symmetry.toml"]

[[occlusion.generate]]
scenario = "diagonal"
coverage = 0.12
count = 2
"#,
        p = paper_patterns().display()
    );
    let path = dir.join("busy.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn same_spec_and_seed_give_identical_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = DatasetSpec::load(&busy_spec(tmp.path())).unwrap();
    // 3 sweep values x (2 patterns + 2 generated) = 12 images.
    assert_eq!(spec.image_count(), 12);
    let ta = same_bytes_on_1_and_2_threads(&spec, tmp.path());
    assert_eq!(ta.len(), 12 + 3);
    // A different seed changes the images.
    let mut other = spec.clone();
    other.seed = 8;
    let c = tmp.path().join("c");
    run(2, &other, &c, None);
    assert_ne!(read_tree(&c)["images/000000.png"], ta["images/000000.png"]);
    // No temporary directories left beside the outputs.
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn dataset_files_agree_with_each_other() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = DatasetSpec::load(&busy_spec(tmp.path())).unwrap();
    let out = tmp.path().join("ds");
    let report = generate_every(&spec, &out, 5);
    assert_eq!(report.images, 3, "every 5th of 12: images 0, 5, 10");

    // truth.csv: one row per marker per image, in image order.
    let mut rd = csv::Reader::from_path(out.join("truth.csv")).unwrap();
    let header: Vec<String> = rd.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(header, coppertag_synth::dataset::TRUTH_COLUMNS);
    let rows: Vec<csv::StringRecord> = rd.records().map(Result::unwrap).collect();
    assert_eq!(rows.len(), 6);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let images: Vec<&str> = rows.iter().map(|r| &r[col("image")]).collect();
    assert_eq!(
        images,
        [
            "images/000000.png",
            "images/000000.png",
            "images/000005.png",
            "images/000005.png",
            "images/000010.png",
            "images/000010.png"
        ]
    );
    for r in &rows {
        assert!(out.join(&r[col("image")]).is_file());
        let marker = &r[col("marker")];
        assert!(marker == "coppertag" || marker == "aruco3");
        if marker == "coppertag" {
            assert_eq!(&r[col("family")], "ct8");
            assert_eq!(&r[col("param")], "ry");
            let scen = &r[col("occlusion_scenario")];
            assert!(
                ["triangle", "symmetry", "diagonal"].contains(&scen),
                "{scen}"
            );
            let cov: f64 = r[col("occlusion_coverage")].parse().unwrap();
            assert!(cov > 0.04, "{cov}");
        } else {
            assert_eq!(&r[col("occlusion_scenario")], "", "occlude = false");
            // The sweep value is the image's, also for markers it does not move.
            assert_eq!(&r[col("param")], "ry");
            assert_eq!(&r[col("tz")], "0.7", "the sweep moves marker 0 only");
        }
    }
    // Image 0 of the coppertag: pattern 05-1-triangle hides corner TL.
    assert_eq!(&rows[0][col("occlusion_pattern")], "05-1-triangle");
    assert_eq!(&rows[0][col("corner_visible0")], "0");
    assert_eq!(&rows[0][col("corner_visible1")], "1");
    let deg: f64 = rows[0][col("value_deg")].parse().unwrap();
    assert!((deg + 10.0).abs() < 1e-9);

    // dataset.json: camera and spec echo.
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("dataset.json")).unwrap()).unwrap();
    assert_eq!(meta["images"], 3);
    assert_eq!(meta["images_in_spec"], 12);
    assert_eq!(meta["camera"]["width"], 320);
    assert_eq!(meta["spec"]["markers"][1]["marker"], "aruco3");
    assert!(meta["spec_toml"]
        .as_str()
        .unwrap()
        .contains("[[occlusion.generate]]"));

    // dataset.mcap: the same images, one message per channel per image.
    let bytes = std::fs::read(out.join("dataset.mcap")).unwrap();
    let mut per_topic = BTreeMap::<String, usize>::new();
    let mut k = 0;
    for msg in mcap::MessageStream::new(&bytes).unwrap() {
        let msg = msg.unwrap();
        let topic = msg.channel.topic.clone();
        *per_topic.entry(topic.clone()).or_default() += 1;
        let v: serde_json::Value = serde_json::from_slice(&msg.data).unwrap();
        if topic == "/camera/image" {
            let name = &rows[2 * k][col("image")];
            let png = std::fs::read(out.join(name)).unwrap();
            assert_eq!(v["data"].as_str().unwrap(), base64(&png));
            assert_eq!(v["format"], "png");
            assert_eq!(
                msg.channel.schema.as_ref().unwrap().name,
                "foxglove.CompressedImage"
            );
            k += 1;
        }
        if topic == "/ground_truth" {
            assert_eq!(v["markers"].as_array().unwrap().len(), 2);
        }
        if topic == "/camera/calibration" {
            assert_eq!(v["distortion_model"], "plumb_bob");
            assert_eq!(v["K"][2], spec.rendering.camera.cx);
        }
    }
    for t in [
        "/camera/image",
        "/camera/calibration",
        "/camera/annotations",
        "/ground_truth",
    ] {
        assert_eq!(per_topic.get(t), Some(&3), "{t}: {per_topic:?}");
    }
}

#[test]
fn an_existing_output_is_kept_unless_forced() {
    let tmp = tempfile::tempdir().unwrap();
    let spec_path = tmp.path().join("s.toml");
    std::fs::write(
        &spec_path,
        "[camera]\nwidth = 64\nheight = 48\nfx = 60.0\n[[markers]]\nsystem = \"stag\"\nid = 1\nsize_m = 0.1\ntranslation = [0, 0, 0.4]\n",
    )
    .unwrap();
    let spec = DatasetSpec::load(&spec_path).unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), "x").unwrap();
    let e = generate(&spec, &out, &GenerateOptions::default(), &|_, _| {}).unwrap_err();
    assert!(matches!(e, SynthError::OutputExists { .. }), "{e}");
    assert!(out.join("keep.txt").is_file());
    generate(
        &spec,
        &out,
        &GenerateOptions {
            every: 1,
            force: true,
        },
        &|_, _| {},
    )
    .unwrap();
    assert!(!out.join("keep.txt").exists() && out.join("truth.csv").is_file());
    let names: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "only the spec and the dataset: {names:?}");
}

#[test]
fn an_interrupted_run_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = DatasetSpec::load(&busy_spec(tmp.path())).unwrap();
    let out = tmp.path().join("sub").join("ds");
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        generate(&spec, &out, &GenerateOptions::default(), &|done, _| {
            assert!(done < 3, "simulated interruption after 3 images");
        })
    }));
    assert!(r.is_err());
    assert!(!out.exists());
    let left: Vec<_> = std::fs::read_dir(tmp.path().join("sub")).unwrap().collect();
    assert!(left.is_empty(), "{left:?}");
    // An output whose parent is a file fails before writing anything.
    let file = tmp.path().join("plain");
    std::fs::write(&file, "").unwrap();
    assert!(generate(
        &spec,
        &file.join("ds"),
        &GenerateOptions::default(),
        &|_, _| {}
    )
    .is_err());
}

#[test]
fn a_spec_without_markers_renders_backgrounds_only() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("empty.toml");
    std::fs::write(
        &path,
        "images = 3\n[camera]\nwidth = 80\nheight = 60\nfx = 70.0\n[background]\nkind = \"clutter\"\ncount = 10\n",
    )
    .unwrap();
    let spec = DatasetSpec::load(&path).unwrap();
    assert_eq!(spec.image_count(), 3);
    let out = tmp.path().join("ds");
    generate(&spec, &out, &GenerateOptions::default(), &|_, _| {}).unwrap();
    let truth = std::fs::read_to_string(out.join("truth.csv")).unwrap();
    assert_eq!(truth.lines().count(), 1, "header only");
    let a = std::fs::read(out.join("images/000000.png")).unwrap();
    let b = std::fs::read(out.join("images/000001.png")).unwrap();
    assert_ne!(a, b, "each image draws its own clutter");
}

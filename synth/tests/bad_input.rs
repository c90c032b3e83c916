//! Bad specs and pattern files are rejected with the file, line and column
//! of the problem.

use std::path::{Path, PathBuf};

use coppertag_synth::{DatasetSpec, SynthError};

use crate::common;
use common::camera_factors;

const GOOD: &str = r#"name = "t"
seed = 3

[camera]
width = 640
height = 480
focal_length_mm = 8.0
pixel_pitch_um = 4.0

[[markers]]
system = "coppertag"
id = 42
size_m = 0.1
translation = [0.0, 0.0, 1.0]
rotation = [0.0, 0.0, 0.0]

[sweep]
param = "z"
from = 0.5
to = 1.5
step = 0.1
"#;

/// Loads `text` as `dir/spec.toml`; returns the error's message and its
/// (line, column).
fn error_of(dir: &Path, text: &str) -> (String, usize, usize) {
    let path = dir.join("spec.toml");
    std::fs::write(&path, text).unwrap();
    match DatasetSpec::load(&path) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.starts_with(&path.display().to_string()),
                "names the file: {msg}"
            );
            match e {
                SynthError::Input { line, column, .. } => (msg, line, column),
                other => panic!("not a positioned input error: {other}"),
            }
        }
    }
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn the_good_spec_loads() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("spec.toml");
    std::fs::write(&path, GOOD).unwrap();
    assert_eq!(DatasetSpec::load(&path).unwrap().image_count(), 11);
}

#[test]
fn unknown_keys_are_rejected_where_they_are() {
    let tmp = tempfile::tempdir().unwrap();
    for (old, new, key) in [
        ("seed = 3", "seed = 3\ncolour = \"red\"", "colour"),
        ("size_m = 0.1", "size_m = 0.1\nsize = 0.2", "size"),
        ("step = 0.1", "step = 0.1\nstride = 2", "stride"),
        (
            "pixel_pitch_um = 4.0",
            "pixel_pitch_um = 4.0\nfocal = 3",
            "focal",
        ),
    ] {
        let text = GOOD.replace(old, new);
        let (msg, line, _) = error_of(tmp.path(), &text);
        assert_eq!(line, line_of(&text, &format!("{key} =")), "{msg}");
        assert!(msg.contains(key), "{msg}");
    }
}

#[test]
fn wrong_types_are_rejected_where_they_are() {
    let tmp = tempfile::tempdir().unwrap();
    for (old, new) in [
        ("size_m = 0.1", "size_m = \"big\""),
        ("width = 640", "width = -640"),
        ("id = 42", "id = 4.2"),
        ("translation = [0.0, 0.0, 1.0]", "translation = [0.0, 1.0]"),
        ("system = \"coppertag\"", "system = \"qrcode\""),
    ] {
        let text = GOOD.replace(old, new);
        let (msg, line, _) = error_of(tmp.path(), &text);
        assert_eq!(line, line_of(&text, new), "{new}: {msg}");
    }
    // Not TOML at all.
    let (msg, line, _) = error_of(tmp.path(), &GOOD.replace("step = 0.1", "step = = 0.1"));
    assert_eq!(line, line_of(GOOD, "step = 0.1"), "{msg}");
}

#[test]
fn bad_values_point_at_their_key() {
    let tmp = tempfile::tempdir().unwrap();
    for (old, new, key, words) in [
        (
            "size_m = 0.1",
            "size_m = -0.1",
            "size_m",
            "must be a positive",
        ),
        (
            "size_m = 0.1",
            "size_m = 0.0",
            "size_m",
            "must be a positive",
        ),
        ("id = 42", "id = 256", "id", "out of range"),
        ("step = 0.1", "step = 0.3", "step", "whole number of steps"),
        ("step = 0.1", "step = -0.1", "step", "must be positive"),
        (
            "pixel_pitch_um = 4.0",
            "pixel_pitch_um = -4.0",
            "focal_length_mm",
            "positive",
        ),
    ] {
        let text = GOOD.replace(old, new);
        let (msg, line, _) = error_of(tmp.path(), &text);
        assert_eq!(line, line_of(&text, &format!("{key} =")), "{msg}");
        assert!(msg.contains(words), "{msg}");
    }
    // A pose behind the camera (without the sweep, which would set z).
    let no_sweep = &GOOD[..GOOD.find("[sweep]").unwrap()];
    let text = no_sweep.replace(
        "translation = [0.0, 0.0, 1.0]",
        "translation = [0.0, 0.0, -1.0]",
    );
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert!(msg.contains("behind the camera"), "{msg}");
    assert_eq!(line, line_of(&text, "translation ="));
    // A sweep that takes the marker behind the camera.
    let text = GOOD.replace("from = 0.5", "from = -0.5");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert!(msg.contains("behind the camera at sweep z = -0.5"), "{msg}");
    assert_eq!(line, line_of(&text, "translation ="));
    // A marker beyond the lens model's valid field.
    let text = GOOD
        .replace(
            "pixel_pitch_um = 4.0",
            "pixel_pitch_um = 4.0\ndistortion = [-0.5, 0.0, 0.0, 0.0, 0.0]",
        )
        .replace(
            "translation = [0.0, 0.0, 1.0]",
            "translation = [2.0, 0.0, 1.0]",
        );
    let (msg, _, _) = error_of(tmp.path(), &text);
    assert!(msg.contains("distortion model is valid"), "{msg}");
}

fn pattern_spec(dir: &Path, pattern: &str) -> (PathBuf, String) {
    let p = dir.join("pat.toml");
    std::fs::write(&p, pattern).unwrap();
    let text = format!("{GOOD}\n[occlusion]\npatterns = [\"pat.toml\"]\n");
    (p, text)
}

#[test]
fn a_broken_occluder_file_is_named_with_its_line() {
    let tmp = tempfile::tempdir().unwrap();
    let good = "scenario = \"triangle\"\ncoverage = 0.08\n\n[[occluder]]\npolygon = [[-0.2, -0.2], [0.6, -0.2], [-0.2, 0.6]]\n";
    let (_, text) = pattern_spec(tmp.path(), good);
    std::fs::write(tmp.path().join("spec.toml"), &text).unwrap();
    DatasetSpec::load(&tmp.path().join("spec.toml")).unwrap();
    for (old, new, line, words) in [
        ("polygon = [[-0.2", "polygon = [[-0.2, -0.2] [0.6", 5, ""),
        ("polygon", "polygno", 5, "polygno"),
        ("\"triangle\"", "\"triangel\"", 1, "triangel"),
        (
            "coverage = 0.08",
            "coverage = 0.3",
            1,
            "stated coverage 0.3",
        ),
        (
            "\"triangle\"",
            "\"same-side\"",
            1,
            "same-side pattern must hide",
        ),
    ] {
        let (pat_path, text) = pattern_spec(tmp.path(), &good.replace(old, new));
        let path = tmp.path().join("spec.toml");
        std::fs::write(&path, &text).unwrap();
        let e = DatasetSpec::load(&path).unwrap_err();
        let msg = e.to_string();
        assert!(
            msg.starts_with(&format!("{}:{line}:", pat_path.display())),
            "{msg}"
        );
        assert!(msg.contains(words), "{msg}");
    }
    // A pattern file that is not there: the spec's line.
    let text = format!("{GOOD}\n[occlusion]\npatterns = [\"missing.toml\"]\n");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "missing.toml"), "{msg}");
}

const GOOD_SAMPLE: &str = concat!(
    r#"name = "s"
seed = 3

[camera]
width = 640
height = 480
fx = 600.0

[sample]
markers = [{ system = "coppertag", family = "ct14" }]
count = 10
repeats = 2
square_m = 0.05
markers_per_frame = [1, 3]
side_px = [20, 50]
tilt_x_deg = [-45, 45]
roll_deg = { values = [0, 90, 180] }
pos_x = [0, 1]
id = "any"
contrast = [0.45, 0.88]
background = ["flat", "clutter"]
clutter_density = [0, 600]
"#,
    camera_factors!(),
    r#"occluder_kind = ["none", "stick", "flush-tape"]
occluder_coverage = [0.02, 0.4]
occluder_style = ["ink", "tape"]
occluder_fill = [0.02, 0.95]
"#
);

#[test]
fn the_good_sampled_spec_loads() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("spec.toml");
    std::fs::write(&path, GOOD_SAMPLE).unwrap();
    assert_eq!(DatasetSpec::load(&path).unwrap().image_count(), 20);
}

#[test]
fn bad_sample_values_point_at_their_key() {
    let tmp = tempfile::tempdir().unwrap();
    for (old, new, key, words) in [
        ("count = 10", "count = 0", "count", "outside"),
        ("repeats = 2", "repeats = 0", "repeats", "outside"),
        (
            "square_m = 0.05",
            "square_m = -0.05",
            "square_m",
            "positive",
        ),
        (
            "markers_per_frame = [1, 3]",
            "markers_per_frame = [1, 13]",
            "markers_per_frame",
            "must lie in",
        ),
        (
            "side_px = [20, 50]",
            "side_px = [50, 20]",
            "side_px",
            "lo above hi",
        ),
        (
            "side_px = [20, 50]",
            "side_px = [20, 50, 80]",
            "side_px",
            "range is [lo, hi]",
        ),
        (
            "side_px = [20, 50]",
            "side_px = \"big\"",
            "side_px",
            "give a number",
        ),
        (
            "side_px = [20, 50]",
            "side_px = [20, 400]",
            "side_px",
            "does not fit",
        ),
        (
            "tilt_x_deg = [-45, 45]",
            "tilt_x_deg = [-95, 45]",
            "tilt_x_deg",
            "must lie in",
        ),
        (
            "roll_deg = { values = [0, 90, 180] }",
            "roll_deg = { values = [] }",
            "roll_deg",
            "a list is",
        ),
        (
            "roll_deg = { values = [0, 90, 180] }",
            "roll_deg = { vals = [0] }",
            "roll_deg",
            "a list is",
        ),
        ("pos_x = [0, 1]", "pos_x = [0, 1.5]", "pos_x", "must lie in"),
        ("id = \"any\"", "id = [3, 300]", "id", "not 300"),
        ("id = \"any\"", "id = \"some\"", "id", "give \"any\""),
        (
            "contrast = [0.45, 0.88]",
            "contrast = [0.45, 0.99]",
            "contrast",
            "must lie in",
        ),
        (
            "background = [\"flat\", \"clutter\"]",
            "background = [\"flat\", \"wall\"]",
            "background",
            "'wall' is not one of",
        ),
        (
            "background = [\"flat\", \"clutter\"]",
            "background = [\"image\"]",
            "background",
            "needs background_images",
        ),
        (
            "clutter_density = [0, 600]",
            "clutter_density = [-1, 600]",
            "clutter_density",
            "must lie in",
        ),
        (
            "gradient = [0, 0.4]",
            "gradient = [0, 2]",
            "gradient",
            "must lie in",
        ),
        (
            "shadow_darkness = [0, 0.6]",
            "shadow_darkness = [0, 1.6]",
            "shadow_darkness",
            "must lie in",
        ),
        (
            "glare_peak = [0, 1.5]",
            "glare_peak = [-1, 1.5]",
            "glare_peak",
            "must lie in",
        ),
        (
            "defocus_px = [0, 2]",
            "defocus_px = [0, 200]",
            "defocus_px",
            "must lie in",
        ),
        (
            "motion_blur_px = [0, 6]",
            "motion_blur_px = [0, 600]",
            "motion_blur_px",
            "must lie in",
        ),
        (
            "read_noise_dn = [0.5, 4]",
            "read_noise_dn = [-0.5, 4]",
            "read_noise_dn",
            "must lie in",
        ),
        (
            "full_well_e = [5000, 20000]",
            "full_well_e = [-5, 20000]",
            "full_well_e",
            "must lie in",
        ),
        (
            "jpeg_quality = [50, 100]",
            "jpeg_quality = [0, 100]",
            "jpeg_quality",
            "must lie in",
        ),
        (
            "distortion_k1 = [-0.15, 0.05]",
            "distortion_k1 = [-0.9, 0.05]",
            "distortion_k1",
            "must lie in",
        ),
        (
            "occluder_kind = [\"none\", \"stick\", \"flush-tape\"]",
            "occluder_kind = [\"none\", \"rope\"]",
            "occluder_kind",
            "'rope' is not one of",
        ),
        (
            "occluder_kind = [\"none\", \"stick\", \"flush-tape\"]",
            "occluder_kind = [\"custom\"]",
            "occluder_kind",
            "'custom' is not one of",
        ),
        (
            "occluder_coverage = [0.02, 0.4]",
            "occluder_coverage = [0.02, 0.5]",
            "occluder_coverage",
            "must lie in",
        ),
        (
            "occluder_coverage = [0.02, 0.4]",
            "occluder_coverage = [0, 0.4]",
            "occluder_coverage",
            "above 0",
        ),
        (
            "occluder_style = [\"ink\", \"tape\"]",
            "occluder_style = [\"ink\", \"velvet\"]",
            "occluder_style",
            "'velvet' is not one of",
        ),
        (
            "occluder_fill = [0.02, 0.95]",
            "occluder_fill = [0.02, 1.95]",
            "occluder_fill",
            "must lie in",
        ),
    ] {
        let text = GOOD_SAMPLE.replace(old, new);
        assert_ne!(text, GOOD_SAMPLE, "{old}");
        let (msg, line, _) = error_of(tmp.path(), &text);
        assert_eq!(line, line_of(&text, &format!("{key} =")), "{msg}");
        assert!(msg.contains(words), "{key}: {msg}");
    }
    // A marker type that does not exist.
    let text = GOOD_SAMPLE.replace("family = \"ct14\"", "family = \"ct99\"");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "markers = ["), "{msg}");
    // A photograph that is not there.
    let text = GOOD_SAMPLE.replace(
        "background = [\"flat\", \"clutter\"]",
        "background = [\"image\"]\nbackground_images = [\"nowhere.png\"]",
    );
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "background_images ="), "{msg}");
    // Neither or both of side_px and distance_m.
    let text = GOOD_SAMPLE.replace("side_px = [20, 50]\n", "");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "[sample]"), "{msg}");
    let text = GOOD_SAMPLE.replace(
        "side_px = [20, 50]",
        "side_px = [20, 50]\ndistance_m = [1, 2]",
    );
    let (msg, _, _) = error_of(tmp.path(), &text);
    assert!(
        msg.contains("exactly one of side_px and distance_m"),
        "{msg}"
    );
    // Unknown keys and a sweep beside the sample.
    let text = GOOD_SAMPLE.replace("count = 10", "count = 10\ncolour = 3");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "colour ="), "{msg}");
    let text = format!("{GOOD_SAMPLE}\n[sweep]\nparam = \"z\"\nfrom = 1\nto = 2\nstep = 1\n");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "[sweep]"), "{msg}");
    assert!(msg.contains("does not go with [sample]"), "{msg}");
}

const PHOTO_SPEC: &str = r#"seed = 5
[camera]
width = 200
height = 150
fx = 200.0
[sample]
count = 3
square_m = 0.05
markers = []
markers_per_frame = 0
background = ["image"]
background_dir = "photos"
"#;

#[test]
fn bad_photo_directories_point_at_background_dir() {
    let tmp = tempfile::tempdir().unwrap();
    // Absent.
    let (msg, line, _) = error_of(tmp.path(), PHOTO_SPEC);
    assert_eq!(line, line_of(PHOTO_SPEC, "background_dir ="), "{msg}");
    assert!(msg.contains("no such directory"), "{msg}");
    assert!(msg.contains("export_photos.py"), "{msg}");
    // Empty.
    let photos = tmp.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    let (msg, line, _) = error_of(tmp.path(), PHOTO_SPEC);
    assert_eq!(line, line_of(PHOTO_SPEC, "background_dir ="), "{msg}");
    assert!(msg.contains("no *.png"), "{msg}");
    // A corrupt PNG.
    std::fs::write(photos.join("x.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    let (msg, line, _) = error_of(tmp.path(), PHOTO_SPEC);
    assert_eq!(line, line_of(PHOTO_SPEC, "background_dir ="), "{msg}");
    assert!(msg.contains("x.png"), "{msg}");
    // Too small.
    image::GrayImage::new(20, 20)
        .save(photos.join("x.png"))
        .unwrap();
    let (msg, _, _) = error_of(tmp.path(), PHOTO_SPEC);
    assert!(msg.contains("smaller than"), "{msg}");
    // Wrong type.
    let text = PHOTO_SPEC.replace("\"photos\"", "3");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "background_dir ="), "{msg}");
    // --photos on a spec without background_dir.
    let path = tmp.path().join("spec.toml");
    let text = PHOTO_SPEC
        .replace("background_dir = \"photos\"\n", "")
        .replace("[\"image\"]", "[\"flat\"]");
    std::fs::write(&path, &text).unwrap();
    let opts = coppertag_synth::LoadOptions {
        photos_dir: Some(photos.clone()),
    };
    match DatasetSpec::load_with(&path, &opts) {
        Err(SynthError::Input { line, message, .. }) => {
            assert_eq!(line, line_of(&text, "[sample]"));
            assert!(message.contains("--photos"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    // A missing --photos directory names it.
    std::fs::write(&path, PHOTO_SPEC).unwrap();
    let opts = coppertag_synth::LoadOptions {
        photos_dir: Some(tmp.path().join("nowhere")),
    };
    let e = DatasetSpec::load_with(&path, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("nowhere") && e.contains("--photos"), "{e}");
}

/// A sampled spec with every key of `[sample]`; its files are made by
/// [`full_sample_files`].
const FULL_SAMPLE: &str = concat!(
    r#"name = "s"
seed = 3

[camera]
width = 640
height = 480
fx = 600.0

[sample]
markers = [{ system = "coppertag", family = "ct14" }, { system = "apriltag3" }]
count = 10
repeats = 2
square_m = 0.05
markers_per_frame = [1, 3]
side_px = [20, 50]
tilt_x_deg = [-45, 45]
tilt_y_deg = [-45, 45]
roll_deg = { values = [0, 90, 180] }
pos_x = [0, 1]
pos_y = [0, 1]
id = [1, 2, 3]
contrast = [0.45, 0.88]
background = ["flat", "gradient", "clutter", "image"]
clutter_density = [0, 600]
background_images = ["wall.png"]
background_dir = "photos"
"#,
    camera_factors!(),
    r#"occluder_kind = ["none", "stick", "flush-tape", "glove-cutout"]
occluder_files = ["cutouts"]
occluder_coverage = [0.02, 0.4]
occluder_style = ["ink", "tape"]
occluder_fill = [0.02, 0.95]
"#
);

/// The photographs and cutouts `FULL_SAMPLE` names, in `dir`.
fn full_sample_files(dir: &Path) {
    let photo = image::GrayImage::from_fn(96, 80, |x, y| image::Luma([(x * 2 + y) as u8]));
    photo.save(dir.join("wall.png")).unwrap();
    std::fs::create_dir_all(dir.join("photos")).unwrap();
    photo.save(dir.join("photos/p.png")).unwrap();
    let cut = dir.join("cutouts");
    std::fs::create_dir_all(&cut).unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/occlusions/cutouts");
    for f in ["glove.toml", "glove.png"] {
        std::fs::copy(src.join(f), cut.join(f)).unwrap();
    }
}

/// `FULL_SAMPLE` with the line starting `key =` replaced by `key = value`
/// (or by `value` alone when `value` holds a newline or starts with `#`).
fn with_line(key: &str, line: &str) -> String {
    let mut found = false;
    let text: Vec<String> = FULL_SAMPLE
        .lines()
        .map(|l| {
            if l.starts_with(&format!("{key} =")) {
                found = true;
                line.to_string()
            } else {
                l.to_string()
            }
        })
        .collect();
    assert!(found, "{key} not in FULL_SAMPLE");
    text.join("\n") + "\n"
}

#[test]
fn every_sample_key_rejects_bad_values_at_its_line() {
    let tmp = tempfile::tempdir().unwrap();
    full_sample_files(tmp.path());
    let path = tmp.path().join("spec.toml");
    std::fs::write(&path, FULL_SAMPLE).unwrap();
    assert_eq!(DatasetSpec::load(&path).unwrap().image_count(), 20);

    // (key, the key's largest allowed value + something, or a value below
    // its smallest): out of range.
    let numeric: [(&str, &str); 22] = [
        ("markers_per_frame", "[1, 13]"),
        ("side_px", "[2, 50]"),
        ("tilt_x_deg", "[-45, 90]"),
        ("tilt_y_deg", "[-90, 45]"),
        ("roll_deg", "[0, 400]"),
        ("pos_x", "[-0.1, 1]"),
        ("pos_y", "[0, 1.1]"),
        ("contrast", "[0, 0.5]"),
        ("clutter_density", "[0, 30000]"),
        ("gradient", "[0, 1.5]"),
        ("shadow_darkness", "[-0.1, 0.5]"),
        ("glare_peak", "[0, 5]"),
        ("defocus_px", "[0, 25]"),
        ("motion_blur_px", "[-1, 6]"),
        ("read_noise_dn", "[0, 101]"),
        ("full_well_e", "[0, 2e7]"),
        ("jpeg_quality", "[0, 100]"),
        ("distortion_k1", "[-0.6, 0]"),
        ("occluder_coverage", "[0.02, 0.41]"),
        ("occluder_fill", "[0, 1.01]"),
        ("count", "0"),
        ("repeats", "1001"),
    ];
    let mut cases: Vec<(String, String, &str)> = Vec::new();
    for (key, out_of_range) in numeric {
        cases.push((
            key.into(),
            format!("{key} = {out_of_range}"),
            "outside|must lie in",
        ));
        cases.push((key.into(), format!("{key} = \"lots\""), ""));
        if !matches!(key, "count" | "repeats") {
            cases.push((key.into(), format!("{key} = [0.9, 0.1]"), "lo above hi"));
            cases.push((key.into(), format!("{key} = []"), "a range is"));
            cases.push((
                key.into(),
                format!("{key} = {{ values = [] }}"),
                "a list is",
            ));
            cases.push((key.into(), format!("{key} = [1, 2, 3]"), "a range is"));
            cases.push((
                key.into(),
                format!("{key} = {{ values = [0.5], step = 1 }}"),
                "a list is",
            ));
            cases.push((key.into(), format!("{key} = nan"), "finite"));
        }
    }
    for key in ["background", "occluder_kind", "occluder_style"] {
        cases.push((key.into(), format!("{key} = []"), "non-empty list"));
        cases.push((key.into(), format!("{key} = 3"), "non-empty list"));
        cases.push((
            key.into(),
            format!("{key} = [\"flat\", 3]"),
            "non-empty list",
        ));
        cases.push((
            key.into(),
            format!("{key} = [\"velvet\"]"),
            "'velvet' is not one of",
        ));
    }
    for key in ["background_images", "occluder_files"] {
        cases.push((key.into(), format!("{key} = []"), "empty list"));
        cases.push((
            key.into(),
            format!("{key} = \"one\""),
            "expected a sequence",
        ));
        cases.push((key.into(), format!("{key} = [\"nowhere\"]"), "nowhere"));
    }
    cases.push(("background_dir".into(), "background_dir = 3".into(), ""));
    cases.push((
        "background_dir".into(),
        "background_dir = \"nowhere\"".into(),
        "no such directory",
    ));
    cases.push(("square_m".into(), "square_m = 0".into(), "positive"));
    cases.push(("square_m".into(), "square_m = \"5 cm\"".into(), ""));
    cases.push(("id".into(), "id = []".into(), "give \"any\""));
    cases.push(("id".into(), "id = [1, \"two\"]".into(), "give \"any\""));
    cases.push(("id".into(), "id = [1, 99999]".into(), "not 99999"));
    cases.push((
        "markers".into(),
        "markers = []".into(),
        "at least one marker type",
    ));
    cases.push((
        "markers".into(),
        "markers = [{ system = \"coppertag\", colour = \"red\" }]".into(),
        "colour",
    ));
    // Events (a factor with a share): share in (0, 1], off within the
    // factor's bounds, both given, no other key.
    for (key, line, words) in [
        (
            "defocus_px",
            "{ range = [0, 2], share = 0, off = 0 }",
            "share must lie in (0, 1]",
        ),
        (
            "defocus_px",
            "{ range = [0, 2], share = 1.5, off = 0 }",
            "share must lie in (0, 1]",
        ),
        (
            "defocus_px",
            "{ range = [0, 2], share = \"half\", off = 0 }",
            "are numbers",
        ),
        (
            "defocus_px",
            "{ range = [0, 2], share = 0.5, off = 30 }",
            "off (the value when absent) must lie in",
        ),
        (
            "defocus_px",
            "{ range = [0, 2], share = 0.5, off = nan }",
            "off (the value when absent) must lie in",
        ),
        (
            "defocus_px",
            "{ range = [0, 2], share = 0.5 }",
            "needs both",
        ),
        ("defocus_px", "{ range = [0, 2], off = 0 }", "needs both"),
        (
            "defocus_px",
            "{ range = [0, 2], share = 0.5, off = 0, when = 1 }",
            "unknown key 'when'",
        ),
        (
            "defocus_px",
            "{ range = [0, 25], share = 0.5, off = 0 }",
            "must lie in",
        ),
        (
            "defocus_px",
            "{ range = [2, 0], share = 0.5, off = 0 }",
            "lo above hi",
        ),
        (
            "defocus_px",
            "{ range = 2, share = 0.5, off = 0 }",
            "a range is",
        ),
        ("defocus_px", "{ values = [1], range = [0, 2] }", "not both"),
        ("defocus_px", "{ share = 0.5, off = 0 }", "an event is"),
        (
            "jpeg_quality",
            "{ range = [50, 100], share = 0.5, off = -1 }",
            "off (the value when absent) must lie in 0..=100",
        ),
        (
            "jpeg_quality",
            "{ range = [0, 100], share = 0.5, off = 0 }",
            "must lie in 1..=100",
        ),
        (
            "glare_peak",
            "{ values = [1, 5], share = 0.5, off = 0 }",
            "must lie in",
        ),
        (
            "occluder_kind",
            "{ values = [\"stick\"], share = 0 }",
            "share must lie in (0, 1]",
        ),
        (
            "occluder_kind",
            "{ values = [\"stick\"], share = 1.01 }",
            "share must lie in (0, 1]",
        ),
        (
            "occluder_kind",
            "{ values = [\"stick\"], share = \"half\" }",
            "share is a number",
        ),
        (
            "occluder_kind",
            "{ values = [\"stick\"], share = 0.5, off = \"none\" }",
            "unknown key 'off'",
        ),
        (
            "occluder_kind",
            "{ values = [\"velvet\"], share = 0.5 }",
            "'velvet' is not one of",
        ),
        (
            "occluder_kind",
            "{ values = [], share = 0.5 }",
            "non-empty list",
        ),
        ("occluder_kind", "{ share = 0.5 }", "non-empty list"),
    ] {
        cases.push((key.into(), format!("{key} = {line}"), words));
    }
    for (key, line, words) in &cases {
        let text = with_line(key, line);
        let (msg, got_line, column) = error_of(tmp.path(), &text);
        assert_eq!(
            got_line,
            line_of(&text, &format!("{key} =")),
            "{line}: {msg}"
        );
        assert!(column >= 1, "{line}: {msg}");
        assert!(
            words.is_empty() || words.split('|').any(|w| msg.contains(w)),
            "{line}: wanted '{words}': {msg}"
        );
        assert!(
            msg.starts_with(&format!("{}:{got_line}:{column}: ", path.display())),
            "{line}: {msg}"
        );
    }
    // Events that are fine load (jpeg's off = 0 is "no JPEG step").
    let mut text = FULL_SAMPLE.to_string();
    for (key, line) in [
        (
            "defocus_px",
            "defocus_px = { range = [0, 2], share = 0.5, off = 0 }",
        ),
        (
            "jpeg_quality",
            "jpeg_quality = { range = [50, 100], share = 0.5, off = 0 }",
        ),
        (
            "roll_deg",
            "roll_deg = { values = [0, 90], share = 1, off = 45 }",
        ),
        (
            "occluder_kind",
            r#"occluder_kind = { values = ["stick", "glove-cutout"], share = 0.5 }"#,
        ),
    ] {
        let old = FULL_SAMPLE
            .lines()
            .find(|l| l.starts_with(&format!("{key} =")))
            .unwrap();
        text = text.replace(old, line);
    }
    std::fs::write(&path, &text).unwrap();
    assert_eq!(DatasetSpec::load(&path).unwrap().image_count(), 20);
    // An unknown key, in [sample] and in a marker type.
    let text = with_line("count", "count = 10\nsample_count = 3");
    let (msg, line, _) = error_of(tmp.path(), &text);
    assert_eq!(line, line_of(&text, "sample_count ="), "{msg}");
    assert!(msg.contains("sample_count"), "{msg}");
    // Nothing was written anywhere: loading fails before any output.
    let mut left: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["cutouts", "photos", "spec.toml", "wall.png"]);
}

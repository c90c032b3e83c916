//! Occluders given as an image with alpha (`datasets/occlusions/cutouts/`):
//! the committed PNGs are what the drawing code below makes (set
//! `COPPERTAG_WRITE_CUTOUTS=1` to rewrite them), they render on the marker
//! plane, their coverage comes from their alpha, and bad images are
//! rejected at the `image` key with file:line:col.

use std::path::{Path, PathBuf};

use coppertag_synth::occlusion::Occlusion;
use coppertag_synth::{generate, DatasetSpec, GenerateOptions, SynthError};
use image::{Rgba, RgbaImage};

fn cutout_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/occlusions/cutouts")
}

/// Alpha of a shape edge at signed distance `d` pixels (negative inside):
/// a one-pixel linear ramp, as an editor's anti-aliased selection.
fn edge_alpha(d: f64) -> f64 {
    (0.5 - d).clamp(0.0, 1.0)
}

/// Signed distance from `p` to a capsule (segment `a`-`b`, radius `r`).
fn capsule(p: [f64; 2], a: [f64; 2], b: [f64; 2], r: f64) -> f64 {
    let (ab, ap) = ([b[0] - a[0], b[1] - a[1]], [p[0] - a[0], p[1] - a[1]]);
    let t = ((ap[0] * ab[0] + ap[1] * ab[1]) / (ab[0] * ab[0] + ab[1] * ab[1])).clamp(0.0, 1.0);
    (ap[0] - t * ab[0]).hypot(ap[1] - t * ab[1]) - r
}

/// Signed distance from `p` to a box of half sides `h` and corner radius
/// `r` centred at `c`.
fn rounded_box(p: [f64; 2], c: [f64; 2], h: [f64; 2], r: f64) -> f64 {
    let q = [
        (p[0] - c[0]).abs() - h[0] + r,
        (p[1] - c[1]).abs() - h[1] + r,
    ];
    q[0].max(0.0).hypot(q[1].max(0.0)) + q[0].max(q[1]).min(0.0) - r
}

fn grey(v: f64, a: f64) -> Rgba<u8> {
    let g = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    Rgba([g, g, g, (a * 255.0).round() as u8])
}

/// A work glove seen from above: palm, four fingers, thumb; dark knit
/// with a diagonal rib texture.
fn glove() -> RgbaImage {
    RgbaImage::from_fn(160, 160, |x, y| {
        let p = [f64::from(x), f64::from(y)];
        let mut d = rounded_box(p, [80.0, 104.0], [34.0, 32.0], 12.0);
        for (fx, top) in [(53.0, 30.0), (70.0, 18.0), (88.0, 16.0), (105.0, 26.0)] {
            d = d.min(capsule(p, [fx, 80.0], [fx, top], 8.5));
        }
        d = d.min(capsule(p, [52.0, 112.0], [20.0, 80.0], 9.5));
        let rib = 0.04 * ((p[0] + p[1]) * 0.9).sin();
        let shade = 0.05 * (p[0] - 80.0) / 80.0;
        grey(0.30 + rib + shade, edge_alpha(d))
    })
}

/// A curved black cable with a lengthwise sheen.
fn cable() -> RgbaImage {
    let centre = |x: f64| 32.0 + 14.0 * (std::f64::consts::TAU * x / 256.0).sin();
    let slope =
        |x: f64| 14.0 * std::f64::consts::TAU / 256.0 * (std::f64::consts::TAU * x / 256.0).cos();
    RgbaImage::from_fn(256, 64, |x, y| {
        let (px, py) = (f64::from(x), f64::from(y));
        // Distance across the cable: vertical offset times the cosine of
        // the centre line's slope.
        let across = (py - centre(px)) / slope(px).hypot(1.0);
        let r = 9.0;
        let v = across / r;
        let sheen = 0.18 * (-(v + 0.35).powi(2) / 0.03).exp();
        grey(0.10 + sheen, edge_alpha(across.abs() - r))
    })
}

fn cutouts() -> [(&'static str, RgbaImage); 2] {
    [("glove.png", glove()), ("cable.png", cable())]
}

#[test]
fn committed_cutouts_are_what_the_drawing_code_makes() {
    let dir = cutout_dir();
    for (name, img) in cutouts() {
        let path = dir.join(name);
        if std::env::var_os("COPPERTAG_WRITE_CUTOUTS").is_some() {
            img.save(&path).unwrap();
        }
        let committed = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgba8();
        assert!(committed == img, "{name} differs from its drawing code");
        // Partly transparent, partly opaque, with soft edges.
        let alphas: Vec<u8> = committed.pixels().map(|p| p.0[3]).collect();
        assert!(alphas.contains(&0) && alphas.contains(&255));
        assert!(alphas.iter().any(|&a| a > 0 && a < 255));
    }
}

#[test]
fn cutout_patterns_load_with_coverage_from_alpha() {
    for name in ["glove", "cable"] {
        let o = Occlusion::load(&cutout_dir().join(format!("{name}.toml"))).unwrap();
        let cov = o.coverage();
        assert!(cov > 0.05 && cov < 0.5, "{name}: {cov}");
        assert_eq!(o.occluder_fractions(), vec![cov]);
    }
}

/// A pattern with one cutout of `png` (written to `dir`).
fn pattern(dir: &Path, png: &str, extra: &str) -> String {
    let text = format!(
        "scenario = \"custom\"\n\n[[occluder]]\nimage = \"{png}\"\ncentre = [0.5, 0.5]\nwidth = 0.5\n{extra}"
    );
    std::fs::write(dir.join("p.toml"), &text).unwrap();
    text
}

#[test]
fn coverage_is_measured_from_alpha() {
    let tmp = tempfile::tempdir().unwrap();
    // An opaque square and the same square at half alpha, 0.5 marker
    // squares wide: 25 % and 12.5 % of the marker square.
    for (alpha, want) in [(255u8, 0.25), (128, 0.25 * 128.0 / 255.0)] {
        RgbaImage::from_pixel(64, 64, Rgba([50, 50, 50, alpha]))
            .save(tmp.path().join("sq.png"))
            .unwrap();
        pattern(tmp.path(), "sq.png", "");
        let o = Occlusion::load(&tmp.path().join("p.toml")).unwrap();
        // The bilinear fade at the border adds half a pixel all round.
        let got = o.coverage();
        assert!(
            (got - want).abs() < 0.01 * want + 0.002,
            "{alpha}: {got} vs {want}"
        );
        // Corners of the marker square are outside it: visible; its centre
        // is hidden only when opaque enough.
        assert_eq!(o.corners_hidden(), [false; 4]);
        assert_eq!(o.hides([0.5, 0.5]), alpha >= 128);
        // Turned a quarter, a centred square covers the same.
        assert!((o.quarter_turns(1).coverage() - got).abs() < 1e-3);
    }
    // Off-centre, half outside the square: half the coverage.
    pattern(tmp.path(), "sq.png", "angle = 0.0\n");
    let text = std::fs::read_to_string(tmp.path().join("p.toml"))
        .unwrap()
        .replace("[0.5, 0.5]", "[0.0, 0.5]");
    std::fs::write(tmp.path().join("p.toml"), text).unwrap();
    let o = Occlusion::load(&tmp.path().join("p.toml")).unwrap();
    let half = 0.25 * 128.0 / 255.0 / 2.0;
    assert!(
        (o.coverage() - half).abs() < 0.01 * half + 0.002,
        "{}",
        o.coverage()
    );
}

/// The error of loading pattern `p.toml` in `dir`, with its line.
fn pattern_error(dir: &Path) -> (String, usize) {
    match Occlusion::load(&dir.join("p.toml")) {
        Ok(_) => panic!("accepted"),
        Err(e) => {
            let msg = e.to_string();
            match e {
                SynthError::Input { line, .. } => (msg, line),
                other => panic!("not a positioned input error: {other}"),
            }
        }
    }
}

#[test]
fn bad_cutout_images_are_rejected_at_the_image_key() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let image_line = 4;
    // Missing.
    pattern(dir, "nowhere.png", "");
    let (msg, line) = pattern_error(dir);
    assert_eq!(line, image_line, "{msg}");
    assert!(
        msg.contains("p.toml:4:1:") && msg.contains("nowhere.png"),
        "{msg}"
    );
    // Corrupt.
    std::fs::write(dir.join("bad.png"), b"\x89PNG\r\n\x1a\ngarbage").unwrap();
    pattern(dir, "bad.png", "");
    let (msg, line) = pattern_error(dir);
    assert_eq!(line, image_line, "{msg}");
    assert!(msg.contains("bad.png"), "{msg}");
    // No alpha channel.
    image::GrayImage::from_pixel(32, 32, image::Luma([40]))
        .save(dir.join("grey.png"))
        .unwrap();
    pattern(dir, "grey.png", "");
    let (msg, line) = pattern_error(dir);
    assert_eq!(line, image_line, "{msg}");
    assert!(msg.contains("no alpha channel"), "{msg}");
    // Fully transparent.
    RgbaImage::new(16, 16).save(dir.join("clear.png")).unwrap();
    pattern(dir, "clear.png", "");
    let (msg, _) = pattern_error(dir);
    assert!(msg.contains("fully transparent"), "{msg}");
    // Placement values and keys that do not go with an image.
    RgbaImage::from_pixel(16, 16, Rgba([0, 0, 0, 255]))
        .save(dir.join("ok.png"))
        .unwrap();
    for (extra, key, words) in [
        ("width = -1.0", "width", "width -1"),
        ("angle = nan", "angle", "finite"),
        ("style = \"tape\"", "style", "does not go with image"),
        ("fill = 0.3", "fill", "does not go with image"),
        ("polygon = [[0, 0], [1, 0], [0, 1]]", "", "exactly one of"),
        ("radius = 3", "radius", "unknown field"),
        ("centre = \"middle\"", "centre", ""),
    ] {
        let text = if key == "width" || key == "centre" {
            let k = key.to_string();
            pattern(dir, "ok.png", "")
                .lines()
                .filter(|l| !l.starts_with(&format!("{k} =")))
                .chain(std::iter::once(extra))
                .collect::<Vec<_>>()
                .join("\n")
        } else {
            pattern(dir, "ok.png", extra)
        };
        std::fs::write(dir.join("p.toml"), &text).unwrap();
        let (msg, line) = pattern_error(dir);
        assert!(msg.contains(words), "{extra}: {msg}");
        let want = if key.is_empty() {
            3 // the [[occluder]] table
        } else {
            text.lines().position(|l| l.starts_with(key)).unwrap() + 1
        };
        assert_eq!(line, want, "{extra}: {msg}");
    }
    // Missing placement.
    std::fs::write(
        dir.join("p.toml"),
        "scenario = \"custom\"\n\n[[occluder]]\nimage = \"ok.png\"\nwidth = 0.5\n",
    )
    .unwrap();
    let (msg, line) = pattern_error(dir);
    assert!(msg.contains("needs centre"), "{msg}");
    assert_eq!(line, 4, "{msg}");
}

const SWEPT: &str = r#"seed = 1
[camera]
width = 320
height = 240
fx = 400.0
[print]
ink = 0.04
paper = 0.92
[background]
kind = "flat"
level = 0.9
[[markers]]
system = "coppertag"
id = 7
size_m = 0.1
translation = [0.0, 0.0, 0.5]
[sweep]
param = "rz"
from = 0.0
to = 0.0
count = 1
"#;

fn render(dir: &Path, name: &str, text: &str) -> (image::GrayImage, Vec<csv::StringRecord>) {
    let spec_path = dir.join(format!("{name}.toml"));
    std::fs::write(&spec_path, text).unwrap();
    let spec = DatasetSpec::load(&spec_path).unwrap();
    let out = dir.join(name);
    generate(&spec, &out, &GenerateOptions::default(), &|_, _| {}).unwrap();
    let img = image::open(out.join("images/000000.png"))
        .unwrap()
        .to_luma8();
    let rows = csv::Reader::from_path(out.join("truth.csv"))
        .unwrap()
        .records()
        .map(|r| r.unwrap())
        .collect();
    (img, rows)
}

#[test]
fn a_cutout_is_drawn_on_the_marker_plane_with_its_alpha() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // A dark disc cutout over the centre of a marker on a light background.
    let disc = RgbaImage::from_fn(64, 64, |x, y| {
        let d = (f64::from(x) - 31.5).hypot(f64::from(y) - 31.5);
        Rgba([230, 230, 230, if d < 24.0 { 255 } else { 0 }])
    });
    disc.save(dir.join("disc.png")).unwrap();
    std::fs::write(
        dir.join("disc.toml"),
        "scenario = \"custom\"\n[[occluder]]\nimage = \"disc.png\"\ncentre = [0.5, 0.5]\nwidth = 0.8\n",
    )
    .unwrap();
    let (plain, _) = render(dir, "plain", SWEPT);
    let with = format!("{SWEPT}[occlusion]\npatterns = [\"disc.toml\"]\n");
    let (occluded, rows) = render(dir, "occluded", &with);
    // The marker square spans 400 * 0.05 / 0.5 = 40 px around the
    // principal point (159.5, 119.5): the disc (radius 0.3 squares = 12
    // px) makes its centre light; outside the disc's reach nothing changes.
    let v = |img: &image::GrayImage, x: u32, y: u32| img.get_pixel(x, y).0[0];
    assert!(v(&occluded, 160, 120) > 200, "{}", v(&occluded, 160, 120));
    let mut changed = 0;
    for (x, y, p) in occluded.enumerate_pixels() {
        let (dx, dy) = (f64::from(x) - 159.5, f64::from(y) - 119.5);
        if dx.hypot(dy) > 0.8 * 20.0 * 1.5 {
            assert_eq!(p.0[0], v(&plain, x, y), "({x}, {y}) outside the cutout");
        } else if p.0[0] != v(&plain, x, y) {
            changed += 1;
        }
    }
    assert!(changed > 200, "{changed} pixels changed");
    // The truth's coverage is the alpha's: a disc of radius 0.3 (24 of 64
    // px over 0.8 squares), pi 0.09.
    let header = csv::Reader::from_path(dir.join("occluded/truth.csv"))
        .unwrap()
        .headers()
        .unwrap()
        .clone();
    let col = header
        .iter()
        .position(|h| h == "occlusion_coverage")
        .unwrap();
    let cov: f64 = rows[0][col].parse().unwrap();
    let want = std::f64::consts::PI * 0.09;
    assert!((cov - want).abs() < 0.01, "{cov} vs {want}");
}

const SAMPLED: &str = r#"seed = 4
[camera]
width = 240
height = 180
fx = 250.0
[sample]
markers = [{ system = "coppertag", family = "ct14" }]
count = 6
square_m = 0.05
side_px = [30, 40]
occluder_files = ["cutouts"]
occluder_kind = ["none", "glove-cutout", "cable-cutout", "stick"]
occluder_coverage = [0.05, 0.3]
"#;

#[test]
fn cutout_files_are_occluder_kinds_of_sampled_specs() {
    let tmp = tempfile::tempdir().unwrap();
    let cut = tmp.path().join("cutouts");
    std::fs::create_dir(&cut).unwrap();
    for f in ["glove.toml", "glove.png", "cable.toml", "cable.png"] {
        std::fs::copy(cutout_dir().join(f), cut.join(f)).unwrap();
    }
    let path = tmp.path().join("s.toml");
    std::fs::write(&path, SAMPLED).unwrap();
    let spec = DatasetSpec::load(&path).unwrap();
    let out = tmp.path().join("out");
    generate(&spec, &out, &GenerateOptions::default(), &|_, _| {}).unwrap();
    let draws = std::fs::read_to_string(out.join("draws.csv")).unwrap();
    assert!(
        draws.contains("occluder_kind,glove-cutout")
            || draws.contains("occluder_kind,cable-cutout"),
        "{draws}"
    );
    assert!(draws.contains("occluder_turn_deg"), "{draws}");
    // An unknown pattern name, a name clash with a built-in kind, and a
    // missing file: errors at their keys, nothing written.
    for (old, new, key) in [
        (
            "\"glove-cutout\", \"cable-cutout\"",
            "\"mitten\"",
            "occluder_kind",
        ),
        ("[\"cutouts\"]", "[\"nowhere\"]", "occluder_files"),
    ] {
        let text = SAMPLED.replace(old, new);
        std::fs::write(&path, &text).unwrap();
        match DatasetSpec::load(&path) {
            Err(SynthError::Input { line, message, .. }) => {
                let want = text.lines().position(|l| l.starts_with(key)).unwrap() + 1;
                assert_eq!(line, want, "{message}");
            }
            other => panic!("{new}: {other:?}"),
        }
    }
    std::fs::write(
        cut.join("stick.toml"),
        std::fs::read_to_string(cut.join("glove.toml"))
            .unwrap()
            .replace("name = \"glove-cutout\"", "name = \"stick\""),
    )
    .unwrap();
    std::fs::write(&path, SAMPLED).unwrap();
    let e = DatasetSpec::load(&path).unwrap_err().to_string();
    assert!(e.contains("built-in occluder kind"), "{e}");
}

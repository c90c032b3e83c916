//! Golden detections: what the detector reports, to four decimals, on every
//! fixture image (`tests/fixtures/{ct14,ct8}/*.png`) and on a fixed set of
//! rendered occlusion scenes (the paper's five scenarios at two levels, both
//! families). The expected text is `tests/fixtures/detections.golden`;
//! any change of an id, a corner (beyond 5e-5 px), an estimated flag or a
//! correction count fails this test, so a restructure of the detector that
//! claims to keep behaviour is checked against it.
//!
//! After a deliberate change of behaviour, regenerate the file with
//! `COPPERTAG_BLESS=1 cargo test -p coppertag --profile ci --test suite golden_detections::`
//! and review the diff.

use crate::common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use common::*;
use coppertag::{Detection, Detector, DetectorConfig, Family};
use image::GrayImage;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// A scene's name, image and, for rendered scenes, the truth: id and
/// data-square corners TL, BL, BR, TR.
type Case = (String, GrayImage, Option<(u64, [[f64; 2]; 4])>);

/// Fixture images, sorted by family then numeric id.
fn fixture_images() -> Vec<Case> {
    let mut out = Vec::new();
    for fam in ["ct14", "ct8"] {
        let dir = fixtures().join(fam);
        let mut ids: Vec<u64> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .filter_map(|e| {
                let p = e.ok()?.path();
                (p.extension()? == "png")
                    .then(|| p.file_stem()?.to_str()?.parse().ok())
                    .flatten()
            })
            .collect();
        ids.sort_unstable();
        for id in ids {
            let path = dir.join(format!("{id}.png"));
            let img = image::open(&path)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                .to_luma8();
            out.push((format!("{fam}/{id}.png"), img, None));
        }
    }
    out
}

/// The rendered scenes: each occlusion scenario at 10 % and 20 % of the
/// data square, with a dark and a light occluder, on a tilted tag at about
/// 0.8 m (a 960 x 540 crop of the paper's camera).
fn rendered_scenes() -> Vec<Case> {
    let mut out = Vec::new();
    let mut rng = Rng::new(99);
    for fam in [Family::ct14(), Family::ct8()] {
        for kind in SCENARIOS {
            for (frac, grey) in [(0.10, 20u8), (0.20, 235)] {
                let id = rng.next_u64() % 200;
                let r = rotation(
                    rng.range(-0.4, 0.4),
                    rng.range(-0.4, 0.4),
                    rng.range(0.0, std::f64::consts::TAU),
                );
                let h = CAMERA.homography(&r, [0.0, 0.0, rng.range(0.6, 1.0)], TAG_SIDE_M);
                let shift =
                    nalgebra::Matrix3::new(1.0, 0.0, -480.0, 0.0, 1.0, -270.0, 0.0, 0.0, 1.0);
                let h = coppertag::homography::Homography::from_matrix(shift * h.matrix());
                let mut s = Scene::new(fam, id, 960, 540, h);
                s.blur = 0.6;
                s.noise = 2.0;
                s.seed = rng.next_u64();
                s.occluders = occluders(kind, frac, (id % 4) as u32, rng.uniform())
                    .into_iter()
                    .map(|poly| Occluder { poly, grey })
                    .collect();
                out.push((
                    format!("render/{}-{id}-{kind:?}-{frac}-{grey}", fam.name()),
                    s.render(),
                    Some((id, s.corners())),
                ));
            }
        }
    }
    out
}

fn line(scene: &str, d: &Detection) -> String {
    let est: String = d
        .estimated
        .iter()
        .map(|&e| if e { 'e' } else { 'm' })
        .collect();
    let mut s = format!(
        "{scene} {} {} corrected={} {est}",
        d.family, d.id, d.corrected
    );
    for c in d.corners {
        write!(s, " {:.4} {:.4}", c[0], c[1]).unwrap();
    }
    s
}

/// The golden text, and every detection in a rendered scene that is not
/// its tag with every corner within 3 px or 5% of the side (the larger) of
/// the truth: a wrong id or a rough corner.
fn report() -> (String, Vec<String>) {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut out = String::from(
        "# scene family id corrections corners(m measured, e estimated) TL BL BR TR x y\n",
    );
    let mut wrong = Vec::new();
    for (name, img, truth) in fixture_images().into_iter().chain(rendered_scenes()) {
        let found = det.detect(&img);
        if let Some((id, corners)) = truth {
            // The sides are the distances from each corner to the next.
            let next = std::array::from_fn(|k| corners[(k + 1) % 4]);
            let side = corner_errors(&corners, &next).iter().sum::<f64>() / 4.0;
            let allowed = rough_bound(side);
            for d in &found {
                let err = worst_corner_error(&d.corners, &corners);
                if d.id != id || err > allowed {
                    wrong.push(format!("{} (corner error {err:.2} px)", line(&name, d)));
                }
            }
        }
        if found.is_empty() {
            writeln!(out, "{name} none").unwrap();
        }
        for d in &found {
            writeln!(out, "{}", line(&name, d)).unwrap();
        }
    }
    (out, wrong)
}

#[test]
fn detections_match_the_golden_file() {
    let path = fixtures().join("detections.golden");
    let (got, wrong) = report();
    assert!(
        wrong.is_empty(),
        "wrong ids or rough corners in rendered scenes:\n{}",
        wrong.join("\n")
    );
    if std::env::var_os("COPPERTAG_BLESS").is_some_and(|v| v == "1") {
        // Atomic: a half-written golden file never replaces a good one.
        let tmp = path.with_extension("golden.tmp");
        std::fs::write(&tmp, &got).unwrap();
        std::fs::rename(&tmp, &path).unwrap();
        eprintln!("wrote {}", path.display());
        return;
    }
    let want = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (create it with COPPERTAG_BLESS=1)", path.display()));
    let diff: Vec<String> = want
        .lines()
        .zip(got.lines())
        .filter(|(a, b)| a != b)
        .map(|(a, b)| format!("- {a}\n+ {b}"))
        .collect();
    assert!(
        diff.is_empty() && want.lines().count() == got.lines().count(),
        "detections differ from {} ({} vs {} lines):\n{}",
        path.display(),
        want.lines().count(),
        got.lines().count(),
        diff.join("\n")
    );
}

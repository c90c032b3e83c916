//! The paper's simulation datasets (`datasets/paper/`): every spec parses,
//! has the paper's image count, and keeps the whole printed marker inside
//! the frame in every image. Checked by projecting, without rendering.

use std::path::{Path, PathBuf};

use coppertag_synth::markers::MarkerSystem;
use coppertag_synth::scene::MarkerView;
use coppertag_synth::DatasetSpec;

fn paper_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/paper")
}

const SWEEPS: [(&str, usize); 5] = [
    ("distance-z", 251),
    ("rotated-x", 141),
    ("rotated-y", 141),
    ("rotated-z", 361),
    ("occlusion", 20),
];

#[test]
fn every_paper_spec_has_the_papers_count_and_stays_in_frame() {
    let mut checked = 0;
    for system in MarkerSystem::ALL {
        for (sweep, count) in SWEEPS {
            let path = paper_dir().join(format!("{}-{sweep}.toml", system.name()));
            let spec = DatasetSpec::load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(spec.image_count(), count, "{}", path.display());
            assert_eq!(spec.markers.len(), 1);
            let m = &spec.markers[0];
            assert_eq!(m.model.system, system);
            assert_eq!(m.size_m, 0.1, "every marker is printed 0.1 m x 0.1 m");
            let cam = &spec.rendering.camera;
            assert_eq!((cam.width, cam.height), (1920, 1080));
            assert!((cam.fx - 16.0 / 0.00586).abs() < 1e-9 && cam.fx == cam.fy);
            assert_eq!((cam.cx, cam.cy), (959.5, 539.5));
            assert!(!cam.has_distortion());
            let e = m.model.half_extent;
            let unit = m.model.metres_per_unit(m.size_m);
            let mut min_side = f64::INFINITY;
            for i in 0..count {
                let frame = spec.frame(i);
                let pose = spec.pose(0, frame.value);
                let view = MarkerView::new(cam, pose, unit, e);
                // The printed image's corners (and so, the marker being
                // planar and convex, all of it) inside the image.
                for p in [[-e, -e], [-e, e], [e, e], [e, -e]] {
                    let q = view.project(p).expect("in front of the camera");
                    assert!(
                        cam.contains(q),
                        "{} image {i}: printed corner {p:?} at {q:?} is outside the frame",
                        path.display()
                    );
                }
                let c: Vec<[f64; 2]> = coppertag_synth::markers::CORNERS
                    .iter()
                    .map(|&p| view.project(p).unwrap())
                    .collect();
                for k in 0..4 {
                    let (a, b) = (c[k], c[(k + 1) % 4]);
                    min_side = min_side.min((a[0] - b[0]).hypot(a[1] - b[1]));
                }
                checked += 1;
            }
            if sweep == "distance-z" {
                // At 2.8 m: CopperTag's data square is 2730.375 * 0.05 / 2.8
                // = 48.76 px (the paper's 48 px), a peer's black square
                // 2730.375 * 0.08 / 2.8 = 78.0 px.
                let expect = cam.fx * unit / 2.8;
                assert!((min_side - expect).abs() < 1e-6, "{min_side} vs {expect}");
                if system == MarkerSystem::Coppertag {
                    assert!((min_side - 48.757).abs() < 1e-3, "{min_side}");
                }
            }
        }
    }
    assert_eq!(
        checked,
        MarkerSystem::ALL.len() * (251 + 141 + 141 + 361 + 20)
    );
}

#[test]
fn sweeps_hit_their_end_values() {
    let spec = DatasetSpec::load(&paper_dir().join("coppertag-distance-z.toml")).unwrap();
    let v = &spec.sweep.as_ref().unwrap().values;
    assert!((v[0] - 0.30).abs() < 1e-12 && (v[250] - 2.80).abs() < 1e-12);
    let spec = DatasetSpec::load(&paper_dir().join("aruco3-rotated-z.toml")).unwrap();
    let v = &spec.sweep.as_ref().unwrap().values;
    assert!((v[360] - std::f64::consts::TAU).abs() < 1e-12);
    let spec = DatasetSpec::load(&paper_dir().join("stag-rotated-x.toml")).unwrap();
    let v = &spec.sweep.as_ref().unwrap().values;
    assert!((v[0] + 70f64.to_radians()).abs() < 1e-12 && v[70].abs() < 1e-12);
}

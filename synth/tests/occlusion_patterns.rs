//! The paper's 20 occlusion patterns (`datasets/occlusions/paper/`): each
//! covers its stated fraction of the marker square within 0.5 % (absolute,
//! exact polygon clipping) and hides the corners its scenario says it hides.
//! The coverage computation itself is checked against rendered pixels.

use std::path::{Path, PathBuf};

use coppertag_synth::coverage::Rasterizer;
use coppertag_synth::occlusion::{pattern_files, Occlusion, Scenario};
use coppertag_synth::polygon;
use coppertag_synth::DatasetSpec;

fn paper_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/occlusions/paper")
}

fn scenario_from_name(name: &str) -> Scenario {
    match name
        .split('-')
        .skip(2)
        .collect::<Vec<_>>()
        .join("-")
        .as_str()
    {
        "triangle" => Scenario::Triangle,
        "same-side" => Scenario::SameSide,
        "symmetry" => Scenario::Symmetry,
        "diagonal" => Scenario::Diagonal,
        "inner" => Scenario::Inner,
        other => panic!("unexpected pattern name {other}"),
    }
}

#[test]
fn twenty_patterns_with_exact_coverage_and_the_right_corners() {
    let files = pattern_files(&paper_dir()).unwrap();
    assert_eq!(files.len(), 20);
    let mut per_level = std::collections::BTreeMap::<u32, Vec<Scenario>>::new();
    for f in &files {
        let o = Occlusion::load(f).unwrap();
        let level: u32 = o.name[..2].parse().unwrap();
        let stated = f64::from(level) / 100.0;
        let exact = o.coverage();
        assert!(
            (exact - stated).abs() <= 0.005,
            "{}: covers {exact}, stated {stated}",
            o.name
        );
        assert_eq!(o.scenario, scenario_from_name(&o.name), "{}", o.name);
        let hidden = o.corners_hidden();
        let n = hidden.iter().filter(|&&h| h).count();
        match o.scenario {
            Scenario::Triangle => assert_eq!(n, 1, "{}", o.name),
            Scenario::SameSide => {
                assert_eq!(n, 2, "{}", o.name);
                assert!(
                    (0..4).any(|i| hidden[i] && hidden[(i + 1) % 4]),
                    "{}: adjacent",
                    o.name
                );
            }
            Scenario::Diagonal => {
                assert_eq!(n, 2, "{}", o.name);
                assert!(
                    (hidden[0] && hidden[2]) || (hidden[1] && hidden[3]),
                    "{}: opposite",
                    o.name
                );
            }
            Scenario::Symmetry => {
                assert_eq!(n, 0, "{}", o.name);
                let b = o.edges_broken();
                assert!(
                    (b[0] && b[2]) || (b[1] && b[3]),
                    "{}: breaks two opposite edges",
                    o.name
                );
            }
            Scenario::Inner => {
                assert_eq!(n, 0, "{}", o.name);
                assert_eq!(o.edges_broken(), [false; 4], "{}", o.name);
                for occ in &o.occluders {
                    // Entirely inside the square: clipping removes nothing,
                    // and it keeps clear of the border.
                    let full = polygon::area(&occ.polygon);
                    assert!((polygon::area_in_unit_square(&occ.polygon) - full).abs() < 1e-12);
                    assert!(occ
                        .polygon
                        .iter()
                        .all(|p| p.iter().all(|&v| (0.125..=0.875).contains(&v))));
                }
            }
            other => unreachable!("{other:?}: the paper's patterns use the five scenarios"),
        }
        per_level.entry(level).or_default().push(o.scenario);
    }
    let all = vec![
        Scenario::Triangle,
        Scenario::SameSide,
        Scenario::Symmetry,
        Scenario::Diagonal,
        Scenario::Inner,
    ];
    assert_eq!(
        per_level.keys().copied().collect::<Vec<_>>(),
        vec![5, 10, 15, 20]
    );
    for (level, s) in per_level {
        assert_eq!(s, all, "level {level}: one pattern per scenario");
    }
}

/// The exact coverage agrees with what is drawn: render each pattern as a
/// mask in a frontal marker square of 400 x 400 px and count covered area.
#[test]
fn exact_coverage_matches_rendered_area() {
    let mut raster = Rasterizer::new();
    let side = 400.0;
    for f in pattern_files(&paper_dir()).unwrap() {
        let o = Occlusion::load(&f).unwrap();
        let polys: Vec<Vec<[f64; 2]>> = o
            .occluders
            .iter()
            .map(|oc| {
                oc.polygon
                    .iter()
                    .map(|p| [p[0] * side, p[1] * side])
                    .collect()
            })
            .collect();
        let mut mask = vec![0.0f32; 400 * 400];
        for p in &polys {
            // Union: a pixel covered by several occluders counts once (up
            // to the edges' anti-aliasing).
            raster.coverage(
                std::slice::from_ref(p),
                tiny_skia::FillRule::Winding,
                400,
                400,
                |x, y, c| {
                    let m = &mut mask[y * 400 + x];
                    *m = 1.0 - (1.0 - *m) * (1.0 - c);
                },
            );
        }
        let area = mask.iter().map(|&m| f64::from(m)).sum::<f64>() / (side * side);
        assert!(
            (area - o.coverage()).abs() < 2e-4,
            "{}: pixels {area}, exact {}",
            o.name,
            o.coverage()
        );
    }
}

/// Occluders are laid on the marker square of every system: the occlusion
/// specs of the five systems name the same 20 patterns, and the truth
/// reports the same coverage for each.
#[test]
fn every_system_gets_the_same_patterns() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../datasets/paper");
    let mut names: Option<Vec<String>> = None;
    for sys in ["coppertag", "apriltag3", "aruco3", "stag", "fractal"] {
        let spec = DatasetSpec::load(&dir.join(format!("{sys}-occlusion.toml"))).unwrap();
        let n: Vec<String> = spec
            .occlusion
            .patterns
            .iter()
            .map(|p| p.name.clone())
            .collect();
        assert_eq!(n.len(), 20);
        if let Some(prev) = &names {
            assert_eq!(prev, &n);
        }
        names = Some(n);
    }
}

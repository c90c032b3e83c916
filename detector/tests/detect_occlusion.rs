//! Occluded tags: the paper's 20 occlusion patterns (5 scenarios x 5, 10,
//! 15, 20 % of the data square) and procedural variants of them at random
//! poses, occluder shades and cut positions.

use crate::common;

use common::*;
use coppertag::{Detector, DetectorConfig, Family};

/// Outcome of one occluded scene.
#[derive(Debug, PartialEq)]
enum Outcome {
    Found,
    Missed,
    WrongId,
}

fn run_scene(det: &mut Detector, s: &Scene, real_errs: &mut Vec<f64>) -> Outcome {
    let img = s.render();
    let found = det.detect(&img);
    if found
        .iter()
        .any(|d| d.id != s.id || d.family != s.family.name())
    {
        return Outcome::WrongId;
    }
    assert!(found.len() <= 1, "duplicates: {found:?}");
    let Some(d) = found.first() else {
        return Outcome::Missed;
    };
    let e = corner_errors(&d.corners, &s.corners());
    for (err, est) in e.iter().zip(d.estimated) {
        if !est {
            real_errs.push(*err);
        }
    }
    Outcome::Found
}

fn scene(kind: Occlusion, frac: f64, rng: &mut Rng, grey: u8, turn: u32, jitter: f64) -> Scene {
    let fam = Family::ct14();
    let id = rng.next_u64() % 256;
    let d = rng.range(0.5, 1.5);
    let r = rotation(
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
        rng.range(0.0, std::f64::consts::TAU),
    );
    let h = CAMERA.homography(
        &r,
        [rng.range(-0.05, 0.05), rng.range(-0.03, 0.03), d],
        TAG_SIDE_M,
    );
    // A 960 x 540 crop of the paper's camera around the tag keeps tests fast.
    let (w, hh) = (960u32, 540u32);
    let shift = nalgebra::Matrix3::new(1.0, 0.0, -480.0, 0.0, 1.0, -270.0, 0.0, 0.0, 1.0);
    let h = coppertag::homography::Homography::from_matrix(shift * h.matrix());
    let mut s = Scene::new(fam, id, w, hh, h);
    s.blur = 0.6;
    s.noise = 2.0;
    s.seed = rng.next_u64();
    s.occluders = occluders(kind, frac, turn, jitter)
        .into_iter()
        .map(|poly| Occluder { poly, grey })
        .collect();
    s
}

const SHADES: [u8; 3] = [20, 235, 120];

fn paper_patterns() -> Vec<String> {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(7);
    let mut errs = Vec::new();
    let mut missed = Vec::new();
    for frac in [0.05, 0.10, 0.15, 0.20] {
        for kind in SCENARIOS {
            for grey in [20u8, 235] {
                let s = scene(kind, frac, &mut rng, grey, 0, 0.5);
                match run_scene(&mut det, &s, &mut errs) {
                    Outcome::Found => {}
                    Outcome::Missed => {
                        if std::env::var_os("CT_DUMP").is_some() {
                            s.render()
                                .save(format!("/tmp/miss-{kind:?}-{frac}-{grey}.png"))
                                .unwrap();
                            eprintln!("truth {:?}", s.corners());
                        }
                        missed.push(format!("{kind:?} {frac} grey {grey}"))
                    }
                    Outcome::WrongId => panic!("wrong id: {kind:?} {frac} grey {grey}"),
                }
            }
        }
    }
    eprintln!(
        "paper patterns (x2 shades): {} of 40 missed: {missed:?}",
        missed.len()
    );
    missed
}

/// Regression floor: the 20 patterns, each with a black and a white
/// occluder, never give a wrong id and at most 1 of the 40 is missed
/// (the current state; see `paper_occlusion_patterns_all`).
#[test]
fn paper_occlusion_patterns() {
    let missed = paper_patterns();
    assert!(missed.len() <= 1, "missed: {missed:#?}");
}

/// The bar: every pattern detected.
#[test]
#[ignore = "known gap: diagonal 15 % with black occluders on a 95 px tag is missed (the visible corner's border is broken up by the cells at 2x downsampling)"]
fn paper_occlusion_patterns_all() {
    let missed = paper_patterns();
    assert!(missed.is_empty(), "missed: {missed:#?}");
}

/// The procedural study: `per_cell` scenes per scenario and occluded
/// share in `fracs`. The scenes are drawn in order from one seed, then
/// detected across the machine's cores (one detector per rayon worker)
/// and tallied in that order: the same outcomes as one detector in one
/// loop, in half the time on two cores.
fn procedural(per_cell: usize, fracs: &[f64], assert_rate: Option<f64>) {
    use rayon::prelude::*;
    let mut rng = Rng::new(2024);
    let mut scenes = Vec::new();
    for kind in SCENARIOS {
        for &frac in fracs {
            for _ in 0..per_cell {
                let grey = SHADES[(rng.next_u64() % 3) as usize];
                let turn = (rng.next_u64() % 4) as u32;
                let jitter = rng.uniform();
                scenes.push(scene(kind, frac, &mut rng, grey, turn, jitter));
            }
        }
    }
    let outcomes: Vec<(Outcome, Vec<f64>)> = scenes
        .par_iter()
        .map_init(
            || Detector::new(DetectorConfig::default()).unwrap(),
            |det, s| {
                let mut errs = Vec::new();
                (run_scene(det, s, &mut errs), errs)
            },
        )
        .collect();
    // In the order the scenes were drawn: per_cell of each scenario and
    // share, as the loops below take them.
    let mut outcomes = outcomes.into_iter();
    let mut errs = Vec::new();
    let mut report = String::new();
    let mut worst: f64 = 1.0;
    for kind in SCENARIOS {
        report += &format!("{kind:?}:");
        // Pooled over 5-20 %, the levels the bar is set on.
        let (mut low_found, mut low_n) = (0usize, 0usize);
        for &frac in fracs {
            let mut found = 0;
            for (outcome, e) in outcomes.by_ref().take(per_cell) {
                errs.extend(e);
                match outcome {
                    Outcome::Found => found += 1,
                    Outcome::Missed => {}
                    Outcome::WrongId => panic!("wrong id: {kind:?} {frac}"),
                }
            }
            if frac <= 0.2 + 1e-9 {
                low_found += found;
                low_n += per_cell;
            }
            report += &format!(
                " {:.0}%:{:.1}%",
                frac * 100.0,
                100.0 * found as f64 / per_cell as f64
            );
        }
        let low = low_found as f64 / low_n.max(1) as f64;
        worst = worst.min(low);
        report += &format!("  (5-20 %: {:.1}% of {low_n})\n", 100.0 * low);
    }
    errs.sort_by(f64::total_cmp);
    let q = |f: f64| errs[((errs.len() - 1) as f64 * f) as usize];
    eprintln!(
        "{report}real-corner error median {:.3} p95 {:.3} (n = {})",
        q(0.5),
        q(0.95),
        errs.len()
    );
    if let Some(min) = assert_rate {
        assert!(worst >= min, "worst scenario rate {worst}\n{report}");
    }
}

/// A quick version of the procedural study (10 scenes per scenario and
/// level, 5-20 %): at least 95 % per scenario, pooled over the levels.
#[test]
fn procedural_occlusion_quick() {
    procedural(10, &[0.05, 0.10, 0.15, 0.20], Some(0.95));
}

/// The bar: 200 scenes per scenario over 5-20 % (50 per level), at
/// least 95 % found in every scenario; the curve continues to 35 %.
#[test]
#[ignore = "about 10 minutes; run with --release --ignored"]
fn procedural_occlusion_full() {
    procedural(50, &[0.05, 0.10, 0.15, 0.20, 0.25, 0.30, 0.35], Some(0.95));
}

/// An ink-dark or paper-white patch over 30-40 % of the data square, the
/// frame and all four corners in view: the hidden cells read confidently
/// wrong, past what the Reed-Solomon code corrects, and the tag is read by
/// its nearest codeword (`likelihood`, on these sharp tags). No wrong id,
/// every corner within 1 px, at least 18 of 24 found with 3 by the
/// nearest codeword (today 19 and 4; without that reading 15 and 0).
#[test]
fn a_third_of_the_square_under_one_patch() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(31);
    let (mut found, mut by_codeword, mut n) = (0, 0, 0);
    for k in 0..24 {
        let frac = 0.30 + 0.10 * (k % 6) as f64 / 5.0;
        let grey = [20u8, 235][k % 2];
        let jitter = rng.uniform();
        let s = scene(Occlusion::Inner, frac, &mut rng, grey, 0, jitter);
        n += 1;
        let img = s.render();
        let dets = det.detect(&img);
        assert!(
            dets.iter().all(|d| d.id == s.id),
            "wrong id at {frac:.2}, grey {grey}: {dets:?}"
        );
        if let Some(d) = dets.first() {
            let e = corner_errors(&d.corners, &s.corners());
            assert!(
                e.iter().all(|&e| e < 1.0),
                "corners {e:?} at {frac:.2}, grey {grey}"
            );
            found += 1;
            by_codeword += usize::from(d.likelihood);
        }
    }
    eprintln!("{found} of {n} found, {by_codeword} by the nearest codeword");
    assert!(found >= 18, "{found} of {n} found");
    assert!(by_codeword >= 3, "{by_codeword} by the nearest codeword");
}

/// Seven tags of the wild set (23-47 px) under occluders that also cover
/// much of the frame and margin rings (diagonal and triangle patterns
/// across two sides, an occluder along a side), cut from its frames
/// (`tests/fixtures/wild/clear-ring-crops.csv`). The rings' plain medians
/// lay within a few grey levels of each other (on `crop-002539-2.png`
/// both 55), so no reading of their grids could tell black from white,
/// and none was found. Read at the levels of the rings' clearer half
/// (`QuadReading::clear_ring`), each is found, every corner within
/// 1.7 px (1.66 px at most, measured). At their true corners each reads
/// its own id, six of them at the clear levels (the seventh,
/// `crop-002820-0.png`, reads there at the plain ones; the detector's
/// quads of it did not).
#[test]
fn tags_whose_rings_an_occluder_covers_read_at_the_clear_levels() {
    let found = crops_found("clear-ring-crops.csv", 1.7);
    assert_eq!(found.len(), 7);
    let fam = Family::by_name("ct14").unwrap();
    let mut clear = Vec::new();
    for c in crops("clear-ring-crops.csv") {
        let r = coppertag::decode_quad(&c.img, fam, &c.truth)
            .unwrap_or_else(|| panic!("{}: not read at its true corners", c.file));
        assert_eq!(r.id, c.id, "{}: a wrong id", c.file);
        if r.clear_ring {
            clear.push(c.file);
        }
    }
    eprintln!("read at the clear levels at the true corners: {clear:?}");
    assert!(clear.len() >= 6, "{clear:?}");
}

//! Verification of a decoded tag's geometry against its own model: dark
//! tape flush with the frame must not leave a rough measured corner, a
//! hidden corner must say it is estimated, and the corner uncertainties
//! must cover the truth.

use crate::common;

use common::*;
use coppertag::{Detection, Detector, DetectorConfig, Family};

/// A ct14 tag of data-square side about `side_px` pixels, tilted, in a
/// 480 x 400 frame.
fn scene(id: u64, side_px: f64, tilt: (f64, f64, f64), seed: u64) -> Scene {
    let d = CAMERA.f * TAG_SIDE_M / side_px;
    let r = rotation(tilt.0, tilt.1, tilt.2);
    let h = CAMERA.homography(&r, [0.0, 0.0, d], TAG_SIDE_M);
    let (w, hh) = (480u32, 400u32);
    let shift = nalgebra::Matrix3::new(
        1.0,
        0.0,
        -(CAMERA.cx() - f64::from(w) / 2.0),
        0.0,
        1.0,
        -(CAMERA.cy() - f64::from(hh) / 2.0),
        0.0,
        0.0,
        1.0,
    );
    let h = coppertag::homography::Homography::from_matrix(shift * h.matrix());
    let mut s = Scene::new(Family::ct14(), id, w, hh, h);
    s.blur = 0.6;
    s.noise = 2.0;
    s.seed = seed;
    s
}

/// Dark tape (ink black) lying along one side of the data square, its
/// outer edge on that side, `depth` of the side deep, running out past a
/// corner (`overhang`) to `end` along the side (tag units, the
/// `flush-tape` occluder of `synth/src/floor_occluders.rs`), turned by
/// `turn` quarter turns.
fn flush_tape(depth: f64, overhang: f64, end: f64, turn: u32, grey: u8) -> Occluder {
    let poly = [
        [-overhang, 0.0],
        [-overhang, depth],
        [end, depth],
        [end, 0.0],
    ]
    .map(|[x, y]| {
        let mut p = [x - 0.5, y - 0.5];
        for _ in 0..turn % 4 {
            p = [-p[1], p[0]];
        }
        p
    });
    Occluder {
        poly: poly.to_vec(),
        grey,
    }
}

/// The largest distance of a measured corner from the truth, and whether
/// any corner (measured or estimated) is rough (beyond 3 px or 5% of the
/// side, the wild benchmark's rule).
fn judge(d: &Detection, s: &Scene) -> (f64, bool) {
    let truth = s.corners();
    let errs = corner_errors(&d.corners, &truth);
    let side = (0..4)
        .map(|i| {
            let (a, b) = (truth[i], truth[(i + 1) % 4]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .sum::<f64>()
        / 4.0;
    let rough = errs.iter().any(|&e| e > rough_bound(side));
    let measured = errs
        .iter()
        .zip(d.estimated)
        .filter(|(_, est)| !est)
        .map(|(e, _)| *e)
        .fold(0.0, f64::max);
    (measured, rough)
}

#[test]
fn flush_tape_never_leaves_a_rough_measured_corner() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(11);
    let (mut found, mut total) = (0, 0);
    for (k, &(depth, end)) in [(0.12, 0.7), (0.2, 1.2), (0.25, 0.5), (0.3, 1.2)]
        .iter()
        .cycle()
        .take(12)
        .enumerate()
    {
        let id = rng.next_u64() % 256;
        let tilt = (
            rng.range(-0.5, 0.5),
            rng.range(-0.5, 0.5),
            rng.range(0.0, std::f64::consts::TAU),
        );
        let mut s = scene(id, rng.range(70.0, 140.0), tilt, k as u64);
        s.occluders.push(flush_tape(
            depth,
            rng.range(0.1, 0.5),
            end,
            k as u32,
            s.black,
        ));
        let out = det.detect(&s.render());
        total += 1;
        for d in &out {
            assert_eq!(d.id, id, "wrong id in scene {k}: {d:?}");
            let (measured, rough) = judge(d, &s);
            assert!(
                !rough,
                "scene {k}: rough detection {d:?} truth {:?}",
                s.corners()
            );
            assert!(
                measured <= 1.0,
                "scene {k}: a measured corner {measured:.2} px off: {d:?} truth {:?}",
                s.corners()
            );
            found += 1;
        }
    }
    eprintln!("flush tape: {found} of {total} found, none rough");
}

#[test]
fn a_stick_over_a_corner_makes_it_estimated() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut seen = 0;
    for (k, grey) in [25u8, 230, 25, 230].into_iter().enumerate() {
        let mut s = scene(17 + k as u64, 110.0, (0.2, -0.3, 0.4 + k as f64), k as u64);
        // A stick 0.2 wide across the TL corner, at 45 degrees: between
        // the lines x + y = c1 and x + y = c2 (TL is on x + y = -1).
        let (c1, c2) = (-1.14, -0.86);
        s.occluders.push(Occluder {
            poly: vec![
                [-1.5, c1 + 1.5],
                [c1 + 1.5, -1.5],
                [c2 + 1.5, -1.5],
                [-1.5, c2 + 1.5],
            ],
            grey,
        });
        let out = det.detect(&s.render());
        let Some(d) = out.first() else {
            continue;
        };
        assert_eq!(d.id, s.id);
        let (measured, rough) = judge(d, &s);
        assert!(!rough, "case {k}: rough {d:?} truth {:?}", s.corners());
        assert!(
            measured <= 1.0,
            "case {k}: measured corner {measured:.2} px off"
        );
        assert!(
            d.estimated[0],
            "case {k}: the hidden TL corner is not estimated: {d:?}"
        );
        assert!(
            !d.estimated[2],
            "case {k}: the visible BR corner is estimated: {d:?}"
        );
        seen += 1;
    }
    assert!(seen >= 3, "only {seen} of 4 stick scenes found");
}

#[test]
fn corner_uncertainty_covers_the_truth() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(5);
    let (mut within, mut n) = (0, 0);
    for k in 0..10 {
        let tilt = (
            rng.range(-0.6, 0.6),
            rng.range(-0.6, 0.6),
            rng.range(0.0, std::f64::consts::TAU),
        );
        let s = scene(rng.next_u64() % 256, rng.range(40.0, 160.0), tilt, k);
        let out = det.detect(&s.render());
        let d = out.first().unwrap_or_else(|| panic!("scene {k} missed"));
        let sigma = d.corner_sigma.expect("a clean tag is fitted");
        for (e, sg) in corner_errors(&d.corners, &s.corners()).iter().zip(sigma) {
            assert!(sg > 0.0 && sg < 1.0, "scene {k}: sigma {sg}");
            n += 1;
            within += usize::from(*e <= 2.0 * sg);
        }
    }
    let share = within as f64 / n as f64;
    eprintln!("corners within 2 sigma: {within} of {n}");
    assert!(share >= 0.9, "only {share:.2} of corners within 2 sigma");
}

/// Tags of data square `side` px (ct14, tilted) with a mid-grey triangle
/// over one corner, cutting 30-40% of the data square and running on over
/// the disc (the wild benchmark's `triangle` occluder), in 40 scenes:
/// how many are found, after checking that every detection has the right
/// id and no rough corner.
fn grey_triangles(side: std::ops::Range<f64>, seed: u64) -> usize {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(seed);
    let mut found = 0;
    for k in 0..40u64 {
        let id = rng.next_u64() % 256;
        let tilt = (
            rng.range(-0.6, 0.6),
            rng.range(-0.6, 0.6),
            rng.range(0.0, std::f64::consts::TAU),
        );
        let mut s = scene(id, rng.range(side.start, side.end), tilt, k);
        let grey = rng.range(100.0, 160.0) as u8;
        for poly in occluders_within(
            Occlusion::Triangle,
            rng.range(0.3, 0.4),
            (k % 4) as u32,
            rng.uniform(),
            1.0,
        ) {
            s.occluders.push(Occluder { poly, grey });
        }
        for d in &det.detect(&s.render()) {
            assert_eq!(d.id, id, "wrong id in scene {k}: {d:?}");
            let (_, rough) = judge(d, &s);
            assert!(!rough, "scene {k}: rough {d:?} truth {:?}", s.corners());
            found += 1;
        }
    }
    eprintln!("grey triangles, side {side:?} px: {found} of 40 found, none rough");
    found
}

/// Small tags: near a hidden corner the sides are cut short, and the model
/// fit, free, crept along the direction they leave unconstrained on to the
/// triangle's edges, where the tag no longer read: right readings were
/// dropped (7 of 40 found). Held near the reading's geometry on a second
/// try, it confirms them (9), and a quad guessed from one corner and the
/// centre checker forms where no other corner did (14). Taking the blur
/// bias off the refined sides (`edge_bias`; 2 points more of the wild
/// benchmark's main subset) traded scenes 3 and 18 for scene 32 (13), and
/// no longer holding readings near the code's limit to their own geometry
/// (a wild-set reading was held 15 px off; see `verify::verify`) lost two
/// more whose held fits were right (11); later changes brought it to 22.
/// Readings with two or three hidden corners that the fit places surely,
/// taken as a last resort (`decoding::Decoded::last_resort`), found 26;
/// without their bound on the estimated corners' sigma
/// (`decoding::LAST_RESORT_SIGMA_PX`), one of them (scene 16) had a hidden
/// corner 3.1 px off at a sigma of 1.3 px.
#[test]
fn small_tags_under_a_grey_triangle_are_found() {
    let found = grey_triangles(30.0..44.0, 23);
    assert!(found >= 26, "only {found} of 40 found");
}

/// Mid-sized tags, found at half resolution: both sides next to the hidden
/// corner are cut within a fifth of a side of their other ends, so those
/// corners are seldom formed, and only one corner of the square is: 21 of
/// 40 were found before the one-corner guess, 33 with it; 34 before the
/// last resorts (`decoding::Decoded::last_resort`), 37 with them.
#[test]
fn mid_sized_tags_under_a_grey_triangle_are_found() {
    let found = grey_triangles(60.0..75.0, 23);
    assert!(found >= 37, "only {found} of 40 found");
}

/// Five tags of the wild set crossed by a stick or a cable, all four
/// corners in view (`fixtures/wild/stick-crops.csv`): the stick cuts the
/// data square in two, the quads of the pieces estimate two corners each,
/// and with two estimated corners the readings were dropped (in their
/// full frames none of the five was found) until a corner whose frame and
/// margin read as printed around it, or which lies where the other three
/// put it, counted as seen when the fit supports all four. Found now, each
/// corner within 1 px.
#[test]
fn tags_cut_in_two_by_a_stick_are_found() {
    assert_eq!(crops_found("stick-crops.csv", 1.0).len(), 5);
}

/// Five small, blurred tags of the wild set read by the code with 6-7
/// corrections (`fixtures/wild/kept-crops.csv`), whose model fit, within a
/// pixel of the reading's corners, no longer reads within the code's
/// capacity: dropped as contradicted (none of the five was found, in its
/// crop or its frame), they stand on their own corners now. Each corner
/// within 1 px, fitted (with a sigma), none read by likelihood.
#[test]
fn small_code_readings_whose_fit_keeps_their_corners_stand() {
    for d in &crops_fitted("kept-crops.csv", 1.0, 5) {
        assert!(!d.likelihood && (5..=7).contains(&d.corrected), "{d:?}");
    }
}

/// Four tags (`fixtures/wild/limit-crops.csv`: one of the wild set under a
/// stick, three of the sigma calibration set, 23-35 px) read by the code
/// or by likelihood, whose model fit, checked by reading the fitted
/// geometry with no limit on the corrections, first decoded as another id
/// with 18-20 symbols corrected, past the code's limit, where a later
/// reading gave the tag's own id: dropped as contradicted (three of them
/// were not found at all; the fourth only by its print aligned to its rim,
/// with every corner estimated), they stand now that another id past the
/// limit contradicts nothing. Each fitted, every corner within 1.5 px
/// (the worst, a corner the fit estimates on a 23 px tag, is 1.0 px off),
/// and the tag under the stick with three measured corners.
#[test]
fn tags_whose_fit_reads_as_another_id_past_the_limit_are_found() {
    let found = crops_fitted("limit-crops.csv", 1.5, 4);
    let measured = found[0].estimated.iter().filter(|&&e| !e).count();
    assert!(measured >= 3, "{:?}", found[0]);
}

/// Five occluded tags of the wild set (`fixtures/wild/beside-hidden-crops.csv`:
/// a triangle, a blob, a stick, flush tape) whose readings have one corner
/// the fit cannot support, under the occluder, and another the quad
/// estimated but which is in view: with two hidden corners they were
/// dropped, until an estimated corner whose frame and margin read without
/// a single misread cell counted as seen beside an unsupported one. Each
/// corner within 2.5 px (the worst, on a 40 px tag, is 2.0 px off; a
/// rough corner is 3 px off).
#[test]
fn occluded_tags_with_one_corner_in_view_though_estimated_are_found() {
    assert_eq!(crops_found("beside-hidden-crops.csv", 2.5).len(), 5);
}

/// Five tags of the wild set under a specular glare that clips part of
/// the data square white (`fixtures/wild/glare-crops.csv`, 38-50 px): the
/// clipped cells read white whatever their colour, and the glare lifts
/// the cells around them, so no reading by the tag's levels or its
/// neighbourhoods decoded, and none of the five was found. Read now with
/// the clipped cells erased, each cell levelled between its neighbours'
/// extremes, on 8-13 symbols corrected with no error; judged as an
/// occluded tag's reading. Each corner within 2 px (the worst, a corner
/// under the glare estimated by the fit, 1.8 px off).
#[test]
fn tags_under_a_clipping_glare_are_found() {
    let found = crops_found("glare-crops.csv", 2.0);
    assert_eq!(found.len(), 5);
}

/// Five tags of the wild set under a glare that clips half the data
/// square or more (`fixtures/wild/glare-nearest-crops.csv`, 36-47 px):
/// the code's glare reading erases every symbol with a washed-out cell,
/// which left too few to stand, and none of the five was found. Read now
/// by the nearest codeword of the cells the glare left, each levelled
/// between its neighbours, as a last resort with every corner seen. Each
/// corner within 2 px.
#[test]
fn tags_with_half_their_square_clipped_by_glare_are_found() {
    crops_read_by_likelihood("glare-nearest-crops.csv", 2.0, 5);
}

/// Tags too small or blurred to make a quad of their own, a glare
/// washing out part of the data square (five wild-set frames' crops,
/// `fixtures/wild/glare-rim-crops.csv`, 29-44 px): the rim look aligned
/// the print to within a pixel, but its cells read by nothing but the
/// nearest codeword of what the glare left, a reading the rim look did
/// not try, and none was found. Read so on the aligned print, kept aside
/// as a last resort and standing with every corner seen, each is found
/// with every corner within 1.5 px.
#[test]
fn glared_tags_found_by_their_rim_read_under_the_glare() {
    for d in &crops_read_by_likelihood("glare-rim-crops.csv", 1.5, 5) {
        assert!(!d.estimated.iter().any(|&e| e), "{d:?}");
    }
}

/// A code reading near the code's limit is not held to its own geometry.
/// A white triangle over a third of a 43 px tag (the wild benchmark's
/// frame 1147, cropped) hides a corner and leaves the triangle's edge
/// against the black disc looking like a side of the frame: the quad
/// through it read the tag with 11 symbols corrected, its hidden corner
/// 15 px off. Its free fit no longer read; the second fit, held near the
/// quad, re-read the same cells and kept it, until such readings were
/// given no second fit (`verify::verify`).
#[test]
fn a_reading_near_the_limit_is_not_held_to_a_wrong_corner() {
    no_wrong_id_or_rough_corner(
        "crop-001147-1.png",
        200,
        [
            [97.311, 51.291],
            [59.523, 72.870],
            [82.537, 106.533],
            [121.846, 84.558],
        ],
    );
}

/// Detects in the wild-set crop `file` (one tag, id `id`, true corners
/// `truth`) and asserts that every detection has that id and no corner
/// more than 3 px off (a rough detection's limit on these tags).
fn no_wrong_id_or_rough_corner(file: &str, id: u64, truth: [[f64; 2]; 4]) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/wild");
    let img = image::open(dir.join(file)).unwrap().to_luma8();
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    for d in det.detect(&img) {
        assert_eq!(d.id, id, "{file}: a wrong id: {d:?}");
        let err = worst_corner_error(&d.corners, &truth);
        assert!(err <= 3.0, "{file}: a corner {err:.1} px off: {d:?}");
    }
}

/// A reading near the code's limit whose hidden corners no perspective
/// could put there is dropped. A white triangle over the lower left of a
/// 44 px tag, strongly tilted (the calibration set's frame 515, cropped):
/// the triangle's edge was taken for the bottom side, and the reading, 10
/// symbols corrected, came out with two estimated corners, one 15.6 px
/// off, 0.26 of the side from the parallelogram of the other three (the
/// right readings near the limit on the wild set: at most 0.144).
#[test]
fn a_reading_near_the_limit_with_an_implausible_hidden_corner_is_dropped() {
    no_wrong_id_or_rough_corner(
        "crop-calib-000515-1.png",
        137,
        [
            [103.586, 98.91],
            [97.531, 52.657],
            [57.851, 62.893],
            [62.441, 107.457],
        ],
    );
}

/// Two tags of the wild set read under an occluder whose model fit leaves
/// two corners unsupported (`fixtures/wild/hidden-fit-crops.csv`: paint
/// over one side, 36% of a 40 px tag; a cable across two opposite
/// corners, 27% of a 42 px tag): with nothing on the quad to check two
/// hidden corners by, they were dropped (in their frames too), until a
/// fit placing each hidden corner with a sigma of at most 1.5 px counted
/// as a check. Found now, each corner within 1 px, the two hidden ones
/// estimated with that sigma.
#[test]
fn occluded_tags_whose_fit_places_two_hidden_corners_surely_are_found() {
    let found = crops_found("hidden-fit-crops.csv", 1.0);
    assert_eq!(found.len(), 2);
    for d in &found {
        let sigma = d.corner_sigma.expect("fitted");
        let hidden: Vec<usize> = (0..4).filter(|&k| d.estimated[k]).collect();
        assert_eq!(hidden.len(), 2, "{d:?}");
        assert!(hidden.iter().all(|&k| sigma[k] <= 1.5), "{d:?}");
    }
}

/// Seven tags of the wild set with one side of the data square hidden
/// (`fixtures/wild/hidden-side-crops.csv`, 28-41 px, cells of 1.7-2.5 px:
/// a grey or dark block along a side, flush tape, a cable), read with 8-10
/// symbols corrected. Three sides alone leave the homography two unknowns
/// free, and the model fit of the sides ran off along them: the readings
/// were dropped as unfit, and of the two found in their crops one had a
/// corner 1.4 px off (in their frames, three had one 3.1-4.5 px off,
/// rough, and were dropped). Where a side shows too few edge points, the
/// fit measures the cell edges too, which pin the hidden side down: each
/// is found now, fitted, every corner within 0.9 px (the worst 0.8 px),
/// with a corner estimated.
#[test]
fn tags_with_a_hidden_side_are_fitted_by_their_cells() {
    for d in &crops_fitted("hidden-side-crops.csv", 0.9, 7) {
        assert!(d.estimated.iter().any(|&e| e), "no corner estimated: {d:?}");
    }
}

/// Five small tags of the wild set under occluders
/// (`fixtures/wild/fragile-fit-crops.csv`, 19-27 px, cells of 1.2-1.7 px),
/// read by the code with 5-7 symbols corrected through quads within
/// 0.15 px of the truth. Their cells are too small for the model fit to
/// measure, and the fit of their sides ran 1-9.5 px off along an
/// occluder's edge, read nothing there and dropped them. A reading that
/// stands without a fit now stands against such a fit too, as unfit
/// (`decoding::small_cells`): each is found, every corner within 0.2 px,
/// with no sigma.
#[test]
fn small_code_readings_stand_against_a_fit_of_their_sides() {
    let found = crops_found("fragile-fit-crops.csv", 0.2);
    assert_eq!(found.len(), 5);
    for d in &found {
        assert!(!d.likelihood && (5..=7).contains(&d.corrected), "{d:?}");
        assert!(d.corner_sigma.is_none(), "fitted: {d:?}");
    }
}

/// Six tags with an occluder's edge along a side, over the white margin
/// (`fixtures/wild/off-side-crops.csv`: five of the ct8 twin, 30-49 px,
/// a grey or dark block flush with a side, or a smear that blurs a side
/// into the block beside it; one of the wild set). Every point of that
/// edge agrees with the others, so the fit kept them all and settled
/// between them and the cell edges: a corner 1.2-4.2 px off, claimed
/// measured. The side whose points lie off the line the rest of the fit
/// puts them on (`verify::OFF_SIDE_CELLS`) now gets no vote: each tag is
/// found, every corner within 0.95 px (the worst 0.91 px), the two corners
/// of the side left out estimated.
#[test]
fn tags_whose_side_is_an_occluders_edge_are_fitted_without_it() {
    for d in &crops_fitted("off-side-crops.csv", 0.95, 6) {
        let side_estimated = (0..4).any(|k| d.estimated[k] && d.estimated[(k + 1) % 4]);
        assert!(side_estimated, "{d:?}");
    }
}

/// Six tags of the wild set under occluders that hide two or three of
/// their corners (`fixtures/wild/last-resort-crops.csv`: two triangles,
/// a cable, a stick, a block along a side, a diagonal band; 20-50 px,
/// 35-40% of the square covered in four). Each was read with the right id,
/// its hidden corners placed by the model fit at a sigma under
/// `decoding::HIDDEN_FIT_SIGMA_PX`, and was dropped when read, as the quad
/// could not check them. Such a reading now stands as a last resort, where
/// no look finds a tag (`decoding::Decoded::last_resort`): each is found,
/// every corner within 0.8 px (the worst 0.74 px), two or more corners
/// estimated, each with a sigma.
#[test]
fn tags_with_two_hidden_corners_the_fit_places_stand_as_a_last_resort() {
    for d in &crops_fitted("last-resort-crops.csv", 0.8, 6) {
        assert!(d.estimated.iter().filter(|&&e| e).count() >= 2, "{d:?}");
    }
}

/// Five tags of the wild set under a glare and an occluder (a triangle,
/// flush tape, an inner or a same-side shape) that hide some of their
/// corners (`fixtures/wild/glare-print-crops.csv`, 29-37 px): their
/// readings under the glare were refused for the hidden corners, which
/// nothing but the fit of the tag's model placed, and none of the five
/// was found. Kept now where the print's fixed look, aligned
/// on its own from the fitted corners, puts every hidden corner within
/// 1.5 px of the fit's: each is found with some corner estimated and every
/// corner within 1.5 px of the truth.
#[test]
fn glared_tags_with_hidden_corners_the_aligned_print_confirms_are_found() {
    for d in &crops_read_by_likelihood("glare-print-crops.csv", 1.5, 5) {
        assert!(d.estimated.iter().any(|&e| e), "{d:?}");
    }
}

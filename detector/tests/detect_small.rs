//! Small tags at the default (downsampled) settings: the full-resolution
//! look around small disc rims (`DetectorConfig::small_tags`) must find
//! data squares of 22-40 px that the downsampled pass alone loses, with the
//! right ids and sub-pixel corners, and must not touch large tags.

use crate::common;

use common::*;
use coppertag::{Detector, DetectorConfig, Family};

/// One tag of `family` with a data square of about `side_px` px, tilted,
/// somewhere in a 640 x 480 frame (the wild benchmark's VGA camera).
fn scene(family: &'static Family, id: u64, side_px: f64, rng: &mut Rng) -> Scene {
    let r = rotation(
        rng.range(-0.5, 0.5),
        rng.range(-0.5, 0.5),
        rng.range(0.0, std::f64::consts::TAU),
    );
    // Anywhere the whole tag (twice the data square) stays in the frame.
    let (px, py) = (
        rng.range(2.0 * side_px, 640.0 - 2.0 * side_px),
        rng.range(2.0 * side_px, 480.0 - 2.0 * side_px),
    );
    let mut s = vga_scene(family, id, side_px, &r, px, py);
    s.blur = 0.5;
    s.noise = 2.0;
    s.seed = rng.next_u64();
    s
}

/// Detects `s` (one tag of `family`, `id`): 1 if found, 0 if not; any
/// detection must be that tag with every corner within 1 px.
fn found_right(det: &mut Detector, s: &Scene, family: &Family, id: u64, what: &str) -> u32 {
    let out = det.detect(&s.render());
    assert!(out.len() <= 1, "{what}: {out:?}");
    for d in &out {
        assert_eq!((d.family.as_str(), d.id), (family.name(), id), "{what}");
        let err = worst_corner_error(&d.corners, &s.corners());
        assert!(err <= 1.0, "{what}: corner {err:.2} px off");
    }
    u32::from(!out.is_empty())
}

/// Found share of 24 small tags (ct14 22-40 px, ct8 20-32 px) with
/// `small_tags` on and off; every detection must have the right id and
/// corners within 1 px.
fn found_share(small_tags: bool) -> f64 {
    let mut det = Detector::new(DetectorConfig {
        small_tags,
        ..DetectorConfig::default()
    })
    .unwrap();
    let mut rng = Rng::new(5);
    let mut found = 0;
    let total = 24;
    for k in 0..total {
        let (family, side) = if k % 3 == 2 {
            (Family::ct8(), rng.range(20.0, 32.0))
        } else {
            (Family::ct14(), rng.range(22.0, 40.0))
        };
        let id = rng.next_u64() % 256;
        let s = scene(family, id, side, &mut rng);
        found += found_right(
            &mut det,
            &s,
            family,
            id,
            &format!("scene {k} ({side:.1} px)"),
        );
    }
    f64::from(found) / f64::from(total)
}

#[test]
fn small_tags_are_found_at_the_default_downsampling() {
    let with = found_share(true);
    let without = found_share(false);
    eprintln!("small tags found: {with:.2} with the full-resolution look, {without:.2} without");
    assert!(with >= 0.9, "only {with:.2} of the small tags found");
    // Without the second look the rim look, last, reads most of these
    // sharp, unoccluded tags from their rims (measured: 0.92, where it
    // was 0.50 before the rim look); on the wild set's 3000 frames turning
    // the second look off loses 463 of 3677 tags (occluded and blurred
    // ones the rim look leaves), so it stays on.
    assert!(
        with >= without,
        "the full-resolution look loses tags: {with:.2} against {without:.2}"
    );
}

#[test]
fn a_large_tag_needs_no_second_look() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(9);
    let s = scene(Family::ct14(), 77, 120.0, &mut rng);
    let out = det.detect(&s.render());
    assert_eq!(out.len(), 1);
    assert_eq!(det.stats().small_regions, 0, "{:?}", det.stats());
}

/// A defocused tag whose cells have faded into each other (blur sigma
/// 0.4-0.55 of a cell): the plain reading fails, the deblurred one must
/// read it (the defocus challenge set's far end).
#[test]
fn defocused_tags_are_read() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(21);
    let mut found = 0;
    let total = 6;
    for k in 0..total {
        let side = rng.range(90.0, 110.0);
        let id = rng.next_u64() % 256;
        let mut s = scene(Family::ct14(), id, side, &mut rng);
        let cell = side / 16.0;
        s.blur = (rng.range(0.4, 0.55) * cell) as f32;
        let out = det.detect(&s.render());
        for d in &out {
            assert_eq!(d.id, id, "scene {k}");
            let err = worst_corner_error(&d.corners, &s.corners());
            // Never rough (the wild benchmark's rule): a corner of a tag
            // blurred this much is rounded over several pixels.
            assert!(
                err <= rough_bound(side),
                "scene {k}: corner {err:.2} px off: {d:?} truth {:?}",
                s.corners()
            );
            found += 1;
        }
    }
    eprintln!("defocused tags found: {found} of {total}");
    assert!(
        found >= total - 1,
        "only {found} of {total} defocused tags read"
    );
}

/// Found share of 24 ct14 tags of 18-26 px, tilted 30-55 degrees about
/// both axes; every detection must have the right id and corners within
/// 1 px.
fn tilted_tiny_found() -> f64 {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(31);
    let (mut found, total) = (0, 24);
    for k in 0..total {
        let side = rng.range(18.0, 26.0);
        let tilt = |rng: &mut Rng| {
            rng.range(0.52, 0.96) * if rng.range(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 }
        };
        let r = rotation(
            tilt(&mut rng),
            tilt(&mut rng),
            rng.range(0.0, std::f64::consts::TAU),
        );
        let (px, py) = (rng.range(80.0, 560.0), rng.range(80.0, 400.0));
        let id = rng.next_u64() % 256;
        let mut s = vga_scene(Family::ct14(), id, side, &r, px, py);
        s.blur = 0.5;
        s.noise = 2.0;
        s.seed = rng.next_u64();
        found += found_right(
            &mut det,
            &s,
            Family::ct14(),
            id,
            &format!("scene {k} ({side:.1} px)"),
        );
    }
    f64::from(found) / f64::from(total)
}

/// Tiny, steeply tilted tags: at full resolution the one-cell white
/// margin inside the disc is a line one or two pixels wide and the data
/// square's border does not close; the look at the region upsampled 2x
/// must find them.
#[test]
fn tiny_tilted_tags_are_found_upsampled() {
    let share = tilted_tiny_found();
    eprintln!("tiny tilted tags found: {share:.2}");
    // 0.46 with the upsampled look, 0.25 without (full resolution only).
    assert!(
        share >= 0.4,
        "only {share:.2} of the tiny tilted tags found"
    );
}

/// Five small tags of the wild set (`fixtures/wild/rim-offset-crops.csv`,
/// 23-34 px; a cable, a stick, a glare spot, blur) whose disc rim,
/// partly hidden or joined to clutter, was fitted to what was left of it:
/// smaller than the disc and off its centre, so that the data square found
/// at full resolution lay more than half a rim axis from the rim's centre,
/// or had sides longer than 1.6 axes, and was not taken as the rim's (none
/// of the five was found, in its crop or its frame). Found now, each
/// corner within 1 px.
#[test]
fn data_squares_off_a_partly_hidden_rim_are_taken() {
    assert_eq!(crops_found("rim-offset-crops.csv", 1.0).len(), 5);
}

/// Six small tags of the wild set (`fixtures/wild/unread-crops.csv`,
/// 17-25 px: under a glare, a stick, a diagonal or a symmetric occluder,
/// motion blur, JPEG) whose quads read nothing where refinement put them,
/// a pixel or so off on cells of 1-1.6 px, and which no other look found
/// (none of the six was found, in its crop or its frame). Found now by
/// aligning the print to those quads after every look
/// (`decoding::aligned_unread`): each reported with a sigma for its
/// corners, every corner within 0.8 px of the truth.
#[test]
fn small_tags_whose_quads_read_nothing_are_read_on_the_aligned_print() {
    crops_fitted("unread-crops.csv", 0.8, 6);
}

/// Three small ct8 tags of the wild benchmark's 1080p frames
/// (`fixtures/bench/`, 26-32 px), each read at its first quad by a
/// detector of both families; a ct14-only detector recognises each as a
/// ct8 tag from its first quads that read nothing (their plain code
/// reading as ct8), and looks neither at its rim nor at its other quads.
/// (Without that, the ct14-only detector decoded 6, 5 and 9 of their
/// quads, each tag's rim once, and took 2-6 ms per crop.)
#[test]
fn small_tags_of_a_family_not_decoded_are_passed_over() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bench");
    let mut both = Detector::new(DetectorConfig::default()).unwrap();
    let mut ct14 =
        Detector::new(DetectorConfig::with_builtin_families(&["ct14"]).unwrap()).unwrap();
    for (file, id) in [
        ("ct8-01-50957.png", 50957),
        ("ct8-04-9407.png", 9407),
        ("ct8-10-12514.png", 12514),
    ] {
        let img = image::open(dir.join(file)).unwrap().to_luma8();
        let found = both.detect(&img);
        assert_eq!(found.len(), 1, "{file}: {found:?}");
        assert_eq!(
            (found[0].family.as_str(), found[0].id),
            ("ct8", id),
            "{file}"
        );
        assert!(ct14.detect(&img).is_empty(), "{file}");
        let st = ct14.stats();
        assert!(st.decode_attempts <= 2, "{file}: {st:?}");
        assert_eq!(st.rim_decodes, 0, "{file}: {st:?}");
    }
}

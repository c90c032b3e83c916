//! Small, defocused ct14 tags: cells of 1.7-2.5 px under a blur of 0.6-0.9
//! cells, where a cell-by-cell reading misreads more symbols than the
//! Reed-Solomon code corrects. The likelihood reading (the whole grid
//! against every codeword as the blur shows it) must find most of them,
//! with the right ids and corners (none rough), each confirmed by the model
//! fit.

use crate::common;

use common::*;
use coppertag::{Detector, DetectorConfig};

/// One ct14 tag with a data square of about `side_px` px, tilted, in a
/// 640 x 480 frame, blurred by `blur` px.
fn scene(id: u64, side_px: f64, blur: f32, rng: &mut Rng) -> Scene {
    blurred_vga_scene(id, side_px, blur, 0.4, 2.0, rng)
}

#[test]
fn blurred_small_tags_are_read_by_likelihood_with_right_corners() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(11);
    let total = 24;
    let (mut found, mut by_likelihood) = (0, 0);
    for k in 0..total {
        let side = rng.range(28.0, 40.0);
        // Blur of 0.6-0.9 cells (a cell is side / 16).
        let blur = (rng.range(0.6, 0.9) * side / 16.0) as f32;
        let id = rng.next_u64() % 256;
        let s = scene(id, side, blur, &mut rng);
        let out = det.detect(&s.render());
        assert!(out.len() <= 1, "scene {k}: {out:?}");
        for d in &out {
            assert_eq!(d.id, id, "scene {k}: wrong id");
            let err = worst_corner_error(&d.corners, &s.corners());
            assert!(
                err <= rough_bound(side),
                "scene {k} ({side:.1} px, blur {blur:.2} px): corner {err:.2} px off"
            );
            if d.likelihood {
                assert!(
                    d.corner_sigma.is_some(),
                    "scene {k}: a likelihood reading stands only with the model fit"
                );
                by_likelihood += 1;
            }
            found += 1;
        }
    }
    eprintln!("found {found}/{total}, {by_likelihood} by likelihood");
    // Measured: 17 of 24, 14 of them by likelihood; the hard reading alone
    // finds 3.
    assert!(found >= 14, "found {found} of {total}");
    assert!(
        by_likelihood >= 8,
        "only {by_likelihood} read by likelihood: the scenes no longer test it"
    );
}

/// Four small, slightly blurred tags cut from the wild set's frames
/// (`tests/fixtures/wild/`), each read by likelihood on its own corners
/// within a pixel and a half of the truth (1.51 px at most; 1.22 px before
/// the sides' blur bias was taken off, which brought the wild set's
/// blurred corners closer on average but this crop's worst one 0.4 px
/// further). The model fit of the sides alone puts
/// their corners 0.5-1.5 px off, where the grid no longer reads clearly as
/// the tag; the readings were dropped for it until a likelihood reading
/// whose fit keeps its corners was let stand on them (none of the four
/// was found before).
#[test]
fn wild_likelihood_readings_stand_on_their_own_corners() {
    crops_read_by_likelihood("likelihood-crops.csv", 1.6, 4);
}

/// Blur does not make a tag look larger. The side of a data square is
/// measured where its profile crosses halfway between the white margin
/// and the black frame, and the margin is one cell wide: under a blur of
/// most of a cell its white sinks towards grey, and the halfway level
/// with it, so that the crossing moves out into the frame. Refinement and
/// the model fit take that bias off (`detect::edge_bias`); without it, the
/// corners of these tags lay 0.63 px too far from the tag centre on
/// average (now 0.11 px), and those of the wild benchmark's blurred
/// 32-48 px tags 0.3-0.5 px.
#[test]
fn blurred_tags_are_not_measured_too_large() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(29);
    let (mut radial, mut corners) = (0.0, 0);
    for k in 0..24 {
        let side = rng.range(36.0, 56.0);
        // Blur of 0.5-0.8 cells: readable, and well into the margin.
        let blur = (rng.range(0.5, 0.8) * side / 16.0) as f32;
        let id = rng.next_u64() % 256;
        let s = scene(id, side, blur, &mut rng);
        let truth = s.corners();
        let centre = truth
            .iter()
            .fold([0.0; 2], |c, p| [c[0] + p[0] / 4.0, c[1] + p[1] / 4.0]);
        for d in det.detect(&s.render()) {
            assert_eq!(d.id, id, "scene {k}: wrong id");
            for (p, t) in d.corners.iter().zip(&truth) {
                // The corner's offset along the ray from the centre.
                let out = [t[0] - centre[0], t[1] - centre[1]];
                let len = out[0].hypot(out[1]);
                radial += ((p[0] - t[0]) * out[0] + (p[1] - t[1]) * out[1]) / len;
                corners += 1;
            }
        }
    }
    assert!(corners >= 4 * 16, "only {} tags found", corners / 4);
    let mean = radial / corners as f64;
    eprintln!(
        "{} tags, corners {mean:+.3} px from the centre on average",
        corners / 4
    );
    // Measured: +0.11 px, against +0.63 px without the bias taken off.
    assert!(
        mean.abs() < 0.2,
        "corners {mean:+.3} px outwards on average"
    );
}

/// Six tags of the wild set blurred by 0.7-1.35 cells (three under an
/// occluder), cut from its frames (`tests/fixtures/wild/faint-crops.csv`).
/// Their cells show several times the contrast of the frame and margin
/// around them, which blur drags together, so their likelihood readings
/// are faint (`QuadReading::faint`) and stand only on the corners of the
/// print aligned to the image. None was found before faint readings
/// were let stand; now each is, within 0.41 px of the truth (measured),
/// with the model fit's sigma.
#[test]
fn faint_readings_stand_on_the_aligned_print() {
    crops_read_by_likelihood("faint-crops.csv", 0.6, 6);
}

/// Seven tags of the wild set (26-43 px), five smeared by motion (4.3-5.5
/// px) and two defocused (one under a cable), cut from its frames
/// (`tests/fixtures/wild/smear-confirm-crops.csv`). On their grids the
/// round likelihood fit leads without reading, and the quad aligned to
/// the leading codeword does not read either; the smear reading, which
/// does, was then not tried: not at the verify stage's confirming reading
/// on the fitted corners, nor at the rim look's small moves of its aligned
/// print, which aligned again instead. None was found before those
/// readings tried it (`decode::Promising`); now each is, every corner
/// within 0.6 px (0.58 px at most, measured), with a fitted sigma.
#[test]
fn smeared_tags_are_read_where_alignment_does_not_help() {
    crops_fitted("smear-confirm-crops.csv", 0.6, 7);
}

/// `decode_quad` reads a grid on the corners it is given as the verify
/// stage reads one on its fitted corners: where the quad aligned to the
/// leading codeword does not read, as smeared by motion. Six of the
/// crops above read so at their true corners, each as its own id (none
/// did before); the seventh (`crop-000099-0.png`, under a cable, in
/// uneven light) reads as shaded (`QuadReading::shaded`: its light fitted
/// with each codeword), and read nowhere at its true corners before that.
#[test]
fn decode_quad_reads_smeared_tags_at_their_true_corners() {
    let fam = coppertag::Family::by_name("ct14").unwrap();
    let mut smeared = Vec::new();
    for c in crops("smear-confirm-crops.csv") {
        let r = coppertag::decode_quad(&c.img, fam, &c.truth)
            .unwrap_or_else(|| panic!("{}: not read", c.file));
        assert_eq!(r.id, c.id, "{}: a wrong id", c.file);
        if c.file == "crop-000099-0.png" {
            assert!(r.shaded && !r.smeared, "{}: {r:?}", c.file);
        } else {
            assert!(r.smeared, "{}: not read as smeared: {r:?}", c.file);
            smeared.push(c.file);
        }
    }
    assert_eq!(smeared.len(), 6, "smeared: {smeared:?}");
}

/// Six tags of the wild set smeared by motion (4.2-5.8 px), cut from its
/// frames (`tests/fixtures/wild/smear-sigma-crops.csv`), each read where a
/// reading as smeared confirmed the model fit. The fit takes the smeared
/// edges for evenly blurred ones and puts a corner up to 1.86 px off at a
/// sigma of 0.3 px: 14 of their 24 corners lay within 2 sigma. Their sigma
/// is now at least 0.02 of the side (`decoding::SMEAR_SIGMA_OF_SIDE`), and
/// 20 of the 24 corners lie within 2 sigma (measured), every corner still
/// within 2 px.
#[test]
fn corners_confirmed_as_smeared_are_not_claimed_too_surely() {
    let found = crops_found("smear-sigma-crops.csv", 2.0);
    assert_eq!(found.len(), 6);
    let mut within = 0;
    for (d, c) in found.iter().zip(crops("smear-sigma-crops.csv")) {
        let sigma = d.corner_sigma.expect("fitted");
        let side = (0..4)
            .map(|k| {
                let (a, b) = (d.corners[k], d.corners[(k + 1) % 4]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .sum::<f64>()
            / 4.0;
        assert!(sigma.iter().all(|&s| s >= 0.02 * side), "{d:?}");
        within += corner_errors(&d.corners, &c.truth)
            .iter()
            .zip(sigma)
            .filter(|(e, s)| **e <= 2.0 * s)
            .count();
    }
    assert!(within >= 20, "{within} of 24 corners within 2 sigma");
}

/// Eight tags of the wild set that no reading read before the shaded one
/// (`decode::QuadReading::shaded`: the likelihood reading with a smooth
/// light field fitted with each codeword and the clipped cells left out),
/// in `fixtures/wild/shaded-crops.csv`: five under a glare spot (31-44 px),
/// three blurred under uneven light (25-32 px). Each is found as a last
/// resort, every corner within 1 px of the truth (the worst 0.7 px).
#[test]
fn tags_under_glare_or_uneven_light_read_with_the_light_fitted() {
    crops_read_by_likelihood("shaded-crops.csv", 1.0, 8);
}

/// The rendered scenes blur only around the tag ([`blur_around`]), to the
/// same bytes as blurring the whole frame: tags of 10-240 px at any turn,
/// under blurs of 0.3-6 px, anywhere in the frame, partly off it, on
/// backgrounds dark and light.
#[test]
fn blurring_around_the_tag_gives_the_whole_frames_blur() {
    use coppertag::homography::Homography;
    use nalgebra::Matrix3;
    let mut rng = Rng::new(5);
    for k in 0..60 {
        let (w, h) = (320, 240);
        let half = rng.range(5.0, 120.0);
        let turn = rng.range(0.0, 6.3);
        let c = [rng.range(-60.0, 380.0), rng.range(-60.0, 300.0)];
        let m = Matrix3::new(
            half * turn.cos(),
            -half * turn.sin(),
            c[0],
            half * turn.sin(),
            half * turn.cos(),
            c[1],
            0.0,
            0.0,
            1.0,
        );
        let mut s = Scene::new(
            coppertag::Family::ct14(),
            rng.next_u64() % 256,
            w,
            h,
            Homography::from_matrix(m),
        );
        s.background = (rng.next_u64() % 256) as u8;
        let blur = rng.range(0.3, 6.0) as f32;
        let mut painted = image::GrayImage::from_pixel(w, h, image::Luma([s.background]));
        s.paint(&mut painted);
        assert_eq!(
            blur_around(&painted, blur, s.painted_box(), s.background),
            imageproc::filter::gaussian_blur_f32(&painted, blur),
            "scene {k}: tag of {:.0} px at {c:?}, blur {blur:.2} px",
            2.0 * half
        );
    }
}

/// `img` smeared by a straight motion of `length` px at `angle` (rad): each
/// pixel the mean of bilinear samples along the segment through it,
/// clamped at the border (the synth's motion blur, written again here so
/// that the detector's tests need nothing of the renderer's crate).
fn smear(img: &image::GrayImage, length: f64, angle: f64) -> image::GrayImage {
    let (w, h) = img.dimensions();
    let at = |x: f64, y: f64| {
        let x = x.clamp(0.0, f64::from(w - 1));
        let y = y.clamp(0.0, f64::from(h - 1));
        let (x0, y0) = (x.floor() as u32, y.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - f64::from(x0), y - f64::from(y0));
        let p = |x, y| f64::from(img.get_pixel(x, y).0[0]);
        (p(x0, y0) * (1.0 - fx) + p(x1, y0) * fx) * (1.0 - fy)
            + (p(x0, y1) * (1.0 - fx) + p(x1, y1) * fx) * fy
    };
    let n = (length.ceil() as usize) * 2 + 1;
    let (s, c) = angle.sin_cos();
    image::GrayImage::from_fn(w, h, |x, y| {
        let sum: f64 = (0..n)
            .map(|k| {
                let t = (k as f64 / (n - 1) as f64 - 0.5) * length;
                at(f64::from(x) + t * c, f64::from(y) + t * s)
            })
            .sum();
        image::Luma([(sum / n as f64).round() as u8])
    })
}

/// A tag smeared by motion along its sides blurs two sides and leaves two
/// sharp, and the fit's blur term, the median over all sides, does not
/// see the smear: its corners then lie further off than their sigma says
/// (on the dense frames a ct14 tag smeared 10 px was reported at sigma
/// 0.26 px, 4.8 px off). Where the sides' blurs differ by over
/// `SMEAR_SPREAD_PX`, the fit takes the smear's sigma floor, 2% of the
/// side (`SMEAR_SIGMA_OF_SIDE`), whichever reading confirmed the tag. On
/// tags smeared 2-2.5 cells along a side, most corners found must then lie
/// within 2 sigma of the truth; the same tags defocused as much must not
/// get the floor (their sides blur alike).
#[test]
fn smeared_tags_carry_the_smear_sigma_floor_and_evenly_blurred_ones_do_not() {
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let mut rng = Rng::new(23);
    let total = 12;
    let (mut smeared_found, mut even_found) = (0, 0);
    let (mut corners, mut within) = (0, 0);
    for k in 0..total {
        let side = rng.range(70.0, 90.0);
        let roll = rng.range(0.0, std::f64::consts::TAU);
        let r = rotation(rng.range(-0.2, 0.2), rng.range(-0.2, 0.2), roll);
        let (px, py) = (rng.range(200.0, 440.0), rng.range(180.0, 300.0));
        let id = rng.next_u64() % 256;
        let mut s = vga_scene(coppertag::Family::ct14(), id, side, &r, px, py);
        s.noise = 1.5;
        s.seed = rng.next_u64();
        // Along a side, within 8 degrees; 2-2.5 cells long (the dense
        // frame's tag: 10 px on a 70 px square).
        let angle = roll + rng.range(-0.14, 0.14);
        let length = rng.range(2.0, 2.5) * side / 16.0;
        for d in det.detect(&smear(&s.render(), length, angle)) {
            assert_eq!(d.id, id, "scene {k}: wrong id");
            let sigma = d.corner_sigma.expect("a fitted reading");
            let err = corner_errors(&d.corners, &s.corners());
            eprintln!("scene {k}, smeared {length:.1} px: errors {err:.2?}, sigma {sigma:.2?}");
            corners += 4;
            within += (0..4).filter(|&c| err[c] <= 2.0 * sigma[c]).count();
            smeared_found += 1;
        }
        // The same tag defocused as much as the smear's own spread
        // (a box of length L has a standard deviation of L / sqrt(12)).
        s.blur = (length / 12f64.sqrt()) as f32;
        let floor = 0.02 * side;
        for d in det.detect(&s.render()) {
            assert_eq!(d.id, id, "scene {k}: wrong id");
            let sigma = d.corner_sigma.expect("a fitted reading");
            assert!(
                sigma.iter().all(|&sg| sg < floor),
                "scene {k} ({side:.0} px, defocus {:.1} px): sigma {sigma:?} at the smear's \
                 floor {floor:.2}",
                s.blur
            );
            even_found += 1;
        }
    }
    eprintln!(
        "smeared: {smeared_found}/{total} found, {within} of {corners} corners within 2 sigma; \
         defocused: {even_found}/{total}"
    );
    assert!(
        smeared_found >= total / 2,
        "smeared: {smeared_found} of {total}"
    );
    assert!(
        even_found >= total / 2,
        "defocused: {even_found} of {total}"
    );
    assert!(
        within as f64 >= MIN_SMEARED_WITHIN * corners as f64,
        "{within} of {corners} smeared corners within 2 sigma"
    );
}

/// Share of the smeared tags' corners that must lie within 2 sigma in
/// [`smeared_tags_carry_the_smear_sigma_floor_and_evenly_blurred_ones_do_not`].
/// Measured: 32 of 40 (10 tags found); without the floor from the sides'
/// blurs 26 of 44 (11 found: the one more is a tag reported with a corner
/// 6.45 px off at sigma 0.40 px, which the floor lifts over the bound of
/// its estimated corner and drops). Two of the 10 are still rough (a corner
/// 4.6 and 8.9 px off at sigma 1.7 px): a smear of two cells and more is
/// where the dense frames' rough detections come from, and this is not
/// their fix.
const MIN_SMEARED_WITHIN: f64 = 0.7;

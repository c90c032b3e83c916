//! The reference photo (`fixtures/coppertag-photo.jpg`, 1920 x 1080, a copy
//! of the project's shared reference image): six ct14 tags on a table among
//! a cable, an Allen key, a sticker, leaves and a light wooden stick. Tag 26
//! lies under the stick, which crosses its left and right sides and hides
//! those two corners: its frame is cut in two, and the stick hides ten of
//! its Reed-Solomon symbols' worth of cells.

use coppertag::{Detector, DetectorConfig};

/// Tag 26's data-square corners measured by hand, in image order top,
/// left, bottom, right (pixel-centre coordinates). How: on each side's
/// visible stretch (chosen by eye away from the corners, the stick and the
/// printed "26" over the right side), 60 profiles across the edge, each
/// edge point where the grey crosses halfway between the frame's black and
/// the square's white (bilinear sampling, 0.25 px steps); a straight line
/// fitted to each side's points (residuals 0.12-0.20 px rms); corners
/// where adjacent lines meet. The left and right corners are hidden under
/// the stick, so they are the extended sides' intersections.
const TAG26_BY_HAND: [[f64; 2]; 4] = [
    [720.3, 782.4],
    [601.4, 850.3],
    [663.9, 974.9],
    [785.6, 903.9],
];

/// Largest distance (px) of any corner of tag 26 from its hand position:
/// the hidden corners are extrapolated along sides cut by the stick.
const HAND_TOLERANCE_PX: f64 = 4.0;

/// Largest distance (px) of a corner the detector marks as measured from
/// its hand position.
const MEASURED_TOLERANCE_PX: f64 = 3.0;

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[test]
fn all_six_tags_of_the_reference_photo() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/coppertag-photo.jpg"
    );
    let img = image::open(path).expect("fixture").to_luma8();
    let mut det = Detector::new(DetectorConfig::default()).unwrap();
    let found = det.detect(&img);
    let ids: Vec<(&str, u64)> = found.iter().map(|d| (d.family.as_str(), d.id)).collect();
    assert_eq!(
        ids,
        [
            ("ct14", 1),
            ("ct14", 4),
            ("ct14", 21),
            ("ct14", 26),
            ("ct14", 188),
            ("ct14", 209)
        ],
        "{found:#?}"
    );
    let tag26 = &found[3];
    for (k, c) in tag26.corners.iter().enumerate() {
        let d = TAG26_BY_HAND
            .iter()
            .map(|&h| distance(*c, h))
            .fold(f64::INFINITY, f64::min);
        assert!(d <= HAND_TOLERANCE_PX, "corner {k} {c:?}: {d:.2} px off");
        if !tag26.estimated[k] {
            assert!(
                d <= MEASURED_TOLERANCE_PX,
                "measured corner {k} {c:?}: {d:.2} px off"
            );
        }
    }
    // Each hand corner has its own detected corner.
    for h in TAG26_BY_HAND {
        let near = tag26
            .corners
            .iter()
            .filter(|&&c| distance(c, h) <= HAND_TOLERANCE_PX)
            .count();
        assert_eq!(near, 1, "hand corner {h:?}: {:?}", tag26.corners);
    }
}

//! The detector's input and family API: a borrowed buffer with a row
//! stride gives the same detections as the packed image, and a family made
//! with `Family::from_spec` (the paper's RS(20,4) variant of ct14) is
//! detected end to end.

use crate::common;

use common::*;
use coppertag::{Detector, DetectorConfig, Family, FamilySetting, GrayView};
use image::GrayImage;

/// `img` copied into a buffer whose rows are `pad` bytes longer than the
/// image (the padding holds noise-like bytes the detector must not read).
fn padded(img: &GrayImage, pad: usize) -> (Vec<u8>, usize) {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let stride = w + pad;
    let mut buf = vec![0u8; stride * h];
    for (y, row) in img.as_raw().chunks_exact(w).enumerate() {
        buf[y * stride..y * stride + w].copy_from_slice(row);
        for (k, b) in buf[y * stride + w..(y + 1) * stride].iter_mut().enumerate() {
            *b = ((y * 31 + k * 97) % 256) as u8;
        }
    }
    // The last row may end right after its pixels.
    buf.truncate(stride * (h - 1) + w);
    (buf, stride)
}

#[test]
fn a_row_stride_gives_the_same_detections() {
    let occluded = {
        let mut s = paper_scene(Family::ct14(), 113, 0.8, &rotation(0.3, -0.2, 0.4));
        s.occluders = occluders(Occlusion::Triangle, 0.1, 1, 0.3)
            .into_iter()
            .map(|poly| Occluder { poly, grey: 20 })
            .collect();
        s
    };
    let scenes = [
        paper_scene(Family::ct14(), 42, 1.0, &rotation(0.35, -0.25, 0.6)),
        paper_scene(Family::ct8(), 4097, 1.2, &rotation(-0.2, 0.3, 2.0)),
        occluded,
    ];
    for downsample in [1, 2] {
        let cfg = DetectorConfig {
            downsample,
            ..DetectorConfig::default()
        };
        let mut det = Detector::new(cfg).unwrap();
        for (k, s) in scenes.iter().enumerate() {
            let img = s.render();
            let packed = det.detect(&img);
            assert_eq!(packed.len(), 1, "scene {k}, downsample {downsample}");
            for pad in [1, 13, 64] {
                let (buf, stride) = padded(&img, pad);
                let view = GrayView::new(&buf, img.width(), img.height(), stride).unwrap();
                assert_eq!(
                    det.detect(view),
                    packed,
                    "scene {k}, downsample {downsample}, stride {stride}"
                );
            }
        }
    }
}

#[test]
fn a_bad_view_is_an_error() {
    let buf = vec![0u8; 100];
    assert!(GrayView::new(&buf, 20, 5, 19).is_err());
    assert!(GrayView::new(&buf, 20, 6, 20).is_err());
    assert!(GrayView::new(&buf, 20, 5, 20).is_ok());
}

/// The paper's CopperTag-14 code, RS(20,4) over GF(256): three id symbols
/// (24-bit ids, e.g. the text "abc"), the verify symbol, 16 parity symbols.
fn ct14_rs20_4() -> Family {
    let mut spec = Family::ct14().spec().clone();
    spec.name = "ct14-rs20-4".into();
    spec.rs.k = 4;
    spec.rs.parity = 16;
    spec.ids = [0, (1 << 24) - 1];
    spec.verify_exceptions.clear();
    Family::from_spec(spec).unwrap()
}

#[test]
fn a_family_from_a_spec_is_detected() {
    let fam: &'static Family = Box::leak(Box::new(ct14_rs20_4()));
    let cfg = DetectorConfig {
        families: vec![FamilySetting::new(fam.clone())],
        ..DetectorConfig::default()
    };
    // The config, family definition included, survives a run log.
    let json = serde_json::to_string(&cfg).unwrap();
    assert!(json.contains("ct14-rs20-4"));
    assert_eq!(serde_json::from_str::<DetectorConfig>(&json).unwrap(), cfg);
    let mut det = Detector::new(cfg).unwrap();
    let abc = u64::from_le_bytes([b'a', b'b', b'c', 0, 0, 0, 0, 0]);
    let poses = [
        (0.8, 0.0, 0.0, 0.0),
        (1.0, 0.35, -0.25, 0.6),
        (1.5, -0.4, 0.2, 2.5),
    ];
    // Id 0 of a family without verify exceptions is an all-zero codeword:
    // its cells are the checkerboard mask, the same turned by 180 degrees,
    // so its corner order cannot be known and it must not be reported (the
    // built-in families give such ids another verify symbol).
    let s = paper_scene(fam, 0, 0.8, &rotation(0.0, 0.0, 0.0));
    assert!(
        det.detect(&s.render()).is_empty(),
        "a symmetric tag has no corner order"
    );
    for (k, &id) in [abc, 1, 255, 256, 0x00ab_cdef, (1 << 24) - 1]
        .iter()
        .enumerate()
    {
        let (d, rx, ry, rz) = poses[k % poses.len()];
        let s = paper_scene(fam, id, d, &rotation(rx, ry, rz));
        let found = det.detect(&s.render());
        assert_eq!(found.len(), 1, "id {id:#x}: {found:?}");
        assert_eq!((found[0].family.as_str(), found[0].id), ("ct14-rs20-4", id));
        let err = corner_errors(&found[0].corners, &s.corners());
        assert!(err.iter().all(|&e| e < 0.5), "id {id:#x}: {err:?}");
    }
    // With a corner hidden, too.
    let mut s = paper_scene(fam, abc, 0.8, &rotation(0.2, 0.1, 1.0));
    s.occluders = occluders(Occlusion::Triangle, 0.1, 0, 0.5)
        .into_iter()
        .map(|poly| Occluder { poly, grey: 235 })
        .collect();
    let found = det.detect(&s.render());
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].id, abc);
}

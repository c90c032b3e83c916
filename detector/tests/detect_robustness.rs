//! Bad input never panics and finishes in bounded time: empty, tiny, huge,
//! uniform, noisy and arbitrary images.

use crate::common;

use common::Rng;
use coppertag::{Detector, DetectorConfig, FamilySetting};
use image::GrayImage;
use proptest::prelude::*;

fn detector() -> Detector {
    Detector::new(DetectorConfig::default()).unwrap()
}

#[test]
fn degenerate_images() {
    let mut det = detector();
    for (w, h) in [
        (0, 0),
        (0, 5),
        (5, 0),
        (1, 1),
        (2, 2),
        (3, 1),
        (1, 300),
        (7, 7),
        (9, 8),
    ] {
        let img = GrayImage::new(w, h);
        assert!(det.detect(&img).is_empty(), "{w}x{h}");
    }
    for v in [0u8, 255, 128] {
        let img = GrayImage::from_pixel(640, 480, image::Luma([v]));
        assert!(det.detect(&img).is_empty(), "uniform {v}");
    }
    let mut rng = Rng::new(3);
    let noise = GrayImage::from_fn(640, 480, |_, _| image::Luma([(rng.next_u64() >> 56) as u8]));
    assert!(det.detect(&noise).is_empty());
    let stripes = GrayImage::from_fn(640, 480, |x, y| {
        image::Luma([if (x / 3 + y / 5) % 2 == 0 { 0 } else { 255 }])
    });
    assert!(det.detect(&stripes).is_empty());
    let checker = GrayImage::from_fn(640, 480, |x, y| {
        image::Luma([if (x / 16 + y / 16) % 2 == 0 { 0 } else { 255 }])
    });
    assert!(det.detect(&checker).is_empty());
}

#[test]
fn config_is_validated() {
    let bad = [
        DetectorConfig {
            families: vec![],
            ..Default::default()
        },
        DetectorConfig {
            families: vec![FamilySetting::builtin("ct14").unwrap(); 2],
            ..Default::default()
        },
        DetectorConfig {
            downsample: 3,
            ..Default::default()
        },
        DetectorConfig {
            threshold_radius: 0,
            ..Default::default()
        },
        DetectorConfig {
            dp_epsilon: f64::NAN,
            ..Default::default()
        },
        DetectorConfig {
            corner_min_angle_deg: 95.0,
            ..Default::default()
        },
        DetectorConfig {
            max_candidates: 0,
            ..Default::default()
        },
    ];
    for c in bad {
        assert!(Detector::new(c.clone()).is_err(), "{c:?}");
    }
    // Round trip through JSON (eval logs the config).
    let c = DetectorConfig::default();
    let json = serde_json::to_string(&c).unwrap();
    assert_eq!(serde_json::from_str::<DetectorConfig>(&json).unwrap(), c);
    // Unknown family names are rejected when the config is read.
    assert!(DetectorConfig::with_builtin_families(&["ct99"]).is_err());
    let json = json.replacen("\"ct8\"", "\"ct99\"", 1);
    assert!(serde_json::from_str::<DetectorConfig>(&json).is_err());
}

/// 20000 x 20000 (400 MB in, about 200 MB of working buffers).
#[test]
#[ignore = "allocates about 600 MB and takes seconds in release; run with --release --ignored"]
fn huge_image() {
    let mut det = detector();
    let mut img = GrayImage::from_pixel(20_000, 20_000, image::Luma([255]));
    let t = std::time::Instant::now();
    assert!(det.detect(&img).is_empty());
    // Some structure: noise in a band.
    let mut rng = Rng::new(5);
    for y in 9000..11000 {
        for x in 0..20_000 {
            img.put_pixel(x, y, image::Luma([(rng.next_u64() >> 56) as u8]));
        }
    }
    det.detect(&img);
    let secs = t.elapsed().as_secs_f64();
    eprintln!("two 20000 x 20000 frames: {secs:.1} s");
    assert!(secs < 60.0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn arbitrary_small_images_do_not_panic(
        w in 0u32..48,
        h in 0u32..48,
        seed in any::<u64>(),
        downsample in 1u32..=2,
    ) {
        let mut rng = Rng::new(seed);
        let mode = seed % 3;
        let img = GrayImage::from_fn(w, h, |x, y| {
            let v = match mode {
                0 => (rng.next_u64() >> 56) as u8,
                1 => if rng.uniform() < 0.5 { 0 } else { 255 },
                _ => if (x / 4 + y / 4) % 2 == 0 { 10 } else { 240 },
            };
            image::Luma([v])
        });
        let mut det = Detector::new(DetectorConfig { downsample, ..Default::default() }).unwrap();
        let found = det.detect(&img);
        prop_assert!(found.len() <= 1);
        for d in &found {
            prop_assert!(d.corners.iter().flatten().all(|v| v.is_finite()));
        }
    }

    #[test]
    fn arbitrary_bytes_as_any_shape(bytes in proptest::collection::vec(any::<u8>(), 0..4096), w in 1u32..128) {
        let h = bytes.len() as u32 / w;
        let img = GrayImage::from_raw(w, h, bytes[..(w * h) as usize].to_vec()).unwrap();
        let mut det = detector();
        let _ = det.detect(&img);
    }
}

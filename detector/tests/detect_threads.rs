//! The multi-core mode (`DetectorConfig::threads`): any thread count finds
//! exactly what one thread finds (the same detections, in the same order,
//! to the bit, and the same stage counts), and absurd thread counts are a
//! named error.

use crate::common;

use common::wild::{camera, wild_frame};
use common::*;
use coppertag::detect::MAX_THREADS;
use coppertag::{DetectionStats, Detector, DetectorConfig, Error, Family};
use image::GrayImage;

/// Thread counts compared with one thread: two (the bar's machine), three
/// (bands, windows and pieces that do not divide evenly).
const THREADS: [usize; 2] = [2, 3];

/// Every count of `s`, times left out (they differ from run to run).
fn counts(s: &DetectionStats) -> [usize; 11] {
    [
        s.width as usize,
        s.height as usize,
        s.contours,
        s.lines,
        s.corners,
        s.ellipses,
        s.candidates,
        s.decode_attempts,
        s.small_regions,
        s.rim_decodes,
        s.detections,
    ]
}

/// Detects on `frames` with one thread and with each of [`THREADS`] (their
/// threads pinned, as by default), and with 2 threads left unpinned
/// (detectors reused across frames, as a camera loop does), and checks
/// that every result and count agrees. Returns the one-thread detector's
/// detections, small-tag regions and rim-look decodes over the frames.
fn same_on_every_thread_count(frames: &[GrayImage], cfg: &DetectorConfig) -> (usize, usize, usize) {
    let make = |threads, pin_threads| {
        Detector::new(DetectorConfig {
            threads,
            pin_threads,
            ..cfg.clone()
        })
        .unwrap()
    };
    let mut one = make(1, false);
    let mut many: Vec<Detector> = THREADS.iter().map(|&t| make(t, true)).collect();
    many.push(make(2, false));
    let (mut total, mut regions, mut rims) = (0, 0, 0);
    for (i, frame) in frames.iter().enumerate() {
        let want = one.detect(frame);
        total += want.len();
        regions += one.stats().small_regions;
        rims += one.stats().rim_decodes;
        for det in &mut many {
            let got = det.detect(frame);
            let (threads, pinned) = (det.config().threads, det.config().pin_threads);
            // Debug prints floats in their shortest exact form: equal
            // strings are equal bits.
            assert_eq!(
                format!("{got:?}"),
                format!("{want:?}"),
                "frame {i}, {threads} threads, pinned {pinned}"
            );
            assert_eq!(
                counts(det.stats()),
                counts(one.stats()),
                "frame {i}, {threads} threads, pinned {pinned}"
            );
        }
    }
    (total, regions, rims)
}

#[test]
fn cluttered_4k_frames_give_the_same_detections_on_any_thread_count() {
    // Two wild-like frames at 3840 x 2160: tags of all sizes, occluded
    // ones, clutter (thousands of borders and candidates, small-tag
    // regions).
    let cam = camera(2160);
    let (frames, tags): (Vec<_>, Vec<_>) = [0x4B01, 0x4B02]
        .iter()
        .map(|&seed| wild_frame(seed, &cam))
        .unzip();
    let (found, regions, _) = same_on_every_thread_count(&frames, &DetectorConfig::default());
    assert!(regions > 0);
    let placed: usize = tags.iter().sum();
    assert!(placed >= 4 && found * 2 >= placed, "{found} of {placed}");
}

#[test]
fn wild_1080p_frames_give_the_same_detections_on_any_thread_count() {
    let cam = camera(1080);
    let frames: Vec<_> = (0..4).map(|i| wild_frame(0xC0FFEE + i, &cam).0).collect();
    // Frames where the rim look decodes rims too.
    let (_, _, rims) = same_on_every_thread_count(&frames, &DetectorConfig::default());
    assert!(rims > 0, "no rim decoded");
    // Without downsampling (no small-tag pass, full-size bands) and with a
    // tight candidate cap (the decode budget runs out mid-frame).
    let full = DetectorConfig {
        downsample: 1,
        ..DetectorConfig::default()
    };
    same_on_every_thread_count(&frames[..1], &full);
    let capped = DetectorConfig {
        max_candidates: 12,
        ..DetectorConfig::default()
    };
    same_on_every_thread_count(&frames, &capped);
}

#[test]
fn small_tags_give_the_same_detections_on_any_thread_count() {
    // Eight tags with data squares of 22-40 px on one 1920 x 1080 frame:
    // read by the full-resolution second look, one region each.
    let mut rng = Rng::new(11);
    let mut img = GrayImage::from_pixel(1920, 1080, image::Luma([150]));
    for k in 0..8u64 {
        let side = rng.range(22.0, 40.0);
        let d = CAMERA.f * TAG_SIDE_M / side;
        let r = rotation(
            rng.range(-0.4, 0.4),
            rng.range(-0.4, 0.4),
            rng.range(0.0, 6.2),
        );
        let (u, v) = (
            240.0 + 440.0 * (k % 4) as f64,
            300.0 + 480.0 * (k / 4) as f64,
        );
        let t = [
            (u - CAMERA.cx()) * d / CAMERA.f,
            (v - CAMERA.cy()) * d / CAMERA.f,
            d,
        ];
        let h = CAMERA.homography(&r, t, TAG_SIDE_M);
        let family = if k % 3 == 2 {
            Family::ct8()
        } else {
            Family::ct14()
        };
        Scene::new(family, 10 + k, 1920, 1080, h).paint(&mut img);
    }
    let img = imageproc::filter::gaussian_blur_f32(&img, 0.6);
    let (found, regions, _) =
        same_on_every_thread_count(std::slice::from_ref(&img), &DetectorConfig::default());
    assert!(
        found >= 6 && regions >= 6,
        "{found} of 8 small tags, {regions} regions"
    );
}

/// A frame of `w` x `h` with tags centred on the rows where the bands of
/// stages 1 and 2 meet on two and three threads (a half and the thirds of
/// the height, both at the working scale and at full resolution), of three
/// sizes, each a little off the row so that the band edge crosses it at a
/// different height, and a ring around each (a border that two bands
/// follow).
fn tags_on_band_edges(w: u32, h: u32, seed: u64) -> (GrayImage, usize) {
    let mut rng = Rng::new(seed);
    let mut img = GrayImage::from_pixel(w, h, image::Luma([165]));
    let mut placed = 0;
    for (k, &row) in [h / 2, h / 3, 2 * h / 3].iter().enumerate() {
        for (j, side) in [34.0, 90.0, 180.0].into_iter().enumerate() {
            let u = f64::from(w) * (j as f64 + 0.6) / 3.3;
            let v = f64::from(row) + rng.range(-0.3, 0.3) * side;
            let d = CAMERA.f * TAG_SIDE_M / side;
            let r = rotation(
                rng.range(-0.3, 0.3),
                rng.range(-0.3, 0.3),
                rng.range(0.0, 6.2),
            );
            let t = [
                (u - CAMERA.cx()) * d / CAMERA.f,
                (v - CAMERA.cy()) * d / CAMERA.f,
                d,
            ];
            let hom = CAMERA.homography(&r, t, TAG_SIDE_M);
            let family = if (k + j) % 2 == 0 {
                Family::ct14()
            } else {
                Family::ct8()
            };
            // A dark ring around the tag, crossing the band edge too.
            let ring = 1.3 * side;
            for y in (v - ring - 6.0).max(0.0) as u32..((v + ring + 6.0) as u32).min(h) {
                for x in (u - ring - 6.0).max(0.0) as u32..((u + ring + 6.0) as u32).min(w) {
                    let dist = (f64::from(x) - u).hypot(f64::from(y) - v);
                    if (dist - ring).abs() < 3.0 {
                        img.put_pixel(x, y, image::Luma([40]));
                    }
                }
            }
            Scene::new(family, (10 * k + j) as u64, w, h, hom).paint(&mut img);
            placed += 1;
        }
    }
    (imageproc::filter::gaussian_blur_f32(&img, 0.7), placed)
}

#[test]
fn tags_across_band_edges_give_the_same_detections_on_any_thread_count() {
    // Even and odd frame sizes: the bands of an odd number of rows do not
    // divide evenly, and a downsampled odd height drops its last row.
    for (w, h, seed) in [(1920, 1080, 21), (1283, 723, 22), (1601, 1201, 23)] {
        let (img, placed) = tags_on_band_edges(w, h, seed);
        let frames = std::slice::from_ref(&img);
        let (found, _, _) = same_on_every_thread_count(frames, &DetectorConfig::default());
        assert!(found * 3 >= placed * 2, "{w}x{h}: {found} of {placed}");
        // At full resolution the bands fall on other rows.
        let full = DetectorConfig {
            downsample: 1,
            ..DetectorConfig::default()
        };
        same_on_every_thread_count(frames, &full);
    }
}

#[test]
fn wild_frames_of_odd_heights_give_the_same_detections_on_any_thread_count() {
    for (height, seed) in [(1081, 0xD1), (721, 0xD2)] {
        let cam = camera(height);
        let frames: Vec<_> = (0..2).map(|i| wild_frame(seed + i, &cam).0).collect();
        assert_eq!(frames[0].height(), height);
        same_on_every_thread_count(&frames, &DetectorConfig::default());
    }
}

#[test]
fn every_thread_count_is_validated() {
    for threads in [MAX_THREADS + 1, usize::MAX] {
        let cfg = DetectorConfig {
            threads,
            ..DetectorConfig::default()
        };
        match cfg.validate() {
            Err(Error::InvalidParameter { name, .. }) => assert_eq!(name, "threads"),
            other => panic!("{threads} threads: {other:?}"),
        }
        assert!(Detector::new(cfg).is_err());
    }
    // 0 is one thread per core; 1 and the maximum are fine.
    for threads in [0, 1, 2, MAX_THREADS] {
        let cfg = DetectorConfig {
            threads,
            ..DetectorConfig::default()
        };
        assert!(cfg.validate().is_ok(), "{threads}");
    }
    let det = Detector::new(DetectorConfig {
        threads: 0,
        ..DetectorConfig::default()
    })
    .unwrap();
    assert_eq!(det.config().threads, 0);
    // A config file names the field; a missing one means one thread.
    let cfg: DetectorConfig = serde_json::from_str(r#"{"threads": 2}"#).unwrap();
    assert_eq!(cfg.threads, 2);
    let cfg: DetectorConfig = serde_json::from_str("{}").unwrap();
    assert_eq!(cfg.threads, 1);
}

#[test]
fn a_threaded_detector_can_move_between_threads() {
    fn send_sync<T: Send + Sync + std::fmt::Debug>(_: &T) {}
    let mut det = Detector::new(DetectorConfig {
        threads: 2,
        ..DetectorConfig::default()
    })
    .unwrap();
    send_sync(&det);
    assert!(format!("{det:?}").contains("threads: 2"));
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/ct14/42.png");
    let img = image::open(path).expect("fixture").to_luma8();
    let found = std::thread::spawn(move || det.detect(&img)).join().unwrap();
    assert_eq!(found.len(), 1);
    assert_eq!(found[0].id, 42);
}

#[test]
fn a_frames_total_time_covers_its_stages_within_the_call() {
    // `total` is the frame's time as the caller's clock sees it, no less
    // than its stages together (they run one after another) and no more
    // than the call: with worker threads it is measured around the whole
    // call, the threads' waking included.
    let frame = wild_frame(0xC0FFEE, &camera(1080)).0;
    for threads in [1, 2] {
        let mut det = Detector::new(DetectorConfig {
            threads,
            ..DetectorConfig::default()
        })
        .unwrap();
        for _ in 0..3 {
            let t = std::time::Instant::now();
            det.detect(&frame);
            let wall = t.elapsed();
            let times = det.stats().times;
            let stages: std::time::Duration = times
                .iter()
                .filter(|(name, _)| *name != "total")
                .map(|(_, d)| d)
                .sum();
            assert!(
                stages <= times.total && times.total <= wall,
                "{threads} threads: stages {stages:?}, total {:?}, call {wall:?}",
                times.total
            );
        }
    }
}

//! One run on a sampled ("wild") dataset, marker by marker: what happened
//! to each true marker, where its reported corners put it, what pose they
//! give, and which factor values it was drawn with.
//!
//! Each true marker takes, among the detections of its family and id whose
//! centre lies within one side of its own, the one with the smallest
//! largest-corner error (corner k against true corner k: corner 0 is the
//! same physical corner for every system, so a detection reporting its
//! corners a quarter turn round is located wrongly, not well). It is
//!
//! - **correct** when every corner is within the match distance
//!   ([`MatchRule`]: 3 px or 5% of the side, the larger),
//! - **rough** when the id is right but some corner is farther: a robot
//!   would trust it, so it is counted on its own, neither a miss nor a
//!   false positive,
//! - **missed** otherwise.
//!
//! Found = correct + rough. Of the remaining detections, another detection
//! of an already taken marker (same id, centre within a side) is a
//! duplicate, one whose centre lies within half a side of a true marker is
//! a wrong id, and anything else is a false positive. On a tag-free
//! dataset (images, no truth rows) every detection is a false positive.

use std::collections::BTreeMap;
use std::path::Path;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::draws::{Draws, FactorValue, Factors};
use crate::error::{EvalError, Result};
use crate::metrics::{centre, dist, MatchRule};
use crate::pose_error::{pose_error, CameraModel, PoseError};
use crate::runlog::RunLog;
use crate::truth::Dataset;

/// The factor holding the marker's measured side in the image, px.
pub const SIDE_FACTOR: &str = "side_px";

/// What happened to one true marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Right id, every corner within the match distance.
    Correct,
    /// Right id, some corner beyond the match distance.
    Rough,
    /// Not found.
    Missed,
}

/// One true marker's outcome.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerOutcome {
    /// Image index.
    pub index: usize,
    /// Marker index in the spec.
    pub marker_index: usize,
    /// Outcome.
    pub status: Status,
    /// Largest corner error of the detection taken, px.
    pub corner_error_max_px: Option<f64>,
    /// Its corners, as reported.
    pub corners: Option<[[f64; 2]; 4]>,
    /// Distance of each of its corners to the true one, px (corner k
    /// against true corner k).
    #[serde(default)]
    pub corner_errors_px: Option<[f64; 4]>,
    /// Its one-sigma corner uncertainties, px, when the detector reports
    /// them ([`crate::sigma`] measures how honest they are).
    #[serde(default)]
    pub corner_sigma: Option<[f64; 4]>,
    /// Which of its corners the detector says it estimated.
    #[serde(default)]
    pub estimated: [bool; 4],
    /// Read by likelihood (CopperTag's blurred-tag reading).
    #[serde(default)]
    pub likelihood: bool,
    /// Pose error from those corners (IPPE).
    pub pose: Option<PoseError>,
    /// Whether CopperTag's decoder reads the marker at its true corners
    /// ([`read_at_truth`]); `None` on other systems' runs.
    #[serde(default)]
    pub read_at_truth: Option<bool>,
    /// Drawn factor values (empty without `draws.csv`), with the measured
    /// side in pixels as [`SIDE_FACTOR`].
    pub factors: Factors,
}

impl MarkerOutcome {
    /// Correct or rough.
    pub fn found(&self) -> bool {
        self.status != Status::Missed
    }
}

/// One detector on one dataset, marker by marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WildRun {
    /// Detector.
    pub detector: String,
    /// Dataset name.
    pub dataset: String,
    /// Images the run covered.
    pub images: usize,
    /// Images the detector could not process.
    pub image_errors: usize,
    /// Image area the run covered, megapixels.
    pub megapixels: f64,
    /// No truth rows: a false-positive set.
    pub tag_free: bool,
    /// Detections matching nothing.
    pub false_positives: usize,
    /// Detections of another id on a true marker.
    pub wrong_ids: usize,
    /// Second detections of a marker already taken.
    pub duplicates: usize,
    /// Detection time per image, ms; empty when the run was not timed
    /// ([`crate::runner::timed`]).
    pub times_ms: Vec<f64>,
    /// One per true marker, in image and truth order.
    pub outcomes: Vec<MarkerOutcome>,
}

/// Draws (if any) and camera of a dataset, from the directories of its
/// parts (one, or one per shard).
pub fn open_extras(dirs: &[&Path]) -> Result<(Option<Draws>, CameraModel)> {
    let mut draws: Option<Draws> = None;
    let mut camera = None;
    for dir in dirs {
        if let Some(d) = Draws::open(dir)? {
            match &mut draws {
                Some(all) => all.extend(d),
                None => draws = Some(d),
            }
        }
        if camera.is_none() {
            camera = Some(CameraModel::open(dir)?);
        }
    }
    let camera = camera.ok_or_else(|| crate::EvalError::InvalidParameter {
        name: "dataset",
        reason: "no dataset directory".into(),
    })?;
    Ok((draws, camera))
}

/// Evaluates `run` on `dataset` marker by marker.
pub fn evaluate(
    run: &RunLog,
    dataset: &Dataset,
    draws: Option<&Draws>,
    camera: &CameraModel,
    rule: MatchRule,
) -> WildRun {
    let mut w = WildRun {
        detector: run.info.detector.clone(),
        dataset: dataset.name.clone(),
        images: run.images.len(),
        image_errors: 0,
        megapixels: run.images.len() as f64 * camera.megapixels(),
        tag_free: dataset.truth.is_empty(),
        false_positives: 0,
        wrong_ids: 0,
        duplicates: 0,
        times_ms: Vec::new(),
        outcomes: Vec::new(),
    };
    let by_image: BTreeMap<&str, &crate::runlog::DetectionsMessage> = run
        .images
        .iter()
        .map(|m| (m.result.image.as_str(), m))
        .collect();
    let empty = Vec::new();
    for (index, image) in &dataset.images {
        let truth = dataset.truth.get(image).unwrap_or(&empty);
        let Some(msg) = by_image.get(image.as_str()) else {
            // Not reached by the run: an error, and its markers missed.
            w.image_errors += 1;
            for m in truth {
                w.outcomes
                    .push(outcome(*index, m, draws, None, Status::Missed));
            }
            continue;
        };
        let r = &msg.result;
        if r.error.is_some() {
            w.image_errors += 1;
        }
        if crate::runner::timed(run.info.sessions) {
            w.times_ms.extend(r.ms);
        }
        let dets = &r.detections;
        let mut used = vec![false; dets.len()];
        for m in truth {
            let tc = m.corners();
            let tcentre = centre(&tc);
            let mut best: Option<(usize, f64)> = None;
            for (k, d) in dets.iter().enumerate() {
                if used[k] || d.family != m.family || d.id != m.id {
                    continue;
                }
                if dist(centre(&d.corners), tcentre) >= m.side_px {
                    continue;
                }
                let err = (0..4)
                    .map(|c| dist(d.corners[c], tc[c]))
                    .fold(0.0, f64::max);
                if best.is_none_or(|(_, e)| err < e) {
                    best = Some((k, err));
                }
            }
            let o = match best {
                Some((k, err)) => {
                    used[k] = true;
                    let status = if err <= rule.tolerance(m) {
                        Status::Correct
                    } else {
                        Status::Rough
                    };
                    let d = &dets[k];
                    let mut o = outcome(*index, m, draws, Some(&d.corners), status);
                    o.corner_error_max_px = Some(err);
                    o.corner_errors_px = Some(std::array::from_fn(|c| dist(d.corners[c], tc[c])));
                    o.corner_sigma = d.corner_sigma;
                    o.estimated = d.estimated;
                    o.likelihood = d.likelihood;
                    o.pose = pose_error(&d.corners, m, camera);
                    o
                }
                None => outcome(*index, m, draws, None, Status::Missed),
            };
            w.outcomes.push(o);
        }
        for (k, d) in dets.iter().enumerate() {
            if used[k] {
                continue;
            }
            let c = centre(&d.corners);
            if truth.iter().any(|m| {
                m.family == d.family && m.id == d.id && dist(c, centre(&m.corners())) < m.side_px
            }) {
                w.duplicates += 1;
            } else if truth
                .iter()
                .any(|m| dist(c, centre(&m.corners())) < m.side_px / 2.0)
            {
                w.wrong_ids += 1;
            } else {
                w.false_positives += 1;
            }
        }
    }
    w
}

fn outcome(
    index: usize,
    m: &crate::truth::TruthMarker,
    draws: Option<&Draws>,
    corners: Option<&[[f64; 2]; 4]>,
    status: Status,
) -> MarkerOutcome {
    let factors = draws.map_or_else(Factors::new, |d| {
        let mut f = d.factors(index, m.marker_index);
        // The side the image shows, whatever size was asked for.
        f.insert(SIDE_FACTOR.into(), FactorValue::Num(m.side_px));
        f
    });
    MarkerOutcome {
        index,
        marker_index: m.marker_index,
        status,
        corner_error_max_px: None,
        corners: corners.copied(),
        corner_errors_px: None,
        corner_sigma: None,
        estimated: [false; 4],
        likelihood: false,
        pose: None,
        read_at_truth: None,
        factors,
    }
}

/// A true marker of a dataset: (image index, marker index).
pub type MarkerKey = (usize, usize);

/// Whether CopperTag's decoder reads each CopperTag marker of `dataset`
/// when handed its true corners ([`coppertag::decode_quad`], the
/// library's decoding from four corners, with its default thresholds), by
/// (image index, marker index); the images are looked for in `dirs` (the
/// dataset's directory, or its shards').
///
/// Why: a marker the detector misses is lost either in the geometry (no
/// quad near its corners, or one the detector would not trust) or in its
/// cells (blur, glare, an occluder leaving too little to read). Read at
/// the true corners, a marker shows which: the share a perfect quad
/// search would reach with this decoder, beside the share the detector
/// found, in each of the wild benchmark's scenarios.
pub fn read_at_truth(dataset: &Dataset, dirs: &[&Path]) -> Result<BTreeMap<MarkerKey, bool>> {
    let jobs: Vec<(usize, &String, &Vec<crate::truth::TruthMarker>)> = dataset
        .images
        .iter()
        .filter_map(|(i, img)| dataset.truth.get(img).map(|t| (*i, img, t)))
        .collect();
    // In image order, so that the first bad image is the one reported.
    let per_image: Vec<Result<Vec<(MarkerKey, bool)>>> = jobs
        .par_iter()
        .map(|&(index, img, truth)| {
            let path = dirs
                .iter()
                .map(|d| d.join(img))
                .find(|p| p.exists())
                .unwrap_or_else(|| dataset.image_path(img));
            let gray = image::open(&path)
                .map_err(|e| EvalError::bad(&path, e.to_string()))?
                .to_luma8();
            Ok(truth
                .iter()
                .filter_map(|m| {
                    let family = coppertag::Family::by_name(&m.family).ok()?;
                    let read = coppertag::decode_quad(&gray, family, &m.corners());
                    Some(((index, m.marker_index), read.is_some_and(|r| r.id == m.id)))
                })
                .collect())
        })
        .collect();
    let mut out = BTreeMap::new();
    for r in per_image {
        out.extend(r?);
    }
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::protocol::{DetectionRecord, ImageResult};
    use crate::runlog::DetectionsMessage;
    use crate::runner::{RunInfo, RunResources};
    use crate::truth::{test_marker, TruthMarker};

    /// A run of `detector` answering `detections` for image `index`.
    pub(crate) fn run_of(detector: &str, images: Vec<(usize, Vec<DetectionRecord>)>) -> RunLog {
        RunLog {
            info: RunInfo {
                detector: detector.into(),
                version: "1".into(),
                parameters: String::new(),
                dataset: "test".into(),
                dataset_dir: String::new(),
                machine: String::new(),
                started_unix_s: 0,
                shard: String::new(),
                sessions: 1,
            },
            resources: RunResources::default(),
            images: images
                .into_iter()
                .map(|(index, detections)| DetectionsMessage {
                    index,
                    result: ImageResult {
                        image: format!("images/{index:06}.png"),
                        ms: Some(1.0 + index as f64),
                        detections,
                        error: None,
                    },
                })
                .collect(),
        }
    }

    pub(crate) fn det(id: u64, corners: [[f64; 2]; 4]) -> DetectionRecord {
        DetectionRecord {
            family: "ct14".into(),
            id,
            corners,
            estimated: [false; 4],
            corrected: None,
            corner_sigma: None,
            likelihood: false,
        }
    }

    pub(crate) fn dataset_of(images: &[usize], truth: Vec<TruthMarker>) -> Dataset {
        let mut by_image: BTreeMap<String, Vec<TruthMarker>> = BTreeMap::new();
        for m in truth {
            by_image.entry(m.image.clone()).or_default().push(m);
        }
        Dataset {
            dir: "unused".into(),
            name: "test".into(),
            images: images
                .iter()
                .map(|&i| (i, format!("images/{i:06}.png")))
                .collect(),
            truth: by_image,
        }
    }

    fn square(x: f64, y: f64, s: f64) -> [[f64; 2]; 4] {
        [[x, y], [x, y + s], [x + s, y + s], [x + s, y]]
    }

    #[test]
    fn a_corner_4_px_off_is_rough_not_missed() {
        let cam = CameraModel::new(640, 480, [600.0, 600.0, 319.5, 239.5], [0.0; 5]).unwrap();
        // Side 40 px: the match distance is max(3, 2) = 3 px.
        let sq = square(100.0, 100.0, 40.0);
        let truth: Vec<TruthMarker> = (0..4).map(|i| test_marker(i, 7, sq, None)).collect();
        let ds = dataset_of(&[0, 1, 2, 3], truth);
        let mut off4 = sq;
        off4[2][1] += 4.0;
        let mut off2 = sq;
        off2[0][0] -= 2.0;
        let run = run_of(
            "coppertag",
            vec![
                (0, vec![det(7, off4)]),
                // Corner 2 px off, and a second copy: a duplicate.
                (1, vec![det(7, off2), det(7, sq)]),
                // Another id on the marker, and a tag far away.
                (2, vec![det(8, sq), det(7, square(400.0, 300.0, 40.0))]),
                // Corners a quarter turn round: right id, wrong corners.
                (3, vec![det(7, [sq[1], sq[2], sq[3], sq[0]])]),
            ],
        );
        let w = evaluate(&run, &ds, None, &cam, MatchRule::default());
        let status: Vec<Status> = w.outcomes.iter().map(|o| o.status).collect();
        assert_eq!(
            status,
            [
                Status::Rough,
                Status::Correct,
                Status::Missed,
                Status::Rough
            ]
        );
        assert_eq!(w.outcomes[0].corner_error_max_px, Some(4.0));
        // The exact copy is taken over the 2 px one.
        assert_eq!(w.outcomes[1].corner_error_max_px, Some(0.0));
        assert_eq!((w.duplicates, w.wrong_ids, w.false_positives), (1, 1, 1));
        assert!(!w.tag_free);
        assert!(w.outcomes.iter().all(|o| o.factors.is_empty()));
    }

    /// A run whose detector sessions ran side by side keeps no times (they
    /// are not one session's); its markers are scored all the same.
    #[test]
    fn a_run_of_sessions_side_by_side_is_scored_but_not_timed() {
        let cam = CameraModel::new(640, 480, [600.0, 600.0, 319.5, 239.5], [0.0; 5]).unwrap();
        let sq = square(100.0, 100.0, 40.0);
        let ds = dataset_of(
            &[0, 1],
            (0..2).map(|i| test_marker(i, 7, sq, None)).collect(),
        );
        let mut run = run_of("coppertag", vec![(0, vec![det(7, sq)]), (1, vec![])]);
        let one = evaluate(&run, &ds, None, &cam, MatchRule::default());
        assert_eq!(one.times_ms, [1.0, 2.0]);
        run.info.sessions = 2;
        let two = evaluate(&run, &ds, None, &cam, MatchRule::default());
        assert!(two.times_ms.is_empty());
        assert_eq!(two.outcomes, one.outcomes);
        assert_eq!(two.outcomes[0].status, Status::Correct);
    }

    /// A tag drawn by the generator reads at its true corners; the same
    /// corners given another id, or a blank image, do not; a marker of a
    /// family that is no CopperTag's is not tried; a truncated or missing
    /// image is an error.
    #[test]
    fn markers_are_read_at_their_true_corners() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("images")).unwrap();
        let fam = coppertag::Family::ct14();
        let shapes = coppertag::geometry::tag_shapes(fam, 42).unwrap();
        // A 128 px print: the data square is its middle half.
        let tag = coppertag_synth::raster::tag_image(&shapes, 128).unwrap();
        tag.save(dir.path().join("images/000000.png")).unwrap();
        tag.save(dir.path().join("images/000001.png")).unwrap();
        image::GrayImage::from_pixel(128, 128, image::Luma([255]))
            .save(dir.path().join("images/000002.png"))
            .unwrap();
        let q = [[31.5, 31.5], [31.5, 95.5], [95.5, 95.5], [95.5, 31.5]];
        let mut other = test_marker(0, 42, q, None);
        other.marker_index = 1;
        other.family = "tag36h11".into();
        let truth = vec![
            test_marker(0, 42, q, None),
            other,
            test_marker(1, 43, q, None),
            test_marker(2, 42, q, None),
        ];
        let mut ds = dataset_of(&[0, 1, 2], truth);
        ds.dir = dir.path().to_path_buf();
        let read = read_at_truth(&ds, &[dir.path()]).unwrap();
        let want: BTreeMap<(usize, usize), bool> =
            [((0, 0), true), ((1, 0), false), ((2, 0), false)].into();
        assert_eq!(read, want);
        // A truncated image and a missing one are errors naming the file.
        let bad = dir.path().join("images/000002.png");
        std::fs::write(&bad, b"\x89PNG\r\n\x1a\n").unwrap();
        let err = read_at_truth(&ds, &[dir.path()]).unwrap_err().to_string();
        assert!(err.contains("000002.png"), "{err}");
        std::fs::remove_file(&bad).unwrap();
        let err = read_at_truth(&ds, &[dir.path()]).unwrap_err().to_string();
        assert!(err.contains("000002.png"), "{err}");
    }

    #[test]
    fn every_detection_on_a_tag_free_set_is_a_false_positive() {
        let cam = CameraModel::new(640, 480, [600.0, 600.0, 319.5, 239.5], [0.0; 5]).unwrap();
        let ds = dataset_of(&[0, 1], Vec::new());
        let run = run_of(
            "stag",
            vec![
                (
                    0,
                    vec![
                        det(1, square(10.0, 10.0, 30.0)),
                        det(2, square(90.0, 10.0, 30.0)),
                    ],
                ),
                (1, vec![det(3, square(10.0, 10.0, 30.0))]),
            ],
        );
        let w = evaluate(&run, &ds, None, &cam, MatchRule::default());
        assert!(w.tag_free);
        assert_eq!(w.false_positives, 3);
        assert!((w.megapixels - 2.0 * 0.3072).abs() < 1e-12);
        let s = crate::wild_summary::summarise(&[w]);
        let fp = s.systems[0].false_positives_per_mp.unwrap();
        assert!((fp - 3.0 / 0.6144).abs() < 1e-9, "{fp}");
        assert_eq!(s.systems[0].markers, 0);
    }
}

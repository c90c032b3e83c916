//! Detection over a recording: every frame of one image topic through the
//! detector, in parallel, with poses when the camera and tag size are
//! known, written as [`super::output`] describes.
//!
//! Frames are read in batches of [`BATCH_FRAMES`] on a reader thread (the
//! next batch while the current one is detected); the frames of a batch
//! are decoded and detected in parallel (rayon), each worker with a
//! detector of its own taken from a shared pool, and their results are
//! written in the recording's order. A frame's result depends on that
//! frame alone, so the output's bytes do not depend on the thread count.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use coppertag::{Detector, DetectorConfig};
use rayon::prelude::*;

use super::bag::{self, RawFrame, Scan, Topic, TopicKind};
use super::camera::{Calibration, FoxgloveCalibration};
use super::frame::{self, FoxgloveImage, Gray};
use super::msgs::{self, CameraInfo, CompressedImage, Image};
use super::output::{BagOutput, FrameResult, RunFacts};
use crate::error::{EvalError, Result};
use crate::pose_error::CameraModel;
use crate::protocol::DetectionRecord;

/// Frames read and detected together: enough to keep every core busy
/// (a few per thread), few enough that a batch of 1080p colour frames
/// stays within a few hundred megabytes.
pub const BATCH_FRAMES: usize = 32;

/// What to do.
#[derive(Debug, Clone)]
pub struct BagDetectOptions {
    /// The recording.
    pub input: PathBuf,
    /// Image topic, or `None` for the only one there is.
    pub topic: Option<String>,
    /// Detector settings.
    pub config: DetectorConfig,
    /// Data-square side, metres; poses need it.
    pub tag_size: Option<f64>,
    /// Data-square sides of particular tags, metres, by (family, id);
    /// they win over `tag_size`.
    pub tag_sizes: std::collections::BTreeMap<(String, u64), f64>,
    /// A calibration from a file (its name, its content), used instead of
    /// the recording's.
    pub camera: Option<(String, Calibration)>,
    /// Keep the frames before damage in a truncated or damaged bag instead
    /// of refusing it.
    pub allow_truncated: bool,
}

impl BagDetectOptions {
    /// Whether any tag gets a pose.
    #[must_use]
    pub fn wants_poses(&self) -> bool {
        self.tag_size.is_some() || !self.tag_sizes.is_empty()
    }

    /// The data-square side of a tag: its own, else the common one.
    #[must_use]
    pub fn side_of(&self, family: &str, id: u64) -> Option<f64> {
        self.tag_sizes
            .get(&(family.to_string(), id))
            .copied()
            .or(self.tag_size)
    }
}

/// A recording checked and ready to run: its topic, its camera.
#[derive(Debug)]
pub struct Plan {
    /// The image topic.
    pub topic: Topic,
    /// Frames to read.
    pub frames: usize,
    /// Where the camera model comes from (a topic or a file), if any.
    pub camera_source: Option<String>,
    /// Camera models by log time (one for a file).
    cameras: Vec<(u64, CameraModel)>,
    /// Set when damage cut the recording short.
    pub truncated: bool,
}

/// The run's outcome.
#[derive(Debug)]
pub struct Outcome {
    /// The output MCAP file's bytes.
    pub mcap: Vec<u8>,
    /// Frames read.
    pub frames: usize,
    /// Detections over all frames.
    pub detections: usize,
    /// Detections with a pose.
    pub poses: usize,
    /// Wall time of the detection pass, seconds.
    pub wall_s: f64,
}

fn bad(path: &Path, message: impl Into<String>) -> EvalError {
    EvalError::bad(path, message)
}

fn seconds(ns: u64) -> String {
    format!("{:.3} s", ns as f64 / 1e9)
}

/// A calibration message decoded.
fn calibration(kind: TopicKind, data: &[u8]) -> std::result::Result<Calibration, String> {
    match kind {
        TopicKind::RosCameraInfo => msgs::decode::<CameraInfo>(data).map(|m| (&m).into()),
        TopicKind::FoxgloveCalibration => serde_json::from_slice::<FoxgloveCalibration>(data)
            .map(|m| (&m).into())
            .map_err(|e| format!("bad foxglove.CameraCalibration JSON: {e}")),
        _ => Err("not a calibration topic".into()),
    }
}

/// Reads the recording once and checks everything a run needs before it
/// starts: the topic, the damage, the camera.
pub fn plan(opts: &BagDetectOptions) -> Result<Plan> {
    let path = opts.input.as_path();
    let scan: Scan = bag::scan(path)?;
    let topic = scan
        .image_topic(opts.topic.as_deref())
        .map_err(|m| bad(path, m))?
        .clone();
    let frames = scan.messages_of(&topic.name);
    if let Some(d) = &scan.damage {
        if !opts.allow_truncated {
            return Err(bad(
                path,
                format!(
                    "the bag is truncated or damaged after {} messages ({}); {} frames of {} come \
                     before the damage: --allow-truncated keeps them",
                    d.after_messages, d.error, frames, topic.name
                ),
            ));
        }
    }
    let mut cameras = Vec::new();
    let mut camera_source = None;
    if let Some((name, cal)) = &opts.camera {
        let model = cal.model().map_err(|m| EvalError::InvalidParameter {
            name: "--camera",
            reason: format!("{name}: {m}"),
        })?;
        cameras.push((0, model));
        camera_source = Some(name.clone());
    } else if let Some(info) = scan.sibling_calibration(&topic) {
        let mut last: Option<Calibration> = None;
        for (t, data) in scan.calibrations.get(&info.name).into_iter().flatten() {
            let cal = calibration(info.kind, data).map_err(|m| {
                bad(
                    path,
                    format!("{} message at {}: {m}", info.name, seconds(*t)),
                )
            })?;
            if last.as_ref() == Some(&cal) {
                continue;
            }
            let model = cal.model().map_err(|m| {
                bad(
                    path,
                    format!("{} message at {}: {m}", info.name, seconds(*t)),
                )
            })?;
            cameras.push((*t, model));
            last = Some(cal);
        }
        camera_source = Some(info.name.clone());
    }
    if opts.wants_poses() && cameras.is_empty() {
        return Err(bad(
            path,
            format!(
                "--tag-size/--tag-sizes need a camera model: no sensor_msgs/msg/CameraInfo beside {} \
                 (for example {}); give one with --camera FILE",
                topic.name,
                topic
                    .name
                    .trim_end_matches("/compressed")
                    .rsplit_once('/')
                    .map_or("/camera_info".to_string(), |(ns, _)| format!(
                        "{ns}/camera_info"
                    ))
            ),
        ));
    }
    Ok(Plan {
        topic,
        frames,
        camera_source,
        cameras,
        truncated: scan.damage.is_some(),
    })
}

/// The camera model in force at `log_time`: the last one logged before
/// it, or the first one when the frame comes before every calibration.
fn camera_at(cameras: &[(u64, CameraModel)], log_time: u64) -> Option<&CameraModel> {
    let after = cameras.partition_point(|(t, _)| *t <= log_time);
    cameras.get(after.saturating_sub(1)).map(|(_, m)| m)
}

/// Stamp (ns), camera frame and grey pixels of one image message.
fn decode(kind: TopicKind, data: &[u8]) -> std::result::Result<(u64, String, Gray<'_>), String> {
    match kind {
        TopicKind::RosImage => {
            let m: Image<'_> = msgs::decode(data)?;
            let g = frame::from_image(&m)?;
            Ok((m.header.stamp.nanos(), m.header.frame_id, g))
        }
        TopicKind::RosCompressedImage => {
            let m: CompressedImage<'_> = msgs::decode(data)?;
            let g = frame::from_compressed_image(&m)?;
            Ok((m.header.stamp.nanos(), m.header.frame_id, g))
        }
        TopicKind::FoxgloveCompressedImage => {
            let m = FoxgloveImage::parse(data)?;
            let g = frame::from_compressed(&m.format, &m.bytes()?)?;
            Ok((m.stamp(), m.frame_id, g))
        }
        _ => Err("not an image topic".into()),
    }
}

fn one_frame(
    plan: &Plan,
    opts: &BagDetectOptions,
    detector: &mut Detector,
    raw: &RawFrame,
) -> std::result::Result<FrameResult, String> {
    let (stamp, frame_id, gray) = decode(plan.topic.kind, &raw.data)?;
    let camera = camera_at(&plan.cameras, raw.log_time);
    if let Some(cam) = camera {
        if cam.size() != gray.size() {
            let (w, h) = gray.size();
            let (cw, ch) = cam.size();
            return Err(format!(
                "the frame is {w} x {h} but the calibration ({}) is for {cw} x {ch}",
                plan.camera_source.as_deref().unwrap_or("")
            ));
        }
    }
    let view = gray.view().map_err(|e| e.to_string())?;
    let found = detector.detect(view);
    let poses = found
        .iter()
        .map(|d| {
            let (cam, side) = (camera?, opts.side_of(&d.family, d.id)?);
            cam.tag_pose(&d.corners, side).ok()
        })
        .collect();
    let detections = found
        .into_iter()
        .map(|d| DetectionRecord {
            family: d.family,
            id: d.id,
            corners: d.corners,
            estimated: d.estimated,
            corrected: Some(d.corrected as u64),
            corner_sigma: d.corner_sigma,
            likelihood: d.likelihood,
        })
        .collect();
    Ok(FrameResult {
        index: raw.index,
        log_time: raw.log_time,
        publish_time: raw.publish_time,
        stamp,
        frame_id,
        detections,
        poses,
    })
}

/// Runs the detector over every frame of the plan's topic;
/// `progress(done)` is called after each batch.
pub fn run(
    opts: &BagDetectOptions,
    plan: &Plan,
    mut progress: impl FnMut(usize),
) -> Result<Outcome> {
    let path = opts.input.as_path();
    let start = Instant::now();
    let facts = RunFacts {
        input: path.display().to_string(),
        topic: plan.topic.name.clone(),
        camera: plan.camera_source.clone().unwrap_or_default(),
        tag_size_m: opts.tag_size,
        tag_sizes_m: opts
            .tag_sizes
            .iter()
            .map(|((f, id), s)| format!("{f}:{id}={s}"))
            .collect::<Vec<_>>()
            .join(","),
        families: opts
            .config
            .families
            .iter()
            .map(|f| f.family.name().to_string())
            .collect::<Vec<_>>()
            .join(","),
        frames: plan.frames,
        truncated: plan.truncated,
        version: env!("CARGO_PKG_VERSION").into(),
    };
    let poses = opts.wants_poses() && !plan.cameras.is_empty();
    let write_err = |e: mcap::McapError| bad(path, format!("cannot write the output MCAP: {e}"));
    let mut out = BagOutput::new(&facts, poses).map_err(write_err)?;
    let pool: Mutex<Vec<Detector>> = Mutex::new(Vec::new());
    let take = || -> Result<Detector> {
        let spare = pool.lock().map_or(None, |mut p| p.pop());
        match spare {
            Some(d) => Ok(d),
            None => Detector::new(opts.config.clone()).map_err(|e| EvalError::Detector {
                detector: "coppertag".into(),
                message: e.to_string(),
            }),
        }
    };
    let (mut done, mut detections, mut with_pose) = (0, 0, 0);
    // The next batch is read (decompressed and copied out of the bag) on a
    // thread of its own while this one is detected; batches still arrive
    // in the bag's order.
    std::thread::scope(|scope| -> Result<()> {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Result<Vec<RawFrame>>>(1);
        scope.spawn(move || {
            let mut frames = match bag::frames(path, &plan.topic.name, plan.frames) {
                Ok(f) => f,
                Err(e) => {
                    let _ = tx.send(Err(e));
                    return;
                }
            };
            loop {
                let batch: Result<Vec<RawFrame>> = frames.by_ref().take(BATCH_FRAMES).collect();
                let last = batch.as_ref().map_or(true, Vec::is_empty);
                // A closed channel means the run stopped on an error.
                if tx.send(batch).is_err() || last {
                    break;
                }
            }
        });
        for batch in rx {
            let batch = batch?;
            if batch.is_empty() {
                break;
            }
            let results: Vec<Result<FrameResult>> = batch
                .par_iter()
                .map(|raw| {
                    let mut det = take()?;
                    let r = one_frame(plan, opts, &mut det, raw).map_err(|m| {
                        bad(
                            path,
                            format!(
                                "{} message {} (log time {}): {m}",
                                plan.topic.name,
                                raw.index,
                                seconds(raw.log_time)
                            ),
                        )
                    });
                    if let Ok(mut p) = pool.lock() {
                        p.push(det);
                    }
                    r
                })
                .collect();
            for r in results {
                let f = r?;
                detections += f.detections.len();
                with_pose += f.poses.iter().filter(|p| p.is_some()).count();
                out.write_frame(&f).map_err(write_err)?;
                done += 1;
            }
            progress(done);
        }
        Ok(())
    })?;
    let wall_s = start.elapsed().as_secs_f64();
    Ok(Outcome {
        mcap: out.finish().map_err(write_err)?,
        frames: done,
        detections,
        poses: with_pose,
        wall_s,
    })
}

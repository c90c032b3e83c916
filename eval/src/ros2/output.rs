//! The MCAP file `coppertag detect --mcap` writes: what a robot user opens
//! beside the recording in Foxglove.
//!
//! | topic | schema (JSON) | one message per frame |
//! |---|---|---|
//! | `/coppertag/detections` | `coppertag.Detections` | ids, corners, corrections, poses |
//! | `/coppertag/annotations` | `foxglove.ImageAnnotations` | outlines and ids over the image topic |
//! | `/coppertag/tf` | `foxglove.FrameTransforms` | camera frame -> `tag_<family>_<id>`, when poses are made |
//!
//! Every message carries its source frame's log and publish times, and
//! the in-message timestamps are the frame's header stamp, so Foxglove
//! matches the annotations with the images they belong to and places the
//! tags in the camera's frame at the moment the frame was taken. Nothing
//! in the file depends on the clock or the thread count.

use std::collections::BTreeMap;
use std::io::Cursor;

use coppertag::pose::TagPose;
use mcap::records::{MessageHeader, Metadata};
use serde::Serialize;
use serde_json::{json, Value};

use crate::protocol::DetectionRecord;
use crate::runlog::{annotations_at, detections_schema};

/// Topic of the detections.
pub const DETECTIONS_TOPIC: &str = "/coppertag/detections";
/// Topic of the image annotations.
pub const ANNOTATIONS_TOPIC: &str = "/coppertag/annotations";
/// Topic of the tag transforms.
pub const TF_TOPIC: &str = "/coppertag/tf";

/// The camera frame used when a frame's header names none (Foxglove needs
/// a parent frame for a transform).
pub const DEFAULT_CAMERA_FRAME: &str = "camera";

/// One processed frame.
#[derive(Debug, Clone)]
pub struct FrameResult {
    /// Place among the topic's messages.
    pub index: usize,
    /// Source log time, ns.
    pub log_time: u64,
    /// Source publish time, ns.
    pub publish_time: u64,
    /// The frame's header stamp, ns.
    pub stamp: u64,
    /// The frame's camera frame (header `frame_id`).
    pub frame_id: String,
    /// What was found.
    pub detections: Vec<DetectionRecord>,
    /// One pose per detection when a camera model and tag size are known.
    pub poses: Vec<Option<TagPose>>,
}

/// Facts about the run, stored as the `coppertag.detect` metadata record.
#[derive(Debug, Clone, Serialize)]
pub struct RunFacts {
    /// The recording, as given.
    pub input: String,
    /// The image topic read.
    pub topic: String,
    /// Where the camera model came from (a topic or a file), or empty.
    pub camera: String,
    /// Data-square side, metres, or empty when no poses were made.
    pub tag_size_m: Option<f64>,
    /// Per-tag sides, `family:id=metres`, comma separated.
    pub tag_sizes_m: String,
    /// Families searched.
    pub families: String,
    /// Frames read.
    pub frames: usize,
    /// Set when frames after damage in the bag were left out.
    pub truncated: bool,
    /// Toolkit version.
    pub version: String,
}

fn time(ns: u64) -> Value {
    json!({"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000})
}

fn frame_transforms_schema() -> Value {
    let vec3 = json!({"type": "object", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}}});
    let quat = json!({"type": "object", "properties": {
        "x": {"type": "number"}, "y": {"type": "number"}, "z": {"type": "number"}, "w": {"type": "number"}}});
    json!({
        "title": "foxglove.FrameTransforms",
        "description": "Poses of the detected tags in the camera frame",
        "type": "object",
        "properties": {"transforms": {"type": "array", "items": {"type": "object", "properties": {
            "timestamp": {"type": "object", "properties": {
                "sec": {"type": "integer", "minimum": 0},
                "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}},
            "parent_frame_id": {"type": "string"},
            "child_frame_id": {"type": "string"},
            "translation": vec3,
            "rotation": quat
        }}}}
    })
}

/// The frame name of a tag in the transform tree.
#[must_use]
pub fn tag_frame(family: &str, id: u64) -> String {
    format!("tag_{family}_{id}")
}

/// Quaternion `[x, y, z, w]` of a rotation matrix (nalgebra's conversion).
fn quaternion(r: &[[f64; 3]; 3]) -> [f64; 4] {
    let m = nalgebra::Matrix3::from_fn(|i, j| r[i][j]);
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(m),
    );
    [q.i, q.j, q.k, q.w]
}

/// The transforms of one frame: one per tag with a pose; of two
/// detections of the same tag, the one with the smaller reprojection
/// error (a transform tree holds one frame per name).
fn transforms(f: &FrameResult) -> Value {
    let parent = if f.frame_id.is_empty() {
        DEFAULT_CAMERA_FRAME
    } else {
        f.frame_id.as_str()
    };
    let mut best: BTreeMap<String, &TagPose> = BTreeMap::new();
    for (d, p) in f.detections.iter().zip(&f.poses) {
        let Some(p) = p else { continue };
        let name = tag_frame(&d.family, d.id);
        let keep = best
            .get(&name)
            .is_none_or(|q| p.best.reprojection_px < q.best.reprojection_px);
        if keep {
            best.insert(name, p);
        }
    }
    let list: Vec<Value> = best
        .into_iter()
        .map(|(child, p)| {
            let t = p.best.translation;
            let [x, y, z, w] = quaternion(&p.best.rotation);
            json!({
                "timestamp": time(f.stamp),
                "parent_frame_id": parent,
                "child_frame_id": child,
                "translation": {"x": t[0], "y": t[1], "z": t[2]},
                "rotation": {"x": x, "y": y, "z": z, "w": w},
            })
        })
        .collect();
    json!({ "transforms": list })
}

#[derive(Serialize)]
struct DetectionJson<'a> {
    #[serde(flatten)]
    record: &'a DetectionRecord,
    #[serde(skip_serializing_if = "Option::is_none")]
    pose: Option<&'a TagPose>,
}

#[derive(Serialize)]
struct DetectionsJson<'a> {
    index: usize,
    image: &'a str,
    stamp: Value,
    frame_id: &'a str,
    detections: Vec<DetectionJson<'a>>,
}

/// The output file being written, frame by frame in the source's order.
pub struct BagOutput {
    writer: mcap::Writer<Cursor<Vec<u8>>>,
    topic: String,
    detections: u16,
    annotations: u16,
    tf: Option<u16>,
    sequence: u32,
}

type McapResult<T> = std::result::Result<T, mcap::McapError>;

impl BagOutput {
    /// Starts the file; `poses` adds the transforms topic.
    pub fn new(facts: &RunFacts, poses: bool) -> McapResult<Self> {
        // zstd on the calling thread: the bytes do not depend on threads.
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_threads(0)
            .profile("")
            .library(concat!("coppertag-eval ", env!("CARGO_PKG_VERSION")))
            .create(Cursor::new(Vec::new()))?;
        writer.write_metadata(&Metadata {
            name: "coppertag.detect".into(),
            metadata: crate::runlog::to_map(facts),
        })?;
        let none = BTreeMap::new();
        let channel = |w: &mut mcap::Writer<_>, name: &str, schema: Value, topic: &str| {
            let s = w.add_schema(name, "jsonschema", schema.to_string().as_bytes())?;
            w.add_channel(s, topic, "json", &none)
        };
        let detections = channel(
            &mut writer,
            "coppertag.Detections",
            detections_schema(),
            DETECTIONS_TOPIC,
        )?;
        let annotations = channel(
            &mut writer,
            "foxglove.ImageAnnotations",
            coppertag_synth::foxglove::annotations_schema(),
            ANNOTATIONS_TOPIC,
        )?;
        let tf = if poses {
            Some(channel(
                &mut writer,
                "foxglove.FrameTransforms",
                frame_transforms_schema(),
                TF_TOPIC,
            )?)
        } else {
            None
        };
        Ok(Self {
            writer,
            topic: facts.topic.clone(),
            detections,
            annotations,
            tf,
            sequence: 0,
        })
    }

    /// Writes the messages of one frame.
    pub fn write_frame(&mut self, f: &FrameResult) -> McapResult<()> {
        let header = |channel_id| MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: f.log_time,
            publish_time: f.publish_time,
        };
        let msg = DetectionsJson {
            index: f.index,
            image: &self.topic,
            stamp: time(f.stamp),
            frame_id: &f.frame_id,
            detections: f
                .detections
                .iter()
                .zip(&f.poses)
                .map(|(record, p)| DetectionJson {
                    record,
                    pose: p.as_ref(),
                })
                .collect(),
        };
        let text =
            serde_json::to_vec(&msg).map_err(|e| mcap::McapError::Io(std::io::Error::other(e)))?;
        self.writer
            .write_to_known_channel(&header(self.detections), &text)?;
        let ann = annotations_at(&time(f.stamp), &f.detections);
        self.writer
            .write_to_known_channel(&header(self.annotations), ann.to_string().as_bytes())?;
        if let Some(tf) = self.tf {
            self.writer
                .write_to_known_channel(&header(tf), transforms(f).to_string().as_bytes())?;
        }
        self.sequence += 1;
        Ok(())
    }

    /// Finishes the file and returns its bytes.
    pub fn finish(mut self) -> McapResult<Vec<u8>> {
        self.writer.finish()?;
        Ok(self.writer.into_inner().into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_of_known_rotations() {
        let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(quaternion(&id), [0.0, 0.0, 0.0, 1.0]);
        // A quarter turn about z.
        let rz = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
        let q = quaternion(&rz);
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (a, b) in q.iter().zip([0.0, 0.0, h, h]) {
            assert!((a - b).abs() < 1e-12, "{q:?}");
        }
    }
}

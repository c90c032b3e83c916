//! A run as an MCAP file, and reading it back.
//!
//! | record | name or topic | content |
//! |---|---|---|
//! | metadata | `coppertag.run` | [`RunInfo`]: detector, version, parameters, dataset, machine, date |
//! | message | `/detections` (`coppertag.Detections`, JSON) | one per image: index, image, ms, detections (with `corner_sigma` and `likelihood` when the detector reports them), error |
//! | message | `/detections/annotations` (`foxglove.ImageAnnotations`, JSON) | outlines and ids, drawn over the dataset's images |
//! | metadata | `coppertag.resources` | [`RunResources`]: CPU, memory, wall time |
//!
//! Messages carry the dataset's log times (`1 s + index * 100 ms`), so a
//! run opened beside its dataset's MCAP in Foxglove overlays its images.
//! Annotation coordinates use Foxglove's convention (origin at the corner of
//! the top-left pixel): our pixel-centre coordinates plus 0.5.

use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;

use mcap::records::{MessageHeader, Metadata};
use serde::{Deserialize, Serialize};
use serde_json::json;

// One annotation schema and one clock for datasets and runs: synth's.
use coppertag_synth::foxglove::{annotations_schema, log_time, stamp};

use crate::error::{EvalError, Result};
use crate::protocol::ImageResult;
use crate::runner::{IndexedResult, RunInfo, RunOutput, RunResources};

/// One `/detections` message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionsMessage {
    /// Image index in the dataset.
    pub index: usize,
    /// The protocol line for the image.
    #[serde(flatten)]
    pub result: ImageResult,
}

/// The `coppertag.Detections` JSON schema, shared by runs over datasets and
/// detection over recordings (`coppertag detect --mcap`), which adds the
/// optional `stamp`, `frame_id` and per-detection `pose`.
pub(crate) fn detections_schema() -> serde_json::Value {
    json!({
        "title": "coppertag.Detections",
        "description": "Markers one detector found in one dataset image or recorded frame. Corners TL, BL, BR, TR in pixel-centre coordinates; poses in metres, tag frame to camera frame.",
        "type": "object",
        "required": ["index", "image", "detections"],
        "properties": {
            "index": {"type": "integer", "minimum": 0},
            "image": {"type": "string", "description": "image file, or the recording's image topic"},
            "stamp": {"type": "object", "description": "the recorded frame's header stamp",
                "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
            "frame_id": {"type": "string", "description": "the recorded frame's camera frame"},
            "ms": {"type": "number", "description": "detection time, ms, around the detect call only"},
            "error": {"type": "string"},
            "detections": {"type": "array", "items": {
                "type": "object",
                "required": ["family", "id", "corners", "estimated"],
                "properties": {
                    "family": {"type": "string"},
                    "id": {"type": "integer", "minimum": 0},
                    "corners": {"type": "array", "minItems": 4, "maxItems": 4,
                        "items": {"type": "array", "minItems": 2, "maxItems": 2, "items": {"type": "number"}}},
                    "estimated": {"type": "array", "minItems": 4, "maxItems": 4, "items": {"type": "boolean"}},
                    "corrected": {"type": ["integer", "null"]},
                    "corner_sigma": {"type": "array", "minItems": 4, "maxItems": 4, "items": {"type": "number", "minimum": 0},
                        "description": "one-sigma uncertainty of each corner (px, radial), when the detector estimates one; absent otherwise"},
                    "likelihood": {"type": "boolean", "description": "read by likelihood (CopperTag's blurred-tag reading); absent means false"},
                    "pose": {"type": "object", "description": "IPPE's two solutions, better first: rotation (row-major), translation (m), reprojection_px",
                        "properties": {"best": {"type": "object"}, "alternative": {"type": "object"}}}
                }
            }}
        }
    })
}

fn annotations(index: usize, result: &ImageResult) -> serde_json::Value {
    annotations_at(&stamp(log_time(index)), &result.detections)
}

/// A `foxglove.ImageAnnotations` message of `detections` stamped `ts` (a
/// Foxglove time): outlines, estimated corners and ids.
pub(crate) fn annotations_at(
    ts: &serde_json::Value,
    detections: &[crate::protocol::DetectionRecord],
) -> serde_json::Value {
    let mut points = Vec::new();
    let mut texts = Vec::new();
    for d in detections {
        let pts: Vec<_> = d
            .corners
            .iter()
            .map(|c| json!({"x": c[0] + 0.5, "y": c[1] + 0.5}))
            .collect();
        points.push(json!({
            "timestamp": ts, "type": 2, "points": pts,
            "outline_color": {"r": 1.0, "g": 0.55, "b": 0.0, "a": 1.0}, "outline_colors": [],
            "fill_color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0}, "thickness": 2.0
        }));
        // Estimated corners as separate points, so they stand out.
        let est: Vec<_> = d
            .corners
            .iter()
            .zip(d.estimated)
            .filter(|(_, e)| *e)
            .map(|(c, _)| json!({"x": c[0] + 0.5, "y": c[1] + 0.5}))
            .collect();
        if !est.is_empty() {
            points.push(json!({
                "timestamp": ts, "type": 1, "points": est,
                "outline_color": {"r": 1.0, "g": 0.0, "b": 0.0, "a": 1.0}, "outline_colors": [],
                "fill_color": {"r": 1.0, "g": 0.0, "b": 0.0, "a": 1.0}, "thickness": 8.0
            }));
        }
        texts.push(json!({
            "timestamp": ts,
            "position": {"x": d.corners[0][0] + 0.5, "y": d.corners[0][1] + 0.5},
            "text": format!("{} {}", d.family, d.id), "font_size": 16.0,
            "text_color": {"r": 1.0, "g": 0.55, "b": 0.0, "a": 1.0},
            "background_color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.6}
        }));
    }
    json!({"circles": [], "points": points, "texts": texts})
}

/// A value's fields as MCAP metadata: strings as they are, anything else as
/// JSON text.
pub(crate) fn to_map<T: Serialize>(value: &T) -> BTreeMap<String, String> {
    let v = serde_json::to_value(value).unwrap_or_default();
    v.as_object()
        .map(|o| {
            o.iter()
                .map(|(k, v)| {
                    (
                        k.clone(),
                        v.as_str().map_or_else(|| v.to_string(), str::to_string),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

/// Writes a run as MCAP to any seekable writer.
pub fn write_run<W: Write + Seek>(
    w: W,
    run: &RunOutput,
) -> std::result::Result<(), mcap::McapError> {
    let mut out = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .profile("")
        .library(concat!("coppertag-eval ", env!("CARGO_PKG_VERSION")))
        .create(w)?;
    out.write_metadata(&Metadata {
        name: "coppertag.run".into(),
        metadata: to_map(&run.info),
    })?;
    let det_schema = out.add_schema(
        "coppertag.Detections",
        "jsonschema",
        detections_schema().to_string().as_bytes(),
    )?;
    let det = out.add_channel(det_schema, "/detections", "json", &BTreeMap::new())?;
    let ann_schema = out.add_schema(
        "foxglove.ImageAnnotations",
        "jsonschema",
        annotations_schema().to_string().as_bytes(),
    )?;
    let ann = out.add_channel(
        ann_schema,
        "/detections/annotations",
        "json",
        &BTreeMap::new(),
    )?;
    for (seq, r) in run.results.iter().enumerate() {
        let t = log_time(r.index);
        let header = |channel_id| MessageHeader {
            channel_id,
            sequence: seq as u32,
            log_time: t,
            publish_time: t,
        };
        let msg = DetectionsMessage {
            index: r.index,
            result: r.result.clone(),
        };
        out.write_to_known_channel(
            &header(det),
            serde_json::to_string(&msg).unwrap_or_default().as_bytes(),
        )?;
        out.write_to_known_channel(
            &header(ann),
            annotations(r.index, &r.result).to_string().as_bytes(),
        )?;
    }
    out.write_metadata(&Metadata {
        name: "coppertag.resources".into(),
        metadata: to_map(&run.resources),
    })?;
    // finish() reports errors that dropping the writer would swallow.
    out.finish()?;
    Ok(())
}

/// Writes a run to `path` atomically, creating its directory.
pub fn save(path: &Path, run: &RunOutput) -> Result<()> {
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    }
    crate::atomic::write_atomic_with(path, |w| {
        // The MCAP writer seeks back to patch offsets: give it a cursor
        // and copy the finished bytes out.
        let mut buf = std::io::Cursor::new(Vec::new());
        write_run(&mut buf, run).map_err(|e| e.to_string())?;
        std::io::Write::write_all(w, buf.get_ref()).map_err(|e| e.to_string())
    })
}

fn from_map<T: for<'de> Deserialize<'de>>(
    path: &Path,
    name: &str,
    m: &BTreeMap<String, String>,
) -> Result<T> {
    let obj: serde_json::Map<String, serde_json::Value> = m
        .iter()
        .map(|(k, v)| {
            let val = serde_json::from_str::<serde_json::Value>(v)
                .ok()
                .filter(|x| !x.is_string() && !x.is_object() && !x.is_array())
                .unwrap_or_else(|| serde_json::Value::String(v.clone()));
            (k.clone(), val)
        })
        .collect();
    serde_json::from_value(serde_json::Value::Object(obj))
        .map_err(|e| EvalError::bad(path, format!("metadata {name}: {e}")))
}

/// A run read back from MCAP.
#[derive(Debug, Clone)]
pub struct RunLog {
    /// Facts about the run.
    pub info: RunInfo,
    /// Resource use.
    pub resources: RunResources,
    /// One message per image, in log order.
    pub images: Vec<DetectionsMessage>,
}

impl RunLog {
    /// Reads and checks a run file. A truncated or foreign MCAP file, or
    /// one without the run's records, is an error naming the file.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes = std::fs::read(path).map_err(|e| EvalError::io(path, e))?;
        let bad = |m: String| EvalError::bad(path, m);
        if !bytes.starts_with(mcap::MAGIC) {
            return Err(bad("not an MCAP file".into()));
        }
        if !bytes.ends_with(mcap::MAGIC) {
            return Err(bad("truncated MCAP file (no closing magic)".into()));
        }
        let mut info = None;
        let mut resources = None;
        for rec in
            mcap::read::LinearReader::new(&bytes).map_err(|e| bad(format!("corrupt MCAP: {e}")))?
        {
            if let mcap::records::Record::Metadata(m) =
                rec.map_err(|e| bad(format!("corrupt MCAP: {e}")))?
            {
                match m.name.as_str() {
                    "coppertag.run" => {
                        info = Some(from_map::<RunInfo>(path, &m.name, &m.metadata)?)
                    }
                    "coppertag.resources" => {
                        resources = Some(from_map::<RunResources>(path, &m.name, &m.metadata)?)
                    }
                    _ => {}
                }
            }
        }
        let info =
            info.ok_or_else(|| bad("not a coppertag run: no coppertag.run metadata".into()))?;
        let resources = resources
            .ok_or_else(|| bad("incomplete run: no coppertag.resources metadata".into()))?;
        let mut images = Vec::new();
        for msg in
            mcap::MessageStream::new(&bytes).map_err(|e| bad(format!("corrupt MCAP: {e}")))?
        {
            let msg = msg.map_err(|e| bad(format!("corrupt MCAP: {e}")))?;
            if msg.channel.topic != "/detections" {
                continue;
            }
            if msg.channel.schema.as_ref().map(|s| s.name.as_str()) != Some("coppertag.Detections")
            {
                return Err(bad("/detections has the wrong schema".into()));
            }
            let m: DetectionsMessage = serde_json::from_slice(&msg.data)
                .map_err(|e| bad(format!("bad /detections message {}: {e}", msg.sequence)))?;
            images.push(m);
        }
        Ok(Self {
            info,
            resources,
            images,
        })
    }

    /// The results as the runner produced them.
    pub fn results(&self) -> Vec<IndexedResult> {
        self.images
            .iter()
            .map(|m| IndexedResult {
                index: m.index,
                result: m.result.clone(),
            })
            .collect()
    }
}

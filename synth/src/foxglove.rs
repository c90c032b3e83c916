//! The dataset as one MCAP file that Foxglove opens: images, camera
//! calibration, ground truth and ground-truth overlays.
//!
//! Encoding: JSON messages with JSON-schema schemas (schema encoding
//! `jsonschema`, message encoding `json`), the form Foxglove documents for
//! JSON data, binary fields as base64 strings (`contentEncoding: base64`).
//! Foxglove recognises its well-known schemas by name, so the channels use
//! `foxglove.CompressedImage`, `foxglove.CameraCalibration` and
//! `foxglove.ImageAnnotations`; the schemas written here are our own
//! statement of the fields we fill.
//!
//! | topic | schema | one message per image |
//! |---|---|---|
//! | `/camera/image` | `foxglove.CompressedImage` | the PNG, `format: "png"` |
//! | `/camera/calibration` | `foxglove.CameraCalibration` | `plumb_bob` model |
//! | `/camera/annotations` | `foxglove.ImageAnnotations` | corners, outline, occluders, ids |
//! | `/ground_truth` | `coppertag.GroundTruth` | the `truth.csv` rows of the image, with occluder outlines |
//!
//! Times are synthetic and deterministic: image `i` (its index in the full
//! dataset, also with `--every`) is logged at `1 s + i * 100 ms`. Nothing
//! in the file depends on the wall clock. Image annotations use Foxglove's
//! convention (origin at the top-left corner of the top-left pixel), i.e.
//! our pixel-centre coordinates plus 0.5.

use std::collections::BTreeMap;
use std::io::{Seek, Write};

use base64::Engine as _;
use mcap::records::MessageHeader;
use serde_json::{json, Value};

use crate::camera::Camera;
use crate::error::Result;
use crate::scene::MarkerTruth;

/// Log time of image `index` in nanoseconds.
#[must_use]
pub fn log_time(index: usize) -> u64 {
    1_000_000_000 + index as u64 * 100_000_000
}

/// Standard base64 (RFC 4648, with padding), by the `base64` crate.
#[must_use]
pub fn base64(data: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(data)
}

fn time_schema() -> Value {
    json!({"type": "object", "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}}})
}

fn point2() -> Value {
    json!({"type": "object", "properties": {"x": {"type": "number"}, "y": {"type": "number"}}})
}

fn color() -> Value {
    json!({"type": "object", "properties": {
        "r": {"type": "number"}, "g": {"type": "number"}, "b": {"type": "number"}, "a": {"type": "number"}}})
}

fn compressed_image_schema() -> Value {
    json!({
        "title": "foxglove.CompressedImage",
        "description": "A compressed image (PNG here)",
        "type": "object",
        "properties": {
            "timestamp": time_schema(),
            "frame_id": {"type": "string"},
            "data": {"type": "string", "contentEncoding": "base64"},
            "format": {"type": "string"}
        }
    })
}

fn calibration_schema() -> Value {
    let arr = |n: usize| json!({"type": "array", "items": {"type": "number"}, "minItems": n, "maxItems": n});
    json!({
        "title": "foxglove.CameraCalibration",
        "description": "Camera calibration parameters",
        "type": "object",
        "properties": {
            "timestamp": time_schema(),
            "frame_id": {"type": "string"},
            "width": {"type": "integer", "minimum": 0},
            "height": {"type": "integer", "minimum": 0},
            "distortion_model": {"type": "string"},
            "D": {"type": "array", "items": {"type": "number"}},
            "K": arr(9),
            "R": arr(9),
            "P": arr(12)
        }
    })
}

/// The `foxglove.ImageAnnotations` JSON schema (the fields we fill), used
/// by datasets and by eval's runs alike.
#[must_use]
pub fn annotations_schema() -> Value {
    json!({
        "title": "foxglove.ImageAnnotations",
        "description": "Ground-truth overlays",
        "type": "object",
        "properties": {
            "circles": {"type": "array", "items": {"type": "object", "properties": {
                "timestamp": time_schema(), "position": point2(), "diameter": {"type": "number"},
                "thickness": {"type": "number"}, "fill_color": color(), "outline_color": color()}}},
            "points": {"type": "array", "items": {"type": "object", "properties": {
                "timestamp": time_schema(), "type": {"type": "integer"},
                "points": {"type": "array", "items": point2()},
                "outline_color": color(), "outline_colors": {"type": "array", "items": color()},
                "fill_color": color(), "thickness": {"type": "number"}}}},
            "texts": {"type": "array", "items": {"type": "object", "properties": {
                "timestamp": time_schema(), "position": point2(), "text": {"type": "string"},
                "font_size": {"type": "number"}, "text_color": color(), "background_color": color()}}}
        }
    })
}

fn truth_schema() -> Value {
    let xy = json!({"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2});
    json!({
        "title": "coppertag.GroundTruth",
        "description": "Ground truth of one synthetic image: one entry per marker. Corners are TL, BL, BR, TR of the marker square in pixel-centre coordinates; poses map the marker frame (x right, y down, z into the marker) to the camera frame, metres and radians.",
        "type": "object",
        "properties": {
            "timestamp": time_schema(),
            "image": {"type": "string"},
            "index": {"type": "integer"},
            "param": {"type": ["string", "null"]},
            "value": {"type": ["number", "null"]},
            "markers": {"type": "array", "items": {"type": "object", "properties": {
                "index": {"type": "integer"},
                "marker": {"type": "string"},
                "family": {"type": "string"},
                "id": {"type": "integer"},
                "size_m": {"type": "number"},
                "square_m": {"type": "number"},
                "corners": {"type": "array", "items": xy, "minItems": 4, "maxItems": 4},
                "corner_in_image": {"type": "array", "items": {"type": "boolean"}},
                "corner_visible": {"type": "array", "items": {"type": "boolean"}},
                "rvec": {"type": "array", "items": {"type": "number"}},
                "quaternion": {"type": "array", "items": {"type": "number"}},
                "tvec": {"type": "array", "items": {"type": "number"}},
                "side_px": {"type": "number"},
                "occlusion": {"type": ["object", "null"]}
            }}}
        }
    })
}

/// A Foxglove `Time` (`sec`, `nsec`) of a log time in nanoseconds.
#[must_use]
pub fn stamp(t: u64) -> Value {
    json!({"sec": t / 1_000_000_000, "nsec": t % 1_000_000_000})
}

fn rgba(r: f64, g: f64, b: f64, a: f64) -> Value {
    json!({"r": r, "g": g, "b": b, "a": a})
}

/// Foxglove's image coordinates: pixel-centre plus 0.5.
fn pt(p: [f64; 2]) -> Value {
    json!({"x": p[0] + 0.5, "y": p[1] + 0.5})
}

/// An MCAP file being written, one image at a time, in image order.
pub struct McapWriter<W: Write + Seek> {
    writer: mcap::Writer<W>,
    image: u16,
    calibration: u16,
    annotations: u16,
    truth: u16,
    sequence: u32,
}

impl<W: Write + Seek> McapWriter<W> {
    /// Starts the file: schemas, channels, the dataset's metadata and the
    /// spec as an attachment.
    pub fn new(out: W, dataset: &Value, spec_name: &str, spec_text: &str) -> Result<Self> {
        // zstd on one thread: compressed bytes do not depend on the thread
        // count. Chunks mostly hold base64 PNG, which zstd shrinks back by
        // about a quarter.
        let mut writer = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(1)
            .compression_threads(0)
            .profile("")
            .create(out)?;
        let schema = |w: &mut mcap::Writer<W>, name: &str, v: Value| -> Result<u16> {
            Ok(w.add_schema(name, "jsonschema", &serde_json::to_vec(&v)?)?)
        };
        let s_img = schema(
            &mut writer,
            "foxglove.CompressedImage",
            compressed_image_schema(),
        )?;
        let s_cal = schema(
            &mut writer,
            "foxglove.CameraCalibration",
            calibration_schema(),
        )?;
        let s_ann = schema(
            &mut writer,
            "foxglove.ImageAnnotations",
            annotations_schema(),
        )?;
        let s_gt = schema(&mut writer, "coppertag.GroundTruth", truth_schema())?;
        let none = BTreeMap::new();
        let image = writer.add_channel(s_img, "/camera/image", "json", &none)?;
        let calibration = writer.add_channel(s_cal, "/camera/calibration", "json", &none)?;
        let annotations = writer.add_channel(s_ann, "/camera/annotations", "json", &none)?;
        let truth = writer.add_channel(s_gt, "/ground_truth", "json", &none)?;
        let mut meta = BTreeMap::new();
        for key in ["name", "seed", "images", "generator", "format_version"] {
            if let Some(v) = dataset.get(key) {
                meta.insert(
                    key.to_string(),
                    match v {
                        Value::String(s) => s.clone(),
                        other => other.to_string(),
                    },
                );
            }
        }
        writer.write_metadata(&mcap::records::Metadata {
            name: "coppertag.dataset".into(),
            metadata: meta,
        })?;
        writer.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: spec_name.to_string(),
            media_type: "application/toml".into(),
            data: std::borrow::Cow::Borrowed(spec_text.as_bytes()),
        })?;
        Ok(Self {
            writer,
            image,
            calibration,
            annotations,
            truth,
            sequence: 0,
        })
    }

    fn put(&mut self, channel: u16, t: u64, msg: &Value) -> Result<()> {
        let data = serde_json::to_vec(msg)?;
        self.put_bytes(channel, t, &data)
    }

    fn put_bytes(&mut self, channel: u16, t: u64, data: &[u8]) -> Result<()> {
        self.writer.write_to_known_channel(
            &MessageHeader {
                channel_id: channel,
                sequence: self.sequence,
                log_time: t,
                publish_time: t,
            },
            data,
        )?;
        Ok(())
    }

    /// Writes the four messages of one image.
    pub fn write_image(
        &mut self,
        index: usize,
        file: &str,
        png: &[u8],
        camera: &Camera,
        sweep: Option<(&str, f64)>,
        markers: &[MarkerTruth],
    ) -> Result<()> {
        let t = log_time(index);
        let frame = "camera";
        // Written by hand: the base64 text goes straight into the message
        // instead of through a JSON string escaper (it needs no escaping).
        let mut msg = Vec::with_capacity(png.len() / 3 * 4 + 128);
        msg.extend_from_slice(
            format!(
                "{{\"timestamp\":{{\"sec\":{},\"nsec\":{}}},\"frame_id\":\"{frame}\",\"format\":\"png\",\"data\":\"",
                t / 1_000_000_000,
                t % 1_000_000_000
            )
            .as_bytes(),
        );
        let start = msg.len();
        msg.resize(start + png.len().div_ceil(3) * 4, 0);
        let written = base64::engine::general_purpose::STANDARD
            .encode_slice(png, &mut msg[start..])
            .expect("buffer sized for the encoding");
        msg.truncate(start + written);
        msg.extend_from_slice(b"\"}");
        self.put_bytes(self.image, t, &msg)?;
        let k = camera.k_matrix();
        self.put(
            self.calibration,
            t,
            &json!({
                "timestamp": stamp(t), "frame_id": frame,
                "width": camera.width, "height": camera.height,
                "distortion_model": "plumb_bob", "D": camera.distortion, "K": k,
                "R": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                "P": [k[0], 0.0, k[2], 0.0, 0.0, k[4], k[5], 0.0, 0.0, 0.0, 1.0, 0.0],
            }),
        )?;
        self.put(self.annotations, t, &annotations(t, markers))?;
        self.put(
            self.truth,
            t,
            &json!({
                "timestamp": stamp(t), "image": file, "index": index,
                "param": sweep.map(|s| s.0), "value": sweep.map(|s| s.1),
                "markers": markers,
            }),
        )?;
        self.sequence += 1;
        Ok(())
    }

    /// Writes the summary and flushes. Must be called: dropping the writer
    /// would swallow errors.
    pub fn finish(mut self) -> Result<W> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

fn annotations(t: u64, markers: &[MarkerTruth]) -> Value {
    let (green, red, yellow, magenta) = (
        rgba(0.1, 0.9, 0.2, 1.0),
        rgba(1.0, 0.15, 0.1, 1.0),
        rgba(1.0, 0.8, 0.0, 1.0),
        rgba(0.9, 0.2, 0.9, 1.0),
    );
    let clear = rgba(0.0, 0.0, 0.0, 0.0);
    let mut circles = Vec::new();
    let mut points = Vec::new();
    let mut texts = Vec::new();
    for m in markers {
        let all = m.corner_visible.iter().all(|&v| v);
        points.push(json!({
            "timestamp": stamp(t), "type": 2,
            "points": m.corners.iter().map(|&c| pt(c)).collect::<Vec<_>>(),
            "outline_color": if all { green.clone() } else { yellow.clone() },
            "fill_color": clear, "thickness": 1.5,
        }));
        for (c, &vis) in m.corners.iter().zip(&m.corner_visible) {
            let col = if vis { green.clone() } else { red.clone() };
            circles.push(json!({
                "timestamp": stamp(t), "position": pt(*c), "diameter": 7.0, "thickness": 1.5,
                "fill_color": clear, "outline_color": col,
            }));
        }
        if let Some(o) = &m.occlusion {
            for poly in &o.polygons_px {
                points.push(json!({
                    "timestamp": stamp(t), "type": 2,
                    "points": poly.iter().map(|&c| pt(c)).collect::<Vec<_>>(),
                    "outline_color": magenta.clone(), "fill_color": clear, "thickness": 1.0,
                }));
            }
        }
        let label = match &m.occlusion {
            Some(o) => format!(
                "{} {} #{} ({} {:.1}%)",
                m.marker,
                m.family,
                m.id,
                o.scenario.name(),
                100.0 * o.coverage
            ),
            None => format!("{} {} #{}", m.marker, m.family, m.id),
        };
        texts.push(json!({
            "timestamp": stamp(t), "position": pt([m.corners[0][0], m.corners[0][1] - 14.0]), "text": label,
            "font_size": 14.0, "text_color": green.clone(), "background_color": rgba(0.0, 0.0, 0.0, 0.6),
        }));
    }
    json!({"circles": circles, "points": points, "texts": texts})
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in [
            ("", ""),
            ("f", "Zg=="),
            ("fo", "Zm8="),
            ("foo", "Zm9v"),
            ("foob", "Zm9vYg=="),
            ("fooba", "Zm9vYmE="),
            ("foobar", "Zm9vYmFy"),
        ] {
            assert_eq!(base64(i.as_bytes()), o);
        }
    }
}

//! Reading a recording: which topics it has, which of them are camera
//! images and calibrations, and its image messages in file order.
//!
//! A bag is read twice, as a stream (memory bounded by the largest chunk,
//! not the file; `mcap::io::MessageReader`): [`scan`] counts the messages
//! of every topic, keeps the calibration messages, and notes where the
//! file is damaged; [`frames`] then yields the chosen topic's messages.
//! A damaged or truncated bag (a recorder killed mid-write has no summary
//! and ends inside a chunk) is refused unless the caller keeps the
//! messages before the damage.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use crate::error::{EvalError, Result};

/// What a topic's messages are, as far as detection cares.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TopicKind {
    /// `sensor_msgs/msg/Image`, CDR.
    RosImage,
    /// `sensor_msgs/msg/CompressedImage`, CDR.
    RosCompressedImage,
    /// `foxglove.CompressedImage`, JSON (the toolkit's own datasets).
    FoxgloveCompressedImage,
    /// `sensor_msgs/msg/CameraInfo`, CDR.
    RosCameraInfo,
    /// `foxglove.CameraCalibration`, JSON.
    FoxgloveCalibration,
    /// Anything else.
    Other,
}

impl TopicKind {
    fn of(schema: &str, encoding: &str) -> Self {
        match (schema, encoding) {
            ("sensor_msgs/msg/Image", "cdr") => Self::RosImage,
            ("sensor_msgs/msg/CompressedImage", "cdr") => Self::RosCompressedImage,
            ("foxglove.CompressedImage", "json") => Self::FoxgloveCompressedImage,
            ("sensor_msgs/msg/CameraInfo", "cdr") => Self::RosCameraInfo,
            ("foxglove.CameraCalibration", "json") => Self::FoxgloveCalibration,
            _ => Self::Other,
        }
    }

    /// Whether the topic carries camera frames.
    #[must_use]
    pub fn is_image(self) -> bool {
        matches!(
            self,
            Self::RosImage | Self::RosCompressedImage | Self::FoxgloveCompressedImage
        )
    }

    /// Whether the topic carries camera calibrations.
    #[must_use]
    pub fn is_calibration(self) -> bool {
        matches!(self, Self::RosCameraInfo | Self::FoxgloveCalibration)
    }
}

/// One topic of a bag.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    /// Topic name.
    pub name: String,
    /// Schema name (`sensor_msgs/msg/Image`...).
    pub schema: String,
    /// Message encoding (`cdr`, `json`...).
    pub encoding: String,
    /// Messages before the end (or the damage).
    pub messages: usize,
    /// What the messages are.
    pub kind: TopicKind,
}

impl std::fmt::Display for Topic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}, {}, {} messages)",
            self.name, self.schema, self.encoding, self.messages
        )
    }
}

/// One message of the chosen topic.
#[derive(Debug, Clone)]
pub struct RawFrame {
    /// Its place among the topic's messages, from 0.
    pub index: usize,
    /// MCAP log time, ns.
    pub log_time: u64,
    /// MCAP publish time, ns.
    pub publish_time: u64,
    /// The serialized message.
    pub data: Vec<u8>,
}

/// Where a bag stops being readable.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damage {
    /// Messages read before it.
    pub after_messages: usize,
    /// The reader's error.
    pub error: String,
}

/// What a first pass over a bag found.
#[derive(Debug, Clone)]
pub struct Scan {
    /// Topics in order of their first message.
    pub topics: Vec<Topic>,
    /// Every message of every calibration topic: topic -> (log time, data).
    pub calibrations: BTreeMap<String, Vec<(u64, Vec<u8>)>>,
    /// Set when the bag is truncated or damaged.
    pub damage: Option<Damage>,
}

fn reader(path: &Path) -> Result<mcap::io::MessageReader<BufReader<File>>> {
    let file = File::open(path).map_err(|e| EvalError::io(path, e))?;
    let mut head = [0u8; 8];
    let n = std::io::Read::read(&mut &file, &mut head).map_err(|e| EvalError::io(path, e))?;
    if n < head.len() || head != *mcap::MAGIC {
        return Err(EvalError::bad(path, "not an MCAP file"));
    }
    let file = File::open(path).map_err(|e| EvalError::io(path, e))?;
    Ok(mcap::io::MessageReader::new(BufReader::with_capacity(
        1 << 20,
        file,
    )))
}

/// Reads the whole bag once: its topics, its calibrations, its damage.
pub fn scan(path: &Path) -> Result<Scan> {
    let mut topics: Vec<Topic> = Vec::new();
    let mut by_channel: BTreeMap<u16, usize> = BTreeMap::new();
    let mut calibrations: BTreeMap<String, Vec<(u64, Vec<u8>)>> = BTreeMap::new();
    let mut damage = None;
    for (count, msg) in reader(path)?.enumerate() {
        let msg = match msg {
            Ok(m) => m,
            Err(e) => {
                damage = Some(Damage {
                    after_messages: count,
                    error: e.to_string(),
                });
                break;
            }
        };
        let slot = *by_channel.entry(msg.channel.id).or_insert_with(|| {
            let schema = msg.channel.schema.as_ref().map_or("", |s| s.name.as_str());
            topics.push(Topic {
                name: msg.channel.topic.clone(),
                schema: schema.to_string(),
                encoding: msg.channel.message_encoding.clone(),
                messages: 0,
                kind: TopicKind::of(schema, &msg.channel.message_encoding),
            });
            topics.len() - 1
        });
        let topic = &mut topics[slot];
        topic.messages += 1;
        if topic.kind.is_calibration() {
            calibrations
                .entry(topic.name.clone())
                .or_default()
                .push((msg.log_time, msg.data.into_owned()));
        }
    }
    Ok(Scan {
        topics,
        calibrations,
        damage,
    })
}

impl Scan {
    /// The image topic to read: `wanted`, or the only one there is.
    pub fn image_topic(&self, wanted: Option<&str>) -> std::result::Result<&Topic, String> {
        let images: Vec<&Topic> = self.topics.iter().filter(|t| t.kind.is_image()).collect();
        let list = |ts: &[&Topic]| {
            ts.iter()
                .map(|t| format!("  {t}"))
                .collect::<Vec<_>>()
                .join("\n")
        };
        let all: Vec<&Topic> = self.topics.iter().collect();
        match wanted {
            Some(name) => match self.topics.iter().find(|t| t.name == name) {
                Some(t) if t.kind.is_image() => Ok(t),
                Some(t) => Err(format!(
                    "topic {name} is {} ({}), not an image topic; image topics are sensor_msgs/msg/Image, \
                     sensor_msgs/msg/CompressedImage (CDR) and foxglove.CompressedImage (JSON)",
                    t.schema, t.encoding
                )),
                None => Err(format!(
                    "no topic {name} in the bag; its topics:\n{}",
                    list(&all)
                )),
            },
            None => match images.as_slice() {
                [one] => Ok(one),
                [] => Err(format!(
                    "no image topic (sensor_msgs/msg/Image, sensor_msgs/msg/CompressedImage or \
                     foxglove.CompressedImage) in the bag; its topics:\n{}",
                    if all.is_empty() { "  (none)".to_string() } else { list(&all) }
                )),
                many => Err(format!(
                    "{} image topics in the bag, choose one with --topic:\n{}",
                    many.len(),
                    list(many)
                )),
            },
        }
    }

    /// The calibration topic beside `image`: in the same namespace (after
    /// image_transport's `/compressed` suffix is dropped), preferring the
    /// conventional `camera_info` (ROS) or `calibration` (Foxglove) name,
    /// else the only calibration topic there.
    #[must_use]
    pub fn sibling_calibration(&self, image: &Topic) -> Option<&Topic> {
        let base = image
            .name
            .strip_suffix("/compressed")
            .filter(|_| image.kind == TopicKind::RosCompressedImage)
            .unwrap_or(&image.name);
        let ns = base.rsplit_once('/').map_or("", |(ns, _)| ns);
        let here: Vec<&Topic> = self
            .topics
            .iter()
            .filter(|t| t.kind.is_calibration())
            .filter(|t| t.name.rsplit_once('/').map_or("", |(ns, _)| ns) == ns)
            .collect();
        here.iter()
            .find(|t| {
                t.name == format!("{ns}/camera_info") || t.name == format!("{ns}/calibration")
            })
            .or_else(|| if here.len() == 1 { here.first() } else { None })
            .copied()
    }

    /// Messages of `topic` before the damage (all of them in a sound bag).
    #[must_use]
    pub fn messages_of(&self, topic: &str) -> usize {
        self.topics
            .iter()
            .find(|t| t.name == topic)
            .map_or(0, |t| t.messages)
    }
}

/// The messages of `topic` in file order, at most `limit` of them (the
/// count [`scan`] found, so a damaged bag ends before its damage).
pub fn frames(
    path: &Path,
    topic: &str,
    limit: usize,
) -> Result<impl Iterator<Item = Result<RawFrame>>> {
    let owned = path.to_path_buf();
    let topic = topic.to_string();
    let mut index = 0;
    Ok(reader(path)?
        .filter_map(move |m| match m {
            Ok(m) if m.channel.topic == topic => {
                let f = RawFrame {
                    index,
                    log_time: m.log_time,
                    publish_time: m.publish_time,
                    data: m.data.into_owned(),
                };
                index += 1;
                Some(Ok(f))
            }
            Ok(_) => None,
            Err(e) => Some(Err(EvalError::bad(&owned, format!("damaged MCAP: {e}")))),
        })
        .take(limit))
}

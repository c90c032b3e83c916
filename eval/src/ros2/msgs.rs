//! The ROS 2 messages the toolkit reads and writes, as serde structs, and
//! their CDR encoding.
//!
//! A rosbag2 MCAP file stores each message as CDR (OMG Common Data
//! Representation, CORBA 3.4 part 2, section 9.3) behind a four-byte
//! encapsulation header (DDS-RTPS 2.5, section 10.5): two bytes naming the
//! representation, two option bytes. ROS 2's middlewares write plain CDR
//! (XCDR1) in the machine's byte order for these types, so `CDR_LE` and
//! `CDR_BE` are read; the XCDR2 and parameter-list forms align 8-byte
//! fields differently and are refused by name rather than misread.
//!
//! The CDR itself (alignment, sequences, strings) is the `cdr-encoding`
//! crate's (maintained with RustDDS and ros2-client); only the message
//! layouts below are written here, field for field in the order of their
//! `.msg` definitions (`sensor_msgs`, `std_msgs`, `builtin_interfaces`),
//! because no maintained crate ships them without a ROS installation.

use std::borrow::Cow;

use byteorder::{BigEndian, LittleEndian};
use serde::{Deserialize, Serialize};

/// Encapsulation identifier of plain CDR, big-endian.
const CDR_BE: [u8; 2] = [0x00, 0x00];
/// Encapsulation identifier of plain CDR, little-endian.
const CDR_LE: [u8; 2] = [0x00, 0x01];

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds, 0..1e9.
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch (negative times clamp to 0).
    #[must_use]
    pub fn nanos(&self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }

    /// The time of `ns` nanoseconds (seconds past `i32::MAX` saturate).
    #[must_use]
    pub fn from_nanos(ns: u64) -> Self {
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct Header {
    /// Acquisition time.
    pub stamp: Time,
    /// Coordinate frame of the data (the camera's optical frame for images).
    pub frame_id: String,
}

/// `sensor_msgs/msg/Image`; `data` borrowed from the message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Image<'a> {
    /// Stamp and camera frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `bgr8`...; `sensor_msgs/image_encodings.hpp`).
    pub encoding: String,
    /// Byte order of multi-byte pixels (1: big-endian).
    pub is_bigendian: u8,
    /// Bytes from one row's start to the next's.
    pub step: u32,
    /// The pixels.
    #[serde(borrow, with = "bytes")]
    pub data: Cow<'a, [u8]>,
}

/// `sensor_msgs/msg/CompressedImage`; `data` borrowed from the message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage<'a> {
    /// Stamp and camera frame.
    pub header: Header,
    /// `jpeg`, `png`, or image_transport's longer forms (`bgr8; jpeg
    /// compressed bgr8`).
    pub format: String,
    /// The compressed file.
    #[serde(borrow, with = "bytes")]
    pub data: Cow<'a, [u8]>,
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub struct RegionOfInterest {
    /// Left column.
    pub x_offset: u32,
    /// Top row.
    pub y_offset: u32,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Whether a rectified ROI was requested.
    pub do_rectify: bool,
}

/// `sensor_msgs/msg/CameraInfo`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct CameraInfo {
    /// Stamp and camera frame.
    pub header: Header,
    /// Rows of the calibrated image.
    pub height: u32,
    /// Columns of the calibrated image.
    pub width: u32,
    /// `plumb_bob`, `rational_polynomial`, `equidistant`...
    pub distortion_model: String,
    /// Distortion coefficients (`k1, k2, p1, p2, k3` for plumb_bob).
    pub d: Vec<f64>,
    /// Intrinsic matrix, row-major.
    pub k: [f64; 9],
    /// Rectification rotation, row-major.
    pub r: [f64; 9],
    /// Projection matrix, row-major.
    pub p: [f64; 12],
    /// Horizontal binning.
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest.
    pub roi: RegionOfInterest,
}

/// `uint8[]` (a CDR sequence: a `u32` count, then the octets) borrowed
/// from the message when the deserializer lends its bytes, else copied;
/// either way one call, not one serde call per pixel where it can be
/// avoided.
mod bytes {
    use std::borrow::Cow;
    use std::fmt;

    use serde::de::{SeqAccess, Visitor};
    use serde::{Deserializer, Serializer};

    /// Largest sequence pre-allocated on a count read from the message
    /// (a 4K RGBA frame); longer ones grow as they are read, so a corrupt
    /// count cannot allocate gigabytes up front.
    const MAX_PREALLOC: usize = 3840 * 2160 * 4;

    pub fn serialize<S: Serializer>(data: &[u8], s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(data)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Cow<'de, [u8]>, D::Error> {
        d.deserialize_bytes(Octets)
    }

    struct Octets;

    impl<'de> Visitor<'de> for Octets {
        type Value = Cow<'de, [u8]>;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a uint8[] sequence")
        }

        fn visit_borrowed_bytes<E>(self, v: &'de [u8]) -> Result<Self::Value, E> {
            Ok(Cow::Borrowed(v))
        }

        fn visit_bytes<E>(self, v: &[u8]) -> Result<Self::Value, E> {
            Ok(Cow::Owned(v.to_vec()))
        }

        fn visit_byte_buf<E>(self, v: Vec<u8>) -> Result<Self::Value, E> {
            Ok(Cow::Owned(v))
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
            let mut v = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(MAX_PREALLOC));
            while let Some(b) = seq.next_element::<u8>()? {
                v.push(b);
            }
            Ok(Cow::Owned(v))
        }
    }
}

/// Decodes one CDR message (with its encapsulation header).
pub fn decode<'a, T: Deserialize<'a>>(data: &'a [u8]) -> Result<T, String> {
    let Some((head, body)) = data.split_first_chunk::<4>() else {
        return Err(format!(
            "{} bytes is too short for a CDR message",
            data.len()
        ));
    };
    let r = match [head[0], head[1]] {
        CDR_LE => cdr_encoding::from_bytes::<T, LittleEndian>(body),
        CDR_BE => cdr_encoding::from_bytes::<T, BigEndian>(body),
        other => {
            return Err(format!(
                "CDR encapsulation {:#06x} is not plain CDR (only CDR_LE and CDR_BE are read)",
                u16::from_be_bytes(other)
            ))
        }
    };
    r.map(|(v, _)| v).map_err(|e| format!("bad CDR: {e}"))
}

/// Encodes one message as little-endian CDR with its encapsulation header.
pub fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, String> {
    let mut out = vec![CDR_LE[0], CDR_LE[1], 0, 0];
    out.extend(cdr_encoding::to_vec::<T, LittleEndian>(msg).map_err(|e| e.to_string())?);
    Ok(out)
}

//! A rendered dataset as a rosbag2 MCAP file (`coppertag synth --format
//! ros2`), so it can be replayed (`ros2 bag play`) into any ROS 2 detector
//! node and its answers compared with the toolkit's.
//!
//! The dataset's own `dataset.mcap` is translated message by message, on
//! the same log times (image `i` at `1 s + i * 100 ms`), into ROS 2
//! messages (CDR, with `ros2msg` schemas as `ros2 bag record` writes them):
//!
//! | topic | type | from |
//! |---|---|---|
//! | `/camera/image_raw` | `sensor_msgs/msg/Image`, `mono8` | the PNG of `/camera/image` |
//! | `/camera/camera_info` | `sensor_msgs/msg/CameraInfo`, plumb_bob | `/camera/calibration` |
//! | `/ground_truth` | `std_msgs/msg/String` | the `coppertag.GroundTruth` JSON of `/ground_truth` |
//!
//! Ground truth travels as JSON text in a standard message type, so a
//! plain ROS 2 installation plays the bag without custom message packages.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Cursor};
use std::path::Path;

use mcap::records::MessageHeader;
use serde::Serialize;

use super::camera::FoxgloveCalibration;
use super::frame::FoxgloveImage;
use super::msgs::{self, Header, Image, Time};
use crate::error::{EvalError, Result};

/// Where the rosbag2 file goes in the dataset directory.
pub const FILE_NAME: &str = "dataset.ros2.mcap";

/// Frame id of the camera, as in the dataset's own MCAP.
const FRAME: &str = "camera";

const SEP: &str =
    "\n================================================================================\n";
const TIME_DEF: &str = "int32 sec\nuint32 nanosec";
const HEADER_DEF: &str = "builtin_interfaces/Time stamp\nstring frame_id";
const ROI_DEF: &str =
    "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify";

/// The `ros2msg` text of a type and its dependencies, in rosbag2's form:
/// the type's own fields, then each dependency after a separator line and
/// `MSG: <name>`.
fn msgdef(fields: &str, deps: &[(&str, &str)]) -> String {
    let mut s = fields.to_string();
    for (name, def) in deps {
        s.push_str(SEP);
        s.push_str("MSG: ");
        s.push_str(name);
        s.push('\n');
        s.push_str(def);
    }
    s
}

fn header_deps() -> Vec<(&'static str, &'static str)> {
    vec![
        ("std_msgs/Header", HEADER_DEF),
        ("builtin_interfaces/Time", TIME_DEF),
    ]
}

/// `std_msgs/msg/String`.
#[derive(Serialize)]
struct StringMsg<'a> {
    data: &'a str,
}

/// Translates a dataset's `dataset.mcap` into the bytes of a rosbag2 MCAP
/// file.
pub fn from_dataset_mcap(path: &Path) -> Result<Vec<u8>> {
    let bad = |m: String| EvalError::bad(path, m);
    let file = File::open(path).map_err(|e| EvalError::io(path, e))?;
    let wr = |e: mcap::McapError| bad(format!("cannot write the rosbag2 file: {e}"));
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .profile("ros2")
        .library(concat!("coppertag-eval ", env!("CARGO_PKG_VERSION")))
        .create(Cursor::new(Vec::new()))
        .map_err(wr)?;
    let image_def = msgdef(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data",
        &header_deps(),
    );
    let mut info_deps = header_deps();
    info_deps.push(("sensor_msgs/RegionOfInterest", ROI_DEF));
    let info_def = msgdef(
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi",
        &info_deps,
    );
    let none = BTreeMap::new();
    let channel = |w: &mut mcap::Writer<_>, ty: &str, def: &str, topic: &str| {
        let s = w.add_schema(ty, "ros2msg", def.as_bytes())?;
        w.add_channel(s, topic, "cdr", &none)
    };
    let image = channel(
        &mut w,
        "sensor_msgs/msg/Image",
        &image_def,
        "/camera/image_raw",
    )
    .map_err(wr)?;
    let info = channel(
        &mut w,
        "sensor_msgs/msg/CameraInfo",
        &info_def,
        "/camera/camera_info",
    )
    .map_err(wr)?;
    let truth = channel(
        &mut w,
        "std_msgs/msg/String",
        "string data",
        "/ground_truth",
    )
    .map_err(wr)?;
    let mut sequence = 0u32;
    for m in mcap::io::MessageReader::new(BufReader::new(file)) {
        let m = m.map_err(|e| bad(format!("damaged MCAP: {e}")))?;
        let at = |what: &str, e: String| bad(format!("{what} at {} ns: {e}", m.log_time));
        let (channel, data) = match m.channel.topic.as_str() {
            "/camera/image" => {
                let fox = FoxgloveImage::parse(&m.data).map_err(|e| at("/camera/image", e))?;
                let bytes = fox.bytes().map_err(|e| at("/camera/image", e))?;
                let grey = image::load_from_memory(&bytes)
                    .map_err(|e| at("/camera/image", e.to_string()))?
                    .to_luma8();
                let msg = Image {
                    header: Header {
                        stamp: Time::from_nanos(fox.stamp()),
                        frame_id: FRAME.into(),
                    },
                    height: grey.height(),
                    width: grey.width(),
                    encoding: "mono8".into(),
                    is_bigendian: 0,
                    step: grey.width(),
                    data: std::borrow::Cow::Borrowed(grey.as_raw()),
                };
                (
                    image,
                    msgs::encode(&msg).map_err(|e| at("/camera/image", e))?,
                )
            }
            "/camera/calibration" => {
                let cal: FoxgloveCalibration = serde_json::from_slice(&m.data)
                    .map_err(|e| at("/camera/calibration", e.to_string()))?;
                let mut ci = cal.to_camera_info(m.log_time);
                ci.header.frame_id = FRAME.into();
                (
                    info,
                    msgs::encode(&ci).map_err(|e| at("/camera/calibration", e))?,
                )
            }
            "/ground_truth" => {
                let text =
                    std::str::from_utf8(&m.data).map_err(|e| at("/ground_truth", e.to_string()))?;
                (
                    truth,
                    msgs::encode(&StringMsg { data: text }).map_err(|e| at("/ground_truth", e))?,
                )
            }
            _ => continue,
        };
        w.write_to_known_channel(
            &MessageHeader {
                channel_id: channel,
                sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
            },
            &data,
        )
        .map_err(wr)?;
        sequence += 1;
    }
    w.finish().map_err(wr)?;
    Ok(w.into_inner().into_inner())
}

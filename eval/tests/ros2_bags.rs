//! `coppertag detect --mcap` on rosbag2 recordings written by an
//! independent tool (the `mcap-ros2-support` Python package in `.venv`,
//! pinned in eval/peers/requirements.txt): rendered frames as
//! `sensor_msgs/msg/Image` (mono8, bgr8) and `CompressedImage` (JPEG, PNG)
//! with `CameraInfo`, checked against the dataset's truth; the output read
//! back by the Python `mcap` reader; and bad recordings refused.
//!
//! Without `.venv` the tests are skipped (plain `cargo test`), unless
//! `COPPERTAG_REQUIRE_VENV=1` (as `make test` sets), when they fail.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use crate::common;
use common::succeed;
use coppertag_eval::pose_error::{angle_between, rotation_of};
use coppertag_eval::truth::Dataset;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn coppertag() -> Command {
    Command::new(env!("CARGO_BIN_EXE_coppertag"))
}

fn python() -> Option<PathBuf> {
    let py = repo().join(".venv/bin/python");
    if py.is_file() {
        return Some(py);
    }
    let why = format!(
        "SKIPPED: {} not found; run `make venv` (make test does) to test rosbag2 input",
        py.display()
    );
    if std::env::var_os("COPPERTAG_REQUIRE_VENV").is_some_and(|v| v == "1") {
        panic!("{why} (COPPERTAG_REQUIRE_VENV=1)");
    }
    eprintln!("{why}");
    None
}

/// Two tags (ct14 42, ct8 1234) through a lens with distortion, three
/// frames turning in their planes: 640 x 480, so the bags stay small.
const SPEC: &str = r#"
name = "ros2-bag"
seed = 3

[camera]
width = 640
height = 480
fx = 800.0
cx = 321.3
cy = 238.9
distortion = [-0.12, 0.03, 0.0005, -0.0004, 0.0]

[background]
kind = "flat"
level = 0.5

[[markers]]
system = "coppertag"
family = "ct14"
id = 42
size_m = 0.1
translation = [-0.08, 0.0, 0.6]
rotation = [0.3, 0.2, 0.0]

[[markers]]
system = "coppertag"
family = "ct8"
id = 1234
size_m = 0.1
translation = [0.09, 0.02, 0.7]
rotation = [-0.2, 0.4, 0.0]

[sweep]
param = "rz"
unit = "deg"
from = 0
to = 40
step = 20
"#;

/// Header stamp of frame `i`, ns; log times come 5 ms later, so a reader
/// that mixes them up is caught.
fn stamp(i: usize) -> u64 {
    100_000_000_000 + i as u64 * 100_000_000
}
const LOG_DELAY_NS: u64 = 5_000_000;

/// Writes a rosbag2 MCAP file with `mcap_ros2` from a JSON description.
const WRITER: &str = r#"
import io, json, sys
import numpy as np
from PIL import Image
from mcap_ros2.writer import Writer

SEP = "\n" + "=" * 80 + "\n"
TIME = "int32 sec\nuint32 nanosec"
HEADER = "builtin_interfaces/Time stamp\nstring frame_id"
DEPS = SEP + "MSG: std_msgs/Header\n" + HEADER + SEP + "MSG: builtin_interfaces/Time\n" + TIME
DEFS = {
    "sensor_msgs/msg/Image": "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
        "uint8 is_bigendian\nuint32 step\nuint8[] data" + DEPS,
    "sensor_msgs/msg/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data" + DEPS,
    "sensor_msgs/msg/CameraInfo": "std_msgs/Header header\nuint32 height\nuint32 width\n"
        "string distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p\n"
        "uint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi" + DEPS + SEP
        + "MSG: sensor_msgs/RegionOfInterest\nuint32 x_offset\nuint32 y_offset\nuint32 height\n"
        "uint32 width\nbool do_rectify",
    "std_msgs/msg/String": "string data",
}

spec = json.load(open(sys.argv[1]))
cam = spec["camera"]
with open(spec["out"], "wb") as f:
    w = Writer(f, chunk_size=spec.get("chunk_size", 1024 * 1024))
    schemas = {}
    def schema(name):
        if name not in schemas:
            schemas[name] = w.register_msgdef(name, DEFS[name])
        return schemas[name]
    seq = 0
    for frame in spec["frames"]:
        grey = np.asarray(Image.open(frame["png"]).convert("L"))
        h, wd = grey.shape
        for t in spec["topics"]:
            header = {"stamp": {"sec": frame["stamp"] // 10**9, "nanosec": frame["stamp"] % 10**9},
                      "frame_id": t.get("frame_id", "cam_optical")}
            kind = t["kind"]
            if kind in ("mono8", "bgr8", "32FC1", "bayer_rggb8"):
                if kind in ("mono8", "bayer_rggb8"):
                    # A grey scene through any colour filter mosaic is that grey.
                    data, step = grey.tobytes(), wd
                elif kind == "bgr8":
                    data, step = np.repeat(grey[:, :, None], 3, axis=2).tobytes(), wd * 3
                else:
                    data, step = (grey.astype(np.float32) / 255).tobytes(), wd * 4
                msg = {"header": header, "height": h, "width": wd, "encoding": kind,
                       "is_bigendian": 0, "step": step, "data": data}
                name = "sensor_msgs/msg/Image"
            elif kind in ("jpeg", "png"):
                buf = io.BytesIO()
                if kind == "jpeg":
                    Image.fromarray(grey).convert("RGB").save(buf, "JPEG", quality=95)
                else:
                    Image.fromarray(grey).save(buf, "PNG")
                msg = {"header": header, "format": kind, "data": buf.getvalue()}
                name = "sensor_msgs/msg/CompressedImage"
            elif kind == "camera_info":
                fx = t.get("fx", cam["fx"])
                k = [fx, 0.0, cam["cx"], 0.0, cam["fy"], cam["cy"], 0.0, 0.0, 1.0]
                msg = {"header": header, "height": cam["height"], "width": cam["width"],
                       "distortion_model": "plumb_bob", "d": cam["distortion"], "k": k,
                       "r": [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                       "p": [fx, 0, cam["cx"], 0, 0, cam["fy"], cam["cy"], 0, 0, 0, 1.0, 0],
                       "binning_x": 0, "binning_y": 0,
                       "roi": {"x_offset": 0, "y_offset": 0, "height": 0, "width": 0, "do_rectify": False}}
                name = "sensor_msgs/msg/CameraInfo"
            else:
                msg = {"data": "hello"}
                name = "std_msgs/msg/String"
            w.write_message(topic=t["name"], schema=schema(name), message=msg,
                            log_time=frame["stamp"] + frame["delay"], publish_time=frame["stamp"] + frame["delay"],
                            sequence=seq)
            seq += 1
    w.finish()
"#;

struct Fixture {
    _dir: tempfile::TempDir,
    ds: PathBuf,
    truth: Dataset,
    camera: serde_json::Value,
}

/// The dataset, rendered once per test run.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let spec = dir.path().join("ros2-bag.toml");
        std::fs::write(&spec, SPEC).unwrap();
        let ds = dir.path().join("ds");
        let st = coppertag()
            .args(["synth", "--quiet", "--format", "ros2", "-o"])
            .arg(&ds)
            .arg(&spec)
            .status()
            .unwrap();
        assert!(st.success(), "synth failed");
        let truth = Dataset::open(&ds).unwrap();
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(ds.join("dataset.json")).unwrap()).unwrap();
        Fixture {
            _dir: dir,
            ds,
            truth,
            camera: meta["camera"].clone(),
        }
    })
}

/// Writes a bag of the fixture's frames with the given topics
/// (`{"name", "kind", ...}`) into `dir/name`.
fn write_bag(py: &Path, dir: &Path, name: &str, topics: serde_json::Value) -> PathBuf {
    write_bag_chunked(py, dir, name, topics, 1 << 20)
}

/// [`write_bag`] with MCAP chunks of `chunk_size` bytes (1: one message each).
fn write_bag_chunked(
    py: &Path,
    dir: &Path,
    name: &str,
    topics: serde_json::Value,
    chunk_size: usize,
) -> PathBuf {
    let f = fixture();
    let out = dir.join(name);
    let frames: Vec<serde_json::Value> = f
        .truth
        .images
        .iter()
        .enumerate()
        .map(|(i, (_, img))| {
            serde_json::json!({"png": f.ds.join(img), "stamp": stamp(i), "delay": LOG_DELAY_NS})
        })
        .collect();
    let desc = serde_json::json!({
        "out": out, "frames": frames, "topics": topics, "camera": f.camera, "chunk_size": chunk_size,
    });
    let desc_path = dir.join(format!("{name}.json"));
    std::fs::write(&desc_path, desc.to_string()).unwrap();
    succeed(
        Command::new(py).arg("-c").arg(WRITER).arg(&desc_path),
        "bag writer failed",
    );
    out
}

fn detect(bag: &Path, out: &Path, extra: &[&str]) -> Output {
    coppertag()
        .args(["detect", "--quiet", "--mcap"])
        .arg(bag)
        .arg("-o")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

/// The side of the data square, metres (half the printed size).
const SQUARE_M: f64 = 0.05;

/// Every topic the good bag holds: one per encoding the bar names.
fn good_topics() -> serde_json::Value {
    serde_json::json!([
        {"name": "/mono/image_raw", "kind": "mono8"},
        {"name": "/mono/camera_info", "kind": "camera_info"},
        {"name": "/color/image_raw", "kind": "bgr8", "frame_id": "color_optical"},
        {"name": "/color/image_raw/compressed", "kind": "jpeg", "frame_id": "color_optical"},
        {"name": "/color/camera_info", "kind": "camera_info", "frame_id": "color_optical"},
        {"name": "/gray/image_raw/compressed", "kind": "png"},
        {"name": "/gray/camera_info", "kind": "camera_info"},
        {"name": "/bayer/image_raw", "kind": "bayer_rggb8"},
        {"name": "/bayer/camera_info", "kind": "camera_info"},
        {"name": "/chatter", "kind": "string"},
    ])
}

fn good_bag(py: &Path) -> &'static Path {
    static BAG: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &BAG.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let bag = write_bag(py, dir.path(), "good.mcap", good_topics());
        (dir, bag)
    })
    .1
}

/// The messages of an output file, read with the Rust `mcap` reader:
/// topic -> (log time, JSON).
fn messages(path: &Path) -> BTreeMap<String, Vec<(u64, serde_json::Value)>> {
    let bytes = std::fs::read(path).unwrap();
    let mut out: BTreeMap<String, Vec<(u64, serde_json::Value)>> = BTreeMap::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        out.entry(m.channel.topic.clone())
            .or_default()
            .push((m.log_time, serde_json::from_slice(&m.data).unwrap()));
    }
    out
}

fn corners(v: &serde_json::Value) -> [[f64; 2]; 4] {
    std::array::from_fn(|i| std::array::from_fn(|j| v[i][j].as_f64().unwrap()))
}

/// Checks one output against the truth: every tag found with its id,
/// corners within 0.5 px, poses within 1% of the distance and 1 degree.
/// `times(i)` gives frame `i`'s header stamp and log time.
fn check_against_truth(out: &Path, frame_id: &str, times: impl Fn(usize) -> (u64, u64)) {
    let f = fixture();
    let msgs = messages(out);
    let dets = &msgs["/coppertag/detections"];
    assert_eq!(dets.len(), f.truth.images.len());
    for (i, (log_time, m)) in dets.iter().enumerate() {
        let (s, log) = times(i);
        assert_eq!(*log_time, log);
        assert_eq!(m["index"], i);
        assert_eq!(m["frame_id"], frame_id);
        assert_eq!(
            m["stamp"],
            serde_json::json!({"sec": s / 1_000_000_000, "nsec": s % 1_000_000_000})
        );
        let truth = &f.truth.truth[&f.truth.images[i].1];
        let found = m["detections"].as_array().unwrap();
        assert_eq!(found.len(), truth.len(), "frame {i}: {m}");
        for t in truth {
            let d = found
                .iter()
                .find(|d| d["family"] == t.family.as_str() && d["id"] == t.id)
                .unwrap_or_else(|| panic!("frame {i}: {} {} not found", t.family, t.id));
            let c = corners(&d["corners"]);
            let tc = [[t.x0, t.y0], [t.x1, t.y1], [t.x2, t.y2], [t.x3, t.y3]];
            for (a, b) in c.iter().zip(tc) {
                let e = (a[0] - b[0]).hypot(a[1] - b[1]);
                assert!(
                    e < 0.5,
                    "frame {i} {} {}: corner off by {e:.3} px",
                    t.family,
                    t.id
                );
            }
            let (rvec, t_true, side) = t.pose().unwrap();
            assert!((side - SQUARE_M).abs() < 1e-12);
            let p = &d["pose"]["best"];
            let est: [f64; 3] = std::array::from_fn(|k| p["translation"][k].as_f64().unwrap());
            let dist = t_true.iter().map(|v| v * v).sum::<f64>().sqrt();
            let err = est
                .iter()
                .zip(t_true)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(
                err < 0.01 * dist,
                "frame {i} {} {}: position off by {:.2}%",
                t.family,
                t.id,
                100.0 * err / dist
            );
            let r = nalgebra::Matrix3::from_fn(|a, b| p["rotation"][a][b].as_f64().unwrap());
            let deg = angle_between(&r, &rotation_of(rvec)).to_degrees();
            assert!(
                deg < 1.0,
                "frame {i} {} {}: rotation off by {deg:.2} deg",
                t.family,
                t.id
            );
        }
    }
    // One annotation and one transform message per frame, on the same times.
    for topic in ["/coppertag/annotations", "/coppertag/tf"] {
        let times: Vec<u64> = msgs[topic].iter().map(|(t, _)| *t).collect();
        let want: Vec<u64> = dets.iter().map(|(t, _)| *t).collect();
        assert_eq!(times, want, "{topic}");
    }
}

#[test]
fn every_encoding_finds_the_truth() {
    let Some(py) = python() else { return };
    let bag = good_bag(&py);
    let dir = tempfile::tempdir().unwrap();
    for (topic, frame_id) in [
        ("/mono/image_raw", "cam_optical"),
        ("/color/image_raw", "color_optical"),
        ("/color/image_raw/compressed", "color_optical"),
        ("/gray/image_raw/compressed", "cam_optical"),
        ("/bayer/image_raw", "cam_optical"),
    ] {
        let out = dir.path().join(format!("{}.mcap", topic.replace('/', "_")));
        let o = detect(bag, &out, &["--topic", topic, "--tag-size", "0.05"]);
        assert!(
            o.status.success(),
            "{topic}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        check_against_truth(&out, frame_id, |i| (stamp(i), stamp(i) + LOG_DELAY_NS));
    }
}

#[test]
fn output_does_not_depend_on_threads() {
    let Some(py) = python() else { return };
    let bag = good_bag(&py);
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("1.mcap"), dir.path().join("2.mcap"));
    for (out, n) in [(&a, "1"), (&b, "3")] {
        let o = detect(
            bag,
            out,
            &[
                "--topic",
                "/color/image_raw",
                "--tag-size",
                "0.05",
                "--threads",
                n,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn output_reads_back_in_python_mcap() {
    let Some(py) = python() else { return };
    let bag = good_bag(&py);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let o = detect(
        bag,
        &out,
        &["--topic", "/mono/image_raw", "--tag-size", "0.05"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let script = r#"
import json, sys
from mcap.reader import make_reader
with open(sys.argv[1], "rb") as f:
    r = make_reader(f)
    out = {"channels": {}, "messages": []}
    for schema, channel, message in r.iter_messages():
        out["channels"][channel.topic] = [schema.name, schema.encoding, channel.message_encoding]
        d = json.loads(message.data)
        entry = {"topic": channel.topic, "log_time": message.log_time, "publish_time": message.publish_time}
        if channel.topic == "/coppertag/tf":
            entry["children"] = sorted(t["child_frame_id"] for t in d["transforms"])
            entry["parents"] = sorted({t["parent_frame_id"] for t in d["transforms"]})
            entry["stamps"] = sorted({t["timestamp"]["sec"] * 10**9 + t["timestamp"]["nsec"] for t in d["transforms"]})
        if channel.topic == "/coppertag/annotations":
            entry["stamps"] = sorted({p["timestamp"]["sec"] * 10**9 + p["timestamp"]["nsec"] for p in d["points"]})
            entry["texts"] = sorted(t["text"] for t in d["texts"])
        out["messages"].append(entry)
print(json.dumps(out))
"#;
    let o = Command::new(&py)
        .arg("-c")
        .arg(script)
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        v["channels"],
        serde_json::json!({
            "/coppertag/detections": ["coppertag.Detections", "jsonschema", "json"],
            "/coppertag/annotations": ["foxglove.ImageAnnotations", "jsonschema", "json"],
            "/coppertag/tf": ["foxglove.FrameTransforms", "jsonschema", "json"],
        })
    );
    let n = fixture().truth.images.len();
    let msgs = v["messages"].as_array().unwrap();
    assert_eq!(msgs.len(), 3 * n);
    for m in msgs {
        let t = m["log_time"].as_u64().unwrap();
        assert_eq!(m["publish_time"], t);
        let i = (0..n)
            .find(|&i| stamp(i) + LOG_DELAY_NS == t)
            .expect("a source log time");
        match m["topic"].as_str().unwrap() {
            "/coppertag/tf" => {
                assert_eq!(
                    m["children"],
                    serde_json::json!(["tag_ct14_42", "tag_ct8_1234"])
                );
                assert_eq!(m["parents"], serde_json::json!(["cam_optical"]));
                assert_eq!(m["stamps"], serde_json::json!([stamp(i)]));
            }
            "/coppertag/annotations" => {
                assert_eq!(m["stamps"], serde_json::json!([stamp(i)]));
                assert_eq!(m["texts"], serde_json::json!(["ct14 42", "ct8 1234"]));
            }
            _ => {}
        }
    }
}

/// Runs a detection that must fail: exit 2, `want` in the message, and no
/// file (not even a temporary one) left in the output directory.
fn refused(bag: &Path, extra: &[&str], want: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.mcap");
    let o = detect(bag, &out, extra);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for w in want {
        assert!(err.contains(w), "'{w}' not in: {err}");
    }
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "output left behind"
    );
}

#[test]
fn bad_recordings_are_refused_by_name() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    // Several image topics and no --topic: the list, and a way out.
    refused(
        good_bag(&py),
        &[],
        &[
            "5 image topics",
            "--topic",
            "/mono/image_raw",
            "/gray/image_raw/compressed",
        ],
    );
    refused(
        good_bag(&py),
        &["--topic", "/chatter"],
        &["/chatter", "std_msgs/msg/String"],
    );
    // No image topic at all.
    let bag = write_bag(
        &py,
        dir.path(),
        "no-image.mcap",
        serde_json::json!([{"name": "/cam/camera_info", "kind": "camera_info"}]),
    );
    refused(
        &bag,
        &[],
        &[
            "no image topic",
            "/cam/camera_info (sensor_msgs/msg/CameraInfo",
        ],
    );
    // An encoding the detector cannot read.
    let bag = write_bag(
        &py,
        dir.path(),
        "float.mcap",
        serde_json::json!([{"name": "/depth/image", "kind": "32FC1"}]),
    );
    refused(
        &bag,
        &[],
        &["/depth/image message 0", "unsupported encoding '32FC1'"],
    );
    // A calibration with a zero focal length.
    let bag = write_bag(
        &py,
        dir.path(),
        "zero-f.mcap",
        serde_json::json!([
            {"name": "/cam/image_raw", "kind": "mono8"},
            {"name": "/cam/camera_info", "kind": "camera_info", "fx": 0.0},
        ]),
    );
    refused(
        &bag,
        &["--tag-size", "0.05"],
        &["/cam/camera_info message at", "fx (K[0]) = 0"],
    );
    // Poses without any calibration.
    let bag = write_bag(
        &py,
        dir.path(),
        "no-info.mcap",
        serde_json::json!([{"name": "/cam/image_raw", "kind": "mono8"}]),
    );
    refused(
        &bag,
        &["--tag-size", "0.05"],
        &[
            "--tag-size/--tag-sizes need a camera model",
            "/cam/camera_info",
        ],
    );
}

#[test]
fn truncated_bag_is_refused_or_read_up_to_the_damage() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    // One chunk per frame, cut after the first: a recorder killed mid-write.
    let full = write_bag_chunked(
        &py,
        dir.path(),
        "chunked.mcap",
        serde_json::json!([
            {"name": "/mono/image_raw", "kind": "mono8"},
            {"name": "/mono/camera_info", "kind": "camera_info"},
        ]),
        1,
    );
    let full = full.as_path();
    let bytes = std::fs::read(full).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 5]).unwrap();
    refused(
        &cut,
        &["--topic", "/mono/image_raw"],
        &["truncated or damaged", "--allow-truncated"],
    );
    let out = dir.path().join("out.mcap");
    let o = detect(
        &cut,
        &out,
        &[
            "--topic",
            "/mono/image_raw",
            "--tag-size",
            "0.05",
            "--allow-truncated",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let kept = messages(&out)["/coppertag/detections"].len();
    let all = fixture().truth.images.len();
    assert!(kept > 0 && kept < all, "kept {kept} of {all} frames");
    // The frames kept are the first ones, found as in the whole bag.
    let whole = dir.path().join("whole.mcap");
    let o = detect(
        full,
        &whole,
        &["--topic", "/mono/image_raw", "--tag-size", "0.05"],
    );
    assert!(o.status.success());
    let (a, b) = (messages(&out), messages(&whole));
    assert_eq!(
        a["/coppertag/detections"][..],
        b["/coppertag/detections"][..kept]
    );
}

/// The dataset's own times: image `i` at 1 s + i * 100 ms.
fn dataset_time(i: usize) -> (u64, u64) {
    let index = fixture().truth.images[i].0 as u64;
    let t = 1_000_000_000 + index * 100_000_000;
    (t, t)
}

#[test]
fn synth_datasets_read_as_recordings() {
    // The Foxglove-JSON dataset.mcap, with its /camera/calibration.
    let f = fixture();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fox.mcap");
    let o = detect(&f.ds.join("dataset.mcap"), &out, &["--tag-size", "0.05"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_against_truth(&out, "camera", dataset_time);
    // The rosbag2 file of `synth --format ros2`.
    let out = dir.path().join("ros2.mcap");
    let o = detect(
        &f.ds.join("dataset.ros2.mcap"),
        &out,
        &["--tag-size", "0.05"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_against_truth(&out, "camera", dataset_time);
}

#[test]
fn synth_ros2_bag_decodes_in_mcap_ros2() {
    let Some(py) = python() else { return };
    let f = fixture();
    let script = r#"
import json, sys
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
out = []
with open(sys.argv[1], "rb") as fh:
    r = make_reader(fh, decoder_factories=[DecoderFactory()])
    for schema, channel, message, msg in r.iter_decoded_messages():
        e = {"topic": channel.topic, "type": schema.name, "log_time": message.log_time}
        if schema.name == "sensor_msgs/msg/Image":
            e.update(encoding=msg.encoding, width=msg.width, height=msg.height, step=msg.step,
                     bytes=len(msg.data), frame_id=msg.header.frame_id,
                     stamp=msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)
        elif schema.name == "sensor_msgs/msg/CameraInfo":
            e.update(k=list(msg.k), d=list(msg.d), model=msg.distortion_model, width=msg.width)
        else:
            e.update(ids=sorted(m["id"] for m in json.loads(msg.data)["markers"]))
        out.append(e)
print(json.dumps(out))
"#;
    let o = Command::new(&py)
        .arg("-c")
        .arg(script)
        .arg(f.ds.join("dataset.ros2.mcap"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Vec<serde_json::Value> = serde_json::from_slice(&o.stdout).unwrap();
    let n = f.truth.images.len();
    assert_eq!(v.len(), 3 * n);
    let cam = &f.camera;
    for (i, frame) in v.chunks(3).enumerate() {
        let (t, _) = dataset_time(i);
        for e in frame {
            assert_eq!(e["log_time"], t);
        }
        assert_eq!(frame[0]["type"], "sensor_msgs/msg/Image");
        assert_eq!(frame[0]["topic"], "/camera/image_raw");
        assert_eq!(frame[0]["encoding"], "mono8");
        assert_eq!(
            (frame[0]["width"].clone(), frame[0]["height"].clone()),
            (640.into(), 480.into())
        );
        assert_eq!(frame[0]["bytes"], 640 * 480);
        assert_eq!(frame[0]["stamp"], t);
        assert_eq!(frame[1]["type"], "sensor_msgs/msg/CameraInfo");
        assert_eq!(frame[1]["model"], "plumb_bob");
        assert_eq!(frame[1]["d"], cam["distortion"]);
        assert_eq!(
            frame[1]["k"],
            serde_json::json!([
                cam["fx"], 0.0, cam["cx"], 0.0, cam["fy"], cam["cy"], 0.0, 0.0, 1.0
            ])
        );
        assert_eq!(frame[2]["type"], "std_msgs/msg/String");
        assert_eq!(frame[2]["ids"], serde_json::json!([42, 1234]));
    }
}

#[test]
fn camera_file_gives_the_poses() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let bag = write_bag(
        &py,
        dir.path(),
        "no-info.mcap",
        serde_json::json!([{"name": "/cam/image_raw", "kind": "mono8"}]),
    );
    let c = &fixture().camera;
    let yaml = |fx: &serde_json::Value| {
        format!(
            "%YAML:1.0\n---\nimage_width: {}\nimage_height: {}\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {}, 0., {}, 0., {}, {}, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: {}\n",
            c["width"], c["height"], fx, c["cx"], c["fy"], c["cy"], c["distortion"]
        )
    };
    let file = dir.path().join("camera.yaml");
    std::fs::write(&file, yaml(&c["fx"])).unwrap();
    let out = dir.path().join("out.mcap");
    let o = detect(
        &bag,
        &out,
        &["--tag-size", "0.05", "--camera", file.to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_against_truth(&out, "cam_optical", |i| (stamp(i), stamp(i) + LOG_DELAY_NS));
    // Only the tag given a size gets a pose and a transform.
    let o = detect(
        &bag,
        &out,
        &[
            "--tag-sizes",
            "ct8:1234=0.05",
            "--camera",
            file.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let msgs = messages(&out);
    for (_, m) in &msgs["/coppertag/detections"] {
        for d in m["detections"].as_array().unwrap() {
            assert_eq!(d.get("pose").is_some(), d["family"] == "ct8", "{d}");
        }
    }
    for (_, m) in &msgs["/coppertag/tf"] {
        assert_eq!(m["transforms"].as_array().unwrap().len(), 1);
        assert_eq!(m["transforms"][0]["child_frame_id"], "tag_ct8_1234");
    }
    std::fs::write(&file, yaml(&0.into())).unwrap();
    refused(
        &bag,
        &["--tag-size", "0.05", "--camera", file.to_str().unwrap()],
        &["--camera", "fx (K[0]) = 0"],
    );
}

#[test]
fn recordings_evaluate_without_truth() {
    let Some(py) = python() else { return };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tags.mcap");
    let o = detect(
        good_bag(&py),
        &out,
        &["--topic", "/mono/image_raw", "--tag-size", "0.05"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Frames 0 and 1 (0 s and 0.1 s): the tags turn 20 degrees in their
    // planes between them, so each is 10 degrees from their mean.
    let res = dir.path().join("results");
    let o = coppertag()
        .args(["eval", "--recording", "--still", "0:0.15", "--json", "-o"])
        .arg(&res)
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let tags = v["recordings"][out.display().to_string()]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(tags.len(), 2);
    for t in &tags {
        assert_eq!(
            (t["frames_seen"].as_u64(), t["frames"].as_u64()),
            (Some(3), Some(3)),
            "{t}"
        );
        assert_eq!(t["corrected_frames"], 0);
        let j = &t["jitter"];
        assert_eq!(j["frames"], 2);
        assert!(j["corner_px"].as_f64().unwrap() > 1.0, "{t}");
        let rot = j["rotation_deg"].as_f64().unwrap();
        assert!((rot - 10.0).abs() < 0.3, "{t}");
    }
    assert!(res.join("stability.json").is_file());
    // A file that is not a detect output is refused.
    let o = coppertag()
        .args(["eval", "--recording", "-o"])
        .arg(&res)
        .arg(good_bag(&py))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("not an output of `coppertag detect --mcap`")
    );
}

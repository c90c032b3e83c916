//! Robot recordings: detection over rosbag2 MCAP files (ROS 2's default
//! bag format) and the toolkit's own Foxglove-JSON datasets.
//!
//! [`bag`] finds the topics and streams the image messages, [`msgs`] holds
//! the ROS 2 message layouts and their CDR encoding, [`frame`] turns image
//! messages into grey frames, [`camera`] turns calibrations into a camera
//! model, [`detect`] runs the detector over the frames in parallel, and
//! [`output`] writes what Foxglove overlays on the recording.
//! [`dataset_bag`] goes the other way: a rendered dataset as a rosbag2 file.

pub mod bag;
pub mod camera;
pub mod camera_file;
pub mod dataset_bag;
pub mod detect;
pub mod frame;
pub mod msgs;
pub mod output;
pub mod stability;

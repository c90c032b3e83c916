//! `coppertag detect --mcap`: detection over a ROS 2 recording, written as
//! an MCAP file that overlays the recording in Foxglove.

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use coppertag::DetectorConfig;
use coppertag_eval::atomic::write_atomic;
use coppertag_eval::ros2::camera::Calibration;
use coppertag_eval::ros2::camera_file;
use coppertag_eval::ros2::detect::{self, BagDetectOptions};

use super::detect::DetectArgs;

/// Reads a `--camera` file (JSON or YAML; see `ros2::camera_file`).
fn camera_file(path: &Path) -> Result<(String, Calibration)> {
    let cal = camera_file::read(path).map_err(|m| anyhow!("--camera {}: {m}", path.display()))?;
    Ok((path.display().to_string(), cal))
}

/// Runs detection over `input`, writing `args.output`.
pub fn run(args: &DetectArgs, input: &Path, config: DetectorConfig) -> Result<()> {
    let Some(output) = args.output.as_deref() else {
        bail!("--mcap needs -o OUT.mcap");
    };
    if let (Ok(a), Ok(b)) = (input.canonicalize(), output.canonicalize()) {
        if a == b {
            bail!("-o {} would overwrite the recording", output.display());
        }
    }
    let opts = BagDetectOptions {
        input: input.to_path_buf(),
        topic: args.topic.clone(),
        config,
        tag_size: args.tag_size,
        tag_sizes: args
            .tag_sizes
            .iter()
            .map(|t| ((t.family.clone(), t.id), t.metres))
            .collect(),
        camera: args.camera.as_deref().map(camera_file).transpose()?,
        allow_truncated: args.allow_truncated,
    };
    let plan = detect::plan(&opts)?;
    if plan.truncated && !args.quiet {
        eprintln!(
            "warning: {} is truncated or damaged; reading the {} frames of {} before the damage",
            input.display(),
            plan.frames,
            plan.topic.name
        );
    }
    let bar = super::progress::bar(plan.frames, &plan.topic.name, args.quiet);
    let work = || detect::run(&opts, &plan, |done| bar.set_position(done as u64));
    let outcome = super::with_threads(args.threads, work)??;
    bar.finish_and_clear();
    write_atomic(output, &outcome.mcap)?;
    let fps = outcome.frames as f64 / outcome.wall_s.max(1e-9);
    let threads = args
        .threads
        .map_or_else(rayon::current_num_threads, |t| t as usize);
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "input": input.display().to_string(),
                "topic": plan.topic.name,
                "camera": plan.camera_source,
                "frames": outcome.frames,
                "detections": outcome.detections,
                "poses": outcome.poses,
                "truncated": plan.truncated,
                "seconds": outcome.wall_s,
                "frames_per_s": fps,
                "threads": threads,
                "output": output.display().to_string(),
            })
        );
    } else if !args.quiet {
        println!(
            "{}: {} frames of {}, {} detections ({} with a pose) in {:.2} s ({fps:.1} frames/s, {threads} threads) -> {}",
            input.display(),
            outcome.frames,
            plan.topic.name,
            outcome.detections,
            outcome.poses,
            outcome.wall_s,
            output.display()
        );
    }
    Ok(())
}

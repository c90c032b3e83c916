//! `coppertag synth`: render a dataset from a TOML spec.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use coppertag_synth::{generate_shard, DatasetSpec, GenerateOptions, LoadOptions, Shard};
use indicatif::{ProgressBar, ProgressStyle};

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag synth datasets/paper/coppertag-distance-z.toml -o runs/coppertag-distance-z\n  \
    coppertag synth datasets/paper/stag-rotated-x.toml -o runs/stag-rotated-x --quick\n  \
    coppertag synth datasets/examples/robustness.toml -o runs/rob --force --timings\n  \
    coppertag synth datasets/wild/coppertag-wild.toml -o runs/wild-3 --shard 3/16\n  \
    coppertag synth datasets/wild/fp-photos.toml -o runs/fp-photos --photos build/photos\n\n\
    Writes <dir>/images/*.png, truth.csv, dataset.json and dataset.mcap (see datasets/README.md).\n\
    The directory is built beside <dir> under a hidden name and renamed into place at the end;\n\
    on any error nothing is left behind. Same spec and seed, same bytes.")]
pub struct SynthArgs {
    /// Dataset spec (TOML); see datasets/README.md for the format.
    pub spec: PathBuf,

    /// Output directory; must not exist unless --force is given.
    #[arg(short, long)]
    pub output: PathBuf,

    /// Render only one in N images (image names and indices stay those of
    /// the full dataset): every Nth image of a sweep; of a sampled spec,
    /// its first 1/N of scenes with all their renders (a Halton prefix
    /// keeps the spread of every factor).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..))]
    pub every: u64,

    /// A tenth of every sweep: the same as --every 10 (for `make reproduce QUICK=1`).
    #[arg(long, conflicts_with = "every")]
    pub quick: bool,

    /// Replace the output directory if it exists.
    #[arg(long)]
    pub force: bool,

    /// Render only shard K of N (0 <= K < N): the images whose index % N
    /// == K, byte for byte as in the whole dataset; truth.csv, draws.csv and
    /// dataset.mcap hold only those images.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,

    /// Read the background photographs from DIR instead of the spec's
    /// sample.background_dir (e.g. a directory written by
    /// eval/peers/export_photos.py); the spec must have that key.
    #[arg(long, value_name = "DIR")]
    pub photos: Option<PathBuf>,

    /// Use this seed instead of the spec's.
    #[arg(long)]
    pub seed: Option<u64>,

    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=256))]
    pub threads: Option<u64>,

    /// Print a timing breakdown (images/s, time per stage) at the end.
    #[arg(long)]
    pub timings: bool,

    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,

    /// `ros2` also writes the dataset as a rosbag2 MCAP file,
    /// <dir>/dataset.ros2.mcap (sensor_msgs/msg/Image mono8 on
    /// /camera/image_raw, CameraInfo on /camera/camera_info, the ground
    /// truth as JSON in std_msgs/msg/String on /ground_truth), to replay
    /// into a ROS 2 detector node (`ros2 bag play`).
    #[arg(long, value_enum, default_value_t = Format::Files)]
    pub format: Format,
}

/// What `coppertag synth` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// PNG images, truth.csv, dataset.json and dataset.mcap (Foxglove).
    Files,
    /// All of those and dataset.ros2.mcap (rosbag2).
    Ros2,
}

fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    Shard::parse(s)
}

fn ms_per(d: Duration, n: usize) -> f64 {
    d.as_secs_f64() * 1000.0 / n.max(1) as f64
}

/// Runs `coppertag synth`.
pub fn run(args: &SynthArgs) -> Result<()> {
    let load = LoadOptions {
        photos_dir: args.photos.clone(),
    };
    let mut spec = DatasetSpec::load_with(&args.spec, &load)?;
    if let Some(seed) = args.seed {
        spec.set_seed(seed);
    }
    let every = if args.quick { 10 } else { args.every as usize };
    let opts = GenerateOptions {
        every,
        force: args.force,
    };
    let total = spec
        .thinned_indices(every)
        .into_iter()
        .filter(|&i| args.shard.is_none_or(|sh| sh.contains(i)))
        .count();
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(total as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} images, {per_sec}, eta {eta}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    bar.set_message(spec.name.clone());
    let work = || {
        generate_shard(&spec, &args.output, &opts, args.shard, &|done, _| {
            bar.set_position(done as u64)
        })
    };
    let report = super::with_threads(args.threads, work)?
        .with_context(|| format!("cannot render {}", args.spec.display()))?;
    bar.finish_and_clear();
    if args.format == Format::Ros2 {
        use coppertag_eval::ros2::dataset_bag;
        let bag = dataset_bag::from_dataset_mcap(&report.dir.join("dataset.mcap"))?;
        coppertag_eval::atomic::write_atomic(&report.dir.join(dataset_bag::FILE_NAME), &bag)?;
    }
    if !args.quiet {
        eprintln!(
            "{}: {} images in {:.1} s ({:.1} images/s) -> {}",
            spec.name,
            report.images,
            report.wall.as_secs_f64(),
            report.images_per_second(),
            report.dir.display()
        );
    }
    if args.timings {
        let n = report.images;
        let s = report.stages;
        println!(
            "{{\"images\": {n}, \"wall_s\": {:.3}, \"images_per_s\": {:.2}, \"threads\": {}, \
             \"ms_per_image\": {{\"render\": {:.2}, \"png_encode\": {:.2}, \"png_write\": {:.2}, \"mcap\": {:.2}, \"csv\": {:.3}}}, \
             \"png_bytes\": {}, \"mcap_bytes\": {}}}",
            report.wall.as_secs_f64(),
            report.images_per_second(),
            args.threads.map_or_else(rayon::current_num_threads, |t| t as usize),
            ms_per(s.render, n),
            ms_per(s.png, n),
            ms_per(s.write_png, n),
            ms_per(s.mcap, n),
            ms_per(s.csv, n),
            report.png_bytes,
            report.mcap_bytes,
        );
    }
    Ok(())
}

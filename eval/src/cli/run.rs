//! `coppertag run`: one detector over one dataset, logged to MCAP.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::runlog;
use coppertag_eval::runner::{self, DetectorSpec};
use coppertag_eval::shard::Shard;
use coppertag_eval::truth::Dataset;

use super::progress::bar;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag run --dataset build/datasets/coppertag-distance-z --detector coppertag -o runs/coppertag.mcap\n  \
    coppertag run --dataset build/datasets/apriltag3-rotated-x --detector apriltag3 -o runs/apriltag3.mcap\n  \
    coppertag run --dataset DIR --command 'python3 my_adapter.py' --name mine -o runs/mine.mcap\n  \
    coppertag run --dataset DIR --detector coppertag --shard 3/16 -o runs/coppertag-3.mcap\n\n\
    Peers run as subprocesses speaking the line protocol of eval/peers/README.md.")]
pub struct RunArgs {
    /// Dataset directory made by `coppertag synth`.
    #[arg(long)]
    pub dataset: PathBuf,

    /// Detector: coppertag (in process), apriltag3, aruco3, stag or fractal
    /// (Python adapters in --peers).
    #[arg(long, required_unless_present = "command")]
    pub detector: Option<String>,

    /// Any other detector: a command that speaks the line protocol (split
    /// on whitespace). Use with --name.
    #[arg(long, conflicts_with = "detector", requires = "name")]
    pub command: Option<String>,

    /// Name of a --command detector in reports.
    #[arg(long)]
    pub name: Option<String>,

    /// Run log to write (MCAP).
    #[arg(short, long)]
    pub output: PathBuf,

    /// Python interpreter for the peer adapters.
    #[arg(long, default_value = ".venv/bin/python")]
    pub python: PathBuf,

    /// Directory of the peer adapters.
    #[arg(long, default_value = "eval/peers")]
    pub peers: PathBuf,

    /// Only shard K of N: the images whose index i has i % N == K (for
    /// example 0/8). `coppertag eval` given the N shard logs gives the
    /// unsharded result. See datasets/cluster/README.md.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<Shard>,

    /// Print the run's totals as one JSON line.
    #[arg(long)]
    pub json: bool,

    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs the subcommand.
pub fn run(args: &RunArgs) -> Result<()> {
    let spec = match (&args.detector, &args.command) {
        (Some(name), _) => DetectorSpec::by_name(name, &args.python, &args.peers)?,
        (None, Some(cmd)) => DetectorSpec::Subprocess {
            name: args.name.clone().unwrap_or_else(|| "custom".into()),
            command: cmd.split_whitespace().map(str::to_string).collect(),
        },
        (None, None) => anyhow::bail!("give --detector NAME or --command CMD"),
    };
    let dataset = Dataset::open(&args.dataset)
        .with_context(|| format!("cannot open dataset {}", args.dataset.display()))?;
    let total = args.shard.map_or(dataset.images.len(), |s| {
        dataset
            .images
            .iter()
            .filter(|(i, _)| s.contains(*i))
            .count()
    });
    let pb = bar(
        total,
        &format!("{} {}", spec.name(), dataset.name),
        args.quiet,
    );
    let out = runner::run_shard(&spec, &dataset, args.shard, |done, _| {
        pb.set_position(done as u64)
    })?;
    pb.finish_and_clear();
    runlog::save(&args.output, &out)?;
    let found: usize = out.results.iter().map(|r| r.result.detections.len()).sum();
    if args.json {
        println!(
            "{}",
            serde_json::json!({"detector": out.info.detector, "dataset": out.info.dataset, "images": out.resources.images,
                "errors": out.resources.errors, "detections": found, "output": args.output.display().to_string()})
        );
    } else {
        eprintln!(
            "{} on {}: {} images, {} detections, {} image errors -> {}",
            out.info.detector,
            out.info.dataset,
            out.resources.images,
            found,
            out.resources.errors,
            args.output.display()
        );
    }
    Ok(())
}

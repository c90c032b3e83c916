//! `coppertag speed`: our time against each peer's on the same frames,
//! interleaved, with a noise band (method: `coppertag_eval::speed`).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::atomic::write_atomic_in_new_dir as write_atomic;
use coppertag_eval::gate::Tolerances;
use coppertag_eval::runner::DetectorSpec;
use coppertag_eval::speed::{confirm_failures, measure, SpeedOptions, SpeedReport};

use super::progress::bar;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag speed --work build/quick -o build/quick/results/speed.json\n  \
    coppertag speed --work build/quick --only stag --reps 9 --json\n\n\
    Needs the datasets of a `coppertag reproduce` run (make gate makes them). For every sweep that\n\
    coppertag and a peer both ran, up to --frames-per-sweep frames are timed with ours and the peer\n\
    back to back, --reps rounds; per frame the best of the rounds counts. The ratio printed is the\n\
    median over frames of ours/peer, with a 95% bootstrap band that resamples frames and rounds.\n\
    With --confirm-against, when the run fails the gate's speed check against that baseline, every\n\
    peer whose whole band lies above the baseline's limit is measured a second time; the output keeps\n\
    both, and `coppertag gate` checks the second.")]
pub struct SpeedArgs {
    /// Work directory of a `coppertag reproduce` run (its `datasets/` is used).
    #[arg(long, default_value = "build/quick")]
    pub work: PathBuf,

    /// Where the measurement goes (JSON; every timing is kept).
    #[arg(long, short)]
    pub output: Option<PathBuf>,

    /// Peers to compare with (default: apriltag3, aruco3, stag, fractal).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,

    /// Sweeps to use, e.g. distance-z,occlusion (default: every sweep both ran).
    #[arg(long, value_delimiter = ',')]
    pub sweeps: Vec<String>,

    /// Rounds over all frames; each frame is timed this often per side (2 to 100).
    #[arg(long, default_value_t = SpeedOptions::default().reps)]
    pub reps: usize,

    /// Frames per sweep, at most, spread evenly over the sweep.
    #[arg(long, default_value_t = SpeedOptions::default().frames_per_sweep)]
    pub frames_per_sweep: usize,

    /// Bootstrap resamples for the noise band (100 to 100000).
    #[arg(long, default_value_t = SpeedOptions::default().resamples)]
    pub resamples: usize,

    /// TEST ONLY: make our detector take this many times as long by burning
    /// CPU after each detection (1 to 10), to prove the gate catches a
    /// slowdown. Recorded in the output.
    #[arg(long, default_value_t = 1.0)]
    pub slowdown: f64,

    /// Baseline (JSON, as `coppertag gate` reads it): when the run fails
    /// the gate's speed check against it, measure again, once, every peer
    /// whose whole band lies above its limit there, so that a burst of load
    /// on one measurement does not fail the gate alone.
    #[arg(long, value_name = "BASELINE")]
    pub confirm_against: Option<PathBuf>,

    /// With --confirm-against: relative growth of the ratio allowed beyond
    /// the noise band (as `coppertag gate --time-ratio`).
    #[arg(long, default_value_t = Tolerances::default().time_ratio)]
    pub time_ratio: f64,

    /// Python interpreter for the peer adapters.
    #[arg(long, default_value = ".venv/bin/python")]
    pub python: PathBuf,

    /// Directory of the peer adapters.
    #[arg(long, default_value = "eval/peers")]
    pub peers: PathBuf,

    /// Print the measurement as one JSON document on stdout.
    #[arg(long)]
    pub json: bool,

    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// One line per peer: times and the ratio with its band.
pub fn describe(report: &SpeedReport) -> String {
    let mut out = format!(
        "{:<10} {:>7} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9}  ratio [95% band]\n",
        "peer", "frames", "ours med", "ours p95", "ours max", "peer med", "peer p95", "peer max"
    );
    for (name, p) in &report.peers {
        out.push_str(&format!(
            "{name:<10} {:>7} {:>7.2}ms {:>7.2}ms {:>7.2}ms {:>7.2}ms {:>7.2}ms {:>7.2}ms  {:.3}x [{:.3}x, {:.3}x]\n",
            p.frames.len(),
            p.ours_ms.median,
            p.ours_ms.p95,
            p.ours_ms.max,
            p.peer_ms.median,
            p.peer_ms.p95,
            p.peer_ms.max,
            p.ratio.median,
            p.ratio.low,
            p.ratio.high
        ));
    }
    out
}

/// Runs the subcommand.
pub fn run(args: &SpeedArgs) -> Result<()> {
    let options = SpeedOptions {
        reps: args.reps,
        frames_per_sweep: args.frames_per_sweep,
        sweeps: args.sweeps.clone(),
        slowdown: args.slowdown,
        resamples: args.resamples,
        ..SpeedOptions::default()
    };
    options.validate()?;
    if !(args.time_ratio.is_finite() && args.time_ratio >= 0.0) {
        anyhow::bail!("--time-ratio must be a non-negative number");
    }
    let baseline = args
        .confirm_against
        .as_deref()
        .map(super::gate::read_baseline)
        .transpose()?;
    let names: Vec<String> = if args.only.is_empty() {
        vec![
            "apriltag3".into(),
            "aruco3".into(),
            "stag".into(),
            "fractal".into(),
        ]
    } else {
        args.only.clone()
    };
    let peers = names
        .iter()
        .map(|n| {
            if n == "coppertag" {
                anyhow::bail!("--only names peers; coppertag is always measured");
            }
            Ok(DetectorSpec::by_name(n, &args.python, &args.peers)?)
        })
        .collect::<Result<Vec<_>>>()?;
    let datasets = args.work.join("datasets");
    if !datasets.is_dir() {
        anyhow::bail!(
            "{} does not exist: render the datasets first (coppertag reproduce --quick --work {})",
            datasets.display(),
            args.work.display()
        );
    }
    let pb = bar(0, "speed", args.quiet || args.json);
    let config = coppertag::detect::DetectorConfig::default();
    let progress = |done: usize, total: usize| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    };
    let mut report = measure(&datasets, &config, &peers, &options, progress)
        .context("speed measurement failed")?;
    if let Some(baseline) = &baseline {
        let tol = Tolerances {
            time_ratio: args.time_ratio,
            ..Tolerances::default()
        };
        let again = confirm_failures(&mut report, baseline, tol, |name| {
            let peer = peers
                .iter()
                .find(|p| p.name() == name)
                .expect("a measured peer is one of the peers asked for");
            let mut one = measure(
                &datasets,
                &config,
                std::slice::from_ref(peer),
                &options,
                progress,
            )?;
            Ok(one.peers.remove(name).expect("the peer just measured"))
        })
        .context("speed measurement failed")?;
        if !again.is_empty() && !args.json {
            eprintln!(
                "measured a second time (the first band lay above the baseline's limit): {}",
                again.join(", ")
            );
        }
    }
    pb.finish_and_clear();
    let json = serde_json::to_string_pretty(&report)?;
    if let Some(out) = &args.output {
        write_atomic(out, json.as_bytes())?;
    }
    if args.json {
        println!("{json}");
    } else {
        if options.slowdown > 1.0 {
            eprintln!(
                "NOTE: ours slowed down {}x on purpose (--slowdown)",
                options.slowdown
            );
        }
        eprint!("{}", describe(&report));
    }
    Ok(())
}

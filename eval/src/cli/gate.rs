//! `coppertag gate`: fail on regressions against a committed baseline.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::atomic::write_atomic_in_new_dir as write_atomic;
use coppertag_eval::gate::{baseline_of, check, Baseline, Tolerances};

use super::evaluate::read_summaries;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag gate --baseline reports/baseline.json --summary build/quick/results/summary.json\n  \
    coppertag gate --baseline reports/baseline.json --summary build/quick/results/summary.json --update\n\n\
    Fails (exit 1) when a detection rate falls, wrong ids, false positives or duplicates grow, the median\n\
    or p95 corner error grows by more than --corner-px or --corner-fraction (the larger), or our median\n\
    time relative to a peer measured in the same run grows by more than --time-ratio.")]
pub struct GateArgs {
    /// Committed baseline (JSON).
    #[arg(long)]
    pub baseline: PathBuf,

    /// summary.json from `coppertag eval` for the run to check.
    #[arg(long)]
    pub summary: PathBuf,

    /// Absolute corner-error growth allowed, px.
    #[arg(long, default_value_t = 0.05)]
    pub corner_px: f64,

    /// Relative corner-error growth allowed.
    #[arg(long, default_value_t = 0.10)]
    pub corner_fraction: f64,

    /// Relative growth allowed in our time over a peer's.
    #[arg(long, default_value_t = 0.25)]
    pub time_ratio: f64,

    /// Write the summary as the new baseline instead of checking.
    #[arg(long)]
    pub update: bool,
}

/// Runs the subcommand; returns whether the gate passed.
pub fn run(args: &GateArgs) -> Result<bool> {
    let summaries = read_summaries(&args.summary)?;
    if args.update {
        let b = baseline_of(&summaries, "coppertag gate --update (make baseline)");
        write_atomic(&args.baseline, serde_json::to_string_pretty(&b)?.as_bytes())?;
        eprintln!(
            "wrote baseline {} ({} entries)",
            args.baseline.display(),
            b.entries.len()
        );
        return Ok(true);
    }
    let text = std::fs::read_to_string(&args.baseline)
        .with_context(|| format!("cannot read {}", args.baseline.display()))?;
    let baseline: Baseline = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a baseline file", args.baseline.display()))?;
    for (name, v) in [
        ("--corner-px", args.corner_px),
        ("--corner-fraction", args.corner_fraction),
        ("--time-ratio", args.time_ratio),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            anyhow::bail!("{name} must be a non-negative number");
        }
    }
    let fails = check(
        &baseline,
        &summaries,
        Tolerances {
            corner_px: args.corner_px,
            corner_fraction: args.corner_fraction,
            time_ratio: args.time_ratio,
        },
    );
    if fails.is_empty() {
        eprintln!(
            "gate passed: {} entries, {} speed ratios checked",
            baseline.entries.len(),
            baseline.time_ratio_vs.len()
        );
        return Ok(true);
    }
    eprintln!("gate FAILED against {}:", args.baseline.display());
    for f in &fails {
        eprintln!("  - {f}");
    }
    Ok(false)
}

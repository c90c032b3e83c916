//! `coppertag gate`: fail on regressions against a committed baseline.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::atomic::write_atomic_in_new_dir as write_atomic;
use coppertag_eval::gate::{
    baseline_of, check, check_speed, check_wild, update_wild, Baseline, Tolerances,
};
use coppertag_eval::speed::SpeedReport;

use super::evaluate::{read_summaries, read_wild};

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag gate --baseline reports/baseline.json --summary build/quick/results/summary.json \\\n      \
    --speed build/quick/results/speed.json\n  \
    coppertag gate --baseline reports/baseline.json --summary build/quick/results/summary.json \\\n      \
    --speed build/quick/results/speed.json --update\n  \
    coppertag gate --baseline reports/baseline.json --summary build/quick/results/summary.json \\\n      \
    --wild build/quick/results/wild.json --update-wild\n\n\
    Fails (exit 1) when a detection rate falls, wrong ids, false positives or duplicates grow, the median\n\
    or p95 corner error grows by more than --corner-px or --corner-fraction (the larger), or the median\n\
    over the peers of the low end of the 95% noise band of our time over each peer's (from `coppertag\n\
    speed`), divided by the baseline ratio, exceeds 1 + --time-ratio (one peer drifting alone cannot\n\
    fail it; a peer of the baseline not measured does), or, for CopperTag's wild-slice entry (from --wild), the\n\
    detection rate falls or rough detections, wrong ids or false positives (per megapixel on tag-free\n\
    frames) grow. --update-wild adds or replaces only what the wild slice decides (the wild entries,\n\
    and every system's entries of the wild datasets named in --wild, from --summary) and leaves the\n\
    rest of the baseline as it is; --update-system NAME does the same for one system's entries (and, with --speed,\n\
    its speed ratio), e.g. a newly added peer. Exit 2: unreadable input.")]
pub struct GateArgs {
    /// Committed baseline (JSON).
    #[arg(long)]
    pub baseline: PathBuf,

    /// summary.json from `coppertag eval` for the run to check.
    #[arg(long)]
    pub summary: PathBuf,

    /// speed.json from `coppertag speed` (required when the baseline has
    /// speed ratios).
    #[arg(long)]
    pub speed: Option<PathBuf>,

    /// Absolute corner-error growth allowed, px.
    #[arg(long, default_value_t = Tolerances::default().corner_px)]
    pub corner_px: f64,

    /// Relative corner-error growth allowed.
    #[arg(long, default_value_t = Tolerances::default().corner_fraction)]
    pub corner_fraction: f64,

    /// Relative growth allowed in our time over the peers', beyond the noise band (the median over
    /// the peers is checked).
    #[arg(long, default_value_t = Tolerances::default().time_ratio)]
    pub time_ratio: f64,

    /// wild.json from `coppertag reproduce` or `coppertag eval --wild`
    /// (required when the baseline has wild entries).
    #[arg(long)]
    pub wild: Option<PathBuf>,

    /// Write the summary as the new baseline instead of checking.
    #[arg(long, conflicts_with_all = ["update_wild", "update_system"])]
    pub update: bool,

    /// Add (or replace) only this system's entries (detector name, e.g.
    /// `fractal`) from --summary, and its speed ratio from --speed when
    /// given, keeping every other entry as it is.
    #[arg(long, value_name = "NAME", conflicts_with = "update_wild")]
    pub update_system: Option<String>,

    /// Add (or replace) only what the wild slice decides: the wild
    /// entries, from --wild, and every system's entries of the datasets
    /// --wild names (the sampled scenes, jitter and tag-free sets), from
    /// --summary; every other entry is kept as it is.
    #[arg(long, requires = "wild")]
    pub update_wild: bool,
}

/// Reads a baseline file (also for `coppertag speed --confirm-against`).
pub(super) fn read_baseline(path: &std::path::Path) -> Result<Baseline> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a baseline file", path.display()))
}

/// Runs the subcommand; returns whether the gate passed.
pub fn run(args: &GateArgs) -> Result<bool> {
    let summaries = read_summaries(&args.summary)?;
    let wild = args.wild.as_deref().map(read_wild).transpose()?;
    if args.update_wild {
        let mut b = read_baseline(&args.baseline)?;
        // `--update-wild` requires `--wild`.
        let Some(w) = wild.as_ref() else {
            anyhow::bail!("--update-wild needs --wild");
        };
        let n = update_wild(&mut b, &summaries, w);
        if b.wild.is_empty() {
            anyhow::bail!(
                "{}: no gated system (coppertag) in the wild summary",
                args.wild
                    .as_deref()
                    .unwrap_or(std::path::Path::new(""))
                    .display()
            );
        }
        write_atomic(&args.baseline, serde_json::to_string_pretty(&b)?.as_bytes())?;
        eprintln!(
            "wrote the wild entries of baseline {} ({} entries) and {n} entries of the wild \
             datasets ({})",
            args.baseline.display(),
            b.wild.len(),
            w.all_datasets().cloned().collect::<Vec<_>>().join(", ")
        );
        return Ok(true);
    }
    let speed: Option<SpeedReport> = match &args.speed {
        None => None,
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            Some(
                serde_json::from_str(&text)
                    .with_context(|| format!("{}: not a `coppertag speed` file", p.display()))?,
            )
        }
    };
    if let Some(s) = speed.as_ref().filter(|s| s.options.slowdown != 1.0) {
        if args.update {
            anyhow::bail!(
                "refusing to make a baseline from a deliberately slowed run (slowdown {})",
                s.options.slowdown
            );
        }
    }
    if let Some(system) = &args.update_system {
        if speed.as_ref().is_some_and(|s| s.options.slowdown != 1.0) {
            anyhow::bail!("refusing to take a speed ratio from a deliberately slowed run");
        }
        let mut b = read_baseline(&args.baseline)?;
        let fresh = baseline_of(&summaries, speed.as_ref(), None, "");
        let prefix = format!("{system}/");
        let entries: Vec<_> = fresh
            .entries
            .into_iter()
            .filter(|(k, _)| k.starts_with(&prefix))
            .collect();
        if entries.is_empty() {
            anyhow::bail!(
                "{}: no entries of system '{system}'",
                args.summary.display()
            );
        }
        let n = entries.len();
        b.entries.retain(|k, _| !k.starts_with(&prefix));
        b.entries.extend(entries);
        if speed.is_some() {
            let Some(ratio) = fresh.speed_ratio_vs.get(system) else {
                anyhow::bail!("the speed file has no ratio against '{system}'");
            };
            b.speed_ratio_vs.insert(system.clone(), *ratio);
        }
        write_atomic(&args.baseline, serde_json::to_string_pretty(&b)?.as_bytes())?;
        eprintln!(
            "wrote {n} entries of {system}{} into baseline {}",
            if speed.is_some() {
                " and its speed ratio"
            } else {
                ""
            },
            args.baseline.display()
        );
        return Ok(true);
    }
    if args.update {
        let b = baseline_of(
            &summaries,
            speed.as_ref(),
            wild.as_ref(),
            "coppertag gate --update (make baseline)",
        );
        write_atomic(&args.baseline, serde_json::to_string_pretty(&b)?.as_bytes())?;
        eprintln!(
            "wrote baseline {} ({} entries)",
            args.baseline.display(),
            b.entries.len()
        );
        return Ok(true);
    }
    let baseline = read_baseline(&args.baseline)?;
    for (name, v) in [
        ("--corner-px", args.corner_px),
        ("--corner-fraction", args.corner_fraction),
        ("--time-ratio", args.time_ratio),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            anyhow::bail!("{name} must be a non-negative number");
        }
    }
    let tol = Tolerances {
        corner_px: args.corner_px,
        corner_fraction: args.corner_fraction,
        time_ratio: args.time_ratio,
    };
    let mut fails = check(&baseline, &summaries, tol);
    match &wild {
        Some(w) => fails.extend(check_wild(&baseline, w)),
        None if !baseline.wild.is_empty() => anyhow::bail!(
            "{} has wild entries: give --wild (wild.json from `coppertag reproduce`)",
            args.baseline.display()
        ),
        None => {}
    }
    match &speed {
        Some(speed) => {
            if speed.options.slowdown != 1.0 {
                eprintln!(
                    "note: this speed run slowed ours {}x on purpose",
                    speed.options.slowdown
                );
            }
            for (peer, first) in &speed.first_attempts {
                eprintln!(
                    "time vs {peer}: the first measurement, {:.3}x (95% band {:.3}x-{:.3}x), lay \
                     wholly above its limit while the check failed, so it was measured again; the \
                     second is checked:",
                    first.ratio.median, first.ratio.low, first.ratio.high
                );
            }
            let check = check_speed(&baseline, speed, tol);
            for v in &check.peers {
                eprintln!("{v}");
            }
            eprintln!("{check}");
            if check.failed {
                fails.push(check.to_string());
            }
        }
        None if !baseline.speed_ratio_vs.is_empty() => anyhow::bail!(
            "{} has speed ratios: give --speed (from `coppertag speed`)",
            args.baseline.display()
        ),
        None => eprintln!("note: no speed ratios in the baseline; speed not checked"),
    }
    if fails.is_empty() {
        eprintln!(
            "gate passed: {} entries, {} wild entries, {} speed ratios checked",
            baseline.entries.len(),
            baseline.wild.len(),
            baseline.speed_ratio_vs.len()
        );
        return Ok(true);
    }
    eprintln!("gate FAILED against {}:", args.baseline.display());
    for f in &fails {
        eprintln!("  - {f}");
    }
    Ok(false)
}

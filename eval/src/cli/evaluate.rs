//! `coppertag eval`: metrics of runs against their datasets' ground truth.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::atomic::write_atomic_in_new_dir as write_atomic;
use coppertag_eval::metrics::{evaluate, MatchRule, Summary};
use coppertag_eval::ros2::stability::{self, Still};
use coppertag_eval::runlog::RunLog;
use coppertag_eval::shard;
use coppertag_eval::truth::Dataset;
use coppertag_eval::wild;
use coppertag_eval::wild_summary::{summarise, WildSummary};

#[derive(Args, Debug)]
#[command(after_help = "Example:\n  coppertag eval runs/*.mcap -o results/\n  \
    coppertag eval --wild runs/coppertag-shard-*.mcap -o results/\n  \
    coppertag eval --recording tags.mcap --still 2:8 -o results/\n\n\
    Writes results/summary.json (every figure, with per-image outcomes) and results/summary.csv.\n\
    Shard runs (`coppertag run --shard K/N`) of one detector on one dataset are merged first: the\n\
    result is exactly that of the unsharded run. All N shards must be given.\n\
    A run that cannot be read, or whose dataset is gone, is reported and skipped; the others are\n\
    still evaluated and written, and the exit code is 2.")]
pub struct EvalArgs {
    /// Run logs (MCAP) from `coppertag run` (with --recording: outputs of
    /// `coppertag detect --mcap`).
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,

    /// Output directory for summary.json and summary.csv (with
    /// --recording: stability.json).
    #[arg(short, long, default_value = "results")]
    pub output: PathBuf,

    /// Dataset directory to use instead of the one recorded in each run.
    #[arg(long)]
    pub dataset: Option<PathBuf>,

    /// Smallest corner distance, px, within which a marker counts as found.
    #[arg(long, default_value_t = 3.0)]
    pub match_px: f64,

    /// Corner distance as a fraction of the marker side; the larger of the
    /// two applies.
    #[arg(long, default_value_t = 0.05)]
    pub match_fraction: f64,

    /// Also evaluate marker by marker for the wild benchmark (rough
    /// detections, pose error, jitter, false positives per megapixel,
    /// factor curves from draws.csv, and the share of corners within 2
    /// sigma for detectors that report a corner sigma, printed too):
    /// writes wild.json, wild-systems.csv, wild-factors.csv and wild-scenarios.csv.
    #[arg(long)]
    pub wild: bool,

    /// Print the summaries (without per-image rows) as JSON on stdout.
    #[arg(long)]
    pub json: bool,

    /// The files are outputs of `coppertag detect --mcap` (recordings,
    /// no ground truth): report per tag the frames it was seen in, its
    /// Reed-Solomon corrections and, with --still, its jitter; writes
    /// OUTPUT/stability.json.
    #[arg(long, conflicts_with_all = ["dataset", "wild"])]
    pub recording: bool,

    /// With --recording: a stretch in which neither the camera nor the
    /// tags move, FROM:TO in seconds after the first frame; corner and
    /// pose jitter are measured over it.
    #[arg(long, requires = "recording", value_parser = parse_still, value_name = "FROM:TO")]
    pub still: Option<Still>,
}

fn parse_still(s: &str) -> std::result::Result<Still, String> {
    let bad = || format!("'{s}' is not FROM:TO seconds (e.g. 2.5:8)");
    let (a, b) = s.split_once(':').ok_or_else(bad)?;
    let (from_s, to_s): (f64, f64) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if !(from_s.is_finite() && to_s.is_finite() && from_s >= 0.0 && to_s > from_s) {
        return Err(format!("{s}: need 0 <= FROM < TO"));
    }
    Ok(Still { from_s, to_s })
}

/// `--recording`: per-tag stability of detect --mcap outputs.
fn recording(args: &EvalArgs) -> Result<()> {
    let mut all = BTreeMap::new();
    for path in &args.runs {
        let tags = stability::evaluate(path, args.still)?;
        if !args.json {
            println!("{}:", path.display());
            for t in &tags {
                let jitter = t.jitter.as_ref().map_or(String::new(), |j| {
                    format!(
                        "; still ({} frames): corners {:.3} px{}{}",
                        j.frames,
                        j.corner_px,
                        j.translation_mm
                            .map_or(String::new(), |v| format!(", position {v:.2} mm")),
                        j.rotation_deg
                            .map_or(String::new(), |v| format!(", rotation {v:.3} deg")),
                    )
                });
                println!(
                    "  {} {}: seen in {}/{} frames, corrected in {} (mean {:.2}, max {}){jitter}",
                    t.family,
                    t.id,
                    t.frames_seen,
                    t.frames,
                    t.corrected_frames,
                    t.corrected_mean,
                    t.corrected_max
                );
            }
        }
        all.insert(path.display().to_string(), tags);
    }
    let doc = serde_json::json!({"still": args.still, "recordings": all});
    if args.json {
        println!("{doc}");
    }
    write_atomic(
        &args.output.join("stability.json"),
        serde_json::to_string_pretty(&doc)?.as_bytes(),
    )?;
    Ok(())
}

/// A run ready to evaluate: its log (a sharded run's shards merged into
/// one) and its dataset (the union of the shards' datasets), with the
/// directories the dataset came from.
pub struct Loaded {
    /// The run.
    pub run: RunLog,
    /// Its dataset.
    pub dataset: Dataset,
    /// Dataset directories (one per shard when each shard had its own).
    pub dirs: Vec<PathBuf>,
}

fn open_one(path: &Path, dataset: Option<&Path>) -> Result<(RunLog, Dataset)> {
    let run = RunLog::read(path)?;
    let dir = dataset.map_or_else(|| PathBuf::from(&run.info.dataset_dir), Path::to_path_buf);
    let ds = Dataset::open(&dir)
        .with_context(|| format!("run {} needs its dataset {}", path.display(), dir.display()))?;
    Ok((run, ds))
}

/// Reads runs and their datasets. Shard runs (`coppertag run --shard`) of
/// one detector on one dataset are merged into the run the unsharded
/// command would have logged, wherever they appear among `runs`; the
/// merged run takes the place of its first shard. Returns the runs and the
/// errors, one per bad run or incomplete set of shards.
pub fn load_all(runs: &[PathBuf], dataset: Option<&Path>) -> (Vec<Loaded>, Vec<String>) {
    enum Item {
        Whole(Box<Loaded>),
        Shards(String),
    }
    let mut items = Vec::new();
    let mut groups: BTreeMap<String, Vec<(RunLog, Dataset)>> = BTreeMap::new();
    let mut errors = Vec::new();
    for path in runs {
        match open_one(path, dataset) {
            Err(e) => errors.push(format!("{e:#}")),
            Ok((run, ds)) if run.info.shard.is_empty() => {
                let dirs = vec![ds.dir.clone()];
                items.push(Item::Whole(Box::new(Loaded {
                    run,
                    dataset: ds,
                    dirs,
                })));
            }
            Ok((run, ds)) => {
                let count = run.info.shard.split_once('/').map_or("", |s| s.1);
                let key = format!("{} on {} in {count} shards", run.info.detector, ds.name);
                let group = groups.entry(key.clone()).or_default();
                if group.is_empty() {
                    items.push(Item::Shards(key));
                }
                group.push((run, ds));
            }
        }
    }
    let mut out = Vec::new();
    for item in items {
        match item {
            Item::Whole(l) => out.push(*l),
            Item::Shards(key) => {
                let (logs, parts): (Vec<RunLog>, Vec<Dataset>) =
                    groups.remove(&key).unwrap_or_default().into_iter().unzip();
                let mut dirs: Vec<PathBuf> = parts.iter().map(|d| d.dir.clone()).collect();
                dirs.sort();
                dirs.dedup();
                match shard::merge(logs).and_then(|run| shard::union(&parts).map(|d| (run, d))) {
                    Ok((run, dataset)) => out.push(Loaded { run, dataset, dirs }),
                    Err(e) => errors.push(format!("{key}: {e}")),
                }
            }
        }
    }
    (out, errors)
}

/// Evaluates runs; returns the summaries and the errors, one per bad run.
pub fn evaluate_all(
    runs: &[PathBuf],
    dataset: Option<&Path>,
    rule: MatchRule,
) -> (Vec<Summary>, Vec<String>) {
    let (loaded, errors) = load_all(runs, dataset);
    let summaries = loaded
        .iter()
        .map(|l| evaluate(&l.run, &l.dataset, rule))
        .collect();
    (summaries, errors)
}

/// The marker-by-marker evaluation of loaded runs on sampled datasets,
/// aggregated; errors name the dataset whose draws or camera are bad.
pub fn evaluate_wild(loaded: &[Loaded], rule: MatchRule) -> (WildSummary, Vec<String>) {
    let mut runs = Vec::new();
    let mut errors = Vec::new();
    for l in loaded {
        let dirs: Vec<&Path> = l.dirs.iter().map(PathBuf::as_path).collect();
        match wild::open_extras(&dirs) {
            Ok((draws, camera)) => {
                let mut run = wild::evaluate(&l.run, &l.dataset, draws.as_ref(), &camera, rule);
                if run.detector == "coppertag" && !run.tag_free {
                    match wild::read_at_truth(&l.dataset, &dirs) {
                        Ok(read) => {
                            for o in &mut run.outcomes {
                                o.read_at_truth = read.get(&(o.index, o.marker_index)).copied();
                            }
                        }
                        Err(e) => errors.push(format!("{}: {e}", l.dataset.name)),
                    }
                }
                runs.push(run);
            }
            Err(e) => errors.push(format!("{}: {e}", l.dataset.name)),
        }
    }
    (summarise(&runs), errors)
}

/// Writes wild.json, wild-systems.csv, wild-factors.csv and
/// wild-scenarios.csv into `dir`, and the dense sets' dense-*.csv when
/// there are any.
pub fn write_wild(dir: &Path, w: &WildSummary) -> Result<()> {
    let json = serde_json::to_string_pretty(w)?;
    write_atomic(&dir.join("wild.json"), json.as_bytes())?;
    for (name, text) in w.csv_files() {
        write_atomic(&dir.join(name), text.as_bytes())?;
    }
    Ok(())
}

/// Reads wild.json.
pub fn read_wild(path: &Path) -> Result<WildSummary> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a wild summary", path.display()))
}

/// Writes summary.json and summary.csv into `dir`.
pub fn write_summaries(dir: &Path, summaries: &[Summary]) -> Result<()> {
    let json = serde_json::to_string_pretty(&serde_json::json!({ "summaries": summaries }))?;
    write_atomic(&dir.join("summary.json"), json.as_bytes())?;
    let mut csv = String::from(
        "detector,dataset,marker,images,image_errors,markers,found,detection_rate,wrong_ids,false_positives,duplicates,mislocated,\
         corner_real_n,corner_real_mean,corner_real_median,corner_real_p95,corner_real_max,\
         corner_est_n,corner_est_mean,corner_est_median,corner_est_p95,corner_est_max,\
         time_median_ms,time_mean_ms,time_p95_ms,cpu_percent_core,peak_memory_mib\n",
    );
    for s in summaries {
        let (r, e, t) = (&s.corner_error_real, &s.corner_error_estimated, &s.time_ms);
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{:.6},{},{},{},{},{},{:.4},{:.4},{:.4},{:.4},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.2},{:.1}\n",
            s.detector, s.dataset, s.marker, s.images, s.image_errors, s.markers, s.found, s.detection_rate,
            s.wrong_ids, s.false_positives, s.duplicates, s.mislocated,
            r.n, r.mean, r.median, r.p95, r.max, e.n, e.mean, e.median, e.p95, e.max,
            t.median, t.mean, t.p95, s.cpu_percent, s.peak_memory_mib
        ));
    }
    write_atomic(&dir.join("summary.csv"), csv.as_bytes())?;
    Ok(())
}

/// Reads summary.json.
pub fn read_summaries(path: &Path) -> Result<Vec<Summary>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    #[derive(serde::Deserialize)]
    struct File {
        summaries: Vec<Summary>,
    }
    let f: File = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a summary file", path.display()))?;
    Ok(f.summaries)
}

/// The honesty of each system's corner sigmas (`make calibrate-sigma`
/// reads it here): one line per system that reports a sigma, and one per
/// set when it ran on several.
fn print_sigma(w: &WildSummary) {
    for r in &w.systems {
        let Some(c) = &r.corner_sigma else { continue };
        eprintln!("{:>10} wild {}", r.system, c.describe());
        if r.corner_sigma_by_set.len() > 1 {
            for (set, c) in &r.corner_sigma_by_set {
                eprintln!("{:>10}   {set}: {}", "", c.describe());
            }
        }
    }
}

/// Runs the subcommand.
pub fn run(args: &EvalArgs) -> Result<()> {
    if args.recording {
        return recording(args);
    }
    if !(args.match_px.is_finite()
        && args.match_px > 0.0
        && args.match_fraction.is_finite()
        && args.match_fraction >= 0.0)
    {
        anyhow::bail!("--match-px must be > 0 and --match-fraction >= 0");
    }
    let rule = MatchRule {
        min_px: args.match_px,
        side_fraction: args.match_fraction,
    };
    let (loaded, mut errors) = load_all(&args.runs, args.dataset.as_deref());
    let summaries: Vec<Summary> = loaded
        .iter()
        .map(|l| evaluate(&l.run, &l.dataset, rule))
        .collect();
    if args.wild && !loaded.is_empty() {
        let (w, wild_errors) = evaluate_wild(&loaded, rule);
        errors.extend(wild_errors);
        write_wild(&args.output, &w)?;
        if !args.json {
            print_sigma(&w);
        }
    }
    for e in &errors {
        eprintln!("error: {e}");
    }
    if !summaries.is_empty() {
        write_summaries(&args.output, &summaries)?;
    }
    if args.json {
        let mut brief = summaries.clone();
        for s in &mut brief {
            s.per_image.clear();
        }
        println!("{}", serde_json::to_string(&brief)?);
    } else {
        for s in &summaries {
            eprintln!(
                "{:>10} {:<28} rate {:>6.2}%  corners median {:.3} px p95 {:.3} px  time median {:.2} ms  wrong {} fp {} dup {}",
                s.detector, s.dataset, 100.0 * s.detection_rate, s.corner_error_real.median, s.corner_error_real.p95,
                s.time_ms.median, s.wrong_ids, s.false_positives, s.duplicates
            );
        }
    }
    if !errors.is_empty() {
        anyhow::bail!(
            "{} of {} runs could not be evaluated",
            errors.len(),
            args.runs.len()
        );
    }
    Ok(())
}

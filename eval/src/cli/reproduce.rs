//! `coppertag reproduce`: datasets -> runs -> metrics -> report, from
//! nothing, for every spec under the given directories.
//!
//! A failing step (a peer that crashes, a dataset that will not render) is
//! reported and skipped; everything else is still produced, and the command
//! exits 2 at the end so the failure is not missed.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use coppertag_eval::atomic::write_atomic_in_new_dir as write_atomic;
use coppertag_eval::metrics::MatchRule;
use coppertag_eval::report::{write_report, Machine};
use coppertag_eval::resources;
use coppertag_eval::runlog;
use coppertag_eval::runner::{self, DetectorSpec};
use coppertag_eval::truth::Dataset;
use coppertag_synth::{generate, DatasetSpec, GenerateOptions, LoadOptions};

use super::evaluate::{evaluate_all, evaluate_wild, load_all, write_summaries, write_wild};
use super::progress::bar;
use super::report::preamble;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag reproduce                      # everything, into build/ and reports/\n  \
    coppertag reproduce --quick --work build/quick --reports build/quick/reports\n\n\
    Spec files are datasets/<dir>/<marker>-<name>.toml; <marker> (coppertag, apriltag3, aruco3, stag, fractal)\n\
    picks the detector that runs on the dataset. Specs in --wild (default datasets/wild, skipped when\n\
    absent) without a marker prefix are run by every detector; the wild runs make the report's wild\n\
    section (rough detections, pose error, jitter, false positives per MP, factor curves). Wild specs\n\
    with sample.background_dir (the natural-photo false-positive set) read the photographs that\n\
    eval/peers/export_photos.py writes into <work>/photos first.")]
pub struct ReproduceArgs {
    /// A tenth of every set: every 10th image of a sweep; of a sampled
    /// (wild) spec, its first tenth of scenes with all their renders (an
    /// even spread over every factor, and jitter groups kept whole).
    #[arg(long)]
    pub quick: bool,

    /// Directories of dataset specs, in order.
    #[arg(long, num_args = 1.., default_values = ["datasets/paper", "datasets/robustness", "datasets/challenge"])]
    pub specs: Vec<PathBuf>,

    /// Working directory for datasets, runs and results (replaced).
    #[arg(long, default_value = "build")]
    pub work: PathBuf,

    /// Directory of the wild (sampled-scene) specs; skipped when absent.
    /// A spec named <marker>-*.toml runs that marker's detector; any other
    /// (a tag-free set, say) runs every detector. Their runs make the
    /// report's wild section.
    #[arg(long, default_value = "datasets/wild")]
    pub wild: PathBuf,

    /// Where the tables and figures go.
    #[arg(long, default_value = "reports")]
    pub reports: PathBuf,

    /// Python interpreter for the peer adapters.
    #[arg(long, default_value = ".venv/bin/python")]
    pub python: PathBuf,

    /// Directory of the peer adapters.
    #[arg(long, default_value = "eval/peers")]
    pub peers: PathBuf,

    /// Only these marker systems (default: all five).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,

    /// Spec directories (among --specs) whose runs are scored for
    /// detection only: the robustness curves quote no time. Their
    /// detectors run --jobs sessions at once, each on its own shard of the
    /// images, put back together exactly as one run (see `coppertag run
    /// --shard`); the report shows no times for them. Every other run is
    /// timed one image after another, since sessions running side by side
    /// slow each other down (on this 2-core machine, our detector's median
    /// doubled).
    #[arg(long, num_args = 0.., default_values = ["datasets/robustness"])]
    pub untimed: Vec<PathBuf>,

    /// Scores detection only, on every set: each run's detector sessions
    /// run --jobs at once, as on the --untimed sets, and no table quotes a
    /// time. For the gate's quick run (`make quick-run`): the gate checks
    /// detection, errors and corners from it, and measures speed apart,
    /// interleaved with the peers (`coppertag speed`).
    #[arg(long)]
    pub no_times: bool,

    /// Detector sessions at once on the --untimed sets. Default: the number
    /// of cores.
    #[arg(long, short = 'j', value_parser = clap::value_parser!(u16).range(1..=256))]
    pub jobs: Option<u16>,

    /// No progress bars.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Whether a spec file sets `sample.background_dir` (photographs exported
/// by `eval/peers/export_photos.py`): a line of the file starting with the
/// key. A wrong guess is caught by the spec loader, which rejects a
/// photos directory for a spec without the key and a missing one for a
/// spec with it.
fn wants_photos(spec: &Path) -> bool {
    std::fs::read_to_string(spec).is_ok_and(|t| {
        t.lines()
            .any(|l| l.trim_start().starts_with("background_dir"))
    })
}

/// Writes the natural photographs of the false-positive set into `dir`
/// with the peers' Python (scikit-image ships them; the version is pinned
/// in eval/peers/requirements.txt).
fn export_photos(args: &ReproduceArgs, dir: &Path) -> Result<()> {
    let script = args.peers.join("export_photos.py");
    let out = std::process::Command::new(&args.python)
        .arg(&script)
        .arg(dir)
        .output()
        .with_context(|| format!("cannot run {} {}", args.python.display(), script.display()))?;
    if !out.status.success() {
        anyhow::bail!(
            "{} failed: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(())
}

/// Datasets this small are rendered whole even in quick mode.
const QUICK_KEEP_WHOLE: usize = 50;

fn spec_files(dirs: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    for dir in dirs {
        if !dir.exists() {
            continue;
        }
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        out.extend(files);
    }
    Ok(out)
}

fn marker_of(spec: &Path) -> String {
    let stem = spec
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    stem.split('-').next().unwrap_or_default().to_string()
}

/// One spec to render and the detectors to run on it.
struct Job {
    spec: PathBuf,
    detectors: Vec<String>,
    wild: bool,
    /// Scored for detection only: detected with several sessions at once.
    untimed: bool,
}

fn jobs(args: &ReproduceArgs) -> Result<Vec<Job>> {
    let wanted = |m: &str| args.only.is_empty() || args.only.iter().any(|o| o == m);
    let mut out = Vec::new();
    for dir in &args.specs {
        let untimed = args.untimed.contains(dir);
        for spec in spec_files(std::slice::from_ref(dir))? {
            if wanted(&marker_of(&spec)) {
                out.push(Job {
                    detectors: vec![marker_of(&spec)],
                    spec,
                    wild: false,
                    untimed,
                });
            }
        }
    }
    for spec in spec_files(std::slice::from_ref(&args.wild))? {
        let marker = marker_of(&spec);
        let detectors: Vec<String> = if runner::KNOWN.contains(&marker.as_str()) {
            vec![marker]
        } else {
            runner::KNOWN.iter().map(|s| s.to_string()).collect()
        };
        let detectors: Vec<String> = detectors.into_iter().filter(|d| wanted(d)).collect();
        if !detectors.is_empty() {
            out.push(Job {
                spec,
                detectors,
                wild: true,
                untimed: false,
            });
        }
    }
    Ok(out)
}

/// Runs the subcommand.
pub fn run(args: &ReproduceArgs) -> Result<()> {
    let jobs = jobs(args)?;
    if jobs.is_empty() {
        anyhow::bail!("no dataset specs found in {:?}", args.specs);
    }
    let every = if args.quick { 10 } else { 1 };
    let workers = args.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        usize::from,
    );
    let mut failures = Vec::new();
    let mut runs = Vec::new();
    let mut wild_runs = Vec::new();
    std::fs::create_dir_all(&args.work)
        .with_context(|| format!("cannot create {}", args.work.display()))?;
    let photos_dir = args.work.join("photos");
    let photos = if jobs.iter().any(|j| wants_photos(&j.spec)) {
        export_photos(args, &photos_dir).map_err(|e| format!("{e:#}"))
    } else {
        Ok(())
    };
    for (i, job) in jobs.iter().enumerate() {
        let spec_path = &job.spec;
        let stem = spec_path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let label = format!("[{}/{}] {stem}", i + 1, jobs.len());
        let dataset_dir = args.work.join("datasets").join(&stem);
        let rendered = if wants_photos(spec_path) {
            photos.clone().map_err(anyhow::Error::msg).and_then(|()| {
                DatasetSpec::load_with(
                    spec_path,
                    &LoadOptions {
                        photos_dir: Some(photos_dir.clone()),
                    },
                )
                .map_err(anyhow::Error::from)
            })
        } else {
            DatasetSpec::load(spec_path).map_err(anyhow::Error::from)
        };
        let rendered = rendered.and_then(|spec| {
            // Small sets (the 20 occlusion images) are kept whole in quick
            // mode: a tenth of them says nothing.
            let every = if spec.image_count() <= QUICK_KEEP_WHOLE {
                1
            } else {
                every
            };
            let pb = bar(
                spec.thinned_indices(every).len(),
                &format!("{label} render"),
                args.quiet,
            );
            let r = generate(
                &spec,
                &dataset_dir,
                &GenerateOptions { every, force: true },
                &|done, _| pb.set_position(done as u64),
            );
            pb.finish_and_clear();
            r.map_err(anyhow::Error::from)
        });
        if let Err(e) = rendered {
            failures.push(format!("{}: {e:#}", spec_path.display()));
            continue;
        }
        for marker in &job.detectors {
            let detector = match DetectorSpec::by_name(marker, &args.python, &args.peers) {
                Ok(d) => d,
                Err(e) => {
                    failures.push(format!("{}: {e}", spec_path.display()));
                    continue;
                }
            };
            // A spec run by one detector keeps its old run name.
            let run_name = if job.detectors.len() == 1 && marker_of(spec_path) == *marker {
                stem.clone()
            } else {
                format!("{stem}@{marker}")
            };
            let result = Dataset::open(&dataset_dir)
                .map_err(anyhow::Error::from)
                .and_then(|ds| {
                    let pb = bar(
                        ds.images.len(),
                        &format!("{label} detect {marker}"),
                        args.quiet,
                    );
                    let sessions = if job.untimed || args.no_times {
                        workers
                    } else {
                        1
                    };
                    let out = runner::run_parallel(&detector, &ds, sessions, |d, _| {
                        pb.set_position(d as u64)
                    });
                    pb.finish_and_clear();
                    let out = out?;
                    let path = args.work.join("runs").join(format!("{run_name}.mcap"));
                    runlog::save(&path, &out)?;
                    Ok(path)
                });
            match result {
                Ok(path) => {
                    if job.wild {
                        wild_runs.push(path.clone());
                    }
                    runs.push(path);
                }
                Err(e) => failures.push(format!("{run_name}: {e:#}")),
            }
        }
        if !args.quiet {
            eprintln!("{label}: done");
        }
    }
    let rule = MatchRule::default();
    let (summaries, errors) = evaluate_all(&runs, None, rule);
    failures.extend(errors);
    let results = args.work.join("results");
    let wild = if wild_runs.is_empty() {
        None
    } else {
        let (loaded, errors) = load_all(&wild_runs, None);
        failures.extend(errors);
        let (w, errors) = evaluate_wild(&loaded, rule);
        failures.extend(errors);
        write_wild(&results, &w)?;
        Some(w)
    };
    if !summaries.is_empty() {
        write_summaries(&results, &summaries)?;
        let machine = Machine {
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            memory: resources::total_memory().unwrap_or(0),
        };
        let made_by = if args.quick {
            "make reproduce QUICK=1"
        } else {
            "make reproduce"
        };
        let md = write_report(
            &summaries,
            &args.reports,
            machine,
            &preamble(&summaries, made_by),
            wild.as_ref(),
        )?;
        write_atomic(&args.reports.join("README.md"), md.as_bytes())?;
        eprintln!(
            "wrote {} and {}",
            results.join("summary.json").display(),
            args.reports.join("README.md").display()
        );
    }
    if !failures.is_empty() {
        for f in &failures {
            eprintln!("error: {f}");
        }
        anyhow::bail!("{} step(s) failed; the rest was written", failures.len());
    }
    Ok(())
}

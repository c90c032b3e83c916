//! Running one detector over every image of a dataset.
//!
//! Ours runs in process (the `coppertag` library, single-threaded, timed
//! around `detect` alone). The peers run as subprocesses speaking the line
//! protocol of [`crate::protocol`]: one path written, one JSON line read, in
//! lock step, so that a hung or crashed peer is noticed on the image that
//! caused it. CPU time and peak memory come from `/proc` ([`crate::resources`]).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use image::GrayImage;
use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};
use crate::protocol::{DetectionRecord, ImageResult};
use crate::resources;
use crate::truth::Dataset;

/// Longest a detector may take on one image before it is declared hung.
const IMAGE_TIMEOUT: Duration = Duration::from_secs(120);

/// The detectors `coppertag run` knows by name.
pub const KNOWN: &[&str] = &["coppertag", "apriltag3", "aruco3", "stag", "fractal"];

/// How to reach a detector.
#[derive(Debug, Clone, PartialEq)]
pub enum DetectorSpec {
    /// The `coppertag` library, in this process.
    CopperTag(coppertag::detect::DetectorConfig),
    /// A program speaking the line protocol.
    Subprocess {
        /// Name used in reports.
        name: String,
        /// Program and arguments.
        command: Vec<String>,
    },
}

impl DetectorSpec {
    /// The detector called `name`: `coppertag`, or a peer adapter from
    /// `peers_dir` run with `python`.
    pub fn by_name(name: &str, python: &Path, peers_dir: &Path) -> Result<Self> {
        match name {
            "coppertag" => Ok(Self::CopperTag(coppertag::detect::DetectorConfig::default())),
            "apriltag3" | "aruco3" | "stag" | "fractal" => Ok(Self::Subprocess {
                name: name.into(),
                command: vec![
                    python.display().to_string(),
                    peers_dir.join(format!("{name}.py")).display().to_string(),
                ],
            }),
            _ => Err(EvalError::InvalidParameter {
                name: "detector",
                reason: format!("unknown detector '{name}' (known: {})", KNOWN.join(", ")),
            }),
        }
    }

    /// Name used in reports.
    pub fn name(&self) -> &str {
        match self {
            Self::CopperTag(_) => "coppertag",
            Self::Subprocess { name, .. } => name,
        }
    }
}

/// Facts about a run, logged as MCAP metadata.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunInfo {
    /// Detector name.
    pub detector: String,
    /// Detector version (ours: crate version; peers: `--version` output).
    pub version: String,
    /// Parameters (ours: the config as JSON; peers: the command line).
    pub parameters: String,
    /// Dataset name.
    pub dataset: String,
    /// Dataset directory as given.
    pub dataset_dir: String,
    /// Machine description.
    pub machine: String,
    /// Start of the run, seconds since the Unix epoch.
    pub started_unix_s: u64,
    /// `K/N` when the run covered only shard K of N of the dataset
    /// ([`crate::shard`]); empty for a whole run.
    #[serde(default)]
    pub shard: String,
    /// Detector sessions that ran at the same time, each on a shard of the
    /// images ([`run_parallel`]); 1 for a run made one image after another.
    /// Per-image times of a run with more than one are not comparable with
    /// the others (the sessions share the machine's cores, caches and
    /// memory bandwidth), so the report does not quote them.
    #[serde(default = "one_session")]
    pub sessions: usize,
}

fn one_session() -> usize {
    1
}

/// Whether a run of `sessions` detector sessions ([`RunInfo::sessions`])
/// is timed: its per-image times are quoted only when one session ran, as
/// sessions side by side (the robustness sets; every run of the gate's
/// quick run, `reproduce --no-times`) share the machine's cores and caches
/// and slow each other down.
pub fn timed(sessions: usize) -> bool {
    sessions == 1
}

/// Resource use of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct RunResources {
    /// Images processed.
    pub images: usize,
    /// Images the detector reported an error for.
    pub errors: usize,
    /// Wall time over the measured images, seconds.
    pub wall_s: f64,
    /// CPU time of the detector over the measured images, seconds.
    pub cpu_s: f64,
    /// Peak resident memory of the detector's process, bytes. For ours this
    /// is the whole evaluation process, an upper bound.
    pub peak_rss: u64,
}

impl RunResources {
    /// Adds the resources of another part of the same run (a shard run
    /// by another process): counts, CPU and wall seconds are summed (so
    /// CPU share stays total CPU over total wall time), and peak memory is
    /// the largest, the only meaningful merge of measurements made by
    /// separate processes.
    pub fn add(&mut self, other: &RunResources) {
        self.images += other.images;
        self.errors += other.errors;
        self.wall_s += other.wall_s;
        self.cpu_s += other.cpu_s;
        self.peak_rss = self.peak_rss.max(other.peak_rss);
    }
}

/// Result for one image, with its dataset index.
#[derive(Debug, Clone, PartialEq)]
pub struct IndexedResult {
    /// Image index in the dataset.
    pub index: usize,
    /// What the detector said.
    pub result: ImageResult,
}

/// A running detector.
pub(crate) trait Session {
    fn detect(&mut self, image: &str, path: &Path) -> Result<ImageResult>;
    /// Resource counters now.
    fn usage(&self) -> Option<resources::Usage>;
    fn version(&self) -> String;
    fn parameters(&self) -> String;
}

struct InProcess {
    detector: coppertag::detect::Detector,
    config: coppertag::detect::DetectorConfig,
}

fn load_gray(path: &Path) -> std::result::Result<GrayImage, String> {
    image::open(path)
        .map(|i| i.to_luma8())
        .map_err(|e| format!("cannot read image: {e}"))
}

impl Session for InProcess {
    fn detect(&mut self, image: &str, path: &Path) -> Result<ImageResult> {
        let img = match load_gray(path) {
            Ok(img) => img,
            Err(e) => {
                return Ok(ImageResult {
                    image: image.into(),
                    ms: None,
                    detections: vec![],
                    error: Some(e),
                })
            }
        };
        let t = Instant::now();
        let found = self.detector.detect(&img);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        Ok(ImageResult {
            image: image.into(),
            ms: Some(ms),
            detections: found
                .into_iter()
                .map(|d| DetectionRecord {
                    family: d.family.to_string(),
                    id: d.id,
                    corners: d.corners,
                    estimated: d.estimated,
                    corrected: Some(d.corrected as u64),
                    corner_sigma: d.corner_sigma,
                    likelihood: d.likelihood,
                })
                .collect(),
            error: None,
        })
    }
    fn usage(&self) -> Option<resources::Usage> {
        // The detector runs on this thread only: its CPU time is this
        // thread's; memory is the process's peak.
        Some(resources::Usage {
            cpu_s: resources::thread_cpu_s()?,
            peak_rss: resources::of_self()?.peak_rss,
        })
    }
    fn version(&self) -> String {
        format!("coppertag {}", env!("CARGO_PKG_VERSION"))
    }
    fn parameters(&self) -> String {
        serde_json::to_string(&self.config).unwrap_or_default()
    }
}

struct Subprocess {
    name: String,
    command: Vec<String>,
    child: Child,
    stdin: Option<ChildStdin>,
    lines: mpsc::Receiver<std::io::Result<String>>,
    version: String,
    stderr_path: PathBuf,
}

impl Subprocess {
    fn start(name: &str, command: &[String]) -> Result<Self> {
        let fail = |message: String| EvalError::Detector {
            detector: name.into(),
            message,
        };
        let (prog, args) = command
            .split_first()
            .ok_or_else(|| fail("empty command".into()))?;
        // The version first, in a short-lived process of its own.
        let version = Command::new(prog)
            .args(args)
            .arg("--version")
            .stdin(Stdio::null())
            .output()
            .map_err(|e| {
                fail(format!(
                    "cannot start {prog}: {e} (is the peer environment installed? run `make venv`)"
                ))
            })?;
        if !version.status.success() {
            return Err(fail(format!(
                "`{} --version` failed: {}",
                command.join(" "),
                String::from_utf8_lossy(&version.stderr).trim()
            )));
        }
        // Adapters print {"detector", "package", "version"}; keep
        // "package version", or the raw line from any other program.
        let raw = String::from_utf8_lossy(&version.stdout).trim().to_string();
        let version = serde_json::from_str::<serde_json::Value>(&raw)
            .ok()
            .and_then(|v| {
                Some(format!(
                    "{} {}",
                    v["package"].as_str()?,
                    v["version"].as_str()?
                ))
            })
            .unwrap_or(raw);
        let stderr_file = tempfile::NamedTempFile::new().map_err(|e| fail(e.to_string()))?;
        let (stderr_handle, stderr_path) = stderr_file.keep().map_err(|e| fail(e.to_string()))?;
        let mut child = Command::new(prog)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::from(stderr_handle))
            .spawn()
            .map_err(|e| fail(format!("cannot start {prog}: {e}")))?;
        let stdout = child.stdout.take().expect("stdout is piped");
        let stdin = child.stdin.take();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Ok(Self {
            name: name.into(),
            command: command.to_vec(),
            child,
            stdin,
            lines: rx,
            version,
            stderr_path,
        })
    }

    fn stderr_tail(&self) -> String {
        let text = std::fs::read_to_string(&self.stderr_path).unwrap_or_default();
        let tail: Vec<&str> = text.lines().rev().take(3).collect();
        tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
    }

    fn died(&mut self, what: &str) -> EvalError {
        let status = self
            .child
            .try_wait()
            .ok()
            .flatten()
            .map_or("still running".to_string(), |s| s.to_string());
        EvalError::Detector {
            detector: self.name.clone(),
            message: format!("{what} ({status}); stderr: {}", self.stderr_tail()),
        }
    }
}

impl Session for Subprocess {
    fn detect(&mut self, image: &str, path: &Path) -> Result<ImageResult> {
        let path_str = path.display().to_string();
        if path_str.contains('\n') {
            return Err(EvalError::InvalidParameter {
                name: "image path",
                reason: format!("{path_str:?} contains a newline"),
            });
        }
        let sent = match self.stdin.as_mut() {
            Some(w) => writeln!(w, "{path_str}").and_then(|()| w.flush()),
            None => Err(std::io::Error::other("stdin closed")),
        };
        if sent.is_err() {
            return Err(self.died("exited before reading an image"));
        }
        let line = match self.lines.recv_timeout(IMAGE_TIMEOUT) {
            Ok(Ok(line)) => line,
            Ok(Err(e)) => return Err(self.died(&format!("unreadable output: {e}"))),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                let _ = self.child.kill();
                return Err(self.died(&format!(
                    "no answer within {} s for {path_str}",
                    IMAGE_TIMEOUT.as_secs()
                )));
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                let _ = self.child.wait();
                return Err(self.died(&format!("exited while processing {path_str}")));
            }
        };
        let mut result = ImageResult::parse(&line).map_err(|e| EvalError::Detector {
            detector: self.name.clone(),
            message: format!("garbage on stdout for {path_str}: {e}: {:.120}", line),
        })?;
        if result.image != path_str {
            return Err(EvalError::Detector {
                detector: self.name.clone(),
                message: format!(
                    "answered for {:?} when asked for {path_str:?}",
                    result.image
                ),
            });
        }
        result.image = image.into();
        Ok(result)
    }
    fn usage(&self) -> Option<resources::Usage> {
        resources::of_pid(self.child.id())
    }
    fn version(&self) -> String {
        self.version.clone()
    }
    fn parameters(&self) -> String {
        self.command.join(" ")
    }
}

impl Drop for Subprocess {
    fn drop(&mut self) {
        // Closing stdin ends the adapter; give it a moment, then make sure.
        drop(self.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.stderr_path);
    }
}

/// Starts `spec`: builds our detector, or starts the peer's process.
pub(crate) fn start(spec: &DetectorSpec) -> Result<Box<dyn Session>> {
    Ok(match spec {
        DetectorSpec::CopperTag(config) => Box::new(InProcess {
            detector: coppertag::detect::Detector::new(config.clone()).map_err(|e| {
                EvalError::Detector {
                    detector: "coppertag".into(),
                    message: e.to_string(),
                }
            })?,
            config: config.clone(),
        }),
        DetectorSpec::Subprocess { name, command } => Box::new(Subprocess::start(name, command)?),
    })
}

/// The outcome of a run.
#[derive(Debug, Clone)]
pub struct RunOutput {
    /// Facts about the run.
    pub info: RunInfo,
    /// One result per image, in dataset order.
    pub results: Vec<IndexedResult>,
    /// Resource use.
    pub resources: RunResources,
}

/// Runs `spec` over the images of `dataset` in `shard` (all of them for
/// `None`) and records the shard in the run's facts.
pub fn run_shard(
    spec: &DetectorSpec,
    dataset: &Dataset,
    shard: Option<crate::shard::Shard>,
    progress: impl FnMut(usize, usize),
) -> Result<RunOutput> {
    let Some(shard) = shard else {
        return run(spec, dataset, progress);
    };
    let mut slice = dataset.clone();
    crate::shard::restrict(&mut slice, shard);
    let mut out = run(spec, &slice, progress)?;
    out.info.shard = shard.to_string();
    Ok(out)
}

/// Runs `spec` over every image of `dataset` with `workers` detector
/// sessions at once, session `k` on shard `k/workers`, and puts the parts
/// together as [`crate::shard::merge`] does for a cluster's shards: the
/// same per-image results in dataset order as [`run`] gives, resources
/// summed. Every session is single-threaded (ours runs on its own thread,
/// each peer in its own process pinned to one thread), so with `workers`
/// at most the number of cores each frame is still timed on a core of
/// its own. `progress(done, total)` counts images over all sessions.
pub fn run_parallel(
    spec: &DetectorSpec,
    dataset: &Dataset,
    workers: usize,
    progress: impl Fn(usize, usize) + Sync,
) -> Result<RunOutput> {
    let workers = workers.clamp(1, dataset.images.len().max(1));
    if workers == 1 {
        return run(spec, dataset, progress);
    }
    let total = dataset.images.len();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tick = || {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(d, total);
    };
    let parts: Vec<Result<RunOutput>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..workers)
            .map(|index| {
                let shard = crate::shard::Shard {
                    index,
                    count: workers,
                };
                let tick = &tick;
                scope.spawn(move || run_shard(spec, dataset, Some(shard), |_, _| tick()))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(EvalError::Detector {
                        detector: spec.name().into(),
                        message: "a detector session panicked".into(),
                    })
                })
            })
            .collect()
    });
    let mut parts = parts.into_iter().collect::<Result<Vec<_>>>()?;
    let mut whole = parts.remove(0);
    whole.info.shard = String::new();
    whole.info.sessions = workers;
    for p in &parts {
        whole.resources.add(&p.resources);
        whole.info.started_unix_s = whole.info.started_unix_s.min(p.info.started_unix_s);
    }
    whole
        .results
        .extend(parts.into_iter().flat_map(|p| p.results));
    whole.results.sort_by_key(|r| r.index);
    Ok(whole)
}

/// Runs `spec` over every image of `dataset`; `progress(done, total)` is
/// called after each image.
///
/// CPU time and wall time are measured from the first image's answer to the
/// last one's, so that interpreter start-up and library loading (which the
/// paper's per-frame figures exclude) are not billed to the detector.
pub fn run(
    spec: &DetectorSpec,
    dataset: &Dataset,
    mut progress: impl FnMut(usize, usize),
) -> Result<RunOutput> {
    let mut session = start(spec)?;
    let started_unix_s = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let total = dataset.images.len();
    let mut results = Vec::with_capacity(total);
    let mut first: Option<(Instant, resources::Usage)> = None;
    let mut errors = 0;
    for (done, (index, image)) in dataset.images.iter().enumerate() {
        let path = dataset.image_path(image);
        let result = session.detect(image, &path)?;
        if result.error.is_some() {
            errors += 1;
        }
        if first.is_none() {
            first = Some((Instant::now(), session.usage().unwrap_or_default()));
        }
        results.push(IndexedResult {
            index: *index,
            result,
        });
        progress(done + 1, total);
    }
    let end = session.usage().unwrap_or_default();
    let (t0, u0) = first.unwrap_or((Instant::now(), end));
    let resources = RunResources {
        images: total,
        errors,
        wall_s: t0.elapsed().as_secs_f64(),
        cpu_s: (end.cpu_s - u0.cpu_s).max(0.0),
        peak_rss: end.peak_rss,
    };
    Ok(RunOutput {
        info: RunInfo {
            detector: spec.name().into(),
            version: session.version(),
            parameters: session.parameters(),
            dataset: dataset.name.clone(),
            dataset_dir: dataset.dir.display().to_string(),
            machine: resources::machine(),
            started_unix_s,
            shard: String::new(),
            sessions: 1,
        },
        results,
        resources,
    })
}

//! Writing a dataset directory from a spec.
//!
//! Layout (all files deterministic: same spec and seed, same bytes):
//!
//! ```text
//! <out>/images/000000.png ...  8-bit grey PNGs, named by image index
//! <out>/truth.csv              one row per marker per image (columns below)
//! <out>/draws.csv              sampled specs only: every drawn factor per image and marker
//! <out>/dataset.json           camera, conventions, the resolved spec and its text
//! <out>/dataset.mcap           the same images with calibration, truth, overlays
//! ```
//!
//! The directory is built next to its destination under a hidden temporary
//! name and renamed into place at the end; on any error the temporary
//! directory is removed and no partial dataset is left. Images render in
//! parallel (rayon) in chunks; files and MCAP messages are written in image
//! order.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rayon::prelude::*;
use serde_json::json;

use crate::camera::Camera;
use crate::coverage::Rasterizer;
use crate::error::{Result, SynthError};
use crate::foxglove::McapWriter;
use crate::scene::MarkerTruth;
use crate::spec::{DatasetSpec, Draw};

/// Columns of `draws.csv` (sampled specs; documented in
/// `datasets/README.md`).
pub const DRAWS_COLUMNS: &[&str] = &["index", "marker_index", "factor", "value"];

/// Columns of `truth.csv`, in order (documented in `datasets/README.md`).
pub const TRUTH_COLUMNS: &[&str] = &[
    "image",
    "index",
    "marker_index",
    "marker",
    "family",
    "id",
    "size_m",
    "square_m",
    "x0",
    "y0",
    "x1",
    "y1",
    "x2",
    "y2",
    "x3",
    "y3",
    "corner_visible0",
    "corner_visible1",
    "corner_visible2",
    "corner_visible3",
    "corner_in_image0",
    "corner_in_image1",
    "corner_in_image2",
    "corner_in_image3",
    "rvec_x",
    "rvec_y",
    "rvec_z",
    "qw",
    "qx",
    "qy",
    "qz",
    "tx",
    "ty",
    "tz",
    "side_px",
    "param",
    "value",
    "value_deg",
    "occlusion_pattern",
    "occlusion_scenario",
    "occlusion_coverage",
    "occluder_fractions",
    "level_corners",
];

/// Version of the dataset layout, in `dataset.json`.
pub const FORMAT_VERSION: u32 = 1;

/// A deterministic slice of a dataset: the images whose index is `k`
/// modulo `n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard, `0..n`.
    pub k: usize,
    /// Number of shards.
    pub n: usize,
}

impl Shard {
    /// Parses `K/N` (`0 <= K < N`).
    pub fn parse(s: &str) -> std::result::Result<Self, String> {
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| format!("'{s}' is not K/N"))?;
        let k: usize = k
            .trim()
            .parse()
            .map_err(|_| format!("'{s}': K is not a whole number"))?;
        let n: usize = n
            .trim()
            .parse()
            .map_err(|_| format!("'{s}': N is not a whole number"))?;
        if n == 0 || k >= n {
            return Err(format!("'{s}': need 0 <= K < N"));
        }
        Ok(Self { k, n })
    }

    /// Whether image `index` belongs to the shard.
    #[must_use]
    pub fn contains(self, index: usize) -> bool {
        index % self.n == self.k
    }
}

/// Options of [`generate`].
#[derive(Debug, Clone)]
pub struct GenerateOptions {
    /// Render only one in this many images (1 = all): of a sweep, those
    /// whose index is a multiple of it; of a sampled spec, the first scenes
    /// with all their renders ([`DatasetSpec::thinned_indices`] says why).
    pub every: usize,
    /// Replace an existing output directory.
    pub force: bool,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        Self {
            every: 1,
            force: false,
        }
    }
}

/// Time spent per stage, summed over images (CPU time on the worker
/// threads for the first three).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimes {
    /// Building the scene and rendering it (rasterising, effects, noise).
    pub render: Duration,
    /// PNG encoding.
    pub png: Duration,
    /// Writing PNG files.
    pub write_png: Duration,
    /// MCAP messages (JSON, base64, zstd) on the writer thread.
    pub mcap: Duration,
    /// `truth.csv` rows on the writer thread.
    pub csv: Duration,
}

/// What [`generate`] did.
#[derive(Debug, Clone)]
pub struct GenerateReport {
    /// The dataset directory.
    pub dir: PathBuf,
    /// Images written.
    pub images: usize,
    /// Wall time from start to the final rename.
    pub wall: Duration,
    /// Per-stage times.
    pub stages: StageTimes,
    /// Total size of the PNG files in bytes.
    pub png_bytes: u64,
    /// Size of `dataset.mcap` in bytes.
    pub mcap_bytes: u64,
}

impl GenerateReport {
    /// Images per second of wall time.
    #[must_use]
    pub fn images_per_second(&self) -> f64 {
        self.images as f64 / self.wall.as_secs_f64().max(1e-9)
    }
}

/// The file name of image `index`, relative to the dataset directory.
#[must_use]
pub fn image_name(index: usize) -> String {
    format!("images/{index:06}.png")
}

/// Encodes an 8-bit grey image as PNG (fdeflate "fast" compression: the
/// same bytes every time).
pub fn encode_png(img: &image::GrayImage) -> Result<Vec<u8>> {
    let mut buf = Vec::with_capacity(img.as_raw().len() / 4);
    let err = |e: png::EncodingError| SynthError::Image {
        path: "(PNG encoding)".into(),
        message: e.to_string(),
    };
    {
        let mut enc = png::Encoder::new(&mut buf, img.width(), img.height());
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::Fast);
        let mut w = enc.write_header().map_err(err)?;
        w.write_image_data(img.as_raw()).map_err(err)?;
        w.finish().map_err(err)?;
    }
    Ok(buf)
}

struct Rendered {
    index: usize,
    png: Vec<u8>,
    markers: Vec<MarkerTruth>,
    draws: Vec<Draw>,
    /// The image's camera (sampled specs may draw its distortion).
    camera: Camera,
    times: [Duration; 3],
}

fn render_one(
    spec: &DatasetSpec,
    index: usize,
    raster: &mut Rasterizer,
    dir: &Path,
) -> Result<Rendered> {
    let t0 = Instant::now();
    let (scene, draws) = match spec.sampled_scene(index) {
        Some(sampled) => {
            let s = sampled?;
            (s.scene, s.draws)
        }
        None => (spec.scene(index)?, Vec::new()),
    };
    let out = scene.render(raster)?;
    let camera = scene.rendering.camera;
    let t1 = Instant::now();
    let png = encode_png(&out.image)?;
    let t2 = Instant::now();
    let path = dir.join(image_name(index));
    std::fs::write(&path, &png).map_err(|e| SynthError::io(&path, e))?;
    let t3 = Instant::now();
    Ok(Rendered {
        index,
        png,
        markers: out.markers,
        draws,
        camera,
        times: [t1 - t0, t2 - t1, t3 - t2],
    })
}

fn b(v: bool) -> &'static str {
    if v {
        "1"
    } else {
        "0"
    }
}

fn truth_rows(
    csv: &mut csv::Writer<BufWriter<File>>,
    spec: &DatasetSpec,
    index: usize,
    markers: &[MarkerTruth],
) -> Result<()> {
    let frame = spec.frame(index);
    let param = spec.sweep.as_ref().map(|s| s.param);
    for m in markers {
        let mut row: Vec<String> = vec![
            image_name(index),
            index.to_string(),
            m.index.to_string(),
            m.marker.to_string(),
            m.family.clone(),
            m.id.to_string(),
            m.size_m.to_string(),
            m.square_m.to_string(),
        ];
        for c in &m.corners {
            row.push(c[0].to_string());
            row.push(c[1].to_string());
        }
        row.extend(m.corner_visible.iter().map(|&v| b(v).to_string()));
        row.extend(m.corner_in_image.iter().map(|&v| b(v).to_string()));
        row.extend(m.rvec.iter().map(f64::to_string));
        row.extend(m.quaternion.iter().map(f64::to_string));
        row.extend(m.tvec.iter().map(f64::to_string));
        row.push(m.side_px.to_string());
        match (param, frame.value) {
            (Some(p), Some(v)) => {
                row.push(p.name().to_string());
                row.push(v.to_string());
                row.push(if p.is_angle() {
                    v.to_degrees().to_string()
                } else {
                    String::new()
                });
            }
            _ => row.extend([String::new(), String::new(), String::new()]),
        }
        match &m.occlusion {
            Some(o) => {
                row.push(o.name.clone());
                row.push(o.scenario.name().to_string());
                row.push(o.coverage.to_string());
                row.push(
                    o.occluder_fractions
                        .iter()
                        .map(f64::to_string)
                        .collect::<Vec<_>>()
                        .join(";"),
                );
            }
            None => row.extend([String::new(), String::new(), "0".to_string(), String::new()]),
        }
        row.push(
            m.levels
                .iter()
                .map(|(id, c)| {
                    let xy: Vec<String> = c.iter().flatten().map(f64::to_string).collect();
                    format!("{id}:{}", xy.join(" "))
                })
                .collect::<Vec<_>>()
                .join(";"),
        );
        debug_assert_eq!(row.len(), TRUTH_COLUMNS.len());
        csv.write_record(&row)?;
    }
    Ok(())
}

/// `draws.csv` rows of image `index`.
fn draw_rows(csv: &mut csv::Writer<BufWriter<File>>, index: usize, draws: &[Draw]) -> Result<()> {
    for d in draws {
        csv.write_record([
            index.to_string(),
            d.marker.map(|m| m.to_string()).unwrap_or_default(),
            d.factor.to_string(),
            d.value.to_string(),
        ])?;
    }
    Ok(())
}

/// `dataset.json`.
fn dataset_json(
    spec: &DatasetSpec,
    images: usize,
    every: usize,
    shard: Option<Shard>,
) -> serde_json::Value {
    let spec_file = spec
        .path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut v = json!({
        "format": "coppertag-synth-dataset",
        "format_version": FORMAT_VERSION,
        "generator": format!("coppertag-synth {}", env!("CARGO_PKG_VERSION")),
        "name": spec.name,
        "description": spec.description,
        "seed": spec.seed,
        "images": images,
        "images_in_spec": spec.image_count(),
        "every": every,
        "spec_file": spec_file,
        "files": {"images": "images/", "truth": "truth.csv", "mcap": "dataset.mcap"},
        "truth_columns": TRUTH_COLUMNS,
        "conventions": {
            "image": "pixel-centre coordinates: the centre of the top-left pixel is (0, 0), x right, y down",
            "camera_frame": "OpenCV: x right, y down, z forward; metres",
            "marker_frame": "origin at the marker-square centre, x right and y down in the upright marker, z into the marker; X_camera = R(rvec) X_marker + tvec",
            "corners": "TL, BL, BR, TR of the marker square: CopperTag data square, peers' outer black square",
            "marker_square_unit": "occluder coordinates: (0,0) = TL corner, (1,1) = BR corner of the marker square",
            "coverage": "area of the union of the occluders inside the marker square / area of the marker square, exact",
            "distortion": "OpenCV plumb_bob [k1, k2, p1, p2, k3]",
            "units": "metres and radians (value_deg in truth.csv for convenience)",
            "mcap_log_time_ns": "1e9 + index * 1e8"
        },
        "camera": spec.rendering.camera,
        "spec": spec.to_json(),
        "spec_toml": spec.text,
    });
    // Keys only sampled or sharded datasets have, so that older datasets
    // keep their bytes.
    if let Some(obj) = v.as_object_mut() {
        if spec.sample.is_some() {
            if let Some(files) = obj.get_mut("files").and_then(|f| f.as_object_mut()) {
                files.insert("draws".into(), json!("draws.csv"));
            }
            obj.insert("draws_columns".into(), json!(DRAWS_COLUMNS));
        }
        if let Some(sh) = shard {
            obj.insert(
                "shard".into(),
                json!({"k": sh.k, "n": sh.n, "rule": "images whose index % n == k"}),
            );
        }
    }
    v
}

/// Renders the dataset of `spec` into the directory `out`.
///
/// `progress(done, total)` is called after each image is written.
pub fn generate(
    spec: &DatasetSpec,
    out: &Path,
    opts: &GenerateOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<GenerateReport> {
    generate_shard(spec, out, opts, None, progress)
}

/// Renders one shard of the dataset of `spec` (all of it for `None`) into
/// the directory `out`: the shard's images are byte for byte those of the
/// whole dataset, and its `truth.csv`, `draws.csv` and `dataset.mcap` hold
/// only its images.
pub fn generate_shard(
    spec: &DatasetSpec,
    out: &Path,
    opts: &GenerateOptions,
    shard: Option<Shard>,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<GenerateReport> {
    let start = Instant::now();
    let every = opts.every.max(1);
    let indices: Vec<usize> = spec
        .thinned_indices(every)
        .into_iter()
        .filter(|&i| shard.is_none_or(|sh| sh.contains(i)))
        .collect();
    if out.exists() && !opts.force {
        return Err(SynthError::OutputExists {
            path: out.to_path_buf(),
        });
    }
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    std::fs::create_dir_all(&parent).map_err(|e| SynthError::io(&parent, e))?;
    let base = out
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "dataset".into());
    let tmp = tempfile::Builder::new()
        .prefix(&format!(".{base}.partial-"))
        .tempdir_in(&parent)
        .map_err(|e| SynthError::io(&parent, e))?;
    let dir = tmp.path().to_path_buf();
    let images_dir = dir.join("images");
    std::fs::create_dir(&images_dir).map_err(|e| SynthError::io(&images_dir, e))?;

    let truth_path = dir.join("truth.csv");
    let mut csv = csv::Writer::from_writer(BufWriter::new(
        File::create(&truth_path).map_err(|e| SynthError::io(&truth_path, e))?,
    ));
    csv.write_record(TRUTH_COLUMNS)?;
    let draws_path = dir.join("draws.csv");
    let mut draws_csv = match spec.sample {
        Some(_) => {
            let mut w = csv::Writer::from_writer(BufWriter::new(
                File::create(&draws_path).map_err(|e| SynthError::io(&draws_path, e))?,
            ));
            w.write_record(DRAWS_COLUMNS)?;
            Some(w)
        }
        None => None,
    };
    let meta = dataset_json(spec, indices.len(), every, shard);
    let mcap_path = dir.join("dataset.mcap");
    let spec_name = spec.path.file_name().map_or_else(
        || "spec.toml".to_string(),
        |s| s.to_string_lossy().into_owned(),
    );
    let mut mcap = McapWriter::new(
        BufWriter::new(File::create(&mcap_path).map_err(|e| SynthError::io(&mcap_path, e))?),
        &meta,
        &spec_name,
        &spec.text,
    )?;

    // Workers render chunks of images in parallel; a writer thread appends
    // them to truth.csv and the MCAP file in image order while the next
    // chunk renders.
    let mut stages = StageTimes::default();
    let mut png_bytes = 0u64;
    let chunk = (rayon::current_num_threads() * 4).max(4);
    let total = indices.len();
    let mut render_error = None;
    let written = std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<Rendered>(chunk * 2);
        let (truth_path, mcap_path, draws_path) = (&truth_path, &mcap_path, &draws_path);
        let writer = scope.spawn(move || -> Result<_> {
            let (mut t_csv, mut t_mcap) = (Duration::ZERO, Duration::ZERO);
            for (done, r) in rx.into_iter().enumerate() {
                let t0 = Instant::now();
                truth_rows(&mut csv, spec, r.index, &r.markers)?;
                if let Some(w) = draws_csv.as_mut() {
                    draw_rows(w, r.index, &r.draws)?;
                }
                let t1 = Instant::now();
                let sweep = spec
                    .sweep
                    .as_ref()
                    .zip(spec.frame(r.index).value)
                    .map(|(s, v)| (s.param.name(), v));
                mcap.write_image(
                    r.index,
                    &image_name(r.index),
                    &r.png,
                    &r.camera,
                    sweep,
                    &r.markers,
                )?;
                t_csv += t1 - t0;
                t_mcap += t1.elapsed();
                progress(done + 1, total);
            }
            let t0 = Instant::now();
            csv.flush().map_err(|e| SynthError::io(truth_path, e))?;
            drop(csv);
            if let Some(mut w) = draws_csv {
                w.flush().map_err(|e| SynthError::io(draws_path, e))?;
            }
            let mut mcap_file = mcap.finish()?;
            mcap_file
                .flush()
                .map_err(|e| SynthError::io(mcap_path, e))?;
            Ok((t_csv, t_mcap + t0.elapsed()))
        });
        'chunks: for part in indices.chunks(chunk) {
            let results = part
                .par_iter()
                .map_init(Rasterizer::new, |r, &i| render_one(spec, i, r, &dir))
                .collect::<Result<Vec<_>>>();
            match results {
                Ok(results) => {
                    for r in results {
                        stages.render += r.times[0];
                        stages.png += r.times[1];
                        stages.write_png += r.times[2];
                        png_bytes += r.png.len() as u64;
                        if tx.send(r).is_err() {
                            // The writer stopped: its error is reported below.
                            break 'chunks;
                        }
                    }
                }
                Err(e) => {
                    render_error = Some(e);
                    break;
                }
            }
        }
        drop(tx);
        writer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    });
    if let Some(e) = render_error {
        return Err(e);
    }
    let (t_csv, t_mcap) = written?;
    stages.csv = t_csv;
    stages.mcap = t_mcap;
    let json_path = dir.join("dataset.json");
    let mut text = serde_json::to_string_pretty(&meta)?;
    text.push('\n');
    std::fs::write(&json_path, text).map_err(|e| SynthError::io(&json_path, e))?;
    let mcap_bytes = std::fs::metadata(&mcap_path).map(|m| m.len()).unwrap_or(0);

    // Into place: the temporary directory becomes `out`; an old `out`
    // (with --force) is moved aside first and removed after.
    // Temporary directories are created private (0700); a dataset is an
    // ordinary directory.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755))
            .map_err(|e| SynthError::io(&dir, e))?;
    }
    let kept = tmp.keep();
    let old = if out.exists() {
        let aside = tempfile::Builder::new()
            .prefix(&format!(".{base}.old-"))
            .tempdir_in(&parent)
            .map_err(|e| SynthError::io(&parent, e))?
            .keep();
        std::fs::remove_dir(&aside).map_err(|e| SynthError::io(&aside, e))?;
        std::fs::rename(out, &aside).map_err(|e| SynthError::io(out, e))?;
        Some(aside)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&kept, out) {
        let _ = std::fs::remove_dir_all(&kept);
        if let Some(old) = &old {
            let _ = std::fs::rename(old, out);
        }
        return Err(SynthError::io(out, e));
    }
    if let Some(old) = old {
        std::fs::remove_dir_all(&old).map_err(|e| SynthError::io(&old, e))?;
    }
    Ok(GenerateReport {
        dir: out.to_path_buf(),
        images: total,
        wall: start.elapsed(),
        stages,
        png_bytes,
        mcap_bytes,
    })
}

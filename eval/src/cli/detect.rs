//! `coppertag detect`: find CopperTags in image files.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use coppertag::pose::{tag_pose, Intrinsics, TagPose};
use coppertag::{Detection, Detector, DetectorConfig};
use image::{GrayImage, Rgb, RgbImage};
use serde::Serialize;

use coppertag_eval::atomic::write_atomic_with;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag detect photo.png\n  \
    coppertag detect frames/*.png --family ct14 --json\n  \
    coppertag detect photo.png --draw annotated.png\n  \
    coppertag detect a.png b.png --draw 'out/{name}-tags.png'\n  \
    coppertag detect photo.png --json --fx 2730 --fy 2730 --cx 959.5 --cy 539.5 --tag-size 0.05\n  \
    coppertag detect --mcap robot.mcap -o tags.mcap\n  \
    coppertag detect --mcap robot.mcap --topic /cam/image_raw --tag-size 0.05 -o tags.mcap\n\n\
    With --mcap, -o gets /coppertag/detections, /coppertag/annotations and (with poses)\n\
    /coppertag/tf on the recording's timestamps: open it together with the recording in\n\
    Foxglove (README.md, \"Detect tags in a ROS 2 recording\").")]
pub struct DetectArgs {
    /// Image files (PNG or JPEG; colour images are converted to grey).
    #[arg(required_unless_present = "mcap", conflicts_with = "mcap")]
    pub(super) images: Vec<PathBuf>,

    /// Read a recording instead of image files: a rosbag2 MCAP file
    /// (sensor_msgs/msg/Image in mono8, mono16, rgb8, bgr8, rgba8, bgra8 or
    /// 8-bit Bayer, or sensor_msgs/msg/CompressedImage in JPEG or PNG; CDR) or a
    /// dataset.mcap written by `coppertag synth`. Needs -o.
    #[arg(long, value_name = "IN.mcap", requires = "output")]
    pub(super) mcap: Option<PathBuf>,

    /// The image topic to read (default: the recording's only image topic;
    /// with several, the command lists them and stops).
    #[arg(long, requires = "mcap")]
    pub(super) topic: Option<String>,

    /// The MCAP file to write (with --mcap); written whole or not at all.
    #[arg(short, long, value_name = "OUT.mcap", requires = "mcap")]
    pub(super) output: Option<PathBuf>,

    /// Camera calibration to use instead of the recording's CameraInfo (by
    /// default the sensor_msgs/msg/CameraInfo topic beside the image topic,
    /// e.g. /cam/camera_info for /cam/image_raw): OpenCV or ROS
    /// camera_calibration YAML (image_width, image_height, camera_matrix,
    /// distortion_coefficients) or a foxglove.CameraCalibration JSON file.
    /// Only plumb_bob distortion.
    #[arg(long, value_name = "FILE", requires = "mcap")]
    pub(super) camera: Option<PathBuf>,

    /// Keep the frames before the damage of a truncated or damaged
    /// recording (a recorder killed mid-write) instead of refusing it.
    #[arg(long, requires = "mcap")]
    pub(super) allow_truncated: bool,

    /// Threads. With --mcap: frames detected in parallel, one per thread
    /// (default: one per core). For images: the threads one image is
    /// detected on (default 1; the detector's `threads` setting, stages
    /// split across them; with 1, the next image is decoded on a second
    /// thread meanwhile). The output is the same for any number.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=256))]
    pub(super) threads: Option<u64>,

    /// With --threads over 1 for images: leave the detector's threads to
    /// the system instead of pinning each to a core of its own (the
    /// detector's `pin_threads` setting, on by default). Pinned is faster
    /// and steadier when the machine is otherwise idle; unpinned can be
    /// better when other busy programs share the cores.
    #[arg(long, requires = "threads", conflicts_with = "mcap")]
    pub(super) unpinned: bool,

    /// No progress bar (with --mcap).
    #[arg(long, short, requires = "mcap")]
    pub(super) quiet: bool,

    /// Families to look for, comma separated.
    #[arg(long, default_value = "ct14,ct8", value_delimiter = ',')]
    pub(super) family: Vec<String>,

    /// Print one JSON line per image instead of text (with --mcap: one
    /// summary line).
    #[arg(long)]
    pub(super) json: bool,

    /// Write each image with the detections drawn over it (corners, edges,
    /// ids; estimated corners hollow). With several images the path must
    /// contain '{name}', replaced by each image's file stem.
    #[arg(long, value_name = "OUT", conflicts_with = "mcap")]
    pub(super) draw: Option<PathBuf>,

    /// Downsampling before the quad search: 1 or 2 (default 2: small tags
    /// are looked at again at full resolution, see --no-small-tags; 1
    /// searches the whole frame at full resolution).
    #[arg(long, default_value_t = 2)]
    pub(super) downsample: u32,

    /// Report only four-corner tags (no recovery of hidden corners).
    #[arg(long)]
    pub(super) no_occlusion: bool,

    /// No second, full-resolution look around disc rims too small to read
    /// on the downsampled image (faster on frames with much small round
    /// clutter; loses data squares under about 40 px).
    #[arg(long)]
    pub(super) no_small_tags: bool,

    /// With --json: add each image's stage times (ms) and counts (borders,
    /// lines, corners, rims, candidates, decodes, small-tag regions,
    /// decodes of the rim look).
    #[arg(long, requires = "json")]
    pub(super) stats: bool,

    /// Focal length x in pixels (pose needs --fx --fy --cx --cy --tag-size).
    #[arg(long, requires_all = ["fy", "cx", "cy", "tag_size"], conflicts_with = "mcap")]
    pub(super) fx: Option<f64>,
    /// Focal length y in pixels.
    #[arg(long, requires = "fx")]
    pub(super) fy: Option<f64>,
    /// Principal point x (pixel-centre coordinates).
    #[arg(long, requires = "fx")]
    pub(super) cx: Option<f64>,
    /// Principal point y.
    #[arg(long, requires = "fx")]
    pub(super) cy: Option<f64>,
    /// Side of the white data square in metres (half the printed tag
    /// size). With images it needs --fx --fy --cx --cy; with --mcap, the
    /// recording's CameraInfo or --camera.
    #[arg(long, value_parser = positive_metres)]
    pub(super) tag_size: Option<f64>,

    /// Sides of particular tags' data squares with --mcap, as
    /// FAMILY:ID=METRES, comma separated (e.g. ct14:42=0.08,ct8:7=0.03);
    /// they win over --tag-size, and without --tag-size only these tags
    /// get a pose.
    #[arg(long, value_delimiter = ',', value_parser = parse_tag_size, requires = "mcap")]
    pub(super) tag_sizes: Vec<TagSize>,
}

#[derive(Serialize)]
struct JsonDetection<'a> {
    family: &'a str,
    id: u64,
    corners: [[f64; 2]; 4],
    estimated: [bool; 4],
    /// One-sigma corner uncertainty (px), null when the tag was not fitted.
    corner_sigma: Option<[f64; 4]>,
    corrected: usize,
    /// Read by likelihood (a blurred tag matched against every codeword);
    /// `corrected` then counts the symbols a cell-by-cell reading missed.
    likelihood: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pose: Option<TagPose>,
}

#[derive(Serialize)]
struct JsonImage<'a> {
    image: &'a str,
    ms: f64,
    detections: Vec<JsonDetection<'a>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    stats: Option<serde_json::Value>,
}

/// One `--tag-sizes` entry.
#[derive(Debug, Clone)]
pub(super) struct TagSize {
    pub(super) family: String,
    pub(super) id: u64,
    pub(super) metres: f64,
}

fn parse_tag_size(s: &str) -> std::result::Result<TagSize, String> {
    let bad = || format!("'{s}' is not FAMILY:ID=METRES (e.g. ct14:42=0.05)");
    let (tag, size) = s.split_once('=').ok_or_else(bad)?;
    let (family, id) = tag.split_once(':').ok_or_else(bad)?;
    let id: u64 = id.trim().parse().map_err(|_| bad())?;
    if family.trim().is_empty() {
        return Err(bad());
    }
    Ok(TagSize {
        family: family.trim().to_string(),
        id,
        metres: positive_metres(size.trim())?,
    })
}

fn positive_metres(s: &str) -> std::result::Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{s} must be a positive number of metres"))
    }
}

/// Runs the subcommand. Every image is processed; unreadable ones are
/// reported on stderr and make the command fail at the end.
pub fn run(args: &DetectArgs) -> Result<()> {
    let config = DetectorConfig {
        downsample: args.downsample,
        recover_occluded: !args.no_occlusion,
        small_tags: !args.no_small_tags,
        // With --mcap the threads are frames in parallel, each frame on one.
        threads: match (&args.mcap, args.threads) {
            (None, Some(t)) => usize::try_from(t).context("--threads is too large")?,
            _ => 1,
        },
        pin_threads: !args.unpinned,
        ..DetectorConfig::with_builtin_families(&args.family).context("--family")?
    };
    if let Some(input) = &args.mcap {
        return super::detect_bag::run(args, input, config);
    }
    if args.tag_size.is_some() && args.fx.is_none() {
        bail!("--tag-size needs --fx --fy --cx --cy for images (with --mcap, the recording's CameraInfo)");
    }
    let mut detector = Detector::new(config).context("invalid detector settings")?;
    if let Some(out) = &args.draw {
        if args.images.len() > 1 && !out.to_string_lossy().contains("{name}") {
            bail!(
                "--draw {}: with several images the path must contain '{{name}}'",
                out.display()
            );
        }
    }
    let intrinsics = match (args.fx, args.fy, args.cx, args.cy) {
        (Some(fx), Some(fy), Some(cx), Some(cy)) => Some(Intrinsics { fx, fy, cx, cy }),
        _ => None,
    };
    let mut failed: Vec<String> = Vec::new();
    // Images are read ahead only for a one-thread detector: a detector on
    // several threads has the cores busy, and a decoding thread beside it
    // slows every frame (on the 2-core machine, 4K frames on two threads
    // took 54 ms each instead of 30).
    let ahead = detector.config().threads == 1;
    let finished = std::thread::scope(|scope| {
        let images: Box<dyn Iterator<Item = Result<GrayImage>>> = if ahead {
            Box::new(read_ahead(scope, &args.images))
        } else {
            Box::new(args.images.iter().map(|p| read_gray(p)))
        };
        for (path, img) in args.images.iter().zip(images) {
            let done =
                img.and_then(|img| one_image(args, &mut detector, path, &img, intrinsics.as_ref()));
            if let Err(e) = done {
                // The reader of our output went away (`coppertag detect
                // ... | head`): nobody is left to tell, so stop quietly, as
                // Unix tools do, instead of panicking in `println!` or going
                // on. (Leaving the scope drops the receiver, which stops the
                // reading thread at its next image.)
                if is_broken_pipe(&e) {
                    return false;
                }
                eprintln!("error: {e:#}");
                failed.push(path.display().to_string());
            }
        }
        true
    });
    if !finished {
        return Ok(());
    }
    if !failed.is_empty() {
        bail!(
            "{} of {} images failed: {}",
            failed.len(),
            args.images.len(),
            failed.join(", ")
        );
    }
    Ok(())
}

/// Whether `e` comes from writing to a pipe whose reader has closed it.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain()
        .filter_map(|c| c.downcast_ref::<io::Error>())
        .any(|io| io.kind() == io::ErrorKind::BrokenPipe)
}

/// `--stats`: the detector's counts, and its stage times in ms.
fn stats_json(st: &coppertag::DetectionStats) -> serde_json::Value {
    let times: serde_json::Map<String, serde_json::Value> = st
        .times
        .iter()
        .map(|(name, d)| (name.to_string(), (d.as_secs_f64() * 1e3).into()))
        .collect();
    serde_json::json!({
        "times_ms": times,
        "contours": st.contours,
        "lines": st.lines,
        "corners": st.corners,
        "ellipses": st.ellipses,
        "candidates": st.candidates,
        "decode_attempts": st.decode_attempts,
        "small_regions": st.small_regions,
        "rim_decodes": st.rim_decodes,
    })
}

/// Images decoded ahead of the detector: at most this many wait, decoded,
/// for the detector to take them (and one more is being decoded), so
/// memory stays at a few frames however long the list is.
const READ_AHEAD: usize = 1;

/// The images at `paths`, in order, decoded to grey one after another on a
/// thread of their own (spawned in `scope`) while the detector works on
/// the one before. Decoding a PNG costs as much as detecting in it or more
/// (about half of the command's time on clean 1080p frames, by `perf`),
/// and with a second core the two overlap: on the 2-core machine,
/// `coppertag detect --json` on 80 1080p frames of the wild bench
/// (`benches/wild.rs`) went from 1.31 to 0.77 s (clean frames) and from
/// 2.6-3.2 to 2.0 s (cluttered ones), on 20 of its 4K frames from 1.94 to
/// 1.01 s, and on the wild set's 3000 VGA frames
/// (`datasets/wild/coppertag-wild.toml`) from 43 to 35 s, with the same
/// output and the same time per detection. An image that cannot be read
/// is an error in its place in the order. The thread stops when the list
/// ends or the receiver is dropped.
fn read_ahead<'scope>(
    scope: &'scope std::thread::Scope<'scope, '_>,
    paths: &'scope [PathBuf],
) -> std::sync::mpsc::IntoIter<Result<GrayImage>> {
    let (tx, rx) = std::sync::mpsc::sync_channel(READ_AHEAD);
    scope.spawn(move || {
        for path in paths {
            if tx.send(read_gray(path)).is_err() {
                break;
            }
        }
    });
    rx.into_iter()
}

/// The image at `path` in grey.
fn read_gray(path: &Path) -> Result<GrayImage> {
    Ok(image::open(path)
        .with_context(|| format!("cannot read image {}", path.display()))?
        .to_luma8())
}

fn one_image(
    args: &DetectArgs,
    detector: &mut Detector,
    path: &Path,
    img: &GrayImage,
    intrinsics: Option<&Intrinsics>,
) -> Result<()> {
    let t = Instant::now();
    let found = detector.detect(img);
    let ms = t.elapsed().as_secs_f64() * 1e3;
    let poses: Vec<Option<TagPose>> = found
        .iter()
        .map(|d| {
            let k = intrinsics?;
            tag_pose(&d.corners, k, args.tag_size?).ok()
        })
        .collect();
    let name = path.display().to_string();
    // Written with `writeln!`, not `println!`: a closed pipe is then an
    // error to stop on (see `run`), not a panic.
    let mut out = io::stdout().lock();
    if args.json {
        let line = JsonImage {
            image: &name,
            ms,
            detections: found
                .iter()
                .zip(&poses)
                .map(|(d, p)| JsonDetection {
                    family: &d.family,
                    id: d.id,
                    corners: d.corners,
                    estimated: d.estimated,
                    corner_sigma: d.corner_sigma,
                    corrected: d.corrected,
                    likelihood: d.likelihood,
                    pose: *p,
                })
                .collect(),
            stats: args.stats.then(|| stats_json(detector.stats())),
        };
        writeln!(out, "{}", serde_json::to_string(&line)?)?;
    } else {
        writeln!(out, "{name}: {} tag(s) in {ms:.2} ms", found.len())?;
        for (d, p) in found.iter().zip(&poses) {
            let corners: Vec<String> = d
                .corners
                .iter()
                .zip(d.estimated)
                .map(|(c, e)| format!("({:.2}, {:.2}){}", c[0], c[1], if e { "*" } else { "" }))
                .collect();
            writeln!(
                out,
                "  {} {}  corrected {}  corners {}",
                d.family,
                d.id,
                d.corrected,
                corners.join(" ")
            )?;
            if let Some(p) = p {
                let t = p.best.translation;
                writeln!(
                    out,
                    "    position [{:.4}, {:.4}, {:.4}] m, reprojection {:.3} px",
                    t[0], t[1], t[2], p.best.reprojection_px
                )?;
            }
        }
    }
    drop(out);
    if let Some(out) = &args.draw {
        let stem = path
            .file_stem()
            .map_or("image".into(), |s| s.to_string_lossy().into_owned());
        let out = PathBuf::from(out.to_string_lossy().replace("{name}", &stem));
        let canvas = draw(img, &found);
        let format = image::ImageFormat::from_path(&out).unwrap_or(image::ImageFormat::Png);
        write_atomic_with(&out, |w| {
            canvas.write_to(w, format).map_err(|e| e.to_string())
        })?;
    }
    Ok(())
}

/// The image in colour with the detections drawn over it.
fn draw(img: &GrayImage, found: &[Detection]) -> RgbImage {
    let mut c = RgbImage::from_fn(img.width(), img.height(), |x, y| {
        let v = img.get_pixel(x, y).0[0];
        Rgb([v, v, v])
    });
    let scale = f64::from(img.width().max(img.height())) / 1000.0;
    let thick = (1.5 * scale).max(1.0);
    for d in found {
        let side = (0..4)
            .map(|i| {
                let (a, b) = (d.corners[i], d.corners[(i + 1) % 4]);
                (a[0] - b[0]).hypot(a[1] - b[1])
            })
            .fold(0.0, f64::max);
        for i in 0..4 {
            let colour = if d.estimated[i] || d.estimated[(i + 1) % 4] {
                Rgb([255, 160, 0])
            } else {
                Rgb([0, 220, 0])
            };
            line(&mut c, d.corners[i], d.corners[(i + 1) % 4], thick, colour);
        }
        // Corner 0 (TL) red, the others blue; estimated corners hollow.
        for (i, p) in d.corners.iter().enumerate() {
            let colour = if i == 0 {
                Rgb([255, 0, 0])
            } else {
                Rgb([0, 90, 255])
            };
            disc(&mut c, *p, (0.04 * side).max(2.0), d.estimated[i], colour);
        }
        // The id, drawn with the tag's own digit strokes at the centre.
        let h = 0.25 * side;
        let (strokes, width) = coppertag::digits::text_strokes(d.id, 0.0, 0.0, 1.0);
        for s in strokes {
            for w in s.windows(2) {
                let m = |p: [f64; 2]| [d.center[0] + p[0] * h, d.center[1] + (p[1] + 0.5) * h];
                line(
                    &mut c,
                    m(w[0]),
                    m(w[1]),
                    (width * h / 2.0).max(1.0),
                    Rgb([255, 0, 255]),
                );
            }
        }
    }
    c
}

fn put(c: &mut RgbImage, x: f64, y: f64, colour: Rgb<u8>) {
    if x >= -0.5 && y >= -0.5 {
        let (xi, yi) = (x.round() as u32, y.round() as u32);
        if xi < c.width() && yi < c.height() {
            c.put_pixel(xi, yi, colour);
        }
    }
}

fn line(c: &mut RgbImage, a: [f64; 2], b: [f64; 2], thick: f64, colour: Rgb<u8>) {
    let len = (b[0] - a[0]).hypot(b[1] - a[1]);
    if !len.is_finite() || len > 1e5 {
        return;
    }
    let steps = (len * 2.0).ceil().max(1.0) as usize;
    let r = (thick / 2.0).max(0.5);
    for k in 0..=steps {
        let t = k as f64 / steps as f64;
        let (x, y) = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]));
        let ri = r.ceil() as i32;
        for dy in -ri..=ri {
            for dx in -ri..=ri {
                if f64::from(dx * dx + dy * dy) <= r * r + 0.25 {
                    put(c, x + f64::from(dx), y + f64::from(dy), colour);
                }
            }
        }
    }
}

fn disc(c: &mut RgbImage, p: [f64; 2], r: f64, hollow: bool, colour: Rgb<u8>) {
    if !r.is_finite() || r > 1e4 {
        return;
    }
    let ri = r.ceil() as i32;
    for dy in -ri..=ri {
        for dx in -ri..=ri {
            let d = f64::from(dx).hypot(f64::from(dy));
            if d <= r && (!hollow || d >= r - 1.5) {
                put(c, p[0] + f64::from(dx), p[1] + f64::from(dy), colour);
            }
        }
    }
}

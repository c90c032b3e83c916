//! Evaluation without ground truth, for recordings: what `coppertag eval
//! --recording` reports from the output of `coppertag detect --mcap`.
//!
//! Per tag: the frames it was seen in out of all frames, its Reed-Solomon
//! corrections, and, over a stretch the user names in which neither the
//! camera nor the tag moves, its jitter: the spread of each corner (px)
//! and of the pose (translation in mm, rotation in degrees), which with
//! nothing moving is the detector's own noise.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};
use crate::pose_error::angle_between;

/// A still stretch: seconds from the recording's first frame (log time).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Still {
    /// Start, seconds after the first frame.
    pub from_s: f64,
    /// End, seconds after the first frame (inclusive).
    pub to_s: f64,
}

/// Jitter of one tag over the still stretch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Jitter {
    /// Frames of the stretch the tag was seen in.
    pub frames: usize,
    /// Root mean square over the four corners of each corner's standard
    /// deviation (distance from its mean position), px.
    pub corner_px: f64,
    /// Standard deviation of the position (distance from the mean), mm;
    /// `None` without poses.
    pub translation_mm: Option<f64>,
    /// RMS angle from the mean rotation (chordal mean), degrees.
    pub rotation_deg: Option<f64>,
}

/// One tag over the recording.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TagStability {
    /// Family.
    pub family: String,
    /// Id.
    pub id: u64,
    /// Frames it was seen in (once per frame, however often detected).
    pub frames_seen: usize,
    /// Frames in the recording.
    pub frames: usize,
    /// Frames in which it was decoded with at least one correction.
    pub corrected_frames: usize,
    /// Mean symbols corrected over the frames it was seen in.
    pub corrected_mean: f64,
    /// Most symbols corrected in one frame.
    pub corrected_max: u64,
    /// Jitter over the still stretch, when one was given and the tag
    /// was seen in at least two of its frames.
    pub jitter: Option<Jitter>,
}

#[derive(Deserialize)]
struct Msg {
    detections: Vec<Det>,
}

#[derive(Deserialize)]
struct Det {
    family: String,
    id: u64,
    corners: [[f64; 2]; 4],
    #[serde(default)]
    corrected: Option<u64>,
    #[serde(default)]
    pose: Option<PoseJson>,
}

#[derive(Deserialize)]
struct PoseJson {
    best: BestJson,
}

#[derive(Deserialize)]
struct BestJson {
    rotation: [[f64; 3]; 3],
    translation: [f64; 3],
}

/// Spread of points around their mean: sqrt(mean squared distance).
fn spread(points: &[Vector3<f64>]) -> f64 {
    let n = points.len() as f64;
    let mean = points.iter().sum::<Vector3<f64>>() / n;
    (points
        .iter()
        .map(|p| (p - mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt()
}

/// The chordal L2 mean of rotations (the rotation nearest the sum of the
/// matrices; Hartley et al., "Rotation Averaging", IJCV 2013).
fn mean_rotation(rs: &[Matrix3<f64>]) -> Matrix3<f64> {
    let sum: Matrix3<f64> = rs.iter().sum();
    let svd = sum.svd(true, true);
    let (u, vt) = (svd.u.unwrap_or_default(), svd.v_t.unwrap_or_default());
    let d = (u * vt).determinant().signum();
    u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * vt
}

/// Reads an output of `coppertag detect --mcap` and reports every tag.
pub fn evaluate(path: &Path, still: Option<Still>) -> Result<Vec<TagStability>> {
    let bytes = std::fs::read(path).map_err(|e| EvalError::io(path, e))?;
    let bad = |m: String| EvalError::bad(path, m);
    let mut frames: Vec<(u64, Msg)> = Vec::new();
    for m in mcap::MessageStream::new(&bytes).map_err(|e| bad(format!("corrupt MCAP: {e}")))? {
        let m = m.map_err(|e| bad(format!("corrupt MCAP: {e}")))?;
        if m.channel.topic != super::output::DETECTIONS_TOPIC {
            continue;
        }
        let msg: Msg = serde_json::from_slice(&m.data)
            .map_err(|e| bad(format!("bad detections message {}: {e}", frames.len())))?;
        frames.push((m.log_time, msg));
    }
    if frames.is_empty() {
        return Err(bad(format!(
            "no {} messages: not an output of `coppertag detect --mcap`",
            super::output::DETECTIONS_TOPIC
        )));
    }
    let t0 = frames[0].0;
    let in_still = |t: u64| {
        still.is_some_and(|s| {
            let secs = (t - t0) as f64 / 1e9;
            secs >= s.from_s && secs <= s.to_s
        })
    };
    // Per tag: (frames seen, corrected per frame, still-stretch samples).
    type Samples = Vec<([[f64; 2]; 4], Option<(Matrix3<f64>, Vector3<f64>)>)>;
    let mut tags: BTreeMap<(String, u64), (usize, Vec<u64>, Samples)> = BTreeMap::new();
    for (t, msg) in &frames {
        let mut seen: BTreeMap<(String, u64), &Det> = BTreeMap::new();
        for d in &msg.detections {
            seen.entry((d.family.clone(), d.id)).or_insert(d);
        }
        for (key, d) in seen {
            let e = tags.entry(key).or_default();
            e.0 += 1;
            e.1.push(d.corrected.unwrap_or(0));
            if in_still(*t) {
                let pose = d.pose.as_ref().map(|p| {
                    (
                        Matrix3::from_fn(|i, j| p.best.rotation[i][j]),
                        Vector3::from(p.best.translation),
                    )
                });
                e.2.push((d.corners, pose));
            }
        }
    }
    Ok(tags
        .into_iter()
        .map(|((family, id), (seen, corrected, samples))| {
            let jitter = (samples.len() >= 2).then(|| {
                let corner_px = ((0..4)
                    .map(|c| {
                        let pts: Vec<Vector3<f64>> = samples
                            .iter()
                            .map(|(k, _)| Vector3::new(k[c][0], k[c][1], 0.0))
                            .collect();
                        spread(&pts).powi(2)
                    })
                    .sum::<f64>()
                    / 4.0)
                    .sqrt();
                let poses: Vec<_> = samples.iter().filter_map(|(_, p)| *p).collect();
                let (translation_mm, rotation_deg) = if poses.len() >= 2 {
                    let ts: Vec<_> = poses.iter().map(|(_, t)| *t).collect();
                    let rs: Vec<_> = poses.iter().map(|(r, _)| *r).collect();
                    let mean = mean_rotation(&rs);
                    let rms = (rs
                        .iter()
                        .map(|r| angle_between(r, &mean).powi(2))
                        .sum::<f64>()
                        / rs.len() as f64)
                        .sqrt();
                    (Some(spread(&ts) * 1e3), Some(rms.to_degrees()))
                } else {
                    (None, None)
                };
                Jitter {
                    frames: samples.len(),
                    corner_px,
                    translation_mm,
                    rotation_deg,
                }
            });
            TagStability {
                family,
                id,
                frames_seen: seen,
                frames: frames.len(),
                corrected_frames: corrected.iter().filter(|&&c| c > 0).count(),
                corrected_mean: corrected.iter().sum::<u64>() as f64 / seen.max(1) as f64,
                corrected_max: corrected.iter().copied().max().unwrap_or(0),
                jitter,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_and_mean_rotation() {
        let pts = [Vector3::new(1.0, 0.0, 0.0), Vector3::new(-1.0, 0.0, 0.0)];
        assert!((spread(&pts) - 1.0).abs() < 1e-12);
        let rz = |a: f64| *nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), a).matrix();
        let m = mean_rotation(&[rz(0.1), rz(0.3)]);
        assert!(angle_between(&m, &rz(0.2)) < 1e-9);
    }
}

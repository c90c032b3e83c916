//! Reading a dataset's ground truth (`truth.csv` and `dataset.json`, written
//! by `coppertag synth`; columns documented in `datasets/README.md`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::error::{EvalError, Result};

/// One marker in one image, as far as evaluation needs it.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TruthMarker {
    /// Image file, relative to the dataset directory.
    pub image: String,
    /// Image index in the full dataset (sets its MCAP log time).
    pub index: usize,
    /// The marker's index in the spec (`marker_index`; older datasets
    /// without the column read as 0).
    #[serde(default)]
    pub marker_index: usize,
    /// Marker system: coppertag, apriltag3, aruco3, stag, fractal.
    pub marker: String,
    /// Family or codebook name.
    pub family: String,
    /// Marker id.
    pub id: u64,
    /// Corner 0 (TL) x.
    pub x0: f64,
    /// Corner 0 (TL) y.
    pub y0: f64,
    /// Corner 1 (BL) x.
    pub x1: f64,
    /// Corner 1 (BL) y.
    pub y1: f64,
    /// Corner 2 (BR) x.
    pub x2: f64,
    /// Corner 2 (BR) y.
    pub y2: f64,
    /// Corner 3 (TR) x.
    pub x3: f64,
    /// Corner 3 (TR) y.
    pub y3: f64,
    /// Side of the marker square in pixels (mean of the four edges).
    pub side_px: f64,
    /// Side of the marker square, metres (the size a pose solver needs).
    #[serde(default)]
    pub square_m: Option<f64>,
    /// Rotation vector marker -> camera, radians, x.
    #[serde(default)]
    pub rvec_x: Option<f64>,
    /// Rotation vector y.
    #[serde(default)]
    pub rvec_y: Option<f64>,
    /// Rotation vector z.
    #[serde(default)]
    pub rvec_z: Option<f64>,
    /// Translation of the marker-square centre, metres, x.
    #[serde(default)]
    pub tx: Option<f64>,
    /// Translation y.
    #[serde(default)]
    pub ty: Option<f64>,
    /// Translation z.
    #[serde(default)]
    pub tz: Option<f64>,
    /// Swept parameter (`z`, `rx`, `ry`, `rz`, `pattern`...).
    #[serde(default)]
    pub param: String,
    /// Its value in metres or radians.
    #[serde(default)]
    pub value: Option<f64>,
    /// Angles in degrees, for plots.
    #[serde(default)]
    pub value_deg: Option<f64>,
    /// Occlusion pattern name, if any.
    #[serde(default)]
    pub occlusion_pattern: String,
    /// Occlusion scenario (triangle, same-side, symmetry, diagonal, inner).
    #[serde(default)]
    pub occlusion_scenario: String,
    /// Exact fraction of the marker square covered by occluders.
    #[serde(default)]
    pub occlusion_coverage: Option<f64>,
}

impl TruthMarker {
    /// The four corners TL, BL, BR, TR.
    pub fn corners(&self) -> [[f64; 2]; 4] {
        [
            [self.x0, self.y0],
            [self.x1, self.y1],
            [self.x2, self.y2],
            [self.x3, self.y3],
        ]
    }

    /// The true pose, when the truth file has it: rotation vector
    /// (radians), translation (metres) and the marker-square side (metres).
    pub fn pose(&self) -> Option<([f64; 3], [f64; 3], f64)> {
        Some((
            [self.rvec_x?, self.rvec_y?, self.rvec_z?],
            [self.tx?, self.ty?, self.tz?],
            self.square_m?,
        ))
    }
}

/// A dataset on disk: its directory, name and ground truth by image.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Directory holding `truth.csv`, `dataset.json` and `images/`.
    pub dir: PathBuf,
    /// Name from `dataset.json` (for example `coppertag-distance-z`).
    pub name: String,
    /// Image files (relative) in index order, with their index.
    pub images: Vec<(usize, String)>,
    /// Markers by image file.
    pub truth: BTreeMap<String, Vec<TruthMarker>>,
}

impl Dataset {
    /// Opens a dataset directory.
    pub fn open(dir: &Path) -> Result<Self> {
        let meta_path = dir.join("dataset.json");
        let meta = std::fs::read_to_string(&meta_path).map_err(|e| EvalError::io(&meta_path, e))?;
        let meta: serde_json::Value =
            serde_json::from_str(&meta).map_err(|e| EvalError::bad(&meta_path, e.to_string()))?;
        let name = meta["name"]
            .as_str()
            .ok_or_else(|| EvalError::bad(&meta_path, "no \"name\""))?
            .to_string();
        let truth_path = dir.join("truth.csv");
        let mut reader = csv::Reader::from_path(&truth_path)
            .map_err(|e| EvalError::bad(&truth_path, e.to_string()))?;
        let mut truth: BTreeMap<String, Vec<TruthMarker>> = BTreeMap::new();
        let mut index_of: BTreeMap<String, usize> = BTreeMap::new();
        for (row, rec) in reader.deserialize::<TruthMarker>().enumerate() {
            let m =
                rec.map_err(|e| EvalError::bad(&truth_path, format!("row {}: {e}", row + 2)))?;
            index_of.insert(m.image.clone(), m.index);
            truth.entry(m.image.clone()).or_default().push(m);
        }
        // Images without markers (clutter, false-positive sets) have no
        // rows; they are found in images/ by their index-named files.
        let img_dir = dir.join("images");
        if let Ok(entries) = std::fs::read_dir(&img_dir) {
            for e in entries.flatten() {
                let file = e.file_name().to_string_lossy().into_owned();
                let Some(stem) = file.strip_suffix(".png") else {
                    continue;
                };
                if let Ok(index) = stem.parse::<usize>() {
                    index_of.entry(format!("images/{file}")).or_insert(index);
                }
            }
        }
        if index_of.is_empty() {
            return Err(EvalError::bad(
                &truth_path,
                "no ground-truth rows and no images",
            ));
        }
        let mut images: Vec<(usize, String)> = index_of.into_iter().map(|(k, v)| (v, k)).collect();
        images.sort();
        Ok(Self {
            dir: dir.to_path_buf(),
            name,
            images,
            truth,
        })
    }

    /// Absolute (or dir-relative) path of an image file.
    pub fn image_path(&self, image: &str) -> PathBuf {
        self.dir.join(image)
    }

    /// The marker system of the dataset (from its first row).
    pub fn marker(&self) -> &str {
        self.truth
            .values()
            .next()
            .and_then(|v| v.first())
            .map_or("", |m| m.marker.as_str())
    }
}

/// A marker for unit tests: `corners` TL, BL, BR, TR; pose fields when
/// `pose` is given as (rvec, tvec, square side).
#[cfg(test)]
pub(crate) fn test_marker(
    index: usize,
    id: u64,
    corners: [[f64; 2]; 4],
    pose: Option<([f64; 3], [f64; 3], f64)>,
) -> TruthMarker {
    let side = (0..4)
        .map(|k| {
            let (a, b) = (corners[k], corners[(k + 1) % 4]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .sum::<f64>()
        / 4.0;
    TruthMarker {
        image: format!("images/{index:06}.png"),
        index,
        marker_index: 0,
        marker: "coppertag".into(),
        family: "ct14".into(),
        id,
        x0: corners[0][0],
        y0: corners[0][1],
        x1: corners[1][0],
        y1: corners[1][1],
        x2: corners[2][0],
        y2: corners[2][1],
        x3: corners[3][0],
        y3: corners[3][1],
        side_px: side,
        square_m: pose.map(|p| p.2),
        rvec_x: pose.map(|p| p.0[0]),
        rvec_y: pose.map(|p| p.0[1]),
        rvec_z: pose.map(|p| p.0[2]),
        tx: pose.map(|p| p.1[0]),
        ty: pose.map(|p| p.1[1]),
        tz: pose.map(|p| p.1[2]),
        param: String::new(),
        value: None,
        value_deg: None,
        occlusion_pattern: String::new(),
        occlusion_scenario: String::new(),
        occlusion_coverage: None,
    }
}

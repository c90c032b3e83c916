//! Reading a sampled dataset's `draws.csv`: the value every sampled factor
//! took, per image and per marker (written by `coppertag synth` for specs
//! with `[sample]`; columns in `datasets/README.md`).
//!
//! `index,marker_index,factor,value`: an empty `marker_index` is an
//! image-level draw that applies to every marker of the image; a marker's
//! own draw of the same factor wins. `value` is a number, or text for
//! categorical factors (`occluder_kind`...). The set of factors is open:
//! whatever the file names is evaluated. A dataset without the file (the
//! paper's sweeps) simply has no factors.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{EvalError, Result};

/// File name inside a dataset directory.
pub const FILE: &str = "draws.csv";

/// The factor that ties renders of one scene with fresh sensor noise.
pub const JITTER_GROUP: &str = "jitter_group";

/// The factor naming the family drawn, where a spec mixes several (the
/// dense sets' CopperTag frames).
pub const FAMILY: &str = "family";

/// One drawn value.
#[derive(Debug, Clone, PartialEq, PartialOrd, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FactorValue {
    /// A number (in the factor's unit, named by its suffix).
    Num(f64),
    /// A category (an occluder kind, a background image...).
    Text(String),
}

impl FactorValue {
    fn parse(s: &str) -> Self {
        match s.trim().parse::<f64>() {
            Ok(v) if v.is_finite() => Self::Num(v),
            _ => Self::Text(s.to_string()),
        }
    }

    /// The number, if the value is one.
    pub fn as_num(&self) -> Option<f64> {
        match self {
            Self::Num(v) => Some(*v),
            Self::Text(_) => None,
        }
    }

    /// The text, if the value is a category.
    pub fn as_text(&self) -> Option<&str> {
        match self {
            Self::Text(t) => Some(t),
            Self::Num(_) => None,
        }
    }

    /// The value as a label (numbers in Rust's shortest round-trip form).
    pub fn label(&self) -> String {
        match self {
            Self::Num(v) => format!("{v}"),
            Self::Text(t) => t.clone(),
        }
    }
}

/// Factor -> value.
pub type Factors = BTreeMap<String, FactorValue>;

/// Factors whose value 0 says the effect was not applied at all, off the
/// scale the factor is drawn on: a `jpeg_quality` of 0 is a frame with no
/// JPEG step (datasets/README.md), the best case rather than the lowest
/// quality. The factor curves leave those markers out (as 0 they filled
/// the lowest bins with lossless frames, so that the curve's "lowest
/// quality" point read as well as its highest), and the scenario rows of
/// compressed frames do not count them. The other events' 0 (no blur, no
/// glare, no shadow) is the low end of their own scale.
const OFF_AT_ZERO: &[&str] = &["jpeg_quality"];

/// Whether value `v` of factor `factor` says the effect was left off
/// ([`OFF_AT_ZERO`]).
pub(crate) fn left_off(factor: &str, v: &FactorValue) -> bool {
    OFF_AT_ZERO.contains(&factor) && v.as_num() == Some(0.0)
}

/// All draws of a dataset.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Draws {
    /// Image-level draws by image index.
    image: BTreeMap<usize, Factors>,
    /// Marker-level draws by (image index, marker index).
    marker: BTreeMap<(usize, usize), Factors>,
}

#[derive(Deserialize)]
struct Row {
    index: usize,
    marker_index: Option<usize>,
    factor: String,
    value: String,
}

impl Draws {
    /// Reads `dir/draws.csv`; `None` when the dataset has no such file.
    pub fn open(dir: &Path) -> Result<Option<Self>> {
        let path = dir.join(FILE);
        if !path.exists() {
            return Ok(None);
        }
        let mut reader =
            csv::Reader::from_path(&path).map_err(|e| EvalError::bad(&path, e.to_string()))?;
        let mut d = Self::default();
        for (row, rec) in reader.deserialize::<Row>().enumerate() {
            let r = rec.map_err(|e| EvalError::bad(&path, format!("row {}: {e}", row + 2)))?;
            if r.factor.is_empty() {
                return Err(EvalError::bad(
                    &path,
                    format!("row {}: empty factor", row + 2),
                ));
            }
            let map = match r.marker_index {
                Some(m) => d.marker.entry((r.index, m)).or_default(),
                None => d.image.entry(r.index).or_default(),
            };
            map.insert(r.factor, FactorValue::parse(&r.value));
        }
        Ok(Some(d))
    }

    /// The factors of marker `marker_index` in image `index`: the image's
    /// draws, overridden by the marker's own.
    pub fn factors(&self, index: usize, marker_index: usize) -> Factors {
        let mut f = self.image.get(&index).cloned().unwrap_or_default();
        if let Some(m) = self.marker.get(&(index, marker_index)) {
            f.extend(m.iter().map(|(k, v)| (k.clone(), v.clone())));
        }
        f
    }

    /// The image-level draws of image `index`.
    pub fn image_factors(&self, index: usize) -> Factors {
        self.image.get(&index).cloned().unwrap_or_default()
    }

    /// Adds another part's draws (a shard of the same dataset).
    pub fn extend(&mut self, other: Self) {
        self.image.extend(other.image);
        self.marker.extend(other.marker);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marker_draws_override_image_draws() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(FILE),
            "index,marker_index,factor,value\n\
             0,,defocus_px,1.5\n0,,occluder_kind,stick\n0,1,defocus_px,2\n3,0,roll_deg,-30\n",
        )
        .unwrap();
        let d = Draws::open(dir.path()).unwrap().unwrap();
        let m0 = d.factors(0, 0);
        assert_eq!(m0["defocus_px"], FactorValue::Num(1.5));
        assert_eq!(m0["occluder_kind"], FactorValue::Text("stick".into()));
        assert_eq!(d.factors(0, 1)["defocus_px"], FactorValue::Num(2.0));
        assert_eq!(d.factors(3, 0)["roll_deg"], FactorValue::Num(-30.0));
        assert!(d.factors(3, 1).is_empty());
        assert!(Draws::open(&dir.path().join("none")).unwrap().is_none());
        std::fs::write(
            dir.path().join(FILE),
            "index,marker_index,factor,value\nx,,a,1\n",
        )
        .unwrap();
        let e = Draws::open(dir.path()).unwrap_err().to_string();
        assert!(e.contains("draws.csv") && e.contains("row 2"), "{e}");
    }
}

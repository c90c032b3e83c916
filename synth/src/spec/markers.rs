//! `[[markers]]`: what is printed, how big, and where.

use std::sync::Arc;

use crate::error::{Result, SynthError};
use crate::markers::MarkerModel;
use crate::pose::Pose;
use crate::toml_input::{steps, KeyLocator};

use super::schema::MarkerFile;

/// A marker of the spec with its base pose.
#[derive(Debug, Clone)]
pub struct MarkerEntry {
    /// Shapes.
    pub model: Arc<MarkerModel>,
    /// Printed size, metres.
    pub size_m: f64,
    /// Pose before the sweep is applied.
    pub pose: Pose,
    /// Whether the spec's occlusions apply to it.
    pub occlude: bool,
}

/// The validated markers. No markers is allowed: background-only images
/// for false-positive tests (their truth.csv has a header and no rows).
pub(super) fn markers(loc: &KeyLocator, files: &[MarkerFile]) -> Result<Vec<MarkerEntry>> {
    let mut markers = Vec::new();
    for (i, mf) in files.iter().enumerate() {
        if !(mf.size_m > 0.0 && mf.size_m.is_finite()) {
            return Err(loc.err(
                steps!["markers", i, "size_m"],
                format!(
                    "markers[{i}].size_m = {} must be a positive number of metres",
                    mf.size_m
                ),
            ));
        }
        if !mf
            .translation
            .iter()
            .chain(&mf.rotation)
            .all(|v| v.is_finite())
        {
            return Err(loc.err(
                steps!["markers", i, "translation"],
                format!("markers[{i}]: translation and rotation must be finite"),
            ));
        }
        let model = MarkerModel::new(mf.system, mf.family.as_deref(), mf.id).map_err(|e| {
            let key = if matches!(e, SynthError::InvalidParameter { name: "family", .. })
                || matches!(e, SynthError::Tag(coppertag::Error::UnknownFamily { .. }))
            {
                "family"
            } else {
                "id"
            };
            loc.err(steps!["markers", i, key], format!("markers[{i}]: {e}"))
        })?;
        markers.push(MarkerEntry {
            model: Arc::new(model),
            size_m: mf.size_m,
            pose: Pose::from_rvec(mf.rotation, mf.translation),
            occlude: mf.occlude,
        });
    }
    Ok(markers)
}

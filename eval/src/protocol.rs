//! The line protocol every detector speaks (ours and the peers' adapters in
//! `eval/peers/`): image paths in, one JSON line out per image, in the
//! `coppertag detect --json` format. See `eval/peers/README.md`.

use serde::{Deserialize, Serialize};

/// One detected marker as the protocol carries it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionRecord {
    /// Family or codebook name (`ct14`, `tag36h11`, `aruco_mip_36h12`,
    /// `stag_hd21`, `fractal_5l_6`).
    pub family: String,
    /// Marker id.
    pub id: u64,
    /// Corners TL, BL, BR, TR in the marker's own frame, pixel-centre
    /// coordinates.
    pub corners: [[f64; 2]; 4],
    /// Which corners were estimated rather than observed.
    #[serde(default)]
    pub estimated: [bool; 4],
    /// Symbols or bits corrected, when the detector tells.
    #[serde(default)]
    pub corrected: Option<u64>,
    /// One-sigma uncertainty of each corner (px, radial), when the
    /// detector estimates one (CopperTag, from the fit of its model to the
    /// tag's edges; the peers report none). Optional so that lines without
    /// it, the peers' and older run logs, still parse.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub corner_sigma: Option<[f64; 4]>,
    /// Read by likelihood (CopperTag: a blurred tag matched against every
    /// codeword rather than decoded cell by cell); false for every other
    /// reading and every other detector. Carried so that the honesty of
    /// `corner_sigma` can be measured for both kinds of reading, which the
    /// detector scales differently.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub likelihood: bool,
}

/// One protocol line: the result for one image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageResult {
    /// The image path as sent.
    pub image: String,
    /// Detection time in milliseconds, measured around the detect call only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ms: Option<f64>,
    /// Detections (empty on error).
    #[serde(default)]
    pub detections: Vec<DetectionRecord>,
    /// Set when the detector could not process the image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl ImageResult {
    /// Parses and checks one protocol line: it must be a JSON object with
    /// finite coordinates, finite non-negative corner sigmas when given,
    /// and either `ms` or `error`.
    pub fn parse(line: &str) -> std::result::Result<Self, String> {
        let r: ImageResult = serde_json::from_str(line.trim()).map_err(|e| e.to_string())?;
        if r.error.is_none() && r.ms.is_none() {
            return Err("line has neither \"ms\" nor \"error\"".into());
        }
        if let Some(ms) = r.ms {
            if !(ms.is_finite() && ms >= 0.0) {
                return Err(format!("bad time {ms}"));
            }
        }
        for d in &r.detections {
            if d.corners.iter().flatten().any(|v| !v.is_finite()) {
                return Err(format!("non-finite corner in detection of id {}", d.id));
            }
            if let Some(sigma) = d.corner_sigma {
                if let Some(s) = sigma.iter().find(|s| !(s.is_finite() && **s >= 0.0)) {
                    return Err(format!(
                        "bad corner_sigma {s} in detection of id {} (need finite px >= 0)",
                        d.id
                    ));
                }
            }
        }
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_adapter_lines() {
        let line = r#"{"image": "a.png", "ms": 1.5, "detections": [{"family": "tag36h11", "id": 3,
            "corners": [[1,2],[3,4],[5,6],[7,8]], "estimated": [false,false,false,false], "corrected": null}]}"#;
        let r = ImageResult::parse(&line.replace('\n', " ")).unwrap();
        assert_eq!(r.detections[0].id, 3);
        let err = ImageResult::parse(r#"{"image": "a.png", "error": "cannot read"}"#).unwrap();
        assert_eq!(err.error.as_deref(), Some("cannot read"));
        assert!(ImageResult::parse("garbage").is_err());
        assert!(ImageResult::parse(r#"{"image": "a.png"}"#).is_err());
        assert!(ImageResult::parse(r#"{"image": "a.png", "ms": -1}"#).is_err());
    }

    fn with_sigma(sigma: &str) -> String {
        format!(
            r#"{{"image": "a.png", "ms": 1, "detections": [{{"family": "ct14", "id": 5,
            "corners": [[1,2],[3,4],[5,6],[7,8]], "estimated": [false,true,false,false],
            "corrected": 0, "corner_sigma": {sigma}, "likelihood": true}}]}}"#
        )
        .replace('\n', " ")
    }

    #[test]
    fn corner_sigma_is_optional_and_checked() {
        // Without it (a peer's line): none, and not a likelihood reading.
        let r = ImageResult::parse(
            r#"{"image": "a.png", "ms": 1, "detections": [{"family": "ct14", "id": 5, "corners": [[1,2],[3,4],[5,6],[7,8]]}]}"#,
        )
        .unwrap();
        assert_eq!(r.detections[0].corner_sigma, None);
        assert!(!r.detections[0].likelihood);
        // `coppertag detect --json` writes null for an unfitted tag.
        let r = ImageResult::parse(&with_sigma("null")).unwrap();
        assert_eq!(r.detections[0].corner_sigma, None);
        let r = ImageResult::parse(&with_sigma("[0.1, 0, 0.25, 1e3]")).unwrap();
        assert_eq!(r.detections[0].corner_sigma, Some([0.1, 0.0, 0.25, 1e3]));
        assert!(r.detections[0].likelihood);
        // Written back, it round-trips; absent fields stay absent.
        let back = serde_json::to_string(&r).unwrap();
        assert_eq!(ImageResult::parse(&back).unwrap(), r);
        let mut plain = r.clone();
        plain.detections[0].corner_sigma = None;
        plain.detections[0].likelihood = false;
        let text = serde_json::to_string(&plain).unwrap();
        assert!(
            !text.contains("corner_sigma") && !text.contains("likelihood"),
            "{text}"
        );
        // Negative, or not four numbers: an error naming the field.
        let e = ImageResult::parse(&with_sigma("[0.1, -0.2, 0.1, 0.1]")).unwrap_err();
        assert!(e.contains("corner_sigma -0.2"), "{e}");
        assert!(ImageResult::parse(&with_sigma("[0.1, 0.2, 0.1]")).is_err());
        assert!(ImageResult::parse(&with_sigma(r#""0.1""#)).is_err());
        assert!(ImageResult::parse(&with_sigma("[0.1, 1e999, 0.1, 0.1]")).is_err());
    }
}

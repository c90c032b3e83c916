//! Camera calibration files for `coppertag detect --camera`: a
//! `foxglove.CameraCalibration` in JSON, or the YAML that OpenCV's
//! calibration (`cv::FileStorage`) and ROS's `camera_calibration` write:
//!
//! ```yaml
//! image_width: 640
//! image_height: 480
//! camera_matrix: {rows: 3, cols: 3, data: [600., 0., 319.5, 0., 600., 239.5, 0., 0., 1.]}
//! distortion_model: plumb_bob        # optional; plumb_bob when absent
//! distortion_coefficients: {rows: 1, cols: 5, data: [-0.1, 0.01, 0., 0., 0.]}
//! ```
//!
//! OpenCV tags its matrices `!!opencv-matrix` (the YAML reader ignores
//! tags on mappings) and opens files with `%YAML:1.0`, a directive no YAML
//! 1.2 parser accepts, so that one line is dropped before parsing.

use std::path::Path;

use yaml_rust2::{Yaml, YamlLoader};

use super::camera::{Calibration, FoxgloveCalibration};

/// Reads a calibration file: JSON when it starts with `{`, else YAML.
pub fn read(path: &Path) -> Result<Calibration, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    if text.trim_start().starts_with('{') {
        let cal: FoxgloveCalibration = serde_json::from_str(&text)
            .map_err(|e| format!("not a foxglove.CameraCalibration: {e}"))?;
        return Ok((&cal).into());
    }
    from_yaml(&text)
}

fn numbers(doc: &Yaml, key: &str) -> Result<Vec<f64>, String> {
    let data = &doc[key]["data"];
    let list = data
        .as_vec()
        .ok_or_else(|| format!("no {key}: {{data: [...]}}"))?;
    list.iter()
        .map(|v| match v {
            Yaml::Real(_) => v.as_f64(),
            Yaml::Integer(i) => Some(*i as f64),
            _ => None,
        })
        .map(|v| v.ok_or_else(|| format!("{key}.data holds a value that is not a number")))
        .collect()
}

fn size(doc: &Yaml, key: &str) -> Result<u32, String> {
    doc[key]
        .as_i64()
        .and_then(|v| u32::try_from(v).ok())
        .ok_or_else(|| format!("no {key} (a whole number of pixels)"))
}

/// Parses OpenCV or ROS calibration YAML.
pub fn from_yaml(text: &str) -> Result<Calibration, String> {
    let body: String = if text.trim_start().starts_with("%YAML:") {
        text.trim_start()
            .split_once('\n')
            .map_or(String::new(), |(_, rest)| rest.to_string())
    } else {
        text.to_string()
    };
    let docs = YamlLoader::load_from_str(&body).map_err(|e| format!("not YAML: {e}"))?;
    let doc = docs.first().ok_or("an empty file")?;
    let k: [f64; 9] = numbers(doc, "camera_matrix")?
        .try_into()
        .map_err(|v: Vec<f64>| format!("camera_matrix.data has {} numbers, not 9", v.len()))?;
    let d = numbers(doc, "distortion_coefficients")?;
    let distortion_model = doc["distortion_model"]
        .as_str()
        .unwrap_or("plumb_bob")
        .to_string();
    Ok(Calibration {
        width: size(doc, "image_width")?,
        height: size(doc, "image_height")?,
        k,
        distortion_model,
        d,
        binning: (0, 0),
        roi: (0, 0, 0, 0),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_opencv_and_ros_files() {
        let opencv = "%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\n\
            camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   \
            data: [ 6.0e+02, 0., 3.195e+02, 0., 600., 239.5, 0., 0., 1. ]\n\
            distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   \
            data: [ -0.1, 0.01, 0., 0., 0 ]\n";
        let c = from_yaml(opencv).unwrap();
        assert_eq!((c.width, c.height), (640, 480));
        assert_eq!(c.k, [600.0, 0.0, 319.5, 0.0, 600.0, 239.5, 0.0, 0.0, 1.0]);
        assert_eq!(c.d, vec![-0.1, 0.01, 0.0, 0.0, 0.0]);
        assert_eq!(c.distortion_model, "plumb_bob");
        assert!(c.model().is_ok());
        let ros = "image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo\n\
            camera_matrix:\n  rows: 3\n  cols: 3\n  data: [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]\n\
            distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  \
            data: [-0.1, 0.01, 0, 0, 0]\n";
        assert_eq!(from_yaml(ros).unwrap(), c);
        let e = from_yaml("image_width: 640\nimage_height: 480\ncamera_matrix: {data: [1, 2]}\n")
            .unwrap_err();
        assert!(e.contains("2 numbers"), "{e}");
        assert!(from_yaml("image_width: 640\n")
            .unwrap_err()
            .contains("camera_matrix"));
    }

    #[test]
    fn reads_foxglove_json_by_content() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("cal.txt");
        std::fs::write(
            &path,
            r#"{"width": 640, "height": 480, "distortion_model": "plumb_bob",
                "D": [-0.1, 0.01, 0, 0, 0], "K": [600, 0, 319.5, 0, 600, 239.5, 0, 0, 1]}"#,
        )
        .unwrap();
        let c = read(&path).unwrap();
        assert_eq!(c.k[2], 319.5);
        assert_eq!(c.d.len(), 5);
        assert!(c.model().is_ok());
        std::fs::write(&path, r#"{"width": 640}"#).unwrap();
        assert!(read(&path)
            .unwrap_err()
            .contains("foxglove.CameraCalibration"));
    }
}

//! `Detector(families=..., **settings)` into a [`DetectorConfig`].
//!
//! The keywords are the config's serialised fields, read off
//! `DetectorConfig::default()` at run time, and each value goes through the
//! config's own deserialiser and [`DetectorConfig::validate`]: the names,
//! defaults, types and valid ranges live in the Rust crate only, so a setting
//! added there is a keyword here with no change to this file.

use coppertag::{DetectorConfig, FamilySetting};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString, PyTuple};
use serde_json::{Map, Value};

/// The serialised key of the family list, which is a keyword of its own.
const FAMILIES: &str = "families";

/// The settings of `config` as a JSON object, families left out.
fn settings_json(config: &DetectorConfig) -> PyResult<Map<String, Value>> {
    match serde_json::to_value(config) {
        Ok(Value::Object(mut map)) => {
            map.remove(FAMILIES);
            Ok(map)
        }
        other => Err(PyRuntimeError::new_err(format!(
            "detector settings do not serialise to an object: {other:?}"
        ))),
    }
}

/// Every setting's name and default value, as Python values (what
/// `coppertag.DEFAULT_SETTINGS` holds).
pub fn defaults_dict(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    settings_dict(py, &DetectorConfig::default())
}

/// The settings of `config` (families left out) as a Python dict.
pub fn settings_dict<'py>(
    py: Python<'py>,
    config: &DetectorConfig,
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (name, value) in settings_json(config)? {
        dict.set_item(name, json_to_py(py, &value)?)?;
    }
    Ok(dict)
}

fn json_to_py<'py>(py: Python<'py>, v: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match v {
        Value::Bool(b) => PyBool::new(py, *b).to_owned().into_any(),
        Value::Number(n) => match (n.as_u64(), n.as_i64()) {
            (Some(u), _) => u.into_pyobject(py)?.into_any(),
            (None, Some(i)) => i.into_pyobject(py)?.into_any(),
            _ => PyFloat::new(py, n.as_f64().unwrap_or(f64::NAN)).into_any(),
        },
        Value::Null => py.None().into_bound(py),
        other => PyString::new(py, &other.to_string()).into_any(),
    })
}

/// A Python scalar as JSON, or `None` for a type no setting has.
fn py_to_json(v: &Bound<'_, PyAny>) -> Option<Value> {
    if let Ok(b) = v.cast::<PyBool>() {
        return Some(Value::Bool(b.is_true()));
    }
    if v.is_instance_of::<PyInt>() {
        if let Ok(u) = v.extract::<u64>() {
            return Some(Value::from(u));
        }
        if let Ok(i) = v.extract::<i64>() {
            return Some(Value::from(i));
        }
        // An integer beyond 64 bits: out of every setting's range.
        return Some(Value::from(f64::INFINITY));
    }
    if v.is_instance_of::<PyFloat>() {
        let f: f64 = v.extract().ok()?;
        // JSON has no NaN or infinity; serde_json stores them as null,
        // which every numeric setting rejects with a type error.
        return Some(serde_json::Number::from_f64(f).map_or(Value::Null, Value::Number));
    }
    None
}

/// The families keyword: names (`"ct14"`) or `(name, max_corrected)` pairs.
fn families(obj: &Bound<'_, PyAny>) -> PyResult<Vec<FamilySetting>> {
    if obj.is_instance_of::<PyString>() {
        return Err(PyTypeError::new_err(
            "families must be a sequence of family names, e.g. (\"ct14\",), not a string",
        ));
    }
    let mut out = Vec::new();
    for item in obj.try_iter().map_err(|_| {
        PyTypeError::new_err(
            "families must be a sequence of family names, e.g. (\"ct14\", \"ct8\")",
        )
    })? {
        let item = item?;
        let setting = if let Ok(name) = item.extract::<String>() {
            FamilySetting::builtin(&name).map_err(crate::errors::to_py)?
        } else if let Ok(pair) = item.cast::<PyTuple>() {
            let (name, max): (String, usize) = pair.extract().map_err(|_| {
                PyTypeError::new_err(
                    "a family is a name or a (name, max_corrected) pair, e.g. (\"ct8\", 2)",
                )
            })?;
            FamilySetting::builtin(&name)
                .map_err(crate::errors::to_py)?
                .with_max_corrected(max)
        } else {
            return Err(PyTypeError::new_err(format!(
                "a family is a name or a (name, max_corrected) pair, got {}",
                item.repr()?
            )));
        };
        out.push(setting);
    }
    Ok(out)
}

/// The config the keywords describe, validated; errors name the setting.
pub fn config(
    families_arg: Option<&Bound<'_, PyAny>>,
    settings: Option<&Bound<'_, PyDict>>,
) -> PyResult<DetectorConfig> {
    let defaults = DetectorConfig::default();
    let mut json = settings_json(&defaults)?;
    if let Some(settings) = settings {
        for (key, value) in settings.iter() {
            let name: String = key.extract()?;
            if !json.contains_key(&name) {
                let known: Vec<&str> = json.keys().map(String::as_str).collect();
                return Err(PyTypeError::new_err(format!(
                    "unknown setting '{name}' (settings: families, {})",
                    known.join(", ")
                )));
            }
            let v = py_to_json(&value).ok_or_else(|| {
                PyTypeError::new_err(format!(
                    "setting {name}: expected a number or a bool, got {}",
                    value
                        .get_type()
                        .name()
                        .map_or("?".into(), |n| n.to_string())
                ))
            })?;
            json.insert(name.clone(), v);
            // Deserialise after each key, so a type or range error of the
            // integer fields (e.g. threshold_offset = 300 for a u8) names
            // the setting that caused it.
            let mut probe = json.clone();
            probe.insert(FAMILIES.into(), Value::Array(Vec::new()));
            if let Err(e) = serde_json::from_value::<DetectorConfig>(Value::Object(probe)) {
                return Err(PyValueError::new_err(format!(
                    "invalid parameter {name}: {} ({e})",
                    value.repr()?
                )));
            }
        }
    }
    json.insert(FAMILIES.into(), Value::Array(Vec::new()));
    let mut config: DetectorConfig = serde_json::from_value(Value::Object(json))
        .map_err(|e| PyValueError::new_err(format!("invalid settings: {e}")))?;
    config.families = match families_arg {
        Some(f) if !f.is_none() => families(f)?,
        _ => defaults.families,
    };
    config.validate().map_err(crate::errors::to_py)?;
    Ok(config)
}

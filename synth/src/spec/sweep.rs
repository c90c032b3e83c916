//! `[sweep]`: one pose parameter stepped over a range.

use serde::Serialize;

use crate::error::Result;
use crate::toml_input::{steps, KeyLocator};

use super::schema::{SweepFile, SweepParam};

/// Most values a sweep may have.
const MAX_SWEEP_VALUES: usize = 10_000_000;
/// How far `(to - from) / step` may be from a whole number.
const WHOLE_STEPS_TOLERANCE: f64 = 1e-6;

/// A sweep of one pose parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Sweep {
    /// What varies.
    pub param: SweepParam,
    /// The values, metres or radians.
    pub values: Vec<f64>,
    /// Markers it moves (indices into the spec's markers).
    pub markers: Vec<usize>,
}

/// The validated sweep of `sf`, over a spec of `n_markers` markers.
pub(super) fn sweep(loc: &KeyLocator, sf: &SweepFile, n_markers: usize) -> Result<Sweep> {
    let unit = match (sf.unit.as_deref(), sf.param.is_angle()) {
        (None | Some("rad"), true) | (None | Some("m"), false) => 1.0,
        (Some("deg"), true) => std::f64::consts::PI / 180.0,
        (Some("mm"), false) => 1e-3,
        (Some(u), _) => {
            return Err(loc.err(
                steps!["sweep", "unit"],
                format!(
                    "sweep.unit '{u}' does not fit param {} (angles: rad, deg; lengths: m, mm)",
                    sf.param.name()
                ),
            ))
        }
    };
    if !(sf.from.is_finite() && sf.to.is_finite()) {
        return Err(loc.err(
            steps!["sweep", "from"],
            "sweep.from and sweep.to must be finite".into(),
        ));
    }
    let values: Vec<f64> = match (sf.step, sf.count) {
        (Some(step), None) => {
            if step.is_nan() || step <= 0.0 {
                return Err(loc.err(
                    steps!["sweep", "step"],
                    format!("sweep.step = {step} must be positive"),
                ));
            }
            if sf.to < sf.from {
                return Err(loc.err(
                    steps!["sweep", "to"],
                    format!("sweep.to = {} is below sweep.from = {}", sf.to, sf.from),
                ));
            }
            let n = (sf.to - sf.from) / step;
            let k = n.round();
            if (n - k).abs() > WHOLE_STEPS_TOLERANCE || k > MAX_SWEEP_VALUES as f64 {
                return Err(loc.err(
                    steps!["sweep", "step"],
                    format!(
                        "sweep: from {} to {} is not a whole number of steps of {step}",
                        sf.from, sf.to
                    ),
                ));
            }
            (0..=k as usize)
                .map(|i| (sf.from + i as f64 * step) * unit)
                .collect()
        }
        (None, Some(count)) => {
            if count == 0 || count > MAX_SWEEP_VALUES {
                return Err(loc.err(
                    steps!["sweep", "count"],
                    format!("sweep.count = {count} is outside 1..={MAX_SWEEP_VALUES}"),
                ));
            }
            if count == 1 {
                vec![sf.from * unit]
            } else {
                (0..count)
                    .map(|i| (sf.from + (sf.to - sf.from) * i as f64 / (count - 1) as f64) * unit)
                    .collect()
            }
        }
        _ => {
            return Err(loc.err(
                steps!["sweep"],
                "sweep: give exactly one of step and count".into(),
            ))
        }
    };
    let markers = sf
        .markers
        .clone()
        .unwrap_or_else(|| (0..n_markers).collect());
    if let Some(&bad) = markers.iter().find(|&&m| m >= n_markers) {
        return Err(loc.err(
            steps!["sweep", "markers"],
            format!("sweep.markers: there is no marker {bad} (the spec has {n_markers})"),
        ));
    }
    Ok(Sweep {
        param: sf.param,
        values,
        markers,
    })
}

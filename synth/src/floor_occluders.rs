//! Occluders seen on factory floors, generated at an exact coverage of the
//! marker square (same frame as [`crate::occlusion`]: the unit square of
//! the marker square, `(0, 0)` at TL):
//!
//! - `stick`: one or two straight bands (a broom handle, a strut, a taut
//!   cable) through the middle part of the square at any angle; one stick
//!   cuts two sides, two crossing sticks can cut all four sides while every
//!   corner stays visible;
//! - `cable`: a curved band (a quadratic Bezier curve swept with a
//!   constant width) across the square;
//! - `flush-tape`: a dark strip lying on the marker's black frame along
//!   one side, running out past a corner, so its outer edge continues the
//!   frame's edge and the corner disappears into a longer straight edge
//!   (drawn at the ink's reflectance by the sampler);
//! - `blob`: an irregular star-shaped blob (dirt, a glove, a hand) of five
//!   random lobes anywhere on the square, also over its edges and corners.
//!
//! Every shape has one free size (a width, a depth or a scale) found by
//! bisection so that the exact coverage ([`polygon::union_area_in_unit_square`])
//! matches the request. Occluders are clipped to [`OCCLUDER_BOX`], the
//! printed CopperTag (the largest printed image of the four systems), so
//! one occluder looks the same on every system's marker.

use rand::RngExt;

use crate::error::{Result, SynthError};
use crate::occlusion::{Appearance, Occluder, Occlusion, Scenario};
use crate::polygon;
use crate::rng::SynthRng;

/// Occluders are clipped to this box in unit-square coordinates: the
/// printed CopperTag, twice the marker square, centred on it.
pub const OCCLUDER_BOX: [f64; 4] = [-0.5, -0.5, 1.5, 1.5];

/// Largest coverage the floor kinds are generated at (the field
/// report: 30-40% coverage).
pub const MAX_FLOOR_COVERAGE: f64 = 0.4;

/// Bisection steps for the free size (2^-60 of the bracket: exact to f64).
const BISECTION_STEPS: usize = 60;

/// Largest coverage error accepted from the bisection.
const COVERAGE_TOLERANCE: f64 = 1e-6;

/// Shape attempts before giving up on a coverage (a random shape may not
/// reach the coverage inside the occluder box).
const ATTEMPTS: usize = 50;

/// Points along a cable's centre line.
const CABLE_SEGMENTS: usize = 32;

/// Vertices of a blob's outline.
const BLOB_VERTICES: usize = 72;

/// Whether `scenario` is one of this module's kinds.
#[must_use]
pub fn is_floor_kind(scenario: Scenario) -> bool {
    matches!(
        scenario,
        Scenario::Stick | Scenario::Cable | Scenario::FlushTape | Scenario::Blob
    )
}

fn clip(polys: Vec<Vec<[f64; 2]>>) -> Vec<Vec<[f64; 2]>> {
    polys
        .into_iter()
        .map(|p| polygon::clip_to_box(&p, OCCLUDER_BOX))
        .filter(|p| p.len() >= 3)
        .collect()
}

fn coverage(polys: &[Vec<[f64; 2]>]) -> f64 {
    polygon::union_area_in_unit_square(polys)
}

/// The shape `make(s)` whose coverage is `target`, for the size `s` in
/// `(0, hi]` (coverage must grow with `s`); `None` when `make(hi)` covers
/// less than `target`.
fn fit(
    target: f64,
    hi: f64,
    make: impl Fn(f64) -> Vec<Vec<[f64; 2]>>,
) -> Option<Vec<Vec<[f64; 2]>>> {
    if coverage(&clip(make(hi))) < target {
        return None;
    }
    let (mut lo, mut hi) = (0.0, hi);
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if coverage(&clip(make(mid))) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let polys = clip(make(hi));
    ((coverage(&polys) - target).abs() <= COVERAGE_TOLERANCE).then_some(polys)
}

/// A band of width `w` along direction `angle` through `c`, long enough
/// to cross the occluder box.
fn band(c: [f64; 2], angle: f64, w: f64) -> Vec<[f64; 2]> {
    let (d, n) = ([angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]);
    let l = 3.0;
    let h = w / 2.0;
    [(-l, -h), (l, -h), (l, h), (-l, h)]
        .iter()
        .map(|&(a, b)| [c[0] + a * d[0] + b * n[0], c[1] + a * d[1] + b * n[1]])
        .collect()
}

/// Rotates unit-square points by `k` quarter turns about the centre.
fn quarter_turns(poly: Vec<[f64; 2]>, k: u32) -> Vec<[f64; 2]> {
    poly.into_iter()
        .map(|p| {
            let mut q = p;
            for _ in 0..k {
                q = [1.0 - q[1], q[0]];
            }
            q
        })
        .collect()
}

fn shape(scenario: Scenario, target: f64, rng: &mut SynthRng) -> Option<Vec<Vec<[f64; 2]>>> {
    use std::f64::consts::{PI, TAU};
    match scenario {
        Scenario::Stick => {
            let n = if rng.random::<bool>() { 2 } else { 1 };
            let sticks: Vec<([f64; 2], f64)> = (0..n)
                .map(|_| {
                    (
                        [rng.random_range(0.25..0.75), rng.random_range(0.25..0.75)],
                        rng.random_range(0.0..PI),
                    )
                })
                .collect();
            fit(target, 1.5, |w| {
                sticks.iter().map(|&(c, a)| band(c, a, w)).collect()
            })
        }
        Scenario::Cable => {
            let a = rng.random_range(0.0..TAU);
            let b = a + PI + rng.random_range(-0.6..0.6);
            let p0 = [0.5 + 1.2 * a.cos(), 0.5 + 1.2 * a.sin()];
            let p2 = [0.5 + 1.2 * b.cos(), 0.5 + 1.2 * b.sin()];
            let p1 = [
                0.5 + rng.random_range(-0.3..0.3),
                0.5 + rng.random_range(-0.3..0.3),
            ];
            let pts: Vec<([f64; 2], [f64; 2])> = (0..=CABLE_SEGMENTS)
                .map(|i| {
                    let t = i as f64 / CABLE_SEGMENTS as f64;
                    let u = 1.0 - t;
                    let p = [
                        u * u * p0[0] + 2.0 * u * t * p1[0] + t * t * p2[0],
                        u * u * p0[1] + 2.0 * u * t * p1[1] + t * t * p2[1],
                    ];
                    let d = [
                        2.0 * u * (p1[0] - p0[0]) + 2.0 * t * (p2[0] - p1[0]),
                        2.0 * u * (p1[1] - p0[1]) + 2.0 * t * (p2[1] - p1[1]),
                    ];
                    let len = d[0].hypot(d[1]).max(1e-12);
                    (p, [-d[1] / len, d[0] / len])
                })
                .collect();
            fit(target, 0.6, |w| {
                let h = w / 2.0;
                let left = pts.iter().map(|(p, n)| [p[0] + h * n[0], p[1] + h * n[1]]);
                let right = pts
                    .iter()
                    .rev()
                    .map(|(p, n)| [p[0] - h * n[0], p[1] - h * n[1]]);
                vec![left.chain(right).collect()]
            })
        }
        Scenario::FlushTape => {
            // Along the top side, its top edge on the frame's outer edge
            // (y = 0), running out past the TL corner; then turned.
            let overhang = rng.random_range(0.1..0.5);
            let end = rng.random_range(0.3..1.3);
            let k = rng.random_range(0..4u32);
            fit(target, 1.0, |d| {
                vec![quarter_turns(
                    vec![[-overhang, 0.0], [-overhang, d], [end, d], [end, 0.0]],
                    k,
                )]
            })
        }
        Scenario::Blob => {
            let lobes: Vec<(f64, f64, f64)> = (2..7)
                .map(|k| {
                    (
                        f64::from(k),
                        rng.random_range(-0.25..0.25) / f64::from(k - 1),
                        rng.random_range(0.0..TAU),
                    )
                })
                .collect();
            let centre = [rng.random_range(0.0..1.0), rng.random_range(0.0..1.0)];
            let unit: Vec<[f64; 2]> = (0..BLOB_VERTICES)
                .map(|i| {
                    let th = TAU * i as f64 / BLOB_VERTICES as f64;
                    let r = 1.0
                        + lobes
                            .iter()
                            .map(|(k, a, p)| a * (k * th + p).cos())
                            .sum::<f64>();
                    [r * th.cos(), r * th.sin()]
                })
                .collect();
            fit(target, 1.2, |s| {
                vec![unit
                    .iter()
                    .map(|p| [centre[0] + s * p[0], centre[1] + s * p[1]])
                    .collect()]
            })
        }
        _ => None,
    }
}

/// A `scenario` occlusion (one of the floor kinds) of exact `coverage`,
/// every occluder with `appearance`.
pub fn generate(
    scenario: Scenario,
    coverage: f64,
    appearance: Appearance,
    name: String,
    rng: &mut SynthRng,
) -> Result<Occlusion> {
    if !is_floor_kind(scenario) {
        return Err(SynthError::InvalidParameter {
            name: "occluder_kind",
            reason: format!("{} is not a factory-floor occluder", scenario.name()),
        });
    }
    if !(coverage > 0.0 && coverage <= MAX_FLOOR_COVERAGE) {
        return Err(SynthError::InvalidParameter {
            name: "occluder_coverage",
            reason: format!("{coverage} is outside (0, {MAX_FLOOR_COVERAGE}]"),
        });
    }
    for _ in 0..ATTEMPTS {
        if let Some(polys) = shape(scenario, coverage, rng) {
            return Ok(Occlusion {
                name,
                scenario,
                occluders: polys
                    .into_iter()
                    .map(|polygon| Occluder {
                        polygon,
                        appearance,
                        cutout: None,
                    })
                    .collect(),
            });
        }
    }
    Err(SynthError::Scene(format!(
        "could not generate a {} occlusion of coverage {coverage}",
        scenario.name()
    )))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occlusion::Style;
    use rand::SeedableRng;

    #[test]
    fn floor_kinds_have_the_requested_coverage() {
        let mut rng = SynthRng::seed_from_u64(9);
        for kind in [
            Scenario::Stick,
            Scenario::Cable,
            Scenario::FlushTape,
            Scenario::Blob,
        ] {
            for &c in &[0.03, 0.1, 0.25, 0.4] {
                let o = generate(kind, c, Style::Solid.appearance(), "t".into(), &mut rng)
                    .unwrap_or_else(|e| panic!("{kind:?} {c}: {e}"));
                assert!(
                    (o.coverage() - c).abs() < 1e-5,
                    "{kind:?} {c}: {}",
                    o.coverage()
                );
            }
        }
    }

    #[test]
    fn two_sticks_can_cut_every_side_and_hide_no_corner() {
        let mut rng = SynthRng::seed_from_u64(1);
        let found = (0..400).any(|_| {
            let o = generate(
                Scenario::Stick,
                0.1,
                Style::Solid.appearance(),
                "t".into(),
                &mut rng,
            )
            .unwrap();
            o.corners_hidden() == [false; 4] && o.edges_broken() == [true; 4]
        });
        assert!(found);
    }

    #[test]
    fn flush_tape_edge_continues_a_side_of_the_square() {
        let mut rng = SynthRng::seed_from_u64(2);
        for _ in 0..20 {
            let o = generate(
                Scenario::FlushTape,
                0.1,
                Style::Solid.appearance(),
                "t".into(),
                &mut rng,
            )
            .unwrap();
            let p = &o.occluders[0].polygon;
            // Some edge of the tape lies on one of the lines x = 0, x = 1,
            // y = 0, y = 1 and reaches outside the square.
            let on_side = (0..p.len()).any(|i| {
                let (a, b) = (p[i], p[(i + 1) % p.len()]);
                (0..2).any(|ax| {
                    [0.0, 1.0].iter().any(|&v| {
                        (a[ax] - v).abs() < 1e-12
                            && (b[ax] - v).abs() < 1e-12
                            && (a[1 - ax].min(b[1 - ax]) < 0.0 || a[1 - ax].max(b[1 - ax]) > 1.0)
                    })
                })
            });
            assert!(on_side, "{p:?}");
        }
    }
}

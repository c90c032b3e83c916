//! Occlusion patterns: occluders laid on a marker, as data.
//!
//! Frame: the unit square of the marker square (the CopperTag data square,
//! a peer's outer black square), `(0, 0)` at its top-left corner, `(1, 1)`
//! at its bottom-right, x right, y down in the upright marker. The corners
//! TL, BL, BR, TR are `(0, 0)`, `(0, 1)`, `(1, 1)`, `(1, 0)`. Occluders may
//! reach outside the square (over the frame and quiet zone); they lie on the
//! marker's plane and move with its pose.
//!
//! Coverage of a pattern = area of the union of its occluders inside the
//! unit square, computed exactly ([`crate::polygon`]); so it is the fraction
//! of the marker square hidden, the same number for every marker system.
//! Circles and ellipses are turned into 360-gons first and drawn as those
//! same polygons, so the coverage is exact for what is drawn.
//!
//! Scenarios (the paper's Fig. 5 plus "inner"):
//! - `triangle`: one corner hidden;
//! - `same-side`: the two corners of one edge hidden;
//! - `symmetry`: a band across the middle that breaks two opposite edges and
//!   hides no corner (on each side of it, the marker looks like a same-side
//!   case);
//! - `diagonal`: two opposite corners hidden;
//! - `inner`: only the data area, inside `[0.125, 0.875]^2` (the peers' data
//!   area, and within CopperTag's), touching no edge and no corner;
//! - `custom`: anything; not checked.
//!
//! A pattern file (TOML) holds one pattern; see `datasets/README.md`.

use std::path::{Path, PathBuf};

use rand::RngExt;
use serde::{Deserialize, Serialize};

use crate::error::{Result, SynthError};
use crate::polygon;
use crate::rng::SynthRng;
use crate::spec::toml_error;

/// Vertices used for circles and ellipses.
pub const ROUND_VERTICES: usize = 360;

/// The unit-square corners TL, BL, BR, TR.
pub const UNIT_CORNERS: [[f64; 2]; 4] = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];

/// Inner scenarios stay inside this box (the peers' data area).
pub const INNER_BOX: [f64; 4] = [0.125, 0.125, 0.875, 0.875];

/// What kind of damage a pattern represents.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Scenario {
    /// One corner hidden.
    Triangle,
    /// Both corners of one edge hidden.
    SameSide,
    /// A band across the middle breaking two opposite edges.
    Symmetry,
    /// Two opposite corners hidden.
    Diagonal,
    /// Data area only.
    Inner,
    /// Not checked.
    Custom,
}

impl Scenario {
    /// The five scenarios with a geometric definition.
    pub const CHECKED: [Scenario; 5] = [
        Scenario::Triangle,
        Scenario::SameSide,
        Scenario::Symmetry,
        Scenario::Diagonal,
        Scenario::Inner,
    ];

    /// The name used in files.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Scenario::Triangle => "triangle",
            Scenario::SameSide => "same-side",
            Scenario::Symmetry => "symmetry",
            Scenario::Diagonal => "diagonal",
            Scenario::Inner => "inner",
            Scenario::Custom => "custom",
        }
    }
}

/// Named looks for occluders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Style {
    /// Light grey adhesive tape with a fine grain.
    Tape,
    /// A dark cable or hose with lengthwise sheen.
    Cable,
    /// Mottled dark dirt.
    Dirt,
    /// A pale paint splash.
    Paint,
    /// Brown-grey cardboard.
    Cardboard,
    /// Flat mid grey, no texture.
    Solid,
}

impl Style {
    /// Every style.
    pub const ALL: [Style; 6] = [
        Style::Tape,
        Style::Cable,
        Style::Dirt,
        Style::Paint,
        Style::Cardboard,
        Style::Solid,
    ];

    /// The look of the style.
    #[must_use]
    pub fn appearance(self) -> Appearance {
        let (fill, texture) = match self {
            Style::Tape => (
                0.72,
                Texture::Noise {
                    amplitude: 0.05,
                    scale: 0.012,
                },
            ),
            Style::Cable => (
                0.14,
                Texture::Stripes {
                    amplitude: 0.06,
                    period: 0.05,
                    angle: 0.0,
                },
            ),
            Style::Dirt => (
                0.33,
                Texture::Noise {
                    amplitude: 0.14,
                    scale: 0.03,
                },
            ),
            Style::Paint => (
                0.86,
                Texture::Noise {
                    amplitude: 0.03,
                    scale: 0.05,
                },
            ),
            Style::Cardboard => (
                0.52,
                Texture::Noise {
                    amplitude: 0.06,
                    scale: 0.02,
                },
            ),
            Style::Solid => (0.5, Texture::None),
        };
        Appearance { fill, texture }
    }
}

/// A procedural texture in unit-square coordinates, added to the fill.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum Texture {
    /// Plain fill.
    None,
    /// Smooth value noise of the given amplitude and feature size.
    Noise {
        /// Peak deviation from the fill (reflectance).
        amplitude: f64,
        /// Feature size in unit-square units.
        scale: f64,
    },
    /// Sinusoidal stripes.
    Stripes {
        /// Peak deviation from the fill.
        amplitude: f64,
        /// Stripe period in unit-square units.
        period: f64,
        /// Direction of the stripes' variation, radians from x.
        angle: f64,
    },
}

/// How an occluder looks: a reflectance and a texture.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Appearance {
    /// Mean reflectance, 0 (black) to 1 (white).
    pub fill: f64,
    /// Texture on top of the fill.
    pub texture: Texture,
}

/// Lattice hash for value noise.
fn lattice(seed: u64, i: i64, j: i64) -> f64 {
    let h = crate::rng::mix64(
        seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ (j as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f),
    );
    (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
}

/// Value noise in `[-1, 1]`: hashed lattice values, smoothstep-interpolated
/// (Perlin's "value noise", 1985), two octaves.
fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let octave = |s: u64, x: f64, y: f64| {
        let (xi, yi) = (x.floor(), y.floor());
        let (fx, fy) = (x - xi, y - yi);
        let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
        let (i, j) = (xi as i64, yi as i64);
        let a = lattice(s, i, j) + sx * (lattice(s, i + 1, j) - lattice(s, i, j));
        let b = lattice(s, i, j + 1) + sx * (lattice(s, i + 1, j + 1) - lattice(s, i, j + 1));
        a + sy * (b - a)
    };
    0.7 * octave(seed, x, y) + 0.3 * octave(seed ^ 0xabcd, 2.0 * x + 17.0, 2.0 * y + 31.0)
}

impl Appearance {
    /// Reflectance at unit-square point `(u, v)`, clamped to `[0, 1]`.
    #[must_use]
    pub fn value(&self, seed: u64, [u, v]: [f64; 2]) -> f64 {
        let t = match self.texture {
            Texture::None => 0.0,
            Texture::Noise { amplitude, scale } => {
                amplitude * value_noise(seed, u / scale, v / scale)
            }
            Texture::Stripes {
                amplitude,
                period,
                angle,
            } => {
                let (s, c) = angle.sin_cos();
                amplitude * (std::f64::consts::TAU * (u * c + v * s) / period).sin()
            }
        };
        (self.fill + t).clamp(0.0, 1.0)
    }

    fn validate(&self) -> std::result::Result<(), String> {
        if !(0.0..=1.0).contains(&self.fill) {
            return Err(format!("fill {} is outside 0..=1", self.fill));
        }
        let ok = match self.texture {
            Texture::None => true,
            Texture::Noise { amplitude, scale } => amplitude >= 0.0 && scale > 0.0,
            Texture::Stripes {
                amplitude,
                period,
                angle,
            } => amplitude >= 0.0 && period > 0.0 && angle.is_finite(),
        };
        if ok {
            Ok(())
        } else {
            Err("texture amplitude must be >= 0 and scale/period > 0".into())
        }
    }
}

/// One occluder: a polygon in unit-square coordinates and its look.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Occluder {
    /// Closed polygon, unit-square coordinates.
    pub polygon: Vec<[f64; 2]>,
    /// Look.
    pub appearance: Appearance,
}

/// A set of occluders with a name and a scenario label.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Occlusion {
    /// Name (the file stem for pattern files).
    pub name: String,
    /// Scenario label.
    pub scenario: Scenario,
    /// Occluders, drawn in order.
    pub occluders: Vec<Occluder>,
}

/// Axis-aligned bounding box `[x0, y0, x1, y1]` of polygons.
fn bbox<'a>(polys: impl IntoIterator<Item = &'a Vec<[f64; 2]>>) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in polys.into_iter().flatten() {
        b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    b
}

impl Occlusion {
    fn polygons(&self) -> Vec<Vec<[f64; 2]>> {
        self.occluders.iter().map(|o| o.polygon.clone()).collect()
    }

    /// Fraction of the marker square hidden (area of the union of the
    /// occluders inside the unit square), exact.
    #[must_use]
    pub fn coverage(&self) -> f64 {
        polygon::union_area_in_unit_square(&self.polygons())
    }

    /// Fraction of the marker square each occluder covers on its own
    /// (Sutherland-Hodgman clipping to the square, then the shoelace area).
    #[must_use]
    pub fn occluder_fractions(&self) -> Vec<f64> {
        self.occluders
            .iter()
            .map(|o| polygon::area_in_unit_square(&o.polygon))
            .collect()
    }

    /// Whether the unit-square point `p` is under an occluder.
    #[must_use]
    pub fn hides(&self, p: [f64; 2]) -> bool {
        self.occluders
            .iter()
            .any(|o| polygon::contains(&o.polygon, p))
    }

    /// For each corner TL, BL, BR, TR: is it hidden?
    #[must_use]
    pub fn corners_hidden(&self) -> [bool; 4] {
        UNIT_CORNERS.map(|c| self.hides(c))
    }

    /// For each edge TL-BL (left), BL-BR (bottom), BR-TR (right), TR-TL
    /// (top): is some point strictly between its corners hidden? Checked on
    /// 4001 points per edge.
    #[must_use]
    pub fn edges_broken(&self) -> [bool; 4] {
        std::array::from_fn(|e| {
            let (a, b) = (UNIT_CORNERS[e], UNIT_CORNERS[(e + 1) % 4]);
            (1..4000).any(|k| {
                let t = f64::from(k) / 4000.0;
                self.hides([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])])
            })
        })
    }

    /// Checks that the geometry matches the scenario label (see the module
    /// docs); `Err` says what does not.
    pub fn check_scenario(&self) -> std::result::Result<(), String> {
        let hidden = self.corners_hidden();
        let n = hidden.iter().filter(|&&h| h).count();
        let names = ["TL", "BL", "BR", "TR"];
        let list: Vec<&str> = (0..4).filter(|&i| hidden[i]).map(|i| names[i]).collect();
        let got = format!("hides {n} corner(s) [{}]", list.join(", "));
        match self.scenario {
            Scenario::Custom => Ok(()),
            Scenario::Triangle if n == 1 => Ok(()),
            Scenario::SameSide if n == 2 && (0..4).any(|i| hidden[i] && hidden[(i + 1) % 4]) => {
                Ok(())
            }
            Scenario::Diagonal
                if n == 2 && ((hidden[0] && hidden[2]) || (hidden[1] && hidden[3])) =>
            {
                Ok(())
            }
            Scenario::Symmetry => {
                let broken = self.edges_broken();
                if n == 0 && ((broken[0] && broken[2]) || (broken[1] && broken[3])) {
                    Ok(())
                } else {
                    Err(format!(
                        "a symmetry pattern must hide no corner and break two opposite edges; it {got} and breaks edges {broken:?} (left, bottom, right, top)"
                    ))
                }
            }
            Scenario::Inner => {
                let b = bbox(self.occluders.iter().map(|o| &o.polygon));
                if b[0] >= INNER_BOX[0]
                    && b[1] >= INNER_BOX[1]
                    && b[2] <= INNER_BOX[2]
                    && b[3] <= INNER_BOX[3]
                {
                    Ok(())
                } else {
                    Err(format!(
                        "an inner pattern must lie inside [0.125, 0.875]^2; its bounding box is {b:?}"
                    ))
                }
            }
            Scenario::Triangle => Err(format!(
                "a triangle pattern must hide exactly one corner; it {got}"
            )),
            Scenario::SameSide => Err(format!(
                "a same-side pattern must hide the two corners of one edge; it {got}"
            )),
            Scenario::Diagonal => Err(format!(
                "a diagonal pattern must hide two opposite corners; it {got}"
            )),
        }
    }
}

// ---------------------------------------------------------------------------
// Pattern files

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CircleSpec {
    centre: [f64; 2],
    radius: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EllipseSpec {
    centre: [f64; 2],
    radii: [f64; 2],
    #[serde(default)]
    angle: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OccluderSpec {
    polygon: Option<Vec<[f64; 2]>>,
    circle: Option<CircleSpec>,
    ellipse: Option<EllipseSpec>,
    style: Option<Style>,
    fill: Option<f64>,
    texture: Option<Texture>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PatternFile {
    name: Option<String>,
    scenario: Scenario,
    coverage: Option<f64>,
    #[allow(dead_code)]
    description: Option<String>,
    #[serde(rename = "occluder", default)]
    occluders: Vec<toml::Spanned<OccluderSpec>>,
}

/// How far a pattern file's stated `coverage` may be from the exact one.
pub const STATED_COVERAGE_TOLERANCE: f64 = 0.005;

fn occluder_from_spec(
    o: &OccluderSpec,
    default_style: Style,
) -> std::result::Result<Occluder, String> {
    let shapes = [o.polygon.is_some(), o.circle.is_some(), o.ellipse.is_some()];
    if shapes.iter().filter(|&&s| s).count() != 1 {
        return Err("an occluder needs exactly one of polygon, circle, ellipse".into());
    }
    let polygon = if let Some(p) = &o.polygon {
        if p.len() < 3 {
            return Err(format!(
                "a polygon needs at least 3 vertices, got {}",
                p.len()
            ));
        }
        p.clone()
    } else if let Some(c) = &o.circle {
        if c.radius.is_nan() || c.radius <= 0.0 {
            return Err(format!("circle radius {} must be positive", c.radius));
        }
        polygon::ellipse(c.centre, [c.radius; 2], 0.0, ROUND_VERTICES)
    } else {
        let e = o.ellipse.as_ref().expect("one shape");
        if !(e.radii[0] > 0.0 && e.radii[1] > 0.0) {
            return Err(format!("ellipse radii {:?} must be positive", e.radii));
        }
        polygon::ellipse(e.centre, e.radii, e.angle, ROUND_VERTICES)
    };
    if polygon
        .iter()
        .flatten()
        .any(|v| !v.is_finite() || v.abs() > 100.0)
    {
        return Err("occluder coordinates must be finite and within +-100".into());
    }
    if polygon::area(&polygon) <= 0.0 {
        return Err("occluder has zero area".into());
    }
    let mut appearance = o.style.unwrap_or(default_style).appearance();
    if let Some(f) = o.fill {
        appearance.fill = f;
    }
    if let Some(t) = o.texture {
        appearance.texture = t;
    }
    appearance.validate()?;
    Ok(Occluder {
        polygon,
        appearance,
    })
}

impl Occlusion {
    /// Parses a pattern file's text; `path` is used in error messages and
    /// for the default name (the file stem).
    pub fn from_toml(text: &str, path: &Path) -> Result<Self> {
        let file: PatternFile = toml::from_str(text).map_err(|e| toml_error(path, text, &e))?;
        let at = |offset: usize, message: String| {
            let (line, column) = crate::spec::line_col(text, offset);
            SynthError::Input {
                path: path.to_path_buf(),
                line,
                column,
                message,
            }
        };
        if file.occluders.is_empty() {
            return Err(at(0, "a pattern needs at least one [[occluder]]".into()));
        }
        let mut occluders = Vec::new();
        for (i, o) in file.occluders.iter().enumerate() {
            let occ = occluder_from_spec(o.get_ref(), Style::Solid)
                .map_err(|m| at(o.span().start, format!("occluder[{i}]: {m}")))?;
            occluders.push(occ);
        }
        let name = file.name.clone().unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
        let occ = Occlusion {
            name,
            scenario: file.scenario,
            occluders,
        };
        occ.check_scenario()
            .map_err(|m| at(0, format!("scenario {}: {m}", file.scenario.name())))?;
        let exact = occ.coverage();
        if let Some(stated) = file.coverage {
            if (stated - exact).abs() > STATED_COVERAGE_TOLERANCE {
                return Err(at(
                    0,
                    format!("stated coverage {stated} but the occluders cover {exact:.6} of the marker square"),
                ));
            }
        }
        Ok(occ)
    }

    /// Reads a pattern file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| SynthError::io(path, e))?;
        Self::from_toml(&text, path)
    }
}

/// Pattern files named by `path`: the file itself, or every `*.toml` in a
/// directory, in file-name order.
pub fn pattern_files(path: &Path) -> Result<Vec<PathBuf>> {
    if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|e| SynthError::io(path, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "toml") && p.is_file())
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(SynthError::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::NotFound,
                    "no *.toml pattern files in this directory",
                ),
            ));
        }
        Ok(files)
    } else if path.is_file() {
        Ok(vec![path.to_path_buf()])
    } else {
        Err(SynthError::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "no such pattern file or directory",
            ),
        ))
    }
}

// ---------------------------------------------------------------------------
// Procedural generation

/// How far generated occluders reach beyond the marker square.
const OVERHANG: f64 = 0.25;

/// One of the 8 symmetries of the unit square: `k` quarter turns about its
/// centre, after a mirror in x when `mirror`.
fn symmetry(p: [f64; 2], k: u32, mirror: bool) -> [f64; 2] {
    let (mut x, mut y) = (p[0] - 0.5, p[1] - 0.5);
    if mirror {
        x = -x;
    }
    for _ in 0..k % 4 {
        (x, y) = (-y, x);
    }
    [x + 0.5, y + 0.5]
}

/// The triangle cutting the top-left corner along `cos(phi) x + sin(phi) y
/// = c` with area `cov` inside the square, reaching outside it; `None` when
/// it would reach another corner.
fn corner_triangle(cov: f64, phi: f64) -> Option<Vec<[f64; 2]>> {
    let (ny, nx) = phi.sin_cos();
    let c = (2.0 * cov * nx * ny).sqrt();
    let (a, b) = (c / nx, c / ny);
    if a >= 0.97 || b >= 0.97 {
        return None;
    }
    // Extend the cut line past the two edges, and close it with an apex
    // outside the corner.
    let d = [a, -b];
    let len = d[0].hypot(d[1]);
    let e = 0.08 / len;
    let p1 = [a + d[0] * e, -b * e];
    let p2 = [-a * e, b + b * e];
    Some(vec![p1, [-OVERHANG, -OVERHANG], p2])
}

fn transform(poly: Vec<[f64; 2]>, k: u32, mirror: bool) -> Vec<[f64; 2]> {
    poly.into_iter().map(|p| symmetry(p, k, mirror)).collect()
}

/// A random occlusion of `scenario` hiding exactly `coverage` of the marker
/// square (to float precision), styled `style` (a random style when
/// `None`).
pub fn generate(
    scenario: Scenario,
    coverage: f64,
    style: Option<Style>,
    name: String,
    rng: &mut SynthRng,
) -> Result<Occlusion> {
    let max = max_coverage(scenario);
    if !(coverage > 0.0 && coverage <= max) {
        return Err(SynthError::InvalidParameter {
            name: "occlusion.generate.coverage",
            reason: format!(
                "{coverage} is outside (0, {max}] for the {} scenario",
                scenario.name()
            ),
        });
    }
    let pick_style =
        |rng: &mut SynthRng| style.unwrap_or(Style::ALL[rng.random_range(0..Style::ALL.len())]);
    for _attempt in 0..200 {
        let k = rng.random_range(0..4u32);
        let mirror = rng.random::<bool>();
        let polys: Option<Vec<Vec<[f64; 2]>>> = match scenario {
            Scenario::Triangle => {
                let phi = rng.random_range(0.44..1.13);
                corner_triangle(coverage, phi).map(|t| vec![t])
            }
            Scenario::Diagonal => {
                let split = rng.random_range(0.35..0.65);
                let (p1, p2) = (rng.random_range(0.44..1.13), rng.random_range(0.44..1.13));
                match (
                    corner_triangle(coverage * split, p1),
                    corner_triangle(coverage * (1.0 - split), p2),
                ) {
                    (Some(a), Some(b)) => Some(vec![a, transform(b, 2, false)]),
                    _ => None,
                }
            }
            Scenario::SameSide => {
                // Band over the top edge: y <= h0 + t (x - 0.5), area h0.
                let h0 = coverage;
                let t = rng.random_range(-0.8..0.8) * h0.min(1.0 - h0);
                let h = |x: f64| h0 + t * (x - 0.5);
                (h(0.0) > 0.01 && h(1.0) > 0.01 && h(0.0) < 0.97 && h(1.0) < 0.97).then(|| {
                    let (l, r) = (-OVERHANG, 1.0 + OVERHANG);
                    vec![vec![[l, -OVERHANG], [r, -OVERHANG], [r, h(r)], [l, h(l)]]]
                })
            }
            Scenario::Symmetry => {
                // Vertical band of horizontal width `coverage`, slightly
                // tilted, from above the square to below it.
                let w = coverage;
                let x0 = rng.random_range(0.35..0.65);
                let t = rng.random_range(-0.25..0.25);
                let xc = |y: f64| x0 + t * (y - 0.5);
                let (lo, hi) = (
                    xc(0.0).min(xc(1.0)) - w / 2.0,
                    xc(0.0).max(xc(1.0)) + w / 2.0,
                );
                (lo > 0.03 && hi < 0.97).then(|| {
                    let (top, bot) = (-OVERHANG, 1.0 + OVERHANG);
                    vec![vec![
                        [xc(top) - w / 2.0, top],
                        [xc(top) + w / 2.0, top],
                        [xc(bot) + w / 2.0, bot],
                        [xc(bot) - w / 2.0, bot],
                    ]]
                })
            }
            Scenario::Inner => {
                // A star-shaped blob r(theta) = 1 + sum a_k cos(k theta + p_k),
                // scaled to the coverage.
                let terms: Vec<(f64, f64, f64)> = (2..5)
                    .map(|k| {
                        (
                            f64::from(k),
                            rng.random_range(-0.1..0.1),
                            rng.random_range(0.0..std::f64::consts::TAU),
                        )
                    })
                    .collect();
                let centre = [rng.random_range(0.4..0.6), rng.random_range(0.4..0.6)];
                let unit: Vec<[f64; 2]> = (0..72)
                    .map(|i| {
                        let th = std::f64::consts::TAU * f64::from(i) / 72.0;
                        let r = 1.0
                            + terms
                                .iter()
                                .map(|(k, a, p)| a * (k * th + p).cos())
                                .sum::<f64>();
                        [r * th.cos(), r * th.sin()]
                    })
                    .collect();
                let s = (coverage / polygon::area(&unit)).sqrt();
                let blob: Vec<[f64; 2]> = unit
                    .iter()
                    .map(|p| [centre[0] + s * p[0], centre[1] + s * p[1]])
                    .collect();
                let b = bbox([&blob]);
                (b[0] > INNER_BOX[0] + 0.01
                    && b[1] > INNER_BOX[1] + 0.01
                    && b[2] < INNER_BOX[2] - 0.01
                    && b[3] < INNER_BOX[3] - 0.01)
                    .then(|| vec![blob])
            }
            Scenario::Custom => {
                return Err(SynthError::InvalidParameter {
                    name: "occlusion.generate.scenario",
                    reason: "custom occlusions come from files, not the generator".into(),
                })
            }
        };
        let Some(polys) = polys else { continue };
        let occluders = polys
            .into_iter()
            .map(|p| {
                let mut appearance = pick_style(rng).appearance();
                if let Texture::Stripes { angle, .. } = &mut appearance.texture {
                    *angle = rng.random_range(0.0..std::f64::consts::PI);
                }
                Occluder {
                    polygon: transform(p, k, mirror),
                    appearance,
                }
            })
            .collect();
        let occ = Occlusion {
            name: name.clone(),
            scenario,
            occluders,
        };
        if occ.check_scenario().is_ok() {
            return Ok(occ);
        }
    }
    Err(SynthError::Scene(format!(
        "could not generate a {} occlusion of coverage {coverage}",
        scenario.name()
    )))
}

/// The largest coverage the generator can make for a scenario.
#[must_use]
pub fn max_coverage(scenario: Scenario) -> f64 {
    match scenario {
        Scenario::Triangle => 0.4,
        Scenario::Diagonal => 0.7,
        Scenario::SameSide => 0.9,
        Scenario::Symmetry => 0.6,
        Scenario::Inner => 0.4,
        Scenario::Custom => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn generated_occlusions_have_exact_coverage_and_scenario() {
        let mut rng = SynthRng::seed_from_u64(5);
        for scenario in Scenario::CHECKED {
            for &c in &[0.02, 0.05, 0.1, 0.2, 0.3] {
                for _ in 0..20 {
                    let o = generate(scenario, c, None, "g".into(), &mut rng).unwrap();
                    let got = o.coverage();
                    assert!((got - c).abs() < 1e-9, "{scenario:?} {c}: {got}");
                    o.check_scenario().unwrap();
                }
            }
        }
        assert!(generate(Scenario::Triangle, 0.9, None, "g".into(), &mut rng).is_err());
    }

    #[test]
    fn pattern_file_round_trip_and_errors() {
        let text = r#"
scenario = "triangle"
coverage = 0.08
[[occluder]]
polygon = [[-0.2, -0.2], [0.6, -0.2], [-0.2, 0.6]]
style = "tape"
"#;
        let o = Occlusion::from_toml(text, Path::new("p/t.toml")).unwrap();
        assert_eq!(o.name, "t");
        assert!((o.coverage() - 0.08).abs() < 1e-15);
        assert_eq!(o.corners_hidden(), [true, false, false, false]);
        // Stated coverage far off, a wrong scenario, an unknown key.
        let wrong = text.replace("0.08", "0.2");
        let e = Occlusion::from_toml(&wrong, Path::new("t.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("stated coverage 0.2"), "{e}");
        let wrong = text.replace("triangle", "diagonal");
        assert!(Occlusion::from_toml(&wrong, Path::new("t.toml")).is_err());
        let wrong = text.replace("style", "colour");
        let e = Occlusion::from_toml(&wrong, Path::new("t.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.toml:6:"), "{e}");
    }
}

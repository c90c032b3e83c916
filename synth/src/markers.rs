//! The four marker systems as vector shapes in one common frame.
//!
//! Marker units: the *marker square* spans `[-0.5, 0.5]` in x and y, origin
//! at its centre, x right, y down in the upright marker. The marker square
//! is the CopperTag data square (corners = the tag's corners) or a peer's
//! outer black square (corners = what its detector reports). Its corners
//! in the order TL, BL, BR, TR are [`CORNERS`]. The printed image is the
//! square `[-half_extent, half_extent]`: 1.0 for CopperTag (the printed tag
//! is 2S for a data square S), 0.625 for the peers (10 cells for an 8-cell
//! black square; STag's margin is 0.125 of its square on each side).
//!
//! CopperTag shapes come from [`coppertag::geometry::tag_shapes`], whose tag
//! units are already marker units. Peer shapes are built here from the
//! committed codebooks in `synth/data/peers/` (see the README there), with
//! the same [`Element`] type: rectangles and discs, painted in order.
//! The fractal marker is a committed bitmap (`fractal_5l_6.json`, drawn by
//! nanofractal, see `eval/peers/export_fractal.py`): its marker square is
//! the outer black square, which the bitmap spans exactly.

use std::sync::OnceLock;

use coppertag::geometry::{Element, Paint, Part, Shape};
use coppertag::Family;
use serde::{Deserialize, Serialize};

use crate::error::SynthError;

/// Corners of the marker square in marker units, TL, BL, BR, TR.
pub const CORNERS: [[f64; 2]; 4] = coppertag::geometry::CORNERS;

/// A marker system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MarkerSystem {
    /// CopperTag, families `ct14` and `ct8`.
    Coppertag,
    /// AprilTag 3, family `tag36h11`.
    Apriltag3,
    /// ArUco 3, dictionary `aruco_mip_36h12`.
    Aruco3,
    /// STag, library HD21 (`stag_hd21`).
    Stag,
    /// Fractal marker (nanofractal), configuration FRACTAL_5L_6
    /// (`fractal_5l_6`, one marker: id 0).
    Fractal,
}

impl MarkerSystem {
    /// Every system, in the order used in reports.
    pub const ALL: [MarkerSystem; 5] = [
        MarkerSystem::Coppertag,
        MarkerSystem::Apriltag3,
        MarkerSystem::Aruco3,
        MarkerSystem::Stag,
        MarkerSystem::Fractal,
    ];

    /// The name used in specs and `truth.csv`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MarkerSystem::Coppertag => "coppertag",
            MarkerSystem::Apriltag3 => "apriltag3",
            MarkerSystem::Aruco3 => "aruco3",
            MarkerSystem::Stag => "stag",
            MarkerSystem::Fractal => "fractal",
        }
    }

    /// The family used when a spec names none.
    #[must_use]
    pub fn default_family(self) -> &'static str {
        match self {
            MarkerSystem::Coppertag => "ct14",
            MarkerSystem::Apriltag3 => "tag36h11",
            MarkerSystem::Aruco3 => "aruco_mip_36h12",
            MarkerSystem::Stag => "stag_hd21",
            MarkerSystem::Fractal => "fractal_5l_6",
        }
    }

    /// Half the side of the printed image in marker units.
    #[must_use]
    pub fn half_extent(self) -> f64 {
        match self {
            MarkerSystem::Coppertag => coppertag::geometry::HALF_EXTENT,
            _ => 0.625,
        }
    }
}

#[derive(Deserialize)]
struct SquareGeometry {
    image_cells: u32,
    quiet_zone_cells: u32,
}

#[derive(Deserialize)]
struct SquareBook {
    name: String,
    bits: usize,
    border_bits: usize,
    geometry: SquareGeometry,
    codes: Vec<Vec<u8>>,
}

#[derive(Deserialize)]
struct StagGeometry {
    margin: f64,
    square: f64,
    inner_disc_centre: [f64; 2],
    inner_disc_radius: f64,
    code_circle_radius: f64,
    filler_max_centre_distance: f64,
    filler_radius: f64,
    code_centres: Vec<[f64; 2]>,
}

#[derive(Deserialize)]
struct StagBook {
    name: String,
    nbits: usize,
    geometry: StagGeometry,
    codes: Vec<Vec<u8>>,
}

/// A fractal marker's level: one nested square marker.
#[derive(Debug, Clone, Deserialize)]
pub struct FractalLevel {
    /// Level id as the detector reports it (0 = the outer square).
    pub id: u32,
    /// Side of the level's data grid in cells.
    pub bits: u32,
    /// The level's corners TL, BL, BR, TR in marker units.
    pub corners: [[f64; 2]; 4],
}

#[derive(Deserialize)]
struct FractalBook {
    name: String,
    cells: usize,
    quiet_zone: f64,
    levels: Vec<FractalLevel>,
    /// Row-major, row 0 at the top, `'1'` = black.
    rows: Vec<String>,
}

fn fractal_book() -> &'static FractalBook {
    static FRACTAL: OnceLock<FractalBook> = OnceLock::new();
    FRACTAL.get_or_init(|| {
        let book: FractalBook =
            serde_json::from_str(include_str!("../data/peers/fractal_5l_6.json"))
                .expect("committed fractal marker parses");
        assert_eq!(book.rows.len(), book.cells);
        assert!(book.rows.iter().all(|r| r.len() == book.cells));
        assert!((book.quiet_zone - 0.125).abs() < 1e-12);
        assert_eq!(book.levels.first().map(|l| l.id), Some(0));
        book
    })
}

/// The fractal marker's levels (outer square first), marker units.
#[must_use]
pub fn fractal_levels() -> &'static [FractalLevel] {
    &fractal_book().levels
}

fn square_book(system: MarkerSystem) -> &'static SquareBook {
    static APRIL: OnceLock<SquareBook> = OnceLock::new();
    static ARUCO: OnceLock<SquareBook> = OnceLock::new();
    let (cell, json) = match system {
        MarkerSystem::Apriltag3 => (&APRIL, include_str!("../data/peers/tag36h11.json")),
        _ => (&ARUCO, include_str!("../data/peers/aruco_mip_36h12.json")),
    };
    cell.get_or_init(|| {
        let book: SquareBook = serde_json::from_str(json).expect("committed peer codebook parses");
        let side = book.bits + 2 * book.border_bits;
        assert_eq!(
            book.geometry.image_cells as usize,
            side + 2 * book.geometry.quiet_zone_cells as usize,
            "codebook geometry"
        );
        assert!(book.codes.iter().all(|c| c.len() == book.bits * book.bits));
        book
    })
}

fn stag_book() -> &'static StagBook {
    static STAG: OnceLock<StagBook> = OnceLock::new();
    STAG.get_or_init(|| {
        let book: StagBook = serde_json::from_str(include_str!("../data/peers/stag_hd21.json"))
            .expect("committed STag codebook parses");
        assert_eq!(book.geometry.code_centres.len(), book.nbits);
        assert!(book.codes.iter().all(|c| c.len() == book.nbits));
        assert!((book.geometry.square - 1.0).abs() < 1e-12);
        assert!((book.geometry.margin - 0.125).abs() < 1e-12);
        book
    })
}

/// A marker of some system and id as vector shapes in marker units.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerModel {
    /// Marker system.
    pub system: MarkerSystem,
    /// Family or dictionary name (as the detectors report it).
    pub family: String,
    /// Marker id.
    pub id: u64,
    /// Shapes in painting order, marker units.
    pub elements: Vec<Element>,
    /// Half the side of the printed image, marker units.
    pub half_extent: f64,
}

fn el(part: Part, paint: Paint, shape: Shape) -> Element {
    Element { shape, paint, part }
}

fn rect(h: f64) -> Shape {
    Shape::Rect {
        x0: -h,
        y0: -h,
        x1: h,
        y1: h,
    }
}

impl MarkerModel {
    /// The marker `id` of `system`; `family` defaults to the system's
    /// family (CopperTag: `ct14` or `ct8`; peers accept only their own).
    pub fn new(system: MarkerSystem, family: Option<&str>, id: u64) -> Result<Self, SynthError> {
        let family = family.unwrap_or(system.default_family());
        let bad_family = || SynthError::InvalidParameter {
            name: "family",
            reason: format!(
                "{} markers come in family {}, not '{family}'",
                system.name(),
                system.default_family()
            ),
        };
        let bad_id = |count: usize| SynthError::InvalidParameter {
            name: "id",
            reason: format!("{family} has ids 0..={}, not {id}", count - 1),
        };
        // A peer's code for `id`, from its codebook (family `name`).
        let code_in =
            |name: &str, codes: &'static [Vec<u8>]| -> Result<&'static Vec<u8>, SynthError> {
                if family != name {
                    return Err(bad_family());
                }
                codes.get(id as usize).ok_or_else(|| bad_id(codes.len()))
            };
        let elements = match system {
            MarkerSystem::Coppertag => {
                let fam = Family::by_name(family)?;
                coppertag::geometry::tag_shapes(fam, id)?
            }
            MarkerSystem::Apriltag3 | MarkerSystem::Aruco3 => {
                let book = square_book(system);
                square_marker_elements(book, code_in(&book.name, &book.codes)?)
            }
            MarkerSystem::Stag => {
                let book = stag_book();
                stag_elements(&book.geometry, code_in(&book.name, &book.codes)?)
            }
            MarkerSystem::Fractal => {
                let book = fractal_book();
                if family != book.name {
                    return Err(bad_family());
                }
                if id != 0 {
                    return Err(bad_id(1));
                }
                fractal_elements(book)
            }
        };
        Ok(Self {
            system,
            family: family.to_string(),
            id,
            elements,
            half_extent: system.half_extent(),
        })
    }

    /// The first and last id of `system`'s family `family` (the system's
    /// default family when `None`).
    pub fn id_range(system: MarkerSystem, family: Option<&str>) -> Result<(u64, u64), SynthError> {
        let family = family.unwrap_or(system.default_family());
        let (name, count) = match system {
            MarkerSystem::Coppertag => {
                let fam = Family::by_name(family)?;
                return Ok((fam.min_id(), fam.max_id()));
            }
            MarkerSystem::Apriltag3 | MarkerSystem::Aruco3 => {
                let book = square_book(system);
                (&book.name, book.codes.len())
            }
            MarkerSystem::Stag => {
                let book = stag_book();
                (&book.name, book.codes.len())
            }
            MarkerSystem::Fractal => (&fractal_book().name, 1),
        };
        if family != name.as_str() {
            return Err(SynthError::InvalidParameter {
                name: "family",
                reason: format!(
                    "{} markers come in family {name}, not '{family}'",
                    system.name()
                ),
            });
        }
        Ok((0, count as u64 - 1))
    }

    /// Metres per marker unit when the printed image is `size_m` wide.
    #[must_use]
    pub fn metres_per_unit(&self, size_m: f64) -> f64 {
        size_m / (2.0 * self.half_extent)
    }
}

/// AprilTag / ArUco: white quiet zone, black square, then the white cells
/// (border and black data cells are the black square showing through, so no
/// two black shapes share an edge).
fn square_marker_elements(book: &SquareBook, code: &[u8]) -> Vec<Element> {
    let black_cells = book.bits + 2 * book.border_bits;
    let unit = 1.0 / black_cells as f64;
    let first = -0.5 + book.border_bits as f64 * unit;
    let white: Vec<[f64; 4]> = code
        .iter()
        .enumerate()
        .filter(|(_, &b)| b == 0)
        .map(|(k, _)| {
            let (r, c) = ((k / book.bits) as f64, (k % book.bits) as f64);
            let x0 = first + c * unit;
            let y0 = first + r * unit;
            [x0, y0, x0 + unit, y0 + unit]
        })
        .collect();
    let half = 0.5 * f64::from(book.geometry.image_cells) * unit;
    vec![
        el(Part::Background, Paint::White, rect(half)),
        el(Part::Frame, Paint::Black, rect(0.5)),
        el(Part::Cells, Paint::White, Shape::Rects(white)),
    ]
}

/// Fractal marker: white quiet zone, black square, then the white cells
/// of the bitmap merged into as few rectangles as a greedy sweep finds
/// (runs along a row, extended down while the rows below repeat the run):
/// some 97 000 cells become a few thousand rectangles.
fn fractal_elements(book: &FractalBook) -> Vec<Element> {
    let n = book.cells;
    let unit = 1.0 / n as f64;
    let mut white: Vec<Vec<bool>> = book
        .rows
        .iter()
        .map(|r| r.bytes().map(|b| b == b'0').collect())
        .collect();
    let mut rects = Vec::new();
    for r in 0..n {
        let mut c = 0;
        while c < n {
            if !white[r][c] {
                c += 1;
                continue;
            }
            let c0 = c;
            while c < n && white[r][c] {
                c += 1;
            }
            let mut r1 = r + 1;
            while r1 < n && (c0..c).all(|k| white[r1][k]) {
                r1 += 1;
            }
            for row in white.iter_mut().take(r1).skip(r) {
                row[c0..c].iter_mut().for_each(|w| *w = false);
            }
            rects.push([
                -0.5 + c0 as f64 * unit,
                -0.5 + r as f64 * unit,
                -0.5 + c as f64 * unit,
                -0.5 + r1 as f64 * unit,
            ]);
        }
    }
    vec![
        el(Part::Background, Paint::White, rect(0.5 + book.quiet_zone)),
        el(Part::Frame, Paint::Black, rect(0.5)),
        el(Part::Cells, Paint::White, Shape::Rects(rects)),
    ]
}

/// STag: white margin, black square, white inner disc, black code circles
/// and the filler discs that join neighbouring circles.
fn stag_elements(g: &StagGeometry, code: &[u8]) -> Vec<Element> {
    let c0 = [g.inner_disc_centre[0] - 0.5, g.inner_disc_centre[1] - 0.5];
    let mut out = vec![
        el(Part::Background, Paint::White, rect(0.5 + g.margin)),
        el(Part::Frame, Paint::Black, rect(0.5)),
        el(
            Part::DataSquare,
            Paint::White,
            Shape::Disc {
                cx: c0[0],
                cy: c0[1],
                r: g.inner_disc_radius,
            },
        ),
    ];
    let black: Vec<[f64; 2]> = code
        .iter()
        .zip(&g.code_centres)
        .filter(|(&b, _)| b == 1)
        .map(|(_, &[x, y])| [x - 0.5, y - 0.5])
        .collect();
    for &[x, y] in &black {
        out.push(el(
            Part::Cells,
            Paint::Black,
            Shape::Disc {
                cx: x,
                cy: y,
                r: g.code_circle_radius,
            },
        ));
    }
    for (i, a) in black.iter().enumerate() {
        for b in &black[i + 1..] {
            if (a[0] - b[0]).hypot(a[1] - b[1]) < g.filler_max_centre_distance {
                out.push(el(
                    Part::Cells,
                    Paint::Black,
                    Shape::Disc {
                        cx: 0.5 * (a[0] + b[0]),
                        cy: 0.5 * (a[1] + b[1]),
                        r: g.filler_radius,
                    },
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_system_builds_and_checks_ids() {
        for sys in MarkerSystem::ALL {
            let m = MarkerModel::new(sys, None, 0).unwrap();
            assert_eq!(m.family, sys.default_family());
            assert!(m.elements.len() >= 3);
            assert!(MarkerModel::new(sys, None, 100_000).is_err());
        }
        assert!(MarkerModel::new(MarkerSystem::Coppertag, Some("ct8"), 65535).is_ok());
        assert!(MarkerModel::new(MarkerSystem::Stag, Some("tag36h11"), 0).is_err());
        assert!(MarkerModel::new(MarkerSystem::Stag, None, 11).is_ok());
        assert!(MarkerModel::new(MarkerSystem::Stag, None, 12).is_err());
    }

    #[test]
    fn fractal_marker_is_its_bitmap() {
        let m = MarkerModel::new(MarkerSystem::Fractal, None, 0).unwrap();
        assert!(MarkerModel::new(MarkerSystem::Fractal, None, 1).is_err());
        assert!((m.metres_per_unit(0.1) - 0.08).abs() < 1e-15);
        let book = fractal_book();
        let Shape::Rects(white) = &m.elements[2].shape else {
            panic!()
        };
        // Every cell centre is white exactly when some rectangle holds it.
        let n = book.cells;
        for (r, row) in book.rows.iter().enumerate() {
            for (c, b) in row.bytes().enumerate() {
                let x = -0.5 + (c as f64 + 0.5) / n as f64;
                let y = -0.5 + (r as f64 + 0.5) / n as f64;
                let inside = white
                    .iter()
                    .any(|q| q[0] < x && x < q[2] && q[1] < y && y < q[3]);
                assert_eq!(inside, b == b'0', "cell ({r}, {c})");
            }
        }
        assert!(white.len() < 5000, "{} rectangles", white.len());
        assert_eq!(fractal_levels().len(), 5);
        assert_eq!(fractal_levels()[0].corners, CORNERS);
    }

    #[test]
    fn printed_sizes() {
        let ct = MarkerModel::new(MarkerSystem::Coppertag, None, 42).unwrap();
        // 0.1 m print: S = 0.05 m, one marker unit.
        assert!((ct.metres_per_unit(0.1) - 0.05).abs() < 1e-15);
        let at = MarkerModel::new(MarkerSystem::Apriltag3, None, 0).unwrap();
        // 0.1 m print: black square 8/10 of it.
        assert!((at.metres_per_unit(0.1) - 0.08).abs() < 1e-15);
        // AprilTag tag36h11 id 0: first data row 0,0,1,0,1,0 -> cells 0, 1, 3, 5 white.
        let Shape::Rects(white) = &at.elements[2].shape else {
            panic!()
        };
        assert_eq!(white[0], [-0.375, -0.375, -0.25, -0.25]);
        assert_eq!(white[2][0], -0.375 + 3.0 * 0.125);
    }
}

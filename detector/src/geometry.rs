//! A tag as vector shapes, in tag units.
//!
//! Tag units: the side S of the white data square is 1, the origin is the tag
//! centre, x right, y down. The printed tag spans `[-1, 1]` in both axes.
//! Shapes are listed in painting order (later ones paint over earlier ones),
//! exactly as the format contract's "Geometry" section draws them, so one
//! list drives the SVG generator, the PNG rasteriser and the camera renderer.

use crate::digits;
use crate::family::Family;
use crate::grid_code::encode_cells;
use crate::Result;

/// Half the side of the printed tag in tag units (the tag is 2S wide).
pub const HALF_EXTENT: f64 = 1.0;

/// Radius of the white disc, r = sqrt(2)/2.
pub const R: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// Frame width b = S/8.
pub const B: f64 = 0.125;

/// Corners of the data square in the canonical order TL, BL, BR, TR.
pub const CORNERS: [[f64; 2]; 4] = [[-0.5, -0.5], [-0.5, 0.5], [0.5, 0.5], [0.5, -0.5]];

/// Paint of a shape.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paint {
    /// Printed black.
    Black,
    /// Paper white.
    White,
}

/// What part of the tag a shape is; lets a renderer or a test pick parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// The white 2S x 2S background.
    Background,
    /// Outer black disc, white disc, the bars joining them and the annulus.
    Rings,
    /// Black frame around the data square.
    Frame,
    /// White data square.
    DataSquare,
    /// The two black ears beside the frame.
    Ears,
    /// The printed id.
    IdText,
    /// The black data cells.
    Cells,
    /// The centre checker (black square with a white disc).
    Checker,
}

/// One vector shape in tag units.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Axis-aligned rectangle `[x0, x1] x [y0, y1]`.
    Rect {
        /// Left.
        x0: f64,
        /// Top.
        y0: f64,
        /// Right.
        x1: f64,
        /// Bottom.
        y1: f64,
    },
    /// Disc.
    Disc {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Radius.
        r: f64,
    },
    /// Ring between two radii.
    Annulus {
        /// Centre x.
        cx: f64,
        /// Centre y.
        cy: f64,
        /// Inner radius.
        r_in: f64,
        /// Outer radius.
        r_out: f64,
    },
    /// Union of axis-aligned rectangles filled as one path, so that adjacent
    /// cells show no anti-aliasing seam between them.
    Rects(Vec<[f64; 4]>),
    /// Polylines stroked with round caps and joins (the id digits).
    Strokes {
        /// Centre lines.
        lines: Vec<Vec<[f64; 2]>>,
        /// Stroke width.
        width: f64,
    },
}

/// A shape with its paint and part.
#[derive(Debug, Clone, PartialEq)]
pub struct Element {
    /// Geometry.
    pub shape: Shape,
    /// Colour.
    pub paint: Paint,
    /// Which part of the tag it draws.
    pub part: Part,
}

/// Height of the printed id digits in tag units.
pub const TEXT_HEIGHT: f64 = 0.085;

fn el(part: Part, paint: Paint, shape: Shape) -> Element {
    Element { shape, paint, part }
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Shape {
    Shape::Rect { x0, y0, x1, y1 }
}

/// Cell `(row, col)` of an `n x n` grid as a rectangle in tag units.
pub fn cell_rect(n: usize, row: usize, col: usize) -> [f64; 4] {
    let step = 1.0 / (n as f64 + 2.0);
    let x0 = -0.5 + (1.0 + col as f64) * step;
    let y0 = -0.5 + (1.0 + row as f64) * step;
    [x0, y0, x0 + step, y0 + step]
}

/// The shapes of tag `id` of `family`, in painting order.
pub fn tag_shapes(family: &Family, id: u64) -> Result<Vec<Element>> {
    let cells = encode_cells(family, id)?;
    let n = family.grid();
    let step = 1.0 / (n as f64 + 2.0);
    let (r, b) = (R, B);
    let ear_x = 0.5 + 1.5 * b;
    let ring = r + b * std::f64::consts::SQRT_2;
    let (text, text_width) = digits::text_strokes(id, 0.0, r, TEXT_HEIGHT);
    let black_cells: Vec<[f64; 4]> = cells
        .iter()
        .enumerate()
        .filter(|(_, &black)| black)
        .map(|(c, _)| cell_rect(n, c / n, c % n))
        .collect();
    let k = family.checker_cells() as f64 * step;
    use Paint::{Black, White};
    Ok(vec![
        el(Part::Background, White, rect(-1.0, -1.0, 1.0, 1.0)),
        el(
            Part::Rings,
            Black,
            Shape::Disc {
                cx: 0.0,
                cy: 0.0,
                r: r + b,
            },
        ),
        el(
            Part::Rings,
            White,
            Shape::Disc {
                cx: 0.0,
                cy: 0.0,
                r,
            },
        ),
        el(Part::Rings, Black, rect(-0.5, -r, 0.5, r)),
        el(Part::Rings, Black, rect(-r, 1.0 / 13.0, r, 0.5)),
        el(
            Part::Frame,
            Black,
            rect(-0.5 - b, -0.5 - b, 0.5 + b, 0.5 + b),
        ),
        el(Part::DataSquare, White, rect(-0.5, -0.5, 0.5, 0.5)),
        el(Part::Ears, Black, rect(-r, -0.5, -ear_x, 1.0 / 6.0)),
        el(Part::Ears, Black, rect(ear_x, -0.5, r, 1.0 / 6.0)),
        el(
            Part::Rings,
            White,
            Shape::Annulus {
                cx: 0.0,
                cy: 0.0,
                r_in: ring - b / 2.0,
                r_out: ring + b / 2.0,
            },
        ),
        el(
            Part::IdText,
            White,
            Shape::Strokes {
                lines: text,
                width: text_width,
            },
        ),
        el(Part::Cells, Black, Shape::Rects(black_cells)),
        el(
            Part::Checker,
            Black,
            rect(-k / 2.0, -k / 2.0, k / 2.0, k / 2.0),
        ),
        el(
            Part::Checker,
            White,
            Shape::Disc {
                cx: 0.0,
                cy: 0.0,
                r: k / 3.0,
            },
        ),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_centres_follow_the_contract() {
        // x = -S/2 + (1.5 + j) * step.
        let [x0, y0, x1, y1] = cell_rect(14, 2, 5);
        let step = 1.0 / 16.0;
        assert!(((x0 + x1) / 2.0 - (-0.5 + 6.5 * step)).abs() < 1e-12);
        assert!(((y0 + y1) / 2.0 - (-0.5 + 3.5 * step)).abs() < 1e-12);
    }

    #[test]
    fn shapes_are_in_painting_order() {
        let shapes = tag_shapes(Family::ct8(), 42).unwrap();
        assert_eq!(shapes[0].part, Part::Background);
        assert_eq!(shapes.last().unwrap().part, Part::Checker);
        assert!(tag_shapes(Family::ct8(), 70000).is_err());
    }
}

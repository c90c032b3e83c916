//! Rasterising vector tag shapes with tiny-skia through any point mapping.
//!
//! Every shape is flattened to polygons in tag units first and each vertex is
//! mapped on its own, so the same code draws a flat print-ready PNG (an
//! affine map) and a tag seen through a camera with lens distortion (a map
//! that bends straight lines): circles are cut finely enough that the chord
//! error stays under a hundredth of a pixel, and straight edges are cut into
//! short pieces so that a bending map is followed. tiny-skia then fills the
//! polygons with its analytic anti-aliasing.

use coppertag::geometry::{Element, Paint, Shape};
use image::GrayImage;
use tiny_skia::{FillRule, LineCap, LineJoin, PathBuilder, PathSegment, Pixmap, Stroke, Transform};

/// A mapping from tag units to output pixels.
///
/// Output coordinates are tiny-skia's: pixel `(i, j)` covers
/// `[i, i + 1] x [j, j + 1]`, so a pixel-centre coordinate is this minus 0.5.
pub trait TagToPixel: Sync {
    /// Maps a point in tag units; `None` when it cannot be seen (behind the
    /// camera).
    fn map(&self, p: [f64; 2]) -> Option<[f64; 2]>;
    /// Largest pixels-per-tag-unit scale anywhere on the tag; sets how finely
    /// shapes are flattened.
    fn scale(&self) -> f64;
    /// Whether straight lines stay straight (no lens distortion): straight
    /// edges then need no subdivision.
    fn preserves_lines(&self) -> bool {
        true
    }
}

/// The flat map of a printed tag: the 2S x 2S square onto a `px` x `px`
/// image.
#[derive(Debug, Clone, Copy)]
pub struct FlatTag {
    /// Side of the output image in pixels.
    pub px: u32,
}

impl TagToPixel for FlatTag {
    fn map(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        let s = f64::from(self.px) / 2.0;
        Some([(p[0] + 1.0) * s, (p[1] + 1.0) * s])
    }
    fn scale(&self) -> f64 {
        f64::from(self.px) / 2.0
    }
}

/// Chord tolerance in output pixels for curves.
const CURVE_TOLERANCE_PX: f64 = 0.01;
/// Longest straight piece, in output pixels, when the map bends lines.
const MAX_EDGE_PX: f64 = 2.0;

fn circle_points(cx: f64, cy: f64, r: f64, scale: f64) -> Vec<[f64; 2]> {
    let r_px = (r * scale).max(1e-6);
    // Sagitta of a chord spanning angle a: r (1 - cos(a/2)) <= tol.
    let half = (1.0 - (CURVE_TOLERANCE_PX / r_px).min(1.0)).acos();
    let n = ((std::f64::consts::PI / half.max(1e-4)).ceil() as usize).clamp(16, 20_000);
    (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * i as f64 / n as f64;
            [cx + r * t.cos(), cy + r * t.sin()]
        })
        .collect()
}

fn subdivide(poly: &[[f64; 2]], scale: f64, bend: bool) -> Vec<[f64; 2]> {
    if !bend {
        return poly.to_vec();
    }
    let mut out = Vec::with_capacity(poly.len() * 4);
    for (i, &a) in poly.iter().enumerate() {
        let b = poly[(i + 1) % poly.len()];
        let len = ((b[0] - a[0]).hypot(b[1] - a[1]) * scale / MAX_EDGE_PX).ceil();
        let steps = (len as usize).max(1);
        for s in 0..steps {
            let t = s as f64 / steps as f64;
            out.push([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]);
        }
    }
    out
}

fn rect_points(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<[f64; 2]> {
    vec![[x0, y0], [x0, y1], [x1, y1], [x1, y0]]
}

/// Closed polygons (tag units) that make up a shape, with the fill rule
/// that combines them.
fn shape_polygons(shape: &Shape, scale: f64) -> (Vec<Vec<[f64; 2]>>, FillRule) {
    match shape {
        Shape::Rect { x0, y0, x1, y1 } => {
            (vec![rect_points(*x0, *y0, *x1, *y1)], FillRule::Winding)
        }
        Shape::Disc { cx, cy, r } => (vec![circle_points(*cx, *cy, *r, scale)], FillRule::Winding),
        Shape::Annulus {
            cx,
            cy,
            r_in,
            r_out,
        } => (
            vec![
                circle_points(*cx, *cy, *r_out, scale),
                circle_points(*cx, *cy, *r_in, scale),
            ],
            FillRule::EvenOdd,
        ),
        Shape::Rects(rects) => (
            rects
                .iter()
                .map(|&[x0, y0, x1, y1]| rect_points(x0, y0, x1, y1))
                .collect(),
            FillRule::Winding,
        ),
        Shape::Strokes { lines, width } => {
            (stroke_polygons(lines, *width, scale), FillRule::Winding)
        }
    }
}

/// Outlines of round-capped strokes, flattened, in tag units.
fn stroke_polygons(lines: &[Vec<[f64; 2]>], width: f64, scale: f64) -> Vec<Vec<[f64; 2]>> {
    // tiny-skia strokes in f32; working in pixel-sized units keeps its
    // flattening and precision in the range it is built for.
    let mut out = Vec::new();
    for line in lines {
        let mut pb = PathBuilder::new();
        for (i, p) in line.iter().enumerate() {
            let (x, y) = ((p[0] * scale) as f32, (p[1] * scale) as f32);
            if i == 0 {
                pb.move_to(x, y);
            } else {
                pb.line_to(x, y);
            }
        }
        let Some(path) = pb.finish() else { continue };
        let stroke = Stroke {
            width: (width * scale) as f32,
            line_cap: LineCap::Round,
            line_join: LineJoin::Round,
            ..Stroke::default()
        };
        let Some(outline) = path.stroke(&stroke, 4.0) else {
            continue;
        };
        let mut poly: Vec<[f64; 2]> = Vec::new();
        let mut last = [0.0f64; 2];
        let to_tag = |p: tiny_skia::Point| [f64::from(p.x) / scale, f64::from(p.y) / scale];
        let flush = |poly: &mut Vec<[f64; 2]>, out: &mut Vec<Vec<[f64; 2]>>| {
            if poly.len() >= 3 {
                out.push(std::mem::take(poly));
            } else {
                poly.clear();
            }
        };
        for seg in outline.segments() {
            match seg {
                PathSegment::MoveTo(p) => {
                    flush(&mut poly, &mut out);
                    last = to_tag(p);
                    poly.push(last);
                }
                PathSegment::LineTo(p) => {
                    last = to_tag(p);
                    poly.push(last);
                }
                PathSegment::QuadTo(c, p) => {
                    let (c, p) = (to_tag(c), to_tag(p));
                    for s in 1..=8 {
                        let t = f64::from(s) / 8.0;
                        let u = 1.0 - t;
                        poly.push(std::array::from_fn(|k| {
                            u * u * last[k] + 2.0 * u * t * c[k] + t * t * p[k]
                        }));
                    }
                    last = p;
                }
                PathSegment::CubicTo(c1, c2, p) => {
                    let (c1, c2, p) = (to_tag(c1), to_tag(c2), to_tag(p));
                    for s in 1..=8 {
                        let t = f64::from(s) / 8.0;
                        let u = 1.0 - t;
                        poly.push(std::array::from_fn(|k| {
                            u * u * u * last[k]
                                + 3.0 * u * u * t * c1[k]
                                + 3.0 * u * t * t * c2[k]
                                + t * t * t * p[k]
                        }));
                    }
                    last = p;
                }
                PathSegment::Close => flush(&mut poly, &mut out),
            }
        }
        flush(&mut poly, &mut out);
    }
    out
}

/// The closed polygons of one element mapped to output pixels (tiny-skia
/// coordinates, see [`TagToPixel`]), flattened and subdivided as described
/// in the module docs, with the fill rule that combines them. `None` when
/// any vertex cannot be mapped.
///
/// This is the geometry both rasterisers draw: tiny-skia through
/// [`element_path`], and the exact-area rasteriser of
/// [`crate::coverage`] that the camera renderer uses.
pub fn element_polygons(
    el: &Element,
    map: &dyn TagToPixel,
) -> Option<(Vec<Vec<[f64; 2]>>, FillRule)> {
    let scale = map.scale();
    let (polys, rule) = shape_polygons(&el.shape, scale);
    let bend = !map.preserves_lines();
    let mut out = Vec::with_capacity(polys.len());
    for poly in polys {
        let poly = subdivide(&poly, scale, bend);
        let mapped: Option<Vec<[f64; 2]>> = poly.iter().map(|&p| map.map(p)).collect();
        out.push(mapped?);
    }
    Some((out, rule))
}

/// Maps a closed polygon given in tag (marker) units to output pixels,
/// subdividing its edges first when the map bends lines, exactly as element
/// shapes are; `None` when a vertex cannot be mapped.
pub fn map_polygon(poly: &[[f64; 2]], map: &dyn TagToPixel) -> Option<Vec<[f64; 2]>> {
    subdivide(poly, map.scale(), !map.preserves_lines())
        .iter()
        .map(|&p| map.map(p))
        .collect()
}

/// Builds the tiny-skia path of one element under a map; `None` when any
/// vertex cannot be mapped or the path is empty.
pub fn element_path(el: &Element, map: &dyn TagToPixel) -> Option<(tiny_skia::Path, FillRule)> {
    let (polys, rule) = element_polygons(el, map)?;
    let mut pb = PathBuilder::new();
    for poly in polys {
        for (i, q) in poly.iter().enumerate() {
            let (x, y) = (q[0] as f32, q[1] as f32);
            if i == 0 {
                pb.move_to(x, y);
            } else {
                pb.line_to(x, y);
            }
        }
        pb.close();
    }
    Some((pb.finish()?, rule))
}

/// Paints elements onto a pixmap under a map, with `colour` choosing the
/// RGBA of each paint. Elements that cannot be mapped are skipped.
pub fn draw_elements(
    pixmap: &mut Pixmap,
    elements: &[Element],
    map: &dyn TagToPixel,
    colour: impl Fn(Paint) -> tiny_skia::Color,
) {
    for el in elements {
        let Some((path, rule)) = element_path(el, map) else {
            continue;
        };
        let mut paint = tiny_skia::Paint::default();
        paint.set_color(colour(el.paint));
        paint.anti_alias = true;
        pixmap.fill_path(&path, &paint, rule, Transform::identity(), None);
    }
}

/// Black ink and white paper.
pub fn black_and_white(p: Paint) -> tiny_skia::Color {
    match p {
        Paint::Black => tiny_skia::Color::BLACK,
        Paint::White => tiny_skia::Color::WHITE,
    }
}

/// The grey channel of an opaque pixmap.
pub fn to_gray(pixmap: &Pixmap) -> GrayImage {
    let data: Vec<u8> = pixmap.data().chunks_exact(4).map(|p| p[0]).collect();
    GrayImage::from_raw(pixmap.width(), pixmap.height(), data)
        .expect("pixmap size matches its data")
}

/// Tag image sides, in pixels, that the generators (`coppertag generate`,
/// Python's `coppertag.generate`) accept: from 16 (the data square is then 8
/// px, under one pixel per cell of ct14: smaller is not a tag any more) to
/// 16384 (a 16k x 16k grey image is 256 MB).
pub const TAG_PX_RANGE: std::ops::RangeInclusive<u32> = 16..=16_384;

/// Renders the printed tag (the whole 2S x 2S square) as a `px` x `px`
/// anti-aliased grey image. `None` when `px` is zero or too large for
/// tiny-skia.
pub fn tag_image(elements: &[Element], px: u32) -> Option<GrayImage> {
    let mut pixmap = Pixmap::new(px, px)?;
    pixmap.fill(tiny_skia::Color::WHITE);
    draw_elements(&mut pixmap, elements, &FlatTag { px }, black_and_white);
    Some(to_gray(&pixmap))
}

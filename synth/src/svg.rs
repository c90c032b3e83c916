//! Print-ready SVG of tags and tag sheets.
//!
//! Documents are sized in millimetres (`width="100mm"`) with a viewBox in
//! millimetres, so any printer driver or browser prints them at the physical
//! size; each tag is a group that scales the tag-unit geometry, so the
//! shapes are exact (circles stay circles, cells share edges without seams).

use std::fmt::Write as _;

use coppertag::geometry::{tag_shapes, Element, Paint, Shape};
use coppertag::Family;

use crate::SynthError;

fn colour(p: Paint) -> &'static str {
    match p {
        Paint::Black => "#000",
        Paint::White => "#fff",
    }
}

/// Formats a coordinate compactly and deterministically.
fn num(v: f64) -> String {
    let s = format!("{v:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

fn circle_path(d: &mut String, cx: f64, cy: f64, r: f64) {
    let _ = write!(
        d,
        "M{} {}A{r} {r} 0 1 0 {} {}A{r} {r} 0 1 0 {} {}Z",
        num(cx + r),
        num(cy),
        num(cx - r),
        num(cy),
        num(cx + r),
        num(cy),
        r = num(r)
    );
}

fn element_svg(out: &mut String, el: &Element) {
    let fill = colour(el.paint);
    match &el.shape {
        Shape::Rect { x0, y0, x1, y1 } => {
            let _ = writeln!(
                out,
                r#"<rect x="{}" y="{}" width="{}" height="{}" fill="{fill}"/>"#,
                num(*x0),
                num(*y0),
                num(x1 - x0),
                num(y1 - y0)
            );
        }
        Shape::Disc { cx, cy, r } => {
            let _ = writeln!(
                out,
                r#"<circle cx="{}" cy="{}" r="{}" fill="{fill}"/>"#,
                num(*cx),
                num(*cy),
                num(*r)
            );
        }
        Shape::Annulus {
            cx,
            cy,
            r_in,
            r_out,
        } => {
            let mut d = String::new();
            circle_path(&mut d, *cx, *cy, *r_out);
            circle_path(&mut d, *cx, *cy, *r_in);
            let _ = writeln!(out, r#"<path d="{d}" fill="{fill}" fill-rule="evenodd"/>"#);
        }
        Shape::Rects(rects) => {
            if rects.is_empty() {
                return;
            }
            let mut d = String::new();
            for &[x0, y0, x1, y1] in rects {
                let _ = write!(
                    d,
                    "M{} {}H{}V{}H{}Z",
                    num(x0),
                    num(y0),
                    num(x1),
                    num(y1),
                    num(x0)
                );
            }
            let _ = writeln!(out, r#"<path d="{d}" fill="{fill}"/>"#);
        }
        Shape::Strokes { lines, width } => {
            let mut d = String::new();
            for line in lines {
                for (i, p) in line.iter().enumerate() {
                    let _ = write!(
                        d,
                        "{}{} {}",
                        if i == 0 { 'M' } else { 'L' },
                        num(p[0]),
                        num(p[1])
                    );
                }
            }
            let _ = writeln!(
                out,
                r#"<path d="{d}" fill="none" stroke="{fill}" stroke-width="{}" stroke-linecap="round" stroke-linejoin="round"/>"#,
                num(*width)
            );
        }
    }
}

/// The tag's shapes as an SVG group placed with its top-left corner at
/// `(x_mm, y_mm)` and printed `size_mm` wide.
fn tag_group(out: &mut String, elements: &[Element], x_mm: f64, y_mm: f64, size_mm: f64) {
    let half = size_mm / 2.0;
    let _ = writeln!(
        out,
        r#"<g transform="translate({} {}) scale({})">"#,
        num(x_mm + half),
        num(y_mm + half),
        num(half)
    );
    for el in elements {
        element_svg(out, el);
    }
    out.push_str("</g>\n");
}

fn check_size(size_mm: f64) -> Result<(), SynthError> {
    if !(size_mm.is_finite() && size_mm > 0.0 && size_mm <= 10_000.0) {
        return Err(SynthError::InvalidParameter {
            name: "size",
            reason: format!("{size_mm} mm is not a printable size (0 < size <= 10 m)"),
        });
    }
    Ok(())
}

/// One tag as a standalone SVG document `size_mm` wide and high (the whole
/// printed square; the data square is half of it).
pub fn tag_svg(family: &Family, id: u64, size_mm: f64) -> Result<String, SynthError> {
    check_size(size_mm)?;
    let elements = tag_shapes(family, id)?;
    let mut out = String::new();
    let s = num(size_mm);
    let _ = writeln!(
        out,
        r#"<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" width="{s}mm" height="{s}mm" viewBox="0 0 {s} {s}">
<title>CopperTag {} id {id}, {s} mm</title>"#,
        family.name()
    );
    tag_group(&mut out, &elements, 0.0, 0.0, size_mm);
    out.push_str("</svg>\n");
    Ok(out)
}

/// Paper sizes for tag sheets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paper {
    /// ISO A4, 210 x 297 mm.
    A4,
    /// ISO A3, 297 x 420 mm.
    A3,
    /// US Letter, 8.5 x 11 in.
    Letter,
}

impl Paper {
    /// Width and height in millimetres.
    pub fn size_mm(self) -> (f64, f64) {
        match self {
            Paper::A4 => (210.0, 297.0),
            Paper::A3 => (297.0, 420.0),
            Paper::Letter => (215.9, 279.4),
        }
    }

    /// Parses `a4`, `a3` or `letter`.
    pub fn parse(s: &str) -> Result<Self, SynthError> {
        match s.to_ascii_lowercase().as_str() {
            "a4" => Ok(Paper::A4),
            "a3" => Ok(Paper::A3),
            "letter" => Ok(Paper::Letter),
            _ => Err(SynthError::InvalidParameter {
                name: "sheet",
                reason: format!("unknown paper '{s}' (known: a4, a3, letter)"),
            }),
        }
    }
}

const MARGIN_MM: f64 = 12.0;
const GAP_MM: f64 = 6.0;
const LABEL_MM: f64 = 5.0;
const HEADER_MM: f64 = 8.0;
const FOOTER_MM: f64 = 14.0;

/// Tags laid out on pages of `paper`, with a label under each tag, a header
/// naming the page and a scale bar to check the print scale. Returns one
/// SVG document per page.
pub fn sheet_svgs(
    family: &Family,
    ids: &[u64],
    size_mm: f64,
    paper: Paper,
) -> Result<Vec<String>, SynthError> {
    check_size(size_mm)?;
    if ids.is_empty() {
        return Err(SynthError::InvalidParameter {
            name: "ids",
            reason: "no ids to lay out".into(),
        });
    }
    for &id in ids {
        family.check_id(id)?;
    }
    let (w, h) = paper.size_mm();
    let usable_w = w - 2.0 * MARGIN_MM;
    let usable_h = h - 2.0 * MARGIN_MM - HEADER_MM - FOOTER_MM;
    let cols = ((usable_w + GAP_MM) / (size_mm + GAP_MM)).floor() as usize;
    let rows = ((usable_h + GAP_MM) / (size_mm + LABEL_MM + GAP_MM)).floor() as usize;
    if cols == 0 || rows == 0 {
        return Err(SynthError::InvalidParameter {
            name: "size",
            reason: format!(
                "a {} mm tag does not fit on {paper:?} paper with its margins",
                num(size_mm)
            ),
        });
    }
    let per_page = cols * rows;
    let pages = ids.len().div_ceil(per_page);
    // Centre the grid horizontally.
    let grid_w = cols as f64 * size_mm + (cols - 1) as f64 * GAP_MM;
    let x0 = (w - grid_w) / 2.0;
    let y0 = MARGIN_MM + HEADER_MM;
    let mut docs = Vec::with_capacity(pages);
    for (page, chunk) in ids.chunks(per_page).enumerate() {
        let mut out = String::new();
        let _ = writeln!(
            out,
            r##"<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" width="{w}mm" height="{h}mm" viewBox="0 0 {w} {h}" font-family="DejaVu Sans, Helvetica, Arial, sans-serif">
<rect width="{w}" height="{h}" fill="#fff"/>
<text x="{}" y="{}" font-size="4">CopperTag {} - {} mm tags (data square {} mm) - page {}/{pages}</text>"##,
            num(MARGIN_MM),
            num(MARGIN_MM + 4.0),
            family.name(),
            num(size_mm),
            num(size_mm / 2.0),
            page + 1,
            w = num(w),
            h = num(h),
        );
        for (i, &id) in chunk.iter().enumerate() {
            let (r, c) = (i / cols, i % cols);
            let x = x0 + c as f64 * (size_mm + GAP_MM);
            let y = y0 + r as f64 * (size_mm + LABEL_MM + GAP_MM);
            tag_group(&mut out, &tag_shapes(family, id)?, x, y, size_mm);
            let _ = writeln!(
                out,
                r#"<text x="{}" y="{}" font-size="3" text-anchor="middle">{} id {id}</text>"#,
                num(x + size_mm / 2.0),
                num(y + size_mm + 3.5),
                family.name()
            );
        }
        scale_bar(&mut out, MARGIN_MM, h - MARGIN_MM - 4.0);
        out.push_str("</svg>\n");
        docs.push(out);
    }
    Ok(docs)
}

/// A 50 mm bar with centimetre ticks: measure it after printing to check
/// that the printer did not scale the page.
fn scale_bar(out: &mut String, x: f64, y: f64) {
    let _ = writeln!(
        out,
        r##"<g stroke="#000" stroke-width="0.3"><line x1="{x}" y1="{y}" x2="{}" y2="{y}"/>"##,
        num(x + 50.0),
        x = num(x),
        y = num(y)
    );
    for cm in 0..=5 {
        let tx = x + 10.0 * f64::from(cm);
        let _ = writeln!(
            out,
            r#"<line x1="{tx}" y1="{}" x2="{tx}" y2="{}"/>"#,
            num(y - 2.0),
            num(y),
            tx = num(tx)
        );
    }
    let _ = writeln!(
        out,
        r#"</g><text x="{}" y="{}" font-size="3">50 mm: print at 100% scale (no "fit to page") and measure this bar</text>"#,
        num(x + 53.0),
        num(y)
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tag_svg_has_physical_size() {
        let svg = tag_svg(Family::ct14(), 42, 100.0).unwrap();
        assert!(svg.contains(r#"width="100mm" height="100mm" viewBox="0 0 100 100""#));
        assert!(svg.contains("scale(50)"));
        assert!(svg.trim_end().ends_with("</svg>"));
    }

    #[test]
    fn sheet_paginates() {
        let ids: Vec<u64> = (0..48).collect();
        let pages = sheet_svgs(Family::ct14(), &ids, 50.0, Paper::A4).unwrap();
        // A4 at 50 mm: 3 columns x 4 rows.
        assert_eq!(pages.len(), 4);
        assert_eq!(pages[0].matches("<g transform=").count(), 12);
        assert!(pages[3].contains("page 4/4"));
        assert!(sheet_svgs(Family::ct14(), &ids, 400.0, Paper::A4).is_err());
        assert!(tag_svg(Family::ct14(), 1, 0.0).is_err());
        assert!(tag_svg(Family::ct14(), 1, -3.0).is_err());
    }
}

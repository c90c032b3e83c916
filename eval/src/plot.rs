//! Line charts as SVG and PNG, with plotters.
//!
//! Text in PNGs is drawn with DejaVu Sans, compiled in (`eval/assets`,
//! licence beside it), so figures look the same on every machine and need
//! no system fonts. Both files are rendered in memory and written
//! atomically.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use crate::error::{EvalError, Result};

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known good: failure is a build defect.
        plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
            .map_err(|_| "bad font")
            .expect("bundled DejaVu Sans loads");
    });
}

/// One line of a chart.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points (x, y); NaN y values break the line (no detection there).
    pub points: Vec<(f64, f64)>,
}

/// A chart's text and axes.
#[derive(Debug, Clone)]
pub struct Chart<'a> {
    /// Title.
    pub title: &'a str,
    /// X-axis label.
    pub x_label: &'a str,
    /// Y-axis label.
    pub y_label: &'a str,
    /// Y range; `None` fits the data.
    pub y_range: Option<(f64, f64)>,
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(214, 95, 0),
    RGBColor(0, 114, 178),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
    series: &[Series],
) -> std::result::Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let pts = series
        .iter()
        .flat_map(|s| s.points.iter())
        .filter(|p| p.0.is_finite() && p.1.is_finite());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, 0.0f64, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y1) = (0.0, 1.0, 1.0);
    }
    if x1 - x0 < 1e-9 {
        x1 = x0 + 1.0;
    }
    if let Some(r) = chart.y_range {
        (y0, y1) = r;
    } else if y1 <= y0 {
        y1 = y0 + 1.0;
    } else {
        y1 += 0.05 * (y1 - y0);
    }
    let mut ctx = ChartBuilder::on(&root)
        .caption(chart.title, ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    ctx.configure_mesh()
        .x_desc(chart.x_label)
        .y_desc(chart.y_label)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        // Split at gaps so a missed detection shows as a break.
        let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
        for &p in &s.points {
            if p.1.is_finite() {
                runs.last_mut().expect("never empty").push(p);
            } else if !runs.last().expect("never empty").is_empty() {
                runs.push(Vec::new());
            }
        }
        let mut first = true;
        for run in runs.into_iter().filter(|r| !r.is_empty()) {
            let line = ctx
                .draw_series(LineSeries::new(run, colour.stroke_width(2)))
                .map_err(|e| err(&e))?;
            if first {
                line.label(s.label.clone()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(3))
                });
                first = false;
            }
        }
    }
    ctx.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

/// Writes `<stem>.svg` and `<stem>.png` (1000 x 560 px).
pub fn line_chart(stem: &Path, chart: &Chart, series: &[Series]) -> Result<()> {
    register_font();
    let (w, h) = (1000u32, 560u32);
    let mut svg = String::new();
    draw(
        SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area(),
        chart,
        series,
    )
    .map_err(|e| EvalError::bad(stem.with_extension("svg"), e))?;
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    draw(
        BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area(),
        chart,
        series,
    )
    .map_err(|e| EvalError::bad(stem.with_extension("png"), e))?;
    let img = image::RgbImage::from_raw(w, h, rgb).expect("buffer matches size");
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| EvalError::bad(stem.with_extension("png"), e.to_string()))?;
    crate::atomic::write_atomic_in_new_dir(&stem.with_extension("svg"), svg.as_bytes())?;
    crate::atomic::write_atomic_in_new_dir(&stem.with_extension("png"), &png)?;
    Ok(())
}

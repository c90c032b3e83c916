//! `coppertag generate`: print-ready tags.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use coppertag::geometry::tag_shapes;
use coppertag::Family;
use coppertag_synth::raster::{tag_image, TAG_PX_RANGE};
use coppertag_synth::svg::{sheet_svgs, tag_svg, Paper};

use coppertag_eval::atomic::write_atomic;

#[derive(Args, Debug)]
#[command(after_help = "Examples:\n  \
    coppertag generate --family ct14 --id 42 --size 100mm -o tag.svg\n  \
    coppertag generate --family ct14 --id 42 -o tag.png --px 1024\n  \
    coppertag generate --family ct8 --ids 0-47 --size 50mm --sheet a4 -o sheet.svg\n  \
    coppertag generate --ids 0-9 -o 'tags/ct14-{id}.png'")]
pub struct GenerateArgs {
    /// Tag family: ct14 (256 ids, 14x14 cells) or ct8 (65536 ids, 8x8 cells).
    #[arg(long, default_value = "ct14")]
    family: String,

    /// Id of the tag to make.
    #[arg(long, conflicts_with = "ids")]
    id: Option<u64>,

    /// Several ids: ranges and single ids separated by commas, e.g. 0-47,60.
    /// With --sheet they are laid out on pages; without it, -o must contain
    /// '{id}' and one file is written per tag.
    #[arg(long)]
    ids: Option<String>,

    /// Printed size of the whole tag (the data square is half of it), with a
    /// unit: mm, cm, m or in. Used for SVG and sheets, and recorded as the
    /// print resolution of PNGs.
    #[arg(long, default_value = "100mm", allow_hyphen_values = true)]
    size: String,

    /// Output file: .svg (vector, physical size) or .png (raster). Pages of a
    /// sheet beyond the first get -p2, -p3... before the extension.
    #[arg(short, long)]
    output: PathBuf,

    /// PNG side in pixels (the whole tag; the data square is half of it).
    #[arg(long, default_value_t = 1024)]
    px: u32,

    /// Lay the tags out on printable pages: a4, a3 or letter (SVG only).
    #[arg(long)]
    sheet: Option<String>,

    /// Print what was written as one JSON line.
    #[arg(long)]
    json: bool,
}

/// Parses a length with a unit into millimetres.
fn parse_size_mm(s: &str) -> Result<f64> {
    let s = s.trim();
    let split = s
        .find(|c: char| c.is_ascii_alphabetic())
        .with_context(|| format!("size '{s}' needs a unit: mm, cm, m or in"))?;
    let (value, unit) = s.split_at(split);
    let value: f64 = value
        .trim()
        .parse()
        .with_context(|| format!("size '{s}' is not a number with a unit"))?;
    let factor = match unit {
        "mm" => 1.0,
        "cm" => 10.0,
        "m" => 1000.0,
        "in" => 25.4,
        _ => bail!("size '{s}': unknown unit '{unit}' (use mm, cm, m or in)"),
    };
    let mm = value * factor;
    if !(mm.is_finite() && mm > 0.0) {
        bail!("size '{s}' must be greater than zero");
    }
    Ok(mm)
}

/// Parses `0-47,60,70-71` into a list of ids.
fn parse_ids(s: &str, family: &Family) -> Result<Vec<u64>> {
    let mut ids = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (lo, hi) = match part.split_once('-') {
            Some((a, b)) => (a.trim(), b.trim()),
            None => (part, part),
        };
        let lo: u64 = lo
            .parse()
            .with_context(|| format!("bad id '{lo}' in --ids"))?;
        let hi: u64 = hi
            .parse()
            .with_context(|| format!("bad id '{hi}' in --ids"))?;
        if lo > hi {
            bail!("bad id range '{part}': start is after end");
        }
        family.check_id(lo)?;
        family.check_id(hi)?;
        ids.extend(lo..=hi);
    }
    if ids.is_empty() {
        bail!("--ids '{s}' names no ids");
    }
    Ok(ids)
}

enum Format {
    Svg,
    Png,
}

fn format_of(path: &Path) -> Result<Format> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("svg") => Ok(Format::Svg),
        Some("png") => Ok(Format::Png),
        _ => bail!("output {} must end in .svg or .png", path.display()),
    }
}

/// `sheet.svg` -> `sheet-p2.svg` for page 2.
fn page_path(path: &Path, page: usize) -> PathBuf {
    if page == 1 {
        return path.to_path_buf();
    }
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("sheet");
    let ext = path.extension().and_then(|s| s.to_str()).unwrap_or("svg");
    path.with_file_name(format!("{stem}-p{page}.{ext}"))
}

fn png_bytes(family: &Family, id: u64, px: u32, size_mm: f64) -> Result<Vec<u8>> {
    let img = tag_image(&tag_shapes(family, id)?, px)
        .with_context(|| format!("cannot allocate a {px} x {px} image"))?;
    let mut bytes = Vec::new();
    let mut enc = png::Encoder::new(&mut bytes, px, px);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    // Record the print resolution so that image viewers and printers know
    // the intended physical size.
    let per_metre = (f64::from(px) / (size_mm / 1000.0)).round() as u32;
    enc.set_pixel_dims(Some(png::PixelDimensions {
        xppu: per_metre,
        yppu: per_metre,
        unit: png::Unit::Meter,
    }));
    let mut w = enc.write_header().context("cannot encode PNG")?;
    w.write_image_data(img.as_raw())
        .context("cannot encode PNG")?;
    w.finish().context("cannot encode PNG")?;
    Ok(bytes)
}

/// Runs the subcommand.
pub fn run(args: &GenerateArgs) -> Result<()> {
    let family = Family::by_name(&args.family)?;
    let size_mm = parse_size_mm(&args.size)?;
    let format = format_of(&args.output)?;
    if matches!(format, Format::Png) && !TAG_PX_RANGE.contains(&args.px) {
        bail!(
            "--px {} is outside {}..={}",
            args.px,
            TAG_PX_RANGE.start(),
            TAG_PX_RANGE.end()
        );
    }
    let ids = match (&args.ids, args.id) {
        (Some(list), _) => parse_ids(list, family)?,
        (None, Some(id)) => {
            family.check_id(id)?;
            vec![id]
        }
        (None, None) => bail!("give --id N or --ids LIST"),
    };
    // Build every document in memory first, so that bad input fails before
    // anything is written.
    let mut files: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    if let Some(sheet) = &args.sheet {
        let paper = Paper::parse(sheet)?;
        if !matches!(format, Format::Svg) {
            bail!("sheets are written as SVG: use an output ending in .svg");
        }
        for (i, page) in sheet_svgs(family, &ids, size_mm, paper)?
            .into_iter()
            .enumerate()
        {
            files.push((page_path(&args.output, i + 1), page.into_bytes()));
        }
    } else {
        let template = args.output.to_string_lossy();
        if ids.len() > 1 && !template.contains("{id}") {
            bail!(
                "{} ids need --sheet, or an output name containing '{{id}}'",
                ids.len()
            );
        }
        for &id in &ids {
            let path = PathBuf::from(template.replace("{id}", &id.to_string()));
            let bytes = match format {
                Format::Svg => tag_svg(family, id, size_mm)?.into_bytes(),
                Format::Png => png_bytes(family, id, args.px, size_mm)?,
            };
            files.push((path, bytes));
        }
    }
    for (path, bytes) in &files {
        write_atomic(path, bytes)?;
    }
    if args.json {
        let written: Vec<String> = files.iter().map(|(p, _)| p.display().to_string()).collect();
        println!(
            "{}",
            serde_json::json!({"family": family.name(), "ids": ids, "size_mm": size_mm, "written": written})
        );
    } else {
        for (path, _) in &files {
            eprintln!("wrote {}", path.display());
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_units() {
        assert_eq!(parse_size_mm("100mm").unwrap(), 100.0);
        assert_eq!(parse_size_mm("10cm").unwrap(), 100.0);
        assert_eq!(parse_size_mm("0.1m").unwrap(), 100.0);
        assert_eq!(parse_size_mm("2in").unwrap(), 50.8);
        for bad in ["0mm", "-5mm", "100", "abc", "5furlong", "nanmm"] {
            assert!(parse_size_mm(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn id_lists_parse() {
        let f = Family::ct14();
        assert_eq!(parse_ids("0-3,7", f).unwrap(), vec![0, 1, 2, 3, 7]);
        assert!(parse_ids("5-2", f).is_err());
        assert!(parse_ids("0-300", f).is_err());
        assert!(parse_ids("x", f).is_err());
    }
}

//! Camera frames from a recording's image messages, as the grey image the
//! detector reads.
//!
//! | message | encodings | to grey |
//! |---|---|---|
//! | `sensor_msgs/msg/Image` | `mono8` | read in place, any row step |
//! | | `mono16` | shifted to 8 bits ([`mono16_shift`]) |
//! | | `rgb8`, `bgr8`, `rgba8`, `bgra8` | Rec. 709 luma (the `image` crate's weights, as `coppertag detect` on a PNG) |
//! | | `bayer_rggb8`, `bayer_bggr8`, `bayer_gbrg8`, `bayer_grbg8` | [`bayer_luma`] |
//! | `sensor_msgs/msg/CompressedImage`, `foxglove.CompressedImage` | `jpeg`, `png` | decoded by the `image` crate |

use std::borrow::Cow;

use image::{GrayImage, ImageFormat};

use super::msgs::{CompressedImage, Image};

/// Encodings of `sensor_msgs/msg/Image` that are read.
pub const IMAGE_ENCODINGS: &[&str] = &[
    "mono8",
    "mono16",
    "rgb8",
    "bgr8",
    "rgba8",
    "bgra8",
    "bayer_rggb8",
    "bayer_bggr8",
    "bayer_gbrg8",
    "bayer_grbg8",
];

/// A grey frame: borrowed from the message when it is `mono8`, else
/// converted.
#[derive(Debug)]
pub enum Gray<'a> {
    /// A `mono8` buffer as it is: pixels, width, height, row step.
    Borrowed(&'a [u8], u32, u32, usize),
    /// A converted frame.
    Owned(GrayImage),
}

impl Gray<'_> {
    /// Width and height in pixels.
    #[must_use]
    pub fn size(&self) -> (u32, u32) {
        match self {
            Gray::Borrowed(_, w, h, _) => (*w, *h),
            Gray::Owned(g) => g.dimensions(),
        }
    }

    /// The frame as the detector's view.
    pub fn view(&self) -> coppertag::Result<coppertag::GrayView<'_>> {
        match self {
            Gray::Borrowed(d, w, h, s) => coppertag::GrayView::new(d, *w, *h, *s),
            Gray::Owned(g) => Ok(g.into()),
        }
    }
}

/// Right shift that brings a 16-bit frame to 8 bits: the frame's largest
/// value decides how many bits are in use (sensors deliver 10 or 12 bits
/// in 16-bit words), and the top 8 of those are kept, so a 12-bit frame is
/// not crushed into its darkest 16 levels. Per frame, so it depends on the
/// frame alone.
#[must_use]
pub fn mono16_shift(max: u16) -> u32 {
    (16 - max.leading_zeros()).saturating_sub(8)
}

/// The grey frame of a raw image message.
pub fn from_image<'a>(img: &Image<'a>) -> Result<Gray<'a>, String> {
    let (w, h) = (img.width as usize, img.height as usize);
    let data: &[u8] = &img.data;
    let bpp = match img.encoding.as_str() {
        "mono8" | "bayer_rggb8" | "bayer_bggr8" | "bayer_gbrg8" | "bayer_grbg8" => 1,
        "mono16" => 2,
        "rgb8" | "bgr8" => 3,
        "rgba8" | "bgra8" => 4,
        other => {
            return Err(format!(
                "unsupported encoding '{other}' (supported: {})",
                IMAGE_ENCODINGS.join(", ")
            ))
        }
    };
    let step = img.step as usize;
    let row = w
        .checked_mul(bpp)
        .ok_or_else(|| format!("{w} x {h} pixels overflow"))?;
    if step < row {
        return Err(format!(
            "row step {step} is below {w} pixels of {bpp} bytes ({})",
            img.encoding
        ));
    }
    let need = if h == 0 { 0 } else { (h - 1) * step + row };
    if data.len() < need || w == 0 || h == 0 {
        return Err(format!(
            "{w} x {h} {} pixels with step {step} need {need} bytes, the message has {}",
            img.encoding,
            data.len()
        ));
    }
    let rows = || (0..h).map(|y| &data[y * step..y * step + row]);
    Ok(match img.encoding.as_str() {
        "mono8" => match &img.data {
            Cow::Borrowed(b) => Gray::Borrowed(b, img.width, img.height, step),
            Cow::Owned(_) => Gray::Owned(
                GrayImage::from_raw(img.width, img.height, rows().flatten().copied().collect())
                    .ok_or("size")?,
            ),
        },
        "mono16" => {
            let big = img.is_bigendian != 0;
            let px = |b: &[u8]| {
                if big {
                    u16::from_be_bytes([b[0], b[1]])
                } else {
                    u16::from_le_bytes([b[0], b[1]])
                }
            };
            let max = rows()
                .flat_map(|r| r.chunks_exact(2).map(px))
                .max()
                .unwrap_or(0);
            let shift = mono16_shift(max);
            let data: Vec<u8> = rows()
                .flat_map(|r| r.chunks_exact(2).map(move |b| (px(b) >> shift) as u8))
                .collect();
            Gray::Owned(GrayImage::from_raw(img.width, img.height, data).ok_or("size")?)
        }
        enc if enc.starts_with("bayer_") => {
            let rows: Vec<&[u8]> = rows().collect();
            Gray::Owned(bayer_luma(&rows, img.width, img.height))
        }
        enc => {
            // Straight from the message's rows: no packed RGB copy first.
            let (ri, bi) = if enc.starts_with("bgr") {
                (2, 0)
            } else {
                (0, 2)
            };
            let mut data = Vec::with_capacity(w * h);
            for r in rows() {
                data.extend(r.chunks_exact(bpp).map(|p| luma(p[ri], p[1], p[bi])));
            }
            Gray::Owned(GrayImage::from_raw(img.width, img.height, data).ok_or("size")?)
        }
    })
}

/// Luma weights of sRGB (Rec. 709) in ten-thousandths, the `image` crate's
/// (`to_luma8`), so a colour frame gives the grey `coppertag detect` gets
/// from the same picture as a PNG file (to within one level: the crate
/// rounds in floating point, this in integers).
const LUMA_WEIGHTS: [u32; 3] = [2126, 7152, 722];

/// Grey of one RGB pixel: the weighted sum, rounded to the nearest level.
#[inline]
fn luma(r: u8, g: u8, b: u8) -> u8 {
    let [wr, wg, wb] = LUMA_WEIGHTS;
    ((wr * u32::from(r) + wg * u32::from(g) + wb * u32::from(b) + 5_000) / 10_000) as u8
}

/// Grey from a Bayer mosaic without demosaicing: the 3 x 3 binomial
/// kernel `[1 2 1; 2 4 2; 1 2 1] / 16` centred on each pixel weighs the
/// mosaic's red, green and blue as `(R + 2 G + B) / 4` whatever the
/// pixel's place in the 2 x 2 pattern (a red or blue centre: 4 + 8 + 4;
/// a green one: 8 for green, 4 each for red and blue), so every Bayer
/// order gives the same luma, centred on the pixel (no half-pixel shift
/// for the corners). Borders repeat the edge pixels.
#[must_use]
pub fn bayer_luma(rows: &[&[u8]], width: u32, height: u32) -> GrayImage {
    let (w, h) = (width as usize, height as usize);
    let at = |x: isize, y: isize| -> u32 {
        let xi = x.clamp(0, w as isize - 1) as usize;
        let yi = y.clamp(0, h as isize - 1) as usize;
        u32::from(rows[yi][xi])
    };
    GrayImage::from_fn(width, height, |x, y| {
        let (x, y) = (x as isize, y as isize);
        let sum = 4 * at(x, y)
            + 2 * (at(x - 1, y) + at(x + 1, y) + at(x, y - 1) + at(x, y + 1))
            + at(x - 1, y - 1)
            + at(x + 1, y - 1)
            + at(x - 1, y + 1)
            + at(x + 1, y + 1);
        image::Luma([((sum + 8) / 16) as u8])
    })
}

/// The file format named by a compressed image's `format` field: `jpeg`
/// or `png` alone, or image_transport's `<raw>; <format> compressed <raw>`.
pub fn compressed_format(format: &str) -> Result<ImageFormat, String> {
    let f = format.to_ascii_lowercase();
    let codec = f.split(';').next_back().unwrap_or("").trim();
    let word = codec.split_whitespace().next().unwrap_or("");
    match word {
        "jpeg" | "jpg" => Ok(ImageFormat::Jpeg),
        "png" => Ok(ImageFormat::Png),
        _ => Err(format!(
            "unsupported compressed format '{format}' (supported: jpeg, png)"
        )),
    }
}

/// Decodes a compressed image file to grey.
pub fn from_compressed(format: &str, data: &[u8]) -> Result<Gray<'static>, String> {
    let f = compressed_format(format)?;
    let img = image::load_from_memory_with_format(data, f)
        .map_err(|e| format!("cannot decode the {format} image: {e}"))?;
    Ok(Gray::Owned(img.to_luma8()))
}

/// The grey frame of a `sensor_msgs/msg/CompressedImage`.
pub fn from_compressed_image(img: &CompressedImage<'_>) -> Result<Gray<'static>, String> {
    from_compressed(&img.format, &img.data)
}

/// A `foxglove.CompressedImage` in JSON, as `coppertag synth` writes it
/// (`data` in base64).
#[derive(Debug, serde::Deserialize)]
pub struct FoxgloveImage {
    /// Acquisition time.
    #[serde(default)]
    pub timestamp: Option<FoxgloveTime>,
    /// Camera frame.
    #[serde(default)]
    pub frame_id: String,
    /// `png` or `jpeg`.
    pub format: String,
    /// The file, base64.
    pub data: String,
}

/// A Foxglove `Time`.
#[derive(Debug, Clone, Copy, serde::Deserialize)]
pub struct FoxgloveTime {
    /// Seconds.
    pub sec: u64,
    /// Nanoseconds.
    pub nsec: u64,
}

impl FoxgloveImage {
    /// Parses one JSON message.
    pub fn parse(data: &[u8]) -> Result<Self, String> {
        serde_json::from_slice(data).map_err(|e| format!("bad foxglove.CompressedImage JSON: {e}"))
    }

    /// The stamp in ns (0 without one).
    #[must_use]
    pub fn stamp(&self) -> u64 {
        self.timestamp.map_or(0, |t| {
            t.sec.saturating_mul(1_000_000_000).saturating_add(t.nsec)
        })
    }

    /// The compressed file's bytes.
    pub fn bytes(&self) -> Result<Vec<u8>, String> {
        use base64::Engine as _;
        base64::engine::general_purpose::STANDARD
            .decode(self.data.as_bytes())
            .map_err(|e| format!("bad base64 image data: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::msgs::Header;
    use image::{DynamicImage, RgbImage};

    fn image<'a>(encoding: &str, w: u32, h: u32, step: u32, data: &'a [u8]) -> Image<'a> {
        Image {
            header: Header::default(),
            height: h,
            width: w,
            encoding: encoding.into(),
            is_bigendian: 0,
            step,
            data: Cow::Borrowed(data),
        }
    }

    fn pixels(g: &Gray<'_>) -> Vec<u8> {
        let v = g.view().unwrap();
        let (w, h) = g.size();
        let mut out = Vec::new();
        for y in 0..h {
            for x in 0..w {
                out.push(v.get(x, y).unwrap());
            }
        }
        out
    }

    #[test]
    fn encodings_agree_on_grey_pixels() {
        // Two rows of three pixels, rows padded to a wider step.
        let grey = [10u8, 128, 250, 0, 77, 255];
        let mono8: Vec<u8> = [&grey[..3], &[9, 9], &grey[3..], &[9, 9]].concat();
        let g = from_image(&image("mono8", 3, 2, 5, &mono8)).unwrap();
        assert!(matches!(g, Gray::Borrowed(..)));
        assert_eq!(pixels(&g), grey);
        for (enc, bpp) in [("rgb8", 3), ("bgr8", 3), ("rgba8", 4), ("bgra8", 4)] {
            let mut data = Vec::new();
            for r in 0..2 {
                for &v in &grey[r * 3..r * 3 + 3] {
                    data.extend(std::iter::repeat_n(v, 3));
                    if bpp == 4 {
                        data.push(255);
                    }
                }
                data.push(1); // padding
            }
            let g = from_image(&image(enc, 3, 2, 3 * bpp + 1, &data)).unwrap();
            assert_eq!(pixels(&g), grey, "{enc}");
        }
        // 12-bit values in 16-bit words keep their top 8 bits.
        let words: Vec<u8> = grey
            .iter()
            .flat_map(|&v| (u16::from(v) << 4).to_le_bytes())
            .collect();
        let g = from_image(&image("mono16", 3, 2, 6, &words)).unwrap();
        assert_eq!(pixels(&g), grey);
    }

    #[test]
    fn bayer_mosaics_of_a_grey_scene_are_that_grey() {
        // Any order: a uniform grey scene gives a uniform mosaic.
        let flat = [90u8; 16];
        let g = from_image(&image("bayer_rggb8", 4, 4, 4, &flat)).unwrap();
        assert!(pixels(&g).iter().all(|&v| v == 90));
        // R = 200, G = 100, B = 0 in RGGB: luma (R + 2G + B) / 4 = 100 everywhere inside.
        let mut m = vec![0u8; 36];
        for y in 0..6 {
            for x in 0..6 {
                m[y * 6 + x] = match (y % 2, x % 2) {
                    (0, 0) => 200,
                    (1, 1) => 0,
                    _ => 100,
                };
            }
        }
        let g = from_image(&image("bayer_rggb8", 6, 6, 6, &m)).unwrap();
        let p = pixels(&g);
        for y in 1..5 {
            for x in 1..5 {
                assert_eq!(p[y * 6 + x], 100, "({x}, {y})");
            }
        }
    }

    #[test]
    fn luma_is_the_image_crates_within_a_level() {
        let mut px = Vec::new();
        for r in (0..=255u8).step_by(15) {
            for g in (0..=255u8).step_by(17) {
                for b in (0..=255u8).step_by(51) {
                    px.extend([r, g, b]);
                }
            }
        }
        let n = (px.len() / 3) as u32;
        let theirs =
            DynamicImage::ImageRgb8(RgbImage::from_raw(n, 1, px.clone()).unwrap()).to_luma8();
        let ours = from_image(&image("rgb8", n, 1, 3 * n, &px)).unwrap();
        for (a, b) in pixels(&ours).iter().zip(theirs.into_raw()) {
            assert!(a.abs_diff(b) <= 1, "{a} vs {b}");
        }
    }

    #[test]
    fn colour_order_is_respected() {
        let red_rgb = [255u8, 0, 0];
        let red_bgr = [0u8, 0, 255];
        let a = from_image(&image("rgb8", 1, 1, 3, &red_rgb)).unwrap();
        let b = from_image(&image("bgr8", 1, 1, 3, &red_bgr)).unwrap();
        assert_eq!(pixels(&a), pixels(&b));
        let blue = from_image(&image("rgb8", 1, 1, 3, &red_bgr)).unwrap();
        assert_ne!(pixels(&a), pixels(&blue));
    }

    #[test]
    fn bad_frames_are_refused_with_reasons() {
        let e = from_image(&image("32FC1", 1, 1, 4, &[0; 4])).unwrap_err();
        assert!(e.contains("32FC1") && e.contains("mono8"), "{e}");
        let e = from_image(&image("mono8", 4, 4, 4, &[0; 15])).unwrap_err();
        assert!(e.contains("need 16 bytes"), "{e}");
        let e = from_image(&image("bgr8", 4, 1, 8, &[0; 12])).unwrap_err();
        assert!(e.contains("row step 8"), "{e}");
        assert!(compressed_format("bgr8; jpeg compressed bgr8").is_ok());
        assert!(compressed_format("16UC1; compressedDepth png").is_err());
        assert!(from_compressed("png", b"not a png")
            .unwrap_err()
            .contains("cannot decode"));
    }
}

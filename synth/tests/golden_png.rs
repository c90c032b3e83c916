//! The PNG generator draws what the reference generator draws: pixel for
//! pixel at 1024 px, except along edges and in the printed id.
//!
//! Tolerance, stated: a pixel is compared as black (< 128) or white. Pixels
//! within one pixel of a black/white boundary in either image are skipped
//! (anti-aliasing and one-pixel rasterisation differences along circles,
//! which the format contract allows), as is the id text box and, for ct8,
//! cell 29 (the reference's known quirk). Every other pixel must agree:
//! zero mismatches.

use coppertag::geometry::{cell_rect, tag_shapes, R, TEXT_HEIGHT};
use coppertag::Family;
use coppertag_synth::raster::tag_image;
use image::GrayImage;

const GOLDEN: &[(&str, &[u64])] = &[
    ("ct14", &[0, 1, 35, 42, 113, 200, 255]),
    ("ct8", &[0, 1, 3, 42, 4097, 30000, 65535]),
];

fn near_edge(img: &GrayImage, x: u32, y: u32) -> bool {
    let c = img.get_pixel(x, y).0[0] < 128;
    let (w, h) = img.dimensions();
    for dy in -1i32..=1 {
        for dx in -1i32..=1 {
            let (nx, ny) = (x as i32 + dx, y as i32 + dy);
            if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                continue;
            }
            if (img.get_pixel(nx as u32, ny as u32).0[0] < 128) != c {
                return true;
            }
        }
    }
    false
}

/// Tag units to pixel index at S = 512 px (pixel i covers [i, i+1)).
fn to_px(v: f64) -> f64 {
    (v + 1.0) * 512.0
}

#[test]
fn rendered_png_matches_golden_outside_edges_and_text() {
    let mut compared_total = 0u64;
    for (name, ids) in GOLDEN {
        let fam = Family::by_name(name).unwrap();
        for &id in *ids {
            let path = format!(
                "{}/../detector/tests/fixtures/{name}/{id}.png",
                env!("CARGO_MANIFEST_DIR")
            );
            let golden = image::open(&path)
                .unwrap_or_else(|e| panic!("missing fixture {path}: {e}"))
                .to_luma8();
            let ours = tag_image(&tag_shapes(fam, id).unwrap(), 1024).unwrap();
            assert_eq!(ours.dimensions(), golden.dimensions());
            // Id text: a generous box around the digits, centred under the
            // data square with its baseline at y = r.
            let half_w = 0.05 * (id.to_string().len() as f64) + 0.03;
            let text = [
                to_px(-half_w),
                to_px(R - TEXT_HEIGHT - 0.03),
                to_px(half_w),
                to_px(R + 0.03),
            ];
            let quirk = if *name == "ct8" {
                let [x0, y0, x1, y1] = cell_rect(8, 29 / 8, 29 % 8);
                Some([
                    to_px(x0) - 1.0,
                    to_px(y0) - 1.0,
                    to_px(x1) + 1.0,
                    to_px(y1) + 1.0,
                ])
            } else {
                None
            };
            let inside =
                |b: &[f64; 4], x: f64, y: f64| x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3];
            let (mut compared, mut mismatched) = (0u64, Vec::new());
            for y in 0..1024 {
                for x in 0..1024 {
                    let (cx, cy) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                    if inside(&text, cx, cy) || quirk.is_some_and(|q| inside(&q, cx, cy)) {
                        continue;
                    }
                    if near_edge(&golden, x, y) || near_edge(&ours, x, y) {
                        continue;
                    }
                    compared += 1;
                    let g = golden.get_pixel(x, y).0[0] < 128;
                    let o = ours.get_pixel(x, y).0[0] < 128;
                    if g != o {
                        mismatched.push((x, y));
                    }
                }
            }
            assert!(
                mismatched.is_empty(),
                "{name} {id}: {} pixels differ, first {:?}",
                mismatched.len(),
                &mismatched[..mismatched.len().min(10)]
            );
            // Edges and text are a small part of the image: most pixels are
            // really compared.
            assert!(
                compared > 900_000,
                "{name} {id}: only {compared} pixels compared"
            );
            compared_total += compared;
        }
    }
    println!("compared {compared_total} pixels over 14 golden tags: all agree");
}

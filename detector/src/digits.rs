//! A small stroke font for the decimal id printed on a tag.
//!
//! The id is for people, not for the decoder, but it must be legible on
//! paper and in rendered images, and the same in SVG, PNG and synthetic
//! camera images. A font file would need a font rasteriser in three places
//! and a licence to ship; ten digits drawn as centre lines stroked with round
//! caps are enough, cost nothing and look the same everywhere.

use std::f64::consts::PI;

/// Glyph cell: digits are `WIDTH` wide and 1 high, y down, baseline at 1.
pub const WIDTH: f64 = 0.56;

fn arc(cx: f64, cy: f64, rx: f64, ry: f64, from_deg: f64, to_deg: f64) -> Vec<[f64; 2]> {
    // Angles in degrees, y down, so positive angles turn clockwise on paper.
    let steps = (((to_deg - from_deg).abs() / 6.0).ceil() as usize).max(2);
    (0..=steps)
        .map(|s| {
            let t = (from_deg + (to_deg - from_deg) * s as f64 / steps as f64) * PI / 180.0;
            [cx + rx * t.cos(), cy + ry * t.sin()]
        })
        .collect()
}

fn join(mut a: Vec<[f64; 2]>, b: &[[f64; 2]]) -> Vec<[f64; 2]> {
    a.extend_from_slice(b);
    a
}

/// Centre lines of a digit's strokes in the glyph cell.
pub fn strokes(digit: u8) -> Vec<Vec<[f64; 2]>> {
    let w = WIDTH;
    let c = w / 2.0;
    match digit {
        0 => vec![arc(c, 0.5, c, 0.5, 0.0, 360.0)],
        1 => vec![vec![[0.12, 0.2], [0.34, 0.0], [0.34, 1.0]]],
        2 => vec![join(
            arc(c, 0.27, 0.26, 0.27, 195.0, 380.0),
            &[[0.0, 1.0], [w, 1.0]],
        )],
        3 => vec![join(
            vec![[0.04, 0.0], [0.52, 0.0], [0.22, 0.4]],
            &arc(c, 0.69, 0.27, 0.31, -100.0, 150.0),
        )],
        4 => vec![vec![[0.42, 1.0], [0.42, 0.0], [0.0, 0.68], [w, 0.68]]],
        5 => vec![join(
            vec![[0.52, 0.0], [0.09, 0.0], [0.05, 0.44]],
            &arc(c, 0.67, 0.28, 0.33, -135.0, 150.0),
        )],
        6 => vec![
            arc(c, 0.71, c, 0.29, 0.0, 360.0),
            vec![[0.46, 0.0], [0.04, 0.62]],
        ],
        7 => vec![vec![[0.0, 0.0], [w, 0.0], [0.16, 1.0]]],
        8 => vec![
            arc(c, 0.25, 0.22, 0.25, 0.0, 360.0),
            arc(c, 0.73, c, 0.27, 0.0, 360.0),
        ],
        _ => strokes(6)
            .into_iter()
            .map(|line| line.into_iter().map(|[x, y]| [w - x, 1.0 - y]).collect())
            .collect(),
    }
}

/// Centre lines of a decimal number set in a line of text of height
/// `height`, horizontally centred on `cx`, with its baseline at `baseline`.
/// Returns the lines and the stroke width to draw them with.
pub fn text_strokes(number: u64, cx: f64, baseline: f64, height: f64) -> (Vec<Vec<[f64; 2]>>, f64) {
    let text = number.to_string();
    let advance = 0.86 * height;
    let width = WIDTH * height + advance * (text.len() - 1) as f64;
    let x0 = cx - width / 2.0;
    let mut lines = Vec::new();
    for (i, ch) in text.bytes().enumerate() {
        let ox = x0 + advance * i as f64;
        for line in strokes(ch - b'0') {
            lines.push(
                line.into_iter()
                    .map(|[x, y]| [ox + x * height, baseline - height + y * height])
                    .collect(),
            );
        }
    }
    (lines, 0.13 * height)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_digit_stays_in_its_cell() {
        for d in 0..10 {
            let s = strokes(d);
            assert!(!s.is_empty());
            for p in s.iter().flatten() {
                assert!((-0.01..=WIDTH + 0.01).contains(&p[0]), "digit {d}: {p:?}");
                assert!((-0.01..=1.01).contains(&p[1]), "digit {d}: {p:?}");
            }
        }
    }

    #[test]
    fn text_is_centred() {
        let (lines, _) = text_strokes(4097, 0.0, 1.0, 0.1);
        let xs: Vec<f64> = lines.iter().flatten().map(|p| p[0]).collect();
        let (lo, hi) = xs
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        assert!((lo + hi).abs() < 0.01, "{lo} {hi}");
    }
}

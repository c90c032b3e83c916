//! A candidate quad that is the printed tag's own outline.
//!
//! A CopperTag is printed as a white square of twice the data square's
//! side with the data square in its middle (the format's tag image,
//! `geometry`). Cut along that square and laid on a darker surface, its
//! outline is the sharpest quad the tag shows: on a small, blurred tag the
//! frame around the data square washes into the disc and the cells, and
//! no quad of the data square forms, while the paper's edge still does
//! (on the wild set, a third of the blurred tags whose data square was
//! missed had their paper outline among the candidates). The data square
//! is then the outline's middle half, through the outline's homography.
//! A tag printed on a larger sheet has no such outline; the hypothesis
//! costs one reading when the quad looks like a printed tag
//! ([`looks_printed`]) and is dropped when it does not read.

use crate::geometry::{B, CORNERS};
use crate::homography::Homography;
use crate::math::sample_bilinear;
use crate::view::GrayView;

/// Smallest data square (px a side) looked for inside an outline: half of
/// the smallest the likelihood reading reads (the wild set's 20 px).
const MIN_INNER_SIDE_PX: f64 = 10.0;

/// Where the white paper is sampled, in tag units (the data square spans
/// -0.5..0.5, the printed square -1..1): near the printed square's corners,
/// outside the black disc (radius 0.82) and inside the paper's edge by a
/// tenth of the data square, so that a blurred edge does not reach it.
const PAPER_AT: f64 = 0.85;

/// Darker by this many grey levels than the paper the frame's corners
/// must be (the centre line of the black frame, whose corners stand out of
/// the disc): a worn print on the wild set still shows 80 or more; a
/// bright square of clutter shows none.
const MIN_PAPER_CONTRAST: f64 = 20.0;

/// The data square inside the outline `q` (corners of the printed square,
/// in the order of a data square's corners), when the quad looks like a
/// printed tag and the square is big enough to read.
pub(crate) fn data_square_within(img: &GrayView<'_>, q: &[[f64; 2]; 4]) -> Option<[[f64; 2]; 4]> {
    // Candidate units: the outline spans -0.5..0.5, so a point at tag
    // units (u, v) is at (u / 2, v / 2).
    let h = Homography::from_points(&CORNERS, q)?;
    let inner = [0, 1, 2, 3].map(|k| h.map([CORNERS[k][0] / 2.0, CORNERS[k][1] / 2.0]));
    let inner = [inner[0]?, inner[1]?, inner[2]?, inner[3]?];
    let side = (0..4)
        .map(|k| {
            let (a, b) = (inner[k], inner[(k + 1) % 4]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .fold(f64::INFINITY, f64::min);
    (side >= MIN_INNER_SIDE_PX && looks_printed(img, &h)).then_some(inner)
}

/// Whether the quad of homography `h` (candidate units) shows paper
/// inside its corners and the black frame's corners further in: every
/// paper sample lighter than every frame sample by [`MIN_PAPER_CONTRAST`].
fn looks_printed(img: &GrayView<'_>, h: &Homography) -> bool {
    let at = |u: f64, v: f64| {
        h.map([u / 2.0, v / 2.0])
            .and_then(|p| sample_bilinear(img, p[0], p[1]))
    };
    let frame = 0.5 + B / 2.0;
    let mut paper = f64::INFINITY;
    let mut ink = f64::NEG_INFINITY;
    for [su, sv] in [[-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0], [1.0, -1.0]] {
        let (Some(p), Some(f)) = (at(su * PAPER_AT, sv * PAPER_AT), at(su * frame, sv * frame))
        else {
            return false;
        };
        paper = paper.min(p);
        ink = ink.max(f);
    }
    paper - ink >= MIN_PAPER_CONTRAST
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic printed tag: the image (`w` x `w` px), its outline and
    /// its data square.
    struct Printed {
        data: Vec<u8>,
        w: u32,
        outline: [[f64; 2]; 4],
        square: [[f64; 2]; 4],
    }

    /// A printed tag (white square of side 2S, black disc of radius
    /// 0.82 S, black frame) axis-aligned, S = `s` px, on grey.
    fn printed(s: f64) -> Printed {
        let w = (4.0 * s) as u32;
        let c = f64::from(w) / 2.0;
        let data: Vec<u8> = (0..w * w)
            .map(|i| {
                let (x, y) = ((f64::from(i % w) - c) / s, (f64::from(i / w) - c) / s);
                let (ax, ay) = (x.abs(), y.abs());
                if ax > 1.0 || ay > 1.0 {
                    60
                } else if ax.max(ay) <= 0.5 {
                    220
                } else if ax.max(ay) <= 0.5 + B || x.hypot(y) <= 0.82 {
                    20
                } else {
                    230
                }
            })
            .collect();
        let sq = |k: f64| CORNERS.map(|p| [c + p[0] * k * s, c + p[1] * k * s]);
        Printed {
            data,
            w,
            outline: sq(2.0),
            square: sq(1.0),
        }
    }

    #[test]
    fn the_outline_of_a_printed_tag_gives_its_data_square() {
        let Printed {
            data,
            w,
            outline,
            square,
        } = printed(30.0);
        let img = GrayView::new(&data, w, w, w as usize).unwrap();
        let inner = data_square_within(&img, &outline).expect("looks printed");
        for k in 0..4 {
            assert!((inner[k][0] - square[k][0]).abs() < 1e-9);
            assert!((inner[k][1] - square[k][1]).abs() < 1e-9);
        }
    }

    #[test]
    fn a_plain_bright_square_is_no_outline() {
        let w = 120u32;
        let data: Vec<u8> = (0..w * w)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if (30..90).contains(&x) && (30..90).contains(&y) {
                    220
                } else {
                    60
                }
            })
            .collect();
        let img = GrayView::new(&data, w, w, w as usize).unwrap();
        let q = [[30.0, 30.0], [30.0, 89.0], [89.0, 89.0], [89.0, 30.0]];
        assert!(data_square_within(&img, &q).is_none());
    }

    #[test]
    fn a_small_outline_is_not_looked_into() {
        let Printed {
            data, w, outline, ..
        } = printed(8.0);
        let img = GrayView::new(&data, w, w, w as usize).unwrap();
        assert!(data_square_within(&img, &outline).is_none());
    }
}

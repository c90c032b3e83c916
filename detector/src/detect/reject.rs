//! Stage 6, before refinement: refusing a candidate quad that is plainly
//! not a tag, for a few dozen samples instead of the thousands that
//! refinement and the decoder's grid take.
//!
//! Every tag has a white margin one cell wide just inside its data square
//! and the black frame just outside it. The decoder measures its own black
//! and white levels there (the medians of the two rings, see
//! [`crate::decode`]) and refuses a quad whose margin is not clearly
//! whiter than its frame. Most of the candidates that cluttered frames
//! give are quads between unrelated dark shapes, where the two rings show
//! the same grey: measured on the coarse quad, before the sides are
//! refined, the same two rings refuse them at once.
//!
//! The coarse corners are up to about a working pixel off (two full
//! pixels at half resolution), and further for estimated corners, so the
//! rings are only judged on quads large enough for that error to stay
//! well inside a cell ([`MIN_SIDE_PX`]); smaller quads always go on to
//! refinement.

use super::quads::Candidate;
use crate::decode::ring_levels;
use crate::geometry::CORNERS;
use crate::homography::Homography;
use crate::math::{norm, sub, to_full};
use crate::view::GrayView;

/// Shortest side (full px) of a coarse quad whose rings are judged. At
/// 48 px a ct14 cell is 3 px, so the margin's centre line lies 1.5 px and
/// the frame's 3 px from the side, beyond a coarse corner's usual error.
/// On the 3000 wild frames, the smallest quads (20 to 48 px) that went on
/// to decode had coarse ring contrasts down to -18 grey levels, their
/// refined quads then reading tags; from 48 px up, no quad that read a tag
/// had less than 37 (99 of them; 93 more in the benchmark sets, none
/// under 64).
pub(crate) const MIN_SIDE_PX: f64 = 48.0;

/// Least difference (grey levels) between the medians of the coarse
/// quad's margin ring and frame ring of a quad judged here; the decoder
/// itself refuses below [`crate::DecodeParams::min_contrast`] (4) on the
/// refined quad. Chosen from the measurements of [`MIN_SIDE_PX`]: at 10,
/// 450 of the 713 failing decodes of the benchmark's 1080p and 4K frames
/// that were that large were refused here (at 20, 14 more), and no tag;
/// a tag that large loses its contrast only under deep shadow over both
/// rings.
pub(crate) const MIN_RING_CONTRAST: f64 = 10.0;

/// Whether the candidate `cand` (working coordinates, downsampling factor
/// `scale`) can be refused before refinement: it is at least
/// [`MIN_SIDE_PX`] on every side at full resolution and its margin and
/// frame rings, for a grid of `n` x `n` cells (the finest family's), differ
/// by less than [`MIN_RING_CONTRAST`].
pub(crate) fn plainly_not_a_tag(
    img: &GrayView<'_>,
    cand: &Candidate,
    scale: f64,
    n: usize,
) -> bool {
    let q = cand.corners.map(|p| to_full(p, scale));
    ring_too_flat(img, &q, n)
}

/// [`plainly_not_a_tag`] for a quad `q` already at full resolution.
fn ring_too_flat(img: &GrayView<'_>, q: &[[f64; 2]; 4], n: usize) -> bool {
    let shortest = (0..4)
        .map(|i| norm(sub(q[(i + 1) % 4], q[i])))
        .fold(f64::INFINITY, f64::min);
    if shortest < MIN_SIDE_PX {
        return false;
    }
    let Some(h) = Homography::from_points(&CORNERS, q) else {
        return false;
    };
    ring_levels(img, n, &h).is_some_and(|(white, black)| white - black < MIN_RING_CONTRAST)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::tag_image;
    use image::GrayImage;

    /// `img` averaged over `(2r + 1)^2` pixels: a strong blur.
    fn box_blur(img: &GrayImage, r: i64) -> GrayImage {
        let (w, h) = (i64::from(img.width()), i64::from(img.height()));
        GrayImage::from_fn(img.width(), img.height(), |x, y| {
            let (mut sum, mut count) = (0u32, 0u32);
            for yy in (i64::from(y) - r).max(0)..=(i64::from(y) + r).min(h - 1) {
                for xx in (i64::from(x) - r).max(0)..=(i64::from(x) + r).min(w - 1) {
                    sum += u32::from(img.get_pixel(xx as u32, yy as u32)[0]);
                    count += 1;
                }
            }
            image::Luma([(sum / count) as u8])
        })
    }

    fn shifted(q: &[[f64; 2]; 4], d: [[f64; 2]; 4]) -> [[f64; 2]; 4] {
        std::array::from_fn(|k| [q[k][0] + d[k][0], q[k][1] + d[k][1]])
    }

    #[test]
    fn a_real_tag_passes_even_with_coarse_corners() {
        let (img, q) = tag_image(77, 96.0, [160.0, 160.0], 0.3);
        assert!(!ring_too_flat(&(&img).into(), &q, 14));
        // Each corner up to 2 px off, as a half-resolution quad's are.
        let off = shifted(&q, [[2.0, -1.5], [-2.0, 1.0], [1.5, 2.0], [-1.0, -2.0]]);
        assert!(!ring_too_flat(&(&img).into(), &off, 14));
    }

    #[test]
    fn a_blurred_tag_passes() {
        let (img, q) = tag_image(77, 60.0, [160.0, 160.0], 0.5);
        let blurred = box_blur(&img, 2);
        let off = shifted(&q, [[1.5, 0.0], [0.0, 1.5], [-1.5, 0.0], [0.0, -1.5]]);
        assert!(!ring_too_flat(&(&blurred).into(), &off, 14));
    }

    #[test]
    fn a_tag_under_a_stick_or_in_shadow_passes() {
        let (mut img, q) = tag_image(77, 100.0, [160.0, 160.0], 0.0);
        // A dark stick 12 px wide across the whole tag.
        for y in 150..162 {
            for x in 0..320 {
                img.put_pixel(x, y, image::Luma([40]));
            }
        }
        assert!(!ring_too_flat(&(&img).into(), &q, 14));
        // A shadow over the left half: 220 -> 80, 30 -> 11.
        for y in 0..320 {
            for x in 0..160 {
                let p = img.get_pixel(x, y)[0];
                img.put_pixel(x, y, image::Luma([(f64::from(p) * 0.36) as u8]));
            }
        }
        assert!(!ring_too_flat(&(&img).into(), &q, 14));
    }

    #[test]
    fn small_quads_are_left_to_the_decoder() {
        // A flat grey image: any quad has no ring contrast, but one under
        // MIN_SIDE_PX is not judged.
        let img = GrayImage::from_pixel(320, 320, image::Luma([128]));
        let small = [
            [100.0, 100.0],
            [100.0, 140.0],
            [140.0, 140.0],
            [140.0, 100.0],
        ];
        assert!(!ring_too_flat(&(&img).into(), &small, 14));
        let large = [
            [100.0, 100.0],
            [100.0, 160.0],
            [160.0, 160.0],
            [160.0, 100.0],
        ];
        assert!(ring_too_flat(&(&img).into(), &large, 14));
    }

    #[test]
    fn clutter_quads_are_refused() {
        let (img, q) = tag_image(77, 96.0, [160.0, 160.0], 0.0);
        let view: GrayView<'_> = (&img).into();
        // The quad of the frame's outer border: its "margin" is the black
        // frame and its "frame" the white page.
        let outer = q.map(|p| [160.0 + (p[0] - 160.0) * 1.25, 160.0 + (p[1] - 160.0) * 1.25]);
        assert!(ring_too_flat(&view, &outer, 14));
        // A quad on the white page beside the tag.
        let page = [[2.0, 2.0], [2.0, 80.0], [80.0, 80.0], [80.0, 2.0]];
        assert!(ring_too_flat(&view, &page, 14));
    }
}

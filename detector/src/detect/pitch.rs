//! Which family's cell grid a quad's data square shows, read off where its
//! edges lie.
//!
//! A ct8 tag and a ct14 tag share their whole fixed look (frame, disc,
//! ears): only the cells tell them apart. A quad of one family decoded as
//! the other reads nothing, after every reading the decoder has (hard,
//! levelled, by likelihood, by the nearest codeword), and on a tag too
//! blurred to decode, after the rim look's moves too: on the wild
//! benchmark's 1080p frames read for ct14 alone, the ct8 tags' rims cost
//! 4.5 ms each. The cells' edges lie on the family's grid lines, every
//! `S / (n + 2)`; the edge strength along a row of the square, as a
//! function of the position, repeats at that period, in phase with the
//! square's corners. Its Fourier coefficient at the grid's frequency,
//! taken at the phase the corners fix (a matched filter), is large for
//! the family printed and about nothing for the other, whose lines fall
//! at every phase.

use crate::family::Family;
use crate::geometry::CORNERS;
use crate::homography::Homography;
use crate::math::sampler_within;
use crate::view::GrayView;

/// Samples along each line across the data square: four per ct14 cell,
/// so that a difference of neighbours sits on every ct14 grid line, and
/// the ct8 cell's period (6.4 samples) is well resolved.
const SAMPLES: usize = 64;

/// Lines across the data square each way, evenly spaced (one through
/// each ct14 cell row): every line crosses the same grid lines, so more
/// of them only average the cells' edges out over more rows, and the
/// samples are most of the cost (a refusal must cost far less than the
/// 0.3 ms of a failed reading).
const LINES: usize = 16;

/// Differences of neighbours left out at each end of a line: the first
/// few lie on the black frame's edge (blurred into the square on a small
/// tag), on the grid lines of both families alike.
const EDGE_SKIP: usize = 3;

/// The share of the edge strength in phase with each grid of `grids`
/// (cells per side) on the data square `q` (corners TL, BL, BR, TR, px)
/// of `img`: from 1 (all edges on the grid lines) through 0 (no
/// preference) to -1 (all edges halfway between). `None` when the square
/// leaves the image, is no convex quad, or shows no edge.
fn grid_phase<const N: usize>(
    img: &GrayView<'_>,
    q: &[[f64; 2]; 4],
    grids: [usize; N],
) -> Option<[f64; N]> {
    let h = Homography::from_points(&CORNERS, q)?;
    let sample = sampler_within(img, q)?;
    let m = h.matrix();
    let m: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)]));
    // The homography's weight is affine in (u, v): of one sign at the four
    // corners, it keeps it over the whole square, which then maps onto the
    // convex quad between the corners, inside the image (`sampler_within`).
    let weight = |[u, v]: [f64; 2]| m[2][0] * u + m[2][1] * v + m[2][2];
    let signs = CORNERS.map(|c| weight(c) > 0.0);
    if signs.iter().any(|&s| s != signs[0]) || CORNERS.iter().any(|&c| weight(c) == 0.0) {
        return None;
    }
    // The homography written out, as in `Homography::map` but without its
    // `Option` per point (the weight cannot vanish, above): the samples
    // are most of this step's cost.
    let at = |u: f64, v: f64| {
        let w = 1.0 / (m[2][0] * u + m[2][1] * v + m[2][2]);
        sample(
            (m[0][0] * u + m[0][1] * v + m[0][2]) * w,
            (m[1][0] * u + m[1][1] * v + m[1][2]) * w,
        )
    };
    let pos = |k: usize, of: usize| -0.5 + (k as f64 + 0.5) / of as f64;
    // Edge strength between neighbours k and k + 1 along a line lies at
    // (k + 1) / SAMPLES from the square's side; summed over the lines of
    // both directions, it is a profile of that position alone.
    let mut profile = [0.0f64; SAMPLES - 1];
    for i in 0..LINES {
        let across = pos(i, LINES);
        let row: [f64; SAMPLES] = std::array::from_fn(|k| at(pos(k, SAMPLES), across));
        let column: [f64; SAMPLES] = std::array::from_fn(|k| at(across, pos(k, SAMPLES)));
        for l in [row, column] {
            for (p, w) in profile.iter_mut().zip(l.windows(2)) {
                *p += (w[1] - w[0]).abs();
            }
        }
    }
    let used = EDGE_SKIP..SAMPLES - 1 - EDGE_SKIP;
    let total: f64 = profile[used.clone()].iter().sum();
    if total <= 0.0 {
        return None;
    }
    Some(grids.map(|n| {
        let period = (n + 2) as f64;
        used.clone()
            .map(|k| {
                let u = (k + 1) as f64 / SAMPLES as f64;
                profile[k] * (std::f64::consts::TAU * period * u).cos()
            })
            .sum::<f64>()
            / total
    }))
}

/// Least phase ([`grid_phase`]) of a grid that [`shown_grid`] names. On
/// the wild set (3000 frames, ct14) and its ct8 twin (the same spec with
/// ct8 tags, every third scene: 1000 frames) the squares that read a tag
/// of their own family showed the other family's grid at a phase of at
/// most 0.067 (ct8's on ct14 tags) and 0.051 (ct14's on ct8 tags), while
/// the ct8 tags of the wild benchmark's 1080p frames that ct14 tried to
/// read showed theirs at up to 0.6, above 0.12 on a third of all the
/// squares read there.
const MIN_SHOWN_PHASE: f64 = 0.12;

/// Least lead of the grid [`shown_grid`] names over the other's phase: on
/// the same readings the other family's grid led the family read by at
/// most 0.117 (at a phase far under [`MIN_SHOWN_PHASE`], on a square whose
/// own grid was in counter-phase, half a cell off).
const MIN_SHOWN_LEAD: f64 = 0.1;

/// The built-in families' grids (cells per side), whose phases
/// [`shown_grid`] compares.
fn builtin_grids() -> [usize; 2] {
    [Family::ct8().grid(), Family::ct14().grid()]
}

/// The grid (cells per side) of the built-in family whose cells the data
/// square `q` (corners TL, BL, BR, TR, px) of `img` clearly shows: its
/// phase at least [`MIN_SHOWN_PHASE`] and [`MIN_SHOWN_LEAD`] over the
/// other's. `None` when neither does, as on a square too blurred or too
/// small for its cells' edges to show, or on clutter.
pub(crate) fn shown_grid(img: &GrayView<'_>, q: &[[f64; 2]; 4]) -> Option<usize> {
    let grids = builtin_grids();
    let [a, b] = grid_phase(img, q, grids)?;
    if a >= MIN_SHOWN_PHASE && a - b >= MIN_SHOWN_LEAD {
        Some(grids[0])
    } else if b >= MIN_SHOWN_PHASE && b - a >= MIN_SHOWN_LEAD {
        Some(grids[1])
    } else {
        None
    }
}

/// Whether a square showing grid `shown` ([`shown_grid`]) cannot be a
/// tag of `family`: a built-in family of another grid. A family of any
/// other grid was never measured against them and is not ruled out.
pub(crate) fn rules_out(shown: usize, family: &Family) -> bool {
    let g = family.grid();
    g != shown && builtin_grids().contains(&g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::family_tag_image;

    /// The grid `shown_grid` names on a tag of `fam` with a data square
    /// of `side` px, box-blurred `blur` times.
    fn shown(fam: &Family, id: u64, side: f64, turn: f64, blur: usize) -> Option<usize> {
        let (mut img, q) = family_tag_image(fam, id, side, [160.0, 160.0], turn);
        for _ in 0..blur {
            img = imageproc::filter::box_filter(&img, 1, 1);
        }
        shown_grid(&GrayView::from(&img), &q)
    }

    #[test]
    fn each_family_shows_its_own_grid() {
        for (k, id) in [3u64, 77, 200, 255].into_iter().enumerate() {
            let turn = 0.4 * k as f64;
            for side in [40.0, 90.0, 160.0] {
                assert_eq!(
                    shown(Family::ct14(), id, side, turn, 0),
                    Some(14),
                    "ct14 {id} {side}"
                );
                assert_eq!(
                    shown(Family::ct8(), id * 211, side, turn, 0),
                    Some(8),
                    "ct8 {id} {side}"
                );
            }
        }
    }

    #[test]
    fn a_square_too_blurred_for_its_cells_shows_none() {
        // Cells of 1.5 px (ct14 at 24 px), blurred over two cells.
        assert_eq!(shown(Family::ct14(), 77, 24.0, 0.3, 3), None);
    }

    #[test]
    fn a_plain_or_striped_square_shows_none() {
        // A white square in a black frame, and one striped at a period
        // neither family has.
        for period in [None, Some(7.0)] {
            let img = image::GrayImage::from_fn(200, 200, |x, y| {
                let (dx, dy) = (f64::from(x) - 100.0, f64::from(y) - 100.0);
                let inner = dx.abs().max(dy.abs()) < 40.0;
                let dark = match (inner, period) {
                    (false, _) => dx.abs().max(dy.abs()) < 50.0,
                    (true, None) => false,
                    (true, Some(p)) => (dx / p).rem_euclid(2.0) < 1.0,
                };
                image::Luma([if dark { 30 } else { 220 }])
            });
            let q = [[60.0, 60.0], [60.0, 140.0], [140.0, 140.0], [140.0, 60.0]];
            assert_eq!(shown_grid(&GrayView::from(&img), &q), None, "{period:?}");
        }
    }

    #[test]
    fn a_square_off_the_image_or_no_square_shows_none() {
        let (img, q) = family_tag_image(Family::ct8(), 4321, 90.0, [160.0, 160.0], 0.2);
        let view = GrayView::from(&img);
        assert_eq!(shown_grid(&view, &q), Some(8));
        let shifted = q.map(|p| [p[0] + 200.0, p[1]]);
        let mut nan = q;
        nan[2] = [f64::NAN, 100.0];
        let point = [q[0]; 4];
        // TL and BL swapped: the sides cross (a bow tie).
        let bow = [q[1], q[0], q[2], q[3]];
        for bad in [shifted, nan, point, bow] {
            assert_eq!(shown_grid(&view, &bad), None, "{bad:?}");
        }
        let empty = image::GrayImage::new(0, 0);
        assert_eq!(shown_grid(&GrayView::from(&empty), &q), None);
    }

    #[test]
    fn only_the_other_builtin_grid_is_ruled_out() {
        assert!(rules_out(8, Family::ct14()));
        assert!(rules_out(14, Family::ct8()));
        assert!(!rules_out(14, Family::ct14()));
        assert!(!rules_out(8, Family::ct8()));
    }
}

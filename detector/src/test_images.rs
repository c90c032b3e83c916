//! Synthetic tag images for the crate's unit tests.

use image::GrayImage;

use crate::family::Family;
use crate::geometry::{B, CORNERS};
use crate::grid_code::encode_cells;

/// Grey level of the printed black in [`tag_image`].
pub(crate) const INK: u8 = 30;
/// Grey level of the page in [`tag_image`].
pub(crate) const PAGE: u8 = 220;

/// Whether point `(u, v)` of the data square (tag units, centre 0, side 1)
/// of a tag with `n` x `n` cells `cells` is black: a black cell, not the
/// white margin.
pub(crate) fn data_black(cells: &[bool], n: usize, u: f64, v: f64) -> bool {
    let step = 1.0 / (n as f64 + 2.0);
    let (j, i) = ((u + 0.5) / step - 1.0, (v + 0.5) / step - 1.0);
    let inside = |k: f64| (0.0..n as f64).contains(&k);
    inside(i) && inside(j) && cells[i as usize * n + j as usize]
}

/// A 320 x 320 image of ct14 tag `id` with data-square side `side` px
/// centred at `c`, turned by `turn` radians, on a white page: black frame,
/// white margin, cells; and its corners TL, BL, BR, TR (pixel-centre
/// coordinates).
pub(crate) fn tag_image(id: u64, side: f64, c: [f64; 2], turn: f64) -> (GrayImage, [[f64; 2]; 4]) {
    family_tag_image(Family::ct14(), id, side, c, turn)
}

/// [`tag_image`] of a tag of family `fam`.
pub(crate) fn family_tag_image(
    fam: &Family,
    id: u64,
    side: f64,
    c: [f64; 2],
    turn: f64,
) -> (GrayImage, [[f64; 2]; 4]) {
    cells_image(fam.grid(), &encode_cells(fam, id).unwrap(), side, c, turn)
}

/// [`tag_image`] of a tag whose `n` x `n` cells are `cells` (row-major,
/// true for black), whatever code they hold.
pub(crate) fn cells_image(
    n: usize,
    cells: &[bool],
    side: f64,
    c: [f64; 2],
    turn: f64,
) -> (GrayImage, [[f64; 2]; 4]) {
    let (cs, sn) = (turn.cos(), turn.sin());
    let img = GrayImage::from_fn(320, 320, |x, y| {
        let (dx, dy) = (f64::from(x) - c[0], f64::from(y) - c[1]);
        let (u, v) = ((cs * dx + sn * dy) / side, (-sn * dx + cs * dy) / side);
        let black = if u.abs().max(v.abs()) > 0.5 + B {
            false
        } else if u.abs().max(v.abs()) > 0.5 {
            true
        } else {
            data_black(cells, n, u, v)
        };
        image::Luma([if black { INK } else { PAGE }])
    });
    let corners = CORNERS.map(|[u, v]| {
        let (x, y) = (u * side, v * side);
        [c[0] + cs * x - sn * y, c[1] + sn * x + cs * y]
    });
    (img, corners)
}

//! Reading a tag smeared by straight-line motion: the cells against every
//! codeword as a motion blur shows it.
//!
//! [`crate::likelihood`] compares the cells with every codeword under a
//! round (Gaussian) blur, the model of defocus. A robot or a part moving
//! during the exposure smears the tag along one direction instead: along
//! it a cell mixes with two or three of its neighbours, across it with
//! none. A round blur wide enough to explain the smear blurs the other
//! axis too, and no codeword fits clearly. On the wild set, ct14 tags whose
//! motion blur spanned 2 to 3 cells read at their true corners 78% and
//! 21% of the time, against 99-100% for those smeared a cell or less.
//!
//! The smear's direction shows in the cells themselves: along it the
//! samples change little from cell to cell, across it as much as ever. The
//! eigenvectors of the cells' structure tensor (the summed outer products
//! of their gradients) give it; the length is not known, so a few are
//! tried. Each codeword is then blurred by the segment of that direction
//! and length (and by the camera's own slight round blur) and fitted as
//! the round templates are: the whole codebook scored on the blurred
//! samples by table look-ups, the best ids on exact templates, the best of
//! those on their best-fitting cells, and a reading stands only with the
//! same clear lead over any other id ([`LikelyFit::reads`]).
//!
//! Motion blur as a box along a segment is the textbook model (e.g.
//! Gonzalez & Woods, "Digital Image Processing", 5.6); the structure
//! tensor is Harris and Stephens' (1988). Its use on a tag's cell grid is
//! this crate's own.

use crate::deblur::outside;
use crate::likelihood::{leading, plain_fit, trimmed, Codebook, LikelyFit};

/// Lengths (cells) of the smears tried. A smear under about one and a half
/// cells leaves the round templates' narrow widths a fit; past 4 cells a
/// 14-cell grid's rows average to nearly the same grey.
const LENGTHS: [f64; 6] = [1.5, 2.0, 2.5, 3.0, 3.5, 4.0];

/// Index in [`LENGTHS`] of the smear every codeword is first scored at.
const COARSE_LENGTH: usize = 2;

/// Round template (index in the likelihood reading's widths: 0.6 cells)
/// whose sums stand in for the middle smear's in the first round: the
/// spread of a 2.5-cell box along the smear and the base blur across it
/// average about 0.6 cells.
const COARSE_SUMS: usize = 1;

/// Round blur (cells) added to every smear: the lens and the sensor's
/// pixels soften even a still tag (the narrowest of the round templates).
/// Trying a wider one too (0.8 cells) at every length found fewer of the
/// wild set's tags (3503 against 3556): more templates bring some other
/// id's fit nearer the best one's, and the lead the reading needs is
/// lost more often than a smear is better fitted.
const BASE_SIGMA: f64 = 0.45;

/// Points along the smear's segment whose blurred spots make up its
/// kernel: a tenth of a cell apart at the longest smear.
const SEGMENT_POINTS: usize = 32;

/// Cells the kernel reaches on each side: half the longest smear plus
/// three round-blur widths.
const REACH: i64 = 4;

/// Kernel weights under this share of the whole are dropped: they move a
/// sample by under a thousandth of the contrast.
const MIN_WEIGHT: f64 = 1e-3;

/// Most the smaller eigenvalue of the cells' structure tensor may be, as
/// a share of the larger, for the cells to count as smeared along one
/// direction. Unblurred or round-blurred cells show about as much change
/// along every direction; a smear of two cells roughly halves the change
/// along it. On the wild set (3000 frames): at 0.55, 3556 tags found; at
/// 0.7, 3583; at 0.85, 3598 but one with a corner over 3 px off; with no
/// bound, 3602 and the same rough one. Each step tries the smear on more
/// grids (0.55 let through about half of those that reached it).
const MAX_ANISOTROPY: f64 = 0.7;

/// Directions of smear whose kernels are tabled, over half a turn: two
/// degrees apart, so a smear's ends lie within 0.035 cells of the tabled
/// segment's at the longest length.
const DIRECTIONS: usize = 90;

/// The first round's best id must fit better than the second by this
/// factor (ratio of plain scores) for the finer rounds to run, as in the
/// round reading: quads that are no tag fit many ids about equally.
const COARSE_LEAD: f64 = 0.6;

/// Ids scored on exact templates after the first round.
const FINE_IDS: usize = 8;

/// Ids scored on their best-fitting cells.
const TRIMMED_IDS: usize = 8;

/// A blur kernel on the cell grid: offsets (row, column) and weights.
type Kernel = Vec<(i64, i64, f64)>;

/// A smear's kernel and what the tag's margin and frame around a grid of
/// `n` x `n` cells add to each cell's sample through it.
struct Smear {
    kernel: Kernel,
    around: Vec<f64>,
}

/// The smears of tabled direction `a` (the angle `a * 180 / DIRECTIONS`
/// degrees from a row) at every length ([`LENGTHS`]) for a grid of `n`
/// cells, each direction made once, when first needed (a few hundred
/// microseconds).
fn smears(a: usize, n: usize) -> &'static [Smear] {
    use std::sync::OnceLock;
    static TABLE: [OnceLock<(usize, Vec<Smear>)>; DIRECTIONS] =
        [const { OnceLock::new() }; DIRECTIONS];
    let make = || {
        let angle = (a % DIRECTIONS) as f64 * std::f64::consts::PI / DIRECTIONS as f64;
        let (uy, ux) = angle.sin_cos();
        let ni = n as i64;
        let list = LENGTHS
            .iter()
            .map(|&l| {
                let kernel = smear_kernel(ux, uy, l);
                let around = blur(&vec![0.0; n * n], n, &kernel, |i, j| outside(i, j, ni));
                Smear { kernel, around }
            })
            .collect();
        (n, list)
    };
    let (grid, list) = TABLE[a % DIRECTIONS].get_or_init(make);
    // One codebook (ct14's) reads smears; another grid side would need
    // its own table.
    debug_assert_eq!(*grid, n);
    list
}

/// The tabled direction ([`kernels`]) nearest the unit vector `(ux, uy)`.
fn direction_index(ux: f64, uy: f64) -> usize {
    let angle = uy.atan2(ux).rem_euclid(std::f64::consts::PI);
    (angle / std::f64::consts::PI * DIRECTIONS as f64).round() as usize % DIRECTIONS
}

/// The kernel of a smear `length` cells long along the unit direction
/// `(ux, uy)` (x along a row, y down the columns), with the round
/// [`BASE_SIGMA`] on top: each point of the segment spread over the cells
/// by a Gaussian, its mass over each cell taken from the error function.
fn smear_kernel(ux: f64, uy: f64, length: f64) -> Kernel {
    let side = (2 * REACH + 1) as usize;
    let mut w = vec![0.0; side * side];
    let mass = |d: f64| {
        let s = BASE_SIGMA * std::f64::consts::SQRT_2;
        0.5 * (libm::erf((d + 0.5) / s) - libm::erf((d - 0.5) / s))
    };
    for p in 0..SEGMENT_POINTS {
        let t = ((p as f64 + 0.5) / SEGMENT_POINTS as f64 - 0.5) * length;
        let (cx, cy) = (t * ux, t * uy);
        let mx: Vec<f64> = (-REACH..=REACH).map(|d| mass(d as f64 - cx)).collect();
        let my: Vec<f64> = (-REACH..=REACH).map(|d| mass(d as f64 - cy)).collect();
        for (i, wy) in my.iter().enumerate() {
            for (j, wx) in mx.iter().enumerate() {
                w[i * side + j] += wy * wx;
            }
        }
    }
    let total: f64 = w.iter().sum();
    let mut k = Kernel::new();
    for (idx, &v) in w.iter().enumerate() {
        if v / total >= MIN_WEIGHT {
            let (i, j) = ((idx / side) as i64 - REACH, (idx % side) as i64 - REACH);
            k.push((i, j, v));
        }
    }
    let kept: f64 = k.iter().map(|t| t.2).sum();
    for t in &mut k {
        t.2 /= kept;
    }
    k
}

/// `x` (an `n` x `n` grid, row-major) blurred by `kernel`, with `beyond`
/// giving what lies outside the grid.
fn blur(x: &[f64], n: usize, kernel: &Kernel, beyond: impl Fn(i64, i64) -> f64) -> Vec<f64> {
    let ni = n as i64;
    let mut out = vec![0.0; n * n];
    for i in 0..ni {
        for j in 0..ni {
            let mut s = 0.0;
            for &(di, dj, w) in kernel {
                let (a, b) = (i + di, j + dj);
                s += w * if (0..ni).contains(&a) && (0..ni).contains(&b) {
                    x[(a * ni + b) as usize]
                } else {
                    beyond(a, b)
                };
            }
            out[(i * ni + j) as usize] = s;
        }
    }
    out
}

/// `x` (an `n` x `n` grid, row-major) blurred by `kernel` with nothing
/// beyond the grid. Taken tap by tap over whole runs of a row, slice by
/// slice, which the compiler vectorises (this runs for every template of
/// the finer rounds; [`blur`] tests every term).
fn blur_inside(x: &[f64], n: usize, kernel: &Kernel) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    let ni = n as i64;
    for &(di, dj, w) in kernel {
        // Cells (i, j) take x[i + di][j + dj] where that is inside.
        let rows = (-di).max(0)..(ni - di).min(ni);
        let (j0, j1) = ((-dj).max(0), (ni - dj).min(ni));
        if j0 >= j1 {
            continue;
        }
        let len = (j1 - j0) as usize;
        for i in rows {
            let src = &x[((i + di) * ni + j0 + dj) as usize..][..len];
            let dst = &mut out[(i * ni + j0) as usize..][..len];
            for (d, &v) in dst.iter_mut().zip(src) {
                *d += w * v;
            }
        }
    }
    out
}

/// The template of the seen grid `seen` (`n` x `n`, 0 black, 1 white, 0.5
/// under the centre checker) through smear `sm`, on the `informative`
/// cells: the grid blurred, plus what the margin and frame add.
fn template(seen: &[f64], n: usize, sm: &Smear, informative: &[usize]) -> Vec<f64> {
    let inside = blur_inside(seen, n, &sm.kernel);
    informative
        .iter()
        .map(|&c| inside[c] + sm.around[c])
        .collect()
}

/// The direction along which the cells `y` of a grid of `n` x `n` change
/// least, as a unit vector (x along a row, y down the columns), when it is
/// clearly one ([`MAX_ANISOTROPY`]): the eigenvector of the smaller
/// eigenvalue of the structure tensor of the central differences taken
/// between informative cells.
fn smear_direction(y: &[f64], n: usize, informative: &[bool]) -> Option<(f64, f64)> {
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for i in 1..n - 1 {
        for j in 1..n - 1 {
            let (l, r, u, d) = (
                i * n + j - 1,
                i * n + j + 1,
                (i - 1) * n + j,
                (i + 1) * n + j,
            );
            if ![l, r, u, d].iter().all(|&c| informative[c]) {
                continue;
            }
            let gx = y[r] - y[l];
            let gy = y[d] - y[u];
            sxx += gx * gx;
            sxy += gx * gy;
            syy += gy * gy;
        }
    }
    let tr = sxx + syy;
    if tr <= 1e-9 {
        return None;
    }
    let disc = ((sxx - syy).powi(2) + 4.0 * sxy * sxy).sqrt();
    let (big, small) = (0.5 * (tr + disc), 0.5 * (tr - disc));
    if small > MAX_ANISOTROPY * big {
        return None;
    }
    // Eigenvector of the smaller eigenvalue.
    let (vx, vy) = if sxy.abs() > 1e-12 {
        (small - syy, sxy)
    } else if sxx < syy {
        (1.0, 0.0)
    } else {
        (0.0, 1.0)
    };
    let len = vx.hypot(vy);
    Some((vx / len, vy / len))
}

/// The best codeword of `book` for the cells' whiteness `y` (as for
/// [`crate::likelihood::read_likely`]) under a straight-line motion blur
/// along the direction the cells show ([`smear_direction`]), and how
/// clearly it wins; `None` when the cells show no such direction or no
/// codeword fits.
pub(crate) fn read_smeared(book: &Codebook, y: &[f64]) -> Option<LikelyFit> {
    let n = book.grid();
    if y.len() != n * n {
        return None;
    }
    let informative = book.informative();
    let mut is_inf = vec![false; n * n];
    for &c in informative {
        is_inf[c] = true;
    }
    let (ux, uy) = smear_direction(y, n, &is_inf)?;
    let smears = smears(direction_index(ux, uy), n);
    let k = informative.len() as f64;
    let ys: Vec<f64> = informative.iter().map(|&c| y[c]).collect();
    let y_sums = (ys.iter().sum(), ys.iter().map(|v| v * v).sum());

    // Round 1: every codeword at the middle length, by look-ups of the
    // blurred samples (the segment is symmetric, so `<y, B x> = <B y, x>`);
    // the templates' own sums are taken from the round template of the
    // same spread, which only orders the ids for the next round.
    let mut masked = vec![0.0; n * n];
    for &c in informative {
        masked[c] = y[c];
    }
    let coarse_smear = &smears[COARSE_LENGTH];
    let z = blur_inside(&masked, n, &coarse_smear.kernel);
    let outside_dot: f64 = informative
        .iter()
        .map(|&c| y[c] * coarse_smear.around[c])
        .sum();
    let coarse = book.score_all(&z, outside_dot, y_sums, COARSE_SUMS, &mut Vec::new());
    let order = leading(&coarse, COARSE_LEAD, FINE_IDS)?;

    // Round 2: those ids at their best rotation, at every length, on
    // exact templates: (score, id index, template).
    let mut fine: Vec<(f64, usize, Vec<f64>)> = order
        .iter()
        .filter_map(|&i| {
            let seen = book.seen_grid(i, coarse[i].1);
            smears
                .iter()
                .filter_map(|sm| {
                    let t = template(&seen, n, sm, informative);
                    let dot = t.iter().zip(&ys).map(|(a, b)| a * b).sum();
                    let ts = (t.iter().sum(), t.iter().map(|v| v * v).sum());
                    plain_fit(dot, ts, y_sums, k).map(|(_, _, score)| (score, i, t))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        })
        .collect();
    fine.sort_by(|a, b| a.0.total_cmp(&b.0));
    fine.truncate(TRIMMED_IDS);

    // Round 3: the best of those on their best-fitting cells.
    let mut scored: Vec<(f64, usize, f64)> = fine
        .iter()
        .filter_map(|(_, i, t)| trimmed(t, &ys).map(|(score, a)| (score, *i, a)))
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    let &(r1, i, a) = scored.first()?;
    let r2 = scored.get(1).map_or(f64::INFINITY, |s| s.0);
    Some(book.smeared_fit(i, coarse[i].1, r1 / r2, a))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;
    use crate::grid_code::seen_whiteness;
    use crate::likelihood::read_likely;

    /// The seen whiteness of ct14 tag `id` at `d` quarter turns, smeared
    /// `length` cells along `angle` (radians from a row), at a contrast of
    /// 0.8 over a black level of 0.1, with a deterministic noise of
    /// amplitude `noise`.
    fn smeared(id: u64, d: usize, angle: f64, length: f64, noise: f64) -> Vec<f64> {
        let fam = Family::ct14();
        let n = fam.grid();
        let ni = n as i64;
        let (uy, ux) = angle.sin_cos();
        let g = seen_whiteness(fam, id, d);
        blur(&g, n, &smear_kernel(ux, uy, length), |i, j| {
            outside(i, j, ni)
        })
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let h = ((i as f64 + 1.0) * 12.9898).sin() * 43_758.545;
            0.1 + 0.8 * v + noise * (h - h.floor() - 0.5)
        })
        .collect()
    }

    #[test]
    fn a_smeared_tag_the_round_templates_miss_is_read() {
        let book = Family::ct14().codebook().unwrap();
        // Smears the round templates miss (those they read say nothing
        // here): two thirds read (6 of 9 when written; the others show no
        // clear direction or lead), none as another id or rotation.
        let (mut missed, mut read) = (0, 0);
        for k in 0..24u64 {
            let (id, d) = (k * 11 % 256, (k % 4) as usize);
            let angle = k as f64 * 0.37;
            let length = [2.5, 3.0, 3.5][(k % 3) as usize];
            let y = smeared(id, d, angle, length, 0.04);
            if read_likely(book, &y).is_some_and(|r| r.reads()) {
                continue;
            }
            missed += 1;
            if let Some(fit) = read_smeared(book, &y).filter(LikelyFit::reads) {
                assert_eq!((fit.id, fit.rotation), (id, d), "case {k}: a wrong id");
                read += 1;
            }
        }
        assert!(
            missed >= 8,
            "only {missed} smears defeat the round templates"
        );
        assert!(read * 3 >= missed * 2, "{read} of {missed} smears read");
    }

    #[test]
    fn the_smear_direction_is_found() {
        let fam = Family::ct14();
        let n = fam.grid();
        let inf: Vec<bool> = (0..n * n).map(|c| !fam.is_covered(c)).collect();
        for (k, angle) in [0.0f64, 0.5, 1.0, 1.6, 2.2, 2.9].into_iter().enumerate() {
            let y = smeared(40 + k as u64 * 30, k % 4, angle, 3.0, 0.0);
            let (ux, uy) = smear_direction(&y, n, &inf).expect("a direction");
            // Unsigned: the angle between the lines.
            let cos = (ux * angle.cos() + uy * angle.sin()).abs();
            // The cells of one 14-cell code show the direction to within
            // about 20 degrees.
            assert!(
                cos > 20f64.to_radians().cos(),
                "angle {angle}: got ({ux}, {uy})"
            );
        }
    }

    #[test]
    fn sharp_tags_read_as_themselves_or_not_at_all() {
        // The direction's bound is loose (a sharp code's cells may show
        // some direction), so the smear may be tried on a sharp tag: it
        // must then read that tag or nothing.
        let book = Family::ct14().codebook().unwrap();
        for k in 0..64u64 {
            let (id, d) = (k * 37 % 256, (k % 4) as usize);
            let y = smeared(id, d, 0.0, 0.0, 0.04);
            if let Some(fit) = read_smeared(book, &y).filter(LikelyFit::reads) {
                assert_eq!((fit.id, fit.rotation), (id, d), "tag {id}");
            }
        }
    }

    #[test]
    fn flat_and_random_grids_are_not_read() {
        let book = Family::ct14().codebook().unwrap();
        assert!(read_smeared(book, &vec![0.5; 196]).is_none_or(|r| !r.reads()));
        // Smooth stripes and blobs, as clutter quads show, along many
        // directions.
        for seed in 0..200u64 {
            let s = seed as f64;
            let y: Vec<f64> = (0..196)
                .map(|i| {
                    let (r, c) = ((i / 14) as f64, (i % 14) as f64);
                    0.5 + 0.4
                        * ((r * (0.3 + 0.01 * s) + c * 0.9 + s).sin()
                            * (c * 0.2 + r * 0.05 * s).cos())
                })
                .collect();
            assert!(
                read_smeared(book, &y).is_none_or(|r| !r.reads()),
                "seed {seed}"
            );
        }
    }

    #[test]
    fn the_sliced_blur_is_the_plain_one() {
        let x: Vec<f64> = (0..196).map(|c| ((c * 7919) % 101) as f64 / 37.0).collect();
        for a in [0, 23, 61] {
            for sm in smears(a, 14) {
                let plain = blur(&x, 14, &sm.kernel, |_, _| 0.0);
                let sliced = blur_inside(&x, 14, &sm.kernel);
                assert!(plain
                    .iter()
                    .zip(&sliced)
                    .all(|(p, q)| (p - q).abs() < 1e-12));
            }
        }
    }

    #[test]
    fn kernels_are_normalised_and_symmetric() {
        for a in [0, 17, 45, 89] {
            for sm in smears(a, 14) {
                let total: f64 = sm.kernel.iter().map(|t| t.2).sum();
                assert!((total - 1.0).abs() < 1e-12);
                for &(i, j, w) in &sm.kernel {
                    let mirror = sm.kernel.iter().find(|t| t.0 == -i && t.1 == -j);
                    assert!(mirror.is_some_and(|m| (m.2 - w).abs() < 1e-9));
                }
            }
        }
    }
}

//! Reading a tag under uneven light by likelihood: the cells against
//! every codeword, with the light's shape across the tag fitted too.
//!
//! A glare spot on a laminated tag, a shadow's soft edge or a lamp's
//! fall-off adds a smooth field to the cells: the likelihood reading of
//! [`crate::likelihood`] fits one contrast and one black level per
//! codeword, and a field that lifts one side of the grid by as much as the
//! cells' own contrast leaves no codeword fitting clearly. Here each
//! codeword is fitted with its contrast and a quadratic field over the
//! grid (six terms), and cells whose samples the sensor clipped (where the
//! glare is brighter than white, black and white cells alike read 255)
//! are left out of the fit: they say nothing.
//!
//! Fitting a nuisance field by least squares and scoring what is left is
//! the generalised likelihood ratio test with a linear nuisance subspace
//! (Scharf and Friedlander, "Matched subspace detectors", IEEE Trans.
//! Signal Processing 42(8), 1994): the samples and each template are
//! projected off the field's span, and a codeword's score is the residual
//! its contrast leaves. Each template's components along the field's
//! terms over the whole grid are tabled in the codebook, so the first
//! round over all codewords takes the plain reading's dot products and a
//! few products per codeword; only the few best ids are fitted again on
//! the unclipped cells.

use crate::likelihood::{leading, Codebook, LikelyFit, SIGMAS};

/// Terms of the light field fitted with each codeword: 1, u, v, u^2, uv,
/// v^2 over the grid (u, v the cell's column and row about the centre, in
/// grid widths). A glare spot of a tenth to 0.4 of the tag's radius is not
/// quadratic, but over the cells it leaves unclipped its flank is close to
/// one; on the wild set's glared tags that no other reading read at their
/// true corners, a plane (three terms) read fewer than the quadratic.
pub(crate) const TERMS: usize = 6;

/// Fewest unclipped informative cells for a reading: a grid under a glare
/// that clips more leaves too few cells to tell 256 ids apart with six
/// terms of light fitted besides.
const MIN_SEEN_CELLS: usize = 40;

/// The first round's best id must leave at most this share of the second
/// id's residual for the finer rounds to run: most quads that are no tag
/// fit many ids about equally, and stop here (of the quads decoded to
/// nothing on 9 600 images holding no CopperTag, the peers' wild sets and
/// the tag-free photos, 329 went further).
const COARSE_LEAD: f64 = 0.8;

/// The best id's residual must be at most the second's over this factor.
/// Measured on the peers' wild sets and the tag-free photos (9 600 images
/// holding no CopperTag): the quads decoded to nothing there that reached
/// the second round led by at most 1.85. With the true corners of the
/// wild set's tags that no other reading read, no id read wrong at any
/// lead from 2 up. At 1.5 the detector found 92 more of the wild set's
/// markers than at 2, one of them rough (a measured corner 3.3 px off);
/// at 3, 74 fewer, none rough either way.
const MIN_RATIO: f64 = 2.0;

/// Ids scored on the unclipped cells at every blur after the first
/// round: with the true corners of the wild set's tags that no other
/// reading read, the first round ranked the true id first for 128 of 132
/// that this reading reads, and within the first 4 for 129 (each id more
/// costs seven template fits).
const SHADED_FINE_IDS: usize = 4;

/// The shading basis over `cells` (grid indices of an `n` x `n` grid),
/// orthonormal over the cells `keep` marks (zero on the others): the
/// field's terms (see [`TERMS`]) by Gram-Schmidt, dropping a term the
/// kept cells cannot tell from the others.
pub(crate) fn basis(n: usize, cells: &[usize], keep: &[bool]) -> Vec<Vec<f64>> {
    let half = (n as f64 - 1.0) / 2.0;
    let coord = |c: usize| {
        (
            ((c % n) as f64 - half) / n as f64,
            ((c / n) as f64 - half) / n as f64,
        )
    };
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(TERMS);
    for term in 0..TERMS {
        let mut v: Vec<f64> = cells
            .iter()
            .zip(keep)
            .map(|(&c, &k)| {
                if !k {
                    return 0.0;
                }
                let (u, w) = coord(c);
                match term {
                    0 => 1.0,
                    1 => u,
                    2 => w,
                    3 => u * u,
                    4 => u * w,
                    _ => w * w,
                }
            })
            .collect();
        let before = dot(&v, &v).sqrt();
        for q in &out {
            let a = dot(&v, q);
            for (x, y) in v.iter_mut().zip(q) {
                *x -= a * y;
            }
        }
        let norm = dot(&v, &v).sqrt();
        if norm > 1e-6 * before.max(1e-12) {
            for x in &mut v {
                *x /= norm;
            }
            out.push(v);
        }
    }
    out
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `v` on the cells `keep` marks, zero on the others.
fn kept(v: &[f64], keep: &[bool]) -> Vec<f64> {
    v.iter()
        .zip(keep)
        .map(|(&x, &k)| if k { x } else { 0.0 })
        .collect()
}

/// `v` with its components along the orthonormal vectors `q` removed.
fn project_out(q: &[Vec<f64>], v: &[f64]) -> Vec<f64> {
    let mut out = v.to_vec();
    for b in q {
        let a = dot(&out, b);
        for (x, y) in out.iter_mut().zip(b) {
            *x -= a * y;
        }
    }
    out
}

/// The best codeword of `book` for the cells' whiteness `y` (n x n,
/// row-major) under a smooth light field, cells marked `clipped` left
/// out, if it reads: one id fitting clearly better than every other
/// ([`MIN_RATIO`]).
///
/// Two rounds: every codeword at the middle blur, with the field fitted
/// over all informative cells (the projections tabled in the codebook);
/// then the [`SHADED_FINE_IDS`] best ids at their best rotation at every blur,
/// fitted on the unclipped cells alone.
pub(crate) fn read_shaded(
    book: &Codebook,
    y: &[f64],
    clipped: &[bool],
    dots: &[f64],
) -> Option<LikelyFit> {
    let n = book.grid();
    if y.len() != n * n || clipped.len() != n * n {
        return None;
    }
    let inf = book.informative();
    let keep: Vec<bool> = inf.iter().map(|&c| !clipped[c]).collect();
    if keep.iter().filter(|&&k| k).count() < MIN_SEEN_CELLS {
        return None;
    }
    // Round 1: every codeword, the field fitted over every informative
    // cell. For the samples `y'` off the field's span,
    // `<y', t> = <y, t> - sum_k <q_k, y> <q_k, t>`: the plain reading's
    // dot products less the tabled `<q_k, t>`, and the residual is
    // `|y'|^2 - <y', t>^2 / |t'|^2`.
    let yi: Vec<f64> = inf.iter().map(|&c| y[c]).collect();
    let along: Vec<f64> = book.shade_basis().iter().map(|q| dot(q, &yi)).collect();
    let yy = dot(&yi, &yi) - dot(&along, &along);
    let computed;
    let dots = if dots.len() == 4 * book.ids() {
        dots
    } else {
        computed = book.coarse_dots(y);
        &computed[..]
    };
    let mut coarse = vec![(f64::INFINITY, 0usize); book.ids()];
    for (j, &plain) in dots.iter().enumerate() {
        let (d, i) = (j / book.ids(), j % book.ids());
        let (proj, norm) = book.shade_coarse(d, i);
        let t = plain - dot(&along, proj);
        if t <= 0.0 || norm <= 1e-9 {
            continue;
        }
        let rss = yy - t * t / norm;
        if rss < coarse[i].0 {
            coarse[i] = (rss, d);
        }
    }
    let order = leading(&coarse, COARSE_LEAD, SHADED_FINE_IDS)?;

    // Round 2: those ids at every blur, on the unclipped cells.
    let q = basis(n, inf, &keep);
    let ymp = project_out(&q, &kept(&yi, &keep));
    let yy = dot(&ymp, &ymp);
    let mut fine: Vec<(f64, usize, usize, f64)> = order
        .iter()
        .filter_map(|&i| {
            let d = coarse[i].1;
            (0..SIGMAS.len())
                .filter_map(|s| {
                    let tp = project_out(&q, &kept(&book.template(i, d, s), &keep));
                    let norm = dot(&tp, &tp);
                    let a = dot(&ymp, &tp);
                    (a > 0.0 && norm > 1e-9).then(|| (yy - a * a / norm, i, s, a / norm))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0))
        })
        .collect();
    fine.sort_by(|a, b| a.0.total_cmp(&b.0));
    let &(r1, i, s, scale) = fine.first()?;
    let r2 = fine.get(1).map_or(f64::INFINITY, |f| f.0);
    (r1 * MIN_RATIO <= r2).then(|| book.fit_of(i, coarse[i].1, s, r1 / r2, scale))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;
    use crate::grid_code::seen_whiteness;
    use crate::likelihood::read_likely;

    fn book() -> &'static Codebook {
        Family::ct14().codebook().unwrap()
    }

    /// A small deterministic noise in -0.5..0.5 for cell `c` of grid `k`.
    fn noise(k: usize, c: usize) -> f64 {
        (((k * 7919 + c * 104_729) % 1000) as f64) / 1000.0 - 0.5
    }

    /// Tag `id` seen at `d` quarter turns under a lamp's fall-off and a
    /// glare spot at (`gx`, `gy`) (grid widths from the centre): the
    /// cells' whiteness with the light added, clipped at 1.3 (where the
    /// sensor saturates), and which cells clipped.
    fn lit(id: u64, d: usize, (gx, gy): (f64, f64), k: usize) -> (Vec<f64>, Vec<bool>) {
        let n = 14;
        let half = (n as f64 - 1.0) / 2.0;
        let mut y = seen_whiteness(Family::ct14(), id, d);
        let mut clipped = vec![false; n * n];
        for (c, v) in y.iter_mut().enumerate() {
            let u = ((c % n) as f64 - half) / n as f64;
            let w = ((c / n) as f64 - half) / n as f64;
            let field =
                0.6 * u + 0.3 * w + 0.9 * (-((u - gx).powi(2) + (w - gy).powi(2)) / 0.25).exp();
            *v = *v * 0.8 + field + 0.08 * noise(k, c);
            if *v >= 1.3 {
                *v = 1.3;
                clipped[c] = true;
            }
        }
        (y, clipped)
    }

    /// A tag under a lamp's fall-off across it and a glare spot clipping
    /// some of its cells reads by its light fitted with each codeword,
    /// where the plain likelihood reading, one contrast and one level per
    /// codeword, does not read it.
    #[test]
    fn a_tag_under_uneven_light_and_glare_reads_with_the_light_fitted() {
        let spots = [(0.2, 0.1), (-0.25, 0.2), (0.0, -0.3), (0.3, 0.3)];
        let mut plain_read = 0;
        for (k, &spot) in spots.iter().enumerate() {
            for (id, d) in [(3, 0), (77, 1), (150, 2), (254, 3)] {
                let (y, clipped) = lit(id, d, spot, k);
                assert!(clipped.iter().any(|&c| c), "no clipped cell: {spot:?}");
                let fit = read_shaded(book(), &y, &clipped, &[])
                    .unwrap_or_else(|| panic!("id {id} turn {d} under {spot:?} not read"));
                assert_eq!((fit.id, fit.rotation), (id, d), "under {spot:?}");
                plain_read += usize::from(read_likely(book(), &y).is_some_and(|f| f.reads()));
            }
        }
        assert!(plain_read <= 4, "the plain reading read {plain_read} of 16");
    }

    /// The first round's dot products given by the plain reading
    /// ([`Codebook::score_all`]) give the same reading as those computed
    /// here.
    #[test]
    fn the_plain_readings_dot_products_give_the_same_reading() {
        let (y, clipped) = lit(42, 1, (0.1, -0.2), 9);
        let mut dots = Vec::new();
        let _ = crate::likelihood::read_likely_keeping(book(), &y, &mut dots);
        assert_eq!(dots.len(), 4 * book().ids());
        let a = read_shaded(book(), &y, &clipped, &dots).expect("read");
        let b = read_shaded(book(), &y, &clipped, &[]).expect("read");
        assert_eq!((a.id, a.rotation), (42, 1));
        assert_eq!((a.id, a.rotation), (b.id, b.rotation));
    }

    /// Grids of the wrong size, or with a clipped-cell mask of the wrong
    /// size, or dot products of the wrong length (computed afresh), are
    /// refused or handled without a panic.
    #[test]
    fn malformed_grids_are_refused() {
        let (y, clipped) = lit(42, 1, (0.1, -0.2), 9);
        assert!(read_shaded(book(), &y[..100], &clipped[..100], &[]).is_none());
        assert!(read_shaded(book(), &y, &clipped[..195], &[]).is_none());
        assert!(read_shaded(book(), &[f64::NAN; 196], &[false; 196], &[]).is_none());
        let fit = read_shaded(book(), &y, &clipped, &[1.0; 7]).expect("read");
        assert_eq!((fit.id, fit.rotation), (42, 1));
    }

    /// Grids of no tag under the same light, cells drawn at random, are
    /// not read; nor is a smooth field alone, nor a grid mostly clipped.
    #[test]
    fn random_grids_smooth_fields_and_clipped_grids_are_not_read() {
        let n = 14;
        let mut state: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for k in 0..300 {
            let (mut y, clipped) = lit(0, 0, (0.1 * (k % 5) as f64 - 0.2, 0.1), k);
            for v in &mut y {
                if *v < 1.3 {
                    *v += if next() % 2 == 0 { 0.4 } else { -0.4 };
                }
            }
            assert!(
                read_shaded(book(), &y, &clipped, &[]).is_none(),
                "grid {k} read"
            );
        }
        let field: Vec<f64> = (0..n * n)
            .map(|c| 0.3 + 0.02 * (c % n) as f64 + 0.01 * (c / n) as f64)
            .collect();
        assert!(read_shaded(book(), &field, &vec![false; n * n], &[]).is_none());
        let (y, _) = lit(9, 0, (0.0, 0.0), 1);
        let mostly: Vec<bool> = (0..n * n).map(|c| c % 7 != 0).collect();
        assert!(read_shaded(book(), &y, &mostly, &[]).is_none());
    }
}

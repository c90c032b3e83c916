//! Reading a heavily occluded tag by its nearest codeword.
//!
//! An occluder as dark as the ink or as light as the paper does not make
//! its cells doubtful: they read confidently, half of them wrong. Past a
//! quarter of the data square hidden, that is more wrong symbols than the
//! Reed-Solomon decoder corrects (ct14: 9), although the grid still holds
//! plenty of information: ct14 has only 256 ids at 4 rotations, and two of
//! its codewords differ in about half of their 180 informative cells.
//!
//! So the confident cells (not within [`DOUBT`] of the threshold) are
//! compared with every codeword, cell by cell (bit sets, a popcount per
//! 64 cells), and the nearest one is read when two things hold:
//!
//! - it is clearly nearer than any other codeword, another id or the same
//!   id at another rotation ([`MIN_LEAD`], [`MIN_LEAD_RATIO`]);
//! - its misread cells are confined to part of the grid
//!   ([`MAX_ERROR_BLOCKS`]): an occluder hides a region, while a quad that
//!   is no tag disagrees with its nearest codeword all over the grid.
//!
//! Such a reading stands only when every corner of its quad was measured
//! and the fit of the tag's model bears all four out (see
//! `detect::decoding`): the cells say nothing about where a hidden corner
//! lies.
//!
//! Minimum-distance decoding against a small codebook is textbook (Lin &
//! Costello, "Error Control Coding", ch. 1); the occluder-confinement test
//! is this crate's own. The thresholds were measured on the wild
//! benchmark's 6001 tags (with their true corners) and on the 35 000 quads
//! the detector tried to decode there, 12 500 of which were no tag: see
//! each constant.

use crate::likelihood::Codebook;

/// Cells whose whiteness is within this distance of the threshold (a
/// half) do not count: they are grey, so neither colour is evidence. A
/// grey occluder's cells drop out here.
const DOUBT: f64 = 0.15;

/// The nearest codeword must be nearer than the second nearest by at least
/// this many cells. Quads that were no tag reached a lead of 14 cells at
/// most (with a ratio of 1.26, below [`MIN_LEAD_RATIO`]).
const MIN_LEAD: u32 = 15;

/// ... and the second nearest's distance must be at least this multiple of
/// the nearest's. Quads that were no tag reached 1.32 at most (with a lead
/// of 9 cells); a tag under an ink-dark occluder over 35% of its square,
/// with its true corners, read at 1.5 to 3.
const MIN_LEAD_RATIO: f64 = 1.35;

/// Side (cells) of the blocks the grid is split into to tell an
/// occluder's misread cells from a non-tag's.
const BLOCK: usize = 2;

/// Most blocks (of 2 x 2 cells: ct14 has 49) that may hold a misread
/// cell, as a share of the grid's blocks. The misread cells of a tag read
/// this way lay in 3 to 37 blocks, half of them in 22 or fewer; the
/// nearest codeword of a quad that was no tag disagreed in 14 to 49
/// blocks. With the two tests above, a share of 0.52 (25 of 49 blocks)
/// read no non-tag quad and no tag as a wrong id, and no non-tag came
/// within 70% of the three limits at once.
const MAX_ERROR_BLOCKS: f64 = 0.52;

/// A nearest-codeword reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Nearest {
    /// Decoded id.
    pub id: u64,
    /// Quarter turns, as in [`crate::grid_code::GridReading::rotation`].
    pub rotation: usize,
    /// Confident cells that disagree with the codeword.
    pub misread: u32,
}

/// The nearest codeword of a grid, cell by cell, before any test.
struct Scan {
    /// Index of its id in the book.
    index: usize,
    /// Its quarter turns.
    rotation: usize,
    /// Confident cells that disagree with it.
    nearest: u32,
    /// ... and with the second nearest codeword (another id or turn).
    second: u32,
    /// Confident cells (bit set).
    confident: Vec<u64>,
    /// Confident cells that read black (bit set).
    black: Vec<u64>,
}

/// Compares the confident cells of `y` with every codeword of `book`.
fn scan(book: &Codebook, y: &[f64]) -> Option<Scan> {
    let n = book.grid();
    if y.len() != n * n {
        return None;
    }
    let words = book.bit_words();
    let mut confident = vec![0u64; words];
    let mut black = vec![0u64; words];
    for &c in book.informative() {
        if (y[c] - 0.5).abs() >= DOUBT {
            confident[c / 64] |= 1 << (c % 64);
            if y[c] < 0.5 {
                black[c / 64] |= 1 << (c % 64);
            }
        }
    }
    // (distance, id index, rotation) of the nearest; distance of the second.
    let mut best = (u32::MAX, 0usize, 0usize);
    let mut second = u32::MAX;
    for d in 0..4 {
        for i in 0..book.ids() {
            let word = book.black_bits(i, d);
            let dist: u32 = (0..words)
                .map(|w| ((word[w] ^ black[w]) & confident[w]).count_ones())
                .sum();
            if dist < best.0 {
                second = best.0;
                best = (dist, i, d);
            } else if dist < second {
                second = dist;
            }
        }
    }
    (second != u32::MAX).then_some(Scan {
        index: best.1,
        rotation: best.2,
        nearest: best.0,
        second,
        confident,
        black,
    })
}

/// The nearest codeword of `book` to the cells' whiteness `y` (the seen
/// grid, row-major, 0 at the frame's black, 1 at the margin's white),
/// when it reads by the module's three tests; `None` otherwise.
pub(crate) fn read_nearest(book: &Codebook, y: &[f64]) -> Option<Nearest> {
    let s = scan(book, y)?;
    let (d1, second) = (s.nearest, s.second);
    if second < d1.saturating_add(MIN_LEAD) || f64::from(second) < MIN_LEAD_RATIO * f64::from(d1) {
        return None;
    }
    // Blocks holding a misread cell.
    let n = book.grid();
    let word = book.black_bits(s.index, s.rotation);
    let side = n.div_ceil(BLOCK);
    let mut hit = vec![false; side * side];
    for &c in book.informative() {
        let bit = 1u64 << (c % 64);
        if s.confident[c / 64] & bit != 0 && (word[c / 64] ^ s.black[c / 64]) & bit != 0 {
            hit[(c / n / BLOCK) * side + (c % n) / BLOCK] = true;
        }
    }
    let blocks = hit.iter().filter(|&&h| h).count();
    if blocks as f64 > MAX_ERROR_BLOCKS * (side * side) as f64 {
        return None;
    }
    Some(Nearest {
        id: book.id(s.index),
        rotation: s.rotation,
        misread: d1,
    })
}

/// The nearest codeword must lead the second by this factor to veto a
/// likelihood reading of another codeword ([`contradicts`]).
const VETO_LEAD_RATIO: f64 = 1.2;

/// Whether the cells of `y`, read cell by cell, name another codeword
/// than `id` at `rotation` with a lead of [`VETO_LEAD_RATIO`]. The
/// likelihood reading models blur as the same in every direction; under
/// a motion blur of 3 to 6 px it read 5 of the wild set's tags, with their
/// true corners, as another id. The cells' own nearest codeword named the
/// right one in 4 of them, 2 with such a lead, and contradicted none of
/// the right readings.
pub(crate) fn contradicts(book: &Codebook, y: &[f64], id: u64, rotation: usize) -> bool {
    scan(book, y).is_some_and(|s| {
        (book.id(s.index), s.rotation) != (id, rotation)
            && f64::from(s.second) >= VETO_LEAD_RATIO * f64::from(s.nearest.max(1))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::family::Family;
    use crate::grid_code::seen_whiteness;

    /// The seen whiteness of ct14 tag `id` at `d` quarter turns.
    fn seen(id: u64, d: usize) -> Vec<f64> {
        seen_whiteness(Family::ct14(), id, d)
    }

    fn book() -> &'static Codebook {
        Family::ct14().codebook().unwrap()
    }

    /// Rows `0..rows` of the grid painted black, as an ink-dark occluder
    /// over the tag's top would.
    fn hide_top(y: &mut [f64], rows: usize) {
        let n = 14;
        for v in &mut y[..rows * n] {
            *v = 0.0;
        }
    }

    #[test]
    fn a_tag_with_its_top_rows_under_ink_is_read_the_hard_reading_is_not() {
        let fam = Family::ct14();
        for (id, d) in [(3u64, 0usize), (77, 1), (200, 3)] {
            let mut y = seen(id, d);
            hide_top(&mut y, 6);
            let bits: Vec<bool> = y.iter().map(|&v| v < 0.5).collect();
            assert!(
                crate::grid_code::decode_cells(fam, &bits, &[]).is_none(),
                "the occluder must defeat the Reed-Solomon reading of id {id} for the test to mean anything"
            );
            let r = read_nearest(book(), &y).expect("nearest codeword reading");
            assert_eq!((r.id, r.rotation), (id, d));
            assert!(r.misread > 0);
        }
    }

    #[test]
    fn misread_cells_all_over_the_grid_are_not_read() {
        // Every sixth informative cell flipped: 30 misread cells, fewer
        // than a tag a third hidden has, but spread over most blocks; the
        // nearest codeword leads clearly, so only the blocks refuse it.
        let mut y = seen(42, 2);
        for (k, &c) in book().informative().iter().enumerate() {
            if k % 6 == 0 {
                y[c] = 1.0 - y[c];
            }
        }
        assert_eq!(read_nearest(book(), &y), None);
    }

    #[test]
    fn flat_and_random_grids_are_not_read() {
        assert_eq!(read_nearest(book(), &[1.0; 196]), None);
        assert_eq!(read_nearest(book(), &[0.0; 196]), None);
        assert_eq!(read_nearest(book(), &[0.5; 196]), None);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200 {
            let y: Vec<f64> = (0..196)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state >> 11) as f64 / (1u64 << 53) as f64
                })
                .collect();
            assert_eq!(read_nearest(book(), &y), None);
        }
    }

    #[test]
    fn the_cells_contradict_another_codeword_not_their_own() {
        let y = seen(150, 1);
        assert!(!contradicts(book(), &y, 150, 1));
        assert!(contradicts(book(), &y, 170, 1));
        // The same id at another turn is another codeword too.
        assert!(contradicts(book(), &y, 150, 2));
        // A flat grid names nothing clearly.
        assert!(!contradicts(book(), &[0.5; 196], 170, 0));
    }

    #[test]
    fn a_wrong_length_grid_is_refused() {
        assert_eq!(read_nearest(book(), &[0.0; 64]), None);
    }
}

//! The cell grid and the codeword: id -> black/white cells, and cells read at
//! any of the four rotations -> id.
//!
//! Follows the format contract: codeword symbols MSB first into the
//! bitstream, zero padding, bit k into cell `cell_order[k]`, a cell is black
//! exactly when `bit ^ mask(cell)` is 1 with a checkerboard mask.

use crate::family::Family;
use crate::Result;

/// Checkerboard mask of a cell: 1 where row + column is odd.
#[inline]
pub(crate) fn mask(cell: usize, n: usize) -> bool {
    let (i, j) = (cell / n, cell % n);
    (i + j) % 2 == 1
}

/// Index of `cell` after rotating an `n x n` grid by `d` quarter turns
/// clockwise (the contract's rotation formulas).
#[inline]
pub fn rotate_cell(cell: usize, n: usize, d: usize) -> usize {
    let (i, j) = (cell / n, cell % n);
    match d % 4 {
        0 => cell,
        1 => j * n + (n - 1 - i),
        2 => n * n - 1 - cell,
        _ => n * (n - 1 - j) + i,
    }
}

/// The cell colours of a tag, row-major, `true` = black. Covered cells (under
/// the centre checker) hold their bitstream value like every other cell;
/// the renderer paints the checker over them.
pub fn encode_cells(family: &Family, id: u64) -> Result<Vec<bool>> {
    let data = family.data_symbols(id)?;
    let code = family.code();
    let word = code.encode(&data)?;
    let m = code.symbol_bits() as usize;
    let n = family.grid();
    let order = &family.spec().cell_order;
    let mut cells = vec![false; family.cells()];
    for (k, &cell) in order.iter().enumerate() {
        let cell = usize::from(cell);
        let bit = word
            .get(k / m)
            .is_some_and(|&sym| (sym >> (m - 1 - k % m)) & 1 == 1);
        cells[cell] = bit ^ mask(cell, n);
    }
    Ok(cells)
}

/// A successful reading of a cell grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GridReading {
    /// Decoded id.
    pub id: u64,
    /// Quarter turns clockwise from the tag's upright orientation to the
    /// orientation the grid was read in.
    pub rotation: usize,
    /// Symbols the Reed-Solomon decoder corrected.
    pub corrected: usize,
    /// Symbols read as erasures (a cell of theirs was erased).
    pub erased: usize,
    /// Symbols corrected that were not erased: the errors. An error costs
    /// the code twice the capacity of an erasure, so a reading's load is
    /// `2 * errors + erased` of the code's parity symbols.
    pub errors: usize,
}

/// Reads a grid of cell colours (`true` = black, row-major, as seen) at all
/// four rotations.
///
/// `erased` marks cells whose colour is unknown (occluded, too close to the
/// threshold); a symbol with an erased cell becomes an RS erasure, which
/// costs half as much correction capacity as an error. Pass an empty slice
/// when nothing is known to be bad.
///
/// A reading is accepted when it decodes, its id is in range and its verify
/// symbol is the one the generator uses for that id (stricter than "any
/// verify symbol": it costs nothing on real tags and removes false reads).
///
/// When two rotations give different ids, the format contract says to
/// report nothing. Taken literally that loses 22 ct8 ids whose ideal grid has
/// a second reading at another rotation with exactly 5 corrections (the
/// code's limit) beside the true one with 0. So the rule here is maximum
/// likelihood with a margin: the reading with fewest corrections wins when
/// every reading of another id, or of the same id at another rotation,
/// needs at least [`AMBIGUITY_MARGIN`] more corrected symbols; otherwise
/// the grid is ambiguous (in id, or in which corner is the tag's top-left)
/// and nothing is returned.
pub fn decode_cells(family: &Family, cells: &[bool], erased: &[bool]) -> Option<GridReading> {
    let readings: [Option<GridReading>; 4] =
        std::array::from_fn(|d| decode_cells_at(family, cells, erased, d));
    let best = readings
        .iter()
        .flatten()
        .min_by_key(|r| (r.corrected, r.rotation))
        .copied()?;
    // Another id, or the same id at another rotation (a tag whose cells
    // read the same turned: its corner order is unknown), nearly as good.
    let contested = readings.iter().flatten().any(|r| {
        (r.id, r.rotation) != (best.id, best.rotation)
            && r.corrected < best.corrected + AMBIGUITY_MARGIN
    });
    (!contested).then_some(best)
}

/// How many more corrected symbols a reading of another id must need before
/// the best reading of a grid is accepted over it.
pub const AMBIGUITY_MARGIN: usize = 3;

/// Reads a grid at one rotation `d` only (see [`decode_cells`] for the
/// acceptance rule). Exposed so that tests and tools can check every
/// rotation separately.
pub fn decode_cells_at(
    family: &Family,
    cells: &[bool],
    erased: &[bool],
    d: usize,
) -> Option<GridReading> {
    let n = family.grid();
    if cells.len() != n * n || (!erased.is_empty() && erased.len() != n * n) {
        return None;
    }
    let code = family.code();
    let m = code.symbol_bits() as usize;
    let nsym = code.n();
    // Fixed-size buffers: a codeword has at most 255 symbols (m <= 8).
    let mut buf = [0u8; 256];
    let word = &mut buf[..nsym];
    let mut erasures = [0usize; 256];
    let mut n_erased = 0;
    let mut last_erased = usize::MAX;
    for (s, symbol) in family.seen_code_cells(d).chunks_exact(m).enumerate() {
        for (b, &(seen, masked)) in symbol.iter().enumerate() {
            let bit = cells[seen] ^ masked;
            word[s] |= u8::from(bit) << (m - 1 - b);
            if !erased.is_empty() && erased[seen] && last_erased != s {
                erasures[n_erased] = s;
                n_erased += 1;
                last_erased = s;
            }
        }
    }
    if n_erased > code.parity() {
        return None;
    }
    let mut seen_word = [0u8; 256];
    seen_word[..nsym].copy_from_slice(word);
    let corrected = code.decode(word, &erasures[..n_erased]).ok()?;
    let erased = &erasures[..n_erased];
    let errors = (0..nsym)
        .filter(|&s| word[s] != seen_word[s] && !erased.contains(&s))
        .count();
    let (id, verify) = family.id_from_data(&word[..code.k()])?;
    (verify == family.verify_symbol(id)).then_some(GridReading {
        id,
        rotation: d % 4,
        corrected,
        erased: n_erased,
        errors,
    })
}

/// The seen whiteness of tag `id` of `family` at `d` quarter turns: 0 on
/// black cells, 1 on white ones, a half on the cells under the centre
/// checker. For tests of the readings that take whiteness.
#[cfg(test)]
pub(crate) fn seen_whiteness(family: &Family, id: u64, d: usize) -> Vec<f64> {
    let n = family.grid();
    let black = encode_cells(family, id).unwrap();
    let mut y = vec![0.5; n * n];
    for (c, &b) in black.iter().enumerate() {
        if !family.is_covered(c) {
            y[rotate_cell(c, n, d)] = if b { 0.0 } else { 1.0 };
        }
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_compose() {
        for n in [8, 14] {
            for c in 0..n * n {
                assert_eq!(rotate_cell(rotate_cell(c, n, 1), n, 3), c);
                assert_eq!(
                    rotate_cell(rotate_cell(c, n, 1), n, 1),
                    rotate_cell(c, n, 2)
                );
            }
        }
        // Top-left goes to top-right under a clockwise quarter turn.
        assert_eq!(rotate_cell(0, 14, 1), 13);
    }

    #[test]
    fn encode_then_decode_each_rotation() {
        let fam = Family::ct14();
        let cells = encode_cells(fam, 42).unwrap();
        for d in 0..4 {
            let mut seen = vec![false; cells.len()];
            for (c, &b) in cells.iter().enumerate() {
                seen[rotate_cell(c, 14, d)] = b;
            }
            let r = decode_cells(fam, &seen, &[]).unwrap();
            assert_eq!((r.id, r.rotation, r.corrected), (42, d, 0));
        }
    }
}

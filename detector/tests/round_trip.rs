//! Every id of both families survives generate -> ideal grid -> decode at
//! every rotation, and the Reed-Solomon margin holds under random cell flips.

use coppertag::grid_code::{
    decode_cells, decode_cells_at, encode_cells, rotate_cell, AMBIGUITY_MARGIN,
};
use coppertag::Family;

fn rotated(cells: &[bool], n: usize, d: usize) -> Vec<bool> {
    let mut out = vec![false; cells.len()];
    for (c, &b) in cells.iter().enumerate() {
        out[rotate_cell(c, n, d)] = b;
    }
    out
}

fn round_trip_all(fam: &Family, rivals: &mut usize) -> usize {
    let n = fam.grid();
    let mut checked = 0;
    for id in fam.min_id()..=fam.max_id() {
        let cells = encode_cells(fam, id).unwrap();
        for d in 0..4 {
            let seen = rotated(&cells, n, d);
            let r = decode_cells(fam, &seen, &[])
                .unwrap_or_else(|| panic!("{} id {id} rotation {d}: no decode", fam.name()));
            assert_eq!(
                (r.id, r.rotation, r.corrected),
                (id, d, 0),
                "{}",
                fam.name()
            );
            // A reading of this grid at a wrong rotation must never yield an
            // id that the full decoder could prefer: it is either absent or
            // loses by the ambiguity margin (22 ct8 ids have such a reading,
            // with 5 corrections, because the reference's verify symbols
            // allow it).
            for wrong in (0..4).filter(|&w| w != d) {
                if let Some(r) = decode_cells_at(fam, &seen, &[], wrong) {
                    assert!(
                        r.corrected >= AMBIGUITY_MARGIN,
                        "{} id {id} seen at rotation {d} also reads as {} at rotation {wrong}",
                        fam.name(),
                        r.id
                    );
                    *rivals += 1;
                }
            }
            checked += 1;
        }
    }
    checked
}

#[test]
fn all_ct14_ids_round_trip() {
    let mut rivals = 0;
    assert_eq!(round_trip_all(Family::ct14(), &mut rivals), 256 * 4);
    assert_eq!(rivals, 0, "ct14 has no rotated readings at all");
}

#[test]
fn all_ct8_ids_round_trip() {
    let mut rivals = 0;
    assert_eq!(round_trip_all(Family::ct8(), &mut rivals), 65536 * 4);
    println!("ct8: {rivals} rotated readings of another id, all outvoted by the margin");
    // 22 ids, each seen at 4 rotations.
    assert_eq!(rivals, 22 * 4);
}

/// Small deterministic generator (SplitMix64) so the test needs no crate and
/// prints the same figures every run.
struct SplitMix(u64);
impl SplitMix {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn flip_distinct(cells: &mut [bool], k: usize, rng: &mut SplitMix) {
    let mut picked = Vec::with_capacity(k);
    while picked.len() < k {
        let c = rng.below(cells.len());
        if !picked.contains(&c) {
            picked.push(c);
            cells[c] = !cells[c];
        }
    }
}

#[test]
fn ct14_random_cell_flips() {
    let fam = Family::ct14();
    let n = fam.grid();
    let mut rng = SplitMix(0x00C0_FFEE);
    // Up to t = 9 flipped cells touch at most 9 symbols: always corrected.
    for k in 0..=fam.code().correctable() {
        for _ in 0..2000 {
            let id = rng.below(256) as u64;
            let d = rng.below(4);
            let mut seen = rotated(&encode_cells(fam, id).unwrap(), n, d);
            flip_distinct(&mut seen, k, &mut rng);
            let r = decode_cells(fam, &seen, &[])
                .unwrap_or_else(|| panic!("id {id}, {k} flips: not corrected"));
            assert_eq!((r.id, r.rotation), (id, d));
            assert!(r.corrected <= k);
        }
    }
    // Beyond t: 100k trials from 10 to 60 flips; decoding may fail, or
    // succeed when flips share symbols or land on padding, but must never
    // return another id.
    let (mut ok, mut failed, mut wrong) = (0u32, 0u32, 0u32);
    let trials: u32 = 100_000;
    for t in 0..trials {
        let k = 10 + (t % 51) as usize;
        let id = rng.below(256) as u64;
        let d = rng.below(4);
        let mut seen = rotated(&encode_cells(fam, id).unwrap(), n, d);
        flip_distinct(&mut seen, k, &mut rng);
        match decode_cells(fam, &seen, &[]) {
            None => failed += 1,
            Some(r) if r.id == id && r.rotation == d => ok += 1,
            Some(_) => wrong += 1,
        }
    }
    println!(
        "ct14, 10-60 random cell flips, {trials} trials: {ok} decoded correctly, {failed} rejected, \
         {wrong} wrong ids (miscorrection rate {:.2e})",
        f64::from(wrong) / f64::from(trials)
    );
    assert_eq!(wrong, 0);
    assert_eq!(ok + failed, trials);
}

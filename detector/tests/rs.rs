//! Integration tests for the Reed-Solomon codec (`coppertag::rs`).

use coppertag::rs::ReedSolomon;
use coppertag::Error;
use proptest::prelude::*;
use proptest::sample::subsequence;

/// `(symbol_bits, primitive_poly, first_root, n, k)` for the codes exercised
/// by the property tests: the two CopperTag codes first, then a spread of
/// other fields, first roots (including one whose roots wrap past 2^m - 1)
/// and shortenings.
const CODES: [(u32, u32, u32, usize, usize); 7] = [
    (8, 0x187, 120, 20, 2), // ct14
    (4, 0x13, 0, 15, 5),    // ct8
    (3, 0b1011, 1, 7, 3),
    (5, 0x25, 3, 31, 11),
    (6, 0x43, 5, 50, 20),
    (7, 0x89, 120, 100, 80),
    (8, 0x11d, 0, 255, 223),
];

fn code(index: usize) -> ReedSolomon {
    let (m, poly, fcr, n, k) = CODES[index];
    ReedSolomon::new(m, poly, fcr, n, k).expect("valid test code")
}

fn ct14() -> ReedSolomon {
    ReedSolomon::new(8, 0x187, 120, 20, 2).unwrap()
}

fn ct8() -> ReedSolomon {
    ReedSolomon::new(4, 0x13, 0, 15, 5).unwrap()
}

/// True when `word` is a codeword of the systematic code `rs`.
fn is_codeword(rs: &ReedSolomon, word: &[u8]) -> bool {
    rs.encode(&word[..rs.k()]).unwrap() == word
}

fn differences(a: &[u8], b: &[u8]) -> usize {
    a.iter().zip(b).filter(|(x, y)| x != y).count()
}

fn symbols(value: &serde_json::Value) -> Vec<u8> {
    value
        .as_array()
        .expect("array of symbols")
        .iter()
        .map(|v| u8::try_from(v.as_u64().expect("integer symbol")).unwrap())
        .collect()
}

#[test]
fn fixture_vectors() {
    let text = include_str!("fixtures/rs-vectors.json");
    let json: serde_json::Value = serde_json::from_str(text).unwrap();
    for (family, rs) in [("ct14", ct14()), ("ct8", ct8())] {
        let vectors = json["families"][family].as_array().expect("family list");
        assert_eq!(vectors.len(), 24, "{family}: vector count");
        for (i, v) in vectors.iter().enumerate() {
            let data = symbols(&v["data"]);
            let codeword = symbols(&v["codeword"]);
            let mut received = symbols(&v["received"]);
            let errors = v["errors"].as_u64().unwrap() as usize;
            assert_eq!(rs.encode(&data).unwrap(), codeword, "{family}[{i}] encode");
            let mut out = vec![0u8; rs.n()];
            rs.encode_into(&data, &mut out).unwrap();
            assert_eq!(out, codeword, "{family}[{i}] encode_into");
            assert_eq!(
                rs.decode(&mut received, &[]),
                Ok(errors),
                "{family}[{i}] decode count"
            );
            assert_eq!(received, codeword, "{family}[{i}] decoded word");
        }
    }
}

/// A random codeword of code `CODES[code]` with `errors` random errors and
/// `erasures` erased positions (random values, possibly the right ones), all
/// at distinct random positions.
#[derive(Debug, Clone)]
struct Damage {
    code: usize,
    data: Vec<u8>,
    /// A permutation of `0..n`: the first `erasures` entries are erased, the
    /// next `errors` get errors.
    positions: Vec<usize>,
    /// Per position: a non-zero error value.
    error_values: Vec<u8>,
    /// Per position: the value written into an erased symbol.
    erasure_values: Vec<u8>,
    erasures: usize,
    errors: usize,
}

impl Damage {
    /// Builds (codeword, received word, erasure list).
    fn apply(&self, rs: &ReedSolomon) -> (Vec<u8>, Vec<u8>, Vec<usize>) {
        let codeword = rs.encode(&self.data).unwrap();
        let mut received = codeword.clone();
        let erased = self.positions[..self.erasures].to_vec();
        for &j in &erased {
            received[j] = self.erasure_values[j];
        }
        for &j in &self.positions[self.erasures..self.erasures + self.errors] {
            received[j] ^= self.error_values[j];
        }
        (codeword, received, erased)
    }
}

/// Damage whose erasure count `f` and error count `e` are chosen by
/// `counts(n, parity)` (a strategy for `(f, e)`).
fn damage<S, F>(counts: F) -> impl Strategy<Value = Damage>
where
    S: Strategy<Value = (usize, usize)>,
    F: Fn(usize, usize) -> S + Clone,
{
    (0..CODES.len()).prop_flat_map(move |code| {
        let (m, _, _, n, k) = CODES[code];
        let max = ((1u32 << m) - 1) as u8;
        (
            Just(code),
            proptest::collection::vec(0..=max, k),
            Just((0..n).collect::<Vec<_>>()).prop_shuffle(),
            proptest::collection::vec(1..=max, n),
            proptest::collection::vec(0..=max, n),
            counts(n, n - k),
        )
            .prop_map(
                |(code, data, positions, error_values, erasure_values, (erasures, errors))| {
                    Damage {
                        code,
                        data,
                        positions,
                        error_values,
                        erasure_values,
                        erasures,
                        errors,
                    }
                },
            )
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Up to `parity / 2` errors are corrected and counted exactly.
    #[test]
    fn corrects_errors_within_capacity(d in damage(|_, p| (Just(0usize), 0..=p / 2))) {
        let rs = code(d.code);
        let (codeword, mut received, _) = d.apply(&rs);
        prop_assert_eq!(rs.decode(&mut received, &[]), Ok(d.errors));
        prop_assert_eq!(received, codeword);
    }

    /// Errors and erasures with `2e + f <= parity` are corrected; the count
    /// covers exactly the symbols whose value changed.
    #[test]
    fn corrects_errors_and_erasures(
        d in damage(|_, p| (0..=p).prop_flat_map(move |f| (Just(f), 0..=(p - f) / 2)))
    ) {
        let rs = code(d.code);
        let (codeword, mut received, erased) = d.apply(&rs);
        let changed = differences(&codeword, &received);
        prop_assert_eq!(rs.decode(&mut received, &erased), Ok(changed));
        prop_assert_eq!(received, codeword);
    }

    /// Beyond capacity the decoder may fail or miscorrect, but any `Ok` is a
    /// codeword within the decoding radius, and a failure leaves the word
    /// untouched. Never panics.
    #[test]
    fn beyond_capacity_is_safe(
        d in damage(|n, p| (0..=(p + 1).min(n)).prop_flat_map(move |f| {
            let min_errors = if f <= p { (p - f) / 2 + 1 } else { 0 };
            (Just(f), min_errors..=n - f)
        }))
    ) {
        let rs = code(d.code);
        let (_, received, erased) = d.apply(&rs);
        check_decode_is_safe(&rs, &received, &erased)?;
    }

    /// Completely random words with random erasure lists (duplicates
    /// included) either decode to a codeword or are left untouched.
    #[test]
    fn random_words_are_safe(
        (code_index, word, erasures) in (0..CODES.len()).prop_flat_map(|c| {
            let (m, _, _, n, k) = CODES[c];
            let max = ((1u32 << m) - 1) as u8;
            (
                Just(c),
                proptest::collection::vec(0..=max, n),
                proptest::collection::vec(0..n, 0..=n - k + 2),
            )
        })
    ) {
        let rs = code(code_index);
        check_decode_is_safe(&rs, &word, &erasures)?;
    }
}

fn check_decode_is_safe(
    rs: &ReedSolomon,
    received: &[u8],
    erasures: &[usize],
) -> Result<(), TestCaseError> {
    let mut word = received.to_vec();
    match rs.decode(&mut word, erasures) {
        Ok(count) => {
            prop_assert!(is_codeword(rs, &word), "Ok with a non-codeword");
            prop_assert_eq!(count, differences(received, &word));
            let mut erased = vec![false; rs.n()];
            for &j in erasures {
                erased[j] = true;
            }
            let f = erased.iter().filter(|&&e| e).count();
            let errors = (0..rs.n())
                .filter(|&j| !erased[j] && word[j] != received[j])
                .count();
            prop_assert!(2 * errors + f <= rs.parity(), "correction beyond radius");
        }
        Err(e) => {
            prop_assert_eq!(e, Error::Uncorrectable);
            prop_assert_eq!(&word[..], received, "word changed on failure");
        }
    }
    Ok(())
}

#[test]
fn codeword_decodes_to_itself() {
    for index in 0..CODES.len() {
        let rs = code(index);
        let data: Vec<u8> = (0..rs.k()).map(|i| (i * 7 + 3) as u8 & 0b111).collect();
        let codeword = rs.encode(&data).unwrap();
        let mut word = codeword.clone();
        assert_eq!(rs.decode(&mut word, &[]), Ok(0));
        assert_eq!(rs.decode(&mut word, &[0, rs.n() - 1]), Ok(0));
        assert_eq!(word, codeword);
    }
}

#[test]
fn accessors() {
    let rs = ct14();
    assert_eq!(
        (
            rs.n(),
            rs.k(),
            rs.parity(),
            rs.symbol_bits(),
            rs.correctable()
        ),
        (20, 2, 18, 8, 9)
    );
    let rs = ct8();
    assert_eq!(
        (
            rs.n(),
            rs.k(),
            rs.parity(),
            rs.symbol_bits(),
            rs.correctable()
        ),
        (15, 5, 10, 4, 5)
    );
}

#[test]
fn erasures_duplicates_and_correct_values() {
    let rs = ct8();
    let codeword = rs.encode(&[1, 2, 3, 4, 5]).unwrap();
    // Ten erasures (the full parity), each listed twice, all wrong.
    let mut word = codeword.clone();
    let erased: Vec<usize> = (0..10).chain(0..10).collect();
    for symbol in &mut word[..10] {
        *symbol ^= 0b1001;
    }
    assert_eq!(rs.decode(&mut word, &erased), Ok(10));
    assert_eq!(word, codeword);

    // Erasing symbols that are right costs capacity but is not counted.
    let mut word = codeword.clone();
    word[1] ^= 7;
    word[9] ^= 1;
    assert_eq!(rs.decode(&mut word, &[4, 5, 6, 7]), Ok(2));
    assert_eq!(word, codeword);

    // More distinct erasures than parity symbols cannot be resolved.
    let mut word = codeword.clone();
    word[0] ^= 1;
    let before = word.clone();
    let erased: Vec<usize> = (0..11).collect();
    assert_eq!(rs.decode(&mut word, &erased), Err(Error::Uncorrectable));
    assert_eq!(word, before);
}

fn assert_invalid(result: Result<ReedSolomon, Error>, what: &str) {
    match result {
        Err(Error::InvalidCode { .. }) => {}
        other => panic!("{what}: expected InvalidCode, got {other:?}"),
    }
}

#[test]
fn invalid_parameters() {
    assert_invalid(ReedSolomon::new(2, 0b111, 0, 3, 1), "m = 2");
    assert_invalid(ReedSolomon::new(9, 0x211, 0, 20, 10), "m = 9");
    // (x^9 - 1)/(x - 1): x has order 9, not 255.
    assert_invalid(ReedSolomon::new(8, 0x1ff, 0, 20, 2), "0x1ff");
    // Irreducible but not primitive: x has order 5.
    assert_invalid(ReedSolomon::new(4, 0x1f, 0, 15, 5), "0x1f");
    // Reducible: x^4 + 1 = (x + 1)^4.
    assert_invalid(ReedSolomon::new(4, 0x11, 0, 15, 5), "0x11");
    // Wrong degree for the symbol size.
    assert_invalid(ReedSolomon::new(5, 0x13, 0, 15, 5), "degree 4 for m = 5");
    assert_invalid(ReedSolomon::new(4, 0x25, 0, 15, 5), "degree 5 for m = 4");
    assert_invalid(ReedSolomon::new(4, 0x13, 0, 15, 15), "k = n");
    assert_invalid(ReedSolomon::new(4, 0x13, 0, 15, 16), "k > n");
    assert_invalid(ReedSolomon::new(4, 0x13, 0, 15, 0), "k = 0");
    assert_invalid(ReedSolomon::new(4, 0x13, 0, 16, 5), "n > 2^m - 1");
    assert_invalid(ReedSolomon::new(8, 0x187, 0, 256, 2), "n > 255");
    assert_invalid(ReedSolomon::new(4, 0x13, 15, 15, 5), "first_root = 2^m - 1");
    // Boundaries that are valid.
    assert!(ReedSolomon::new(3, 0b1011, 6, 7, 6).is_ok());
    assert!(ReedSolomon::new(8, 0x11d, 254, 255, 1).is_ok());
    assert!(ReedSolomon::new(4, 0x19, 0, 2, 1).is_ok()); // x^4+x^3+1
}

#[test]
fn bad_lengths() {
    let rs = ct8();
    assert_eq!(
        rs.encode(&[1, 2, 3, 4]),
        Err(Error::BadLength {
            expected: 5,
            got: 4
        })
    );
    let mut out = vec![0u8; 16];
    assert_eq!(
        rs.encode_into(&[1, 2, 3, 4, 5], &mut out),
        Err(Error::BadLength {
            expected: 15,
            got: 16
        })
    );
    let mut word = vec![0u8; 14];
    assert_eq!(
        rs.decode(&mut word, &[]),
        Err(Error::BadLength {
            expected: 15,
            got: 14
        })
    );
}

#[test]
fn symbols_out_of_range() {
    let rs = ct8();
    assert_eq!(
        rs.encode(&[1, 2, 3, 16, 5]),
        Err(Error::SymbolOutOfRange {
            index: 3,
            value: 16,
            bits: 4
        })
    );
    let mut word = rs.encode(&[1, 2, 3, 4, 5]).unwrap();
    word[12] = 200;
    let before = word.clone();
    assert_eq!(
        rs.decode(&mut word, &[]),
        Err(Error::SymbolOutOfRange {
            index: 12,
            value: 200,
            bits: 4
        })
    );
    assert_eq!(word, before);
}

#[test]
fn erasure_out_of_range() {
    let rs = ct8();
    let mut word = rs.encode(&[1, 2, 3, 4, 5]).unwrap();
    assert_eq!(
        rs.decode(&mut word, &[3, 15]),
        Err(Error::BadErasure { index: 15, n: 15 })
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// ct14 is RS(255, 237) with the leading 235 symbols fixed at zero and
    /// not transmitted. Take a full-length codeword whose untransmitted part
    /// has a few non-zero symbols, transmit its last 20 symbols with a few
    /// more errors, at most 9 in all: the full-length decoder corrects it
    /// (placing errors in untransmitted positions), so no ct14 codeword is
    /// within 9 symbols and the shortened decoder must refuse.
    #[test]
    fn shortened_code_rejects_untransmitted_positions(
        hidden in subsequence((0..235usize).collect::<Vec<_>>(), 1..=5),
        hidden_values in proptest::collection::vec(1..=255u8, 5),
        data in proptest::collection::vec(any::<u8>(), 2),
        visible in subsequence((0..20usize).collect::<Vec<_>>(), 0..=4),
        visible_values in proptest::collection::vec(1..=255u8, 4),
    ) {
        let full = ReedSolomon::new(8, 0x187, 120, 255, 237).unwrap();
        let short = ct14();
        let mut full_data = vec![0u8; 237];
        for (&j, &v) in hidden.iter().zip(&hidden_values) {
            full_data[j] = v;
        }
        full_data[235..].copy_from_slice(&data);
        let full_codeword = full.encode(&full_data).unwrap();

        let mut padded = full_codeword.clone();
        padded[..235].fill(0);
        for (&j, &v) in visible.iter().zip(&visible_values) {
            padded[235 + j] ^= v;
        }
        let received = padded[235..].to_vec();

        // The unrestricted decoder lands on the full codeword, outside the
        // shortened code.
        let errors = hidden.len() + visible.len();
        let mut full_word = padded.clone();
        prop_assert_eq!(full.decode(&mut full_word, &[]), Ok(errors));
        prop_assert_eq!(&full_word, &full_codeword);

        let mut word = received.clone();
        prop_assert_eq!(short.decode(&mut word, &[]), Err(Error::Uncorrectable));
        prop_assert_eq!(word, received);
    }
}

/// Many ct14 codewords with 10 to 20 random errors (beyond the 9 the code
/// corrects): every `Ok` must be a ct14 codeword at most 9 symbols away, and
/// a good share of the words must be rejected.
#[test]
fn shortened_code_heavy_damage() {
    let rs = ct14();
    // xorshift64*: a tiny deterministic generator, enough for test damage.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d)
    };
    let trials = 20_000;
    let mut rejected = 0;
    for _ in 0..trials {
        let data = [next() as u8, next() as u8];
        let codeword = rs.encode(&data).unwrap();
        let mut received = codeword.clone();
        let errors = 10 + (next() % 11) as usize;
        let mut positions: Vec<usize> = (0..20).collect();
        for i in 0..errors {
            let j = i + (next() % (20 - i) as u64) as usize;
            positions.swap(i, j);
            received[positions[i]] ^= (next() % 255 + 1) as u8;
        }
        let mut word = received.clone();
        match rs.decode(&mut word, &[]) {
            Ok(count) => {
                assert!(is_codeword(&rs, &word));
                assert!(count <= 9);
                assert_eq!(count, differences(&word, &received));
            }
            Err(e) => {
                assert_eq!(e, Error::Uncorrectable);
                assert_eq!(word, received);
                rejected += 1;
            }
        }
    }
    assert!(
        rejected > trials * 9 / 10,
        "only {rejected} of {trials} rejected"
    );
}

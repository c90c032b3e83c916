//! Reed-Solomon codec over GF(2^m), 3 <= m <= 8.
//!
//! CopperTag needs Reed-Solomon codes with parameters that existing crates do
//! not cover together: symbol sizes other than 8 bits (the `ct8` family uses
//! GF(16)), arbitrary primitive polynomials, an arbitrary first consecutive
//! root (`ct14` uses 120), shortened codes, and errors-and-erasures decoding.
//! The Reed-Solomon crates on crates.io fix GF(2^8) and a first root of 0, or
//! lack erasures or shortening, so this module is written by hand from the
//! published algorithms rather than taken from another project:
//!
//! * encoding is systematic: the parity is the remainder of `d(x) x^P`
//!   divided by the generator polynomial, computed with the usual
//!   linear-feedback shift register;
//! * syndromes are evaluated with Horner's rule;
//! * the errata (errors + erasures) locator comes from the Berlekamp-Massey
//!   algorithm initialised with the erasure locator, as in R. E. Blahut,
//!   *Algebraic Codes for Data Transmission* (Cambridge University Press,
//!   2003), section 7 ("decoding of erasures and errors"), and the Wikipedia
//!   article "Reed–Solomon error correction";
//! * the locator's roots are found with a Chien search (R. T. Chien, 1964);
//! * the error values come from Forney's algorithm (G. D. Forney, 1965),
//!   generalised to an arbitrary first consecutive root.
//!
//! # Conventions (CopperTag spec)
//!
//! Symbols are elements of GF(2^m) in polynomial basis, with generator element
//! `alpha = 2` (the polynomial `x`). A codeword `c_0 .. c_{N-1}` lists the
//! coefficients of the codeword polynomial from the highest degree down, so
//! `c_j` is the coefficient of `x^(N-1-j)`. The first `K` symbols are the data,
//! the last `P = N - K` the parity, and the codeword polynomial is divisible
//! by `g(x) = prod_{i=0}^{P-1} (x - alpha^(first_root + i))`.
//!
//! A shortened code (`N < 2^m - 1`) behaves as if the leading `2^m - 1 - N`
//! symbols were zeros that are not transmitted. The decoder never places an
//! error in those positions: a locator whose roots point there is rejected as
//! [`Error::Uncorrectable`].

use crate::{Error, Result};
use std::fmt;

/// Largest supported symbol size in bits.
const MAX_BITS: u32 = 8;
/// Smallest supported symbol size in bits.
const MIN_BITS: u32 = 3;
/// Size of the fixed stack buffers used by the decoder. The largest code has
/// `n = 255` symbols and at most `254` parity symbols; polynomials of degree
/// up to `P + 1` therefore fit in 256 coefficients.
const BUF: usize = 256;

/// Arithmetic in GF(2^m) through exponent and logarithm tables.
///
/// `exp` holds two periods of `alpha^i` so that `exp[log a + log b]` needs no
/// reduction modulo `2^m - 1`; `log[0]` is unused (zero has no logarithm and
/// every caller checks for it first).
#[derive(Clone)]
struct Gf {
    /// Symbol size in bits.
    bits: u32,
    /// The primitive polynomial the field is built with.
    poly: u32,
    /// Multiplicative order of alpha: `2^m - 1`.
    order: usize,
    /// `exp[i] = alpha^i` for `0 <= i < 2 * order`.
    exp: [u8; 2 * BUF],
    /// `log[alpha^i] = i` for `0 <= i < order`.
    log: [u8; BUF],
}

impl fmt::Debug for Gf {
    /// The tables are noise; show only what identifies the field.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Gf")
            .field("bits", &self.bits)
            .field("poly", &format_args!("{:#x}", self.poly))
            .finish()
    }
}

impl Gf {
    /// Builds the tables for GF(2^bits) with the given polynomial, checking
    /// that the polynomial has degree `bits` and is primitive, i.e. that
    /// `alpha = x` runs through all `2^bits - 1` non-zero elements before
    /// returning to 1.
    fn new(bits: u32, poly: u32) -> Result<Self> {
        if !(MIN_BITS..=MAX_BITS).contains(&bits) {
            return Err(invalid(format!(
                "symbol size {bits} bits is outside {MIN_BITS}..={MAX_BITS}"
            )));
        }
        let size = 1u32 << bits;
        if poly >> bits != 1 {
            return Err(invalid(format!(
                "polynomial {poly:#x} does not have degree {bits}"
            )));
        }
        let order = (size - 1) as usize;
        let mut exp = [0u8; 2 * BUF];
        let mut log = [0u8; BUF];
        let mut seen = [false; BUF];
        let mut x: u32 = 1;
        for i in 0..order {
            // A repeated value (or reaching 0, possible when the constant
            // term is zero) before `order` steps means alpha's order is
            // smaller than 2^m - 1: the polynomial is not primitive.
            if x == 0 || seen[x as usize] {
                return Err(not_primitive(poly, bits));
            }
            seen[x as usize] = true;
            exp[i] = x as u8;
            exp[i + order] = x as u8;
            log[x as usize] = i as u8;
            x <<= 1;
            if x & size != 0 {
                x ^= poly;
            }
        }
        if x != 1 {
            return Err(not_primitive(poly, bits));
        }
        Ok(Gf {
            bits,
            poly,
            order,
            exp,
            log,
        })
    }

    /// Number of field elements, `2^m`.
    #[inline]
    fn size(&self) -> usize {
        self.order + 1
    }

    /// `alpha^e` for any exponent (reduced modulo the field order).
    #[inline]
    fn pow_alpha(&self, e: usize) -> u8 {
        self.exp[e % self.order]
    }

    /// Product of two field elements.
    #[inline]
    fn mul(&self, a: u8, b: u8) -> u8 {
        if a == 0 || b == 0 {
            0
        } else {
            self.exp[self.log[a as usize] as usize + self.log[b as usize] as usize]
        }
    }

    /// `a * alpha^e` where `e < order`: the decoder's products by a factor
    /// whose logarithm `e` it took once (Berlekamp-Massey's discrepancy),
    /// and Horner's rule for the syndromes, which the tests check the
    /// tabled syndromes against.
    #[inline]
    fn mul_alpha(&self, a: u8, e: usize) -> u8 {
        if a == 0 {
            0
        } else {
            self.exp[self.log[a as usize] as usize + e]
        }
    }

    /// Quotient `a / b`; `b` must be non-zero (an internal invariant).
    #[inline]
    fn div(&self, a: u8, b: u8) -> u8 {
        assert!(b != 0, "division by zero in GF(2^{})", self.bits);
        if a == 0 {
            0
        } else {
            self.exp[self.log[a as usize] as usize + self.order - self.log[b as usize] as usize]
        }
    }

    /// Multiplicative inverse; `a` must be non-zero. The decoder takes
    /// the inverse's logarithm directly; the tests check division by it.
    #[cfg(test)]
    fn inv(&self, a: u8) -> u8 {
        self.div(1, a)
    }

    /// Evaluates the polynomial with coefficients `p[i]` of `x^i` (lowest
    /// degree first) at `x`, by Horner's rule.
    #[inline]
    fn eval_low_first(&self, p: &[u8], x: u8) -> u8 {
        p.iter().rev().fold(0, |acc, &c| self.mul(acc, x) ^ c)
    }

    /// The word indices `j` in `0..n` (of a word of `n` symbols) at which
    /// `lambda` (lowest degree first) vanishes at `X^-1`, `X =
    /// alpha^(n-1-j)`, in increasing order, written to `out`; returns how
    /// many.
    ///
    /// Term by term in the exponents (Chien's own recurrence): at index
    /// j, term i is alpha^(log lambda_i + i e_j), where e_j is the order
    /// less n - 1 - j; e_j grows by one with j, so each non-zero term's
    /// exponent grows by i. One table look-up per term and index, where
    /// Horner's rule ([`Gf::eval_low_first`]) took a product, two look-ups
    /// and two zero tests, per term. Why: the words read from clutter are
    /// nearly all uncorrectable and most reach this search; on 300 wild
    /// frames the decoder's share of the detection time went from 5.5% to
    /// 4.5%.
    fn chien(&self, lambda: &[u8], n: usize, out: &mut [usize; BUF]) -> usize {
        let order = self.order;
        let mut exps = [0usize; BUF];
        let mut steps = [0usize; BUF];
        let mut terms = 0usize;
        let e0 = (order - (n - 1) % order) % order;
        for (i, &c) in lambda.iter().enumerate().filter(|(_, &c)| c != 0) {
            exps[terms] = (usize::from(self.log[usize::from(c)]) + i * e0) % order;
            steps[terms] = i % order;
            terms += 1;
        }
        let (exps, steps) = (&mut exps[..terms], &steps[..terms]);
        let mut found = 0usize;
        for j in 0..n {
            let mut value = 0u8;
            for (e, &step) in exps.iter_mut().zip(steps) {
                value ^= self.exp[*e];
                *e += step;
                if *e >= order {
                    *e -= order;
                }
            }
            if value == 0 {
                out[found] = j;
                found += 1;
            }
        }
        found
    }
}

/// Shorthand for an [`Error::InvalidCode`].
fn invalid(reason: String) -> Error {
    Error::InvalidCode { reason }
}

/// The error for a polynomial whose root `x` is not a generator.
fn not_primitive(poly: u32, bits: u32) -> Error {
    invalid(format!(
        "polynomial {poly:#x} is not primitive over GF(2^{bits})"
    ))
}

/// A Reed-Solomon code `RS(n, k)` over GF(2^m) with a given primitive
/// polynomial and first consecutive root, possibly shortened
/// (`n < 2^m - 1`). See the [module documentation](self) for the symbol
/// order and conventions.
///
/// Building one precomputes the field tables and the generator polynomial;
/// encoding and decoding afterwards allocate nothing but the output of
/// [`ReedSolomon::encode`].
#[derive(Debug, Clone)]
pub struct ReedSolomon {
    /// Field arithmetic tables.
    gf: Gf,
    /// First consecutive root exponent, `0 <= first_root < 2^m - 1`.
    first_root: usize,
    /// Codeword length in symbols.
    n: usize,
    /// Data symbols per codeword.
    k: usize,
    /// Generator polynomial, highest degree first: `generator[0] = 1` is the
    /// coefficient of `x^P`, `generator[P]` the constant term.
    generator: Vec<u8>,
    /// `syndrome_powers[i * n + j]`: the exponent of alpha that symbol `j`
    /// is multiplied by in syndrome `i`, `(first_root + i) (n - 1 - j)`
    /// modulo the field order. With it each syndrome is a sum of
    /// independent products (one table look-up per non-zero symbol, its
    /// logarithm taken once for all syndromes) rather than Horner's chain
    /// of dependent ones: the syndromes were most of the decoder's time,
    /// and the decoder runs at four rotations for every quad read.
    syndrome_powers: Vec<u16>,
}

impl ReedSolomon {
    /// Builds the code `RS(n, k)` over GF(2^`symbol_bits`) generated by
    /// `primitive_poly` (bit `i` is the coefficient of `x^i`, so
    /// x^8+x^7+x^2+x+1 is `0x187`), with generator polynomial roots
    /// `alpha^first_root .. alpha^(first_root + n - k - 1)`.
    ///
    /// Returns [`Error::InvalidCode`] unless `3 <= symbol_bits <= 8`,
    /// `primitive_poly` has degree `symbol_bits` and is primitive (checked:
    /// `alpha = 2` must have order `2^m - 1`), `1 <= k < n <= 2^m - 1`, and
    /// `first_root < 2^m - 1`. An out-of-range `first_root` is rejected
    /// rather than silently reduced, since it is almost certainly a typo.
    pub fn new(
        symbol_bits: u32,
        primitive_poly: u32,
        first_root: u32,
        n: usize,
        k: usize,
    ) -> Result<Self> {
        let gf = Gf::new(symbol_bits, primitive_poly)?;
        let order = gf.order;
        if n > order {
            return Err(invalid(format!(
                "length n = {n} exceeds 2^{symbol_bits} - 1 = {order}"
            )));
        }
        if k == 0 || k >= n {
            return Err(invalid(format!("need 1 <= k < n, got n = {n}, k = {k}")));
        }
        let first_root = first_root as usize;
        if first_root >= order {
            return Err(invalid(format!(
                "first root {first_root} must be below 2^{symbol_bits} - 1 = {order}"
            )));
        }
        let parity = n - k;
        // g(x) = prod (x - alpha^(first_root + i)); build it lowest degree
        // first (so multiplying by (x + r) is a simple shift-and-add), then
        // reverse to the highest-first order the encoder uses.
        let mut low_first = vec![0u8; parity + 1];
        low_first[0] = 1;
        for i in 0..parity {
            let root = gf.pow_alpha(first_root + i);
            for j in (0..=i + 1).rev() {
                let shifted = if j > 0 { low_first[j - 1] } else { 0 };
                low_first[j] = shifted ^ gf.mul(low_first[j], root);
            }
        }
        low_first.reverse();
        let syndrome_powers = (0..parity)
            .flat_map(|i| {
                let e = (first_root + i) % order;
                (0..n).map(move |j| ((e * (n - 1 - j)) % order) as u16)
            })
            .collect();
        Ok(ReedSolomon {
            gf,
            first_root,
            n,
            k,
            generator: low_first,
            syndrome_powers,
        })
    }

    /// Codeword length `n` in symbols.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Number of data symbols `k` per codeword.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Number of parity symbols, `n - k`.
    pub fn parity(&self) -> usize {
        self.n - self.k
    }

    /// Symbol size `m` in bits.
    pub fn symbol_bits(&self) -> u32 {
        self.gf.bits
    }

    /// Maximum number of symbol errors correctable without erasures:
    /// `parity / 2`.
    pub fn correctable(&self) -> usize {
        self.parity() / 2
    }

    /// Checks that every symbol of `symbols` fits in `m` bits.
    fn check_symbols(&self, symbols: &[u8]) -> Result<()> {
        let size = self.gf.size();
        match symbols.iter().position(|&s| s as usize >= size) {
            Some(index) => Err(Error::SymbolOutOfRange {
                index,
                value: symbols[index],
                bits: self.gf.bits,
            }),
            None => Ok(()),
        }
    }

    /// Encodes `data` (exactly `k` symbols, each below `2^m`) into `out`
    /// (exactly `n` symbols): `out` receives the data followed by the
    /// `n - k` parity symbols.
    ///
    /// Returns [`Error::BadLength`] for wrong slice lengths and
    /// [`Error::SymbolOutOfRange`] for an oversized data symbol; `out` is
    /// untouched on error.
    pub fn encode_into(&self, data: &[u8], out: &mut [u8]) -> Result<()> {
        if data.len() != self.k {
            return Err(Error::BadLength {
                expected: self.k,
                got: data.len(),
            });
        }
        if out.len() != self.n {
            return Err(Error::BadLength {
                expected: self.n,
                got: out.len(),
            });
        }
        self.check_symbols(data)?;
        let p = self.parity();
        let (head, parity) = out.split_at_mut(self.k);
        head.copy_from_slice(data);
        parity.fill(0);
        // Shift-register division of d(x) x^P by the monic g(x): `parity`
        // holds the running remainder, highest degree first. Each data
        // symbol entering at the top feeds back `d + r_{P-1}` times g.
        for &d in data {
            let feedback = d ^ parity[0];
            for i in 0..p - 1 {
                parity[i] = parity[i + 1] ^ self.gf.mul(feedback, self.generator[i + 1]);
            }
            parity[p - 1] = self.gf.mul(feedback, self.generator[p]);
        }
        Ok(())
    }

    /// Encodes `data` (exactly `k` symbols) and returns the `n`-symbol
    /// codeword, data first. Errors as for [`ReedSolomon::encode_into`].
    pub fn encode(&self, data: &[u8]) -> Result<Vec<u8>> {
        let mut out = vec![0u8; self.n];
        self.encode_into(data, &mut out)?;
        Ok(out)
    }

    /// Computes the syndromes `S_i = r(alpha^(first_root + i))`,
    /// `0 <= i < P`, into `syn[..P]`; returns whether they are all zero.
    #[inline]
    fn syndromes(&self, word: &[u8], syn: &mut [u8; BUF]) -> bool {
        // The non-zero symbols, as (position, logarithm). Bytes, not
        // `usize`s: a word is at most 255 symbols long (GF(256)) and a
        // logarithm below 255, and the array is zeroed on every call
        // (4 KiB of `usize` pairs was 1% of a cluttered frame's decoding).
        let mut terms = [(0u8, 0u8); BUF];
        let mut count = 0;
        for (j, &c) in word.iter().enumerate() {
            if c != 0 {
                terms[count] = (j as u8, self.gf.log[usize::from(c)]);
                count += 1;
            }
        }
        let terms = &terms[..count];
        let n = self.n;
        let mut all_zero = true;
        for (i, s) in syn.iter_mut().take(self.parity()).enumerate() {
            let powers = &self.syndrome_powers[i * n..(i + 1) * n];
            // Both exponents are below the order, so their sum indexes the
            // doubled exponent table directly.
            let v = terms.iter().fold(0u8, |acc, &(j, l)| {
                acc ^ self.gf.exp[usize::from(l) + usize::from(powers[usize::from(j)])]
            });
            *s = v;
            all_zero &= v == 0;
        }
        all_zero
    }

    /// Corrects `word` (exactly `n` symbols, c_0 first) in place.
    ///
    /// `erasures` are positions (indices into `word`) known to be unreliable;
    /// duplicates are ignored. Decoding succeeds whenever
    /// `2 * errors + erasures <= parity`, and returns the number of symbols
    /// whose value was changed: an erased symbol that turns out to be right
    /// is not counted.
    ///
    /// Input errors: [`Error::BadLength`], [`Error::SymbolOutOfRange`],
    /// [`Error::BadErasure`] (position `>= n`). Decoding failures return
    /// [`Error::Uncorrectable`]: more distinct erasures than parity
    /// symbols, a locator whose degree is inconsistent with the
    /// Berlekamp-Massey length or exceeds the capacity, fewer roots among the
    /// `n` transmitted positions than the locator's degree (this is what
    /// rejects corrections falling into the untransmitted zeros of a
    /// shortened code), a zero error value at a non-erased position, or
    /// non-zero syndromes after correction. On any error `word` is left
    /// unchanged.
    ///
    /// The decoder runs once per detection candidate, so it does no heap
    /// allocation: all working polynomials live in fixed 256-entry stack
    /// arrays (enough for the largest code, `n = 255`).
    pub fn decode(&self, word: &mut [u8], erasures: &[usize]) -> Result<usize> {
        if word.len() != self.n {
            return Err(Error::BadLength {
                expected: self.n,
                got: word.len(),
            });
        }
        self.check_symbols(word)?;
        let n = self.n;
        let p = self.parity();
        let gf = &self.gf;
        let order = gf.order;

        // Deduplicate the erasures; `erased[j]` marks word index j.
        let mut erased = [false; BUF];
        let mut num_erasures = 0usize;
        for &index in erasures {
            if index >= n {
                return Err(Error::BadErasure { index, n });
            }
            if !erased[index] {
                erased[index] = true;
                num_erasures += 1;
            }
        }
        // With more erasures than parity symbols the erased values cannot be
        // determined, even if the word happens to be a codeword.
        if num_erasures > p {
            return Err(Error::Uncorrectable);
        }

        let mut syn = [0u8; BUF];
        // Fast path: a received codeword needs no work. This is by far the
        // most common case for a real marker, so skip the locator entirely.
        if self.syndromes(word, &mut syn) {
            return Ok(0);
        }

        // Erasure locator Gamma(x) = prod (1 - X_j x), X_j = alpha^(n-1-j),
        // lowest degree first; it seeds both Lambda and B below.
        let mut lambda = [0u8; BUF];
        lambda[0] = 1;
        let mut deg = 0usize;
        for (j, _) in erased.iter().enumerate().take(n).filter(|(_, &e)| e) {
            let x = gf.pow_alpha(n - 1 - j);
            deg += 1;
            for i in (1..=deg).rev() {
                lambda[i] ^= gf.mul(lambda[i - 1], x);
            }
        }
        let mut b = lambda;

        // Berlekamp-Massey with erasures (Blahut): start at step f with
        // L = f and iterate over the remaining P - f syndromes.
        let f = num_erasures;
        let mut len = f;
        let mut tmp = [0u8; BUF];
        for r in f + 1..=p {
            // Discrepancy Delta_r = sum_j Lambda_j S_{r-1-j}.
            let mut delta = 0u8;
            for j in 0..r.min(len + 1) {
                delta ^= gf.mul(lambda[j], syn[r - 1 - j]);
            }
            // B <- x B (computed into tmp so Lambda can use it).
            tmp[0] = 0;
            tmp[1..=p + 1].copy_from_slice(&b[..=p]);
            if delta == 0 {
                b = tmp;
                continue;
            }
            // Products by Delta (and by its inverse) with their logarithms
            // taken once (`Gf::mul_alpha`): `gf.mul` looks up both
            // factors' every time.
            let log_delta = usize::from(gf.log[usize::from(delta)]);
            if 2 * len < r + f {
                // Length change: B <- Lambda / Delta, Lambda <- Lambda - Delta x B.
                let log_inv = (order - log_delta) % order;
                for i in 0..=p + 1 {
                    let old = lambda[i];
                    lambda[i] ^= gf.mul_alpha(tmp[i], log_delta);
                    b[i] = gf.mul_alpha(old, log_inv);
                }
                len = r + f - len;
            } else {
                for i in 0..=p + 1 {
                    lambda[i] ^= gf.mul_alpha(tmp[i], log_delta);
                }
                b = tmp;
            }
        }

        // Degree checks: the locator must have exactly `len` roots, and the
        // implied number of errors must fit the capacity with the erasures.
        let deg = match lambda[..=p + 1].iter().rposition(|&c| c != 0) {
            Some(d) => d,
            None => return Err(Error::Uncorrectable),
        };
        if deg != len || 2 * (len - f) + f > p {
            return Err(Error::Uncorrectable);
        }

        // Chien search over the n transmitted positions only: word index j
        // is the coefficient of x^(n-1-j), its locator X = alpha^(n-1-j), and
        // Lambda(X^-1) = 0 marks it. Roots pointing into the untransmitted
        // zeros of a shortened code are never found, so the root-count check
        // below rejects such "corrections".
        let mut positions = [0usize; BUF];
        let num_roots = gf.chien(&lambda[..=deg], n, &mut positions);
        if num_roots != deg {
            return Err(Error::Uncorrectable);
        }

        // Forney: Omega(x) = S(x) Lambda(x) mod x^P, and the error value at
        // X is Y = X^(1 - first_root) Omega(X^-1) / Lambda'(X^-1) (signs
        // vanish in characteristic 2).
        let mut omega = [0u8; BUF];
        for (i, o) in omega.iter_mut().enumerate().take(p) {
            let mut acc = 0u8;
            for j in 0..=i.min(deg) {
                acc ^= gf.mul(lambda[j], syn[i - j]);
            }
            *o = acc;
        }
        // Formal derivative: only odd powers survive in characteristic 2.
        let mut deriv = [0u8; BUF];
        for i in (1..=deg).step_by(2) {
            deriv[i - 1] = lambda[i];
        }
        // Exponent of X^(1 - first_root), taken modulo the field order.
        let x_exp = (1 + order - self.first_root) % order;

        let mut corrected = [0u8; BUF];
        corrected[..n].copy_from_slice(word);
        let mut changed = 0usize;
        for &j in &positions[..num_roots] {
            let power = n - 1 - j;
            let x_inv = gf.pow_alpha(order - power);
            let denom = gf.eval_low_first(&deriv[..deg.max(1)], x_inv);
            if denom == 0 {
                return Err(Error::Uncorrectable);
            }
            let num = gf.eval_low_first(&omega[..p], x_inv);
            let value = gf.mul(gf.div(num, denom), gf.pow_alpha(power * x_exp));
            if value == 0 {
                // An erased symbol may legitimately be right already; a
                // zero value at an error position means the locator is wrong.
                if erased[j] {
                    continue;
                }
                return Err(Error::Uncorrectable);
            }
            corrected[j] ^= value;
            changed += 1;
        }

        // Belt and braces: the result must be a codeword.
        if !self.syndromes(&corrected[..n], &mut syn) {
            return Err(Error::Uncorrectable);
        }
        word.copy_from_slice(&corrected[..n]);
        Ok(changed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Primitive polynomials for every supported symbol size.
    const FIELDS: [(u32, u32); 7] = [
        (3, 0b1011),
        (4, 0x13),
        (5, 0x25),
        (6, 0x43),
        (7, 0x89),
        (8, 0x11d),
        (8, 0x187),
    ];

    /// Carry-less multiplication reduced by `poly`, as a reference.
    fn slow_mul(a: u8, b: u8, bits: u32, poly: u32) -> u8 {
        let (mut a, mut b, mut acc) = (a as u32, b as u32, 0u32);
        while b != 0 {
            if b & 1 != 0 {
                acc ^= a;
            }
            b >>= 1;
            a <<= 1;
            if a >> bits != 0 {
                a ^= poly;
            }
        }
        acc as u8
    }

    #[test]
    fn table_mul_matches_shift_and_add() {
        for (bits, poly) in FIELDS {
            let gf = Gf::new(bits, poly).unwrap();
            for a in 0..gf.size() as u8 {
                for b in 0..gf.size() as u8 {
                    assert_eq!(gf.mul(a, b), slow_mul(a, b, bits, poly), "{a}*{b}");
                }
            }
        }
    }

    /// The Chien search's recurrence finds the roots Horner's rule finds,
    /// for polynomials of every degree up to 16 over each field, words
    /// of every length up to the field's order.
    #[test]
    fn chien_finds_the_roots_horner_finds() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for (bits, poly) in FIELDS {
            let gf = Gf::new(bits, poly).unwrap();
            for trial in 0..400 {
                let deg = trial % 17;
                let n = 1 + (next() as usize) % gf.order;
                // Some polynomials built from chosen roots, so that roots
                // are found; the others random, with zero coefficients.
                let mut lambda = vec![0u8; deg + 1];
                if trial % 2 == 0 {
                    lambda[0] = 1;
                    for d in 1..=deg {
                        let x = gf.pow_alpha(next() as usize % gf.order);
                        for i in (1..=d).rev() {
                            lambda[i] ^= gf.mul(lambda[i - 1], x);
                        }
                    }
                } else {
                    for c in lambda.iter_mut() {
                        let keep = next() % 4 != 0;
                        *c = if keep {
                            (next() % gf.size() as u64) as u8
                        } else {
                            0
                        };
                    }
                }
                let want: Vec<usize> = (0..n)
                    .filter(|&j| {
                        let x_inv = gf.pow_alpha(gf.order - (n - 1 - j));
                        gf.eval_low_first(&lambda, x_inv) == 0
                    })
                    .collect();
                let mut out = [0usize; BUF];
                let found = gf.chien(&lambda, n, &mut out);
                assert_eq!(&out[..found], &want[..], "GF(2^{bits}) {lambda:?} n {n}");
            }
        }
    }

    #[test]
    fn inverse_and_division() {
        for (bits, poly) in FIELDS {
            let gf = Gf::new(bits, poly).unwrap();
            for a in 1..gf.size() as u8 {
                assert_eq!(gf.mul(a, gf.inv(a)), 1);
                for b in 1..gf.size() as u8 {
                    assert_eq!(gf.mul(gf.div(a, b), b), a);
                }
            }
            assert_eq!(gf.div(0, 1), 0);
        }
    }

    #[test]
    fn exp_log_round_trip() {
        for (bits, poly) in FIELDS {
            let gf = Gf::new(bits, poly).unwrap();
            assert_eq!(gf.order, (1 << bits) - 1);
            for i in 0..gf.order {
                assert_eq!(gf.log[gf.exp[i] as usize] as usize, i);
                assert_eq!(gf.exp[i + gf.order], gf.exp[i]);
            }
            assert_eq!(gf.pow_alpha(gf.order), 1);
            assert_eq!(gf.pow_alpha(1), 2);
        }
    }

    #[test]
    fn known_products() {
        let gf = Gf::new(8, 0x11d).unwrap();
        assert_eq!(gf.mul(0x80, 2), 0x1d);
        assert_eq!(gf.pow_alpha(8), 0x1d);
        let gf = Gf::new(4, 0x13).unwrap();
        assert_eq!(gf.pow_alpha(4), 0b0011);
        assert_eq!(gf.mul(0b1000, 0b0010), 0b0011);
    }

    #[test]
    fn rejects_non_primitive() {
        // x^4+x^3+x^2+x+1 is irreducible, but x has order 5.
        assert!(Gf::new(4, 0x1f).is_err());
        // x^4 + 1 = (x + 1)^4 is reducible.
        assert!(Gf::new(4, 0x11).is_err());
        // No constant term: x is not even invertible.
        assert!(Gf::new(4, 0x12).is_err());
        // (x^9 - 1)/(x - 1): x has order 9.
        assert!(Gf::new(8, 0x1ff).is_err());
    }

    /// The tabled syndromes equal Horner's rule on random words of both
    /// families' codes, with and without zero symbols.
    #[test]
    fn tabled_syndromes_match_horner() {
        let mut x: u64 = 0x2545_F491_4F6C_DD1D;
        for (bits, poly, first_root, n, k) in [(8, 0x187, 120, 20, 2), (4, 0x13, 0, 15, 5)] {
            let rs = ReedSolomon::new(bits, poly, first_root, n, k).unwrap();
            let size = 1u64 << bits;
            for _ in 0..2000 {
                let word: Vec<u8> = (0..n)
                    .map(|_| {
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        // A quarter of the symbols zero.
                        (if x.is_multiple_of(4) {
                            0
                        } else {
                            (x >> 8) % size
                        }) as u8
                    })
                    .collect();
                let mut syn = [0u8; BUF];
                let zero = rs.syndromes(&word, &mut syn);
                for (i, &s) in syn.iter().take(rs.parity()).enumerate() {
                    let e = (rs.first_root + i) % rs.gf.order;
                    let horner = word.iter().fold(0u8, |acc, &c| rs.gf.mul_alpha(acc, e) ^ c);
                    assert_eq!(s, horner, "syndrome {i} of {word:?}");
                }
                assert_eq!(zero, syn[..rs.parity()].iter().all(|&s| s == 0));
            }
        }
    }

    #[test]
    fn generator_has_the_right_roots() {
        let rs = ReedSolomon::new(8, 0x187, 120, 20, 2).unwrap();
        let mut low_first = rs.generator.clone();
        low_first.reverse();
        assert_eq!(low_first.len(), 19);
        for i in 0..18 {
            let root = rs.gf.pow_alpha(120 + i);
            assert_eq!(rs.gf.eval_low_first(&low_first, root), 0);
        }
        assert_ne!(rs.gf.eval_low_first(&low_first, rs.gf.pow_alpha(119)), 0);
        assert_ne!(rs.gf.eval_low_first(&low_first, rs.gf.pow_alpha(138)), 0);
    }
}

//! A scrambled Halton sequence: the low-discrepancy points behind sampled
//! datasets (`[sample]` in a spec).
//!
//! Why Halton and not Sobol: a sampled dataset may have any number of
//! scenes, and every prefix of a Halton sequence is well spread, while
//! Sobol's balance properties hold for powers of two only; dimensions are
//! added one prime base at a time, with no direction-number tables to ship
//! or choose. Why scrambled: plain Halton points in two high bases (say 89
//! and 97) lie on a few lines for the first thousands of points, which
//! would tie factors together (every large tilt with a short distance).
//! Each digit position of each dimension gets its own random permutation
//! of the digits, seeded by the dataset's seed ("random digit
//! permutation", a simplified Owen scrambling: Owen, "Randomly permuted
//! (t,m,s)-nets and (t,s)-sequences", 1995; for Halton, Mascagni and Chi,
//! "On the scrambled Halton sequence", 2004). Digit `0` is permuted too, so
//! the tail of a point's digits is not all zeros; the radical inverse is
//! summed to full `f64` precision.

use crate::rng::{derive_seed, mix64};

/// The first `n` primes (trial division; n is at most a few hundred).
fn primes(n: usize) -> Vec<u64> {
    let mut out: Vec<u64> = Vec::with_capacity(n);
    let mut c = 2u64;
    while out.len() < n {
        if out
            .iter()
            .take_while(|&&p| p * p <= c)
            .all(|&p| !c.is_multiple_of(p))
        {
            out.push(c);
        }
        c += 1;
    }
    out
}

/// Digits of base `b` needed to resolve an `f64` in [0, 1): `b^k >= 2^53`.
fn digits_for(b: u64) -> usize {
    let mut k = 0;
    let mut scale = 1.0f64;
    while scale < 9_007_199_254_740_992.0 {
        scale *= b as f64;
        k += 1;
    }
    k
}

/// A scrambled Halton sequence over a fixed number of dimensions.
#[derive(Debug, Clone)]
pub struct ScrambledHalton {
    bases: Vec<u64>,
    /// `perms[d][k]`: the digit permutation of dimension `d`, digit `k`.
    perms: Vec<Vec<Vec<u16>>>,
}

impl ScrambledHalton {
    /// The sequence of `dims` dimensions scrambled by `seed`.
    #[must_use]
    pub fn new(dims: usize, seed: u64) -> Self {
        let bases = primes(dims);
        let perms = bases
            .iter()
            .enumerate()
            .map(|(d, &b)| {
                (0..digits_for(b))
                    .map(|k| {
                        // Fisher-Yates with a SplitMix64 counter stream.
                        let mut p: Vec<u16> = (0..b as u16).collect();
                        let mut state = derive_seed(seed, &[d as u64, k as u64]);
                        for i in (1..p.len()).rev() {
                            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
                            let j = (mix64(state) % (i as u64 + 1)) as usize;
                            p.swap(i, j);
                        }
                        p
                    })
                    .collect()
            })
            .collect();
        Self { bases, perms }
    }

    /// Number of dimensions.
    #[must_use]
    pub fn dims(&self) -> usize {
        self.bases.len()
    }

    /// Coordinate `d` of point `i`, in [0, 1).
    ///
    /// # Panics
    /// When `d` is not below [`ScrambledHalton::dims`].
    #[must_use]
    pub fn value(&self, i: u64, d: usize) -> f64 {
        let b = self.bases[d];
        let inv = 1.0 / b as f64;
        let mut n = i;
        let mut scale = inv;
        let mut v = 0.0;
        for perm in &self.perms[d] {
            let digit = (n % b) as usize;
            n /= b;
            v += f64::from(perm[digit]) * scale;
            scale *= inv;
        }
        v.min(1.0 - f64::EPSILON / 2.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_primes() {
        assert_eq!(primes(8), vec![2, 3, 5, 7, 11, 13, 17, 19]);
    }

    #[test]
    fn every_prefix_is_stratified_in_each_dimension() {
        // The radical inverse puts exactly one of the first b^k points in
        // each interval [j / b^k, (j + 1) / b^k), scrambled or not.
        let h = ScrambledHalton::new(6, 11);
        for d in 0..6 {
            let b = h.bases[d] as usize;
            let n = b * b;
            let mut seen = vec![0usize; n];
            for i in 0..n as u64 {
                let v = h.value(i, d);
                assert!((0.0..1.0).contains(&v));
                seen[(v * n as f64) as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "dimension {d}: {seen:?}");
        }
    }

    #[test]
    fn scrambling_breaks_the_correlation_of_high_bases() {
        // Dimensions 23 and 24 (bases 89 and 97): unscrambled, the first
        // 89 points lie on the line y = 89/97 x; scrambled, the sample
        // correlation is small.
        let h = ScrambledHalton::new(25, 3);
        let n = 1000;
        let xs: Vec<f64> = (0..n).map(|i| h.value(i, 23)).collect();
        let ys: Vec<f64> = (0..n).map(|i| h.value(i, 24)).collect();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let (mx, my) = (mean(&xs), mean(&ys));
        let cov: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
        let vx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
        let vy: f64 = ys.iter().map(|y| (y - my) * (y - my)).sum();
        let r = cov / (vx * vy).sqrt();
        assert!(r.abs() < 0.1, "correlation {r}");
        // Different seeds, different points; same seed, same points.
        let g = ScrambledHalton::new(25, 4);
        assert_ne!(h.value(5, 3), g.value(5, 3));
        assert_eq!(h.value(5, 3), ScrambledHalton::new(25, 3).value(5, 3));
    }
}

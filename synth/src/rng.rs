//! Seeded randomness with a fixed algorithm.
//!
//! Every random choice of a dataset comes from a generator seeded by the
//! spec's seed, the image's index and a stream number naming what the
//! numbers are for (background, noise, occlusion, ...). Images are therefore
//! independent of each other and of the thread that renders them, and the
//! same spec and seed give the same bytes.
//!
//! The generator is xoshiro256++ (Blackman and Vigna, 2018) from the `rand`
//! crate, a fixed algorithm (unlike `StdRng`). Seeds are combined with the
//! SplitMix64 finaliser (Steele, Lea and Flood, 2014).

use rand::SeedableRng;

/// The generator used everywhere in synth.
pub type SynthRng = rand::rngs::Xoshiro256PlusPlus;

/// What a random stream is used for; part of its seed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    /// Background clutter and textures.
    Background = 1,
    /// Sensor noise.
    Noise = 2,
    /// Procedurally generated occlusions.
    Occlusion = 3,
    /// Occluder textures.
    Texture = 4,
    /// Choices of sampled scenes that are not low-discrepancy draws
    /// (placement retries, shadow and glare shapes).
    Sample = 5,
}

/// SplitMix64's output function: a bijective 64-bit mixer.
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Combines a seed with further numbers into a new seed.
#[must_use]
pub fn derive_seed(seed: u64, parts: &[u64]) -> u64 {
    let mut h = mix64(seed ^ 0x5851_f42d_4c95_7f2d);
    for &p in parts {
        h = mix64(h.wrapping_add(0x9e37_79b9_7f4a_7c15) ^ p);
    }
    h
}

/// The generator of `stream` for image `index` of a dataset seeded `seed`.
#[must_use]
pub fn image_rng(seed: u64, index: u64, stream: Stream) -> SynthRng {
    SynthRng::seed_from_u64(derive_seed(seed, &[index, stream as u64]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let a: Vec<u64> = (0..4)
            .map(|_| image_rng(7, 3, Stream::Noise).random())
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|_| image_rng(7, 3, Stream::Noise).random())
            .collect();
        assert_eq!(a, b);
        let x: u64 = image_rng(7, 3, Stream::Noise).random();
        let y: u64 = image_rng(7, 4, Stream::Noise).random();
        let z: u64 = image_rng(7, 3, Stream::Background).random();
        assert!(x != y && x != z && y != z);
    }
}

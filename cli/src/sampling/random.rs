//! A tiny seeded random number generator (SplitMix64) and seed hashing.
//!
//! Rendering seeds one generator per pixel from the pixel's index, so results do
//! not depend on how rayon splits the work.

use glam::Vec2;

/// SplitMix64 (Steele, Lea and Flood 2014): one 64-bit add and a mix per number,
/// statistically good enough for Monte Carlo and trivially seedable.
#[derive(Clone, Debug)]
pub struct SampleRng {
    state: u64,
}

impl SampleRng {
    /// A generator whose sequence depends only on `seed`.
    pub fn new(seed: u64) -> Self {
        SampleRng { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`, with 24 random bits (every value exactly representable).
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// Two independent uniform numbers in `[0, 1)`.
    pub fn next_vec2(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }

    /// Uniform integer in `0..n` (`n > 0`), by multiply-shift.
    pub fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next_u64()) * n as u128) >> 64) as usize
    }
}

/// Hashes a list of numbers into one well-mixed seed, e.g. `(picture, pixel)`.
pub fn hash_seed(parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(0x243F_6A88_85A3_08D3, |h, &p| mix64(h ^ mix64(p)))
}

/// The SplitMix64 finaliser (a bijection on u64 with full avalanche).
fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_floats_have_the_right_mean_and_range() {
        let mut rng = SampleRng::new(7);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += f64::from(x);
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
    }

    #[test]
    fn seeds_differ_by_part_and_order() {
        assert_ne!(hash_seed(&[1, 2]), hash_seed(&[2, 1]));
        assert_ne!(hash_seed(&[0]), hash_seed(&[1]));
        assert_eq!(hash_seed(&[3, 4]), hash_seed(&[3, 4]));
    }

    #[test]
    fn below_stays_in_range() {
        let mut rng = SampleRng::new(1);
        assert!((0..1000).all(|_| rng.below(3) < 3));
    }
}

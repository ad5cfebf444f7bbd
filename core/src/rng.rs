//! Deterministic random numbers for everything in core that samples: light
//! samples (ssv), bake directions and PCA starts (transfer), stratified jitter in
//! SH projection.
//!
//! SplitMix64 (Steele, Lea and Flood, "Fast Splittable Pseudorandom Number
//! Generators", OOPSLA 2014): one add and a mixing finaliser per draw, passes
//! BigCrush, and seeds are cheap, so every independent stream (a vertex, a pass, a
//! light) gets its own generator and results do not depend on thread scheduling.

/// The SplitMix64 generator.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

/// The SplitMix64 step from `state`: the finaliser of `state + γ`, a bijection on
/// `u64` with full avalanche, usable as a hash.
#[inline]
pub fn splitmix64(state: u64) -> u64 {
    let mut z = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The top 53 bits of `bits` as a uniform number in `[0, 1)`.
#[inline]
pub fn unit_f64(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

impl SplitMix64 {
    /// A generator whose first output depends on every bit of `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// The stream of item `item` in pass `pass` of a run seeded with `seed` (for
    /// example a bake's vertex and bounce pass).
    pub fn for_vertex(seed: u64, item: u64, pass: u64) -> Self {
        // Mixing each part through the finaliser keeps nearby (item, pass) pairs
        // on unrelated streams.
        let a = splitmix64(seed);
        let b = splitmix64(a ^ item.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        SplitMix64::new(splitmix64(b ^ pass.wrapping_mul(0xD1B5_4A32_D192_ED03)))
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let out = splitmix64(self.state);
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        out
    }

    /// A uniform `f32` in `[0, 1)` (24 random bits).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    /// A uniform `f64` in `[0, 1)` (53 random bits).
    #[inline]
    pub fn next_f64(&mut self) -> f64 {
        unit_f64(self.next_u64())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published first outputs of SplitMix64 seeded with 1234567 (the
    /// reference C implementation by Vigna).
    #[test]
    fn matches_the_reference_sequence() {
        let mut rng = SplitMix64::new(1_234_567);
        assert_eq!(rng.next_u64(), 6_457_827_717_110_365_317);
        assert_eq!(rng.next_u64(), 3_203_168_211_198_807_973);
        assert_eq!(rng.next_u64(), 9_817_491_932_198_370_423);
    }

    #[test]
    fn floats_are_in_the_unit_interval() {
        let mut rng = SplitMix64::new(9);
        for _ in 0..10_000 {
            let (a, b) = (rng.next_f32(), rng.next_f64());
            assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
        }
    }
}

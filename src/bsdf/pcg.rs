//! PCG32 (O'Neill 2014, "PCG: a family of simple fast space-efficient statistically good algorithms for random
//! number generation", XSH-RR 64/32): a small deterministic generator for tests, histograms and benchmarks.
//! Not used for rendering (the renderer has its own Owen-scrambled Sobol sampler).

/// A PCG32 stream.
#[derive(Debug, Clone)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

    /// A generator seeded with `seed` on stream `stream`.
    pub fn new(seed: u64, stream: u64) -> Pcg32 {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 uniformly distributed bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// A uniform number in [0, 1) with 24 random bits (every value exactly representable in f32).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Three uniform numbers, the `u` of [`super::Bsdf::sample`].
    #[inline]
    pub fn next_u3(&mut self) -> [f32; 3] {
        [self.next_f32(), self.next_f32(), self.next_f32()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_sequence() {
        // O'Neill's pcg32-demo: seed 42, stream 54 starts 0xa15c02b7, 0x7b47f409, 0xba1d3330.
        let mut r = Pcg32::new(42, 54);
        assert_eq!(
            [r.next_u32(), r.next_u32(), r.next_u32()],
            [0xa15c02b7, 0x7b47f409, 0xba1d3330]
        );
    }

    #[test]
    fn uniform_mean_and_range() {
        let mut r = Pcg32::new(1, 2);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        // Mean 1/2 with standard error 1/√(12 n) = 0.0009: 5 σ.
        assert!((sum / n as f64 - 0.5).abs() < 0.0046);
    }
}

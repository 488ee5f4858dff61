//! Sample streams keyed by (pixel, sample index, dimension): Owen-scrambled Sobol points (Burley 2020, the
//! `sobol_burley` crate), so every pixel's samples are independent of threads and tile order.

use crate::util::hash::hash64;

/// The sample dimensions a camera sample uses, named so no two consumers share one.
pub mod dim {
    /// Pixel-filter offset, x and y.
    pub const FILTER: u32 = 0;
    /// Environment-light direction (two dimensions).
    pub const ENVIRONMENT: u32 = 2;
}

/// The sampler of one pixel.
#[derive(Debug, Clone, Copy)]
pub struct PixelSampler {
    seed: u32,
}

impl PixelSampler {
    /// The sampler of pixel (`x`, `y`) for scene seed `seed`.
    #[inline]
    pub fn new(x: u32, y: u32, seed: u32) -> Self {
        // x, y < 2¹⁶ (film.resolution ≤ 32768), so (seed, y, x) fill disjoint bits: every seed bit counts.
        let key = (u64::from(seed) << 32) | (u64::from(y & 0xffff) << 16) | u64::from(x & 0xffff);
        PixelSampler { seed: hash(key) }
    }

    /// Component `dimension` (< 256) of sample `index`, in [0, 1).
    ///
    /// Sobol points are stratified in blocks of 2¹⁶ indices (the most `sobol_burley` computes); a larger index
    /// (more than 65536 samples of one dimension in one pixel, e.g. many spp × many light samples) continues in an
    /// independently scrambled block.
    #[inline]
    pub fn get(&self, index: u32, dimension: u32) -> f32 {
        self.get_salted(index, dimension, 0)
    }

    /// As [`PixelSampler::get`], from an independent scrambling chosen by `salt` (e.g. one per light, so that the
    /// samples of different lights are not correlated).
    #[inline]
    pub fn get_salted(&self, index: u32, dimension: u32, salt: u32) -> f32 {
        let block = index >> 16;
        let seed = if block == 0 && salt == 0 {
            self.seed
        } else {
            hash(u64::from(self.seed) | (u64::from(block) << 32) ^ (u64::from(salt) << 48))
        };
        sobol_burley::sample(index & 0xffff, dimension, seed)
    }

    /// A 64-bit key for one ray of sample `index` (e.g. the stochastic strand presence of
    /// [`crate::accel::strand_present`]), unique per (pixel, seed, index, dimension, salt) up to hash collisions.
    #[inline]
    pub fn key(&self, index: u32, dimension: u32, salt: u32) -> u64 {
        let a = hash64((u64::from(self.seed) << 32) | u64::from(index));
        hash64(a ^ (u64::from(dimension) << 32 | u64::from(salt)))
    }

    /// Two consecutive dimensions starting at `dimension`.
    #[inline]
    pub fn get_2d(&self, index: u32, dimension: u32) -> (f32, f32) {
        (self.get(index, dimension), self.get(index, dimension + 1))
    }
}

/// [`hash64`] (SplitMix64) folded to 32 bits: decorrelates the per-pixel scrambling seeds.
#[inline]
fn hash(z: u64) -> u32 {
    hash64(z) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_in_unit_interval_and_stratified() {
        let s = PixelSampler::new(3, 7, 42);
        let n = 256;
        let mut bins = [0u32; 16];
        for i in 0..n {
            let u = s.get(i, 0);
            assert!((0.0..1.0).contains(&u));
            bins[(u * 16.0) as usize] += 1;
        }
        // A (0, 1)-sequence puts exactly n/16 points in each of 16 equal intervals.
        assert!(bins.iter().all(|&b| b == 16), "{bins:?}");
    }

    #[test]
    fn indices_beyond_one_sobol_block_stay_uniform() {
        let s = PixelSampler::new(5, 9, 1);
        let mut bins = [0u32; 16];
        for i in 65_536..65_536 + 4096 {
            bins[(s.get(i, 3) * 16.0) as usize] += 1;
        }
        assert!(bins.iter().all(|&b| b == 256), "{bins:?}");
        assert_ne!(s.get(7, 3), s.get(65_536 + 7, 3));
        assert_ne!(s.get_salted(7, 3, 1), s.get(7, 3));
        assert_ne!(s.key(7, 3, 0), s.key(7, 3, 1));
        assert_ne!(s.key(7, 3, 0), s.key(8, 3, 0));
    }

    #[test]
    fn every_seed_bit_changes_the_stream() {
        let base = PixelSampler::new(4, 2, 0).get(0, 0);
        for bit in 0..32 {
            let other = PixelSampler::new(4, 2, 1 << bit).get(0, 0);
            assert_ne!(base, other, "seed bit {bit} is ignored");
        }
    }

    #[test]
    fn neighbouring_pixels_get_different_streams() {
        let a = PixelSampler::new(0, 0, 0).get(0, 0);
        let b = PixelSampler::new(1, 0, 0).get(0, 0);
        assert_ne!(a, b);
    }
}

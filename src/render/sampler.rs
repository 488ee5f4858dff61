//! Sample streams keyed by (pixel, sample index, dimension): Owen-scrambled Sobol points (Burley 2020, the
//! `sobol_burley` crate), so every pixel's samples are independent of threads and tile order.

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
        let key = (u64::from(seed) << 40) ^ (u64::from(y) << 20) ^ u64::from(x);
        PixelSampler { seed: hash(key) }
    }

    /// Component `dimension` of sample `index`, in [0, 1).
    #[inline]
    pub fn get(&self, index: u32, dimension: u32) -> f32 {
        sobol_burley::sample(index, dimension, self.seed)
    }

    /// Two consecutive dimensions starting at `dimension`.
    #[inline]
    pub fn get_2d(&self, index: u32, dimension: u32) -> (f32, f32) {
        (self.get(index, dimension), self.get(index, dimension + 1))
    }
}

/// SplitMix64 finaliser folded to 32 bits: decorrelates the per-pixel scrambling seeds.
#[inline]
fn hash(mut z: u64) -> u32 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as u32
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
    fn neighbouring_pixels_get_different_streams() {
        let a = PixelSampler::new(0, 0, 0).get(0, 0);
        let b = PixelSampler::new(1, 0, 0).get(0, 0);
        assert_ne!(a, b);
    }
}

//! Sample streams keyed by (pixel, sample index, dimension): Owen-scrambled Sobol points (Burley 2020, the
//! `sobol_burley` crate), so every pixel's samples are independent of threads and tile order.

use std::cell::Cell;
use std::sync::OnceLock;

use sobol_burley::parts::{
    hash_int4, owen_scramble_int4_rev, owen_scramble_rev, sobol_int4_rev, Int4,
};

use crate::util::hash::{hash64, unit_f32};

/// Every sample dimension a camera sample uses, in one table so that no two consumers share one. The values are
/// part of every image: changing one changes the noise of every render (`scripts/same-images.sh` notices).
///
/// | dimensions | width | consumer |
/// |---|---|---|
/// | `FILTER` = 0 | 2 | pixel-filter offset x, y (`render`) |
/// | `vertex(b, LIGHT_SELECT)` = 2 + 8b | 1 | path vertex b: light chosen ∝ its selection weight |
/// | `vertex(b, LIGHT)` = 3 + 8b | 2 | path vertex b: light sample |
/// | `vertex(b, MATERIAL)` = 5 + 8b | 3 | path vertex b: material (BSDF) sample |
/// | `vertex(b, ROULETTE)` = 8 + 8b | 1 | path vertex b: Russian roulette |
/// | `vertex(0, LIGHT_TERMINATE)` = 9 | 1 | the first vertex's light-sample roulette (`light_threshold`; deeper vertices reuse their light-selection draw's remainder) |
/// | 9 + 8b, b ≥ 1 | 1 | spare |
///
/// Vertex 0 is the first shading point; its light samples also read scramblings salted per light
/// ([`PixelSampler::get_salted`]), in the same dimensions.
pub mod dim {
    /// Dimensions of a `sobol_burley` point.
    pub const COUNT: u32 = 256;
    /// Pixel-filter offset, x and y (2 dimensions).
    pub const FILTER: u32 = 0;
    /// The first dimension of path vertex 0, after the filter's.
    pub const FIRST_VERTEX: u32 = 2;
    /// Dimensions per path vertex.
    pub const PER_VERTEX: u32 = 8;
    /// Offset in a vertex's block: the light chosen in proportion to its selection weight (1 dimension).
    pub const LIGHT_SELECT: u32 = 0;
    /// Offset in a vertex's block: the light sample (2 dimensions).
    pub const LIGHT: u32 = 1;
    /// Offset in a vertex's block: the material sample (3 dimensions).
    pub const MATERIAL: u32 = 3;
    /// Offset in a vertex's block: Russian roulette after the vertex (1 dimension).
    pub const ROULETTE: u32 = 6;
    /// Offset in vertex 0's block: whether a dim light sample traces its shadow ray (1 dimension, apart from the
    /// light sample's own two so that the choice is independent of where the sample fell; vertex 0's samples under
    /// `lights = "all"` have no selection draw whose remainder could serve).
    pub const LIGHT_TERMINATE: u32 = 7;
    /// The most path vertices whose blocks fit in [`COUNT`] dimensions (31).
    pub const MAX_VERTICES: u32 = (COUNT - FIRST_VERTEX) / PER_VERTEX;

    /// Dimension `offset` (one of [`LIGHT_SELECT`], [`LIGHT`], [`MATERIAL`], [`ROULETTE`], [`LIGHT_TERMINATE`]) of
    /// path vertex `b`
    /// (0 = the first shading point; `b` < [`MAX_VERTICES`]).
    #[inline]
    pub const fn vertex(b: u32, offset: u32) -> u32 {
        FIRST_VERTEX + b * PER_VERTEX + offset
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        /// Every named range of the table, as (first dimension, width, name).
        fn ranges() -> Vec<(u32, u32, String)> {
            let mut r = vec![(FILTER, 2, "filter".to_string())];
            for b in 0..MAX_VERTICES {
                for (offset, width, name) in [
                    (LIGHT_SELECT, 1, "light select"),
                    (LIGHT, 2, "light"),
                    (MATERIAL, 3, "material"),
                    (ROULETTE, 1, "roulette"),
                ] {
                    r.push((vertex(b, offset), width, format!("vertex {b} {name}")));
                }
            }
            // Only vertex 0 reads LIGHT_TERMINATE (deeper vertices reuse their selection draw's remainder).
            r.push((
                vertex(0, LIGHT_TERMINATE),
                1,
                "vertex 0 light terminate".to_string(),
            ));
            r
        }

        #[test]
        fn no_two_consumers_share_a_dimension_and_all_fit() {
            let mut owner: Vec<Option<String>> = vec![None; COUNT as usize];
            for (first, width, name) in ranges() {
                for d in first..first + width {
                    let slot = owner
                        .get_mut(d as usize)
                        .unwrap_or_else(|| panic!("{name}: dimension {d} >= {COUNT}"));
                    if let Some(other) = slot {
                        panic!("dimension {d} is used by both {other} and {name}");
                    }
                    *slot = Some(name.clone());
                }
            }
        }

        #[test]
        fn the_recorded_images_dimensions_are_unchanged() {
            // The values every render so far used: changing one changes the noise of every image.
            assert_eq!(FILTER, 0);
            assert_eq!(
                [LIGHT_SELECT, LIGHT, MATERIAL, ROULETTE].map(|o| vertex(0, o)),
                [2, 3, 5, 8]
            );
            assert_eq!(
                [LIGHT_SELECT, LIGHT, MATERIAL, ROULETTE].map(|o| vertex(2, o)),
                [18, 19, 21, 24]
            );
            assert_eq!(vertex(0, LIGHT_TERMINATE), 9);
            assert_eq!(MAX_VERTICES, 31);
        }
    }
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
    ///
    /// Past the Sobol sequence's [`dim::COUNT`] dimensions (bounces past the 30th, which only a tail of paths
    /// reaches: [`crate::render::integrator::MAX_TAIL_LENGTH`]) the numbers are independent uniform ones hashed from
    /// the pixel, index, dimension and salt: unbiased, not stratified, where a path's contribution is already
    /// small.
    #[inline]
    pub fn get_salted(&self, index: u32, dimension: u32, salt: u32) -> f32 {
        if dimension >= dim::COUNT {
            return unit_f32(self.key(index, dimension, salt));
        }
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

/// How many dimensions a [`CameraSample`] computes at once: four `sobol_burley` sets (16 dimensions).
const BATCH: usize = 16;

/// How many batches a [`CameraSample`] keeps: dimensions 0 to 31, the filter's and path vertices 0 to 3 (a path of
/// up to 3 bounces); deeper dimensions are computed one at a time.
const CACHED_BATCHES: usize = 2;

/// `sobol_burley`'s sets per batch.
const SETS: usize = BATCH / 4;

/// Sobol's direction numbers of dimensions 0 to 31, bit-reversed as `sobol_burley` keeps them: `rows[b][k][s]` is
/// the four-lane number set 4b + s XORs in when bit k (from the top) of the shuffled, bit-reversed index is set.
/// Read once from the crate's own public `parts::sobol_int4_rev` (an index with one bit set gives that bit's
/// numbers), so the values are the crate's by construction.
struct Directions {
    rows: [[[Int4; SETS]; 16]; CACHED_BATCHES],
}

fn directions() -> &'static Directions {
    static TABLE: OnceLock<Directions> = OnceLock::new();
    TABLE.get_or_init(|| Directions {
        rows: std::array::from_fn(|b| {
            std::array::from_fn(|k| {
                std::array::from_fn(|s| sobol_int4_rev(1u32 << (31 - k), (SETS * b + s) as u32))
            })
        }),
    })
}

/// Dimensions 16b to 16b + 15 of sample `index` (< 2¹⁶) for scrambling seed `seed`: exactly what
/// `sobol_burley::sample_4d` gives for sets 4b to 4b + 3 (tested), with the index's scrambling and the walk over
/// its bits done once for the four sets, and each set finished by the crate's own scrambling, bit reversal and
/// conversion (`parts`), as `sample_4d` finishes it.
#[inline]
fn sample_16d(index: u32, batch: usize, seed: u32) -> [f32; BATCH] {
    let rows = &directions().rows[batch];
    let shuffled = owen_scramble_rev(
        index.reverse_bits(),
        sobol_burley::parts::hash(seed ^ 0x79c68e4a),
    );
    let mut acc: [Int4; SETS] = [[0u32; 4].into(); SETS];
    // Each set bit among the top 16 XORs in its row (`sobol_int4_rev`'s walk; XOR's order does not matter).
    let mut bits = shuffled >> 16;
    while bits != 0 {
        let row = &rows[15 - bits.trailing_zeros() as usize];
        bits &= bits - 1;
        for (a, r) in acc.iter_mut().zip(row) {
            *a ^= *r;
        }
    }
    // `sample_4d`'s Owen scrambling of each set, from the seed and the set's number.
    let seed_mul: Int4 = [seed.wrapping_mul(0x9c8f2d3b); 4].into();
    let mut out = [0.0f32; BATCH];
    for (s, (sobol, o)) in acc.into_iter().zip(out.chunks_exact_mut(4)).enumerate() {
        let set: Int4 = [(SETS * batch + s) as u32; 4].into();
        let scramble = seed_mul ^ set ^ [0x912f69ba, 0x174f18ab, 0x691e72ca, 0xb40cc1b8].into();
        o.copy_from_slice(
            &owen_scramble_int4_rev(sobol, hash_int4(scramble))
                .reverse_bits()
                .to_f32_norm(),
        );
    }
    out
}

/// The random numbers of one camera sample (sample `index` of one pixel), computed sixteen dimensions at a time
/// ([`sample_16d`], which gives exactly the values `sobol_burley::sample` gives one dimension at a time) and kept for
/// the path's later reads. A path reads about ten dimensions of its sample (on the peer scene twelve, in four
/// `sobol_burley` sets): one batch replaces four four-wide computations (`sample_4d`, on the peer scene the largest
/// single item of cuticle's own instructions, 12 %), or up to sixteen scalar ones. Reads of another index (several
/// light or material samples per vertex), of a salted scrambling, or beyond the kept batches go to
/// [`PixelSampler::get_salted`] as before, so every value is unchanged.
#[derive(Debug)]
pub struct CameraSample<'s> {
    sampler: &'s PixelSampler,
    index: u32,
    /// Bit b set: `batches[b]` holds dimensions 16b to 16b + 15.
    filled: Cell<u32>,
    /// Cells per value, so that a read copies one f32, not the batch.
    batches: [[Cell<f32>; BATCH]; CACHED_BATCHES],
}

impl<'s> CameraSample<'s> {
    /// Sample `index` of `sampler`'s pixel; nothing is computed until a dimension is read.
    #[inline]
    pub fn new(sampler: &'s PixelSampler, index: u32) -> Self {
        CameraSample {
            sampler,
            index,
            filled: Cell::new(0),
            batches: Default::default(),
        }
    }

    /// [`PixelSampler::get_salted`], from the kept batches when the read is of this sample, unsalted, in the first
    /// [`CACHED_BATCHES`] batches and in the first Sobol block.
    #[inline(always)]
    pub fn get_salted(&self, index: u32, dimension: u32, salt: u32) -> f32 {
        let d = dimension as usize;
        match self.kept(index, d, d, salt) {
            Some(batch) => batch[d % BATCH].get(),
            None => self.uncached(index, dimension, salt),
        }
    }

    /// `N` consecutive dimensions from `dimension` ([`CameraSample::get_salted`] of each): one check and one fill
    /// when they lie in one kept batch, as a light sample's two and a material sample's three do.
    #[inline(always)]
    pub fn get_n<const N: usize>(&self, index: u32, dimension: u32, salt: u32) -> [f32; N] {
        let first = dimension as usize;
        match self.kept(index, first, first + N - 1, salt) {
            Some(batch) => std::array::from_fn(|k| batch[first % BATCH + k].get()),
            None => std::array::from_fn(|k| self.get_salted(index, dimension + k as u32, salt)),
        }
    }

    /// The kept batch holding dimensions `first` to `last` of sample `index`, filled if it was not yet; `None` for a
    /// read the kept batches do not hold (another index, a salt, a run across batches, a deeper dimension, a later
    /// Sobol block).
    #[inline(always)]
    fn kept(
        &self,
        index: u32,
        first: usize,
        last: usize,
        salt: u32,
    ) -> Option<&[Cell<f32>; BATCH]> {
        let batch = first / BATCH;
        if index != self.index
            || salt != 0
            || batch != last / BATCH
            || batch >= CACHED_BATCHES
            || index >> 16 != 0
        {
            return None;
        }
        if self.filled.get() & (1u32 << batch) == 0 {
            self.fill(batch);
        }
        Some(&self.batches[batch])
    }

    /// [`PixelSampler::get_salted`] for a read the kept batches do not hold (out of line: the reads above are
    /// inlined where the path reads them, about ten per camera sample).
    #[cold]
    #[inline(never)]
    fn uncached(&self, index: u32, dimension: u32, salt: u32) -> f32 {
        self.sampler.get_salted(index, dimension, salt)
    }

    /// Computes batch `batch` (out of line: once per batch and sample, where the reads above are many and inlined).
    #[inline(never)]
    fn fill(&self, batch: usize) {
        let values = sample_16d(self.index, batch, self.sampler.seed);
        for (cell, v) in self.batches[batch].iter().zip(values) {
            cell.set(v);
        }
        self.filled.set(self.filled.get() | (1u32 << batch));
    }

    /// [`PixelSampler::get`] through the kept batches.
    #[inline]
    pub fn get(&self, index: u32, dimension: u32) -> f32 {
        self.get_salted(index, dimension, 0)
    }

    /// [`PixelSampler::get_2d`] through the kept batches.
    #[inline]
    pub fn get_2d(&self, index: u32, dimension: u32) -> (f32, f32) {
        (self.get(index, dimension), self.get(index, dimension + 1))
    }

    /// [`PixelSampler::key`] (keys are hashes, not Sobol points: nothing to keep).
    #[inline]
    pub fn key(&self, index: u32, dimension: u32, salt: u32) -> u64 {
        self.sampler.key(index, dimension, salt)
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
    fn camera_sample_reads_the_same_values_as_the_scalar_sampler() {
        // Every dimension of the kept sets and beyond, in an order that fills sets out of order, plus reads the
        // cache must pass through (another index, a salt, a second Sobol block): bit for bit the scalar values.
        let s = PixelSampler::new(11, 5, 9);
        for index in [0u32, 1, 7, 65535, 65536, 70000] {
            let c = CameraSample::new(&s, index);
            for dimension in (0..40).rev().chain(0..40) {
                assert_eq!(
                    c.get(index, dimension),
                    s.get(index, dimension),
                    "index {index} dim {dimension}"
                );
            }
            assert_eq!(c.get_salted(index, 3, 2), s.get_salted(index, 3, 2));
            assert_eq!(c.get(index + 1, 3), s.get(index + 1, 3));
            assert_eq!(c.get_2d(index, 4), s.get_2d(index, 4));
            assert_eq!(c.key(index, 4, 1), s.key(index, 4, 1));
            // Runs of two and three, within a batch, across the batches' border (14..17), past the kept ones, salted
            // and of another index, on a fresh sample (so that the run's own check fills the batch).
            for (d, salt, other) in [
                (5, 0, 0),
                (14, 0, 0),
                (15, 0, 0),
                (30, 0, 0),
                (31, 0, 0),
                (40, 0, 0),
                (3, 2, 0),
                (3, 0, 1),
            ] {
                let fresh = CameraSample::new(&s, index);
                let i = index + other;
                let three: [f32; 3] = fresh.get_n(i, d, salt);
                let two: [f32; 2] = fresh.get_n(i, d, salt);
                for k in 0..3u32 {
                    assert_eq!(
                        three[k as usize],
                        s.get_salted(i, d + k, salt),
                        "index {i} dim {d}+{k} salt {salt}"
                    );
                }
                assert_eq!(two, [three[0], three[1]]);
            }
        }
    }

    #[test]
    fn sixteen_dimensions_at_once_are_the_crates_values() {
        // Every batch, seeds with high and low bits, indices over the whole first block: bit for bit sample_4d.
        for seed in [0u32, 1, 0xffff_ffff, 0x8000_0000, 12345, 0xdead_beef] {
            for index in (0..65536u32).step_by(97).chain([0, 1, 65535]) {
                for batch in 0..CACHED_BATCHES {
                    let got = sample_16d(index, batch, seed);
                    for set in 0..4 {
                        let want = sobol_burley::sample_4d(index, (4 * batch + set) as u32, seed);
                        assert_eq!(
                            &got[4 * set..4 * set + 4],
                            &want,
                            "seed {seed} index {index} batch {batch}"
                        );
                    }
                }
            }
        }
    }

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

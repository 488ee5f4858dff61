//! Splatting reconstruction ([`Reconstruction::Splat`](super::Reconstruction::Splat)): each camera sample lands
//! uniformly in its pixel and counts in every pixel whose filter reaches it, weighted by the filter; a pixel is the
//! weighted mean of the samples that reach it, Σ w f / Σ w.
//!
//! With the thesis' 3-pixel Gaussian (σ = ½, truncated at 1.5 px) a sample reaches the 3 × 3 pixels around its
//! own, so each pixel averages the samples of nine: at the same spp the frame is less noisy than with filter
//! importance sampling, where a pixel averages its own samples alone, and it converges to the same image.
//!
//! # Exact sums, so the image is the same for any tile split
//!
//! A pixel's value depends on its neighbours' samples, and a neighbour may be in another work tile or, under
//! `--tile I/N` and `--crop`, in another process. Each **source** pixel first sums its own samples' splats towards
//! each pixel it reaches ([`SourceSums`], f32, in sample order: a function of that pixel's sample stream alone).
//! Those sums are then added into their targets as **fixed-point integers** (value × 2⁶⁴ in an i128, [`fixed`]):
//! integer addition is associative, so a target's total is the same whatever order its sources arrive in — one
//! tile, two tiles, two processes. A region rendered alone also renders the **margin** pixels just outside it
//! (inside the frame) for their splats into it, so its pixels are bit for bit the full frame's.
//!
//! Inside a work tile the pixels whose sources all belong to the tile are finished at once ([`render_tile`]); the
//! rest, a ring of `reach` pixels along edges shared with other tiles, leave the tile as [`Edge`] sums and are
//! finished when the region is assembled ([`finish_edges`]).
//!
//! Fixed point: an f32 sum of at least 2⁻⁶⁴ · 2²⁴ ≈ 10⁻¹² is kept exactly, smaller ones lose their low bits (the
//! film's values are radiances and weights; 10⁻¹² of the pixel's scale is far below an f32 pixel's precision), and
//! a cell saturates past 2⁶³ ≈ 9 · 10¹⁸.

use super::film::{self, Accumulate, Layout, PixelSums, Tile, CHANNELS, QUANTITIES};
use super::integrator::PathSample;
use super::Region;
use crate::image::Image;

/// 2⁻⁶⁴: one unit of [`fixed`].
const UNIT: f64 = 1.0 / 18_446_744_073_709_551_616.0;

/// The splat's filter: the Gaussian that filter importance sampling draws from ([`super::filter::GaussianFilter`]):
/// σ = width / 6, truncated at the radius width / 2, separable in x and y.
#[derive(Debug, Clone, Copy)]
pub struct SplatFilter {
    radius: f32,
    /// 1 / (2σ²).
    falloff: f32,
    /// A sample reaches the pixels at offsets −reach ..= reach from its own, in x and in y.
    reach: u32,
}

impl SplatFilter {
    /// The filter of total `width` pixels (> 0).
    pub fn new(width: f32) -> SplatFilter {
        let radius = 0.5 * width;
        let sigma = width / 6.0;
        // A sample at u ∈ [0, 1) of its pixel reaches a pixel whose centre is nearer than the radius: the centre
        // of the pixel k away sits at k + ½, so |u − k − ½| < r needs |k| < r + ½ − u, at most ⌈r − ½⌉.
        let reach = (radius - 0.5).ceil().max(0.0) as u32;
        SplatFilter {
            radius,
            falloff: 1.0 / (2.0 * sigma * sigma),
            reach,
        }
    }

    /// How far, in pixels, a sample reaches from its own pixel.
    pub fn reach(&self) -> u32 {
        self.reach
    }

    /// Pixels per side of the square a sample reaches: 2 · reach + 1.
    fn side(&self) -> usize {
        2 * self.reach as usize + 1
    }

    /// The share of the variance of each pixel's sample mean that its splats put into the image, for a `size`
    /// frame ([`NoiseShares`]).
    ///
    /// Source pixel q's share is Σ_p c_pq over its targets p, with c_pq = E(w_pq²) / (Σ_q′ E(w_pq′))². Why: target
    /// p is Σ_q S_q^wf / Σ_q S_q^w, S_q the sums of source q's n_q samples each divided by n_q (the same for every
    /// q at a fixed spp). For independent samples uniform in their pixels, of variance σ_q², its variance is
    /// Σ_q E(w_pq²) σ_q² / n_q / (Σ_q E(w_pq))² to first order: each source's variance of the mean, σ_q² / n_q,
    /// reaches p with weight c_pq, and the image's mean variance is Σ_q (σ_q² / n_q) Σ_p c_pq / N where the
    /// pixels' brightness varies slowly. The filter is separable, so the share is a product of one per axis;
    /// inside the frame it is 0.32 for the 3-pixel Gaussian (tested against splatted noise), more within `reach`
    /// of the frame's edges, where targets have fewer sources.
    pub fn noise_shares(&self, size: [u32; 2]) -> NoiseShares {
        NoiseShares {
            x: self.axis_shares(size[0]),
            y: self.axis_shares(size[1]),
        }
    }

    /// [`SplatFilter::noise_shares`] along one axis of `len` pixels.
    fn axis_shares(&self, len: u32) -> Vec<f64> {
        let r = i64::from(self.reach);
        let len = i64::from(len);
        // E[g] and E[g²] over a sample uniform in a source pixel k = source − target pixels from the target, for
        // k in −r ..= r, by the midpoint rule on the filter's own f32 weights.
        const STEPS: usize = 1024;
        let mut moments = vec![(0.0f64, 0.0f64); self.side()];
        let mut w = vec![0.0f32; self.side()];
        for i in 0..STEPS {
            let u = (i as f32 + 0.5) / STEPS as f32;
            self.weights(u, &mut w);
            // w[j] is the weight towards the target at offset j − r from the source: k = r − j.
            for (j, &g) in w.iter().enumerate() {
                let m = &mut moments[self.side() - 1 - j];
                m.0 += f64::from(g) / STEPS as f64;
                m.1 += f64::from(g) * f64::from(g) / STEPS as f64;
            }
        }
        let moment = |k: i64| moments[(k + r) as usize];
        let inside = |v: i64| (0..len).contains(&v);
        // Σ_q′ E[g] for each target.
        let totals: Vec<f64> = (0..len)
            .map(|p| {
                (p - r..=p + r)
                    .filter(|&s| inside(s))
                    .map(|s| moment(s - p).0)
                    .sum()
            })
            .collect();
        (0..len)
            .map(|q| {
                (q - r..=q + r)
                    .filter(|&p| inside(p) && totals[p as usize] > 0.0)
                    .map(|p| moment(q - p).1 / (totals[p as usize] * totals[p as usize]))
                    .sum()
            })
            .collect()
    }

    /// The filter's weights along one axis for a sample at `u` in its pixel: `out[k]` is the weight of the pixel at
    /// offset k − reach.
    #[inline]
    fn weights(&self, u: f32, out: &mut [f32]) {
        for (k, w) in out.iter_mut().enumerate() {
            let d = u - (k as f32 - self.reach as f32 + 0.5);
            *w = if d.abs() < self.radius {
                (-d * d * self.falloff).exp()
            } else {
                0.0
            };
        }
    }
}

/// The share of each pixel's variance of the mean that reaches a splatted image ([`SplatFilter::noise_shares`]), per
/// column and per row of the frame.
#[derive(Debug, Clone)]
pub struct NoiseShares {
    x: Vec<f64>,
    y: Vec<f64>,
}

impl NoiseShares {
    /// Pixel (x, y)'s share.
    pub fn at(&self, x: u32, y: u32) -> f64 {
        self.x[x as usize] * self.y[y as usize]
    }
}

/// Which of the film's quantities ([`film::quantities`]) a frame splats: those its kept channels read (the peer
/// scene keeps the beauty alone: 4 of 30), then the weight. Measured on the peer scene at 96², 16 spp, one thread
/// (callgrind, whole process, 7.44 G instructions by filter importance sampling): splatting all 30 quantities took
/// 131 M instructions in the film, the beauty's 4 take 81 M (1.1 %), a third of it the filter's `exp`.
#[derive(Debug, Clone)]
pub struct Summed {
    quantities: Vec<usize>,
}

impl Summed {
    /// The quantities `layout`'s channels read.
    pub(super) fn new(layout: &Layout) -> Summed {
        Summed {
            quantities: film::quantities_read(layout),
        }
    }

    /// Every quantity (tests).
    #[cfg(test)]
    fn all() -> Summed {
        Summed {
            quantities: (0..QUANTITIES).collect(),
        }
    }

    /// Values per target: the quantities and the weight, last.
    pub fn width(&self) -> usize {
        self.quantities.len() + 1
    }
}

/// One source pixel's samples splatted towards each pixel they reach: `side`² targets of [`Summed::width`] values
/// each, in f32, summed in sample order. Kept and cleared per pixel, so a tile allocates it once.
pub struct SourceSums {
    filter: SplatFilter,
    summed: Summed,
    sums: Vec<f32>,
    wx: Vec<f32>,
    wy: Vec<f32>,
    values: Vec<f32>,
}

impl SourceSums {
    /// Empty sums for `filter`, of the quantities `summed`.
    pub fn new(filter: SplatFilter, summed: Summed) -> SourceSums {
        let side = filter.side();
        let width = summed.width();
        SourceSums {
            sums: vec![0.0; SourceSums::len(filter, &summed)],
            filter,
            summed,
            wx: vec![0.0; side],
            wy: vec![0.0; side],
            values: vec![0.0; width],
        }
    }

    /// How many values [`SourceSums::sums`] holds for `filter` and `summed`: side² targets × [`Summed::width`].
    pub fn len(filter: SplatFilter, summed: &Summed) -> usize {
        filter.side() * filter.side() * summed.width()
    }

    /// Forgets every sample.
    pub fn clear(&mut self) {
        self.sums.fill(0.0);
    }

    /// The sums towards every target, as [`SourceSums::load`] takes them back: a pixel's sums kept between
    /// adaptive sampling's rounds.
    pub fn sums(&self) -> &[f32] {
        &self.sums
    }

    /// Replaces the sums by `sums` (of [`SourceSums::len`] values, as [`SourceSums::sums`] gives them).
    pub fn load(&mut self, sums: &[f32]) {
        self.sums.copy_from_slice(sums);
    }

    /// The sums towards the pixel at offset (dx, dy) from the source, each in −reach ..= reach.
    fn target(&self, dx: i64, dy: i64) -> &[f32] {
        let r = i64::from(self.filter.reach);
        let k = ((dy + r) * self.filter.side() as i64 + dx + r) as usize;
        let width = self.summed.width();
        &self.sums[k * width..(k + 1) * width]
    }
}

impl Accumulate for SourceSums {
    fn add(&mut self, s: &PathSample) {
        if !film::is_finite(s) {
            film::count_dropped();
            return;
        }
        let q = film::quantities(s);
        for (v, &i) in self.values.iter_mut().zip(&self.summed.quantities) {
            *v = q[i];
        }
        *self.values.last_mut().expect("the weight") = 1.0;
        self.filter.weights(s.film[0], &mut self.wx);
        self.filter.weights(s.film[1], &mut self.wy);
        let (side, width) = (self.wx.len(), self.values.len());
        for (j, &wy) in self.wy.iter().enumerate() {
            for (i, &wx) in self.wx.iter().enumerate() {
                let w = wy * wx;
                if w == 0.0 {
                    continue;
                }
                let k = j * side + i;
                for (c, v) in self.sums[k * width..(k + 1) * width]
                    .iter_mut()
                    .zip(&self.values)
                {
                    *c += w * v;
                }
            }
        }
    }
}

/// `v` × 2⁶⁴ as an integer, exactly for |v| ≥ 2⁻⁴⁰, truncated toward zero below, saturated at ±2¹²⁷ (see the
/// [module docs](self)); 0 for zero, subnormals and NaN.
#[inline]
pub fn fixed(v: f32) -> i128 {
    let bits = v.to_bits();
    let exponent = ((bits >> 23) & 0xff) as i32;
    if exponent == 0 || v.is_nan() {
        return 0;
    }
    let mantissa = i128::from((bits & 0x7f_ffff) | 0x80_0000);
    // v = mantissa · 2^(exponent − 150), so v · 2⁶⁴ = mantissa · 2^(exponent − 86).
    let shift = exponent - 86;
    let magnitude = if shift > 103 {
        i128::MAX
    } else if shift >= 0 {
        mantissa << shift
    } else if shift > -24 {
        mantissa >> -shift
    } else {
        0
    };
    if bits >> 31 == 1 {
        -magnitude
    } else {
        magnitude
    }
}

/// A pixel of the region whose sources are not all in one tile: the fixed-point sums ([`fixed`]) one tile gave it.
pub struct Edge {
    x: u32,
    y: u32,
    sums: Box<[i128]>,
}

/// What a worker keeps from tile to tile: a tile's target sums (34² × 31 × 16 B = 573 KB with every AOV). Allocated
/// and freed per tile they cost page faults and TLB shootdowns: a 2048² frame of the default scene at 1 spp with
/// every AOV took 26.7 s against 18.7 s by filter importance sampling, `perf` putting 6 % of the time in the kernel
/// under the tile loop.
#[derive(Default)]
pub struct Scratch {
    cells: Vec<i128>,
}

/// A work tile's targets: the tile grown by the reach, clipped to the region (pixels outside it are not output),
/// each [`Summed::width`] fixed-point sums.
struct Grid<'s> {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    width: usize,
    cells: &'s mut [i128],
}

impl Grid<'_> {
    /// Target (x, y)'s sums.
    fn cell(&self, x: u32, y: u32) -> &[i128] {
        let k = ((y - self.y0) * (self.x1 - self.x0) + (x - self.x0)) as usize;
        &self.cells[k * self.width..(k + 1) * self.width]
    }

    /// Adds source pixel (`qx`, `qy`)'s splats, each times `scale`, to the targets inside the grid.
    fn add(&mut self, qx: u32, qy: u32, source: &SourceSums, scale: f32) {
        let r = i64::from(source.filter.reach);
        let width = self.width;
        for dy in -r..=r {
            let y = i64::from(qy) + dy;
            if y < i64::from(self.y0) || y >= i64::from(self.y1) {
                continue;
            }
            for dx in -r..=r {
                let x = i64::from(qx) + dx;
                if x < i64::from(self.x0) || x >= i64::from(self.x1) {
                    continue;
                }
                let from = source.target(dx, dy);
                if from[width - 1] == 0.0 {
                    continue;
                }
                let k =
                    ((y as u32 - self.y0) * (self.x1 - self.x0) + (x as u32 - self.x0)) as usize;
                for (c, &v) in self.cells[k * width..(k + 1) * width].iter_mut().zip(from) {
                    if v != 0.0 {
                        *c = c.saturating_add(fixed(v * scale));
                    }
                }
            }
        }
    }
}

/// The pixel a target's sums (of the quantities `summed`) make: all of [`CHANNELS`] written from samples
/// ([`film::from_samples`]; those of quantities not summed are 0), the weighted mean Σ w f / Σ w.
fn finish(cell: &[i128], summed: &Summed) -> [f32; CHANNELS.len()] {
    let mut q = [0.0; QUANTITIES];
    for (&v, &i) in cell.iter().zip(&summed.quantities) {
        q[i] = (v as f64 * UNIT) as f32;
    }
    let weight = cell[summed.width() - 1] as f64 * UNIT;
    let mut pixel = [0.0; CHANNELS.len()];
    let k = if weight > 0.0 {
        (1.0 / weight) as f32
    } else {
        0.0
    };
    PixelSums::from_quantities(&q).write_scaled(k, &mut pixel);
    pixel
}

/// Where a coordinate's source pixel is rendered: the nearest coordinate of the region (a margin pixel belongs to
/// the tile at the region's edge next to it).
fn home(v: i64, lo: u32, hi: u32) -> i64 {
    v.clamp(i64::from(lo), i64::from(hi) - 1)
}

/// The source pixels work tile `tile` of `region` (in a `size` frame) renders for a filter of reach `reach`, row by
/// row: its own pixels and the margin pixels outside the region whose nearest region pixel is in the tile (their
/// splats reach into the region), clipped to the frame.
pub(super) fn sources(
    tile: &Tile,
    region: Region,
    size: [u32; 2],
    reach: u32,
) -> impl Iterator<Item = (u32, u32)> {
    let r = i64::from(reach);
    let (tx0, ty0, tx1, ty1) = (tile.x0, tile.y0, tile.x1, tile.y1);
    let owns = move |x: i64, y: i64| {
        let (hx, hy) = (home(x, region.x0, region.x1), home(y, region.y0, region.y1));
        (i64::from(tx0)..i64::from(tx1)).contains(&hx)
            && (i64::from(ty0)..i64::from(ty1)).contains(&hy)
    };
    let sy0 = (i64::from(ty0) - r).max(0);
    let sy1 = (i64::from(ty1) + r).min(i64::from(size[1]));
    let sx0 = (i64::from(tx0) - r).max(0);
    let sx1 = (i64::from(tx1) + r).min(i64::from(size[0]));
    (sy0..sy1)
        .flat_map(move |qy| (sx0..sx1).map(move |qx| (qx, qy)))
        // A pixel of the region is its own home: the tile owns its own pixels and its margin.
        .filter(move |&(qx, qy)| owns(qx, qy))
        .map(|(qx, qy)| (qx as u32, qy as u32))
}

/// The region pixel a source pixel's samples are counted with: itself inside the region, the nearest region pixel
/// for a margin pixel.
pub(super) fn home_of(x: u32, y: u32, region: Region) -> (u32, u32) {
    (
        home(i64::from(x), region.x0, region.x1) as u32,
        home(i64::from(y), region.y0, region.y1) as u32,
    )
}

/// A work tile's targets being summed: its [`Grid`] in a worker's [`Scratch`], with what finishing them needs.
pub(super) struct TileSplats<'s> {
    grid: Grid<'s>,
    region: Region,
    size: [u32; 2],
    reach: u32,
}

impl<'s> TileSplats<'s> {
    /// No splats yet for work tile `tile` of `region` in a `size` frame: its targets are the tile grown by the
    /// filter's reach, clipped to the region.
    pub(super) fn new(
        scratch: &'s mut Scratch,
        tile: &Tile,
        region: Region,
        size: [u32; 2],
        filter: SplatFilter,
        summed: &Summed,
    ) -> TileSplats<'s> {
        let r = i64::from(filter.reach);
        let grown = |lo: u32, hi: u32, region_lo: u32, region_hi: u32| {
            (
                (i64::from(lo) - r).max(i64::from(region_lo)) as u32,
                (i64::from(hi) + r).min(i64::from(region_hi)) as u32,
            )
        };
        let (x0, x1) = grown(tile.x0, tile.x1, region.x0, region.x1);
        let (y0, y1) = grown(tile.y0, tile.y1, region.y0, region.y1);
        let width = summed.width();
        let cells = ((x1 - x0) * (y1 - y0)) as usize * width;
        scratch.cells.clear();
        scratch.cells.resize(cells, 0);
        TileSplats {
            grid: Grid {
                x0,
                y0,
                x1,
                y1,
                width,
                cells: &mut scratch.cells,
            },
            region,
            size,
            reach: filter.reach,
        }
    }

    /// Adds source pixel (`qx`, `qy`)'s splats, each sum times `scale` (1 where every source took the same count;
    /// 1/n under adaptive sampling, so that each source counts as the mean of its own n samples).
    pub(super) fn add(&mut self, qx: u32, qy: u32, source: &SourceSums, scale: f32) {
        self.grid.add(qx, qy, source, scale);
    }

    /// Finishes the tile: its own pixels get their count (`taken`, row-major over the tile) and centre channels
    /// from `own`, the pixels whose sources all belong to the tile their splatted channels. Returns the sums of the
    /// others, to be finished with the neighbouring tiles' ([`finish_edges`]).
    pub(super) fn finish(
        self,
        tile: &mut Tile,
        summed: &Summed,
        taken: &[u32],
        mut own: impl FnMut(u32, u32, u32, &mut [f32]),
    ) -> Vec<Edge> {
        let TileSplats {
            grid,
            region,
            size,
            reach,
        } = self;
        let r = i64::from(reach);
        let width = grid.width;
        // A target is finished when every frame pixel within reach is rendered by this tile.
        let (tx0, ty0, tx1, ty1) = (tile.x0, tile.y0, tile.x1, tile.y1);
        let finished = |x: u32, y: u32| {
            let axis = |v: u32, frame: u32, lo: u32, hi: u32, tile_lo: u32, tile_hi: u32| {
                let first = home((i64::from(v) - r).max(0), lo, hi);
                let last = home((i64::from(v) + r).min(i64::from(frame) - 1), lo, hi);
                first >= i64::from(tile_lo) && last < i64::from(tile_hi)
            };
            axis(x, size[0], region.x0, region.x1, tx0, tx1)
                && axis(y, size[1], region.y0, region.y1, ty0, ty1)
        };
        let mut edges = Vec::new();
        for y in grid.y0..grid.y1 {
            for x in grid.x0..grid.x1 {
                let cell = grid.cell(x, y);
                let done = finished(x, y);
                if (tx0..tx1).contains(&x) && (ty0..ty1).contains(&y) {
                    let n = taken[((y - ty0) * (tx1 - tx0) + (x - tx0)) as usize];
                    let done = done.then(|| finish(cell, summed));
                    tile.set_pixel(x, y, |pixel| {
                        if let Some(done) = &done {
                            pixel.copy_from_slice(done);
                        }
                        own(x, y, n, pixel);
                    });
                }
                if !done && cell[width - 1] != 0 {
                    edges.push(Edge {
                        x,
                        y,
                        sums: cell.into(),
                    });
                }
            }
        }
        edges
    }
}

/// Renders work tile `tile` of `region` in a `size` frame by splatting: every source pixel of the tile
/// ([`sources`]) takes its samples through `take` (returning how many), its own pixels get their count and centre
/// channels from `own`, and the pixels whose sources all belong to the tile are finished. Returns the sums of the
/// others, to be finished with the neighbouring tiles' ([`finish_edges`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn render_tile(
    scratch: &mut Scratch,
    tile: &mut Tile,
    region: Region,
    size: [u32; 2],
    filter: SplatFilter,
    summed: &Summed,
    mut take: impl FnMut(u32, u32, &mut SourceSums) -> u32,
    own: impl FnMut(u32, u32, u32, &mut [f32]),
) -> Vec<Edge> {
    let mut splats = TileSplats::new(scratch, tile, region, size, filter, summed);
    let mut source = SourceSums::new(filter, summed.clone());
    let mut taken = vec![0u32; ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize];
    for (qx, qy) in sources(tile, region, size, filter.reach) {
        source.clear();
        let n = take(qx, qy, &mut source);
        if (tile.x0..tile.x1).contains(&qx) && (tile.y0..tile.y1).contains(&qy) {
            taken[((qy - tile.y0) * (tile.x1 - tile.x0) + (qx - tile.x0)) as usize] = n;
        }
        splats.add(qx, qy, &source, 1.0);
    }
    splats.finish(tile, summed, &taken, own)
}

/// Finishes the pixels of `image` (the assembled `region`, channels of `layout`) whose sources span tiles: each
/// one's sums from every tile that gave it some, added exactly, written into its sample channels. Pixels outside
/// `rendered` (tiles a cancel left out) stay as they are.
pub(super) fn finish_edges(
    image: &mut Image,
    region: Region,
    layout: &Layout,
    summed: &Summed,
    edges: impl IntoIterator<Item = Edge>,
    rendered: &[Region],
) {
    let mut totals: std::collections::HashMap<(u32, u32), Box<[i128]>> = Default::default();
    for e in edges {
        match totals.entry((e.x, e.y)) {
            std::collections::hash_map::Entry::Occupied(mut o) => {
                for (t, v) in o.get_mut().iter_mut().zip(e.sums.iter()) {
                    *t = t.saturating_add(*v);
                }
            }
            std::collections::hash_map::Entry::Vacant(v) => {
                v.insert(e.sums);
            }
        }
    }
    for ((x, y), cell) in totals {
        let inside = |t: &Region| (t.x0..t.x1).contains(&x) && (t.y0..t.y1).contains(&y);
        if !rendered.iter().any(inside) {
            continue;
        }
        let pixel = finish(&cell, summed);
        film::write_from_samples(image, x - region.x0, y - region.y0, &pixel, layout);
    }
}

#[cfg(test)]
mod tests;

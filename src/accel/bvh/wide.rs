//! The traversal structure of the pure-Rust backend: the binary SAH tree of [`Bvh`] collapsed into 4-wide nodes,
//! whose lanes hold axis-aligned boxes or, near the leaves, oriented boxes. Both kinds are tested four at a time
//! over structure-of-arrays lanes (glam's `Vec4`: SSE instructions from safe code, no intrinsics).
//!
//! - **4-wide nodes** (Wald, Benthin & Boulos 2008, "Getting rid of packets"; Dammertz et al. 2008, "Shallow
//!   bounding volume hierarchies"; Embree's BVH4): each binary inner node is replaced by up to four descendants,
//!   the cover of least surface-area cost ([`collapse`]), so a ray loads one node and tests four boxes where the
//!   binary tree loaded two nodes per level. 8-wide nodes (AVX lanes) cost
//!   more instructions (bench trace ray loops, furball 96x96: round 2.94 G against 2.78 G, flat 1.45 G against
//!   1.29 G) for no wall-clock gain that one run separates from noise, so the nodes are 4-wide.
//! - **Oriented nodes** (Woop et al. 2014, "Exploiting local orientation similarity for efficient ray traversal
//!   of hair and fur", the idea behind Embree's hair BVH): hair is thin, long and diagonal, so an axis-aligned box
//!   around a few segments of a strand is mostly empty space. For each child of at most [`OBB_MAX`] segments the
//!   collapse also bounds the segments' quarter spans in a frame whose third axis is their mean chord direction
//!   ([`Obb`]); a node whose children's oriented boxes have at most [`OBB_AREA`] of the aligned boxes' surface
//!   area stores them ([`Obbs4`]: per lane the affine map onto the cube [0, 1]³, a child for which the aligned
//!   box is smaller keeping it in the identity frame), and the walk transforms the ray into each lane's frame.
//!   Our trees are still built by the aligned SAH (Woop et al. also split in the oriented frame: not done), so
//!   oriented nodes appear only where the aligned tree already groups a strand's neighbouring segments: 97 800 of
//!   the fur ball's 118 443 nodes with four segments per leaf. With one segment per leaf
//!   ([`super::BuildOptions::default`]) the oriented lanes bound each segment on its own, so the leaves need no
//!   per-segment span capsules (112 bytes per segment): 193 bytes per segment against 229 with capsules (Embree:
//!   143; 138 with four segments per leaf), and 2.5× fewer last-level cache misses in the ray loops.
//! - **Oriented lanes as affine maps onto the unit cube** ([`Obbs4`], the form of Embree's oriented nodes), 240
//!   bytes per node (224 with the children packed, [`Links`]). Quantised lanes (the encoding of Embree's `CurveNi` leaves, after Ylitie, Karras & Laine 2017:
//!   16-bit frames and bounds relative to the node's box, 172 bytes per node) save cache misses (estimated cycles
//!   1.083 G against 1.096 G for orthonormal `f32` frames with lower and upper bounds) but cost ~110 instructions
//!   per node test, a third of the camera rays' walk (perf). The unit-cube map needs no bounds and no widening:
//!   camera rays' `intersect` takes 118.8 M instructions against the quantised lanes' 126.0 M (callgrind,
//!   `bench trace scenes/furball.toml --curves flat --threads 1 --repetitions 1 --res 96x96 --backend bvh`), and
//!   `bench trace scenes/furball.toml --curves flat --threads 1 --repetitions 3`, BVH ÷ Embree, two interleaved
//!   runs each, quantised against unit-cube: camera 2.06 / 2.06 against 1.94 / 1.89, secondary 1.78 / 1.81 against
//!   1.68 / 1.68, exact shadows 1.82 / 1.81 against 1.66 / 1.69, stochastic 1.73 / 1.74 against 1.66 / 1.67; memory
//!   193 bytes per segment against the quantised lanes' 162.5 (Embree 143). Huge pages for the node and leaf arrays
//!   (`madvise(MADV_HUGEPAGE)`, as Embree does: it holds 51 MB of its tree on 2 MiB pages here) make secondary and
//!   shadow rays 0–6 % faster and camera rays no faster, but the build 2.3× Embree's instead of 1.85× (the
//!   huge-page faults themselves, also when advised before the first write), so the arrays use ordinary pages.
//! - **Leaves** hold each segment's control points, ids and opacity in one 76-byte entry ([`Primitive`]), so a
//!   curve test reads one place, as Embree's curve leaves also store their control points.
//!
//! Measured (callgrind, inside the benchmark's ray loops, `bench trace scenes/furball.toml --threads 1
//! --repetitions 1 --res 96x96 --backend bvh`, same rays and figures): a binary tree takes 8.74 G instructions
//! (round) / 2.98 G (flat), 4-wide nodes with span-box leaves 5.30 G / 1.94 G (flat 1.82 G with an `ArrayVec`
//! stack), span capsules in the leaves 2.90 G / 1.41 G. In estimated cycles (cache simulation: instructions + 10
//! per L1 miss + 200 per last-level miss; Embree on the same rays: round 1.41 G, flat 0.71 G): capsule leaves
//! 3.27 G / 1.80 G, oriented nodes 3.12 G / 1.66 G, oriented nodes without capsules 3.08 G / 1.60 G, and one
//! segment per leaf (the layout here) 2.74 G / 1.35 G. Perf shows the walk waiting on the first load of a node
//! and of a leaf entry: memory more than arithmetic bounds it.
//! - **Prefetch**: perf puts over half of the walk's samples on the first load of a node or a leaf
//!   entry, so every child a node's test hits has its cache lines requested at once ([`crate::sys::prefetch`]):
//!   the nearest is entered next, the others are in cache by the time they are popped. `bench trace
//!   scenes/furball.toml --threads 1,2 --repetitions 3`, BVH ÷ Embree at 1 / 2 threads, without → with prefetch: flat
//!   camera 2.17 / 2.11 → 2.04 / 2.03, secondary 2.34 / 2.08 → 2.05 / 1.92, exact shadow 2.50 / 2.22 → 2.09 /
//!   2.03, stochastic 2.00 / 1.86 → 1.86 / 1.72; round secondary 1.62 / 1.40 → 1.40 / 1.18, exact 1.41 / 1.35 →
//!   1.30 / 1.23. Aligning nodes to 64 bytes on top (173.5 instead of 162.5 bytes per segment) buys nothing.
//! - **Slab test**: min/max of the two slab distances per axis (no branch on the direction's sign), far distances
//!   scaled by Ize 2013's 1 + 2γ₃ as in [`super::Aabb::entry`]. Direction components too small to invert are
//!   replaced by ±2⁻⁶⁴ (Embree's `rcp_safe` idea), so no 0 · ∞ = NaN can reach the comparisons: the inverse stays
//!   finite and a box is entered exactly when the binary tree's robust test enters it, up to boxes within 2⁻⁶⁴ · d
//!   of the origin's plane.

use arrayvec::ArrayVec;

use glam::{Vec3, Vec4};

#[cfg(test)]
use super::build::for_each_span_points;
use super::build::polygon;
use super::{BuildOptions, Bvh, Control, FAR_SCALE};
use crate::hair::Strands;
use crate::ray::Ray;

#[cfg(test)]
mod checks;
mod collapse;

/// Traversal stack entries: a 4-wide node pushes at most three children (always three, the extra ones cut off at
/// once), and the tree is at most as deep as the binary one ([`super::STACK_SIZE`] levels).
const WIDE_STACK: usize = 3 * super::STACK_SIZE + 3;

/// Per 4-bit lane mask, all ones in the lanes it leaves out: a missed child's sort key becomes `u32::MAX` with one
/// OR (no per-lane select), after every hit child's.
const MISSED_LANES: [[u32; 4]; 16] = {
    let mut table = [[0u32; 4]; 16];
    let mut mask = 0;
    while mask < 16 {
        let mut lane = 0;
        while lane < 4 {
            if mask & (1 << lane) == 0 {
                table[mask][lane] = u32::MAX;
            }
            lane += 1;
        }
        mask += 1;
    }
    table
};

/// Leaves an order-free walk ([`WideBvh::for_each`]) keeps waiting while their prefetched entries load.
const DEFERRED: usize = 4;

/// Smallest direction component magnitude inverted as it is (see the module docs).
const MIN_DIRECTION: f32 = 5.421_011e-20; // 2⁻⁶⁴

/// 1 / [`MIN_DIRECTION`], the largest inverse direction component.
const MAX_INVERSE: f32 = 1.844_674_4e19; // 2⁶⁴

/// Four boxes as structure of arrays, one SSE register per axis and side: `lo[axis]`, `hi[axis]` (lane = box).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Boxes4 {
    lo: [Vec4; 3],
    hi: [Vec4; 3],
}

impl Boxes4 {
    /// No box (every lane invalid: lanes are masked by the caller).
    const EMPTY: Boxes4 = Boxes4 {
        lo: [Vec4::INFINITY; 3],
        hi: [Vec4::NEG_INFINITY; 3],
    };

    fn set(&mut self, lane: usize, lo: Vec3, hi: Vec3) {
        for axis in 0..3 {
            self.lo[axis][lane] = lo[axis];
            self.hi[axis][lane] = hi[axis];
        }
    }

    /// Entry distances of the four boxes and the bit mask of the lanes the ray crosses within `[tnear, tfar]`.
    #[inline(always)]
    fn test(&self, r: &WideRay) -> (Vec4, u32) {
        let mut tmin = Vec4::splat(r.tnear);
        let mut far = Vec4::INFINITY;
        for axis in 0..3 {
            let t0 = (self.lo[axis] - r.origin[axis]) * r.inv_dir[axis];
            let t1 = (self.hi[axis] - r.origin[axis]) * r.inv_dir[axis];
            tmin = tmin.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        // Ize's factor once on the nearest far slab: rounding is monotone, so s · min(a, b) = min(s · a, s · b)
        // exactly, the same mask as scaling each axis.
        let tmax = Vec4::splat(r.tfar).min(far * FAR_SCALE);
        (tmin, tmin.cmple(tmax).bitmask())
    }
}

/// Four oriented boxes as Embree's oriented BVH nodes store them (Woop et al. 2014): per lane the affine map of
/// world space onto the unit cube [0, 1]³ of the lane's box, row i being the box's axis i divided by its extent
/// along it. A ray's slab distances are then −o/d and (1 − o)/d for the ray's origin o and direction d in each
/// lane's map: no bounds to load. An axis-aligned child is the map of its box, so any child can sit in an
/// oriented node's lane. Rounding: the map is rounded to `f32`, which moves a box's faces by a few ulps of its
/// centre's coordinates, and the ray's origin is mapped with a relative error of a few ulps of its distance
/// from the box: both are far below the 10⁻⁵ of the coordinates' scale every box is padded by ([`Obb::around`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obbs4 {
    /// `m[i][j]`: component j of each lane's row i.
    m: [[Vec4; 3]; 3],
    /// Each lane's translation along row i.
    t: [Vec4; 3],
}

impl Obbs4 {
    /// The lanes of up to four oriented boxes (a lane without a box maps everything outside the cube: the caller
    /// masks it anyway).
    fn new(lanes: &[Obb]) -> Obbs4 {
        let mut q = Obbs4 {
            m: [[Vec4::ZERO; 3]; 3],
            t: [Vec4::splat(2.0); 3],
        };
        for (lane, o) in lanes.iter().enumerate() {
            let centre = o.centre.as_dvec3();
            for i in 0..3 {
                // x ↦ (axisᵢ · (x − centre) + halfᵢ) / (2 halfᵢ), in f64 and rounded once.
                let scale = 0.5 / f64::from(o.half[i]);
                let row = o.axes[i].as_dvec3() * scale;
                for j in 0..3 {
                    q.m[i][j][lane] = row[j] as f32;
                }
                q.t[i][lane] = (0.5 - row.dot(centre)) as f32;
            }
        }
        q
    }

    /// Entry distances and the mask of lanes crossed within `[tnear, tfar]` (as [`Boxes4::test`]).
    #[inline(always)]
    fn test(&self, r: &WideRay) -> (Vec4, u32) {
        let mut tmin = Vec4::splat(r.tnear);
        let mut far = Vec4::INFINITY;
        for i in 0..3 {
            let m = &self.m[i];
            let o = m[0].mul_add(
                r.origin[0],
                m[1].mul_add(r.origin[1], m[2].mul_add(r.origin[2], self.t[i])),
            );
            let d = m[0].mul_add(r.dir[0], m[1].mul_add(r.dir[1], m[2] * r.dir[2]));
            // 1 / d with |1 / d| at most 2⁶⁴ (see the module docs); ±0 gives ±2⁶⁴.
            let inv = (Vec4::ONE / d).clamp(Vec4::splat(-MAX_INVERSE), Vec4::splat(MAX_INVERSE));
            // The slab [0, 1]: −o / d and (1 − o) / d.
            let a = o * inv;
            let (t0, t1) = (-a, inv - a);
            tmin = tmin.max(t0.min(t1));
            far = far.min(t0.max(t1));
        }
        let tmax = Vec4::splat(r.tfar).min(far * FAR_SCALE);
        (tmin, tmin.cmple(tmax).bitmask())
    }

    /// Lane `lane`'s row i and translation (tests).
    #[cfg(test)]
    fn row(&self, lane: usize, i: usize) -> (Vec3, f32) {
        let m = &self.m[i];
        (
            Vec3::new(m[0][lane], m[1][lane], m[2][lane]),
            self.t[i][lane],
        )
    }
}

/// One oriented box: centre, orthonormal axes and half-extents along them.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Obb {
    centre: Vec3,
    axes: [Vec3; 3],
    half: Vec3,
}

impl Obb {
    /// The eight corners, world space, in `f64` (no rounding worth the name).
    #[cfg(test)]
    fn corners(&self) -> [glam::DVec3; 8] {
        let half = self.half.as_dvec3();
        std::array::from_fn(|k| {
            let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
            self.centre.as_dvec3()
                + self.axes[0].as_dvec3() * (sign(1) * half.x)
                + self.axes[1].as_dvec3() * (sign(2) * half.y)
                + self.axes[2].as_dvec3() * (sign(4) * half.z)
        })
    }

    fn area(&self) -> f32 {
        let h = self.half;
        8.0 * (h.x * h.y + h.y * h.z + h.z * h.x)
    }

    /// The box in frame `axes` around the spans of `segments`, padded for rounding.
    fn around(strands: &Strands, segments: impl Iterator<Item = u32>, axes: [Vec3; 3]) -> Obb {
        let mut lo = Vec3::INFINITY;
        let mut hi = Vec3::NEG_INFINITY;
        let mut scale = 0.0f32;
        for segment in segments {
            // The quarter spans' points: the seven of the refined polygon.
            for q in polygon(strands, segment) {
                let x = q.truncate();
                let p = Vec3::new(axes[0].dot(x), axes[1].dot(x), axes[2].dot(x));
                let r = q.w.abs();
                lo = lo.min(p - r);
                hi = hi.max(p + r);
                scale = scale.max(x.abs().max_element() + r);
            }
        }
        let mid = 0.5 * (lo + hi);
        let pad = 1e-5 * scale + f32::MIN_POSITIVE;
        Obb {
            centre: axes[0] * mid.x + axes[1] * mid.y + axes[2] * mid.z,
            axes,
            half: (0.5 * (hi - lo)).max(Vec3::ZERO) + Vec3::splat(pad),
        }
    }

    /// The box oriented along the segments' mean chord direction (Woop et al. 2014), or `None` without one.
    fn oriented(strands: &Strands, segments: impl Iterator<Item = u32> + Clone) -> Option<Obb> {
        let mut axis = Vec3::ZERO;
        for segment in segments.clone() {
            let first = strands.segment_first[segment as usize] as usize;
            let a = Vec3::from_slice(&strands.control_points[first][..3]);
            let b = Vec3::from_slice(&strands.control_points[first + 3][..3]);
            let chord = (b - a).normalize_or_zero();
            axis += if chord.dot(axis) < 0.0 { -chord } else { chord };
        }
        let axis = axis.try_normalize()?;
        let (x, y) = axis.any_orthonormal_pair();
        let obb = Obb::around(strands, segments, [x, y, axis]);
        obb.half.is_finite().then_some(obb)
    }
}

/// A ray prepared for [`Boxes4::test`] and [`Obbs4::test`]: every component splatted across four lanes.
#[derive(Debug, Clone, Copy)]
struct WideRay {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
    inv_dir: [Vec4; 3],
    tnear: f32,
    tfar: f32,
}

impl WideRay {
    fn new(ray: &Ray) -> Self {
        let safe = |d: f32| {
            if d.abs() < MIN_DIRECTION {
                MIN_DIRECTION.copysign(d)
            } else {
                d
            }
        };
        let splat = |v: [f32; 3]| v.map(Vec4::splat);
        WideRay {
            origin: splat(ray.origin.to_array()),
            dir: splat(ray.dir.to_array()),
            inv_dir: splat(ray.dir.to_array().map(|d| 1.0 / safe(d))),
            tnear: ray.tnear,
            tfar: ray.tfar,
        }
    }
}

/// [`Child::count`] of an oriented inner node: a count byte no leaf has ([`super::BuildOptions::max_leaf`] ≤ 254),
/// so that a node's packed children ([`Links`]) widen to a [`Child`] with no select.
const ORIENTED: u32 = 255;

/// Largest subtree (segments) given an oriented box: it bounds the build's extra work. On the fur ball 64 and
/// 8 192 give the same tree (larger subtrees of the aligned SAH tree mix directions, so their oriented boxes never
/// win), and 64 builds it in 0.57 s instead of 0.92 s (round, 2 threads).
const OBB_MAX: u32 = 64;

/// An oriented node replaces an aligned one when its children's oriented boxes have at most this fraction of the
/// aligned boxes' surface area (an oriented lane costs about twice an aligned one). Measured (estimated cycles as
/// in the module docs, one segment per leaf): 0.8 against 1.0, flat 1.35 G against 1.40 G, round 2.74 G against
/// 2.78 G.
const OBB_AREA: f32 = 0.8;

/// A child reference: an inner node's index, or a leaf's first entry and entry count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Child {
    /// Inner: node index. Leaf: index of its first entry in [`WideBvh::primitives`].
    index: u32,
    /// Leaf: number of entries (1–254). Aligned inner node: 0. Oriented inner node: [`ORIENTED`].
    count: u32,
}

impl Child {
    /// The child with an inner node's index moved by `aligned` or `oriented` (by its kind); a leaf as it is.
    fn shifted(self, aligned: u32, oriented: u32) -> Child {
        let shift = match self.count {
            0 => aligned,
            ORIENTED => oriented,
            _ => 0,
        };
        Child {
            index: self.index + shift,
            ..self
        }
    }
}

/// A 4-wide node: the boxes of up to four children ([`Boxes4`] or [`Obbs4`]) and the children they lead to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideNode<B> {
    boxes: B,
    links: Links,
}

/// A node's four children in 21 bytes, where four [`Child`]ren and a lane mask take 36: an aligned node is then 128
/// bytes and an oriented one 224 (144 and 240 with the boxes' 16-byte alignment). A child's count is a byte: 0 for
/// an aligned node, [`ORIENTED`] for an oriented one, a leaf's entry count otherwise (at most 254), so that a lane
/// widens to a [`Child`] by two loads. Measured (`bench trace scenes/furball.toml --threads 1 --repetitions 3`, two
/// interleaved runs each, BVH ÷ Embree time per ray, unpacked → packed with the kind in a lane bit): 170.3 → 164.0
/// bytes per segment, the times within the runs' spread; but callgrind (ray loops, `--res 96x96 --threads 1
/// --backend bvh`) counted 6.4 % (round) and 9.9 % (flat) more instructions with the kind in a bit, which this
/// encoding removes (numbers in the commit).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Links {
    /// Per lane: an inner node's index, or a leaf's first entry.
    index: [u32; 4],
    /// Per lane: the child's [`Child::count`] as a byte.
    count: [u8; 4],
    /// Bits 0–3: the lanes that hold a child.
    lanes: u8,
}

impl Links {
    /// The links to `children` (lanes without one: none).
    fn new(children: &[Child]) -> Links {
        let mut links = Links {
            index: [0; 4],
            count: [0; 4],
            lanes: 0,
        };
        for (lane, c) in children.iter().enumerate() {
            links.index[lane] = c.index;
            links.lanes |= 1 << lane;
            links.count[lane] =
                u8::try_from(c.count).expect("a leaf holds at most 254 entries (max_leaf)");
        }
        links
    }

    /// The children, inner nodes' indices moved by `aligned` or `oriented` (by kind), leaves as they are.
    fn shifted(mut self, aligned: u32, oriented: u32) -> Links {
        for lane in 0..4 {
            if self.lanes & (1 << lane) != 0 {
                self.index[lane] = self.child(lane).shifted(aligned, oriented).index;
            }
        }
        self
    }

    /// The four children (lanes without one included: see [`Links::valid`]).
    #[cfg(test)]
    fn children(&self) -> [Child; 4] {
        std::array::from_fn(|lane| self.child(lane))
    }

    /// Bit mask of the lanes that hold a child.
    #[inline(always)]
    fn valid(&self) -> u32 {
        u32::from(self.lanes)
    }

    /// The child in `lane`.
    #[inline(always)]
    fn child(&self, lane: usize) -> Child {
        Child {
            index: self.index[lane],
            count: u32::from(self.count[lane]),
        }
    }
}

/// A leaf entry: everything a ray–curve test and the shadow bookkeeping need, in one place, so that a leaf is
/// read sequentially instead of through four index arrays (segment → first control point → points, segment →
/// strand → opacity), as Embree's curve leaves also store their control points.
///
/// 76 bytes, not padded to 80 for 16-byte alignment (the control points are read with unaligned loads either way).
/// Measured (`bench trace scenes/furball.toml --threads 1 --repetitions 3`, two interleaved runs each, BVH ÷
/// Embree time per ray, 80 → 76 bytes): 164.0 → 160.0 bytes per segment; round camera 1.80 / 2.05 → 1.90 / 1.87,
/// secondary 1.21 / 1.08 → 1.21 / 1.23, exact shadows 1.08 / 1.05 → 1.14 / 1.08, stochastic 1.18 / 1.10 → 1.08 /
/// 1.11; flat 2.01 / 1.90 → 1.87 / 1.90, 1.64 / 1.74 → 1.85 / 1.75, 1.41 / 1.55 → 1.50 / 1.61, 1.72 / 1.71 → 1.72 /
/// 1.62: within the runs' spread. Callgrind with cache simulation (ray loops of `bench trace scenes/furball.toml
/// --threads 1 --repetitions 1 --res 96x96 --backend bvh --curves flat`, estimated cycles = instructions + 10 per
/// L1 miss + 200 per last-level miss): 978.7 M with 80-byte leaves and unpacked nodes, 994.8 M with 76-byte leaves
/// and the packed nodes of [`Links`] (+1.6 %), for 6 % fewer bytes per segment.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Primitive {
    /// The segment's control points (x, y, z, radius).
    pub control_points: [[f32; 4]; 4],
    /// The segment id.
    pub segment: u32,
    /// The strand it belongs to.
    pub strand: u32,
    /// The strand's opacity.
    pub opacity: f32,
}

/// The 4-wide tree with aligned and oriented nodes (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct WideBvh {
    nodes: Vec<WideNode<Boxes4>>,
    oriented: Vec<WideNode<Obbs4>>,
    /// The leaf entries, leaf by leaf.
    primitives: Vec<Primitive>,
    /// The root (a node or a leaf) and its box in lane 0, or nothing (no segments).
    root: Option<(Child, Boxes4)>,
}

impl WideBvh {
    /// The wide tree over the segments of `strands`, built with `options` without ever holding the binary tree
    /// of the whole model ([`collapse::build`]).
    ///
    /// # Panics
    /// If `options` are out of range (see [`Bvh::build`]).
    pub fn build(strands: &Strands, options: BuildOptions) -> WideBvh {
        collapse::build(strands, options)
    }

    /// Collapses `bvh` (built over `strands`) into 4-wide nodes, oriented where that is tighter, and stores each
    /// leaf entry's curve: the tree [`WideBvh::build`] makes, up to the nodes where its chunks meet the top levels.
    pub fn new(bvh: &Bvh, strands: &Strands) -> WideBvh {
        collapse::from_binary(bvh, strands)
    }

    /// The tree of collapsed `nodes` under `root` (and its box), with a leaf entry per segment id of `order`.
    fn assemble(
        nodes: collapse::Nodes,
        root: Option<(Child, super::Aabb)>,
        order: &[u32],
        strands: &Strands,
    ) -> WideBvh {
        use rayon::prelude::*;
        let primitives = order
            .par_iter()
            .map(|&segment| {
                let first = strands.segment_first[segment as usize] as usize;
                let strand = strands.segment_strand[segment as usize];
                Primitive {
                    control_points: std::array::from_fn(|i| strands.control_points[first + i]),
                    segment,
                    strand,
                    opacity: strands.opacity[strand as usize],
                }
            })
            .collect();
        WideBvh {
            nodes: nodes.aligned,
            oriented: nodes.oriented,
            primitives,
            root: root.map(|(child, b)| {
                let mut root_box = Boxes4::EMPTY;
                root_box.set(0, b.lo, b.hi);
                (child, root_box)
            }),
        }
    }

    /// Memory of nodes and leaf entries, bytes.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.oriented.as_slice())
            + std::mem::size_of_val(self.primitives.as_slice())
    }

    /// The leaf entries, leaf by leaf.
    pub fn primitives(&self) -> &[Primitive] {
        &self.primitives
    }

    /// The closest primitive along `ray`: [`Bvh::closest`]'s contract, the callback given the leaf entry.
    pub fn closest<F: FnMut(&Primitive, f32) -> Option<f32>>(
        &self,
        ray: &Ray,
        mut hit: F,
    ) -> Option<f32> {
        let mut r = WideRay::new(ray);
        let mut found = None;
        self.walk::<false, _>(&mut r, |primitive, r| {
            if let Some(t) = hit(primitive, r.tfar) {
                debug_assert!(t >= r.tnear && t <= r.tfar, "hit t = {t} outside the ray");
                r.tfar = t;
                found = Some(t);
            }
            Control::Continue
        });
        found
    }

    /// Every primitive in a leaf whose bounds the ray crosses: [`Bvh::for_each`]'s contract, the callback given the
    /// leaf entry.
    pub fn for_each<F: FnMut(&Primitive, f32) -> Control>(&self, ray: &Ray, mut visit: F) -> bool {
        let mut r = WideRay::new(ray);
        self.walk::<false, _>(&mut r, |primitive, r| visit(primitive, r.tfar))
    }

    /// [`WideBvh::for_each`] for a query that visits every primitive anyway (transmittance): leaves are offered a
    /// few node visits after the walk reaches them, while their prefetched entries load, so not in walk order.
    /// For a query that usually stops at its first hit (an any-hit shadow ray) this is slower: the stop comes
    /// later. Measured (`bench trace scenes/furball.toml --curves flat --threads 1 --backend bvh`, two runs, four
    /// leaves waiting): exact shadows 0.103 / 0.108 → 0.123 / 0.117 Mrays/s; stochastic shadows through it 0.490 /
    /// 0.492 → 0.443 / 0.444. Eight leaves waiting: exact shadows 0.117 / 0.114, no better than four.
    pub fn for_each_unordered<F: FnMut(&Primitive, f32) -> Control>(
        &self,
        ray: &Ray,
        mut visit: F,
    ) -> bool {
        let mut r = WideRay::new(ray);
        self.walk::<true, _>(&mut r, |primitive, r| visit(primitive, r.tfar))
    }

    /// Offers the entries of `leaf` to `primitive` in order; true when one of them stops the walk.
    #[inline(always)]
    fn offer<F: FnMut(&Primitive, &mut WideRay) -> Control>(
        &self,
        leaf: Child,
        r: &mut WideRay,
        primitive: &mut F,
    ) -> bool {
        let first = leaf.index as usize;
        for p in &self.primitives[first..first + leaf.count as usize] {
            if primitive(p, r) == Control::Stop {
                return true;
            }
        }
        false
    }

    /// Hints the cache to load a stacked child's node or first leaf entry before it is popped.
    #[inline(always)]
    fn prefetch(&self, child: Child) {
        let i = child.index as usize;
        match child.count {
            0 => crate::sys::prefetch::prefetch(&self.nodes[i]),
            ORIENTED => crate::sys::prefetch::prefetch(&self.oriented[i]),
            _ => crate::sys::prefetch::prefetch(&self.primitives[i]),
        }
    }

    #[inline]
    fn walk<const DEFER: bool, F: FnMut(&Primitive, &mut WideRay) -> Control>(
        &self,
        r: &mut WideRay,
        mut primitive: F,
    ) -> bool {
        let Some((root, root_box)) = self.root else {
            return false;
        };
        if root_box.test(r).1 & 1 == 0 {
            return false;
        }
        // `ArrayVec`: a fixed array without the cost of initialising 2 kB per ray (measured: 8 % of the walk).
        let mut stack = ArrayVec::<(Child, f32), WIDE_STACK>::new();
        // With `DEFER`, leaves reached wait here, oldest first, while the walk goes on and their prefetched entries
        // arrive; the oldest is tested when a newer one needs its place, the rest when the walk ends.
        let mut deferred = [Child { index: 0, count: 0 }; DEFERRED];
        let mut waiting = 0usize;
        let mut current = root;
        loop {
            if current.count > 0 && current.count != ORIENTED {
                let leaf = if DEFER {
                    let slot = waiting % DEFERRED;
                    let oldest = deferred[slot];
                    deferred[slot] = current;
                    waiting += 1;
                    (waiting > DEFERRED).then_some(oldest)
                } else {
                    Some(current)
                };
                if leaf.is_some_and(|leaf| self.offer(leaf, r, &mut primitive)) {
                    return true;
                }
            } else {
                let (tmin, mask, links) = if current.count == 0 {
                    let node = &self.nodes[current.index as usize];
                    let (t, m) = node.boxes.test(r);
                    (t, m & node.links.valid(), &node.links)
                } else {
                    let node = &self.oriented[current.index as usize];
                    let (t, m) = node.boxes.test(r);
                    (t, m & node.links.valid(), &node.links)
                };
                let tmin = tmin.to_array();
                if mask != 0 {
                    // Hit children sorted by entry distance without data-dependent branches: each lane's key is
                    // its entry distance's bits (t ≥ tnear ≥ 0, and non-negative floats order as their bits do;
                    // the sign bit is cleared for −0) with the lane number in the two lowest bits, missed lanes
                    // all ones by a table ([`MISSED_LANES`]: camera rays' walk 129.4 M → 126.0 M instructions,
                    // callgrind, fur ball flat 96²); a five-comparator sorting network of integer min/max
                    // (conditional moves, where a swap of lane numbers compiled to a branch that mispredicted
                    // 3.5 M times in the flat fur-ball benchmark, 40 % of the walk's mispredictions) orders them.
                    // The farther ones are stacked so that the nearer are popped first, and the nearest entered.
                    // Dropping the distances' two lowest bits only reorders children whose entry distances agree
                    // to 2⁻²¹ relative, which changes no query's answer.
                    if mask.is_power_of_two() {
                        current = links.child(mask.trailing_zeros() as usize);
                        self.prefetch(current);
                        continue;
                    }
                    let missed = MISSED_LANES[mask as usize];
                    let mut key: [u32; 4] = std::array::from_fn(|lane| {
                        (tmin[lane].to_bits() & 0x7fff_fffc) | lane as u32 | missed[lane]
                    });
                    for (a, b) in [(0, 1), (2, 3), (0, 2), (1, 3), (1, 2)] {
                        let (x, y) = (key[a], key[b]);
                        key[a] = x.min(y);
                        key[b] = x.max(y);
                    }
                    // Three pushes whatever the count, then the stack cut back to the n − 1 valid ones: no loop
                    // whose trip count (1–3) mispredicts. Pushed farthest first: key[n − 1], …, key[1], then
                    // key[1] again as filler (n < 4), removed by the truncation.
                    let n = mask.count_ones() as usize;
                    for k in &key[..n] {
                        self.prefetch(links.child((k & 3) as usize));
                    }
                    let top = stack.len() + n - 1;
                    for i in 0..3 {
                        let lane = (key[(n - 1).saturating_sub(i).max(1)] & 3) as usize;
                        stack.push((links.child(lane), tmin[lane]));
                    }
                    stack.truncate(top);
                    current = links.child((key[0] & 3) as usize);
                    continue;
                }
            }
            loop {
                let Some((child, t)) = stack.pop() else {
                    return DEFER
                        && (waiting.saturating_sub(DEFERRED)..waiting)
                            .any(|k| self.offer(deferred[k % DEFERRED], r, &mut primitive));
                };
                if t <= r.tfar {
                    current = child;
                    break;
                }
            }
        }
    }
}

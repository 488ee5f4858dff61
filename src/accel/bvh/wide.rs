//! The traversal structure of the pure-Rust backend: the binary SAH tree of [`Bvh`] collapsed into 4-wide nodes,
//! with four span capsules per segment in the leaves. Both are tested four at a time over structure-of-arrays
//! lanes (glam's `Vec4`: SSE instructions from safe code, no intrinsics).
//!
//! - **4-wide nodes** (Wald, Benthin & Boulos 2008, "Getting rid of packets"; Dammertz et al. 2008, "Shallow
//!   bounding volume hierarchies"; Embree's BVH4): each binary inner node is replaced by up to four descendants,
//!   opening the child of largest surface area first (Embree's and pbrt's "collapse" heuristic), so a ray loads
//!   one 128-byte node and tests four boxes where the binary tree loaded two nodes per level. 8-wide nodes (AVX
//!   lanes, tried 1 Dec 2026) cost more instructions (bench trace ray loops, furball 96x96: round 2.78 G → 2.94 G,
//!   flat 1.29 G → 1.45 G) for no wall-clock gain that one run could separate from noise: four it is.
//! - **Span capsules in the leaves**: hair is thin, long and diagonal, so even the union of a segment's four span
//!   boxes (what the tree is built on, [`super::Bounding::Spans`]) is mostly empty space; most rays that reach a
//!   leaf pass the segment by. Each segment keeps its four quarter spans (u ∈ [0, ¼], …, [¾, 1] from midpoint
//!   subdivision) as capsules ([`Capsules4`]: a chord segment and a radius, conservative for the swept surface)
//!   and the ray–curve test runs only when the ray comes within one of them — the role Embree's oriented leaf
//!   bounds play (Woop et al. 2014, "Exploiting local orientation similarity for efficient ray traversal of hair
//!   and fur"), at 112 bytes per segment.
//!
//! Measured (callgrind, instructions inside the benchmark's ray loops, `bench trace scenes/furball.toml --threads
//! 1 --repetitions 1 --res 96x96 --backend bvh`, same rays and figures): binary tree 8.74 G (round) / 2.98 G
//! (flat); 4-wide with span-box leaves 5.30 G / 1.94 G; flat ribbon tests 1 684 010 → 203 049 calls. Replacing
//! the zero-initialised traversal stack by an `ArrayVec`: flat 1.94 G → 1.82 G. After faster curve tests, span
//! boxes plus an oriented line bound per span: 2.78 G / 1.29 G at 325 bytes per segment; capsules alone (this
//! version): 2.90 G / 1.41 G at 229 bytes per segment, the same wall time within noise (three interleaved runs of
//! each, 1 thread, 192² furball), so the smaller leaves win. Perf shows the walk waiting on the first load of a
//! leaf entry and of a node: memory, not arithmetic, bounds it.
//! - **Slab test**: min/max of the two slab distances per axis (no branch on the direction's sign), far distances
//!   scaled by Ize 2013's 1 + 2γ₃ as in [`super::Aabb::entry`]. Direction components too small to invert are
//!   replaced by ±2⁻⁶⁴ (Embree's `rcp_safe` idea), so no 0 · ∞ = NaN can reach the comparisons: the inverse stays
//!   finite and a box is entered exactly when the binary tree's robust test enters it, up to boxes within 2⁻⁶⁴ · d
//!   of the origin's plane.

use arrayvec::ArrayVec;
use glam::{Vec3, Vec4};

use super::build::for_each_span_points;
use super::{Bvh, Control, FAR_SCALE};
use crate::hair::Strands;
use crate::ray::Ray;

/// Traversal stack entries: a 4-wide node pushes at most three children, and the tree is at most as deep as the
/// binary one ([`super::STACK_SIZE`] levels).
const WIDE_STACK: usize = 3 * super::STACK_SIZE + 1;

/// Smallest direction component magnitude inverted as it is (see the module docs).
const MIN_DIRECTION: f32 = 5.421_011e-20; // 2⁻⁶⁴

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
        let mut tmax = Vec4::splat(r.tfar);
        for axis in 0..3 {
            let t0 = (self.lo[axis] - r.origin[axis]) * r.inv_dir[axis];
            let t1 = (self.hi[axis] - r.origin[axis]) * r.inv_dir[axis];
            tmin = tmin.max(t0.min(t1));
            tmax = tmax.min(t0.max(t1) * FAR_SCALE);
        }
        (tmin, tmin.cmple(tmax).bitmask())
    }
}

/// Four capsules: per lane, a chord segment a…a+e through a span's first and last control points and a radius R
/// within which the span's swept surface lies. By the convex-hull property the curve point c(u) = Σ bᵢ pᵢ and
/// radius r(u) = Σ bᵢ rᵢ satisfy dist(c(u), chord) + r(u) ≤ maxᵢ (dist(pᵢ, chord) + rᵢ) (distance to a segment is
/// convex), so that maximum bounds every point of a round tube or flat ribbon. It is widened by one more radius
/// (the intersectors accept hits up to that far beyond the surface, see [`crate::accel::curves`]) and for
/// rounding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capsules4 {
    a: [Vec4; 3],
    e: [Vec4; 3],
    radius: Vec4,
}

impl Capsules4 {
    /// Lanes that reject nothing (radius ∞).
    const EMPTY: Capsules4 = Capsules4 {
        a: [Vec4::ZERO; 3],
        e: [Vec4::ZERO; 3],
        radius: Vec4::INFINITY,
    };

    /// Sets lane `lane` from a span's four control points (x, y, z, radius).
    fn set(&mut self, lane: usize, p: [Vec4; 4]) {
        let (a, b) = (p[0].truncate(), p[3].truncate());
        let e = b - a;
        let len2 = e.length_squared();
        let (mut bound, mut scale, mut max_radius) = (0.0f32, 0.0f32, 0.0f32);
        for q in p {
            let w = q.truncate() - a;
            // Distance to the chord segment a…b (to the point a if the span has no length): convex, so its
            // maximum over the hull is at a control point.
            let d2 = if len2 > 0.0 {
                (w - e * (w.dot(e) / len2).clamp(0.0, 1.0)).length_squared()
            } else {
                w.length_squared()
            };
            bound = bound.max(d2.max(0.0).sqrt() + q.w.abs());
            scale = scale.max(q.truncate().abs().max_element()).max(q.w.abs());
            max_radius = max_radius.max(q.w.abs());
        }
        // Tolerance: one more radius (the intersectors accept hits that close), and rounding of the coordinates.
        let radius = bound + max_radius + 1e-5 * scale;
        for axis in 0..3 {
            self.a[axis][lane] = a[axis];
            self.e[axis][lane] = e[axis];
        }
        self.radius[lane] = if radius.is_finite() {
            radius
        } else {
            f32::INFINITY
        };
    }

    /// Bit mask of the lanes whose capsule (chord segment a…a+e, radius R) the ray may cross within
    /// `[tnear, tfar]`. With w = a − o, u = w × d and v = e × d, the squared distance from the chord point a + s·e
    /// to the ray's line is |u + s v|² / |d|², least at s = −(u·v)/(v·v) clamped to [0, 1]; the lane is kept
    /// unless that exceeds R². Along the ray the capsule spans t ∈ [min(t_a, t_b) − R/|d|, max(t_a, t_b) + R/|d|]
    /// (t_x = (x − o)·d / |d|²), which must meet `[tnear, tfar]`. Comparisons are written so that a NaN keeps the
    /// lane.
    #[inline(always)]
    fn test(&self, r: &WideRay) -> u32 {
        let [dx, dy, dz] = r.dir;
        let [ex, ey, ez] = self.e;
        let wx = self.a[0] - r.origin[0];
        let wy = self.a[1] - r.origin[1];
        let wz = self.a[2] - r.origin[2];
        let (ux, uy, uz) = (wy * dz - wz * dy, wz * dx - wx * dz, wx * dy - wy * dx);
        let (vx, vy, vz) = (ey * dz - ez * dy, ez * dx - ex * dz, ex * dy - ey * dx);
        let vv = vx * vx + vy * vy + vz * vz;
        let uv = ux * vx + uy * vy + uz * vz;
        // Parallel chord (vv = 0): every s is as close; s = 0.
        let s =
            Vec4::select(vv.cmpgt(Vec4::ZERO), -uv / vv, Vec4::ZERO).clamp(Vec4::ZERO, Vec4::ONE);
        let (cx, cy, cz) = (ux + s * vx, uy + s * vy, uz + s * vz);
        let dist2 = cx * cx + cy * cy + cz * cz;
        let far = dist2.cmpgt(self.radius * self.radius * r.dd);
        // Along the ray, in units of t·|d|².
        let ta = wx * dx + wy * dy + wz * dz;
        let tb = ta + (ex * dx + ey * dy + ez * dz);
        let reach = self.radius * r.len;
        let before = (ta.max(tb) + reach).cmplt(r.tnear_dd);
        let after = (ta.min(tb) - reach).cmpgt(r.tfar_dd);
        !(far | before | after).bitmask() & 0xf
    }
}

/// A ray prepared for [`Boxes4::test`] and [`Capsules4::test`]: every component splatted across four lanes.
#[derive(Debug, Clone, Copy)]
struct WideRay {
    origin: [Vec4; 3],
    dir: [Vec4; 3],
    inv_dir: [Vec4; 3],
    /// |d|², |d|, tnear·|d|², tfar·|d|² (for [`Capsules4::test`]; `tfar_dd` follows `tfar`).
    dd: Vec4,
    len: Vec4,
    tnear_dd: Vec4,
    tfar_dd: Vec4,
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
        let dd = ray.dir.length_squared();
        WideRay {
            origin: splat(ray.origin.to_array()),
            dir: splat(ray.dir.to_array()),
            inv_dir: splat(ray.dir.to_array().map(|d| 1.0 / safe(d))),
            dd: Vec4::splat(dd),
            len: Vec4::splat(dd.sqrt()),
            tnear_dd: Vec4::splat(ray.tnear * dd),
            tfar_dd: Vec4::splat(ray.tfar * dd),
            tnear: ray.tnear,
            tfar: ray.tfar,
        }
    }

    /// Shortens the ray to end at `t`.
    #[inline]
    fn set_tfar(&mut self, t: f32) {
        self.tfar = t;
        self.tfar_dd = Vec4::splat(t * self.dd.x);
    }
}

/// A child reference: an inner node's index, or a leaf's first entry and entry count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Child {
    /// Inner: node index. Leaf: index of its first entry in [`WideBvh::primitives`].
    index: u32,
    /// Leaf: number of entries (> 0). Inner: 0.
    count: u32,
}

/// A 4-wide node: the boxes of up to four children and which lanes hold one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideNode {
    boxes: Boxes4,
    children: [Child; 4],
    /// Bit mask of the lanes that hold a child.
    valid: u32,
}

/// A leaf entry: everything a ray–curve test and the shadow bookkeeping need, in one place, so that a leaf is
/// read sequentially instead of through four index arrays (segment → first control point → points, segment →
/// strand → opacity), as Embree's curve leaves also store their control points.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(16))]
pub struct Primitive {
    /// The segment's four quarter spans as capsules.
    capsules: Capsules4,
    /// The segment's control points (x, y, z, radius).
    pub control_points: [[f32; 4]; 4],
    /// The segment id.
    pub segment: u32,
    /// The strand it belongs to.
    pub strand: u32,
    /// The strand's opacity.
    pub opacity: f32,
}

impl Primitive {
    /// Whether the leaf filter lets `ray` through to the curve test: some span's capsule may be crossed (what the
    /// walk asks before offering the primitive).
    pub fn crosses(&self, ray: &Ray) -> bool {
        self.capsules.test(&WideRay::new(ray)) != 0
    }
}

/// The 4-wide tree with per-segment span capsules (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct WideBvh {
    nodes: Vec<WideNode>,
    /// The leaf entries, leaf by leaf.
    primitives: Vec<Primitive>,
    /// The root (a node or a leaf) and its box in lane 0, or nothing (no segments).
    root: Option<(Child, Boxes4)>,
}

impl WideBvh {
    /// Collapses `bvh` (built over `strands`) into 4-wide nodes and stores each leaf entry's curve and capsules.
    pub fn new(bvh: &Bvh, strands: &Strands) -> WideBvh {
        use rayon::prelude::*;
        let primitives = bvh
            .primitives()
            .par_iter()
            .map(|&segment| {
                let mut capsules = Capsules4::EMPTY;
                let mut lane = 0;
                for_each_span_points(strands, segment, 2, |points| {
                    capsules.set(lane, points);
                    lane += 1;
                });
                let first = strands.segment_first[segment as usize] as usize;
                let strand = strands.segment_strand[segment as usize];
                Primitive {
                    capsules,
                    control_points: std::array::from_fn(|i| strands.control_points[first + i]),
                    segment,
                    strand,
                    opacity: strands.opacity[strand as usize],
                }
            })
            .collect();
        let mut wide = WideBvh {
            nodes: Vec::new(),
            primitives,
            root: None,
        };
        let binary = bvh.nodes();
        if let Some(top) = binary.first() {
            let mut root_box = Boxes4::EMPTY;
            root_box.set(0, Vec3::from_array(top.lo), Vec3::from_array(top.hi));
            wide.root = Some((wide.collapse(binary, 0), root_box));
        }
        wide
    }

    /// Memory of nodes and leaf entries, bytes.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.primitives.as_slice())
    }

    /// The leaf entries, leaf by leaf.
    pub fn primitives(&self) -> &[Primitive] {
        &self.primitives
    }

    /// The wide child for binary node `i`, appending the wide nodes below it (depth first).
    fn collapse(&mut self, binary: &[super::Node], i: usize) -> Child {
        let node = &binary[i];
        if node.is_leaf() {
            return Child {
                index: node.offset,
                count: node.count,
            };
        }
        // Open inner children, largest surface area first, until there are four.
        let mut open: Vec<usize> = vec![i + 1, node.offset as usize];
        while open.len() < 4 {
            let Some(k) = open
                .iter()
                .enumerate()
                .filter(|(_, &c)| !binary[c].is_leaf())
                .max_by(|(_, &a), (_, &b)| {
                    binary[a]
                        .bounds()
                        .area()
                        .total_cmp(&binary[b].bounds().area())
                })
                .map(|(k, _)| k)
            else {
                break;
            };
            let c = open[k];
            open.splice(k..=k, [c + 1, binary[c].offset as usize]);
        }
        let me = self.nodes.len();
        self.nodes.push(WideNode {
            boxes: Boxes4::EMPTY,
            children: [Child { index: 0, count: 0 }; 4],
            valid: 0,
        });
        let mut wide = self.nodes[me];
        for (lane, &c) in open.iter().enumerate() {
            let b = binary[c].bounds();
            wide.boxes.set(lane, b.lo, b.hi);
            wide.children[lane] = self.collapse(binary, c);
            wide.valid |= 1 << lane;
        }
        self.nodes[me] = wide;
        Child {
            index: me as u32,
            count: 0,
        }
    }

    /// The closest primitive along `ray`: [`Bvh::closest`]'s contract, the callback given the leaf entry.
    pub fn closest<F: FnMut(&Primitive, f32) -> Option<f32>>(
        &self,
        ray: &Ray,
        mut hit: F,
    ) -> Option<f32> {
        let mut r = WideRay::new(ray);
        let mut found = None;
        self.walk(&mut r, |primitive, r| {
            if let Some(t) = hit(primitive, r.tfar) {
                debug_assert!(t >= r.tnear && t <= r.tfar, "hit t = {t} outside the ray");
                r.set_tfar(t);
                found = Some(t);
            }
            Control::Continue
        });
        found
    }

    /// Every primitive whose capsules the ray may cross: [`Bvh::for_each`]'s contract, the callback given the leaf
    /// entry.
    pub fn for_each<F: FnMut(&Primitive, f32) -> Control>(&self, ray: &Ray, mut visit: F) -> bool {
        let mut r = WideRay::new(ray);
        self.walk(&mut r, |primitive, r| visit(primitive, r.tfar))
    }

    #[inline]
    fn walk<F: FnMut(&Primitive, &mut WideRay) -> Control>(
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
        let mut current = root;
        loop {
            if current.count > 0 {
                let first = current.index as usize;
                for p in &self.primitives[first..first + current.count as usize] {
                    if p.capsules.test(r) != 0 && primitive(p, r) == Control::Stop {
                        return true;
                    }
                }
            } else {
                let node = &self.nodes[current.index as usize];
                let (tmin, mask) = node.boxes.test(r);
                let tmin = tmin.to_array();
                let mut mask = mask & node.valid;
                if mask != 0 {
                    // Hit children sorted by entry distance, nearest last (it is entered, the others stacked so
                    // that the nearer are popped first).
                    let mut hits = [(Child { index: 0, count: 0 }, 0.0f32); 4];
                    let mut n = 0;
                    while mask != 0 {
                        let lane = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let entry = (node.children[lane], tmin[lane]);
                        let mut j = n;
                        while j > 0 && hits[j - 1].1 < entry.1 {
                            hits[j] = hits[j - 1];
                            j -= 1;
                        }
                        hits[j] = entry;
                        n += 1;
                    }
                    for &h in &hits[..n - 1] {
                        stack.push(h);
                    }
                    current = hits[n - 1].0;
                    continue;
                }
            }
            loop {
                let Some((child, t)) = stack.pop() else {
                    return false;
                };
                if t <= r.tfar {
                    current = child;
                    break;
                }
            }
        }
    }
}

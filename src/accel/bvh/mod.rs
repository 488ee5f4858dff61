//! A bounding volume hierarchy over the B-spline segments of [`Strands`], in safe Rust: the
//! acceleration structure of the pure-Rust backend. The ray–curve tests are not here (they are
//! [`crate::accel::curves`]); traversal hands each candidate segment to a callback, so any primitive test plugs in.
//!
//! - **Primitives** are the cubic segments Embree gets (same control points and ids). A segment is bounded by the
//!   box of its control points, each inflated by its own radius: by the convex-hull property the centre
//!   c(u) = Σ bᵢ(u) pᵢ and the radius r(u) = Σ bᵢ(u) rᵢ use the same non-negative weights summing to 1, so
//!   c(u) ± r(u) = Σ bᵢ (pᵢ ± rᵢ) lies inside [minᵢ(pᵢ − rᵢ), maxᵢ(pᵢ + rᵢ)] per axis, and so does the swept sphere
//!   (round) or ribbon (flat) around it. [`Bounding`] can tighten this by splitting the segment into 2ⁿ spans,
//!   each with its own four control points from midpoint subdivision (Lane & Riesenfeld 1980), bounded the same way.
//! - **Build**: binned SAH (Wald 2007, "On fast construction of SAH-based bounding volume hierarchies"): centroids
//!   binned into [`BuildOptions::bins`] bins per axis, the cheapest plane by the surface-area heuristic
//!   (MacDonald & Booth 1990), leaves of at most [`BuildOptions::max_leaf`] primitives. The two halves of a large
//!   node are built with `rayon::join`; every decision depends only on the node's primitives, so the tree is the
//!   same for any thread count (tested). With [`BuildOptions::oriented_splits`] nodes of at most
//!   [`build::ORIENTED_SPLIT_MAX`] segments also try splits in oriented frames (Woop et al. 2014, as Embree's hair
//!   builder does; `build::oriented_split`) and keep whichever split has the lowest SAH; node boxes stay
//!   axis-aligned here, and [`wide`] bounds the children of such splits in their own oriented frames. Measured on
//!   the fur ball it does not pay (off by default; numbers at [`BuildOptions::default`]).
//! - **Layout**: pbrt-v3's linear BVH (Pharr, Jakob & Humphreys, §4.3.4): 32-byte nodes in depth-first order, the
//!   first child right after its parent, the second child's index in the node.
//! - **Traversal** (this file's, for trees over triangles and as the reference the tests compare [`wide`] with;
//!   the curve tracer walks [`wide::WideBvh`], the same tree collapsed to 4-wide nodes chunk by chunk as the build
//!   finishes them, [`wide::WideBvh::build`]): a fixed stack of [`STACK_SIZE`]
//!   entries (no allocation per ray); both children's boxes are tested at the parent, the nearer entered first and
//!   the other stacked with its entry distance, skipped when a closer hit has been found by the time it is popped
//!   (measured against pbrt's split-axis order: 2–4 % fewer box tests). Boxes use the robust slab test of Ize 2013
//!   ("Robust BVH ray traversal", JCGT 2(2)): far slab distances scaled by 1 + 2γ₃ so that rounding never loses a box
//!   the ray touches.

mod build;
#[cfg(test)]
mod tests;
pub mod wide;

use glam::Vec3;

use crate::hair::Strands;
use crate::ray::Ray;

/// Entries of the traversal stack. The build splits by median below [`build::MEDIAN_DEPTH`] levels, which bounds
/// the depth (and so the stack) for any input of fewer than 2³² primitives.
pub const STACK_SIZE: usize = 64;

/// γ₃ = 3ε / (1 − 3ε) with ε = 2⁻²⁴ (half an ulp of 1): the relative error bound of the slab distance
/// (b − o) · (1/d), three rounded operations (Ize 2013, §3; pbrt-v3 eq. 3.9).
const GAMMA_3: f32 = 3.0 * f32::EPSILON * 0.5 / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Factor on the far slab distance: Ize 2013's 1 + 2γ₃, which keeps the test conservative.
const FAR_SCALE: f32 = 1.0 + 2.0 * GAMMA_3;

/// An axis-aligned box, world space. The empty box has `lo = +∞`, `hi = −∞`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub lo: Vec3,
    /// Upper corner.
    pub hi: Vec3,
}

impl Aabb {
    /// The empty box, the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    /// The smallest box containing both.
    #[inline]
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    /// Whether `other` lies inside this box (boundaries included).
    pub fn contains(&self, other: &Aabb) -> bool {
        self.lo.cmple(other.lo).all() && other.hi.cmple(self.hi).all()
    }

    /// Centre of the box.
    #[inline]
    pub fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    /// Surface area; 0 for an empty box.
    pub fn area(&self) -> f32 {
        let e = (self.hi - self.lo).max(Vec3::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The box's entry distance along a ray in `[tnear, tfar]`, or `None` if the ray misses it there. Ize 2013's
    /// robust slab test: conservative under rounding, and correct for zero direction components (their inverse is
    /// ±∞; a NaN from 0 · ∞, an origin on the slab plane, is ignored by `f32::max`/`min`).
    #[inline]
    pub fn entry(&self, ray: &RayInv) -> Option<f32> {
        let (near, far) = ray.slabs(self.lo, self.hi);
        let tmin = ray.tnear.max(near[0]).max(near[1]).max(near[2]);
        let tmax = ray.tfar.min(far[0]).min(far[1]).min(far[2]);
        (tmin <= tmax).then_some(tmin)
    }
}

/// A ray prepared for box tests: the inverse direction and its signs, computed once per ray.
#[derive(Debug, Clone, Copy)]
pub struct RayInv {
    origin: Vec3,
    inv_dir: Vec3,
    /// Per axis, whether the direction is negative (then the box's `hi` is the near slab).
    negative: [bool; 3],
    /// Start of the interval.
    pub tnear: f32,
    /// End of the interval.
    pub tfar: f32,
}

impl RayInv {
    /// Prepares `ray`. Zero direction components give infinite inverses, which the slab test handles.
    pub fn new(ray: &Ray) -> Self {
        let inv_dir = ray.dir.recip();
        RayInv {
            origin: ray.origin,
            inv_dir,
            // The sign bit, not `< 0`: −0 has an inverse of −∞ and must take the `hi` slab as near.
            negative: [
                inv_dir.x.is_sign_negative(),
                inv_dir.y.is_sign_negative(),
                inv_dir.z.is_sign_negative(),
            ],
            tnear: ray.tnear,
            tfar: ray.tfar,
        }
    }

    /// Near and far slab distances per axis, the far ones scaled by Ize's 1 + 2γ₃.
    #[inline]
    fn slabs(&self, lo: Vec3, hi: Vec3) -> ([f32; 3], [f32; 3]) {
        let (lo, hi, o, inv) = (lo.to_array(), hi.to_array(), self.origin, self.inv_dir);
        let (o, inv) = (o.to_array(), inv.to_array());
        let mut near = [0.0; 3];
        let mut far = [0.0; 3];
        for a in 0..3 {
            let (n, f) = if self.negative[a] {
                (hi[a], lo[a])
            } else {
                (lo[a], hi[a])
            };
            near[a] = (n - o[a]) * inv[a];
            far[a] = (f - o[a]) * inv[a] * FAR_SCALE;
        }
        (near, far)
    }
}

/// How tightly each segment is bounded (see the module doc for why the boxes are conservative).
///
/// Measured on 20 000 random rays with each segment's box as the primitive (a one-off measurement;
/// `bench trace --backend bvh` times it): primitive tests per closest-hit ray on furball.hair (455 505
/// segments) 3.9 with `Hull`, 1.6 / 1.1 / 0.9 with 2 / 4 / 8 spans, box tests 61 / 46 / 41 / 39, at 67–68 bytes
/// per segment and the same build time; on straight.hair 21.3 / 6.6 / 3.2 / 2.1 primitive tests. Span references
/// double the nodes and the build time and test no fewer primitives (1.6 on furball for 2 spans). Four spans
/// ([`BuildOptions::default`]) take most of the gain. Build, furball.hair, 2 threads: 303 ms (Embree's round
/// build in the same process: 263 ms).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Bounding {
    /// One box around the segment's four control points, each inflated by its radius.
    Hull,
    /// The union of the boxes of 2^`levels` spans of the segment (midpoint subdivision): still one primitive per
    /// segment, a tighter box.
    Spans {
        /// Subdivision levels, 1–3 (2, 4 or 8 spans).
        levels: u32,
    },
    /// Each of 2^`levels` spans is a primitive of its own, so a segment can sit in several leaves and the
    /// callback may see it more than once per ray.
    SpanRefs {
        /// Subdivision levels, 1–3 (2, 4 or 8 spans).
        levels: u32,
    },
}

/// Build parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildOptions {
    /// Segment bounds.
    pub bounding: Bounding,
    /// Largest number of primitives in a leaf (1–254: the wide tree keeps a leaf's count in a byte beside its node
    /// kinds).
    pub max_leaf: usize,
    /// SAH bins per axis (2–32).
    pub bins: usize,
    /// SAH cost of one primitive (ray–curve) test, in box tests (> 0). Higher makes smaller leaves.
    pub intersect_cost: f32,
    /// Also search each node of at most [`build::ORIENTED_SPLIT_MAX`] primitives for splits in oriented frames
    /// (Woop et al. 2014; `build::oriented_split`), kept where their SAH is lower. Ignored with
    /// [`Bounding::SpanRefs`]. Off by default (measured below).
    pub oriented_splits: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            bounding: Bounding::Spans { levels: 2 },
            // One segment per leaf: the wide tree's lanes (oriented where that is tighter, see `wide`) then bound
            // each segment on its own, and a curve test runs only for a segment whose own box the ray crosses,
            // as Embree's hair BVH bounds each curve. Measured with oriented nodes (callgrind with cache
            // simulation, `bench trace` ray loops, furball 96x96, 1 thread; estimated cycles = instructions + 10
            // per L1 miss + 200 per last-level miss): max_leaf 4 -> 1, flat 1.60 G -> 1.35 G, round 3.08 G ->
            // 2.74 G.
            max_leaf: 1,
            bins: 16,
            // Matters for max_leaf > 1 only. Measured with max_leaf 4 and span-capsule leaves (callgrind, same
            // loops): cost 1 against 4: round 2.85 G -> 2.78 G instructions, flat 1.37 G -> 1.29 G.
            intersect_cost: 1.0,
            // Off: measured on the fur ball (flat; callgrind with cache simulation, `bench trace` ray loops, 96x96,
            // 1 thread, estimated cycles with mispredicts) the four ray loops went 1.179 G -> 1.164 G (-1.3 %,
            // exact shadows 0.846 G -> 0.835 G) for 3.69 G -> 7.97 G build instructions (+55 % of the whole
            // build with the collapse): not worth it. See `build::oriented_split`.
            oriented_splits: false,
        }
    }
}

/// A 32-byte node (pbrt-v3's `LinearBVHNode`): an inner node's first child is the next node and its second is
/// `offset`; a leaf holds `count` primitives from `offset` in [`Bvh::primitives`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Box of everything below, lower corner.
    pub lo: [f32; 3],
    /// Box of everything below, upper corner.
    pub hi: [f32; 3],
    /// Inner node: index of the second child. Leaf: index of its first primitive.
    pub offset: u32,
    /// Leaf: number of primitives (> 0). Inner node: 0.
    pub count: u32,
}

impl Node {
    /// Whether this node is a leaf.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    /// The node's box.
    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            lo: Vec3::from_array(self.lo),
            hi: Vec3::from_array(self.hi),
        }
    }
}

/// What an all-hits walk does after a primitive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Control {
    /// Go on visiting primitives.
    Continue,
    /// End the walk (an occluder was found).
    Stop,
}

/// A BVH over the segments of one [`Strands`].
#[derive(Debug, Clone, PartialEq)]
pub struct Bvh {
    nodes: Vec<Node>,
    primitives: Vec<u32>,
    options: BuildOptions,
}

impl Bvh {
    /// Builds the hierarchy over all segments of `strands`, in parallel on the current rayon pool.
    ///
    /// # Panics
    /// If `options` are out of range (a programming error, not an input error).
    pub fn build(strands: &Strands, options: BuildOptions) -> Bvh {
        build::build(strands, options)
    }

    /// Builds the hierarchy over primitives known only by their boxes (the triangles of `accel::mesh`): primitive
    /// `i` is `boxes[i]`, and [`Bvh::closest`] and [`Bvh::for_each`] hand `i` to their callbacks. The build is the
    /// one of [`Bvh::build`] with aligned splits only: `options.bounding` does not apply and
    /// `options.oriented_splits` is ignored (there is no segment direction to orient a frame by).
    ///
    /// # Panics
    /// If `options` are out of range, or there are 2³² boxes or more.
    pub fn build_boxes(boxes: &[Aabb], options: BuildOptions) -> Bvh {
        build::build_boxes(boxes, options)
    }

    /// The nodes, depth first; empty for a model without segments.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// Segment id of each leaf entry (a segment appears once, or once per span with [`Bounding::SpanRefs`]).
    pub fn primitives(&self) -> &[u32] {
        &self.primitives
    }

    /// The options it was built with.
    pub fn options(&self) -> BuildOptions {
        self.options
    }

    /// Memory of nodes and primitive indices, bytes.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.nodes.as_slice())
            + std::mem::size_of_val(self.primitives.as_slice())
    }

    /// The closest primitive along `ray`. `hit(segment, tfar)` tests one segment against the ray, with `tfar` the
    /// closest distance found so far, and returns its hit distance, which must lie in `[ray.tnear, tfar]`; the
    /// walk then only visits boxes before it. Returns the closest distance returned, if any: the caller keeps
    /// the hit's details in the closure (the last `Some` it returned is the closest).
    pub fn closest<F: FnMut(u32, f32) -> Option<f32>>(&self, ray: &Ray, mut hit: F) -> Option<f32> {
        let mut r = RayInv::new(ray);
        let mut found = None;
        self.walk(&mut r, |segment, r| {
            if let Some(t) = hit(segment, r.tfar) {
                debug_assert!(
                    t >= r.tnear && t <= r.tfar,
                    "hit callback returned t = {t} outside [{}, {}]",
                    r.tnear,
                    r.tfar
                );
                r.tfar = t;
                found = Some(t);
            }
            Control::Continue
        });
        found
    }

    /// Visits every primitive whose leaf box the ray crosses in `[tnear, tfar]` (nearer boxes first, but not
    /// sorted), until `visit(segment, tfar)` returns [`Control::Stop`]. Returns whether it stopped: for
    /// transmittance (every hit counts) and any-hit shadow queries.
    pub fn for_each<F: FnMut(u32, f32) -> Control>(&self, ray: &Ray, mut visit: F) -> bool {
        let mut r = RayInv::new(ray);
        self.walk(&mut r, |segment, r| visit(segment, r.tfar))
    }

    /// The traversal both queries share; `leaf_primitive` may shorten `r.tfar`. Returns whether it was stopped.
    #[inline]
    fn walk<F: FnMut(u32, &mut RayInv) -> Control>(
        &self,
        r: &mut RayInv,
        mut leaf_primitive: F,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let entry = |i: usize, r: &RayInv| {
            #[cfg(test)]
            tests::NODE_VISITS.with(|v| v.set(v.get() + 1));
            self.nodes[i].bounds().entry(r)
        };
        if entry(0, r).is_none() {
            return false;
        }
        // Far children still to visit, with their entry distances: skipped when a closer hit has been found since.
        let mut stack = [(0u32, 0.0f32); STACK_SIZE];
        let mut top = 0;
        let mut index = 0usize;
        loop {
            let node = &self.nodes[index];
            if node.is_leaf() {
                let first = node.offset as usize;
                for &segment in &self.primitives[first..first + node.count as usize] {
                    if leaf_primitive(segment, r) == Control::Stop {
                        return true;
                    }
                }
            } else {
                // Both children's boxes tested here: the nearer entry first (front to back), the other stacked.
                let (a, b) = (index + 1, node.offset as usize);
                match (entry(a, r), entry(b, r)) {
                    (Some(ta), Some(tb)) => {
                        let (near, far, t_far) = if ta <= tb { (a, b, tb) } else { (b, a, ta) };
                        stack[top] = (far as u32, t_far);
                        top += 1;
                        index = near;
                        continue;
                    }
                    (Some(_), None) => {
                        index = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        index = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            loop {
                if top == 0 {
                    return false;
                }
                top -= 1;
                let (i, t) = stack[top];
                if t <= r.tfar {
                    index = i as usize;
                    break;
                }
            }
        }
    }
}

/// The bounds of one segment as `bounding` defines them (the union of its spans' boxes for the span modes).
pub fn segment_bounds(strands: &Strands, segment: u32, bounding: Bounding) -> Aabb {
    if bounding == (Bounding::Spans { levels: 2 }) {
        // The default bounding: the quarter spans' points are the seven of the refined polygon, and the union of
        // the spans' boxes is the box of those points (the same minima and maxima of the same values).
        return build::polygon(strands, segment)
            .iter()
            .fold(Aabb::EMPTY, |b, c| {
                let (x, r) = (c.truncate(), Vec3::splat(c.w.abs()));
                b.union(Aabb {
                    lo: x - r,
                    hi: x + r,
                })
            });
    }
    let mut b = Aabb::EMPTY;
    build::for_each_span(strands, segment, bounding, |span| b = b.union(span));
    b
}

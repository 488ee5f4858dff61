//! Binned SAH construction (Wald 2007) into pbrt-v3's depth-first node array, parallel at the top levels, with
//! splits also searched in oriented frames near the leaves (Woop et al. 2014, see [`oriented_split`]). The curve
//! segments of [`Bvh::build`] and the plain boxes of [`Bvh::build_boxes`] (triangles) become the same primitive
//! references and go through the same build.

use glam::{Vec3, Vec4};

use super::{Aabb, Bounding, BuildOptions, Bvh, Node, STACK_SIZE};
use crate::hair::Strands;

/// Below this depth the build stops looking for SAH planes and splits at the median: with at most 2³² primitives
/// the tree is then at most `MEDIAN_DEPTH + 32 ≤ STACK_SIZE` levels deep, so the traversal stack cannot overflow.
pub(super) const MEDIAN_DEPTH: u32 = (STACK_SIZE - 32) as u32;

/// Nodes with at least this many primitives build their two halves with `rayon::join`. Smaller subtrees are not
/// worth a task (a 4 096-primitive subtree builds in well under a millisecond).
pub(super) const PARALLEL_MIN: usize = 4096;

/// Most SAH bins per axis: Wald 2007 found 16–32 enough; the bin arrays live on the stack, sized by this.
pub(super) const MAX_BINS: usize = 32;

/// SAH cost of visiting a node (one box test), the unit of [`BuildOptions::intersect_cost`].
const TRAVERSAL_COST: f32 = 1.0;

/// Largest node (primitives) whose split is also searched in oriented frames ([`oriented_split`]). Above it the
/// primitives of a node point every way and an oriented split rarely wins. Counted on the fur ball with a limit
/// of 4 096 (aligned / object-in-frame / strand splits chosen): nodes of 2–3 segments 77 k / 25 k / 158 k, 4–63
/// segments 24 k / 125 k / 26 k, 64–511 9.5 k / 9.4 k / 29, 512–4 095 2 273 / 33 / 0; and the ray loops'
/// estimated cycles are the same with 4 096 and 256 (1.163 G, 1.164 G), so 256 saves the build the rest.
pub(super) const ORIENTED_SPLIT_MAX: usize = 256;

/// SAH cost of an aligned split per unit of the parent's surface area, against one primitive test per unit of a
/// child's area (Embree's hair builder: traversal 1 against intersection 6, `bvh_builder_hair.h`).
const ALIGNED_TRAVERSAL: f32 = 1.0 / 6.0;
/// The same for an oriented split. Embree charges 5 (of 6); measured on the fur ball (flat, estimated cycles of
/// the ray loops) 5/6 and 1/6 gave the same (1.164 G, 1.165 G): our collapse, not the split, decides whether a
/// lane is oriented, so the build charges the aligned cost.
const ORIENTED_TRAVERSAL: f32 = 1.0 / 6.0;

/// A segment's control polygon after two levels of midpoint subdivision (x, y, z, radius): its four quarter
/// spans are the consecutive fours of these seven points (span k is points k..k + 4), so the box of the seven
/// points, each inflated by its radius, in any frame holds the quarter spans' hulls; in the world frame it is
/// the segment's [`Bounding::Spans`]` { levels: 2 }` box.
type Polygon = [Vec4; 7];

/// What the build reads besides the primitive references.
struct Context<'a> {
    options: &'a BuildOptions,
    /// Each segment's [`Polygon`], by segment id; empty when oriented splits are off.
    polygons: &'a [Polygon],
}

/// A primitive during the build: its box and id (the segment, or the index of a box given to
/// [`Bvh::build_boxes`]).
#[derive(Debug, Clone, Copy)]
struct PrimRef {
    bounds: Aabb,
    segment: u32,
}

/// Calls `f` with the box of each span of `segment` that `bounding` asks for (one box for [`Bounding::Hull`]).
pub(super) fn for_each_span(
    strands: &Strands,
    segment: u32,
    bounding: Bounding,
    mut f: impl FnMut(Aabb),
) {
    let first = strands.segment_first[segment as usize] as usize;
    let cps: [Vec4; 4] =
        std::array::from_fn(|i| Vec4::from_array(strands.control_points[first + i]));
    let levels = match bounding {
        Bounding::Hull => 0,
        Bounding::Spans { levels } | Bounding::SpanRefs { levels } => levels,
    };
    subdivide(cps, levels, &mut |p| f(hull_box(&p)));
}

/// Calls `f` with the four control points (x, y, z, radius) of each of the 2^`levels` spans of `segment`, in order
/// along the curve.
#[cfg(test)]
pub(super) fn for_each_span_points(
    strands: &Strands,
    segment: u32,
    levels: u32,
    mut f: impl FnMut([Vec4; 4]),
) {
    let first = strands.segment_first[segment as usize] as usize;
    let cps: [Vec4; 4] =
        std::array::from_fn(|i| Vec4::from_array(strands.control_points[first + i]));
    subdivide(cps, levels, &mut f);
}

/// Recursive midpoint subdivision of a uniform cubic B-spline segment (x, y, z, radius together, since both use
/// the same basis): the refined polygon of P₀…P₃ is E₀, V₁, E₁, V₂, E₂ with edge points Eᵢ = (Pᵢ + Pᵢ₊₁)/2 and
/// vertex points Vᵢ = (Pᵢ₋₁ + 6Pᵢ + Pᵢ₊₁)/8 (Lane & Riesenfeld 1980); [E₀ V₁ E₁ V₂] is u ∈ [0, ½] and
/// [V₁ E₁ V₂ E₂] is u ∈ [½, 1].
fn subdivide(p: [Vec4; 4], levels: u32, f: &mut impl FnMut([Vec4; 4])) {
    if levels == 0 {
        f(p);
        return;
    }
    let e = |i: usize| 0.5 * (p[i] + p[i + 1]);
    let v = |i: usize| 0.125 * (p[i - 1] + 6.0 * p[i] + p[i + 1]);
    let (e0, v1, e1, v2, e2) = (e(0), v(1), e(1), v(2), e(2));
    subdivide([e0, v1, e1, v2], levels - 1, f);
    subdivide([v1, e1, v2, e2], levels - 1, f);
}

/// The box of four control points, each inflated by its own radius (w): conservative for the swept surface,
/// see the module doc.
fn hull_box(p: &[Vec4; 4]) -> Aabb {
    p.iter().fold(Aabb::EMPTY, |b, c| {
        let (x, r) = (c.truncate(), Vec3::splat(c.w.abs()));
        b.union(Aabb {
            lo: x - r,
            hi: x + r,
        })
    })
}

/// Checks the options every build shares.
fn check_options(options: &BuildOptions) {
    assert!(
        (1..=254).contains(&options.max_leaf),
        "bvh: max_leaf must be in 1..=254, got {}",
        options.max_leaf
    );
    assert!(
        (2..=MAX_BINS).contains(&options.bins),
        "bvh: bins must be in 2..={MAX_BINS}, got {}",
        options.bins
    );
    assert!(
        options.intersect_cost > 0.0,
        "bvh: intersect_cost must be > 0, got {}",
        options.intersect_cost
    );
}

/// Builds the tree over the segments of `strands` (see [`Bvh::build`]).
pub(super) fn build(strands: &Strands, options: BuildOptions) -> Bvh {
    check_options(&options);
    check_span_levels(&options);
    let refs = primitive_refs(strands, options.bounding);
    let polygons = polygons(strands, &options);
    from_refs(refs, options, &polygons)
}

/// Checks the span levels of [`Bounding::Spans`] and [`Bounding::SpanRefs`].
fn check_span_levels(options: &BuildOptions) {
    if let Bounding::Spans { levels } | Bounding::SpanRefs { levels } = options.bounding {
        assert!(
            (1..=3).contains(&levels),
            "bvh: span levels must be in 1..=3, got {levels}"
        );
    }
}

/// Each segment's [`Polygon`] when the build searches oriented splits, else nothing. A span reference is not a
/// whole segment, so span-reference trees keep the aligned build.
fn polygons(strands: &Strands, options: &BuildOptions) -> Vec<Polygon> {
    if options.oriented_splits && !matches!(options.bounding, Bounding::SpanRefs { .. }) {
        use rayon::prelude::*;
        (0..strands.segment_count() as u32)
            .into_par_iter()
            .map(|segment| polygon(strands, segment))
            .collect()
    } else {
        Vec::new()
    }
}

/// Builds the tree over primitives given by their boxes alone (see [`Bvh::build_boxes`]): primitive `i` is
/// `boxes[i]`. Aligned splits only, since there is no segment to orient a frame by.
pub(super) fn build_boxes(boxes: &[Aabb], options: BuildOptions) -> Bvh {
    check_options(&options);
    assert!(
        boxes.len() <= u32::MAX as usize,
        "bvh: {} primitives exceed u32 indices",
        boxes.len()
    );
    let refs = boxes
        .iter()
        .enumerate()
        .map(|(i, &bounds)| PrimRef {
            bounds,
            segment: i as u32,
        })
        .collect();
    from_refs(
        refs,
        BuildOptions {
            oriented_splits: false,
            ..options
        },
        &[],
    )
}

/// The build both entry points share: the tree over `refs`, with oriented splits where `polygons` (by primitive
/// id) is not empty.
fn from_refs(mut refs: Vec<PrimRef>, options: BuildOptions, polygons: &[Polygon]) -> Bvh {
    let top = top_of(&mut refs, &options, polygons, &|chunk: Chunk| chunk.nodes);
    let mut nodes = Vec::new();
    if let Some(top) = top {
        assemble(top, &mut nodes);
    }
    Bvh {
        nodes,
        primitives: refs.iter().map(|r| r.segment).collect(),
        options,
    }
}

/// One reference per segment, or one per span for [`Bounding::SpanRefs`]; in segment order (determinism).
fn primitive_refs(strands: &Strands, bounding: Bounding) -> Vec<PrimRef> {
    use rayon::prelude::*;
    let n = strands.segment_count() as u32;
    match bounding {
        Bounding::SpanRefs { .. } => {
            let mut refs = Vec::new();
            for segment in 0..n {
                for_each_span(strands, segment, bounding, |bounds| {
                    refs.push(PrimRef { bounds, segment });
                });
            }
            refs
        }
        _ => (0..n)
            .into_par_iter()
            .map(|segment| PrimRef {
                bounds: super::segment_bounds(strands, segment, bounding),
                segment,
            })
            .collect(),
    }
}

/// The top levels of a tree, built in parallel ([`build_top`]): inner nodes of at least [`PARALLEL_MIN`]
/// primitives, and below them the subtrees built on one thread ([`Chunk`]), each handed to the caller as soon as it
/// is built, so that no tree of the whole model needs to exist at once.
#[derive(Debug)]
pub(super) enum Top<R> {
    /// A node of the parallel levels: its box, its primitives (`count` from `first`) and its two children.
    Inner {
        bounds: Aabb,
        first: u32,
        count: u32,
        children: Box<[Top<R>; 2]>,
    },
    /// A subtree built on one thread: its box, its primitives, and what the caller made of it.
    Chunk {
        bounds: Aabb,
        first: u32,
        count: u32,
        value: R,
    },
}

impl<R> Top<R> {
    /// The box of everything below.
    pub(super) fn bounds(&self) -> Aabb {
        match self {
            Top::Inner { bounds, .. } | Top::Chunk { bounds, .. } => *bounds,
        }
    }

    /// The first primitive below and the number of primitives.
    pub(super) fn range(&self) -> (u32, u32) {
        match self {
            Top::Inner { first, count, .. } | Top::Chunk { first, count, .. } => (*first, *count),
        }
    }
}

/// A subtree built on one thread below the parallel levels: its binary nodes in depth-first order (second-child
/// offsets relative to its first node, leaf offsets into the whole primitive array) and its primitives, which
/// start at `base` in the final order.
pub(super) struct Chunk<'a> {
    pub(super) nodes: Vec<Node>,
    pub(super) base: u32,
    refs: &'a [PrimRef],
}

impl Chunk<'_> {
    /// The segment ids of the chunk's primitives `first..first + count` (indices into the whole array).
    pub(super) fn segments(
        &self,
        first: u32,
        count: u32,
    ) -> impl Iterator<Item = u32> + Clone + '_ {
        let start = (first - self.base) as usize;
        self.refs[start..start + count as usize]
            .iter()
            .map(|r| r.segment)
    }
}

/// Builds the tree over the segments of `strands` as [`build`] does, handing each subtree below the parallel
/// levels to `chunk` on the thread that built it. Returns the top levels (nothing for no segments) and every leaf
/// entry's segment id in final order; the tree is the same for any thread count, and so is every chunk.
pub(super) fn build_top<R: Send>(
    strands: &Strands,
    options: BuildOptions,
    chunk: &(impl Fn(Chunk) -> R + Sync),
) -> (Option<Top<R>>, Vec<u32>) {
    check_options(&options);
    check_span_levels(&options);
    let mut refs = primitive_refs(strands, options.bounding);
    let polygons = polygons(strands, &options);
    let top = top_of(&mut refs, &options, &polygons, chunk);
    (top, refs.iter().map(|r| r.segment).collect())
}

/// The top levels over `refs`, which end in final order (see [`build_top`]).
fn top_of<R: Send>(
    refs: &mut [PrimRef],
    options: &BuildOptions,
    polygons: &[Polygon],
    chunk: &(impl Fn(Chunk) -> R + Sync),
) -> Option<Top<R>> {
    let cx = Context { options, polygons };
    assert!(
        refs.len() <= u32::MAX as usize,
        "bvh: {} primitives exceed u32 indices",
        refs.len()
    );
    (!refs.is_empty()).then(|| top(refs, 0, 0, &cx, chunk))
}

fn top<R: Send>(
    refs: &mut [PrimRef],
    base: u32,
    depth: u32,
    cx: &Context,
    chunk: &(impl Fn(Chunk) -> R + Sync),
) -> Top<R> {
    let count = refs.len() as u32;
    if refs.len() >= PARALLEL_MIN {
        let (bounds, centroids) = node_bounds(refs);
        if let Some(mid) = split(refs, &bounds, &centroids, depth, cx) {
            let (left, right) = refs.split_at_mut(mid);
            let (l, r) = rayon::join(
                || top(left, base, depth + 1, cx, chunk),
                || top(right, base + mid as u32, depth + 1, cx, chunk),
            );
            return Top::Inner {
                bounds,
                first: base,
                count,
                children: Box::new([l, r]),
            };
        }
    }
    // At most 2n − 1 nodes.
    let mut nodes = Vec::with_capacity(2 * refs.len() - 1);
    sequential(refs, base, depth, cx, &mut nodes);
    let bounds = nodes[0].bounds();
    let value = chunk(Chunk { nodes, base, refs });
    Top::Chunk {
        bounds,
        first: base,
        count,
        value,
    }
}

/// The binary node array of a tree's top levels and chunks: depth first, second-child offsets shifted to where
/// each chunk lands.
fn assemble(top: Top<Vec<Node>>, out: &mut Vec<Node>) {
    match top {
        Top::Inner {
            bounds, children, ..
        } => {
            let me = out.len();
            out.push(inner(&bounds, 0));
            let [left, right] = *children;
            assemble(left, out);
            out[me].offset = out.len() as u32;
            assemble(right, out);
        }
        Top::Chunk { value, .. } => place(out, value),
    }
}

/// Appends a subtree built with indices from 0, shifting its second-child indices by where it lands.
fn place(out: &mut Vec<Node>, sub: Vec<Node>) {
    let shift = out.len() as u32;
    out.extend(sub.into_iter().map(|mut n| {
        if !n.is_leaf() {
            n.offset += shift;
        }
        n
    }));
}

/// The same build on one thread, appending to `out` (indices relative to `out`'s start).
fn sequential(refs: &mut [PrimRef], base: u32, depth: u32, cx: &Context, out: &mut Vec<Node>) {
    let (bounds, centroids) = node_bounds(refs);
    match split(refs, &bounds, &centroids, depth, cx) {
        None => out.push(leaf(&bounds, base, refs.len())),
        Some(mid) => {
            let me = out.len();
            out.push(inner(&bounds, 0));
            let (left, right) = refs.split_at_mut(mid);
            sequential(left, base, depth + 1, cx, out);
            out[me].offset = out.len() as u32;
            sequential(right, base + mid as u32, depth + 1, cx, out);
        }
    }
}

fn leaf(bounds: &Aabb, first: u32, count: usize) -> Node {
    Node {
        lo: bounds.lo.to_array(),
        hi: bounds.hi.to_array(),
        offset: first,
        count: count as u32,
    }
}

fn inner(bounds: &Aabb, second: u32) -> Node {
    Node {
        lo: bounds.lo.to_array(),
        hi: bounds.hi.to_array(),
        offset: second,
        count: 0,
    }
}

/// Chooses how to split `refs` and partitions them: `Some(mid)` puts `refs[..mid]` in the first child;
/// `None` makes a leaf.
fn split(
    refs: &mut [PrimRef],
    bounds: &Aabb,
    centroids: &Aabb,
    depth: u32,
    cx: &Context,
) -> Option<usize> {
    let options = cx.options;
    let n = refs.len();
    if n == 1 {
        return None;
    }
    let extent = centroids.hi - centroids.lo;
    // The widest centroid axis: the median split's axis, and the SAH's when it finds nothing better.
    let widest = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    if depth < MEDIAN_DEPTH && extent[widest] > 0.0 {
        let best = best_plane(refs.iter().map(|r| r.bounds), centroids, options.bins);
        if let Some(plane) = best {
            // SAH (MacDonald & Booth 1990): C = C_trav + C_isect · (A_L N_L + A_R N_R) / A against C_isect · N.
            let area = bounds.area();
            let split_cost = if area > 0.0 {
                TRAVERSAL_COST + options.intersect_cost * plane.cost / area
            } else {
                TRAVERSAL_COST + options.intersect_cost * n as f32
            };
            if n <= options.max_leaf && options.intersect_cost * n as f32 <= split_cost {
                return None;
            }
            if let Some(mid) = oriented_split(refs, area, plane.cost, cx) {
                return Some(mid);
            }
            let mid = partition(refs, |r| plane.bin_of(r) < plane.bin);
            if mid > 0 && mid < n {
                return Some(mid);
            }
        }
    }
    if n <= options.max_leaf {
        return None;
    }
    // No usable plane (all centroids equal, or too deep): split at the median centroid of the widest axis.
    let mid = n / 2;
    refs.select_nth_unstable_by(mid, |a, b| {
        a.bounds.centroid()[widest].total_cmp(&b.bounds.centroid()[widest])
    });
    Some(mid)
}

/// The box of the primitives and the box of their centroids, in one pass.
fn node_bounds(refs: &[PrimRef]) -> (Aabb, Aabb) {
    refs.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), r| {
        let m = r.bounds.centroid();
        (b.union(r.bounds), c.union(Aabb { lo: m, hi: m }))
    })
}

/// A candidate plane: primitives whose centroid falls in a bin below `bin` on `axis` go left.
#[derive(Debug, Clone, Copy)]
struct Plane {
    axis: usize,
    bin: usize,
    /// A_L N_L + A_R N_R.
    cost: f32,
    lo: f32,
    scale: f32,
    bins: usize,
}

impl Plane {
    /// The bin of a primitive's centroid, computed identically when binning and when partitioning.
    #[inline]
    fn bin_of(&self, r: &PrimRef) -> usize {
        bin_index(
            r.bounds.centroid()[self.axis],
            self.lo,
            self.scale,
            self.bins,
        )
    }
}

#[inline]
fn bin_index(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    // `as usize` saturates (NaN → 0); the min keeps the top centroid in the last bin.
    (((c - lo) * scale) as usize).min(bins - 1)
}

/// Wald 2007's binning: per axis, count primitives and grow boxes per centroid bin, then sweep the bin boundaries
/// from both sides for the cheapest A_L N_L + A_R N_R.
///
/// All three axes are binned in one pass over `refs` (the build's hottest loop: one pass instead of three, each
/// centroid computed once); each bin sees its primitives in the same order as three passes would, so the boxes,
/// costs and chosen plane are bit for bit the same.
fn best_plane(
    boxes_in: impl IntoIterator<Item = Aabb>,
    centroids: &Aabb,
    bins: usize,
) -> Option<Plane> {
    let (lo, hi) = (centroids.lo, centroids.hi);
    // A flat axis bins everything into bin 0 (scale 0) and is skipped by the sweep.
    let scale: [f32; 3] = std::array::from_fn(|axis| {
        if hi[axis] > lo[axis] {
            bins as f32 * (1.0 - 1e-6) / (hi[axis] - lo[axis])
        } else {
            0.0
        }
    });
    let mut count = [[0usize; MAX_BINS]; 3];
    let mut boxes = [[Aabb::EMPTY; MAX_BINS]; 3];
    for bounds in boxes_in {
        let c = bounds.centroid();
        for axis in 0..3 {
            let b = bin_index(c[axis], lo[axis], scale[axis], bins);
            count[axis][b] += 1;
            boxes[axis][b] = boxes[axis][b].union(bounds);
        }
    }
    let mut best: Option<Plane> = None;
    for axis in 0..3 {
        if hi[axis] <= lo[axis] {
            continue;
        }
        let (count, boxes) = (&count[axis], &boxes[axis]);
        // Only planes after a non-empty bin are swept: every plane in a run of empty bins partitions as the first
        // plane of the run and costs the same (a union with an empty box changes nothing), and the first of equal
        // costs is the one kept, so the plane chosen is the one a sweep over every bin chooses, with one area per
        // non-empty bin (most nodes have few primitives; their 16 bins are mostly empty).
        let mut used = [0usize; MAX_BINS];
        let mut m = 0;
        for (i, &c) in count.iter().enumerate().take(bins) {
            if c > 0 {
                used[m] = i;
                m += 1;
            }
        }
        // right_cost[p] = A · N of the non-empty bins from the p-th on; sweep left to right adding the left side.
        let mut right_cost = [0.0f32; MAX_BINS];
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for p in (1..m).rev() {
            acc = acc.union(boxes[used[p]]);
            n += count[used[p]];
            right_cost[p] = acc.area() * n as f32;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0usize);
        for p in 1..m {
            acc = acc.union(boxes[used[p - 1]]);
            n += count[used[p - 1]];
            let cost = acc.area() * n as f32 + right_cost[p];
            if best.is_none_or(|b| cost < b.cost) {
                best = Some(Plane {
                    axis,
                    bin: used[p - 1] + 1,
                    cost,
                    lo: lo[axis],
                    scale: scale[axis],
                    bins,
                });
            }
        }
    }
    best
}

/// Moves the elements satisfying `left` to the front (Hoare's two-index scheme); returns how many there are.
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> usize {
    let (mut i, mut j) = (0, refs.len());
    loop {
        while i < j && left(&refs[i]) {
            i += 1;
        }
        while i < j && !left(&refs[j - 1]) {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        refs.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}

/// A segment's [`Polygon`]: its control polygon after two levels of [`subdivide`], computed directly. The
/// quarter spans [`subdivide`] makes share their points (span k is points k..k + 4 here, each computed by the
/// same operations on the same operands, so bit for bit the same): two levels of the recursion compute 15 points
/// and hand out 16 where the spans have 7.
pub(super) fn polygon(strands: &Strands, segment: u32) -> Polygon {
    let first = strands.segment_first[segment as usize] as usize;
    let p: [Vec4; 4] = std::array::from_fn(|i| Vec4::from_array(strands.control_points[first + i]));
    let e = |a: Vec4, b: Vec4| 0.5 * (a + b);
    let v = |a: Vec4, b: Vec4, c: Vec4| 0.125 * (a + 6.0 * b + c);
    // Level 1: E₀ V₁ E₁ V₂ E₂; level 2 refines that five-point polygon the same way.
    let (e0, v1, e1, v2, e2) = (
        e(p[0], p[1]),
        v(p[0], p[1], p[2]),
        e(p[1], p[2]),
        v(p[1], p[2], p[3]),
        e(p[2], p[3]),
    );
    [
        e(e0, v1),
        v(e0, v1, e1),
        e(v1, e1),
        v(v1, e1, v2),
        e(e1, v2),
        v(e1, v2, e2),
        e(v2, e2),
    ]
}

/// An orthonormal frame whose third axis is `axis` (a unit vector), as the rows of a rotation.
fn frame(axis: Vec3) -> [Vec3; 3] {
    let (x, y) = axis.any_orthonormal_pair();
    [x, y, axis]
}

/// The box of `polygon` in `frame` (coordinates along the frame's axes), each point inflated by its radius.
fn frame_box(polygon: &Polygon, frame: &[Vec3; 3]) -> Aabb {
    polygon.iter().fold(Aabb::EMPTY, |b, q| {
        let x = q.truncate();
        let p = Vec3::new(frame[0].dot(x), frame[1].dot(x), frame[2].dot(x));
        let r = Vec3::splat(q.w.abs());
        b.union(Aabb {
            lo: p - r,
            hi: p + r,
        })
    })
}

/// A segment's direction: the unit vector from its first to its last refined point, or zero.
fn direction(polygon: &Polygon) -> Vec3 {
    (polygon[6] - polygon[0]).truncate().normalize_or_zero()
}

/// How an oriented split sends each primitive (by position in the node's slice) left or right.
struct OrientedChoice {
    cost: f32,
    left: Vec<bool>,
}

/// Woop et al. 2014's splits in oriented space, which Embree's hair builder (`bvh_builder_hair.h`) tries beside
/// the aligned binned SAH and keeps when cheaper: an **object split in the node's frame** (binned SAH over the
/// primitives' boxes in a frame whose third axis is their mean direction, each direction counted with the sign
/// that agrees with the sum so far, as [`super::wide`]'s oriented boxes), and a **strand split** (Embree's
/// `heuristic_strand_array.h`: the first primitive's direction and the direction least parallel to it; each
/// primitive goes with the one it is more parallel to, each side bounded in its own direction's frame). Costs are
/// SAH with the oriented boxes' areas (traversal [`ORIENTED_TRAVERSAL`] against [`ALIGNED_TRAVERSAL`]); the
/// collapse to wide nodes bounds the children of an oriented split in their own oriented frames where that is
/// tighter. Returns the split's `mid` after partitioning `refs` when an oriented split is cheaper than the aligned
/// one of cost `aligned_cost` (A_L N_L + A_R N_R, over the node's surface area `area`), or `None`.
fn oriented_split(
    refs: &mut [PrimRef],
    area: f32,
    aligned_cost: f32,
    cx: &Context,
) -> Option<usize> {
    let n = refs.len();
    // Two primitives have one partition, whatever the frame.
    if cx.polygons.is_empty() || n <= 2 || n > ORIENTED_SPLIT_MAX {
        return None;
    }
    let polygon = |r: &PrimRef| &cx.polygons[r.segment as usize];
    let mut best: Option<OrientedChoice> = None;
    let mut best_cost = aligned_cost + ALIGNED_TRAVERSAL * area;
    let mut consider = |choice: OrientedChoice| {
        if choice.cost < best_cost {
            best_cost = choice.cost;
            best = Some(choice);
        }
    };
    // Object split in the node's mean-direction frame.
    let mut sum = Vec3::ZERO;
    for r in refs.iter() {
        let d = direction(polygon(r));
        sum += if d.dot(sum) < 0.0 { -d } else { d };
    }
    if let Some(axis) = sum.try_normalize() {
        let f = frame(axis);
        let boxes: Vec<Aabb> = refs.iter().map(|r| frame_box(polygon(r), &f)).collect();
        let centroids = boxes.iter().fold(Aabb::EMPTY, |c, b| {
            let m = b.centroid();
            c.union(Aabb { lo: m, hi: m })
        });
        if let Some(plane) = best_plane(boxes.iter().copied(), &centroids, cx.options.bins) {
            consider(OrientedChoice {
                cost: plane.cost + ORIENTED_TRAVERSAL * area,
                left: boxes
                    .iter()
                    .map(|b| {
                        let c = b.centroid()[plane.axis];
                        bin_index(c, plane.lo, plane.scale, plane.bins) < plane.bin
                    })
                    .collect(),
            });
        }
    }
    // Strand split: two direction clusters.
    let directions: Vec<Vec3> = refs.iter().map(|r| direction(polygon(r))).collect();
    if let Some(&axis0) = directions.iter().find(|d| **d != Vec3::ZERO) {
        let axis1 = directions
            .iter()
            .filter(|d| **d != Vec3::ZERO)
            .min_by(|a, b| a.dot(axis0).abs().total_cmp(&b.dot(axis0).abs()))
            .copied()
            .unwrap_or(axis0);
        let left: Vec<bool> = directions
            .iter()
            .map(|d| d.dot(axis0).abs() > d.dot(axis1).abs())
            .collect();
        let (f0, f1) = (frame(axis0), frame(axis1));
        let (mut lb, mut rb, mut ln) = (Aabb::EMPTY, Aabb::EMPTY, 0usize);
        for (r, &l) in refs.iter().zip(&left) {
            if l {
                lb = lb.union(frame_box(polygon(r), &f0));
                ln += 1;
            } else {
                rb = rb.union(frame_box(polygon(r), &f1));
            }
        }
        if ln > 0 && ln < n {
            consider(OrientedChoice {
                cost: lb.area() * ln as f32
                    + rb.area() * (n - ln) as f32
                    + ORIENTED_TRAVERSAL * area,
                left,
            });
        }
    }
    let mut choice = best?;
    let mid = partition_marked(refs, &mut choice.left);
    (mid > 0 && mid < n).then_some(mid)
}

/// [`partition`] by a mark per element (`left[i]` for `refs[i]`), the marks moved along with the elements.
fn partition_marked(refs: &mut [PrimRef], left: &mut [bool]) -> usize {
    let (mut i, mut j) = (0, refs.len());
    loop {
        while i < j && left[i] {
            i += 1;
        }
        while i < j && !left[j - 1] {
            j -= 1;
        }
        if i >= j {
            return i;
        }
        refs.swap(i, j - 1);
        left.swap(i, j - 1);
        i += 1;
        j -= 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::util::hash::{hash64, unit_f32};

    /// The sweep over every bin boundary (Wald 2007 as written), the reference for [`best_plane`]'s sweep over
    /// non-empty bins: (axis, cost, which boxes go left).
    fn every_bin(boxes: &[Aabb], centroids: &Aabb, bins: usize) -> Option<(usize, f32, Vec<bool>)> {
        let (lo, hi) = (centroids.lo, centroids.hi);
        let mut best: Option<(usize, usize, f32, f32, f32)> = None;
        for axis in 0..3 {
            if hi[axis] <= lo[axis] {
                continue;
            }
            let scale = bins as f32 * (1.0 - 1e-6) / (hi[axis] - lo[axis]);
            let bin = |b: &Aabb| bin_index(b.centroid()[axis], lo[axis], scale, bins);
            let mut count = vec![0usize; bins];
            let mut acc_box = vec![Aabb::EMPTY; bins];
            for b in boxes {
                count[bin(b)] += 1;
                acc_box[bin(b)] = acc_box[bin(b)].union(*b);
            }
            for i in 1..bins {
                let (mut l, mut r) = (Aabb::EMPTY, Aabb::EMPTY);
                let (mut nl, mut nr) = (0, 0);
                for k in 0..bins {
                    if k < i {
                        l = l.union(acc_box[k]);
                        nl += count[k];
                    } else {
                        r = r.union(acc_box[k]);
                        nr += count[k];
                    }
                }
                if nl == 0 || nr == 0 {
                    continue;
                }
                let cost = l.area() * nl as f32 + r.area() * nr as f32;
                if best.is_none_or(|b| cost < b.2) {
                    best = Some((axis, i, cost, lo[axis], scale));
                }
            }
        }
        best.map(|(axis, i, cost, lo, scale)| {
            let left = boxes
                .iter()
                .map(|b| bin_index(b.centroid()[axis], lo, scale, bins) < i)
                .collect();
            (axis, cost, left)
        })
    }

    #[test]
    fn sweeping_non_empty_bins_chooses_the_plane_a_sweep_of_every_bin_does() {
        let mut compared = 0;
        for case in 0..400u64 {
            let n = 2 + (hash64(case) % 40) as usize;
            // Clusters, so that most bins are empty, and some coincident centroids.
            let clusters = 1 + (hash64(case ^ 0x55) % 4) as usize;
            let boxes: Vec<Aabb> = (0..n)
                .map(|i| {
                    let k = (i % clusters) as u64;
                    let u = |d: u64| unit_f32(hash64(case * 1000 + i as u64 * 7 + d));
                    let c = Vec3::new(k as f32 * 10.0, k as f32 * 3.0, 0.0)
                        + Vec3::new(u(1), u(2), u(3)) * if case % 5 == 0 { 0.0 } else { 1.0 };
                    let h = Vec3::new(u(4), u(5), u(6)) * 0.5;
                    Aabb {
                        lo: c - h,
                        hi: c + h,
                    }
                })
                .collect();
            let centroids = boxes.iter().fold(Aabb::EMPTY, |c, b| {
                let m = b.centroid();
                c.union(Aabb { lo: m, hi: m })
            });
            for bins in [2, 7, 16, 32] {
                let want = every_bin(&boxes, &centroids, bins);
                let got = best_plane(boxes.iter().copied(), &centroids, bins).map(|p| {
                    let left = boxes
                        .iter()
                        .map(|b| bin_index(b.centroid()[p.axis], p.lo, p.scale, p.bins) < p.bin)
                        .collect::<Vec<_>>();
                    (p.axis, p.cost, left)
                });
                assert_eq!(
                    got.as_ref().map(|g| (g.0, g.1.to_bits(), &g.2)),
                    want.as_ref().map(|w| (w.0, w.1.to_bits(), &w.2)),
                    "case {case}, {n} boxes, {bins} bins"
                );
                compared += usize::from(want.is_some());
            }
        }
        assert!(compared > 1000, "only {compared} cases had a plane");
    }
}

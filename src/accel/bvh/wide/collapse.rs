//! How the 4-wide tree is made from the binary build: each wide node takes as lanes the cover of its binary
//! node's children by at most four subtrees that costs least (the sum of the wide nodes' surface areas,
//! [`Covers`]), and a node whose children's oriented boxes are tighter becomes an oriented node (see the parent
//! module). The build's few top-level nodes open their largest child first instead (Embree's and pbrt's collapse).
//!
//! **Least-cost covers against opening the largest child first** (one segment per leaf): opening the largest
//! child leaves a node of two or three lanes wherever a subtree of two or three segments ends. The least-cost
//! cover packs them: on the fur ball (`cuticle bench trace scenes/furball.toml --threads 1 --repetitions 3`, two
//! interleaved runs each) 192.0 → 170.3 bytes per segment (Embree 142.6), and the BVH ÷ Embree time per ray the
//! same within the runs' spread (round camera 1.77 / 1.83 → 1.83 / 1.73, secondary 1.27 / 1.31 → 1.15 / 1.26,
//! exact shadows 1.13 / 1.13 → 1.29 / 1.07, stochastic 1.10 / 0.98 → 1.10 / 1.03; flat 1.88 / 1.86 → 1.83 / 1.89,
//! 1.78 / 2.04 → 1.79 / 1.98, 1.68 / 1.73 → 1.84 / 1.69, 1.66 / 1.64 → 1.66 / 1.60). Charging each node a
//! constant besides its area (the chunk root's area) packs further, 166.6 bytes per segment, at the same speed: not
//! kept, since it adds a constant that the speed does not ask for.
//!
//! **A lean build** ([`build()`]): the binary tree of the whole model never exists. The build's parallel top levels
//! hand each subtree of fewer than `PARALLEL_MIN` primitives to the collapse on the thread that built it (its
//! binary nodes are then freed), which appends the subtree's wide nodes to the shared arrays; the few top-level
//! binary nodes are collapsed last. Each child's oriented box is computed once, when its lane is made. The peak is
//! then the primitive references, the wide nodes and the leaf entries, where collapsing a finished binary tree held
//! the binary nodes and an oriented box per binary node besides (`cuticle bench build --strands 100000 --curves
//! round --embree-layout fast`, numbers in the commit and docs/measured/).
//!
//! **Where a chunk lands**: chunks append their nodes in the order they finish, so the node arrays' order depends
//! on the threads, while the tree (every node's boxes, children and leaf entries) does not: a walk visits the same
//! nodes in the same order, and the images are the same, for any thread count (tested). Putting chunks in a fixed
//! order would copy every node once more and hold the copies together with the originals, which is the peak this
//! build removes.

use std::sync::Mutex;

use arrayvec::ArrayVec;
use glam::Vec3;

use super::{Boxes4, Child, Links, Obb, Obbs4, WideBvh, WideNode, OBB_AREA, OBB_MAX, ORIENTED};
use crate::accel::bvh::build::{self, Chunk, Top};
use crate::accel::bvh::{Aabb, BuildOptions, Bvh, Node};
use crate::hair::Strands;

/// Wide nodes by kind; a child's index is into the array of its kind.
#[derive(Debug, Default)]
pub(super) struct Nodes {
    pub(super) aligned: Vec<WideNode<Boxes4>>,
    pub(super) oriented: Vec<WideNode<Obbs4>>,
}

impl Nodes {
    /// Appends `other`, whose children index its own arrays, and returns where its child `root` now is.
    fn append(&mut self, other: Nodes, root: Child) -> Child {
        let (aligned, oriented) = (self.aligned.len() as u32, self.oriented.len() as u32);
        self.aligned
            .extend(shifted(other.aligned, aligned, oriented));
        self.oriented
            .extend(shifted(other.oriented, aligned, oriented));
        root.shifted(aligned, oriented)
    }

    /// Makes the node over `lanes` (oriented where its children's oriented boxes are tighter, see
    /// [`OBB_AREA`]) and returns it as a child.
    fn push<S: Iterator<Item = u32> + Clone>(
        &mut self,
        lanes: &[Lane<S>],
        strands: &Strands,
    ) -> Child {
        let obbs: ArrayVec<Option<Obb>, 4> = lanes
            .iter()
            .map(|l| {
                (l.count <= OBB_MAX)
                    .then(|| Obb::oriented(strands, l.segments.clone()))
                    .flatten()
            })
            .collect();
        let aligned_area: f32 = lanes.iter().map(|l| l.bounds.area()).sum();
        let oriented_area: f32 = lanes
            .iter()
            .zip(&obbs)
            .map(|(l, o)| o.map_or(l.bounds.area(), |o| o.area().min(l.bounds.area())))
            .sum();
        let children: ArrayVec<Child, 4> = lanes.iter().map(|l| l.child).collect();
        let links = Links::new(&children);
        if oriented_area < OBB_AREA * aligned_area {
            let boxes: ArrayVec<Obb, 4> = lanes
                .iter()
                .zip(&obbs)
                .map(|(l, o)| {
                    let aligned = Obb::aligned(&l.bounds);
                    match o {
                        Some(o) if o.area() < aligned.area() => *o,
                        _ => aligned,
                    }
                })
                .collect();
            self.oriented.push(WideNode {
                boxes: Obbs4::new(&boxes),
                links,
            });
            return Child {
                index: self.oriented.len() as u32 - 1,
                count: ORIENTED,
            };
        }
        let mut boxes = Boxes4::EMPTY;
        for (lane, l) in lanes.iter().enumerate() {
            boxes.set(lane, l.bounds.lo, l.bounds.hi);
        }
        self.aligned.push(WideNode { boxes, links });
        Child {
            index: self.aligned.len() as u32 - 1,
            count: 0,
        }
    }
}

/// `nodes` with their inner children moved by `aligned` or `oriented` (by kind).
fn shifted<B>(
    nodes: Vec<WideNode<B>>,
    aligned: u32,
    oriented: u32,
) -> impl Iterator<Item = WideNode<B>> {
    nodes.into_iter().map(move |mut n| {
        n.links = n.links.shifted(aligned, oriented);
        n
    })
}

/// A lane of a node being made: the child's aligned box, how many leaf entries are below it and their segments
/// (for its oriented box), and the child itself.
struct Lane<S> {
    bounds: Aabb,
    count: u32,
    segments: S,
    child: Child,
}

/// Opens `first` and `second` (children of one node of the top levels) until there are four or none can be opened, largest surface
/// area first (the last of equal ones), as the entries `open` says: `Some((a, b))` for one that opens into `a`
/// and `b`.
fn open_lanes<T: Copy>(
    first: T,
    second: T,
    area: impl Fn(T) -> f32,
    open: impl Fn(T) -> Option<(T, T)>,
) -> ArrayVec<T, 4> {
    let mut lanes = ArrayVec::<T, 4>::new();
    lanes.push(first);
    lanes.push(second);
    while !lanes.is_full() {
        let Some(k) = lanes
            .iter()
            .enumerate()
            .filter(|(_, &c)| open(c).is_some())
            .max_by(|(_, &a), (_, &b)| area(a).total_cmp(&area(b)))
            .map(|(k, _)| k)
        else {
            break;
        };
        let (a, b) = open(lanes[k]).expect("filtered");
        lanes[k] = a;
        lanes.insert(k + 1, b);
    }
    lanes
}

/// The covers of binary subtrees by wide lanes of least cost (Ylitie, Karras & Laine 2017's collapse by dynamic
/// programming, for 4-wide nodes): the cost of a tree is the sum of its wide nodes' surface areas, proportional
/// to how often a ray visits them (the SAH; leaf tests are the same for every cover, so they do not count).
/// For binary node m, `cost[m]` holds
/// - `[0]`: m as one lane, L(m) = 0 for a leaf, A(m) + D(m, 4) for an inner node (a wide node of its own);
/// - `[k − 1]`, k = 2…4: D(m, k), the least cost of m's two children in at most k lanes:
///   min over j of C(left, j) + C(right, k − j), where C(c, j) = L(c), or D(c, j) when c is opened (j ≥ 2).
///
/// Opening the largest child first (the greedy collapse of the top levels) leaves nodes of two or three lanes
/// where a subtree of two or three leaves ends; the least-cost cover packs such leaves into their parent's lanes
/// where that saves a node.
pub(super) struct Covers {
    cost: Vec<[f32; 4]>,
}

impl Covers {
    /// The costs of every subtree of `binary` (depth first: children after their parent).
    pub(super) fn new(binary: &[Node]) -> Covers {
        let mut cost = vec![[0.0f32; 4]; binary.len()];
        for m in (0..binary.len()).rev() {
            let node = &binary[m];
            if node.is_leaf() {
                continue;
            }
            let (l, r) = (m + 1, node.offset as usize);
            let c = |cost: &[[f32; 4]], child: usize, j: usize| lane_or_open(&cost[child], j);
            let mut entry = [0.0f32; 4];
            for k in 2..=4 {
                entry[k - 1] = (1..k)
                    .map(|j| c(&cost, l, j) + c(&cost, r, k - j))
                    .fold(f32::INFINITY, f32::min);
            }
            entry[0] = node.bounds().area() + entry[3];
            cost[m] = entry;
        }
        Covers { cost }
    }

    /// The lanes of binary inner node `i`'s wide node: the children's least-cost cover by at most four.
    fn lanes(&self, binary: &[Node], i: usize) -> ArrayVec<usize, 4> {
        let mut out = ArrayVec::new();
        self.open(binary, i, 4, &mut out);
        out
    }

    /// Appends the cover of inner node `m`'s children by at most `k` lanes.
    fn open(&self, binary: &[Node], m: usize, k: usize, out: &mut ArrayVec<usize, 4>) {
        let (l, r) = (m + 1, binary[m].offset as usize);
        let split = |j: usize| lane_or_open(&self.cost[l], j) + lane_or_open(&self.cost[r], k - j);
        // The first j of least cost: the same choice as the table's minimum.
        let j = (1..k)
            .min_by(|&a, &b| split(a).total_cmp(&split(b)))
            .expect("k >= 2");
        self.cover(binary, l, j, out);
        self.cover(binary, r, k - j, out);
    }

    /// Appends the cover of subtree `c` by at most `j` lanes: `c` itself, or its children when opening it costs
    /// no more.
    fn cover(&self, binary: &[Node], c: usize, j: usize, out: &mut ArrayVec<usize, 4>) {
        if j >= 2 && !binary[c].is_leaf() && self.cost[c][j - 1] <= self.cost[c][0] {
            self.open(binary, c, j, out);
        } else {
            out.push(c);
        }
    }
}

/// C(c, j): subtree `c` (costs `cost`) in at most `j` lanes, opened when that is cheaper (a leaf's entries are
/// all 0: it takes one lane and costs nothing).
fn lane_or_open(cost: &[f32; 4], j: usize) -> f32 {
    if j >= 2 {
        cost[0].min(cost[j - 1])
    } else {
        cost[0]
    }
}

/// The wide child for binary node `i` of `binary` (a whole tree or a [`Chunk`]'s nodes: leaf offsets index the
/// whole leaf-entry array), appending the wide nodes below it to `out` depth first, children before their node.
/// `segments(first, count)` gives the segments of leaf entries `first..first + count`.
fn collapse<S: Iterator<Item = u32> + Clone>(
    out: &mut Nodes,
    binary: &[Node],
    covers: &impl Fn(usize) -> ArrayVec<usize, 4>,
    i: usize,
    strands: &Strands,
    segments: &impl Fn(u32, u32) -> S,
) -> Child {
    let node = &binary[i];
    if node.is_leaf() {
        return Child {
            index: node.offset,
            count: node.count,
        };
    }
    let mut lanes = ArrayVec::<Lane<S>, 4>::new();
    for c in covers(i) {
        let (first, count) = range(binary, c);
        lanes.push(Lane {
            bounds: binary[c].bounds(),
            count,
            segments: segments(first, count),
            child: collapse(out, binary, covers, c, strands, segments),
        });
    }
    out.push(&lanes, strands)
}

/// First leaf entry and number of entries below binary node `i` (a subtree's entries are contiguous).
fn range(binary: &[Node], i: usize) -> (u32, u32) {
    let mut lo = i;
    while !binary[lo].is_leaf() {
        lo += 1;
    }
    let mut hi = i;
    while !binary[hi].is_leaf() {
        hi = binary[hi].offset as usize;
    }
    let first = binary[lo].offset;
    (first, binary[hi].offset + binary[hi].count - first)
}

/// The wide child for a node of the build's top levels, whose chunks are already collapsed (their value is their
/// root); `segments` are all leaf entries' segment ids.
fn collapse_top(out: &mut Nodes, top: &Top<Child>, strands: &Strands, segments: &[u32]) -> Child {
    let children = match top {
        Top::Chunk { value, .. } => return *value,
        Top::Inner { children, .. } => children,
    };
    let open = open_lanes(
        &children[0],
        &children[1],
        |c| c.bounds().area(),
        |c| match c {
            Top::Inner { children, .. } => Some((&children[0], &children[1])),
            Top::Chunk { .. } => None,
        },
    );
    let mut lanes = ArrayVec::<Lane<_>, 4>::new();
    for c in open {
        let (first, count) = c.range();
        lanes.push(Lane {
            bounds: c.bounds(),
            count,
            segments: segments[first as usize..(first + count) as usize]
                .iter()
                .copied(),
            child: collapse_top(out, c, strands, segments),
        });
    }
    out.push(&lanes, strands)
}

/// The wide tree over the segments of `strands`, built without the whole binary tree (see the module docs).
pub(super) fn build(strands: &Strands, options: BuildOptions) -> WideBvh {
    let shared = Mutex::new(Nodes::default());
    let (top, order) = build::build_top(strands, options, &|chunk: Chunk| {
        let mut local = Nodes::default();
        let covers = Covers::new(&chunk.nodes);
        let covers = |i: usize| covers.lanes(&chunk.nodes, i);
        let root = collapse(
            &mut local,
            &chunk.nodes,
            &covers,
            0,
            strands,
            &|first, count| chunk.segments(first, count),
        );
        drop(chunk);
        shared
            .lock()
            .expect("no collapse panicked holding the node arrays")
            .append(local, root)
    });
    let mut nodes = shared.into_inner().expect("no collapse panicked");
    let root = top.map(|top| {
        let child = collapse_top(&mut nodes, &top, strands, &order);
        (child, top.bounds())
    });
    WideBvh::assemble(nodes, root, &order, strands)
}

/// The wide tree of a finished binary tree `bvh` over `strands` (the tests' reference for [`build()`]).
pub(super) fn from_binary(bvh: &Bvh, strands: &Strands) -> WideBvh {
    let mut nodes = Nodes::default();
    let segments = bvh.primitives();
    let root = bvh.nodes().first().map(|top| {
        let covers = Covers::new(bvh.nodes());
        let covers = |i: usize| covers.lanes(bvh.nodes(), i);
        let child = collapse(
            &mut nodes,
            bvh.nodes(),
            &covers,
            0,
            strands,
            &|first, count| {
                segments[first as usize..(first + count) as usize]
                    .iter()
                    .copied()
            },
        );
        (child, top.bounds())
    });
    WideBvh::assemble(nodes, root, segments, strands)
}

impl Obb {
    /// The aligned box `b` as an oriented one (identity frame), padded for rounding as [`Obb::around`] pads.
    fn aligned(b: &Aabb) -> Obb {
        Obb {
            centre: b.centroid(),
            axes: [Vec3::X, Vec3::Y, Vec3::Z],
            half: 0.5 * (b.hi - b.lo)
                + Vec3::splat(1e-5 * b.lo.abs().max(b.hi.abs()).max_element() + f32::MIN_POSITIVE),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The greedy collapse's lanes for binary inner node `i` (largest surface area opened first).
    fn greedy(binary: &[Node], i: usize) -> ArrayVec<usize, 4> {
        open_lanes(
            i + 1,
            binary[i].offset as usize,
            |c| binary[c].bounds().area(),
            |c| (!binary[c].is_leaf()).then(|| (c + 1, binary[c].offset as usize)),
        )
    }

    /// The cost (sum of the wide nodes' areas, in f64) and node count of the subtree under binary node `i` when
    /// every wide node takes the lanes `lanes` gives.
    fn cost(
        binary: &[Node],
        i: usize,
        lanes: &dyn Fn(usize) -> ArrayVec<usize, 4>,
    ) -> (f64, usize) {
        if binary[i].is_leaf() {
            return (0.0, 0);
        }
        lanes(i)
            .into_iter()
            .fold((f64::from(binary[i].bounds().area()), 1), |(c, n), lane| {
                let (cl, nl) = cost(binary, lane, lanes);
                (c + cl, n + nl)
            })
    }

    /// Every cover of inner node `m`'s children by at most `k` lanes, enumerated.
    fn all_covers(binary: &[Node], m: usize, k: usize) -> Vec<Vec<usize>> {
        let (l, r) = (m + 1, binary[m].offset as usize);
        let of = |c: usize, j: usize| -> Vec<Vec<usize>> {
            let mut out = vec![vec![c]];
            if j >= 2 && !binary[c].is_leaf() {
                out.extend(all_covers(binary, c, j));
            }
            out
        };
        let mut out = Vec::new();
        for j in 1..k {
            for a in of(l, j) {
                for b in of(r, k - j) {
                    out.push([a.clone(), b].concat());
                }
            }
        }
        out
    }

    /// The least cost of the subtree under `i` over every cover at every node, by enumeration.
    fn brute_force(binary: &[Node], i: usize) -> f64 {
        if binary[i].is_leaf() {
            return 0.0;
        }
        let best = all_covers(binary, i, 4)
            .into_iter()
            .map(|lanes| lanes.iter().map(|&c| brute_force(binary, c)).sum::<f64>())
            .fold(f64::INFINITY, f64::min);
        f64::from(binary[i].bounds().area()) + best
    }

    fn groom(strands: u32, points: u32) -> Strands {
        let model =
            crate::hair::procedural::Procedural::FurBall(crate::hair::procedural::FurBall {
                strands,
                points,
                ..Default::default()
            })
            .generate()
            .expect("fur ball");
        Strands::from_model(&model)
    }

    #[test]
    fn the_least_cost_cover_is_the_best_of_every_cover() {
        for seed_strands in [3, 5, 8] {
            let strands = groom(seed_strands, 5);
            let bvh = Bvh::build(&strands, BuildOptions::default());
            let b = bvh.nodes();
            let covers = Covers::new(b);
            let want = brute_force(b, 0);
            let (got, _) = cost(b, 0, &|i| covers.lanes(b, i));
            assert!(
                (got - want).abs() <= 1e-5 * want,
                "{seed_strands} strands: the cover costs {got}, the best of all covers {want}"
            );
            assert!((f64::from(covers.cost[0][0]) - got).abs() <= 1e-4 * got);
        }
    }

    #[test]
    fn the_least_cost_cover_beats_opening_the_largest_child_first_on_the_fur_ball() {
        let strands = groom(2000, 16);
        let bvh = Bvh::build(&strands, BuildOptions::default());
        let b = bvh.nodes();
        let covers = Covers::new(b);
        let (least, nodes) = cost(b, 0, &|i| covers.lanes(b, i));
        let (greedy, greedy_nodes) = cost(b, 0, &|i| greedy(b, i));
        // Never costlier (it is the least over every cover, which the greedy one is); measured 0.991 of the
        // greedy cost in 0.862 of its nodes (12 804 against 14 861, 30 000 segments).
        assert!(
            least <= greedy && nodes < greedy_nodes * 90 / 100,
            "least-cost cover {least} in {nodes} nodes, greedy {greedy} in {greedy_nodes}"
        );
    }
}

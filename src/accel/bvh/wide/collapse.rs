//! How the 4-wide tree is made from the binary build: each binary inner node's children are opened, largest
//! surface area first, until a node has four (Embree's and pbrt's collapse), and a node whose children's oriented
//! boxes are tighter becomes an oriented node (see the parent module).
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

use super::{Boxes4, Child, Obb, Obbs4, WideBvh, WideNode, OBB_AREA, OBB_MAX, ORIENTED};
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
        let shift = move |c: Child| match c.count {
            0 => Child {
                index: c.index + aligned,
                count: 0,
            },
            ORIENTED => Child {
                index: c.index + oriented,
                count: ORIENTED,
            },
            _ => c,
        };
        self.aligned.extend(shifted(other.aligned, shift));
        self.oriented.extend(shifted(other.oriented, shift));
        shift(root)
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
        let mut children = [Child { index: 0, count: 0 }; 4];
        for (lane, l) in lanes.iter().enumerate() {
            children[lane] = l.child;
        }
        let valid = (1 << lanes.len()) - 1;
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
                children,
                valid,
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
        self.aligned.push(WideNode {
            boxes,
            children,
            valid,
        });
        Child {
            index: self.aligned.len() as u32 - 1,
            count: 0,
        }
    }
}

/// `nodes` with each child moved by `shift`.
fn shifted<B>(
    nodes: Vec<WideNode<B>>,
    shift: impl Fn(Child) -> Child,
) -> impl Iterator<Item = WideNode<B>> {
    nodes.into_iter().map(move |mut n| {
        n.children = n.children.map(&shift);
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

/// Opens `first` and `second` (children of one node) until there are four or none can be opened, largest surface
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

/// The wide child for binary node `i` of `binary` (a whole tree or a [`Chunk`]'s nodes: leaf offsets index the
/// whole leaf-entry array), appending the wide nodes below it to `out` depth first, children before their node.
/// `segments(first, count)` gives the segments of leaf entries `first..first + count`.
fn collapse<S: Iterator<Item = u32> + Clone>(
    out: &mut Nodes,
    binary: &[Node],
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
    let open = open_lanes(
        i + 1,
        node.offset as usize,
        |c| binary[c].bounds().area(),
        |c| (!binary[c].is_leaf()).then(|| (c + 1, binary[c].offset as usize)),
    );
    let mut lanes = ArrayVec::<Lane<S>, 4>::new();
    for &c in &open {
        let (first, count) = range(binary, c);
        lanes.push(Lane {
            bounds: binary[c].bounds(),
            count,
            segments: segments(first, count),
            child: collapse(out, binary, c, strands, segments),
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
        let root = collapse(&mut local, &chunk.nodes, 0, strands, &|first, count| {
            chunk.segments(first, count)
        });
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
        let child = collapse(&mut nodes, bvh.nodes(), 0, strands, &|first, count| {
            segments[first as usize..(first + count) as usize]
                .iter()
                .copied()
        });
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

//! What the tests check of a wide tree: that every lane's box holds the segments below it, and the tree's shape
//! independent of where its nodes are stored; and the oriented lanes' boxes against random frames.

use glam::{Vec3, Vec4};

use super::*;

impl WideBvh {
    /// The tree as words, depth first from the root: per inner node its kind, valid lanes and boxes' bits, then
    /// its children; per leaf its first entry and count; then every leaf entry. Two trees that differ only in
    /// where their nodes are stored have the same shape.
    pub fn shape(&self) -> Vec<u32> {
        let mut out = Vec::new();
        if let Some((root, root_box)) = self.root {
            out.extend(
                root_box
                    .lo
                    .iter()
                    .chain(&root_box.hi)
                    .flat_map(|v| v.to_array().map(f32::to_bits)),
            );
            self.shape_of(root, &mut out);
        }
        for p in &self.primitives {
            out.extend(p.control_points.iter().flatten().map(|x| x.to_bits()));
            out.extend([p.segment, p.strand, p.opacity.to_bits()]);
        }
        out
    }

    fn shape_of(&self, child: Child, out: &mut Vec<u32>) {
        let words = |v: &[Vec4]| -> Vec<u32> {
            v.iter()
                .flat_map(|v| v.to_array().map(f32::to_bits))
                .collect()
        };
        let (children, valid) = match child.count {
            0 => {
                let n = &self.nodes[child.index as usize];
                out.push(0);
                out.extend(words(&n.boxes.lo));
                out.extend(words(&n.boxes.hi));
                (n.links.children(), n.links.valid())
            }
            ORIENTED => {
                let n = &self.oriented[child.index as usize];
                out.push(1);
                for row in &n.boxes.m {
                    out.extend(words(row));
                }
                out.extend(words(&n.boxes.t));
                (n.links.children(), n.links.valid())
            }
            count => {
                out.extend([2, child.index, count]);
                return;
            }
        };
        out.push(valid);
        for (lane, &below) in children.iter().enumerate() {
            if valid & (1 << lane) != 0 {
                self.shape_of(below, out);
            }
        }
    }

    /// Asserts that every lane's box, aligned or oriented, holds the eighth spans of every segment below it
    /// (their control points, each inflated by its radius), up to 10⁻⁵ of the coordinates' scale: the culling is
    /// conservative, and the walk can only skip segments the ray cannot hit. `whole_segments: false` (a tree
    /// whose leaves reference spans, [`super::Bounding::SpanRefs`]) checks nothing, since a lane's aligned box
    /// holds only the spans referenced below it.
    pub fn check_bounds(&self, strands: &Strands, whole_segments: bool) {
        let Some((root, _)) = self.root else {
            return;
        };
        self.check_child(root, strands, whole_segments);
    }

    /// The segments below `child`, after checking the boxes of its inner nodes.
    fn check_child(&self, child: Child, strands: &Strands, whole_segments: bool) -> Vec<u32> {
        let (children, valid) = match child.count {
            0 => {
                let n = &self.nodes[child.index as usize];
                (n.links.children(), n.links.valid())
            }
            ORIENTED => {
                let n = &self.oriented[child.index as usize];
                (n.links.children(), n.links.valid())
            }
            count => {
                let first = child.index as usize;
                return self.primitives[first..first + count as usize]
                    .iter()
                    .map(|p| p.segment)
                    .collect();
            }
        };
        let mut all = Vec::new();
        for (lane, &below) in children.iter().enumerate() {
            if valid & (1 << lane) == 0 {
                continue;
            }
            let segments = self.check_child(below, strands, whole_segments);
            for &s in segments.iter().filter(|_| whole_segments) {
                // Eighth spans: inside the hull of any coarser subdivision, so every box the build can make
                // (segment hull, 2, 4 or 8 spans) and every oriented box (around quarter spans) holds them.
                for_each_span_points(strands, s, 3, |points| {
                    for q in points {
                        let x = q.truncate();
                        let tolerance = 1e-5 * (x.abs().max_element() + q.w.abs()) + 1e-30;
                        assert!(
                            self.lane_holds(child, lane, x, q.w.abs(), tolerance),
                            "segment {s}: point {q} outside its box in lane {lane} of node {child:?}"
                        );
                    }
                });
            }
            all.extend(segments);
        }
        all
    }

    /// Whether lane `lane` of inner node `node` holds the sphere of radius `r` around `x`, up to `tolerance`.
    fn lane_holds(&self, node: Child, lane: usize, x: Vec3, r: f32, tolerance: f32) -> bool {
        if node.count == 0 {
            let b = &self.nodes[node.index as usize].boxes;
            return (0..3).all(|a| {
                x[a] - r >= b.lo[a][lane] - tolerance && x[a] + r <= b.hi[a][lane] + tolerance
            });
        }
        let b = &self.oriented[node.index as usize].boxes;
        (0..3).all(|i| {
            // In the lane's unit cube: the sphere's centre along the row and its radius times the row's length.
            let (row, t) = b.row(lane, i);
            let p = row.dot(x) + t;
            let reach = (r - tolerance) * row.length();
            p - reach >= 0.0 && p + reach <= 1.0
        })
    }
}

#[cfg(test)]
mod oriented_lane_tests {
    use super::*;
    use crate::util::hash::{hash64, unit_f32};
    use crate::util::sampling::uniform_sphere;

    /// Oriented boxes of random frames, sizes (thin and long, as hair) and places, up to `scale` from the origin.
    fn random_obbs(seed: u64, scale: f32) -> Vec<Obb> {
        let mut state = hash64(seed);
        let mut u = || {
            state = hash64(state);
            unit_f32(state)
        };
        (0..4)
            .map(|_| {
                let axis = uniform_sphere(u(), u());
                let (x, y) = axis.any_orthonormal_pair();
                Obb {
                    centre: scale * Vec3::new(u(), u(), u()),
                    axes: [x, y, axis],
                    half: Vec3::new(1e-3 + 1e-2 * u(), 1e-3 + 1e-2 * u(), 0.02 + 0.2 * u()),
                }
            })
            .collect()
    }

    /// Every point of each lane's oriented box (corners and random inner points) lies in the lane's unit cube
    /// once the box is padded as the build pads it ([`Obb::around`]: 10⁻⁵ of the coordinates' scale), and a ray
    /// from 5 scales away through such a point enters the lane no later than the point: the rounding of the map
    /// and of the ray's transform stays inside the padding.
    #[test]
    fn lanes_hold_their_oriented_boxes() {
        for seed in 0..200u64 {
            let scale = [0.1, 1.0, 100.0][seed as usize % 3];
            let obbs = random_obbs(seed, scale);
            let padded: Vec<Obb> = obbs
                .iter()
                .map(|o| {
                    let reach = o.centre.abs().max_element() + o.half.max_element();
                    Obb {
                        half: o.half + Vec3::splat(1e-5 * reach),
                        ..*o
                    }
                })
                .collect();
            let q = Obbs4::new(&padded);
            let mut state = hash64(seed ^ 0x5eed);
            let mut u = || {
                state = hash64(state);
                unit_f32(state)
            };
            for (lane, o) in obbs.iter().enumerate() {
                let mut points: Vec<Vec3> = o.corners().iter().map(|c| c.as_vec3()).collect();
                for _ in 0..16 {
                    let s = Vec3::new(2.0 * u() - 1.0, 2.0 * u() - 1.0, 2.0 * u() - 1.0);
                    points.push(
                        o.centre
                            + o.axes[0] * (s.x * o.half.x)
                            + o.axes[1] * (s.y * o.half.y)
                            + o.axes[2] * (s.z * o.half.z),
                    );
                }
                for p in points {
                    for i in 0..3 {
                        let (row, t) = q.row(lane, i);
                        let x = row.dot(p) + t;
                        assert!(
                            (0.0..=1.0).contains(&x),
                            "seed {seed} lane {lane} row {i}: {x} outside [0, 1]"
                        );
                    }
                    let from = p + 5.0 * scale * uniform_sphere(u(), u());
                    let ray = Ray::new(from, p - from);
                    let (tmin, mask) = q.test(&WideRay::new(&ray));
                    assert!(
                        mask & (1 << lane) != 0 && tmin[lane] <= 1.0,
                        "seed {seed} lane {lane}: ray {ray:?} misses the lane or enters it at {} > 1",
                        tmin[lane]
                    );
                }
            }
        }
    }
}

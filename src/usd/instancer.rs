//! `UsdGeomPointInstancer`: each prototype's curves and meshes read once, in the prototype's own space, then placed
//! at every instance.
//!
//! An instance's transform is the instancer's world transform times `translate(positions[i]) ·
//! rotate(orientations[i]) · scale(scales[i])` (USD's `ComputeInstanceTransformsAtTime` without velocities), and
//! the prototype's own `xformOp`s apply inside it, its ancestors' do not. Instances whose id is in `invisibleIds`
//! are left out (`ids` when authored, else the instance's index). `velocities`, `accelerations` and the time
//! samples of motion are not read: a still frame at the attributes' default values. Cameras and lights inside a
//! prototype are not read.
//!
//! The geometry an instancer makes is counted before it is made: a few kilobytes of positions can place a
//! prototype a million times, so the total points are checked against [`MAX_POINTS`] first.

use std::collections::{BTreeMap, HashSet};

use glam::{DMat4, DQuat, DVec3};
use openusd::usd;

use super::reader::Geometry;
use super::values::{ints, quats, vec3s};
use super::xform::world_radius_scale;
use super::{prim_err, Reader, UsdError, MAX_POINTS};

/// How deep point instancers may nest (an instancer among another's prototypes); deeper is refused as a cycle.
pub(super) const MAX_NESTING: u32 = 8;

impl Reader<'_> {
    /// The instances of the `PointInstancer` `prim` (world transform `world`) added to `geometry`.
    pub(super) fn point_instancer(
        &mut self,
        prim: &usd::Prim,
        world: DMat4,
        geometry: &mut Geometry,
        depth: u32,
    ) -> Result<(), UsdError> {
        let pp = prim.path().clone();
        let bad = |m: String| prim_err(self.path, &pp, m);
        if depth >= MAX_NESTING {
            return Err(bad(format!(
                "point instancers nested more than {MAX_NESTING} deep (a prototype that instances itself?)"
            )));
        }
        let prototypes = prim
            .relationship("prototypes")
            .targets()
            .map_err(|e| bad(format!("prototypes: {e:#}")))?;
        let indices = self
            .get_as(prim, "protoIndices", "an int array", ints)?
            .unwrap_or_default();
        let positions = self
            .get_as(prim, "positions", "a point array", vec3s)?
            .unwrap_or_default();
        let n = indices.len();
        if positions.len() != n {
            return Err(bad(format!(
                "positions has {} values for {n} protoIndices",
                positions.len()
            )));
        }
        let orientations = self.get_as(prim, "orientations", "a quaternion array", quats)?;
        let scales = self.get_as(prim, "scales", "a vector array", vec3s)?;
        for (name, len) in [
            ("orientations", orientations.as_ref().map(Vec::len)),
            ("scales", scales.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len.filter(|&l| l != n) {
                return Err(bad(format!("{name} has {len} values for {n} instances")));
            }
        }
        let ids = self.get_as(prim, "ids", "an int array", ints)?;
        if let Some(len) = ids.as_ref().map(Vec::len).filter(|&l| l != n) {
            return Err(bad(format!("ids has {len} values for {n} instances")));
        }
        let invisible: HashSet<i64> = self
            .get_as(prim, "invisibleIds", "an int array", ints)?
            .unwrap_or_default()
            .into_iter()
            .collect();
        if let Some(i) = indices
            .iter()
            .position(|&k| k < 0 || k as usize >= prototypes.len())
        {
            return Err(bad(format!(
                "protoIndices[{i}] is {}, outside the {} prototypes",
                indices[i],
                prototypes.len()
            )));
        }
        // Each prototype used, read once in its own space.
        let mut read: BTreeMap<usize, Geometry> = BTreeMap::new();
        for &k in &indices {
            let k = k as usize;
            if read.contains_key(&k) {
                continue;
            }
            let target = self.prim_at(&prototypes[k], prim)?;
            if !target
                .is_valid()
                .map_err(|e| bad(format!("prototype {}: {e:#}", prototypes[k])))?
            {
                return Err(bad(format!(
                    "prototype {} is not a prim on the stage",
                    prototypes[k]
                )));
            }
            let mut g = Geometry::default();
            self.walk(target, DMat4::IDENTITY, &mut g, depth + 1)?;
            read.insert(k, g);
        }
        let visible = |i: usize| !invisible.contains(&ids.as_ref().map_or(i as i64, |ids| ids[i]));
        let total: u64 = (0..n)
            .filter(|&i| visible(i))
            .map(|i| {
                let g = &read[&(indices[i] as usize)];
                g.strands.control_points.len() as u64
                    + g.meshes
                        .iter()
                        .map(|m| m.positions.len() as u64)
                        .sum::<u64>()
            })
            .sum();
        if total > MAX_POINTS {
            return Err(bad(format!(
                "{n} instances make {total} points, more than the reader's limit of {MAX_POINTS}"
            )));
        }
        let mut uneven = false;
        for i in (0..n).filter(|&i| visible(i)) {
            let k = indices[i] as usize;
            // The quaternion's rotation formula without normalising it first, as Pixar's library computes instance
            // transforms: a half-precision unit quaternion is up to 1e-3 from unit length, and normalising would
            // move points 1e-4 from where every other USD reader puts them.
            let rotation = orientations.as_ref().map_or(DQuat::IDENTITY, |q| q[i]);
            if rotation.length_squared() < 1e-12 {
                return Err(bad(format!("orientations[{i}] is zero")));
            }
            let scale = scales.as_ref().map_or(DVec3::ONE, |s| s[i].as_dvec3());
            if !(rotation.is_finite() && scale.is_finite() && positions[i].is_finite()) {
                return Err(bad(format!("instance {i}'s transform is not finite")));
            }
            uneven |= (scale.max_element() - scale.min_element()).abs()
                > 1e-6 * scale.max_element().abs();
            let m = world
                * DMat4::from_translation(positions[i].as_dvec3())
                * DMat4::from_quat(rotation)
                * DMat4::from_scale(scale);
            let g = &read[&k];
            if g.strands.strand_count() > 0 {
                // Appended in the prototype's space, then moved in place: no copy per instance.
                let first = geometry.strands.control_points.len();
                geometry.strands.append(&g.strands);
                let r = world_radius_scale(m);
                for c in &mut geometry.strands.control_points[first..] {
                    let p = m.transform_point3(DVec3::new(c[0].into(), c[1].into(), c[2].into()));
                    *c = [p.x as f32, p.y as f32, p.z as f32, c[3] * r];
                }
            }
            for mesh in &g.meshes {
                let mut mesh = mesh.clone().transformed(m.as_mat4());
                mesh.name = format!("{}[{i}]", mesh.name);
                geometry.meshes.push(mesh);
            }
        }
        for g in read.values() {
            geometry.curve_prims.extend(g.curve_prims.iter().cloned());
        }
        if uneven {
            self.warn(
                &pp,
                "instances scaled unevenly: their widths scaled by the mean scale",
            );
        }
        Ok(())
    }
}

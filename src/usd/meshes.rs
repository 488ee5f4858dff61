//! `Mesh` prims as triangle meshes, and the albedo of their `displayColor` or bound `UsdPreviewSurface`.

use glam::{DMat4, Vec3};
use openusd::usd;

use crate::mesh::{fan_triangulate, TriangleMesh};

use super::values::{ints, vec3, vec3s};
use super::MAX_POINTS;
use super::{prim_err, Reader, UsdError};

impl Reader<'_> {
    /// One `Mesh` prim, fanned into triangles, world space.
    pub(super) fn mesh(
        &mut self,
        prim: &usd::Prim,
        world: DMat4,
    ) -> Result<TriangleMesh, UsdError> {
        let pp = prim.path().clone();
        let bad = |m: String| prim_err(self.path, &pp, m);
        let points = self
            .get_as(prim, "points", "a point array", vec3s)?
            .unwrap_or_default();
        let counts = self
            .get_as(prim, "faceVertexCounts", "an int array", ints)?
            .unwrap_or_default();
        let indices = self
            .get_as(prim, "faceVertexIndices", "an int array", ints)?
            .unwrap_or_default();
        if points.len() as u64 > MAX_POINTS {
            return Err(bad(format!(
                "{} points is more than the reader's limit of {MAX_POINTS}",
                points.len()
            )));
        }
        if let Some(i) = counts.iter().position(|&c| c < 0) {
            return Err(bad(format!("faceVertexCounts[{i}] is {}", counts[i])));
        }
        if let Some(i) = indices
            .iter()
            .position(|&x| x < 0 || x as usize >= points.len())
        {
            return Err(bad(format!(
                "faceVertexIndices[{i}] is {}, outside the {} points",
                indices[i],
                points.len()
            )));
        }
        let counts_u: Vec<u32> = counts.iter().map(|&c| c as u32).collect();
        let indices_u: Vec<u32> = indices.iter().map(|&c| c as u32).collect();
        let fan = fan_triangulate(&counts_u, &indices_u).ok_or_else(|| {
            let sum: u64 = counts.iter().map(|&c| c as u64).sum();
            bad(format!(
                "faceVertexCounts add up to {sum} corners but faceVertexIndices has {}",
                indices.len()
            ))
        })?;
        let left = self.token(prim, "orientation", "rightHanded")? == "leftHanded";
        let mut triangles: Vec<[u32; 3]> = fan.iter().map(|t| t.points).collect();
        let expect = |interp: &str| match interp {
            "constant" => Some(1),
            "uniform" => Some(counts.len()),
            "vertex" | "varying" => Some(points.len()),
            "faceVarying" => Some(indices.len()),
            _ => None,
        };
        let mut albedo = Vec3::splat(0.5);
        let mut corner_albedo = None;
        let mut clamped = false;
        let mut clamp = |c: [f32; 3]| {
            let v = Vec3::from_array(c);
            let k = if v.is_nan() {
                Vec3::splat(0.5)
            } else {
                v.clamp(Vec3::ZERO, Vec3::ONE)
            };
            clamped |= k != v;
            k
        };
        if let Some((colors, interp)) = self.primvar3(prim, "primvars:displayColor", &expect)? {
            if interp == "constant" {
                albedo = clamp(colors[0]);
            } else {
                let per: Vec<[Vec3; 3]> = fan
                    .iter()
                    .map(|t| match interp.as_str() {
                        "uniform" => [clamp(colors[t.face as usize]); 3],
                        "faceVarying" => t.corners.map(|i| clamp(colors[i as usize])),
                        _ => t.points.map(|i| clamp(colors[i as usize])),
                    })
                    .collect();
                corner_albedo = Some(per);
            }
        } else if let Some(c) = self.material_color(prim)? {
            albedo = clamp(c);
        } else {
            self.warn(
                &pp,
                "no displayColor and no UsdPreviewSurface diffuseColor: albedo 0.5",
            );
        }
        if clamped {
            self.warn(&pp, "colours outside [0, 1] clamped");
        }
        if left {
            // leftHanded: the file's winding is clockwise; reversing keeps (b − a) × (c − a) the front.
            for t in &mut triangles {
                t.swap(1, 2);
            }
            if let Some(c) = &mut corner_albedo {
                c.iter_mut().for_each(|c| c.swap(1, 2));
            }
        }
        // `subdivisionScheme` other than "none" (catmullClark by default) marks a smooth surface: shaded with
        // smooth normals over its cage (not subdivided).
        let smooth = self.token(prim, "subdivisionScheme", "catmullClark")? != "none";
        let mut mesh = TriangleMesh {
            name: format!("{}:{pp}", self.path.display()),
            positions: points.clone(),
            triangles,
            corner_albedo,
            albedo,
            vertex_normals: None,
        }
        .transformed(world.as_mat4());
        if smooth {
            mesh = mesh.smoothed();
        }
        mesh.validate().map_err(|e| bad(e.message))?;
        Ok(mesh)
    }

    /// The constant `inputs:diffuseColor` of the `UsdPreviewSurface` bound by `material:binding`, if that chain
    /// is there.
    pub(super) fn material_color(
        &mut self,
        prim: &usd::Prim,
    ) -> Result<Option<[f32; 3]>, UsdError> {
        let targets = prim
            .relationship("material:binding")
            .targets()
            .unwrap_or_default();
        let Some(material) = targets.first() else {
            return Ok(None);
        };
        let mat = self.stage.prim(material.clone());
        let outputs = mat
            .attribute("outputs:surface")
            .connections()
            .unwrap_or_default();
        let Some(out) = outputs.first() else {
            return Ok(None);
        };
        let shader = self.stage.prim(out.prim_path());
        let id = self.token(&shader, "info:id", "")?;
        if id != "UsdPreviewSurface" {
            self.warn(
                prim.path(),
                &format!(
                    "bound shader {} is {id:?}, not UsdPreviewSurface: albedo 0.5",
                    shader.path()
                ),
            );
            return Ok(None);
        }
        let connected = !shader
            .attribute("inputs:diffuseColor")
            .connections()
            .unwrap_or_default()
            .is_empty();
        if connected {
            self.warn(
                prim.path(),
                "diffuseColor is connected (a texture?): its constant value, if any, is read",
            );
        }
        Ok(self
            .get_as(&shader, "inputs:diffuseColor", "a colour", vec3)?
            .map(|c| c.as_vec3().to_array()))
    }
}

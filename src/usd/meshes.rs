//! `Mesh` prims as triangle meshes, and the albedo of their `displayColor` or bound `UsdPreviewSurface`.

use glam::{DMat4, Vec3};
use openusd::usd;

use crate::mesh::{fan_triangulate, FanTriangle, MeshTexture, TriangleMesh};

use super::materials::Diffuse;
use super::values::{ints, vec2s, vec3s};
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
        // The bound material first, as a renderer's final frame shades it; `displayColor` is the look of a
        // prim without one.
        let mut texture = None;
        match self.material_diffuse(prim)? {
            Some(Diffuse::Texture(tex)) => {
                let name = format!("primvars:{}", tex.varname);
                match self.primvar(prim, &name, "a texture coordinate array", vec2s, &expect)? {
                    Some((st, interp)) => {
                        texture = Some(MeshTexture {
                            corner_st: per_corner(&fan, &interp, &st),
                            image: tex.image,
                            wrap: tex.wrap,
                            scale: tex.scale,
                            bias: tex.bias,
                        });
                    }
                    None => self.warn(
                        &pp,
                        &format!("the material's texture reads {name}, which the mesh has not: albedo 0.5"),
                    ),
                }
            }
            Some(Diffuse::Color(c)) => albedo = clamp(c.to_array()),
            None => {
                if let Some((colors, interp)) =
                    self.primvar3(prim, "primvars:displayColor", &expect)?
                {
                    if interp == "constant" {
                        albedo = clamp(colors[0]);
                    } else {
                        let colors: Vec<Vec3> = colors.into_iter().map(&mut clamp).collect();
                        corner_albedo = Some(per_corner(&fan, &interp, &colors));
                    }
                } else {
                    self.warn(&pp, "no UsdPreviewSurface and no displayColor: albedo 0.5");
                }
            }
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
            if let Some(t) = &mut texture {
                t.corner_st.iter_mut().for_each(|c| c.swap(1, 2));
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
            texture,
        }
        .transformed(world.as_mat4());
        if smooth {
            mesh = mesh.smoothed();
        }
        mesh.validate().map_err(|e| bad(e.message))?;
        Ok(mesh)
    }
}

/// A primvar's values at each triangle's three corners, by its interpolation (its length already checked against
/// it): one value for all, one per polygon, one per polygon corner (`faceVarying`), else one per point.
fn per_corner<T: Copy>(fan: &[FanTriangle], interp: &str, values: &[T]) -> Vec<[T; 3]> {
    fan.iter()
        .map(|t| match interp {
            "constant" => [values[0]; 3],
            "uniform" => [values[t.face as usize]; 3],
            "faceVarying" => t.corners.map(|i| values[i as usize]),
            _ => t.points.map(|i| values[i as usize]),
        })
        .collect()
}

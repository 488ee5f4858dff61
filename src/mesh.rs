//! Triangle meshes: the surfaces hair grows from (a scalp, a head) and anything else a groom file brings beside its
//! curves. Plain data, as a reader produces it: world-space positions, triangles as index triples, and a Lambert
//! albedo, constant, per triangle corner or from a texture. The tracers ([`crate::accel::mesh`]) and the shading
//! ([`crate::shape`]) read it; nothing here knows a file format.

use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3};

/// What is wrong with a mesh, naming it (its file and prim).
#[derive(Debug, thiserror::Error)]
#[error("{name}: {message}")]
pub struct MeshError {
    /// The mesh's name: file and prim path, as a reader gave it.
    pub name: String,
    /// What is wrong, lower case, with the offending numbers.
    pub message: String,
}

/// A triangle mesh with a two-sided Lambert material.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriangleMesh {
    /// Where it came from (e.g. `head.usda:/Head/Mesh`), for messages and `cuticle info`.
    pub name: String,
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Triangles as indices into `positions`; the normal of triangle (a, b, c) lies along (b − a) × (c − a).
    pub triangles: Vec<[u32; 3]>,
    /// Albedo at each triangle's three corners (linear RGB in [0, 1]), interpolated across the triangle; `None`:
    /// [`TriangleMesh::albedo`] everywhere. Per corner holds every interpolation a file gives (constant, per face,
    /// per vertex, per face-vertex) in one layout.
    pub corner_albedo: Option<Vec<[Vec3; 3]>>,
    /// The albedo where `corner_albedo` is `None`.
    pub albedo: Vec3,
    /// Unit shading normals at the points, interpolated across each triangle ([`TriangleMesh::shading_normal`]);
    /// `None`: each triangle is shaded with its own normal (flat).
    pub vertex_normals: Option<Vec<Vec3>>,
    /// Texture coordinates at each triangle's three corners, and the texture they look up: the albedo wherever
    /// both are there (it takes the place of `corner_albedo` and `albedo`).
    pub texture: Option<MeshTexture>,
}

/// How a texture's coordinate outside [0, 1] is brought back (USD's `UsdUVTexture` `wrapS`/`wrapT`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TextureWrap {
    /// The texture tiles.
    Repeat,
    /// The edge texel continues.
    Clamp,
    /// The texture tiles, every other copy mirrored.
    Mirror,
    /// Black outside.
    Black,
}

/// A texture's texels: linear RGB, top row first, as decoded once and shared by every mesh (and instance) using it.
#[derive(Debug, Clone, PartialEq)]
pub struct TextureImage {
    /// Where it came from, for messages.
    pub name: String,
    /// Width in texels (≥ 1).
    pub width: usize,
    /// Height in texels (≥ 1).
    pub height: usize,
    /// `width × height` linear RGB texels, top row first.
    pub texels: Vec<Vec3>,
}

/// A mesh's albedo texture: coordinates per triangle corner and the texture they look up, `albedo = texel × scale +
/// bias` (USD's `UsdUVTexture`), clamped to [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct MeshTexture {
    /// Texture coordinates (s, t) at each triangle's corners; t = 0 is the image's bottom row.
    pub corner_st: Vec<[Vec2; 3]>,
    /// The texels.
    pub image: Arc<TextureImage>,
    /// Wrap of s and of t.
    pub wrap: [TextureWrap; 2],
    /// Multiplies the texel.
    pub scale: Vec3,
    /// Added after the scale.
    pub bias: Vec3,
}

impl TextureImage {
    /// The texel at integer (x, y) after wrapping (`None`: black, outside a [`TextureWrap::Black`] texture).
    #[inline]
    fn texel(&self, x: i64, y: i64, wrap: [TextureWrap; 2]) -> Vec3 {
        let fold = |i: i64, n: usize, w: TextureWrap| -> Option<usize> {
            let n = n as i64;
            Some(match w {
                TextureWrap::Repeat => i.rem_euclid(n),
                TextureWrap::Clamp => i.clamp(0, n - 1),
                TextureWrap::Mirror => {
                    let k = i.rem_euclid(2 * n);
                    if k < n {
                        k
                    } else {
                        2 * n - 1 - k
                    }
                }
                TextureWrap::Black => {
                    if !(0..n).contains(&i) {
                        return None;
                    }
                    i
                }
            } as usize)
        };
        match (fold(x, self.width, wrap[0]), fold(y, self.height, wrap[1])) {
            (Some(x), Some(y)) => self.texels[y * self.width + x],
            _ => Vec3::ZERO,
        }
    }

    /// The bilinearly filtered texel at (s, t): texel centres at (i + ½) / width, t = 0 at the bottom row (USD's and
    /// OpenGL's convention; the image's first row is its top).
    pub fn lookup(&self, st: Vec2, wrap: [TextureWrap; 2]) -> Vec3 {
        if !st.is_finite() {
            return Vec3::ZERO;
        }
        // Far coordinates are folded into one period first (exact for repeat and mirror, and for clamp and black
        // beyond ±1e6 nothing changes), so the integer conversions below cannot overflow.
        let st = st.clamp(Vec2::splat(-1e6), Vec2::splat(1e6));
        let x = st.x as f64 * self.width as f64 - 0.5;
        let y = (1.0 - st.y as f64) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let t = |dx: i64, dy: i64| self.texel(x0 + dx, y0 + dy, wrap);
        (t(0, 0) * (1.0 - fx) + t(1, 0) * fx) * (1.0 - fy)
            + (t(0, 1) * (1.0 - fx) + t(1, 1) * fx) * fy
    }

    /// Bytes the texels take.
    pub fn bytes(&self) -> usize {
        self.texels.len() * std::mem::size_of::<Vec3>() + self.name.len()
    }
}

impl TriangleMesh {
    /// Checks what the tracers and the shading rely on: at least one triangle, every index in range, positions
    /// finite and within [`crate::ray::MAX_SCENE_COORD`] of the origin, one albedo triple per triangle, albedos
    /// finite and in [0, 1] (a Lambert surface reflects at most what arrives).
    pub fn validate(&self) -> Result<(), MeshError> {
        let fail = |message: String| {
            Err(MeshError {
                name: self.name.clone(),
                message,
            })
        };
        if self.triangles.is_empty() {
            return fail("has no triangles".into());
        }
        let max = crate::ray::MAX_SCENE_COORD;
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| !p.is_finite() || p.abs().max_element() > max)
        {
            return fail(format!(
                "point {i} at {:?} is not finite or lies farther than {max:e} from the origin",
                self.positions[i].to_array()
            ));
        }
        let n = self.positions.len();
        if let Some((t, tri)) = self
            .triangles
            .iter()
            .enumerate()
            .find(|(_, tri)| tri.iter().any(|&i| i as usize >= n))
        {
            return fail(format!(
                "triangle {t} names point {} of {n}",
                tri.iter().max().copied().unwrap_or(0)
            ));
        }
        let bad_albedo = |c: Vec3| !c.is_finite() || c.min_element() < 0.0 || c.max_element() > 1.0;
        if bad_albedo(self.albedo) {
            return fail(format!(
                "albedo {:?} is not in [0, 1]",
                self.albedo.to_array()
            ));
        }
        if let Some(normals) = &self.vertex_normals {
            if normals.len() != n {
                return fail(format!("{} normals for {n} points", normals.len()));
            }
            if let Some(i) = normals.iter().position(|v| !v.is_finite()) {
                return fail(format!("normal {i} is not finite"));
            }
        }
        if let Some(corners) = &self.corner_albedo {
            if corners.len() != self.triangles.len() {
                return fail(format!(
                    "{} albedo triples for {} triangles",
                    corners.len(),
                    self.triangles.len()
                ));
            }
            if let Some(t) = corners
                .iter()
                .position(|c| c.iter().any(|&c| bad_albedo(c)))
            {
                return fail(format!(
                    "triangle {t}'s colour {:?} is not in [0, 1]",
                    corners[t].map(|c| c.to_array())
                ));
            }
        }
        if let Some(tex) = &self.texture {
            if tex.corner_st.len() != self.triangles.len() {
                return fail(format!(
                    "{} texture coordinate triples for {} triangles",
                    tex.corner_st.len(),
                    self.triangles.len()
                ));
            }
            if let Some(t) = tex
                .corner_st
                .iter()
                .position(|c| c.iter().any(|st| !st.is_finite()))
            {
                return fail(format!("triangle {t}'s texture coordinates are not finite"));
            }
            let i = &tex.image;
            if i.width == 0 || i.height == 0 || i.texels.len() != i.width * i.height {
                return fail(format!(
                    "texture {} has {} texels for {} x {}",
                    i.name,
                    i.texels.len(),
                    i.width,
                    i.height
                ));
            }
            if !(tex.scale.is_finite() && tex.bias.is_finite()) {
                return fail(format!("texture {}'s scale or bias is not finite", i.name));
            }
        }
        Ok(())
    }

    /// The box around the points the triangles use (all points, for a valid mesh read from a file).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions.iter().fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Bytes the mesh holds, without its texture's texels (shared; [`TextureImage::bytes`]).
    pub fn bytes(&self) -> usize {
        self.positions.len() * std::mem::size_of::<Vec3>()
            + self.triangles.len() * std::mem::size_of::<[u32; 3]>()
            + self
                .corner_albedo
                .as_ref()
                .map_or(0, |c| c.len() * std::mem::size_of::<[Vec3; 3]>())
            + self
                .vertex_normals
                .as_ref()
                .map_or(0, |v| v.len() * std::mem::size_of::<Vec3>())
            + self
                .texture
                .as_ref()
                .map_or(0, |t| t.corner_st.len() * std::mem::size_of::<[Vec2; 3]>())
            + self.name.len()
    }

    /// Triangle `t`'s three corners.
    #[inline]
    pub fn corners(&self, t: u32) -> [Vec3; 3] {
        self.triangles[t as usize].map(|i| self.positions[i as usize])
    }

    /// Triangle `t`'s unit normal along (b − a) × (c − a) (zero for a degenerate triangle, which no tracer hits).
    #[inline]
    pub fn normal(&self, t: u32) -> Vec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// The shading normal at barycentric (`u`, `v`) of triangle `t`, on the side of its geometric normal
    /// `geometric` ([`TriangleMesh::normal`]): the points' normals interpolated, or `geometric` itself for a flat
    /// mesh or where the interpolation vanishes.
    #[inline]
    pub fn shading_normal(&self, t: u32, u: f32, v: f32, geometric: Vec3) -> Vec3 {
        let Some(normals) = &self.vertex_normals else {
            return geometric;
        };
        let [a, b, c] = self.triangles[t as usize].map(|i| normals[i as usize]);
        let n = (a * (1.0 - u - v) + b * u + c * v).normalize_or_zero();
        if n == Vec3::ZERO {
            geometric
        } else if n.dot(geometric) < 0.0 {
            -n
        } else {
            n
        }
    }

    /// The mesh shaded smoothly: each point's normal is the area-weighted mean of its triangles' normals (what a
    /// subdivision surface's limit normal approaches on a fine cage; a coarse cage is still seen by its
    /// silhouette).
    pub fn smoothed(mut self) -> TriangleMesh {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for tri in &self.triangles {
            let [a, b, c] = tri.map(|i| self.positions[i as usize]);
            // (b − a) × (c − a) is twice the triangle's area along its normal: the area weighting.
            let n = (b - a).cross(c - a);
            if n.is_finite() {
                for &i in tri {
                    normals[i as usize] += n;
                }
            }
        }
        for n in &mut normals {
            *n = n.normalize_or_zero();
        }
        self.vertex_normals = Some(normals);
        self
    }

    /// The albedo at barycentric (`u`, `v`) of triangle `t`: the point a + u (b − a) + v (c − a).
    #[inline]
    pub fn albedo_at(&self, t: u32, u: f32, v: f32) -> Vec3 {
        if let Some(tex) = &self.texture {
            let [a, b, c] = tex.corner_st[t as usize];
            let st = a * (1.0 - u - v) + b * u + c * v;
            let texel = tex.image.lookup(st, tex.wrap);
            return (texel * tex.scale + tex.bias).clamp(Vec3::ZERO, Vec3::ONE);
        }
        match &self.corner_albedo {
            None => self.albedo,
            Some(corners) => {
                let [a, b, c] = corners[t as usize];
                (a * (1.0 - u - v) + b * u + c * v).clamp(Vec3::ZERO, Vec3::ONE)
            }
        }
    }

    /// The mesh with every point moved by `m` (a reader's transform from the prim's space to the world). A
    /// transform that mirrors (negative determinant) flips the triangles' winding, so reversing each triangle keeps
    /// the normal convention; the material is two-sided, so only the convention depends on it.
    pub fn transformed(mut self, m: Mat4) -> TriangleMesh {
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        if let Some(normals) = &mut self.vertex_normals {
            // Normals move by the inverse transpose of the linear part.
            let n = glam::Mat3::from_mat4(m).inverse().transpose();
            for v in normals {
                *v = (n * *v).normalize_or_zero();
            }
        }
        if m.determinant() < 0.0 {
            for tri in &mut self.triangles {
                tri.swap(1, 2);
            }
            if let Some(corners) = &mut self.corner_albedo {
                for c in corners {
                    c.swap(1, 2);
                }
            }
            if let Some(tex) = &mut self.texture {
                for c in &mut tex.corner_st {
                    c.swap(1, 2);
                }
            }
        }
        self
    }
}

/// Fans polygons into triangles: polygon k has `counts[k]` points, its indices the next `counts[k]` entries of
/// `indices` (USD's `faceVertexCounts` and `faceVertexIndices`, OBJ's faces). Returns the triangles and, for each,
/// its polygon and the positions in `indices` of its three corners (so per-face and per-face-vertex data follow
/// the triangles). Polygons of fewer than three points are dropped (a file may carry points and lines among its
/// faces); `None` when the counts need more indices than there are.
pub fn fan_triangulate(counts: &[u32], indices: &[u32]) -> Option<Vec<FanTriangle>> {
    let needed: u64 = counts.iter().map(|&c| u64::from(c)).sum();
    if needed != indices.len() as u64 {
        return None;
    }
    let triangles: u64 = counts.iter().map(|&c| u64::from(c.saturating_sub(2))).sum();
    let mut out = Vec::with_capacity(usize::try_from(triangles).ok()?);
    let mut at = 0usize;
    for (face, &c) in counts.iter().enumerate() {
        let c = c as usize;
        for k in 1..c.saturating_sub(1) {
            let corner = [at, at + k, at + k + 1];
            out.push(FanTriangle {
                points: corner.map(|i| indices[i]),
                face: face as u32,
                corners: corner.map(|i| i as u32),
            });
        }
        at += c;
    }
    Some(out)
}

/// One triangle of [`fan_triangulate`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FanTriangle {
    /// Its points (indices into the positions).
    pub points: [u32; 3],
    /// The polygon it came from.
    pub face: u32,
    /// The positions in the face-vertex index list of its corners.
    pub corners: [u32; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> TriangleMesh {
        let fan = fan_triangulate(&[4], &[0, 1, 2, 3]).unwrap();
        TriangleMesh {
            name: "square".into(),
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            triangles: fan.iter().map(|t| t.points).collect(),
            corner_albedo: None,
            albedo: Vec3::splat(0.5),
            vertex_normals: None,
            texture: None,
        }
    }

    /// A 2 × 2 texture: top row red, green; bottom row blue, white.
    fn four_texels() -> Arc<TextureImage> {
        Arc::new(TextureImage {
            name: "four".into(),
            width: 2,
            height: 2,
            texels: vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE],
        })
    }

    #[test]
    fn a_texture_is_looked_up_with_t_up_bilinearly_and_wrapped() {
        let img = four_texels();
        let repeat = [TextureWrap::Repeat; 2];
        // Texel centres: s, t = 0.25 or 0.75, t = 0 at the bottom row.
        assert_eq!(img.lookup(Vec2::new(0.25, 0.75), repeat), Vec3::X);
        assert_eq!(img.lookup(Vec2::new(0.75, 0.75), repeat), Vec3::Y);
        assert_eq!(img.lookup(Vec2::new(0.25, 0.25), repeat), Vec3::Z);
        assert_eq!(img.lookup(Vec2::new(0.75, 0.25), repeat), Vec3::ONE);
        // Halfway between the top two: their mean.
        assert_eq!(
            img.lookup(Vec2::new(0.5, 0.75), repeat),
            Vec3::new(0.5, 0.5, 0.0)
        );
        // One period over, the same texel; at s = 0 repeat blends the row's two ends, clamp keeps the edge.
        assert_eq!(img.lookup(Vec2::new(1.25, -0.75), repeat), Vec3::Z);
        assert_eq!(
            img.lookup(Vec2::new(0.0, 0.75), repeat),
            Vec3::new(0.5, 0.5, 0.0)
        );
        let clamp = [TextureWrap::Clamp; 2];
        assert_eq!(img.lookup(Vec2::new(-3.0, 0.75), clamp), Vec3::X);
        // Mirror: s in (1, 2) runs backwards.
        let mirror = [TextureWrap::Mirror; 2];
        assert_eq!(img.lookup(Vec2::new(1.25, 0.75), mirror), Vec3::Y);
        // Black outside, and half black half a texel past the edge.
        let black = [TextureWrap::Black; 2];
        assert_eq!(img.lookup(Vec2::new(-0.75, 0.75), black), Vec3::ZERO);
        assert_eq!(img.lookup(Vec2::new(0.0, 0.75), black), Vec3::X * 0.5);
        assert_eq!(img.lookup(Vec2::new(f32::NAN, 0.5), repeat), Vec3::ZERO);
        assert!(img.lookup(Vec2::new(1e30, -1e30), repeat).is_finite());
    }

    #[test]
    fn a_textured_mesh_takes_its_albedo_from_the_texture_scaled_biased_and_clamped() {
        let mut m = square();
        m.texture = Some(MeshTexture {
            // Triangle 0 (0, 1, 2) mapped so its corners sit on texel centres.
            corner_st: vec![
                [
                    Vec2::new(0.25, 0.25),
                    Vec2::new(0.75, 0.25),
                    Vec2::new(0.75, 0.75),
                ];
                2
            ],
            image: four_texels(),
            wrap: [TextureWrap::Repeat; 2],
            scale: Vec3::splat(0.5),
            bias: Vec3::new(0.1, 0.0, 0.0),
        });
        m.validate().unwrap();
        assert_eq!(m.albedo_at(0, 0.0, 0.0), Vec3::new(0.1, 0.0, 0.5));
        assert_eq!(m.albedo_at(0, 1.0, 0.0), Vec3::new(0.6, 0.5, 0.5));
        assert_eq!(m.albedo_at(0, 0.0, 1.0), Vec3::new(0.1, 0.5, 0.0));
        m.texture.as_mut().unwrap().scale = Vec3::splat(4.0);
        assert_eq!(m.albedo_at(0, 1.0, 0.0), Vec3::ONE, "clamped to 1");
        m.texture.as_mut().unwrap().corner_st.pop();
        assert!(m
            .validate()
            .unwrap_err()
            .message
            .contains("1 texture coordinate triples for 2 triangles"));
    }

    #[test]
    fn polygons_fan_into_triangles_that_remember_their_face_and_corners() {
        let fan = fan_triangulate(
            &[3, 4, 2, 5],
            &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13],
        )
        .unwrap();
        // 1 + 2 + 0 + 3 triangles; the 2-point face is dropped.
        assert_eq!(fan.len(), 6);
        assert_eq!(fan[1].points, [3, 4, 5]);
        assert_eq!(fan[2].points, [3, 5, 6]);
        assert_eq!((fan[2].face, fan[2].corners), (1, [3, 5, 6]));
        assert_eq!((fan[5].face, fan[5].points), (3, [9, 12, 13]));
        assert!(fan_triangulate(&[3, 4], &[0, 1, 2]).is_none());
        assert!(fan_triangulate(&[u32::MAX, u32::MAX], &[0; 4]).is_none());
    }

    #[test]
    fn a_mesh_is_checked_before_it_is_traced() {
        let good = square();
        assert!(good.validate().is_ok());
        assert_eq!(good.normal(0), Vec3::Z);
        let mut bad = square();
        bad.triangles[1][2] = 4;
        let e = bad.validate().unwrap_err().to_string();
        assert!(
            e.starts_with("square: triangle 1 names point 4 of 4"),
            "{e}"
        );
        let mut far = square();
        far.positions[2].x = f32::NAN;
        assert!(far.validate().unwrap_err().message.contains("point 2"));
        let mut bright = square();
        bright.corner_albedo = Some(vec![
            [Vec3::ONE; 3],
            [Vec3::ONE, Vec3::ONE, Vec3::splat(1.5)],
        ]);
        assert!(bright
            .validate()
            .unwrap_err()
            .message
            .contains("triangle 1's colour"));
        bright.corner_albedo = Some(vec![[Vec3::ONE; 3]]);
        assert!(bright
            .validate()
            .unwrap_err()
            .message
            .contains("1 albedo triples for 2"));
        assert!(TriangleMesh::default().validate().is_err());
    }

    #[test]
    fn albedo_interpolates_across_a_triangle() {
        let mut m = square();
        m.corner_albedo = Some(vec![[Vec3::X, Vec3::Y, Vec3::Z]; 2]);
        assert_eq!(m.albedo_at(0, 0.0, 0.0), Vec3::X);
        assert_eq!(m.albedo_at(0, 1.0, 0.0), Vec3::Y);
        assert_eq!(m.albedo_at(1, 0.25, 0.5), Vec3::new(0.25, 0.25, 0.5));
    }

    #[test]
    fn smooth_normals_interpolate_and_keep_to_the_front() {
        // A roof of two triangles folded along x = 0.5: their normals lean ±x, the ridge's points get the mean.
        let mut m = square();
        m.positions = vec![
            Vec3::ZERO,
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(0.5, 1.0, 0.5),
            Vec3::Y,
        ];
        m.positions.push(Vec3::X);
        m.positions.push(Vec3::new(1.0, 1.0, 0.0));
        m.triangles = vec![[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]];
        let m = m.smoothed();
        assert!(m.validate().is_ok());
        let normals = m.vertex_normals.as_ref().unwrap();
        // The four triangles have equal areas; ridge point 1 is in one left triangle (normal ∝ (−1, 0, 1)) and two
        // right ones (∝ (1, 0, 1)): its normal is ∝ (1, 0, 3). Point 0 is on the left slope alone.
        let ridge = Vec3::new(1.0, 0.0, 3.0).normalize();
        assert!((normals[1] - ridge).length() < 1e-6, "{:?}", normals[1]);
        assert!((normals[0] - Vec3::new(-1.0, 0.0, 1.0).normalize()).length() < 1e-6);
        let g = m.normal(0);
        assert!((m.shading_normal(0, 1.0, 0.0, g) - ridge).length() < 1e-6);
        let halfway = m.shading_normal(0, 0.5, 0.0, g);
        assert!((halfway - (normals[0] + ridge).normalize()).length() < 1e-6);
        // Asked with the geometric normal flipped, the shading normal follows it to that side.
        assert!(m.shading_normal(0, 0.3, 0.3, -g).dot(-g) > 0.0);
        assert_eq!(square().shading_normal(0, 0.2, 0.2, Vec3::Z), Vec3::Z);
        // Moved and scaled unevenly, the normals stay perpendicular to the moved surface.
        let stretched = m
            .clone()
            .transformed(Mat4::from_scale(Vec3::new(1.0, 1.0, 3.0)));
        let n = stretched.vertex_normals.as_ref().unwrap()[0];
        let edge = stretched.positions[1] - stretched.positions[0];
        assert!(n.dot(edge.normalize()).abs() < 0.75, "{n}");
        assert!((n.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_mirroring_transform_keeps_the_normal_convention() {
        let m = square().transformed(Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0)));
        assert_eq!(m.positions[1], Vec3::NEG_X);
        // Mirrored in x, the square still faces +z once the winding is reversed.
        assert_eq!(m.normal(0), Vec3::Z);
        let moved = square().transformed(Mat4::from_translation(Vec3::Z));
        assert_eq!(moved.bounds(), (Vec3::Z, Vec3::new(1.0, 1.0, 1.0)));
    }
}

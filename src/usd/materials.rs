//! A mesh's albedo from its bound material: the `UsdPreviewSurface`'s `diffuseColor`, constant or from a
//! `UsdUVTexture` (read through OpenImageIO) looked up at a `UsdPrimvarReader_float2`'s coordinates.
//!
//! What a texture reads, after the `UsdPreviewSurface` specification: `inputs:file` (relative to the root layer's
//! directory, or a file inside a `.usdz` package), `inputs:st` connected to a primvar reader whose `inputs:varname`
//! names the mesh's coordinates (`st` when the reader is not there), `inputs:wrapS`/`wrapT` (`repeat`, `clamp`,
//! `mirror`, `black`; `useMetadata`, the default, is taken as `repeat`: the image formats read here carry no wrap
//! metadata), `inputs:scale` and `inputs:bias` (albedo = texel × scale + bias), `inputs:sourceColorSpace` (`sRGB`,
//! `raw`, or `auto`: sRGB where OpenImageIO says the file is, as it does for 8-bit PNG and JPEG) and
//! `inputs:fallback` (the albedo where the file cannot be used: it is an error instead, naming the file, as any
//! other unreadable input is). Only the `rgb` output is read.

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use openusd::{sdf, usd};

use crate::mesh::{TextureImage, TextureWrap};

use super::values::{rgb_of4, token, vec3};
use super::{prim_err, Reader, UsdError};

/// The most bytes a texture's decoded texels may take (as f32 while decoding): 2 GiB, a 16k × 8k RGBA image.
pub const MAX_TEXTURE_BYTES: u64 = 2 << 30;

/// The diffuse colour a bound `UsdPreviewSurface` gives.
pub(super) enum Diffuse {
    /// A constant albedo.
    Color(Vec3),
    /// A texture.
    Texture(TextureSource),
}

/// A `UsdUVTexture` as the mesh reads it.
pub(super) struct TextureSource {
    /// The primvar holding the texture coordinates.
    pub(super) varname: String,
    /// The texels.
    pub(super) image: Arc<TextureImage>,
    /// Wrap of s and t.
    pub(super) wrap: [TextureWrap; 2],
    /// albedo = texel × scale + bias.
    pub(super) scale: Vec3,
    /// albedo = texel × scale + bias.
    pub(super) bias: Vec3,
}

/// The sRGB transfer function undone (IEC 61966-2-1).
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Reader<'_> {
    /// The shader a prim's `name` input or output is connected to, if it is connected.
    fn source_of(&self, prim: &usd::Prim, name: &str) -> Result<Option<usd::Prim>, UsdError> {
        let connections = prim.attribute(name).connections().unwrap_or_default();
        connections
            .first()
            .map(|c| self.prim_at(&c.prim_path(), prim))
            .transpose()
    }

    /// The diffuse colour of the `UsdPreviewSurface` bound to `prim` by `material:binding`: its texture, its
    /// constant `diffuseColor`, or the specification's default 0.18 grey. `None` without a bound preview surface.
    pub(super) fn material_diffuse(
        &mut self,
        prim: &usd::Prim,
    ) -> Result<Option<Diffuse>, UsdError> {
        let targets = prim
            .relationship("material:binding")
            .targets()
            .unwrap_or_default();
        let Some(material) = targets.first() else {
            return Ok(None);
        };
        let mat = self.prim_at(material, prim)?;
        let Some(shader) = self.source_of(&mat, "outputs:surface")? else {
            return Ok(None);
        };
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
        if let Some(texture) = self.source_of(&shader, "inputs:diffuseColor")? {
            let id = self.token(&texture, "info:id", "")?;
            if id == "UsdUVTexture" {
                return Ok(Some(Diffuse::Texture(self.uv_texture(&texture)?)));
            }
            self.warn(
                prim.path(),
                &format!(
                    "diffuseColor is connected to {} ({id:?}, not UsdUVTexture): its constant value is read",
                    texture.path()
                ),
            );
        }
        let color = self
            .get_as(&shader, "inputs:diffuseColor", "a colour", vec3)?
            .map_or(Vec3::splat(0.18), |c| c.as_vec3());
        Ok(Some(Diffuse::Color(color)))
    }

    /// A `UsdUVTexture` shader's file (decoded once per reader), coordinates, wrap, scale and bias.
    fn uv_texture(&mut self, shader: &usd::Prim) -> Result<TextureSource, UsdError> {
        let sp = shader.path().clone();
        let bad = |m: String| prim_err(self.path, &sp, m);
        let file = match self.get(shader, "inputs:file")? {
            Some(sdf::Value::AssetPath(a)) if !a.as_str().is_empty() => a.as_str().to_owned(),
            _ => return Err(bad("inputs:file is not an asset path".into())),
        };
        let wrap = |s: &mut Self, name: &str| -> Result<TextureWrap, UsdError> {
            Ok(match s.token(shader, name, "useMetadata")?.as_str() {
                "repeat" | "useMetadata" => TextureWrap::Repeat,
                "clamp" => TextureWrap::Clamp,
                "mirror" => TextureWrap::Mirror,
                "black" => TextureWrap::Black,
                other => {
                    return Err(prim_err(
                        s.path,
                        shader.path(),
                        format!("{name}: unknown wrap {other:?}"),
                    ))
                }
            })
        };
        let wrap = [wrap(self, "inputs:wrapS")?, wrap(self, "inputs:wrapT")?];
        let scale = self
            .get_as(shader, "inputs:scale", "a float4", rgb_of4)?
            .unwrap_or(Vec3::ONE);
        let bias = self
            .get_as(shader, "inputs:bias", "a float4", rgb_of4)?
            .unwrap_or(Vec3::ZERO);
        let space = self.token(shader, "inputs:sourceColorSpace", "auto")?;
        if !matches!(space.as_str(), "auto" | "raw" | "sRGB") {
            return Err(bad(format!(
                "inputs:sourceColorSpace: unknown colour space {space:?}"
            )));
        }
        let varname = match self.source_of(shader, "inputs:st")? {
            Some(reader) => match self.get(&reader, "inputs:varname")? {
                Some(v) => token(&v).filter(|t| !t.is_empty()).ok_or_else(|| {
                    bad(format!("{}: inputs:varname is not a name", reader.path()))
                })?,
                None => "st".to_owned(),
            },
            None => "st".to_owned(),
        };
        let image = if self
            .path
            .to_str()
            .is_some_and(super::crate_check::is_package)
            && PathBuf::from(&file).is_relative()
        {
            self.packaged_texture(&file, &space).map_err(bad)?
        } else {
            let path = self.asset_file(&file);
            self.texture_image(&path, &space).map_err(bad)?
        };
        Ok(TextureSource {
            varname,
            image,
            wrap,
            scale,
            bias,
        })
    }

    /// The file an asset path names: relative paths from the root layer's directory.
    pub(super) fn asset_file(&self, asset: &str) -> PathBuf {
        let p = PathBuf::from(asset);
        if p.is_relative() {
            self.path.parent().unwrap_or(Path::new("")).join(p)
        } else {
            p
        }
    }

    /// The texels of the file `name` inside the `.usdz` package being read: copied to a temporary file (OpenImageIO
    /// reads files) and decoded as [`Reader::texture_image`] does.
    fn packaged_texture(&mut self, name: &str, space: &str) -> Result<Arc<TextureImage>, String> {
        let key = (self.path.join(name), space.to_owned());
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        let fail = |e: &dyn std::fmt::Display| format!("texture {name} in the package: {e}");
        let file = std::fs::File::open(self.path).map_err(|e| fail(&e))?;
        let mut archive = zip::ZipArchive::new(file).map_err(|e| fail(&e))?;
        let mut entry = archive.by_name(name).map_err(|e| fail(&e))?;
        if entry.size() > MAX_TEXTURE_BYTES {
            return Err(fail(&format!(
                "{} bytes, more than a texture's {MAX_TEXTURE_BYTES}",
                entry.size()
            )));
        }
        let suffix = Path::new(name)
            .extension()
            .map(|e| format!(".{}", e.to_string_lossy()))
            .unwrap_or_default();
        let mut copy = tempfile::Builder::new()
            .prefix("cuticle-texture-")
            .suffix(&suffix)
            .tempfile()
            .map_err(|e| fail(&e))?;
        std::io::copy(&mut entry.by_ref().take(MAX_TEXTURE_BYTES), &mut copy)
            .map_err(|e| fail(&e))?;
        // Named after the package entry, not the temporary copy.
        let name = format!("{}[{name}]", self.path.display());
        let image = Arc::new(decode_texture(copy.path(), name, space)?);
        self.textures.insert(key, image.clone());
        Ok(image)
    }

    /// The texels of `path`, linear, decoded once per file and `sourceColorSpace`.
    fn texture_image(&mut self, path: &Path, space: &str) -> Result<Arc<TextureImage>, String> {
        let key = (path.to_path_buf(), space.to_owned());
        if let Some(t) = self.textures.get(&key) {
            return Ok(t.clone());
        }
        let image = Arc::new(decode_texture(path, path.display().to_string(), space)?);
        self.textures.insert(key, image.clone());
        Ok(image)
    }
}

/// The texels of the image file `path` as linear RGB, named `name`: sRGB-decoded as `sourceColorSpace` `space`
/// says (see the module doc), premultiplied alpha undone.
fn decode_texture(path: &Path, name: String, space: &str) -> Result<TextureImage, String> {
    let (image, attrs) =
        crate::image::read_at_most_with(path, &["oiio:ColorSpace"], MAX_TEXTURE_BYTES)
            .map_err(|e| format!("texture: {e}"))?;
    let srgb = match space {
        "sRGB" => true,
        "raw" => false,
        _ => attrs[0]
            .as_deref()
            .is_some_and(|c| c.to_ascii_lowercase().contains("srgb")),
    };
    let find = |name: &str| image.channels.iter().position(|c| c == name);
    let n = image.channels.len();
    let rgb = match (find("R"), find("G"), find("B")) {
        (Some(r), Some(g), Some(b)) => [r, g, b],
        _ if n >= 1 => [0, 0, 0],
        _ => return Err(format!("texture {name}: no channels")),
    };
    let alpha = find("A");
    let decode = |c: f32| if srgb { srgb_to_linear(c) } else { c };
    let texels = image
        .data
        .chunks_exact(n)
        .map(|px| {
            // The image holds colour premultiplied by alpha; an albedo is the colour itself.
            let a = alpha.map_or(1.0, |a| px[a]);
            let k = if a > 0.0 { 1.0 / a } else { 1.0 };
            Vec3::from_array(rgb.map(|i| decode(px[i] * k)))
        })
        .collect();
    Ok(TextureImage {
        name,
        width: image.width,
        height: image.height,
        texels,
    })
}

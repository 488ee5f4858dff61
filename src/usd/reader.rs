//! One read of a stage: the traversal, attribute values with their time samples, and primvars.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::DMat4;
use openusd::{sdf, usd};

use crate::hair::Strands;
use crate::mesh::{TextureImage, TriangleMesh};

use super::values::{floats, ints, scalar, token, vec3s};
use super::{Parts, UsdError, UsdStage};

/// One read in progress.
pub(super) struct Reader<'a> {
    pub(super) path: &'a Path,
    pub(super) stage: usd::Stage,
    pub(super) default_radius: f32,
    /// The geometry this read converts.
    pub(super) parts: Parts,
    pub(super) out: UsdStage,
    /// Textures decoded so far, by file and `sourceColorSpace`: each is decoded once however many meshes and
    /// instances use it.
    pub(super) textures: HashMap<(PathBuf, String), Arc<TextureImage>>,
}

/// Curves and meshes read from one subtree, in traversal order.
#[derive(Default)]
pub(super) struct Geometry {
    pub(super) strands: Strands,
    pub(super) curve_prims: Vec<String>,
    pub(super) meshes: Vec<TriangleMesh>,
}

/// Whether each step of `path`'s parent chain is shorter than the last. openusd 0.6 takes some malformed names
/// (a prim `a}`, an attribute `xfor}Op:scale`) for a path that is its own parent, and any query of it recursed until
/// the stack overflowed or looped for good (both found by the `usd` fuzz target): such paths are refused before
/// they are queried.
pub(super) fn well_formed(path: &sdf::Path) -> bool {
    let mut p = path.clone();
    while let Some(q) = p.parent() {
        if q.as_str().len() >= p.as_str().len() {
            return false;
        }
        p = q;
    }
    true
}

/// An openusd error on `prim`.
pub(super) fn usd_err(file: &Path, prim: &sdf::Path, e: anyhow::Error) -> UsdError {
    prim_err(file, prim, format!("{e:#}"))
}

/// A prim-level error.
pub(super) fn prim_err(path: &Path, prim: &sdf::Path, message: impl Into<String>) -> UsdError {
    UsdError {
        path: path.to_path_buf(),
        prim: Some(prim.to_string()),
        message: message.into(),
    }
}

impl<'a> Reader<'a> {
    pub(super) fn new(
        path: &'a Path,
        name: &str,
        default_radius: f32,
        parts: Parts,
    ) -> Result<Self, UsdError> {
        let stage = usd::Stage::open(name)
            .map_err(|e| UsdError::file(path, format!("cannot open the stage: {e:#}")))?;
        Ok(Reader {
            path,
            stage,
            default_radius,
            parts,
            out: UsdStage::default(),
            textures: HashMap::new(),
        })
    }

    pub(super) fn read(mut self, root: Option<&str>) -> Result<UsdStage, UsdError> {
        let file = self.path;
        let token = |key: &str| -> Option<String> {
            match self.stage.stage_metadata(key).ok().flatten() {
                Some(sdf::Value::Token(t)) => Some(t.as_str().to_owned()),
                Some(sdf::Value::String(s)) => Some(s),
                _ => None,
            }
        };
        self.out.up_axis = token("upAxis").unwrap_or_else(|| "Y".into());
        self.out.meters_per_unit = match self.stage.stage_metadata("metersPerUnit").ok().flatten() {
            Some(v) => scalar(&v).unwrap_or(0.01),
            None => 0.01,
        };
        let root_path = match root {
            None => sdf::Path::abs_root(),
            Some(r) => sdf::Path::new(r)
                .map_err(|e| UsdError::file(self.path, format!("root {r:?}: {e}")))?,
        };
        if !well_formed(&root_path) {
            return Err(prim_err(
                self.path,
                &root_path,
                "a prim name the USD parser cannot place under its parent",
            ));
        }
        // The root's own world transform: its ancestors' ops, outermost first.
        let mut chain = Vec::new();
        let mut p = root_path.parent();
        while let Some(q) = p {
            if q == sdf::Path::abs_root() {
                break;
            }
            p = q.parent();
            chain.push(q);
        }
        let mut world = DMat4::IDENTITY;
        for q in chain.iter().rev() {
            let prim = self.stage.prim(q.clone());
            world = self.world_of(&prim, world)?;
        }
        let root_prim = self.stage.prim(root_path.clone());
        if root.is_some()
            && !root_prim
                .is_valid()
                .map_err(|e| usd_err(file, &root_path, e))?
        {
            return Err(prim_err(self.path, &root_path, "no such prim on the stage"));
        }
        let mut geometry = Geometry::default();
        self.walk(root_prim, world, &mut geometry, 0)?;
        if geometry.strands.strand_count() > 0 {
            self.out.strands = Some(geometry.strands);
        }
        self.out.curve_prims = geometry.curve_prims;
        self.out.meshes = geometry.meshes;
        Ok(self.out)
    }

    /// Reads the geometry under `root` (included) into `geometry`, `world` being the transform of `root`'s
    /// parent. `depth` counts the point instancers this walk is inside: cameras and lights are read only outside
    /// them (a prototype's camera or light is not one of the stage's).
    ///
    /// Skipped with their subtrees, as a renderer's final frame skips them: inactive, undefined (`over`) and
    /// abstract (`class`) prims, `visibility = "invisible"`, and `purpose` `guide` or `proxy` (a groom's guide
    /// curves, a preview stand-in). Instanceable prims are read through their instance proxies: the stage
    /// composes a prototype's children under each instance, so nothing is needed here. A `PointInstancer`'s
    /// children are read only as its prototypes, once per instance ([`Reader::point_instancer`]).
    pub(super) fn walk(
        &mut self,
        root: usd::Prim,
        world: DMat4,
        geometry: &mut Geometry,
        depth: u32,
    ) -> Result<(), UsdError> {
        let file = self.path;
        let mut stack = vec![(root, world)];
        while let Some((prim, parent)) = stack.pop() {
            let ppath = prim.path().clone();
            let is_root = ppath == sdf::Path::abs_root();
            let world = if is_root {
                parent
            } else {
                let e = |e| usd_err(file, &ppath, e);
                if !prim.is_active().map_err(e)?
                    || !prim.is_defined().map_err(e)?
                    || prim.is_abstract().map_err(e)?
                {
                    continue;
                }
                let ty = prim
                    .type_name()
                    .map_err(e)?
                    .map(|t| t.as_str().to_owned())
                    .unwrap_or_default();
                *self.out.prim_types.entry(ty.clone()).or_default() += 1;
                // `visibility` and `purpose` belong to imageable prims, which are typed; a typeless prim's are
                // not read, as USD does not read them.
                let typed = !ty.is_empty();
                if typed && self.token(&prim, "visibility", "inherited")? == "invisible" {
                    self.out.skipped.invisible += 1;
                    continue;
                }
                let purpose = if typed {
                    self.token(&prim, "purpose", "default")?
                } else {
                    String::new()
                };
                match purpose.as_str() {
                    "guide" => {
                        self.out.skipped.guide += 1;
                        continue;
                    }
                    "proxy" => {
                        self.out.skipped.proxy += 1;
                        continue;
                    }
                    _ => {}
                }
                let world = self.world_of(&prim, parent)?;
                match ty.as_str() {
                    "BasisCurves" if !self.parts.curves => {}
                    "Mesh" if !self.parts.meshes => self.out.mesh_prims += 1,
                    "BasisCurves" => {
                        let s = self.curves(&prim, world)?;
                        if s.strand_count() > 0 {
                            geometry.strands.append(&s);
                            geometry.curve_prims.push(ppath.to_string());
                        }
                    }
                    "Mesh" => {
                        self.out.mesh_prims += 1;
                        let m = self.mesh(&prim, world)?;
                        geometry.meshes.push(m);
                    }
                    "PointInstancer" => {
                        self.point_instancer(&prim, world, geometry, depth)?;
                        continue;
                    }
                    "Camera" if depth > 0 => self.warn(
                        &ppath,
                        "a camera in a point instancer's prototype is not read",
                    ),
                    "Camera" => {
                        if self.out.camera.is_none() {
                            self.out.camera = Some(self.camera(&prim, world)?);
                        } else {
                            self.warn(&ppath, "a second camera: only the first is read");
                        }
                    }
                    t if t.ends_with("Light") && depth > 0 => self.warn(
                        &ppath,
                        "a light in a point instancer's prototype is not read",
                    ),
                    "DistantLight" | "DomeLight" => {
                        let l = self.light(&prim, &ty, world)?;
                        self.out.lights.push(l);
                    }
                    t if t.ends_with("Light") => self.warn(
                        &ppath,
                        &format!("{t} is not read (only DistantLight and DomeLight)"),
                    ),
                    _ => {}
                }
                world
            };
            let children = prim.children().map_err(|e| usd_err(file, &ppath, e))?;
            for c in children.into_iter().rev() {
                // openusd 0.6 takes some malformed names (`a}`) for a path whose parent is itself, and any query
                // of such a prim recurses until the stack overflows: refused before it is touched.
                if c.path().parent().as_ref() != Some(&ppath) {
                    return Err(prim_err(
                        file,
                        c.path(),
                        "a prim name the USD parser cannot place under its parent",
                    ));
                }
                stack.push((c, world));
            }
        }
        Ok(())
    }

    pub(super) fn warn(&mut self, prim: &sdf::Path, message: &str) {
        self.out
            .warnings
            .push(format!("{}:{prim}: {message}", self.path.display()));
    }

    /// The prim at `path` (a relationship's target, a connection's source), refused if the path is malformed
    /// ([`well_formed`]); `from` is the prim that named it.
    pub(super) fn prim_at(
        &self,
        path: &sdf::Path,
        from: &usd::Prim,
    ) -> Result<usd::Prim, UsdError> {
        if !well_formed(path) {
            return Err(prim_err(
                self.path,
                from.path(),
                format!("names {path}, a path the USD parser cannot resolve"),
            ));
        }
        Ok(self.stage.prim(path.clone()))
    }

    /// Refuses an attribute name (from the file: an `xformOpOrder` entry, a primvar reader's `varname`) whose path
    /// is malformed ([`well_formed`]).
    pub(super) fn check_attribute(&self, prim: &usd::Prim, name: &str) -> Result<(), UsdError> {
        let ok = prim
            .path()
            .append_property(name)
            .is_ok_and(|p| well_formed(&p));
        if ok {
            Ok(())
        } else {
            Err(prim_err(
                self.path,
                prim.path(),
                format!("attribute name {name:?} is not one the USD parser can resolve"),
            ))
        }
    }

    /// The value of `prim.name`: its default, else its earliest time sample (with a warning), else `None`.
    pub(super) fn get(
        &mut self,
        prim: &usd::Prim,
        name: &str,
    ) -> Result<Option<sdf::Value>, UsdError> {
        let file = self.path;
        self.check_attribute(prim, name)?;
        let attr = prim.attribute(name);
        let e = |e| usd_err(file, prim.path(), e);
        match attr.get::<sdf::Value>().map_err(e)? {
            Some(sdf::Value::ValueBlock) => return Ok(None),
            Some(v) => return Ok(Some(v)),
            None => {}
        }
        let samples = attr.time_samples().map_err(e)?.unwrap_or_default();
        let earliest = samples.into_iter().min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((t, v)) = earliest {
            self.warn(
                prim.path(),
                &format!("{name} has no default value: its earliest time sample (t = {t}) is read"),
            );
            return Ok((!matches!(v, sdf::Value::ValueBlock)).then_some(v));
        }
        Ok(None)
    }

    /// `get` converted by `f`; a value of another type is an error naming the attribute.
    pub(super) fn get_as<T>(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        what: &str,
        f: impl Fn(&sdf::Value) -> Option<T>,
    ) -> Result<Option<T>, UsdError> {
        match self.get(prim, name)? {
            None => Ok(None),
            Some(v) => f(&v)
                .map(Some)
                .ok_or_else(|| prim_err(self.path, prim.path(), format!("{name} is not {what}"))),
        }
    }

    /// The interpolation metadata of a primvar (`default` when not authored).
    pub(super) fn interpolation(&self, prim: &usd::Prim, name: &str, default: &str) -> String {
        if self.check_attribute(prim, name).is_err() {
            return default.to_owned();
        }
        match prim
            .attribute(name)
            .get_metadata::<sdf::Value>("interpolation")
            .ok()
            .flatten()
        {
            Some(sdf::Value::Token(t)) => t.as_str().to_owned(),
            _ => default.to_owned(),
        }
    }

    pub(super) fn token(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        default: &str,
    ) -> Result<String, UsdError> {
        Ok(self
            .get_as(prim, name, "a token", token)?
            .unwrap_or_else(|| default.to_owned()))
    }

    /// A primvar's values and interpolation, converted by `f` (`what` names the type in an error), its length
    /// checked against `expect`. An indexed primvar (`<name>:indices`) is expanded: each index picks a value, and
    /// the indices take the interpolation's length.
    pub(super) fn primvar<T: Clone>(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        what: &str,
        f: impl Fn(&sdf::Value) -> Option<Vec<T>>,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Option<(Vec<T>, String)>, UsdError> {
        let Some(v) = self.get_as(prim, name, what, f)? else {
            return Ok(None);
        };
        if v.is_empty() {
            return Ok(None);
        }
        let indices_name = format!("{name}:indices");
        let v = match self.get_as(prim, &indices_name, "an int array", ints)? {
            None => v,
            Some(indices) => {
                if let Some(i) = indices.iter().position(|&k| k < 0 || k as usize >= v.len()) {
                    return Err(prim_err(
                        self.path,
                        prim.path(),
                        format!(
                            "{indices_name}[{i}] is {}, outside the {} values",
                            indices[i],
                            v.len()
                        ),
                    ));
                }
                indices.iter().map(|&k| v[k as usize].clone()).collect()
            }
        };
        let interp = self.interpolation(prim, name, "constant");
        self.check_len(prim, name, v.len(), &interp, expect)?;
        Ok(Some((v, interp)))
    }

    /// A colour primvar ([`Reader::primvar`]).
    #[allow(clippy::type_complexity)]
    pub(super) fn primvar3(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Option<(Vec<[f32; 3]>, String)>, UsdError> {
        Ok(self
            .primvar(prim, name, "a colour array", vec3s, expect)?
            .map(|(v, interp)| (v.into_iter().map(|c| c.to_array()).collect(), interp)))
    }

    /// A float primvar ([`Reader::primvar`]).
    pub(super) fn primvar1(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Option<(Vec<f32>, String)>, UsdError> {
        self.primvar(prim, name, "a float array", floats, expect)
    }

    pub(super) fn check_len(
        &self,
        prim: &usd::Prim,
        name: &str,
        len: usize,
        interp: &str,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<(), UsdError> {
        match expect(interp) {
            Some(n) if n == len => Ok(()),
            Some(n) => Err(prim_err(
                self.path,
                prim.path(),
                format!("{name} has {len} values; {interp} interpolation needs {n}"),
            )),
            None => Err(prim_err(
                self.path,
                prim.path(),
                format!("{name}: unknown interpolation {interp:?}"),
            )),
        }
    }
}

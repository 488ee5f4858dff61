//! USD stages (`.usda`, `.usdc`, `.usdz`) as a groom: `UsdGeomBasisCurves` → B-spline [`Strands`], `UsdGeomMesh` →
//! [`TriangleMesh`], the first `UsdGeomCamera`, `UsdLux` distant and dome lights, all in world space.
//!
//! The stage is composed by the `openusd` crate (pure Rust). The reader walks the active, defined, non-abstract
//! prims under a root, composing each prim's `xformOp`s (`translate*`, `scale*`, `rotateX/Y/Z`, the six
//! `rotateXYZ` orders, `orient`, `transform`, `!invert!`, in `xformOpOrder`; `!resetXformStack!` drops the
//! parent's transform) onto its parent's. What it reads and what it leaves:
//!
//! - **Time**: every attribute's default value; an attribute with only time samples gives its earliest sample, and
//!   a warning says so.
//! - **Units**: `upAxis` and `metersPerUnit` are reported, not applied: a Z-up stage is read as it is.
//! - **Curves** ([`curves`]): every basis, wrap and width interpolation converted exactly; `widths` are diameters.
//!   Without widths every curve gets `default_radius`, tapered to half at the tip like a `.hair` file without
//!   thickness ([`Strands::from_model`], thesis §5.2); authored widths are used as they are. Pinned B-splines go
//!   through [`Strands::from_model`], so a `.hair` strand written as a pinned B-spline reads back bit for bit.
//!   `primvars:displayColor` and `primvars:displayOpacity` give the strand's colour and opacity at its root
//!   (clamped to [0, 1], with a warning).
//! - **Meshes**: polygons fanned into triangles; `leftHanded` reverses the winding; `displayColor` (constant,
//!   uniform, vertex, faceVarying) becomes the corner albedo, else the bound `UsdPreviewSurface`'s constant
//!   `inputs:diffuseColor`, else 0.5 grey with a warning.
//! - **Lights**: `DistantLight` and `DomeLight`; other lights are skipped with a warning.
//!
//! Bad input: every error names the file and, where there is one, the prim. Counts are checked against the
//! arrays before anything proportional to them is allocated. `openusd` 0.6 can panic on malformed binary files
//! (a `todo!` for old versions, out-of-range lookup tables), so the whole read runs under
//! [`std::panic::catch_unwind`] and a panic becomes a [`UsdError`]. What cannot be caught (its allocations from a
//! `.usdc`'s declared sizes, its recursion into values holding themselves, its loops) is checked first: a crate
//! file, and each crate file in a `.usdz`, is walked as openusd will read it ([`crate_check`]: tables, path tree and
//! every field's value, each size held to the file), and a `.usdz` layer stored compressed is refused. Layers the
//! stage composes from other files (sublayers, references, payloads) are opened by openusd without that walk. The
//! file's size is bounded by [`MAX_FILE_BYTES`] before it is opened.

mod crate_check;
pub mod curves;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::{DMat4, DQuat, DVec3, Vec3};
use openusd::{sdf, usd};

use crate::hair::{HairModel, Strands};
use crate::mesh::{fan_triangulate, TriangleMesh};
use curves::{Basis, Radius, Wrap};

/// The largest file the reader opens, bytes.
pub const MAX_FILE_BYTES: u64 = 16 << 30;
/// The most points (curve vertices or mesh points) one prim may hold: 2³¹, so every index fits a u32 with room
/// for the converted control points.
pub const MAX_POINTS: u64 = 1 << 31;

/// What went wrong reading a stage: the file, the prim when there is one, and what.
#[derive(Debug, thiserror::Error)]
#[error("{}{}: {message}", .path.display(), .prim.as_deref().map(|p| format!(":{p}")).unwrap_or_default())]
pub struct UsdError {
    /// The stage's root layer.
    pub path: PathBuf,
    /// The prim path, when the problem is in one prim.
    pub prim: Option<String>,
    /// What is wrong, lower case, with the offending numbers.
    pub message: String,
}

impl UsdError {
    fn file(path: &Path, message: impl Into<String>) -> Self {
        UsdError {
            path: path.to_path_buf(),
            prim: None,
            message: message.into(),
        }
    }

    /// The message with its prim but not its file, for an error that names the file itself.
    pub fn without_file(&self) -> String {
        match &self.prim {
            Some(prim) => format!("{prim}: {}", self.message),
            None => self.message.clone(),
        }
    }
}

/// A stage read as a groom, world space.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UsdStage {
    /// Every `BasisCurves` prim's curves, in traversal order; `None` when there are none.
    pub strands: Option<Strands>,
    /// The `BasisCurves` prims' paths, in the order of their strands.
    pub curve_prims: Vec<String>,
    /// Every `Mesh` prim, fanned into triangles, named `file:/prim/path`.
    pub meshes: Vec<TriangleMesh>,
    /// The first `Camera` prim in traversal order.
    pub camera: Option<UsdCamera>,
    /// `DistantLight` and `DomeLight` prims.
    pub lights: Vec<UsdLight>,
    /// Prims traversed, by type name (`""` for typeless prims).
    pub prim_types: BTreeMap<String, usize>,
    /// The stage's `upAxis` ("Y" when not authored); reported, not applied.
    pub up_axis: String,
    /// The stage's `metersPerUnit` (0.01 when not authored); reported, not applied.
    pub meters_per_unit: f64,
    /// What was skipped or approximated, one line each.
    pub warnings: Vec<String>,
}

/// A camera in world space. USD cameras look down their −Z axis with +Y up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UsdCamera {
    /// The eye.
    pub position: Vec3,
    /// Unit view direction.
    pub forward: Vec3,
    /// Unit up direction (the camera's +Y; not re-orthogonalised against `forward`).
    pub up: Vec3,
    /// 2 atan(verticalAperture / (2 focalLength)), degrees.
    pub vertical_fov_degrees: f32,
    /// horizontalAperture / verticalAperture when either is authored; `None` leaves the film's aspect.
    pub aspect: Option<f32>,
}

/// A `UsdLux` light.
#[derive(Debug, Clone, PartialEq)]
pub enum UsdLight {
    /// `DistantLight`: shines along its −Z axis.
    Distant {
        /// Unit direction towards the light (its +Z axis in world space).
        direction_to_light: Vec3,
        /// `inputs:color`.
        color: Vec3,
        /// `inputs:intensity`.
        intensity: f32,
        /// `inputs:exposure` (the light is scaled by 2^exposure).
        exposure: f32,
        /// `inputs:angle`: the sun's angular diameter, degrees.
        angle_degrees: f32,
    },
    /// `DomeLight`: light from every direction.
    Dome {
        /// `inputs:color`.
        color: Vec3,
        /// `inputs:intensity`.
        intensity: f32,
        /// `inputs:exposure`.
        exposure: f32,
        /// `inputs:texture:file`, relative paths taken from the root layer's directory.
        texture: Option<PathBuf>,
    },
}

/// Reads the stage at `path`, from the prim `root` down (the whole stage when `None`). Curves without widths get
/// `default_radius` (tapered, as a `.hair` file without thickness).
pub fn read(path: &Path, root: Option<&str>, default_radius: f32) -> Result<UsdStage, UsdError> {
    if !(default_radius.is_finite() && default_radius > 0.0) {
        return Err(UsdError::file(
            path,
            format!("default radius {default_radius} must be > 0"),
        ));
    }
    let meta = std::fs::metadata(path).map_err(|e| UsdError::file(path, e.to_string()))?;
    if !meta.is_file() {
        return Err(UsdError::file(path, "not a regular file"));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(UsdError::file(
            path,
            format!(
                "{} bytes is more than the reader's limit of {MAX_FILE_BYTES}",
                meta.len()
            ),
        ));
    }
    let Some(name) = path.to_str() else {
        return Err(UsdError::file(
            path,
            "the path is not UTF-8, which openusd needs",
        ));
    };
    // A crate file, or each one in a .usdz, is walked before openusd allocates what it declares ([`crate_check`]).
    crate_check::check(path).map_err(|e| UsdError::file(path, format!("malformed file: {e}")))?;
    let run = std::panic::AssertUnwindSafe(|| Reader::new(path, name, default_radius)?.read(root));
    match std::panic::catch_unwind(run) {
        Ok(result) => result,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            Err(UsdError::file(
                path,
                format!("malformed file: the USD parser failed ({what})"),
            ))
        }
    }
}

/// What `cuticle info` prints about a stage.
#[derive(Debug, Clone, PartialEq)]
pub struct UsdSummary {
    /// The file.
    pub path: PathBuf,
    /// Prims by type.
    pub prim_types: BTreeMap<String, usize>,
    /// Strands, segments and control points.
    pub strands: (usize, usize, usize),
    /// Meshes and their triangles.
    pub meshes: (usize, usize),
    /// Whether there is a camera.
    pub camera: bool,
    /// Lights read.
    pub lights: usize,
    /// Bounds of strands and meshes (min, max); `None` when there is no geometry.
    pub bounds: Option<(Vec3, Vec3)>,
    /// `upAxis` and `metersPerUnit`.
    pub units: (String, f64),
    /// Warnings.
    pub warnings: usize,
}

/// Reads the stage and sums it up for `cuticle info`.
pub fn summary(path: &Path, root: Option<&str>) -> Result<UsdSummary, UsdError> {
    let s = read(path, root, DEFAULT_RADIUS)?;
    let mut bounds: Option<(Vec3, Vec3)> = None;
    let mut grow = |b: (Vec3, Vec3)| {
        bounds = Some(bounds.map_or(b, |(lo, hi)| (lo.min(b.0), hi.max(b.1))));
    };
    if let Some(st) = &s.strands {
        grow(st.bounds());
    }
    s.meshes.iter().for_each(|m| grow(m.bounds()));
    Ok(UsdSummary {
        path: path.to_path_buf(),
        prim_types: s.prim_types.clone(),
        strands: s.strands.as_ref().map_or((0, 0, 0), |st| {
            (
                st.strand_count(),
                st.segment_count(),
                st.control_points.len(),
            )
        }),
        meshes: (
            s.meshes.len(),
            s.meshes.iter().map(|m| m.triangles.len()).sum(),
        ),
        camera: s.camera.is_some(),
        lights: s.lights.len(),
        bounds,
        units: (s.up_axis.clone(), s.meters_per_unit),
        warnings: s.warnings.len(),
    })
}

/// Radius of a USD curve without `widths`, in the stage's units: 0.005 (a width of 0.01: 100 µm in a stage in
/// centimetres, the unit DCCs write grooms in). USD leaves the default to the renderer; `hair.radius_scale`
/// scales it like any other radius.
pub const DEFAULT_RADIUS: f32 = 0.005;

impl fmt::Display for UsdSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let types: Vec<String> = self
            .prim_types
            .iter()
            .map(|(t, n)| format!("{n} {}", if t.is_empty() { "untyped" } else { t }))
            .collect();
        write!(
            f,
            "{}: usd, {} prims ({}); {} strands, {} segments; {} meshes, {} triangles; camera: {}; {} lights; up {}, {} m/unit",
            self.path.display(),
            self.prim_types.values().sum::<usize>(),
            types.join(", "),
            self.strands.0,
            self.strands.1,
            self.meshes.0,
            self.meshes.1,
            if self.camera { "yes" } else { "no" },
            self.lights,
            self.units.0,
            self.units.1,
        )?;
        if let Some((lo, hi)) = self.bounds {
            write!(f, "; bounds {:?} .. {:?}", lo.to_array(), hi.to_array())?;
        }
        if self.warnings > 0 {
            write!(f, "; {} warnings", self.warnings)?;
        }
        Ok(())
    }
}

/// One read in progress.
struct Reader<'a> {
    path: &'a Path,
    stage: usd::Stage,
    default_radius: f32,
    out: UsdStage,
}

/// An openusd error on `prim`.
fn usd_err(file: &Path, prim: &sdf::Path, e: anyhow::Error) -> UsdError {
    prim_err(file, prim, format!("{e:#}"))
}

/// A prim-level error.
fn prim_err(path: &Path, prim: &sdf::Path, message: impl Into<String>) -> UsdError {
    UsdError {
        path: path.to_path_buf(),
        prim: Some(prim.to_string()),
        message: message.into(),
    }
}

impl<'a> Reader<'a> {
    fn new(path: &'a Path, name: &str, default_radius: f32) -> Result<Self, UsdError> {
        let stage = usd::Stage::open(name)
            .map_err(|e| UsdError::file(path, format!("cannot open the stage: {e:#}")))?;
        Ok(Reader {
            path,
            stage,
            default_radius,
            out: UsdStage::default(),
        })
    }

    fn read(mut self, root: Option<&str>) -> Result<UsdStage, UsdError> {
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
        let mut stack = vec![(root_prim, world)];
        let mut strands = Strands::default();
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
                let world = self.world_of(&prim, parent)?;
                let ty = prim
                    .type_name()
                    .map_err(e)?
                    .map(|t| t.as_str().to_owned())
                    .unwrap_or_default();
                *self.out.prim_types.entry(ty.clone()).or_default() += 1;
                if prim.is_instance().map_err(e)? {
                    self.warn(
                        &ppath,
                        "instanced prim: its prototype's geometry is not read",
                    );
                }
                match ty.as_str() {
                    "BasisCurves" => {
                        let s = self.curves(&prim, world)?;
                        if s.strand_count() > 0 {
                            strands.append(&s);
                            self.out.curve_prims.push(ppath.to_string());
                        }
                    }
                    "Mesh" => {
                        let m = self.mesh(&prim, world)?;
                        self.out.meshes.push(m);
                    }
                    "Camera" => {
                        if self.out.camera.is_none() {
                            self.out.camera = Some(self.camera(&prim, world)?);
                        } else {
                            self.warn(&ppath, "a second camera: only the first is read");
                        }
                    }
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
                stack.push((c, world));
            }
        }
        if strands.strand_count() > 0 {
            self.out.strands = Some(strands);
        }
        Ok(self.out)
    }

    fn warn(&mut self, prim: &sdf::Path, message: &str) {
        self.out
            .warnings
            .push(format!("{}:{prim}: {message}", self.path.display()));
    }

    /// The value of `prim.name`: its default, else its earliest time sample (with a warning), else `None`.
    fn get(&mut self, prim: &usd::Prim, name: &str) -> Result<Option<sdf::Value>, UsdError> {
        let file = self.path;
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
    fn get_as<T>(
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
    fn interpolation(&self, prim: &usd::Prim, name: &str, default: &str) -> String {
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

    fn token(&mut self, prim: &usd::Prim, name: &str, default: &str) -> Result<String, UsdError> {
        Ok(self
            .get_as(prim, name, "a token", token)?
            .unwrap_or_else(|| default.to_owned()))
    }

    /// `parent` composed with the prim's `xformOpOrder`.
    fn world_of(&mut self, prim: &usd::Prim, parent: DMat4) -> Result<DMat4, UsdError> {
        let order: Vec<String> = match self.get(prim, "xformOpOrder")? {
            None => return Ok(parent),
            Some(sdf::Value::TokenVec(v)) => v.iter().map(|t| t.as_str().to_owned()).collect(),
            Some(sdf::Value::StringVec(v)) => v,
            Some(_) => {
                return Err(prim_err(
                    self.path,
                    prim.path(),
                    "xformOpOrder is not a token array",
                ))
            }
        };
        let mut world = parent;
        let mut local = DMat4::IDENTITY;
        for (i, op) in order.iter().enumerate() {
            if op == "!resetXformStack!" {
                if i != 0 {
                    return Err(prim_err(
                        self.path,
                        prim.path(),
                        format!(
                            "!resetXformStack! at position {i} of xformOpOrder (only the first)"
                        ),
                    ));
                }
                world = DMat4::IDENTITY;
                continue;
            }
            let (invert, name) = match op.strip_prefix("!invert!") {
                Some(n) => (true, n),
                None => (false, op.as_str()),
            };
            let m = self.op_matrix(prim, name)?;
            let m = if invert {
                if m.determinant().abs() < 1e-300 {
                    return Err(prim_err(
                        self.path,
                        prim.path(),
                        format!("{op}: a singular op cannot be inverted"),
                    ));
                }
                m.inverse()
            } else {
                m
            };
            // USD applies the ops from the last to the first: the first op is outermost.
            local *= m;
        }
        Ok(world * local)
    }

    /// One `xformOp:<kind>[:suffix]` as a column-vector matrix.
    fn op_matrix(&mut self, prim: &usd::Prim, name: &str) -> Result<DMat4, UsdError> {
        let kind = name
            .strip_prefix("xformOp:")
            .and_then(|k| k.split(':').next())
            .unwrap_or("");
        let bad = |what: &str| prim_err(self.path, prim.path(), format!("{name}: {what}"));
        let Some(v) = self.get(prim, name)? else {
            return Err(bad("named in xformOpOrder but has no value"));
        };
        let v3 = || vec3(&v).ok_or_else(|| bad("expected three numbers"));
        let s = || scalar(&v).ok_or_else(|| bad("expected a number"));
        let rot = |axis: char, deg: f64| match axis {
            'X' => DMat4::from_rotation_x(deg.to_radians()),
            'Y' => DMat4::from_rotation_y(deg.to_radians()),
            _ => DMat4::from_rotation_z(deg.to_radians()),
        };
        let m = match kind {
            "translate" => DMat4::from_translation(v3()?),
            "translateX" => DMat4::from_translation(DVec3::X * s()?),
            "translateY" => DMat4::from_translation(DVec3::Y * s()?),
            "translateZ" => DMat4::from_translation(DVec3::Z * s()?),
            "scale" => DMat4::from_scale(v3()?),
            "scaleX" => DMat4::from_scale(DVec3::new(s()?, 1.0, 1.0)),
            "scaleY" => DMat4::from_scale(DVec3::new(1.0, s()?, 1.0)),
            "scaleZ" => DMat4::from_scale(DVec3::new(1.0, 1.0, s()?)),
            "rotateX" | "rotateY" | "rotateZ" => rot(kind.as_bytes()[6] as char, s()?),
            "rotateXYZ" | "rotateXZY" | "rotateYXZ" | "rotateYZX" | "rotateZXY" | "rotateZYX" => {
                let a = v3()?;
                let angle = |c: char| match c {
                    'X' => a.x,
                    'Y' => a.y,
                    _ => a.z,
                };
                // rotateABC applies A first, then B, then C: R = R_C · R_B · R_A on column vectors.
                let axes: Vec<char> = kind[6..].chars().collect();
                rot(axes[2], angle(axes[2]))
                    * rot(axes[1], angle(axes[1]))
                    * rot(axes[0], angle(axes[0]))
            }
            "orient" => {
                let q = quat(&v).ok_or_else(|| bad("expected a quaternion"))?;
                DMat4::from_quat(q.normalize())
            }
            "transform" => match v {
                // USD's row-vector matrix, row-major, is the column-vector matrix, column-major.
                sdf::Value::Matrix4d(m) => DMat4::from_cols_array(&m.0),
                _ => return Err(bad("expected a matrix4d")),
            },
            _ => return Err(bad("unknown transform op")),
        };
        if !m.is_finite() {
            return Err(bad("not finite"));
        }
        Ok(m)
    }

    /// One `BasisCurves` prim as strands, world space.
    fn curves(&mut self, prim: &usd::Prim, world: DMat4) -> Result<Strands, UsdError> {
        let pp = prim.path().clone();
        let bad = |m: String| prim_err(self.path, &pp, m);
        let ty = self.token(prim, "type", "cubic")?;
        let basis_name = self.token(prim, "basis", "bezier")?;
        let wrap_name = self.token(prim, "wrap", "nonperiodic")?;
        let basis = match (ty.as_str(), basis_name.as_str()) {
            ("linear", _) => Basis::Linear,
            ("cubic", "bezier") => Basis::Bezier,
            ("cubic", "bspline") => Basis::BSpline,
            ("cubic", "catmullRom") => Basis::CatmullRom,
            ("cubic", b) => {
                return Err(bad(format!(
                    "unknown basis {b:?} (bezier, bspline, catmullRom)"
                )))
            }
            (t, _) => return Err(bad(format!("unknown curve type {t:?} (cubic, linear)"))),
        };
        let wrap = match wrap_name.as_str() {
            "nonperiodic" => Wrap::Nonperiodic,
            "periodic" => Wrap::Periodic,
            "pinned" => Wrap::Pinned,
            w => {
                return Err(bad(format!(
                    "unknown wrap {w:?} (nonperiodic, periodic, pinned)"
                )))
            }
        };
        let counts = self
            .get_as(prim, "curveVertexCounts", "an int array", ints)?
            .unwrap_or_default();
        let points = self
            .get_as(prim, "points", "a point array", vec3s)?
            .unwrap_or_default();
        // Counts against the points before anything is allocated for them.
        if let Some(c) = counts.iter().position(|&c| c < 0) {
            return Err(bad(format!("curveVertexCounts[{c}] is {}", counts[c])));
        }
        let total: u64 = counts.iter().map(|&c| c as u64).sum();
        if total != points.len() as u64 {
            return Err(bad(format!(
                "curveVertexCounts add up to {total} vertices but there are {} points",
                points.len()
            )));
        }
        if total > MAX_POINTS {
            return Err(bad(format!(
                "{total} vertices is more than the reader's limit of {MAX_POINTS}"
            )));
        }
        let mut segments = Vec::with_capacity(counts.len());
        for (i, &c) in counts.iter().enumerate() {
            let n = c as usize;
            let s = curves::segment_count(basis, wrap, n)
                .ok_or_else(|| bad(format!("curve {i} has {n} vertices: no {ty} {basis_name} {wrap_name} curve has that many")))?;
            segments.push(s);
        }
        let nvary: usize = counts
            .iter()
            .zip(&segments)
            .map(|(&c, &s)| curves::varying_count(basis, wrap, c as usize, s))
            .sum();
        let ncurves = counts.len();
        let expect = |interp: &str| match interp {
            "constant" => Some(1),
            "uniform" => Some(ncurves),
            "vertex" => Some(points.len()),
            "varying" | "faceVarying" => Some(nvary),
            _ => None,
        };
        // Widths: diameters; their interpolation defaults to vertex.
        let widths = self.get_as(prim, "widths", "a float array", floats)?;
        let widths_interp = self.interpolation(prim, "widths", "vertex");
        let widths = match widths {
            Some(w) if w.is_empty() => None,
            Some(w) => {
                let want = expect(&widths_interp).ok_or_else(|| {
                    bad(format!("widths: unknown interpolation {widths_interp:?}"))
                })?;
                if w.len() != want {
                    return Err(bad(format!(
                        "widths has {} values; {widths_interp} interpolation needs {want}",
                        w.len()
                    )));
                }
                if let Some(i) = w.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(bad(format!("widths[{i}] is {} (must be >= 0)", w[i])));
                }
                Some(w.into_iter().map(|w| 0.5 * w).collect::<Vec<f32>>())
            }
            None => None,
        };
        let color = self.primvar3(prim, "primvars:displayColor", &expect)?;
        let opacity = self.primvar1(prim, "primvars:displayOpacity", &expect)?;
        let pts: Vec<Vec3> = transform_points(&points, world);
        if let Some(i) = pts
            .iter()
            .position(|p| !p.is_finite() || p.abs().max_element() > crate::ray::MAX_SCENE_COORD)
        {
            return Err(bad(format!(
                "point {i} at {:?} is not finite or farther than {:e} from the origin",
                pts[i].to_array(),
                crate::ray::MAX_SCENE_COORD
            )));
        }
        let scale = world_radius_scale(world);
        // Each curve's colour and opacity: the primvar's value at its root.
        let (mut clamped_color, mut clamped_opacity) = (0usize, 0usize);
        let mut roots = Vec::with_capacity(ncurves);
        let (mut v, mut vary) = (0usize, 0usize);
        for (c, (&n, &s)) in counts.iter().zip(&segments).enumerate() {
            let pick = |interp: &str| match interp {
                "constant" => 0,
                "uniform" => c,
                "vertex" => v,
                _ => vary,
            };
            let col = color
                .as_ref()
                .map_or([1.0; 3], |(x, interp)| x[pick(interp)]);
            let col_c = col.map(|x| if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) });
            clamped_color += usize::from(col_c != col);
            let op = opacity.as_ref().map_or(1.0, |(x, interp)| x[pick(interp)]);
            let op_c = if op.is_nan() { 1.0 } else { op.clamp(0.0, 1.0) };
            clamped_opacity += usize::from(op_c.to_bits() != op.to_bits());
            roots.push((col_c, op_c));
            v += n as usize;
            vary += curves::varying_count(basis, wrap, n as usize, s);
        }
        let mut out = Strands::default();
        let mut clamped_radius = 0;
        let no_widths = widths.is_none();
        let pinned_bspline = basis == Basis::BSpline
            && wrap == Wrap::Pinned
            && widths_interp != "varying"
            && widths_interp != "faceVarying";
        if pinned_bspline {
            // The `.hair` path: one model, converted by `Strands::from_model` (phantoms, taper without widths).
            let mut model = HairModel {
                points: pts,
                strand_offsets: Vec::with_capacity(ncurves + 1),
                radius: Vec::with_capacity(points.len()),
                radius_from_file: !no_widths,
                transparency: Vec::with_capacity(points.len()),
                color: Vec::with_capacity(points.len()),
                format: "usd".into(),
                info: String::new(),
            };
            model.strand_offsets.push(0);
            let mut v = 0usize;
            for (c, &n) in counts.iter().enumerate() {
                let n = n as usize;
                let (col, op) = roots[c];
                for i in 0..n {
                    let r = match &widths {
                        None => self.default_radius,
                        Some(w) => match widths_interp.as_str() {
                            "constant" => w[0],
                            "uniform" => w[c],
                            _ => w[v + i],
                        },
                    };
                    model.radius.push(r * scale);
                }
                model.transparency.extend(std::iter::repeat_n(1.0 - op, n));
                model.color.extend(std::iter::repeat_n(col, n));
                v += n;
                model.strand_offsets.push(v as u32);
            }
            out = Strands::from_model(&model);
            // The opacity as the file gives it (not 1 − (1 − opacity)).
            for (o, r) in out.opacity.iter_mut().zip(&roots) {
                *o = r.1;
            }
        } else {
            let (mut cps, mut first) = (Vec::new(), Vec::new());
            let (mut v, mut vary) = (0usize, 0usize);
            let mut taper = Vec::new();
            for (c, (&n, &s)) in counts.iter().zip(&segments).enumerate() {
                let n = n as usize;
                let nv = curves::varying_count(basis, wrap, n, s);
                let scaled: Vec<f32>;
                let radius = match (&widths, widths_interp.as_str()) {
                    (None, _) => {
                        taper.clear();
                        taper.extend((0..n).map(|i| {
                            self.default_radius * scale * (1.0 - 0.5 * i as f32 / (n - 1) as f32)
                        }));
                        Radius::Vertex(&taper)
                    }
                    (Some(w), "constant") => Radius::Constant(w[0] * scale),
                    (Some(w), "uniform") => Radius::Constant(w[c] * scale),
                    (Some(w), "vertex") => {
                        scaled = w[v..v + n].iter().map(|r| r * scale).collect();
                        Radius::Vertex(&scaled)
                    }
                    (Some(w), _) => {
                        scaled = w[vary..vary + nv].iter().map(|r| r * scale).collect();
                        Radius::Varying(&scaled)
                    }
                };
                cps.clear();
                first.clear();
                clamped_radius +=
                    curves::convert(basis, wrap, &pts[v..v + n], radius, &mut cps, &mut first);
                let (col, op) = roots[c];
                out.push_strand(&cps, &first, op, col)
                    .ok_or_else(|| bad(format!("curve {c}: no segment")))?;
                v += n;
                vary += nv;
            }
        }
        if clamped_radius > 0 {
            self.warn(&pp, &format!("{clamped_radius} converted control point radii were below 0 and are clamped to 0"));
        }
        if clamped_color > 0 {
            self.warn(
                &pp,
                &format!("displayColor of {clamped_color} curves clamped to [0, 1]"),
            );
        }
        if clamped_opacity > 0 {
            self.warn(
                &pp,
                &format!("displayOpacity of {clamped_opacity} curves clamped to [0, 1]"),
            );
        }
        if scale != 1.0 {
            self.warn(
                &pp,
                &format!("widths scaled by the transform's mean scale {scale}"),
            );
        }
        Ok(out)
    }

    /// A colour primvar and its interpolation, its length checked against `expect`.
    #[allow(clippy::type_complexity)]
    fn primvar3(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Option<(Vec<[f32; 3]>, String)>, UsdError> {
        let Some(v) = self.get_as(prim, name, "a colour array", vec3s)? else {
            return Ok(None);
        };
        if v.is_empty() {
            return Ok(None);
        }
        let interp = self.interpolation(prim, name, "constant");
        self.check_len(prim, name, v.len(), &interp, expect)?;
        Ok(Some((
            v.into_iter().map(|c| c.to_array()).collect(),
            interp,
        )))
    }

    /// A float primvar and its interpolation, its length checked against `expect`.
    fn primvar1(
        &mut self,
        prim: &usd::Prim,
        name: &str,
        expect: &dyn Fn(&str) -> Option<usize>,
    ) -> Result<Option<(Vec<f32>, String)>, UsdError> {
        let Some(v) = self.get_as(prim, name, "a float array", floats)? else {
            return Ok(None);
        };
        if v.is_empty() {
            return Ok(None);
        }
        let interp = self.interpolation(prim, name, "constant");
        self.check_len(prim, name, v.len(), &interp, expect)?;
        Ok(Some((v, interp)))
    }

    fn check_len(
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

    /// One `Mesh` prim, fanned into triangles, world space.
    fn mesh(&mut self, prim: &usd::Prim, world: DMat4) -> Result<TriangleMesh, UsdError> {
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
    fn material_color(&mut self, prim: &usd::Prim) -> Result<Option<[f32; 3]>, UsdError> {
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

    fn camera(&mut self, prim: &usd::Prim, world: DMat4) -> Result<UsdCamera, UsdError> {
        let f = self
            .get_as(prim, "focalLength", "a number", scalar)?
            .unwrap_or(50.0);
        let h = self.get_as(prim, "horizontalAperture", "a number", scalar)?;
        let v = self.get_as(prim, "verticalAperture", "a number", scalar)?;
        let (hv, vv) = (h.unwrap_or(20.955), v.unwrap_or(15.2908));
        if !(f > 0.0 && vv > 0.0 && hv > 0.0) {
            return Err(prim_err(
                self.path,
                prim.path(),
                format!("focalLength {f} and apertures {hv} × {vv} must be > 0"),
            ));
        }
        let dir = |d: DVec3| world.transform_vector3(d).normalize_or_zero().as_vec3();
        let cam = UsdCamera {
            position: world.transform_point3(DVec3::ZERO).as_vec3(),
            forward: dir(DVec3::NEG_Z),
            up: dir(DVec3::Y),
            vertical_fov_degrees: (2.0 * (vv / (2.0 * f)).atan()).to_degrees() as f32,
            aspect: (h.is_some() || v.is_some()).then_some((hv / vv) as f32),
        };
        if cam.forward == Vec3::ZERO || cam.up == Vec3::ZERO || !cam.position.is_finite() {
            return Err(prim_err(
                self.path,
                prim.path(),
                "the camera's transform is degenerate",
            ));
        }
        Ok(cam)
    }

    fn light(&mut self, prim: &usd::Prim, ty: &str, world: DMat4) -> Result<UsdLight, UsdError> {
        let num = |s: &mut Self, name: &str, default: f64| -> Result<f32, UsdError> {
            let v = match s.get_as(prim, &format!("inputs:{name}"), "a number", scalar)? {
                Some(v) => Some(v),
                None => s.get_as(prim, name, "a number", scalar)?,
            };
            Ok(v.unwrap_or(default) as f32)
        };
        let intensity = num(self, "intensity", 1.0)?;
        let exposure = num(self, "exposure", 0.0)?;
        let color = match self.get_as(prim, "inputs:color", "a colour", vec3)? {
            Some(c) => Some(c),
            None => self.get_as(prim, "color", "a colour", vec3)?,
        }
        .map_or(Vec3::ONE, |c| c.as_vec3());
        if ty == "DistantLight" {
            let angle = num(self, "angle", 0.53)?;
            let d = world
                .transform_vector3(DVec3::Z)
                .normalize_or_zero()
                .as_vec3();
            if d == Vec3::ZERO {
                return Err(prim_err(
                    self.path,
                    prim.path(),
                    "the light's transform is degenerate",
                ));
            }
            Ok(UsdLight::Distant {
                direction_to_light: d,
                color,
                intensity,
                exposure,
                angle_degrees: angle,
            })
        } else {
            let texture = match self.get(prim, "inputs:texture:file")? {
                Some(sdf::Value::AssetPath(a)) if !a.as_str().is_empty() => {
                    let p = PathBuf::from(a.resolved_path().unwrap_or(a.as_str()));
                    Some(if p.is_relative() {
                        self.path.parent().unwrap_or(Path::new("")).join(p)
                    } else {
                        p
                    })
                }
                _ => None,
            };
            if world
                .transform_vector3(DVec3::Y)
                .normalize_or_zero()
                .dot(DVec3::Y)
                < 1.0 - 1e-9
                && texture.is_some()
            {
                self.warn(
                    prim.path(),
                    "the dome's rotation is not applied to its texture",
                );
            }
            Ok(UsdLight::Dome {
                color,
                intensity,
                exposure,
                texture,
            })
        }
    }
}

/// Points moved by `m` (in f64, rounded once); the identity leaves them bit for bit.
fn transform_points(points: &[Vec3], m: DMat4) -> Vec<Vec3> {
    if m == DMat4::IDENTITY {
        return points.to_vec();
    }
    points
        .iter()
        .map(|p| m.transform_point3(p.as_dvec3()).as_vec3())
        .collect()
}

/// The factor a transform scales widths by: the cube root of |det|, the mean scale (exact for uniform scale).
fn world_radius_scale(m: DMat4) -> f32 {
    let d = m.determinant().abs();
    if (d - 1.0).abs() < 1e-12 {
        1.0
    } else {
        d.cbrt() as f32
    }
}

fn scalar(v: &sdf::Value) -> Option<f64> {
    Some(match v {
        sdf::Value::Float(x) => f64::from(*x),
        sdf::Value::Double(x) => *x,
        sdf::Value::Half(x) => f64::from(x.to_f32()),
        sdf::Value::Int(x) => f64::from(*x),
        _ => return None,
    })
}

fn token(v: &sdf::Value) -> Option<String> {
    match v {
        sdf::Value::Token(t) => Some(t.as_str().to_owned()),
        sdf::Value::String(s) => Some(s.clone()),
        _ => None,
    }
}

fn vec3(v: &sdf::Value) -> Option<DVec3> {
    Some(match v {
        sdf::Value::Vec3f(a) => DVec3::new(a.x.into(), a.y.into(), a.z.into()),
        sdf::Value::Vec3d(a) => DVec3::new(a.x, a.y, a.z),
        sdf::Value::Vec3h(a) => DVec3::new(a.x.to_f64(), a.y.to_f64(), a.z.to_f64()),
        // A one-element colour array (`color3f[] displayColor = [(…)]`).
        sdf::Value::Vec3fVec(a) if a.len() == 1 => {
            DVec3::new(a[0].x.into(), a[0].y.into(), a[0].z.into())
        }
        _ => return None,
    })
}

fn quat(v: &sdf::Value) -> Option<DQuat> {
    Some(match v {
        sdf::Value::Quatf(q) => DQuat::from_xyzw(q.x.into(), q.y.into(), q.z.into(), q.w.into()),
        sdf::Value::Quatd(q) => DQuat::from_xyzw(q.x, q.y, q.z, q.w),
        sdf::Value::Quath(q) => {
            DQuat::from_xyzw(q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64())
        }
        _ => return None,
    })
}

fn vec3s(v: &sdf::Value) -> Option<Vec<Vec3>> {
    Some(match v {
        sdf::Value::Vec3fVec(a) => a.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        sdf::Value::Vec3dVec(a) => a
            .iter()
            .map(|p| DVec3::new(p.x, p.y, p.z).as_vec3())
            .collect(),
        sdf::Value::Vec3hVec(a) => a
            .iter()
            .map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()))
            .collect(),
        _ => return None,
    })
}

fn floats(v: &sdf::Value) -> Option<Vec<f32>> {
    Some(match v {
        sdf::Value::FloatVec(a) => a.clone(),
        sdf::Value::DoubleVec(a) => a.iter().map(|&x| x as f32).collect(),
        sdf::Value::HalfVec(a) => a.iter().map(|x| x.to_f32()).collect(),
        sdf::Value::Float(x) => vec![*x],
        _ => return None,
    })
}

fn ints(v: &sdf::Value) -> Option<Vec<i64>> {
    Some(match v {
        sdf::Value::IntVec(a) => a.iter().map(|&x| i64::from(x)).collect(),
        sdf::Value::Int64Vec(a) => a.clone(),
        _ => return None,
    })
}

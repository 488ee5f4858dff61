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
//! - **Units**: `upAxis` and `metersPerUnit` are reported; points stay in the stage's space (a Z-up stage is read
//!   as it is, and `cuticle render` of it stands its default camera and sun along +z: [`crate::scene`]).
//! - **Curves** ([`curves`]): every basis, wrap and width interpolation converted exactly; `widths` are diameters.
//!   Without widths every curve gets `default_radius`, tapered to half at the tip like a `.hair` file without
//!   thickness ([`Strands::from_model`], thesis §5.2); authored widths are used as they are. Pinned B-splines go
//!   through [`Strands::from_model`], so a `.hair` strand written as a pinned B-spline reads back bit for bit.
//!   `primvars:displayColor` and `primvars:displayOpacity` give the strand's colour and opacity at its root
//!   (clamped to [0, 1], with a warning).
//! - **Meshes**: polygons fanned into triangles; `leftHanded` reverses the winding. The albedo is the bound
//!   `UsdPreviewSurface`'s `diffuseColor`, constant or a `UsdUVTexture` ([`materials`]); without one,
//!   `displayColor` (constant, uniform, vertex, faceVarying) as the corner albedo; else 0.5 grey with a warning.
//!   Indexed primvars (`<name>:indices`) are expanded.
//! - **Lights**: `DistantLight` and `DomeLight`; other lights are skipped with a warning.
//! - **Instancing**: instanceable prims through their instance proxies (the composed stage puts a prototype's
//!   children under every instance); `PointInstancer`s by placing their prototypes ([`instancer`]).
//! - **Left out**, with their subtrees, as a final frame leaves them: `visibility = "invisible"` and `purpose`
//!   `guide` or `proxy` ([`Skipped`] counts them).
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

mod basis_curves;
mod camera;
mod crate_check;
pub mod curves;
mod instancer;
mod lux;
mod materials;
mod meshes;
mod reader;
mod values;
mod xform;

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::hair::Strands;
use crate::mesh::TriangleMesh;

use reader::{prim_err, Reader};

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
    /// `Mesh` prims a final frame shows (read or not: [`read_parts`]).
    pub mesh_prims: usize,
    /// The first `Camera` prim in traversal order.
    pub camera: Option<UsdCamera>,
    /// `DistantLight` and `DomeLight` prims.
    pub lights: Vec<UsdLight>,
    /// Prims traversed, by type name (`""` for typeless prims).
    pub prim_types: BTreeMap<String, usize>,
    /// The stage's `upAxis` ("Y" when not authored); points are not turned by it.
    pub up_axis: String,
    /// The stage's `metersPerUnit` (0.01 when not authored); reported, not applied.
    pub meters_per_unit: f64,
    /// Prims left out with their subtrees because a final frame does not show them.
    pub skipped: Skipped,
    /// What was skipped or approximated, one line each.
    pub warnings: Vec<String>,
}

/// Prims left out, with their subtrees, by what marks them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Skipped {
    /// `visibility = "invisible"`.
    pub invisible: usize,
    /// `purpose = "guide"` (a groom's guide curves).
    pub guide: usize,
    /// `purpose = "proxy"` (a preview stand-in for render geometry).
    pub proxy: usize,
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
    read_parts(path, root, default_radius, Parts::ALL)
}

/// Which geometry a read converts; the camera, lights, units and prim counts are always read. A scene that takes
/// its hair, its head and its camera from one stage reads each part once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Parts {
    /// `BasisCurves` as strands.
    pub curves: bool,
    /// `Mesh` prims as triangle meshes (their textures decoded).
    pub meshes: bool,
}

impl Parts {
    /// Curves and meshes.
    pub const ALL: Parts = Parts {
        curves: true,
        meshes: true,
    };
    /// Neither: the camera, lights and counts.
    pub const NONE: Parts = Parts {
        curves: false,
        meshes: false,
    };
}

/// [`read`], converting only the geometry `parts` names ([`UsdStage::mesh_prims`] counts the meshes left).
pub fn read_parts(
    path: &Path,
    root: Option<&str>,
    default_radius: f32,
    parts: Parts,
) -> Result<UsdStage, UsdError> {
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
    let run =
        std::panic::AssertUnwindSafe(|| Reader::new(path, name, default_radius, parts)?.read(root));
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
    /// Prims left out as invisible, guides or proxies.
    pub skipped: Skipped,
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
        skipped: s.skipped,
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
        let k = self.skipped;
        if k.invisible + k.guide + k.proxy > 0 {
            write!(
                f,
                "; left out: {} invisible, {} guide, {} proxy prims",
                k.invisible, k.guide, k.proxy
            )?;
        }
        if self.warnings > 0 {
            write!(f, "; {} warnings", self.warnings)?;
        }
        Ok(())
    }
}

//! [`Scene`] (being assembled) → [`Scene::commit`] → [`CommittedScene`] (immutable, queried from many threads; its
//! queries are in `query.rs`).

use std::fmt;
use std::sync::Arc;

use super::device::{Device, DeviceHandle};
use super::error::{EmbreeError, ErrorCode};
use super::ffi::*;
use super::geometry::CurveGeometry;
use super::triangles::TriangleGeometry;

/// BVH build quality (`RTCBuildQuality`): higher builds slower and traces faster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BuildQuality {
    /// `RTC_BUILD_QUALITY_LOW`: Morton-code build, for geometry that changes every frame.
    Low,
    /// `RTC_BUILD_QUALITY_MEDIUM`: SAH build (Embree's default).
    #[default]
    Medium,
    /// `RTC_BUILD_QUALITY_HIGH`: SAH with spatial splits; suits long, diagonal strands.
    High,
}

impl BuildQuality {
    fn raw(self) -> RTCBuildQuality {
        match self {
            BuildQuality::Low => RTC_BUILD_QUALITY_LOW,
            BuildQuality::Medium => RTC_BUILD_QUALITY_MEDIUM,
            BuildQuality::High => RTC_BUILD_QUALITY_HIGH,
        }
    }
}

/// How Embree lays out the BVH's leaves (`RTC_SCENE_FLAG_COMPACT`). For curves, Embree 3.13 on AVX2 builds
/// `bvh8obb.virtualcurve8v` (each leaf holds a copy of its segments' control points) by default and
/// `bvh4obb.virtualcurve8i` (leaves hold indices into the vertex buffer) when compact (`Scene::createHairAccel`);
/// the build quality does not change the curve builder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// Embree's default: control points copied into the leaves, fastest to trace.
    #[default]
    Fast,
    /// `RTC_SCENE_FLAG_COMPACT`: leaves index the vertex buffer; less memory per segment.
    Compact,
}

/// Scene flags for every scene: per-query filter functions on (the transparent-shadow filter is passed with the
/// query); robust traversal off (it costs speed, and the brute-force tests in `tests/embree.rs` match without it);
/// not dynamic (hair is built once); not compact (compact layouts trade speed for memory).
#[cfg(not(embree4))]
const SCENE_FLAGS: RTCSceneFlags = RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION;
/// Scene flags for every scene (Embree 4 spelling; see the Embree 3 constant for the reasons).
#[cfg(embree4)]
const SCENE_FLAGS: RTCSceneFlags = RTC_SCENE_FLAG_FILTER_FUNCTION_IN_ARGUMENTS;

/// A scene being assembled. [`Scene::commit`] builds the BVH and turns it into a [`CommittedScene`].
pub struct Scene {
    raw: RTCScene,
    device: Arc<DeviceHandle>,
    /// Keeps every attached curve geometry, and so its strand table (the filter's user data), alive.
    geometries: Vec<CurveGeometry>,
    /// Keeps every attached triangle geometry alive.
    triangles: Vec<TriangleGeometry>,
}

// SAFETY: an Embree scene has no thread affinity; mutation needs `&mut self`.
unsafe impl Send for Scene {}

impl fmt::Debug for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Scene")
            .field("geometries", &self.geometries)
            .field("triangles", &self.triangles)
            .finish()
    }
}

impl Scene {
    /// An empty static scene with per-query filter functions enabled and robust traversal off.
    pub fn new(device: &Device, quality: BuildQuality) -> Result<Scene, EmbreeError> {
        Self::with_layout(device, quality, Layout::Fast)
    }

    /// [`Scene::new`] with a choice of BVH [`Layout`].
    pub fn with_layout(
        device: &Device,
        quality: BuildQuality,
        layout: Layout,
    ) -> Result<Scene, EmbreeError> {
        let flags = match layout {
            Layout::Fast => SCENE_FLAGS,
            Layout::Compact => SCENE_FLAGS | RTC_SCENE_FLAG_COMPACT,
        };
        Self::with_flags(device, quality, flags)
    }

    /// An empty static scene in Embree's robust mode (`RTC_SCENE_FLAG_ROBUST`), for triangle meshes: Embree then
    /// intersects triangles with its watertight Plücker test instead of the faster Möller–Trumbore test (which
    /// lets rays through shared edges and vertices) and avoids the traversal shortcuts that lose precision.
    pub fn robust(device: &Device, quality: BuildQuality) -> Result<Scene, EmbreeError> {
        Self::with_flags(device, quality, SCENE_FLAGS | RTC_SCENE_FLAG_ROBUST)
    }

    fn with_flags(
        device: &Device,
        quality: BuildQuality,
        flags: RTCSceneFlags,
    ) -> Result<Scene, EmbreeError> {
        let handle = &device.inner;
        let raw = handle.call("create scene", || {
            // SAFETY: `handle.raw` is a live device.
            unsafe { rtcNewScene(handle.raw) }
        })?;
        if raw.is_null() {
            return Err(EmbreeError {
                code: ErrorCode::Unknown,
                message: "create scene: embree returned no scene".into(),
            });
        }
        let scene = Scene {
            raw,
            device: Arc::clone(handle),
            geometries: Vec::new(),
            triangles: Vec::new(),
        };
        scene.device.call("configure scene", || {
            // SAFETY: `raw` is a live scene and `flags` a combination of the header's flags.
            unsafe { rtcSetSceneFlags(raw, flags) };
            // SAFETY: `raw` is a live scene and the quality one of the header's constants.
            unsafe { rtcSetSceneBuildQuality(raw, quality.raw()) };
        })?;
        Ok(scene)
    }

    /// Attaches `geometry` and returns its geometry id (Embree's `geomID`). The scene keeps the geometry.
    ///
    /// Embree itself rejects a geometry created on another device (`invalid argument`).
    pub fn attach(&mut self, geometry: CurveGeometry) -> Result<u32, EmbreeError> {
        let id = self.device.call("attach geometry", || {
            // SAFETY: both handles are live; Embree checks that they belong to the same device.
            unsafe { rtcAttachGeometry(self.raw, geometry.raw) }
        })?;
        self.geometries.push(geometry);
        Ok(id)
    }

    /// Attaches a triangle mesh and returns its geometry id (Embree's `geomID`, counted with the curve geometries
    /// in attachment order). The scene keeps the geometry.
    pub fn attach_triangles(&mut self, geometry: TriangleGeometry) -> Result<u32, EmbreeError> {
        let id = self.device.call("attach triangle geometry", || {
            // SAFETY: both handles are live; Embree checks that they belong to the same device.
            unsafe { rtcAttachGeometry(self.raw, geometry.raw) }
        })?;
        self.triangles.push(geometry);
        Ok(id)
    }

    /// Builds the BVH. Only a committed scene can be traced.
    pub fn commit(self) -> Result<CommittedScene, EmbreeError> {
        self.device.call("commit scene", || {
            // SAFETY: `raw` is a live scene whose geometries are all committed.
            unsafe { rtcCommitScene(self.raw) }
        })?;
        Ok(CommittedScene { scene: self })
    }
}

impl Drop for Scene {
    fn drop(&mut self) {
        self.device.release("release scene", || {
            // SAFETY: we own one reference to `raw` and give it up exactly once, before the geometries (and their
            // strand tables) are dropped.
            unsafe { rtcReleaseScene(self.raw) }
        });
    }
}

/// A committed scene: immutable, and safe to query from many threads at once.
#[derive(Debug)]
pub struct CommittedScene {
    scene: Scene,
}

// SAFETY: Embree allows concurrent `rtcIntersect1`/`rtcOccluded1` on a committed scene that nobody modifies, and
// `CommittedScene` offers no way to modify it; every query keeps its own context and ray on its own stack, and the
// shared strand tables are immutable.
unsafe impl Sync for CommittedScene {}

impl CommittedScene {
    pub(super) fn raw(&self) -> RTCScene {
        self.scene.raw
    }

    /// The device the scene lives on (for [`DeviceHandle::after_query`]).
    pub(super) fn device(&self) -> &DeviceHandle {
        &self.scene.device
    }

    /// The curve geometries in the scene, in the order they were attached.
    pub fn geometries(&self) -> &[CurveGeometry] {
        &self.scene.geometries
    }

    /// The triangle geometries in the scene, in the order they were attached.
    pub fn triangle_geometries(&self) -> &[TriangleGeometry] {
        &self.scene.triangles
    }
}

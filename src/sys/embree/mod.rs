//! Safe wrappers over Embree: the only place in cuticle that calls into `libembree`.
//!
//! Embree 3.13 (Debian 12) is the version this module is built and tested against. When `build.rs` finds Embree 4
//! it sets `cfg(embree4)`; the Embree 4 paths below (`#[cfg(embree4)]`) follow the Embree 4 headers
//! (`rtcore_common.h`, `rtcore_ray.h`, `rtcore_scene.h`) and are built and tested against Embree 4.4 with 4.2's
//! headers (`scripts/embree4.sh`, run by `.ci/run`); `ffi.rs` leaves room for the fields 4.3+ added.
//!
//! # Objects and who owns what
//! - [`Device`]: one Embree device. Its error callback and memory monitor write into a boxed state that the device
//!   owns and frees only after unregistering both callbacks. Cloning a `Device` shares the handle; scenes and
//!   geometries hold it too, so the device outlives them.
//! - [`CurveGeometry`]: B-spline curves (round tubes or flat ribbons) from `float4` control points `(x, y, z, r)`
//!   and one `u32` per segment (its first control point). Embree copies both arrays into buffers it owns. Each
//!   geometry carries a [`StrandTable`] (segment → strand, strand → opacity) as its Embree user data, which is
//!   what the transparent-shadow filter reads.
//! - [`TriangleGeometry`]: a triangle mesh from `float3` positions and `uint3` indices, copied into Embree-owned
//!   buffers. A [`Scene::robust`] scene traces it with Embree's watertight triangle test; its hits report the
//!   triangle as `primID` and Embree's barycentrics (u, v).
//! - [`Scene`] (being built) → [`Scene::commit`] → [`CommittedScene`]: only a committed scene answers queries
//!   (Embree does not check this in release builds), and it is `Send + Sync`.
//!
//! # Queries
//! [`CommittedScene::intersect1`] finds the closest hit. [`CommittedScene::transmittance1`] runs an occlusion query
//! whose filter function rejects every hit (so traversal continues) and multiplies the transmittance by
//! `1 − opacity` once per **strand** — round curves report one crossing several times (front and back of the
//! tube, and both segments at a joint), so neither primitive ids nor distances de-duplicate correctly.
//! [`CommittedScene::intersect1_stochastic`] and [`CommittedScene::occluded1_stochastic`] see only the strands a
//! caller's presence test keeps for the ray (a closure `present(strand, opacity)`, called by their filter once per
//! candidate hit).
//!
//! The packet queries ([`CommittedScene::intersect_packet`], [`CommittedScene::intersect_packet_stochastic`],
//! [`CommittedScene::occluded_packet`], [`CommittedScene::occluded_packet_stochastic`]) trace 8 or 16 rays with one
//! `rtcIntersect8/16` or `rtcOccluded8/16` call and report per lane what the single-ray query would; the
//! stochastic ones take one presence test `present(lane, strand, opacity)` for the packet, and their filter finds
//! each hit's lane from the ray's `id`.
//!
//! Every query first validates its ray with [`Ray::check`](crate::ray::Ray::check): Debian's libembree3 has
//! assertions on and aborts the process on a NaN/Inf ray, a negative `tnear` or an origin beyond ~1.8e18.
//!
//! # Errors
//! Embree reports errors through the device's error callback; every wrapper call that can fail checks for an error
//! recorded on the calling thread (and clears Embree's per-thread error code) and returns it as an
//! [`EmbreeError`].
//!
//! # Dependencies
//! `std`, `glam` (`Vec3` in [`RayHit`]), `thiserror`, the bindgen output, and from the crate only `crate::ray`
//! ([`Ray`](crate::ray::Ray), [`InvalidRay`](crate::ray::InvalidRay), [`MAX_ORIGIN`](crate::ray::MAX_ORIGIN)): the
//! plain ray every query takes and validates. Nothing from the layers above: which strands a stochastic query sees
//! is their decision, passed down as the presence test (`accel` passes its `strand_present` hash under the ray's
//! key).
//!
//! # Files
//! - `ffi.rs`: bindgen's output and hand-written replacements for what it cannot translate.
//! - `error.rs`: [`EmbreeError`] and its [`ErrorCode`].
//! - `device.rs`: [`Device`], its callbacks and their state.
//! - `geometry.rs`: [`StrandTable`] and [`CurveGeometry`].
//! - `triangles.rs`: [`TriangleGeometry`].
//! - `scene.rs`: [`Scene`], [`BuildQuality`] and [`CommittedScene`].
//! - `query.rs`: the queries of a [`CommittedScene`] and their results ([`RayHit`], [`Transmittance`]).
//! - `packet.rs`: the packet queries of a [`CommittedScene`] (8 or 16 rays per call).
//! - `filter.rs`: the filter functions Embree calls per candidate hit, and the per-query payloads they use.
#![warn(unsafe_op_in_unsafe_fn)]

mod device;
mod error;
mod ffi;
mod filter;
mod geometry;
mod packet;
mod query;
mod scene;
mod triangles;

pub use device::Device;
pub use error::{EmbreeError, ErrorCode};
pub use filter::{Cutoff, SEEN_STRANDS, TRANSMITTANCE_CUTOFF};
pub use geometry::{CurveBasis, CurveGeometry, StrandTable};
pub use packet::PACKET_WIDTHS;
pub use query::{RayHit, Transmittance};
pub use scene::{BuildQuality, CommittedScene, Layout, Scene};
pub use triangles::TriangleGeometry;

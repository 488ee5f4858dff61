//! The hair frame of thesis §4.1 (Marschner et al. 2003's notation) and the angles every model is written in.
//!
//! - u: the tangent, root → tip. v, w: span the normal plane, u × v = w (right-handed).
//! - θ ∈ [−π/2, π/2]: the longitudinal angle from the normal plane, sin θ = ω·u (θ = π/2 is u, −π/2 is −u).
//! - φ ∈ [−π, π]: the azimuth of ω projected on the normal plane, φ = atan2(ω·w, ω·v) (0 is v, π/2 is w).
//! - θh = (θr + θi)/2, θd = (θr − θi)/2, relative φ = φr − φi wrapped to [−π, π], with r the reflected (view,
//!   `wo`) and i the incident (light, `wi`) direction, both pointing away from the fibre.
//!
//! Local coordinates are (ω·u, ω·v, ω·w) (thesis eq. 22): **x is the tangent component**. The thesis' shader
//! read the wrong coordinate index when converting to spherical coordinates (§8.1); the tests below pin the
//! conversion with directions whose θ, φ, θh and θd are known.
//!
//! # Where v comes from
//!
//! - **Round curves** ([`HairFrame::from_round_curve`]): v is the outward surface normal at the hit, made
//!   orthogonal to u. Embree's geometric normal `Ng` for round curves points outward but is not unit length
//!   (and not exactly orthogonal to the tangent), so it is projected and normalised here.
//! - **Flat ribbons** ([`HairFrame::from_ribbon`]): a ribbon has no outward normal worth the name, so, as the
//!   thesis did (§5.3.1), v is the Gram-Schmidt orthogonalisation of a per-strand noise vector against u
//!   ([`strand_noise`]). The azimuth φ is then arbitrary per strand (fixed along a strand, random across
//!   strands). Every model in this module depends on φr and φi only through φ = φr − φi, so that arbitrary
//!   rotation changes nothing they compute. [`super::chiang`] also uses the offset h across the fibre, which the
//!   integrator takes from the hit (Embree's v across the ribbon), not from this frame, so it is unaffected too;
//!   an elliptical cross-section would not be (not implemented).

use crate::util::hash::{hash64, unit_f32};
use crate::util::real::Real;
use crate::util::sampling::uniform_sphere;
use glam::Vec3;
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

/// Smallest cos θ a model divides by (θ within 0.0057° of the tangent). Solid-angle pdfs carry 1/cos θi and
/// Marschner-type f carries 1/cos²θd; both are integrable singularities, and clamping here keeps every value
/// finite while changing the integrals by a solid angle of about π·1e-8 sr.
pub const COS_THETA_MIN: f32 = 1e-4;

/// The θh range [θr/2 − π/4, θr/2 + π/4] of a view at `theta_r` (θi = 2θh − θr ∈ [−π/2, π/2]), in f64: the
/// interval every model's θh distribution is truncated to.
#[inline]
pub fn theta_h_range(theta_r: f32) -> (f64, f64) {
    let c = 0.5 * theta_r as f64;
    let q = std::f64::consts::FRAC_PI_4;
    (c - q, c + q)
}

/// An orthonormal hair frame (u, v, w) in world space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HairFrame {
    /// Tangent, root → tip.
    pub u: Vec3,
    /// First normal-plane axis (φ = 0).
    pub v: Vec3,
    /// Second normal-plane axis (φ = π/2), u × v.
    pub w: Vec3,
}

impl HairFrame {
    /// The frame of a round curve: u = `tangent` (normalised), v = the component of Embree's outward geometric
    /// normal `ng` orthogonal to u, normalised. If `ng` is (nearly) parallel to u or zero, v is any vector
    /// orthogonal to u.
    pub fn from_round_curve(tangent: Vec3, ng: Vec3) -> HairFrame {
        Self::gram_schmidt(tangent, ng)
    }

    /// The frame of a flat ribbon (thesis §5.3.1): v = Gram-Schmidt of the per-strand `noise` vector against u
    /// (see [`strand_noise`] and the module docs for the consequence: φ is arbitrary per strand).
    pub fn from_ribbon(tangent: Vec3, noise: Vec3) -> HairFrame {
        Self::gram_schmidt(tangent, noise)
    }

    /// u = normalised `tangent` (x axis if zero), v = `a` − (a·u)u normalised, w = u × v.
    fn gram_schmidt(tangent: Vec3, a: Vec3) -> HairFrame {
        let u = tangent.try_normalize().unwrap_or(Vec3::X);
        let v = a - u * a.dot(u);
        // Guard: `a` (nearly) parallel to u leaves only rounding noise, which would not be orthogonal to u.
        let v = if v.length_squared() > 1e-8 * a.length_squared() {
            v.normalize()
        } else {
            u.any_orthonormal_vector()
        };
        HairFrame {
            u,
            v,
            w: u.cross(v),
        }
    }

    /// World → local hair frame (thesis eq. 22): (ω·u, ω·v, ω·w).
    #[inline]
    pub fn to_local(&self, world: Vec3) -> Vec3 {
        Vec3::new(world.dot(self.u), world.dot(self.v), world.dot(self.w))
    }

    /// Local hair frame → world: x u + y v + z w.
    #[inline]
    pub fn to_world(&self, local: Vec3) -> Vec3 {
        self.u * local.x + self.v * local.y + self.w * local.z
    }
}

/// A unit vector that depends only on `strand_id`, for [`HairFrame::from_ribbon`] (the thesis' "hair specific
/// index to create an arbitrary noise-based vector"). A SplitMix64 hash of the id, mapped uniformly to the sphere.
pub fn strand_noise(strand_id: u32) -> Vec3 {
    let z = hash64(u64::from(strand_id));
    // Two disjoint 24-bit fields of one hash: bits 40..64 and 8..32.
    let (a, b) = (unit_f32(z), unit_f32(z << 32));
    uniform_sphere(a, b)
}

/// θ of a local direction: atan2(x, √(y² + z²)) ∈ [−π/2, π/2] (exact near the poles, unlike asin(x)).
#[inline]
pub fn theta(local: Vec3) -> f32 {
    theta_of(&local.to_array())
}

/// [`theta`] of directions given component by component (`[x, y, z]`), in any number type ([`Real`]): one
/// direction per lane. The arctangent of the unnormalised (x, ρ), so it does not wait for a normalisation.
#[inline(always)]
pub fn theta_of<R: Real>(w: &[R; 3]) -> R {
    atan2_of(w[0], (w[1] * w[1] + w[2] * w[2]).sqrt())
}

/// atan2(y, x) ∈ [−π, π] (0 for x = y = 0), absolute error < 6e-7 rad (2 f32 ulps at π): reduction to
/// t = min/max ∈ [0, 1], then to |u| ≤ tan(π/8) by atan t = π/4 + atan((t − 1)/(t + 1)) (one division from min and
/// max directly), where the Maclaurin series
/// of atan to u¹⁵ is off by less than tan(π/8)¹⁷/17 = 2e-8. Cheaper than libm's `atan2f`, which dominated
/// [`Angles::new`] and so every eval (the angles of every model go through here). [`atan2_of`] at `f32`.
#[inline]
pub fn atan2(y: f32, x: f32) -> f32 {
    atan2_of(y, x)
}

/// √(y² + z²), the length of the normal-plane projection (plain sqrt: directions are O(1), so the overflow
/// care of `hypot`, which costs more than the rest of [`Angles::new`], buys nothing here).
#[inline]
fn rho(local: Vec3) -> f32 {
    (local.y * local.y + local.z * local.z).sqrt()
}

/// (sin θ, cos θ) from x = ω·u and ρ = √(y² + z²), for any non-zero length; (0, 1) for a zero vector.
#[inline]
fn sin_cos_from(x: f32, rho: f32) -> (f32, f32) {
    sin_cos_from_of(x, rho)
}

/// φ of a local direction: atan2(z, y) ∈ [−π, π] (0 for a direction along ±u).
#[inline]
pub fn phi(local: Vec3) -> f32 {
    atan2(local.z, local.y)
}

/// (sin θ, cos θ) of a local direction, for any non-zero length; cos θ ≥ 0. A zero vector gives (0, 1).
#[inline]
pub fn sin_cos_theta(local: Vec3) -> (f32, f32) {
    sin_cos_theta_of(&local.to_array())
}

/// [`sin_cos_theta`] of directions given component by component (`[x, y, z]`), in any number type ([`Real`]):
/// one direction per lane.
#[inline(always)]
pub fn sin_cos_theta_of<R: Real>(w: &[R; 3]) -> (R, R) {
    sin_cos_from_of(w[0], (w[1] * w[1] + w[2] * w[2]).sqrt())
}

/// The unit local direction with longitudinal angle `theta` and azimuth `phi`: (sin θ, cos θ cos φ, cos θ sin φ).
/// cos θ is clamped at 0 so θ slightly past ±π/2 (rounding) does not flip the azimuth.
#[inline]
pub fn from_spherical(theta: f32, phi: f32) -> Vec3 {
    Vec3::from_array(from_spherical_of(theta, phi))
}

/// [`from_spherical`] in any number type ([`Real`]), one direction per lane, component by component (`[x, y, z]`).
#[inline(always)]
pub fn from_spherical_of<R: Real>(theta: R, phi: R) -> [R; 3] {
    let (sin_t, cos_t) = theta.sin_cos();
    let (sin_p, cos_p) = phi.sin_cos();
    let cos_t = cos_t.max(R::splat(0.0));
    [sin_t, cos_t * cos_p, cos_t * sin_p]
}

/// The unit local direction with longitudinal angle θi, given by `sin_t` and `cos_t` (a sampler keeps them for
/// [`Angles::from_sampled`]), whose azimuth is φi = φr − φ, φr that of `wo` and
/// φ given by its cosine and sine: (cos φi, sin φi) is (cos φr, sin φr) = (ωo·v, ωo·w)/ρo turned by −φ (the angle
/// difference formulas), so neither φr (an arctangent) nor φi (a sine and cosine) is formed. φr = 0 for `wo`
/// along ±u, as [`phi`] gives. Equals `from_spherical(θi, phi(wo) − φ)` to rounding.
#[inline]
pub fn from_sin_cos_theta_and_relative_azimuth(
    sin_t: f32,
    cos_t: f32,
    wo: Vec3,
    cos_phi: f32,
    sin_phi: f32,
) -> Vec3 {
    let (cos_r, sin_r, _) = unit_azimuth_of(wo.y, wo.z, rho(wo));
    Vec3::from(turned_by_relative_azimuth_of(
        sin_t, cos_t, cos_r, sin_r, cos_phi, sin_phi,
    ))
}

/// An angle wrapped to [−π, π].
#[inline]
pub fn wrap_phi(x: f32) -> f32 {
    let y = x - TAU * (x / TAU).round();
    y.clamp(-PI, PI)
}

/// The angles of a pair (ωo, ωi), thesis Table 1, with ωr = ωo. Arctangents are what cost here, so θh, which
/// every model needs, is the only angle computed up front (one arctangent of θr + θi); θr, θi, θd and the
/// relative azimuth φ are methods. The half-angle cosines the models need are computed without trigonometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Angles {
    /// sin θo.
    pub sin_theta_o: f32,
    /// sin θi.
    pub sin_theta_i: f32,
    /// cos θo ≥ 0.
    pub cos_theta_o: f32,
    /// cos θi ≥ 0.
    pub cos_theta_i: f32,
    /// θh = (θr + θi)/2.
    pub theta_h: f32,
    /// cos θd ≥ 0, as half the length of (cos θo + cos θi, sin θo + sin θi) (accurate also near θd = ±π/2).
    pub cos_theta_d: f32,
    /// cos(φ/2) ≥ 0 for φ ∈ [−π, π], as half the length of the sum of the two unit normal-plane projections
    /// (accurate near φ = ±π, where 1 + cos φ would cancel). 1 when either direction lies along ±u (φ = 0 there).
    pub cos_half_phi: f32,
    /// sin(φr − φi) · ρo ρi.
    phi_sin: f32,
    /// cos(φr − φi) · ρo ρi.
    phi_cos: f32,
}

impl Angles {
    /// The angles of local directions `wo` and `wi` (any non-zero length).
    ///
    /// Always inlined: as a call, its result went through the stack, and the callers' first use (φ's arctangent
    /// loading `phi_sin` and `phi_cos` as one 8-byte word just written as two 4-byte ones) missed store-to-load
    /// forwarding, the hottest instruction of ISHair's eval profile (23 % of the caller's samples).
    #[inline(always)]
    pub fn new(wo: Vec3, wi: Vec3) -> Angles {
        let (rho_o, rho_i) = (rho(wo), rho(wi));
        // θh in one arctangent of θr + θi ([`theta_h_of`]), not two, and not waiting for the normalisation below.
        let theta_h = theta_h_of(wo.x, rho_o, wi.x, rho_i);
        let (sin_theta_o, cos_theta_o) = sin_cos_from(wo.x, rho_o);
        let (sin_theta_i, cos_theta_i) = sin_cos_from(wi.x, rho_i);
        let cos_theta_d = half_length_of(cos_theta_o + cos_theta_i, sin_theta_o + sin_theta_i);
        let cos_half_phi = if rho_o > 0.0 && rho_i > 0.0 {
            let (a, b) = (1.0 / rho_o, 1.0 / rho_i);
            half_length_of(wo.y * a + wi.y * b, wo.z * a + wi.z * b)
        } else {
            1.0
        };
        Angles {
            sin_theta_o,
            sin_theta_i,
            cos_theta_o,
            cos_theta_i,
            theta_h,
            cos_theta_d,
            cos_half_phi,
            phi_sin: wo.z * wi.y - wo.y * wi.z,
            phi_cos: wo.y * wi.y + wo.z * wi.z,
        }
    }

    /// The angles of a pair a sampler has just drawn, from what it already knows rather than from the returned
    /// direction: θo and (sin θo, cos θo); θi (already in [−π/2, π/2]) and (sin θi, cos θi); the relative
    /// azimuth φ = φr − φi by cos(φ/2) ≥ 0, cos φ and sin φ. No arctangent, square root (but cos θd's) or
    /// division, where [`Angles::new`] takes two, four and three.
    ///
    /// These are the angles of the direction *drawn*; the direction a sampler returns is that one rounded to
    /// f32, whose [`Angles::new`] differs by the rounding (≈ 1e-7 rad) and by [`atan2`]'s error (< 6e-7 rad), which
    /// a lobe of width β magnifies ~1/β times in relative terms. The models' sample tests bound exactly that:
    /// what `sample` returns lies within the values `eval` and `pdf` take within 1e-6 rad of the returned
    /// direction.
    #[inline(always)]
    pub fn from_sampled(
        theta_o: f32,
        (sin_theta_o, cos_theta_o): (f32, f32),
        theta_i: f32,
        (sin_theta_i, cos_theta_i): (f32, f32),
        cos_half_phi: f32,
        cos_phi: f32,
        sin_phi: f32,
    ) -> Angles {
        let cos_theta_i = cos_theta_i.max(0.0);
        Angles {
            sin_theta_o,
            sin_theta_i,
            cos_theta_o,
            cos_theta_i,
            theta_h: 0.5 * (theta_o + theta_i),
            cos_theta_d: half_length_of(cos_theta_o + cos_theta_i, sin_theta_o + sin_theta_i),
            cos_half_phi,
            phi_sin: sin_phi,
            phi_cos: cos_phi,
        }
    }

    /// θr = θo, the view direction's longitudinal angle (one arctangent; [`theta`] of ωo gives the same to
    /// rounding).
    #[inline]
    pub fn theta_o(&self) -> f32 {
        atan2(self.sin_theta_o, self.cos_theta_o)
    }

    /// θi (one arctangent).
    #[inline]
    pub fn theta_i(&self) -> f32 {
        atan2(self.sin_theta_i, self.cos_theta_i)
    }

    /// θd = (θr − θi)/2 (two arctangents).
    #[inline]
    pub fn theta_d(&self) -> f32 {
        0.5 * (self.theta_o() - self.theta_i())
    }

    /// The relative azimuth φ = φr − φi ∈ [−π, π] (0 when either direction lies along ±u), in one arctangent of
    /// the sine and cosine of the difference.
    #[inline]
    pub fn phi(&self) -> f32 {
        atan2(self.phi_sin, self.phi_cos)
    }
}

/// h = sin γo, the offset of a hit across a **round** fibre as seen from ωo (the convention of
/// [`super::chiang`]'s module docs): u · (n × ω̂o⊥), with `tangent` u, `normal` n the outward surface normal at the
/// hit and ω̂o⊥ the unit projection of `wo` (towards the viewer) on the normal plane. Any frame (world or local): a
/// triple product. Neither n nor u need be unit or exactly orthogonal (they are projected); 0 if `wo` runs along u
/// or n along u. Clamped to [−1, 1].
pub fn h_from_normal(tangent: Vec3, normal: Vec3, wo: Vec3) -> f32 {
    let u = tangent.normalize_or_zero();
    let n = normal.reject_from_normalized(u).normalize_or_zero();
    let w = wo.reject_from_normalized(u).normalize_or_zero();
    u.dot(n.cross(w)).clamp(-1.0, 1.0)
}

/// h = sin γo for a hit on a **flat ribbon** standing for a fibre: (2v − 1) b · (ω̂o⊥ × u), with `v` ∈ [0, 1]
/// the hit's coordinate across the ribbon, `across` the direction b in which v grows, u the `tangent`. For a
/// ribbon facing the viewer b · (ω̂o⊥ × u) = ±1, so |h| = |2v − 1| and the sign says which side of the fibre the
/// hit stands for (the same h a round fibre of the ribbon's width gives at the same offset; tested).
pub fn h_from_ribbon(v: f32, across: Vec3, tangent: Vec3, wo: Vec3) -> f32 {
    let u = tangent.normalize_or_zero();
    let w = wo.reject_from_normalized(u).normalize_or_zero();
    let b = across.normalize_or_zero();
    ((2.0 * v - 1.0) * b.dot(w.cross(u))).clamp(-1.0, 1.0)
}

/// [`atan2`] over any [`Real`] (one f32 or eight lanes), branches as selects: the one implementation of the
/// polynomial arctangent, which the scalar [`atan2`] is at `f32`.
#[inline(always)]
pub fn atan2_of<R: Real>(y: R, x: R) -> R {
    let zero = R::splat(0.0);
    let (ax, ay) = (x.abs(), y.abs());
    let swap = ay.gt(ax);
    let (num, den) = (R::select(swap, ax, ay), R::select(swap, ay, ax));
    // t = num/den; past tan(π/8), u = (t − 1)/(t + 1) = (num − den)/(num + den): one division either way, and
    // written as (num − k den)/(den + k num) with k ∈ {0, 1} it needs no branch.
    let k = R::select(num.gt(R::splat(0.414_213_57) * den), R::splat(1.0), zero);
    let u = (num - k * den) / (den + k * num);
    let base = k * R::splat(FRAC_PI_4);
    let (v, v2) = (u * u, (u * u) * (u * u));
    let c = R::splat;
    // atan u = u (1 − u²/3 + u⁴/5 − … − u¹⁴/15), by Estrin's scheme in v = u² (pairs, then v², v⁴): a dependency
    // chain of three multiply-adds instead of Horner's seven.
    let poly = (c(1.0) + v * c(-1.0 / 3.0))
        + v2 * (c(1.0 / 5.0) + v * c(-1.0 / 7.0))
        + (v2 * v2)
            * ((c(1.0 / 9.0) + v * c(-1.0 / 11.0)) + v2 * (c(1.0 / 13.0) + v * c(-1.0 / 15.0)));
    let a = base + u * poly;
    let a = R::select(swap, c(FRAC_PI_2) - a, a);
    let a = R::select(x.lt(zero), c(PI) - a, a);
    let a = R::select(y.lt(zero), -a, a);
    // Both zero (0/0 above): the direction is along ±u, where φ is undefined; 0 as `f32::atan2` gives. A NaN
    // argument stays NaN (no comparison holds).
    R::select(den.eq(zero), zero, a)
}

/// θh = (θr + θi)/2 of two directions given by their tangent components x and normal-plane lengths ρ, over any
/// [`Real`]: θr + θi ∈ [−π, π] from its sine and cosine (angle-sum formulas, each scaled by |ωo||ωi| > 0, which
/// the arctangent ignores), so θh costs one arctangent, not two, and needs no normalisation. Exactly at a pole the
/// sine may be a zero of either sign; θr + θi = ±π then takes the sign of the poles.
#[inline(always)]
pub fn theta_h_of<R: Real>(x_o: R, rho_o: R, x_i: R, rho_i: R) -> R {
    let sin_sum = x_o * rho_i + rho_o * x_i;
    let cos_sum = rho_o * rho_i - x_o * x_i;
    let zero = R::splat(0.0);
    let pole = sin_sum.eq(zero) & cos_sum.lt(zero);
    let half_pi = R::splat(FRAC_PI_2);
    R::select(
        pole,
        R::select((x_o + x_i).lt(zero), -half_pi, half_pi),
        R::splat(0.5) * atan2_of(sin_sum, cos_sum),
    )
}

/// Half the length of (a, b), at most 1: cos θd from (cos θo + cos θi, sin θo + sin θi) (accurate also near
/// θd = ±π/2), cos(φ/2) from the sum of the two unit normal-plane projections (accurate near φ = ±π, where
/// 1 + cos φ would cancel).
#[inline(always)]
pub fn half_length_of<R: Real>(a: R, b: R) -> R {
    (R::splat(0.5) * (a * a + b * b).sqrt()).min(R::splat(1.0))
}

/// (sin θ, cos θ) from x = ω·u and ρ = √(y² + z²) over any [`Real`], for any non-zero length; (0, 1) for a zero
/// vector. [`sin_cos_theta`]'s arithmetic.
#[inline(always)]
pub fn sin_cos_from_of<R: Real>(x: R, rho: R) -> (R, R) {
    let len2 = x * x + rho * rho;
    let some = len2.gt(R::splat(0.0));
    let inv = R::splat(1.0) / len2.sqrt();
    (
        R::select(some, x * inv, R::splat(0.0)),
        R::select(some, rho * inv, R::splat(1.0)),
    )
}

/// (cos φ, sin φ) of the normal-plane projection (y, z) of a direction, ρ = √(y² + z²) its length, and whether
/// it has one (ρ > 0); (1, 0) along ±u, where [`phi`] gives 0.
#[inline(always)]
pub fn unit_azimuth_of<R: Real>(y: R, z: R, rho: R) -> (R, R, R::Mask) {
    let some = rho.gt(R::splat(0.0));
    let inv = R::splat(1.0) / rho;
    (
        R::select(some, y * inv, R::splat(1.0)),
        R::select(some, z * inv, R::splat(0.0)),
        some,
    )
}

/// The unit direction of [`from_sin_cos_theta_and_relative_azimuth`] over any [`Real`], given ωo's normal-plane
/// direction (cos φr, sin φr) ([`unit_azimuth_of`]): (cos φi, sin φi) is it turned by −φ (the angle difference
/// formulas), φ given by its cosine and sine.
#[inline(always)]
pub fn turned_by_relative_azimuth_of<R: Real>(
    sin_t: R,
    cos_t: R,
    cos_r: R,
    sin_r: R,
    cos_phi: R,
    sin_phi: R,
) -> [R; 3] {
    let cos_i = cos_r * cos_phi + sin_r * sin_phi;
    let sin_i = sin_r * cos_phi - cos_r * sin_phi;
    let cos_t = cos_t.max(R::splat(0.0));
    [sin_t, cos_t * cos_i, cos_t * sin_i]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};

    const EPS: f32 = 1e-5; // f32 trigonometry on unit vectors: a few ulps of π.

    fn deg(x: f32) -> f32 {
        x.to_radians()
    }

    #[test]
    fn fast_atan2_matches_libm() {
        let mut worst = 0.0f32;
        for i in 0..=400 {
            for j in 0..=400 {
                let (y, x) = (-2.0 + i as f32 * 0.01, -2.0 + j as f32 * 0.01);
                worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
            }
        }
        for (y, x) in [
            (1e-30, 1.0),
            (1.0, 1e-30),
            (-1.0, -1e-30),
            (1e30, -1e30),
            (0.0, -1.0),
            (0.0, 1.0),
        ] {
            worst = worst.max((atan2(y, x) - y.atan2(x)).abs());
        }
        // The series is off by < 2e-8; the rest is f32 rounding (2 ulps of π = 4.8e-7).
        assert!(worst < 6e-7, "{worst}");
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert!(atan2(f32::NAN, 1.0).is_nan());
        assert!(atan2(1.0, f32::NAN).is_nan());
    }

    #[test]
    fn atan2_in_lanes_is_the_scalar_one_bit_for_bit() {
        // The same arithmetic in every lane: equal bits, zeros of both signs and both-zero lanes among others.
        use wide::f32x8;
        let mut pairs: Vec<(f32, f32)> = (0..=40)
            .flat_map(|i| (0..=40).map(move |j| (-2.0 + i as f32 * 0.1, -2.0 + j as f32 * 0.1)))
            .collect();
        pairs.extend([
            (0.0, 0.0),
            (-0.0, 0.0),
            (0.0, -0.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1e-30, 1.0),
        ]);
        for chunk in pairs.chunks(8) {
            let at = |k: usize| chunk[k.min(chunk.len() - 1)];
            let lanes = atan2_of(
                f32x8::new(std::array::from_fn(|k| at(k).0)),
                f32x8::new(std::array::from_fn(|k| at(k).1)),
            );
            for (k, &(y, x)) in chunk.iter().enumerate() {
                assert_eq!(
                    lanes.lane(k).to_bits(),
                    atan2(y, x).to_bits(),
                    "atan2({y}, {x})"
                );
            }
        }
    }

    #[test]
    fn generic_angles_in_eight_lanes_match_one_at_a_time() {
        // The polynomial arctangent and θh's angle sum in f32x8 against f32: the same arithmetic, so equal to
        // rounding (no FMA contraction either way).
        use wide::f32x8;
        let xs: [f32; 8] = [-2.0, -0.7, -1e-30, 0.0, 0.3, 1.0, 1.5, 2.0];
        let ys: [f32; 8] = [0.5, -1.2, 0.0, 0.0, -0.0, 1e-30, -3.0, 0.9];
        let (x8, y8) = (f32x8::new(xs), f32x8::new(ys));
        let a8 = atan2_of(y8, x8);
        let h8 = theta_h_of(x8, y8.abs(), y8, x8.abs());
        for k in 0..8 {
            assert_eq!(a8.lane(k), atan2(ys[k], xs[k]), "atan2 lane {k}");
            assert_eq!(
                h8.lane(k),
                theta_h_of(xs[k], ys[k].abs(), ys[k], xs[k].abs())
            );
        }
        // The poles: θh = ±π/2 with the sign of the poles.
        assert_eq!(theta_h_of(1.0f32, 0.0, 1.0, 0.0), FRAC_PI_2);
        assert_eq!(theta_h_of(-1.0f32, 0.0, -1.0, 0.0), -FRAC_PI_2);
    }

    #[test]
    fn relative_azimuth_direction_matches_from_spherical() {
        let mut worst = 0.0f32;
        for i in 0..=36 {
            for j in 0..=36 {
                let wo = from_spherical(deg(-90.0 + 5.0 * i as f32), deg(-180.0 + 10.0 * j as f32));
                for k in 0..=24 {
                    let (theta_i, phi_rel) =
                        (deg(-90.0 + 7.5 * k as f32), deg(-180.0 + 15.0 * k as f32));
                    let (s, c) = phi_rel.sin_cos();
                    let (sin_t, cos_t) = theta_i.sin_cos();
                    let got = from_sin_cos_theta_and_relative_azimuth(sin_t, cos_t, wo, c, s);
                    worst = worst.max((got - from_spherical(theta_i, phi(wo) - phi_rel)).length());
                }
            }
        }
        assert!(worst < 2e-6, "{worst}");
    }

    #[test]
    fn axes_give_known_angles() {
        // u → θ = 90°; −u → −90°; v → (0, 0); w → (0, 90°); −v → φ = ±180°.
        assert!((theta(Vec3::X) - FRAC_PI_2).abs() < EPS);
        assert!((theta(-Vec3::X) + FRAC_PI_2).abs() < EPS);
        assert!(theta(Vec3::Y).abs() < EPS && phi(Vec3::Y).abs() < EPS);
        assert!(theta(Vec3::Z).abs() < EPS && (phi(Vec3::Z) - FRAC_PI_2).abs() < EPS);
        assert!((phi(-Vec3::Y).abs() - PI).abs() < EPS);
        assert!((phi(-Vec3::Z) + FRAC_PI_2).abs() < EPS);
    }

    #[test]
    fn oblique_direction_gives_known_angles() {
        // θ = 30°, φ = 45°: (sin 30°, cos 30° cos 45°, cos 30° sin 45°). Reading the wrong index (thesis §8.1),
        // e.g. sin θ = ω.y, would give θ = 37.8° and fail.
        let w = Vec3::new(
            0.5,
            0.75f32.sqrt() * FRAC_PI_4.cos(),
            0.75f32.sqrt() * FRAC_PI_4.sin(),
        );
        assert!(
            (theta(w) - deg(30.0)).abs() < EPS,
            "{}",
            theta(w).to_degrees()
        );
        assert!((phi(w) - deg(45.0)).abs() < EPS, "{}", phi(w).to_degrees());
        let back = from_spherical(deg(30.0), deg(45.0));
        assert!((back - w).length() < EPS);
        // Round trip over a grid, including the poles' neighbourhood and φ = ±π.
        for i in 0..=36 {
            for j in 0..=72 {
                let t = deg(-89.9 + 179.8 * i as f32 / 36.0);
                let p = deg(-180.0 + 5.0 * j as f32);
                let v = from_spherical(t, p);
                assert!((theta(v) - t).abs() < 1e-5, "θ {t} φ {p}");
                assert!(wrap_phi(phi(v) - p).abs() < 2e-4, "θ {t} φ {p}: {}", phi(v));
            }
        }
    }

    #[test]
    fn half_and_difference_angles() {
        // θo = 40°, φo = 10°; θi = −20°, φi = 70°: θh = 10°, θd = 30°, φ = φr − φi = −60°.
        let wo = from_spherical(deg(40.0), deg(10.0));
        let wi = from_spherical(deg(-20.0), deg(70.0));
        let a = Angles::new(wo, wi);
        assert!((a.theta_o() - deg(40.0)).abs() < EPS);
        assert!((a.theta_i() - deg(-20.0)).abs() < EPS);
        assert!((a.theta_h - deg(10.0)).abs() < EPS);
        assert!((a.theta_d() - deg(30.0)).abs() < EPS);
        assert!(
            (a.phi() - deg(-60.0)).abs() < EPS,
            "{}",
            a.phi().to_degrees()
        );
        assert!((a.cos_half_phi - deg(30.0).cos()).abs() < EPS);
        assert!((a.cos_theta_d - deg(30.0).cos()).abs() < EPS);
        assert!((a.sin_theta_o - deg(40.0).sin()).abs() < EPS);
        assert!((a.cos_theta_i - deg(20.0).cos()).abs() < EPS);
        // Relative φ wraps: φr = 170°, φi = −170° ⇒ φ = 340° ≡ −20°.
        let a = Angles::new(
            from_spherical(0.0, deg(170.0)),
            from_spherical(0.0, deg(-170.0)),
        );
        assert!(
            (a.phi() - deg(-20.0)).abs() < 1e-4,
            "{}",
            a.phi().to_degrees()
        );
        // Near φ = π and θd = π/2 the half-angle cosines keep their accuracy: φ = 179.9°, θo = −θi = 89.9°.
        let a = Angles::new(
            from_spherical(deg(89.9), deg(90.0)),
            from_spherical(deg(-89.9), deg(-89.9)),
        );
        assert!(
            (a.cos_half_phi / deg(0.05).sin() - 1.0).abs() < 1e-3,
            "{}",
            a.cos_half_phi
        );
        assert!(
            (a.cos_theta_d / deg(0.1).sin() - 1.0).abs() < 1e-3,
            "{}",
            a.cos_theta_d
        );
    }

    #[test]
    fn round_curve_frame_from_unnormalised_normal() {
        // Tangent +z, Embree-like Ng = 2.5 x + 0.3 z (outward, not unit, not orthogonal to u).
        let f = HairFrame::from_round_curve(Vec3::Z, Vec3::new(2.5, 0.0, 0.3));
        assert!((f.u - Vec3::Z).length() < EPS);
        assert!((f.v - Vec3::X).length() < EPS);
        assert!((f.w - Vec3::Y).length() < EPS, "u × v = w: {}", f.w);
        // World +y lies along w: θ = 0, φ = 90°; world +z along the tangent: θ = 90°.
        let l = f.to_local(Vec3::Y);
        assert!(theta(l).abs() < EPS && (phi(l) - FRAC_PI_2).abs() < EPS);
        assert!((theta(f.to_local(Vec3::Z)) - FRAC_PI_2).abs() < EPS);
        // world → local → world.
        let d = Vec3::new(0.3, -0.5, 0.81).normalize();
        assert!((f.to_world(f.to_local(d)) - d).length() < EPS);
    }

    #[test]
    fn ribbon_frame_is_orthonormal_and_fixed_per_strand() {
        let t = Vec3::new(0.2, 0.9, -0.1).normalize();
        for id in [0u32, 1, 7, 123_456, u32::MAX] {
            let n = strand_noise(id);
            assert!((n.length() - 1.0).abs() < 1e-5);
            assert_eq!(n, strand_noise(id));
            let f = HairFrame::from_ribbon(t, n);
            for (a, b) in [(f.u, f.v), (f.v, f.w), (f.u, f.w)] {
                assert!(a.dot(b).abs() < 1e-5);
            }
            assert!((f.u.cross(f.v) - f.w).length() < 1e-5);
        }
        // Degenerate inputs still give a frame: noise parallel to the tangent, zero tangent.
        let f = HairFrame::from_ribbon(t, t * 3.0);
        assert!(f.u.dot(f.v).abs() < 1e-5 && (f.v.length() - 1.0).abs() < 1e-5);
        let f = HairFrame::from_round_curve(Vec3::ZERO, Vec3::ZERO);
        assert!(f.u.is_finite() && f.v.is_finite() && f.w.is_finite());
    }
}

//! Chiang's view, eval and sample for eight shading points at once (steps 1–2 of `docs/design/wavefront.md`):
//! a batch of paths is shaded one f32×8 vector (AVX2) at a time, where the scalar [`Chiang::eval_viewed`]
//! evaluates one path's four lobes as one f64×4 vector. The integrator's `integrator.lanes` path calls them
//! (`Integrator::sample_lanes`); `cargo bench -p cuticle-bench --bench bsdf -- chiang-lanes` measures the eval against the scalar one.
//!
//! The same model, written for f32 lanes:
//! - M_p (d'Eon et al. 2011) as exp(ln c − (1 − cos(θi + θo′))/v − a) I₀(a) for a = cos θi cos θo′/v ≤ 10 and
//!   exp(ln c − (1 − cos(θi + θo′))/v) I₀ₑ(a) above, the scalar model's two expansions cut to 16 terms. The scalar
//!   model forms cos θi cos θo′ − sin θi sin θo′ − 1 in f64, where the difference of terms ~1/v is exact enough;
//!   here 1 − cos(θi + θo′) is sin²(θi + θo′)/(1 + cos(θi + θo′)) (or 1 − cos where the cosine is negative), which
//!   no rounding of nearly equal terms enters, so f32 keeps M_p's relative precision also for narrow lobes.
//! - N_p, the trimmed logistic at φ − Φ(p) wrapped to [−π, π], and φ by `wide`'s arctangent.
//! - f_p = A_p M_p N_p / cos θi per lobe and the mixture pdf Σ P(p) M_p N_p, as [`Chiang::eval_viewed`] gives them.

use super::{m_uniform, Chiang, ChiangView, I0_ASYMPTOTIC, I0_SERIES, M_P_SWITCH, P_MAX};
use crate::bsdf::frame::COS_THETA_MIN;
use crate::bsdf::LobeValues;
use crate::util::color::REC709_LUMINANCE;
use glam::{Vec3, Vec3A};
use std::f32::consts::{PI, TAU};
use wide::{f32x8, CmpEq, CmpGt, CmpLe, CmpLt};

/// Shading points per batch: one f32×8 vector.
pub const LANES: usize = 8;

/// Eight [`ChiangView`]s, lane by lane (structure of arrays).
#[derive(Debug, Clone, Copy)]
pub struct ViewLanes {
    /// ωo's components in the normal plane (y, z): φ is measured from it.
    wo_y: f32x8,
    wo_z: f32x8,
    /// A_p per p and colour channel.
    ap: [[f32x8; 3]; P_MAX + 1],
    /// P(p).
    ap_pdf: [f32x8; P_MAX + 1],
    /// Φ(p) for p = 0, 1, 2.
    phis: [f32x8; P_MAX],
    /// (sin θo′, |cos θo′|) per p.
    tilted_sin: [f32x8; P_MAX + 1],
    tilted_cos: [f32x8; P_MAX + 1],
}

impl ViewLanes {
    /// The eight views in lanes 0 to 7.
    pub fn new(views: &[ChiangView; LANES]) -> ViewLanes {
        // A generic closure, not `&dyn Fn`: called per field and lane, dynamic calls cost more than the copies.
        #[inline(always)]
        fn lane(views: &[ChiangView; LANES], f: impl Fn(&ChiangView) -> f32) -> f32x8 {
            f32x8::new(std::array::from_fn(|k| f(&views[k])))
        }
        let v = views;
        ViewLanes {
            wo_y: lane(v, |v| v.wo.y),
            wo_z: lane(v, |v| v.wo.z),
            ap: std::array::from_fn(|p| std::array::from_fn(|c| lane(v, |v| v.view.ap[p][c]))),
            ap_pdf: std::array::from_fn(|p| lane(v, |v| v.view.ap_pdf[p])),
            phis: std::array::from_fn(|p| lane(v, |v| v.view.phis[p])),
            tilted_sin: std::array::from_fn(|p| lane(v, |v| v.view.tilted[p].0 as f32)),
            tilted_cos: std::array::from_fn(|p| lane(v, |v| v.view.tilted[p].1 as f32)),
        }
    }
}

/// Lane `k` of three vectors (x, y, z or R, G, B).
#[inline]
fn lane_vec3(c: &[f32x8; 3], k: usize) -> Vec3 {
    Vec3::new(
        c[0].as_array_ref()[k],
        c[1].as_array_ref()[k],
        c[2].as_array_ref()[k],
    )
}

/// The Fresnel reflectance of a dielectric of index `eta` at incidence cosine `cos_i` per lane
/// ([`crate::bsdf::fresnel::dielectric`]; 1 past the critical angle).
#[inline(always)]
fn dielectric(cos_i: f32x8, eta: f32) -> f32x8 {
    let one = f32x8::splat(1.0);
    let eta = f32x8::splat(eta);
    let cos_i = cos_i.max(f32x8::ZERO).min(one);
    let sin2_t = (one - cos_i * cos_i) / (eta * eta);
    let cos_t = (one - sin2_t).max(f32x8::ZERO).sqrt();
    let r_parl = eta.mul_sub(cos_i, cos_t) / eta.mul_add(cos_i, cos_t);
    let r_perp = eta.mul_neg_add(cos_t, cos_i) / eta.mul_add(cos_t, cos_i);
    let f = f32x8::splat(0.5) * r_parl.mul_add(r_parl, r_perp * r_perp);
    sin2_t.cmp_lt(one).blend(f, one)
}

impl Chiang {
    /// [`ChiangView`]s of eight shading points at once, in lanes ([`ChiangFibre::viewed`] of each): lane k at the
    /// offset `h[k]` across the fibre, seen from ωo's lane k (`wo`: x, y, z vectors, local frame).
    ///
    /// [`ChiangFibre::viewed`]: super::ChiangFibre::viewed
    pub fn view_lanes(&self, h: f32x8, wo: &[f32x8; 3]) -> ViewLanes {
        let one = f32x8::splat(1.0);
        let [x, y, z] = *wo;
        let eta = self.params.eta;
        let h = h.max(f32x8::splat(-1.0)).min(one);
        let gamma_o = h.asin();
        let cos_gamma_o = (one - h * h).max(f32x8::ZERO).sqrt();
        let rho = y.mul_add(y, z * z).sqrt();
        let inv_len = one / x.mul_add(x, rho * rho).sqrt();
        let (sin_o, cos_o) = (x * inv_len, rho * inv_len);
        // Refraction into the fibre: θt and, in the normal plane, γt with Bravais' index η′.
        let sin_t = sin_o / f32x8::splat(eta);
        let cos_t = (one - sin_t * sin_t).max(f32x8::ZERO).sqrt();
        let eta_p = (f32x8::splat(eta * eta) - sin_o * sin_o)
            .max(f32x8::ZERO)
            .sqrt()
            / cos_o.max(f32x8::splat(COS_THETA_MIN));
        let sin_gt = (h / eta_p).max(f32x8::splat(-1.0)).min(one);
        let gamma_t = sin_gt.asin();
        let cos_gt = (one - sin_gt * sin_gt).max(f32x8::ZERO).sqrt();
        let chord = f32x8::splat(2.0) * cos_gt / cos_t;
        let sigma = self.params.sigma_a;
        let t: [f32x8; 3] = std::array::from_fn(|c| (-f32x8::splat(sigma[c]) * chord).exp());
        // A_p ([`super::a_p`]).
        let f = dielectric(cos_o * cos_gamma_o, eta);
        let a1: [f32x8; 3] = std::array::from_fn(|c| (one - f) * (one - f) * t[c]);
        let a2: [f32x8; 3] = std::array::from_fn(|c| a1[c] * f * t[c]);
        let a3: [f32x8; 3] = std::array::from_fn(|c| {
            let ft = f * t[c];
            a2[c] * ft.cmp_lt(one).blend(ft / (one - ft), f32x8::ZERO)
        });
        let ap = [[f; 3], a1, a2, a3];
        let lum: [f32x8; P_MAX + 1] = ap.map(|a| {
            a[0] * f32x8::splat(REC709_LUMINANCE.x)
                + a[1] * f32x8::splat(REC709_LUMINANCE.y)
                + a[2] * f32x8::splat(REC709_LUMINANCE.z)
        });
        let total = lum[0] + lum[1] + lum[2] + lum[3];
        let ap_pdf = lum.map(|l| l / total);
        let phis = std::array::from_fn(|p| {
            let p = p as f32;
            f32x8::splat(2.0 * p) * gamma_t - f32x8::splat(2.0) * gamma_o + f32x8::splat(p * PI)
        });
        // Tilts: θo − 2α (R), θo + α (TT), θo + 4α (TRT), θo (residual) ([`ChiangFibre::view`]).
        let rot = |(s, c): (f64, f64), sign: f32| {
            let (s, c) = (f32x8::splat(s as f32), f32x8::splat(c as f32));
            let sign = f32x8::splat(sign);
            (
                sin_o.mul_add(c, sign * cos_o * s),
                cos_o.mul_sub(c, sign * sin_o * s).abs(),
            )
        };
        let tilted = [
            rot(self.tilt[1], -1.0),
            rot(self.tilt[0], 1.0),
            rot(self.tilt[2], 1.0),
            (sin_o, cos_o),
        ];
        ViewLanes {
            wo_y: y,
            wo_z: z,
            ap,
            ap_pdf,
            phis,
            tilted_sin: tilted.map(|t| t.0),
            tilted_cos: tilted.map(|t| t.1),
        }
    }
}

/// Eight material samples ([`Chiang::sample_lanes`]).
#[derive(Debug, Clone, Copy)]
pub struct SampleLanes {
    /// The sampled ωi (x, y, z vectors, local frame, unit length).
    pub wi: [f32x8; 3],
    /// The order p each lane's sampler drew (0 R, 1 TT, 2 TRT, 3 the residual; [`P_MAX`] + 1 in a uniformly
    /// sampled model).
    pub p: [u8; LANES],
    /// f per lobe and the pdf at ωi ([`Chiang::eval_lanes`] there).
    pub eval: EvalLanes,
}

impl SampleLanes {
    /// Lane `k`'s sampled ωi.
    pub fn wi(&self, k: usize) -> Vec3 {
        lane_vec3(&self.wi, k)
    }
}

impl Chiang {
    /// [`Chiang::sample_viewed`] for eight views at once with lane k's random numbers (`u[0]`, `u[1]`, `u[2]`
    /// lane k): the order p by P(p) (the remainder of u₀, rescaled, turns the longitudinal lobe's azimuth), sin θi
    /// by d'Eon et al.'s inverse CDF, φi by the trimmed logistic about Φ(p) (uniform for the residual), then f and
    /// the pdf at the sampled ωi. Lanes whose A_p all vanish keep the scalar model's fallback (the last p with
    /// P(p) > 0, remainder ½).
    pub fn sample_lanes(&self, views: &ViewLanes, u: [f32x8; 3]) -> SampleLanes {
        let one = f32x8::splat(1.0);
        if m_uniform(self) {
            let sin_i = (one - f32x8::splat(2.0) * u[0]).max(-one).min(one);
            let cos_i = (one - sin_i * sin_i).max(f32x8::ZERO).sqrt();
            let (s, c) = (f32x8::splat(TAU) * u[1]).sin_cos();
            let wi = [sin_i, cos_i * c, cos_i * s];
            return SampleLanes {
                wi,
                p: [P_MAX as u8 + 1; LANES],
                eval: self.eval_lanes(views, &wi),
            };
        }
        // p by P(p), as the scalar model subtracts: r < q_p picks p, else r −= q_p.
        let mut r = u[0];
        let mut chosen = f32x8::ZERO; // all-ones lanes once a p was picked
        let mut p_of = f32x8::splat(-1.0);
        let mut remainder = f32x8::splat(0.5);
        for p in 0..=P_MAX {
            let q = views.ap_pdf[p];
            let take = r.cmp_lt(q) & !chosen;
            p_of = take.blend(f32x8::splat(p as f32), p_of);
            remainder = take.blend((r / q).min(one), remainder);
            chosen |= take;
            r -= q;
        }
        // The fallback: the last p with P(p) > 0.
        let mut last = f32x8::ZERO;
        for p in 0..=P_MAX {
            last = views.ap_pdf[p]
                .cmp_gt(f32x8::ZERO)
                .blend(f32x8::splat(p as f32), last);
        }
        let p_of = chosen.blend(p_of, last);
        let pick = |values: [f32x8; P_MAX + 1]| {
            (0..=P_MAX).fold(values[0], |acc, p| {
                p_of.cmp_eq(f32x8::splat(p as f32)).blend(values[p], acc)
            })
        };
        let (sin_o, cos_o) = (pick(views.tilted_sin), pick(views.tilted_cos));
        let lobe_constant =
            |f: &dyn Fn(usize) -> f32| pick(std::array::from_fn(|p| f32x8::splat(f(p))));
        let v = lobe_constant(&|p| self.longitudinal[p.min(P_MAX - 1)].v as f32);
        let one_minus_e =
            lobe_constant(&|p| (1.0 - self.longitudinal[p.min(P_MAX - 1)].exp_m2_over_v) as f32);
        // sin θi ([`super::Longitudinal::sample_sin_theta`]): w = cos t − 1 = v ln(ξ + (1 − ξ) e^{−2/v}) ∈ [−2, 0]
        // with ξ = 1 − u₁, i.e. v ln(1 + x), x = −u₁ (1 − e^{−2/v}), by Kahan's ln(1 + x) = ln(y) x / (y − 1),
        // y = 1 + x rounded: the scalar model takes the logarithm in f64, where a wide lobe's argument near 1 keeps
        // its digits; this keeps them in f32.
        let x = -u[1] * one_minus_e;
        let y1 = one + x;
        let ln1p = (y1 - one)
            .cmp_eq(f32x8::ZERO)
            .blend(x, y1.ln() * (x / (y1 - one)));
        let w = (v * ln1p).max(f32x8::splat(-2.0));
        let (cos_t, sin_t) = (
            one + w,
            (-w * (f32x8::splat(2.0) + w)).max(f32x8::ZERO).sqrt(),
        );
        let cos_phi = (f32x8::splat(TAU) * remainder).cos();
        let sin_i = (sin_t * cos_phi)
            .mul_sub(cos_o, cos_t * sin_o)
            .max(-one)
            .min(one);
        let cos_i = (one - sin_i * sin_i).max(f32x8::ZERO).sqrt();
        // φi − φo: Φ(p) plus the trimmed logistic's draw ([`super::Azimuthal::sample`]), uniform for the residual.
        let a = &self.azimuthal;
        let (lo, th) = (
            f32x8::splat(a.cdf_lo as f32),
            f32x8::splat(a.tanh_half as f32),
        );
        let q = u[2].mul_add(th, lo);
        let q_c = (one - u[2]).mul_add(th, lo);
        let logistic = (f32x8::splat(a.s) * (q / q_c).ln())
            .max(f32x8::splat(-PI))
            .min(f32x8::splat(PI));
        let phis = pick([views.phis[0], views.phis[1], views.phis[2], f32x8::ZERO]);
        let residual = p_of.cmp_eq(f32x8::splat(P_MAX as f32));
        let dphi = residual.blend(f32x8::splat(TAU) * u[2], phis + logistic);
        let phi_i = views.wo_z.atan2(views.wo_y) + dphi;
        let (s, c) = phi_i.sin_cos();
        let wi = [sin_i, cos_i * c, cos_i * s];
        let p = p_of.as_array_ref().map(|p| p as u8);
        SampleLanes {
            wi,
            p,
            eval: self.eval_lanes(views, &wi),
        }
    }
}

/// Eight directions as three vectors (x, y, z), the layout [`Chiang::eval_lanes`] reads.
pub fn directions(w: &[Vec3; LANES]) -> [f32x8; 3] {
    std::array::from_fn(|c| f32x8::new(w.each_ref().map(|v| v[c])))
}

/// f per lobe (R, TT, TRT with the residual; RGB each) and the pdf of eight evaluations.
#[derive(Debug, Clone, Copy)]
pub struct EvalLanes {
    /// f of R, per colour channel.
    pub r: [f32x8; 3],
    /// f of TT.
    pub tt: [f32x8; 3],
    /// f of TRT and the residual p ≥ 3.
    pub trt: [f32x8; 3],
    /// The sampling pdf at ωi.
    pub pdf: f32x8,
}

impl EvalLanes {
    /// Lane `k` as [`Chiang::eval_viewed`] returns it.
    pub fn lane(&self, k: usize) -> (LobeValues, f32) {
        let rgb = |c: &[f32x8; 3]| Vec3A::from(lane_vec3(c, k));
        (
            LobeValues {
                r: rgb(&self.r),
                tt: rgb(&self.tt),
                trt: rgb(&self.trt),
                ..Default::default()
            },
            self.pdf.as_array_ref()[k],
        )
    }
}

/// Σ_{k<16} c_k x^k by Estrin's scheme, in f32 lanes.
#[inline(always)]
fn estrin16(c: &[f64; 32], x: f32x8) -> f32x8 {
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let k = |i: usize| f32x8::splat(c[i] as f32);
    let a: [f32x8; 8] = std::array::from_fn(|i| k(2 * i + 1).mul_add(x, k(2 * i)));
    let b: [f32x8; 4] = std::array::from_fn(|i| a[2 * i + 1].mul_add(x2, a[2 * i]));
    let d0 = b[1].mul_add(x4, b[0]);
    let d1 = b[3].mul_add(x4, b[2]);
    d1.mul_add(x8, d0)
}

impl Chiang {
    /// [`Chiang::eval_viewed`] for eight (view, ωi) pairs at once: lane k evaluates `views` lane k at ωi's lane k
    /// (`wi`: x, y, z, each a vector of the eight directions' component, as a batch of paths keeps them). Lanes
    /// are independent: a lane without a path (a zero direction) gives NaN in that lane only, for the caller to
    /// ignore.
    pub fn eval_lanes(&self, views: &ViewLanes, wi: &[f32x8; 3]) -> EvalLanes {
        let [x, y, z] = *wi;
        let one = f32x8::splat(1.0);
        // (sin θi, cos θi) of unit length.
        let rho = y.mul_add(y, z * z).sqrt();
        let inv_len = one / x.mul_add(x, rho * rho).sqrt();
        let (sin_i, cos_i) = (x * inv_len, rho * inv_len);
        // φ = φi − φo.
        let phi = views
            .wo_y
            .mul_sub(z, views.wo_z * y)
            .atan2(views.wo_y.mul_add(y, views.wo_z * z));
        let switch = f32x8::splat(M_P_SWITCH as f32);
        let mut mn = [f32x8::ZERO; P_MAX + 1];
        for (p, mn_p) in mn.iter_mut().enumerate() {
            let l = &self.longitudinal[p.min(P_MAX - 1)];
            let (inv_v, log_norm) = (
                f32x8::splat(l.inv_v as f32),
                f32x8::splat(l.log_norm as f32),
            );
            let (so, co) = (views.tilted_sin[p], views.tilted_cos[p]);
            let a = cos_i * co * inv_v;
            // 1 − cos(θi + θo′) without cancellation.
            let sin_sum = sin_i.mul_add(co, cos_i * so);
            let cos_sum = cos_i.mul_sub(co, sin_i * so);
            let one_minus_cos = cos_sum
                .cmp_gt(f32x8::ZERO)
                .blend(sin_sum * sin_sum / (one + cos_sum), one - cos_sum);
            let series = a.cmp_le(switch);
            let exponent = log_norm - one_minus_cos * inv_v - series.blend(a, f32x8::ZERO);
            // Each expansion only where a lane needs it (TRT's and the residual's wide lobes never reach the
            // asymptotic one at the usual roughness, TT's narrow one seldom stays in the series).
            let small = if series.any() {
                let a = a.min(switch);
                let y = f32x8::splat(0.25) * a * a;
                y.mul_add(estrin16(&I0_SERIES, y), one)
            } else {
                f32x8::ZERO
            };
            let large = if series.all() {
                f32x8::ZERO
            } else {
                let inv_a = one / a.max(switch);
                estrin16(&I0_ASYMPTOTIC, inv_a) * (inv_a * f32x8::splat(1.0 / TAU)).sqrt()
            };
            let m_p = exponent.exp() * series.blend(small, large);
            *mn_p = if p < P_MAX {
                let d = phi - views.phis[p];
                let d = (d - f32x8::splat(TAU) * (d / f32x8::splat(TAU)).round())
                    .max(f32x8::splat(-PI))
                    .min(f32x8::splat(PI));
                let e = (-d.abs() * f32x8::splat(self.azimuthal.inv_s)).exp();
                let e1 = e + one;
                m_p * (e * f32x8::splat(self.azimuthal.norm) / (e1 * e1))
            } else {
                m_p * f32x8::splat(0.5 / PI)
            };
        }
        let inv_cos = one / cos_i.max(f32x8::splat(COS_THETA_MIN));
        let f =
            |p: usize| -> [f32x8; 3] { std::array::from_fn(|c| views.ap[p][c] * mn[p] * inv_cos) };
        let (f2, f3) = (f(2), f(3));
        let pdf = if m_uniform(self) {
            f32x8::splat(crate::util::sampling::UNIFORM_SPHERE_PDF)
        } else {
            (0..=P_MAX).fold(f32x8::ZERO, |s, p| views.ap_pdf[p].mul_add(mn[p], s))
        };
        EvalLanes {
            r: f(0),
            tt: f(1),
            trt: std::array::from_fn(|c| f2[c] + f3[c]),
            pdf,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::chiang::ChiangParams;
    use crate::util::sampling::uniform_sphere;
    use rand::Rng;
    use rand_pcg::Pcg32;

    /// The largest relative difference of the lanes from the scalar model over `batches` batches of random views
    /// and directions (every lobe and channel and the pdf; values under `floor` of the batch's largest compared
    /// absolutely, as a fraction of that largest), and whether every lane value was finite.
    fn worst(model: &Chiang, rng: &mut Pcg32, batches: usize) -> (f64, bool) {
        let mut worst = 0.0f64;
        let mut finite = true;
        for _ in 0..batches {
            let mut views = Vec::with_capacity(LANES);
            let mut wi = [Vec3::ZERO; LANES];
            for w in wi.iter_mut() {
                let h = rng.random_range(-1.0f32..=1.0);
                let wo = uniform_sphere(rng.random(), rng.random());
                views.push(model.at(h).viewed(wo));
                *w = uniform_sphere(rng.random(), rng.random());
            }
            let views: [ChiangView; LANES] = views.try_into().unwrap();
            let got = model.eval_lanes(&ViewLanes::new(&views), &directions(&wi));
            for k in 0..LANES {
                let (want, want_pdf) = model.eval_viewed(&views[k], wi[k]);
                let (lane, lane_pdf) = got.lane(k);
                let pairs = [(want.r, lane.r), (want.tt, lane.tt), (want.trt, lane.trt)];
                let scale = pairs
                    .iter()
                    .map(|(w, _)| w.max_element())
                    .fold(want_pdf, f32::max)
                    .max(1e-30) as f64;
                let mut compare = |w: f32, l: f32| {
                    finite &= l.is_finite();
                    let (w, l) = (w as f64, l as f64);
                    let rel = (l - w).abs() / w.abs().max(1e-3 * scale);
                    worst = worst.max(rel);
                };
                for (w, l) in pairs {
                    for c in 0..3 {
                        compare(w[c], l[c]);
                    }
                }
                compare(want_pdf, lane_pdf);
            }
        }
        (worst, finite)
    }

    #[test]
    fn eight_lanes_give_the_scalar_models_values_to_f32_precision() {
        let mut rng = Pcg32::new(27, 8);
        for beta_m in [0.001f32, 0.005, 0.02, 0.1, 0.3, 0.6, 1.0] {
            for beta_n in [0.001f32, 0.05, 0.3, 0.9, 1.0] {
                let model = Chiang::new(ChiangParams {
                    beta_m,
                    beta_n,
                    ..ChiangParams::default()
                })
                .unwrap();
                let (w, finite) = worst(&model, &mut rng, 64);
                assert!(
                    finite,
                    "βm {beta_m} βn {beta_n}: a lane value is not finite"
                );
                // f32 directions carry ~6e-8 rad of rounding, which moves M_p by (θ − θc)/v of it: at three
                // standard deviations of the narrowest lobe (TT, v/4) 3.6e-7/√v relative — the precision f itself
                // has from f32 inputs (0.05 % at βm = 0.001, 2.4e-5 at 0.02). Beyond that, 1e-4.
                let v = f64::from(crate::bsdf::chiang::longitudinal_variance(beta_m));
                let tolerance = 1e-4 + 3.6e-7 / v.sqrt();
                assert!(
                    w < tolerance,
                    "βm {beta_m} βn {beta_n}: lanes off the scalar model by {w:e} (relative)"
                );
            }
        }
    }

    #[test]
    fn views_taken_in_lanes_evaluate_as_the_scalar_views_do() {
        // The lanes' views (f32 throughout, `wide`'s arcsine and exponential) evaluated by the lanes' eval against
        // the scalar model's views and eval: the same tolerance as the eval alone.
        let mut rng = Pcg32::new(27, 9);
        for beta_m in [0.001f32, 0.02, 0.3, 1.0] {
            for sigma in [0.0f32, 0.5, 4.0] {
                let model = Chiang::new(ChiangParams {
                    beta_m,
                    sigma_a: Vec3::new(sigma, 2.0 * sigma, 0.5 * sigma),
                    ..ChiangParams::default()
                })
                .unwrap();
                // The eval test's tolerance with five f32 roundings of the angles (3e-7 rad) where it has one:
                // the lanes also take sin θo, cos θo and the tilts' rotations in f32, where the scalar view keeps
                // them in f64 (0.25 % at βm = 0.001, where the lobes are 0.04° wide; 1.1e-4 at βm = 0.3).
                let v = f64::from(crate::bsdf::chiang::longitudinal_variance(beta_m));
                let tolerance = 1e-4 + 1.8e-6 / v.sqrt();
                for _ in 0..64 {
                    let h: [f32; LANES] = std::array::from_fn(|_| rng.random_range(-1.0f32..=1.0));
                    let wo: [Vec3; LANES] =
                        std::array::from_fn(|_| uniform_sphere(rng.random(), rng.random()));
                    let wi: [Vec3; LANES] =
                        std::array::from_fn(|_| uniform_sphere(rng.random(), rng.random()));
                    let lanes = model.eval_lanes(
                        &model.view_lanes(f32x8::new(h), &directions(&wo)),
                        &directions(&wi),
                    );
                    for k in 0..LANES {
                        let (want, want_pdf) =
                            model.eval_viewed(&model.at(h[k]).viewed(wo[k]), wi[k]);
                        let (got, got_pdf) = lanes.lane(k);
                        let scale = [want.r, want.tt, want.trt]
                            .iter()
                            .map(|w| w.max_element())
                            .fold(want_pdf, f32::max)
                            .max(1e-30) as f64;
                        let pairs = [(want.r, got.r), (want.tt, got.tt), (want.trt, got.trt)];
                        let mut values: Vec<(f32, f32)> = pairs
                            .iter()
                            .flat_map(|(w, g)| (0..3).map(move |c| (w[c], g[c])))
                            .collect();
                        values.push((want_pdf, got_pdf));
                        for (w, g) in values {
                            assert!(g.is_finite(), "βm {beta_m} σ {sigma}: not finite");
                            let rel =
                                (g as f64 - w as f64).abs() / (w.abs() as f64).max(1e-3 * scale);
                            assert!(
                                rel < tolerance,
                                "βm {beta_m} σ {sigma} h {}: {g} against {w} ({rel:e})",
                                h[k]
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn eight_lanes_draw_the_scalar_models_samples() {
        // Same views, same random numbers: the lanes must draw the scalar model's order p and, to f32 precision,
        // its direction (so its distribution, which the scalar model's χ² tests check). The two subtract the
        // orders' probabilities in the same order, so no lane is expected to pick another.
        let mut rng = Pcg32::new(27, 10);
        let (mut n, mut other_p) = (0usize, 0usize);
        for beta_m in [0.01f32, 0.1, 0.3, 1.0] {
            for beta_n in [0.01f32, 0.3, 1.0] {
                let model = Chiang::new(ChiangParams {
                    beta_m,
                    beta_n,
                    ..ChiangParams::default()
                })
                .unwrap();
                for _ in 0..64 {
                    let views: [ChiangView; LANES] = std::array::from_fn(|_| {
                        model
                            .at(rng.random_range(-1.0f32..=1.0))
                            .viewed(uniform_sphere(rng.random(), rng.random()))
                    });
                    let u: [[f32; 3]; LANES] = std::array::from_fn(|_| rng.random());
                    let lanes = model.sample_lanes(
                        &ViewLanes::new(&views),
                        std::array::from_fn(|c| f32x8::new(u.map(|u| u[c]))),
                    );
                    for k in 0..LANES {
                        let Some((want, _)) = model.sample_viewed(&views[k], u[k]) else {
                            continue;
                        };
                        n += 1;
                        let lobe = match lanes.p[k] {
                            0 => Some(crate::bsdf::Lobe::R),
                            1 => Some(crate::bsdf::Lobe::Tt),
                            _ => Some(crate::bsdf::Lobe::Trt),
                        };
                        if lobe != want.lobe {
                            other_p += 1;
                            continue;
                        }
                        let wi = lanes.wi(k);
                        assert!(
                            (wi.length() - 1.0).abs() < 1e-5,
                            "βm {beta_m}: |ωi| {}",
                            wi.length()
                        );
                        // The chord between the two, in f64: the angle for angles this small (an f32 dot product's
                        // arccosine cannot resolve under ~3e-4 rad).
                        let angle = (0..3)
                            .map(|c| (f64::from(wi[c]) - f64::from(want.wi[c])).powi(2))
                            .sum::<f64>()
                            .sqrt();
                        assert!(
                            angle < 2e-5,
                            "βm {beta_m} βn {beta_n}: ωi {wi} against {} ({angle:e} rad)",
                            want.wi
                        );
                    }
                }
            }
        }
        assert!(n > 0, "no lane was compared");
        assert_eq!(other_p, 0, "{other_p} of {n} lanes drew another order");
    }

    #[test]
    fn grazing_directions_and_edge_offsets_stay_finite_and_match() {
        // The sweep every BSDF here passes, through the lanes: ωo and ωi along the fibre (θ = ±90°), a hair's
        // breadth from it, and across it; h at the fibre's edges and centre; the roughness range's ends. Every lane
        // value finite and non-negative; and within the views test's tolerance of the scalar model where both
        // directions' azimuths are defined: a direction whose normal-plane component is ρ has its azimuth only to
        // ~6e-8/ρ rad in f32, which N_p at βn = 0.001 (s ≈ 1.7e-4) turns into differences of that over s between
        // any two f32 evaluations — unbounded at the axis, so the comparison skips ρ < 0.01 (0.6° off the axis).
        let thetas = [-90.0f32, -89.99, -60.0, 0.0, 45.0, 89.99, 90.0].map(f32::to_radians);
        let phis = [0.0f32, 1.0, PI];
        let hs = [-1.0f32, -0.9999, 0.0, 0.5, 0.9999, 1.0];
        let dir = |t: f32, p: f32| Vec3::new(t.sin(), t.cos() * p.cos(), t.cos() * p.sin());
        let mut cases = Vec::new();
        for &to in &thetas {
            for &ti in &thetas {
                for &pi in &phis {
                    for &h in &hs {
                        cases.push((h, dir(to, 0.3), dir(ti, 0.3 + pi)));
                    }
                }
            }
        }
        for beta_m in [0.001f32, 0.3, 1.0] {
            for beta_n in [0.001f32, 0.3, 1.0] {
                let model = Chiang::new(ChiangParams {
                    beta_m,
                    beta_n,
                    ..ChiangParams::default()
                })
                .unwrap();
                let v = f64::from(crate::bsdf::chiang::longitudinal_variance(beta_m));
                let tolerance = 1e-4 + 1.8e-6 / v.sqrt();
                for batch in cases.chunks_exact(LANES) {
                    let h = f32x8::new(std::array::from_fn(|k| batch[k].0));
                    let wo: [Vec3; LANES] = std::array::from_fn(|k| batch[k].1);
                    let wi: [Vec3; LANES] = std::array::from_fn(|k| batch[k].2);
                    let views = model.view_lanes(h, &directions(&wo));
                    let got = model.eval_lanes(&views, &directions(&wi));
                    let drawn = model.sample_lanes(
                        &views,
                        [f32x8::splat(0.37), f32x8::splat(0.61), f32x8::splat(0.83)],
                    );
                    for k in 0..LANES {
                        let (want, want_pdf) =
                            model.eval_viewed(&model.at(batch[k].0).viewed(wo[k]), wi[k]);
                        let (lane, lane_pdf) = got.lane(k);
                        let scale = [want.r, want.tt, want.trt]
                            .iter()
                            .map(|w| w.max_element())
                            .fold(want_pdf, f32::max)
                            .max(1e-30) as f64;
                        let mut values = vec![(want_pdf, lane_pdf)];
                        for (w, l) in [(want.r, lane.r), (want.tt, lane.tt), (want.trt, lane.trt)] {
                            values.extend((0..3).map(|c| (w[c], l[c])));
                        }
                        let rho = |w: Vec3| (w.y * w.y + w.z * w.z).sqrt();
                        let defined = rho(wo[k]) >= 0.01 && rho(wi[k]) >= 0.01;
                        for (w, l) in values {
                            assert!(
                                l.is_finite() && l >= 0.0,
                                "βm {beta_m} βn {beta_n} case {:?}: {l}",
                                batch[k]
                            );
                            let rel =
                                (l as f64 - w as f64).abs() / (w.abs() as f64).max(1e-3 * scale);
                            assert!(
                                !defined || rel < tolerance,
                                "βm {beta_m} βn {beta_n} case {:?}: {l} against {w}",
                                batch[k]
                            );
                        }
                        let (s, _) = drawn.eval.lane(k);
                        let w = drawn.wi(k);
                        assert!(
                            w.is_finite() && (w.length() - 1.0).abs() < 1e-5,
                            "sampled ωi {w}"
                        );
                        assert!(s.sum().is_finite(), "f at the sampled ωi");
                    }
                }
            }
        }
    }
}

//! A fibre model written once for one shading point or eight: the [`Fibre`] trait, generic over the number type
//! [`Real`] (`f32` for one point, `f32x8` for eight, [`LANES`]), as Mitsuba 3's plugins are templated over `Float`.
//!
//! A model prepares a hit once ([`Fibre::view`]: what depends on the offset h across the fibre and on ωo, as
//! pbrt-v4's materials build a BxDF per hit) and then evaluates ([`Fibre::eval_view`]) and samples
//! ([`Fibre::sample_view`]) it as often as the shading point needs. The scalar [`Bsdf`] of every model is
//! [`At`], the generic code at `R = f32`; batched shading runs the same code at `R = f32x8`. Directions are
//! given component by component (`[x, y, z]` in the local hair frame of [`super::frame`]), colours channel by
//! channel, so that lane k of every number is one shading point.

use glam::{Vec3, Vec3A};
use wide::f32x8;

use super::{make_sample, Bsdf, BsdfSample, Lobe, LobeValues};
use crate::util::real::Real;

/// Shading points per batch: one f32×8 vector (AVX2).
pub const LANES: usize = 8;

/// f per lobe, channel by channel (R, G, B), in number type `R`; [`LobeValues`] for one lane.
#[derive(Debug, Clone, Copy)]
pub struct LobesOf<R> {
    /// R, the surface reflection (Marschner, ISHair, Chiang) or Kajiya-Kay's specular cone.
    pub r: [R; 3],
    /// TT, transmission.
    pub tt: [R; 3],
    /// TRT (Chiang: with the residual orders p ≥ 3).
    pub trt: [R; 3],
    /// ISHair's glints.
    pub glint: [R; 3],
    /// The diffuse term.
    pub diffuse: [R; 3],
}

impl<R: Real> LobesOf<R> {
    /// Every lobe zero.
    #[inline(always)]
    pub fn zero() -> LobesOf<R> {
        let z = [R::splat(0.0); 3];
        LobesOf {
            r: z,
            tt: z,
            trt: z,
            glint: z,
            diffuse: z,
        }
    }

    /// Lane `k`'s lobes.
    #[inline]
    pub fn lane(&self, k: usize) -> LobeValues {
        let c = |v: &[R; 3]| Vec3A::new(v[0].lane(k), v[1].lane(k), v[2].lane(k));
        LobeValues {
            r: c(&self.r),
            tt: c(&self.tt),
            trt: c(&self.trt),
            glint: c(&self.glint),
            diffuse: c(&self.diffuse),
        }
    }
}

/// f per lobe and the sampling pdf at one (ωo, ωi) per lane.
#[derive(Debug, Clone, Copy)]
pub struct EvalOf<R> {
    /// f per lobe.
    pub lobes: LobesOf<R>,
    /// The pdf per unit solid angle with which [`Fibre::sample_view`] draws ωi.
    pub pdf: R,
}

impl<R: Real> EvalOf<R> {
    /// Lane `k`: (f per lobe, pdf).
    #[inline]
    pub fn lane(&self, k: usize) -> (LobeValues, f32) {
        (self.lobes.lane(k), self.pdf.lane(k))
    }
}

/// A sampled ωi per lane, with f and the pdf there ([`EvalOf`] at ωi). A lane whose sampler draws nothing has
/// pdf 0.
#[derive(Debug, Clone, Copy)]
pub struct SampleOf<R> {
    /// ωi, local frame, unit length.
    pub wi: [R; 3],
    /// f and the pdf at ωi.
    pub eval: EvalOf<R>,
    /// The lobe the sampler chose, as its index in [`Lobe::ALL`]; negative when none was chosen (uniform
    /// sampling).
    pub lobe: R,
}

impl<R: Real> SampleOf<R> {
    /// Lane `k`'s ωi.
    #[inline]
    pub fn wi(&self, k: usize) -> Vec3 {
        lane_vec3(&self.wi, k)
    }

    /// Lane `k` as a [`BsdfSample`] (None where the pdf is not positive and finite).
    #[inline]
    pub fn to_sample(&self, k: usize) -> Option<BsdfSample> {
        let wi = self.wi(k);
        let (lobes, pdf) = self.eval.lane(k);
        let l = self.lobe.lane(k);
        let lobe = (l >= 0.0).then(|| Lobe::ALL[l as usize]);
        let cos_theta_i = (wi.y * wi.y + wi.z * wi.z).sqrt();
        make_sample(wi, lobes.sum(), pdf, cos_theta_i, lobe)
    }
}

/// A fibre scattering model written once over the number type ([`Real`]).
pub trait Fibre {
    /// What eval and sample share for one hit: the terms of its offset h and ωo.
    type View<R: Real>: Copy;

    /// Whether the model reads the offset h = sin γo across the fibre (Chiang et al.); the others are the same
    /// at every h.
    fn uses_offset(&self) -> bool {
        false
    }

    /// The hit at offset `h` ∈ [−1, 1] seen from `wo` (local frame, unit length), prepared.
    fn view<R: Real>(&self, h: R, wo: [R; 3]) -> Self::View<R>;

    /// f per lobe and the pdf towards `wi` (local frame, unit length).
    fn eval_view<R: Real>(&self, view: &Self::View<R>, wi: [R; 3]) -> EvalOf<R>;

    /// A direction drawn with the random numbers `u` (each in [0, 1)), with f and the pdf there.
    fn sample_view<R: Real>(&self, view: &Self::View<R>, u: [R; 3]) -> SampleOf<R>;
}

/// A [`Fibre`] at one offset h: its scalar [`Bsdf`] (the generic code at `R = f32`).
#[derive(Debug, Clone, Copy)]
pub struct At<'a, F> {
    /// The model.
    pub model: &'a F,
    /// h = sin γo ∈ [−1, 1].
    pub h: f32,
}

impl<F: Fibre> Bsdf for At<'_, F> {
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        let view = self.model.view(self.h, wo.to_array());
        self.model.eval_view(&view, wi.to_array()).lobes.lane(0)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let view = self.model.view(self.h, wo.to_array());
        self.model.sample_view(&view, u).to_sample(0)
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let view = self.model.view(self.h, wo.to_array());
        self.model.eval_view(&view, wi.to_array()).pdf
    }
}

/// Lane `k` of three vectors (x, y, z).
#[inline]
pub fn lane_vec3<R: Real>(c: &[R; 3], k: usize) -> Vec3 {
    Vec3::new(c[0].lane(k), c[1].lane(k), c[2].lane(k))
}

/// Eight directions as three vectors (x, y, z), the layout the lane forms read.
#[inline]
pub fn directions(w: &[Vec3; LANES]) -> [f32x8; 3] {
    std::array::from_fn(|c| f32x8::new(w.each_ref().map(|v| v[c])))
}

/// A [`Fibre`]'s eight-lane form seen as a scalar [`Bsdf`], for tests that run every check on both forms: each
/// query goes into lane [`InLanes::LANE`] of a batch whose other lanes hold other directions and offsets (so a lane
/// that leaked into another would show), and that lane is read back.
#[derive(Debug, Clone, Copy)]
pub struct InLanes<'a, F> {
    /// The model.
    pub model: &'a F,
    /// The offset h of the query's lane.
    pub h: f32,
}

impl<F: Fibre> InLanes<'_, F> {
    /// The lane the query takes.
    pub const LANE: usize = 5;

    /// Eight lanes: `v` in [`InLanes::LANE`], fixed other values elsewhere.
    fn spread(v: Vec3, others: impl Fn(usize) -> Vec3) -> [f32x8; 3] {
        directions(&std::array::from_fn(|k| {
            if k == Self::LANE {
                v
            } else {
                others(k)
            }
        }))
    }

    fn view(&self, wo: Vec3) -> F::View<f32x8> {
        let h = f32x8::new(std::array::from_fn(|k| {
            if k == Self::LANE {
                self.h
            } else {
                0.9 - 0.25 * k as f32
            }
        }));
        let other =
            |k: usize| Vec3::new(0.3 - 0.1 * k as f32, 0.5, 0.2 * k as f32 - 0.7).normalize();
        self.model.view(h, Self::spread(wo, other))
    }

    fn eval8(&self, wo: Vec3, wi: Vec3) -> EvalOf<f32x8> {
        let other = |k: usize| Vec3::new(0.1 * k as f32 - 0.4, -0.6, 0.3).normalize();
        self.model
            .eval_view(&self.view(wo), Self::spread(wi, other))
    }
}

impl<F: Fibre> Bsdf for InLanes<'_, F> {
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        self.eval8(wo, wi).lobes.lane(Self::LANE)
    }

    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let u8 = std::array::from_fn(|c| {
            f32x8::new(std::array::from_fn(|k| {
                if k == Self::LANE {
                    u[c]
                } else {
                    (0.37 * (k + c) as f32).fract()
                }
            }))
        });
        self.model
            .sample_view(&self.view(wo), u8)
            .to_sample(Self::LANE)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.eval8(wo, wi).pdf.lane(Self::LANE)
    }
}

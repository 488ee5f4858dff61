//! A fibre material ready to shade: the scattering model of a scene's `[material]`, built once per frame.
//!
//! # Models that depend on the hit
//!
//! Marschner, ISHair and Kajiya-Kay are one [`Bsdf`] for every hit. Chiang et al. 2016 also depends on the offset
//! h = sin γo of the hit across the fibre ([`super::chiang`]), which the [`Bsdf`] trait does not carry. Rather than
//! widen the trait, a [`Material`] hands the integrator a per-hit [`HitBsdf`] from [`Material::at`]: for the fixed
//! models a borrowed reference to the one model (no work), for Chiang the model at h
//! ([`super::chiang::Chiang::at`]: an arcsine and a square root, on the stack). Nothing is allocated per hit or per
//! sample, and the integrator computes h only when [`Material::uses_offset`] says the model reads it.

use super::chiang::{Chiang, ChiangView};
use super::lanes::{At, EvalOf, Fibre, SampleOf};
use super::{Bsdf, BsdfSample, LobeValues};
use glam::Vec3;
use wide::f32x8;

/// The scattering model of a [`Material`].
pub enum Scattering {
    /// A model that is the same at every hit (Kajiya-Kay, Marschner, ISHair).
    Fixed(Box<dyn Bsdf + Send + Sync>),
    /// Chiang et al. 2016, which depends on the hit's offset h across the fibre.
    Chiang(Chiang),
}

/// A material ready to shade: the model and whether the strand colour tints its diffuse lobe.
pub struct Material {
    /// The scattering model, in the local hair frame.
    pub scattering: Scattering,
    /// `true` when the scene gave no diffuse `color`: the diffuse lobe is multiplied by each strand's colour.
    pub tint_diffuse_by_strand: bool,
    /// The model's scene name, for messages and summaries.
    pub name: &'static str,
}

impl Material {
    /// Whether [`Material::at`] reads h (so the integrator need not compute it otherwise).
    #[inline]
    pub fn uses_offset(&self) -> bool {
        matches!(self.scattering, Scattering::Chiang(_))
    }

    /// The scattering of a hit of offset `h` across the fibre seen from `wo` (local frame), prepared once for every
    /// light sample, material sample and pdf of the shading point ([`PreparedBsdf`]). With `view` false (a hit
    /// that is not shaded further, e.g. a path's last vertex under light sampling alone) nothing is precomputed.
    #[inline]
    pub fn prepare(&self, h: f32, wo: Vec3, view: bool) -> PreparedBsdf<'_> {
        match &self.scattering {
            Scattering::Chiang(c) if view => PreparedBsdf::Chiang {
                model: c,
                view: c.view(h, wo.to_array()),
            },
            _ => PreparedBsdf::Direct {
                bsdf: self.at(h),
                wo,
            },
        }
    }

    /// The [`Bsdf`] at a hit of offset `h` = sin γo ∈ [−1, 1] across the fibre (ignored by the fixed models).
    #[inline]
    pub fn at(&self, h: f32) -> HitBsdf<'_> {
        match &self.scattering {
            Scattering::Fixed(b) => HitBsdf::Fixed(b.as_ref()),
            Scattering::Chiang(c) => HitBsdf::Chiang(c.at(h)),
        }
    }
}

/// The [`Bsdf`] of one hit ([`Material::at`]); a plain value, no allocation.
#[derive(Clone, Copy)]
pub enum HitBsdf<'a> {
    /// A model that is the same at every hit.
    Fixed(&'a (dyn Bsdf + Send + Sync)),
    /// Chiang et al. at the hit's h.
    Chiang(At<'a, Chiang>),
}

impl Bsdf for HitBsdf<'_> {
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        match self {
            HitBsdf::Fixed(b) => b.eval_lobes(wo, wi),
            HitBsdf::Chiang(c) => c.eval_lobes(wo, wi),
        }
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        match self {
            HitBsdf::Fixed(b) => b.eval(wo, wi),
            HitBsdf::Chiang(c) => c.eval(wo, wi),
        }
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        match self {
            HitBsdf::Fixed(b) => b.sample(wo, u),
            HitBsdf::Chiang(c) => c.sample(wo, u),
        }
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        match self {
            HitBsdf::Fixed(b) => b.pdf(wo, wi),
            HitBsdf::Chiang(c) => c.pdf(wo, wi),
        }
    }
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Material")
            .field("name", &self.name)
            .field("tint_diffuse_by_strand", &self.tint_diffuse_by_strand)
            .finish()
    }
}

/// A hit's fibre scattering prepared for its ωo ([`Material::prepare`], as pbrt-v4's materials build a BxDF at
/// each hit): what the integrator evaluates and samples, without knowing the model.
// The Chiang variant carries its view terms (~150 bytes): a vertex lives on the stack for one path step, and boxing
// it would allocate per vertex.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
pub enum PreparedBsdf<'a> {
    /// A model evaluated from (ωo, ωi) at each call.
    Direct {
        /// The model at the hit.
        bsdf: HitBsdf<'a>,
        /// ωo, local frame.
        wo: Vec3,
    },
    /// Chiang et al. with the terms of this ωo and h computed once.
    Chiang {
        /// The model.
        model: &'a Chiang,
        /// The terms of the hit's ωo and h.
        view: ChiangView<f32>,
    },
}

impl PreparedBsdf<'_> {
    /// f per lobe (before cos θi) and the sampling pdf, for light arriving from `wi` (local frame).
    #[inline]
    pub fn eval(&self, wi: Vec3) -> (LobeValues, f32) {
        match self {
            PreparedBsdf::Direct { bsdf, wo } => (bsdf.eval_lobes(*wo, wi), bsdf.pdf(*wo, wi)),
            PreparedBsdf::Chiang { model, view } => model.eval_view(view, wi.to_array()).lane(0),
        }
    }

    /// A sampled ωi (local frame) with its pdf, and f per lobe there.
    #[inline]
    pub fn sample(&self, u: [f32; 3]) -> Option<(BsdfSample, LobeValues)> {
        match self {
            PreparedBsdf::Direct { bsdf, wo } => {
                let s = bsdf.sample(*wo, u)?;
                // The sample's pdf is the mixture pdf already; only the per-lobe split is evaluated.
                let lobes = bsdf.eval_lobes(*wo, s.wi);
                Some((s, lobes))
            }
            PreparedBsdf::Chiang { model, view } => {
                let s = model.sample_view(view, u);
                Some((s.to_sample(0)?, s.eval.lobes.lane(0)))
            }
        }
    }
}

impl Material {
    /// Whether the model has a form in lanes ([`Material::prepare_lanes`]).
    pub fn has_lanes(&self) -> bool {
        matches!(self.scattering, Scattering::Chiang(_))
    }

    /// Eight hits prepared together, lane k at offset `h` lane k seen from `wo` lane k (local frames): the same
    /// model as [`Material::prepare`] in f32×8 lanes ([`super::lanes`]). None for a model without a lane form
    /// ([`Material::has_lanes`]).
    #[inline]
    pub fn prepare_lanes(&self, h: f32x8, wo: [f32x8; 3]) -> Option<PreparedLanes<'_>> {
        match &self.scattering {
            Scattering::Chiang(c) => Some(PreparedLanes::Chiang {
                model: c,
                view: c.view(h, wo),
            }),
            Scattering::Fixed(_) => None,
        }
    }
}

/// Eight hits' fibre scattering prepared together ([`Material::prepare_lanes`]): what a batch of paths evaluates
/// and samples in lanes, without knowing the model.
#[derive(Clone, Copy)]
pub enum PreparedLanes<'a> {
    /// Chiang et al. with the terms of each lane's ωo and h.
    Chiang {
        /// The model.
        model: &'a Chiang,
        /// The terms per lane.
        view: ChiangView<f32x8>,
    },
}

impl PreparedLanes<'_> {
    /// f per lobe and the pdf towards `wi` per lane (local frames).
    #[inline]
    pub fn eval(&self, wi: [f32x8; 3]) -> EvalOf<f32x8> {
        match self {
            PreparedLanes::Chiang { model, view } => model.eval_view(view, wi),
        }
    }

    /// A sampled ωi per lane with the random numbers `u`, with f and the pdf there.
    #[inline]
    pub fn sample(&self, u: [f32x8; 3]) -> SampleOf<f32x8> {
        match self {
            PreparedLanes::Chiang { model, view } => model.sample_view(view, u),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::chiang::ChiangParams;
    use crate::bsdf::kajiya_kay::{KajiyaKay, KajiyaKayParams};

    #[test]
    fn chiang_material_depends_on_h_and_fixed_does_not() {
        let (wo, wi) = (
            Vec3::new(0.3, 0.8, 0.2).normalize(),
            Vec3::new(-0.2, 0.1, 0.9).normalize(),
        );
        let chiang = Material {
            scattering: Scattering::Chiang(Chiang::new(ChiangParams::default()).unwrap()),
            tint_diffuse_by_strand: false,
            name: "chiang",
        };
        assert!(chiang.uses_offset());
        let (a, b) = (chiang.at(-0.6).eval(wo, wi), chiang.at(0.6).eval(wo, wi));
        assert!(
            (a - b).abs().max_element() > 1e-3 * a.max_element(),
            "{a} {b}"
        );
        // The per-hit value is exactly the model at that h.
        let model = Chiang::new(ChiangParams::default()).unwrap();
        assert_eq!(chiang.at(0.6).eval(wo, wi), model.at(0.6).eval(wo, wi));
        let kk = Material {
            scattering: Scattering::Fixed(Box::new(
                KajiyaKay::from_params(KajiyaKayParams::default()).unwrap(),
            )),
            tint_diffuse_by_strand: true,
            name: "kajiya-kay",
        };
        assert!(!kk.uses_offset());
        assert_eq!(kk.at(-0.6).eval(wo, wi), kk.at(0.6).eval(wo, wi));
    }

    /// The prepared fibre gives what the model's [`Bsdf`] gives at the same hit: every model, viewed or not, the
    /// same lobes, pdf and samples over a spread of directions and random numbers (the view only saves work).
    #[test]
    fn a_prepared_fibre_evaluates_and_samples_as_its_model() {
        use crate::scene::MaterialConfig;
        use crate::util::sampling::uniform_sphere;
        for name in ["kajiya-kay", "marschner", "ishair", "chiang"] {
            let material = MaterialConfig::named(name).unwrap().build().unwrap();
            for (k, h) in [-0.7f32, 0.0, 0.4].into_iter().enumerate() {
                let wo = uniform_sphere(0.13 + 0.2 * k as f32, 0.71);
                let bsdf = material.at(h);
                for view in [false, true] {
                    let prepared = material.prepare(h, wo, view);
                    for i in 0..64 {
                        let u = [(i as f32 + 0.5) / 64.0, (i * 37 % 64) as f32 / 64.0, 0.37];
                        let wi = uniform_sphere(u[0], u[1]);
                        let (lobes, pdf) = prepared.eval(wi);
                        assert_eq!(lobes.sum(), bsdf.eval_lobes(wo, wi).sum(), "{name} h {h}");
                        assert_eq!(pdf, bsdf.pdf(wo, wi), "{name} h {h}");
                        let (p, q) = (prepared.sample(u), bsdf.sample(wo, u));
                        assert_eq!(
                            p.map(|(s, _)| (s.wi, s.pdf)),
                            q.map(|s| (s.wi, s.pdf)),
                            "{name}"
                        );
                        if let Some((s, lobes)) = p {
                            assert_eq!(
                                lobes.sum(),
                                bsdf.eval_lobes(wo, s.wi).sum(),
                                "{name} h {h}"
                            );
                        }
                    }
                }
            }
        }
    }
}

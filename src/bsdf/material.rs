//! A fibre material ready to shade: the scattering model of a scene's `[material]`, built once per frame, and what
//! it hands the integrator at a hit.
//!
//! Every model is one [`Fibre`] (written once over the number type, [`super::lanes`]). At a hit the material
//! prepares it for the hit's offset h and ωo ([`Material::prepare`], as pbrt-v4's materials build a BxDF per hit):
//! a [`PreparedBsdf`] for one shading point, a [`PreparedLanes`] for eight ([`Material::prepare_lanes`]). The
//! integrator evaluates and samples those and names no model. Nothing is allocated per hit or per sample; the
//! integrator computes h only when [`Material::uses_offset`] says the model reads it (Chiang et al.).

use super::chiang::Chiang;
use super::dual::DualScattering;
use super::ishair::IsHair;
use super::kajiya_kay::KajiyaKay;
use super::lanes::{At, EvalOf, Fibre, SampleOf};
use super::marschner::Marschner;
use super::{Bsdf, BsdfSample, LobeValues};
use glam::Vec3;
use std::sync::{Arc, OnceLock};
use wide::f32x8;

/// The scattering model of a [`Material`].
#[derive(Debug, Clone)]
pub enum Scattering {
    /// Kajiya & Kay 1989.
    KajiyaKay(KajiyaKay),
    /// Marschner's R lobes as Hery & Ramamoorthi sample them (thesis §4.2).
    Marschner(Marschner),
    /// ISHair (Ou et al. 2012, thesis §4.3).
    IsHair(IsHair),
    /// Chiang et al. 2016, which depends on the hit's offset h across the fibre.
    Chiang(Chiang),
}

/// `$body` with `$m` bound to the model of a [`Scattering`]; in the second form, the result wrapped in the
/// same-named variant of the enum `$out` (one arm per model, written once).
macro_rules! per_model {
    ($scattering:expr, $m:ident => $body:expr) => {
        match $scattering {
            Scattering::KajiyaKay($m) => $body,
            Scattering::Marschner($m) => $body,
            Scattering::IsHair($m) => $body,
            Scattering::Chiang($m) => $body,
        }
    };
    ($scattering:expr, $m:ident, $out:ident => $body:expr) => {
        match $scattering {
            Scattering::KajiyaKay($m) => $out::KajiyaKay($body),
            Scattering::Marschner($m) => $out::Marschner($body),
            Scattering::IsHair($m) => $out::IsHair($body),
            Scattering::Chiang($m) => $out::Chiang($body),
        }
    };
}

/// `$body` with `$m` and `$v` bound to the model and view of a prepared enum (`$ty`: [`Viewed`] or
/// [`PreparedLanes`]).
macro_rules! per_prepared {
    ($ty:ident, $prepared:expr, ($m:ident, $v:ident) => $body:expr) => {
        match $prepared {
            $ty::KajiyaKay(($m, $v)) => $body,
            $ty::Marschner(($m, $v)) => $body,
            $ty::IsHair(($m, $v)) => $body,
            $ty::Chiang(($m, $v)) => $body,
        }
    };
}

/// A material ready to shade: the model and whether the strand colour tints its diffuse lobe.
#[derive(Clone)]
pub struct Material {
    /// The scattering model, in the local hair frame.
    pub scattering: Scattering,
    /// `true` when the scene gave no diffuse `color`: the diffuse lobe is multiplied by each strand's colour.
    pub tint_diffuse_by_strand: bool,
    /// The model's scene name, for messages and summaries.
    pub name: &'static str,
    /// Dual scattering's tables, built on first use ([`Material::dual`]) and shared by the material's clones.
    pub dual: DualTables,
}

/// A material's dual-scattering tables, computed once when first asked for (~50 ms on one core, so a material
/// that never renders with dual scattering never pays for them).
#[derive(Clone, Default)]
pub struct DualTables(Arc<OnceLock<Option<DualScattering>>>);

impl Material {
    /// Dual scattering's tables of this material ([`crate::bsdf::dual`]), or `None` for a model it is not built for
    /// (every model but Chiang's).
    pub fn dual(&self) -> Option<&DualScattering> {
        self.dual
            .0
            .get_or_init(|| match &self.scattering {
                Scattering::Chiang(m) => Some(DualScattering::new(m)),
                _ => None,
            })
            .as_ref()
    }

    /// Whether the model reads the offset h (so the integrator need not compute it otherwise).
    #[inline]
    pub fn uses_offset(&self) -> bool {
        per_model!(&self.scattering, m => m.uses_offset())
    }

    /// The scattering of a hit of offset `h` across the fibre seen from `wo` (local frame), prepared once for every
    /// light sample, material sample and pdf of the shading point. With `view` false (a hit whose shading the
    /// caller does in lanes, [`Material::prepare_lanes`]) nothing is computed until it is used.
    #[inline]
    pub fn prepare(&self, h: f32, wo: Vec3, view: bool) -> PreparedBsdf<'_> {
        if !view {
            return PreparedBsdf::Later(self, h, wo);
        }
        let wo = wo.to_array();
        PreparedBsdf::Viewed(per_model!(&self.scattering, m, Viewed => (m, m.view(h, wo))))
    }

    /// Eight hits prepared together, lane k at offset `h` lane k seen from `wo` lane k (local frames): the same
    /// model as [`Material::prepare`] in f32×8 lanes.
    #[inline]
    pub fn prepare_lanes(&self, h: f32x8, wo: [f32x8; 3]) -> PreparedLanes<'_> {
        per_model!(&self.scattering, m, PreparedLanes => (m, m.view(h, wo)))
    }

    /// The [`Bsdf`] at a hit of offset `h` = sin γo ∈ [−1, 1] across the fibre (ignored by the models that do not
    /// read it), for tools that take any [`Bsdf`] (plots, albedo tables).
    #[inline]
    pub fn at(&self, h: f32) -> HitBsdf<'_> {
        per_model!(&self.scattering, m, HitBsdf => At { model: m, h })
    }
}

/// The [`Bsdf`] of one hit ([`Material::at`]); a plain value, no allocation.
#[derive(Clone, Copy)]
pub enum HitBsdf<'a> {
    #[allow(missing_docs)]
    KajiyaKay(At<'a, KajiyaKay>),
    #[allow(missing_docs)]
    Marschner(At<'a, Marschner>),
    #[allow(missing_docs)]
    IsHair(At<'a, IsHair>),
    #[allow(missing_docs)]
    Chiang(At<'a, Chiang>),
}

/// `$body` with `$b` bound to a [`HitBsdf`]'s model at its h.
macro_rules! per_hit {
    ($hit:expr, $b:ident => $body:expr) => {
        match $hit {
            HitBsdf::KajiyaKay($b) => $body,
            HitBsdf::Marschner($b) => $body,
            HitBsdf::IsHair($b) => $body,
            HitBsdf::Chiang($b) => $body,
        }
    };
}

impl Bsdf for HitBsdf<'_> {
    #[inline]
    fn eval_lobes(&self, wo: Vec3, wi: Vec3) -> LobeValues {
        per_hit!(self, b => b.eval_lobes(wo, wi))
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        per_hit!(self, b => b.sample(wo, u))
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        per_hit!(self, b => b.pdf(wo, wi))
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

/// A hit's fibre scattering prepared for its h and ωo ([`Material::prepare`]): what the integrator evaluates and
/// samples, without knowing the model.
#[derive(Clone, Copy)]
pub enum PreparedBsdf<'a> {
    /// The model with the terms of this h and ωo.
    Viewed(Viewed<'a>),
    /// Not prepared yet: the material, h and ωo (local frame).
    Later(&'a Material, f32, Vec3),
}

/// A model with the terms of one hit's h and ωo ([`PreparedBsdf::Viewed`]).
// Chiang's variant carries its view terms (~120 bytes): a vertex lives on the stack for one path step, and boxing it
// would allocate per vertex.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
pub enum Viewed<'a> {
    #[allow(missing_docs)]
    KajiyaKay((&'a KajiyaKay, <KajiyaKay as Fibre>::View<f32>)),
    #[allow(missing_docs)]
    Marschner((&'a Marschner, <Marschner as Fibre>::View<f32>)),
    #[allow(missing_docs)]
    IsHair((&'a IsHair, <IsHair as Fibre>::View<f32>)),
    #[allow(missing_docs)]
    Chiang((&'a Chiang, <Chiang as Fibre>::View<f32>)),
}

impl PreparedBsdf<'_> {
    /// f per lobe (before cos θi) and the sampling pdf, for light arriving from `wi` (local frame).
    #[inline]
    pub fn eval(&self, wi: Vec3) -> (LobeValues, f32) {
        match self {
            PreparedBsdf::Viewed(p) => {
                per_prepared!(Viewed, p, (m, v) => m.eval_view(v, wi.to_array()).lane(0))
            }
            PreparedBsdf::Later(material, h, wo) => material.prepare(*h, *wo, true).eval(wi),
        }
    }

    /// A sampled ωi (local frame) with its pdf, and f per lobe there.
    #[inline]
    pub fn sample(&self, u: [f32; 3]) -> Option<(BsdfSample, LobeValues)> {
        match self {
            PreparedBsdf::Viewed(p) => {
                let s = per_prepared!(Viewed, p, (m, v) => m.sample_view(v, u));
                Some((s.to_sample(0)?, s.eval.lobes.lane(0)))
            }
            PreparedBsdf::Later(material, h, wo) => material.prepare(*h, *wo, true).sample(u),
        }
    }
}

/// Eight hits' fibre scattering prepared together ([`Material::prepare_lanes`]): what a batch of paths evaluates
/// and samples in lanes, without knowing the model.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy)]
pub enum PreparedLanes<'a> {
    #[allow(missing_docs)]
    KajiyaKay((&'a KajiyaKay, <KajiyaKay as Fibre>::View<f32x8>)),
    #[allow(missing_docs)]
    Marschner((&'a Marschner, <Marschner as Fibre>::View<f32x8>)),
    #[allow(missing_docs)]
    IsHair((&'a IsHair, <IsHair as Fibre>::View<f32x8>)),
    #[allow(missing_docs)]
    Chiang((&'a Chiang, <Chiang as Fibre>::View<f32x8>)),
}

impl PreparedLanes<'_> {
    /// f per lobe and the pdf towards `wi` per lane (local frames).
    #[inline]
    pub fn eval(&self, wi: [f32x8; 3]) -> EvalOf<f32x8> {
        per_prepared!(PreparedLanes, self, (m, v) => m.eval_view(v, wi))
    }

    /// A sampled ωi per lane with the random numbers `u`, with f and the pdf there.
    #[inline]
    pub fn sample(&self, u: [f32x8; 3]) -> SampleOf<f32x8> {
        per_prepared!(PreparedLanes, self, (m, v) => m.sample_view(v, u))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::chiang::ChiangParams;
    use crate::bsdf::kajiya_kay::KajiyaKayParams;

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
            dual: Default::default(),
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
            scattering: Scattering::KajiyaKay(
                KajiyaKay::from_params(KajiyaKayParams::default()).unwrap(),
            ),
            tint_diffuse_by_strand: true,
            name: "kajiya-kay",
            dual: Default::default(),
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
                        // f per lobe at the sampled direction, as eval gives it there to f32 rounding (Marschner
                        // evaluates at the angles it drew, not at the rounded direction); except along the fibre's
                        // axis, where the azimuth is undefined and a sampler's f follows the azimuth it drew.
                        if let Some((s, lobes)) = p.filter(|(s, _)| s.wi.x.abs() < 1.0 - 1e-6) {
                            let (a, b) = (lobes.sum(), bsdf.eval_lobes(wo, s.wi).sum());
                            assert!(
                                (a - b).abs().max_element() <= 1e-5 * b.max_element(),
                                "{name} h {h}: {a} against {b}"
                            );
                        }
                    }
                }
            }
        }
    }
}

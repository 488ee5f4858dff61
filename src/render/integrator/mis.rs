//! Multiple importance sampling of direct light at one path vertex (Veach 1997, chapter 9): how a light sample
//! and a material sample that can reach the same light share it.
//!
//! Each vertex runs two strategies: the light strategy (`n_l` light samples; with one light chosen per sample,
//! light j expects n_j = n_l · P(j) of them) and the material strategy (`n_m` BSDF samples). Veach's
//! multi-sample estimator (§9.2.2) weights every sample X of strategy i by w_i(X) and divides it by n_i p_i(X);
//! the weights of the strategies that can produce X must sum to 1 for it to stay unbiased. The weights here are
//! the power heuristic (β = 2, §9.2.4) over the count-weighted densities n_i p_i, with three exceptions:
//!
//! - a **delta light** (a distant light of zero angular radius) can only be found by light sampling: its light
//!   sample takes weight 1, and its density for a material sample is 0;
//! - **single strategies** (`strategy = "light"` / `"material"`) give their own strategy weight 1 and the other 0;
//! - at the **last vertex** of a path under MIS or light sampling, the light sample takes the whole weight and a
//!   material sample none, so the integrator traces no material ray there (still unbiased; one ray less per path).

use glam::Vec3;

use crate::light::{Light, LightSample};

use super::{LightSelection, Settings, Strategy};

/// Power heuristic (Veach §9.2.4, β = 2) for the count-weighted densities `a` = n_a p_a of the strategy being
/// weighted and `b` = n_b p_b of the other: w_a = a² / (a² + b²). An infinite `a` takes weight 1; two zero (or
/// non-finite) densities weight 0.
#[inline]
pub(super) fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 && (a2 + b2).is_finite() {
        a2 / (a2 + b2)
    } else if a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// The strategies of one path vertex and how their samples are weighted (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Mis {
    /// Which strategies estimate direct light.
    pub(super) strategy: Strategy,
    /// Whether every light gets `light_samples` samples or each sample goes to one light chosen ∝ power.
    pub(super) selection: LightSelection,
    /// n_l: light samples (per light under [`LightSelection::All`], in all under [`LightSelection::One`]).
    pub(super) light_samples: u32,
    /// n_m: material samples.
    pub(super) material_samples: u32,
    /// Whether this is the path's last vertex (the last-vertex rule applies).
    pub(super) last: bool,
}

impl Mis {
    /// The first shading point: the settings' sample counts (at least 1 each) and light selection. It is never
    /// the last vertex in the sense of [`Mis::light_only`], even with `path_length` = 0: its material samples are
    /// the thesis' "material samples".
    pub(super) fn first_vertex(s: &Settings) -> Mis {
        Mis {
            strategy: s.strategy,
            selection: s.light_selection,
            light_samples: s.light_samples.max(1),
            material_samples: s.material_samples.max(1),
            last: false,
        }
    }

    /// A vertex after the first: one light chosen ∝ power, one material sample; `last` at the path's end.
    pub(super) fn deeper_vertex(strategy: Strategy, last: bool) -> Mis {
        Mis {
            strategy,
            selection: LightSelection::One,
            light_samples: 1,
            material_samples: 1,
            last,
        }
    }

    /// The last-vertex rule: at the path's last vertex under MIS or light sampling only the light sample counts
    /// (weight 1; a material sample's weight is 0, so none is traced). Under material sampling the material
    /// sample still carries the non-delta lights there.
    #[inline]
    pub(super) fn light_only(&self) -> bool {
        self.last && self.strategy != Strategy::Material
    }

    /// Whether the light strategy samples a light at all: not a non-delta light under material-only sampling
    /// (material samples find it); a delta light always (nothing else can).
    #[inline]
    pub(super) fn samples_light(&self, delta: bool) -> bool {
        delta || self.strategy != Strategy::Material
    }

    /// Samples one light gets under [`LightSelection::All`]: n_l, or 1 for a delta light (more would all draw
    /// the same direction).
    #[inline]
    pub(super) fn samples_per_light(&self, delta: bool) -> u32 {
        if delta {
            1
        } else {
            self.light_samples
        }
    }

    /// n_j, the number of light samples a light expects here: [`Mis::samples_per_light`] under
    /// [`LightSelection::All`], n_l · `p_select` (its selection probability) under [`LightSelection::One`].
    #[inline]
    pub(super) fn light_count(&self, delta: bool, p_select: f32) -> f32 {
        match self.selection {
            LightSelection::All => self.samples_per_light(delta) as f32,
            LightSelection::One => self.light_samples as f32 * p_select,
        }
    }

    /// n_m p_m: the material strategy's count-weighted density for a direction it draws with density `pdf`.
    #[inline]
    pub(super) fn material_density(&self, pdf: f32) -> f32 {
        self.material_samples as f32 * pdf
    }

    /// n_j p_j: the light strategy's count-weighted density for `light` (selection probability `p_select`) to
    /// draw `wi` from `p` — 0 for a delta light, which no material sample can hit.
    #[inline]
    pub(super) fn light_density(&self, light: &Light, p_select: f32, p: Vec3, wi: Vec3) -> f32 {
        if light.is_delta() {
            0.0
        } else {
            self.light_count(false, p_select) * light.pdf_li(p, wi)
        }
    }

    /// w_l of light sample `ls` of a light expecting `count` samples here ([`Mis::light_count`]), where the
    /// material draws its direction with density `pdf_m` (per sample).
    #[inline]
    pub(super) fn light_weight(&self, ls: &LightSample, count: f32, pdf_m: f32) -> f32 {
        if ls.delta || self.light_only() {
            return 1.0;
        }
        match self.strategy {
            Strategy::Mis => power_heuristic(count * ls.pdf, self.material_density(pdf_m)),
            Strategy::Light => 1.0,
            Strategy::Material => 0.0,
        }
    }

    /// w_m of a material sample of count-weighted density `p_material` ([`Mis::material_density`]) that reached a
    /// light whose count-weighted density for it is `p_light` ([`Mis::light_density`]).
    #[inline]
    pub(super) fn material_weight(&self, p_material: f32, p_light: f32) -> f32 {
        if self.light_only() {
            return 0.0;
        }
        match self.strategy {
            Strategy::Mis => power_heuristic(p_material, p_light),
            Strategy::Light => 0.0,
            Strategy::Material => 1.0,
        }
    }
}

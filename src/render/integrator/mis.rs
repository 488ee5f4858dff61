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
//! - at the **last vertex** of a path under light sampling alone no material ray is traced (its weight would be 0).
//!   Under MIS the last vertex keeps both strategies, like every other vertex. Giving the light sample the whole
//!   weight there is unbiased and saves a ray, but for narrow lobes under an environment it is the poor strategy:
//!   it covers the Chiang peer scene at 64 spp in orange single-pixel fireflies (a uniformly sampled environment
//!   direction landing in a narrow TT lobe at the second vertex) where Mitsuba 3, which keeps MIS there, is
//!   smooth.

use glam::Vec3;

use crate::light::{Light, LightSample};

use super::{LightSelection, Settings, Strategy};

/// Power heuristic (Veach §9.2.4, β = 2) for the count-weighted densities `a` = n_a p_a of the strategy being
/// weighted and `b` = n_b p_b of the other: w_a = a² / (a² + b²). An infinite `a` takes weight 1; two zero (or
/// non-finite) densities weight 0.
#[inline]
pub(in crate::render) fn power_heuristic(a: f32, b: f32) -> f32 {
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
pub(in crate::render) struct Mis {
    /// Which strategies estimate direct light.
    pub(in crate::render) strategy: Strategy,
    /// Whether every light gets `light_samples` samples or each sample goes to one light chosen ∝ its selection
    /// weight.
    pub(in crate::render) selection: LightSelection,
    /// n_l: light samples (per light under [`LightSelection::All`], in all under [`LightSelection::One`]).
    pub(in crate::render) light_samples: u32,
    /// n_m: material samples.
    pub(in crate::render) material_samples: u32,
    /// Whether this is the path's last vertex (the last-vertex rule applies).
    pub(super) last: bool,
}

impl Mis {
    /// The first shading point: the settings' sample counts (at least 1 each) and light selection. It is never
    /// the last vertex in the sense of [`Mis::light_only`], even with `path_length` = 0: its material samples are
    /// the thesis' "material samples".
    pub(in crate::render) fn first_vertex(s: &Settings) -> Mis {
        Mis {
            strategy: s.strategy,
            selection: s.light_selection,
            light_samples: s.light_samples.max(1),
            material_samples: s.material_samples.max(1),
            last: false,
        }
    }

    /// A vertex after the first: one light chosen ∝ its selection weight, one material sample; `last` at the path's
    /// end.
    pub(in crate::render) fn deeper_vertex(strategy: Strategy, last: bool) -> Mis {
        Mis {
            strategy,
            selection: LightSelection::One,
            light_samples: 1,
            material_samples: 1,
            last,
        }
    }

    /// Whether no material sample is needed at this vertex: the path's last vertex under light sampling alone
    /// (a material sample would weigh 0 there). Under MIS the last vertex keeps its material sample (see the
    /// module docs); under material sampling it carries the non-delta lights.
    #[inline]
    pub(in crate::render) fn light_only(&self) -> bool {
        self.last && self.strategy == Strategy::Light
    }

    /// Whether the light strategy samples a light at all: not a non-delta light under material-only sampling
    /// (material samples find it); a delta light always (nothing else can).
    #[inline]
    pub(in crate::render) fn samples_light(&self, delta: bool) -> bool {
        delta || self.strategy != Strategy::Material
    }

    /// Samples one light gets under [`LightSelection::All`]: n_l, or 1 for a delta light (more would all draw
    /// the same direction).
    #[inline]
    pub(in crate::render) fn samples_per_light(&self, delta: bool) -> u32 {
        if delta {
            1
        } else {
            self.light_samples
        }
    }

    /// n_j, the number of light samples a light expects here: [`Mis::samples_per_light`] under
    /// [`LightSelection::All`], n_l · `p_select` (its selection probability) under [`LightSelection::One`].
    #[inline]
    pub(in crate::render) fn light_count(&self, delta: bool, p_select: f32) -> f32 {
        match self.selection {
            LightSelection::All => self.samples_per_light(delta) as f32,
            LightSelection::One => self.light_samples as f32 * p_select,
        }
    }

    /// n_m p_m: the material strategy's count-weighted density for a direction it draws with density `pdf`.
    #[inline]
    pub(in crate::render) fn material_density(&self, pdf: f32) -> f32 {
        self.material_samples as f32 * pdf
    }

    /// n_j p_j: the light strategy's count-weighted density for `light` (selection probability `p_select`) to
    /// draw `wi` from `p` — 0 for a delta light, which no material sample can hit.
    #[inline]
    pub(in crate::render) fn light_density(
        &self,
        light: &Light,
        p_select: f32,
        p: Vec3,
        wi: Vec3,
    ) -> f32 {
        if light.is_delta() {
            0.0
        } else {
            self.light_count(false, p_select) * light.pdf_li(p, wi)
        }
    }

    /// w_l of light sample `ls` of a light expecting `count` samples here ([`Mis::light_count`]), where the
    /// material draws its direction with density `pdf_m` (per sample).
    #[inline]
    pub(in crate::render) fn light_weight(&self, ls: &LightSample, count: f32, pdf_m: f32) -> f32 {
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
    pub(in crate::render) fn material_weight(&self, p_material: f32, p_light: f32) -> f32 {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::light::{Distant, Distribution1D};

    /// Weights here are a few f32 operations on exactly representable inputs: a few ulps.
    const TOLERANCE: f32 = 1e-6;

    fn close(what: &str, got: f32, want: f32) {
        assert!(
            (got - want).abs() <= TOLERANCE,
            "{what}: got {got}, want {want}"
        );
    }

    /// The first vertex with `n_l` light samples and `n_m` material samples.
    fn first(strategy: Strategy, selection: LightSelection, n_l: u32, n_m: u32) -> Mis {
        Mis {
            strategy,
            selection,
            light_samples: n_l,
            material_samples: n_m,
            last: false,
        }
    }

    /// A light sample of density `pdf` towards +z (not a delta light).
    fn sample(pdf: f32) -> LightSample {
        LightSample {
            wi: Vec3::Z,
            radiance: Vec3::ONE,
            pdf,
            distance: f32::INFINITY,
            delta: false,
        }
    }

    /// (w_l, w_m) of one direction that a (non-delta) light chosen with probability `p_select` draws with
    /// density `p_l` and the material with density `p_m`, as the integrator computes them: w_l for the light
    /// sample, w_m for a material sample that hits the light.
    fn weights(mis: &Mis, p_select: f32, p_l: f32, p_m: f32) -> (f32, f32) {
        let n_j = mis.light_count(false, p_select);
        let w_l = mis.light_weight(&sample(p_l), n_j, p_m);
        let w_m = mis.material_weight(mis.material_density(p_m), n_j * p_l);
        (w_l, w_m)
    }

    /// Asserts [`weights`] at (`p_select`, `p_l`, `p_m`) against hand-computed (w_l, w_m).
    fn check(what: &str, mis: Mis, (p_select, p_l, p_m): (f32, f32, f32), want: (f32, f32)) {
        let (w_l, w_m) = weights(&mis, p_select, p_l, p_m);
        close(&format!("{what}: w_l"), w_l, want.0);
        close(&format!("{what}: w_m"), w_m, want.1);
    }

    #[test]
    fn power_heuristic_over_counts_times_pdfs() {
        // (w_l by hand, n_l, p_l, n_m, p_m); w_m = 1 - w_l. The counts matter, not only the pdfs.
        let cases = [
            (0.5, 4, 0.5, 1, 2.0),          // (4·0.5)² / ((4·0.5)² + (1·2)²) = 4 / 8
            (0.1, 4, 0.25, 1, 3.0),         // (4·0.25)² / ((4·0.25)² + (1·3)²) = 1 / 10
            (0.9, 1, 3.0, 2, 0.5),          // (1·3)² / ((1·3)² + (2·0.5)²) = 9 / 10
            (36.0 / 36.25, 2, 3.0, 1, 0.5), // (2·3)² / ((2·3)² + (1·0.5)²) = 36 / 36.25
        ];
        for (w_l, n_l, p_l, n_m, p_m) in cases {
            let what = format!("n_l {n_l}, p_l {p_l}, n_m {n_m}, p_m {p_m}");
            let mis = first(Strategy::Mis, LightSelection::All, n_l, n_m);
            check(&what, mis, (1.0, p_l, p_m), (w_l, 1.0 - w_l));
        }
    }

    #[test]
    fn the_last_vertex_keeps_mis_and_light_sampling_traces_no_material_ray_there() {
        // Densities at which MIS gives the light sample 1 / 10 and a material sample's emitter hit 9 / 10, at an
        // inner vertex and at the last one alike (the material ray is traced there too).
        let densities = (1.0, 1.0, 3.0);
        let inner = Mis::deeper_vertex(Strategy::Mis, false);
        assert!(!inner.light_only());
        check("mis, inner vertex", inner, densities, (0.1, 0.9));
        let last = Mis::deeper_vertex(Strategy::Mis, true);
        assert!(!last.light_only());
        check("mis, last vertex", last, densities, (0.1, 0.9));
        // Light sampling alone: the same, last or not.
        let light = Mis::deeper_vertex(Strategy::Light, true);
        assert!(light.light_only());
        check("light, last vertex", light, densities, (1.0, 0.0));
        // Material sampling keeps its material sample at the last vertex (only it finds non-delta lights).
        let material = Mis::deeper_vertex(Strategy::Material, true);
        assert!(!material.light_only());
        check("material, last vertex", material, densities, (0.0, 1.0));
    }

    #[test]
    fn single_strategies_give_their_own_samples_weight_one() {
        for selection in [LightSelection::All, LightSelection::One] {
            let light = first(Strategy::Light, selection, 4, 1);
            check("light only", light, (0.5, 0.25, 3.0), (1.0, 0.0));
            assert!(light.samples_light(false) && light.samples_light(true));
            let material = first(Strategy::Material, selection, 4, 1);
            check("material only", material, (0.5, 0.25, 3.0), (0.0, 1.0));
            // Material sampling leaves non-delta lights to the material samples, delta lights to light samples.
            assert!(!material.samples_light(false) && material.samples_light(true));
        }
    }

    #[test]
    fn a_delta_light_is_found_by_light_samples_only() {
        let sun = Light::Distant(Distant::new(-Vec3::Z, Vec3::splat(2.0), 0.0).unwrap());
        assert!(sun.is_delta());
        let p = Vec3::ZERO;
        let ls = sun
            .sample_li(p, [0.3, 0.7])
            .expect("a distant light always samples");
        assert!(ls.delta && ls.wi == Vec3::Z, "{ls:?}");
        let mis = first(Strategy::Mis, LightSelection::All, 4, 1);
        // One sample, not n_l: every sample would draw the same direction.
        assert_eq!(mis.samples_per_light(true), 1);
        let n = mis.light_count(true, 1.0);
        close("n_j of a delta light", n, 1.0);
        // Weight 1 even where the material's density is far larger than the light's "pdf" of 1.
        close("w_l, delta", mis.light_weight(&ls, n, 1e6), 1.0);
        // A material sample along the sun direction has no light density to share with, and nothing to find.
        close("p_l, delta", mis.light_density(&sun, 1.0, p, Vec3::Z), 0.0);
        assert_eq!(sun.le(-ls.wi), Vec3::ZERO);
        assert_eq!(sun.le(ls.wi), Vec3::ZERO);
        // Material-only sampling still light-samples it, with weight 1.
        let material = first(Strategy::Material, LightSelection::All, 4, 1);
        assert!(material.samples_light(true));
        let w = material.light_weight(&ls, n, 1e6);
        close("w_l, delta, material", w, 1.0);
        // A sun of finite size is an ordinary light: MIS weights it, with n_l p_l as its density.
        let disk = Light::Distant(Distant::new(-Vec3::Z, Vec3::splat(2.0), 0.1).unwrap());
        let ls = disk.sample_li(p, [0.3, 0.7]).unwrap();
        assert!(!ls.delta);
        let w = mis.light_weight(&ls, mis.light_count(false, 1.0), 1e6);
        assert!(w > 0.0 && w < 1.0, "w_l, disk: {w}");
        let want = 4.0 * disk.pdf_li(p, ls.wi);
        close("p_l, disk", mis.light_density(&disk, 1.0, p, ls.wi), want);
    }

    #[test]
    fn one_light_per_sample_puts_the_selection_probability_into_the_light_pdf() {
        // Two lights of power 1 and 3: P(0) = 1/4, P(1) = 3/4.
        let select = Distribution1D::new(&[1.0, 3.0]);
        let (p0, p1) = (select.pmf(0), select.pmf(1));
        close("P(0)", p0, 0.25);
        close("P(1)", p1, 0.75);
        // n_l = 4, n_m = 1, light pdf 0.5, material pdf 0.5. Light 1 expects 4 · 3/4 = 3 samples:
        // (3·0.5)² / ((3·0.5)² + (1·0.5)²) = 2.25 / 2.5;
        let one = first(Strategy::Mis, LightSelection::One, 4, 1);
        close("n_1", one.light_count(false, p1), 3.0);
        check("one, light 1", one, (p1, 0.5, 0.5), (0.9, 0.1));
        // light 0 expects 4 · 1/4 = 1: (1·0.5)² / ((1·0.5)² + (1·0.5)²) = 1/2;
        close("n_0", one.light_count(false, p0), 1.0);
        check("one, light 0", one, (p0, 0.5, 0.5), (0.5, 0.5));
        // every light of `lights = "all"` expects all 4: (4·0.5)² / ((4·0.5)² + (1·0.5)²) = 4 / 4.25.
        let all = first(Strategy::Mis, LightSelection::All, 4, 1);
        check("all", all, (p1, 0.5, 0.5), (4.0 / 4.25, 0.25 / 4.25));
        // A material sample that reaches light 1 weighs against n_l P(1) p_l(ωi), the light's own pdf.
        let sun = Light::Distant(Distant::new(-Vec3::Z, Vec3::ONE, 0.2).unwrap());
        let p_li = sun.pdf_li(Vec3::ZERO, Vec3::Z);
        assert!(p_li > 0.0);
        let density = one.light_density(&sun, p1, Vec3::ZERO, Vec3::Z);
        close("p_l, one", density, 3.0 * p_li);
        let density = all.light_density(&sun, p1, Vec3::ZERO, Vec3::Z);
        close("p_l, all", density, 4.0 * p_li);
        // Deeper vertices choose one light for their one sample: n_j = P(j), so (0.75·2)² / ((0.75·2)² + 0.5²).
        let deeper = Mis::deeper_vertex(Strategy::Mis, false);
        close("n_1, deeper", deeper.light_count(false, p1), 0.75);
        check("deeper, light 1", deeper, (p1, 2.0, 0.5), (0.9, 0.1));
    }

    #[test]
    fn power_heuristic_edge_cases() {
        close("both zero", power_heuristic(0.0, 0.0), 0.0);
        close("other zero", power_heuristic(2.0, 0.0), 1.0);
        close("own zero", power_heuristic(0.0, 2.0), 0.0);
        close("own infinite", power_heuristic(f32::INFINITY, 2.0), 1.0);
        close("other infinite", power_heuristic(2.0, f32::INFINITY), 0.0);
        // Squares that overflow f32 fall back to 0, as two infinite densities would.
        close("both huge", power_heuristic(1e30, 1e30), 0.0);
    }
}

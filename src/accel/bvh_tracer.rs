//! The pure-Rust strand tracer: [`WideBvh`] traversal (the binned-SAH build collapsed to 4-wide nodes)
//! with the ray–curve tests of [`crate::accel::curves`], behind the [`Tracer`] trait, reproducing
//! [`crate::accel::embree::EmbreeTracer`] query for query.
//!
//! - **Closest hit**: [`WideBvh::closest`] with the round or flat segment test.
//! - **Transmittance**: every segment the walk reaches is offered ([`WideBvh::for_each`]); a segment whose strand
//!   is ignored, transparent (opacity 0) or already counted is skipped before its curve test, any other is tested
//!   over the whole `[tnear, tfar]`. The bookkeeping is Embree's filter's (`sys::embree::filter`): ∏ (1 − aᵢ) over
//!   distinct strands, at most [`SEEN_STRANDS`] remembered in a fixed array (one more distinct strand ends the ray
//!   dark), 0 once below [`TRANSMITTANCE_CUTOFF`]. Neither ending depends on traversal order, so the result is
//!   Embree's up to the rounding of the product.
//! - **Stochastic queries**: a strand absent for the ray's key ([`strand_present`]) or ignored is skipped before
//!   its curve test, which is what Embree's filter does after it (the decision is per strand, so the same hits
//!   survive).
//! - **Rays** are validated by [`Ray::check`] and a direction with a component ≥ [`MAX_ORIGIN`] is scaled down
//!   with its interval scaled up, hit distances divided back, exactly as the Embree queries do.
//!
//! Nothing is allocated per ray.

use std::time::Instant;

use super::bvh::wide::{Primitive, WideBvh};
use super::bvh::{BuildOptions, Control};
use super::curves::flat::RibbonRay;
use super::curves::{flat, round, CurveHit};
use super::{strand_present, CurveKind, Hit, Tracer};
use crate::hair::Strands;
use crate::ray::{InvalidRay, Ray, MAX_ORIGIN};
use crate::sys::embree::{SEEN_STRANDS, TRANSMITTANCE_CUTOFF};

/// Strands in a pure-Rust BVH, intersected as round tubes or flat ribbons. Queries may run from many threads.
#[derive(Debug, Clone)]
pub struct BvhTracer {
    bvh: WideBvh,
    kind: CurveKind,
    build_seconds: f64,
}

impl BvhTracer {
    /// Builds a BVH ([`BuildOptions::default`]) over `strands` (copied into its leaves), to intersect as curves of
    /// type `kind`.
    pub fn new(strands: &Strands, kind: CurveKind) -> Self {
        Self::with_options(strands, kind, BuildOptions::default())
    }

    /// [`BvhTracer::new`] with explicit build options.
    ///
    /// # Panics
    /// If `options` are out of range (see [`WideBvh::build`]).
    pub fn with_options(strands: &Strands, kind: CurveKind, options: BuildOptions) -> Self {
        let start = Instant::now();
        let bvh = WideBvh::build(strands, options);
        BvhTracer {
            bvh,
            kind,
            build_seconds: start.elapsed().as_secs_f64(),
        }
    }

    /// The curve type the strands are intersected as.
    pub fn kind(&self) -> CurveKind {
        self.kind
    }

    /// The hierarchy (for its size and statistics).
    pub fn bvh(&self) -> &WideBvh {
        &self.bvh
    }

    /// The query ray as the walk and the curve tests take it ([`traced_ray`]), with its ray space worked out once
    /// when the curves are flat ribbons.
    fn query(&self, ray: &Ray) -> Result<Query, InvalidRay> {
        let (ray, scale) = traced_ray(ray)?;
        let ribbon = match self.kind {
            CurveKind::Round => None,
            CurveKind::Flat => Some(RibbonRay::new(ray.origin, ray.dir)),
        };
        Ok(Query { ray, scale, ribbon })
    }

    /// The closest hit on a strand accepted by `accept(strand, opacity)`, with `t` in the caller's units.
    fn closest(
        &self,
        ray: &Ray,
        accept: impl Fn(u32, f32) -> bool,
    ) -> Result<Option<Hit>, InvalidRay> {
        let q = self.query(ray)?;
        let mut best = None;
        self.bvh.closest(&q.ray, |p, tfar| {
            if !accept(p.strand, p.opacity) {
                return None;
            }
            let hit = q.test(p, tfar)?;
            best = Some((p.segment, p.strand, hit));
            Some(hit.t)
        });
        Ok(best.map(|(segment, strand, h)| Hit {
            t: h.t / q.scale,
            segment,
            strand,
            u: h.u,
            v: h.v,
            ng: h.ng,
        }))
    }
}

/// A query's ray ([`BvhTracer::query`]): the traced ray, the factor its direction was scaled down by, and for
/// flat curves its ray space (`None`: round curves).
struct Query {
    ray: Ray,
    scale: f32,
    ribbon: Option<RibbonRay>,
}

impl Query {
    /// The ray–curve test of one leaf entry over `[ray.tnear, tfar]`.
    #[inline]
    fn test(&self, p: &Primitive, tfar: f32) -> Option<CurveHit> {
        let (r, cp) = (&self.ray, p.control_points);
        match &self.ribbon {
            None => round::intersect(r.origin, r.dir, r.tnear, tfar, cp),
            Some(ribbon) => flat::intersect_prepared(ribbon, r.tnear, tfar, cp),
        }
    }

    /// Whether the ray hits the leaf entry's curve in `[ray.tnear, tfar]` (the answer of [`Query::test`], found
    /// sooner: both searches end at the first hit).
    #[inline]
    fn occludes(&self, p: &Primitive, tfar: f32) -> bool {
        let (r, cp) = (&self.ray, p.control_points);
        match &self.ribbon {
            None => round::occludes(r.origin, r.dir, r.tnear, tfar, cp),
            Some(ribbon) => flat::occludes_prepared(ribbon, r.tnear, tfar, cp),
        }
    }
}

/// The ray as Embree traces it (`sys::embree::query`'s `embree_ray`): validated, and a direction with a component
/// ≥ [`MAX_ORIGIN`] scaled down by its largest component, the interval scaled up by the same factor (returned), so
/// that the same points are traced.
fn traced_ray(ray: &Ray) -> Result<(Ray, f32), InvalidRay> {
    ray.check()?;
    let longest = ray.dir.abs().max_element();
    if longest >= MAX_ORIGIN {
        let scaled = Ray::segment(
            ray.origin,
            ray.dir / longest,
            ray.tnear * longest,
            ray.tfar * longest,
        );
        Ok((scaled, longest))
    } else {
        Ok((*ray, 1.0))
    }
}

/// Strand id that no strand has (Embree's `RTC_INVALID_GEOMETRY_ID`, as the filter uses it).
const NO_STRAND: u32 = u32::MAX;

/// The transmittance bookkeeping of Embree's filter (`TransmittanceQuery::on_hit`) on a fixed array.
struct Seen {
    ignore_strand: u32,
    transmittance: f32,
    len: usize,
    strands: [u32; SEEN_STRANDS],
}

impl Seen {
    fn new(ignore_strand: Option<u32>) -> Self {
        Seen {
            ignore_strand: ignore_strand.unwrap_or(NO_STRAND),
            transmittance: 1.0,
            len: 0,
            strands: [NO_STRAND; SEEN_STRANDS],
        }
    }

    /// Whether a hit on `strand` of `opacity` would change nothing (transparent, ignored or already counted): then
    /// its curve test can be skipped.
    fn skips(&self, strand: u32, opacity: f32) -> bool {
        opacity == 0.0 || strand == self.ignore_strand || self.strands[..self.len].contains(&strand)
    }

    /// Adds `strand` to the strands seen (the caller has checked there is room).
    fn remember(&mut self, strand: u32) {
        self.strands[self.len] = strand;
        self.len += 1;
    }

    /// Counts a hit on a strand not skipped: transmittance ×= 1 − opacity; stops dark below the cutoff or when
    /// the list is full.
    fn count(&mut self, strand: u32, opacity: f32) -> Control {
        if self.len == SEEN_STRANDS {
            self.transmittance = 0.0;
            return Control::Stop;
        }
        self.remember(strand);
        self.transmittance *= 1.0 - opacity;
        if self.transmittance < TRANSMITTANCE_CUTOFF {
            self.transmittance = 0.0;
            return Control::Stop;
        }
        Control::Continue
    }
}

impl Tracer for BvhTracer {
    /// Wall time to build the BVH and fill its leaves, in seconds.
    fn build_seconds(&self) -> f64 {
        self.build_seconds
    }

    /// The hierarchy: nodes and leaf entries, which hold the tracer's copy of the curves.
    fn memory_bytes(&self) -> usize {
        self.bvh.bytes()
    }

    fn intersect(&self, ray: &Ray) -> Result<Option<Hit>, InvalidRay> {
        self.closest(ray, |_, _| true)
    }

    fn transmittance(&self, ray: &Ray, ignore_strand: Option<u32>) -> Result<f32, InvalidRay> {
        let q = self.query(ray)?;
        let mut seen = Seen::new(ignore_strand);
        self.bvh.for_each_unordered(&q.ray, |p, tfar| {
            if seen.skips(p.strand, p.opacity) || !q.occludes(p, tfar) {
                return Control::Continue;
            }
            seen.count(p.strand, p.opacity)
        });
        Ok(seen.transmittance)
    }

    fn strands_crossed(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        limit: u32,
    ) -> Result<u32, InvalidRay> {
        let limit = limit.clamp(1, SEEN_STRANDS as u32) as usize;
        let q = self.query(ray)?;
        let mut seen = Seen::new(ignore_strand);
        self.bvh.for_each_unordered(&q.ray, |p, tfar| {
            if seen.skips(p.strand, p.opacity) || !q.occludes(p, tfar) {
                return Control::Continue;
            }
            seen.remember(p.strand);
            if seen.len >= limit {
                Control::Stop
            } else {
                Control::Continue
            }
        });
        Ok(seen.len.min(limit) as u32)
    }

    fn intersect_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<Option<Hit>, InvalidRay> {
        self.closest(ray, |strand, opacity| {
            Some(strand) != ignore_strand && strand_present(key, strand, opacity)
        })
    }

    fn occluded_stochastic(
        &self,
        ray: &Ray,
        ignore_strand: Option<u32>,
        key: u64,
    ) -> Result<bool, InvalidRay> {
        let q = self.query(ray)?;
        Ok(self.bvh.for_each(&q.ray, |p, tfar| {
            let present =
                Some(p.strand) != ignore_strand && strand_present(key, p.strand, p.opacity);
            if present && q.occludes(p, tfar) {
                Control::Stop
            } else {
                Control::Continue
            }
        }))
    }
}

#[cfg(test)]
mod tests {

    use glam::Vec3;

    use super::*;
    use crate::accel::embree::EmbreeTracer;
    use crate::accel::testing::random_bundle;

    /// Primary rays on the random bundle (each hit also spawns a secondary ray).
    const RAYS: usize = 10_000;

    /// Primary rays on the real models: 10⁵.
    const FILE_RAYS: usize = 100_000;

    /// Fraction of rays on which the backends must agree, per query.
    const AGREEMENT: f64 = 0.999;

    /// Relative tolerance on the hit distance.
    const T_TOLERANCE: f32 = 1e-3;

    /// Largest fraction of secondary rays (no strand ignored) on which the backends disagree and one of them hits
    /// the strand the ray starts on (measured: 37 % on the bundle, 35 % on straight.hair, round; 0 flat).
    const SELF_HIT_FRACTION: f64 = 0.45;

    /// Absolute tolerance on transmittance.
    const TRANSMITTANCE_TOLERANCE: f32 = 1e-4;

    /// A hair model of the test data ([`crate::util::test_data`]), strands of opacity ½.
    fn hair_file(name: &str) -> Strands {
        let mut strands = crate::accel::testing::hair_file(name);
        strands.set_opacity(0.5);
        strands
    }

    /// Agreement counts of one query, and the worst disagreement seen.
    struct Tally {
        query: &'static str,
        rays: usize,
        agree: usize,
        worst: String,
        worst_score: f64,
        /// Secondary rays on which the backends disagree and one hits the strand the ray starts on (not in `rays`).
        self_hits: usize,
        /// Disagreements at the silhouette ([`grazing`]; counted for the hit queries only).
        grazing: usize,
    }

    impl Tally {
        fn new(query: &'static str) -> Self {
            Tally {
                query,
                rays: 0,
                agree: 0,
                worst: String::from("none"),
                worst_score: 0.0,
                self_hits: 0,
                grazing: 0,
            }
        }

        /// Records one ray: `score` 0 is perfect agreement, ≤ 1 within tolerance.
        fn add(&mut self, score: f64, what: impl FnOnce() -> String) {
            self.rays += 1;
            if score <= 1.0 {
                self.agree += 1;
            }
            if score > self.worst_score {
                self.worst_score = score;
                self.worst = what();
            }
        }

        fn check(&self, case: &str) {
            let fraction = self.agree as f64 / self.rays as f64;
            if self.self_hits > 0 {
                let all = self.rays + self.self_hits;
                let self_fraction = self.self_hits as f64 / all as f64;
                assert!(
                    self_fraction <= SELF_HIT_FRACTION,
                    "{case} {}: {}/{all} rays disagree with a hit on their own strand",
                    self.query,
                    self.self_hits
                );
            }
            assert!(
                fraction >= AGREEMENT,
                "{case} {}: only {}/{} rays agree with embree ({} disagreements at the silhouette); worst: {}",
                self.query,
                self.agree,
                self.rays,
                self.grazing,
                self.worst
            );
        }
    }

    /// Closest hits agree: both miss, or the same strand at |Δt| ≤ [`T_TOLERANCE`]·t (score: the ratio to that
    /// bound, or ∞ for a different strand or a hit against a miss).
    fn hit_score(a: Option<Hit>, b: Option<Hit>) -> f64 {
        match (a, b) {
            (None, None) => 0.0,
            (Some(a), Some(b)) if a.strand == b.strand => {
                let bound = T_TOLERANCE * a.t.abs().max(b.t.abs());
                let dt = (a.t - b.t).abs();
                if dt == 0.0 {
                    0.0
                } else {
                    f64::from(dt) / f64::from(bound).max(f64::MIN_POSITIVE)
                }
            }
            _ => f64::INFINITY,
        }
    }

    /// Both backends' answers to the four queries for one ray.
    struct Outcome {
        ray: Ray,
        ignore: Option<u32>,
        key: u64,
        intersect: (Option<Hit>, Option<Hit>),
        transmittance: (f32, f32),
        stochastic: (Option<Hit>, Option<Hit>),
        occluded: (bool, bool),
        crossed: (u32, u32),
    }

    fn outcome(
        embree: &EmbreeTracer,
        bvh: &BvhTracer,
        ray: Ray,
        ignore: Option<u32>,
        key: u64,
    ) -> Outcome {
        Outcome {
            ray,
            ignore,
            key,
            intersect: (
                embree.intersect(&ray).unwrap(),
                bvh.intersect(&ray).unwrap(),
            ),
            transmittance: (
                embree.transmittance(&ray, ignore).unwrap(),
                bvh.transmittance(&ray, ignore).unwrap(),
            ),
            stochastic: (
                embree.intersect_stochastic(&ray, ignore, key).unwrap(),
                bvh.intersect_stochastic(&ray, ignore, key).unwrap(),
            ),
            occluded: (
                embree.occluded_stochastic(&ray, ignore, key).unwrap(),
                bvh.occluded_stochastic(&ray, ignore, key).unwrap(),
            ),
            crossed: (
                embree.strands_crossed(&ray, ignore, 64).unwrap(),
                bvh.strands_crossed(&ray, ignore, 64).unwrap(),
            ),
        }
    }

    /// Whether a hit lies at the strand's silhouette, where the two intersectors' roundings decide hit or miss:
    /// on a round tube, the ray within ~6° of the tangent plane (|cos| < 0.1 between the ray and the outward
    /// normal); on a flat ribbon, within 1 % of its width from an edge (|v| > 0.98).
    fn grazing(kind: CurveKind, ray: &Ray, hit: Option<Hit>) -> bool {
        hit.is_some_and(|h| match kind {
            CurveKind::Round => ray.dir.normalize().dot(h.ng.normalize()).abs() < 0.1,
            CurveKind::Flat => h.v.abs() > 0.98,
        })
    }

    /// Tallies the outcomes of one set of rays, query by query.
    fn tally(case: &str, kind: CurveKind, outcomes: &[Outcome]) {
        let names = [
            "intersect",
            "transmittance",
            "intersect_stochastic",
            "occluded_stochastic",
            "strands_crossed",
        ];
        let mut t = names.map(Tally::new);
        for o in outcomes {
            let (ray, ignore, key) = (&o.ray, o.ignore, o.key);
            let (e, b) = o.intersect;
            let score = hit_score(e, b);
            // A secondary ray starting on its strand: whether and where the round tube it starts on is hit again
            // (leaving it at t ≈ 0, or a short chord through it) is decided differently by Embree and
            // `curves::round`, the origin lying on the surface only up to rounding. Counted apart.
            let own = |h: Option<Hit>| h.is_some_and(|h| Some(h.strand) == ignore);
            if score > 1.0 && (own(e) || own(b)) {
                t[0].self_hits += 1;
            } else {
                if score > 1.0 && (grazing(kind, ray, e) || grazing(kind, ray, b)) {
                    t[0].grazing += 1;
                }
                t[0].add(score, || format!("{ray:?}: embree {e:?}, bvh {b:?}"));
            }
            let (e, b) = o.transmittance;
            let score = f64::from((e - b).abs() / TRANSMITTANCE_TOLERANCE);
            t[1].add(score, || {
                format!("{ray:?} ignore {ignore:?}: embree {e}, bvh {b}")
            });
            let (e, b) = o.stochastic;
            let score = hit_score(e, b);
            if score > 1.0 && (grazing(kind, ray, e) || grazing(kind, ray, b)) {
                t[2].grazing += 1;
            }
            t[2].add(score, || {
                format!("{ray:?} ignore {ignore:?} key {key}: embree {e:?}, bvh {b:?}")
            });
            let (e, b) = o.occluded;
            t[3].add(if e == b { 0.0 } else { f64::INFINITY }, || {
                format!("{ray:?} ignore {ignore:?} key {key}: embree {e}, bvh {b}")
            });
            let (e, b) = o.crossed;
            t[4].add(if e == b { 0.0 } else { f64::INFINITY }, || {
                format!("{ray:?} ignore {ignore:?}: embree {e} strands, bvh {b}")
            });
        }
        for tally in &t {
            tally.check(case);
        }
    }

    /// `rays` rays from outside the model's box towards points inside it, and a secondary ray from each Embree
    /// hit (tnear 0, uniform direction, the hit strand ignored where the query takes one), compared query by
    /// query. Rays are made from hashes of their index, traced in parallel, tallied in order.
    fn agree_with_embree(case: &str, strands: &Strands, kind: CurveKind, rays: usize) {
        use crate::util::hash::{hash64, unit_f32};
        use crate::util::sampling::uniform_sphere;
        use rayon::prelude::*;
        let embree = EmbreeTracer::new(strands, kind).expect("embree scene");
        let bvh = BvhTracer::new(strands, kind);
        let (lo, hi) = strands.bounds();
        let (centre, size) = (0.5 * (lo + hi), hi - lo);
        let (primary, secondary): (Vec<Outcome>, Vec<Option<Outcome>>) = (0..rays)
            .into_par_iter()
            .map(|i| {
                let mut state = hash64(i as u64 ^ 0x00a9_2ee3);
                let mut u = || {
                    state = hash64(state);
                    unit_f32(state)
                };
                let target = lo + size * Vec3::new(u(), u(), u());
                let away = uniform_sphere(u(), u());
                let origin = centre + 1.5 * size.length() * away;
                let ray = Ray::new(origin, target - origin);
                let key = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
                let first = outcome(&embree, &bvh, ray, None, key);
                let second = first.intersect.0.map(|hit| {
                    let ray = Ray::new(ray.at(hit.t), uniform_sphere(u(), u()));
                    outcome(&embree, &bvh, ray, Some(hit.strand), key ^ 1)
                });
                (first, second)
            })
            .unzip();
        let secondary: Vec<Outcome> = secondary.into_iter().flatten().collect();
        assert!(
            secondary.len() > rays / 10,
            "{case}: only {} of {rays} rays hit (a vacuous test)",
            secondary.len()
        );
        tally(&format!("{case} primary"), kind, &primary);
        tally(&format!("{case} secondary"), kind, &secondary);
    }

    #[test]
    fn random_bundle_round_agrees_with_embree() {
        agree_with_embree(
            "bundle round",
            &random_bundle(300, 16, 5),
            CurveKind::Round,
            RAYS,
        );
    }

    #[test]
    fn random_bundle_flat_agrees_with_embree() {
        agree_with_embree(
            "bundle flat",
            &random_bundle(300, 16, 5),
            CurveKind::Flat,
            RAYS,
        );
    }

    #[test]
    fn straight_hair_round_agrees_with_embree() {
        agree_with_embree(
            "straight.hair round",
            &hair_file("straight.hair"),
            CurveKind::Round,
            FILE_RAYS,
        );
    }

    #[test]
    fn straight_hair_flat_agrees_with_embree() {
        agree_with_embree(
            "straight.hair flat",
            &hair_file("straight.hair"),
            CurveKind::Flat,
            FILE_RAYS,
        );
    }

    #[test]
    fn furball_round_agrees_with_embree() {
        agree_with_embree(
            "furball round",
            &hair_file("furball.hair"),
            CurveKind::Round,
            FILE_RAYS,
        );
    }

    #[test]
    fn furball_flat_agrees_with_embree() {
        agree_with_embree(
            "furball flat",
            &hair_file("furball.hair"),
            CurveKind::Flat,
            FILE_RAYS,
        );
    }

    /// A model from polylines of (point, radius).
    fn model(strands: &[Vec<(Vec3, f32)>]) -> Strands {
        let mut m = crate::hair::HairModel {
            strand_offsets: vec![0],
            ..Default::default()
        };
        for strand in strands {
            for &(p, r) in strand {
                m.points.push(p);
                m.radius.push(r);
                m.transparency.push(0.5);
                m.color.push([0.5; 3]);
            }
            m.strand_offsets.push(m.points.len() as u32);
        }
        Strands::from_model(&m)
    }

    #[test]
    fn degenerate_models_build_and_trace_without_panic_or_nan() {
        fn line(n: usize, r: impl Fn(f32) -> f32) -> Vec<(Vec3, f32)> {
            (0..n)
                .map(|i| {
                    let s = i as f32 / (n - 1).max(1) as f32;
                    (Vec3::new(0.1 * s, s, 0.05 * s * s), r(s))
                })
                .collect()
        }
        let origin = Vec3::new(0.02, 0.5, 0.0);
        let cases: Vec<(&str, Strands)> = vec![
            ("empty model", Strands::default()),
            ("single two-point strand", model(&[line(2, |_| 0.02)])),
            (
                "zero radius at the tip",
                model(&[line(8, |s| 0.02 * (1.0 - s))]),
            ),
            ("zero radius everywhere", model(&[line(8, |_| 0.0)])),
            ("all points coincident", model(&[vec![(origin, 0.02); 6]])),
            (
                "repeated points inside a strand",
                model(&[line(4, |_| 0.02)
                    .into_iter()
                    .flat_map(|p| [p, p, p])
                    .collect()]),
            ),
            (
                "coincident strands",
                model(&[line(5, |_| 0.02), line(5, |_| 0.02), line(5, |_| 0.02)]),
            ),
        ];
        for (what, strands) in &cases {
            for kind in [CurveKind::Round, CurveKind::Flat] {
                let bvh = BvhTracer::new(strands, kind);
                let embree = EmbreeTracer::new(strands, kind).expect("embree scene");
                let mut disagree = 0u64;
                let mut hits = 0u64;
                let rays = 2000u64;
                for i in 0..rays {
                    let u =
                        |k: u64| crate::util::hash::unit_f32(crate::util::hash::hash64(i * 8 + k));
                    let target =
                        Vec3::new(0.15 * u(0) - 0.02, 1.1 * u(1) - 0.05, 0.1 * u(2) - 0.03);
                    let from = crate::util::sampling::uniform_sphere(u(3), u(4)) * 3.0;
                    let ray = Ray::new(from, target - from);
                    let hit = bvh.intersect(&ray).unwrap();
                    if let Some(h) = hit {
                        hits += 1;
                        assert!(
                            h.t.is_finite()
                                && h.u.is_finite()
                                && h.v.is_finite()
                                && h.ng.is_finite(),
                            "{what} {kind:?}: {h:?}"
                        );
                        assert!((0.0..=1.0).contains(&h.u), "{what} {kind:?}: {h:?}");
                    }
                    disagree +=
                        u64::from(hit.is_some() != embree.intersect(&ray).unwrap().is_some());
                    let t = bvh.transmittance(&ray, None).unwrap();
                    assert!(
                        (0.0..=1.0).contains(&t),
                        "{what} {kind:?}: transmittance {t}"
                    );
                    let _ = bvh.intersect_stochastic(&ray, Some(0), i).unwrap();
                    let _ = bvh.occluded_stochastic(&ray, None, i).unwrap();
                }
                if *what == "single two-point strand" || *what == "zero radius at the tip" {
                    // Well-formed curves: the two backends agree here as on real hair.
                    assert!(hits > rays / 50, "{what} {kind:?}: only {hits} hits");
                    assert!(
                        disagree <= rays / 500,
                        "{what} {kind:?}: {disagree} disagreements"
                    );
                }
            }
        }
    }

    #[test]
    fn rejects_the_rays_embree_rejects() {
        let strands = random_bundle(10, 4, 1);
        let bvh = BvhTracer::new(&strands, CurveKind::Round);
        let embree = EmbreeTracer::new(&strands, CurveKind::Round).expect("embree scene");
        let bad = [
            Ray::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X),
            Ray::new(Vec3::new(2e19, 0.0, 0.0), Vec3::X),
            Ray::new(Vec3::ZERO, Vec3::ZERO),
            Ray::segment(Vec3::ZERO, Vec3::X, -1.0, 1.0),
            Ray::segment(Vec3::ZERO, Vec3::X, 2.0, 1.0),
        ];
        for ray in bad {
            let expected = embree.intersect(&ray).unwrap_err();
            assert_eq!(bvh.intersect(&ray), Err(expected), "{ray:?}");
            assert_eq!(bvh.transmittance(&ray, None), Err(expected), "{ray:?}");
            assert_eq!(
                bvh.intersect_stochastic(&ray, None, 1),
                Err(expected),
                "{ray:?}"
            );
            assert_eq!(
                bvh.occluded_stochastic(&ray, None, 1),
                Err(expected),
                "{ray:?}"
            );
        }
    }

    #[test]
    fn huge_directions_are_traced_like_embree() {
        let strands = random_bundle(50, 8, 2);
        let bvh = BvhTracer::new(&strands, CurveKind::Round);
        let embree = EmbreeTracer::new(&strands, CurveKind::Round).expect("embree scene");
        let ray = Ray::new(Vec3::new(-5.0, 0.01, 0.02), Vec3::new(1e19, 0.0, 0.0));
        let (e, b) = (
            embree.intersect(&ray).unwrap(),
            bvh.intersect(&ray).unwrap(),
        );
        assert!(hit_score(e, b) <= 1.0, "embree {e:?}, bvh {b:?}");
    }

    #[test]
    fn seen_list_ends_dark_when_full() {
        let mut seen = Seen::new(Some(7));
        assert!(seen.skips(7, 0.5), "ignored");
        assert!(seen.skips(3, 0.0), "transparent");
        for s in 0..SEEN_STRANDS as u32 {
            assert!(!seen.skips(s + 100, 1e-6));
            assert_eq!(seen.count(s + 100, 1e-6), Control::Continue);
        }
        assert!(seen.skips(100, 1e-6), "already counted");
        assert!(seen.transmittance > 0.99);
        assert_eq!(seen.count(999, 1e-6), Control::Stop);
        assert_eq!(seen.transmittance, 0.0);
    }
}

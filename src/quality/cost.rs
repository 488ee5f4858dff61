//! A deterministic cost model: the predicted CPU time of a render from its ray counts, so that auto can compare
//! configurations by what they cost without reading the clock (its decisions stay the same for any thread count
//! and load).
//!
//! Rays of different kinds cost different amounts: a camera ray that misses the hair is cheap, a shadow ray with
//! exact transmittance traverses the whole fur, and every light or material sample at a vertex also evaluates the
//! BSDF and the MIS densities. Counting rays alone made a (1 light, 4 material) candidate look 1.3× as costly as
//! (1, 1) per camera sample on the default scene where it measured 1.4–1.8× (`docs/study/auto/README.md`), and
//! auto picked it. The weights here are seconds per ray of each kind, *including* the shading work that comes
//! with the ray, fitted by least squares to the CPU time of the pixel loop (one thread) over 4 ray-count
//! regressors; see [`WEIGHTS`] for the measurement.

use crate::render::integrator::RayCounts;

/// Seconds per ray (or map lookup) of each kind, shading included (the type lives with the ray counts it weighs).
pub use crate::render::integrator::RayCost as CostWeights;

/// The weights auto uses. Measured on this machine class (2-core AMD EPYC VM, x86-64-v3 release build, one thread, the
/// machine loaded by other work: read them as ratios, camera 1 : shadow 3.6 : material 3.7 : lookup 1.8) by `cargo test
/// --release --test quality calibrate_cost_model -- --ignored --nocapture`: the CPU time of the pixel loop of the
/// default scene at 128², 4 spp (the test renders at 16 since, below), round and flat curves × ray-traced and
/// deep-opacity shadows × path length 0–3 × the four light/material candidates (81 renders of 0.1–0.8 s), fitted by
/// least squares over the four ray counts; the fit is within −16 % and +42 % of every render, within ±20 % of 72 of
/// them (the CSV is `docs/study/auto/cost-calibration.csv`). Round curves cost ~15 % more per ray than flat; one set of
/// weights serves both, as the candidates compared are always on the same curves.
///
/// Refitted and not adopted (4 Dec 2026): the same test at 16 spp on an idle machine over all four of its scenes, timed
/// by the nanosecond CPU clock (`docs/study/auto/cost-calibration-16spp.csv`, 256 renders of 0.16–2.1 CPU s), fitted
/// with one cost level per scene and curves (decisions compare candidates within a frame, so only the weights' ratios
/// matter): these weights leave a relative RMS residual of 0.166, a refit of the four 0.152 (camera 1 : shadow 3.7 :
/// material 2.6 : lookup 1.5), and a fifth weight for the rays traced after the first vertex (which start inside the
/// hair: callgrind puts straight hair's path-3 frame under the city map at +9.4 % of its path-1 frame's instructions,
/// and its path 2 under the sunset map at +7.0 %, where these weights predict +6.5 % and +4.7 %) 0.125. But single
/// renders scatter by ±5 % (the sunset scene's flat path 1/2/3 at 0.459/0.437/0.432 CPU s for rising ray counts), and
/// the residuals by path length within a scene and curves — what the path-length decision reads — are no flatter with
/// either refit (sunset flat paths 1 → 2: −0.021 → +0.074 here, −0.014 → +0.081 refitted, +0.010 → +0.128 with the
/// fifth weight).
///
/// **`deep`, added 5 Dec 2026** (session 30): what a ray costs depends on the vertex it leaves. Callgrind instruction
/// counts — deterministic, free of the clock's ±5 % — of a frame at path length 1 and one at 2
/// (`scripts/deep-ray-cost.sh SCENE`: flat, ray-traced, one thread, 64², 16 spp; the default scene and fur ball at 8)
/// put a vertex at bounce 2 at 1.27× (default scene), 1.60× (fur ball), 1.39× (straight hair under the city map, 128²,
/// 20 spp), 1.45× (sunset, 128²; 1.42 at 64²), 1.41× (interior) and 1.42× (studio) the instructions of one at bounce 1,
/// while a bounce-1 vertex's two rays cost what two first-vertex rays do (city: 8.6 k instructions a ray at bounce 1,
/// 8.7 k for a first-vertex light sample; 11.9 k at bounce 2): rays from the third vertex on start deep in the hair and
/// traverse more of it. Per ray the four weights above charge every shadow and material ray alike, so they priced a
/// longer path ~3 % under its instructions on straight hair under the city map (path 3 over path 1: +6.5 % predicted,
/// +9.4 % measured), and the path-length decision, whose candidates there are within 1–6 % of each other, leaned to
/// longer paths (auto's path was longer than that of the fastest fixed configuration meeting the target on 9 of 14 rows
/// in the twenty-first study run, shorter on none). `deep` adds 0.41 × the mean shadow/material weight (the hair
/// scenes' median excess, 1.4e-6 s) to every shadow and material ray traced at bounce 2 or later ([`RayCounts::deep`]).
/// It is the instructions' excess; by the clock the excess is larger (path 3 over path 1 +11.8 % by CPU time where the
/// instructions say +9.4 %, cache misses deep in the fur), so this is the smaller of the two corrections. The Cornell
/// box's bounce-2 vertex costs 2.59× its bounce-1 one (there bounce 1 mostly lands on the walls, whose rays are cheap):
/// the model stays coarse for scenes whose vertices change from walls to hair with depth.
///
/// [`RayCounts::deep`]: crate::render::integrator::RayCounts::deep
pub const WEIGHTS: CostWeights = CostWeights {
    camera: 0.92e-6,
    shadow: 3.34e-6,
    material: 3.42e-6,
    map_lookup: 1.66e-6,
    deep: 1.4e-6,
};

/// The inverse efficiency of a sampling configuration: the relative MSE of one estimate times its predicted cost
/// (the cost of reaching a given noise, as the noise falls as 1 / cost). Smaller is better.
pub fn inverse_efficiency(rel_mse: f64, rays: &RayCounts, weights: &CostWeights) -> f64 {
    rel_mse * weights.seconds(rays)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts(camera: u64, shadow: u64, material: u64) -> RayCounts {
        RayCounts {
            camera,
            shadow,
            material,
            ..RayCounts::default()
        }
    }

    #[test]
    fn a_four_sample_candidate_at_equal_rel_mse_times_rays_ranks_below_one_sample_when_its_rays_cost_more(
    ) {
        // The default scene's rays at path 3, 4 spp, 128² (docs/study/auto/cost-calibration.csv): (1 light,
        // 1 material) and (1, 4). The extra rays of (1, 4) are material rays, which cost more than the camera rays
        // that make up half of (1, 1)'s. Its relMSE is set so that relMSE × rays ties (as the default scene's
        // pilots nearly did: 2.45e-2 × 7608 against 1.88e-2 × 9862), which counting rays broke towards (1, 4).
        let one = counts(81920, 55658, 35581);
        let four = counts(81920, 55686, 95840);
        let e1 = 2.45e-2;
        let e4 = e1 * one.total() as f64 / four.total() as f64;
        let (c1, c4) = (
            inverse_efficiency(e1, &one, &WEIGHTS),
            inverse_efficiency(e4, &four, &WEIGHTS),
        );
        assert!(c4 > 1.05 * c1, "(1, 4) {c4:.3e} against (1, 1) {c1:.3e}");
        // With every kind weighted alike the model is relMSE × rays again, and the two tie.
        let alike = CostWeights {
            camera: 1.0,
            shadow: 1.0,
            material: 1.0,
            map_lookup: 1.0,
            deep: 0.0,
        };
        let (a1, a4) = (
            inverse_efficiency(e1, &one, &alike),
            inverse_efficiency(e4, &four, &alike),
        );
        assert!((a1 - a4).abs() < 1e-9 * a1, "{a1} {a4}");
    }

    #[test]
    fn the_deep_weight_prices_a_longer_path_as_its_instructions() {
        // Callgrind, one thread, flat curves, ray-traced shadows, render_tiles' instructions:
        // straight hair under the city map at 128², 20 spp, path 1 against path 3 (2 771 M against 3 031 M), and
        // under the sunset map at 16 spp, path 1 against path 2 (2 193 M against 2 347 M). Their rays: the longer
        // frame adds only vertices at bounce 2 and later (the paths agree up to bounce 1), so its extra shadow and
        // material rays are all deep. Without the deep weight the ratio came out 2.6 % (city) and 2.2 % (sunset)
        // low, the error that leaned the path-length choice long.
        let frame = |camera: u64, each: u64, deep: u64| RayCounts {
            camera,
            shadow: each,
            material: each,
            deep,
            ..RayCounts::default()
        };
        let cases = [
            (
                "city, path 3 / path 1",
                frame(327_680, 115_252, 0),
                frame(327_680, 125_737, 20_970),
                3031.0 / 2771.0,
            ),
            (
                "sunset, path 2 / path 1",
                frame(262_144, 92_212, 0),
                frame(262_144, 98_248, 12_072),
                2347.3 / 2193.0,
            ),
        ];
        let flat = CostWeights {
            deep: 0.0,
            ..WEIGHTS
        };
        for (name, short, long, measured) in cases {
            let ratio = |w: &CostWeights| w.seconds(&long) / w.seconds(&short);
            let (with, without) = (ratio(&WEIGHTS), ratio(&flat));
            assert!(
                (with / measured - 1.0).abs() < 0.01,
                "{name}: {with} against {measured}"
            );
            assert!(
                without / measured - 1.0 < -0.02,
                "{name}: {without} against {measured}"
            );
        }
    }

    #[test]
    fn the_weights_predict_the_measured_cpu_time_of_each_candidate_on_the_default_scene() {
        // docs/study/auto/cost-calibration.csv, flat, ray-traced shadows, path 2, 4 spp at 128²: (1, 1) 0.37 s
        // CPU, (1, 4) 0.49 s, (4, 1) 0.57 s, (4, 4) 0.71 s.
        let measured = [
            (counts(81920, 54613, 34536), 0.37),
            (counts(81920, 54629, 94783), 0.49),
            (counts(81920, 114844, 34536), 0.57),
            (counts(81920, 114860, 94783), 0.71),
        ];
        for (rays, seconds) in measured {
            let predicted = WEIGHTS.seconds(&rays);
            assert!(
                (predicted / seconds - 1.0).abs() < 0.25,
                "{rays:?}: predicted {predicted:.3} s, measured {seconds} s"
            );
        }
    }
}

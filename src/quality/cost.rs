//! A deterministic cost model: the predicted CPU time of a render from its ray counts, so that auto can compare
//! configurations by what they cost without reading the clock (its decisions stay the same for any thread count
//! and load).
//!
//! Rays of different kinds cost different amounts: a camera ray that misses the hair is cheap, a shadow ray with
//! exact transmittance traverses the whole fur, and every light or material sample at a vertex also evaluates the
//! BSDF and the MIS densities. Counting rays alone makes a (1 light, 4 material) candidate look 1.3× as costly as
//! (1, 1) per camera sample on the default scene, where it measures 1.4–1.8× (`docs/measured/auto.md`), and
//! auto would pick it. The weights here are seconds per ray of each kind, *including* the shading work that comes
//! with the ray, fitted by least squares to the CPU time of the pixel loop (one thread) over 4 ray-count
//! regressors; see [`WEIGHTS`] for the measurement.

use crate::render::integrator::RayCounts;

/// Seconds per ray (or map lookup) of each kind, shading included (the type lives with the ray counts it weighs).
pub use crate::render::integrator::RayCost as CostWeights;

/// The weights auto uses, seconds per ray with its shading: `camera`, `shadow`, `material`, `map_lookup` (one
/// deep-opacity-map lookup), and `deep`, added to each shadow and material ray traced at bounce 2 or later
/// ([`RayCounts::deep`](crate::render::integrator::RayCounts::deep)). The first four are a least-squares fit to the
/// one-thread CPU time of the default scene's pixel loop at 128², 4 spp, over round and flat curves × ray-traced and
/// map shadows × path length 0–3 × the four light/material candidates (81 renders,
/// `docs/measured/study/auto/cost-calibration.csv`); read them as ratios, 1 : 3.6 : 3.7 : 1.8.
/// `deep` is 0.41 × the mean shadow/material weight: the median excess, in callgrind instructions, of a bounce-2
/// vertex's rays over a bounce-1 vertex's on the hair scenes (`scripts/deep-ray-cost.sh SCENE`).
/// `counted` (per strand-counting query of dual scattering, its dual shading included) and `crossed` (per strand
/// it counted): least squares over four one-thread renders, 8 spp, blond Chiang, path length 0 against dual and
/// dual-published on `scenes/default.toml` at 128² and `scenes/study/straight-city.toml` at 96×128, each
/// render's time less the path-0 render's plus its shadow rays at `shadow`'s weight (7 Dec 2026, the code of
/// commit 597d91c, another study on the second core): 6.7 µs and 0.65 µs, the four renders within 15 %. Tuned on
/// those two shipped scenes.
pub const WEIGHTS: CostWeights = CostWeights {
    camera: 0.92e-6,
    shadow: 3.34e-6,
    material: 3.42e-6,
    map_lookup: 1.66e-6,
    deep: 1.4e-6,
    counted: 6.7e-6,
    crossed: 0.65e-6,
};

/// How many times a ribbon's the cost model's weights take a round tube's rays to cost: the weights were fitted
/// on both kinds alike, and a tube's intersection costs more. One-thread render times of round over flat curves at
/// 128², 16 spp, path 3, ray-traced shadows (the same rays within 0.5 %): 1.13 on `scenes/default.toml`, 1.69 on
/// `scenes/furball.toml`, 1.40 on `scenes/thesis/straight-city-marschner.toml` (6 Dec 2026, commit cc24cb3); the
/// middle one. Tuned on those three shipped scenes, judged on the generated set.
pub const ROUND_CURVE_COST: f64 = 1.4;

/// CPU seconds of building one deep opacity map per texel and layer, and per curve segment rasterised.
/// One-thread build times (`render --threads 1`, the time the summary prints) of the fur ball's sun map
/// (`scenes/furball-shadows.toml`, 455 505 segments, 16 layers) at 256², 512², 1024², 2048²: 0.224, 0.450, 1.209,
/// 4.621 s. The fit t = 0.154 s + 1.065 µs × texels (16 layers) gives 0.224, 0.433, 1.27, 4.62 s. 6 Dec 2026, commit
/// 0b1a2c3; tuned on that shipped scene.
pub const MAP_SECONDS_PER_TEXEL_LAYER: f64 = 6.66e-8;
/// See [`MAP_SECONDS_PER_TEXEL_LAYER`]: 0.154 s over 455 505 segments.
pub const MAP_SECONDS_PER_SEGMENT: f64 = 3.4e-7;

/// Predicted CPU seconds of building one deep opacity map of `resolution`² texels and `layers` layers over
/// `segments` curve segments.
pub fn map_build_seconds(resolution: u32, layers: u32, segments: usize) -> f64 {
    let texels = f64::from(resolution) * f64::from(resolution);
    MAP_SECONDS_PER_TEXEL_LAYER * texels * f64::from(layers)
        + MAP_SECONDS_PER_SEGMENT * segments as f64
}

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
        // The default scene's rays at path 3, 4 spp, 128² (docs/measured/study/auto/cost-calibration.csv): (1 light,
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
            counted: 1.0,
            crossed: 0.0,
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
        // material rays are all deep. Without the deep weight the ratio comes out 2.6 % (city) and 2.2 % (sunset)
        // low, an error that leans the path-length choice long.
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
        // docs/measured/study/auto/cost-calibration.csv, flat, ray-traced shadows, path 2, 4 spp at 128²: (1, 1) 0.37 s
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

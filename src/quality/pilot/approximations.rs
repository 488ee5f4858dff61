//! The approximations auto may choose — flat ribbons for round tubes, deep opacity maps for ray-traced shadows, dual
//! scattering for path tracing's bounces —
//! each kept only with the bias it measures against the more exact choice on the same pilot windows and seeds, and
//! only where it is cheaper for the target once that bias is paid for.
//!
//! A rule cannot know a scene's bias: a texel per pixel of the hair left a sparse groom's maps 0.071 (relative
//! RMSE) from ray-traced shadows, and on seed 1's generated scenes ribbons chosen by the sub-pixel rule measured
//! 0.17 and 0.30 (Chiang at 0.47 and 0.42 px) and 0.136 (Kajiya-Kay, a white close-up) from their tubes, each
//! from two independent 128- or 64-spp renders per geometry at path 3 (`docs/measured/auto.md`). So each approximation is rendered beside the exact choice: the
//! pilots' two seeds give each pixel two independent differences d_a, d_b of the approximation against the exact
//! choice, and the mean of d_a d_b / (m̃² + 0.01) estimates the relMSE the approximation adds as bias, unbiased
//! whatever the noise ([`bounce_bias`], as a bounce's). Auto keeps the approximation when its bias (plus
//! [`Margins::approximation_standard_errors`](crate::quality::Margins::approximation_standard_errors) standard
//! errors) fits the bias budget and its
//! predicted CPU seconds for the target (the frame's at the noise budget that bias leaves, and any maps' build) are
//! the fewer; the bias then
//! comes off the noise budget, and the frame's estimate of its error carries it.
//!
//! Where the 4-spp bound keeps ribbons out but the bound a confirmation may expect would let them pay, and what
//! they would save pays for it, the comparison is rendered again with 4× the samples on a quarter of the windows
//! (twice at most, [`CONFIRM_SPP_FACTOR`]), which halves the standard error at the first comparison's cost.
//!
//! Both choices are rendered as the path-length search's first pilots ([`bounce_pairs`] at
//! [`FIRST_PILOT_PATH_LENGTH`]), so the choice kept costs nothing more: the search starts from its pilots.

use crate::accel::CurveKind;
use crate::render::settings::{MultipleScattering, RenderSettings, ShadowMode, Strategy};
use crate::render::{Frame, Region};
use crate::shadow::ShadowMaps;

use super::super::cost::{map_build_seconds, ROUND_CURVE_COST};
use super::super::{Decision, Fixed, Margins, QualityConfig};
use super::bounces::{bounce_bias, bounce_pairs, FIRST_PILOT_PATH_LENGTH};
use super::pair::Pair;
use super::{windows, PILOT_SPP};

/// Share of target² the approximations auto keeps may take as bias, together: the bounces left out take up to a
/// quarter (half the target), so the noise keeps at least a quarter of target².
pub const APPROXIMATION_BIAS_SHARE: f64 = 0.5;

/// How many times more samples per pixel each confirmation of the ribbons' bias takes than the one before (on a
/// quarter of the windows, [`super::comparison_windows`]), and how many confirmations there may be. The products of
/// two seeds' differences have a standard error ∝ 1/(spp √pixels), so four times the samples on a quarter of the
/// pixels halves it at the cost of the first comparison. At 4 spp the bound is mostly the pilots' noise: straight
/// hair under the city map (128², path 3) reads a point bias of 0.0375 and a bound of 0.0687, where two 256-spp
/// renders per geometry of the whole film measure the ribbons' bias at −8.4e-6 ± 5.1e-6 relMSE (none); on the
/// default scene 0.0094 (the pilots' point 0.0116).
const CONFIRM_SPP_FACTOR: u32 = 4;
/// See [`CONFIRM_SPP_FACTOR`].
const CONFIRM_STAGES: usize = 2;

/// The finest deep opacity maps auto builds, texels along a side, and how many doublings of the first resolution
/// it tries: a 2048² map of 16 layers holds 302 MB per light.
const MAX_MAP_RESOLUTION: u32 = 2048;
const MAP_DOUBLINGS: u32 = 2;

/// One approximation auto kept, with its measured bias.
#[derive(Debug, Clone, PartialEq)]
pub struct Approximation {
    /// What was approximated, e.g. "ribbons for tubes".
    pub what: String,
    /// The bias, relative RMSE, with the margin's standard errors: what the budget takes off the noise.
    pub bias: f64,
    /// The point estimate of the bias, relative RMSE (0 where the products' mean is negative).
    pub point: f64,
    /// The standard error of the products' mean (relMSE).
    pub standard_error: f64,
}

impl Approximation {
    /// The bias as relMSE (with its margin): what it takes from the noise budget.
    pub fn bias2(&self) -> f64 {
        self.bias * self.bias
    }
}

/// The relMSE the approximations in `kept` take together as bias (their biases add in quadrature).
pub fn bias2_of(kept: &[Approximation]) -> f64 {
    kept.iter().map(Approximation::bias2).sum()
}

/// The pilots of one choice: the pairs at every path length up to the pilots' (cut from one render per seed).
pub(super) struct Pilots {
    pub(super) pairs: Vec<Pair>,
    /// Predicted CPU seconds of the two renders, without any curve factor.
    pub(super) predicted: f64,
    /// [`ROUND_CURVE_COST`] for round tubes, 1 for ribbons: the cost model counts rays alike on both.
    curve_cost: f64,
    /// The share of the pilots' per-pixel noise the frame's film keeps ([`RenderSettings::noise_share`]).
    share: f64,
}

impl Pilots {
    fn render(
        frame: &Frame,
        settings: &RenderSettings,
        maps: Option<&ShadowMaps>,
        windows: &[Region],
    ) -> Pilots {
        let (pairs, predicted) = bounce_pairs(frame, settings, maps, windows);
        let curve_cost = match frame.curves {
            CurveKind::Round => ROUND_CURVE_COST,
            CurveKind::Flat => 1.0,
        };
        Pilots {
            pairs,
            predicted,
            curve_cost,
            share: settings.noise_share(),
        }
    }

    fn longest(&self) -> &Pair {
        self.pairs.last().expect("path length 0 at least")
    }

    /// The predicted CPU seconds of a `film_pixels` frame at the noise budget `noise2` (relMSE): the pilots' CPU s
    /// per estimate, scaled from their pixels to the film's and by the samples the budget needs, the frame's
    /// relMSE (the pilots' times the film's share) / budget times theirs.
    fn frame_seconds(&self, film_pixels: f64, noise2: f64) -> f64 {
        let p = self.longest();
        if noise2 <= 0.0 {
            return f64::INFINITY;
        }
        let pixels = p.0[0].rgb.len().max(1) as f64;
        self.curve_cost * p.predicted_seconds() * film_pixels / pixels * p.rel_mse() * self.share
            / noise2
    }
}

/// The bias of `approx` against `exact` (pilots of the same windows and seeds, at the same path length), with
/// `standard_errors` standard errors added to the relMSE before the square root, and never under the magnitude of
/// a negative mean: the products estimate a square without bias, so a mean of −x is noise that could as well
/// have read +x (seed 1's scene 8 read −0.187 ± 0.099 for a true 0.029; its standard error reads low on
/// heavy-tailed products).
fn bias_of(
    what: String,
    approx: &Pilots,
    exact: &Pilots,
    windows: &[Region],
    standard_errors: f64,
) -> Approximation {
    let m = bounce_bias(approx.longest().rgb(), exact.longest().rgb(), windows);
    Approximation {
        what,
        bias: (m.mean + standard_errors * m.standard_error)
            .max(-m.mean)
            .max(0.0)
            .sqrt(),
        point: m.mean.max(0.0).sqrt(),
        standard_error: m.standard_error,
    }
}

/// What [`choose`] decided and rendered.
pub struct Chosen {
    /// A frame traced as tubes, when auto measured ribbons as too biased for the target (render it, not the
    /// caller's).
    pub frame: Option<Frame>,
    /// The deep opacity maps of the settings chosen, when they use maps.
    pub maps: Option<ShadowMaps>,
    /// Wall time of building every map tried, seconds.
    pub maps_seconds: f64,
    /// The decisions, for printing.
    pub decisions: Vec<Decision>,
    /// What the pilots measured, for [`super::plan`].
    pub measured: Measured,
}

/// What [`choose`] measured, for [`super::plan`].
pub struct Measured {
    /// The approximations kept, with their bias.
    pub approximations: Vec<Approximation>,
    /// The pilots of the choice kept, for the path-length search to start from.
    pub(super) pilots: Option<Pilots>,
    /// Predicted CPU seconds of every pilot rendered here.
    pub predicted_seconds: f64,
    /// Wall time of the comparisons (pilots and maps), seconds.
    pub seconds: f64,
}

/// Measures each approximation the frame or the rules chose (ribbons for a model that reads the offset h, deep
/// opacity maps) against the exact choice and keeps or replaces it; `settings` (its shadows decided by the rule
/// [`crate::quality::decide_shadows`], `maps` built for them) is changed to what is kept. What `fixed` names is
/// kept as it is, unmeasured.
pub fn choose(
    frame: &Frame,
    settings: &mut RenderSettings,
    maps: Option<ShadowMaps>,
    maps_seconds: f64,
    quality: &QualityConfig,
    fixed: Fixed,
    margins: Margins,
) -> Chosen {
    let [width, height] = settings.film.resolution;
    let windows = windows(width, height);
    let film_pixels = f64::from(width) * f64::from(height);
    let target2 = f64::from(quality.target).powi(2);
    // The noise's budget for a choice whose approximations take `bias2` (relMSE) together, the bounces left out
    // taking up to a quarter of target² (the path length is decided after).
    let noise_left = |bias2: f64| 0.75 * target2 - bias2;
    let mut pilot = settings.clone();
    pilot.film.spp = PILOT_SPP;
    if !fixed.path_length {
        pilot.integrator.path_length = FIRST_PILOT_PATH_LENGTH;
    }
    let mut chosen = Chosen {
        frame: None,
        maps,
        maps_seconds,
        decisions: Vec::new(),
        measured: Measured {
            approximations: Vec::new(),
            pilots: None,
            predicted_seconds: 0.0,
            seconds: 0.0,
        },
    };
    let start = std::time::Instant::now();
    let mut render = |frame: &Frame, s: &RenderSettings, maps: Option<&ShadowMaps>| {
        let p = Pilots::render(frame, s, maps, &windows);
        chosen.measured.predicted_seconds += p.predicted;
        p
    };
    let mut current: Option<Pilots> = None;

    // Ribbons for tubes, whenever the curve rule chose ribbons, for every model: a model that does not read h still
    // sees the ribbons' geometry (a white Kajiya-Kay close-up of seed 1's generated set, 2 × 64 spp, path 3:
    // ribbons' bias 0.136 relative RMSE against tubes).
    let human = crate::util::input_file::human_bytes;
    let held_maps = |settings: &RenderSettings, maps: &Option<ShadowMaps>| {
        maps.as_ref().map_or(0, |_| frame.map_bytes(settings))
    };
    // The second tracer, while the ribbons' stays alive (the frame the job holds).
    let mut second_tracer = 0;
    if !fixed.curves && frame.curves == CurveKind::Flat {
        let tubes_bytes = frame.tracer_bytes(CurveKind::Round);
        let fits = frame.fits(tubes_bytes + held_maps(settings, &chosen.maps));
        if !fits {
            chosen.decisions.push(Decision {
                key: "hair.curves",
                value: "flat".into(),
                reason: format!(
                    "tubes not measured against the ribbons: their tracer ({}) beside the ribbons' and the maps \
                     does not fit the memory limit ({} left)",
                    human(tubes_bytes),
                    human(frame.memory_headroom().unwrap_or(0))
                ),
            });
        }
        if let Some(round) = fits
            .then(|| frame.with_curves(CurveKind::Round).ok())
            .flatten()
        {
            let flat = render(frame, &pilot, chosen.maps.as_ref());
            let tubes = render(&round, &pilot, chosen.maps.as_ref());
            let c_round = tubes.frame_seconds(film_pixels, noise_left(0.0));
            let c_flat = |bias2: f64| flat.frame_seconds(film_pixels, noise_left(bias2));
            let pays =
                |bias2: f64| bias2 <= APPROXIMATION_BIAS_SHARE * target2 && c_flat(bias2) < c_round;
            let mut a = bias_of(
                "ribbons for tubes".into(),
                &flat,
                &tubes,
                &windows,
                margins.approximation_standard_errors,
            );
            let mut listed = vec![format!(
                "{PILOT_SPP} spp on {} windows: bias {:.4} (point {:.4}), ribbons' frame {:.2}",
                windows.len(),
                a.bias,
                a.point,
                c_flat(a.bias2())
            )];
            // Where the ribbons' bias bound keeps them out but the bound a confirmation may expect would let them
            // pay, the comparison is rendered again with CONFIRM_SPP_FACTOR× the samples on a quarter of the
            // windows, while what the ribbons would then save pays for the further pilots (see CONFIRM_SPP_FACTOR).
            let picked: Vec<Region> = super::comparison_windows(&windows)
                .into_iter()
                .map(|i| windows[i])
                .collect();
            let pair_cost = flat.predicted + ROUND_CURVE_COST * tubes.predicted;
            let mut confirm = pilot.clone();
            let mut windows_before = windows.len() as f64;
            for _ in 0..CONFIRM_STAGES {
                if pays(a.bias2()) {
                    break;
                }
                // The standard error falls as 1/(spp √pixels); the bound the confirmation may expect is the point
                // estimate one standard error lower plus the margin's standard errors at what is left of it.
                let shrink =
                    (windows_before / picked.len() as f64).sqrt() / f64::from(CONFIRM_SPP_FACTOR);
                let expected = (a.point * a.point - a.standard_error).max(0.0)
                    + shrink * margins.approximation_standard_errors * a.standard_error;
                let saving = c_round - c_flat(expected);
                confirm.film.spp *= CONFIRM_SPP_FACTOR;
                windows_before = picked.len() as f64;
                let cost =
                    pair_cost * f64::from(confirm.film.spp / PILOT_SPP) * picked.len() as f64
                        / windows.len() as f64;
                if !pays(expected) || saving <= cost {
                    listed.push(format!(
                        "not confirmed at {} spp: predicted saving {:.2} s at the bias bound it may expect, its \
                         pilots {cost:.2} s",
                        confirm.film.spp,
                        saving.max(0.0)
                    ));
                    break;
                }
                let f = render(frame, &confirm, chosen.maps.as_ref());
                let t = render(&round, &confirm, chosen.maps.as_ref());
                a = bias_of(
                    "ribbons for tubes".into(),
                    &f,
                    &t,
                    &picked,
                    margins.approximation_standard_errors,
                );
                listed.push(format!(
                    "{} spp on {} windows: bias {:.4} (point {:.4}), ribbons' frame {:.2}",
                    confirm.film.spp,
                    picked.len(),
                    a.bias,
                    a.point,
                    c_flat(a.bias2())
                ));
            }
            let keep = pays(a.bias2());
            chosen.decisions.push(Decision {
                key: "hair.curves",
                value: if keep { "flat" } else { "round" }.into(),
                reason: format!(
                    "ribbons against tubes on the same pilots (path {}; ribbons' bias with {} standard error(s) \
                     added; predicted CPU s of the frame at the noise the target leaves, tubes' rays taken as \
                     {ROUND_CURVE_COST}× a ribbon's): tubes {c_round:.2}; {}",
                    pilot.integrator.path_length,
                    margins.approximation_standard_errors,
                    listed.join("; ")
                ),
            });
            if keep {
                chosen.measured.approximations.push(a);
                current = Some(flat);
            } else {
                chosen.frame = Some(round);
                current = Some(tubes);
                second_tracer = tubes_bytes;
            }
        }
    }

    // Deep opacity maps for ray-traced shadows, finer maps while they are too biased.
    if !fixed.shadows && settings.shadows.mode == ShadowMode::DeepOpacity {
        let active = chosen.frame.as_ref().unwrap_or(frame);
        let taken = bias2_of(&chosen.measured.approximations);
        let mut rays_settings = pilot.clone();
        rays_settings.shadows.mode = ShadowMode::Raytraced;
        let rays = render(active, &rays_settings, None);
        let c_rays = rays.frame_seconds(film_pixels, noise_left(taken));
        let segments = active.strands.segment_count();
        let first = settings.shadows.deep_opacity.resolution;
        let mut listed = Vec::new();
        let mut kept = None;
        let mut resolution = first;
        loop {
            if resolution != settings.shadows.deep_opacity.resolution || chosen.maps.is_none() {
                settings.shadows.deep_opacity.resolution = resolution;
                let start = std::time::Instant::now();
                chosen.maps = Some(active.shadow_maps(settings));
                chosen.maps_seconds += start.elapsed().as_secs_f64();
                current = None;
            }
            pilot.shadows.deep_opacity.resolution = resolution;
            let with_maps = match current.take() {
                Some(p) => p,
                None => render(active, &pilot, chosen.maps.as_ref()),
            };
            let a = bias_of(
                format!("deep opacity maps {resolution}² for ray-traced shadows"),
                &with_maps,
                &rays,
                &windows,
                margins.approximation_standard_errors,
            );
            let b2 = a.bias2();
            // The maps of this resolution are built: their build is spent, whatever is chosen.
            let c_maps = with_maps.frame_seconds(film_pixels, noise_left(taken + b2));
            listed.push(format!(
                "{resolution}²: bias {:.4} (point {:.4}), {c_maps:.2} s",
                a.bias, a.point
            ));
            if taken + b2 <= APPROXIMATION_BIAS_SHARE * target2 && c_maps < c_rays {
                kept = Some((a, with_maps));
                break;
            }
            let next = resolution * 2;
            if next > MAX_MAP_RESOLUTION.min(first << MAP_DOUBLINGS) {
                break;
            }
            // Finer maps are built while the current ones are alive: both must fit beside the frame.
            let mut finer = settings.clone();
            finer.shadows.deep_opacity.resolution = next;
            let bytes = second_tracer + held_maps(settings, &chosen.maps) + frame.map_bytes(&finer);
            if !frame.fits(bytes) {
                listed.push(format!(
                    "{next}²: not built, its maps beside the current ones ({}) do not fit the memory limit ({} \
                     left)",
                    human(bytes - second_tracer),
                    human(frame.memory_headroom().unwrap_or(0).saturating_sub(second_tracer))
                ));
                break;
            }
            // Finer maps are tried only if, even without bias, their frame and build would beat the rays.
            let layers = settings.shadows.deep_opacity.layers;
            let count = chosen.maps.as_ref().map_or(1, |m| m.maps().len()) as f64;
            let build = count * map_build_seconds(next, layers, segments);
            let at_best = with_maps.frame_seconds(film_pixels, noise_left(taken)) + build;
            if at_best >= c_rays {
                listed.push(format!(
                    "{next}²: not built, at best {at_best:.2} s with its build {build:.2} s"
                ));
                break;
            }
            resolution = next;
        }
        let reason = format!(
            "maps against ray-traced shadows on the same pilots ({PILOT_SPP} spp, path {}; bias with {} standard \
             error(s) added; predicted CPU s of the frame at the noise the target leaves): {}; ray-traced \
             {c_rays:.2} s",
            pilot.integrator.path_length,
            margins.approximation_standard_errors,
            listed.join("; ")
        );
        match kept {
            Some((a, p)) => {
                chosen.decisions.push(Decision {
                    key: "shadows.mode",
                    value: format!(
                        "deep-opacity, {}² texels, {} layers",
                        resolution, settings.shadows.deep_opacity.layers
                    ),
                    reason,
                });
                chosen.measured.approximations.push(a);
                current = Some(p);
            }
            None => {
                settings.shadows.mode = ShadowMode::Raytraced;
                settings.shadows.deep_opacity.resolution = first;
                chosen.maps = None;
                chosen.decisions.push(Decision {
                    key: "shadows.mode",
                    value: "raytraced".into(),
                    reason,
                });
                current = Some(rays);
            }
        }
    }
    // Dual scattering for the bounces path tracing would trace, where it is built (Chiang's model): measured against
    // path tracing with a tail that Russian roulette alone ends (every bounce, no bias in path length), on the same
    // windows and seeds; its cost against that of the path-traced frame with every bounce, which is what auto
    // renders otherwise (a tail past the path length it finds). Where deep opacity maps were kept for the shadows,
    // dual reads its strand counts from them: they are rebuilt with counts if those fit beside the frame (else
    // dual counts along rays, as the maps without counts leave it).
    let active = chosen.frame.as_ref().unwrap_or(frame);
    if !fixed.path_length
        && settings.integrator.strategy != Strategy::Material
        && !settings.integrator.dual()
        && active.material.dual().is_some()
    {
        let taken = bias2_of(&chosen.measured.approximations);
        let mut every_bounce = pilot.clone();
        every_bounce.integrator.tail = 1.0;
        let paths = render(active, &every_bounce, chosen.maps.as_ref());
        let mut dual_settings = pilot.clone();
        dual_settings.integrator.multiple_scattering = MultipleScattering::Dual;
        let mut dual_frame_settings = settings.clone();
        dual_frame_settings.integrator.multiple_scattering = MultipleScattering::Dual;
        let counting_maps = chosen
            .maps
            .as_ref()
            .filter(|_| {
                frame.fits(
                    second_tracer
                        + held_maps(settings, &chosen.maps)
                        + frame.map_bytes(&dual_frame_settings),
                )
            })
            .map(|_| {
                let start = std::time::Instant::now();
                let maps = active.shadow_maps(&dual_frame_settings);
                chosen.maps_seconds += start.elapsed().as_secs_f64();
                maps
            });
        let dual = render(
            active,
            &dual_settings,
            counting_maps.as_ref().or(chosen.maps.as_ref()),
        );
        let a = bias_of(
            "dual scattering for path tracing".into(),
            &dual,
            &paths,
            &windows,
            margins.approximation_standard_errors,
        );
        let c_dual = dual.frame_seconds(film_pixels, noise_left(taken + a.bias2()));
        let c_paths = paths.frame_seconds(film_pixels, noise_left(taken));
        let keep = taken + a.bias2() <= APPROXIMATION_BIAS_SHARE * target2 && c_dual < c_paths;
        chosen.decisions.push(Decision {
            key: "integrator.multiple_scattering",
            value: if keep { "dual" } else { "path" }.into(),
            reason: format!(
                "dual scattering against path tracing to every bounce (path {} and Russian roulette's tail) on the \
                 same pilots ({PILOT_SPP} spp): dual's bias {:.4} (point {:.4}, {} standard error(s) added; the \
                 approximations' budget is {:.4}); predicted CPU s of the frame at the noise the target leaves, dual \
                 {c_dual:.2}, path tracing {c_paths:.2}",
                pilot.integrator.path_length,
                a.bias,
                a.point,
                margins.approximation_standard_errors,
                (APPROXIMATION_BIAS_SHARE * target2 - taken).max(0.0).sqrt(),
            ),
        });
        if keep {
            settings.integrator.multiple_scattering = MultipleScattering::Dual;
            chosen.measured.approximations.push(a);
            current = Some(dual);
            if counting_maps.is_some() {
                chosen.maps = counting_maps;
            }
        }
    }
    chosen.measured.pilots = current;
    chosen.measured.seconds = start.elapsed().as_secs_f64();
    chosen
}

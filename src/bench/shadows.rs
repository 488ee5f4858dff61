//! Shadow-cost benchmark (`cuticle bench shadows SCENE`): what self-shadowing costs with ray-traced shadows and with
//! deep opacity maps, measured in one run on the same scene, and how far the two images are apart.
//!
//! Method: the hair is loaded and its BVH built once; then the frame is rendered with `shadows = none`,
//! `"raytraced"` and `"deep-opacity"`, each `repetitions` times after one untimed warm-up, on a local rayon pool.
//! The **shadow cost** of a mode is its median render time minus the median of `none` (for deep opacity maps plus
//! the median map-build time). The RMS difference of the deep-opacity beauty from the ray-traced one (both at the
//! scene's spp) is printed beside it; `cuticle study shadows` measures both against a converged reference. The
//! reference configuration is `scenes/furball-shadows.toml` (the fur ball under one distant light, 512², 16 spp).

use std::fmt;

use std::time::Instant;

use rayon::prelude::*;

use super::frame::FrameBenchError;
use crate::image::Image;
use crate::measure::Timing;
use crate::render::{thread_pool, Frame, Request, ShadowMode};
use crate::scene::Scene;
use crate::shadow::deep_opacity::MapFrame;

/// One shadow mode's timings.
#[derive(Debug, Clone)]
pub struct ModeTiming {
    /// The mode.
    pub mode: ShadowMode,
    /// Pixel loop.
    pub render: Timing,
    /// Map build (0 unless deep opacity).
    pub build: Timing,
    /// Shadow rays traced per frame.
    pub shadow_rays: u64,
    /// Map memory, bytes.
    pub map_bytes: usize,
}

/// The result of [`shadows`].
#[derive(Debug, Clone)]
pub struct ShadowReport {
    /// Scene file.
    pub scene: String,
    /// Resolution and spp.
    pub resolution: [u32; 2],
    /// Camera samples per pixel.
    pub spp: u32,
    /// Worker threads.
    pub threads: usize,
    /// none, raytraced, deep-opacity.
    pub modes: Vec<ModeTiming>,
    /// RMS difference (RGB) between the deep-opacity and ray-traced beauty images.
    pub rms_difference: f64,
    /// Mean of the ray-traced beauty (RGB), to read the difference against.
    pub mean_level: f64,
    /// What building the first distant light's map by tracing would cost: (rays, seconds) for one
    /// exact-transmittance ray per texel (a full traversal, as an all-hits query collecting layers would need).
    pub traced_build: Option<(u64, f64)>,
}

impl ShadowReport {
    fn get(&self, mode: ShadowMode) -> &ModeTiming {
        self.modes
            .iter()
            .find(|m| m.mode == mode)
            .expect("every mode is measured")
    }

    /// Seconds that self-shadowing adds in `mode` (render − render without shadows, plus map build).
    pub fn shadow_cost(&self, mode: ShadowMode) -> f64 {
        let m = self.get(mode);
        m.render.median + m.build.median - self.get(ShadowMode::None).render.median
    }
}

impl fmt::Display for ShadowReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [w, h] = self.resolution;
        writeln!(
            f,
            "shadow benchmark: {} ({w}x{h}, {} spp); {} threads; medians after 1 warm-up",
            self.scene, self.spp, self.threads
        )?;
        for m in &self.modes {
            writeln!(
                f,
                "{:<13} render {:.3} s ({:.3}-{:.3}), map build {:.3} s, {} shadow rays, maps {:.1} MB, shadow cost {:.3} s",
                m.mode.name(),
                m.render.median,
                m.render.min,
                m.render.max,
                m.build.median,
                m.shadow_rays,
                m.map_bytes as f64 / 1e6,
                self.shadow_cost(m.mode)
            )?;
        }
        let (rt, dom) = (
            self.shadow_cost(ShadowMode::Raytraced),
            self.shadow_cost(ShadowMode::DeepOpacity),
        );
        if let Some((rays, seconds)) = self.traced_build {
            writeln!(
                f,
                "a ray-traced map build (one exact-transmittance ray per texel): {rays} rays in {seconds:.3} s, against the rasterised build above"
            )?;
        }
        write!(
            f,
            "deep-opacity shadow cost / ray-traced shadow cost = {:.3}; RMS difference of the images {:.4} (mean level {:.4})",
            dom / rt,
            self.rms_difference,
            self.mean_level
        )
    }
}

/// Mean of R, G and B over `image`.
fn mean_rgb(image: &Image) -> f64 {
    let n = image.channels.len();
    let rgb: Vec<usize> = ["R", "G", "B"]
        .iter()
        .filter_map(|c| image.channel_index(c))
        .collect();
    let sum: f64 = image
        .data
        .chunks_exact(n)
        .flat_map(|p| rgb.iter().map(|&c| f64::from(p[c])))
        .sum();
    sum / (rgb.len() * image.width * image.height).max(1) as f64
}

/// Runs the benchmark (see the module docs).
pub fn shadows(
    scene: &Scene,
    threads: usize,
    repetitions: usize,
) -> Result<ShadowReport, FrameBenchError> {
    let pool = thread_pool(Some(threads))?;
    let frame = Frame::load(scene.resolve()?)?;
    let mut modes = Vec::new();
    let mut images = Vec::new();
    for mode in [
        ShadowMode::None,
        ShadowMode::Raytraced,
        ShadowMode::DeepOpacity,
    ] {
        let mut settings = frame.settings.clone();
        settings.shadows.mode = mode;
        let run = || {
            let r = pool.install(|| frame.render(Request::new(&settings)));
            (r.image, r.stats)
        };
        let (image, warm) = run();
        let (mut render_s, mut build_s) = (Vec::new(), Vec::new());
        for _ in 0..repetitions.max(1) {
            let (_, stats) = run();
            render_s.push(stats.seconds);
            build_s.push(stats.shadow_build_seconds);
        }
        modes.push(ModeTiming {
            mode,
            render: Timing::from_samples(render_s),
            build: Timing::from_samples(build_s),
            shadow_rays: warm.rays.shadow,
            map_bytes: warm.shadow_map_bytes,
        });
        images.push(image);
    }
    // The study's RMSE over R, G, B (no pixel mask needed: only the whole-image figure is printed).
    let mask = vec![false; images[1].width * images[1].height];
    let rms = crate::measure::metrics::errors(&images[2], &images[1], &mask)
        .expect("renders of one scene share their size and carry R, G, B")
        .rmse;
    let level = mean_rgb(&images[1]);
    let traced_build = frame.lights.iter().find_map(|l| match l {
        crate::light::Light::Distant(d) => Some(d.to_sun()),
        _ => None,
    });
    let traced_build = traced_build.map(|to_sun| {
        let res = scene.shadows.deep_opacity.resolution;
        let map = MapFrame::fit_orthographic(-to_sun, &frame.strands, res);
        let start = Instant::now();
        pool.install(|| {
            (0..res).into_par_iter().for_each(|ty| {
                for tx in 0..res {
                    let _ = frame.tracer.transmittance(&map.texel_ray(tx, ty), None);
                }
            })
        });
        (
            u64::from(res) * u64::from(res),
            start.elapsed().as_secs_f64(),
        )
    });
    Ok(ShadowReport {
        scene: scene.source.display().to_string(),
        resolution: scene.film.resolution,
        spp: scene.film.spp,
        threads: pool.current_num_threads(),
        modes,
        rms_difference: rms,
        mean_level: level,
        traced_build,
    })
}

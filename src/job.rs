//! One render job, as `cuticle render` runs it: [`Job::prepare`] turns a scene (command-line overrides applied)
//! into a built frame — memory checked, hair loaded, `--quality auto`'s plan made, deep opacity maps built — and
//! [`Job::render`] renders one animation frame of it (the whole film, a crop or a tile), stopping cleanly on a
//! cancel flag; [`Job::write`] writes its outputs all-or-nothing. The CLI and the tests ([`render_scene`]) run
//! this sequence, so it is written once; `study auto` calls the same planning steps
//! ([`quality::plan_curves`], [`quality::plan_frame_with`]) on frames it keeps loaded across its timed runs.
//!
//! The job sits above [`crate::quality`] (auto plans a built [`Frame`]) and [`crate::farm`] (tiles, frames and
//! interrupted renders), and below the measurement layer.

use std::ops::RangeInclusive;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use crate::farm::{self, FarmError, Interrupted};
use crate::image::{self, ExrInfo, Image, ImageError, Outputs};
use crate::quality::denoised::DenoisedSchedule;
use crate::quality::{self, pilot::PilotPlan, Decision, Fixed, QualityMode};
use crate::render::Request as RenderRequest;
use crate::render::{
    budget, thread_pool, Frame, FrameError, Reconstruction, Region, RenderSettings, RenderStats,
    ShadowMode, ThreadPoolError,
};
use crate::scene::{Overrides, Scene, SceneError};
use crate::shadow::ShadowMaps;

/// Which pixels of the film a job renders.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Part {
    /// The whole film.
    #[default]
    Full,
    /// The pixels x0..x1 × y0..y1 (`--crop`).
    Crop(Region),
    /// Band `index` (from 0) of `count` bands of whole rows (`--tile I/N`).
    Tile {
        /// Which band.
        index: u32,
        /// How many bands.
        count: u32,
    },
}

/// What to render and where to write it: everything `cuticle render` takes besides the scene.
#[derive(Debug, Clone)]
pub struct Request {
    /// The scene, command-line overrides applied.
    pub scene: Scene,
    /// The keys the user fixed (auto keeps them); [`Fixed::from_overrides`] from the command line.
    pub fixed: Fixed,
    /// Worker threads (`None`: one per core).
    pub threads: Option<usize>,
    /// Memory limit, bytes (`None`: [`budget::default_limit`]).
    pub max_memory: Option<u64>,
    /// The pixels to render.
    pub part: Part,
    /// Animation frames of the camera's turntable (`None`: the scene's frame, one output).
    pub frames: Option<RangeInclusive<i32>>,
    /// The output image: `.exr` (beauty + AOVs, and a `.png` preview beside it) or `.png` (preview only); `None`
    /// for a job whose frames are only kept in memory (tests, studies).
    pub output: Option<PathBuf>,
    /// Also write every deep opacity map into this directory.
    pub dump_shadow_maps: Option<PathBuf>,
    /// Denoise each frame with this guide ([`crate::image::denoise`]): `denoised.R/G/B` beside the beauty, and the
    /// preview made from them. Whole frames only.
    pub denoise: Option<crate::image::denoise::Guide>,
    /// Show a progress bar.
    pub progress: bool,
}

/// Why a job could not be prepared or run. Each message names the file, key or option.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The frame could not be built (memory, hair file, tracer).
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// An output cannot be written.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A render-farm step failed, or the render was interrupted ([`FarmError::Interrupted`]).
    #[error(transparent)]
    Farm(#[from] FarmError),
    /// The worker pool could not be started.
    #[error(transparent)]
    Threads(#[from] ThreadPoolError),
    /// An option or setting that does not fit this job, with the reason.
    #[error("{0}")]
    Invalid(String),
    /// A file or directory could not be used.
    #[error("{path}: {message}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// What was being done.
        message: &'static str,
        /// The I/O error.
        source: std::io::Error,
    },
}

/// What `--quality auto` decided for a job.
#[derive(Debug, Clone)]
pub struct AutoPlan {
    /// Every decision, in the order made (the curve kind first).
    pub decisions: Vec<Decision>,
    /// The pilots' measurements and predictions.
    pub pilot: PilotPlan,
    /// The error target.
    pub target: f32,
    /// Whether the user fixed the samples per pixel.
    pub spp_fixed: bool,
}

impl AutoPlan {
    /// Why the fixed settings cannot meet the target, if the pilots predict they miss it: the predicted noise at
    /// the fixed spp against the noise the target leaves once the bias of left-out bounces is taken off.
    pub fn shortfall(&self) -> Option<String> {
        let p = &self.pilot;
        if !self.spp_fixed || p.predicted_noise <= p.noise_budget || p.noise_budget <= 0.0 {
            return None;
        }
        let needed = (f64::from(p.spp) * (p.predicted_noise / p.noise_budget).powi(2)).ceil();
        Some(format!(
            "--spp {} cannot meet --target {}: predicted noise {:.3}, the target leaves {:.3}; about {} spp would",
            p.spp, self.target, p.predicted_noise, p.noise_budget, needed
        ))
    }
}

/// One rendered animation frame of a job.
#[derive(Debug, Clone)]
pub struct Rendered {
    /// The animation frame (`None`: the scene's own, without a frame number in the file name).
    pub frame: Option<i32>,
    /// The region's pixels.
    pub image: Image,
    /// The EXR header: data window, job hash, completeness.
    pub info: ExrInfo,
    /// Counters of the render.
    pub stats: RenderStats,
    /// Wall seconds of denoising the frame (0 without `--denoise`), with the rounds' halves under auto.
    pub denoise_seconds: f64,
    /// Under `--quality auto --denoise`, what the frame's denoised rounds measured.
    pub rounds: Option<quality::denoised::Rounds>,
}

/// A prepared render job ([`Job::prepare`]).
pub struct Job {
    request: Request,
    pool: rayon::ThreadPool,
    /// The frame: hair, tracer, lights, material.
    pub frame: Frame,
    /// The settings the frames render with (auto's, under `--quality auto`).
    pub settings: RenderSettings,
    maps: Option<ShadowMaps>,
    maps_seconds: f64,
    /// What auto decided (`None` under fixed quality).
    pub auto: Option<AutoPlan>,
    /// Under `--quality auto --denoise` (the spp not fixed): the denoised frame's rounds.
    pub denoised: Option<quality::denoised::DenoisedSchedule>,
    /// The pixels rendered.
    pub region: Region,
    /// The scene as rendered, for the job hash that tiles are matched by.
    description: String,
    exr_output: bool,
}

impl Fixed {
    /// The auto-decided keys a set of command-line overrides fixes.
    pub fn from_overrides(o: &Overrides) -> Fixed {
        Fixed {
            curves: o.curves.is_some(),
            shadows: o.shadows.is_some(),
            path_length: o.path_length.is_some(),
            samples: o.light_samples.is_some() || o.material_samples.is_some(),
            spp: o.spp.is_some(),
        }
    }
}

impl Job {
    /// Checks every output path, starts the worker pool, loads and builds the frame within the memory limit, makes
    /// auto's plan and builds the deep opacity maps the frames need. Nothing is written.
    pub fn prepare(request: Request) -> Result<Job, JobError> {
        let scene = &request.scene;
        let exr_output = check_outputs(&request)?;
        if request.denoise.is_some() {
            // Both checked before anything is loaded: a whole-frame step, and a library that may be missing.
            if request.part != Part::Full {
                return Err(JobError::Invalid(
                    "--denoise denoises whole frames: render the tiles or crop without it, and denoise the merged \
                     frame (`cuticle merge --denoise`)"
                        .to_owned(),
                ));
            }
            crate::image::denoise::available()
                .map_err(|e| JobError::Invalid(format!("--denoise: {e}")))?;
        }
        let threads = request
            .threads
            .map(budget::check_threads)
            .transpose()
            .map_err(JobError::Invalid)?;
        let pool = thread_pool(threads)?;
        let spec = scene.resolve()?;
        // The region is checked against the film before anything is loaded or built (auto never changes the
        // resolution): a crop outside the frame was refused only after a 27 s build at 3·10⁵ strands.
        let [width, height] = spec.settings.film.resolution;
        let region = match request.part {
            Part::Crop(crop) => {
                crop.check_inside(width, height)
                    .map_err(JobError::Invalid)?;
                crop
            }
            Part::Tile { index, count } => {
                Region::band(index, count, width, height).map_err(JobError::Invalid)?
            }
            Part::Full => Region::full(width, height),
        };
        let (limit, limit_source) = match request.max_memory {
            Some(bytes) => (bytes, "--max-memory".to_owned()),
            None => budget::default_limit(),
        };
        let quality = (scene.quality.mode == QualityMode::Auto).then_some(&scene.quality);
        let fixed = request.fixed;
        let mut decisions = Vec::new();
        let mut frame = pool.install(|| {
            // Auto samples adaptively unless --spp fixes the count: its memory is checked for that.
            Frame::load_adjusted(
                spec,
                limit,
                &limit_source,
                quality.is_some() && !fixed.spp,
                |strands, spec| {
                    if quality.is_some() && !fixed.curves {
                        let s = &spec.settings;
                        let (kind, d) = quality::plan_curves(
                            strands,
                            &spec.material,
                            &s.camera,
                            s.film.resolution,
                        );
                        spec.curves = kind;
                        decisions.push(d);
                    }
                },
            )
        })?;
        // Identified after loading, so a missing or unreadable input is reported by the reader that needs it.
        let description = job_identity(scene)?;
        // The frame is built: load OpenImageIO in the background while it renders. Not earlier: `dlopen` holds the
        // loader's lock for the whole load (OpenImageIO pulls in some sixty libraries, ~0.1 s), and creating
        // threads needs that lock, so Embree's device and build (TBB starting its workers) would wait for it.
        image::preload();
        // Splatting correlates neighbouring pixels' noise. OIDN cannot denoise that (its documentation: weighted
        // pixel sampling "causes the denoising to fail"): a denoised frame renders with filter importance sampling,
        // and auto plans for that film.
        let film_settings = |settings: &RenderSettings| {
            let mut settings = settings.clone();
            if request.denoise.is_some() {
                settings.film.reconstruction = Reconstruction::Importance;
            }
            settings
        };
        let planned = quality.map(|q| {
            let settings = film_settings(&frame.settings);
            pool.install(|| quality::plan_frame(&frame, &settings, q, fixed))
        });
        let mut denoised = None;
        let (settings, planned_maps, auto) = match planned {
            Some(p) => {
                if let Some(tubes) = p.frame {
                    // Auto measured the ribbons too biased and built the tubes: they are what renders.
                    frame = tubes;
                }
                // A measured curve decision replaces the rule's, and says what the rule read.
                let mut measured = p.decisions;
                if let Some(m) = measured.iter_mut().find(|d| d.key == "hair.curves") {
                    if let Some(i) = decisions.iter().position(|d| d.key == "hair.curves") {
                        let rule = decisions.remove(i);
                        m.reason = format!(
                            "{}; before measuring, by the rule: {}",
                            m.reason, rule.reason
                        );
                    }
                }
                decisions.extend(measured);
                if let (Some(guide), false) = (request.denoise, fixed.spp) {
                    let extra = DenoisedSchedule::extra_bytes(&p.settings);
                    if frame.fits(extra) {
                        let s = DenoisedSchedule::new(&p.pilot, &scene.quality, guide);
                        denoised = Some(s);
                        // The rounds replace the adaptive rule: the target applies to the denoised frame.
                        decisions.retain(|d| d.key != "adaptive sampling" && d.key != "film.spp");
                        decisions.push(s.decision());
                    } else {
                        decisions.push(Decision {
                            key: "film.spp",
                            value: "adaptive, then denoised".to_owned(),
                            reason: format!(
                                "--denoise: the denoised rounds need {} more than the memory limit leaves, so the \
                                 target applies to the frame before denoising (the adaptive rule above)",
                                crate::util::input_file::human_bytes(extra)
                            ),
                        });
                    }
                }
                let auto = AutoPlan {
                    decisions,
                    pilot: p.pilot,
                    target: scene.quality.target,
                    spp_fixed: fixed.spp,
                };
                (p.settings, p.maps.map(|m| (m, p.maps_seconds)), Some(auto))
            }
            None => (frame.settings.clone(), None, None),
        };
        let settings = film_settings(&settings);
        let [width, height] = settings.film.resolution;
        settings
            .camera
            .camera(frame.hair_bounds(), width, height)
            .map_err(|m| JobError::Invalid(format!("{}: {m}", scene.source.display())))?;
        debug_assert_eq!(
            [width, height],
            settings.film.resolution,
            "auto changed the film"
        );
        // Deep opacity maps are built once: for the render (in deep-opacity mode) and for dumping alike.
        let start = Instant::now();
        let (maps, maps_seconds) = match planned_maps {
            Some((m, s)) => (Some(m), s),
            None => {
                let wanted = settings.shadows.mode == ShadowMode::DeepOpacity
                    || request.dump_shadow_maps.is_some();
                let maps = wanted.then(|| pool.install(|| frame.shadow_maps(&settings)));
                (maps, start.elapsed().as_secs_f64())
            }
        };
        Ok(Job {
            request,
            pool,
            frame,
            settings,
            maps,
            maps_seconds,
            auto,
            denoised,
            region,
            description,
            exr_output,
        })
    }

    /// The animation frames to render, in order (`None`: the scene's frame).
    pub fn frames(&self) -> Vec<Option<i32>> {
        frame_numbers(&self.request.frames)
    }

    /// The output image of animation frame `frame` (`None` for a job without outputs).
    pub fn output_path(&self, frame: Option<i32>) -> Option<PathBuf> {
        self.request
            .output
            .as_ref()
            .map(|o| farm::frame_path(o, frame))
    }

    /// Worker threads of the job's pool.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Renders animation frame `frame` on the job's pool. Once `cancel` holds a signal number no new tile starts;
    /// the tiles finished so far are then written to the partial EXR beside the output (if there are any) and the
    /// result is [`FarmError::Interrupted`] naming it.
    pub fn render(
        &self,
        frame: Option<i32>,
        cancel: Option<&AtomicUsize>,
    ) -> Result<Rendered, JobError> {
        let mut settings = self.settings.clone();
        settings.camera.frame = frame.unwrap_or(0);
        let mut request = RenderRequest::new(&settings)
            .maps(self.maps.as_ref(), self.maps_seconds)
            .region(self.region)
            .progress(self.request.progress);
        if let Some(c) = cancel {
            request = request.cancel(c);
        }
        let (r, rounds, mut denoise_seconds) = match &self.denoised {
            Some(schedule) => {
                let d = self
                    .pool
                    .install(|| {
                        quality::denoised::render(&self.frame, request, schedule, self.threads())
                    })
                    .map_err(|e| JobError::Invalid(format!("--denoise: {e}")))?;
                (d.render, Some(d.rounds), d.denoise_seconds)
            }
            None => (self.pool.install(|| self.frame.render(request)), None, 0.0),
        };
        let [width, height] = settings.film.resolution;
        let job = farm::job_hash(&self.description, settings.camera.frame);
        let info = farm::render_info(
            self.region,
            width,
            height,
            &job,
            settings.camera.frame,
            r.tiles_done,
            r.tiles_total,
        );
        let mut info = info;
        let reconstruction = if settings.splats() {
            Reconstruction::Splat
        } else {
            Reconstruction::Importance
        };
        info.attributes.push((
            farm::KEY_RECONSTRUCTION.to_owned(),
            reconstruction.name().to_owned(),
        ));
        if !r.is_complete() {
            let signal = cancel.map_or(0, |c| c.load(Ordering::Relaxed)) as i32;
            let partial = self
                .output_path(frame)
                .filter(|_| r.tiles_done > 0)
                .map(|p| farm::free_partial_path(&p));
            if let Some(p) = &partial {
                let mut outputs = Outputs::new();
                outputs.exr(p, &r.image, &info)?;
                outputs.commit()?;
            }
            return Err(FarmError::Interrupted(Interrupted { signal, partial }).into());
        }
        let mut image = r.image;
        let start = std::time::Instant::now();
        if let (Some(guide), None) = (self.request.denoise, &rounds) {
            crate::image::denoise::add_denoised(&mut image, guide, self.threads())
                .map_err(|e| JobError::Invalid(format!("--denoise: {e}")))?;
            denoise_seconds = start.elapsed().as_secs_f64();
        }
        Ok(Rendered {
            frame,
            image,
            info,
            stats: r.stats,
            denoise_seconds,
            rounds,
        })
    }

    /// Writes `rendered`'s image (EXR and PNG preview, or the PNG alone) and, with the first frame, the shadow maps
    /// to dump; all or nothing. Returns the paths written.
    pub fn write(&self, rendered: &Rendered) -> Result<Vec<PathBuf>, JobError> {
        let path = self
            .output_path(rendered.frame)
            .ok_or_else(|| JobError::Invalid("this job has no output to write".to_owned()))?;
        let mut outputs = Outputs::new();
        let first = self.frames().first() == Some(&rendered.frame);
        if let (Some(dir), Some(maps), true) = (&self.request.dump_shadow_maps, &self.maps, first) {
            for (name, map) in maps.maps() {
                outputs.exr(
                    &dir.join(format!("{name}.exr")),
                    &map.to_image(),
                    &Default::default(),
                )?;
            }
        }
        if self.exr_output {
            outputs.exr_with_preview(
                &path,
                &path.with_extension("png"),
                &rendered.image,
                &rendered.info,
            )?;
        } else {
            outputs.png_preview(&path, &rendered.image)?;
        }
        Ok(outputs.commit()?)
    }

    /// One line on what a frame cost: strands, curves, backend, film, samples, threads, times and ray counts.
    pub fn summary(&self, stats: &RenderStats) -> String {
        let s = &self.settings;
        let [width, height] = s.film.resolution;
        let samples = match (s.adaptive, &self.denoised) {
            (_, Some(d)) => format!("denoised rounds from {} to at most {} spp", d.first, d.max),
            // Each pixel traces its samples' camera rays and, for the centre AOVs, one centre ray.
            (Some(a), None) => {
                let pixels = u64::from(self.region.width()) * u64::from(self.region.height());
                let centre = if s.film.traces_centre_ray() {
                    pixels
                } else {
                    0
                };
                let mean = stats.rays.camera.saturating_sub(centre) as f64 / pixels.max(1) as f64;
                format!("adaptive {}..{} spp (mean {mean:.1})", a.min, a.max)
            }
            (None, None) => format!("{} spp", s.film.spp),
        };
        // Dual scattering's strand counts (ray traced; the maps' lookups are on the maps' line) and tables.
        // The tables are asked for only under dual scattering: asking builds them (~50 ms).
        let dual = s
            .integrator
            .dual()
            .then(|| self.frame.material.dual())
            .flatten();
        let counted = match dual {
            Some(d) if stats.rays.counted > 0 => format!(
                ", {} strand counts over {} strands; dual-scattering tables {:.3} s",
                stats.rays.counted,
                stats.rays.crossed,
                d.build_seconds()
            ),
            Some(d) => format!("; dual-scattering tables {:.3} s", d.build_seconds()),
            None => String::new(),
        };
        format!(
            "{} strands ({} curves, {} backend), {width}x{height}, {samples}, {} threads: load {:.2} s, build {:.2} \
             s, render {:.2} s ({:.2} Mrays/s: {} camera, {} shadow, {} material rays{counted})",
            self.frame.strands.strand_count(),
            self.frame.curves.name(),
            self.frame.backend.name(),
            self.threads(),
            self.frame.load_seconds,
            self.frame.build_seconds(),
            stats.seconds,
            stats.rays.total() as f64 / stats.seconds / 1e6,
            stats.rays.camera,
            stats.rays.shadow,
            stats.rays.material,
        )
    }

    /// Whether the frames render with deep opacity maps.
    pub fn uses_maps(&self) -> bool {
        self.settings.shadows.mode == ShadowMode::DeepOpacity
    }
}

/// Checks, before anything is loaded or rendered, that every output of `request` can be written (each animation
/// frame's image and preview, the shadow-map directory); whether the images are EXRs (`false` for PNG or none).
fn check_outputs(request: &Request) -> Result<bool, JobError> {
    let exr_output = match &request.output {
        Some(output) => {
            let exr = match image::extension(output).as_deref() {
                Some("exr") => true,
                Some("png") => false,
                _ => {
                    return Err(JobError::Invalid(format!(
                        "{}: output must end in .exr or .png",
                        output.display()
                    )))
                }
            };
            // Every output path is checked before anything is loaded or rendered: writable, and neither a file
            // the scene reads (an output named like the environment map overwrote it) nor another output of the
            // run (`x.png` as the output is also the EXR's preview name only for an EXR output).
            let inputs = request.scene.input_files();
            for f in frame_numbers(&request.frames) {
                let path = farm::frame_path(output, f);
                let mut outputs = vec![path.clone()];
                if exr {
                    outputs.push(path.with_extension("png"));
                }
                for out in &outputs {
                    image::check_output(out)?;
                    if let Some(input) = inputs
                        .iter()
                        .find(|i| crate::util::input_file::same_target(i, out))
                    {
                        return Err(JobError::Invalid(format!(
                            "{}: the output would overwrite {}, which the scene reads",
                            out.display(),
                            input.display()
                        )));
                    }
                }
            }
            exr
        }
        None => false,
    };
    if let Some(dir) = &request.dump_shadow_maps {
        std::fs::create_dir_all(dir).map_err(|source| JobError::Io {
            path: dir.clone(),
            message: "cannot create the shadow-map directory",
            source,
        })?;
        image::check_output(&dir.join("map.exr"))?;
    }
    Ok(exr_output)
}

/// What ties a job's tiles together: the scene as rendered (after overrides) without the way its paths were
/// spelled (`sc.toml` and `./sc.toml` are one job), and the content of every file it reads (a hair file replaced
/// between two tiles, under the same path, is another job).
fn job_identity(scene: &Scene) -> Result<String, JobError> {
    let mut bare = scene.clone();
    bare.source = PathBuf::new();
    bare.base_dir = PathBuf::new();
    if bare.hair.file.is_some() {
        bare.hair.file = Some(PathBuf::new());
    }
    if bare.environment.map.is_some() {
        bare.environment.map = Some(PathBuf::new());
    }
    let mut text = format!("{bare:?}");
    for path in scene.input_files() {
        let hash = crate::util::hash::file_hash(&path).map_err(|source| JobError::Io {
            path: path.clone(),
            message: "cannot read it to identify the job",
            source,
        })?;
        text.push_str(&format!("\n{hash:016x}"));
    }
    Ok(text)
}

fn frame_numbers(frames: &Option<RangeInclusive<i32>>) -> Vec<Option<i32>> {
    match frames {
        Some(r) => r.clone().map(Some).collect(),
        None => vec![None],
    }
}

/// Renders a whole scene once with its own settings (auto's plan under `quality.mode = "auto"`), on `threads`
/// workers, without writing anything: the sequence of `cuticle render` for tests and studies.
pub fn render_scene(
    scene: Scene,
    fixed: Fixed,
    threads: Option<usize>,
) -> Result<(Job, Rendered), JobError> {
    let job = Job::prepare(Request {
        scene,
        fixed,
        threads,
        max_memory: None,
        part: Part::Full,
        frames: None,
        output: None,
        dump_shadow_maps: None,
        denoise: None,
        progress: false,
    })?;
    let rendered = job.render(None, None)?;
    Ok((job, rendered))
}

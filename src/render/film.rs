//! The film: the channels of a rendered frame (beauty and AOVs), the per-pixel sums of camera samples, and the
//! assembly of rendered tiles into one [`Image`].
//!
//! Channels are found by name ([`channel`], evaluated at compile time), never by a hand-kept index, so adding or
//! reordering a channel in [`CHANNELS`] cannot silently write one pass into another.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;

use crate::bsdf::{Lobe, LobeValues};
use crate::image::Image;

use super::integrator::PathSample;
use super::settings::FilmConfig;

/// Channels of the film, in order: beauty RGBA, then AOVs as `layer.channel` (EXR naming).
///
/// - `diffuse`, `specular` and the lobe layers `lobe_R`, `lobe_TT`, `lobe_TRT`, `lobe_glint` split the light
///   leaving the first shading point by the lobe it went through (Lambert shapes count as diffuse):
///   R + TT + TRT + glint = specular, and diffuse + specular = direct + indirect.
/// - `direct` (light scattered once) and `indirect` (more than once); beauty = direct + indirect + what the camera
///   sees of emitters and the background.
/// - `shadow.Y`: the fraction of the first shading point's light-sample contributions that its shadow rays let
///   through (1 where nothing was lit or nothing was hit).
/// - `albedo`: a one-sample estimate of the first shading point's directional albedo (f cos θ / pdf).
/// - `depth.Z`, `tangent`, `strand.id`: from one unfiltered ray through the pixel centre (a depth or id averaged
///   across an edge would name no real surface); depth is +∞, tangent 0 and id −1 where it misses, tangent 0 and
///   id −1 where it sees a shape.
/// - `spp`: the camera samples the pixel took (the film's spp, or what adaptive sampling chose for it).
pub const CHANNELS: [&str; 38] = [
    "R",
    "G",
    "B",
    "A",
    "diffuse.R",
    "diffuse.G",
    "diffuse.B",
    "specular.R",
    "specular.G",
    "specular.B",
    "lobe_R.R",
    "lobe_R.G",
    "lobe_R.B",
    "lobe_TT.R",
    "lobe_TT.G",
    "lobe_TT.B",
    "lobe_TRT.R",
    "lobe_TRT.G",
    "lobe_TRT.B",
    "lobe_glint.R",
    "lobe_glint.G",
    "lobe_glint.B",
    "direct.R",
    "direct.G",
    "direct.B",
    "indirect.R",
    "indirect.G",
    "indirect.B",
    "shadow.Y",
    "albedo.R",
    "albedo.G",
    "albedo.B",
    "depth.Z",
    "tangent.X",
    "tangent.Y",
    "tangent.Z",
    "strand.id",
    "spp",
];

/// The layer channel `channel` belongs to: its name up to the first `.` (`depth.Z` → `depth`, `spp` → `spp`), and
/// `beauty` for R, G, B and A.
pub fn layer_of(channel: &str) -> &str {
    match channel {
        "R" | "G" | "B" | "A" => "beauty",
        c => c.split('.').next().unwrap_or(c),
    }
}

/// The AOV layers of [`CHANNELS`] (every layer but the beauty), each once, in channel order: the names
/// `film.aovs` takes.
pub fn aov_layers() -> Vec<&'static str> {
    let mut layers: Vec<&'static str> = Vec::new();
    for c in CHANNELS {
        let layer = layer_of(c);
        if layer != "beauty" && !layers.contains(&layer) {
            layers.push(layer);
        }
    }
    layers
}

/// The layers filled by the unfiltered ray through the pixel centre ([`write_centre`]).
pub const CENTRE_LAYERS: [&str; 3] = ["depth", "tangent", "strand"];

/// The channels a frame keeps: the beauty and the AOV layers `film.aovs` names, as indices into [`CHANNELS`] in
/// its order. Tiles store only these (a pixel's other channels are computed and dropped at once): on the peer
/// scene, which keeps the beauty alone, its tiles hold 4 floats a pixel instead of 38.
#[derive(Debug, Clone)]
pub(super) struct Layout {
    keep: std::sync::Arc<[usize]>,
}

impl Layout {
    /// The channels `film` keeps.
    pub(super) fn new(film: &FilmConfig) -> Layout {
        let keep: Vec<usize> = (0..CHANNELS.len())
            .filter(|&c| {
                let layer = layer_of(CHANNELS[c]);
                layer == "beauty" || film.keeps_aov(layer)
            })
            .collect();
        Layout { keep: keep.into() }
    }

    /// How many.
    pub(super) fn len(&self) -> usize {
        self.keep.len()
    }

    /// Their names.
    pub(super) fn names(&self) -> Vec<String> {
        self.keep.iter().map(|&c| CHANNELS[c].to_string()).collect()
    }
}

/// `image` (of [`CHANNELS`]) with only the channels `film` keeps ([`Layout`]): what the tiles' own selection must
/// give.
#[cfg(test)]
fn select_layers(image: Image, film: &FilmConfig) -> Image {
    let keep = Layout::new(film).keep;
    if keep.len() == image.channels.len() {
        return image;
    }
    let names = keep.iter().map(|&c| image.channels[c].clone()).collect();
    let mut out = Image::new(image.width, image.height, names);
    let (from, to) = (image.channels.len(), keep.len());
    for (src, dst) in image
        .data
        .chunks_exact(from)
        .zip(out.data.chunks_exact_mut(to))
    {
        for (d, &c) in dst.iter_mut().zip(keep.iter()) {
            *d = src[c];
        }
    }
    out
}

/// Index of channel `name` in [`CHANNELS`]. In a `const` it fails the build when the name is not a channel.
pub const fn channel(name: &str) -> usize {
    let mut i = 0;
    while i < CHANNELS.len() {
        if str_eq(CHANNELS[i], name) {
            return i;
        }
        i += 1;
    }
    panic!("no such film channel");
}

const fn str_eq(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

/// Channels written from the camera samples' sums ([`PixelSums::write`]): each layer's first channel.
mod at {
    use super::channel;
    pub const BEAUTY: usize = channel("R");
    pub const ALPHA: usize = channel("A");
    pub const DIFFUSE: usize = channel("diffuse.R");
    pub const SPECULAR: usize = channel("specular.R");
    pub const LOBE_R: usize = channel("lobe_R.R");
    pub const LOBE_TT: usize = channel("lobe_TT.R");
    pub const LOBE_TRT: usize = channel("lobe_TRT.R");
    pub const LOBE_GLINT: usize = channel("lobe_glint.R");
    pub const DIRECT: usize = channel("direct.R");
    pub const INDIRECT: usize = channel("indirect.R");
    pub const SHADOW: usize = channel("shadow.Y");
    pub const ALBEDO: usize = channel("albedo.R");
    pub const DEPTH: usize = channel("depth.Z");
    pub const TANGENT: usize = channel("tangent.X");
    pub const STRAND: usize = channel("strand.id");
    pub const SPP: usize = channel("spp");
}

/// Camera samples with a NaN or infinite value, left out of their pixels since the process started.
static DROPPED: AtomicU64 = AtomicU64::new(0);

/// How many camera samples had a NaN or infinite value in any channel and were left out of their pixel, since the
/// process started (read it before and after a render for that render's count; `render` prints it as a warning).
///
/// The guard behind the validation bounds: scene and file parameters are bounded so that no sample should ever be
/// non-finite, but one that is would turn its whole pixel (and, through the filter, its neighbours) into NaN in
/// every output. Such a sample is dropped and the pixel averages the samples that remain, a bias far smaller
/// than a NaN pixel and counted so it is never silent.
pub fn dropped_samples() -> u64 {
    DROPPED.load(Ordering::Relaxed)
}

/// The film accumulators of one pixel (sums over its camera samples); a [`super::PixelSampling`] strategy adds
/// each sample it takes.
#[derive(Default)]
pub struct PixelSums {
    /// Samples left out because a value was not finite.
    dropped: u32,
    beauty: Vec3,
    alpha: f32,
    lobes: LobeValues,
    direct: Vec3,
    indirect: Vec3,
    lit: f32,
    unshadowed: f32,
    albedo: Vec3,
}

/// What takes a pixel's camera samples as a sampling strategy draws them: the pixel's own sums
/// ([`PixelSums`], filter importance sampling) or its splats onto its neighbours
/// ([`super::splat::SourceSums`]).
pub trait Accumulate {
    /// Adds one camera sample.
    fn add(&mut self, s: &PathSample);
}

/// How many per-sample values the film sums ([`quantities`]).
pub const QUANTITIES: usize = 30;

/// Where each value starts in [`quantities`]: the one layout the sample's values, the pixel's sums
/// ([`PixelSums::from_quantities`]) and the layers' needs ([`quantities_of`]) are read with.
mod q {
    pub const BEAUTY: usize = 0;
    pub const ALPHA: usize = 3;
    /// The lobes R, TT, TRT, glint, diffuse ([`crate::bsdf::Lobe::ALL`]'s order), three each.
    pub const LOBES: usize = 4;
    pub const DIRECT: usize = 19;
    pub const INDIRECT: usize = 22;
    pub const LIT: usize = 25;
    pub const UNSHADOWED: usize = 26;
    pub const ALBEDO: usize = 27;
    pub const END: usize = 30;
}
const _: () = assert!(q::END == QUANTITIES);

/// Whether every value of `s` the film sums is finite: a sample that is not is dropped ([`dropped_samples`]).
pub(super) fn is_finite(s: &PathSample) -> bool {
    let l = &s.lobes;
    [s.beauty, s.direct, s.indirect, s.albedo]
        .iter()
        .all(|v| v.is_finite())
        && [l.r, l.tt, l.trt, l.glint, l.diffuse]
            .iter()
            .all(|v| v.is_finite())
        && (s.alpha + s.lit + s.unshadowed).is_finite()
}

/// Counts a dropped sample in [`dropped_samples`].
pub(super) fn count_dropped() {
    DROPPED.fetch_add(1, Ordering::Relaxed);
}

/// The values of `s` the film sums, at the offsets of [`q`]: beauty, alpha, the lobes, direct, indirect, lit,
/// unshadowed, albedo.
pub(super) fn quantities(s: &PathSample) -> [f32; QUANTITIES] {
    let mut values = [0.0; QUANTITIES];
    let mut put = |at: usize, v: &[f32]| values[at..at + v.len()].copy_from_slice(v);
    put(q::BEAUTY, &s.beauty.to_array());
    put(q::ALPHA, &[s.alpha]);
    for (k, lobe) in Lobe::ALL.into_iter().enumerate() {
        put(q::LOBES + 3 * k, &s.lobes.get(lobe).to_array());
    }
    put(q::DIRECT, &s.direct.to_array());
    put(q::INDIRECT, &s.indirect.to_array());
    put(q::LIT, &[s.lit]);
    put(q::UNSHADOWED, &[s.unshadowed]);
    put(q::ALBEDO, &s.albedo.to_array());
    values
}

/// The quantities ([`quantities`], by index) the channels `layout` keeps are made of, in order.
pub(super) fn quantities_read(layout: &Layout) -> Vec<usize> {
    let mut read = [false; QUANTITIES];
    for &c in layout.keep.iter() {
        if let Some(range) = quantities_of(layer_of(CHANNELS[c])) {
            read[range].fill(true);
        }
    }
    (0..QUANTITIES).filter(|&i| read[i]).collect()
}

/// Which of [`quantities`] layer `layer` is made of (`None`: it is not made from the samples).
fn quantities_of(layer: &str) -> Option<std::ops::Range<usize>> {
    Some(match layer {
        "beauty" => q::BEAUTY..q::LOBES,
        "diffuse" | "specular" | "lobe_R" | "lobe_TT" | "lobe_TRT" | "lobe_glint" => {
            q::LOBES..q::DIRECT
        }
        "direct" => q::DIRECT..q::INDIRECT,
        "indirect" => q::INDIRECT..q::LIT,
        "shadow" => q::LIT..q::ALBEDO,
        "albedo" => q::ALBEDO..q::END,
        _ => return None,
    })
}

impl Accumulate for PixelSums {
    fn add(&mut self, s: &PathSample) {
        if !is_finite(s) {
            self.dropped += 1;
            count_dropped();
            return;
        }
        self.beauty += s.beauty;
        self.alpha += s.alpha;
        for lobe in Lobe::ALL {
            *self.lobes.get_mut(lobe) += s.lobes.get(lobe);
        }
        self.direct += s.direct;
        self.indirect += s.indirect;
        self.lit += s.lit;
        self.unshadowed += s.unshadowed;
        self.albedo += s.albedo;
    }
}

impl PixelSums {
    /// Sums holding `values` (at the offsets of [`q`], as [`quantities`] makes them), nothing dropped.
    pub(super) fn from_quantities(values: &[f32; QUANTITIES]) -> PixelSums {
        let v = |at: usize| Vec3::new(values[at], values[at + 1], values[at + 2]);
        let mut lobes = LobeValues::default();
        for (k, lobe) in Lobe::ALL.into_iter().enumerate() {
            *lobes.get_mut(lobe) = v(q::LOBES + 3 * k).into();
        }
        PixelSums {
            dropped: 0,
            beauty: v(q::BEAUTY),
            alpha: values[q::ALPHA],
            lobes,
            direct: v(q::DIRECT),
            indirect: v(q::INDIRECT),
            lit: values[q::LIT],
            unshadowed: values[q::UNSHADOWED],
            albedo: v(q::ALBEDO),
        }
    }

    /// Writes the averaged pixel into `pixel` (all of [`CHANNELS`]; the pixel-centre channels are
    /// [`write_centre`]'s).
    pub(super) fn write(&self, spp: u32, pixel: &mut [f32]) {
        // The mean of the samples kept (all of them but in a bug: see `dropped_samples`).
        let kept = spp.saturating_sub(self.dropped);
        self.write_scaled(if kept > 0 { 1.0 / kept as f32 } else { 0.0 }, pixel);
        pixel[at::SPP] = spp as f32;
    }

    /// Writes the sums times `k` into `pixel`'s channels written from the samples (all of [`CHANNELS`] but the
    /// pixel-centre ones and `spp`): the pixel's mean when `k` is one over its samples' count or weight.
    pub(super) fn write_scaled(&self, k: f32, pixel: &mut [f32]) {
        let l = self.lobes.scaled(k);
        let specular = l.r + l.tt + l.trt + l.glint;
        let shadow = if self.unshadowed > 0.0 {
            self.lit / self.unshadowed
        } else {
            1.0
        };
        let mut put = |at: usize, v: &[f32]| pixel[at..at + v.len()].copy_from_slice(v);
        put(at::BEAUTY, &(self.beauty * k).to_array());
        put(at::ALPHA, &[self.alpha * k]);
        for (at, v) in [
            (at::DIFFUSE, l.diffuse.into()),
            (at::SPECULAR, specular.into()),
            (at::LOBE_R, l.r.into()),
            (at::LOBE_TT, l.tt.into()),
            (at::LOBE_TRT, l.trt.into()),
            (at::LOBE_GLINT, l.glint.into()),
            (at::DIRECT, self.direct * k),
            (at::INDIRECT, self.indirect * k),
            (at::ALBEDO, self.albedo * k),
        ] {
            put(at, &v.to_array());
        }
        put(at::SHADOW, &[shadow]);
    }
}

/// Whether channel `c` of [`CHANNELS`] is written from the camera samples ([`PixelSums::write_scaled`]), not from
/// the pixel's own count or centre ray.
pub(super) fn from_samples(c: usize) -> bool {
    !(c == at::SPP
        || c == at::DEPTH
        || (at::TANGENT..at::TANGENT + 3).contains(&c)
        || c == at::STRAND)
}

/// Writes what one unfiltered ray through the pixel centre found: camera depth, unit tangent and strand id
/// (+∞, 0 and −1 where it missed).
pub(super) fn write_centre(depth: f32, tangent: Vec3, strand: f32, pixel: &mut [f32]) {
    pixel[at::DEPTH] = depth;
    pixel[at::TANGENT..at::TANGENT + 3].copy_from_slice(&tangent.to_array());
    pixel[at::STRAND] = strand;
}

/// A rectangle of pixels rendered as one unit of parallel work: `x0..x1` × `y0..y1`, the channels its [`Layout`]
/// keeps interleaved.
pub(super) struct Tile {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
    layout: Layout,
    pub pixels: Vec<f32>,
}

impl Tile {
    /// A zeroed tile keeping `layout`'s channels.
    pub(super) fn new(x0: u32, y0: u32, x1: u32, y1: u32, layout: &Layout) -> Tile {
        let n = ((x1 - x0) * (y1 - y0)) as usize * layout.keep.len();
        Tile {
            x0,
            y0,
            x1,
            y1,
            layout: layout.clone(),
            pixels: vec![0.0; n],
        }
    }

    /// Sets pixel (`x`, `y`) (image coordinates inside the tile): `fill` writes it as all of [`CHANNELS`] (starting
    /// from zeros), the tile keeps its layout's.
    #[inline]
    pub(super) fn set_pixel(&mut self, x: u32, y: u32, fill: impl FnOnce(&mut [f32])) {
        let mut full = [0.0f32; CHANNELS.len()];
        fill(&mut full);
        let nc = self.layout.keep.len();
        let o = (((y - self.y0) * (self.x1 - self.x0) + (x - self.x0)) as usize) * nc;
        for (d, &c) in self.pixels[o..o + nc]
            .iter_mut()
            .zip(self.layout.keep.iter())
        {
            *d = full[c];
        }
    }
}

/// Writes `pixel`'s channels taken from samples ([`from_samples`], all of [`CHANNELS`] given) into pixel (`x`, `y`)
/// of `image`, which holds `layout`'s channels: a splatted pixel finished after its tiles were assembled.
pub(super) fn write_from_samples(
    image: &mut Image,
    x: u32,
    y: u32,
    pixel: &[f32; CHANNELS.len()],
    layout: &Layout,
) {
    let nc = layout.keep.len();
    let o = (y as usize * image.width + x as usize) * nc;
    for (d, &c) in image.data[o..o + nc].iter_mut().zip(layout.keep.iter()) {
        if from_samples(c) {
            *d = pixel[c];
        }
    }
}

/// The frame of `width` × `height` pixels assembled from its tiles, with the channels of their `layout`.
pub(super) fn assemble(width: u32, height: u32, tiles: &[Tile], layout: &Layout) -> Image {
    let names = layout.names();
    let nc = names.len();
    let mut image = Image::new(width as usize, height as usize, names);
    for tile in tiles {
        debug_assert_eq!(tile.layout.keep, layout.keep);
        let tw = (tile.x1 - tile.x0) as usize;
        for (row, chunk) in tile.pixels.chunks(tw * nc).enumerate() {
            let o = ((tile.y0 as usize + row) * width as usize + tile.x0 as usize) * nc;
            image.data[o..o + chunk.len()].copy_from_slice(chunk);
        }
    }
    image
}

#[cfg(test)]
mod tests {

    #[test]
    fn aov_layers_cover_every_channel_once() {
        let layers = aov_layers();
        assert_eq!(layers.len(), 14, "{layers:?}");
        for c in CHANNELS {
            let l = layer_of(c);
            assert!(l == "beauty" || layers.contains(&l), "{c}");
        }
        for l in CENTRE_LAYERS {
            assert!(layers.contains(&l), "{l}");
        }
    }

    #[test]
    fn select_layers_keeps_the_beauty_and_the_chosen_layers_in_order() {
        let mut image = Image::new(2, 1, CHANNELS.iter().map(|c| c.to_string()).collect());
        for (i, v) in image.data.iter_mut().enumerate() {
            *v = i as f32;
        }
        let film = |aovs: &[&str]| FilmConfig {
            aovs: aovs.iter().map(|a| a.to_string()).collect(),
            ..FilmConfig::default()
        };
        assert_eq!(select_layers(image.clone(), &FilmConfig::default()), image);
        let some = select_layers(image.clone(), &film(&["spp", "depth"]));
        assert_eq!(some.channels, ["R", "G", "B", "A", "depth.Z", "spp"]);
        let n = CHANNELS.len() as f32;
        let depth = at::DEPTH as f32;
        assert_eq!(
            some.pixel(1, 0),
            [n, n + 1.0, n + 2.0, n + 3.0, n + depth, 2.0 * n - 1.0]
        );
        assert!(film(&["depth"]).traces_centre_ray() && !film(&["albedo"]).traces_centre_ray());
        assert!(film(&["all"]).validate().is_ok() && film(&[]).validate().is_ok());
        assert!(film(&["all", "depth"]).validate().is_err());
        assert!(film(&["normal"])
            .validate()
            .unwrap_err()
            .contains("film.aovs"));
    }

    use super::*;

    #[test]
    fn channels_are_found_by_name_and_unique() {
        for (i, name) in CHANNELS.iter().enumerate() {
            assert_eq!(channel(name), i, "{name}");
        }
        assert_eq!(CHANNELS[at::DEPTH], "depth.Z");
        assert_eq!(CHANNELS[at::SHADOW], "shadow.Y");
    }

    #[test]
    fn every_channel_is_written_exactly_once() {
        // Fill the sums with distinct values, write a pixel over NaNs, and check no channel is left unwritten.
        let s = PathSample {
            beauty: Vec3::new(1.0, 2.0, 3.0),
            alpha: 1.0,
            direct: Vec3::splat(4.0),
            indirect: Vec3::splat(5.0),
            lit: 0.5,
            unshadowed: 1.0,
            albedo: Vec3::splat(0.25),
            ..Default::default()
        };
        let mut sums = PixelSums::default();
        sums.add(&s);
        sums.add(&s);
        let mut pixel = vec![f32::NAN; CHANNELS.len()];
        sums.write(2, &mut pixel);
        write_centre(7.0, Vec3::X, 3.0, &mut pixel);
        let unwritten: Vec<_> = CHANNELS
            .iter()
            .zip(&pixel)
            .filter(|(_, v)| v.is_nan())
            .map(|(c, _)| *c)
            .collect();
        assert!(unwritten.is_empty(), "{unwritten:?}");
        let get = |name: &str| pixel[channel(name)];
        assert_eq!(
            (get("R"), get("G"), get("B"), get("A")),
            (1.0, 2.0, 3.0, 1.0)
        );
        assert_eq!((get("direct.G"), get("indirect.B")), (4.0, 5.0));
        assert_eq!((get("shadow.Y"), get("albedo.R")), (0.5, 0.25));
        assert_eq!(
            (get("depth.Z"), get("tangent.X"), get("strand.id")),
            (7.0, 1.0, 3.0)
        );
    }

    #[test]
    fn a_samples_quantities_make_the_pixel_its_sums_make() {
        let s = PathSample {
            beauty: Vec3::new(1.0, 2.0, 3.0),
            alpha: 0.5,
            lobes: LobeValues {
                r: glam::Vec3A::new(4.0, 5.0, 6.0),
                tt: glam::Vec3A::new(7.0, 8.0, 9.0),
                trt: glam::Vec3A::new(10.0, 11.0, 12.0),
                glint: glam::Vec3A::new(13.0, 14.0, 15.0),
                diffuse: glam::Vec3A::new(16.0, 17.0, 18.0),
            },
            direct: Vec3::new(19.0, 20.0, 21.0),
            indirect: Vec3::new(22.0, 23.0, 24.0),
            lit: 0.25,
            unshadowed: 0.75,
            albedo: Vec3::new(0.1, 0.2, 0.3),
            ..Default::default()
        };
        let mut sums = PixelSums::default();
        sums.add(&s);
        let (mut a, mut b) = ([0.0; CHANNELS.len()], [0.0; CHANNELS.len()]);
        sums.write_scaled(1.0, &mut a);
        PixelSums::from_quantities(&quantities(&s)).write_scaled(1.0, &mut b);
        assert_eq!(a, b);
        // Every value has a place of its own.
        let mut sorted = quantities(&s).to_vec();
        sorted.sort_by(f32::total_cmp);
        sorted.dedup();
        assert_eq!(sorted.len(), QUANTITIES);
    }

    #[test]
    fn a_non_finite_sample_is_dropped_counted_and_the_rest_averaged() {
        let good = PathSample {
            beauty: Vec3::splat(2.0),
            alpha: 1.0,
            ..Default::default()
        };
        let mut bad = good;
        bad.lobes.tt = glam::Vec3A::new(0.0, f32::INFINITY, 0.0);
        let mut nan = good;
        nan.unshadowed = f32::NAN;
        let before = dropped_samples();
        let mut sums = PixelSums::default();
        for s in [&good, &bad, &nan, &good] {
            sums.add(s);
        }
        assert!(dropped_samples() - before >= 2);
        let mut pixel = vec![0.0; CHANNELS.len()];
        sums.write(4, &mut pixel);
        assert!(pixel.iter().all(|v| v.is_finite()), "{pixel:?}");
        assert_eq!((pixel[channel("R")], pixel[channel("A")]), (2.0, 1.0));
    }

    #[test]
    fn tiles_land_where_they_belong_with_the_channels_kept() {
        let film = |aovs: &[&str]| FilmConfig {
            aovs: aovs.iter().map(|a| a.to_string()).collect(),
            ..FilmConfig::default()
        };
        // Pixel (x, y) channel c holds 100 x + 1000 y + c in every channel of CHANNELS.
        let fill = |x: u32, y: u32| {
            move |p: &mut [f32]| {
                for (c, v) in p.iter_mut().enumerate() {
                    *v = (100 * x + 1000 * y) as f32 + c as f32;
                }
            }
        };
        let render = |layout: &Layout| {
            let mut a = Tile::new(0, 0, 2, 2, layout);
            let mut b = Tile::new(2, 0, 3, 2, layout);
            for y in 0..2 {
                a.set_pixel(0, y, fill(0, y));
                a.set_pixel(1, y, fill(1, y));
                b.set_pixel(2, y, fill(2, y));
            }
            assemble(3, 2, &[a, b], layout)
        };
        let everything = render(&Layout::new(&film(&["all"])));
        assert_eq!(everything.channels.len(), CHANNELS.len());
        assert_eq!(everything.get(2, 1, 5), 1205.0);
        assert_eq!(everything.get(1, 0, 0), 100.0);
        for aovs in [&[][..], &["spp", "depth"], &["lobe_TT"]] {
            let f = film(aovs);
            let kept = render(&Layout::new(&f));
            assert_eq!(kept, select_layers(everything.clone(), &f), "{aovs:?}");
        }
        assert_eq!(
            render(&Layout::new(&film(&[]))).channels,
            ["R", "G", "B", "A"]
        );
    }
}

//! Helpers shared by the integration tests: rendering whole frames, and finding the third-party data ([`data`]).
//! Each test binary uses some of them.
#![allow(dead_code)]

pub mod data;

use cuticle::image::Image;
use cuticle::quality::Fixed;
use cuticle::render::RenderStats;
use cuticle::scene::Scene;

/// Renders `scene` (hair, lights and all) on a pool of `threads` threads, through the render job the `render`
/// command runs ([`cuticle::job`]), asserting no ray was refused.
pub fn render_scene(scene: &Scene, threads: usize) -> Image {
    render_scene_with_stats(scene, threads).0
}

/// [`render_scene`] with the render's statistics (ray counts and times).
pub fn render_scene_with_stats(scene: &Scene, threads: usize) -> (Image, RenderStats) {
    let (_, rendered) =
        cuticle::job::render_scene(scene.clone(), Fixed::default(), Some(threads)).unwrap();
    assert_eq!(rendered.stats.rays.rejected, 0);
    (rendered.image, rendered.stats)
}

/// How many values of two equally long pixel buffers differ in any bit (the thread-count and tile-split
/// determinism checks: 0 expected).
pub fn bit_differences(a: &[f32], b: &[f32]) -> usize {
    assert_eq!(a.len(), b.len(), "buffers of different sizes");
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count()
}

/// Channel `name` of `image`, row by row; panics naming a missing channel.
pub fn channel(image: &Image, name: &str) -> Vec<f32> {
    let c = image
        .channel_index(name)
        .unwrap_or_else(|| panic!("no channel {name}"));
    (0..image.height)
        .flat_map(|y| (0..image.width).map(move |x| (x, y)))
        .map(|(x, y)| image.get(x, y, c))
        .collect()
}

/// The names of the files directly in `dir`, sorted.
pub fn listing(dir: &std::path::Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

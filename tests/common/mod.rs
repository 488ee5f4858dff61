//! Helpers shared by the integration tests: rendering whole frames, and finding the third-party data ([`data`]).
//! Each test binary uses some of them.
#![allow(dead_code)]

pub mod data;

use cuticle::image::Image;
use cuticle::render::{thread_pool, Frame, Options, RenderStats};
use cuticle::scene::Scene;

/// Renders `scene` (hair, lights and all) on a pool of `threads` threads, through the same frame set-up as the
/// `render` command, asserting no ray was refused.
pub fn render_scene(scene: &Scene, threads: usize) -> Image {
    render_scene_with_stats(scene, threads).0
}

/// [`render_scene`] with the render's statistics (ray counts and times).
pub fn render_scene_with_stats(scene: &Scene, threads: usize) -> (Image, RenderStats) {
    let frame = Frame::load(scene.resolve().unwrap()).unwrap();
    let pool = thread_pool(Some(threads)).unwrap();
    let (image, stats) = pool.install(|| frame.render(Options::default()));
    assert_eq!(stats.rays.rejected, 0);
    (image, stats)
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

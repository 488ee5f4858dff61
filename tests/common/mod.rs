//! Helpers shared by the integration tests that render whole frames.

use cuticle::accel::embree::EmbreeTracer;
use cuticle::image::Image;
use cuticle::render::{self, Options};
use cuticle::scene::Scene;

/// Renders `scene` (hair, lights and all) on a pool of `threads` threads, asserting no ray was refused.
pub fn render_scene(scene: &Scene, threads: usize) -> Image {
    let strands = render::load_strands(scene).unwrap();
    let tracer = EmbreeTracer::new(&strands, scene.hair.curves).unwrap();
    let lights = scene.build_lights().unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (image, stats) =
        pool.install(|| render::render(scene, &strands, &tracer, &lights, Options::default()));
    assert_eq!(stats.rays.rejected, 0);
    image
}

//! Whole-frame properties: determinism across thread counts, and that the default scene shows hair.

use cuticle::accel::embree::EmbreeTracer;
use cuticle::render::{self, Options};
use cuticle::scene::Scene;

fn render_with_threads(scene: &Scene, threads: usize) -> Vec<f32> {
    let strands = render::load_strands(scene).unwrap();
    let tracer = EmbreeTracer::new(&strands, scene.hair.curves).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let (image, stats) =
        pool.install(|| render::render(scene, &strands, &tracer, Options::default()));
    assert_eq!(stats.rejected_rays, 0);
    image.data
}

/// The default scene, smaller so the test stays fast; everything else (model, lights, shadows) as shipped.
fn small_default() -> Scene {
    let mut scene = Scene::default_scene();
    scene.film.resolution = [96, 80];
    scene.film.spp = 4;
    scene
}

#[test]
fn one_and_two_threads_give_bit_identical_pixels() {
    let scene = small_default();
    let a = render_with_threads(&scene, 1);
    let b = render_with_threads(&scene, 2);
    assert_eq!(a.len(), b.len());
    let differing = a
        .iter()
        .zip(&b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    assert_eq!(
        differing, 0,
        "{differing} channel values differ between 1 and 2 threads"
    );
}

#[test]
fn a_different_seed_gives_a_different_image() {
    // Guards the determinism test against a renderer that ignores its sample streams.
    let scene = small_default();
    let mut other = scene.clone();
    other.film.seed = 7;
    assert_ne!(
        render_with_threads(&scene, 2),
        render_with_threads(&other, 2)
    );
}

#[test]
fn the_default_scene_shows_lit_hair() {
    let scene = small_default();
    let data = render_with_threads(&scene, 2);
    let nc = render::CHANNELS.len();
    let pixels: Vec<&[f32]> = data.chunks(nc).collect();
    let covered = pixels.iter().filter(|p| p[3] > 0.5).count();
    assert!(
        covered > pixels.len() / 10,
        "hair covers {covered} of {} pixels",
        pixels.len()
    );
    assert!(pixels
        .iter()
        .all(|p| p[..4].iter().all(|v| v.is_finite() && *v >= 0.0)));
    let lit = pixels
        .iter()
        .filter(|p| p[3] > 0.5 && p[0] + p[1] + p[2] > 0.05)
        .count();
    assert!(
        lit > covered / 2,
        "{lit} of {covered} hair pixels receive light"
    );
    // Depth is finite exactly where the centre ray hit a strand, with a strand id there.
    for p in &pixels {
        assert_eq!(p[4].is_finite(), p[8] >= 0.0);
    }
}

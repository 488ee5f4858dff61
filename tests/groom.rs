//! A groom on its head, from USD: the stage's camera places the view, the head hides and shadows the hair, the
//! hair shadows the head, the scalp does not shadow the roots, both backends draw the same frame, and strands from
//! USD render as the same strands from a `.hair` file do, bit for bit.
//!
//! The stage is `tests/data/usd/groom.usda` (36 strands on a 352-triangle head, written by Pixar's usd-core with
//! `scripts/usd-test-data.py`).

mod common;

use std::path::{Path, PathBuf};

use cuticle::hair::HairModel;
use cuticle::image::Image;
use cuticle::scene::Scene;

use common::{bit_differences, channel, render_scene};

fn stage_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/usd")
}

/// A denser groom than the stage's 36 strands, on the same head (unit sphere about (0, 1.5, 0)): 1 200 strands
/// of 8 points rooted on its top (polar angle up to 75°), growing out along the normal and drooping, as
/// `.usda` text. The roots lie on the sphere, which the head's 352 flat triangles approximate from inside, so a
/// root sits just outside the mesh between its vertices and on it at them.
fn dense_groom() -> String {
    let (mut counts, mut points) = (Vec::new(), Vec::new());
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let n = 1200;
    for i in 0..n {
        let z = 1.0 - (1.0 - 75f32.to_radians().cos()) * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - z * z).sqrt();
        let phi = golden * i as f32;
        let normal = [r * phi.cos(), z, r * phi.sin()];
        counts.push("8".to_string());
        for k in 0..8 {
            let s = 0.05 * k as f32;
            let p = [
                normal[0] * (1.0 + s),
                1.5 + normal[1] * (1.0 + s) - 0.4 * s * s,
                normal[2] * (1.0 + s),
            ];
            points.push(format!("({:?}, {:?}, {:?})", p[0], p[1], p[2]));
        }
    }
    format!(
        "#usda 1.0\ndef BasisCurves \"Hair\"\n{{\nuniform token type = \"cubic\"\nuniform token basis = \"bspline\"\n\
         uniform token wrap = \"pinned\"\nint[] curveVertexCounts = [{}]\npoint3f[] points = [{}]\n\
         float[] widths = [0.012] (interpolation = \"constant\")\n}}\n",
        counts.join(", "),
        points.join(", ")
    )
}

/// The groom scene: the dense groom on the stage's head (when `head`), the camera from `groom.usda`; `extra`
/// appended (lights, overrides).
fn groom(head: bool, extra: &str) -> Scene {
    let dir = std::env::temp_dir().join(format!("cuticle-groom-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let hair = dir.join("dense.usda");
    if !hair.exists() {
        cuticle::util::atomic_file::write(&hair, dense_groom().as_bytes()).unwrap();
    }
    let stage = stage_dir().join("groom.usda");
    let shape = if head {
        format!("[[shape]]\nkind = \"usd\"\nfile = {stage:?}\nprim = \"/World/Head/Skin\"\n")
    } else {
        String::new()
    };
    let text = format!(
        "[hair]\nfile = {hair:?}\n\n[camera]\nusd = {stage:?}\n\n\
         [film]\nresolution = [80, 80]\nspp = 4\naovs = [\"all\"]\n\n[material]\nmodel = \"chiang\"\n\n{shape}\n{extra}"
    );
    Scene::parse(&text, &dir.join("groom.toml"), &dir).unwrap_or_else(|e| panic!("{e}"))
}

/// Pixels whose first shading point is a fibre (light through the hair lobes, none through a Lambert shape).
fn hair_pixels(image: &Image) -> Vec<usize> {
    let spec = channel(image, "specular.G");
    let diffuse = channel(image, "diffuse.G");
    (0..spec.len())
        .filter(|&i| spec[i] > 0.0 && diffuse[i] == 0.0)
        .collect()
}

/// Pixels whose first shading point is the head: diffuse light and no hair lobe.
fn head_pixels(image: &Image) -> Vec<usize> {
    let spec = channel(image, "specular.G");
    let diffuse = channel(image, "diffuse.G");
    (0..spec.len())
        .filter(|&i| diffuse[i] > 0.0 && spec[i] == 0.0)
        .collect()
}

fn mean_at(image: &Image, name: &str, pixels: &[usize]) -> f64 {
    let c = channel(image, name);
    pixels.iter().map(|&i| f64::from(c[i])).sum::<f64>() / pixels.len().max(1) as f64
}

const SUN_ABOVE: &str =
    "[[light]]\nkind = \"distant\"\ndirection = [0.0, -1.0, 0.0]\nirradiance = 3.0\n";
const SUN_BELOW: &str =
    "[[light]]\nkind = \"distant\"\ndirection = [0.0, 1.0, 0.0]\nirradiance = 3.0\n";

#[test]
fn the_stage_places_the_camera_and_the_head_hides_the_hair_behind_it() {
    let scene = groom(true, SUN_ABOVE);
    let stage = cuticle::usd::read(&stage_dir().join("groom.usda"), None, 0.005).unwrap();
    let cam = stage.camera.unwrap();
    let spec = scene.resolve().unwrap();
    assert_eq!(spec.settings.camera.position, Some(cam.position.to_array()));
    assert_eq!(spec.settings.camera.fov, cam.vertical_fov_degrees);
    assert_eq!(spec.shapes.meshes().len(), 1);

    let with_head = render_scene(&scene, 2);
    let without = render_scene(&groom(false, SUN_ABOVE), 2);
    let ids = |image: &Image| {
        channel(image, "strand.id")
            .iter()
            .filter(|&&id| id >= 0.0)
            .count()
    };
    let (seen_with, seen_without) = (ids(&with_head), ids(&without));
    // The strands behind the head's silhouette are hidden by it: the centre rays see fewer hair pixels.
    assert!(
        seen_with > 0 && (seen_with as f64) < 0.9 * seen_without as f64,
        "hair pixels with the head {seen_with}, without {seen_without}"
    );
    let head = head_pixels(&with_head);
    assert!(head.len() > 30, "the head covers {} pixels", head.len());
    assert!(head_pixels(&without).is_empty());
    // Where the centre ray meets the head, its depth is in the depth AOV and no strand is named; with no head,
    // every pixel without a strand at its centre has no depth.
    let head_at_centre = |image: &Image| {
        let depth = channel(image, "depth.Z");
        let id = channel(image, "strand.id");
        (0..id.len())
            .filter(|&i| id[i] == -1.0 && depth[i].is_finite())
            .count()
    };
    assert!(
        head_at_centre(&with_head) >= 30,
        "{}",
        head_at_centre(&with_head)
    );
    assert_eq!(head_at_centre(&without), 0);
}

#[test]
fn the_head_shadows_the_hair_and_the_hair_shadows_the_head() {
    // Opacity 0: the hair casts no shadow, so only the head can shadow a strand.
    let clear = "[shadows]\nmode = \"raytraced\"\n";
    let transparent = |sun: &str, head: bool| {
        let mut s = groom(head, &format!("{sun}{clear}"));
        s.hair.opacity = Some(0.0);
        s
    };
    // Lit from below, the strands on top of the head are in its shadow (the tips that reach past its sides are
    // not); lit from above, nothing shadows them.
    let below = render_scene(&transparent(SUN_BELOW, true), 2);
    let below_headless = render_scene(&transparent(SUN_BELOW, false), 2);
    let above = render_scene(&transparent(SUN_ABOVE, true), 2);
    let hair = hair_pixels(&above);
    assert!(hair.len() > 200, "{} hair pixels", hair.len());
    let (lit_below, lit_below_headless, lit_above) = (
        mean_at(&below, "shadow.Y", &hair),
        mean_at(&below_headless, "shadow.Y", &hair),
        mean_at(&above, "shadow.Y", &hair),
    );
    assert!(
        lit_below < 0.6 && lit_below_headless > 0.99,
        "hair lit from below through the head: {lit_below}, without the head: {lit_below_headless}"
    );
    // The scalp does not shadow the roots: every strand lit from above sees the sun (no acne where hair meets
    // skin; `cuticle::shape`'s module doc says why none needs hiding).
    assert!(lit_above > 0.97, "hair lit from above: {lit_above}");

    // The hair shadows the head: opaque strands darken the scalp under them.
    let mut opaque = groom(true, &format!("{SUN_ABOVE}{clear}"));
    opaque.hair.opacity = Some(1.0);
    let shadowed = render_scene(&opaque, 2);
    let head = head_pixels(&above);
    let (under_opaque, under_clear) = (
        mean_at(&shadowed, "shadow.Y", &head),
        mean_at(&above, "shadow.Y", &head),
    );
    assert!(
        under_opaque < under_clear - 0.01,
        "the head's light with opaque hair {under_opaque}, with transparent hair {under_clear}"
    );
}

#[test]
fn embree_and_the_rust_bvh_render_the_groom_on_its_head_alike() {
    let embree = render_scene(&groom(true, SUN_ABOVE), 2);
    let mut scene = groom(true, SUN_ABOVE);
    scene.hair.backend = cuticle::accel::Backend::Bvh;
    let bvh = render_scene(&scene, 2);
    let (a, b) = (channel(&embree, "strand.id"), channel(&bvh, "strand.id"));
    let same = a.iter().zip(&b).filter(|(x, y)| x == y).count();
    assert!(
        same as f64 >= 0.99 * a.len() as f64,
        "{same} of {} centre rays agree",
        a.len()
    );
    let (da, db) = (channel(&embree, "depth.Z"), channel(&bvh, "depth.Z"));
    let close = da
        .iter()
        .zip(&db)
        .filter(|(x, y)| x == y || ((*x - *y).abs() <= 1e-4 * x.abs()))
        .count();
    assert!(
        close as f64 >= 0.99 * da.len() as f64,
        "{close} depths agree"
    );
    let mean = |im: &Image| channel(im, "G").iter().map(|&v| f64::from(v)).sum::<f64>();
    let (ma, mb) = (mean(&embree), mean(&bvh));
    assert!((ma - mb).abs() <= 0.01 * ma, "frame sums {ma} and {mb}");
}

/// A Cem Yuksel `.hair` file of `m` with its points and per-point thickness (flags: segments, points, thickness).
fn hair_file(m: &HairModel) -> Vec<u8> {
    let mut b = Vec::new();
    b.extend_from_slice(b"HAIR");
    b.extend_from_slice(&(m.strand_count() as u32).to_le_bytes());
    b.extend_from_slice(&(m.points.len() as u32).to_le_bytes());
    b.extend_from_slice(&(1u32 | 2 | 4).to_le_bytes());
    b.extend_from_slice(&0u32.to_le_bytes()); // default segments (a segments array follows)
    b.extend_from_slice(&1.0f32.to_le_bytes()); // default thickness
    b.extend_from_slice(&0.0f32.to_le_bytes()); // default transparency
    for c in [0.3f32, 0.2, 0.1] {
        b.extend_from_slice(&c.to_le_bytes()); // default colour
    }
    b.resize(128, 0);
    for s in 0..m.strand_count() {
        b.extend_from_slice(&((m.strand_range(s).len() - 1) as u16).to_le_bytes());
    }
    for p in &m.points {
        for x in p.to_array() {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    for r in &m.radius {
        b.extend_from_slice(&(2.0 * r).to_le_bytes());
    }
    b
}

/// `m` as pinned B-spline `BasisCurves` in `.usda` text: the points, widths = the file's thickness, and the colour
/// and opacity the `.hair` reader gives.
fn usda_file(m: &HairModel) -> String {
    let list = |v: Vec<String>| v.join(", ");
    let p3 = |p: [f32; 3]| format!("({:?}, {:?}, {:?})", p[0], p[1], p[2]);
    let counts = (0..m.strand_count())
        .map(|s| m.strand_range(s).len().to_string())
        .collect();
    format!(
        "#usda 1.0\ndef BasisCurves \"Hair\"\n{{\nuniform token type = \"cubic\"\nuniform token basis = \"bspline\"\n\
         uniform token wrap = \"pinned\"\nint[] curveVertexCounts = [{}]\npoint3f[] points = [{}]\n\
         float[] widths = [{}] (interpolation = \"vertex\")\n\
         color3f[] primvars:displayColor = [{}] (interpolation = \"vertex\")\n\
         float[] primvars:displayOpacity = [{}] (interpolation = \"vertex\")\n}}\n",
        list(counts),
        list(m.points.iter().map(|p| p3(p.to_array())).collect()),
        list(m.radius.iter().map(|r| format!("{:?}", 2.0 * r)).collect()),
        list(m.color.iter().map(|c| p3(*c)).collect()),
        list(m.transparency.iter().map(|t| format!("{:?}", 1.0 - t)).collect()),
    )
}

#[test]
fn strands_from_usd_render_as_the_same_strands_from_a_hair_file_bit_for_bit() {
    let source = cuticle::hair::load(&common::data::file("hair/straight.hair")).unwrap();
    // The first 300 strands, each point given its own thickness (straight.hair has none), written as a `.hair` and
    // read back: the model both files are made of.
    let n = 300.min(source.strand_count());
    let end = source.strand_offsets[n] as usize;
    let mut m = source.clone();
    m.points.truncate(end);
    m.strand_offsets.truncate(n + 1);
    m.radius = (0..end).map(|i| 0.02 + 1e-4 * (i % 5) as f32).collect();
    m.transparency.truncate(end);
    m.color.truncate(end);
    let dir = tempfile::tempdir().unwrap();
    let hair = dir.path().join("few.hair");
    std::fs::write(&hair, hair_file(&m)).unwrap();
    let model = cuticle::hair::load(&hair).unwrap();
    assert!(model.radius_from_file);
    std::fs::write(dir.path().join("few.usda"), usda_file(&model)).unwrap();
    // Each pixel its own samples: the check below that some pixel is mostly hair reads a thin strand's own
    // coverage, which a splat spreads over 3 × 3 pixels.
    let scene = |file: &str| {
        let text = format!(
            "[hair]\nfile = \"{file}\"\nopacity = 0.5\n\n[film]\nresolution = [48, 48]\nspp = 4\nreconstruction = \"importance\"\n\n\
             [material]\nmodel = \"chiang\"\n\n[integrator]\npath_length = 3\n\n{SUN_ABOVE}\n\
             [environment]\nradiance = [0.4, 0.4, 0.5]\n"
        );
        Scene::parse(&text, &dir.path().join("s.toml"), dir.path()).unwrap()
    };
    let from_hair = render_scene(&scene("few.hair"), 2);
    let from_usd = render_scene(&scene("few.usda"), 2);
    assert!(
        channel(&from_hair, "A").iter().any(|&a| a > 0.5),
        "the hair is in view"
    );
    assert_eq!(bit_differences(&from_hair.data, &from_usd.data), 0);
}

#[test]
fn the_memory_estimate_holds_the_head_and_its_tracer() {
    let spec = groom(true, SUN_ABOVE).resolve().unwrap();
    let triangles: usize = spec.shapes.meshes().iter().map(|m| m.triangles.len()).sum();
    let estimate = cuticle::render::budget::estimate_frame(&spec, 2, false).unwrap();
    assert!(
        estimate.meshes
            >= triangles as u64 * cuticle::render::budget::MESH_ACCEL_BYTES_PER_TRIANGLE,
        "{estimate:?} for {triangles} triangles"
    );
    let refused = estimate
        .check(estimate.total() - 1, "a test limit")
        .unwrap_err();
    assert!(refused.to_string().contains("meshes"), "{refused}");
}

#[test]
fn an_instanced_groom_is_checked_against_the_memory_limit_with_the_strands_it_makes() {
    // 4 000 instances of a 50-strand tuft from a file of a few kilobytes: 200 000 strands, 1.6 M points.
    let dir = tempfile::tempdir().unwrap();
    let mut tuft = String::new();
    for k in 0..50 {
        let x = 0.01 * k as f32;
        tuft += &format!("({x},0,0),({x},0.1,0),({x},0.2,0.01),({x},0.3,0.02),({x},0.4,0.03),({x},0.5,0.04),({x},0.6,0.05),({x},0.7,0.06),");
    }
    let positions: Vec<String> = (0..4000)
        .map(|i| format!("({},{},0)", i % 64, i / 64))
        .collect();
    let text = format!(
        "#usda 1.0\ndef PointInstancer \"Fur\" {{\n  rel prototypes = </Fur/Tuft>\n  int[] protoIndices = [{}]\n  \
         point3f[] positions = [{}]\n  def BasisCurves \"Tuft\" {{\n    uniform token basis = \"bspline\"\n    \
         int[] curveVertexCounts = [{}]\n    point3f[] points = [{}]\n  }}\n}}\n",
        vec!["0"; 4000].join(","),
        positions.join(","),
        vec!["8"; 50].join(","),
        tuft.trim_end_matches(',')
    );
    let stage = dir.path().join("fur.usda");
    std::fs::write(&stage, text).unwrap();
    let scene = format!(
        "[hair]\nfile = {stage:?}\n\n[camera]\nview = [0.0, 0.0, -1.0]\n\n[film]\nresolution = [32, 32]\nspp = 1\n"
    );
    let spec = Scene::parse(&scene, &dir.path().join("s.toml"), dir.path())
        .unwrap()
        .resolve()
        .unwrap();
    // The file's size alone estimates far less than the strands it makes.
    let before = cuticle::render::budget::estimate_frame(&spec, 2, false).unwrap();
    let made = cuticle::render::budget::estimate_frame_of(&spec, (200_000, 1_600_000), 2, false);
    assert!(
        made.total() > before.total() + (100 << 20),
        "{before:?} {made:?}"
    );
    let limit = (before.total() + made.total()) / 2;
    let e = match cuticle::render::Frame::load_within(spec, limit, "a test limit") {
        Ok(_) => panic!("a frame over the limit was built"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("a test limit"), "{e}");
}

#[test]
fn a_textured_head_mesh_renders_its_texture_as_its_albedo() {
    // textured.usda's camera sees x in [−0.5, 5.5] and y in [−0.1, 1.1] at the cards (z = 0): `Card` (x 0..2)
    // maps s = x / 2, t = y onto checker.png. One strand stands behind the camera, out of view.
    let dir = tempfile::tempdir().unwrap();
    let hair = dir.path().join("strand.usda");
    std::fs::write(
        &hair,
        "#usda 1.0\ndef BasisCurves \"H\" {\n  uniform token basis = \"bspline\"\n  int[] curveVertexCounts = [4]\n  \
         point3f[] points = [(0,0,20),(0,1,20),(0,2,20),(0,3,20)]\n}\n",
    )
    .unwrap();
    let stage = stage_dir().join("textured.usda");
    let text = format!(
        "[hair]\nfile = {hair:?}\n\n[camera]\nusd = {stage:?}\n\n[film]\nresolution = [300, 60]\nspp = 1\n\
         aovs = [\"all\"]\n\n[[shape]]\nkind = \"usd\"\nfile = {stage:?}\n\n[environment]\nradiance = [1.0, 1.0, 1.0]\n"
    );
    let scene = Scene::parse(&text, &dir.path().join("t.toml"), dir.path()).unwrap();
    let texture = cuticle::usd::read(&stage, None, 0.005).unwrap().meshes[0]
        .texture
        .clone()
        .unwrap();
    let image = render_scene(&scene, 2);
    let albedo = ["albedo.R", "albedo.G", "albedo.B"].map(|c| channel(&image, c));
    let mut checked = 0;
    for j in 0..60 {
        for i in 0..300 {
            let x = -0.5 + 6.0 * (i as f32 + 0.5) / 300.0;
            let y = 1.1 - 1.2 * (j as f32 + 0.5) / 60.0;
            // Inside the card, away from its edges (a pixel's centre ray lands within 1e-4 of (x, y)).
            if !(0.01..1.99).contains(&x) || !(0.01..0.99).contains(&y) {
                continue;
            }
            // The albedo channel is filtered over the pixel's samples: it must lie within what the texture
            // holds over the filter's footprint (±2 pixels, 0.04 in x and y).
            let (mut lo, mut hi) = (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY);
            for a in -4..=4 {
                for b in -4..=4 {
                    let (px, py) = (x + 0.01 * a as f32, y + 0.01 * b as f32);
                    let v = texture
                        .image
                        .lookup(glam::Vec2::new(px / 2.0, py), texture.wrap);
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            let got = glam::Vec3::from_array(albedo.each_ref().map(|c| c[j * 300 + i]));
            assert!(
                got.cmpge(lo - 1e-4).all() && got.cmple(hi + 1e-4).all(),
                "pixel ({i}, {j}) at ({x}, {y}): albedo {got}, texture from {lo} to {hi}"
            );
            checked += 1;
        }
    }
    assert!(checked > 4000, "{checked} pixels on the card");
}

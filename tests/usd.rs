//! The USD reader against files written by Pixar's library (`scripts/usd-test-data.py`, in `tests/data/usd/`)
//! and against stages the tests write as `.usda` text: formats agree, transforms land where hand maths says, a
//! `.hair` model written as pinned B-splines reads back bit for bit, and bad files fail with their name.

use std::path::{Path, PathBuf};

use cuticle::hair::{HairModel, Strands};
use cuticle::usd::{self, UsdLight, UsdStage};
use glam::Vec3;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/usd")
        .join(name)
}

/// Radius for curves without widths.
const R: f32 = 0.01;

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A stage with the file's name taken out of mesh names and warnings, to compare stages read from different files.
fn without_file(mut s: UsdStage) -> UsdStage {
    for m in &mut s.meshes {
        m.name = m.name.rsplit_once(':').unwrap().1.to_owned();
    }
    for w in &mut s.warnings {
        *w = w
            .split_once(":/")
            .map_or(w.clone(), |(_, rest)| rest.to_owned());
    }
    s
}

#[test]
fn usda_usdc_and_usdz_of_one_stage_read_the_same() {
    let a = usd::read(&data("groom.usda"), None, R).unwrap();
    let c = usd::read(&data("groom.usdc"), None, R).unwrap();
    let z = usd::read(&data("groom.usdz"), None, R).unwrap();
    let (a, c, z) = (without_file(a), without_file(c), without_file(z));
    assert_eq!(a, c);
    assert_eq!(a.strands, z.strands);
    assert_eq!(a.meshes, z.meshes);
    assert_eq!(a.camera, z.camera);
    // The dome's texture path is the package's for the .usdz; the rest of the lights agree.
    assert_eq!(a.lights[0], z.lights[0]);
}

#[test]
fn the_groom_has_its_strands_head_camera_and_lights_where_the_script_put_them() {
    let s = usd::read(&data("groom.usda"), None, R).unwrap();
    let st = s.strands.as_ref().unwrap();
    assert_eq!(st.strand_count(), 36);
    assert_eq!(st.segment_count(), 36 * 5, "6 pinned points: 5 segments");
    assert_eq!(s.curve_prims, ["/World/Head/Hair/Strands"]);
    // First strand's root: n = (sin 0.15, cos 0.15, 0), rotated 30° about y, then moved up 1.5.
    let n = Vec3::new(0.15f32.sin(), 0.15f32.cos(), 0.0);
    let a = 30f32.to_radians();
    let want = Vec3::new(n.x * a.cos(), n.y + 1.5, -n.x * a.sin());
    let root = st.eval(0, 0.0);
    assert!((root.position - want).length() < 1e-5, "{root:?} vs {want}");
    assert!((root.radius - 0.01).abs() < 1e-6, "width 0.02 at the root");
    assert!((st.opacity[0] - 0.75).abs() < 1e-7);
    assert!((st.color[1][0] - 0.31).abs() < 1e-6);
    assert_eq!(s.meshes.len(), 1);
    let m = &s.meshes[0];
    assert_eq!(m.triangles.len(), 16 + 16 * 10 * 2 + 16);
    assert!(
        m.name.ends_with("groom.usda:/World/Head/Skin"),
        "{}",
        m.name
    );
    assert!(
        (m.albedo - Vec3::new(0.8, 0.6, 0.5)).abs().max_element() < 1e-6,
        "bound UsdPreviewSurface"
    );
    let (lo, hi) = m.bounds();
    assert!(
        (lo - Vec3::new(-1.0, 0.5, -1.0)).abs().max_element() < 1e-5
            && (hi - Vec3::new(1.0, 2.5, 1.0)).abs().max_element() < 1e-5
    );
    let cam = s.camera.unwrap();
    assert_eq!(cam.position, Vec3::new(0.0, 1.5, 8.0));
    assert_eq!(cam.forward, Vec3::NEG_Z);
    let fov = 2.0 * (12.0f64 / 35.0).atan().to_degrees();
    assert!(
        (f64::from(cam.vertical_fov_degrees) - fov).abs() < 1e-4,
        "{cam:?}"
    );
    assert_eq!(cam.aspect, Some(1.5));
    let h = std::f32::consts::FRAC_1_SQRT_2;
    match &s.lights[0] {
        UsdLight::Distant {
            direction_to_light,
            intensity,
            angle_degrees,
            color,
            ..
        } => {
            assert!(
                (*direction_to_light - Vec3::new(0.0, h, h)).length() < 1e-6,
                "{direction_to_light}"
            );
            assert_eq!((*intensity, *angle_degrees), (3.0, 1.0));
            assert!((*color - Vec3::new(1.0, 0.9, 0.8)).length() < 1e-6);
        }
        l => panic!("{l:?}"),
    }
    match &s.lights[1] {
        UsdLight::Dome {
            intensity,
            exposure,
            texture,
            ..
        } => {
            assert_eq!((*intensity, *exposure), (0.5, 1.0));
            assert!(texture.as_ref().unwrap().ends_with("sky.exr"));
        }
        l => panic!("{l:?}"),
    }
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("/World/Bulb") && w.contains("SphereLight")),
        "{:?}",
        s.warnings
    );
    assert_eq!((s.up_axis.as_str(), s.meters_per_unit), ("Y", 0.01));
    let sum = usd::summary(&data("groom.usdc"), None).unwrap();
    assert_eq!((sum.strands.0, sum.meshes.1, sum.lights), (36, 352, 2));
    println!("{sum}");
    // A root limits the traversal to its subtree.
    let head = usd::read(&data("groom.usda"), Some("/World/Head/Hair"), R).unwrap();
    assert_eq!(
        head.strands, s.strands,
        "the root's ancestors' transforms still apply"
    );
    assert!(head.meshes.is_empty() && head.camera.is_none());
}

#[test]
fn every_basis_wrap_and_width_interpolation_of_the_file_converts() {
    let s = usd::read(&data("bases.usda"), None, R).unwrap();
    let st = s.strands.as_ref().unwrap();
    assert_eq!(s.curve_prims.len(), 4 * 3 * 5);
    for (i, prim) in s.curve_prims.iter().enumerate() {
        let name = prim.rsplit('/').next().unwrap();
        let f: Vec<&str> = name.split('_').collect();
        let (ty, basis, wrap, interp) = (f[0], f[1], f[2], f[3]);
        let segments = match (ty, basis, wrap) {
            ("linear", _, "periodic") => 7,
            ("linear", _, _) => 6,
            (_, "bezier", "periodic") => 2,
            (_, "bezier", _) => 2,
            (_, _, "periodic") => 7,
            (_, _, "pinned") => 6,
            _ => 4,
        };
        let segs: Vec<usize> = (0..st.segment_count())
            .filter(|&k| st.segment_strand[k] as usize == i)
            .collect();
        assert_eq!(segs.len(), segments, "{name}");
        let start = st.eval(segs[0] as u32, 0.0);
        // Widths 0.25, 0.375, …: the first is 0.25 wherever it is the curve's first value at u = 0.
        let first_width_at_start = interp != "vertex"
            || !((basis == "catmullRom" || basis == "bspline")
                && wrap != "pinned"
                && ty == "cubic");
        // Radii the conversion clamped at 0 (and warned about) are not exact.
        let clamped = s
            .warnings
            .iter()
            .any(|w| w.contains(&format!("{prim}:")) && w.contains("clamped"));
        if first_width_at_start && interp != "uniform" && !clamped {
            assert!((start.radius - 0.125).abs() < 1e-6, "{name}: {start:?}");
        }
        // Curves that pass through their first point: Bézier, linear, pinned.
        if basis == "bezier" || ty == "linear" || wrap == "pinned" {
            assert!(
                (start.position - Vec3::new(0.0, 0.0, 1.0)).length() < 1e-6,
                "{name}: {start:?}"
            );
        }
    }
}

/// The first `n` strands of a model.
fn first_strands(m: &HairModel, n: usize) -> HairModel {
    let n = n.min(m.strand_count());
    let end = m.strand_offsets[n] as usize;
    HairModel {
        points: m.points[..end].to_vec(),
        strand_offsets: m.strand_offsets[..=n].to_vec(),
        radius: m.radius[..end].to_vec(),
        radius_from_file: m.radius_from_file,
        transparency: m.transparency[..end].to_vec(),
        color: m.color[..end].to_vec(),
        format: m.format.clone(),
        info: String::new(),
    }
}

/// A model as a pinned B-spline `BasisCurves` prim in `.usda` text (shortest round-trip floats).
fn as_usda(m: &HairModel) -> String {
    let list = |v: Vec<String>| v.join(", ");
    let p3 = |p: [f32; 3]| format!("({:?}, {:?}, {:?})", p[0], p[1], p[2]);
    let counts: Vec<String> = (0..m.strand_count())
        .map(|s| m.strand_range(s).len().to_string())
        .collect();
    let points: Vec<String> = m.points.iter().map(|p| p3(p.to_array())).collect();
    let color: Vec<String> = m.color.iter().map(|c| p3(*c)).collect();
    let opacity: Vec<String> = m
        .transparency
        .iter()
        .map(|t| format!("{:?}", 1.0 - t))
        .collect();
    let widths = if m.radius_from_file {
        let w: Vec<String> = m.radius.iter().map(|r| format!("{:?}", 2.0 * r)).collect();
        format!(
            "float[] widths = [{}] (interpolation = \"vertex\")\n",
            list(w)
        )
    } else {
        String::new()
    };
    format!(
        "#usda 1.0\ndef BasisCurves \"Hair\"\n{{\nuniform token type = \"cubic\"\nuniform token basis = \"bspline\"\n\
         uniform token wrap = \"pinned\"\nint[] curveVertexCounts = [{}]\npoint3f[] points = [{}]\n{widths}\
         color3f[] primvars:displayColor = [{}] (interpolation = \"vertex\")\n\
         float[] primvars:displayOpacity = [{}] (interpolation = \"vertex\")\n}}\n",
        list(counts),
        list(points),
        list(color),
        list(opacity)
    )
}

#[test]
fn a_hair_model_written_as_pinned_bsplines_reads_back_bit_for_bit() {
    let straight = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hair/straight.hair");
    assert!(
        straight.exists(),
        "{} is missing (CI has ../shared/data)",
        straight.display()
    );
    let model = first_strands(&cuticle::hair::load(&straight).unwrap(), 200);
    let dir = tempfile::tempdir().unwrap();
    let mut thin = model.clone();
    // Without widths: the default radius at every point, tapered like a `.hair` file without thickness.
    thin.radius_from_file = false;
    thin.radius.iter_mut().for_each(|r| *r = R);
    // With widths: per-point thickness, used as it is.
    let mut thick = model.clone();
    thick.radius_from_file = true;
    thick
        .radius
        .iter_mut()
        .enumerate()
        .for_each(|(i, r)| *r = 0.01 + 1e-5 * (i % 7) as f32);
    for m in [&thin, &thick] {
        let p = write(dir.path(), "hair.usda", as_usda(m).as_bytes());
        let s = usd::read(&p, None, R).unwrap();
        let want = Strands::from_model(m);
        let got = s.strands.unwrap();
        assert_eq!(got.control_points.len(), want.control_points.len());
        let bits = |v: &[[f32; 4]]| {
            v.iter()
                .flat_map(|c| c.map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        assert!(
            bits(&got.control_points) == bits(&want.control_points),
            "control points differ (radius from file: {})",
            m.radius_from_file
        );
        assert_eq!(got.segment_first, want.segment_first);
        assert_eq!(got.strand_offsets, want.strand_offsets);
        assert_eq!(got.color, want.color);
        assert!(got
            .opacity
            .iter()
            .zip(&want.opacity)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn nested_transforms_move_points_where_hand_maths_says() {
    let dir = tempfile::tempdir().unwrap();
    let text = r#"#usda 1.0
(
    upAxis = "Z"
    metersPerUnit = 1
)
def Xform "A" {
    double3 xformOp:translate = (1, 2, 3)
    float3 xformOp:scale = (2, 2, 2)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
    def Xform "B" {
        float xformOp:rotateZ = 90
        uniform token[] xformOpOrder = ["xformOp:rotateZ"]
        def BasisCurves "C" {
            uniform token type = "linear"
            int[] curveVertexCounts = [2]
            point3f[] points = [(1, 0, 0), (1, 0, 1)]
            float[] widths = [0.5] (interpolation = "constant")
        }
        def Camera "Cam" {
            float focalLength = 50
            float verticalAperture = 20
        }
    }
    def Xform "Reset" {
        uniform token[] xformOpOrder = ["!resetXformStack!", "xformOp:translate"]
        double3 xformOp:translate = (0, 0, 5)
        def Mesh "M" {
            point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
            int[] faceVertexCounts = [3]
            int[] faceVertexIndices = [0, 1, 2]
            uniform token orientation = "leftHanded"
            color3f[] primvars:displayColor = [(2, 0.5, -1)]
        }
    }
}
"#;
    let p = write(dir.path(), "xf.usda", text.as_bytes());
    let s = usd::read(&p, None, R).unwrap();
    assert_eq!((s.up_axis.as_str(), s.meters_per_unit), ("Z", 1.0));
    let st = s.strands.unwrap();
    // (1, 0, 0) → rotateZ 90 → (0, 1, 0) → scale 2 → (0, 2, 0) → +(1, 2, 3) → (1, 4, 3).
    let a = st.eval(0, 0.0);
    let b = st.eval(0, 1.0);
    assert!(
        (a.position - Vec3::new(1.0, 4.0, 3.0)).length() < 1e-6,
        "{a:?}"
    );
    assert!(
        (b.position - Vec3::new(1.0, 4.0, 5.0)).length() < 1e-6,
        "{b:?}"
    );
    assert!(
        (a.radius - 0.5).abs() < 1e-6,
        "width 0.5 → radius 0.25, scaled by 2"
    );
    let cam = s.camera.unwrap();
    assert!((cam.position - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6);
    assert!((cam.forward - Vec3::NEG_Z).length() < 1e-6);
    assert!(
        (cam.up - Vec3::NEG_X).length() < 1e-6,
        "+y turned 90° about z: {cam:?}"
    );
    let fov = 2.0 * (10.0f32 / 50.0).atan().to_degrees();
    assert!((cam.vertical_fov_degrees - fov).abs() < 1e-4);
    let m = &s.meshes[0];
    assert_eq!(
        m.positions[1],
        Vec3::new(1.0, 0.0, 5.0),
        "the reset drops A's transform"
    );
    assert_eq!(m.triangles, [[0, 2, 1]], "leftHanded reverses the winding");
    assert_eq!(m.albedo, Vec3::new(1.0, 0.5, 0.0));
    assert!(
        s.warnings.iter().any(|w| w.contains("clamped")),
        "{:?}",
        s.warnings
    );
}

/// The error of reading `text` as `name`, which must name the file (and the prim when given).
fn fails(name: &str, text: &[u8], prim: Option<&str>, says: &str) {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), name, text);
    let e = usd::read(&p, None, R).expect_err(name).to_string();
    assert!(e.starts_with(&p.display().to_string()), "{e}");
    if let Some(prim) = prim {
        assert!(e.contains(prim), "{e}");
    }
    assert!(e.contains(says), "{name}: {e}");
}

fn curves(counts: &str, points: &str) -> String {
    format!("#usda 1.0\ndef BasisCurves \"C\" {{\nuniform token basis = \"bspline\"\nint[] curveVertexCounts = [{counts}]\npoint3f[] points = [{points}]\n}}\n")
}

#[test]
fn bad_files_fail_with_their_name_and_prim() {
    let usdc = std::fs::read(data("groom.usdc")).unwrap();
    for cut in [usdc.len() / 2, usdc.len() - 100, 100, 10] {
        fails("cut.usdc", &usdc[..cut], None, "");
    }
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    for name in ["g.usda", "g.usdc", "g.usdz"] {
        fails(name, &garbage, None, "");
    }
    let mut bad_magic = usdc.clone();
    bad_magic[100..200].fill(0xff);
    fails("scribbled.usdc", &bad_magic, None, "");
    let p = "(0,0,0), (0,1,0), (0,2,0), (0,3,0)";
    fails(
        "sum.usda",
        curves("4, 4", p).as_bytes(),
        Some("/C"),
        "add up to 8 vertices but there are 4 points",
    );
    fails("huge.usda", curves("4000000000", p).as_bytes(), None, "");
    fails(
        "negative.usda",
        curves("-4, 8", p).as_bytes(),
        Some("/C"),
        "is -4",
    );
    fails(
        "short.usda",
        curves("2, 2", p).as_bytes(),
        Some("/C"),
        "curve 0 has 2 vertices",
    );
    let mesh = "#usda 1.0\ndef Mesh \"M\" {\npoint3f[] points = [(0,0,0), (1,0,0), (0,1,0)]\nint[] faceVertexCounts = [3]\nint[] faceVertexIndices = [0, 1, 7]\n}\n";
    fails(
        "index.usda",
        mesh.as_bytes(),
        Some("/M"),
        "faceVertexIndices[2] is 7",
    );
    let widths = "#usda 1.0\ndef BasisCurves \"C\" {\nuniform token basis = \"bspline\"\nint[] curveVertexCounts = [4]\npoint3f[] points = [(0,0,0), (0,1,0), (0,2,0), (0,3,0)]\nfloat[] widths = [1, 2]\n}\n";
    fails(
        "widths.usda",
        widths.as_bytes(),
        Some("/C"),
        "widths has 2 values; vertex interpolation needs 4",
    );
    let e = usd::read(Path::new("/nonexistent/groom.usda"), None, R)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("/nonexistent/groom.usda"), "{e}");
}

#[test]
fn a_subdivision_surface_is_shaded_smoothly_and_a_polygon_mesh_flat() {
    let dir = tempfile::tempdir().unwrap();
    let quad = |scheme: &str| {
        format!(
            "#usda 1.0\ndef Mesh \"M\"\n{{\n{scheme}int[] faceVertexCounts = [4]\nint[] faceVertexIndices = [0, 1, 2, 3]\n\
             point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0.5), (0, 1, 0)]\n}}\n"
        )
    };
    // No `subdivisionScheme`: catmullClark, USD's default, a smooth surface.
    let smooth = usd::read(&write(dir.path(), "s.usda", quad("").as_bytes()), None, R).unwrap();
    let normals = smooth.meshes[0].vertex_normals.as_ref().unwrap();
    assert_eq!(normals.len(), 4);
    // Point 0 is in both triangles of the fan (0, 1, 2) and (0, 2, 3): its normal is between theirs.
    let (a, b) = (smooth.meshes[0].normal(0), smooth.meshes[0].normal(1));
    assert!(a != b && normals[0].dot(a) > 0.9 && normals[0].dot(b) > 0.9 && normals[0] != a);
    let flat = usd::read(
        &write(
            dir.path(),
            "f.usda",
            quad("uniform token subdivisionScheme = \"none\"\n").as_bytes(),
        ),
        None,
        R,
    )
    .unwrap();
    assert!(flat.meshes[0].vertex_normals.is_none());
    // The groom's head (no scheme authored) is smooth.
    let groom = usd::read(&data("groom.usda"), None, R).unwrap();
    assert!(groom.meshes[0].vertex_normals.is_some());
}

/// The world points of every strand (`curve`) and mesh (`mesh`) in `instancing.expected`, as Pixar's library
/// places them.
fn expected_points(kind: &str) -> Vec<Vec<Vec3>> {
    let text = std::fs::read_to_string(data("instancing.expected")).unwrap();
    text.lines()
        .filter_map(|l| l.strip_prefix(kind).map(str::trim))
        .map(|l| {
            let v: Vec<f32> = l.split(' ').map(|x| x.parse().unwrap()).collect();
            v.chunks(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect()
        })
        .collect()
}

/// Whether `got` holds the point lists of `want`, in any order, each point within `tol`.
fn same_point_sets(mut got: Vec<Vec<Vec3>>, mut want: Vec<Vec<Vec3>>, tol: f32) {
    let key =
        |v: &Vec<Vec3>| (v[0].x * 1e4).round() as i64 * 1_000_003 + (v[0].z * 1e4).round() as i64;
    got.sort_by_key(key);
    want.sort_by_key(key);
    assert_eq!(got.len(), want.len(), "how many");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.len(), w.len());
        for (a, b) in g.iter().zip(w) {
            assert!((*a - *b).abs().max_element() <= tol, "{a} against {b}");
        }
    }
}

#[test]
fn instances_and_point_instancers_land_where_pixars_library_puts_them_and_guides_are_left_out() {
    let s = usd::read(&data("instancing.usda"), None, R).unwrap();
    let st = s.strands.as_ref().unwrap();
    let strands: Vec<Vec<Vec3>> = (0..st.strand_count())
        .map(|k| {
            let (a, b) = (
                st.strand_offsets[k] as usize,
                st.strand_offsets[k + 1] as usize,
            );
            st.control_points[a..b]
                .iter()
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        })
        .collect();
    // Three instances of a two-strand tuft, two visible instances of a one-strand prototype: the guide curves,
    // the invisible prim and the hidden instance are not there.
    assert_eq!(strands.len(), 8);
    same_point_sets(strands, expected_points("curve"), 2e-6);
    let meshes: Vec<Vec<Vec3>> = s.meshes.iter().map(|m| m.positions.clone()).collect();
    same_point_sets(meshes, expected_points("mesh"), 2e-6);
    assert_eq!(s.skipped.guide, 1);
    assert_eq!(s.skipped.invisible, 1);
    // Widths scale with the instance: the tuft's 0.1 at scales 1, 1.5 and 2, the strand's 0.05 at 1 and 2. The
    // file's half-precision quaternions are up to 2.2e-4 from unit length, and their matrix scales by that much.
    let mut radii: Vec<f32> = (0..st.strand_count())
        .map(|k| st.control_points[st.strand_offsets[k] as usize][3])
        .collect();
    radii.sort_by(f32::total_cmp);
    let want = [0.025, 0.05, 0.05, 0.05, 0.075, 0.075, 0.1, 0.1];
    for (r, w) in radii.iter().zip(want) {
        assert!((r - w).abs() <= 2.5e-4 * w, "radii {radii:?}");
    }
}

#[test]
fn a_point_instancer_that_would_make_too_much_or_points_outside_its_prototypes_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let stage = |indices: &str, positions: &str| {
        format!(
            "#usda 1.0\ndef PointInstancer \"P\" {{\n  rel prototypes = </P/Protos/C>\n  int[] protoIndices = \
             {indices}\n  point3f[] positions = {positions}\n  def Scope \"Protos\" {{\n    def BasisCurves \"C\" \
             {{\n      uniform token basis = \"bspline\"\n      int[] curveVertexCounts = [4]\n      point3f[] \
             points = [(0,0,0),(0,1,0),(0,2,0),(0,3,0)]\n    }}\n  }}\n}}\n"
        )
    };
    fails_in(
        dir.path(),
        "index.usda",
        &stage("[0, 1]", "[(0,0,0),(1,0,0)]"),
        "/P",
        "protoIndices[1] is 1, outside the 1 prototypes",
    );
    fails_in(
        dir.path(),
        "count.usda",
        &stage("[0, 0]", "[(0,0,0)]"),
        "/P",
        "positions has 1 values for 2 protoIndices",
    );
    // An instancer placing another: 4 points × 65,536 inner instances × 10,000 outer ones is 2.6 × 10⁹ points,
    // refused before any is made.
    let positions = |n: usize| {
        let v: Vec<String> = (0..n).map(|i| format!("({i},0,0)")).collect();
        format!("[{}]", v.join(","))
    };
    let zeros = |n: usize| format!("[{}]", vec!["0"; n].join(","));
    let nested = format!(
        "#usda 1.0\ndef PointInstancer \"Outer\" {{\n  rel prototypes = </Outer/Inner>\n  int[] protoIndices = {}\n  \
         point3f[] positions = {}\n  def PointInstancer \"Inner\" {{\n    rel prototypes = </Outer/Inner/C>\n    \
         int[] protoIndices = {}\n    point3f[] positions = {}\n    def BasisCurves \"C\" {{\n      uniform token \
         basis = \"bspline\"\n      int[] curveVertexCounts = [4]\n      point3f[] points = \
         [(0,0,0),(0,1,0),(0,2,0),(0,3,0)]\n    }}\n  }}\n}}\n",
        zeros(10_000),
        positions(10_000),
        zeros(65_536),
        positions(65_536)
    );
    fails_in(
        dir.path(),
        "nested.usda",
        &nested,
        "/Outer",
        "10000 instances make 2621440000 points, more than the reader's limit",
    );
    // Two instances read fine, and the prototype under the instancer is not read as itself.
    let p = write(
        dir.path(),
        "ok.usda",
        stage("[0, 0]", "[(0,0,0),(1,0,0)]").as_bytes(),
    );
    let s = usd::read(&p, None, R).unwrap();
    assert_eq!(s.strands.unwrap().strand_count(), 2);
}

fn fails_in(dir: &Path, name: &str, text: &str, prim: &str, says: &str) {
    let p = write(dir, name, text.as_bytes());
    let e = usd::read(&p, None, R).unwrap_err();
    assert_eq!(e.prim.as_deref(), Some(prim), "{e}");
    assert!(e.to_string().contains(says), "{e}");
}

/// sRGB-encoded byte → linear.
fn srgb(byte: u8) -> f32 {
    let c = byte as f32 / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// checker.png's texels, top row first (`TEXELS` in scripts/usd-test-data.py).
const TEXELS: [[[u8; 3]; 4]; 2] = [
    [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255]],
    [[128, 128, 128], [64, 32, 16], [200, 100, 50], [0, 0, 0]],
];

/// The albedo of `mesh` at texture coordinates `st` on its first quad (corners st (0,0), (1,0), (1,1), (0,1) for
/// `Card`; triangle 0 is (0, 1, 2), triangle 1 (0, 2, 3)), through the mesh's own triangle lookup.
fn albedo_at_st(mesh: &cuticle::mesh::TriangleMesh, s: f32, t: f32) -> Vec3 {
    let tex = mesh.texture.as_ref().expect("a texture");
    // Solve st = a + u (b − a) + v (c − a) on triangle 0.
    let [a, b, c] = tex.corner_st[0];
    let (e1, e2, p) = (b - a, c - a, glam::Vec2::new(s, t) - a);
    let det = e1.perp_dot(e2);
    let (u, v) = (p.perp_dot(e2) / det, e1.perp_dot(p) / det);
    mesh.albedo_at(0, u, v)
}

#[test]
fn a_usd_preview_surface_texture_gives_the_albedo_in_usda_and_in_usdz() {
    for name in ["textured.usda", "textured.usdz"] {
        let s = usd::read(&data(name), None, R).unwrap();
        assert!(s.warnings.is_empty(), "{:?}", s.warnings);
        let card = &s.meshes[0];
        assert!(card.name.ends_with("/World/Card"));
        // An 8-bit PNG with sourceColorSpace auto is sRGB: every texel centre gives its texel, decoded.
        for (row, texels) in TEXELS.iter().enumerate() {
            for (col, texel) in texels.iter().enumerate() {
                let (s_, t_) = ((col as f32 + 0.5) / 4.0, 1.0 - (row as f32 + 0.5) / 2.0);
                let got = albedo_at_st(card, s_, t_);
                let want = Vec3::from_array(texel.map(srgb));
                assert!(
                    (got - want).abs().max_element() < 2e-6,
                    "{name} texel ({col}, {row}): {got} against {want}"
                );
            }
        }
        // Raw, × 0.5 + (0.1, 0, 0), wrapS clamp: s = −0.5 keeps the left column; s runs −0.5..1.5 over the card.
        let raw = &s.meshes[1];
        let tex = raw.texture.as_ref().unwrap();
        let raw_at = |s_: f32, t_: f32| {
            tex.image.lookup(glam::Vec2::new(s_, t_), tex.wrap) * tex.scale + tex.bias
        };
        let byte = |c: u8| c as f32 / 255.0;
        let want = Vec3::new(byte(128) * 0.5 + 0.1, byte(128) * 0.5, byte(128) * 0.5);
        assert!((raw_at(-0.4, 0.25) - want).abs().max_element() < 2e-6);
        // The card's corner at x = 3 has s = −0.5.
        assert!(
            (raw.texture.as_ref().unwrap().corner_st[0][0] - glam::Vec2::new(-0.5, 0.0)).length()
                < 1e-6
        );
        assert!(tex.image.name.contains("checker.png"));
    }
}

#[test]
fn a_missing_or_unreadable_texture_is_an_error_naming_the_shader() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(data("textured.usda"))
        .unwrap()
        .replace("@checker.png@", "@nothing-here.png@");
    let p = write(dir.path(), "t.usda", text.as_bytes());
    let e = usd::read(&p, None, R).unwrap_err();
    assert_eq!(e.prim.as_deref(), Some("/World/Looks/Srgb/Texture"), "{e}");
    assert!(e.to_string().contains("nothing-here.png"), "{e}");
    // A file that is not an image.
    std::fs::write(dir.path().join("nothing-here.png"), b"not an image").unwrap();
    let e = usd::read(&p, None, R).unwrap_err();
    assert!(e.to_string().contains("nothing-here.png"), "{e}");
}

#[test]
fn a_read_of_some_parts_converts_only_those_and_counts_the_meshes_it_left() {
    let all = usd::read(&data("groom.usda"), None, R).unwrap();
    let none = usd::read_parts(&data("groom.usda"), None, R, usd::Parts::NONE).unwrap();
    assert_eq!((none.strands.is_none(), none.meshes.len()), (true, 0));
    assert_eq!(none.mesh_prims, all.meshes.len());
    assert_eq!((none.camera, &none.lights), (all.camera, &all.lights));
    let curves = usd::Parts {
        curves: true,
        meshes: false,
    };
    let hair = usd::read_parts(&data("groom.usda"), None, R, curves).unwrap();
    assert_eq!((hair.strands, hair.meshes.len()), (all.strands, 0));
}

#[test]
fn names_the_parser_takes_for_their_own_parent_are_refused_before_they_are_queried() {
    // openusd 0.6 parses `a}` into a path whose parent is itself; any query of the prim recursed until the stack
    // overflowed (found by the `usd` fuzz target).
    let dir = tempfile::tempdir().unwrap();
    fails_in(
        dir.path(),
        "own.usda",
        "#usda 1.0\ndef Xform \"W\"\n{\n    def Xform \"a}\"\n    {\n    }\n}\n",
        "/W/a}",
        "cannot place under its parent",
    );
    // An attribute named so (here an xformOp) looped for good in openusd's index cache.
    fails_in(
        dir.path(),
        "attr.usda",
        "#usda 1.0\ndef Xform \"W\"\n{\n    uniform token[] xformOpOrder = [\"xfor}Op:scale\"]\n}\n",
        "/W",
        "attribute name \"xfor}Op:scale\" is not one the USD parser can resolve",
    );
    // And a root asked for by such a name.
    let p = write(
        dir.path(),
        "root.usda",
        b"#usda 1.0\ndef Xform \"W\"\n{\n}\n",
    );
    let e = usd::read(&p, Some("/W/a}"), R).unwrap_err();
    assert!(
        e.to_string().contains("cannot place under its parent"),
        "{e}"
    );
}

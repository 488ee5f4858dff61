//! Parts of a frame (`render --crop`, `--tile I/N`) equal the full render there, `merge`
//! assembles them bit for bit and refuses what does not make one frame; `--frames` renders a turntable.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use cuticle::image;

const EXE: &str = env!("CARGO_BIN_EXE_cuticle");
/// Small and few samples: the check is bit-exactness, not image quality.
const SMALL: [&str; 5] = ["--res", "40x30", "--spp", "2", "-q"];

fn cuticle(args: &[&str]) -> Output {
    Command::new(EXE).args(args).output().expect("run cuticle")
}

fn ok(o: Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn render(out: &Path, extra: &[&str]) {
    let mut args = vec!["render", "-o", out.to_str().unwrap()];
    args.extend_from_slice(&SMALL);
    args.extend_from_slice(extra);
    ok(cuticle(&args));
}

fn same_bits(a: &image::Image, b: &image::Image) {
    assert_eq!((a.width, a.height), (b.width, b.height));
    for (c, name) in a.channels.iter().enumerate() {
        let d = b
            .channel_index(name)
            .unwrap_or_else(|| panic!("{name} missing"));
        for y in 0..a.height {
            for x in 0..a.width {
                assert_eq!(
                    a.get(x, y, c).to_bits(),
                    b.get(x, y, d).to_bits(),
                    "{name} at ({x}, {y})"
                );
            }
        }
    }
}

#[test]
fn four_tiles_merged_equal_the_full_frame_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    // Both films: a splatted pixel sums its neighbours' samples, across bands and work tiles.
    for reconstruction in ["importance", "splat"] {
        let film = ["--reconstruction", reconstruction];
        let full = dir.path().join("full.exr");
        render(&full, &film);
        let tiles: Vec<PathBuf> = (0..4)
            .map(|i| {
                let t = dir.path().join(format!("tile{i}.exr"));
                render(&t, &[&film[..], &["--tile", &format!("{i}/4")]].concat());
                t
            })
            .collect();
        let merged = dir.path().join("merged.exr");
        let mut args = vec!["merge", "-o", merged.to_str().unwrap()];
        args.extend(tiles.iter().map(|t| t.to_str().unwrap()));
        ok(cuticle(&args));
        // Every channel (beauty, AOVs, the centre-ray depth, tangent and id) equal bit for bit.
        same_bits(&image::read(&full).unwrap(), &image::read(&merged).unwrap());
        assert!(dir.path().join("merged.png").is_file());
    }
    let tiles: Vec<PathBuf> = (0..4)
        .map(|i| dir.path().join(format!("tile{i}.exr")))
        .collect();

    // A tile records its place in the frame and its job.
    let (_, window, attrs) =
        image::read_with_info(&tiles[1], &["cuticle:job", "cuticle:complete"]).unwrap();
    assert_eq!(
        (window.x, window.y, window.full_width, window.full_height),
        (0, 7, 40, 30)
    );
    assert_eq!(attrs[1].as_deref(), Some("1"));

    // Gaps, overlaps and tiles of other settings are refused, naming the problem.
    let err = |args: &[&str]| {
        let o = cuticle(args);
        assert_eq!(o.status.code(), Some(2));
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let t: Vec<&str> = tiles.iter().map(|t| t.to_str().unwrap()).collect();
    let out = dir.path().join("bad.exr");
    let out = out.to_str().unwrap();
    assert!(err(&["merge", "-o", out, t[0], t[1], t[3]]).contains("uncovered"));
    assert!(err(&["merge", "-o", out, t[0], t[1], t[1], t[2], t[3]]).contains("overlaps"));
    let other = dir.path().join("other.exr");
    render(&other, &["--tile", "2/4", "--seed", "9"]);
    let e = err(&[
        "merge",
        "-o",
        out,
        t[0],
        t[1],
        other.to_str().unwrap(),
        t[3],
    ]);
    assert!(e.contains("another job") && e.contains("other.exr"), "{e}");
    assert!(!Path::new(out).exists());
}

#[test]
fn a_crop_equals_the_same_region_of_the_full_frame() {
    let dir = tempfile::tempdir().unwrap();
    for reconstruction in ["importance", "splat"] {
        let film = ["--reconstruction", reconstruction];
        let full = dir.path().join("full.exr");
        render(&full, &film);
        let crop = dir.path().join("crop.exr");
        render(&crop, &[&film[..], &["--crop", "5,3,38,21"]].concat());
        let (full, crop) = (image::read(&full).unwrap(), image::read(&crop).unwrap());
        assert_eq!((crop.width, crop.height), (33, 18));
        for (c, name) in crop.channels.iter().enumerate() {
            let f = full.channel_index(name).unwrap();
            for y in 0..crop.height {
                for x in 0..crop.width {
                    assert_eq!(
                        crop.get(x, y, c).to_bits(),
                        full.get(x + 5, y + 3, f).to_bits(),
                        "{reconstruction}: {name} at ({x}, {y}) of the crop"
                    );
                }
            }
        }
    }
    let o = cuticle(&[
        "render", "-o", "x.exr", "--res", "40x30", "--crop", "0,0,41,5",
    ]);
    assert!(String::from_utf8_lossy(&o.stderr).contains("outside the 40x30 frame"));
}

#[test]
fn frames_of_a_turntable_and_their_tiles() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("turntable.toml");
    let default =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/default.toml"))
            .expect("scenes/default.toml");
    let text = default.replacen(
        "[camera]\n",
        "[camera]\norbit_degrees_per_frame = 90.0\n",
        1,
    );
    assert_ne!(text, default, "scenes/default.toml has a [camera] table");
    std::fs::write(&scene, text).unwrap();
    let out = dir.path().join("spin.exr");
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(&SMALL);
    args.extend_from_slice(&["--frames", "1..2"]);
    ok(cuticle(&args));
    let f1 = image::read(dir.path().join("spin.0001.exr")).unwrap();
    let f2 = image::read(dir.path().join("spin.0002.exr")).unwrap();
    assert!(dir.path().join("spin.0002.png").is_file());
    assert_ne!(f1.data, f2.data, "the camera turned between frames");

    // Frame 2 in two tiles merges into the same frame 2.
    for i in 0..2 {
        let t = dir.path().join(format!("t{i}.exr"));
        let mut args = vec!["render", scene.to_str().unwrap(), "-o", t.to_str().unwrap()];
        args.extend_from_slice(&SMALL);
        let part = format!("{i}/2");
        args.extend_from_slice(&["--frames", "2..2", "--tile", &part]);
        ok(cuticle(&args));
    }
    let merged = dir.path().join("m.exr");
    let t = |i| dir.path().join(format!("t{i}.0002.exr"));
    ok(cuticle(&[
        "merge",
        "-o",
        merged.to_str().unwrap(),
        t(0).to_str().unwrap(),
        t(1).to_str().unwrap(),
    ]));
    same_bits(&f2, &image::read(&merged).unwrap());
}

/// `merge` trusts nothing it is given: a tile spelled `./s.toml` is the same job as one from `s.toml`; a tile
/// rendered after the hair file was replaced (same path) is another job; a FIFO as a tile is refused at once; a
/// tile whose header declares a 100 000² frame is refused before the frame is allocated.
#[test]
fn merge_identifies_jobs_by_content_and_refuses_what_it_cannot_trust() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write_hair = |seed_colour: f32| {
        let mut m = cuticle::hair::HairModel {
            strand_offsets: vec![0],
            format: cuticle::hair::yuksel::FORMAT.to_owned(),
            ..Default::default()
        };
        for s in 0..20 {
            for k in 0..4 {
                m.points
                    .push(glam::Vec3::new(s as f32 * 0.05, k as f32 * 0.1, 0.0));
                m.radius.push(0.01);
                m.transparency.push(0.0);
                m.color.push([seed_colour; 3]);
            }
            m.strand_offsets.push(m.points.len() as u32);
        }
        cuticle::hair::yuksel::write(&d.join("h.hair"), &m).unwrap();
    };
    write_hair(0.5);
    std::fs::write(
        d.join("s.toml"),
        "[hair]\nfile = \"h.hair\"\n[film]\nresolution = [16, 16]\nspp = 1\n",
    )
    .unwrap();
    let tile = |scene: &str, i: usize, out: &str| {
        let o = Command::new(EXE)
            .current_dir(d)
            .args([
                "render",
                scene,
                "-q",
                "--tile",
                &format!("{i}/2"),
                "-o",
                out,
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let merge = |tiles: &[&str]| {
        Command::new(EXE)
            .current_dir(d)
            .args(["merge", "-o", "m.exr"])
            .args(tiles)
            .output()
            .unwrap()
    };
    tile("s.toml", 0, "t0.exr");
    tile("./s.toml", 1, "t1.exr");
    let o = merge(&["t0.exr", "t1.exr"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    write_hair(0.9);
    tile("s.toml", 1, "t1.exr");
    let o = merge(&["t0.exr", "t1.exr"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("belongs to another job"), "{e}");
    // A FIFO: refused without waiting for a writer.
    let fifo = d.join("f.exr");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let start = std::time::Instant::now();
    let o = merge(&["f.exr"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(start.elapsed() < std::time::Duration::from_secs(5));
    // A forged header: a 1×1 tile of a 100 000² frame.
    let mut forged = image::Image::new(1, 1, vec!["R".to_owned(), "G".to_owned(), "B".to_owned()]);
    forged.data.fill(1.0);
    let mut outputs = image::Outputs::new();
    outputs
        .exr(
            &d.join("forged.exr"),
            &forged,
            &image::ExrInfo {
                window: Some(image::DataWindow {
                    x: 0,
                    y: 0,
                    full_width: 100_000,
                    full_height: 100_000,
                }),
                attributes: vec![
                    ("cuticle:job".to_owned(), "x".to_owned()),
                    ("cuticle:complete".to_owned(), "1".to_owned()),
                ],
            },
        )
        .unwrap();
    outputs.commit().unwrap();
    let o = merge(&["forged.exr"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("100000 x 100000") && e.contains("allowed"),
        "{e}"
    );
}

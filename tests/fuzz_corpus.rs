//! Replays the fuzz corpora (`fuzz/corpus/<target>/`, seeds and anything a fuzzing run found) through the same
//! entry points as the cargo-fuzz targets (`cuticle::scene::fuzz`), with stable Rust: what CI runs. A corpus file
//! may be accepted or rejected; none may panic. The seeds made from real files must still be accepted.

use std::path::{Path, PathBuf};

fn corpus(target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: empty corpus", dir.display());
    files
}

/// Runs every file of `target`'s corpus through `entry`; returns the names accepted.
fn replay(target: &str, entry: fn(&[u8]) -> bool) -> Vec<String> {
    let mut accepted = Vec::new();
    for path in corpus(target) {
        let bytes = std::fs::read(&path).unwrap();
        assert!(
            bytes.len() <= 64 << 10,
            "{}: corpus files stay under 64 KiB",
            path.display()
        );
        // A panic fails the test naming the file (the parser's own message is printed above it).
        let accepted_here = std::panic::catch_unwind(|| entry(&bytes))
            .unwrap_or_else(|_| panic!("{}: the {target} entry point panicked", path.display()));
        if accepted_here {
            accepted.push(path.file_name().unwrap().to_string_lossy().into_owned());
        }
    }
    accepted
}

#[test]
fn hair_corpus_replays_and_real_seeds_parse() {
    let ok = replay("hair", cuticle::scene::fuzz::hair);
    for seed in [
        "straight-4-strands.hair",
        "straight-1-strand.hair",
        "furball-3-strands.hair",
    ] {
        assert!(
            ok.iter().any(|n| n == seed),
            "{seed} rejected; accepted: {ok:?}"
        );
    }
    assert!(!ok.iter().any(|n| n == "header-2pow32-strands.hair"));
}

#[test]
fn tfx_corpus_replays_and_real_seeds_parse() {
    let ok = replay("tfx", cuticle::scene::fuzz::tfx);
    for seed in ["mohawk-4-strands.tfx", "mohawk-1-strand.tfx"] {
        assert!(
            ok.iter().any(|n| n == seed),
            "{seed} rejected; accepted: {ok:?}"
        );
    }
    assert!(!ok.iter().any(|n| n == "header-huge-counts.tfx"));
}

#[test]
fn scene_corpus_replays_and_shipped_scenes_validate() {
    let ok = replay("scene", cuticle::scene::fuzz::scene);
    for name in ["default.toml", "furball.toml", "cornell-box.toml"] {
        assert!(
            ok.iter().any(|n| n == name),
            "{name} rejected; accepted: {ok:?}"
        );
    }
}

/// The tiles `render --tile` writes merge; tiles of another job, a forged 100 000² frame, overlapping tiles, a
/// gap, and a tile whose header declares a 1.8 GB attribute (OpenEXR allocated it) do not.
#[test]
fn merge_corpus_replays_and_real_tiles_merge() {
    let ok = replay("merge", cuticle::scene::fuzz::merge);
    for seed in [
        "two-tiles.bin",
        "four-tiles.bin",
        "aov-tiles.bin",
        "whole-frame.exr",
    ] {
        assert!(
            ok.iter().any(|n| n == seed),
            "{seed} rejected; accepted: {ok:?}"
        );
    }
    for seed in [
        "another-job.bin",
        "forged-100000-frame.bin",
        "overlap.bin",
        "gap.bin",
        "oom-1.8-GB-attribute.bin",
    ] {
        assert!(!ok.iter().any(|n| n == seed), "{seed} accepted");
    }
}

#[test]
fn corpora_stay_small() {
    let total: u64 = ["hair", "tfx", "scene", "merge"]
        .iter()
        .flat_map(|t| corpus(t))
        .map(|p| std::fs::metadata(p).unwrap().len())
        .sum();
    assert!(total <= 2 << 20, "corpora total {total} bytes, over 2 MiB");
}

#[test]
fn usd_corpus_replays_and_real_seeds_parse() {
    let ok = replay("usd", cuticle::scene::fuzz::usd);
    for seed in [
        "a-groom.usda",
        "a-bases.usda",
        "c-groom.usdc",
        "z-groom.usdz",
        "a-instancing.usda",
        "z-textured.usdz",
    ] {
        assert!(
            ok.iter().any(|n| n == seed),
            "{seed} rejected; accepted: {ok:?}"
        );
    }
    // The fuzzer's two finds: token tables declaring more than the file holds (openusd panicked on one and
    // allocated 9 PB on the other). The rest are `src/usd/crate_check.rs`'s hostile files: arrays declaring 2^40
    // elements (openusd aborts allocating 4-13 TB), values holding themselves (a stack overflow, or a loop), path
    // trees built exponentially often or quadratically long, the same inside a .usdz, and a deflated .usdz layer.
    // `usd::read` refuses all of them before openusd reads them. And a prim named `a}` and an attribute named
    // `xfor}Op:scale`, which openusd takes for their own parents (a query of the prim recursed until the stack
    // overflowed; of the attribute, looped for good): refused before they are queried.
    for hostile in [
        "c-truncated.usdc",
        "a-huge-count.usda",
        "c-token-table-overflow.usdc",
        "c-token-table-9pb.usdc",
        "c-points-2pow40.usdc",
        "c-token-array-2pow40.usdc",
        "c-compressed-ints-2pow40.usdc",
        "c-dictionary-holding-itself.usdc",
        "c-dictionary-looping.usdc",
        "c-time-samples-holding-themselves.usdc",
        "c-path-tree-exponential.usdc",
        "c-path-tree-quadratic.usdc",
        "z-points-2pow40.usdz",
        "z-deflated-points-2pow40.usdz",
        "a-prim-own-parent.usda",
        "a-attribute-own-parent.usda",
    ] {
        assert!(!ok.iter().any(|n| n == hostile), "{hostile} accepted");
    }
}

use std::io::Cursor;

use super::*;

fn data(name: &str) -> Vec<u8> {
    std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/usd")
            .join(name),
    )
    .unwrap()
}

/// `bytes` with the u64 at `offset` set to `value`.
fn with(mut bytes: Vec<u8>, offset: usize, value: u64) -> Vec<u8> {
    bytes[offset..offset + 8].copy_from_slice(&value.to_le_bytes());
    bytes
}

/// The offset of section `name`'s start in `bytes`' table of contents.
fn section_start(bytes: &[u8], name: &str) -> usize {
    let u = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap()) as usize;
    let toc = u(16);
    (0..u(toc))
        .map(|k| toc + 8 + 32 * k)
        .find(|&e| bytes[e..e + 16].starts_with(name.as_bytes()) && bytes[e + name.len()] == 0)
        .map(|e| u(e + 16))
        .unwrap()
}

/// The crate file `bytes` walked in memory.
fn walked(bytes: &[u8]) -> Result<(), String> {
    walk(&mut Crate {
        src: Cursor::new(bytes),
        base: 0,
        len: bytes.len() as u64,
    })
}

/// The stage file `bytes` named `name` checked as `usd::read` checks it.
fn checked(name: &str, bytes: &[u8]) -> Result<(), String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    check(&path)
}

/// `f` run on a walk of `bytes` (a version 0.8 crate file) with no memory bound.
fn unbounded<T>(bytes: &[u8], f: impl FnOnce(&mut Values<Cursor<&[u8]>>) -> T) -> T {
    let mut c = Crate {
        src: Cursor::new(bytes),
        base: 0,
        len: bytes.len() as u64,
    };
    f(&mut Values::new(&mut c, 0x00_08_00, 0, u64::MAX))
}

/// The value representations of `bytes`' fields.
fn reps(bytes: &[u8]) -> Vec<u64> {
    let Ok(reps) = unbounded(bytes, |v| v.reps(section_start(bytes, "FIELDS") as u64)) else {
        panic!("the fields do not decompress")
    };
    reps
}

/// The offset of the count of the largest uncompressed array of type `ty` among `bytes`' fields, and the count.
fn largest_array(bytes: &[u8], ty: u64) -> (usize, u64) {
    largest(bytes, ty, false)
}

/// The offset of the largest compressed array of type `ty` among `bytes`' fields, and its count.
fn largest_compressed(bytes: &[u8], ty: u64) -> (usize, u64) {
    largest(bytes, ty, true)
}

/// The offset and count of the largest array of type `ty` among `bytes`' fields that is stored in the file
/// (offset not 0, where the file's magic is), compressed or not as `compressed` says.
fn largest(bytes: &[u8], ty: u64, compressed: bool) -> (usize, u64) {
    reps(bytes)
        .into_iter()
        .filter(|r| {
            r >> 63 != 0
                && (r >> 48) & 0xff == ty
                && (r & 1 << 61 != 0) == compressed
                && r & 0xffff_ffff_ffff != 0
        })
        .map(|r| (r & 0xffff_ffff_ffff) as usize)
        .map(|at| {
            (
                at,
                u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()),
            )
        })
        .max_by_key(|&(_, count)| count)
        .unwrap()
}

#[test]
fn a_crate_file_passes_and_its_declared_sizes_are_held_to_the_file() {
    let good = data("groom.usdc");
    assert_eq!(walked(&good), Ok(()));
    assert_eq!(checked("g.usdc", &good), Ok(()));
    let tokens = section_start(&good, "TOKENS");
    // A token table claiming more than LZ4 can expand its compressed bytes to.
    let huge = with(good.clone(), tokens + 8, 1 << 40);
    assert!(walked(&huge)
        .unwrap_err()
        .contains("more than LZ4 can expand"));
    // Compressed bytes past the end of the file (the fuzzer's 9 PB table was one).
    let past = with(good.clone(), tokens + 16, 1 << 50);
    assert!(walked(&past).unwrap_err().contains("run past the end"));
    // A paths table declaring 2^40 paths: more than the file's tables may take.
    let paths = with(good.clone(), section_start(&good, "PATHS"), 1 << 40);
    assert!(walked(&paths).unwrap_err().contains("tables declare"));
    // A table of contents past the end, and a truncated file.
    assert!(walked(&with(good.clone(), 16, good.len() as u64)).is_err());
    assert!(walked(&good[..good.len() / 2]).is_err());
    assert!(walked(&good[..20]).unwrap_err().contains("32-byte header"));
}

#[test]
fn a_value_array_declaring_more_than_the_file_is_refused() {
    let good = data("groom.usdc");
    // The curves' points: the largest vec3f array.
    let (at, count) = largest_array(&good, 24);
    assert!(count >= 36 * 6, "{count} points");
    let bad = with(good.clone(), at, 1 << 40);
    let e = checked("g.usdc", &bad).unwrap_err();
    assert!(
        e.contains(&format!(
            "value array at byte {at} declares 1099511627776 elements of 12 bytes, more than the file's \
             remaining {} bytes",
            good.len() - at - 8
        )),
        "{e}"
    );
    // One point more than the file holds, and the count the file holds.
    let room = (good.len() - at - 8) as u64 / 12;
    assert!(walked(&with(good.clone(), at, room + 1)).is_err());
    assert!(walked(&with(good.clone(), at, room)).is_ok());
    // The token array the fuzzer found (xformOpOrder), at 2^40 tokens.
    let (at, _) = largest_array(&good, 11);
    let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
    assert!(
        e.contains("declares 1099511627776 elements of 4 bytes"),
        "{e}"
    );
}

/// The value representation of `bytes`' field whose array of type `ty` is at `at`.
fn field_of(bytes: &[u8], ty: u64, at: usize) -> usize {
    reps(bytes)
        .iter()
        .position(|r| (r >> 48) & 0xff == ty && r & 0xffff_ffff_ffff == at as u64)
        .unwrap()
}

/// An LZ4 block of `data` as one run of literals, behind openusd's chunk count (0), with its 8-byte size.
fn block_of(data: &[u8]) -> Vec<u8> {
    let mut b = vec![0u8];
    if data.len() < 15 {
        b.push((data.len() as u8) << 4);
    } else {
        b.push(0xf0);
        let mut rest = data.len() - 15;
        while rest >= 255 {
            b.push(255);
            rest -= 255;
        }
        b.push(rest as u8);
    }
    b.extend_from_slice(data);
    [(b.len() as u64).to_le_bytes().to_vec(), b].concat()
}

/// `values` in Pixar's integer coding for 32 bits: the commonest delta, 2-bit codes, the other deltas.
fn encode_ints(values: &[i32]) -> Vec<u8> {
    let mut prev = 0i32;
    let deltas: Vec<i32> = values
        .iter()
        .map(|&v| (v.wrapping_sub(prev), prev = v).0)
        .collect();
    let mut counts = std::collections::HashMap::new();
    deltas
        .iter()
        .for_each(|&d| *counts.entry(d).or_insert(0) += 1);
    let common = counts
        .into_iter()
        .max_by_key(|&(d, n)| (n, -(d as i64)))
        .map_or(0, |(d, _)| d);
    let mut codes = vec![0u8; deltas.len().div_ceil(4)];
    let mut rest = Vec::new();
    for (k, &d) in deltas.iter().enumerate() {
        let code = if d == common {
            0
        } else if let Ok(d) = i8::try_from(d) {
            rest.push(d as u8);
            1
        } else if let Ok(d) = i16::try_from(d) {
            rest.extend(d.to_le_bytes());
            2
        } else {
            rest.extend(d.to_le_bytes());
            3
        };
        codes[k / 4] |= code << (2 * (k % 4));
    }
    [common.to_le_bytes().to_vec(), codes, rest].concat()
}

/// `bytes` with section `name` moved to `section`, appended at the end (its table of contents entry
/// repointed).
fn with_section(bytes: Vec<u8>, name: &str, section: &[u8]) -> Vec<u8> {
    let u = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap()) as usize;
    let toc = u(16);
    let entry = (0..u(toc))
        .map(|k| toc + 8 + 32 * k)
        .find(|&e| bytes[e..e + 16].starts_with(name.as_bytes()) && bytes[e + name.len()] == 0)
        .unwrap();
    let start = bytes.len() as u64;
    let bytes = [bytes, section.to_vec()].concat();
    with(
        with(bytes, entry + 16, start),
        entry + 24,
        section.len() as u64,
    )
}

/// `bytes` with its fields' value representations edited by `edit`, which may append values to the file: a
/// FIELDS section at the end, its representations in a literal LZ4 block.
fn with_reps(bytes: &[u8], edit: impl FnOnce(&mut Vec<u64>, &mut Vec<u8>)) -> Vec<u8> {
    let mut reps = reps(bytes);
    let fields = section_start(bytes, "FIELDS");
    let indices = u64::from_le_bytes(bytes[fields + 8..fields + 16].try_into().unwrap()) as usize;
    let mut file = bytes.to_vec();
    edit(&mut reps, &mut file);
    let section = [
        (reps.len() as u64).to_le_bytes().to_vec(),
        bytes[fields + 8..fields + 16 + indices].to_vec(),
        block_of(
            &reps
                .iter()
                .flat_map(|r| r.to_le_bytes())
                .collect::<Vec<u8>>(),
        ),
    ]
    .concat();
    with_section(file, "FIELDS", &section)
}

/// `bytes` with a string table of one string (token 0), for dictionaries' keys (groom.usdc has no strings).
fn with_a_string(bytes: Vec<u8>) -> Vec<u8> {
    with_section(
        bytes,
        "STRINGS",
        &[&1u64.to_le_bytes()[..], &0u32.to_le_bytes()].concat(),
    )
}

/// `bytes` with its path tree replaced by a chain of `n` paths (the root, then each the child of the one before,
/// named by the longest token) whose jumps `jump` gives (the last one's is -2: no child, no sibling).
fn with_path_chain(bytes: &[u8], n: i32, jump: i32) -> Vec<u8> {
    let longest = {
        let Ok(tokens) = unbounded(bytes, |v| v.tokens(section_start(bytes, "TOKENS") as u64))
        else {
            panic!("the tokens do not decompress")
        };
        (0..tokens.len()).max_by_key(|&k| tokens[k]).unwrap() as i32
    };
    let jumps: Vec<i32> = (0..n).map(|k| if k + 1 == n { -2 } else { jump }).collect();
    let section = [
        (n as u64).to_le_bytes().to_vec(),
        (n as u64).to_le_bytes().to_vec(),
        block_of(&encode_ints(&(0..n).collect::<Vec<_>>())),
        block_of(&encode_ints(&vec![longest; n as usize])),
        block_of(&encode_ints(&jumps)),
    ]
    .concat();
    with_section(bytes.to_vec(), "PATHS", &section)
}

/// A `.usdz` of `entries` (name, bytes), stored as the USDZ spec asks.
fn package(entries: &[(&str, &[u8])]) -> Vec<u8> {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let stored =
        zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in entries {
        zip.start_file(*name, stored).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

/// A `.usdz` whose groom.usdc, `layer`, is deflated (as the spec does not allow and openusd reads: zip's
/// deflate is built for openusd).
fn deflated(layer: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let deflated = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("groom.usdc", deflated).unwrap();
    zip.write_all(layer).unwrap();
    zip.finish().unwrap().into_inner()
}

/// `package` with its entry `name` marked as deflated (compression method 8) in its local and central headers.
fn marked_deflated(mut package: Vec<u8>, name: &str) -> Vec<u8> {
    let u16_at = |p: &[u8], o: usize| u16::from_le_bytes([p[o], p[o + 1]]) as usize;
    for k in 0..package.len() - 4 {
        // The method's offset, and where the name and its length are, in a local or central header.
        let (method, name_at, length_at) =
            match u32::from_le_bytes(package[k..k + 4].try_into().unwrap()) {
                0x0403_4b50 => (k + 8, k + 30, k + 26),
                0x0201_4b50 => (k + 10, k + 46, k + 28),
                _ => continue,
            };
        if package.get(name_at..name_at + u16_at(&package, length_at)) == Some(name.as_bytes()) {
            package[method..method + 2].copy_from_slice(&8u16.to_le_bytes());
        }
    }
    package
}

/// The hostile files of these tests, by corpus name (`fuzz/corpus/usd/`, less the format byte).
fn hostile() -> Vec<(&'static str, Vec<u8>)> {
    let good = data("groom.usdc");
    let (points, _) = largest_array(&good, 24);
    let (tokens, _) = largest_array(&good, 11);
    let (ints, _) = largest_compressed(&good, 3);
    let field = field_of(&good, 24, points);
    let bad_points = with(good.clone(), points, 1 << 40);
    vec![
        ("c-points-2pow40.usdc", bad_points.clone()),
        (
            "c-token-array-2pow40.usdc",
            with(good.clone(), tokens, 1 << 40),
        ),
        (
            "c-compressed-ints-2pow40.usdc",
            with(good.clone(), ints, 1 << 40),
        ),
        (
            "c-dictionary-holding-itself.usdc",
            with_reps(&with_a_string(good.clone()), |reps, file| {
                // Points as a dictionary of one entry: this dictionary (its offset, 8, runs from the offset to
                // the value representation after it).
                let at = file.len() as u64;
                file.extend(1u64.to_le_bytes());
                file.extend(0u32.to_le_bytes());
                file.extend(8i64.to_le_bytes());
                file.extend((31 << 48 | at).to_le_bytes());
                reps[field] = 31 << 48 | at;
            }),
        ),
        (
            "c-dictionary-looping.usdc",
            with_reps(&with_a_string(good.clone()), |reps, file| {
                // Points as a dictionary of 2^40 entries: the first leads to an inlined int, each next one's
                // offset (-12) back to that int, after which the next entry begins again.
                let at = file.len() as u64;
                file.extend((1u64 << 40).to_le_bytes());
                file.extend(0u32.to_le_bytes());
                file.extend(8i64.to_le_bytes());
                file.extend((3u64 << 48 | 1 << 62 | 7).to_le_bytes());
                file.extend(0u32.to_le_bytes());
                file.extend((-12i64).to_le_bytes());
                reps[field] = 31 << 48 | at;
            }),
        ),
        (
            "c-time-samples-holding-themselves.usdc",
            with_reps(&good, |reps, file| {
                // Points as time samples: offsets to the times (a double vector of one, at +40) and to the
                // samples (at +24: one, these time samples).
                let at = file.len() as u64;
                file.extend(8i64.to_le_bytes());
                file.extend((48u64 << 48 | (at + 40)).to_le_bytes());
                file.extend(8i64.to_le_bytes());
                file.extend(1u64.to_le_bytes());
                file.extend((46u64 << 48 | at).to_le_bytes());
                file.extend(1u64.to_le_bytes());
                file.extend(1.0f64.to_le_bytes());
                reps[field] = 46 << 48 | at;
            }),
        ),
        (
            "c-path-tree-exponential.usdc",
            with_path_chain(&good, 64, 1),
        ),
        (
            "c-path-tree-quadratic.usdc",
            with_path_chain(&good, 1 << 15, -1),
        ),
        (
            "z-points-2pow40.usdz",
            package(&[("groom.usdc", &bad_points)]),
        ),
        ("z-deflated-points-2pow40.usdz", deflated(&bad_points)),
    ]
}

/// A file of [`hostile`].
fn hostile_file(name: &str) -> Vec<u8> {
    hostile().into_iter().find(|(n, _)| *n == name).unwrap().1
}

#[test]
fn a_compressed_array_declaring_more_than_its_bytes_decode_to_is_refused() {
    let good = data("groom.usdc");
    // The mesh's face vertex indices: the largest compressed int array.
    let (at, count) = largest_compressed(&good, 3);
    assert!(count > 100, "{count}");
    let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
    assert!(
        e.contains(&format!(
            "compressed value array at byte {at} declares 1099511627776 elements, more than"
        )),
        "{e}"
    );
    // Its compressed size past the end of the file.
    let e = walked(&with(good.clone(), at + 8, 1 << 40)).unwrap_err();
    assert!(e.contains("compressed bytes run past the end"), "{e}");
    // The widths: a compressed float array.
    let (at, _) = largest_compressed(&good, 8);
    let e = walked(&with(good.clone(), at, 1 << 40)).unwrap_err();
    assert!(e.contains("declares 1099511627776 elements"), "{e}");
    // A list operation's paths (a relationship's targets) and a token vector (a prim's children).
    let path_ops: Vec<usize> = reps(&good)
        .into_iter()
        .filter(|r| (r >> 48) & 0xff == 34)
        .map(|r| (r & 0xffff_ffff_ffff) as usize)
        .collect();
    assert_eq!(good[path_ops[0]], 3, "an explicit list");
    let e = walked(&with(good.clone(), path_ops[0] + 1, 1 << 40)).unwrap_err();
    assert!(
        e.contains("declares 1099511627776 elements of 4 bytes"),
        "{e}"
    );
    let children = reps(&good)
        .into_iter()
        .find(|r| (r >> 48) & 0xff == 41)
        .map(|r| (r & 0xffff_ffff_ffff) as usize)
        .unwrap();
    let e = walked(&with(good.clone(), children, 1 << 40)).unwrap_err();
    assert!(
        e.contains("declares 1099511627776 elements of 4 bytes"),
        "{e}"
    );
}

#[test]
fn rewritten_tables_read_and_values_holding_themselves_are_refused() {
    let good = data("groom.usdc");
    // The rewriting itself keeps the file good, for the walk and for openusd.
    let same = with_reps(&good, |_, _| {});
    assert_eq!(walked(&same), Ok(()));
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("same.usdc"), &same).unwrap();
    let stage = super::super::read(&dir.path().join("same.usdc"), None, 0.01).unwrap();
    assert_eq!(stage.strands.unwrap().strand_count(), 36);
    let e = walked(&hostile_file("c-dictionary-holding-itself.usdc")).unwrap_err();
    assert!(
        e.contains(&format!("nest more than {MAX_DEPTH} deep")),
        "{e}"
    );
    let e = walked(&hostile_file("c-time-samples-holding-themselves.usdc")).unwrap_err();
    assert!(
        e.contains(&format!("nest more than {MAX_DEPTH} deep")),
        "{e}"
    );
    let e = walked(&hostile_file("c-dictionary-looping.usdc")).unwrap_err();
    assert!(e.contains("reads more than"), "{e}");
}

#[test]
fn a_path_tree_reaching_an_entry_twice_or_building_too_much_is_refused() {
    let good = data("groom.usdc");
    // A chain of 64 paths each the child of the one before passes; with jumps of 1 (a child and a sibling,
    // both the next entry) openusd would build entry k 2^k times: the last entry is the first reached again.
    assert_eq!(walked(&with_path_chain(&good, 64, -1)), Ok(()));
    let e = walked(&hostile_file("c-path-tree-exponential.usdc")).unwrap_err();
    assert!(e.contains("reaches entry 63 twice"), "{e}");
    // 2^15 nested paths: 2^29 path strings of up to 2^15 components, from a few KB.
    let e = walked(&hostile_file("c-path-tree-quadratic.usdc")).unwrap_err();
    assert!(e.contains("tables and values declare"), "{e}");
}

#[test]
fn a_package_s_crate_files_are_walked_and_compressed_layers_refused() {
    let good = data("groom.usdc");
    assert_eq!(checked("g.usdz", &data("groom.usdz")), Ok(()));
    assert_eq!(
        checked("g.usdz", &package(&[("groom.usdc", &good)])),
        Ok(())
    );
    // The points at 2^40 in the package's groom.usdc, through `usd::read`.
    let (at, _) = largest_array(&good, 24);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("g.usdz");
    std::fs::write(&path, hostile_file("z-points-2pow40.usdz")).unwrap();
    let e = super::super::read(&path, None, 0.01)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&format!(
            "malformed file: the package's groom.usdc: value array at byte {at} declares 1099511627776 elements of \
             12 bytes"
        )),
        "{e}"
    );
    // Also when the crate file is not the first entry nor named as one.
    let named = package(&[
        ("a.usda", b"#usda 1.0\n"),
        ("b.bin", &with(good.clone(), at, 1 << 40)),
    ]);
    assert!(checked("g.usdz", &named)
        .unwrap_err()
        .contains("the package's b.bin"));
    // A compressed layer is refused; a compressed texture is left.
    let e = checked("g.usdz", &hostile_file("z-deflated-points-2pow40.usdz")).unwrap_err();
    assert!(e.contains("groom.usdc is compressed (Deflated)"), "{e}");
    assert!(checked("g.usdz", &deflated(&good))
        .unwrap_err()
        .contains("compressed (Deflated)"));
    let texture = marked_deflated(
        package(&[("groom.usdc", &good), ("sky.exr", b"not read")]),
        "sky.exr",
    );
    assert_eq!(checked("g.usdz", &texture), Ok(()));
}

/// Writes [`hostile`] into the fuzz corpus, each behind its format byte (1: `.usdc`, 2: `.usdz`):
/// `cargo test --release --lib write_usd_corpus -- --ignored`.
#[test]
#[ignore]
fn write_usd_corpus() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/usd");
    for (name, bytes) in hostile() {
        let kind = if name.ends_with(".usdz") { 2u8 } else { 1 };
        std::fs::write(dir.join(name), [&[kind][..], &bytes].concat()).unwrap();
    }
}

#[test]
fn openusd_objects_fit_the_bytes_counted_for_them() {
    use openusd::{sdf, tf};
    use std::mem::size_of;
    for size in [
        size_of::<String>(),
        size_of::<tf::Token>(),
        size_of::<sdf::Path>(),
        size_of::<sdf::AssetPath>(),
        size_of::<sdf::Reference>(),
        size_of::<sdf::Payload>(),
        size_of::<sdf::Value>(),
        size_of::<(String, sdf::Value)>(),
    ] {
        assert!(size as u64 <= PER_OBJECT, "{size} bytes");
    }
}

#[test]
fn ints_decode_as_openusd_decodes_them() {
    // Common delta 1, then a small (-3), a medium (300) and a large (70000) delta: 0b11_10_01_00.
    let mut data = 1i32.to_le_bytes().to_vec();
    data.push(0b11_10_01_00);
    data.push(-3i8 as u8);
    data.extend(300i16.to_le_bytes());
    data.extend(70000i32.to_le_bytes());
    assert_eq!(
        decode_ints(&data, 4),
        Some(vec![1, (-2i32) as u32, 298, 70298])
    );
    assert_eq!(decode_ints(&data[..data.len() - 1], 4), None);
}

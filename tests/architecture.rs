//! The map is true: `docs/architecture.md` names every source file under `src/` (and no file that is gone), its
//! layer table names every top-level module, `lib.rs`' module doc names every module it declares, and no code
//! imports a module of a higher layer than its own.
//!
//! The layer table is the markdown table under `## Layers` in `docs/architecture.md`: one row per layer, top
//! first, `| N | module module ... |`. A module may use modules of its own layer or any layer below. Only code is
//! read: comment lines are skipped (doc links may point anywhere), and so are test code (items marked
//! `#[cfg(test)]`, and files named `tests.rs` or `testing.rs`), which may reach up for fixtures.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("cannot read {rel}: {e}"))
}

/// Every `.rs` file under `src/`, as paths relative to `src/` with `/` separators.
fn source_files() -> Vec<String> {
    fn walk(dir: &Path, base: &Path, out: &mut Vec<String>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, base, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let rel: PathBuf = path.strip_prefix(base).unwrap().into();
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    let mut files = Vec::new();
    let src = root().join("src");
    walk(&src, &src, &mut files);
    files.sort();
    files
}

/// The top-level module a source file belongs to (`main.rs` and `cli/` are the binary, named `cli`).
fn module_of(file: &str) -> String {
    let first = file.split('/').next().unwrap();
    match first.trim_end_matches(".rs") {
        "main" | "cli" => "cli".to_owned(),
        m => m.to_owned(),
    }
}

/// The layer table: module → layer number (1 = top).
fn layers(doc: &str) -> BTreeMap<String, usize> {
    let section = doc
        .split("\n## Layers")
        .nth(1)
        .expect("docs/architecture.md has a `## Layers` section");
    let section = section.split("\n## ").next().unwrap();
    let mut layers = BTreeMap::new();
    for line in section.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 3 {
            continue;
        }
        let Ok(n) = cells[1].parse::<usize>() else {
            continue;
        };
        for module in cells[2].split_whitespace() {
            let module = module.trim_matches('`').trim_end_matches(',');
            assert!(
                layers.insert(module.to_owned(), n).is_none(),
                "docs/architecture.md: module {module} is in two layers"
            );
        }
    }
    assert!(
        !layers.is_empty(),
        "docs/architecture.md: the layer table has no rows"
    );
    layers
}

/// The modules `lib.rs` declares (`pub mod x;`).
fn declared_modules(lib: &str) -> Vec<String> {
    lib.lines()
        .filter_map(|l| l.trim().strip_prefix("pub mod "))
        .map(|m| m.trim_end_matches(';').to_owned())
        .collect()
}

/// The lines of `text` that are code: not comments, not inside an item marked `#[cfg(test)]` (the item's braces
/// are followed to its end), with their 0-based line numbers.
fn code_lines(text: &str) -> Vec<(usize, &str)> {
    let mut out = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((i, line)) = lines.next() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("//") {
            continue;
        }
        if trimmed.starts_with("#[cfg(test)]") {
            // Skip the item: up to a `;` ending a one-line item, or until its braces balance.
            let mut depth = 0i32;
            let mut opened = false;
            for (_, l) in lines.by_ref() {
                depth += l.matches('{').count() as i32 - l.matches('}').count() as i32;
                opened |= l.contains('{');
                if (opened && depth <= 0) || (!opened && l.trim_end().ends_with(';')) {
                    break;
                }
            }
            continue;
        }
        out.push((i, line));
    }
    out
}

#[test]
fn the_map_names_every_source_file_and_no_missing_one() {
    let doc = read("docs/architecture.md");
    let files = source_files();
    let missing: Vec<&String> = files
        .iter()
        .filter(|f| !doc.contains(&format!("`{f}`")))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/architecture.md does not name these source files (as `path/under/src.rs`): {missing:?}"
    );
    // Every backticked path ending in .rs that the map names must exist.
    let named: BTreeSet<&str> = doc
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| s.ends_with(".rs") && !s.contains(' ') && !s.starts_with("tests/"))
        .filter(|s| !s.starts_with("benches/") && !s.starts_with("fuzz/") && *s != "build.rs")
        .collect();
    let gone: Vec<&&str> = named
        .iter()
        .filter(|n| !files.iter().any(|f| f == *n))
        .collect();
    assert!(
        gone.is_empty(),
        "docs/architecture.md names source files that do not exist: {gone:?}"
    );
}

#[test]
fn every_module_has_a_layer_and_lib_rs_names_it() {
    let doc = read("docs/architecture.md");
    let layers = layers(&doc);
    let lib = read("src/lib.rs");
    let docs: String = lib
        .lines()
        .filter(|l| l.starts_with("//!"))
        .collect::<Vec<_>>()
        .join("\n");
    let mut modules = declared_modules(&lib);
    modules.push("cli".to_owned());
    for m in &modules {
        assert!(
            layers.contains_key(m),
            "module {m} has no row in docs/architecture.md's layer table"
        );
        if m != "cli" {
            assert!(
                docs.contains(&format!("[`{m}`]")) || docs.contains(&format!("[`mod@{m}`]")),
                "lib.rs' module doc does not name module {m} (as [`{m}`])"
            );
        }
    }
    for m in layers.keys() {
        assert!(
            modules.contains(m),
            "docs/architecture.md's layer table names {m}, which lib.rs does not declare"
        );
    }
}

#[test]
fn no_import_runs_up_the_layers() {
    let layers = layers(&read("docs/architecture.md"));
    let mut upward = Vec::new();
    for file in source_files() {
        let name = file.rsplit('/').next().unwrap();
        if name == "tests.rs" || name == "testing.rs" {
            continue;
        }
        let from = module_of(&file);
        let Some(&own) = layers.get(&from) else {
            continue; // reported by every_module_has_a_layer_and_lib_rs_names_it
        };
        let text = read(&format!("src/{file}"));
        for (i, line) in code_lines(&text) {
            for prefix in ["crate::", "cuticle::"] {
                for (at, _) in line.match_indices(prefix) {
                    let rest = &line[at + prefix.len()..];
                    let target: String = rest
                        .chars()
                        .take_while(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || *c == '_')
                        .collect();
                    if target == from {
                        continue;
                    }
                    if let Some(&theirs) = layers.get(&target) {
                        if theirs < own {
                            upward.push(format!(
                                "src/{file}:{}: {from} (layer {own}) uses {target} (layer {theirs})",
                                i + 1
                            ));
                        }
                    }
                }
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports up the layer order of docs/architecture.md:\n{}",
        upward.join("\n")
    );
}

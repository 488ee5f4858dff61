//! Build script: finds Embree (4 preferred, else 3), generates its bindings with bindgen, and compiles the small
//! OpenImageIO C++ shim in `ffi/` into a shared library that the binary embeds. Any missing native dependency stops the build with one message naming the Debian
//! packages to install.

use std::env;
use std::path::PathBuf;

const APT_HINT: &str =
    "sudo apt-get install libembree-dev libopenimageio-dev libclang-dev clang pkg-config";

fn fail(what: &str) -> ! {
    eprintln!("\n\ncuticle build error: {what}\n  on Debian/Ubuntu install the native dependencies with:\n    {APT_HINT}\n");
    panic!("cuticle build error: {what} (install: {APT_HINT})");
}

/// Which Embree major version the headers belong to, and where they are.
struct Embree {
    major: u32,
    include_dirs: Vec<PathBuf>,
}

fn find_embree() -> Embree {
    // `EMBREE_DIR` (an install prefix with `include/embree{4,3}/rtcore.h` and `lib/`) wins when set, so a custom
    // Embree (e.g. `scripts/embree4.sh DIR`) is used even where the system has another one.
    if let Some(dir) = env::var_os("EMBREE_DIR") {
        let dir = PathBuf::from(dir);
        let lib = dir.join("lib");
        for major in [4, 3] {
            let include = dir.join("include");
            if include.join(format!("embree{major}/rtcore.h")).exists() {
                println!("cargo:rustc-link-search=native={}", lib.display());
                // The binaries find the library where they were linked against it, without LD_LIBRARY_PATH.
                println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
                println!("cargo:rustc-link-lib=embree{major}");
                return Embree {
                    major,
                    include_dirs: vec![include],
                };
            }
        }
        fail(&format!(
            "EMBREE_DIR={} has neither include/embree4/rtcore.h nor include/embree3/rtcore.h",
            dir.display()
        ));
    }
    // Embree 4 ships a pkg-config file; Debian 12's Embree 3.13.5 ships none, so fall back to the header location.
    if let Ok(lib) = pkg_config::Config::new()
        .atleast_version("4.0")
        .probe("embree4")
    {
        return Embree {
            major: 4,
            include_dirs: lib.include_paths,
        };
    }
    let roots = ["/usr/include", "/usr/local/include"].map(PathBuf::from);
    for root in &roots {
        if root.join("embree4/rtcore.h").exists() {
            println!("cargo:rustc-link-lib=embree4");
            return Embree {
                major: 4,
                include_dirs: vec![root.clone()],
            };
        }
    }
    if let Ok(lib) = pkg_config::Config::new().probe("embree") {
        return Embree {
            major: 3,
            include_dirs: lib.include_paths,
        };
    }
    for root in &roots {
        if root.join("embree3/rtcore.h").exists() {
            println!("cargo:rustc-link-lib=embree3");
            return Embree {
                major: 3,
                include_dirs: vec![root.clone()],
            };
        }
    }
    fail("Embree headers not found (looked for embree4/rtcore.h and embree3/rtcore.h; set EMBREE_DIR for a custom install)");
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=ffi");
    println!("cargo:rerun-if-env-changed=EMBREE_DIR");
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    let out = PathBuf::from(env::var("OUT_DIR").expect("cargo sets OUT_DIR"));

    // --- Embree bindings ---------------------------------------------------------------------------------------
    let embree = find_embree();
    if embree.major == 4 {
        println!("cargo:rustc-cfg=embree4");
    }
    let mut builder = bindgen::Builder::default()
        .header("ffi/embree.h")
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC.*")
        .prepend_enum_name(false)
        .derive_default(true)
        .layout_tests(true);
    if embree.major == 4 {
        builder = builder.clang_arg("-DCUTICLE_EMBREE4");
    }
    for dir in &embree.include_dirs {
        builder = builder.clang_arg(format!("-I{}", dir.display()));
    }
    let bindings =
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| builder.generate())) {
            Ok(Ok(b)) => b,
            Ok(Err(e)) => fail(&format!("bindgen could not read the Embree headers: {e}")),
            Err(_) => fail("bindgen could not load libclang (package libclang-dev)"),
        };
    bindings
        .write_to_file(out.join("embree_bindings.rs"))
        .expect("write embree bindings to OUT_DIR");

    // --- OpenImageIO shim ---------------------------------------------------------------------------------------
    // A shared library linked against OpenImageIO, embedded in the binary and loaded on first use
    // (src/sys/oiio.rs says why: OpenImageIO's 260 dependencies cost every process half a second at start-up).
    // So nothing here links OpenImageIO into cuticle itself.
    let oiio = match pkg_config::Config::new()
        .cargo_metadata(false)
        .probe("OpenImageIO")
    {
        Ok(lib) => lib,
        Err(e) => fail(&format!("OpenImageIO not found by pkg-config ({e})")),
    };
    let mut cc = cc::Build::new();
    cc.cpp(true)
        .pic(true)
        .cargo_metadata(false)
        .flag_if_supported("-std=c++17")
        .warnings(true)
        // Under cargo-fuzz (-Zsanitizer=address) cc adds -fsanitize=address, and a shim linked against gcc's libasan
        // aborts the fuzz target when it is loaded beside rustc's ASan runtime: the shim is not instrumented.
        .flag("-fno-sanitize=address");
    for dir in &oiio.include_paths {
        cc.include(dir);
    }
    let shim = out.join("libcuticle_oiio.so");
    let mut link = cc.get_compiler().to_command();
    link.arg("-shared")
        .arg("ffi/oiio_shim.cpp")
        .arg("-o")
        .arg(&shim)
        .arg("-Wl,-soname,libcuticle_oiio.so")
        // Fail here, not at dlopen, if a symbol is missing.
        .arg("-Wl,--no-undefined");
    for dir in &oiio.link_paths {
        link.arg(format!("-L{}", dir.display()));
        // The shim finds a non-system OpenImageIO where it was linked against it.
        link.arg(format!("-Wl,-rpath,{}", dir.display()));
    }
    for lib in &oiio.libs {
        link.arg(format!("-l{lib}"));
    }
    match link.status() {
        Ok(status) if status.success() => {}
        Ok(status) => fail(&format!(
            "compiling the OpenImageIO shim failed ({status}): {link:?}"
        )),
        Err(e) => fail(&format!(
            "cannot run the C++ compiler for the OpenImageIO shim: {e}"
        )),
    }
}

//! Finds the system Embree and generates bindings for its header with bindgen.
//!
//! Search order: pkg-config `embree4`, then `embree3`, then the `EMBREE_DIR` variable (a prefix
//! with include/ and lib/), then the standard Debian paths (Debian 12 ships Embree 3.13 without
//! a .pc file). Emits `cfg(embree4)` or `cfg(embree3)` for the version found.

use std::path::PathBuf;
use std::process::Command;

struct Found {
    version: u32,
    include: PathBuf,
    lib_dirs: Vec<PathBuf>,
    how: String,
}

fn pkg_config(name: &str, version: u32) -> Option<Found> {
    let run = |arg: &str| {
        let out = Command::new("pkg-config").args([arg, name]).output().ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    let include = run("--variable=includedir")?;
    let libs = run("--libs-only-L").unwrap_or_default();
    let lib_dirs = libs
        .split_whitespace()
        .filter_map(|s| s.strip_prefix("-L"))
        .map(PathBuf::from)
        .collect();
    Some(Found {
        version,
        include: PathBuf::from(include),
        lib_dirs,
        how: format!("pkg-config {name}"),
    })
}

fn from_prefix(prefix: PathBuf, how: String) -> Option<Found> {
    for version in [4, 3] {
        let include = prefix.join("include");
        if include.join(format!("embree{version}/rtcore.h")).exists() {
            let lib_dirs = vec![
                prefix.join("lib"),
                prefix.join("lib64"),
                prefix.join("lib/x86_64-linux-gnu"),
            ];
            return Some(Found {
                version,
                include,
                lib_dirs,
                how,
            });
        }
    }
    None
}

fn main() {
    println!("cargo::rustc-check-cfg=cfg(embree3)");
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    println!("cargo::rerun-if-env-changed=EMBREE_DIR");
    let found = pkg_config("embree4", 4)
        .or_else(|| pkg_config("embree3", 3))
        .or_else(|| {
            std::env::var_os("EMBREE_DIR")
                .and_then(|d| from_prefix(PathBuf::from(d), "EMBREE_DIR".into()))
        })
        .or_else(|| from_prefix(PathBuf::from("/usr"), "standard paths under /usr".into()))
        .or_else(|| {
            from_prefix(
                PathBuf::from("/usr/local"),
                "standard paths under /usr/local".into(),
            )
        });
    let Some(found) = found else {
        panic!(
            "Embree not found (tried pkg-config embree4/embree3, EMBREE_DIR, /usr, /usr/local). \
             Install it (Debian: ./scripts/setup-debian, or apt-get install libembree-dev \
             libclang1-14 libclang-common-14-dev), set EMBREE_DIR, or build without Embree: \
             cargo build --no-default-features"
        );
    };
    let version = found.version;
    for dir in &found.lib_dirs {
        println!("cargo::rustc-link-search=native={}", dir.display());
    }
    println!("cargo::rustc-link-lib=dylib=embree{version}");
    println!("cargo::rustc-cfg=embree{version}");
    println!("cargo::metadata=version={version}");
    let header = found.include.join(format!("embree{version}/rtcore.h"));
    println!("cargo::rerun-if-changed={}", header.display());
    let bindings = bindgen::Builder::default()
        .header(header.to_string_lossy())
        .clang_arg(format!("-I{}", found.include.display()))
        .allowlist_function("rtc.*")
        .allowlist_type("RTC.*")
        .allowlist_var("RTC_.*")
        .rustified_enum("RTCError")
        .derive_default(true)
        .layout_tests(false)
        .generate()
        .unwrap_or_else(|e| {
            panic!(
                "bindgen failed on {} (found by {}): {e}",
                header.display(),
                found.how
            )
        });
    let out =
        PathBuf::from(std::env::var("OUT_DIR").expect("cargo sets OUT_DIR")).join("bindings.rs");
    bindings
        .write_to_file(&out)
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
}

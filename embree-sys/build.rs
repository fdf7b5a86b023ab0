//! Finds the system Embree and generates bindings for its header with bindgen.
//!
//! Where it looks: with `EMBREE_DIR` set, only there (a prefix with include/ and lib/);
//! otherwise pkg-config `embree4`, then `embree3`, then the standard paths under /usr and
//! /usr/local (Debian 12 ships Embree 3.13 without a .pc file). Of the installations found,
//! Embree 4 wins over Embree 3; `EMBREE_VERSION=3` or `4` accepts only that version. Says which
//! one it took (a cargo warning) and emits `cfg(embree4)` or `cfg(embree3)` here and, through
//! the `links` metadata `DEP_EMBREE_VERSION`, to the crate that calls Embree.

use std::path::{Path, PathBuf};
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

/// The installations of Embree 4 and 3 under `prefix`: a header and a library beside it.
fn from_prefix(prefix: &Path, how: &str) -> Vec<Found> {
    let include = prefix.join("include");
    let lib_dirs: Vec<PathBuf> = [
        "lib",
        "lib64",
        "lib/x86_64-linux-gnu",
        "lib/aarch64-linux-gnu",
    ]
    .iter()
    .map(|d| prefix.join(d))
    .filter(|d| d.is_dir())
    .collect();
    [4, 3]
        .into_iter()
        .filter(|version| include.join(format!("embree{version}/rtcore.h")).exists())
        .filter_map(|version| {
            let library = format!("libembree{version}.so");
            let dir = lib_dirs.iter().find(|d| d.join(&library).exists())?;
            Some(Found {
                version,
                include: include.clone(),
                lib_dirs: vec![dir.clone()],
                how: format!("{how} {}", prefix.display()),
            })
        })
        .collect()
}

fn main() {
    println!("cargo::rustc-check-cfg=cfg(embree3)");
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    for var in ["EMBREE_DIR", "EMBREE_VERSION", "PKG_CONFIG_PATH"] {
        println!("cargo::rerun-if-env-changed={var}");
    }
    let wanted = match std::env::var("EMBREE_VERSION").ok().as_deref() {
        None | Some("") => None,
        Some("3") => Some(3),
        Some("4") => Some(4),
        Some(other) => panic!("EMBREE_VERSION={other}: expected 3 or 4 (or unset for either)"),
    };
    let dir = std::env::var_os("EMBREE_DIR").map(PathBuf::from);
    let mut found: Vec<Found> = match &dir {
        Some(dir) => from_prefix(dir, "EMBREE_DIR"),
        None => pkg_config("embree4", 4)
            .into_iter()
            .chain(pkg_config("embree3", 3))
            .chain(from_prefix(Path::new("/usr"), "standard paths under"))
            .chain(from_prefix(Path::new("/usr/local"), "standard paths under"))
            .collect(),
    };
    found.retain(|f| wanted.is_none_or(|v| f.version == v));
    // Stable: among the same version the search order above decides.
    found.sort_by_key(|f| std::cmp::Reverse(f.version));
    let Some(found) = found.into_iter().next() else {
        let version = wanted.map_or("Embree 3 or 4".to_string(), |v| format!("Embree {v}"));
        let place = match &dir {
            Some(dir) => format!(
                "EMBREE_DIR={} (include/embree{{3,4}}/rtcore.h and lib/libembree{{3,4}}.so)",
                dir.display()
            ),
            None => "pkg-config embree4/embree3, /usr, /usr/local".to_string(),
        };
        panic!(
            "{version} not found (looked in {place}). Install it (Debian: libembree-dev, which is \
             Embree 3 on Debian 12 and Embree 4 on Debian 13, with libclang for bindgen; \
             ./scripts/setup-debian installs them), set EMBREE_DIR to its prefix, or build \
             without Embree: cargo build --no-default-features"
        );
    };
    let version = found.version;
    println!(
        "cargo::warning=Embree {version} ({}; headers {}/embree{version})",
        found.how,
        found.include.display()
    );
    for dir in &found.lib_dirs {
        println!("cargo::rustc-link-search=native={}", dir.display());
    }
    println!("cargo::rustc-link-lib=dylib=embree{version}");
    println!("cargo::rustc-cfg=embree{version}");
    println!("cargo::metadata=version={version}");
    let headers = found.include.join(format!("embree{version}"));
    // The whole folder: rtcore_config.h decides the layout of the hit structures.
    println!("cargo::rerun-if-changed={}", headers.display());
    let header = headers.join("rtcore.h");
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

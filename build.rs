//! Passes the Embree major version that embree-sys found (its `links` metadata) on as
//! `cfg(embree3)` / `cfg(embree4)`, so src/accel/embree.rs can speak either API.

fn main() {
    println!("cargo::rustc-check-cfg=cfg(embree3)");
    println!("cargo::rustc-check-cfg=cfg(embree4)");
    println!("cargo::rerun-if-changed=build.rs");
    if let Ok(version) = std::env::var("DEP_EMBREE_VERSION") {
        println!("cargo::rustc-cfg=embree{version}");
    }
}

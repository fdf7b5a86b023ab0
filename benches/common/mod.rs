//! What the benchmarks share.

// Each bench compiles this module on its own and uses a part of it.
#![allow(dead_code)]

use std::path::Path;
use vmerge::accel::AccelKind;
use vmerge::scene::{self, LoadOptions, Scene};

/// The scene `name` at `path` over the `accel` backend, or `None`, said on stderr, when it is
/// absent or does not load: the conference room's mesh lives outside the project.
pub fn load_scene(name: &str, path: &Path, accel: AccelKind) -> Option<Scene> {
    if !path.exists() {
        eprintln!("skipping {name}: {} is absent", path.display());
        return None;
    }
    let options = LoadOptions {
        accel,
        lenient: true,
        shading_normals: true,
    };
    scene::load(path, &options)
        .map_err(|e| eprintln!("skipping {name}: {e}"))
        .ok()
}

/// Million rays per second in the best round.
pub fn best_mrays(times: &[f64], rays: usize) -> Option<f64> {
    let best = times.iter().copied().fold(f64::INFINITY, f64::min);
    best.is_finite().then(|| rays as f64 / best / 1e6)
}

/// The median over rounds of `a`'s time over `b`'s in the same round: a ratio of neighbours
/// in time, which a slow spell of the machine shifts far less than it shifts either time.
pub fn paired_ratio(a: &[f64], b: &[f64]) -> Option<f64> {
    let mut ratios: Vec<f64> = a.iter().zip(b).map(|(a, b)| a / b).collect();
    ratios.sort_by(f64::total_cmp);
    (!ratios.is_empty()).then(|| ratios[ratios.len() / 2])
}

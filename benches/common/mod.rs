//! What the benchmarks share.

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

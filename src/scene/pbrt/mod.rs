//! pbrt-v4 scene files (`.pbrt`): the subset that Bitterli's scenes and typical exports use,
//! read into the same [`SceneParts`] as the TOML format (docs/pbrt.md).
//!
//! `tokenizer` and `parser` turn text into checked directives, `directives` lists every
//! directive once (its form, where it may stand, its handler), `import` walks the files
//! (Include/Import) and hands the result to the scene builder; the handlers live by concept:
//! `state` (attributes, transforms, objects flattened, camera and settings), `shapes` (with
//! `ply`, which reads the meshes in parallel, each file once, and `quadrics`, disks and
//! cylinders as meshes), `material` (the rules that map
//! pbrt's materials onto vmerge's BSDFs), `textures` and `lights`. Every error names the file
//! and line; warnings too.

use super::{LoadOptions, SceneError, SceneParts};
use std::path::Path;

mod directives;
mod envmap;
mod import;
mod lights;
mod material;
mod parser;
pub mod ply;
mod quadrics;
mod shapes;
mod state;
#[cfg(test)]
mod tests;
mod textures;
mod tokenizer;

/// Reads a pbrt-v4 scene, with its warnings in the parts.
pub fn load_parts(path: &Path, options: &LoadOptions) -> Result<SceneParts, SceneError> {
    import::import(path, options.lenient)
}

/// Whether `path` names a pbrt scene (by its extension).
pub fn is_pbrt(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pbrt"))
}

//! pbrt-v4 scene files (`.pbrt`): the subset that Bitterli's scenes and typical exports use,
//! read into the same [`SceneParts`] as the TOML format (README, "pbrt-v4 scenes").
//!
//! `tokenizer` and `parser` turn text into checked directives, `import` runs pbrt's graphics
//! state over them (Include/Import, attributes, transforms, objects flattened), `ply` reads the
//! meshes (in parallel, each file once), and `material` holds the rules that map pbrt's
//! materials onto vmerge's BSDFs. Every error names the file and line; warnings too.

use super::{LoadOptions, SceneError, SceneParts};
use std::path::Path;

mod envmap;
mod import;
mod material;
mod parser;
pub mod ply;
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

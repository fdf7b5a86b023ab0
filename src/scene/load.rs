//! The TOML scene file and its OBJ/MTL meshes.
use super::{Scene, SceneError};
use crate::accel::AccelKind;
use std::path::Path;

#[derive(Clone, Copy, Debug)]
pub struct LoadOptions {
    pub accel: AccelKind,
    /// Clamp Phong materials with kd + ks > 1 (with a warning) instead of rejecting them.
    pub lenient: bool,
}

pub fn load(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let _ = (path, options);
    todo!("scene loader")
}

use crate::accel::AccelError;
use crate::files::FileError;
use std::path::PathBuf;
use thiserror::Error;

/// Everything that can be wrong with a scene. Each message names the file and the entry.
#[derive(Debug, Error)]
pub enum SceneError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error("{file}: {message}")]
    Parse { file: PathBuf, message: String },
    /// A problem at a line of a pbrt scene file.
    #[error("{file}:{line}: {message}")]
    At {
        file: PathBuf,
        line: u32,
        message: String,
    },
    #[error("{file}: {entry}: {message}")]
    Invalid {
        file: PathBuf,
        entry: String,
        message: String,
    },
    #[error("{file}: the lights' power overflows f32: {message}; scale the emission down")]
    LightPower { file: PathBuf, message: String },
    /// No geometry; `dropped` degenerate triangles were all there was.
    #[error("{file}: the scene has no geometry{}", dropped_note(*.dropped))]
    NoGeometry { file: PathBuf, dropped: usize },
    #[error("{file}: the scene has no lights (no emissive material, [[light]] or sky)")]
    NoLights { file: PathBuf },
    #[error("{file}: the scene has no [[camera]]")]
    NoCamera { file: PathBuf },
    #[error("{file}: no camera named or numbered '{camera}' (cameras: {available:?})")]
    UnknownCamera {
        file: PathBuf,
        camera: String,
        available: Vec<String>,
    },
    #[error("{file}: building the ray-query structure failed: {source}")]
    Accel { file: PathBuf, source: AccelError },
}

/// Where every triangle was dropped, the error says so (there is no scene to warn with).
fn dropped_note(dropped: usize) -> String {
    match dropped {
        0 => String::new(),
        n => format!(" (dropped {n} degenerate triangles)"),
    }
}

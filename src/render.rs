//! The progressive render loop: iterations, time limit, progress and reference errors.

use crate::accel::AccelKind;
use crate::integrator::Technique;
use serde::{Deserialize, Serialize};

/// Every option that changes the image. Serialized into the EXR so `continue` can resume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderOptions {
    pub technique: Technique,
    pub seed: u64,
    pub camera: Option<String>,
    pub resolution: Option<[u32; 2]>,
    /// MIS power (1 = balance heuristic, 2 = power heuristic).
    pub beta: f32,
    /// Merge radius in world units; `None` = the scene's default.
    pub radius: Option<f32>,
    /// Radius shrinking exponent (000 eq. 2.85); `None` = the technique's default.
    pub alpha: Option<f32>,
    /// Segments of a full path; `None` = the scene's default, 0 = unbounded.
    pub max_path_length: Option<u32>,
    /// Path length (in segments) from which Russian roulette may end paths.
    pub roulette: u32,
    pub no_vc: bool,
    pub no_vm: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            technique: Technique::Pt,
            seed: 0,
            camera: None,
            resolution: None,
            beta: 2.0,
            radius: None,
            alpha: None,
            max_path_length: None,
            roulette: 3,
            no_vc: false,
            no_vm: false,
        }
    }
}

/// How the scene's ray queries are answered; not part of the image.
#[derive(Clone, Copy, Debug)]
pub struct Execution {
    pub accel: AccelKind,
    pub threads: Option<usize>,
}

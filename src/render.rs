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

/// Renders `iterations` iterations of `options.technique` and returns the film: the library
/// call behind `vmerge render --iterations N` without progress, time limit or files.
pub fn render_iterations(
    scene: &crate::scene::Scene,
    options: &RenderOptions,
    iterations: u64,
) -> Result<crate::film::Film, crate::scene::SceneError> {
    let [width, height] = options.resolution.unwrap_or(scene.defaults.resolution);
    let camera = crate::scene::Camera::new(scene.camera(options.camera.as_deref())?, width, height);
    let mut film = crate::film::Film::new(width, height);
    let mut integrator = crate::integrator::create(crate::integrator::RenderContext {
        scene,
        camera,
        options,
    });
    let mut frame = vec![crate::color::Rgb::BLACK; film.pixel_count()];
    for iteration in 0..iterations {
        frame.fill(crate::color::Rgb::BLACK);
        integrator.render_iteration(iteration, &mut frame);
        film.add_iteration(&frame);
    }
    Ok(film)
}

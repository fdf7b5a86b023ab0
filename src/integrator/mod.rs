//! Integrators. Each renders one iteration at a time into a per-pixel frame: one eye sub-path
//! per pixel and, for the bidirectional ones, one light sub-path per pixel (001 sec. 2.3).

use crate::color::Rgb;
use crate::options::{RenderOptions, Technique};
use crate::scene::{Camera, Scene};
use upg::UpgCounters;

pub mod bpt;
pub mod connection;
pub mod density;
pub mod mis;
pub mod pt;
pub mod subpath;
pub mod upg;
pub mod vcm;

/// Counters an iteration reports besides its image.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IterationStats {
    /// Samples dropped for being NaN or infinite.
    pub dropped_samples: u64,
    /// Rays traced (closest-hit, shadow and tentative), for the samples-per-second display.
    pub rays: u64,
    pub upg: UpgCounters,
}

impl std::ops::Add for IterationStats {
    type Output = IterationStats;
    fn add(self, other: IterationStats) -> IterationStats {
        IterationStats {
            dropped_samples: self.dropped_samples + other.dropped_samples,
            rays: self.rays + other.rays,
            upg: self.upg + other.upg,
        }
    }
}

/// Everything an integrator needs that does not change between iterations.
pub struct RenderContext<'a> {
    pub scene: &'a Scene,
    pub camera: Camera,
    pub options: &'a RenderOptions,
}

impl RenderContext<'_> {
    /// Path-length bound in segments; `u32::MAX` when unbounded.
    pub fn max_path_length(&self) -> u32 {
        match self
            .options
            .max_path_length
            .unwrap_or(self.scene.defaults.max_path_length)
        {
            0 => u32::MAX,
            n => n,
        }
    }
}

/// One technique. `render_iteration` adds this iteration's estimate of every pixel's
/// radiance into `frame` (zeroed by the caller), using only random streams seeded from
/// (seed, iteration, pixel), so the result does not depend on the thread count.
pub trait Integrator: Send + Sync {
    fn render_iteration(&mut self, iteration: u64, frame: &mut [Rgb]) -> IterationStats;

    /// Technique-specific statistics for the metadata and the progress line.
    fn statistics(&self) -> Vec<(String, String)> {
        Vec::new()
    }
}

/// Creates the integrator for `ctx.options.technique`.
pub fn create<'a>(ctx: RenderContext<'a>) -> Box<dyn Integrator + 'a> {
    match ctx.options.technique {
        Technique::Pt => Box::new(pt::PathTracer::new(ctx)),
        Technique::Bpt => Box::new(bpt::Bpt::new(ctx)),
        Technique::Lt
        | Technique::Ppm
        | Technique::Bpm
        | Technique::Vcm
        | Technique::Upg
        | Technique::UpgCamera => Box::new(vcm::VertexCm::new(ctx)),
    }
}

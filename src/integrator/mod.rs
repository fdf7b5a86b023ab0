//! Integrators. Each renders one iteration at a time into a per-pixel frame: one eye sub-path
//! per pixel and, for the bidirectional ones, one light sub-path per pixel (001 sec. 2.3).
//!
//! Imports run downward here too: this file, `connection.rs`, `density.rs`, `mis.rs` and
//! `subpath.rs` are the shared layer and name no technique; the techniques (`pt.rs`, `bpt.rs`,
//! `vcm.rs`, `upg/`) name the shared layer, and only `vcm.rs` names `upg/`. The technique is
//! chosen above this module, in `render.rs`.

use crate::color::Rgb;
use crate::options::RenderOptions;
use crate::scene::{Camera, Scene};
use std::time::Duration;

pub mod bpt;
pub mod camera_rays;
pub mod connection;
pub mod density;
pub mod mis;
pub mod pt;
pub mod scatter;
pub mod subpath;
pub mod upg;
pub mod vcm;

/// Counters every technique reports of an iteration besides its image; a technique's own
/// counters go through [`Integrator::counters`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct IterationStats {
    /// Samples dropped for being NaN or infinite.
    pub dropped_samples: u64,
    /// Rays traced (closest-hit, shadow and tentative), for the samples-per-second display.
    pub rays: u64,
}

impl std::ops::Add for IterationStats {
    type Output = IterationStats;
    fn add(self, other: IterationStats) -> IterationStats {
        IterationStats {
            dropped_samples: self.dropped_samples + other.dropped_samples,
            rays: self.rays + other.rays,
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

    /// Technique-specific statistics for the metadata; the time since the run began gives
    /// their rates.
    fn statistics(&self, _elapsed: Duration) -> Vec<(String, String)> {
        Vec::new()
    }

    /// The technique's own work counts, totals over the iterations rendered so far, for the
    /// progress line, the live preview and the metadata's rates; none by default.
    fn counters(&self) -> Counters {
        Counters::default()
    }
}

/// Work counts a technique keeps of its own (UPG's merges and tentative rays), by name: what
/// they mean is the technique's to say, the render loop only hands them on.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Counters(Vec<(&'static str, u64)>);

impl Counters {
    pub fn new(counts: Vec<(&'static str, u64)>) -> Self {
        Counters(counts)
    }

    /// The count named `name`, if the technique reports one.
    pub fn get(&self, name: &str) -> Option<u64> {
        self.0
            .iter()
            .find(|(n, _)| *n == name)
            .map(|&(_, count)| count)
    }
}

//! The film: f64 accumulation of per-iteration estimates, EXR files with vmerge's metadata,
//! and tone-mapped PNG previews.

use crate::color::Rgb;
use rayon::prelude::*;

mod atomic;
pub mod exr;
pub mod metadata;
pub mod png;
mod reference;
mod splat;

pub use atomic::{atomic_write, remove_stale_temporaries};
pub use exr::{FilmError, Image};
pub use metadata::{ErrorSample, Metadata, MetadataError, TraceWindow};
pub use reference::{ErrorTracker, PERCEPTUAL_SHARE};
pub use splat::{add_splats, Splats};

/// Sum of all iterations' per-pixel estimates, in f64 so that long renders do not lose
/// precision; the image is `sum / iterations`.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub sum: Vec<[f64; 3]>,
    pub iterations: u64,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        Film {
            width,
            height,
            sum: vec![[0.0; 3]; width as usize * height as usize],
            iterations: 0,
        }
    }

    pub fn pixel_count(&self) -> usize {
        self.sum.len()
    }

    /// Adds one iteration's estimate (one value per pixel).
    pub fn add_iteration(&mut self, frame: &[Rgb]) {
        debug_assert_eq!(frame.len(), self.sum.len());
        // On every thread: a serial pass between iterations would hold up the others.
        self.sum.par_iter_mut().zip(frame).for_each(|(s, c)| {
            s[0] += c.r as f64;
            s[1] += c.g as f64;
            s[2] += c.b as f64;
        });
        self.iterations += 1;
    }

    /// Adds the iterations of another film of the same resolution: the sums add up, so the
    /// mean becomes the iteration-weighted mean of the two.
    pub fn accumulate(&mut self, other: &Film) {
        debug_assert_eq!((self.width, self.height), (other.width, other.height));
        for (s, o) in self.sum.iter_mut().zip(&other.sum) {
            for c in 0..3 {
                s[c] += o[c];
            }
        }
        self.iterations += other.iterations;
    }

    /// The mean radiance of each pixel.
    pub fn mean(&self) -> Vec<Rgb> {
        let scale = if self.iterations > 0 {
            1.0 / self.iterations as f64
        } else {
            0.0
        };
        self.sum
            .iter()
            .map(|s| {
                Rgb::new(
                    (s[0] * scale) as f32,
                    (s[1] * scale) as f32,
                    (s[2] * scale) as f32,
                )
            })
            .collect()
    }

    /// Mean radiance over the whole image, per channel.
    pub fn average(&self) -> [f64; 3] {
        average(&self.mean())
    }
}

/// Mean of an image, per channel, accumulated in f64.
pub fn average(pixels: &[Rgb]) -> [f64; 3] {
    let mut acc = [0.0f64; 3];
    for p in pixels {
        acc[0] += p.r as f64;
        acc[1] += p.g as f64;
        acc[2] += p.b as f64;
    }
    let n = pixels.len().max(1) as f64;
    acc.map(|a| a / n)
}

/// Adds a sample to a pixel unless it is NaN or infinite, which is counted instead: such
/// samples never reach the film.
#[inline]
pub fn add_sample(pixel: &mut Rgb, value: Rgb, dropped: &mut u64) {
    if value.is_finite() {
        *pixel += value;
    } else {
        *dropped += 1;
    }
}

//! Errors of a render against a reference image, for the whole image and the trace windows:
//! what `--reference` records in the metadata. The measures themselves are
//! [`crate::metrics`]'s.

use super::{ErrorSample, FilmError, Image, TraceWindow};
use crate::color::Rgb;
use crate::metrics::{self, pointwise, Measure, Selection};
use std::path::Path;
use std::time::Instant;

/// The perceptual measures (FLIP, SSIM) of a trace may take at most this share of the render
/// time so far: HDR-FLIP filters the image once per exposure, several times the cost of an
/// iteration of a fast technique on a large image.
pub const PERCEPTUAL_SHARE: f64 = 0.05;

/// Errors of a render's mean image against a reference, for the whole image and for each trace
/// window: what `--reference` records in the metadata.
pub struct ErrorTracker {
    reference: Image,
    traces: Vec<TraceWindow>,
    /// Seconds spent so far on the measures that are not pointwise.
    perceptual_seconds: f64,
}

impl ErrorTracker {
    /// Refuses (naming `path`, the reference's file) a reference whose resolution differs from
    /// the render's `width` x `height`, one with NaN or infinite pixels, and trace windows that
    /// lie wholly outside the image.
    pub fn new(
        reference: Image,
        path: &Path,
        width: u32,
        height: u32,
        traces: Vec<TraceWindow>,
    ) -> Result<Self, FilmError> {
        let invalid = |message: String| FilmError::Invalid {
            file: path.into(),
            message,
        };
        if (reference.width, reference.height) != (width, height) {
            return Err(invalid(format!(
                "the reference is {}x{}, the render {width}x{height}",
                reference.width, reference.height
            )));
        }
        if let Some(i) = reference.pixels.iter().position(|p| !p.is_finite()) {
            return Err(invalid(format!(
                "the reference has a NaN or infinite value at pixel ({}, {})",
                i % width as usize,
                i / width as usize
            )));
        }
        for t in &traces {
            let (x0, y0, x1, y1) = t.rect(width, height);
            if x0 >= x1 || y0 >= y1 {
                return Err(invalid(format!(
                    "the trace window {t} lies outside the {width}x{height} image"
                )));
            }
        }
        Ok(ErrorTracker {
            reference,
            traces,
            perceptual_seconds: 0.0,
        })
    }

    /// The image errors are measured against.
    pub fn reference(&self) -> &Image {
        &self.reference
    }

    /// The errors of `mean` (the render's mean image, row-major) after `seconds` and
    /// `iterations`: the pointwise measures always; the perceptual ones too at power-of-two
    /// iterations (evenly spaced on log-log convergence charts) while their cost so far stays
    /// within [`PERCEPTUAL_SHARE`] of `seconds`.
    pub fn measure(&mut self, mean: &[Rgb], seconds: f64, iterations: u64) -> ErrorSample {
        let affordable = self.perceptual_seconds <= PERCEPTUAL_SHARE * seconds;
        let all = iterations.is_power_of_two() && affordable;
        self.sample(mean, seconds, iterations, all)
    }

    /// Every measure of `mean`: the last sample of a run.
    pub fn measure_all(&mut self, mean: &[Rgb], seconds: f64, iterations: u64) -> ErrorSample {
        self.sample(mean, seconds, iterations, true)
    }

    fn sample(&mut self, mean: &[Rgb], seconds: f64, iterations: u64, all: bool) -> ErrorSample {
        debug_assert_eq!(mean.len(), self.reference.pixels.len());
        let (w, h) = (self.reference.width, self.reference.height);
        let started = Instant::now();
        let selection = if all {
            Selection::All
        } else {
            Selection::Pointwise
        };
        let errors = metrics::measure(mean, &self.reference.pixels, w, h, selection);
        if all {
            self.perceptual_seconds += started.elapsed().as_secs_f64();
        }
        let traces = self
            .traces
            .iter()
            .map(|t| {
                let e = pointwise::errors_in(mean, &self.reference.pixels, w, t.rect(w, h));
                [Measure::Mae, Measure::Rmse].map(|m| e.get(m).unwrap_or(0.0))
            })
            .collect();
        let mut others = metrics::Errors::default();
        for m in ErrorSample::OTHERS {
            if let Some(v) = errors.get(m) {
                others.set(m, v);
            }
        }
        ErrorSample {
            seconds,
            iterations,
            mae: errors.get(Measure::Mae).unwrap_or(0.0),
            rmse: errors.get(Measure::Rmse).unwrap_or(0.0),
            traces,
            others,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> Rgb) -> Image {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        Image {
            width,
            height,
            pixels,
        }
    }

    #[test]
    fn tracker_measures_image_and_windows() {
        let reference = image(16, 8, |x, y| Rgb::splat((x + y) as f32));
        let mean = image(16, 8, |x, y| {
            Rgb::splat((x + y) as f32 + if x < 4 && y < 4 { 1.0 } else { 0.0 })
        });
        let windows = vec![
            TraceWindow {
                x: 2,
                y: 2,
                half_width: 2,
            },
            TraceWindow {
                x: 12,
                y: 4,
                half_width: 2,
            },
        ];
        let mut tracker =
            ErrorTracker::new(reference, Path::new("ref.exr"), 16, 8, windows).unwrap();
        let e = tracker.measure(&mean.pixels, 1.5, 7);
        assert_eq!((e.seconds, e.iterations), (1.5, 7));
        assert_eq!(e.mae, 16.0 / 128.0);
        assert_eq!(e.rmse, (16.0f64 / 128.0).sqrt());
        assert_eq!(e.traces, vec![[1.0, 1.0], [0.0, 0.0]]);
        assert!(e.get(Measure::RelativeMse).is_some());
        // 8 pixels high: too small for FLIP and SSIM's windows.
        let e = tracker.measure_all(&mean.pixels, 1.5, 7);
        assert!(e.get(Measure::HdrFlip).is_none());
    }

    #[test]
    fn perceptual_measures_stay_within_their_share() {
        let reference = image(64, 64, |x, y| Rgb::splat((x * y) as f32 / 64.0));
        let mut tracker =
            ErrorTracker::new(reference.clone(), Path::new("r.exr"), 64, 64, vec![]).unwrap();
        // Iteration 3 is no power of two; iteration 4 at a render time of 0 s cannot afford
        // them once iteration 1 has spent any time on them.
        let perceptual = |e: &ErrorSample| e.get(Measure::Ssim).is_some();
        assert!(perceptual(&tracker.measure(&reference.pixels, 0.0, 1)));
        assert!(!perceptual(&tracker.measure(&reference.pixels, 1e9, 3)));
        assert!(!perceptual(&tracker.measure(&reference.pixels, 0.0, 4)));
        assert!(perceptual(&tracker.measure(&reference.pixels, 1e9, 8)));
        assert!(perceptual(&tracker.measure_all(&reference.pixels, 0.0, 9)));
    }

    #[test]
    fn tracker_refuses_bad_references_naming_the_file() {
        let ok = image(4, 4, |_, _| Rgb::WHITE);
        let path = Path::new("the-reference.exr");
        let mut nan = ok.clone();
        nan.pixels[5].g = f32::NAN;
        let outside = vec![TraceWindow {
            x: 10,
            y: 10,
            half_width: 2,
        }];
        for result in [
            ErrorTracker::new(ok.clone(), path, 4, 5, Vec::new()),
            ErrorTracker::new(nan, path, 4, 4, Vec::new()),
            ErrorTracker::new(ok, path, 4, 4, outside),
        ] {
            let message = result.err().expect("refused").to_string();
            assert!(message.contains("the-reference.exr"), "{message}");
        }
    }
}

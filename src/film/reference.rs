//! Errors of an image against a reference (000 sec. 3.4): the mean absolute error and the
//! root-mean-square error over all pixels and all three channels, for the whole image and for
//! the trace windows.

use super::{ErrorSample, FilmError, Image, TraceWindow};
use crate::color::Rgb;
use rayon::prelude::*;
use std::path::Path;

/// `(mae, rmse)` of `a` against `b` over the pixel rectangle `(x0, y0, x1, y1)`, meaning
/// `[x0, x1) x [y0, y1)`, of images `width` pixels wide:
///
/// mae = sum |a - b| / n and rmse = sqrt(sum (a - b)^2 / n), the sums running over the
/// rectangle's pixels and the channels R, G, B, n = 3 x pixels. An empty rectangle gives 0.
///
/// Rows are summed in parallel, then added in row order, so the result does not depend on the
/// thread count.
pub fn errors_in(a: &[Rgb], b: &[Rgb], width: u32, rect: (u32, u32, u32, u32)) -> (f64, f64) {
    let (x0, y0, x1, y1) = rect;
    let rows: Vec<(f64, f64)> = (y0..y1)
        .into_par_iter()
        .map(|y| {
            let start = y as usize * width as usize;
            let range = start + x0 as usize..start + x1 as usize;
            let (mut abs, mut sq) = (0.0f64, 0.0f64);
            for (p, q) in a[range.clone()].iter().zip(&b[range]) {
                for (p, q) in p.to_array().into_iter().zip(q.to_array()) {
                    let d = p as f64 - q as f64;
                    abs += d.abs();
                    sq += d * d;
                }
            }
            (abs, sq)
        })
        .collect();
    let (abs, sq) = rows
        .into_iter()
        .fold((0.0, 0.0), |(a, s), (ra, rs)| (a + ra, s + rs));
    let n = 3 * x1.saturating_sub(x0) as usize * y1.saturating_sub(y0) as usize;
    if n == 0 {
        return (0.0, 0.0);
    }
    (abs / n as f64, (sq / n as f64).sqrt())
}

/// Errors of a render's mean image against a reference, for the whole image and for each trace
/// window: what `--reference` records in the metadata.
pub struct ErrorTracker {
    reference: Image,
    traces: Vec<TraceWindow>,
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
        Ok(ErrorTracker { reference, traces })
    }

    /// The image errors are measured against.
    pub fn reference(&self) -> &Image {
        &self.reference
    }

    /// The errors of `mean` (the render's mean image, row-major) after `seconds` and
    /// `iterations`.
    pub fn measure(&self, mean: &[Rgb], seconds: f64, iterations: u64) -> ErrorSample {
        debug_assert_eq!(mean.len(), self.reference.pixels.len());
        let (w, h) = (self.reference.width, self.reference.height);
        let (mae, rmse) = errors_in(mean, &self.reference.pixels, w, (0, 0, w, h));
        let traces = self
            .traces
            .iter()
            .map(|t| {
                let (mae, rmse) = errors_in(mean, &self.reference.pixels, w, t.rect(w, h));
                [mae, rmse]
            })
            .collect();
        ErrorSample {
            seconds,
            iterations,
            mae,
            rmse,
            traces,
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
    fn errors_match_their_definition() {
        // a - b = (1, -2, 0) on one pixel of four: sum |d| = 3, sum d^2 = 5, n = 12.
        let b = image(2, 2, |_, _| Rgb::splat(1.0));
        let mut a = b.clone();
        a.pixels[3] = Rgb::new(2.0, -1.0, 1.0);
        let (mae, rmse) = errors_in(&a.pixels, &b.pixels, 2, (0, 0, 2, 2));
        assert_eq!(mae, 3.0 / 12.0);
        assert_eq!(rmse, (5.0f64 / 12.0).sqrt());
        // The window holding only that pixel: n = 3.
        let (mae, rmse) = errors_in(&a.pixels, &b.pixels, 2, (1, 1, 2, 2));
        assert_eq!(mae, 1.0);
        assert_eq!(rmse, (5.0f64 / 3.0).sqrt());
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
        let tracker = ErrorTracker::new(reference, Path::new("ref.exr"), 16, 8, windows).unwrap();
        let e = tracker.measure(&mean.pixels, 1.5, 7);
        assert_eq!((e.seconds, e.iterations), (1.5, 7));
        assert_eq!(e.mae, 16.0 / 128.0);
        assert_eq!(e.rmse, (16.0f64 / 128.0).sqrt());
        assert_eq!(e.traces, vec![[1.0, 1.0], [0.0, 0.0]]);
    }

    #[test]
    fn errors_do_not_depend_on_the_thread_count() {
        let mut rng = crate::sampling::Rng::from_seed(3, 0);
        let mut noise = |_, _| Rgb::new(rng.next_f32(), rng.next_f32() * 1e3, rng.next_f32());
        let a = image(64, 64, &mut noise);
        let b = image(64, 64, &mut noise);
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let (mae, rmse) = pool.install(|| errors_in(&a.pixels, &b.pixels, 64, (0, 0, 64, 64)));
            (mae.to_bits(), rmse.to_bits())
        };
        assert_eq!(run(1), run(3));
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

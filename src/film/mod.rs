//! The film: f64 accumulation of per-iteration estimates, EXR files with vmerge's metadata,
//! and tone-mapped PNG previews.

use crate::color::Rgb;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

pub mod exr;
mod metadata;
pub mod png;

pub use exr::{FilmError, Image};
pub use metadata::{ErrorSample, Metadata, TraceWindow};

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
        for (s, c) in self.sum.iter_mut().zip(frame) {
            s[0] += c.r as f64;
            s[1] += c.g as f64;
            s[2] += c.b as f64;
        }
        self.iterations += 1;
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

/// Writes a file atomically: into a temporary file in the same directory, flushed and synced,
/// then renamed over `path`. A crash or a full disk leaves either the old file or the new one,
/// never a half-written one.
pub fn atomic_write(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let temporary = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let result = (|| {
        let mut writer = BufWriter::new(File::create(&temporary)?);
        write(&mut writer)?;
        writer.flush()?;
        writer.get_ref().sync_all()?;
        drop(writer);
        std::fs::rename(&temporary, path)?;
        // The rename itself is durable only once the directory is synced.
        File::open(dir)?.sync_all()
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result
}

/// Mean absolute and root-mean-square error of `a` against `b` over the pixel rectangle
/// `[x0, x1) x [y0, y1)` of images `width` wide, over all three channels (000 sec. 3.4).
pub fn errors_in(a: &[Rgb], b: &[Rgb], width: u32, rect: (u32, u32, u32, u32)) -> (f64, f64) {
    let (x0, y0, x1, y1) = rect;
    let (mut abs, mut sq, mut n) = (0.0f64, 0.0f64, 0usize);
    for y in y0..y1 {
        let row = (y * width) as usize;
        for i in row + x0 as usize..row + x1 as usize {
            for (p, q) in a[i].to_array().into_iter().zip(b[i].to_array()) {
                let d = (p - q) as f64;
                abs += d.abs();
                sq += d * d;
                n += 1;
            }
        }
    }
    let n = n.max(1) as f64;
    (abs / n, (sq / n).sqrt())
}

/// Errors of a render's mean image against a reference, for the whole image and for each trace
/// window: what `--reference` records in the metadata.
pub struct ErrorTracker {
    reference: Image,
    traces: Vec<TraceWindow>,
}

impl ErrorTracker {
    /// Refuses a reference whose resolution differs from the render's.
    pub fn new(
        reference: Image,
        path: &Path,
        width: u32,
        height: u32,
        traces: Vec<TraceWindow>,
    ) -> Result<Self, FilmError> {
        if (reference.width, reference.height) != (width, height) {
            return Err(FilmError::Invalid {
                file: path.into(),
                message: format!(
                    "the reference is {}x{}, the render {width}x{height}",
                    reference.width, reference.height
                ),
            });
        }
        Ok(ErrorTracker { reference, traces })
    }

    pub fn measure(&self, mean: &[Rgb], seconds: f64, iterations: u64) -> ErrorSample {
        let (w, h) = (self.reference.width, self.reference.height);
        let (mae, rmse) = errors_in(mean, &self.reference.pixels, w, (0, 0, w, h));
        let traces = self
            .traces
            .iter()
            .map(|t| {
                let (a, r) = errors_in(mean, &self.reference.pixels, w, t.rect(w, h));
                [a, r]
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

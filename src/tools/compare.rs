//! Comparing images: mean value, errors against each other, relative difference.

use crate::color::Rgb;
use crate::film::{self, exr, FilmError, Image};
use crate::metrics::{self, Errors, Selection};
use std::path::Path;

/// Mean R, G, B of any RGB (or luminance) EXR, over all pixels.
pub fn average(path: &Path) -> Result<[f64; 3], FilmError> {
    Ok(film::average(&exr::read_image(path)?.pixels))
}

/// The measures of `selection` of `a` against the reference `b` (see [`crate::metrics`]);
/// FLIP and SSIM are left out of images narrower or lower than
/// [`MIN_SIZE`](crate::metrics::ssim::MIN_SIZE) pixels. Refuses images of different resolutions.
pub fn errors(a_path: &Path, b_path: &Path, selection: Selection) -> Result<Errors, FilmError> {
    let a = exr::read_image(a_path)?;
    let b = exr::read_image(b_path)?;
    same_size(&a, a_path, &b, b_path)?;
    Ok(metrics::measure(
        &a.pixels, &b.pixels, a.width, a.height, selection,
    ))
}

/// Writes to `out` the relative difference of `a` to `b` (000 Fig. 3.3): `|a - b| / |b|` per
/// pixel and channel. Where `b` is 0 the absolute difference `|a - b|` is written instead, so
/// that 0 stays 0 and a spurious value in `a` still shows. Refuses images of different
/// resolutions.
pub fn diff(out: &Path, a_path: &Path, b_path: &Path) -> Result<(), FilmError> {
    let a = exr::read_image(a_path)?;
    let b = exr::read_image(b_path)?;
    same_size(&a, a_path, &b, b_path)?;
    let relative = |p: f32, q: f32| {
        let d = (p - q).abs();
        if q != 0.0 {
            d / q.abs()
        } else {
            d
        }
    };
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| Rgb::new(relative(p.r, q.r), relative(p.g, q.g), relative(p.b, q.b)))
        .collect();
    exr::write_image(
        out,
        &Image {
            width: a.width,
            height: a.height,
            pixels,
        },
    )
}

fn same_size(a: &Image, a_path: &Path, b: &Image, b_path: &Path) -> Result<(), FilmError> {
    if (a.width, a.height) == (b.width, b.height) {
        return Ok(());
    }
    Err(FilmError::Invalid {
        file: b_path.into(),
        message: format!(
            "is {}x{} but {} is {}x{}",
            b.width,
            b.height,
            a_path.display(),
            a.width,
            a.height
        ),
    })
}

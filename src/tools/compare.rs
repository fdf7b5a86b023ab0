//! Comparing images: mean value, errors against each other, relative difference.

use crate::color::Rgb;
use crate::film::{self, exr, FilmError, Image};
use std::path::Path;

/// Mean R, G, B of any RGB (or luminance) EXR, over all pixels.
pub fn average(path: &Path) -> Result<[f64; 3], FilmError> {
    Ok(film::average(&exr::read_image(path)?.pixels))
}

/// Mean absolute and RMS error between two images (000 sec. 3.4), over all pixels and the
/// three channels: `mae = sum |a - b| / 3N`, `rmse = sqrt(sum (a - b)^2 / 3N)` for N pixels.
/// Refuses images of different resolutions.
pub fn errors(a_path: &Path, b_path: &Path) -> Result<(f64, f64), FilmError> {
    let a = exr::read_image(a_path)?;
    let b = exr::read_image(b_path)?;
    same_size(&a, a_path, &b, b_path)?;
    Ok(film::errors_in(
        &a.pixels,
        &b.pixels,
        a.width,
        (0, 0, a.width, a.height),
    ))
}

/// Relative MSE of `a` against the reference `b`: the mean over pixels and channels of
/// (a - b)^2 / (b^2 + 0.01), pbrt's convention, so that dark regions weigh as much as bright
/// ones without dividing by zero. Refuses images of different resolutions.
pub fn relative_mse(a_path: &Path, b_path: &Path) -> Result<f64, FilmError> {
    let a = exr::read_image(a_path)?;
    let b = exr::read_image(b_path)?;
    same_size(&a, a_path, &b, b_path)?;
    let term = |p: f32, q: f32| {
        let (p, q) = (f64::from(p), f64::from(q));
        (p - q) * (p - q) / (q * q + 0.01)
    };
    let sum: f64 = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| term(p.r, q.r) + term(p.g, q.g) + term(p.b, q.b))
        .sum();
    Ok(sum / (3 * a.pixels.len().max(1)) as f64)
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

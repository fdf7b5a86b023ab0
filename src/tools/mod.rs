//! Tools that work on rendered files (000 sec. 3.4, Appendix A): average, errors, diff, merge,
//! bake, strip, time, measurements, traces and plot.

use crate::color::Rgb;
use crate::film::{self, exr, FilmError, Image, Metadata, TraceWindow};
use std::path::{Path, PathBuf};

mod plot;

pub use plot::plot;

/// Mean RGB of an image.
pub fn average(path: &Path) -> Result<[f64; 3], FilmError> {
    Ok(film::average(&exr::read_image(path)?.pixels))
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

/// Mean absolute and RMS error between two images, over all pixels and channels.
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

/// Writes the relative difference |a - b| / b per channel (000 Fig. 3.3); where b is 0 the
/// difference is |a - b| itself, so a wrong non-zero value still shows.
pub fn diff(out: &Path, a_path: &Path, b_path: &Path) -> Result<(), FilmError> {
    let a = exr::read_image(a_path)?;
    let b = exr::read_image(b_path)?;
    same_size(&a, a_path, &b, b_path)?;
    let rel = |p: f32, q: f32| {
        if q != 0.0 {
            (p - q).abs() / q.abs()
        } else {
            (p - q).abs()
        }
    };
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| Rgb::new(rel(p.r, q.r), rel(p.g, q.g), rel(p.b, q.b)))
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

/// Merges renders of the same scene (hash), resolution, technique and options made with
/// different seeds: the sums and iterations add up, so the result is the iteration-weighted
/// mean, exact in f64. For the shrinking-radius techniques (ppm, bpm, vcm with alpha < 1) this
/// is the average of independent progressive renders, each with its own radius sequence, not
/// one longer progressive render.
pub fn merge(out: &Path, inputs: &[PathBuf]) -> Result<(), FilmError> {
    let Some((first_path, rest)) = inputs.split_first() else {
        return Err(FilmError::Invalid {
            file: out.into(),
            message: "merge needs at least one input".into(),
        });
    };
    let (mut film, mut metadata) = exr::read_render(first_path)?;
    let mut seeds = vec![metadata.options.seed.to_string()];
    for path in rest {
        let (other, m) = exr::read_render(path)?;
        let mismatch = |what: &str| FilmError::Invalid {
            file: path.clone(),
            message: format!(
                "cannot merge with {}: different {what}",
                first_path.display()
            ),
        };
        if m.scene_hash != metadata.scene_hash {
            return Err(mismatch("scene"));
        }
        if (other.width, other.height) != (film.width, film.height) {
            return Err(mismatch("resolution"));
        }
        if m.options.technique != metadata.options.technique {
            return Err(mismatch("technique"));
        }
        let mut a = m.options.clone();
        a.seed = metadata.options.seed;
        if a != metadata.options {
            return Err(mismatch("options"));
        }
        for (s, o) in film.sum.iter_mut().zip(&other.sum) {
            for c in 0..3 {
                s[c] += o[c];
            }
        }
        film.iterations += other.iterations;
        metadata.render_seconds += m.render_seconds;
        metadata.dropped_samples += m.dropped_samples;
        seeds.push(m.options.seed.to_string());
    }
    metadata.iterations = film.iterations;
    metadata.errors.clear();
    metadata
        .statistics
        .push(("merged_seeds".into(), seeds.join(" ")));
    exr::write_render(out, &film, &metadata)
}

/// Writes the mean image alone, as a plain RGB EXR without vmerge's channels and metadata.
pub fn bake(out: &Path, input: &Path) -> Result<(), FilmError> {
    exr::write_image(out, &exr::read_image(input)?)
}

/// Writes the render without its error series.
pub fn strip(out: &Path, input: &Path) -> Result<(), FilmError> {
    let (film, mut metadata) = exr::read_render(input)?;
    metadata.errors.clear();
    metadata.traces.clear();
    metadata.reference = None;
    exr::write_render(out, &film, &metadata)
}

pub fn metadata(path: &Path) -> Result<Metadata, FilmError> {
    Ok(exr::read_render(path)?.1)
}

/// The error series as CSV: seconds, iterations, mae, rmse, then mae and rmse per trace.
pub fn measurements(path: &Path) -> Result<String, FilmError> {
    let m = metadata(path)?;
    let mut csv = String::from("seconds,iterations,mae,rmse");
    for (i, _) in m.traces.iter().enumerate() {
        csv.push_str(&format!(",trace{i}_mae,trace{i}_rmse"));
    }
    csv.push('\n');
    for e in &m.errors {
        csv.push_str(&format!(
            "{},{},{},{}",
            e.seconds, e.iterations, e.mae, e.rmse
        ));
        for [a, r] in &e.traces {
            csv.push_str(&format!(",{a},{r}"));
        }
        csv.push('\n');
    }
    Ok(csv)
}

pub fn traces(path: &Path) -> Result<Vec<TraceWindow>, FilmError> {
    Ok(metadata(path)?.traces)
}

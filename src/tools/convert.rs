//! Converting renders: a plain EXR for other programs, or a render without its error series.

use crate::film::{exr, FilmError};
use std::path::Path;

/// Writes the mean image of `input` (any RGB EXR) to `out` as a plain RGB EXR, without vmerge's
/// sum channels and metadata: what other programs (tone mappers, viewers) need.
pub fn bake(out: &Path, input: &Path) -> Result<(), FilmError> {
    exr::write_image(out, &exr::read_image(input)?)
}

/// Writes the render `input` to `out` without its error series, trace windows and reference;
/// the sums and everything `continue` and `merge` need stay.
pub fn strip(out: &Path, input: &Path) -> Result<(), FilmError> {
    let (film, mut metadata) = exr::read_render(input)?;
    metadata.errors.clear();
    metadata.traces.clear();
    metadata.reference = None;
    exr::write_render(out, &film, &metadata)
}

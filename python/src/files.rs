//! vmerge's files and tools from Python: renders and images read and written, renders merged,
//! images compared, batch plans run and reported.

use crate::errors;
use crate::result::{image_array, pixels_of, RenderResult};
use numpy::{PyArray3, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use vmerge::color::Rgb;
use vmerge::film::{exr, Image};
use vmerge::metrics::{Measure, Selection};
use vmerge::render::StopFlag;
use vmerge::tools::batch::{self, Plan};

/// Reads a vmerge render (image, exact sums, metadata) from its EXR.
#[pyfunction]
pub fn read(py: Python<'_>, path: PathBuf) -> PyResult<RenderResult> {
    let (film, metadata) = py
        .detach(|| exr::read_render(&path))
        .map_err(errors::film)?;
    Ok(RenderResult::new(film, metadata))
}

/// Reads any RGB (or luminance) EXR as a float32 array of shape (height, width, 3).
#[pyfunction]
pub fn read_image<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let image = py.detach(|| exr::read_image(&path)).map_err(errors::film)?;
    image_array(py, &image.pixels, image.width, image.height)
}

/// Writes a float32 array of shape (height, width, 3) as a plain RGB EXR, atomically.
#[pyfunction]
pub fn write_image(
    py: Python<'_>,
    path: PathBuf,
    image: PyReadonlyArray3<'_, f32>,
) -> PyResult<()> {
    let (pixels, width, height) = pixels_of(&image)?;
    let image = Image {
        width,
        height,
        pixels,
    };
    py.detach(|| exr::write_image(&path, &image))
        .map_err(errors::film)
}

/// Merges renders of the same scene and options made with different seeds (paths of vmerge
/// EXRs, or `Result`s), weighted by their iterations, refusing what `vmerge merge` refuses.
/// Written to `output` when given; the merge is returned either way.
#[pyfunction]
#[pyo3(signature = (renders, output = None))]
pub fn merge(
    py: Python<'_>,
    renders: Vec<Bound<'_, PyAny>>,
    output: Option<PathBuf>,
) -> PyResult<RenderResult> {
    let scratch = tempfile::Builder::new()
        .prefix("vmerge-merge-")
        .tempdir()
        .map_err(|e| PyValueError::new_err(format!("a scratch folder: {e}")))?;
    let mut inputs = Vec::with_capacity(renders.len());
    for (k, render) in renders.iter().enumerate() {
        if let Ok(result) = render.cast::<RenderResult>() {
            let path = scratch.path().join(format!("input-{k}.exr"));
            let r = result.get();
            py.detach(|| exr::write_render(&path, &r.film, &r.metadata))
                .map_err(errors::film)?;
            inputs.push(path);
        } else {
            inputs.push(render.extract::<PathBuf>().map_err(|_| {
                PyTypeError::new_err("merge takes vmerge.Result objects or paths of renders")
            })?);
        }
    }
    let output = output.unwrap_or_else(|| scratch.path().join("merged.exr"));
    let (film, metadata) = py
        .detach(|| {
            vmerge::tools::merge(&output, &inputs)?;
            exr::read_render(&output)
        })
        .map_err(errors::film)?;
    Ok(RenderResult::new(film, metadata))
}

/// An image given as an array, a `Result` or a path.
fn image_of(py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<(Vec<Rgb>, u32, u32)> {
    if let Ok(result) = value.cast::<RenderResult>() {
        let r = result.get();
        return Ok((r.film.mean(), r.film.width, r.film.height));
    }
    if let Ok(array) = value.extract::<PyReadonlyArray3<'_, f32>>() {
        return pixels_of(&array);
    }
    if let Ok(array) = value.extract::<PyReadonlyArray3<'_, f64>>() {
        let as_f32 = array.as_array().mapv(|v| v as f32);
        let bound = numpy::PyArray3::from_owned_array(py, as_f32);
        return pixels_of(&bound.readonly());
    }
    let path: PathBuf = value.extract().map_err(|_| {
        PyTypeError::new_err("an image is an array (height, width, 3), a vmerge.Result or a path")
    })?;
    let image = py.detach(|| exr::read_image(&path)).map_err(errors::film)?;
    Ok((image.pixels, image.width, image.height))
}

/// The error measures of `image` against `reference` (arrays, `Result`s or paths) over all
/// pixels and channels, as `vmerge errors` measures them: a dict from each measure's name
/// (`mae`, `rmse`, `relmse`, `ldr-flip`, `hdr-flip`, `ssim`) to its value. `pointwise` keeps
/// to the pixel-wise ones (MAE, RMSE, relative MSE), which cost far less than FLIP and SSIM;
/// those are left out of images too small for their filters.
#[pyfunction]
#[pyo3(name = "errors", signature = (image, reference, pointwise = false))]
pub fn image_errors<'py>(
    py: Python<'py>,
    image: Bound<'py, PyAny>,
    reference: Bound<'py, PyAny>,
    pointwise: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let (a, width, height) = image_of(py, &image)?;
    let (b, ref_width, ref_height) = image_of(py, &reference)?;
    if (width, height) != (ref_width, ref_height) {
        return Err(PyValueError::new_err(format!(
            "the image is {width}x{height}, the reference {ref_width}x{ref_height}"
        )));
    }
    let selection = if pointwise {
        Selection::Pointwise
    } else {
        Selection::All
    };
    let errors = py.detach(|| vmerge::metrics::measure(&a, &b, width, height, selection));
    let dict = PyDict::new(py);
    for (measure, value) in errors.iter() {
        dict.set_item(measure.name(), value)?;
    }
    Ok(dict)
}

/// The names of the error measures, in the order every output lists them.
#[pyfunction]
pub fn measure_names() -> Vec<&'static str> {
    Measure::ALL.iter().map(|m| m.name()).collect()
}

/// Runs every cell of a batch plan that needs it, references first, in this process; returns
/// the number of cells run. Ctrl-C stops the current cell at the end of an iteration (it is
/// written, and continues when the plan runs again) and raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (plan, accel = None))]
pub fn run_batch(py: Python<'_>, plan: PathBuf, accel: Option<&str>) -> PyResult<usize> {
    let accel = crate::render::accel_kind(accel)?;
    let plan = py.detach(|| Plan::load(&plan)).map_err(errors::batch)?;
    let flag = StopFlag::default();
    let mut interrupt = None;
    let mut warnings = Vec::new();
    let ran = py.detach(|| {
        batch::run(&plan, accel, &flag, &mut |event| match event {
            batch::Event::Iteration { .. } => {
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    interrupt = Some(e);
                    flag.store(true, Ordering::SeqCst);
                }
            }
            batch::Event::Warning(w) => warnings.push(w.to_string()),
            batch::Event::RunWarning(w) => warnings.push(w.to_string()),
            _ => {}
        })
    });
    crate::render::warn_all(py, &warnings)?;
    let ran = ran.map_err(errors::batch)?;
    match interrupt {
        Some(e) => Err(e),
        None => Ok(ran),
    }
}

/// Writes a batch plan's report from the cells that exist; returns the path of its page.
#[pyfunction]
pub fn batch_report(py: Python<'_>, plan: PathBuf) -> PyResult<PathBuf> {
    py.detach(|| batch::report(&Plan::load(&plan)?))
        .map_err(errors::batch)
}

//! A render's outcome as Python sees it: the exact film (sums and iterations) and the metadata,
//! shown as numpy arrays and dicts, written as vmerge's EXR.

use numpy::{PyArray1, PyArray3, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;
use vmerge::color::Rgb;
use vmerge::film::{Film, Metadata};

/// A render: its image, the exact sums it can be continued and merged from, and the record of
/// how it was made.
#[pyclass(name = "Result", module = "vmerge", frozen)]
pub struct RenderResult {
    pub film: Film,
    pub metadata: Metadata,
}

/// Pixels as a float32 array of shape (height, width, 3).
pub fn image_array<'py>(
    py: Python<'py>,
    pixels: &[Rgb],
    width: u32,
    height: u32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let flat: Vec<f32> = pixels.iter().flat_map(|p| [p.r, p.g, p.b]).collect();
    PyArray1::from_vec(py, flat).reshape([height as usize, width as usize, 3])
}

/// An array of shape (height, width, 3) as pixels, with its width and height.
pub fn pixels_of(array: &PyReadonlyArray3<'_, f32>) -> PyResult<(Vec<Rgb>, u32, u32)> {
    let shape = array.shape();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "an image is an array of shape (height, width, 3), not {shape:?}"
        )));
    }
    let side = |n: usize| {
        u32::try_from(n).map_err(|_| PyValueError::new_err(format!("{n} pixels is too large")))
    };
    let array = array.as_array();
    let pixels = array
        .rows()
        .into_iter()
        .map(|p| Rgb::new(p[0], p[1], p[2]))
        .collect();
    Ok((pixels, side(shape[1])?, side(shape[0])?))
}

/// A statistic's text as a number where it is one.
fn statistic<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    if let Ok(i) = text.parse::<i64>() {
        return Ok(i.into_pyobject(py)?.into_any());
    }
    if let Ok(f) = text.parse::<f64>() {
        return Ok(f.into_pyobject(py)?.into_any());
    }
    Ok(text.into_pyobject(py)?.into_any())
}

pub fn statistics_dict<'py>(
    py: Python<'py>,
    statistics: &[(String, String)],
) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    for (name, value) in statistics {
        dict.set_item(name, statistic(py, value)?)?;
    }
    Ok(dict)
}

impl RenderResult {
    pub fn new(film: Film, metadata: Metadata) -> Self {
        RenderResult { film, metadata }
    }
}

#[pymethods]
impl RenderResult {
    /// The mean radiance, float32, shape (height, width, 3).
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        image_array(py, &self.film.mean(), self.film.width, self.film.height)
    }

    /// The exact per-pixel sums over all iterations, float64, shape (height, width, 3).
    #[getter]
    fn sums<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let flat: Vec<f64> = self.film.sum.iter().flatten().copied().collect();
        PyArray1::from_vec(py, flat).reshape([
            self.film.height as usize,
            self.film.width as usize,
            3,
        ])
    }

    #[getter]
    fn iterations(&self) -> u64 {
        self.film.iterations
    }

    #[getter]
    fn width(&self) -> u32 {
        self.film.width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.film.height
    }

    /// Render time in seconds, earlier runs of a continued render included.
    #[getter]
    fn seconds(&self) -> f64 {
        self.metadata.render_seconds
    }

    /// Everything recorded about the render, as the EXR's `vmerge.*` attributes hold it.
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let m = &self.metadata;
        let dict = PyDict::new(py);
        dict.set_item("vmerge_version", &m.vmerge_version)?;
        dict.set_item("scene", &m.scene)?;
        dict.set_item("scene_hash", &m.scene_hash)?;
        dict.set_item("technique", m.options.technique.name())?;
        dict.set_item("seed", m.options.seed)?;
        dict.set_item("options", crate::options::to_dict(py, &m.options)?)?;
        dict.set_item("accel", &m.accel)?;
        dict.set_item("iterations", m.iterations)?;
        dict.set_item("render_seconds", m.render_seconds)?;
        dict.set_item("cpu_seconds", m.cpu_seconds)?;
        dict.set_item("dropped_samples", m.dropped_samples)?;
        dict.set_item("statistics", statistics_dict(py, &m.statistics)?)?;
        dict.set_item("reference", &m.reference)?;
        let traces: Vec<(u32, u32, u32)> =
            m.traces.iter().map(|t| (t.x, t.y, t.half_width)).collect();
        dict.set_item("traces", traces)?;
        Ok(dict)
    }

    /// The technique's statistics (merges, tentative rays, rates ...), numbers where they are.
    #[getter]
    fn statistics<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        statistics_dict(py, &self.metadata.statistics)
    }

    /// The error series against the reference: arrays `seconds`, `iterations`, one per measure
    /// (`mae`, `rmse`, `relmse`, `ldr-flip`, `hdr-flip`, `ssim`; NaN where a sample did not
    /// measure it), and `traces` of shape (samples, windows, 2) holding each window's mae and
    /// rmse.
    #[getter]
    fn errors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let e = &self.metadata.errors;
        let dict = PyDict::new(py);
        dict.set_item(
            "seconds",
            PyArray1::from_vec(py, e.iter().map(|s| s.seconds).collect()),
        )?;
        dict.set_item(
            "iterations",
            PyArray1::from_vec(py, e.iter().map(|s| s.iterations).collect()),
        )?;
        // Every measure a sample may hold, NaN where it was not measured (the perceptual
        // ones are measured at fewer samples than the pixel-wise ones).
        for measure in vmerge::metrics::Measure::ALL {
            let values: Vec<f64> = e
                .iter()
                .map(|s| s.get(measure).unwrap_or(f64::NAN))
                .collect();
            dict.set_item(measure.name(), PyArray1::from_vec(py, values))?;
        }
        let windows = self.metadata.traces.len();
        let flat: Vec<f64> = e
            .iter()
            .flat_map(|s| s.traces.iter().flatten().copied())
            .collect();
        dict.set_item(
            "traces",
            PyArray1::from_vec(py, flat).reshape([e.len(), windows, 2])?,
        )?;
        Ok(dict)
    }

    /// Writes the render as vmerge's EXR (image, sums, metadata), atomically; with `png`, a
    /// tone-mapped preview next to it.
    #[pyo3(signature = (path, png = false))]
    fn write(&self, py: Python<'_>, path: PathBuf, png: bool) -> PyResult<()> {
        py.detach(|| {
            vmerge::film::exr::write_render(&path, &self.film, &self.metadata)?;
            if png {
                vmerge::film::png::write_preview(
                    &path.with_extension("png"),
                    &self.film.mean(),
                    self.film.width,
                    self.film.height,
                )?;
            }
            Ok(())
        })
        .map_err(crate::errors::film)
    }

    fn __repr__(&self) -> String {
        format!(
            "vmerge.Result({} {}x{}, {} iterations, {:.3} s, seed {})",
            self.metadata.options.technique,
            self.film.width,
            self.film.height,
            self.film.iterations,
            self.metadata.render_seconds,
            self.metadata.options.seed
        )
    }
}

/// The trace windows' list for a render, `(x, y, half_width)` each.
pub fn traces_from(list: Option<&Bound<'_, PyList>>) -> PyResult<Vec<vmerge::film::TraceWindow>> {
    let Some(list) = list else {
        return Ok(Vec::new());
    };
    list.iter()
        .map(|item| {
            if let Ok(text) = item.extract::<String>() {
                return text
                    .parse()
                    .map_err(|e: String| PyValueError::new_err(format!("`trace` {text}: {e}")));
            }
            let (x, y, w): (u32, u32, u32) = item.extract()?;
            format!("{x}x{y}x{w}")
                .parse()
                .map_err(|e: String| PyValueError::new_err(format!("`trace` {x}x{y}x{w}: {e}")))
        })
        .collect()
}

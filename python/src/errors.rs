//! The library's errors as Python exceptions, with the library's messages: a bad option is a
//! `ValueError`, a bad scene a `SceneError` (a `ValueError` too), a file that cannot be read
//! or written an `OSError`, and a render stopped by Ctrl-C an `Interrupted` (a
//! `KeyboardInterrupt`) that carries the partial result.

use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::PyErr;
use vmerge::film::FilmError;
use vmerge::render::RenderError;
use vmerge::tools::batch::BatchError;

create_exception!(
    vmerge,
    SceneError,
    PyValueError,
    "A scene file that cannot be rendered: the message names the file and the entry."
);
create_exception!(
    vmerge,
    Interrupted,
    PyKeyboardInterrupt,
    "Ctrl-C stopped a render at the end of an iteration; `result` holds what was rendered."
);

pub fn film(e: FilmError) -> PyErr {
    match e {
        FilmError::Read { .. } | FilmError::Write { .. } => PyOSError::new_err(e.to_string()),
        FilmError::NotARender { .. } | FilmError::Invalid { .. } => {
            PyValueError::new_err(e.to_string())
        }
    }
}

pub fn scene(e: vmerge::scene::SceneError) -> PyErr {
    SceneError::new_err(e.to_string())
}

pub fn option(e: vmerge::options::OptionError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

pub fn render(e: RenderError) -> PyErr {
    match e {
        RenderError::Scene(e) => scene(e),
        RenderError::Film(e) => film(e),
        RenderError::Options(e) => option(e),
        RenderError::File(e) => PyOSError::new_err(e.to_string()),
        RenderError::Memory(e) => PyValueError::new_err(e.to_string()),
        RenderError::NoStop | RenderError::SceneChanged { .. } => {
            PyValueError::new_err(e.to_string())
        }
        RenderError::WrittenElsewhere { .. } | RenderError::Lost { .. } => {
            PyOSError::new_err(e.to_string())
        }
        RenderError::NoCpuClock => PyRuntimeError::new_err(e.to_string()),
    }
}

pub fn batch(e: BatchError) -> PyErr {
    if e.is_input() {
        PyValueError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

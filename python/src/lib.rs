//! `import vmerge`: the renderer's library calls on numpy arrays. Every render option of the
//! command line is a keyword argument, read and validated by the library's one option table;
//! renders release the GIL and stop cleanly on Ctrl-C.

use pyo3::prelude::*;

mod errors;
mod files;
mod options;
mod render;
mod result;

#[pymodule]
fn _vmerge(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("Interrupted", py.get_type::<errors::Interrupted>())?;
    m.add(
        "TECHNIQUES",
        vmerge::options::Technique::ALL.map(|t| t.name()).to_vec(),
    )?;
    m.add_class::<render::PyScene>()?;
    m.add_class::<render::Step>()?;
    m.add_class::<render::Progressive>()?;
    m.add_class::<result::RenderResult>()?;
    m.add_function(wrap_pyfunction!(render::load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(render::render_progressive, m)?)?;
    m.add_function(wrap_pyfunction!(render::continue_render, m)?)?;
    m.add_function(wrap_pyfunction!(options::option_names, m)?)?;
    m.add_function(wrap_pyfunction!(render::set_threads, m)?)?;
    m.add_function(wrap_pyfunction!(files::read, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(files::merge, m)?)?;
    m.add_function(wrap_pyfunction!(files::image_errors, m)?)?;
    m.add_function(wrap_pyfunction!(files::measure_names, m)?)?;
    m.add_function(wrap_pyfunction!(files::run_batch, m)?)?;
    m.add_function(wrap_pyfunction!(files::batch_report, m)?)?;
    Ok(())
}

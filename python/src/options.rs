//! Render options as keyword arguments: one keyword per row of the library's option table,
//! each value turned into the text the command line would pass and read by the table's own
//! reader, then validated as the command line validates; and the options back as a dict.

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use vmerge::options::{Form, OptionSpec, RenderOptions, OPTIONS, SWITCH_ON};

/// The separators a value of several parts may take on the command line (`64x64`, `1,2`).
const SEPARATORS: [&str; 2] = ["x", ","];

/// The text of one value, as the command line would give it.
fn scalar_text(value: &Bound<'_, PyAny>) -> Option<String> {
    if value.is_instance_of::<PyBool>() {
        return None;
    }
    if value.is_instance_of::<PyInt>() || value.is_instance_of::<PyString>() {
        return value.str().ok().map(|s| s.to_string());
    }
    if value.is_instance_of::<PyFloat>() {
        // Python's repr is the shortest text that reads back as the same number.
        return value.repr().ok().map(|s| s.to_string());
    }
    None
}

/// The separator `spec` reads parts with: the one for which a value of `parts` ones parses.
fn separator(spec: &OptionSpec, parts: usize) -> Option<&'static str> {
    SEPARATORS.into_iter().find(|sep| {
        let probe = vec!["1"; parts].join(sep);
        let mut scratch = RenderOptions::DEFAULT;
        (spec.parse)(&mut scratch, &probe).is_ok()
    })
}

/// The command-line text of `value` for `spec`; `None` for a switch that is off.
fn argument(spec: &OptionSpec, value: &Bound<'_, PyAny>) -> PyResult<Option<String>> {
    let wrong = |what: &str| {
        PyTypeError::new_err(format!(
            "`{}` takes {what}, not {}",
            spec.name,
            value
                .get_type()
                .name()
                .map_or_else(|_| "this".into(), |n| n.to_string())
        ))
    };
    match spec.form {
        Form::Switch => match value.cast::<PyBool>() {
            Ok(b) => Ok(b.is_true().then(|| SWITCH_ON.to_string())),
            Err(_) => Err(wrong("True or False")),
        },
        Form::Value { .. } => {
            if let Some(text) = scalar_text(value) {
                return Ok(Some(text));
            }
            let parts: Vec<Bound<'_, PyAny>> = if let Ok(t) = value.cast::<PyTuple>() {
                t.iter().collect()
            } else if let Ok(l) = value.cast::<PyList>() {
                l.iter().collect()
            } else {
                return Err(wrong("a number or a string"));
            };
            let sep = separator(spec, parts.len()).ok_or_else(|| wrong("a single value"))?;
            let texts = parts
                .iter()
                .map(|p| scalar_text(p).ok_or_else(|| wrong("numbers in its sequence")))
                .collect::<PyResult<Vec<String>>>()?;
            Ok(Some(texts.join(sep)))
        }
    }
}

/// Options from keyword arguments, each read by the table and the whole validated as the
/// command line validates it; `None` values keep their defaults.
pub fn from_kwargs(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<RenderOptions> {
    let mut options = RenderOptions::DEFAULT;
    if let Some(kwargs) = kwargs {
        for (key, value) in kwargs.iter() {
            let key: String = key.extract()?;
            let spec = OPTIONS.iter().find(|s| s.name == key).ok_or_else(|| {
                let names: Vec<&str> = OPTIONS.iter().map(|s| s.name).collect();
                PyTypeError::new_err(format!(
                    "unexpected keyword argument '{key}'; the render options are {}",
                    names.join(", ")
                ))
            })?;
            if value.is_none() {
                continue;
            }
            if let Some(text) = argument(spec, &value)? {
                spec.read(&mut options, &text)
                    .map_err(|e| PyValueError::new_err(e.to_string()))?;
            }
        }
    }
    options.validate().map_err(crate::errors::option)?;
    Ok(options)
}

/// A TOML value as a Python object.
fn toml_to_py<'py>(py: Python<'py>, value: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        toml::Value::String(s) => s.into_pyobject(py)?.into_any(),
        toml::Value::Integer(i) => i.into_pyobject(py)?.into_any(),
        toml::Value::Float(f) => f.into_pyobject(py)?.into_any(),
        toml::Value::Boolean(b) => PyBool::new(py, *b).to_owned().into_any(),
        toml::Value::Datetime(d) => d.to_string().into_pyobject(py)?.into_any(),
        toml::Value::Array(a) => PyTuple::new(
            py,
            a.iter()
                .map(|v| toml_to_py(py, v))
                .collect::<PyResult<Vec<_>>>()?,
        )?
        .into_any(),
        toml::Value::Table(t) => {
            let dict = PyDict::new(py);
            for (k, v) in t {
                dict.set_item(k, toml_to_py(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

/// The options as a dict with one entry per row of the table, `None` where an option has no
/// value (the scene's or the technique's default applies).
pub fn to_dict<'py>(py: Python<'py>, options: &RenderOptions) -> PyResult<Bound<'py, PyDict>> {
    let text = vmerge::film::metadata::options_to_toml(options)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| PyValueError::new_err(e.to_string()))?;
    let dict = PyDict::new(py);
    for spec in OPTIONS {
        let value = match spec.name {
            "seed" => options.seed.into_pyobject(py)?.into_any(),
            name => match table.get(name) {
                Some(v) => toml_to_py(py, v)?,
                None => py.None().into_bound(py),
            },
        };
        dict.set_item(spec.name, value)?;
    }
    Ok(dict)
}

/// The names of the render options, in the table's order.
#[pyfunction]
pub fn option_names() -> Vec<&'static str> {
    OPTIONS.iter().map(|s| s.name).collect()
}

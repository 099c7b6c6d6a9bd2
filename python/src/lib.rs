//! `fluorite._fluorite`: the Python extension of fluorite (PyO3 + numpy).
//!
//! Nothing here models, reads or measures colour: every call goes to the `fluorite`
//! library. This crate converts types (numpy arrays ⇄ `Vec<f64>`, dictionaries, lights),
//! releases the GIL around every read, fit, joint fit, image fit and render, and turns the library's
//! errors, and any panic, into `fluorite.FluoriteError`. The Python package
//! (`python/fluorite/`) re-exports it with typed stubs.

use std::panic::AssertUnwindSafe;

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

mod convert;
mod fit;
mod image;
mod joint;
mod lights;
mod material;
mod measurement;
mod render;
mod stages;

create_exception!(
    fluorite,
    FluoriteError,
    PyValueError,
    "A fluorite operation failed. The message is the library's, as the `fluorite` command \
     prints it after `fluorite: error: ` (file, line and column for malformed files; the \
     parameter and what would be accepted for impossible options)."
);

/// Why a call into the library did not return a value.
pub(crate) enum Failure {
    /// The library's error.
    Library(fluorite::Error),
    /// A panic inside the library (a bug), with its message.
    Panic(String),
}

impl Failure {
    /// The Python exception: the error's Display on one line, as the CLI prints it.
    pub(crate) fn into_py_err(self, what: &str) -> PyErr {
        match self {
            Failure::Library(e) => error(e),
            Failure::Panic(message) => FluoriteError::new_err(format!(
                "internal error in {what}: {message}: please report"
            )),
        }
    }
}

/// A library error as `FluoriteError`, its message the one the CLI prints.
pub(crate) fn error(e: fluorite::Error) -> PyErr {
    FluoriteError::new_err(e.to_string().replace('\n', " "))
}

/// A `FluoriteError` with a message of this crate (argument conversion).
pub(crate) fn invalid(parameter: &str, message: impl std::fmt::Display) -> PyErr {
    error(fluorite::Error::invalid(parameter, message.to_string()))
}

/// Runs `f`, catching a panic so that it cannot unwind into Python.
pub(crate) fn guarded<T>(f: impl FnOnce() -> fluorite::Result<T>) -> Result<T, Failure> {
    match std::panic::catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(e)) => Err(Failure::Library(e)),
        Err(payload) => {
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic without a message".to_string());
            Err(Failure::Panic(message))
        }
    }
}

/// Runs `f` with the GIL released (other Python threads run meanwhile), guarded against
/// panics. `what` names the call in the message of a panic. Everything `f` uses must be
/// Rust data: numpy inputs are copied into vectors before.
pub(crate) fn detached<T: Send>(
    py: Python<'_>,
    what: &str,
    f: impl FnOnce() -> fluorite::Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| guarded(f))
        .map_err(|failure| failure.into_py_err(what))
}

/// Runs `f` holding the GIL (quick calls: conversions, small computations), guarded
/// against panics.
pub(crate) fn attached<T>(what: &str, f: impl FnOnce() -> fluorite::Result<T>) -> PyResult<T> {
    guarded(f).map_err(|failure| failure.into_py_err(what))
}

/// Panics inside the guard, for the test suite: the panic must arrive as
/// `FluoriteError("internal error ...: please report")`, never abort the interpreter.
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    detached(py, "_panic_for_tests", || -> fluorite::Result<()> {
        panic!("deliberate panic (test of the panic guard)")
    })
}

/// The Python extension module `fluorite._fluorite`.
#[pymodule]
fn _fluorite(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("FluoriteError", py.get_type::<FluoriteError>())?;
    m.add("__version__", fluorite::export::VERSION)?;
    m.add(
        "STANDARD_LIGHTS",
        fluorite::colour::STANDARD_LIGHTS.to_vec(),
    )?;
    m.add("DEFAULT_TOLERANCE", fluorite::fit::DEFAULT_TOLERANCE)?;
    m.add(
        "DEFAULT_COLOUR_WEIGHT",
        fluorite::fit::DEFAULT_COLOUR_WEIGHT,
    )?;
    m.add(
        "WATER_RAMAN_SHIFT_CM",
        fluorite::eem::scatter::WATER_RAMAN_SHIFT_CM,
    )?;
    m.add_class::<lights::PyLight>()?;
    m.add_class::<measurement::PyMeasurement>()?;
    m.add_class::<material::PyMaterial>()?;
    m.add_class::<material::PyFluorophore>()?;
    m.add_class::<fit::PyFit>()?;
    m.add_class::<joint::PyJointResult>()?;
    m.add_class::<joint::PyParafacFit>()?;
    m.add_class::<image::PyImageFit>()?;
    m.add_class::<image::PyMaterialMap>()?;
    m.add_class::<stages::PyImageStages>()?;
    m.add_function(wrap_pyfunction!(measurement::read, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit_many, m)?)?;
    m.add_function(wrap_pyfunction!(joint::joint, m)?)?;
    m.add_function(wrap_pyfunction!(render::render, m)?)?;
    m.add_function(wrap_pyfunction!(image::fit_image, m)?)?;
    m.add_function(wrap_pyfunction!(image::write_image, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    m.add_function(wrap_pyfunction!(fit::_fit_seconds, m)?)?;
    Ok(())
}

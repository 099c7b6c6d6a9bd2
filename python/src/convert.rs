//! Conversions between Python values and the library's: numpy arrays, JSON-serialisable
//! reports as dictionaries, choice names, paths.

use std::path::PathBuf;

use numpy::ndarray::{Array2, Array3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayLike1, PyArrayLike2,
};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyString, PyTuple};

use crate::invalid;

/// A 1-D float64 numpy array (a copy).
pub(crate) fn array1<'py>(py: Python<'py>, values: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, values)
}

/// A `rows × columns` float64 numpy array from row-major values.
pub(crate) fn array2<'py>(
    py: Python<'py>,
    rows: usize,
    columns: usize,
    values: Vec<f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    Array2::from_shape_vec((rows, columns), values)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| invalid("array", e))
}

/// A `height × width × 3` numpy array from row-major pixels.
pub(crate) fn image<'py, T: numpy::Element>(
    py: Python<'py>,
    height: usize,
    width: usize,
    values: Vec<T>,
) -> PyResult<Bound<'py, PyArray3<T>>> {
    Array3::from_shape_vec((height, width, 3), values)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| invalid("image", e))
}

/// A 1-D sequence of numbers (numpy array, list, tuple…) as a vector; `what` names the
/// argument in the error.
pub(crate) fn floats(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
    let value = &aligned(value)?;
    let array: PyArrayLike1<'_, f64, AllowTypeChange> = value.extract().map_err(|_| {
        invalid(
            what,
            format!(
                "expected a 1-D array of numbers (wavelengths in nm or values), got {}",
                type_name(value)
            ),
        )
    })?;
    Ok(array.as_array().iter().copied().collect())
}

/// A 2-D array of numbers as (rows, columns, row-major values).
pub(crate) fn floats2(value: &Bound<'_, PyAny>, what: &str) -> PyResult<(usize, usize, Vec<f64>)> {
    let value = &aligned(value)?;
    let array: PyArrayLike2<'_, f64, AllowTypeChange> = value.extract().map_err(|_| {
        invalid(
            what,
            format!("expected a 2-D array of numbers, got {}", type_name(value)),
        )
    })?;
    let view = array.as_array();
    let (rows, columns) = view.dim();
    Ok((rows, columns, view.iter().copied().collect()))
}

/// Whether `value` converts to a 1-D array of numbers (without raising).
pub(crate) fn is_floats(value: &Bound<'_, PyAny>) -> bool {
    let Ok(value) = aligned(value) else {
        return false;
    };
    !value.is_instance_of::<PyString>()
        && value
            .extract::<PyArrayLike1<'_, f64, AllowTypeChange>>()
            .is_ok()
}

/// `value` itself, or a copy when it is a numpy array whose data are not aligned for its
/// type (a buffer received over the network or sliced from bytes can be): the numpy
/// crate's views require alignment and would panic instead of raising.
pub(crate) fn aligned<'py>(value: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
    match value.cast::<numpy::PyUntypedArray>() {
        Ok(array) if !numpy::PyUntypedArrayMethods::is_aligned(array) => value.call_method0("copy"),
        _ => Ok(value.clone()),
    }
}

/// The Python type name of `value`, for messages.
pub(crate) fn type_name(value: &Bound<'_, PyAny>) -> String {
    value
        .get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "an object".into())
}

/// A path given as `str` or `os.PathLike`.
pub(crate) fn path(value: &Bound<'_, PyAny>, what: &str) -> PyResult<PathBuf> {
    value.extract::<PathBuf>().map_err(|_| {
        invalid(
            what,
            format!(
                "expected a path (str or os.PathLike), got {}",
                type_name(value)
            ),
        )
    })
}

/// Whether `value` is a path (`str` or `os.PathLike`).
pub(crate) fn is_path(value: &Bound<'_, PyAny>) -> bool {
    value.is_instance_of::<PyString>() || value.hasattr("__fspath__").unwrap_or(false)
}

/// None, one path, or a list of paths.
pub(crate) fn paths(value: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Vec<PathBuf>> {
    match value {
        None => Ok(Vec::new()),
        Some(v) if v.is_none() => Ok(Vec::new()),
        Some(v) if is_path(v) => Ok(vec![path(v, what)?]),
        Some(v) => v
            .try_iter()
            .map_err(|_| invalid(what, "expected a path or a list of paths"))?
            .map(|item| path(&item?, what))
            .collect(),
    }
}

/// The items of a list, tuple or other iterable.
pub(crate) fn items<'py>(
    value: &Bound<'py, PyAny>,
    what: &str,
) -> PyResult<Vec<Bound<'py, PyAny>>> {
    if let Ok(list) = value.cast::<PyList>() {
        return Ok(list.iter().collect());
    }
    if let Ok(tuple) = value.cast::<PyTuple>() {
        return Ok(tuple.iter().collect());
    }
    value
        .try_iter()
        .map_err(|_| invalid(what, format!("expected a list, got {}", type_name(value))))?
        .collect()
}

/// A choice among a clap value enum's names (the CLI's spellings), case-insensitive.
pub(crate) fn choice<T: clap::ValueEnum>(value: &str, parameter: &str) -> PyResult<T> {
    T::from_str(value, true).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value())
            .map(|p| p.get_name().to_string())
            .collect();
        invalid(
            parameter,
            format!("\"{value}\" is not one of {}", names.join(", ")),
        )
    })
}

/// JSON text as Python objects (`json.loads`): the library's reports become
/// dictionaries with exactly the content and numbers the written files hold.
pub(crate) fn json<'py>(py: Python<'py>, text: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (text,))
}

/// A serialisable library value as Python objects (through its JSON).
pub(crate) fn to_py<'py, T: serde::Serialize>(
    py: Python<'py>,
    value: &T,
) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| invalid("report", e))?;
    json(py, &text)
}

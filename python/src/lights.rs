//! Lights: a built-in name or CSV file, a pair of arrays, any object with `.wavelengths`
//! and `.values` (a colour-science `SpectralDistribution`), or a `fluorite.Light`.

use std::sync::OnceLock;

use fluorite::colour::{Light, STANDARD_LIGHTS};
use pyo3::prelude::*;
use pyo3::types::{PyList, PyTuple};

use crate::convert::{array1, floats, is_floats, is_path, items, path, type_name};
use crate::{attached, invalid};

/// A light source: a relative spectral power distribution, zero outside its samples.
///
/// ``Light("d65")`` is a built-in light (``"d65"``, ``"a"``, ``"f11"``, ``"uv"``: D65 plus
/// a 365 nm LED) or a two-column CSV file (``wavelength_nm,power``), as the command
/// line's ``--lights`` accepts; ``Light.from_samples(wavelengths, values, name=...)``
/// builds one from samples (checked: at least two, wavelengths strictly increasing in
/// 100–100,000 nm, powers finite, non-negative and not all zero).
///
/// Everywhere fluorite takes a light it also takes the name, a pair of arrays
/// ``(wavelengths, values)`` or any object with ``.wavelengths`` and ``.values`` (and
/// optionally ``.name``), such as a colour-science ``SpectralDistribution``.
#[pyclass(module = "fluorite", name = "Light", frozen)]
#[derive(Clone)]
pub struct PyLight {
    pub(crate) light: Light,
}

#[pymethods]
impl PyLight {
    /// A built-in light by name (d65, a, f11, uv) or a two-column CSV file.
    #[new]
    fn new(name_or_path: &Bound<'_, PyAny>) -> PyResult<Self> {
        let text = path(name_or_path, "light")?;
        let text = text.to_string_lossy().into_owned();
        let light = attached("Light", || Light::parse(&text))?;
        Ok(PyLight { light })
    }

    /// A light from samples: ``wavelengths`` in nm (strictly increasing) and relative
    /// ``values`` (power, ≥ 0), linear between samples and zero outside them.
    #[staticmethod]
    #[pyo3(signature = (wavelengths, values, name = "custom"))]
    fn from_samples(
        wavelengths: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
        name: &str,
    ) -> PyResult<Self> {
        let wavelengths = floats(wavelengths, "light wavelengths")?;
        let values = floats(values, "light values")?;
        let light = attached("Light.from_samples", || {
            Light::from_samples(name, wavelengths, values)
        })?;
        Ok(PyLight { light })
    }

    /// The light's name (``d65``, the CSV file's stem, or the name given).
    #[getter]
    fn name(&self) -> String {
        self.light.name.clone()
    }

    /// Sample wavelengths in nm (float64 array).
    #[getter]
    fn wavelengths<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        array1(py, &self.light.spectrum.wavelength_nm)
    }

    /// Relative spectral power at the sample wavelengths (float64 array).
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        array1(py, &self.light.spectrum.value)
    }

    fn __repr__(&self) -> String {
        let w = &self.light.spectrum.wavelength_nm;
        format!(
            "Light({:?}, {} samples, {}–{} nm)",
            self.light.name,
            w.len(),
            w.first().copied().unwrap_or(f64::NAN),
            w.last().copied().unwrap_or(f64::NAN)
        )
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let from_samples = py.get_type::<PyLight>().getattr("from_samples")?;
        let args = (
            self.wavelengths(py),
            self.values(py),
            self.light.name.clone(),
        );
        (from_samples, args).into_pyobject(py).map(|t| t.into_any())
    }
}

/// The built-in lights, tabulated once per process (each call would otherwise parse the
/// embedded CIE tables again: a measurable share of a 10 ms fit).
fn builtin(name: &str) -> Option<Light> {
    static BUILTIN: OnceLock<Vec<Light>> = OnceLock::new();
    let lower = name.to_ascii_lowercase();
    BUILTIN
        .get_or_init(Light::standard)
        .iter()
        .find(|l| l.name == lower)
        .cloned()
}

/// The lights a fit is judged under by default (d65, a, f11, uv).
pub(crate) fn standard() -> Vec<Light> {
    STANDARD_LIGHTS
        .iter()
        .filter_map(|name| builtin(name))
        .collect()
}

/// One light from any of the accepted forms; `default_name` names a pair of arrays.
pub(crate) fn light(value: &Bound<'_, PyAny>, default_name: &str) -> PyResult<Light> {
    if let Ok(l) = value.cast::<PyLight>() {
        return Ok(l.get().light.clone());
    }
    if is_path(value) {
        let text = path(value, "light")?.to_string_lossy().into_owned();
        if let Some(light) = builtin(&text) {
            return Ok(light);
        }
        return attached("light", || Light::parse(&text));
    }
    if value.hasattr("wavelengths")? && value.hasattr("values")? {
        let name = value
            .getattr("name")
            .ok()
            .and_then(|n| n.extract::<String>().ok())
            .filter(|n| !n.trim().is_empty())
            .unwrap_or_else(|| default_name.to_string());
        let wavelengths = floats(&value.getattr("wavelengths")?, "light wavelengths")?;
        let values = floats(&value.getattr("values")?, "light values")?;
        return attached("light", || Light::from_samples(&name, wavelengths, values));
    }
    if let Some((wavelengths, values)) = pair(value)? {
        let wavelengths = floats(&wavelengths, "light wavelengths")?;
        let values = floats(&values, "light values")?;
        return attached("light", || {
            Light::from_samples(default_name, wavelengths, values)
        });
    }
    Err(invalid(
        "light",
        format!(
            "expected a light name (d65, a, f11, uv), a CSV path, a pair of arrays (wavelengths, values) or an object with .wavelengths and .values; got {}",
            type_name(value)
        ),
    ))
}

/// `(wavelengths, values)`: a tuple or list of two 1-D arrays of numbers.
fn pair<'py>(
    value: &Bound<'py, PyAny>,
) -> PyResult<Option<(Bound<'py, PyAny>, Bound<'py, PyAny>)>> {
    if !(value.is_instance_of::<PyTuple>() || value.is_instance_of::<PyList>()) {
        return Ok(None);
    }
    let parts = items(value, "light")?;
    match parts.as_slice() {
        [w, v] if is_floats(w) && is_floats(v) => Ok(Some((w.clone(), v.clone()))),
        _ => Ok(None),
    }
}

/// The lights of a `lights=` argument: None (the default), one light in any form, or a
/// list of them. A pair of arrays alone is one light named `custom`; in a list, light i
/// given as arrays is named `custom-<i+1>` (objects with a `.name` keep theirs).
pub(crate) fn lights(value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Vec<Light>>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let single = value.cast::<PyLight>().is_ok()
        || is_path(value)
        || (value.hasattr("wavelengths")? && value.hasattr("values")?)
        || pair(value)?.is_some();
    if single {
        return Ok(Some(vec![light(value, "custom")?]));
    }
    let list = items(value, "lights")?;
    if list.is_empty() {
        return Err(invalid(
            "lights",
            "is empty; give at least one light (d65, a, f11, uv, a CSV path or samples)",
        ));
    }
    list.iter()
        .enumerate()
        .map(|(i, item)| light(item, &format!("custom-{}", i + 1)))
        .collect::<PyResult<Vec<_>>>()
        .map(Some)
}

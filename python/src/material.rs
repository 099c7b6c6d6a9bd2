//! `fluorite.Material` and `fluorite.Fluorophore`: fitted or hand-made materials, their
//! matrices, colours, baked spectra, checks and exports.

use std::path::{Path, PathBuf};

use fluorite::check::{CheckReport, check_material};
use fluorite::colour::{material_xyz, xyz_to_lab};
use fluorite::export::{
    ExportFormat, ExportOptions, RgbSpace, default_grids, export_with_notes, matrix, parse_grid,
    total_radiance_factor_at, write_files,
};
use fluorite::spectrum::Spectrum;
use fluorite::{Error, Fluorophore, Material, Units, YieldForm};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use crate::convert::{array1, array2, floats, items, to_py, type_name};
use crate::lights::light;
use crate::{attached, detached, invalid};

/// A diffuse fluorescent material (Jung et al. 2018): a reflectance r(λ) and fluorophores,
/// each an absorption a(λ) (max 1), an emission e(λ) (1/nm, ∫e = 1), a concentration c
/// and a yield (the energy yield Q, or the photon yield Φ in the photon form).
///
/// Get one from ``fluorite.fit(...).material``, ``Material.load(path)`` or
/// ``Material.from_json(text)``, or build one:
/// ``Material("name", wavelengths, reflectance, fluorophores=[Fluorophore(...)])``. Every
/// way in checks the model's laws (ranges, normalisations, energy and photon
/// conservation) and raises ``FluoriteError`` naming the first one broken.
#[pyclass(module = "fluorite", name = "Material", frozen)]
#[derive(Clone)]
pub struct PyMaterial {
    pub(crate) material: Material,
}

/// One fluorescent component of a material.
///
/// ``absorption`` and ``emission`` are ``(wavelengths, values)`` pairs of float64
/// arrays: a(λ) with max 1 and e(λ) in 1/nm with ∫e dλ = 1, both zero outside their
/// samples. ``concentration`` is c (fraction absorbed at the absorption peak),
/// ``quantum_yield`` the yield of ``yield_form``: Q (``"energy"``, the paper's constant
/// energy yield) or Φ (``"photon"``, a constant photon yield); ``k`` = c·yield is what a
/// reradiation matrix determines.
#[pyclass(module = "fluorite", name = "Fluorophore", frozen)]
#[derive(Clone)]
pub struct PyFluorophore {
    pub(crate) fluorophore: Fluorophore,
}

fn spectrum(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Spectrum> {
    let parts = items(value, what)?;
    let [w, v] = parts.as_slice() else {
        return Err(invalid(what, "expected a pair (wavelengths, values)"));
    };
    let (w, v) = (floats(w, what)?, floats(v, what)?);
    attached(what, || Spectrum::new(w, v, what))
}

fn pair<'py>(
    py: Python<'py>,
    s: &Spectrum,
) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
    (array1(py, &s.wavelength_nm), array1(py, &s.value))
}

#[pymethods]
impl PyFluorophore {
    /// A fluorophore from its spectra (``(wavelengths, values)`` pairs, already
    /// normalised: max a = 1, ∫e = 1), c and the yield of ``yield_form``. The material it
    /// joins checks the laws.
    #[new]
    #[pyo3(signature = (absorption, emission, concentration, quantum_yield, *, yield_form = "energy"))]
    fn new(
        absorption: &Bound<'_, PyAny>,
        emission: &Bound<'_, PyAny>,
        concentration: f64,
        quantum_yield: f64,
        yield_form: &str,
    ) -> PyResult<Self> {
        let yield_form = match yield_form.to_ascii_lowercase().as_str() {
            "energy" => YieldForm::Energy,
            "photon" => YieldForm::Photon,
            other => {
                return Err(invalid(
                    "yield_form",
                    format!("\"{other}\" is not one of energy, photon"),
                ));
            }
        };
        Ok(PyFluorophore {
            fluorophore: Fluorophore {
                concentration,
                quantum_yield,
                yield_form,
                concentration_range: None,
                absorption: spectrum(absorption, "absorption")?,
                emission: spectrum(emission, "emission")?,
            },
        })
    }

    /// a(λ) as (wavelengths nm, values), max 1, zero outside the samples.
    #[getter]
    fn absorption<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        pair(py, &self.fluorophore.absorption)
    }

    /// e(λ) as (wavelengths nm, values in 1/nm), ∫e dλ = 1, zero outside the samples.
    #[getter]
    fn emission<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        pair(py, &self.fluorophore.emission)
    }

    /// c: the fraction absorbed at the absorption peak, in [0, 1].
    #[getter]
    fn concentration(&self) -> f64 {
        self.fluorophore.concentration
    }

    /// The yield of ``yield_form``: Q (energy) or Φ (photon), in [0, 1].
    #[getter]
    fn quantum_yield(&self) -> f64 {
        self.fluorophore.quantum_yield
    }

    /// ``"energy"`` (constant energy yield Q) or ``"photon"`` (constant photon yield Φ).
    #[getter]
    fn yield_form(&self) -> &'static str {
        self.fluorophore.yield_form.name()
    }

    /// k = c·Q (or c·Φ): the scale a reradiation matrix determines.
    #[getter]
    fn k(&self) -> f64 {
        self.fluorophore.k()
    }

    /// The interval of c consistent with the data (a fit's), or None.
    #[getter]
    fn concentration_range(&self) -> Option<(f64, f64)> {
        self.fluorophore.concentration_range.map(|[a, b]| (a, b))
    }

    /// λ̄e = ∫λ·e dλ, the mean emission wavelength in nm.
    #[getter]
    fn mean_emission(&self) -> f64 {
        self.fluorophore.emission_mean_nm()
    }

    fn __repr__(&self) -> String {
        let f = &self.fluorophore;
        format!(
            "Fluorophore(c={:.4}, {}={:.4} ({} form), mean emission {:.1} nm)",
            f.concentration,
            if f.yield_form == YieldForm::Photon {
                "Φ"
            } else {
                "Q"
            },
            f.quantum_yield,
            f.yield_form.name(),
            f.emission_mean_nm()
        )
    }
}

/// The material file's name and a JSON origin for messages.
const JSON_ORIGIN: &str = "<json>";

#[pymethods]
impl PyMaterial {
    /// A material from its reflectance r(λ) (``wavelengths`` nm and ``reflectance``
    /// values, held at its end values outside them) and fluorophores (none: a plain
    /// reflector). The laws are checked.
    #[new]
    #[pyo3(signature = (name, wavelengths, reflectance, fluorophores = None))]
    fn new(
        name: &str,
        wavelengths: &Bound<'_, PyAny>,
        reflectance: &Bound<'_, PyAny>,
        fluorophores: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let w = floats(wavelengths, "wavelengths")?;
        let r = floats(reflectance, "reflectance")?;
        let parts = match fluorophores.filter(|f| !f.is_none()) {
            None => Vec::new(),
            Some(list) => items(list, "fluorophores")?
                .iter()
                .map(|f| {
                    f.cast::<PyFluorophore>()
                        .map(|f| f.get().fluorophore.clone())
                        .map_err(|_| {
                            invalid(
                                "fluorophores",
                                format!(
                                    "expected fluorite.Fluorophore objects, got {}",
                                    type_name(f)
                                ),
                            )
                        })
                })
                .collect::<PyResult<Vec<_>>>()?,
        };
        let material = attached("Material", || {
            let reflectance = Spectrum::new(w, r, "reflectance")?;
            let material = Material::new(name, reflectance, parts);
            material.validate()?;
            Ok(material)
        })?;
        Ok(PyMaterial { material })
    }

    /// Reads and checks a material file (``fluorite-material/1`` JSON).
    #[staticmethod]
    fn load(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Self> {
        let path = crate::convert::path(path, "path")?;
        let material = detached(py, "Material.load", || Material::load(&path))?;
        Ok(PyMaterial { material })
    }

    /// Parses and checks material JSON text (what ``to_json`` and ``fluorite fit`` write).
    #[staticmethod]
    fn from_json(text: &str) -> PyResult<Self> {
        let material = attached("Material.from_json", || {
            Material::from_json(text, Path::new(JSON_ORIGIN))
        })?;
        Ok(PyMaterial { material })
    }

    /// The material as pretty JSON, conservation margins refreshed: exactly what
    /// ``save`` and the command line write.
    fn to_json(&self) -> String {
        self.material.to_json()
    }

    /// Writes the material JSON to ``path`` atomically (a temporary file, then renamed).
    fn save(&self, py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<()> {
        let path = crate::convert::path(path, "path")?;
        let material = &self.material;
        detached(py, "Material.save", || material.save(&path))
    }

    /// The material's name.
    #[getter]
    fn name(&self) -> String {
        self.material.name.clone()
    }

    /// r(λ) as (wavelengths nm, values): the reflectance of the non-fluorescent part,
    /// held at its end values outside the samples.
    #[getter]
    fn reflectance<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>) {
        pair(py, &self.material.reflectance)
    }

    /// The fluorophores (empty for a plain reflector).
    #[getter]
    fn fluorophores(&self) -> Vec<PyFluorophore> {
        self.material
            .fluorophores
            .iter()
            .map(|f| PyFluorophore {
                fluorophore: f.clone(),
            })
            .collect()
    }

    /// The ``fit`` block as a dictionary (how the material was fitted and how well it
    /// matches), or None for a hand-made material.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.material.fit.as_ref().map(|f| to_py(py, f)).transpose()
    }

    /// The reradiation matrix the material predicts, float64 of shape
    /// (len(excitation), len(emission)), on any grids (nm, strictly increasing; default:
    /// the material's own samples, for a fit the measurement's grids): radiance factors
    /// per emission bin like a BFC-450's, or densities per nm with ``per_nm``; the
    /// diagonal d = (1 − Σc·a)·r where both grids share a wavelength.
    #[pyo3(signature = (excitation = None, emission = None, *, per_nm = false))]
    fn matrix<'py>(
        &self,
        py: Python<'py>,
        excitation: Option<&Bound<'py, PyAny>>,
        emission: Option<&Bound<'py, PyAny>>,
        per_nm: bool,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (default_ex, default_em) = default_grids(&self.material);
        let ex = match excitation.filter(|e| !e.is_none()) {
            Some(e) => floats(e, "excitation")?,
            None => default_ex,
        };
        let em = match emission.filter(|e| !e.is_none()) {
            Some(e) => floats(e, "emission")?,
            None => default_em,
        };
        let units = if per_nm { Units::PerNm } else { Units::PerBin };
        let material = &self.material;
        let m = detached(py, "Material.matrix", || matrix(material, &ex, &em, units))?;
        array2(py, m.n_excitation(), m.n_emission(), m.values)
    }

    /// The colour of a flat patch of the material under ``light`` (a name, a CSV path,
    /// (wavelengths, values), or an object with .wavelengths/.values), with its
    /// fluorescence, as fluorite's colorimetry computes it (CIE 1931 2°, 1 nm over
    /// 300–830 nm, trapezoid weights): a dict with ``"xyz"`` (the perfect white diffuser
    /// under the light has Y = 100), ``"lab"`` (CIELAB against that white), ``"white"``
    /// (its XYZ) and ``"light"`` (the light's name).
    #[pyo3(signature = (light = None))]
    fn colour<'py>(
        &self,
        py: Python<'py>,
        light: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let light = one_light(py, light)?;
        let (xyz, white) = material_xyz(&self.material, &light);
        let lab = xyz_to_lab(xyz, white);
        let out = PyDict::new(py);
        out.set_item("xyz", array1(py, &xyz))?;
        out.set_item("lab", array1(py, &lab))?;
        out.set_item("white", array1(py, &white))?;
        out.set_item("light", light.name.clone())?;
        Ok(out)
    }

    /// The total radiance factor βT(λ) under ``light`` (CIE 15): d(λ) plus the
    /// fluorescence the light excites, divided by the light; what a non-fluorescent
    /// renderer needs to show the material exactly under that light (as ``export("mitsuba")``
    /// bakes it). At ``wavelengths`` (nm; default 300–830 every 1 nm); float64 array.
    #[pyo3(signature = (light = None, wavelengths = None))]
    fn total_radiance_factor<'py>(
        &self,
        py: Python<'py>,
        light: Option<&Bound<'py, PyAny>>,
        wavelengths: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let light = one_light(py, light)?;
        let grid = match wavelengths.filter(|w| !w.is_none()) {
            Some(w) => floats(w, "wavelengths")?,
            None => fluorite::colour::colour_grid().0,
        };
        let material = &self.material;
        let values = attached("Material.total_radiance_factor", || {
            Ok(total_radiance_factor_at(material, &light, &grid))
        })?;
        Ok(array1(py, &values))
    }

    /// The laws of the model the material breaks (energy and photon conservation,
    /// ranges, normalisations, forms), each a dict with ``law``, ``statement``,
    /// ``margin``, ``worst_value``, ``worst_at``, ``worst_nm`` and ``violations``, as
    /// ``fluorite check`` reports them. Empty when it conserves.
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let material = &self.material;
        let report = attached("Material.check", || Ok(check_material(material)))?;
        failed_laws(py, &report)
    }

    /// Checks a material file leniently, as ``fluorite check`` does: a file that breaks
    /// the laws (which ``load`` refuses) is still read, and every broken law is listed
    /// (dicts as ``check()`` gives them). Raises ``FluoriteError`` only when the file cannot
    /// be read or is no material at all.
    #[staticmethod]
    fn check_file<'py>(
        py: Python<'py>,
        path: &Bound<'py, PyAny>,
    ) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let path = crate::convert::path(path, "path")?;
        let report = detached(py, "Material.check_file", || {
            fluorite::check::check_file(&path)
        })?;
        failed_laws(py, &report)
    }

    /// Exports the material to ``path`` in format ``to``: ``"csv"``, ``"matrix"``,
    /// ``"bfc"``, ``"art"``, ``"exr"``, ``"rgb"`` (one file: ``path`` names it, or an
    /// existing folder or one ending in ``/``) or ``"mitsuba"``, ``"pbrt"``,
    /// ``"pearray"`` (a folder, created if missing), as ``fluorite export`` does.
    /// ``excitation``/``emission``: the matrix grids (arrays in nm or
    /// ``"start:end:step"`` text) of the matrix formats; ``per_nm``: matrix cells per nm;
    /// ``lights``: the lights of mitsuba, pbrt, pearray and rgb (default D65);
    /// ``space``: ``"srgb"`` or ``"xyz"`` for rgb. Options a format does not use are
    /// refused. Returns the paths written (all or none are written).
    #[pyo3(signature = (to, path, *, excitation = None, emission = None, per_nm = false, lights = None, space = None))]
    #[allow(clippy::too_many_arguments)]
    fn export<'py>(
        &self,
        py: Python<'py>,
        to: &str,
        path: &Bound<'py, PyAny>,
        excitation: Option<&Bound<'py, PyAny>>,
        emission: Option<&Bound<'py, PyAny>>,
        per_nm: bool,
        lights: Option<&Bound<'py, PyAny>>,
        space: Option<&str>,
    ) -> PyResult<Vec<String>> {
        let out = crate::convert::path(path, "path")?;
        let format = attached("export", || ExportFormat::parse(to))?;
        let excitation = grid(excitation, "--excitation-grid")?;
        let emission = grid(emission, "--emission-grid")?;
        let space = space
            .map(|s| attached("export", || RgbSpace::parse(s)))
            .transpose()?;
        let lights = crate::lights::lights(lights)?.unwrap_or_default();
        let options = ExportOptions {
            format,
            excitation_nm: excitation,
            emission_nm: emission,
            units: if per_nm { Units::PerNm } else { Units::PerBin },
            lights,
            space,
        };
        let material = &self.material;
        let written = detached(py, "Material.export", || {
            let exported = export_with_notes(material, &options)?;
            let names_a_folder = out.is_dir() || out.as_os_str().to_string_lossy().ends_with('/');
            let targets: Vec<(PathBuf, Vec<u8>)> = if format.is_single_file() && !names_a_folder {
                exported
                    .files
                    .into_iter()
                    .map(|f| (out.clone(), f.contents))
                    .collect()
            } else {
                std::fs::create_dir_all(&out).map_err(|e| {
                    Error::io(
                        &out,
                        std::io::Error::new(
                            e.kind(),
                            format!("cannot create the output folder: {e}"),
                        ),
                    )
                })?;
                exported
                    .files
                    .into_iter()
                    .map(|f| (out.join(&f.name), f.contents))
                    .collect()
            };
            write_files(&targets)?;
            Ok(targets.into_iter().map(|(p, _)| p).collect::<Vec<_>>())
        })?;
        Ok(written.iter().map(|p| p.display().to_string()).collect())
    }

    fn __repr__(&self) -> String {
        let m = &self.material;
        format!(
            "Material({:?}, {} fluorophore{}{})",
            m.name,
            m.fluorophores.len(),
            if m.fluorophores.len() == 1 { "" } else { "s" },
            m.fit
                .as_ref()
                .filter(|f| !f.model.is_empty())
                .map(|f| format!(", model {}", f.model))
                .unwrap_or_default()
        )
    }

    /// Materials are equal when their JSON is (what a file holds: the fit's time, which
    /// is not written, does not count).
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<PyMaterial>()
            .is_ok_and(|o| o.get().material.to_json() == self.material.to_json())
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let from_json = py.get_type::<PyMaterial>().getattr("from_json")?;
        (from_json, (self.material.to_json(),))
            .into_pyobject(py)
            .map(|t| t.into_any())
    }
}

/// The laws a check report finds broken, as dictionaries.
fn failed_laws<'py>(py: Python<'py>, report: &CheckReport) -> PyResult<Vec<Bound<'py, PyAny>>> {
    let failed = report.failed();
    report
        .laws
        .iter()
        .filter(|l| failed.contains(&l.law))
        .map(|l| to_py(py, l))
        .collect()
}

/// One light, D65 when None.
fn one_light(
    py: Python<'_>,
    value: Option<&Bound<'_, PyAny>>,
) -> PyResult<fluorite::colour::Light> {
    match value.filter(|v| !v.is_none()) {
        Some(v) => light(v, "custom"),
        None => light(PyString::new(py, "d65").as_any(), "d65"),
    }
}

/// A matrix grid: an array of wavelengths or `start:end:step` text.
fn grid(value: Option<&Bound<'_, PyAny>>, flag: &str) -> PyResult<Option<Vec<f64>>> {
    match value.filter(|v| !v.is_none()) {
        None => Ok(None),
        Some(v) => {
            if let Ok(text) = v.extract::<String>() {
                return attached("export", || parse_grid(&text, flag)).map(Some);
            }
            floats(v, flag).map(Some)
        }
    }
}

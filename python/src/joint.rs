//! `fluorite.joint`: joint fits of sample sets (PARAFAC of instrument EEMs, or the
//! concentration series of surface matrices).

use fluorite::fit::YieldChoice;
use fluorite::fit::joint::JointFit;
use fluorite::fit::joint::reference::{AnalyteMatch, Reference};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{array1, array2, choice, is_path, items, to_py, type_name};
use crate::material::PyMaterial;
use crate::measurement::{PyMeasurement, ReadArgs};
use crate::{detached, invalid};
use fluorite::pipeline::joint::fit_samples;
use fluorite::pipeline::{JointOutcome, JointRequest, Prepared, read_input};

/// One PARAFAC model of a set of EEMs (one component count K).
///
/// The shapes are shared by every sample: ``excitation_loadings`` (K, n_excitation),
/// each row an absorption a(λ) with max 1 on ``excitation`` (nm), and
/// ``emission_loadings`` (K, n_emission), each an emission e(λ) with ∫e dλ = 1 on
/// ``emission``; ``scores`` (n_samples, K) carry the scale (c·Q in the data's units),
/// samples in ``samples`` order, components largest share first.
#[pyclass(module = "fluorite", name = "ParafacFit", frozen)]
pub struct PyParafacFit {
    fit: JointFit,
    matches: Option<Vec<AnalyteMatch>>,
}

impl PyParafacFit {
    /// One row per component of the spectrum `spectrum` picks, as a float64 (K, n) array.
    fn loadings<'py>(
        &self,
        py: Python<'py>,
        spectrum: impl Fn(&fluorite::fit::joint::JointComponent) -> &Vec<f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rows: Vec<&Vec<f64>> = self.fit.components.iter().map(spectrum).collect();
        let n = rows.first().map_or(0, |r| r.len());
        array2(
            py,
            rows.len(),
            n,
            rows.into_iter().flatten().copied().collect(),
        )
    }
}

#[pymethods]
impl PyParafacFit {
    /// K, the number of components.
    #[getter]
    fn components(&self) -> usize {
        self.fit.components.len()
    }

    /// Sample names (file stems), in input order.
    #[getter]
    fn samples(&self) -> Vec<String> {
        self.fit.samples.clone()
    }

    /// The excitation grid of the loadings (nm, after ``ex_range``).
    #[getter]
    fn excitation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let grid = self
            .fit
            .components
            .first()
            .map(|c| c.absorption.wavelength_nm.clone())
            .unwrap_or_default();
        array1(py, &grid)
    }

    /// The emission grid of the loadings (nm, after ``em_range``).
    #[getter]
    fn emission<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let grid = self
            .fit
            .components
            .first()
            .map(|c| c.emission.wavelength_nm.clone())
            .unwrap_or_default();
        array1(py, &grid)
    }

    /// Absorption (excitation) loadings, float64 (K, n_excitation), each max 1.
    #[getter]
    fn excitation_loadings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.loadings(py, |c| &c.absorption.value)
    }

    /// Emission loadings, float64 (K, n_emission), each with ∫e dλ = 1 (1/nm).
    #[getter]
    fn emission_loadings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.loadings(py, |c| &c.emission.value)
    }

    /// Scores, float64 (n_samples, K), in the data's (arbitrary) units.
    #[getter]
    fn scores<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let k = self.fit.components.len();
        let values: Vec<f64> = self.fit.scores.iter().flatten().copied().collect();
        array2(py, self.fit.scores.len(), k, values)
    }

    /// Each component's share of the model's sum of squares (float64, K).
    #[getter]
    fn shares<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let shares: Vec<f64> = self.fit.components.iter().map(|c| c.share).collect();
        array1(py, &shares)
    }

    /// 1 − Σ residual² / Σ data² over the measured cells (uncentred, as drEEM reports).
    #[getter]
    fn explained_variance(&self) -> f64 {
        self.fit.explained_variance
    }

    /// Core consistency in per cent (Bro & Kiers 2003).
    #[getter]
    fn core_consistency(&self) -> f64 {
        self.fit.core_consistency
    }

    /// Split-half validation as a dict (``split``, ``pairs``, ``min_congruence``,
    /// ``validated``), or None when skipped or with fewer than four samples.
    #[getter]
    fn split_half<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.fit
            .split_half
            .as_ref()
            .map(|s| to_py(py, s))
            .transpose()
    }

    /// RMS residual relative to the RMS data, per sample (float64).
    #[getter]
    fn residual_per_sample<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.fit.residual_per_sample)
    }

    /// Whether the alternating least squares converged.
    #[getter]
    fn converged(&self) -> bool {
        self.fit.converged
    }

    /// ALS sweeps run.
    #[getter]
    fn iterations(&self) -> usize {
        self.fit.iterations
    }

    /// With a ``reference`` of known concentrations: per analyte a dict with
    /// ``analyte``, ``component`` (1-based; 0 when none correlates), ``r_squared`` and
    /// ``samples``; None without a reference.
    #[getter]
    fn matches<'py>(&self, py: Python<'py>) -> PyResult<Option<Vec<Bound<'py, PyDict>>>> {
        self.matches
            .as_ref()
            .map(|list| {
                list.iter()
                    .map(|m| {
                        let d = PyDict::new(py);
                        d.set_item("analyte", &m.analyte)?;
                        d.set_item("component", m.component)?;
                        d.set_item("r_squared", m.r_squared)?;
                        d.set_item("samples", m.samples)?;
                        Ok(d)
                    })
                    .collect()
            })
            .transpose()
    }

    /// The whole model as a dict (the ``model.json`` a joint fit writes).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.fit)
    }

    /// The ``model.json`` text.
    fn to_json(&self) -> String {
        self.fit.to_json()
    }

    fn __repr__(&self) -> String {
        format!(
            "ParafacFit(K={}, {} samples, explained variance {:.4}, core consistency {:.1} %{})",
            self.fit.components.len(),
            self.fit.samples.len(),
            self.fit.explained_variance,
            self.fit.core_consistency,
            self.fit
                .split_half
                .as_ref()
                .map(|s| format!(
                    ", split-half {}",
                    if s.validated {
                        "validated"
                    } else {
                        "not validated"
                    }
                ))
                .unwrap_or_default()
        )
    }
}

/// The result of ``fluorite.joint``: PARAFAC models of a set of instrument EEMs (one per
/// component count asked for, ``fits``), or the concentration series of surface
/// matrices of one material (``series``).
///
/// For one PARAFAC model (one K), ``excitation_loadings``, ``emission_loadings``,
/// ``scores``, ``explained_variance``, ``core_consistency`` and ``split_half`` are that
/// model's (see ``ParafacFit``); with several K use ``fits[i]``.
#[pyclass(module = "fluorite", name = "JointResult", frozen)]
pub struct PyJointResult {
    outcome: JointOutcome,
    fits: Vec<Py<PyParafacFit>>,
}

impl PyJointResult {
    fn single(&self, what: &str) -> PyResult<&Py<PyParafacFit>> {
        match self.fits.as_slice() {
            [one] => Ok(one),
            [] => Err(invalid(
                what,
                "a concentration series has no PARAFAC factors; see .series and .materials",
            )),
            several => Err(invalid(
                what,
                format!(
                    "{} models were fitted (K = {}); take one from .fits",
                    several.len(),
                    several
                        .iter()
                        .map(|f| f.get().components().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )),
        }
    }
}

#[pymethods]
impl PyJointResult {
    /// ``"parafac"`` (instrument EEMs) or ``"series"`` (surface matrices).
    #[getter]
    fn kind(&self) -> &'static str {
        match self.outcome {
            JointOutcome::Series(_) => "series",
            JointOutcome::Eem(_) => "parafac",
        }
    }

    /// The PARAFAC models, one per component count (empty for a series).
    #[getter]
    fn fits<'py>(&self, py: Python<'py>) -> Vec<Py<PyParafacFit>> {
        self.fits.iter().map(|f| f.clone_ref(py)).collect()
    }

    /// The concentration series (the ``series.json`` content: shared r, a, e and yield,
    /// c per file with standard errors) as a dict; None for EEMs.
    #[getter]
    fn series<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match &self.outcome {
            JointOutcome::Series(s) => to_py(py, s.as_ref()).map(Some),
            JointOutcome::Eem(_) => Ok(None),
        }
    }

    /// A series' complete material per file (shared spectra and yield, its c); empty
    /// for EEMs.
    #[getter]
    fn materials(&self) -> Vec<PyMaterial> {
        match &self.outcome {
            JointOutcome::Series(s) => (0..s.files.len())
                .map(|i| PyMaterial {
                    material: s.material_for(i),
                })
                .collect(),
            JointOutcome::Eem(_) => Vec::new(),
        }
    }

    /// A series' concentrations c per file (float64); None for EEMs.
    #[getter]
    fn concentrations<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray1<f64>>> {
        match &self.outcome {
            JointOutcome::Series(s) => {
                let c: Vec<f64> = s.files.iter().map(|f| f.concentration).collect();
                Some(array1(py, &c))
            }
            JointOutcome::Eem(_) => None,
        }
    }

    /// The single PARAFAC model's absorption loadings (K, n_excitation).
    #[getter]
    fn excitation_loadings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.single("excitation_loadings")?
            .get()
            .excitation_loadings(py)
    }

    /// The single PARAFAC model's emission loadings (K, n_emission).
    #[getter]
    fn emission_loadings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.single("emission_loadings")?
            .get()
            .emission_loadings(py)
    }

    /// The single PARAFAC model's excitation grid (nm).
    #[getter]
    fn excitation<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(self.single("excitation")?.get().excitation(py))
    }

    /// The single PARAFAC model's emission grid (nm).
    #[getter]
    fn emission<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray1<f64>>> {
        Ok(self.single("emission")?.get().emission(py))
    }

    /// The single PARAFAC model's scores (n_samples, K).
    #[getter]
    fn scores<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        self.single("scores")?.get().scores(py)
    }

    /// The single PARAFAC model's explained variance.
    #[getter]
    fn explained_variance(&self) -> PyResult<f64> {
        Ok(self
            .single("explained_variance")?
            .get()
            .explained_variance())
    }

    /// The single PARAFAC model's core consistency (%).
    #[getter]
    fn core_consistency(&self) -> PyResult<f64> {
        Ok(self.single("core_consistency")?.get().core_consistency())
    }

    /// The single PARAFAC model's split-half validation (dict or None).
    #[getter]
    fn split_half<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.single("split_half")?.get().split_half(py)
    }

    /// Writes what ``fluorite fit --joint`` writes into folder ``dir`` (created if
    /// missing): per K ``model.json``, ``scores.csv``, ``component-<k>.json`` (in
    /// ``k<K>/`` subfolders for several K), or ``series.json`` and one material per file.
    /// Returns the paths written.
    fn write(&self, py: Python<'_>, dir: &Bound<'_, PyAny>) -> PyResult<Vec<String>> {
        let dir = crate::convert::path(dir, "dir")?;
        let outcome = &self.outcome;
        let written = detached(py, "JointResult.write", || outcome.write(&dir))?;
        Ok(written.iter().map(|p| p.display().to_string()).collect())
    }

    fn __repr__(&self) -> String {
        match &self.outcome {
            JointOutcome::Series(s) => format!(
                "JointResult(series of {} files, {} form, yield {:.4})",
                s.files.len(),
                s.yield_form.name(),
                s.quantum_yield
            ),
            JointOutcome::Eem(fits) => format!(
                "JointResult(parafac, K = {})",
                fits.iter()
                    .map(|f| f.fit.components.len().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}

/// Component counts: an int, or a list / tuple / range of ints.
fn components(value: Option<&Bound<'_, PyAny>>) -> PyResult<Vec<usize>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(Vec::new());
    };
    if let Ok(k) = value.extract::<usize>() {
        return Ok(vec![k]);
    }
    items(value, "components")?
        .iter()
        .map(|k| {
            k.extract::<usize>().map_err(|_| {
                invalid(
                    "components",
                    format!("expected counts (int, list or range), got {}", type_name(k)),
                )
            })
        })
        .collect()
}

fn range(value: Option<(f64, f64)>, what: &str) -> PyResult<Option<(f64, f64)>> {
    match value {
        Some((lo, hi)) if !(lo.is_finite() && hi.is_finite() && lo < hi) => Err(invalid(
            what,
            format!("({lo}, {hi}): give (low, high) in nm with low below high"),
        )),
        other => Ok(other),
    }
}

/// Fits a set of samples jointly, as ``fluorite fit FILES --joint`` does.
///
/// ``measurements`` is a list of ``Measurement`` objects and/or paths (read with the
/// reading options of ``fluorite.read``). Prepared instrument EEMs get a non-negative
/// PARAFAC per component count (``components``: an int, default 4, or a list or range
/// of them): shapes shared by all samples, one score per sample and component, judged by
/// explained variance, core consistency and split-half (``no_split_half`` skips it),
/// within ``em_range``/``ex_range`` (``(low, high)`` nm); ``reference`` (a CSV of known
/// concentrations) matches each analyte to a component. Radiance-factor surface
/// matrices of one material at several concentrations get the concentration series
/// (shared r, a, e and yield, c per file; ``yield_form``, ``guard``, ``lights``).
/// ``max_iterations`` bounds the PARAFAC sweeps or the series' Gauss-Newton.
///
/// The GIL is released during the fit. Returns a ``JointResult``.
#[pyfunction]
#[pyo3(signature = (measurements, *, components = None, em_range = None, ex_range = None, no_split_half = false, max_iterations = 500, lights = None, yield_form = "auto", guard = None, reference = None, format = None, rows = None, zero_is_missing = None, per_nm = None, units = None, blank = None, absorbance = None, keep_scatter = None, scatter_width = None, bandwidth = None, raman_shift = None))]
#[allow(clippy::too_many_arguments)]
pub fn joint<'py>(
    py: Python<'py>,
    measurements: &Bound<'py, PyAny>,
    components: Option<Bound<'py, PyAny>>,
    em_range: Option<(f64, f64)>,
    ex_range: Option<(f64, f64)>,
    no_split_half: bool,
    max_iterations: u64,
    lights: Option<Bound<'py, PyAny>>,
    yield_form: &str,
    guard: Option<f64>,
    reference: Option<Bound<'py, PyAny>>,
    format: Option<String>,
    rows: Option<String>,
    zero_is_missing: Option<bool>,
    per_nm: Option<bool>,
    units: Option<String>,
    blank: Option<Bound<'py, PyAny>>,
    absorbance: Option<Bound<'py, PyAny>>,
    keep_scatter: Option<bool>,
    scatter_width: Option<Bound<'py, PyAny>>,
    bandwidth: Option<f64>,
    raman_shift: Option<f64>,
) -> PyResult<PyJointResult> {
    let read = ReadArgs {
        format,
        rows,
        zero_is_missing,
        per_nm,
        units,
        blank,
        absorbance,
        keep_scatter,
        scatter_width,
        bandwidth,
        raman_shift,
    };
    let input = read.options()?;
    let given = read.first_given();
    let mut request = JointRequest {
        components: self::components(components.as_ref())?,
        em_range: range(em_range, "em_range")?,
        ex_range: range(ex_range, "ex_range")?,
        no_split_half,
        max_iterations,
        yield_choice: choice::<YieldChoice>(yield_form, "yield_form")?,
        guard_nm: guard,
        ..JointRequest::default()
    };
    if let Some(lights) = crate::lights::lights(lights.as_ref())? {
        request.lights = lights;
    }
    let reference = reference
        .filter(|r| !r.is_none())
        .map(|r| crate::convert::path(&r, "reference"))
        .transpose()?;
    enum Sample {
        Given(Box<Prepared>),
        File(std::path::PathBuf),
    }
    let samples = items(measurements, "measurements")?
        .iter()
        .map(|v| {
            if let Ok(m) = v.cast::<PyMeasurement>() {
                if let Some(option) = given {
                    return Err(invalid(
                        option,
                        "is an option for reading files, but a Measurement was given; pass paths, or read them first",
                    ));
                }
                Ok(Sample::Given(Box::new(m.get().prepared.clone())))
            } else if is_path(v) {
                Ok(Sample::File(crate::convert::path(v, "measurements")?))
            } else {
                Err(invalid(
                    "measurements",
                    format!("expected Measurement objects or paths, got {}", type_name(v)),
                ))
            }
        })
        .collect::<PyResult<Vec<_>>>()?;
    let count = samples.len();
    let outcome = detached(py, "joint", move || {
        if let Some(path) = &reference {
            request.reference = Some(Reference::read(path)?);
        }
        let prepared = samples
            .into_iter()
            .enumerate()
            .map(|(i, s)| match s {
                Sample::Given(p) => Ok(*p),
                Sample::File(path) => read_input(&path, i, count, &input),
            })
            .collect::<fluorite::Result<Vec<_>>>()?;
        fit_samples(&prepared, &request)
    })?;
    let fits = match &outcome {
        JointOutcome::Eem(fits) => fits
            .iter()
            .map(|f| {
                Py::new(
                    py,
                    PyParafacFit {
                        fit: f.fit.clone(),
                        matches: f.matches.clone(),
                    },
                )
            })
            .collect::<PyResult<Vec<_>>>()?,
        JointOutcome::Series(_) => Vec::new(),
    };
    Ok(PyJointResult { outcome, fits })
}

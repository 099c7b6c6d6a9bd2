//! `fluorite.fit`, `fluorite.fit_many` and `fluorite.Fit`.

use std::path::PathBuf;

use fluorite::Material;
use fluorite::fit::{
    BandAxisChoice, FitOptions, FitOutcome, ModelChoice, Solver, Start, YieldChoice,
};
use fluorite::material::FluorophoreShapes;
use numpy::PyArray2;
use pyo3::prelude::*;

use crate::convert::{array2, choice, is_path, to_py, type_name};
use crate::material::PyMaterial;
use crate::measurement::{PyMeasurement, ReadArgs};
use crate::{FluoriteError, attached, detached, error, invalid};
use fluorite::pipeline::{InputOptions, Prepared, fit_many as fit_all, fit_prepared, read_input};

/// The result of a fit: the material (or, for an uncalibrated EEM, the fluorophore's
/// shapes) and the fit's report.
///
/// ``material`` is a ``fluorite.Material`` (None when the data determine shapes only);
/// ``shapes`` the ``fluorite-fluorophore/1`` content as a dict for such fits (None
/// otherwise); ``delta_e`` maps each light to the ΔE2000 between the measurement as
/// measured and the fitted model; ``report`` is the JSON ``fit`` block as a dict;
/// ``to_json()`` is byte for byte what ``fluorite fit`` writes for the same input and
/// options.
#[pyclass(module = "fluorite", name = "Fit", frozen)]
pub struct PyFit {
    outcome: FitOutcome,
    measurement: Prepared,
}

#[pymethods]
impl PyFit {
    /// The fitted material, or None for a shapes-only fit (an uncalibrated EEM).
    #[getter]
    fn material(&self) -> Option<PyMaterial> {
        match &self.outcome {
            FitOutcome::Material(m) => Some(PyMaterial {
                material: (**m).clone(),
            }),
            FitOutcome::Shapes(_) => None,
        }
    }

    /// For a shapes-only fit (an uncalibrated EEM): the ``fluorite-fluorophore/1`` content
    /// (absorption and emission shapes, k in the data's units, what is undetermined, the
    /// report) as a dict; None when the fit gave a material.
    #[getter]
    fn shapes<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match &self.outcome {
            FitOutcome::Shapes(s) => to_py(py, s.as_ref()).map(Some),
            FitOutcome::Material(_) => Ok(None),
        }
    }

    /// ΔE2000 per light (name → value) between the measurement as measured and the fitted
    /// model, for a flat patch: the report's ``delta_e2000``.
    #[getter]
    fn delta_e<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.outcome.report().delta_e2000)
    }

    /// Per light (name → value), the RMS ΔE2000 that the cells' noise alone (σ from the
    /// anti-Stokes side, the report's ``noise_sigma``) gives the measured patch colour:
    /// how well the measurement knows its own colour. A ``delta_e`` of this size is within
    /// what the measurement can tell. The report's ``delta_e2000_noise``; empty when the
    /// fit judged no colour or found no noise.
    #[getter]
    fn delta_e_noise<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.outcome.report().delta_e2000_noise)
    }

    /// Crosstalk found next to the diagonal (the instrument's, not the material's), as a
    /// dict: per side the fraction of the diagonal one step ``below`` and ``above`` it (with
    /// ``below_error``, ``above_error``, ``quiet_rows``), what it is worth in the measured
    /// colour per light (``delta_e2000``), and whether the fit took it out of the cells
    /// (``removed``; ``note`` says why not). ``None`` when no cell shows it above the noise.
    /// The report's ``crosstalk``.
    #[getter]
    fn crosstalk<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.outcome.report().crosstalk)
    }

    /// The fit report, the JSON ``fit`` block as a dict (solver, convergence, residuals,
    /// ΔE2000, warnings, model, search, escalation, preprocessing, …).
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, self.outcome.report())
    }

    /// Where not to trust the fit, one sentence each (empty when none).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.outcome.report().warnings.clone()
    }

    /// Whether the solver met its convergence criterion.
    #[getter]
    fn converged(&self) -> bool {
        self.outcome.report().converged
    }

    /// The spectral model fitted (``tabulated``, ``gaussian:1x2+r4``, …).
    #[getter]
    fn model(&self) -> String {
        self.outcome.report().model.clone()
    }

    /// Wall time of the fit inside the library, in seconds (not written to the JSON).
    #[getter]
    fn seconds(&self) -> f64 {
        self.outcome.report().seconds
    }

    /// The measurement fitted (as read and prepared).
    #[getter]
    fn measurement(&self) -> PyMeasurement {
        PyMeasurement {
            prepared: self.measurement.clone(),
        }
    }

    /// The matrix the fitted material predicts on the measurement's grids and in its
    /// units, float64 (n_excitation, n_emission), to set beside ``measurement.values``;
    /// None for a shapes-only fit.
    #[getter]
    fn predicted<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyArray2<f64>>>> {
        match &self.outcome {
            FitOutcome::Material(material) => {
                let m = &self.measurement.measurement;
                let p = attached("Fit.predicted", || {
                    Ok(fluorite::model::predict_like(material, m))
                })?;
                array2(py, p.n_excitation(), p.n_emission(), p.values).map(Some)
            }
            FitOutcome::Shapes(_) => Ok(None),
        }
    }

    /// The JSON ``fluorite fit`` writes for this fit (material or shapes), byte for byte.
    fn to_json(&self) -> String {
        self.outcome.to_json()
    }

    /// Writes ``to_json()`` to ``path`` atomically (a temporary file, then renamed).
    fn save(&self, py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<()> {
        let path = crate::convert::path(path, "path")?;
        let json = self.outcome.to_json();
        detached(py, "Fit.save", || {
            fluorite::files::write_atomic(&path, json.as_bytes())
        })
    }

    fn __repr__(&self) -> String {
        let r = self.outcome.report();
        let de: Vec<String> = r
            .delta_e2000
            .iter()
            .map(|(l, v)| format!("{l} {v:.2}"))
            .collect();
        format!(
            "Fit({:?}, {}, model {}, {}, ΔE2000 {}{})",
            self.measurement.measurement.name,
            match self.outcome {
                FitOutcome::Material(_) => "material",
                FitOutcome::Shapes(_) => "shapes",
            },
            if r.model.is_empty() {
                "tabulated"
            } else {
                &r.model
            },
            if r.converged {
                "converged"
            } else {
                "not converged"
            },
            de.join(", "),
            if r.warnings.is_empty() {
                String::new()
            } else {
                format!(", {} warnings", r.warnings.len())
            }
        )
    }

    /// Pickling (process pools): the written JSON, the time and the measurement.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let kind = matches!(self.outcome, FitOutcome::Material(_));
        let state = (
            kind,
            self.outcome.to_json(),
            self.outcome.report().seconds,
            self.measurement(),
        );
        let rebuild = py.get_type::<PyFit>().getattr("_from_state")?;
        (rebuild, (state,)).into_pyobject(py).map(|t| t.into_any())
    }

    /// Rebuilds a pickled fit (see ``__reduce__``).
    #[staticmethod]
    fn _from_state(state: (bool, String, f64, Bound<'_, PyMeasurement>)) -> PyResult<Self> {
        let (is_material, json, seconds, measurement) = state;
        let mut outcome = attached("Fit", || {
            Ok(if is_material {
                FitOutcome::Material(Box::new(Material::from_json(
                    &json,
                    std::path::Path::new("<pickle>"),
                )?))
            } else {
                let shapes: FluorophoreShapes = serde_json::from_str(&json)
                    .map_err(|e| fluorite::Error::invalid("fit", e.to_string()))?;
                FitOutcome::Shapes(Box::new(shapes))
            })
        })?;
        outcome.set_seconds(seconds);
        Ok(PyFit {
            outcome,
            measurement: measurement.get().prepared.clone(),
        })
    }
}

// The signatures spell the library's defaults as literals, for `help()`; they must agree.
const _: () = assert!(fluorite::fit::DEFAULT_TOLERANCE == 1e-5);
const _: () = assert!(fluorite::fit::DEFAULT_COLOUR_WEIGHT == 0.01);

/// The fit options of `fit` and `fit_many` (the flags of `fluorite fit`).
pub(crate) struct FitArgs<'py, 'a> {
    pub lights: Option<Bound<'py, PyAny>>,
    pub model: Option<String>,
    pub max_delta_e: Option<f64>,
    pub yield_form: &'a str,
    pub quantum_yield: Option<f64>,
    pub concentration: Option<f64>,
    pub guard: Option<f64>,
    pub solver: &'a str,
    pub start: &'a str,
    pub max_iterations: u64,
    pub tolerance: f64,
    pub colour_weight: f64,
    pub noise_aware_bound: bool,
    pub band_axis: &'a str,
}

impl FitArgs<'_, '_> {
    /// The library's options, as `fluorite fit` builds them from its flags.
    pub fn options(&self) -> PyResult<FitOptions> {
        let model = self
            .model
            .as_deref()
            .map(|m| attached("fit", || m.parse::<ModelChoice>()))
            .transpose()?;
        Ok(FitOptions {
            solver: choice::<Solver>(self.solver, "solver")?,
            guard_nm: self.guard,
            yield_choice: choice::<YieldChoice>(self.yield_form, "yield_form")?,
            quantum_yield: self.quantum_yield,
            concentration: self.concentration,
            max_iterations: self.max_iterations,
            tolerance: self.tolerance,
            lights: match crate::lights::lights(self.lights.as_ref())? {
                Some(lights) => lights,
                None => crate::lights::standard(),
            },
            start: choice::<Start>(self.start, "start")?,
            model: match (model, self.max_delta_e) {
                (Some(model), _) => model,
                (None, Some(_)) => ModelChoice::Auto,
                (None, None) => ModelChoice::AsNeeded,
            },
            max_delta_e: self.max_delta_e,
            colour_weight: self.colour_weight,
            noise_aware_bound: match (self.noise_aware_bound, self.max_delta_e) {
                (true, None) => {
                    return Err(crate::invalid(
                        "noise_aware_bound",
                        "judges the search's bound; give max_delta_e too",
                    ));
                }
                (flag, _) => flag,
            },
            band_axis: match (
                model,
                choice::<BandAxisChoice>(self.band_axis, "band_axis")?,
            ) {
                (Some(ModelChoice::Fixed(_)), axis) if axis != BandAxisChoice::Both => {
                    return Err(crate::invalid(
                        "band_axis",
                        "chooses the model search's axis; a model that names one structure takes its name's (append @wavelength for bands Gaussian in wavelength): drop band_axis or model",
                    ));
                }
                (_, axis) => axis,
            },
        })
    }
}

/// What to fit: a measurement already read, or a file to read with the options.
enum Item {
    Measurement(Box<Prepared>),
    Path(PathBuf),
}

fn item(value: &Bound<'_, PyAny>, read_given: Option<&str>) -> PyResult<Item> {
    if let Ok(m) = value.cast::<PyMeasurement>() {
        if let Some(option) = read_given {
            return Err(invalid(
                option,
                "is an option for reading a file, but a Measurement was given (it was read already); pass the path instead, or read it with fluorite.read(path, ...) first",
            ));
        }
        return Ok(Item::Measurement(Box::new(m.get().prepared.clone())));
    }
    if is_path(value) {
        return Ok(Item::Path(crate::convert::path(value, "path")?));
    }
    Err(invalid(
        "fit",
        format!(
            "expected a fluorite.Measurement or a path (str or os.PathLike), got {}",
            type_name(value)
        ),
    ))
}

/// Reads (if a path) `item` as input `index` of `count`.
fn prepared(
    item: Item,
    index: usize,
    count: usize,
    input: &InputOptions,
) -> fluorite::Result<Prepared> {
    match item {
        Item::Measurement(p) => Ok(*p),
        Item::Path(path) => read_input(&path, index, count, input),
    }
}

/// Fits the diffuse fluorescent BBRRDF (Jung et al. 2018) to a reradiation matrix.
///
/// ``measurement_or_path`` is a ``Measurement`` (``values`` of shape (n_excitation,
/// n_emission), NaN = missing) or a file path, read with the reading options of
/// ``fluorite.read`` (``format``, ``rows``, ``zero_is_missing``, ``per_nm``, ``units``,
/// ``blank``, ``absorbance``, ``keep_scatter``, ``scatter_width``, ``bandwidth``,
/// ``raman_shift``; refused with a Measurement, which was read already).
///
/// The options are those of ``fluorite fit``, with its defaults:
///
/// - ``lights``: the lights of the ΔE2000 report, of the colour term and of the search's
///   bound (default d65, a, f11, uv): names, CSV paths, ``(wavelengths, values)`` pairs,
///   objects with ``.wavelengths``/``.values``, or a list of them.
/// - ``model``: ``"as-needed"`` (default: one fluorophore on the grid, escalated to the
///   first parametric model the noise-aware search keeps, each light held to ΔE2000 ≤ 1
///   or its measured colour's noise, when it does not explain the matrix; a miss the
///   crosstalk it removed explains does not escalate),
///   ``"tabulated"``, ``"auto"`` (the model search) or ``"gaussian:KxB[/E][+rD|+rt]"``;
///   ``max_delta_e`` implies ``"auto"`` and sets its bound.
/// - ``yield_form``: ``"auto"``, ``"energy"`` or ``"photon"``; ``quantum_yield`` or
///   ``concentration`` pins Q or c from outside knowledge.
/// - ``guard``: set aside cells within this many nm of the diagonal (default none).
/// - ``solver`` (``"lbfgs"``, ``"gauss-newton"``, ``"nelder-mead"``, ``"init"``),
///   ``start`` (``"closed-form"``, ``"flat"``), ``max_iterations``, ``tolerance``,
///   ``colour_weight``.
/// - ``noise_aware_bound``: with ``max_delta_e``, hold each light to max(bound, 3 × the
///   measured colour's own noise RMS ΔE2000; at most the grid fit's ΔE2000 + bound) and
///   weigh its colour term by that noise (a noisy colour's also by the share of what the
///   grid fit leaves beyond the noise, in its residual or that colour); take the
///   candidates' reflectance tabulated where no polynomial fits the grid fit's diagonal
///   within the cells' noise; a candidate that meets the bound but that the
///   matrix tells from the grid model is passed over: for the grid fit where it leaves
///   only noise and meets the bound (or, where it meets a light only within that
///   light's noise, for the larger one-component model of lowest BIC below its own,
///   fitted to the matrix alone, that meets the bound and passes), else for a later
///   candidate that passes
///   (``fluorite fit --noise-aware-bound``); the report's
///   ``model_search.misses_within_noise`` lists the lights judged so, and
///   ``model_search.matrix_test`` what the test decided and why.
/// - ``band_axis``: ``"both"`` (default: the model search runs with its Gaussian bands on
///   wavenumber and on wavelength and keeps the one that meets its rule, of two the one
///   of lower BIC; ``model_search.band_axis`` says which and why), ``"wavenumber"`` or
///   ``"wavelength"``; a ``model`` that names one structure takes its name's axis
///   (``@wavelength``, else wavenumber).
///
/// The GIL is released while the file is read and the fit runs. Returns a ``Fit``;
/// raises ``FluoriteError`` with the command line's message.
#[pyfunction]
#[pyo3(signature = (measurement_or_path, *, lights = None, model = None, max_delta_e = None, yield_form = "auto", quantum_yield = None, concentration = None, guard = None, solver = "lbfgs", start = "closed-form", max_iterations = 500, tolerance = 1e-5, colour_weight = 0.01, noise_aware_bound = false, band_axis = "both", format = None, rows = None, zero_is_missing = None, per_nm = None, units = None, blank = None, absorbance = None, keep_scatter = None, scatter_width = None, bandwidth = None, raman_shift = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit<'py>(
    py: Python<'py>,
    measurement_or_path: &Bound<'py, PyAny>,
    lights: Option<Bound<'py, PyAny>>,
    model: Option<String>,
    max_delta_e: Option<f64>,
    yield_form: &str,
    quantum_yield: Option<f64>,
    concentration: Option<f64>,
    guard: Option<f64>,
    solver: &str,
    start: &str,
    max_iterations: u64,
    tolerance: f64,
    colour_weight: f64,
    noise_aware_bound: bool,
    band_axis: &str,
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
) -> PyResult<PyFit> {
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
    let args = FitArgs {
        lights,
        model,
        max_delta_e,
        yield_form,
        quantum_yield,
        concentration,
        guard,
        solver,
        start,
        max_iterations,
        tolerance,
        colour_weight,
        noise_aware_bound,
        band_axis,
    };
    let options = args.options()?;
    let input = read.options()?;
    let what = item(measurement_or_path, read.first_given())?;
    let (measurement, outcome) = detached(py, "fit", || {
        let prepared = prepared(what, 0, 1, &input)?;
        let outcome = fit_prepared(&prepared, &options)?;
        Ok((prepared, outcome))
    })?;
    Ok(PyFit {
        outcome,
        measurement,
    })
}

/// Fits several measurements or files in parallel (a pool of ``threads`` Rust threads;
/// default: one per core), with the GIL released; results in input order.
///
/// ``items`` is a list of ``Measurement`` objects and/or paths; the options are those of
/// ``fluorite.fit`` (per-input ``blank``/``absorbance`` lists apply in the items' order,
/// as on the command line). With ``errors="raise"`` (the default) the first failure
/// raises ``FluoriteError`` naming the item; with ``errors="return"`` a failed item's
/// place in the list holds its ``FluoriteError`` instead of a ``Fit``.
#[pyfunction]
#[pyo3(signature = (items, *, threads = None, errors = "raise", lights = None, model = None, max_delta_e = None, yield_form = "auto", quantum_yield = None, concentration = None, guard = None, solver = "lbfgs", start = "closed-form", max_iterations = 500, tolerance = 1e-5, colour_weight = 0.01, noise_aware_bound = false, band_axis = "both", format = None, rows = None, zero_is_missing = None, per_nm = None, units = None, blank = None, absorbance = None, keep_scatter = None, scatter_width = None, bandwidth = None, raman_shift = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit_many<'py>(
    py: Python<'py>,
    items: &Bound<'py, PyAny>,
    threads: Option<usize>,
    errors: &str,
    lights: Option<Bound<'py, PyAny>>,
    model: Option<String>,
    max_delta_e: Option<f64>,
    yield_form: &str,
    quantum_yield: Option<f64>,
    concentration: Option<f64>,
    guard: Option<f64>,
    solver: &str,
    start: &str,
    max_iterations: u64,
    tolerance: f64,
    colour_weight: f64,
    noise_aware_bound: bool,
    band_axis: &str,
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
) -> PyResult<Vec<Py<PyAny>>> {
    let return_errors = match errors {
        "raise" => false,
        "return" => true,
        other => {
            return Err(invalid(
                "errors",
                format!("\"{other}\" is not one of raise, return"),
            ));
        }
    };
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
    let args = FitArgs {
        lights,
        model,
        max_delta_e,
        yield_form,
        quantum_yield,
        concentration,
        guard,
        solver,
        start,
        max_iterations,
        tolerance,
        colour_weight,
        noise_aware_bound,
        band_axis,
    };
    let options = args.options()?;
    let input = read.options()?;
    let given = read.first_given();
    let list = crate::convert::items(items, "items")?
        .iter()
        .map(|v| item(v, given))
        .collect::<PyResult<Vec<_>>>()?;
    let count = list.len();
    // Each input is read (or taken as given), then all are fitted on the pool.
    let (inputs, outcomes) = detached(py, "fit_many", || {
        let inputs: Vec<fluorite::Result<Prepared>> = list
            .into_iter()
            .enumerate()
            .map(|(i, it)| prepared(it, i, count, &input))
            .collect();
        let ready: Vec<Prepared> = inputs
            .iter()
            .filter_map(|p| p.as_ref().ok())
            .cloned()
            .collect();
        let outcomes = fit_all(&ready, &options, threads)?;
        Ok((inputs, outcomes))
    })?;
    let mut outcomes = outcomes.into_iter();
    let mut out = Vec::with_capacity(count);
    for (i, input) in inputs.into_iter().enumerate() {
        let result = input.and_then(|prepared| {
            let outcome = outcomes.next().ok_or_else(|| {
                fluorite::Error::invalid("fit_many", "the pool returned fewer results than inputs")
            })??;
            Ok(PyFit {
                outcome,
                measurement: prepared,
            })
        });
        match result {
            Ok(fit) => out.push(Py::new(py, fit)?.into_any()),
            Err(e) if return_errors => out.push(error(e).into_value(py).into_any()),
            Err(e) => {
                return Err(FluoriteError::new_err(format!(
                    "item {i}: {}",
                    e.to_string().replace('\n', " ")
                )));
            }
        }
    }
    Ok(out)
}

/// For `benchmarks/overhead.py`: the wall time of `runs` default fits of `measurement`
/// timed inside Rust around the whole library call (`pipeline::fit_prepared`, GIL
/// released, no Python in between), in seconds: the Rust fit the Python call is
/// compared with.
#[pyfunction]
pub fn _fit_seconds(
    py: Python<'_>,
    measurement: &Bound<'_, PyMeasurement>,
    runs: usize,
) -> PyResult<Vec<f64>> {
    let prepared = measurement.get().prepared.clone();
    let options = FitOptions {
        lights: crate::lights::standard(),
        ..FitOptions::default()
    };
    detached(py, "_fit_seconds", || {
        (0..runs)
            .map(|_| {
                let started = std::time::Instant::now();
                fit_prepared(&prepared, &options)?;
                Ok(started.elapsed().as_secs_f64())
            })
            .collect()
    })
}

//! `fluorite.read` and `fluorite.Measurement`: reradiation matrices as numpy arrays.

use std::path::PathBuf;

use fluorite::eem::{Preprocessing, UnitsChoice};
use fluorite::formats::{Format, RowsAre};
use fluorite::{Measurement, Units};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{array1, array2, choice, floats, floats2, paths, to_py};
use crate::{attached, detached, invalid};
use fluorite::pipeline::{EemSettings, InputOptions, Prepared, read_input};

/// A bispectral reradiation (Donaldson) matrix on its own grids.
///
/// ``values`` has shape ``(n_excitation, n_emission)``, float64: row ``i`` is
/// monochromatic excitation at ``excitation[i]`` nm, column ``j`` the radiance factor
/// observed at emission ``emission[j]`` nm (per emission bin, unless ``per_nm``). NaN
/// marks a missing (unmeasured or masked) cell. Whatever a file's orientation (a BFC-450
/// file's rows are emission), the arrays are excitation × emission.
///
/// Read one with ``fluorite.read(path)``, or build one from arrays:
/// ``Measurement(excitation, emission, values, name="sample")``. Building checks what
/// reading checks (grids strictly increasing in 100–100,000 nm, the shape, no infinite
/// cells, at least one measured cell) and prepares the matrix as reading does for the
/// given ``units`` (``"radiance-factor"``, the default, leaves a plausible matrix as it
/// is; ``"auto"``, ``"percent"`` or ``"arbitrary"`` decide the units and clean an
/// uncalibrated EEM: zeros missing, Rayleigh and Raman scatter masked unless
/// ``keep_scatter``).
#[pyclass(module = "fluorite", name = "Measurement", frozen)]
#[derive(Clone)]
pub struct PyMeasurement {
    pub(crate) prepared: Prepared,
}

impl PyMeasurement {
    pub(crate) fn measurement(&self) -> &Measurement {
        &self.prepared.measurement
    }
}

#[pymethods]
impl PyMeasurement {
    /// A matrix from arrays: ``excitation`` (n_ex,) and ``emission`` (n_em,) in nm,
    /// ``values`` of shape (n_ex, n_em), NaN for missing cells.
    #[new]
    #[pyo3(signature = (excitation, emission, values, *, name = "measurement", per_nm = false, units = "radiance-factor", keep_scatter = false))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        excitation: &Bound<'_, PyAny>,
        emission: &Bound<'_, PyAny>,
        values: &Bound<'_, PyAny>,
        name: &str,
        per_nm: bool,
        units: &str,
        keep_scatter: bool,
    ) -> PyResult<Self> {
        let excitation = floats(excitation, "excitation")?;
        let emission = floats(emission, "emission")?;
        let (rows, columns, values) = floats2(values, "values")?;
        if (rows, columns) != (excitation.len(), emission.len()) {
            return Err(invalid(
                &format!("{name}: values"),
                format!(
                    "has shape ({rows}, {columns}), expected (n_excitation, n_emission) = ({}, {}); rows are excitation wavelengths, columns emission (transpose a matrix whose rows are emission)",
                    excitation.len(),
                    emission.len()
                ),
            ));
        }
        let units_choice: UnitsChoice = choice(units, "units")?;
        let name = name.to_string();
        let prepared = detached(py, "Measurement", move || {
            let m = Measurement::new(
                name,
                excitation,
                emission,
                values,
                if per_nm { Units::PerNm } else { Units::PerBin },
            )?;
            let input = InputOptions {
                eem: EemSettings {
                    units: units_choice,
                    keep_scatter,
                    ..EemSettings::default()
                },
                ..InputOptions::default()
            };
            Prepared::from_measurement(m, &input)
        })?;
        Ok(PyMeasurement { prepared })
    }

    /// Excitation wavelengths in nm, strictly increasing (float64, shape (n_excitation,)).
    #[getter]
    fn excitation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.measurement().excitation_nm)
    }

    /// Emission wavelengths in nm, strictly increasing (float64, shape (n_emission,)).
    #[getter]
    fn emission<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.measurement().emission_nm)
    }

    /// The matrix, float64 of shape (n_excitation, n_emission); NaN = missing cell. A
    /// copy: changing it does not change the measurement.
    #[getter]
    fn values<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let m = self.measurement();
        array2(py, m.n_excitation(), m.n_emission(), m.values.clone())
    }

    /// (n_excitation, n_emission).
    #[getter]
    fn shape(&self) -> (usize, usize) {
        (
            self.measurement().n_excitation(),
            self.measurement().n_emission(),
        )
    }

    /// A short name: the file stem, or the name given.
    #[getter]
    fn name(&self) -> String {
        self.measurement().name.clone()
    }

    /// The file it was read from, or None.
    #[getter]
    fn source(&self) -> Option<String> {
        self.measurement()
            .source
            .as_ref()
            .map(|p| p.display().to_string())
    }

    /// SHA-256 of the file's bytes (hex), or None.
    #[getter]
    fn sha256(&self) -> Option<String> {
        self.measurement().source_sha256.clone()
    }

    /// ``"surface"`` (radiance factors with a reflectance diagonal) or
    /// ``"instrument-eem"`` (an uncalibrated solution EEM, prepared: its fit gives shapes
    /// and a scale).
    #[getter]
    fn kind(&self) -> &'static str {
        if self.prepared.preprocessing.is_some() {
            "instrument-eem"
        } else {
            "surface"
        }
    }

    /// True when values are densities per nm of emission, False for radiance factors per
    /// emission bin (a BFC-450's).
    #[getter]
    fn per_nm(&self) -> bool {
        self.measurement().units == Units::PerNm
    }

    /// True when the data carry a reflectance diagonal (surfaces; not solution EEMs).
    #[getter]
    fn has_diagonal(&self) -> bool {
        self.measurement().has_diagonal
    }

    /// True when the values are on an arbitrary scale (instrument counts).
    #[getter]
    fn arbitrary_scale(&self) -> bool {
        self.measurement().arbitrary_scale
    }

    /// What was done to an instrument EEM before fitting (units, zeros, blank, inner
    /// filter, scatter bands) as a dictionary, the fit report's ``preprocessing`` block;
    /// None for a radiance-factor matrix.
    #[getter]
    fn preprocessing<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.prepared
            .preprocessing
            .as_ref()
            .map(|p| to_py(py, p))
            .transpose()
    }

    /// What the reader and the preparation decided that you should know, one line each.
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.measurement().notes.clone()
    }

    fn __repr__(&self) -> String {
        let m = self.measurement();
        let range = |g: &[f64]| {
            format!(
                "{}–{} nm",
                g.first().copied().unwrap_or(f64::NAN),
                g.last().copied().unwrap_or(f64::NAN)
            )
        };
        format!(
            "Measurement({:?}, {}, {} excitation × {} emission, excitation {}, emission {}, {} missing cells)",
            m.name,
            self.kind(),
            m.n_excitation(),
            m.n_emission(),
            range(&m.excitation_nm),
            range(&m.emission_nm),
            m.values.iter().filter(|v| v.is_nan()).count()
        )
    }

    /// Pickling (process pools): the whole state, rebuilt without re-validation.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = self.measurement();
        let preprocessing = self
            .prepared
            .preprocessing
            .as_ref()
            .map(|p| serde_json::to_string(p).map_err(|e| invalid("preprocessing", e)))
            .transpose()?;
        let state = (
            m.name.clone(),
            self.source(),
            m.source_sha256.clone(),
            m.excitation_nm.clone(),
            m.emission_nm.clone(),
            m.values.clone(),
            self.per_nm(),
            m.has_diagonal,
            m.arbitrary_scale,
            m.notes.clone(),
            preprocessing,
        );
        let rebuild = py.get_type::<PyMeasurement>().getattr("_from_state")?;
        (rebuild, (state,)).into_pyobject(py).map(|t| t.into_any())
    }

    /// Rebuilds a pickled measurement (see ``__reduce__``).
    #[staticmethod]
    #[allow(clippy::type_complexity)]
    fn _from_state(
        state: (
            String,
            Option<String>,
            Option<String>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            bool,
            bool,
            bool,
            Vec<String>,
            Option<String>,
        ),
    ) -> PyResult<Self> {
        let (name, source, sha, ex, em, values, per_nm, diagonal, arbitrary, notes, pre) = state;
        let preprocessing = pre
            .map(|text| {
                serde_json::from_str::<Preprocessing>(&text)
                    .map_err(|e| invalid("preprocessing", e))
            })
            .transpose()?;
        let measurement = Measurement {
            name,
            source: source.map(PathBuf::from),
            source_sha256: sha,
            excitation_nm: ex,
            emission_nm: em,
            values,
            units: if per_nm { Units::PerNm } else { Units::PerBin },
            has_diagonal: diagonal,
            arbitrary_scale: arbitrary,
            notes,
        };
        attached("Measurement", || measurement.validate())?;
        Ok(PyMeasurement {
            prepared: Prepared {
                measurement,
                preprocessing,
            },
        })
    }
}

/// The reading options of `read` and `fit` (the flags of `fluorite fit` that say how to
/// read and prepare a file). `None`: the command line's default.
#[derive(Default)]
pub(crate) struct ReadArgs<'py> {
    pub format: Option<String>,
    pub rows: Option<String>,
    pub zero_is_missing: Option<bool>,
    pub per_nm: Option<bool>,
    pub units: Option<String>,
    pub blank: Option<Bound<'py, PyAny>>,
    pub absorbance: Option<Bound<'py, PyAny>>,
    pub keep_scatter: Option<bool>,
    pub scatter_width: Option<Bound<'py, PyAny>>,
    pub bandwidth: Option<f64>,
    pub raman_shift: Option<f64>,
}

impl ReadArgs<'_> {
    /// The first option given (not None), by its keyword.
    pub fn first_given(&self) -> Option<&'static str> {
        [
            ("format", self.format.is_some()),
            ("rows", self.rows.is_some()),
            ("zero_is_missing", self.zero_is_missing.is_some()),
            ("per_nm", self.per_nm.is_some()),
            ("units", self.units.is_some()),
            ("blank", self.blank.as_ref().is_some_and(|b| !b.is_none())),
            (
                "absorbance",
                self.absorbance.as_ref().is_some_and(|a| !a.is_none()),
            ),
            ("keep_scatter", self.keep_scatter.is_some()),
            (
                "scatter_width",
                self.scatter_width.as_ref().is_some_and(|s| !s.is_none()),
            ),
            ("bandwidth", self.bandwidth.is_some()),
            ("raman_shift", self.raman_shift.is_some()),
        ]
        .into_iter()
        .find(|(_, given)| *given)
        .map(|(name, _)| name)
    }

    /// The library's input options.
    pub fn options(&self) -> PyResult<InputOptions> {
        let mut options = InputOptions::default();
        options.read.format = self
            .format
            .as_deref()
            .map(|f| choice::<Format>(f, "format"))
            .transpose()?;
        options.read.rows = self
            .rows
            .as_deref()
            .map(|r| choice::<RowsAre>(r, "rows"))
            .transpose()?;
        options.read.zero_is_missing = self.zero_is_missing;
        options.read.per_nm = self.per_nm.unwrap_or(false);
        if let Some(units) = &self.units {
            options.eem.units = choice::<UnitsChoice>(units, "units")?;
        }
        options.eem.blank = paths(self.blank.as_ref(), "blank")?;
        options.eem.absorbance = paths(self.absorbance.as_ref(), "absorbance")?;
        options.eem.keep_scatter = self.keep_scatter.unwrap_or(false);
        if let Some(widths) = self.scatter_width.as_ref().filter(|w| !w.is_none()) {
            let widths = widths.cast::<PyDict>().map_err(|_| {
                invalid(
                    "scatter_width",
                    "expected a dict of line → half-width in nm, e.g. {\"rayleigh1\": 12, \"raman1\": 8} (lines rayleigh1, raman1, rayleigh2, raman2 or all)",
                )
            })?;
            for (line, nm) in widths.iter() {
                let line: String = line
                    .extract()
                    .map_err(|_| invalid("scatter_width", "its keys are line names"))?;
                let nm: f64 = nm.extract().map_err(|_| {
                    invalid(
                        "scatter_width",
                        format!("{line}: the half-width must be a number of nm"),
                    )
                })?;
                attached("scatter_width", || options.eem.set_scatter_width(&line, nm))?;
            }
        }
        options.eem.bandwidth_nm = self.bandwidth;
        if let Some(shift) = self.raman_shift {
            options.eem.raman_shift_cm = shift;
        }
        Ok(options)
    }
}

/// Reads and prepares `path` (file `index` of `count` for per-input blank and absorbance
/// files) without the GIL.
pub(crate) fn read_prepared(
    py: Python<'_>,
    path: PathBuf,
    index: usize,
    count: usize,
    options: &InputOptions,
) -> PyResult<Prepared> {
    detached(py, "read", || read_input(&path, index, count, options))
}

// `read`'s signature spells water's Raman shift as a literal, for `help()`.
const _: () = assert!(fluorite::eem::scatter::WATER_RAMAN_SHIFT_CM == 3400.0);

/// Reads a reradiation matrix from a file: wide CSV, long CSV, BFC-450, WebFluor,
/// bispectral OpenEXR or a raw instrument EEM, told from the content unless ``format``
/// names it (``"wide"``, ``"long"``, ``"bfc"``, ``"webfluor"``, ``"exr"``).
///
/// The options are those of ``fluorite fit``: ``rows`` (``"excitation"`` or
/// ``"emission"``: what the rows of a wide matrix are; default the corner label, else
/// inferred), ``zero_is_missing`` (default: on for WebFluor), ``per_nm`` (values are
/// densities per nm), ``units`` (``"auto"``, ``"radiance-factor"``, ``"percent"``,
/// ``"arbitrary"``), and for instrument EEMs ``blank`` and ``absorbance`` (paths),
/// ``keep_scatter``, ``scatter_width`` (dict line → half-width nm, lines ``rayleigh1``,
/// ``raman1``, ``rayleigh2``, ``raman2`` or ``all``), ``bandwidth`` (nm) and
/// ``raman_shift`` (cm⁻¹, water's 3400 by default).
///
/// Returns a ``Measurement`` whose ``values`` are (n_excitation, n_emission), NaN for
/// missing cells. A malformed file raises ``FluoriteError`` with the command line's
/// message (file, line and column).
#[pyfunction]
#[pyo3(signature = (path, *, format = None, rows = None, zero_is_missing = None, per_nm = false, units = "auto", blank = None, absorbance = None, keep_scatter = false, scatter_width = None, bandwidth = None, raman_shift = 3400.0))]
#[allow(clippy::too_many_arguments)]
pub fn read<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
    format: Option<String>,
    rows: Option<String>,
    zero_is_missing: Option<bool>,
    per_nm: bool,
    units: &str,
    blank: Option<Bound<'py, PyAny>>,
    absorbance: Option<Bound<'py, PyAny>>,
    keep_scatter: bool,
    scatter_width: Option<Bound<'py, PyAny>>,
    bandwidth: Option<f64>,
    raman_shift: f64,
) -> PyResult<PyMeasurement> {
    let args = ReadArgs {
        format,
        rows,
        zero_is_missing,
        per_nm: Some(per_nm),
        units: Some(units.to_string()),
        blank,
        absorbance,
        keep_scatter: Some(keep_scatter),
        scatter_width,
        bandwidth,
        raman_shift: Some(raman_shift),
    };
    let options = args.options()?;
    let path = crate::convert::path(path, "path")?;
    let prepared = read_prepared(py, path, 0, 1, &options)?;
    Ok(PyMeasurement { prepared })
}

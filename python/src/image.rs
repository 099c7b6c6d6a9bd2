//! `fluorite.fit_image`, `fluorite.write_image`, `fluorite.ImageFit` and
//! `fluorite.MaterialMap`: bispectral images (a numpy array or a spectral OpenEXR) fitted
//! into material maps.
//!
//! A numpy image has shape (height, width, excitation, emission), like a stack of
//! measurements' `values`. The library keeps a pixel as one vector of the cells its
//! [`Layout`] holds, in canonical order (the diagonal cells by wavelength, then the
//! reradiation cells λi → λo > λi excitation-major); [`cell_indices`] maps each of those
//! cells to its (excitation, emission) position in the array, and every other cell (λo <
//! λi, or λo = λi where the grids do not both hold λ) is not read.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use fluorite::image::fit::{ImageFit, ImageFitOptions, MAX_COMPONENTS, YieldPreference};
use fluorite::image::map::LoadedTextures;
use fluorite::image::sink::{ImageSpec, Rect, write_image as write_exr};
use fluorite::image::{ArrayImage, Cell, ExrImage, Layout, MaterialMap, PixelSource};
use numpy::ndarray::{Array3, ArrayViewD};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray1, PyArray3, PyArrayDescrMethods, PyArrayDyn,
    PyArrayLikeDyn, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{array1, floats, is_path, to_py, type_name};
use crate::material::{PyFluorophore, PyMaterial};
use crate::{attached, detached, invalid};

/// Name of an image given as an array (the material map's `name`).
pub(crate) const ARRAY_NAME: &str = "image";

/// A wavelength grid of an array image: finite, strictly increasing, in fluorite's range,
/// as long as the array's axis.
pub(crate) fn grid(
    value: Option<&Bound<'_, PyAny>>,
    what: &str,
    axis: usize,
    length: usize,
) -> PyResult<Vec<f64>> {
    let axis_name = if axis == 2 { "excitation" } else { "emission" };
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Err(invalid(
            what,
            format!(
                "is required with an array image: the {axis_name} wavelengths (nm) of axis {axis}"
            ),
        ));
    };
    let grid = floats(value, what)?;
    if grid.len() != length {
        return Err(invalid(
            what,
            format!(
                "{} wavelength(s), but the image's {axis_name} axis (axis {axis} of shape (height, width, excitation, emission)) has {length}",
                grid.len()
            ),
        ));
    }
    if let Some(bad) = grid.iter().find(|v| !v.is_finite()) {
        return Err(invalid(
            what,
            format!("holds {bad}: give wavelengths in nm"),
        ));
    }
    if let Some(w) = grid.windows(2).find(|w| w[1] <= w[0]) {
        return Err(invalid(
            what,
            format!("must increase strictly ({} nm follows {} nm)", w[1], w[0]),
        ));
    }
    for &nm in [grid.first(), grid.last()].into_iter().flatten() {
        fluorite::limits::check_wavelength(nm).map_err(|message| invalid(what, message))?;
    }
    Ok(grid)
}

/// For each cell of `layout` in canonical order, its (excitation, emission) indices into
/// the grids the layout was made from.
pub(crate) fn cell_indices(
    layout: &Layout,
    ex: &[f64],
    em: &[f64],
) -> PyResult<Vec<(usize, usize)>> {
    let find = |grid: &[f64], nm: f64, what: &str| {
        fluorite::spectrum::find_wavelength(grid, nm).ok_or_else(|| {
            invalid(
                what,
                format!("{nm} nm is not on the grid (wavelengths closer than 1e-6 nm?)"),
            )
        })
    };
    layout
        .cells
        .iter()
        .map(|&c| {
            let (i, o) = match c {
                Cell::Diagonal(i) => (i, i),
                Cell::Reradiation(i, o) => (i, o),
            };
            Ok((
                find(ex, layout.wavelengths[i], "excitation_nm")?,
                find(em, layout.wavelengths[o], "emission_nm")?,
            ))
        })
        .collect()
}

/// The pixels of a 4-D array in the layout's canonical order, pixel-major (row by row).
pub(crate) fn gather<T: Copy + Into<f64>>(
    view: ArrayViewD<'_, T>,
    cells: &[(usize, usize)],
) -> Vec<f32> {
    let shape = view.shape().to_vec();
    let (h, w, ni, no) = (shape[0], shape[1], shape[2], shape[3]);
    let standard = view.as_standard_layout();
    let values = standard.as_slice().unwrap_or(&[]);
    let mut out = Vec::with_capacity(h * w * cells.len());
    for p in 0..h * w {
        let base = p * ni * no;
        out.extend(
            cells
                .iter()
                .map(|&(i, o)| values[base + i * no + o].into() as f32),
        );
    }
    out
}

/// A shape as Python writes it: `(20, 24, 25, 21)`, `(5,)`.
fn shape_text(shape: &[usize]) -> String {
    let parts: Vec<String> = shape.iter().map(|n| n.to_string()).collect();
    match parts.as_slice() {
        [one] => format!("({one},)"),
        _ => format!("({})", parts.join(", ")),
    }
}

/// The shape of a numpy image, checked: (height, width, excitation, emission).
pub(crate) fn shape4(shape: &[usize]) -> PyResult<[usize; 4]> {
    let text = shape_text(shape);
    let &[h, w, ni, no] = shape else {
        return Err(invalid(
            "source",
            format!(
                "expected an array of shape (height, width, excitation, emission), got {} dimension(s), shape {text}",
                shape.len()
            ),
        ));
    };
    if h * w < 2 {
        return Err(invalid(
            "source",
            format!(
                "{} pixel(s) (shape {text}): an image fit shares its fluorophores across pixels; fit a single matrix with fluorite.fit(fluorite.Measurement(excitation_nm, emission_nm, source[0, 0])) instead",
                h * w
            ),
        ));
    }
    if ni == 0 || no == 0 {
        return Err(invalid(
            "source",
            format!("shape {text} holds no cell (an empty excitation or emission axis)"),
        ));
    }
    Ok([h, w, ni, no])
}

/// A numpy image (float32, float64 or anything numpy casts to float32) with its grids as
/// an `ArrayImage`: the cells its layout holds, in canonical order.
fn array_image(
    source: &Bound<'_, PyAny>,
    excitation_nm: Option<&Bound<'_, PyAny>>,
    emission_nm: Option<&Bound<'_, PyAny>>,
) -> PyResult<ArrayImage> {
    let not_an_array = || {
        invalid(
            "source",
            format!(
                "expected a path (str or os.PathLike) to a bispectral OpenEXR or a numpy array of shape (height, width, excitation, emission), got {}",
                type_name(source)
            ),
        )
    };
    let source = &crate::convert::aligned(source)?;
    // One of the three views, kept alive while the values are gathered.
    let borrowed = |_| {
        invalid(
            "source",
            "the array is being written elsewhere (borrowed mutably)",
        )
    };
    let as_f32 = match source.cast::<PyArrayDyn<f32>>() {
        Ok(a) => Some(a.try_readonly().map_err(borrowed)?),
        Err(_) => None,
    };
    let as_f64 = match source.cast::<PyArrayDyn<f64>>() {
        Ok(a) => Some(a.try_readonly().map_err(borrowed)?),
        Err(_) => None,
    };
    let cast = if as_f32.is_none() && as_f64.is_none() {
        // Other numpy arrays are cast to float32 when they hold real numbers.
        if let Ok(array) = source.cast::<PyUntypedArray>() {
            let dtype = array.dtype();
            if !matches!(dtype.kind(), b'b' | b'i' | b'u' | b'f') {
                return Err(invalid(
                    "source",
                    format!("an array of dtype {dtype}: give real numbers (float32 or float64)"),
                ));
            }
        }
        Some(
            source
                .extract::<PyArrayLikeDyn<'_, f32, AllowTypeChange>>()
                .map_err(|_| not_an_array())?,
        )
    } else {
        None
    };
    let shape: Vec<usize> = match (&as_f32, &as_f64, &cast) {
        (Some(a), _, _) => a.shape().to_vec(),
        (_, Some(a), _) => a.shape().to_vec(),
        (_, _, Some(a)) => a.shape().to_vec(),
        _ => return Err(not_an_array()),
    };
    let [h, w, ni, no] = shape4(&shape)?;
    let ex = grid(excitation_nm, "excitation_nm", 2, ni)?;
    let em = grid(emission_nm, "emission_nm", 3, no)?;
    if !ex.iter().any(|&i| em.iter().any(|&o| o > i)) {
        return Err(invalid(
            "emission_nm",
            "no emission wavelength is above an excitation wavelength: the image holds no fluorescence (λi → λo > λi) to fit",
        ));
    }
    let layout = attached("fit_image", || Layout::from_grids(&ex, &em))?;
    let cells = cell_indices(&layout, &ex, &em)?;
    let values = match (as_f32, as_f64, cast) {
        (Some(a), _, _) => gather(a.as_array(), &cells),
        (_, Some(a), _) => gather(a.as_array(), &cells),
        (_, _, Some(a)) => gather(a.as_array(), &cells),
        _ => return Err(not_an_array()),
    };
    attached("fit_image", || {
        ArrayImage::new(ARRAY_NAME, w, h, layout, values)
    })
}

/// What `fit_image` reads.
enum Source {
    Exr(PathBuf),
    Array(Box<ArrayImage>),
}

fn source_of(
    value: &Bound<'_, PyAny>,
    excitation_nm: Option<&Bound<'_, PyAny>>,
    emission_nm: Option<&Bound<'_, PyAny>>,
) -> PyResult<Source> {
    if is_path(value) {
        for (given, name) in [
            (excitation_nm, "excitation_nm"),
            (emission_nm, "emission_nm"),
        ] {
            if given.is_some_and(|g| !g.is_none()) {
                return Err(invalid(
                    name,
                    "is for an array image only: a bispectral OpenEXR names its wavelengths in its channels",
                ));
            }
        }
        return Ok(Source::Exr(crate::convert::path(value, "source")?));
    }
    array_image(value, excitation_nm, emission_nm).map(|a| Source::Array(Box::new(a)))
}

/// A count option as the library's validation words it when out of range.
fn count(value: i64, flag: &str) -> PyResult<usize> {
    usize::try_from(value)
        .ok()
        .filter(|v| (1..=MAX_COMPONENTS).contains(v))
        .ok_or_else(|| invalid(flag, format!("{value}: give 1 to {MAX_COMPONENTS}")))
}

/// The result of an image fit: the material map and how each number of fluorophores did.
///
/// ``components`` is K, the number of fluorophores chosen (or asked for); ``trials`` one
/// dict per K tried, in order: ``components``, ``share_within`` (the share of unmasked
/// pixels within the bound under every light), ``median_delta_e``, ``p99_delta_e`` and
/// ``max_delta_e`` (ΔE2000 of fitted against measured, light name → value),
/// ``residual_share``, ``iterations``, ``converged``. ``masked_pixels`` counts the pixels
/// left out for non-finite cells (NaN in every map), ``notes`` says what the fit decided
/// and what to know, ``files`` lists every file written, ``map`` is the material map
/// (``map_path`` its JSON).
#[pyclass(module = "fluorite", name = "ImageFit", frozen)]
pub struct PyImageFit {
    fit: ImageFit,
    lights: Vec<String>,
    notes: Vec<String>,
    map: Py<PyMaterialMap>,
}

impl PyImageFit {
    /// The library's outcome.
    pub(crate) fn outcome(&self) -> &ImageFit {
        &self.fit
    }

    /// The result of `fit` with its options and notes (the input's first).
    pub(crate) fn new(
        py: Python<'_>,
        fit: ImageFit,
        options: &ImageFitOptions,
        notes: Vec<String>,
    ) -> PyResult<Self> {
        let map = PyMaterialMap::open(py, fit.map_path.clone())?;
        Ok(PyImageFit {
            lights: options.lights.iter().map(|l| l.name.clone()).collect(),
            notes,
            map: Py::new(py, map)?,
            fit,
        })
    }
}

#[pymethods]
impl PyImageFit {
    /// K: the number of shared fluorophores of the map.
    #[getter]
    fn components(&self) -> usize {
        self.fit.components
    }

    /// Each K tried, in order, as dicts (ΔE2000 per light name).
    #[getter]
    fn trials<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let per_light = |values: &[f64]| -> PyResult<Bound<'py, PyDict>> {
            let d = PyDict::new(py);
            for (l, v) in self.lights.iter().zip(values) {
                d.set_item(l, v)?;
            }
            Ok(d)
        };
        self.fit
            .trials
            .iter()
            .map(|t| {
                let d = PyDict::new(py);
                d.set_item("components", t.components)?;
                d.set_item("share_within", t.share_within)?;
                d.set_item("median_delta_e", per_light(&t.median_delta_e)?)?;
                d.set_item("p99_delta_e", per_light(&t.p99_delta_e)?)?;
                d.set_item("max_delta_e", per_light(&t.max_delta_e)?)?;
                d.set_item("residual_share", t.residual_share)?;
                d.set_item("iterations", t.iterations)?;
                d.set_item("converged", t.converged)?;
                Ok(d)
            })
            .collect()
    }

    /// Pixels left out of the fit for non-finite cells (NaN in every map).
    #[getter]
    fn masked_pixels(&self) -> usize {
        self.fit.masked_pixels
    }

    /// Non-finite cells of the masked pixels.
    #[getter]
    fn non_finite_cells(&self) -> usize {
        self.fit.non_finite_cells
    }

    /// Pixels whose material needed clamping to conserve energy.
    #[getter]
    fn clamped_pixels(&self) -> usize {
        self.fit.clamped_pixels
    }

    /// What the fit decided and what to know, one sentence each (the input's notes first).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.notes.clone()
    }

    /// Every file written, as paths (str).
    #[getter]
    fn files(&self) -> Vec<String> {
        self.fit
            .files
            .iter()
            .map(|p| p.display().to_string())
            .collect()
    }

    /// The material map's JSON (``material-map.json`` in the output folder).
    #[getter]
    fn map_path(&self) -> String {
        self.fit.map_path.display().to_string()
    }

    /// The material map written.
    #[getter]
    fn map(&self, py: Python<'_>) -> Py<PyMaterialMap> {
        self.map.clone_ref(py)
    }

    /// The lights of the bound, by name (the keys of the trials' ΔE2000 dicts).
    #[getter]
    fn lights(&self) -> Vec<String> {
        self.lights.clone()
    }

    /// Stages an earlier run into the same folder had finished (resumed, not redone).
    #[getter]
    fn resumed(&self) -> Vec<String> {
        self.fit.resumed.clone()
    }

    fn __repr__(&self) -> String {
        let share = self
            .fit
            .trials
            .iter()
            .find(|t| t.components == self.fit.components)
            .map_or(f64::NAN, |t| t.share_within);
        format!(
            "ImageFit(K={}, {:.1} % of pixels within the bound, {} masked, {} trial(s), {:?})",
            self.fit.components,
            100.0 * share,
            self.fit.masked_pixels,
            self.fit.trials.len(),
            self.fit.map_path.display().to_string()
        )
    }
}

/// A material map (``fluorite-material-map/1``): K fluorophores shared by every pixel, a
/// concentration per fluorophore and pixel, a reflectance per pixel, as
/// ``fluorite.fit_image`` and ``fluorite fit-image`` write it (``material-map.json`` with
/// ``concentration.exr`` and ``reflectance.exr`` beside it).
///
/// ``fluorophores`` are ``fluorite.Fluorophore`` objects whose ``concentration`` is the
/// largest over the image (the per-pixel values are ``concentration()``); their yields
/// are the ones the fit's gauge chose for the whole image. The textures are read on first
/// use, whole.
#[pyclass(module = "fluorite", name = "MaterialMap", frozen)]
pub struct PyMaterialMap {
    map: MaterialMap,
    path: PathBuf,
    textures: OnceLock<LoadedTextures>,
}

impl PyMaterialMap {
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let map = detached(py, "MaterialMap.load", || MaterialMap::load(&path))?;
        Ok(PyMaterialMap {
            map,
            path,
            textures: OnceLock::new(),
        })
    }

    /// The textures, read on first use.
    fn textures(&self, py: Python<'_>) -> PyResult<&LoadedTextures> {
        if let Some(t) = self.textures.get() {
            return Ok(t);
        }
        let (map, path) = (&self.map, &self.path);
        let loaded = detached(py, "MaterialMap textures", || {
            let t = map.load_textures(path)?;
            if (t.width, t.height) != (map.width, map.height) {
                return Err(fluorite::Error::parse(
                    map.texture_paths(path).0,
                    0,
                    0,
                    format!(
                        "{}×{} pixels, while {} says {}×{}",
                        t.width,
                        t.height,
                        path.display(),
                        map.width,
                        map.height
                    ),
                ));
            }
            Ok(t)
        })?;
        let _ = self.textures.set(loaded);
        Ok(self.textures.get().expect("set just above"))
    }
}

#[pymethods]
impl PyMaterialMap {
    /// Reads a material map's JSON (``material-map.json``); its textures are read when
    /// first asked for.
    #[staticmethod]
    fn load(py: Python<'_>, path: &Bound<'_, PyAny>) -> PyResult<Self> {
        let path = crate::convert::path(path, "path")?;
        PyMaterialMap::open(py, path)
    }

    /// The JSON file read.
    #[getter]
    fn path(&self) -> String {
        self.path.display().to_string()
    }

    /// The map's name (the image's file stem, ``"image"`` for an array).
    #[getter]
    fn name(&self) -> String {
        self.map.name.clone()
    }

    /// Pixels per row.
    #[getter]
    fn width(&self) -> usize {
        self.map.width
    }

    /// Rows.
    #[getter]
    fn height(&self) -> usize {
        self.map.height
    }

    /// The K fluorophores every pixel shares; each one's ``concentration`` is its largest
    /// over the image.
    #[getter]
    fn fluorophores(&self) -> Vec<PyFluorophore> {
        self.map
            .fluorophores
            .iter()
            .map(|f| PyFluorophore {
                fluorophore: f.clone(),
            })
            .collect()
    }

    /// How the yields (hence the concentrations' scale) were chosen: a matrix fixes only
    /// c·Q.
    #[getter]
    fn gauge(&self) -> String {
        self.map.gauge.clone()
    }

    /// The ``fit`` block as a dict (the bound, the trials, masked and clamped pixels,
    /// notes), or None for a hand-written map.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.map.fit.as_ref().map(|f| to_py(py, f)).transpose()
    }

    /// The concentrations, float32 of shape (height, width, K): ``[y, x, k]`` is c_k at
    /// pixel (x, y), row 0 the image's top; NaN at masked pixels.
    fn concentration<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let t = self.textures(py)?;
        let k = self.map.fluorophores.len();
        Array3::from_shape_vec((t.height, t.width, k), t.concentration.clone())
            .map(|a| a.into_pyarray(py))
            .map_err(|e| invalid("concentration", e))
    }

    /// The reflectance: ``(wavelengths, values)``, wavelengths float64 (n,) in nm and
    /// values float32 of shape (height, width, n), ``[y, x, i]`` r at pixel (x, y) and
    /// wavelength i; NaN at masked pixels.
    #[allow(clippy::type_complexity)] // a pair of arrays, named in the doc
    fn reflectance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyArray1<f64>>, Bound<'py, PyArray3<f32>>)> {
        let t = self.textures(py)?;
        let n = t.wavelengths.len();
        let values = Array3::from_shape_vec((t.height, t.width, n), t.reflectance.clone())
            .map(|a| a.into_pyarray(py))
            .map_err(|e| invalid("reflectance", e))?;
        Ok((array1(py, &t.wavelengths), values))
    }

    /// The material of pixel (x, y) (column x, row y from the top): the shared
    /// fluorophores at that pixel's concentrations and its reflectance, a
    /// ``fluorite.Material`` like a single fit's. A masked pixel raises ``FluoriteError``.
    fn material_at(&self, py: Python<'_>, x: i64, y: i64) -> PyResult<PyMaterial> {
        let (w, h) = (self.map.width, self.map.height);
        let x = usize::try_from(x).ok().filter(|&x| x < w).ok_or_else(|| {
            invalid(
                "x",
                format!("{x} is outside 0 to {} (width {w})", w as i64 - 1),
            )
        })?;
        let y = usize::try_from(y).ok().filter(|&y| y < h).ok_or_else(|| {
            invalid(
                "y",
                format!("{y} is outside 0 to {} (height {h})", h as i64 - 1),
            )
        })?;
        let t = self.textures(py)?;
        let k = self.map.fluorophores.len();
        let n = t.wavelengths.len();
        let p = y * t.width + x;
        let material = attached("MaterialMap.material_at", || {
            let mut m = self.map.material_at(
                &t.concentration[p * k..(p + 1) * k],
                &t.wavelengths,
                &t.reflectance[p * n..(p + 1) * n],
            )?;
            m.name = format!("{} ({x}, {y})", self.map.name);
            Ok(m)
        })?;
        Ok(PyMaterial { material })
    }

    /// The map's JSON, as written.
    fn to_json(&self) -> String {
        self.map.to_json()
    }

    fn __repr__(&self) -> String {
        format!(
            "MaterialMap({:?}, {}×{} pixels, {} fluorophore{}, {:?})",
            self.map.name,
            self.map.width,
            self.map.height,
            self.map.fluorophores.len(),
            if self.map.fluorophores.len() == 1 {
                ""
            } else {
                "s"
            },
            self.path.display().to_string()
        )
    }

    /// Pickles as its path (the files stay where they are).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let load = py.get_type::<PyMaterialMap>().getattr("load")?;
        (load, (self.path.clone(),))
            .into_pyobject(py)
            .map(|t| t.into_any())
    }
}

/// Fits a bispectral image into a material map: K fluorophores shared by every pixel, a
/// concentration per fluorophore and pixel, a reflectance per pixel (``fluorite
/// fit-image``).
///
/// ``source`` is a path (str or os.PathLike) to a bispectral OpenEXR (the spectral
/// layout's ``T.<λ>nm`` and ``T.<λi>nm.<λo>nm`` channels), or a numpy array of shape
/// (height, width, excitation, emission), float32 or float64, with ``excitation_nm`` and
/// ``emission_nm`` (1-D, strictly increasing, nm): ``source[y, x, i, j]`` is the cell
/// excitation_nm[i] → emission_nm[j] of pixel (x, y), row 0 the top. The fit reads the
/// diagonal where both grids hold a wavelength and the cells with emission_nm[j] >
/// excitation_nm[i]; the others (λo < λi, the anti-Stokes side) are not read. A pixel
/// with a NaN (or infinite) cell is masked: left out, NaN in every map.
///
/// ``output`` is the folder written (created if missing; a run into a folder holding an
/// unfinished run of the same image and options resumes it): ``material-map.json``,
/// ``concentration.exr``, ``reflectance.exr``, ``fitted.exr``, ``delta-e.exr``,
/// ``delta-e-<light>.png``, ``under-<light>.png``.
///
/// ``components`` fixes K; by default K is the smallest (up to ``max_components``, at
/// most 6) whose fit is within ΔE2000 ``max_delta_e`` under every light of ``lights``
/// (default d65, a, f11, uv; any light form ``fit`` takes) on at least ``share`` of the
/// unmasked pixels. ``yield_form``: ``"auto"``, ``"energy"`` or ``"photon"``. ``zip``:
/// ZIP-compress the EXR outputs.
///
/// The GIL is released while it runs. Returns an ``ImageFit``; raises ``FluoriteError``
/// naming the argument at fault.
#[pyfunction]
#[pyo3(signature = (source, *, output, components = None, max_components = 4, max_delta_e = 1.0, share = 0.99, lights = None, yield_form = "auto", zip = false, excitation_nm = None, emission_nm = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit_image<'py>(
    py: Python<'py>,
    source: &Bound<'py, PyAny>,
    output: &Bound<'py, PyAny>,
    components: Option<i64>,
    max_components: i64,
    max_delta_e: f64,
    share: f64,
    lights: Option<Bound<'py, PyAny>>,
    yield_form: &str,
    zip: bool,
    excitation_nm: Option<Bound<'py, PyAny>>,
    emission_nm: Option<Bound<'py, PyAny>>,
) -> PyResult<PyImageFit> {
    let out = crate::convert::path(output, "output")?;
    let options = image_options(
        components,
        max_components,
        max_delta_e,
        share,
        lights.as_ref(),
        yield_form,
        zip,
    )?;
    let input = source_of(source, excitation_nm.as_ref(), emission_nm.as_ref())?;
    let (fit, notes) = detached(py, "fit_image", || match &input {
        Source::Exr(path) => {
            let image = ExrImage::open(path)?;
            let fit =
                fluorite::image::fit::fit_image(PixelSource::Exr(&image), &out, &options, &|_| {})?;
            let notes = image.notes.iter().chain(&fit.notes).cloned().collect();
            Ok((fit, notes))
        }
        Source::Array(image) => {
            let fit = fluorite::image::fit::fit_image(
                PixelSource::Array(image),
                &out,
                &options,
                &|_| {},
            )?;
            let notes = fit.notes.clone();
            Ok((fit, notes))
        }
    })?;
    PyImageFit::new(py, fit, &options, notes)
}

/// `fit_image`'s options as the library's, checked.
pub(crate) fn image_options(
    components: Option<i64>,
    max_components: i64,
    max_delta_e: f64,
    share: f64,
    lights: Option<&Bound<'_, PyAny>>,
    yield_form: &str,
    zip: bool,
) -> PyResult<ImageFitOptions> {
    let yield_preference = match yield_form.to_ascii_lowercase().as_str() {
        "auto" => YieldPreference::Auto,
        "energy" => YieldPreference::Energy,
        "photon" => YieldPreference::Photon,
        other => {
            return Err(invalid(
                "yield_form",
                format!("\"{other}\" is not one of auto, energy, photon"),
            ));
        }
    };
    let options = ImageFitOptions {
        components: components.map(|k| count(k, "--components")).transpose()?,
        max_components: count(max_components, "--max-components")?,
        max_delta_e,
        share,
        lights: match crate::lights::lights(lights)? {
            Some(lights) => lights,
            None => crate::lights::standard(),
        },
        yield_preference,
        zip,
        ..ImageFitOptions::default()
    };
    attached("fit_image", || options.validate())?;
    Ok(options)
}

/// Writes a numpy image as a bispectral OpenEXR (the spectral layout of Fichet, Mercier
/// and Wilkie: a channel ``T.<λ>nm`` per diagonal cell, ``T.<λi>nm.<λo>nm`` per
/// reradiation cell), the file ``fit_image`` and ``fluorite fit-image`` read.
///
/// ``source``, ``excitation_nm`` and ``emission_nm`` are as ``fit_image`` takes them: an
/// array of shape (height, width, excitation, emission) and its grids; the cells the
/// layout has no channel for (λo < λi) are not written. ``half``: 16-bit floats
/// (``fluorite synth --image --half``); ``zip``: lossless ZIP compression. The file is
/// written tile by tile beside ``path`` and renamed into place, GIL released. Returns the
/// path written.
#[pyfunction]
#[pyo3(signature = (path, source, *, excitation_nm, emission_nm, half = false, zip = false))]
pub fn write_image<'py>(
    py: Python<'py>,
    path: &Bound<'py, PyAny>,
    source: &Bound<'py, PyAny>,
    excitation_nm: &Bound<'py, PyAny>,
    emission_nm: &Bound<'py, PyAny>,
    half: bool,
    zip: bool,
) -> PyResult<String> {
    let target = crate::convert::path(path, "path")?;
    if is_path(source) {
        return Err(invalid(
            "source",
            "expected a numpy array of shape (height, width, excitation, emission), got a path",
        ));
    }
    let image = array_image(source, Some(excitation_nm), Some(emission_nm))?;
    detached(py, "write_image", || {
        write_array(&target, &image, half, zip)
    })?;
    Ok(target.display().to_string())
}

/// Writes `image` to `path` as a spectral OpenEXR.
fn write_array(path: &Path, image: &ArrayImage, half: bool, zip: bool) -> fluorite::Result<()> {
    use fluorite::formats::exr::{VERSION, VERSION_ATTRIBUTE};
    let cells = image.layout.len();
    let spec = ImageSpec {
        width: image.width,
        height: image.height,
        channels: image.layout.channel_names(),
        half,
        zip,
        attributes: vec![(VERSION_ATTRIBUTE.to_string(), VERSION.to_string())],
    };
    let produce = |rect: Rect| -> fluorite::Result<Vec<f32>> {
        let mut out = Vec::with_capacity(rect.width * rect.height * cells);
        for y in rect.y..rect.y + rect.height {
            let start = (y * image.width + rect.x) * cells;
            out.extend_from_slice(&image.values[start..start + rect.width * cells]);
        }
        Ok(out)
    };
    write_exr(path, &spec, produce, |_, _| {})
}

//! `fluorite._fluorite._ImageStages`: the stages of an image fit one at a time, for
//! `fluorite.dask` to run the passes over the image on a Dask cluster.
//!
//! Every kernel is the library's ([`fluorite::image::fit::stages`], the functions
//! `fit-image`'s own passes call on each block), run with the GIL released on one thread:
//! a pass over blocks `first..first + count` of a bispectral EXR (read by chunks, the
//! image's blocks) or over rows of an image in memory (bands of 16 rows, the blocks of
//! `fluorite.fit_image` on a numpy array) returns each block's contribution; the caller
//! sums them in block order, as the library's passes do. The fit on the compressed image
//! (the pixels' records) and the outputs run through
//! [`fluorite::image::fit::fit_image_from_records`], the code `fit_image` runs after its
//! passes.

use std::sync::{Arc, Mutex};

use fluorite::image::fit::band::{OutputJob, PngStyle, write_band};
use fluorite::image::fit::colour::CellColours;
use fluorite::image::fit::outputs::BandMapper;
use fluorite::image::fit::passes::{Census, orthonormal};
use fluorite::image::fit::records::{
    ChunkMapper, RECORD_CHUNK, RecordContext, RecordKernel, fold_exact,
};
use fluorite::image::fit::scratch::RecordLayout;
use fluorite::image::fit::shared::Shared;
use fluorite::image::fit::{ImageFitOptions, RecordSource, fit_image_from_records, stages};
use fluorite::image::source::ChunkIndex;
use fluorite::image::{ArrayImage, ExrImage, Layout, PixelSource};
use numpy::ndarray::{Array2, Array3};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray2, PyArray3, PyArrayLikeDyn, PyReadonlyArray2,
    PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

mod arrays;
mod mapper;

use arrays::{Blocks, basis_of, chunk_values, stack, unaligned};
use mapper::PythonMapper;

use crate::convert::is_path;
use crate::image::{PyImageFit, cell_indices, grid, image_options};
use crate::{detached, error, invalid};

/// What the passes read.
enum Input {
    /// A bispectral OpenEXR, with its blocks.
    Exr(Box<ExrImage>, Box<ChunkIndex>),
    /// An image whose pixels come as arrays (height, width, excitation, emission): its
    /// size and layout (no values), and each layout cell's (excitation, emission) index.
    Array(ArrayImage, Vec<(usize, usize)>, [usize; 2]),
}

/// The stages of one image fit (``fluorite.dask.fit_image`` makes one per process).
///
/// ``source`` is a bispectral OpenEXR path, or None for an image given as arrays: then
/// ``excitation_nm``, ``emission_nm`` and ``shape`` (height, width) describe it, and
/// each pass takes its rows as an array (rows, width, excitation, emission) starting at
/// a row that is a multiple of ``block_rows``. The other options are ``fit_image``'s.
#[pyclass(module = "fluorite._fluorite", name = "_ImageStages", frozen)]
pub struct PyImageStages {
    input: Input,
    options: ImageFitOptions,
    /// Diagonal cells (the reradiation cells follow them).
    first: usize,
    /// Reradiation cells.
    m: usize,
    record: RecordLayout,
    colours: CellColours,
}

impl PyImageStages {
    fn image(&self) -> PixelSource<'_> {
        match &self.input {
            Input::Exr(image, _) => PixelSource::Exr(image),
            Input::Array(image, _, _) => PixelSource::Array(image),
        }
    }

    /// The blocks of a pass: `first..first + count` of an EXR, or the bands of rows
    /// `pixels` holds from row `y` of an array image.
    fn blocks(
        &self,
        first: usize,
        count: usize,
        pixels: Option<&Bound<'_, PyAny>>,
        y: usize,
    ) -> PyResult<Blocks<'_>> {
        match (&self.input, pixels) {
            (Input::Exr(image, index), None) => {
                let end = first
                    .checked_add(count)
                    .filter(|&e| e <= index.places.len());
                let Some(end) = end else {
                    return Err(invalid(
                        "count",
                        format!(
                            "blocks {first}..{first}+{count} are outside the image's {} blocks",
                            index.places.len()
                        ),
                    ));
                };
                Ok(Blocks::Exr(image, index, first..end))
            }
            (Input::Array(image, cells, [ni, no]), Some(pixels)) => {
                if !y.is_multiple_of(stages::ROWS_PER_BLOCK) {
                    return Err(invalid(
                        "y",
                        format!(
                            "{y}: a chunk starts at a multiple of {} rows",
                            stages::ROWS_PER_BLOCK
                        ),
                    ));
                }
                let values = chunk_values(pixels, cells, image.width, *ni, *no)?;
                let rows = values.len() / (image.width * cells.len()).max(1);
                if y + rows > image.height {
                    return Err(invalid(
                        "pixels",
                        format!(
                            "rows {y}..{} are outside the image's {} rows",
                            y + rows,
                            image.height
                        ),
                    ));
                }
                let width = image.width;
                let cells = cells.len();
                Ok(Blocks::Array(values, y, width, cells))
            }
            (Input::Exr(..), Some(_)) => Err(invalid(
                "pixels",
                "the stages read a bispectral OpenEXR: give first and count, not pixels",
            )),
            (Input::Array(..), None) => Err(invalid(
                "pixels",
                "is required for an image given as arrays: its rows (rows, width, excitation, emission)",
            )),
        }
    }
}

/// The blocks of one call, read (EXR) or built (array) as the kernel runs.
#[pymethods]
impl PyImageStages {
    #[new]
    #[pyo3(signature = (source, *, components = None, max_components = 4, max_delta_e = 1.0, share = 0.99, lights = None, yield_form = "auto", zip = false, excitation_nm = None, emission_nm = None, shape = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        source: Option<&Bound<'_, PyAny>>,
        components: Option<i64>,
        max_components: i64,
        max_delta_e: f64,
        share: f64,
        lights: Option<Bound<'_, PyAny>>,
        yield_form: &str,
        zip: bool,
        excitation_nm: Option<Bound<'_, PyAny>>,
        emission_nm: Option<Bound<'_, PyAny>>,
        shape: Option<(usize, usize)>,
    ) -> PyResult<Self> {
        let options = image_options(
            components,
            max_components,
            max_delta_e,
            share,
            lights.as_ref(),
            yield_form,
            zip,
        )?;
        let input = match source.filter(|s| !s.is_none()) {
            Some(path) if is_path(path) => {
                let path = crate::convert::path(path, "source")?;
                let (image, index) = detached(py, "fluorite.dask", || {
                    let image = ExrImage::open(&path)?;
                    let index = image.chunk_index()?;
                    Ok((image, index))
                })?;
                Input::Exr(Box::new(image), Box::new(index))
            }
            Some(_) => {
                return Err(invalid(
                    "source",
                    "expected a bispectral OpenEXR path, or None with excitation_nm, emission_nm and shape",
                ));
            }
            None => {
                let Some((height, width)) = shape else {
                    return Err(invalid(
                        "shape",
                        "is required for an image given as arrays: (height, width)",
                    ));
                };
                let ex = floats_len(excitation_nm.as_ref(), "excitation_nm")?;
                let em = floats_len(emission_nm.as_ref(), "emission_nm")?;
                let ex = grid(excitation_nm.as_ref(), "excitation_nm", 2, ex)?;
                let em = grid(emission_nm.as_ref(), "emission_nm", 3, em)?;
                if !ex.iter().any(|&i| em.iter().any(|&o| o > i)) {
                    return Err(invalid(
                        "emission_nm",
                        "no emission wavelength is above an excitation wavelength: the image holds no fluorescence (λi → λo > λi) to fit",
                    ));
                }
                let layout = Layout::from_grids(&ex, &em).map_err(error)?;
                let cells = cell_indices(&layout, &ex, &em)?;
                if width * height < 2 {
                    return Err(invalid(
                        "shape",
                        format!(
                            "{} pixel(s): an image fit shares its fluorophores across pixels",
                            width * height
                        ),
                    ));
                }
                // The image's size, layout and name: its values come with each pass.
                let image = ArrayImage {
                    name: crate::image::ARRAY_NAME.to_string(),
                    width,
                    height,
                    layout,
                    values: Vec::new(),
                };
                Input::Array(image, cells, [ex.len(), em.len()])
            }
        };
        let layout = match &input {
            Input::Exr(image, _) => &image.layout,
            Input::Array(image, _, _) => &image.layout,
        };
        if layout.diagonal_count == 0 {
            return Err(invalid(
                "source",
                "the image holds reradiation cells only, no diagonal (T.<λ>nm): a material map needs each pixel's reflectance",
            ));
        }
        let first = layout.diagonal_count;
        let m = layout.len() - first;
        let record = RecordLayout {
            rank: options.rank.min(m),
            diagonal: first,
            lights: options.lights.len(),
        };
        let colours = CellColours::new(layout, &options.lights);
        Ok(PyImageStages {
            input,
            options,
            first,
            m,
            record,
            colours,
        })
    }

    /// Pixels per row.
    #[getter]
    fn width(&self) -> usize {
        self.image().width()
    }

    /// Rows.
    #[getter]
    fn height(&self) -> usize {
        self.image().height()
    }

    /// Cells per pixel (the layout's, canonical order).
    #[getter]
    fn cells(&self) -> usize {
        self.image().layout().len()
    }

    /// Reradiation cells per pixel (m: the rows of the sketch and the basis).
    #[getter]
    fn m(&self) -> usize {
        self.m
    }

    /// Columns of the sketch and the basis.
    #[getter]
    fn rank(&self) -> usize {
        self.record.rank
    }

    /// Power steps (each one more pass between the sketch and the projection).
    #[getter]
    fn power_steps(&self) -> usize {
        self.options.power_steps
    }

    /// The wavelengths (nm) of the diagonal cells: the reflectance's samples.
    #[getter]
    fn diagonal_nm(&self) -> Vec<f64> {
        let image = self.image();
        let layout = image.layout();
        layout.cells[..self.first]
            .iter()
            .map(|c| match *c {
                fluorite::image::Cell::Diagonal(w) => layout.wavelengths[w],
                fluorite::image::Cell::Reradiation(i, _) => layout.wavelengths[i],
            })
            .collect()
    }

    /// Each layout cell's (excitation, emission) index into the grids of an image given
    /// as arrays, in the layout's canonical order (None for an EXR): `a[:, :, ex, em]`
    /// with these indices is the (rows, width, cells) form of an array.
    #[getter]
    fn cell_grid(&self) -> Option<Vec<(usize, usize)>> {
        match &self.input {
            Input::Exr(..) => None,
            Input::Array(_, cells, _) => Some(cells.clone()),
        }
    }

    /// Floats per pixel record (the projection's output).
    #[getter]
    fn record_len(&self) -> usize {
        self.record.len()
    }

    /// Rows per block of an image given as arrays (None for an EXR: its blocks are the
    /// file's chunks).
    #[getter]
    fn block_rows(&self) -> Option<usize> {
        match self.input {
            Input::Exr(..) => None,
            Input::Array(..) => Some(stages::ROWS_PER_BLOCK),
        }
    }

    /// The blocks of a pass, in order, as (x, y, width, height) pixel rectangles.
    fn block_rects(&self) -> Vec<(usize, usize, usize, usize)> {
        match &self.input {
            Input::Exr(_, index) => index
                .places
                .iter()
                .map(|p| (p.x, p.y, p.width, p.height))
                .collect(),
            Input::Array(image, _, _) => (0..image.height)
                .step_by(stages::ROWS_PER_BLOCK)
                .map(|y| {
                    (
                        0,
                        y,
                        image.width,
                        stages::ROWS_PER_BLOCK.min(image.height - y),
                    )
                })
                .collect(),
        }
    }

    /// Pass 1 over some blocks: (contributions (blocks, m, rank) float32, masked pixels,
    /// non-finite cells). GIL released.
    #[pyo3(signature = (first = 0, count = 0, pixels = None, y = 0))]
    fn sketch<'py>(
        &self,
        py: Python<'py>,
        first: usize,
        count: usize,
        pixels: Option<&Bound<'py, PyAny>>,
        y: usize,
    ) -> PyResult<(Bound<'py, PyArray3<f32>>, usize, usize)> {
        let blocks = self.blocks(first, count, pixels, y)?;
        let (first_cell, rank, seed, width) = (
            self.first,
            self.record.rank,
            self.options.seed,
            self.image().width(),
        );
        let parts = detached(py, "fluorite.dask sketch", || {
            blocks.each(|b| Ok(stages::sketch_block(b, first_cell, rank, seed, width)))
        })?;
        let mut census = Census::default();
        let mut local = Vec::with_capacity(parts.len());
        for (part, c) in parts {
            census.masked_pixels += c.masked_pixels;
            census.non_finite_cells += c.non_finite_cells;
            local.push(part);
        }
        Ok((
            stack(py, local, self.m, rank)?,
            census.masked_pixels,
            census.non_finite_cells,
        ))
    }

    /// A power step over some blocks, for the current `basis` (m, rank): contributions
    /// (blocks, m, rank) float32. GIL released.
    #[pyo3(signature = (basis, first = 0, count = 0, pixels = None, y = 0))]
    fn power<'py>(
        &self,
        py: Python<'py>,
        basis: PyReadonlyArray2<'py, f64>,
        first: usize,
        count: usize,
        pixels: Option<&Bound<'py, PyAny>>,
        y: usize,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let rank = self.record.rank;
        let q = stages::as_f32(&basis_of(basis, self.m, rank)?);
        let blocks = self.blocks(first, count, pixels, y)?;
        let first_cell = self.first;
        let parts = detached(py, "fluorite.dask power", || {
            blocks.each(|b| Ok(stages::power_block(b, first_cell, &q, rank)))
        })?;
        stack(py, parts, self.m, rank)
    }

    /// The projection of some blocks on the final `basis` (m, rank): a list of (x, y,
    /// records) per block, records float32 (height, width, record_len) of the block's
    /// pixels. GIL released.
    #[pyo3(signature = (basis, first = 0, count = 0, pixels = None, y = 0))]
    #[allow(clippy::type_complexity)]
    fn project<'py>(
        &self,
        py: Python<'py>,
        basis: PyReadonlyArray2<'py, f64>,
        first: usize,
        count: usize,
        pixels: Option<&Bound<'py, PyAny>>,
        y: usize,
    ) -> PyResult<Vec<(usize, usize, Bound<'py, PyArray3<f32>>)>> {
        let basis = basis_of(basis, self.m, self.record.rank)?;
        let both =
            stages::projection_matrix(&basis, &self.colours, self.first, self.m, self.record.rank);
        let blocks = self.blocks(first, count, pixels, y)?;
        let (first_cell, record) = (self.first, self.record);
        let parts = detached(py, "fluorite.dask projection", || {
            blocks.each(|b| {
                let (x, y, w, h) = (b.x, b.y, b.width, b.height);
                Ok((
                    x,
                    y,
                    w,
                    h,
                    stages::projection_block(b, first_cell, &both, record),
                ))
            })
        })?;
        parts
            .into_iter()
            .map(|(x, y, w, h, records)| {
                let a = Array3::from_shape_vec((h, w, record.len()), records)
                    .map_err(|e| invalid("records", e))?;
                Ok((x, y, a.into_pyarray(py)))
            })
            .collect()
    }

    /// The cells of some blocks of an EXR as a list of (x, y, cells), cells float32
    /// (height, width, cells) in the layout's canonical order (the diagonal cells by
    /// wavelength, then the reradiation cells excitation-major). GIL released.
    #[allow(clippy::type_complexity)]
    fn read_blocks<'py>(
        &self,
        py: Python<'py>,
        first: usize,
        count: usize,
    ) -> PyResult<Vec<(usize, usize, Bound<'py, PyArray3<f32>>)>> {
        let blocks = self.blocks(first, count, None, 0)?;
        let parts = detached(py, "fluorite.dask read_blocks", || {
            blocks.each(|b| {
                let n = b.pixel_count();
                let mut pixels = vec![0f32; n * b.cells];
                for (c, plane) in b.planes.chunks_exact(n).enumerate() {
                    for (q, &v) in plane.iter().enumerate() {
                        pixels[q * b.cells + c] = v;
                    }
                }
                Ok((b.x, b.y, b.width, b.height, b.cells, pixels))
            })
        })?;
        parts
            .into_iter()
            .map(|(x, y, w, h, cells, pixels)| {
                let a = Array3::from_shape_vec((h, w, cells), pixels)
                    .map_err(|e| invalid("pixels", e))?;
                Ok((x, y, a.into_pyarray(py)))
            })
            .collect()
    }

    /// An orthonormal basis (m, rank) of the range of a summed sketch or power step `z`
    /// (m, rank), as the library's passes make it.
    fn orthonormal<'py>(
        &self,
        py: Python<'py>,
        z: PyReadonlyArray2<'py, f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (m, rank) = (self.m, self.record.rank);
        let z = basis_of(z, m, rank)?;
        let q = detached(py, "fluorite.dask orthonormal", || {
            Ok(orthonormal(&z, m, rank))
        })?;
        Array2::from_shape_vec((m, rank), q)
            .map(|a| a.into_pyarray(py))
            .map_err(|e| invalid("basis", e))
    }

    /// The fit after the passes, into the folder `output`: `basis` (m, rank) after the
    /// power steps, the sketch's census, and `read_rows(y, rows)` returning the records
    /// of rows y..y + rows as float32 (rows, width, record_len). The records are copied
    /// into the run's scratch file band by band; the shared fluorophores, the gauge and
    /// every output are then `fit_image`'s. With `map_chunks`, the passes over the
    /// records of the shared fit run through it: `map_chunks(kernel, chunks)` returns, in
    /// order, the `chunks` results of `run_records(basis, kernel, first, records)` on
    /// every chunk of ``RECORD_CHUNK`` records (pixel order, the last shorter), as text.
    /// With `map_bands` (and uncompressed outputs), the EXR outputs' tiles are written by
    /// it: `map_bands(job)` returns an iterable of ``(y, clamped, png)``, the results of
    /// ``write_band(job, y, records)`` on bands of whole rows of 64-pixel tiles covering
    /// the image, in row order; the PNGs are encoded here from their rows. With
    /// `fetch_pixels(first, count)` returning the records of pixels first..first + count
    /// (count, record_len) float32, the records are read through it when needed (with
    /// both mappers: the start's few pixels) instead of copied through `read_rows`.
    /// Returns an ``ImageFit``.
    #[pyo3(signature = (output, basis, masked_pixels, non_finite_cells, read_rows, map_chunks = None, map_bands = None, fetch_pixels = None))]
    #[allow(clippy::too_many_arguments)]
    fn fit_records(
        &self,
        py: Python<'_>,
        output: &Bound<'_, PyAny>,
        basis: PyReadonlyArray2<'_, f64>,
        masked_pixels: usize,
        non_finite_cells: usize,
        read_rows: Py<PyAny>,
        map_chunks: Option<Py<PyAny>>,
        map_bands: Option<Py<PyAny>>,
        fetch_pixels: Option<Py<PyAny>>,
    ) -> PyResult<PyImageFit> {
        let out = crate::convert::path(output, "output")?;
        let basis = basis_of(basis, self.m, self.record.rank)?;
        let census = Census {
            masked_pixels,
            non_finite_cells,
        };
        let (width, height, len) = (
            self.image().width(),
            self.image().height(),
            self.record.len(),
        );
        // A Python error of a callable, raised again as it was.
        let raised: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
        const BAND: usize = 64;
        let image = self.image();
        let options = &self.options;
        let mapper = map_chunks.map(|call| PythonMapper {
            call,
            raised: &raised,
        });
        let mapper = mapper.as_ref().map(|m| m as &dyn ChunkMapper);
        let bands = map_bands.map(|call| PythonMapper {
            call,
            raised: &raised,
        });
        let bands = bands.as_ref().map(|m| m as &dyn BandMapper);
        let records = match fetch_pixels {
            Some(fetch) => {
                let raised = Arc::clone(&raised);
                RecordSource::Fetch(Box::new(move |first: usize, count: usize| {
                    let got = Python::attach(|py| -> PyResult<Vec<f32>> {
                        let a = fetch.call1(py, (first, count))?;
                        let a = a
                            .bind(py)
                            .extract::<PyArrayLikeDyn<'_, f32, AllowTypeChange>>()
                            .map_err(|_| {
                                invalid(
                                    "fetch_pixels",
                                    "returned something other than an array of real numbers",
                                )
                            })?;
                        if a.shape() != [count, len] {
                            return Err(invalid(
                                "fetch_pixels",
                                format!(
                                    "returned shape {:?} for {count} pixels: expected ({count}, {len})",
                                    a.shape()
                                ),
                            ));
                        }
                        Ok(a.as_array().iter().copied().collect())
                    });
                    got.map_err(|e| {
                        *raised.lock().expect("not poisoned") = Some(e);
                        fluorite::Error::invalid("fetch_pixels", "raised an exception")
                    })
                }))
            }
            None => RecordSource::Fill(Box::new(|scratch| {
                for y in (0..height).step_by(BAND) {
                    let rows = BAND.min(height - y);
                    let band = Python::attach(|py| -> PyResult<Vec<f32>> {
                        let a = read_rows.call1(py, (y, rows))?;
                        let a = a
                            .bind(py)
                            .extract::<PyArrayLikeDyn<'_, f32, AllowTypeChange>>()
                            .map_err(|_| {
                                invalid(
                                    "read_rows",
                                    "returned something other than an array of real numbers",
                                )
                            })?;
                        if a.shape() != [rows, width, len] {
                            return Err(invalid(
                                "read_rows",
                                format!(
                                    "returned shape {:?} for rows {y}..{}: expected ({rows}, {width}, {len})",
                                    a.shape(),
                                    y + rows
                                ),
                            ));
                        }
                        Ok(a.as_array().iter().copied().collect())
                    });
                    match band {
                        Ok(band) => scratch.write(y * width, &band)?,
                        Err(e) => {
                            *raised.lock().expect("not poisoned") = Some(e);
                            return Err(fluorite::Error::invalid(
                                "read_rows",
                                "raised an exception",
                            ));
                        }
                    }
                }
                Ok(())
            })),
        };
        let result = detached(py, "fluorite.dask fit", || {
            fit_image_from_records(
                image,
                &out,
                options,
                &basis,
                &census,
                records,
                mapper,
                bands,
                &|_| {},
            )
        });
        if let Some(e) = raised.lock().expect("not poisoned").take() {
            return Err(e);
        }
        let fit = result?;
        let notes = match &self.input {
            Input::Exr(image, _) => image.notes.iter().chain(&fit.notes).cloned().collect(),
            Input::Array(..) => fit.notes.clone(),
        };
        PyImageFit::new(py, fit, &self.options, notes)
    }

    /// Records per chunk of a pass over the records (``fit_records``' `map_chunks`).
    #[classattr]
    #[allow(non_snake_case)]
    fn RECORD_CHUNK() -> usize {
        RECORD_CHUNK
    }

    /// A pass over records (a worker's part of ``fit_records``' `map_chunks`): `kernel`
    /// (text, as `map_chunks` got it) on `records` (n, record_len) float32, the records
    /// of pixels first..first + n, `first` a multiple of ``RECORD_CHUNK``; basis (m,
    /// rank) the fit's. Returns one text result per chunk of ``RECORD_CHUNK`` records, in
    /// order. GIL released.
    fn run_records(
        &self,
        py: Python<'_>,
        basis: PyReadonlyArray2<'_, f64>,
        kernel: &str,
        first: usize,
        records: PyReadonlyArray2<'_, f32>,
    ) -> PyResult<Vec<String>> {
        let kernel: RecordKernel = serde_json::from_str(kernel)
            .map_err(|e| invalid("kernel", format!("not a kernel of fit_records ({e})")))?;
        let basis = basis_of(basis, self.m, self.record.rank)?;
        let len = self.record.len();
        if records.shape()[1] != len {
            return Err(invalid(
                "records",
                format!("shape {:?}: expected (n, {len})", records.shape()),
            ));
        }
        if !first.is_multiple_of(RECORD_CHUNK) {
            return Err(invalid(
                "first",
                format!("{first} is not a multiple of RECORD_CHUNK ({RECORD_CHUNK})"),
            ));
        }
        let values: Vec<f32> = records.as_array().iter().copied().collect();
        let layout = self.image().layout().clone();
        let (options, record) = (&self.options, self.record);
        detached(py, "fluorite.dask records", || {
            let context = RecordContext::new(&layout, &basis, record, options);
            let prepared = context.prepare(&kernel);
            let mut results = values
                .chunks(RECORD_CHUNK * len)
                .enumerate()
                .map(|(i, chunk)| context.run(&prepared, first + i * RECORD_CHUNK, chunk))
                .collect::<fluorite::Result<Vec<_>>>()?;
            // One judge result for the task's chunks (exact), not one per chunk.
            fold_exact(&mut results);
            results
                .iter()
                .map(|result| {
                    serde_json::to_string(result)
                        .map_err(|e| fluorite::Error::invalid("records", e.to_string()))
                })
                .collect()
        })
    }

    /// A worker's part of ``fit_records``' `map_bands`: writes rows y..y + rows (whole
    /// rows of 64-pixel tiles; `records` (rows, width, record_len) float32, their
    /// records; basis (m, rank) the fit's) of every EXR output of `job` (text, as `map_bands` got it) into its
    /// staged files, and returns ``(clamped, png)``: the band's pixels whose material
    /// needed clamping and its rows of every PNG (bytes). GIL released.
    fn write_band<'py>(
        &self,
        py: Python<'py>,
        job: &str,
        basis: PyReadonlyArray2<'py, f64>,
        y: usize,
        records: PyReadonlyArray3<'py, f32>,
    ) -> PyResult<(usize, Bound<'py, PyBytes>)> {
        let job: OutputJob = serde_json::from_str(job)
            .map_err(|e| invalid("job", format!("not a job of fit_records' map_bands ({e})")))?;
        let basis_values = basis_of(basis, self.m, self.record.rank)?;
        let shape = records.shape().to_vec();
        let (width, height) = (self.image().width(), self.image().height());
        let len = self.record.len();
        if shape.len() != 3 || shape[1] != width || shape[2] != len {
            return Err(invalid(
                "records",
                format!("shape {shape:?}: expected (rows, {width}, {len})"),
            ));
        }
        let rows = shape[0];
        let values: Vec<f32> = records.as_array().iter().copied().collect();
        let layout = self.image().layout().clone();
        let (options, record) = (&self.options, self.record);
        let band = detached(py, "fluorite.dask outputs", || {
            let model = stages::pixel_model(
                &layout,
                options,
                &job.shared,
                &basis_values,
                record,
                job.sigma,
            );
            let cells = fluorite::image::fit::cells_of(&layout);
            let vectors: Vec<Vec<f64>> = (0..job.shared.k)
                .map(|c| job.shared.cell_vector(&cells, c))
                .collect();
            let style = PngStyle::new(&model, options.max_delta_e);
            write_band(
                &job,
                &model,
                &layout,
                &vectors,
                &style,
                (width, height),
                y,
                rows,
                &values,
                len,
            )
        })?;
        Ok((band.clamped, PyBytes::new(py, &band.png)))
    }

    /// The model of a finished fit's pixels, as text for `evaluate` (the chosen K's
    /// shared spectra and the cell noise σ, JSON).
    fn model_of(&self, fit: PyRef<'_, PyImageFit>) -> PyResult<String> {
        let outcome = fit.outcome();
        let trial = outcome
            .trials
            .iter()
            .find(|t| t.components == outcome.components)
            .ok_or_else(|| invalid("fit", "holds no trial of its K"))?;
        let model = serde_json::json!({
            "shared": trial.shared,
            "sigma": outcome.noise_sigma,
        });
        Ok(model.to_string())
    }

    /// Every pixel's map values from its record, as the fit's EXR outputs hold them:
    /// (concentration (h, w, K), reflectance (h, w, diagonal cells), ΔE2000 (h, w,
    /// lights)), float32, NaN at masked pixels, for `records` (h, w, record_len) of the
    /// projection on `basis` and `model` from `model_of`. GIL released.
    #[allow(clippy::type_complexity)]
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        model: &str,
        basis: PyReadonlyArray2<'py, f64>,
        records: PyReadonlyArray3<'py, f32>,
    ) -> PyResult<(
        Bound<'py, PyArray3<f32>>,
        Bound<'py, PyArray3<f32>>,
        Bound<'py, PyArray3<f32>>,
    )> {
        let bad = |e: String| invalid("model", format!("not a model of model_of ({e})"));
        let value: serde_json::Value =
            serde_json::from_str(model).map_err(|e| bad(e.to_string()))?;
        let shared: Shared =
            serde_json::from_value(value["shared"].clone()).map_err(|e| bad(e.to_string()))?;
        let sigma = value["sigma"]
            .as_f64()
            .ok_or_else(|| bad("no sigma".to_string()))?;
        let basis = basis_of(basis, self.m, self.record.rank)?;
        if !records.is_aligned() {
            return Err(unaligned("records"));
        }
        let shape = records.shape().to_vec();
        let len = self.record.len();
        if shape.len() != 3 || shape[2] != len {
            return Err(invalid(
                "records",
                format!("shape {shape:?}: expected (rows, columns, {len})"),
            ));
        }
        let values: Vec<f32> = records.as_array().iter().copied().collect();
        let (h, w) = (shape[0], shape[1]);
        let k = shared.k;
        let nd = self.first;
        let lights = self.options.lights.len();
        let layout = self.image().layout().clone();
        let (options, record) = (&self.options, self.record);
        let (c, r, d) = detached(py, "fluorite.dask evaluate", || {
            let pixel = stages::pixel_model(&layout, options, &shared, &basis, record, sigma);
            let mut c = Vec::with_capacity(h * w * k);
            let mut r = Vec::with_capacity(h * w * nd);
            let mut d = Vec::with_capacity(h * w * lights);
            for rec in values.chunks_exact(len) {
                let fit = pixel.fit(rec);
                let colours = pixel.colours(rec, &fit);
                c.extend(fit.concentration[..k].iter().map(|&v| v as f32));
                r.extend(fit.reflectance.iter().map(|&v| v as f32));
                d.extend(colours.delta_e.iter().map(|&v| v as f32));
            }
            Ok((c, r, d))
        })?;
        let array = |values: Vec<f32>, n: usize| {
            Array3::from_shape_vec((h, w, n), values)
                .map(|a| a.into_pyarray(py))
                .map_err(|e| invalid("maps", e))
        };
        Ok((array(c, k)?, array(r, nd)?, array(d, lights)?))
    }

    fn __repr__(&self) -> String {
        format!(
            "_ImageStages({:?}, {}×{} pixels, {} cells, rank {})",
            self.image().describe(),
            self.image().width(),
            self.image().height(),
            self.image().layout().len(),
            self.record.rank
        )
    }
}

/// The length of a 1-D grid argument (checked fully by `grid`).
fn floats_len(value: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<usize> {
    match value.filter(|v| !v.is_none()) {
        Some(v) => Ok(crate::convert::floats(v, what)?.len()),
        None => Err(invalid(
            what,
            "is required for an image given as arrays (nm, 1-D)",
        )),
    }
}

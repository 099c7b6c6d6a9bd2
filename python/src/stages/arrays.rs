//! Arrays to and from Python for the stages: a pass's blocks, an array chunk's cells, the
//! contributions stacked, a basis checked.

use fluorite::image::ExrImage;
use fluorite::image::fit::stages;
use fluorite::image::source::{ChunkIndex, PlanarBlock};
use numpy::ndarray::{Array3, ArrayViewD};
use numpy::{
    AllowTypeChange, IntoPyArray, PyArray3, PyArrayDyn, PyArrayLikeDyn, PyArrayMethods,
    PyReadonlyArray2, PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::prelude::*;

use crate::image::gather;
use crate::invalid;

/// The blocks of one pass: a range of an EXR's blocks, or rows of an array chunk (values,
/// first row, width, cells).
pub(super) enum Blocks<'a> {
    Exr(&'a ExrImage, &'a ChunkIndex, std::ops::Range<usize>),
    Array(Vec<f32>, usize, usize, usize),
}

impl Blocks<'_> {
    /// Runs `map` on every block in order (on this thread).
    pub(super) fn each<T>(
        self,
        mut map: impl FnMut(PlanarBlock) -> fluorite::Result<T>,
    ) -> fluorite::Result<Vec<T>> {
        let mut out = Vec::new();
        match self {
            Blocks::Exr(image, index, range) => {
                image.pass_planar_range(range, index, &mut map, |t| {
                    out.push(t);
                    Ok(())
                })?;
            }
            Blocks::Array(values, y, width, cells) => {
                for block in stages::row_blocks(&values, y, width, cells) {
                    out.push(map(block)?);
                }
            }
        }
        Ok(out)
    }
}

/// The rows of an array chunk as the layout's cells, pixel-major (float32, as
/// `fit_image` reads a numpy image): (rows, width, excitation, emission), or (rows,
/// width, cells) already in the layout's canonical cell order.
pub(super) fn chunk_values(
    pixels: &Bound<'_, PyAny>,
    cells: &[(usize, usize)],
    width: usize,
    ni: usize,
    no: usize,
) -> PyResult<Vec<f32>> {
    let check = |shape: &[usize]| -> PyResult<()> {
        let grid = shape.len() == 4 && shape[1] == width && shape[2] == ni && shape[3] == no;
        let canonical = shape.len() == 3 && shape[1] == width && shape[2] == cells.len();
        if !(grid || canonical) {
            return Err(invalid(
                "pixels",
                format!(
                    "shape {shape:?}: expected (rows, {width}, {ni}, {no}) (rows, width, excitation, emission) or (rows, {width}, {}) (rows, width, cells)",
                    cells.len()
                ),
            ));
        }
        Ok(())
    };
    fn values<T: Copy + Into<f64>>(view: ArrayViewD<'_, T>, cells: &[(usize, usize)]) -> Vec<f32> {
        if view.ndim() == 3 {
            // Canonical cells: converted as `gather` converts them.
            view.as_standard_layout()
                .iter()
                .map(|&v| v.into() as f32)
                .collect()
        } else {
            gather(view, cells)
        }
    }
    if pixels
        .cast::<PyUntypedArray>()
        .is_ok_and(|a| !a.is_aligned())
    {
        return Err(unaligned("pixels"));
    }
    if let Ok(a) = pixels.cast::<PyArrayDyn<f32>>() {
        let a = a.readonly();
        check(a.shape())?;
        return Ok(values(a.as_array(), cells));
    }
    if let Ok(a) = pixels.cast::<PyArrayDyn<f64>>() {
        let a = a.readonly();
        check(a.shape())?;
        return Ok(values(a.as_array(), cells));
    }
    let a = pixels
        .extract::<PyArrayLikeDyn<'_, f32, AllowTypeChange>>()
        .map_err(|_| invalid("pixels", "expected a numpy array of real numbers"))?;
    check(a.shape())?;
    Ok(values(a.as_array(), cells))
}

/// The error for an array whose data are not aligned (one deserialised from a buffer):
/// numpy.require(a, requirements=["C", "A"]) copies it aligned.
pub(super) fn unaligned(what: &str) -> PyErr {
    invalid(
        what,
        "the array's data are not aligned to its type: pass numpy.require(a, requirements=[\"C\", \"A\"])",
    )
}

/// Stacks blocks' m × rank contributions into an array (blocks, m, rank).
pub(super) fn stack<'py>(
    py: Python<'py>,
    parts: Vec<Vec<f32>>,
    m: usize,
    rank: usize,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let n = parts.len();
    let flat: Vec<f32> = parts.into_iter().flatten().collect();
    Array3::from_shape_vec((n, m, rank), flat)
        .map(|a| a.into_pyarray(py))
        .map_err(|e| invalid("parts", e))
}

/// A basis (m × rank) from Python, checked.
pub(super) fn basis_of(
    basis: PyReadonlyArray2<'_, f64>,
    m: usize,
    rank: usize,
) -> PyResult<Vec<f64>> {
    if !basis.is_aligned() {
        return Err(unaligned("basis"));
    }
    if basis.shape() != [m, rank] {
        return Err(invalid(
            "basis",
            format!("shape {:?}: expected ({m}, {rank})", basis.shape()),
        ));
    }
    Ok(basis.as_array().iter().copied().collect())
}

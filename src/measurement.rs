//! A measured (or model-predicted) bispectral reradiation matrix on its own grids.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::spectrum::{bin_widths, check_grid, find_wavelength};

/// Largest magnitude of a cell: no radiance factor or instrument count comes near it, and
/// beyond it the squares the fit sums overflow to infinity (a cell of −1e308 made
/// L-BFGS's line search loop forever; found by tests/suite/fuzz.rs).
pub const MAX_CELL_MAGNITUDE: f64 = 1e100;

/// How the matrix's values are expressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Units {
    /// Radiance factor per emission bin (what a BFC-450 writes): off the diagonal,
    /// M = k·a(λi)·e(λo)·Δλo.
    #[default]
    PerBin,
    /// Spectral density per nm of emission: off the diagonal, M = k·a(λi)·e(λo).
    PerNm,
}

/// What a cell of a reradiation matrix holds, for fitting and plotting.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellKind {
    /// No measured value.
    Missing,
    /// λo = λi: reflectance (plus the fluorescence emitted at the same wavelength).
    Diagonal,
    /// 0 < |λo − λi| ≤ guard: instrument bandwidth crosstalk, excluded from fits.
    Guard,
    /// λo > λi + guard: the Stokes side, where fluorescence appears.
    Stokes,
    /// λo < λi − guard: the anti-Stokes side, only noise in real surfaces.
    AntiStokes,
}

/// A reradiation (Donaldson) matrix: for monochromatic excitation at `excitation_nm[i]`,
/// the radiance factor observed at emission `emission_nm[j]`, stored at
/// `values[i * emission_nm.len() + j]`. NaN marks a missing (unmeasured) cell.
#[derive(Debug, Clone, PartialEq)]
pub struct Measurement {
    /// A short name for outputs (the file stem).
    pub name: String,
    /// The file it was read from, if any.
    pub source: Option<PathBuf>,
    /// SHA-256 of the file's bytes, hex, if read from a file.
    pub source_sha256: Option<String>,
    /// Excitation wavelengths in nm, strictly increasing.
    pub excitation_nm: Vec<f64>,
    /// Emission wavelengths in nm, strictly increasing.
    pub emission_nm: Vec<f64>,
    /// Row-major values, excitation rows × emission columns; NaN = missing.
    pub values: Vec<f64>,
    /// How the values are expressed.
    pub units: Units,
    /// True when the data carry a diagonal (reflectance). Solution EEMs do not: their
    /// near-diagonal cells are Rayleigh scatter, masked by the instrument.
    pub has_diagonal: bool,
    /// True when the values are on an arbitrary scale (counts), so absolute quantities
    /// (k, c, Q, reflectance) are undetermined.
    pub arbitrary_scale: bool,
    /// Things the reader decided that the user should know (inferred orientation, …).
    pub notes: Vec<String>,
}

impl Measurement {
    /// Builds a matrix, checking grids, shape and values. `name` is used in errors.
    pub fn new(
        name: impl Into<String>,
        excitation_nm: Vec<f64>,
        emission_nm: Vec<f64>,
        values: Vec<f64>,
        units: Units,
    ) -> Result<Self> {
        let m = Measurement {
            name: name.into(),
            source: None,
            source_sha256: None,
            excitation_nm,
            emission_nm,
            values,
            units,
            has_diagonal: true,
            arbitrary_scale: false,
            notes: Vec::new(),
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks the invariants: grids valid, shape right, no infinities or cells beyond
    /// [`MAX_CELL_MAGNITUDE`], a usable cell.
    pub fn validate(&self) -> Result<()> {
        let what = |s: &str| format!("{}: {s}", self.name);
        if self.excitation_nm.is_empty() || self.emission_nm.is_empty() {
            return Err(Error::invalid(
                what("grid"),
                "has no excitation or no emission wavelengths",
            ));
        }
        check_grid(&self.excitation_nm, &what("excitation_nm"))?;
        check_grid(&self.emission_nm, &what("emission_nm"))?;
        let cells = self.excitation_nm.len() * self.emission_nm.len();
        if cells > crate::limits::MAX_CELLS {
            return Err(Error::invalid(
                what("grid"),
                format!(
                    "{} excitation × {} emission wavelengths make {cells} cells; at most {} are fitted at once: bin the grid or fit parts of it",
                    self.excitation_nm.len(),
                    self.emission_nm.len(),
                    crate::limits::MAX_CELLS
                ),
            ));
        }
        if self.values.len() != self.excitation_nm.len() * self.emission_nm.len() {
            return Err(Error::invalid(
                what("values"),
                format!(
                    "holds {} cells, expected {} excitation × {} emission",
                    self.values.len(),
                    self.excitation_nm.len(),
                    self.emission_nm.len()
                ),
            ));
        }
        if let Some(k) = self.values.iter().position(|v| v.is_infinite()) {
            let (i, j) = (k / self.emission_nm.len(), k % self.emission_nm.len());
            return Err(Error::invalid(
                what("values"),
                format!(
                    "cell at excitation {} nm, emission {} nm is infinite; use NaN or leave it empty for a missing cell",
                    self.excitation_nm[i], self.emission_nm[j]
                ),
            ));
        }
        if let Some(k) = self
            .values
            .iter()
            .position(|v| v.abs() > MAX_CELL_MAGNITUDE)
        {
            let (i, j) = (k / self.emission_nm.len(), k % self.emission_nm.len());
            return Err(Error::invalid(
                what("values"),
                format!(
                    "cell at excitation {} nm, emission {} nm is {:e}, beyond ±{MAX_CELL_MAGNITUDE:e} (its square overflows the fit's sums); correct the cell, or use NaN or leave it empty for a missing cell",
                    self.excitation_nm[i], self.emission_nm[j], self.values[k]
                ),
            ));
        }
        if self.values.iter().all(|v| v.is_nan()) {
            return Err(Error::invalid(
                what("values"),
                "no cell holds a measured value",
            ));
        }
        Ok(())
    }

    /// Number of excitation rows.
    pub fn n_excitation(&self) -> usize {
        self.excitation_nm.len()
    }

    /// Number of emission columns.
    pub fn n_emission(&self) -> usize {
        self.emission_nm.len()
    }

    /// Value at excitation row `i`, emission column `j` (NaN when missing).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.values[i * self.emission_nm.len() + j]
    }

    /// Mutable access to a cell.
    pub fn get_mut(&mut self, i: usize, j: usize) -> &mut f64 {
        let n = self.emission_nm.len();
        &mut self.values[i * n + j]
    }

    /// The diagonal cells: `(excitation row, emission column)` pairs at shared wavelengths,
    /// in increasing wavelength. Empty when the data carry no diagonal.
    pub fn diagonal(&self) -> Vec<(usize, usize)> {
        if !self.has_diagonal {
            return Vec::new();
        }
        self.emission_nm
            .iter()
            .enumerate()
            .filter_map(|(j, &l)| find_wavelength(&self.excitation_nm, l).map(|i| (i, j)))
            .collect()
    }

    /// The emission columns next to each diagonal cell: `(row, diagonal column, column
    /// below, column above)`, the columns j − 1 and j + 1 where the emission grid has
    /// them, measured or not. Crosstalk next to the diagonal sits there whatever the two
    /// grids' steps (one excitation step need not be one emission step, nor the same
    /// across the grid): the fit's crosstalk removal and the synthesiser both use this.
    pub fn diagonal_neighbours(&self) -> Vec<(usize, usize, Option<usize>, Option<usize>)> {
        self.diagonal()
            .into_iter()
            .map(|(i, j)| {
                let above = Some(j + 1).filter(|&a| a < self.n_emission());
                (i, j, j.checked_sub(1), above)
            })
            .collect()
    }

    /// Classifies cell (`i`, `j`) for a guard band of `guard_nm` around the diagonal.
    /// Without a diagonal (solution EEMs) no cell is `Diagonal`, but the guard band
    /// still excludes the scatter next to λo = λi.
    pub fn cell_kind(&self, i: usize, j: usize, guard_nm: f64) -> CellKind {
        if self.get(i, j).is_nan() {
            return CellKind::Missing;
        }
        let offset = self.emission_nm[j] - self.excitation_nm[i];
        if offset.abs() <= 1e-6 {
            if self.has_diagonal {
                CellKind::Diagonal
            } else {
                CellKind::Guard
            }
        } else if offset.abs() <= guard_nm + 1e-6 {
            CellKind::Guard
        } else if offset > 0.0 {
            CellKind::Stokes
        } else {
            CellKind::AntiStokes
        }
    }

    /// The default guard band: one grid step, the larger of the two grids' typical
    /// (median) spacings.
    pub fn default_guard_nm(&self) -> f64 {
        crate::numeric::median_step(&self.excitation_nm)
            .max(crate::numeric::median_step(&self.emission_nm))
    }

    /// Emission bin widths (nm) by the trapezoid rule, see [`crate::spectrum::bin_widths`].
    pub fn emission_bin_widths(&self) -> Vec<f64> {
        bin_widths(&self.emission_nm)
    }

    /// This matrix with its missing cells (not finite) taken from `model`, a matrix on the
    /// same grids in the same units (a fit's prediction): the patch whose colour is judged,
    /// every measured cell as measured.
    pub fn filled_from(&self, model: &Measurement) -> Measurement {
        let mut out = self.clone();
        for (v, f) in out.values.iter_mut().zip(&model.values) {
            if !v.is_finite() {
                *v = *f;
            }
        }
        out
    }

    /// The same matrix expressed per emission bin (values multiplied by the bin width
    /// when stored per nm). The diagonal is a plain reflectance factor in both units and
    /// is left alone.
    pub fn to_per_bin(&self) -> Measurement {
        let mut out = self.clone();
        if self.units == Units::PerNm {
            let widths = self.emission_bin_widths();
            let diag = self.diagonal();
            for i in 0..self.n_excitation() {
                for (j, w) in widths.iter().enumerate() {
                    if !diag.contains(&(i, j)) {
                        *out.get_mut(i, j) *= w;
                    }
                }
            }
            out.units = Units::PerBin;
        }
        out
    }
}

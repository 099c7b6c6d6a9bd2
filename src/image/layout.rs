//! The cells of a bispectral image: which (excitation, emission) pairs a pixel holds, in
//! the order fluorite keeps them in memory.
//!
//! The spectral OpenEXR layout (Fichet, Mercier and Wilkie 2021) has one wavelength grid
//! for both axes, a diagonal channel `T.<λ>nm` per wavelength and a reradiation channel
//! `T.<λi>nm.<λo>nm` per pair with λo > λi; an image need not hold every one of them
//! (a BFC-450 grid measures emission from 380 nm only). A pixel is kept as one vector in
//! the canonical order of [`Layout::cells`]: the diagonal cells by wavelength, then the
//! reradiation cells excitation-major. That order, not the file's alphabetical channel
//! order, is what every pass sees.

use crate::error::{Error, Result};
use crate::formats::exr::{diagonal_channel, reradiation_channel};

/// One cell of a pixel's matrix, as indices into [`Layout::wavelengths`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Cell {
    /// The diagonal (reflectance plus the fluorescence emitted at λ itself) at λ.
    Diagonal(usize),
    /// The reradiation from the first wavelength to the second (longer) one.
    Reradiation(usize, usize),
}

/// The cells an image holds.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// The one grid of both axes, increasing (nm).
    pub wavelengths: Vec<f64>,
    /// The cells in canonical order: diagonal cells by wavelength, then reradiation
    /// cells by excitation, then emission.
    pub cells: Vec<Cell>,
    /// Number of diagonal cells (they come first in `cells`).
    pub diagonal_count: usize,
}

impl Layout {
    /// The layout of the given cells (any order, no duplicates) on `wavelengths`.
    pub fn new(wavelengths: Vec<f64>, mut cells: Vec<Cell>) -> Result<Layout> {
        if wavelengths.windows(2).any(|w| w[1] <= w[0]) {
            return Err(Error::invalid(
                "layout",
                "the wavelengths must increase strictly",
            ));
        }
        let n = wavelengths.len();
        for c in &cells {
            match *c {
                Cell::Diagonal(i) if i < n => {}
                Cell::Reradiation(i, o) if i < o && o < n => {}
                _ => {
                    return Err(Error::invalid(
                        "layout",
                        format!("cell {c:?} is not a cell of a {n}-wavelength grid with λo > λi"),
                    ));
                }
            }
        }
        cells.sort();
        let before = cells.len();
        cells.dedup();
        if cells.len() != before {
            return Err(Error::invalid("layout", "a cell is named twice"));
        }
        let diagonal_count = cells
            .iter()
            .filter(|c| matches!(c, Cell::Diagonal(_)))
            .count();
        if !cells.iter().any(|c| matches!(c, Cell::Reradiation(..))) {
            return Err(Error::invalid(
                "layout",
                "the image holds no reradiation (T.<λi>nm.<λo>nm) channel: it has no fluorescence to fit; fit its reflectance as a plain spectral image instead",
            ));
        }
        Ok(Layout {
            wavelengths,
            cells,
            diagonal_count,
        })
    }

    /// Every cell of the layout on a measurement's grids: the diagonal where both grids
    /// hold the wavelength, and every λi → λo > λi with λi on the excitation grid and λo
    /// on the emission grid. `excitation_nm` and `emission_nm` must be increasing.
    pub fn from_grids(excitation_nm: &[f64], emission_nm: &[f64]) -> Result<Layout> {
        let grid = crate::export::exr::layout_grid(excitation_nm, emission_nm);
        let find = |nm: f64| crate::spectrum::find_wavelength(&grid, nm);
        let ex: Vec<usize> = excitation_nm.iter().filter_map(|&l| find(l)).collect();
        let em: Vec<usize> = emission_nm.iter().filter_map(|&l| find(l)).collect();
        let mut cells = Vec::new();
        for &i in &ex {
            if em.contains(&i) {
                cells.push(Cell::Diagonal(i));
            }
            cells.extend(
                em.iter()
                    .filter(|&&o| o > i)
                    .map(|&o| Cell::Reradiation(i, o)),
            );
        }
        Layout::new(grid, cells)
    }

    /// Number of cells per pixel.
    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Whether the layout holds no cell (never true for a [`Layout::new`] result).
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The reradiation cells (they follow the diagonal ones).
    pub fn reradiation(&self) -> &[Cell] {
        &self.cells[self.diagonal_count..]
    }

    /// The wavelengths (indices) that hold a diagonal cell, in order.
    pub fn diagonal_wavelengths(&self) -> Vec<usize> {
        self.cells[..self.diagonal_count]
            .iter()
            .filter_map(|c| match *c {
                Cell::Diagonal(i) => Some(i),
                Cell::Reradiation(..) => None,
            })
            .collect()
    }

    /// The excitation wavelengths (indices) of the reradiation cells, in order.
    pub fn excitation_wavelengths(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self
            .reradiation()
            .iter()
            .map(|c| match *c {
                Cell::Reradiation(i, _) | Cell::Diagonal(i) => i,
            })
            .collect();
        v.dedup();
        v
    }

    /// The emission wavelengths (indices) of the reradiation cells, in order.
    pub fn emission_wavelengths(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self
            .reradiation()
            .iter()
            .map(|c| match *c {
                Cell::Reradiation(_, o) | Cell::Diagonal(o) => o,
            })
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The channel name of cell `c` in the spectral EXR layout.
    pub fn channel_name(&self, c: Cell) -> String {
        match c {
            Cell::Diagonal(i) => diagonal_channel(self.wavelengths[i]),
            Cell::Reradiation(i, o) => {
                reradiation_channel(self.wavelengths[i], self.wavelengths[o])
            }
        }
    }

    /// The channel names of every cell, in canonical order.
    pub fn channel_names(&self) -> Vec<String> {
        self.cells.iter().map(|&c| self.channel_name(c)).collect()
    }

    /// Index of cell `c` in canonical order.
    pub fn position(&self, c: Cell) -> Option<usize> {
        self.cells.binary_search(&c).ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bfc_grid_has_the_cells_its_instrument_measures() {
        let ex: Vec<f64> = (0..49).map(|i| 300.0 + 10.0 * i as f64).collect();
        let em: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * i as f64).collect();
        let layout = Layout::from_grids(&ex, &em).unwrap();
        assert_eq!(layout.wavelengths.len(), 49);
        assert_eq!(layout.diagonal_count, 41);
        // Rows 300–370 nm reach all 41 emission samples; rows 380–780 the longer ones.
        assert_eq!(layout.reradiation().len(), 8 * 41 + 41 * 40 / 2);
        assert_eq!(layout.channel_name(layout.cells[0]), "T.380nm");
        assert_eq!(layout.channel_name(layout.cells[41]), "T.300nm.380nm");
        assert_eq!(layout.excitation_wavelengths().len(), 48);
        assert_eq!(layout.emission_wavelengths().len(), 41);
    }
}

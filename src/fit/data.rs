//! The cells a fit uses, gathered once from a measurement.

use crate::error::{Error, Result};
use crate::measurement::{CellKind, Measurement, Units};
use crate::spectrum::{Spectrum, bin_widths};

/// One matrix cell used by the fit.
#[derive(Debug, Clone, Copy)]
pub struct Cell {
    /// Excitation row.
    pub row: usize,
    /// Emission column.
    pub column: usize,
    /// Measured value (per bin or per nm, as the measurement).
    pub value: f64,
}

/// Everything the objective needs from a measurement, precomputed.
#[derive(Debug, Clone)]
pub struct FitData {
    /// Excitation grid (nm).
    pub excitation_nm: Vec<f64>,
    /// Emission grid (nm).
    pub emission_nm: Vec<f64>,
    /// Off-diagonal cells outside the guard band (Stokes and anti-Stokes), measured.
    pub off_diagonal: Vec<Cell>,
    /// Diagonal cells with a measured value.
    pub diagonal: Vec<Cell>,
    /// Diagonal positions `(row, column)` whether measured or not.
    pub diagonal_positions: Vec<(usize, usize)>,
    /// Cells in the guard band (excluded), measured.
    pub guard: Vec<Cell>,
    /// Stokes-side cells (λo > λi + guard): where fluorescence is judged.
    pub stokes: Vec<Cell>,
    /// Anti-Stokes cells (λo < λi − guard): noise in real surfaces.
    pub anti_stokes: Vec<Cell>,
    /// Trapezoid emission bin widths (nm).
    pub emission_bin_widths: Vec<f64>,
    /// Factor turning the fitted emission column values v_j into e_j·Δλ_j: the bin width
    /// for per-nm data (v = e), 1 for per-bin data (v = e·Δλ).
    pub emission_weight: Vec<f64>,
    /// Guard band used (nm).
    pub guard_nm: f64,
}

impl FitData {
    /// Gathers the cells of `m` for a guard band of `guard_nm` around the diagonal.
    pub fn new(m: &Measurement, guard_nm: f64) -> Self {
        let mut data = FitData {
            excitation_nm: m.excitation_nm.clone(),
            emission_nm: m.emission_nm.clone(),
            off_diagonal: Vec::new(),
            diagonal: Vec::new(),
            diagonal_positions: m.diagonal(),
            guard: Vec::new(),
            stokes: Vec::new(),
            anti_stokes: Vec::new(),
            emission_bin_widths: bin_widths(&m.emission_nm),
            emission_weight: Vec::new(),
            guard_nm,
        };
        data.emission_weight = match m.units {
            Units::PerBin => vec![1.0; m.n_emission()],
            Units::PerNm => data.emission_bin_widths.clone(),
        };
        for row in 0..m.n_excitation() {
            for column in 0..m.n_emission() {
                let cell = Cell {
                    row,
                    column,
                    value: m.get(row, column),
                };
                match m.cell_kind(row, column, guard_nm) {
                    CellKind::Missing => {}
                    CellKind::Diagonal => data.diagonal.push(cell),
                    CellKind::Guard => data.guard.push(cell),
                    CellKind::Stokes => {
                        data.off_diagonal.push(cell);
                        data.stokes.push(cell);
                    }
                    CellKind::AntiStokes => {
                        data.off_diagonal.push(cell);
                        data.anti_stokes.push(cell);
                    }
                }
            }
        }
        data
    }

    /// Number of excitation samples.
    pub fn n_excitation(&self) -> usize {
        self.excitation_nm.len()
    }

    /// Number of emission samples.
    pub fn n_emission(&self) -> usize {
        self.emission_nm.len()
    }

    /// Robust noise level: 1.4826 × the median absolute deviation of the anti-Stokes
    /// cells, which hold only noise on real surfaces. With fewer than ten of them (solution
    /// EEMs record nothing below the excitation, or it is masked as scatter) the spread of
    /// the other cells would measure the fluorescence itself, not its noise: the noise is
    /// then read from the roughness along emission, the robust spread of second
    /// differences (√6·σ for white noise), falling back to all off-diagonal cells only
    /// when too few runs of three measured cells exist.
    pub fn noise_sigma(&self) -> f64 {
        if self.anti_stokes.len() >= 10 {
            return robust_sigma(self.anti_stokes.iter().map(|c| c.value));
        }
        let n_em = self.n_emission();
        let mut grid = vec![f64::NAN; self.n_excitation() * n_em];
        for c in &self.off_diagonal {
            grid[c.row * n_em + c.column] = c.value;
        }
        let second_differences: Vec<f64> = grid
            .chunks(n_em)
            .flat_map(|row| row.windows(3).map(|w| w[0] - 2.0 * w[1] + w[2]))
            .filter(|d| d.is_finite())
            .collect();
        if second_differences.len() >= 10 {
            robust_sigma(second_differences.into_iter()) / 6f64.sqrt()
        } else {
            robust_sigma(self.off_diagonal.iter().map(|c| c.value))
        }
    }
}

/// 1.4826 × median absolute deviation from the median (σ for Gaussian noise).
pub fn robust_sigma(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return 0.0;
    }
    let m = crate::numeric::median(&v);
    let dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    1.4826 * crate::numeric::median(&dev)
}

/// Fills unmeasured diagonal samples (not finite) by linear interpolation between the
/// measured ones (ends held), within their cap; an error naming `name` when none is
/// measured.
pub fn fill_missing(
    diagonal: &mut [f64],
    wavelengths: &[f64],
    cap: &[f64],
    name: &str,
) -> Result<()> {
    let known: Vec<usize> = (0..diagonal.len())
        .filter(|&p| diagonal[p].is_finite())
        .collect();
    if known.is_empty() {
        return Err(Error::Fit(format!(
            "{name}: the diagonal (reflectance) is not measured at any wavelength; supply the diagonal or fit as an EEM"
        )));
    }
    let s = Spectrum {
        wavelength_nm: known.iter().map(|&p| wavelengths[p]).collect(),
        value: known.iter().map(|&p| diagonal[p]).collect(),
    };
    for p in 0..diagonal.len() {
        if !diagonal[p].is_finite() {
            diagonal[p] = s.eval_clamped(wavelengths[p]).clamp(0.0, cap[p].max(0.0));
        }
    }
    Ok(())
}

/// A fit report naming the measurement it comes from (its file, or its name, and the
/// file's SHA-256), the rest default.
pub fn provenance(m: &Measurement) -> crate::material::FitReport {
    crate::material::FitReport {
        source: m
            .source
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| m.name.clone()),
        source_sha256: m.source_sha256.clone().unwrap_or_default(),
        ..Default::default()
    }
}

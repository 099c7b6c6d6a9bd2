//! The cells a fit uses, gathered once from a measurement.

use crate::error::{Error, Result};
use crate::measurement::{CellKind, Measurement, Units};
use crate::spectrum::{Spectrum, bin_widths};

use super::crosstalk;
use crate::material::CrosstalkCorrection;

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
    /// The crosstalk next to the diagonal found in these cells: taken out of them where
    /// its `removed` says so, else they are as measured (`None`: none was significant).
    pub crosstalk: Option<CrosstalkCorrection>,
}

impl FitData {
    /// The cells a fit reported in `report` used: as measured, or less the crosstalk next
    /// to the diagonal it removed ([`super::crosstalk`]).
    pub fn as_fitted(m: &Measurement, report: &crate::material::FitReport) -> Self {
        Self::with_crosstalk(m, report.guard_nm, report.crosstalk.as_ref())
    }

    /// The cells of `m` less `crosstalk` where it was removed (its `removed` flag), else as
    /// measured; `crosstalk` is kept with them for the fit's report.
    pub fn with_crosstalk(
        m: &Measurement,
        guard_nm: f64,
        crosstalk: Option<&CrosstalkCorrection>,
    ) -> Self {
        let mut data = match crosstalk.filter(|c| c.removed) {
            Some(c) => Self::new(&crosstalk::remove(m, c), guard_nm),
            None => Self::new(m, guard_nm),
        };
        // Kept either way: the report says what was found, and why it was kept if it was.
        data.crosstalk = crosstalk.cloned();
        data
    }

    /// Gathers the cells of `m` as measured, for a guard band of `guard_nm` around the
    /// diagonal.
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
            crosstalk: None,
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

    /// The emission density e (1/nm, ∫e = 1) of emission column values `v` whose
    /// normaliser Σ v·w is `normaliser`: e_j = v_j·w_j/(Δλ_j·normaliser).
    pub fn emission_density(&self, v: &[f64], normaliser: f64) -> Vec<f64> {
        v.iter()
            .zip(&self.emission_weight)
            .zip(&self.emission_bin_widths)
            .map(|((v, ew), w)| v * ew / (w * normaliser))
            .collect()
    }

    /// S = Σ v_j·w_j and M = Σ v_j·w_j·λ_j of emission column values `v`: the emission
    /// normaliser and its first moment (M/S = λ̄e).
    pub fn emission_sum_moment(&self, v: &[f64]) -> (f64, f64) {
        let (mut sum, mut moment) = (0.0, 0.0);
        for ((v, w), l) in v.iter().zip(&self.emission_weight).zip(&self.emission_nm) {
            sum += v * w;
            moment += v * w * l;
        }
        (sum, moment)
    }

    /// Robust noise level: 1.4826 × the median absolute deviation of the anti-Stokes
    /// cells, which hold only noise on real surfaces. With fewer than ten anti-Stokes cells
    /// (a layout without them, such as the spectral EXR), or when they do not spread at
    /// all (an instrument that writes exact zeros there, or noise-free data), it is the
    /// roughness of the Stokes cells along emission instead: the spread of their second
    /// differences, which a smooth emission band hardly has (the values' own spread would
    /// read the signal as noise). A σ of 0 would make every cell infinitely significant.
    pub fn noise_sigma(&self) -> f64 {
        if self.anti_stokes.len() >= 10 {
            let sigma = robust_sigma(self.anti_stokes.iter().map(|c| c.value));
            if sigma > 0.0 {
                return sigma;
            }
        }
        roughness_sigma(&self.stokes)
            .filter(|s| *s > 0.0)
            .unwrap_or_else(|| robust_sigma(self.off_diagonal.iter().map(|c| c.value)))
    }
}

/// σ of i.i.d. noise on a smooth signal, from the robust spread of the second differences
/// v[i−1] − 2·v[i] + v[i+1] (variance 6σ²) of cells adjacent along emission (cells in
/// row-major order); `None` with fewer than ten such triples.
fn roughness_sigma(cells: &[Cell]) -> Option<f64> {
    let second_differences: Vec<f64> = cells
        .windows(3)
        .filter(|w| {
            w[0].row == w[2].row && w[1].column == w[0].column + 1 && w[2].column == w[1].column + 1
        })
        .map(|w| w[0].value - 2.0 * w[1].value + w[2].value)
        .collect();
    (second_differences.len() >= 10)
        .then(|| robust_sigma(second_differences.into_iter()) / 6f64.sqrt())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Gaussian noise of known σ on smooth emission bands (8 rows × 40 columns at 5 nm):
    /// the roughness estimate finds σ, not the bands' spread.
    #[test]
    fn roughness_sigma_finds_the_noise_on_smooth_bands() {
        let sigma = 2e-3;
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cells = Vec::new();
        for row in 0..8 {
            for column in 0..40 {
                let nm = 450.0 + 5.0 * column as f64;
                let band = 0.05 * (-((nm - 560.0) / 40.0).powi(2) / 2.0).exp();
                let gauss = (-2.0 * uniform().max(1e-300).ln()).sqrt()
                    * (2.0 * std::f64::consts::PI * uniform()).cos();
                cells.push(Cell {
                    row,
                    column,
                    value: band + sigma * gauss,
                });
            }
        }
        let estimate = roughness_sigma(&cells).unwrap();
        assert!((estimate / sigma - 1.0).abs() < 0.2, "{estimate}");
        // The values' own spread reads the band as noise.
        let spread = robust_sigma(cells.iter().map(|c| c.value));
        assert!(spread > 3.0 * sigma, "{spread}");
        // Noise-free bands: far below the band's scale.
        for c in &mut cells {
            c.value =
                0.05 * (-((450.0 + 5.0 * c.column as f64 - 560.0) / 40.0).powi(2) / 2.0).exp();
        }
        assert!(roughness_sigma(&cells).unwrap() < 2e-4);
    }

    /// An instrument that writes exact zeros below the diagonal: the anti-Stokes cells do
    /// not spread, so the noise comes from the Stokes cells' roughness (σ known).
    #[test]
    fn exact_zeros_below_the_diagonal_do_not_make_the_noise_zero() {
        let sigma = 1e-3;
        let mut spec = crate::synth::SynthSpec::preset("green-dye").unwrap();
        spec.noise_sigma = sigma;
        spec.crosstalk = 0.0;
        let (mut m, _) = spec.generate().unwrap();
        let n_em = m.emission_nm.len();
        for (i, excitation) in m.excitation_nm.iter().enumerate() {
            for (j, emission) in m.emission_nm.iter().enumerate() {
                if emission < excitation {
                    m.values[i * n_em + j] = 0.0;
                }
            }
        }
        let data = FitData::new(&m, 0.0);
        assert!(data.anti_stokes.len() >= 10);
        let estimate = data.noise_sigma();
        assert!((estimate / sigma - 1.0).abs() < 0.3, "{estimate}");
    }
}

//! Is a matrix a bispectral radiance-factor matrix or an uncalibrated EEM?
//!
//! A radiance factor is bounded by energy conservation: no cell can exceed 1 by more
//! than noise (the diagonal is a reflectance factor plus the fluorescence in the same
//! bin), and the light reradiated from one excitation wavelength, summed over the
//! emission bins, cannot exceed the light that arrived (ρ(λi) ≤ 1, model.md §3). An
//! instrument EEM in counts breaks both by orders of magnitude; its λo = λi line is
//! Rayleigh scatter, not a reflectance.

use serde::{Deserialize, Serialize};

use crate::measurement::{Measurement, Units};

/// Largest cell a radiance-factor matrix may hold (1 plus room for noise and a
/// calibration a few per cent off; the shared BFC-450 files reach 0.96).
pub const MAX_RADIANCE_FACTOR_CELL: f64 = 1.5;
/// Largest row sum (per emission bin) a radiance-factor matrix may hold: the energy law
/// ρ(λi) ≤ 1 plus the same room (the shared surface files reach 0.99).
pub const MAX_RADIANCE_FACTOR_ROW: f64 = 1.5;

/// What the user said about the units, or `Auto` to infer them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum UnitsChoice {
    /// Infer from the values (the default).
    #[default]
    Auto,
    /// Dimensionless bispectral radiance factors with a reflectance diagonal (BFC-450).
    RadianceFactor,
    /// Instrument counts (an uncalibrated EEM): shapes and a scale only.
    Arbitrary,
}

/// The verdict on a matrix's values.
#[derive(Debug, Clone, PartialEq)]
pub struct UnitsVerdict {
    /// True when the values can be radiance factors.
    pub radiance_factor: bool,
    /// The largest measured cell.
    pub max_cell: f64,
    /// The largest excitation-row sum (per emission bin, positive cells).
    pub max_row_sum: f64,
    /// The excitation wavelength of that row (nm).
    pub max_row_nm: f64,
    /// Why, in words (names the figures and the bounds).
    pub reason: String,
}

/// Judges whether `m`'s values can be radiance factors (see the module doc). A matrix
/// [`Measurement::validate`] refuses (no wavelengths, values not filling the grids, no
/// measured cell) cannot be: its verdict says why, with NaN figures.
pub fn classify(m: &Measurement) -> UnitsVerdict {
    if let Err(e) = m.validate() {
        return UnitsVerdict {
            radiance_factor: false,
            max_cell: f64::NAN,
            max_row_sum: f64::NAN,
            max_row_nm: f64::NAN,
            reason: format!("values cannot be judged: {e}"),
        };
    }
    let widths = m.emission_bin_widths();
    let diagonal = m.diagonal();
    let mut max_cell = f64::NEG_INFINITY;
    let (mut max_row_sum, mut max_row_nm) = (0.0f64, m.excitation_nm[0]);
    for (i, &ex) in m.excitation_nm.iter().enumerate() {
        let mut sum = 0.0;
        for (j, w) in widths.iter().enumerate() {
            let v = m.get(i, j);
            if !v.is_finite() {
                continue;
            }
            max_cell = max_cell.max(v);
            // Per-nm densities are integrated; the diagonal is a plain factor in both.
            let per_bin = if m.units == Units::PerNm && !diagonal.contains(&(i, j)) {
                v * w
            } else {
                v
            };
            sum += per_bin.max(0.0);
        }
        if sum > max_row_sum {
            max_row_sum = sum;
            max_row_nm = ex;
        }
    }
    let radiance_factor =
        max_cell <= MAX_RADIANCE_FACTOR_CELL && max_row_sum <= MAX_RADIANCE_FACTOR_ROW;
    let reason = if radiance_factor {
        format!(
            "values can be radiance factors: largest cell {max_cell:.3} and largest excitation-row sum {max_row_sum:.3} (at {max_row_nm} nm) are within the bounds a reflectance and energy conservation allow ({MAX_RADIANCE_FACTOR_CELL})"
        )
    } else if max_cell > MAX_RADIANCE_FACTOR_CELL {
        format!(
            "values cannot be radiance factors: the largest cell is {max_cell:.4e}, while a reflectance factor (and any one cell of a radiance-factor matrix) is at most about 1 (bound {MAX_RADIANCE_FACTOR_CELL}); read as an uncalibrated EEM in arbitrary units, so the λo = λi line is scatter, not a reflectance"
        )
    } else {
        format!(
            "values cannot be radiance factors: the excitation row at {max_row_nm} nm reradiates {max_row_sum:.3} times the incident light summed over its emission bins, while energy conservation allows at most 1 (bound {MAX_RADIANCE_FACTOR_ROW}); read as an uncalibrated EEM in arbitrary units, so the λo = λi line is scatter, not a reflectance"
        )
    };
    UnitsVerdict {
        radiance_factor,
        max_cell,
        max_row_sum,
        max_row_nm,
        reason,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn matrix(values: Vec<f64>, units: Units) -> Measurement {
        Measurement::new(
            "t",
            vec![400.0, 410.0],
            vec![400.0, 410.0, 420.0],
            values,
            units,
        )
        .unwrap()
    }

    #[test]
    fn bounds_decide() {
        // A plausible surface: reflectance 0.9 and a little fluorescence.
        let surface = matrix(vec![0.9, 0.05, 0.02, 0.0, 0.9, 0.05], Units::PerBin);
        assert!(classify(&surface).radiance_factor);
        // (values, units, what the refusal must name)
        let refused = [
            // Counts.
            (
                vec![900.0, 50.0, 20.0, 0.0, 900.0, 50.0],
                Units::PerBin,
                "largest cell",
            ),
            // Every cell below 1 but the row reradiates more than arrived.
            (vec![0.9, 0.8, 0.7, 0.0, 0.5, 0.1], Units::PerBin, "400 nm"),
            // Per nm, the same cells integrate over 10 nm bins.
            (vec![0.9, 0.08, 0.0, 0.0, 0.9, 0.0], Units::PerNm, ""),
        ];
        for (values, units, named) in refused {
            let v = classify(&matrix(values.clone(), units));
            assert!(
                !v.radiance_factor && v.reason.contains(named),
                "{values:?} {units:?}: {}",
                v.reason
            );
        }
    }
}

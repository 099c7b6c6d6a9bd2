//! Is a matrix a bispectral radiance-factor matrix or an uncalibrated EEM?
//!
//! A radiance factor is bounded by energy conservation: no cell can exceed 1 by more
//! than noise (the diagonal is a reflectance factor plus the fluorescence in the same
//! bin), and the light reradiated from one excitation wavelength, summed over the
//! emission bins, cannot exceed the light that arrived (ρ(λi) ≤ 1, model.md §3). An
//! instrument EEM in counts breaks both by orders of magnitude; its λo = λi line is
//! Rayleigh scatter, not a reflectance.
//!
//! Many instruments and spreadsheets write radiance factors ×100 (percent). Such a matrix
//! breaks the bounds like counts do, but divided by 100 it keeps them and its diagonal
//! looks like a reflectance: it dominates its rows and holds most of the signal
//! ([`classify_percent`]). Counts EEMs break the bounds by far more than a factor 100
//! (the shared staRdom and Dorrit files: row sums of 10⁴–10⁷).

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
    /// Radiance factors written ×100 (percent): read divided by 100.
    Percent,
}

/// What percent radiance factors are divided by.
pub const PERCENT: f64 = 100.0;
/// Smallest share of the rows with a measured diagonal cell in which that cell is the
/// row's largest, for a matrix to be read as percent radiance factors (the shared surface
/// files: 76–100 %; cerise pigment and yellow textile fluoresce above their reflectance
/// where they absorb).
const MIN_DOMINANT_ROWS: f64 = 0.5;
/// Smallest share of the positive signal the diagonal must hold (the shared surface
/// files: 62–98 %).
const MIN_DIAGONAL_SHARE: f64 = 0.5;
/// Smallest peak reflectance (diagonal ÷ 100) a percent matrix may have: below it the
/// matrix is more likely radiance factors a little over the bounds than a surface darker
/// than black velvet.
const MIN_PEAK_REFLECTANCE: f64 = 0.02;
/// Largest median ratio of the cell one emission step below the diagonal to the diagonal
/// cell: a reflectance is sharp (the shared surface files: medians 0.001–0.044), while a
/// Rayleigh scatter line, which can dominate an EEM's rows too, spreads over the
/// neighbouring cells by the instrument's bandwidth.
const MAX_SHOULDER: f64 = 0.25;
/// Fewest measured diagonal cells that can show a reflectance.
const MIN_DIAGONAL_CELLS: usize = 3;

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

/// The verdict on whether a matrix holds radiance factors ×100.
#[derive(Debug, Clone, PartialEq)]
pub struct PercentVerdict {
    /// True when the values look like percent radiance factors (bounds ÷ 100 and a
    /// reflectance diagonal); what `--units auto` reads ÷ 100.
    pub percent: bool,
    /// True when the values ÷ 100 keep the radiance-factor bounds and break them as they
    /// stand; what `--units percent` requires.
    pub bounds_fit: bool,
    /// Why, in words (names the figures).
    pub reason: String,
}

/// Judges whether `m` holds radiance factors written ×100 (see the module doc);
/// `verdict` is [`classify`]'s verdict on `m` as it stands.
pub fn classify_percent(m: &Measurement, verdict: &UnitsVerdict) -> PercentVerdict {
    let refuse = |bounds_fit: bool, reason: String| PercentVerdict {
        percent: false,
        bounds_fit,
        reason,
    };
    if verdict.radiance_factor {
        return refuse(
            false,
            format!(
                "the values are radiance factors as they stand (largest cell {:.3}), so ÷ 100 they would be a surface darker than any",
                verdict.max_cell
            ),
        );
    }
    if verdict.max_cell.is_nan() {
        return refuse(false, verdict.reason.clone());
    }
    let mut scaled = m.clone();
    scaled.values.iter_mut().for_each(|v| *v /= PERCENT);
    let scaled_verdict = classify(&scaled);
    if !scaled_verdict.radiance_factor {
        return refuse(
            false,
            format!(
                "even ÷ 100 the values break the radiance-factor bounds (largest cell {:.4e}, largest excitation-row sum {:.4e}; bound {MAX_RADIANCE_FACTOR_CELL})",
                scaled_verdict.max_cell, scaled_verdict.max_row_sum
            ),
        );
    }
    // The diagonal must look like a reflectance: the largest cell of most rows, most of
    // the signal, and a peak no darker than a black surface.
    let diagonal: Vec<(usize, f64)> = m
        .diagonal()
        .into_iter()
        .map(|(i, j)| (i, m.get(i, j)))
        .filter(|(_, v)| v.is_finite())
        .collect();
    if m.arbitrary_scale || diagonal.len() < MIN_DIAGONAL_CELLS {
        return refuse(
            true,
            format!(
                "÷ 100 the values keep the radiance-factor bounds, but the matrix has {} measured diagonal (λo = λi) cells{}, so nothing shows a reflectance",
                diagonal.len(),
                if m.arbitrary_scale {
                    " and its format holds counts"
                } else {
                    ""
                }
            ),
        );
    }
    let n = m.emission_nm.len();
    let positive = |row: &[f64]| {
        row.iter()
            .filter(|v| v.is_finite())
            .map(|v| v.max(0.0))
            .sum::<f64>()
    };
    let dominant = diagonal
        .iter()
        .filter(|&&(i, d)| {
            m.values[i * n..(i + 1) * n]
                .iter()
                .all(|v| !(v.is_finite() && *v > d))
        })
        .count();
    let shoulders: Vec<f64> = m
        .diagonal()
        .into_iter()
        .filter(|&(_, j)| j > 0)
        .map(|(i, j)| (m.get(i, j - 1) / m.get(i, j)).abs())
        .filter(|r| r.is_finite())
        .collect();
    let shoulder = if shoulders.is_empty() {
        0.0
    } else {
        crate::numeric::median(&shoulders)
    };
    let diagonal_signal: f64 = diagonal.iter().map(|(_, d)| d.max(0.0)).sum();
    let share = diagonal_signal / positive(&m.values);
    let peak = diagonal
        .iter()
        .map(|(_, d)| *d)
        .fold(f64::NEG_INFINITY, f64::max)
        / PERCENT;
    let dominant_share = dominant as f64 / diagonal.len() as f64;
    let figures = format!(
        "largest cell {:.1}, ÷ 100 {:.3} with largest excitation-row sum {:.3} (bound {MAX_RADIANCE_FACTOR_ROW}); the diagonal is the largest cell in {dominant} of its {} rows, holds {:.0} % of the signal, peaks at reflectance {:.3} and is sharp (the cell one step below holds {:.1} % of it in the median row)",
        verdict.max_cell,
        scaled_verdict.max_cell,
        scaled_verdict.max_row_sum,
        diagonal.len(),
        100.0 * share,
        peak,
        100.0 * shoulder
    );
    let percent = dominant_share >= MIN_DOMINANT_ROWS
        && share >= MIN_DIAGONAL_SHARE
        && peak >= MIN_PEAK_REFLECTANCE
        && shoulder <= MAX_SHOULDER;
    PercentVerdict {
        percent,
        bounds_fit: true,
        reason: if percent {
            format!("the values look like radiance factors ×100 (percent): {figures}")
        } else {
            format!(
                "÷ 100 the values keep the radiance-factor bounds, but the diagonal does not look like a reflectance (percent needs it largest in {:.0} % of its rows, {:.0} % of the signal, a peak ≥ {MIN_PEAK_REFLECTANCE} and at most {:.0} % one step below): {figures}",
                100.0 * MIN_DOMINANT_ROWS,
                100.0 * MIN_DIAGONAL_SHARE,
                100.0 * MAX_SHOULDER
            )
        },
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

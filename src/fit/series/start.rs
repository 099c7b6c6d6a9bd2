//! The closed-form start of a series fit.
//!
//! 1. Shapes: the masked non-negative rank-1 factorisation of the file with the strongest
//!    fluorescence gives a (max 1) and the emission column values.
//! 2. Per file, the least-squares scale h_j = c_j·g of those shapes on its off-diagonal
//!    cells, and its diagonal less that fluorescence, d_j = (1 − c_j·a)·r.
//! 3. With c_j = h_j/g, d_j(λ) = r(λ) − r(λ)·a(λ)·h_j/g is a straight line in h_j at every
//!    diagonal wavelength: intercept r, slope −r·a/g. The slopes over the intercepts,
//!    fitted to a over all wavelengths at once, give 1/g; then c_j = h_j/g and r by least
//!    squares. Exact on exact data; the refinement does the rest.

use super::model::{SeriesModel, SeriesParameters};
use crate::error::{Error, Result};
use crate::fit::data::FitData;
use crate::fit::init::{MAX_SWEEPS, rank_one};
use crate::fit::representation::START_KAPPA_CAP;
use crate::material::YieldForm;

/// The shapes the start takes from the strongest file.
#[derive(Debug, Clone)]
pub struct Shapes {
    /// a on the excitation grid, max 1.
    pub absorption: Vec<f64>,
    /// Emission column values, Σ v·w = 1.
    pub emission: Vec<f64>,
    /// Where a = 1.
    pub peak: usize,
}

/// The rank-1 shapes of the file whose fluorescence is strongest; an error naming the
/// files when none fluoresces.
pub fn shapes(files: &[FitData], form: YieldForm, names: &[String]) -> Result<Shapes> {
    let mut best: Option<(f64, Shapes)> = None;
    for data in files {
        let start = rank_one(data, MAX_SWEEPS);
        let row: Vec<f64> = match form {
            YieldForm::Energy => start.row.clone(),
            YieldForm::Photon => start
                .row
                .iter()
                .zip(&data.excitation_nm)
                .map(|(u, l)| u / l)
                .collect(),
        };
        let (peak, peak_value) = row
            .iter()
            .copied()
            .enumerate()
            .fold((0, 0.0), |acc, (i, x)| if x > acc.1 { (i, x) } else { acc });
        let sum: f64 = start
            .column
            .iter()
            .zip(&data.emission_weight)
            .map(|(v, w)| v * w)
            .sum();
        let strength = peak_value * sum;
        if strength > 0.0 && best.as_ref().is_none_or(|(s, _)| strength > *s) {
            best = Some((
                strength,
                Shapes {
                    absorption: row.iter().map(|x| x / peak_value).collect(),
                    emission: start.column.iter().map(|v| v / sum).collect(),
                    peak,
                },
            ));
        }
    }
    best.map(|(_, shapes)| shapes).ok_or_else(|| {
        Error::Fit(format!(
            "{}: no file shows fluorescence off the diagonal; a concentration series needs a fluorescent material",
            names.join(", ")
        ))
    })
}

/// The closed-form start on `model` from `shapes` (see the module doc); an error naming
/// the files when their diagonals do not separate c from Q.
pub fn closed_form(
    model: &SeriesModel<'_>,
    shapes: &Shapes,
    names: &[String],
) -> Result<SeriesParameters> {
    let n = model.normaliser(&shapes.absorption, &shapes.emission).value;
    let a = &shapes.absorption;
    let shape =
        |row: usize, column: usize| a[row] * model.row_factor(row) * shapes.emission[column] / n;
    // h_j = c_j·g: the scale of the shapes in file j.
    let scales: Vec<f64> = model
        .files
        .iter()
        .map(|data| {
            let (mut cross, mut square) = (0.0, 0.0);
            for c in &data.off_diagonal {
                let s = shape(c.row, c.column);
                cross += c.value * s;
                square += s * s;
            }
            if square > 0.0 {
                (cross / square).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    // Diagonal less fluorescence, per position: (file j, d_j) over the files measuring it.
    let mut lines: Vec<Vec<(usize, f64)>> = vec![Vec::new(); model.positions.len()];
    for (j, data) in model.files.iter().enumerate() {
        for (c, &p) in data.diagonal.iter().zip(&model.diagonal_index[j]) {
            lines[p].push((j, c.value - scales[j] * shape(c.row, c.column)));
        }
    }
    // Slope −r·a/g and intercept r per position: Σ (slope + intercept·a/g)² is least at
    // 1/g = −Σ slope·intercept·a / Σ (intercept·a)².
    let (mut num, mut den) = (0.0, 0.0);
    for (&(row, _), points) in model.positions.iter().zip(&lines) {
        let points: Vec<(f64, f64)> = points.iter().map(|&(j, d)| (scales[j], d)).collect();
        if let Some((slope, intercept)) = straight_line(&points) {
            num -= slope * intercept * a[row];
            den += (intercept * a[row]).powi(2);
        }
    }
    let inverse_yield = num / den;
    if !(den > 0.0 && inverse_yield.is_finite() && inverse_yield > 0.0) {
        return Err(Error::Fit(format!(
            "{}: the diagonals do not fall where the material absorbs as the fluorescence rises, so c cannot be separated from Q; check that the files hold one material at different concentrations, and measure concentrations that differ more (e.g. by a factor of 3 or more) on a diagonal that includes the absorption band",
            names.join(", ")
        )));
    }
    let yield_fraction = (1.0 / inverse_yield).min(START_KAPPA_CAP);
    let concentrations: Vec<f64> = scales
        .iter()
        .map(|h| (h / yield_fraction).clamp(0.0, START_KAPPA_CAP))
        .collect();
    // r by least squares given c: d_j = r·(1 − c_j·a).
    let reflectance = model
        .positions
        .iter()
        .zip(&lines)
        .map(|(&(row, _), points)| {
            let (mut cross, mut square) = (0.0, 0.0);
            for &(j, d) in points {
                let transmitted = 1.0 - concentrations[j] * a[row];
                cross += d * transmitted;
                square += transmitted * transmitted;
            }
            if square > 0.0 {
                (cross / square).clamp(0.0, START_KAPPA_CAP)
            } else {
                0.5
            }
        })
        .collect();
    Ok(SeriesParameters {
        absorption: shapes.absorption.clone(),
        emission: shapes.emission.clone(),
        reflectance,
        yield_fraction,
        concentrations,
    })
}

/// Least-squares (slope, intercept) of points (x, y); None with fewer than two distinct x.
fn straight_line(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    if points.len() < 2 {
        return None;
    }
    let n = points.len() as f64;
    let mean_x = points.iter().map(|p| p.0).sum::<f64>() / n;
    let mean_y = points.iter().map(|p| p.1).sum::<f64>() / n;
    let spread: f64 = points.iter().map(|p| (p.0 - mean_x).powi(2)).sum();
    if !spread.is_finite() || spread <= 1e-24 * mean_x.powi(2).max(1e-300) {
        return None;
    }
    let slope = points
        .iter()
        .map(|p| (p.0 - mean_x) * (p.1 - mean_y))
        .sum::<f64>()
        / spread;
    Some((slope, mean_y - slope * mean_x))
}

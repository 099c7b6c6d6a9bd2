//! Whether the matrix can tell a compact candidate from the grid model it started from.
//!
//! A candidate that meets the colour bound may do so because it follows the material, or
//! because its colour term pulled it onto the measured colour while its bands miss the
//! matrix (bands of the wrong shape, a second band it lacks). Against the truth the second
//! kind is worse than the grid model (one component, every sample free), which is nearer
//! the truth whenever one fluorophore made the matrix. The nested-model test of least
//! squares tells them apart: the candidate's residual above the grid model's, in units of
//! the noise, against its χ² spread.

use std::collections::BTreeMap;

use crate::material::Material;
use crate::measurement::Measurement;
use crate::model::predict_like;

use super::super::data::FitData;
use super::{Fitted, worst};

/// Standard deviations of the χ² spread a candidate's extra residual may exceed its mean by
/// and still count as noise.
pub const MATRIX_TEST_SIGMAS: f64 = 3.0;

/// The test of a compact candidate against the grid model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct MatrixTest {
    /// (RSS of the candidate − RSS of the grid model) / s², s² the larger of σ² and the
    /// residual variance the grid model leaves per degree of freedom.
    pub statistic: f64,
    /// Parameters the grid model has beyond the candidate (at least 1).
    pub degrees: f64,
    /// The statistic's largest value still noise: degrees + 3·√(2·degrees).
    pub limit: f64,
}

impl MatrixTest {
    /// Whether the candidate misses the matrix by more than noise where the grid model
    /// does not.
    pub fn rejects(&self) -> bool {
        self.statistic > self.limit
    }

    /// `statistic`, `limit` and `degrees` in words.
    pub fn describe(&self) -> String {
        format!(
            "its matrix residual exceeds the grid model's by {:.0} σ² against at most {:.0} for noise ({:.0} fewer parameters)",
            self.statistic, self.limit, self.degrees
        )
    }
}

/// The sum of squared residuals of `material` over the cells of `data` (off-diagonal and
/// diagonal, as the fits count them).
pub(super) fn residual_sum_of_squares(material: &Material, m: &Measurement, data: &FitData) -> f64 {
    let predicted = predict_like(material, m);
    data.off_diagonal
        .iter()
        .chain(&data.diagonal)
        .map(|c| (c.value - predicted.get(c.row, c.column)).powi(2))
        .filter(|r| r.is_finite())
        .sum()
}

/// The test of a candidate with `candidate_parameters` leaving `candidate_rss` against the
/// grid model with `grid_parameters` leaving `grid_rss`, over `cells` cells at noise level
/// `sigma`. Where the grid model leaves more than σ² per degree of freedom (structure no
/// one-component model explains, or σ estimated low), that variance is the unit: the test
/// then asks only what the candidate loses beyond the grid model.
pub(super) fn against_grid(
    candidate_rss: f64,
    candidate_parameters: usize,
    grid_rss: f64,
    grid_parameters: usize,
    cells: usize,
    sigma: f64,
) -> MatrixTest {
    let free = cells.saturating_sub(grid_parameters).max(1) as f64;
    let variance = (sigma * sigma).max(grid_rss / free).max(1e-300);
    let degrees = (grid_parameters as f64 - candidate_parameters as f64).max(1.0);
    MatrixTest {
        statistic: (candidate_rss - grid_rss) / variance,
        degrees,
        limit: degrees + MATRIX_TEST_SIGMAS * (2.0 * degrees).sqrt(),
    }
}

/// What the matrix test makes of a candidate that met the bound.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Verdict {
    /// The matrix cannot tell it from the grid model (or the grid fit misses a bound the
    /// candidate meets): keep it.
    Keep,
    /// The matrix tells it from the grid model, which leaves no more than noise and meets
    /// every bound too: keep the grid fit, for this reason.
    KeepGrid(String),
    /// The matrix tells it from the grid model, and the grid model leaves structure one
    /// component cannot explain (a second fluorophore): look on up the ladder for a
    /// candidate that passes, for this reason.
    LookFurther(String),
}

/// The grid model's mean squared residual, in units of σ², over the off-diagonal cells
/// more than one emission step from the diagonal, above which it counts as leaving
/// structure ([`Verdict::LookFurther`]). Measured on `fluorite class` (five seeds, every
/// candidate the test judged): 0.46–1.58 where one fluorophore made the matrix (one case
/// at 15.8, seed 11 case089), 0.68–724 on two-dye truths (a weak second dye leaves
/// nothing). Cells next to the diagonal are left out: what remains of the crosstalk there
/// (up to 350 σ² per cell on one-dye truths) says nothing about a second fluorophore.
pub const GRID_STRUCTURE_VARIANCE: f64 = 3.0;

/// The grid model's mean squared residual in units of σ² over the off-diagonal cells of
/// `data` more than one emission step from their excitation wavelength (where the
/// crosstalk next to the diagonal sits, in rows with a diagonal cell and in rows whose
/// excitation lies off the emission grid).
fn structure_left(base: &Material, m: &Measurement, data: &FitData, sigma: f64) -> f64 {
    let predicted = predict_like(base, m);
    let em = &m.emission_nm;
    let step = |j: usize| {
        let below = j.checked_sub(1).map(|b| em[j] - em[b]);
        let above = em.get(j + 1).map(|a| a - em[j]);
        below.into_iter().chain(above).fold(0.0f64, f64::max)
    };
    let (sum, count) = data
        .off_diagonal
        .iter()
        .filter(|c| (em[c.column] - m.excitation_nm[c.row]).abs() > step(c.column) + 1e-6)
        .map(|c| (c.value - predicted.get(c.row, c.column)).powi(2))
        .filter(|r| r.is_finite())
        .fold((0.0, 0usize), |(s, n), r| (s + r, n + 1));
    sum / count.max(1) as f64 / (sigma * sigma).max(1e-300)
}

/// The matrix test of `candidate`, which met every light's bound in `light_bounds`, against
/// the grid fit `base` it started from, on the cells `data` of `m` at noise level `sigma`.
pub(super) fn judge(
    candidate: &Fitted,
    base: &Material,
    m: &Measurement,
    data: &FitData,
    sigma: f64,
    lights: &[crate::colour::Light],
    light_bounds: &BTreeMap<String, f64>,
) -> Verdict {
    let (Some(report), Some(candidate_report)) =
        (base.fit.as_ref(), candidate.material.fit.as_ref())
    else {
        return Verdict::Keep;
    };
    let test = against_grid(
        residual_sum_of_squares(&candidate.material, m, data),
        candidate_report.parameter_count,
        residual_sum_of_squares(base, m, data),
        report.parameter_count,
        data.off_diagonal.len() + data.diagonal.len(),
        sigma,
    );
    if !test.rejects() {
        return Verdict::Keep;
    }
    let left = structure_left(base, m, data, sigma);
    let name = candidate.spec.name();
    if left > GRID_STRUCTURE_VARIANCE {
        return Verdict::LookFurther(format!(
            "{name} met the bound, but {}: pulled onto the measured colour, its bands miss the matrix; the grid model leaves {left:.1} σ² per cell away from the diagonal (structure one fluorophore cannot explain), so the search went on",
            test.describe()
        ));
    }
    let grid_meets = lights.iter().all(|l| {
        let limit = light_bounds.get(&l.name).copied().unwrap_or(f64::INFINITY);
        report
            .delta_e2000
            .get(&l.name)
            .is_some_and(|de| *de <= limit)
    });
    if !grid_meets {
        return Verdict::Keep;
    }
    Verdict::KeepGrid(format!(
        "kept the grid fit: {name} met the bound, but {}: pulled onto the measured colour, its bands miss the matrix; the grid model leaves {left:.1} σ² per cell away from the diagonal and meets the bound too (worst ΔE2000 {:.2})",
        test.describe(),
        worst(&report.delta_e2000)
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_candidate_losing_only_noise_passes_and_one_losing_structure_fails() {
        // 2000 cells at σ = 1e-3; the grid model (130 parameters) leaves pure noise.
        let sigma: f64 = 1e-3;
        let grid_rss = (2000.0 - 130.0) * sigma * sigma;
        // 13 parameters: 117 fewer, so χ²(117) has mean 117 and spread √234 ≈ 15.3.
        let noise_only = against_grid(
            grid_rss + 117.0 * sigma * sigma,
            13,
            grid_rss,
            130,
            2000,
            sigma,
        );
        assert!(!noise_only.rejects(), "{noise_only:?}");
        assert!((noise_only.limit - (117.0 + 3.0 * 234f64.sqrt())).abs() < 1e-9);
        let structure = against_grid(
            grid_rss + 200.0 * sigma * sigma,
            13,
            grid_rss,
            130,
            2000,
            sigma,
        );
        assert!(structure.rejects(), "{structure:?}");
    }

    #[test]
    fn structure_the_grid_model_leaves_widens_the_unit() {
        // The grid model leaves 4 σ² per degree of freedom: a loss of 300 σ² is 75 units.
        let sigma: f64 = 1e-3;
        let grid_rss = 4.0 * (2000.0 - 130.0) * sigma * sigma;
        let t = against_grid(
            grid_rss + 300.0 * sigma * sigma,
            13,
            grid_rss,
            130,
            2000,
            sigma,
        );
        assert!((t.statistic - 75.0).abs() < 1e-9, "{t:?}");
        assert!(!t.rejects());
    }

    #[test]
    fn a_candidate_closer_than_the_grid_model_passes() {
        // Two components can fit a two-fluorophore matrix better than the grid model.
        let t = against_grid(1.0, 40, 5.0, 130, 2000, 1e-3);
        assert!(t.statistic < 0.0 && !t.rejects());
    }
}

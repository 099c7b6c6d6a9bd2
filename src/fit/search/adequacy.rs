//! Whether the matrix can tell a compact candidate from the grid model it started from.
//!
//! A candidate that meets the colour bound may do so because it follows the material, or
//! because its colour term pulled it onto the measured colour while its bands miss the
//! matrix (bands of the wrong shape, a second band it lacks). Against the truth the second
//! kind is worse than the grid model (one component, every sample free), which is nearer
//! the truth whenever one fluorophore made the matrix. The nested-model test of least
//! squares tells them apart: the candidate's residual above the grid model's, in units of
//! the noise, against its χ² spread.
//!
//! The grid model is the better answer only where one fluorophore made the matrix. Where
//! its residual holds a second one (a significant non-negative rank-1 component, the
//! question the grid fit asks of a matrix before it fits any fluorescence), the search
//! looks on among two-component models instead.

use crate::material::Material;
use crate::measurement::Measurement;
use crate::model::predict_like;

use super::super::assess::{SECOND_FLUOROPHORE_ENERGY, second_fluorophore_energy};
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

/// The sum of squared residuals of `predicted` (a model's matrix on the measurement's
/// grids) over the cells of `data` (off-diagonal and diagonal, as the fits count them).
fn residual_sum_of_squares(predicted: &Measurement, data: &FitData) -> f64 {
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
    let variance = noise_unit(grid_rss, grid_parameters, cells, sigma);
    let degrees = (grid_parameters as f64 - candidate_parameters as f64).max(1.0);
    MatrixTest {
        statistic: (candidate_rss - grid_rss) / variance,
        degrees,
        limit: noise_limit(degrees),
    }
}

/// The most χ² (in the matrix test's unit) that noise gives `degrees` degrees of
/// freedom: their mean plus [`MATRIX_TEST_SIGMAS`] standard deviations.
pub(super) fn noise_limit(degrees: f64) -> f64 {
    degrees + MATRIX_TEST_SIGMAS * (2.0 * degrees).sqrt()
}

/// The matrix test's unit of squared residual: σ², or what the grid model with
/// `grid_parameters` leaves per degree of freedom over `cells` cells where that is more.
fn noise_unit(grid_rss: f64, grid_parameters: usize, cells: usize, sigma: f64) -> f64 {
    let free = cells.saturating_sub(grid_parameters).max(1) as f64;
    (sigma * sigma).max(grid_rss / free).max(1e-300)
}

/// [`noise_unit`] of the grid fit `base`, whose matrix on the measurement's grids is
/// `predicted`, over the cells `data` at noise level `sigma`: the unit the reflectance
/// form is judged in too (`reflectance::reflectance_form`).
pub(super) fn grid_noise_unit(
    base: &Material,
    predicted: &Measurement,
    data: &FitData,
    sigma: f64,
) -> f64 {
    let rss = residual_sum_of_squares(predicted, data);
    let parameters = base.fit.as_ref().map_or(0, |r| r.parameter_count);
    noise_unit(
        rss,
        parameters,
        data.off_diagonal.len() + data.diagonal.len(),
        sigma,
    )
}

/// How the matrix test's words begin where it keeps the grid fit.
pub(super) const KEPT_GRID: &str = "kept the grid fit: ";

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

/// The grid fit as the matrix test sees it: what it leaves of the matrix, and whether it
/// meets the search's bounds. It depends on the grid fit alone, so a search computes it
/// once, however many candidates it judges.
pub(super) struct GridReference {
    /// Its predicted matrix's residual sum of squares over the fitted cells.
    rss: f64,
    /// Its free parameters.
    parameters: usize,
    /// [`second_fluorophore_energy`] of its residual.
    second: f64,
    /// Whether it meets every light's bound of the search (or misses only by the
    /// crosstalk it removed, under the lights of `crosstalk_lights`).
    meets_bounds: bool,
    /// The lights it misses only by the crosstalk next to the diagonal it removed (within
    /// the bound of the cells it fitted; `crosstalk_check::crosstalk_explained`).
    crosstalk_lights: Vec<String>,
    /// Its largest ΔE2000 against the measurement.
    worst: f64,
}

impl GridReference {
    /// Its BIC on the search's cells `data` at noise level `sigma`, as the candidates'
    /// (the grid fit's own report may hold it on other cells: the crosstalk it kept).
    pub fn bic(&self, sigma: f64, data: &FitData) -> f64 {
        super::super::assess::bic(self.rss, sigma, self.parameters, data)
    }

    /// The grid fit `base` of `m`'s cells `data` at noise level `sigma`, its matrix on
    /// `m`'s grids `predicted` (`predict_like`); `meets_bounds` as the search judged its
    /// ΔE2000, `crosstalk_lights` the lights it misses only by the crosstalk it removed.
    pub fn new(
        base: &Material,
        predicted: &Measurement,
        m: &Measurement,
        data: &FitData,
        sigma: f64,
        meets_bounds: bool,
        crosstalk_lights: Vec<String>,
    ) -> Self {
        let report = base.fit.as_ref();
        GridReference {
            rss: residual_sum_of_squares(predicted, data),
            parameters: report.map_or(0, |r| r.parameter_count),
            second: second_fluorophore_energy(predicted, m, data, sigma),
            meets_bounds,
            crosstalk_lights,
            worst: report.map_or(f64::NAN, |r| worst(&r.delta_e2000)),
        }
    }
}

/// The matrix test of `candidate`, which met every light's bound, against the grid fit
/// `grid` it started from, on the cells `data` of `m` at noise level `sigma`.
pub(super) fn judge(
    candidate: &Fitted,
    grid: &GridReference,
    m: &Measurement,
    data: &FitData,
    sigma: f64,
) -> Verdict {
    let Some(candidate_report) = candidate.material.fit.as_ref() else {
        return Verdict::Keep;
    };
    let second = grid.second;
    let name = candidate.spec.name();
    // One component cannot take what one component's grid model leaves, however little it
    // loses beyond that model (where the grid model leaves a second fluorophore, the test
    // below measures in its residual's units and passes such a candidate).
    if second > SECOND_FLUOROPHORE_ENERGY && candidate.spec.components == 1 {
        return Verdict::LookFurther(format!(
            "{name} met the bound, but what the grid model leaves away from the diagonal holds a rank-1 component of {second:.1} × σ²(√m + √n)² (a second fluorophore, beyond the {SECOND_FLUOROPHORE_ENERGY} noise reaches), so the search went on"
        ));
    }
    // The delivered material's residual, not the solver's from the same parameters: the
    // material is them tabulated, its r lowered where ρ passes 1 between samples, and that
    // moves the residual (CIBA12's photon forms by 37–136 σ², as much as the limit).
    let test = against_grid(
        residual_sum_of_squares(&predict_like(&candidate.material, m), data),
        candidate_report.parameter_count,
        grid.rss,
        grid.parameters,
        data.off_diagonal.len() + data.diagonal.len(),
        sigma,
    );
    if !test.rejects() {
        return Verdict::Keep;
    }
    if second > SECOND_FLUOROPHORE_ENERGY {
        return Verdict::LookFurther(format!(
            "{name} met the bound, but {}: pulled onto the measured colour, its bands miss the matrix; what the grid model leaves away from the diagonal holds a rank-1 component of {second:.1} × σ²(√m + √n)² (a second fluorophore, beyond the {SECOND_FLUOROPHORE_ENERGY} noise reaches), so the search went on",
            test.describe()
        ));
    }
    if !grid.meets_bounds {
        return Verdict::Keep;
    }
    let meets = if grid.crosstalk_lights.is_empty() {
        "it meets the bound too".to_string()
    } else {
        format!(
            "it meets the bound too, bar {} where it misses the measured colour only by the crosstalk next to the diagonal it removed (within the bound of the cells it fitted)",
            grid.crosstalk_lights.join(", ")
        )
    };
    Verdict::KeepGrid(format!(
        "{KEPT_GRID}{name} met the bound, but {}: pulled onto the measured colour, its bands miss the matrix; what the grid model leaves holds no second fluorophore ({second:.1} × σ²(√m + √n)²) and {meets} (worst ΔE2000 {:.2} against the measured colour)",
        test.describe(),
        grid.worst
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

//! The reflectance the search's candidates share: the lowest sigmoid-polynomial degree
//! that keeps the grid fit's colour (and, under --noise-aware-bound, fits its diagonal
//! within the noise), and the weights that make its fit a fit of the diagonal.

use crate::material::Material;
use crate::measurement::Measurement;
use crate::parametric::fit::fit_sigmoid_polynomial;

use super::super::assess;
use super::super::data::FitData;
use super::ReflectanceForm;
use super::adequacy::noise_limit;

/// Highest degree of a sigmoid-polynomial reflectance the search tries before it falls
/// back to a tabulated reflectance.
pub const MAX_REFLECTANCE_DEGREE: usize = 12;

/// Share of the ΔE2000 bound the reflectance alone may use when its degree is chosen.
pub(super) const REFLECTANCE_SHARE: f64 = 0.5;

/// The reflectance form for the search: the lowest sigmoid-polynomial degree whose
/// diagonal, with the tabulated fit's fluorescence, stays within `budget` ΔE2000 of the
/// tabulated fit under every light and, given `diagonal_noise` (under --noise-aware-bound:
/// the cells, the grid fit's matrix on the measurement's grids and the noise level σ),
/// within the noise of the tabulated fit's diagonal in the matrix test's unit
/// ([`within_diagonal_noise`]); tabulated when no degree up to [`MAX_REFLECTANCE_DEGREE`]
/// does.
///
/// The noise-aware search tests every candidate against the grid model on the matrix,
/// and a reflectance the diagonal's own noise rejects fails that test for every
/// candidate alike: a sharp reflectance edge (a sigmoid 10 nm wide) that degree 11 meets
/// in colour misses the diagonal by 1,699 σ² against 52 for noise, and `fluorite class
/// --seed 66` case051 (one dye, σ 1.7·10⁻³) kept its grid fit, 4.41 from the truth,
/// where gaussian:1x1+rt ends 1.71 from it. Over 81 class seeds the default moved 1,087
/// fits nearer the truth and 824 further (docs/results.md, session 32).
pub(super) fn reflectance_form(
    base: &Material,
    m: &Measurement,
    lights: &[crate::colour::Light],
    budget: f64,
    diagonal_noise: Option<(&FitData, &Measurement, f64)>,
) -> ReflectanceForm {
    let nm = &base.reflectance.wavelength_nm;
    let r = &base.reflectance.value;
    let reference = assess::predicted_labs(base, m, lights);
    let weights = diagonal_weights(base);
    // The diagonal noise test counts the measured diagonal cells only: the grid fit
    // interpolates r where the file holds none, and those samples carry no noise.
    let measured: Vec<bool> = match diagonal_noise {
        Some((data, ..)) if data.diagonal_positions.len() == r.len() => data
            .diagonal_positions
            .iter()
            .map(|&(row, column)| {
                data.diagonal
                    .iter()
                    .any(|c| c.row == row && c.column == column)
            })
            .collect(),
        _ => vec![true; r.len()],
    };
    let unit = diagonal_noise.map(|(data, predicted, sigma)| {
        super::adequacy::grid_noise_unit(base, predicted, data, sigma)
    });
    for degree in 1..=MAX_REFLECTANCE_DEGREE {
        let Ok(fit) = fit_sigmoid_polynomial(nm, r, Some(&weights), degree) else {
            continue;
        };
        let mut candidate = base.clone();
        candidate.reflectance.value = nm.iter().map(|&l| fit.form.eval(l)).collect();
        let lab = assess::predicted_labs(&candidate, m, lights);
        let ok = reference
            .iter()
            .zip(&lab)
            .all(|(a, b)| crate::colour::delta_e2000(*a, *b) <= budget);
        let fits_diagonal = || {
            unit.is_none_or(|unit| {
                within_diagonal_noise(
                    &candidate.reflectance.value,
                    r,
                    &weights,
                    &measured,
                    unit,
                    degree + 1,
                )
            })
        };
        if ok && fits_diagonal() {
            return ReflectanceForm::Polynomial(degree);
        }
    }
    ReflectanceForm::Tabulated
}

/// Whether the reflectance `form` (sampled where `tabulated` is) stays within the noise
/// of the tabulated fit's diagonal: Σ w·(form − tabulated)²/`unit` over the `measured`
/// samples the diagonal sees (w from [`diagonal_weights`] > 0, turning a reflectance
/// difference into the diagonal cell's) at most n − p + 3 × √(2(n − p)) for those n
/// samples and the form's `parameters` p: the matrix test's limit for p parameters fewer,
/// in its unit (σ², or the grid model's residual per degree of freedom where that is
/// more).
fn within_diagonal_noise(
    form: &[f64],
    tabulated: &[f64],
    weights: &[f64],
    measured: &[bool],
    unit: f64,
    parameters: usize,
) -> bool {
    if !(unit.is_finite() && unit > 0.0) {
        return true;
    }
    let (mut chi2, mut samples) = (0.0, 0usize);
    for (((f, t), w), seen) in form.iter().zip(tabulated).zip(weights).zip(measured) {
        if *seen && *w > 0.0 {
            chi2 += w * (f - t).powi(2) / unit;
            samples += 1;
        }
    }
    chi2 <= noise_limit((samples as f64 - parameters as f64).max(1.0))
}

/// Weights making a reflectance fit a fit of the diagonal d = (1 − Σc·a)·r: where the
/// fluorophores absorb nearly everything r is barely observable.
pub(super) fn diagonal_weights(material: &Material) -> Vec<f64> {
    material
        .reflectance
        .wavelength_nm
        .iter()
        .map(|&l| (1.0 - material.absorbed(l)).max(0.0).powi(2))
        .collect()
}

//! The reflectance the search's candidates share: the lowest sigmoid-polynomial degree
//! that keeps the grid fit's colour, and the weights that make its fit a fit of the
//! diagonal.

use crate::material::Material;
use crate::measurement::Measurement;
use crate::parametric::fit::fit_sigmoid_polynomial;

use super::super::assess;
use super::ReflectanceForm;

/// Highest degree of a sigmoid-polynomial reflectance the search tries before it falls
/// back to a tabulated reflectance.
pub const MAX_REFLECTANCE_DEGREE: usize = 12;

/// Share of the ΔE2000 bound the reflectance alone may use when its degree is chosen.
pub(super) const REFLECTANCE_SHARE: f64 = 0.5;

/// The reflectance form for the search: the lowest sigmoid-polynomial degree whose
/// diagonal, with the tabulated fit's fluorescence, stays within `budget` ΔE2000 of the
/// tabulated fit under every light and, given the cells' noise σ (`diagonal_sigma`,
/// under --noise-aware-bound), within that noise of the tabulated fit's diagonal
/// ([`within_diagonal_noise`]); tabulated when no degree up to
/// [`MAX_REFLECTANCE_DEGREE`] does.
///
/// The noise-aware search tests every candidate against the grid model on the matrix,
/// and a reflectance the diagonal's own noise rejects fails that test for every
/// candidate alike: a sharp reflectance edge (a sigmoid 10 nm wide) that degree 11 meets
/// in colour misses the diagonal by 1,841 σ² against 52 for noise, and `fluorite class
/// --seed 66` case051 (one dye, σ 1.7·10⁻³) kept its grid fit, 4.41 from the truth,
/// where gaussian:1x1+rt ends 1.71 from it. Over 81 class seeds the default moved 1,137
/// fits nearer the truth and 875 further (docs/results.md, session 32).
pub(super) fn reflectance_form(
    base: &Material,
    m: &Measurement,
    lights: &[crate::colour::Light],
    budget: f64,
    diagonal_sigma: Option<f64>,
) -> ReflectanceForm {
    let nm = &base.reflectance.wavelength_nm;
    let r = &base.reflectance.value;
    let reference = assess::predicted_labs(base, m, lights);
    let weights = diagonal_weights(base);
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
        let fits_diagonal = diagonal_sigma.is_none_or(|sigma| {
            within_diagonal_noise(&candidate.reflectance.value, r, &weights, sigma, degree + 1)
        });
        if ok && fits_diagonal {
            return ReflectanceForm::Polynomial(degree);
        }
    }
    ReflectanceForm::Tabulated
}

/// Whether the reflectance `form` (sampled where `tabulated` is) stays within the cells'
/// noise `sigma` of the tabulated fit's: Σ w·(form − tabulated)²/σ² (w from
/// [`diagonal_weights`], turning a reflectance difference into the diagonal cell's) at
/// most the χ² spread of the samples the form has fewer than the table, n − p + 3 ×
/// √(2(n − p)) for its `parameters` p: the matrix test's allowance for the same
/// parameters.
fn within_diagonal_noise(
    form: &[f64],
    tabulated: &[f64],
    weights: &[f64],
    sigma: f64,
    parameters: usize,
) -> bool {
    if !(sigma.is_finite() && sigma > 0.0) {
        return true;
    }
    let chi2 = form
        .iter()
        .zip(tabulated)
        .zip(weights)
        .map(|((f, t), w)| w * (f - t).powi(2))
        .sum::<f64>()
        / (sigma * sigma);
    let degrees = (tabulated.len() as f64 - parameters as f64).max(1.0);
    chi2 <= degrees + 3.0 * (2.0 * degrees).sqrt()
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

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
/// tabulated fit under every light; tabulated when no degree up to
/// [`MAX_REFLECTANCE_DEGREE`] does.
pub(super) fn reflectance_form(
    base: &Material,
    m: &Measurement,
    lights: &[crate::colour::Light],
    budget: f64,
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
        if ok {
            return ReflectanceForm::Polynomial(degree);
        }
    }
    ReflectanceForm::Tabulated
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

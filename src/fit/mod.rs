//! Fitting the diffuse fluorescent BBRRDF to a reradiation matrix.
//!
//! [`fit`] dispatches: the default fit as needed ([`escalate`]: the grid fit, escalated to
//! the search when one fluorophore does not explain the matrix), the grid (tabulated) fit,
//! or the parametric model search. Below it, one concern per file:
//!
//! - `options`: [`FitOptions`], [`Solver`], [`Start`], [`YieldChoice`], [`FitOutcome`].
//! - [`data`]: the cells a fit uses, gathered once (and `fill_missing` for diagonals).
//! - [`init`]: the closed-form start (masked non-negative rank-1 factorisation).
//! - [`objective`] and [`representation`]: the grid model's cost, gradient and Jacobian
//!   in either yield form, with the colour term; the parameterisation that keeps every
//!   iterate feasible.
//! - [`solve`]: L-BFGS, Gauss-Newton and Nelder-Mead, each run by the one optimiser
//!   runner ([`crate::optimise::run`]).
//! - `tabulated`: the grid pipeline (start, refinement in one or both yield forms, the
//!   noise bootstrap); `grid_material`: its spectra turned into a material, a plain
//!   reflector or shapes.
//! - [`parametric`] and [`search`]: the band-and-sigmoid models and the search for the
//!   smallest one meeting a ΔE2000 bound (it starts from the grid fit).
//! - [`assess`] and [`checks`]: accuracy against the measurement as measured, BIC, and the
//!   warnings of the failure regimes.
//! - [`series`]: the joint fit of a surface concentration series (shared r, a, e and
//!   yield, one c per file), which separates c from Q.
//! - [`joint`]: the joint fit of a set of prepared EEMs ([`crate::eem`]): non-negative
//!   PARAFAC, shapes shared by the samples and a score per sample, judged by core
//!   consistency and split-half, and matched to known concentrations.

pub mod assess;
pub mod checks;
mod colour_term;
pub mod crosstalk;
mod crosstalk_check;
pub mod data;
mod dense_nmf;
pub mod escalate;
mod grid_material;
pub mod init;
pub mod joint;
pub mod objective;
mod options;
pub mod parametric;
mod prune;
pub mod representation;
pub mod search;
pub mod series;
pub mod solve;
mod start;
mod tabulated;

use std::time::Instant;

use crate::colour::{Light, PatchColorimeter, delta_e2000};
use crate::error::{Error, Result};
use crate::material::{
    FitReport, Fluorophore, FluorophoreShapes, Material, SHAPES_SCHEMA, YieldForm,
};
use crate::measurement::Measurement;
use crate::measurement::Units;
use crate::spectrum::Spectrum;

use data::{FitData, fill_missing};
use objective::{DiagonalRegime, Objective};
use representation::{GridSpectra, Representation, Tabulated};

use options::validate_options;
pub use options::*;
use representation::START_KAPPA_CAP;
use tabulated::fit_checked;

/// Fits the model to `m`.
pub fn fit(m: &Measurement, options: &FitOptions) -> Result<FitOutcome> {
    let mut outcome = match options.model {
        ModelChoice::Tabulated => fit_checked(m, options, true, true),
        ModelChoice::AsNeeded => escalate::fit_as_needed(m, options),
        _ => {
            validate_options(options)?;
            search::fit_model(m, options)
        }
    }?;
    if let FitOutcome::Material(material) = &mut outcome {
        // The grid fit records it itself from its own cells and colour term, when it can.
        let recorded = options.model == ModelChoice::Tabulated
            && material
                .fit
                .as_ref()
                .is_some_and(|r| !r.delta_e2000_noise.is_empty());
        if !recorded {
            record_colour_noise(m, material, &options.lights);
        }
    }
    Ok(outcome)
}

/// Records in `material`'s report how well the measurement knows its own colour under
/// each light the fit was judged under ([`assess::colour_noise_delta_e2000`]), so that a
/// reported ΔE2000 can be read against it.
fn record_colour_noise(m: &Measurement, material: &mut Material, given: &[Light]) {
    let Some((lights, sigma)) = noise_lights(material, given) else {
        return;
    };
    let data = match material.fit.as_ref() {
        Some(report) => FitData::as_fitted(m, report),
        None => FitData::new(m, 0.0),
    };
    let noise = assess::colour_noise_delta_e2000(m, material, &data, &lights, sigma);
    set_colour_noise(material, &lights, noise);
}

/// The lights [`record_colour_noise`] judges `material`'s colour noise under (those of its
/// report's ΔE2000, found in `given` or built in) and the noise σ, or None when there is
/// nothing to record.
fn noise_lights(material: &Material, given: &[Light]) -> Option<(Vec<Light>, f64)> {
    let report = material.fit.as_ref()?;
    let sigma = report.noise_sigma;
    if report.delta_e2000.is_empty() || !(sigma.is_finite() && sigma > 0.0) {
        return None;
    }
    let lights: Vec<Light> = report
        .delta_e2000
        .keys()
        .filter_map(|name| {
            given
                .iter()
                .find(|l| &l.name == name)
                .cloned()
                .or_else(|| Light::builtin(name))
        })
        .collect();
    (lights.len() == report.delta_e2000.len()).then_some((lights, sigma))
}

/// Stores `noise` (per light of `lights`) as the report's `delta_e2000_noise`.
fn set_colour_noise(material: &mut Material, lights: &[Light], noise: Vec<f64>) {
    let names = lights.iter().map(|l| l.name.clone());
    if let Some(report) = material.fit.as_mut() {
        report.delta_e2000_noise = names.zip(noise).collect();
    }
}

/// [`record_colour_noise`] on the fit's own cells `data` (of `m` itself, unscaled):
/// from its colour term's noise covariance and measured colours (`reference`, per light of
/// `options.lights`) where they are the figure's (every cell measured, so the patch is the
/// file's own), else computed afresh on `data`. The same numbers either way, without
/// gathering the cells again (callgrind: a fifth of a million instructions a fit).
fn record_own_colour_noise(
    m: &Measurement,
    material: &mut Material,
    options: &FitOptions,
    data: &FitData,
    colour: Option<&objective::ColourTerm>,
    reference: &[crate::colour::Xyz],
) {
    let Some((lights, sigma)) = noise_lights(material, &options.lights) else {
        return;
    };
    let reused = colour
        .filter(|_| m.values.iter().all(|v| v.is_finite()))
        .and_then(|term| {
            // Each light's figure from its own entry of the fit's lights.
            let index: Option<Vec<usize>> = lights
                .iter()
                .map(|l| options.lights.iter().position(|g| g.name == l.name))
                .collect();
            let index = index?;
            let covariance: Option<Vec<_>> = index
                .iter()
                .map(|&k| term.noise_covariance.get(k).copied())
                .collect();
            let xyz: Option<Vec<_>> = index.iter().map(|&k| reference.get(k).copied()).collect();
            Some(assess::noise_delta_e2000(m, &lights, &xyz?, &covariance?))
        });
    let noise = reused
        .unwrap_or_else(|| assess::colour_noise_delta_e2000(m, material, data, &lights, sigma));
    set_colour_noise(material, &lights, noise);
}

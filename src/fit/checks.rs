//! Failure checks after refinement: conditions under which the stability sweeps
//! (`fluorite stability`, [`crate::evaluate::stability`]) show a fit losing the truth
//! although the solver converged. Each check looks only at the data and the fitted
//! spectra, so it fires in a user's real run, and adds one warning that says what to do.

use super::data::FitData;
use super::objective::Objective;
use super::representation::GridSpectra;

/// Fluorescence peak below this many noise σ: a and e are dominated by noise. In the
/// stability sweeps the shape error is about 3/ratio, so it passes 10 % near 30.
pub const LOW_SIGNAL_RATIO: f64 = 30.0;
/// Residual RMS of the first fitted cells next to the diagonal (or the guard band), in
/// noise σ and relative to the residual of the other cells, that marks crosstalk.
pub const CROSSTALK_RESIDUAL_FACTOR: f64 = 3.0;
/// An absorption band resolved by at most this many excitation samples above half its
/// maximum is under-sampled: its width and peak, hence colour under spiky lights, are
/// guesses.
pub const MIN_SAMPLES_ACROSS_BAND: usize = 2;

/// Runs every check and appends a warning for each that fires.
pub fn after_refinement(
    objective: &Objective<'_>,
    spectra: &GridSpectra,
    noise_sigma: f64,
    warnings: &mut Vec<String>,
) {
    let data = objective.data;
    let derived = objective.derived(spectra);
    let fitted = |i: usize, j: usize| objective.fitted(spectra, &derived, i, j);
    low_signal(data, &fitted, noise_sigma, warnings);
    wide_crosstalk(data, &fitted, noise_sigma, warnings);
    undersampled_absorption(data, spectra, warnings);
}

/// The fluorescence barely clears the noise: the shapes follow the noise.
fn low_signal(
    data: &FitData,
    fitted: &dyn Fn(usize, usize) -> f64,
    noise_sigma: f64,
    warnings: &mut Vec<String>,
) {
    let peak = data
        .off_diagonal
        .iter()
        .map(|c| fitted(c.row, c.column))
        .fold(0.0f64, f64::max);
    if noise_sigma > 0.0 && peak < LOW_SIGNAL_RATIO * noise_sigma {
        warnings.push(format!(
            "weak fluorescence: its peak {peak:.2e} is only {:.1}× the noise σ = {noise_sigma:.2e}, so the fitted absorption and emission shapes follow the noise; average repeated measurements or treat the shapes as rough",
            peak / noise_sigma
        ));
    }
}

/// Crosstalk the fit does not model (next to the diagonal, or past the guard band when one
/// is set) shows as a residual concentrated in the first cells it fits, on both sides of
/// the diagonal.
fn wide_crosstalk(
    data: &FitData,
    fitted: &dyn Fn(usize, usize) -> f64,
    noise_sigma: f64,
    warnings: &mut Vec<String>,
) {
    let step = grid_step(&data.emission_nm);
    let (mut near, mut n_near, mut far, mut n_far) = (0.0, 0usize, 0.0, 0usize);
    for c in &data.off_diagonal {
        let offset = (data.emission_nm[c.column] - data.excitation_nm[c.row]).abs();
        let r2 = (c.value - fitted(c.row, c.column)).powi(2);
        if offset <= data.guard_nm + step + 1e-6 {
            near += r2;
            n_near += 1;
        } else {
            far += r2;
            n_far += 1;
        }
    }
    if n_near == 0 || n_far == 0 {
        return;
    }
    let near_rms = (near / n_near as f64).sqrt();
    let far_rms = (far / n_far as f64).sqrt();
    if near_rms > CROSSTALK_RESIDUAL_FACTOR * noise_sigma.max(far_rms) {
        warnings.push(format!(
            "residual concentrated in the cells next to the {} (RMS {near_rms:.2e}, {:.1}× the rest): crosstalk (e.g. a wavelength offset between the monochromators) the model does not hold, or fluorescence of a small Stokes shift it misses; --guard {} sets those cells aside",
            if data.guard_nm > 0.0 {
                format!("{} nm guard band", data.guard_nm)
            } else {
                "diagonal".to_string()
            },
            near_rms / far_rms.max(noise_sigma).max(f64::MIN_POSITIVE),
            data.guard_nm + step
        ));
    }
}

/// The absorption band is narrower than the excitation step.
fn undersampled_absorption(data: &FitData, spectra: &GridSpectra, warnings: &mut Vec<String>) {
    let peak = spectra.absorption.iter().cloned().fold(0.0f64, f64::max);
    if peak <= 0.0 {
        return;
    }
    let across = spectra
        .absorption
        .iter()
        .filter(|&&a| a >= 0.5 * peak)
        .count();
    if across <= MIN_SAMPLES_ACROSS_BAND {
        warnings.push(format!(
            "absorption band resolved by only {across} excitation sample(s) above half its peak (step {} nm): its shape between samples is interpolated, colour under narrow-band lights is uncertain; measure a finer excitation grid",
            grid_step(&data.excitation_nm)
        ));
    }
}

/// The smallest spacing of a grid (its step for uniform grids).
fn grid_step(grid: &[f64]) -> f64 {
    grid.windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min)
        .min(1e6)
}

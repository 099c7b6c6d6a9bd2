//! The bounds and colour weights of `--noise-aware-bound`, and the misses a measured
//! colour's own noise explains: each light judged against what its measurement can tell.

use std::collections::{BTreeMap, VecDeque};

use crate::fit::parametric::{ModelSpec, ReflectanceForm};
use crate::material::YieldForm;
use crate::parametric::BandDomain;

use crate::material::Material;
use crate::measurement::Measurement;

use super::super::assess;
use super::super::data::FitData;

/// Each light's bound under --noise-aware-bound: max(`bound`, 3 × the measured colour's
/// noise RMS), but never more than `bound` beyond the grid fit's own ΔE2000 under that
/// light (`grid`). The grid model (one component, every sample free) shows how near one
/// fluorophore can come to the measured colour; a candidate further from it than that,
/// by more than the bound, misfits the matrix rather than its noise (a one-component
/// model of two dyes whose misfit the colour term no longer hides). Measured on
/// `fluorite class`, five seeds: the cap lowers the noise-aware search's p90 or max on
/// three (seed 11 max 7.99 → 4.06, seed 12 p90 1.56 → 1.35) and raises none. Where no
/// candidate meets these bounds, the fallback is the default rule (least excess over
/// the uncapped noise bounds): judging it by the capped ones as well kept the red
/// pigment at σ 2.5·10⁻³ nearer its truth (twelve draws, median 2.60 → 2.04) but raised
/// the class (seed 11 max 4.06 → 7.22, 0xBEEF p90 1.87 → 1.96).
pub(super) fn noise_widened_bounds(
    bound: f64,
    lights: &[crate::colour::Light],
    noise: &[f64],
    grid: &BTreeMap<String, f64>,
) -> BTreeMap<String, f64> {
    let mut bounds = assess::noise_aware_bounds(bound, lights, noise);
    for (light, widened) in bounds.iter_mut() {
        if let Some(grid) = grid.get(light).filter(|g| g.is_finite()) {
            *widened = bound.max(widened.min(grid + bound));
        }
    }
    bounds
}

/// Under --noise-aware-bound, where the grid model (one fluorophore, every sample free)
/// misses `light` by ΔE2000 `grid`, beyond the `limit` its noise explains (or within it,
/// but at a χ² beyond [`assess::NOISE_CHI2_LIMIT`], given as `chi2`): drops the
/// one-component structures from `jobs` but the smallest, which is fitted as the start of
/// the two-component models only (never chosen). Returns that structure and what the
/// search reports as skipped.
///
/// A one-component model could meet that light's bound only through the colour term
/// hiding its misfit, which the noise weighting no longer does. On `fluorite class` (five
/// seeds) starting at two components lowered a median, p90 or max on four and raised
/// none (0xBEEF's two-dye cases 1.16 / 3.30 → 0.99 / 3.00). Without the one-component
/// start, seed 165 case085 (two dyes, the grid fit 24.7 from the measured colour) had
/// every two-component model start from the grid fit alone and end 25 from the measured
/// colour, 27.13 from the truth, where the literal search, starting from its 1x1 parent,
/// ends within 0.4; with the parent alone, seed 30 case116's 2x1 started worse, so those
/// models start from both (`CandidateContext::parentless_starts_too`). Over 145 seeds the
/// noise-aware search changed on 830 of 21,750 cases, 423 nearer the truth and 394
/// further: those 0.58 / 1.87 / 27.13 → 0.55 / 1.73 / 10.99 (docs/results.md).
pub(super) fn skip_one_component_models(
    jobs: &mut VecDeque<(usize, usize, usize)>,
    light: &str,
    (grid, limit, chi2): (f64, f64, Option<f64>),
    reflectance: ReflectanceForm,
    domain: BandDomain,
) -> (Option<(usize, usize, usize)>, String) {
    let parent = jobs.iter().copied().find(|s| s.0 == 1);
    jobs.retain(|s| s.0 > 1 || Some(*s) == parent);
    let start = parent
        .map(|(components, absorption_bands, emission_bands)| {
            let spec = ModelSpec {
                components,
                absorption_bands,
                emission_bands,
                reflectance,
                domain,
                yield_form: YieldForm::Energy,
            };
            format!(
                "; {} fitted only as a start of the two-component models",
                spec.name()
            )
        })
        .unwrap_or_default();
    (
        parent,
        format!(
            "one-component models: under {light} the grid model (K = 1, every sample free) has ΔE2000 {grid:.2}, {} (--noise-aware-bound){start}",
            match chi2 {
                Some(chi2) => format!(
                    "within the {limit:.2} the measured colour's noise RMS explains but at χ² {chi2:.1}, beyond the {} noise alone passes in 1 of 10⁵ draws",
                    assess::NOISE_CHI2_LIMIT
                ),
                None => format!("beyond the {limit:.2} the measured colour's noise explains"),
            }
        ),
    )
}

/// χ² (three degrees of freedom) a colour miss must pass before [`grid_misfit_shares`]
/// counts any of it as structure: the noise's mean, 3, plus three standard deviations
/// (√6 each), as the grid fit's own colour term counts its rows' residual.
const MISFIT_CHI2_FLOOR: f64 = 3.0 + 3.0 * 2.449_489_742_783_178;

/// Per light, how much of what the grid fit leaves the cells' noise does not explain: the
/// larger of its off-diagonal residual's share beyond the noise, max(0, 1 − σ²/RMS²),
/// and its miss of that light's measured colour beyond the noise, max(0, 1 −
/// [`MISFIT_CHI2_FLOOR`] / χ²) with χ² the miss's ([`assess::misfit_colour_chi2`]). It
/// scales that light's colour pull under --noise-aware-bound. The colour term is for
/// structure a model cannot follow (the grid fit weighs its own by such a share). Where
/// the grid model, one fluorophore with every sample free, leaves only noise in the
/// cells and in the colour, a candidate's bands can follow the matrix, and the pull
/// drags them onto the noise of the measured colour instead: the default seed's case127
/// (one dye, σ 3·10⁻³) ended gaussian:1x1+rt 2.49 from the truth, 1.33 without. Both
/// parts: the residual's alone took the uv pull from a weak UV-excited blue emitter
/// beside a pigment (`uv_tail`, seed 2026, uvtail009), whose two LED rows' residual
/// stays within their noise while it moves the uv colour by 4 ΔE2000, far beyond its own
/// (the search ended 2.56 from the truth under uv instead of 0.33); the colour's alone
/// left the pull on most class draws, no nearer the truth than before. It applies only
/// where the colour's noise already weakens the pull ([`noise_pull_weights`]). Over 68
/// `fluorite class` seeds: docs/results.md.
pub(super) fn grid_misfit_shares(
    base: &Material,
    m: &Measurement,
    data: &FitData,
    lights: &[crate::colour::Light],
    sigma: f64,
) -> Vec<f64> {
    let rms = assess::accuracy(base, m, data, lights).rms_off_diagonal;
    let residual_share = if rms > 0.0 && rms.is_finite() {
        (1.0 - sigma * sigma / (rms * rms)).max(0.0)
    } else {
        0.0
    };
    assess::misfit_colour_chi2(m, base, data, lights, sigma)
        .into_iter()
        .map(|chi2| {
            let colour = if chi2 > MISFIT_CHI2_FLOOR {
                1.0 - MISFIT_CHI2_FLOOR / chi2
            } else {
                0.0
            };
            colour.max(residual_share)
        })
        .collect()
}

/// Each light's share of the colour weight under --noise-aware-bound: 1 while the
/// measured colour's noise RMS (`noise`, ΔE2000 per light) is at most
/// [`crate::fit::NOISE_PULL_SHARE`] × `bound`, then falling as 1/noise² (inverse-variance
/// weighting of the colour residual) and scaled by that light's share of what the grid
/// fit leaves beyond the noise (`shares`, [`grid_misfit_shares`]). A precise colour keeps
/// its full pull: the shares moved postit_pink's escalated fit from gaussian:2x2+r6 (uv
/// 0.14 against the measurement) to gaussian:2x1/2+r6 (uv 1.33), its d65, a and f11
/// colours known to better than a fifth of the bound.
pub(super) fn noise_pull_weights(bound: f64, noise: &[f64], shares: &[f64]) -> Vec<f64> {
    let scale = crate::fit::NOISE_PULL_SHARE * bound;
    noise
        .iter()
        .enumerate()
        .map(|(l, n)| {
            if n.is_finite() && *n > scale {
                (scale / n).powi(2) * shares.get(l).copied().unwrap_or(1.0)
            } else {
                1.0
            }
        })
        .collect()
}

/// Per light `material` misses `bound` under, (its ΔE2000, the measured colour's own
/// noise as RMS ΔE2000), when every miss is within [`assess::NOISE_COVERAGE`] × that
/// noise; empty when some miss is not (or none is measured against noise).
pub(super) fn misses_within_noise(
    m: &Measurement,
    material: &Material,
    data: &FitData,
    lights: &[crate::colour::Light],
    sigma: f64,
    bound: f64,
) -> BTreeMap<String, [f64; 2]> {
    let Some(report) = material.fit.as_ref() else {
        return BTreeMap::new();
    };
    let noise = assess::colour_noise_delta_e2000(m, material, data, lights, sigma);
    let mut misses = BTreeMap::new();
    for (light, noise) in lights.iter().zip(noise) {
        match report.delta_e2000.get(&light.name) {
            Some(&de) if de > bound => {
                if !(de.is_finite() && de <= assess::NOISE_COVERAGE * noise) {
                    return BTreeMap::new();
                }
                misses.insert(light.name.clone(), [de, noise]);
            }
            _ => {}
        }
    }
    misses
}

/// The search's rule in words: the first model within `budget` under each light (`noise_aware`:
/// within `light_bounds`, the colour terms weighed by `shares`), or, without a bound, the
/// lowest BIC (or the one model `--model` fixed, where `candidates` is 1).
pub(super) fn rule_words(
    budget: Option<f64>,
    noise_aware: bool,
    lights: &[crate::colour::Light],
    light_bounds: &BTreeMap<String, f64>,
    shares: &[f64],
    candidates: usize,
) -> String {
    match budget {
        Some(bound) if noise_aware => format!(
            "first model with ΔE2000 ≤ max({bound}, {} × the measured colour's noise RMS, at most the grid fit's + {bound}) under each light: {} (--noise-aware-bound; each light's colour term weighed by that noise and, where that noise weakens it, by the share of what the grid fit leaves beyond the noise, in the cells or that colour: {})",
            assess::NOISE_COVERAGE,
            lights
                .iter()
                .map(|l| format!(
                    "{} ≤ {:.2}",
                    l.name,
                    light_bounds.get(&l.name).copied().unwrap_or(bound)
                ))
                .collect::<Vec<_>>()
                .join(", "),
            lights
                .iter()
                .zip(shares)
                .map(|(l, s)| format!("{} {s:.2}", l.name))
                .collect::<Vec<_>>()
                .join(", "),
        ),
        Some(bound) => format!(
            "first model with ΔE2000 ≤ {bound} under {}",
            lights
                .iter()
                .map(|l| l.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
        ),
        None if candidates == 1 => "fixed by --model".to_string(),
        None => "lowest BIC on the matrix residual".to_string(),
    }
}

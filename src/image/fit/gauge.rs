//! From shared spectra and pixel scores to materials: the yield form and yield of each
//! fluorophore, chosen once for the whole image.
//!
//! A matrix fixes only s_k(p) = c_k(p)·Q_k (model.md §4 and §8). The gauge gives each
//! fluorophore the largest yield the conservation laws allow for its form — Q = min(1,
//! λmin/λ̄e) for a constant energy yield, Φ = 1 for a constant photon yield — so every
//! pixel gets the smallest concentration its measurement allows, and the pixel that
//! needs most sets no other pixel's scale. The energy form is kept unless it needs a
//! concentration above 1 somewhere while the photon form does not (the same preference
//! as `fluorite fit --yield auto`).

use crate::material::{Fluorophore, YieldForm};
use crate::spectrum::{Spectrum, bin_widths};

use super::shared::{Cells, Shared};

/// Which yield form the image's fluorophores take.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum YieldPreference {
    /// Constant energy yield Q.
    Energy,
    /// Constant photon yield Φ.
    Photon,
    /// Energy unless it needs c > 1 where photon does not.
    #[default]
    Auto,
}

/// The fluorophores of an image and how a pixel's scores become concentrations.
#[derive(Debug, Clone, PartialEq)]
pub struct Gauge {
    /// The fluorophores; `concentration` is the largest c over the image.
    pub fluorophores: Vec<Fluorophore>,
    /// c_k(p) = factor_k · s_k(p).
    pub factors: Vec<f64>,
    /// One line per fluorophore: form, yield, why.
    pub description: Vec<String>,
}

/// One fluorophore in a given form: (fluorophore with c = 1, factor).
fn in_form(
    beta: &[f64],
    epsilon: &[f64],
    cells: &Cells,
    form: YieldForm,
) -> Option<(Fluorophore, f64)> {
    let widths = bin_widths(&cells.emission_nm);
    let density: Vec<f64> = epsilon.iter().zip(&widths).map(|(e, w)| e / w).collect();
    let emission = Spectrum::new(cells.emission_nm.clone(), density, "emission").ok()?;
    let mean = emission.mean_wavelength_nm();
    if !mean.is_finite() || beta.iter().all(|&b| b <= 0.0) {
        return None;
    }
    let (absorption, factor_scale) = match form {
        YieldForm::Energy => (beta.to_vec(), 1.0),
        YieldForm::Photon => {
            // s·β(λ) = c·Φ·(λ/λ̄e)·a(λ): a ∝ β·λ̄e/λ, scaled to max 1 by N.
            let raw: Vec<f64> = beta
                .iter()
                .zip(&cells.excitation_nm)
                .map(|(b, l)| b * mean / l)
                .collect();
            let n = raw.iter().cloned().fold(0.0, f64::max);
            (raw.iter().map(|v| v / n).collect(), n)
        }
    };
    let absorption = Spectrum::new(cells.excitation_nm.clone(), absorption, "absorption").ok()?;
    let mut f = Fluorophore {
        concentration: 1.0,
        quantum_yield: 1.0,
        yield_form: form,
        concentration_range: None,
        absorption,
        emission,
    };
    let limit = f.yield_limit();
    f.quantum_yield = limit;
    // Energy: c·Q = s, so c = s/Q. Photon: c·Φ = s·N.
    Some((f, factor_scale / limit))
}

/// The gauge of `shared` under `preference`.
pub fn choose(shared: &Shared, cells: &Cells, preference: YieldPreference) -> Gauge {
    let (ni, no) = (cells.excitation_nm.len(), cells.emission_nm.len());
    let mut fluorophores = Vec::new();
    let mut factors = Vec::new();
    let mut description = Vec::new();
    for k in 0..shared.k {
        let beta = &shared.excitation[k * ni..(k + 1) * ni];
        let epsilon = &shared.emission[k * no..(k + 1) * no];
        let s_max = shared.max_scores.get(k).copied().unwrap_or(0.0);
        let energy = in_form(beta, epsilon, cells, YieldForm::Energy);
        let photon = in_form(beta, epsilon, cells, YieldForm::Photon);
        let pick = match (preference, energy, photon) {
            (YieldPreference::Energy, Some(e), _) => Some((e, "energy form asked for")),
            (YieldPreference::Photon, _, Some(p)) => Some((p, "photon form asked for")),
            (YieldPreference::Auto, Some(e), Some(p)) => {
                if e.1 * s_max <= 1.0 || e.1 <= p.1 {
                    Some((e, "energy form: its photon law leaves every pixel's c ≤ 1"))
                } else {
                    Some((
                        p,
                        "photon form: a constant energy yield would need c > 1 at the pixel that needs most",
                    ))
                }
            }
            (_, Some(e), _) => Some((e, "energy form")),
            (_, None, Some(p)) => Some((p, "photon form")),
            (_, None, None) => None,
        };
        // `super::prune` removed components without absorption or emission.
        let Some(((mut f, factor), why)) = pick else {
            continue;
        };
        f.concentration = (factor * s_max).min(1.0);
        description.push(format!(
            "fluorophore {}: {}; {} = {:.4} (the largest the conservation laws allow), largest c = {:.4}{}",
            k + 1,
            why,
            if f.yield_form == YieldForm::Energy { "Q" } else { "Φ" },
            f.quantum_yield,
            factor * s_max,
            if factor * s_max > 1.0 {
                " (above 1: those pixels' concentrations are clamped to 1, their fluorescence scaled down)"
            } else {
                ""
            }
        ));
        fluorophores.push(f);
        factors.push(factor);
    }
    Gauge {
        fluorophores,
        factors,
        description,
    }
}

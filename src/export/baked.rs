//! The total radiance factor βT(λ) of a material under one light (CIE 15): what a stock,
//! non-fluorescent renderer needs to show a fluorescent material exactly, for that light.
//!
//! A flat patch of the model lit by L(λ) sends back (model.md §6)
//! Lo(λ) = d(λ)·L(λ) + Σ_f e_f(λ)·∫ X_f(λi)·L(λi) dλi, with d = (1 − Σc·a)·r and
//! X_f = c·Q(λi)·a the energy fraction re-emitted (Q(λi) = Φ·λi/λ̄e in the photon form).
//! Dividing by L gives βT = d + Σ_f e_f·∫X_f·L / L: a reflectance that may exceed 1 where
//! the emission is strong and the light weak. It is exact for a uniformly lit surface
//! under L alone (any light of the same relative spectrum), and wrong under any other.
//!
//! The sums are the ones fluorite's colour uses ([`crate::colour::material_xyz`]): 1 nm
//! samples over 300–830 nm with trapezoid weights, so ∫ L·βT·x̄ on that grid is the
//! bispectral model's XYZ exactly, except for light emitted where L has no power, which
//! no reflectance can carry ([`BakedSpectrum::unlit_share`]).

use crate::colour::{Light, colour_grid, reemitted_energy};
use crate::material::Material;

/// A material's total radiance factor βT(λ) for one light.
#[derive(Debug, Clone, PartialEq)]
pub struct BakedSpectrum {
    /// The light it is valid for.
    pub light: String,
    /// Wavelengths (nm): 300–830 every 1 nm.
    pub wavelength_nm: Vec<f64>,
    /// βT (dimensionless; above 1 where fluorescence outshines the reflected light).
    pub value: Vec<f64>,
    /// Share of the re-emitted energy that falls where the light has no power, where βT
    /// holds the plain d (0 when the light covers the emission).
    pub unlit_share: f64,
}

impl BakedSpectrum {
    /// The largest βT.
    pub fn max(&self) -> f64 {
        self.value.iter().copied().fold(0.0, f64::max)
    }
}

/// βT of `material` under `light` (see the module documentation).
pub fn total_radiance_factor(material: &Material, light: &Light) -> BakedSpectrum {
    let (grid, widths) = colour_grid();
    let reemitted = reemitted_energy(material, light);
    let mut unlit = 0.0;
    let mut total = 0.0;
    let value = grid
        .iter()
        .zip(&widths)
        .map(|(&l, &w)| {
            let (value, fluorescence, lit) = beta_t(material, light, &reemitted, l);
            total += fluorescence * w;
            if !lit {
                unlit += fluorescence * w;
            }
            value
        })
        .collect();
    BakedSpectrum {
        light: light.name.clone(),
        wavelength_nm: grid,
        value,
        unlit_share: if total > 0.0 { unlit / total } else { 0.0 },
    }
}

/// βT of `material` under `light` at any `wavelength_nm` (the values
/// [`total_radiance_factor`] tabulates on its grid): d(λ) + Σ_f e_f(λ)·∫X_f·L / L(λ), and
/// the plain d where the light has no power.
pub fn total_radiance_factor_at(
    material: &Material,
    light: &Light,
    wavelength_nm: &[f64],
) -> Vec<f64> {
    let reemitted = reemitted_energy(material, light);
    wavelength_nm
        .iter()
        .map(|&l| beta_t(material, light, &reemitted, l).0)
        .collect()
}

/// βT at `l` given each fluorophore's re-emitted energy: (βT, the fluorescence emitted
/// at `l`, whether the light has power there).
fn beta_t(material: &Material, light: &Light, reemitted: &[f64], l: f64) -> (f64, f64, bool) {
    let fluorescence: f64 = material
        .fluorophores
        .iter()
        .zip(reemitted)
        .map(|(f, r)| r * f.emission.eval_zero_outside(l))
        .sum();
    let power = light.power(l);
    if power > 0.0 {
        (
            material.diagonal(l) + fluorescence / power,
            fluorescence,
            true,
        )
    } else {
        (material.diagonal(l), fluorescence, false)
    }
}

/// For targets that hold one fluorophore: the index of the one that re-emits the most
/// energy under `light`, and its share of all re-emitted energy (1 for a single one).
/// None without fluorophores.
pub fn strongest_fluorophore(material: &Material, light: &Light) -> Option<(usize, f64)> {
    let reemitted = reemitted_energy(material, light);
    let total: f64 = reemitted.iter().sum();
    let (index, most) = reemitted
        .iter()
        .copied()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    Some((index, if total > 0.0 { most / total } else { 1.0 }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beta_t_at_any_wavelength_is_the_tabulated_one() {
        let material: Material =
            serde_json::from_str(include_str!("../../data/red-pigment.truth.json")).unwrap();
        for light in Light::standard() {
            let baked = total_radiance_factor(&material, &light);
            let at = total_radiance_factor_at(&material, &light, &baked.wavelength_nm);
            assert_eq!(at, baked.value, "{}", light.name);
        }
    }
}

//! A parameter vector turned into a material: spectra tabulated finely from the forms,
//! the gauge of each component, the reflectance, and the forms block.

use super::*;

/// Step (nm) of the tabulation a parametric material carries beside its forms.
pub const TABULATION_STEP_NM: f64 = 1.0;

/// The measurement grid refined to [`TABULATION_STEP_NM`] (grid points kept); over a range
/// wider than [`crate::limits::MAX_TABULATION_SAMPLES`] nm, to the coarser step that keeps it
/// within that many samples.
pub fn fine_grid(coarse: &[f64]) -> Vec<f64> {
    let (Some(&first), Some(&last)) = (coarse.first(), coarse.last()) else {
        return Vec::new();
    };
    let step = crate::limits::tabulation_step_nm(last - first, TABULATION_STEP_NM);
    let steps = ((last - first) / step)
        .floor()
        .clamp(0.0, crate::limits::MAX_TABULATION_SAMPLES as f64) as usize;
    let mut grid: Vec<f64> = (0..=steps)
        .map(|n| first + n as f64 * step)
        .chain(coarse.iter().copied())
        .collect();
    grid.sort_by(f64::total_cmp);
    grid.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    grid
}

impl Problem<'_> {
    /// The material `theta` stands for: forms, their fine tabulation, c at its smallest
    /// feasible value per component (the gauge of the tabulated fit), and Q = k/c.
    pub fn material(&self, theta: &[f64], name: &str) -> Result<Material> {
        let mut material = self.material_without_margins(theta, name)?;
        material.conservation = Some(material.conservation_margins());
        Ok(material)
    }

    /// [`Problem::material`] without its conservation block, for a caller that computes
    /// it as it lowers the reflectance onto the energy bound
    /// ([`Material::lower_reflectance_to_energy_bound_with_margins`]): each search of the
    /// energy law's extrema was about 1 % of a noise-aware search.
    pub fn material_without_margins(&self, theta: &[f64], name: &str) -> Result<Material> {
        let data = self.data;
        let spec = self.layout.spec;
        let gm = self.grid_model(theta);
        let excitation_fine = fine_grid(&data.excitation_nm);
        let emission_fine = fine_grid(&data.emission_nm);
        let mut fluorophores = Vec::with_capacity(spec.components);
        let mut forms = Vec::with_capacity(spec.components);
        for k in 0..spec.components {
            let [absorption_bands, emission_bands] = self.component_bands(theta, k);
            // Absorption: normalise on the fit grid, trim the support where the bands fall
            // below the floor (the photon law's λmin), renormalise on the fine grid.
            let mut absorption = GaussianBands::from_params(
                spec.domain,
                [
                    data.excitation_nm[0],
                    *data.excitation_nm.last().unwrap_or(&0.0),
                ],
                &absorption_bands,
            );
            absorption.scale(1.0 / gm.absorption_peak[k]);
            if let Some(first) = gm.absorption[k].iter().position(|&a| a >= ABSORPTION_FLOOR) {
                absorption.support_nm[0] = data.excitation_nm[first];
            }
            let fine_peak = excitation_fine
                .iter()
                .map(|&l| absorption.eval(l))
                .fold(0.0, f64::max)
                .max(1e-300);
            absorption.scale(1.0 / fine_peak);
            let absorption = SpectralForm::GaussianBands(absorption);
            let what = format!("fluorophores[{k}]");
            let absorption_samples =
                absorption.tabulate(&excitation_fine, &format!("{what}.absorption"))?;
            // Emission: ∫e = 1 on the fine grid.
            let mut emission = GaussianBands::from_params(
                spec.domain,
                [
                    data.emission_nm[0],
                    *data.emission_nm.last().unwrap_or(&0.0),
                ],
                &emission_bands,
            );
            let raw = SpectralForm::GaussianBands(emission.clone())
                .tabulate(&emission_fine, &format!("{what}.emission"))?;
            let integral = raw.integral().max(1e-300);
            emission.scale(1.0 / integral);
            let emission = SpectralForm::GaussianBands(emission);
            let emission_samples =
                emission.tabulate(&emission_fine, &format!("{what}.emission"))?;
            // c·a is what the fit determined: c = κ·(fine peak); k = c·Q keeps the
            // fitted product: k = (κ/γ)·peak·∫/S.
            let concentration = (gm.kappa[k] * fine_peak).min(1.0);
            // (γ = 1 in the photon form: c = k, Φ = 1.)
            let k_product =
                gm.kappa[k] / gm.photon_factor[k] * fine_peak * integral / gm.normaliser[k];
            let mut absorption_samples = absorption_samples;
            // Rounding of the renormalisation may leave the peak a hair above 1.
            absorption_samples
                .value
                .iter_mut()
                .for_each(|a| *a = a.min(1.0));
            let mut fluorophore = Fluorophore {
                concentration,
                quantum_yield: 0.0,
                yield_form: spec.yield_form,
                concentration_range: None,
                absorption: absorption_samples,
                emission: emission_samples,
            };
            let limit = fluorophore.yield_limit();
            fluorophore.quantum_yield = if concentration > 0.0 {
                (k_product / concentration).min(limit)
            } else {
                0.0
            };
            fluorophores.push(fluorophore);
            forms.push(FluorophoreForms {
                absorption,
                emission,
            });
        }
        // The penalty lets Σ c·a overshoot 1 by ~1e-4, and the fine grid sees peaks the
        // fit grid missed: scale the concentrations onto the bound (k = c·Q is kept where
        // the yield allows).
        let mut wavelengths: Vec<f64> = excitation_fine.clone();
        wavelengths.extend(&emission_fine);
        let means: Vec<f64> = fluorophores.iter().map(|f| f.emission_mean_nm()).collect();
        // Σ c·a·m with m = max(1, λ/λ̄e) in the photon form: where the energy yield
        // exceeds Φ the emitted energy must fit under 1 too.
        let capped_by = |fluorophores: &[Fluorophore], l: f64| -> f64 {
            fluorophores
                .iter()
                .zip(&means)
                .map(|(f, &mean)| {
                    f.concentration
                        * f.absorption.eval_zero_outside(l)
                        * f.excitation_factor_with_mean(l, mean).max(1.0)
                })
                .sum()
        };
        let total_peak = wavelengths
            .iter()
            .map(|&l| capped_by(&fluorophores, l))
            .fold(0.0, f64::max);
        if total_peak > 1.0 {
            for f in &mut fluorophores {
                let k_product = f.k();
                f.concentration /= total_peak;
                f.quantum_yield = (k_product / f.concentration).min(f.yield_limit());
            }
        }
        // Reflectance.
        let diagonal_nm: Vec<f64> = self
            .diagonal
            .iter()
            .map(|d| data.emission_nm[d.column])
            .collect();
        let absorbed_by = |l: f64| -> f64 {
            fluorophores
                .iter()
                .map(|f| f.concentration * f.absorption.eval_zero_outside(l))
                .sum()
        };
        let (reflectance, reflectance_form) = match spec.reflectance {
            ReflectanceForm::Polynomial(_) => {
                let form = SpectralForm::SigmoidPolynomial(SigmoidPolynomial {
                    support_nm: self.reflectance_support,
                    coefficients: theta[self.layout.reflectance()].to_vec(),
                });
                let mut samples = form.tabulate(&fine_grid(&diagonal_nm), "reflectance")?;
                if spec.photon() {
                    // The fit's diagonal is d = (1 − Σκ·a·m)·σ(p): r = d/(1 − Σc·a) is the
                    // sigmoid only where no component absorbs above its mean emission.
                    for (r, &l) in samples.value.iter_mut().zip(&samples.wavelength_nm) {
                        let transmitted = 1.0 - absorbed_by(l);
                        if transmitted > 0.0 {
                            *r = (*r * (1.0 - capped_by(&fluorophores, l)) / transmitted)
                                .clamp(0.0, 1.0);
                        }
                    }
                    let agrees = form
                        .agreement(
                            &samples.wavelength_nm,
                            &samples.value,
                            0.5 * crate::check::FORM_TOLERANCE,
                        )
                        .is_none_or(|a| a.worst <= 0.5 * crate::check::FORM_TOLERANCE);
                    let form = agrees.then_some(form);
                    (samples, form)
                } else {
                    (samples, Some(form))
                }
            }
            ReflectanceForm::Tabulated => {
                let mut values: Vec<f64> = (0..self.diagonal.len())
                    .map(|p| self.diagonal_value(&gm, p).0)
                    .collect();
                let unbounded = vec![f64::INFINITY; values.len()];
                crate::fit::data::fill_missing(&mut values, &diagonal_nm, &unbounded, name)?;
                let r = values
                    .iter()
                    .zip(&diagonal_nm)
                    .map(|(d, &l)| {
                        let transmitted = 1.0 - absorbed_by(l);
                        if transmitted > 0.0 {
                            (d / transmitted).clamp(0.0, 1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect();
                (Spectrum::new(diagonal_nm.clone(), r, "reflectance")?, None)
            }
        };
        let mut material = Material::without_margins(name.to_string(), reflectance, fluorophores);
        let absorbed_by = |l: f64| material.absorbed(l);
        // Feasible interval of each c with the others held: c ≥ k·γ, c·a ≤ 1 − d − Σ others.
        let ranges: Vec<[f64; 2]> = (0..material.fluorophores.len())
            .map(|k| {
                let f = &material.fluorophores[k];
                let mut upper: f64 = 1.0;
                for &l in &diagonal_nm {
                    let a = f.absorption.eval_zero_outside(l);
                    if a > 0.0 {
                        let others = absorbed_by(l) - f.concentration * a;
                        upper = upper.min((1.0 - material.diagonal(l) - others) / a);
                    }
                }
                [f.concentration, upper.max(f.concentration)]
            })
            .collect();
        for (f, range) in material.fluorophores.iter_mut().zip(ranges) {
            f.concentration_range = Some(range);
        }
        material.forms = Some(MaterialForms {
            model: spec.name(),
            reflectance: reflectance_form,
            fluorophores: forms,
        });
        Ok(material)
    }
}

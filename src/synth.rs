//! Synthetic reradiation matrices with known ground truth, for examples, tests and the
//! stability sweeps: dye-like Gaussian bands, a smooth reflectance, chosen noise,
//! crosstalk next to the diagonal and missing cells.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::material::{Fluorophore, Material, YieldForm};
use crate::measurement::{Measurement, Units};
use crate::model::predict;
use crate::numeric::SplitMix64;
use crate::parametric::{
    BandDomain, FluorophoreForms, GaussianBand, GaussianBands, MaterialForms, SpectralForm,
};
use crate::spectrum::{Spectrum, bin_widths, uniform_grid};

/// A Gaussian band: in wavelength, or (a spec's [`SynthSpec::band_axis`]) in wavenumber
/// with the same centre and the standard deviation `width_nm` has at its centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Band {
    /// Centre (nm).
    pub centre_nm: f64,
    /// Standard deviation (nm).
    pub width_nm: f64,
    /// Relative height.
    pub weight: f64,
}

/// Bands from (centre nm, width nm, weight) triples: the presets' tables.
fn bands(table: &[(f64, f64, f64)]) -> Vec<Band> {
    table
        .iter()
        .map(|&(centre_nm, width_nm, weight)| Band {
            centre_nm,
            width_nm,
            weight,
        })
        .collect()
}

impl Band {
    fn eval(&self, nm: f64, axis: BandDomain) -> f64 {
        let z = match axis {
            BandDomain::Wavelength => (nm - self.centre_nm) / self.width_nm,
            // 1/λ − 1/λc over the width in 1/λ at the centre, w/λc².
            BandDomain::Wavenumber => {
                (1.0 / nm - 1.0 / self.centre_nm) * self.centre_nm * self.centre_nm / self.width_nm
            }
        };
        self.weight * (-0.5 * z * z).exp()
    }

    /// Its standard deviation on `axis` in that axis's unit (nm, or cm⁻¹ for wavenumber):
    /// a [`GaussianBand`]'s width.
    fn width_on(&self, axis: BandDomain) -> f64 {
        match axis {
            BandDomain::Wavelength => self.width_nm,
            BandDomain::Wavenumber => 1e7 * self.width_nm / (self.centre_nm * self.centre_nm),
        }
    }
}

fn wavelength() -> BandDomain {
    BandDomain::Wavelength
}

fn is_wavelength(axis: &BandDomain) -> bool {
    *axis == BandDomain::Wavelength
}

/// One further fluorescent component of a [`SynthSpec`], defined like the spec's own.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthComponent {
    /// Absorption bands (normalised to max 1 on the excitation grid).
    pub absorption: Vec<Band>,
    /// Emission bands (normalised to ∫e = 1 on the emission grid).
    pub emission: Vec<Band>,
    /// Concentration c.
    pub concentration: f64,
    /// Quantum yield as a fraction of its photon limit: of λmin/λ̄e for the energy yield
    /// Q (energy form), of 1 for the photon yield Φ (photon form).
    pub yield_fraction_of_limit: f64,
    /// Which yield is constant over the excitation wavelength (default: energy).
    #[serde(default, skip_serializing_if = "YieldForm::is_energy")]
    pub yield_form: YieldForm,
}

/// Everything that defines a synthetic measurement.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SynthSpec {
    /// Name of the example (file stem).
    pub name: String,
    /// Excitation grid (nm).
    pub excitation_nm: Vec<f64>,
    /// Emission grid (nm).
    pub emission_nm: Vec<f64>,
    /// Absorption bands (normalised to max 1 on the excitation grid).
    pub absorption: Vec<Band>,
    /// Emission bands (normalised to ∫e = 1 on the emission grid).
    pub emission: Vec<Band>,
    /// Reflectance: a sigmoid from `reflectance_low` to `reflectance_high` around
    /// `reflectance_edge_nm` with width `reflectance_width_nm`.
    pub reflectance_low: f64,
    /// See `reflectance_low`.
    pub reflectance_high: f64,
    /// See `reflectance_low`.
    pub reflectance_edge_nm: f64,
    /// See `reflectance_low`.
    pub reflectance_width_nm: f64,
    /// Concentration c.
    pub concentration: f64,
    /// Quantum yield as a fraction of its photon limit (so it always conserves photons):
    /// Q = fraction·λmin/λ̄e in the energy form, Φ = fraction in the photon form.
    pub yield_fraction_of_limit: f64,
    /// Which yield of the first component is constant over the excitation wavelength
    /// (default: energy). A photon-form truth must still conserve energy where it absorbs
    /// above its mean emission wavelength; [`SynthSpec::truth`] checks.
    #[serde(default, skip_serializing_if = "YieldForm::is_energy")]
    pub yield_form: YieldForm,
    /// Further fluorescent components beside the one above (absent in one-fluorophore
    /// specs). The truth lists the first component first, then these in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<SynthComponent>,
    /// The axis every band is Gaussian in (default: wavelength).
    #[serde(default = "wavelength", skip_serializing_if = "is_wavelength")]
    pub band_axis: BandDomain,
    /// Gaussian noise σ added to every cell (radiance-factor units).
    pub noise_sigma: f64,
    /// Crosstalk as the real BFC-450 files show it (model.md §5): a small wavelength
    /// offset between the monochromators moves this fraction of each row's diagonal
    /// reflectance from the emission column above the diagonal cell (j + 1) to the one
    /// below it (j − 1). It sums to zero, so the row keeps its energy (except at the
    /// grid's ends, where one of the two lies outside it). Real files:
    /// about 0.001 (CIBA12, HERPICER, the post-its) to 0.04 (POLGREE, TEXTYELL).
    pub crosstalk: f64,
    /// Fraction of off-diagonal cells left unmeasured (NaN).
    pub missing_fraction: f64,
    /// Random seed.
    pub seed: u64,
}

impl SynthSpec {
    /// A BFC-450-like spec (excitation 300–780, emission 380–780, 10 nm) of a named
    /// preset: `green-dye` (fluorescein-like), `red-pigment` (cerise-like), `brightener`
    /// (optical brightener: UV absorption, blue emission), `two-dyes` (two fluorophores:
    /// a brightener absorbing at 365 nm and emitting at 440 nm, and an orange-red dye
    /// absorbing at 545 nm and emitting at 610 nm), `plain` (no fluorescence).
    pub fn preset(name: &str) -> Result<SynthSpec> {
        let mut spec = SynthSpec {
            name: name.to_string(),
            excitation_nm: uniform_grid(300.0, 780.0, 10.0),
            emission_nm: uniform_grid(380.0, 780.0, 10.0),
            absorption: vec![],
            emission: vec![],
            reflectance_low: 0.05,
            reflectance_high: 0.9,
            reflectance_edge_nm: 500.0,
            reflectance_width_nm: 20.0,
            concentration: 0.8,
            yield_fraction_of_limit: 0.9,
            yield_form: YieldForm::Energy,
            components: vec![],
            band_axis: BandDomain::Wavelength,
            noise_sigma: MEASURED_NOISE_SIGMA,
            crosstalk: 0.001,
            missing_fraction: 0.0,
            seed: 1,
        };
        match name {
            "green-dye" => {
                spec.absorption = bands(&[(490.0, 18.0, 1.0), (330.0, 25.0, 0.25)]);
                spec.emission = bands(&[(520.0, 15.0, 1.0), (550.0, 25.0, 0.3)]);
                spec.reflectance_edge_nm = 460.0;
                spec.reflectance_low = 0.1;
            }
            "red-pigment" => {
                spec.absorption = bands(&[(545.0, 22.0, 1.0), (380.0, 40.0, 0.3)]);
                spec.emission = bands(&[(605.0, 20.0, 1.0)]);
                spec.reflectance_edge_nm = 590.0;
                spec.concentration = 0.9;
            }
            "brightener" => {
                spec.absorption = bands(&[(350.0, 20.0, 1.0)]);
                spec.emission = bands(&[(435.0, 15.0, 1.0), (460.0, 20.0, 0.4)]);
                spec.reflectance_low = 0.6;
                spec.reflectance_high = 0.88;
                spec.reflectance_edge_nm = 400.0;
                spec.concentration = 0.7;
            }
            "two-dyes" => {
                // An optical brightener (UV absorption, blue emission) and an orange-red
                // dye (green absorption, orange-red emission) in a white base.
                spec.absorption = bands(&[(365.0, 15.0, 1.0)]);
                spec.emission = bands(&[(440.0, 15.0, 1.0), (465.0, 20.0, 0.35)]);
                spec.concentration = 0.6;
                spec.yield_fraction_of_limit = 0.8;
                spec.components = vec![SynthComponent {
                    absorption: bands(&[(545.0, 18.0, 1.0)]),
                    emission: bands(&[(610.0, 17.0, 1.0), (640.0, 25.0, 0.3)]),
                    concentration: 0.7,
                    yield_fraction_of_limit: 0.85,
                    yield_form: YieldForm::Energy,
                }];
                spec.reflectance_low = 0.55;
                spec.reflectance_high = 0.9;
                spec.reflectance_edge_nm = 400.0;
            }
            "plain" => {
                spec.absorption = vec![];
                spec.emission = vec![];
                spec.concentration = 0.0;
            }
            other => {
                return Err(Error::invalid(
                    "--preset",
                    format!(
                        "unknown preset \"{other}\"; choose one of {}",
                        PRESETS.join(", ")
                    ),
                ));
            }
        }
        Ok(spec)
    }

    /// A one-dye spec on a BFC-450-like grid of `step_nm` (excitation 300–780, emission
    /// 380–780 nm): one Gaussian absorption band at `absorption` (centre, width nm) and one
    /// emission band at `emission` (centre, width nm), the green-dye preset's reflectance
    /// and yield, concentration `concentration`, noise `noise_sigma`, no crosstalk and no
    /// missing cells. The sweeps of one-band dyes start from it.
    pub fn one_band_dye(
        absorption: (f64, f64),
        emission: (f64, f64),
        concentration: f64,
        noise_sigma: f64,
        step_nm: f64,
        seed: u64,
    ) -> SynthSpec {
        let band = |(centre_nm, width_nm): (f64, f64)| Band {
            centre_nm,
            width_nm,
            weight: 1.0,
        };
        SynthSpec {
            name: format!("dye-{:.0}-{:.0}", absorption.0, emission.0),
            excitation_nm: uniform_grid(300.0, 780.0, step_nm),
            emission_nm: uniform_grid(380.0, 780.0, step_nm),
            absorption: vec![band(absorption)],
            emission: vec![band(emission)],
            concentration,
            noise_sigma,
            crosstalk: 0.0,
            missing_fraction: 0.0,
            seed,
            ..Self::preset("green-dye").expect("a preset")
        }
    }

    /// The same draw without its fluorophores: the same reflectance, grids, noise,
    /// crosstalk, missing cells and seed, zero concentration and no further components.
    /// What a fit must call a plain reflector ([`crate::evaluate::class`]'s dye-free twins).
    pub fn dye_free_twin(&self) -> SynthSpec {
        SynthSpec {
            concentration: 0.0,
            components: Vec::new(),
            ..self.clone()
        }
    }

    /// The ground-truth material, sampled on the spec's grids (so the tabulated model
    /// represents it exactly): the spec's own fluorophore (unless it has no absorption
    /// bands or zero concentration), then one per entry of `components`, in order.
    pub fn truth(&self) -> Result<Material> {
        let reflectance: Vec<f64> = self
            .emission_nm
            .iter()
            .map(|&l| {
                let t = 1.0
                    / (1.0 + (-(l - self.reflectance_edge_nm) / self.reflectance_width_nm).exp());
                self.reflectance_low + (self.reflectance_high - self.reflectance_low) * t
            })
            .collect();
        let reflectance = Spectrum::new(self.emission_nm.clone(), reflectance, "reflectance")?;
        let mut fluorophores = Vec::new();
        for (component, place) in self.active_components() {
            fluorophores.push(self.fluorophore(&component, &place)?.0);
        }
        if fluorophores.is_empty() {
            return Ok(Material::new(self.name.clone(), reflectance, vec![]));
        }
        let material = Material::new(self.name.clone(), reflectance, fluorophores);
        material.validate()?;
        Ok(material)
    }

    /// The components that make fluorophores (absorption bands and c > 0), in order, with
    /// their place in the spec for errors.
    fn active_components(&self) -> Vec<(SynthComponent, String)> {
        let first = SynthComponent {
            absorption: self.absorption.clone(),
            emission: self.emission.clone(),
            concentration: self.concentration,
            yield_fraction_of_limit: self.yield_fraction_of_limit,
            yield_form: self.yield_form,
        };
        std::iter::once(first)
            .chain(self.components.iter().cloned())
            .enumerate()
            .filter(|(_, c)| !c.absorption.is_empty() && c.concentration != 0.0)
            .map(|(n, c)| {
                let place = if n == 0 {
                    "synth".to_string()
                } else {
                    format!("synth.components[{}]", n - 1)
                };
                (c, place)
            })
            .collect()
    }

    /// The ground truth with a `forms` block (model `synth`): per fluorophore the
    /// Gaussian bands (on the spec's band axis, zero outside its grids) that generate its
    /// spectra, scaled exactly as its samples are. The reflectance stays tabulated.
    pub fn truth_with_forms(&self) -> Result<Material> {
        let mut material = self.truth()?;
        let mut fluorophores = Vec::new();
        for (component, place) in self.active_components() {
            let (_, peak, area) = self.fluorophore(&component, &place)?;
            let form = |bands: &[Band], scale: f64, grid: &[f64]| {
                SpectralForm::GaussianBands(GaussianBands {
                    domain: self.band_axis,
                    support_nm: [grid[0], grid[grid.len() - 1]],
                    bands: bands
                        .iter()
                        .map(|b| GaussianBand {
                            centre_nm: b.centre_nm,
                            width: b.width_on(self.band_axis),
                            height: b.weight / scale,
                        })
                        .collect(),
                })
            };
            fluorophores.push(FluorophoreForms {
                absorption: form(&component.absorption, peak, &self.excitation_nm),
                emission: form(&component.emission, area, &self.emission_nm),
            });
        }
        material.forms = Some(MaterialForms {
            model: "synth".to_string(),
            reflectance: None,
            fluorophores,
        });
        material.validate()?;
        Ok(material)
    }

    /// One component sampled on the spec's grids: a normalised to max 1, e to ∫e = 1, and
    /// Q the given fraction of the photon limit λmin/λ̄e; with the absorption peak and
    /// emission area divided out. `place` names it in errors.
    fn fluorophore(
        &self,
        component: &SynthComponent,
        place: &str,
    ) -> Result<(Fluorophore, f64, f64)> {
        let sample = |bands: &[Band], grid: &[f64]| -> Vec<f64> {
            grid.iter()
                .map(|&l| bands.iter().map(|b| b.eval(l, self.band_axis)).sum())
                .collect()
        };
        // Bands sampled on a grid, divided by their `scale` (peak or area), which must be
        // positive; `scale_is` says what it is, on which grid, for the error.
        let normalised =
            |samples: Vec<f64>, scale: f64, what: &str, scale_is: String| -> Result<Vec<f64>> {
                if !(scale.is_finite() && scale > 0.0) {
                    return Err(Error::invalid(
                        format!("{place}.{what}"),
                        format!("{scale_is}; give bands with positive weight inside it"),
                    ));
                }
                Ok(samples.iter().map(|x| x / scale).collect())
            };
        let a = sample(&component.absorption, &self.excitation_nm);
        let peak = a.iter().cloned().fold(0.0, f64::max);
        let on_grid = format!("peaks at {peak} on the excitation grid");
        let a = normalised(a, peak, "absorption", on_grid)?;
        let e = sample(&component.emission, &self.emission_nm);
        let widths = bin_widths(&self.emission_nm);
        let area: f64 = e.iter().zip(&widths).map(|(x, w)| x * w).sum();
        let on_grid = format!("integrates to {area} on the emission grid");
        let e = normalised(e, area, "emission", on_grid)?;
        let absorption = Spectrum::new(self.excitation_nm.clone(), a, "absorption")?;
        let emission = Spectrum::new(self.emission_nm.clone(), e, "emission")?;
        let mut fluorophore = Fluorophore {
            concentration: component.concentration,
            quantum_yield: 0.0,
            yield_form: component.yield_form,
            concentration_range: None,
            absorption,
            emission,
        };
        fluorophore.quantum_yield = component.yield_fraction_of_limit * fluorophore.yield_limit();
        Ok((fluorophore, peak, area))
    }

    /// Checks the measurement's parameters: noise σ and crosstalk finite and ≥ 0, the
    /// missing fraction in [0, 1). Errors name the field and the `fluorite synth` flag
    /// that sets it. (The truth's parameters are checked by [`SynthSpec::truth`], with
    /// the material's laws.)
    pub fn validate(&self) -> Result<()> {
        for (value, field) in [
            (self.noise_sigma, "noise_sigma (--noise)"),
            (self.crosstalk, "crosstalk (--crosstalk)"),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(Error::invalid(
                    field,
                    format!("is {value}; give a non-negative number"),
                ));
            }
        }
        let missing = self.missing_fraction;
        if !(0.0..1.0).contains(&missing) {
            return Err(Error::invalid(
                "missing_fraction (--missing)",
                format!("is {missing}; give a fraction in [0, 1)"),
            ));
        }
        Ok(())
    }

    /// The synthetic measurement (per 10 nm-style bin) and its ground truth; fails when
    /// [`SynthSpec::validate`] does.
    pub fn generate(&self) -> Result<(Measurement, Material)> {
        self.validate()?;
        let truth = self.truth()?;
        let mut m = predict(
            &truth,
            &self.name,
            &self.excitation_nm,
            &self.emission_nm,
            Units::PerBin,
            true,
        );
        // + one emission column below the diagonal, − one above: an offset, no energy.
        for i in 0..m.n_excitation() {
            let moved = self.crosstalk * truth.diagonal(self.excitation_nm[i]);
            let (below, above) = crosstalk_columns(&m, i);
            if let Some(c) = below {
                *m.get_mut(i, c) += moved;
            }
            if let Some(c) = above {
                *m.get_mut(i, c) -= moved;
            }
        }
        let mut rng = SplitMix64::new(self.seed);
        for i in 0..m.n_excitation() {
            for j in 0..m.n_emission() {
                let offset = (self.emission_nm[j] - self.excitation_nm[i]).abs();
                let value = m.get_mut(i, j);
                *value += self.noise_sigma * rng.normal();
                if offset > 1e-6 && rng.uniform() < self.missing_fraction {
                    *value = f64::NAN;
                }
            }
        }
        Ok((m, truth))
    }
}

/// The emission columns of row `i` of `m` that the synthesiser's crosstalk goes to: those
/// next to its diagonal cell ([`Measurement::diagonal_neighbours`], j ∓ 1, as the fit
/// removes it), or, in a row without a diagonal cell (an excitation wavelength off the
/// emission grid), the columns on either side of its wavelength within one emission step
/// of it (the grid's spacing there, or at its end).
fn crosstalk_columns(m: &Measurement, i: usize) -> (Option<usize>, Option<usize>) {
    let l = &m.emission_nm;
    let x = m.excitation_nm[i];
    if let Some(j) = crate::spectrum::find_wavelength(l, x) {
        return (j.checked_sub(1), Some(j + 1).filter(|&a| a < l.len()));
    }
    let above = l.iter().position(|&v| v > x);
    let below = match above {
        Some(a) => a.checked_sub(1),
        None => Some(l.len() - 1),
    };
    let spacing = match (below, above) {
        (Some(b), Some(a)) => l[a] - l[b],
        _ if l.len() < 2 => 0.0,
        (None, _) => l[1] - l[0],
        (_, None) => l[l.len() - 1] - l[l.len() - 2],
    };
    let near = |c: usize| (l[c] - x).abs() <= spacing + 1e-6;
    (below.filter(|&c| near(c)), above.filter(|&c| near(c)))
}

impl SynthSpec {
    /// A concentration series of this spec: one measurement and truth per entry of
    /// `concentrations` (the first component's c; spectra, reflectance and yield shared),
    /// named `<name>-c<c>`, each with its own noise draw (seed + index). Fails when
    /// [`SynthSpec::validate`] does.
    pub fn concentration_series(
        &self,
        concentrations: &[f64],
    ) -> Result<Vec<(SynthSpec, Measurement, Material)>> {
        self.validate()?;
        if concentrations.is_empty() {
            return Err(Error::invalid(
                "--concentrations",
                "is empty; give two or more concentrations, e.g. 0.2,0.5,1.0",
            ));
        }
        if self.absorption.is_empty() {
            return Err(Error::invalid(
                "--concentrations",
                format!(
                    "preset \"{}\" has no fluorophore to vary; choose a fluorescent preset",
                    self.name
                ),
            ));
        }
        concentrations
            .iter()
            .enumerate()
            .map(|(n, &c)| {
                if !(c > 0.0 && c <= 1.0) {
                    return Err(Error::invalid(
                        "--concentrations",
                        format!("holds {c}; every concentration must lie in (0, 1]"),
                    ));
                }
                let spec = SynthSpec {
                    name: format!("{}-c{c}", self.name),
                    concentration: c,
                    seed: self.seed.wrapping_add(n as u64),
                    ..self.clone()
                };
                let (m, truth) = spec.generate()?;
                Ok((spec, m, truth))
            })
            .collect()
    }
}

/// The noise the real BFC-450 files show on their anti-Stokes side (1.4826 × median
/// absolute deviation, 0.0005–0.0008 across the six files): the presets' default. The
/// data README's "about ±0.003" is the spread of the extreme cells.
pub const MEASURED_NOISE_SIGMA: f64 = 0.0006;

/// Names accepted by [`SynthSpec::preset`].
pub const PRESETS: [&str; 5] = [
    "green-dye",
    "red-pigment",
    "brightener",
    "two-dyes",
    "plain",
];

impl SynthSpec {
    /// One draw of the UV-tail pigment class, on the BFC-450 grid: an orange-red pigment
    /// (absorption 470–560 nm plus a UV band at 310–390 nm of 0.15–0.6 of the peak,
    /// emission 40–90 nm above, with an optional shoulder) in a dark-to-light reflectance
    /// edge, energy or photon form, BFC-450 noise (σ 4·10⁻⁴–9·10⁻⁴) and crosstalk
    /// (0.001–0.04); with `emitter`, a weak UV-excited blue emitter beside it (absorption
    /// 345–380 nm, emission 425–455 nm, c 0.003–0.05: a brightener in the substrate or
    /// binder, as HERPICER.BFC shows). Named `uvtailNNN` after `index`; `rng` draws
    /// everything, so a seed fixes the class.
    pub fn uv_tail_pigment(rng: &mut SplitMix64, index: usize, emitter: bool) -> SynthSpec {
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
        let band = |centre_nm: f64, width_nm: f64, weight: f64| Band {
            centre_nm,
            width_nm,
            weight,
        };
        let main = u(470.0, 560.0);
        let absorption = vec![
            band(main, u(18.0, 40.0), 1.0),
            band(u(310.0, 390.0), u(15.0, 40.0), u(0.15, 0.6)),
        ];
        let peak = main + u(40.0, 90.0);
        let emission = vec![
            band(peak, u(15.0, 30.0), 1.0),
            band(peak + u(20.0, 40.0), u(20.0, 35.0), u(0.0, 0.4)),
        ];
        let (reflectance_low, reflectance_high) = (u(0.03, 0.1), u(0.75, 0.9));
        let reflectance_edge_nm = main + u(20.0, 50.0);
        let reflectance_width_nm = u(10.0, 25.0);
        let concentration = u(0.5, 0.9);
        let yield_fraction_of_limit = u(0.5, 0.95);
        let yield_form = if u(0.0, 1.0) < 0.5 {
            YieldForm::Energy
        } else {
            YieldForm::Photon
        };
        let components = if emitter {
            vec![SynthComponent {
                absorption: vec![band(u(345.0, 380.0), u(12.0, 25.0), 1.0)],
                emission: vec![
                    band(u(425.0, 455.0), u(12.0, 22.0), 1.0),
                    band(u(460.0, 480.0), u(15.0, 25.0), 0.35),
                ],
                concentration: u(0.003, 0.05),
                yield_fraction_of_limit: u(0.3, 0.9),
                yield_form: YieldForm::Energy,
            }]
        } else {
            vec![]
        };
        let noise_sigma = u(4e-4, 9e-4);
        let crosstalk = u(0.001, 0.04);
        SynthSpec {
            name: format!("uvtail{index:03}"),
            excitation_nm: uniform_grid(300.0, 780.0, 10.0),
            emission_nm: uniform_grid(380.0, 780.0, 10.0),
            absorption,
            emission,
            reflectance_low,
            reflectance_high,
            reflectance_edge_nm,
            reflectance_width_nm,
            concentration,
            yield_fraction_of_limit,
            yield_form,
            components,
            band_axis: BandDomain::Wavelength,
            noise_sigma,
            crosstalk,
            missing_fraction: 0.0,
            seed: rng.next_u64(),
        }
    }
}

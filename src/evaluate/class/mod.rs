//! Accuracy on a randomized class of synthetic materials: materials not in `../shared`.
//!
//! [`draw`] makes `cases` seeded [`SynthSpec`]s — one fluorophore (70 %) or two (30 %),
//! absorption peak 300–620 nm with an optional second band, Stokes shift 15–120 nm, a
//! sigmoid reflectance, concentration, yield and yield form, noise log-uniform in
//! 1e-4–3e-3, crosstalk 0–0.05, missing cells 0–0.05, the BFC-450 grid (70 %), a 5 nm
//! grid (20 %) or a 20 nm grid (10 %). [`run`] fits every case with each of [`METHODS`]
//! (the grid fit, the model search under ΔE2000 ≤ [`SEARCH_BOUND`], the same with
//! `--noise-aware-bound`, and the default fit) and compares each fit with the
//! measurement (the fit report's ΔE2000) and with the truth (the materials' colours).

use std::time::Instant;

use rayon::prelude::*;

use crate::colour::{Light, PatchColorimeter, delta_e2000};
use crate::error::{Error, Result};
use crate::fit::{BandAxisChoice, FitOptions, FitOutcome, ModelChoice, fit};
use crate::material::{Material, YieldForm};
use crate::measurement::Measurement;
use crate::numeric::{SplitMix64, median_step};
use crate::parametric::BandDomain;
use crate::spectrum::uniform_grid;
use crate::synth::{Band, SynthComponent, SynthSpec};

use super::stability::material_delta_e;
use super::{SEARCH_BOUND, quantile};

mod report;
pub use report::{CSV_HEADER, case_files, to_csv, to_markdown};

/// Number of cases of `fluorite class` by default.
pub const DEFAULT_CASES: usize = 150;
/// Seed of `fluorite class` by default.
pub const DEFAULT_SEED: u64 = 0xC1A5_5EE9_2026_1130;

/// A seed as `fluorite class --seed` takes it: decimal, or hexadecimal after `0x` (`_`
/// allowed between the digits, as in [`DEFAULT_SEED`]). The error says what was given.
pub fn parse_seed(text: &str) -> std::result::Result<u64, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
        None => text.parse(),
    };
    parsed.map_err(|e| format!("\"{text}\" is not a seed ({e}); give e.g. 42 or 0xC1A55EE9"))
}
/// Draws the synthesiser may refuse per case before [`draw`] gives up.
const MAX_REFUSALS_PER_CASE: usize = 100;
/// Name of the default grid fit in tables.
pub const GRID_FIT: &str = "grid";
/// Name of the model search in tables.
pub const SEARCH: &str = "search";
/// Name of the model search with `--noise-aware-bound` in tables.
pub const SEARCH_NOISE: &str = "search-noise";
/// Name of the default fit (`fluorite fit` with no options: the grid fit, escalated to
/// the search where it misses) in tables.
pub const DEFAULT_FIT: &str = "default";
/// The methods of a sweep, in the order each case lists them.
pub const METHODS: [&str; 4] = [GRID_FIT, SEARCH, SEARCH_NOISE, DEFAULT_FIT];
/// How many of the worst cases against the truth the report lists per method.
pub const WORST_LISTED: usize = 10;

/// What to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClassConfig {
    /// Number of cases.
    pub cases: usize,
    /// Seed of the draws.
    pub seed: u64,
    /// The axis the drawn bands are Gaussian in (wavelength unless asked otherwise): drawn
    /// from the same random numbers with bands Gaussian in wavenumber, the class asks
    /// whether a choice it makes holds where its truth is of the other shape (the draws
    /// the synthesiser refuses depend on the shape, so from the first refused in one
    /// shape only, the two classes' cases differ).
    pub truth_bands: BandDomain,
    /// The band axis of the searches (`search`, `search-noise` and the default fit's
    /// escalation): `--band-axis`.
    pub band_axis: BandAxisChoice,
}

impl Default for ClassConfig {
    fn default() -> Self {
        ClassConfig {
            cases: DEFAULT_CASES,
            seed: DEFAULT_SEED,
            truth_bands: BandDomain::Wavelength,
            band_axis: BandAxisChoice::Both,
        }
    }
}

/// The drawn specs and how many draws the synthesiser refused (and were redrawn).
#[derive(Debug, Clone, PartialEq)]
pub struct Draws {
    /// One spec per case, named `case000`, `case001`, ...
    pub specs: Vec<SynthSpec>,
    /// Draws [`SynthSpec::generate`] refused (e.g. Σ c·a > 1).
    pub refused: usize,
}

/// One method's fit of one case.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodResult {
    /// One of [`METHODS`].
    pub method: String,
    /// The error `fit` returned, if any.
    pub error: Option<String>,
    /// The fitted model (`tabulated`, `gaussian:…`).
    pub model: String,
    /// Largest ΔE2000 over the four standard lights against the measurement (the fit
    /// report's); ∞ when the fit failed.
    pub delta_e_measurement: f64,
    /// Largest ΔE2000 over the four standard lights against the true material; ∞ when
    /// the fit failed.
    pub delta_e_truth: f64,
    /// Whether the search met its bound (None for the grid fit and the default fit); for
    /// [`SEARCH_NOISE`], its noise-widened bounds.
    pub bound_met: Option<bool>,
    /// Fluorophores fitted.
    pub fluorophores: usize,
    /// Wall time of the fit (ms).
    pub ms: f64,
    /// The fitted material, its report included (None when the fit failed).
    pub material: Option<Box<Material>>,
}

/// One case: what was drawn and every method's fit.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// Name (`case000`, ...).
    pub name: String,
    /// What was drawn: [`SynthSpec::generate`] makes the measurement and the truth.
    pub spec: SynthSpec,
    /// Fluorophores of the truth.
    pub true_fluorophores: usize,
    /// Excitation grid step (nm).
    pub step_nm: f64,
    /// Noise σ.
    pub noise_sigma: f64,
    /// Crosstalk fraction.
    pub crosstalk: f64,
    /// Share of missing cells.
    pub missing_fraction: f64,
    /// Largest ΔE2000 over the four standard lights between the measured colour (the
    /// cells as measured, noise and crosstalk included, missing cells filled from the
    /// truth) and the truth's, both on the measurement's grids: what no fit controls. A
    /// fit within b of the measured colour is about this − b or more from the truth.
    pub measured_colour_truth: f64,
    /// The case's dye-free twin fitted by the grid fit: see [`DyeFreeTwin`].
    pub dye_free: DyeFreeTwin,
    /// One fit per method, in the order of [`METHODS`].
    pub results: Vec<MethodResult>,
}

/// A case drawn again without its fluorophores (the same reflectance, grid, noise,
/// crosstalk and missing cells) and fitted with the grid fit, which the searches start
/// from and keep as it is when it finds no fluorescence: it must stay a plain reflector.
#[derive(Debug, Clone, PartialEq)]
pub struct DyeFreeTwin {
    /// Fluorophores the grid fit gave it (0: a plain reflector, as it should be).
    pub fluorophores: usize,
    /// Largest ΔE2000 over the four standard lights between that fit and its truth (∞
    /// when the fit failed).
    pub delta_e_truth: f64,
    /// The error the fit returned, if any.
    pub error: Option<String>,
}

/// A whole sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct ClassSweep {
    /// What was drawn.
    pub config: ClassConfig,
    /// Draws the synthesiser refused.
    pub refused: usize,
    /// The cases in draw order.
    pub cases: Vec<Case>,
}

/// Distribution of one ΔE2000 over the successful fits of a group of cases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeltaEStats {
    /// Fits counted.
    pub n: usize,
    /// Median.
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Maximum.
    pub max: f64,
    /// Share at most 1.
    pub within_1: f64,
    /// Share at most 2.
    pub within_2: f64,
}

/// ΔE2000 statistics over all cases and split by the truth's fluorophore count.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplitStats {
    /// Every case.
    pub all: DeltaEStats,
    /// Truths with one fluorophore.
    pub one: DeltaEStats,
    /// Truths with two fluorophores.
    pub two: DeltaEStats,
}

/// Summary of one method over the sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct MethodSummary {
    /// Method name.
    pub method: String,
    /// Cases.
    pub cases: usize,
    /// Fits that returned an error.
    pub errors: usize,
    /// Fits that met the search's bound (None for the grid fit).
    pub bound_met: Option<usize>,
    /// Fits whose fluorophore count equals the truth's.
    pub fluorophores_right: usize,
    /// ΔE2000 against the measurement.
    pub measurement: SplitStats,
    /// ΔE2000 against the truth.
    pub truth: SplitStats,
    /// Wall time median, 90th percentile and maximum (ms).
    pub ms: [f64; 3],
}

fn uniform(rng: &mut SplitMix64, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.uniform()
}

/// One fluorescent component: absorption and emission bands, c, yield and form.
fn draw_component(rng: &mut SplitMix64) -> SynthComponent {
    let peak = uniform(rng, 300.0, 620.0);
    let mut absorption = vec![Band {
        centre_nm: peak,
        width_nm: uniform(rng, 10.0, 50.0),
        weight: 1.0,
    }];
    if rng.uniform() < 0.5 {
        let centre_nm = (peak - uniform(rng, 40.0, 150.0)).max(290.0);
        absorption.push(Band {
            centre_nm,
            width_nm: uniform(rng, 15.0, 50.0),
            weight: uniform(rng, 0.1, 0.5),
        });
    }
    let shift = uniform(rng, 15.0, 120.0);
    let mut emission_peak = (peak + shift).min(760.0);
    // Emission below the emission grid (380 nm) would be unmeasurable: move it onto it.
    if emission_peak < 380.0 {
        emission_peak = 380.0 + uniform(rng, 0.0, 40.0);
    }
    let emission_width = uniform(rng, 10.0, 45.0);
    let mut emission = vec![Band {
        centre_nm: emission_peak,
        width_nm: emission_width,
        weight: 1.0,
    }];
    if rng.uniform() < 0.5 {
        emission.push(Band {
            centre_nm: emission_peak + uniform(rng, 15.0, 40.0),
            width_nm: emission_width * uniform(rng, 1.0, 1.6),
            weight: uniform(rng, 0.2, 0.5),
        });
    }
    let concentration = uniform(rng, 0.1, 1.0);
    let yield_fraction_of_limit = uniform(rng, 0.3, 1.0);
    let yield_form = if rng.uniform() < 0.2 {
        YieldForm::Photon
    } else {
        YieldForm::Energy
    };
    SynthComponent {
        absorption,
        emission,
        concentration,
        yield_fraction_of_limit,
        yield_form,
    }
}

/// One spec (the scratch sweep's draw order, so its seed reproduces its cases).
fn draw_spec(rng: &mut SplitMix64, name: String) -> SynthSpec {
    let two = rng.uniform() < 0.3;
    let first = draw_component(rng);
    let components = if two {
        vec![draw_component(rng)]
    } else {
        vec![]
    };
    let reflectance_low = uniform(rng, 0.02, 0.6);
    let reflectance_high = uniform(rng, (reflectance_low + 0.05).max(0.5), 0.95);
    let reflectance_edge_nm = uniform(rng, 380.0, 650.0);
    let reflectance_width_nm = uniform(rng, 10.0, 40.0);
    let (low, high) = (1e-4f64.ln(), 3e-3f64.ln());
    let noise_sigma = (low + (high - low) * rng.uniform()).exp();
    let crosstalk = uniform(rng, 0.0, 0.05);
    let missing_fraction = uniform(rng, 0.0, 0.05);
    let g = rng.uniform();
    let step = if g < 0.2 {
        5.0
    } else if g < 0.3 {
        20.0
    } else {
        10.0
    };
    SynthSpec {
        name,
        excitation_nm: uniform_grid(300.0, 780.0, step),
        emission_nm: uniform_grid(380.0, 780.0, step),
        absorption: first.absorption,
        emission: first.emission,
        reflectance_low,
        reflectance_high,
        reflectance_edge_nm,
        reflectance_width_nm,
        concentration: first.concentration,
        yield_fraction_of_limit: first.yield_fraction_of_limit,
        yield_form: first.yield_form,
        components,
        band_axis: BandDomain::Wavelength,
        noise_sigma,
        crosstalk,
        missing_fraction,
        seed: rng.next_u64(),
    }
}

/// Draws `config.cases` specs the synthesiser accepts, redrawing (and counting) those
/// it refuses. Deterministic in `config.seed`.
pub fn draw(config: &ClassConfig) -> Result<Draws> {
    let mut rng = SplitMix64::new(config.seed);
    let mut specs = Vec::with_capacity(config.cases);
    let mut refused = 0;
    while specs.len() < config.cases {
        let spec = SynthSpec {
            band_axis: config.truth_bands,
            ..draw_spec(&mut rng, format!("case{:03}", specs.len()))
        };
        if spec.generate().is_ok() {
            specs.push(spec);
        } else {
            refused += 1;
            if refused > MAX_REFUSALS_PER_CASE * config.cases.max(1) {
                return Err(Error::invalid(
                    "--seed",
                    format!(
                        "the synthesiser refused {refused} draws for {} accepted; try another seed",
                        specs.len()
                    ),
                ));
            }
        }
    }
    Ok(Draws { specs, refused })
}

/// The grid fit's options: one fluorophore on the grid (`--model tabulated`), never
/// escalated.
pub fn grid_options() -> FitOptions {
    FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    }
}

/// The search's options: the parametric model search under the bound, on `band_axis`.
fn search_options(band_axis: BandAxisChoice) -> FitOptions {
    FitOptions {
        model: ModelChoice::Auto,
        max_delta_e: Some(SEARCH_BOUND),
        band_axis,
        ..FitOptions::default()
    }
}

/// The search with `--noise-aware-bound`: each light held to max(bound, 3 × its measured
/// colour's noise RMS, at most the grid fit's ΔE2000 + bound), its colour term weighed by
/// that noise.
fn noise_aware_search_options(band_axis: BandAxisChoice) -> FitOptions {
    FitOptions {
        noise_aware_bound: true,
        ..search_options(band_axis)
    }
}

/// Whether `method` is one of the searches (which report whether they met their bound).
fn is_search(method: &str) -> bool {
    method == SEARCH || method == SEARCH_NOISE
}

/// Fits `measurement` with `options` and compares with the measurement and the truth.
fn fit_one(method: &str, options: &FitOptions, m: &Measurement, truth: &Material) -> MethodResult {
    let start = Instant::now();
    let outcome = fit(m, options);
    let ms = start.elapsed().as_secs_f64() * 1e3;
    let mut result = MethodResult {
        method: method.to_string(),
        error: None,
        model: String::new(),
        delta_e_measurement: f64::INFINITY,
        delta_e_truth: f64::INFINITY,
        bound_met: None,
        fluorophores: 0,
        ms,
        material: None,
    };
    let material = match outcome {
        Ok(FitOutcome::Material(material)) => *material,
        Ok(FitOutcome::Shapes(_)) => {
            result.error = Some("fit returned shapes, not a material".into());
            return result;
        }
        Err(e) => {
            result.error = Some(e.to_string());
            return result;
        }
    };
    let Some(report) = &material.fit else {
        result.error = Some("fit returned a material without its report".into());
        return result;
    };
    result.model = report.model.clone();
    result.delta_e_measurement = report.delta_e2000.values().copied().fold(0.0, f64::max);
    // The default fit's search, where it escalated, ran under the default's own bounds.
    result.bound_met = is_search(method)
        .then(|| report.model_search.as_ref().map(|s| s.met))
        .flatten();
    result.fluorophores = material.fluorophores.len();
    result.delta_e_truth = material_delta_e(&material, truth, &Light::standard());
    result.material = Some(Box::new(material));
    result
}

/// One case: generate, fit with every method (the searches on `band_axis`).
fn run_case(spec: &SynthSpec, band_axis: BandAxisChoice) -> Result<Case> {
    let (m, truth) = spec.generate()?;
    let measured_colour_truth = measured_colour_delta_e(&m, &truth);
    let dye_free = dye_free_twin(spec)?;
    let results = vec![
        fit_one(GRID_FIT, &grid_options(), &m, &truth),
        fit_one(SEARCH, &search_options(band_axis), &m, &truth),
        fit_one(
            SEARCH_NOISE,
            &noise_aware_search_options(band_axis),
            &m,
            &truth,
        ),
        fit_one(
            DEFAULT_FIT,
            &FitOptions {
                band_axis,
                ..FitOptions::default()
            },
            &m,
            &truth,
        ),
    ];
    Ok(Case {
        name: spec.name.clone(),
        spec: spec.clone(),
        true_fluorophores: truth.fluorophores.len(),
        step_nm: median_step(&spec.excitation_nm),
        noise_sigma: spec.noise_sigma,
        crosstalk: spec.crosstalk,
        missing_fraction: spec.missing_fraction,
        measured_colour_truth,
        dye_free,
        results,
    })
}

/// `spec` without its fluorophores, fitted with the grid fit ([`DyeFreeTwin`]).
fn dye_free_twin(spec: &SynthSpec) -> Result<DyeFreeTwin> {
    let (m, truth) = spec.dye_free_twin().generate()?;
    let grid = fit_one(GRID_FIT, &grid_options(), &m, &truth);
    Ok(DyeFreeTwin {
        fluorophores: grid.fluorophores,
        delta_e_truth: grid.delta_e_truth,
        error: grid.error,
    })
}

/// Largest ΔE2000 over the four standard lights between the patch colour of the cells of
/// `m` (missing cells filled from `truth`) and of `truth`, on the grids of `m`: how far
/// the colour a bound is judged against lies from the truth, whatever is fitted.
pub fn measured_colour_delta_e(m: &Measurement, truth: &Material) -> f64 {
    let true_cells = crate::model::predict_like(truth, m).to_per_bin();
    let measured = m.to_per_bin().filled_from(&true_cells);
    Light::standard()
        .iter()
        .map(|light| {
            let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
            delta_e2000(pc.lab(&measured), pc.lab(&true_cells))
        })
        .fold(0.0, f64::max)
}

/// Draws the cases and fits each with every method of [`METHODS`], in parallel over
/// cases (the results do not depend on the order; only the times do).
pub fn run(config: &ClassConfig) -> Result<ClassSweep> {
    run_named(config, &[])
}

/// Like [`run`], but fits only the cases of the draw named in `names` (`case069`, ...;
/// every case when `names` is empty), in the draw's order. A case is the same whatever
/// else is fitted: the draws depend only on the seed.
pub fn run_named(config: &ClassConfig, names: &[String]) -> Result<ClassSweep> {
    let draws = draw(config)?;
    if let Some(unknown) = names
        .iter()
        .find(|name| !draws.specs.iter().any(|s| &s.name == *name))
    {
        return Err(Error::invalid(
            "--case",
            format!(
                "no case \"{unknown}\" among the {} drawn; give names case000–case{:03} (or raise --cases)",
                draws.specs.len(),
                draws.specs.len().saturating_sub(1)
            ),
        ));
    }
    let cases = draws
        .specs
        .par_iter()
        .filter(|s| names.is_empty() || names.contains(&s.name))
        .map(|spec| run_case(spec, config.band_axis))
        .collect::<Result<Vec<_>>>()?;
    Ok(ClassSweep {
        config: *config,
        refused: draws.refused,
        cases,
    })
}

fn stats(values: &[f64]) -> DeltaEStats {
    let n = values.len();
    let share = |limit: f64| values.iter().filter(|&&v| v <= limit).count() as f64 / n as f64;
    DeltaEStats {
        n,
        median: quantile(values, 0.5),
        p90: quantile(values, 0.9),
        max: values.iter().copied().fold(f64::NAN, f64::max),
        within_1: share(1.0),
        within_2: share(2.0),
    }
}

/// The (case, result) pairs of `method`.
fn of_method<'a>(sweep: &'a ClassSweep, method: &'a str) -> Vec<(&'a Case, &'a MethodResult)> {
    sweep
        .cases
        .iter()
        .flat_map(|c| c.results.iter().map(move |r| (c, r)))
        .filter(|(_, r)| r.method == method)
        .collect()
}

/// Statistics of `values`, (the truth's fluorophore count, value) pairs, over all of them
/// and split by that count.
fn split_by_dyes(values: &[(usize, f64)]) -> SplitStats {
    let select = |k: Option<usize>| -> Vec<f64> {
        values
            .iter()
            .filter(|(dyes, _)| k.is_none_or(|k| *dyes == k))
            .map(|(_, v)| *v)
            .collect()
    };
    SplitStats {
        all: stats(&select(None)),
        one: stats(&select(Some(1))),
        two: stats(&select(Some(2))),
    }
}

fn split_stats(pairs: &[(&Case, &MethodResult)], value: fn(&MethodResult) -> f64) -> SplitStats {
    let values: Vec<(usize, f64)> = pairs
        .iter()
        .filter(|(_, r)| r.error.is_none())
        .map(|(c, r)| (c.true_fluorophores, value(r)))
        .collect();
    split_by_dyes(&values)
}

/// The measured colour's own ΔE2000 from the truth ([`Case::measured_colour_truth`]),
/// over all cases and split by the truth's fluorophore count.
pub fn measured_colour_floor(sweep: &ClassSweep) -> SplitStats {
    let values: Vec<(usize, f64)> = sweep
        .cases
        .iter()
        .map(|c| (c.true_fluorophores, c.measured_colour_truth))
        .collect();
    split_by_dyes(&values)
}

/// One summary per method ([`METHODS`]).
pub fn summarise(sweep: &ClassSweep) -> Vec<MethodSummary> {
    METHODS
        .iter()
        .map(|&method| {
            let pairs = of_method(sweep, method);
            let ms: Vec<f64> = pairs.iter().map(|(_, r)| r.ms).collect();
            MethodSummary {
                method: method.to_string(),
                cases: pairs.len(),
                errors: pairs.iter().filter(|(_, r)| r.error.is_some()).count(),
                bound_met: is_search(method).then(|| {
                    pairs
                        .iter()
                        .filter(|(_, r)| r.bound_met == Some(true))
                        .count()
                }),
                fluorophores_right: pairs
                    .iter()
                    .filter(|(c, r)| r.error.is_none() && r.fluorophores == c.true_fluorophores)
                    .count(),
                measurement: split_stats(&pairs, |r| r.delta_e_measurement),
                truth: split_stats(&pairs, |r| r.delta_e_truth),
                ms: [
                    quantile(&ms, 0.5),
                    quantile(&ms, 0.9),
                    ms.iter().copied().fold(f64::NAN, f64::max),
                ],
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_deterministic_and_in_range() {
        let config = ClassConfig {
            cases: 40,
            seed: 7,
            ..ClassConfig::default()
        };
        let a = draw(&config).unwrap();
        assert_eq!(a, draw(&config).unwrap());
        assert_eq!(a.specs.len(), 40);
        for s in &a.specs {
            assert!((1e-4..=3e-3).contains(&s.noise_sigma));
            assert!((0.0..=0.05).contains(&s.crosstalk));
            assert!(s.components.len() <= 1);
            assert!((300.0..=620.0).contains(&s.absorption[0].centre_nm));
            assert!([5.0, 10.0, 20.0].contains(&median_step(&s.excitation_nm)));
        }
    }

    #[test]
    fn stats_of_known_values() {
        let s = stats(&[0.5, 1.0, 1.5, 3.0]);
        assert_eq!((s.n, s.max, s.within_1, s.within_2), (4, 3.0, 0.5, 0.75));
        assert_eq!(s.median, 1.25);
    }
}

//! Joint fit of a surface concentration series: several reradiation
//! matrices of one material at different concentrations, with shared r, a, e and yield
//! and one concentration c_j per file.
//!
//! One matrix identifies only k = c·Q off the diagonal and d = (1 − c·a)·r on it
//! (model.md §4): c is a gauge. Across files at different concentrations the diagonals
//! d_j = (1 − c_j·a)·r fall where the material absorbs as c_j rises, while k_j = c_j·Q
//! rises in proportion; that separates c_j from Q. The fit stacks every file's cells into
//! one least-squares problem ([`model`]), starts it in closed form ([`start`]) and refines
//! it by Gauss-Newton ([`crate::fit::solve`], through the one runner [`crate::optimise::run`]). Standard errors
//! come from the Gauss-Newton Jacobian at the optimum: covariance σ²·(JᵀJ)⁺ in the
//! physical parameters, with σ the larger of the anti-Stokes noise estimate the single
//! fits report and the residual RMS (so misfit widens the errors).

pub mod model;
pub mod start;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::colour::Light;
use crate::error::{Error, Result};
use crate::fit::data::{FitData, fill_missing, provenance};
use crate::fit::{YieldChoice, assess, solve};
use crate::formats::{ReadOptions, read};
use crate::material::{CrosstalkCorrection, FitReport, Fluorophore, Material, YieldForm};
use crate::measurement::Measurement;
use crate::spectrum::Spectrum;
use model::SeriesModel;

/// Schema tag of a series fit's JSON.
pub const SERIES_SCHEMA: &str = "fluorite-series/1";

/// Concentration ratio (largest over smallest) below which the series is flagged: the
/// diagonals then barely differ and c, Q come with large errors.
const SMALL_SPREAD: f64 = 2.0;

/// Singular values of JᵀJ below this fraction of the largest count as flat directions
/// in the pseudo-inverse (parameters the data do not constrain get no error from them).
const PSEUDO_INVERSE_RTOL: f64 = 1e-14;

/// How to fit a series.
#[derive(Debug, Clone)]
pub struct SeriesOptions {
    /// The yield form: constant energy yield Q (the paper's), constant photon yield Φ,
    /// or `Auto`: both fitted, the photon form taken only when it fits clearly better
    /// (a series can tell them apart: the diagonal sees a, the fluorescence a·Q(λ)).
    pub yield_choice: YieldChoice,
    /// Cells within this many nm of the diagonal are set aside (default: none).
    pub guard_nm: Option<f64>,
    /// Gauss-Newton iteration limit.
    pub max_iterations: u64,
    /// Stop when an iteration changes the residual norm ‖r‖ by less than this fraction of
    /// the data's norm ‖M‖.
    pub tolerance: f64,
    /// Lights of the per-file ΔE2000.
    pub lights: Vec<Light>,
    /// How [`run`] reads the files.
    pub read: ReadOptions,
}

impl Default for SeriesOptions {
    fn default() -> Self {
        SeriesOptions {
            yield_choice: YieldChoice::Auto,
            guard_nm: None,
            max_iterations: 100,
            tolerance: 1e-9,
            lights: Light::standard(),
            read: ReadOptions::default(),
        }
    }
}

/// One file of a series: its concentration and how well the shared material fits it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesFile {
    /// The measurement's name (file stem).
    pub name: String,
    /// The file fitted (or the name when not read from a file).
    pub source: String,
    /// SHA-256 of the file, hex (empty when not read from a file).
    pub source_sha256: String,
    /// c_j, fraction absorbed at the absorption peak.
    pub concentration: f64,
    /// Its propagated standard error.
    pub concentration_std_error: f64,
    /// k_j = c_j·Q (c_j·Φ in the photon form).
    pub k: f64,
    /// Its propagated standard error.
    pub k_std_error: f64,
    /// Noise σ of this file (robust, anti-Stokes cells).
    pub noise_sigma: f64,
    /// RMS of this file's residuals over the fitted cells.
    pub residual_rms: f64,
    /// ‖M − F‖/‖M‖ over the Stokes cells.
    pub rel_residual_fluorescence: f64,
    /// RMSE of the diagonal.
    pub rmse_diagonal: f64,
    /// ΔE2000 of a flat patch of this file's material against the file, per light.
    pub delta_e2000: BTreeMap<String, f64>,
    /// Crosstalk next to the diagonal found in this file and taken out of its cells before
    /// the joint fit, as a single fit does (fitting.md); every ΔE2000 is still against
    /// the cells as measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crosstalk: Option<CrosstalkCorrection>,
}

/// A fitted concentration series: the shared spectra and yield, and per file c.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SeriesFit {
    /// Always [`SERIES_SCHEMA`].
    pub schema: String,
    /// r(λ) of the non-fluorescent part, shared.
    pub reflectance: Spectrum,
    /// a(λ), max 1, shared.
    pub absorption: Spectrum,
    /// e(λ) in 1/nm, ∫e = 1, shared.
    pub emission: Spectrum,
    /// Which yield is constant over the excitation wavelength.
    pub yield_form: YieldForm,
    /// Why that form, in words.
    pub yield_choice: String,
    /// The yield of that form: energy Q or photon Φ.
    pub quantum_yield: f64,
    /// Its propagated standard error.
    pub quantum_yield_std_error: f64,
    /// The files, in input order.
    pub files: Vec<SeriesFile>,
    /// Pooled noise σ of the files (RMS of their robust anti-Stokes estimates).
    pub noise_sigma: f64,
    /// RMS of all residuals, with the degrees of freedom the fit used taken out.
    pub residual_sigma: f64,
    /// The σ the standard errors are scaled by: the larger of the two above.
    pub error_sigma: f64,
    /// Gauss-Newton iterations.
    pub iterations: u64,
    /// Whether Gauss-Newton met its tolerance.
    pub converged: bool,
    /// Objective ½‖r‖² per iteration, the closed-form start first.
    pub cost_history: Vec<f64>,
    /// Wall time (seconds).
    pub seconds: f64,
    /// Where not to trust the result.
    pub warnings: Vec<String>,
}

impl SeriesFit {
    /// The complete material of file `file` (the shared spectra and yield with its c),
    /// with a fit block naming the file and the series gauge.
    pub fn material_for(&self, file: usize) -> Material {
        let f = &self.files[file];
        let mut material = Material::new(
            f.name.clone(),
            self.reflectance.clone(),
            vec![Fluorophore {
                concentration: f.concentration,
                quantum_yield: self.quantum_yield,
                yield_form: self.yield_form,
                concentration_range: None,
                absorption: self.absorption.clone(),
                emission: self.emission.clone(),
            }],
        );
        material.fit = Some(FitReport {
            source: f.source.clone(),
            source_sha256: f.source_sha256.clone(),
            solver: "gauss-newton".into(),
            converged: self.converged,
            iterations: self.iterations,
            seconds: self.seconds,
            gauge: format!(
                "concentration series of {} files: c = {:.4} ± {:.4} separated from the yield by how the diagonals fall as c rises",
                self.files.len(),
                f.concentration,
                f.concentration_std_error
            ),
            rel_residual_fluorescence: f.rel_residual_fluorescence,
            rmse_diagonal: f.rmse_diagonal,
            delta_e2000: f.delta_e2000.clone(),
            warnings: self.warnings.clone(),
            noise_sigma: f.noise_sigma,
            model: "tabulated series".into(),
            yield_choice: self.yield_choice.clone(),
            cost_history: self.cost_history.clone(),
            ..FitReport::default()
        });
        material
    }

    /// Writes the series into folder `dir` (created if missing), all files or none:
    /// `<stem>.json` (this fit, `fluorite-series/1`) and one material per file,
    /// `<file name>.json` (`fluorite-material/1`, for check, plot, export and render).
    /// Returns the paths written.
    pub fn write(&self, dir: &Path, stem: &str) -> Result<Vec<PathBuf>> {
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mut files = vec![(
            dir.join(format!("{stem}.json")),
            self.to_json().into_bytes(),
        )];
        for (j, f) in self.files.iter().enumerate() {
            let path = dir.join(format!("{}.json", f.name));
            if files.iter().any(|(p, _)| *p == path) {
                return Err(Error::invalid(
                    "FILES",
                    format!(
                        "two outputs would be {}; give the files distinct names, or the series another stem",
                        path.display()
                    ),
                ));
            }
            files.push((path, self.material_for(j).to_json().into_bytes()));
        }
        crate::files::write_files(&files)?;
        Ok(files.into_iter().map(|(p, _)| p).collect())
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("a series fit serialises");
        s.push('\n');
        s
    }
}

/// Reads `paths` (see [`SeriesOptions::read`]) and fits them as one concentration series.
pub fn run(paths: &[PathBuf], options: &SeriesOptions) -> Result<SeriesFit> {
    let measurements = paths
        .iter()
        .map(|p| read(p, &options.read))
        .collect::<Result<Vec<_>>>()?;
    fit_concentration_series(&measurements, options)
}

/// The name a measurement goes by in messages: its file, else its name.
fn label(m: &Measurement) -> String {
    m.source
        .as_deref()
        .map(Path::display)
        .map(|p| p.to_string())
        .unwrap_or_else(|| m.name.clone())
}

/// Checks that `measurements` can form a series: two or more calibrated surface matrices
/// on one pair of grids, in one unit.
fn validate(measurements: &[Measurement], options: &SeriesOptions) -> Result<()> {
    if measurements.len() < 2 {
        return Err(Error::invalid(
            "FILES",
            format!(
                "a concentration series needs at least two matrices of one material at different concentrations, got {}; one matrix identifies only k = c·Q (fit it alone with `fluorite fit`)",
                measurements.len()
            ),
        ));
    }
    crate::fit::options::validate_refinement(
        options.guard_nm,
        options.max_iterations,
        options.tolerance,
    )?;
    let first = &measurements[0];
    let same = |a: &[f64], b: &[f64]| {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-6)
    };
    for m in measurements {
        m.validate()?;
        let verdict = crate::eem::units::classify(m);
        if !m.has_diagonal || m.arbitrary_scale || !verdict.radiance_factor {
            return Err(Error::invalid(
                label(m),
                format!(
                    "is not a calibrated surface matrix with a diagonal ({}); a concentration series needs radiance-factor matrices whose diagonal (reflectance) is measured",
                    verdict.reason
                ),
            ));
        }
        if !same(&m.excitation_nm, &first.excitation_nm)
            || !same(&m.emission_nm, &first.emission_nm)
            || m.units != first.units
        {
            return Err(Error::invalid(
                label(m),
                format!(
                    "its grids or units differ from {}'s; measure every concentration with the same instrument settings",
                    label(first)
                ),
            ));
        }
        if m.diagonal().is_empty() {
            return Err(Error::invalid(
                label(m),
                "its excitation and emission grids share no wavelength, so it has no diagonal; the diagonal is what separates c from Q",
            ));
        }
    }
    Ok(())
}

/// Fits `measurements` (two or more matrices of one material at different
/// concentrations, same grids) with shared r, a, e and yield and one c per file.
pub fn fit_concentration_series(
    measurements: &[Measurement],
    options: &SeriesOptions,
) -> Result<SeriesFit> {
    let started = Instant::now();
    validate(measurements, options)?;
    let guard_nm = options.guard_nm.unwrap_or(0.0);
    // The instrument's crosstalk next to the diagonal, per file, out of the cells the joint
    // fit sees (the one-fluorophore model holds none; a single fit removes it too).
    let files: Vec<FitData> = measurements
        .iter()
        .map(|m| {
            let sigma = FitData::new(m, guard_nm).noise_sigma();
            let found = crate::fit::crosstalk::estimate(m, sigma, &options.lights);
            FitData::with_crosstalk(m, guard_nm, found.as_ref())
        })
        .collect();
    let names: Vec<String> = measurements.iter().map(label).collect();
    let fit_in = |form| fit_form(measurements, &files, &names, form, options);
    let mut fit = match options.yield_choice {
        YieldChoice::Energy | YieldChoice::Photon => {
            let form = match options.yield_choice {
                YieldChoice::Photon => YieldForm::Photon,
                _ => YieldForm::Energy,
            };
            let (mut fit, _) = fit_in(form)?;
            fit.yield_choice = format!("{} form, as asked (--yield {})", form.name(), form.name());
            fit
        }
        YieldChoice::Auto => {
            let (energy, photon) =
                rayon::join(|| fit_in(YieldForm::Energy), || fit_in(YieldForm::Photon));
            choose_form(energy, photon)?
        }
    };
    fit.seconds = started.elapsed().as_secs_f64();
    Ok(fit)
}

/// The better of the two forms' fits (each with its residual sum of squares), with the
/// reason; either alone when the other failed.
fn choose_form(
    energy: Result<(SeriesFit, f64)>,
    photon: Result<(SeriesFit, f64)>,
) -> Result<SeriesFit> {
    let (mut fit, reason) = match (energy, photon) {
        (Ok((energy, e)), Ok((photon, p))) => {
            let objectives = format!("objective ½·RSS {:.4e} against {:.4e}", 0.5 * p, 0.5 * e);
            // The rule single fits choose by.
            if assess::photon_form_fits_better(0.5 * e, 0.5 * p, energy.error_sigma) {
                let reason = format!("photon form (constant Φ): it fits better ({objectives})");
                (photon, reason)
            } else {
                let reason = format!(
                    "energy form (constant Q): the photon form fits no better ({objectives})"
                );
                (energy, reason)
            }
        }
        (Ok((energy, _)), Err(e)) => (
            energy,
            format!("energy form (constant Q): the photon form failed ({e})"),
        ),
        (Err(e), Ok((photon, _))) => (
            photon,
            format!("photon form (constant Φ): the energy form failed ({e})"),
        ),
        (Err(e), Err(_)) => return Err(e),
    };
    fit.yield_choice = reason;
    Ok(fit)
}

/// The series fitted in yield form `form`, with its residual sum of squares.
fn fit_form(
    measurements: &[Measurement],
    files: &[FitData],
    names: &[String],
    form: YieldForm,
    options: &SeriesOptions,
) -> Result<(SeriesFit, f64)> {
    let shapes = start::shapes(files, form, names)?;
    let model = SeriesModel::new(files, form, shapes.peak);
    let theta0 = model.encode(&start::closed_form(&model, &shapes, names)?);
    let start_norm = norm(&model.residuals_of(&model.decode(&theta0)));
    // The tolerance is relative to the data's scale: exact data end at a residual of
    // rounding error, which no relative change of it would reach.
    let data_norm = files
        .iter()
        .flat_map(|d| d.off_diagonal.iter().chain(&d.diagonal))
        .map(|c| c.value * c.value)
        .sum::<f64>()
        .sqrt();
    let stopping = crate::optimise::Stopping {
        max_iterations: options.max_iterations,
        gradient_tolerance: 0.0,
        cost_tolerance: options.tolerance * data_norm.max(1e-300),
    };
    let refined = solve::gauss_newton_model(&model, &theta0, stopping).map_err(Error::Fit)?;
    let params = model.decode(&refined.theta);
    let mut cost_history = vec![0.5 * start_norm * start_norm];
    cost_history.extend(refined.cost_history.iter().filter(|c| c.is_finite()));

    // Noise and the σ of the standard errors.
    let residuals = model.residuals_of(&params);
    let cells = residuals.len() - 1;
    let rss: f64 = residuals[..cells].iter().map(|r| r * r).sum();
    // The gauge row fixes the emission scale, one of the parameters.
    let dof = cells.saturating_sub(model.n_params() - 1).max(1);
    let residual_sigma = (rss / dof as f64).sqrt();
    let file_noise: Vec<f64> = files.iter().map(FitData::noise_sigma).collect();
    let noise_sigma =
        (file_noise.iter().map(|s| s * s).sum::<f64>() / file_noise.len() as f64).sqrt();
    let error_sigma = noise_sigma.max(residual_sigma);
    let covariance = covariance(&model.jacobian_physical(&params), error_sigma);
    let variance = |gradient: &[f64]| -> f64 {
        let g = nalgebra::DVector::from_column_slice(gradient);
        (g.transpose() * &covariance * &g)[(0, 0)].max(0.0)
    };
    let (quantum_yield, yield_gradient) = model.yield_with_gradient(&params);

    // The shared spectra in the material's normalisation.
    let data = &files[0];
    let n = model.normaliser(&params.absorption, &params.emission);
    let absorption = Spectrum::new(
        data.excitation_nm.clone(),
        params.absorption.clone(),
        "absorption",
    )?;
    let emission = Spectrum::new(
        data.emission_nm.clone(),
        data.emission_density(&params.emission, n.sum),
        "emission",
    )?;
    let all_positions = &data.diagonal_positions;
    let wavelengths: Vec<f64> = all_positions
        .iter()
        .map(|&(_, j)| data.emission_nm[j])
        .collect();
    let mut reflectance = vec![f64::NAN; all_positions.len()];
    for (p, position) in model.positions.iter().enumerate() {
        if let Some(q) = all_positions.iter().position(|x| x == position) {
            reflectance[q] = params.reflectance[p];
        }
    }
    fill_missing(
        &mut reflectance,
        &wavelengths,
        &vec![1.0; wavelengths.len()],
        &names.join(", "),
    )?;
    let reflectance = Spectrum::new(wavelengths, reflectance, "reflectance")?;

    let mut offset = 0;
    let mut series_files = Vec::new();
    for (j, (m, data)) in measurements.iter().zip(files).enumerate() {
        let c = params.concentrations[j];
        let mut c_gradient = vec![0.0; model.n_params()];
        c_gradient[model.c_index(j)] = 1.0;
        let k_gradient: Vec<f64> = c_gradient
            .iter()
            .zip(&yield_gradient)
            .map(|(dc, dq)| quantum_yield * dc + c * dq)
            .collect();
        let count = data.off_diagonal.len() + data.diagonal.len();
        let own = &residuals[offset..offset + count];
        offset += count;
        let report = provenance(m);
        series_files.push(SeriesFile {
            name: m.name.clone(),
            source: report.source,
            source_sha256: report.source_sha256,
            concentration: c,
            concentration_std_error: variance(&c_gradient).sqrt(),
            k: c * quantum_yield,
            k_std_error: variance(&k_gradient).sqrt(),
            noise_sigma: file_noise[j],
            residual_rms: norm(own) / (count.max(1) as f64).sqrt(),
            rel_residual_fluorescence: 0.0,
            rmse_diagonal: 0.0,
            delta_e2000: BTreeMap::new(),
            crosstalk: data.crosstalk.clone(),
        });
    }
    let mut fit = SeriesFit {
        schema: SERIES_SCHEMA.into(),
        reflectance,
        absorption,
        emission,
        yield_form: form,
        yield_choice: String::new(),
        quantum_yield,
        quantum_yield_std_error: variance(&yield_gradient).sqrt(),
        files: series_files,
        noise_sigma,
        residual_sigma,
        error_sigma,
        iterations: refined.iterations,
        converged: refined.converged,
        cost_history,
        seconds: 0.0,
        warnings: Vec::new(),
    };
    // Per-file accuracy of the shared material with that file's c, as single fits report it.
    for (j, (m, data)) in measurements.iter().zip(files).enumerate() {
        let material = fit.material_for(j);
        if let Err(e) = material.validate() {
            fit.warnings.push(format!(
                "{}: the material with c = {:.4} breaks a constraint ({e})",
                names[j], fit.files[j].concentration
            ));
        }
        let accuracy = assess::accuracy(&material, m, data, &options.lights);
        let file = &mut fit.files[j];
        file.rel_residual_fluorescence = accuracy.rel_residual_fluorescence;
        file.rmse_diagonal = accuracy.rmse_diagonal;
        file.delta_e2000 = accuracy.delta_e2000;
    }
    fit.warnings.extend(warnings(&fit, &refined, names));
    Ok((fit, rss))
}

/// The warnings of a finished series fit.
fn warnings(fit: &SeriesFit, refined: &crate::optimise::Refined, names: &[String]) -> Vec<String> {
    let mut out = Vec::new();
    if !refined.converged {
        out.push(format!(
            "Gauss-Newton stopped before converging ({}) after {} iterations; raise the iteration limit",
            refined.termination, refined.iterations
        ));
    }
    let (lo, hi) = fit
        .files
        .iter()
        .map(|f| f.concentration)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), c| {
            (lo.min(c), hi.max(c))
        });
    if hi < SMALL_SPREAD * lo {
        out.push(format!(
            "the concentrations span only {lo:.3}–{hi:.3} (a factor {:.2}): the diagonals barely differ, so c and Q are poorly separated; add a concentration at least {SMALL_SPREAD}× lower or higher",
            hi / lo
        ));
    }
    // Exact (synthetic) data have a noise estimate of rounding error; below a floor
    // relative to the signal a residual is not worth a warning.
    let signal = fit.reflectance.max().max(1e-300);
    if fit.residual_sigma > (assess::RESIDUAL_NOISE_FACTOR * fit.noise_sigma).max(1e-7 * signal) {
        out.push(format!(
            "residual σ {:.2e} is {:.1}× the noise σ {:.2e}: the files hold structure one material with shared spectra does not explain (another material, another instrument setting, or several fluorophores); the errors are scaled by the residual",
            fit.residual_sigma,
            fit.residual_sigma / fit.noise_sigma.max(1e-300),
            fit.noise_sigma
        ));
    }
    for (f, name) in fit.files.iter().zip(names) {
        if f.concentration >= 0.999 {
            out.push(format!(
                "{name}: c = {:.4} sits at its bound 1; its error is not meaningful",
                f.concentration
            ));
        }
    }
    out
}

fn norm(values: &[f64]) -> f64 {
    values.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// σ²·(JᵀJ)⁺: the parameters' covariance from the Jacobian at the optimum.
fn covariance(jacobian: &DMatrix<f64>, sigma: f64) -> DMatrix<f64> {
    let normal = jacobian.transpose() * jacobian;
    let (rows, columns) = normal.shape();
    let largest = normal.diagonal().max().max(1e-300);
    match normal.pseudo_inverse(PSEUDO_INVERSE_RTOL * largest) {
        Ok(inverse) => inverse * (sigma * sigma),
        Err(_) => DMatrix::from_element(rows, columns, f64::NAN),
    }
}

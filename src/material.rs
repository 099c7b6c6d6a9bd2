//! The fitted material: the contract between fitting and everything downstream
//! (check, export, plot, render). Serialised as `fluorite-material/1` JSON.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::parametric::MaterialForms;
use crate::spectrum::Spectrum;

/// Schema tag written into every material file.
pub const SCHEMA: &str = "fluorite-material/1";

/// A diffuse fluorescent material (Jung et al. 2018), possibly with several fluorophores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Material {
    /// Always [`SCHEMA`].
    pub schema: String,
    /// A short name (the measurement's file stem for fits).
    pub name: String,
    /// r(λ): reflectance of the non-fluorescent part; holds its end values outside its samples.
    pub reflectance: Spectrum,
    /// The fluorescent components (one for the paper's model; empty for a plain reflector).
    pub fluorophores: Vec<Fluorophore>,
    /// How the material was fitted; absent for hand-written materials.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitReport>,
    /// Conservation margins, recomputed whenever a material is written.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub conservation: Option<Conservation>,
    /// Continuous forms of the spectra (parametric fits); the tabulated spectra above are
    /// these forms sampled finely, and everything downstream reads the samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub forms: Option<MaterialForms>,
}

/// Which quantum yield of a fluorophore is constant over the excitation wavelength
/// (model.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Hash)]
#[serde(rename_all = "lowercase")]
pub enum YieldForm {
    /// The paper's form: a constant energy yield Q (emitted / absorbed energy). Photon
    /// conservation then caps Q at λmin/λ̄e for every row. A file without `yield_form`
    /// has this meaning.
    #[default]
    Energy,
    /// A constant photon yield Φ (emitted / absorbed photons, Kasha–Vavilov): the energy
    /// yield is Φ·λi/λ̄e, photon-conserving for every Φ ≤ 1.
    Photon,
}

impl YieldForm {
    /// The name written into material files and reports (`energy`, `photon`).
    pub fn name(self) -> &'static str {
        match self {
            YieldForm::Energy => "energy",
            YieldForm::Photon => "photon",
        }
    }

    /// Whether this is the default (energy) form; such files omit the field.
    pub fn is_energy(&self) -> bool {
        *self == YieldForm::Energy
    }
}

/// One fluorescent component.
///
/// In JSON the yield is `quantum_yield` (Q) in the energy form and `photon_yield` (Φ)
/// beside `"yield_form": "photon"` in the photon form, so a reader that knows only the
/// energy form fails on a photon-form file instead of misreading Φ as Q.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "FluorophoreFile", into = "FluorophoreFile")]
pub struct Fluorophore {
    /// c: fraction absorbed at the absorption peak, in [0, 1].
    pub concentration: f64,
    /// The yield of the fluorophore's form, in [0, 1]: the energy quantum yield Q (emitted
    /// / absorbed energy) in the energy form, the photon quantum yield Φ (emitted /
    /// absorbed photons) in the photon form.
    pub quantum_yield: f64,
    /// Which yield is constant over the excitation wavelength.
    pub yield_form: YieldForm,
    /// The interval of c for which every constraint holds given the data (c and Q are not
    /// separately identifiable; only k = c·Q is).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub concentration_range: Option<[f64; 2]>,
    /// a(λ): absorption, max 1, zero outside its samples.
    pub absorption: Spectrum,
    /// e(λ): emission density in 1/nm, ∫e = 1, zero outside its samples.
    pub emission: Spectrum,
}

/// The JSON layout of a [`Fluorophore`].
#[derive(Serialize, Deserialize)]
struct FluorophoreFile {
    concentration: f64,
    #[serde(default, skip_serializing_if = "YieldForm::is_energy")]
    yield_form: YieldForm,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    quantum_yield: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    photon_yield: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    concentration_range: Option<[f64; 2]>,
    absorption: Spectrum,
    emission: Spectrum,
}

impl TryFrom<FluorophoreFile> for Fluorophore {
    type Error = String;

    fn try_from(f: FluorophoreFile) -> std::result::Result<Self, String> {
        let quantum_yield = match (f.yield_form, f.quantum_yield, f.photon_yield) {
            (YieldForm::Energy, Some(q), None) => q,
            (YieldForm::Photon, None, Some(phi)) => phi,
            (YieldForm::Energy, _, Some(_)) => {
                return Err(
                    "a fluorophore with `photon_yield` needs \"yield_form\": \"photon\"".into(),
                );
            }
            (YieldForm::Photon, Some(_), _) => {
                return Err(
                    "a photon-form fluorophore gives its yield as `photon_yield` (Φ), not `quantum_yield`".into(),
                );
            }
            (YieldForm::Energy, None, None) => {
                return Err("missing field `quantum_yield`".into());
            }
            (YieldForm::Photon, None, None) => {
                return Err("missing field `photon_yield`".into());
            }
        };
        Ok(Fluorophore {
            concentration: f.concentration,
            quantum_yield,
            yield_form: f.yield_form,
            concentration_range: f.concentration_range,
            absorption: f.absorption,
            emission: f.emission,
        })
    }
}

impl From<Fluorophore> for FluorophoreFile {
    fn from(f: Fluorophore) -> Self {
        let (quantum_yield, photon_yield) = match f.yield_form {
            YieldForm::Energy => (Some(f.quantum_yield), None),
            YieldForm::Photon => (None, Some(f.quantum_yield)),
        };
        FluorophoreFile {
            concentration: f.concentration,
            yield_form: f.yield_form,
            quantum_yield,
            photon_yield,
            concentration_range: f.concentration_range,
            absorption: f.absorption,
            emission: f.emission,
        }
    }
}

impl Fluorophore {
    /// k = c·Q (energy form) or c·Φ (photon form): the only scale a reradiation matrix
    /// determines. The fluorescent term is k·a(λi)·e(λo) in the energy form and
    /// k·a(λi)·(λi/λ̄e)·e(λo) in the photon form.
    pub fn k(&self) -> f64 {
        self.concentration * self.quantum_yield
    }

    /// The energy yield at excitation `nm` given the mean emission wavelength: Q in the
    /// energy form, Φ·λi/λ̄e in the photon form.
    pub fn energy_yield_with_mean(&self, nm: f64, emission_mean_nm: f64) -> f64 {
        match self.yield_form {
            YieldForm::Energy => self.quantum_yield,
            YieldForm::Photon => self.quantum_yield * nm / emission_mean_nm,
        }
    }

    /// The photon yield at excitation `nm` given the mean emission wavelength: Q·λ̄e/λi in
    /// the energy form, Φ in the photon form.
    pub fn photon_yield_with_mean(&self, nm: f64, emission_mean_nm: f64) -> f64 {
        match self.yield_form {
            YieldForm::Energy => self.quantum_yield * emission_mean_nm / nm,
            YieldForm::Photon => self.quantum_yield,
        }
    }

    /// The excitation factor of the fluorescent term relative to a(λi): 1 in the energy
    /// form, λi/λ̄e in the photon form (the energy yield over the yield parameter).
    pub fn excitation_factor_with_mean(&self, nm: f64, emission_mean_nm: f64) -> f64 {
        match self.yield_form {
            YieldForm::Energy => 1.0,
            YieldForm::Photon => nm / emission_mean_nm,
        }
    }

    /// c·Q(λi)·a(λi): the fraction of the energy arriving at excitation `nm` that this
    /// fluorophore re-emits (the row factor of its fluorescent term: the term is this
    /// times e(λo)). Computes λ̄e; use [`Fluorophore::reradiated_with_mean`] in loops.
    pub fn reradiated(&self, nm: f64) -> f64 {
        self.reradiated_with_mean(nm, self.emission_mean_nm())
    }

    /// [`Fluorophore::reradiated`] with λ̄e given.
    pub fn reradiated_with_mean(&self, nm: f64, emission_mean_nm: f64) -> f64 {
        self.concentration
            * self.energy_yield_with_mean(nm, emission_mean_nm)
            * self.absorption.eval_zero_outside(nm)
    }

    /// The largest photon yield over the absorbed wavelengths (≤ 1 is photon
    /// conservation): Q·λ̄e/λmin in the energy form, Φ in the photon form. None when a
    /// vanishes everywhere or the emission has no mean.
    pub fn max_photon_yield(&self) -> Option<f64> {
        let shortest = self.shortest_absorbed_nm()?;
        let mean = self.emission_mean_nm();
        mean.is_finite()
            .then(|| self.photon_yield_with_mean(shortest, mean))
    }

    /// The largest value of the form's yield that conserves photons at every absorbed
    /// wavelength and lies in [0, 1]: min(1, λmin/λ̄e) for a constant energy yield Q,
    /// whose photon yield Q·λ̄e/λ is largest at the shortest absorbed wavelength λmin;
    /// 1 for a constant photon yield Φ. 1 also when nothing bounds Q (a vanishes
    /// everywhere, or the emission has no mean).
    pub fn yield_limit(&self) -> f64 {
        match self.yield_form {
            YieldForm::Photon => 1.0,
            YieldForm::Energy => self
                .shortest_absorbed_nm()
                .map(|shortest| shortest / self.emission_mean_nm())
                .filter(|limit| limit.is_finite())
                .map_or(1.0, |limit| limit.min(1.0)),
        }
    }

    /// λ̄e = ∫λ·e dλ, the mean emission wavelength (nm).
    pub fn emission_mean_nm(&self) -> f64 {
        self.emission.mean_wavelength_nm()
    }

    /// Shortest wavelength with a > 0 (nm), or None when a vanishes everywhere.
    pub fn shortest_absorbed_nm(&self) -> Option<f64> {
        let a = &self.absorption;
        let first = a.value.iter().position(|&v| v > 0.0)?;
        // Linear interpolation from a zero sample means absorption starts just after it;
        // the sample itself is the infimum.
        Some(if first > 0 {
            a.wavelength_nm[first - 1]
        } else {
            a.wavelength_nm[0]
        })
    }
}

/// What the fit did and how well it matches the data (the `fit` block).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct FitReport {
    /// The measurement file fitted.
    pub source: String,
    /// SHA-256 of the measurement file.
    pub source_sha256: String,
    /// Solver that produced the result (`init`, `lbfgs`, `gauss-newton`, …).
    pub solver: String,
    /// Whether the solver met its convergence criterion (false also when it hit the
    /// iteration limit).
    pub converged: bool,
    /// Solver iterations.
    pub iterations: u64,
    /// Wall time of the fit (seconds).
    /// Not written to JSON (read when present, for older files): a wall-clock time would
    /// make every rewrite of a committed fit differ. `fit` prints it; `bench` measures speed.
    #[serde(default, skip_serializing)]
    pub seconds: f64,
    /// Cells within this distance of the diagonal were excluded (0: none, the default).
    pub guard_nm: f64,
    /// The convention that picked c within its feasible interval.
    pub gauge: String,
    /// ‖M − fit‖ / ‖M‖ over the fluorescent cells used by the fit (outside the guard band).
    pub rel_residual_fluorescence: f64,
    /// RMSE of the diagonal (reflectance factor units).
    pub rmse_diagonal: f64,
    /// ΔE2000 of a flat patch, measured matrix vs fitted model, per light.
    pub delta_e2000: BTreeMap<String, f64>,
    /// Problems found: the fit is still written, but these say where not to trust it.
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Quantities the data could not determine (e.g. reflectance for a solution EEM).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub undetermined: Vec<String>,
    /// Noise level estimated from the anti-Stokes side (reflectance-factor units).
    #[serde(default)]
    pub noise_sigma: f64,
    /// Sum of |M| in the excluded guard-band cells, relative to the fluorescent signal
    /// (0 without a guard band, the default: every measured cell is fitted).
    #[serde(default)]
    pub guard_signal_fraction: f64,
    /// Cells of the colour reference the file does not hold, filled from the model (the
    /// reference is otherwise the measurement as measured).
    #[serde(default)]
    pub reference_filled_cells: usize,
    /// Largest share, over the lights, of the reference patch's luminance that those
    /// filled cells carry.
    #[serde(default)]
    pub reference_filled_share: f64,
    /// Per light, ΔE2000 between the reference patch with and without those filled
    /// cells: what the model's guess in cells no one measured is worth in colour.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub reference_filled_delta_e2000: BTreeMap<String, f64>,
    /// Per light, the RMS ΔE2000 that the cells' noise alone (σ = `noise_sigma`, white)
    /// gives the measured patch colour: how well the measurement itself knows its colour.
    /// A reported `delta_e2000` of this size is within what the measurement can tell, and
    /// a fit that came closer would be fitting noise.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub delta_e2000_noise: BTreeMap<String, f64>,
    /// Why the fluorophores' yield form was chosen (`fit --yield auto`).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub yield_choice: String,
    /// Objective value per solver iteration (for convergence plots).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub cost_history: Vec<f64>,
    /// The spectral model (`tabulated`, `gaussian:1x2+r4`, …); empty in files written
    /// before models had names (those are tabulated).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub model: String,
    /// Free parameters of the model (0 when unknown).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub parameter_count: usize,
    /// Bayesian information criterion on the matrix residual, RSS/σ² + p·ln n, with σ the
    /// anti-Stokes noise level: lower is better among fits of the same data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bic: Option<f64>,
    /// The candidates tried when the model was chosen automatically.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub model_search: Option<ModelSearch>,
    /// The default fit's choice (`--model as-needed`): whether it went beyond one
    /// fluorophore, and why.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub escalation: Option<Escalation>,
    /// What was done to an uncalibrated EEM before the fit (units, blank, inner filter,
    /// scatter masked); absent for radiance-factor matrices.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preprocessing: Option<crate::eem::Preprocessing>,
    /// Crosstalk found next to the diagonal (the instrument's, not the material's) and
    /// whether the fit took it out of the cells; absent where none rose above the noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crosstalk: Option<CrosstalkCorrection>,
}

/// Crosstalk next to the diagonal: per side, the fraction of the diagonal found one step
/// off it in the rows without fluorescence, and whether the fit used the cells without it.
/// In a per-nm file (`units`) the off-diagonal cells are densities per nm of emission
/// while the diagonal is a plain reflectance factor, so the fractions are per nm.
///
/// Every field has a default, so a block written by hand or by an older version loads
/// with what it gives: missing fractions and errors are 0, and `removed` is false (the
/// cells are then fitted as measured, [`crate::fit::data::FitData::as_fitted`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct CrosstalkCorrection {
    /// Fraction one step below the diagonal (λo = λi − step); 0 where not significant.
    #[serde(default)]
    pub below: f64,
    /// Fraction one step above the diagonal (λo = λi + step); 0 where not significant.
    #[serde(default)]
    pub above: f64,
    /// Standard error of `below` (noise σ over the quiet rows' diagonal); 0 where too few
    /// rows without fluorescence measured that side.
    #[serde(default)]
    pub below_error: f64,
    /// Standard error of `above`.
    #[serde(default)]
    pub above_error: f64,
    /// Rows without fluorescence the estimate used.
    #[serde(default)]
    pub quiet_rows: usize,
    /// Per light, ΔE2000 between the measured patch with and without the crosstalk: what
    /// it is worth in the colour every reported ΔE2000 is measured against.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub delta_e2000: BTreeMap<String, f64>,
    /// True when the fit's cells were taken without it (its net energy given back to the
    /// diagonal); false when it was kept as measured (`note` says why).
    #[serde(default)]
    pub removed: bool,
    /// Why it was kept as measured, when it was; when removed, anything else to know (the
    /// model search removed it where the grid fit it started from had kept it).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
    /// The file's units: per bin (fractions of the diagonal) or per nm (fractions of the
    /// diagonal per nm of emission). Written only for per-nm files.
    #[serde(default, skip_serializing_if = "is_per_bin")]
    pub units: crate::measurement::Units,
}

fn is_per_bin(units: &crate::measurement::Units) -> bool {
    *units == crate::measurement::Units::PerBin
}

impl FitReport {
    /// The largest, over the lights, of [`FitReport::reference_filled_delta_e2000`]: what
    /// the filled cells are worth in colour at most (0 when none were filled).
    pub fn reference_filled_worth(&self) -> f64 {
        self.reference_filled_delta_e2000
            .values()
            .copied()
            .fold(0.0, f64::max)
    }
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// What the default fit (`--model as-needed`) chose: one fluorophore on the grid, or the
/// model search's model because one fluorophore did not explain the matrix.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Escalation {
    /// Whether the fit went beyond the one-fluorophore grid fit.
    pub escalated: bool,
    /// Why, with the figures.
    pub reason: String,
    /// The one-fluorophore grid fit's ΔE2000 against the measurement under d65, a, f11.
    pub grid_delta_e2000: BTreeMap<String, f64>,
    /// The one-fluorophore grid fit's ‖M − F‖/‖M‖ over the Stokes cells.
    pub grid_rel_residual_fluorescence: f64,
}

/// How a model was chosen: the rule, every candidate tried, and the choice.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct ModelSearch {
    /// The rule, in words (`first model with ΔE2000 ≤ 1 under d65, a, f11, uv`).
    pub rule: String,
    /// The ΔE2000 bound, when the rule is colour accuracy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_delta_e: Option<f64>,
    /// Candidates in the order tried (smallest first).
    pub candidates: Vec<Candidate>,
    /// Models the search did not try, and why (`one-component models: …`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub skipped: Option<String>,
    /// The model chosen.
    pub chosen: String,
    /// Whether the chosen model meets the rule (false: none did; the closest was kept).
    pub met: bool,
    /// Where the rule is not met: per light the kept model misses, its ΔE2000 against
    /// the measured colour's own noise (RMS ΔE2000), when every miss is within
    /// [`crate::fit::assess::NOISE_COVERAGE`] × that noise, so no model could be told
    /// nearer the measured colour than one that fits its noise. Where a search with
    /// `--noise-aware-bound` met its rule: the lights above `max_delta_e` that met it
    /// only through the widened bound. Empty otherwise.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub misses_within_noise: BTreeMap<String, [f64; 2]>,
    /// `--noise-aware-bound` only, where the matrix told a candidate that met the bound
    /// from the grid model by more than noise: what the search did (kept the grid fit, or
    /// went on to a candidate that passes), and why.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix_test: Option<String>,
    /// Where the search ran on both band axes (`--band-axis both`): which axis it kept
    /// and why (it met the rule where the other did not, or the lower BIC), and what the
    /// other kept; `candidates` then lists the other axis's after its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band_axis: Option<String>,
    /// The candidate with the lowest BIC among those tried.
    pub lowest_bic: String,
    /// Wall time of the whole search (seconds).
    /// Not written to JSON (read when present, for older files): a wall-clock time would
    /// make every rewrite of a committed fit differ. `fit` prints it; `bench` measures speed.
    #[serde(default, skip_serializing)]
    pub seconds: f64,
}

/// One model tried by the search.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Candidate {
    /// Model name.
    pub model: String,
    /// Free parameters.
    pub parameters: usize,
    /// ΔE2000 per light (measured patch vs this model).
    pub delta_e2000: BTreeMap<String, f64>,
    /// ‖M − fit‖/‖M‖ over the Stokes cells.
    pub rel_residual_fluorescence: f64,
    /// BIC on the matrix residual.
    pub bic: f64,
    /// Fit time (seconds).
    /// Not written to JSON (read when present, for older files): a wall-clock time would
    /// make every rewrite of a committed fit differ. `fit` prints it; `bench` measures speed.
    #[serde(default, skip_serializing)]
    pub seconds: f64,
    /// Why the candidate failed to fit, if it did (then the figures are empty).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// The objective the candidate reached (matrix and colour terms, the same function for
    /// every candidate of one search, so a larger model's can be compared with the smaller
    /// models it contains).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub objective: Option<f64>,
}

/// Conservation margins of a material (the `conservation` block): the worst values of the
/// energy and photon laws as `check` finds them ([`Material::conservation_margins`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Conservation {
    /// max over λ of ρ(λ) = (1 − Σc·a)·r + Σc·Q(λ)·a·∫e (∫e = 1 in a valid material, but
    /// the albedo is computed with the emission's actual area); must be ≤ 1.
    pub max_energy_albedo: f64,
    /// max over fluorophores and absorbed λ of the photon yield (Q·λ̄e/λ in the energy
    /// form, Φ in the photon form); must be ≤ 1.
    pub max_photon_ratio: f64,
}

impl Material {
    /// A material from its parts, with conservation margins computed.
    pub fn new(
        name: impl Into<String>,
        reflectance: Spectrum,
        fluorophores: Vec<Fluorophore>,
    ) -> Self {
        let mut m = Material::without_margins(name, reflectance, fluorophores);
        m.conservation = Some(m.conservation_margins());
        m
    }

    /// A material from its parts without its conservation block (`conservation` is
    /// `None`), for a caller that computes the block itself once the material is final.
    pub fn without_margins(
        name: impl Into<String>,
        reflectance: Spectrum,
        fluorophores: Vec<Fluorophore>,
    ) -> Self {
        Material {
            schema: SCHEMA.to_string(),
            name: name.into(),
            reflectance,
            fluorophores,
            fit: None,
            conservation: None,
            forms: None,
        }
    }

    /// Total fraction absorbed by fluorophores at `nm`: Σ c·a(λ).
    pub fn absorbed(&self, nm: f64) -> f64 {
        self.fluorophores
            .iter()
            .map(|f| f.concentration * f.absorption.eval_zero_outside(nm))
            .sum()
    }

    /// d(λ) = (1 − Σc·a(λ))·r(λ): the ordinary (diagonal) reflectance.
    pub fn diagonal(&self, nm: f64) -> f64 {
        (1.0 - self.absorbed(nm)) * self.reflectance.eval_clamped(nm)
    }

    /// ρ(λ) = (1 − Σc·a)·r + Σc·Q(λ)·a·∫e: the total energy albedo for excitation at
    /// `nm`, the quantity of the energy law (∫e is 1 in a valid material; the emission's
    /// actual area is used, so a check of an unnormalised file sees what it emits).
    pub fn energy_albedo(&self, nm: f64) -> f64 {
        self.energy_albedo_with(nm, &self.emission_moments())
    }

    /// (∫e, λ̄e) per fluorophore (∫e is 1 for a valid material; computed, as checks run
    /// on any).
    pub fn emission_moments(&self) -> Vec<(f64, f64)> {
        self.fluorophores
            .iter()
            .map(|f| (f.emission.integral(), f.emission_mean_nm()))
            .collect()
    }

    /// ρ(λ) with the emission moments of [`Material::emission_moments`] given (they cost a
    /// pass over each emission). An emission without area (∫e = 0, which the emission
    /// law reports) adds nothing, though its mean, and so the photon form's Q(λ), is
    /// undefined.
    pub fn energy_albedo_with(&self, nm: f64, emission_moments: &[(f64, f64)]) -> f64 {
        self.diagonal(nm)
            + self
                .fluorophores
                .iter()
                .zip(emission_moments)
                .filter(|(_, (integral, _))| *integral != 0.0)
                .map(|(f, &(integral, mean))| f.reradiated_with_mean(nm, mean) * integral)
                .sum::<f64>()
    }

    /// Off-diagonal reradiation density Σ c·Q(λi)·a(λi)·e(λo) over fluorophores (1/nm).
    /// Computes each λ̄e; use [`Material::fluorescence_with`] in loops.
    pub fn fluorescence(&self, excitation_nm: f64, emission_nm: f64) -> f64 {
        self.fluorescence_with(excitation_nm, emission_nm, &self.emission_moments())
    }

    /// [`Material::fluorescence`] with the emission moments given.
    pub fn fluorescence_with(
        &self,
        excitation_nm: f64,
        emission_nm: f64,
        emission_moments: &[(f64, f64)],
    ) -> f64 {
        self.fluorophores
            .iter()
            .zip(emission_moments)
            .map(|(f, &(_, mean))| {
                f.reradiated_with_mean(excitation_nm, mean)
                    * f.emission.eval_zero_outside(emission_nm)
            })
            .sum()
    }

    /// [`Material::fluorescence_with`] at every (excitation, emission) pair of the two
    /// grids, row-major (one row per excitation wavelength). Each fluorophore's factors
    /// are evaluated once per row and once per column, not once per cell: the same
    /// products summed in the same order, so each value equals `fluorescence_with`'s bit
    /// for bit (per cell, predicting a matrix was 3 % of a model search).
    pub fn fluorescence_on_grid(&self, excitation_nm: &[f64], emission_nm: &[f64]) -> Vec<f64> {
        let moments = self.emission_moments();
        let reradiated: Vec<Vec<f64>> = self
            .fluorophores
            .iter()
            .zip(&moments)
            .map(|(f, &(_, mean))| {
                excitation_nm
                    .iter()
                    .map(|&l| f.reradiated_with_mean(l, mean))
                    .collect()
            })
            .collect();
        let emitted: Vec<Vec<f64>> = self
            .fluorophores
            .iter()
            .map(|f| {
                emission_nm
                    .iter()
                    .map(|&l| f.emission.eval_zero_outside(l))
                    .collect()
            })
            .collect();
        let mut values = Vec::with_capacity(excitation_nm.len() * emission_nm.len());
        for i in 0..excitation_nm.len() {
            for j in 0..emission_nm.len() {
                values.push(
                    reradiated
                        .iter()
                        .zip(&emitted)
                        .map(|(r, e)| r[i] * e[j])
                        .sum(),
                );
            }
        }
        values
    }

    /// All wavelengths at which some spectrum of the material is sampled, sorted.
    pub fn sample_wavelengths(&self) -> Vec<f64> {
        // Spectra often share one grid (a fit tabulates every form on the same one): each
        // distinct grid is merged once, as a repeat would only be deduplicated again.
        let mut grids: Vec<&[f64]> = vec![&self.reflectance.wavelength_nm];
        for f in &self.fluorophores {
            for grid in [&f.absorption.wavelength_nm, &f.emission.wavelength_nm] {
                if !grids.contains(&grid.as_slice()) {
                    grids.push(grid);
                }
            }
        }
        let mut all: Vec<f64> = grids.concat();
        all.sort_by(f64::total_cmp);
        all.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        all
    }

    /// Reads and validates a material file.
    pub fn load(path: &Path) -> Result<Material> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Material::from_json(&text, path)
    }

    /// Parses and validates material JSON text, as [`Material::load`] reads a file;
    /// `path` names the text in errors (its file, or a placeholder such as `<json>`).
    pub fn from_json(text: &str, path: &Path) -> Result<Material> {
        let material: Material = serde_json::from_str(text).map_err(|e| {
            Error::parse(
                path,
                e.line(),
                e.column(),
                format!("not a fluorite material: {e}"),
            )
        })?;
        material.validate().map_err(|e| match e {
            Error::Invalid { parameter, message } => {
                Error::parse(path, 0, 0, format!("{parameter} {message}"))
            }
            other => other,
        })?;
        Ok(material)
    }

    /// The material as pretty JSON, with conservation margins refreshed.
    pub fn to_json(&self) -> String {
        let mut m = self.clone();
        m.conservation = Some(self.conservation_margins());
        let mut s = serde_json::to_string_pretty(&m).expect("material serialises");
        s.push('\n');
        s
    }

    /// Writes the material atomically (temporary file, then rename).
    pub fn save(&self, path: &Path) -> Result<()> {
        crate::files::write_atomic(path, self.to_json().as_bytes())
    }
}

/// Schema tag of a shapes-only fit (solution EEMs: no diagonal, often arbitrary scale).
pub const SHAPES_SCHEMA: &str = "fluorite-fluorophore/1";

/// What a matrix without a diagonal determines: the absorption and emission shapes and,
/// when the data are calibrated, k = c·Q. Written instead of a [`Material`] so that no
/// reflectance, concentration or yield is invented; `undetermined` names what is missing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FluorophoreShapes {
    /// Always [`SHAPES_SCHEMA`].
    pub schema: String,
    /// A short name (the measurement's file stem).
    pub name: String,
    /// a(λ), max 1.
    pub absorption: Spectrum,
    /// e(λ), ∫e = 1 (1/nm).
    pub emission: Spectrum,
    /// k = c·Q when the data are calibrated; absent on an arbitrary scale.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<f64>,
    /// k in the data's own (arbitrary) units.
    pub k_data_units: f64,
    /// The quantities the data cannot determine, in words.
    pub undetermined: Vec<String>,
    /// The fit's report.
    pub fit: FitReport,
}

impl FluorophoreShapes {
    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("shapes serialise");
        s.push('\n');
        s
    }
}

//! Checking any material against the model's laws (model.md §1 and §3).
//!
//! [`Material::load`] stops at the first broken constraint; a check must instead read
//! materials that are broken (hand-written, exported by someone else) and name *every*
//! violated law with its worst wavelength and margin. So the JSON is first read leniently
//! into a [`RawMaterial`] (numbers that are not numbers become NaN, spectra may be unsorted
//! or of unequal length), then every [`Law`] is evaluated independently.
//!
//! A law's *margin* is `bound − worst value` in the law's own units: positive when it
//! holds, negative when broken. A law fails when its margin is below `−tolerance`.
//! Laws whose inputs are malformed (non-finite, unsorted) are reported as not evaluated;
//! the structural law that makes them unevaluable fails instead.

use std::path::Path;

use serde::Serialize;
use serde_json::Value;

use crate::error::{Error, Result};
use crate::material::{Conservation, Fluorophore, Material, SCHEMA, YieldForm};
use crate::parametric::MaterialForms;
use crate::spectrum::{Spectrum, bin_widths};

mod laws;
mod raw;

pub use laws::check;
pub use raw::{RawFluorophore, RawForms, RawMaterial, RawSpectrum};

/// Tolerance for the normalisations max a = 1 and ∫e = 1.
pub const NORMALISATION_TOLERANCE: f64 = 1e-6;
/// Largest difference between a form and its samples, relative to the samples' peak.
pub const FORM_TOLERANCE: f64 = 1e-6;
/// Tolerance for range and conservation checks (values may exceed a bound by this much).
pub const BOUND_TOLERANCE: f64 = 1e-9;

/// The laws a material must satisfy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Law {
    /// The file declares the `fluorite-material/1` schema.
    Schema,
    /// Every spectrum has as many values as wavelengths, at least one sample, finite
    /// non-negative values and positive wavelengths.
    FiniteNonNegative,
    /// Wavelengths strictly increase within every spectrum.
    SortedWavelengths,
    /// r(λ) ≤ 1.
    ReflectanceRange,
    /// a(λ) ≤ 1.
    AbsorptionRange,
    /// 0 ≤ c ≤ 1.
    ConcentrationRange,
    /// 0 ≤ Q ≤ 1 (energy form) or 0 ≤ Φ ≤ 1 (photon form), the yield given as its form
    /// requires (`quantum_yield`, or `photon_yield` beside `"yield_form": "photon"`).
    QuantumYieldRange,
    /// max a = 1.
    AbsorptionPeak,
    /// ∫e dλ = 1.
    EmissionIntegral,
    /// Σ c·a(λ) ≤ 1: the fluorophores together absorb at most all the light.
    TotalAbsorption,
    /// ρ(λ) = (1 − Σc·a)·r + Σc·Q(λ)·a·∫e ≤ 1, with Q(λ) = Q (energy form) or
    /// Φ·λ/λ̄e (photon form).
    Energy,
    /// Q·λ̄e/λ ≤ 1 wherever a(λ) > 0 (energy form); Φ ≤ 1 (photon form).
    Photons,
    /// The `forms` block (when present) parses, has one entry per fluorophore, finite
    /// parameters, and reproduces the tabulated samples within
    /// [`FORM_TOLERANCE`] of each spectrum's peak.
    Forms,
}

impl Law {
    /// Every law, in report order.
    pub const ALL: [Law; 13] = [
        Law::Schema,
        Law::FiniteNonNegative,
        Law::SortedWavelengths,
        Law::ReflectanceRange,
        Law::AbsorptionRange,
        Law::ConcentrationRange,
        Law::QuantumYieldRange,
        Law::AbsorptionPeak,
        Law::EmissionIntegral,
        Law::TotalAbsorption,
        Law::Energy,
        Law::Photons,
        Law::Forms,
    ];

    /// The law's short name (as in the JSON report).
    pub fn name(self) -> &'static str {
        match self {
            Law::Schema => "schema",
            Law::FiniteNonNegative => "finite-non-negative",
            Law::SortedWavelengths => "sorted-wavelengths",
            Law::ReflectanceRange => "reflectance-range",
            Law::AbsorptionRange => "absorption-range",
            Law::ConcentrationRange => "concentration-range",
            Law::QuantumYieldRange => "quantum-yield-range",
            Law::AbsorptionPeak => "absorption-peak",
            Law::EmissionIntegral => "emission-integral",
            Law::TotalAbsorption => "total-absorption",
            Law::Energy => "energy",
            Law::Photons => "photons",
            Law::Forms => "forms",
        }
    }

    /// The law as a formula.
    pub fn statement(self) -> &'static str {
        match self {
            Law::Schema => "schema = \"fluorite-material/1\"",
            Law::FiniteNonNegative => {
                "every sample finite and ≥ 0, wavelengths in 100–100,000 nm, one value per wavelength"
            }
            Law::SortedWavelengths => "wavelengths strictly increasing",
            Law::ReflectanceRange => "r(λ) ≤ 1",
            Law::AbsorptionRange => "a(λ) ≤ 1",
            Law::ConcentrationRange => "0 ≤ c ≤ 1",
            Law::QuantumYieldRange => "0 ≤ Q ≤ 1 (energy form), 0 ≤ Φ ≤ 1 (photon form)",
            Law::AbsorptionPeak => "max a = 1",
            Law::EmissionIntegral => "∫e dλ = 1 (1/nm, trapezoid rule)",
            Law::TotalAbsorption => "Σ c·a(λ) ≤ 1",
            Law::Energy => "ρ(λ) = (1 − Σc·a)·r + Σc·Q(λ)·a·∫e ≤ 1, Q(λ) = Q or Φ·λ/λ̄e",
            Law::Photons => "Q·λ̄e/λ ≤ 1 where a(λ) > 0 (energy form), Φ ≤ 1 (photon form)",
            Law::Forms => "forms = samples (relative to the peak)",
        }
    }

    /// How far past its bound a value may lie before the law counts as broken.
    pub fn tolerance(self) -> f64 {
        match self {
            Law::AbsorptionPeak | Law::EmissionIntegral => NORMALISATION_TOLERANCE,
            Law::Forms => FORM_TOLERANCE,
            _ => BOUND_TOLERANCE,
        }
    }
}

impl std::fmt::Display for Law {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Whether a law holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// The law holds within its tolerance.
    Pass,
    /// The law is broken.
    Fail,
    /// The law could not be evaluated because its inputs are malformed (another law
    /// fails for that).
    NotEvaluated,
}

/// The outcome of one law.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LawResult {
    /// Which law.
    pub law: Law,
    /// The law as a formula.
    pub statement: String,
    /// Pass, fail or not evaluated.
    pub status: Status,
    /// `bound − worst value` (negative when broken; for the normalisations −|value − 1|).
    /// For the structural laws: the smallest sample (`finite-non-negative`), the smallest
    /// wavelength step in nm (`sorted-wavelengths`), 0 (`schema`). NaN (JSON null) when
    /// not evaluated, when nothing was checked, or when the worst value is not a number.
    pub margin: f64,
    /// The tolerance the margin is compared with.
    pub tolerance: f64,
    /// The worst value found.
    pub worst_value: f64,
    /// Where the worst value is (`fluorophores[0].absorption`), if anywhere.
    pub worst_at: Option<String>,
    /// The wavelength of the worst value (nm), when it has one.
    pub worst_nm: Option<f64>,
    /// One sentence per violation found (all of them, not just the worst).
    pub violations: Vec<String>,
}

/// Per-fluorophore quantities a chemist would quote.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FluorophoreSummary {
    /// Which yield is constant over the excitation wavelength.
    pub yield_form: YieldForm,
    /// The constant yield of the form: Q (energy form) or Φ (photon form).
    #[serde(rename = "yield")]
    pub yield_value: f64,
    /// k = c·Q (energy form) or c·Φ (photon form).
    pub k: f64,
    /// λ̄e = ∫λ·e dλ / ∫e dλ (nm).
    pub mean_emission_nm: f64,
    /// Shortest and longest wavelength where a > 0 (nm).
    pub absorbed_nm: Option<[f64; 2]>,
    /// Range of the photon quantum yield over the absorbed wavelengths: Φ(λ) = Q·λ̄e/λ in
    /// the energy form, the constant [Φ, Φ] in the photon form.
    pub photon_yield_range: Option<[f64; 2]>,
    /// Range of the energy quantum yield over the absorbed wavelengths: the constant
    /// [Q, Q] in the energy form, Q(λ) = Φ·λ/λ̄e in the photon form.
    pub energy_yield_range: Option<[f64; 2]>,
}

/// What the `forms` block holds and how well it reproduces the samples.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FormsSummary {
    /// The model name (`gaussian:1x2`, …; empty when the block gives none).
    pub model: String,
    /// Number of forms (reflectance, and absorption and emission per fluorophore).
    pub forms: usize,
    /// Free parameters of all forms together.
    pub parameters: usize,
    /// Largest |form(λ) − sample| over every sample, relative to its spectrum's peak
    /// (NaN when the block could not be compared).
    pub worst_deviation: f64,
    /// Remarks that break no law, e.g. an absorption form rising above 1 between samples
    /// (everything downstream uses the samples).
    pub notes: Vec<String>,
}

/// The full report of [`check`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckReport {
    /// The material's name.
    pub material: String,
    /// The file checked, if any.
    pub source: Option<String>,
    /// True when no law fails.
    pub valid: bool,
    /// The model of the material's continuous forms (None: tabulated spectra only).
    pub model: Option<String>,
    /// Every law, in [`Law::ALL`] order.
    pub laws: Vec<LawResult>,
    /// Per fluorophore: k, λ̄e and the photon quantum yield range.
    pub fluorophores: Vec<FluorophoreSummary>,
    /// The `forms` block, when the material has one.
    pub forms: Option<FormsSummary>,
}

impl CheckReport {
    /// The laws that fail.
    pub fn failed(&self) -> Vec<Law> {
        self.laws
            .iter()
            .filter(|l| l.status == Status::Fail)
            .map(|l| l.law)
            .collect()
    }

    /// The names of the laws that fail, comma-separated.
    pub fn failed_names(&self) -> String {
        let names: Vec<&str> = self.failed().iter().map(|l| l.name()).collect();
        names.join(", ")
    }

    /// The result of one law.
    pub fn law(&self, law: Law) -> &LawResult {
        self.laws
            .iter()
            .find(|l| l.law == law)
            .expect("every law is reported")
    }

    /// The report as pretty JSON (NaN margins as null).
    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("report serialises");
        s.push('\n');
        s
    }
}

/// Reads `path` leniently and checks it. Errors only when the file cannot be read or
/// is not a material at all (the CLI's exit code 2).
pub fn check_file(path: &Path) -> Result<CheckReport> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let raw = RawMaterial::from_json(&text, path)?;
    let mut report = check(&raw);
    report.source = Some(path.display().to_string());
    Ok(report)
}

/// Checks a material held in memory.
pub fn check_material(material: &Material) -> CheckReport {
    check(&RawMaterial::from(material))
}

//! The law engine: every [`Law`] evaluated on a [`RawMaterial`], with its worst value,
//! wavelength and margin; [`Material::validate`] asks it for the first broken law.

use super::*;

/// Tracks the worst observation of one law.
struct Tracker {
    law: Law,
    evaluated: bool,
    margin: f64,
    worst_value: f64,
    worst_at: Option<String>,
    worst_nm: Option<f64>,
    violations: Vec<String>,
}

impl Tracker {
    fn new(law: Law) -> Self {
        Tracker {
            law,
            evaluated: true,
            margin: f64::INFINITY,
            worst_value: f64::NAN,
            worst_at: None,
            worst_nm: None,
            violations: Vec::new(),
        }
    }

    /// Records a value with its margin; `at` is formatted only when the value is the worst
    /// so far, and `message` is called when it breaks the law (margin below −tolerance,
    /// or not a number).
    fn observe(
        &mut self,
        margin: f64,
        value: f64,
        at: impl std::fmt::Display,
        nm: Option<f64>,
        message: impl FnOnce() -> String,
    ) {
        let broken = margin.is_nan() || margin < -self.law.tolerance();
        self.observe_if(broken, margin, value, at, nm, message);
    }

    /// Records a value whose verdict the caller decides.
    fn observe_if(
        &mut self,
        broken: bool,
        margin: f64,
        value: f64,
        at: impl std::fmt::Display,
        nm: Option<f64>,
        message: impl FnOnce() -> String,
    ) {
        // A non-number is the worst there is; the first one found stays reported.
        let worse = if margin.is_nan() {
            !self.margin.is_nan()
        } else {
            !self.margin.is_nan() && margin < self.margin
        };
        if worse {
            self.margin = margin;
            self.worst_value = value;
            self.worst_at = Some(at.to_string());
            self.worst_nm = nm;
        }
        if broken {
            self.violations.push(message());
        }
    }

    fn result(self) -> LawResult {
        let status = if !self.violations.is_empty() {
            Status::Fail
        } else if !self.evaluated {
            Status::NotEvaluated
        } else {
            Status::Pass
        };
        // A law with nothing to observe (no fluorophore) holds with an infinite margin;
        // JSON has no infinity, so report NaN (null).
        let margin = if self.margin.is_infinite() || !self.evaluated && status != Status::Fail {
            f64::NAN
        } else {
            self.margin
        };
        LawResult {
            law: self.law,
            statement: self.law.statement().to_string(),
            status,
            margin,
            tolerance: self.law.tolerance(),
            worst_value: self.worst_value,
            worst_at: self.worst_at,
            worst_nm: self.worst_nm,
            violations: self.violations,
        }
    }
}

/// Whether a raw spectrum is well formed enough to evaluate derived laws on.
fn usable(s: &RawSpectrum) -> bool {
    !s.value.is_empty()
        && s.value.len() == s.wavelength_nm.len()
        && s.value.iter().all(|v| v.is_finite())
        && s.wavelength_nm.len() <= crate::limits::MAX_GRID_POINTS
        && s.wavelength_nm
            .iter()
            .all(|l| crate::limits::WAVELENGTH_NM.contains(l))
        && s.wavelength_nm.windows(2).all(|w| w[1] > w[0])
}

fn to_spectrum(s: &RawSpectrum) -> Spectrum {
    Spectrum {
        wavelength_nm: s.wavelength_nm.clone(),
        value: s.value.clone(),
    }
}

/// How far a check follows the `forms` block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum FormsDepth {
    /// The [`Law::Forms`] comparison with the samples, and a scan between samples for
    /// the report's notes (a full report).
    Report,
    /// The [`Law::Forms`] comparison alone: the notes break no law, so validation skips
    /// the scan.
    Law,
    /// Not at all ([`Law::Forms`] not evaluated): for a material whose samples were just
    /// tabulated from its forms by the same code.
    Skip,
}

/// Checks every law on `m` and reports each with its worst wavelength and margin.
pub fn check(m: &RawMaterial) -> CheckReport {
    check_to(m, FormsDepth::Report)
}

/// [`check`], following the forms block to `depth`.
pub(super) fn check_to(m: &RawMaterial, depth: FormsDepth) -> CheckReport {
    let mut schema = Tracker::new(Law::Schema);
    let ok = m.schema == SCHEMA;
    schema.observe(
        if ok { 0.0 } else { f64::NAN },
        f64::NAN,
        "schema",
        None,
        || format!("schema is \"{}\"; fluorite reads \"{SCHEMA}\"", m.schema),
    );
    if !ok {
        schema.worst_at = Some("schema".into());
    }

    let mut spectra: Vec<(String, &RawSpectrum)> =
        vec![("reflectance".to_string(), &m.reflectance)];
    for (n, f) in m.fluorophores.iter().enumerate() {
        spectra.push((format!("fluorophores[{n}].absorption"), &f.absorption));
        spectra.push((format!("fluorophores[{n}].emission"), &f.emission));
    }

    // Structure: finite, non-negative, one value per wavelength; sorted wavelengths.
    let mut finite = Tracker::new(Law::FiniteNonNegative);
    let mut sorted = Tracker::new(Law::SortedWavelengths);
    for (what, s) in &spectra {
        if s.value.len() != s.wavelength_nm.len() || s.value.is_empty() {
            finite.observe(f64::NAN, f64::NAN, what, None, || {
                format!(
                    "{what} has {} wavelengths and {} values; give one value per wavelength and at least one sample",
                    s.wavelength_nm.len(),
                    s.value.len()
                )
            });
        }
        for (i, &l) in s.wavelength_nm.iter().enumerate() {
            let margin = if l.is_finite() { l } else { f64::NAN };
            if !(l.is_finite() && l > 0.0) {
                finite.observe_if(true, margin, l, format_args!("{what}.wavelength_nm[{i}]"), None, || {
                    format!("{what}.wavelength_nm[{i}] is {l}; wavelengths are positive finite numbers in nm")
                });
            } else if let Err(message) = crate::limits::check_wavelength(l) {
                finite.observe_if(
                    true,
                    margin,
                    l,
                    format_args!("{what}.wavelength_nm[{i}]"),
                    None,
                    || format!("{what}.wavelength_nm[{i}]: {message}"),
                );
            }
            if i > 0 {
                let prev = s.wavelength_nm[i - 1];
                let step = l - prev;
                // NaN steps (non-numbers) count as unsorted.
                let broken = step <= 0.0 || step.is_nan();
                sorted.observe_if(broken, step, step, format_args!("{what}.wavelength_nm[{i}]"), Some(l), || {
                    format!("{what}.wavelength_nm[{i}] = {l} nm does not exceed the previous {prev} nm; sort the samples and remove repeats")
                });
            }
        }
        for (i, &v) in s.value.iter().enumerate() {
            let nm = s.wavelength_nm.get(i).copied();
            let margin = if v.is_finite() { v } else { f64::NAN };
            finite.observe(margin, v, format_args!("{what}.value[{i}]"), nm, || {
                format!(
                    "{what}.value[{i}] is {}{}; samples must be finite and ≥ 0",
                    if v.is_nan() {
                        "not a number".to_string()
                    } else {
                        v.to_string()
                    },
                    nm.map(|l| format!(" at {l} nm")).unwrap_or_default()
                )
            });
        }
    }
    // Sorting margins are steps in nm, the finite law's margins are values: report
    // the structural margins only when they mean something.
    let structure_ok = spectra.iter().all(|(_, s)| usable(s));

    // Upper bounds of r and a (their lower bound 0 is the non-negative law).
    let upper = |law: Law, list: Vec<(String, &RawSpectrum)>| {
        let mut t = Tracker::new(law);
        for (what, s) in list {
            for (i, &v) in s.value.iter().enumerate() {
                if !v.is_finite() {
                    continue;
                }
                let nm = s.wavelength_nm.get(i).copied();
                t.observe(1.0 - v, v, format_args!("{what}.value[{i}]"), nm, || {
                    format!(
                        "{what}.value[{i}] is {v}{}; it must be ≤ 1",
                        nm.map(|l| format!(" at {l} nm")).unwrap_or_default()
                    )
                });
            }
        }
        t
    };
    let reflectance_range = upper(
        Law::ReflectanceRange,
        vec![("reflectance".into(), &m.reflectance)],
    );
    let absorption_range = upper(
        Law::AbsorptionRange,
        m.fluorophores
            .iter()
            .enumerate()
            .map(|(n, f)| (format!("fluorophores[{n}].absorption"), &f.absorption))
            .collect(),
    );
    let scalar = |law: Law, key: &str, get: fn(&RawFluorophore) -> f64| {
        let mut t = Tracker::new(law);
        for (n, f) in m.fluorophores.iter().enumerate() {
            let v = get(f);
            let margin = if v.is_nan() { f64::NAN } else { v.min(1.0 - v) };
            t.observe(
                margin,
                v,
                format_args!("fluorophores[{n}].{key}"),
                None,
                || format!("fluorophores[{n}].{key} is {v}; it must lie in [0, 1]"),
            );
        }
        t
    };
    let concentration_range = scalar(Law::ConcentrationRange, "concentration", |f| {
        f.concentration
    });
    let mut yield_range = Tracker::new(Law::QuantumYieldRange);
    for (n, f) in m.fluorophores.iter().enumerate() {
        let key = match f.yield_form {
            YieldForm::Energy => "quantum_yield",
            YieldForm::Photon => "photon_yield",
        };
        let at = format!("fluorophores[{n}].{key}");
        if !f.yield_issues.is_empty() {
            yield_range.observe_if(true, f64::NAN, f.quantum_yield, &at, None, || {
                f.yield_issues.join("; ")
            });
            continue;
        }
        let v = f.quantum_yield;
        let margin = if v.is_nan() { f64::NAN } else { v.min(1.0 - v) };
        let symbol = match f.yield_form {
            YieldForm::Energy => "the energy yield Q",
            YieldForm::Photon => "the photon yield Φ",
        };
        yield_range.observe(margin, v, &at, None, || {
            format!("{at} is {v}; {symbol} must lie in [0, 1]")
        });
    }

    // Normalisations.
    let mut peak = Tracker::new(Law::AbsorptionPeak);
    let mut integral = Tracker::new(Law::EmissionIntegral);
    for (n, f) in m.fluorophores.iter().enumerate() {
        let p = format!("fluorophores[{n}]");
        if usable(&f.absorption) {
            let (i, max) = f.absorption.value.iter().copied().enumerate().fold(
                (0, f64::NEG_INFINITY),
                |a, (i, v)| if v > a.1 { (i, v) } else { a },
            );
            peak.observe(
                -(max - 1.0).abs(),
                max,
                format_args!("{p}.absorption"),
                Some(f.absorption.wavelength_nm[i]),
                || format!("{p}.absorption peaks at {max} (at {} nm); normalise it to max a = 1 and fold the scale into the concentration", f.absorption.wavelength_nm[i]),
            );
        } else {
            peak.evaluated = false;
        }
        if usable(&f.emission) {
            let area: f64 = bin_widths(&f.emission.wavelength_nm)
                .iter()
                .zip(&f.emission.value)
                .map(|(w, v)| w * v)
                .sum();
            integral.observe(
                -(area - 1.0).abs(),
                area,
                format_args!("{p}.emission"),
                None,
                || format!("{p}.emission integrates to {area} (trapezoid rule); emission is a density in 1/nm with ∫e dλ = 1: divide it by {area}"),
            );
        } else {
            integral.evaluated = false;
        }
    }

    // Laws on the whole material: need every spectrum usable.
    let mut total = Tracker::new(Law::TotalAbsorption);
    let mut energy = Tracker::new(Law::Energy);
    let mut photons = Tracker::new(Law::Photons);
    let mut summaries = Vec::new();
    let scalars_ok = m
        .fluorophores
        .iter()
        .all(|f| f.concentration.is_finite() && f.quantum_yield.is_finite());
    if structure_ok && scalars_ok {
        let material = Material {
            schema: SCHEMA.to_string(),
            name: m.name.clone(),
            reflectance: to_spectrum(&m.reflectance),
            fluorophores: m
                .fluorophores
                .iter()
                .map(|f| Fluorophore {
                    concentration: f.concentration,
                    quantum_yield: f.quantum_yield,
                    yield_form: f.yield_form,
                    concentration_range: None,
                    absorption: to_spectrum(&f.absorption),
                    emission: to_spectrum(&f.emission),
                })
                .collect(),
            fit: None,
            forms: None,
            conservation: None,
        };
        let grid = material.sample_wavelengths();
        for &l in &grid {
            let absorbed = material.absorbed(l);
            total.observe(1.0 - absorbed, absorbed, "fluorophores", Some(l), || {
                format!(
                    "the fluorophores absorb Σc·a = {absorbed} at {l} nm; lower the concentrations"
                )
            });
        }
        let lower = if material
            .fluorophores
            .iter()
            .any(|f| f.yield_form == YieldForm::Photon)
        {
            "lower r, c or the yield (Q, or Φ in the photon form, where Q(λ) = Φ·λ/λ̄e grows with λ)"
        } else {
            "lower r, c or Q"
        };
        for (l, rho) in energy_extrema(&material, &grid) {
            energy.observe(1.0 - rho, rho, "albedo", Some(l), || {
                format!("albedo ρ = {rho} at {l} nm: the material reflects and emits more energy than it receives; {lower}")
            });
        }
        for (n, f) in material.fluorophores.iter().enumerate() {
            let mean = f.emission_mean_nm();
            let absorbed = absorbed_range(f);
            let mut summary = FluorophoreSummary {
                yield_form: f.yield_form,
                yield_value: f.quantum_yield,
                k: f.k(),
                mean_emission_nm: mean,
                absorbed_nm: absorbed,
                photon_yield_range: None,
                energy_yield_range: None,
            };
            if let Some([lo, hi]) = absorbed
                && mean.is_finite()
            {
                summary.photon_yield_range = Some([
                    f.photon_yield_with_mean(hi, mean),
                    f.photon_yield_with_mean(lo, mean),
                ]);
                summary.energy_yield_range = Some([
                    f.energy_yield_with_mean(lo, mean),
                    f.energy_yield_with_mean(hi, mean),
                ]);
            }
            // The photon yield is largest at the shortest absorbed wavelength (it is
            // constant in the photon form).
            if let (Some(ratio), Some([lo, _])) = (f.max_photon_yield(), absorbed) {
                let y = f.quantum_yield;
                let nm = (f.yield_form == YieldForm::Energy).then_some(lo);
                photons.observe(1.0 - ratio, ratio, format_args!("fluorophores[{n}]"), nm, || {
                    match f.yield_form {
                        YieldForm::Energy => format!(
                            "fluorophores[{n}] emits Q·λ̄e/λ = {ratio:.6} photons per absorbed photon at {lo} nm (Q = {y}, λ̄e = {mean:.2} nm); photon conservation allows Q ≤ {:.6} (or a constant photon yield Φ ≤ 1: \"yield_form\": \"photon\")",
                            f.yield_limit()
                        ),
                        YieldForm::Photon => format!(
                            "fluorophores[{n}] emits Φ = {y} photons per absorbed photon at every absorbed wavelength; photon conservation allows Φ ≤ 1"
                        ),
                    }
                });
            }
            summaries.push(summary);
        }
    } else {
        total.evaluated = false;
        energy.evaluated = false;
        photons.evaluated = false;
    }

    let (forms_law, forms) = match depth {
        FormsDepth::Skip => {
            let mut law = Tracker::new(Law::Forms);
            law.evaluated = m.forms.is_none();
            (law, None)
        }
        _ => check_forms(m, depth == FormsDepth::Report),
    };

    let laws = vec![
        schema.result(),
        finite.result(),
        sorted.result(),
        reflectance_range.result(),
        absorption_range.result(),
        concentration_range.result(),
        yield_range.result(),
        peak.result(),
        integral.result(),
        total.result(),
        energy.result(),
        photons.result(),
        forms_law.result(),
    ];
    let valid = laws.iter().all(|l| l.status != Status::Fail);
    CheckReport {
        material: m.name.clone(),
        source: None,
        valid,
        model: m.forms.as_ref().map(|f| f.model.clone()),
        laws,
        fluorophores: summaries,
        forms,
    }
}

/// Spacing (nm) at which absorption forms are searched for values above 1 between
/// samples.
const FORM_SCAN_STEP_NM: f64 = 0.5;

/// The [`Law::Forms`] tracker and the forms summary: every form compared with its
/// spectrum's samples (all violations named, one per spectrum), and with `notes` every
/// absorption form scanned between its samples.
fn check_forms(m: &RawMaterial, notes: bool) -> (Tracker, Option<FormsSummary>) {
    let mut law = Tracker::new(Law::Forms);
    let Some(raw) = &m.forms else {
        return (law, None);
    };
    let mut summary = FormsSummary {
        model: raw.model.clone(),
        forms: 0,
        parameters: 0,
        worst_deviation: f64::NAN,
        notes: Vec::new(),
    };
    let Some(forms) = &raw.forms else {
        let error = raw.error.clone().unwrap_or_default();
        law.observe_if(true, f64::NAN, f64::NAN, "forms", None, || {
            format!("the forms block does not read: {error}; fix it or drop the block (everything downstream uses the samples)")
        });
        return (law, Some(summary));
    };
    if forms.fluorophores.len() != m.fluorophores.len() {
        law.observe_if(true, f64::NAN, f64::NAN, "forms.fluorophores", None, || {
            format!(
                "forms.fluorophores has {} entries for {} fluorophores; give one per fluorophore, in order, or drop the forms block",
                forms.fluorophores.len(),
                m.fluorophores.len()
            )
        });
    }
    let fluorophores = m.fluorophores.iter().map(|f| (&f.absorption, &f.emission));
    let pairs = forms.pairs(&m.reflectance, fluorophores);
    summary.forms = pairs.len();
    summary.parameters = pairs.iter().map(|(f, _, _)| f.n_params()).sum();
    let mut worst = 0.0f64;
    let mut compared = false;
    for (form, samples, what) in pairs {
        let place = format!("forms.{what}");
        if let Err(e) = form.validate(&place) {
            law.observe_if(true, f64::NAN, f64::NAN, &place, None, || {
                format!("{e}; fix the parameters or drop the forms block")
            });
            continue;
        }
        if !usable(samples) {
            // The structural laws report the samples; nothing to compare with.
            law.evaluated = false;
            continue;
        }
        compared = true;
        if let Some(a) = form.agreement(&samples.wavelength_nm, &samples.value, FORM_TOLERANCE) {
            worst = worst.max(a.worst);
            law.observe(-a.worst, a.worst, &place, Some(a.at_nm), || {
                format!(
                    "{place} gives {} at {} nm where {what} has the sample {} ({} of {} samples differ by more than {FORM_TOLERANCE:.0e} of the peak); re-tabulate the samples from the form or drop the forms block",
                    a.form_value,
                    a.at_nm,
                    a.sample,
                    a.beyond,
                    samples.value.len()
                )
            });
        }
        // Between samples an absorption form may exceed 1 though its samples do not.
        if notes
            && what.ends_with(".absorption")
            && let (Some(&lo), Some(&hi)) =
                (samples.wavelength_nm.first(), samples.wavelength_nm.last())
        {
            let steps = ((hi - lo) / FORM_SCAN_STEP_NM).ceil().min(1e6) as usize;
            let (top_nm, top) = (0..=steps)
                .map(|i| lo + (i as f64 * FORM_SCAN_STEP_NM).min(hi - lo))
                .map(|l| (l, form.eval(l)))
                .fold(
                    (lo, f64::NEG_INFINITY),
                    |a, b| if b.1 > a.1 { b } else { a },
                );
            if top > 1.0 + NORMALISATION_TOLERANCE {
                summary.notes.push(format!(
                    "{place} reaches {top:.4} at {top_nm} nm between samples (the samples, which everything uses, stay ≤ 1); sample it more finely to follow the form"
                ));
            }
        }
    }
    if compared {
        summary.worst_deviation = worst;
    }
    (law, Some(summary))
}

/// Shortest and longest wavelength where a > 0: a is linear between samples, so a
/// zero sample next to a positive one bounds the absorbed interval (its infimum or
/// supremum), as [`Fluorophore::shortest_absorbed_nm`] finds the shortest.
fn absorbed_range(f: &Fluorophore) -> Option<[f64; 2]> {
    let lo = f.shortest_absorbed_nm()?;
    let a = &f.absorption;
    let last = a.value.iter().rposition(|&v| v > 0.0)?;
    let hi = a.wavelength_nm[(last + 1).min(a.len() - 1)];
    Some([lo, hi])
}

/// The conservation block of `material` from the energy law's extrema (as
/// [`energy_extrema`] returns them) and the photon law's worst value per fluorophore
/// ([`Fluorophore::max_photon_yield`], what the photon law observes): 0 where nothing is
/// observed (no fluorophore).
fn conservation(material: &Material, extrema: &[(f64, f64)]) -> Conservation {
    Conservation {
        max_energy_albedo: extrema.iter().map(|&(_, rho)| rho).fold(0.0, f64::max),
        max_photon_ratio: material
            .fluorophores
            .iter()
            .filter_map(Fluorophore::max_photon_yield)
            .fold(0.0, f64::max),
    }
}

/// The local maxima of ρ(λ) on `grid` (every spectrum's samples): between samples every
/// spectrum is linear, so ρ = (1 − Σc·a)·r + Σc·Q(λ)·a·∫e is quadratic there, and its
/// maximum is at an end or at the vertex. Returns (λ, ρ) for every sample and interior
/// vertex, which include the global maximum exactly.
///
/// The photon form keeps ρ quadratic between samples: its fluorescent term
/// c·Φ·(λ/λ̄e)·a(λ)·∫e is λ (linear) times a (linear), a quadratic like (1 − Σc·a)·r, so
/// the sum is still one quadratic per interval and the vertex search stays exact (no
/// dense evaluation needed). Three values per interval (ends and midpoint) determine it.
fn energy_extrema(material: &Material, grid: &[f64]) -> Vec<(f64, f64)> {
    let moments = material.emission_moments();
    let albedo = |l: f64| material.energy_albedo_with(l, &moments);
    let mut out: Vec<(f64, f64)> = grid.iter().map(|&l| (l, albedo(l))).collect();
    for k in 1..grid.len() {
        let ((l0, f0), (l1, f1)) = (out[k - 1], out[k]);
        let fm = albedo(0.5 * (l0 + l1));
        // ρ(t) = f0 + b·t + c·t², t ∈ [0, 1].
        let c = 2.0 * (f0 + f1) - 4.0 * fm;
        let b = f1 - f0 - c;
        if c < 0.0 {
            let t = -b / (2.0 * c);
            if t > 0.0 && t < 1.0 {
                let l = l0 + t * (l1 - l0);
                out.push((l, albedo(l)));
            }
        }
    }
    out
}

/// The material's own checks, made by the law engine above: one place defines each law.
impl Material {
    /// The conservation block: the worst values of the energy and photon laws, found as
    /// the law engine finds them (ρ at every sample and every interval's vertex, so its
    /// exact maximum; each fluorophore's photon yield at its shortest absorbed
    /// wavelength). Written into every material, it agrees with what `check` reports.
    pub fn conservation_margins(&self) -> Conservation {
        conservation(self, &energy_extrema(self, &self.sample_wavelengths()))
    }

    /// Checks every law of the model (every [`Law`]: well-formed spectra, a, r, c and the
    /// yield in [0, 1], max a = 1, ∫e = 1, the forms, Σc·a ≤ 1, energy and photons) and
    /// returns the first broken one, in [`Law::ALL`] order, as an error naming where it
    /// breaks and by how much.
    pub fn validate(&self) -> Result<()> {
        self.validate_to(FormsDepth::Law)
    }

    /// [`Material::validate`] without comparing the forms with the samples, for a
    /// material whose samples were just tabulated from its forms (a model search's
    /// candidates: the chosen one is then validated in full).
    pub(crate) fn validate_except_forms(&self) -> Result<()> {
        self.validate_to(FormsDepth::Skip)
    }

    fn validate_to(&self, depth: FormsDepth) -> Result<()> {
        let report = check_to(&RawMaterial::from(self), depth);
        match report.laws.iter().find(|l| l.status == Status::Fail) {
            None => Ok(()),
            Some(law) => Err(Error::invalid(
                law.worst_at.clone().unwrap_or_else(|| law.law.to_string()),
                format!(
                    "breaks the {} law ({}): {}",
                    law.law,
                    law.statement,
                    law.violations.first().cloned().unwrap_or_else(|| format!(
                        "worst value {}, margin {}",
                        law.worst_value, law.margin
                    ))
                ),
            )),
        }
    }

    /// Lowers the reflectance samples around any wavelength where the energy albedo ρ
    /// exceeds 1 (within [`BOUND_TOLERANCE`]), found exactly as the energy law finds it
    /// (every sample and every interval's vertex): a fit bounds ρ at its grid samples,
    /// but in the photon form the emitted term c·Φ·a(λ)·λ/λ̄e is quadratic between
    /// samples and can rise above the chord. Returns the largest reduction of r (0 when
    /// none).
    pub fn lower_reflectance_to_energy_bound(&mut self) -> f64 {
        self.lower_reflectance_to_energy_bound_with_margins().0
    }

    /// [`Material::lower_reflectance_to_energy_bound`], and the conservation block of the
    /// material it leaves ([`Material::conservation_margins`]) from the extrema its last
    /// pass found (where that pass lowered nothing, they are the material's; else they
    /// are searched again): a fit writes both, and each searched every interval.
    pub fn lower_reflectance_to_energy_bound_with_margins(&mut self) -> (f64, Conservation) {
        let mut largest: f64 = 0.0;
        let mut settled = None;
        for _ in 0..20 {
            let grid = self.sample_wavelengths();
            let mut changed = false;
            let extrema = energy_extrema(self, &grid);
            for &(l, rho) in &extrema {
                let excess = rho - 1.0;
                if excess <= 0.5 * BOUND_TOLERANCE {
                    continue;
                }
                let transmitted = (1.0 - self.absorbed(l)).max(1e-12);
                // Lower both samples bracketing λ (the reflectance holds its ends outside).
                let samples = &self.reflectance.wavelength_nm;
                let upper = samples.partition_point(|&g| g < l).min(samples.len() - 1);
                let lower = upper.saturating_sub(1);
                let cut = excess / transmitted + BOUND_TOLERANCE;
                for i in [lower, upper] {
                    let v = &mut self.reflectance.value[i];
                    let new = (*v - cut).max(0.0);
                    largest = largest.max(*v - new);
                    *v = new;
                }
                changed = true;
            }
            if !changed {
                settled = Some(extrema);
                break;
            }
        }
        let margins = match settled {
            Some(extrema) => conservation(self, &extrema),
            None => self.conservation_margins(),
        };
        (largest, margins)
    }
}

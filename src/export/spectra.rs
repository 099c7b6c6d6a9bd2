//! Spectra tables: the `csv` export and the two-column files renderers read.

use crate::material::{Fluorophore, Material, YieldForm};

use super::{VERSION, one_line};

/// Every wavelength at which some spectrum of the material is sampled.
pub(super) fn union_grid(material: &Material) -> Vec<f64> {
    material.sample_wavelengths()
}

/// The `csv` export: `wavelength_nm,absorption,emission,reflectance` (with `_N` suffixes
/// for several fluorophores) on the union of the material's sample wavelengths; a and e
/// are zero outside their samples, r holds its end values.
pub(super) fn csv(material: &Material) -> String {
    let name = one_line(&material.name);
    let n = material.fluorophores.len();
    let suffix = |i: usize| {
        if n > 1 {
            format!("_{i}")
        } else {
            String::new()
        }
    };
    let mut out = format!(
        "# fluorite {VERSION} export of material \"{name}\": spectra of the diffuse fluorescent BBRRDF (Jung et al. 2018)\n"
    );
    out.push_str("# wavelength_nm: wavelength (nm)\n");
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = suffix(i);
        out.push_str(&format!(
            "# absorption{s}: a(λ), dimensionless, max a = 1, zero outside the samples\n# emission{s}: e(λ), emission density in 1/nm, ∫e dλ = 1, zero outside the samples\n# concentration{s}: c = {}\n{}",
            f.concentration,
            yield_lines(f, &s, "# ")
        ));
    }
    out.push_str(
        "# reflectance: r(λ), dimensionless reflectance of the non-fluorescent part, end values held outside the samples\n",
    );
    out.push_str(&forms_header(material, "# "));
    out.push_str("wavelength_nm");
    for i in 0..n {
        let s = suffix(i);
        out.push_str(&format!(",absorption{s},emission{s}"));
    }
    out.push_str(",reflectance\n");
    for l in union_grid(material) {
        out.push_str(&format!("{l}"));
        for f in &material.fluorophores {
            out.push_str(&format!(
                ",{},{}",
                f.absorption.eval_zero_outside(l),
                f.emission.eval_zero_outside(l)
            ));
        }
        out.push_str(&format!(",{}\n", material.reflectance.eval_clamped(l)));
    }
    out
}

/// Header lines (each starting with `prefix`) stating a fluorophore's yield: `quantum_yield`
/// Q in the energy form; `yield_form` and `photon_yield` Φ (with the energy yield it
/// implies) in the photon form. `s` is the fluorophore's column suffix.
pub(super) fn yield_lines(f: &Fluorophore, s: &str, prefix: &str) -> String {
    match f.yield_form {
        YieldForm::Energy => format!(
            "{prefix}quantum_yield{s}: Q = {} (energy yield, constant over the excitation wavelength)\n",
            f.quantum_yield
        ),
        YieldForm::Photon => format!(
            "{prefix}yield_form{s}: photon (a constant photon yield Φ; the energy yield is Q(λi) = Φ·λi/λ̄e)\n{prefix}photon_yield{s}: Φ = {}\n{prefix}mean_emission{s}: λ̄e = {} nm\n",
            f.quantum_yield,
            f.emission_mean_nm()
        ),
    }
}

/// Header lines (each starting with `prefix`) describing the material's continuous forms:
/// the model and every form's parameters as compact JSON, so that an export of a
/// parametric fit keeps its forms. Empty without a forms block.
pub(super) fn forms_header(material: &Material, prefix: &str) -> String {
    let Some(forms) = &material.forms else {
        return String::new();
    };
    let mut out = format!(
        "{prefix}forms: model {}; the sampled spectra are these continuous forms evaluated (parameters as in the material's JSON forms block)\n",
        one_line(&forms.model)
    );
    let json = |f: &crate::parametric::SpectralForm| {
        serde_json::to_string(f).unwrap_or_else(|e| format!("(not serialisable: {e})"))
    };
    if let Some(r) = &forms.reflectance {
        out.push_str(&format!("{prefix}form reflectance: {}\n", json(r)));
    }
    let n = forms.fluorophores.len();
    for (i, f) in forms.fluorophores.iter().enumerate() {
        let s = if n > 1 {
            format!("_{i}")
        } else {
            String::new()
        };
        out.push_str(&format!(
            "{prefix}form absorption{s}: {}\n",
            json(&f.absorption)
        ));
        out.push_str(&format!(
            "{prefix}form emission{s}: {}\n",
            json(&f.emission)
        ));
    }
    out
}

/// A two-column spectrum file (`wavelength value` per line) with `#` header lines, as
/// Mitsuba 3 and pbrt-v4 read them.
pub(super) fn two_column(header: &[String], samples: impl Iterator<Item = (f64, f64)>) -> String {
    let mut out = String::new();
    for h in header {
        out.push_str("# ");
        out.push_str(h);
        out.push('\n');
    }
    for (l, v) in samples {
        out.push_str(&format!("{} {}\n", number(l), number(v)));
    }
    out
}

/// A number as the renderers' readers take it: rounded to f32 (they read f32; pbrt-v4's
/// `std::stof`), in the shorter of plain and exponent form, each the shortest text that
/// reads back to the same f32 (at most 15 characters; pbrt-v4's buffer holds 31), and 0
/// below f32's normal range (1.18e-38), where `std::stof` fails.
pub(super) fn number(value: f64) -> String {
    let single = value as f32;
    if single.abs() < f32::MIN_POSITIVE || !single.is_finite() {
        return "0".to_string();
    }
    let plain = format!("{single}");
    let exponent = format!("{single:e}");
    if exponent.len() < plain.len() {
        exponent
    } else {
        plain
    }
}

/// Where a fluorophore's excitation is written: the absorption's samples, and in the
/// photon form also points splitting every interval into steps of at most 1 nm (c·Φ·λ·a/λ̄e
/// is quadratic between samples; linear interpolation over ≤ 1 nm is then within
/// c·Φ·|Δa|/(4·λ̄e) per nm step of it).
pub(super) fn excitation_grid(f: &Fluorophore) -> Vec<f64> {
    let samples = &f.absorption.wavelength_nm;
    match f.yield_form {
        YieldForm::Energy => samples.clone(),
        YieldForm::Photon => {
            let mut grid = Vec::with_capacity(samples.len());
            for w in samples.windows(2) {
                let steps = ((w[1] - w[0]).ceil() as usize).clamp(1, 100_000);
                grid.extend((0..steps).map(|j| w[0] + (w[1] - w[0]) * j as f64 / steps as f64));
            }
            grid.extend(samples.last());
            grid
        }
    }
}

//! Mitsuba 3 and pbrt-v4: spectrum files and scene snippets.
//!
//! Neither renderer ships a fluorescent BSDF, so the export gives what one needs: the
//! non-fluorescent albedo (1 − Σc·a)·r for a plain `diffuse` BSDF (correct for everything
//! except the reradiation), and each fluorescent lobe's excitation c·Q·a and normalised
//! emission e for a fluorescent diffuse BSDF (the model's
//! f = [δ(λi − λo)·(1 − Σc·a(λi))·r(λi) + Σ c·Q·a(λi)·e(λo)] / π).
//!
//! A material with several fluorophores keeps every one: one excitation and emission
//! file per component (`_0`, `_1`, …), a snippet that names all lobes in one BSDF, and
//! the full reradiation matrix (all components summed) for matrix-based renderers.
//!
//! A photon-form fluorophore (constant photon yield Φ) has the energy yield
//! Q(λi) = Φ·λi/λ̄e: its excitation file holds c·Q(λi)·a(λi), sampled every nanometre or
//! finer (λ·a is quadratic between the absorption's samples, and renderers interpolate
//! linearly), and the snippets say that a plugin taking a constant yield cannot express
//! it.

use crate::material::{Fluorophore, Material, YieldForm};

use super::spectra::{two_column, union_grid};
use super::{VERSION, one_line};

/// A spectrum file to write: file name, header lines, (wavelength, value) samples.
type SpectrumFile = (String, Vec<String>, Vec<(f64, f64)>);

/// The spectra both renderers get.
fn spectra(material: &Material, stem: &str) -> Vec<SpectrumFile> {
    let name = one_line(&material.name);
    let produced = format!("fluorite {VERSION} export of material \"{name}\"");
    let grid = union_grid(material);
    let n = material.fluorophores.len();
    let albedo = if n > 1 {
        format!(
            "quantity: non-fluorescent albedo (1 - Σ c_k*a_k(λ))*r(λ) over the {n} fluorophores, dimensionless (diagonal reflectance)"
        )
    } else {
        "quantity: non-fluorescent albedo (1 - c*a(λ))*r(λ), dimensionless (diagonal reflectance)"
            .to_string()
    };
    let mut out = vec![
        (
            format!("{stem}_albedo.spd"),
            vec![
                produced.clone(),
                albedo,
                "columns: wavelength (nm), value".into(),
            ],
            grid.iter().map(|&l| (l, material.diagonal(l))).collect(),
        ),
        (
            format!("{stem}_reflectance.spd"),
            vec![
                produced.clone(),
                "quantity: reflectance r(λ) of the non-fluorescent part, dimensionless".into(),
                "columns: wavelength (nm), value".into(),
            ],
            grid.iter()
                .map(|&l| (l, material.reflectance.eval_clamped(l)))
                .collect(),
        ),
    ];
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = if n > 1 {
            format!("_{i}")
        } else {
            String::new()
        };
        let quantity = match f.yield_form {
            YieldForm::Energy => format!(
                "quantity: fluorescent excitation c*Q*a(λ), dimensionless (fraction of incident energy at λ re-emitted), c = {}, Q = {}",
                f.concentration, f.quantum_yield
            ),
            YieldForm::Photon => format!(
                "quantity: fluorescent excitation c*Q(λ)*a(λ) with the energy yield Q(λ) = Φ*λ/λ̄e (photon form: constant photon yield), dimensionless (fraction of incident energy at λ re-emitted), c = {}, Φ = {}, λ̄e = {} nm; sampled at most 1 nm apart (λ*a is quadratic between the absorption samples)",
                f.concentration,
                f.quantum_yield,
                f.emission_mean_nm()
            ),
        };
        let mean = f.emission_mean_nm();
        out.push((
            format!("{stem}_excitation{s}.spd"),
            vec![
                produced.clone(),
                quantity,
                "columns: wavelength (nm), value".into(),
            ],
            excitation_grid(f)
                .into_iter()
                .map(|l| (l, f.reradiated_with_mean(l, mean)))
                .collect(),
        ));
        out.push((
            format!("{stem}_emission{s}.spd"),
            vec![
                produced.clone(),
                "quantity: normalised emission spectrum e(λ) in 1/nm (integral over nm = 1)".into(),
                "columns: wavelength (nm), value".into(),
            ],
            f.emission
                .wavelength_nm
                .iter()
                .zip(&f.emission.value)
                .map(|(&l, &e)| (l, e))
                .collect(),
        ));
    }
    if let Some(forms) = &material.forms {
        let note = format!(
            "spectra: samples of the continuous forms of model {} (parameters in the material's JSON forms block)",
            one_line(&forms.model)
        );
        for (_, header, _) in &mut out {
            header.insert(1, note.clone());
        }
    }
    out
}

/// Where a fluorophore's excitation is written: the absorption's samples, and in the
/// photon form also points splitting every interval into steps of at most 1 nm (c·Φ·λ·a/λ̄e
/// is quadratic between samples; linear interpolation over ≤ 1 nm is then within
/// c·Φ·|Δa|/(4·λ̄e) per nm step of it).
fn excitation_grid(f: &Fluorophore) -> Vec<f64> {
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

/// Comment lines (each starting with `prefix`) for the photon-form fluorophores: the
/// excitation file holds c·Q(λi)·a with Q(λi) = Φ·λi/λ̄e, which a plugin taking a constant
/// quantum yield cannot express. Empty when every fluorophore is in the energy form.
fn photon_note(material: &Material, prefix: &str) -> String {
    let mut out = String::new();
    for (i, f) in material.fluorophores.iter().enumerate() {
        if f.yield_form != YieldForm::Photon {
            continue;
        }
        let s = lobe_suffix(material, i);
        out.push_str(&format!(
            "{prefix}Lobe{s} has a constant PHOTON yield Φ = {} (yield_form photon), not a constant energy yield:\n\
{prefix}its energy yield is Q(λi) = Φ·λi/λ̄e (λ̄e = {} nm), already in excitation{s}. A plugin that\n\
{prefix}takes a constant quantum_yield and an absorption cannot express this form: give it the\n\
{prefix}excitation spectrum (with quantum_yield 1 and concentration 1) or use the reradiation matrix.\n",
            f.quantum_yield,
            f.emission_mean_nm()
        ));
    }
    out
}

/// The yield parameter of a lobe for the plugin snippet: `quantum_yield` (Q) in the
/// energy form, `yield_form` and `photon_yield` (Φ) in the photon form.
fn yield_floats(f: &Fluorophore, suffix: &str) -> String {
    match f.yield_form {
        YieldForm::Energy => format!(
            "    <float name=\"quantum_yield{suffix}\" value=\"{}\"/>\n",
            f.quantum_yield
        ),
        YieldForm::Photon => format!(
            "    <string name=\"yield_form{suffix}\" value=\"photon\"/>\n    <float name=\"photon_yield{suffix}\" value=\"{}\"/>\n",
            f.quantum_yield
        ),
    }
}

/// The suffix of fluorophore `i`'s files: none for a single fluorophore, `_i` otherwise.
fn lobe_suffix(material: &Material, i: usize) -> String {
    if material.fluorophores.len() > 1 {
        format!("_{i}")
    } else {
        String::new()
    }
}

/// The comment lines listing each lobe's files, for the Mitsuba snippet.
fn lobe_files(material: &Material, stem: &str) -> String {
    let mut out = String::new();
    for i in 0..material.fluorophores.len() {
        let s = lobe_suffix(material, i);
        out.push_str(&format!(
            "{stem}_excitation{s}.spd   c·Q(λi)·a{s}, dimensionless: fraction of energy at λi re-emitted\n\
             {stem}_emission{s}.spd     e{s} in 1/nm, ∫e dλ = 1: where the re-emitted energy goes\n"
        ));
    }
    out
}

fn render_spectra(material: &Material, stem: &str) -> Vec<(String, String)> {
    spectra(material, stem)
        .into_iter()
        .map(|(file, header, samples)| (file, two_column(&header, samples.into_iter())))
        .collect()
}

/// Mitsuba 3: `.spd` files and `NAME.xml`.
pub(super) fn mitsuba(material: &Material, stem: &str) -> Vec<(String, String)> {
    let mut files = render_spectra(material, stem);
    let name = one_line(&material.name).replace("--", "- -");
    let n = material.fluorophores.len();
    let sum = if n > 1 { "Σ" } else { "" };
    let lobes = lobe_files(material, stem);
    let several = if n > 1 {
        format!(
            "{stem}_reradiation.csv  the full reradiation matrix, all {n} fluorophores summed\n\
     This material has {n} fluorescent components: a fluorescent BSDF with a single\n\
     excitation/emission pair cannot hold it. Give the BSDF every lobe (below: f adds\n\
     excitation_k(λi)·emission_k(λo)/π for each k), or use the reradiation matrix.\n"
        )
    } else {
        String::new()
    };
    let forms = match &material.forms {
        Some(f) => format!(
            "\nThe spectra are samples of the continuous forms of model {} (see the material JSON).",
            one_line(&f.model).replace("--", "- -")
        ),
        None => String::new(),
    };
    let photon = photon_note(material, "     ").replace("--", "- -");
    let q = if photon.is_empty() { "Q" } else { "Q(λi)" };
    let mut xml = format!(
        "<!-- fluorite {VERSION} export of material \"{name}\" for Mitsuba 3 (spectral variant, e.g. scalar_spectral).\n\
     The diffuse fluorescent BBRRDF (Jung et al. 2018):\n\
       f(λi, λo) = [ δ(λi - λo)·(1 - {sum}c·a(λi))·r(λi) + {sum}c·{q}·a(λi)·e(λo) ] / π\n\
     Files (two columns: wavelength in nm, value):\n\
       {stem}_albedo.spd       (1 - {sum}c·a)·r, dimensionless: the non-fluorescent diffuse albedo\n\
       {stem}_reflectance.spd  r, dimensionless\n\
{lobes}{several}\
{photon}\
     Mapping onto a fluorescent diffuse BSDF: the plain `diffuse` BSDF below with the albedo\n\
     is exact for the reflected part. A fluorescent diffuse BSDF adds, for light arriving at\n\
     λi, the energy excitation(λi) re-emitted at λo with density emission(λo), both lobes\n\
     cosine-distributed. Sampling (model.md §6): on camera paths (λo known) sample\n\
     λi ∝ excitation(λi) and choose fluorescence with P = X·e(λo) / (X·e(λo) + albedo(λo)),\n\
     X = ∫excitation dλ (= c·Q·∫a dλ for a constant energy yield Q).{forms} -->\n"
    );
    xml.push_str(&format!(
        "<bsdf type=\"diffuse\" id=\"{}\">\n    <spectrum name=\"reflectance\" filename=\"{stem}_albedo.spd\"/>\n</bsdf>\n",
        super::file_stem(&material.name)
    ));
    if n > 1 {
        let mut lobes = String::new();
        for (i, f) in material.fluorophores.iter().enumerate() {
            lobes.push_str(&format!(
                "    <spectrum name=\"excitation_{i}\" filename=\"{stem}_excitation_{i}.spd\"/>\n    <spectrum name=\"emission_{i}\" filename=\"{stem}_emission_{i}.spd\"/>\n    <float name=\"concentration_{i}\" value=\"{}\"/>\n{}",
                f.concentration,
                yield_floats(f, &format!("_{i}"))
            ));
        }
        xml.push_str(&format!(
            "<!-- {n} fluorescent lobes for a fluorescent diffuse BSDF plugin (not part of stock Mitsuba 3):\n\
<bsdf type=\"fluorescent_diffuse\">\n    <spectrum name=\"albedo\" filename=\"{stem}_albedo.spd\"/>\n    <integer name=\"lobes\" value=\"{n}\"/>\n{lobes}</bsdf> -->\n"
        ));
    }
    if let [f] = material.fluorophores.as_slice() {
        xml.push_str(&format!(
            "<!-- fluorescent lobe for a fluorescent diffuse BSDF plugin (not part of stock Mitsuba 3):\n\
<bsdf type=\"fluorescent_diffuse\">\n    <spectrum name=\"albedo\" filename=\"{stem}_albedo.spd\"/>\n    <spectrum name=\"excitation\" filename=\"{stem}_excitation.spd\"/>\n    <spectrum name=\"emission\" filename=\"{stem}_emission.spd\"/>\n    <float name=\"concentration\" value=\"{}\"/>\n{}</bsdf> -->\n",
            f.concentration,
            yield_floats(f, "")
        ));
    }
    files.push((format!("{stem}.xml"), xml));
    files
}

/// pbrt-v4: `.spd` files and `NAME.pbrt` (the matrix is added by the caller).
pub(super) fn pbrt(material: &Material, stem: &str) -> Vec<(String, String)> {
    let mut files = render_spectra(material, stem);
    let name = one_line(&material.name);
    let n = material.fluorophores.len();
    let sum = if n > 1 { "Σ" } else { "" };
    let lobes: String = (0..n)
        .map(|i| {
            let s = lobe_suffix(material, i);
            format!("# {stem}_excitation{s}.spd (c·Q(λi)·a{s}, dimensionless), {stem}_emission{s}.spd (e{s}, 1/nm, ∫e dλ = 1),\n")
        })
        .collect();
    let summed = if n > 1 {
        format!(", all {n} fluorophores summed")
    } else {
        String::new()
    };
    let several = if n > 1 {
        format!(
            "# This material has {n} fluorescent components (the lobes below): a fluorescent material\n\
# with a single excitation/emission pair cannot hold it; give it every lobe, or use the matrix.\n"
        )
    } else {
        String::new()
    };
    let forms = match &material.forms {
        Some(f) => format!(
            "# The spectra are samples of the continuous forms of model {} (see the material JSON).\n",
            one_line(&f.model)
        ),
        None => String::new(),
    };
    let photon = photon_note(material, "# ");
    let q = if photon.is_empty() { "Q" } else { "Q(λi)" };
    let mut scene = format!(
        "# fluorite {VERSION} export of material \"{name}\" for pbrt-v4.\n\
# The diffuse fluorescent BBRRDF (Jung et al. 2018):\n\
#   f(λi, λo) = [ δ(λi - λo)·(1 - {sum}c·a(λi))·r(λi) + {sum}c·{q}·a(λi)·e(λo) ] / π\n\
# Files: {stem}_albedo.spd ((1 - {sum}c·a)·r, dimensionless), {stem}_reflectance.spd (r),\n\
{lobes}\
# {stem}_reradiation.csv (the full reradiation matrix{summed}, rows excitation, columns emission,\n\
# for matrix-based renderers; see its header for units).\n\
{several}{photon}{forms}\
# Stock pbrt-v4 has no fluorescent material: the diffuse material below is exact for the\n\
# reflected part; a fluorescent diffuse material adds excitation(λi)·emission(λo)/π.\n"
    );
    scene.push_str(&format!(
        "MakeNamedMaterial \"{}\"\n    \"string type\" \"diffuse\"\n    \"spectrum reflectance\" \"{stem}_albedo.spd\"\n",
        name.replace('"', "'")
    ));
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = lobe_suffix(material, i);
        let y = match f.yield_form {
            YieldForm::Energy => format!("Q = {}", f.quantum_yield),
            YieldForm::Photon => format!(
                "photon form, Φ = {} (Q(λi) = Φ·λi/λ̄e, λ̄e = {} nm)",
                f.quantum_yield,
                f.emission_mean_nm()
            ),
        };
        scene.push_str(&format!(
            "# fluorescent lobe{s}: c = {}, {y}, excitation \"{stem}_excitation{s}.spd\", emission \"{stem}_emission{s}.spd\"\n",
            f.concentration
        ));
    }
    files.push((format!("{stem}.pbrt"), scene));
    files
}

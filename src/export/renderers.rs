//! Mitsuba 3 and pbrt-v4: spectrum files and scene snippets.
//!
//! Neither renderer ships a fluorescent BSDF, so the export gives what one needs: the
//! non-fluorescent albedo (1 − c·a)·r for a plain `diffuse` BSDF (correct for everything
//! except the reradiation), and the fluorescent lobe's excitation c·Q·a and normalised
//! emission e for a fluorescent diffuse BSDF (the model's
//! f = [δ(λi − λo)·(1 − c·a(λi))·r(λi) + c·Q·a(λi)·e(λo)] / π).

use crate::material::Material;

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
    let mut out = vec![
        (
            format!("{stem}_albedo.spd"),
            vec![
                produced.clone(),
                "quantity: non-fluorescent albedo (1 - c*a(λ))*r(λ), dimensionless (diagonal reflectance)".into(),
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
        out.push((
            format!("{stem}_excitation{s}.spd"),
            vec![
                produced.clone(),
                format!(
                    "quantity: fluorescent excitation c*Q*a(λ), dimensionless (fraction of incident energy at λ re-emitted), c = {}, Q = {}",
                    f.concentration, f.quantum_yield
                ),
                "columns: wavelength (nm), value".into(),
            ],
            f.absorption
                .wavelength_nm
                .iter()
                .zip(&f.absorption.value)
                .map(|(&l, &a)| (l, f.k() * a))
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
    let mut xml = format!(
        "<!-- fluorite {VERSION} export of material \"{name}\" for Mitsuba 3 (spectral variant, e.g. scalar_spectral).\n\
     The diffuse fluorescent BBRRDF (Jung et al. 2018):\n\
       f(λi, λo) = [ δ(λi - λo)·(1 - c·a(λi))·r(λi) + c·Q·a(λi)·e(λo) ] / π\n\
     Files (two columns: wavelength in nm, value):\n\
       {stem}_albedo.spd       (1 - c·a)·r, dimensionless: the non-fluorescent diffuse albedo\n\
       {stem}_reflectance.spd  r, dimensionless\n\
       {stem}_excitation.spd   c·Q·a, dimensionless: fraction of energy at λi re-emitted\n\
       {stem}_emission.spd     e in 1/nm, ∫e dλ = 1: where the re-emitted energy goes\n\
     Mapping onto a fluorescent diffuse BSDF: the plain `diffuse` BSDF below with the albedo\n\
     is exact for the reflected part. A fluorescent diffuse BSDF adds, for light arriving at\n\
     λi, the energy excitation(λi) re-emitted at λo with density emission(λo), both lobes\n\
     cosine-distributed. Sampling (model.md §6): on camera paths (λo known) sample λi ∝ a\n\
     and choose fluorescence with P = k·A·e(λo) / (k·A·e(λo) + albedo(λo)), A = ∫a dλ, k = c·Q. -->\n"
    );
    xml.push_str(&format!(
        "<bsdf type=\"diffuse\" id=\"{}\">\n    <spectrum name=\"reflectance\" filename=\"{stem}_albedo.spd\"/>\n</bsdf>\n",
        super::file_stem(&material.name)
    ));
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = if material.fluorophores.len() > 1 {
            format!("_{i}")
        } else {
            String::new()
        };
        xml.push_str(&format!(
            "<!-- fluorescent lobe{s} for a fluorescent diffuse BSDF plugin (not part of stock Mitsuba 3):\n\
<bsdf type=\"fluorescent_diffuse\">\n    <spectrum name=\"albedo\" filename=\"{stem}_albedo.spd\"/>\n    <spectrum name=\"excitation\" filename=\"{stem}_excitation{s}.spd\"/>\n    <spectrum name=\"emission\" filename=\"{stem}_emission{s}.spd\"/>\n    <float name=\"concentration\" value=\"{}\"/>\n    <float name=\"quantum_yield\" value=\"{}\"/>\n</bsdf> -->\n",
            f.concentration, f.quantum_yield
        ));
    }
    files.push((format!("{stem}.xml"), xml));
    files
}

/// pbrt-v4: `.spd` files and `NAME.pbrt` (the matrix is added by the caller).
pub(super) fn pbrt(material: &Material, stem: &str) -> Vec<(String, String)> {
    let mut files = render_spectra(material, stem);
    let name = one_line(&material.name);
    let mut scene = format!(
        "# fluorite {VERSION} export of material \"{name}\" for pbrt-v4.\n\
# The diffuse fluorescent BBRRDF (Jung et al. 2018):\n\
#   f(λi, λo) = [ δ(λi - λo)·(1 - c·a(λi))·r(λi) + c·Q·a(λi)·e(λo) ] / π\n\
# Files: {stem}_albedo.spd ((1 - c·a)·r, dimensionless), {stem}_reflectance.spd (r),\n\
# {stem}_excitation.spd (c·Q·a, dimensionless), {stem}_emission.spd (e, 1/nm, ∫e dλ = 1),\n\
# {stem}_reradiation.csv (the full reradiation matrix, rows excitation, columns emission,\n\
# for matrix-based renderers; see its header for units).\n\
# Stock pbrt-v4 has no fluorescent material: the diffuse material below is exact for the\n\
# reflected part; a fluorescent diffuse material adds excitation(λi)·emission(λo)/π.\n"
    );
    scene.push_str(&format!(
        "MakeNamedMaterial \"{}\"\n    \"string type\" \"diffuse\"\n    \"spectrum reflectance\" \"{stem}_albedo.spd\"\n",
        name.replace('"', "'")
    ));
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = if material.fluorophores.len() > 1 {
            format!("_{i}")
        } else {
            String::new()
        };
        scene.push_str(&format!(
            "# fluorescent lobe{s}: c = {}, Q = {}, excitation \"{stem}_excitation{s}.spd\", emission \"{stem}_emission{s}.spd\"\n",
            f.concentration, f.quantum_yield
        ));
    }
    files.push((format!("{stem}.pbrt"), scene));
    files
}
